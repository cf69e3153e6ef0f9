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

/// One row block's J^T J scattered into the lower triangle of a larger matrix: N(idx[a],
/// idx[c]) += alpha sum_d Jt(a, d) Jt(c, d) for every pair a <= c, at the pair's larger index as the
/// row (N column-major with leading dimension ld). Jt: the row block's columns transposed (nc x
/// dim, column-major: component d of column a at Jt[a + d nc]); idx: the columns' indices in N,
/// distinct. The normal equations of joint maps are accumulated pose by pose with this (a pose
/// touches ~60 of ~1,000 columns).
template <int Dim>
inline void scatterGramLower(double* N, Eigen::Index ld, const double* Jt, Eigen::Index nc, const Eigen::Index* idx,
                             double alpha) {
  for (Eigen::Index a = 0; a < nc; ++a) {
    double xa[Dim];
    for (int d = 0; d < Dim; ++d) xa[d] = Jt[a + d * nc];
    const Eigen::Index ia = idx[a];
    for (Eigen::Index c = a; c < nc; ++c) {
      double v = Jt[c] * xa[0];
      for (int d = 1; d < Dim; ++d) v += Jt[c + d * nc] * xa[d];
      const Eigen::Index ic = idx[c];
      N[(ia < ic ? ia : ic) * ld + (ia < ic ? ic : ia)] += alpha * v;
    }
  }
}
inline void scatterGramLower(double* N, Eigen::Index ld, const double* Jt, Eigen::Index nc, int dim, const Eigen::Index* idx,
                             double alpha = 1.0) {
  if (dim == 3) return scatterGramLower<3>(N, ld, Jt, nc, idx, alpha);
  if (dim == 6) return scatterGramLower<6>(N, ld, Jt, nc, idx, alpha);
  for (Eigen::Index a = 0; a < nc; ++a)
    for (Eigen::Index c = a; c < nc; ++c) {
      double v = 0;
      for (int d = 0; d < dim; ++d) v += Jt[c + d * nc] * Jt[a + d * nc];
      const Eigen::Index ia = idx[a], ic = idx[c];
      N[(ia < ic ? ia : ic) * ld + (ia < ic ? ic : ia)] += alpha * v;
    }
}

}  // namespace accura::calib::detail
