#pragma once
// The scene's shape recovered from a field, to cast a bright source's shadows at its true
// direction. The LEDs' shadows, interpolated by flow (source_render.h), go wrong where
// a shadow's shape changes between two LEDs (a sphere's shadow swinging across a relief); a shape
// casts them right at any direction, as far as the shape is right. So:
//  - Depth from the photometric normals: the gradients integrated (least squares) over regions of
//    continuous surface, split where neighbouring normals or albedo chromaticities jump (a limb, a
//    sphere in front of a backdrop).
//  - Each region's height above the largest (the backdrop) and its relief scale: the placement
//  whose
//    traced shadows best match the shadows every LED measured, as occluder and as receiver (shadow
//    carving). A region ringed by steep normals floats (a sphere): its hidden half mirrors the
//    visible one. Small regions (bump tips cut off by steep flanks) continue their surroundings.
//  - Visibility: rays traced through the depth map (orthographic camera; image x along +x, image y
//    along -y, heights along +z toward the camera, in depth-map pixels).
// It is trusted only where it agrees with what the LEDs nearest the source measured: with at
// least 7 of the 8 nearest over most of a pixel's 3x3 neighbourhood, and with the nearest at the
// pixel. Elsewhere (its shape wrong, a detail too fine for it) the flows render the shadow
// (add_bright_source).
// Larger fields are reduced to at most kDepthMapSize pixels a side for the depth (a minute's
// carving at 512^2 on 2 cores); the coarser the depth map against the field, the more pixels the
// agreement test hands back to the flows (at 512^2 with a 256 map: 0.104 on the demo's small
// source, against 0.059 with the full map and 0.111 by the flows alone).
#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <vector>

#include "lightstage/image.h"
#include "lightstage/progress.h"
#include "relight/sources/source_render.h"

namespace ls::relight {

class ShadowGeometry;

// What the rays from one field pixel share, and the rays along one direction
// (ShadowGeometry::sees).
struct ShadowRayStart {
  float u = 0, v = 0;     // The field pixel's centre in depth-map pixels,
  float height = 0;       // the ray's height there (depth-map pixels, toward the camera),
  std::size_t pixel = 0;  // and the depth-map pixel it starts in.
};
struct ShadowRayDirection {
  float dx = 0, dy = 0, dz = 0;    // Unit, depth-map axes (image x, -image y, toward the camera).
  float step = 0;                  // Of t a step (half a depth-map pixel across); 0 straight up.
  float steps_per_px[2] = {0, 0};  // Steps a pixel along x and y (0 where it does not move).
};

// A bright source's view of the geometry: its disc's directions and the LEDs nearest it.
class SourceShadowView {
 public:
  // The share of the source's disc field pixel (x, y) sees, and whether the geometry agrees there
  // with the measured shadows of the LED nearest the source (true when dead LEDs left that one
  // far) and of kAgreeing of the kNearestLeds; nullopt where it has no surface.
  struct Visibility {
    float share = 1;
    bool nearest_agrees = false, most_agree = false;
  };
  std::optional<Visibility> visibility(int x, int y) const;
  // What add_bright_source takes of the shape: the share each field pixel sees where the shape is
  // trusted there (it agrees with the nearest LED at the pixel, and with most of the LEDs around
  // over most of its 3x3 neighbourhood: a lone pixel of one kind among the other, a ray slipping
  // between two depth samples, is noise), NaN where the flows decide. 1 channel, the field's size;
  // the traced rays of every pixel (0.5-0.7 s at 512^2 on one core, many frames' worth): a
  // viewer keeps it while the source stays.
  Image trusted_visibility() const;

 private:
  friend class ShadowGeometry;
  const ShadowGeometry* geometry_ = nullptr;
  std::vector<ShadowRayDirection> disc_;
  // Per LED nearest the source, nearest first: where the shape agrees with what it measured.
  std::vector<const std::vector<std::uint64_t>*> nearest_agreement_;
  bool nearest_decides_ = false;  // The source's nearest LED is within the dome's spacing.
};

class ShadowGeometry {
 public:
  static constexpr int kDepthMapSize = 512;  // Longest side of the depth map, in its pixels.
  static constexpr int kNearestLeds = 8;     // LEDs around a source its shadows are checked with,
  static constexpr int kAgreeing = 7;        // and how many must agree.

  // `lit_mask(l)`: LED l's led_lit_mask, for each of `led_dirs` (unit, stage frame), called for
  // as many LEDs at once as there are cores; progress, phase "bright sources (the scene's
  // shape)", after each such few LEDs' masks and after each region placed.
  ShadowGeometry(const LambertianFit& fit, const std::vector<Eigen::Vector3d>& led_dirs,
                 const std::function<LitMask(int led)>& lit_mask, const ProgressFn& progress = {});

  // A source's view: its disc (angular radius) and the LEDs nearest it.
  SourceShadowView view(const Eigen::Vector3d& dir, double radius_rad) const;

  // Field pixel (x, y) sees the direction (unit, stage frame) past the recovered shape.
  bool sees(int x, int y, const Eigen::Vector3f& dir) const;
  // The same with what a pixel's rays share, and a direction's, worked out once: a source's disc
  // traces 16 rays a pixel, and each direction is traced from every pixel.
  ShadowRayStart ray_start(int x, int y) const;
  static ShadowRayDirection ray_direction(const Eigen::Vector3f& dir);
  bool sees(const ShadowRayStart& from, const ShadowRayDirection& along) const;
  // Height toward the camera of each depth-map pixel (field pixels / scale()), in its pixels;
  // kNoSurface where nothing was recovered.
  const std::vector<float>& heights() const { return top_px_; }
  // How far below its top each depth-map pixel's solid reaches, in its pixels (infinite where
  // it is attached to what lies under it).
  const std::vector<float>& thicknesses() const { return thickness_px_; }
  int width() const { return width_; }
  int height() const { return height_; }
  int scale() const { return scale_; }
  static constexpr float kNoSurface = -1e30f;

 private:
  friend class SourceShadowView;
  int field_width_ = 0, field_height_ = 0;
  int width_ = 0, height_ = 0, scale_ = 1;
  std::vector<float> top_px_;        // Surface height toward the camera.
  std::vector<float> thickness_px_;  // How far the solid reaches below it (infinite: attached).
  float highest_px_ = kNoSurface;
  // Level k >= 1: the highest top over each 2^k x 2^k block of depth-map pixels, so that a
  // rising ray skips a block it is above (the same answer as marching through it).
  std::vector<std::vector<float>> highest_in_block_;
  void build_block_pyramid();  // highest_px_ and highest_in_block_ from top_px_ (shadow_rays.cc).
  float highest_in_block(int level, int x, int y) const {
    return highest_in_block_[size_t(
        level - 1)][size_t(y >> level) * size_t(((width_ - 1) >> level) + 1) + size_t(x >> level)];
  }
  // One bit a field pixel: where LED l's shadows as the shape casts them agree with what it
  // measured. Made when a source first falls near the LED, kept for every source after it.
  const std::vector<std::uint64_t>& agreement(int led) const;

  std::vector<Eigen::Vector3f> led_dirs_;
  std::vector<std::vector<std::uint64_t>> led_lit_bits_;  // Field resolution, one bit a pixel.
  mutable std::mutex agreement_mutex_;
  mutable std::map<int, std::vector<std::uint64_t>> agreement_;
};

}  // namespace ls::relight
