// The names a decode gives its images, the ones the loaders read (io/btf_names.h).
#pragma once
#include <string>

#include "io/image_io.h"
#include "pipeline/decode_selection.h"
#include "util/layout.h"

namespace nbtf {

// Path of one image relative to the output folder. One naming per layout: UBO2003 names
// carry a running number, the source's image number (light x views + view) when both
// directions are measured, else `outputIndex` (the decode numbers all of its images by their
// position in the output whenever one of them is unmeasured, so numbers never collide).
std::string decodedImagePath(Layout layout, ImageFormat format, const DirectionChoice& light,
                             const DirectionChoice& view, int numViews, int outputIndex = -1);

}  // namespace nbtf
