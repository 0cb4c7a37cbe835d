// Shared by the compressor tests: the paper's model on the small test material, and a substring check.
#pragma once
#include <string>

#include "model_test_material.h"
#include "pipeline/compressor.h"

namespace nbtf::testing {

inline bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

// The paper's model (no per-texel modulation, float32 parts), as these tests check it.
inline CompressOptions quickOptions(int clusters) {
  CompressOptions o;
  o.train = testing::quickConfig();
  o.train.modulation.mode = "none";
  o.train.storage = StorageConfig{"float32", "float32", "raw"};
  o.clusters = clusters;
  o.progress = false;
  return o;
}

}  // namespace nbtf::testing
