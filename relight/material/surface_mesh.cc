#include "relight/material/surface_mesh.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "relight/sources/shadow_geometry.h"

namespace ls::relight {

SurfaceMesh plane_mesh(int width, int height, double height_m) {
  const float h = float(height_m) / 2, w = h * float(width) / float(height);
  SurfaceMesh mesh;
  // Top-left, top-right, bottom-right, bottom-left.
  mesh.positions = {{-w, h, 0}, {w, h, 0}, {w, -h, 0}, {-w, -h, 0}};
  mesh.normals.assign(4, Eigen::Vector3f::UnitZ());
  mesh.tangents.assign(4, Eigen::Vector4f(1, 0, 0, 1));
  mesh.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  mesh.indices = {0, 3, 2, 0, 2, 1};
  return mesh;
}

SurfaceMesh shape_mesh(const ShadowGeometry& shape, int width, int height, double height_m,
                       float max_step) {
  const int gw = shape.width(), gh = shape.height(), scale = shape.scale();
  const std::vector<float>& top = shape.heights();
  // Metres per field pixel; heights are in depth-map pixels (scale field pixels each).
  const float metre = float(height_m) / float(height);
  const float half_w = metre * float(width) / 2, half_h = float(height_m) / 2;
  const auto surface = [&](int i, int j) {
    return i >= 0 && j >= 0 && i < gh && j < gw &&
           top[size_t(i) * gw + j] != ShadowGeometry::kNoSurface;
  };
  // Heights where there is no surface: the nearest row's, so that normals at an edge stay sane.
  const auto z_at = [&](int i, int j) {
    i = std::clamp(i, 0, gh - 1);
    j = std::clamp(j, 0, gw - 1);
    const float z = top[size_t(i) * gw + j];
    return z == ShadowGeometry::kNoSurface ? 0.0f : z * float(scale) * metre;
  };
  SurfaceMesh mesh;
  mesh.grid_width = gw;
  mesh.grid_height = gh;
  mesh.grid_scale = scale;
  const float step = float(scale) * metre;
  for (int i = 0; i < gh; ++i) {
    for (int j = 0; j < gw; ++j) {
      const float fx = (float(j) + 0.5f) * float(scale), fy = (float(i) + 0.5f) * float(scale);
      mesh.positions.emplace_back(fx * metre - half_w, half_h - fy * metre, z_at(i, j));
      mesh.uvs.emplace_back(fx / float(width), fy / float(height));
      // Central differences within the surface (one-sided at its edges).
      const auto slope = [&](int di, int dj) {
        const bool ahead = surface(i + di, j + dj), behind = surface(i - di, j - dj);
        const float span = float(int(ahead) + int(behind)) * step;
        if (span == 0) return 0.0f;
        return (z_at(ahead ? i + di : i, ahead ? j + dj : j) -
                z_at(behind ? i - di : i, behind ? j - dj : j)) /
               span;
      };
      const float dz_dx = slope(0, 1), dz_dy = -slope(1, 0);  // Rows grow toward -Y.
      const Eigen::Vector3f n = Eigen::Vector3f(-dz_dx, -dz_dy, 1).normalized();
      mesh.normals.push_back(n);
      const Eigen::Vector3f t = (Eigen::Vector3f::UnitX() - n * n.x()).normalized();
      mesh.tangents.emplace_back(t.x(), t.y(), t.z(), 1.0f);
    }
  }
  const auto joined = [&](std::initializer_list<std::pair<int, int>> corners) {
    float lo = 1e30f, hi = -1e30f;
    for (const auto& [i, j] : corners) {
      if (!surface(i, j)) return false;
      lo = std::min(lo, top[size_t(i) * gw + j]);
      hi = std::max(hi, top[size_t(i) * gw + j]);
    }
    return hi - lo <= max_step;
  };
  const auto index = [&](int i, int j) { return uint32_t(i * gw + j); };
  for (int i = 0; i + 1 < gh; ++i) {
    for (int j = 0; j + 1 < gw; ++j) {
      // Counter-clockwise seen from +Z: rows grow toward -Y.
      if (joined({{i, j}, {i + 1, j}, {i + 1, j + 1}})) {
        mesh.indices.insert(mesh.indices.end(),
                            {index(i, j), index(i + 1, j), index(i + 1, j + 1)});
      }
      if (joined({{i, j}, {i + 1, j + 1}, {i, j + 1}})) {
        mesh.indices.insert(mesh.indices.end(),
                            {index(i, j), index(i + 1, j + 1), index(i, j + 1)});
      }
    }
  }
  return mesh;
}

Image tangent_space_normals(const Image& stage_normals, const SurfaceMesh& mesh) {
  if (mesh.grid_width == 0) return stage_normals;
  Image out = stage_normals;
  const int gw = mesh.grid_width, gh = mesh.grid_height;
  for (int y = 0; y < out.height; ++y) {
    for (int x = 0; x < out.width; ++x) {
      // The pixel in grid coordinates (vertex (i, j) at field pixel ((j + .5) s, (i + .5) s)).
      const float gx =
          std::clamp((float(x) + 0.5f) / float(mesh.grid_scale) - 0.5f, 0.0f, float(gw - 1));
      const float gy =
          std::clamp((float(y) + 0.5f) / float(mesh.grid_scale) - 0.5f, 0.0f, float(gh - 1));
      const int j0 = std::min(int(gx), gw - 2 < 0 ? 0 : gw - 2);
      const int i0 = std::min(int(gy), gh - 2 < 0 ? 0 : gh - 2);
      const int j1 = std::min(j0 + 1, gw - 1), i1 = std::min(i0 + 1, gh - 1);
      const float fx = gx - float(j0), fy = gy - float(i0);
      const auto at = [&](const auto& values, int i, int j) { return values[size_t(i) * gw + j]; };
      const auto blend = [&](const auto& values) {
        return ((1 - fy) * ((1 - fx) * at(values, i0, j0) + fx * at(values, i0, j1)) +
                fy * ((1 - fx) * at(values, i1, j0) + fx * at(values, i1, j1)))
            .eval();
      };
      const Eigen::Vector3f n = blend(mesh.normals).normalized();
      const Eigen::Vector4f t4 = blend(mesh.tangents);
      const Eigen::Vector3f t = (t4.head<3>() - n * n.dot(t4.head<3>())).normalized();
      const Eigen::Vector3f b = n.cross(t);
      float* px = &out.pixels[(size_t(y) * out.width + x) * 3];
      const Eigen::Vector3f fitted(px[0], px[1], px[2]);
      const Eigen::Vector3f local(t.dot(fitted), b.dot(fitted), n.dot(fitted));
      const Eigen::Vector3f unit = local.norm() > 0 ? local.normalized() : Eigen::Vector3f::UnitZ();
      px[0] = unit.x();
      px[1] = unit.y();
      px[2] = unit.z();
    }
  }
  return out;
}

}  // namespace ls::relight
