// lightstage export gltf|materialx MAPS.exr --out DIR: the fitted models as a material other
// renderers read (app/jobs/material_job.h). lightstage render MAPS.exr --shape ... is bound with
// the rest of render in compact_command.cc; lightstage bench material measures them.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <memory>

#include "app/cli/commands.h"
#include "app/jobs/material_job.h"
#include "evaluation/material_bench.h"

namespace ls::cli {

namespace {

void add_material_export(CLI::App& exporter, const std::string& format,
                         const std::string& description) {
  auto args = std::make_shared<jobs::MaterialExportOptions>();
  args->format = format;
  auto quiet = std::make_shared<bool>(false);
  auto* command = exporter.add_subcommand(format, description);
  command->add_option("maps", args->maps, "Model maps (lightstage fit's MAPS.exr).")
      ->required()
      ->check(CLI::ExistingFile);
  command->add_option("--out", args->out, "Folder to write (made; its files replaced).")
      ->required();
  command->add_option("--name", args->name, "Name of the material and its files. Default: MAPS.");
  if (format == "gltf") {
    command->add_option("--height", args->height_m, "The captured view's height in metres.")
        ->capture_default_str();
    command
        ->add_option("--shape-from", args->shape_from,
                     "The field the maps were fitted from: the mesh is the scene's shape "
                     "recovered from it (normals and the LEDs' shadows), not a plane.")
        ->check(CLI::ExistingFile);
  }
  add_quiet_flag(*command, *quiet);
  command->callback([args, quiet] {
    const auto lock = lock_output(args->out);
    const jobs::MaterialExportSummary s = jobs::export_material(*args, progress_printer(*quiet));
    std::printf(
        "%s: %d pixels converted to GGX metallic-roughness (%d distinct lobes fitted), "
        "F0 %.3f\n",
        s.files.document.c_str(), s.pixels, s.distinct_lobes, s.f0);
    std::printf(
        "conversion error (relative RMS of f cos over the hemisphere, 3 views): median "
        "%.1f%%, 95th percentile %.1f%%, max %.1f%%; per pixel: %s\n",
        100 * s.median_error, 100 * s.p95_error, 100 * s.max_error, s.error_preview.c_str());
    std::printf("mesh: %zu vertices, %zu triangles%s\n", s.vertices, s.triangles,
                args->shape_from.empty() ? " (a plane)" : " (the recovered shape)");
    for (const relight::WrittenTexture& t : s.files.textures) {
      std::printf("  %s: %d-bit PNG\n", t.file.c_str(), t.bits);
    }
    std::printf("done in %.2f s\n", s.seconds);
  });
}

}  // namespace

void add_material_exports(CLI::App& exporter) {
  add_material_export(
      exporter, "gltf",
      "A glTF 2.0 asset of fitted model maps (lightstage fit's MAPS.exr): the captured surface as "
      "a plane with the metallic-roughness textures (base colour, roughness, tangent-space "
      "normal map; the dielectric specular strength through KHR_materials_specular). The "
      "conversion to GGX is a fit; its error is printed and written as conversion_error.png.");
  add_material_export(
      exporter, "materialx",
      "A MaterialX document (Standard Surface, MaterialX 1.38) of fitted model maps with its PNG "
      "textures, for USD and film pipelines; the same conversion as export gltf.");
}

void add_material_bench(CLI::App& bench) {
  auto args = std::make_shared<evaluation::MaterialBenchOptions>();
  for (const char* map : {"sky_sun", "softbox_studio", "small_source"}) {
    args->maps.push_back(data_dir() / "envmaps" / (std::string(map) + ".exr"));
  }
  args->blender_script = data_dir().parent_path() / "tests/tools/blender_render_gltf.py";
  auto* cmd = bench.add_subcommand(
      "material",
      "The demo's fitted maps exported as glTF and rendered by Blender (Cycles, CPU) under each "
      "shipped map, against lightstage's render of the maps: per pixel the difference against "
      "the conversion's reported error (CSV, chart), per map the mean difference, and the "
      "times. Needs blender.");
  cmd->add_option("--out", args->out, "Output directory.")->capture_default_str();
  cmd->add_option("--resolution", args->resolution, "Capture and render width and height.")
      ->capture_default_str();
  cmd->add_option("--samples", args->samples, "Cycles samples per pixel.")->capture_default_str();
  cmd->callback([args] {
    const evaluation::MaterialBenchSummary s =
        evaluation::run_material_bench(*args, progress_printer(bench_quiet()));
    std::printf(
        "conversion: %d pixels in %.3f s (%.0f pixels/s); error median %.1f%%, p95 %.1f%%\n",
        s.pixels, s.conversion_s, s.pixels / std::max(s.conversion_s, 1e-9), 100 * s.median_error,
        100 * s.p95_error);
    std::printf("%-16s %22s %14s %11s\n", "map", "Blender vs lightstage", "lightstage s",
                "Blender s");
    for (const evaluation::MaterialBenchRow& r : s.rows) {
      std::printf("%-16s %21.1f%% %14.3f %11.1f\n", r.map.c_str(), 100 * r.mean_difference,
                  r.lightstage_s, r.blender_s);
    }
    std::fprintf(stderr, "wrote %s and %s\n", s.csv.c_str(), s.chart.c_str());
  });
}

}  // namespace ls::cli
