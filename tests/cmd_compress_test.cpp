// Runs the built `nbtf compress` and `nbtf info` binaries: exit codes, messages for bad
// input, and a small end-to-end run whose file `nbtf info` then describes.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <thread>
#include <nlohmann/json.hpp>

#include "codec/nbtf_file.h"
#include "codec_fixtures.h"
#include "test_util.h"
#include "util/atomic_file.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;

using test::RunResult;
RunResult run(const std::string& args) { return test::runNbtf(args); }

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

// A scratch folder per test, removed afterwards.
class CmdCompress : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("nbtf_cmd_compress_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
            std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::permissions(dir_, fs::perms::owner_all, fs::perm_options::add, ec);
    fs::remove_all(dir_, ec);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  std::string writeStack() { return testing::writeTestStack(path("stack")); }

  // A config file for a quick run (the test recipe of the model tests).
  std::string writeQuickConfig(int epochs, double checkpointSeconds = 300, const std::string& extra = "") {
    TrainConfig c = testing::quickConfig();
    std::string text = R"({"optimizer": {"name": "adam", "learning_rate": )" + std::to_string(c.learningRate) +
                       R"(}, "training": {"batch_size": )" + std::to_string(c.batchSize) +
                       R"(, "images_per_input": )" + std::to_string(c.imagesPerInput) +
                       R"(, "min_steps": 0, "min_steps_per_input": 0, "epochs": )" + std::to_string(epochs) +
                       R"(, "checkpoint_seconds": )" + std::to_string(checkpointSeconds) + extra + "}}";
    writeFileAtomic(path("quick.json"), text);
    return path("quick.json");
  }

  // Starts `nbtf compress` on a run far too long to finish, checkpointing every 0.2 s, and
  // sends SIGINT once its checkpoint shows that training has started.
  struct Interrupted {
    int status = 0;
    std::string log;
  };
  Interrupted interruptTraining(const std::string& stack, const std::string& out) {
    std::string config = writeQuickConfig(1000000, 0.2);
    std::string log = path("int.log"), bin = std::string(NBTF_BIN_DIR) + "/nbtf";
    pid_t pid = fork();
    if (pid == 0) {
      int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      ::dup2(fd, 1);
      ::dup2(fd, 2);
      ::execl(bin.c_str(), "nbtf", "compress", stack.c_str(), "-o", out.c_str(), "--clusters", "5", "--threads", "1",
              "--config", config.c_str(), "-q", static_cast<char*>(nullptr));
      ::_exit(127);
    }
    auto waitFor = [](auto condition, double seconds) {
      for (int i = 0; i < seconds * 20 && !condition(); ++i) ::usleep(50000);
      return condition();
    };
    const bool training = waitFor([&] { return fs::exists(out + ".ckpt"); }, 60);
    ::kill(pid, SIGINT);
    Interrupted result;
    bool exited = false;  // waitpid reaps once: remember the answer
    waitFor([&] { return exited = exited || ::waitpid(pid, &result.status, WNOHANG) == pid; }, 60);
    if (!exited) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &result.status, 0);
    }
    result.log = std::string((std::istreambuf_iterator<char>(*std::make_unique<std::ifstream>(log))), {});
    EXPECT_TRUE(training) << "no checkpoint appeared";
    EXPECT_TRUE(exited) << "nbtf compress did not stop after SIGINT";
    return result;
  }

  fs::path dir_;
};

TEST_F(CmdCompress, MissingInputIsNamed) {
  RunResult r = run("compress " + path("no_such_stack") + " -o " + path("out.nbtf") + " -q");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_TRUE(contains(r.output, "nbtf compress: error: " + path("no_such_stack") + ": no such file or folder"))
      << r.output;
  EXPECT_FALSE(fs::exists(path("out.nbtf")));
}

// --memory-limit: a run whose estimated peak is above it is refused before loading, with the
// stack, the estimate and the limit named, and nothing written; a bad size names the option.
TEST_F(CmdCompress, MemoryLimitRefusesWhatCannotFit) {
  std::string stack = writeStack();
  const std::string out = path("out.nbtf");
  RunResult r = run("compress " + stack + " -o " + out + " --clusters 4 -q --memory-limit 100M");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_TRUE(contains(r.output, "nbtf compress: error: " + stack + ": ")) << r.output;
  EXPECT_TRUE(contains(r.output, "need about")) << r.output;
  EXPECT_TRUE(contains(r.output, "--memory-limit 100M allows 100 MiB")) << r.output;
  EXPECT_TRUE(contains(r.output, "the stack and the program alone do not fit")) << r.output;
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out + ".ckpt"));
  EXPECT_FALSE(contains(r.output, "load")) << "refused before loading: " << r.output;
  r = run("compress " + stack + " -o " + out + " --clusters 4 -q --memory-limit 12X");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_TRUE(contains(r.output, "--memory-limit: expected a size in bytes")) << r.output;
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(CmdCompress, UnwritableOutputFailsBeforeAnyWork) {
  std::string stack = writeStack();
  // Missing folders are created (one rule for every command), but not through a file.
  writeFileAtomic(path("a_file"), std::string("not a folder"));
  RunResult r = run("compress " + stack + " -o " + path("a_file/out.nbtf") + " -q");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_TRUE(contains(r.output, "out.nbtf: cannot create the folder")) << r.output;
  EXPECT_FALSE(contains(r.output, "summary")) << r.output;
  if (::geteuid() != 0) {  // root writes anywhere: only a real user can see the permission error
    fs::create_directories(path("readonly"));
    fs::permissions(path("readonly"), fs::perms::owner_read | fs::perms::owner_exec);
    r = run("compress " + stack + " -o " + path("readonly/out.nbtf") + " -q");
    EXPECT_EQ(r.exitCode, 1) << r.output;
    EXPECT_TRUE(contains(r.output, "is not writable")) << r.output;
  }
}

TEST_F(CmdCompress, BadOptionsAreRejected) {
  RunResult r = run("compress " + path("x") + " -q");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "missing -o <out.nbtf>")) << r.output;
  r = run("compress " + path("x") + " -o " + path("o.nbtf") + " --clusters -3");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "--clusters must be >= 0")) << r.output;
  r = run("compress " + path("x") + " -o " + path("o.nbtf") + " --holdout 1.5");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "--holdout must be a fraction in [0, 1), got 1.5")) << r.output;
  r = run("compress " + path("x") + " -o " + path("o.nbtf") + " --cluster-space srgb");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "--cluster-space: expected log or linear, got 'srgb'")) << r.output;
  writeFileAtomic(path("typo.json"), R"({"training": {"epochz": 3}})");
  r = run("compress " + path("x") + " -o " + path("o.nbtf") + " --config " + path("typo.json"));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "typo.json: 'training.epochz' unknown key")) << r.output;
}

TEST_F(CmdCompress, CompressThenInfoEndToEnd) {
  std::string stack = writeStack();
  std::string out = path("m.nbtf"), stats = path("stats.json");
  RunResult r = run("compress " + stack + " -o " + out + " --clusters 6 --holdout 0.1 --seed 3 --threads 1 --config " +
                    writeQuickConfig(60) + " --stats-json " + stats + " -q");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "summary: " + out + " (clustered-neural, k = 6)")) << r.output;
  EXPECT_TRUE(contains(r.output, "held-out images")) << r.output;
  EXPECT_TRUE(contains(r.output, "time (wall clock, s): load")) << r.output;
  EXPECT_FALSE(fs::exists(out + ".ckpt"));  // a finished run leaves no checkpoint behind

  CompressedBtf b = readNbtf(out);
  EXPECT_EQ(b.numClusters(), 6);
  EXPECT_EQ(b.layout, Layout::Utia);
  nlohmann::json j = nlohmann::json::parse(std::ifstream(stats));
  EXPECT_EQ(j["bytes"]["file"].get<std::uint64_t>(), fs::file_size(out));
  EXPECT_GT(j["rmse_holdout"].get<double>(), 0);

  RunResult info = run("info " + out);
  EXPECT_EQ(info.exitCode, 0) << info.output;
  EXPECT_TRUE(contains(info.output, "clustered-neural, k = 6 clusters")) << info.output;
  EXPECT_TRUE(contains(info.output, "8 x 8 = 64")) << info.output;
  EXPECT_TRUE(contains(info.output, "81 (9 lights x 9 views)")) << info.output;
  EXPECT_TRUE(contains(info.output, "raw float32")) << info.output;
  EXPECT_TRUE(contains(info.output, "seed 3")) << info.output;

  // The same command again gives the same bytes (--resume without a checkpoint starts afresh).
  std::string again = path("again.nbtf");
  r = run("compress " + stack + " -o " + again + " --clusters 6 --holdout 0.1 --seed 3 --threads 1 --config " +
          path("quick.json") + " -q --resume");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "--resume: no checkpoint at " + again + ".ckpt, starting from the beginning"))
      << r.output;
  EXPECT_EQ(readFileBytes(again), readFileBytes(out));
}

// Without --clusters, k is the config's clustering.clusters (1000 by default), capped on a small
// input to one cluster per 10 texels; an asked-for k above the texel count stays an error.
TEST_F(CmdCompress, DefaultClusterCountAdaptsToASmallInput) {
  std::string stack = writeStack();  // 8 x 8 texels
  std::string out = path("d.nbtf"), stats = path("d.json");
  RunResult r = run("compress " + stack + " -o " + out + " --seed 1 --threads 1 --config " + writeQuickConfig(3) +
                    " --stats-json " + stats + " -q");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "(clustered-neural, k = 6: the config's 1000 capped to one cluster per 10 of the 64 texels)"))
      << r.output;
  EXPECT_EQ(readNbtf(out).numClusters(), 6);
  nlohmann::json j = nlohmann::json::parse(std::ifstream(stats));
  EXPECT_EQ(j["clusters"].get<int>(), 6);
  EXPECT_EQ(j["clusters_configured"].get<int>(), 1000);

  // A config's own k below the cap is used as it is, and the stats say nothing was capped.
  writeFileAtomic(path("k3.json"), R"({"clustering": {"clusters": 3}, "training": {"batch_size": 1024, )"
                                   R"("images_per_input": 64, "min_steps": 0, "min_steps_per_input": 0, "epochs": 2}})");
  r = run("compress " + stack + " -o " + out + " --seed 1 --threads 1 --config " + path("k3.json") +
          " --stats-json " + stats + " -q");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "(clustered-neural, k = 3)\n")) << r.output;
  EXPECT_EQ(readNbtf(out).numClusters(), 3);
  EXPECT_TRUE(nlohmann::json::parse(std::ifstream(stats))["clusters_configured"].is_null());

  // --clusters is a request: above the texel count it is refused, not capped.
  fs::remove(out);
  r = run("compress " + stack + " -o " + out + " --clusters 100 --threads 1 --config " + path("quick.json") + " -q");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_TRUE(contains(r.output, "--clusters 100 is larger than the 64 texels")) << r.output;
  EXPECT_FALSE(fs::exists(out));
  // The same with a crop: its texels decide, before loading.
  r = run("compress " + stack + " -o " + out + " --clusters 20 --crop 0,0,4,4 --threads 1 --config " +
          path("quick.json") + " -q");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_TRUE(contains(r.output, "--clusters 20 is larger than the 16 texels of the crop")) << r.output;
  EXPECT_FALSE(fs::exists(out));
  r = run("compress " + stack + " -o " + out + " --crop 0,0,4,4 --seed 1 --threads 1 --config " + path("quick.json") +
          " -q");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "k = 1: the config's 1000 capped to one cluster per 10 of the 16 texels")) << r.output;
}

// "clustering.texels_per_cluster" makes k follow the input's size (the same ratio on every
// input); --clusters still overrides it.
TEST_F(CmdCompress, TexelsPerClusterSetsKFromTheInputsSize) {
  std::string stack = writeStack();  // 8 x 8 texels
  std::string out = path("t.nbtf"), stats = path("t.json");
  writeFileAtomic(path("per.json"), R"({"clustering": {"texels_per_cluster": 2.5}, "training": {"batch_size": 1024, )"
                                    R"("images_per_input": 64, "min_steps": 0, "min_steps_per_input": 0, "epochs": 2}})");
  RunResult r = run("compress " + stack + " -o " + out + " --seed 1 --threads 1 --config " + path("per.json") +
                    " --stats-json " + stats + " -q");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "(clustered-neural, k = 26: one cluster per 2.5 of the 64 texels (the config's "
                                 "texels_per_cluster))"))
      << r.output;
  EXPECT_EQ(readNbtf(out).numClusters(), 26);  // round(64 / 2.5)
  nlohmann::json j = nlohmann::json::parse(std::ifstream(stats));
  EXPECT_EQ(j["texels_per_cluster"].get<double>(), 2.5);
  EXPECT_TRUE(j["clusters_configured"].is_null());
  // A crop of 4 x 4 texels: k = round(16 / 2.5) = 6.
  r = run("compress " + stack + " -o " + out + " --crop 0,0,4,4 --seed 1 --threads 1 --config " + path("per.json") +
          " -q");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(readNbtf(out).numClusters(), 6);
  r = run("compress " + stack + " -o " + out + " --clusters 5 --seed 1 --threads 1 --config " + path("per.json") +
          " --stats-json " + stats + " -q");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(readNbtf(out).numClusters(), 5);
  EXPECT_TRUE(nlohmann::json::parse(std::ifstream(stats))["texels_per_cluster"].is_null());
}

// --stack-storage file keeps the samples in an unnamed scratch file (under --scratch-dir): the
// same file as with the stack in memory, nothing left in the folder, the folder in the stats.
TEST_F(CmdCompress, StackInAScratchFileGivesTheSameFile) {
  std::string stack = writeStack();
  const std::string common = " --clusters 6 --holdout 0.1 --seed 3 --threads 2 --config " + writeQuickConfig(20) + " -q";
  RunResult r = run("compress " + stack + " -o " + path("memory.nbtf") + common + " --stack-storage memory");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  fs::create_directories(path("scratch"));
  r = run("compress " + stack + " -o " + path("file.nbtf") + common + " --stack-storage file --scratch-dir " +
          path("scratch") + " --stats-json " + path("stats.json"));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(readFileBytes(path("file.nbtf")), readFileBytes(path("memory.nbtf")));
  EXPECT_TRUE(fs::is_empty(path("scratch"))) << "the scratch file has no name and goes with the process";
  nlohmann::json j = nlohmann::json::parse(std::ifstream(path("stats.json")));
  EXPECT_TRUE(contains(j["stack_scratch_dir"].get<std::string>(), "scratch")) << j.dump();
  // auto keeps a stack this small in memory.
  r = run("compress " + stack + " -o " + path("auto.nbtf") + common + " --stats-json " + path("auto.json"));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(nlohmann::json::parse(std::ifstream(path("auto.json")))["stack_scratch_dir"].get<std::string>(), "");
  EXPECT_EQ(readFileBytes(path("auto.nbtf")), readFileBytes(path("memory.nbtf")));

  r = run("compress " + stack + " -o " + path("x.nbtf") + common + " --stack-storage disk");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "--stack-storage must be auto, memory or file, got \"disk\"")) << r.output;
  r = run("compress " + stack + " -o " + path("x.nbtf") + common + " --stack-storage file --scratch-dir " +
          path("missing"));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, path("missing") + ": --scratch-dir: not a folder")) << r.output;
  EXPECT_FALSE(fs::exists(path("x.nbtf")));
}

// A config file's training.threads is capped at the cores like --threads, with the same
// warning (it was taken as given: 1000 threads ran, and the file recorded 1000).
TEST_F(CmdCompress, ConfigThreadsAreCappedLikeTheOption) {
  const int cores = static_cast<int>(std::thread::hardware_concurrency());
  if (cores < 1) GTEST_SKIP() << "the number of cores is unknown here";
  std::string stack = writeStack();
  std::string out = path("m.nbtf"), stats = path("stats.json");
  std::string config = writeQuickConfig(4, 300, R"(, "threads": 100000)");
  RunResult r = run("compress " + stack + " -o " + out + " --clusters 4 -q --config " + config);
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "nbtf compress: warning: training.threads in " + config + ": 100000 is more than the " +
                                     std::to_string(cores) + " cores of this machine; using " + std::to_string(cores)))
      << r.output;
  nlohmann::json meta = nlohmann::json::parse(readNbtf(out).metadataJson);
  EXPECT_EQ(meta["threads"].get<int>(), cores);
  // --threads still wins over the file, with its own warning.
  r = run("compress " + stack + " -o " + out + " --clusters 4 -q --threads 1 --config " + config);
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_FALSE(contains(r.output, "warning")) << r.output;
  EXPECT_EQ(nlohmann::json::parse(readNbtf(out).metadataJson)["threads"].get<int>(), 1);
}

// `--config NAME` reads a config of configs/ compiled in, and the file records its name; a name
// that is neither a file nor a built-in config says which names there are.
TEST_F(CmdCompress, BuiltInConfigsAreNamedAndRecorded) {
  std::string stack = writeStack();
  std::string out = path("c.nbtf");
  RunResult r = run("compress " + stack + " -o " + out + " --clusters 4 --epochs 1 -q --config compact");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  nlohmann::json meta = nlohmann::json::parse(readNbtf(out).metadataJson);
  EXPECT_EQ(meta["config_name"], "compact");
  EXPECT_EQ(meta["config"]["model"]["decoder_width"], 64);
  EXPECT_EQ(meta["config"]["modulation"]["channels"], 1);
  r = run("compress " + stack + " -o " + path("d.nbtf") + " --clusters 4 --epochs 1 -q");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_FALSE(nlohmann::json::parse(readNbtf(path("d.nbtf")).metadataJson).contains("config_name"));
  r = run("compress " + stack + " -o " + path("e.nbtf") + " --clusters 4 -q --config compactt");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "compactt: cannot open config file (nor is it a built-in config: adaptive, balanced, close_up, compact, "
                                 "converged, default, high_fidelity, paper, paper-clustered)"))
      << r.output;
  EXPECT_FALSE(fs::exists(path("e.nbtf")));
}

// Command-line rough edges, each as a new user met it.
TEST_F(CmdCompress, CommandLineRoughEdges) {
  std::string stack = writeStack();  // 8 x 8 texels, 9 x 9 directions
  // Extra positional arguments were silently ignored.
  RunResult r = run("compress " + stack + " " + stack + " -o " + path("x.nbtf") + " -q");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "unexpected argument '" + stack + "'")) << r.output;
  EXPECT_FALSE(fs::exists(path("x.nbtf")));
  r = run("info " + stack + " extra");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "unexpected argument 'extra'")) << r.output;
  // A value that does not parse names its option.
  r = run("compress " + stack + " -o " + path("x.nbtf") + " --clusters abc");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "--clusters: invalid value")) << r.output;
  EXPECT_TRUE(contains(r.output, "abc")) << r.output;
  r = run("decode x.nbtf -o out --jpeg-quality=high");
  EXPECT_TRUE(contains(r.output, "--jpeg-quality: invalid value")) << r.output;
  // More threads than cores: a warning, and the cores are used.
  r = run("info " + stack + " --threads 100000");
  EXPECT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "nbtf info: warning: --threads 100000 is more than the")) << r.output;
  // A crop outside the images is a crop error, even when k is also too large for it.
  r = run("compress " + stack + " -o " + path("x.nbtf") + " --crop 20,20,30,30 --clusters 2000 -q");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "crop 20,20,30,30 lies outside the 8 x 8 images")) << r.output;
  // -q is common to every command (query, decode and info rejected or ignored it before).
  for (const char* cmd : {"query", "decode", "info", "eval", "cluster", "compress"}) {
    RunResult h = run(std::string(cmd) + " --help");
    EXPECT_TRUE(contains(h.output, "-q, --quiet")) << cmd << "\n" << h.output;
  }
  // --version and help <command>.
  r = run("--version");
  EXPECT_EQ(r.exitCode, 0);
  EXPECT_TRUE(contains(r.output, "nbtf 0.")) << r.output;
  r = run("help decode");
  EXPECT_EQ(r.exitCode, 0);
  EXPECT_TRUE(contains(r.output, "nbtf decode")) << r.output;
  EXPECT_TRUE(contains(r.output, "--lights")) << r.output;
  EXPECT_EQ(run("help nosuch").exitCode, 2);
}

TEST_F(CmdCompress, InfoJsonAndDirections) {
  std::string stack = writeStack();
  RunResult r = run("info " + stack + " --json -q");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  nlohmann::json j = nlohmann::json::parse(r.output);
  EXPECT_EQ(j["kind"], "stack");
  EXPECT_EQ(j["images"].get<int>(), 81);
  EXPECT_EQ(j["texels"].get<int>(), 64);
  r = run("info " + stack + " --directions");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "lights (9;")) << r.output;
  EXPECT_TRUE(contains(r.output, "decode --lights 0-5")) << r.output;
  r = run("info " + stack + " --directions --json");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  nlohmann::json d = nlohmann::json::parse(r.output);
  ASSERT_EQ(d["lights"].size(), 9u);
  EXPECT_EQ(d["lights"][3]["index"].get<int>(), 3);

  std::string out = path("m.nbtf");
  r = run("compress " + stack + " -o " + out + " --clusters 4 --threads 1 --config " + writeQuickConfig(8));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  // Progress in units a user reads: steps (8 epochs of one step each), k-means finished at 100%.
  EXPECT_TRUE(contains(r.output, "train (steps)")) << r.output;
  EXPECT_TRUE(contains(r.output, "100% 8/8")) << r.output;
  EXPECT_FALSE(contains(r.output, "/1000")) << r.output;
  EXPECT_TRUE(contains(r.output, "converged after")) << r.output;
  EXPECT_FALSE(contains(r.output, "1% ")) << r.output;
  r = run("info " + out + " --json");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  j = nlohmann::json::parse(r.output);
  EXPECT_EQ(j["kind"], "nbtf");
  EXPECT_EQ(j["clusters"].get<int>(), 4);
  EXPECT_EQ(j["bytes"]["file"].get<std::uint64_t>(), fs::file_size(out));
  EXPECT_TRUE(j["metadata"]["source"].contains("fingerprint"));
  r = run("info " + out + " --directions");
  EXPECT_TRUE(contains(r.output, "views (9;")) << r.output;
}

// Outputs: through a symbolic link the target is replaced and the link stays; a device or
// pipe is written in place; missing parent folders are created.
TEST_F(CmdCompress, OutputsThroughLinksDevicesAndNewFolders) {
  std::string stack = writeStack();
  fs::create_directories(path("real"));
  fs::create_symlink(path("real/m.nbtf"), path("link.nbtf"));
  RunResult r = run("compress " + stack + " -o " + path("link.nbtf") + " --clusters 4 --threads 1 -q --config " +
                    writeQuickConfig(3) + " --stats-json /dev/stdout");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(fs::is_symlink(path("link.nbtf")));
  EXPECT_TRUE(fs::is_regular_file(path("real/m.nbtf")));
  EXPECT_TRUE(contains(r.output, "\"rmse_train\"")) << r.output;  // the stats went to stdout
  r = run("compress " + stack + " -o " + path("new/sub/m.nbtf") + " --clusters 4 --threads 1 -q --config " +
          path("quick.json") + " --stats-json /dev/null");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(fs::is_regular_file(path("new/sub/m.nbtf")));
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
}

TEST_F(CmdCompress, PcaMethodOptionsAreChecked) {
  std::string stack = writeStack();  // 8 x 8 texels, 81 images
  std::string out = path("p.nbtf");
  struct Case {
    std::string options, message;
  };
  for (const Case& c : std::vector<Case>{
           {"--method pca", "--method pca needs --components C"},
           {"--method pca --components 0", "--components must be >= 1 with --method pca"},
           {"--method pca --components 65", "--components 65 is more than the PCA baseline allows here: at most 64"},
           {"--method pca --components 4 --epochs 3", "--epochs applies to the neural methods only"},
           {"--method pca --components 4 --clusters 8", "--clusters applies to the neural methods only"},
           {"--method pca --components 4 --save-encoder " + path("e.nbtf"), "--save-encoder applies to the neural"},
           {"--method per-texel --clusters 5", "--method per-texel has one latent per texel"},
           {"--method clustered --clusters 0", "--method clustered needs --clusters k >= 1"},
           {"--method svd", "unknown --method 'svd' (expected clustered, per-texel or pca)"}}) {
    RunResult r = run("compress " + stack + " -o " + out + " -q " + c.options);
    EXPECT_EQ(r.exitCode, 1) << c.options << ": " << r.output;
    EXPECT_TRUE(contains(r.output, c.message)) << c.options << ": " << r.output;
    EXPECT_FALSE(fs::exists(out)) << c.options;
  }
}

TEST_F(CmdCompress, PcaCompressThenInfoEndToEnd) {
  std::string stack = writeStack();
  std::string out = path("p.nbtf"), stats = path("p.json");
  RunResult r = run("compress " + stack + " -o " + out + " --method pca --components 4 --holdout 0.1 --seed 2 " +
                    "--stats-json " + stats + " -q");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "summary: " + out + " (pca, C = 4 components)")) << r.output;
  EXPECT_TRUE(contains(r.output, "held-out images")) << r.output;
  EXPECT_FALSE(fs::exists(out + ".ckpt"));
  CompressedBtf b = readNbtf(out);
  EXPECT_EQ(b.method, CodecMethod::Pca);
  EXPECT_EQ(b.pcaComponents(), 4);
  EXPECT_EQ(b.holdoutImages.size(), 8u);
  nlohmann::json j = nlohmann::json::parse(std::ifstream(stats));
  EXPECT_EQ(j["bytes"]["file"].get<std::uint64_t>(), fs::file_size(out));
  EXPECT_EQ(j["bytes"]["pca_coefficients"].get<std::uint64_t>(), 64u * 4 * 4);
  EXPECT_GT(j["rmse_holdout"].get<double>(), 0);

  RunResult info = run("info " + out);
  EXPECT_EQ(info.exitCode, 0) << info.output;
  for (const char* part : {"format 1.4", "pca (classic baseline), C = 4 components", "coefficients   64 texels x 4",
                           "mean", "basis", "raw float32", "ratio", "kept out of the PCA fit"})
    EXPECT_TRUE(contains(info.output, part)) << part << "\n" << info.output;
  // --json lists the file's own parts (the PCA parts, no neural ones), as Python's sizes does.
  RunResult infoJson = run("info " + out + " --json");
  ASSERT_EQ(infoJson.exitCode, 0) << infoJson.output;
  const nlohmann::json bytes = nlohmann::json::parse(infoJson.output)["bytes"];
  EXPECT_EQ(bytes["pca_coefficients"].get<std::uint64_t>(), 64u * 4 * 4);
  EXPECT_EQ(bytes["pca_components"].get<int>(), 4);
  EXPECT_EQ(bytes["pca_mean"].get<std::uint64_t>() + bytes["pca_basis"].get<std::uint64_t>() + 64u * 4 * 4,
            bytes["total"].get<std::uint64_t>());
  for (const char* neural : {"decoder", "latents", "ids"}) EXPECT_FALSE(bytes.contains(neural)) << neural;

  // The default method is unchanged: --clusters 0 is still the per-texel neural method.
  RunResult perTexel = run("compress " + stack + " -o " + path("t.nbtf") + " --clusters 0 --epochs 1 -q");
  ASSERT_EQ(perTexel.exitCode, 0) << perTexel.output;
  EXPECT_EQ(readNbtf(path("t.nbtf")).method, CodecMethod::PerTexelNeural);
}

TEST_F(CmdCompress, SigintCheckpointsAndWritesNothing) {
  std::string stack = writeStack();
  std::string out = path("int.nbtf");
  const Interrupted run = interruptTraining(stack, out);
  EXPECT_TRUE(WIFEXITED(run.status) && WEXITSTATUS(run.status) == 130) << run.log;
  EXPECT_FALSE(fs::exists(out)) << run.log;
  EXPECT_TRUE(fs::exists(out + ".ckpt"));
  EXPECT_TRUE(contains(run.log, "interrupted; nothing written to " + out)) << run.log;
  EXPECT_TRUE(contains(run.log, "--resume")) << run.log;
}

TEST_F(CmdCompress, ResumeRefusesADamagedCheckpointOrAnotherPlanByName) {
  std::string stack = writeStack();
  std::string out = path("int.nbtf"), ckpt = out + ".ckpt";
  ASSERT_EQ(WEXITSTATUS(interruptTraining(stack, out).status), 130);
  const std::string same = stack + " -o " + out + " --clusters 5 --threads 1 --config " + path("quick.json") + " -q --resume";
  // Another number of steps: the learning-rate schedule would not be the one it was trained on.
  RunResult epochs = run("compress " + same + " --epochs 3");
  EXPECT_EQ(epochs.exitCode, 1) << epochs.output;
  EXPECT_TRUE(contains(epochs.output, ckpt + ": checkpoint of a run planned for")) << epochs.output;
  EXPECT_TRUE(contains(epochs.output, "start over without --resume")) << epochs.output;
  // One flipped byte in the middle: refused at once, by name, before any training.
  std::vector<std::uint8_t> bytes = readFileBytes(ckpt);
  bytes[bytes.size() / 2] ^= 0x10;
  writeFileAtomic(ckpt, bytes.data(), bytes.size());
  RunResult damaged = run("compress " + same);
  EXPECT_EQ(damaged.exitCode, 1) << damaged.output;
  EXPECT_TRUE(contains(damaged.output, ckpt + ": checkpoint is damaged (checksum")) << damaged.output;
  EXPECT_FALSE(contains(damaged.output, "NaN")) << damaged.output;
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(CmdCompress, AnInterruptedRunsCheckpointIsNeitherReplacedNorDeletedUnasked) {
  std::string stack = writeStack();
  std::string out = path("int.nbtf"), ckpt = out + ".ckpt";
  ASSERT_EQ(WEXITSTATUS(interruptTraining(stack, out).status), 130);
  const std::vector<std::uint8_t> saved = readFileBytes(ckpt);
  const std::string same = "compress " + stack + " -o " + out + " --clusters 5 --threads 1 --config " + path("quick.json") + " -q";
  // The same command without --resume: refused, saying how far the run got and the two ways on.
  RunResult again = run(same);
  EXPECT_EQ(again.exitCode, 1) << again.output;
  EXPECT_TRUE(contains(again.output, ckpt + ": an earlier run's training checkpoint (step ")) << again.output;
  EXPECT_TRUE(contains(again.output, "s of training")) << again.output;
  EXPECT_TRUE(contains(again.output, "--resume continues that run, --restart deletes it")) << again.output;
  EXPECT_EQ(readFileBytes(ckpt), saved);
  EXPECT_FALSE(fs::exists(out));
  // Both at once is a contradiction.
  RunResult both = run(same + " --resume --restart");
  EXPECT_EQ(both.exitCode, 1) << both.output;
  EXPECT_TRUE(contains(both.output, "give one of them")) << both.output;
  EXPECT_EQ(readFileBytes(ckpt), saved);
  // --restart deletes it knowingly and trains a new run to the end.
  writeQuickConfig(1);
  RunResult restart = run(same + " --restart");
  EXPECT_EQ(restart.exitCode, 0) << restart.output;
  EXPECT_TRUE(contains(restart.output, "--restart: deleted " + ckpt)) << restart.output;
  EXPECT_TRUE(fs::exists(out));
  EXPECT_FALSE(fs::exists(ckpt));
}

TEST_F(CmdCompress, ADamagedCheckpointIsRefusedBeforeTheStackIsLoaded) {
  std::string stack = writeStack();
  std::string out = path("int.nbtf"), ckpt = out + ".ckpt";
  ASSERT_EQ(WEXITSTATUS(interruptTraining(stack, out).status), 130);
  std::vector<std::uint8_t> bytes = readFileBytes(ckpt);
  bytes[bytes.size() / 2] ^= 0x10;
  writeFileAtomic(ckpt, bytes.data(), bytes.size());
  // The stack is made unreadable too: the checkpoint's error coming first shows that it was
  // judged before the stack was loaded.
  for (const auto& e : fs::recursive_directory_iterator(stack))
    if (e.is_regular_file()) {
      writeFileAtomic(e.path().string(), std::string("not an image"));
      break;
    }
  for (const char* how : {" --resume", ""}) {
    RunResult r = run("compress " + stack + " -o " + out + " --clusters 5 --threads 1 --config " + path("quick.json") + " -q" + how);
    EXPECT_EQ(r.exitCode, 1) << r.output;
    EXPECT_TRUE(contains(r.output, ckpt + ": checkpoint is damaged (checksum")) << r.output;
    EXPECT_TRUE(contains(r.output, "--restart deletes it and starts over")) << r.output;
    EXPECT_EQ(readFileBytes(ckpt), bytes);
  }
}

// Smaller rough edges, each as a new user met it.
TEST_F(CmdCompress, LimitsOverflowsLayoutsAndAdaptiveTargetsAreNamed) {
  std::string stack = writeStack();  // 8 x 8 texels (UTIA names), 9 x 9 directions
  const std::string out = path("x.nbtf");
  RunResult r = run("compress " + stack + " -o " + out + " -q --memory-limit 99999999999999999999");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "--memory-limit")) << r.output;
  EXPECT_TRUE(contains(r.output, "too large")) << r.output;
  // A material too small for the neural methods: refused before loading, with the reason.
  for (const std::string& crop : {std::string("0,0,1,1"), std::string("0,0,2,2"), std::string("0,0,5,3")}) {
    r = run("compress " + stack + " -o " + out + " -q --crop " + crop);
    EXPECT_EQ(r.exitCode, 1) << r.output;
    EXPECT_TRUE(contains(r.output, "texels are too few for the neural methods (at least 16")) << r.output;
    EXPECT_TRUE(contains(r.output, "--method pca")) << r.output;
  }
  EXPECT_FALSE(fs::exists(out));
  r = run("compress " + stack + " -o " + out + " -q --crop 0,0,4294967296,4");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "--crop: 4294967296 in '0,0,4294967296,4' is too large")) << r.output;
  // --max-clusters above the texel count is an error, as --clusters is.
  r = run("compress " + stack + " -o " + out + " -q --clusters 8 --adaptive --max-clusters 65 --epochs 1");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "--max-clusters 65 is larger than the 64 texels")) << r.output;
  // A size budget below the decoder alone is refused before loading; one below the smallest
  // file the run can write is found after the first stage. Neither leaves a checkpoint or
  // adaptive state behind.
  r = run("compress " + stack + " -o " + out + " -q --clusters 8 --adaptive --size-budget 1000 --stages 2 --epochs 2");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "--size-budget 1000 bytes is below the decoder alone")) << r.output;
  // Sizes take units as --memory-limit does (one parser): 1K is 1024 bytes.
  r = run("compress " + stack + " -o " + out + " -q --clusters 8 --adaptive --size-budget 1K --stages 2 --epochs 2");
  EXPECT_TRUE(contains(r.output, "--size-budget 1024 bytes is below the decoder alone")) << r.output;
  r = run("compress " + stack + " -o " + out + " -q --clusters 8 --adaptive --size-budget 36Q --stages 2 --epochs 2");
  EXPECT_TRUE(contains(r.output, "--size-budget: expected a size in bytes")) << r.output;
  EXPECT_FALSE(fs::exists(out + ".ckpt"));
  r = run("compress " + stack + " -o " + out + " -q --clusters 8 --adaptive --size-budget 28400 --stages 2 --epochs 2");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "--size-budget 28400 bytes is below the smallest file")) << r.output;
  EXPECT_FALSE(fs::exists(out + ".ckpt"));
  EXPECT_FALSE(fs::exists(out + ".ckpt.adaptive.json"));
  EXPECT_FALSE(fs::exists(out));
  // An unreachable target says it was missed.
  r = run("compress " + stack + " -o " + out + " --clusters 8 --adaptive --target-rmse 0.000001 --stages 2 --epochs 2 "
          "--stats-json " + path("s.json") + " -q");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "target rmse 1e-06 missed")) << r.output;
  // A layout the names contradict, and a layout given to a .btf file.
  const std::string ubo = path("ubo");
  for (const auto& e : fs::recursive_directory_iterator(stack)) {
    if (!e.is_regular_file()) continue;
    const fs::path rel = fs::relative(e.path(), stack);
    fs::create_directories(fs::path(ubo) / rel.parent_path());
    fs::copy_file(e.path(), fs::path(ubo) / rel.parent_path() / ("00001 " + rel.filename().string()));
  }
  r = run("info " + ubo + " --layout utia");
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "--layout utia: the images are named in the ubo2003 layout")) << r.output;
  // --layout ubo2014 names a .btf file: on a folder it is an error, not "(forced)" and ignored.
  for (const std::string& cmd : {"info " + ubo + " --layout ubo2014", "info " + ubo + " --layout ubo2014 --directions",
                                 "compress " + ubo + " -o " + path("u.nbtf") + " --layout ubo2014 -q"}) {
    r = run(cmd);
    EXPECT_EQ(r.exitCode, 1) << cmd << ": " << r.output;
    EXPECT_TRUE(contains(r.output, "is a folder of images: --layout ubo2014 applies to UBO2014 .btf files only"))
        << cmd << ": " << r.output;
  }
}

TEST_F(CmdCompress, AnOutputThatIsAnInputIsRefusedAndTheInputKept) {
  std::string stack = writeStack();
  const std::string btf = path("in.btf");
  writeFileAtomic(btf, std::string("a measured UBO2014 file, as far as this test is concerned"));
  const std::vector<std::uint8_t> before = readFileBytes(btf);
  fs::create_symlink(btf, path("link.btf"));
  struct Case {
    std::string args, expect;
  };
  const std::string quick = " --clusters 4 --epochs 1 -q";
  const std::vector<Case> cases = {
      {btf + " -o " + btf + quick, "-o '" + btf + "' is the same file as the input"},
      {btf + " -o " + path("link.btf") + quick, "is the same file as the input"},
      {btf + " -o " + path("x/../in.btf") + quick, "is the same file as the input"},
      {btf + " -o " + path("a.nbtf") + " --stats-json " + btf + quick, "--stats-json '" + btf + "' is the same file"},
      {stack + " -o " + path("a.nbtf") + " --stats-json " + path("a.nbtf") + quick, "are the same file"},
      {btf + " -o " + path("a.nbtf") + " --save-encoder " + btf + quick, "--save-encoder '" + btf + "' is the same"},
      {stack + " -o " + stack + quick, "is the same folder as the input"},
      {btf + ".ckpt -o " + btf + quick, "the checkpoint '" + btf + ".ckpt' is the same file as the input"},
  };
  for (const Case& c : cases) {
    RunResult r = run("compress " + c.args);
    EXPECT_EQ(r.exitCode, 1) << c.args << "\n" << r.output;
    EXPECT_TRUE(contains(r.output, c.expect)) << c.args << "\n" << r.output;
  }
  EXPECT_EQ(readFileBytes(btf), before);
  EXPECT_FALSE(fs::exists(path("a.nbtf")));
}

TEST_F(CmdCompress, InfoRejectsDamagedFiles) {
  std::vector<std::uint8_t> bytes(100, 0);
  writeFileAtomic(path("zero.nbtf"), bytes.data(), bytes.size());
  RunResult r = run("info " + path("zero.nbtf"));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "zero.nbtf: not an .nbtf file")) << r.output;
  std::vector<std::uint8_t> head(kNbtfMagic, kNbtfMagic + 8);
  writeFileAtomic(path("cut.nbtf"), head.data(), head.size());
  r = run("info " + path("cut.nbtf"));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_TRUE(contains(r.output, "cut.nbtf: truncated")) << r.output;
}

// --adaptive: the summary and the stats record the stages, --size-budget holds for the written
// file, the same seed gives the same file, and the targets need --adaptive.
TEST_F(CmdCompress, AdaptiveStagesBudgetAndSameSeed) {
  const std::string stack = writeStack();
  const std::string common = " --adaptive --clusters 8 --initial-clusters 3 --stages 3 --seed 2 --threads 1 --config " +
                             writeQuickConfig(60) + " -q";
  const std::string free = path("free.nbtf"), stats = path("free.json");
  RunResult r = run("compress " + stack + " -o " + free + common + " --max-clusters 12 --stats-json " + stats);
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "adaptive: 3 stages, k 3 -> ")) << r.output;
  EXPECT_FALSE(fs::exists(free + ".ckpt"));
  nlohmann::json j = nlohmann::json::parse(std::ifstream(stats));
  ASSERT_EQ(j["adaptive"]["stages"].size(), 3u);
  EXPECT_EQ(j["adaptive"]["stages"][2]["bytes"].get<std::uint64_t>(), fs::file_size(free));
  EXPECT_EQ(j["bytes"]["file"].get<std::uint64_t>(), fs::file_size(free));
  const int k = j["clusters"].get<int>();
  EXPECT_GT(k, 3);
  EXPECT_LE(k, 12);
  RunResult info = run("info " + free);
  EXPECT_TRUE(contains(info.output, "k = " + std::to_string(k) + " clusters")) << info.output;

  const std::uint64_t budget = fs::file_size(free) - 50;
  const std::string a = path("a.nbtf"), b = path("b.nbtf");
  for (const std::string& out : {a, b}) {
    r = run("compress " + stack + " -o " + out + common + " --size-budget " + std::to_string(budget));
    ASSERT_EQ(r.exitCode, 0) << r.output;
    EXPECT_LE(fs::file_size(out), budget);
  }
  EXPECT_EQ(readFileBytes(a), readFileBytes(b));

  // The same run from a config file's "adaptive" object: the same bytes.
  nlohmann::json config = nlohmann::json::parse(std::ifstream(writeQuickConfig(60)));
  config["adaptive"] = {{"enabled", true}, {"initial_clusters", 3}, {"stages", 3}};
  writeFileAtomic(path("adaptive.json"), config.dump());
  const std::string fromConfig = path("config.nbtf");
  r = run("compress " + stack + " -o " + fromConfig + " --clusters 8 --seed 2 --threads 1 --max-clusters 12 --config " +
          path("adaptive.json") + " -q");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(readFileBytes(fromConfig), readFileBytes(free));
  EXPECT_EQ(nlohmann::json::parse(readNbtf(fromConfig).metadataJson)["adaptive"]["config"]["max_clusters"], 12);
  config["adaptive"]["stages"] = 30;
  writeFileAtomic(path("adaptive.json"), config.dump());
  r = run("compress " + stack + " -o " + path("bad.nbtf") + " --config " + path("adaptive.json") + " -q");
  EXPECT_NE(r.exitCode, 0);
  EXPECT_TRUE(contains(r.output, "adaptive.json: 'adaptive.stages' (--stages) must be in 1..20, got 30")) << r.output;

  for (const std::string& bad : {std::string(" --target-rmse 0.1"), std::string(" --max-clusters 9"),
                                 std::string(" --adaptive --method pca --components 3"),
                                 std::string(" --adaptive --stages 21"), std::string(" --adaptive --size-budget 0"),
                                 std::string(" --adaptive --clusters 0")}) {
    r = run("compress " + stack + " -o " + path("bad.nbtf") + bad + " -q");
    EXPECT_NE(r.exitCode, 0) << bad << ": " << r.output;
  }
  EXPECT_TRUE(contains(run("compress " + stack + " -o " + path("bad.nbtf") + " --target-rmse 0.1 -q").output,
                       "--target-rmse needs --adaptive"));
}


// --size-budget without --adaptive: the named config the budget reaches and the largest k that
// fits, said in the summary and the stats; the file never above the budget; the options that
// contradict it refused before loading.
TEST_F(CmdCompress, SizeBudgetChoosesTheConfigAndTheClusters) {
  const std::string stack = writeStack();  // 8 x 8 texels
  const std::string out = path("b.nbtf"), stats = path("b.json");
  const std::string quick = " --epochs 1 --seed 1 --threads 1 -q --stats-json " + stats;
  // Above every point: high_fidelity at one cluster per 2.5 texels, round(64 / 2.5) = 26.
  RunResult r = run("compress " + stack + " -o " + out + " --size-budget 10M" + quick);
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "(clustered-neural, k = 26: one cluster per 2.5 texels, the densest point, smaller "
                                 "than --size-budget, in high_fidelity's recipe, the named config the budget reaches)"))
      << r.output;
  nlohmann::json j = nlohmann::json::parse(std::ifstream(stats));
  EXPECT_EQ(j["size_budget"]["config"], "high_fidelity");
  EXPECT_TRUE(j["size_budget"]["at_densest"].get<bool>());
  EXPECT_EQ(nlohmann::json::parse(readNbtf(out).metadataJson)["config_name"], "high_fidelity");
  // Budgets below the densest file: the most clusters that fit, in the recipe the budget reaches.
  const std::uint64_t densest = fs::file_size(out);
  for (std::uint64_t budget : {densest - 4096, std::uint64_t(40000)}) {
    r = run("compress " + stack + " -o " + out + " --size-budget " + std::to_string(budget) + quick);
    ASSERT_EQ(r.exitCode, 0) << r.output;
    j = nlohmann::json::parse(std::ifstream(stats));
    EXPECT_LE(fs::file_size(out), budget);
    EXPECT_EQ(j["size_budget"]["bytes"].get<std::uint64_t>(), budget);
    EXPECT_LE(j["size_budget"]["estimate_bytes"].get<std::uint64_t>(), budget);
    EXPECT_GE(j["size_budget"]["estimate_bytes"].get<std::uint64_t>(), fs::file_size(out));
    EXPECT_FALSE(j["size_budget"]["at_densest"].get<bool>());
    EXPECT_TRUE(contains(r.output, "the most that fit --size-budget, in " + j["size_budget"]["config"].get<std::string>() +
                                   "'s recipe"))
        << r.output;
    EXPECT_TRUE(contains(r.output, "  size budget  ")) << r.output;
  }
  // A config given: its recipe; PCA: the components.
  r = run("compress " + stack + " -o " + out + " --config balanced --size-budget 10M" + quick);
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(nlohmann::json::parse(std::ifstream(stats))["size_budget"]["config"].is_null());
  EXPECT_EQ(nlohmann::json::parse(readNbtf(out).metadataJson)["config_name"], "balanced");
  EXPECT_EQ(readNbtf(out).numClusters(), 26);
  r = run("compress " + stack + " -o " + out + " --method pca --size-budget 30K -q");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "components: the most that fit --size-budget")) << r.output;
  EXPECT_LE(fs::file_size(out), 30u * 1024);
  fs::remove(out);
  // Refused before loading, nothing written.
  const std::pair<std::string, std::string> refused[] = {
      {" --size-budget 100K --clusters 5", "give --clusters or --size-budget, not both"},
      {" --size-budget 100K --method per-texel", "--method per-texel has one latent per texel and nothing to choose"},
      {" --size-budget 100K --method pca --components 3", "give --components or --size-budget, not both"},
      {" --size-budget 0", "--size-budget: expected a size in bytes"},
      {" --size-budget 2000", "--size-budget 2000 bytes is below the smallest file of this input: compact's recipe "
                              "with one cluster is up to"},
      {" --size-budget 2000 --method pca", "--size-budget 2000 bytes is below the smallest PCA file of this input"}};
  for (const auto& [options, message] : refused) {
    r = run("compress " + stack + " -o " + out + options + " -q");
    EXPECT_EQ(r.exitCode, 1) << options << ": " << r.output;
    EXPECT_TRUE(contains(r.output, message)) << options << ": " << r.output;
    EXPECT_FALSE(fs::exists(out)) << options;
    EXPECT_FALSE(fs::exists(out + ".ckpt")) << options;
  }
}

}  // namespace
}  // namespace nbtf
