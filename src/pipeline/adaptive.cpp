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
#include "pipeline/compressor_internal.h"
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

CompressedBtf compressAdaptive(const BtfStack& stack, const CompressOptions& o, const AbrdfSource& x,
                               ClusteringResult clustering, float alpha, int pcaComponents, CompressStats& stats) {
  const AdaptiveOptions& a = o.adaptive;
  const bool say = o.progress && !Progress::quiet();  // stage lines, as the progress bars
  const std::int64_t texels = stack.numTexels();
  const int images = stack.numImages();
  auto tEdit = Clock::now();

  const std::vector<std::uint8_t> holdout = holdoutImageMask(images, o.train.holdoutFraction, o.train.seed);
  std::vector<int> trainImages;
  for (int i = 0; i < images; ++i)
    if (!holdout[i]) trainImages.push_back(i);
  const ModulationConfig& mc = o.train.modulation;
  const bool modulated = mc.mode != "none";
  const int terms = modulated ? mc.terms : 1, outs = 3 * terms;
  stats.modulationMode = mc.mode;
  const int channels = modulated ? mc.channels : 1;
  if (modulated) stats.modulationTerms = mc.terms, stats.modulationChannels = channels, stats.modulationBits = mc.bits;

  // ---- One schedule of T steps for all stages: the plan of a fixed-k run with k = --clusters.
  TrainConfig config = o.train;
  config.model.outputTerms = terms;
  config.progress = config.progress && o.progress;
  config.stopFlag = o.stopFlag;
  const std::int64_t totalSteps =
      planTraining(config, std::max(1, o.clusters), static_cast<int>(trainImages.size())).totalSteps;
  if (totalSteps <= 0)
    throw Error("--adaptive needs a training bounded in steps (epochs > 0), not by a time budget only");
  config.epochs = std::max(1, config.epochs);
  config.minSteps = config.maxSteps = static_cast<int>(std::min<std::int64_t>(totalSteps, 1 << 30));
  const int stagesPlanned = static_cast<int>(std::max<std::int64_t>(1, std::min<std::int64_t>(a.stages, totalSteps)));
  std::vector<std::int64_t> stageEnd(stagesPlanned, totalSteps);
  for (int j = 1; j < stagesPlanned; ++j) {
    std::int64_t end = std::llround(totalSteps * a.growthFraction * j / (stagesPlanned - 1));
    stageEnd[j - 1] = std::min(totalSteps - (stagesPlanned - j), std::max<std::int64_t>(j, end));
  }
  const bool temporaryCheckpoint = o.checkpointPath.empty() && config.checkpointPath.empty();
  config.checkpointPath = !o.checkpointPath.empty() ? o.checkpointPath
                          : temporaryCheckpoint     ? temporaryCheckpointPath()
                                                    : config.checkpointPath;
  config.resume = false;
  stats.checkpointPath = temporaryCheckpoint ? "" : config.checkpointPath;
  const std::string statePath = adaptiveStatePath(config.checkpointPath);
  struct RemoveTemporary {
    std::vector<std::string> paths;
    bool active;
    ~RemoveTemporary() {
      std::error_code ec;
      if (active)
        for (const std::string& p : paths) std::filesystem::remove(p, ec);
    }
  } removeTemporary{{config.checkpointPath, statePath}, temporaryCheckpoint};
  const std::uint64_t fingerprint = runFingerprint(o, clustering.ids, images, pcaComponents);

  const std::vector<double> energy = texelEnergies(stack, alpha, trainImages);
  const MatrixXfCol& scores = clustering.scores;
  std::vector<std::int32_t> ids = std::move(clustering.ids);
  int k = static_cast<int>(clustering.representatives.rows());
  MatrixXfCol representatives = std::move(clustering.representatives);
  {
    // Drop clusters k-means left empty (duplicate points) before the first stage.
    std::vector<int> kept = compactClusters(ids, k);
    if (static_cast<int>(kept.size()) != k) {
      k = static_cast<int>(kept.size());
      representatives = clusterRepresentatives(x, ids, k, Representative::Median);
    }
  }
  std::vector<int> generation(k, 0);
  const int kCapFixed = static_cast<int>(std::min<std::int64_t>(texels, a.maxClusters > 0 ? a.maxClusters : texels));
  const double latentBytes = config.model.latentDim * (config.storage.latents == "half" ? 2.0 : 4.0);
  stats.seconds.cluster += secondsSince(tEdit);

  std::vector<AdaptiveStage>& stages = stats.adaptiveStages;
  stages.clear();
  std::string stopReason = "stages done";
  CompressedBtf b;
  TrainResult last;
  std::vector<float> coefficients;
  std::int64_t stepsDone = 0;
  // Trains from the current step to `end` on the current clusters (a warm start after the
  // first stage) and assembles the model; false when the user interrupted.
  auto runStage = [&](std::int64_t end, bool warm) {
    auto tc = Clock::now();
    coefficients = modulated ? trainingCoefficients(stack, alpha, ids, k, holdout, mc, false)
                             : std::vector<float>{};
    stats.seconds.cluster += secondsSince(tc);
    TrainInputs inputs;
    inputs.stack = &stack;
    inputs.alpha = alpha;
    inputs.encoderInputs = &representatives;
    inputs.ids = ids;
    inputs.texelCoefficients = coefficients;
    inputs.coefficientTerms = modulated ? mc.terms : 0;
    inputs.coefficientChannels = channels;
    TrainConfig stageConfig = config;
    stageConfig.warmStart = warm;
    stageConfig.stopAtStep = end < totalSteps ? end : 0;
    auto tt = Clock::now();
    last = trainModel(inputs, stageConfig);
    if (o.stopFlag && o.stopFlag->load()) return false;
    stepsDone = last.steps;
    const bool stageEndOnly = last.interrupted;  // stopped at the stage boundary: no exact RMSE yet
    b = assembleCompressed(stack, config, CodecMethod::ClusteredNeural, alpha, last, ids, k, coefficients,
                           trainImages, holdout, false);
    if (stageEndOnly && last.rmseTrain < 0) {
      NbtfDecoder decoder(b, DecoderOptions{}, "adaptive stage");
      std::tie(last.rmseTrain, last.rmseHoldout) = decodedRmse(decoder, stack, alpha, holdout);
    }
    stats.seconds.train += secondsSince(tt);
    return true;
  };
  auto metadataFor = [&](const std::string& adaptiveJson) {
    CompressStats s = stats;
    s.clusters = k;
    return metadataJson(stack, config, last, &clustering, pcaComponents, s, adaptiveJson);
  };
  // The stage's entry, its bytes measured with the metadata it would be written with.
  auto recordStage = [&] {
    AdaptiveStage st;
    st.clusters = k;
    st.steps = stepsDone;
    st.rmseTrain = last.rmseTrain;
    stages.push_back(st);
    b.metadataJson = metadataFor(adaptiveMetadataJson(o, stages, generation, stopReason));
    stages.back().bytes = writtenBytes(b);
    if (say)
      std::fprintf(stderr, "adaptive: stage %d/%d  k = %d  steps %lld/%lld  rmse %.6f  %llu bytes\n",
                   static_cast<int>(stages.size()), stagesPlanned, k, static_cast<long long>(stepsDone),
                   static_cast<long long>(totalSteps), st.rmseTrain,
                   static_cast<unsigned long long>(stages.back().bytes));
  };
  // Applies merges (from, into), drops empty clusters, keeps `generation` in step.
  auto applyMerges = [&](const std::vector<std::pair<int, int>>& merges) {
    for (const auto& m : merges) mergeClusters(ids, m.first, m.second);
    std::vector<int> kept = compactClusters(ids, k);
    std::vector<int> g(kept.size());
    for (std::size_t c = 0; c < kept.size(); ++c) g[c] = generation[kept[c]];
    generation = std::move(g);
    const int pruned = k - static_cast<int>(kept.size());
    k = static_cast<int>(kept.size());
    return pruned;
  };
  // Decoded terms of the current model and the mean cluster error, for merges.
  auto mergeInputs = [&](std::vector<float>& decoded, std::vector<float>& best, std::vector<double>& shares) {
    decoded = decodeClusterTerms(b, stack, outs);
    best = clusterValues(stack, alpha, ids, k, modulated ? coefficients.data() : nullptr, terms, true, false, channels)
               .means;
    shares = clusterErrorShares(decoded, best, clusterSizes(ids, k), ids, energy, trainImages, images, outs);
  };

  // ---- --resume: continue the stage in progress from its saved clusters and the checkpoint.
  int firstStage = 0;
  bool resumedWarm = false;  // the first stage run continues from the checkpoint
  std::error_code ec;
  if (o.train.resume && std::filesystem::exists(statePath, ec)) {
    StageState saved = loadStageState(statePath, fingerprint, texels, stagesPlanned, totalSteps);
    resumedWarm = std::filesystem::exists(config.checkpointPath, ec);
    if (saved.stage > 0 && !resumedWarm)
      throw fileError(statePath, "stage " + std::to_string(saved.stage + 1) + " of the adaptive run continues from \"" +
                                     config.checkpointPath + "\", which does not exist; rerun without --resume");
    firstStage = saved.stage;
    stepsDone = saved.startStep;
    k = saved.k;
    ids = std::move(saved.ids);
    generation = std::move(saved.generation);
    stages = std::move(saved.stages);
    stopReason = saved.stopReason;
    if (firstStage > 0) representatives = clusterRepresentatives(x, ids, k, Representative::Median);
    if (say)
      std::fprintf(stderr, "adaptive: resuming stage %d/%d (k = %d) from %s\n", firstStage + 1, stagesPlanned, k,
                   config.checkpointPath.c_str());
  } else if (o.train.resume && say) {
    std::fprintf(stderr, "adaptive: --resume: no saved state at %s, starting from the beginning\n", statePath.c_str());
  }

  for (int stage = firstStage; stage < stagesPlanned; ++stage) {
    if (say)
      std::fprintf(stderr, "adaptive: stage %d/%d  k = %d  training steps %lld..%lld\n", stage + 1, stagesPlanned, k,
                   static_cast<long long>(stepsDone), static_cast<long long>(stageEnd[stage]));
    saveStageState(statePath, fingerprint, StageState{stage, stepsDone, k, ids, generation, stages, stopReason});
    if (!runStage(stageEnd[stage], stage > 0 || resumedWarm)) {
      stats.interrupted = true;
      return {};
    }
    recordStage();
    if (stage + 1 == stagesPlanned) break;

    // ---- Edit the clusters for the next stage.
    tEdit = Clock::now();
    const std::vector<int> sizes = clusterSizes(ids, k);
    std::vector<float> decoded, best;
    std::vector<double> shares;
    mergeInputs(decoded, best, shares);
    const double total = std::accumulate(shares.begin(), shares.end(), 0.0);
    const int roundsLeft = stagesPlanned - 1 - stage;
    // Where k should go: toward the cap (or the budget's estimate) geometrically over the
    // rounds left; with neither, doubling; no growth once the target is met.
    int kCap = kCapFixed;
    if (a.sizeBudget > 0)
      kCap = clustersWithinBudget(stages, latentBytes, 0.99 * static_cast<double>(a.sizeBudget), kCapFixed);
    int kNext;
    if (a.targetRmse > 0 && last.rmseTrain <= a.targetRmse) {
      kNext = std::min(k, kCap);
      stopReason = "target rmse met";
    } else if (a.maxClusters > 0 || a.sizeBudget > 0) {
      kNext = static_cast<int>(std::ceil(k * std::pow(static_cast<double>(kCap) / k, 1.0 / roundsLeft) - 1e-9));
      kNext = std::min(kNext, kCap);
      if (kNext <= k) stopReason = a.sizeBudget > 0 && kCap < kCapFixed ? "size budget reached" : "max clusters reached";
    } else {
      kNext = std::min(2 * k, kCap);
    }
    // Merges: near-duplicates always, more when k must shrink.
    const double meanShare = k > 0 ? total / k : 0;
    std::vector<std::pair<int, int>> merges =
        chooseMerges(b.latents, config.model.latentDim, decoded, best, sizes, trainImages, images, outs,
                     a.mergeTolerance * meanShare, std::max(0, k - kNext));
    // Shares follow the clusters through the merges (a merged cluster: the sum).
    std::vector<double> merged = shares;
    for (const auto& m : merges) merged[m.second] += merged[m.first], merged[m.first] = -1;
    const int kBefore = k;
    std::vector<int> keptIds;
    {
      std::vector<std::int32_t> probe(k);
      std::iota(probe.begin(), probe.end(), 0);
      for (const auto& m : merges) mergeClusters(probe, m.first, m.second);
      for (int c = 0; c < k; ++c)
        if (probe[c] == c && sizes[c] > 0) keptIds.push_back(c);
    }
    const int pruned = applyMerges(merges) - static_cast<int>(merges.size());
    std::vector<double> shareNow(k);
    for (int c = 0; c < k; ++c) shareNow[c] = merged[keptIds[c]];
    // Splits: the largest share first (ties: the lower id), clusters of >= 2 distinct texels.
    // A split's children may be split again in the same round: each is queued with the
    // parent's share x its fraction of the texels x 1/2 (an estimate: no model has been
    // trained on them yet).
    const int wanted = std::max(0, kNext - k);
    int splits = 0;
    {
      std::vector<int> sizesNow = clusterSizes(ids, k);
      auto later = [](const std::pair<double, int>& p, const std::pair<double, int>& q) {
        return p.first != q.first ? p.first < q.first : p.second > q.second;
      };
      std::vector<std::pair<double, int>> queue;
      for (int c = 0; c < k; ++c) queue.emplace_back(shareNow[c], c);
      std::make_heap(queue.begin(), queue.end(), later);
      while (splits < wanted && !queue.empty()) {
        std::pop_heap(queue.begin(), queue.end(), later);
        const auto [share, c] = queue.back();
        queue.pop_back();
        const std::uint64_t seed =
            SplitMix64::mix(SplitMix64::mix(SplitMix64::mix(o.train.seed, kSplitStream), stage), c);
        if (!splitCluster(scores, ids, c, k, seed)) continue;
        const int parentSize = sizesNow[c];
        sizesNow = clusterSizes(ids, k + 1);
        const int childGeneration = ++generation[c];
        generation.push_back(childGeneration);
        for (int child : {c, k}) {
          queue.emplace_back(0.5 * share * sizesNow[child] / parentSize, child);
          std::push_heap(queue.begin(), queue.end(), later);
        }
        ++k, ++splits;
      }
    }
    AdaptiveStage& st = stages.back();
    st.splits = splits;
    st.merges = static_cast<int>(merges.size());
    st.pruned = pruned;
    if (say)
      std::fprintf(stderr, "adaptive: after stage %d: %d merges, %d pruned, %d splits: k %d -> %d\n", stage + 1,
                   st.merges, pruned, splits, kBefore, k);
    if (splits < wanted && stopReason == "stages done") stopReason = "no cluster left to split";
    representatives = clusterRepresentatives(x, ids, k, Representative::Median);
    stats.seconds.cluster += secondsSince(tEdit);
  }

  // ---- A byte budget is a promise: merge (without further training) until the file fits.
  for (int attempt = 0; a.sizeBudget > 0 && stages.back().bytes > a.sizeBudget; ++attempt) {
    if (k <= 1 || attempt >= 30) {
      removeTemporary.active = true;  // no resumed run could meet the budget either
      throw Error("--size-budget " + std::to_string(a.sizeBudget) + " bytes is below the smallest file this run " +
                  "can write (" + std::to_string(stages.back().bytes) + " bytes at k = " + std::to_string(k) + ")");
    }
    const double excess = static_cast<double>(stages.back().bytes - a.sizeBudget);
    const int count = std::min(k - 1, std::max(1, static_cast<int>(std::ceil(excess / (latentBytes + 2))) + 1));
    std::vector<float> decoded, best;
    std::vector<double> shares;
    mergeInputs(decoded, best, shares);
    std::vector<std::pair<int, int>> merges = chooseMerges(b.latents, config.model.latentDim, decoded, best,
                                                           clusterSizes(ids, k), trainImages, images, outs, 0, count);
    applyMerges(merges);
    representatives = clusterRepresentatives(x, ids, k, Representative::Median);
    stages.back().merges += static_cast<int>(merges.size());
    if (say)
      std::fprintf(stderr, "adaptive: %llu bytes > --size-budget %llu: %d merges, k = %d\n",
                   static_cast<unsigned long long>(stages.back().bytes),
                   static_cast<unsigned long long>(a.sizeBudget), static_cast<int>(merges.size()), k);
    // Latents of the merged clusters from the trained encoder: a warm start with no steps left.
    if (!runStage(totalSteps, true)) {
      stats.interrupted = true;
      return {};
    }
    stopReason = "size budget reached";
    AdaptiveStage& st = stages.back();
    st.clusters = k;
    st.rmseTrain = last.rmseTrain;
    b.metadataJson = metadataFor(adaptiveMetadataJson(o, stages, generation, stopReason));
    st.bytes = writtenBytes(b);
  }

  // ---- The final material: its stage entry records the written size exactly (the entry is
  // part of the metadata it measures, so settle it in a few rounds).
  stats.clusters = k;
  stats.adaptiveStopReason = stopReason;
  stats.epochs = last.epochsRun;
  stats.steps = last.steps;
  stats.samplesPerSecond = last.samplesPerSecond;
  stats.decoderGflops = last.decoderGflops;
  stats.holdoutImages = static_cast<int>(b.holdoutImages.size());
  stats.rmseTrain = last.rmseTrain;
  stats.rmseHoldout = last.rmseHoldout;
  {
    ClusterValues floor = clusterValues(stack, alpha, ids, k, nullptr, 1, false, false);
    stats.rmseFloor = floor.floorRmse(trainImages, texels);
    if (modulated)
      stats.rmseFloorModulated =
          clusterValues(stack, alpha, ids, k, coefficients.data(), terms, false, false, channels)
              .floorRmse(trainImages, texels);
  }
  // The metadata is zstd-coded, so its size can swing between two values as the recorded
  // size's digits change (the size with A recorded is B, with B it is A). Then a run of
  // spaces after the JSON (which readers skip) of growing length is tried until the recorded
  // size is the size: the first that settles is kept.
  std::string padding;
  for (int attempt = 0; attempt < 64; ++attempt, padding += ' ') {
    bool settled = false;
    for (int round = 0; round < 4 && !settled; ++round) {
      b.metadataJson = metadataFor(adaptiveMetadataJson(o, stages, generation, stopReason)) + padding;
      const std::uint64_t bytes = writtenBytes(b);
      settled = bytes == stages.back().bytes;
      stages.back().bytes = bytes;
    }
    if (settled) break;
  }
  if (a.sizeBudget > 0 && writtenBytes(b) > a.sizeBudget)
    throw Error("--size-budget: internal error, the final file exceeds the budget");
  // The summary says so when the target was not met (the file records the stages' RMSE).
  if (a.targetRmse > 0 && last.rmseTrain > a.targetRmse) {
    char missed[128];
    std::snprintf(missed, sizeof missed, "target rmse %g missed (%.5f at the end)", a.targetRmse, last.rmseTrain);
    stats.adaptiveStopReason = std::string(missed) + "; " + stopReason;
  }
  b.validate("compressed result");
  stats.sizes = computeSizes(b);
  return b;
}

}  // namespace detail
}  // namespace nbtf
