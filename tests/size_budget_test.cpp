// --size-budget without --adaptive (pipeline/size_budget.h): the estimate before loading bounds
// the written file from above and stays near it; the choice of recipe and k on the named
// configs' curve; the budgets no file can meet.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <tuple>
#include <utility>

#include "codec_fixtures.h"
#include "pipeline/compress_config.h"
#include "pipeline/size_budget.h"
#include "util/error.h"

namespace nbtf {
namespace {
namespace fs = std::filesystem;

// A named config's options as `nbtf compress --config NAME --epochs 1 --threads 1 -q` makes them.
CompressOptions namedOptions(const std::string& name) {
  const CompressConfig c = loadCompressConfig(name);
  CompressOptions o;
  o.train = c.train;
  o.train.builtInConfig = name;
  o.train.epochs = 1;
  o.train.minSteps = o.train.minStepsPerInput = o.train.maxSteps = 0;
  o.train.threads = 1;
  o.train.progress = false;
  o.clusters = c.clusters;
  o.clustersAreDefault = true;
  o.texelsPerCluster = c.texelsPerCluster;
  o.clusteringSpace = c.clusteringSpace;
  o.progress = false;
  return o;
}

class SizeBudget : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("nbtf_size_budget_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    stack_ = testing::writeTestStack((dir_ / "stack").string());  // 8 x 8 texels, 81 images
    input_ = resolveBtfInput(stack_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::uint64_t writtenBytes(const CompressOptions& o) {
    const std::string out = (dir_ / "out.nbtf").string();
    return compressBtf(stack_, out, o).sizes.fileBytes;
  }
  fs::path dir_;
  std::string stack_;
  BtfInput input_;
};

TEST_F(SizeBudget, TheEstimateBoundsTheWrittenFileFromAboveAndStaysNearIt) {
  for (const std::string name : {"default", "balanced", "high_fidelity", "paper-clustered"})
    for (int k : {1, 7, 26}) {
      CompressOptions o = namedOptions(name);
      const std::uint64_t estimate = estimatedFileBytes(input_, o, k);
      o.clusters = k;
      o.clustersAreDefault = false;
      o.texelsPerCluster = 0;
      const std::uint64_t written = writtenBytes(o);
      EXPECT_GE(estimate, written) << name << ", k = " << k;
      // The metadata allowance (4 KiB) and the random ids and codes' excess at 64 texels.
      EXPECT_LT(estimate, written + 6144) << name << ", k = " << k;
    }
  CompressOptions pca = namedOptions("default");
  pca.pcaBaseline = true;
  pca.clustersAreDefault = false;
  for (int c : {1, 4}) {
    pca.pcaComponents = c;
    const std::uint64_t estimate = estimatedFileBytes(input_, pca, c), written = writtenBytes(pca);
    EXPECT_GE(estimate, written) << "PCA, C = " << c;
    EXPECT_LT(estimate, written + 6144) << "PCA, C = " << c;
  }
}

// The curve: the largest named config whose takeover point fits, then the largest k in it.
TEST_F(SizeBudget, TheBudgetChoosesTheRecipeAndTheLargestClusterCountThatFits) {
  // Own points at k = 6 of 64 texels here; the takeovers at 6, 12 and 18 clusters.
  auto curveOptions = [] {
    CompressOptions o = namedOptions("default");
    const std::pair<const char*, int> curve[] = {{"default", 1}, {"balanced", 2}, {"high_fidelity", 3}};
    for (const auto& [name, takeover] : curve) {
      o.sizeBudgetCurve.push_back(namedOptions(name));
      o.sizeBudgetCurve.back().sizeBudgetTakeover = takeover;
    }
    return o;
  };
  struct Case {
    std::string config;
    int k;
  };
  // Budgets just at a recipe's file for k: that recipe (its takeover point fits; the next one's
  // does not) and exactly that k.
  for (const Case& c : {Case{"default", 9}, Case{"balanced", 14}, Case{"high_fidelity", 25}}) {
    CompressOptions o = curveOptions();
    o.sizeBudget = estimatedFileBytes(input_, namedOptions(c.config), c.k);
    CompressStats stats;
    chooseSizeBudgetPoint(input_, o, stats);
    EXPECT_EQ(stats.sizeBudgetConfig, c.config);
    EXPECT_EQ(o.train.builtInConfig, c.config);
    EXPECT_EQ(o.clusters, c.k) << c.config;
    EXPECT_FALSE(o.clustersAreDefault);
    EXPECT_LE(stats.sizeBudgetEstimate, o.sizeBudget);
    EXPECT_FALSE(stats.sizeBudgetAtDensest);
    EXPECT_TRUE(o.sizeBudgetCurve.empty());
  }
  // A richer recipe's own point fits but not its takeover point: the plainer one, with more
  // clusters than the richer one would have had.
  for (const auto& [budgetConfig, budgetK, config] :
       {std::tuple<std::string, int, std::string>{"balanced", 10, "default"}, {"high_fidelity", 16, "balanced"}}) {
    CompressOptions o = curveOptions();
    o.sizeBudget = estimatedFileBytes(input_, namedOptions(budgetConfig), budgetK);
    CompressStats stats;
    chooseSizeBudgetPoint(input_, o, stats);
    EXPECT_EQ(stats.sizeBudgetConfig, config) << budgetConfig << ", k = " << budgetK;
    EXPECT_GT(o.clusters, budgetK) << budgetConfig << ", k = " << budgetK;
    EXPECT_LE(stats.sizeBudgetEstimate, o.sizeBudget);
  }
  // Below the default's own point (k = 6 of 64 texels): the default with fewer clusters.
  CompressOptions o = curveOptions();
  o.sizeBudget = estimatedFileBytes(input_, namedOptions("default"), 4);
  CompressStats stats;
  chooseSizeBudgetPoint(input_, o, stats);
  EXPECT_EQ(stats.sizeBudgetConfig, "default");
  EXPECT_EQ(o.clusters, 4);
  // A budget above every point: high_fidelity at one cluster per 2.5 texels, round(64 / 2.5).
  o = curveOptions();
  o.sizeBudget = 100u << 20;
  stats = {};
  chooseSizeBudgetPoint(input_, o, stats);
  EXPECT_EQ(stats.sizeBudgetConfig, "high_fidelity");
  EXPECT_EQ(o.clusters, 26);
  EXPECT_TRUE(stats.sizeBudgetAtDensest);
  // A config given (no curve): its recipe, k from the budget.
  o = namedOptions("balanced");
  o.sizeBudget = estimatedFileBytes(input_, namedOptions("balanced"), 15);
  stats = {};
  chooseSizeBudgetPoint(input_, o, stats);
  EXPECT_EQ(o.clusters, 15);
  EXPECT_EQ(stats.sizeBudgetConfig, "");
  EXPECT_EQ(o.train.builtInConfig, "balanced");
  // PCA: the components.
  o = namedOptions("default");
  o.pcaBaseline = true;
  o.sizeBudget = estimatedFileBytes(input_, o, 3) + 10;
  stats = {};
  chooseSizeBudgetPoint(input_, o, stats);
  EXPECT_EQ(o.pcaComponents, 3);
}

TEST_F(SizeBudget, BudgetsNoFileMeetsAreRefusedNamingTheSmallest) {
  CompressOptions o = namedOptions("default");
  const std::uint64_t smallest = estimatedFileBytes(input_, o, 1);
  o.sizeBudget = smallest - 1;
  CompressStats stats;
  try {
    chooseSizeBudgetPoint(input_, o, stats);
    FAIL() << "a budget below one cluster's file was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(stack_), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("is below the smallest file of this input: default's recipe with one "
                                         "cluster is up to " + std::to_string(smallest) + " bytes"),
              std::string::npos)
        << e.what();
  }
  o = namedOptions("default");
  o.sizeBudget = 1000;
  o.pcaBaseline = true;
  EXPECT_THROW(chooseSizeBudgetPoint(input_, o, stats), Error);
  o = namedOptions("default");
  o.sizeBudget = 1u << 20;
  o.clusters = 0;  // per-texel
  o.clustersAreDefault = false;
  EXPECT_THROW(chooseSizeBudgetPoint(input_, o, stats), Error);
}

// close_up's density is the cap's: the two cannot drift apart.
TEST(SizeBudgetDensest, IsCloseUpsTexelsPerCluster) {
  EXPECT_EQ(loadCompressConfig("close_up").texelsPerCluster, kDensestTexelsPerCluster);
}

}  // namespace
}  // namespace nbtf
