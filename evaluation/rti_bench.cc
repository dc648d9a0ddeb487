// `lightstage bench rti` (evaluation/rti_bench.h).
#include "evaluation/rti_bench.h"

#include <algorithm>
#include <fstream>
#include <map>

#include "capture/olat_import.h"
#include "evaluation/chart.h"
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

void write_chart_of(const fs::path& out, const std::string& scene,
                    const std::vector<const RtiBenchRow*>& rows) {
  std::map<std::string, ChartSeries> series;
  for (const RtiBenchRow* r : rows) {
    ChartSeries& s = series[r->family];
    s.name = r->family;
    s.x.push_back(r->bytes / 1024);
    s.y.push_back(r->result.psnr_srgb8_db);
    s.point_labels.push_back(r->name);
  }
  std::vector<ChartSeries> all;
  all.reserve(series.size() + 1);
  for (auto& [_, s] : series) all.push_back(s);
  if (scene.starts_with("real")) {
    ChartSeries relight{"relight (issue 18's figures)", {}, {}, {}, false};
    for (const ReferenceFigure& f : relight_loewenkopf_figures()) {
      if (f.bytes <= 0) continue;
      relight.x.push_back(f.bytes / 1024);
      relight.y.push_back(f.psnr_db);
      relight.point_labels.push_back(f.name);
    }
    all.push_back(relight);
  }
  const std::string stem = scene.substr(0, scene.find(' '));
  write_chart(out / ("rti_" + stem + "_psnr_vs_bytes.png"),
              {"RTI formats, " + scene + ": held-out 8-bit sRGB PSNR vs stored size",
               "KiB per scene (as stored)", "8-bit sRGB PSNR on held-out lights, dB", true},
              all);
}

}  // namespace

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
    std::vector<const RtiBenchRow*> rows;
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
    for (const RtiBenchRow& r : summary.rows) {
      if (r.scene == scene) rows.push_back(&r);
    }
    write_chart_of(options.out, scene, rows);
  }
  fs::remove_all(scratch);
  summary.csv = options.out / "rti.csv";
  std::ofstream csv(summary.csv);
  if (!csv) throw InputError(summary.csv.string() + ": cannot write");
  csv << "scene,format,bytes,psnr_srgb8_db,psnr_linear_db,held_out\n";
  for (const RtiBenchRow& r : summary.rows) {
    csv << '"' << r.scene << "\",\"" << r.name << "\"," << r.bytes << ',' << r.result.psnr_srgb8_db
        << ',' << r.result.psnr_db << ',' << r.result.held_out << '\n';
  }
  return summary;
}

}  // namespace ls::evaluation
