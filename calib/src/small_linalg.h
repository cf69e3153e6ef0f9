// Internal: 6x6 LU with partial pivoting and the positive-definiteness test of a symmetric
// 6x6 matrix, written out for the IK's inner loop (several times fewer instructions than the
// generic dense decompositions at this size). Checked against Eigen in tests/test_ik.cpp.
#pragma once

#include <Eigen/Core>
#include <cmath>

namespace accura::calib::detail {

/// A = P^T L U of a 6x6 matrix (Doolittle, partial pivoting). The rows are not moved: `row_`
/// records which row of A is the i-th pivot row (the same numbers as swapping them, without
/// the stores a swap of rows chosen at run time costs).
class Lu6 {
 public:
  /// False when a pivot is zero or not finite (A singular to working precision).
  bool factor(const Eigen::Matrix<double, 6, 6>& A) { return factor(A.data()); }
  /// The same for the 6x6 matrix stored column by column at `a` (Eigen's default order).
  bool factor(const double* a) {
#pragma GCC unroll 6
    for (int r = 0; r < 6; ++r) {
      row_[r] = r;
#pragma GCC unroll 6
      for (int c = 0; c < 6; ++c) m_[r][c] = a[6 * c + r];
    }
#pragma GCC unroll 6
    for (int k = 0; k < 6; ++k) {
      // the pivot search without branches (which row wins is data: a branch mispredicts)
      int p = k;
      double best = std::abs(m_[row_[k]][k]);
      for (int i = k + 1; i < 6; ++i) {
        const double v = std::abs(m_[row_[i]][k]);
        const bool larger = v > best;
        best = larger ? v : best;
        p = larger ? i : p;
      }
      if (!(best > 0) || !(best < 1e300)) return false;
      const int rk = row_[p];
      row_[p] = row_[k];
      row_[k] = rk;
      const double inv = 1.0 / m_[rk][k];
      inv_[k] = inv;
      for (int i = k + 1; i < 6; ++i) {
        double* ri = m_[row_[i]];
        const double l = ri[k] * inv;
        ri[k] = l;
        for (int c = k + 1; c < 6; ++c) ri[c] -= l * m_[rk][c];
      }
    }
    return true;
  }

  /// x = A^-1 b.
  Eigen::Matrix<double, 6, 1> solve(const Eigen::Matrix<double, 6, 1>& b) const {
    double y[6];
#pragma GCC unroll 6
    for (int i = 0; i < 6; ++i) y[i] = b[row_[i]];
#pragma GCC unroll 6
    for (int r = 1; r < 6; ++r) {
      const double* mr = m_[row_[r]];
      for (int c = 0; c < r; ++c) y[r] -= mr[c] * y[c];
    }
    Eigen::Matrix<double, 6, 1> x;
#pragma GCC unroll 6
    for (int r = 5; r >= 0; --r) {
      const double* mr = m_[row_[r]];
      double v = y[r];
      for (int c = r + 1; c < 6; ++c) v -= mr[c] * x[c];
      x[r] = v * inv_[r];
    }
    return x;
  }

 private:
  // (not initialised: factor() writes every entry solve() reads)
  double m_[6][6];  ///< A's rows in place: L below the diagonal, U on and above (row row_[i])
  double inv_[6];   ///< 1 / U(i, i)
  int row_[6];
};

/// Is the symmetric 6x6 matrix G positive definite? (L D L^T without square roots: every
/// pivot d_j > 0; only the lower triangle is read.)
inline bool positiveDefinite6(const Eigen::Matrix<double, 6, 6>& G) {
  double l[6][6];  // l[i][k] * d[k] for k < i (the scaled lower factor)
  double d[6], inv[6];
#pragma GCC unroll 6
  for (int j = 0; j < 6; ++j) {
    double dj = G(j, j);
    for (int k = 0; k < j; ++k) dj -= l[j][k] * l[j][k] * inv[k];
    if (!(dj > 0)) return false;
    d[j] = dj;
    inv[j] = 1.0 / dj;
    for (int i = j + 1; i < 6; ++i) {
      double v = G(i, j);
      for (int k = 0; k < j; ++k) v -= l[i][k] * l[j][k] * inv[k];
      l[i][j] = v;  // = L(i, j) d_j
    }
  }
  (void)d;
  return true;
}

}  // namespace accura::calib::detail
