#include "sim/ground_truth.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>

#include "lightstage/direction_index.h"
#include "lightstage/errors.h"
#include "physics/sphere.h"
#include "sim/sim_stage.h"
#include "sim/tracer.h"

namespace ls::sim {

namespace {}  // namespace

Image render_ground_truth(const Scene& scene, const CameraSpec& camera,
                          const physics::EnvironmentMap& map, const GroundTruthOptions& options) {
  if (options.directions_width < 4 || options.directions_width % 2 != 0) {
    throw InputError("ground truth: directions_width: expected an even number >= 4, got " +
                     std::to_string(options.directions_width));
  }
  std::vector<physics::CoarseTexel> texels =
      physics::box_filter_environment(map, options.directions_width, options.rotation_deg);
  if (!options.covered_by_leds.empty()) {
    const double radius = options.coverage_radius_rad > 0
                              ? options.coverage_radius_rad
                              : max_nearest_neighbour_angle(options.covered_by_leds);
    const double cos_radius = std::cos(radius);
    std::erase_if(texels, [&](const physics::CoarseTexel& t) {
      for (const auto& led : options.covered_by_leds) {
        if (t.dir_in_stage.dot(led.normalized()) >= cos_radius) return false;
      }
      return true;
    });
  }

  // Block corners on the coarse grid, (blocks_x + 1) x (blocks_y + 1), and each texel's four.
  const int block = std::max(1, options.visibility_block);
  const int cw = options.directions_width, ch = cw / 2;
  const int blocks_x = (cw + block - 1) / block, blocks_y = (ch + block - 1) / block;
  std::vector<Eigen::Vector3d> corner_dirs;
  for (int j = 0; j <= blocks_y; ++j) {
    for (int i = 0; i <= blocks_x; ++i) {
      const Eigen::Vector3d d0 = physics::EnvironmentMap::direction(
          double(std::min(i * block, cw)) / cw, double(std::min(j * block, ch)) / ch);
      corner_dirs.push_back(physics::rotate_about_y(d0, options.rotation_deg));
    }
  }
  std::vector<std::array<int, 4>> texel_corners(texels.size());
  for (size_t k = 0; k < texels.size(); ++k) {
    const int i = texels[k].x / block, j = texels[k].y / block;
    const int c00 = j * (blocks_x + 1) + i;
    texel_corners[k] = {c00, c00 + 1, c00 + blocks_x + 1, c00 + blocks_x + 2};
  }

  const std::vector<SurfaceHit> hits = trace_camera(scene, camera, options.scene_time_s);
  const detail::Tracer tracer(scene);
  Image out(camera.width, camera.height, 3);
  tbb::parallel_for(tbb::blocked_range<int>(0, camera.height), [&](const auto& rows) {
    std::vector<int8_t> corner_visible(corner_dirs.size());  // -1: not traced yet.
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < camera.width; ++x) {
        const SurfaceHit& h = hits[size_t(y) * camera.width + x];
        if (!h.hit) continue;
        const Eigen::Vector3d origin = detail::shadow_ray_origin(h);
        auto sees = [&](const Eigen::Vector3d& dir) { return !tracer.occluded(origin, dir, 0.0); };
        std::fill(corner_visible.begin(), corner_visible.end(), int8_t(-1));
        auto corner = [&](int c) {
          if (corner_visible[c] < 0) corner_visible[c] = sees(corner_dirs[c]) ? 1 : 0;
          return corner_visible[c];
        };
        // Lambert's f is constant: sum the cosine-weighted light and multiply once.
        const bool lambert_only = h.material.diffuse == physics::brdf::DiffuseModel::kLambert &&
                                  h.material.specular == physics::brdf::SpecularModel::kNone;
        const double cos_o = h.normal.dot(h.wo);
        Eigen::Vector3d sum(0, 0, 0);
        if (cos_o > 0) {
          for (size_t k = 0; k < texels.size(); ++k) {
            const physics::CoarseTexel& t = texels[k];
            const double cos_i = h.normal.dot(t.dir_in_stage);
            if (cos_i <= 0) continue;
            Eigen::Vector3d weight;
            if (lambert_only) {
              weight = t.radiance_x_sr * cos_i;
            } else {
              const Eigen::Vector3d f = physics::brdf::eval(
                  h.material,
                  physics::brdf::Geometry<double>{cos_i, cos_o, t.dir_in_stage.dot(h.wo)});
              if (!(f.maxCoeff() > 0)) continue;
              weight = t.radiance_x_sr.cwiseProduct(f) * cos_i;
            }
            bool lit;
            if (block == 1) {
              lit = sees(t.dir_in_stage);
            } else {
              const auto& c = texel_corners[k];
              const int corners = corner(c[0]) + corner(c[1]) + corner(c[2]) + corner(c[3]);
              lit = corners == 4 ? true : corners == 0 ? false : sees(t.dir_in_stage);
            }
            if (lit) sum += weight;
          }
          if (lambert_only) sum = sum.cwiseProduct(h.material.albedo) / std::numbers::pi;
        }
        for (int c = 0; c < 3; ++c) out.at(x, y, c) = float(sum[c]);
      }
    }
  });
  return out;
}

Image render_source_visibility(const Scene& scene, const CameraSpec& camera,
                               const Eigen::Vector3d& dir, double radius_rad, int samples) {
  if (!(radius_rad >= 0) || samples < 1 || !dir.allFinite() || dir.norm() == 0) {
    throw InputError("source visibility: expected a direction, a radius >= 0 and samples >= 1");
  }
  const std::vector<Eigen::Vector3d> dirs = physics::disc_directions(dir, radius_rad, samples);
  const std::vector<SurfaceHit> hits = trace_camera(scene, camera);
  const detail::Tracer tracer(scene);
  Image out(camera.width, camera.height, 1);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, hits.size()), [&](const auto& range) {
    for (size_t k = range.begin(); k < range.end(); ++k) {
      const SurfaceHit& hit = hits[k];
      if (!hit.hit) continue;
      int seen = 0;
      for (const Eigen::Vector3d& d : dirs) {
        seen += !tracer.occluded(detail::shadow_ray_origin(hit), d, 0.0);
      }
      out.at(hit.pixel_x, hit.pixel_y, 0) = float(seen) / float(samples);
    }
  });
  return out;
}

Image render_ground_truth(const Scene& scene, const CameraSpec& camera,
                          const physics::EnvironmentMap& map, const GroundTruthOptions& options,
                          double time_s) {
  GroundTruthOptions at_time = options;
  at_time.scene_time_s = time_s;
  return render_ground_truth(scene, camera, map, at_time);
}

}  // namespace ls::sim
