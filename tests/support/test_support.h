#pragma once
// Shared test helpers: a private temporary directory per test, image comparison that says where
// and by how much, and paths to the source tree and shared data.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "lightstage/image.h"
#include "lightstage/image_metrics.h"

namespace ls::testing {

// A fresh directory under the system temp dir, removed when the test ends (kept if
// LIGHTSTAGE_KEEP_TEST_DIRS is set, for debugging).
class TempDir {
 public:
  TempDir();
  ~TempDir();
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

std::filesystem::path source_dir();
// ../shared/data beside the checkout (LIGHTSTAGE_SHARED_DATA overrides). Tests that need it skip
// with a message when it is absent.
std::filesystem::path shared_data_dir();
std::filesystem::path cli_path();

using ls::compare_images;
using ls::ImageError;

// Passes when relative RMSE <= rel_tol; the message prints the error, the worst pixel and values.
::testing::AssertionResult ImageNear(const Image& actual, const Image& expected, double rel_tol,
                                     const Image* mask = nullptr);

// Runs a shell command, capturing stdout+stderr; returns the exit status.
int run_command(const std::string& command, std::string* output);

// The file's bytes ("" when it cannot be read).
std::string file_bytes(const std::filesystem::path& path);

// Overwrites `size` bytes of the file at byte `offset` from its end (a damaged file).
void patch_from_end(const std::filesystem::path& path, std::uintmax_t offset, const void* bytes,
                    std::size_t size);

}  // namespace ls::testing
