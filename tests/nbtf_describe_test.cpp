#include "codec/nbtf_describe.h"

#include <gtest/gtest.h>

#include "codec_fixtures.h"

namespace nbtf {
namespace {

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

TEST(NbtfDescribe, ClusteredFileShowsMethodGeometrySizesAndTraining) {
  CompressedBtf b = testing::makeBtf(5);
  b.metadataJson = R"({"seed": 3, "threads": 2, "config": {"optimizer": "adam"},
                       "training": {"rmse_train": 0.0213, "rmse_holdout": 0.0251, "epochs": 12},
                       "clustering": {"pca_components": 8, "pca_explained_variance_ratio": 0.93,
                                      "kmeans_iterations": 17}})";
  std::string text = describeNbtf(b, "m.nbtf", 4321);
  EXPECT_TRUE(contains(text, "clustered-neural, k = 5 clusters")) << text;
  EXPECT_TRUE(contains(text, "4 x 3 = 12 (crop 3,5,4,3 of 14 x 23 source images)")) << text;
  EXPECT_TRUE(contains(text, "6 (3 lights x 2 views)")) << text;
  EXPECT_TRUE(contains(text, "layout utia, half float")) << text;
  EXPECT_TRUE(contains(text, "alpha          1.75")) << text;
  EXPECT_TRUE(contains(text, "12 -> 6 (ReLU) -> 5 (ReLU) -> 3 (linear), 131 parameters")) << text;
  EXPECT_TRUE(contains(text, "2 images (33.3%) kept out of training")) << text;
  EXPECT_TRUE(contains(text, "RMSE 0.0213 on training images, 0.0251 on held-out images (linear RGB / alpha")) << text;
  EXPECT_TRUE(contains(text, "12 epochs, seed 3, 2 threads, adam")) << text;
  EXPECT_TRUE(contains(text, "PCA with 8 components explains 93.0% of the variance")) << text;
  // Size table: 131 x 4 decoder, 5 x 8 x 4 latents, 12 one-byte ids, raw 12 x 6 x 12.
  EXPECT_TRUE(contains(text, "524 B")) << text;
  EXPECT_TRUE(contains(text, "160 B")) << text;
  EXPECT_TRUE(contains(text, "12 texels x 1 byte")) << text;
  EXPECT_TRUE(contains(text, "696 B")) << text;
  EXPECT_TRUE(contains(text, "864 B")) << text;
  EXPECT_TRUE(contains(text, "4,321 B")) << text;
}

TEST(NbtfDescribe, PerTexelFileWithoutMetadataStillDescribes) {
  CompressedBtf b = testing::makeBtf(0);
  b.holdoutImages.clear();
  b.metadataJson = "{}";
  std::string text = describeNbtf(b, "p.nbtf", 0);
  EXPECT_TRUE(contains(text, "per-texel-neural, one latent per texel")) << text;
  EXPECT_TRUE(contains(text, "none (per-texel")) << text;
  EXPECT_TRUE(contains(text, "none (every image was used")) << text;
  EXPECT_FALSE(contains(text, "training  ")) << text;
}

// The metadata comes from the file, so it is untrusted: odd but valid JSON numbers and
// wrong types must still describe (found by reasoning about the fuzz target, which calls
// describeNbtf on every file that parses: "%.6g" printed a subnormal that std::stod then
// refused to read back, an exception out of `nbtf info`).
TEST(NbtfDescribe, HostileMetadataValuesStillDescribe) {
  CompressedBtf b = testing::makeBtf(5);
  for (const char* meta : {R"({"clustering": {"pca_explained_variance_ratio": 1e-320, "pca_components": "x"}})",
                           R"({"clustering": {"pca_explained_variance_ratio": 1e308}})",
                           R"({"clustering": {"pca_explained_variance_ratio": -5e-324}})",
                           R"({"training": {"rmse_train": 4.9e-324, "epochs": [1]}, "seed": {"a": 1}})",
                           R"({"clustering": 3, "training": null, "config": {"optimizer": 7}})"}) {
    b.metadataJson = meta;
    std::string text;
    ASSERT_NO_THROW(text = describeNbtf(b, "m.nbtf", 0)) << meta;
    EXPECT_TRUE(contains(text, "clustered-neural, k = 5 clusters")) << text;
  }
  b.metadataJson = R"({"clustering": {"pca_explained_variance_ratio": 1e-320, "pca_components": 2}})";
  EXPECT_TRUE(contains(describeNbtf(b, "m.nbtf", 0), "explains 0.0% of the variance"));
}

}  // namespace
}  // namespace nbtf
