// The jobs around a field: capture a session, import a one-light-at-a-time set, compress a field,
// render a compact file, photometric-stereo normals alone.
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "app/jobs/capture_job.h"
#include "app/jobs/compress_job.h"
#include "app/jobs/fit_job.h"
#include "app/jobs/import_job.h"
#include "capture/half_storage.h"
#include "capture/light_calibration.h"
#include "lightstage/errors.h"
#include "lightstage/exr_channels.h"
#include "python/src/arrays.h"
#include "python/src/bindings.h"
#include "python/src/errors.h"
#include "python/src/runner.h"

namespace ls::python {

namespace {

namespace fs = std::filesystem;

// --- capture ---

py::dict capture_summary(const jobs::CaptureJobSummary& s) {
  py::dict d;
  d["already_complete"] = s.already_complete;
  d["frames_present_before"] = s.frames_present_before;
  d["frames_missing_before"] = s.frames_missing_before;
  d["frames_captured"] = s.capture.frames_captured;
  d["camera_retries"] = s.capture.camera_retries;
  d["frames_reshot"] = s.capture.frames_reshot;
  d["message"] = s.capture.message;
  d["seconds"] = s.capture.seconds;
  d["dead_leds"] = s.dead_leds;
  d["frame_problems"] = s.frame_problems;
  d["drift"] = s.drift;
  return d;
}

py::object capture(const py::object& stage, const py::object& scene, const py::object& out,
                   bool resume, uint64_t seed, bool verify_frames, const py::object& exposures_from,
                   const py::object& progress) {
  jobs::CaptureOptions options;
  options.stage_file = to_optional_path(stage);
  options.scene_file = to_optional_path(scene);
  options.session_dir = to_path(out);
  options.resume = resume;
  options.seed = seed;
  options.verify_frames = verify_frames;
  options.exposures_from = to_optional_path(exposures_from);
  jobs::CaptureJobSummary summary;
  run_job(progress, [&](const JobContext& job) {
    jobs::CaptureCallbacks callbacks;
    // A capture stops cleanly at the flag, before its next frame, with every LED off.
    callbacks.stop_requested = job.stop_requested;
    callbacks.on_progress = job.observe;
    summary = jobs::capture(options, callbacks);
  });
  using Status = CaptureSummary::Status;
  switch (summary.capture.status) {
    case Status::kComplete:
    case Status::kInterrupted:  // Only by a KeyboardInterrupt, which run_job raised.
      break;
    case Status::kCameraFailed:
    case Status::kDarkFramesLit:
      throw HardwareError(options.session_dir.string() + ": " + summary.capture.message);
    case Status::kWriteFailed:
      throw_storage_error(options.session_dir.string() + ": " + summary.capture.message,
                          options.session_dir.string());
  }
  py::dict result;
  result["session"] = options.session_dir;
  result["summary"] = capture_summary(summary);
  return make_result("Captured", result);
}

// --- import ---

py::object import_set(const py::object& source, const py::object& out, bool linear, bool srgb,
                      const std::optional<double>& gamma, int max_size, bool drop_saturated,
                      bool keep_all, const std::vector<std::array<double, 3>>& circles,
                      double sphere_radius, double focal_length_px, const py::object& stage,
                      double time, const std::string& storage, const py::object& memory,
                      const py::object& progress) {
  if (int(linear) + int(srgb) + int(gamma.has_value()) > 1) {
    throw InputError("import: give one of linear, srgb and gamma");
  }
  capture::OlatImportOptions options;
  options.storage = capture::parse_storage_choice("--storage", storage);
  if (linear) options.transfer = capture::TransferCurve::kLinear;
  if (srgb) options.transfer = capture::TransferCurve::kSrgb;
  if (gamma) {
    options.transfer = capture::TransferCurve::kGamma;
    options.gamma = *gamma;
  }
  options.max_size = max_size;
  options.zero_saturated = drop_saturated;
  options.keep_all = keep_all;
  for (const auto& [cx, cy, r] : circles) {
    options.spheres.outlines.push_back(capture::outlines_from_circles({cx, cy, r})[0]);
  }
  options.spheres.radius_m = sphere_radius;
  options.spheres.focal_length_px = focal_length_px;
  if (!stage.is_none()) options.stage_file = to_path(stage);
  options.scene_time_s = time;
  const fs::path from = to_path(source), to = to_path(out);
  const MemoryBudget budget = to_memory(memory);
  jobs::ImportJobSummary summary;
  run_job(progress, [&](const JobContext& job) {
    summary = jobs::import_set(from, to, options, budget, job.progress);
  });
  const capture::OlatImportSummary& s = summary.import;
  py::dict d;
  d["format"] = capture::to_string(summary.format);
  d["images"] = s.images;
  d["width"] = s.width, d["height"] = s.height, d["lights"] = summary.lights;
  d["source_width"] = s.source_width, d["source_height"] = s.source_height;
  d["pixel_format"] = s.pixel_format;
  d["transfer_undone"] = s.transfer_undone;
  d["saturated_fraction"] = s.saturated_fraction;
  d["notes"] = s.notes;
  d["consistency"] = s.consistency;
  d["inconsistent"] = s.inconsistent;
  d["inconsistent_left_out"] = s.inconsistent_left_out();
  d["light_placement"] = s.light_placement;
  d["warnings"] = s.warnings;
  d["preview"] = summary.preview;
  d["seconds"] = s.seconds;
  py::dict result;
  result["field"] = py::module_::import("lightstage._lightstage").attr("Field").attr("open")(to);
  result["summary"] = d;
  return make_result("Imported", result);
}

// --- compress, render ---

py::object compress(const py::object& input, const py::object& out, const std::string& format,
                    const py::object& rank, int tile, double gain, const std::string& encoding,
                    const py::object& memory, const py::object& progress) {
  jobs::CompressOptions options;
  options.input = to_path(input);
  options.out = to_path(out);
  options.format = format;
  options.rank = py::str(rank).cast<std::string>();
  options.tile = tile;
  options.gain = gain;
  options.encoding = encoding;
  options.memory = to_memory(memory);
  jobs::CompressSummary s;
  run_job(progress, [&](const JobContext& job) { s = jobs::compress(options, job.progress); });
  py::dict d;
  d["representation"] = s.representation;
  d["details"] = s.details;
  d["bytes_per_pixel"] = s.bytes_per_pixel;
  d["raw_bytes_per_pixel"] = s.raw_bytes_per_pixel;
  d["input_bytes"] = s.input_bytes;
  d["output_bytes"] = s.output_bytes;
  d["band_rows"] = s.band_rows;
  py::dict result;
  result["out"] = options.out;
  result["summary"] = d;
  return make_result("Compressed", result);
}

py::object render(const py::object& input, const py::object& light, const py::object& env,
                  double rotate, bool bright_sources, const py::object& out,
                  const py::object& progress) {
  jobs::RenderOptions options;
  options.input = to_path(input);
  if (!light.is_none()) options.light = to_numbers(light);
  options.environment = to_optional_path(env);
  options.rotation_deg = rotate;
  options.bright_sources = bright_sources;
  std::unique_ptr<TempDir> temp;
  if (out.is_none()) temp = std::make_unique<TempDir>();
  options.out = temp ? temp->path() / "render.exr" : to_path(out);
  jobs::RenderSummary s;
  auto image = std::make_shared<Image>();
  run_job(progress, [&](const JobContext&) {
    s = jobs::render_compact(options);
    *image = read_image(options.out);
  });
  py::dict d;
  d["representation"] = s.representation;
  d["width"] = s.width, d["height"] = s.height;
  d["sources"] = s.sources;
  py::dict result;
  result["image"] = image_view(image, "rendered image");
  result["out"] = temp ? py::none() : py::cast(options.out);
  result["summary"] = d;
  return make_result("Rendered", result);
}

// --- normals ---

py::object normals(const py::object& field, const py::object& out, const std::string& method,
                   const py::object& memory, const py::object& progress) {
  jobs::NormalsJobOptions options;
  options.field_file = to_optional_path(field);
  std::unique_ptr<TempDir> temp;
  if (out.is_none()) temp = std::make_unique<TempDir>();
  options.out = temp ? temp->path() / "normals.exr" : to_path(out);
  options.method = method;
  options.memory = to_memory(memory);
  jobs::NormalsJobSummary s;
  auto image = std::make_shared<Image>();
  run_job(progress, [&](const JobContext& job) {
    s = jobs::estimate_normals(options, job.progress);
    *image = read_named_channels(options.out, jobs::normals_channel_names(), "normals",
                                 "'lightstage normals'", /*exact=*/true)
                 .image;
  });
  py::dict d;
  d["width"] = s.width, d["height"] = s.height;
  d["flagged_pixels"] = s.flagged_pixels;
  d["empty_pixels"] = s.empty_pixels;
  d["noise_source"] = s.noise_source;
  d["seconds"] = s.seconds;
  d["band_rows"] = s.band_rows;
  py::dict result;
  result["maps"] = named_views(image, "normals");
  result["out"] = temp ? py::none() : py::cast(options.out);
  result["summary"] = d;
  return make_result("Normals", result);
}

}  // namespace

void bind_more_jobs(py::module_& m) {
  m.def("capture", &capture, py::arg("stage") = py::none(), py::arg("scene") = py::none(),
        py::kw_only(), py::arg("out"), py::arg("resume") = false, py::arg("seed") = 1,
        py::arg("verify_frames") = true, py::arg("exposures_from") = py::none(),
        py::arg("progress") = py::none());
  m.def("import_set", &import_set, py::arg("source"), py::kw_only(), py::arg("out"),
        py::arg("linear") = false, py::arg("srgb") = false, py::arg("gamma") = py::none(),
        py::arg("max_size") = 0, py::arg("drop_saturated") = false, py::arg("keep_all") = false,
        py::arg("circles") = std::vector<std::array<double, 3>>{}, py::arg("sphere_radius") = 0.0,
        py::arg("focal_length_px") = 0.0, py::arg("stage") = py::none(), py::arg("time") = 0.0,
        py::arg("storage") = "auto", py::arg("memory") = py::none(),
        py::arg("progress") = py::none());
  m.def("compress", &compress, py::arg("input"), py::kw_only(), py::arg("out"),
        py::arg("format") = "pca", py::arg("rank") = "auto", py::arg("tile") = 0,
        py::arg("gain") = 0.0, py::arg("encoding") = "", py::arg("memory") = py::none(),
        py::arg("progress") = py::none());
  m.def("render", &render, py::arg("input"), py::kw_only(), py::arg("light") = py::none(),
        py::arg("env") = py::none(), py::arg("rotate") = 0.0, py::arg("bright_sources") = true,
        py::arg("out") = py::none(), py::arg("progress") = py::none());
  m.def("normals", &normals, py::arg("field"), py::kw_only(), py::arg("out") = py::none(),
        py::arg("method") = "robust", py::arg("memory") = py::none(),
        py::arg("progress") = py::none());
}

}  // namespace ls::python
