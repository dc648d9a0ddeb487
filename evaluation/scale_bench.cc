#include "evaluation/scale_bench.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <optional>

#include "evaluation/chart.h"
#include "evaluation/csv_table.h"
#include "lightstage/errors.h"
#include "lightstage/stage.h"

namespace ls::evaluation {

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Drops the file's pages from this machine's page cache (written back first), so that the next
// read comes from the disk (or the VM host's cache, which this cannot reach).
void evict(const fs::path& file) {
  const int fd = open(file.c_str(), O_RDONLY);
  if (fd < 0) return;
  fdatasync(fd);
  posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED);
  close(fd);
}

// Seconds to read the whole file in 8 MiB chunks.
double read_seconds(const fs::path& file) {
  std::vector<char> buffer(size_t(8) << 20);
  const auto t0 = Clock::now();
  const int fd = open(file.c_str(), O_RDONLY);
  if (fd < 0) throw InputError(file.string() + ": cannot open to time its reading");
  while (read(fd, buffer.data(), buffer.size()) > 0) {
  }
  close(fd);
  return seconds_since(t0);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

// The steps' measurements over the runs, by step name.
struct Samples {
  std::map<std::string, std::vector<double>> seconds, peak_mib;
  const std::string& add(const std::string& step, const Measured& m) {
    seconds[step].push_back(m.seconds);
    peak_mib[step].push_back(m.peak_mib);
    return m.output;
  }
};

// One size's runs into the CSV, and their medians into `rows`.
void record(int size, int leds, double field_mib, double budget_mib, Samples& samples,
            std::ostream& csv, std::vector<ScaleBenchRow>& rows) {
  const double pixels = double(size) * size;
  for (const auto& [name, seconds] : samples.seconds) {
    for (size_t r = 0; r < seconds.size(); ++r) {
      csv << size << "," << leds << "," << name << "," << r << "," << seconds[r] << ","
          << samples.peak_mib[name][r] << "," << field_mib << "," << budget_mib << "\n";
    }
    ScaleBenchRow row{size, leds, name, median(seconds), median(samples.peak_mib[name]), field_mib};
    if (name == "capture" || name == "build") {
      row.per_unit = row.seconds / leds, row.unit = "s per LED";
    } else if (name.rfind("relight (", 0) == 0) {
      row.per_unit = row.seconds, row.unit = "s per relit image";
    } else if (name.rfind("fit", 0) == 0) {
      row.per_unit = pixels / row.seconds, row.unit = "pixels/s";
    } else {
      row.per_unit = field_mib / row.seconds, row.unit = "field MiB/s";
    }
    rows.push_back(row);
  }
}

ScaleMpiModel mpi_model(double one_rank_s, double two_ranks_s, double io_floor_s) {
  ScaleMpiModel model;
  model.one_rank_s = one_rank_s;
  model.two_ranks_s = two_ranks_s;
  // T(1) = s + p, T(2) = s + p/2.
  model.serial_s = std::clamp(2 * two_ranks_s - one_rank_s, 0.0, one_rank_s);
  model.parallel_s = one_rank_s - model.serial_s;
  model.io_floor_s = io_floor_s;
  for (int n = 1; n <= 64; n *= 2) {
    model.ranks.push_back(n);
    model.model_s.push_back(std::max(model.serial_s + model.parallel_s / n, io_floor_s));
  }
  return model;
}

// scale_medians.csv beside `runs` (a scale.csv): per size and step, the medians over the runs.
fs::path write_medians(const CsvTable& runs) {
  fs::path path = fs::path(runs.path).replace_filename("scale_medians.csv");
  std::ofstream csv(path);
  if (!csv) throw InputError(path.string() + ": cannot write");
  csv << "size,leds,step,megapixels,seconds,peak_mib,field_mib,budget_mib,field_mib_per_s\n";
  const size_t size_column = runs.column("size"), step_column = runs.column("step");
  const std::vector<double> seconds = runs.numbers("seconds"), peak = runs.numbers("peak_mib"),
                            field = runs.numbers("field_mib"), budget = runs.numbers("budget_mib");
  const size_t leds = runs.column("leds");
  for (const std::string& size : runs.distinct("size")) {
    for (const std::string& step : runs.distinct("step")) {
      std::vector<double> s, p;
      size_t last = 0;
      for (size_t r = 0; r < runs.rows.size(); ++r) {
        if (runs.rows[r][size_column] != size || runs.rows[r][step_column] != step) continue;
        s.push_back(seconds[r]);
        p.push_back(peak[r]);
        last = r;
      }
      if (s.empty()) continue;
      const double megapixels = std::stod(size) * std::stod(size) / 1e6;
      csv << size << ',' << runs.rows[last][leds] << ',' << csv_field(step) << ',' << megapixels
          << ',' << median(s) << ',' << median(p) << ',' << field[last] << ',' << budget[last]
          << ',' << field[last] / median(s) << '\n';
    }
  }
  return path;
}

// scale_mpi.csv beside `runs`: the MPI model (mpi_model) from the medians of the MPI fits' runs
// at the size they ran at; nothing when there are none.
std::optional<fs::path> write_mpi_model(const CsvTable& runs) {
  const size_t size_column = runs.column("size"), step_column = runs.column("step");
  const std::vector<double> seconds = runs.numbers("seconds");
  std::string size;
  std::map<std::string, std::vector<double>> by_step;
  for (size_t r = 0; r < runs.rows.size(); ++r) {
    if (runs.rows[r][step_column].starts_with("fit mpi")) size = runs.rows[r][size_column];
  }
  if (size.empty()) return std::nullopt;
  for (size_t r = 0; r < runs.rows.size(); ++r) {
    if (runs.rows[r][size_column] == size) by_step[runs.rows[r][step_column]].push_back(seconds[r]);
  }
  // Basis materials read the field three times (fits, pool, blends).
  const ScaleMpiModel m = mpi_model(median(by_step["fit mpi 1"]), median(by_step["fit mpi 2"]),
                                    3 * median(by_step["read (disk)"]));
  fs::path path = fs::path(runs.path).replace_filename("scale_mpi.csv");
  std::ofstream csv(path);
  if (!csv) throw InputError(path.string() + ": cannot write");
  csv << "size,ranks,measured_s,model_s,io_floor_s\n";
  for (size_t i = 0; i < m.ranks.size(); ++i) {
    csv << size << ',' << m.ranks[i] << ',';
    if (i < 2) csv << (i == 0 ? m.one_rank_s : m.two_ranks_s);
    csv << ',' << m.model_s[i] << ',' << m.io_floor_s << '\n';
  }
  return path;
}

}  // namespace

void write_scale_charts(const fs::path& csv) {
  const CsvTable runs = CsvTable::read(csv);
  const fs::path medians = write_medians(runs);
  const auto steps = [](std::initializer_list<const char*> names) {
    std::vector<ChartSeries> series;
    for (const char* name : names) series.push_back({.title = name, .where = {{"step", name}}});
    return series;
  };
  Chart memory{.csv = medians,
               .x = "megapixels",
               .y = "peak_mib",
               .series = steps({"build", "relight (disk)", "fit", "compress hsh3"}),
               .title = "Peak resident memory of each step against the budget",
               .x_label = "megapixels",
               .y_label = "MiB"};
  memory.series.push_back(
      {.title = "--memory budget", .where = {{"step", "build"}}, .y = "budget_mib"});
  memory.series.push_back({.title = "field file", .where = {{"step", "build"}}, .y = "field_mib"});
  write_chart(fs::path(csv).replace_filename("scale_peak_memory.png"), memory);
  write_chart(
      fs::path(csv).replace_filename("scale_throughput.png"),
      {.csv = medians,
       .x = "megapixels",
       .y = "field_mib_per_s",
       .series = steps({"read (cache)", "read (disk)", "relight pass (cache)",
                        "relight pass (disk)", "relight (disk)", "build", "compress hsh3"}),
       .title =
           "Field bytes through each step (relight: one image; pass: its reading and relighting)",
       .x_label = "megapixels",
       .y_label = "field MiB/s",
       .log_y = true});
  const std::optional<fs::path> mpi = write_mpi_model(runs);
  if (!mpi) return;
  write_chart(fs::path(csv).replace_filename("scale_mpi_ranks.png"),
              {.csv = *mpi,
               .x = "ranks",
               // The measured points last, over the model's (equal at 1 and 2 ranks).
               .series = {{.title = "model: serial + parallel / n, floored by I/O", .y = "model_s"},
                          {.title = "I/O floor (3 passes from one store as fast as this disk)",
                           .y = "io_floor_s"},
                          {.title = "measured", .y = "measured_s"}},
               .title = "lightstage fit under MPI at " + CsvTable::read(*mpi).rows.at(0).at(0) +
                        "²: time against ranks (one core each)",
               .x_label = "ranks",
               .y_label = "seconds",
               .log_x = true});
}

std::string ScaleBenchOptions::validate() const {
  if (executable.empty() || !fs::exists(executable)) return "the lightstage executable is missing";
  if (env_map.empty() || !fs::exists(env_map)) return "--env: the environment map is missing";
  if (sizes.empty()) return "--sizes: give at least one size";
  for (const int s : sizes) {
    if (s < 16 || s > 16384) return "--sizes: each in [16, 16384], got " + std::to_string(s);
  }
  if (runs < 1) return "--runs: at least 1";
  if (memory_bytes < (std::size_t(16) << 20)) return "--memory: at least 16 MiB";
  return {};
}

ScaleBenchSummary run_scale_bench(const ScaleBenchOptions& options, const ProgressFn& progress) {
  throw_if_invalid(options.validate());
  fs::create_directories(options.out);
  ScaleBenchSummary summary;
  summary.csv = options.out / "scale.csv";
  std::ofstream csv(summary.csv);
  csv << "size,leds,step,run,seconds,peak_mib,field_mib,budget_mib\n";
  const std::string exe = fs::absolute(options.executable).string();
  const std::string budget = std::to_string(options.memory_bytes);
  const double budget_mib = double(options.memory_bytes) / (1 << 20);
  const bool mpi = options.mpi && std::system("command -v mpiexec > /dev/null 2>&1") == 0;
  if (options.mpi && !mpi) summary.mpi_note = "mpiexec is not on PATH (install openmpi-bin)";
  if (mpi && geteuid() == 0) {  // Open MPI refuses root without both.
    setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 0);
    setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 0);
  }
  int mpi_size = *std::min_element(options.sizes.begin(), options.sizes.end());
  for (const int size : options.sizes) {
    if (size <= options.fit_max_size) mpi_size = std::max(mpi_size, size);
  }
  long done = 0;
  const long total = long(options.sizes.size()) * (1 + options.runs) + (mpi ? options.runs : 0);
  for (const int size : options.sizes) {
    const fs::path dir = options.out / ("size" + std::to_string(size));
    fs::remove_all(dir);
    fs::create_directories(dir);
    const fs::path session = dir / "session", field = dir / "field.exr";
    const auto log = [&](const std::string& step) { return dir / (step + ".log"); };
    Stage stage = default_stage();
    stage.camera.width = stage.camera.height = size;
    if (options.single_exposure) {
      stage.camera.bracket = {stage.camera.bracket[stage.camera.bracket.size() / 2]};
    }
    std::ofstream(dir / "stage.json") << stage_to_json(stage);
    const int leds = int(stage.leds.size());
    const std::string label = std::to_string(size) + "²";
    Samples samples;
    samples.add("capture", run_process({exe, "capture", "--stage", (dir / "stage.json").string(),
                                        "--out", session.string(), "--quiet"},
                                       log("capture")));
    report(progress, "bench scale", ++done, total, label + " captured");
    const auto step = [&](const std::string& name, std::vector<std::string> args) {
      args.insert(args.begin(), exe);
      return samples.add(name, run_process(args, log(name)));
    };
    // Relighting's own pass over the field (reading and relighting, as it prints it), beside the
    // process's time.
    const auto relight_step = [&](const std::string& from, const std::vector<std::string>& args) {
      const std::string printed = step("relight (" + from + ")", args);
      const std::string key = "field read and relit in ";
      const size_t at = printed.find(key);
      if (at == std::string::npos) throw InputError("bench scale: relight did not print its pass");
      samples.add("relight pass (" + from + ")",
                  {std::stod(printed.substr(at + key.size())), 0, {}});
    };
    double field_mib = 0;
    for (int run = 0; run < options.runs; ++run) {
      fs::remove(field);
      step("build",
           {"build", session.string(), "--out", field.string(), "--memory", budget, "--quiet"});
      field_mib = double(fs::file_size(field)) / (1 << 20);
      read_seconds(field);
      samples.add("read (cache)", {read_seconds(field), 0, {}});
      evict(field);
      samples.add("read (disk)", {read_seconds(field), 0, {}});
      const std::vector<std::string> relight = {
          "relight", field.string(),           "--env",    options.env_map.string(),
          "--out",   (dir / "relit").string(), "--memory", budget,
          "--quiet"};
      evict(field);
      relight_step("disk", relight);
      read_seconds(field);
      relight_step("cache", relight);
      if (size <= options.fit_max_size) {
        step("fit", {"fit", field.string(), "--out", (dir / "maps.exr").string(), "--memory",
                     budget, "--quiet"});
      }
      step("compress hsh3", {"compress", field.string(), "--out", (dir / "field.rti").string(),
                             "--format", "hsh3", "--memory", budget});
      report(progress, "bench scale", ++done, total, label + " run " + std::to_string(run + 1));
    }
    if (mpi && size == mpi_size) {
      for (int run = 0; run < options.runs; ++run) {
        for (const int n : {1, 2}) {
          samples.add("fit mpi " + std::to_string(n),
                      run_process({"mpiexec", "-n", std::to_string(n), "--bind-to", "core", "--mca",
                                   "btl", "self,vader", "--mca", "oob_tcp_if_include", "lo", exe,
                                   "fit", field.string(), "--out", (dir / "maps_mpi.exr").string(),
                                   "--memory", budget, "--quiet"},
                                  log("fit mpi " + std::to_string(n))));
        }
        report(progress, "bench scale", ++done, total,
               label + " MPI run " + std::to_string(run + 1));
      }
    }
    record(size, leds, field_mib, budget_mib, samples, csv, summary.rows);
    if (mpi && size == mpi_size) {
      // Basis materials read the field three times (fits, pool, blends).
      const double disk_mib_per_s = field_mib / median(samples.seconds["read (disk)"]);
      summary.mpi = mpi_model(median(samples.seconds["fit mpi 1"]),
                              median(samples.seconds["fit mpi 2"]), 3 * field_mib / disk_mib_per_s);
      summary.mpi_size = size;
    }
    if (!options.keep) fs::remove_all(dir);
  }
  csv.close();
  write_scale_charts(summary.csv);
  return summary;
}

}  // namespace ls::evaluation
