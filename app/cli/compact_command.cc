// lightstage compress FIELD --out OUT [--format F] [--rank k|auto] [--tile N] [--gain G]: writes
// one compact representation (.ptm, .rti, or the PCA binary format of relight/compact/pca_field.h)
// through the compress job (app/jobs/compress_job.h). FIELD is a field EXR, or an .lp capture (or a
// folder holding one), imported directly. lightstage render COMPACT --light X Y Z | --env MAP:
// relights one (an OpenLIME folder too). lightstage export openlime FIELD --out DIR: the OpenLIME
// planes. `lightstage bench compact` is in bench_command.cc.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <memory>

#include "app/cli/commands.h"
#include "app/jobs/compress_job.h"
#include "app/jobs/material_job.h"
#include "app/jobs/ranks.h"
#include "lightstage/memory.h"
#include "lightstage/memory_option.h"

namespace ls::cli {

void add_compress_command(CLI::App& app) {
  auto args = std::make_shared<jobs::CompressOptions>();
  auto quiet = std::make_shared<bool>(false);
  auto* compress = app.add_subcommand(
      "compress",
      "Writes a compact representation of a field (EXR, or an .lp capture imported directly): "
      ".ptm (PTM_1.2 RGB/LRGB), .rti (HSH) or the lightstage PCA format.");
  compress->add_option("field", args->input, "Field EXR, .lp file, or folder with one .lp.")
      ->required();
  compress->add_option("--out", args->out, "Output file.")->required();
  compress->add_option("--format", args->format, "pca | ptm | ptm-lrgb | hsh2 | hsh3 | hsh4.")
      ->capture_default_str();
  compress
      ->add_option(
          "--rank", args->rank,
          "PCA rank: a number; auto (the LEDs' images to the noise floor: what a map's sun and "
          "small sources are rendered from); or held-out (the smallest within 0.25 dB of the "
          "best on held-out LEDs: the best relighting between the LEDs per byte). Never a file "
          "larger than the input.")
      ->capture_default_str();
  compress->add_option("--tile", args->tile, "PCA tile size in pixels (0: one global basis).")
      ->capture_default_str();
  compress
      ->add_option("--gain", args->gain,
                   "RTI files: display units (white = 1) per field unit; 0: the brightest "
                   "sample is white.")
      ->capture_default_str();
  compress->add_option(
      "--encoding", args->encoding,
      "RTI files: srgb (the sRGB codes of the field, fitted as such: what RTIViewer, "
      "relight and OpenLIME show) or linear (.rti only, for lightstage's own use). "
      "Default: srgb.");
  add_memory_option(*compress, args->memory,
                    "Compress: the band of the field read at once (twice for PCA); an .lp set is "
                    "read in bands straight from its images.",
                    "half of the memory available; an .lp set's images 32 MiB");
  add_quiet_flag(*compress, *quiet);
  compress->callback([args, quiet] {
    // A bad --format or --rank is bad input (exit 2): jobs::compress validates them.
    const auto lock = lock_output(args->out);
    const jobs::CompressSummary summary =
        jobs::compress(*args, progress_printer(*quiet || !jobs::Ranks::world().root()));
    if (!jobs::Ranks::world().root()) return;  // Under MPI rank 0 wrote the file and prints.
    for (const std::string& warning : summary.warnings) {
      std::fprintf(stderr, "warning: %s\n", warning.c_str());
    }
    if (args->format == "pca") {
      std::printf("%s\n%s: %.1f bytes per pixel\n", summary.details.c_str(), args->out.c_str(),
                  summary.bytes_per_pixel);
    } else {
      std::printf("%s: %s %s, %.0f bytes per pixel\n", args->out.c_str(),
                  summary.representation.c_str(), summary.details.c_str(), summary.bytes_per_pixel);
    }
    // Against what the user has on disk, and the float field it was computed from.
    const auto mib = [](std::uintmax_t bytes) { return double(bytes) / (1 << 20); };
    std::printf(
        "wrote %.2f MiB from %.2f MiB of input (%.3gx); the float field in memory: %.0f "
        "bytes per pixel\n",
        mib(summary.output_bytes), mib(summary.input_bytes),
        summary.input_bytes > 0 ? double(summary.output_bytes) / summary.input_bytes : 0.0,
        summary.raw_bytes_per_pixel);
    if (summary.band_rows > 0) {
      std::printf("read in bands of %d rows", summary.band_rows);
      if (summary.ranks > 1) std::printf(" split over %d MPI ranks", summary.ranks);
      if (summary.resumed_rows > 0) {
        std::printf(" (%d rows' fits taken from an interrupted run)", summary.resumed_rows);
      }
      std::printf("\n");
    }
    std::printf("peak memory %.1f MiB\n", double(peak_resident_bytes()) / (1 << 20));
  });
}

void add_export_command(CLI::App& app) {
  auto* exporter = app.add_subcommand("export", "Writes a field in another program's format.");
  exporter->require_subcommand(1);
  auto args = std::make_shared<jobs::OpenLimeExportOptions>();
  auto quiet = std::make_shared<bool>(false);
  auto* openlime = exporter->add_subcommand(
      "openlime",
      "An OpenLIME folder (info.json and its planes, as relight writes them) of a field or an .lp "
      "set: quantised PCA planes with RBF or bilinear interpolation between the lights, "
      "display-referred (sRGB), read by the OpenLIME viewer and by lightstage render.");
  openlime->add_option("field", args->input, "Field EXR, .lp file, or folder with one .lp.")
      ->required();
  openlime->add_option("--out", args->out, "Folder to write (made; its files replaced).")
      ->required();
  openlime->add_option("--type", args->type, "rbf | bilinear.")->capture_default_str();
  openlime
      ->add_option("--planes", args->planes,
                   "Planes, a multiple of 3; 0: the fewest within 0.25 dB of the best on "
                   "held-out lights.")
      ->capture_default_str();
  openlime->add_option("--image", args->image, "Planes as jpg or png (lossless).")
      ->capture_default_str();
  openlime->add_option("--quality", args->quality, "JPEG quality.")->capture_default_str();
  openlime
      ->add_option("--gain", args->gain,
                   "Display units (white = 1) per field unit; 0: the brightest sample is white.")
      ->capture_default_str();
  add_memory_option(*openlime, args->memory,
                    "Export: the band of the field read at once (three passes); an .lp set is "
                    "read in bands straight from its images.",
                    "half of the memory available; an .lp set's images 32 MiB");
  add_quiet_flag(*openlime, *quiet);
  openlime->callback([args, quiet] {
    // Bad options are bad input (exit 2), as compress's.
    const auto lock = lock_output(args->out);
    const jobs::OpenLimeExportSummary summary =
        jobs::export_openlime(*args, progress_printer(*quiet));
    const auto mib = [](std::uintmax_t bytes) { return double(bytes) / (1 << 20); };
    std::printf("%s: OpenLIME %s (%s), %dx%d from %d lights\n", args->out.c_str(),
                summary.representation.c_str(), summary.chosen.c_str(), summary.width,
                summary.height, summary.lights);
    std::printf("wrote %.3f MiB from %.2f MiB of input (%.3gx)\n", mib(summary.output_bytes),
                mib(summary.input_bytes),
                summary.input_bytes > 0 ? double(summary.output_bytes) / summary.input_bytes : 0.0);
    if (summary.band_rows > 0) std::printf("read in bands of %d rows\n", summary.band_rows);
    std::printf("peak memory %.1f MiB\n", double(peak_resident_bytes()) / (1 << 20));
  });
  add_material_exports(*exporter);
}

void add_render_command(CLI::App& app) {
  auto args = std::make_shared<jobs::RenderOptions>();
  auto* render = app.add_subcommand(
      "render",
      "Relights a compact file (.ptm, .rti, the lightstage PCA format, or an OpenLIME folder) "
      "under one distant light or an environment map: a linear EXR in field units and a PNG "
      "preview. With --shape, renders fitted model maps (lightstage fit's MAPS.exr) on a new "
      "shape instead.");
  render
      ->add_option("compact", args->input, "Compact file, OpenLIME folder, or (--shape) MAPS.exr.")
      ->required()
      ->check(CLI::ExistingPath);
  render->add_option("--out", args->out, "Output image (.exr; a .png preview beside it).")
      ->required();
  render
      ->add_option("--light", args->light,
                   "X Y Z: direction toward the light, stage frame (+Y up, camera on +Z), unit "
                   "irradiance at normal incidence.")
      ->expected(3);
  render->add_option("--env", args->environment, "Environment map (EXR/HDR) instead of --light.");
  render->add_option("--rotate", args->rotation_deg, "Rotation of the map about +Y, degrees.")
      ->capture_default_str();
  render->add_flag("!--no-bright-sources", args->bright_sources,
                   "A PCA under a map with a sun or small lamp: relight it by the LED cells too "
                   "instead of rendering it at its true direction with moving shadows.");
  render
      ->add_flag("!--no-compact-sources", args->bright_sources, "Deprecated: --no-bright-sources.")
      ->group("");
  render
      ->add_option("--shape", args->shape,
                   "sphere | cylinder | plane | MESH.obj: the material of MAPS.exr on that shape "
                   "(mapped by the shape's UVs, the fitted normals on top of its own), seen "
                   "from +Z by an orthographic camera 2.4 tall; the shapes are 2 units across.")
      ->group("Material on a shape");
  render->add_option("--tiles", args->tiles, "--shape: repeats of the maps over the shape's UVs.")
      ->capture_default_str()
      ->group("Material on a shape");
  render->add_option("--resolution", args->resolution, "--shape: image width and height.")
      ->capture_default_str()
      ->group("Material on a shape");
  add_quiet_flag(*render);
  render->callback([args] {
    if (const std::string problem = args->validate(); !problem.empty()) {
      throw CLI::ValidationError("render", problem);
    }
    const auto lock = lock_output(args->out);
    const jobs::RenderSummary summary =
        args->shape.empty() ? jobs::render_compact(*args) : jobs::render_material(*args);
    for (const std::string& warning : summary.warnings) {
      std::fprintf(stderr, "warning: %s\n", warning.c_str());
    }
    std::printf("%s: %dx%d, %s relit\n", args->out.c_str(), summary.width, summary.height,
                summary.representation.c_str());
    if (!summary.sources.empty()) std::printf("  %s\n", summary.sources.c_str());
    std::filesystem::path png = args->out;
    png.replace_extension(".png");
    std::printf(
        "  preview %s: exposed %+.2f stops (x%.3g) from the EXR's linear values, then sRGB\n",
        png.c_str(), summary.preview_stops, std::exp2(summary.preview_stops));
  });
}

}  // namespace ls::cli
