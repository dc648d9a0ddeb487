#include "sim/sim_stage.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <thread>

#include "lightstage/errors.h"
#include "sim/time_varying.h"
#include "sim/tracer.h"

namespace ls::sim {

namespace {

using detail::Tracer;

// Applies a material's spatial variation at the object's (s, t).
brdf::Material shade_material(const SceneMaterial& m, const Image* texture,
                              const Eigen::Vector2d& st) {
  brdf::Material out = m.base;
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
  const double aspect = double(camera.width) / camera.height;
  // Pixel centres; row 0 at the top (+Y).
  const double ndc_x = 2.0 * (x + 0.5) / camera.width - 1.0;
  const double ndc_y = 1.0 - 2.0 * (y + 0.5) / camera.height;
  if (camera.fov_y_deg <= 0.0) {
    const double half_h = 0.5 * camera.ortho_height_m;
    // Far enough in front of any stage object; the view plane is parallel to z = 0.
    *origin = Eigen::Vector3d(ndc_x * half_h * aspect, ndc_y * half_h, 100.0);
    *dir = Eigen::Vector3d(0, 0, -1);
  } else {
    const double tan_half = std::tan(0.5 * camera.fov_y_deg * brdf::kPi / 180.0);
    *origin = Eigen::Vector3d(0, 0, camera.distance_m);
    *dir = Eigen::Vector3d(ndc_x * tan_half * aspect, ndc_y * tan_half, -1.0).normalized();
  }
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
        const auto g = brdf::Geometry<double>::from_world(h.normal, wi, h.wo);
        if (!(g.cos_i > 0)) continue;
        const Eigen::Vector3d f = brdf::eval(h.material, g);
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
        const auto g = brdf::Geometry<double>::from_world(h.normal, wi, h.wo);
        if (!(g.cos_i > 0)) continue;
        const Eigen::Vector3d f = brdf::eval(h.material, g);
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

// ---------------------------------------------------------------------------------------------
// SimStage

namespace {

uint64_t mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// SplitMix64: a tiny generator per pixel, seeded by hashing (seed, sequence key, pixel), so the
// noise of any pixel of any frame is independent of what was captured before.
struct PixelRng {
  uint64_t state;
  uint64_t next() { return mix64(state += 0x9E3779B97F4A7C15ull); }
  double uniform_open() { return (double(next() >> 11) + 0.5) * 0x1.0p-53; }  // (0, 1)
  // Two independent standard normals (Box-Muller).
  void normals(double* z0, double* z1) {
    const double r = std::sqrt(-2.0 * std::log(uniform_open()));
    const double a = 2.0 * brdf::kPi * uniform_open();
    *z0 = r * std::cos(a);
    *z1 = r * std::sin(a);
  }
  int poisson(double mean) {  // Knuth; only for small means.
    const double limit = std::exp(-mean);
    int k = 0;
    double p = uniform_open();
    while (p > limit && k < 1000) {
      ++k;
      p *= uniform_open();
    }
    return k;
  }
};

// Below this mean the shot noise is sampled as Poisson; above, as its normal approximation.
constexpr double kPoissonNormalThresholdE = 50.0;

}  // namespace

struct SimStage::State {
  Stage stage;
  Scene scene;
  uint64_t seed = 0;
  std::unique_ptr<Tracer> tracer;        // Refers to `scene`, which never moves after construction.
  std::vector<SurfaceHit> hits_at_zero;  // Materials at scene time 0.
  bool time_varying = false;             // Any material with a process.
  // The cache of one scene time: hits with their materials then, and the one-light images.
  double cached_time_s = 0.0;
  std::vector<SurfaceHit> hits;
  std::vector<std::optional<Image>> one_light;  // Per LED, computed on first use.
  // Kept within cache_bytes, least recently used first out: a 4096^2 dome's 151 images would take
  // 30 GB, and a capture lights one LED after another (its bracket shares the image).
  std::size_t cache_bytes = std::size_t(1) << 30;
  std::vector<uint64_t> last_used;  // Per LED, a use counter.
  uint64_t uses = 0;
  std::vector<bool> on, dead;
  std::vector<double> level;  // Share of the time each lit LED is on (set_levels; else 1).
  std::multiset<uint64_t> timeout_keys;
  int timeout_after = -1;                                           // Negative: off.
  std::map<uint64_t, std::pair<SimStage::FrameFault, int>> faults;  // Key -> fault, shots left.
  std::vector<uint16_t> last_pixels;  // The previous frame, kept while faults are pending.
  int stuck_led = -1;
  double drift_per_frame = 0.0;
  int drift_start_frame = 0;
  int frames_delivered = 0;

  class Lights final : public LightController {
   public:
    explicit Lights(State& s) : s_(s) {}
    int num_lights() const override { return int(s_.stage.leds.size()); }
    void set_light(int led_index, bool on) override {
      if (led_index < 0 || led_index >= num_lights()) {
        throw HardwareError("sim:" + s_.stage.name + ": set_light: LED index " +
                            std::to_string(led_index) + " out of range [0, " +
                            std::to_string(num_lights()) + ")");
      }
      s_.on[led_index] = on;
      s_.level[led_index] = 1.0;
    }
    void set_levels(const std::vector<double>& level) override {
      check_levels(level, num_lights(), "sim:" + s_.stage.name);
      for (size_t l = 0; l < level.size(); ++l) {
        s_.level[l] = level[l];
        s_.on[l] = level[l] > 0;
      }
    }
    void all_off() noexcept override {
      std::fill(s_.on.begin(), s_.on.end(), false);
      std::fill(s_.level.begin(), s_.level.end(), 1.0);
    }

   private:
    State& s_;
  };

  class Cam final : public Camera {
   public:
    explicit Cam(State& s) : s_(s) {}
    CameraInfo info() const override {
      const CameraSpec& c = s_.stage.camera;
      return {"sim:" + s_.stage.name,
              "lightstage simulated camera",
              c.width,
              c.height,
              c.channels,
              c.bit_depth};
    }
    CapturedFrame capture(const FrameRequest& request) override { return s_.capture(request); }

   private:
    State& s_;
  };

  Lights lights{*this};
  Cam cam{*this};

  // Moves the cache to `time_s`: a static scene looks the same at every time, so it keeps one.
  void set_time(double time_s) {
    if (!time_varying || time_s == cached_time_s) return;
    hits = at_time(scene, hits_at_zero, time_s);
    cached_time_s = time_s;
    for (auto& image : one_light) image.reset();
  }

  // Drops the least recently used one-light images, but those of the LEDs `keep` marks, while the
  // cache with `keep`'s images is over its budget. Only at the start of a capture: references
  // handed out by one_light_image stay valid until the next capture.
  void trim_cache(const std::vector<bool>& keep) {
    const std::size_t image_bytes =
        std::size_t(stage.camera.width) * stage.camera.height * 3 * sizeof(float);
    std::size_t cached = 0;  // And those this capture will render.
    for (size_t l = 0; l < one_light.size(); ++l)
      cached += one_light[l] || keep[l] ? image_bytes : 0;
    while (cached > cache_bytes) {
      int oldest = -1;
      for (size_t l = 0; l < one_light.size(); ++l) {
        if (one_light[l] && !keep[l] && (oldest < 0 || last_used[l] < last_used[size_t(oldest)])) {
          oldest = int(l);
        }
      }
      if (oldest < 0) return;
      one_light[size_t(oldest)].reset();
      cached -= image_bytes;
    }
  }

  const Image& one_light_image(int led) {
    last_used[size_t(led)] = ++uses;
    if (!one_light[led]) {
      const Led& l = stage.leds[led];
      one_light[led] = l.distance_m
                           ? detail::render_one_near_light_with(
                                 *tracer, hits, *l.distance_m * l.dir_in_stage.normalized())
                           : detail::render_one_light_with(*tracer, hits, l.dir_in_stage);
    }
    return *one_light[led];
  }

  // A stale or torn frame takes the previous frame's pixels (all, or the rows from half the height
  // down); the previous frame is kept only while faults are pending.
  void apply_buffer_fault(std::optional<SimStage::FrameFault> fault, std::vector<uint16_t>& pixels,
                          size_t row_values) {
    if (last_pixels.size() == pixels.size()) {
      if (fault == SimStage::FrameFault::kStale) pixels = last_pixels;
      if (fault == SimStage::FrameFault::kTorn) {
        const size_t from = pixels.size() / row_values / 2 * row_values;
        std::copy(last_pixels.begin() + long(from), last_pixels.end(), pixels.begin() + long(from));
      }
    }
    if (faults.empty()) {
      last_pixels.clear();
    } else {
      last_pixels = pixels;
    }
  }

  CapturedFrame capture(const FrameRequest& request) {
    const std::string camera_name = "sim:" + stage.name;
    if (auto it = timeout_keys.find(request.sequence_key); it != timeout_keys.end()) {
      timeout_keys.erase(it);
      throw CameraTimeout(camera_name + ": no frame within " +
                          std::to_string(stage.camera.timeout_s) + " s (injected, sequence key " +
                          std::to_string(request.sequence_key) + ")");
    }
    if (timeout_after >= 0 && frames_delivered >= timeout_after) {
      throw CameraTimeout(camera_name + ": no frame within " +
                          std::to_string(stage.camera.timeout_s) + " s (injected after " +
                          std::to_string(timeout_after) + " frames)");
    }
    const CameraSpec& cam_spec = stage.camera;
    if (!(request.exposure_s > 0) || !(request.gain > 0)) {
      throw HardwareError(camera_name + ": capture: expected a positive exposure and gain, got " +
                          std::to_string(request.exposure_s) + " s, gain " +
                          std::to_string(request.gain));
    }
    if (cam_spec.channels != 1 && cam_spec.channels != 3) {
      throw HardwareError(camera_name + ": channels: the simulator delivers 1 or 3, got " +
                          std::to_string(cam_spec.channels));
    }
    if (cam_spec.bit_depth < 1 || cam_spec.bit_depth > 16) {
      throw HardwareError(camera_name + ": bit_depth: expected 1..16, got " +
                          std::to_string(cam_spec.bit_depth));
    }
    const int w = cam_spec.width, h = cam_spec.height;
    const size_t n = size_t(w) * h;
    set_time(request.scene_time_s);  // The scene as it is at this frame's plan time.
    trim_cache(on);
    const auto exposure_ends =
        std::chrono::steady_clock::now() + std::chrono::duration<double>(request.exposure_s);

    std::optional<SimStage::FrameFault> fault;
    if (auto it = faults.find(request.sequence_key); it != faults.end()) {
      fault = it->second.first;
      if (--it->second.second <= 0) faults.erase(it);
    }
    // Radiance: the sum of the lit LEDs' one-light images times their RGB irradiance.
    std::vector<const float*> sources;
    std::vector<Eigen::Vector3f> weights;
    const size_t n_leds = stage.leds.size();
    for (size_t l = 0; l < n_leds; ++l) {
      if ((!on[l] && int(l) != stuck_led) || dead[l]) continue;
      const size_t lit = fault == SimStage::FrameFault::kWrongLed ? (l + 1) % n_leds : l;
      sources.push_back(one_light_image(int(lit)).pixels.data());
      const double drift = 1.0 + drift_per_frame * (frames_delivered - drift_start_frame);
      const double share = int(l) == stuck_led && !on[l] ? 1.0 : level[l];
      weights.push_back((share * drift * stage.leds[lit].irradiance_rgb()).cast<float>());
    }

    const SimulatedSensor& sensor = cam_spec.simulated;
    const double to_x = request.exposure_s / cam_spec.radiometric_scale;  // L -> normalised.
    const double dark_e = sensor.dark_current_e_per_s * request.exposure_s;
    const double read2 = sensor.read_noise_e * sensor.read_noise_e;
    const double gain_over_well = request.gain / sensor.full_well_e;
    const double max_dn = double((1u << cam_spec.bit_depth) - 1u);
    double gamma = 1.0;
    if (cam_spec.response.kind != CameraResponse::Kind::kLinear && cam_spec.response.gamma > 0) {
      gamma = cam_spec.response.gamma;
    }
    const double inv_gamma = 1.0 / gamma;
    const uint64_t frame_seed = mix64(mix64(seed ^ 0x5DEECE66Dull) ^ request.sequence_key);
    const int out_channels = cam_spec.channels;

    CapturedFrame frame;
    frame.exposure_s = request.exposure_s;
    frame.gain = request.gain;
    frame.raw.width = w;
    frame.raw.height = h;
    frame.raw.channels = out_channels;
    frame.raw.bit_depth = cam_spec.bit_depth;
    frame.raw.pixels.resize(n * out_channels);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const auto& range) {
      for (size_t p = range.begin(); p < range.end(); ++p) {
        double rgb[3] = {0, 0, 0};
        for (size_t k = 0; k < sources.size(); ++k) {
          for (int c = 0; c < 3; ++c) rgb[c] += double(sources[k][p * 3 + c]) * weights[k][c];
        }
        if (out_channels == 1) rgb[0] = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
        PixelRng rng{mix64(frame_seed ^ (uint64_t(p) * 0xD1B54A32D192ED03ull))};
        double z[4];
        rng.normals(&z[0], &z[1]);
        if (out_channels > 2) rng.normals(&z[2], &z[3]);
        for (int c = 0; c < out_channels; ++c) {
          const double mean_e = std::max(0.0, rgb[c] * to_x) * sensor.full_well_e + dark_e;
          double e;
          if (mean_e >= kPoissonNormalThresholdE) {
            e = mean_e + std::sqrt(mean_e + read2) * z[c];  // Shot and read noise together.
          } else {
            e = rng.poisson(mean_e) + sensor.read_noise_e * z[c];
          }
          e = std::clamp(e, 0.0, sensor.full_well_e);
          double x = std::clamp(e * gain_over_well + sensor.black_level, 0.0, 1.0);
          if (gamma != 1.0) x = std::pow(x, inv_gamma);
          frame.raw.pixels[p * out_channels + c] = uint16_t(std::lround(x * max_dn));
        }
      }
    });
    apply_buffer_fault(fault, frame.raw.pixels, size_t(w) * out_channels);
    if (sensor.real_time) std::this_thread::sleep_until(exposure_ends);
    ++frames_delivered;
    return frame;
  }
};

SimStage::SimStage(Stage stage, Scene scene, uint64_t seed) : state_(std::make_unique<State>()) {
  state_->stage = std::move(stage);
  state_->scene = std::move(scene);
  state_->seed = seed;
  for (const Led& led : state_->stage.leds) {
    if (led.distance_m && !(*led.distance_m > 0)) {
      throw InputError(state_->stage.source + ": leds: LED " + std::to_string(led.id) +
                       ": expected a positive distance, got " + std::to_string(*led.distance_m));
    }
  }
  state_->tracer = std::make_unique<Tracer>(state_->scene);
  state_->hits_at_zero = trace_camera(state_->scene, state_->stage.camera);
  state_->hits = state_->hits_at_zero;
  state_->time_varying = has_time_varying_materials(state_->scene);
  const size_t leds = state_->stage.leds.size();
  state_->one_light.resize(leds);
  state_->last_used.resize(leds, 0);
  state_->on.assign(leds, false);
  state_->level.assign(leds, 1.0);
  state_->dead.assign(leds, false);
}

SimStage::~SimStage() = default;

LightController& SimStage::lights() { return state_->lights; }
Camera& SimStage::camera() { return state_->cam; }
const Stage& SimStage::stage() const { return state_->stage; }
const Scene& SimStage::scene() const { return state_->scene; }
const std::vector<SurfaceHit>& SimStage::hits() const { return state_->hits; }
double SimStage::scene_time_s() const { return state_->cached_time_s; }

void SimStage::set_scene_time(double time_s) { state_->set_time(time_s); }

const Image& SimStage::one_light_image(int led_index) {
  LS_CHECK(led_index >= 0 && led_index < int(state_->stage.leds.size()),
           "LED index " + std::to_string(led_index) + " out of range");
  return state_->one_light_image(led_index);
}

void SimStage::set_one_light_cache_bytes(std::size_t bytes) { state_->cache_bytes = bytes; }

int SimStage::cached_one_light_images() const {
  return int(std::count_if(state_->one_light.begin(), state_->one_light.end(),
                           [](const auto& image) { return image.has_value(); }));
}

const Image& SimStage::one_light_image(int led_index, double time_s) {
  state_->set_time(time_s);
  return one_light_image(led_index);
}

void SimStage::inject_timeouts(std::vector<uint64_t> sequence_keys) {
  state_->timeout_keys.insert(sequence_keys.begin(), sequence_keys.end());
}

void SimStage::inject_timeout_after(int frames) {
  state_->timeout_after = frames;
  state_->frames_delivered = 0;
}

void SimStage::inject_frame_fault(uint64_t sequence_key, FrameFault fault, int shots) {
  state_->faults[sequence_key] = {fault, shots};
}

void SimStage::set_output_drift(double per_frame) {
  state_->drift_per_frame = per_frame;
  state_->drift_start_frame = state_->frames_delivered;
}

void SimStage::perturb_led(int led_index, double intensity_factor,
                           const Eigen::Vector3d& dir_in_stage) {
  LS_CHECK(led_index >= 0 && led_index < int(state_->stage.leds.size()),
           "LED index " + std::to_string(led_index) + " out of range");
  Led& led = state_->stage.leds[size_t(led_index)];
  led.intensity *= intensity_factor;
  led.dir_in_stage = dir_in_stage.normalized();
  state_->one_light[size_t(led_index)].reset();
}

void SimStage::set_stuck_led(int led_index) {
  LS_CHECK(led_index < int(state_->stage.leds.size()),
           "LED index " + std::to_string(led_index) + " out of range");
  state_->stuck_led = led_index;
}

void SimStage::set_dead_led(int led_index, bool dead) {
  LS_CHECK(led_index >= 0 && led_index < int(state_->stage.leds.size()),
           "LED index " + std::to_string(led_index) + " out of range");
  state_->dead[led_index] = dead;
}

}  // namespace ls::sim
