// What the CLI refuses as a new user meets it: each refusal names the file and the field (or the
// option); what it accepts is said with a warning; one process writes an output at a time.
#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <iterator>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "lightstage/image.h"
#include "lightstage/output_lock.h"
#include "lightstage/session.h"
#include "tests/app/cli_process.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

namespace fs = std::filesystem;
using testing::cli_path;
using testing::run_command;

// A captured session (s) and its field (f.exr), shared by the tests.
class Refusals : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    tmp_ = std::make_unique<testing::TempDir>();
    const fs::path stage = testing::WriteSmallStage(tmp_->path());
    std::string out;
    ASSERT_EQ(Run("capture --quiet --stage " + stage.string() + " --out " + Path("s"), &out), 0)
        << out;
    ASSERT_EQ(Run("build --quiet " + Path("s") + " --out " + Path("f.exr"), &out), 0) << out;
  }
  static void TearDownTestSuite() { tmp_.reset(); }

  static std::string Path(const std::string& name) { return (*tmp_ / name).string(); }
  static int Run(const std::string& args, std::string* out) {
    return run_command(cli_path().string() + " " + args, out);
  }
  // Runs args; expects `code` and every fragment in the output.
  static void Expect(const std::string& args, int code,
                     std::initializer_list<std::string> fragments) {
    std::string out;
    EXPECT_EQ(Run(args, &out), code) << args << "\n" << out;
    for (const std::string& f : fragments) {
      EXPECT_NE(out.find(f), std::string::npos) << "'" << f << "' not in: " << out;
    }
  }

  static std::unique_ptr<testing::TempDir> tmp_;
};

std::unique_ptr<testing::TempDir> Refusals::tmp_;

TEST_F(Refusals, StageNamesAMissingSideCarFileWithItsField) {
  std::ofstream(*tmp_ / "flat.json") << R"({"layout": {"type": "fibonacci", "count": 10},
    "calibration": {"flat_field": "gone.exr"}})";
  Expect("stage " + Path("flat.json"), 2, {"flat.json: calibration.flat_field", "not found"});
  std::ofstream(*tmp_ / "table.json") << R"({"layout": {"type": "fibonacci", "count": 10},
    "camera": {"response": {"type": "table", "file": "gone.txt"}}})";
  Expect("stage " + Path("table.json"), 2, {"table.json: camera.response.file", "not found"});
}

TEST_F(Refusals, OptionsOutsideTheirUseAreRefusedNamingThem) {
  // --encoding is for RTI files; a PCA holds linear values.
  Expect("compress " + Path("f.exr") + " --format pca --encoding linear --out " + Path("e.lspca"),
         2, {"--encoding linear", "RTI files"});
  EXPECT_FALSE(fs::exists(Path("e.lspca")));
  // A rotation that cannot be named in whole degrees.
  Expect("relight --quiet " + Path("f.exr") + " --env " +
             (testing::source_dir() / "data" / "envmaps" / "sky_sun.exr").string() +
             " --rotate 1e300 --out " + Path("rot"),
         1, {"--rotate", "1e+300"});
  EXPECT_FALSE(fs::exists(Path("rot")));
  // The same bound on every command that turns a map; an exposure beyond any scene's range.
  const std::string map = (testing::source_dir() / "data" / "envmaps" / "sky_sun.exr").string();
  ASSERT_EQ(
      Run("compress --quiet " + Path("f.exr") + " --format ptm --out " + Path("rot.ptm"), nullptr),
      0);
  Expect("render " + Path("rot.ptm") + " --env " + map + " --rotate 1e300 --out " + Path("rot.exr"),
         1, {"--rotate", "[-36000, 36000]", "1e+300"});
  Expect("play " + Path("s") + " --field " + Path("f.exr") + " --env " + map +
             " --rotate 1e300 --out " + Path("rot_play"),
         1, {"--rotate", "[-36000, 36000]", "1e+300"});
  Expect("relight --quiet " + Path("f.exr") + " --env " + map + " --exposure 1e300 --out " +
             Path("exposed"),
         1, {"--exposure", "[-64, 64]", "1e+300"});
  for (const char* made : {"rot.exr", "rot_play", "exposed"}) {
    EXPECT_FALSE(fs::exists(Path(made))) << made;
  }
  // A negative group size.
  Expect("play " + Path("s") + " --env " +
             (testing::source_dir() / "data" / "envmaps" / "sky_sun.exr").string() +
             " --audit-groups -3 --out " + Path("p"),
         1, {"--audit-groups: Value -3 not in range 0"});
}

// Options a command would ignore, or values it would wrap, are refused naming the option.
TEST_F(Refusals, OptionsThatWouldBeIgnoredOrWrappedAreRefused) {
  const std::string map = (testing::source_dir() / "data" / "envmaps" / "sky_sun.exr").string();
  Expect("envmaps --width 63 --out " + Path("odd_maps"), 1, {"--width", "even"});
  EXPECT_FALSE(fs::exists(Path("odd_maps")));
  Expect("relight --quiet " + Path("f.exr") + " --env " + map + " --coverage-deg 500 --out " +
             Path("cov"),
         1, {"--coverage-deg", "0..180"});
  Expect("relight --quiet " + Path("f.exr") + " --env " + map + " --directions 16 --out " +
             Path("dirs"),
         1, {"--directions", "--models"});
  Expect("relight --quiet " + Path("f.exr") + " --env " + map + " --source-pixels 100 --out " +
             Path("tiny"),
         1, {"--source-pixels", "at least 4096"});
  Expect("compress " + Path("f.exr") + " --format ptm --rank 5 --out " + Path("r.ptm"), 2,
         {"--rank 5", "--format pca only"});
  Expect("compress " + Path("f.exr") + " --format hsh2 --tile 16 --out " + Path("t.rti"), 2,
         {"--tile", "--format pca only"});
  Expect("compress " + Path("f.exr") + " --format pca --out " + Path("pca.ptm"), 2,
         {"pca.ptm", "writes a .lspca file, not a .ptm"});
  Expect("compress " + Path("f.exr") + " --format ptm --out " + Path("ptm.pca"), 2,
         {"ptm.pca", "writes a .ptm file, not a .pca"});
  Expect("compress " + Path("f.exr") + " --out " + Path("pca.exr"), 2,
         {"pca.exr", "writes a .lspca file, not a .exr"});
  Expect("export openlime " + Path("f.exr") + " --image png --quality 50 --out " + Path("q50"), 2,
         {"--quality", "jpg only"});
  ASSERT_EQ(
      Run("compress --quiet " + Path("f.exr") + " --format ptm --out " + Path("l.ptm"), nullptr),
      0);
  Expect("render " + Path("l.ptm") + " --light 0 0 1 --rotate 45 --out " + Path("l.exr"), 1,
         {"--rotate", "--light"});
  Expect("capture --seed -1 --out " + Path("seed"), 1, {"--seed", "0..18446744073709551615"});
  Expect("capture --seed 99999999999999999999999 --out " + Path("seed"), 1, {"--seed"});
  Expect("play " + Path("s") + " --field " + Path("f.exr") + " --env " + map +
             " --gain-tolerance -1 --out " + Path("gain"),
         1, {"--gain-tolerance"});
  Expect("play " + Path("s") + " --field " + Path("f.exr") + " --env " + map +
             " --rotate nan --out " + Path("nan"),
         1, {"--rotate", "finite"});
  for (const char* made : {"cov", "dirs", "r.ptm", "t.rti", "pca.ptm", "ptm.pca", "pca.exr", "q50",
                           "l.exr", "seed", "gain", "nan"}) {
    EXPECT_FALSE(fs::exists(Path(made))) << made;
  }
}

// A capture refused before its first frame leaves no session behind; a capture into a session
// another capture is writing names that process.
TEST_F(Refusals, ACaptureRefusedBeforeItsFirstFrameLeavesNoSession) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(12, -10));
  stage.camera.width = stage.camera.height = 16;
  stage.camera.response.kind = CameraResponse::Kind::kTable;
  stage.camera.response.table_file = *tmp_ / "table.csv";
  write_file_atomic(*tmp_ / "tabled.json", stage_to_json(stage));
  std::ofstream(*tmp_ / "table.csv") << "not a number\n";
  Expect("capture --quiet --stage " + Path("tabled.json") + " --out " + Path("tabled"), 2,
         {"table.csv"});
  EXPECT_FALSE(fs::exists(Path("tabled")));
  const SessionWriterLock capturing(*tmp_ / "s");
  Expect("capture --quiet --out " + Path("s"), 2,
         {Path("s") + ": a capture (process " + std::to_string(getpid()) + ")"});
}

// An OpenLIME folder whose info.json lacks what it must hold is refused naming the field.
TEST_F(Refusals, AnOpenLimeFolderWithoutMaterialsIsRefusedNamingTheField) {
  ASSERT_EQ(Run("export openlime --quiet " + Path("f.exr") + " --out " + Path("nomat"), nullptr),
            0);
  std::string info;
  {
    std::ifstream in(*tmp_ / "nomat" / "info.json");
    info.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const size_t at = info.find("\"materials\"");
  ASSERT_NE(at, std::string::npos);
  const size_t open = info.find('[', at), close = info.find(']', info.find('}', at));
  info.replace(open, close - open + 1, "[]");
  std::ofstream(*tmp_ / "nomat" / "info.json") << info;
  Expect("render " + Path("nomat") + " --light 0 0 1 --out " + Path("nomat.exr"), 2,
         {"info.json: materials: expected an array of at least 1 entries"});
}

// An .lp set's lines, with 8-bit images of a gradient: "name x y z" per light.
void WriteLp(const fs::path& dir, const std::vector<std::string>& lines) {
  fs::create_directories(dir);
  std::string lp = std::to_string(lines.size()) + "\n";
  for (const std::string& line : lines) {
    const std::string image = line.substr(0, line.find(' '));
    std::vector<uint8_t> rgb(16 * 16 * 3);
    for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = uint8_t(40 + i % 150);
    write_rgb8(dir / image, 16, 16, rgb.data());
    lp += line + "\n";
  }
  std::ofstream(dir / "set.lp") << lp;
}

// What an input says twice, or a step no plan made, is refused naming its line or field.
TEST_F(Refusals, InputsThatSayAThingTwiceOrAskForWhatIsNotThereAreRefused) {
  const std::vector<std::string> lights = {"a.png 0.5 0 0.866", "b.png -0.5 0 0.866",
                                           "c.png 0 0.5 0.866", "d.png 0 -0.5 0.866"};
  WriteLp(*tmp_ / "lp_twice", {lights[0], lights[1], lights[2], "a.png 0 -0.5 0.866"});
  Expect("import --quiet " + Path("lp_twice/set.lp") + " --out " + Path("twice.exr"), 2,
         {"set.lp:5: image: a.png is listed already, at " + Path("lp_twice/set.lp") + ":2"});
  WriteLp(*tmp_ / "lp_same", {lights[0], lights[1], lights[2], "d.png 1 0 1.732"});
  Expect("import --quiet " + Path("lp_same/set.lp") + " --out " + Path("same.exr"), 2,
         {"set.lp:5: light direction", "is the direction of the light at"});
  WriteLp(*tmp_ / "lp", lights);
  Expect("import --quiet " + Path("lp/set.lp") + " --interval 60 --out " + Path("one"), 2,
         {"--interval", "two sets or more"});
  ASSERT_EQ(Run("import --quiet " + Path("lp/set.lp") + " --out " + Path("lp.exr"), nullptr), 0);
  // Another capture's field is not this session's to play.
  Expect("play " + Path("s") + " --field " + Path("lp.exr") + " --env " +
             (testing::source_dir() / "data" / "envmaps" / "sky_sun.exr").string() + " --out " +
             Path("other"),
         2, {Path("lp.exr") + ": --field: LED 0", "give the field built from " + Path("s")});
  // No reference LED was shot: there is no drift to divide out.
  Expect("build --quiet --correct-drift " + Path("s") + " --out " + Path("drift.exr"), 2,
         {"plan.reference_led", "--correct-drift"});
  for (const char* made : {"twice.exr", "same.exr", "one", "other", "drift.exr"}) {
    EXPECT_FALSE(fs::exists(Path(made))) << made;
  }
}

// An --out that is a file where a folder is written is bad input (exit 2) naming it, not a
// storage fault; the file stays as it was.
TEST_F(Refusals, AnOutputFolderThatIsAFileIsRefusedNamingIt) {
  const std::string map = (testing::source_dir() / "data" / "envmaps" / "sky_sun.exr").string();
  std::ofstream(*tmp_ / "afile") << "junk";
  WriteLp(*tmp_ / "lp_file",
          {"a.png 0.5 0 0.866", "b.png -0.5 0 0.866", "c.png 0 0.5 0.866", "d.png 0 -0.5 0.866"});
  const std::string lp = Path("lp_file/set.lp");
  for (const std::string& command : std::vector<std::string>{
           "relight --quiet " + Path("f.exr") + " --env " + map + " --out ",
           "export openlime --quiet " + Path("f.exr") + " --out ",
           "play " + Path("s") + " --field " + Path("f.exr") + " --env " + map + " --out ",
           "envmaps --width 32 --out ",
           "import --quiet " + lp + " " + lp + " --interval 5 --out ",
           "capture --quiet --out ",
       }) {
    Expect(command + Path("afile"), 2, {Path("afile") + ": expected a folder"});
    Expect(command + Path("afile/below"), 2, {Path("afile") + ": expected a folder"});
  }
  std::ifstream in(*tmp_ / "afile");
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()),
            "junk");
}

// An output that is one of the inputs (or a link to it) is refused naming both, the input intact.
TEST_F(Refusals, AnOutputThatIsAnInputIsRefusedNamingBoth) {
  fs::copy_file(*tmp_ / "f.exr", *tmp_ / "in.exr", fs::copy_options::overwrite_existing);
  fs::create_symlink(*tmp_ / "in.exr", *tmp_ / "link.exr");
  const std::string in = Path("in.exr");
  const std::string bytes = testing::Slurp(*tmp_ / "in.exr");
  Expect("fit --quiet " + in + " --out " + in, 2, {in + ": --out is the input " + in});
  Expect("fit --quiet " + in + " --out " + Path("link.exr"), 2, {"--out is the input " + in});
  Expect("normals --quiet " + in + " --out " + in, 2, {in + ": --out is the input " + in});
  Expect("compress --quiet " + in + " --out " + in, 2, {in});
  WriteLp(*tmp_ / "lp_over",
          {"a.png 0.5 0 0.866", "b.png -0.5 0 0.866", "c.png 0 0.5 0.866", "d.png 0 -0.5 0.866"});
  const std::string image = Path("lp_over/b.png");
  const std::string png = testing::Slurp(image);
  Expect("import --quiet " + Path("lp_over/set.lp") + " --out " + image, 2,
         {image + ": --out is the input " + image});
  EXPECT_EQ(testing::Slurp(*tmp_ / "in.exr"), bytes) << "the input was overwritten";
  EXPECT_EQ(testing::Slurp(image), png) << "the image was overwritten";
}

// A light behind the object (z <= 0) is refused for an RTI basis (fitted on the hemisphere toward
// the camera); a PCA lit from beyond its captured lights (from below the dome) is rendered with
// a warning that says so.
TEST_F(Refusals, ALightACompactFileCannotShowIsRefusedOrWarned) {
  ASSERT_EQ(Run("compress --quiet " + Path("f.exr") + " --format ptm --out " + Path("below.ptm"),
                nullptr),
            0);
  ASSERT_EQ(Run("compress --quiet " + Path("f.exr") + " --out " + Path("below.lspca"), nullptr), 0);
  Expect("render " + Path("below.ptm") + " --light 0 0 -1 --out " + Path("below_ptm.exr"), 2,
         {Path("below.ptm") + ": --light", "z > 0"});
  EXPECT_FALSE(fs::exists(Path("below_ptm.exr")));
  Expect(
      "render " + Path("below.lspca") + " --light 0 -1 0 --out " + Path("below_pca.exr"), 0,
      {"warning: " + Path("below.lspca") + ": --light: extrapolated beyond the captured lights"});
  std::string out;
  ASSERT_EQ(
      Run("render " + Path("below.lspca") + " --light 0 1 0.3 --out " + Path("above.exr"), &out),
      0);
  EXPECT_EQ(out.find("extrapolated"), std::string::npos) << out;
}

// The time steps of a time-lapse are one kind of set lit from the same directions: a step lit
// otherwise, or a DiLiGenT folder (linear) among .lp sets (sRGB), is refused naming the step.
TEST_F(Refusals, ATimeLapseWhoseStepsAreLitUnlikeIsRefusedNamingTheStep) {
  const std::vector<std::string> lights = {"a.png 0.5 0 0.866", "b.png -0.5 0 0.866",
                                           "c.png 0 0.5 0.866", "d.png 0 -0.5 0.866"};
  WriteLp(*tmp_ / "tl" / "t0", lights);
  WriteLp(*tmp_ / "tl" / "t1", {lights[0], lights[1], lights[2], "d.png 0 -0.6 0.8"});
  Expect("import --quiet " + Path("tl/t0/set.lp") + " " + Path("tl/t1/set.lp") +
             " --interval 5 --out " + Path("tl_out"),
         2, {Path("tl/t1/set.lp") + ": time step 1: light 4 is", "from light 4 of"});
  WriteLp(*tmp_ / "dil", lights);
  std::ofstream(*tmp_ / "dil" / "filenames.txt") << "a.png\nb.png\nc.png\nd.png\n";
  std::ofstream(*tmp_ / "dil" / "light_directions.txt")
      << "0.5 0 0.866\n-0.5 0 0.866\n0 0.5 0.866\n0 -0.5 0.866\n";
  fs::remove(*tmp_ / "dil" / "set.lp");
  Expect("import --quiet " + Path("tl/t0/set.lp") + " " + Path("dil") + " --interval 5 --out " +
             Path("tl_out"),
         2, {Path("dil") + ": time step 1: expected RTI .lp file", "got DiLiGenT folder"});
  EXPECT_FALSE(fs::exists(Path("tl_out")));
}

// A refusal says what is wrong, not a cause that only looks like it.
TEST_F(Refusals, ARefusalNamesWhatIsWrongNotAnotherCause) {
  fs::create_directories(*tmp_ / "a_folder");
  Expect("stage " + Path("a_folder"), 2, {Path("a_folder") + ": a folder, not a stage file"});
  std::ofstream(*tmp_ / "flat_folder.json") << R"({"layout": {"type": "fibonacci", "count": 10},
    "calibration": {"flat_field": "a_folder"}})";
  Expect("stage " + Path("flat_folder.json"), 2,
         {"calibration.flat_field", "a_folder is a folder, not a file"});
  WriteLp(*tmp_ / "two_lp", {"a.png 0.5 0 0.866", "b.png -0.5 0 0.866", "c.png 0 0.5 0.866"});
  fs::copy_file(*tmp_ / "two_lp" / "set.lp", *tmp_ / "two_lp" / "copy.lp");
  Expect("import --quiet " + Path("two_lp") + " --out " + Path("two_lp.exr"), 2,
         {"expected exactly one .lp file in the folder, found 2"});
  std::string out;
  EXPECT_EQ(Run("import --quiet " + Path("two_lp/set.lp") + " " + Path("two_lp/copy.lp") +
                    " --interval 0 --out " + Path("iv0"),
                &out),
            1);
  EXPECT_NE(out.find("--interval: expected a positive number, got 0"), std::string::npos) << out;
  EXPECT_LT(out.size(), 200u) << out;
}

TEST_F(Refusals, WhatIsAssumedIsSaid) {
  Expect("compress " + Path("f.exr") + " --format pca --rank 100000 --out " + Path("r.lspca"), 0,
         {"warning: --rank 100000: more than this field allows", "used"});
}

// --quiet means the same on every command: no progress output.
TEST_F(Refusals, QuietIsTakenByEveryCommandThatWrites) {
  Expect("compress --quiet " + Path("f.exr") + " --format pca --out " + Path("q.lspca"), 0, {});
  Expect("export openlime --quiet " + Path("f.exr") + " --out " + Path("q_ol"), 0, {});
  std::string out;
  ASSERT_EQ(Run("export openlime " + Path("f.exr") + " --out " + Path("loud_ol"), &out), 0);
  std::string quiet;
  ASSERT_EQ(Run("export openlime --quiet " + Path("f.exr") + " --out " + Path("quiet_ol"), &quiet),
            0);
  EXPECT_LT(quiet.size(), out.size()) << "--quiet printed as much as without it: " << quiet;
}

// --quiet is taken by every command and subcommand, those that show no progress too.
TEST_F(Refusals, QuietIsTakenByEveryCommand) {
  // Every command and subcommand, separated by commas.
  std::istringstream commands(
      "capture,build,relight,fit,normals,view,import,compress,export openlime,render,play,"
      "calibrate directions,calibrate intensities,calibrate camera,stage,envmaps,devices,check,"
      "demo,bench leds,bench sun,bench exposures,bench fit,bench fit-sweeps,bench temporal,"
      "bench compact,bench rti,bench charts,bench scale");
  for (std::string command; std::getline(commands, command, ',');) {
    Expect(command + " --help", 0, {"--quiet"});
  }
  ASSERT_EQ(Run("compress --quiet " + Path("f.exr") + " --format ptm --out " + Path("quiet.ptm"),
                nullptr),
            0);
  Expect("stage --quiet", 0, {"LEDs"});
  Expect("stage --quiet --write " + Path("quiet_stage.json"), 0, {});
  Expect("envmaps --quiet --width 32 --out " + Path("quiet_maps"), 0, {});
  Expect("render --quiet " + Path("quiet.ptm") + " --light 0 0 1 --out " + Path("quiet.exr"), 0,
         {});
  Expect("devices --quiet --no-cameras", 0, {});
  Expect("bench charts --quiet --dir " + Path("quiet_maps"), 2, {"no bench CSV file"});
}

// A capture whose frames cannot fit in memory is refused before a device opens or a file is
// written, naming the stage's fields; the address-space limit stands for a smaller machine.
TEST_F(Refusals, ACaptureLargerThanMemoryIsRefusedBeforeItStarts) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(30, -10));
  stage.camera.width = stage.camera.height = 16384;
  write_file_atomic(*tmp_ / "huge.json", stage_to_json(stage));
  std::string out;
  EXPECT_EQ(run_command("ulimit -v 4000000; " + cli_path().string() + " capture --quiet --stage " +
                            Path("huge.json") + " --out " + Path("huge"),
                        &out),
            2)
      << out;
  EXPECT_NE(out.find(Path("huge.json") + ": camera.width, camera.height"), std::string::npos)
      << out;
  EXPECT_NE(out.find("of memory are available"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(Path("huge")));
}

// One process writes an output at a time: a second is refused naming the first; a build does not
// read a session that a capture is writing.
TEST_F(Refusals, ASecondWriterIsRefusedNamingTheFirst) {
  const std::string me = "(process " + std::to_string(getpid()) + ")";
  {
    const OutputLock held(Path("busy.exr"));
    Expect("build --quiet " + Path("s") + " --out " + Path("busy.exr"), 2,
           {Path("busy.exr") + ": another lightstage run is writing it " + me});
    Expect("fit --quiet " + Path("f.exr") + " --out " + Path("busy.exr"), 2, {me});
    EXPECT_FALSE(fs::exists(Path("busy.exr")));
  }
  {
    // The commands that write a stage file, maps or a folder of results lock them too.
    const OutputLock stage_file(Path("busy.json"));
    const OutputLock folder(Path("busy"));
    Expect("stage --write " + Path("busy.json"), 2, {Path("busy.json") + ": another", me});
    Expect("envmaps --width 32 --out " + Path("busy"), 2, {Path("busy") + ": another", me});
    Expect("demo --quiet --no-truth --out " + Path("busy"), 2, {Path("busy") + ": another", me});
    Expect("calibrate camera --images " + Path("s") + " --out " + Path("busy.json"), 2, {me});
    EXPECT_FALSE(fs::exists(Path("busy.json")));
    EXPECT_FALSE(fs::exists(Path("busy")));
  }
  Expect("build --quiet " + Path("s") + " --out " + Path("busy.exr"), 0, {});
  EXPECT_FALSE(fs::exists(Path("busy.exr.lock"))) << "the lock outlived the run";
  {
    const SessionWriterLock capturing(*tmp_ / "s");
    Expect("build --quiet " + Path("s") + " --out " + Path("during.exr"), 2,
           {Path("s") + ": a capture " + me + " is writing this session"});
    EXPECT_FALSE(fs::exists(Path("during.exr.partial")));
  }
}

}  // namespace
}  // namespace ls
