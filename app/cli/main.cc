// lightstage: dispatch only. Each subcommand lives in its own file (commands.h).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <new>
#include <string>

#include "app/cli/commands.h"
#include "app/cli/register_backends.h"
#include "app/jobs/ranks.h"
#include "lightstage/checkpoint_dir.h"
#include "lightstage/errors.h"

namespace {

// Under MPI (several ranks), `build`, `import`, `fit`, `normals`, `compress` and `relight` split
// their work; any other command would run once per rank, each writing the same outputs: refused.
void check_split_over_ranks(const CLI::App& app, int argc, char** argv) {
  const ls::jobs::Ranks& ranks = ls::jobs::Ranks::world();
  if (ranks.size() == 1) return;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg.empty() || arg[0] == '-') continue;
    if (arg == "fit" || arg == "normals" || arg == "build" || arg == "compress" ||
        arg == "import" || arg == "relight") {
      return;
    }
    const auto named = [&](const CLI::App* sub) { return sub->get_name() == arg; };
    if (app.get_subcommands(named).empty()) continue;
    throw ls::InputError(
        "'lightstage " + arg + "' runs as one process; under MPI (" + std::to_string(ranks.size()) +
        " ranks) only 'lightstage build', 'import', 'fit', 'normals', 'compress' and 'relight' "
        "split their work over ranks");
  }
}

// A run that failed says what it kept for the next one to resume from (OUT.partial/).
int failed(int code) {
  for (const auto& dir : ls::CheckpointDir::left_for_resume()) {
    std::fprintf(stderr,
                 "note: %s/ kept for resuming: running the same command again resumes from it; "
                 "delete it to start over\n",
                 dir.c_str());
  }
  return code;
}

int run(int argc, char** argv) {
  CLI::App app{
      "lightstage: light-stage capture and relighting.\n"
      "Typical use: lightstage capture --out S && lightstage build S --out F.exr && "
      "lightstage relight F.exr --env MAP.exr --out R\n"
      "or simply: lightstage demo"};
  ls::cli::register_backends();
  app.require_subcommand(1);
  ls::cli::add_capture_command(app);
  ls::cli::add_build_command(app);
  ls::cli::add_relight_command(app);
  ls::cli::add_demo_command(app);
  ls::cli::add_stage_command(app);
  ls::cli::add_envmaps_command(app);
  ls::cli::add_bench_command(app);
  ls::cli::add_compress_command(app);
  ls::cli::add_render_command(app);
  ls::cli::add_export_command(app);
  ls::cli::add_devices_command(app);
  ls::cli::add_check_command(app);
  ls::cli::add_play_command(app);
  ls::cli::add_calibrate_command(app);
  ls::cli::add_fit_command(app);
  ls::cli::add_normals_command(app);
  ls::cli::add_import_command(app);
  ls::cli::add_view_command(app);
  try {
    check_split_over_ranks(app, argc, argv);
    app.parse(argc, argv);
  } catch (const CLI::RuntimeError& e) {
    return failed(e.get_exit_code());  // A subcommand's own exit code (2, 3, 4, 130).
  } catch (const CLI::ParseError& e) {
    // Prints the message (or the help); any usage error exits with the documented 1.
    return app.exit(e) == 0 ? 0 : 1;
  } catch (const ls::StorageError& e) {
    std::fprintf(stderr, "storage error: %s\n", e.what());
    return failed(ls::cli::kExitStorageError);
  } catch (const ls::InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return failed(ls::cli::kExitInputError);
  } catch (const ls::HardwareError& e) {
    std::fprintf(stderr, "hardware error: %s\n", e.what());
    return failed(ls::cli::kExitHardwareError);
  } catch (const std::filesystem::filesystem_error& e) {  // A folder that cannot be made or read.
    std::fprintf(stderr, "storage error: %s\n", e.what());
    return failed(ls::cli::kExitStorageError);
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr,
                 "error: out of memory: an allocation failed (give a smaller --memory where the "
                 "command takes one, or free memory)\n");
    return failed(ls::cli::kExitInputError);
  } catch (const std::exception& e) {  // Not one of ours: said (and, under MPI, ends every rank).
    std::fprintf(stderr, "error: %s\n", e.what());
    return failed(ls::cli::kExitInputError);
  } catch (...) {
    std::fprintf(stderr, "error: unknown exception\n");
    return failed(ls::cli::kExitInputError);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const ls::jobs::Ranks::Session mpi(argc, argv);
    const int code = run(argc, argv);
    // One rank's error ends them all: the others may be waiting for it.
    if (code != 0) ls::jobs::Ranks::world().abort(code);
    return code;
  } catch (const ls::InputError& e) {  // Started by mpirun, built without MPI.
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {  // From MPI's start or end: said, not a core dump.
    std::fprintf(stderr, "error: %s\n", e.what());
    return ls::cli::kExitInputError;
  } catch (...) {
    std::fprintf(stderr, "error: unknown exception\n");
    return ls::cli::kExitInputError;
  }
}
