// The leading eigenvectors against Eigen's full solver: values, vectors (up to sign), residuals
// and orthogonality, on covariance-like spectra, a repeated eigenvalue and a tiny matrix.
#include "relight/compact/leading_eigenvectors.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>

namespace ls::relight {
namespace {

// Q diag(values) Q^T with a random orthogonal Q (fixed seed).
Eigen::MatrixXd with_spectrum(const Eigen::VectorXd& values, unsigned seed) {
  std::srand(seed);
  const Eigen::MatrixXd random = Eigen::MatrixXd::Random(values.size(), values.size());
  const Eigen::MatrixXd q = Eigen::HouseholderQR<Eigen::MatrixXd>(random).householderQ();
  return q * values.asDiagonal() * q.transpose();
}

// Every vector an eigenvector (residual at rounding level), the set orthonormal.
void expect_eigenpairs(const Eigen::MatrixXd& a, const LeadingEigen& found) {
  const double norm = a.norm();
  for (Eigen::Index j = 0; j < found.vectors.cols(); ++j) {
    const Eigen::VectorXd v = found.vectors.col(j);
    EXPECT_LE((a * v - found.values(j) * v).norm(), 1e-10 * norm) << "vector " << j;
  }
  const Eigen::MatrixXd gram = found.vectors.transpose() * found.vectors;
  EXPECT_LT((gram - Eigen::MatrixXd::Identity(gram.rows(), gram.cols())).cwiseAbs().maxCoeff(),
            1e-10);
}

TEST(LeadingEigenvectors, MatchTheFullSolverOnADecayingSpectrum) {
  // As an RTI covariance: eigenvalues falling geometrically over 300 dimensions.
  const int n = 300, count = 30;
  Eigen::VectorXd values(n);
  for (int i = 0; i < n; ++i) values(i) = std::pow(0.8, i);
  const Eigen::MatrixXd a = with_spectrum(values, 7);
  const LeadingEigen found = leading_eigenvectors(a, count);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> full(a);
  ASSERT_EQ(found.vectors.rows(), n);
  ASSERT_EQ(found.vectors.cols(), count);
  for (int j = 0; j < count; ++j) {
    EXPECT_NEAR(found.values(j), full.eigenvalues()(n - 1 - j), 1e-12) << j;
    // The same direction (the sign is either): |cos| = 1 to rounding for separated values.
    EXPECT_NEAR(std::abs(found.vectors.col(j).dot(full.eigenvectors().col(n - 1 - j))), 1.0, 1e-9)
        << j;
  }
  expect_eigenpairs(a, found);
}

TEST(LeadingEigenvectors, ARepeatedEigenvalueGivesAnOrthonormalBasisOfItsSpace) {
  // The second largest value three times, then a cluster closer than the cluster gap.
  Eigen::VectorXd values = Eigen::VectorXd::LinSpaced(80, 0.01, 0.5);
  values.head(6) << 4.0, 2.0, 2.0, 2.0, 1.0 + 1e-9, 1.0;
  const Eigen::MatrixXd a = with_spectrum(values, 11);
  const LeadingEigen found = leading_eigenvectors(a, 6);
  const double expected[6] = {4.0, 2.0, 2.0, 2.0, 1.0 + 1e-9, 1.0};
  for (int j = 0; j < 6; ++j) EXPECT_NEAR(found.values(j), expected[j], 1e-12) << j;
  expect_eigenpairs(a, found);
}

TEST(LeadingEigenvectors, SmallAndDegenerateSizes) {
  const Eigen::MatrixXd one = Eigen::MatrixXd::Constant(1, 1, 3.0);
  const LeadingEigen single = leading_eigenvectors(one, 1);
  EXPECT_DOUBLE_EQ(single.values(0), 3.0);
  EXPECT_DOUBLE_EQ(std::abs(single.vectors(0, 0)), 1.0);
  // Rank one: the leading vector, then any unit vectors orthogonal to it.
  Eigen::VectorXd u = Eigen::VectorXd::LinSpaced(5, 1, 5).normalized();
  const Eigen::MatrixXd rank_one = 2.0 * u * u.transpose();
  const LeadingEigen found = leading_eigenvectors(rank_one, 3);
  EXPECT_NEAR(found.values(0), 2.0, 1e-12);
  EXPECT_NEAR(std::abs(found.vectors.col(0).dot(u)), 1.0, 1e-12);
  expect_eigenpairs(rank_one, found);
  EXPECT_EQ(leading_eigenvectors(rank_one, 0).vectors.cols(), 0);
  // A zero matrix (a field without variation): still orthonormal vectors, never NaN.
  const LeadingEigen zero = leading_eigenvectors(Eigen::MatrixXd::Zero(6, 6), 4);
  EXPECT_TRUE(zero.values.isZero());
  expect_eigenpairs(Eigen::MatrixXd::Zero(6, 6), zero);
}

}  // namespace
}  // namespace ls::relight
