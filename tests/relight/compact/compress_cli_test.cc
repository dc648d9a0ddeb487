// `lightstage compress`: the real .lp capture straight into each representation, and usage errors.
#include <gtest/gtest.h>

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

}  // namespace
}  // namespace ls
