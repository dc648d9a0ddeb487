// lightstage demo: the whole slice on the simulated stage, start to finish.
//   simulated capture of the demo scene on the built-in dome -> reflectance field -> relit under
//   every shipped map -> contact sheet, and a comparison with the directly rendered ground truth.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <exception>

#include "app/cli/commands.h"
#include "app/cli/validators.h"
#include "app/jobs/contact_sheet.h"
#include "capture/field.h"
#include "lightstage/image_metrics.h"
#include "lightstage/session.h"
#include "physics/envmap.h"
#include "sim/ground_truth.h"
#include "sim/scene.h"

namespace ls::cli {

namespace fs = std::filesystem;

namespace {

struct DemoArgs {
  fs::path out = "demo-out";
  int resolution = 256;
  uint64_t seed = 1;
  bool shared_maps = true;
  bool truth = true;
  bool quiet = false;
  bool dslr = false;
};

void run_demo(const DemoArgs& args) {
  // The demo's folder as a whole: its steps lock their own outputs inside it as well.
  const auto lock = lock_output(args.out);
  const bool out_existed = fs::exists(args.out);
  fs::create_directories(args.out);
  const fs::path session_dir = args.out / "session";
  std::fprintf(stderr, "== 1/4 capture on the simulated %s -> %s\n",
               args.dslr ? "DSLR dome (raw files, serial LED board)" : "stage",
               session_dir.c_str());
  if (fs::exists(session_dir / "manifest.json")) {
    jobs::CaptureOptions resume;
    resume.session_dir = session_dir;
    resume.resume = true;
    if (const int code = capture_session(resume, args.quiet); code != 0)
      throw CLI::RuntimeError(code);
  } else {
    // The built-in dome at the demo's resolution.
    Stage stage = default_stage();
    stage.camera.width = stage.camera.height = args.resolution;
    if (args.dslr) {  // The same dome and scene through the DSLR path (sim/dslr_backend.h).
      stage.camera.backend = "sim-dslr";
      stage.camera.bit_depth = 16;
      // Binned: a pixel's colour from its own block of sites, as the 3-channel camera has it.
      stage.camera.tether.raw.mode = RawDecodeOptions::Mode::kBin2x2;
    }
    const fs::path stage_file = args.out / "stage.json";
    jobs::CaptureOptions capture;
    capture.stage_file = stage_file;
    capture.session_dir = session_dir;
    capture.seed = args.seed;
    int code = 0;
    std::exception_ptr error;
    try {
      write_file_atomic(stage_file, stage_to_json(stage));
      code = capture_session(capture, args.quiet);
    } catch (...) {
      error = std::current_exception();
    }
    if (code != 0 || error) {
      // A capture that failed before its first frame left no session (jobs::capture): the demo
      // leaves nothing either; a session with frames stays for the next run to resume.
      if (!fs::exists(session_dir)) {
        std::error_code ignored;
        if (out_existed) {
          fs::remove(stage_file, ignored);
        } else {
          fs::remove_all(args.out, ignored);
        }
      }
      if (error) std::rethrow_exception(error);
      throw CLI::RuntimeError(code);
    }
  }

  const fs::path field_file = args.out / "field.exr";
  std::fprintf(stderr, "== 2/4 build the reflectance field -> %s\n", field_file.c_str());
  jobs::BuildJobOptions build;
  build.session_dir = session_dir;
  build.out = field_file;
  build_field_file(build, args.quiet);

  std::fprintf(stderr, "== 3/4 relight under every shipped environment map -> %s\n",
               (args.out / "relit").c_str());
  jobs::RelightOptions relight;
  relight.field_file = field_file;
  relight.maps = shipped_environment_maps(args.shared_maps);
  relight.out_dir = args.out / "relit";
  const jobs::RelightSummary relit = relight_and_report(relight, args.quiet);
  std::vector<jobs::Preview> previews;
  for (const jobs::RelitImage& image : relit.images) previews.push_back({image.png, image.label});
  jobs::write_contact_sheet(args.out / "contact_sheet.png", previews,
                            "lightstage demo: simulated capture, relit under " +
                                std::to_string(previews.size()) + " environment maps");

  if (!args.truth) return;
  std::fprintf(stderr, "== 4/4 compare with the directly rendered ground truth -> %s\n",
               (args.out / "truth").c_str());
  const Session session = Session::open(session_dir);
  const Stage& stage = session.stage();
  const sim::Scene scene = sim::default_scene();
  std::vector<jobs::Preview> comparison;
  std::printf("%-28s %12s %10s\n", "map", "rel. RMSE", "PSNR dB");
  for (const auto& map_path : shipped_environment_maps(false)) {
    const physics::EnvironmentMap map = physics::EnvironmentMap::load(map_path);
    sim::GroundTruthOptions gt;
    gt.directions_width = 128;  // 1.4-degree quadrature: exact shadows, ~20 s per map at 256^2.
    gt.covered_by_leds = stage.led_directions();
    const Image truth = sim::render_ground_truth(scene, stage.camera, map, gt);
    const Image relit = read_image(relight.out_dir / (map_path.stem().string() + ".exr"));
    const std::string name = map_path.stem().string();
    fs::create_directories(args.out / "truth");
    const double stops = auto_exposure_stops(truth);
    write_exr(args.out / "truth" / (name + ".exr"), truth);
    write_png_preview(args.out / "truth" / (name + ".png"), truth, stops);
    write_png_preview(args.out / "truth" / (name + "_relit.png"), relit, stops);
    const ImageError err = compare_images(relit, truth);
    const double rel = err.relative_rmse;
    std::printf("%-28s %12.4f %10.2f\n", name.c_str(), rel, err.psnr_db);
    char label[96];
    std::snprintf(label, sizeof label, "%s relit (rel.RMSE %.3f)", name.c_str(), rel);
    comparison.push_back({args.out / "truth" / (name + "_relit.png"), label});
    comparison.push_back({args.out / "truth" / (name + ".png"), name + " ground truth"});
  }
  jobs::write_contact_sheet(
      args.out / "comparison.png", comparison,
      "relit from the captured field vs ground truth rendered from the scene");
  std::fprintf(stderr, "done: see %s and %s\n", (args.out / "contact_sheet.png").c_str(),
               (args.out / "comparison.png").c_str());
}

}  // namespace

void add_demo_command(CLI::App& app) {
  auto args = std::make_shared<DemoArgs>();
  auto* cmd = app.add_subcommand(
      "demo",
      "Run the whole slice on the simulated stage: capture the demo scene on the built-in dome, "
      "build its reflectance field, relight it under every shipped environment map, and compare "
      "with the directly rendered ground truth. Re-running resumes or reuses the session.");
  cmd->add_option("--out", args->out, "Output directory.")->capture_default_str();
  cmd->add_option("--resolution", args->resolution, "Camera width and height in pixels.")
      ->check(CLI::Range(16, 2048))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "Noise seed of the simulated camera.")
      ->capture_default_str()
      ->check(kSeed);
  cmd->add_flag("!--no-shared-maps", args->shared_maps,
                "Only the maps in data/envmaps, not ../shared/data/envmaps.");
  cmd->add_flag("!--no-truth", args->truth, "Skip the ground-truth comparison.");
  add_quiet_flag(*cmd, args->quiet);
  cmd->add_flag("--dslr", args->dslr,
                "Capture on the simulated DSLR dome: every frame a raw (DNG) file from a "
                "gphoto2-like camera, decoded by LibRaw (binned 2x2), the LEDs on a serial "
                "board.");
  cmd->callback([args] { run_demo(*args); });
}

}  // namespace ls::cli
