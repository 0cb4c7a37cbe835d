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

}  // namespace nbtf::synth
