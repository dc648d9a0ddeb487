#include "app/jobs/compress_job.h"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <optional>

#include "app/jobs/ranks.h"
#include "capture/field.h"
#include "capture/field_file.h"
#include "capture/olat_import.h"
#include "lightstage/bands.h"
#include "lightstage/checkpoint_dir.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/memory.h"
#include "lightstage/rank_split.h"
#include "lightstage/run_outputs.h"
#include "lightstage/scratch_file.h"
#include "physics/envmap.h"
#include "relight/compact/pca_bands.h"
#include "relight/compact/pca_field.h"
#include "relight/compact/plane_field.h"
#include "relight/compact/rti_fits.h"
#include "relight/compact/rti_io.h"
#include "relight/sources/map_relight.h"

namespace ls::jobs {

namespace fs = std::filesystem;

namespace {

// The PCA rank: 0 for "auto" and "held-out", -1 when the text is not a positive integer.
int parse_rank(const std::string& text) {
  if (text == "auto" || text == "held-out") return 0;
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

// A file beside the output for the job's length only.
struct RemovedWhenDone {
  fs::path path;
  RemovedWhenDone(const RemovedWhenDone&) = delete;
  RemovedWhenDone& operator=(const RemovedWhenDone&) = delete;
  explicit RemovedWhenDone(fs::path p) : path(std::move(p)) {}
  ~RemovedWhenDone() {
    std::error_code ignored;
    fs::remove(path, ignored);
  }
};

bool is_olat_set(const fs::path& input) {
  return input.extension() == ".lp" || fs::is_directory(input);
}

// The field file to read `input` from, an EXR as it is. An .lp set: empty (to be imported whole)
// unless a budget is given or its field takes more than the budget: then
// imported into a field file beside `out` (in bands, see import_olat_to_file), read from there
// and removed when `imported` goes.
fs::path field_file_for(const fs::path& input, const fs::path& out, const MemoryBudget& memory,
                        std::optional<RemovedWhenDone>& imported, const ProgressFn& progress) {
  if (!is_olat_set(input)) return input;
  if (!memory.given()) {
    const capture::ReflectanceField header = capture::olat_header(input, {});
    const std::size_t bytes =
        capture::ReflectanceField::bytes_for(header.width(), header.height(), header.num_lights());
    if (bytes <= memory.bytes()) return {};
  }
  fs::path file = out;
  file += ".imported.exr";
  imported.emplace(file);
  report(progress, "import", 0, 1, input.filename());
  capture::import_olat_to_file(input, capture::OlatImportOptions{}, file, {}, memory);
  report(progress, "import", 1, 1);
  return file;
}

// Where a command's field comes from: whole in memory, or band by band from a field file or
// straight from an .lp set's images. An .lp set is read in bands from its images whatever its
// size: that is faster than importing it whole (bench rti: compress ptm 2.7 s against 6.0 s on
// 612x512x96 JPEGs) and holds --memory of it (unset: MemoryBudget::kImageSetBytes), not the float
// field.
struct FieldRows {
  std::optional<RemovedWhenDone> imported;  // Removed after the stream reading it is closed.
  std::optional<capture::FieldStream> stream;
  std::unique_ptr<capture::OlatBands> images;

  // Opens `input`. An .lp set its images cannot give band by band (capture::OlatBands::open)
  // is imported whole, or into a field file beside `out` when that does not fit.
  FieldRows(const fs::path& input, const fs::path& out, const MemoryBudget& memory,
            const ProgressFn& progress) {
    if (is_olat_set(input)) images = capture::OlatBands::open(input, capture::OlatImportOptions{});
    if (images) return;
    const fs::path file = field_file_for(input, out, memory, imported, progress);
    if (!file.empty()) stream.emplace(file);
  }
  bool in_bands() const { return stream || images; }
  const capture::ReflectanceField& header() const {
    return stream ? stream->header() : images->header();
  }
  int height() const { return header().height(); }
  int row_alignment() const { return stream ? stream->row_alignment() : 1; }
  // The rows of a band for a memory budget (an .lp set's images: unset, kImageSetBytes).
  int band_rows(const MemoryBudget& memory) const {
    if (stream) return stream->band_rows(memory);
    return images->rows_within(memory.bytes_or(MemoryBudget::kImageSetBytes));
  }
  void read_rows(int y0, int y1, capture::ReflectanceField& band) {
    if (stream) {
      stream->read_rows(y0, y1, band);
    } else {
      images->read_rows(y0, y1, band);
    }
  }
};

// The field's bands of `rows` rows, each pass over them showing its progress by rows. Split over
// ranks a rank reads its own bands only (the others visited without values:
// write_rti_file_in_bands leaves them to theirs).
capture::FieldBands split_bands(FieldRows& stream, int rows, const RankSplit& split,
                                const ProgressFn& progress) {
  return [&stream, rows, split, progress, pass = 0](const capture::BandVisitor& visit) mutable {
    const std::string label = "pass " + std::to_string(++pass) + " (rows)";
    const int height = stream.height();
    capture::ReflectanceField band;
    for (int b = 0, y0 = 0; y0 < height; ++b, y0 += rows) {
      const int y1 = std::min(height, y0 + rows);
      if (split.mine(b)) {
        stream.read_rows(y0, y1, band);
        visit(band);
      } else {
        capture::ReflectanceField shell = capture::ReflectanceField::without_values(
            stream.header().width(), y1 - y0, stream.header().lights());
        shell.set_band(y0, height);
        visit(shell);
      }
      report(progress, label, y1, height);
    }
  };
}

}  // namespace

std::string CompressOptions::validate() const {
  relight::RtiFitOptions rti;
  if (format != "pca" && !rti_basis(format, rti)) {
    return "--format: expected pca, ptm, ptm-lrgb, hsh2, hsh3 or hsh4, got \"" + format + "\"";
  }
  if (parse_rank(rank) < 0) {
    return "--rank: expected a positive integer, \"auto\" or \"held-out\", got \"" + rank + "\"";
  }
  if (tile < 0) return "--tile: expected a tile size in pixels >= 0 (0: one global basis)";
  if (format != "pca" && rank != CompressOptions{}.rank) {
    return "--rank " + rank + ": for --format pca only (an RTI basis has its own size)";
  }
  if (format != "pca" && tile != 0) return "--tile: for --format pca only";
  // A name that says another format misleads every reader that goes by it (render reads what is
  // not .ptm or .rti as PCA; an .exr is taken for a field or an image).
  const std::string wanted = format == "pca"             ? ".lspca"
                             : format.starts_with("ptm") ? ".ptm"
                                                         : ".rti";
  const std::string named = out.extension().string();
  const bool pca_name = named == ".lspca" || named == ".pca";
  const bool other_format = named == ".ptm" || named == ".rti" || pca_name || named == ".exr" ||
                            named == ".png" || named == ".jpg" || named == ".hdr";
  if (other_format && named != wanted && !(format == "pca" && pca_name)) {
    return "--out " + out.string() + ": --format " + format + " writes a " + wanted +
           " file, not a " + named + " (viewers and render tell the formats apart by the name)";
  }
  if (!(gain >= 0 && gain < 1e30)) return "--gain: expected a finite gain >= 0";
  if (!encoding.empty() && encoding != "srgb" && encoding != "linear") {
    return "--encoding: expected srgb or linear, got \"" + encoding + "\"";
  }
  if (!encoding.empty() && format == "pca") {
    return "--encoding " + encoding +
           ": for RTI files (.ptm, .rti) only; a PCA file holds the field's linear values";
  }
  if (encoding == "linear" && format.starts_with("ptm")) {
    return "--encoding linear: a .ptm has no room to say its values are linear, and every viewer "
           "shows them as sRGB; use --format hsh2|hsh3|hsh4 for a linear file";
  }
  if (input.empty()) return "give the field (or .lp set) to compress";
  if (out.empty()) return "--out: give the output file";
  return {};
}

std::string CompressOptions::to_json() const {
  return nlohmann::json{{"input", input.string()},
                        {"format", format},
                        {"rank", rank},
                        {"tile", tile},
                        {"gain", gain},
                        {"encoding", encoding},
                        {"memory_bytes", memory.given_bytes()}}
      .dump();
}

// Bytes of the input on disk: an EXR's file, or the images an .lp set lists.
std::uintmax_t input_bytes(const fs::path& input) {
  if (!fs::is_directory(input) && input.extension() != ".lp") return fs::file_size(input);
  return capture::olat_image_bytes(input);
}

namespace {

// Display-referred files need their gain before the fit: by default the brightest sample becomes
// white. From the field in memory, or a pass over the file in bands (rank 0's, shared).
double white_gain(FieldRows* stream, int rows, const capture::ReflectanceField& whole,
                  const Ranks& ranks) {
  std::vector<double> brightest = {0.0};
  if (!stream) {
    brightest[0] = whole.largest_value();
  } else if (ranks.root()) {
    const int height = stream->height();  // In the bands' rows: within --memory.
    capture::ReflectanceField band;
    for (int y0 = 0; y0 < height; y0 += rows) {
      stream->read_rows(y0, std::min(height, y0 + rows), band);
      brightest[0] = std::max(brightest[0], double(band.largest_value()));
    }
  }
  ranks.broadcast(brightest);
  return brightest[0] > 0 ? 1.0 / brightest[0] : 1.0;
}

// The largest PCA rank whose file is no larger than `input_bytes`; at least 1.
int rank_within(std::uintmax_t input_bytes, const capture::ReflectanceField& header, int tile) {
  const int lights = header.num_lights();
  const double per_rank =
      relight::PcaField::data_bytes(header.width(), header.height(), lights, 1, tile);
  return std::max(1,
                  int((double(input_bytes) - relight::PcaField::header_bytes(lights)) / per_rank));
}

}  // namespace

CompressSummary compress(const CompressOptions& options, const ProgressFn& progress) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    throw InputError("compress: " + problem);
  }
  refuse_output_over_input(options.out, options.input);
  relight::PcaOptions pca_options;
  pca_options.rank = parse_rank(options.rank);
  pca_options.tile_size = options.tile;
  if (options.rank == "held-out") pca_options.rank_rule = relight::PcaRankRule::kHeldOutLights;
  // The field whole, or in bands of rows when it is larger than the memory for it (whole PCA
  // tiles or Gram sub-bands per band: the same bytes as in memory): of a field EXR, or of an .lp
  // set's images.
  const std::string ext = options.input.extension().string();
  // Under MPI a field's bands are split over the ranks (an .lp set is read by one process).
  const Ranks& ranks = Ranks::world();
  if (ranks.size() > 1 && (ext == ".lp" || fs::is_directory(options.input))) {
    throw InputError(
        "compress: under MPI only a field EXR splits its bands over the ranks; "
        "compress .lp sets as one process (without mpirun), or import them first");
  }
  const RankSplit split = ranks.split();
  capture::ReflectanceField whole;
  std::optional<CheckpointDir> checkpoint;
  capture::FieldBands bands;
  int rows = 0;
  FieldRows stream(options.input, options.out, options.memory, progress);
  if (!stream.in_bands()) {
    report(progress, "read", 0, 1, options.input.filename());
    whole = capture::import_olat(options.input, capture::OlatImportOptions{});
    report(progress, "read", 1, 1);
  } else {
    const int height = stream.height();
    const int align =
        options.format == "pca"
            ? std::lcm(stream.row_alignment(), relight::PcaField::band_alignment(
                                                   stream.header().width(), height, pca_options))
            : stream.row_alignment();
    rows = band_rows_for_ranks(std::max(align, stream.band_rows(options.memory) / align * align),
                               height, align, split.size);
    if (rows < height || split.split()) {
      // What a compression in bands finished is kept beside the output for a killed run to
      // resume from (with the band height it was done in): the RTI fits' coefficients, or the
      // PCA's basis and coefficients. Rank 0 decides the band height before the others read it.
      checkpoint.emplace(options.out, input_identity(options.input, options.to_json()));
      rows = agreed_band_rows(*checkpoint, rows, split);
    }
    if (rows >= height && !split.split()) {
      report(progress, "read", 0, 1, options.input.filename());
      stream.read_rows(0, height, whole);
      report(progress, "read", 1, 1);
    } else {
      bands = split_bands(stream, rows, split, progress);
    }
  }
  const capture::ReflectanceField& header = bands ? stream.header() : whole;
  if (!bands) bands = capture::whole_field(whole), rows = 0;
  CompressSummary summary;
  summary.raw_bytes_per_pixel = 12.0 * header.num_lights();
  summary.input_bytes = input_bytes(options.input);
  summary.band_rows = rows;
  if (options.format == "pca") {
    // A compression's default never writes more than it was given: the automatic rank is held
    // to what the input's bytes hold.
    const int within_input = rank_within(summary.input_bytes, header, options.tile);
    if (pca_options.rank == 0) {
      pca_options.max_rank = std::min(pca_options.max_rank, within_input);
    }
    relight::PcaSummary pca_summary;
    relight::PcaField pca;
    if (rows > 0) {
      const relight::PcaBandsInput input{
          header,
          [&](int y0, int y1, capture::ReflectanceField& band) { stream.read_rows(y0, y1, band); },
          bands, rows};
      pca = relight::pca_in_bands(input, pca_options, *checkpoint, options.out, split, pca_summary,
                                  summary.resumed_rows, progress);
      summary.ranks = ranks.size();
      if (!ranks.root()) return summary;  // Rank 0 wrote the file.
      checkpoint->remove();
    } else {
      pca = relight::PcaField::build(header, bands, pca_options, &pca_summary);
      pca.write(options.out);
    }
    summary.representation = pca.name();
    summary.details = pca_summary.to_string();
    if (pca_options.rank > pca.rank()) {
      summary.warnings.push_back("--rank " + options.rank +
                                 ": more than this field allows (its usable lights); rank " +
                                 std::to_string(pca.rank()) + " used");
    }
    // The cap bound the choice when it took the largest rank allowed, or when the held-out error
    // was still falling there.
    const bool best_at_cap = pca_summary.held_out_best_rank() == within_input;
    const std::string cap = std::to_string(within_input) +
                            ", the largest rank whose file is no larger than the input (" +
                            std::to_string(summary.input_bytes >> 10) + " KiB)";
    if (pca_options.rank == 0 && pca.rank() == within_input) {
      summary.warnings.push_back("--rank " + options.rank + ": held at " + cap +
                                 ", which the automatic choice reached; --rank N gives a larger, "
                                 "closer file");
    } else if (pca_options.rank == 0 && best_at_cap) {
      summary.warnings.push_back("--rank held-out: ranks tried up to " + cap +
                                 "; the held-out error still fell there, so --rank N above it "
                                 "relights closer in a larger file");
    }
    summary.bytes_per_pixel = pca.bytes_per_pixel();
    summary.output_bytes = fs::file_size(options.out);
    return summary;
  }
  relight::RtiFitOptions rti_options;
  rti_basis(options.format, rti_options);
  if (options.encoding != "linear") {
    rti_options.srgb_gain = options.gain > 0
                                ? options.gain
                                : white_gain(rows > 0 ? &stream : nullptr, rows, whole, ranks);
  }
  relight::RtiWritten written;
  if (rows > 0) {  // In bands: the coefficients through a file, not held.
    written = relight::write_rti_file_in_bands(options.out, header, bands, rti_options,
                                               options.gain, checkpoint->dir(), split);
    summary.ranks = split.size;
    if (split.rank != 0) return summary;  // Rank 0 wrote the file.
    checkpoint->remove();
  } else {
    const relight::RtiField fit = relight::RtiField::fit(header, bands, rti_options);
    relight::write_rti_file(options.out, relight::quantise(fit, options.gain));
    written = {fit.name(), fit.lights_used, fit.bytes_per_pixel()};
  }
  summary.representation = written.name;
  summary.details = "from " + std::to_string(written.lights_used) + " LEDs";
  summary.bytes_per_pixel = written.bytes_per_pixel;
  summary.output_bytes = fs::file_size(options.out);
  summary.resumed_rows = written.resumed_rows;
  return summary;
}

std::string OpenLimeExportOptions::validate() const {
  if (type != "rbf" && type != "bilinear") {
    return "--type: expected rbf or bilinear (OpenLIME's types), got \"" + type + "\"";
  }
  if (planes != 0 && (planes < 3 || planes % 3 != 0)) {
    return "--planes: expected a positive multiple of 3 (OpenLIME reads three to an image), or 0 "
           "(the fewest the data needs), got " +
           std::to_string(planes);
  }
  if (image != "jpg" && image != "png") {
    return "--image: expected jpg or png, got \"" + image + "\"";
  }
  if (quality < 1 || quality > 100) return "--quality: expected a JPEG quality in 1..100";
  if (image == "png" && quality != OpenLimeExportOptions{}.quality) {
    return "--quality: for --image jpg only (PNG planes are lossless)";
  }
  if (!(gain >= 0 && gain < 1e30)) return "--gain: expected a finite gain >= 0";
  if (input.empty()) return "give the field (or .lp set) to export";
  if (out.empty()) return "--out: give the folder to write";
  return {};
}

OpenLimeExportSummary export_openlime(const OpenLimeExportOptions& options,
                                      const ProgressFn& progress) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    throw InputError("export openlime: " + problem);
  }
  // The field whole, or within --memory in bands (three passes).
  FieldRows stream(options.input, options.out, options.memory, progress);
  capture::ReflectanceField whole;
  capture::FieldBands bands;
  const int rows = stream.in_bands() ? stream.band_rows(options.memory) : 0;
  if (stream.in_bands() && rows < stream.height()) {
    bands = [&, pass = 0](const capture::BandVisitor& visit) mutable {
      const std::string label = "pass " + std::to_string(++pass) + " (rows)";
      capture::ReflectanceField band;
      for (int y0 = 0; y0 < stream.height(); y0 += rows) {
        const int y1 = std::min(stream.height(), y0 + rows);
        stream.read_rows(y0, y1, band);
        visit(band);
        report(progress, label, y1, stream.height());
      }
    };
  } else {
    report(progress, "read", 0, 1, options.input.filename());
    if (stream.in_bands()) {
      stream.read_rows(0, stream.height(), whole);
    } else {
      whole = capture::import_olat(options.input, capture::OlatImportOptions{});
    }
    report(progress, "read", 1, 1);
    bands = capture::whole_field(whole);
  }
  const capture::ReflectanceField& field = stream.in_bands() ? stream.header() : whole;
  relight::PlaneFieldOptions plane_options;
  plane_options.interpolation = options.type == "rbf" ? relight::PlaneInterpolation::kRbf
                                                      : relight::PlaneInterpolation::kBilinear;
  plane_options.planes = options.planes;
  plane_options.gain = options.gain;
  report(progress, "planes", 0, 1, options.planes == 0 ? "choosing from the data" : "");
  const relight::PlaneField built = relight::PlaneField::build(field, bands, plane_options);
  report(progress, "planes", 1, 1);
  const relight::PlaneField written =
      relight::write_openlime(options.out, built, options.image, options.quality);
  OpenLimeExportSummary summary;
  summary.representation = written.name();
  char chosen[64];
  if (written.interpolation == relight::PlaneInterpolation::kRbf) {
    std::snprintf(chosen, sizeof chosen, "sigma %.3g", written.sigma);
  } else {
    std::snprintf(chosen, sizeof chosen, "grid %dx%d", written.resolution, written.resolution);
  }
  summary.chosen = chosen;
  summary.width = written.width();
  summary.height = written.height();
  summary.lights = field.num_lights();
  summary.band_rows = stream.in_bands() && rows < stream.height() ? rows : 0;
  summary.input_bytes = input_bytes(options.input);
  summary.output_bytes = written.stored_bytes;
  return summary;
}

std::string RenderOptions::validate() const {
  if (input.empty()) {
    return shape.empty() ? "a compact file (.ptm, .rti, PCA or an OpenLIME folder) is required"
                         : "the model maps (lightstage fit's MAPS.exr) are required";
  }
  if (!shape.empty()) {
    if (!(tiles > 0) || !std::isfinite(tiles) || tiles > 1e4) {
      return "--tiles: expected a positive number of repeats (at most 10000)";
    }
    if (resolution < 1 || resolution > 16384) return "--resolution: expected 1 to 16384 pixels";
  }
  if (out.extension() != ".exr") {
    return "--out: the render is an OpenEXR file (linear): give a path ending in .exr, got \"" +
           out.string() + "\"";
  }
  if (light.empty() == environment.empty()) return "give either --light X Y Z or --env MAP";
  if (!light.empty()) {
    if (light.size() != 3) return "--light: expected X Y Z";
    const Eigen::Vector3d dir(light[0], light[1], light[2]);
    if (!dir.allFinite() || !(dir.norm() > 0)) return "--light: expected a non-zero direction";
  }
  if (std::string problem = rotation_problem(rotation_deg); !problem.empty()) return problem;
  if (!light.empty() && rotation_deg != 0)
    return "--rotate: turns an --env map; a --light has none";
  return {};
}

namespace {

// Why a point light at `light` is extrapolated from the PCA's lights: farther from every one of
// them than any is from its nearest neighbour (outside the dome's coverage); empty when it is not.
std::string beyond_the_lights(const Eigen::Vector3d& light, const relight::PcaField& pca) {
  std::vector<Eigen::Vector3d> dirs;
  for (const capture::FieldLight& l : pca.lights()) {
    if (l.valid) dirs.push_back(l.dir_in_stage.normalized());
  }
  if (dirs.size() < 2) return {};
  const auto angle = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return std::atan2(a.cross(b).norm(), a.dot(b));
  };
  double widest_gap = 0, nearest = M_PI;
  for (size_t i = 0; i < dirs.size(); ++i) {
    double own = M_PI;
    for (size_t j = 0; j < dirs.size(); ++j) {
      if (j != i) own = std::min(own, angle(dirs[i], dirs[j]));
    }
    widest_gap = std::max(widest_gap, own);
    nearest = std::min(nearest, angle(light, dirs[i]));
  }
  if (nearest <= widest_gap) return {};
  char text[200];
  std::snprintf(text, sizeof text,
                "extrapolated beyond the captured lights: the nearest is %.1f degrees away (they "
                "are at most %.1f degrees apart); the image is a guess",
                nearest * 180 / M_PI, widest_gap * 180 / M_PI);
  return text;
}

}  // namespace

RenderSummary render_compact(const RenderOptions& options) {
  if (const std::string problem = options.validate(); !problem.empty()) {
    throw InputError("render: " + problem);
  }
  const std::string ext = options.input.extension().string();
  std::unique_ptr<relight::CompactField> field;
  if (fs::is_directory(options.input) || options.input.filename() == "info.json") {
    field = std::make_unique<relight::PlaneField>(relight::read_openlime(
        fs::is_directory(options.input) ? options.input : options.input.parent_path()));
  } else if (ext == ".ptm" || ext == ".rti") {
    field = std::make_unique<relight::RtiField>(
        relight::dequantise(relight::read_rti_file(options.input)));
  } else {
    field = std::make_unique<relight::PcaField>(relight::PcaField::read(options.input));
  }
  RenderSummary summary{field->name(), field->width(), field->height(), {}};
  Image image;
  const auto* pca = dynamic_cast<const relight::PcaField*>(field.get());
  if (options.environment.empty()) {
    const Eigen::Vector3d light =
        Eigen::Vector3d(options.light[0], options.light[1], options.light[2]).normalized();
    if (pca) {
      if (std::string beyond = beyond_the_lights(light, *pca); !beyond.empty()) {
        summary.warnings.push_back(options.input.string() + ": --light: " + beyond);
      }
    } else if (!(light.z() > 0)) {
      // An RTI basis is fitted to lights in front of the object only: behind, its polynomial is
      // made up.
      throw InputError(options.input.string() + ": --light: a light with z <= 0 is behind the " +
                       "object (the camera is on +Z); a " + field->name() +
                       " basis is fitted on the hemisphere toward the camera: give a light with "
                       "z > 0");
    }
    image = field->relight_point(light);
  } else {
    const physics::EnvironmentMap map = physics::EnvironmentMap::load(options.environment);
    // A PCA under a map with a bright source the dome covers: the rest by LED cells, each source
    // at its direction (shadows from the reconstruction's shape where it agrees with the LEDs).
    if (pca && options.bright_sources) {
      relight::MapRelighter relighter(*pca);
      const relight::SplitLighting lighting = relighter.lighting(map, options.rotation_deg);
      if (relight::MapRelighter::renders_sources(lighting)) {
        relighter.render(lighting, image);
        summary.sources = lighting.report();
      }
    }
    if (image.pixels.empty()) {
      image = field->relight(relight::LightingForModels::environment(map, options.rotation_deg));
    }
  }
  write_exr(options.out, image);
  fs::path png = options.out;
  png.replace_extension(".png");
  summary.preview_stops = auto_exposure_stops(image);
  write_png_preview(png, image, summary.preview_stops);
  return summary;
}

}  // namespace ls::jobs
