// Plugs a compressed material (.nbtf) into the evaluation: checks that the reference is the
// material the file was made from (texel size, light and view directions), and reconstructs
// images with the decoder.
//
// Decoding goes through the codec's decoder API (codec/decoder.h), so the evaluation measures
// exactly what `nbtf decode` and a renderer get. One image needs one decoder evaluation per
// latent row, not per texel: in the clustered mode the k latents are decoded for the image's
// (light, view) and scattered to the texels by the id list.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "codec/decoder.h"
#include "codec/nbtf_file.h"
#include "eval/evaluate.h"
#include "io/btf_stack.h"

namespace nbtf {

// The split generation of each cluster of a file written by `nbtf compress --adaptive`
// (0 = from the initial k-means, +1 per split; the metadata's adaptive.generation), or empty.
std::vector<int> clusterGenerationsOf(const CompressedBtf& btf);

class CompressedReconstruction {
 public:
  // Copies `btf` into a decoder. Throws nbtf::Error if the decoder does not take
  // latentDim + 4 inputs and give 3 outputs, or the material is otherwise invalid.
  explicit CompressedReconstruction(const CompressedBtf& btf, const std::string& name = "compressed BTF");

  // Image `image` (= light * views + view) as linear RGB: decoder output x alpha, not
  // clamped (the metric sees what the model predicts). width * height * 3 floats.
  // Thread-safe.
  void image(int image, float* linearRgb) const;
  // Decoder evaluations per image: k (clustered) or the texel count (per-texel).
  int evaluationsPerImage() const { return decoder_.latentRows(); }
  const NbtfDecoder& decoder() const { return decoder_; }

 private:
  NbtfDecoder decoder_;
};

// Throws nbtf::Error naming both sources and the first thing that differs: texel size, number
// of lights or views, or a direction (index and both angles; 0.001 degree tolerance).
void checkReferenceMatches(const CompressedBtf& btf, const BtfStack& reference, const std::string& fileName,
                           const std::string& referenceName);

// Table 1 sizes of the file (fileBytes = its size on disk, 0 = unknown).
SizeTable sizeTableOf(const CompressedBtf& btf, std::uint64_t fileBytes);

// Everything evaluate() needs, from the file and its matching reference. `reconstruction`
// must outlive the returned inputs.
EvalInputs compressedEvalInputs(const CompressedBtf& btf, const BtfStack& reference,
                                const CompressedReconstruction& reconstruction, const std::string& fileName,
                                const std::string& referenceName, std::uint64_t fileBytes);

}  // namespace nbtf
