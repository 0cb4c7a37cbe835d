#include "util/memory.h"

#include <gtest/gtest.h>

#include <sys/resource.h>

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

// Page faults of the calling thread so far.
long minorFaults() {
  rusage usage{};
  getrusage(RUSAGE_THREAD, &usage);
  return usage.ru_minflt;
}

TEST(Memory, FreedMemoryIsReusedWithoutFaultingItInAgain) {
  reuseFreedMemory();
  // 40 MiB: more than glibc ever takes from its heap by itself, so without the setting each
  // block is mapped afresh and every one of its 10,240 pages faults in on first touch.
  const std::size_t bytes = std::size_t(40) << 20;
  long faults = 0;
  for (int round = 0; round < 3; ++round) {
    const long before = minorFaults();
    std::vector<char> block(bytes, static_cast<char>(round + 1));
    volatile char sink = block[block.size() / 2];
    (void)sink;
    faults = minorFaults() - before;
  }
  EXPECT_LT(faults, 1000) << "the last of three 40 MiB blocks faulted in " << faults << " pages";
}

TEST(Memory, FormatsInReadableUnits) {
  EXPECT_EQ(formatBytes(512), "512 B");
  EXPECT_EQ(formatBytes(std::size_t(820) << 20), "820 MiB");
  EXPECT_EQ(formatBytes(std::size_t(6471816) * 1024), "6.17 GiB");
}

}  // namespace
}  // namespace nbtf
