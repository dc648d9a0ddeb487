#pragma once
// The eigenvectors of a symmetric matrix's few largest eigenvalues, for PCA bases that keep a
// handful of planes out of hundreds of dimensions.
//
// Householder tridiagonalisation (as Eigen's full solver starts), the tridiagonal's eigenvalues
// alone (O(n^2)), then each wanted eigenvector by inverse iteration on the tridiagonal (O(n) a
// step, orthogonalised against those found before it, as LAPACK's dstein does within clusters)
// carried back through the Householder reflections (O(n^2) each). The full solver's cost is the
// accumulation of every eigenvector through the QR sweeps (O(n^3) with a large constant): at
// n = 720 and 30 vectors this is several times faster.
#include <Eigen/Core>

namespace ls::relight {

struct LeadingEigen {
  Eigen::VectorXd values;   // Descending.
  Eigen::MatrixXd vectors;  // n x count, unit columns in the same order.
};

// The `count` largest eigenvalues (count <= n) of the symmetric `matrix` (its lower triangle is
// read) and their eigenvectors.
LeadingEigen leading_eigenvectors(const Eigen::MatrixXd& matrix, int count);

}  // namespace ls::relight
