// The options of `nbtf compress` and how they become a CompressOptions (compress_options.h).
#include "options/compress_options.h"

#include <cmath>
#include <cstdio>

#include "cli_common.h"
#include "model/config/config_section.h"
#include "pipeline/compress_config.h"
#include "util/atomic_file.h"
#include "options/clustering_options.h"
#include "options/memory_options.h"
#include "util/memory.h"

namespace nbtf::cli {
namespace {

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

// What a value checked after the command line was applied came from, for its error.
std::string configSource(const cxxopts::ParseResult& args) {
  return args.count("config") ? args["config"].as<std::string>() + " + command line" : "command line";
}

// The config file's recipe (or the compiled-in defaults, identical to configs/default.json),
// with the command-line options on top.
TrainConfig buildTrainConfig(TrainConfig c, const cxxopts::ParseResult& args, const std::string& output,
                             const std::string& program) {
  // Threads: --threads (capped, with its warning, by applyCommonOptions) over the config file's
  // training.threads, which is capped by the same rule.
  if (args.count("threads"))
    c.threads = args["threads"].as<int>() > 0 ? threadCount() : 0;
  else if (c.threads > 0)
    c.threads = cappedThreads(c.threads, program, "training.threads in " + args["config"].as<std::string>() + ":");
  if (args.count("holdout")) {
    c.holdoutFraction = args["holdout"].as<double>();
    if (!(c.holdoutFraction >= 0 && c.holdoutFraction < 1))
      throw Error("--holdout must be a fraction in [0, 1), got " + number(c.holdoutFraction));
  }
  if (args.count("epochs")) {
    c.epochs = args["epochs"].as<int>();
    if (c.epochs < 1) throw Error("--epochs must be >= 1, got " + std::to_string(c.epochs));
    c.minSteps = c.minStepsPerInput = c.maxSteps = 0;  // epochs given explicitly: exactly that many, no step bounds
  }
  if (args.count("time-budget")) {
    c.timeBudgetSeconds = args["time-budget"].as<double>();
    if (!(c.timeBudgetSeconds > 0 && std::isfinite(c.timeBudgetSeconds)))
      throw Error("--time-budget must be a positive number of seconds, got " + number(c.timeBudgetSeconds));
    if (!args.count("epochs")) c.epochs = 0;  // a budget alone: train until it is spent
  }
  if (const auto seed = clusteringArgs(args).seed) c.seed = *seed;
  if (args.count("resume")) c.resume = true;
  if (c.checkpointPath.empty()) c.checkpointPath = defaultCheckpointPath(output);
  validateTrainConfig(c, configSource(args));
  return c;
}

// --method: "clustered" (default; k from --clusters), "per-texel" (= --clusters 0) or "pca".
// Options that only mean something to another method are errors, not silently ignored.
void applyMethod(const cxxopts::ParseResult& args, CompressOptions& o) {
  const std::string method = args["method"].as<std::string>();
  if (method == "pca") {
    for (const char* neural : {"clusters", "config", "epochs", "time-budget", "resume", "restart", "save-encoder"})
      if (args.count(neural))
        throw Error(std::string("--") + neural + " applies to the neural methods only, not to --method pca");
    const bool budget = args.count("size-budget") && !args.count("adaptive");  // the budget chooses C
    if (!args.count("components") && !budget)
      throw Error("--method pca needs --components C (the number of principal components kept, >= 1) or "
                  "--size-budget BYTES (the most components that fit)");
    o.pcaBaseline = true;
    o.clustersAreDefault = false;
    if (o.pcaComponents < 1 && !(budget && !args.count("components")))
      throw Error("--components must be >= 1 with --method pca (the number of principal components kept), got " +
                  std::to_string(o.pcaComponents));
  } else if (method == "per-texel") {
    if (args.count("clusters") && o.clusters != 0)
      throw Error("--method per-texel has one latent per texel; it takes no --clusters (got " +
                  std::to_string(o.clusters) + ")");
    o.clusters = 0;
    o.clustersAreDefault = false;
  } else if (method == "clustered") {
    if (args.count("method") && o.clusters == 0)
      throw Error("--method clustered needs --clusters k >= 1 (for one latent per texel use --method per-texel)");
  } else {
    throw Error("unknown --method '" + method + "' (expected clustered, per-texel or pca)");
  }
}

// --adaptive and its targets over the config file's "adaptive" object (`a`); the targets
// without adaptive clusters are errors.
void applyAdaptive(const cxxopts::ParseResult& args, AdaptiveOptions a, CompressOptions& o) {
  if (args.count("adaptive")) a.enabled = true;
  for (const char* key : {"target-rmse", "max-clusters", "stages", "initial-clusters"})
    if (args.count(key) && !a.enabled)
      throw Error(std::string("--") + key + " needs --adaptive (or \"adaptive\": {\"enabled\": true} in the config)");
  if (!a.enabled) return;
  const std::string given = args.count("adaptive") ? "--adaptive" : "adaptive.enabled in the config";
  if (o.pcaBaseline || o.clusters == 0) throw Error(given + " needs the clustered method (--clusters > 0)");
  // On the command line 0 is not a target: the options take positive values.
  if (args.count("target-rmse")) {
    a.targetRmse = args["target-rmse"].as<double>();
    if (!(a.targetRmse > 0 && std::isfinite(a.targetRmse)))
      throw Error("--target-rmse must be a positive number, got " + number(a.targetRmse));
  }
  if (args.count("max-clusters")) {
    a.maxClusters = args["max-clusters"].as<int>();
    if (a.maxClusters < 1) throw Error("--max-clusters must be >= 1, got " + std::to_string(a.maxClusters));
  }
  if (args.count("size-budget")) {
    a.sizeBudget = parseByteSize(args["size-budget"].as<std::string>(), "--size-budget");
  }
  if (args.count("stages")) a.stages = args["stages"].as<int>();
  if (args.count("initial-clusters")) {
    a.initialClusters = args["initial-clusters"].as<int>();
    if (a.initialClusters < 1)
      throw Error("--initial-clusters must be >= 1, got " + std::to_string(a.initialClusters));
  }
  validateAdaptiveOptions(a, configSource(args));
  o.adaptive = a;
}

// --size-budget without adaptive clusters (pipeline/size_budget.h): k (PCA: C) is the largest
// whose file fits; without --config the budget also picks the recipe from `kSizeBudgetCurve`,
// each taking over from the one before at `takeover` times its own k, where fabric's measurements
// put it ahead (docs/compress.md, *A size budget*: balanced at k = 1000, twice its 500, passes the
// default's densest; high_fidelity at k = 1500, three times its 500, passes balanced's).
struct CurveRecipe {
  const char* config;
  int takeover;
};
const CurveRecipe kSizeBudgetCurve[] = {{"compact", 1}, {"default", 1}, {"balanced", 2}, {"high_fidelity", 3}};

void applySizeBudget(const cxxopts::ParseResult& args, CompressOptions& o) {
  if (!args.count("size-budget") || o.adaptive.enabled) return;
  o.sizeBudget = parseByteSize(args["size-budget"].as<std::string>(), "--size-budget");
  if (args.count("clusters"))
    throw Error("--size-budget chooses the number of clusters: give --clusters or --size-budget, not both");
  if (args.count("components") && o.pcaBaseline)
    throw Error("--size-budget chooses PCA's components: give --components or --size-budget, not both");
  if (o.clusters == 0 && !o.clustersAreDefault)
    throw Error("--size-budget chooses the number of clusters (or of PCA's components); --method per-texel has one "
                "latent per texel and nothing to choose");
}

}  // namespace

void addCompressOptions(cxxopts::Options& options) {
  options.add_options()("input", "BTF stack folder (UBO2003 or UTIA layout) or UBO2014 .btf file", cxxopts::value<std::string>())(
      "o,output", "Output .nbtf file", cxxopts::value<std::string>())(
      "method",
      "clustered (the paper's clustered neural BTF), per-texel (neural, one latent per texel; = --clusters 0) or "
      "pca (the classic PCA baseline: --components C principal components, no training)",
      cxxopts::value<std::string>()->default_value("clustered"))(
      "config",
      "Config JSON: the training recipe and the adaptive clusters; a file, or the name of a config of configs/, "
      "compiled in (" + builtInConfigList() + ") (default: identical to configs/default.json)",
      cxxopts::value<std::string>())(
      "holdout", "Fraction of (light, view) images kept out of training, in [0, 1)", cxxopts::value<double>())(
      "epochs", "Training epochs (overrides the config)", cxxopts::value<int>())(
      "time-budget", "Training time budget in seconds (alone: train until it is spent)",
      cxxopts::value<double>())(
      "stats-json", "Also write the summary as JSON to this file", cxxopts::value<std::string>())(
      "save-encoder", "Also write this .nbtf file with the encoder inside (for fine-tuning)",
      cxxopts::value<std::string>())("resume", "Continue from the checkpoint of an interrupted run")(
      "restart", "Delete an interrupted run's checkpoint and start over (without --resume or --restart a run "
                 "whose checkpoint exists is refused)")(
      "world-size", "Data-parallel training over this many processes (docs/model.md; same command on every rank)",
      cxxopts::value<int>()->default_value("1"))(
      "rank", "This process's rank, 0..world-size-1 (rank 0 hosts the rendezvous and writes the file)",
      cxxopts::value<int>()->default_value("0"))(
      "master", "HOST:PORT of rank 0's rendezvous (with --world-size > 1; rank 0 listens on that address only)",
      cxxopts::value<std::string>())(
      "dist-timeout", "Seconds the rendezvous and every collective may wait for the other ranks",
      cxxopts::value<double>()->default_value("120"))(
      "dist-secret",
      "Shared secret every rank presents at the rendezvous (default: NBTF_DIST_SECRET, which keeps it out of the "
      "process list; rank 0 generates and prints one when neither is set)",
      cxxopts::value<std::string>())(
      "adaptive",
      "Adaptive clusters: train in stages, splitting the clusters with the largest share of the error and "
      "merging near-duplicates between stages (training steps as for fixed k = --clusters)")(
      "target-rmse", "--adaptive: stop adding clusters once a stage's training RMSE is at most R",
      cxxopts::value<double>())("max-clusters", "--adaptive: at most K clusters", cxxopts::value<int>())(
      "size-budget",
      "The written file is at most this size (36K, 1.5M, 40000; K = 1024 bytes): the largest k (--method pca: "
      "components) that fits; without --config also the named config (compact, default, balanced, high_fidelity) the "
      "budget reaches; with --adaptive the clusters grow to it",
      cxxopts::value<std::string>())(
      "stages", "--adaptive: training stages (default 5)", cxxopts::value<int>())(
      "initial-clusters", "--adaptive: k of the first stage (default: max clusters or --clusters / 2^(stages-1))",
      cxxopts::value<int>());
  addClusteringOptions(options);
  addMemoryOptions(options);
  addStackOptions(options);
}

namespace {

// The recipe of `configPath` ("" = the compiled-in default) with the command line over it: the
// training config, the default k and the clustering space, what a config sets (and what
// --size-budget's curve swaps); returns the config for its "adaptive" object.
CompressConfig applyRecipe(const cxxopts::ParseResult& args, const std::string& program, const std::string& output,
                           const std::string& configPath, CompressOptions& o) {
  CompressConfig config = configPath.empty() ? CompressConfig{} : loadCompressConfig(configPath);
  o.train = buildTrainConfig(config.train, args, output, program);
  if (isBuiltInConfig(configPath)) o.train.builtInConfig = configPath;
  const ClusteringArgs clustering = clusteringArgs(args);
  o.clusters = clustering.clusters.value_or(config.clusters);
  o.clustersAreDefault = !clustering.clusters;
  if (o.clustersAreDefault) o.texelsPerCluster = config.texelsPerCluster;
  if (o.clusters < 0) throw Error("--clusters must be >= 0 (0 = per-texel), got " + std::to_string(o.clusters));
  o.clusteringSpace = clustering.space.value_or(config.clusteringSpace);
  return config;
}

}  // namespace

CompressRequest compressRequest(const cxxopts::ParseResult& args, const std::string& program) {
  if (!args.count("input")) throw Error("missing <input> (see 'nbtf compress --help')");
  if (!args.count("output")) throw Error("missing -o <out.nbtf> (see 'nbtf compress --help')");
  CompressRequest request;
  request.input = args["input"].as<std::string>();
  request.output = args["output"].as<std::string>();
  request.configPath = args.count("config") ? args["config"].as<std::string>() : "";
  CompressOptions& o = request.options;
  const CompressConfig config = applyRecipe(args, program, request.output, request.configPath, o);
  if (!args.count("threads") && o.train.threads > 0) setThreadCount(o.train.threads);
  o.pcaComponents = clusteringArgs(args).components.value_or(0);
  applyMethod(args, o);
  DistributedConfig& dist = o.train.distributed;
  dist.worldSize = args["world-size"].as<int>();
  dist.rank = args["rank"].as<int>();
  dist.timeoutSeconds = args["dist-timeout"].as<double>();
  if (args.count("master")) dist.master = args["master"].as<std::string>();
  if (dist.enabled() && !args.count("master")) throw Error("--world-size > 1 needs --master HOST:PORT");
  if (dist.enabled() && o.pcaBaseline) throw Error("--world-size: the PCA baseline has no training to distribute");
  validateDistributedConfig(dist);
  if (args.count("dist-secret")) dist.secret = args["dist-secret"].as<std::string>();
  completeDistributedSecret(dist);
  applyAdaptive(args, config.adaptive, o);
  if (dist.enabled() && o.adaptive.enabled)
    throw Error("--adaptive cannot be used with --world-size > 1 (its stages restart from checkpoints)");
  if (auto layout = layoutOption(args)) o.load.layout = *layout;
  if (auto crop = cropOption(args)) o.load.crop = *crop;
  if (args.count("save-encoder")) o.saveEncoderPath = args["save-encoder"].as<std::string>();
  o.restart = args.count("restart") > 0;
  if (o.restart && o.train.resume)
    throw Error("--resume continues the checkpoint and --restart deletes it: give one of them");
  const MemoryOptions memory = memoryOptions(args);
  o.memoryLimit = memory.limit;
  o.memoryLimitText = memory.limitText;
  o.stackStorage = memory.stack;
  request.statsPath = args.count("stats-json") ? args["stats-json"].as<std::string>() : "";
  applySizeBudget(args, o);
  if (o.sizeBudget > 0 && request.configPath.empty() && !o.pcaBaseline)
    for (const CurveRecipe& entry : kSizeBudgetCurve) {
      CompressOptions recipe;
      applyRecipe(args, program, request.output, entry.config, recipe);
      recipe.train.distributed = o.train.distributed;  // the run's, with its one secret
      recipe.sizeBudgetTakeover = entry.takeover;
      o.sizeBudgetCurve.push_back(std::move(recipe));
    }
  return request;
}

void prepareCompressOutputs(const CompressRequest& request) {
  const CompressOptions& o = request.options;
  // Before anything is created or read: no output may be an input or another output.
  refuseOverlappingCompressPaths(request.input, request.output, o,
                                 o.train.builtInConfig.empty() ? request.configPath : "",
                                 {{"--stats-json", request.statsPath}});
  // Every command creates the missing folders above its outputs.
  for (const std::string& out : {request.output, request.statsPath, o.saveEncoderPath})
    if (!out.empty()) createParentFolders(out);
  if (!request.statsPath.empty()) checkWritable(request.statsPath);  // the rest is checked by compressBtf
}

}  // namespace nbtf::cli
