#include "tests/support/test_support.h"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <random>
#include <sstream>
#include <stdexcept>

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

std::string file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void patch_from_end(const std::filesystem::path& path, std::uintmax_t offset, const void* bytes,
                    std::size_t size) {
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  f.seekp(std::streamoff(std::filesystem::file_size(path) - offset));
  f.write(static_cast<const char*>(bytes), std::streamsize(size));
  if (!f) throw std::runtime_error(path.string() + ": cannot patch");
}

}  // namespace ls::testing
