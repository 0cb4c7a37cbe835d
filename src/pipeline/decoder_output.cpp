#include "pipeline/decoder_output.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "io/btf_names.h"
#include "pipeline/decode_folder.h"
#include "io/color.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/memory.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/timer.h"

namespace nbtf {
namespace fs = std::filesystem;

// ---- Direction lists ------------------------------------------------------------------------

namespace {

double normalizedPhi(double phi) {
  double p = std::fmod(phi, 360.0);
  if (p < 0) p += 360.0;
  return p;
}

// To the 1e-6 degrees of a typed angle (tTHETApPHI), by the angles themselves.
bool sameAngles(const Direction& a, const Direction& b) {
  constexpr double kTol = 1e-6;
  if (std::fabs(a.thetaDeg - b.thetaDeg) > kTol) return false;
  if (a.thetaDeg <= kTol) return true;  // the pole: every azimuth is the same direction
  double d = std::fabs(normalizedPhi(a.phiDeg) - normalizedPhi(b.phiDeg));
  return std::min(d, 360.0 - d) <= kTol;
}

bool parseInt(const std::string& s, long& out) {
  if (s.empty() || !(std::isdigit(static_cast<unsigned char>(s[0])))) return false;
  char* end = nullptr;
  errno = 0;
  out = std::strtol(s.c_str(), &end, 10);
  return errno == 0 && *end == '\0';
}

bool parseDouble(const std::string& s, double& out) {
  if (s.empty()) return false;
  char* end = nullptr;
  out = std::strtod(s.c_str(), &end);
  return *end == '\0' && std::isfinite(out);
}

}  // namespace

DirectionChoice chooseDirection(const Direction& d, const std::vector<Direction>& measured) {
  DirectionChoice c;
  c.direction = {d.thetaDeg, normalizedPhi(d.phiDeg)};
  for (std::size_t i = 0; i < measured.size(); ++i)
    if (sameAngles(c.direction, measured[i])) {
      c.direction = measured[i];
      c.index = static_cast<int>(i);
      break;
    }
  return c;
}

std::vector<DirectionChoice> allDirections(const std::vector<Direction>& measured) {
  std::vector<DirectionChoice> out;
  for (std::size_t i = 0; i < measured.size(); ++i) out.push_back({measured[i], static_cast<int>(i)});
  return out;
}

std::vector<DirectionChoice> parseDirectionList(const std::string& text, const std::vector<Direction>& measured,
                                                const std::string& option) {
  const std::string what = option.substr(option.find_first_not_of('-')) == "views" ? "view" : "light";
  if (text == "all") return allDirections(measured);
  auto fail = [&](const std::string& item, const std::string& why) {
    return Error(option + ": item '" + item + "' " + why +
                 " (LIST: 'all', or comma-separated N, N-M or tTHETApPHI, e.g. '0-5,12,t37.5p200')");
  };
  const int count = static_cast<int>(measured.size());
  std::vector<DirectionChoice> out;
  auto add = [&](const DirectionChoice& c) {
    for (const auto& e : out)
      if (c.measured() ? e.index == c.index : (!e.measured() && sameAngles(e.direction, c.direction))) return;
    out.push_back(c);
  };
  std::string item;
  std::istringstream in(text);
  bool any = false;
  while (std::getline(in, item, ',')) {
    any = true;
    if (item.empty()) throw fail(item, "is empty");
    if (item[0] == 't') {
      auto p = item.find('p');
      double theta = 0, phi = 0;
      if (p == std::string::npos || !parseDouble(item.substr(1, p - 1), theta) || !parseDouble(item.substr(p + 1), phi))
        throw fail(item, "is not tTHETApPHI with THETA and PHI in degrees");
      Direction d{theta, phi};
      try {
        checkHemisphere(d, what);
      } catch (const Error& e) {
        throw fail(item, std::string("is not on the hemisphere: ") + e.what());
      }
      add(chooseDirection(d, measured));
      continue;
    }
    long first = 0, last = 0;
    auto dash = item.find('-');
    bool ok = dash == std::string::npos ? parseInt(item, first) && (last = first, true)
                                        : parseInt(item.substr(0, dash), first) && parseInt(item.substr(dash + 1), last);
    if (!ok) throw fail(item, "is not an index N, a range N-M or tTHETApPHI");
    if (first > last) throw fail(item, "is an empty range (N-M needs N <= M)");
    if (last >= count)
      throw fail(item, "is out of range: the material has " + std::to_string(count) + " " + what + " directions (0.." +
                           std::to_string(count - 1) + ")");
    for (long i = first; i <= last; ++i) add({measured[i], static_cast<int>(i)});
  }
  if (!any) throw fail(text, "is empty");
  return out;
}

std::pair<int, int> parseImageSize(const std::string& text, const std::string& option, int maxSide) {
  long w = 0, h = 0;
  auto x = text.find_first_of("xX");
  if (x == std::string::npos || !parseInt(text.substr(0, x), w) || !parseInt(text.substr(x + 1), h))
    throw Error(option + ": expected WxH (e.g. 256x256), got '" + text + "'");
  const long kMax = maxSide;
  if (w < 1 || h < 1 || w > kMax || h > kMax)
    throw Error(option + ": size " + text + " is out of range (1 .. " + std::to_string(kMax) + " per side)");
  return {static_cast<int>(w), static_cast<int>(h)};
}

// ---- sRGB encoding ----------------------------------------------------------------------------

namespace {
float floatFromBits(std::uint32_t b) {
  float f;
  std::memcpy(&f, &b, sizeof f);
  return f;
}
std::uint32_t bitsOf(float f) {
  std::uint32_t b;
  std::memcpy(&b, &f, sizeof b);
  return b;
}
}  // namespace

Srgb8Encoder::Srgb8Encoder() {
  // Non-negative floats order like their bit patterns: bisect on the bits.
  for (int i = 0; i < 255; ++i) {
    std::uint32_t lo = 0, hi = bitsOf(1.0f);
    while (lo < hi) {
      std::uint32_t mid = lo + (hi - lo) / 2;
      if (linearToSrgb8(floatFromBits(mid)) >= i + 1) hi = mid;
      else lo = mid + 1;
    }
    thresholds_[i] = floatFromBits(lo);
  }
  thresholds_[255] = INFINITY;
  auto codeOf = [this](float x) {  // the number of thresholds <= x
    return static_cast<int>(std::upper_bound(thresholds_, thresholds_ + 255, x) - thresholds_);
  };
  firstBits_ = bitsOf(thresholds_[0]);
  const std::uint32_t buckets = ((bitsOf(1.0f) - firstBits_) >> kBucketShift) + 1;
  bucketCode_.resize(buckets);
  for (std::uint32_t b = 0; b < buckets; ++b) {
    const std::uint32_t first = firstBits_ + (b << kBucketShift), last = first + (1u << kBucketShift) - 1;
    bucketCode_[b] = static_cast<std::uint8_t>(codeOf(floatFromBits(first)));
    // One comparison finishes a value only if its bucket holds at most one threshold.
    if (codeOf(floatFromBits(std::min(last, bitsOf(1.0f)))) > bucketCode_[b] + 1)
      throw Error("Srgb8Encoder: two sRGB rounding thresholds in one table bucket");
  }
}

// ---- Layout, format, names -------------------------------------------------------------------

Layout resolvedLayout(const NbtfDecoder& decoder, const DecodeStackOptions& options) {
  if (options.layout != Layout::Unknown) return options.layout;
  return decoder.material().layout == Layout::Utia ? Layout::Utia : Layout::Ubo2003;
}

ImageFormat resolvedFormat(const NbtfDecoder& decoder, const DecodeStackOptions& options) {
  if (options.format) return *options.format;
  return decoder.material().sourceSampleType == SampleType::Half ? ImageFormat::Exr : ImageFormat::Png;
}

std::string decodedImagePath(Layout layout, ImageFormat format, const DirectionChoice& light,
                             const DirectionChoice& view, int numViews, int outputIndex) {
  std::string ext = extensionOf(format);
  const bool measured = light.measured() && view.measured();
  if (layout == Layout::Ubo2003 && !measured && outputIndex < 0)
    throw Error("decodedImagePath: an unmeasured direction in the UBO2003 layout needs the output index");
  std::string name =
      layout == Layout::Utia ? utiaFileName(light.direction, view.direction, ext)
      : outputIndex >= 0     ? ubo2003FileName(outputIndex, light.direction, view.direction, ext)
                             : ubo2003FileName(light.index * numViews + view.index, light.direction, view.direction, ext);
  return (fs::path(viewFolderName(view.direction)) / name).string();
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

const Srgb8Encoder& srgbEncoder() {
  static const Srgb8Encoder encoder;
  return encoder;
}

// File writes run on their own threads: every atomic write ends with an fsync, which waits
// on the disk (about 4 ms per file measured here) while using no CPU, and concurrent
// fsyncs overlap. The decoding threads hand finished images over through a bounded queue.
class WriterPool {
 public:
  WriterPool(int threads, std::size_t capacity) : capacity_(std::max<std::size_t>(1, capacity)) {
    for (int i = 0; i < threads; ++i) threads_.emplace_back([this] { work(); });
  }
  ~WriterPool() { stop(); }

  // Blocks while the queue is full; throws the first failed write's error.
  void submit(std::function<void()> job) {
    std::unique_lock<std::mutex> lock(mutex_);
    notFull_.wait(lock, [&] { return jobs_.size() < capacity_ || error_; });
    if (error_) std::rethrow_exception(error_);
    jobs_.push_back(std::move(job));
    notEmpty_.notify_one();
  }
  // Waits for every queued write; throws the first failed write's error.
  void finish() {
    stop();
    if (error_) std::rethrow_exception(error_);
  }

 private:
  void stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      closing_ = true;
    }
    notEmpty_.notify_all();
    for (auto& t : threads_)
      if (t.joinable()) t.join();
  }
  void work() {
    while (true) {
      std::function<void()> job;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        notEmpty_.wait(lock, [&] { return !jobs_.empty() || closing_; });
        if (jobs_.empty()) return;
        job = std::move(jobs_.front());
        jobs_.pop_front();
        notFull_.notify_one();
        if (error_) continue;  // after a failure the rest is dropped
      }
      try {
        job();
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!error_) error_ = std::current_exception();
        notFull_.notify_all();
      }
    }
  }

  std::size_t capacity_;
  std::vector<std::thread> threads_;
  std::deque<std::function<void()>> jobs_;
  std::mutex mutex_;
  std::condition_variable notEmpty_, notFull_;
  std::exception_ptr error_;
  bool closing_ = false;
};

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
  const Srgb8Encoder& encode = srgbEncoder();
  const std::size_t values = 3 * static_cast<std::size_t>(r.width) * r.height;
  const std::size_t imageBytes = values * (exr ? sizeof(float) : 1);
  WriterPool writers(kWriterThreads, kQueuedBytes / std::max<std::size_t>(1, imageBytes));
  const auto stopped = [&] { return options.stopFlag && options.stopFlag->load(); };
  std::atomic<int> started{0};
  parallelForDynamic(static_cast<std::size_t>(r.images), [&](std::size_t i, int) {
    if (stopped()) return;
    ++started;
    const DirectionChoice& l = lights[i / r.views];
    const DirectionChoice& v = views[i % r.views];
    std::vector<float> rows;
    std::uint64_t neg = 0;
    std::string path = pathOf(static_cast<int>(i));
    if (decoder.modulated()) {
      // Every texel has its own value: decode the image, then encode texel by texel.
      std::vector<float> linear;
      decodeCheckedImage(decoder, l, v, r.width, r.height, linear, neg, exr ? kHalfMax : INFINITY);
      clamped += neg;
      if (exr) {
        writers.submit([&, path = std::move(path), image = std::move(linear)] {
          writeExr(path, r.width, r.height, image.data(), true, space);
          progress.advance();
        });
      } else {
        Image8 image;
        image.width = r.width, image.height = r.height;
        image.rgb.resize(values);
        for (std::size_t j = 0; j < values; ++j) image.rgb[j] = encode(linear[j]);
        writers.submit([&, path = std::move(path), image = std::move(image)] {
          writeImage8(path, r.format, image, options.jpegQuality);
          progress.advance();
        });
      }
      return;
    }
    decodeCheckedRows(decoder, l, v, rows, neg, exr ? kHalfMax : INFINITY);
    clamped += neg;
    if (exr) {
      std::vector<float> image(values);
      scatterRows(decoder, rows.data(), r.width, r.height, image.data());
      writers.submit([&, path = std::move(path), image = std::move(image)] {
        writeExr(path, r.width, r.height, image.data(), true, space);
        progress.advance();
      });
    } else {
      std::vector<std::uint8_t> rowBytes(rows.size());
      for (std::size_t j = 0; j < rows.size(); ++j) rowBytes[j] = encode(rows[j]);
      Image8 image;
      image.width = r.width, image.height = r.height;
      image.rgb.resize(values);
      scatterRows(decoder, rowBytes.data(), r.width, r.height, image.rgb.data());
      writers.submit([&, path = std::move(path), image = std::move(image)] {
        writeImage8(path, r.format, image, options.jpegQuality);
        progress.advance();
      });
    }
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
  const Srgb8Encoder& encode = srgbEncoder();
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
