#pragma once
// What lightstage relight's renders share (app/jobs/relight_job.cc: fields; relight_models.cc:
// fitted and time-varying models): the maps and rotations in output order, the writer of the
// images, the field's lights and the memory the run may hold. Internal to the jobs library.
#include <Eigen/Core>
#include <chrono>
#include <filesystem>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "app/jobs/job.h"
#include "app/jobs/ranks.h"
#include "app/jobs/relight_job.h"
#include "capture/field.h"
#include "lightstage/image.h"
#include "physics/envmap.h"
#include "relight/sources/map_relight.h"

namespace ls::jobs {

double ms_between(Clock::time_point a, Clock::time_point b);

// Output name of a map and rotation: the map's stem, its folder when two maps share a stem, and
// the rotation when there is one.
std::string output_name(const std::filesystem::path& map_path, double rotation,
                        bool several_rotations, std::set<std::string>& used_names);

// The maps and rotations in output order, each map loaded once: here, so that a bad one stops the
// run before any image is written.
class MapRotations {
 public:
  explicit MapRotations(const RelightOptions& options);
  MapRotations(const MapRotations&) = delete;  // all() points into maps_.
  MapRotations& operator=(const MapRotations&) = delete;
  long count() const { return long(all_.size()); }
  // Each map and rotation (the maps held here) and its output name, in output order.
  const std::vector<relight::MapRotation>& all() const { return all_; }
  const std::string& name(std::size_t i) const { return names_[i]; }
  template <typename Fn>  // fn(map, rotation_deg, output name)
  void for_each(Fn&& fn) const {
    for (std::size_t i = 0; i < all_.size(); ++i) fn(*all_[i].map, all_[i].rotation_deg, names_[i]);
  }

 private:
  std::vector<physics::EnvironmentMap> maps_;
  std::vector<relight::MapRotation> all_;
  std::vector<std::string> names_;
};

// The PNG preview's exposure (preview_exposure in relight_outputs.cc), and the luminance of a
// lighting's irradiance (per light, at normal incidence).
double preview_exposure(const Image& relit, double light_luma);
double total_luma(const std::vector<Eigen::Vector3f>& irradiance_rgb);
double total_luma(const std::vector<float>& irradiance_rgb);  // RGB triplets, one per light.

class RelitWriter {
 public:
  RelitWriter(const RelightOptions& options, RelightSummary& summary)
      : options_(options), summary_(summary), attributes_{{kOptionsAttribute, options.to_json()}} {}
  // The output directory is made with the first image: a run that fails before leaves none.
  // light_luma: the lighting's total irradiance (luminance, at normal incidence), for the PNG's
  // exposure (preview_exposure); 0 when unknown.
  void write(const std::string& name, Image& relit, std::string detail = {},
             double light_luma = 0) {
    std::filesystem::create_directories(options_.out_dir);
    relit.channel_names = {"R", "G", "B"};
    // Listed before it is written: a run that fails removes what it wrote (relight()).
    const RelitImage& out = summary_.images.emplace_back(
        RelitImage{options_.out_dir / (name + ".exr"), options_.out_dir / (name + ".png"), name,
                   std::move(detail)});
    write_exr(out.exr, relit, ExrPixelType::kFloat, attributes_);
    write_png_preview(out.png, relit,
                      options_.exposure_stops.value_or(preview_exposure(relit, light_luma)));
  }

 private:
  const RelightOptions& options_;
  RelightSummary& summary_;
  ExrAttributes attributes_;
};

double coverage_rad(const RelightOptions& options);
// What the run may hold: options.memory_bytes, or (0) half of the memory available.
std::size_t memory_given(const RelightOptions& options);

// Under MPI, after each rank rendered its bands of `rows` rows (band b on rank b % ranks) into
// full-size `images`: the rows gathered on rank 0 through a spill beside the output folder, and
// each rank's `counts` (pixels an edit changed, ...) summed into rank 0's. True on rank 0; the
// others return false once their rows are there.
bool gather_rows_over_ranks(const RelightOptions& options, const Ranks& ranks, int rows,
                            const std::vector<Image*>& images, std::vector<long>& counts);

// The fitted models (relight --models) and the time-varying ones (--temporal), rendered a band
// of maps at a time (relight_models.cc).
void relight_models(const RelightOptions& options, RelightSummary& summary,
                    const ProgressFn& progress);
void relight_temporal(const RelightOptions& options, RelightSummary& summary,
                      const ProgressFn& progress);

}  // namespace ls::jobs
