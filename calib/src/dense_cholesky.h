// Internal: the dense Cholesky factorisation of the large normal matrices of identification
// with joint maps (a few hundred to ~1,500 unknowns: the Levenberg-Marquardt steps, the
// joint-map cross-validation, the covariance). LAPACK's dpotrf / dpotrs from OpenBLAS, which
// picks its kernels for the processor it runs on (AVX2, AVX-512) where Eigen's blocked LLT is
// compiled for the baseline x86-64 (SSE2): 2.5x faster at these sizes (bench/README.md).
#pragma once

#include <Eigen/Core>

namespace accura::calib::detail {

/// Factorises the symmetric positive definite A = L L^T in place: L is written into the lower
/// triangle (read from there: the strictly upper triangle is neither read nor written). False
/// when A is not positive definite to working precision (the lower triangle is then partly
/// overwritten). Throws NumericalError for a matrix too large for LAPACK's 32-bit sizes.
bool choleskyInPlace(Eigen::Ref<Eigen::MatrixXd> A);

/// Solves L L^T X = B in place (B: n rows, any number of columns) with the factor that
/// choleskyInPlace left in the lower triangle of L.
void choleskySolveInPlace(const Eigen::Ref<const Eigen::MatrixXd>& L, Eigen::Ref<Eigen::MatrixXd> B);

}  // namespace accura::calib::detail
