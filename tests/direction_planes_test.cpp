#include "util/direction_planes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <utility>
#include <vector>

namespace nbtf {
namespace {

DirectionPlanes randomPlanes(int resolution, int features, std::uint32_t seed) {
  DirectionPlanes p;
  p.resolution = resolution;
  p.features = features;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  p.values.resize(p.valueCount());
  for (float& v : p.values) v = u(rng);
  return p;
}

// Bilinear interpolation written the plain way, in double: the value at (x, y) of plane p is
// the weighted mean of the four grid values around it, grid point i at -1 + 2 i / (R - 1).
double referenceSample(const DirectionPlanes& planes, int plane, int feature, double x, double y) {
  const int R = planes.resolution, F = planes.features;
  auto at = [&](int gx, int gy) {
    return static_cast<double>(planes.values[((static_cast<std::size_t>(plane) * R + gy) * R + gx) * F + feature]);
  };
  auto grid = [&](double c) { return std::clamp((c + 1) / 2 * (R - 1), 0.0, R - 1.0); };
  const double gx = grid(x), gy = grid(y);
  const int x0 = std::min(static_cast<int>(std::floor(gx)), R - 2), y0 = std::min(static_cast<int>(std::floor(gy)), R - 2);
  const double fx = gx - x0, fy = gy - y0;
  return (1 - fx) * (1 - fy) * at(x0, y0) + fx * (1 - fy) * at(x0 + 1, y0) + (1 - fx) * fy * at(x0, y0 + 1) +
         fx * fy * at(x0 + 1, y0 + 1);
}

TEST(DirectionPlanes, SamplingMatchesABruteForceBilinearReference) {
  const DirectionPlanes planes = randomPlanes(7, 3, 1);
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> u(-1.2f, 1.2f);  // beyond the border too: clamped
  for (int trial = 0; trial < 200; ++trial) {
    float points[6];
    for (float& c : points) c = u(rng);
    float out[DirectionPlanes::kPlanes * 3];
    sampleDirectionPlanes(planes, points, out);
    for (int p = 0; p < 3; ++p)
      for (int f = 0; f < 3; ++f)
        EXPECT_NEAR(out[p * 3 + f], referenceSample(planes, p, f, points[2 * p], points[2 * p + 1]), 1e-5)
            << "plane " << p << " feature " << f;
  }
  // At a grid point the value is the stored one exactly (the corners included).
  for (int gy : {0, 3, 6})
    for (int gx : {0, 2, 6}) {
      const float x = -1 + 2.0f * gx / 6, y = -1 + 2.0f * gy / 6;
      float points[6] = {x, y, x, y, x, y}, out[9];
      sampleDirectionPlanes(planes, points, out);
      for (int p = 0; p < 3; ++p)
        EXPECT_FLOAT_EQ(out[p * 3 + 1], planes.values[((p * 7 + gy) * 7 + gx) * 3 + 1]) << gx << "," << gy;
    }
}

// The scattered gradient is the derivative of sum(dOut . sample(values)) by every value:
// checked by central finite differences on every value a point touches and on one it does not.
TEST(DirectionPlanes, GradientMatchesFiniteDifferences) {
  DirectionPlanes planes = randomPlanes(5, 2, 3);
  const float points[6] = {0.13f, -0.41f, -0.77f, 0.52f, 0.9f, 0.95f};
  const float dOut[6] = {0.3f, -1.1f, 0.7f, 0.25f, -0.6f, 1.4f};
  std::vector<float> gradient(planes.valueCount(), 0.0f);
  scatterDirectionPlanesGradient(planes, points, dOut, gradient.data());
  auto objective = [&] {
    float out[6];
    sampleDirectionPlanes(planes, points, out);
    double s = 0;
    for (int i = 0; i < 6; ++i) s += static_cast<double>(dOut[i]) * out[i];
    return s;
  };
  int touched = 0;
  for (std::size_t i = 0; i < planes.values.size(); ++i) {
    const float keep = planes.values[i], h = 1e-2f;
    planes.values[i] = keep + h;
    const double up = objective();
    planes.values[i] = keep - h;
    const double down = objective();
    planes.values[i] = keep;
    EXPECT_NEAR(gradient[i], (up - down) / (2 * h), 1e-4) << "value " << i;
    touched += gradient[i] != 0;
  }
  EXPECT_EQ(touched, 3 * 4 * 2);  // 4 corners per plane, 2 features, 3 planes
}

// Training computes each pair's taps once and scatters the features in ranges, one range
// per thread: sampling from taps is sampling from the points, and the ranges' scatters,
// each over all rows in order, give the whole scatter's bits.
TEST(DirectionPlanes, TapsAndFeatureRangesGiveTheSameBits) {
  const int R = 6, F = 5, rows = 300;
  const DirectionPlanes planes = randomPlanes(R, F, 11);
  std::mt19937 rng(12);
  std::uniform_real_distribution<float> u(-1.1f, 1.1f);
  std::vector<float> points(6 * rows), dOut(3 * F * rows);
  for (float& c : points) c = u(rng);
  for (float& d : dOut) d = u(rng);
  std::vector<float> whole(planes.valueCount(), 0.5f), ranged = whole;
  for (int r = 0; r < rows; ++r) {
    const PlaneTaps taps = planeTaps(R, &points[6 * r]);
    float fromPoints[3 * F], fromTaps[3 * F];
    sampleDirectionPlanes(planes, &points[6 * r], fromPoints);
    sampleDirectionPlanes(taps, R, F, planes.values.data(), fromTaps);
    for (int i = 0; i < 3 * F; ++i) ASSERT_EQ(fromTaps[i], fromPoints[i]) << "row " << r << " input " << i;
    scatterDirectionPlanesGradient(planes, &points[6 * r], &dOut[3 * F * r], whole.data());
  }
  for (auto [first, end] : {std::pair{0, 2}, std::pair{2, 3}, std::pair{3, F}})
    for (int r = 0; r < rows; ++r)
      scatterDirectionPlanesGradient(planeTaps(R, &points[6 * r]), R, F, &dOut[3 * F * r], ranged.data(), first, end);
  EXPECT_EQ(ranged, whole);
  // Points near one another share cells, so values collect several rows' terms.
  int moved = 0;
  for (float g : whole) moved += g != 0.5f;
  EXPECT_GT(moved, 3 * F * 4);
}

// Cluster planes: row r's values are a DirectionPlanes block of their own, sampled and
// differentiated by the same functions (the raw overloads the training and the decoder call).
TEST(RowPlanes, EachRowIsADirectionPlanesBlock) {
  RowPlanes rows;
  rows.resolution = 5, rows.features = 3, rows.rows = 4;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1, 1);
  rows.values.resize(rows.valueCount());
  for (float& v : rows.values) v = u(rng);
  EXPECT_EQ(rows.valuesPerRow(), 3u * 5 * 5 * 3);
  EXPECT_EQ(rows.inputCount(), 9);
  const float points[6] = {0.3f, -0.2f, 0.85f, 0.1f, -0.6f, -0.95f};
  for (int r = 0; r < rows.rows; ++r) {
    DirectionPlanes block;
    block.resolution = 5, block.features = 3;
    block.values.assign(rows.rowValues(r), rows.rowValues(r) + rows.valuesPerRow());
    float want[9], got[9];
    sampleDirectionPlanes(block, points, want);
    sampleDirectionPlanes(rows.resolution, rows.features, rows.rowValues(r), points, got);
    for (int i = 0; i < 9; ++i) EXPECT_EQ(got[i], want[i]) << "row " << r << " input " << i;
    for (int p = 0; p < 3; ++p)
      for (int f = 0; f < 3; ++f)
        EXPECT_NEAR(got[p * 3 + f], referenceSample(block, p, f, points[2 * p], points[2 * p + 1]), 1e-5);
    const float dOut[9] = {1, -2, 0.5f, 0.25f, 3, -1, 0.1f, 0.2f, -0.3f};
    std::vector<float> a(block.valueCount(), 0.0f), b(block.valueCount(), 0.0f);
    scatterDirectionPlanesGradient(block, points, dOut, a.data());
    scatterDirectionPlanesGradient(rows.resolution, rows.features, points, dOut, b.data());
    EXPECT_EQ(a, b);
  }
}

TEST(DirectionPlanes, PointsAreTheStereographicProjectionsOfLightViewAndHalfVector) {
  float out[6];
  directionPlanePoints({0, 0, 1}, {0, 0, 1}, out);
  for (float c : out) EXPECT_FLOAT_EQ(c, 0);
  // At the horizon the projection reaches radius 1; the half vector of two opposite grazing
  // directions is the normal.
  directionPlanePoints({1, 0, 0}, {-1, 0, 0}, out);
  EXPECT_FLOAT_EQ(out[0], 1);
  EXPECT_FLOAT_EQ(out[2], -1);
  EXPECT_FLOAT_EQ(out[4], 0);
  EXPECT_FLOAT_EQ(out[5], 0);
  // theta = 60 degrees at phi = 90: radius tan(30 degrees) along y; the half vector of a light
  // at the normal and a view at 60 degrees lies at 30 degrees (radius tan 15 degrees).
  const double s = std::sin(M_PI / 3), c = std::cos(M_PI / 3);
  directionPlanePoints({0, 0, 1}, {0, s, c}, out);
  EXPECT_NEAR(out[3], std::tan(M_PI / 6), 1e-6);
  EXPECT_NEAR(out[5], std::tan(M_PI / 12), 1e-6);
  EXPECT_NEAR(out[4], 0, 1e-7);
}

}  // namespace
}  // namespace nbtf
