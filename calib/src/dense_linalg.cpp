// accura: dense Cholesky and J^T J by LAPACK and BLAS (dense_linalg.h).
#include "dense_linalg.h"

#include <algorithm>
#include <climits>
#include <cstddef>
#include <mutex>
#include <string>

#include "accura/calib/errors.h"

extern "C" {
// LAPACK (Fortran calling convention; OpenBLAS): the Cholesky factorisation and its solve
void dpotrf_(const char* uplo, const int* n, double* a, const int* lda, int* info);
void dpotrs_(const char* uplo, const int* n, const int* nrhs, const double* a, const int* lda, double* b, const int* ldb,
             int* info);
// BLAS: B = alpha B A^-T (A lower triangular: the panel below a factorised diagonal block)
void dtrsm_(const char* side, const char* uplo, const char* transa, const char* diag, const int* m, const int* n,
            const double* alpha, const double* a, const int* lda, double* b, const int* ldb);
// BLAS: C = alpha A^T A + beta C (or alpha A A^T + beta C) on one triangle of C
void dsyrk_(const char* uplo, const char* trans, const int* n, const int* k, const double* alpha, const double* a,
            const int* lda, const double* beta, double* c, const int* ldc);
}

namespace accura::calib::detail {

namespace {

// Debian's single-threaded OpenBLAS takes its work buffers from a table without a lock (its
// blas_memory_alloc locks only its one-time set-up): two threads calling it at once may share
// a buffer and corrupt each other's results (seen in a review: dsyrk from two threads, about 1
// result in 1000 wrong; the joint-map cross-validation on two threads, 1-2 % of the tables).
// Every call into it is made under this lock, so identification and diagnosis may run on
// several threads of the caller's (test Identify.DenseLinearAlgebraIsSafeOnSeveralThreads).
std::mutex& blasMutex() {
  static std::mutex m;
  return m;
}

int lapackSize(Eigen::Index v, const char* what) {
  if (v < 0 || v > INT_MAX)
    throw NumericalError(std::string("dense Cholesky: ") + what + " " + std::to_string(v) + " exceeds LAPACK's sizes");
  return static_cast<int>(v);
}

}  // namespace

bool choleskyInPlace(Eigen::Ref<Eigen::MatrixXd> A) {
  if (A.rows() != A.cols())
    throw ArgumentError("dense Cholesky: expected a square matrix, got " + std::to_string(A.rows()) + " x " +
                        std::to_string(A.cols()));
  const int n = lapackSize(A.rows(), "size"), lda = lapackSize(std::max<Eigen::Index>(A.outerStride(), 1), "stride");
  if (n == 0) return true;
  const char lower = 'L';
  int info = 0;
  const std::lock_guard<std::mutex> lock(blasMutex());
  // right-looking in blocks of kBlock columns: the diagonal block by dpotrf, the panel below it
  // by dtrsm, the trailing lower triangle by dsyrk. At the joint maps' sizes (n = 750 .. 1,500)
  // 20-25 % faster on one core than OpenBLAS' own dpotrf on the whole (Skylake-X, OpenBLAS
  // 0.3.21: n = 750 4.0 vs 3.1 ms, n = 1100 12.1 vs 9.6 ms); the factor equal to rounding.
  constexpr int kBlock = 64;
  double* a = A.data();
  for (int k = 0; k < n; k += kBlock) {
    const int b = std::min(kBlock, n - k), m = n - k - b;
    double* akk = a + static_cast<std::ptrdiff_t>(k) * lda + k;
    dpotrf_(&lower, &b, akk, &lda, &info);
    if (info != 0) return false;
    if (m == 0) break;
    const char right = 'R', transposed = 'T', no = 'N';
    const double one = 1.0, minus_one = -1.0;
    dtrsm_(&right, &lower, &transposed, &no, &m, &b, &one, akk, &lda, akk + b, &lda);
    dsyrk_(&lower, &no, &m, &b, &minus_one, akk + b, &lda, &one, akk + static_cast<std::ptrdiff_t>(b) * lda + b, &lda);
  }
  return true;
}

void choleskySolveInPlace(const Eigen::Ref<const Eigen::MatrixXd>& L, Eigen::Ref<Eigen::MatrixXd> B) {
  if (L.rows() != L.cols() || B.rows() != L.rows())
    throw ArgumentError("dense Cholesky solve: expected a square factor and " + std::to_string(L.rows()) +
                        " right-hand-side rows, got " + std::to_string(L.rows()) + " x " + std::to_string(L.cols()) +
                        " and " + std::to_string(B.rows()));
  const int n = lapackSize(L.rows(), "size"), nrhs = lapackSize(B.cols(), "right-hand sides");
  if (n == 0 || nrhs == 0) return;
  const int lda = lapackSize(std::max<Eigen::Index>(L.outerStride(), 1), "stride"),
            ldb = lapackSize(std::max<Eigen::Index>(B.outerStride(), 1), "stride");
  const char lower = 'L';
  int info = 0;
  {
    const std::lock_guard<std::mutex> lock(blasMutex());
    dpotrs_(&lower, &n, &nrhs, L.data(), &lda, B.data(), &ldb, &info);
  }
  if (info != 0) throw NumericalError("dense Cholesky solve: LAPACK dpotrs reported argument " + std::to_string(-info));
}

void addGramLower(Eigen::Ref<Eigen::MatrixXd> A, const Eigen::Ref<const Eigen::MatrixXd>& J, double alpha) {
  if (A.rows() != A.cols() || J.cols() != A.rows())
    throw ArgumentError("J^T J: expected a square matrix of J's " + std::to_string(J.cols()) + " columns, got " +
                        std::to_string(A.rows()) + " x " + std::to_string(A.cols()));
  const int n = lapackSize(A.rows(), "size"), k = lapackSize(J.rows(), "rows");
  if (n == 0 || k == 0) return;
  const int lda = lapackSize(std::max<Eigen::Index>(J.outerStride(), 1), "stride"),
            ldc = lapackSize(std::max<Eigen::Index>(A.outerStride(), 1), "stride");
  const char lower = 'L', transposed = 'T';
  const double one = 1.0;
  const std::lock_guard<std::mutex> lock(blasMutex());
  dsyrk_(&lower, &transposed, &n, &k, &alpha, J.data(), &lda, &one, A.data(), &ldc);
}

Eigen::MatrixXd gram(const Eigen::Ref<const Eigen::MatrixXd>& J) {
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(J.cols(), J.cols());
  addGramLower(G, J);
  G.triangularView<Eigen::StrictlyUpper>() = G.transpose();
  return G;
}

}  // namespace accura::calib::detail
