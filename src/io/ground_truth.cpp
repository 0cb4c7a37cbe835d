#include "io/ground_truth.h"

#include <ImfChannelList.h>
#include <ImfChromaticities.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfStandardAttributes.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "io/btf_names.h"
#include "util/error.h"

namespace nbtf {

const char* const kGroundTruthFolder = "ground_truth";

std::string groundTruthPath(const std::string& stackDir, const Direction& view) {
  return (std::filesystem::path(stackDir) / kGroundTruthFolder / (viewFolderName(view) + ".exr")).string();
}

bool hasGroundTruth(const std::string& stackDir, const std::vector<Direction>& views) {
  std::error_code ec;
  if (views.empty() || !std::filesystem::is_directory(std::filesystem::path(stackDir) / kGroundTruthFolder, ec))
    return false;
  for (const Direction& v : views)
    if (!std::filesystem::is_regular_file(groundTruthPath(stackDir, v), ec)) return false;
  return true;
}

std::vector<float> readGroundTruthBlock(const std::string& path, int block, int blocks, int* widthOut,
                                        int* heightOut) {
  std::vector<float> rgb;
  int width = 0, height = 0;
  try {
    Imf::InputFile file(path.c_str());
    const Imf::Header& header = file.header();
    Imath::Box2i dw = header.dataWindow();
    width = dw.max.x - dw.min.x + 1;
    int total = dw.max.y - dw.min.y + 1;
    if (total % blocks != 0) {
      std::ostringstream s;
      s << "ground truth is " << width << " x " << total << ", not " << blocks << " images stacked vertically";
      throw fileError(path, s.str());
    }
    height = total / blocks;
    for (const char* c : {"R", "G", "B"})
      if (!header.channels().findChannel(c)) throw fileError(path, std::string("ground truth has no channel ") + c);
    if (Imf::hasChromaticities(header) && Imf::chromaticities(header).red.x > 0.99f)
      throw fileError(path, "ground truth is tagged CIE XYZ; nbtf-synth writes linear sRGB");
    if (!file.isComplete()) throw fileError(path, "EXR is truncated (incomplete pixel data)");
    rgb.assign(static_cast<std::size_t>(width) * height * 3, 0.0f);
    int first = dw.min.y + block * height;
    const std::size_t stride = static_cast<std::size_t>(width) * 3 * sizeof(float);
    char* base = reinterpret_cast<char*>(rgb.data()) - static_cast<std::ptrdiff_t>(dw.min.x) * 3 * sizeof(float) -
                 static_cast<std::ptrdiff_t>(first) * static_cast<std::ptrdiff_t>(stride);
    Imf::FrameBuffer fb;
    const char* names[3] = {"R", "G", "B"};
    for (int c = 0; c < 3; ++c)
      fb.insert(names[c], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), 3 * sizeof(float), stride));
    file.setFrameBuffer(fb);
    file.readPixels(first, first + height - 1);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw fileError(path, std::string("cannot read ground truth EXR: ") + e.what());
  }
  for (std::size_t i = 0; i < rgb.size(); ++i)
    if (!std::isfinite(rgb[i]) || rgb[i] < 0) {
      std::ostringstream s;
      s << "ground truth image " << block << " has value " << rgb[i] << " at texel " << i / 3
        << "; values must be finite and non-negative";
      throw fileError(path, s.str());
    }
  if (widthOut) *widthOut = width;
  if (heightOut) *heightOut = height;
  return rgb;
}

std::vector<float> readGroundTruthImage(const std::string& stackDir, const std::vector<Direction>& lights,
                                        const std::vector<Direction>& views, int image, const Crop& crop) {
  const int nl = static_cast<int>(lights.size()), nv = static_cast<int>(views.size());
  if (image < 0 || image >= nl * nv)
    throw Error("ground truth image " + std::to_string(image) + " is out of range (0 to " +
                std::to_string(nl * nv - 1) + ")");
  const std::string path = groundTruthPath(stackDir, views[image % nv]);
  int width = 0, height = 0;
  std::vector<float> rgb = readGroundTruthBlock(path, image / nv, nl, &width, &height);
  if (crop.empty()) return rgb;
  if (crop.x + crop.width > width || crop.y + crop.height > height)
    throw fileError(path, "crop " + std::to_string(crop.x) + "," + std::to_string(crop.y) + "," +
                              std::to_string(crop.width) + "," + std::to_string(crop.height) + " lies outside the " +
                              std::to_string(width) + " x " + std::to_string(height) + " ground truth");
  std::vector<float> out(static_cast<std::size_t>(crop.width) * crop.height * 3);
  for (int y = 0; y < crop.height; ++y)
    std::copy_n(rgb.begin() + (static_cast<std::size_t>(crop.y + y) * width + crop.x) * 3,
                static_cast<std::size_t>(crop.width) * 3, out.begin() + static_cast<std::size_t>(y) * crop.width * 3);
  return out;
}

}  // namespace nbtf
