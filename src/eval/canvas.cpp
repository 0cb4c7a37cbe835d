#include "eval/canvas.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "util/error.h"

namespace nbtf {
namespace {

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
const std::string kDegree = "\xC2\xB0";

cv::Mat wrap(Image8& img) { return cv::Mat(img.height, img.width, CV_8UC3, img.rgb.data()); }
cv::Scalar scalar(Color8 c) { return cv::Scalar(c.r, c.g, c.b); }

double fontScale(int size) {
  static const int capHeight = [] {
    int base = 0;
    return cv::getTextSize("H", kFont, 1.0, 1, &base).height;
  }();
  return static_cast<double>(size) / capHeight;
}
int thicknessFor(int size) { return size >= 15 ? 2 : 1; }

// Splits at degree signs: the text pieces between them.
std::vector<std::string> splitDegrees(const std::string& text) {
  std::vector<std::string> parts;
  std::size_t start = 0;
  for (std::size_t p; (p = text.find(kDegree, start)) != std::string::npos; start = p + kDegree.size())
    parts.push_back(text.substr(start, p - start));
  parts.push_back(text.substr(start));
  return parts;
}
int degreeAdvance(int size) { return std::max(4, size * 2 / 3); }

}  // namespace

Canvas::Canvas(int width, int height, Color8 background) {
  if (width <= 0 || height <= 0) throw Error("canvas: size must be positive");
  image_.width = width, image_.height = height;
  image_.rgb.resize(static_cast<std::size_t>(width) * height * 3);
  for (std::size_t i = 0; i < image_.rgb.size(); i += 3)
    image_.rgb[i] = background.r, image_.rgb[i + 1] = background.g, image_.rgb[i + 2] = background.b;
}

void Canvas::fillRect(int x, int y, int w, int h, Color8 color) {
  if (w <= 0 || h <= 0) return;
  cv::Mat m = wrap(image_);
  cv::rectangle(m, cv::Rect(x, y, w, h), scalar(color), cv::FILLED);
}

void Canvas::strokeRect(int x, int y, int w, int h, Color8 color, int thickness) {
  cv::Mat m = wrap(image_);
  cv::rectangle(m, cv::Rect(x, y, w, h), scalar(color), thickness, cv::LINE_8);
}

void Canvas::line(int x0, int y0, int x1, int y1, Color8 color, int thickness) {
  cv::Mat m = wrap(image_);
  cv::line(m, {x0, y0}, {x1, y1}, scalar(color), thickness, cv::LINE_AA);
}

void Canvas::circle(int cx, int cy, int radius, Color8 color, bool filled) {
  cv::Mat m = wrap(image_);
  cv::circle(m, {cx, cy}, radius, scalar(color), filled ? cv::FILLED : 1, cv::LINE_AA);
}

int Canvas::textWidth(const std::string& text, int size) const {
  auto parts = splitDegrees(text);
  int width = 0, base = 0;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    if (!parts[i].empty()) width += cv::getTextSize(parts[i], kFont, fontScale(size), thicknessFor(size), &base).width;
    if (i + 1 < parts.size()) width += degreeAdvance(size);
  }
  return width;
}

void Canvas::text(const std::string& text, int x, int y, int size, Color8 color, Align align, bool vertical) {
  if (vertical) {
    // Draw horizontally on a scratch canvas, rotate, and copy the inked pixels.
    int w = textWidth(text, size) + 4, h = size * 2 + 4;
    Canvas scratch(w, h, kWhite);
    scratch.text(text, 2, h / 2, size, kBlack);
    cv::Mat src = wrap(scratch.image_), rotated;
    cv::rotate(src, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
    int left = x - rotated.cols / 2, top = y - rotated.rows / 2;
    for (int r = 0; r < rotated.rows; ++r)
      for (int c = 0; c < rotated.cols; ++c) {
        int px = left + c, py = top + r;
        if (px < 0 || py < 0 || px >= width() || py >= height()) continue;
        // Ink coverage from the white scratch background, blended onto this canvas.
        double a = 1.0 - rotated.at<cv::Vec3b>(r, c)[0] / 255.0;
        if (a <= 0) continue;
        std::uint8_t* p = &image_.rgb[(static_cast<std::size_t>(py) * width() + px) * 3];
        p[0] = static_cast<std::uint8_t>(std::lround(p[0] * (1 - a) + color.r * a));
        p[1] = static_cast<std::uint8_t>(std::lround(p[1] * (1 - a) + color.g * a));
        p[2] = static_cast<std::uint8_t>(std::lround(p[2] * (1 - a) + color.b * a));
      }
    return;
  }
  int width = textWidth(text, size);
  int left = align == Align::Left ? x : align == Align::Center ? x - width / 2 : x - width;
  int baseline = y + size / 2;
  cv::Mat m = wrap(image_);
  auto parts = splitDegrees(text);
  int base = 0;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    if (!parts[i].empty()) {
      cv::putText(m, parts[i], {left, baseline}, kFont, fontScale(size), scalar(color), thicknessFor(size), cv::LINE_AA);
      left += cv::getTextSize(parts[i], kFont, fontScale(size), thicknessFor(size), &base).width;
    }
    if (i + 1 < parts.size()) {
      int r = std::max(1, size / 5);
      cv::circle(m, {left + r + 1, baseline - size + r}, r, scalar(color), 1, cv::LINE_AA);
      left += degreeAdvance(size);
    }
  }
}

void Canvas::blit(const Image8& img, int x, int y) {
  for (int r = 0; r < img.height; ++r) {
    int py = y + r;
    if (py < 0 || py >= height()) continue;
    for (int c = 0; c < img.width; ++c) {
      int px = x + c;
      if (px < 0 || px >= width()) continue;
      const std::uint8_t* s = &img.rgb[(static_cast<std::size_t>(r) * img.width + c) * 3];
      std::uint8_t* d = &image_.rgb[(static_cast<std::size_t>(py) * width() + px) * 3];
      d[0] = s[0], d[1] = s[1], d[2] = s[2];
    }
  }
}

// ---- Colour map

Color8 viridis(double t) {
  // OpenCV's COLORMAP_VIRIDIS table (BGR), read once into RGB.
  static const std::vector<Color8> table = [] {
    cv::Mat ramp(1, 256, CV_8UC1), colored;
    for (int i = 0; i < 256; ++i) ramp.at<std::uint8_t>(0, i) = static_cast<std::uint8_t>(i);
    cv::applyColorMap(ramp, colored, cv::COLORMAP_VIRIDIS);
    std::vector<Color8> out(256);
    for (int i = 0; i < 256; ++i) {
      auto bgr = colored.at<cv::Vec3b>(0, i);
      out[i] = {bgr[2], bgr[1], bgr[0]};
    }
    return out;
  }();
  if (!(t > 0)) t = 0;  // NaN -> 0
  if (t > 1) t = 1;
  return table[static_cast<std::size_t>(std::lround(t * 255))];
}

// ---- Ticks

std::vector<double> niceTicks(double lo, double hi, int maxTicks) {
  if (!(hi > lo)) return {lo};
  maxTicks = std::max(2, maxTicks);
  // The finest 1, 2, 5 x 10^k step that needs no more than maxTicks ticks.
  double base = std::pow(10.0, std::floor(std::log10((hi - lo) / maxTicks)));
  double step = base;
  for (double f : {1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0}) {
    step = f * base;
    double count = std::floor(hi / step + 1e-9) - std::ceil(lo / step - 1e-9) + 1;
    if (count <= maxTicks) break;
  }
  std::vector<double> ticks;
  double first = std::ceil(lo / step - 1e-9);
  double last = std::floor(hi / step + 1e-9);
  for (double k = first; k <= last; ++k) ticks.push_back(k == 0 ? 0.0 : k * step);
  return ticks;
}

std::string formatTick(double value, double step) {
  int decimals = step > 0 ? std::max(0, static_cast<int>(std::ceil(-std::log10(step) - 1e-9))) : 3;
  // niceTicks steps are 1, 2 or 5 x 10^k, so the step's own decimals are enough.
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", std::min(decimals, 10), value);
  return buf;
}

// ---- Display scaling

Image8 displayScale(const Image8& image, int targetSide, int maxSide) {
  int side = std::max(image.width, image.height);
  cv::Mat src(image.height, image.width, CV_8UC3, const_cast<std::uint8_t*>(image.rgb.data())), dst;
  if (side <= targetSide) {
    int factor = std::max(1, targetSide / side);
    cv::resize(src, dst, {image.width * factor, image.height * factor}, 0, 0, cv::INTER_NEAREST);
  } else if (side > maxSide) {
    double f = static_cast<double>(maxSide) / side;
    cv::resize(src, dst, {std::max(1, int(image.width * f)), std::max(1, int(image.height * f))}, 0, 0,
               cv::INTER_AREA);
  } else {
    dst = src.clone();
  }
  Image8 out;
  out.width = dst.cols, out.height = dst.rows;
  out.rgb.assign(dst.data, dst.data + static_cast<std::size_t>(dst.cols) * dst.rows * 3);
  return out;
}

}  // namespace nbtf
