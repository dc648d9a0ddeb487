// The lightstage executable as a user drives it: kill -9 and resume, Ctrl-C, bad input, --help.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "lightstage/session.h"
#include "lightstage/stage.h"
#include "tests/app/cli_process.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

namespace fs = std::filesystem;
using testing::cli_path;
using testing::CountLines;
using testing::run_command;
using testing::Slurp;
using testing::Spawn;
using testing::WaitForFrames;
using testing::WriteSmallStage;

TEST(Cli, KilledCaptureResumesToExactlyTheFramesOfAnUninterruptedOne) {
  testing::TempDir tmp;
  const fs::path stage = WriteSmallStage(tmp.path());
  const std::string cli = cli_path().string();
  std::string out;
  ASSERT_EQ(run_command(cli + " capture --quiet --stage " + stage.string() + " --out " +
                            (tmp / "whole").string(),
                        &out),
            0)
      << out;

  const pid_t pid = Spawn(
      {cli, "capture", "--quiet", "--stage", stage.string(), "--out", (tmp / "killed").string()});
  WaitForFrames(tmp / "killed", 40, pid);
  kill(pid, SIGKILL);
  int status;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status)) << "capture finished before it could be killed";
  const int before = CountLines(tmp / "killed" / "frames.jsonl");
  EXPECT_GE(before, 40);

  // One writer at a time: while another process holds the session (here, this test), a resume
  // is refused naming it, and captures nothing.
  {
    const SessionWriterLock held(tmp / "killed");
    EXPECT_EQ(run_command(cli + " capture --quiet --resume " + (tmp / "killed").string(), &out), 2)
        << out;
    EXPECT_NE(out.find("another capture is writing this session (process " +
                       std::to_string(getpid()) + ")"),
              std::string::npos)
        << out;
    EXPECT_EQ(CountLines(tmp / "killed" / "frames.jsonl"), before);
  }
  // The killed capture's lock died with it (its capture.lock file is left, and stale): the resume
  // takes it.
  ASSERT_EQ(run_command(cli + " capture --quiet --resume " + (tmp / "killed").string(), &out), 0)
      << out;
  // Same frames, bit for bit, and nothing else.
  std::vector<std::string> whole, resumed;
  for (const auto& e : fs::directory_iterator(tmp / "whole" / "frames"))
    whole.push_back(e.path().filename());
  for (const auto& e : fs::directory_iterator(tmp / "killed" / "frames"))
    resumed.push_back(e.path().filename());
  std::sort(whole.begin(), whole.end());
  std::sort(resumed.begin(), resumed.end());
  ASSERT_EQ(whole, resumed);
  ASSERT_EQ(whole.size(), size_t(3 * (2 + 30)));
  for (const auto& name : whole) {
    ASSERT_TRUE(Slurp(tmp / "whole" / "frames" / name) == Slurp(tmp / "killed" / "frames" / name))
        << name;
  }
  EXPECT_NE(Slurp(tmp / "killed" / "manifest.json").find("\"complete\""), std::string::npos);
}

TEST(Cli, InterruptStopsCleanlyWithExitCode130AndTellsHowToResume) {
  testing::TempDir tmp;
  const fs::path stage = WriteSmallStage(tmp.path());
  const pid_t pid = Spawn({cli_path().string(), "capture", "--quiet", "--stage", stage.string(),
                           "--out", (tmp / "s").string()});
  WaitForFrames(tmp / "s", 20, pid);
  kill(pid, SIGINT);
  int status;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130);
  EXPECT_NE(Slurp(tmp / "s" / "manifest.json").find("\"interrupted\""), std::string::npos);
  std::string out;
  EXPECT_EQ(
      run_command(cli_path().string() + " capture --quiet --resume " + (tmp / "s").string(), &out),
      0)
      << out;
}

void ExpectCliError(const std::string& args, std::initializer_list<std::string> fragments) {
  std::string out;
  const int code = run_command(cli_path().string() + " " + args, &out);
  EXPECT_EQ(code, 2) << args << "\n" << out;
  for (const auto& f : fragments)
    EXPECT_NE(out.find(f), std::string::npos) << "'" << f << "' not in: " << out;
}

TEST(Cli, MalformedStageSceneAndMapFilesGiveClearErrors) {
  testing::TempDir tmp;
  std::ofstream(tmp / "stage.json") << R"({"layout": {"type": "fibonacci", "count": 10},
    "camera": {"bracket": [{"exposure_s": "fast"}]}})";
  ExpectCliError(
      "capture --stage " + (tmp / "stage.json").string() + " --out " + (tmp / "s").string(),
      {"stage.json", "camera.bracket[0].exposure_s", "expected"});
  EXPECT_FALSE(fs::exists(tmp / "s" / "manifest.json"));  // Nothing created for bad input.

  // A stage naming a flat field that is not there: refused before the first frame (the build
  // would need it), naming the stage file and the field.
  std::ofstream(tmp / "flat.json") << R"({"layout": {"type": "fibonacci", "count": 10},
    "calibration": {"flat_field": "missing.flatfield.exr"}})";
  ExpectCliError(
      "capture --stage " + (tmp / "flat.json").string() + " --out " + (tmp / "s3").string(),
      {"flat.json: calibration.flat_field", "missing.flatfield.exr not found"});
  EXPECT_FALSE(fs::exists(tmp / "s3"));

  std::ofstream(tmp / "scene.json") << R"({"materials": [{"name": "m", "albedo": [0.5, 0.5, 0.5]}],
    "spheres": [{"center": [0, 0, 0], "radius": -1, "material": "m"}]})";
  ExpectCliError(
      "capture --scene " + (tmp / "scene.json").string() + " --out " + (tmp / "s2").string(),
      {"scene.json", "spheres[0].radius"});

  // A truncated map, and a map with a NaN.
  const std::string real = Slurp(testing::source_dir() / "data" / "envmaps" / "softbox_studio.exr");
  std::ofstream(tmp / "cut.exr", std::ios::binary) << real.substr(0, real.size() / 3);
  Image nan_map(64, 32, 3, 1.0f);
  nan_map.at(5, 7, 1) = NAN;
  write_exr(tmp / "nan.exr", nan_map);
  // A field to relight.
  std::string out;
  const fs::path stage = WriteSmallStage(tmp.path());
  ASSERT_EQ(run_command(cli_path().string() + " capture --quiet --stage " + stage.string() +
                            " --out " + (tmp / "ok").string(),
                        &out),
            0)
      << out;
  ASSERT_EQ(run_command(cli_path().string() + " build --quiet " + (tmp / "ok").string() +
                            " --out " + (tmp / "f.exr").string(),
                        &out),
            0)
      << out;
  ExpectCliError("relight " + (tmp / "f.exr").string() + " --env " + (tmp / "cut.exr").string() +
                     " --out " + (tmp / "r").string(),
                 {"cut.exr"});
  ExpectCliError("relight " + (tmp / "f.exr").string() + " --env " + (tmp / "nan.exr").string() +
                     " --out " + (tmp / "r").string(),
                 {"nan.exr", "x=5", "y=7"});
  // A good map before the bad one: the run stops before any image, and leaves no output folder.
  const fs::path good_map = testing::source_dir() / "data" / "envmaps" / "softbox_studio.exr";
  ExpectCliError("relight " + (tmp / "f.exr").string() + " --env " + good_map.string() + " " +
                     (tmp / "nan.exr").string() + " --out " + (tmp / "r").string(),
                 {"nan.exr"});
  EXPECT_FALSE(fs::exists(tmp / "r"));
  // Maps relit by the cells alone: --no-bright-sources, and its deprecated name.
  for (const std::string flag : {"--no-bright-sources", "--no-compact-sources"}) {
    EXPECT_EQ(run_command(cli_path().string() + " relight --quiet " + (tmp / "f.exr").string() +
                              " --env " + good_map.string() + " --out " +
                              (tmp / ("cells" + flag)).string() + " " + flag,
                          &out),
              0)
        << flag << ": " << out;
  }
  ExpectCliError("build " + tmp.path().string() + " --out " + (tmp / "g.exr").string(),
                 {"not a lightstage session"});

  // A session whose frames/ became a file: resume stops (exit 4) and says to move it aside, not
  // to free space.
  fs::copy(tmp / "ok", tmp / "damaged", fs::copy_options::recursive);
  fs::remove_all(tmp / "damaged" / "frames");
  std::ofstream(tmp / "damaged" / "frames") << "not a folder";
  EXPECT_EQ(
      run_command(cli_path().string() + " capture --quiet --resume " + (tmp / "damaged").string(),
                  &out),
      4)
      << out;
  EXPECT_NE(out.find("frames is not a folder: move it aside"), std::string::npos) << out;
}

// bench charts redraws a bench's charts from its CSV alone, and refuses a folder without one.
TEST(Cli, BenchChartsRedrawsFromTheCsvAlone) {
  testing::TempDir tmp;
  const std::string cli = cli_path().string() + " bench charts --dir " + tmp.path().string();
  std::string out;
  EXPECT_NE(run_command(cli, &out), 0) << out;
  std::string found;
  if (run_command("command -v gnuplot", &found) != 0) {
    EXPECT_NE(out.find("gnuplot"), std::string::npos) << out;
    GTEST_SKIP() << "gnuplot is not installed: " << out;
  }
  EXPECT_NE(out.find(tmp.path().string()), std::string::npos) << out;
  std::ofstream(tmp / "temporal.csv")
      << "steps,step_fit_us_per_pixel_step,temporal_fit_us_per_pixel,render_rel_rms_error,"
         "median_rate_rel_error,varying_recall,static_constant\n"
         "3,221,0.5,0.19,,0,1\n5,220,92,0.074,0.2,0.96,0.97\n8,220,144,0.075,0.025,1,0.98\n";
  ASSERT_EQ(run_command(cli, &out), 0) << out;
  EXPECT_TRUE(fs::exists(tmp / "temporal_error_vs_steps.png")) << out;
  EXPECT_TRUE(fs::exists(tmp / "temporal_time_vs_steps.gp")) << out;
}

// --memory is one option with one parser on every command that takes it: what is not a size is
// refused (exit 2) naming the option and the text, before any work; a small one is taken with a
// warning; each help says what the budget bounds there, with the units.
TEST(Cli, EveryCommandRefusesABadMemoryBudgetNamingIt) {
  testing::TempDir tmp;
  const std::vector<std::string> commands = {"build",
                                             "import",
                                             "fit",
                                             "fit --time " + tmp.path().string(),
                                             "normals",
                                             "compress",
                                             "export openlime",
                                             "relight",
                                             "view",
                                             "bench rti",
                                             "bench scale"};
  for (const std::string& cmd : commands) {
    for (const std::string bad : {"-1", "0"}) {
      ExpectCliError(cmd + " --memory " + bad, {"--memory '" + bad + "'"});
    }
  }
  for (const std::string& cmd : {std::string("build"), std::string("view")}) {
    ExpectCliError(cmd + " --memory -5", {"--memory '-5': a size cannot be negative"});
    ExpectCliError(cmd + " --memory 1", {"--memory '1': below 16 KiB"});
    ExpectCliError(cmd + " --memory 18446744073709551616",
                   {"--memory '18446744073709551616': too large"});
    ExpectCliError(cmd + " --memory 2X", {"--memory '2X': not a size", "512M, 2G"});
  }
  std::string out;
  // Taken, with a warning; then fit stops for its missing --out (usage).
  EXPECT_EQ(run_command(cli_path().string() + " fit --memory 20000", &out), 1) << out;
  EXPECT_NE(out.find("warning: --memory 19.5 KiB is below 16 MiB"), std::string::npos) << out;
  for (const std::string cmd : {"build", "import", "fit", "normals", "compress", "relight"}) {
    ASSERT_EQ(run_command(cli_path().string() + " " + cmd + " --help", &out), 0) << cmd;
    EXPECT_NE(out.find("--memory SIZE"), std::string::npos) << cmd << ": " << out;
    EXPECT_NE(out.find("powers of 1024"), std::string::npos) << cmd << ": " << out;
  }
  ASSERT_EQ(run_command(cli_path().string() + " import --help", &out), 0);
  EXPECT_NE(out.find("Default: 32 MiB"), std::string::npos) << out;
}

// Each subcommand's help names its own options and positionals (a few that only it has), and not
// those of an unrelated command: a help wired to the wrong subcommand, or an option dropped, fails.
TEST(Cli, HelpExplainsEverySubcommand) {
  const std::vector<std::pair<std::string, std::vector<std::string>>> expected = {
      {"capture", {"--out", "--resume", "--stage", "--scene", "--seed"}},
      {"build", {"session", "--out", "--all-time-steps", "--time-step"}},
      {"relight",
       {"field", "--env", "--light", "--models", "--temporal", "--edits", "--rotate",
        "--no-bright-sources"}},
      {"demo", {"--out", "--resolution", "--no-truth", "--no-shared-maps"}},
      {"stage", {"file", "--write"}},
      {"envmaps", {"--out", "--width"}},
      {"import", {"source", "--gamma", "--srgb", "--linear", "--drop-saturated", "--max-size"}},
      {"fit", {"field", "--method", "--phong", "--time"}},
      {"calibrate", {"directions", "intensities", "camera"}},
      {"compress", {"field", "--rank", "--tile", "--format"}},
      {"bench", {"leds", "fit-sweeps", "fit", "compact", "temporal", "charts"}},
      {"devices", {"--no-cameras"}},
      {"check", {"stage", "--blink", "--blink-seconds", "--no-frame"}},
      {"view", {"inputs", "--env", "--source", "--split", "--script", "--screenshot"}},
  };
  for (const auto& [cmd, words] : expected) {
    std::string out;
    EXPECT_EQ(run_command(cli_path().string() + " " + cmd + " --help", &out), 0) << cmd;
    for (const std::string& word : words) {
      EXPECT_NE(out.find(word), std::string::npos)
          << cmd << " --help lacks " << word << ": " << out;
    }
    // Options of other commands are not listed: --resume is capture's, --blink check's.
    if (cmd != "capture") {
      EXPECT_EQ(out.find("--resume"), std::string::npos) << cmd << ": " << out;
    }
    if (cmd != "check") {
      EXPECT_EQ(out.find("--blink"), std::string::npos) << cmd << ": " << out;
    }
  }
  std::string out;
  EXPECT_EQ(run_command(cli_path().string(), &out), 1) << out;  // No subcommand: usage.
  EXPECT_EQ(run_command(cli_path().string() + " capture --no-such-option", &out), 1) << out;
  EXPECT_NE(out.find("--no-such-option"), std::string::npos) << out;
  EXPECT_EQ(run_command(cli_path().string() + " capture", &out), 1) << out;  // Needs --out.
  EXPECT_NE(out.find("--out"), std::string::npos) << out;
}

}  // namespace
}  // namespace ls
