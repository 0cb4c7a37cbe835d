#include "synth/ground_truth.h"

#include <ImfChannelList.h>
#include <ImfChromaticities.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStandardAttributes.h>

#include <cmath>
#include <sstream>

#include "util/error.h"

namespace nbtf::synth {

struct GroundTruthWriter::File {
  std::unique_ptr<Imf::OutputFile> out;
};

GroundTruthWriter::GroundTruthWriter(const std::string& path, int width, int height, int blocks,
                                     const std::string& comment)
    : file_(std::make_unique<File>()), path_(path), width_(width), height_(height), blocks_(blocks) {
  try {
    Imf::Header header(width, height * blocks);
    // Rendered float32 values hardly compress (ZIP saves ~4 % and doubled the generator's
    // run time): store them plainly.
    header.compression() = Imf::NO_COMPRESSION;
    for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
    Imf::addChromaticities(header, Imf::Chromaticities());  // Rec. 709 primaries, D65: linear sRGB
    if (!comment.empty()) Imf::addComments(header, comment);
    file_->out = std::make_unique<Imf::OutputFile>(path.c_str(), header);
  } catch (const std::exception& e) {
    throw fileError(path, std::string("cannot create EXR: ") + e.what());
  }
}

GroundTruthWriter::~GroundTruthWriter() = default;

void GroundTruthWriter::append(const float* rgb) {
  if (written_ >= blocks_) throw fileError(path_, "ground truth already holds all its images");
  try {
    // Slices address absolute scan lines: shift the base so this block's first row is y = 0.
    const std::size_t stride = static_cast<std::size_t>(width_) * 3 * sizeof(float);
    char* base = const_cast<char*>(reinterpret_cast<const char*>(rgb)) -
                 static_cast<std::ptrdiff_t>(written_) * height_ * static_cast<std::ptrdiff_t>(stride);
    Imf::FrameBuffer fb;
    const char* names[3] = {"R", "G", "B"};
    for (int c = 0; c < 3; ++c)
      fb.insert(names[c], Imf::Slice(Imf::FLOAT, base + c * sizeof(float), 3 * sizeof(float), stride));
    file_->out->setFrameBuffer(fb);
    file_->out->writePixels(height_);
  } catch (const std::exception& e) {
    throw fileError(path_, std::string("cannot write EXR: ") + e.what());
  }
  ++written_;
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

}  // namespace nbtf::synth
