// Data-parallel training (model/distributed/distributed.h): the tile shares, the settings check, and
// `nbtf compress` processes on the loopback interface: two against one process with the same
// global batch, mismatched ranks, a lone rank.
#include "model/distributed/distributed.h"

#include <arpa/inet.h>
#include <ifaddrs.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "codec_fixtures.h"
#include "socket_fixtures.h"
#include "model/distributed/rendezvous_store.h"
#include "test_util.h"
#include "util/atomic_file.h"
#include "util/error.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;
using test::freePort;
using test::listenOn;

TEST(Distributed, TileSharesCoverEveryTileOnceAndEvenly) {
  for (int tiles : {2, 7, 32})
    for (int world : {1, 2, 3}) {
      if (world > tiles) continue;
      int next = 0;
      for (int r = 0; r < world; ++r) {
        int b = 0, e = 0;
        tileShare(tiles, r, world, b, e);
        EXPECT_EQ(b, next) << tiles << " tiles, rank " << r << " of " << world;
        EXPECT_GE(e - b, tiles / world);
        EXPECT_LE(e - b, tiles / world + 1);
        next = e;
      }
      EXPECT_EQ(next, tiles);
    }
}

TEST(Distributed, BadSettingsAreNamed) {
  DistributedConfig c;
  c.worldSize = 2, c.rank = 2, c.master = "127.0.0.1:29500";
  test::expectErrorContaining([&] { validateDistributedConfig(c); }, {"--rank 2", "0..1"});
  c.rank = 1, c.master = "127.0.0.1";
  test::expectErrorContaining([&] { validateDistributedConfig(c); }, {"--master", "HOST:PORT"});
  c.master = "127.0.0.1:99999";
  test::expectErrorContaining([&] { validateDistributedConfig(c); }, {"port 99999"});
  c.master = "127.0.0.1:29500", c.timeoutSeconds = 0;
  test::expectErrorContaining([&] { validateDistributedConfig(c); }, {"--dist-timeout"});
}

using test::RunResult;
RunResult run(const std::string& args) { return test::runNbtf(args); }

// `nbtf ARGS` under `timeout 60`: a run that hangs ends with 124, a crash with 128 + signal,
// so the exit code tells a clear error (1) from both without timing anything.
RunResult runBounded(const std::string& args) {
  RunResult r;
  const std::string cmd = "timeout 60 " + std::string(NBTF_BIN_DIR) + "/nbtf " + args + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  std::size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  const int status = pclose(p);
  r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

TEST(Distributed, TheFirstSettingThatDiffersIsNamed) {
  const std::vector<std::pair<std::string, std::string>> zero{{"--clusters", "8"}, {"--seed", "1"}};
  EXPECT_EQ(distributedMismatch(zero, zero, 1), "");
  EXPECT_EQ(distributedMismatch(zero, {{"--clusters", "8"}, {"--seed", "2"}}, 1),
            "--seed differs: rank 0 has 1, rank 1 has 2");
  EXPECT_EQ(distributedMismatch(zero, {{"--clusters", "16"}, {"--seed", "2"}}, 3),
            "--clusters differs: rank 0 has 8, rank 3 has 16");
  EXPECT_NE(distributedMismatch(zero, {{"--clusters", "8"}}, 1).find("--seed"), std::string::npos);
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

constexpr const char* kSecret = " --dist-secret test-secret";

class DistributedCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("nbtf_distributed_" +
                                        std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) +
                                        "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    stack_ = testing::writeTestStack(path("stack"));
    // The test recipe: 16 encoder inputs x 64 images per step, split 8 + 8 over two ranks.
    // Float products: with bfloat16 operands a last-bit difference (the ranks' gradients are
    // summed in another order) now and then flips a weight's rounding, and the runs drift
    // apart as two seeds do (measured: 0.8% of the RMSE here), hiding what this test checks.
    writeFileAtomic(path("quick.json"),
                    R"({"optimizer": {"name": "adam", "learning_rate": 0.003}, "training": {"batch_size": 1024,)"
                    R"( "images_per_input": 64, "min_steps": 0, "max_steps": 0, "epochs": 60, "products": "float"}})");
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string common(const std::string& stack = "", int seed = 3) const {
    return (stack.empty() ? stack_ : stack) + " --clusters 4 --config " + path("quick.json") + " --seed " +
           std::to_string(seed) + " --threads 1 -q";
  }
  // Starts rank 1 (`args`: its input and options) in the background; its output goes to
  // rank1.log, its exit code to rank1.rc; returns its pid (the nbtf process itself, so that a
  // test can kill it; waitFor bounds the wait).
  // Every rank is given rank 0's -o (two.nbtf) unless `output` says otherwise.
  pid_t startRank1(int port, const std::string& extra = "", const std::string& args = "",
                   const std::string& output = "two.nbtf") {
    std::string cmd = "( " + std::string(NBTF_BIN_DIR) + "/nbtf compress " + (args.empty() ? common() : args) +
                      " -o " + path(output) + " --world-size 2 --rank 1 --master 127.0.0.1:" +
                      std::to_string(port) + " " + extra + " > " + path("rank1.log") + " 2>&1 & echo $! > " +
                      path("rank1.pid") + "; wait $!; echo $? > " + path("rank1.rc") + " ) > /dev/null 2>&1 &";
    if (std::system(cmd.c_str()) != 0) return -1;
    for (int i = 0; i < 100 && slurp(path("rank1.pid")).empty(); ++i) usleep(20000);
    const std::string pid = slurp(path("rank1.pid"));
    return pid.empty() ? -1 : std::stoi(pid);
  }
  // Waits for rank 1 and returns its exit code (-1 when it has none yet).
  int waitFor(pid_t pid) {
    for (int i = 0; i < 900 && kill(pid, 0) == 0; ++i) usleep(100000);
    for (int i = 0; i < 50 && slurp(path("rank1.rc")).empty(); ++i) usleep(100000);
    const std::string rc = slurp(path("rank1.rc"));
    return rc.empty() ? -1 : std::stoi(rc);
  }
  // Rank 1 runs `rank1Args` (its input and options) writing `rank1Output`, rank 0 runs
  // `rank0Args` writing two.nbtf: both must stop at the rendezvous (exit 1, neither file
  // written), each saying `expected`.
  void expectBothStopSaying(const std::string& rank1Args, const std::string& rank1Output, const std::string& rank0Args,
                            const std::string& expected) {
    const int port = freePort();
    pid_t rank1 = startRank1(port, kSecret + std::string(" --dist-timeout 30"), rank1Args, rank1Output);
    ASSERT_GT(rank1, 0);
    RunResult r = runBounded("compress " + rank0Args + " -o " + path("two.nbtf") +
                             " --world-size 2 --rank 0 --dist-timeout 30 --master 127.0.0.1:" + std::to_string(port) +
                             kSecret);
    const int rc1 = waitFor(rank1);
    const std::string log1 = slurp(path("rank1.log"));
    EXPECT_EQ(r.exitCode, 1) << r.output;
    EXPECT_EQ(rc1, 1) << "134 is SIGABRT\n" << log1;
    EXPECT_NE(r.output.find(expected), std::string::npos) << r.output;
    EXPECT_NE(log1.find(expected), std::string::npos) << log1;
    EXPECT_FALSE(fs::exists(path("two.nbtf")));
    EXPECT_FALSE(fs::exists(path(rank1Output)));
  }

  fs::path dir_;
  std::string stack_;
};

TEST_F(DistributedCli, TwoProcessesMatchOneWithTheSameGlobalBatch) {
  RunResult one = run("compress " + common() + " -o " + path("one.nbtf") + " --stats-json " + path("one.json"));
  ASSERT_EQ(one.exitCode, 0) << one.output;
  const int port = freePort();
  pid_t rank1 = startRank1(port, kSecret);
  ASSERT_GT(rank1, 0);
  RunResult two = run("compress " + common() + " -o " + path("two.nbtf") + " --stats-json " + path("two.json") +
                      " --world-size 2 --rank 0 --master 127.0.0.1:" + std::to_string(port) + kSecret);
  waitFor(rank1);
  ASSERT_EQ(two.exitCode, 0) << two.output << "\nrank 1:\n" << slurp(path("rank1.log"));
  EXPECT_NE(two.output.find("data-parallel: 2 processes"), std::string::npos) << two.output;
  // libtorch's logging (glog) is initialized quietly: none of its lines reach the user.
  for (const std::string& text : {two.output, slurp(path("rank1.log"))}) {
    EXPECT_EQ(text.find("InitGoogleLogging"), std::string::npos) << text;
    EXPECT_EQ(text.find("frame #"), std::string::npos) << text;
  }
  EXPECT_NE(slurp(path("rank1.log")).find("rank 1 of 2: trained its share"), std::string::npos)
      << slurp(path("rank1.log"));
  EXPECT_NE(slurp(path("rank1.log")).find("rank 0 writes " + path("two.nbtf")), std::string::npos)
      << slurp(path("rank1.log"));
  auto a = nlohmann::json::parse(slurp(path("one.json"))), b = nlohmann::json::parse(slurp(path("two.json")));
  EXPECT_EQ(a["steps"], b["steps"]);
  // The same steps over the same samples and the same encoder batches; the gradients are summed
  // in another order, so not bit for bit: the stated tolerance is 0.1% of the RMSE (measured:
  // 4e-6 relative).
  const double ra = a["rmse_train"], rb = b["rmse_train"];
  EXPECT_NEAR(rb, ra, 1e-3 * ra) << "one process " << ra << ", two " << rb;
  // Every step sends the whole gradient: encoder + decoder parameters as float32.
  EXPECT_GT(b["all_reduce_bytes_per_step"].get<double>(), 24383 * 4.0);
}

TEST_F(DistributedCli, ALoneRankStopsAtItsTimeoutWithOneLine) {
  // No secret given: rank 0 generates one and says how to pass it on.
  RunResult r = runBounded("compress " + common() + " -o " + path("alone.nbtf") +
                           " --world-size 2 --rank 0 --dist-timeout 3 --master 127.0.0.1:" + std::to_string(freePort()));
  EXPECT_EQ(r.exitCode, 1) << "124: it waited past `timeout 60`; 128 + N: it crashed\n" << r.output;
  EXPECT_NE(r.output.find("NBTF_DIST_SECRET="), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("rank 0 of 2"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("rendezvous failed: rank 1 did not join within 3 s"), std::string::npos) << r.output;
  // One line: no C++ backtrace of libtorch's.
  EXPECT_EQ(r.output.find("frame #"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("Exception raised from"), std::string::npos) << r.output;
  const auto error = r.output.find("error: ");
  ASSERT_NE(error, std::string::npos) << r.output;
  EXPECT_EQ(r.output.find('\n', error) + 1, r.output.size()) << "the error is not the last line:\n" << r.output;
  EXPECT_FALSE(fs::exists(path("alone.nbtf")));
}

TEST_F(DistributedCli, AWorkerWithoutTheSecretIsToldHowToGetIt) {
  RunResult r = runBounded("compress " + common() + " -o " + path("w.nbtf") +
                           " --world-size 2 --rank 1 --master 127.0.0.1:" + std::to_string(freePort()));
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("--dist-secret"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("NBTF_DIST_SECRET"), std::string::npos) << r.output;
}

TEST_F(DistributedCli, APortInUseIsReportedAtOnce) {
  const int port = freePort();
  const int busy = listenOn(port);
  ASSERT_GE(busy, 0);
  // --dist-timeout above `timeout 60`: only an immediate failure exits 1.
  RunResult r = runBounded("compress " + common() + " -o " + path("p.nbtf") +
                           " --world-size 2 --rank 0 --dist-timeout 100 --master 127.0.0.1:" + std::to_string(port) +
                           kSecret);
  close(busy);
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("port " + std::to_string(port) + " on 127.0.0.1 is already in use"), std::string::npos)
      << r.output;
}

TEST_F(DistributedCli, RanksWithDifferentSeedsBothStopNamingTheSeed) {
  expectBothStopSaying(common("", 2), "two.nbtf", common("", 1), "--seed differs: rank 0 has 1, rank 1 has 2");
}

TEST_F(DistributedCli, RanksWritingDifferentFilesStop) {
  // Only rank 0 writes: a rank given another -o would believe its path written.
  expectBothStopSaying(common(), "rank1.nbtf", common(),
                       "-o differs: rank 0 has " + path("two.nbtf") + ", rank 1 has " + path("rank1.nbtf"));
}

TEST_F(DistributedCli, RanksOnDifferentMaterialsStopWithAnErrorNotACrash) {
  // Another material: 8 x 6 texels instead of 8 x 8 (the collectives' buffers would differ).
  const std::string other = path("other");
  {
    testing::TestMaterial m = testing::makeTestMaterial(8, 6);
    std::vector<float> rgb(static_cast<std::size_t>(m.stack.numTexels()) * 3);
    for (int l = 0; l < m.stack.numLights(); ++l)
      for (int v = 0; v < m.stack.numViews(); ++v) {
        const fs::path folder = fs::path(other) / viewFolderName(m.stack.views()[v]);
        fs::create_directories(folder);
        m.stack.imageLinear(m.stack.imageIndex(l, v), rgb.data());
        writeExr((folder / utiaFileName(m.stack.lights()[l], m.stack.views()[v], ".exr")).string(), m.stack.width(),
                 m.stack.height(), rgb.data(), false);
      }
  }
  expectBothStopSaying(common(other), "two.nbtf", common(),
                       "source size (width x height, lights x views) differs: rank 0 has 8x8");
}

TEST_F(DistributedCli, AKilledWorkerStopsTheOthersWithAnError) {
  // Long enough that rank 1 is killed while both train.
  writeFileAtomic(path("quick.json"),
                  R"({"optimizer": {"name": "adam", "learning_rate": 0.003}, "training": {"batch_size": 1024,)"
                  R"( "images_per_input": 64, "min_steps": 0, "max_steps": 0, "epochs": 100000}})");
  const int port = freePort();
  pid_t rank1 = startRank1(port, kSecret);
  ASSERT_GT(rank1, 0);
  std::thread killer([&] {
    // Once rank 1 has been training a moment (its log is silent with -q), stop it hard.
    sleep(8);
    kill(rank1, SIGKILL);
  });
  RunResult r = runBounded("compress " + common() + " -o " + path("two.nbtf") +
                           " --world-size 2 --rank 0 --dist-timeout 10 --master 127.0.0.1:" + std::to_string(port) +
                           kSecret);
  killer.join();
  EXPECT_EQ(r.exitCode, 1) << "124: it waited past `timeout 60`\n" << r.output;
  EXPECT_NE(r.output.find("distributed training (rank 0 of 2"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("InitGoogleLogging"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(path("two.nbtf")));
}

}  // namespace
}  // namespace nbtf
