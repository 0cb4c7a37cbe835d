// The reference check of `nbtf eval` (eval/evaluate_file.cpp): the reference against the file's source fingerprint.
#include "eval/evaluate_file.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "codec_fixtures.h"
#include "gltf/gltf_export.h"
#include "synth/synth_material.h"
#include "model_test_material.h"
#include "pipeline/compress_parts.h"
#include "test_util.h"

namespace nbtf {
namespace {

// A file made from `stack`: its metadata holds the stack's source record.
CompressedBtf madeFrom(const BtfStack& stack) {
  CompressedBtf b = compressedFrame(stack, CodecMethod::ClusteredNeural, 1);
  b.metadataJson = nlohmann::json{{"source", nlohmann::json::parse(sourceMetadataJson(stack))}}.dump();
  return b;
}

// The same stack twice as bright: another material by its per-image means.
BtfStack brighter(const BtfStack& stack) {
  BtfStack other = stack;
  std::vector<float> rgb(3 * static_cast<std::size_t>(stack.numTexels()));
  for (int image = 0; image < stack.numImages(); ++image) {
    stack.imageLinear(image, rgb.data());
    for (float& v : rgb) v *= 2;
    other.setImageLinear(image, rgb.data());
  }
  return other;
}

// A glTF fit is evaluated like a .nbtf: the same RMSE as the export measured, its textures as
// the size; a reference of another size is refused.
TEST(EvaluateFile, AGltfFitIsEvaluatedAgainstItsStackAndTheGroundTruth) {
  const std::string stack = test::tempFilePath("eval_gltf_stack"), out = test::tempFilePath("eval_gltf_fit");
  std::filesystem::remove_all(stack), std::filesystem::remove_all(out);
  synth::SynthOptions so;
  so.preset = "wool";
  so.width = so.height = 8, so.layout = Layout::Utia, so.format = ImageFormat::Png, so.progress = false;
  synth::writeSynthStack(so, stack);
  gltf::ExportOptions eo;
  eo.progress = false, eo.fit.samples = 64, eo.fit.iterations = 5, eo.sheen = eo.specular = gltf::ExtensionMode::Off;
  const gltf::ExportSummary fit = gltf::exportGltf(stack, out, eo);
  EvaluateFileOptions o;
  o.eval.progress = false;
  o.eval.blurSampleImages = 0;
  const EvaluateFileResult r = evaluateFile(out + "/material.gltf", stack, o);
  EXPECT_NEAR(r.result.all.rmse, fit.errors[0].rmse, 1e-5 * fit.errors[0].rmse);
  EXPECT_TRUE(r.result.sizes.gltf);
  EXPECT_EQ(r.result.sizes.total, fit.bytes.total());
  EXPECT_EQ(r.evaluationsPerImage, 64);
  EXPECT_EQ(r.result.methodFamily, "gltf");
  EvaluateFileOptions cropped = o;
  cropped.crop = Crop{0, 0, 4, 4};
  test::expectErrorContaining([&] { evaluateFile(out + "/material.gltf", stack, cropped); },
                              {"material.gltf", "8 x 8", "4 x 4"});
}

TEST(EvaluateFile, TheReferenceTheFileWasMadeFromMatches) {
  const testing::TestMaterial m = testing::makeTestMaterial();
  const std::string line = checkReferenceFingerprint(madeFrom(m.stack), m.stack, "m.nbtf", "ref", false, "nbtf eval");
  EXPECT_EQ(line.rfind("matches the file's source fingerprint (median difference 0.0%, ", 0), 0u) << line;
}

TEST(EvaluateFile, AnotherMaterialIsRefusedUnlessForced) {
  const testing::TestMaterial m = testing::makeTestMaterial();
  const CompressedBtf file = madeFrom(m.stack);
  const BtfStack other = brighter(m.stack);
  test::expectErrorContaining([&] { checkReferenceFingerprint(file, other, "m.nbtf", "other", false, "nbtf eval"); },
                              {"reference 'other' is not the material 'm.nbtf' was made from",
                               "per-image mean linear RGB differs by", "--force uses it anyway"});
  ::testing::internal::CaptureStderr();
  const std::string line = checkReferenceFingerprint(file, other, "m.nbtf", "other", true, "nbtf eval");
  const std::string warning = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(line.rfind("MISMATCH, used anyway (--force): per-image mean linear RGB differs by ", 0), 0u) << line;
  EXPECT_NE(warning.find("nbtf eval: warning: reference 'other'"), std::string::npos) << warning;
  EXPECT_NE(warning.find("using it anyway (--force)"), std::string::npos) << warning;
}

TEST(EvaluateFile, AFileWithoutAFingerprintIsNotChecked) {
  const testing::TestMaterial m = testing::makeTestMaterial();
  CompressedBtf file = madeFrom(m.stack);
  file.metadataJson = R"({"seed": 1})";
  ::testing::internal::CaptureStderr();
  const std::string line = checkReferenceFingerprint(file, brighter(m.stack), "old.nbtf", "ref", false, "nbtf eval");
  const std::string warning = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(line, "not checked: the file has no source fingerprint (made by an older nbtf)");
  EXPECT_NE(warning.find("old.nbtf has no source fingerprint"), std::string::npos) << warning;
}

}  // namespace
}  // namespace nbtf
