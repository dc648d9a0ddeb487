// `lightstage bench rti`'s memory part (evaluation/rti_bench.h): a one-light set of
// RtiMemoryOptions' size (612 x 512, 96 lights by default) written as JPEGs and an .lp file, then
// import, compress and export run on it as the user runs them, one process each, their peak
// resident memory measured.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "evaluation/rti_bench.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "sim/noisy_field.h"
#include "sim/rti_scenes.h"

namespace ls::evaluation {

namespace fs = std::filesystem;

namespace {

// The glossy simulated scene as a photographer's set: the brightest sample just white, sRGB JPEGs
// (quality 90), "images/light_NNN.jpg x y z" per light. Returns the .lp file.
fs::path write_jpeg_set(const RtiMemoryOptions& options, const fs::path& dir,
                        const ProgressFn& progress) {
  Stage stage = sim::rti_dome_stage(options.lights, 10.0, options.width);
  stage.camera.height = options.height;
  report(progress, "bench rti memory: render", 0, 1);
  const capture::ReflectanceField field =
      sim::render_ideal_field(stage, sim::rti_scene(sim::RtiScene::kGlossy));
  report(progress, "bench rti memory: render", 1, 1);
  const float brightest = field.largest_value();
  fs::create_directories(dir / "images");
  std::string lp = std::to_string(field.num_lights()) + "\n";
  std::vector<uint8_t> rgb(std::size_t(field.width()) * field.height() * 3);
  for (int l = 0; l < field.num_lights(); ++l) {
    for (int y = 0; y < field.height(); ++y) {
      for (int x = 0; x < field.width(); ++x) {
        for (int c = 0; c < 3; ++c) {
          const float v = std::clamp(field.at(x, y, l, c) / brightest, 0.0f, 1.0f);
          rgb[(std::size_t(y) * field.width() + x) * 3 + c] = uint8_t(srgb8_code(v));
        }
      }
    }
    char name[64];
    const Eigen::Vector3d& d = field.lights()[size_t(l)].dir_in_stage;
    std::snprintf(name, sizeof name, "images/light_%03d.jpg", l);
    write_rgb8(dir / name, field.width(), field.height(), rgb.data(), 90);
    char line[160];
    std::snprintf(line, sizeof line, "%s %.6f %.6f %.6f\n", name, d.x(), d.y(), d.z());
    lp += line;
    report(progress, "bench rti memory: JPEGs", l + 1, field.num_lights());
  }
  std::ofstream(dir / "set.lp") << lp;
  return dir / "set.lp";
}

}  // namespace

RtiMemorySummary run_rti_memory_bench(const RtiMemoryOptions& options, const ProgressFn& progress) {
  if (options.executable.empty()) throw InputError("bench rti memory: no lightstage executable");
  const fs::path dir = options.out / ".rti_memory_set";
  fs::remove_all(dir);
  const fs::path lp = write_jpeg_set(options, dir, progress);
  RtiMemorySummary summary;
  summary.width = options.width, summary.height = options.height, summary.lights = options.lights;
  for (const auto& entry : fs::directory_iterator(dir / "images")) {
    summary.jpeg_mib += double(entry.file_size()) / (1 << 20);
  }
  const std::string exe = options.executable.string(), set = lp.string();
  const std::string budget = std::to_string(options.memory_bytes);
  const fs::path field = dir / "field.exr";
  // Each step by default and within the budget.
  const std::vector<std::pair<std::string, std::vector<std::string>>> jobs = {
      {"import", {"import", set, "--out", field.string()}},
      {"compress ptm", {"compress", set, "--out", (dir / "a.ptm").string(), "--format", "ptm"}},
      {"compress hsh3", {"compress", set, "--out", (dir / "a.rti").string(), "--format", "hsh3"}},
      {"export openlime rbf 27",
       {"export", "openlime", set, "--out", (dir / "rbf").string(), "--planes", "27"}},
      {"export openlime bilinear 9",
       {"export", "openlime", set, "--out", (dir / "bilinear").string(), "--type", "bilinear",
        "--planes", "9"}},
  };
  std::vector<std::pair<std::string, std::vector<std::string>>> steps = {
      {"start (--help)", {exe, "--help"}}};
  for (const auto& [name, args] : jobs) {
    std::vector<std::string> argv = {exe};
    argv.insert(argv.end(), args.begin(), args.end());
    steps.emplace_back(name, argv);
    argv.insert(argv.end(), {"--memory", budget});
    steps.emplace_back(name + " --memory", argv);
  }
  long done = 0;
  for (const auto& [step, argv] : steps) {
    const Measured m = run_process(argv, dir / "step.log");
    summary.rows.push_back({step, m.peak_mib, m.seconds});
    report(progress, "bench rti memory", ++done, long(steps.size()), step);
  }
  if (!options.keep) fs::remove_all(dir);
  return summary;
}

}  // namespace ls::evaluation
