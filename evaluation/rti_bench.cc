// `lightstage bench rti` (evaluation/rti_bench.h).
#include "evaluation/rti_bench.h"

#include <algorithm>
#include <fstream>
#include <map>

#include "capture/olat_import.h"
#include "evaluation/chart.h"
#include "evaluation/csv_table.h"
#include "lightstage/errors.h"
#include "relight/compact/pca_field.h"
#include "relight/compact/plane_field.h"
#include "relight/compact/rti_io.h"
#include "sim/noisy_field.h"
#include "sim/rti_scenes.h"

namespace ls::evaluation {

namespace fs = std::filesystem;

const std::vector<ReferenceFigure>& relight_loewenkopf_figures() {
  static const std::vector<ReferenceFigure> figures = {{"relight ptm", 27.00, 0},
                                                       {"relight hsh3", 28.37, 0},
                                                       {"relight bilinear 9", 28.32, 0},
                                                       {"relight rbf 9", 28.29, 100e3},
                                                       {"relight rbf 27", 30.47, 151e3}};
  return figures;
}

std::string RtiBenchOptions::validate() const { return out.empty() ? "bench rti: --out" : ""; }

namespace {

struct Format {
  std::string family;
  // Builds the format from the training lights, through its stored bytes; the bytes per scene.
  std::function<std::unique_ptr<relight::CompactField>(const capture::ReflectanceField&, double&)>
      build;
};

// `.ptm`/`.rti`: fitted in sRGB codes, quantised, encoded and decoded.
Format rti_format(relight::RtiBasis basis, bool lrgb, double gain) {
  return {basis == relight::RtiBasis::kPtm ? "ptm" : "hsh",
          [=](const capture::ReflectanceField& f, double& bytes) {
            relight::RtiFitOptions options;
            options.basis = basis;
            options.lrgb = lrgb;
            options.srgb_gain = gain;
            const std::string encoded =
                relight::encode_rti_file(relight::quantise(relight::RtiField::fit(f, options)));
            bytes = double(encoded.size());
            auto read = std::make_unique<relight::RtiField>(
                relight::dequantise(relight::decode_rti_file(encoded, "bench")));
            // A .ptm cannot hold its gain (it reads back in display units): the user knows it.
            read->set_display_gain(gain);
            return read;
          }};
}

// OpenLIME's folder, written and read back.
Format plane_format(relight::PlaneInterpolation interpolation, int planes, double gain,
                    const fs::path& scratch, const std::string& image_format = "jpg") {
  return {std::string(relight::to_string(interpolation)) + " " + image_format,
          [=](const capture::ReflectanceField& f, double& bytes) {
            relight::PlaneFieldOptions options;
            options.interpolation = interpolation;
            options.planes = planes;
            options.gain = gain;
            const fs::path folder =
                scratch / (std::string(relight::to_string(interpolation)) + std::to_string(planes));
            auto field = std::make_unique<relight::PlaneField>(relight::write_openlime(
                folder, relight::PlaneField::build(f, options), image_format));
            fs::remove_all(folder);
            bytes = double(field->stored_bytes);
            return field;
          }};
}

// The lightstage PCA file (float32 coefficients, linear).
Format pca_format(int rank, const fs::path& scratch) {
  return {"pca (float32)", [=](const capture::ReflectanceField& f, double& bytes) {
            relight::PcaOptions options;
            options.rank = rank;
            const fs::path file = scratch / "field.lspca";
            relight::PcaField::build(f, options).write(file);
            bytes = double(fs::file_size(file));
            auto field = std::make_unique<relight::PcaField>(relight::PcaField::read(file));
            fs::remove(file);
            return field;
          }};
}

std::vector<Format> formats(double gain, bool quick, const fs::path& scratch) {
  using relight::PlaneInterpolation;
  using relight::RtiBasis;
  std::vector<Format> out = {
      rti_format(RtiBasis::kPtm, true, gain), rti_format(RtiBasis::kPtm, false, gain),
      rti_format(RtiBasis::kHsh2, false, gain), rti_format(RtiBasis::kHsh3, false, gain)};
  if (!quick) out.push_back(rti_format(RtiBasis::kHsh4, false, gain));
  for (const int planes : quick ? std::vector<int>{9} : std::vector<int>{6, 9, 12, 18, 27}) {
    out.push_back(plane_format(PlaneInterpolation::kRbf, planes, gain, scratch));
    out.push_back(plane_format(PlaneInterpolation::kBilinear, planes, gain, scratch));
    out.push_back(plane_format(PlaneInterpolation::kBilinear, planes, gain, scratch, "png"));
  }
  for (const int rank : quick ? std::vector<int>{4} : std::vector<int>{2, 4, 8}) {
    out.push_back(pca_format(rank, scratch));
  }
  return out;
}

// The planes of an OpenLIME format's name ("rbf 9 planes png": "9"); empty for the others.
std::string planes_of(const std::string& name) {
  const size_t at = name.find(" planes");
  if (at == std::string::npos) return {};
  const size_t from = name.rfind(' ', at - 1);
  return name.substr(from + 1, at - from - 1);
}

void write_rti_csv(const fs::path& path, const std::vector<RtiBenchRow>& rows) {
  std::ofstream csv(path);
  if (!csv) throw InputError(path.string() + ": cannot write");
  csv << "scene,family,format,planes,bytes,kib,psnr_srgb8_db,psnr_linear_db,held_out\n";
  for (size_t i = 0; i < rows.size(); ++i) {
    const RtiBenchRow& r = rows[i];
    csv << csv_field(r.scene) << ',' << csv_field(r.family) << ',' << csv_field(r.name) << ','
        << planes_of(r.name) << ',' << r.bytes << ',' << r.bytes / 1024 << ','
        << r.result.psnr_srgb8_db << ',' << r.result.psnr_db << ',' << r.result.held_out << '\n';
    if (!r.scene.starts_with("real") || (i + 1 < rows.size() && rows[i + 1].scene == r.scene)) {
      continue;
    }
    // After the real set's rows: relight's figures on it (no size when it gave none).
    for (const ReferenceFigure& f : relight_loewenkopf_figures()) {
      csv << csv_field(r.scene) << ",relight's figures," << f.name << ",,";
      if (f.bytes > 0) {
        csv << f.bytes << ',' << f.bytes / 1024;
      } else {
        csv << ',';
      }
      csv << ',' << f.psnr_db << ",,\n";
    }
  }
}

}  // namespace

void write_rti_charts(const fs::path& csv) {
  const CsvTable table = CsvTable::read(csv);
  const std::vector<std::string> families = table.distinct("family");
  for (const std::string& scene : table.distinct("scene")) {
    std::vector<ChartSeries> series = series_by("family", families);
    for (ChartSeries& s : series) {
      s.where.push_back({"scene", scene});
      // The planes' formats named by their planes (the family is in the legend).
      const bool planes = s.title.starts_with("rbf") || s.title.starts_with("bilinear");
      s.labels = planes ? ChartLabels{.column = "planes", .format = "%g"}
                        : ChartLabels{.column = "format"};
    }
    const std::string stem = scene.substr(0, scene.find(' '));
    write_chart(fs::path(csv).replace_filename("rti_" + stem + "_psnr_vs_bytes.png"),
                {.csv = csv,
                 .x = "kib",
                 .y = "psnr_srgb8_db",
                 .series = series,
                 .title = "RTI formats, " + scene +
                          ": held-out 8-bit sRGB PSNR vs stored size (labels: planes, names)",
                 .x_label = "KiB per scene (as stored)",
                 .y_label = "8-bit sRGB PSNR on held-out lights, dB",
                 .log_x = true});
  }
}

RtiBenchSummary run_rti_bench(const RtiBenchOptions& options, const ProgressFn& progress) {
  throw_if_invalid(options.validate());
  fs::create_directories(options.out);
  RtiBenchSummary summary;
  // Scenes and their display gains: the real set's own codes (gain 1); the simulated scene's
  // brightest sample white.
  std::vector<std::pair<std::string, capture::ReflectanceField>> scenes;
  capture::FieldNoise noise;  // As bench compact: about 1.5% read and 2.5% shot noise.
  noise.read_variance = 1e-5;
  noise.shot_variance_per_unit = 2e-4;
  noise.method = "simulated";
  scenes.emplace_back("glossy (sim)", sim::render_noisy_field(
                                          sim::rti_dome_stage(150, 10.0, options.quick ? 32 : 64),
                                          sim::rti_scene(sim::RtiScene::kGlossy), noise, 7));
  if (!options.quick && !options.real_lp.empty() && fs::exists(options.real_lp)) {
    scenes.emplace_back("real (loewenkopf)", capture::import_rti_lp(options.real_lp, {}));
  } else if (!options.quick) {
    summary.notes.push_back(options.real_lp.string() + " is absent: the simulated scene only");
  }
  const fs::path scratch = options.out / ".rti_bench_scratch";  // Each format's files, a while.
  fs::create_directories(scratch);
  for (const auto& [scene, field] : scenes) {
    const double gain = scene.starts_with("real") ? 1.0 : 1.0 / field.largest_value();
    const std::vector<Format> list = formats(gain, options.quick, scratch);
    LeaveLightsOutOptions leave_out;
    leave_out.display_gain = gain;
    leave_out.min_dir_z = 0.0;  // The RTI formats know the camera's hemisphere only.
    long done = 0;
    for (const Format& format : list) {
      RtiBenchRow row;
      row.scene = scene;
      row.family = format.family;
      row.result = leave_lights_out(
          field, [&](const capture::ReflectanceField& f) { return format.build(f, row.bytes); },
          leave_out);
      // The planes' image format tells JPEG and PNG rows of one type apart.
      row.name = row.result.name + (format.family.ends_with(" png") ? " png" : "");
      summary.rows.push_back(row);
      report(progress, "bench rti", ++done, long(list.size()), scene + " " + row.name);
    }
  }
  fs::remove_all(scratch);
  summary.csv = options.out / "rti.csv";
  write_rti_csv(summary.csv, summary.rows);
  write_rti_charts(summary.csv);
  return summary;
}

}  // namespace ls::evaluation
