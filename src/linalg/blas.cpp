#include "linalg/blas.h"

#include <omp.h>

#include <climits>

#include "util/error.h"
#include "util/parallel.h"

// The Fortran BLAS entry point: present in every BLAS, so no particular header is needed.
extern "C" void sgemm_(const char* transa, const char* transb, const int* m, const int* n, const int* k,
                       const float* alpha, const float* a, const int* lda, const float* b, const int* ldb,
                       const float* beta, float* c, const int* ldc);

namespace nbtf {

namespace {

int checkedInt(Eigen::Index v, const char* what) {
  if (v > INT_MAX) throw Error(std::string("matrix product: ") + what + " exceeds the BLAS index range");
  return static_cast<int>(v);
}

// OpenBLAS (OpenMP build) takes its thread count from the calling thread's OpenMP
// setting. Set it for one call and put it back, so nobody else's setting changes.
class BlasThreads {
 public:
  explicit BlasThreads(int threads) : previous_(omp_get_max_threads()) { omp_set_num_threads(threads); }
  ~BlasThreads() { omp_set_num_threads(previous_); }

 private:
  int previous_;
};

void sgemm(bool transposeA, bool transposeB, int m, int n, int k, const float* a, int lda, const float* b, int ldb,
           float* c, int ldc, bool accumulate = false) {
  const float one = 1.0f, beta = accumulate ? 1.0f : 0.0f;
  const char ta = transposeA ? 'T' : 'N', tb = transposeB ? 'T' : 'N';
  sgemm_(&ta, &tb, &m, &n, &k, &one, a, &lda, b, &ldb, &beta, c, &ldc);
}

}  // namespace

void blasMultiply(const MatrixXfCol& a, bool transposeA, const MatrixXfCol& b, MatrixXfCol& c) {
  const Eigen::Index rows = transposeA ? a.cols() : a.rows();
  const Eigen::Index inner = transposeA ? a.rows() : a.cols();
  if (inner != b.rows()) throw Error("matrix product: inner dimensions differ");
  c.resize(rows, b.cols());
  if (rows == 0 || b.cols() == 0) return;
  if (inner == 0) {
    c.setZero();
    return;
  }
  const int n = checkedInt(b.cols(), "columns"), k = checkedInt(inner, "inner size");
  const int lda = checkedInt(std::max<Eigen::Index>(1, a.rows()), "leading dimension");
  const int ldb = checkedInt(std::max<Eigen::Index>(1, b.rows()), "leading dimension");
  const int ldc = checkedInt(rows, "rows");
  // Fixed slices of the result's rows, one single-threaded product each: every entry is
  // computed the same way whatever the thread count (OpenBLAS's own threading changes the
  // last bits with it), and the threads are nbtf's.
  const Eigen::Index slice = transposeA ? 512 : 1024;
  const Eigen::Index slices = (rows + slice - 1) / slice;
  parallelForDynamic(slices, [&](std::size_t s, int) {
    const Eigen::Index r0 = static_cast<Eigen::Index>(s) * slice;
    const int m = static_cast<int>(std::min(slice, rows - r0));
    // Rows r0.. of op(a): rows of a, or columns of a when transposed.
    const float* aSlice = transposeA ? a.data() + r0 * a.rows() : a.data() + r0;
    gemmOnThisThread(transposeA, false, m, n, k, aSlice, lda, b.data(), ldb, c.data() + r0, ldc);
  });
}

void gemmOnThisThread(bool transposeA, bool transposeB, int m, int n, int k, const float* a, int lda,
                      const float* b, int ldb, float* c, int ldc, bool accumulate) {
  if (m == 0 || n == 0) return;
  BlasThreads threads(1);
  sgemm(transposeA, transposeB, m, n, k, a, lda, b, ldb, c, ldc, accumulate);
}

}  // namespace nbtf
