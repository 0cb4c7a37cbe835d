// The report's figures, drawn with eval/canvas.h: the light x view RMSE heat map with a
// colour bar, line charts (RMSE by elevation), and reference | reconstruction | magnified
// error comparison strips. Every figure carries its axis labels and units in the image.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "eval/canvas.h"
#include "util/directions.h"

namespace nbtf {

// ---- Heat map

// A cell outlined on the heat map (the compared direction pairs), with a short label.
struct HeatMapMark {
  int row = 0, col = 0;
  std::string label;
};

struct HeatMapLabels {
  std::string title, rowAxis, colAxis, colorBar;
};

// values: rows x cols, row-major (rows = lights, cols = views). Rows and columns are
// grouped into elevation rings (theta rounded to whole degrees), separated by thin lines
// and labelled with the ring's theta. The colour scale runs from 0 to the largest value.
// Throws nbtf::Error if the sizes disagree or a value is not finite.
Image8 renderDirectionHeatMap(const std::vector<double>& values, const std::vector<Direction>& rows,
                              const std::vector<Direction>& cols, const HeatMapLabels& labels,
                              const std::vector<HeatMapMark>& marks = {});

// ---- Line chart

struct ChartSeries {
  std::string name;
  std::vector<double> x, y;
  Color8 color;
  std::vector<std::string> labels;  // optional: one per point, written beside it (e.g. "k=500")
};

struct ChartAxes {
  std::vector<double> xTicks;  // where given (else nice ticks, or powers of 10 on a log axis)
  bool logX = false;           // log10 x axis (every x must be > 0)
  std::string xTickPrefix;     // before every x tick label (e.g. "1:" for ratios)
};

// y axis from 0 (from a round value below the smallest where every value lies in the upper
// half of that range); the legend in the first corner of the plot that hides no point or line (top
// right, top left, bottom right, bottom left), or below the plot when each would; point labels
// above right of their point, or where they hide no marker or other label and stay inside the
// image. The one plotting path of nbtf: report figures and the sweep's
// rate-distortion plots (no external program).
Image8 renderLineChart(const std::vector<ChartSeries>& series, const std::string& title, const std::string& xLabel,
                       const std::string& yLabel, const ChartAxes& axes = {});
// The y ticks of a line chart whose values span [ymin, ymax]: evenly spaced, the first at
// or below ymin (0, or a round value below ymin where ymin > ymax / 2), the last at or above ymax.
std::vector<double> lineChartYTicks(double ymin, double ymax);

// ---- Comparison strip

// Magnification for the error panel: the largest 1, 2 or 5 x 10^k (at least 1) that keeps the
// 99th percentile of the per-texel error (mean over RGB of |ref - rec| / alpha) at or below
// full scale.
double chooseErrorMagnification(const float* reference, const float* reconstruction, int texels, float alpha);

// reference | reconstruction | error x magnification, side by side. Reference and
// reconstruction are shown as 8-bit sRGB of their linear values (clamped to [0, 1], as the
// source images are stored); the error panel maps magnification x (mean over RGB of
// |ref - rec| / alpha) through viridis, with a colour bar in unmagnified units.
Image8 renderComparison(const float* reference, const float* reconstruction, int width, int height, float alpha,
                        double magnification, const std::string& title);

// ---- Cluster map

// The label image of a clustered material (ids: width x height, row-major), each texel in
// the colour of its cluster's split generation (generation[c]; empty = all 0, a fixed-k
// file), every cluster a slightly different shade of it so the boundaries show; with a
// legend of the generations and their cluster counts. Throws nbtf::Error on bad sizes.
Image8 renderClusterMap(const std::vector<std::int32_t>& ids, int width, int height, int clusters,
                        const std::vector<int>& generation, const std::string& title);

}  // namespace nbtf
