#include "capture/sphere_lights.h"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <numbers>

#include "lightstage/text.h"

namespace ls::capture {

namespace {

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

// The mean of where the rays leave the dome, or nullopt when none does.
std::optional<Eigen::Vector3d> where_rays_meet(const std::vector<LightRay>& rays,
                                               const FittedDome& dome) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int count = 0;
  for (const LightRay& ray : rays) {
    if (const auto p = exit_point(ray, dome)) {
      sum += *p;
      ++count;
    }
  }
  if (count == 0) return std::nullopt;
  return sum / count;
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

// A sphere of radius_m seen by a pinhole camera, from the circle fitted to its outline. The
// outline is an ellipse whose major axis is radial, its ends at theta +- alpha off the axis
// (theta: the centre's angle, sin alpha = radius / distance), its minor semi-axis
// f sin(alpha) / sqrt(cos^2 theta - sin^2 alpha): the circle's centre lies outward of the
// centre's image and its radius is the mean semi-axis, each off by a pixel at 15 deg off the
// axis. theta and alpha are solved for so that the ellipse has the circle's centre and area.
MirrorSphere locate_pinhole_sphere(const SphereOutline& outline, const ViewCamera& camera,
                                   double radius_m) {
  const Eigen::Vector2d principal(camera.cx, camera.cy);
  const Eigen::Vector2d offset = outline.center_px - principal;
  const double f = camera.fx, rho = offset.norm();
  const Eigen::Vector2d radial = rho > 1e-9 ? Eigen::Vector2d(offset / rho) : Eigen::Vector2d(1, 0);
  double theta = std::atan(rho / f), alpha = std::atan(outline.radius_px / f);
  for (int i = 0; i < 50; ++i) {
    const double a = 0.5 * f * (std::tan(theta + alpha) - std::tan(theta - alpha));
    const double b =
        f * std::sin(alpha) /
        std::sqrt(std::max(1e-12, std::pow(std::cos(theta), 2) - std::pow(std::sin(alpha), 2)));
    const double centre = 0.5 * f * (std::tan(theta + alpha) + std::tan(theta - alpha));
    theta += std::atan(rho / f) - std::atan(centre / f);
    alpha *= outline.radius_px / std::sqrt(a * b);
  }
  Eigen::Vector3d origin, dir;
  camera.ray(principal + f * std::tan(theta) * radial, &origin, &dir);
  return {origin + radius_m / std::sin(alpha) * dir, radius_m};
}

// The camera and the spheres it sees, rows y0..y1 of width x height images (outlines in the
// rows' pixels).
struct SphereView {
  ViewCamera camera;
  std::vector<MirrorSphere> spheres;
  FieldView view;
  double scene_m = 0;    // The size of what the camera sees: triangulations 1000x further are not.
  std::string geometry;  // Said of positions.
};

SphereView view_spheres(const std::vector<SphereOutline>& outlines, int width, int height, int y0,
                        int y1, const SphereLightOptions& options) {
  SphereView seen;
  ViewCamera& camera = seen.camera;
  camera = ViewCamera::orthographic_pixels(width, y1 - y0);
  camera.cy = 0.5 * height - y0;
  if (options.focal_length_px > 0) {
    camera.orthographic = false;
    camera.fx = camera.fy = options.focal_length_px;
    // Placed with the camera at the origin, then the frame moved so that the table they rest on
    // is z = 0 (their mean; the spread says how far the camera is from looking straight down).
    camera.centre_in_stage = Eigen::Vector3d::Zero();
    double table_z = 0, lowest = 0, highest = 0;
    for (size_t s = 0; s < outlines.size(); ++s) {
      seen.spheres.push_back(locate_pinhole_sphere(outlines[s], camera, options.radius_m));
      const double z = seen.spheres.back().center_in_stage.z() - options.radius_m;
      table_z += z / double(outlines.size());
      lowest = s == 0 ? z : std::min(lowest, z);
      highest = s == 0 ? z : std::max(highest, z);
    }
    camera.centre_in_stage.z() = -table_z;
    for (MirrorSphere& sphere : seen.spheres) sphere.center_in_stage.z() -= table_z;
    const double fov_y_deg =
        2 * std::atan(0.5 * height / options.focal_length_px) * 180 / std::numbers::pi;
    seen.view = FieldView{fov_y_deg, -table_z, 2.4, 0.0};
    seen.scene_m = -table_z;
    seen.geometry = format_numbers("; pinhole view %.3g deg high from %.4g m above the table",
                                   fov_y_deg, -table_z);
    if (outlines.size() > 1) {
      seen.geometry +=
          format_numbers(" (the spheres rest %.1f mm apart in height)", 1e3 * (highest - lowest));
    }
  } else {
    camera.metres_per_pixel =
        options.radius_m > 0 ? options.radius_m / outlines[0].radius_px : kNominalMetresPerPixel;
    for (const SphereOutline& o : outlines) {
      const double radius_m = o.radius_px * camera.metres_per_pixel;
      seen.spheres.push_back(locate_sphere(o, camera, radius_m, radius_m));  // Resting on z = 0.
    }
    seen.view = FieldView{0.0, 4.0, height * camera.metres_per_pixel, 0.0};
    seen.scene_m = (width + height) * camera.metres_per_pixel;
    if (options.radius_m <= 0) {
      seen.geometry = format_numbers(" (scale nominal, %.2g mm per pixel: no sphere radius given)",
                                     1e3 * camera.metres_per_pixel);
    }
  }
  return seen;
}

}  // namespace

std::string SphereLightOptions::validate(int image_width, int image_height) const {
  if (!(radius_m >= 0) || !std::isfinite(radius_m)) {
    return "sphere radius: expected 0 (unknown) or a positive size in metres, got " +
           std::to_string(radius_m);
  }
  if (!(focal_length_px >= 0) || !std::isfinite(focal_length_px)) {
    return format_numbers(
        "focal length: expected 0 (orthographic) or a positive number of pixels, got %g",
        focal_length_px);
  }
  if (focal_length_px > 0 && !(radius_m > 0)) {
    return "focal length: a pinhole camera needs the spheres' radius (to place them in depth)";
  }
  for (size_t s = 0; s < outlines.size(); ++s) {
    const SphereOutline& o = outlines[s];
    const std::string which = "sphere " + std::to_string(s + 1);
    if (!(o.radius_px >= 4)) {
      return which + format_numbers(": radius: expected at least 4 pixels, got %g", o.radius_px);
    }
    if (!(o.center_px.x() - o.radius_px >= 0 && o.center_px.y() - o.radius_px >= 0 &&
          o.center_px.x() + o.radius_px <= image_width &&
          o.center_px.y() + o.radius_px <= image_height)) {
      return which +
             format_numbers(": expected inside the %gx%g images, got centre (%g, ", image_width,
                            image_height, o.center_px.x()) +
             format_numbers("%g) radius %g", o.center_px.y(), o.radius_px);
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
  const int spheres_given = int(options.outlines.size());
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
  std::vector<SphereOutline> outlines = options.outlines;
  for (SphereOutline& o : outlines) o.center_px.y() -= y0;
  const SphereView seen = view_spheres(outlines, width, height, y0, y1, options);
  const ViewCamera& camera = seen.camera;
  const std::vector<MirrorSphere>& spheres = seen.spheres;
  placed.view = seen.view;
  // A light above the table (z > 0) is mirrored within sin(45 deg) = 0.71 of the radius from the
  // centre: the highlight is looked for within 0.85 of it, clear of the rim, which mirrors the
  // lit table and has the backdrop blurred into it (a blob reaching it is pulled outward).
  std::vector<SphereOutline> search = outlines;
  for (SphereOutline& o : search) o.radius_px *= 0.85;
  DirectionOptions direction_options;
  direction_options.highlight = options.highlight;
  direction_options.max_distance_m = 1e3 * seen.scene_m;

  std::vector<LedDirectionEstimate> estimates(static_cast<size_t>(n));
  std::mutex problems_mutex;
  ProgressCount done(progress, "spheres", n);
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
    done.finished_one();
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
  const int found = int(std::count_if(placed.directions.begin(), placed.directions.end(),
                                      [](const auto& d) { return d.has_value(); }));
  placed.description = std::to_string(found) + " of " + std::to_string(n) + " lights found on " +
                       std::to_string(spheres_given) + " sphere" + (spheres_given > 1 ? "s" : "");
  if (spheres_given < 2) {
    placed.description += ": directions only (a second sphere gives positions)";
    return placed;
  }
  const std::string triangulated = std::to_string(crossed.size());
  if (const std::optional<FittedDome> fitted = fit_dome(crossed)) {
    const FittedDome& dome = *fitted;
    for (int l = 0; l < n; ++l) {
      placed.positions[size_t(l)] = where_rays_meet(estimates[size_t(l)].rays, dome);
    }
    placed.description += "; " + triangulated + " triangulated lie on a dome of radius " +
                          format_numbers("%.4g m (RMS %.2g m off it), centre (%.3g, ",
                                         dome.radius_m, dome.rms_m, dome.centre.x()) +
                          format_numbers("%.3g, %.3g) m: every light placed where its rays meet it",
                                         dome.centre.y(), dome.centre.z());
  } else {
    for (int l = 0; l < n; ++l)
      placed.positions[size_t(l)] = estimates[size_t(l)].position_in_stage;
    placed.description +=
        "; " + triangulated + " positions where their rays cross (no dome fits them)";
  }
  for (int l = 0; l < n; ++l) {
    if (placed.positions[size_t(l)]) {
      placed.directions[size_t(l)] = placed.positions[size_t(l)]->normalized();
    }
  }
  placed.description += seen.geometry;
  return placed;
}

}  // namespace ls::capture
