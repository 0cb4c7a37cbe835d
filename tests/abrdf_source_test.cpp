// The streamed ABRDF matrix (preprocess/abrdf_source.h) against the in-memory one: the same
// standardization, the same blocks, the same PCA, k-means labels and medians, bit for bit.
#include "preprocess/abrdf_source.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <atomic>
#include <cmath>
#include <memory>
#include <random>

#include "cluster/cluster_output.h"
#include "cluster/clustering.h"
#include "cluster/pca.h"
#include "test_util.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/progress.h"
#include "util/scratch_mapping.h"

namespace nbtf {
namespace {

// A small material with structure (three "threads" of different reflectance, a light- and
// view-dependent lobe) and per-texel noise. texels = width x height; odd sizes so that columns
// start at every offset modulo the SIMD width and the row slices of 1024 texels end mid-way.
// With `scratchDir`, the samples live in a scratch file there.
BtfStack structuredStack(int width, int height, int lights, int views, SampleType type, unsigned seed,
                         const std::string& scratchDir = "") {
  std::vector<Direction> l, v;
  for (int i = 0; i < lights; ++i) l.push_back({10.0 * i, 40.0 * i});
  for (int i = 0; i < views; ++i) v.push_back({12.0 * i, 60.0 * i});
  BtfStack stack(l, v, width, height, type, scratchDir);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> noise(-0.04f, 0.04f);
  std::vector<float> rgb(static_cast<std::size_t>(width) * height * 3);
  for (int image = 0; image < stack.numImages(); ++image) {
    const int li = image / views, vi = image % views;
    for (int t = 0; t < width * height; ++t) {
      const int x = t % width, y = t / width, kind = (x / 3 + y / 4) % 3;
      const float lobe = 0.3f + 0.5f * std::cos(0.4f * (li - vi) + kind);
      for (int c = 0; c < 3; ++c)
        rgb[3 * t + c] = std::max(0.0f, 0.15f * (kind + 1) * (1 + 0.2f * c) * lobe + noise(rng) + (c == kind ? 0.1f : 0.0f));
    }
    stack.setImageLinear(image, rgb.data());
  }
  // One black pixel everywhere: a constant dimension (standardized to 0).
  if (type == SampleType::Srgb8) std::fill(stack.imageBytes(1), stack.imageBytes(1) + stack.bytesPerImage(), 0);
  return stack;
}

MatrixXfCol standardizedMatrix(const BtfStack& stack, Standardization& s) {
  MatrixXfCol x = abrdfMatrix(stack, false);
  s = standardizeInPlace(x);
  return x;
}

class AbrdfSourceTest : public ::testing::Test {
 protected:
  void SetUp() override { Progress::setQuiet(true); }
  void TearDown() override { setThreadCount(0); }
};

// The texel colours `nbtf cluster` draws, from the stack (8-bit or half, in memory or in a
// scratch file): the matrix version's floats, and read image by image, so a stack in a scratch
// file is copied out, not mapped (read texel by texel, every page of the file was mapped in).
TEST_F(AbrdfSourceTest, TexelColoursEqualTheMatrixVersionAndMapNoScratchPages) {
  test::TempDir scratch;
  for (SampleType type : {SampleType::Srgb8, SampleType::Half}) {
    for (const std::string& dir : {std::string(), scratch.path()}) {
      const std::string where = std::string(sampleTypeName(type)) + (dir.empty() ? " in memory" : " in a scratch file");
      const BtfStack stack = structuredStack(67, 61, 9, 9, type, 3, dir);
      const std::size_t mappedBefore = residentFileBytes();
      const Eigen::MatrixXf fromStack = texelMeanColour(stack);
      const std::size_t mappedAfter = residentFileBytes();
      MatrixXfCol linear(stack.numTexels(), 3 * stack.numImages());
      for (int t = 0; t < stack.numTexels(); ++t) {
        const std::vector<float> abrdf = stack.abrdfLinear(t);
        for (int d = 0; d < linear.cols(); ++d) linear(t, d) = abrdf[d];
      }
      EXPECT_TRUE(fromStack == texelMeanColour(linear)) << where;
      if (!dir.empty())
        EXPECT_LT(mappedAfter, mappedBefore + stack.numImages() * stack.bytesPerImage() / 4) << where;
    }
  }
}

// Values computed on demand that count how many they were asked for: a stand-in for a
// factorized UBO2014 file, whose values cost a product each.
class CountingValues : public ComputedStackValues {
 public:
  CountingValues(int texels, int images) : texels_(texels), images_(images) {}
  void image(int image, float* out) const override {
    for (int t = 0; t < texels_; ++t) value(image, t, out + 3 * t);
  }
  void value(int image, int texel, float rgb[3]) const override {
    ++computed;
    for (int c = 0; c < 3; ++c) rgb[c] = 0.05f + 0.01f * ((texel * 7 + image * 3 + c * 5) % 23) + 0.002f * (texel % 5);
  }
  void gather(const int* images, int numImages, const int* texels, int count, float* out) const override {
    const int n = images ? numImages : images_;
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < count; ++k) {
        float rgb[3];
        value(images ? images[j] : j, texels[k], rgb);
        for (int c = 0; c < 3; ++c) out[static_cast<std::size_t>(3 * j + c) * count + k] = rgb[c];
      }
  }
  std::size_t bytes() const override { return 0; }
  mutable std::atomic<std::int64_t> computed{0};

 private:
  int texels_, images_;
};

// A sample of texels (PCA's, step 3 of docs/clustering.md) holds the rows' values bit for bit,
// and costs its own size: a computed stack computes only the sampled texels, not a pass.
TEST_F(AbrdfSourceTest, GatheredRowsHoldTheRowsValuesAndComputeOnlyThoseTexels) {
  std::vector<Eigen::Index> texels;
  for (Eigen::Index t = 0; t < 1107; t += 3) texels.push_back(t);  // 369: two runs, both row slices
  texels.push_back(1106);
  auto expectRows = [&](const AbrdfSource& source, const MatrixXfCol& x, const std::string& where) {
    const MatrixXfCol rows = source.gatherRows(texels);
    ASSERT_EQ(rows.rows(), static_cast<Eigen::Index>(texels.size()));
    ASSERT_EQ(rows.cols(), x.cols());
    std::int64_t mismatches = 0;
    for (std::size_t k = 0; k < texels.size(); ++k)
      for (Eigen::Index d = 0; d < x.cols(); ++d) mismatches += rows(static_cast<Eigen::Index>(k), d) != x(texels[k], d);
    EXPECT_EQ(mismatches, 0) << where;
  };
  test::TempDir scratch;
  for (SampleType type : {SampleType::Srgb8, SampleType::Half})
    for (const std::string& dir : {std::string(), scratch.path()}) {
      const std::string where = std::string(sampleTypeName(type)) + (dir.empty() ? " in memory" : " in a scratch file");
      BtfStack stack = structuredStack(41, 27, 5, 4, type, 2, dir);  // 1107 texels
      Standardization s;
      const MatrixXfCol x = standardizedMatrix(stack, s);
      expectRows(DenseAbrdfSource(x), x, where + ", in-memory X");
      expectRows(StackAbrdfSource(stack, s), x, where + ", standardized log");
      const float alpha = targetAlpha(stack);
      const MatrixXfCol linear = abrdfMatrix(stack, false) / alpha;
      expectRows(StackAbrdfSource::linear(stack, alpha), linear, where + ", linear");
    }
  std::vector<Direction> lights, views;
  for (int i = 0; i < 5; ++i) lights.push_back({10.0 * i, 40.0 * i}), views.push_back({12.0 * i, 60.0 * i});
  auto values = std::make_shared<CountingValues>(41 * 27, 25);
  const BtfStack computed(lights, views, 41, 27, SampleType::Half, values);
  Standardization s;
  const MatrixXfCol x = standardizedMatrix(computed, s);
  values->computed = 0;
  expectRows(StackAbrdfSource(computed, s), x, "computed");
  EXPECT_EQ(values->computed.load(), static_cast<std::int64_t>(texels.size()) * computed.numImages());
  // Out of order, repeated or outside the material: refused, naming the position.
  const StackAbrdfSource source(computed, s);
  for (const std::vector<Eigen::Index>& bad : {std::vector<Eigen::Index>{3, 2}, {4, 4}, {-1}, {1107}})
    EXPECT_THROW(source.gatherRows(bad), Error);

  // PCA on a sample (8,281 texels: at least 4 x the 2,048 of the smallest sample): the stack's
  // sample is the in-memory X's, so the results are the same bits.
  BtfStack large = structuredStack(91, 91, 4, 5, SampleType::Srgb8, 4);
  Standardization ls;
  const MatrixXfCol lx = standardizedMatrix(large, ls);
  PcaOptions o;
  o.components = 8;
  o.oversampling = 10;
  o.progress = false;
  o.sampleBytes = 1;  // the smallest sample, 2048 texels
  ASSERT_TRUE(o.samples(lx.rows(), lx.cols()));
  const PcaResult dense = randomizedPca(lx, o), streamed = randomizedPca(StackAbrdfSource(large, ls), o);
  EXPECT_EQ(streamed.sampledTexels, 2048);
  EXPECT_TRUE(streamed.basis == dense.basis);
  EXPECT_TRUE(streamed.scores == dense.scores);
}

// An 8-bit stack's pass takes the logarithms from a table of its 256 values, in memory or read
// out of a scratch file; a half stack's computes them: the same statistics either way.
TEST_F(AbrdfSourceTest, FitStandardizationMatchesTheInMemoryStatisticsBitForBit) {
  test::TempDir scratch;
  for (SampleType type : {SampleType::Srgb8, SampleType::Half})
    for (const std::string& dir : {std::string(), scratch.path()}) {
      const std::string where = std::string(sampleTypeName(type)) + (dir.empty() ? " in memory" : " in a scratch file");
      BtfStack stack = structuredStack(37, 29, 4, 3, type, 1, dir);
      ASSERT_EQ(stack.inScratchFile(), !dir.empty());
      Standardization dense;
      standardizedMatrix(stack, dense);
      float alpha = 0;
      Standardization streamed = fitStandardization(stack, false, &alpha);
      EXPECT_EQ(alpha, targetAlpha(stack)) << where;  // from the same pass
      ASSERT_EQ(streamed.mean.size(), dense.mean.size());
      EXPECT_TRUE((streamed.mean.array() == dense.mean.array()).all()) << where;
      EXPECT_TRUE((streamed.stddev.array() == dense.stddev.array()).all()) << where;
      if (type == SampleType::Srgb8) EXPECT_EQ(streamed.stddev[3], 0.0f) << where;  // image 1 is black: constant
    }
}

TEST_F(AbrdfSourceTest, BlocksHoldExactlyWhatTheMatrixHolds) {
  for (SampleType type : {SampleType::Srgb8, SampleType::Half}) {
    BtfStack stack = structuredStack(41, 27, 5, 4, type, 2);  // 1107 texels: two row slices
    Standardization s;
    const MatrixXfCol x = standardizedMatrix(stack, s);
    StackAbrdfSource source(stack, s);
    ASSERT_EQ(source.rows(), x.rows());
    ASSERT_EQ(source.cols(), x.cols());
    int columnSlices = 0, rowSlices = 0, mismatches = 0;
    source.forEachColumnSlice([&](Eigen::Index c0, Eigen::Index c1, const float* data) {
      for (Eigen::Index d = c0; d < c1; ++d)
        for (Eigen::Index t = 0; t < x.rows(); ++t) mismatches += data[(d - c0) * x.rows() + t] != x(t, d);
      ++columnSlices;
    });
    source.forEachRowSlice([&](Eigen::Index r0, Eigen::Index r1, const float* data, Eigen::Index ld) {
      for (Eigen::Index d = 0; d < x.cols(); ++d)
        for (Eigen::Index t = r0; t < r1; ++t) mismatches += data[d * ld + t - r0] != x(t, d);
      ++rowSlices;
    });
    EXPECT_EQ(mismatches, 0) << sampleTypeName(type);
    EXPECT_EQ(columnSlices, 1);
    EXPECT_EQ(rowSlices, 2);
  }
}

TEST_F(AbrdfSourceTest, StreamingPcaEqualsTheInMemoryPca) {
  // 1,107 texels x 3 x 120 images: two row slices, a column slice of 360 dimensions.
  BtfStack stack = structuredStack(41, 27, 12, 10, SampleType::Srgb8, 3);
  Standardization s;
  const MatrixXfCol x = standardizedMatrix(stack, s);
  StackAbrdfSource source(stack, s);
  PcaOptions o;
  o.components = 8;
  o.oversampling = 10;
  o.powerIterations = 2;
  o.progress = false;
  for (int threads : {1, 2}) {
    setThreadCount(threads);
    PcaResult dense = randomizedPca(x, o), streamed = randomizedPca(source, o);
    // The same math on the same values in the same slices: identical, not merely close.
    EXPECT_TRUE(streamed.basis == dense.basis) << threads << " threads";
    EXPECT_TRUE(streamed.scores == dense.scores) << threads << " threads";
    EXPECT_TRUE(streamed.mean == dense.mean);
    EXPECT_EQ(streamed.totalVariance, dense.totalVariance);
    // And close to the exact PCA, within tolerance: the leading component itself, the next
    // ones (whose variances lie close together here) as a subspace.
    Eigen::MatrixXd centred = x.cast<double>().rowwise() - x.cast<double>().colwise().mean();
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(centred.transpose() * centred / x.rows());
    const Eigen::Index d = eig.eigenvectors().cols();
    EXPECT_GT(std::abs(eig.eigenvectors().col(d - 1).dot(streamed.basis.col(0).cast<double>())), 0.999);
    const Eigen::MatrixXd top = eig.eigenvectors().rightCols(6);
    for (int j = 0; j < 3; ++j)
      EXPECT_GT((top.transpose() * streamed.basis.col(j).cast<double>()).norm(), 0.99) << "component " << j;
    EXPECT_NEAR(streamed.explainedVariance(0), eig.eigenvalues()(d - 1), 1e-3 * eig.eigenvalues()(d - 1));
  }
}

// The standardization pass also gives the moments of the standardized columns, bit for bit
// those of X, so that PCA skips its own pass over the stack and still gives the same result.
TEST_F(AbrdfSourceTest, MomentsFromTheStandardizationPassSparePcaAPass) {
  for (SampleType type : {SampleType::Srgb8, SampleType::Half}) {
    BtfStack stack = structuredStack(41, 27, 6, 5, type, 5);  // odd sizes: every column offset
    Standardization s;
    const MatrixXfCol x = standardizedMatrix(stack, s);
    ColumnMoments moments;
    Standardization streamed = fitStandardization(stack, false, nullptr, &moments);
    ASSERT_EQ(moments.mean.size(), x.cols());
    for (Eigen::Index d = 0; d < x.cols(); ++d) {
      double mean, variance;
      columnMoments(x.col(d).data(), x.rows(), mean, variance);
      ASSERT_EQ(moments.mean[d], static_cast<float>(mean)) << sampleTypeName(type) << " dimension " << d;
      ASSERT_EQ(moments.variance[d], variance) << sampleTypeName(type) << " dimension " << d;
    }
    StackAbrdfSource plain(stack, streamed), known(stack, streamed, moments);
    EXPECT_EQ(plain.knownMoments(), nullptr);
    ASSERT_NE(known.knownMoments(), nullptr);
    PcaOptions o;
    o.components = 6;
    o.progress = false;
    PcaResult a = randomizedPca(plain, o), b = randomizedPca(known, o);
    EXPECT_TRUE(a.mean == b.mean) << sampleTypeName(type);
    EXPECT_EQ(a.totalVariance, b.totalVariance) << sampleTypeName(type);
    EXPECT_TRUE(a.basis == b.basis) << sampleTypeName(type);
    EXPECT_TRUE(a.scores == b.scores) << sampleTypeName(type);
  }
}

TEST_F(AbrdfSourceTest, StreamingClusteringGivesTheSameLabelsAndMedians) {
  BtfStack stack = structuredStack(33, 35, 6, 5, SampleType::Srgb8, 4);  // 1,155 texels
  Standardization s;
  const MatrixXfCol x = standardizedMatrix(stack, s);
  StackAbrdfSource source(stack, s);
  ClusteringOptions o;
  o.clusters = 12;
  o.pca.components = 6;
  o.seed = 7;
  o.progress = false;
  for (int threads : {1, 2}) {
    setThreadCount(threads);
    ClusteringResult dense = clusterAbrdfs(x, o), streamed = clusterAbrdfs(source, o);
    EXPECT_EQ(streamed.ids, dense.ids) << threads << " threads";
    EXPECT_EQ(streamed.sizes, dense.sizes);
    EXPECT_TRUE(streamed.representatives == dense.representatives);
    EXPECT_EQ(streamed.inertia, dense.inertia);
    for (Representative kind : {Representative::Median, Representative::Mean})
      EXPECT_TRUE(clusterRepresentatives(source, dense.ids, o.clusters, kind) ==
                  clusterRepresentatives(x, dense.ids, o.clusters, kind));
  }
}

// The linear source holds the stack's linear values / alpha, the encoder's targets' space, in
// every block (8-bit: from one table; half: computed), and never offers coded images (their
// tables are per column, the standardized source's layout).
TEST_F(AbrdfSourceTest, LinearSourceHoldsTheLinearValuesOverAlpha) {
  test::TempDir scratch;
  for (SampleType type : {SampleType::Srgb8, SampleType::Half})
    for (const std::string& dir : {std::string(), scratch.path()}) {
      const std::string where = std::string(sampleTypeName(type)) + (dir.empty() ? " in memory" : " in a scratch file");
      BtfStack stack = structuredStack(41, 27, 5, 4, type, 2, dir);  // 1107 texels: two row slices
      const MatrixXfCol linear = abrdfMatrix(stack, false);        // linear values, before the log
      const float alpha = targetAlpha(stack);
      ASSERT_GT(alpha, 0.0f);
      const StackAbrdfSource source = StackAbrdfSource::linear(stack, alpha);
      EXPECT_TRUE(source.isLinear());
      EXPECT_EQ(source.knownMoments(), nullptr);
      ASSERT_EQ(source.rows(), linear.rows());
      ASSERT_EQ(source.cols(), linear.cols());
      std::int64_t mismatches = 0, nonZero = 0;
      source.forEachColumnSlice([&](Eigen::Index c0, Eigen::Index c1, const float* data) {
        for (Eigen::Index d = c0; d < c1; ++d)
          for (Eigen::Index t = 0; t < linear.rows(); ++t) {
            const float v = data[(d - c0) * linear.rows() + t];
            mismatches += v != linear(t, d) / alpha;
            nonZero += v != 0;
          }
      });
      source.forEachRowSlice([&](Eigen::Index r0, Eigen::Index r1, const float* data, Eigen::Index ld) {
        for (Eigen::Index d = 0; d < linear.cols(); ++d)
          for (Eigen::Index t = r0; t < r1; ++t) mismatches += data[d * ld + t - r0] != linear(t, d) / alpha;
      });
      EXPECT_EQ(mismatches, 0) << where;
      EXPECT_GT(nonZero, linear.size() / 2) << where;
      EXPECT_FALSE(source.forEachCodedImage([](Eigen::Index, const std::uint8_t*, const float*, int) {})) << where;
    }
  BtfStack stack = structuredStack(5, 4, 2, 2, SampleType::Srgb8, 1);
  EXPECT_THROW(StackAbrdfSource::linear(stack, 0.0f), Error);
}

// Clusters found in another space: PCA and k-means see the space's values, the medians are
// x's. The same as clustering the space itself, with x's medians of the resulting labels.
TEST_F(AbrdfSourceTest, ClusteringInTheLinearSpaceTakesTheMediansFromX) {
  BtfStack stack = structuredStack(33, 35, 6, 5, SampleType::Srgb8, 4);  // 1,155 texels
  Standardization s;
  const MatrixXfCol x = standardizedMatrix(stack, s);
  const float alpha = targetAlpha(stack);
  const MatrixXfCol linear = abrdfMatrix(stack, false) / alpha;
  StackAbrdfSource source(stack, s);
  const StackAbrdfSource linearSource = StackAbrdfSource::linear(stack, alpha);
  ClusteringOptions o;
  o.clusters = 12;
  o.pca.components = 6;
  o.seed = 7;
  o.progress = false;
  const ClusteringResult inLinear = clusterAbrdfs(source, o, &linearSource);
  const ClusteringResult ofLinear = clusterAbrdfs(linear, o);  // the linear matrix clustered on its own
  EXPECT_EQ(inLinear.ids, ofLinear.ids);
  EXPECT_EQ(inLinear.inertia, ofLinear.inertia);
  EXPECT_TRUE(inLinear.representatives == clusterRepresentatives(x, inLinear.ids, o.clusters, Representative::Median));
  EXPECT_FALSE(inLinear.representatives == ofLinear.representatives);  // those are linear values
  // A space of another shape is refused.
  BtfStack other = structuredStack(33, 34, 6, 5, SampleType::Srgb8, 4);
  const StackAbrdfSource otherSource = StackAbrdfSource::linear(other, alpha);
  test::expectErrorContaining([&] { clusterAbrdfs(source, o, &otherSource); }, {"clustering space is 1122 x 90"});
}

// An 8-bit stack's medians come from counts of its codes, in memory or from a scratch file:
// the selection's values bit for bit, for clusters of one texel, of even and odd sizes, an
// empty one, and a constant column (image 1 is black).
TEST_F(AbrdfSourceTest, MediansFromCodeCountsAreTheSelectionsBitForBit) {
  test::TempDir scratch;
  for (const std::string& dir : {std::string(), scratch.path()}) {
    BtfStack stack = structuredStack(23, 19, 3, 4, SampleType::Srgb8, 6, dir);  // 437 texels
    Standardization s;
    const MatrixXfCol x = standardizedMatrix(stack, s);
    StackAbrdfSource source(stack, s);
    int coded = 0;
    EXPECT_TRUE(source.forEachCodedImage([&](Eigen::Index, const std::uint8_t*, const float*, int) { ++coded; }));
    EXPECT_EQ(coded, stack.numImages());
    EXPECT_FALSE(DenseAbrdfSource(x).forEachCodedImage([](Eigen::Index, const std::uint8_t*, const float*, int) {}));
    // Clusters 0-5: 73 or 72 texels; 6: one texel; 7: two; 8: none.
    std::vector<std::int32_t> ids(static_cast<std::size_t>(x.rows()));
    for (std::size_t t = 0; t < ids.size(); ++t) ids[t] = static_cast<std::int32_t>(t % 6);
    ids[0] = 6, ids[1] = ids[2] = 7;
    for (int threads : {1, 2}) {
      setThreadCount(threads);
      const MatrixXfCol fromCodes = clusterRepresentatives(source, ids, 9, Representative::Median);
      const MatrixXfCol selected = clusterRepresentatives(x, ids, 9, Representative::Median);
      EXPECT_TRUE(fromCodes == selected) << (dir.empty() ? "in memory" : "in a scratch file") << ", " << threads
                                         << " threads";
      EXPECT_EQ(fromCodes(6, 10), x(0, 10));
      EXPECT_EQ(fromCodes(7, 10), 0.5f * (std::min(x(1, 10), x(2, 10)) + std::max(x(1, 10), x(2, 10))));
      EXPECT_TRUE((fromCodes.row(8).array() == 0.0f).all());
      EXPECT_TRUE((fromCodes.col(3).array() == 0.0f).all());  // the black image's red column
    }
  }
}

TEST_F(AbrdfSourceTest, ColumnSlicesNarrowOnlyForLargeMaterials) {
  EXPECT_EQ(columnSliceWidth(10000), kColumnSlice);      // 100 x 100: the slices PCA always used
  EXPECT_EQ(columnSliceWidth(131072), kColumnSlice);     // up to 256 MiB per slice
  EXPECT_EQ(columnSliceWidth(65536 * 4), 256);           // 512 x 512
  const Eigen::Index w = columnSliceWidth(640000);       // 800 x 800
  EXPECT_EQ(w % 16, 0);
  EXPECT_LE(w * 640000 * 4, Eigen::Index(256) << 20);
  EXPECT_GE(columnSliceWidth(100000000), 16);
}

TEST_F(AbrdfSourceTest, WorkingMemoryIsFarBelowTheMatrix) {
  // A full UBO2003 material, 256 x 256 texels x 6561 images, on 2 threads: tables + slices.
  const std::size_t bytes = StackAbrdfSource::workingBytes(65536, 6561, SampleType::Srgb8, 2);
  EXPECT_LT(bytes, std::size_t(600) << 20);
  EXPECT_GT(bytes, std::size_t(100) << 20);
  // 800 x 800: the column slices narrow, the working set stays under 1 GiB.
  EXPECT_LT(StackAbrdfSource::workingBytes(640000, 6561, SampleType::Srgb8, 2), std::size_t(1) << 30);
}

TEST_F(AbrdfSourceTest, RejectsStatisticsOfAnotherShape) {
  BtfStack stack = structuredStack(5, 4, 2, 2, SampleType::Srgb8, 5);
  Standardization s;
  s.mean = Eigen::VectorXf::Zero(5);
  s.stddev = Eigen::VectorXf::Ones(5);
  EXPECT_THROW(StackAbrdfSource(stack, s), Error);
}

}  // namespace
}  // namespace nbtf
