// Compact reflectance fields (issue 7):
//  * lightstage bench compact [--out DIR] [--quick]: every representation on the simulated RTI
//    scenes (matte, glossy, shadowed) and the real RTI set: bytes per pixel, build time, relight
//    time per frame, PSNR and SSIM on held-out LEDs. Writes compact.csv and, per scene, PSNR
//    against relight time and PSNR against bytes per pixel as PNG charts.
//  * lightstage compress FIELD --out OUT [--format F] [--rank k|auto] [--tile N] [--gain G]:
//    writes one representation (.ptm, .rti, or the PCA binary format of
//    relight/compact/pca_field.h). FIELD is a field EXR, or an .lp capture (or a folder holding
//    one), imported directly.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>

#include "app/cli/chart.h"
#include "app/cli/commands.h"
#include "app/jobs/compress_job.h"
#include "capture/field.h"
#include "capture/olat_import.h"
#include "evaluation/leave_lights_out.h"
#include "lightstage/errors.h"
#include "lightstage/progress.h"
#include "relight/compact/pca_field.h"
#include "relight/compact/rti_fits.h"
#include "relight/compact/rti_io.h"
#include "relight/fit/fit.h"
#include "relight/fit/model_render.h"
#include "relight/lighting/light_cells.h"

namespace ls::cli {

namespace fs = std::filesystem;

namespace {

struct CompactBenchArgs {
  fs::path out = "bench-out";
  bool quick = false;
  int repeats = 15;
};

struct Candidate {
  std::string family;  // Chart series.
  sim::CompactBuilder build;
  bool automatic = false;  // The software's own choice (PCA, automatic rank).
};

std::vector<Candidate> candidates(bool quick) {
  std::vector<Candidate> out;
  out.push_back({"raw", [](const capture::ReflectanceField& f) {
                   return std::unique_ptr<relight::CompactField>(
                       new relight::RawCompactField(capture::ReflectanceField(f)));
                 }});
  auto pca = [](int rank, int tile, relight::PcaRankRule rule = relight::PcaRankRule::kNoiseFloor) {
    return [=](const capture::ReflectanceField& f) {
      relight::PcaOptions options;
      options.rank = rank;
      options.tile_size = tile;
      options.rank_rule = rule;
      return std::unique_ptr<relight::CompactField>(
          new relight::PcaField(relight::PcaField::build(f, options)));
    };
  };
  for (int k : {2, 4, 8, 16, 32, 64}) {
    out.push_back({"pca global", pca(k, 0)});
    out.push_back({"pca 16px tiles", pca(k, 16)});
  }
  out.push_back({"pca auto (noise floor)", pca(0, 0), true});
  out.push_back(
      {"pca auto (held-out LEDs)", pca(0, 0, relight::PcaRankRule::kHeldOutLights), true});
  out.push_back(
      {"pca auto (held-out LEDs)", pca(0, 16, relight::PcaRankRule::kHeldOutLights), true});
  auto rti = [](relight::RtiBasis basis, bool lrgb) {
    return [=](const capture::ReflectanceField& f) {
      relight::RtiFitOptions options;
      options.basis = basis;
      options.lrgb = lrgb;
      return std::unique_ptr<relight::CompactField>(
          new relight::RtiField(relight::RtiField::fit(f, options)));
    };
  };
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

struct Row {
  std::string scene, family, name;
  sim::LeaveLightsOutResult result;
  double relight_ms = 0;
  bool automatic = false;
  bool pareto_bytes = false, pareto_time = false;
};

// A point is on the front when no other point is at least as good on both axes and better on one.
void mark_pareto(std::vector<Row*>& rows) {
  for (Row* a : rows) {
    a->pareto_bytes = a->pareto_time = true;
    for (const Row* b : rows) {
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

void run_compact_bench(const CompactBenchArgs& args) {
  fs::create_directories(args.out);
  const int resolution = args.quick ? 32 : 64;
  std::vector<std::pair<std::string, capture::ReflectanceField>> scenes;
  capture::FieldNoise noise;  // As tests/compact: about 1.5% read and 2.5% shot noise.
  noise.read_variance = 1e-5;
  noise.shot_variance_per_unit = 2e-4;
  noise.method = "simulated";
  for (auto s : {sim::RtiScene::kMatte, sim::RtiScene::kGlossy, sim::RtiScene::kShadowed}) {
    scenes.emplace_back(sim::to_string(s),
                        sim::render_noisy_field(sim::rti_dome_stage(150, 10.0, resolution),
                                                sim::rti_scene(s), noise, 7));
  }
  // The real RTI set beside the checkout (../shared/data, as the tests find it).
  const fs::path lp =
      data_dir().parent_path().parent_path() / "shared/data/rti/loewenkopf_klein/dirs.lp";
  if (fs::exists(lp)) {
    scenes.emplace_back("real (loewenkopf)", capture::import_rti_lp(lp, {}));
  } else {
    std::fprintf(stderr, "note: %s is absent: simulated scenes only\n", lp.c_str());
  }
  const auto map = relight::EnvironmentMap::load(data_dir() / "envmaps/sky_sun.exr");
  const std::vector<Candidate> list = candidates(args.quick);
  std::vector<Row> rows;
  ProgressReporter progress("bench compact", long(scenes.size() * list.size()));
  long done = 0;
  for (const auto& [scene_name, field] : scenes) {
    std::vector<Eigen::Vector3d> dirs;
    for (const auto& l : field.lights()) dirs.push_back(l.dir_in_stage);
    const relight::LightWeights weights = relight::integrate_environment(map, dirs);
    const auto lighting = relight::LightingForModels::led_cells(dirs, weights);
    for (const Candidate& c : list) {
      Row row;
      row.scene = scene_name;
      row.family = c.family;
      row.automatic = c.automatic;
      sim::LeaveLightsOutOptions options;
      options.inspect = [&](const relight::CompactField& compact) {
        Image frame;
        compact.relight_into(lighting, frame);  // Warm-up.
        std::vector<double> ms;
        for (int i = 0; i < args.repeats; ++i) {
          const auto t0 = std::chrono::steady_clock::now();
          compact.relight_into(lighting, frame);
          ms.push_back(
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                  .count());
        }
        std::sort(ms.begin(), ms.end());
        row.relight_ms = ms[ms.size() / 2];
      };
      row.result = sim::leave_lights_out(field, c.build, options);
      row.name = row.result.name;
      rows.push_back(row);
      progress.update(++done, scene_name + " " + row.name);
    }
  }
  progress.done();

  std::ofstream csv(args.out / "compact.csv");
  csv << "scene,representation,bytes_per_pixel,build_s,relight_ms,psnr_db,ssim,held_out,"
         "automatic,pareto_psnr_bytes,pareto_psnr_time\n";
  std::printf("%-18s %-18s %9s %8s %10s %8s %7s %s\n", "scene", "representation", "B/px", "build s",
              "relight ms", "PSNR dB", "SSIM", "front (bytes, time)");
  for (const auto& [scene_name, field] : scenes) {
    std::vector<Row*> scene_rows;
    for (Row& r : rows) {
      if (r.scene == scene_name) scene_rows.push_back(&r);
    }
    mark_pareto(scene_rows);
    std::map<std::string, ChartSeries> by_time, by_bytes;
    for (const Row* r : scene_rows) {
      csv << '"' << r->scene << "\",\"" << r->name << "\"," << r->result.bytes_per_pixel << ','
          << r->result.build_s << ',' << r->relight_ms << ',' << r->result.psnr_db << ','
          << r->result.ssim << ',' << r->result.held_out << ',' << r->automatic << ','
          << r->pareto_bytes << ',' << r->pareto_time << '\n';
      std::printf("%-18s %-18s %9.1f %8.3f %10.3f %8.2f %7.4f %s%s%s\n", r->scene.c_str(),
                  r->name.c_str(), r->result.bytes_per_pixel, r->result.build_s, r->relight_ms,
                  r->result.psnr_db, r->result.ssim, r->pareto_bytes ? "bytes " : "",
                  r->pareto_time ? "time " : "", r->automatic ? "<- automatic" : "");
      const std::string series = r->family;
      for (auto* chart : {&by_time, &by_bytes}) {
        ChartSeries& s = (*chart)[series];
        s.name = series;
        s.y.push_back(r->result.psnr_db);
        s.point_labels.push_back(r->name);
      }
      by_time[series].x.push_back(r->relight_ms);
      by_bytes[series].x.push_back(r->result.bytes_per_pixel);
    }
    std::string stem = scene_name.substr(0, scene_name.find(' '));
    auto values = [](const std::map<std::string, ChartSeries>& m) {
      std::vector<ChartSeries> v;
      for (const auto& [_, s] : m) v.push_back(s);
      return v;
    };
    write_chart(args.out / ("compact_" + stem + "_psnr_vs_time.png"),
                {"Compact fields, " + scene_name + ": held-out PSNR vs relight time per frame",
                 "relight time per frame (environment map), ms", "PSNR on held-out LEDs, dB", true},
                values(by_time));
    write_chart(args.out / ("compact_" + stem + "_psnr_vs_bytes.png"),
                {"Compact fields, " + scene_name + ": held-out PSNR vs size", "bytes per pixel",
                 "PSNR on held-out LEDs, dB", true},
                values(by_bytes));
  }
  std::fprintf(stderr, "wrote %s and compact_<scene>_psnr_vs_{time,bytes}.png\n",
               (args.out / "compact.csv").c_str());
}

}  // namespace

void add_compact_commands(CLI::App& app) {
  // `bench compact` joins the subcommands of `bench` (add_bench_command runs first).
  CLI::App* bench = app.get_subcommand("bench");
  auto bench_args = std::make_shared<CompactBenchArgs>();
  auto* compact = bench->add_subcommand(
      "compact",
      "Compact reflectance fields (PCA global and tiled, PTM, HSH, fitted models, the raw field): "
      "bytes per pixel, build time, relight time per frame, PSNR and SSIM on held-out LEDs, on "
      "simulated RTI scenes and the real RTI set. CSV + charts.");
  compact->add_option("--out", bench_args->out, "Output directory.")->capture_default_str();
  compact->add_flag("--quick", bench_args->quick, "32x32 scenes, no model fits.");
  compact->add_option("--repeats", bench_args->repeats, "Timed relights (median reported).")
      ->capture_default_str();
  compact->callback([bench_args] { run_compact_bench(*bench_args); });

  auto args = std::make_shared<jobs::CompressOptions>();
  auto* compress = app.add_subcommand(
      "compress",
      "Writes a compact representation of a field (EXR, or an .lp capture imported directly): "
      ".ptm (PTM_1.2 RGB/LRGB), .rti (HSH) or the lightstage PCA format.");
  compress->add_option("field", args->input, "Field EXR, .lp file, or folder with one .lp.")
      ->required();
  compress->add_option("--out", args->out, "Output file.")->required();
  compress->add_option("--format", args->format, "pca | ptm | ptm-lrgb | hsh2 | hsh3 | hsh4.")
      ->capture_default_str();
  compress->add_option("--rank", args->rank, "PCA rank: a number or auto (from the noise floor).")
      ->capture_default_str();
  compress->add_option("--tile", args->tile, "PCA tile size in pixels (0: one global basis).")
      ->capture_default_str();
  compress
      ->add_option("--gain", args->gain,
                   "RTI files: display units (white = 1) per field unit; 0: the brightest "
                   "sample is white.")
      ->capture_default_str();
  compress->callback([args] {
    // A bad --format or --rank is bad input (exit 2), as before options were validated here.
    const jobs::CompressSummary summary = jobs::compress(*args);
    if (args->format == "pca") {
      std::printf("%s\n%s: %.1f bytes per pixel (raw field: %.1f)\n", summary.details.c_str(),
                  args->out.c_str(), summary.bytes_per_pixel, summary.raw_bytes_per_pixel);
    } else {
      std::printf("%s: %s %s, %.0f bytes per pixel (raw field: %.0f)\n", args->out.c_str(),
                  summary.representation.c_str(), summary.details.c_str(), summary.bytes_per_pixel,
                  summary.raw_bytes_per_pixel);
    }
  });
}

}  // namespace ls::cli
