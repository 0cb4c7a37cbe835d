#include "pipeline/compress_config.h"

#include <cmath>
#include <nlohmann/json.hpp>

#include "model/config_section.h"
#include "util/error.h"

namespace nbtf {

namespace {

constexpr int kMaxAdaptiveStages = 20;

[[noreturn]] void bad(const std::string& source, const std::string& key, const std::string& option,
                      const std::string& msg) {
  throw fileError(source, "'adaptive." + key + "' " + (option.empty() ? "" : "(" + option + ") ") + msg);
}

}  // namespace

CompressConfig loadCompressConfig(const std::string& path) {
  std::vector<std::string> sections = kTrainConfigSections;
  sections.insert(sections.end(), kCompressOnlyConfigSections.begin(), kCompressOnlyConfigSections.end());
  const nlohmann::json root = readConfigFile(path, sections);
  CompressConfig c;
  c.train = trainConfigFromJson(root, path);
  {
    ConfigSection clustering(root, "clustering", path);
    std::string space = clusteringSpaceName(c.clusteringSpace);
    clustering.read("space", space);
    clustering.read("clusters", c.clusters);
    clustering.rejectUnknown();
    if (c.clusters < 0)
      throw fileError(path, "'clustering.clusters' must be >= 0 (the default k; 0 = per-texel), got " +
                                std::to_string(c.clusters));
    try {
      c.clusteringSpace = parseClusteringSpace(space, "'clustering.space'");
    } catch (const Error& e) {
      throw fileError(path, e.what());
    }
  }
  AdaptiveOptions& a = c.adaptive;
  ConfigSection s(root, "adaptive", path);
  s.read("enabled", a.enabled);
  s.read("target_rmse", a.targetRmse);
  s.read("max_clusters", a.maxClusters);
  s.read("size_budget", a.sizeBudget);
  s.read("initial_clusters", a.initialClusters);
  s.read("stages", a.stages);
  s.read("growth_fraction", a.growthFraction);
  s.read("merge_tolerance", a.mergeTolerance);
  s.rejectUnknown();
  validateAdaptiveOptions(a, path);
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
  nlohmann::json j = {{"enabled", a.enabled},
                      {"target_rmse", a.targetRmse},
                      {"max_clusters", a.maxClusters},
                      {"size_budget", a.sizeBudget},
                      {"initial_clusters", a.initialClusters},
                      {"stages", a.stages},
                      {"growth_fraction", a.growthFraction},
                      {"merge_tolerance", a.mergeTolerance}};
  return j.dump();
}

}  // namespace nbtf
