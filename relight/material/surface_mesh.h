#pragma once
// The captured surface as a mesh for a glTF asset: the plane the field was seen on, or the scene's
// shape recovered from the LEDs' shadows and the photometric normals (relight/sources/
// shadow_geometry.h). Stage frame (+Y up, +Z toward the camera), metres; texture coordinates
// (0, 0) at the maps' top-left, v down (glTF's).
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "lightstage/image.h"

namespace ls::relight {

class ShadowGeometry;

struct SurfaceMesh {
  std::vector<Eigen::Vector3f> positions, normals;  // Per vertex; normals unit.
  std::vector<Eigen::Vector4f> tangents;            // Unit along increasing u, w = +1.
  std::vector<Eigen::Vector2f> uvs;
  std::vector<uint32_t> indices;  // Triangles, counter-clockwise seen from outside.
  // A grid mesh (the recovered shape) also keeps its grid, for tangent_space_normals: vertex
  // (i, j) is index i * grid_width + j, over field pixels scaled by grid_scale.
  int grid_width = 0, grid_height = 0, grid_scale = 1;
};

// A height_m tall plane as wide as width x height pixels say, centred at the origin, facing +Z.
SurfaceMesh plane_mesh(int width, int height, double height_m);

// The recovered shape over a width x height field (the maps' size), the field height_m tall: one
// vertex per depth-map pixel, a triangle wherever its three corners are surface and their heights
// within `max_step` depth-map pixels of each other (a limb or an occluding edge is left open, not
// bridged by a wall the camera never saw).
SurfaceMesh shape_mesh(const ShadowGeometry& shape, int width, int height, double height_m,
                       float max_step = 3.0f);

// The fitted normals (stage frame, 3 channels) in the mesh's tangent frames at each pixel (the
// vertex frames interpolated bilinearly over the grid): what glTF's normal texture holds. A plane
// (no grid) leaves them as they are: its tangent frame is the stage's.
Image tangent_space_normals(const Image& stage_normals, const SurfaceMesh& mesh);

}  // namespace ls::relight
