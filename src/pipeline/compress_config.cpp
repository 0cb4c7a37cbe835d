#include "pipeline/compress_config.h"

#include <cmath>
#include <nlohmann/json.hpp>

#include "model/config/config_section.h"
#include "util/error.h"

namespace nbtf {

namespace {

constexpr int kMaxAdaptiveStages = 20;

[[noreturn]] void bad(const std::string& source, const std::string& key, const std::string& option,
                      const std::string& msg) {
  throw fileError(source, "'adaptive." + key + "' " + (option.empty() ? "" : "(" + option + ") ") + msg);
}

}  // namespace

namespace {

// The "clustering" and "adaptive" keys (config_section.h); the clustering space is read by name
// beside them.
#define NBTF_COMPRESS_FIELD(section, key, member) \
  ConfigField<CompressConfig> { section, key, [](CompressConfig& c) -> ConfigValue { return &c.member; }, nullptr }
const ConfigField<CompressConfig> kCompressFields[] = {
    NBTF_COMPRESS_FIELD("clustering", "clusters", clusters),
    NBTF_COMPRESS_FIELD("clustering", "texels_per_cluster", texelsPerCluster),
    NBTF_COMPRESS_FIELD("adaptive", "enabled", adaptive.enabled),
    NBTF_COMPRESS_FIELD("adaptive", "target_rmse", adaptive.targetRmse),
    NBTF_COMPRESS_FIELD("adaptive", "max_clusters", adaptive.maxClusters),
    NBTF_COMPRESS_FIELD("adaptive", "size_budget", adaptive.sizeBudget),
    NBTF_COMPRESS_FIELD("adaptive", "initial_clusters", adaptive.initialClusters),
    NBTF_COMPRESS_FIELD("adaptive", "stages", adaptive.stages),
    NBTF_COMPRESS_FIELD("adaptive", "growth_fraction", adaptive.growthFraction),
    NBTF_COMPRESS_FIELD("adaptive", "merge_tolerance", adaptive.mergeTolerance),
};
#undef NBTF_COMPRESS_FIELD

void readClusteringSpace(ConfigSection& clustering, CompressConfig& c, const std::string& path) {
  std::string space = clusteringSpaceName(c.clusteringSpace);
  clustering.read("space", space);
  try {
    c.clusteringSpace = parseClusteringSpace(space, "'clustering.space'");
  } catch (const Error& e) {
    throw fileError(path, e.what());
  }
}

}  // namespace

CompressConfig loadCompressConfig(const std::string& path) {
  std::vector<std::string> sections = kTrainConfigSections;
  sections.insert(sections.end(), kCompressOnlyConfigSections.begin(), kCompressOnlyConfigSections.end());
  const nlohmann::json root = readConfigFile(path, sections);
  CompressConfig c;
  c.train = trainConfigFromJson(root, path);
  for (const std::string& name : kCompressOnlyConfigSections) {
    ConfigSection section(root, name, path);
    if (name == "clustering") readClusteringSpace(section, c, path);
    readConfigFields(section, name, kCompressFields, c, path);
    section.rejectUnknown();
  }
  if (c.clusters < 0)
    throw fileError(path, "'clustering.clusters' must be >= 0 (the default k; 0 = per-texel), got " +
                              std::to_string(c.clusters));
  if (c.texelsPerCluster != 0) {
    if (!(c.texelsPerCluster >= 1 && std::isfinite(c.texelsPerCluster)))
      throw fileError(path, "'clustering.texels_per_cluster' must be a number >= 1 (k = texels / it), got " +
                                nlohmann::json(c.texelsPerCluster).dump());
    if (root.contains("clustering") && root["clustering"].contains("clusters"))
      throw fileError(path, "'clustering' gives both 'clusters' and 'texels_per_cluster': give one (a fixed k, or k "
                            "from the input's size)");
  }
  validateAdaptiveOptions(c.adaptive, path);
  return c;
}

void validateAdaptiveOptions(const AdaptiveOptions& a, const std::string& source) {
  if (!(std::isfinite(a.targetRmse) && a.targetRmse >= 0))
    bad(source, "target_rmse", "--target-rmse", "must be a number >= 0 (0 = no target)");
  if (a.maxClusters < 0) bad(source, "max_clusters", "--max-clusters", "must be >= 0 (0 = no cap)");
  if (a.initialClusters < 0)
    bad(source, "initial_clusters", "--initial-clusters", "must be >= 0 (0 = from the stages and the cap)");
  if (a.stages < 1 || a.stages > kMaxAdaptiveStages)
    bad(source, "stages", "--stages",
        "must be in 1.." + std::to_string(kMaxAdaptiveStages) + ", got " + std::to_string(a.stages));
  if (!(a.growthFraction > 0 && a.growthFraction < 1))
    bad(source, "growth_fraction", "", "must be in (0, 1): the share of the steps the growing stages take");
  if (!(std::isfinite(a.mergeTolerance) && a.mergeTolerance >= 0))
    bad(source, "merge_tolerance", "", "must be a number >= 0 (0 = merge only to meet a size budget)");
}

std::string adaptiveConfigJson(const AdaptiveOptions& a) {
  CompressConfig c;
  c.adaptive = a;
  return configFieldsJson(kCompressFields, c, {"adaptive"})["adaptive"].dump();
}

}  // namespace nbtf
