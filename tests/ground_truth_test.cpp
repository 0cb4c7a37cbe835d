// The float ground truth beside a synthetic stack (io/ground_truth.h) and nbtf eval's
// measurement against it (EvalInputs::groundTruth).
#include "io/ground_truth.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "eval/evaluate.h"
#include "io/btf_loader.h"
#include "synth/synth_material.h"
#include "test_util.h"
#include "util/error.h"
#include "util/progress.h"

namespace nbtf {
namespace {

// An 8 x 8 fabric in the UTIA layout (PNG) with its ground truth.
std::string writeStack(const std::string& dir) {
  synth::SynthOptions o;
  o.preset = "fabric";
  o.width = o.height = 8;
  o.seed = 3;
  o.layout = Layout::Utia;
  o.format = ImageFormat::Png;
  o.progress = false;
  synth::writeSynthStack(o, dir);
  return dir;
}

BtfStack load(const std::string& dir, const Crop& crop = {}) {
  LoadOptions options;
  options.crop = crop;
  options.progress = false;
  return loadBtfStack(dir, options);
}

// One stack for the suite: writing it is most of the time.
class GroundTruth : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    Progress::setQuiet(true);
    tmp_ = new test::TempDir;
    dir_ = writeStack((std::filesystem::path(tmp_->path()) / "fabric").string());
  }
  static void TearDownTestSuite() { delete tmp_; }
  static test::TempDir* tmp_;
  static std::string dir_;
};
test::TempDir* GroundTruth::tmp_ = nullptr;
std::string GroundTruth::dir_;

TEST_F(GroundTruth, EvalMeasuresTheReconstructionAndTheStoredStackAgainstIt) {
  const std::string& dir = dir_;
  const BtfStack stack = load(dir);
  ASSERT_TRUE(hasGroundTruth(dir, stack.views()));
  EvalInputs in;
  in.reference = &stack;
  in.groundTruth = groundTruthBeside(dir, stack, {});
  ASSERT_TRUE(static_cast<bool>(in.groundTruth));
  // The stored stack as the reconstruction: no error against itself, and against the ground
  // truth exactly the stack's own (its quantization).
  in.reconstruct = [&](int image, float* out) { stack.imageLinear(image, out); };
  in.holdoutImages = {5, 700};
  EvalOptions options;
  options.progress = false;
  options.blurSampleImages = 1;
  const EvalResult r = evaluate(in, options);
  ASSERT_TRUE(r.hasGroundTruth);
  EXPECT_EQ(r.all.rmse, 0.0);
  EXPECT_GT(r.groundTruthAll.rmse, 0.0);
  EXPECT_GT(r.groundTruthHoldout.rmse, 0.0);
  EXPECT_EQ(r.referenceVsGroundTruth.rmse, r.groundTruthAll.rmse);
  EXPECT_EQ(r.referenceVsGroundTruth.count, r.all.count);
  EXPECT_EQ(r.referenceVsGroundTruthHoldout.rmse, r.groundTruthHoldout.rmse);
  // UTIA PNGs are lossless: their floor is the 8-bit steps alone.
  EXPECT_EQ(r.referenceEncoding, "8-bit sRGB");
  EXPECT_NE(r.noiseFloorCause.find("8-bit steps"), std::string::npos);
  // 8-bit sRGB PNGs: the quantization stays below half a code step of the brightest values.
  EXPECT_LT(r.groundTruthAll.rmseSrgb8, 0.5);
}

TEST_F(GroundTruth, IsCroppedAsTheStackAndAbsentWithoutItsFolder) {
  const std::string& dir = dir_;
  const BtfStack whole = load(dir);
  const Crop crop{2, 3, 4, 5};
  const BtfStack cropped = load(dir, crop);
  const int image = 81 * 40 + 17;
  std::vector<float> full(static_cast<std::size_t>(whole.numTexels()) * 3), part(static_cast<std::size_t>(cropped.numTexels()) * 3);
  groundTruthBeside(dir, whole, {})(image, full.data());
  groundTruthBeside(dir, cropped, crop)(image, part.data());
  for (int y = 0; y < crop.height; ++y)
    for (int x = 0; x < crop.width; ++x)
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(part[(y * crop.width + x) * 3 + c], full[((crop.y + y) * whole.width() + crop.x + x) * 3 + c]);
  // A crop beyond the ground truth's images is refused by name.
  test::expectErrorContaining([&] { readGroundTruthImage(dir, whole.lights(), whole.views(), image, Crop{6, 0, 4, 4}); },
                              {"ground_truth", "lies outside the 8 x 8 ground truth"});
  std::filesystem::remove_all(std::filesystem::path(dir) / kGroundTruthFolder);
  EXPECT_FALSE(hasGroundTruth(dir, whole.views()));
  EXPECT_FALSE(static_cast<bool>(groundTruthBeside(dir, whole, {})));
}

}  // namespace
}  // namespace nbtf
