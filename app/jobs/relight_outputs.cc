#include "app/jobs/relight_outputs.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <optional>
#include <utility>

#include "lightstage/checkpoint_dir.h"
#include "lightstage/errors.h"
#include "lightstage/memory.h"
#include "lightstage/scratch_file.h"

namespace ls::jobs {

namespace fs = std::filesystem;

double ms_between(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

std::string output_name(const fs::path& map_path, double rotation, bool several_rotations,
                        std::set<std::string>& used_names) {
  std::string name = map_path.stem().string();
  if (used_names.count(name)) name = map_path.parent_path().filename().string() + "_" + name;
  if (several_rotations || rotation != 0.0) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "_rot%03d", int(std::lround(rotation)));
    name += buf;
  }
  used_names.insert(name);
  return name;
}

MapRotations::MapRotations(const RelightOptions& options) {
  maps_.reserve(options.maps.size());  // all_ points into it.
  for (const fs::path& map_path : options.maps) {
    maps_.push_back(physics::EnvironmentMap::load(map_path));
  }
  std::set<std::string> used_names;  // Maps from different folders may share a file name.
  for (std::size_t m = 0; m < maps_.size(); ++m) {
    for (const double rotation : options.rotations_deg) {
      all_.push_back({&maps_[m], rotation});
      names_.push_back(
          output_name(options.maps[m], rotation, options.rotations_deg.size() > 1, used_names));
    }
  }
}

// A preview is exposed by its own highlights (auto_exposure_stops), but never more than
// kDarkSceneStops brighter than a white Lambertian surface that all of the light reaches at normal
// incidence (radiance sum E / pi at 0.9): a scene that a map leaves dark (lit from behind the
// backdrop) reads as dark, not as its noise amplified to full scale.
constexpr double kDarkSceneStops = 2;

double preview_exposure(const Image& relit, double light_luma) {
  const double own = auto_exposure_stops(relit);
  if (!(light_luma > 0) || !std::isfinite(light_luma)) return own;
  return std::min(own, -std::log2(light_luma / M_PI / 0.9) + kDarkSceneStops);
}

double total_luma(const std::vector<Eigen::Vector3f>& irradiance_rgb) {
  double sum = 0;
  for (const Eigen::Vector3f& e : irradiance_rgb)
    sum += luminance(Eigen::Vector3d(e.cast<double>()));
  return sum;
}

// RGB triplets, one per light (LightWeights::irradiance_rgb).
double total_luma(const std::vector<float>& irradiance_rgb) {
  double sum = 0;
  for (size_t i = 0; i + 2 < irradiance_rgb.size(); i += 3) {
    sum +=
        luminance(Eigen::Vector3d(irradiance_rgb[i], irradiance_rgb[i + 1], irradiance_rgb[i + 2]));
  }
  return sum;
}

double coverage_rad(const RelightOptions& options) { return options.coverage_deg * M_PI / 180.0; }

std::size_t memory_given(const RelightOptions& options) {
  return MemoryBudget(options.memory_bytes).bytes();
}

bool gather_rows_over_ranks(const RelightOptions& options, const Ranks& ranks, int rows,
                            const std::vector<Image*>& images, std::vector<long>& counts) {
  const fs::path dir = options.out_dir.string() + ".partial";
  // Rank 0 makes the folder (empty) while the others wait, then each rank writes its rows.
  if (ranks.root()) {
    std::error_code error;
    fs::remove_all(dir, error);
    fs::create_directories(dir, error);
    if (error) {
      throw InputError(dir.string() +
                       ": cannot create the folder the ranks gather their rows in (" +
                       error.message() + ")");
    }
  }
  ranks.barrier();
  ScratchFile spill(dir / "relit.spill",
                    "the images relit under MPI are gathered through a file beside the output "
                    "folder: it needs their size free there",
                    ScratchFile::Lifetime::kKept);
  const int height = images.empty() ? 0 : images[0]->height;
  const auto at = [&](std::size_t i, int y) {
    return (i * std::size_t(height) + std::size_t(y)) * images[i]->width * images[i]->channels;
  };
  const auto transfer = [&](int y0, bool write) {
    const int y1 = std::min(height, y0 + rows);
    for (std::size_t i = 0; i < images.size(); ++i) {
      float* first = &images[i]->pixels[at(0, y0)];
      const std::size_t count = at(0, y1) - at(0, y0);
      write ? spill.write(first, count, at(i, y0)) : spill.read(first, count, at(i, y0));
    }
  };
  for (int b = ranks.rank(), y0; (y0 = b * rows) < height; b += ranks.size()) transfer(y0, true);
  spill.sync();
  write_record(dir / ("counts_" + std::to_string(ranks.rank())), "lightstage relight counts 1",
               {{"counts", counts}}, {});
  ranks.barrier();  // Every rank's rows and counts are there.
  if (!ranks.root()) return false;
  spill.reopen();  // The others' rows as they wrote them (a file system shared between nodes).
  for (int b = 0, y0; (y0 = b * rows) < height; ++b) {
    if (b % ranks.size() != 0) transfer(y0, false);
  }
  for (int r = 1; r < ranks.size(); ++r) {
    std::vector<long> theirs;
    const bool read =
        read_record(dir / ("counts_" + std::to_string(r)), "lightstage relight counts 1",
                    [&](const nlohmann::json& info) {
                      theirs = info.at("counts").get<std::vector<long>>();
                      return std::optional<std::vector<RecordTarget>>(std::vector<RecordTarget>{});
                    });
    if (!read || theirs.size() != counts.size()) {
      throw InputError(dir.string() + ": rank " + std::to_string(r) + "'s counts are missing");
    }
    for (std::size_t i = 0; i < counts.size(); ++i) counts[i] += theirs[i];
  }
  std::error_code ignored;
  fs::remove_all(dir, ignored);
  return true;
}

}  // namespace ls::jobs
