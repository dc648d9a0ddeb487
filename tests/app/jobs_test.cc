// The library entry points the CLI binds (app/jobs): capture through the back-end registry,
// build, relight, fit; options validated with messages that name the option; options recorded in
// the files they write.
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <iostream>
#include <iterator>

#include "app/jobs/build_job.h"
#include "app/jobs/capture_job.h"
#include "app/jobs/compress_job.h"
#include "app/jobs/contact_sheet.h"
#include "app/jobs/fit_job.h"
#include "app/jobs/relight_job.h"
#include "app/jobs/relight_outputs.h"
#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/backend_registry.h"
#include "lightstage/direction_index.h"
#include "lightstage/errors.h"
#include "lightstage/session.h"
#include "physics/envmap.h"
#include "relight/compact/pca_field.h"
#include "relight/compact/rti_fits.h"
#include "relight/compact/rti_io.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "sim/ground_truth.h"
#include "sim/sim_backend.h"
#include "tests/app/e2e_fixtures.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

namespace fs = std::filesystem;

std::string exr_string_attribute(const fs::path& file, const std::string& name) {
  auto in = OIIO::ImageInput::open(file.string());
  if (!in) return {};
  const OIIO::ParamValue* p = in->spec().find_attribute(name);
  return p ? std::string(p->get_string()) : std::string();
}

// A job stopped as by a kill: its progress callback throws once `phase` is half done, and `at`
// (when given) gets how far it was.
struct Killed {};
jobs::ProgressFn killed_halfway_through(const std::string& phase, long* at = nullptr) {
  return [phase, at](const std::string& p, long done, long total, const std::string&) {
    if (p != phase || 2 * done < total) return;
    if (at) *at = done;
    throw Killed{};
  };
}

std::string input_error(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}

// A small capture of the demo scene on the built-in dome: every frame of the plan, through the
// registry's "sim" back-end, then built and relit by the jobs.
class Jobs : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sim::register_backend(backend_registry());
    dir_ = new testing::TempDir();
    Stage stage = default_stage();
    stage.camera.width = stage.camera.height = 24;
    write_file_atomic(*dir_ / "stage.json", stage_to_json(stage));
    jobs::CaptureOptions capture;
    capture.stage_file = *dir_ / "stage.json";
    capture.session_dir = *dir_ / "session";
    summary_ = new jobs::CaptureJobSummary(jobs::capture(capture));
    planned_frames_ = int(plan_frames(stage).size());
  }
  static void TearDownTestSuite() {
    delete summary_;
    delete dir_;
  }
  // The fixture's session built into DIR/field.exr.
  static fs::path built_field(const fs::path& dir) {
    jobs::BuildJobOptions build;
    build.session_dir = *dir_ / "session";
    build.out = dir / "field.exr";
    (void)jobs::build(build);
    return build.out;
  }
  static testing::TempDir* dir_;
  static jobs::CaptureJobSummary* summary_;
  static int planned_frames_;
};
testing::TempDir* Jobs::dir_ = nullptr;
jobs::CaptureJobSummary* Jobs::summary_ = nullptr;
int Jobs::planned_frames_ = 0;

TEST_F(Jobs, CaptureTakesEveryPlannedFrameThroughTheRegistryAndResumesToNothing) {
  EXPECT_EQ(summary_->capture.status, CaptureSummary::Status::kComplete)
      << summary_->capture.message;
  EXPECT_EQ(summary_->capture.frames_captured, planned_frames_);
  jobs::CaptureOptions resume;
  resume.session_dir = *dir_ / "session";
  resume.resume = true;
  const jobs::CaptureJobSummary again = jobs::capture(resume);
  EXPECT_TRUE(again.already_complete);
  EXPECT_EQ(again.frames_present_before, planned_frames_);
}

TEST_F(Jobs, CaptureRefusesABackendNoOneRegisteredNamingTheStageField) {
  Stage stage = default_stage();
  stage.camera.backend = "aravis";  // Only "sim" is registered in this test.
  write_file_atomic(*dir_ / "aravis.json", stage_to_json(stage));
  jobs::CaptureOptions options;
  options.stage_file = *dir_ / "aravis.json";
  options.session_dir = *dir_ / "never";
  const std::string what = input_error([&] { (void)jobs::capture(options); });
  EXPECT_NE(what.find("aravis.json: camera.backend"), std::string::npos) << what;
  EXPECT_NE(what.find("got \"aravis\""), std::string::npos) << what;
  EXPECT_FALSE(fs::exists(*dir_ / "never")) << "nothing is created before the devices open";
}

TEST_F(Jobs, OptionsSayWhatIsWrongByOption) {
  jobs::CaptureOptions capture;
  EXPECT_NE(capture.validate().find("--out"), std::string::npos);
  capture.session_dir = "s";
  capture.resume = true;
  capture.stage_file = "x.json";
  EXPECT_NE(capture.validate().find("--stage"), std::string::npos);

  jobs::RelightOptions relight;
  relight.field_file = "f.exr";
  relight.out_dir = "out";
  EXPECT_NE(relight.validate().find("--env"), std::string::npos);
  relight.maps = {"m.exr"};
  EXPECT_EQ(relight.validate(), "");
  relight.light_dir = Eigen::Vector3d(0, 0, 1);
  EXPECT_NE(relight.validate().find("--light"), std::string::npos);
  relight.light_dir.reset();
  relight.time_s = 3.0;
  EXPECT_NE(relight.validate().find("--temporal"), std::string::npos);
  relight.temporal_file = "t.exr";
  relight.time_s = std::nan("");
  EXPECT_NE(relight.validate().find("--time"), std::string::npos);

  jobs::FitJobOptions fit;
  fit.field_file = "f.exr";
  fit.out = "m.exr";
  fit.method = "svd";
  EXPECT_NE(fit.validate().find("--method"), std::string::npos);
  fit.method = "ls";
  fit.out = "maps";  // Refused before any fitting, not after.
  EXPECT_NE(fit.validate().find(".exr"), std::string::npos);
  fit.out = "m.exr";
  fit.time_inputs = {"t0.exr"};
  EXPECT_NE(fit.validate().find("not both"), std::string::npos);

  jobs::BuildJobOptions build;
  build.session_dir = "s";
  EXPECT_NE(build.validate().find("--out"), std::string::npos);
}

TEST_F(Jobs, BuildAndRelightWriteWhatTheLibraryComputesAndRecordTheirOptions) {
  jobs::BuildJobOptions build;
  build.session_dir = *dir_ / "session";
  build.out = *dir_ / "field.exr";
  const jobs::BuildJobSummary built = jobs::build(build);
  ASSERT_EQ(built.fields.size(), 1u);
  EXPECT_EQ(built.fields[0].lights, int(default_stage().leds.size()));
  EXPECT_NE(exr_string_attribute(build.out, jobs::kOptionsAttribute).find("\"time_step\":0"),
            std::string::npos);

  const capture::ReflectanceField field = capture::read_field(build.out);
  const fs::path map_file = *dir_ / "sky.exr";
  Image sky(64, 32, 3, 0.0f);
  for (int y = 0; y < 16; ++y) {
    for (int x = 0; x < 64; ++x) sky.at(x, y, 2) = sky.at(x, y, 0) = 1.0f + 0.05f * x;
  }
  write_exr(map_file, sky);

  jobs::RelightOptions relight;
  relight.field_file = build.out;
  relight.maps = {map_file};
  relight.rotations_deg = {0.0, 90.0};
  relight.out_dir = *dir_ / "relit";
  const jobs::RelightSummary summary = jobs::relight(relight);
  ASSERT_EQ(summary.images.size(), 2u);
  EXPECT_TRUE(fs::exists(summary.contact_sheet));
  std::vector<Eigen::Vector3d> dirs;
  std::vector<bool> valid;
  for (const auto& light : field.lights()) {
    dirs.push_back(light.dir_in_stage);
    valid.push_back(light.valid);
  }
  const physics::EnvironmentMap map = physics::EnvironmentMap::load(map_file);
  for (size_t k = 0; k < 2; ++k) {
    const Image expected = relight::relight(
        field, relight::integrate_environment(map, dirs, relight.rotations_deg[k], 0.0, valid));
    const Image written = read_image(summary.images[k].exr);
    ASSERT_EQ(written.pixels.size(), expected.pixels.size());
    for (size_t i = 0; i < written.pixels.size(); ++i) {
      ASSERT_EQ(written.pixels[i], expected.pixels[i]) << summary.images[k].label << " value " << i;
    }
    EXPECT_NE(exr_string_attribute(summary.images[k].exr, jobs::kOptionsAttribute).find("sky.exr"),
              std::string::npos);
  }
}

// A map that lights the scene from behind the backdrop (spot1Lux) leaves it nearly black:
// its preview stays dark instead of being exposed until its noise fills the frame; a map that
// lights the scene keeps the exposure of its own highlights.
// The contact sheet reads each preview's 8-bit codes as stored: grey repeated, alpha dropped, the
// codes unchanged where a tile is only enlarged; a preview cut short is refused by name.
TEST(ContactSheet, TilesGreyRgbAndRgbaPreviewsWithTheirCodesAndNamesOneItCannotRead) {
  testing::TempDir dir;
  const auto write_png = [&](const std::string& name, const std::vector<unsigned char>& pixel) {
    const int channels = int(pixel.size());
    std::vector<unsigned char> codes;
    for (int i = 0; i < 16 * 16; ++i) codes.insert(codes.end(), pixel.begin(), pixel.end());
    const fs::path path = dir / name;
    auto out = OIIO::ImageOutput::create(path.string());
    EXPECT_TRUE(out &&
                out->open(path.string(), OIIO::ImageSpec(16, 16, channels, OIIO::TypeDesc::UINT8)));
    EXPECT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, codes.data()));
    out->close();
    return path;
  };
  const std::vector<jobs::Preview> tiles = {{write_png("grey.png", {77}), "grey"},
                                            {write_png("rgb.png", {10, 120, 250}), "rgb"},
                                            {write_png("rgba.png", {200, 30, 90, 255}), "rgba"}};
  jobs::write_contact_sheet(dir / "sheet.png", tiles, "three previews");
  auto in = OIIO::ImageInput::open((dir / "sheet.png").string());
  ASSERT_TRUE(in);
  const OIIO::ImageSpec spec = in->spec();
  std::vector<unsigned char> sheet(size_t(spec.width) * spec.height * spec.nchannels);
  ASSERT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UINT8, sheet.data()));
  ASSERT_EQ(spec.nchannels, 3);
  // A tile's centre: tiles of 256 px, 4 px apart, under a 30 px title.
  const auto centre_of = [&](int tile) {
    const size_t p = (size_t(30 + 128) * spec.width + size_t(tile * 260 + 128)) * 3;
    return std::vector<unsigned char>(sheet.begin() + long(p), sheet.begin() + long(p) + 3);
  };
  EXPECT_EQ(centre_of(0), (std::vector<unsigned char>{77, 77, 77}));
  EXPECT_EQ(centre_of(1), (std::vector<unsigned char>{10, 120, 250}));
  EXPECT_EQ(centre_of(2), (std::vector<unsigned char>{200, 30, 90}));

  const fs::path cut = dir / "cut.png";
  std::ifstream whole(tiles[1].png, std::ios::binary);
  const std::string bytes{std::istreambuf_iterator<char>(whole), {}};
  write_file_atomic(cut, bytes.substr(0, bytes.size() / 2));
  const std::string error = input_error([&] {
    jobs::write_contact_sheet(dir / "sheet2.png", {{cut, "cut"}}, "cut short");
  });
  EXPECT_NE(error.find("cut.png"), std::string::npos) << error;
  EXPECT_FALSE(fs::exists(dir / "sheet2.png"));
}

TEST_F(Jobs, APreviewOfADarkRelightIsDarkNotNoise) {
  jobs::BuildJobOptions build;
  build.session_dir = *dir_ / "session";
  build.out = *dir_ / "field.exr";
  (void)jobs::build(build);
  Image behind(64, 32, 3, 0.0f);  // A bright patch at -Z (the map's centre): behind the scene.
  for (int y = 14; y < 18; ++y) {
    for (int x = 30; x < 34; ++x)
      behind.at(x, y, 0) = behind.at(x, y, 1) = behind.at(x, y, 2) = 1e3f;
  }
  write_exr(*dir_ / "behind.exr", behind);
  jobs::RelightOptions relight;
  relight.field_file = build.out;
  relight.maps = {*dir_ / "behind.exr",
                  testing::source_dir() / "data" / "envmaps" / "softbox_studio.exr"};
  relight.out_dir = *dir_ / "relit";
  const jobs::RelightSummary summary = jobs::relight(relight);
  ASSERT_EQ(summary.images.size(), 2u);
  const auto mean_code = [](const fs::path& png) {
    const Image image = read_image(png);
    double sum = 0;
    for (const float v : image.pixels) sum += v;
    return 255 * sum / double(image.pixels.size());
  };
  const double dark = mean_code(summary.images[0].png), lit = mean_code(summary.images[1].png);
  std::printf("preview means: lit from behind %.1f, softbox %.1f (of 255)\n", dark, lit);
  // Measured: 5.6 and 140; exposed by its own highlights, the first would be 114, all noise.
  EXPECT_LT(dark, 20);
  EXPECT_GT(lit, 100);
}

// A map's bright source is rendered at its direction and reported; when that would hold more
// than the memory given, it is relit by the LED cells instead (the same bytes as
// --no-bright-sources) and the output's detail says so; when only the scene's shape would, its
// shadows come from the flows alone (as --no-source-geometry), with a note.
TEST_F(Jobs, BrightSourcesOverTheMemoryGivenAreRelitByTheCellsAndSaySo) {
  jobs::BuildJobOptions build;
  build.session_dir = *dir_ / "session";
  build.out = *dir_ / "field.exr";
  (void)jobs::build(build);
  jobs::RelightOptions relight;
  relight.field_file = build.out;
  relight.maps = {testing::source_dir() / "data" / "envmaps" / "small_source.exr"};
  const auto run = [&](const std::string& name) {
    relight.out_dir = *dir_ / name;
    const jobs::RelightSummary summary = jobs::relight(relight);
    EXPECT_EQ(summary.images.size(), 1u);
    return std::make_pair(summary.images[0].detail, read_image(summary.images[0].exr));
  };
  const auto [split_detail, split] = run("split");
  EXPECT_NE(split_detail.find("bright source at elevation 50.0 deg"), std::string::npos)
      << split_detail;
  relight.bright_sources = false;
  const auto [cells_detail, cells] = run("cells");
  EXPECT_EQ(cells_detail.find("bright source"), std::string::npos) << cells_detail;
  EXPECT_NE(split.pixels, cells.pixels);
  relight.bright_sources = true;
  relight.memory_bytes = 1000;
  const auto [tight_detail, tight] = run("tight");
  EXPECT_NE(tight_detail.find("relit by the LED cells"), std::string::npos) << tight_detail;
  EXPECT_NE(tight_detail.find("--memory"), std::string::npos) << tight_detail;
  EXPECT_EQ(tight.pixels, cells.pixels);
  // Room for the source's LEDs (117 KB at 24x24) but not for every LED's image while the scene's
  // shape is recovered (1 MB more): the shadows by the flows alone, and the detail says so.
  relight.memory_bytes = 300000;
  const auto [flows_detail, flows] = run("flows");
  EXPECT_NE(flows_detail.find("by the LEDs' flows alone"), std::string::npos) << flows_detail;
  relight.memory_bytes = 0;
  relight.source_geometry = false;
  const auto [no_shape_detail, no_shape] = run("no_shape");
  EXPECT_EQ(no_shape_detail.find("flows alone"), std::string::npos) << no_shape_detail;
  EXPECT_EQ(flows.pixels, no_shape.pixels);
}

// A fit in bands of rows that is stopped halfway (as by a kill) resumes from the bands it
// finished: it fits only the rest, and its maps are those of an uninterrupted fit of the whole
// field; the finished bands are removed once the maps are written.
TEST_F(Jobs, AnInterruptedFitInBandsResumesFromTheBandsItFinished) {
  const testing::TempDir dir;
  const fs::path field_file = built_field(dir.path());
  jobs::FitJobOptions fit;
  fit.field_file = field_file;
  fit.out = dir / "whole.exr";
  const jobs::FitJobSummary whole = jobs::fit(fit);
  const capture::ReflectanceField field = capture::read_field(field_file);
  // The summary says where the time went, whole or in bands: each part measured, their sum
  // within the fit's own time (which excludes the noise, and the reading that the bands' basis
  // materials include).
  const auto expect_time_split = [](const jobs::FitJobSummary& s, bool bands) {
    const relight::FitTimes& t = s.fit.times;
    EXPECT_GT(t.normals, 0);
    EXPECT_GT(t.candidates, 0);
    EXPECT_GT(t.materials, 0);  // Basis materials (the default).
    EXPECT_GT(t.writing, 0);
    EXPECT_EQ(t.reading > 0, bands);
    EXPECT_LE(t.normals + t.candidates + t.materials + t.shadows + t.writing,
              s.seconds + t.reading + 1e-3);
  };
  expect_time_split(whole, false);
  fit.out = dir / "maps.exr";
  fit.memory =
      MemoryBudget(3 * 2 * std::size_t(field.width()) * field.num_lights() * 3 * sizeof(float));
  EXPECT_THROW((void)jobs::fit(fit, killed_halfway_through("fit (rows)")), Killed);
  EXPECT_FALSE(fs::exists(fit.out));
  EXPECT_TRUE(fs::exists(dir / "maps.exr.partial"));
  const jobs::FitJobSummary resumed = jobs::fit(fit);
  expect_time_split(resumed, true);
  ASSERT_LT(resumed.band_rows, field.height());
  EXPECT_GE(2 * resumed.resumed_rows, field.height());
  EXPECT_LT(resumed.resumed_rows, field.height());
  EXPECT_EQ(resumed.resumed_rows % resumed.band_rows, 0);
  EXPECT_EQ(read_image(fit.out).pixels, read_image(dir / "whole.exr").pixels);
  EXPECT_FALSE(fs::exists(dir / "maps.exr.partial"));

  // Stopped halfway through assigning the basis materials, it keeps the bands assigned too.
  fs::remove(fit.out);
  long assigned = 0;
  EXPECT_THROW((void)jobs::fit(fit, killed_halfway_through("materials (rows)", &assigned)), Killed);
  ASSERT_GT(assigned, 0) << "the field has basis materials to assign";
  long kept = 0;
  const jobs::FitJobSummary again =
      jobs::fit(fit, [&](const std::string& phase, long done, long, const std::string& item) {
        if (phase == "materials (rows)" && item == "resumed") kept = done;
      });
  EXPECT_EQ(again.resumed_rows, field.height()) << "every band's per-pixel fit was kept";
  EXPECT_EQ(kept, assigned);
  EXPECT_EQ(read_image(fit.out).pixels, read_image(dir / "whole.exr").pixels);
}

// The noise of a field without measured noise (an imported set) is estimated from its object's
// pixels, so the empty frame around an object changes nothing: the same field padded with black
// borders is fitted with the same noise and gives the same normals, to 0.1 degrees.
TEST_F(Jobs, TheEmptyFrameAroundAnImportedObjectDoesNotChangeItsFit) {
  const testing::TempDir dir;
  capture::ReflectanceField object = capture::read_field(built_field(dir.path()));
  object.noise = {};  // As an import: no dark frames, no bracket.
  constexpr int kLeft = 37, kTop = 21;
  capture::ReflectanceField framed(object.width() + kLeft + 50, object.height() + kTop + 9,
                                   object.lights());
  capture::copy_attributes(object, framed);
  for (int y = 0; y < object.height(); ++y) {
    for (int x = 0; x < object.width(); ++x) {
      std::copy_n(object.pixel(x, y), 3 * object.num_lights(), framed.pixel(kLeft + x, kTop + y));
    }
  }
  capture::write_field(dir / "object.exr", object);
  capture::write_field(dir / "framed.exr", framed);
  jobs::FitJobOptions fit;
  fit.field_file = dir / "object.exr";
  fit.out = dir / "object_maps.exr";
  const jobs::FitJobSummary alone = jobs::fit(fit);
  fit.field_file = dir / "framed.exr";
  fit.out = dir / "framed_maps.exr";
  const jobs::FitJobSummary in_frame = jobs::fit(fit);
  EXPECT_NE(alone.noise_source.find("estimated from the data"), std::string::npos)
      << alone.noise_source;
  EXPECT_EQ(alone.noise_source, in_frame.noise_source);
  EXPECT_EQ(alone.noise.a, in_frame.noise.a);
  EXPECT_EQ(alone.noise.b, in_frame.noise.b);
  const Image a = read_image(dir / "object_maps.exr");
  const Image b = read_image(dir / "framed_maps.exr");
  int normal[3];
  for (int c = 0; c < 3; ++c) {
    const std::string name = std::string("normal.") + "xyz"[c];
    normal[c] = int(std::find(a.channel_names.begin(), a.channel_names.end(), name) -
                    a.channel_names.begin());
    ASSERT_LT(normal[c], a.channels) << name;
    ASSERT_EQ(b.channel_names[size_t(normal[c])], name);
  }
  double worst_deg = 0;
  for (int y = 0; y < a.height; ++y) {
    for (int x = 0; x < a.width; ++x) {
      Eigen::Vector3d na, nb;
      for (int c = 0; c < 3; ++c) {
        na(c) = a.at(x, y, normal[c]);
        nb(c) = b.at(kLeft + x, kTop + y, normal[c]);
      }
      if (na.squaredNorm() == 0) continue;
      worst_deg = std::max(
          worst_deg,
          std::acos(std::clamp(na.normalized().dot(nb.normalized()), -1.0, 1.0)) * 180 / M_PI);
    }
  }
  EXPECT_LE(worst_deg, 0.1);
}

// --dim-samples reaches the fit and is recorded in its maps: on a capture 70x too dark, the fit
// with the dim samples readmitted writes other maps (by how much they are better:
// tests/relight/fit/fit_test.cc, FitModels.ADarkSurfacesDimSamples...).
TEST_F(Jobs, DimSamplesReachTheFitOfADarkCaptureAndAreRecorded) {
  const testing::TempDir dir;
  capture::ReflectanceField dark = capture::read_field(built_field(dir.path()));
  for (int y = 0; y < dark.height(); ++y) {
    float* row = dark.pixel(0, y);
    for (int i = 0; i < dark.width() * dark.num_lights() * 3; ++i) row[i] *= 0.015f;
  }
  capture::write_field(dir / "dark.exr", dark);
  jobs::FitJobOptions fit;
  fit.field_file = dir / "dark.exr";
  fit.materials = "per-pixel";
  fit.out = dir / "plain.exr";
  jobs::fit(fit);
  fit.dim_samples = true;
  fit.out = dir / "dim.exr";
  jobs::fit(fit);
  EXPECT_NE(read_image(dir / "plain.exr").pixels, read_image(dir / "dim.exr").pixels);
  EXPECT_NE(
      exr_string_attribute(dir / "dim.exr", jobs::kOptionsAttribute).find("\"dim_samples\":true"),
      std::string::npos);
  EXPECT_NE(exr_string_attribute(dir / "plain.exr", jobs::kOptionsAttribute)
                .find("\"dim_samples\":false"),
            std::string::npos);
}

// A build in bands that is stopped halfway through merging the LEDs (as by a kill) resumes from
// the LEDs it merged: it merges only the rest, and writes the bytes of an uninterrupted build;
// the kept LEDs are removed once the field is written.
TEST_F(Jobs, AnInterruptedBuildInBandsResumesFromTheLedsItMerged) {
  const testing::TempDir dir;
  const Stage stage = Session::open(*dir_ / "session").stage();
  jobs::BuildJobOptions build;
  build.session_dir = *dir_ / "session";
  build.out = dir / "whole.exr";
  (void)jobs::build(build);
  // A budget for a few rows at a time: built in bands through the kept spill.
  build.memory = MemoryBudget(
      4 * capture::ReflectanceField::bytes_for(stage.camera.width, 6, int(stage.leds.size())));
  build.out = dir / "field.exr";
  EXPECT_THROW((void)jobs::build(build, killed_halfway_through("build")), Killed);
  EXPECT_FALSE(fs::exists(build.out));
  ASSERT_TRUE(fs::exists(dir / "field.exr.partial" / "leds.spill"));
  const jobs::BuildJobSummary resumed = jobs::build(build);
  const jobs::BuiltField& built = resumed.fields.at(0);
  ASSERT_LT(built.band_rows, built.height);
  EXPECT_GT(built.build.resumed_lights, 0);
  EXPECT_LT(built.build.resumed_lights, built.build.lights_used);
  EXPECT_EQ(capture::read_field(build.out).values(),
            capture::read_field(dir / "whole.exr").values());
  EXPECT_EQ(capture::read_field(build.out).noise.read_variance,
            capture::read_field(dir / "whole.exr").noise.read_variance);
  EXPECT_FALSE(fs::exists(dir / "field.exr.partial"));
}

// A compression in bands that is stopped halfway resumes from the bands it finished, and writes
// the bytes of an uninterrupted run: to .rti, from the bands it fitted; to PCA, from the basis
// its first pass found and the bands it projected.
TEST_F(Jobs, AnInterruptedCompressInBandsResumesFromTheBandsItFitted) {
  const testing::TempDir dir;
  const fs::path field_file = built_field(dir.path());
  const capture::ReflectanceField field = capture::read_field(field_file);
  const auto bytes = [](const fs::path& f) {
    std::ifstream in(f, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  // PCA in tiles of 16 pixels: bands of whole tile rows (a global basis sums its Gram matrix over
  // sub-bands of 64 rows at this width: one band).
  for (const auto& [format, phase] :
       {std::pair{"hsh3", "pass 1 (rows)"}, std::pair{"pca", "coefficients (rows)"}}) {
    jobs::CompressOptions compress;
    compress.input = field_file;
    compress.format = format;
    compress.tile = std::string(format) == "pca" ? 16 : 0;
    compress.out = dir / (std::string("whole.") + format);
    (void)jobs::compress(compress);
    compress.out = dir / (std::string("bands.") + format);
    compress.memory = MemoryBudget(
        5 * capture::ReflectanceField::bytes_for(field.width(), 4, field.num_lights()));
    EXPECT_THROW((void)jobs::compress(compress, killed_halfway_through(phase)), Killed);
    EXPECT_FALSE(fs::exists(compress.out));
    EXPECT_TRUE(fs::exists(compress.out.string() + ".partial/coefficients.spill")) << format;
    bool passes = false;  // PCA: the basis's pass over the field is not made again.
    const jobs::CompressSummary resumed =
        jobs::compress(compress, [&](const std::string& p, long, long, const std::string&) {
          passes = passes || p == "pass 1 (rows)";
        });
    ASSERT_LT(resumed.band_rows, field.height());
    ASSERT_GT(resumed.band_rows, 0);
    EXPECT_GE(2 * resumed.resumed_rows, field.height());
    EXPECT_LT(resumed.resumed_rows, field.height());
    EXPECT_EQ(passes, std::string(format) != "pca") << format;
    EXPECT_EQ(bytes(compress.out), bytes(dir / (std::string("whole.") + format))) << format;
    EXPECT_FALSE(fs::exists(compress.out.string() + ".partial"));
  }
}

// `lightstage render` relights what `compress` wrote, as the library relights the file's decoded
// coefficients (bit for bit), upright: under an LED's direction it is that LED's image, not the
// image upside down.
TEST_F(Jobs, RenderRelightsACompactFileUnderALightAsItsFormatHoldsIt) {
  const testing::TempDir dir;
  const fs::path field_file = built_field(dir.path());
  const capture::ReflectanceField field = capture::read_field(field_file);
  const int led = field.num_lights() / 3;  // High on the dome: a lit, shaded image.
  const Eigen::Vector3d dir_to_led = field.lights()[size_t(led)].dir_in_stage;
  const auto rms = [](const Image& a, const std::function<float(int, int, int)>& b) {
    double sum = 0;
    for (int y = 0; y < a.height; ++y) {
      for (int x = 0; x < a.width; ++x) {
        for (int c = 0; c < 3; ++c) sum += std::pow(a.at(x, y, c) - b(x, y, c), 2);
      }
    }
    return std::sqrt(sum / double(a.num_pixels() * 3));
  };
  for (const std::string format : {"hsh3", "ptm", "pca"}) {
    jobs::CompressOptions compress;
    compress.input = field_file;
    compress.format = format;
    compress.out = dir / (format == "pca" ? "field.lspca" : format == "ptm" ? "f.ptm" : "f.rti");
    (void)jobs::compress(compress);
    jobs::RenderOptions render;
    render.input = compress.out;
    render.out = dir / (format + ".exr");
    render.light = {dir_to_led.x(), dir_to_led.y(), dir_to_led.z()};
    const jobs::RenderSummary summary = jobs::render_compact(render);
    EXPECT_EQ(summary.width, field.width()) << format;
    const Image rendered = read_image(render.out);
    EXPECT_TRUE(fs::exists(dir / (format + ".png"))) << format;
    // The preview's exposure is said: the one it was written with.
    EXPECT_DOUBLE_EQ(summary.preview_stops, auto_exposure_stops(rendered)) << format;
    const Image expected =
        format == "pca"
            ? relight::PcaField::read(compress.out).relight_point(dir_to_led)
            : relight::dequantise(relight::read_rti_file(compress.out)).relight_point(dir_to_led);
    EXPECT_EQ(rendered.pixels, expected.pixels) << format;
    // A .ptm cannot hold its gain: it renders with white = 1, the brightest sample.
    const float gain = format == "ptm"
                           ? 1.0f / *std::max_element(field.values().begin(), field.values().end())
                           : 1.0f;
    const double upright =
        rms(rendered, [&](int x, int y, int c) { return gain * field.at(x, y, led, c); });
    const double flipped = rms(rendered, [&](int x, int y, int c) {
      return gain * field.at(x, field.height() - 1 - y, led, c);
    });
    std::cout << format << ": rms against the LED's image " << upright << ", upside down "
              << flipped << "\n";
    EXPECT_LT(upright, 0.5 * flipped) << format;
  }
  jobs::RenderOptions bad;
  bad.input = dir / "f.rti";
  bad.out = dir / "bad.exr";
  bad.light = {0, 0, 0};
  EXPECT_NE(input_error([&] { (void)jobs::render_compact(bad); }).find("--light"),
            std::string::npos);
  bad.light.clear();
  EXPECT_NE(input_error([&] { (void)jobs::render_compact(bad); }).find("--env"), std::string::npos);
  EXPECT_FALSE(fs::exists(bad.out));
}

// A PCA under a small source: rendered at the source's direction from the PCA's own
// reconstruction (its normals, its LEDs' shadows, the shape they give), not by the map's grid of
// lights interpolated between the LEDs; against ground truth from the scene (64x64 demo scene).
TEST_F(Jobs, RenderOfAPcaCastsASmallSourcesShadowsAtItsDirection) {
  const testing::TempDir dir;
  Stage stage = default_stage();
  stage.camera.width = stage.camera.height = 64;
  const sim::Scene scene = sim::default_scene();
  capture::write_field(dir / "field.exr", testing::CaptureAndBuild(dir / "s", stage, scene));
  jobs::CompressOptions compress;
  compress.input = dir / "field.exr";
  compress.out = dir / "field.lspca";
  (void)jobs::compress(compress);
  const fs::path map_file = testing::source_dir() / "data" / "envmaps" / "small_source.exr";
  jobs::RenderOptions render;
  render.input = compress.out;
  render.environment = map_file;
  render.out = dir / "sources.exr";
  const jobs::RenderSummary summary = jobs::render_compact(render);
  EXPECT_NE(summary.sources.find("bright source"), std::string::npos) << summary.sources;
  render.bright_sources = false;
  render.out = dir / "grid.exr";
  EXPECT_TRUE(jobs::render_compact(render).sources.empty());
  const auto dirs = stage.led_directions();
  sim::GroundTruthOptions gt;
  gt.covered_by_leds = dirs;
  gt.coverage_radius_rad = max_nearest_neighbour_angle(dirs);
  const Image truth =
      sim::render_ground_truth(scene, stage.camera, physics::EnvironmentMap::load(map_file), gt);
  const double with_sources = compare_images(read_image(dir / "sources.exr"), truth).relative_rmse;
  const double by_grid = compare_images(read_image(dir / "grid.exr"), truth).relative_rmse;
  std::cout << "PCA under small_source: relative RMSE " << with_sources << " (by the grid "
            << by_grid << ")\n";
  // Measured 0.089 (by the grid 0.200; at 256^2 the demo's PCA gives 0.046 against 0.199):
  // asserted under 0.1 and under half the grid's.
  EXPECT_LT(with_sources, 0.1);
  EXPECT_LT(with_sources, 0.5 * by_grid);
}

TEST_F(Jobs, RelightRefusesBadOptionsBeforeWritingAnything) {
  jobs::RelightOptions relight;
  relight.field_file = *dir_ / "missing.exr";
  relight.out_dir = *dir_ / "not-created";
  const std::string what = input_error([&] { (void)jobs::relight(relight); });
  EXPECT_NE(what.find("--env"), std::string::npos) << what;
  EXPECT_FALSE(fs::exists(relight.out_dir));
}

// Each map is read once, before any image: one removed after the run started still renders, under
// every rotation, by its output names.
TEST_F(Jobs, MapRotationsReadEachMapOnceUpFront) {
  const fs::path map_file = *dir_ / "maps" / "sky.exr";
  fs::create_directories(map_file.parent_path());
  fs::copy_file(testing::source_dir() / "data" / "envmaps" / "small_source.exr", map_file);
  jobs::RelightOptions relight;
  relight.maps = {map_file};
  relight.rotations_deg = {0.0, 90.0};
  const jobs::MapRotations map_rotations(relight);
  fs::remove(map_file);
  std::vector<std::string> names;
  map_rotations.for_each([&](const physics::EnvironmentMap& map, double, const std::string& name) {
    EXPECT_GT(map.width(), 0);
    names.push_back(name);
  });
  EXPECT_EQ(names, (std::vector<std::string>{"sky_rot000", "sky_rot090"}));
  ASSERT_EQ(map_rotations.all().size(), 2u);
  EXPECT_EQ(map_rotations.all()[0].map, map_rotations.all()[1].map);
  EXPECT_EQ(map_rotations.all()[1].rotation_deg, 90.0);
}

}  // namespace
}  // namespace ls
