// The BTF data model: an image stack indexed by (light, view), stored compactly.
//
// Storage is image-major: image i = light * numViews + view holds height x width x RGB.
// 8-bit sources stay 8-bit sRGB in memory (4x smaller than float32) and are linearized
// on access through a table; EXR sources stay half floats. An ABRDF is one texel's
// values over all images: out[3 * image + channel], linear.
//
// A stack can also compute its values instead of storing them (ComputedStackValues: a
// factorized UBO2014 material, io/ubo2014_btf.h), so that a material larger than memory as
// half floats can still be compressed. Every linear accessor works on both; the raw-storage
// ones (imageBytes, setImageLinear) exist only for stored stacks.
//
// A stored stack's samples are in memory, or in an unnamed scratch file mapped into memory
// (util/scratch_mapping.h) when they would not fit beside the run's working sets: the same
// bytes and accessors, the pages held by the system's file cache instead of the process.
#pragma once
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "util/directions.h"
#include "util/layout.h"
#include "util/page_buffer.h"
#include "util/scratch_mapping.h"

namespace nbtf {

// Values of a stack computed on demand. Each function gives exactly the values a stored stack
// of the same material would hold (e.g. rounded to half floats), so results never depend on
// which of the two a loader chose.
class ComputedStackValues {
 public:
  virtual ~ComputedStackValues() = default;
  // One image, linear RGB, texels x 3 floats.
  virtual void image(int image, float* out) const = 0;
  // One texel's value in one image, linear RGB.
  virtual void value(int image, int texel, float rgb[3]) const = 0;
  // texels[k] in images[j] (nullptr: every image, j = image): out[(3 j + c) x count + k].
  virtual void gather(const int* images, int numImages, const int* texels, int count, float* out) const = 0;
  // Bytes the computation keeps in memory (the factors).
  virtual std::size_t bytes() const = 0;
};

class BtfStack {
 public:
  BtfStack() = default;
  BtfStack(std::vector<Direction> lights, std::vector<Direction> views, int width, int height, SampleType type);
  // The same with the samples in a scratch file under `scratchDir` ("" = in memory). Throws
  // nbtf::FileAccessError naming the folder when the file cannot be made there. Copies of such
  // a stack share its samples.
  BtfStack(std::vector<Direction> lights, std::vector<Direction> views, int width, int height, SampleType type,
           const std::string& scratchDir);
  // A stack whose values are computed (no storage); `type` is the precision they are rounded to.
  BtfStack(std::vector<Direction> lights, std::vector<Direction> views, int width, int height, SampleType type,
           std::shared_ptr<const ComputedStackValues> values);

  // ---- Shape
  int numLights() const { return static_cast<int>(lights_.size()); }
  int numViews() const { return static_cast<int>(views_.size()); }
  int numImages() const { return numLights() * numViews(); }
  int width() const { return width_; }
  int height() const { return height_; }
  int numTexels() const { return width_ * height_; }
  int imageIndex(int light, int view) const { return light * numViews() + view; }
  const std::vector<Direction>& lights() const { return lights_; }
  const std::vector<Direction>& views() const { return views_; }
  SampleType sampleType() const { return type_; }
  bool isComputed() const { return computed_ != nullptr; }
  // Whether the stored samples live in a scratch file (the folder it is in; "" = in memory).
  bool inScratchFile() const { return scratch_ != nullptr; }
  std::string scratchDirectory() const;
  // Bytes the values take in the process's memory: the stored samples, what a computed stack
  // keeps, or 0 for samples in a scratch file.
  std::size_t bytesInMemory() const { return computed_ ? computed_->bytes() : scratch_ ? 0 : data_.size(); }
  // Bytes this stack would take as linear float32 RGB (the paper's "raw" size).
  std::size_t rawFloat32Bytes() const { return static_cast<std::size_t>(numImages()) * numTexels() * 3 * 4; }

  // ---- Linear access
  float sample(int image, int texel, int channel) const;
  // One whole image, linear RGB, width * height * 3 floats.
  void imageLinear(int image, float* out) const;
  // One texel's ABRDF, linear: out[3 * image + channel], numImages * 3 floats.
  void abrdfLinear(int texel, float* out) const;
  std::vector<float> abrdfLinear(int texel) const;
  // Several texels in several images (images == nullptr: all, numImages ignored), linear,
  // dimension-major: out[(3 j + c) x count + k] is texels[k] in images[j] (a count x 3 images
  // column-major matrix). Reads image by image, so a stored stack is read in order.
  void gatherLinear(const int* images, int numImages, const int* texels, int count, float* out) const;
  // gatherLinear's values as the stack holds them, storedValueBytes() bytes each: the 8-bit
  // code, the half's bits, or (a computed stack) the float. A batch of them takes a quarter
  // (8-bit) or half the memory of floats; storedToLinear turns `count` consecutive ones into
  // gatherLinear's values times `scale` (the same floats as multiplying those afterwards).
  std::size_t storedValueBytes() const { return computed_ ? sizeof(float) : bytesPerSample(); }
  void gatherStored(const int* images, int numImages, const int* texels, int count, std::uint8_t* out) const;
  void storedToLinear(const std::uint8_t* values, std::size_t count, float scale, float* out) const;
  // Smallest and largest linear value over the whole stack.
  void valueRange(float& lo, float& hi) const;

  // ---- Raw storage (loaders and writers; stored stacks only: a computed one throws)
  std::uint8_t* imageBytes(int image);
  const std::uint8_t* imageBytes(int image) const;
  // Bytes [first, first + count) of image `image`, for reading: a pointer into memory, or, for a
  // stack in a scratch file, those bytes copied into `buffer` (resized as needed) by read calls.
  // Passes over a whole stack read it this way: through the mapping, every pass over a stack
  // larger than the mapping's budget maps it again fault by fault, several times slower.
  const std::uint8_t* readImageBytes(int image, std::size_t first, std::size_t count,
                                     std::vector<std::uint8_t>& buffer) const;
  std::size_t bytesPerImage() const { return static_cast<std::size_t>(numTexels()) * 3 * bytesPerSample(); }
  std::size_t bytesPerSample() const { return type_ == SampleType::Srgb8 ? 1 : 2; }
  // Stores one image's bytes (bytesPerImage of them): copied into memory, or written to the
  // scratch file by write calls (no page faults).
  void writeImageBytes(int image, const std::uint8_t* bytes);
  // Stores linear floats into image `image` (converted to the stack's sample type).
  void setImageLinear(int image, const float* rgb);

  // ---- Provenance
  std::string source;        // path it was loaded from
  Layout layout = Layout::Unknown;
  int sourceWidth = 0, sourceHeight = 0;  // full image size on disk
  Crop crop;                 // the crop applied while loading (empty = none)

 private:
  std::vector<Direction> lights_, views_;
  int width_ = 0, height_ = 0;
  SampleType type_ = SampleType::Srgb8;
  std::uint8_t* samples() { return scratch_ ? scratch_->data() : data_.data(); }
  const std::uint8_t* samples() const { return scratch_ ? scratch_->data() : data_.data(); }
  std::size_t sampleBytes() const { return scratch_ ? scratch_->size() : data_.size(); }
  // Calls put(j, c, k, sample) for texels[k] in images[j], channel c, with a pointer to the
  // stored sample (bytesPerSample bytes); image by image, reading each image's span once.
  template <class Put>
  void forEachGathered(const int* images, int numImages, const int* texels, int count, Put put) const;

  PageBuffer data_;  // the samples in memory (zero until written; see util/page_buffer.h)
  std::shared_ptr<ScratchMapping> scratch_;  // the samples, when they live in a scratch file
  std::shared_ptr<const ComputedStackValues> computed_;
};

}  // namespace nbtf
