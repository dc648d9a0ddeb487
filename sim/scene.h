#pragma once
// The simulated world in front of the camera: geometry and per-pixel ground-truth materials.
// Scene files are JSON, validated on load (errors name the file, the field and what was expected).
#include <Eigen/Core>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "physics/brdf.h"
#include "sim/time_varying.h"

namespace ls::sim {

// A material with optional spatial variation over the object's own 2D coordinates (s, t) in
// [0,1]^2.
struct SceneMaterial {
  std::string name;
  physics::brdf::Material base;
  // Optional per-pixel variation: a checker of two albedos, or an albedo texture (any image file).
  std::optional<Eigen::Vector3d> checker_albedo;  // Alternates with base.albedo.
  int checker_cells = 8;
  std::filesystem::path albedo_texture;
  // A time-varying material (sim/time_varying.h); then `base` is what points outside the process's
  // region keep, and neither a checker nor a texture is allowed.
  std::optional<MaterialProcess> process;
};

struct Sphere {
  Eigen::Vector3d center{0, 0, 0};
  double radius = 1.0;
  int material = 0;
};

// A rectangle through `center` with unit normal `normal`, half extents along its two tangents.
struct Plane {
  Eigen::Vector3d center{0, 0, 0};
  Eigen::Vector3d normal{0, 0, 1};
  double half_width = 1.0;
  double half_height = 1.0;
  int material = 0;
};

// A height field over a rectangle in the plane z = base_z, facing +Z (toward the camera):
// z = base_z + h(x, y) sampled on a grid; casts shadows on itself and on what lies below it.
struct HeightField {
  Eigen::Vector3d center{0, 0, 0};  // Centre of the base rectangle.
  double half_width = 1.0;          // Along X.
  double half_height = 1.0;         // Along Y.
  int resolution = 256;             // Grid samples per side.
  std::vector<float> heights;       // resolution^2, row-major, row 0 at +Y (top).
  int material = 0;
  // Procedural description it was generated from, kept for manifests.
  std::string description;
};

struct Scene {
  std::vector<SceneMaterial> materials;
  std::vector<Sphere> spheres;
  std::vector<Plane> planes;
  std::vector<HeightField> height_fields;
  std::string source = "<built-in>";
};

Scene load_scene(const std::filesystem::path& path);
Scene parse_scene(std::string_view json_text, const std::string& source_name);

// The demo scene: a matte sphere, a glossy sphere, a rough (Oren-Nayar) sphere and a bumpy height
// field with cast shadows, on a checkered ground plane.
Scene default_scene();

// A time-varying scene (data/scenes/time_varying.json holds the same text), over about 10 minutes
// of scene time: a sphere of paint drying (lambda = 1/120 s, uniform), a wet plane drying in a
// patch spreading from its centre (sigmoid, kappa = 1/30 s, front speed 1/600 per s), a glossy
// sphere gathering dust along a stroke (lambda = 1/200 s, faster toward s = 1) and a static matte
// sphere, before a grey backdrop.
Scene time_varying_scene();
// Materials that rise and fall (data/scenes/rise_and_fall.json holds the same text), over about
// 20 minutes: a metal sphere corroding from a spot outwards (corroding, lambda = 1/300 s, front
// speed 1/400 per s: red albedo 0.073 -> 0.118 at its peak -> 0.057, k_s 0.2 -> 0.01, roughness
// 0.15 -> 0.27), a stone slab wetted along a brush stroke from 100 s, then drying (wetting_drying,
// kappa = 1/40 s, lambda = 1/250 s, both x0.7 at the stroke's start to x1.4 at its end), a static
// matte sphere, before a grey backdrop.
Scene rise_and_fall_scene();
bool has_time_varying_materials(const Scene& scene);

// What the camera sees at one pixel.
struct SurfaceHit {
  bool hit = false;
  Eigen::Vector3d position{0, 0, 0};
  Eigen::Vector3d normal{0, 0, 1};   // Unit, facing the viewer.
  Eigen::Vector3d wo{0, 0, 1};       // Unit, toward the camera.
  physics::brdf::Material material;  // With spatial variation already applied.
  int object = -1;                   // For region masks in tests.
  int material_index = -1;           // Into Scene::materials; -1 when !hit.
  Eigen::Vector2d st{0, 0};          // The object's own (s, t) in [0,1]^2 at the hit.
  // The pixel this hit belongs to (trace_camera returns them row-major); render_one_light takes
  // the image size from the last one.
  int pixel_x = 0;
  int pixel_y = 0;
};

// Object indices in SurfaceHit::object: spheres first, then planes, then height fields.
int object_index_of_plane(const Scene& scene, int plane);
int object_index_of_height_field(const Scene& scene, int height_field);

}  // namespace ls::sim
