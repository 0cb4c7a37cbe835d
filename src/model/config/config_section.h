// Config files (configs/*.json): one JSON object per component. The reader every component's
// loader uses, so all of them reject unknown keys and wrong types the same way, naming the
// file and the key ("model.latent_dim"): a typo never silently runs with a default.
#pragma once
#include <cstddef>
#include <cstdint>
#include <set>
#include <string>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "util/directions.h"

namespace nbtf {

struct TrainConfig;

// The components loadTrainConfig reads.
extern const std::vector<std::string> kTrainConfigSections;
// The components only `nbtf compress` reads (pipeline/compress_config.h): loadTrainConfig
// accepts and skips them, so that one config file serves both.
extern const std::vector<std::string> kCompressOnlyConfigSections;

// The configs shipped in configs/, compiled in: "compact" -> the text of configs/compact.json
// (nullptr: no such built-in config), and their names, sorted.
const char* builtInConfigText(const std::string& name);
std::vector<std::string> builtInConfigNames();
std::string builtInConfigList();  // "adaptive, compact, ...": for help texts and errors
// True when `pathOrName` is not a file and names a built-in config ("compact"): what
// `--config` reads then.
bool isBuiltInConfig(const std::string& pathOrName);

// Parses a config file (comments allowed): a JSON object whose keys are all in `sections`.
// A name that is not a file but a built-in config's ("compact") reads that config.
nlohmann::json readConfigFile(const std::string& path, const std::vector<std::string>& sections);

// The training recipe from a parsed config file's model, optimizer, training, modulation and
// storage objects (other keys of `root` are left to their own readers); `path` names errors.
TrainConfig trainConfigFromJson(const nlohmann::json& root, const std::string& path);

// Reads the keys of one component object, remembering which were consumed; a key that is
// absent leaves its output as it was.
class ConfigSection {
 public:
  ConfigSection(const nlohmann::json& root, const std::string& name, const std::string& file);

  void read(const char* key, int& out);
  void read(const char* key, std::uint64_t& out);
  void read(const char* key, double& out);
  void read(const char* key, bool& out);
  void read(const char* key, std::string& out);
  void read(const char* key, std::vector<int>& out);

  // After all reads: any key not consumed is a typo or an option that does not exist.
  void rejectUnknown() const;

 private:
  const nlohmann::json* find(const char* key);
  std::string path(const std::string& key) const { return name_ + "." + key; }
  [[noreturn]] void fail(const std::string& key, const std::string& msg) const;

  std::string name_, file_;
  const nlohmann::json* obj_ = nullptr;
  std::set<std::string> seen_;
};

// Where a config key's value lives in its struct.
using ConfigValue =
    std::variant<int*, std::uint64_t*, double*, bool*, std::string*, std::vector<int>*, DirectionEncoding*>;

// One config key of a config struct C (TrainConfig, CompressConfig): its component and key,
// where its value lives, and whether a file's recorded recipe carries it (null = always). Each
// struct's readers and writer walk one table of these, so a key is added in one place.
template <class C>
struct ConfigField {
  const char* section;
  const char* key;
  ConfigValue (*value)(C&);
  bool (*recorded)(const C&);
};

// Reads one key into its value (a direction encoding by name); absent leaves it as it was.
void readConfigValue(ConfigSection& section, const char* sectionName, const char* key, const ConfigValue& value,
                     const std::string& path);
// j[section][key] = the value (a direction encoding by name).
void writeConfigValue(nlohmann::json& j, const char* section, const char* key, const ConfigValue& value);

// Reads the keys of `fields` that belong to the component `section` reads.
template <class C, std::size_t N>
void readConfigFields(ConfigSection& section, const std::string& name, const ConfigField<C> (&fields)[N], C& config,
                      const std::string& path) {
  for (const ConfigField<C>& field : fields)
    if (name == field.section) readConfigValue(section, field.section, field.key, field.value(config), path);
}

// The recorded keys of `fields` (of the components in `sections`; all when empty) as a JSON object.
template <class C, std::size_t N>
nlohmann::json configFieldsJson(const ConfigField<C> (&fields)[N], C config,
                                const std::vector<std::string>& sections = {}) {
  nlohmann::json j = nlohmann::json::object();
  for (const ConfigField<C>& field : fields) {
    if (field.recorded && !field.recorded(config)) continue;
    bool wanted = sections.empty();
    for (const std::string& s : sections) wanted = wanted || s == field.section;
    if (wanted) writeConfigValue(j, field.section, field.key, field.value(config));
  }
  return j;
}

}  // namespace nbtf
