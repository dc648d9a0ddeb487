#include "relight/compact/leading_eigenvectors.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "lightstage/errors.h"

namespace ls::relight {
namespace {

constexpr int kInverseIterations = 4;  // From a machine-precision eigenvalue, 1-2 suffice.
// Eigenvalues closer than this (relative to the matrix's norm) are one cluster: their vectors
// are orthogonalised against each other (LAPACK dstein's ORTOL).
constexpr double kClusterGap = 1e-3;

// T - mu I for the symmetric tridiagonal T, factored by Gaussian elimination with partial
// pivoting (LAPACK dgttrf): U has the diagonal d and two superdiagonals du, du2; l holds the
// multipliers and swapped[i] whether rows i and i + 1 were exchanged.
class ShiftedTridiagonal {
 public:
  ShiftedTridiagonal(const Eigen::VectorXd& diagonal, const Eigen::VectorXd& off, double mu,
                     double tiny)
      : n_(diagonal.size()),
        d_(diagonal.array() - mu),
        du_(off),
        du2_(Eigen::VectorXd::Zero(std::max<Eigen::Index>(n_ - 2, 0))),
        l_(off),
        swapped_(size_t(std::max<Eigen::Index>(n_ - 1, 0)), false) {
    for (Eigen::Index i = 0; i + 1 < n_; ++i) {
      if (std::abs(d_(i)) >= std::abs(l_(i))) {
        if (d_(i) == 0) d_(i) = tiny;
        const double factor = l_(i) / d_(i);
        l_(i) = factor;
        d_(i + 1) -= factor * du_(i);
      } else {
        const double factor = d_(i) / l_(i);
        d_(i) = l_(i);
        l_(i) = factor;
        const double upper = du_(i);
        du_(i) = d_(i + 1);
        d_(i + 1) = upper - factor * d_(i + 1);
        if (i + 2 < n_) {
          du2_(i) = du_(i + 1);
          du_(i + 1) = -factor * du_(i + 1);
        }
        swapped_[size_t(i)] = true;
      }
    }
    for (Eigen::Index i = 0; i < n_; ++i) {
      if (std::abs(d_(i)) < tiny) d_(i) = d_(i) < 0 ? -tiny : tiny;  // Singular: mu is exact.
    }
  }

  // x <- (T - mu I)^-1 x.
  void solve(Eigen::VectorXd& x) const {
    for (Eigen::Index i = 0; i + 1 < n_; ++i) {
      if (swapped_[size_t(i)]) {
        const double xi = x(i);
        x(i) = x(i + 1);
        x(i + 1) = xi - l_(i) * x(i);
      } else {
        x(i + 1) -= l_(i) * x(i);
      }
    }
    for (Eigen::Index i = n_ - 1; i >= 0; --i) {
      double sum = x(i);
      if (i + 1 < n_) sum -= du_(i) * x(i + 1);
      if (i + 2 < n_) sum -= du2_(i) * x(i + 2);
      x(i) = sum / d_(i);
    }
  }

 private:
  Eigen::Index n_;
  Eigen::VectorXd d_, du_, du2_, l_;
  std::vector<bool> swapped_;
};

}  // namespace

LeadingEigen leading_eigenvectors(const Eigen::MatrixXd& matrix, int count) {
  const Eigen::Index n = matrix.rows();
  LS_CHECK(matrix.cols() == n && count >= 0 && count <= n,
           "leading_eigenvectors: " + std::to_string(count) + " of a " + std::to_string(n) + "x" +
               std::to_string(matrix.cols()) + " matrix");
  LeadingEigen out{Eigen::VectorXd(count), Eigen::MatrixXd(n, count)};
  if (count == 0) return out;
  const Eigen::Tridiagonalization<Eigen::MatrixXd> tridiagonal(matrix);
  const Eigen::VectorXd diagonal = tridiagonal.diagonal();
  const Eigen::VectorXd off = tridiagonal.subDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> values;
  values.computeFromTridiagonal(diagonal, off, Eigen::EigenvaluesOnly);
  LS_CHECK(values.info() == Eigen::Success, "leading_eigenvectors: the QR sweeps did not converge");
  double norm = diagonal.cwiseAbs().maxCoeff();
  if (n > 1) norm += 2 * off.cwiseAbs().maxCoeff();
  const double eps = std::numeric_limits<double>::epsilon();
  const double tiny = std::max(eps * norm, std::numeric_limits<double>::min());
  Eigen::MatrixXd on_tridiagonal(n, count);
  double previous_mu = 0;
  int cluster_start = 0;
  for (int j = 0; j < count; ++j) {
    const double lambda = values.eigenvalues()(n - 1 - j);
    out.values(j) = lambda;
    // Within a cluster each shift steps down a little from the last (dstein), so that no two
    // vectors start from one factorisation.
    double mu = lambda;
    if (j > 0 && out.values(j - 1) - lambda > kClusterGap * norm) cluster_start = j;
    if (j > cluster_start && previous_mu - mu < 10 * eps * norm) mu = previous_mu - 10 * eps * norm;
    previous_mu = mu;
    const ShiftedTridiagonal shifted(diagonal, off, mu, tiny);
    Eigen::VectorXd x(n);
    for (Eigen::Index i = 0; i < n; ++i) {  // A fixed start with a part along every vector.
      x(i) = 1 + 0.5 * std::sin(double(i + 1) * (j + 1.618));
    }
    const auto orthogonalise = [&](Eigen::VectorXd& v) {
      for (int k = cluster_start; k < j; ++k)
        v -= on_tridiagonal.col(k).dot(v) * on_tridiagonal.col(k);
      return v.norm();
    };
    for (int it = 0; it < kInverseIterations; ++it) {
      shifted.solve(x);
      const double length = orthogonalise(x);
      if (length > 0 && std::isfinite(length)) {
        x /= length;
        continue;
      }
      // Nothing left of the start (a zero or overflowing matrix): the first axis not yet spanned.
      for (Eigen::Index i = 0; i < n; ++i) {
        x = Eigen::VectorXd::Unit(n, i);
        if (orthogonalise(x) > 0.5) break;
      }
      x.normalize();
      break;
    }
    on_tridiagonal.col(j) = x;
  }
  out.vectors = tridiagonal.matrixQ() * on_tridiagonal;
  return out;
}

}  // namespace ls::relight
