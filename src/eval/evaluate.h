// One evaluation pass: compares every image of a reference BTF with its reconstruction,
// accumulating the metrics of eval/metrics.h per (light, view) image, then picks the
// compared direction pairs (the paper's Fig. 7 pairs and the worst image), renders their
// comparison strips and estimates the effective blur sigma on a sample of images.
//
// The reconstruction is abstract (a callback), so `nbtf eval` plugs in a .nbtf decoder and
// tests plug in synthetic ones (the reference blurred, noisy, or scaled).
#pragma once
#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "eval/blur.h"
#include "eval/metrics.h"
#include "eval/render_section.h"
#include "io/btf_stack.h"
#include "io/image_io.h"

namespace nbtf {

// Table 1 of the paper, in bytes. total = decoder + latents + ids (the paper's definition:
// headers and metadata not counted); fileBytes = the file's actual size (0 = unknown).
struct SizeTable {
  std::uint64_t rawFloat32 = 0, decoder = 0, latents = 0, ids = 0, total = 0, fileBytes = 0;
  std::uint64_t perTexel = 0;  // per-texel modulation codes as stored (0 = none)
  std::uint64_t planes = 0;    // direction planes as stored (0 = none)
  std::uint64_t clusterPlanes = 0;  // cluster planes as stored (0 = none)
  // The same with the paper's 4-byte ids (0 = not given, or equal to the above).
  std::uint64_t idsPaper = 0, totalPaper = 0;
  // The PCA baseline's parts instead (decoder, latents, ids 0): total = mean + basis + coefficients.
  bool pca = false;
  int pcaComponents = 0;
  std::uint64_t pcaMean = 0, pcaBasis = 0, pcaCoefficients = 0;
  // A glTF fit (nbtf export-gltf) instead: total = its textures' bytes (PNG files).
  bool gltf = false;
  std::uint64_t textures = 0;
  bool known() const { return total > 0; }
  double ratio() const { return total ? static_cast<double>(rawFloat32) / static_cast<double>(total) : 0; }
};

// A requested (view, light) pair to show side by side.
struct DirectionPair {
  std::string name;
  Direction view, light;
  std::string note;  // shown with the comparison (e.g. why this pair)
};
// The two pairs of the paper's Fig. 7: view (15, 60) with light (30, 60), and the grazing
// view (75, 345) with light (75, 0) (the light printed in the paper, (345, 0), is no valid
// direction).
std::vector<DirectionPair> paperFigure7Pairs();

struct EvalInputs {
  const BtfStack* reference = nullptr;
  float alpha = 0;  // the file's alpha; <= 0: the reference's largest linear value
  // Writes image `image` (= light * numViews + view) as linear RGB, width * height * 3
  // floats, on the reference's scale (decoder output times alpha). Called concurrently for
  // different images; must be deterministic (the worst image is reconstructed twice).
  std::function<void(int image, float* linearRgb)> reconstruct;
  std::vector<int> holdoutImages;  // images kept out of training (may be empty)
  SizeTable sizes;                 // sizes.total == 0: no size table (e.g. synthetic inputs)
  std::string method;              // e.g. "clustered neural, k = 500"
  // For sweeps: the curve this result belongs to ("clustered-neural", "per-texel-neural",
  // "pca"; default: method) and its parameter (k, components; NaN = none).
  std::string methodFamily;
  double methodParameter = std::numeric_limits<double>::quiet_NaN();
  std::string referenceName;       // where the reference came from
  std::string compressedName;      // the compressed file, if any
  std::vector<std::pair<std::string, std::string>> details;  // extra facts for the header
  // Clustered materials: texel -> cluster ids (clusters > 0) and the per-texel modulation's
  // effective coefficients (texels x terms, empty = none), so the report can show the floors.
  std::vector<std::int32_t> clusterIds;
  int clusters = 0;
  std::vector<float> texelCoefficients;
  int coefficientTerms = 0;
  int coefficientChannels = 1;  // 3: per-channel coefficients (texels x terms x 3)
  // Adaptive files (nbtf compress --adaptive): each cluster's split generation (empty = none,
  // every cluster from the initial k-means), for the cluster map.
  std::vector<int> clusterGenerations;
  // Optional: the float ground truth the reference was quantized from (nbtf-synth writes it
  // beside its stacks; io/ground_truth.h), as `reconstruct` writes images. When set, the
  // reconstruction and the stored reference are measured against it too.
  std::function<void(int image, float* linearRgb)> groundTruth;
  std::string groundTruthName;
};

struct EvalOptions {
  std::vector<DirectionPair> pairs = paperFigure7Pairs();
  int blurSampleImages = 8;  // evenly spaced images for the blur estimate (besides compared ones)
  BlurOptions blur;
  bool progress = true;
};

struct Comparison {
  std::string name, note;
  DirectionPair requested;
  int light = 0, view = 0, image = 0;
  bool exact = true;  // the requested directions were measured exactly
  ErrorSummary error;
  BlurEstimate blur;
  double magnification = 1;  // of the error panel
  Image8 figure;             // reference | reconstruction | error strip
};

struct BlurSample {
  int light = 0, view = 0, image = 0;
  BlurEstimate estimate;
};

struct EvalResult {
  // ---- Inputs, described
  std::string method, methodFamily, referenceName, compressedName;
  double methodParameter = std::numeric_limits<double>::quiet_NaN();
  std::vector<std::pair<std::string, std::string>> details;
  int width = 0, height = 0;
  std::vector<Direction> lights, views;
  float alpha = 0;
  bool alphaFromReference = false;
  SizeTable sizes;
  std::vector<int> holdoutImages;

  // ---- Metrics
  ErrorTable table;
  ErrorSummary all, training, holdout;  // training = all when there is no hold-out set
  // Against the float ground truth (EvalInputs::groundTruth; hasGroundTruth false = none):
  // the reconstruction's errors, and the stored reference's own: the noise floor, what the
  // stack's encoding lost (an 8-bit JPEG stack: mostly the JPEG's loss) and no model fitted to
  // the stack can tell from the material. A model closer to the stack than this is fitting it.
  bool hasGroundTruth = false;
  std::string groundTruthName;
  ErrorSummary groundTruthAll, groundTruthTraining, groundTruthHoldout;
  ErrorSummary referenceVsGroundTruth, referenceVsGroundTruthHoldout;
  // How the reference stores its values ("8-bit sRGB JPEG", ...) and what its noise floor is
  // made of, in words for the report.
  std::string referenceEncoding, noiseFloorCause;
  std::vector<ElevationError> byLightElevation, byViewElevation;
  int worstImage = 0;
  std::vector<Comparison> comparisons;
  std::vector<BlurSample> blurSamples;  // unique images, ascending
  double blurSigmaMedian = 0;
  BlurOptions blurOptions;
  // Graininess: RMSE (linear RGB / alpha) between the reference's and the reconstruction's
  // mean brightness maps (each texel's value averaged over all images), and the two maps
  // side by side (displayed brightened by meanMapGain so the reference's brightest is white).
  double meanMapRmse = 0;
  double meanMapGain = 1, meanMapMagnification = 1;
  Image8 meanMapFigure;
  // Clustered: the cluster-mean floor over all images (the best any one-value-per-cluster
  // model can do) and, with per-texel modulation, the floor of the modulated model; -1 = none.
  double floorRmse = -1, floorRmseModulated = -1;
  // Clustered: the cluster map (texels coloured by split generation; eval/figures.h) and the
  // number of clusters per generation; empty when not clustered.
  Image8 clusterMapFigure;
  std::vector<int> clustersPerGeneration;
  // A rendered comparison to include (`nbtf eval --render-compare DIR`); empty = none.
  RenderSection render;
  double seconds = 0;

  bool hasHoldout() const { return !holdoutImages.empty(); }
};

// Runs the pass. Throws nbtf::Error on bad inputs, naming the image (light, view) and the
// value for a non-finite reconstruction.
EvalResult evaluate(const EvalInputs& inputs, const EvalOptions& options = {});

// The float ground truth beside a stack folder (nbtf-synth's ground_truth/, io/ground_truth.h)
// as EvalInputs::groundTruth, cropped as the reference was loaded; empty when the folder has
// none for every view of `reference`.
std::function<void(int image, float* linearRgb)> groundTruthBeside(const std::string& stackDir,
                                                                   const BtfStack& reference, const Crop& crop);


}  // namespace nbtf
