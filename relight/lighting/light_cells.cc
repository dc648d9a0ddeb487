#include "relight/lighting/light_cells.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <string>

#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "physics/sphere.h"

namespace ls::relight {

namespace {

std::vector<Eigen::Vector3d> normalized_directions(const std::vector<Eigen::Vector3d>& dirs) {
  std::vector<Eigen::Vector3d> out;
  out.reserve(dirs.size());
  for (size_t i = 0; i < dirs.size(); ++i) {
    const double norm = dirs[i].norm();
    LS_CHECK(std::isfinite(norm) && norm > 0.0, "LED direction " + std::to_string(i) +
                                                    " must be finite and non-zero, got norm " +
                                                    std::to_string(norm));
    out.push_back(dirs[i] / norm);
  }
  return out;
}

double resolve_coverage_radius(const std::vector<Eigen::Vector3d>& unit_dirs,
                               double coverage_radius_rad) {
  return coverage_radius_rad > 0.0 ? coverage_radius_rad : max_nearest_neighbour_angle(unit_dirs);
}

// Nearest-LED search accelerated by a coarse lat-long bucket grid. Each bucket lists every LED
// that can be nearest to some direction inside it: with c the bucket's centre, r the largest
// angle from c to any point of the bucket and d the angle from c to its nearest LED, the nearest
// LED of any point p in the bucket is within d + r of p, hence within d + 2r of c.
class NearestLed {
 public:
  // `usable` (empty = all) marks the LEDs that may be returned.
  NearestLed(const std::vector<Eigen::Vector3d>& unit_dirs, const std::vector<bool>& usable)
      : dirs_(unit_dirs) {
    std::vector<int> pool;
    std::vector<Eigen::Vector3d> pool_dirs;
    for (int l = 0; l < int(dirs_.size()); ++l) {
      if (usable.empty() || usable[l]) {
        pool.push_back(l);
        pool_dirs.push_back(dirs_[l]);
      }
    }
    // Each bucket's nearest LED and the LEDs within its reach from a k-d tree: scanning every LED
    // per bucket is O(buckets x LEDs), minutes at 100,000 LEDs.
    const DirectionIndex index(pool_dirs);
    // Buckets about a quarter of the mean LED spacing: a handful of candidates each.
    const double spacing_rad = std::sqrt(4.0 * std::numbers::pi / std::max<size_t>(pool.size(), 1));
    grid_h_ = std::clamp(int(std::ceil(std::numbers::pi / (0.25 * spacing_rad))), 16, 512);
    grid_w_ = 2 * grid_h_;
    offsets_.assign(size_t(grid_w_) * grid_h_ + 1, 0);
    std::vector<std::vector<int>> lists(size_t(grid_w_) * grid_h_);
    tbb::parallel_for(0, grid_h_, [&](int by) {
      const double v0 = double(by) / grid_h_, v1 = double(by + 1) / grid_h_;
      for (int bx = 0; bx < grid_w_; ++bx) {
        const double u0 = double(bx) / grid_w_, u1 = double(bx + 1) / grid_w_;
        const Eigen::Vector3d centre =
            physics::EnvironmentMap::direction(0.5 * (u0 + u1), 0.5 * (v0 + v1));
        // Within a lat-long bucket the farthest point from the centre is a corner.
        double min_corner_dot = 1.0;
        for (double u : {u0, u1}) {
          for (double v : {v0, v1}) {
            min_corner_dot =
                std::min(min_corner_dot, centre.dot(physics::EnvironmentMap::direction(u, v)));
          }
        }
        const double radius_rad = std::acos(std::clamp(min_corner_dot, -1.0, 1.0)) + 1e-9;
        if (pool.empty()) continue;
        const double reach_rad = index.nearest_angle(centre) + 2.0 * radius_rad + 1e-9;
        std::vector<int>& list = lists[size_t(by) * grid_w_ + bx];
        for (const int k : index.within(centre, reach_rad)) list.push_back(pool[size_t(k)]);
        std::sort(list.begin(), list.end());
      }
    });
    for (size_t b = 0; b < lists.size(); ++b) offsets_[b + 1] = offsets_[b] + int(lists[b].size());
    candidates_.reserve(offsets_.back());
    for (const auto& list : lists) candidates_.insert(candidates_.end(), list.begin(), list.end());
  }

  int bucket(double u, double v) const {
    const int bx = std::min(int(u * grid_w_), grid_w_ - 1);
    const int by = std::min(int(v * grid_h_), grid_h_ - 1);
    return by * grid_w_ + bx;
  }

  // Index of the nearest usable LED (-1 when there is none) and its dot product with `dir`.
  // Ties go to the lower index, as a brute-force search in index order would.
  int nearest(const Eigen::Vector3d& dir, int bucket, double* best_dot) const {
    int best = -1;
    double best_d = -2.0;
    for (int k = offsets_[bucket]; k < offsets_[bucket + 1]; ++k) {
      const int l = candidates_[k];
      const double d = dir.dot(dirs_[l]);
      if (d > best_d) {
        best_d = d;
        best = l;
      }
    }
    *best_dot = best_d;
    return best;
  }

  double mean_candidates() const { return double(candidates_.size()) / (offsets_.size() - 1); }

 private:
  const std::vector<Eigen::Vector3d>& dirs_;
  int grid_w_ = 0, grid_h_ = 0;
  std::vector<int> offsets_;     // Bucket b's candidates: [offsets_[b], offsets_[b + 1]).
  std::vector<int> candidates_;  // Sorted by LED index within a bucket.
};

// Walks a width x width/2 lat-long grid with supersample^2 samples per pixel and calls
// visit(block, map_x, map_y, cell, weight_sr) for every sample, where cell is the LED whose cell
// holds the sample (-1: uncovered). Each sub-row of samples gets its exact solid angle, so the
// samples of a pixel sum to that pixel's exact solid angle and all samples sum to 4 pi.
// Rows are processed in parallel; `block` is the map row (callers accumulate per row and reduce
// in row order, which keeps results independent of the thread count).
template <class Visit>
void for_each_cell_sample(const std::vector<Eigen::Vector3d>& unit_dirs,
                          const std::vector<bool>& valid, double coverage_radius_rad, int width,
                          int supersample, Visit&& visit) {
  const int height = width / 2;
  const int ss = supersample;
  const bool all_valid =
      valid.empty() || std::all_of(valid.begin(), valid.end(), [](bool b) { return b; });
  // Coverage is a property of the dome (all LEDs); cells of dead LEDs go to the nearest valid one.
  const NearestLed nearest_any(unit_dirs, {});
  const std::optional<NearestLed> nearest_valid =
      all_valid ? std::nullopt : std::optional<NearestLed>(std::in_place, unit_dirs, valid);
  const double cos_coverage =
      coverage_radius_rad >= std::numbers::pi ? -2.0 : std::cos(coverage_radius_rad);

  const int samples_w = width * ss;
  std::vector<double> sin_phi(samples_w), cos_phi(samples_w);
  std::vector<double> sample_u(samples_w);
  for (int sx = 0; sx < samples_w; ++sx) {
    const double u = (sx + 0.5) / samples_w;
    const double phi = 2.0 * std::numbers::pi * u - std::numbers::pi;
    sin_phi[sx] = std::sin(phi);
    cos_phi[sx] = std::cos(phi);
    sample_u[sx] = u;
  }
  const double sample_azimuth_sr = 2.0 * std::numbers::pi / samples_w;

  tbb::parallel_for(
      tbb::blocked_range<int>(0, height, 1),
      [&](const tbb::blocked_range<int>& rows) {
        for (int y = rows.begin(); y < rows.end(); ++y) {
          for (int sy = 0; sy < ss; ++sy) {
            const double theta_top = std::numbers::pi * (y + double(sy) / ss) / height;
            const double theta_bottom = std::numbers::pi * (y + double(sy + 1) / ss) / height;
            const double theta = 0.5 * (theta_top + theta_bottom);
            const double weight_sr =
                sample_azimuth_sr * (std::cos(theta_top) - std::cos(theta_bottom));
            const double sin_theta = std::sin(theta), cos_theta = std::cos(theta);
            const double v = theta / std::numbers::pi;
            for (int sx = 0; sx < samples_w; ++sx) {
              const Eigen::Vector3d dir(sin_theta * sin_phi[sx], cos_theta,
                                        -sin_theta * cos_phi[sx]);
              const int bucket = nearest_any.bucket(sample_u[sx], v);
              double best_dot;
              int cell = nearest_any.nearest(dir, bucket, &best_dot);
              if (best_dot < cos_coverage) {
                cell = -1;
              } else if (nearest_valid) {
                cell =
                    nearest_valid->nearest(dir, nearest_valid->bucket(sample_u[sx], v), &best_dot);
              }
              visit(y, sx / ss, y, cell, weight_sr);
            }
          }
        }
      },
      tbb::simple_partitioner());
}

}  // namespace

LightCells LightCells::compute(const std::vector<Eigen::Vector3d>& led_dirs,
                               double coverage_radius_rad, int resolution, int supersample) {
  LS_CHECK(resolution >= 2 && resolution % 2 == 0,
           "resolution must be even and >= 2, got " + std::to_string(resolution));
  LS_CHECK(supersample >= 1, "supersample must be >= 1, got " + std::to_string(supersample));
  const std::vector<Eigen::Vector3d> dirs = normalized_directions(led_dirs);
  LightCells cells;
  cells.coverage_radius_rad = resolve_coverage_radius(dirs, coverage_radius_rad);
  const int num_leds = int(dirs.size());
  const int height = resolution / 2;
  // Per map row: num_leds cells + uncovered.
  const size_t stride = size_t(num_leds) + 1;
  std::vector<double> per_row(stride * height, 0.0);
  for_each_cell_sample(dirs, {}, cells.coverage_radius_rad, resolution, supersample,
                       [&](int block, int, int, int cell, double weight_sr) {
                         per_row[block * stride + (cell < 0 ? num_leds : cell)] += weight_sr;
                       });
  cells.solid_angle_sr.assign(num_leds, 0.0);
  for (int y = 0; y < height; ++y) {
    const double* row = per_row.data() + y * stride;
    for (int l = 0; l < num_leds; ++l) cells.solid_angle_sr[l] += row[l];
    cells.uncovered_sr += row[num_leds];
  }
  return cells;
}

double LightWeights::uncovered_fraction() const {
  const double total = luminance(total_irradiance_rgb);
  return total > 0.0 ? luminance(uncovered_irradiance_rgb) / total : 0.0;
}

LightWeights integrate_environment(const physics::EnvironmentMap& map,
                                   const std::vector<Eigen::Vector3d>& led_dirs,
                                   double rotation_deg, double coverage_radius_rad,
                                   const std::vector<bool>& valid, int supersample) {
  LS_CHECK(valid.empty() || valid.size() == led_dirs.size(),
           "valid has " + std::to_string(valid.size()) + " entries for " +
               std::to_string(led_dirs.size()) + " LEDs");
  LS_CHECK(supersample >= 1, "supersample must be >= 1, got " + std::to_string(supersample));
  std::vector<Eigen::Vector3d> dirs = normalized_directions(led_dirs);
  const double coverage_rad = resolve_coverage_radius(dirs, coverage_radius_rad);
  // The map rotated by +alpha puts the content of map direction d at R_y(alpha) d; it falls in
  // LED l's cell exactly when d is nearest to R_y(-alpha) l. Rotating the LEDs into the map's
  // frame keeps the sample grid aligned with the map's pixels.
  const Eigen::Matrix3d map_from_stage =
      physics::rotation_about_y(-rotation_deg * std::numbers::pi / 180.0);
  for (auto& d : dirs) d = map_from_stage * d;

  const int num_leds = int(dirs.size());
  const int height = map.height();
  const size_t stride = 3 * (size_t(num_leds) + 1);
  std::vector<double> per_row(stride * height, 0.0);
  const Image& radiance = map.radiance();
  for_each_cell_sample(dirs, valid, coverage_rad, map.width(), supersample,
                       [&](int block, int x, int y, int cell, double weight_sr) {
                         double* acc = per_row.data() + block * stride +
                                       3 * size_t(cell < 0 ? num_leds : cell);
                         const float* l = &radiance.pixels[(size_t(y) * map.width() + x) * 3];
                         acc[0] += weight_sr * l[0];
                         acc[1] += weight_sr * l[1];
                         acc[2] += weight_sr * l[2];
                       });
  std::vector<double> sum(stride, 0.0);
  for (int y = 0; y < height; ++y) {
    const double* row = per_row.data() + y * stride;
    for (size_t k = 0; k < stride; ++k) sum[k] += row[k];
  }
  LightWeights weights;
  weights.irradiance_rgb.resize(3 * size_t(num_leds));
  for (size_t k = 0; k < 3 * size_t(num_leds); ++k) weights.irradiance_rgb[k] = float(sum[k]);
  weights.uncovered_irradiance_rgb =
      Eigen::Vector3d(sum[3 * num_leds], sum[3 * num_leds + 1], sum[3 * num_leds + 2]);
  weights.total_irradiance_rgb = weights.uncovered_irradiance_rgb;
  for (int l = 0; l < num_leds; ++l) {
    weights.total_irradiance_rgb += Eigen::Vector3d(sum[3 * l], sum[3 * l + 1], sum[3 * l + 2]);
  }
  return weights;
}

}  // namespace ls::relight
