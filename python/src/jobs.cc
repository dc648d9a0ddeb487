// The jobs that make and use a field: build, relight, fit. Each binds its options by keyword to
// the library's options struct, runs the job as the CLI does (python/src/runner.h) and returns its
// outputs as arrays with the summary as a dict.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <memory>
#include <string>
#include <vector>

#include "app/jobs/build_job.h"
#include "app/jobs/fit_job.h"
#include "app/jobs/relight_job.h"
#include "lightstage/errors.h"
#include "python/src/arrays.h"
#include "python/src/bindings.h"
#include "python/src/runner.h"
#include "relight/fit/fit.h"

namespace ls::python {

namespace {

namespace fs = std::filesystem;

// --- build ---

py::dict build_summary(const jobs::BuildJobSummary& s) {
  py::list fields;
  for (const jobs::BuiltField& f : s.fields) {
    py::dict d;
    d["file"] = f.file;
    d["time_step"] = f.time_step;
    d["scene_time_s"] = f.scene_time_s;
    d["width"] = f.width, d["height"] = f.height, d["lights"] = f.lights;
    d["mebibytes"] = f.mebibytes;
    d["file_mebibytes"] = f.file_mebibytes;
    d["band_rows"] = f.band_rows;
    d["missing_led_ids"] = f.missing_led_ids;
    d["response"] = f.build.response_used;
    d["saturated_fraction"] = f.build.saturated_fraction;
    d["storage"] = f.build.storage.half ? "half" : "float";
    d["warnings"] = f.build.warnings;
    d["seconds"] = f.build.seconds;
    fields.append(d);
  }
  py::dict d;
  d["fields"] = fields;
  d["reference_z_m"] = s.reference_z_m;
  return d;
}

py::object build(const py::object& session, const py::object& out, int time_step,
                 bool all_time_steps, const py::object& memory, const std::string& storage,
                 bool correct_drift, const py::object& progress) {
  jobs::BuildJobOptions options;
  options.session_dir = to_path(session);
  options.out = to_path(out);
  options.time_step = time_step;
  options.all_time_steps = all_time_steps;
  options.memory = to_memory(memory);
  options.storage = storage;
  options.correct_drift = correct_drift;
  jobs::BuildJobSummary summary;
  run_job(progress, [&](const JobContext& job) { summary = jobs::build(options, job.progress); });
  py::list fields;
  const py::object open = py::module_::import("lightstage._lightstage").attr("Field").attr("open");
  for (const jobs::BuiltField& f : summary.fields) fields.append(open(f.file));
  py::dict result;
  result["fields"] = fields;
  result["summary"] = build_summary(summary);
  return make_result("Built", result);
}

// --- relight ---

py::object relight(const py::object& field, const py::object& env, const py::object& rotate,
                   const py::object& models, const py::object& temporal,
                   const std::optional<double>& time, const py::object& edits,
                   const std::optional<Eigen::Vector3d>& light,
                   const std::optional<double>& exposure, double coverage_deg, bool bright_sources,
                   bool source_geometry, std::size_t source_pixels, const py::object& memory,
                   int directions, const py::object& out, const py::object& progress) {
  jobs::RelightOptions options;
  options.field_file = to_optional_path(field);
  options.models_file = to_optional_path(models);
  options.temporal_file = to_optional_path(temporal);
  options.time_s = time;
  options.edits_file = to_optional_path(edits);
  options.maps = to_paths(env);
  options.rotations_deg = to_numbers(rotate);
  options.light_dir = light;
  options.exposure_stops = exposure;
  options.coverage_deg = coverage_deg;
  options.bright_sources = bright_sources;
  options.source_geometry = source_geometry;
  options.source_pixels = source_pixels;
  options.memory_bytes = to_memory(memory).given_bytes();
  options.directions_width = directions;
  std::unique_ptr<TempDir> temp;
  if (out.is_none()) temp = std::make_unique<TempDir>();
  options.out_dir = temp ? temp->path() / "relit" : to_path(out);

  jobs::RelightSummary summary;
  std::vector<std::shared_ptr<Image>> pixels;
  run_job(progress, [&](const JobContext& job) {
    summary = jobs::relight(options, job.progress);
    for (const jobs::RelitImage& image : summary.images) {
      pixels.push_back(std::make_shared<Image>(read_image(image.exr)));
    }
  });

  py::dict images, details;
  for (size_t i = 0; i < summary.images.size(); ++i) {
    // By the file's name: the map's, with the rotation when several were asked for.
    const std::string name = summary.images[i].exr.stem().string();
    images[py::str(name)] = image_view(pixels[i], "relit image " + name);
    details[py::str(name)] = summary.images[i].detail;
  }
  py::dict s;
  s["details"] = details;
  s["edit_reports"] = summary.edit_reports;
  s["first_time_s"] = summary.first_time_s;
  s["last_time_s"] = summary.last_time_s;
  s["extrapolated_pixels"] = summary.extrapolated_pixels;
  s["field_pass_s"] = summary.field_pass_s;
  s["field_file_bytes"] = summary.field_file_bytes;
  py::dict result;
  result["images"] = images;
  result["out"] = temp ? py::none() : py::cast(options.out_dir);
  result["summary"] = s;
  return make_result("Relit", result);
}

// --- fit ---

py::dict fit_summary(const jobs::FitJobSummary& summary) {
  const relight::FitSummary& s = summary.fit;
  py::dict d;
  d["width"] = summary.width, d["height"] = summary.height;
  d["pixels"] = s.pixels, d["fitted"] = s.fitted, d["flagged"] = s.flagged, d["empty"] = s.empty;
  py::dict per_model;
  for (int m = 0; m < 5; ++m) per_model[relight::to_string(relight::FitModel(m))] = s.per_model[m];
  d["per_model"] = per_model;
  d["not_converged"] = s.not_converged;
  d["discarded_nonfinite_fits"] = s.discarded_nonfinite_fits;
  d["scene_materials"] = s.scene_materials;
  d["material_pixels"] = s.material_pixels;
  py::list materials;
  for (const relight::Material& m : summary.materials) {
    py::dict md;
    md["model"] = relight::to_string(m.model);
    md["albedo"] = std::vector<double>{m.albedo(0), m.albedo(1), m.albedo(2)};
    md["sigma"] = m.sigma, md["ks"] = m.ks, md["roughness"] = m.roughness;
    md["pixels"] = m.pixels, md["scene_material"] = m.scene_material;
    materials.append(md);
  }
  d["materials"] = materials;
  d["noise_source"] = summary.noise_source;
  d["noise"] = py::dict(py::arg("read_variance") = summary.noise.a,
                        py::arg("shot_variance_per_unit") = summary.noise.b);
  d["seconds"] = summary.seconds;
  const relight::FitTimes& t = s.times;  // Where the seconds went, as `lightstage fit` prints.
  d["times"] = py::dict(py::arg("noise") = t.noise, py::arg("normals") = t.normals,
                        py::arg("candidates") = t.candidates, py::arg("materials") = t.materials,
                        py::arg("shadows") = t.shadows, py::arg("writing") = t.writing,
                        py::arg("reading") = t.reading);
  d["band_rows"] = summary.band_rows;
  d["resumed_rows"] = summary.resumed_rows;
  return d;
}

py::object fit(const py::object& field, const py::object& out, bool phong, bool dim_samples,
               const std::string& method, const std::string& materials, const py::object& memory,
               const py::object& progress) {
  jobs::FitJobOptions options;
  options.field_file = to_optional_path(field);
  std::unique_ptr<TempDir> temp;
  if (out.is_none()) temp = std::make_unique<TempDir>();
  options.out = temp ? temp->path() / "maps.exr" : to_path(out);
  options.phong = phong;
  options.dim_samples = dim_samples;
  options.method = method;
  options.materials = materials;
  options.memory = to_memory(memory);
  jobs::FitJobSummary summary;
  auto maps = std::make_shared<relight::ModelMaps>();
  run_job(progress, [&](const JobContext& job) {
    summary = jobs::fit(options, job.progress);
    *maps = relight::read_model_maps(options.out);
  });
  py::dict result;
  result["maps"] = named_views(std::shared_ptr<Image>(maps, &maps->maps), "model maps");
  result["out"] = temp ? py::none() : py::cast(options.out);
  result["summary"] = fit_summary(summary);
  return make_result("Fitted", result);
}

}  // namespace

void bind_jobs(py::module_& m) {
  m.def("build", &build, py::arg("session"), py::kw_only(), py::arg("out"),
        py::arg("time_step") = 0, py::arg("all_time_steps") = false, py::arg("memory") = py::none(),
        py::arg("storage") = "auto", py::arg("correct_drift") = false,
        py::arg("progress") = py::none());
  m.def("relight", &relight, py::arg("field") = py::none(), py::kw_only(),
        py::arg("env") = py::none(), py::arg("rotate") = 0.0, py::arg("models") = py::none(),
        py::arg("temporal") = py::none(), py::arg("time") = py::none(),
        py::arg("edits") = py::none(), py::arg("light") = py::none(),
        py::arg("exposure") = py::none(), py::arg("coverage_deg") = 0.0,
        py::arg("bright_sources") = true, py::arg("source_geometry") = true,
        py::arg("source_pixels") = jobs::RelightOptions{}.source_pixels,
        py::arg("memory") = py::none(), py::arg("directions") = 64, py::arg("out") = py::none(),
        py::arg("progress") = py::none());
  m.def("fit", &fit, py::arg("field"), py::kw_only(), py::arg("out") = py::none(),
        py::arg("phong") = false, py::arg("dim_samples") = false, py::arg("method") = "robust",
        py::arg("materials") = "basis", py::arg("memory") = py::none(),
        py::arg("progress") = py::none());
}

}  // namespace ls::python
