// lightstage: dispatch only. Each subcommand lives in its own file (commands.h).
#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>

#include "app/cli/commands.h"
#include "app/cli/register_backends.h"
#include "lightstage/errors.h"

int main(int argc, char** argv) {
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
  ls::cli::add_devices_command(app);
  ls::cli::add_check_command(app);
  ls::cli::add_calibrate_command(app);
  ls::cli::add_fit_command(app);
  ls::cli::add_import_command(app);
  ls::cli::add_view_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::RuntimeError& e) {
    return e.get_exit_code();  // A subcommand's own exit code (2, 3, 4, 130).
  } catch (const CLI::ParseError& e) {
    // Prints the message (or the help); any usage error exits with the documented 1.
    return app.exit(e) == 0 ? 0 : 1;
  } catch (const ls::InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return ls::cli::kExitInputError;
  } catch (const ls::HardwareError& e) {
    std::fprintf(stderr, "hardware error: %s\n", e.what());
    return ls::cli::kExitHardwareError;
  }
  return 0;
}
