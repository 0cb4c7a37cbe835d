// The standardized ABRDF matrix X (M texels x 3N dimensions, preprocess/abrdf_matrix.h) as a
// source of blocks, so that PCA, the column statistics and the cluster representatives never
// need all of X at once.
//
// Two kinds of block, each exactly what the in-memory X holds there:
//   - column slices: columns [c0, c1) over all M texels (column-major, leading dimension M);
//   - row slices: texels [r0, r1) over all 3N dimensions (column-major, leading dimension r1 - r0).
// DenseAbrdfSource wraps an in-memory X (blocks are pointers into it); StackAbrdfSource makes
// them on demand from the 8-bit (or half) stack: an 8-bit stack through one 256-entry table per
// dimension (the standardized value of every byte), a half stack value by value. The same code
// (cluster/pca.cpp, cluster/clustering.cpp) runs on either, and gets the same bits: column slices
// are laid out at the addresses modulo the SIMD width that X gives them, because Eigen's
// vectorized sums depend on them.
//
// Memory of StackAbrdfSource: per worker thread one column slice (M x columnSliceWidth(M)
// floats, at most 256 MiB) and one row slice (kRowSlice x 3N floats, 80 MB for a full
// UBO2003 material), plus the tables (3N x 256 floats, 20 MB): never the 4 x M x 3N bytes of X.
#pragma once
#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "preprocess/abrdf_matrix.h"

namespace nbtf {

// Rows per row slice, and the widest column slice: the slices the BLAS products of PCA have
// always used (linalg/blas.cpp), so results do not depend on where the data comes from.
constexpr Eigen::Index kRowSlice = 1024;
constexpr Eigen::Index kColumnSlice = 512;
// Columns per column slice for M texels: kColumnSlice, fewer (a multiple of 16, at least 16)
// when M x kColumnSlice floats would pass 256 MiB (more than 131,072 texels). A function of
// M only: results never depend on the thread count.
Eigen::Index columnSliceWidth(Eigen::Index rows);

class AbrdfSource {
 public:
  virtual ~AbrdfSource() = default;
  virtual Eigen::Index rows() const = 0;  // M texels
  virtual Eigen::Index cols() const = 0;  // D = 3 x images

  // visit(c0, c1, data): data holds columns [c0, c1), column j - c0 at data + (j - c0) x rows().
  // Slices of columnSliceWidth(rows()) columns, in parallel (each visit on one thread, any
  // order); `label`: a progress bar in columns (empty: none).
  using ColumnVisit = std::function<void(Eigen::Index c0, Eigen::Index c1, const float* data)>;
  void forEachColumnSlice(const ColumnVisit& visit, const std::string& label = "") const;
  // visit(r0, r1, data, ld): texels [r0, r1) of every column, entry (t, d) at data[d x ld + t - r0].
  // Slices of kRowSlice texels, in parallel; `label`: a progress bar in texels (empty: none).
  using RowVisit = std::function<void(Eigen::Index r0, Eigen::Index r1, const float* data, Eigen::Index ld)>;
  void forEachRowSlice(const RowVisit& visit, const std::string& label = "") const;
  // Rows `texels` (increasing, each once) of X, in memory: texels.size() x cols(), the values
  // the row slices hold. A stack reads only these texels of each image (a computed stack
  // computes only them): a sample costs its own size, not a pass over X. In parallel over runs
  // of texels; `label`: a progress bar in texels (empty: none).
  MatrixXfCol gatherRows(const std::vector<Eigen::Index>& texels, const std::string& label = "") const;

  // Bytes of working memory the slices take on `workers` threads (0 for an in-memory X).
  virtual std::size_t sliceBytes(int /*workers*/) const { return 0; }
  // The columns' moments when known without a pass over X (PCA then skips its first pass).
  virtual const ColumnMoments* knownMoments() const { return nullptr; }

  // Sources whose values are one of 256 per column (an 8-bit stack) visit their images, each
  // once, in parallel: visit(image, bytes, tables, worker), bytes the image's M x 3 interleaved
  // codes, column 3 x image + c of texel t holding tables[256 c + bytes[3 t + c]] (each table
  // never falls as the byte rises), worker the thread's index below threadCount(); `label`: a
  // progress bar in columns (empty: none). Others return false and visit nothing.
  using CodedImageVisit =
      std::function<void(Eigen::Index image, const std::uint8_t* bytes, const float* tables, int worker)>;
  virtual bool forEachCodedImage(const CodedImageVisit& /*visit*/, const std::string& /*label*/ = "") const {
    return false;
  }

 protected:
  // An in-memory X returns its data (column-major, leading dimension rows()); others nullptr
  // and fill blocks on demand.
  virtual const float* dense() const { return nullptr; }
  // Columns [c0, c1) into out (leading dimension rows()).
  virtual void fillColumns(Eigen::Index c0, Eigen::Index c1, float* out) const;
  // Texels [r0, r1) into out (leading dimension r1 - r0).
  virtual void fillRows(Eigen::Index r0, Eigen::Index r1, float* out) const;
  // Texels texels[0, n) (increasing) into out, entry (k, d) at out[d x ld + k]; a stack's
  // fillRows is this over the slice's texels.
  virtual void fillTexels(const Eigen::Index* texels, Eigen::Index n, float* out, Eigen::Index ld) const;
};

class DenseAbrdfSource : public AbrdfSource {
 public:
  explicit DenseAbrdfSource(const MatrixXfCol& x) : x_(x) {}
  Eigen::Index rows() const override { return x_.rows(); }
  Eigen::Index cols() const override { return x_.cols(); }

 protected:
  const float* dense() const override { return x_.data(); }

 private:
  const MatrixXfCol& x_;
};

// The standardized log ABRDFs of a stack, made on demand, or (StackAbrdfSource::linear) its
// linear ABRDFs divided by alpha: the space the error is measured in, where clusters follow the
// highlights rather than the diffuse colour (docs/clustering.md, *Clustering space*). Keeps a
// reference to the stack.
class StackAbrdfSource : public AbrdfSource {
 public:
  // `moments`: those of the standardized columns (fitStandardization), or empty.
  StackAbrdfSource(const BtfStack& stack, Standardization standardization, ColumnMoments moments = {});
  // Linear values / alpha (alpha > 0, eq. 5): one 256-entry table for every dimension of an
  // 8-bit stack; standardization() is empty and no moments are known.
  static StackAbrdfSource linear(const BtfStack& stack, float alpha);
  bool isLinear() const { return alpha_ > 0; }
  Eigen::Index rows() const override { return stack_.numTexels(); }
  Eigen::Index cols() const override { return 3 * static_cast<Eigen::Index>(stack_.numImages()); }
  const Standardization& standardization() const { return s_; }
  std::size_t sliceBytes(int workers) const override;
  const ColumnMoments* knownMoments() const override { return moments_.mean.size() == cols() ? &moments_ : nullptr; }
  bool forEachCodedImage(const CodedImageVisit& visit, const std::string& label = "") const override;
  // Working memory for a stack of this shape (tables + per-worker slices), before it exists.
  static std::size_t workingBytes(std::int64_t texels, int images, SampleType type, int workers);

 protected:
  void fillColumns(Eigen::Index c0, Eigen::Index c1, float* out) const override;
  void fillRows(Eigen::Index r0, Eigen::Index r1, float* out) const override;
  void fillTexels(const Eigen::Index* texels, Eigen::Index n, float* out, Eigen::Index ld) const override;

 private:
  StackAbrdfSource(const BtfStack& stack, float alpha);
  const float* table(Eigen::Index d) const {
    return isLinear() ? table_.data() : &table_[static_cast<std::size_t>(d) * 256];
  }
  void transformRun(float* values, Eigen::Index n, Eigen::Index d) const;  // linear -> this source's values

  const BtfStack& stack_;
  Standardization s_;
  ColumnMoments moments_;
  float alpha_ = 0;  // > 0: the linear source
  // 8-bit stacks: the value of each byte, D x 256 (dimension-major; the standardized log
  // source) or one 256-entry table shared by every dimension (the linear source).
  std::vector<float> table_;
};

}  // namespace nbtf
