#pragma once
// Lat-long (equirectangular) environment maps of radiance (DESIGN.md conventions):
// pixel centre (u, v) in [0,1)^2, u across, v down, row 0 at the top, looks along
//   d = (sin(theta) sin(phi), cos(theta), -sin(theta) cos(phi)),  theta = pi v, phi = 2 pi u - pi.
// The top row is the zenith (+Y), the map's centre is -Z, u = 0.75 is +X. A pixel's solid angle is
// exactly (2 pi / W)(cos theta_top - cos theta_bottom) of its row. Rotation is about +Y.
#include <Eigen/Core>
#include <filesystem>

#include "lightstage/image.h"

namespace ls::physics {

class EnvironmentMap {
 public:
  // Validates: 3 or more channels (RGB used; 1 channel is grey), width == 2 * height, every value
  // finite. Errors are InputErrors naming the file and the first bad pixel. Negative values in a
  // file are repaired, not rejected: lossy EXR compression (DWAA/DWAB, 8x8 DCT blocks) rings around
  // bright sources (published maps carry lobes down to -15% of the sun), while it keeps each
  // block's mean. So per 8x8 block and channel, negatives become 0 and the block's positive values
  // are scaled to keep the block's integral (a block whose integral is negative becomes 0).
  // Refused: an 8-bit PNG or JPEG (display-referred), and a file whose channels are not R, G, B
  // (A): a grey or XYZ map.
  static EnvironmentMap load(const std::filesystem::path& path);
  // In-memory maps are strict: every value finite and >= 0 (a negative here is a bug upstream).
  explicit EnvironmentMap(Image radiance_rgb, std::string source = "<memory>");

  int width() const { return radiance_.width; }
  int height() const { return radiance_.height; }
  const Image& radiance() const { return radiance_; }  // 3 channels, linear radiance.
  const std::string& source() const { return source_; }
  // How many values load() found negative and repaired (0 for in-memory maps).
  long long negative_values_repaired() const { return negative_values_repaired_; }

  static Eigen::Vector3d direction(double u, double v);   // (u, v) -> unit direction.
  static Eigen::Vector2d uv(const Eigen::Vector3d& dir);  // Inverse, u in [0,1), v in [0,1].
  double pixel_solid_angle_sr(int row) const;
  Eigen::Vector3d pixel_direction(int x, int y) const;  // Direction of a pixel's centre.
  // Bilinear lookup (wraps in u) of the map rotated by rotation_deg about +Y.
  Eigen::Vector3f radiance_toward(const Eigen::Vector3d& dir, double rotation_deg = 0.0) const;
  // Sum over the sphere of L dw per channel (irradiance-like "total power" of the map).
  Eigen::Vector3d integral() const;

 private:
  EnvironmentMap(Image radiance_rgb, std::string source, bool repair_negatives);

  Image radiance_;
  std::string source_;
  long long negative_values_repaired_ = 0;
};

// A direction of the unrotated map as the map rotated by rotation_deg about +Y shows it:
// R_y(rotation) d (physics/sphere.h), the sense of radiance_toward.
Eigen::Vector3d rotate_about_y(const Eigen::Vector3d& dir, double rotation_deg);

// One texel of a map box-filtered onto a coarse lat-long grid.
struct CoarseTexel {
  Eigen::Vector3d dir_in_stage;  // Texel centre in the rotated map (unit, toward the light).
  Eigen::Vector3d
      radiance_x_sr;  // Mean radiance times solid angle: irradiance at normal incidence.
  int x = 0, y = 0;   // On the coarse grid.
};
// Box-filters the map, rotated by rotation_deg about +Y, onto a width x width/2 grid: each coarse
// texel gets the solid-angle weighted mean of the fine pixels it overlaps (fractional overlaps in u
// and in cos(theta), so any pair of resolutions works). Returns the texels with light, row by row.
// InputError unless width is even and >= 4.
std::vector<CoarseTexel> box_filter_environment(const EnvironmentMap& map, int width,
                                                double rotation_deg = 0.0);

}  // namespace ls::physics
