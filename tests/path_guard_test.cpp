// util/path_guard.h: an output that is an input (or another output) is refused, through
// symbolic links, `..` and hard links; no output may lie inside an input folder, and a folder
// output may not hold an input.
#include "util/path_guard.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "test_util.h"
#include "util/atomic_file.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;

TEST(PathGuard, AnOutputThatIsAnInputIsRefusedHoweverItIsNamed) {
  test::TempDir dir;
  const std::string in = dir / "in.btf";
  writeFileAtomic(in, std::string("measured"));
  fs::create_directories(dir / "sub");
  fs::create_symlink(in, dir / "link.btf");
  ASSERT_EQ(::link(in.c_str(), (dir / "hard.btf").c_str()), 0);
  for (const std::string& out : {in, dir / "sub/../in.btf", dir / "link.btf", dir / "hard.btf"})
    test::expectErrorContaining([&] { refuseOverlappingPaths({{"<input>", in}}, {{"-o", out}}); },
                                {"-o '" + out + "'", "same file as the input <input>", "nothing was written"});
  EXPECT_NO_THROW(refuseOverlappingPaths({{"<input>", in}}, {{"-o", dir / "out.nbtf"}}));
  EXPECT_TRUE(samePath(in, dir / "hard.btf"));
  EXPECT_FALSE(samePath(in, dir / "out.nbtf"));
}

TEST(PathGuard, TwoOutputsOnOneFileAreRefused) {
  test::TempDir dir;
  const std::string out = dir / "same.nbtf";
  test::expectErrorContaining(
      [&] { refuseOverlappingPaths({}, {{"-o", out}, {"--stats-json", dir / "./same.nbtf"}}); },
      {"-o '" + out + "'", "--stats-json", "are the same file"});
  // Devices and empty paths never clash.
  EXPECT_NO_THROW(refuseOverlappingPaths({{"<input>", "/dev/stdin"}}, {{"-o", "/dev/null"}, {"--stats-json", "/dev/null"}, {"--x", ""}}));
}

TEST(PathGuard, FolderOutputsMayNotHoldOrLieInsideAnInput) {
  test::TempDir dir;
  fs::create_directories(dir / "stack/tv000_pv000");
  const std::string file = dir / "stack/m.nbtf";
  writeFileAtomic(file, std::string("x"));
  test::expectErrorContaining([&] { refuseOverlappingPaths({{"<file.nbtf>", file}}, {{"-o", dir / "stack", true}}); },
                              {"output folder -o", "holds the input <file.nbtf>"});
  test::expectErrorContaining(
      [&] { refuseOverlappingPaths({{"<input>", dir / "stack", true}}, {{"-o", dir / "stack/tv000_pv000", true}}); },
      {"lies inside the input folder <input>"});
  test::expectErrorContaining(
      [&] { refuseOverlappingPaths({}, {{"-o", dir / "report", true}, {"--stats-json", dir / "report/s.json"}}); },
      {"--stats-json", "lies inside the output folder -o"});
}

TEST(PathGuard, NoOutputLiesAnywhereInsideAnInputFolder) {
  test::TempDir dir;
  fs::create_directories(dir / "stack/tv000_pv000");
  const std::string image = dir / "stack/tv000_pv000/00000.jpg";
  writeFileAtomic(image, std::string("measured"));
  fs::create_symlink(dir / "stack", dir / "linked");
  fs::create_symlink(image, dir / "image.jpg");
  // The folder is an input whatever `folder` says: it is found out from the file system.
  for (const std::string& out : {image, dir / "stack/new.nbtf", dir / "linked/tv000_pv000/00000.jpg",
                                 dir / "image.jpg", dir / "stack/ground_truth/x.exr"})
    test::expectErrorContaining([&] { refuseOverlappingPaths({{"<input>", dir / "stack"}}, {{"-o", out}}); },
                                {"-o '" + out + "'", "input folder <input>", "nothing was written"});
  test::expectErrorContaining([&] { refuseOverlappingPaths({{"<input>", dir / "linked"}}, {{"-o", dir / "stack/x", true}}); },
                              {"lies inside the input folder <input>"});
  // Beside the folder is fine.
  EXPECT_NO_THROW(refuseOverlappingPaths({{"<input>", dir / "stack"}}, {{"-o", dir / "out.nbtf"}, {"--x", dir / "rep", true}}));
}

TEST(PathGuard, ADotDotAfterAMissingFolderIsResolvedAsTheWriteWouldBe) {
  test::TempDir dir;
  const std::string in = dir / "in.btf";
  writeFileAtomic(in, std::string("measured"));
  const std::string out = dir / "x/y/../../in.btf";  // x does not exist: the kernel cannot resolve it yet
  test::expectErrorContaining([&] { refuseOverlappingPaths({{"<input>", in}}, {{"-o", out}}); },
                              {"same file as the input"});
  EXPECT_TRUE(samePath(in, out));
  test::expectErrorContaining([&] { refuseOverlappingPaths({{"<input>", dir.path()}}, {{"-o", dir / "x/../new.nbtf"}}); },
                              {"lies inside the input folder <input>"});
  EXPECT_FALSE(fs::exists(dir / "x"));  // checking creates nothing
}

}  // namespace
}  // namespace nbtf
