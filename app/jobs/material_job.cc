#include "app/jobs/material_job.h"

#include <cctype>
#include <cmath>
#include <vector>

#include "capture/field_file.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/run_outputs.h"
#include "physics/envmap.h"
#include "relight/fit/fit.h"
#include "relight/material/ggx_conversion.h"
#include "relight/material/shape_render.h"
#include "relight/material/surface_mesh.h"
#include "relight/sources/field_sources.h"

namespace ls::jobs {
namespace fs = std::filesystem;

namespace {

// A name MaterialX and glTF tools take: letters, digits and underscores, not starting with a digit.
std::string element_name(const std::string& wanted) {
  std::string name;
  for (const char c : wanted) name += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  if (name.empty() || std::isdigit(static_cast<unsigned char>(name[0]))) name = "m_" + name;
  return name;
}

}  // namespace

std::string MaterialExportOptions::validate() const {
  if (maps.empty()) return "the model maps (lightstage fit's MAPS.exr) are required";
  if (out.empty()) return "--out: a folder is required";
  if (format != "gltf" && format != "materialx") {
    return "format: expected gltf or materialx, got \"" + format + "\"";
  }
  if (!(height_m > 0) || !std::isfinite(height_m)) return "--height: expected a positive size";
  if (!shape_from.empty() && format != "gltf") return "--shape-from: glTF only (a mesh)";
  return {};
}

MaterialExportSummary export_material(const MaterialExportOptions& options,
                                      const ProgressFn& progress) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    throw InputError("export " + options.format + ": " + problem);
  }
  const Clock::time_point start = Clock::now();
  report(progress, "read", 0, 1, options.maps.filename());
  const relight::ModelMaps maps = relight::read_model_maps(options.maps);
  report(progress, "read", 1, 1);
  if (maps.summary.fitted == 0) {
    throw InputError(options.maps.string() + ": no pixel has a fitted model: nothing to export");
  }
  report(progress, "convert to GGX", 0, 1);
  const relight::GgxConversion material = relight::convert_to_ggx(maps);
  report(progress, "convert to GGX", 1, 1);

  relight::SurfaceMesh mesh =
      relight::plane_mesh(maps.maps.width, maps.maps.height, options.height_m);
  if (!options.shape_from.empty()) {
    const capture::ReflectanceField field = capture::read_field(options.shape_from);
    if (field.width() != maps.maps.width || field.height() != maps.maps.height) {
      throw InputError(options.shape_from.string() + ": --shape-from: a " +
                       std::to_string(field.width()) + "x" + std::to_string(field.height()) +
                       " field, but the maps are " + std::to_string(maps.maps.width) + "x" +
                       std::to_string(maps.maps.height) + ": give the field they were fitted from");
    }
    relight::FieldSources sources(field);
    sources.recover_geometry(progress);
    mesh =
        relight::shape_mesh(*sources.geometry(), field.width(), field.height(), options.height_m);
  }
  RunOutputs outputs(options.out);  // Removed, with the folder if this made it, on failure.
  const std::string name =
      element_name(options.name.empty() ? options.maps.stem().string() : options.name);
  // What this format writes (and only that: another format's files in the folder stay).
  const bool gltf = options.format == "gltf";
  const std::vector<std::string> files =
      gltf ? std::vector<std::string>{"metallic_roughness.png", "specular_strength.png",
                                      name + ".gltf", name + ".bin"}
           : std::vector<std::string>{"roughness.png", "specular.png", name + ".mtlx"};
  for (const std::string& file : files) outputs.add(options.out / file);
  for (const char* file : {"base_color.png", "normal.png", "conversion_error.png"}) {
    outputs.add(options.out / file);
  }
  report(progress, "write", 0, 1);
  MaterialExportSummary summary;
  summary.files = gltf ? relight::write_gltf(material, options.out, name, mesh)
                       : relight::write_materialx(material, options.out, name);
  // The error per pixel as an image: white at 20% relative error.
  Image error(material.width, material.height, 3);
  for (size_t i = 0; i < error.num_pixels(); ++i) {
    for (int c = 0; c < 3; ++c) error.pixels[i * 3 + c] = material.error.pixels[i] / 0.2f;
  }
  summary.error_preview = options.out / "conversion_error.png";
  write_png_preview(summary.error_preview, error);
  report(progress, "write", 1, 1);
  outputs.keep();
  summary.vertices = mesh.positions.size();
  summary.triangles = mesh.indices.size() / 3;
  summary.pixels = material.pixels;
  summary.distinct_lobes = material.distinct_lobes;
  summary.f0 = material.f0;
  summary.median_error = material.median_error;
  summary.p95_error = material.p95_error;
  summary.max_error = material.max_error;
  summary.seconds = seconds_since(start);
  return summary;
}

RenderSummary render_material(const RenderOptions& options) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    throw InputError("render: " + problem);
  }
  const relight::ModelMaps maps = relight::read_model_maps(options.input);
  relight::ShapeRenderOptions shape;
  shape.shape = relight::shape_named(options.shape);
  relight::Mesh mesh;
  if (shape.shape == relight::Shape::kMesh) {
    if (fs::path(options.shape).extension() != ".obj") {
      throw InputError("render: --shape: expected sphere, cylinder, plane or an .obj mesh, got \"" +
                       options.shape + "\"");
    }
    mesh = relight::read_obj(options.shape);
    shape.mesh = &mesh;
  }
  shape.width = shape.height = options.resolution;
  shape.tiles = options.tiles;
  const relight::LightingForModels lighting =
      options.environment.empty()
          ? relight::LightingForModels::directional(
                Eigen::Vector3d(options.light[0], options.light[1], options.light[2]).normalized(),
                Eigen::Vector3d::Ones())
          : relight::LightingForModels::environment(
                physics::EnvironmentMap::load(options.environment), options.rotation_deg);
  const Image image = relight::render_on_shape(maps, lighting, shape);
  RunOutputs outputs(options.out.parent_path().empty() ? fs::path(".") : options.out.parent_path());
  fs::path png = options.out;
  png.replace_extension(".png");
  outputs.add(options.out);
  outputs.add(png);
  write_exr(options.out, image);
  RenderSummary summary;
  summary.representation = "model maps on " + options.shape;
  summary.width = image.width;
  summary.height = image.height;
  summary.preview_stops = auto_exposure_stops(image);
  write_png_preview(png, image, summary.preview_stops);
  outputs.keep();
  return summary;
}

}  // namespace ls::jobs
