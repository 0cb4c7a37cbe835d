#include "util/page_buffer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>

#include "io/btf_stack.h"

namespace nbtf {
namespace {

constexpr std::size_t kMiB = std::size_t(1) << 20;

bool allZero(const PageBuffer& b) {
  return std::all_of(b.data(), b.data() + b.size(), [](std::uint8_t v) { return v == 0; });
}

// The mapping's "THPeligible" line in /proc/self/smaps: 1 when the kernel may back it with
// huge pages; -1 when the mapping is not found.
int hugePageEligible(const void* address) {
  std::ifstream smaps("/proc/self/smaps");
  const auto at = reinterpret_cast<std::uintptr_t>(address);
  std::string line;
  bool inside = false;
  while (std::getline(smaps, line)) {
    std::uintptr_t begin = 0, end = 0;
    char dash = 0;
    std::istringstream range(line);
    if (range >> std::hex >> begin >> dash >> end && dash == '-') {
      inside = begin <= at && at < end;
      continue;
    }
    if (inside && line.rfind("THPeligible:", 0) == 0) return std::stoi(line.substr(12));
  }
  return -1;
}

// The system's setting for transparent huge pages: the bracketed word ("always", "madvise",
// "never"), or empty where the kernel has none.
std::string transparentHugePages() {
  std::ifstream in("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string text;
  std::getline(in, text);
  const auto open = text.find('['), close = text.find(']');
  return open == std::string::npos || close == std::string::npos ? "" : text.substr(open + 1, close - open - 1);
}

TEST(PageBuffer, SmallAndLargeBuffersStartZeroAndKeepWhatIsWritten) {
  for (std::size_t bytes : {std::size_t(1), std::size_t(4097), 2 * kMiB, 5 * kMiB + 3}) {
    PageBuffer b(bytes);
    ASSERT_EQ(b.size(), bytes);
    ASSERT_NE(b.data(), nullptr);
    EXPECT_TRUE(allZero(b)) << bytes << " bytes";
    b.data()[bytes - 1] = 9;
    b.data()[0] = 7;
    EXPECT_EQ(b.data()[0], 7);
    if (bytes > 1) EXPECT_EQ(b.data()[bytes - 1], 9);
  }
  PageBuffer none(0);
  EXPECT_TRUE(none.empty());
  EXPECT_EQ(none.data(), nullptr);
}

TEST(PageBuffer, CopiesAreDeepAndMovesLeaveTheSourceEmpty) {
  PageBuffer a(3 * kMiB);
  a.data()[12345] = 42;
  PageBuffer copy = a;
  ASSERT_EQ(copy.size(), a.size());
  EXPECT_NE(copy.data(), a.data());
  EXPECT_EQ(copy.data()[12345], 42);
  copy.data()[12345] = 1;
  EXPECT_EQ(a.data()[12345], 42);

  const std::uint8_t* at = a.data();
  PageBuffer moved = std::move(a);
  EXPECT_EQ(moved.data(), at);
  EXPECT_EQ(moved.size(), 3 * kMiB);
  EXPECT_TRUE(a.empty());
  EXPECT_EQ(a.data(), nullptr);

  PageBuffer assigned(10);
  assigned = std::move(moved);
  EXPECT_EQ(assigned.data(), at);
  EXPECT_TRUE(moved.empty());
  assigned = copy;  // copy assignment over a buffer that holds memory
  EXPECT_EQ(assigned.data()[12345], 1);
  EXPECT_EQ(assigned.size(), copy.size());
}

// Large buffers start on a 2 MiB boundary and are advised for huge pages: where the system
// grants them on request (or always), the kernel reports the mapping eligible.
TEST(PageBuffer, LargeBuffersAreAlignedAndAdvisedForHugePages) {
  PageBuffer b(8 * kMiB);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(b.data()) % (2 * kMiB), 0u);
  const std::string setting = transparentHugePages();
  if (setting != "madvise" && setting != "always") GTEST_SKIP() << "transparent huge pages: '" << setting << "'";
  EXPECT_EQ(hugePageEligible(b.data()), 1);
}

// A stack in memory reads zero where nothing was written, as it did when it was a vector.
TEST(PageBuffer, ANewStackInMemoryIsZero) {
  BtfStack stack({{10, 0}, {20, 90}}, {{0, 0}}, 64, 48, SampleType::Srgb8);
  ASSERT_EQ(stack.bytesInMemory(), stack.bytesPerImage() * 2);
  for (int image = 0; image < 2; ++image) {
    const std::uint8_t* bytes = stack.imageBytes(image);
    EXPECT_TRUE(std::all_of(bytes, bytes + stack.bytesPerImage(), [](std::uint8_t v) { return v == 0; }));
  }
  BtfStack copy = stack;
  EXPECT_NE(copy.imageBytes(0), stack.imageBytes(0));
}

}  // namespace
}  // namespace nbtf
