#pragma once
// `lightstage bench rti`: every RTI-style format lightstage writes, measured as the RTI
// community measures them (relight's figures): every 5th light held out, the rest compressed into
// the format's stored bytes (8-bit .ptm/.rti, OpenLIME JPEG planes and info.json, the float PCA
// file) and read back, the held-out lights rendered, 8-bit sRGB PSNR pooled over them, against
// the bytes per scene. On the real set (loewenkopf) and a simulated one; relight's own figures on
// the real set are written after its rows (family "relight's figures") and drawn beside them.
// Writes rti.csv and rti_<scene>_psnr_vs_bytes.png.
#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "evaluation/bench_support.h"
#include "evaluation/leave_lights_out.h"

namespace ls::evaluation {

struct RtiBenchOptions {
  std::filesystem::path out = "bench-out";
  std::filesystem::path real_lp;  // The real set (.lp); skipped when absent.
  bool quick = false;             // A 32x32 simulated scene only, fewer formats.
  std::string validate() const;   // Empty when valid.
};

struct RtiBenchRow {
  std::string scene, family, name;
  double bytes = 0;  // Stored, per scene.
  LeaveLightsOutResult result;
};

struct RtiBenchSummary {
  std::vector<RtiBenchRow> rows;
  std::vector<std::string> notes;
  std::filesystem::path csv;
};

RtiBenchSummary run_rti_bench(const RtiBenchOptions& options, const ProgressFn& progress = {});

// Memory: a one-light set of width x height pixels and `lights` lights (the glossy simulated
// scene as sRGB JPEGs and an .lp file), then import, compress and export openlime run on it as
// separate lightstage processes, each one's peak resident memory (wait4) measured: by default and
// within --memory. "start" is the process doing nothing (--help): what loading its libraries costs.
struct RtiMemoryOptions {
  std::filesystem::path out = "bench-out";
  std::filesystem::path executable;  // The lightstage executable (the CLI: itself).
  int width = 612, height = 512, lights = 96;
  std::size_t memory_bytes = std::size_t(64) << 20;  // The --memory steps' budget.
  bool keep = false;                                 // Keep the set and what was written.
};

struct RtiMemoryRow {
  std::string step;
  double peak_mib = 0, seconds = 0;
};

struct RtiMemorySummary {
  int width = 0, height = 0, lights = 0;
  double jpeg_mib = 0;  // The set's images on disk.
  std::vector<RtiMemoryRow> rows;
};

RtiMemorySummary run_rti_memory_bench(const RtiMemoryOptions& options,
                                      const ProgressFn& progress = {});

// rti_<scene>_psnr_vs_bytes.png (the scene's first word) beside `csv` (an rti.csv), from it alone.
void write_rti_charts(const std::filesystem::path& csv);

// relight's figures on loewenkopf_klein (built from its sources, every 5th light held out, 8-bit
// sRGB PSNR pooled): name, dB, bytes per scene (0 where the figures give no size).
struct ReferenceFigure {
  const char* name;
  double psnr_db;
  double bytes;
};
const std::vector<ReferenceFigure>& relight_loewenkopf_figures();

}  // namespace ls::evaluation
