#include "pipeline/adaptive.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numeric>
#include <tuple>
#include <nlohmann/json.hpp>

#include "cluster/cluster_edit.h"
#include "cluster/cluster_values.h"
#include "codec/decoder.h"
#include "pipeline/compress_config.h"
#include "model/training_set.h"
#include "pipeline/compress_parts.h"
#include "util/atomic_file.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/random.h"
#include "util/timer.h"

#if defined(__unix__)
#include <unistd.h>
#endif

namespace nbtf {
namespace {

using json = nlohmann::json;

constexpr std::uint64_t kSplitStream = 0x73706c6974ull;  // "split"


// Per texel: sum over the training images and channels of y^2 (linear / alpha). Images in
// order, texels in parallel: each texel's sum runs in image order on any thread count.
std::vector<double> texelEnergies(const BtfStack& stack, float alpha, const std::vector<int>& trainImages) {
  const std::size_t texels = static_cast<std::size_t>(stack.numTexels());
  std::vector<double> energy(texels, 0.0);
  std::vector<float> rgb(3 * texels);
  const double inv = 1.0 / alpha;
  for (int image : trainImages) {
    stack.imageLinear(image, rgb.data());
    parallelFor(texels, [&](std::size_t begin, std::size_t end) {
      for (std::size_t t = begin; t < end; ++t)
        for (int c = 0; c < 3; ++c) {
          const double v = rgb[3 * t + c] * inv;
          energy[t] += v * v;
        }
    });
  }
  return energy;
}

// Every cluster's decoded terms at every image: clusters x images x outs (clusterValues' layout).
std::vector<float> decodeClusterTerms(const CompressedBtf& b, const BtfStack& stack, int outs) {
  NbtfDecoder decoder(b, DecoderOptions{}, "adaptive stage");
  const int k = b.latentRows, images = stack.numImages(), views = stack.numViews();
  std::vector<float> out(static_cast<std::size_t>(k) * images * outs);
  parallelFor(images, [&](std::size_t begin, std::size_t end) {
    std::vector<float> rows(static_cast<std::size_t>(k) * outs);
    for (std::size_t i = begin; i < end; ++i) {
      decoder.decodeRowTerms(stack.lights()[i / views], stack.views()[i % views], rows.data());
      for (int g = 0; g < k; ++g)
        std::copy(&rows[static_cast<std::size_t>(g) * outs], &rows[static_cast<std::size_t>(g) * outs] + outs,
                  &out[(static_cast<std::size_t>(g) * images + i) * outs]);
    }
  });
  return out;
}

char generationDigit(int g) { return "0123456789abcdefghijklmnopqrstuvwxyz"[std::min(g, 35)]; }

std::string temporaryCheckpointPath() {
  static int counter = 0;
  long pid = 0;
#if defined(__unix__)
  pid = static_cast<long>(::getpid());
#endif
  return (std::filesystem::temp_directory_path() /
          ("nbtf-adaptive-" + std::to_string(pid) + "-" + std::to_string(counter++) + ".ckpt"))
      .string();
}

// The size the written file will have (the encoder is never in the output).
std::uint64_t writtenBytes(CompressedBtf& b) {
  std::vector<std::uint8_t> encoder = std::move(b.encoderState);
  b.encoderState.clear();
  const std::uint64_t bytes = serializeNbtf(b).size();
  b.encoderState = std::move(encoder);
  return bytes;
}

// ---- Resuming (--resume): the clusters of the stage in progress, saved beside the training
// checkpoint at the start of every stage (adaptiveStatePath).
struct StageState {
  int stage = 0;                 // the stage in progress
  std::int64_t startStep = 0;    // the schedule's step at its start
  int k = 0;
  std::vector<std::int32_t> ids;
  std::vector<int> generation;
  std::vector<AdaptiveStage> stages;  // the entries of the stages before it
  std::string stopReason;
};
constexpr const char* kStateFormat = "nbtf adaptive state 1";

std::string hex64(std::uint64_t v) {
  char buf[20];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

// What must match for a state to be resumed: the options (recipe, targets, k, seed) and the
// data (its shape and the initial k-means labels, which hash the ABRDFs' clustering).
std::uint64_t runFingerprint(const CompressOptions& o, const std::vector<std::int32_t>& initialIds, int images,
                             int pcaComponents) {
  const std::string text = trainConfigJson(o.train) + adaptiveConfigJson(o.adaptive);
  std::uint64_t h = SplitMix64::mix(0x6164617074ull, text.size());  // "adapt"
  for (unsigned char ch : text) h = SplitMix64::mix(h, ch);
  for (std::uint64_t v : {static_cast<std::uint64_t>(o.clusters), o.train.seed, static_cast<std::uint64_t>(images),
                          static_cast<std::uint64_t>(pcaComponents), static_cast<std::uint64_t>(initialIds.size())})
    h = SplitMix64::mix(h, v);
  for (std::int32_t id : initialIds) h = SplitMix64::mix(h, static_cast<std::uint32_t>(id));
  return h;
}

void saveStageState(const std::string& path, std::uint64_t fingerprint, const StageState& s) {
  json stages = json::array();
  for (const AdaptiveStage& st : s.stages)
    stages.push_back({st.clusters, st.steps, st.rmseTrain, st.bytes, st.splits, st.merges, st.pruned});
  json j = {{"format", kStateFormat}, {"fingerprint", hex64(fingerprint)}, {"stage", s.stage},
            {"start_step", s.startStep}, {"k", s.k},  {"stop_reason", s.stopReason},
            {"stages", stages},          {"generation", s.generation}, {"ids", s.ids}};
  writeFileAtomic(path, j.dump());
}

StageState loadStageState(const std::string& path, std::uint64_t fingerprint, std::int64_t texels, int stagesPlanned,
                          std::int64_t totalSteps) {
  StageState s;
  try {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw fileError(path, "cannot open the adaptive run's saved state");
    const json j = json::parse(in);
    if (!j.is_object() || j.value("format", "") != kStateFormat)
      throw fileError(path, "not an nbtf adaptive state file (\"format\" is not \"" + std::string(kStateFormat) + "\")");
    if (j.at("fingerprint").get<std::string>() != hex64(fingerprint))
      throw fileError(path, "saved by a run with other options or data; rerun without --resume to start afresh");
    s.stage = j.at("stage").get<int>();
    s.startStep = j.at("start_step").get<std::int64_t>();
    s.k = j.at("k").get<int>();
    s.stopReason = j.at("stop_reason").get<std::string>();
    s.ids = j.at("ids").get<std::vector<std::int32_t>>();
    s.generation = j.at("generation").get<std::vector<int>>();
    for (const json& e : j.at("stages")) {
      AdaptiveStage st;
      st.clusters = e.at(0).get<int>();
      st.steps = e.at(1).get<std::int64_t>();
      st.rmseTrain = e.at(2).get<double>();
      st.bytes = e.at(3).get<std::uint64_t>();
      st.splits = e.at(4).get<int>();
      st.merges = e.at(5).get<int>();
      st.pruned = e.at(6).get<int>();
      s.stages.push_back(st);
    }
  } catch (const json::exception& e) {
    throw fileError(path, std::string("damaged adaptive state: ") + e.what());
  }
  const bool idsOk = std::all_of(s.ids.begin(), s.ids.end(), [&](std::int32_t id) { return id >= 0 && id < s.k; });
  if (s.stage < 0 || s.stage >= stagesPlanned || static_cast<int>(s.stages.size()) != s.stage || s.startStep < 0 ||
      s.startStep > totalSteps || s.k < 1 || static_cast<std::int64_t>(s.ids.size()) != texels || !idsOk ||
      static_cast<int>(s.generation.size()) != s.k)
    throw fileError(path, "damaged adaptive state: its stage, steps, clusters or ids do not fit this run");
  return s;
}

}  // namespace

std::string adaptiveStatePath(const std::string& checkpointPath) { return checkpointPath + ".adaptive.json"; }

std::vector<double> clusterErrorShares(const std::vector<float>& decoded, const std::vector<float>& best,
                                       const std::vector<int>& sizes, const std::vector<std::int32_t>& ids,
                                       const std::vector<double>& texelEnergy, const std::vector<int>& trainImages,
                                       int images, int outs) {
  const int k = static_cast<int>(sizes.size());
  const std::size_t expected = static_cast<std::size_t>(k) * images * outs;
  if (decoded.size() != expected || best.size() != expected)
    throw Error("cluster error shares: value arrays do not match " + std::to_string(k) + " clusters x " +
                std::to_string(images) + " images x " + std::to_string(outs) + " outputs");
  if (ids.size() != texelEnergy.size()) throw Error("cluster error shares: one energy per texel expected");
  std::vector<double> within(k, 0.0);
  for (std::size_t t = 0; t < ids.size(); ++t) within[ids[t]] += texelEnergy[t];
  std::vector<double> shares(k, 0.0);
  for (int c = 0; c < k; ++c) {
    double model = 0, projected = 0;
    for (int i : trainImages) {
      const std::size_t at = (static_cast<std::size_t>(c) * images + i) * outs;
      for (int o = 0; o < outs; ++o) {
        const double d = static_cast<double>(decoded[at + o]) - best[at + o];
        model += d * d;
        projected += static_cast<double>(best[at + o]) * best[at + o];
      }
    }
    // The leftover is a difference of two large sums: clamp its rounding below zero.
    shares[c] = sizes[c] * model + std::max(0.0, within[c] - sizes[c] * projected);
  }
  return shares;
}

std::vector<std::pair<int, int>> chooseMerges(const std::vector<float>& latents, int latentDim,
                                              const std::vector<float>& decoded, const std::vector<float>& best,
                                              const std::vector<int>& sizes, const std::vector<int>& trainImages,
                                              int images, int outs, double maxCost, int atLeast) {
  const int k = static_cast<int>(sizes.size());
  if (latents.size() != static_cast<std::size_t>(k) * latentDim ||
      decoded.size() != static_cast<std::size_t>(k) * images * outs ||
      (!best.empty() && best.size() != decoded.size()))
    throw Error("cluster merges: latents or decoded values do not match " + std::to_string(k) + " clusters");
  struct Candidate {
    double cost;
    int a, b;
  };
  std::vector<Candidate> candidates;
  for (int c = 0; c < k; ++c) {
    if (sizes[c] == 0) continue;
    int nearest = -1;
    double nearestDistance = std::numeric_limits<double>::infinity();
    for (int d = 0; d < k; ++d) {
      if (d == c || sizes[d] == 0) continue;
      double dist = 0;
      for (int j = 0; j < latentDim; ++j) {
        const double v = static_cast<double>(latents[static_cast<std::size_t>(c) * latentDim + j]) -
                         latents[static_cast<std::size_t>(d) * latentDim + j];
        dist += v * v;
      }
      if (dist < nearestDistance) nearestDistance = dist, nearest = d;
    }
    if (nearest < 0) continue;
    auto distance = [&](const std::vector<float>& values) {
      double sum = 0;
      for (int i : trainImages) {
        const float* f = &values[(static_cast<std::size_t>(c) * images + i) * outs];
        const float* g = &values[(static_cast<std::size_t>(nearest) * images + i) * outs];
        for (int o = 0; o < outs; ++o) sum += (static_cast<double>(f[o]) - g[o]) * (static_cast<double>(f[o]) - g[o]);
      }
      return sum;
    };
    const double diff = std::max(distance(decoded), best.empty() ? 0.0 : distance(best));
    const double n1 = sizes[c], n2 = sizes[nearest];
    candidates.push_back({n1 * n2 / (n1 + n2) * diff, std::min(c, nearest), std::max(c, nearest)});
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& x, const Candidate& y) {
    if (x.cost != y.cost) return x.cost < y.cost;
    return x.a != y.a ? x.a < y.a : x.b < y.b;
  });
  std::vector<std::uint8_t> used(k, 0);
  std::vector<std::pair<int, int>> merges;
  for (const Candidate& cand : candidates) {
    if (cand.cost >= maxCost && static_cast<int>(merges.size()) >= atLeast) break;
    if (used[cand.a] || used[cand.b]) continue;
    used[cand.a] = used[cand.b] = 1;
    const bool aKeeps = sizes[cand.a] >= sizes[cand.b];  // on a tie the lower id (a) keeps
    merges.emplace_back(aKeeps ? cand.b : cand.a, aKeeps ? cand.a : cand.b);
  }
  return merges;
}

namespace detail {

int clustersWithinBudget(const std::vector<AdaptiveStage>& stages, double latentBytes, double bytesAllowed, int kMax) {
  if (stages.empty() || stages.back().clusters < 1 || kMax < 1)
    throw Error("cluster budget: no stage with clusters to estimate from");
  const AdaptiveStage& now = stages.back();
  const double kNow = now.clusters, bytesNow = static_cast<double>(now.bytes), perCluster = latentBytes + 2;
  double perDoubling = 0;
  if (stages.size() >= 2) {
    const AdaptiveStage& before = stages[stages.size() - 2];
    if (before.clusters >= 1 && before.clusters != now.clusters)
      perDoubling = std::max(0.0, (bytesNow - static_cast<double>(before.bytes) - perCluster * (kNow - before.clusters)) /
                                      (std::log2(kNow) - std::log2(static_cast<double>(before.clusters))));
  }
  auto estimate = [&](int k) { return bytesNow + perCluster * (k - kNow) + perDoubling * (std::log2(k) - std::log2(kNow)); };
  // The estimate grows with k: bisect for the last k that fits (at least 1: the caller's
  // final merges enforce the budget itself).
  int lo = 1, hi = kMax;
  while (lo < hi) {
    const int mid = lo + (hi - lo + 1) / 2;
    if (estimate(mid) <= bytesAllowed) lo = mid;
    else hi = mid - 1;
  }
  return lo;
}

int initialAdaptiveClusters(const CompressOptions& o, std::int64_t texels) {
  const AdaptiveOptions& a = o.adaptive;
  validateAdaptiveOptions(a, "adaptive options");
  if (o.train.model.clusterPlaneFeatures > 0)
    throw Error("--adaptive cannot train cluster planes (\"cluster_planes\"): each stage changes the clusters they "
                "belong to; use a fixed --clusters");
  int k0 = a.initialClusters;
  if (k0 == 0) {
    const int reference = a.maxClusters > 0 ? a.maxClusters : o.clusters;
    k0 = std::max(2, static_cast<int>(std::lround(reference / std::pow(2.0, a.stages - 1))));
  }
  if (a.maxClusters > 0) k0 = std::min(k0, a.maxClusters);
  return static_cast<int>(std::min<std::int64_t>(k0, texels));
}

std::string adaptiveMetadataJson(const CompressOptions& o, const std::vector<AdaptiveStage>& stages,
                                 const std::vector<int>& generation, const std::string& stopReason) {
  json a;
  json list = json::array();
  for (const AdaptiveStage& s : stages)
    list.push_back({{"k", s.clusters},
                    {"steps", s.steps},
                    {"rmse_train", s.rmseTrain},
                    {"bytes", s.bytes},
                    {"splits", s.splits},
                    {"merges", s.merges},
                    {"pruned", s.pruned}});
  a["stages"] = list;
  a["config"] = json::parse(adaptiveConfigJson(o.adaptive));  // the settings that ran
  a["stop_reason"] = stopReason;
  std::string digits(generation.size(), '0');
  for (std::size_t c = 0; c < generation.size(); ++c) digits[c] = generationDigit(generation[c]);
  a["generation"] = digits;  // split generation per cluster, base 36
  return a.dump();
}

namespace {

// Deletes the run's checkpoint and stage state when they were temporary (no --checkpoint).
struct RemoveTemporary {
  std::vector<std::string> paths;
  bool active = false;
  ~RemoveTemporary() {
    std::error_code ec;
    if (active)
      for (const std::string& p : paths) std::filesystem::remove(p, ec);
  }
};

// One adaptive run (compressAdaptive): plan the stages in the constructor, then per stage
// train (runStage) and edit the clusters (editClusters: merges, then splits); enforce the
// size budget by merging; finish with the file's final metadata and the summary.
class AdaptiveRun {
 public:
  AdaptiveRun(const BtfStack& stack, const CompressOptions& o, const AbrdfSource& x, ClusteringResult& clustering,
              float alpha, int pcaComponents, CompressStats& stats);

  void resume();                      // --resume: the saved stage, clusters and stage list
  bool trainStages();                 // false when the user interrupted
  bool enforceBudget();               // false when the user interrupted
  CompressedBtf finish();

 private:
  void planSchedule();
  void dropEmptyClusters();
  bool runStage(std::int64_t endStep, double endSeconds, bool warm);
  void recordStage();
  int nextClusterCount(int stage);
  void editClusters(int stage);
  int splitLargest(int stage, const std::vector<double>& shares, int wanted);
  int applyMerges(const std::vector<std::pair<int, int>>& merges);
  void mergeInputs(std::vector<float>& decoded, std::vector<float>& best, std::vector<double>& shares);
  std::string metadataFor(const std::string& adaptiveJson);
  void settleFinalSize();

  const BtfStack& stack_;
  const CompressOptions& o_;
  const AdaptiveOptions& a_;
  const AbrdfSource& x_;
  ClusteringResult& clustering_;
  const float alpha_;
  const int pcaComponents_;
  CompressStats& stats_;
  const bool say_;  // stage lines, as the progress bars
  const std::int64_t texels_;
  const int images_;

  // ---- The plan
  std::vector<std::uint8_t> holdout_;
  std::vector<int> trainImages_;
  const ModulationConfig& mc_;
  bool modulated_ = false;
  int terms_ = 1, outs_ = 3, channels_ = 1;
  TrainConfig config_;
  std::int64_t totalSteps_ = 0;
  int stagesPlanned_ = 1;
  std::vector<std::int64_t> stageEnd_;
  // --time-budget without --epochs: the stages end at these seconds of the training clock,
  // which carries over the stages through the checkpoint, so they share the budget.
  bool timed_ = false;
  std::vector<double> stageEndSeconds_;
  std::string statePath_;
  RemoveTemporary removeTemporary_;
  std::uint64_t fingerprint_ = 0;
  std::vector<double> energy_;
  int kCapFixed_ = 0;
  double latentBytes_ = 0;

  // ---- The clusters and the model as they stand
  std::vector<std::int32_t> ids_;
  int k_ = 0;
  MatrixXfCol representatives_;
  std::vector<int> generation_;
  std::string stopReason_ = "stages done";
  CompressedBtf b_;
  TrainResult last_;
  std::vector<float> coefficients_;
  std::int64_t stepsDone_ = 0;
  int firstStage_ = 0;
  bool resumedWarm_ = false;  // the first stage run continues from the checkpoint
};

AdaptiveRun::AdaptiveRun(const BtfStack& stack, const CompressOptions& o, const AbrdfSource& x,
                         ClusteringResult& clustering, float alpha, int pcaComponents, CompressStats& stats)
    : stack_(stack),
      o_(o),
      a_(o.adaptive),
      x_(x),
      clustering_(clustering),
      alpha_(alpha),
      pcaComponents_(pcaComponents),
      stats_(stats),
      say_(o.progress && !Progress::quiet()),
      texels_(stack.numTexels()),
      images_(stack.numImages()),
      mc_(o.train.modulation) {
  const auto tEdit = Clock::now();
  holdout_ = holdoutImageMask(images_, o.train.holdoutFraction, o.train.seed);
  for (int i = 0; i < images_; ++i)
    if (!holdout_[i]) trainImages_.push_back(i);
  modulated_ = mc_.mode != "none";
  terms_ = modulated_ ? mc_.terms : 1;
  outs_ = 3 * terms_;
  stats_.modulationMode = mc_.mode;
  channels_ = modulated_ ? mc_.channels : 1;
  if (modulated_) stats_.modulationTerms = mc_.terms, stats_.modulationChannels = channels_, stats_.modulationBits = mc_.bits;
  planSchedule();
  fingerprint_ = runFingerprint(o, clustering.ids, images_, pcaComponents);
  energy_ = texelEnergies(stack, alpha, trainImages_);
  ids_ = std::move(clustering.ids);
  k_ = static_cast<int>(clustering.representatives.rows());
  representatives_ = std::move(clustering.representatives);
  dropEmptyClusters();
  generation_.assign(k_, 0);
  kCapFixed_ = static_cast<int>(std::min<std::int64_t>(texels_, a_.maxClusters > 0 ? a_.maxClusters : texels_));
  latentBytes_ = config_.model.latentDim * (config_.storage.latents == "half" ? 2.0 : 4.0);
  stats_.seconds.cluster += secondsSince(tEdit);
  stats_.adaptiveStages.clear();
}

// One schedule of T steps for all stages: the plan of a fixed-k run with k = --clusters;
// the stages end at growing fractions of it. The checkpoint carries the model between them.
void AdaptiveRun::planSchedule() {
  config_ = o_.train;
  // The polish phase freezes the encoder, whose latents every cluster edit needs: it lies in
  // the last stage, at most half of it (the default's 0.5 becomes 0.2 with growth 0.6).
  config_.polishFraction = std::min(config_.polishFraction, 0.5 * (1 - a_.growthFraction));
  config_.model.outputTerms = terms_;
  config_.progress = config_.progress && o_.progress;
  config_.stopFlag = o_.stopFlag;
  totalSteps_ = planTraining(config_, std::max(1, o_.clusters), static_cast<int>(trainImages_.size())).totalSteps;
  timed_ = totalSteps_ <= 0;
  if (timed_) {
    // The same fractions of the budget as of the steps below; the last stage runs to its end.
    stagesPlanned_ = std::max(1, a_.stages);
    stageEnd_.assign(stagesPlanned_, 0);
    stageEndSeconds_.assign(stagesPlanned_, 0);
    for (int j = 1; j < stagesPlanned_; ++j)
      stageEndSeconds_[j - 1] = config_.timeBudgetSeconds * a_.growthFraction * j / (stagesPlanned_ - 1);
  } else {
    config_.epochs = std::max(1, config_.epochs);
    config_.minSteps = config_.maxSteps = static_cast<int>(std::min<std::int64_t>(totalSteps_, 1 << 30));
    stagesPlanned_ = static_cast<int>(std::max<std::int64_t>(1, std::min<std::int64_t>(a_.stages, totalSteps_)));
    stageEnd_.assign(stagesPlanned_, totalSteps_);
    for (int j = 1; j < stagesPlanned_; ++j) {
      std::int64_t end = std::llround(totalSteps_ * a_.growthFraction * j / (stagesPlanned_ - 1));
      stageEnd_[j - 1] = std::min(totalSteps_ - (stagesPlanned_ - j), std::max<std::int64_t>(j, end));
    }
  }
  const bool temporaryCheckpoint = o_.checkpointPath.empty() && config_.checkpointPath.empty();
  config_.checkpointPath = !o_.checkpointPath.empty() ? o_.checkpointPath
                           : temporaryCheckpoint     ? temporaryCheckpointPath()
                                                     : config_.checkpointPath;
  config_.resume = false;
  stats_.checkpointPath = temporaryCheckpoint ? "" : config_.checkpointPath;
  statePath_ = adaptiveStatePath(config_.checkpointPath);
  removeTemporary_.paths = {config_.checkpointPath, statePath_};
  removeTemporary_.active = temporaryCheckpoint;
}

// Drops clusters k-means left empty (duplicate points) before the first stage.
void AdaptiveRun::dropEmptyClusters() {
  std::vector<int> kept = compactClusters(ids_, k_);
  if (static_cast<int>(kept.size()) == k_) return;
  k_ = static_cast<int>(kept.size());
  representatives_ = clusterRepresentatives(x_, ids_, k_, Representative::Median);
}

void AdaptiveRun::resume() {
  std::error_code ec;
  if (o_.train.resume && std::filesystem::exists(statePath_, ec)) {
    StageState saved = loadStageState(statePath_, fingerprint_, texels_, stagesPlanned_, totalSteps_);
    resumedWarm_ = std::filesystem::exists(config_.checkpointPath, ec);
    if (saved.stage > 0 && !resumedWarm_)
      throw fileError(statePath_, "stage " + std::to_string(saved.stage + 1) + " of the adaptive run continues from \"" +
                                      config_.checkpointPath + "\", which does not exist; rerun without --resume");
    firstStage_ = saved.stage;
    stepsDone_ = saved.startStep;
    k_ = saved.k;
    ids_ = std::move(saved.ids);
    generation_ = std::move(saved.generation);
    stats_.adaptiveStages = std::move(saved.stages);
    stopReason_ = saved.stopReason;
    if (firstStage_ > 0) representatives_ = clusterRepresentatives(x_, ids_, k_, Representative::Median);
    if (say_)
      std::fprintf(stderr, "adaptive: resuming stage %d/%d (k = %d) from %s\n", firstStage_ + 1, stagesPlanned_, k_,
                   config_.checkpointPath.c_str());
  } else if (o_.train.resume && say_) {
    std::fprintf(stderr, "adaptive: --resume: no saved state at %s, starting from the beginning\n", statePath_.c_str());
  }
}

bool AdaptiveRun::trainStages() {
  for (int stage = firstStage_; stage < stagesPlanned_; ++stage) {
    if (say_ && timed_)
      std::fprintf(stderr, "adaptive: stage %d/%d  k = %d  training from step %lld until %.0f s of the %.0f s budget\n",
                   stage + 1, stagesPlanned_, k_, static_cast<long long>(stepsDone_),
                   stageEndSeconds_[stage] > 0 ? stageEndSeconds_[stage] : config_.timeBudgetSeconds,
                   config_.timeBudgetSeconds);
    else if (say_)
      std::fprintf(stderr, "adaptive: stage %d/%d  k = %d  training steps %lld..%lld\n", stage + 1, stagesPlanned_, k_,
                   static_cast<long long>(stepsDone_), static_cast<long long>(stageEnd_[stage]));
    saveStageState(statePath_, fingerprint_,
                   StageState{stage, stepsDone_, k_, ids_, generation_, stats_.adaptiveStages, stopReason_});
    if (!runStage(stageEnd_[stage], stageEndSeconds_.empty() ? 0 : stageEndSeconds_[stage], stage > 0 || resumedWarm_))
      return false;
    recordStage();
    if (stage + 1 == stagesPlanned_) break;
    const auto tEdit = Clock::now();
    editClusters(stage);
    stats_.seconds.cluster += secondsSince(tEdit);
  }
  return true;
}

// Trains from the current step to step `endStep` (or to `endSeconds` of the training clock;
// 0 = the plan's end) on the current clusters (a warm start after the first stage) and
// assembles the model; false when the user interrupted.
bool AdaptiveRun::runStage(std::int64_t endStep, double endSeconds, bool warm) {
  auto tc = Clock::now();
  coefficients_ = modulated_ ? trainingCoefficients(stack_, alpha_, ids_, k_, holdout_, mc_, false)
                             : std::vector<float>{};
  stats_.seconds.cluster += secondsSince(tc);
  TrainInputs inputs;
  inputs.stack = &stack_;
  inputs.alpha = alpha_;
  inputs.encoderInputs = &representatives_;
  inputs.ids = ids_;
  inputs.texelCoefficients = coefficients_;
  inputs.coefficientTerms = modulated_ ? mc_.terms : 0;
  inputs.coefficientChannels = channels_;
  TrainConfig stageConfig = config_;
  stageConfig.warmStart = warm;
  stageConfig.stopAtStep = endStep < totalSteps_ || timed_ ? endStep : 0;
  stageConfig.stopAtSeconds = endSeconds;
  auto tt = Clock::now();
  last_ = trainModel(inputs, stageConfig);
  if (o_.stopFlag && o_.stopFlag->load()) return false;
  stepsDone_ = last_.steps;
  const bool stageEndOnly = last_.interrupted;  // stopped at the stage boundary: no exact RMSE yet
  b_ = assembleCompressed(stack_, config_, CodecMethod::ClusteredNeural, alpha_, last_, ids_, k_, coefficients_,
                          trainImages_, holdout_, false);
  if (stageEndOnly && last_.rmseTrain < 0) {
    NbtfDecoder decoder(b_, DecoderOptions{}, "adaptive stage");
    std::tie(last_.rmseTrain, last_.rmseHoldout) = decodedRmse(decoder, stack_, alpha_, holdout_);
  }
  stats_.seconds.train += secondsSince(tt);
  return true;
}

std::string AdaptiveRun::metadataFor(const std::string& adaptiveJson) {
  CompressStats s = stats_;
  s.clusters = k_;
  return metadataJson(stack_, config_, last_, &clustering_, pcaComponents_, s, adaptiveJson);
}

// The stage's entry, its bytes measured with the metadata it would be written with.
void AdaptiveRun::recordStage() {
  std::vector<AdaptiveStage>& stages = stats_.adaptiveStages;
  AdaptiveStage st;
  st.clusters = k_;
  st.steps = stepsDone_;
  st.rmseTrain = last_.rmseTrain;
  stages.push_back(st);
  b_.metadataJson = metadataFor(adaptiveMetadataJson(o_, stages, generation_, stopReason_));
  stages.back().bytes = writtenBytes(b_);
  if (say_) {
    const std::string planned = timed_ ? "" : "/" + std::to_string(totalSteps_);
    std::fprintf(stderr, "adaptive: stage %d/%d  k = %d  steps %lld%s  rmse %.6f  %llu bytes\n",
                 static_cast<int>(stages.size()), stagesPlanned_, k_, static_cast<long long>(stepsDone_),
                 planned.c_str(), st.rmseTrain, static_cast<unsigned long long>(stages.back().bytes));
  }
}

// Applies merges (from, into), drops empty clusters, keeps `generation` in step; returns
// how many clusters went.
int AdaptiveRun::applyMerges(const std::vector<std::pair<int, int>>& merges) {
  for (const auto& m : merges) mergeClusters(ids_, m.first, m.second);
  std::vector<int> kept = compactClusters(ids_, k_);
  std::vector<int> g(kept.size());
  for (std::size_t c = 0; c < kept.size(); ++c) g[c] = generation_[kept[c]];
  generation_ = std::move(g);
  const int pruned = k_ - static_cast<int>(kept.size());
  k_ = static_cast<int>(kept.size());
  return pruned;
}

// Decoded terms of the current model and the mean cluster error, for merges.
void AdaptiveRun::mergeInputs(std::vector<float>& decoded, std::vector<float>& best, std::vector<double>& shares) {
  decoded = decodeClusterTerms(b_, stack_, outs_);
  best = clusterValues(stack_, alpha_, ids_, k_, modulated_ ? coefficients_.data() : nullptr, terms_, true, false,
                       channels_)
             .means;
  shares = clusterErrorShares(decoded, best, clusterSizes(ids_, k_), ids_, energy_, trainImages_, images_, outs_);
}

// Where k should go after `stage`: toward the cap (or the budget's estimate) geometrically
// over the rounds left; with neither, doubling; no growth once the target is met.
int AdaptiveRun::nextClusterCount(int stage) {
  const int roundsLeft = stagesPlanned_ - 1 - stage;
  int kCap = kCapFixed_;
  if (a_.sizeBudget > 0)
    kCap = clustersWithinBudget(stats_.adaptiveStages, latentBytes_, 0.99 * static_cast<double>(a_.sizeBudget),
                                kCapFixed_);
  if (a_.targetRmse > 0 && last_.rmseTrain <= a_.targetRmse) {
    stopReason_ = "target rmse met";
    return std::min(k_, kCap);
  }
  if (a_.maxClusters > 0 || a_.sizeBudget > 0) {
    int kNext = static_cast<int>(std::ceil(k_ * std::pow(static_cast<double>(kCap) / k_, 1.0 / roundsLeft) - 1e-9));
    kNext = std::min(kNext, kCap);
    if (kNext <= k_) stopReason_ = a_.sizeBudget > 0 && kCap < kCapFixed_ ? "size budget reached" : "max clusters reached";
    return kNext;
  }
  return std::min(2 * k_, kCap);
}

// The clusters for the next stage: merges (near-duplicates always, more when k must
// shrink), then splits of the clusters with the largest error share.
void AdaptiveRun::editClusters(int stage) {
  const std::vector<int> sizes = clusterSizes(ids_, k_);
  std::vector<float> decoded, best;
  std::vector<double> shares;
  mergeInputs(decoded, best, shares);
  const double total = std::accumulate(shares.begin(), shares.end(), 0.0);
  const int kNext = nextClusterCount(stage);
  const double meanShare = k_ > 0 ? total / k_ : 0;
  std::vector<std::pair<int, int>> merges =
      chooseMerges(b_.latents, config_.model.latentDim, decoded, best, sizes, trainImages_, images_, outs_,
                   a_.mergeTolerance * meanShare, std::max(0, k_ - kNext));
  // Shares follow the clusters through the merges (a merged cluster: the sum).
  std::vector<double> merged = shares;
  for (const auto& m : merges) merged[m.second] += merged[m.first], merged[m.first] = -1;
  const int kBefore = k_;
  std::vector<int> keptIds;
  {
    std::vector<std::int32_t> probe(k_);
    std::iota(probe.begin(), probe.end(), 0);
    for (const auto& m : merges) mergeClusters(probe, m.first, m.second);
    for (int c = 0; c < k_; ++c)
      if (probe[c] == c && sizes[c] > 0) keptIds.push_back(c);
  }
  const int pruned = applyMerges(merges) - static_cast<int>(merges.size());
  std::vector<double> shareNow(k_);
  for (int c = 0; c < k_; ++c) shareNow[c] = merged[keptIds[c]];
  const int wanted = std::max(0, kNext - k_);
  const int splits = splitLargest(stage, shareNow, wanted);
  AdaptiveStage& st = stats_.adaptiveStages.back();
  st.splits = splits;
  st.merges = static_cast<int>(merges.size());
  st.pruned = pruned;
  if (say_)
    std::fprintf(stderr, "adaptive: after stage %d: %d merges, %d pruned, %d splits: k %d -> %d\n", stage + 1,
                 st.merges, pruned, splits, kBefore, k_);
  if (splits < wanted && stopReason_ == "stages done") stopReason_ = "no cluster left to split";
  representatives_ = clusterRepresentatives(x_, ids_, k_, Representative::Median);
}

// Splits up to `wanted` clusters, the largest share first (ties: the lower id), clusters of
// >= 2 distinct texels. A split's children may be split again in the same round: each is
// queued with the parent's share x its fraction of the texels x 1/2 (an estimate: no model
// has been trained on them yet). Returns the splits made.
int AdaptiveRun::splitLargest(int stage, const std::vector<double>& shares, int wanted) {
  int splits = 0;
  std::vector<int> sizesNow = clusterSizes(ids_, k_);
  auto later = [](const std::pair<double, int>& p, const std::pair<double, int>& q) {
    return p.first != q.first ? p.first < q.first : p.second > q.second;
  };
  std::vector<std::pair<double, int>> queue;
  for (int c = 0; c < k_; ++c) queue.emplace_back(shares[c], c);
  std::make_heap(queue.begin(), queue.end(), later);
  while (splits < wanted && !queue.empty()) {
    std::pop_heap(queue.begin(), queue.end(), later);
    const auto [share, c] = queue.back();
    queue.pop_back();
    const std::uint64_t seed = SplitMix64::mix(SplitMix64::mix(SplitMix64::mix(o_.train.seed, kSplitStream), stage), c);
    if (!splitCluster(clustering_.scores, ids_, c, k_, seed)) continue;
    const int parentSize = sizesNow[c];
    sizesNow = clusterSizes(ids_, k_ + 1);
    const int childGeneration = ++generation_[c];
    generation_.push_back(childGeneration);
    for (int child : {c, k_}) {
      queue.emplace_back(0.5 * share * sizesNow[child] / parentSize, child);
      std::push_heap(queue.begin(), queue.end(), later);
    }
    ++k_, ++splits;
  }
  return splits;
}

// A byte budget is a promise: merge (without further training) until the file fits.
bool AdaptiveRun::enforceBudget() {
  std::vector<AdaptiveStage>& stages = stats_.adaptiveStages;
  for (int attempt = 0; a_.sizeBudget > 0 && stages.back().bytes > a_.sizeBudget; ++attempt) {
    if (k_ <= 1 || attempt >= 30) {
      removeTemporary_.active = true;  // no resumed run could meet the budget either
      throw Error("--size-budget " + std::to_string(a_.sizeBudget) + " bytes is below the smallest file this run " +
                  "can write (" + std::to_string(stages.back().bytes) + " bytes at k = " + std::to_string(k_) + ")");
    }
    const double excess = static_cast<double>(stages.back().bytes - a_.sizeBudget);
    const int count = std::min(k_ - 1, std::max(1, static_cast<int>(std::ceil(excess / (latentBytes_ + 2))) + 1));
    std::vector<float> decoded, best;
    std::vector<double> shares;
    mergeInputs(decoded, best, shares);
    std::vector<std::pair<int, int>> merges = chooseMerges(b_.latents, config_.model.latentDim, decoded, best,
                                                           clusterSizes(ids_, k_), trainImages_, images_, outs_, 0, count);
    applyMerges(merges);
    representatives_ = clusterRepresentatives(x_, ids_, k_, Representative::Median);
    stages.back().merges += static_cast<int>(merges.size());
    if (say_)
      std::fprintf(stderr, "adaptive: %llu bytes > --size-budget %llu: %d merges, k = %d\n",
                   static_cast<unsigned long long>(stages.back().bytes),
                   static_cast<unsigned long long>(a_.sizeBudget), static_cast<int>(merges.size()), k_);
    // Latents of the merged clusters from the trained encoder: a warm start with no steps left.
    if (!runStage(timed_ ? stepsDone_ : totalSteps_, 0, true)) return false;
    stopReason_ = "size budget reached";
    AdaptiveStage& st = stages.back();
    st.clusters = k_;
    st.rmseTrain = last_.rmseTrain;
    b_.metadataJson = metadataFor(adaptiveMetadataJson(o_, stages, generation_, stopReason_));
    st.bytes = writtenBytes(b_);
  }
  return true;
}

// The final stage entry records the written size exactly. The entry is part of the metadata
// it measures, and the metadata is zstd-coded, so its size can swing between two values as
// the recorded size's digits change (the size with A recorded is B, with B it is A). Then a
// run of spaces after the JSON (which readers skip) of growing length is tried until the
// recorded size is the size: the first that settles is kept.
void AdaptiveRun::settleFinalSize() {
  std::vector<AdaptiveStage>& stages = stats_.adaptiveStages;
  std::string padding;
  for (int attempt = 0; attempt < 64; ++attempt, padding += ' ') {
    bool settled = false;
    for (int round = 0; round < 4 && !settled; ++round) {
      b_.metadataJson = metadataFor(adaptiveMetadataJson(o_, stages, generation_, stopReason_)) + padding;
      const std::uint64_t bytes = writtenBytes(b_);
      settled = bytes == stages.back().bytes;
      stages.back().bytes = bytes;
    }
    if (settled) break;
  }
}

CompressedBtf AdaptiveRun::finish() {
  stats_.clusters = k_;
  stats_.adaptiveStopReason = stopReason_;
  stats_.epochs = last_.epochsRun;
  stats_.steps = last_.steps;
  stats_.samplesPerSecond = last_.samplesPerSecond;
  stats_.decoderGflops = last_.decoderGflops;
  stats_.products = last_.products;
  stats_.holdoutImages = static_cast<int>(b_.holdoutImages.size());
  stats_.rmseTrain = last_.rmseTrain;
  stats_.rmseHoldout = last_.rmseHoldout;
  stats_.rmseFloor = clusterValues(stack_, alpha_, ids_, k_, nullptr, 1, false, false).floorRmse(trainImages_, texels_);
  if (modulated_)
    stats_.rmseFloorModulated = clusterValues(stack_, alpha_, ids_, k_, coefficients_.data(), terms_, false, false, channels_)
                                    .floorRmse(trainImages_, texels_);
  settleFinalSize();
  if (a_.sizeBudget > 0 && writtenBytes(b_) > a_.sizeBudget)
    throw Error("--size-budget: internal error, the final file exceeds the budget");
  // The summary says so when the target was not met (the file records the stages' RMSE).
  if (a_.targetRmse > 0 && last_.rmseTrain > a_.targetRmse) {
    char missed[128];
    std::snprintf(missed, sizeof missed, "target rmse %g missed (%.5f at the end)", a_.targetRmse, last_.rmseTrain);
    stats_.adaptiveStopReason = std::string(missed) + "; " + stopReason_;
  }
  b_.validate("compressed result");
  stats_.sizes = computeSizes(b_);
  return std::move(b_);
}

}  // namespace

CompressedBtf compressAdaptive(const BtfStack& stack, const CompressOptions& o, const AbrdfSource& x,
                               ClusteringResult clustering, float alpha, int pcaComponents, CompressStats& stats) {
  AdaptiveRun run(stack, o, x, clustering, alpha, pcaComponents, stats);
  run.resume();
  if (!run.trainStages() || !run.enforceBudget()) {
    stats.interrupted = true;
    return {};
  }
  return run.finish();
}

}  // namespace detail
}  // namespace nbtf
