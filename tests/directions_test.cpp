#include "util/directions.h"

#include <gtest/gtest.h>

#include <cmath>

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
