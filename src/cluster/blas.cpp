#include "cluster/blas.h"

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
  const int m = checkedInt(rows, "rows"), n = checkedInt(b.cols(), "columns"), k = checkedInt(inner, "inner size");
  const int lda = checkedInt(std::max<Eigen::Index>(1, a.rows()), "leading dimension");
  const int ldb = checkedInt(std::max<Eigen::Index>(1, b.rows()), "leading dimension");
  const int ldc = m;
  const float one = 1.0f, zero = 0.0f;
  const char ta = transposeA ? 'T' : 'N', tb = 'N';
  // OpenBLAS (OpenMP build) takes its thread count from the calling thread's OpenMP
  // setting: follow --threads, and leave the setting as it was for anyone else.
  const int previous = omp_get_max_threads();
  omp_set_num_threads(threadCount());
  sgemm_(&ta, &tb, &m, &n, &k, &one, a.data(), &lda, b.data(), &ldb, &zero, c.data(), &ldc);
  omp_set_num_threads(previous);
}

}  // namespace nbtf
