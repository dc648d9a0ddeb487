#include "relight/sources/source_render.h"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "lightstage/direction_index.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "relight/sources/shadow_geometry.h"

namespace ls::relight {

namespace {

constexpr double kInvPi = 1.0 / std::numbers::pi;
// A sample under this share of its Lambertian term is in a cast shadow. Half: a penumbra pixel is
// shadowed once the occluder covers more than half of the LED.
constexpr double kShadowRatio = 0.5;
// Lambertian terms under this share of the image's mean one are too dark to tell a shadow from a
// dark material (or are an attached shadow): such pixels take the nearest told pixel's answer.
constexpr double kLitDarkShare = 0.02;
// Near the terminator rough materials fall well below Lambert's cosine (Oren-Nayar): there only a
// sample under this share is a shadow (a cast shadow there is near black).
constexpr double kGrazingCosine = 0.2;
constexpr double kGrazingShadowRatio = 0.15;

Eigen::Vector3d pixel3(const Image& image, size_t p) {
  const float* v = &image.pixels[3 * p];
  return {v[0], v[1], v[2]};
}

// Lambertian term of a pixel toward a light, per channel, in field units.
Eigen::Vector3d lambert(const LambertianFit& fit, size_t p, const Eigen::Vector3d& dir) {
  return pixel3(fit.albedo, p) * (kInvPi * std::max(0.0, pixel3(fit.normal, p).dot(dir)));
}

// The signed distances as an 8-bit image for optical flow: 8 levels per pixel within 16 pixels of
// an edge, where the shapes are; flat farther away.
cv::Mat distance_image(const LedShadow& led) {
  cv::Mat image(led.height, led.width, CV_8U);
  for (size_t p = 0; p < led.edge_distance_px.size(); ++p) {
    image.data[p] = uchar(std::clamp(128.0f + 8.0f * led.edge_distance_px[p], 0.0f, 255.0f));
  }
  return image;
}

// The gloss as an 8-bit image for optical flow: log scaled, so that a highlight's shape and not
// only its peak is seen, from 1% of the brightest gloss up.
cv::Mat gloss_image(const LedShadow& led) {
  const size_t pixels = size_t(led.width) * led.height;
  std::vector<float> y(pixels);
  float peak = 0;
  for (size_t p = 0; p < pixels; ++p) {
    const float* g = &led.gloss_rgb[3 * p];
    y[p] = std::max(0.0f, luminance(g));
    peak = std::max(peak, y[p]);
  }
  cv::Mat image(led.height, led.width, CV_8U);
  const float floor = 0.01f * peak;
  for (size_t p = 0; p < pixels; ++p) {
    image.data[p] =
        peak > 0 && y[p] > floor
            ? uchar(std::clamp(255.0f * std::log(y[p] / floor) / std::log(100.0f), 0.0f, 255.0f))
            : 0;
  }
  return image;
}

cv::Mat dense_flow(const cv::Mat& from, const cv::Mat& to) {
  cv::Mat flow;
  cv::DISOpticalFlow::create(cv::DISOpticalFlow::PRESET_MEDIUM)->calc(from, to, flow);
  return flow;
}

std::vector<float> flow_values(const cv::Mat& flow) {
  const float* f = flow.ptr<float>();
  return {f, f + 2 * size_t(flow.rows) * flow.cols};
}

// Bilinear lookup of an image of `channels` (<= 3) floats per pixel, clamped at the border.
inline void bilinear_sample(const float* image, int width, int height, int channels, float x,
                            float y, float* out) {
  x = std::clamp(x, 0.0f, float(width - 1));
  y = std::clamp(y, 0.0f, float(height - 1));
  const int x0 = int(x), y0 = int(y);
  const int x1 = std::min(x0 + 1, width - 1), y1 = std::min(y0 + 1, height - 1);
  const float fx = x - float(x0), fy = y - float(y0);
  const float* a = image + (size_t(y0) * width + x0) * channels;
  const float* b = image + (size_t(y0) * width + x1) * channels;
  const float* c = image + (size_t(y1) * width + x0) * channels;
  const float* d = image + (size_t(y1) * width + x1) * channels;
  for (int ch = 0; ch < channels; ++ch) {
    out[ch] = (1 - fy) * ((1 - fx) * a[ch] + fx * b[ch]) + fy * ((1 - fx) * c[ch] + fx * d[ch]);
  }
}

}  // namespace

std::optional<LedTriangle> led_triangle(const std::vector<Eigen::Vector3d>& unit_dirs,
                                        const std::vector<bool>& usable, const Eigen::Vector3d& dir,
                                        double coverage_rad) {
  std::vector<int> near;
  for (int l = 0; l < int(unit_dirs.size()); ++l) {
    if (usable.empty() || usable[size_t(l)]) near.push_back(l);
  }
  if (near.empty()) return std::nullopt;
  const size_t count = std::min<size_t>(12, near.size());
  std::partial_sort(near.begin(), near.begin() + long(count), near.end(), [&](int a, int b) {
    return unit_dirs[size_t(a)].dot(dir) > unit_dirs[size_t(b)].dot(dir);
  });
  near.resize(count);
  std::optional<LedTriangle> best;
  double best_plane =
      -2;  // The containing triangle with the smallest circumcircle, if none is empty.
  for (size_t i = 0; i < count; ++i) {
    for (size_t j = i + 1; j < count; ++j) {
      for (size_t k = j + 1; k < count; ++k) {
        const Eigen::Vector3d& a = unit_dirs[size_t(near[i])];
        const Eigen::Vector3d& b = unit_dirs[size_t(near[j])];
        const Eigen::Vector3d& c = unit_dirs[size_t(near[k])];
        Eigen::Matrix3d m;
        m << a, b, c;
        if (std::abs(m.determinant()) < 1e-12) continue;
        const Eigen::Vector3d w = m.partialPivLu().solve(dir);
        if (w.minCoeff() < -1e-12) continue;
        // The circumcircle is where the plane through a, b, c cuts the sphere; Delaunay: no other
        // LED beyond that plane.
        Eigen::Vector3d normal = (b - a).cross(c - a).normalized();
        if (normal.dot(a) < 0) normal = -normal;
        const double plane = normal.dot(a);
        bool empty = true;
        for (size_t o = 0; o < count && empty; ++o) {
          if (o != i && o != j && o != k && normal.dot(unit_dirs[size_t(near[o])]) > plane + 1e-9) {
            empty = false;
          }
        }
        if (!empty && plane <= best_plane) continue;
        LedTriangle t;
        t.leds = {near[i], near[j], near[k]};
        const Eigen::Vector3d weights = w.cwiseMax(0.0) / w.cwiseMax(0.0).sum();
        t.weights = {weights[0], weights[1], weights[2]};
        if (empty) return t;
        best = t;
        best_plane = plane;
      }
    }
  }
  if (best) return best;
  const Eigen::Vector3d& nearest = unit_dirs[size_t(near.front())];
  if (angle_between(nearest, dir) > coverage_rad) return std::nullopt;
  return LedTriangle{{near.front(), near.front(), near.front()}, {1.0, 0.0, 0.0}};
}

LitMask led_lit_mask(const Eigen::Vector3d& led_dir, const std::vector<float>& rgb,
                     const LambertianFit& fit) {
  const int width = fit.normal.width, height = fit.normal.height;
  const size_t pixels = size_t(width) * height;
  LS_CHECK(rgb.size() == 3 * pixels && fit.albedo.pixels.size() == 3 * pixels,
           "led_lit_mask: the LED image and the Lambertian fit differ in size");
  const Eigen::Vector3d dir = led_dir.normalized();
  std::vector<double> expected(pixels);
  double sum = 0;
  size_t lit_count = 0;
  for (size_t p = 0; p < pixels; ++p) {
    expected[p] = luminance(lambert(fit, p, dir));
    if (expected[p] > 0) {
      sum += expected[p];
      ++lit_count;
    }
  }
  const double dark = kLitDarkShare * (lit_count ? sum / double(lit_count) : 0.0);
  // Where the Lambertian term is too dark to tell (attached shadow, black material) the nearest
  // told pixel's answer: edges then run only between what was seen lit and what was seen
  // shadowed, not along every terminator.
  LitMask lit(pixels);
  cv::Mat untold(height, width, CV_8U);
  for (size_t p = 0; p < pixels; ++p) {
    const double measured = luminance(Eigen::Vector3d(rgb[3 * p], rgb[3 * p + 1], rgb[3 * p + 2]));
    const double ratio =
        pixel3(fit.normal, p).dot(dir) < kGrazingCosine ? kGrazingShadowRatio : kShadowRatio;
    const bool told = expected[p] > dark;
    lit[p] = told && measured < ratio * expected[p] ? 0 : 1;
    untold.data[p] = told ? 0 : 255;
  }
  if (cv::countNonZero(untold) < int(pixels)) {
    cv::Mat distance, labels;
    cv::distanceTransform(untold, distance, labels, cv::DIST_L2, cv::DIST_MASK_5,
                          cv::DIST_LABEL_PIXEL);
    std::vector<std::uint8_t> answer_of_label(pixels + 1, 1);
    for (size_t p = 0; p < pixels; ++p) {
      if (!untold.data[p]) answer_of_label[size_t(labels.ptr<int>()[p])] = lit[p];
    }
    for (size_t p = 0; p < pixels; ++p) {
      if (untold.data[p]) lit[p] = answer_of_label[size_t(labels.ptr<int>()[p])];
    }
  }
  return lit;
}

LedShadow led_shadow(const Eigen::Vector3d& led_dir, std::vector<float> rgb,
                     const LambertianFit& fit) {
  const int width = fit.normal.width, height = fit.normal.height;
  const size_t pixels = size_t(width) * height;
  LedShadow shadow;
  shadow.dir = led_dir.normalized();
  shadow.width = width;
  shadow.height = height;
  LitMask mask = led_lit_mask(shadow.dir, rgb, fit);
  for (auto& v : mask) v = v ? 255 : 0;
  const cv::Mat lit(height, width, CV_8U, mask.data());
  // Distances to the nearest pixel of the other kind; the edge lies half a pixel from both sides.
  cv::Mat to_shadow, to_lit, shadowed;
  cv::distanceTransform(lit, to_shadow, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  cv::bitwise_not(lit, shadowed);
  cv::distanceTransform(shadowed, to_lit, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  const float limit = float(std::max(width, height)) / 4;
  shadow.edge_distance_px.resize(pixels);
  for (size_t p = 0; p < pixels; ++p) {
    const float d = lit.data[p] ? to_shadow.ptr<float>()[p] - 0.5f : 0.5f - to_lit.ptr<float>()[p];
    shadow.edge_distance_px[p] = std::clamp(d, -limit, limit);
  }
  shadow.gloss_rgb.assign(3 * pixels, 0.0f);
  for (size_t p = 0; p < pixels; ++p) {
    if (!lit.data[p]) continue;
    const Eigen::Vector3d excess =
        Eigen::Vector3d(rgb[3 * p], rgb[3 * p + 1], rgb[3 * p + 2]) - lambert(fit, p, shadow.dir);
    for (int c = 0; c < 3; ++c) shadow.gloss_rgb[3 * p + size_t(c)] = float(excess[c]);
  }
  shadow.rgb = std::move(rgb);
  return shadow;
}

LedPairFlow led_pair_flow(const LedShadow& from, const LedShadow& to) {
  LS_CHECK(from.width > 0 && from.width == to.width && from.height == to.height,
           "led_pair_flow: the LED shadows differ in size");
  return {flow_values(dense_flow(distance_image(from), distance_image(to))),
          flow_values(dense_flow(gloss_image(from), gloss_image(to)))};
}

void add_bright_source(const std::array<const LedShadow*, 3>& shadows, const PairFlows& flows,
                       const LedTriangle& triangle, const BrightSource& source,
                       const LambertianFit& fit, Image& out, const Image* visibility,
                       const Image* shape) {
  const int width = fit.normal.width, height = fit.normal.height;
  LS_CHECK(out.width == width && out.height == height && out.channels == 3,
           "add_bright_source: the output is not the field's size");
  LS_CHECK(!visibility || (visibility->width == width && visibility->height == height &&
                           visibility->channels == 1),
           "add_bright_source: the visibility is not one channel of the field's size");
  LS_CHECK(!shape || (shape->width == width && shape->height == height && shape->channels == 1),
           "add_bright_source: the shape's visibility is not one channel of the field's size");
  const float limit = float(std::max(width, height)) / 4;
  // Each LED's shadows move toward where the others have them, by the others' weights
  // (multi-image morphing, on the distance images).
  std::array<std::array<double, 3>, 3> angle{};
  for (int k = 0; k < 3; ++k) {
    for (int j = 0; j < 3; ++j) {
      const Eigen::Vector3d& a = shadows[size_t(k)]->dir;
      const Eigen::Vector3d& b = shadows[size_t(j)]->dir;
      angle[size_t(k)][size_t(j)] = angle_between(a, b);
      LS_CHECK(j == k || triangle.weights[size_t(k)] < kMinTriangleWeight ||
                   angle[size_t(k)][size_t(j)] <= 0 || flows[size_t(k)][size_t(j)] != nullptr,
               "add_bright_source: a flow from a weighted LED is missing");
    }
  }
  // The LEDs that carry weight, each with the flows toward the others (float, per pixel: this loop
  // runs for every frame of a turning sun). Toward an LED of no weight a flow moves nothing, but
  // still gives how fast the edges move: the penumbra of a source at an LED's own direction.
  struct Toward {
    const float* shadow_flow;
    const float* gloss_flow;
    float weight, inv_angle;
  };
  struct Active {
    const LedShadow* led;
    float weight;
    int towards = 0;
    std::array<Toward, 2> toward{};
  };
  std::array<Active, 3> active{};
  int count = 0;
  for (int k = 0; k < 3; ++k) {
    if (triangle.weights[size_t(k)] < kMinTriangleWeight) continue;
    Active& a = active[size_t(count++)];
    a = {shadows[size_t(k)], float(triangle.weights[size_t(k)])};
    for (int j = 0; j < 3; ++j) {
      const LedPairFlow* f = flows[size_t(k)][size_t(j)];
      if (j == k || f == nullptr || angle[size_t(k)][size_t(j)] <= 0) continue;
      a.toward[size_t(a.towards++)] = {f->shadow.data(), f->gloss.data(),
                                       float(triangle.weights[size_t(j)]),
                                       float(1 / angle[size_t(k)][size_t(j)])};
    }
  }
  const Eigen::Vector3f s = source.dir.normalized().cast<float>();
  const Eigen::Vector3f irradiance = source.irradiance_rgb.cast<float>();
  const float radius = float(source.radius_rad), max_half_width = limit / 4;
  tbb::parallel_for(0, height, [&](int y) {
    for (int x = 0; x < width; ++x) {
      const size_t p = size_t(y) * width + x;
      float distance_px = 0, speed = 0, shadow_weight = 0;
      float gloss[3] = {0, 0, 0}, in_shadow[3] = {0, 0, 0};
      for (int i = 0; i < count; ++i) {
        const Active& a = active[size_t(i)];
        // LED k's shadows and highlights displaced toward the source: by sum_j w_j flow[k][j]
        // (sampled where the pixel is; the flows are smooth).
        float dx = 0, dy = 0, gx = 0, gy = 0;
        for (int t = 0; t < a.towards; ++t) {
          const Toward& to = a.toward[size_t(t)];
          const float vx = to.shadow_flow[2 * p], vy = to.shadow_flow[2 * p + 1];
          dx += to.weight * vx;
          dy += to.weight * vy;
          gx += to.weight * to.gloss_flow[2 * p];
          gy += to.weight * to.gloss_flow[2 * p + 1];
          speed = std::max(speed, std::sqrt(vx * vx + vy * vy) * to.inv_angle);
        }
        const LedShadow& led = *a.led;
        float edge;
        bilinear_sample(led.edge_distance_px.data(), width, height, 1, float(x) - dx, float(y) - dy,
                        &edge);
        distance_px += a.weight * edge;
        float g[3];
        bilinear_sample(led.gloss_rgb.data(), width, height, 3, float(x) - gx, float(y) - gy, g);
        for (int c = 0; c < 3; ++c) gloss[c] += a.weight * g[c];
        if (led.edge_distance_px[p] <= 0) {
          for (int c = 0; c < 3; ++c) in_shadow[c] += a.weight * led.rgb[3 * p + size_t(c)];
          shadow_weight += a.weight;
        }
      }
      const float half_width = std::clamp(radius * speed, 0.5f, max_half_width);
      const float* n = &fit.normal.pixels[3 * p];
      const float cosine = std::max(0.0f, n[0] * s[0] + n[1] * s[1] + n[2] * s[2]) * float(kInvPi);
      const float* albedo = &fit.albedo.pixels[3 * p];
      float visible = std::clamp(0.5f + distance_px / (2 * half_width), 0.0f, 1.0f);
      if (visibility) {
        visible = visibility->pixels[p];
      } else if (shape && !std::isnan(shape->pixels[p])) {
        visible = shape->pixels[p];
      }
      float* o = &out.pixels[3 * p];
      for (int c = 0; c < 3; ++c) {
        const float shading = std::max(0.0f, albedo[c] * cosine + gloss[c]);
        const float bounced = shadow_weight > 0 ? in_shadow[c] / shadow_weight : 0.0f;
        o[c] += irradiance[c] * (visible * shading + (1 - visible) * bounced);
      }
    }
  });
}

}  // namespace ls::relight
