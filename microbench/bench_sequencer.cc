// Sequencer overhead per frame: the time run_capture spends on anything but waiting for the camera
// (switching LEDs, planning, writing and journaling each frame durably, the dead-LED check), with
// Aravis' in-process fake camera (the real Aravis API path, no network) and with the simulated
// stage (its frames unchecked, /0, and checked on arrival, /1: what the checks cost). Counters:
// overhead_ms (per frame, not in Camera::capture), camera_ms (per frame, inside it), frames (per
// capture), fps, and fps_vs_camera (the fake's own rate: its trigger poll).
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <memory>
#include <string>

#include "lightstage/controller/sequencer.h"
#include "lightstage/hardware/aravis_camera.h"
#include "lightstage/session.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

class NullLights : public ls::LightController {
 public:
  explicit NullLights(int n) : n_(n) {}
  int num_lights() const override { return n_; }
  void set_light(int, bool) override {}
  void all_off() noexcept override {}

 private:
  int n_;
};

// Measures the time spent inside the wrapped camera.
class TimedCamera : public ls::Camera {
 public:
  explicit TimedCamera(ls::Camera& inner) : inner_(inner) {}
  ls::CameraInfo info() const override { return inner_.info(); }
  ls::CapturedFrame capture(const ls::FrameRequest& r) override {
    const auto t0 = Clock::now();
    ls::CapturedFrame f = inner_.capture(r);
    seconds += std::chrono::duration<double>(Clock::now() - t0).count();
    return f;
  }
  double seconds = 0;

 private:
  ls::Camera& inner_;
};

ls::Stage bench_stage(const std::string& backend) {
  ls::Stage stage = ls::stage_with_directions(ls::fibonacci_dome_directions(16, 0));
  stage.camera.backend = backend;
  stage.camera.device_id = backend == "aravis" ? "Fake_1" : "";
  stage.camera.width = 64;
  stage.camera.height = 64;
  stage.camera.channels = backend == "aravis" ? 1 : 3;
  stage.camera.bit_depth = backend == "aravis" ? 8 : 12;
  stage.camera.bracket = {{0.001, 1.0}, {0.004, 1.0}, {0.016, 1.0}};
  stage.plan.dark_frames = 2;
  // Frames take their exposure time, as on a real camera: the frame writer then works while the
  // camera exposes, as it does in a real capture (an instant camera would measure the disk).
  stage.camera.simulated.real_time = true;
  return stage;
}

// One full capture per iteration into a fresh session.
// camera_fps: the camera's own frame rate, when it sets one (0: not known).
void run_sessions(benchmark::State& state, const ls::Stage& stage, ls::LightController& lights,
                  ls::Camera& camera, bool verify_frames, double camera_fps = 0) {
  const fs::path root = fs::temp_directory_path() / ("ls_bench_seq_" + std::to_string(::getpid()));
  TimedCamera timed(camera);
  ls::SequencerOptions options;
  options.sleep = [](double) {};
  options.verify_frames = verify_frames;
  double total_s = 0;
  long frames = 0;
  int run = 0;
  for (auto _ : state) {
    state.PauseTiming();
    const fs::path dir = root / std::to_string(run++);
    ls::Session session = ls::Session::create(dir, stage, {});
    state.ResumeTiming();
    const auto t0 = Clock::now();
    const ls::CaptureSummary summary = ls::run_capture(session, lights, timed, options);
    total_s += std::chrono::duration<double>(Clock::now() - t0).count();
    frames += summary.frames_captured;
    state.PauseTiming();
    fs::remove_all(dir);
    state.ResumeTiming();
  }
  fs::remove_all(root);
  state.counters["frames"] = double(frames) / double(state.iterations());
  state.counters["overhead_ms"] = 1e3 * (total_s - timed.seconds) / double(frames);
  state.counters["camera_ms"] = 1e3 * timed.seconds / double(frames);
  state.counters["fps"] = double(frames) / total_s;
  if (camera_fps > 0) state.counters["fps_vs_camera"] = double(frames) / total_s / camera_fps;
}

void BM_SequencerOverhead_AravisFake(benchmark::State& state) {
  const ls::Stage stage = bench_stage("aravis");
  ls::AravisCamera camera(stage.camera);
  constexpr double kCameraFps = 200;  // The fake delivers a frame per trigger poll: 5 ms.
  camera.set_fake_trigger_frequency(kCameraFps);
  NullLights lights(int(stage.leds.size()));
  // Unchecked: the fake draws a test pattern, whatever the LEDs do.
  run_sessions(state, stage, lights, camera, /*verify_frames=*/false, kCameraFps);
}
BENCHMARK(BM_SequencerOverhead_AravisFake)->Unit(benchmark::kMillisecond)->MinTime(2.0);

void BM_SequencerOverhead_Sim(benchmark::State& state) {
  const ls::Stage stage = bench_stage("sim");
  ls::sim::SimStage sim(stage, ls::sim::default_scene(), /*seed=*/1);
  run_sessions(state, stage, sim.lights(), sim.camera(), state.range(0) != 0);
}
BENCHMARK(BM_SequencerOverhead_Sim)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace

BENCHMARK_MAIN();
