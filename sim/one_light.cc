// Tracing the camera's view and rendering it under one LED, for SimStage and ground truth.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "capture/field.h"
#include "lightstage/errors.h"
#include "sim/sim_stage.h"
#include "sim/time_varying.h"
#include "sim/tracer.h"

namespace ls::sim {

namespace {

using detail::Tracer;

// Applies a material's spatial variation at the object's (s, t).
physics::brdf::Material shade_material(const SceneMaterial& m, const Image* texture,
                                       const Eigen::Vector2d& st) {
  physics::brdf::Material out = m.base;
  const double s = std::clamp(st.x(), 0.0, 1.0), t = std::clamp(st.y(), 0.0, 1.0);
  if (m.checker_albedo) {
    const int cs = std::min(int(s * m.checker_cells), m.checker_cells - 1);
    const int ct = std::min(int(t * m.checker_cells), m.checker_cells - 1);
    if ((cs + ct) % 2 == 1) out.albedo = *m.checker_albedo;
  } else if (texture != nullptr && texture->width > 0) {
    const int x = std::min(int(s * texture->width), texture->width - 1);
    const int y = std::min(int(t * texture->height), texture->height - 1);
    for (int c = 0; c < 3; ++c) {
      const int ch = texture->channels >= 3 ? c : 0;
      out.albedo[c] = std::clamp(double(texture->at(x, y, ch)), 0.0, 1.0);
    }
  }
  return out;
}

void camera_ray(const CameraSpec& camera, int x, int y, Eigen::Vector3d* origin,
                Eigen::Vector3d* dir) {
  capture::FieldView view;
  view.fov_y_deg = camera.fov_y_deg;
  view.camera_distance_m = camera.distance_m;
  view.ortho_height_m = camera.ortho_height_m;
  capture::camera_ray(view, camera.width, camera.height, x, y, origin, dir);
}

bool hit_sees(const Tracer& tracer, const SurfaceHit& hit, const Eigen::Vector3d& dir) {
  return !tracer.occluded(detail::shadow_ray_origin(hit), dir, 0.0);
}

}  // namespace

std::vector<SurfaceHit> trace_camera(const Scene& scene, const CameraSpec& camera) {
  if (camera.width < 1 || camera.height < 1) {
    throw InputError(scene.source + ": camera: expected a positive image size, got " +
                     std::to_string(camera.width) + "x" + std::to_string(camera.height));
  }
  const Tracer tracer(scene);
  std::vector<Image> textures(scene.materials.size());
  for (size_t i = 0; i < scene.materials.size(); ++i) {
    if (!scene.materials[i].albedo_texture.empty()) {
      textures[i] = read_image(scene.materials[i].albedo_texture);
    }
  }
  std::vector<SurfaceHit> hits(size_t(camera.width) * camera.height);
  tbb::parallel_for(tbb::blocked_range<int>(0, camera.height), [&](const auto& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < camera.width; ++x) {
        SurfaceHit& h = hits[size_t(y) * camera.width + x];
        h.pixel_x = x;
        h.pixel_y = y;
        Eigen::Vector3d origin, dir;
        camera_ray(camera, x, y, &origin, &dir);
        detail::RayHit rh;
        if (!tracer.intersect(origin, dir, 0.0, &rh)) continue;
        h.hit = true;
        h.object = rh.object;
        h.position = origin + rh.t * dir;
        h.wo = -dir;
        Eigen::Vector2d st;
        tracer.surface(h.position, rh.object, &h.normal, &st);
        if (h.normal.dot(h.wo) < 0) h.normal = -h.normal;  // Back sides of planes.
        const int m = tracer.material_of(rh.object);
        h.material_index = m;
        h.st = st;
        h.material = scene.materials[m].process
                         ? material_at(scene.materials[m], st.x(), st.y(), /*time_s=*/0.0)
                         : shade_material(scene.materials[m], &textures[m], st);
      }
    }
  });
  return hits;
}

std::vector<SurfaceHit> at_time(const Scene& scene, std::vector<SurfaceHit> hits, double time_s) {
  for (SurfaceHit& h : hits) {
    if (!h.hit || h.material_index < 0) continue;
    LS_CHECK(h.material_index < int(scene.materials.size()),
             "hit material " + std::to_string(h.material_index) + " of " +
                 std::to_string(scene.materials.size()));
    const SceneMaterial& m = scene.materials[h.material_index];
    if (m.process) h.material = material_at(m, h.st.x(), h.st.y(), time_s);
  }
  return hits;
}

std::vector<SurfaceHit> trace_camera(const Scene& scene, const CameraSpec& camera, double time_s) {
  return at_time(scene, trace_camera(scene, camera), time_s);
}

bool visible(const Scene& scene, const Eigen::Vector3d& position, const Eigen::Vector3d& dir) {
  // Without a normal, the offset runs along the ray: hits nearer than the offset are the surface
  // the point lies on.
  return !Tracer(scene).occluded(position, dir.normalized(), detail::kShadowOffsetM);
}

namespace detail {

// Shared by render_one_light and the SimStage cache; the tracer is built once by the caller.
Image render_one_light_with(const Tracer& tracer, const std::vector<SurfaceHit>& hits,
                            const Eigen::Vector3d& dir_in_stage) {
  if (hits.empty()) return Image();
  const int width = hits.back().pixel_x + 1, height = hits.back().pixel_y + 1;
  LS_CHECK(size_t(width) * height == hits.size(),
           "hits do not form an image: " + std::to_string(hits.size()) + " hits, last at (" +
               std::to_string(width - 1) + ", " + std::to_string(height - 1) + ")");
  const Eigen::Vector3d wi = dir_in_stage.normalized();
  Image out(width, height, 3);
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const auto& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width; ++x) {
        const SurfaceHit& h = hits[size_t(y) * width + x];
        if (!h.hit) continue;
        const auto g = physics::brdf::Geometry<double>::from_world(h.normal, wi, h.wo);
        if (!(g.cos_i > 0)) continue;
        const Eigen::Vector3d f = physics::brdf::eval(h.material, g);
        if (!(f.maxCoeff() > 0)) continue;
        if (!hit_sees(tracer, h, wi)) continue;
        for (int c = 0; c < 3; ++c) out.at(x, y, c) = float(f[c] * g.cos_i);
      }
    }
  });
  return out;
}

Image render_one_near_light_with(const Tracer& tracer, const std::vector<SurfaceHit>& hits,
                                 const Eigen::Vector3d& led_position_in_stage) {
  if (hits.empty()) return Image();
  const int width = hits.back().pixel_x + 1, height = hits.back().pixel_y + 1;
  LS_CHECK(size_t(width) * height == hits.size(),
           "hits do not form an image: " + std::to_string(hits.size()) + " hits");
  // Irradiance at x per unit irradiance at the origin (both facing the LED): (d0 / r)^2.
  const double d0_squared = led_position_in_stage.squaredNorm();
  LS_CHECK(d0_squared > 0, "a near LED at the stage centre");
  Image out(width, height, 3);
  tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const auto& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width; ++x) {
        const SurfaceHit& h = hits[size_t(y) * width + x];
        if (!h.hit) continue;
        const Eigen::Vector3d to_led = led_position_in_stage - h.position;
        const double r_squared = to_led.squaredNorm();
        if (!(r_squared > 1e-12)) continue;  // The LED sits on the surface: no defined light.
        const Eigen::Vector3d wi = to_led / std::sqrt(r_squared);
        const auto g = physics::brdf::Geometry<double>::from_world(h.normal, wi, h.wo);
        if (!(g.cos_i > 0)) continue;
        const Eigen::Vector3d f = physics::brdf::eval(h.material, g);
        if (!(f.maxCoeff() > 0)) continue;
        // Shadow ray from the offset origin to the LED itself: geometry behind it does not count.
        const Eigen::Vector3d origin = shadow_ray_origin(h);
        const Eigen::Vector3d to_led_from_origin = led_position_in_stage - origin;
        const double reach = to_led_from_origin.norm();
        if (tracer.occluded(origin, to_led_from_origin / reach, 0.0, reach)) continue;
        const double falloff = d0_squared / r_squared;
        for (int c = 0; c < 3; ++c) out.at(x, y, c) = float(f[c] * g.cos_i * falloff);
      }
    }
  });
  return out;
}

}  // namespace detail

Image render_one_light(const Scene& scene, const std::vector<SurfaceHit>& hits,
                       const Eigen::Vector3d& dir_in_stage) {
  return detail::render_one_light_with(Tracer(scene), hits, dir_in_stage);
}

Image render_one_near_light(const Scene& scene, const std::vector<SurfaceHit>& hits,
                            const Eigen::Vector3d& led_position_in_stage) {
  return detail::render_one_near_light_with(Tracer(scene), hits, led_position_in_stage);
}

Image render_one_led(const Scene& scene, const std::vector<SurfaceHit>& hits, const Led& led) {
  if (led.distance_m) {
    return render_one_near_light(scene, hits, *led.distance_m * led.dir_in_stage.normalized());
  }
  return render_one_light(scene, hits, led.dir_in_stage);
}

}  // namespace ls::sim
