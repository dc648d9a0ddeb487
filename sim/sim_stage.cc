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
#include "lightstage/image.h"
#include "lightstage/memory.h"
#include "sim/time_varying.h"
#include "sim/tracer.h"

namespace ls::sim {

using detail::Tracer;

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
    const double a = 2.0 * physics::brdf::kPi * uniform_open();
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
  int trigger_edges = 0;  // Seen by the camera's trigger input since it was armed.
  bool trigger_wire_broken = false;
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
    void pulse_trigger() override {
      if (!s_.stage.camera.sync.line_triggered()) LightController::pulse_trigger();
      if (!s_.trigger_wire_broken) ++s_.trigger_edges;
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
    void set_trigger_line(const std::function<void()>& pulse) override {
      if (!s_.stage.camera.sync.line_triggered()) Camera::set_trigger_line(pulse);  // Throws.
      pulse_ = pulse;
    }
    CapturedFrame capture(const FrameRequest& request) override {
      if (s_.stage.camera.sync.line_triggered()) {  // Exposes on the edge its input sees.
        if (!pulse_) {
          throw HardwareError(info().id + ": camera.sync.trigger \"line\" and no controller " +
                              "line wired to it (camera.sync.gpio)");
        }
        s_.trigger_edges = 0;
        pulse_();
        if (s_.trigger_edges == 0) {
          throw CameraTimeout(info().id + ": no frame within camera.timeout_s: the trigger line " +
                              "was pulsed and the camera saw no edge (injected broken wire)");
        }
      }
      return s_.capture(request);
    }

   private:
    State& s_;
    std::function<void()> pulse_;  // camera.sync.trigger "line".
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
        if (out_channels == 1) rgb[0] = luminance(rgb[0], rgb[1], rgb[2]);
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
  // Per pixel: the camera's hits (at time zero and now), two one-light images (the fewest a frame
  // renders from) and the frame with the previous one a fault replays.
  const CameraSpec& camera = state_->stage.camera;
  const std::size_t bytes_per_pixel = 2 * sizeof(SurfaceHit) + std::size_t(2 * 3) * sizeof(float) +
                                      std::size_t(2 * camera.channels) * sizeof(uint16_t);
  require_memory(std::size_t(camera.width) * std::size_t(camera.height) * bytes_per_pixel,
                 state_->stage.source + ": camera.width, camera.height: the simulated stage's " +
                     std::to_string(camera.width) + "x" + std::to_string(camera.height) + " camera",
                 "give the simulated camera fewer pixels");
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

void SimStage::set_trigger_wire_broken(bool broken) { state_->trigger_wire_broken = broken; }

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
