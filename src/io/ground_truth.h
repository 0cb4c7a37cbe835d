// The float ground truth beside a synthetic stack (nbtf-synth, docs/data_tools.md): in the
// stack's folder, ground_truth/<view folder>.exr per view, float32 linear sRGB (Rec. 709
// chromaticities), the light images stacked top to bottom in light order. nbtf eval measures
// a reconstruction against it as well as against the stored (8-bit or half) stack.
#pragma once
#include <string>
#include <vector>

#include "util/directions.h"
#include "util/layout.h"

namespace nbtf {

extern const char* const kGroundTruthFolder;  // "ground_truth"

// DIR/ground_truth/<viewFolderName(view)>.exr
std::string groundTruthPath(const std::string& stackDir, const Direction& view);
// True when DIR has a ground_truth folder with one file for every view.
bool hasGroundTruth(const std::string& stackDir, const std::vector<Direction>& views);

// Reads image `block` of a ground-truth file of `blocks` stacked images (width x height x 3
// linear floats). Checks the file's shape and values; throws nbtf::Error naming the file.
std::vector<float> readGroundTruthBlock(const std::string& path, int block, int blocks, int* width = nullptr,
                                        int* height = nullptr);

// Image `light * views + view` of the ground truth beside a stack, cropped like the stack
// (`crop` empty = whole image), width x height x 3 linear floats.
std::vector<float> readGroundTruthImage(const std::string& stackDir, const std::vector<Direction>& lights,
                                        const std::vector<Direction>& views, int image, const Crop& crop = {});

}  // namespace nbtf
