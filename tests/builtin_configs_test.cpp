// The configs/*.json files compiled into the library (model/config/builtin_configs.cpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "model/config/config_section.h"
#include "model/config/train_config.h"

namespace nbtf {
namespace {

// Every config of configs/ is compiled in, as it is in the file.
TEST(CompressConfig, BuiltInConfigsAreTheShippedFiles) {
  const std::string dir = std::string(NBTF_SOURCE_DIR) + "/configs/";
  const std::vector<std::string> names = builtInConfigNames();
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().extension() == ".json") files.push_back(e.path().stem().string());
  std::sort(files.begin(), files.end());
  EXPECT_EQ(names, files);
  for (const std::string& name : names) {
    SCOPED_TRACE(name);
    std::ifstream in(dir + name + ".json");
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(std::string(builtInConfigText(name)), text);
    EXPECT_TRUE(isBuiltInConfig(name));
  }
  EXPECT_EQ(builtInConfigText("no-such-config"), nullptr);
  EXPECT_EQ(trainConfigJson(loadTrainConfig("compact")), trainConfigJson(loadTrainConfig(dir + "compact.json")));
}

// The names come sorted, and the list help texts show is those names, comma-separated.
TEST(BuiltInConfigs, NamesAreSortedAndListedInOrder) {
  const std::vector<std::string> names = builtInConfigNames();
  ASSERT_FALSE(names.empty());
  EXPECT_TRUE(std::is_sorted(names.begin(), names.end()));
  EXPECT_NE(std::find(names.begin(), names.end(), "default"), names.end());
  std::string list;
  for (const std::string& name : names) list += (list.empty() ? "" : ", ") + name;
  EXPECT_EQ(builtInConfigList(), list);
  EXPECT_EQ(builtInConfigText(""), nullptr);
  EXPECT_EQ(builtInConfigText("default.json"), nullptr);  // names, not file names
}

}  // namespace
}  // namespace nbtf
