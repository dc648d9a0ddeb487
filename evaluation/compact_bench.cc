#include "evaluation/compact_bench.h"

#include <chrono>
#include <fstream>
#include <map>
#include <utility>

#include "capture/olat_import.h"
#include "evaluation/chart.h"
#include "evaluation/csv_table.h"
#include "lightstage/errors.h"
#include "relight/compact/pca_field.h"
#include "relight/compact/rti_fits.h"
#include "relight/fit/fit.h"
#include "relight/fit/model_render.h"
#include "relight/lighting/light_cells.h"
#include "sim/noisy_field.h"
#include "sim/rti_scenes.h"

namespace ls::evaluation {

namespace fs = std::filesystem;

std::string CompactBenchOptions::validate() const {
  if (repeats < 1)
    return "bench compact: repeats: expected at least 1, got " + std::to_string(repeats);
  if (environment_map.empty()) return "bench compact: environment_map: expected a map file";
  return {};
}

namespace {

struct Candidate {
  std::string family;  // Chart series.
  CompactBuilder build;
  bool automatic = false;  // The software's own choice (PCA, automatic rank).
};

CompactBuilder pca(int rank, int tile,
                   relight::PcaRankRule rule = relight::PcaRankRule::kNoiseFloor) {
  return [=](const capture::ReflectanceField& f) {
    relight::PcaOptions options;
    options.rank = rank;
    options.tile_size = tile;
    options.rank_rule = rule;
    return std::unique_ptr<relight::CompactField>(
        new relight::PcaField(relight::PcaField::build(f, options)));
  };
}

CompactBuilder rti(relight::RtiBasis basis, bool lrgb) {
  return [=](const capture::ReflectanceField& f) {
    relight::RtiFitOptions options;
    options.basis = basis;
    options.lrgb = lrgb;
    return std::unique_ptr<relight::CompactField>(
        new relight::RtiField(relight::RtiField::fit(f, options)));
  };
}

std::vector<Candidate> candidates(bool quick) {
  std::vector<Candidate> out;
  out.push_back({"raw", [](const capture::ReflectanceField& f) {
                   return std::unique_ptr<relight::CompactField>(
                       new relight::RawCompactField(capture::ReflectanceField(f)));
                 }});
  for (int k : {2, 4, 8, 16, 32, 64}) {
    out.push_back({"pca global", pca(k, 0)});
    out.push_back({"pca 16px tiles", pca(k, 16)});
  }
  out.push_back({"pca auto (noise floor)", pca(0, 0), true});
  out.push_back(
      {"pca auto (held-out LEDs)", pca(0, 0, relight::PcaRankRule::kHeldOutLights), true});
  out.push_back(
      {"pca auto (held-out LEDs)", pca(0, 16, relight::PcaRankRule::kHeldOutLights), true});
  out.push_back({"ptm", rti(relight::RtiBasis::kPtm, false)});
  out.push_back({"ptm", rti(relight::RtiBasis::kPtm, true)});
  for (auto b : {relight::RtiBasis::kHsh2, relight::RtiBasis::kHsh3, relight::RtiBasis::kHsh4}) {
    out.push_back({"hsh", rti(b, false)});
  }
  if (!quick) {
    out.push_back({"models", [](const capture::ReflectanceField& f) {
                     relight::FitOptions options;
                     options.use_noise_of(f);
                     return std::unique_ptr<relight::CompactField>(
                         new relight::ModelCompactField(relight::fit_models(f, options)));
                   }});
  }
  return out;
}

// The simulated RTI scenes, and the real set when it is there.
std::vector<std::pair<std::string, capture::ReflectanceField>> scenes(
    const CompactBenchOptions& options, std::vector<std::string>& notes) {
  std::vector<std::pair<std::string, capture::ReflectanceField>> out;
  const int resolution = options.quick ? 32 : 64;
  capture::FieldNoise noise;  // As tests/compact: about 1.5% read and 2.5% shot noise.
  noise.read_variance = 1e-5;
  noise.shot_variance_per_unit = 2e-4;
  noise.method = "simulated";
  for (auto s : {sim::RtiScene::kMatte, sim::RtiScene::kGlossy, sim::RtiScene::kShadowed}) {
    out.emplace_back(sim::to_string(s),
                     sim::render_noisy_field(sim::rti_dome_stage(150, 10.0, resolution),
                                             sim::rti_scene(s), noise, 7));
  }
  if (!options.real_lp.empty() && fs::exists(options.real_lp)) {
    out.emplace_back("real (loewenkopf)", capture::import_rti_lp(options.real_lp, {}));
  } else {
    notes.push_back(options.real_lp.string() + " is absent: simulated scenes only");
  }
  return out;
}

// A point is on the front when no other point is at least as good on both axes and better on one.
void mark_pareto(std::vector<CompactBenchRow*>& rows) {
  for (CompactBenchRow* a : rows) {
    a->pareto_bytes = a->pareto_time = true;
    for (const CompactBenchRow* b : rows) {
      if (a == b) continue;
      const double pa = a->result.psnr_db, pb = b->result.psnr_db;
      if (pb >= pa && b->result.bytes_per_pixel <= a->result.bytes_per_pixel &&
          (pb > pa || b->result.bytes_per_pixel < a->result.bytes_per_pixel)) {
        a->pareto_bytes = false;
      }
      if (pb >= pa && b->relight_ms <= a->relight_ms &&
          (pb > pa || b->relight_ms < a->relight_ms)) {
        a->pareto_time = false;
      }
    }
  }
}

// Every candidate on one field: leave-lights-out scores and relight time under `lighting`.
void score_scene(const std::string& scene_name, const capture::ReflectanceField& field,
                 const physics::EnvironmentMap& map, const CompactBenchOptions& options,
                 const std::vector<Candidate>& list, std::vector<CompactBenchRow>& rows,
                 const ProgressFn& progress, long& done, long total) {
  const std::vector<Eigen::Vector3d> dirs = capture::light_directions(field.lights());
  const relight::LightWeights weights = relight::integrate_environment(map, dirs);
  const auto lighting = relight::LightingForModels::led_cells(dirs, weights);
  for (const Candidate& c : list) {
    CompactBenchRow row;
    row.scene = scene_name;
    row.family = c.family;
    row.automatic = c.automatic;
    LeaveLightsOutOptions leave_out;
    leave_out.inspect = [&](const relight::CompactField& compact) {
      Image frame;
      compact.relight_into(lighting, frame);  // Warm-up.
      row.relight_ms = median_ms(options.repeats, [&] { compact.relight_into(lighting, frame); });
    };
    row.result = leave_lights_out(field, c.build, leave_out);
    row.name = row.result.name;
    rows.push_back(row);
    report(progress, "bench compact", ++done, total, scene_name + " " + row.name);
  }
}

void write_compact_csv(const fs::path& path, const std::vector<CompactBenchRow>& rows) {
  std::ofstream csv(path);
  if (!csv) throw InputError(path.string() + ": cannot write");
  csv << "scene,family,representation,bytes_per_pixel,build_s,relight_ms,psnr_db,ssim,held_out,"
         "automatic,pareto_psnr_bytes,pareto_psnr_time\n";
  for (const CompactBenchRow& r : rows) {
    csv << csv_field(r.scene) << ',' << csv_field(r.family) << ',' << csv_field(r.name) << ','
        << r.result.bytes_per_pixel << ',' << r.result.build_s << ',' << r.relight_ms << ','
        << r.result.psnr_db << ',' << r.result.ssim << ',' << r.result.held_out << ','
        << r.automatic << ',' << r.pareto_bytes << ',' << r.pareto_time << '\n';
  }
}

}  // namespace

void write_compact_charts(const fs::path& csv) {
  const CsvTable table = CsvTable::read(csv);
  const std::vector<std::string> families = table.distinct("family");
  for (const std::string& scene : table.distinct("scene")) {
    const std::string stem = scene.substr(0, scene.find(' '));
    for (const bool by_time : {true, false}) {
      // Names beside the points on the front (no other both smaller, or faster, and better).
      std::vector<ChartSeries> series = series_by("family", families);
      for (ChartSeries& s : series) {
        s.where.push_back({"scene", scene});
        s.labels = {.column = "representation",
                    .where = {by_time ? "pareto_psnr_time" : "pareto_psnr_bytes", "1"}};
      }
      const Chart chart{
          .csv = csv,
          .x = by_time ? "relight_ms" : "bytes_per_pixel",
          .y = "psnr_db",
          .series = series,
          .title = "Compact fields, " + scene + ": held-out PSNR vs " +
                   (by_time ? "relight time per frame" : "size") + " (labels: the front)",
          .x_label = by_time ? "relight time per frame (environment map), ms" : "bytes per pixel",
          .y_label = "PSNR on held-out LEDs, dB",
          .log_x = true};
      write_chart(fs::path(csv).replace_filename("compact_" + stem + "_psnr_vs_" +
                                                 (by_time ? "time" : "bytes") + ".png"),
                  chart);
    }
  }
}

CompactBenchSummary run_compact_bench(const CompactBenchOptions& options,
                                      const ProgressFn& progress) {
  throw_if_invalid(options.validate());
  fs::create_directories(options.out);
  CompactBenchSummary summary;
  const auto fields = scenes(options, summary.notes);
  const auto map = physics::EnvironmentMap::load(options.environment_map);
  const std::vector<Candidate> list = candidates(options.quick);
  long done = 0;
  const long total = long(fields.size() * list.size());
  for (const auto& [scene_name, field] : fields) {
    score_scene(scene_name, field, map, options, list, summary.rows, progress, done, total);
  }
  for (const auto& [scene_name, field] : fields) {
    std::vector<CompactBenchRow*> scene_rows;
    for (CompactBenchRow& r : summary.rows) {
      if (r.scene == scene_name) scene_rows.push_back(&r);
    }
    mark_pareto(scene_rows);
  }
  summary.csv = options.out / "compact.csv";
  write_compact_csv(summary.csv, summary.rows);
  write_compact_charts(summary.csv);
  return summary;
}

}  // namespace ls::evaluation
