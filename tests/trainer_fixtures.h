// Shared by the training tests (trainer, checkpoints, evaluation): the test material built
// once, image lists, model comparison and temporary checkpoint paths.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "model/trainer.h"
#include "model_test_material.h"
#include "test_util.h"

namespace nbtf::testing {

inline const TestMaterial& material() {
  static TestMaterial m = makeTestMaterial();
  return m;
}

inline std::vector<int> allImages(const TestMaterial& m) {
  std::vector<int> v(m.stack.numImages());
  for (int i = 0; i < m.stack.numImages(); ++i) v[i] = i;
  return v;
}

inline std::vector<int> asInts(const std::vector<std::int32_t>& v) { return std::vector<int>(v.begin(), v.end()); }

inline std::string tempPath(const std::string& name) { return test::tempFilePath("trainer_test_" + name); }

inline bool sameModel(const TrainResult& a, const TrainResult& b) {
  if (a.latents != b.latents || a.decoder.layers.size() != b.decoder.layers.size()) return false;
  for (std::size_t l = 0; l < a.decoder.layers.size(); ++l)
    if (a.decoder.layers[l].weight != b.decoder.layers[l].weight || a.decoder.layers[l].bias != b.decoder.layers[l].bias)
      return false;
  return true;
}

}  // namespace nbtf::testing
