// What `nbtf cluster` writes for people to judge a clustering: the id list as a label
// image (one colour per cluster) and a JSON summary (sizes, inertia, variance, timings).
#pragma once
#include <array>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cluster/clustering.h"
#include "io/btf_stack.h"
#include "io/image_io.h"

namespace nbtf {

// A cluster's colour: a bijective scramble of the id into 24 bits, so neighbouring ids get
// unrelated colours and the id list can be read back exactly from a lossless PNG.
std::array<std::uint8_t, 3> labelColour(int id);
int labelFromColour(const std::uint8_t* rgb);  // the inverse

// ids: width * height, row-major (texel t = y * width + x, as in BtfStack).
Image8 labelImage(const std::vector<std::int32_t>& ids, int width, int height);

// Appearance images, to judge a clustering by eye when k is too large for label colours:
// each texel's linear RGB averaged over all images (from the linear ABRDF matrix, M x 3N),
// and the same with every texel given its cluster's average. M x 3, linear.
Eigen::MatrixXf texelMeanColour(const MatrixXfCol& linearAbrdfs);
// The same (bit for bit) from the stack, without the matrix.
Eigen::MatrixXf texelMeanColour(const BtfStack& stack);
Eigen::MatrixXf clusterMeanColour(const Eigen::MatrixXf& texelColour, const std::vector<std::int32_t>& ids, int k);
// Linear RGB (M x 3) -> 8-bit sRGB image, divided by `scale` first (e.g. the brightest texel).
Image8 colourImage(const Eigen::MatrixXf& rgb, int width, int height, float scale);

// Cluster sizes in power-of-two bins: [1], [2, 3], [4, 7], ... (empty clusters in [0, 0]).
struct SizeBin {
  int smallest = 0, largest = 0;  // inclusive range of sizes
  int clusters = 0;
};
std::vector<SizeBin> sizeHistogram(const std::vector<int>& sizes);

// Where the clustered data came from and what the steps before clustering cost.
struct ClusterRunInfo {
  std::string input;
  int width = 0, height = 0, images = 0;
  Crop crop;
  float alpha = 0;  // target normalization (linear)
  ClusteringSpace space = ClusteringSpace::Log;  // the values PCA and k-means ran on
  int threads = 0;
  // matrixSeconds: the texel colours (one read of the stack); standardizeSeconds: the
  // standardization's statistics (another). The ABRDF matrix is streamed, never built.
  double loadSeconds = 0, matrixSeconds = 0, standardizeSeconds = 0, totalSeconds = 0;
  std::size_t peakMemoryBytes = 0;  // peak resident set size (getrusage), 0 = not measured
};

nlohmann::json clusteringSummary(const ClusteringResult& result, const ClusteringOptions& options,
                                 const ClusterRunInfo& info);

}  // namespace nbtf
