// A small raster canvas for the report's figures (heat map, charts, comparison strips):
// filled shapes, lines and labelled text drawn with OpenCV into an 8-bit sRGB image,
// plus the pieces every figure shares (viridis colour map, "nice" axis ticks).
// The header stays free of OpenCV; figures are plain Image8 values.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "io/image_io.h"

namespace nbtf {

struct Color8 {
  std::uint8_t r = 0, g = 0, b = 0;
};
constexpr Color8 kWhite{255, 255, 255};
constexpr Color8 kBlack{0, 0, 0};
constexpr Color8 kGrey{128, 128, 128};
constexpr Color8 kLightGrey{225, 225, 225};

enum class Align { Left, Center, Right };

class Canvas {
 public:
  Canvas(int width, int height, Color8 background = kWhite);
  int width() const { return image_.width; }
  int height() const { return image_.height; }

  void fillRect(int x, int y, int w, int h, Color8 color);
  void strokeRect(int x, int y, int w, int h, Color8 color, int thickness = 1);
  void line(int x0, int y0, int x1, int y1, Color8 color, int thickness = 1);
  void circle(int cx, int cy, int radius, Color8 color, bool filled = true);

  // Text whose vertical centre is at y; x is its left edge, centre or right edge by `align`.
  // `size` is the height of a capital letter in pixels. A UTF-8 degree sign (U+00B0) is drawn
  // as a small ring (the Hershey fonts have none). vertical = rotated 90 degrees counter-
  // clockwise (reads bottom to top), centred on (x, y).
  void text(const std::string& text, int x, int y, int size, Color8 color = kBlack, Align align = Align::Left,
            bool vertical = false);
  int textWidth(const std::string& text, int size) const;

  // Copies `image` with its top-left corner at (x, y) (clipped to the canvas).
  void blit(const Image8& image, int x, int y);

  const Image8& image() const { return image_; }
  Image8 release() { return std::move(image_); }

 private:
  Image8 image_;
};

// The viridis colour map (matplotlib's perceptually uniform default), t in [0, 1] (clamped).
Color8 viridis(double t);

// 3 to ~maxTicks round tick values (steps of 1, 2 or 5 x 10^k) covering [lo, hi]; the first
// tick >= lo, the last <= hi.
std::vector<double> niceTicks(double lo, double hi, int maxTicks);
// A tick label with as many decimals as the step needs ("0.005", "0.01", "20").
std::string formatTick(double value, double step);

// Scales an image for display: nearest-neighbour by an integer factor when it is small
// (texels stay visible as blocks), area-averaged down when it is larger than `maxSide`.
Image8 displayScale(const Image8& image, int targetSide, int maxSide);

}  // namespace nbtf
