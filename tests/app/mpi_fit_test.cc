// `lightstage fit` and `fit --time` under MPI: `mpirun -n 2` splits the bands over two
// ranks and writes the bytes of a one-process fit (but for the time in its header). Runs where
// CMake found MPI (CI installs it); skipped with a message elsewhere.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <iostream>
#include <iterator>
#include <string>
#include <vector>

#include "app/jobs/capture_job.h"
#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/backend_registry.h"
#include "lightstage/image.h"
#include "lightstage/stage.h"
#include "sim/noisy_field.h"
#include "sim/scene.h"
#include "sim/sim_backend.h"
#include "tests/relight/time/time_fixtures.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

namespace fs = std::filesystem;

// Two ranks on this machine, talking through shared memory and loopback only (no traffic leaves
// it); as root, Open MPI wants its two confirmations.
std::string mpirun_two() {
  return "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 " LIGHTSTAGE_MPIEXEC
         " -n 2 --oversubscribe --bind-to none --mca btl self,vader --mca oob_tcp_if_include lo ";
}

// The file's bytes with the time it was written (OpenEXR's capDate attribute) blanked.
std::string bytes_but_time(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  const std::string name("capDate\0string\0", 15);  // Then its size (4 bytes) and value.
  const size_t at = bytes.find(name);
  if (at != std::string::npos) {
    const size_t value = at + name.size() + 4;  // "YYYY:MM:DD HH:MM:SS"
    for (size_t i = value; i < value + 19 && i < bytes.size(); ++i) bytes[i] = '#';
  }
  return bytes;
}

int run(const std::string& command, std::string* out) {
  const int code = testing::run_command(command, out);
  if (code != 0) std::cout << command << "\n" << *out << "\n";  // Why it failed.
  return code;
}

fs::path write_test_field(const fs::path& dir) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(60, -11.5));
  stage.camera.width = 48;
  stage.camera.height = 40;
  capture::FieldNoise noise;
  noise.read_variance = 1e-6;
  noise.shot_variance_per_unit = 1e-4;
  capture::write_field(dir / "field.exr",
                       sim::render_noisy_field(stage, sim::default_scene(), noise, 5));
  return dir / "field.exr";
}

TEST(MpiFit, TwoRanksWriteTheBytesOfOneProcess) {
  if (std::string(LIGHTSTAGE_MPIEXEC).empty()) {
    GTEST_SKIP() << "built without MPI (install libopenmpi-dev and openmpi-bin: scripts/setup.sh)";
  }
  const testing::TempDir dir;
  const fs::path field = write_test_field(dir.path());
  const std::string cli = testing::cli_path().string();
  // `normals` too: its bands estimated by both ranks, written by rank 0.
  std::string one_out, two_out;
  const std::string normals = cli + " normals '" + field.string() + "' --out ";
  ASSERT_EQ(run(normals + "'" + (dir / "n1.exr").string() + "'", &one_out), 0);
  ASSERT_EQ(run(mpirun_two() + normals + "'" + (dir / "n2.exr").string() + "'", &two_out), 0);
  EXPECT_NE(two_out.find("split over 2 MPI ranks"), std::string::npos) << two_out;
  EXPECT_TRUE(bytes_but_time(dir / "n1.exr") == bytes_but_time(dir / "n2.exr"));
  EXPECT_TRUE(bytes_but_time(dir / "n1.normal.png") == bytes_but_time(dir / "n2.normal.png"));
  EXPECT_FALSE(fs::exists(dir / "n2.exr.partial"));
  for (const std::string materials : {"basis", "per-pixel"}) {
    const std::string fit = " fit '" + field.string() + "' --materials " + materials + " --out ";
    std::string one_out, two_out;
    ASSERT_EQ(run(cli + fit + "'" + (dir / "one.exr").string() + "'", &one_out), 0);
    ASSERT_EQ(run(mpirun_two() + cli + fit + "'" + (dir / "two.exr").string() + "'", &two_out), 0);
    EXPECT_NE(two_out.find("split over 2 MPI ranks"), std::string::npos) << two_out;
    const std::string one = bytes_but_time(dir / "one.exr");
    EXPECT_GT(one.size(), 48u * 40 * 4);
    EXPECT_TRUE(one == bytes_but_time(dir / "two.exr")) << materials;
    EXPECT_FALSE(fs::exists(dir / "two.exr.partial")) << "the checkpoints are removed";
  }
}

// fit --time: the bands of every step split over the ranks, the curves learnt on rank 0 from
// every band's sample and sent to the others: the bytes of one process's fit.
TEST(MpiFit, TimeSeriesTwoRanksWriteTheBytesOfOneProcess) {
  if (std::string(LIGHTSTAGE_MPIEXEC).empty()) GTEST_SKIP() << "built without MPI";
  const testing::TempDir dir;
  Stage stage = stage_with_directions(fibonacci_dome_directions(40, -11.5));
  stage.camera.width = 24;
  stage.camera.height = 20;
  const sim::Scene scene = sim::time_varying_scene();
  fs::create_directories(dir / "fields");
  int i = 0;
  for (const double t : {0.0, 120.0, 300.0, 500.0, 800.0, 1200.0}) {
    capture::write_field(dir / "fields" / ("field_t00" + std::to_string(i) + ".exr"),
                         relight::time_testing::field_at(stage, scene, t, {}, 7 + i));
    ++i;
  }
  const std::string cli = testing::cli_path().string();
  const std::string fit = " fit --time '" + (dir / "fields").string() + "' --out ";
  std::string one_out, two_out;
  ASSERT_EQ(run(cli + fit + "'" + (dir / "one.exr").string() + "'", &one_out), 0);
  ASSERT_EQ(run(mpirun_two() + cli + fit + "'" + (dir / "two.exr").string() + "'", &two_out), 0);
  EXPECT_NE(two_out.find("split over 2 MPI ranks"), std::string::npos) << two_out;
  EXPECT_NE(one_out.find(" curve "), std::string::npos) << one_out;
  const std::string one = bytes_but_time(dir / "one.exr");
  EXPECT_GT(one.size(), 24u * 20 * 4);
  EXPECT_TRUE(one == bytes_but_time(dir / "two.exr"));
  EXPECT_FALSE(fs::exists(dir / "two.exr.partial")) << "the checkpoints are removed";
  // Rendered at a time, each rank its bands of the maps: the images and the extrapolated count.
  const std::string at = cli + " relight --temporal '" + (dir / "one.exr").string() +
                         "' --time 1500 --light 0.3 0.2 0.93 --out ";
  ASSERT_EQ(run(at + "'" + (dir / "t1").string() + "'", &one_out), 0);
  ASSERT_EQ(run(mpirun_two() + at + "'" + (dir / "t2").string() + "'", &two_out), 0);
  EXPECT_TRUE(bytes_but_time(dir / "t1" / "light_t1500s.exr") ==
              bytes_but_time(dir / "t2" / "light_t1500s.exr"));
  const auto extrapolated = [](const std::string& out) {
    return out.substr(out.find("EXTRAPOLATED"),
                      out.find("varying pixels") - out.find("EXTRAPOLATED"));
  };
  EXPECT_EQ(extrapolated(one_out), extrapolated(two_out)) << one_out << two_out;
}

// build: each rank merges its share of the LEDs into the spill beside the field (with their
// records), rank 0 counts the others' as a resumed build does and writes the field: the bytes of
// one process's build, in memory or in bands.
TEST(MpiFit, BuildTwoRanksWriteTheBytesOfOneProcess) {
  if (std::string(LIGHTSTAGE_MPIEXEC).empty()) GTEST_SKIP() << "built without MPI";
  sim::register_backend(backend_registry());
  const testing::TempDir dir;
  Stage stage = default_stage();
  stage.camera.width = 24;
  stage.camera.height = 20;
  write_file_atomic(dir / "stage.json", stage_to_json(stage));
  jobs::CaptureOptions capture;
  capture.stage_file = dir / "stage.json";
  capture.session_dir = dir / "session";
  (void)jobs::capture(capture);
  const std::string build =
      testing::cli_path().string() + " build '" + (dir / "session").string() + "' --out ";
  for (const std::string memory : {"", " --memory 200000"}) {
    std::string one_out, two_out;
    ASSERT_EQ(run(build + "'" + (dir / "one.exr").string() + "'" + memory, &one_out), 0);
    ASSERT_EQ(run(mpirun_two() + build + "'" + (dir / "two.exr").string() + "'" + memory, &two_out),
              0);
    EXPECT_NE(two_out.find("LEDs merged by 2 MPI ranks"), std::string::npos) << two_out;
    EXPECT_EQ(two_out.find("taken from an interrupted run"), std::string::npos) << two_out;
    const std::string one = bytes_but_time(dir / "one.exr");
    EXPECT_GT(one.size(), 24u * 20 * 4);
    EXPECT_TRUE(one == bytes_but_time(dir / "two.exr")) << memory;
    EXPECT_FALSE(fs::exists(dir / "two.exr.partial")) << "the checkpoint is removed";
  }
}

// compress: each rank fits (or, for PCA, finds the Gram matrices of, then projects) its share of
// the bands into records and a spill beside the output, rank 0 finds the basis, quantises and
// writes the file: the bytes of one process, for the RTI formats and PCA (global, tiled, and with
// the rank chosen on held-out LEDs: rank 0 reads the field for that pass).
TEST(MpiFit, CompressTwoRanksWriteTheBytesOfOneProcess) {
  if (std::string(LIGHTSTAGE_MPIEXEC).empty()) GTEST_SKIP() << "built without MPI";
  const testing::TempDir dir;
  const fs::path field = write_test_field(dir.path());
  const std::string compress = testing::cli_path().string() + " compress '" + field.string() + "'";
  for (const auto& [format, ext] :
       {std::pair{"hsh3", ".rti"}, std::pair{"ptm-lrgb", ".ptm"}, std::pair{"pca", ".pca"},
        std::pair{"pca --tile 8", ".tpca"}, std::pair{"pca --rank held-out", ".hpca"}}) {
    const std::string args = std::string(" --format ") + format + " --out ";
    std::string one_out, two_out;
    ASSERT_EQ(
        run(compress + args + "'" + (dir / ("one" + std::string(ext))).string() + "'", &one_out),
        0);
    ASSERT_EQ(run(mpirun_two() + compress + args + "'" +
                      (dir / ("two" + std::string(ext))).string() + "'",
                  &two_out),
              0);
    EXPECT_NE(two_out.find("split over 2 MPI ranks"), std::string::npos) << two_out;
    const std::string one = bytes_but_time(dir / ("one" + std::string(ext)));
    EXPECT_GT(one.size(), 48u * 40);
    EXPECT_TRUE(one == bytes_but_time(dir / ("two" + std::string(ext)))) << format;
    EXPECT_FALSE(fs::exists(dir / ("two" + std::string(ext) + ".partial")))
        << "the checkpoint is removed";
  }
}

// import: each rank reads its share of a real RTI set's images into the spill beside the field
// (a record each), rank 0 takes the others' and writes the field: the bytes of one process.
TEST(MpiFit, ImportTwoRanksWriteTheBytesOfOneProcess) {
  if (std::string(LIGHTSTAGE_MPIEXEC).empty()) GTEST_SKIP() << "built without MPI";
  const fs::path lp = testing::shared_data_dir() / "rti/loewenkopf_klein/dirs.lp";
  if (!fs::exists(lp)) GTEST_SKIP() << lp << " is not here";
  const testing::TempDir dir;
  const std::string import = testing::cli_path().string() + " import '" + lp.string() +
                             "' --max-size 48 --memory 20000 --out ";
  std::string one_out, two_out;
  ASSERT_EQ(run(import + "'" + (dir / "one.exr").string() + "'", &one_out), 0);
  ASSERT_EQ(run(mpirun_two() + import + "'" + (dir / "two.exr").string() + "'", &two_out), 0);
  EXPECT_NE(two_out.find("read by 2 MPI ranks"), std::string::npos) << two_out;
  EXPECT_TRUE(bytes_but_time(dir / "one.exr") == bytes_but_time(dir / "two.exr"));
  EXPECT_TRUE(bytes_but_time(dir / "one.preview.png") == bytes_but_time(dir / "two.preview.png"));
  EXPECT_FALSE(fs::exists(dir / "two.exr.partial"));
}

// Any other command would run once per rank, each writing the same outputs: refused, on every rank.
TEST(MpiFit, OtherCommandsAreRefusedUnderMpi) {
  if (std::string(LIGHTSTAGE_MPIEXEC).empty()) GTEST_SKIP() << "built without MPI";
  const testing::TempDir dir;
  const fs::path field = write_test_field(dir.path());
  std::string out;
  EXPECT_NE(testing::run_command(mpirun_two() + testing::cli_path().string() + " stage --write '" +
                                     (dir / "stage.json").string() + "'",
                                 &out),
            0);
  EXPECT_NE(out.find("split their work over ranks"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir / "stage.json"));
}

// relight: each rank relights its bands of the field (or renders its bands of the fitted maps)
// under every map, rank 0 gathers the rows and writes the images: the bytes of one process.
TEST(MpiFit, RelightTwoRanksWriteTheBytesOfOneProcess) {
  if (std::string(LIGHTSTAGE_MPIEXEC).empty()) GTEST_SKIP() << "built without MPI";
  const testing::TempDir dir;
  const fs::path field = write_test_field(dir.path());
  Image sky(64, 32, 3, 0.2f);
  for (int y = 0; y < 16; ++y) {
    for (int x = 0; x < 64; ++x) sky.at(x, y, 0) = 1.0f + 0.05f * x;
  }
  write_exr(dir / "sky.exr", sky);
  const std::string relight = testing::cli_path().string() + " relight '" + field.string() +
                              "' --env '" + (dir / "sky.exr").string() + "' --rotate 0 90 --out ";
  std::string one_out, two_out;
  ASSERT_EQ(run(relight + "'" + (dir / "one").string() + "'", &one_out), 0);
  ASSERT_EQ(run(mpirun_two() + relight + "'" + (dir / "two").string() + "'", &two_out), 0);
  EXPECT_NE(two_out.find("split over 2 MPI ranks"), std::string::npos) << two_out;
  for (const std::string name : {"sky_rot000.exr", "sky_rot090.exr"}) {
    EXPECT_TRUE(bytes_but_time(dir / "one" / name) == bytes_but_time(dir / "two" / name)) << name;
  }
  EXPECT_FALSE(fs::exists(dir / "two.partial"));
  // The fitted models too (the field fills their flagged pixels), each rank its bands of maps.
  ASSERT_EQ(run(testing::cli_path().string() + " fit '" + field.string() + "' --out '" +
                    (dir / "maps.exr").string() + "'",
                &one_out),
            0);
  const std::string models = testing::cli_path().string() + " relight '" + field.string() +
                             "' --models '" + (dir / "maps.exr").string() + "' --env '" +
                             (dir / "sky.exr").string() + "' --light 0.3 0.2 0.93 --out ";
  ASSERT_EQ(run(models + "'" + (dir / "m1").string() + "'", &one_out), 0);
  ASSERT_EQ(run(mpirun_two() + models + "'" + (dir / "m2").string() + "'", &two_out), 0);
  for (const std::string name : {"sky.exr", "light.exr"}) {
    EXPECT_TRUE(bytes_but_time(dir / "m1" / name) == bytes_but_time(dir / "m2" / name)) << name;
  }
  EXPECT_FALSE(fs::exists(dir / "m2.partial"));
}

}  // namespace
}  // namespace ls
