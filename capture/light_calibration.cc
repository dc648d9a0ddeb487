#include "capture/light_calibration.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "lightstage/angles.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/text.h"

namespace ls::capture {
namespace {

double luminance(const Image& image, size_t pixel) {
  const float* p = image.pixels.data() + pixel * image.channels;
  if (image.channels >= 3) return ls::luminance(p[0], p[1], p[2]);
  return p[0];
}

cv::Mat luminance_mat(const Image& image) {
  cv::Mat out(image.height, image.width, CV_32F);
  for (int y = 0; y < image.height; ++y) {
    float* row = out.ptr<float>(y);
    for (int x = 0; x < image.width; ++x)
      row[x] = float(luminance(image, size_t(y) * image.width + x));
  }
  return out;
}

}  // namespace

double angle_between_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  // atan2 of |a x b| and a.b stays accurate for tiny angles, unlike acos.
  return std::atan2(a.cross(b).norm(), a.dot(b)) / kDegToRad;
}

// ---------------------------------------------------------------------------------------------
// ViewCamera

ViewCamera ViewCamera::from_spec(const CameraSpec& camera) {
  ViewCamera v;
  v.width = camera.width;
  v.height = camera.height;
  v.cx = 0.5 * camera.width;
  v.cy = 0.5 * camera.height;
  if (camera.fov_y_deg <= 0) {
    v.orthographic = true;
    v.metres_per_pixel = camera.ortho_height_m / camera.height;
  } else {
    v.orthographic = false;
    v.fy = 0.5 * camera.height / std::tan(0.5 * camera.fov_y_deg * kDegToRad);
    v.fx = v.fy;  // Square pixels.
    v.centre_in_stage = Eigen::Vector3d(0, 0, camera.distance_m);
  }
  return v;
}

ViewCamera ViewCamera::orthographic_pixels(int width, int height) {
  ViewCamera v;
  v.width = width;
  v.height = height;
  v.cx = 0.5 * width;
  v.cy = 0.5 * height;
  v.orthographic = true;
  v.metres_per_pixel = 1.0;
  return v;
}

void ViewCamera::ray(const Eigen::Vector2d& pixel, Eigen::Vector3d* origin,
                     Eigen::Vector3d* dir) const {
  if (orthographic) {
    // Far in front of anything the image shows.
    const double z = 10.0 * (width + height) * metres_per_pixel;
    *origin = Eigen::Vector3d((pixel.x() - cx) * metres_per_pixel,
                              -(pixel.y() - cy) * metres_per_pixel, z);
    *dir = Eigen::Vector3d(0, 0, -1);
  } else {
    *origin = centre_in_stage;
    *dir = Eigen::Vector3d((pixel.x() - cx) / fx, -(pixel.y() - cy) / fy, -1.0).normalized();
  }
}

Eigen::Vector2d ViewCamera::project(const Eigen::Vector3d& p) const {
  if (orthographic) return {p.x() / metres_per_pixel + cx, -p.y() / metres_per_pixel + cy};
  const Eigen::Vector3d q = p - centre_in_stage;
  const double depth = std::max(-q.z(), 1e-12);
  return {cx + fx * q.x() / depth, cy - fy * q.y() / depth};
}

// ---------------------------------------------------------------------------------------------
// Spheres

std::vector<SphereOutline> find_sphere_outlines(const Image& reference, int max_spheres,
                                                double min_radius_px) {
  std::vector<SphereOutline> out;
  if (reference.width < 4 || reference.height < 4 || max_spheres < 1) return out;
  const cv::Mat lum = luminance_mat(reference);
  // Scale so that the brightest 0.1% saturate: robust to highlights, keeps 8 bits for Otsu.
  std::vector<float> sorted(lum.begin<float>(), lum.end<float>());
  const size_t k = size_t(0.999 * double(sorted.size() - 1));
  std::nth_element(sorted.begin(), sorted.begin() + k, sorted.end());
  const double top = sorted[k];
  if (!(top > 0)) return out;
  cv::Mat bytes;
  lum.convertTo(bytes, CV_8U, 255.0 / top);
  cv::Mat binary;
  cv::threshold(bytes, binary, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(binary, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  std::vector<std::pair<double, int>> by_area;
  for (size_t i = 0; i < contours.size(); ++i) {
    by_area.push_back({cv::contourArea(contours[i]), int(i)});
  }
  std::sort(by_area.rbegin(), by_area.rend());
  for (const auto& [area, index] : by_area) {
    if (int(out.size()) >= max_spheres) break;
    if (area < std::numbers::pi * min_radius_px * min_radius_px) break;
    // The region with its holes filled (dark reflections inside the sphere), then its moments.
    cv::Mat mask = cv::Mat::zeros(binary.size(), CV_8U);
    cv::drawContours(mask, contours, index, cv::Scalar(255), cv::FILLED);
    const cv::Moments m = cv::moments(mask, /*binaryImage=*/true);
    if (m.m00 <= 0) continue;
    SphereOutline s;
    s.center_px = Eigen::Vector2d(m.m10 / m.m00 + 0.5, m.m01 / m.m00 + 0.5);
    s.radius_px = std::sqrt(m.m00 / std::numbers::pi);
    // A uniform ellipse has second moments a^2/4 and b^2/4 along its axes.
    Eigen::Matrix2d cov;
    cov << m.mu20 / m.m00, m.mu11 / m.m00, m.mu11 / m.m00, m.mu02 / m.m00;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
    const double a = 2.0 * std::sqrt(std::max(eig.eigenvalues()(1), 0.0));
    const double b = 2.0 * std::sqrt(std::max(eig.eigenvalues()(0), 0.0));
    // Scale the axes so that pi a b equals the measured area (removes the pixelation bias).
    const double scale = a * b > 0 ? s.radius_px / std::sqrt(a * b) : 1.0;
    s.major_semi_axis_px = eig.eigenvectors().col(1) * a * scale;
    out.push_back(s);
  }
  std::sort(out.begin(), out.end(), [](const SphereOutline& l, const SphereOutline& r) {
    return l.center_px.x() < r.center_px.x();
  });
  return out;
}

std::optional<SphereOutline> find_sphere_circle_hough(const Image& reference, double min_radius_px,
                                                      double max_radius_px) {
  const cv::Mat lum = luminance_mat(reference);
  double lo = 0, hi = 0;
  cv::minMaxLoc(lum, &lo, &hi);
  if (!(hi > lo)) return std::nullopt;
  cv::Mat bytes;
  lum.convertTo(bytes, CV_8U, 255.0 / (hi - lo), -255.0 * lo / (hi - lo));
  cv::GaussianBlur(bytes, bytes, cv::Size(0, 0), 2.0);
  std::vector<cv::Vec3f> circles;
  cv::HoughCircles(bytes, circles, cv::HOUGH_GRADIENT, /*dp=*/2, /*minDist=*/min_radius_px,
                   /*param1=*/100, /*param2=*/50, int(min_radius_px), int(max_radius_px));
  if (circles.empty()) return std::nullopt;
  SphereOutline s;
  // OpenCV's pixel centres are integers; ours are at +0.5.
  s.center_px = Eigen::Vector2d(circles[0][0] + 0.5, circles[0][1] + 0.5);
  s.radius_px = circles[0][2];
  s.major_semi_axis_px = Eigen::Vector2d(s.radius_px, 0);
  return s;
}

std::vector<SphereOutline> outlines_from_circles(const std::vector<double>& circles) {
  std::vector<SphereOutline> outlines;
  for (size_t i = 0; i + 2 < circles.size(); i += 3) {
    SphereOutline o;
    o.center_px = Eigen::Vector2d(circles[i], circles[i + 1]);
    o.radius_px = circles[i + 2];
    o.major_semi_axis_px = Eigen::Vector2d(o.radius_px, 0);
    outlines.push_back(o);
  }
  return outlines;
}

MirrorSphere locate_sphere(const SphereOutline& outline, const ViewCamera& camera, double radius_m,
                           double center_z_m) {
  MirrorSphere s;
  if (camera.orthographic) {
    Eigen::Vector3d origin, dir;
    camera.ray(outline.center_px, &origin, &dir);
    s.center_in_stage = Eigen::Vector3d(origin.x(), origin.y(), center_z_m);
    s.radius_m = outline.radius_px * camera.metres_per_pixel;
    return s;
  }
  if (!(radius_m > 0)) {
    throw InputError("mirror sphere: radius_m: a pinhole camera needs the sphere's radius, got " +
                     std::to_string(radius_m));
  }
  // The tangent cone from the camera centre: its generators through the ends of the outline's
  // major axis make the half angle alpha with its axis, and sin(alpha) = radius / distance.
  Eigen::Vector2d axis = outline.major_semi_axis_px;
  if (axis.norm() < 1e-9) axis = Eigen::Vector2d(outline.radius_px, 0);
  Eigen::Vector3d o1, d1, o2, d2;
  camera.ray(outline.center_px - axis, &o1, &d1);
  camera.ray(outline.center_px + axis, &o2, &d2);
  const double alpha = 0.5 * std::atan2(d1.cross(d2).norm(), d1.dot(d2));
  s.radius_m = radius_m;
  s.center_in_stage =
      camera.centre_in_stage + (radius_m / std::sin(alpha)) * (d1 + d2).normalized();
  return s;
}

// ---------------------------------------------------------------------------------------------
// Highlights

namespace {

// The centroid of the area where `values` (pixel centres at +0.5; negative: outside the disc,
// taken as 0) interpolated bilinearly reach `threshold`, over `box` grown by a pixel: 8x8 samples
// per pixel. A clipped core's edge then moves with its neighbours' values, not a pixel at a time.
Eigen::Vector2d area_centroid(const cv::Mat& values, const cv::Rect& box, double threshold) {
  const int w = values.cols, h = values.rows;
  const auto value = [&](int x, int y) {
    return std::max(0.0f, values.at<float>(std::clamp(y, 0, h - 1), std::clamp(x, 0, w - 1)));
  };
  constexpr int kSub = 8;
  Eigen::Vector2d sum(0, 0);
  double area = 0;
  for (int y = std::max(0, box.y - 1); y <= std::min(h - 1, box.y + box.height); ++y) {
    for (int x = std::max(0, box.x - 1); x <= std::min(w - 1, box.x + box.width); ++x) {
      for (int j = 0; j < kSub; ++j) {
        for (int i = 0; i < kSub; ++i) {
          // In pixel-centre coordinates: pixel (x, y)'s centre is (x, y).
          const double px = x + (i + 0.5) / kSub - 0.5, py = y + (j + 0.5) / kSub - 0.5;
          const int ix = int(std::floor(px)), iy = int(std::floor(py));
          const double fx = px - ix, fy = py - iy;
          const double v = (1 - fy) * ((1 - fx) * value(ix, iy) + fx * value(ix + 1, iy)) +
                           fy * ((1 - fx) * value(ix, iy + 1) + fx * value(ix + 1, iy + 1));
          if (v < threshold) continue;
          sum += Eigen::Vector2d(px + 0.5, py + 0.5);
          area += 1;
        }
      }
    }
  }
  return area > 0 ? Eigen::Vector2d(sum / area)
                  : Eigen::Vector2d(box.x + 0.5 * box.width, box.y + 0.5 * box.height);
}

}  // namespace

std::optional<Highlight> find_highlight(const Image& image, const SphereOutline& outline,
                                        const HighlightOptions& options, std::string* problem) {
  const double r = outline.radius_px;
  const int x0 = std::max(0, int(std::floor(outline.center_px.x() - r)));
  const int x1 = std::min(image.width - 1, int(std::ceil(outline.center_px.x() + r)));
  const int y0 = std::max(0, int(std::floor(outline.center_px.y() - r)));
  const int y1 = std::min(image.height - 1, int(std::ceil(outline.center_px.y() + r)));
  if (x1 <= x0 || y1 <= y0) {
    *problem = "the sphere lies outside the image";
    return std::nullopt;
  }
  const int w = x1 - x0 + 1, h = y1 - y0 + 1;
  cv::Mat values(h, w, CV_32F, cv::Scalar(-1.0f));  // -1: outside the disc.
  std::vector<float> inside;
  double peak = 0;
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const Eigen::Vector2d d = Eigen::Vector2d(x + 0.5, y + 0.5) - outline.center_px;
      if (d.norm() > 0.995 * r) continue;
      const float v = float(luminance(image, size_t(y) * image.width + x));
      values.at<float>(y - y0, x - x0) = v;
      inside.push_back(v);
      peak = std::max(peak, double(v));
    }
  }
  if (inside.empty()) {
    *problem = "the sphere's disc holds no pixels";
    return std::nullopt;
  }
  auto percentile = [&](double q) {
    const size_t k = size_t(q * double(inside.size() - 1));
    std::nth_element(inside.begin(), inside.begin() + k, inside.end());
    return double(inside[k]);
  };
  const double p50 = percentile(0.5), p90 = percentile(0.9);
  // Pixel noise from neighbour differences (robust: their median absolute value), which a
  // reflection's smooth texture hardly raises: a dark frame's noise peak must not pass for a
  // highlight.
  std::vector<float> steps;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x + 1 < w; ++x) {
      const float a = values.at<float>(y, x), b = values.at<float>(y, x + 1);
      if (a >= 0 && b >= 0) steps.push_back(std::abs(a - b));
    }
  }
  double sigma = 0;
  if (!steps.empty()) {
    std::nth_element(steps.begin(), steps.begin() + steps.size() / 2, steps.end());
    sigma = 1.4826 * steps[steps.size() / 2] / std::sqrt(2.0);
  }
  if (!(peak > options.min_peak) || !(peak > options.min_contrast * std::max(p90, 0.0)) ||
      !(peak > p50 + options.min_snr * sigma)) {
    *problem = format_numbers(
        "no highlight: the brightest pixel (%.4g) does not stand out from the "
        "disc (median %.4g, 90th percentile %.4g)",
        peak, p50, p90);
    return std::nullopt;
  }
  const bool core = options.clipped_core_fraction > 0 && options.saturation_level > 0 &&
                    peak >= options.saturation_level;
  const double threshold = (core ? options.clipped_core_fraction : options.blob_fraction) * peak;
  cv::Mat mask = values > threshold;
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  std::vector<double> energy(n, 0.0), sx(n, 0.0), sy(n, 0.0);
  std::vector<int> count(n, 0), saturated(n, 0);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const int l = labels.at<int>(y, x);
      if (l == 0) continue;
      const double v = values.at<float>(y, x);
      const double wgt = v - threshold;
      energy[l] += wgt;
      sx[l] += wgt * (x0 + x + 0.5);
      sy[l] += wgt * (y0 + y + 0.5);
      ++count[l];
      if (options.saturation_level > 0 && v >= options.saturation_level) ++saturated[l];
    }
  }
  int best = 0, second = 0;
  for (int l = 1; l < n; ++l) {
    if (best == 0 || energy[l] > energy[best]) {
      second = best;
      best = l;
    } else if (second == 0 || energy[l] > energy[second]) {
      second = l;
    }
  }
  if (best == 0 || !(energy[best] > 0)) {
    *problem = "no highlight blob above the threshold";
    return std::nullopt;
  }
  if (second != 0 && energy[second] > options.second_blob_ratio * energy[best]) {
    *problem =
        format_numbers("two highlights: the second has %.0f%% of the first's energy, at %.0f px",
                       100.0 * energy[second] / energy[best],
                       (Eigen::Vector2d(sx[second] / energy[second], sy[second] / energy[second]) -
                        Eigen::Vector2d(sx[best] / energy[best], sy[best] / energy[best]))
                           .norm());
    return std::nullopt;
  }
  Highlight hl;
  hl.center_px = Eigen::Vector2d(sx[best] / energy[best], sy[best] / energy[best]);
  if (core) {
    const cv::Rect box(stats.at<int>(best, cv::CC_STAT_LEFT), stats.at<int>(best, cv::CC_STAT_TOP),
                       stats.at<int>(best, cv::CC_STAT_WIDTH),
                       stats.at<int>(best, cv::CC_STAT_HEIGHT));
    hl.center_px = Eigen::Vector2d(x0, y0) + area_centroid(values, box, threshold);
  }
  hl.peak = peak;
  hl.pixels = count[best];
  hl.saturated_pixels = saturated[best];
  return hl;
}

std::optional<LightRay> reflect_at(const ViewCamera& camera, const MirrorSphere& sphere,
                                   const Eigen::Vector2d& pixel) {
  Eigen::Vector3d o, d;
  camera.ray(pixel, &o, &d);
  const Eigen::Vector3d oc = o - sphere.center_in_stage;
  const double b = oc.dot(d);
  const double c = oc.squaredNorm() - sphere.radius_m * sphere.radius_m;
  const double disc = b * b - c;
  if (disc < 0) return std::nullopt;
  const double t = -b - std::sqrt(disc);
  const Eigen::Vector3d p = o + t * d;
  const Eigen::Vector3d n = (p - sphere.center_in_stage).normalized();
  const Eigen::Vector3d v = -d;
  LightRay ray;
  ray.origin = p;
  ray.dir = (2.0 * n.dot(v) * n - v).normalized();
  ray.normal_angle_deg = angle_between_deg(n, v);
  return ray;
}

std::optional<Eigen::Vector3d> closest_point_to_rays(const std::vector<LightRay>& rays,
                                                     double* rms_distance_m, double min_angle_deg) {
  if (rays.size() < 2) return std::nullopt;
  double widest = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    for (size_t j = i + 1; j < rays.size(); ++j) {
      widest = std::max(widest, angle_between_deg(rays[i].dir, rays[j].dir));
    }
  }
  if (widest < min_angle_deg) return std::nullopt;
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const LightRay& r : rays) {
    const Eigen::Matrix3d perp = Eigen::Matrix3d::Identity() - r.dir * r.dir.transpose();
    a += perp;
    b += perp * r.origin;
  }
  const Eigen::Vector3d p = a.ldlt().solve(b);
  if (!p.allFinite()) return std::nullopt;
  double sum2 = 0;
  for (const LightRay& r : rays) {
    if ((p - r.origin).dot(r.dir) <= 0) return std::nullopt;  // Behind a sphere.
    const Eigen::Vector3d q = p - r.origin;
    sum2 += (q - q.dot(r.dir) * r.dir).squaredNorm();
  }
  if (rms_distance_m) *rms_distance_m = std::sqrt(sum2 / double(rays.size()));
  return p;
}

DirectionCalibration calibrate_directions(const std::vector<const Image*>& images,
                                          const std::vector<std::string>& names,
                                          const std::vector<SphereOutline>& outlines,
                                          const std::vector<MirrorSphere>& spheres,
                                          const ViewCamera& camera,
                                          const DirectionOptions& options) {
  LS_CHECK(outlines.size() == spheres.size(), "one outline per sphere");
  LS_CHECK(names.size() == images.size(), "one name per image");
  DirectionCalibration result;
  for (size_t i = 0; i < images.size(); ++i) {
    LedDirectionEstimate est;
    est.led_index = int(i);
    const Image& image = *images[i];
    auto report = [&](int sphere, const std::string& what) {
      result.problems.push_back({int(i), sphere, names[i], what});
    };
    if (image.width != camera.width || image.height != camera.height) {
      report(-1, "image is " + std::to_string(image.width) + "x" + std::to_string(image.height) +
                     ", the camera " + std::to_string(camera.width) + "x" +
                     std::to_string(camera.height));
      result.leds.push_back(est);
      continue;
    }
    for (size_t s = 0; s < spheres.size(); ++s) {
      std::string problem;
      const auto hl = find_highlight(image, outlines[s], options.highlight, &problem);
      if (!hl) {
        report(int(s), problem);
        continue;
      }
      const auto ray = reflect_at(camera, spheres[s], hl->center_px);
      if (!ray) {
        report(int(s), "the highlight lies outside the sphere");
        continue;
      }
      if (ray->normal_angle_deg > options.highlight.max_normal_angle_deg) {
        report(int(s), format_numbers("highlight too near the rim (normal %.1f deg from the view)",
                                      ray->normal_angle_deg));
        continue;
      }
      est.rays.push_back(*ray);
    }
    if (est.rays.empty()) {
      result.leds.push_back(est);
      continue;
    }
    est.ok = true;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const LightRay& r : est.rays) mean += r.dir;
    est.dir_in_stage = mean.normalized();
    std::vector<LightRay> steady;  // Rays good enough to triangulate with.
    for (const LightRay& r : est.rays) {
      if (r.normal_angle_deg <= options.max_triangulation_normal_deg) steady.push_back(r);
    }
    double miss = 0;
    if (const auto p = closest_point_to_rays(steady, &miss, options.min_triangulation_angle_deg);
        p && p->norm() <= options.max_distance_m && p->norm() > 0) {
      est.position_in_stage = *p;
      est.ray_miss_m = miss;
      est.dir_in_stage = p->normalized();
    }
    result.leds.push_back(est);
  }
  return result;
}

// ---------------------------------------------------------------------------------------------
// White target

StageUpdate apply_directions(const DirectionCalibration& calibration, Stage* stage) {
  StageUpdate update;
  for (const LedDirectionEstimate& e : calibration.leds) {
    if (!e.ok || e.led_index < 0 || e.led_index >= int(stage->leds.size())) continue;
    Led& led = stage->leds[e.led_index];
    led.dir_in_stage = e.dir_in_stage.normalized();
    if (e.position_in_stage) led.distance_m = e.position_in_stage->norm();
    ++update.directions_changed;
  }
  return update;
}

}  // namespace ls::capture
