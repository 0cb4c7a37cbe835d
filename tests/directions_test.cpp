#include "util/directions.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "util/error.h"

namespace nbtf {

TEST(Directions, Hemisphere81HasTheUboRings) {
  const auto& dirs = hemisphere81();
  ASSERT_EQ(dirs.size(), 81u);
  int counts[6] = {};
  for (const auto& d : dirs) counts[static_cast<int>(d.thetaDeg / 15)]++;
  EXPECT_EQ(counts[0], 1);
  EXPECT_EQ(counts[1], 6);
  EXPECT_EQ(counts[2], 12);
  EXPECT_EQ(counts[3], 18);
  EXPECT_EQ(counts[4], 20);
  EXPECT_EQ(counts[5], 24);
  // Ring ascending, then phi ascending, phi starting at 0 with even steps.
  EXPECT_DOUBLE_EQ(dirs[1].phiDeg, 0);
  EXPECT_DOUBLE_EQ(dirs[2].phiDeg, 60);
  EXPECT_DOUBLE_EQ(dirs[80].thetaDeg, 75);
  EXPECT_DOUBLE_EQ(dirs[80].phiDeg, 345);
}

TEST(Directions, UnitVectorRoundTrip) {
  Direction d{37.5, 200};
  auto v = d.unitVector();
  EXPECT_NEAR(v[0] * v[0] + v[1] * v[1] + v[2] * v[2], 1.0, 1e-12);
  Direction back = Direction::fromUnitVector(v[0], v[1], v[2]);
  EXPECT_NEAR(back.thetaDeg, 37.5, 1e-9);
  EXPECT_NEAR(back.phiDeg, 200, 1e-9);
}

TEST(Directions, StereographicMapsHemisphereToUnitDisk) {
  auto n = stereographic({0, 123});
  EXPECT_NEAR(n[0], 0, 1e-7);
  EXPECT_NEAR(n[1], 0, 1e-7);
  auto h = stereographic({90, 90});
  EXPECT_NEAR(h[0], 0, 1e-6);
  EXPECT_NEAR(h[1], 1, 1e-6);
  // R = sin(pi - t) / (1 - cos(pi - t)) = tan(t / 2) for theta = 60: tan(30 deg).
  auto m = stereographic({60, 0});
  EXPECT_NEAR(m[0], std::tan(M_PI / 6), 1e-6);
}

TEST(Directions, ParseAndRejectBelowHorizon) {
  Direction d = parseDirection("37.5,200", "light");
  EXPECT_DOUBLE_EQ(d.thetaDeg, 37.5);
  EXPECT_DOUBLE_EQ(d.phiDeg, 200);
  EXPECT_THROW(parseDirection("95,0", "light"), Error);
  EXPECT_THROW(parseDirection("30", "view"), Error);
  EXPECT_THROW(parseDirection("30,abc", "view"), Error);
  try {
    parseDirection("120,0", "view");
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("view"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("hemisphere"), std::string::npos);
  }
}

TEST(Directions, NearestDirection) {
  const auto& dirs = hemisphere81();
  EXPECT_EQ(nearestDirection(dirs, {1, 0}), 0);
  EXPECT_EQ(nearestDirection(dirs, {74, 344}), 80);
}

}  // namespace nbtf

namespace nbtf {
namespace {

// The half-vector encoding: the paper's 4 stereographic values first (exactly what the
// stereographic encoding gives), then the unit half vector and cos(theta_d), computed by hand.
TEST(Directions, HalfVectorEncodingExtendsTheStereographicOne) {
  EXPECT_EQ(directionInputCount(DirectionEncoding::Stereographic), 4);
  EXPECT_EQ(directionInputCount(DirectionEncoding::StereographicHalf), 8);
  const Direction light{45, 0}, view{45, 180};  // mirror pair: h is the normal, theta_d = 45
  float paper[kMaxDirectionInputs], half[kMaxDirectionInputs];
  encodeDirections(DirectionEncoding::Stereographic, light, view, paper);
  encodeDirections(DirectionEncoding::StereographicHalf, light, view, half);
  auto l = stereographic(light), v = stereographic(view);
  EXPECT_EQ(paper[0], l[0]);
  EXPECT_EQ(paper[1], l[1]);
  EXPECT_EQ(paper[2], v[0]);
  EXPECT_EQ(paper[3], v[1]);
  for (int q = 0; q < 4; ++q) EXPECT_EQ(half[q], paper[q]);
  EXPECT_NEAR(half[4], 0, 1e-6);
  EXPECT_NEAR(half[5], 0, 1e-6);
  EXPECT_NEAR(half[6], 1, 1e-6);
  EXPECT_NEAR(half[7], std::cos(45 * M_PI / 180), 1e-6);

  // A general pair: h = normalize(l + v), cos(theta_d) = l . h.
  const Direction a{30, 60}, b{70, 300};
  encodeDirections(DirectionEncoding::StereographicHalf, a, b, half);
  auto la = a.unitVector(), vb = b.unitVector();
  double h[3] = {la[0] + vb[0], la[1] + vb[1], la[2] + vb[2]};
  double n = std::sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(half[4 + c], h[c] / n, 1e-6);
  EXPECT_NEAR(half[7], (la[0] * h[0] + la[1] * h[1] + la[2] * h[2]) / n, 1e-6);
  // The unit-vector form gives the same inputs (the decoder's UV queries use it).
  float fromVectors[kMaxDirectionInputs];
  encodeDirections(DirectionEncoding::StereographicHalf, la, vb, fromVectors);
  for (int q = 0; q < 8; ++q) EXPECT_NEAR(fromVectors[q], half[q], 1e-6) << q;
}

// The Fourier encodings: the paper's 4 values, then sin and cos of pi 2^o times each of them,
// octaves 0..2 (encoding 3) or 0..1 (encoding 4, the default: the same values without octave 2).
TEST(Directions, FourierEncodingAddsSinesAndCosinesOfTheStereographicCoordinates) {
  EXPECT_EQ(fourierOctaves(DirectionEncoding::StereographicFourier), 3);
  EXPECT_EQ(fourierOctaves(DirectionEncoding::StereographicFourier2), 2);
  EXPECT_EQ(fourierOctaves(DirectionEncoding::Stereographic), 0);
  EXPECT_EQ(fourierOctaves(DirectionEncoding::StereographicHalf), 0);
  EXPECT_EQ(directionInputCount(DirectionEncoding::StereographicFourier), 28);
  EXPECT_EQ(directionInputCount(DirectionEncoding::StereographicFourier2), 20);
  EXPECT_EQ(kMaxDirectionInputs, 28);
  const Direction light{30, 60}, view{70, 300};
  float paper[kMaxDirectionInputs], three[kMaxDirectionInputs];
  encodeDirections(DirectionEncoding::Stereographic, light, view, paper);
  encodeDirections(DirectionEncoding::StereographicFourier, light, view, three);
  for (DirectionEncoding e : {DirectionEncoding::StereographicFourier, DirectionEncoding::StereographicFourier2}) {
    const int octaves = fourierOctaves(e);
    float fourier[kMaxDirectionInputs];
    encodeDirections(e, light, view, fourier);
    for (int q = 0; q < 4; ++q) EXPECT_EQ(fourier[q], paper[q]);
    for (int c = 0; c < 4; ++c)
      for (int o = 0; o < octaves; ++o)
        for (int j = 0; j < 2; ++j) {
          const double a = M_PI * (1 << o) * paper[c];
          const float got = fourier[4 + 2 * (c * octaves + o) + j];
          EXPECT_NEAR(got, j == 0 ? std::sin(a) : std::cos(a), 1e-6) << c << " " << o;
          EXPECT_EQ(got, three[4 + 2 * (c * 3 + o) + j]) << c << " " << o;  // same bits as encoding 3's
        }
    // The unit-vector form gives the same inputs.
    float fromVectors[kMaxDirectionInputs];
    encodeDirections(e, light.unitVector(), view.unitVector(), fromVectors);
    for (int q = 0; q < directionInputCount(e); ++q) EXPECT_NEAR(fromVectors[q], fourier[q], 1e-5) << q;
    const std::string count = std::to_string(directionInputCount(e)) + " inputs";
    EXPECT_NE(directionEncodingDescription(e).find(count), std::string::npos) << directionEncodingDescription(e);
    EXPECT_NE(directionEncodingDescription(e).find(std::to_string(octaves) + " octaves"), std::string::npos);
  }
}

// The octaves above 0 come from doubling the angle, not from libm (queries pay for the sines
// and cosines); over the whole disk they must give the floats of the direct sin and cos, so
// files trained before keep their answers (a float ulp at most, where the double lands on a
// rounding boundary).
TEST(Directions, FourierOctavesByAngleDoublingMatchTheDirectSinesAndCosines) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> theta(0, 90), phi(0, 360);
  const int octaves = fourierOctaves(DirectionEncoding::StereographicFourier);
  int differing = 0;
  for (int i = 0; i < 20000; ++i) {
    const Direction light{theta(rng), phi(rng)}, view{theta(rng), phi(rng)};
    float in[kMaxDirectionInputs];
    encodeDirections(DirectionEncoding::StereographicFourier, light, view, in);
    for (int c = 0; c < 4; ++c)
      for (int o = 0; o < octaves; ++o) {
        const double a = M_PI * (1 << o) * in[c];
        const float direct[2] = {static_cast<float>(std::sin(a)), static_cast<float>(std::cos(a))};
        for (int j = 0; j < 2; ++j) {
          const float got = in[4 + 2 * (c * octaves + o) + j];
          EXPECT_LE(std::fabs(got - direct[j]), std::nextafter(std::fabs(direct[j]), 2.f) - std::fabs(direct[j]))
              << "coordinate " << c << " octave " << o;
          differing += got != direct[j];
        }
      }
  }
  EXPECT_LE(differing, 20000 * 24 / 1000);  // rare: at most one value in a thousand
}

TEST(Directions, EncodingNamesRoundTripAndUnknownNamesAreRefused) {
  EXPECT_EQ(directionEncodings(),
            (std::vector<DirectionEncoding>{DirectionEncoding::Stereographic, DirectionEncoding::StereographicHalf,
                                            DirectionEncoding::StereographicFourier,
                                            DirectionEncoding::StereographicFourier2}));
  for (DirectionEncoding e : directionEncodings()) EXPECT_EQ(parseDirectionEncoding(directionEncodingName(e)), e);
  EXPECT_EQ(directionEncodingName(DirectionEncoding::StereographicFourier2), "stereographic+fourier2");
  for (int code = 1; code <= 4; ++code) EXPECT_TRUE(isDirectionEncoding(code)) << code;
  EXPECT_FALSE(isDirectionEncoding(0));
  EXPECT_FALSE(isDirectionEncoding(5));
  try {
    parseDirectionEncoding("half");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("stereographic+half"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace nbtf
