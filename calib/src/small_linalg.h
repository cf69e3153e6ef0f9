// Internal: 6x6 LU with partial pivoting and the positive-definiteness test of a symmetric
// 6x6 matrix, written out for the IK's inner loop (several times fewer instructions than the
// generic dense decompositions at this size). Checked against Eigen in tests/test_ik.cpp.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <utility>

namespace accura::calib::detail {

/// A = P^T L U of a 6x6 matrix (Doolittle, partial pivoting).
class Lu6 {
 public:
  /// False when a pivot is zero or not finite (A singular to working precision).
  bool factor(const Eigen::Matrix<double, 6, 6>& A) {
#pragma GCC unroll 6
    for (int r = 0; r < 6; ++r)
#pragma GCC unroll 6
      for (int c = 0; c < 6; ++c) a_[r][c] = A(r, c);
#pragma GCC unroll 6
    for (int k = 0; k < 6; ++k) {
      int p = k;
      double best = std::abs(a_[k][k]);
      for (int r = k + 1; r < 6; ++r) {
        const double v = std::abs(a_[r][k]);
        if (v > best) {
          best = v;
          p = r;
        }
      }
      perm_[k] = p;
      if (!(best > 0) || !(best < 1e300)) return false;
      if (p != k) {
#pragma GCC unroll 6
        for (int c = 0; c < 6; ++c) std::swap(a_[k][c], a_[p][c]);
      }
      const double inv = 1.0 / a_[k][k];
      inv_[k] = inv;
      for (int r = k + 1; r < 6; ++r) {
        const double l = a_[r][k] * inv;
        a_[r][k] = l;
        for (int c = k + 1; c < 6; ++c) a_[r][c] -= l * a_[k][c];
      }
    }
    return true;
  }

  /// x = A^-1 b.
  Eigen::Matrix<double, 6, 1> solve(const Eigen::Matrix<double, 6, 1>& b) const {
    double y[6];
#pragma GCC unroll 6
    for (int i = 0; i < 6; ++i) y[i] = b[i];
#pragma GCC unroll 6
    for (int k = 0; k < 6; ++k)
      if (perm_[k] != k) std::swap(y[k], y[perm_[k]]);
#pragma GCC unroll 6
    for (int r = 1; r < 6; ++r)
      for (int c = 0; c < r; ++c) y[r] -= a_[r][c] * y[c];
    Eigen::Matrix<double, 6, 1> x;
#pragma GCC unroll 6
    for (int r = 5; r >= 0; --r) {
      double v = y[r];
      for (int c = r + 1; c < 6; ++c) v -= a_[r][c] * x[c];
      x[r] = v * inv_[r];
    }
    return x;
  }

 private:
  double a_[6][6] = {};
  double inv_[6] = {};
  int perm_[6] = {};
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
