#include "pipeline/decoder_output.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <sstream>

#include <nlohmann/json.hpp>

#include "io/btf_names.h"
#include "pipeline/decoded_image_names.h"
#include "pipeline/decode_folder.h"
#include "io/color.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/memory.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/timer.h"
#include "util/writer_pool.h"

namespace nbtf {
namespace fs = std::filesystem;

// ---- Layout and format ---------------------------------------------------------------------------

Layout resolvedLayout(const NbtfDecoder& decoder, const DecodeStackOptions& options) {
  if (options.layout != Layout::Unknown) return options.layout;
  return decoder.material().layout == Layout::Utia ? Layout::Utia : Layout::Ubo2003;
}

ImageFormat resolvedFormat(const NbtfDecoder& decoder, const DecodeStackOptions& options) {
  if (options.format) return *options.format;
  return decoder.material().sourceSampleType == SampleType::Half ? ImageFormat::Exr : ImageFormat::Png;
}

// ---- Decoding images ----------------------------------------------------------------------------

namespace {

std::string describePair(const DirectionChoice& l, const DirectionChoice& v) {
  std::ostringstream s;
  s << "light (" << l.direction.thetaDeg << ", " << l.direction.phiDeg << "), view (" << v.direction.thetaDeg << ", "
    << v.direction.phiDeg << ")";
  return s.str();
}

// Largest finite half float: EXR values beyond it would be stored as infinity.
constexpr float kHalfMax = 65504.0f;

// Decoded linear values: each checked finite and below maxValue (an error naming the pair),
// negatives clamped to 0 and counted.
void checkDecoded(const NbtfDecoder& decoder, const DirectionChoice& l, const DirectionChoice& v,
                  std::vector<float>& values, std::uint64_t& clamped, float maxValue) {
  for (float& x : values) {
    if (!std::isfinite(x) || x > maxValue) {
      std::ostringstream s;
      s << "decoder output " << x << " for " << describePair(l, v)
        << (std::isfinite(x) ? " exceeds the largest half float (65504)" : " is not finite")
        << "; the material's decoder is unusable at these angles";
      throw fileError(decoder.name(), s.str());
    }
    if (x < 0) x = 0, ++clamped;
  }
}

// One image's per-row values: decoded (linear), checked.
void decodeCheckedRows(const NbtfDecoder& decoder, const DirectionChoice& l, const DirectionChoice& v,
                       std::vector<float>& rows, std::uint64_t& clamped, float maxValue) {
  rows.resize(3 * static_cast<std::size_t>(decoder.latentRows()));
  decoder.decodeRows(l.direction, v.direction, rows.data(), OutputScale::Linear);
  checkDecoded(decoder, l, v, rows, clamped, maxValue);
}

// A modulated material's image (linear, tiled over width x height), checked: its texels are
// not copies of rows.
void decodeCheckedImage(const NbtfDecoder& decoder, const DirectionChoice& l, const DirectionChoice& v, int width,
                        int height, std::vector<float>& image, std::uint64_t& clamped, float maxValue) {
  image.resize(3 * static_cast<std::size_t>(width) * height);
  decoder.decodeImage(l.direction, v.direction, image.data(), OutputScale::Linear, width, height);
  checkDecoded(decoder, l, v, image, clamped, maxValue);
}

// Texel values from per-row values, tiling the material over width x height.
template <class T>
void scatterRows(const NbtfDecoder& decoder, const T* rows, int width, int height, T* out) {
  const int w = decoder.width(), h = decoder.height();
  for (int y = 0; y < height; ++y) {
    const int sy = y % h;
    T* dst = out + static_cast<std::size_t>(y) * width * 3;
    for (int x = 0, sx = 0; x < width; ++x, sx = sx + 1 == w ? 0 : sx + 1) {
      const T* src = rows + 3 * static_cast<std::size_t>(decoder.latentRowOfTexel(sy * w + sx));
      dst[3 * x + 0] = src[0], dst[3 * x + 1] = src[1], dst[3 * x + 2] = src[2];
    }
  }
}

constexpr int kWriterThreads = 8;
constexpr std::size_t kQueuedBytes = std::size_t(256) << 20;  // bound on images waiting to be written

}  // namespace

namespace {
// Images in flight: one being decoded per thread (linear floats and the encoded copy), the
// writers' queue and the one each writer holds. Refused before any allocation when that
// cannot fit (a --size of 65536 x 65536 is 51 GB an image).
void checkDecodeMemory(int width, int height) {
  const double values = 3.0 * width * height;
  const double perImage = values * (sizeof(float) + sizeof(float));
  const double inFlight = threadCount() + kWriterThreads + 2;
  const double need = perImage * inFlight;
  const double limit = static_cast<double>(defaultMemoryLimit());
  if (need > limit)
    throw Error("--size " + std::to_string(width) + "x" + std::to_string(height) + ": decoding needs about " +
                formatBytes(static_cast<std::size_t>(need)) + " (" + formatBytes(static_cast<std::size_t>(perImage)) +
                " per image, " + std::to_string(static_cast<int>(inFlight)) + " in flight), more than the " +
                formatBytes(static_cast<std::size_t>(limit)) + " allowed (75% of physical memory)");
}
}  // namespace

namespace {
// What every image of a decode shares: the decoder, the images' shape and format, the writers.
struct ImageSink {
  const NbtfDecoder& decoder;
  const DecodeStackResult& r;
  const DecodeStackOptions& options;
  ExrColorSpace space;
  WriterPool& writers;
  Progress& progress;
  std::atomic<std::uint64_t>& clamped;
};

// One image: decoded at (l, v), encoded for its format and handed to the writers.
void decodeAndSubmit(const ImageSink& sink, const DirectionChoice& l, const DirectionChoice& v, std::string path) {
  const NbtfDecoder& decoder = sink.decoder;
  const DecodeStackResult& r = sink.r;
  WriterPool& writers = sink.writers;
  // The writers run after this returns: what they use is captured by value, the progress bar
  // (the caller's) by reference.
  const int width = r.width, height = r.height, quality = sink.options.jpegQuality;
  const ImageFormat format = r.format;
  const ExrColorSpace space = sink.space;
  const bool exr = r.format == ImageFormat::Exr;
  const Srgb8Encoder& encode = srgb8Encoder();
  const std::size_t values = 3 * static_cast<std::size_t>(r.width) * r.height;
  std::vector<float> rows;
  std::uint64_t neg = 0;
  if (decoder.modulated()) {
    // Every texel has its own value: decode the image, then encode texel by texel.
    std::vector<float> linear;
    decodeCheckedImage(decoder, l, v, r.width, r.height, linear, neg, exr ? kHalfMax : INFINITY);
    sink.clamped += neg;
    if (exr) {
      writers.submit([width, height, space, &progress = sink.progress,
                      path = std::move(path), image = std::move(linear)] {
        writeExr(path, width, height, image.data(), true, space);
        progress.advance();
      });
    } else {
      Image8 image;
      image.width = r.width, image.height = r.height;
      image.rgb.resize(values);
      for (std::size_t j = 0; j < values; ++j) image.rgb[j] = encode(linear[j]);
      writers.submit([format, quality, &progress = sink.progress, path = std::move(path), image = std::move(image)] {
        writeImage8(path, format, image, quality);
        progress.advance();
      });
    }
    return;
  }
  decodeCheckedRows(decoder, l, v, rows, neg, exr ? kHalfMax : INFINITY);
  sink.clamped += neg;
  if (exr) {
    std::vector<float> image(values);
    scatterRows(decoder, rows.data(), r.width, r.height, image.data());
    writers.submit([width, height, space, &progress = sink.progress,
                    path = std::move(path), image = std::move(image)] {
      writeExr(path, width, height, image.data(), true, space);
      progress.advance();
    });
  } else {
    std::vector<std::uint8_t> rowBytes(rows.size());
    for (std::size_t j = 0; j < rows.size(); ++j) rowBytes[j] = encode(rows[j]);
    Image8 image;
    image.width = r.width, image.height = r.height;
    image.rgb.resize(values);
    scatterRows(decoder, rowBytes.data(), r.width, r.height, image.rgb.data());
    writers.submit([format, quality, &progress = sink.progress, path = std::move(path), image = std::move(image)] {
      writeImage8(path, format, image, quality);
      progress.advance();
    });
  }
}
}  // namespace

DecodeStackResult writeDecodedStack(const NbtfDecoder& decoder, const std::string& folder,
                                    const DecodeStackOptions& options) {
  DecodeStackResult r;
  r.folder = folder;
  r.layout = resolvedLayout(decoder, options);
  if (r.layout == Layout::Ubo2014)
    throw Error("the ubo2014 layout is one .btf file, not a folder of images (writeDecodedUbo2014)");
  r.format = resolvedFormat(decoder, options);
  const std::vector<DirectionChoice> lights = options.lights.empty() ? allDirections(decoder.lights()) : options.lights;
  const std::vector<DirectionChoice> views = options.views.empty() ? allDirections(decoder.views()) : options.views;
  r.lights = static_cast<int>(lights.size());
  r.views = static_cast<int>(views.size());
  r.images = r.lights * r.views;
  r.width = options.width ? options.width : decoder.width();
  r.height = options.height ? options.height : decoder.height();
  if (options.jpegQuality < 1 || options.jpegQuality > 100)
    throw Error("JPEG quality " + std::to_string(options.jpegQuality) + " is outside 1..100");
  checkDecodeMemory(r.width, r.height);

  // The images go into a staging folder that replaces `folder` as a whole at the end
  // (pipeline/decode_folder.h): an interrupted decode never leaves two decodes mixed.
  nlohmann::json description = {{"generator", "nbtf decode"},
                                 {"layout", layoutName(r.layout)},
                                 {"format", extensionOf(r.format).substr(1)},
                                 {"lights", r.lights},
                                 {"views", r.views},
                                 {"images", r.images},
                                 {"width", r.width},
                                 {"height", r.height}};
  DecodeFolder output(folder, description.dump());
  std::error_code ec;
  for (const auto& v : views) {
    fs::path sub = fs::path(output.staging()) / viewFolderName(v.direction);
    fs::create_directories(sub, ec);
    if (ec) throw fileError(sub.string(), "cannot create folder: " + ec.message());
  }
  const int numViews = static_cast<int>(decoder.views().size());
  bool allMeasured = true;
  for (const auto& l : lights) allMeasured = allMeasured && l.measured();
  for (const auto& v : views) allMeasured = allMeasured && v.measured();
  auto pathOf = [&](int image) {
    return (fs::path(output.staging()) / decodedImagePath(r.layout, r.format, lights[image / r.views], views[image % r.views],
                                                numViews, allMeasured ? -1 : image))
        .string();
  };
  checkWritable(pathOf(0));

  const bool exr = r.format == ImageFormat::Exr;
  const ExrColorSpace space = r.layout == Layout::Utia ? ExrColorSpace::CieXyz : ExrColorSpace::LinearSrgb;
  std::atomic<std::uint64_t> clamped{0};
  Progress progress("decode", static_cast<std::size_t>(r.images), options.progress);
  const std::size_t imageBytes = 3 * static_cast<std::size_t>(r.width) * r.height * (exr ? sizeof(float) : 1);
  WriterPool writers(kWriterThreads, kQueuedBytes / std::max<std::size_t>(1, imageBytes));
  const ImageSink sink{decoder, r, options, space, writers, progress, clamped};
  const auto stopped = [&] { return options.stopFlag && options.stopFlag->load(); };
  std::atomic<int> started{0};
  parallelForDynamic(static_cast<std::size_t>(r.images), [&](std::size_t i, int) {
    if (stopped()) return;
    ++started;
    decodeAndSubmit(sink, lights[i / r.views], views[i % r.views], pathOf(static_cast<int>(i)));
  });
  writers.finish();
  if (stopped()) {  // the DecodeFolder removes the staging folder on its way out
    r.interrupted = true;
    r.written = started.load();
    return r;
  }
  output.commit();
  progress.finish();
  r.seconds = progress.elapsedSeconds();
  r.evaluations = static_cast<std::uint64_t>(r.images) * static_cast<std::uint64_t>(decoder.latentRows());
  r.clampedNegative = clamped;
  return r;
}

std::string formatDecodeSummary(const DecodeStackResult& r, const NbtfDecoder& decoder) {
  char buf[512];
  std::string out;
  std::snprintf(buf, sizeof buf, "decoded %d image%s (%d light%s x %d view%s), %d x %d texels each\n", r.images,
                r.images == 1 ? "" : "s", r.lights, r.lights == 1 ? "" : "s", r.views, r.views == 1 ? "" : "s",
                r.width, r.height);
  out += buf;
  out += "  output   " + r.folder + " (" + layoutName(r.layout) + " layout and names)\n";
  if (r.format == ImageFormat::Exr) {
    std::snprintf(buf, sizeof buf, "  format   EXR, half float, linear %s (decoder output x alpha %.6g)\n",
                  r.layout == Layout::Utia ? "CIE XYZ (tagged with XYZ chromaticities)" : "RGB, sRGB primaries",
                  decoder.alpha());
  } else {
    std::snprintf(buf, sizeof buf, "  format   %s, 8-bit sRGB (linear = decoder output x alpha %.6g, clamped to [0, 1])\n",
                  r.format == ImageFormat::Png ? "PNG" : "JPEG", decoder.alpha());
  }
  out += buf;
  if (decoder.pca())
    std::snprintf(buf, sizeof buf, "  decoder  PCA baseline, %d components, %d texel evaluation%s per image (%llu in all)\n",
                  decoder.material().latentDim, decoder.latentRows(), decoder.latentRows() == 1 ? "" : "s",
                  static_cast<unsigned long long>(r.evaluations));
  else
    std::snprintf(buf, sizeof buf, "  decoder  %s, %d evaluation%s per image (%llu in all), %s kernels\n",
                  decoder.clustered() ? "clustered" : "per-texel", decoder.latentRows(),
                  decoder.latentRows() == 1 ? "" : "s", static_cast<unsigned long long>(r.evaluations),
                  decoderIsaName(decoder.isa()).c_str());
  out += buf;
  if (r.clampedNegative) {
    std::snprintf(buf, sizeof buf, "  clamped  %llu negative linear value%s written as 0\n",
                  static_cast<unsigned long long>(r.clampedNegative), r.clampedNegative == 1 ? "" : "s");
    out += buf;
  }
  std::snprintf(buf, sizeof buf, "  time     %.2f s (%.0f images/s, %d threads)\n", r.seconds,
                r.seconds > 0 ? r.images / r.seconds : 0.0, threadCount());
  out += buf;
  return out;
}

BtfStack decodeStack(const NbtfDecoder& decoder, SampleType type, const std::vector<DirectionChoice>& lightChoice,
                     const std::vector<DirectionChoice>& viewChoice, bool progressBar) {
  const auto lights = lightChoice.empty() ? allDirections(decoder.lights()) : lightChoice;
  const auto views = viewChoice.empty() ? allDirections(decoder.views()) : viewChoice;
  std::vector<Direction> ld, vd;
  for (const auto& l : lights) ld.push_back(l.direction);
  for (const auto& v : views) vd.push_back(v.direction);
  BtfStack stack(ld, vd, decoder.width(), decoder.height(), type);
  const CompressedBtf& m = decoder.material();
  stack.source = decoder.name();
  stack.layout = m.layout;
  stack.sourceWidth = m.sourceWidth;
  stack.sourceHeight = m.sourceHeight;
  stack.crop = m.crop;
  const std::size_t images = static_cast<std::size_t>(stack.numImages());
  const Srgb8Encoder& encode = srgb8Encoder();
  Progress progress("decode", images, progressBar);
  parallelForDynamic(images, [&](std::size_t i, int) {
    std::vector<float> rows;
    std::uint64_t clamped = 0;
    const auto& l = lights[i / views.size()];
    const auto& v = views[i % views.size()];
    if (decoder.modulated()) {
      std::vector<float> image;
      decodeCheckedImage(decoder, l, v, decoder.width(), decoder.height(), image, clamped,
                         type == SampleType::Half ? kHalfMax : INFINITY);
      if (type == SampleType::Srgb8) {
        std::uint8_t* out = stack.imageBytes(static_cast<int>(i));
        for (std::size_t j = 0; j < image.size(); ++j) out[j] = encode(image[j]);
      } else {
        stack.setImageLinear(static_cast<int>(i), image.data());
      }
      progress.advance();
      return;
    }
    decodeCheckedRows(decoder, l, v, rows, clamped, type == SampleType::Half ? kHalfMax : INFINITY);
    if (type == SampleType::Srgb8) {
      std::vector<std::uint8_t> rowBytes(rows.size());
      for (std::size_t j = 0; j < rows.size(); ++j) rowBytes[j] = encode(rows[j]);
      scatterRows(decoder, rowBytes.data(), decoder.width(), decoder.height(), stack.imageBytes(static_cast<int>(i)));
    } else {
      std::vector<float> image(3 * static_cast<std::size_t>(decoder.numTexels()));
      scatterRows(decoder, rows.data(), decoder.width(), decoder.height(), image.data());
      stack.setImageLinear(static_cast<int>(i), image.data());
    }
    progress.advance();
  });
  progress.finish();
  return stack;
}

DecodeUbo2014Result writeDecodedUbo2014(const NbtfDecoder& decoder, const std::string& path,
                                        const DecodeStackOptions& options, const Ubo2014FactorizeOptions& factorize) {
  const auto start = std::chrono::steady_clock::now();
  std::error_code ec;
  if (fs::is_directory(path, ec))
    throw fileError(path, "is a folder; --layout ubo2014 writes one .btf file (e.g. -o material.btf)");
  if (options.format) throw Error("--format does not apply to --layout ubo2014 (the .btf file stores half floats)");
  if (options.width || options.height) throw Error("--size does not apply to --layout ubo2014");
  checkUbo2014FactorizeOptions(factorize);
  checkWritable(path);
  BtfStack stack = decodeStack(decoder, SampleType::Half, options.lights, options.views, options.progress);
  Ubo2014FactorizeOptions f = factorize;
  f.progress = options.progress;
  if (f.xml.empty()) {
    std::string name;
    for (char c : decoder.name()) name += c == '"' ? std::string("&quot;") : c == '&' ? std::string("&amp;") : c == '<' ? std::string("&lt;") : std::string(1, c);
    f.xml = "<nbtf-decode source=\"" + name + "\"/>";
  }
  DecodeUbo2014Result r;
  Ubo2014Btf btf = factorizeUbo2014(stack, f, &r.factorization);
  btf.write(path);
  r.file = path;
  r.lights = stack.numLights(), r.views = stack.numViews(), r.images = stack.numImages();
  r.width = stack.width(), r.height = stack.height();
  r.fileBytes = fs::file_size(path, ec);
  r.seconds = secondsSince(start);
  return r;
}

std::string formatDecodeUbo2014Summary(const DecodeUbo2014Result& r) {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "wrote %s (ubo2014, !DFMF08FCR, %d lights x %d views = %d images, %d x %d texels, %d components per "
                "channel, %zu bytes) in %.1f s\n"
                "factorization (stored half floats vs the decoded values, linear RGB): RMSE %.4g (mean value %.4g), "
                "max abs error %.4g\n",
                r.file.c_str(), r.lights, r.views, r.images, r.width, r.height, r.factorization.components, r.fileBytes,
                r.seconds, r.factorization.rmseLinear, r.factorization.inputMean, r.factorization.maxAbsError);
  return buf;
}

}  // namespace nbtf
