// Faults: `nbtf compress` and `nbtf decode` killed with SIGKILL at random,
// seeded moments, again and again. Whatever the moment, no partial file may appear under
// a final name: the output .nbtf is absent, the previous file, or the complete new one;
// every decoded image under its final name is complete. `--resume` / a re-run then
// finishes the job with the result of an uninterrupted run.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>

#include "codec/nbtf_file.h"
#include "codec_fixtures.h"
#include "decoder_fixtures.h"
#include "io/btf_loader.h"
#include "io/btf_names.h"
#include "util/directions.h"
#include "io/image_io.h"
#include "test_util.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace nbtf {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// `nbtf ARGS...` as a child process, output discarded.
pid_t spawnNbtf(const std::vector<std::string>& args) {
  std::vector<std::string> argv = {"nbtf"};
  argv.insert(argv.end(), args.begin(), args.end());
  std::vector<char*> cargv;
  for (auto& a : argv) cargv.push_back(a.data());
  cargv.push_back(nullptr);
  const std::string bin = std::string(NBTF_BIN_DIR) + "/nbtf";
  pid_t pid = ::fork();
  if (pid == 0) {
    int fd = ::open("/dev/null", O_WRONLY);
    ::dup2(fd, 1);
    ::dup2(fd, 2);
    ::execv(bin.c_str(), cargv.data());
    ::_exit(127);
  }
  return pid;
}

// Waits for the child; returns its exit status, or -1 if a signal ended it.
int waitExit(pid_t pid) {
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

struct Outcome {
  bool killed = false;  // false: the child had already exited by itself
  int exitCode = -1;
};

// Lets the child run for `seconds`, then SIGKILLs it (unless it has ended by then). With
// `afterFile`, the seconds count from when that file exists: on a loaded machine the child's
// start takes longer than any fixed delay foresees.
Outcome killAfter(pid_t pid, double seconds, const std::string& afterFile = "") {
  int status = 0;
  while (!afterFile.empty() && !fs::exists(afterFile)) {
    if (::waitpid(pid, &status, WNOHANG) == pid) return {false, WIFEXITED(status) ? WEXITSTATUS(status) : -1};
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  const auto start = Clock::now();
  while (secondsSince(start) < seconds) {
    if (::waitpid(pid, &status, WNOHANG) == pid) return {false, WIFEXITED(status) ? WEXITSTATUS(status) : -1};
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ::kill(pid, SIGKILL);
  ::waitpid(pid, &status, 0);
  if (WIFSIGNALED(status)) return {true, -1};
  return {false, WIFEXITED(status) ? WEXITSTATUS(status) : -1};
}

// Regular files under `root` by path relative to it, split into visible and hidden names
// (a leading dot: the temporary names of util/atomic_file.h).
struct Listing {
  std::vector<std::string> visible, hidden;
};
Listing listFiles(const std::string& root) {
  Listing l;
  if (!fs::exists(root)) return l;  // killed before the folder was made
  for (const auto& e : fs::recursive_directory_iterator(root)) {
    if (!e.is_regular_file()) continue;
    std::string rel = fs::relative(e.path(), root).string();
    (e.path().filename().string()[0] == '.' ? l.hidden : l.visible).push_back(rel);
  }
  std::sort(l.visible.begin(), l.visible.end());
  return l;
}

// ---- nbtf compress --------------------------------------------------------------------

TEST(KillCompress, RandomSigkillsLeaveNoPartialFileAndResumeMatchesAnUninterruptedRun) {
  test::TempDir dir;
  const std::string stack = testing::writeTestStack(dir / "stack");
  // The model tests' quick recipe, checkpointing every 50 ms so that kills land between
  // checkpoints, during checkpoint writes and during the final write.
  TrainConfig q = testing::quickConfig();
  writeFileAtomic(dir / "quick.json",
                  R"({"optimizer": {"name": "adam", "learning_rate": )" + std::to_string(q.learningRate) +
                      R"(}, "training": {"batch_size": )" + std::to_string(q.batchSize) +
                      R"(, "images_per_input": )" + std::to_string(q.imagesPerInput) +
                      R"(, "epochs": 400, "min_steps": 0, "min_steps_per_input": 0, "checkpoint_seconds": 0.05}})");
  auto compressArgs = [&](const std::string& out, const std::string& stats) {
    return std::vector<std::string>{"compress", stack, "-o", out, "--clusters", "5", "--seed", "3", "--threads", "1",
                                    "--config", dir / "quick.json", "--stats-json", stats, "-q", "--resume"};
  };

  // The uninterrupted reference, timed to place the kills.
  const auto refStart = Clock::now();
  ASSERT_EQ(waitExit(spawnNbtf(compressArgs(dir / "ref.nbtf", dir / "ref.json"))), 0);
  const double refSeconds = secondsSince(refStart);
  const std::vector<std::uint8_t> refBytes = readFileBytes(dir / "ref.nbtf");
  const nlohmann::json refStats = nlohmann::json::parse(std::ifstream(dir / "ref.json"));
  const double refRmse = refStats["rmse_train"].get<double>();
  // Wall time before training starts (process start, libraries, load, clustering).
  const double trainSeconds = refStats["seconds"]["train"].get<double>();
  const double startSeconds = std::max(0.05, refSeconds - trainSeconds);

  // The output path holds an older, valid file: it must survive every kill intact.
  const std::string out = dir / "out.nbtf";
  writeNbtf(out, testing::makeBtf(3));
  const std::vector<std::uint8_t> previous = readFileBytes(out);

  // Kills alternate between the start (loading, clustering; no checkpoint yet or the
  // previous run's) and training (once a checkpoint exists: between and during checkpoint
  // writes); each resumed run gets a little further, and the last one must finish what is left.
  std::mt19937 rng(20261121);
  std::uniform_real_distribution<double> duringStart(0.02, startSeconds), duringTraining(0.0, 0.2 * trainSeconds);
  int kills = 0, killsWithCheckpoint = 0, killsAfterTheWrite = 0;
  for (int attempt = 0; attempt < 8; ++attempt) {
    const bool inTraining = attempt % 2 == 1;
    const double after = inTraining ? duringTraining(rng) : duringStart(rng);
    Outcome o = killAfter(spawnNbtf(compressArgs(out, dir / "out.json")), after, inTraining ? out + ".ckpt" : "");
    if (!o.killed) {
      ASSERT_EQ(o.exitCode, 0) << "the run ended by itself, but failed";
      break;
    }
    ++kills;
    killsWithCheckpoint += fs::exists(out + ".ckpt");
    SCOPED_TRACE("kill " + std::to_string(kills) + " after " + std::to_string(after) + " s" +
                 (inTraining ? " of training" : ""));
    ASSERT_TRUE(fs::exists(out)) << "the previous file disappeared";
    std::vector<std::uint8_t> now = readFileBytes(out);
    if (now != previous) {
      // Replaced: only by the complete new file, which then reads back.
      ++killsAfterTheWrite;
      EXPECT_NO_THROW(readNbtf(out));
      EXPECT_EQ(now, refBytes) << "a killed and resumed run wrote a different file";
    }
  }
  std::printf("uninterrupted run %.2f s (%.2f s training); %d kills, %d left a checkpoint, %d came after the output was written\n",
              refSeconds, trainSeconds, kills, killsWithCheckpoint, killsAfterTheWrite);
  EXPECT_GE(kills, 3) << "too few kills landed while the run was going";
  EXPECT_GE(killsWithCheckpoint, 1) << "no kill landed during training: --resume was not exercised";

  // A last --resume completes, with the quality (and, deterministic, the bytes) of the
  // uninterrupted run.
  ASSERT_EQ(waitExit(spawnNbtf(compressArgs(out, dir / "out.json"))), 0);
  EXPECT_EQ(readFileBytes(out), refBytes);
  const double rmse = nlohmann::json::parse(std::ifstream(dir / "out.json"))["rmse_train"].get<double>();
  EXPECT_NEAR(rmse, refRmse, 1e-3 * refRmse);
  EXPECT_FALSE(fs::exists(out + ".ckpt"));
  for (const std::string& f : listFiles(dir.path()).visible)
    EXPECT_TRUE(f.rfind("stack/", 0) == 0 || f == "quick.json" || f == "ref.nbtf" || f == "ref.json" ||
                f == "out.nbtf" || f == "out.json")
        << "unexpected file " << f;
}

// ---- nbtf decode ----------------------------------------------------------------------

LoadOptions quietLoad() {
  LoadOptions o;
  o.progress = false;
  return o;
}

// 81 lights x 12 views of 24 x 16 texels, 8-bit PNG: long enough to be stopped mid-way.
void writeDecodeMaterial(const std::string& path) {
  CompressedBtf m = testing::makeDisplayableMaterial(4, 24, 16);
  m.lights = hemisphere81();
  m.views.assign(hemisphere81().begin(), hemisphere81().begin() + 12);
  m.holdoutImages.clear();
  m.layout = Layout::Ubo2003;
  m.sourceSampleType = SampleType::Srgb8;
  m.crop = {};
  m.sourceWidth = m.width, m.sourceHeight = m.height;
  writeNbtf(path, m);
}

// Ctrl-C during a decode: the images written so far were in the staging folder, which is
// removed; the earlier decode at the destination is untouched; the command says so, exit 130.
TEST(KillDecode, CtrlCRemovesTheStagingFolderAndSaysWhatHappened) {
  test::TempDir dir;
  writeDecodeMaterial(dir / "m.nbtf");
  const std::string out = dir / "out", staging = dir / ".out.nbtf-decoding", log = dir / "log.txt";
  ASSERT_EQ(waitExit(spawnNbtf({"decode", dir / "m.nbtf", "-o", out, "--lights", "0", "-q"})), 0);
  const Listing earlier = listFiles(out);
  // Large images, so that the decode runs long enough to be interrupted in the middle.
  const std::string cmd = "exec '" + std::string(NBTF_BIN_DIR) + "/nbtf' decode '" + (dir / "m.nbtf") + "' -o '" + out +
                          "' --size 512x512 --format png -q > '" + log + "' 2>&1";
  pid_t pid = ::fork();
  if (pid == 0) {
    ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  bool started = false;
  for (int i = 0; i < 3000 && !started; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    started = listFiles(staging).visible.size() >= 3;  // the description and two images
  }
  ::kill(pid, SIGINT);
  const int code = waitExit(pid);
  ASSERT_TRUE(started) << "the decode never wrote an image";
  const std::vector<std::uint8_t> bytes = readFileBytes(log);
  const std::string text(bytes.begin(), bytes.end());
  EXPECT_EQ(code, 130) << text;
  EXPECT_NE(text.find("nbtf decode: interrupted after "), std::string::npos) << text;
  EXPECT_NE(text.find("now removed: nothing was written to " + out + " (what was there is unchanged)"), std::string::npos)
      << text;
  EXPECT_FALSE(fs::exists(staging));
  EXPECT_EQ(listFiles(out).visible, earlier.visible);
}

TEST(KillDecode, EveryImageUnderItsFinalNameIsCompleteAndARerunFinishes) {
  test::TempDir dir;
  writeDecodeMaterial(dir / "m.nbtf");
  auto decodeArgs = [&](const std::string& out) {
    return std::vector<std::string>{"decode", dir / "m.nbtf", "-o", out, "--format", "png", "-q"};
  };

  // The uninterrupted reference, timed to place the kills.
  const auto refStart = Clock::now();
  ASSERT_EQ(waitExit(spawnNbtf(decodeArgs(dir / "ref"))), 0);
  const double refSeconds = secondsSince(refStart);
  const Listing ref = listFiles(dir / "ref");
  ASSERT_EQ(ref.visible.size(), 81u * 12u + 1) << "every image and the decode's description";
  ASSERT_TRUE(ref.hidden.empty());
  std::map<std::string, std::vector<std::uint8_t>> refBytes;
  for (const std::string& f : ref.visible) refBytes[f] = readFileBytes(dir / ("ref/" + f));

  // The images go into a staging folder that takes the output's place only once complete
  // (pipeline/decode_folder.h): a killed decode leaves no output folder at all, and a staging
  // folder whose finished images are complete and which every loader refuses as a whole.
  const std::string out = dir / "out", staging = dir / ".out.nbtf-decoding";
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> moment(0.1 * refSeconds, 0.8 * refSeconds);
  int kills = 0;
  // Up to 8 tries for 3 kills: on a loaded machine a decode may finish before its moment.
  for (int attempt = 0; attempt < 8 && kills < 3; ++attempt) {
    Outcome o = killAfter(spawnNbtf(decodeArgs(out)), moment(rng));
    if (!o.killed) {
      fs::remove_all(out);
      continue;
    }
    if (fs::exists(out)) {
      // Killed after its last step, the staging folder taking the output's place: then the
      // output is whole, and no staging folder is left.
      std::vector<std::string> got = listFiles(out).visible, want = ref.visible;
      std::sort(got.begin(), got.end());
      std::sort(want.begin(), want.end());
      EXPECT_EQ(got, want) << "a killed decode left a partial output folder";
      EXPECT_FALSE(fs::exists(staging));
      fs::remove_all(out);
      continue;
    }
    ++kills;
    SCOPED_TRACE("decode kill " + std::to_string(kills));
    const Listing l = listFiles(staging);
    for (const std::string& f : l.visible) {
      if (f == kDecodeDescriptionName) continue;
      ASSERT_TRUE(refBytes.count(f)) << "unexpected file " << f;
      EXPECT_EQ(readFileBytes(staging + "/" + f), refBytes[f]) << f << " is incomplete";
    }
    if (fs::exists(staging)) {
      try {
        loadBtfStack(staging, quietLoad());
        ADD_FAILURE() << "the staging folder of a killed decode loaded";
      } catch (const nbtf::Error& e) {
        EXPECT_NE(std::string(e.what()).find("interrupted nbtf decode"), std::string::npos) << e.what();
      }
    }
  }
  std::printf("uninterrupted decode %.2f s; %d kills\n", refSeconds, kills);
  EXPECT_GE(kills, 2) << "too few kills landed while decoding";

  // Re-running into the same folder finishes the stack; it loads and equals the reference,
  // and the staging folder is gone.
  ASSERT_EQ(waitExit(spawnNbtf(decodeArgs(out))), 0);
  EXPECT_FALSE(fs::exists(staging));
  const Listing done = listFiles(out);
  ASSERT_EQ(done.visible, ref.visible);
  for (const std::string& f : done.visible) EXPECT_EQ(readFileBytes(out + "/" + f), refBytes[f]) << f;
  BtfStack stack = loadBtfStack(out, quietLoad());
  EXPECT_EQ(stack.numImages(), 81 * 12);
  EXPECT_EQ(stack.width(), 24);
}

}  // namespace
}  // namespace nbtf
