#include "relight/material/shape_render.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tiny_obj_loader.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>

#include "lightstage/errors.h"
#include "relight/fit/model_render.h"

namespace ls::relight {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
constexpr double kNoHit = std::numeric_limits<double>::infinity();

// What the camera ray of one pixel meets.
struct Hit {
  double t = kNoHit;
  Vector3d normal, tangent, bitangent;  // Unit; bitangent toward decreasing v.
  Vector2d uv;
};

// A sphere's or cylinder's (u, v) frame at unit normal direction n about +Y.
void around_y(const Vector3d& n, Hit* hit) {
  const double phi = std::atan2(n.x(), n.z());
  hit->tangent = Vector3d(std::cos(phi), 0, -std::sin(phi));
}

bool hit_sphere(const Vector3d& o, const Vector3d& d, Hit* hit) {
  const double b = o.dot(d), c = o.squaredNorm() - 1.0, disc = b * b - c;
  if (disc < 0) return false;
  const double t = -b - std::sqrt(disc);
  if (!(t > 0)) return false;
  const Vector3d n = (o + t * d).normalized();
  hit->t = t;
  hit->normal = n;
  around_y(n, hit);
  hit->bitangent = hit->normal.cross(hit->tangent);
  const double theta = std::acos(std::clamp(n.y(), -1.0, 1.0));
  hit->uv = {(std::atan2(n.x(), n.z()) + std::numbers::pi) / (2 * std::numbers::pi),
             theta / std::numbers::pi};
  return true;
}

bool hit_cylinder(const Vector3d& o, const Vector3d& d, Hit* hit) {
  const double a = d.x() * d.x() + d.z() * d.z();
  if (!(a > 1e-12)) return false;
  const double b = o.x() * d.x() + o.z() * d.z(), c = o.x() * o.x() + o.z() * o.z() - 1.0;
  const double disc = b * b - a * c;
  if (disc < 0) return false;
  for (const double t : {(-b - std::sqrt(disc)) / a, (-b + std::sqrt(disc)) / a}) {
    const Vector3d p = o + t * d;
    if (!(t > 0) || std::abs(p.y()) > 1.0) continue;
    hit->t = t;
    hit->normal = Vector3d(p.x(), 0, p.z()).normalized();
    if (hit->normal.dot(d) > 0) hit->normal = -hit->normal;  // The inside, seen through the top.
    around_y(Vector3d(p.x(), 0, p.z()).normalized(), hit);
    hit->bitangent = Vector3d::UnitY();
    hit->uv = {(std::atan2(p.x(), p.z()) + std::numbers::pi) / (2 * std::numbers::pi),
               (1.0 - p.y()) / 2};
    return true;
  }
  return false;
}

bool hit_plane(const Vector3d& o, const Vector3d& d, Hit* hit) {
  if (!(std::abs(d.z()) > 1e-12)) return false;
  const double t = -o.z() / d.z();
  const Vector3d p = o + t * d;
  if (!(t > 0) || std::abs(p.x()) > 1.0 || std::abs(p.y()) > 1.0) return false;
  hit->t = t;
  hit->normal = Vector3d::UnitZ();
  hit->tangent = Vector3d::UnitX();
  hit->bitangent = Vector3d::UnitY();
  hit->uv = {(p.x() + 1) / 2, (1 - p.y()) / 2};
  return true;
}

// Per-vertex tangents along increasing u (the faces' UV derivatives, area-weighted), made
// orthogonal to the vertex normals.
std::vector<Vector3d> mesh_tangents(const Mesh& mesh) {
  std::vector<Vector3d> tangents(mesh.positions.size(), Vector3d::Zero());
  for (const auto& tri : mesh.triangles) {
    const Vector3d e1 = mesh.positions[tri[1]] - mesh.positions[tri[0]];
    const Vector3d e2 = mesh.positions[tri[2]] - mesh.positions[tri[0]];
    const Vector2d d1 = mesh.uvs[tri[1]] - mesh.uvs[tri[0]];
    const Vector2d d2 = mesh.uvs[tri[2]] - mesh.uvs[tri[0]];
    const double det = d1.x() * d2.y() - d2.x() * d1.y();
    if (!(std::abs(det) > 1e-20)) continue;
    // d P / d u, weighted by the face's UV area.
    const Vector3d t = (e1 * d2.y() - e2 * d1.y()) * (det > 0 ? 1.0 : -1.0);
    for (const int v : tri) tangents[v] += t;
  }
  for (size_t v = 0; v < tangents.size(); ++v) {
    const Vector3d& n = mesh.normals[v];
    Vector3d t = tangents[v] - n * n.dot(tangents[v]);
    if (!(t.norm() > 1e-12)) t = n.unitOrthogonal();
    tangents[v] = t.normalized();
  }
  return tangents;
}

// The nearest triangle each pixel's ray meets: per triangle, the pixels of its projected bounding
// box tested exactly (Moller-Trumbore).
std::vector<Hit> trace_mesh(const Mesh& mesh, const ShapeRenderOptions& options) {
  const int w = options.width, h = options.height;
  std::vector<Hit> hits(size_t(w) * h);
  const std::vector<Vector3d> tangents = mesh_tangents(mesh);
  const capture::FieldView& view = options.camera;
  const double half_h = view.fov_y_deg > 0
                            ? std::tan(0.5 * view.fov_y_deg * std::numbers::pi / 180.0)
                            : 0.5 * view.ortho_height_m;
  const double aspect = double(w) / h;
  // A point's pixel coordinates (continuous, pixel centres at + 0.5).
  const auto project = [&](const Vector3d& p) {
    const double depth = view.fov_y_deg > 0 ? view.camera_distance_m - p.z() : 1.0;
    const double ndc_x = p.x() / depth / (half_h * aspect), ndc_y = p.y() / depth / half_h;
    return Vector2d((ndc_x + 1) / 2 * w, (1 - ndc_y) / 2 * h);
  };
  for (const auto& tri : mesh.triangles) {
    const Vector3d& a = mesh.positions[tri[0]];
    const Vector3d e1 = mesh.positions[tri[1]] - a, e2 = mesh.positions[tri[2]] - a;
    Vector2d lo = project(a), hi = lo;
    for (const int v : {tri[1], tri[2]}) {
      const Vector2d q = project(mesh.positions[v]);
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
    const int x0 = std::max(0, int(std::floor(lo.x() - 1))), x1 = std::min(w - 1, int(hi.x() + 1));
    const int y0 = std::max(0, int(std::floor(lo.y() - 1))), y1 = std::min(h - 1, int(hi.y() + 1));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        Vector3d o, d;
        capture::camera_ray(view, w, h, x, y, &o, &d);
        const Vector3d p = d.cross(e2);
        const double det = e1.dot(p);
        if (std::abs(det) < 1e-14) continue;
        const Vector3d s = o - a;
        const double b1 = s.dot(p) / det;
        const Vector3d q = s.cross(e1);
        const double b2 = d.dot(q) / det, t = e2.dot(q) / det;
        Hit& hit = hits[size_t(y) * w + x];
        if (b1 < 0 || b2 < 0 || b1 + b2 > 1 || !(t > 0) || t >= hit.t) continue;
        const double b0 = 1 - b1 - b2;
        const auto blend = [&](const auto& values) {
          return (b0 * values[tri[0]] + b1 * values[tri[1]] + b2 * values[tri[2]]).eval();
        };
        hit.t = t;
        hit.normal = blend(mesh.normals).normalized();
        if (hit.normal.dot(d) > 0) hit.normal = -hit.normal;  // A back face seen.
        const Vector3d tangent = blend(tangents);
        hit.tangent = (tangent - hit.normal * hit.normal.dot(tangent)).normalized();
        hit.uv = blend(mesh.uvs);
        // Toward decreasing v: N x T, or its opposite where the face's UVs are mirrored.
        const Vector2d d1 = mesh.uvs[tri[1]] - mesh.uvs[tri[0]];
        const Vector2d d2 = mesh.uvs[tri[2]] - mesh.uvs[tri[0]];
        const Vector3d du = e1 * d2.y() - e2 * d1.y(), dv = e2 * d1.x() - e1 * d2.x();
        const double handed = du.cross(-dv).dot(hit.normal);
        hit.bitangent = hit.normal.cross(hit.tangent) * (handed >= 0 ? 1.0 : -1.0);
      }
    }
  }
  return hits;
}

// Texel (x, y) of the maps at wrapped coordinates.
const float* texel(const ModelMaps& maps, int x, int y) {
  const int w = maps.maps.width, h = maps.maps.height;
  x = ((x % w) + w) % w;
  y = ((y % h) + h) % h;
  return &maps.maps.pixels[(size_t(y) * w + x) * maps.maps.channels];
}

// Radiance toward wo of one texel's model, its normal put in the hit's tangent frame.
Eigen::Vector3f shade_texel(const float* m, const Hit& hit, const Vector3d& wo,
                            const LightingForModels& lighting, float max_ks) {
  if (FitModel(int(m[kMapModel])) == FitModel::kNone) return Eigen::Vector3f::Zero();
  const Vector3d local(m[kMapNormalX], m[kMapNormalY], m[kMapNormalZ]);
  const Eigen::Vector3f n =
      (hit.tangent * local.x() + hit.bitangent * local.y() + hit.normal * local.z())
          .normalized()
          .cast<float>();
  const Eigen::Vector3f wo_f = wo.cast<float>(), geometric = hit.normal.cast<float>();
  const float cos_o = n.dot(wo_f);
  if (!(cos_o > 0)) return Eigen::Vector3f::Zero();
  Eigen::Vector3f out = Eigen::Vector3f::Zero();
  for (size_t k = 0; k < lighting.dirs_in_stage.size(); ++k) {
    const Eigen::Vector3f& wi = lighting.dirs_in_stage[k];
    const float cos_i = n.dot(wi);
    if (!(cos_i > 0) || !(geometric.dot(wi) > 0)) continue;
    const physics::brdf::Geometry<float> g{cos_i, cos_o, wi.dot(wo_f)};
    out += model_brdf(m, g, max_ks).cwiseProduct(lighting.irradiance_rgb[k]) * cos_i;
  }
  return out;
}

}  // namespace

Shape shape_named(const std::string& name) {
  if (name == "sphere") return Shape::kSphere;
  if (name == "cylinder") return Shape::kCylinder;
  if (name == "plane") return Shape::kPlane;
  return Shape::kMesh;
}

Mesh read_obj(const std::filesystem::path& path) {
  tinyobj::ObjReaderConfig config;
  config.triangulate = true;
  config.vertex_color = false;
  config.mtl_search_path = path.parent_path().string();
  tinyobj::ObjReader reader;
  if (!reader.ParseFromFile(path.string(), config)) {
    throw InputError(path.string() + ": cannot read the mesh: " +
                     (reader.Error().empty() ? "not an OBJ file" : reader.Error()));
  }
  const tinyobj::attrib_t& attrib = reader.GetAttrib();
  Mesh mesh;
  const auto vec3 = [](const std::vector<tinyobj::real_t>& v, int i) {
    return Vector3d(v[3 * size_t(i)], v[3 * size_t(i) + 1], v[3 * size_t(i) + 2]);
  };
  bool all_normals = true;
  for (const tinyobj::shape_t& shape : reader.GetShapes()) {
    const auto& indices = shape.mesh.indices;
    for (size_t f = 0; f + 2 < indices.size(); f += 3) {
      std::array<int, 3> tri{};
      for (int k = 0; k < 3; ++k) {
        const tinyobj::index_t& index = indices[f + k];
        if (index.texcoord_index < 0) {
          throw InputError(path.string() + ": face " + std::to_string(f / 3 + 1) + " of '" +
                           shape.name +
                           "' has no texture coordinates (vt): the material is mapped by them");
        }
        tri[k] = int(mesh.positions.size());
        mesh.positions.push_back(vec3(attrib.vertices, index.vertex_index));
        // OBJ's v grows up the image; ours down the maps' rows.
        mesh.uvs.emplace_back(attrib.texcoords[2 * size_t(index.texcoord_index)],
                              1.0 - attrib.texcoords[2 * size_t(index.texcoord_index) + 1]);
        all_normals = all_normals && index.normal_index >= 0;
        mesh.normals.push_back(index.normal_index >= 0
                                   ? vec3(attrib.normals, index.normal_index).normalized()
                                   : Vector3d::Zero());
      }
      mesh.triangles.push_back(tri);
    }
  }
  if (mesh.triangles.empty()) throw InputError(path.string() + ": the mesh has no faces");
  for (const Vector3d& p : mesh.positions) {
    if (!p.allFinite()) throw InputError(path.string() + ": a vertex is not finite");
  }
  if (!all_normals) {
    // Smooth normals: each corner takes the area-weighted normals of the faces at its position.
    std::map<std::array<double, 3>, Vector3d> at;
    for (const auto& tri : mesh.triangles) {
      const Vector3d face = (mesh.positions[tri[1]] - mesh.positions[tri[0]])
                                .cross(mesh.positions[tri[2]] - mesh.positions[tri[0]]);
      for (const int v : tri) {
        const Vector3d& p = mesh.positions[v];
        auto [it, fresh] = at.try_emplace({p.x(), p.y(), p.z()}, Vector3d::Zero());
        it->second += face;
      }
    }
    for (size_t v = 0; v < mesh.positions.size(); ++v) {
      const Vector3d& p = mesh.positions[v];
      const Vector3d n = at[{p.x(), p.y(), p.z()}];
      mesh.normals[v] = n.norm() > 0 ? n.normalized() : Vector3d::UnitZ();
    }
  }
  return mesh;
}

Image render_on_shape(const ModelMaps& maps, const LightingForModels& lighting,
                      const ShapeRenderOptions& options) {
  if (options.width < 1 || options.height < 1) {
    throw InputError("render on a shape: expected a positive image size, got " +
                     std::to_string(options.width) + "x" + std::to_string(options.height));
  }
  if (!(options.tiles > 0) || !std::isfinite(options.tiles)) {
    throw InputError("render on a shape: tiles: expected a positive number");
  }
  if (options.shape == Shape::kMesh && options.mesh == nullptr) {
    throw InputError("render on a shape: a mesh shape needs its mesh");
  }
  LS_CHECK(maps.maps.channels == kMapChannelCount, "model maps of the wrong channel count");
  const int w = options.width, h = options.height;
  std::vector<Hit> hits;
  if (options.shape == Shape::kMesh) {
    hits = trace_mesh(*options.mesh, options);
  } else {
    hits.resize(size_t(w) * h);
    tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const auto& rows) {
      for (int y = rows.begin(); y < rows.end(); ++y) {
        for (int x = 0; x < w; ++x) {
          Vector3d o, d;
          capture::camera_ray(options.camera, w, h, x, y, &o, &d);
          Hit& hit = hits[size_t(y) * w + x];
          const bool any = options.shape == Shape::kSphere     ? hit_sphere(o, d, &hit)
                           : options.shape == Shape::kCylinder ? hit_cylinder(o, d, &hit)
                                                               : hit_plane(o, d, &hit);
          if (!any) hit.t = kNoHit;
        }
      }
    });
  }
  Image out(w, h, 4);
  out.channel_names = {"R", "G", "B", "A"};
  const int mw = maps.maps.width, mh = maps.maps.height;
  tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const auto& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < w; ++x) {
        const Hit& hit = hits[size_t(y) * w + x];
        if (hit.t == kNoHit) continue;
        Vector3d o, d;
        capture::camera_ray(options.camera, w, h, x, y, &o, &d);
        // Bilinear over the four texels around (u, v) x tiles, texel centres at + 0.5.
        const double tu = hit.uv.x() * options.tiles * mw - 0.5;
        const double tv = hit.uv.y() * options.tiles * mh - 0.5;
        const int x0 = int(std::floor(tu)), y0 = int(std::floor(tv));
        const double fx = tu - x0, fy = tv - y0;
        Eigen::Vector3f radiance = Eigen::Vector3f::Zero();
        for (int k = 0; k < 4; ++k) {
          const double weight = (k & 1 ? fx : 1 - fx) * (k & 2 ? fy : 1 - fy);
          if (weight <= 0) continue;
          const float* m = texel(maps, x0 + (k & 1), y0 + (k >> 1));
          radiance +=
              float(weight) * shade_texel(m, hit, -d, lighting, options.max_specular_albedo);
        }
        float* px = &out.pixels[(size_t(y) * w + x) * 4];
        for (int c = 0; c < 3; ++c) px[c] = std::isfinite(radiance[c]) ? radiance[c] : 0.0f;
        px[3] = 1;
      }
    }
  });
  return out;
}

}  // namespace ls::relight
