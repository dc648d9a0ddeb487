// OpenLIME's interpolation between the lights (relight/compact/plane_interpolation.h).
#include "relight/compact/plane_interpolation.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

namespace ls::relight::openlime {
namespace {

// The octahedral grid of the bilinear type: node (x, y), index x + y * res, as relight's
// buildResampleMap places it.
Eigen::Vector3d grid_direction(int x, int y, int res) {
  const double ox = 2.0 * x / (res - 1) - 1, oy = 2.0 * y / (res - 1) - 1;
  const double gx = (ox - oy) / 2, gy = (ox + oy) / 2;
  return Eigen::Vector3d(gx, gy, std::max(0.0, 1 - std::abs(gx) - std::abs(gy))).normalized();
}

}  // namespace

Eigen::VectorXd rbf_weights(const std::vector<Eigen::Vector3d>& lights, const Eigen::Vector3d& dir,
                            double sigma, double drop) {
  Eigen::VectorXd w(Eigen::Index(lights.size()));
  for (size_t i = 0; i < lights.size(); ++i) {
    w(Eigen::Index(i)) = std::exp(-(lights[i] - dir).squaredNorm() / (sigma * sigma));
  }
  if (!(w.sum() > 0)) return w;
  w /= w.sum();
  w = (w.array() > drop).select(w, 0.0);
  if (w.sum() > 0) w /= w.sum();
  return w;
}

void bilinear_nodes(const Eigen::Vector3d& dir, int res, int node[4], double weight[4]) {
  const double s = std::abs(dir.x()) + std::abs(dir.y()) + std::abs(dir.z());
  double x = (dir.x() + dir.y()) / s, y = (dir.y() - dir.x()) / s;
  x = (x + 1) / 2 * (res - 1);
  y = (y + 1) / 2 * (res - 1);
  const int sx = std::min(res - 2, std::max(0, int(std::floor(x))));
  const int sy = std::min(res - 2, std::max(0, int(std::floor(y))));
  const double dx = x - sx, dy = y - sy;
  node[0] = sx + sy * res, weight[0] = (1 - dx) * (1 - dy);
  node[1] = sx + 1 + sy * res, weight[1] = dx * (1 - dy);
  node[2] = sx + (sy + 1) * res, weight[2] = (1 - dx) * dy;
  node[3] = sx + 1 + (sy + 1) * res, weight[3] = dx * dy;
}

Eigen::Vector3d viewer_light(const Eigen::Vector3d& dir) {
  Eigen::Vector3d l = dir.normalized();
  const double r = std::hypot(l.x(), l.y());
  if (r > 1) l.head<2>() /= r;
  l.z() = std::sqrt(std::max(0.0, 1 - l.x() * l.x() - l.y() * l.y()));
  return l;
}

Eigen::MatrixXd bilinear_resampling(const std::vector<Eigen::Vector3d>& lights, int res,
                                    double sigma, double k) {
  const Eigen::Index n = Eigen::Index(lights.size()), dims = Eigen::Index(res) * res;
  Eigen::MatrixXd b(dims, n), a = Eigen::MatrixXd::Zero(n, dims);
  for (int y = 0; y < res; ++y) {
    for (int x = 0; x < res; ++x) {
      b.row(x + Eigen::Index(y) * res) =
          rbf_weights(lights, grid_direction(x, y, res), sigma, 0.005);
    }
  }
  for (Eigen::Index i = 0; i < n; ++i) {
    int node[4];
    double weight[4];
    bilinear_nodes(viewer_light(lights[size_t(i)]), res, node, weight);
    for (int q = 0; q < 4; ++q) a(i, node[q]) += weight[q];
  }
  Eigen::MatrixXd normal = a.transpose() * a;
  normal.diagonal().array() += k;
  const Eigen::MatrixXd residual = Eigen::MatrixXd::Identity(n, n) - a * b;
  return b + normal.ldlt().solve(a.transpose() * residual);
}

}  // namespace ls::relight::openlime
