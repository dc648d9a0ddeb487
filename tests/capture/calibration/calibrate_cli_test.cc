// `lightstage calibrate` end to end: photographs of calibration targets rendered on a perturbed
// simulated dome are written to disk, the command calibrates the nominal stage file from them,
// and the stage it writes is compared with the truth.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "capture/light_calibration.h"
#include "sim/calibration_targets.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

using capture::angle_between_deg;

// A nominal 16-LED stage file, the dome it perturbs, and the photographs of its calibration
// targets written under a temporary directory; each step runs the command on them.
class CalibrateDome : public ::testing::Test {
 protected:
  void SetUp() override {
    nominal_ = stage_with_directions(fibonacci_dome_directions(16, 20.0));
    nominal_.camera.width = 640;
    nominal_.camera.height = 320;
    nominal_.camera.fov_y_deg = 0;
    nominal_.camera.ortho_height_m = 0.3;
    nominal_.source = path("stage.json");
    write_file_atomic(dir_ / "stage.json", stage_to_json(nominal_));
    sim::StagePerturbation perturbation;
    perturbation.seed = 3;
    perturbed_ = sim::perturb_stage(nominal_, perturbation);
  }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  static std::string led_file(int id) {
    char name[32];
    std::snprintf(name, sizeof name, "led%03d.exr", id);
    return name;
  }
  static std::string white_file(size_t l) {
    char name[32];
    std::snprintf(name, sizeof name, "white_%02zu.exr", l);
    return name;
  }
  // `lightstage calibrate ARGS`: its exit code, its output in output_.
  int calibrate(const std::string& args) {
    return testing::run_command(testing::cli_path().string() + " calibrate " + args, &output_);
  }

  sim::MirrorSphereRenderer sphere_renderer() const {
    return sim::MirrorSphereRenderer(
        {{Eigen::Vector3d(-0.18, 0, 0), 0.1}, {Eigen::Vector3d(0.18, 0, 0), 0.1}}, nominal_.camera);
  }
  // Mirror spheres' reference shot: FOLDER/reference.exr.
  void write_sphere_reference(const std::string& folder) {
    sim::SensorModel sensor;
    sensor.full_scale = 2.0;
    std::filesystem::create_directories(dir_ / folder);
    write_exr(dir_ / folder / "reference.exr",
              sim::apply_sensor(sphere_renderer().render_reference(1.0, 0.65), sensor, 1));
  }
  // Mirror spheres: a reference shot, one photograph per LED; LED 4's is black (it did not fire).
  void write_sphere_photos() {
    write_sphere_reference("spheres");
    const sim::MirrorSphereRenderer renderer = sphere_renderer();
    sim::SensorModel sensor;
    sensor.full_scale = 100.0;
    for (size_t l = 0; l < nominal_.leds.size(); ++l) {
      Image shot = renderer.render_led(perturbed_.truth.leds[l], 0.025, 0.65);
      if (l == 4) std::fill(shot.pixels.begin(), shot.pixels.end(), 0.0f);
      write_exr(dir_ / "spheres" / led_file(nominal_.leds[l].id),
                sim::apply_sensor(shot, sensor, 10 + l));
    }
  }

  // White target: one photograph per LED, in stage order (no ledNNN names).
  void write_white_photos() {
    std::filesystem::create_directories(dir_ / "white");
    sim::SensorModel sensor;
    sensor.full_scale = 0.5;
    sensor.blur_sigma_px = 0;
    sim::WhitePlaneTarget plane;
    plane.albedo = 0.8;
    for (size_t l = 0; l < nominal_.leds.size(); ++l) {
      write_exr(dir_ / "white" / white_file(l),
                sim::apply_sensor(sim::render_white_plane(plane, perturbed_.truth.leds[l],
                                                          perturbed_.beams[l], nominal_.camera),
                                  sensor, 100 + l));
    }
  }

  void expect_directions_recovered() {
    const Stage with_dirs = load_stage(dir_ / "directions.json");
    double worst = 0;
    int calibrated_dirs = 0;
    for (size_t l = 0; l < nominal_.leds.size(); ++l) {
      const bool kept =
          angle_between_deg(with_dirs.leds[l].dir_in_stage, nominal_.leds[l].dir_in_stage) < 1e-6;
      if (l == 4) {
        EXPECT_TRUE(kept) << "the dark image's LED keeps the drawing's direction";
      }
      if (kept) continue;  // LED 4, and LEDs behind the spheres (rim).
      ++calibrated_dirs;
      worst = std::max(worst, angle_between_deg(with_dirs.leds[l].dir_in_stage,
                                                perturbed_.truth.leds[l].dir_in_stage));
    }
    std::printf("directions: %d calibrated, worst %.3f deg\n", calibrated_dirs, worst);
    // Measured: 14 of 16, worst 0.059 deg.
    EXPECT_GE(calibrated_dirs, 14);
    EXPECT_LT(worst, 0.2);
  }

  void expect_intensities_recovered() {
    EXPECT_TRUE(std::filesystem::exists(dir_ / "calibrated.flatfield.exr"));
    const Stage calibrated = load_stage(dir_ / "calibrated.json");
    // The calibrated stage names its flat fields, so that `build` divides them out.
    EXPECT_EQ(calibrated.calibration.flat_field, dir_ / "calibrated.flatfield.exr");
    EXPECT_NO_THROW(capture::read_flat_field(calibrated.calibration.flat_field, calibrated));
    double worst_e = 0;
    int intensities = 0;
    for (size_t l = 0; l < nominal_.leds.size(); ++l) {
      // The plane faces the camera: LEDs behind it (z < 0.05) keep their intensities.
      if (perturbed_.truth.leds[l].dir_in_stage.z() < 0.1) continue;
      if (l == 4) continue;  // Its direction is the drawing's, 2 deg off: so is its cosine.
      ++intensities;
      const Eigen::Vector3d truth = perturbed_.truth.leds[l].irradiance_rgb();
      for (int c = 0; c < 3; ++c) {
        worst_e =
            std::max(worst_e, std::abs(calibrated.leds[l].irradiance_rgb()[c] / truth[c] - 1));
      }
    }
    std::printf("intensities: %d compared, worst %.3f%%\n", intensities, 100 * worst_e);
    // Measured: 7 LEDs, worst 0.19%.
    EXPECT_GE(intensities, 7);
    EXPECT_LT(worst_e, 0.01);
  }

  testing::TempDir dir_;
  Stage nominal_;
  sim::PerturbedStage perturbed_;
  std::string output_;
};

TEST_F(CalibrateDome, DirectionsThenIntensitiesRecoverThePerturbedDome) {
  write_sphere_photos();
  ASSERT_EQ(calibrate("directions --quiet --stage " + path("stage.json") + " --images " +
                      path("spheres") + " --saturation 100 --out " + path("directions.json")),
            0)
      << output_;
  std::printf("%s", output_.c_str());
  EXPECT_NE(output_.find("led004.exr: sphere 0: no highlight"), std::string::npos) << output_;
  expect_directions_recovered();

  write_white_photos();
  ASSERT_EQ(
      calibrate("intensities --quiet --stage " + path("directions.json") + " --white " +
                path("white") + " --albedo 0.8 --saturation 0.5 --out " + path("calibrated.json")),
      0)
      << output_;
  std::printf("%s", output_.c_str());
  expect_intensities_recovered();
}

// No LED calibrated (every LED photo dark) is exit code 2 with no stage written.
TEST_F(CalibrateDome, DarkPhotosCalibrateNoDirectionAndWriteNothing) {
  write_sphere_reference("dark");
  for (const Led& led : nominal_.leds)
    write_exr(dir_ / "dark" / led_file(led.id), Image(640, 320, 3));
  EXPECT_EQ(calibrate("directions --quiet --stage " + path("stage.json") + " --images " +
                      path("dark") + " --out " + path("none.json")),
            2)
      << output_;
  EXPECT_NE(output_.find("no LED direction calibrated"), std::string::npos) << output_;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "none.json"));
}

// A NaN measurement (a usage error, 1) and an output in a missing folder (2) are refused before
// any work; photos of noise, not of the white target, have every LED refused by name, no LED made
// 3x brighter (it was +201%), exit code 2 and nothing written.
TEST_F(CalibrateDome, BadIntensityInputIsRefusedAndWritesNothing) {
  write_white_photos();
  const std::string intensities = "intensities --quiet --stage " + path("stage.json") +
                                  " --white " + path("white") + " --out " + path("i2.json");
  EXPECT_EQ(calibrate(intensities + " --plane-z nan"), 1) << output_;  // Usage.
  EXPECT_NE(output_.find("--plane-z: expected a finite number, got nan"), std::string::npos)
      << output_;
  EXPECT_EQ(calibrate(intensities + " --flat-field " + (dir_ / "missing" / "ff.exr").string()), 2)
      << output_;
  EXPECT_NE(output_.find("does not exist"), std::string::npos) << output_;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "missing"));
  EXPECT_FALSE(std::filesystem::exists(dir_ / "i2.json"));

  std::filesystem::create_directories(dir_ / "noise");
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> noise(0.0f, 0.4f);
  for (size_t l = 0; l < nominal_.leds.size(); ++l) {
    Image photo(640, 320, 3);
    for (float& v : photo.pixels) v = noise(rng);
    write_exr(dir_ / "noise" / white_file(l), photo);
  }
  EXPECT_EQ(calibrate("intensities --quiet --stage " + path("stage.json") + " --white " +
                      path("noise") + " --out " + path("i2.json")),
            2)
      << output_;
  EXPECT_NE(output_.find("white_01.exr: the image is not a smoothly lit white plane"),
            std::string::npos)
      << output_;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "i2.json"));
}

// No sphere in the reference shot, or a photo named for an LED id beyond an int: exit code 2 and
// a message naming the file, no crash.
TEST_F(CalibrateDome, BadSpherePhotosAreInputErrorsNamingTheFile) {
  write_sphere_photos();
  const std::string directions = "directions --quiet --stage " + path("stage.json") + " --images " +
                                 path("spheres") + " --out " + path("x.json");
  write_exr(dir_ / "spheres" / "reference.exr", Image(640, 320, 3));
  EXPECT_EQ(calibrate(directions), 2) << output_;
  EXPECT_NE(output_.find("reference.exr: no sphere found"), std::string::npos) << output_;

  std::filesystem::copy_file(dir_ / "spheres" / "reference.exr",
                             dir_ / "spheres" / "led99999999999999999999.exr");
  EXPECT_EQ(calibrate(directions), 2) << output_;
  EXPECT_NE(output_.find("led99999999999999999999.exr: LED id"), std::string::npos) << output_;
}

TEST(CalibrateCli, CameraFromChessboardPhotographsWritesTheFieldOfView) {
  testing::TempDir dir;
  Stage stage = default_stage();
  stage.camera.width = 640;
  stage.camera.height = 480;
  stage.camera.fov_y_deg = 30.0;  // The drawing; the lens is 40 deg.
  write_file_atomic(dir / "stage.json", stage_to_json(stage));
  CameraSpec lens = stage.camera;
  lens.fov_y_deg = 40.0;
  lens.distance_m = 1.0;
  const sim::Chessboard board;  // 9x6, 30 mm.
  std::filesystem::create_directories(dir / "boards");
  const double tilts[][2] = {{0, 0}, {30, 0}, {-30, 0}, {0, 30}, {0, -30}, {25, 25}, {-20, -20}};
  sim::SensorModel sensor;
  for (int i = 0; i < 7; ++i) {
    const sim::BoardPose pose = sim::board_facing_camera(
        board, Eigen::Vector3d(0.01 * i - 0.03, 0, 0), tilts[i][0], tilts[i][1]);
    write_exr(dir / "boards" / ("view" + std::to_string(i) + ".exr"),
              sim::apply_sensor(sim::render_chessboard(board, pose, lens), sensor, 70 + i));
  }
  write_exr(dir / "boards" / "view9_blank.exr", Image(640, 480, 3, 0.3f));
  std::string output;
  const std::string cli = testing::cli_path().string();
  ASSERT_EQ(testing::run_command(
                cli + " calibrate camera --quiet --images " + (dir / "boards").string() +
                    " --board 9x6 --square 30 --square-pixels --stage " +
                    (dir / "stage.json").string() + " --out " + (dir / "calibrated.json").string(),
                &output),
            0)
      << output;
  std::printf("%s", output.c_str());
  EXPECT_NE(output.find("view9_blank.exr"), std::string::npos) << output;
  EXPECT_NE(output.find("no 9x6 board found"), std::string::npos) << output;
  const Stage calibrated = load_stage(dir / "calibrated.json");
  std::printf("fov_y_deg: drawing 30, lens 40, calibrated %.4f\n", calibrated.camera.fov_y_deg);
  // Measured: 40.039 deg from 7 views, one focal length (the principal point, which the stage
  // file cannot hold, is poorly fixed by so few views: 13.5 px off in x).
  EXPECT_NEAR(calibrated.camera.fov_y_deg, 40.0, 0.1);
  // A board description that is not WxH: exit code 2 naming the flag.
  EXPECT_EQ(testing::run_command(cli + " calibrate camera --quiet --images " +
                                     (dir / "boards").string() + " --board 9by6",
                                 &output),
            2)
      << output;
  EXPECT_NE(output.find("--board: expected WxH"), std::string::npos) << output;
  // A count beyond an int (std::stoi threw out_of_range here once): exit code 2 naming the flag.
  EXPECT_EQ(testing::run_command(cli + " calibrate camera --quiet --images " +
                                     (dir / "boards").string() + " --board 99999999999x6",
                                 &output),
            2)
      << output;
  EXPECT_NE(output.find("--board: expected at most 1000"), std::string::npos) << output;
  // A stage to update that cannot be: no --stage, or a camera of another size. Exit code 2, and
  // refused before the fit (no view reported).
  const std::string camera = cli + " calibrate camera --quiet --images " +
                             (dir / "boards").string() + " --out " + (dir / "x.json").string();
  EXPECT_EQ(testing::run_command(camera, &output), 2) << output;
  EXPECT_NE(output.find("--out: needs --stage"), std::string::npos) << output;
  EXPECT_EQ(output.find("board found"), std::string::npos) << output;
  stage.camera.height = 240;
  write_file_atomic(dir / "small.json", stage_to_json(stage));
  EXPECT_EQ(testing::run_command(camera + " --stage " + (dir / "small.json").string(), &output), 2)
      << output;
  EXPECT_NE(output.find("small.json: camera: expected 640x480 like the photographs, got 640x240"),
            std::string::npos)
      << output;
  EXPECT_EQ(output.find("board found"), std::string::npos) << output;
  EXPECT_FALSE(std::filesystem::exists(dir / "x.json"));
}

}  // namespace
}  // namespace ls
