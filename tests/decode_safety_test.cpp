// `nbtf decode` never destroys a stack it did not write and never leaves two decodes mixed
// (pipeline/decode_folder.h): a measured stack or a foreign folder as -o is refused with
// its files untouched; an earlier decode is replaced whole; a decode killed at any moment
// leaves the earlier decode or the new one, and a staging folder every loader refuses.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>

#include "codec/nbtf_file.h"
#include "codec_fixtures.h"
#include "decoder_fixtures.h"
#include "io/btf_loader.h"
#include "io/btf_names.h"
#include "pipeline/decode_folder.h"
#include "test_util.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;

// Every file below `folder` (relative path -> bytes): what a user would lose.
std::map<std::string, std::vector<std::uint8_t>> snapshot(const std::string& folder) {
  std::map<std::string, std::vector<std::uint8_t>> files;
  std::error_code ec;
  if (!fs::exists(folder, ec)) return files;
  for (const auto& e : fs::recursive_directory_iterator(folder))
    if (e.is_regular_file()) files[fs::relative(e.path(), folder).string()] = readFileBytes(e.path().string());
  return files;
}

std::string readText(const std::string& path) {
  const std::vector<std::uint8_t> bytes = readFileBytes(path);
  return std::string(bytes.begin(), bytes.end());
}

LoadOptions quietLoad() {
  LoadOptions o;
  o.progress = false;
  return o;
}

class DecodeSafety : public ::testing::Test {
 protected:
  void SetUp() override {
    a_ = dir_ / "a.nbtf", b_ = dir_ / "b.nbtf";
    writeNbtf(a_, testing::makeDisplayableMaterial(4, 7, 5, 11));
    writeNbtf(b_, testing::makeDisplayableMaterial(4, 7, 5, 12));
  }
  test::RunResult decode(const std::string& file, const std::string& out, const std::string& extra = "") {
    return test::runNbtf("decode '" + file + "' -o '" + out + "' -q --format png " + extra);
  }
  test::TempDir dir_;
  std::string a_, b_;
};

TEST_F(DecodeSafety, AMeasuredStackIsNeverADestination) {
  const std::string stack = testing::writeTestStack(dir_ / "stack");
  const auto before = snapshot(stack);
  for (const char* format : {"png", "jpg", "exr"}) {
    const test::RunResult r = test::runNbtf("decode '" + a_ + "' -o '" + stack + "' -q --format " + format);
    EXPECT_EQ(r.exitCode, 1) << r.output;
    EXPECT_NE(r.output.find("holds a BTF image stack that nbtf decode did not write"), std::string::npos) << r.output;
    EXPECT_EQ(snapshot(stack), before) << "decode --format " << format << " changed the measured stack";
  }
  EXPECT_NO_THROW(loadBtfStack(stack, quietLoad()));
  // Any other file nbtf did not write is kept too.
  fs::create_directories(dir_ / "notes");
  writeFileAtomic(dir_ / "notes/readme.txt", std::string("mine"));
  const test::RunResult r = decode(a_, dir_ / "notes");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("readme.txt"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(dir_ / "notes/readme.txt"));
}

TEST_F(DecodeSafety, AnEarlierDecodeIsReplacedWholeAndOnlyIfItHoldsNothingElse) {
  const std::string out = dir_ / "out";
  ASSERT_EQ(decode(a_, out).exitCode, 0);
  const auto all = snapshot(out);
  ASSERT_TRUE(all.count(kDecodeDescriptionName));
  // A subset decode of another file replaces it whole: no image of the first is left.
  const test::RunResult r = decode(b_, out, "--lights 0 --views 0");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const auto one = snapshot(out);
  EXPECT_EQ(one.size(), 2u) << "one image and the description";
  const BtfStack stack = loadBtfStack(out, quietLoad());
  EXPECT_EQ(stack.numImages(), 1);
  // A file the user put into a decode folder is not ours to delete.
  writeFileAtomic((fs::path(out) / fs::path(one.begin()->first).parent_path() / "notes.txt").string(), std::string("x"));
  const test::RunResult again = decode(a_, out);
  EXPECT_EQ(again.exitCode, 1) << again.output;
  EXPECT_NE(again.output.find("notes.txt"), std::string::npos) << again.output;
  EXPECT_EQ(snapshot(out).size(), 3u);
}

TEST_F(DecodeSafety, AnInterruptedDecodeIsRefusedByTheLoaderAndCleanedByTheNextDecode) {
  const std::string out = dir_ / "out";
  {
    DecodeFolder folder(out, R"({"generator": "test"})");
    ASSERT_TRUE(fs::is_directory(folder.staging()));
    writeFileAtomic((fs::path(folder.staging()) / "tl000_pl000_tv000_pv000.png").string(), std::string("x"));
    // The description says incomplete: the loader refuses the staging folder by name.
    try {
      loadBtfStack(folder.staging(), quietLoad());
      ADD_FAILURE() << "an incomplete decode loaded";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("interrupted nbtf decode"), std::string::npos) << e.what();
    }
  }  // not committed: removed
  EXPECT_FALSE(fs::exists(dir_ / ".out.nbtf-decoding"));
  EXPECT_FALSE(fs::exists(out));
  // A staging folder left by a killed decode is ours: the next decode removes it and finishes.
  ASSERT_EQ(decode(a_, out).exitCode, 0);
  fs::create_directories(dir_ / ".out.nbtf-decoding");
  writeFileAtomic(dir_ / (".out.nbtf-decoding/" + std::string(kDecodeDescriptionName)), std::string(R"({"complete": false})"));
  ASSERT_EQ(decode(b_, out).exitCode, 0);
  EXPECT_FALSE(fs::exists(dir_ / ".out.nbtf-decoding"));
  // So is one killed before its description was written: empty, or holding only the
  // description's temporary file.
  for (bool temporaryFile : {false, true}) {
    fs::create_directories(dir_ / ".out.nbtf-decoding");
    if (temporaryFile)
      writeFileAtomic(dir_ / (".out.nbtf-decoding/." + std::string(kDecodeDescriptionName) + ".tmp4242_1"),
                      std::string("{"));
    const test::RunResult again = decode(a_, out);
    ASSERT_EQ(again.exitCode, 0) << again.output;
    EXPECT_FALSE(fs::exists(dir_ / ".out.nbtf-decoding"));
  }
  // One that is not ours is left alone, and the decode says so.
  fs::create_directories(dir_ / ".out.nbtf-decoding");
  writeFileAtomic(dir_ / ".out.nbtf-decoding/precious.txt", std::string("x"));
  const test::RunResult r = decode(a_, out);
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_TRUE(fs::exists(dir_ / ".out.nbtf-decoding/precious.txt"));
}

// Removing a decode (an earlier one after the exchange, or a staging folder) marks it
// incomplete before its images go: a removal stopped half-way never leaves a folder that
// claims to be complete. The stop is made real with an immutable view folder (chattr +i).
TEST_F(DecodeSafety, ARemovalStoppedHalfWayLeavesADecodeMarkedIncomplete) {
  const std::string out = dir_ / "out";
  ASSERT_EQ(decode(a_, out).exitCode, 0);
  std::string view;
  for (const auto& e : fs::directory_iterator(out))
    if (e.is_directory()) view = e.path().string();
  ASSERT_FALSE(view.empty());
  if (std::system(("chattr +i '" + view + "' 2>/dev/null").c_str()) != 0)
    GTEST_SKIP() << "chattr +i is not available here (it makes the removal stop half-way)";
  std::error_code ec;
  removeDecodeFolder(out, ec);
  const std::string description = readText(out + "/" + kDecodeDescriptionName);
  const int undo = std::system(("chattr -i '" + view + "'").c_str());
  EXPECT_EQ(undo, 0);
  EXPECT_TRUE(ec) << "the immutable folder should have stopped the removal";
  EXPECT_NE(description.find("\"complete\": false"), std::string::npos) << description;
  try {
    loadBtfStack(out, quietLoad());
    ADD_FAILURE() << "a half-removed decode loaded";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("interrupted nbtf decode"), std::string::npos) << e.what();
  }
  ASSERT_EQ(decode(b_, out).exitCode, 0);  // the next decode still recognises it as its own
}

TEST_F(DecodeSafety, ImpossibleSizesAreRefusedAndFileOutputsGetTheirFolders) {
  test::RunResult r = decode(a_, dir_ / "big", "--size 65536x65536");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("--size 65536x65536: decoding needs about"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("bad_alloc"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir_ / "big"));
  const std::string btf = dir_ / "a/b/x.btf";
  r = test::runNbtf("decode '" + a_ + "' --layout ubo2014 --components 2 -o '" + btf + "' -q");
  EXPECT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(fs::is_regular_file(btf));
  // The input itself is never an output.
  r = test::runNbtf("decode '" + a_ + "' --layout ubo2014 -o '" + a_ + "' -q");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("is the same file as the input <file.nbtf>"), std::string::npos) << r.output;
  EXPECT_NO_THROW(readNbtf(a_));
}

TEST_F(DecodeSafety, AKilledDecodeLeavesTheEarlierDecodeOrTheNewOneNeverAMixture) {
  // Large images (the texture tiled to 384 x 384) so that a decode takes a while.
  const std::string out = dir_ / "out", refB = dir_ / "ref_b";
  const std::string size = "--size 384x384";
  ASSERT_EQ(decode(a_, out, size).exitCode, 0);
  ASSERT_EQ(decode(b_, refB, size).exitCode, 0);
  const auto oldDecode = snapshot(out), newDecode = snapshot(refB);
  ASSERT_NE(oldDecode, newDecode);
  int sawOld = 0, sawNew = 0;
  for (int delayMs : {0, 5, 15, 30, 50, 80, 120, 180, 260, 400}) {
    const std::string bin = std::string(NBTF_BIN_DIR) + "/nbtf";
    pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      ::execl(bin.c_str(), "nbtf", "decode", b_.c_str(), "-o", out.c_str(), "-q", "--format", "png", "--size",
              "384x384", static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::usleep(delayMs * 1000);
    ::kill(pid, SIGKILL);
    ::waitpid(pid, nullptr, 0);
    const auto now = snapshot(out);
    const bool isOld = now == oldDecode, isNew = now == newDecode;
    EXPECT_TRUE(isOld || isNew) << "after a kill at " << delayMs << " ms, " << out << " holds " << now.size()
                                << " files that are neither decode";
    sawOld += isOld, sawNew += isNew;
    std::error_code ec;
    if (fs::exists(dir_ / ".out.nbtf-decoding", ec) && fs::exists(dir_ / (".out.nbtf-decoding/" + std::string(kDecodeDescriptionName)), ec) &&
        readFileBytes(dir_ / (".out.nbtf-decoding/" + std::string(kDecodeDescriptionName))).size() > 0) {
      const std::string text = [&] {
        auto bytes = readFileBytes(dir_ / (".out.nbtf-decoding/" + std::string(kDecodeDescriptionName)));
        return std::string(bytes.begin(), bytes.end());
      }();
      if (text.find("\"complete\": false") != std::string::npos)
        EXPECT_THROW(loadBtfStack(dir_ / ".out.nbtf-decoding", quietLoad()), Error);
    }
    // Back to the earlier decode for the next round.
    if (!isOld) {
      const test::RunResult back = decode(a_, out, size);
      ASSERT_EQ(back.exitCode, 0) << back.output;
    }
  }
  // Which moments the kills hit depends on the machine; both outcomes are fine, each counted.
  std::printf("kills that left the earlier decode: %d, the new one: %d\n", sawOld, sawNew);
  const test::RunResult last = decode(b_, out, size);
  ASSERT_EQ(last.exitCode, 0) << last.output;
  EXPECT_EQ(snapshot(out), newDecode) << "a decode after the kills finishes";
}

}  // namespace
}  // namespace nbtf
