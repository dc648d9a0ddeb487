#include "tests/support/test_support.h"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <sstream>

namespace ls::testing {

namespace fs = std::filesystem;

TempDir::TempDir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = info ? std::string(info->test_suite_name()) + "." + info->name() : "test";
  std::replace(name.begin(), name.end(), '/', '_');
  std::random_device rd;
  path_ = fs::temp_directory_path() /
          ("lightstage-" + name + "-" + std::to_string(getpid()) + "-" + std::to_string(rd()));
  fs::create_directories(path_);
}

TempDir::~TempDir() {
  if (std::getenv("LIGHTSTAGE_KEEP_TEST_DIRS")) return;
  std::error_code ec;
  fs::remove_all(path_, ec);
}

fs::path source_dir() { return LIGHTSTAGE_SOURCE_DIR; }

fs::path shared_data_dir() {
  if (const char* env = std::getenv("LIGHTSTAGE_SHARED_DATA")) return env;
  return source_dir().parent_path() / "shared" / "data";
}

fs::path cli_path() { return LIGHTSTAGE_CLI; }

ImageError compare_images(const Image& actual, const Image& expected, const Image* mask) {
  ImageError e;
  if (actual.width != expected.width || actual.height != expected.height ||
      actual.channels != expected.channels) {
    e.rmse = e.relative_rmse = e.max_abs = INFINITY;
    return e;
  }
  double sum_sq = 0, sum_ref_sq = 0, peak = 0;
  size_t n = 0;
  for (int y = 0; y < actual.height; ++y) {
    for (int x = 0; x < actual.width; ++x) {
      if (mask && mask->at(x, y, 0) == 0.0f) continue;
      for (int c = 0; c < actual.channels; ++c) {
        const double a = actual.at(x, y, c), b = expected.at(x, y, c);
        const double d = std::isfinite(a) ? a - b : INFINITY;
        sum_sq += d * d;
        sum_ref_sq += b * b;
        peak = std::max(peak, b);
        ++n;
        if (std::abs(d) > e.max_abs || !std::isfinite(d)) {
          e.max_abs = std::abs(d);
          e.worst_x = x, e.worst_y = y, e.worst_c = c;
        }
      }
    }
  }
  if (n == 0) return e;
  e.rmse = std::sqrt(sum_sq / n);
  const double ref_rms = std::sqrt(sum_ref_sq / n);
  e.relative_rmse = ref_rms > 0 ? e.rmse / ref_rms : e.rmse;
  e.psnr_db = e.rmse > 0 ? 20.0 * std::log10(peak / e.rmse) : INFINITY;
  return e;
}

::testing::AssertionResult ImageNear(const Image& actual, const Image& expected, double rel_tol,
                                     const Image* mask) {
  if (actual.width != expected.width || actual.height != expected.height ||
      actual.channels != expected.channels) {
    return ::testing::AssertionFailure()
           << "size differs: " << actual.width << "x" << actual.height << "x" << actual.channels
           << " vs " << expected.width << "x" << expected.height << "x" << expected.channels;
  }
  const ImageError e = compare_images(actual, expected, mask);
  std::ostringstream msg;
  msg << "relative RMSE " << e.relative_rmse << " (tolerance " << rel_tol << "), PSNR " << e.psnr_db
      << " dB, worst |diff| " << e.max_abs << " at (" << e.worst_x << ", " << e.worst_y << ", c"
      << e.worst_c << ")";
  if (e.worst_x >= 0) {
    msg << ": actual " << actual.at(e.worst_x, e.worst_y, e.worst_c) << " expected "
        << expected.at(e.worst_x, e.worst_y, e.worst_c);
  }
  if (e.relative_rmse <= rel_tol) return ::testing::AssertionSuccess() << msg.str();
  return ::testing::AssertionFailure() << msg.str();
}

int run_command(const std::string& command, std::string* output) {
  std::string full = command + " 2>&1";
  FILE* pipe = popen(full.c_str(), "r");
  if (!pipe) return -1;
  std::array<char, 4096> buf;
  std::string out;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), pipe)) > 0) out.append(buf.data(), n);
  const int status = pclose(pipe);
  if (output) *output = out;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

}  // namespace ls::testing
