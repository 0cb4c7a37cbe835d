#include "util/memory.h"

#include <gtest/gtest.h>

#include <vector>

#include "util/error.h"

namespace nbtf {
namespace {

TEST(Memory, ParsesSizesWithBinaryUnits) {
  EXPECT_EQ(parseByteSize("123", "--memory-limit"), 123u);
  EXPECT_EQ(parseByteSize("800K", "--memory-limit"), 800u * 1024);
  EXPECT_EQ(parseByteSize("16M", "--memory-limit"), 16u << 20);
  EXPECT_EQ(parseByteSize("12G", "--memory-limit"), std::size_t(12) << 30);
  EXPECT_EQ(parseByteSize("12GiB", "--memory-limit"), std::size_t(12) << 30);
  EXPECT_EQ(parseByteSize("1.5g", "--memory-limit"), std::size_t(3) << 29);
  EXPECT_EQ(parseByteSize("2TB", "--memory-limit"), std::size_t(2) << 40);
}

TEST(Memory, RejectsWhatIsNotASizeNamingTheOption) {
  for (const char* bad : {"", "G", "12X", "-5G", "0", "1.2.3G", "12 G", "0.1"}) {
    try {
      parseByteSize(bad, "--memory-limit");
      ADD_FAILURE() << "'" << bad << "' was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("--memory-limit"), std::string::npos) << e.what();
    }
  }
}

TEST(Memory, PhysicalMemoryAndTheDefaultLimit) {
  const std::size_t physical = physicalMemoryBytes();
  EXPECT_GT(physical, std::size_t(64) << 20);  // /proc/meminfo is readable here
  EXPECT_EQ(defaultMemoryLimit(), physical / 4 * 3);
}

TEST(Memory, PeakResidentGrowsWithTouchedMemory) {
  const std::size_t before = peakResidentBytes();
  EXPECT_GT(before, 0u);
  std::vector<char> block(std::size_t(64) << 20, 1);  // 64 MiB, touched
  volatile char sink = block[block.size() / 2];
  (void)sink;
  EXPECT_GE(peakResidentBytes(), std::max(before, std::size_t(64) << 20));
}

TEST(Memory, FormatsInReadableUnits) {
  EXPECT_EQ(formatBytes(512), "512 B");
  EXPECT_EQ(formatBytes(std::size_t(820) << 20), "820 MiB");
  EXPECT_EQ(formatBytes(std::size_t(6471816) * 1024), "6.17 GiB");
}

}  // namespace
}  // namespace nbtf
