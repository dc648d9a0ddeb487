#pragma once
// A captured material on another shape: the fitted models (relight/fit/fit.h ModelMaps) looked up
// by the shape's texture coordinates and rendered under distant lights (an environment map's,
// LightingForModels), as "texture-mapping with the BTF" put a captured appearance on new geometry.
//
// Conventions: the stage frame (+Y up, camera on +Z looking toward -Z), the camera of capture::
// FieldView (orthographic by default). Texture coordinates (u, v) in [0, 1] span the maps, (0, 0)
// at the top-left texel, v growing down the rows (glTF's convention; an OBJ's v, which grows up,
// is flipped on reading), repeated `tiles` times over the shape's own (u, v). At a hit the shape
// gives its normal N and its tangent frame: T along increasing u, B toward decreasing v (up the
// maps). The maps were fitted facing the camera, so their stage-frame normal n is a tangent-space
// normal: the shading normal is T n.x + B n.y + N n.z. Each of the four nearest texels is shaded
// with its own model and normal and the results blended bilinearly. A light lights a hit when it
// is above both the shading normal and the shape's own surface; no cast shadows between parts of
// the shape, no interreflection.
//
// Shapes, centred at the origin: a sphere of radius 1 (u from the azimuth about +Y, 0.5 facing
// the camera; v from the +Y pole, as the simulator's spheres); an open cylinder of radius 1 about
// +Y from y = -1 to 1 (u as the sphere's, v = (1 - y) / 2); a 2 x 2 plane facing +Z (u = (x + 1)
// / 2, v = (1 - y) / 2); a triangle mesh (read_obj) as it is.
#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "capture/field.h"
#include "lightstage/image.h"
#include "relight/fit/fit.h"
#include "relight/lighting/lighting.h"

namespace ls::relight {

struct Mesh {
  std::vector<Eigen::Vector3d> positions;  // Per vertex (corners are not shared between faces).
  std::vector<Eigen::Vector3d> normals;    // Per vertex, unit.
  std::vector<Eigen::Vector2d> uvs;        // Per vertex, v down.
  std::vector<std::array<int, 3>> triangles;
};

// A Wavefront OBJ through tinyobjloader: triangulated; texture coordinates required (InputError
// naming the file otherwise); normals from the file, or the faces' area-weighted ones.
Mesh read_obj(const std::filesystem::path& path);

enum class Shape { kSphere, kCylinder, kPlane, kMesh };

struct ShapeRenderOptions {
  Shape shape = Shape::kSphere;
  const Mesh* mesh = nullptr;  // kMesh.
  int width = 256, height = 256;
  capture::FieldView camera;  // Orthographic, 2.4 tall, by default.
  double tiles = 1.0;         // Repeats of the maps over the shape's (u, v).
  float max_specular_albedo = float(kDefaultMaxSpecularAlbedo);  // As ModelRenderOptions'.
};

// 4 channels: linear radiance RGB (the maps' field units x the lights' irradiance) and coverage
// (1 where the shape was hit). Rows in parallel (TBB). InputError for options that do not fit.
Image render_on_shape(const ModelMaps& maps, const LightingForModels& lighting,
                      const ShapeRenderOptions& options);

// "sphere", "cylinder", "plane"; anything else is a mesh's path.
Shape shape_named(const std::string& name);

}  // namespace ls::relight
