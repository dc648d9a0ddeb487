#include "app/jobs/compress_job.h"

#include <charconv>

#include "capture/field.h"
#include "capture/olat_import.h"
#include "lightstage/errors.h"
#include "relight/compact/pca_field.h"
#include "relight/compact/rti_fits.h"
#include "relight/compact/rti_io.h"

namespace ls::jobs {

namespace fs = std::filesystem;

namespace {

// The PCA rank: 0 for "auto", -1 when the text is not a positive integer.
int parse_rank(const std::string& text) {
  if (text == "auto") return 0;
  int rank = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), rank);
  return (error == std::errc() && end == text.data() + text.size() && rank > 0) ? rank : -1;
}

bool rti_basis(const std::string& format, relight::RtiFitOptions& options) {
  options.lrgb = format == "ptm-lrgb";
  if (format == "ptm" || format == "ptm-rgb" || format == "ptm-lrgb") {
    options.basis = relight::RtiBasis::kPtm;
  } else if (format == "hsh2") {
    options.basis = relight::RtiBasis::kHsh2;
  } else if (format == "hsh3") {
    options.basis = relight::RtiBasis::kHsh3;
  } else if (format == "hsh4") {
    options.basis = relight::RtiBasis::kHsh4;
  } else {
    return false;
  }
  return true;
}

}  // namespace

std::string CompressOptions::validate() const {
  relight::RtiFitOptions rti;
  if (format != "pca" && !rti_basis(format, rti)) {
    return "--format: expected pca, ptm, ptm-lrgb, hsh2, hsh3 or hsh4, got \"" + format + "\"";
  }
  if (parse_rank(rank) < 0) {
    return "--rank: expected a positive integer or \"auto\", got \"" + rank + "\"";
  }
  if (tile < 0) return "--tile: expected a tile size in pixels >= 0 (0: one global basis)";
  if (!(gain >= 0 && gain < 1e30)) return "--gain: expected a finite gain >= 0";
  if (input.empty()) return "give the field (or .lp set) to compress";
  if (out.empty()) return "--out: give the output file";
  return {};
}

CompressSummary compress(const CompressOptions& options, const ProgressFn& progress) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    throw InputError("compress: " + problem);
  }
  report(progress, "read", 0, 1, options.input.filename());
  const std::string ext = options.input.extension().string();
  const capture::ReflectanceField field =
      (ext == ".lp" || fs::is_directory(options.input))
          ? capture::import_olat(options.input, capture::OlatImportOptions{})
          : capture::read_field(options.input);
  report(progress, "read", 1, 1);
  CompressSummary summary;
  summary.raw_bytes_per_pixel = 12.0 * field.num_lights();
  if (options.format == "pca") {
    relight::PcaOptions pca_options;
    pca_options.rank = parse_rank(options.rank);
    pca_options.tile_size = options.tile;
    relight::PcaSummary pca_summary;
    const relight::PcaField pca = relight::PcaField::build(field, pca_options, &pca_summary);
    pca.write(options.out);
    summary.representation = pca.name();
    summary.details = pca_summary.to_string();
    summary.bytes_per_pixel = pca.bytes_per_pixel();
    return summary;
  }
  relight::RtiFitOptions rti_options;
  rti_basis(options.format, rti_options);
  const relight::RtiField fit = relight::RtiField::fit(field, rti_options);
  relight::write_rti_file(options.out, relight::quantise(fit, options.gain));
  summary.representation = fit.name();
  summary.details = "from " + std::to_string(fit.lights_used) + " LEDs";
  summary.bytes_per_pixel = fit.bytes_per_pixel();
  return summary;
}

}  // namespace ls::jobs
