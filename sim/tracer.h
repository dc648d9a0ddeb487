#pragma once
// Internal to sim/: ray queries against a Scene with per-object data precomputed once (plane
// tangent frames, height-field bounds and per-block height ranges). Not a public header.
#include <Eigen/Core>
#include <vector>

#include "lightstage/image.h"
#include "sim/scene.h"

namespace ls::sim::detail {

struct RayHit {
  double t = 0.0;
  int object = -1;  // Spheres, then planes, then height fields (see object_index_of_*).
};

class Tracer {
 public:
  explicit Tracer(const Scene& scene);

  // Nearest hit with t in (t_min, inf).
  bool intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double t_min,
                 RayHit* hit) const;
  // Any hit with t in (t_min, inf): the shadow-ray query.
  bool occluded(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double t_min) const;
  // Any hit with t in (t_min, t_max): the shadow ray toward a light at a finite distance t_max.
  bool occluded(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double t_min,
                double t_max) const;

  // Shading data at a hit: unit geometric/shading normal (not yet facing the viewer) and the
  // object's own (s, t) coordinates in [0,1]^2 for spatially varying materials.
  void surface(const Eigen::Vector3d& position, int object, Eigen::Vector3d* normal,
               Eigen::Vector2d* st) const;
  int material_of(int object) const;

  const Scene& scene() const { return scene_; }

 private:
  struct PlaneFrame {
    Eigen::Vector3d center, normal, u, v;  // u along half_width, v along half_height.
    double half_width, half_height;
  };
  struct Field {
    const HeightField* hf;
    int n;                 // Samples per side.
    double x_left, y_top;  // World x of column 0, world y of row 0.
    double dx, dy;         // Sample spacing in metres.
    double base_z;
    Eigen::Vector3d box_lo, box_hi;           // World bounds of the surface.
    int blocks;                               // Blocks per side.
    std::vector<float> block_min, block_max;  // Height range of the samples each block spans.
  };

  bool hit_sphere(int i, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min,
                  double* t) const;
  bool hit_plane(int i, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min,
                 double* t) const;
  // `any`: return at the first crossing without refining it (shadow rays).
  bool hit_field(const Field& f, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_min,
                 bool any, double* t) const;
  static double height_at(const Field& f, double gx, double gy);  // Grid coordinates, bilinear.

  const Scene& scene_;
  std::vector<PlaneFrame> planes_;
  std::vector<Field> fields_;
};

// Tangent frame of a plane: u = normalize(+Y x n) (+X for a plane facing +Z), v = n x u (+Y);
// for planes facing +-Y, u = +X.
void plane_tangents(const Eigen::Vector3d& normal, Eigen::Vector3d* u, Eigen::Vector3d* v);

// render_one_light with a tracer built once by the caller.
Image render_one_light_with(const Tracer& tracer, const std::vector<SurfaceHit>& hits,
                            const Eigen::Vector3d& dir_in_stage);

// render_one_near_light with a tracer built once by the caller.
Image render_one_near_light_with(const Tracer& tracer, const std::vector<SurfaceHit>& hits,
                                 const Eigen::Vector3d& led_position_in_stage);

// The surface offset used for shadow rays, metres (scene scale is about a metre).
inline constexpr double kShadowOffsetM = 2e-4;

// Where shadow rays from a camera hit start: offset along its normal so the surface does not
// shadow itself. The one-light images and the ground truth must use the same rule to agree.
inline Eigen::Vector3d shadow_ray_origin(const SurfaceHit& hit) {
  return hit.position + kShadowOffsetM * hit.normal;
}

}  // namespace ls::sim::detail
