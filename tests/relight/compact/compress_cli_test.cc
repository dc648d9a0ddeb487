// `lightstage compress`: the real .lp capture straight into each representation, and usage errors.
#include <gtest/gtest.h>

#include <fstream>

#include "relight/compact/pca_field.h"
#include "relight/compact/rti_io.h"
#include "tests/relight/compact/compact_fixtures.h"

namespace ls {
namespace {

TEST(CompressCommand, ImportsAnLpCaptureIntoEachRepresentation) {
  if (!std::filesystem::exists(compact_testing::real_lp())) {
    GTEST_SKIP() << compact_testing::real_lp() << " is absent";
  }
  testing::TempDir dir;
  const std::string lp = compact_testing::real_lp().string();
  std::string output;
  const std::string cli = testing::cli_path().string();
  ASSERT_EQ(
      testing::run_command(
          cli + " compress " + lp + " --format hsh3 --out " + (dir / "lion.rti").string(), &output),
      0)
      << output;
  EXPECT_EQ(relight::read_rti_file(dir / "lion.rti").terms, 9);
  ASSERT_EQ(testing::run_command(
                cli + " compress " + lp + " --format ptm-lrgb --out " + (dir / "lion.ptm").string(),
                &output),
            0)
      << output;
  EXPECT_EQ(relight::read_rti_file(dir / "lion.ptm").format, relight::RtiFileFormat::kPtmLrgb);
  ASSERT_EQ(
      testing::run_command(
          cli + " compress " + lp + " --rank 6 --out " + (dir / "lion.lspca").string(), &output),
      0)
      << output;
  EXPECT_EQ(relight::PcaField::read(dir / "lion.lspca").rank(), 6);
  // Sizes against what is on disk: the set's JPEGs (3.6 MiB), not the float field in memory.
  char sizes[96];
  std::snprintf(sizes, sizeof sizes, "wrote %.2f MiB from 3.58 MiB of input",
                double(std::filesystem::file_size(dir / "lion.lspca")) / (1 << 20));
  EXPECT_NE(output.find(sizes), std::string::npos) << output;
  // The default (--rank auto) never writes more than it was given: its noise floor asks a rank
  // (measured 136) whose file would be 4.4 MiB from these 3.6 MiB.
  ASSERT_EQ(testing::run_command(
                cli + " compress " + lp + " --out " + (dir / "auto.lspca").string(), &output),
            0)
      << output;
  std::uintmax_t input_bytes = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(
           compact_testing::real_lp().parent_path() / "jpg")) {
    if (entry.is_regular_file()) input_bytes += entry.file_size();
  }
  EXPECT_LE(std::filesystem::file_size(dir / "auto.lspca"), input_bytes) << output;
  EXPECT_NE(output.find("--rank auto: held at"), std::string::npos) << output;
  // --rank held-out chooses on held-out LEDs and says so: measured rank 64 (2.1 MiB), 0.24 dB from
  // the best of the ranks whose files fit, the error still falling at the largest of them (110).
  ASSERT_EQ(testing::run_command(cli + " compress " + lp + " --rank held-out --out " +
                                     (dir / "held_out.lspca").string(),
                                 &output),
            0)
      << output;
  EXPECT_LT(std::filesystem::file_size(dir / "held_out.lspca"),
            std::filesystem::file_size(dir / "auto.lspca"))
      << output;
  EXPECT_NE(output.find("(automatic) from held-out LEDs:"), std::string::npos) << output;
  EXPECT_NE(output.find("--rank held-out: ranks tried up to 110"), std::string::npos) << output;
  // Tiles of 4 pixels make each rank's file 16x larger: the bound (18) binds the choice itself.
  ASSERT_EQ(testing::run_command(cli + " compress " + lp + " --rank held-out --tile 4 --out " +
                                     (dir / "tiles.lspca").string(),
                                 &output),
            0)
      << output;
  EXPECT_LE(std::filesystem::file_size(dir / "tiles.lspca"), input_bytes) << output;
  EXPECT_NE(output.find(" 18, the largest rank whose file is no larger than the input"),
            std::string::npos)
      << output;
  // Only the images the .lp lists count, also for an .lp named from its own folder.
  std::filesystem::copy(compact_testing::real_lp().parent_path(), dir / "set",
                        std::filesystem::copy_options::recursive);
  std::ofstream(dir / "set" / "unlisted.jpg") << std::string(1 << 20, 'x');
  ASSERT_EQ(testing::run_command("cd " + (dir / "set").string() + " && " + cli +
                                     " compress dirs.lp --format hsh2 --out x.rti",
                                 &output),
            0)
      << output;
  EXPECT_NE(output.find("from 3.58 MiB of input"), std::string::npos) << output;
  // Bad input: exit 2 with a message naming the option.
  EXPECT_EQ(testing::run_command(
                cli + " compress " + lp + " --format jpeg --out " + (dir / "x").string(), &output),
            2);
  EXPECT_NE(output.find("--format"), std::string::npos) << output;
  EXPECT_EQ(testing::run_command(
                cli + " compress " + lp + " --rank many --out " + (dir / "x").string(), &output),
            2);
  EXPECT_NE(output.find("--rank"), std::string::npos) << output;
}

// Within --memory the set goes through a field file in bands: the same bytes as imported whole.
// `export openlime` writes the folder OpenLIME opens; `render` reads it back.
TEST(CompressCommand, WithinMemoryTheSameFilesAndOpenLimeFolders) {
  if (!std::filesystem::exists(compact_testing::real_lp())) {
    GTEST_SKIP() << compact_testing::real_lp() << " is absent";
  }
  namespace fs = std::filesystem;
  testing::TempDir dir;
  const std::string lp = compact_testing::real_lp().string(), cli = testing::cli_path().string();
  const std::string small = " --memory 200000";  // Bands of a few rows of the 64x43 set.
  std::string output;
  for (const std::string& memory : {std::string(), small}) {
    const std::string tag = memory.empty() ? "whole" : "bands";
    ASSERT_EQ(testing::run_command(cli + " compress " + lp + " --format hsh3" + memory + " --out " +
                                       (dir / (tag + ".rti")).string(),
                                   &output),
              0)
        << output;
    ASSERT_EQ(testing::run_command(cli + " export openlime " + lp + " --planes 9" + memory +
                                       " --out " + (dir / tag).string(),
                                   &output),
              0)
        << output;
    EXPECT_NE(output.find("OpenLIME rbf 9 planes"), std::string::npos) << output;
    EXPECT_EQ(output.find("read in bands") != std::string::npos, !memory.empty()) << output;
  }
  EXPECT_EQ(testing::file_bytes(dir / "whole.rti"), testing::file_bytes(dir / "bands.rti"));
  for (const char* file : {"info.json", "plane_0.jpg", "plane_2.jpg"}) {
    EXPECT_EQ(testing::file_bytes(dir / "whole" / file), testing::file_bytes(dir / "bands" / file))
        << file;
  }
  EXPECT_FALSE(fs::exists(dir / "whole" / "plane_3.jpg"));
  EXPECT_FALSE(fs::exists(dir / "bands.rti.imported.exr"));  // The field file is removed.
  ASSERT_EQ(testing::run_command(cli + " render " + (dir / "whole").string() +
                                     " --light 0.2 0.3 0.93 --out " + (dir / "lit.exr").string(),
                                 &output),
            0)
      << output;
  EXPECT_NE(output.find("64x43, rbf 9 planes relit"), std::string::npos) << output;
  EXPECT_EQ(
      testing::run_command(
          cli + " export openlime " + lp + " --type ptm --out " + (dir / "x").string(), &output),
      2);
  EXPECT_NE(output.find("--type"), std::string::npos) << output;
}

}  // namespace
}  // namespace ls
