#include "sim/calibration_targets.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "lightstage/angles.h"
#include "lightstage/direction_index.h"  // angle_between
#include "lightstage/errors.h"

namespace ls::sim {
namespace {

constexpr double kReferenceDistanceM = 1.0;  // Sets a distant LED's angular size.

// The simulator's camera (sim_stage.cc camera_ray), written out again here so that calibration
// code, which has its own camera model, is checked against an independent one.
void camera_ray_at(const CameraSpec& camera, double px, double py, Eigen::Vector3d* origin,
                   Eigen::Vector3d* dir) {
  const double aspect = double(camera.width) / camera.height;
  const double ndc_x = 2.0 * px / camera.width - 1.0;
  const double ndc_y = 1.0 - 2.0 * py / camera.height;
  if (camera.fov_y_deg <= 0.0) {
    const double half_h = 0.5 * camera.ortho_height_m;
    *origin = Eigen::Vector3d(ndc_x * half_h * aspect, ndc_y * half_h, 100.0);
    *dir = Eigen::Vector3d(0, 0, -1);
  } else {
    const double tan_half = std::tan(0.5 * camera.fov_y_deg * kDegToRad);
    *origin = Eigen::Vector3d(0, 0, camera.distance_m);
    *dir = Eigen::Vector3d(ndc_x * tan_half * aspect, ndc_y * tan_half, -1.0).normalized();
  }
}

// Nearest ball along the ray: the reflected ray's origin and direction.
bool reflect(const std::vector<MirrorBall>& balls, const Eigen::Vector3d& o,
             const Eigen::Vector3d& d, Eigen::Vector3d* p, Eigen::Vector3d* r) {
  double best = 1e300;
  int hit = -1;
  for (size_t i = 0; i < balls.size(); ++i) {
    const Eigen::Vector3d oc = o - balls[i].center;
    const double b = oc.dot(d);
    const double disc = b * b - (oc.squaredNorm() - balls[i].radius_m * balls[i].radius_m);
    if (disc < 0) continue;
    const double t = -b - std::sqrt(disc);
    if (t > 0 && t < best) {
      best = t;
      hit = int(i);
    }
  }
  if (hit < 0) return false;
  *p = o + best * d;
  const Eigen::Vector3d n = (*p - balls[hit].center).normalized();
  *r = d - 2.0 * d.dot(n) * n;
  return true;
}

// Solid angle of a disc (or ball) of angular radius alpha.
double cap_solid_angle(double alpha) { return 2.0 * std::numbers::pi * (1.0 - std::cos(alpha)); }

}  // namespace

PerturbedStage perturb_stage(const Stage& nominal, const StagePerturbation& p) {
  PerturbedStage out;
  out.truth = nominal;
  std::mt19937_64 rng(p.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  const double per_axis = p.direction_sigma_deg * kDegToRad / std::sqrt(2.0);
  for (Led& led : out.truth.leds) {
    const Eigen::Vector3d d = led.dir_in_stage.normalized();
    Eigen::Vector3d t1 = d.unitOrthogonal(), t2 = d.cross(t1);
    const Eigen::Vector2d offset(per_axis * normal(rng), per_axis * normal(rng));
    const double a = offset.norm();
    if (a > 0) {
      const Eigen::Vector3d axis = (offset.x() * t2 - offset.y() * t1).normalized();
      led.dir_in_stage = (Eigen::AngleAxisd(a, axis) * d).normalized();
    }
    led.intensity *= 1.0 + p.intensity_jitter * uniform(rng);
    for (int c = 0; c < 3; ++c) led.color_gain[c] *= 1.0 + p.color_jitter * uniform(rng);
    if (p.dome_radius_m) {
      led.distance_m = *p.dome_radius_m * (1.0 + 0.02 * uniform(rng));
    } else {
      led.distance_m.reset();
    }
    LedBeam beam;
    beam.gx = p.beam_gradient_per_m * normal(rng);
    beam.gy = p.beam_gradient_per_m * normal(rng);
    beam.k = p.beam_gradient_per_m * normal(rng);
    out.beams.push_back(beam);
  }
  return out;
}

Image apply_sensor(const Image& radiance, const SensorModel& sensor, uint64_t seed) {
  LS_CHECK(sensor.full_scale > 0 && sensor.bit_depth >= 1 && sensor.bit_depth <= 16,
           "sensor: full scale " + std::to_string(sensor.full_scale) + ", bit depth " +
               std::to_string(sensor.bit_depth));
  Image out = radiance;
  if (sensor.blur_sigma_px > 0) {
    for (int c = 0; c < out.channels; ++c) {
      cv::Mat plane(out.height, out.width, CV_32F);
      for (size_t i = 0; i < out.num_pixels(); ++i) {
        plane.at<float>(int(i)) = out.pixels[i * out.channels + c];
      }
      cv::GaussianBlur(plane, plane, cv::Size(0, 0), sensor.blur_sigma_px);
      for (size_t i = 0; i < out.num_pixels(); ++i) {
        out.pixels[i * out.channels + c] = plane.at<float>(int(i));
      }
    }
  }
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double max_dn = double((1u << sensor.bit_depth) - 1u);
  const double read2 = sensor.read_noise_e * sensor.read_noise_e;
  for (float& v : out.pixels) {
    const double mean_e = std::max(0.0, double(v)) / sensor.full_scale * sensor.full_well_e;
    // Shot and read noise (normal approximation; the targets are well exposed).
    double e = mean_e + std::sqrt(mean_e + read2) * normal(rng);
    e = std::clamp(e, 0.0, sensor.full_well_e);
    const double dn = std::round(e / sensor.full_well_e * max_dn);
    v = float(dn / max_dn * sensor.full_scale);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------

struct MirrorSphereRenderer::Rays {
  CameraSpec camera;
  int supersample = 4;
  // Per pixel, the reflected ray through its centre and how far (radians) the reflected direction
  // strays inside the pixel; a negative spread marks a pixel that misses every ball.
  std::vector<Eigen::Vector3f> origin, dir;
  std::vector<float> spread;
};

MirrorSphereRenderer::MirrorSphereRenderer(std::vector<MirrorBall> balls, const CameraSpec& camera,
                                           int supersample)
    : balls_(std::move(balls)),
      width_(camera.width),
      height_(camera.height),
      rays_(std::make_unique<Rays>()) {
  rays_->camera = camera;
  rays_->supersample = std::max(1, supersample);
  const size_t n = size_t(width_) * height_;
  rays_->origin.resize(n);
  rays_->dir.resize(n);
  rays_->spread.assign(n, -1.0f);
  tbb::parallel_for(tbb::blocked_range<int>(0, height_), [&](const auto& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width_; ++x) {
        const size_t i = size_t(y) * width_ + x;
        Eigen::Vector3d o, d, p, r;
        camera_ray_at(camera, x + 0.5, y + 0.5, &o, &d);
        const bool centre_hit = reflect(balls_, o, d, &p, &r);
        double spread = 0;
        bool any_hit = centre_hit, all_hit = centre_hit;
        for (int corner = 0; corner < 4; ++corner) {
          Eigen::Vector3d oc, dc, pc, rc;
          camera_ray_at(camera, x + (corner & 1), y + (corner >> 1), &oc, &dc);
          const bool hit = reflect(balls_, oc, dc, &pc, &rc);
          any_hit |= hit;
          all_hit &= hit;
          if (hit && centre_hit) spread = std::max(spread, angle_between(r, rc));
        }
        if (!any_hit) continue;
        // Pixels on an outline are always sampled in full.
        rays_->spread[i] = all_hit ? float(3.0 * spread + 1e-3) : float(std::numbers::pi);
        if (centre_hit) {
          rays_->origin[i] = p.cast<float>();
          rays_->dir[i] = r.cast<float>();
        } else {
          rays_->origin[i] = o.cast<float>();
          rays_->dir[i] = d.cast<float>();
        }
      }
    }
  });
}

MirrorSphereRenderer::~MirrorSphereRenderer() = default;

Image MirrorSphereRenderer::render_led(const Led& led, double led_radius_m,
                                       double reflectance) const {
  Image out(width_, height_, 3);
  const Eigen::Vector3d dir = led.dir_in_stage.normalized();
  const bool near = led.distance_m.has_value();
  const double distance = near ? *led.distance_m : kReferenceDistanceM;
  const Eigen::Vector3d led_pos = distance * dir;
  const double alpha = std::asin(std::min(1.0, led_radius_m / distance));
  // Uniform radiance over the LED's disc, so that its irradiance at the origin is irradiance_rgb.
  const Eigen::Vector3d led_radiance = led.irradiance_rgb() / cap_solid_angle(alpha);
  const int ss = rays_->supersample;
  tbb::parallel_for(tbb::blocked_range<int>(0, height_), [&](const auto& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width_; ++x) {
        const size_t i = size_t(y) * width_ + x;
        const float spread = rays_->spread[i];
        if (spread < 0) continue;
        const Eigen::Vector3d p0 = rays_->origin[i].cast<double>();
        const Eigen::Vector3d r0 = rays_->dir[i].cast<double>();
        const Eigen::Vector3d toward = near ? (led_pos - p0).normalized() : dir;
        const double reach =
            near ? std::asin(std::min(1.0, led_radius_m / (led_pos - p0).norm())) : alpha;
        if (spread < std::numbers::pi && angle_between(r0, toward) > reach + spread + 1e-3)
          continue;
        int lit = 0;
        for (int sy = 0; sy < ss; ++sy) {
          for (int sx = 0; sx < ss; ++sx) {
            Eigen::Vector3d o, d, p, r;
            camera_ray_at(rays_->camera, x + (sx + 0.5) / ss, y + (sy + 0.5) / ss, &o, &d);
            if (!reflect(balls_, o, d, &p, &r)) continue;
            if (near) {
              // Does the reflected ray meet the LED's ball?
              const Eigen::Vector3d oc = p - led_pos;
              const double b = oc.dot(r);
              const double disc = b * b - (oc.squaredNorm() - led_radius_m * led_radius_m);
              if (disc >= 0 && -b - std::sqrt(disc) > 0) ++lit;
            } else if (angle_between(r, dir) <= alpha) {
              ++lit;
            }
          }
        }
        if (lit == 0) continue;
        const double fraction = double(lit) / (ss * ss);
        for (int c = 0; c < 3; ++c)
          out.at(x, y, c) = float(reflectance * fraction * led_radiance[c]);
      }
    }
  });
  return out;
}

Image MirrorSphereRenderer::render_reference(double environment_radiance,
                                             double reflectance) const {
  Image out(width_, height_, 3);
  const int ss = rays_->supersample;
  tbb::parallel_for(tbb::blocked_range<int>(0, height_), [&](const auto& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width_; ++x) {
        const size_t i = size_t(y) * width_ + x;
        if (rays_->spread[i] < 0) continue;
        int hits = ss * ss;
        if (rays_->spread[i] >=
            std::numbers::pi) {  // An outline pixel: count the samples on a ball.
          hits = 0;
          for (int sy = 0; sy < ss; ++sy) {
            for (int sx = 0; sx < ss; ++sx) {
              Eigen::Vector3d o, d, p, r;
              camera_ray_at(rays_->camera, x + (sx + 0.5) / ss, y + (sy + 0.5) / ss, &o, &d);
              hits += reflect(balls_, o, d, &p, &r);
            }
          }
        }
        const float v = float(reflectance * environment_radiance * hits / (ss * ss));
        for (int c = 0; c < 3; ++c) out.at(x, y, c) = v;
      }
    }
  });
  return out;
}

Image render_white_plane(const WhitePlaneTarget& target, const Led& led, const LedBeam& beam,
                         const CameraSpec& camera) {
  Image out(camera.width, camera.height, 3);
  const Eigen::Vector3d n(0, 0, 1);
  const Eigen::Vector3d dir = led.dir_in_stage.normalized();
  const bool near = led.distance_m.has_value();
  const Eigen::Vector3d led_pos = near ? Eigen::Vector3d(*led.distance_m * dir) : dir;
  const Eigen::Vector3d e0 = led.irradiance_rgb();
  tbb::parallel_for(tbb::blocked_range<int>(0, camera.height), [&](const auto& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < camera.width; ++x) {
        Eigen::Vector3d o, d;
        camera_ray_at(camera, x + 0.5, y + 0.5, &o, &d);
        if (std::abs(d.z()) < 1e-12) continue;
        const Eigen::Vector3d p = o + ((target.center.z() - o.z()) / d.z()) * d;
        double geometry;  // Irradiance on the plane per unit irradiance at the origin.
        if (near) {
          const Eigen::Vector3d to_led = led_pos - p;
          geometry = std::max(0.0, n.dot(to_led.normalized())) * led_pos.squaredNorm() /
                     to_led.squaredNorm();
        } else {
          geometry = std::max(0.0, n.dot(dir));
        }
        const double scale = target.albedo / std::numbers::pi * geometry * beam.at(p.x(), p.y());
        for (int c = 0; c < 3; ++c) out.at(x, y, c) = float(scale * e0[c]);
      }
    }
  });
  return out;
}

BoardPose board_facing_camera(const Chessboard& board, const Eigen::Vector3d& center_in_stage,
                              double tilt_x_deg, double tilt_y_deg) {
  // Untilted: board x along stage +X, board y (rows) along stage -Y, so the printed side (-z in
  // the board frame) faces stage +Z, the camera, and the image shows the board upright.
  Eigen::Matrix3d facing;
  facing << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  const Eigen::Matrix3d tilt =
      (Eigen::AngleAxisd(tilt_y_deg * kDegToRad, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(tilt_x_deg * kDegToRad, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  BoardPose pose;
  pose.rotation = tilt * facing;
  const Eigen::Vector3d board_centre(0.5 * (board.inner_cols - 1) * board.square_m,
                                     0.5 * (board.inner_rows - 1) * board.square_m, 0.0);
  pose.translation = center_in_stage - pose.rotation * board_centre;
  return pose;
}

Image render_chessboard(const Chessboard& board, const BoardPose& pose, const CameraSpec& camera,
                        int supersample) {
  LS_CHECK(board.inner_cols >= 2 && board.inner_rows >= 2 && board.square_m > 0,
           "chessboard: " + std::to_string(board.inner_cols) + "x" +
               std::to_string(board.inner_rows) + " corners, square " +
               std::to_string(board.square_m) + " m");
  const int ss = std::max(1, supersample);
  const Eigen::Matrix3d board_from_stage = pose.rotation.transpose();
  // Squares are indexed from the one left of and above the first inner corner (-1, -1); the card
  // reaches one square beyond the pattern on every side.
  const double lo = -2.0 * board.square_m;
  const double hi_x = (board.inner_cols + 1) * board.square_m;
  const double hi_y = (board.inner_rows + 1) * board.square_m;
  Image out(camera.width, camera.height, 3);
  tbb::parallel_for(tbb::blocked_range<int>(0, camera.height), [&](const auto& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < camera.width; ++x) {
        double sum = 0;
        for (int sy = 0; sy < ss; ++sy) {
          for (int sx = 0; sx < ss; ++sx) {
            Eigen::Vector3d o, d;
            camera_ray_at(camera, x + (sx + 0.5) / ss, y + (sy + 0.5) / ss, &o, &d);
            const Eigen::Vector3d ob = board_from_stage * (o - pose.translation);
            const Eigen::Vector3d db = board_from_stage * d;
            if (std::abs(db.z()) < 1e-12) continue;
            const double t = -ob.z() / db.z();
            if (t <= 0) continue;
            const Eigen::Vector3d p = ob + t * db;
            if (p.x() < lo || p.x() > hi_x || p.y() < lo || p.y() > hi_y) continue;
            const int i = int(std::floor(p.x() / board.square_m));
            const int j = int(std::floor(p.y() / board.square_m));
            const bool in_pattern =
                i >= -1 && i < board.inner_cols && j >= -1 && j < board.inner_rows;
            const bool black = in_pattern && ((i + j) % 2 + 2) % 2 == 0;
            sum += black ? board.black_radiance : board.white_radiance;
          }
        }
        const float v = float(sum / (ss * ss));
        for (int c = 0; c < 3; ++c) out.at(x, y, c) = v;
      }
    }
  });
  return out;
}

}  // namespace ls::sim
