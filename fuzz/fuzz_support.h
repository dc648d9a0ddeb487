#pragma once
// What the libFuzzer targets in fuzz/ share (nothing crashes, nothing bad is accepted).
//
// The rule every target follows: a reader given any bytes either returns, or refuses them with the
// project's InputError (lightstage/errors.h). Anything else — a crash, a sanitizer report, an
// LS_CHECK, another exception escaping — is a finding: libFuzzer saves the input and stops.
//
// EXR-based formats (fields, model maps, temporal maps) are fuzzed through a text description of
// the file rather than its bytes, so that the mutations land on what lightstage parses (the
// attributes, the channel names, the layout, the values) instead of on OpenEXR's own framing:
//
//   <width> <height> <tile size, 0: scanlines> <float|half> <data window x> <data window y>
//   --
//   <channel names, comma-separated, in the order of the values below>
//   --
//   <pixel values, pixel-major, whitespace-separated; repeated to fill, 0 when none>
//   --
//   <name>=<value>            one string attribute per part (lightstage:*, or compression);
//   --                        lightstage:scene_time_s is written as a double when it is a number
//   ...
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "lightstage/errors.h"

namespace ls::fuzz {

// A folder of this process's own under $TMPDIR (else /tmp), created on first use and removed when
// the process exits normally. Also limits OpenImageIO and TBB to one thread: a fuzz run keeps to
// one core, and its runs are repeatable.
const std::filesystem::path& work_dir();

// Writes `bytes` to work_dir() / name, replacing it; returns the path.
std::filesystem::path write_file(const std::string& name, std::string_view bytes);

inline std::string_view as_text(const uint8_t* data, size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

// `text` split at lines holding only "--" (the parts of a description, or of a session's files).
std::vector<std::string> split_parts(std::string_view text);
std::string join_parts(const std::vector<std::string>& parts);

// Whether LIGHTSTAGE_FUZZ_VERBOSE is set: the refusals are printed (replaying an input by hand).
bool verbose();

// Runs `read`: the project's InputError is the expected refusal of bad input and is swallowed;
// everything else escapes to libFuzzer as a finding.
template <class Read>
void expect_only_input_errors(Read&& read) {
  try {
    read();
  } catch (const InputError& e) {
    if (verbose()) std::fprintf(stderr, "refused: %s\n", e.what());
  }
}

// Writes the EXR a description (above) describes to `path`. False when the description cannot be
// written as an EXR at all (no channels, an empty or repeated channel name, OpenImageIO refuses
// it): such inputs are skipped, they test nothing of ours. Sizes are clamped to at most 32 x 32
// pixels, 96 channels and tiles of 16.
bool write_described_exr(std::string_view description, const std::filesystem::path& path);
// The description of an EXR a lightstage writer wrote (the seeds of the EXR targets).
std::string describe_exr(const std::filesystem::path& path);

}  // namespace ls::fuzz
