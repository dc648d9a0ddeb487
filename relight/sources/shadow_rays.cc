// The shadow rays through the scene's recovered depth map (ShadowGeometry::sees): a pyramid of
// each block's highest top, which a rising ray skips once above it.
#include <algorithm>
#include <cmath>
#include <vector>

#include "relight/sources/depth_map_pixel.h"
#include "relight/sources/shadow_geometry.h"

namespace ls::relight {

namespace {

constexpr float kRayStartPx = 0.1f;  // Above its own surface a ray starts at.
// Neighbouring depth samples within this many pixels of height are one surface (a field pixel
// between them takes their interpolated height).
constexpr float kOneSurfaceStepPx = 3.0f;

// Along a ray from (u, v), the first step whose pixel, (x, y) now, leaves its 2^level block;
// within a step of it (float rounding), so a caller steps back one.
int first_step_outside(const ShadowRayDirection& ray, float u, float v, int x, int y, int level) {
  float steps = 1e9f;  // More steps than any ray takes.
  const float from[2] = {u, v}, along[2] = {ray.dx, ray.dy};
  const int at[2] = {x, y};
  for (int a = 0; a < 2; ++a) {
    if (along[a] == 0) continue;
    // Pixel q holds coordinates [q - 0.5, q + 0.5) (pixel_of).
    const int block = (at[a] >> level) << level;
    const float edge = float(along[a] > 0 ? block + (1 << level) : block) - 0.5f;
    steps = std::min(steps, (edge - from[a]) * ray.steps_per_px[a]);
  }
  return int(std::ceil(steps));
}

}  // namespace

void ShadowGeometry::build_block_pyramid() {
  for (const float z : top_px_) highest_px_ = std::max(highest_px_, z);
  const std::vector<float>* finer = &top_px_;
  for (int level = 1; (1 << (level - 1)) < std::max(width_, height_); ++level) {
    const int w = ((width_ - 1) >> level) + 1, h = ((height_ - 1) >> level) + 1;
    const int fw = ((width_ - 1) >> (level - 1)) + 1, fh = ((height_ - 1) >> (level - 1)) + 1;
    std::vector<float> block(size_t(w) * h, kNoSurface);
    for (int y = 0; y < fh; ++y) {
      for (int x = 0; x < fw; ++x) {
        float& b = block[size_t(y / 2) * w + size_t(x / 2)];
        b = std::max(b, (*finer)[size_t(y) * fw + x]);
      }
    }
    finer = &highest_in_block_.emplace_back(std::move(block));
  }
}

ShadowRayDirection ShadowGeometry::ray_direction(const Eigen::Vector3f& dir) {
  ShadowRayDirection ray;
  ray.dx = dir.x(), ray.dy = -dir.y(), ray.dz = dir.z();
  const float dxy = std::hypot(ray.dx, ray.dy);
  if (dxy < 1e-6f) return ray;  // Straight up: nothing is in the way.
  ray.step = 0.5f / dxy;
  if (ray.dx != 0) ray.steps_per_px[0] = 1 / (ray.step * ray.dx);
  if (ray.dy != 0) ray.steps_per_px[1] = 1 / (ray.step * ray.dy);
  return ray;
}

ShadowRayStart ShadowGeometry::ray_start(int x, int y) const {
  ShadowRayStart start;
  // The field pixel's centre in depth-map pixels.
  start.u = (float(x) + 0.5f) / float(scale_) - 0.5f;
  start.v = (float(y) + 0.5f) / float(scale_) - 0.5f;
  const int px = std::clamp(pixel_of(start.u), 0, width_ - 1),
            py = std::clamp(pixel_of(start.v), 0, height_ - 1);
  start.pixel = size_t(py) * width_ + px;
  start.height = top_px_[start.pixel];
  if (scale_ > 1) {
    // The surface under the field pixel, between the depth map's samples where they are one
    // surface (no jump), not the nearest sample's: a slope's pixels would shadow themselves.
    const int x0 = std::clamp(int(std::floor(start.u)), 0, std::max(width_ - 2, 0));
    const int y0 = std::clamp(int(std::floor(start.v)), 0, std::max(height_ - 2, 0));
    const float fx = std::clamp(start.u - float(x0), 0.0f, 1.0f),
                fy = std::clamp(start.v - float(y0), 0.0f, 1.0f);
    const size_t a = size_t(y0) * width_ + x0;
    const float z00 = top_px_[a], z01 = top_px_[a + 1], z10 = top_px_[a + width_],
                z11 = top_px_[a + width_ + 1];
    const float lo = std::min({z00, z01, z10, z11}), hi = std::max({z00, z01, z10, z11});
    if (lo > kNoSurface && hi - lo < kOneSurfaceStepPx) {
      start.height = (1 - fy) * ((1 - fx) * z00 + fx * z01) + fy * ((1 - fx) * z10 + fx * z11);
    }
  }
  start.height += kRayStartPx;
  return start;
}

bool ShadowGeometry::sees(int x, int y, const Eigen::Vector3f& dir) const {
  return sees(ray_start(x, y), ray_direction(dir));
}

bool ShadowGeometry::sees(const ShadowRayStart& from, const ShadowRayDirection& along) const {
  if (along.step == 0) return true;
  const float u = from.u, v = from.v, start = from.height, step = along.step;
  const float dx = along.dx, dy = along.dy, dz = along.dz;
  const size_t p = from.pixel;
  const int steps = 4 * (width_ + height_), levels = int(highest_in_block_.size());
  int level = 0;
  for (int i = 1; i < steps;) {
    const float t = step * float(i);
    const int qx = pixel_of(u + t * dx), qy = pixel_of(v + t * dy);
    if (qx < 0 || qy < 0 || qx >= width_ || qy >= height_) return true;
    const float ray = start + t * dz;
    if (ray > highest_px_) return true;
    if (dz > 0) {
      // Rising: above a block's highest top here, it is above it until it leaves the block.
      while (level < levels && ray > highest_in_block(level + 1, qx, qy)) ++level;
      while (level > 0 && !(ray > highest_in_block(level, qx, qy))) --level;
      if (level > 0) {
        i = std::max(i + 1, first_step_outside(along, u, v, qx, qy, level) - 1);
        continue;
      }
    }
    const size_t q = size_t(qy) * width_ + qx;
    if (q != p && ray < top_px_[q] && ray > top_px_[q] - thickness_px_[q]) return false;
    ++i;
  }
  return true;
}

}  // namespace ls::relight
