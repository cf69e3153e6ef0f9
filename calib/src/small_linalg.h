// Internal: 6x6 LU with partial pivoting, a 6x6 solve in 3x3 blocks, and the
// positive-definiteness test of a symmetric 6x6 matrix, written out for the IK's inner loop
// (several times fewer instructions than the generic dense decompositions at this size). Checked against Eigen in tests/test_ik.cpp.
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

/// A x = b for a 6x6 matrix in 3x3 blocks [P Q; R S] without pivoting: with the inverse of S
/// and of the Schur complement T = P - Q S^-1 R (both by their adjugates),
///   x1 = T^-1 (b1 - Q S^-1 b2),  x2 = S^-1 (b2 - R x1).
/// Two divisions and no indexing by pivot rows: about a quarter of Lu6's instructions and a
/// much shorter chain of dependent operations. For the IK's Jacobian (rows [dp; dphi],
/// columns per joint) S is the wrist axes' rotation block and T the position block of the
/// first three joints at the wrist point. factor() refuses (the caller then takes Lu6) unless
/// both S and T are well conditioned in the sense of Hadamard's ratio
/// |det M| / (|m_0| |m_1| |m_2|) >= kMinRatio (m_j the columns; 1 for orthogonal columns,
/// 0 when singular; scale-invariant per column), so the blocks' rounding errors stay within
/// a few hundred ulps of the pivoted LU's.
class Block6 {
 public:
  static constexpr double kMinRatio = 1e-2;

  /// The 6x6 matrix stored column by column at `a`. False when S or T is ill conditioned
  /// (Hadamard ratio below kMinRatio) or not finite.
  bool factor(const double* a) {
    double P[3][3], Q[3][3], S[3][3];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        P[i][j] = a[6 * j + i];
        Q[i][j] = a[6 * (j + 3) + i];
        r_[i][j] = a[6 * j + i + 3];
        S[i][j] = a[6 * (j + 3) + i + 3];
      }
    double det_s = 0, det_t = 0;
    if (!inverse3(S, si_, det_s)) return false;
    // W = Q S^-1, T = P - W R
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) w_[i][j] = Q[i][0] * si_[0][j] + Q[i][1] * si_[1][j] + Q[i][2] * si_[2][j];
    double T[3][3];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) T[i][j] = P[i][j] - (w_[i][0] * r_[0][j] + w_[i][1] * r_[1][j] + w_[i][2] * r_[2][j]);
    if (!inverse3(T, ti_, det_t)) return false;
    det_ = det_s * det_t;  // det [P Q; R S] = det(S) det(P - Q S^-1 R)
    return true;
  }

  /// The matrix's determinant (after a factor() that returned true).
  double determinant() const { return det_; }

  /// x = A^-1 b.
  Eigen::Matrix<double, 6, 1> solve(const Eigen::Matrix<double, 6, 1>& b) const {
    double c[3], x1[3], d[3];
    for (int i = 0; i < 3; ++i) c[i] = b[i] - (w_[i][0] * b[3] + w_[i][1] * b[4] + w_[i][2] * b[5]);
    for (int i = 0; i < 3; ++i) x1[i] = ti_[i][0] * c[0] + ti_[i][1] * c[1] + ti_[i][2] * c[2];
    for (int i = 0; i < 3; ++i) d[i] = b[i + 3] - (r_[i][0] * x1[0] + r_[i][1] * x1[1] + r_[i][2] * x1[2]);
    Eigen::Matrix<double, 6, 1> x;
    for (int i = 0; i < 3; ++i) {
      x[i] = x1[i];
      x[i + 3] = si_[i][0] * d[0] + si_[i][1] * d[1] + si_[i][2] * d[2];
    }
    return x;
  }

 private:
  /// inv = m^-1 by the adjugate; false when Hadamard's ratio is below kMinRatio.
  static bool inverse3(const double (&m)[3][3], double (&inv)[3][3], double& det_out) {
    const double c00 = m[1][1] * m[2][2] - m[1][2] * m[2][1];
    const double c01 = m[1][2] * m[2][0] - m[1][0] * m[2][2];
    const double c02 = m[1][0] * m[2][1] - m[1][1] * m[2][0];
    const double det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02;
    double n[3];
    for (int j = 0; j < 3; ++j) n[j] = m[0][j] * m[0][j] + m[1][j] * m[1][j] + m[2][j] * m[2][j];
    // det^2 >= kMinRatio^2 |m_0|^2 |m_1|^2 |m_2|^2 (false for NaN)
    if (!(det * det >= kMinRatio * kMinRatio * (n[0] * n[1] * n[2])) || !(std::abs(det) < 1e300) || det == 0)
      return false;
    det_out = det;
    const double id = 1.0 / det;
    inv[0][0] = c00 * id;
    inv[1][0] = c01 * id;
    inv[2][0] = c02 * id;
    inv[0][1] = (m[0][2] * m[2][1] - m[0][1] * m[2][2]) * id;
    inv[1][1] = (m[0][0] * m[2][2] - m[0][2] * m[2][0]) * id;
    inv[2][1] = (m[0][1] * m[2][0] - m[0][0] * m[2][1]) * id;
    inv[0][2] = (m[0][1] * m[1][2] - m[0][2] * m[1][1]) * id;
    inv[1][2] = (m[0][2] * m[1][0] - m[0][0] * m[1][2]) * id;
    inv[2][2] = (m[0][0] * m[1][1] - m[0][1] * m[1][0]) * id;
    return true;
  }

  // (not initialised: factor() writes every entry solve() reads)
  double r_[3][3];   ///< the bottom left block R
  double si_[3][3];  ///< S^-1
  double w_[3][3];   ///< Q S^-1
  double ti_[3][3];  ///< T^-1
  double det_;       ///< det(S) det(T)
};

/// Is the symmetric 6x6 matrix G positive definite? (L D L^T without square roots: every
/// pivot d_j > 0; only the lower triangle is read.) Pivot after pivot: each division waits
/// for the one before.
inline bool positiveDefiniteLdl6(const Eigen::Matrix<double, 6, 6>& G) {
  double l[6][6];  // l[i][k] * d[k] for k < i (the scaled lower factor)
  double inv[6];
#pragma GCC unroll 6
  for (int j = 0; j < 6; ++j) {
    double dj = G(j, j);
    for (int k = 0; k < j; ++k) dj -= l[j][k] * l[j][k] * inv[k];
    if (!(dj > 0)) return false;
    inv[j] = 1.0 / dj;
    for (int i = j + 1; i < 6; ++i) {
      double v = G(i, j);
      for (int k = 0; k < j; ++k) v -= l[i][k] * l[j][k] * inv[k];
      l[i][j] = v;  // = L(i, j) d_j
    }
  }
  return true;
}

/// Is the symmetric 6x6 matrix G positive definite? Only the lower triangle is read; a NaN
/// entry gives false.
///
/// First without a chain of divisions (the common case, a well-conditioned G, then has a short
/// dependency chain), on G' = D^-1/2 G D^-1/2, D = diag(G) (the same answer: a congruence;
/// unit diagonal, so every entry of a positive definite G' lies in [-1, 1]): Sylvester's
/// criterion in 3x3 blocks, G' = [G11 G21^T; G21 G22] positive definite when G11 is and so is
/// its Schur complement S = G22 - G21 G11^-1 G21^T; with G11's adjugate,
/// H = det(G11) S = det(G11) G22 - G21 adj(G11) G21^T, each block by its three leading minors.
/// Taken only where every |G'(i, j)| <= 1 (necessary for positive definiteness): the products
/// then stay below about 5e5 in size and their rounding below 1e-10 (below 1e-13 for a positive
/// definite G'), so an answer "positive definite" with every minor above kClear = 1e-8 is the
/// exact one. Everywhere else
/// (near the boundary, or not positive definite) positiveDefiniteLdl6 decides.
inline bool positiveDefinite6(const Eigen::Matrix<double, 6, 6>& G) {
  double r[6];  // D^-1/2 (independent of each other: no chain)
  bool diagonal_positive = true;
  for (int i = 0; i < 6; ++i) {
    diagonal_positive &= G(i, i) > 0;
    r[i] = 1.0 / std::sqrt(G(i, i));
  }
  if (!diagonal_positive) return false;
  const auto g = [&](int i, int j) { return G(i, j) * r[i] * r[j]; };
  // G11 = [1 b c; b 1 e; c e 1] and its adjugate (symmetric)
  const double b = g(1, 0), c = g(2, 0), e = g(2, 1);
  // |G'(i, j)| <= 1 (necessary for positive definiteness): bounds every product below
  double largest = std::max(std::abs(b), std::max(std::abs(c), std::abs(e)));
  const double j00 = 1 - e * e, j01 = c * e - b, j02 = b * e - c;
  const double j11 = 1 - c * c, j12 = b * c - e, j22 = 1 - b * b;
  const double det = j00 + b * j01 + c * j02;
  double l[3][3];  // G21
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) {
      l[i][k] = g(3 + i, k);
      largest = std::max(largest, std::abs(l[i][k]));
    }
  // X = adj(G11) G21^T (3x3): X(k, m) = sum_n adj(k, n) G21(m, n)
  const double adj[3][3] = {{j00, j01, j02}, {j01, j11, j12}, {j02, j12, j22}};
  double x[3][3];
  for (int k = 0; k < 3; ++k)
    for (int m = 0; m < 3; ++m) x[k][m] = adj[k][0] * l[m][0] + adj[k][1] * l[m][1] + adj[k][2] * l[m][2];
  // H = det G22 - G21 X (lower triangle; G22's diagonal is 1)
  const auto h = [&](int i, int m, double g22) {
    return det * g22 - (l[i][0] * x[0][m] + l[i][1] * x[1][m] + l[i][2] * x[2][m]);
  };
  const double h00 = h(0, 0, 1), h10 = h(1, 0, g(4, 3)), h11 = h(1, 1, 1), h20 = h(2, 0, g(5, 3)),
               h21 = h(2, 1, g(5, 4)), h22 = h(2, 2, 1);  // (below: |G22'(i, j)| <= 1 too)
  const double k00 = h11 * h22 - h21 * h21, k01 = h20 * h21 - h10 * h22, k02 = h10 * h21 - h20 * h11;
  const double det_h = h00 * k00 + h10 * k01 + h20 * k02;
  constexpr double kClear = 1e-8;
  const double g43 = g(4, 3), g53 = g(5, 3), g54 = g(5, 4);
  const bool bounded = largest <= 1 && std::abs(g43) <= 1 && std::abs(g53) <= 1 && std::abs(g54) <= 1;
  const bool clearly = bounded & (j22 > kClear) & (det > kClear) & (h00 > kClear) & (h00 * h11 - h10 * h10 > kClear) &
                       (det_h > kClear);
  return clearly || positiveDefiniteLdl6(G);
}

}  // namespace accura::calib::detail
