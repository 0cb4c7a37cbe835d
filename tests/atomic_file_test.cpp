#include "util/atomic_file.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <thread>

#include "test_util.h"
#include "util/error.h"

namespace nbtf {
using test::expectErrorContaining;
using test::TempDir;

TEST(AtomicFile, WritesAndReplaces) {
  TempDir dir;
  writeFileAtomic(dir / "a.bin", std::string("first"));
  writeFileAtomic(dir / "a.bin", std::string("second"));
  auto bytes = readFileBytes(dir / "a.bin");
  EXPECT_EQ(std::string(bytes.begin(), bytes.end()), "second");
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), {}), 1);
}

// The temporary names are recognisable for their target (decode folders rely on it).
TEST(AtomicFile, TemporaryNamesAreRecognisedForTheirTargetOnly) {
  const std::string tmp = std::filesystem::path(temporaryPathFor("/some/folder/nbtf_decode.json")).filename().string();
  EXPECT_TRUE(isTemporaryNameFor(tmp, "nbtf_decode.json")) << tmp;
  EXPECT_FALSE(isTemporaryNameFor(tmp, "other.json")) << tmp;
  EXPECT_FALSE(isTemporaryNameFor("nbtf_decode.json", "nbtf_decode.json"));
  EXPECT_FALSE(isTemporaryNameFor("tl000_pl000_tv000_pv000.png", "nbtf_decode.json"));
}

TEST(AtomicFile, FailedWriterKeepsThePreviousFile) {
  TempDir dir;
  writeFileAtomic(dir / "a.bin", std::string("complete"));
  EXPECT_THROW(writeAtomicVia(dir / "a.bin",
                              [](const std::string& tmp) {
                                std::ofstream(tmp) << "half";
                                throw Error("writer crashed");
                              }),
               Error);
  auto bytes = readFileBytes(dir / "a.bin");
  EXPECT_EQ(std::string(bytes.begin(), bytes.end()), "complete");
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), {}), 1);  // temporary removed
}

TEST(AtomicFile, CheckWritable) {
  TempDir dir;
  EXPECT_NO_THROW(checkWritable(dir / "out.nbtf"));
  expectErrorContaining([] { checkWritable("/nonexistent/out.nbtf"); }, {"/nonexistent/out.nbtf", "does not exist"});
  expectErrorContaining([&] { checkWritable(dir.path()); }, {"folder"});
  if (geteuid() != 0) {  // root writes anywhere
    std::filesystem::create_directory(dir / "ro");
    chmod((dir / "ro").c_str(), 0555);
    expectErrorContaining([&] { checkWritable(dir / "ro/out.nbtf"); }, {"not writable"});
  }
}

TEST(AtomicFile, ReadMissingFileNamesIt) {
  expectErrorContaining([] { readFileBytes("/nonexistent/x.bin"); }, {"/nonexistent/x.bin", "cannot open"});
}

}  // namespace nbtf

namespace nbtf {

// Atomic replacement is for regular files only: a symbolic link is followed (its target is
// replaced, the link stays), a pipe or device is written in place and never unlinked.
TEST(AtomicFile, SymbolicLinkTargetIsReplacedAndTheLinkStays) {
  TempDir dir;
  std::filesystem::create_directories(dir / "real");
  writeFileAtomic(dir / "real/a.txt", std::string("old"));
  std::filesystem::create_symlink(dir / "real/a.txt", dir / "link.txt");
  checkWritable(dir / "link.txt");
  writeFileAtomic(dir / "link.txt", std::string("new"));
  EXPECT_TRUE(std::filesystem::is_symlink(dir / "link.txt"));
  auto bytes = readFileBytes(dir / "real/a.txt");
  EXPECT_EQ(std::string(bytes.begin(), bytes.end()), "new");
  // A dangling link: the file it names is created.
  std::filesystem::create_symlink("real/b.txt", dir / "dangling.txt");
  writeAtomicVia(dir / "dangling.txt", [](const std::string& tmp) { std::ofstream(tmp) << "via"; });
  EXPECT_TRUE(std::filesystem::is_symlink(dir / "dangling.txt"));
  EXPECT_TRUE(std::filesystem::is_regular_file(dir / "real/b.txt"));
}

TEST(AtomicFile, PipesAndDevicesAreWrittenInPlace) {
  TempDir dir;
  const std::string fifo = dir / "pipe";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string received;
  std::thread reader([&] {
    std::ifstream in(fifo);
    received.assign(std::istreambuf_iterator<char>(in), {});
  });
  checkWritable(fifo);
  writeFileAtomic(fifo, std::string("through the pipe"));
  reader.join();
  EXPECT_EQ(received, "through the pipe");
  struct stat st;
  ASSERT_EQ(::lstat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode)) << "the pipe was replaced";
  // /dev/null: written in place, also by writers that need a file name.
  checkWritable("/dev/null");
  writeFileAtomic("/dev/null", std::string("x"));
  writeAtomicVia("/dev/null", [](const std::string& tmp) { std::ofstream(tmp) << "via"; });
  ASSERT_EQ(::stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), {}), 1);  // no temporaries left
}

TEST(AtomicFile, CreateParentFolders) {
  TempDir dir;
  createParentFolders(dir / "a/b/c.txt");
  EXPECT_TRUE(std::filesystem::is_directory(dir / "a/b"));
  EXPECT_FALSE(std::filesystem::exists(dir / "a/b/c.txt"));
}

}  // namespace nbtf
