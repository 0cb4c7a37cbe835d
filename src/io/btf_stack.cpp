#include "io/btf_stack.h"

#include <Imath/half.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <sstream>

#include "io/color.h"
#include "util/error.h"
#include "util/parallel.h"

namespace nbtf {

BtfStack::BtfStack(std::vector<Direction> lights, std::vector<Direction> views, int width, int height,
                   SampleType type)
    : BtfStack(std::move(lights), std::move(views), width, height, type, std::string()) {}

BtfStack::BtfStack(std::vector<Direction> lights, std::vector<Direction> views, int width, int height,
                   SampleType type, const std::string& scratchDir)
    : lights_(std::move(lights)), views_(std::move(views)), width_(width), height_(height), type_(type) {
  const std::size_t bytes = static_cast<std::size_t>(numImages()) * bytesPerImage();
  if (scratchDir.empty())
    data_ = PageBuffer(bytes);
  else
    scratch_ = std::make_shared<ScratchMapping>(
        scratchDir, bytes, type == SampleType::Srgb8 ? "the 8-bit stack" : "the half-float stack");
}

std::string BtfStack::scratchDirectory() const { return scratch_ ? scratch_->directory() : std::string(); }

BtfStack::BtfStack(std::vector<Direction> lights, std::vector<Direction> views, int width, int height,
                   SampleType type, std::shared_ptr<const ComputedStackValues> values)
    : lights_(std::move(lights)), views_(std::move(views)), width_(width), height_(height), type_(type),
      computed_(std::move(values)) {
  if (!computed_) throw Error("BtfStack: a computed stack needs its values");
}

namespace {
[[noreturn]] void noStoredBytes(const std::string& source) {
  throw Error((source.empty() ? std::string("this stack") : source) +
              ": its values are computed from factors on demand; it has no stored image bytes");
}
}  // namespace

std::uint8_t* BtfStack::imageBytes(int image) {
  if (computed_) noStoredBytes(source);
  return samples() + static_cast<std::size_t>(image) * bytesPerImage();
}
const std::uint8_t* BtfStack::imageBytes(int image) const {
  if (computed_) noStoredBytes(source);
  return samples() + static_cast<std::size_t>(image) * bytesPerImage();
}

const std::uint8_t* BtfStack::readImageBytes(int image, std::size_t first, std::size_t count,
                                             std::vector<std::uint8_t>& buffer) const {
  if (!scratch_) return imageBytes(image) + first;
  if (first > bytesPerImage() || count > bytesPerImage() - first)
    throw Error("BtfStack::readImageBytes: bytes past the end of an image");
  buffer.resize(count);
  scratch_->read(static_cast<std::size_t>(image) * bytesPerImage() + first, count, buffer.data());
  return buffer.data();
}

namespace {
// One buffer per thread for the images a stack in a scratch file copies out: reused, so that
// reading an image does not fault in a fresh allocation every time.
std::vector<std::uint8_t>& threadImageBuffer() {
  thread_local std::vector<std::uint8_t> buffer;
  return buffer;
}

inline float halfToFloat(std::uint16_t bits) {
  Imath::half h;
  h.setBits(bits);
  return static_cast<float>(h);
}
}  // namespace

float BtfStack::sample(int image, int texel, int channel) const {
  if (computed_) {
    float rgb[3];
    computed_->value(image, texel, rgb);
    return rgb[channel];
  }
  std::size_t i = static_cast<std::size_t>(texel) * 3 + channel;
  if (type_ == SampleType::Srgb8) return srgb8ToLinearTable()[imageBytes(image)[i]];
  std::uint16_t bits;
  std::memcpy(&bits, imageBytes(image) + 2 * i, 2);
  return halfToFloat(bits);
}

void BtfStack::imageLinear(int image, float* out) const {
  if (computed_) return computed_->image(image, out);
  std::size_t n = static_cast<std::size_t>(numTexels()) * 3;
  const std::uint8_t* src = readImageBytes(image, 0, bytesPerImage(), threadImageBuffer());
  if (type_ == SampleType::Srgb8) {
    const float* lut = srgb8ToLinearTable();
    for (std::size_t i = 0; i < n; ++i) out[i] = lut[src[i]];
  } else {
    const std::uint16_t* h = reinterpret_cast<const std::uint16_t*>(src);
    for (std::size_t i = 0; i < n; ++i) out[i] = halfToFloat(h[i]);
  }
}

void BtfStack::abrdfLinear(int texel, float* out) const {
  if (computed_) return computed_->gather(nullptr, numImages(), &texel, 1, out);  // count 1: the same layout
  std::size_t offset = static_cast<std::size_t>(texel) * 3;
  int n = numImages();
  if (type_ == SampleType::Srgb8) {
    const float* lut = srgb8ToLinearTable();
    for (int i = 0; i < n; ++i) {
      const std::uint8_t* p = imageBytes(i) + offset;
      out[3 * i] = lut[p[0]], out[3 * i + 1] = lut[p[1]], out[3 * i + 2] = lut[p[2]];
    }
  } else {
    for (int i = 0; i < n; ++i) {
      const std::uint16_t* p = reinterpret_cast<const std::uint16_t*>(imageBytes(i)) + offset;
      out[3 * i] = halfToFloat(p[0]), out[3 * i + 1] = halfToFloat(p[1]), out[3 * i + 2] = halfToFloat(p[2]);
    }
  }
}

std::vector<float> BtfStack::abrdfLinear(int texel) const {
  std::vector<float> out(static_cast<std::size_t>(numImages()) * 3);
  abrdfLinear(texel, out.data());
  return out;
}

template <class Put>
void BtfStack::forEachGathered(const int* images, int numImages, const int* texels, int count, Put put) const {
  if (!images) numImages = this->numImages();
  // In a scratch file, the span of texels the gather covers is copied out of each image when it
  // is at most 64 times what the gather needs (a slice, or a batch of clusters); a scattered few
  // texels are read through the mapping.
  int lo = 0, hi = -1;
  if (scratch_ && count > 0) {
    const auto [mn, mx] = std::minmax_element(texels, texels + count);
    if (static_cast<std::int64_t>(*mx) - *mn + 1 <= std::int64_t(64) * count) lo = *mn, hi = *mx;
  }
  const std::size_t sample = bytesPerSample();
  const std::size_t spanFirst = static_cast<std::size_t>(lo) * 3 * sample;
  const std::size_t spanBytes = static_cast<std::size_t>(hi - lo + 1) * 3 * sample;
  for (int j = 0; j < numImages; ++j) {
    const int image = images ? images[j] : j;
    // src starts at texel lo.
    const std::uint8_t* src =
        hi >= lo ? readImageBytes(image, spanFirst, spanBytes, threadImageBuffer()) : imageBytes(image);
    for (int k = 0; k < count; ++k) {
      const std::uint8_t* texel = src + static_cast<std::size_t>(texels[k] - lo) * 3 * sample;
      for (int c = 0; c < 3; ++c) put(j, c, k, texel + c * sample);
    }
  }
}

void BtfStack::gatherLinear(const int* images, int numImages, const int* texels, int count, float* out) const {
  if (computed_) return computed_->gather(images, numImages, texels, count, out);
  const float* lut = type_ == SampleType::Srgb8 ? srgb8ToLinearTable() : nullptr;
  forEachGathered(images, numImages, texels, count, [&](int j, int c, int k, const std::uint8_t* sample) {
    float v;
    if (lut) {
      v = lut[*sample];
    } else {
      std::uint16_t bits;
      std::memcpy(&bits, sample, 2);
      v = halfToFloat(bits);
    }
    out[static_cast<std::size_t>(3 * j + c) * count + k] = v;
  });
}

void BtfStack::gatherStored(const int* images, int numImages, const int* texels, int count, std::uint8_t* out) const {
  if (computed_) {
    const std::size_t n = static_cast<std::size_t>(3) * (images ? numImages : this->numImages()) * count;
    std::vector<float> values(n);
    computed_->gather(images, numImages, texels, count, values.data());
    std::memcpy(out, values.data(), n * sizeof(float));
    return;
  }
  if (type_ == SampleType::Srgb8)
    forEachGathered(images, numImages, texels, count, [&](int j, int c, int k, const std::uint8_t* sample) {
      out[static_cast<std::size_t>(3 * j + c) * count + k] = *sample;
    });
  else
    forEachGathered(images, numImages, texels, count, [&](int j, int c, int k, const std::uint8_t* sample) {
      std::memcpy(out + 2 * (static_cast<std::size_t>(3 * j + c) * count + k), sample, 2);
    });
}

void BtfStack::storedToLinear(const std::uint8_t* values, std::size_t count, float scale, float* out) const {
  if (computed_) {
    for (std::size_t i = 0; i < count; ++i) {
      float v;
      std::memcpy(&v, values + sizeof(float) * i, sizeof(float));
      out[i] = v * scale;
    }
  } else if (type_ == SampleType::Srgb8) {
    const float* lut = srgb8ToLinearTable();
    for (std::size_t i = 0; i < count; ++i) out[i] = lut[values[i]] * scale;
  } else {
    for (std::size_t i = 0; i < count; ++i) {
      std::uint16_t bits;
      std::memcpy(&bits, values + 2 * i, 2);
      out[i] = halfToFloat(bits) * scale;
    }
  }
}

void BtfStack::valueRange(float& lo, float& hi) const {
  lo = std::numeric_limits<float>::infinity();
  hi = -lo;
  if (computed_) {
    // Image by image in parallel; min and max do not depend on the order.
    const int workers = threadCount();
    std::vector<float> los(workers, lo), his(workers, hi);
    std::vector<std::vector<float>> buffers(workers);
    parallelForDynamic(numImages(), [&](std::size_t image, int worker) {
      std::vector<float>& rgb = buffers[worker];
      rgb.resize(static_cast<std::size_t>(numTexels()) * 3);
      computed_->image(static_cast<int>(image), rgb.data());
      for (float v : rgb) los[worker] = std::min(los[worker], v), his[worker] = std::max(his[worker], v);
    });
    for (int w = 0; w < workers; ++w) lo = std::min(lo, los[w]), hi = std::max(hi, his[w]);
    if (numImages() == 0 || numTexels() == 0) lo = hi = 0;
    return;
  }
  if (sampleBytes() == 0) {
    lo = hi = 0;
    return;
  }
  if (type_ == SampleType::Srgb8) {
    auto [mn, mx] = std::minmax_element(samples(), samples() + sampleBytes());
    lo = srgb8ToLinear(*mn), hi = srgb8ToLinear(*mx);
    return;
  }
  const std::uint16_t* h = reinterpret_cast<const std::uint16_t*>(samples());
  for (std::size_t i = 0, n = sampleBytes() / 2; i < n; ++i) {
    float v = halfToFloat(h[i]);
    lo = std::min(lo, v), hi = std::max(hi, v);
  }
}

void BtfStack::writeImageBytes(int image, const std::uint8_t* bytes) {
  std::uint8_t* dst = imageBytes(image);  // throws for a computed stack
  if (scratch_)
    scratch_->write(static_cast<std::size_t>(image) * bytesPerImage(), bytesPerImage(), bytes);
  else
    std::copy_n(bytes, bytesPerImage(), dst);
}

void BtfStack::setImageLinear(int image, const float* rgb) {
  std::size_t n = static_cast<std::size_t>(numTexels()) * 3;
  std::vector<std::uint8_t>& converted = threadImageBuffer();
  if (scratch_) converted.resize(bytesPerImage());
  std::uint8_t* dst = scratch_ ? converted.data() : imageBytes(image);  // imageBytes throws for a computed stack
  if (type_ == SampleType::Srgb8) {
    for (std::size_t i = 0; i < n; ++i) dst[i] = linearToSrgb8(rgb[i]);
  } else {
    std::uint16_t* h = reinterpret_cast<std::uint16_t*>(dst);
    for (std::size_t i = 0; i < n; ++i) h[i] = Imath::half(rgb[i]).bits();
  }
  if (scratch_) writeImageBytes(image, dst);
}

}  // namespace nbtf
