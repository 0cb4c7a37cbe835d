// Large float products through the system BLAS. On Debian that is OpenBLAS (installed for
// libtorch by scripts/setup.sh, picked through the libblas.so.3 alternative): 2-3x the
// speed of Eigen's portable (SSE2) kernels on the M x 3N ABRDF matrix, which is what
// PCA's cost is made of. Internal to the cluster stage.
#pragma once
#include "preprocess/abrdf_matrix.h"

namespace nbtf {

// c = op(a) * b, op(a) = a or a^T; c is resized. Runs on threadCount() threads.
void blasMultiply(const MatrixXfCol& a, bool transposeA, const MatrixXfCol& b, MatrixXfCol& c);

}  // namespace nbtf
