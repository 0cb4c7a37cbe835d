// The exact ground truth of a synthetic stack: per view one float32 OpenEXR in linear
// sRGB (Rec. 709 chromaticities), its 81 light images stacked top to bottom in light
// order, so the file is width x (81 * height). Written image by image as they are
// rendered (memory stays one image, whatever the size) and read back one image at a time.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "io/ground_truth.h"

namespace nbtf::synth {

class GroundTruthWriter {
 public:
  // Opens `path` (pass a temporary name: see writeAtomicVia) for `blocks` images.
  GroundTruthWriter(const std::string& path, int width, int height, int blocks, const std::string& comment);
  ~GroundTruthWriter();
  // Appends the next image (width * height * 3 linear floats).
  void append(const float* rgb);
  int written() const { return written_; }

 private:
  struct File;
  std::unique_ptr<File> file_;
  std::string path_;
  int width_, height_, blocks_, written_ = 0;
};

using nbtf::readGroundTruthBlock;  // the reader is in io/ground_truth.h (nbtf eval reads it too)

}  // namespace nbtf::synth
