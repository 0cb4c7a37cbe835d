// The config file reader every component's loader uses (model/config/config_section.h).
#include "model/config/config_section.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "test_util.h"

namespace nbtf {
namespace {

using nlohmann::json;

TEST(ConfigSection, ReadsEveryTypeAndLeavesAbsentKeysAsTheyWere) {
  const json root = json::parse(R"({"part": {"count": 7, "seed": 18446744073709551615, "rate": 0.25,
                                             "on": true, "name": "adam", "widths": [4, 8, 16]}})");
  ConfigSection s(root, "part", "c.json");
  int count = 1, missingInt = 42;
  std::uint64_t seed = 0;
  double rate = 0;
  bool on = false;
  std::string name = "sgd";
  std::vector<int> widths = {1};
  s.read("count", count);
  s.read("seed", seed);
  s.read("rate", rate);
  s.read("on", on);
  s.read("name", name);
  s.read("widths", widths);
  s.read("absent", missingInt);
  EXPECT_EQ(count, 7);
  EXPECT_EQ(seed, 18446744073709551615ull);
  EXPECT_DOUBLE_EQ(rate, 0.25);
  EXPECT_TRUE(on);
  EXPECT_EQ(name, "adam");
  EXPECT_EQ(widths, (std::vector<int>{4, 8, 16}));
  EXPECT_EQ(missingInt, 42);
  EXPECT_NO_THROW(s.rejectUnknown());

  // An integer is a number too; an absent component reads nothing and rejects nothing.
  const json integerRoot = json::parse(R"({"part": {"rate": 3}})");
  ConfigSection integerRate(integerRoot, "part", "c.json");
  integerRate.read("rate", rate);
  EXPECT_DOUBLE_EQ(rate, 3.0);
  ConfigSection absent(root, "other", "c.json");
  absent.read("count", count);
  EXPECT_EQ(count, 7);
  EXPECT_NO_THROW(absent.rejectUnknown());
}

TEST(ConfigSection, WrongTypesAndUnknownKeysNameTheFileAndTheKey) {
  auto errorReading = [](const char* text, auto value) {
    const json root = json::parse(text);  // the section reads it in place: it must outlive the section
    ConfigSection s(root, "part", "c.json");
    return test::errorOf([&] { s.read("key", value); });
  };
  EXPECT_EQ(errorReading(R"({"part": {"key": 2.5}})", int{}), "c.json: 'part.key' must be an integer, got a number");
  EXPECT_EQ(errorReading(R"({"part": {"key": 3000000000}})", int{}), "c.json: 'part.key' is out of range");
  EXPECT_EQ(errorReading(R"({"part": {"key": -1}})", std::uint64_t{}),
            "c.json: 'part.key' must be a non-negative integer, got an integer");
  EXPECT_EQ(errorReading(R"({"part": {"key": "fast"}})", double{}), "c.json: 'part.key' must be a number, got a string");
  EXPECT_EQ(errorReading(R"({"part": {"key": 1}})", bool{}), "c.json: 'part.key' must be true or false, got an integer");
  EXPECT_EQ(errorReading(R"({"part": {"key": 5}})", std::string{}), "c.json: 'part.key' must be a string, got an integer");
  EXPECT_EQ(errorReading(R"({"part": {"key": 5}})", std::vector<int>{}),
            "c.json: 'part.key' must be an array of integers, got an integer");
  EXPECT_EQ(errorReading(R"({"part": {"key": [1, "x"]}})", std::vector<int>{}),
            "c.json: 'part.key' must be an array of integers, has a string");
  EXPECT_EQ(test::errorOf([] { ConfigSection(json::parse(R"({"part": 3})"), "part", "c.json"); }),
            "c.json: 'part' must be an object, got an integer");

  const json typo = json::parse(R"({"part": {"known": 1, "typo": 2}})");
  ConfigSection s(typo, "part", "c.json");
  int known = 0;
  s.read("known", known);
  EXPECT_EQ(test::errorOf([&] { s.rejectUnknown(); }), "c.json: 'part.typo' unknown key");
}

TEST(ConfigSection, ReadConfigFileAcceptsCommentsAndOnlyTheGivenComponents) {
  test::TempDir dir;
  const std::string path = dir / "c.json";
  std::ofstream(path) << "// a comment\n{\"model\": {\"latent_dim\": 4}, /* another */ \"training\": {}}\n";
  const json root = readConfigFile(path, {"model", "training"});
  EXPECT_EQ(root["model"]["latent_dim"], 4);
  test::expectErrorContaining([&] { readConfigFile(path, {"model"}); },
                              {path, "'training' unknown key (expected model)"});
  std::ofstream(path) << "[1, 2]";
  test::expectErrorContaining([&] { readConfigFile(path, {"model", "training"}); },
                              {path, "must be a JSON object with model, training"});
  std::ofstream(path) << "{\"model\": ";
  test::expectErrorContaining([&] { readConfigFile(path, {"model"}); }, {path, "not valid JSON"});
  test::expectErrorContaining([&] { readConfigFile(dir / "none.json", {"model"}); },
                              {"none.json", "cannot open config file", builtInConfigList()});
}

// A name that is no file reads the built-in config of that name; a file of that name wins.
TEST(ConfigSection, ABuiltInConfigIsReadByNameUnlessAFileHasThatName) {
  ASSERT_NE(builtInConfigText("compact"), nullptr);
  EXPECT_TRUE(isBuiltInConfig("compact"));
  EXPECT_FALSE(isBuiltInConfig("no-such-config"));
  std::vector<std::string> sections = kTrainConfigSections;
  sections.insert(sections.end(), kCompressOnlyConfigSections.begin(), kCompressOnlyConfigSections.end());
  EXPECT_EQ(readConfigFile("compact", sections),
            json::parse(builtInConfigText("compact"), nullptr, true, /*ignore_comments=*/true));

  test::TempDir dir;
  const std::string cwd = std::filesystem::current_path().string();
  std::filesystem::current_path(dir.path());
  std::ofstream("compact") << R"({"model": {"latent_dim": 3}})";
  const bool builtIn = isBuiltInConfig("compact");
  const json fromFile = readConfigFile("compact", sections);
  std::filesystem::current_path(cwd);
  EXPECT_FALSE(builtIn);
  EXPECT_EQ(fromFile, json::parse(R"({"model": {"latent_dim": 3}})"));
}

// The table walkers: a field is read into its struct, a direction encoding by name, and written
// back the same way.
TEST(ConfigSection, ConfigValuesReadAndWriteThroughTheirVariant) {
  const json root = json::parse(R"({"model": {"latent_dim": 5, "direction_inputs": "stereographic"}})");
  ConfigSection s(root, "model", "c.json");
  int latent = 8;
  DirectionEncoding encoding = DirectionEncoding::StereographicHalf;
  readConfigValue(s, "model", "latent_dim", ConfigValue(&latent), "c.json");
  readConfigValue(s, "model", "direction_inputs", ConfigValue(&encoding), "c.json");
  EXPECT_EQ(latent, 5);
  EXPECT_EQ(encoding, DirectionEncoding::Stereographic);
  json out;
  writeConfigValue(out, "model", "latent_dim", ConfigValue(&latent));
  writeConfigValue(out, "model", "direction_inputs", ConfigValue(&encoding));
  EXPECT_EQ(out, root);

  const json badRoot = json::parse(R"({"model": {"direction_inputs": "half"}})");
  ConfigSection bad(badRoot, "model", "c.json");
  test::expectErrorContaining([&] { readConfigValue(bad, "model", "direction_inputs", ConfigValue(&encoding), "c.json"); },
                              {"c.json", "'model.direction_inputs' is not valid"});
}

}  // namespace
}  // namespace nbtf
