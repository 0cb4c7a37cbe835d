// A rendered comparison in the evaluation report: the folder `nbtf render --compare` writes
// (compare.json, reference.png, compressed.png, error.png) read back, so `nbtf eval
// --render-compare DIR` shows the paper's Tables 3-4 quantities (RMSE of the whole rendered
// image and of its darkest and brightest 10%) beside the per-image metrics.
#pragma once
#include <string>

#include "io/image_io.h"

namespace nbtf {

struct RenderSection {
  std::string folder, scene, sampling, reference, compressed, space;
  int width = 0, height = 0;
  double rmseAll = 0, rmseDark = 0, rmseBright = 0, errorMagnification = 1;
  Image8 referenceImage, compressedImage, errorImage;
  bool present() const { return !folder.empty(); }
};

// Reads the folder; every missing file or key is an nbtf::Error naming it.
RenderSection loadRenderSection(const std::string& folder);

}  // namespace nbtf
