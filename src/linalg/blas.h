// Large float products through the system BLAS. On Debian that is OpenBLAS (installed for
// libtorch by scripts/setup.sh, picked through the libblas.so.3 alternative): 2-4x the
// speed of Eigen's portable (SSE2) kernels, on the M x 3N ABRDF matrix (PCA) and on the
// point-centre products of k-means, and the PCA baseline's fit. Every stage from
// preprocess on may use it (its own library, nbtf_linalg, so the decoder never links BLAS).
#pragma once
#include <Eigen/Core>

namespace nbtf {

// Column-major float matrix (BLAS order); preprocess/abrdf_matrix.h holds the ABRDFs in it.
using MatrixXfCol = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor>;

// c = op(a) * b, op(a) = a or a^T; c is resized. Runs on threadCount() threads; the result
// does not depend on their number.
void blasMultiply(const MatrixXfCol& a, bool transposeA, const MatrixXfCol& b, MatrixXfCol& c);

// c = op(a) * op(b), column-major with BLAS conventions (m x n result, inner size k), on the
// calling thread only: for products inside parallelFor workers, where every worker runs
// its own, and whose result then does not depend on the thread count.
// accumulate: c += op(a) * op(b) instead.
void gemmOnThisThread(bool transposeA, bool transposeB, int m, int n, int k, const float* a, int lda,
                      const float* b, int ldb, float* c, int ldc, bool accumulate = false);

}  // namespace nbtf
