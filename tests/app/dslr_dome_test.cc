// The simulated DSLR dome end to end: every frame a shot of the gphoto2 back-end's camera logic,
// downloaded as a DNG and decoded by LibRaw, every LED switched by the serial board emulator; the
// field built and relit, judged against the simulator's ground truth beside the 3-channel camera's
// ("GigE") path on the same scene. And the faults of such a dome: the camera gone mid-bracket, the
// board silent, each stopping with a clear error, every frame kept, and a resume completing.
#include <gtest/gtest.h>

#include <fstream>
#include <iostream>
#include <memory>

#include "capture/build_field.h"
#include "lightstage/controller/sequencer.h"
#include "lightstage/errors.h"
#include "lightstage/session.h"
#include "physics/envmap.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "sim/dslr_backend.h"
#include "sim/ground_truth.h"
#include "sim/scene.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

namespace fs = std::filesystem;

Stage dome_stage(const std::string& backend) {
  Stage stage = default_stage();
  stage.camera.width = stage.camera.height = 48;
  stage.camera.backend = backend;
  if (backend == "sim-dslr") {
    stage.camera.bit_depth = 16;
    stage.camera.tether.raw.mode = RawDecodeOptions::Mode::kBin2x2;
    stage.camera.timeout_s = 0.3;
    stage.camera.retries = 0;
  }
  return stage;
}

SequencerOptions simulated_clock() {
  SequencerOptions options;
  options.sleep = [](double) {};
  return options;
}

CaptureSummary capture_on_dslr_dome(Session& session, sim::SimulatedDslrDome& dome) {
  return run_capture(session, *dome.lights, *dome.camera, simulated_clock());
}

double relit_error(const capture::ReflectanceField& field, const Stage& stage, const char* map_name,
                   const sim::Scene& scene) {
  const physics::EnvironmentMap map =
      physics::EnvironmentMap::load(testing::source_dir() / "data" / "envmaps" / map_name);
  const auto dirs = stage.led_directions();
  const Image relit = relight::relight(field, relight::integrate_environment(map, dirs));
  sim::GroundTruthOptions gt;
  gt.directions_width = 64;
  gt.covered_by_leds = dirs;
  const Image truth = sim::render_ground_truth(scene, stage.camera, map, gt);
  return testing::compare_images(relit, truth).relative_rmse;
}

TEST(DslrDome, ItsRawCaptureRelightsAsWellAsTheThreeChannelCameras) {
  const testing::TempDir dir;
  const sim::Scene scene = sim::default_scene();

  const Stage gige_stage = dome_stage("sim");
  Session gige = Session::create(dir / "gige", gige_stage, {"sim", "", 1});
  sim::SimStage sim_stage(gige_stage, scene, 1);
  ASSERT_EQ(run_capture(gige, sim_stage.lights(), sim_stage.camera(), simulated_clock()).status,
            CaptureSummary::Status::kComplete);

  const Stage dslr_stage = dome_stage("sim-dslr");
  Session dslr = Session::create(dir / "dslr", dslr_stage, {"sim-dslr", "", 1});
  const auto dome = sim::open_simulated_dslr_dome(dslr_stage, scene, 1);
  const CaptureSummary summary = capture_on_dslr_dome(dslr, *dome);
  ASSERT_EQ(summary.status, CaptureSummary::Status::kComplete) << summary.message;
  EXPECT_EQ(dome->dslr->shots(), int(plan_frames(dslr_stage).size()));

  // Each frame's DNG kept beside it, journaled and verified.
  Session reopened = Session::open(dir / "dslr");
  const FrameCheck check = reopened.verify_frames();
  EXPECT_TRUE(check.damaged.empty());
  EXPECT_EQ(check.verified, int(plan_frames(dslr_stage).size()));
  const FrameRecord& first = reopened.frames().begin()->second;
  EXPECT_EQ(fs::path(first.original_file).extension(), ".DNG");
  EXPECT_TRUE(fs::exists(dir / "dslr" / first.original_file));

  const capture::ReflectanceField gige_field = capture::build_field(gige, {});
  const capture::ReflectanceField dslr_field = capture::build_field(reopened, {});
  for (const char* map : {"softbox_studio.exr", "sky_sun.exr"}) {
    const double gige_error = relit_error(gige_field, gige_stage, map, scene);
    const double dslr_error = relit_error(dslr_field, dslr_stage, map, scene);
    std::cout << map << ": relative RMSE against ground truth, 3-channel camera " << gige_error
              << ", DSLR dome " << dslr_error << "\n";
    EXPECT_LE(dslr_error, 1.10 * gige_error) << map;  // The bound: within 10%.
  }

  // A damaged raw file is found as a damaged frame would be.
  {
    std::fstream f(dir / "dslr" / first.original_file,
                   std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(400);
    f.put('\x5a');
  }
  Session damaged = Session::open(dir / "dslr");
  const FrameCheck after = damaged.verify_frames();
  ASSERT_EQ(after.damaged.size(), 1u);
  EXPECT_NE(after.damaged[0].find(first.original_file), std::string::npos) << after.damaged[0];
}

// The camera vanishes after `shots` shots, or the board goes silent after `commands`: the capture
// stops with the device named, its frames kept; reopened (as --resume does) it completes.
void expect_stop_then_resume(const std::function<void(sim::SimulatedDslrDome&)>& break_it,
                             const std::string& named) {
  const testing::TempDir dir;
  Stage stage = dome_stage("sim-dslr");
  stage.leds.resize(12);
  const sim::Scene scene = sim::default_scene();
  {
    Session session = Session::create(dir / "s", stage, {"sim-dslr", "", 1});
    const auto dome = sim::open_simulated_dslr_dome(stage, scene, 1);
    break_it(*dome);
    // A camera that stops delivering ends the run with a status; a device error is thrown (the
    // CLI's exit 3). Either way the message names the device.
    std::string message;
    try {
      const CaptureSummary stopped = capture_on_dslr_dome(session, *dome);
      EXPECT_NE(stopped.status, CaptureSummary::Status::kComplete);
      message = stopped.message;
    } catch (const HardwareError& e) {
      message = e.what();
    }
    EXPECT_NE(message.find(named), std::string::npos) << message;
  }
  Session session = Session::open(dir / "s");
  const int kept = int(session.frames().size());
  EXPECT_GT(kept, 0) << "the frames before the fault are kept";
  const auto dome = sim::open_simulated_dslr_dome(stage, scene, 1);  // Reconnected.
  const CaptureSummary resumed = capture_on_dslr_dome(session, *dome);
  ASSERT_EQ(resumed.status, CaptureSummary::Status::kComplete) << resumed.message;
  EXPECT_EQ(resumed.frames_already_present, kept);
  EXPECT_EQ(int(session.frames().size()), int(plan_frames(stage).size()));
}

TEST(DslrDome, ACameraGoneMidBracketStopsNamingItAndResumeCompletes) {
  expect_stop_then_resume([](sim::SimulatedDslrDome& d) { d.dslr->disconnect_after_shots(20); },
                          "lightstage simulated DSLR (sim:usb)");
}

TEST(DslrDome, ADownloadThatNeverComesStopsAsATimeoutAndResumeCompletes) {
  expect_stop_then_resume([](sim::SimulatedDslrDome& d) { d.dslr->lose_file_of_shot(7); },
                          "no raw file within");
}

TEST(DslrDome, ASilentBoardStopsNamingItsPortAndResumeCompletes) {
  expect_stop_then_resume(
      [](sim::SimulatedDslrDome& d) {
        d.board->change_after(15, sim::LedBoardEmulator::Behaviour::kSilent);
      },
      "LED board on /dev/pts/");
}

TEST(DslrDome, GarbageFromTheBoardStopsNamingItAndResumeCompletes) {
  expect_stop_then_resume(
      [](sim::SimulatedDslrDome& d) {
        d.board->change_after(15, sim::LedBoardEmulator::Behaviour::kGarbage);
      },
      "not an lsled1 board?");
}

}  // namespace
}  // namespace ls
