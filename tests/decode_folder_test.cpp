// The output folder of `nbtf decode` (pipeline/decode_folder.cpp): staged, described, exchanged whole, and only over its own earlier decodes.
#include "pipeline/decode_folder.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "io/btf_names.h"
#include "test_util.h"
#include "util/atomic_file.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;

nlohmann::json descriptionOf(const std::string& folder) {
  std::ifstream in(fs::path(folder) / kDecodeDescriptionName);
  return nlohmann::json::parse(in);
}

// A decode's image in its view folder, as the decoder names it.
void writeImage(const std::string& folder, const std::string& text) {
  fs::create_directories(fs::path(folder) / "tv000_pv000");
  writeFileAtomic((fs::path(folder) / "tv000_pv000" / "tl000_pl000_tv000_pv000.png").string(), text);
}

TEST(DecodeFolder, StagesBesideTheDestinationAndCommitsItComplete) {
  test::TempDir dir;
  const std::string out = dir / "out";
  {
    DecodeFolder folder(out, R"({"generator": "test"})");
    EXPECT_EQ(fs::path(folder.staging()).filename(), ".out.nbtf-decoding");
    EXPECT_EQ(descriptionOf(folder.staging())["complete"], false);
    EXPECT_EQ(descriptionOf(folder.staging())["generator"], "test");
    EXPECT_FALSE(fs::exists(out));
    writeImage(folder.staging(), "first");
    folder.commit();
  }
  EXPECT_FALSE(fs::exists(dir / ".out.nbtf-decoding"));
  EXPECT_EQ(descriptionOf(out)["complete"], true);
  EXPECT_EQ(test::errorOf([&] { checkReplaceableDecodeFolder(out); }), "(no error)");

  // A second decode replaces the first whole.
  {
    DecodeFolder folder(out, R"({"generator": "second"})");
    EXPECT_EQ(descriptionOf(out)["generator"], "test");  // untouched until the commit
    writeImage(folder.staging(), "second");
    folder.commit();
  }
  EXPECT_EQ(descriptionOf(out)["generator"], "second");
  std::ifstream image(fs::path(out) / "tv000_pv000" / "tl000_pl000_tv000_pv000.png");
  std::string text;
  image >> text;
  EXPECT_EQ(text, "second");
  EXPECT_FALSE(fs::exists(dir / ".out.nbtf-decoding"));
}

TEST(DecodeFolder, AnUncommittedDecodeLeavesNothing) {
  test::TempDir dir;
  const std::string out = dir / "out";
  {
    DecodeFolder folder(out, R"({})");
    writeImage(folder.staging(), "x");
  }
  EXPECT_FALSE(fs::exists(dir / ".out.nbtf-decoding"));
  EXPECT_FALSE(fs::exists(out));
  // An empty folder is a destination too.
  fs::create_directories(out);
  EXPECT_NO_THROW(checkReplaceableDecodeFolder(out));
}

TEST(DecodeFolder, ForeignFoldersAndFilesAreRefusedByName) {
  test::TempDir dir;
  const std::string stack = dir / "stack";
  writeImage(stack, "measured");  // a measured stack: no description
  test::expectErrorContaining([&] { checkReplaceableDecodeFolder(stack); },
                              {stack, "holds a BTF image stack that nbtf decode did not write", "tv000_pv000"});
  test::expectErrorContaining([&] { DecodeFolder(stack, "{}"); }, {"a BTF image stack"});
  EXPECT_TRUE(fs::exists(fs::path(stack) / "tv000_pv000" / "tl000_pl000_tv000_pv000.png"));

  const std::string notes = dir / "notes";
  fs::create_directories(notes);
  writeFileAtomic(notes + "/todo.txt", std::string("x"));
  test::expectErrorContaining([&] { checkReplaceableDecodeFolder(notes); }, {"holds files that nbtf decode did not write"});

  // An earlier decode with a file the user added: not ours to delete.
  const std::string out = dir / "out";
  {
    DecodeFolder folder(out, "{}");
    writeImage(folder.staging(), "x");
    folder.commit();
  }
  writeFileAtomic(out + "/tv000_pv000/notes.txt", std::string("x"));
  test::expectErrorContaining([&] { checkReplaceableDecodeFolder(out); }, {"holds a file", "notes.txt"});

  writeFileAtomic(dir / "plain", std::string("x"));
  test::expectErrorContaining([&] { DecodeFolder(dir / "plain", "{}"); }, {"exists and is not a folder"});
}

TEST(DecodeFolder, RemovingADecodeRemovesItAll) {
  test::TempDir dir;
  const std::string out = dir / "out";
  {
    DecodeFolder folder(out, "{}");
    writeImage(folder.staging(), "x");
    folder.commit();
  }
  std::error_code ec;
  removeDecodeFolder(out, ec);
  EXPECT_FALSE(ec) << ec.message();
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace
}  // namespace nbtf
