#include "util/scratch_mapping.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "io/btf_stack.h"
#include "test_util.h"
#include "util/error.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;

// Each test in a fresh folder of its own.
class ScratchMappingTest : public ::testing::Test {
 protected:
  test::TempDir tmp_;
  fs::path dir_{tmp_.path()};
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

// Read calls see what was written through the mapping; a read past the end is refused.
TEST_F(ScratchMappingTest, ReadsSeeWhatTheMappingHolds) {
  ScratchMapping m(dir_.string(), 3 * 4096 + 100, "the test array", 0, std::chrono::milliseconds(0));
  for (std::size_t i = 0; i < m.size(); ++i) m.data()[i] = static_cast<std::uint8_t>(i * 31 + 7);
  std::vector<std::uint8_t> out(5000);
  m.read(4000, out.size(), out.data());
  for (std::size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], static_cast<std::uint8_t>((4000 + i) * 31 + 7)) << i;
  m.releaseResident();
  m.read(m.size() - 10, 10, out.data());
  EXPECT_EQ(out[9], static_cast<std::uint8_t>((m.size() - 1) * 31 + 7));
  EXPECT_THROW(m.read(m.size() - 10, 11, out.data()), Error);
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

// How many of `path`'s pages are in the file cache (mincore over a mapping of it).
std::size_t cachedPages(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) return 0;
  const std::size_t bytes = static_cast<std::size_t>(::lseek(fd, 0, SEEK_END));
  void* map = ::mmap(nullptr, bytes, PROT_READ, MAP_SHARED, fd, 0);
  ::close(fd);
  if (map == MAP_FAILED) return 0;
  const std::size_t page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  std::vector<unsigned char> resident((bytes + page - 1) / page);
  std::size_t count = 0;
  if (::mincore(map, bytes, resident.data()) == 0)
    for (unsigned char r : resident) count += r & 1;
  ::munmap(map, bytes);
  return count;
}

// A source file read and then dropped leaves the file cache (on a file system with one).
TEST_F(ScratchMappingTest, ASourceFileDroppedLeavesTheFileCache) {
  if (isMemoryFileSystem(dir_.string())) GTEST_SKIP() << dir_ << " lives in memory: it has no file cache to leave";
  const std::string path = (dir_ / "source.bin").string();
  {
    std::ofstream out(path, std::ios::binary);
    std::vector<char> bytes(std::size_t(4) << 20, 'x');
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
  {  // written back, so that its pages are clean and may be dropped
    const int fd = ::open(path.c_str(), O_RDONLY);
    ASSERT_GE(fd, 0);
    ::fsync(fd);
    ::close(fd);
  }
  std::ifstream in(path, std::ios::binary);
  std::vector<char> back(std::size_t(4) << 20);
  in.read(back.data(), static_cast<std::streamsize>(back.size()));
  ASSERT_GT(cachedPages(path), 0u) << "the file was just read";
  dropFromFileCache(path);
  EXPECT_EQ(cachedPages(path), 0u);
  dropFromFileCache((dir_ / "missing.bin").string());  // no error: there is nothing to drop
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
  // Read calls (whole images, spans of texels) give what the mapping holds.
  std::vector<float> a(15 * 3), b(15 * 3);
  for (int i = 0; i < memory.numImages(); ++i) {
    memory.imageLinear(i, a.data());
    file.imageLinear(i, b.data());
    EXPECT_EQ(a, b) << "image " << i;
  }
  std::vector<std::uint8_t> buffer;
  const std::uint8_t* bytes = file.readImageBytes(3, 6, 9, buffer);
  EXPECT_EQ(std::vector<std::uint8_t>(bytes, bytes + 9), std::vector<std::uint8_t>(memory.imageBytes(3) + 6, memory.imageBytes(3) + 15));
  EXPECT_THROW(file.readImageBytes(3, 40, 9, buffer), Error);
  const int images[] = {5, 0, 2};
  for (const std::vector<int>& texels : {std::vector<int>{4, 2, 3, 9}, std::vector<int>{14, 0}, std::vector<int>{7}}) {
    std::vector<float> g1(3 * 3 * texels.size()), g2(g1.size());
    memory.gatherLinear(images, 3, texels.data(), static_cast<int>(texels.size()), g1.data());
    file.gatherLinear(images, 3, texels.data(), static_cast<int>(texels.size()), g2.data());
    EXPECT_EQ(g1, g2) << texels.size() << " texels from " << texels.front();
    std::vector<std::uint8_t> s1(g1.size()), s2(g1.size());
    memory.gatherStored(images, 3, texels.data(), static_cast<int>(texels.size()), s1.data());
    file.gatherStored(images, 3, texels.data(), static_cast<int>(texels.size()), s2.data());
    EXPECT_EQ(s1, s2) << texels.size() << " texels from " << texels.front();
  }
  // A few texels scattered over a large image are read through the mapping, and agree too.
  BtfStack wideMemory(lights, views, 200, 1, SampleType::Srgb8), wideFile(lights, views, 200, 1, SampleType::Srgb8, dir_.string());
  for (int i = 0; i < wideMemory.numImages(); ++i)
    for (std::size_t k = 0; k < wideMemory.bytesPerImage(); ++k)
      wideMemory.imageBytes(i)[k] = wideFile.imageBytes(i)[k] = static_cast<std::uint8_t>(13 * i + 5 * k);
  const int far[] = {0, 199};
  std::vector<float> w1(3 * 6 * 2), w2(w1.size());
  wideMemory.gatherLinear(nullptr, 0, far, 2, w1.data());
  wideFile.gatherLinear(nullptr, 0, far, 2, w2.data());
  EXPECT_EQ(w1, w2);
  std::vector<std::uint8_t> ws(w1.size());
  wideFile.gatherStored(nullptr, 0, far, 2, ws.data());
  wideFile.storedToLinear(ws.data(), ws.size(), 1.0f, w2.data());
  EXPECT_EQ(w1, w2);
  float lo1, hi1, lo2, hi2;
  memory.valueRange(lo1, hi1);
  file.valueRange(lo2, hi2);
  EXPECT_EQ(lo1, lo2);
  EXPECT_EQ(hi1, hi2);
  BtfStack half(lights, views, 5, 3, SampleType::Half, dir_.string());
  std::vector<float> rgb(15 * 3, 0.25f);
  half.setImageLinear(4, rgb.data());
  EXPECT_EQ(half.sample(4, 14, 2), 0.25f);
  const int span[] = {13, 14};
  std::vector<float> halfValues(3 * 6 * 2);
  half.gatherLinear(nullptr, 0, span, 2, halfValues.data());
  EXPECT_EQ(halfValues[(3 * 4 + 2) * 2 + 1], 0.25f);  // image 4, blue, texel 14
  EXPECT_EQ(halfValues[(3 * 3 + 2) * 2 + 1], 0.0f);
  EXPECT_TRUE(fs::is_empty(dir_));
}

}  // namespace
}  // namespace nbtf
