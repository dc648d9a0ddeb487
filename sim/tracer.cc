#include "sim/tracer.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "lightstage/errors.h"

namespace ls::sim {

namespace detail {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kBlockCells = 8;  // Height-field cells per side of a min/max block.
}  // namespace

void plane_tangents(const Eigen::Vector3d& normal, Eigen::Vector3d* u, Eigen::Vector3d* v) {
  const Eigen::Vector3d up(0, 1, 0);
  Eigen::Vector3d tu = up.cross(normal);
  if (tu.norm() < 1e-6) tu = Eigen::Vector3d(1, 0, 0);
  *u = tu.normalized();
  *v = normal.cross(*u).normalized();
}

Tracer::Tracer(const Scene& scene) : scene_(scene) {
  for (const Plane& p : scene.planes) {
    PlaneFrame f;
    f.center = p.center;
    f.normal = p.normal.normalized();
    plane_tangents(f.normal, &f.u, &f.v);
    f.half_width = p.half_width;
    f.half_height = p.half_height;
    planes_.push_back(f);
  }
  for (const HeightField& hf : scene.height_fields) {
    LS_CHECK(hf.resolution >= 2 && hf.heights.size() == size_t(hf.resolution) * hf.resolution,
             "height field has " + std::to_string(hf.heights.size()) + " samples for resolution " +
                 std::to_string(hf.resolution));
    Field f;
    f.hf = &hf;
    f.n = hf.resolution;
    f.x_left = hf.center.x() - hf.half_width;
    f.y_top = hf.center.y() + hf.half_height;
    f.dx = 2.0 * hf.half_width / (f.n - 1);
    f.dy = 2.0 * hf.half_height / (f.n - 1);
    f.base_z = hf.center.z();
    const auto [lo, hi] = std::minmax_element(hf.heights.begin(), hf.heights.end());
    f.box_lo = {f.x_left, hf.center.y() - hf.half_height, f.base_z + *lo};
    f.box_hi = {hf.center.x() + hf.half_width, f.y_top, f.base_z + *hi};
    f.blocks = (f.n - 1 + kBlockCells - 1) / kBlockCells;
    f.block_min.assign(size_t(f.blocks) * f.blocks, std::numeric_limits<float>::max());
    f.block_max.assign(size_t(f.blocks) * f.blocks, std::numeric_limits<float>::lowest());
    for (int bi = 0; bi < f.blocks; ++bi) {
      for (int bj = 0; bj < f.blocks; ++bj) {
        float mn = std::numeric_limits<float>::max(), mx = std::numeric_limits<float>::lowest();
        // Inclusive sample range: the bilinear surface over the block depends on its edges.
        for (int i = bi * kBlockCells; i <= std::min((bi + 1) * kBlockCells, f.n - 1); ++i) {
          for (int j = bj * kBlockCells; j <= std::min((bj + 1) * kBlockCells, f.n - 1); ++j) {
            const float h = hf.heights[size_t(i) * f.n + j];
            mn = std::min(mn, h);
            mx = std::max(mx, h);
          }
        }
        f.block_min[size_t(bi) * f.blocks + bj] = mn;
        f.block_max[size_t(bi) * f.blocks + bj] = mx;
      }
    }
    fields_.push_back(std::move(f));
  }
}

int Tracer::material_of(int object) const {
  const int ns = int(scene_.spheres.size()), np = int(scene_.planes.size());
  if (object < ns) return scene_.spheres[object].material;
  if (object < ns + np) return scene_.planes[object - ns].material;
  return scene_.height_fields[object - ns - np].material;
}

bool Tracer::hit_sphere(int i, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min,
                        double* t) const {
  const Sphere& s = scene_.spheres[i];
  const Eigen::Vector3d oc = o - s.center;
  const double b = oc.dot(d);  // d is unit.
  const double c = oc.squaredNorm() - s.radius * s.radius;
  const double disc = b * b - c;
  if (disc < 0) return false;
  const double root = std::sqrt(disc);
  double tt = -b - root;
  if (tt <= t_min) tt = -b + root;
  if (tt <= t_min) return false;
  *t = tt;
  return true;
}

bool Tracer::hit_plane(int i, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min,
                       double* t) const {
  const PlaneFrame& p = planes_[i];
  const double denom = d.dot(p.normal);
  if (std::abs(denom) < 1e-12) return false;
  const double tt = (p.center - o).dot(p.normal) / denom;
  if (tt <= t_min) return false;
  const Eigen::Vector3d local = o + tt * d - p.center;
  if (std::abs(local.dot(p.u)) > p.half_width || std::abs(local.dot(p.v)) > p.half_height) {
    return false;
  }
  *t = tt;
  return true;
}

double Tracer::height_at(const Field& f, double gx, double gy) {
  const double max_g = f.n - 1;
  gx = std::clamp(gx, 0.0, max_g);
  gy = std::clamp(gy, 0.0, max_g);
  const int j0 = std::min(int(gx), f.n - 2), i0 = std::min(int(gy), f.n - 2);
  const double tx = gx - j0, ty = gy - i0;
  const float* row0 = f.hf->heights.data() + size_t(i0) * f.n + j0;
  const float* row1 = row0 + f.n;
  return (1 - ty) * ((1 - tx) * row0[0] + tx * row0[1]) + ty * ((1 - tx) * row1[0] + tx * row1[1]);
}

// Marches the grid in steps of half a cell, skipping whole 8x8-cell blocks whose height range the
// ray passes entirely above (or below); a crossing of the surface is refined by bisection.
bool Tracer::hit_field(const Field& f, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                       double t_min, bool any, double* t_out) const {
  double t0 = t_min, t1 = kInf;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(d[k]) < 1e-15) {
      if (o[k] < f.box_lo[k] || o[k] > f.box_hi[k]) return false;
      continue;
    }
    double ta = (f.box_lo[k] - o[k]) / d[k], tb = (f.box_hi[k] - o[k]) / d[k];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (!(t0 < t1)) return false;

  // Grid coordinates along the ray: g(t) = g(0) + t * g_rate.
  const double gx_origin = (o.x() - f.x_left) / f.dx, gy_origin = (f.y_top - o.y()) / f.dy;
  const double gx_rate = d.x() / f.dx, gy_rate = -d.y() / f.dy;
  const double grid_speed = std::max(std::abs(gx_rate), std::abs(gy_rate));
  const double dt_step = grid_speed > 1e-12 ? 0.5 / grid_speed : kInf;
  auto above = [&](double t) {
    return o.z() + t * d.z() - f.base_z -
           height_at(f, gx_origin + t * gx_rate, gy_origin + t * gy_rate);
  };
  auto block_exit = [&](double g, double rate, int block) {
    if (rate > 0) return ((block + 1) * kBlockCells - g) / rate;
    if (rate < 0) return (block * kBlockCells - g) / rate;
    return kInf;
  };

  double ta = t0;
  double fa = above(ta);
  while (ta < t1) {
    const double gx = gx_origin + ta * gx_rate, gy = gy_origin + ta * gy_rate;
    // The block the ray is entering: nudge along the motion so boundaries do not stall it.
    const int bj = std::clamp(int(std::floor((gx + std::copysign(1e-7, gx_rate)) / kBlockCells)), 0,
                              f.blocks - 1);
    const int bi = std::clamp(int(std::floor((gy + std::copysign(1e-7, gy_rate)) / kBlockCells)), 0,
                              f.blocks - 1);
    double tb = ta + std::min(block_exit(gx, gx_rate, bj), block_exit(gy, gy_rate, bi));
    tb = std::min(std::max(tb, ta + 1e-9), t1);
    const double za = o.z() + ta * d.z() - f.base_z, zb = o.z() + tb * d.z() - f.base_z;
    const size_t b = size_t(bi) * f.blocks + bj;
    if (std::min(za, zb) > f.block_max[b] && fa > 0) {
      ta = tb;  // Still above at tb: the block's edge samples are within its range too.
      continue;
    }
    if (std::max(za, zb) < f.block_min[b] && fa < 0) {
      ta = tb;
      continue;
    }
    while (ta < tb) {
      const double tn = std::min(ta + dt_step, tb);
      const double fn = above(tn);
      if ((fa >= 0) != (fn >= 0)) {
        if (any) {
          *t_out = tn;
          return true;
        }
        double lo = ta, hi = tn, flo = fa;
        for (int it = 0; it < 48 && hi - lo > 1e-9; ++it) {
          const double mid = 0.5 * (lo + hi);
          const double fm = above(mid);
          if ((fm >= 0) == (flo >= 0)) {
            lo = mid;
            flo = fm;
          } else {
            hi = mid;
          }
        }
        *t_out = 0.5 * (lo + hi);
        return true;
      }
      ta = tn;
      fa = fn;
    }
  }
  return false;
}

bool Tracer::intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double t_min,
                       RayHit* hit) const {
  double best = kInf;
  int best_object = -1;
  double t = 0;
  const int ns = int(scene_.spheres.size()), np = int(planes_.size());
  for (int i = 0; i < ns; ++i) {
    if (hit_sphere(i, origin, dir, t_min, &t) && t < best) {
      best = t;
      best_object = i;
    }
  }
  for (int i = 0; i < np; ++i) {
    if (hit_plane(i, origin, dir, t_min, &t) && t < best) {
      best = t;
      best_object = ns + i;
    }
  }
  for (size_t i = 0; i < fields_.size(); ++i) {
    if (hit_field(fields_[i], origin, dir, t_min, /*any=*/false, &t) && t < best) {
      best = t;
      best_object = ns + np + int(i);
    }
  }
  if (best_object < 0) return false;
  hit->t = best;
  hit->object = best_object;
  return true;
}

bool Tracer::occluded(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                      double t_min) const {
  return occluded(origin, dir, t_min, kInf);
}

bool Tracer::occluded(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double t_min,
                      double t_max) const {
  // Each hit_* returns its nearest crossing past t_min, so comparing it with t_max is enough.
  double t = 0;
  for (int i = 0; i < int(scene_.spheres.size()); ++i) {
    if (hit_sphere(i, origin, dir, t_min, &t) && t < t_max) return true;
  }
  for (int i = 0; i < int(planes_.size()); ++i) {
    if (hit_plane(i, origin, dir, t_min, &t) && t < t_max) return true;
  }
  for (const Field& f : fields_) {
    if (hit_field(f, origin, dir, t_min, /*any=*/true, &t) && t < t_max) return true;
  }
  return false;
}

void Tracer::surface(const Eigen::Vector3d& position, int object, Eigen::Vector3d* normal,
                     Eigen::Vector2d* st) const {
  const int ns = int(scene_.spheres.size()), np = int(planes_.size());
  if (object < ns) {
    const Sphere& s = scene_.spheres[object];
    const Eigen::Vector3d n = (position - s.center).normalized();
    *normal = n;
    // Lat-long around +Y: s from the azimuth (0.5 faces the camera), t from the pole.
    const double theta = std::acos(std::clamp(n.y(), -1.0, 1.0));
    const double phi = std::atan2(n.x(), n.z());
    *st = {(phi + physics::brdf::kPi) / (2 * physics::brdf::kPi), theta / physics::brdf::kPi};
  } else if (object < ns + np) {
    const PlaneFrame& p = planes_[object - ns];
    *normal = p.normal;
    const Eigen::Vector3d local = position - p.center;
    *st = {0.5 * (local.dot(p.u) / p.half_width + 1.0),
           0.5 * (1.0 - local.dot(p.v) / p.half_height)};
  } else {
    const Field& f = fields_[object - ns - np];
    const double gx = (position.x() - f.x_left) / f.dx, gy = (f.y_top - position.y()) / f.dy;
    // Central differences one cell wide; y grows opposite to the grid rows.
    const double dh_dx = (height_at(f, gx + 1, gy) - height_at(f, gx - 1, gy)) / (2 * f.dx);
    const double dh_dy = -(height_at(f, gx, gy + 1) - height_at(f, gx, gy - 1)) / (2 * f.dy);
    *normal = Eigen::Vector3d(-dh_dx, -dh_dy, 1.0).normalized();
    *st = {gx / (f.n - 1), gy / (f.n - 1)};
  }
}

}  // namespace detail

}  // namespace ls::sim
