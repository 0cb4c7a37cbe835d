#include "eval/figures.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "io/color.h"
#include "util/error.h"

namespace nbtf {
namespace {

constexpr Color8 kMarkColor{230, 40, 40};

// Consecutive runs of directions on one elevation ring: [begin, end) index ranges.
struct Ring {
  int begin, end;
  long theta;
};
std::vector<Ring> ringsOf(const std::vector<Direction>& dirs) {
  std::vector<Ring> rings;
  for (int i = 0; i < static_cast<int>(dirs.size()); ++i) {
    long t = std::lround(dirs[static_cast<std::size_t>(i)].thetaDeg);
    if (rings.empty() || rings.back().theta != t) rings.push_back({i, i + 1, t});
    else rings.back().end = i + 1;
  }
  return rings;
}

std::string degrees(long theta) { return std::to_string(theta) + "\xC2\xB0"; }

// A vertical colour bar from 0 (bottom) to vmax (top) with ticks and a rotated label.
void drawColorBar(Canvas& c, int x, int y, int w, int h, double vmax, const std::string& label) {
  for (int r = 0; r < h; ++r) c.fillRect(x, y + r, w, 1, viridis(1.0 - static_cast<double>(r) / std::max(1, h - 1)));
  c.strokeRect(x, y, w, h, kGrey);
  auto ticks = niceTicks(0, vmax, 6);
  double step = ticks.size() > 1 ? ticks[1] - ticks[0] : vmax;
  int labelRight = x + w;
  for (double t : ticks) {
    int ty = y + h - 1 - static_cast<int>(std::lround(t / vmax * (h - 1)));
    c.line(x + w, ty, x + w + 5, ty, kBlack);
    std::string s = formatTick(t, step);
    c.text(s, x + w + 8, ty, 10, kBlack);
    labelRight = std::max(labelRight, x + w + 8 + c.textWidth(s, 10));
  }
  c.text(label, labelRight + 16, y + h / 2, 11, kBlack, Align::Center, true);
}

}  // namespace

// ---- Heat map

Image8 renderDirectionHeatMap(const std::vector<double>& values, const std::vector<Direction>& rows,
                              const std::vector<Direction>& cols, const HeatMapLabels& labels,
                              const std::vector<HeatMapMark>& marks) {
  const int nr = static_cast<int>(rows.size()), nc = static_cast<int>(cols.size());
  if (nr == 0 || nc == 0 || values.size() != static_cast<std::size_t>(nr) * nc)
    throw Error("heat map: " + std::to_string(values.size()) + " values for " + std::to_string(nr) + " x " +
                std::to_string(nc) + " cells");
  double vmax = 0;
  for (double v : values) {
    if (!std::isfinite(v)) throw Error("heat map: a value is not finite");
    vmax = std::max(vmax, v);
  }
  if (vmax <= 0) vmax = 1;  // all zero: any scale shows it as the bottom colour

  const int cell = std::max(2, std::min(48, 648 / std::max(nr, nc)));
  const int gridW = nc * cell, gridH = nr * cell;
  const int left = 110, top = 56, right = 150, bottom = 78;
  Canvas c(left + gridW + right, top + gridH + bottom);
  c.text(labels.title, left + gridW / 2, 22, 14, kBlack, Align::Center);

  for (int r = 0; r < nr; ++r)
    for (int k = 0; k < nc; ++k)
      c.fillRect(left + k * cell, top + r * cell, cell, cell, viridis(values[static_cast<std::size_t>(r) * nc + k] / vmax));

  // Ring separators and tick labels (skipped where they would overlap the previous one).
  auto colRings = ringsOf(cols), rowRings = ringsOf(rows);
  int lastRight = -1000;
  for (const auto& ring : colRings) {
    if (ring.begin > 0) c.line(left + ring.begin * cell, top, left + ring.begin * cell, top + gridH, kWhite);
    int cx = left + (ring.begin + ring.end) * cell / 2;
    std::string s = degrees(ring.theta);
    int w = c.textWidth(s, 10);
    c.line(cx, top + gridH, cx, top + gridH + 4, kBlack);
    if (cx - w / 2 > lastRight + 4) {
      c.text(s, cx, top + gridH + 14, 10, kBlack, Align::Center);
      lastRight = cx + w / 2;
    }
  }
  int lastBottom = -1000;
  for (const auto& ring : rowRings) {
    if (ring.begin > 0) c.line(left, top + ring.begin * cell, left + gridW, top + ring.begin * cell, kWhite);
    int cy = top + (ring.begin + ring.end) * cell / 2;
    c.line(left - 4, cy, left, cy, kBlack);
    if (cy - 6 > lastBottom + 2) {
      c.text(degrees(ring.theta), left - 8, cy, 10, kBlack, Align::Right);
      lastBottom = cy + 6;
    }
  }
  c.strokeRect(left - 1, top - 1, gridW + 2, gridH + 2, kGrey);
  c.text(labels.colAxis, left + gridW / 2, top + gridH + 38, 11, kBlack, Align::Center);
  c.text("(rings by elevation theta; azimuth phi ascending within a ring)", left + gridW / 2, top + gridH + 58, 9,
         kGrey, Align::Center);
  c.text(labels.rowAxis, 30, top + gridH / 2, 11, kBlack, Align::Center, true);

  // Marked cells: a ring around the cell and a label beside it.
  for (const auto& m : marks) {
    if (m.row < 0 || m.row >= nr || m.col < 0 || m.col >= nc) continue;
    int x = left + m.col * cell, y = top + m.row * cell, pad = std::max(2, cell / 2);
    c.strokeRect(x - pad, y - pad, cell + 2 * pad, cell + 2 * pad, kWhite, 3);
    c.strokeRect(x - pad, y - pad, cell + 2 * pad, cell + 2 * pad, kMarkColor, 1);
    bool leftSide = x + cell + pad + 30 > left + gridW;
    int tx = leftSide ? x - pad - 3 : x + cell + pad + 3;
    int tw = c.textWidth(m.label, 10);
    int bx = leftSide ? tx - tw - 2 : tx - 2;
    c.fillRect(bx, y + cell / 2 - 8, tw + 4, 16, kWhite);
    c.text(m.label, tx, y + cell / 2, 10, kMarkColor, leftSide ? Align::Right : Align::Left);
  }

  drawColorBar(c, left + gridW + 24, top, 18, gridH, vmax, labels.colorBar);
  return c.release();
}

// ---- Line chart

std::vector<double> lineChartYTicks(double ymin, double ymax) {
  // From 0, unless every value lies in the upper half of that range: then from a round value
  // below the smallest, so that close values do not share a few pixels. The start is put on
  // the grid of the ticks it gives (a lower start can coarsen the step: redone).
  std::vector<double> ticks = niceTicks(0, ymax > 0 ? ymax : 1, 6);
  if (ymin > 0.5 * ymax && ymax > ymin) {
    auto stepOf = [&](const std::vector<double>& t) { return t.size() > 1 ? t[1] - t[0] : ymax - ymin; };
    double step = stepOf(niceTicks(ymin, ymax, 6)), low = 0;
    for (int pass = 0; pass < 4; ++pass) {
      low = std::floor(ymin / step + 1e-9) * step;
      ticks = niceTicks(low, ymax, 6);
      const double next = stepOf(ticks);
      if (std::abs(next - step) <= 1e-6 * step) break;  // low lies on the grid of its ticks
      step = next;
    }
    if (ticks.front() > low + 1e-6 * step) ticks.insert(ticks.begin(), low);
  }
  // One more step on top where the last tick is below the largest value.
  const double step = ticks.size() > 1 ? ticks[1] - ticks[0] : 1;
  if (ticks.back() < ymax) ticks.push_back(ticks.back() + step);
  return ticks;
}

namespace {

constexpr int kChartLeft = 86, kChartRight = 24, kChartTop = 50, kChartBottom = 62, kPlotW = 560, kPlotH = 300;

// Rectangles in pixels: the markers', the legend's candidates, the labels'.
struct Box {
  int x0, y0, x1, y1;
  bool overlaps(const Box& o) const { return x0 < o.x1 && o.x0 < x1 && y0 < o.y1 && o.y0 < y1; }
  bool holds(double x, double y) const { return x >= x0 && x <= x1 && y >= y0 && y <= y1; }
};

// The data's ranges and the plotted ranges, and the mapping between them and pixels. On a
// log axis everything works on log10 x; ticks and labels convert back.
struct ChartFrame {
  bool logX = false;
  double xmin = 1e300, xmax = -1e300, ymin = 1e300, ymax = 0;  // x in axis units
  double x0 = 0, x1 = 1, yLow = 0, y1 = 1;
  double toAxis(double x) const { return logX ? std::log10(x) : x; }
  int px(double x) const { return kChartLeft + static_cast<int>(std::lround((x - x0) / (x1 - x0) * kPlotW)); }
  int py(double y) const {
    return kChartTop + kPlotH - static_cast<int>(std::lround((y - yLow) / (y1 - yLow) * kPlotH));
  }
  int pointX(const ChartSeries& s, std::size_t i) const { return px(toAxis(s.x[i])); }
  int pointY(const ChartSeries& s, std::size_t i) const { return py(s.y[i]); }
};

// Checks every series and frames their points: x padded by 5% each side, y on `yTicks`.
ChartFrame frameChart(const std::vector<ChartSeries>& series, const ChartAxes& axes, std::vector<double>& yTicks) {
  ChartFrame f;
  f.logX = axes.logX;
  for (const auto& s : series) {
    if (s.x.size() != s.y.size()) throw Error("line chart: series '" + s.name + "' has unequal x and y counts");
    if (!s.labels.empty() && s.labels.size() != s.x.size())
      throw Error("line chart: series '" + s.name + "' has " + std::to_string(s.labels.size()) + " labels for " +
                  std::to_string(s.x.size()) + " points");
    for (std::size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) throw Error("line chart: a value is not finite");
      if (axes.logX && s.x[i] <= 0)
        throw Error("line chart: series '" + s.name + "' has x = " + std::to_string(s.x[i]) + " on a log axis");
      double x = f.toAxis(s.x[i]);
      f.xmin = std::min(f.xmin, x), f.xmax = std::max(f.xmax, x), f.ymin = std::min(f.ymin, s.y[i]),
      f.ymax = std::max(f.ymax, s.y[i]);
    }
  }
  if (f.xmin > f.xmax) f.xmin = 0, f.xmax = 1;
  if (f.xmax == f.xmin) f.xmin -= 1, f.xmax += 1;
  double pad = 0.05 * (f.xmax - f.xmin);
  f.x0 = f.xmin - pad, f.x1 = f.xmax + pad;
  yTicks = lineChartYTicks(f.ymin, f.ymax);
  f.yLow = yTicks.front(), f.y1 = yTicks.back();
  return f;
}

std::vector<Box> markerBoxes(const std::vector<ChartSeries>& series, const ChartFrame& f) {
  std::vector<Box> boxes;
  for (const auto& s : series)
    for (std::size_t i = 0; i < s.x.size(); ++i) {
      const int x = f.pointX(s, i), y = f.pointY(s, i);
      boxes.push_back({x - 4, y - 4, x + 5, y + 5});
    }
  return boxes;
}

struct LegendBox {
  int x, y, w, h;
  bool below;  // under the plot, the image grown to hold it
};

// Legend: in the first corner of the plot (top right, top left, bottom right, bottom left)
// that hides no point or stretch of line; below the plot when every corner would.
LegendBox placeLegend(const std::vector<ChartSeries>& series, const ChartFrame& f, const std::vector<Box>& markers) {
  const Canvas measure(1, 1);
  int legendW = 0;
  for (const auto& s : series) legendW = std::max(legendW, measure.textWidth(s.name, 10));
  const int boxW = legendW + 46, boxH = 20 * static_cast<int>(series.size()) + 6;
  auto hides = [&](int bx, int by) {
    const Box box{bx - 5, by - 5, bx + boxW + 5, by + boxH + 5};
    if (std::any_of(markers.begin(), markers.end(), [&](const Box& m) { return m.overlaps(box); })) return true;
    for (const auto& s : series)
      for (std::size_t i = 1; i < s.x.size(); ++i) {
        const double xa = f.pointX(s, i - 1), ya = f.pointY(s, i - 1), xb = f.pointX(s, i), yb = f.pointY(s, i);
        for (int step = 1; step < 16; ++step)
          if (box.holds(xa + (xb - xa) * step / 16, ya + (yb - ya) * step / 16)) return true;
      }
    return false;
  };
  const int inLeft = kChartLeft + 8, inRight = kChartLeft + kPlotW - boxW - 2, inTop = kChartTop + 4,
            inBottom = kChartTop + kPlotH - boxH - 4;
  const std::pair<int, int> corners[] = {{inRight, inTop}, {inLeft, inTop}, {inRight, inBottom}, {inLeft, inBottom}};
  for (const auto& [bx, by] : corners)
    if (!hides(bx, by)) return {bx, by, boxW, boxH, false};
  return {kChartLeft + (kPlotW - boxW) / 2, kChartTop + kPlotH + kChartBottom, boxW, boxH, true};
}

// Ticks (in axis units) and their labels (in data units).
void xAxisTicks(const ChartAxes& axes, const ChartFrame& f, std::vector<double>& xTicks,
                std::vector<std::string>& xTickText) {
  if (!axes.xTicks.empty()) {
    double step = axes.xTicks.size() > 1 ? axes.xTicks[1] - axes.xTicks[0] : 1;
    for (double t : axes.xTicks) xTicks.push_back(f.toAxis(t)), xTickText.push_back(formatTick(t, step));
  } else if (axes.logX) {
    // Powers of 10; with less than two decades also 2 and 5 times them.
    const bool fine = f.xmax - f.xmin < 2;
    for (int e = static_cast<int>(std::floor(f.x0)); e <= static_cast<int>(std::ceil(f.x1)); ++e)
      for (double m : fine ? std::vector<double>{1, 2, 5} : std::vector<double>{1}) {
        double t = std::log10(m) + e;
        if (t < f.x0 || t > f.x1) continue;
        xTicks.push_back(t);
        const double value = m * std::pow(10.0, e);
        xTickText.push_back(formatTick(value, value));
      }
  } else {
    xTicks = niceTicks(f.xmin, f.xmax, 8);
    double step = xTicks.size() > 1 ? xTicks[1] - xTicks[0] : 1;
    for (double t : xTicks) xTickText.push_back(formatTick(t, step));
  }
}

void drawChartAxes(Canvas& c, const ChartFrame& f, const ChartAxes& axes, const std::vector<double>& yTicks,
                   const std::string& xLabel, const std::string& yLabel) {
  const int left = kChartLeft, top = kChartTop, plotW = kPlotW, plotH = kPlotH;
  const double yStep = yTicks.size() > 1 ? yTicks[1] - yTicks[0] : 1;
  for (double t : yTicks) {
    c.line(left, f.py(t), left + plotW, f.py(t), kLightGrey);
    c.text(formatTick(t, yStep), left - 8, f.py(t), 10, kBlack, Align::Right);
  }
  std::vector<double> xTicks;
  std::vector<std::string> xTickText;
  xAxisTicks(axes, f, xTicks, xTickText);
  for (std::size_t i = 0; i < xTicks.size(); ++i) {
    const double t = xTicks[i];
    if (axes.logX) c.line(f.px(t), top, f.px(t), top + plotH, kLightGrey);
    c.line(f.px(t), top + plotH, f.px(t), top + plotH + 5, kBlack);
    c.text(axes.xTickPrefix + xTickText[i], f.px(t), top + plotH + 16, 10, kBlack, Align::Center);
  }
  c.line(left, top, left, top + plotH, kBlack);
  c.line(left, top + plotH, left + plotW, top + plotH, kBlack);
  c.text(xLabel, left + plotW / 2, top + plotH + 42, 11, kBlack, Align::Center);
  c.text(yLabel, 22, top + plotH / 2, 11, kBlack, Align::Center, true);
}

void drawSeries(Canvas& c, const std::vector<ChartSeries>& series, const ChartFrame& f) {
  for (const auto& s : series) {
    for (std::size_t i = 1; i < s.x.size(); ++i)
      c.line(f.pointX(s, i - 1), f.pointY(s, i - 1), f.pointX(s, i), f.pointY(s, i), s.color, 2);
    for (std::size_t i = 0; i < s.x.size(); ++i) c.circle(f.pointX(s, i), f.pointY(s, i), 4, s.color);
  }
}

// Labels: above right of the point, else above left, below right, below left: the first
// place right of the y axis and inside the image that no marker or earlier label holds (else
// the first such place). Each label placed joins `taken`.
void drawPointLabels(Canvas& c, const std::vector<ChartSeries>& series, const ChartFrame& f, std::vector<Box>& taken) {
  const Box image{kChartLeft + 2, 0, kChartLeft + kPlotW + kChartRight, kChartTop + kPlotH + kChartBottom};
  for (const auto& s : series)
    for (std::size_t i = 0; i < s.labels.size(); ++i) {
      if (s.labels[i].empty()) continue;
      const int x = f.pointX(s, i), y = f.pointY(s, i), w = c.textWidth(s.labels[i], 9);
      const std::pair<int, int> offsets[] = {{6, -10}, {-6 - w, -10}, {6, 12}, {-6 - w, 12}};
      int chosen = -1;
      for (int k = 0; k < 4; ++k) {
        const Box b{x + offsets[k].first, y + offsets[k].second - 6, x + offsets[k].first + w, y + offsets[k].second + 6};
        if (b.x0 < image.x0 || b.x1 > image.x1 - 2 || b.y0 < image.y0 || b.y1 > image.y1) continue;
        if (chosen < 0) chosen = k;
        if (std::none_of(taken.begin(), taken.end(), [&](const Box& t) { return t.overlaps(b); })) {
          chosen = k;
          break;
        }
      }
      if (chosen < 0) chosen = 0;
      const int lx0 = x + offsets[chosen].first, ly0 = y + offsets[chosen].second;
      taken.push_back({lx0, ly0 - 6, lx0 + w, ly0 + 6});
      c.text(s.labels[i], lx0, ly0, 9, s.color, Align::Left);
    }
}

void drawLegend(Canvas& c, const std::vector<ChartSeries>& series, const LegendBox& box) {
  const int lx = box.x + 6, ly = box.y + 4;
  c.fillRect(box.x, box.y, box.w, box.h, kWhite);
  c.strokeRect(box.x, box.y, box.w, box.h, kLightGrey);
  for (std::size_t i = 0; i < series.size(); ++i) {
    int yy = ly + 8 + 20 * static_cast<int>(i);
    c.line(lx, yy, lx + 24, yy, series[i].color, 2);
    c.circle(lx + 12, yy, 4, series[i].color);
    c.text(series[i].name, lx + 32, yy, 10, kBlack);
  }
}

}  // namespace

Image8 renderLineChart(const std::vector<ChartSeries>& series, const std::string& title, const std::string& xLabel,
                       const std::string& yLabel, const ChartAxes& axes) {
  std::vector<double> yTicks;
  const ChartFrame frame = frameChart(series, axes, yTicks);
  std::vector<Box> taken = markerBoxes(series, frame);  // the markers, then each label as it is placed
  const LegendBox legend = placeLegend(series, frame, taken);
  Canvas c(kChartLeft + kPlotW + kChartRight, kChartTop + kPlotH + kChartBottom + (legend.below ? legend.h + 8 : 0));
  c.text(title, kChartLeft + kPlotW / 2, 22, 14, kBlack, Align::Center);
  drawChartAxes(c, frame, axes, yTicks, xLabel, yLabel);
  drawSeries(c, series, frame);
  drawPointLabels(c, series, frame, taken);
  drawLegend(c, series, legend);
  return c.release();
}

// ---- Comparison strip

namespace {
std::vector<double> texelErrors(const float* ref, const float* rec, int texels, float alpha) {
  std::vector<double> e(static_cast<std::size_t>(texels));
  for (int t = 0; t < texels; ++t) {
    double s = 0;
    for (int ch = 0; ch < 3; ++ch) s += std::abs(static_cast<double>(ref[3 * t + ch]) - rec[3 * t + ch]);
    e[static_cast<std::size_t>(t)] = s / 3 / alpha;
  }
  return e;
}

Image8 srgbImage(const float* rgb, int w, int h) {
  Image8 img;
  img.width = w, img.height = h;
  img.rgb.resize(static_cast<std::size_t>(w) * h * 3);
  for (std::size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = linearToSrgb8(rgb[i]);
  return img;
}

std::string formatFactor(double m) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", m);
  return buf;
}
}  // namespace

double chooseErrorMagnification(const float* reference, const float* reconstruction, int texels, float alpha) {
  if (texels <= 0) return 1;
  auto e = texelErrors(reference, reconstruction, texels, alpha);
  std::size_t k = static_cast<std::size_t>(std::floor(0.99 * (e.size() - 1)));
  std::nth_element(e.begin(), e.begin() + static_cast<long>(k), e.end());
  double p99 = e[k];
  if (!(p99 > 0)) return 1;
  double best = 1;
  for (double mag = 1; mag <= 1e7; mag *= 10)
    for (double f : {1.0, 2.0, 5.0})
      if (f * mag * p99 <= 1.0) best = std::max(best, f * mag);
  return best;
}

Image8 renderComparison(const float* reference, const float* reconstruction, int width, int height, float alpha,
                        double magnification, const std::string& title) {
  const int texels = width * height;
  Image8 ref = displayScale(srgbImage(reference, width, height), 240, 360);
  Image8 rec = displayScale(srgbImage(reconstruction, width, height), 240, 360);
  auto e = texelErrors(reference, reconstruction, texels, alpha);
  Image8 err;
  err.width = width, err.height = height;
  err.rgb.resize(static_cast<std::size_t>(texels) * 3);
  for (int t = 0; t < texels; ++t) {
    Color8 col = viridis(e[static_cast<std::size_t>(t)] * magnification);
    err.rgb[3 * t] = col.r, err.rgb[3 * t + 1] = col.g, err.rgb[3 * t + 2] = col.b;
  }
  err = displayScale(err, 240, 360);

  const int gap = 18, margin = 16, pw = ref.width, ph = ref.height;
  const int top = 58, barH = 12;
  Canvas c(2 * margin + 3 * pw + 2 * gap, top + ph + 76);
  c.text(title, c.width() / 2, 18, 13, kBlack, Align::Center);
  const char* names[] = {"reference", "reconstruction", nullptr};
  std::string errName = "|error| x " + formatFactor(magnification);
  for (int i = 0; i < 3; ++i) {
    int x = margin + i * (pw + gap);
    c.text(names[i] ? names[i] : errName, x + pw / 2, top - 14, 12, kBlack, Align::Center);
    c.blit(i == 0 ? ref : i == 1 ? rec : err, x, top);
    c.strokeRect(x - 1, top - 1, pw + 2, ph + 2, kGrey);
  }
  // Colour bar under the error panel, in unmagnified units: 0 .. 1 / magnification.
  int bx = margin + 2 * (pw + gap), by = top + ph + 10;
  for (int i = 0; i < pw; ++i) c.fillRect(bx + i, by, 1, barH, viridis(static_cast<double>(i) / std::max(1, pw - 1)));
  c.strokeRect(bx, by, pw, barH, kGrey);
  double full = 1.0 / magnification;
  auto ticks = niceTicks(0, full, 4);
  double step = ticks.size() > 1 ? ticks[1] - ticks[0] : full;
  for (double t : ticks) {
    int tx = bx + static_cast<int>(std::lround(t / full * (pw - 1)));
    c.line(tx, by + barH, tx, by + barH + 4, kBlack);
    c.text(formatTick(t, step), tx, by + barH + 13, 9, kBlack, Align::Center);
  }
  c.text("mean over RGB of |ref - rec| / alpha (linear); bar in unmagnified units", bx + pw, by + barH + 32, 9, kGrey,
         Align::Right);
  c.text("shown as 8-bit sRGB of the linear values", margin, top + ph + 16, 9, kGrey);
  return c.release();
}

Image8 renderClusterMap(const std::vector<std::int32_t>& ids, int width, int height, int clusters,
                        const std::vector<int>& generation, const std::string& title) {
  const int texels = width * height;
  if (width < 1 || height < 1 || static_cast<int>(ids.size()) != texels || clusters < 1 ||
      (!generation.empty() && static_cast<int>(generation.size()) != clusters))
    throw Error("cluster map: " + std::to_string(ids.size()) + " ids for " + std::to_string(width) + " x " +
                std::to_string(height) + " texels, " + std::to_string(clusters) + " clusters, " +
                std::to_string(generation.size()) + " generations");
  // Generations: a qualitative palette (Tableau 10).
  static const Color8 palette[] = {{78, 121, 167}, {242, 142, 43}, {225, 87, 89},  {118, 183, 178}, {89, 161, 79},
                                   {237, 201, 72}, {176, 122, 161}, {255, 157, 167}, {156, 117, 95}, {186, 176, 172}};
  auto genOf = [&](int c) { return generation.empty() ? 0 : std::max(0, generation[c]); };
  int maxGen = 0;
  std::vector<int> perGen(1, 0);
  for (int c = 0; c < clusters; ++c) {
    const int g = genOf(c);
    maxGen = std::max(maxGen, g);
    if (static_cast<int>(perGen.size()) <= g) perGen.resize(g + 1, 0);
    ++perGen[g];
  }
  Image8 map;
  map.width = width, map.height = height;
  map.rgb.resize(static_cast<std::size_t>(texels) * 3);
  for (int t = 0; t < texels; ++t) {
    const int c = ids[t];
    if (c < 0 || c >= clusters) throw Error("cluster map: texel " + std::to_string(t) + " has cluster id " +
                                            std::to_string(c) + ", expected 0.." + std::to_string(clusters - 1));
    const Color8 base = palette[genOf(c) % 10];
    // A shade per cluster: 0.7 .. 1.15 of the generation's colour, from a hash of the id.
    const std::uint32_t h = static_cast<std::uint32_t>(c) * 2654435761u;
    const double shade = 0.7 + 0.45 * ((h >> 24) / 255.0);
    auto channel = [&](std::uint8_t v) { return static_cast<std::uint8_t>(std::min(255.0, v * shade)); };
    map.rgb[3 * t] = channel(base.r), map.rgb[3 * t + 1] = channel(base.g), map.rgb[3 * t + 2] = channel(base.b);
  }
  Image8 shown = displayScale(map, 320, 480);
  const int margin = 16, top = 40, legendW = 190;
  Canvas c(2 * margin + shown.width + legendW, std::max(top + shown.height + 30, top + 24 * (maxGen + 2)));
  c.text(title, c.width() / 2, 18, 13, kBlack, Align::Center);
  c.blit(shown, margin, top);
  c.strokeRect(margin - 1, top - 1, shown.width + 2, shown.height + 2, kGrey);
  const int lx = margin + shown.width + 20;
  c.text("split generation", lx, top + 6, 11);
  for (int g = 0; g <= maxGen; ++g) {
    const int y = top + 26 + 22 * g;
    c.fillRect(lx, y - 7, 14, 14, palette[g % 10]);
    c.strokeRect(lx, y - 7, 14, 14, kGrey);
    c.text(std::to_string(g) + (g == 0 ? " (initial)" : "") + ": " + std::to_string(perGen[g]) + " clusters", lx + 22, y,
           10);
  }
  c.text("k = " + std::to_string(clusters) + "; shades tell clusters apart", margin, top + shown.height + 16, 9, kGrey);
  return c.release();
}

}  // namespace nbtf
