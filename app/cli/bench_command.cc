// lightstage bench: speed and accuracy measurements that write CSV and chart images. The work is
// in evaluation/ (one entry point per bench); this file binds options and prints the tables.
//  leds:        relighting accuracy and speed as the number of LEDs grows (evaluation/led_bench.h).
//  fit-sweeps:  failure sweeps of normals and fits (evaluation/fit_sweeps_bench.h).
//  fit:         per-pixel model fits against field relighting (evaluation/fit_bench.h).
//  temporal:    time-varying BRDF fits as the time steps grow (evaluation/temporal_bench.h).
//  compact:     compact fields on held-out LEDs (evaluation/compact_bench.h).
//  rti:         the RTI formats as stored, against relight (evaluation/rti_bench.h).
//  charts:      every bench's charts redrawn from its CSV (evaluation/bench_charts.h).
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

#include "app/cli/commands.h"
#include "app/cli/validators.h"
#include "app/jobs/contact_sheet.h"
#include "evaluation/bench_charts.h"
#include "evaluation/chart.h"
#include "evaluation/compact_bench.h"
#include "evaluation/exposure_bench.h"
#include "evaluation/fit_bench.h"
#include "evaluation/fit_sweeps_bench.h"
#include "evaluation/led_bench.h"
#include "evaluation/normals_bench.h"
#include "evaluation/rti_bench.h"
#include "evaluation/scale_bench.h"
#include "evaluation/sun_bench.h"
#include "evaluation/temporal_bench.h"
#include "lightstage/errors.h"
#include "lightstage/memory_option.h"

namespace ls::cli {

namespace fs = std::filesystem;

// --quiet of the bench that runs (one a process): no progress output.
bool& bench_quiet() {
  static bool quiet = false;
  return quiet;
}

namespace {

void print_leds(const evaluation::LedBenchSummary& summary) {
  std::printf("%6s %-14s %-15s %10s %8s %11s %11s %10s\n", "LEDs", "map", "method", "rel.RMSE",
              "PSNR", "relight ms", "weights ms", "uncovered");
  for (const evaluation::LedBenchRow& r : summary.rows) {
    if (r.turns > 0) {  // Medians over the turns, untimed.
      std::printf("%6d %-14s %-15s %10.4f %8.2f median of %d turns %6.2f%%\n", r.leds,
                  r.map.c_str(), r.method.c_str(), r.relative_rmse, r.psnr_db, r.turns,
                  100 * r.uncovered_fraction);
      continue;
    }
    std::printf("%6d %-14s %-15s %10.4f %8.2f %11.3f %11.2f %9.2f%%\n", r.leds, r.map.c_str(),
                r.method.c_str(), r.relative_rmse, r.psnr_db, r.relight_ms, r.light_weights_ms,
                100 * r.uncovered_fraction);
  }
  std::fprintf(stderr, "wrote %s, leds_psnr_vs_time.png, leds_error_vs_count{,_turned}.png\n",
               summary.csv.c_str());
  if (!summary.comparison.empty()) {
    std::vector<jobs::Preview> tiles;
    for (const auto& image : summary.comparison) tiles.push_back({image.png, image.label});
    const std::filesystem::path sheet = summary.csv.parent_path() / "leds_compact_sources.png";
    jobs::write_contact_sheet(sheet, tiles, "LED cells | source at its direction | truth", 256, 3);
    std::fprintf(stderr, "wrote %s\n", sheet.c_str());
  }
}

std::string show(const std::optional<double>& v, double scale = 1.0) {
  if (!v) return "-";
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", *v * scale);
  return text;
}

void print_fit_sweeps(const evaluation::FitSweepsBenchSummary& summary) {
  std::printf("%-22s %7s %8s %8s %8s %8s %7s %7s %7s %6s %5s %5s %8s\n", "axis", "value", "LS deg",
              "rob deg", "fit deg", "fit p95", "flag%", "model%", "albedo%", "gross", "impl",
              "inval", "fit px/s");
  for (const evaluation::SweepPoint& p : summary.points) {
    std::printf("%-22s %7g %8s %8s %8s %8s %7.1f %7s %7s %6d %5d %5d %8.0f\n",
                evaluation::to_string(p.axis), p.value, show(p.least_squares.mean_deg).c_str(),
                show(p.robust.mean_deg).c_str(), show(p.fit.mean_deg).c_str(),
                show(p.fit.p95_deg).c_str(), 100 * p.fit.flagged_fraction,
                show(p.model_accuracy, 100).c_str(), show(p.albedo_rel, 100).c_str(),
                p.unflagged_gross_errors, p.unflagged_implausible, p.invalid_outputs,
                p.fit_pixels_per_second);
  }
  std::fprintf(stderr, "wrote %s and fit_sweeps_<axis>.png; %d invalid outputs\n",
               summary.csv.c_str(), summary.invalid_outputs);
}

void print_normals(const evaluation::NormalsBenchSummary& summary) {
  for (const std::string& why : summary.real_sets_missing) {
    std::fprintf(stderr, "note: no real set measured: %s\n", why.c_str());
  }
  std::printf("%-26s %-17s %9s %9s %8s %9s %8s %9s %9s\n", "set", "method", "mean deg", "median",
              "flag%", "seconds", "pixels", "least c.", "most c.");
  for (const evaluation::NormalsBenchRow& r : summary.rows) {
    const auto number = [](double v) {
      char text[16] = "-";
      if (!std::isnan(v)) std::snprintf(text, sizeof text, "%.3f", v);
      return std::string(text);
    };
    std::printf("%-26s %-17s %9.3f %9s %8.1f %9.3f %8d %9s %9s\n", r.set.c_str(), r.method.c_str(),
                r.mean_deg, number(r.median_deg).c_str(), 100 * r.flagged_fraction, r.seconds,
                r.pixels, number(r.least_confident_deg).c_str(),
                number(r.most_confident_deg).c_str());
  }
  std::fprintf(stderr, "wrote %s and normals.png\n", summary.csv.c_str());
}

void print_fit(const evaluation::FitBenchSummary& summary) {
  std::fprintf(stderr, "noise: %s: variance = %.3g + %.3g * v\n", summary.noise_source.c_str(),
               summary.noise_read_variance, summary.noise_shot_variance_per_unit);
  std::printf("%-26s %-14s %9s %11s %10s %9s %8s %8s %8s %8s %5s %7s\n", "method", "map", "fit s",
              "fit px/s", "render ms", "rel.RMSE", "PSNR", "flagged", "speckle", "L wrong", "mats",
              "fine");
  for (const evaluation::FitBenchRow& r : summary.rows) {
    if (r.method == "field") {
      std::printf("%-26s %-14s %9s %11s %10.3f %9.4f %8.2f %8s\n", "field", r.map.c_str(), "-", "-",
                  r.render_ms, r.relative_rmse, r.psnr_db, "-");
    } else {
      char fine[16] = "-";
      if (r.fine_relative_rmse > 0) std::snprintf(fine, sizeof fine, "%.4f", r.fine_relative_rmse);
      std::printf("%-26s %-14s %9.2f %11.0f %10.3f %9.4f %8.2f %7.1f%% %7.2f%% %7.2f%% %5d %7s\n",
                  r.method.c_str(), r.map.c_str(), r.fit_s, r.fit_pixels_per_s, r.render_ms,
                  r.relative_rmse, r.psnr_db, 100 * r.flagged_fraction, 100 * r.speckle,
                  100 * r.wrong_on_lambertian, r.materials, fine);
    }
  }
  std::fprintf(stderr, "wrote %s, fit_error_vs_time.png, fit_error_vs_throughput.png\n",
               summary.csv.c_str());
}

void print_temporal(const evaluation::TemporalBenchSummary& summary) {
  std::printf("%6s %22s %22s %12s %12s %10s %10s\n", "steps", "step fit us/px/step",
              "temporal fit us/px", "render err", "rate err", "recall", "static ok");
  for (const evaluation::TemporalBenchRow& r : summary.rows) {
    std::printf("%6d %22.1f %22.1f %12.4f %12.4f %10.3f %10.3f\n", r.steps,
                r.step_fit_us_per_pixel_step, r.temporal_fit_us_per_pixel, r.render_error,
                r.median_rate_error, r.varying_recall, r.static_constant);
  }
  std::fprintf(stderr, "wrote %s, temporal_error_vs_steps.png, temporal_time_vs_steps.png\n",
               summary.csv.c_str());
  if (summary.held_out.empty()) return;
  std::printf(
      "\nrise-and-fall scene, relative RMS error at the steps held out, and at the captured "
      "steps:\n"
      "%8s %4s %8s %9s %9s %10s %10s %9s %9s %11s %11s %12s\n",
      "exposure", "dim", "captured", "fit", "BIC alone", "processes", "step fits", "linear",
      "nearest", "fit@capt", "steps@capt", "photos@capt");
  for (const evaluation::HeldOutBenchRow& r : summary.held_out) {
    std::printf("%8.2f %4s %8d %9.4f %9.4f %10.4f %10.4f %9.4f %9.4f %11.4f %11.4f %12.4f\n",
                r.exposure, r.dim_samples ? "yes" : "no", r.captured, r.fit, r.by_bic_alone,
                r.processes_only, r.step_fits_interpolated, r.linear, r.nearest, r.fit_at_captured,
                r.step_fits_at_captured, r.photos_at_captured);
  }
  std::fprintf(stderr,
               "wrote temporal_held_out{,_dark,_dark_dim}.csv, "
               "temporal_held_out{,_dark,_dark_dim}_vs_steps.png, temporal_edits.png\n");
}

void print_compact(const evaluation::CompactBenchSummary& summary) {
  for (const std::string& note : summary.notes) std::fprintf(stderr, "note: %s\n", note.c_str());
  std::printf("%-18s %-18s %9s %8s %10s %8s %7s %s\n", "scene", "representation", "B/px", "build s",
              "relight ms", "PSNR dB", "SSIM", "front (bytes, time)");
  for (const evaluation::CompactBenchRow& r : summary.rows) {
    std::printf("%-18s %-18s %9.1f %8.3f %10.3f %8.2f %7.4f %s%s%s\n", r.scene.c_str(),
                r.name.c_str(), r.result.bytes_per_pixel, r.result.build_s, r.relight_ms,
                r.result.psnr_db, r.result.ssim, r.pareto_bytes ? "bytes " : "",
                r.pareto_time ? "time " : "", r.automatic ? "<- automatic" : "");
  }
  std::fprintf(stderr, "wrote %s and compact_<scene>_psnr_vs_{time,bytes}.png\n",
               summary.csv.c_str());
}

void add_rti(CLI::App& bench) {
  auto args = std::make_shared<evaluation::RtiBenchOptions>();
  auto* cmd = bench.add_subcommand(
      "rti",
      "The RTI formats as stored (.ptm, .rti, OpenLIME planes, PCA): held-out 8-bit sRGB PSNR "
      "against bytes per scene, on the real RTI set and a simulated one, beside relight's "
      "figures. CSV + charts.");
  cmd->add_option("--out", args->out, "Output directory.")->capture_default_str();
  cmd->add_flag("--quick", args->quick, "A 32x32 simulated scene, fewer formats, no memory part.");
  auto memory = std::make_shared<evaluation::RtiMemoryOptions>();
  auto measure_memory = std::make_shared<bool>(true);
  cmd->add_flag("!--no-memory", *measure_memory,
                "Skip the memory part (a 612x512, 96-light JPEG set through import, compress and "
                "export, each a process of its own).");
  auto budget = std::make_shared<MemoryBudget>(memory->memory_bytes);
  add_memory_option(*cmd, *budget, "Bench rti: the memory part's steps' --memory.");
  cmd->add_flag("--keep", memory->keep, "Keep the memory part's set and what was written from it.");
  cmd->callback([args, memory, measure_memory, budget] {
    memory->memory_bytes = budget->bytes();
    args->real_lp =
        data_dir().parent_path().parent_path() / "shared/data/rti/loewenkopf_klein/dirs.lp";
    const evaluation::RtiBenchSummary summary =
        evaluation::run_rti_bench(*args, progress_printer(bench_quiet()));
    for (const std::string& note : summary.notes) std::fprintf(stderr, "note: %s\n", note.c_str());
    std::printf("%-18s %-20s %10s %12s %12s\n", "scene", "format", "KiB", "sRGB8 dB", "linear dB");
    for (const evaluation::RtiBenchRow& r : summary.rows) {
      std::printf("%-18s %-20s %10.1f %12.2f %12.2f\n", r.scene.c_str(), r.name.c_str(),
                  r.bytes / 1024, r.result.psnr_srgb8_db, r.result.psnr_db);
    }
    std::printf("relight (cnr-isti-vclab) on loewenkopf, the same held-out lights:");
    for (const auto& f : evaluation::relight_loewenkopf_figures()) {
      std::printf(" %s %.2f dB", f.name, f.psnr_db);
    }
    std::printf("\nwrote %s and rti_<scene>_psnr_vs_bytes.png\n", summary.csv.c_str());
    if (args->quick || !*measure_memory) return;
    memory->out = args->out;
    memory->executable = fs::read_symlink("/proc/self/exe");
    const evaluation::RtiMemorySummary m =
        evaluation::run_rti_memory_bench(*memory, progress_printer(bench_quiet()));
    std::printf("\npeak memory, %dx%d, %d lights (JPEGs %.1f MiB); --memory %zu MiB:\n", m.width,
                m.height, m.lights, m.jpeg_mib, memory->memory_bytes >> 20);
    for (const evaluation::RtiMemoryRow& r : m.rows) {
      std::printf("  %-36s %8.1f MiB %8.2f s\n", r.step.c_str(), r.peak_mib, r.seconds);
    }
    std::printf("relight (cnr-isti-vclab) on the same set: 100-236 MiB\n");
  });
}

void add_sun(CLI::App& bench) {
  auto args = std::make_shared<evaluation::SunBenchOptions>();
  auto* cmd = bench.add_subcommand(
      "sun",
      "A small source between the LEDs: swept from an LED to the middle of three and turned "
      "through a full circle; the field relit by LED cells, with the source at its true "
      "direction (shadows by the flows alone, and with the scene's recovered shape), and with the "
      "scene's exact visibility of it (the shadows' share of the error), each against ground "
      "truth (built-in dome, demo scene).");
  cmd->add_option("--out", args->out, "Output directory.")->capture_default_str();
  cmd->add_option("--resolution", args->resolution, "Camera width and height.")
      ->capture_default_str();
  cmd->add_option("--radius-deg", args->radius_deg, "Angular radius of the source.")
      ->capture_default_str();
  cmd->add_option("--sweep-steps", args->sweep_steps, "Steps of the sweep.")->capture_default_str();
  cmd->add_option("--turn-steps", args->turn_steps, "Positions around the turn.")
      ->capture_default_str();
  cmd->add_option("--repeats", args->repeats, "Timed repeats (median reported).")
      ->capture_default_str();
  cmd->callback([args] {
    const evaluation::SunBenchSummary summary =
        evaluation::run_sun_bench(*args, progress_printer(bench_quiet()));
    std::printf("%-6s %9s %12s %11s %11s %13s %9s %9s %11s\n", "path", "position", "nearest LED",
                "cells RMSE", "flows RMSE", "sources RMSE", "cells ms", "flows ms", "sources ms");
    for (const evaluation::SunBenchRow& r : summary.rows) {
      std::printf("%-6s %9.3f %10.1f d %11.4f %11.4f %13.4f %9.2f %9.2f %11.2f\n", r.path.c_str(),
                  r.position, r.angle_to_nearest_led_deg, r.cells_rmse, r.flows_rmse,
                  r.sources_rmse, r.cells_ms, r.flows_ms, r.sources_ms);
    }
    std::fprintf(stderr,
                 "once per field: normals and LED shadows %.0f ms; with the scene's shape %.0f ms "
                 "(sources: flows + shape)\n",
                 summary.flows_setup_ms, summary.sources_setup_ms);
    std::fprintf(stderr, "wrote %s, sun_sweep.png, sun_turn.png, sun_error_vs_time.png\n",
                 summary.csv.c_str());
  });
}

void add_exposures(CLI::App& bench) {
  auto args = std::make_shared<evaluation::ExposureBenchOptions>();
  args->hdr_scene = std::filesystem::path(LIGHTSTAGE_DATA_DIR) / "scenes" / "hdr.json";
  auto* cmd = bench.add_subcommand(
      "exposures",
      "Exposures chosen per LED from an earlier session (capture --exposures-from) against the "
      "whole bracket, on the demo scene and a high-dynamic-range one (a near-mirror sphere "
      "beside a dark cloth): LED frames, exposure and capture time, field error against truth.");
  cmd->add_option("--out", args->out, "Output directory.")->capture_default_str();
  cmd->add_option("--resolution", args->resolution, "Camera width and height.")
      ->capture_default_str();
  cmd->add_option("--camera-fps", args->camera_fps,
                  "The camera's read-out rate: a frame takes at least 1/fps.")
      ->capture_default_str();
  cmd->callback([args] {
    const evaluation::ExposureBenchSummary summary =
        evaluation::run_exposure_bench(*args, progress_printer(bench_quiet()));
    std::printf("%-6s %-14s %10s %11s %10s %11s %9s\n", "scene", "plan", "LED frames", "exposure s",
                "capture s", "median err", "p90 err");
    for (const evaluation::ExposureBenchRow& r : summary.rows) {
      for (const auto& [plan, o] : {std::pair{"whole bracket", r.whole}, {"chosen", r.chosen}}) {
        std::printf("%-6s %-14s %10d %11.2f %10.2f %10.2f%% %8.2f%%\n", r.scene.c_str(), plan,
                    o.led_frames, o.exposure_s, o.capture_s, 100 * o.median_error,
                    100 * o.p90_error);
      }
    }
    std::fprintf(stderr, "wrote %s and exposures_error_vs_time.png\n", summary.csv.c_str());
  });
}

void add_leds(CLI::App& bench) {
  auto args = std::make_shared<evaluation::LedBenchOptions>();
  auto* cmd = bench.add_subcommand(
      "leds",
      "Relighting accuracy against ground truth, and time per frame, as the number of LEDs "
      "grows (Fibonacci domes of the given sizes, the demo scene, every shipped map).");
  cmd->add_option("--out", args->out, "Output directory.")->capture_default_str();
  cmd->add_option("--counts", args->counts, "Dome sizes.")->delimiter(',')->capture_default_str();
  cmd->add_option("--resolution", args->resolution, "Camera width and height.")
      ->capture_default_str();
  cmd->add_option("--repeats", args->repeats, "Timed repeats (median reported).")
      ->capture_default_str();
  cmd->add_option("--turns", args->turns,
                  "Maps with a bright source are also relit turned to this many azimuths about "
                  "the vertical, each against its own truth: median errors (0: not turned).")
      ->capture_default_str();
  auto shared_maps = std::make_shared<bool>(false);
  cmd->add_flag("--shared-maps", *shared_maps,
                "Also the real maps in ../shared/data/envmaps (ground truth rendered under each).");
  cmd->callback([args, shared_maps] {
    args->maps = shipped_environment_maps(*shared_maps);
    print_leds(evaluation::run_led_bench(*args, progress_printer(bench_quiet())));
  });
}

void add_fit_sweeps(CLI::App& bench) {
  auto args = std::make_shared<evaluation::FitSweepsBenchOptions>();
  auto* cmd = bench.add_subcommand(
      "fit-sweeps",
      "Failure sweeps of photometric-stereo normals and per-pixel fits on simulated ground truth: "
      "noise, LED count (down to below the minimum), light-direction error, shadowed fraction, "
      "saturation, dead LEDs and grazing normals. Writes fit_sweeps.csv and one chart per axis.");
  cmd->add_option("--out", args->out, "Output directory.")->capture_default_str();
  cmd->add_flag("--quick", args->sweeps.quick, "Three values per axis.");
  cmd->add_option("--height", args->sweeps.height, "Image height in pixels (width is 3x).")
      ->check(CLI::Range(4, 512))
      ->capture_default_str();
  cmd->add_option("--leds", args->sweeps.leds, "LEDs on every axis but the LED count.")
      ->check(CLI::Range(4, 2000))
      ->capture_default_str();
  cmd->callback([args] {
    args->sweeps.width = 3 * args->sweeps.height;
    print_fit_sweeps(evaluation::run_fit_sweeps_bench(*args, progress_printer(bench_quiet())));
  });
}

void add_normals(CLI::App& bench) {
  auto args = std::make_shared<evaluation::NormalsBenchOptions>();
  auto* cmd = bench.add_subcommand(
      "normals",
      "Every photometric-stereo method (least squares, robust, the fit's normals, on real sets "
      "also with --dim-samples) on every real set with ground-truth normals (DiLiGenT layout with "
      "Normal_gt.mat, run as the user runs them: import, normals, fit) and on the simulator's hard "
      "scenes (cast shadows, saturation, "
      "dead LEDs, grazing normals, noise): error against time. Writes normals.csv and "
      "normals.png.");
  cmd->add_option("--out", args->out, "Output directory.")->capture_default_str();
  args->data = data_dir().parent_path().parent_path() / "shared/data/diligent";
  cmd->add_option("--data", args->data, "Folder of DiLiGenT-layout sets with Normal_gt.mat.")
      ->capture_default_str();
  cmd->add_option("--repeats", args->repeats, "Timed runs per method on a real set (median).")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  cmd->add_flag("--quick", args->quick, "Smaller simulated scenes.");
  cmd->callback([args] {
    args->executable = fs::read_symlink("/proc/self/exe");
    print_normals(evaluation::run_normals_bench(*args, progress_printer(bench_quiet())));
  });
}

void add_fit(CLI::App& bench) {
  auto args = std::make_shared<evaluation::FitBenchOptions>();
  auto* cmd = bench.add_subcommand(
      "fit",
      "Per-pixel model fits against field relighting on the demo scene: fit throughput of each "
      "model (Lambert, Oren-Nayar, Lambert + Torrance-Sparrow, Lambert + Phong, and the BIC "
      "choice), each by the profiled solver and by LM on every candidate, and the error of "
      "relighting from it under every shipped map against ground "
      "truth, with the field's relighting on the same chart. Writes fit.csv and two charts.");
  cmd->add_option("--out", args->out, "Output directory.")->capture_default_str();
  cmd->add_option("--leds", args->leds, "LEDs on the Fibonacci dome.")
      ->check(CLI::Range(8, 2000))
      ->capture_default_str();
  cmd->add_option("--resolution", args->resolution, "Camera width and height.")
      ->check(CLI::Range(8, 1024))
      ->capture_default_str();
  cmd->add_option("--repeats", args->repeats, "Timed repeats of relighting (median).")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  cmd->callback([args] {
    args->maps = shipped_environment_maps(false);
    print_fit(evaluation::run_fit_bench(*args, progress_printer(bench_quiet())));
  });
}

void add_temporal(CLI::App& bench) {
  auto args = std::make_shared<evaluation::TemporalBenchOptions>();
  auto* cmd = bench.add_subcommand(
      "temporal",
      "Time-varying BRDF fits on the simulator's time-varying scene as the number of time steps "
      "grows: fit time per pixel and error against ground truth (render at uncaptured times, "
      "recovered rates). Writes temporal.csv and two charts. Then the rise-and-fall scene's time "
      "lapse captured at a growing number of its steps, as exposed, 5x darker, and 5x darker with "
      "its dim samples readmitted: error at the steps held out for the curves, the processes "
      "alone, linear interpolation and the nearest step (CSV + chart per case), and a time edit "
      "and an effect transfer over time (temporal_edits.png).");
  cmd->add_option("--out", args->out, "Output directory.")->capture_default_str();
  cmd->add_option("--steps", args->steps, "Numbers of time steps.")
      ->delimiter(',')
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  cmd->add_option("--leds", args->leds, "LEDs on the Fibonacci dome.")
      ->check(CLI::Range(8, 2000))
      ->capture_default_str();
  cmd->add_option("--width", args->width, "Image width.")->check(CLI::Range(4, 1024));
  cmd->add_option("--height", args->height, "Image height.")->check(CLI::Range(4, 1024));
  cmd->add_option("--duration", args->duration_s, "Scene seconds covered by the steps.")
      ->check(kPositive)
      ->capture_default_str();
  cmd->add_option("--captured", args->captured,
                  "Numbers of the time lapse's steps captured for the held-out part (empty: "
                  "leave it out).")
      ->delimiter(',')
      ->check(CLI::Range(2, 64))
      ->capture_default_str();
  cmd->callback([args] {
    print_temporal(evaluation::run_temporal_bench(*args, progress_printer(bench_quiet())));
  });
}

void add_compact(CLI::App& bench) {
  auto args = std::make_shared<evaluation::CompactBenchOptions>();
  auto* cmd = bench.add_subcommand(
      "compact",
      "Compact reflectance fields (PCA global and tiled, PTM, HSH, fitted models, the raw field): "
      "bytes per pixel, build time, relight time per frame, PSNR and SSIM on held-out LEDs, on "
      "simulated RTI scenes and the real RTI set. CSV + charts.");
  cmd->add_option("--out", args->out, "Output directory.")->capture_default_str();
  cmd->add_flag("--quick", args->quick, "32x32 scenes, no model fits.");
  cmd->add_option("--repeats", args->repeats, "Timed relights (median reported).")
      ->capture_default_str();
  cmd->callback([args] {
    args->environment_map = data_dir() / "envmaps/sky_sun.exr";
    // The real RTI set beside the checkout (../shared/data, as the tests find it).
    args->real_lp =
        data_dir().parent_path().parent_path() / "shared/data/rti/loewenkopf_klein/dirs.lp";
    print_compact(evaluation::run_compact_bench(*args, progress_printer(bench_quiet())));
  });
}

void print_scale(const evaluation::ScaleBenchSummary& summary, std::size_t budget) {
  std::printf("medians; every step's --memory %zu MiB\n", budget >> 20);
  std::printf("%-6s %-5s %-20s %10s %10s %10s %12s\n", "size", "LEDs", "step", "seconds",
              "peak MiB", "field MiB", "per unit");
  for (const evaluation::ScaleBenchRow& r : summary.rows) {
    std::printf("%-6d %-5d %-20s %10.2f %10.1f %10.1f %12.4g %s\n", r.size, r.leds, r.step.c_str(),
                r.seconds, r.peak_mib, r.field_mib, r.per_unit, r.unit.c_str());
  }
  const evaluation::ScaleMpiModel& m = summary.mpi;
  if (m.ranks.empty()) {
    if (!summary.mpi_note.empty()) std::printf("MPI not measured: %s\n", summary.mpi_note.c_str());
  } else {
    std::printf(
        "fit under MPI at %d² (one core a rank): 1 rank %.2f s, 2 ranks %.2f s (%.2fx); model "
        "%.2f s serial + %.2f s parallel, I/O floor %.2f s:",
        summary.mpi_size, m.one_rank_s, m.two_ranks_s, m.one_rank_s / m.two_ranks_s, m.serial_s,
        m.parallel_s, m.io_floor_s);
    for (size_t i = 0; i < m.ranks.size(); ++i)
      std::printf(" %d: %.2f s", m.ranks[i], m.model_s[i]);
    std::printf("\n");
  }
  std::fprintf(stderr, "wrote %s and scale_*.png\n", summary.csv.c_str());
}

void add_scale(CLI::App& bench) {
  auto args = std::make_shared<evaluation::ScaleBenchOptions>();
  auto* cmd = bench.add_subcommand(
      "scale",
      "Each step (capture, build, relight, fit, compress) on the built-in dome at growing "
      "camera sizes, as separate lightstage processes within --memory: median time, peak "
      "resident memory against the budget, relighting against reading the field from the page "
      "cache and from disk; fit under MPI with 1 and 2 ranks and a model to 64. The capture is "
      "the simulated stage's, every shadow ray traced (not repeated). CSV + charts.");
  cmd->add_option("--out", args->out, "Output directory.")->capture_default_str();
  cmd->add_option("--sizes", args->sizes, "Camera widths (= heights).")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--runs", args->runs, "Runs of each step (medians reported).")
      ->capture_default_str();
  auto budget = std::make_shared<MemoryBudget>(args->memory_bytes);
  add_memory_option(*cmd, *budget, "Bench scale: every step's --memory (at least 16 MiB).");
  cmd->add_option("--fit-max-size", args->fit_max_size,
                  "Larger sizes are not fitted (a fit's time grows with the pixels); MPI runs at "
                  "the largest size fitted.")
      ->capture_default_str();
  cmd->add_flag("!--no-mpi", args->mpi, "Skip the MPI fits.");
  cmd->add_flag("--keep", args->keep, "Keep each size's session and field.");
  cmd->add_flag("--single-exposure", args->single_exposure,
                "Capture one exposure per LED (the bracket's middle one), not three: a third of "
                "the frames' disk, for the largest sizes.");
  cmd->callback([args, budget] {
    args->memory_bytes = budget->bytes();
    args->executable = fs::read_symlink("/proc/self/exe");
    args->env_map = data_dir() / "envmaps/sky_sun.exr";
    print_scale(evaluation::run_scale_bench(*args, progress_printer(bench_quiet())),
                args->memory_bytes);
  });
}

void add_charts(CLI::App& bench) {
  auto dir = std::make_shared<fs::path>("bench-out");
  auto* cmd = bench.add_subcommand(
      "charts",
      "Redraw every bench's charts from the CSV files in a folder (leds.csv, fit.csv, ...), "
      "without running the benches: each chart and its gnuplot script (NAME.gp) beside its CSV. "
      "Needs gnuplot (Debian: gnuplot-nox).");
  cmd->add_option("--dir", *dir, "Folder of the benches' CSV files (a bench's --out).")
      ->capture_default_str();
  cmd->callback([dir] {
    const evaluation::RedrawnCharts charts = evaluation::redraw_bench_charts(*dir);
    for (const fs::path& csv : charts.drawn) std::printf("charts of %s redrawn\n", csv.c_str());
    if (charts.errors.empty()) return;
    std::string errors;
    for (const std::string& e : charts.errors) errors += "\n  " + e;
    throw InputError("bench charts: not drawn:" + errors);
  });
}

}  // namespace

void add_bench_command(CLI::App& app) {
  auto* bench =
      app.add_subcommand("bench", "Measure speed and accuracy; writes CSV and chart images.");
  bench->require_subcommand(1);
  add_leds(*bench);
  add_sun(*bench);
  add_exposures(*bench);
  add_material_bench(*bench);
  add_fit_sweeps(*bench);
  add_normals(*bench);
  add_fit(*bench);
  add_temporal(*bench);
  add_compact(*bench);
  add_rti(*bench);
  add_scale(*bench);
  add_charts(*bench);
  for (CLI::App* sub : bench->get_subcommands([](CLI::App*) { return true; })) {
    add_quiet_flag(*sub, bench_quiet());
  }
  // After a bench (its own callback first): charts need gnuplot; without it, their scripts alone.
  bench->callback([bench] {
    const auto missing = evaluation::chart_tool_missing();
    if (!missing || bench->got_subcommand("charts")) return;
    std::fprintf(stderr,
                 "note: charts not drawn: %s. Each chart's gnuplot script (NAME.gp) is written "
                 "beside the CSV: 'lightstage bench charts --dir OUT' draws them.\n",
                 missing->c_str());
  });
}

}  // namespace ls::cli
