// Reading and writing single images: JPEG/PNG (8-bit sRGB, via OpenCV) and OpenEXR
// (half or float, linear). Every write is atomic (temporary name, then rename); every
// error names the file and what is wrong.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace nbtf {

enum class ImageFormat { Jpg, Png, Exr };
ImageFormat imageFormatFromName(const std::string& name);  // by extension; throws on unknown
std::string extensionOf(ImageFormat f);                      // ".jpg", ".png", ".exr"
ImageFormat parseImageFormat(const std::string& text);      // "jpg"|"png"|"exr"

// Colour space of EXR pixel data on disk.
enum class ExrColorSpace { LinearSrgb, CieXyz };

// A decoded image in memory, interleaved RGB, row-major, top row first.
struct Image8 {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // sRGB-encoded
};
struct ImageRgba8 {  // with alpha (glTF's packed textures: sheen colour + roughness)
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgba;
};
struct ImageF {
  int width = 0, height = 0;
  std::vector<float> rgb;  // linear
};

// Reads an 8-bit RGB JPEG or PNG. Rejects, naming the file: unreadable or truncated
// files, grayscale or alpha images, 16-bit images.
Image8 readImage8(const std::string& path);
// An 8-bit PNG or JPEG with or without alpha (alpha 255 where it has none); rejects the rest
// as readImage8 does.
ImageRgba8 readImageRgba8(const std::string& path);

// Reads an RGB(A) EXR into linear sRGB floats. `space` says how the pixels are
// encoded when the file itself does not say (a chromaticities attribute wins).
// Rejects NaN, Inf and negative values, naming the file and the first bad pixel.
ImageF readExr(const std::string& path, ExrColorSpace fallbackSpace = ExrColorSpace::LinearSrgb);

// Writes 8-bit sRGB (PNG or JPEG by `format`) from linear floats (clamped to [0,1]).
void writeImageSrgb8(const std::string& path, ImageFormat format, int width, int height,
                     const float* linearRgb, int jpegQuality = 95);
// Writes an 8-bit image already sRGB-encoded.
void writeImage8(const std::string& path, ImageFormat format, const Image8& image, int jpegQuality = 95);
// Writes an 8-bit RGBA PNG (the path must end in .png).
void writeImageRgba8(const std::string& path, const ImageRgba8& image);

// Writes an RGB EXR from linear sRGB floats: half or full float; optionally converted to
// CIE XYZ (and tagged with XYZ chromaticities) as UTIA stores it.
void writeExr(const std::string& path, int width, int height, const float* linearRgb, bool halfFloat = true,
              ExrColorSpace space = ExrColorSpace::LinearSrgb);

}  // namespace nbtf
