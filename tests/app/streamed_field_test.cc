// Fields read in bands of rows: `lightstage relight` on scanline and tiled fields
// gives the bytes of the in-memory relighting, and its peak memory does not follow the field;
// `lightstage fit --memory` gives the maps of the whole field.
#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <iostream>
#include <iterator>
#include <string>
#include <vector>

#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/controller/sequencer.h"
#include "lightstage/exr_channels.h"
#include "lightstage/image.h"
#include "lightstage/session.h"
#include "lightstage/stage.h"
#include "relight/fit/fit.h"
#include "relight/fit/normals.h"
#include "sim/noisy_field.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

namespace fs = std::filesystem;

// A field of smooth values with a little hash noise: no run-length compression to speak of.
capture::ReflectanceField synthetic_field(int width, int height, int leds) {
  std::vector<capture::FieldLight> lights;
  const std::vector<Eigen::Vector3d> dirs = fibonacci_dome_directions(leds, -11.5);
  for (int l = 0; l < leds; ++l) {
    capture::FieldLight light;
    light.led_id = l;
    light.dir_in_stage = dirs[size_t(l)];
    lights.push_back(light);
  }
  capture::ReflectanceField field(width, height, lights);
  uint32_t state = 12345;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      float* p = field.pixel(x, y);
      for (int i = 0; i < 3 * leds; ++i) {
        state = state * 1664525u + 1013904223u;
        p[i] = 0.1f + 0.5f * float(x + y) / float(width + height) + float(state >> 8) * 1e-8f;
      }
    }
  }
  return field;
}

std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Runs the CLI; its exit code and the peak resident memory it reports (its own, VmHWM), in KiB.
struct Measured {
  int code = -1;
  long peak_kib = 0;
};
Measured run_measured(const std::vector<std::string>& args) {
  std::string command = testing::cli_path().string();
  for (const std::string& a : args) command += " '" + a + "'";
  Measured m;
  std::string out;
  m.code = testing::run_command(command, &out);
  if (m.code != 0) std::cout << command << "\n" << out << "\n";  // Why it failed.
  const size_t at = out.find("peak memory ");
  if (at != std::string::npos) m.peak_kib = long(std::stod(out.substr(at + 12)) * 1024);
  return m;
}

fs::path write_map(const fs::path& dir) {
  Image sky(64, 32, 3, 0.2f);
  for (int y = 0; y < 16; ++y) {
    for (int x = 0; x < 64; ++x) sky.at(x, y, 0) = 1.0f + 0.05f * x;
  }
  write_exr(dir / "sky.exr", sky);
  return dir / "sky.exr";
}

TEST(StreamedField, TiledAndScanlineBandsRelightBitIdentically) {
  const testing::TempDir dir;
  const capture::ReflectanceField field = synthetic_field(96, 80, 24);
  capture::write_field(dir / "scanline.exr", field);
  capture::write_field(dir / "tiled.exr", field, {}, 16);
  const fs::path map = write_map(dir.path());
  // In memory, then in bands of 5 rows (scanline) and 16 rows (one tile row).
  const std::string budget = std::to_string(5 * 96 * 72 * sizeof(float) * 2);
  for (const std::string name : {"scanline", "tiled"}) {
    const std::string field_file = (dir / (name + ".exr")).string();
    ASSERT_EQ(run_measured({"relight", field_file, "--env", map.string(), "--out",
                            (dir / (name + "_whole")).string()})
                  .code,
              0);
    ASSERT_EQ(run_measured({"relight", field_file, "--env", map.string(), "--memory", budget,
                            "--out", (dir / (name + "_bands")).string()})
                  .code,
              0);
    const Image whole = read_image(dir / (name + "_whole") / "sky.exr");
    const Image bands = read_image(dir / (name + "_bands") / "sky.exr");
    EXPECT_EQ(whole.pixels, bands.pixels) << name;
  }
  EXPECT_EQ(read_image(dir / "scanline_whole" / "sky.exr").pixels,
            read_image(dir / "tiled_bands" / "sky.exr").pixels);
  // The tiled file reads back as the same field.
  EXPECT_EQ(capture::read_field(dir / "tiled.exr").values(), field.values());
}

// The simulated default scene under `leds` LEDs of a dome, with measured noise.
capture::ReflectanceField noisy_sim_field(int leds, int width, int height) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(leds, -11.5));
  stage.camera.width = width;
  stage.camera.height = height;
  capture::FieldNoise noise;
  noise.read_variance = 1e-6;
  noise.shot_variance_per_unit = 1e-4;
  noise.measured = true;
  return sim::render_noisy_field(stage, sim::default_scene(), noise, 5);
}

// Fitted in bands of 7 rows, with basis materials (two more passes: the pooled pixels' rows, then
// every pixel's blend) and per pixel, the maps are the whole field's, byte for byte.
// The LEDs are near (positions and a view): a pixel sees them from where it is in the frame, not
// in its band.
TEST(StreamedField, FitsInBandsGiveTheMapsOfTheWholeField) {
  const testing::TempDir dir;
  capture::ReflectanceField field = noisy_sim_field(60, 48, 40);
  field.view = capture::FieldView{};
  for (capture::FieldLight& light : field.lights()) {
    light.position_in_stage = 2.0 * light.dir_in_stage.normalized();
  }
  capture::write_field(dir / "field.exr", field);
  const std::size_t row_bytes = 48 * 3 * field.lights().size() * sizeof(float);
  const std::string budget = std::to_string(7 * 2 * row_bytes);  // The band and its read buffer.
  for (const std::string materials : {"basis", "per-pixel"}) {
    const auto fit = [&](const std::string& name, const std::vector<std::string>& extra) {
      std::vector<std::string> args = {"fit",         (dir / "field.exr").string(),
                                       "--materials", materials,
                                       "--out",       (dir / name).string()};
      args.insert(args.end(), extra.begin(), extra.end());
      ASSERT_EQ(run_measured(args).code, 0) << materials;
    };
    fit("whole.exr", {});
    fit("bands.exr", {"--memory", budget});
    const Image whole = read_image(dir / "whole.exr");
    EXPECT_EQ(whole.pixels, read_image(dir / "bands.exr").pixels) << materials;
    EXPECT_EQ(whole.width, 48);
  }
}

// `lightstage relight --models` reads the maps a band of rows at a time (16 rows under a tiny
// budget), with a mask edit (its rows found in the frame) and the field for the flagged pixels
// (one pass over its file): the images of the maps rendered whole, byte for byte.
TEST(StreamedField, ModelsRenderedInBandsAreTheWholeMapsRender) {
  const testing::TempDir dir;
  const capture::ReflectanceField field = noisy_sim_field(36, 40, 56);
  capture::write_field(dir / "field.exr", field);
  ASSERT_EQ(
      run_measured({"fit", (dir / "field.exr").string(), "--out", (dir / "maps.exr").string()})
          .code,
      0);
  Image mask(40, 56, 3);
  for (int y = 20; y < 50; ++y) {
    for (int x = 5; x < 30; ++x) mask.at(x, y, 0) = mask.at(x, y, 1) = mask.at(x, y, 2) = 1;
  }
  write_png_preview(dir / "mask.png", mask);
  {
    std::ofstream edits(dir / "edits.json");
    edits << R"({"edits": [{"select": {"mask": "mask.png"}, "albedo_tint": [1, 0.2, 0.2]}]})";
  }
  const auto render = [&](const std::string& out, const std::vector<std::string>& extra) {
    std::vector<std::string> args = {"relight",  (dir / "field.exr").string(),
                                     "--models", (dir / "maps.exr").string(),
                                     "--edits",  (dir / "edits.json").string(),
                                     "--env",    write_map(dir.path()).string(),
                                     "--light",  "0.3",
                                     "0.2",      "0.93",
                                     "--out",    (dir / out).string()};
    args.insert(args.end(), extra.begin(), extra.end());
    ASSERT_EQ(run_measured(args).code, 0);
  };
  render("whole", {});
  render("bands", {"--memory", "16K"});
  for (const std::string name : {"sky.exr", "light.exr"}) {
    const Image whole = read_image(dir / "whole" / name);
    EXPECT_EQ(whole.height, 56);
    EXPECT_TRUE(whole.pixels == read_image(dir / "bands" / name).pixels) << name;
  }
}

// `lightstage normals` reads the field in bands and writes the photometric-stereo normals, albedo,
// confidence and flags that relight/fit/normals.h estimates on the whole field, bit for bit.
TEST(StreamedField, NormalsInBandsAreThoseOfTheWholeField) {
  const testing::TempDir dir;
  const capture::ReflectanceField field = noisy_sim_field(40, 40, 36);
  capture::write_field(dir / "field.exr", field);
  const std::size_t row_bytes = 40 * 3 * field.lights().size() * sizeof(float);
  const Measured run =
      run_measured({"normals", (dir / "field.exr").string(), "--out",
                    (dir / "normals.exr").string(), "--memory", std::to_string(5 * row_bytes)});
  ASSERT_EQ(run.code, 0);
  relight::FitOptions fit;
  fit.use_noise_of(field);
  const relight::NormalMap whole = relight::estimate_normals(field, fit.normals);
  const NamedChannelFile file =
      read_named_channels(dir / "normals.exr",
                          {"normal.x", "normal.y", "normal.z", "albedo.r", "albedo.g", "albedo.b",
                           "confidence", "flags"},
                          "normals", "'lightstage normals'", /*exact=*/true);
  ASSERT_EQ(file.image.width, 40);
  ASSERT_EQ(file.image.height, 36);
  int flagged = 0;
  for (size_t i = 0; i < file.image.num_pixels(); ++i) {
    const float* n = &file.image.pixels[i * 8];
    for (int c = 0; c < 3; ++c) {
      ASSERT_EQ(n[c], whole.normal.pixels[i * 3 + size_t(c)]) << "pixel " << i;
      ASSERT_EQ(n[3 + c], whole.albedo.pixels[i * 3 + size_t(c)]) << "pixel " << i;
    }
    ASSERT_EQ(n[6], whole.confidence.pixels[i]) << "pixel " << i;
    ASSERT_EQ(n[7], whole.flags.pixels[i]) << "pixel " << i;
    flagged += n[7] != 0;
  }
  EXPECT_EQ(flagged, whole.flagged_pixels);
  for (const char* preview :
       {"normals.normal.png", "normals.albedo.png", "normals.confidence.png"}) {
    EXPECT_TRUE(fs::exists(dir / preview)) << preview;
  }
}

// A field without measured noise (an import's) is weighed by the noise of its own data, sampled
// from rows spread down the field whatever --memory: in bands, the normals are those of the whole.
TEST(StreamedField, NormalsOfAFieldWithoutMeasuredNoiseAreTheSameInBands) {
  const testing::TempDir dir;
  capture::ReflectanceField field = noisy_sim_field(40, 40, 36);
  field.noise = capture::FieldNoise{};  // Not measured.
  capture::write_field(dir / "field.exr", field);
  const std::size_t row_bytes = 40 * 3 * field.lights().size() * sizeof(float);
  const auto normals = [&](const std::string& out, const std::vector<std::string>& extra) {
    std::vector<std::string> args = {"normals", (dir / "field.exr").string(), "--out",
                                     (dir / out).string()};
    args.insert(args.end(), extra.begin(), extra.end());
    EXPECT_EQ(run_measured(args).code, 0) << out;
    return read_image(dir / out);
  };
  const Image whole = normals("whole.exr", {});
  const Image banded = normals("banded.exr", {"--memory", std::to_string(5 * row_bytes)});
  EXPECT_EQ(whole.pixels, banded.pixels);
}

// A session captured on the simulated stage (no waits between frames).
fs::path capture_session(const fs::path& dir, int width, int height, int leds) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(leds, -11.5));
  stage.camera.width = width;
  stage.camera.height = height;
  sim::SimStage sim(stage, sim::default_scene(), /*seed=*/3);
  Session session = Session::create(dir, stage, {});
  SequencerOptions instant;
  instant.sleep = [](double) {};
  run_capture(session, sim.lights(), sim.camera(), instant);
  return dir;
}

TEST(StreamedField, BuildInBandsKeepsWithinTheBudget) {
  const testing::TempDir dir;
  // A 24 MiB field (256 x 192 x 42 LEDs), four times the 6 MiB budget.
  const fs::path big = capture_session(dir / "big", 256, 192, 42);
  const fs::path small = capture_session(dir / "small", 16, 16, 42);
  auto build = [&](const fs::path& session, const std::string& out,
                   const std::vector<std::string>& extra) {
    std::vector<std::string> args = {"build", session.string(), "--out", (dir / out).string()};
    args.insert(args.end(), extra.begin(), extra.end());
    const Measured m = run_measured(args);
    EXPECT_EQ(m.code, 0) << out;
    return m.peak_kib;
  };
  const std::size_t budget = std::size_t(6) << 20;
  // The fixed overhead: the same build of a 16 x 16 session (libraries, the session, the writer).
  const long overhead_kib = build(small, "small.exr", {});
  const long whole_kib = build(big, "whole.exr", {});
  const long banded_kib = build(big, "bands.exr", {"--memory", std::to_string(budget)});
  // Beside the budget, what scales with the frame, not the field: the darks' means and up to two
  // LEDs merged at once (the bracket's 16-bit frames, the merge, the LED's image and gains: about
  // 130 bytes a pixel, 6 MiB here), the photon-transfer samples of the noise estimate (at most
  // 12 LEDs x 10,000 pixels x 2 exposure pairs x 3 channels x 16 bytes, 11 MiB), and 4 MiB for
  // the allocator.
  const long frame_kib = 130L * 256 * 192 / 1024;
  const long allowed_kib = overhead_kib + long(budget >> 10) + frame_kib + (15 << 10);
  std::cout << "peak RSS of build: 16x16 session " << overhead_kib << " KiB, 24 MiB field whole "
            << whole_kib << " KiB, in bands within 6 MiB " << banded_kib << " KiB (allowed "
            << allowed_kib << ")\n";
  EXPECT_LT(banded_kib, allowed_kib);
  EXPECT_GT(whole_kib, banded_kib + (12 << 10));  // The measurement sees the field.
  EXPECT_EQ(capture::read_field(dir / "whole.exr").values(),
            capture::read_field(dir / "bands.exr").values());
}

TEST(StreamedField, PeakMemoryFollowsTheBudgetNotTheField) {
  const testing::TempDir dir;
  // 48 MiB of field values, four times the 12 MiB budget.
  capture::ReflectanceField field = synthetic_field(512, 256, 32);
  ASSERT_EQ(field.bytes(), std::size_t(48) << 20);
  // Its noise stated (NoiseModel's defaults, with which the fits' guards below were measured):
  // what a fit estimates from values that follow no reflectance model is not what this is about.
  field.noise = relight::NoiseModel{}.as_field_noise();
  field.noise.measured = true;
  field.noise.method = "stated by the test";
  capture::write_field(dir / "big.exr", field, {}, 32);
  capture::write_field(dir / "small.exr", synthetic_field(16, 16, 32));
  const fs::path map = write_map(dir.path());
  auto relight = [&](const std::string& file, const std::vector<std::string>& extra) {
    std::vector<std::string> args = {"relight", (dir / file).string(),
                                     "--env",   map.string(),
                                     "--out",   (dir / ("out_" + file)).string()};
    args.insert(args.end(), extra.begin(), extra.end());
    const Measured m = run_measured(args);
    EXPECT_EQ(m.code, 0) << file;
    return m.peak_kib;
  };
  const std::size_t budget = std::size_t(12) << 20;
  // The fixed overhead: the same command on a 16 x 16 field (libraries, the map, the writers).
  const long overhead_kib = relight("small.exr", {});
  // Relighting reads the field in pieces of at most 8 MiB as the file holds them and sums them into
  // its output (3 floats per pixel, 1.5 MiB, and its 8-bit preview): it holds no band, so its
  // memory is that whatever the budget, with 4 MiB of margin for the allocator.
  const long allowed_kib = overhead_kib + (8 << 10) + (2 << 10) + (4 << 10);
  const long whole_kib = relight("big.exr", {});
  const long banded_kib = relight("big.exr", {"--memory", std::to_string(budget)});
  std::cout << "peak RSS: 16x16 field " << overhead_kib << " KiB, 48 MiB field " << whole_kib
            << " KiB, with a 12 MiB budget " << banded_kib << " KiB (allowed " << allowed_kib
            << ")\n";
  EXPECT_LT(whole_kib, allowed_kib);
  EXPECT_LT(banded_kib, allowed_kib);

  // Fitted within the same budget, per pixel and with basis materials: the maps and normals are
  // never held whole (25 floats a pixel, 12.5 MiB here, and the maps' writer's copy, 8.5 MiB),
  // only a band's. Writing each band's checkpoint (its 25 floats a pixel, for resuming) costs
  // about nine times that band in the EXR writer (measured: 14 MiB at bands of 32 rows): a
  // regression guard from that measure, with the 4 MiB margin.
  auto fit = [&](const std::string& file, const std::string& materials,
                 const std::vector<std::string>& extra) {
    std::vector<std::string> args = {"fit",         (dir / file).string(),
                                     "--materials", materials,
                                     "--out",       (dir / ("maps_" + file)).string()};
    args.insert(args.end(), extra.begin(), extra.end());
    const Measured m = run_measured(args);
    EXPECT_EQ(m.code, 0) << file;
    return m.peak_kib;
  };
  for (const std::string materials : {"per-pixel", "basis"}) {
    const long fit_overhead_kib = fit("small.exr", materials, {});
    const long fit_banded_kib = fit("big.exr", materials, {"--memory", std::to_string(budget)});
    const long checkpoint_kib = long(9 * 32 * 512 * 25 * sizeof(float) >> 10);
    // Basis materials hold what their search needs whatever the field's size
    // (relight/fit/basis_materials.cc): up to 16 clusters of 96 pool pixels, each its terms at the
    // 32 LEDs (10 doubles a LED) and its 10 lobe sums (18 doubles), and the maps of the ~16k
    // pixels clustered, twice (80 bytes each). The fit finds one material here (8.3 MiB more).
    const long materials_kib =
        materials == "basis" ? long((16 * 96 * (10 * 32 + 10 * 18) * 8 + 2 * 16384 * 80) >> 10) : 0;
    const long fit_allowed_kib =
        fit_overhead_kib + long(budget >> 10) + checkpoint_kib + materials_kib + (4 << 10);
    std::cout << "fit (" << materials << ") peak RSS: 16x16 field " << fit_overhead_kib
              << " KiB, 48 MiB field in bands " << fit_banded_kib << " KiB (allowed "
              << fit_allowed_kib << ")\n";
    EXPECT_LT(fit_banded_kib, fit_allowed_kib) << materials;
  }

  // Compressed to HSH (order 2, 12 coefficients a pixel) within the same budget: the coefficients
  // go to a file beside the output as each band is fitted, and are quantised and written a row at
  // a time. Beside the band, it holds the band's coefficients and their copy by row (12 of the
  // band's 96 floats a pixel, twice): not the image's (12 floats a pixel, 6 MiB here).
  auto compress = [&](const std::string& file, const std::vector<std::string>& extra) {
    std::vector<std::string> args = {"compress", (dir / file).string(),
                                     "--format", "hsh2",
                                     "--out",    (dir / ("hsh_" + file + ".rti")).string()};
    args.insert(args.end(), extra.begin(), extra.end());
    const Measured m = run_measured(args);
    EXPECT_EQ(m.code, 0) << file;
    return m.peak_kib;
  };
  const long compress_overhead_kib = compress("small.exr", {});
  const long compress_banded_kib = compress("big.exr", {"--memory", std::to_string(budget)});
  const long compress_allowed_kib =
      compress_overhead_kib + long(budget >> 10) + long(budget >> 10) * 2 * 12 / 96 + (4 << 10);
  std::cout << "compress peak RSS: 16x16 field " << compress_overhead_kib
            << " KiB, 48 MiB field in bands " << compress_banded_kib << " KiB (allowed "
            << compress_allowed_kib << ")\n";
  EXPECT_LT(compress_banded_kib, compress_allowed_kib);
}

// Compressed in bands (scanline and tiled files, global and tiled PCA, RTI fits), the files have
// the bytes of the compression in memory.
TEST(StreamedField, CompressInBandsWritesTheBytesOfTheWholeField) {
  const testing::TempDir dir;
  const capture::ReflectanceField field = synthetic_field(96, 80, 24);
  capture::write_field(dir / "scanline.exr", field);
  capture::write_field(dir / "tiled.exr", field, {}, 16);
  // Bands of about 10 rows (PCA: whole 16-row tiles, or the Gram's 32-row sub-bands).
  const std::string budget = std::to_string(10 * 2 * 96 * 72 * sizeof(float));
  const std::vector<std::vector<std::string>> formats = {{"--format", "pca"},
                                                         {"--format", "pca", "--tile", "16"},
                                                         {"--format", "hsh3"},
                                                         {"--format", "ptm"},
                                                         {"--format", "ptm-lrgb"}};
  for (const std::string name : {"scanline", "tiled"}) {
    for (size_t f = 0; f < formats.size(); ++f) {
      const auto compress = [&](const std::string& out, const std::vector<std::string>& extra) {
        std::vector<std::string> args = {"compress", (dir / (name + ".exr")).string(), "--out",
                                         (dir / out).string()};
        args.insert(args.end(), formats[f].begin(), formats[f].end());
        args.insert(args.end(), extra.begin(), extra.end());
        EXPECT_EQ(run_measured(args).code, 0) << name << " " << f;
        return read_bytes(dir / out);
      };
      const std::string whole = compress("whole", {});
      EXPECT_FALSE(whole.empty());
      EXPECT_EQ(compress("bands", {"--memory", budget}), whole) << name << " " << formats[f][1];
      for (const auto& entry : fs::directory_iterator(dir.path())) {  // Nothing spilled is left.
        EXPECT_EQ(entry.path().string().find(".rows-"), std::string::npos) << entry.path();
      }
    }
  }
}

}  // namespace
}  // namespace ls
