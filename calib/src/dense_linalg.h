// Internal: the dense products and factorisations that dominate identification with joint maps
// and the diagnosis: the Cholesky factorisation of the normal matrices (a few hundred to ~1,500
// unknowns: the Levenberg-Marquardt steps, the joint-map cross-validation, the covariance) and
// the normal matrix J^T J of a tall stacked Jacobian. LAPACK's dpotrf / dpotrs and BLAS's dsyrk
// from OpenBLAS, which picks its kernels for the processor it runs on (AVX2, AVX-512) where
// Eigen is compiled for the baseline x86-64 (SSE2): 2.5x faster at these sizes (bench/README.md).
// Thread safety: Debian's single-threaded OpenBLAS is not safe to call from two threads at once
// (it takes its work buffers from a table without a lock); every call here is made under one
// process-wide lock, so identification and diagnosis may run on several threads of the
// caller's. Results depend on the kernels OpenBLAS picks for the processor: equal across
// processors to the rounding, not to the last bit.
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

/// A += alpha J^T J on the lower triangle of the square A (J: any number of rows, A.rows()
/// columns); the strictly upper triangle is neither read nor written. Throws ArgumentError when
/// the sizes do not match.
void addGramLower(Eigen::Ref<Eigen::MatrixXd> A, const Eigen::Ref<const Eigen::MatrixXd>& J, double alpha = 1.0);

/// J^T J, both triangles (addGramLower on zeros, then mirrored).
Eigen::MatrixXd gram(const Eigen::Ref<const Eigen::MatrixXd>& J);

}  // namespace accura::calib::detail
