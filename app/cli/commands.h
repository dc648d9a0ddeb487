#pragma once
// The lightstage subcommands. Each adds itself to the CLI11 app; parsing and printing live here,
// the work in the libraries. Exit codes: 0 done, 1 usage, 2 bad input, 3 hardware fault,
// 4 storage (an output or frame could not be written), 130 interrupted (resumable).
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "app/jobs/build_job.h"
#include "app/jobs/capture_job.h"
#include "app/jobs/fit_job.h"
#include "app/jobs/job.h"
#include "app/jobs/relight_job.h"
#include "lightstage/output_lock.h"

namespace CLI {
class App;
}

namespace ls::cli {

inline constexpr int kExitInputError = 2;
inline constexpr int kExitHardwareError = 3;
inline constexpr int kExitStorageError = 4;  // An output or frame could not be written.
inline constexpr int kExitInterrupted = 130;

void add_capture_command(CLI::App& app);
void add_build_command(CLI::App& app);
void add_relight_command(CLI::App& app);
void add_demo_command(CLI::App& app);
void add_stage_command(CLI::App& app);
void add_envmaps_command(CLI::App& app);
void add_bench_command(CLI::App& app);
void add_compress_command(CLI::App& app);       // compact_command.cc
void add_render_command(CLI::App& app);         // compact_command.cc
void add_export_command(CLI::App& app);         // compact_command.cc
void add_material_exports(CLI::App& exporter);  // material_command.cc: export gltf, materialx
void add_material_bench(CLI::App& bench);       // material_command.cc: bench material
bool& bench_quiet();                            // bench_command.cc: the running bench's --quiet
void add_devices_command(CLI::App& app);
void add_check_command(CLI::App& app);
void add_play_command(CLI::App& app);  // play_command.cc: the superposition check.
void add_calibrate_command(CLI::App& app);
void add_fit_command(CLI::App& app);
void add_normals_command(CLI::App& app);  // fit_command.cc
void add_import_command(CLI::App& app);
void add_view_command(CLI::App& app);  // view_command.cc: the interactive viewer.

// How a field file holds its values and why (capture/half_storage.h): the storage written, what
// half costs (absent: float asked for) and the file's size.
std::string storage_line(const capture::FieldStorage& storage,
                         const std::optional<capture::HalfCheck>& half_check,
                         double file_mebibytes);

// The lock on an output file or folder while this process writes it: a second writer is refused
// naming the first (InputError). None on the other ranks of an MPI run: rank 0 holds it.
std::unique_ptr<OutputLock> lock_output(const std::filesystem::path& out);

// Prints a job's progress on stderr, one bar per phase (lightstage/progress.h); silent when quiet.
jobs::ProgressFn progress_printer(bool quiet);

// --quiet, one meaning on every command: no progress output (warnings and results are printed
// all the same). A command that shows no progress takes it too, so that one script line serves
// every command.
void add_quiet_flag(CLI::App& cmd, bool& quiet);
void add_quiet_flag(CLI::App& cmd);

// The jobs with the operator's messages, shared by the demo and the single-step commands; each
// returns the exit code.
int capture_session(const jobs::CaptureOptions& options, bool quiet);
int build_field_file(const jobs::BuildJobOptions& options, bool quiet);
jobs::RelightSummary relight_and_report(const jobs::RelightOptions& options, bool quiet);
int fit_field_file(const jobs::FitJobOptions& options, bool quiet);

// Shipped maps: data/envmaps in the source tree, plus ../shared/data/envmaps when present.
std::vector<std::filesystem::path> shipped_environment_maps(bool include_shared);
std::filesystem::path data_dir();

}  // namespace ls::cli
