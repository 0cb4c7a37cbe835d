#include "cluster/cluster_values.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <numeric>
#include <cmath>
#include <cstring>
#include <string>

#include "linalg/blas.h"
#include "util/error.h"
#include "util/page_buffer.h"
#include "util/random.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/simd.h"

namespace nbtf {

namespace {
double rmseOf(const std::vector<double>& perImageSse, const std::vector<int>& images, std::int64_t texels) {
  double sse = 0;
  for (int i : images) sse += perImageSse.at(static_cast<std::size_t>(i));
  const double count = static_cast<double>(images.size()) * static_cast<double>(texels) * 3.0;
  return count > 0 ? std::sqrt(sse / count) : 0.0;
}
}  // namespace

double ClusterValues::floorRmse(const std::vector<int>& images, std::int64_t texels) const {
  return rmseOf(withinSse, images, texels);
}
double ClusterValues::plainFloorRmse(const std::vector<int>& images, std::int64_t texels) const {
  return rmseOf(plainWithinSse, images, texels);
}

namespace {

// One image's cluster values: the (modulated) means of every cluster and the leftover, the sum
// over texels and channels of the squared difference between a value and its model. In phases
// (fitImage runs them), texel by texel, so that two models of one image can share the passes.
// kTerms and kChannels fix the shape at compile time (0: given at run time), so that the loops
// over a texel's terms and channels unroll; without kCoef every coefficient is exactly 1 (the
// plain means, the same doubles).
template <int kTerms, int kChannels, bool kCoef>
class ImageFit {
 public:
  ImageFit(const std::vector<std::int32_t>& ids, const std::vector<int>& sizes, const float* coef, int terms, int channels)
      : ids_(ids), sizes_(sizes), coef_(coef), terms_(kTerms ? kTerms : terms), channels_(kChannels ? kChannels : channels),
        sums_(sizes.size() * 3 * terms_), mean_(sizes.size() * 3 * terms_) {}
  void clear() { std::fill(sums_.begin(), sums_.end(), 0.0); }
  // Texel t of the image's linear RGB (texels x 3), times invAlpha, into its cluster's sums.
  void add(std::int64_t t, const float* rgb, float invAlpha) {
    double* s = &sums_[static_cast<std::size_t>(ids_[t]) * outputs()];
    for (int r = 0; r < terms(); ++r)
      for (int c = 0; c < 3; ++c) s[3 * r + c] += static_cast<double>(rgb[3 * t + c] * invAlpha) * coefficient(t, r, c);
  }
  void finishMeans() {
    for (std::size_t g = 0; g < sizes_.size(); ++g)
      for (int o = 0; o < outputs(); ++o) {
        const std::size_t at = g * outputs() + o;
        mean_[at] = sizes_[g] ? static_cast<float>(sums_[at] / sizes_[g]) : 0.0f;
      }
  }
  // Texel t's squared differences from its model, added to sse channel by channel.
  void addLeftover(std::int64_t t, const float* rgb, float invAlpha, double& sse) const {
    const float* m = &mean_[static_cast<std::size_t>(ids_[t]) * outputs()];
    for (int c = 0; c < 3; ++c) {
      double model = 0;
      for (int r = 0; r < terms(); ++r) model += coefficient(t, r, c) * m[3 * r + c];
      double d = static_cast<double>(rgb[3 * t + c] * invAlpha) - model;
      sse += d * d;
    }
  }
  const std::vector<float>& means() const { return mean_; }  // clusters x outputs, of the last fit
  const std::vector<std::int32_t>& ids() const { return ids_; }
  const std::vector<int>& sizes() const { return sizes_; }

 private:
  int terms() const { return kTerms ? kTerms : terms_; }
  int channels() const { return kChannels ? kChannels : channels_; }
  int outputs() const { return 3 * terms(); }
  // Texel t's coefficient of term r in channel c (channels 1: the same for all three).
  double coefficient(std::int64_t t, int r, int c) const {
    if constexpr (!kCoef) return 1.0;
    return coef_[t * terms() * channels() + r * channels() + (channels() > 1 ? c : 0)];
  }
  const std::vector<std::int32_t>& ids_;
  const std::vector<int>& sizes_;
  const float* coef_;
  int terms_, channels_;
  std::vector<double> sums_;
  std::vector<float> mean_;
};

// Fits one image with each of `fits`, their leftovers into sse[0], sse[1], ...: every fit's
// sums and leftover take the same doubles in the same order as it would alone, but the fits'
// additions (each a chain of dependent adds, the leftover one long chain) run side by side in
// one pass over the image.
template <class... Fits>
void fitImage(const float* rgb, float invAlpha, std::int64_t texels, double* sse, Fits&... fits) {
  (fits.clear(), ...);
  for (std::int64_t t = 0; t < texels; ++t) (fits.add(t, rgb, invAlpha), ...);
  (fits.finishMeans(), ...);
  std::array<double, sizeof...(Fits)> sums{};
  for (std::int64_t t = 0; t < texels; ++t) {
    std::size_t j = 0;
    (fits.addLeftover(t, rgb, invAlpha, sums[j++]), ...);
  }
  std::copy(sums.begin(), sums.end(), sse);
}

// clusterValues' pass with the model's shape fixed: images [begin, end) on one thread.
template <class Model>
void fitImages(const BtfStack& stack, Model model, std::size_t begin, std::size_t end, float invAlpha, bool keepMeans,
               bool plainFloorToo, int clusters, std::size_t outputs, ClusterValues& out, Progress& bar) {
  const std::int64_t texels = stack.numTexels();
  const std::size_t images = static_cast<std::size_t>(stack.numImages());
  std::vector<float> rgb(static_cast<std::size_t>(texels) * 3);
  ImageFit<1, 1, false> plain(model.ids(), model.sizes(), nullptr, 1, 1);
  for (std::size_t i = begin; i < end; ++i) {
    stack.imageLinear(static_cast<int>(i), rgb.data());
    if (plainFloorToo) {
      double sse[2];
      fitImage(rgb.data(), invAlpha, texels, sse, model, plain);
      out.withinSse[i] = sse[0];
      out.plainWithinSse[i] = sse[1];
    } else {
      fitImage(rgb.data(), invAlpha, texels, &out.withinSse[i], model);
    }
    if (keepMeans)
      for (int g = 0; g < clusters; ++g)
        std::copy_n(&model.means()[g * outputs], outputs, &out.means[(static_cast<std::size_t>(g) * images + i) * outputs]);
    bar.advance();
  }
}

}  // namespace

ClusterValues clusterValues(const BtfStack& stack, float alpha, const std::vector<std::int32_t>& ids, int clusters,
                            const float* coef, int terms, bool keepMeans, bool progress, int channels,
                            bool plainFloorToo) {
  const int images = stack.numImages();
  const std::int64_t texels = stack.numTexels();
  if (static_cast<std::int64_t>(ids.size()) != texels)
    throw Error("cluster values: " + std::to_string(ids.size()) + " ids for " + std::to_string(texels) + " texels");
  if (terms < 1 || (!coef && terms != 1)) throw Error("cluster values: " + std::to_string(terms) + " terms");
  if (channels != 1 && channels != 3) throw Error("cluster values: " + std::to_string(channels) + " channels");
  std::vector<int> sizes(clusters, 0);
  for (std::int32_t id : ids) {
    if (id < 0 || id >= clusters) throw Error("cluster values: cluster id " + std::to_string(id) + " out of range");
    ++sizes[id];
  }
  const std::size_t outputs = 3 * static_cast<std::size_t>(terms);
  ClusterValues out;
  if (keepMeans) out.means.assign(static_cast<std::size_t>(clusters) * images * outputs, 0.0f);
  out.withinSse.assign(images, 0.0);
  if (plainFloorToo) out.plainWithinSse.assign(images, 0.0);
  Progress bar("cluster means", images, progress);
  const float invAlpha = 1.0f / alpha;
  parallelFor(images, [&](std::size_t begin, std::size_t end) {
    auto run = [&](auto model) {
      fitImages(stack, std::move(model), begin, end, invAlpha, keepMeans, plainFloorToo, clusters, outputs, out, bar);
    };
    // The shapes the recipes use, unrolled; any other at run time.
    if (!coef)
      run(ImageFit<1, 1, false>(ids, sizes, nullptr, 1, 1));
    else if (terms == 1 && channels == 3)
      run(ImageFit<1, 3, true>(ids, sizes, coef, 1, 3));
    else if (terms == 1 && channels == 1)
      run(ImageFit<1, 1, true>(ids, sizes, coef, 1, 1));
    else
      run(ImageFit<0, 0, true>(ids, sizes, coef, terms, channels));
  });
  bar.finish();
  return out;
}

namespace {

// Orthonormal columns (thin Householder QR, in double).
Eigen::MatrixXf orthonormalColumns(const Eigen::MatrixXf& a) {
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(a.cast<double>());
  return (qr.householderQ() * Eigen::MatrixXd::Identity(a.rows(), a.cols())).cast<float>();
}

}  // namespace

void topLeftSingularVectors(const Eigen::Ref<const Eigen::MatrixXf>& y, int terms, std::uint64_t seed, Eigen::MatrixXd& u,
                            Eigen::VectorXd& sigma, int* iterationsOut) {
  const Eigen::Index n = y.rows(), dims = y.cols();
  const Eigen::Index rank = std::min(n, dims);
  if (terms < 1 || rank == 0) throw Error("top singular vectors: need terms >= 1 and a non-empty matrix");
  const int ld = static_cast<int>(y.outerStride());
  const Eigen::Index want = std::min<Eigen::Index>(terms, rank);
  const Eigen::Index block = std::min<Eigen::Index>(rank, want + 6);
  // Start: the mean row (close to the top right singular vector of same-signed data) and fixed
  // pseudo-random directions.
  Eigen::MatrixXf v(dims, block);
  v.col(0) = y.colwise().sum().transpose();
  if (!(v.col(0).squaredNorm() > 0)) v.col(0).setOnes();
  SplitMix64 random(seed);
  for (Eigen::Index j = 1; j < block; ++j)
    for (Eigen::Index d = 0; d < dims; ++d) v(d, j) = static_cast<float>(random.uniform() - 0.5);
  v = orthonormalColumns(v);
  Eigen::MatrixXf w(n, block), z(dims, block);
  Eigen::MatrixXd previous;
  double previousTurn = 1;
  constexpr int kMaxIterations = 200;
  int iteration = 0;
  for (; iteration < kMaxIterations; ++iteration) {
    // q = orth(y v); B = q^T y (block x dims); B B^T = Ub S^2 Ub^T: y's left singular vectors
    // are approximately q Ub, the next right ones orth(B^T) = orth(y^T q). Single-threaded BLAS
    // products: the same bits on any thread count.
    gemmOnThisThread(false, false, static_cast<int>(n), static_cast<int>(block), static_cast<int>(dims), y.data(),
                     ld, v.data(), static_cast<int>(dims), w.data(), static_cast<int>(n));
    const Eigen::MatrixXf q = orthonormalColumns(w);
    gemmOnThisThread(true, false, static_cast<int>(dims), static_cast<int>(block), static_cast<int>(n), y.data(),
                     ld, q.data(), static_cast<int>(n), z.data(), static_cast<int>(dims));
    const Eigen::MatrixXd zd = z.cast<double>();
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(zd.transpose() * zd);  // = B B^T, ascending
    u.resize(n, want);
    sigma.resize(want);
    for (Eigen::Index r = 0; r < want; ++r) {
      u.col(r) = q.cast<double>() * eig.eigenvectors().col(block - 1 - r);
      sigma(r) = std::sqrt(std::max(0.0, eig.eigenvalues()(block - 1 - r)));
    }
    v = orthonormalColumns(z);
    // Converged when every wanted vector stopped turning: 1 - |cos| below 1e-11 (angles of
    // about 4e-6 rad), or, below 1e-8, when the turn no longer halves: the float products'
    // rounding then moves the vectors as much as the iteration does (without this, some
    // clusters of a few hundred texels ran all 200 iterations).
    bool settled = false;
    if (previous.size() > 0) {
      double turn = 0;  // the largest 1 - |cos| over the wanted vectors that are not negligible
      for (Eigen::Index r = 0; r < want; ++r)
        if (sigma(r) > 1e-12 * std::max(1.0, sigma(0)))
          turn = std::max(turn, 1.0 - std::abs(previous.col(r).dot(u.col(r))));
      settled = turn <= 1e-11 || (turn < 1e-8 && turn > 0.5 * previousTurn);
      previousTurn = turn;
    }
    previous = u;
    if (settled) break;
  }
  if (iterationsOut) *iterationsOut = iteration + 1;
}

namespace {

// The top `terms` left singular vectors of y (n x dims), each oriented to a positive sum, as
// columns of u (n x terms; a column stays 0 where the singular value is negligible).
Eigen::MatrixXd leadingLeftVectors(const Eigen::Ref<const Eigen::MatrixXf>& y, int terms, std::uint64_t seed) {
  const Eigen::Index n = y.rows(), dims = y.cols();
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(n, terms);
  if (std::min(n, dims) > kExactSvdUpTo) {
    // Large clusters of long ABRDFs: subspace iteration for the top vectors only
    // (n x dims x (terms + 6) per iteration instead of n x min(n, dims) x dims).
    Eigen::MatrixXd u;
    Eigen::VectorXd sigma;
    topLeftSingularVectors(y, terms, seed, u, sigma);
    for (int r = 0; r < terms && r < u.cols(); ++r) {
      if (sigma(r) * sigma(r) <= 1e-12 * std::max(1.0, sigma(0) * sigma(0))) break;
      out.col(r) = u.col(r).sum() < 0 ? Eigen::VectorXd(-u.col(r)) : Eigen::VectorXd(u.col(r));
    }
    return out;
  }
  // The left singular vectors of y come from the smaller of its two Gram matrices: the
  // n x n one (y y^T: its eigenvectors), or, for clusters with more texels than values per
  // ABRDF (few images, large clusters), the dims x dims one (y^T y: u = y v / sigma).
  const bool texelSide = n <= dims;
  Eigen::MatrixXd gram, yd;
  if (texelSide) {
    gram = (y * y.transpose()).cast<double>();
  } else {
    yd = y.cast<double>();  // in double: u = y v / sigma divides by small singular values
    gram = yd.transpose() * yd;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(gram);
  const Eigen::Index m = gram.rows();
  for (int r = 0; r < terms && r < m; ++r) {
    const double lambda = eig.eigenvalues()(m - 1 - r);  // eigenvalues ascend
    if (lambda <= 1e-12 * std::max(1.0, eig.eigenvalues()(m - 1))) break;
    Eigen::VectorXd u;
    if (texelSide) {
      u = eig.eigenvectors().col(m - 1 - r);
    } else {
      u = yd * eig.eigenvectors().col(m - 1 - r);
      u.normalize();  // = y v / sigma, up to rounding
    }
    if (u.sum() < 0) u = -u;
    out.col(r) = u;
  }
  return out;
}

}  // namespace

namespace {

// The ABRDFs of clusters [first, last) as one column-major matrix each (raw[g - first]: the
// cluster's texels as rows in `members` order, column 3 j + c: image used[j], channel c), as the
// stack holds the values (BtfStack::gatherStored: a quarter of the floats' bytes for an 8-bit
// stack, so a batch holds four times the texels and the stack is read a quarter as often), in
// one pass over the images: each image's texels of the batch are read in ascending order (nearly
// sequential for a stack in memory, and each image once), and the images are split over the
// threads. The matrices live in `storage`, kept from batch to batch: a fresh buffer of this size
// (up to gigabytes) costs more to fault in than its values cost to gather.
template <class Value>
void scatterToClusters(const std::uint8_t* gathered, int count, std::size_t images, std::size_t firstColumn,
                       const std::vector<std::pair<std::uint32_t, std::uint32_t>>& slots,
                       const std::vector<std::uint8_t*>& raw, const std::vector<std::size_t>& rows) {
  // Column by column: each cluster's column is written in row order. The values are copied
  // as bytes (memcpy of one Value: a single load and store), which any buffer may hold.
  for (std::size_t j = 0; j < images; ++j)
    for (int c = 0; c < 3; ++c) {
      const std::uint8_t* values = gathered + (3 * j + c) * static_cast<std::size_t>(count) * sizeof(Value);
      const std::size_t column = 3 * (firstColumn + j) + c;
      for (int i = 0; i < count; ++i) {
        const auto [cluster, row] = slots[i];
        std::memcpy(raw[cluster] + (column * rows[cluster] + row) * sizeof(Value), values + i * sizeof(Value),
                    sizeof(Value));
      }
    }
}

void gatherClusters(const BtfStack& stack, const std::vector<int>& used, const std::vector<std::vector<int>>& members,
                    std::size_t first, std::size_t last, PageBuffer& storage, std::vector<std::uint8_t*>& raw) {
  struct Slot {
    int texel;
    std::uint32_t cluster;  // within the batch
    std::uint32_t row;
  };
  std::vector<Slot> sorted;
  for (std::size_t g = first; g < last; ++g)
    for (std::size_t k = 0; k < members[g].size(); ++k)
      sorted.push_back({members[g][k], static_cast<std::uint32_t>(g - first), static_cast<std::uint32_t>(k)});
  std::sort(sorted.begin(), sorted.end(), [](const Slot& a, const Slot& b) { return a.texel < b.texel; });
  std::vector<int> texels(sorted.size());
  std::vector<std::pair<std::uint32_t, std::uint32_t>> slots(sorted.size());
  for (std::size_t i = 0; i < sorted.size(); ++i) texels[i] = sorted[i].texel, slots[i] = {sorted[i].cluster, sorted[i].row};
  const std::size_t dims = 3 * used.size(), valueBytes = stack.storedValueBytes();
  constexpr std::size_t kAlign = 64;
  std::vector<std::size_t> offsets, rows;
  std::size_t bytes = 0;
  for (std::size_t g = first; g < last; ++g) {
    offsets.push_back(bytes);
    rows.push_back(members[g].size());
    bytes += (members[g].size() * dims * valueBytes + kAlign - 1) / kAlign * kAlign;
  }
  if (storage.size() < bytes) {  // freed first: never the old values beside the new
    storage = PageBuffer();
    storage = PageBuffer(bytes);
  }
  raw.clear();
  for (std::size_t offset : offsets) raw.push_back(storage.data() + offset);
  const int count = static_cast<int>(texels.size());
  // A few images per gather: a computed stack reads each texel's factors once per gather.
  constexpr std::size_t kImages = 16;
  parallelFor((used.size() + kImages - 1) / kImages, [&](std::size_t begin, std::size_t end) {
    std::vector<std::uint8_t> gathered(3 * kImages * static_cast<std::size_t>(count) * valueBytes);
    for (std::size_t j0 = begin * kImages; j0 < std::min(end * kImages, used.size()); j0 += kImages) {
      const std::size_t m = std::min(kImages, used.size() - j0);
      stack.gatherStored(&used[j0], static_cast<int>(m), texels.data(), count, gathered.data());
      if (valueBytes == 1)
        scatterToClusters<std::uint8_t>(gathered.data(), count, m, j0, slots, raw, rows);
      else if (valueBytes == 2)
        scatterToClusters<std::uint16_t>(gathered.data(), count, m, j0, slots, raw, rows);
      else
        scatterToClusters<std::uint32_t>(gathered.data(), count, m, j0, slots, raw, rows);
    }
  });
}

}  // namespace

std::vector<float> texelCoefficients(const BtfStack& stack, float alpha, const std::vector<std::int32_t>& ids,
                                     int clusters, const std::vector<std::uint8_t>& useImage, int terms, bool progress,
                                     int channels) {
  const int images = stack.numImages();
  const std::int64_t texels = stack.numTexels();
  if (terms < 1) throw Error("texel coefficients: terms must be >= 1");
  if (channels != 1 && channels != 3) throw Error("texel coefficients: channels must be 1 or 3");
  if (static_cast<int>(useImage.size()) != images) throw Error("texel coefficients: image mask has the wrong size");
  if (static_cast<std::int64_t>(ids.size()) != texels) throw Error("texel coefficients: one id per texel needed");
  std::vector<int> used;
  for (int i = 0; i < images; ++i)
    if (useImage[i]) used.push_back(i);
  if (used.empty()) throw Error("texel coefficients: no images to derive them from");
  std::vector<std::vector<int>> members(clusters);
  for (std::int64_t t = 0; t < texels; ++t) {
    if (ids[t] < 0 || ids[t] >= clusters) throw Error("texel coefficients: cluster id out of range");
    members[ids[t]].push_back(static_cast<int>(t));
  }
  const float invAlpha = 1.0f / alpha;
  const Eigen::Index usedImages = static_cast<Eigen::Index>(used.size());
  const int columns = terms * channels;
  std::vector<float> out(static_cast<std::size_t>(texels) * columns, 0.0f);
  // Batches of clusters whose stored values take at most the bytes of modulationTexelsPerThread
  // floats per thread (at least one cluster), and one cluster's values as floats per thread.
  const std::size_t valueBytes = stack.storedValueBytes();
  const std::size_t batchTexels = static_cast<std::size_t>(threadCount()) *
                                  modulationTexelsPerThread(texels, clusters) * sizeof(float) / valueBytes;
  Progress bar("texel coefficients", static_cast<std::size_t>(texels), progress);
  PageBuffer storage;
  std::vector<std::uint8_t*> batch;
  const Eigen::Index valueColumns = channels > 1 ? usedImages : 3 * usedImages;
  std::vector<AlignedFloats> valueStorage(threadCount());
  for (std::size_t first = 0; first < static_cast<std::size_t>(clusters);) {
    std::size_t last = first, size = 0;
    while (last < static_cast<std::size_t>(clusters) && (last == first || size + members[last].size() <= batchTexels))
      size += members[last++].size();
    gatherClusters(stack, used, members, first, last, storage, batch);
    // One cluster at a time to whichever thread is free: their costs grow with the square of
    // their sizes (20 to 900 texels), so equal counts per thread left one thread idle.
    std::size_t largest = 0;
    for (std::size_t g = first; g < last; ++g) largest = std::max(largest, members[g].size());
    parallelForDynamic(last - first, [&](std::size_t b, int worker) {
      const std::size_t g = first + b;
      const std::vector<int>& texelsOf = members[g];
      const Eigen::Index n = static_cast<Eigen::Index>(texelsOf.size());
      if (n == 0) return;
      // A cluster's values as floats (one channel's columns with per-channel coefficients), in
      // the worker's buffer, sized once for the batch's largest cluster.
      AlignedFloats& values = valueStorage[worker];
      if (values.size() < largest * static_cast<std::size_t>(valueColumns))
        values.resize(largest * static_cast<std::size_t>(valueColumns));
      const double scale = std::sqrt(static_cast<double>(n));
      const std::uint64_t seed = SplitMix64::mix(0x5eed5eedULL, g);
      for (int c = 0; c < channels; ++c) {
        // The cluster's ABRDFs as rows, linear / alpha: with per-channel coefficients column
        // j holds image j's channel c, else column 3 j + c does.
        Eigen::Map<Eigen::MatrixXf> y(values.data(), n, valueColumns);
        for (Eigen::Index j = 0; j < valueColumns; ++j) {
          const Eigen::Index column = channels > 1 ? 3 * j + c : j;
          stack.storedToLinear(batch[b] + static_cast<std::size_t>(column * n) * valueBytes,
                               static_cast<std::size_t>(n), invAlpha, y.col(j).data());
        }
        const Eigen::MatrixXd u = leadingLeftVectors(y, terms, seed);
        for (int r = 0; r < terms; ++r)
          for (Eigen::Index k = 0; k < n; ++k)
            out[static_cast<std::size_t>(texelsOf[k]) * columns + r * channels + c] = static_cast<float>(scale * u(k, r));
      }
      bar.advance(static_cast<std::size_t>(n));
    });
    first = last;
  }
  bar.finish();
  return out;
}

namespace {

// What a refit of the texel coefficients solves for: every cluster's term values at each image,
// and how the channels group into least-squares problems: all of RGB with one coefficient per
// term (channels 1), or each channel alone (channels 3).
struct RefitProblem {
  const std::vector<float>& terms;
  int clusters;
  std::size_t n, o;  // images; values per cluster and image (3 per term)
  int r, channels;
  double meanWeight;
  // Cluster g's values at image i start here.
  const float* termsAt(std::size_t g, std::size_t i) const { return &terms[(i * clusters + g) * o]; }
  int firstChannel(int q) const { return channels > 1 ? q : 0; }
  int endChannel(int q) const { return channels > 1 ? q + 1 : 3; }
};

// Cluster g's term values averaged over the images (F: term a, channel c at 3 a + c).
void addTermMean(const RefitProblem& p, std::size_t g, double* mean) {
  for (std::size_t i = 0; i < p.n; ++i)
    for (std::size_t j = 0; j < p.o; ++j) mean[j] += p.termsAt(g, i)[j];
  for (std::size_t j = 0; j < p.o; ++j) mean[j] /= static_cast<double>(p.n);
}

// Cluster g's Gram matrix of its terms over the images and group q's channels, with the mean
// term where `mean` is given.
Eigen::MatrixXd termGram(const RefitProblem& p, std::size_t g, int q, const double* mean) {
  const int r = p.r;
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(r, r);
  for (std::size_t i = 0; i < p.n; ++i) {
    const float* f = p.termsAt(g, i);
    for (int c = p.firstChannel(q); c < p.endChannel(q); ++c)
      for (int a = 0; a < r; ++a)
        for (int b = 0; b <= a; ++b) gram(a, b) += double(f[3 * a + c]) * f[3 * b + c];
  }
  if (mean) {
    for (int c = p.firstChannel(q); c < p.endChannel(q); ++c)
      for (int a = 0; a < r; ++a)
        for (int b = 0; b <= a; ++b) gram(a, b) += p.meanWeight * p.n * mean[3 * a + c] * mean[3 * b + c];
  }
  for (int a = 0; a < r; ++a)
    for (int b = 0; b < a; ++b) gram(b, a) = gram(a, b);
  const double ridge = 1e-9 * std::max(gram.trace(), 1e-30);
  gram.diagonal().array() += ridge;
  return gram;
}

// Per cluster and group: the Gram matrix of its terms over images and the group's channels,
// regularized a little so that a term that is (nearly) zero everywhere gets coefficient 0
// instead of noise. With meanWeight w > 0 the per-channel mean over the images, F (the
// cluster's) and Y (the texel's), enters too: + w n |sum_a e_a F_a - Y|^2, i.e. w n F F^T on
// the Gram matrix and w n F Y on the right-hand side; `termMeans` receives F per cluster.
std::vector<Eigen::LDLT<Eigen::MatrixXd>> termSolvers(const RefitProblem& p, std::vector<double>& termMeans) {
  std::vector<Eigen::LDLT<Eigen::MatrixXd>> solvers(static_cast<std::size_t>(p.clusters) * p.channels);
  termMeans.assign(p.meanWeight > 0 ? static_cast<std::size_t>(p.clusters) * p.o : 0, 0.0);
  parallelFor(static_cast<std::size_t>(p.clusters), [&](std::size_t begin, std::size_t end) {
    for (std::size_t g = begin; g < end; ++g) {
      const double* mean = nullptr;
      if (p.meanWeight > 0) {
        addTermMean(p, g, &termMeans[g * p.o]);
        mean = &termMeans[g * p.o];
      }
      for (int q = 0; q < p.channels; ++q) solvers[g * p.channels + q].compute(termGram(p, g, q, mean));
    }
  });
  return solvers;
}

// One thread's refit of chunks of consecutive texels, with its buffers: each chunk is gathered
// as the stack stores them, and every image is read once per chunk.
class ChunkRefit {
 public:
  ChunkRefit(const BtfStack& stack, const RefitProblem& p, const std::vector<int>& images,
             const std::vector<std::int32_t>& ids, const std::vector<Eigen::LDLT<Eigen::MatrixXd>>& solvers,
             const std::vector<double>& termMeans, float invAlpha, std::size_t maxChunkTexels)
      : stack_(stack), p_(p), images_(images), ids_(ids), solvers_(solvers), termMeans_(termMeans),
        invAlpha_(invAlpha), valueBytes_(stack.storedValueBytes()), rhs_(p.r),
        stored_(3 * p.n * maxChunkTexels * valueBytes_) {}

  // The coefficients of texels first .. first + count into `out` (texels x terms x channels).
  void run(std::size_t first, int count, std::vector<float>& out) {
    gather(first, count);
    sumImages(count);
    solve(first, count, out);
  }

 private:
  void gather(std::size_t first, int count) {
    chunk_.resize(count);
    std::iota(chunk_.begin(), chunk_.end(), static_cast<int>(first));
    row_.resize(count);
    stack_.gatherStored(images_.data(), static_cast<int>(p_.n), chunk_.data(), count, stored_.data());
    termOffset_.resize(count);
    for (int k = 0; k < count; ++k) {
      const std::int32_t g = ids_[first + k];
      if (g < 0 || g >= p_.clusters) throw Error("fit texel coefficients: cluster id out of range");
      termOffset_[k] = static_cast<std::size_t>(g) * p_.o;
    }
  }

  // The sums image by image, across the chunk's texels. Each texel's sums add the same
  // terms in the same order as a texel-by-texel loop would.
  void sumImages(int count) {
    const int r = p_.r, channels = p_.channels;
    texelSums_.assign(3 * static_cast<std::size_t>(count), 0.0);
    rhsSums_.assign(static_cast<std::size_t>(count) * channels * r, 0.0);
    for (std::size_t i = 0; i < p_.n; ++i)
      for (int c = 0; c < 3; ++c) {
        stack_.storedToLinear(stored_.data() + (3 * i + c) * count * valueBytes_, static_cast<std::size_t>(count),
                              invAlpha_, row_.data());
        const int q = channels > 1 ? c : 0;
        const float* image = p_.termsAt(0, i) + c;  // every cluster's values at this image: a few KB
        if (p_.meanWeight > 0)
          for (int k = 0; k < count; ++k) texelSums_[3 * k + c] += row_[k];
        if (r == 1) {  // the default, as one tight loop
          for (int k = 0; k < count; ++k)
            rhsSums_[static_cast<std::size_t>(k) * channels + q] += double(row_[k]) * image[termOffset_[k]];
        } else {
          for (int k = 0; k < count; ++k) {
            const double y = row_[k];
            double* sums = &rhsSums_[(static_cast<std::size_t>(k) * channels + q) * r];
            const float* f = image + termOffset_[k];
            for (int a = 0; a < r; ++a) sums[a] += y * f[3 * a];
          }
        }
      }
  }

  void solve(std::size_t first, int count, std::vector<float>& out) {
    const int r = p_.r, channels = p_.channels, columns = r * channels;
    for (int k = 0; k < count; ++k) {
      const std::size_t t = first + k;
      const std::int32_t g = ids_[t];
      for (int q = 0; q < channels; ++q) {
        for (int a = 0; a < r; ++a) rhs_(a) = rhsSums_[(static_cast<std::size_t>(k) * channels + q) * r + a];
        if (p_.meanWeight > 0) {
          const double* mean = &termMeans_[static_cast<std::size_t>(g) * p_.o];
          for (int c = p_.firstChannel(q); c < p_.endChannel(q); ++c)
            for (int a = 0; a < r; ++a) rhs_(a) += p_.meanWeight * mean[3 * a + c] * texelSums_[3 * k + c];  // w n F (sum / n)
        }
        Eigen::VectorXd e = solvers_[static_cast<std::size_t>(g) * channels + q].solve(rhs_);
        for (int a = 0; a < r; ++a)
          out[t * columns + a * channels + q] = std::isfinite(e(a)) ? static_cast<float>(e(a)) : 0.0f;
      }
    }
  }

  const BtfStack& stack_;
  const RefitProblem& p_;
  const std::vector<int>& images_;
  const std::vector<std::int32_t>& ids_;
  const std::vector<Eigen::LDLT<Eigen::MatrixXd>>& solvers_;
  const std::vector<double>& termMeans_;
  const float invAlpha_;
  const std::size_t valueBytes_;
  Eigen::VectorXd rhs_;
  std::vector<int> chunk_;
  PageBuffer stored_;                   // the chunk's texels in the images, image by image (gatherStored)
  std::vector<float> row_;              // one image's channel of them, linear / alpha
  std::vector<std::size_t> termOffset_;  // each texel's cluster's values within an image's
  std::vector<double> texelSums_, rhsSums_;  // per texel: sums by channel; right-hand sides (channel group, term)
};

}  // namespace

std::vector<float> fitTexelCoefficients(const BtfStack& stack, float alpha, const std::vector<std::int32_t>& ids,
                                        int clusters, const std::vector<int>& images, const std::vector<float>& terms,
                                        int r, bool progress, double meanWeight, int channels) {
  const std::int64_t texels = stack.numTexels();
  const std::size_t n = images.size(), o = 3 * static_cast<std::size_t>(r);
  if (r < 1 || terms.size() != static_cast<std::size_t>(clusters) * n * o)
    throw Error("fit texel coefficients: " + std::to_string(terms.size()) + " term values for " +
                std::to_string(n) + " images x " + std::to_string(clusters) + " clusters x " + std::to_string(o));
  if (channels != 1 && channels != 3) throw Error("fit texel coefficients: channels must be 1 or 3");
  if (static_cast<std::int64_t>(ids.size()) != texels) throw Error("fit texel coefficients: one id per texel needed");
  // One least-squares problem per texel and channel group.
  const RefitProblem problem{terms, clusters, n, o, r, channels, meanWeight};
  std::vector<double> termMeans;
  const std::vector<Eigen::LDLT<Eigen::MatrixXd>> solvers = termSolvers(problem, termMeans);
  const float invAlpha = 1.0f / alpha;
  std::vector<float> out(static_cast<std::size_t>(texels) * r * channels, 0.0f);
  Progress bar("refit texel coefficients", static_cast<std::size_t>(texels), progress);
  // Chunks of consecutive texels: one read call per image and chunk for a stack in a scratch
  // file, so that larger chunks make fewer calls; 256 to 4096 texels, within the stage's budget
  // per thread (modulationTexelsPerThread).
  const std::size_t valueBytes = stack.storedValueBytes();
  const std::size_t chunkTexels =
      std::clamp<std::size_t>(modulationTexelsPerThread(texels, clusters) * sizeof(float) / valueBytes, 256, 4096);
  parallelFor(static_cast<std::size_t>(texels), [&](std::size_t begin, std::size_t end) {
    ChunkRefit refit(stack, problem, images, ids, solvers, termMeans, invAlpha, std::min(chunkTexels, end - begin));
    for (std::size_t first = begin; first < end; first += chunkTexels) {
      const int count = static_cast<int>(std::min(chunkTexels, end - first));
      refit.run(first, count, out);
      bar.advance(static_cast<std::size_t>(count));
    }
  }, chunkTexels);
  bar.finish();
  return out;
}

}  // namespace nbtf
