#include "util/atomic_file.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>

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
