#include "util/scratch_mapping.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <thread>

#include "io/btf_stack.h"
#include "util/error.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;

class ScratchMappingTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("nbtf_scratch_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

// The contents survive the pages being handed back (the file cache keeps them), the pages
// leave the process's resident set, and the file has no name in the folder.
TEST_F(ScratchMappingTest, ContentsSurviveReleasingTheResidentPages) {
  const std::size_t bytes = std::size_t(64) << 20;
  ScratchMapping m(dir_.string(), bytes, "the test array", 0, std::chrono::milliseconds(0));  // no background trims
  ASSERT_EQ(m.size(), bytes);
  for (std::size_t i = 0; i < bytes; i += 4096) m.data()[i] = static_cast<std::uint8_t>(i / 4096 * 7 + 1);
  const std::size_t touched = residentFileBytes();
  m.releaseResident();
  const std::size_t released = residentFileBytes();
  EXPECT_GE(touched, released + bytes / 2) << "touched " << touched << ", after the release " << released;
  EXPECT_EQ(m.releases(), 1u);
  for (std::size_t i = 0; i < bytes; i += 4096)
    ASSERT_EQ(m.data()[i], static_cast<std::uint8_t>(i / 4096 * 7 + 1)) << "byte " << i;
  EXPECT_TRUE(fs::is_empty(dir_));
}

// The background thread hands the pages back once more than the budget is resident, and not
// before: touching less than the budget leaves them mapped.
TEST_F(ScratchMappingTest, TheBackgroundThreadHandsPagesBackOverTheBudget) {
  const std::size_t bytes = std::size_t(64) << 20;
  ScratchMapping m(dir_.string(), bytes, "the test array", std::size_t(16) << 20, std::chrono::milliseconds(1));
  for (std::size_t i = 0; i < (std::size_t(4) << 20); i += 4096) m.data()[i] = 1;  // 4 MiB: under the budget
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(m.releases(), 0u);
  for (std::size_t i = 0; i < bytes; i += 4096) m.data()[i] = 2;  // 64 MiB: over it
  for (int wait = 0; wait < 5000 && m.releases() < 1; ++wait) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_GE(m.releases(), 1u);
  for (std::size_t i = 0; i < bytes; i += 4096) ASSERT_EQ(m.data()[i], 2) << "byte " << i;
}

TEST_F(ScratchMappingTest, AFolderThatCannotHoldItIsNamed) {
  const std::string missing = (dir_ / "missing").string();
  try {
    ScratchMapping m(missing, 4096, "the 8-bit stack");
    ADD_FAILURE() << "no error";
  } catch (const FileAccessError& e) {
    EXPECT_EQ(e.path(), missing);
    EXPECT_NE(std::string(e.what()).find("cannot create the scratch file for the 8-bit stack"), std::string::npos)
        << e.what();
  }
}

// A stack in a scratch file reads and writes as one in memory, and takes none of its bytes.
TEST_F(ScratchMappingTest, AStackInAScratchFileHoldsTheSameValues) {
  const std::vector<Direction> lights = {{0, 0}, {30, 0}}, views = {{0, 0}, {30, 90}, {60, 0}};
  BtfStack memory(lights, views, 5, 3, SampleType::Srgb8);
  BtfStack file(lights, views, 5, 3, SampleType::Srgb8, dir_.string());
  EXPECT_FALSE(memory.inScratchFile());
  ASSERT_TRUE(file.inScratchFile());
  EXPECT_EQ(file.scratchDirectory(), dir_.string());
  EXPECT_EQ(file.bytesInMemory(), 0u);
  for (int i = 0; i < memory.numImages(); ++i)
    for (std::size_t b = 0; b < memory.bytesPerImage(); ++b)
      memory.imageBytes(i)[b] = file.imageBytes(i)[b] = static_cast<std::uint8_t>(37 * i + 11 * b);
  for (int t = 0; t < memory.numTexels(); ++t) EXPECT_EQ(file.abrdfLinear(t), memory.abrdfLinear(t)) << "texel " << t;
  float lo1, hi1, lo2, hi2;
  memory.valueRange(lo1, hi1);
  file.valueRange(lo2, hi2);
  EXPECT_EQ(lo1, lo2);
  EXPECT_EQ(hi1, hi2);
  BtfStack half(lights, views, 5, 3, SampleType::Half, dir_.string());
  std::vector<float> rgb(15 * 3, 0.25f);
  half.setImageLinear(4, rgb.data());
  EXPECT_EQ(half.sample(4, 14, 2), 0.25f);
  EXPECT_TRUE(fs::is_empty(dir_));
}

}  // namespace
}  // namespace nbtf
