// Adaptive clusters (`nbtf compress --adaptive`): spend the latents where the error is.
//
// Training runs in stages along one schedule of T optimizer steps (T = planTraining's steps
// for fixed k = --clusters; the stages before the last end at even fractions of
// AdaptiveOptions::growthFraction x T). After each stage but the last, the stage's model is
// assembled and measured, each cluster's share of the training error is computed, clusters
// whose latents decode to nearly the same values are merged, empty ones dropped, and the
// clusters with the largest error shares are split in two by 2-means on their texels' PCA
// scores. The next stage warm-starts from the previous one's checkpoint (TrainConfig::
// warmStart): the encoder, the decoder and Adam's moments carry over bit for bit, because
// none of their shapes depend on k. A cluster's latent is not a parameter but the encoder's
// output on its representative (the median ABRDF), so new clusters get theirs from the
// encoder on their new representatives and unchanged clusters keep theirs (docs/model.md).
// An interrupted run resumes from the checkpoint and the stage's saved clusters
// (adaptiveStatePath), and writes the same bytes as one uninterrupted run.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "cluster/clustering.h"
#include "pipeline/compressor.h"

namespace nbtf {

// Per-cluster share of the training error (linear / alpha, summed over texels x training
// images x RGB) of a model whose cluster c decodes to terms f_c (clusters x images x outs,
// outs = 3 x terms, as clusterValues' means) when its best terms are T_c (same layout):
//   share_c = n_c sum_i |f_ci - T_ci|^2 + (sum_{t in c} |y_t|^2 - n_c sum_i |T_ci|^2),
// the second part the within-cluster leftover, from `texelEnergy` (per texel, sum over the
// training images and channels of y^2). Pure arithmetic; summed in image order.
std::vector<double> clusterErrorShares(const std::vector<float>& decoded, const std::vector<float>& best,
                                       const std::vector<int>& sizes, const std::vector<std::int32_t>& ids,
                                       const std::vector<double>& texelEnergy, const std::vector<int>& trainImages,
                                       int images, int outs);

// Merges for the next stage: each cluster paired with its nearest latent (L2), costing
//   n_c n_d / (n_c + n_d) x max(sum |f_c - f_d|^2, sum |T_c - T_d|^2)
// over training images and outputs, f the decoded terms and T the clusters' best terms
// (`best`, same layout; empty = decoded only): what one cluster at their weighted mean would
// add, when both the model and the data say they are alike. Pairs are taken cheapest first,
// each cluster in at most one pair, while cost < `maxCost`, and at least `atLeast` of them
// (to shrink k for a byte budget). Returns (from, into) pairs, `into` the larger cluster (on
// a tie the lower id).
std::vector<std::pair<int, int>> chooseMerges(const std::vector<float>& latents, int latentDim,
                                              const std::vector<float>& decoded, const std::vector<float>& best,
                                              const std::vector<int>& sizes, const std::vector<int>& trainImages,
                                              int images, int outs, double maxCost, int atLeast);

// Where an adaptive run keeps the clusters of the stage in progress, beside its training
// checkpoint, so that `--resume` continues an interrupted run: written at the start of every
// stage, removed with the checkpoint.
std::string adaptiveStatePath(const std::string& checkpointPath);

namespace detail {

// The largest k in 1 .. kMax whose file is estimated to take at most `bytesAllowed`, from the
// stages so far (the last one's k and bytes): bytes(k) = bytes_now + (latentBytes + 2)
// (k - k_now) + c (log2 k - log2 k_now). The linear part is a latent and the id stream's
// least cost per cluster; c >= 0 is what the id stream adds per doubling of k (its entropy
// grows about like log2 k bits per texel), fitted to the last two stages of different k (0
// with one). A straight line through two stages overestimates the cost of the next clusters,
// since each doubling of k costs the ids about the same bytes, and left budgets unused.
int clustersWithinBudget(const std::vector<AdaptiveStage>& stages, double latentBytes, double bytesAllowed, int kMax);

// k of the first stage.
int initialAdaptiveClusters(const CompressOptions& o, std::int64_t texels);

// The adaptive pipeline from the initial clustering (with scores) on: stages, edits, the
// final material; fills stats (adaptiveStages, RMSE, sizes). `x`: the standardized M x 3N
// ABRDF matrix, streamed from the stack (representatives of changed clusters are medians of
// its rows, one read of it per stage).
CompressedBtf compressAdaptive(const BtfStack& stack, const CompressOptions& o, const AbrdfSource& x,
                               ClusteringResult clustering, float alpha, int pcaComponents, CompressStats& stats);

// The "adaptive" object of the file's metadata: {"stages": [{k, steps, rmse_train, bytes,
// splits, merges, pruned}], "generation": "<one base-36 digit per cluster>", "stop_reason",
// "config": the settings (adaptiveConfigJson)}.
std::string adaptiveMetadataJson(const CompressOptions& o, const std::vector<AdaptiveStage>& stages,
                                 const std::vector<int>& generation, const std::string& stopReason);

}  // namespace detail

}  // namespace nbtf
