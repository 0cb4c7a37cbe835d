#include "model/config/config_section.h"

#include <algorithm>
#include <climits>
#include <filesystem>
#include <fstream>
#include <type_traits>

#include "util/error.h"

namespace nbtf {

using json = nlohmann::json;

const std::vector<std::string> kTrainConfigSections = {"model",    "direction_planes", "cluster_planes", "optimizer",
                                                       "training", "modulation",       "storage"};
const std::vector<std::string> kCompressOnlyConfigSections = {"clustering", "adaptive"};

namespace {

std::string typeName(const json& v) {
  if (v.is_number_integer()) return "an integer";
  if (v.is_number()) return "a number";
  return std::string("a ") + v.type_name();
}

std::string joined(const std::vector<std::string>& names) {
  std::string s;
  for (std::size_t i = 0; i < names.size(); ++i) s += (i ? ", " : "") + names[i];
  return s;
}

}  // namespace

bool isBuiltInConfig(const std::string& pathOrName) {
  std::error_code ec;
  return !std::filesystem::exists(pathOrName, ec) && builtInConfigText(pathOrName) != nullptr;
}

json readConfigFile(const std::string& path, const std::vector<std::string>& sections) {
  json root;
  try {
    if (isBuiltInConfig(path)) {
      root = json::parse(builtInConfigText(path), nullptr, true, /*ignore_comments=*/true);
    } else {
      std::ifstream in(path);
      if (!in) throw fileError(path, "cannot open config file (nor is it a built-in config: " + builtInConfigList() + ")");
      root = json::parse(in, nullptr, true, /*ignore_comments=*/true);
    }
  } catch (const json::parse_error& e) {
    throw fileError(path, std::string("not valid JSON: ") + e.what());
  }
  if (!root.is_object()) throw fileError(path, "must be a JSON object with " + joined(sections));
  for (auto it = root.begin(); it != root.end(); ++it)
    if (std::find(sections.begin(), sections.end(), it.key()) == sections.end())
      throw fileError(path, "'" + it.key() + "' unknown key (expected " + joined(sections) + ")");
  return root;
}

ConfigSection::ConfigSection(const json& root, const std::string& name, const std::string& file)
    : name_(name), file_(file) {
  auto it = root.find(name);
  if (it == root.end()) return;
  if (!it->is_object()) fail(name, "must be an object, got " + typeName(*it));
  obj_ = &*it;
}

void ConfigSection::read(const char* key, int& out) {
  if (const json* v = find(key)) {
    if (!v->is_number_integer()) fail(path(key), "must be an integer, got " + typeName(*v));
    auto x = v->get<std::int64_t>();
    if (x < INT32_MIN || x > INT32_MAX) fail(path(key), "is out of range");
    out = static_cast<int>(x);
  }
}

void ConfigSection::read(const char* key, std::uint64_t& out) {
  if (const json* v = find(key)) {
    if (!v->is_number_integer() || (!v->is_number_unsigned() && v->get<std::int64_t>() < 0))
      fail(path(key), "must be a non-negative integer, got " + typeName(*v));
    out = v->get<std::uint64_t>();
  }
}

void ConfigSection::read(const char* key, double& out) {
  if (const json* v = find(key)) {
    if (!v->is_number()) fail(path(key), "must be a number, got " + typeName(*v));
    out = v->get<double>();
  }
}

void ConfigSection::read(const char* key, bool& out) {
  if (const json* v = find(key)) {
    if (!v->is_boolean()) fail(path(key), "must be true or false, got " + typeName(*v));
    out = v->get<bool>();
  }
}

void ConfigSection::read(const char* key, std::string& out) {
  if (const json* v = find(key)) {
    if (!v->is_string()) fail(path(key), "must be a string, got " + typeName(*v));
    out = v->get<std::string>();
  }
}

void ConfigSection::read(const char* key, std::vector<int>& out) {
  if (const json* v = find(key)) {
    if (!v->is_array()) fail(path(key), "must be an array of integers, got " + typeName(*v));
    out.clear();
    for (const json& e : *v) {
      if (!e.is_number_integer()) fail(path(key), "must be an array of integers, has " + typeName(e));
      out.push_back(e.get<int>());
    }
  }
}

void ConfigSection::rejectUnknown() const {
  if (!obj_) return;
  for (auto it = obj_->begin(); it != obj_->end(); ++it)
    if (!seen_.count(it.key())) fail(path(it.key()), "unknown key");
}

const json* ConfigSection::find(const char* key) {
  seen_.insert(key);
  if (!obj_) return nullptr;
  auto it = obj_->find(key);
  return it == obj_->end() ? nullptr : &*it;
}

void ConfigSection::fail(const std::string& key, const std::string& msg) const {
  throw fileError(file_, "'" + key + "' " + msg);
}

void readConfigValue(ConfigSection& section, const char* sectionName, const char* key, const ConfigValue& value,
                     const std::string& path) {
  std::visit(
      [&](auto* out) {
        using T = std::remove_pointer_t<decltype(out)>;
        if constexpr (std::is_same_v<T, DirectionEncoding>) {
          std::string name = directionEncodingName(*out);
          section.read(key, name);
          try {
            *out = parseDirectionEncoding(name);
          } catch (const Error& e) {
            throw fileError(path, "'" + std::string(sectionName) + "." + key + "' is not valid: " + e.what());
          }
        } else {
          section.read(key, *out);
        }
      },
      value);
}

void writeConfigValue(nlohmann::json& j, const char* section, const char* key, const ConfigValue& value) {
  std::visit(
      [&](auto* v) {
        if constexpr (std::is_same_v<std::remove_pointer_t<decltype(v)>, DirectionEncoding>)
          j[section][key] = directionEncodingName(*v);
        else
          j[section][key] = *v;
      },
      value);
}

}  // namespace nbtf
