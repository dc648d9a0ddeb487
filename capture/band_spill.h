#pragma once
// LED images spilled to disk in bands of rows, so that a field larger than memory is built from
// LED-major frames into a pixel-major file (capture/build_field.h): band b holds each
// LED's rows of that band in turn, so an LED is written with one pwrite per band and a band is
// read back with one pread. The file is removed when the SpillFile is destroyed, unless it is kept
// for a build that may be resumed (capture/build_checkpoint.h).
#include <atomic>
#include <cstddef>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/progress.h"
#include "lightstage/scratch_file.h"

namespace ls::capture {

// The rows per band for making a field of this size within `memory`; a band is held twice while
// it is written (as spilled, then pixel-major). The height: make it in memory.
int spill_band_rows(int width, int height, int num_lights, const MemoryBudget& memory);

class SpillFile {
 public:
  // Beside `field_file` (OUT.spill-PID), or, given `kept_at`, there and kept after (what an
  // earlier run put there is read back by reread).
  SpillFile(const std::filesystem::path& field_file, int width, int height, int num_lights,
            int band_rows, const std::filesystem::path& kept_at = {});
  SpillFile(const SpillFile&) = delete;
  SpillFile& operator=(const SpillFile&) = delete;

  int bands() const { return (height_ + band_rows_ - 1) / band_rows_; }
  int band_first_row(int band) const { return band * band_rows_; }
  int band_height(int band) const { return std::min(band_rows_, height_ - band_first_row(band)); }
  // LED `light`'s image (width * height * 3 floats, row-major, RGB innermost).
  void put(int light, const std::vector<float>& rgb);
  // LED `light`'s image as put wrote it (by this run or an earlier one: a resumed build), counted
  // in the largest value as put counts it.
  void reread(int light, std::vector<float>& rgb);
  // Every LED put so far made durable (before a checkpoint says they are there).
  void sync() { file_.sync(); }
  // What other processes wrote since it was opened (MPI ranks on other nodes): ScratchFile::reopen.
  void reopen() { file_.reopen(); }
  // Band b into `band` (resized to the band's rows), pixel-major as the field stores it;
  // `scratch` holds the band as spilled.
  // `keep` (indices of the lights put, in order): only those, in that order; empty: every light.
  void read_band(int b, std::vector<float>& scratch, ReflectanceField& band,
                 const std::vector<int>& keep = {});
  // Every band into the field file `out` (FieldWriter; header: its lights and attributes), band
  // by band; progress "write" (bands written) after each. Stored as `choice` asks (half scaled by
  // the largest value put; auto: half, written again in float when a band fails check_half).
  // Returns the storage written; *check, when given, the half check (half or auto). `keep`
  // (indices of the lights put, in order) leaves the others out; empty: every light. The header's
  // lights are those written.
  FieldStorage write_field(const std::filesystem::path& out, const ReflectanceField& header,
                           const ExrAttributes& attributes, const ProgressFn& progress,
                           StorageChoice choice = StorageChoice::kFloat, HalfCheck* check = nullptr,
                           const std::vector<int>& keep = {});

 private:
  std::size_t offset(int band) const;  // In floats.
  void count_largest(const std::vector<float>& rgb);

  int width_, height_, lights_, band_rows_;
  ScratchFile file_;
  std::atomic<float> largest_{0};  // |value| over the images put (puts may run in parallel).
};

}  // namespace ls::capture
