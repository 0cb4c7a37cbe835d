// nbtf-bench-train (scripts/bench_train.sh): every part runs on a tiny material and prints the
// figures the script reads, for every direction encoding, so a change to the model cannot
// silently break the benchmark. Counts and values only; the timings are the benchmark's.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "codec_fixtures.h"
#include "test_util.h"
#include "util/atomic_file.h"
#include "util/directions.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;

bool hasFigure(const std::string& output, const std::string& key) {
  return output.find("\n" + key + " ") != std::string::npos || output.rfind(key + " ", 0) == 0;
}

TEST(BenchTrain, EveryPartRunsForEveryDirectionEncoding) {
  test::TempDir dir;
  const std::string stack = testing::writeTestStack(dir / "stack");
  for (DirectionEncoding encoding : directionEncodings()) {
    const std::string name = directionEncodingName(encoding);
    const std::string config = dir / ("config_" + std::to_string(static_cast<int>(encoding)) + ".json");
    writeFileAtomic(config, R"({"model": {"direction_inputs": ")" + name +
                                R"("}, "training": {"batch_size": 256, "images_per_input": 32, "epochs": 1,)"
                                R"( "min_steps": 0, "max_steps": 0}})");
    const test::RunResult r = test::runProgram(
        "nbtf-bench-train",
        "--threads 1 --matmul -n 32 --decoder-only --steps 2 --throughput --size 8 --directions 9 --seconds 0.5 "
        "--clusters 4 --converge '" + stack + "' --long-factor 1 --config '" + config + "'");
    ASSERT_EQ(r.exitCode, 0) << name << "\n" << r.output;
    for (const char* key : {"matmul_gflops", "decoder_only_gflops", "decoder_only_samples_per_second",
                            "throughput_decoder_gflops", "throughput_samples_per_second", "converge_seconds",
                            "converge_rmse_train", "long_rmse_train", "reference_rmse_cluster_mean"})
      EXPECT_TRUE(hasFigure(r.output, key)) << name << ": no '" << key << "' in\n" << r.output;
    EXPECT_EQ(r.output.find("frame #"), std::string::npos) << r.output;
  }
}

TEST(BenchTrain, AnErrorIsOneLine) {
  const test::RunResult r = test::runProgram("nbtf-bench-train", "--converge /nonexistent/stack --clusters 4");
  EXPECT_EQ(r.exitCode, 1) << r.output;
  EXPECT_NE(r.output.find("nbtf-bench-train: error: /nonexistent/stack"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("frame #"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace nbtf
