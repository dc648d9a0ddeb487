// lightstage export gltf|materialx MAPS.exr --out DIR: the fitted models as a material other
// renderers read (app/jobs/material_job.h). lightstage render MAPS.exr --shape ... is bound with
// the rest of render in compact_command.cc.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <memory>

#include "app/cli/commands.h"
#include "app/jobs/material_job.h"

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
  command->add_flag("--quiet", *quiet, "No progress output.");
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

}  // namespace ls::cli
