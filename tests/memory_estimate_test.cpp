#include "pipeline/memory_estimate.h"

#include <gtest/gtest.h>

#include "util/error.h"

namespace nbtf {
namespace {

constexpr std::size_t GiB = std::size_t(1) << 30;

StackShape shape(int width, int height, int lights, int views, SampleType type) {
  StackShape s;
  s.width = width, s.height = height, s.lights = lights, s.views = views, s.type = type;
  return s;
}

TEST(MemoryEstimate, ClusteredFullMaterialStaysNearTheEightBitStack) {
  // 256 x 256 UBO2003 (81 x 81 images, 8-bit), k = 500, 32 components, one modulation term.
  const StackShape s = shape(256, 256, 81, 81, SampleType::Srgb8);
  MemoryEstimate e = estimateCompressMemory(s, 500, false, 32, 48, 1, 2);
  EXPECT_EQ(e.stack, std::size_t(6561) * 65536 * 3);
  EXPECT_LT(e.working + e.process, GiB);  // the target: the stack + 1 GiB
  // The per-texel mode and the PCA baseline hold the 4 x M x 3N bytes matrix.
  const std::size_t matrix = std::size_t(65536) * 19683 * 4;
  EXPECT_GT(estimateCompressMemory(s, 0, false, 32, 48, 1, 2).working, matrix);
  EXPECT_GT(estimateCompressMemory(s, 500, true, 32, 48, 1, 2).working, matrix);
}

TEST(MemoryEstimate, EightHundredSquareFitsSixteenGiB) {
  const StackShape s = shape(800, 800, 81, 81, SampleType::Srgb8);
  MemoryEstimate e = estimateCompressMemory(s, 500, false, 32, 48, 1, 2);
  EXPECT_LT(e.total(), 16 * GiB);
  EXPECT_GT(e.total(), e.stack);
  EXPECT_FALSE(e.stage.empty());
}

// With the 8-bit stack in a scratch file (--stack-storage, the 800 x 800 benchmark's 12 GiB target) the stack
// counts as the pages touched between two trims; a small stack counts whole.
TEST(MemoryEstimate, AStackInAScratchFileCountsItsResidentWindow) {
  const MemoryEstimate e = estimateCompressMemory(shape(800, 800, 81, 81, SampleType::Srgb8), 500, false, 32, 48, 1, 2);
  const MemoryEstimate f = withStackInScratchFile(e);
  EXPECT_GT(e.total(), 12 * GiB);
  EXPECT_LT(f.total(), 12 * GiB);
  EXPECT_EQ(f.stack, kScratchResidentWindow);
  EXPECT_EQ(f.working, e.working);
  EXPECT_TRUE(f.stackInScratchFile);
  const MemoryEstimate small = estimateCompressMemory(shape(16, 16, 9, 9, SampleType::Srgb8), 8, false, 4, 8, 1, 2);
  EXPECT_EQ(withStackInScratchFile(small).stack, small.stack);
  try {
    enforceMemoryLimit(f, f.total() - 1, "--memory-limit 1G", "in", shape(800, 800, 81, 81, SampleType::Srgb8));
    ADD_FAILURE() << "not refused";
  } catch (const Error& error) {
    EXPECT_NE(std::string(error.what()).find("the stack's pages in use (it is in a scratch file)"), std::string::npos)
        << error.what();
  }
}

TEST(MemoryEstimate, RefusalNamesInputShapeEstimateAndLimit) {
  const StackShape s = shape(800, 800, 81, 81, SampleType::Srgb8);
  MemoryEstimate e = estimateCompressMemory(s, 500, false, 32, 48, 1, 2);
  EXPECT_NO_THROW(enforceMemoryLimit(e, e.total(), "--memory-limit X", "stack", s));
  try {
    enforceMemoryLimit(e, 8 * GiB, "--memory-limit 8G", "/data/big", s);
    FAIL() << "no error";
  } catch (const Error& err) {
    const std::string m = err.what();
    for (const char* part : {"/data/big", "800 x 800 texels x 6561 images", "8-bit", "--memory-limit 8G", "8.00 GiB",
                             "the stack and the program alone do not fit", "--crop"})
      EXPECT_NE(m.find(part), std::string::npos) << part << " not in: " << m;
  }
  try {
    enforceMemoryLimit(e, e.stack + e.process + 1, "--memory-limit 12G", "/data/big", s);
    FAIL() << "no error";
  } catch (const Error& err) {
    EXPECT_EQ(std::string(err.what()).find("alone"), std::string::npos) << err.what();
  }
}

}  // namespace
}  // namespace nbtf
