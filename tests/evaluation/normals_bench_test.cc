// `lightstage bench normals`: DiLiGenT's ground truth read as SciPy reads it, and every method
// measured on the real sets in ../shared/data and the simulator's hard scenes.
#include "evaluation/normals_bench.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iostream>
#include <map>

#include "evaluation/chart.h"
#include "lightstage/errors.h"
#include "tests/support/test_support.h"

namespace ls::evaluation {
namespace {

namespace fs = std::filesystem;

fs::path diligent() { return ls::testing::shared_data_dir() / "diligent"; }

TEST(NormalsBench, ReadsDiligentGroundTruthAsScipyDoes) {
  if (!fs::exists(diligent() / "ball")) GTEST_SKIP() << "no ../shared/data";
  const Image truth = read_diligent_normals(diligent() / "ball" / "Normal_gt.mat");
  ASSERT_EQ(truth.width, 158);
  ASSERT_EQ(truth.height, 158);
  int object = 0;
  for (int y = 0; y < truth.height; ++y) {
    for (int x = 0; x < truth.width; ++x) {
      const Eigen::Vector3d n(truth.at(x, y, 0), truth.at(x, y, 1), truth.at(x, y, 2));
      if (n.norm() < 0.5) continue;
      ++object;
      EXPECT_NEAR(n.norm(), 1.0, 1e-5);
    }
  }
  // scipy.io.loadmat(...)['Normal_gt']: 15791 unit normals; [79, 79] = (0.0018, -0.0019, 1.0),
  // [20, 79] (row, column) = (0.0018, 0.8321, 0.5547): y up in the image.
  EXPECT_EQ(object, 15791);
  EXPECT_NEAR(truth.at(79, 79, 2), 0.99999657, 1e-6);
  EXPECT_NEAR(truth.at(79, 20, 1), 0.83205676, 1e-6);
  EXPECT_NEAR(truth.at(20, 79, 0), -0.83208352, 1e-6);

  ls::testing::TempDir tmp;
  std::ofstream(tmp / "bad.mat") << "not a MATLAB file";
  try {
    read_diligent_normals(tmp / "bad.mat");
    FAIL() << "a text file read as a .mat";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.mat"), std::string::npos) << e.what();
  }
}

TEST(NormalsBench, EveryMethodOnRealSetsAndHardScenes) {
  if (!fs::exists(diligent() / "ball")) GTEST_SKIP() << "no ../shared/data";
  ls::testing::TempDir tmp;
  NormalsBenchOptions options;
  options.out = tmp.path();
  options.data = diligent();
  options.executable = ls::testing::cli_path();
  options.repeats = 1;
  options.quick = true;
  const NormalsBenchSummary summary = run_normals_bench(options);
  std::map<std::pair<std::string, std::string>, NormalsBenchRow> rows;
  for (const NormalsBenchRow& r : summary.rows) {
    std::cout << r.set << " / " << r.method << ": " << r.mean_deg << " deg, " << r.seconds << " s, "
              << 100 * r.flagged_fraction << "% flagged\n";
    rows[{r.set, r.method}] = r;
    EXPECT_GT(r.seconds, 0) << r.set << " " << r.method;
  }
  // Two real sets and five hard scenes, three methods each; the real sets also fit with their dim
  // samples readmitted.
  EXPECT_EQ(summary.rows.size(), size_t(7 * 3 + 2));
  for (const char* method : {"least squares", "robust", "fit", "fit --dim-samples"}) {
    for (const char* set : {"ball", "reading"}) {
      ASSERT_TRUE(rows.count({set, method})) << set << " " << method;
      EXPECT_TRUE(std::isfinite(rows[{set, method}].mean_deg));
    }
  }
  const auto mean = [&](const std::string& set, const std::string& method) {
    return rows[{set, method}].mean_deg;
  };
  // Guards 5% over the figures measured: ball least squares 2.78, robust 1.99, fit 1.71, fit with
  // the dim samples 1.67 deg; reading 18.56, 12.65, 12.15, 12.20.
  EXPECT_LT(mean("ball", "fit"), 1.79);
  EXPECT_LT(mean("ball", "fit --dim-samples"), 1.76);
  EXPECT_LT(mean("reading", "fit --dim-samples"), 12.81);
  EXPECT_LT(mean("ball", "robust"), 2.09);
  EXPECT_LT(mean("reading", "fit"), 12.69);
  EXPECT_LT(mean("reading", "robust"), 13.28);
  // The robust normals' confidence says where they are wrong on the concave, shadowed reading:
  // measured 25.9 deg over the least confident quarter, 4.4 over the surest. (Not on the ball,
  // whose error is a bias spread evenly over it: 1.9 and 2.4.)
  const NormalsBenchRow& reading = rows[{"reading", "robust"}];
  EXPECT_GT(reading.least_confident_deg, 3 * reading.most_confident_deg);
  // What each method is for: the robust normals leave cast shadows out, least squares cannot.
  EXPECT_LT(mean("sim shadowed_fraction 0.75", "robust"),
            mean("sim shadowed_fraction 0.75", "least squares"));
  EXPECT_TRUE(fs::exists(summary.csv));
  if (!chart_tool_missing()) {
    EXPECT_TRUE(fs::exists(tmp / "normals.png"));
  }
  EXPECT_FALSE(fs::exists(tmp / "normals-work"));
}

}  // namespace
}  // namespace ls::evaluation
