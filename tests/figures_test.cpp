// The report figures: heat map cells carry the colour of their value, the error
// magnification is a round factor, the comparison strip holds the three panels.
#include "eval/figures.h"

#include <gtest/gtest.h>

#include <cmath>

#include "io/color.h"
#include "test_util.h"
#include "util/error.h"

namespace nbtf {
namespace {

Color8 pixel(const Image8& img, int x, int y) {
  const std::uint8_t* p = &img.rgb[(static_cast<std::size_t>(y) * img.width + x) * 3];
  return {p[0], p[1], p[2]};
}
bool same(Color8 a, Color8 b) { return a.r == b.r && a.g == b.g && a.b == b.b; }

// Finds the first pixel of colour c scanning rows from the top, left of maxX.
bool find(const Image8& img, Color8 c, int& fx, int& fy, int maxX = 1 << 30) {
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < std::min(img.width, maxX); ++x)
      if (same(pixel(img, x, y), c)) return fx = x, fy = y, true;
  return false;
}

// The row with the most pixels of colour c (a chart's horizontal line of that colour).
int rowWithMost(const Image8& img, Color8 c) {
  int row = 0, most = 0;
  for (int y = 0; y < img.height; ++y) {
    int n = 0;
    for (int x = 0; x < img.width; ++x) n += same(pixel(img, x, y), c);
    if (n > most) most = n, row = y;
  }
  return row;
}

// The centres of the runs of colour c along a row, from column fromX on (a row through a
// chart's round markers just off its line: one run per marker).
std::vector<double> runCentres(const Image8& img, Color8 c, int row, int fromX = 0) {
  std::vector<double> centres;
  for (int x = fromX; x < img.width; ++x)
    if (same(pixel(img, x, row), c) && (x == fromX || !same(pixel(img, x - 1, row), c))) {
      int e = x;
      while (e + 1 < img.width && same(pixel(img, e + 1, row), c)) ++e;
      centres.push_back((x + e) / 2.0);
    }
  return centres;
}

TEST(Figures, HeatMapCellsHaveTheColourOfTheirValue) {
  // 2 x 3: the largest value maps to the top of the colour map, 0 to the bottom.
  std::vector<Direction> rows = {{0, 0}, {30, 0}}, cols = {{0, 0}, {45, 0}, {45, 180}};
  std::vector<double> v = {0.0, 0.5, 1.0, 0.25, 0.75, 0.5};
  Image8 img = renderDirectionHeatMap(v, rows, cols, {"t", "light", "view", "RMSE"});
  // Search the grid only: the colour bar on the right holds every colour.
  const int gridRight = img.width - 150;
  int x0, y0, x1, y1;
  ASSERT_TRUE(find(img, viridis(1.0), x1, y1, gridRight));  // the max cell: row 0, column 2
  ASSERT_TRUE(find(img, viridis(0.25), x0, y0, gridRight));  // row 1, column 0
  EXPECT_GT(y0, y1) << "row 1 lies below row 0";
  EXPECT_GT(x1, x0);
  // The cell of value 0.75 sits right of 0.25's cell, in the same row.
  int x2, y2;
  ASSERT_TRUE(find(img, viridis(0.75), x2, y2, gridRight));
  EXPECT_GT(x2, x0);
  EXPECT_EQ(y2, y0);
  test::expectErrorContaining([&] { renderDirectionHeatMap({1, 2}, rows, cols, {}); }, {"2 values", "2 x 3"});
  v[3] = NAN;
  test::expectErrorContaining([&] { renderDirectionHeatMap(v, rows, cols, {}); }, {"not finite"});
}

TEST(Figures, MagnificationIsARoundFactorThatKeepsTheErrorOnScale) {
  const int texels = 100;
  std::vector<float> ref(texels * 3, 0.5f), rec(ref);
  for (int t = 0; t < texels; ++t)
    for (int c = 0; c < 3; ++c) rec[3 * t + c] += 0.003f * (t % 10);  // errors 0 .. 0.027 (alpha 1)
  // 99th percentile 0.027 -> 1 / 0.027 = 37 -> largest 1/2/5 x 10^k below: 20.
  EXPECT_EQ(chooseErrorMagnification(ref.data(), rec.data(), texels, 1.0f), 20.0);
  // alpha scales the error down: alpha 2 -> 0.0135 -> 74 -> 50.
  EXPECT_EQ(chooseErrorMagnification(ref.data(), rec.data(), texels, 2.0f), 50.0);
  EXPECT_EQ(chooseErrorMagnification(ref.data(), ref.data(), texels, 1.0f), 1.0);
}

TEST(Figures, ComparisonShowsReferenceReconstructionAndError) {
  const int w = 8, h = 8;
  std::vector<float> ref(w * h * 3, 0.2f), rec(ref);
  rec[0] = rec[1] = rec[2] = 0.3f;  // one texel off by 0.1
  Image8 img = renderComparison(ref.data(), rec.data(), w, h, 1.0f, 10, "title");
  // The reference grey (sRGB of 0.2) is on screen, and so is the saturated error colour
  // (0.1 x 10 = full scale) of the broken texel.
  std::uint8_t g = linearToSrgb8(0.2f);
  int x, y, ex, ey;
  ASSERT_TRUE(find(img, {g, g, g}, x, y));
  ASSERT_TRUE(find(img, viridis(1.0), ex, ey));
  EXPECT_GT(ex, img.width / 2) << "error panel is on the right";
  EXPECT_GE(img.width, 3 * 240);
}

TEST(Figures, LineChartRejectsMismatchedSeries) {
  ChartSeries s{"a", {0, 15}, {0.1}, kBlack, {}};
  test::expectErrorContaining([&] { renderLineChart({s}, "t", "x", "y"); }, {"series 'a'"});
  s.y.push_back(0.2);
  Image8 img = renderLineChart({s}, "t", "x", "y", ChartAxes{{0, 15}, false, ""});
  EXPECT_GT(img.width, 500);
}

// The rate-distortion plots' axis: log10 x, ticks at powers of 10, a point at 10^3 drawn a
// third of the way from 10^2 to 10^5; x <= 0 and mislabelled series are errors.
TEST(Figures, LineChartLogAxisPlacesPointsByDecade) {
  const Color8 pure{255, 0, 0};
  ChartSeries s{"a", {100, 1000, 100000}, {0.1, 0.1, 0.1}, pure, {}};
  ChartAxes axes;
  axes.logX = true;
  Image8 img = renderLineChart({s}, "t", "x", "y", axes);
  // The row through the points has the most red (the line); 3 rows above it only the round
  // markers are red: three runs, whose centres are the points.
  const std::vector<double> centres = runCentres(img, pure, rowWithMost(img, pure) - 3);
  ASSERT_EQ(centres.size(), 3u);
  // Linear in log10: 10^3 lies 1/3 of the way from 10^2 to 10^5 (on a linear axis, 1%).
  EXPECT_NEAR((centres[1] - centres[0]) / (centres[2] - centres[0]), 1.0 / 3.0, 0.01);
  s.x[0] = 0;
  test::expectErrorContaining([&] { renderLineChart({s}, "t", "x", "y", axes); }, {"series 'a'", "log axis"});
  s.x[0] = 100;
  s.labels = {"k=1"};
  test::expectErrorContaining([&] { renderLineChart({s}, "t", "x", "y", axes); }, {"1 labels for 3 points"});
}

// The legend goes to a corner that hides no point: here the points fill the top right (where
// the legend used to be), and all three stay visible. A label at the right edge is written
// left of its point, inside the image.
TEST(Figures, LineChartLegendAndLabelsLeaveThePointsVisible) {
  const Color8 pure{255, 0, 0};
  ChartSeries s{"a series with a long name", {1, 8, 9, 10}, {0.1, 0.95, 0.95, 0.95}, pure, {"", "", "", "k=2000"}};
  Image8 img = renderLineChart({s}, "t", "x", "y");
  const int lineRow = rowWithMost(img, pure);
  // In the right half: the legend's own marker may share the rows.
  const std::vector<double> centres = runCentres(img, pure, lineRow + 3, img.width / 2);
  ASSERT_EQ(centres.size(), 3u) << "each point of the top line keeps its marker";
  // The last point's label: red text above it, to its left, none to its right.
  auto redIn = [&](int x0, int x1) {
    int n = 0;
    for (int y = std::max(0, lineRow - 18); y <= lineRow - 6; ++y)
      for (int x = std::max(0, x0); x <= std::min(img.width - 1, x1); ++x) n += same(pixel(img, x, y), pure);
    return n;
  };
  const int last = static_cast<int>(centres[2]);
  EXPECT_GT(redIn(last - 60, last - 6), 0);
  EXPECT_EQ(redIn(last + 6, img.width - 1), 0);
}

// Two labelled points close together: the second label finds a place off the first, so
// adding the blue point leaves every reddish pixel of the chart (the red label's smoothed
// strokes included) as it was. A grey line along the top fixes the axes.
TEST(Figures, LineChartLabelsDoNotCoverEachOther) {
  const Color8 red{255, 0, 0}, blue{0, 0, 255};
  ChartSeries axes{"axes", {1, 10}, {1.0, 1.0}, Color8{128, 128, 128}, {}};
  ChartSeries a{"a", {5}, {0.3}, red, {"k=1000"}};
  ChartSeries b{"b", {5.5}, {0.3}, blue, {"k=500"}};
  auto count = [&](const Image8& img) {
    int n = 0;
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x) {
        const Color8 p = pixel(img, x, y);
        n += p.r >= 128 && p.g < 96 && p.b < 96;
      }
    return n;
  };
  const int alone = count(renderLineChart({axes, a}, "t", "x", "y"));
  EXPECT_EQ(count(renderLineChart({axes, a, b}, "t", "x", "y")), alone);
}

// Values in a narrow band high above 0 fill the plot's height, as values from 0 to the same
// top do: the y axis starts at a round value below them, not at 0.
TEST(Figures, LineChartNarrowBandFillsThePlot) {
  const Color8 red{255, 0, 0};
  auto redRows = [&](const Image8& img) {
    int rows = 0;
    for (int y = 0; y < img.height; ++y) {
      bool any = false;
      for (int x = 0; x < img.width && !any; ++x) any = same(pixel(img, x, y), red);
      rows += any;
    }
    return rows;
  };
  const int band = redRows(renderLineChart({ChartSeries{"a", {1, 2}, {0.9, 1.0}, red, {}}}, "t", "x", "y"));
  const int full = redRows(renderLineChart({ChartSeries{"a", {1, 2}, {0.0, 1.0}, red, {}}}, "t", "x", "y"));
  EXPECT_NEAR(band, full, 2);
  // Below the upper half, the axis stays at 0: 0.4 to 1.0 spans 60% of what 0 to 1.0 does.
  const int low = redRows(renderLineChart({ChartSeries{"a", {1, 2}, {0.4, 1.0}, red, {}}}, "t", "x", "y"));
  EXPECT_LT(low, full - 50);
}

// The y ticks: evenly spaced, from 0 or (values in the upper half) from a round value at or
// below the smallest, up to at least the largest.
TEST(Figures, LineChartYTicksAreEvenAndCoverTheValues) {
  const std::pair<double, double> ranges[] = {{0.0417, 0.0475}, {0.0466, 0.0510}, {0.9, 1.0}, {0.1, 1.0},
                                              {0.0, 0.08}, {0.02, 0.02}, {0.0, 0.0}, {123.4, 125.0}};
  for (const auto& [lo, hi] : ranges) {
    const std::vector<double> t = lineChartYTicks(lo, hi);
    ASSERT_GE(t.size(), 2u) << lo << " " << hi;
    const double step = t[1] - t[0];
    for (std::size_t i = 1; i < t.size(); ++i) EXPECT_NEAR(t[i] - t[i - 1], step, 1e-9 * step) << lo << " " << hi;
    EXPECT_LE(t.front(), lo) << lo << " " << hi;
    EXPECT_GE(t.back(), hi) << lo << " " << hi;
    if (lo > 0.5 * hi && hi > lo)
      EXPECT_GT(t.front(), 0) << lo << " " << hi;
    else
      EXPECT_EQ(t.front(), 0) << lo << " " << hi;
  }
}

// When every corner of the plot holds a point, the legend goes below it: the image grows by
// the legend's height instead of covering data.
TEST(Figures, LineChartLegendGoesBelowWhenEveryCornerHoldsData) {
  ChartSeries top{"top", {1, 10}, {0.95, 0.95}, Color8{255, 0, 0}, {}};
  ChartSeries low{"bottom", {1, 10}, {0.05, 0.05}, Color8{0, 0, 255}, {}};
  const Image8 corners = renderLineChart({top, low}, "t", "x", "y");
  top.x.push_back(20);  // the lines end left of x = 20: the right-hand corners are free
  top.y.push_back(0);
  const Image8 free = renderLineChart({top, low}, "t", "x", "y");
  EXPECT_EQ(corners.width, free.width);
  EXPECT_EQ(corners.height, free.height + 20 * 2 + 6 + 8);
}

// The cluster map: texels of one generation share a hue, generations differ, clusters differ
// in shade; bad sizes are errors.
TEST(Figures, ClusterMapColoursTexelsByGeneration) {
  // 4 x 2 texels: left half cluster 0 (generation 0), right half clusters 1 and 2 (generation 1).
  std::vector<std::int32_t> ids = {0, 0, 1, 2, 0, 0, 1, 2};
  Image8 img = renderClusterMap(ids, 4, 2, 3, {0, 1, 1}, "map");
  ASSERT_GT(img.width, 320);
  // The map is scaled up and drawn at (16, 40): sample texel centres.
  const int scale = 320 / 4;
  auto at = [&](int tx, int ty) { return pixel(img, 16 + tx * scale + scale / 2, 40 + ty * scale + scale / 2); };
  EXPECT_TRUE(same(at(0, 0), at(1, 1)));    // one cluster, one colour
  EXPECT_FALSE(same(at(0, 0), at(2, 0)));   // another generation
  EXPECT_FALSE(same(at(2, 0), at(3, 0)));   // same generation, another cluster: another shade
  Color8 a = at(2, 0), b = at(3, 0);        // the same hue: channels in the same order
  EXPECT_EQ(a.r > a.b, b.r > b.b);
  EXPECT_THROW(renderClusterMap(ids, 3, 2, 3, {}, "map"), Error);
  EXPECT_THROW(renderClusterMap(ids, 4, 2, 2, {}, "map"), Error);      // id 2 out of range
  EXPECT_THROW(renderClusterMap(ids, 4, 2, 3, {0, 1}, "map"), Error);  // one generation per cluster
}

}  // namespace
}  // namespace nbtf
