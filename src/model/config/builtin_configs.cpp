// The configs/*.json files as compiled in (src/CMakeLists.txt generates the table).
#include <algorithm>
#include <utility>

#include "model/config/config_section.h"

namespace nbtf {
namespace {

const std::pair<const char*, const char*> kBuiltInConfigs[] = {
#include "builtin_configs.inc"
};

}  // namespace

const char* builtInConfigText(const std::string& name) {
  for (const auto& [configName, text] : kBuiltInConfigs)
    if (name == configName) return text;
  return nullptr;
}

std::vector<std::string> builtInConfigNames() {
  std::vector<std::string> names;
  for (const auto& entry : kBuiltInConfigs) names.push_back(entry.first);
  std::sort(names.begin(), names.end());
  return names;
}

std::string builtInConfigList() {
  std::string list;
  for (const std::string& name : builtInConfigNames()) list += (list.empty() ? "" : ", ") + name;
  return list;
}

}  // namespace nbtf
