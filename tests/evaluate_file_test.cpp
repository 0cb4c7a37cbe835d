// The reference check of `nbtf eval` (eval/evaluate_file.cpp): the reference against the file's source fingerprint.
#include "eval/evaluate_file.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "codec_fixtures.h"
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
