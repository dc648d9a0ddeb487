#include "capture/sphere_lights.h"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <mutex>

namespace ls::capture {

namespace {

std::string format(const char* pattern, double a, double b = 0, double c = 0) {
  char text[256];
  std::snprintf(text, sizeof(text), pattern, a, b, c);
  return text;
}

// Where the ray leaves the dome (its origin inside), or nullopt.
std::optional<Eigen::Vector3d> exit_point(const LightRay& ray, const FittedDome& dome) {
  const Eigen::Vector3d oc = ray.origin - dome.centre;
  const double b = oc.dot(ray.dir);
  const double disc = b * b - (oc.squaredNorm() - dome.radius_m * dome.radius_m);
  if (disc < 0) return std::nullopt;
  const double t = -b + std::sqrt(disc);
  if (!(t > 0)) return std::nullopt;
  return ray.origin + t * ray.dir;
}

// The dome of the triangulated positions, refitted without those more than 3 RMS (and 1% of
// the radius) off it: one bad highlight must not bend it. nullopt when they are no dome.
std::optional<FittedDome> fit_dome(const std::vector<Eigen::Vector3d>& positions) {
  std::optional<FittedDome> dome = fit_sphere(positions);
  if (!dome) return std::nullopt;
  std::vector<Eigen::Vector3d> near;
  const double limit = std::max(3.0 * dome->rms_m, 0.01 * dome->radius_m);
  for (const Eigen::Vector3d& p : positions) {
    if (std::abs((p - dome->centre).norm() - dome->radius_m) <= limit) near.push_back(p);
  }
  if (near.size() < positions.size() && near.size() >= positions.size() / 2) {
    dome = fit_sphere(near);
  }
  if (!dome || dome->rms_m > kDomeTolerance * dome->radius_m) return std::nullopt;
  return dome;
}

}  // namespace

std::string SphereLightOptions::validate(int image_width, int image_height) const {
  if (!(radius_m >= 0) || !std::isfinite(radius_m)) {
    return "sphere radius: expected a positive size, got " + std::to_string(radius_m);
  }
  for (size_t s = 0; s < outlines.size(); ++s) {
    const SphereOutline& o = outlines[s];
    const std::string which = "sphere " + std::to_string(s + 1);
    if (!(o.radius_px >= 4)) return which + ": radius: expected at least 4 pixels";
    if (!(o.center_px.x() - o.radius_px >= 0 && o.center_px.y() - o.radius_px >= 0 &&
          o.center_px.x() + o.radius_px <= image_width &&
          o.center_px.y() + o.radius_px <= image_height)) {
      return which +
             format(": expected inside the %gx%g images, got centre (%g, ", image_width,
                    image_height, o.center_px.x()) +
             format("%g) radius %g", o.center_px.y(), o.radius_px);
    }
  }
  return "";
}

std::optional<FittedDome> fit_sphere(const std::vector<Eigen::Vector3d>& points) {
  if (points.size() < 4) return std::nullopt;
  Eigen::MatrixXd a(points.size(), 4);
  Eigen::VectorXd rhs(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    a.row(Eigen::Index(i)) << points[i].x(), points[i].y(), points[i].z(), 1.0;
    rhs[Eigen::Index(i)] = -points[i].squaredNorm();
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
  if (qr.rank() < 4) return std::nullopt;
  const Eigen::Vector4d b = qr.solve(rhs);
  FittedDome dome;
  dome.centre = -0.5 * b.head<3>();
  const double r2 = dome.centre.squaredNorm() - b[3];
  if (!(r2 > 0) || !std::isfinite(r2)) return std::nullopt;
  dome.radius_m = std::sqrt(r2);
  double sum2 = 0;
  for (const Eigen::Vector3d& p : points) {
    sum2 += std::pow((p - dome.centre).norm() - dome.radius_m, 2);
  }
  dome.rms_m = std::sqrt(sum2 / double(points.size()));
  return dome;
}

PlacedLights place_lights_from_spheres(int width, int height, const std::vector<std::string>& names,
                                       const ImageRows& read, const SphereLightOptions& options,
                                       const ProgressFn& progress) {
  PlacedLights placed;
  placed.spheres = int(options.outlines.size());
  const int n = int(names.size());
  placed.positions.resize(size_t(n));
  placed.directions.resize(size_t(n));
  if (options.outlines.empty() || n == 0) return placed;
  // Only the rows the spheres cover are kept; the camera's centre moves with them.
  double top = height, bottom = 0;
  for (const SphereOutline& o : options.outlines) {
    top = std::min(top, o.center_px.y() - o.radius_px);
    bottom = std::max(bottom, o.center_px.y() + o.radius_px);
  }
  const int y0 = std::max(0, int(std::floor(top)) - 2);
  const int y1 = std::min(height, int(std::ceil(bottom)) + 2);
  const double first_radius_px = options.outlines[0].radius_px;
  placed.metres_per_pixel =
      options.radius_m > 0 ? options.radius_m / first_radius_px : kNominalMetresPerPixel;
  ViewCamera camera = ViewCamera::orthographic_pixels(width, y1 - y0);
  camera.metres_per_pixel = placed.metres_per_pixel;
  camera.cy = 0.5 * height - y0;
  std::vector<SphereOutline> outlines = options.outlines;
  std::vector<MirrorSphere> spheres;
  for (SphereOutline& o : outlines) {
    o.center_px.y() -= y0;
    const double radius_m = o.radius_px * placed.metres_per_pixel;
    spheres.push_back(locate_sphere(o, camera, radius_m, radius_m));  // Resting on z = 0.
  }
  // A light above the table (z > 0) is mirrored within sin(45 deg) = 0.71 of the radius of the
  // centre: the highlight is looked for within 0.85 of it, clear of the rim, which mirrors the
  // lit table and has the backdrop blurred into it (a blob reaching it is pulled outward).
  std::vector<SphereOutline> search = outlines;
  for (SphereOutline& o : search) o.radius_px *= 0.85;
  DirectionOptions direction_options;
  direction_options.highlight = options.highlight;
  direction_options.max_distance_m = 1e3 * (width + height) * placed.metres_per_pixel;

  std::vector<LedDirectionEstimate> estimates(static_cast<size_t>(n));
  std::mutex problems_mutex;
  std::atomic<int> done{0};
  tbb::parallel_for(0, n, [&](int l) {
    const Image rows = read(l, y0, y1);
    DirectionCalibration one = calibrate_directions({&rows}, {names[size_t(l)]}, search, spheres,
                                                    camera, direction_options);
    estimates[size_t(l)] = one.leds[0];
    estimates[size_t(l)].led_index = l;
    const std::lock_guard<std::mutex> lock(problems_mutex);
    for (ImageProblem& p : one.problems) {
      p.led_index = l;
      placed.problems.push_back(std::move(p));
    }
    if (progress) progress("spheres", ++done, n, {});
  });
  std::sort(placed.problems.begin(), placed.problems.end(),
            [](const ImageProblem& a, const ImageProblem& b) { return a.led_index < b.led_index; });

  std::vector<Eigen::Vector3d> crossed;
  for (int l = 0; l < n; ++l) {
    const LedDirectionEstimate& e = estimates[size_t(l)];
    if (!e.ok) continue;
    placed.directions[size_t(l)] = e.dir_in_stage.normalized();
    if (e.position_in_stage) crossed.push_back(*e.position_in_stage);
  }
  placed.triangulated = int(crossed.size());
  const int found = int(std::count_if(placed.directions.begin(), placed.directions.end(),
                                      [](const auto& d) { return d.has_value(); }));
  placed.description = std::to_string(found) + " of " + std::to_string(n) + " lights found on " +
                       std::to_string(placed.spheres) + " sphere" + (placed.spheres > 1 ? "s" : "");
  if (placed.spheres < 2) {
    placed.description += ": directions only (a second sphere gives positions)";
    return placed;
  }
  placed.dome = fit_dome(crossed);
  if (placed.dome) {
    const FittedDome& dome = *placed.dome;
    for (int l = 0; l < n; ++l) {
      const LedDirectionEstimate& e = estimates[size_t(l)];
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      int count = 0;
      for (const LightRay& ray : e.rays) {
        if (const auto p = exit_point(ray, dome)) {
          sum += *p;
          ++count;
        }
      }
      if (count > 0) placed.positions[size_t(l)] = sum / count;
    }
    placed.description += "; " + std::to_string(placed.triangulated) +
                          " triangulated lie on a dome of radius " +
                          format("%.4g m (RMS %.2g m off it), centre (%.3g, ", dome.radius_m,
                                 dome.rms_m, dome.centre.x()) +
                          format("%.3g, %.3g) m: every light placed where its rays meet it",
                                 dome.centre.y(), dome.centre.z());
  } else {
    for (int l = 0; l < n; ++l)
      placed.positions[size_t(l)] = estimates[size_t(l)].position_in_stage;
    placed.description += "; " + std::to_string(placed.triangulated) +
                          " positions where their rays cross (no dome fits them)";
  }
  for (int l = 0; l < n; ++l) {
    if (placed.positions[size_t(l)]) {
      placed.directions[size_t(l)] = placed.positions[size_t(l)]->normalized();
    }
  }
  if (options.radius_m <= 0) {
    placed.description += format(" (scale nominal, %.2g mm per pixel: no sphere radius given)",
                                 1e3 * placed.metres_per_pixel);
  }
  return placed;
}

}  // namespace ls::capture
