// Output folders written whole (util/output_folder.h): replaced only when ours, nothing left
// behind on failure.
#include "util/output_folder.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "test_util.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;

const OutputFolderKind kKind{"a test export", "marker.txt", {}};

std::size_t entries(const fs::path& dir) {
  std::size_t n = 0;
  for (const auto& e : fs::directory_iterator(dir)) (void)e, ++n;
  return n;
}

TEST(OutputFolder, ANewFolderIsWrittenAndAnEarlierOneReplacedWhole) {
  const fs::path dir = test::tempFilePath("output_folder_new");
  fs::remove_all(dir);
  writeFolderAtomic(dir.string(), kKind, [](const fs::path& tmp) {
    const std::string a = "1";
    writeWholeFile(tmp / "marker.txt", a.data(), a.size());
    writeWholeFile(tmp / "old.txt", a.data(), a.size());
  });
  EXPECT_TRUE(fs::exists(dir / "old.txt"));
  writeFolderAtomic(dir.string(), kKind, [](const fs::path& tmp) {
    const std::string b = "2";
    writeWholeFile(tmp / "marker.txt", b.data(), b.size());
  });
  EXPECT_FALSE(fs::exists(dir / "old.txt"));  // replaced, not merged
  EXPECT_EQ(entries(dir), 1u);
}

TEST(OutputFolder, AForeignFolderIsRefusedAndAFailedWriteLeavesTheEarlierOne) {
  const fs::path dir = test::tempFilePath("output_folder_foreign");
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "thesis.tex") << "years of work";
  test::expectErrorContaining([&] { checkReplaceableFolder(dir.string(), kKind); },
                              {dir.string(), "is not a test export", "marker.txt"});
  std::ofstream(dir / "marker.txt") << "ours";
  const OutputFolderKind picky{"a test export", "marker.txt", [](const fs::path&) { return false; }};
  test::expectErrorContaining([&] { checkReplaceableFolder(dir.string(), picky); }, {"is not a test export"});
  EXPECT_THROW(writeFolderAtomic(dir.string(), kKind, [](const fs::path&) { throw Error("disk full"); }), Error);
  EXPECT_TRUE(fs::exists(dir / "thesis.tex"));  // the earlier folder, untouched
  for (const auto& e : fs::directory_iterator(dir.parent_path()))
    EXPECT_EQ(e.path().filename().string().find(".nbtf_test_output_folder_foreign.tmp-"), std::string::npos);
}

}  // namespace
}  // namespace nbtf
