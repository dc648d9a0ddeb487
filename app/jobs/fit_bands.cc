#include "app/jobs/fit_bands.h"

#include <algorithm>
#include <chrono>
#include <span>
#include <vector>

#include "relight/fit/basis_materials.h"
#include "relight/fit/normals.h"

namespace ls::jobs {

namespace {

using Clock = std::chrono::steady_clock;

// Rows [y0, y0 + band.height) of `frame` (sized and named after the first band when empty).
void paste_rows(const Image& band, int y0, int frame_height, Image& frame) {
  if (frame.pixels.empty()) {
    frame = Image(band.width, frame_height, band.channels);
    frame.channel_names = band.channel_names;
  }
  std::copy(band.pixels.begin(), band.pixels.end(),
            frame.pixels.begin() + std::ptrdiff_t(y0) * band.width * band.channels);
}

std::span<float> rows_of(Image& image, int y0, int y1) {
  const size_t row = size_t(image.width) * size_t(image.channels);
  return {image.pixels.data() + size_t(y0) * row, size_t(y1 - y0) * row};
}

// Rank 0's basis materials on every rank: per material its model, albedo, sigma, k_s, roughness,
// pixels and scene material, after the dispersion.
constexpr size_t kMaterialValues = 9;

void broadcast(const Ranks& ranks, relight::BasisMaterials& basis) {
  std::vector<double> values = {basis.dispersion};
  for (const relight::Material& m : basis.materials) {
    values.insert(values.end(), {double(m.model), m.albedo(0), m.albedo(1), m.albedo(2), m.sigma,
                                 m.ks, m.roughness, double(m.pixels), double(m.scene_material)});
  }
  ranks.broadcast(values);
  basis.dispersion = values[0];
  basis.materials.resize((values.size() - 1) / kMaterialValues);
  for (size_t k = 0; k < basis.materials.size(); ++k) {
    const double* v = &values[1 + k * kMaterialValues];
    relight::Material& m = basis.materials[k];
    m.model = relight::FitModel(int(v[0]));
    m.albedo = {v[1], v[2], v[3]};
    m.sigma = v[4], m.ks = v[5], m.roughness = v[6];
    m.pixels = int(v[7]), m.scene_material = int(v[8]);
  }
}

// The counts that assigning materials changes: pixels per model, not converged, explained by
// materials, and each material's pixels.
std::vector<long long> assignment_counts(const relight::ModelMaps& maps) {
  const relight::FitSummary& s = maps.summary;
  std::vector<long long> counts(std::begin(s.per_model), std::end(s.per_model));
  counts.push_back(s.not_converged);
  counts.push_back(s.material_pixels);
  for (const relight::Material& m : maps.materials) counts.push_back(m.pixels);
  return counts;
}

void set_assignment_counts(const std::vector<long long>& counts, relight::ModelMaps& maps) {
  relight::FitSummary& s = maps.summary;
  size_t i = 0;
  for (int& n : s.per_model) n = int(counts[i++]);
  s.not_converged = int(counts[i++]);
  s.material_pixels = int(counts[i++]);
  for (relight::Material& m : maps.materials) m.pixels = int(counts[i++]);
}

}  // namespace

int band_rows_for_ranks(int rows, int height, int alignment, int ranks) {
  if (ranks == 1) return rows;
  // As many bands as the memory needs, at least kBandsPerRank a rank, and a multiple of the ranks
  // so that each rank fits as many (9 bands over 2 ranks kept one waiting a ninth of the fit).
  constexpr int kBandsPerRank = 4;
  int bands = std::max((height + rows - 1) / rows, kBandsPerRank * ranks);
  bands = (bands + ranks - 1) / ranks * ranks;
  const int share = (height + bands - 1) / bands;
  const int aligned = (share + alignment - 1) / alignment * alignment;
  return std::max(alignment, std::min(rows, aligned));
}

relight::ModelMaps fit_in_bands(capture::FieldStream& stream, int rows,
                                const relight::FitOptions& fit, const BandCheckpoints& checkpoints,
                                const Ranks& ranks, const ProgressFn& progress,
                                BandFitTimes& times) {
  const capture::ReflectanceField& header = stream.header();
  const int height = header.height();
  const int band_count = (height + rows - 1) / rows;
  relight::FitOptions per_band = fit;
  per_band.materials = relight::FitMaterials::kPerPixel;
  per_band.progress = {};
  relight::NormalMap normals;
  relight::ModelMaps maps;
  const std::vector<Eigen::Vector3f> led_dirs = relight::led_dirs_of(header);
  maps.noise = fit.normals.noise;  // As fit_models records them.
  maps.noise_source = fit.noise_source;
  capture::ReflectanceField band;
  // Where band b's rows end.
  const auto end_of = [&](int b) { return std::min(height, (b + 1) * rows); };
  const auto read = [&](int b) {
    const auto t0 = Clock::now();
    stream.read_rows(b * rows, end_of(b), band);
    times.read_seconds += std::chrono::duration<double>(Clock::now() - t0).count();
  };
  // Normals and per-pixel fits of band b: from its checkpoint when there is one (an earlier run's,
  // or another rank's), else fitted here and kept.
  const auto fit_band = [&](int b, bool own) {
    const int y0 = b * rows, y1 = end_of(b);
    relight::NormalMap band_normals;
    relight::ModelMaps band_maps;
    if (checkpoints.load(y0, led_dirs, band_normals, band_maps)) {
      if (own) times.resumed_rows += y1 - y0;
    } else {
      read(b);
      band_normals = relight::estimate_normals(band, fit.normals);
      band_maps = relight::fit_models(band, band_normals, per_band);
      checkpoints.save(y0, band_normals, band_maps);
    }
    paste_rows(band_normals.normal, y0, height, normals.normal);
    paste_rows(band_normals.albedo, y0, height, normals.albedo);
    paste_rows(band_normals.confidence, y0, height, normals.confidence);
    paste_rows(band_normals.flags, y0, height, normals.flags);
    normals.flagged_pixels += band_normals.flagged_pixels;
    paste_rows(band_maps.maps, y0, height, maps.maps);
    paste_rows(band_maps.shadows.words, y0, height, maps.shadows.words);
    maps.shadows.led_dirs_in_stage = band_maps.shadows.led_dirs_in_stage;
    maps.summary.add(band_maps.summary);
  };
  long own_rows = 0, done_rows = 0;
  for (int b = ranks.rank(); b < band_count; b += ranks.size()) {
    own_rows += end_of(b) - b * rows;
  }
  for (int b = ranks.rank(); b < band_count; b += ranks.size()) {
    fit_band(b, /*own=*/true);
    done_rows += end_of(b) - b * rows;
    report(progress, "fit (rows)", done_rows, own_rows);
  }
  ranks.barrier();  // Every band is in its checkpoint.
  for (int b = 0; ranks.root() && b < band_count; ++b) {
    if (!ranks.owns(b)) fit_band(b, /*own=*/false);
  }
  if (fit.materials != relight::FitMaterials::kBasis) return maps;

  relight::BasisMaterials basis;
  if (ranks.root()) {
    const auto all_bands = [&](const relight::BandVisitor& visit) {
      for (int b = 0; b < band_count; ++b) read(b), visit(band);
    };
    basis = relight::find_basis_materials(header, all_bands, maps, fit);
  }
  broadcast(ranks, basis);
  if (basis.materials.empty()) return maps;
  maps.materials = basis.materials;
  maps.summary.materials = int(basis.materials.size());
  const std::vector<long long> before = assignment_counts(maps);
  for (int b = ranks.rank(); b < band_count; b += ranks.size()) {
    read(b);
    relight::assign_basis_materials(header, band, normals, basis, fit, maps);
  }
  // Rank 0 gathers the other ranks' rows of the maps and their changes to the counts.
  std::vector<long long> change = assignment_counts(maps);
  for (size_t i = 0; i < change.size(); ++i) change[i] -= before[i];
  ranks.sum_to_root(change);
  for (int b = 0; ranks.size() > 1 && b < band_count; ++b) {
    for (Image* image : {&maps.maps, &maps.shadows.words}) {
      const std::span<float> band_rows = rows_of(*image, b * rows, end_of(b));
      if (ranks.root() && !ranks.owns(b)) ranks.receive(band_rows, ranks.owner(b));
      if (!ranks.root() && ranks.owns(b)) ranks.send(band_rows, 0);
    }
  }
  if (!ranks.root()) return maps;
  for (size_t i = 0; i < change.size(); ++i) change[i] += before[i];
  set_assignment_counts(change, maps);
  maps.summary.scene_materials = relight::group_scene_materials(maps.maps, maps.materials);
  return maps;
}

}  // namespace ls::jobs
