#include "io/image_io.h"

#include <ImfChannelList.h>
#include <ImfChromaticities.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStandardAttributes.h>
#include <Imath/half.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "io/color.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace nbtf {

// ---- Formats -----------------------------------------------------------------

ImageFormat imageFormatFromName(const std::string& name) {
  auto dot = name.rfind('.');
  std::string ext = dot == std::string::npos ? "" : name.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == "jpg" || ext == "jpeg") return ImageFormat::Jpg;
  if (ext == "png") return ImageFormat::Png;
  if (ext == "exr") return ImageFormat::Exr;
  throw fileError(name, "unknown image extension (expected .jpg, .png or .exr)");
}

std::string extensionOf(ImageFormat f) {
  switch (f) {
    case ImageFormat::Jpg: return ".jpg";
    case ImageFormat::Png: return ".png";
    case ImageFormat::Exr: return ".exr";
  }
  return "";
}

ImageFormat parseImageFormat(const std::string& text) {
  if (text == "jpg" || text == "jpeg") return ImageFormat::Jpg;
  if (text == "png") return ImageFormat::Png;
  if (text == "exr") return ImageFormat::Exr;
  throw Error("unknown image format '" + text + "' (expected jpg, png or exr)");
}

// ---- 8-bit reading -------------------------------------------------------------

namespace {
// A decoder given a truncated JPEG fills the missing rows with grey and only warns;
// the end markers are the reliable sign of a complete file.
void checkComplete(const std::string& path, const std::vector<std::uint8_t>& bytes, ImageFormat format) {
  if (bytes.empty()) throw fileError(path, "file is empty");
  if (format == ImageFormat::Jpg) {
    if (bytes.size() < 4 || bytes[0] != 0xFF || bytes[1] != 0xD8) throw fileError(path, "not a JPEG file");
    // EOI (FF D9) must be the last marker; allow a little trailing padding.
    std::size_t from = bytes.size() > 64 ? bytes.size() - 64 : 0;
    bool eoi = false;
    for (std::size_t i = bytes.size() - 1; i > from; --i)
      if (bytes[i - 1] == 0xFF && bytes[i] == 0xD9) { eoi = true; break; }
    if (!eoi) throw fileError(path, "JPEG is truncated (no end-of-image marker)");
  } else if (format == ImageFormat::Png) {
    static const std::uint8_t sig[8] = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
    if (bytes.size() < 8 || !std::equal(sig, sig + 8, bytes.begin())) throw fileError(path, "not a PNG file");
    static const char iend[] = "IEND";
    if (bytes.size() < 20 || !std::equal(iend, iend + 4, bytes.end() - 8))
      throw fileError(path, "PNG is truncated (no IEND chunk at the end)");
  }
}
}  // namespace

namespace {
// An 8-bit JPEG or PNG as OpenCV decodes it (BGR or BGRA), checked for completeness and depth.
cv::Mat decodeImage8(const std::string& path) {
  ImageFormat format = imageFormatFromName(path);
  if (format == ImageFormat::Exr) throw fileError(path, "EXR is not an 8-bit format");
  std::vector<std::uint8_t> bytes = readFileBytes(path);
  checkComplete(path, bytes, format);
  cv::Mat mat;
  try {
    mat = cv::imdecode(cv::Mat(1, static_cast<int>(bytes.size()), CV_8U, bytes.data()), cv::IMREAD_UNCHANGED);
  } catch (const std::exception& e) {
    throw fileError(path, std::string("cannot decode image: ") + e.what());
  }
  if (mat.empty()) throw fileError(path, "cannot decode image (corrupt or unsupported)");
  if (mat.depth() != CV_8U) {
    std::ostringstream s;
    s << "has " << (mat.depth() == CV_16U ? "16" : "non-8") << "-bit samples; nbtf reads 8-bit RGB "
      << "JPEG/PNG or EXR (convert this stack to 8-bit or EXR)";
    throw fileError(path, s.str());
  }
  return mat;
}

std::string channelCount(int channels) {
  return std::to_string(channels) + " channel" + (channels == 1 ? " (grayscale)" : "s");
}

// `channels` 3 or 4 interleaved from OpenCV's BGR(A) rows (alpha 255 where the image has none).
std::vector<std::uint8_t> toRgb(const cv::Mat& mat, int channels) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(mat.cols) * mat.rows * channels);
  const int in = mat.channels();
  for (int y = 0; y < mat.rows; ++y) {
    const std::uint8_t* src = mat.ptr<std::uint8_t>(y);
    std::uint8_t* dst = out.data() + static_cast<std::size_t>(y) * mat.cols * channels;
    for (int x = 0; x < mat.cols; ++x) {  // OpenCV stores BGR(A)
      dst[channels * x + 0] = src[in * x + 2];
      dst[channels * x + 1] = src[in * x + 1];
      dst[channels * x + 2] = src[in * x + 0];
      if (channels == 4) dst[4 * x + 3] = in == 4 ? src[4 * x + 3] : 255;
    }
  }
  return out;
}

void encodeAndWrite(const std::string& path, ImageFormat format, const cv::Mat& mat, int jpegQuality) {
  std::vector<int> params;
  if (format == ImageFormat::Jpg) params = {cv::IMWRITE_JPEG_QUALITY, jpegQuality};
  std::vector<std::uint8_t> encoded;
  bool ok = false;
  try {
    ok = cv::imencode(extensionOf(format), mat, encoded, params);
  } catch (const std::exception& e) {
    throw fileError(path, std::string("cannot encode image: ") + e.what());
  }
  if (!ok) throw fileError(path, "cannot encode image");
  writeFileAtomic(path, encoded.data(), encoded.size());
}
}  // namespace

Image8 readImage8(const std::string& path) {
  const cv::Mat mat = decodeImage8(path);
  if (mat.channels() != 3) throw fileError(path, "has " + channelCount(mat.channels()) + "; expected 3 (RGB)");
  Image8 img;
  img.width = mat.cols;
  img.height = mat.rows;
  img.rgb = toRgb(mat, 3);
  return img;
}

ImageRgba8 readImageRgba8(const std::string& path) {
  const cv::Mat mat = decodeImage8(path);
  if (mat.channels() != 3 && mat.channels() != 4)
    throw fileError(path, "has " + channelCount(mat.channels()) + "; expected 3 (RGB) or 4 (RGBA)");
  ImageRgba8 img;
  img.width = mat.cols;
  img.height = mat.rows;
  img.rgba = toRgb(mat, 4);
  return img;
}

// ---- EXR reading -----------------------------------------------------------------

namespace {
bool isXyzChromaticities(const Imf::Chromaticities& c) {
  auto near = [](float a, float b) { return std::fabs(a - b) < 1e-3f; };
  return near(c.red.x, 1) && near(c.red.y, 0) && near(c.green.x, 0) && near(c.green.y, 1) &&
         near(c.blue.x, 0) && near(c.blue.y, 0);
}
}  // namespace

ImageF readExr(const std::string& path, ExrColorSpace fallbackSpace) {
  ImageF img;
  ExrColorSpace space = fallbackSpace;
  try {
    Imf::InputFile file(path.c_str());
    const Imf::Header& header = file.header();
    Imath::Box2i dw = header.dataWindow();
    img.width = dw.max.x - dw.min.x + 1;
    img.height = dw.max.y - dw.min.y + 1;
    if (img.width <= 0 || img.height <= 0) throw fileError(path, "EXR has an empty data window");
    const Imf::ChannelList& channels = header.channels();
    const char* names[3] = {"R", "G", "B"};
    if (!channels.findChannel("R") && channels.findChannel("X")) {
      names[0] = "X", names[1] = "Y", names[2] = "Z";
      space = ExrColorSpace::CieXyz;
    }
    for (const char* n : names)
      if (!channels.findChannel(n)) throw fileError(path, std::string("EXR has no channel '") + n + "' (expected RGB)");
    if (Imf::hasChromaticities(header))
      space = isXyzChromaticities(Imf::chromaticities(header)) ? ExrColorSpace::CieXyz : ExrColorSpace::LinearSrgb;
    img.rgb.assign(static_cast<std::size_t>(img.width) * img.height * 3, 0.0f);
    Imf::FrameBuffer fb;
    char* base = reinterpret_cast<char*>(img.rgb.data()) -
                 (static_cast<std::ptrdiff_t>(dw.min.x) + static_cast<std::ptrdiff_t>(dw.min.y) * img.width) * 3 *
                     sizeof(float);
    for (int c = 0; c < 3; ++c)
      fb.insert(names[c], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), 3 * sizeof(float),
                                     3 * sizeof(float) * img.width));
    file.setFrameBuffer(fb);
    if (!file.isComplete()) throw fileError(path, "EXR is truncated (incomplete pixel data)");
    file.readPixels(dw.min.y, dw.max.y);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw fileError(path, std::string("cannot read EXR: ") + e.what());
  }
  for (std::size_t i = 0; i < img.rgb.size(); ++i) {
    float v = img.rgb[i];
    if (!std::isfinite(v) || v < 0) {
      std::size_t pixel = i / 3;
      std::ostringstream s;
      s << "pixel (" << pixel % img.width << ", " << pixel / img.width << ") channel " << i % 3 << " is " << v
        << "; EXR values must be finite and non-negative (policy: rejected, not clamped)";
      throw fileError(path, s.str());
    }
  }
  if (space == ExrColorSpace::CieXyz) {
    // Out-of-gamut XYZ maps to slightly negative sRGB: clamp those to 0.
    for (std::size_t i = 0; i < img.rgb.size(); i += 3) {
      xyzToLinearSrgb(&img.rgb[i]);
      for (int c = 0; c < 3; ++c) img.rgb[i + c] = std::max(0.0f, img.rgb[i + c]);
    }
  }
  return img;
}

// ---- Writing ------------------------------------------------------------------------

void writeImage8(const std::string& path, ImageFormat format, const Image8& image, int jpegQuality) {
  if (format == ImageFormat::Exr) throw fileError(path, "writeImage8 cannot write EXR");
  cv::Mat mat(image.height, image.width, CV_8UC3);
  for (int y = 0; y < image.height; ++y) {
    const std::uint8_t* src = image.rgb.data() + static_cast<std::size_t>(y) * image.width * 3;
    std::uint8_t* dst = mat.ptr<std::uint8_t>(y);
    for (int x = 0; x < image.width; ++x) {
      dst[3 * x + 0] = src[3 * x + 2];
      dst[3 * x + 1] = src[3 * x + 1];
      dst[3 * x + 2] = src[3 * x + 0];
    }
  }
  encodeAndWrite(path, format, mat, jpegQuality);
}

void writeImageRgba8(const std::string& path, const ImageRgba8& image) {
  if (imageFormatFromName(path) != ImageFormat::Png) throw fileError(path, "an RGBA image is written as PNG");
  cv::Mat mat(image.height, image.width, CV_8UC4);
  for (int y = 0; y < image.height; ++y) {
    const std::uint8_t* src = image.rgba.data() + static_cast<std::size_t>(y) * image.width * 4;
    std::uint8_t* dst = mat.ptr<std::uint8_t>(y);
    for (int x = 0; x < image.width; ++x) {
      dst[4 * x + 0] = src[4 * x + 2];
      dst[4 * x + 1] = src[4 * x + 1];
      dst[4 * x + 2] = src[4 * x + 0];
      dst[4 * x + 3] = src[4 * x + 3];
    }
  }
  encodeAndWrite(path, ImageFormat::Png, mat, 95);
}

void writeImageSrgb8(const std::string& path, ImageFormat format, int width, int height, const float* linearRgb,
                     int jpegQuality) {
  Image8 img;
  img.width = width;
  img.height = height;
  img.rgb.resize(static_cast<std::size_t>(width) * height * 3);
  for (std::size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = linearToSrgb8(linearRgb[i]);
  writeImage8(path, format, img, jpegQuality);
}

void writeExr(const std::string& path, int width, int height, const float* linearRgb, bool halfFloat,
              ExrColorSpace space) {
  std::size_t n = static_cast<std::size_t>(width) * height * 3;
  std::vector<float> values(linearRgb, linearRgb + n);
  if (space == ExrColorSpace::CieXyz)
    for (std::size_t i = 0; i < n; i += 3) linearSrgbToXyz(&values[i]);
  std::vector<Imath::half> halves;
  if (halfFloat) {
    halves.resize(n);
    for (std::size_t i = 0; i < n; ++i) halves[i] = Imath::half(values[i]);
  }
  writeAtomicVia(path, [&](const std::string& tmp) {
    try {
      Imf::Header header(width, height);
      Imf::PixelType type = halfFloat ? Imf::HALF : Imf::FLOAT;
      for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(type));
      if (space == ExrColorSpace::CieXyz)
        Imf::addChromaticities(header, Imf::Chromaticities(Imath::V2f(1, 0), Imath::V2f(0, 1), Imath::V2f(0, 0),
                                                           Imath::V2f(0.3127f, 0.3290f)));
      Imf::OutputFile file(tmp.c_str(), header);
      Imf::FrameBuffer fb;
      std::size_t elem = halfFloat ? sizeof(Imath::half) : sizeof(float);
      char* base = halfFloat ? reinterpret_cast<char*>(halves.data()) : reinterpret_cast<char*>(values.data());
      const char* names[3] = {"R", "G", "B"};
      for (int c = 0; c < 3; ++c)
        fb.insert(names[c], Imf::Slice(type, base + c * elem, 3 * elem, 3 * elem * width));
      file.setFrameBuffer(fb);
      file.writePixels(height);
    } catch (const std::exception& e) {
      throw fileError(path, std::string("cannot write EXR: ") + e.what());
    }
  });
}

}  // namespace nbtf
