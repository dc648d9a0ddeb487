#pragma once
// Captured materials out of lightstage: the fitted model maps (lightstage fit's MAPS.exr) as a glTF
// 2.0 asset or a MaterialX document (relight/material/material_export.h), and rendered on another
// shape (relight/material/shape_render.h).
#include <filesystem>
#include <string>
#include <vector>

#include "app/jobs/compress_job.h"
#include "app/jobs/job.h"
#include "relight/material/material_export.h"

namespace ls::jobs {

struct MaterialExportOptions {
  std::filesystem::path maps;  // lightstage fit's MAPS.exr.
  std::filesystem::path out;   // Folder (made; its files replaced).
  std::string format;          // gltf | materialx
  std::string name;            // Of the document and the material; empty: the maps' stem.
  double height_m = 1.0;       // glTF: the captured surface's height (the view's).
  // glTF: the field the maps were fitted from; then the mesh is the scene's shape recovered from
  // it (relight/sources/shadow_geometry.h), not a plane.
  std::filesystem::path shape_from;
  std::string validate() const;
};

struct MaterialExportSummary {
  relight::MaterialExport files;
  size_t vertices = 0, triangles = 0;   // The glTF's mesh.
  std::filesystem::path error_preview;  // The conversion's error per pixel, as an image.
  int pixels = 0, distinct_lobes = 0;
  double f0 = 0, median_error = 0, p95_error = 0, max_error = 0;
  double seconds = 0;
};

MaterialExportSummary export_material(const MaterialExportOptions& options,
                                      const ProgressFn& progress = {});

// The maps of options.input on options.shape under options.light or options.environment:
// options.out (4 channels, linear RGB and coverage) and a PNG preview beside it.
RenderSummary render_material(const RenderOptions& options);

}  // namespace ls::jobs
