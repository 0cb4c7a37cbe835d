// Data-parallel training (model/distributed.h): the tile shares, and two `nbtf compress`
// processes on the loopback interface against one process with the same global batch.
#include "model/distributed.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "codec_fixtures.h"
#include "test_util.h"
#include "util/atomic_file.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;

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

// A port on the loopback interface that was free a moment ago.
int freePort() {
  int s = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = 0;
  bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t n = sizeof a;
  getsockname(s, reinterpret_cast<sockaddr*>(&a), &n);
  close(s);
  return ntohs(a.sin_port);
}

using test::RunResult;
RunResult run(const std::string& args) { return test::runNbtf(args); }

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

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
    writeFileAtomic(path("quick.json"),
                    R"({"optimizer": {"name": "adam", "learning_rate": 0.003}, "training": {"batch_size": 1024,)"
                    R"( "images_per_input": 64, "min_steps": 0, "max_steps": 0, "epochs": 60}})");
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string common() const {
    return stack_ + " --clusters 4 --config " + path("quick.json") + " --seed 3 --threads 1 -q";
  }
  // Starts rank 1 in the background; its output goes to rank1.log, its pid is returned.
  pid_t startRank1(int port, const std::string& extra = "") {
    std::string cmd = std::string(NBTF_BIN_DIR) + "/nbtf compress " + common() + " -o " + path("rank1.nbtf") +
                      " --world-size 2 --rank 1 --master 127.0.0.1:" + std::to_string(port) + " " + extra + " > " +
                      path("rank1.log") + " 2>&1 & echo $!";
    FILE* p = popen(cmd.c_str(), "r");
    int pid = -1;
    if (p) {
      if (std::fscanf(p, "%d", &pid) != 1) pid = -1;
      pclose(p);
    }
    return pid;
  }
  void waitFor(pid_t pid) {
    for (int i = 0; i < 600 && kill(pid, 0) == 0; ++i) usleep(100000);
  }
  fs::path dir_;
  std::string stack_;
};

TEST_F(DistributedCli, TwoProcessesMatchOneWithTheSameGlobalBatch) {
  RunResult one = run("compress " + common() + " -o " + path("one.nbtf") + " --stats-json " + path("one.json"));
  ASSERT_EQ(one.exitCode, 0) << one.output;
  const int port = freePort();
  pid_t rank1 = startRank1(port);
  ASSERT_GT(rank1, 0);
  RunResult two = run("compress " + common() + " -o " + path("two.nbtf") + " --stats-json " + path("two.json") +
                      " --world-size 2 --rank 0 --master 127.0.0.1:" + std::to_string(port));
  waitFor(rank1);
  ASSERT_EQ(two.exitCode, 0) << two.output << "\nrank 1:\n" << slurp(path("rank1.log"));
  EXPECT_NE(two.output.find("data-parallel: 2 processes"), std::string::npos) << two.output;
  EXPECT_NE(slurp(path("rank1.log")).find("rank 1 of 2: trained its share"), std::string::npos)
      << slurp(path("rank1.log"));
  EXPECT_FALSE(fs::exists(path("rank1.nbtf"))) << "only rank 0 writes the file";
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

TEST_F(DistributedCli, AMissingPeerIsAnErrorNotAHang) {
  RunResult r = run("compress " + common() + " -o " + path("alone.nbtf") +
                    " --world-size 2 --rank 0 --dist-timeout 5 --master 127.0.0.1:" + std::to_string(freePort()));
  EXPECT_NE(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("rank 0 of 2"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("rendezvous failed"), std::string::npos) << r.output;
  EXPECT_LT(r.seconds, 60) << r.output;
  EXPECT_FALSE(fs::exists(path("alone.nbtf")));
}

TEST_F(DistributedCli, AKilledWorkerStopsTheOthersWithAnError) {
  // Long enough that rank 1 is killed while both train.
  writeFileAtomic(path("quick.json"),
                  R"({"optimizer": {"name": "adam", "learning_rate": 0.003}, "training": {"batch_size": 1024,)"
                  R"( "images_per_input": 64, "min_steps": 0, "max_steps": 0, "epochs": 100000}})");
  const int port = freePort();
  pid_t rank1 = startRank1(port);
  ASSERT_GT(rank1, 0);
  std::thread killer([&] {
    // Once rank 1 has been training a moment (its log is silent with -q), stop it hard.
    sleep(8);
    kill(rank1, SIGKILL);
  });
  RunResult r = run("compress " + common() + " -o " + path("two.nbtf") +
                    " --world-size 2 --rank 0 --dist-timeout 10 --master 127.0.0.1:" + std::to_string(port));
  killer.join();
  EXPECT_NE(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("distributed training (rank 0 of 2"), std::string::npos) << r.output;
  EXPECT_LT(r.seconds, 60) << r.output;
  EXPECT_FALSE(fs::exists(path("two.nbtf")));
}

}  // namespace
}  // namespace nbtf
