// `nbtf info --json` of a material (codec/nbtf_info.cpp): the description and the part sizes it shows, for each kind.
#include "codec/nbtf_info.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "codec/nbtf_file.h"
#include "codec_fixtures.h"

namespace nbtf {
namespace {

using nlohmann::json;

TEST(NbtfInfo, ClusteredJsonDescribesTheMaterial) {
  const CompressedBtf b = testing::makeBtf(5);
  const json j = json::parse(nbtfInfoJson(b, "m.nbtf", 1234));
  EXPECT_EQ(j["kind"], "nbtf");
  EXPECT_EQ(j["file"], "m.nbtf");
  EXPECT_EQ(j["format_version"], std::to_string(b.formatMajor) + "." + std::to_string(b.formatMinor));
  EXPECT_EQ(j["method"], "clustered-neural");
  EXPECT_EQ(j["width"], 4);
  EXPECT_EQ(j["height"], 3);
  EXPECT_EQ(j["image_size"], json({14, 23}));
  EXPECT_EQ(j["crop"], json({3, 5, 4, 3}));
  EXPECT_EQ(j["layout"], "utia");
  EXPECT_EQ(j["lights"], 3);
  EXPECT_EQ(j["views"], 2);
  EXPECT_EQ(j["images"], 6);
  EXPECT_EQ(j["clusters"], 5);
  EXPECT_EQ(j["latent_dim"], 8);
  EXPECT_EQ(j["latent_rows"], 5);
  EXPECT_EQ(j["direction_inputs"], directionEncodingName(b.directionEncoding));
  EXPECT_EQ(j["alpha"].get<double>(), 1.75);
  EXPECT_EQ(j["holdout_images"], 2);
  EXPECT_EQ(j["metadata"], json::parse(b.metadataJson));
  // The bytes are the sizes computeSizes gives, with the file's size as given.
  const NbtfSizes sizes = computeSizes(b, 1234);
  EXPECT_EQ(j["bytes"], nbtfPartBytes(sizes));
  EXPECT_EQ(j["bytes"]["file"], 1234);
  EXPECT_EQ(j["bytes"]["latent_rows"], 5);
  EXPECT_EQ(j["bytes"]["decoder"], sizes.decoder);
  EXPECT_EQ(j["bytes"]["total"], sizes.total);
  EXPECT_EQ(j["ratio"].get<double>(), sizes.ratio);
  EXPECT_FALSE(j["bytes"].contains("pca_basis"));
}

// Uncropped, metadata that is no JSON, and a PCA file: its own parts, no direction inputs.
TEST(NbtfInfo, PcaAndUnreadableMetadataAndNoCrop) {
  CompressedBtf b = testing::makePcaBtf(3);
  b.crop = Crop{};
  b.metadataJson = "{not json";
  const json j = json::parse(nbtfInfoJson(b, "p.nbtf", 0));
  EXPECT_EQ(j["method"], "pca");
  EXPECT_TRUE(j["crop"].is_null());
  EXPECT_TRUE(j["metadata"].is_null());
  EXPECT_FALSE(j.contains("direction_inputs"));
  EXPECT_EQ(j["pca_components"], 3);
  for (const char* key : {"pca_mean", "pca_basis", "pca_coefficients", "pca_components", "total", "raw_float32",
                          "file", "ratio"})
    EXPECT_TRUE(j["bytes"].contains(key)) << key;
  EXPECT_FALSE(j["bytes"].contains("decoder"));
  EXPECT_EQ(j["bytes"]["pca_components"], 3);
  EXPECT_EQ(j["bytes"]["file"], 0);
  const NbtfSizes sizes = computeSizes(b, 0);
  EXPECT_EQ(j["bytes"]["pca_basis"], sizes.pcaBasis);
  EXPECT_GT(sizes.pcaBasis, 0u);
}

TEST(NbtfInfo, PartBytesOfANeuralFileNameEveryPart) {
  NbtfSizes s;
  s.decoder = 10, s.latents = 20, s.ids = 30, s.modulation = 40, s.planes = 50, s.clusterPlanes = 60;
  s.decoderParameters = 7, s.latentRows = 8, s.latentDim = 9, s.idsPaper = 11, s.totalPaper = 12, s.ratioPaper = 1.5;
  s.total = 210, s.rawFloat32 = 4200, s.fileBytes = 300, s.ratio = 20;
  const json j = nbtfPartBytes(s);
  EXPECT_EQ(j, json::parse(R"({"decoder": 10, "latents": 20, "ids": 30, "modulation": 40, "planes": 50,
                               "cluster_planes": 60, "decoder_parameters": 7, "latent_rows": 8, "latent_dim": 9,
                               "ids_paper": 11, "total_paper": 12, "ratio_paper": 1.5, "total": 210,
                               "raw_float32": 4200, "file": 300, "ratio": 20.0})"));
}

}  // namespace
}  // namespace nbtf
