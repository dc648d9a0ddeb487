#include "relight/fit/fit_bands.h"

#include <algorithm>
#include <chrono>
#include <optional>
#include <vector>

#include "capture/field_file.h"
#include "lightstage/bands.h"
#include "lightstage/errors.h"
#include "relight/fit/basis_materials.h"
#include "relight/fit/normals.h"

namespace ls::relight {

namespace {

// Rank 0's basis materials on every rank: per material its model, albedo, sigma, k_s, roughness,
// pixels and scene material, after the dispersion.
constexpr size_t kMaterialValues = 9;

void broadcast(const RankSplit& split, relight::BasisMaterials& basis) {
  std::vector<double> values = {basis.dispersion};
  for (const relight::Material& m : basis.materials) {
    values.insert(values.end(), {double(m.model), m.albedo(0), m.albedo(1), m.albedo(2), m.sigma,
                                 m.ks, m.roughness, double(m.pixels), double(m.scene_material)});
  }
  split.share(values);
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

// One band's checkpoint at a time, and the field's band rows.
class Bands : public BandPlan {
 public:
  Bands(capture::FieldStream& stream, int rows, const BandCheckpoints& checkpoints,
        BandFitTimes& times)
      : BandPlan(stream.header().height(), rows),
        stream_(stream),
        checkpoints_(checkpoints),
        led_dirs_(relight::led_dirs_of(stream.header())),
        times_(times) {}

  const capture::ReflectanceField& read_field(int b) { return read_rows(first_row(b), end_row(b)); }
  // The field's band given back once the last band is read (the maps' writer needs the room).
  void release_field() { field_ = {}; }
  bool load(int b, FitStage stage) {
    return checkpoints_.load(first_row(b), led_dirs_, normals, maps, stage);
  }
  // A band every earlier step left in its checkpoint.
  void load_finished(int b, FitStage stage) {
    if (!load(b, stage)) {
      // What this run wrote itself and cannot read back: its storage failed.
      throw StorageError(checkpoints_.file(first_row(b), stage).string() +
                         ": a finished band's checkpoint is missing or unreadable (removed while "
                         "the fit ran?)");
    }
  }
  void save(int b, FitStage stage) const { checkpoints_.save(first_row(b), normals, maps, stage); }
  // The maps of every band as loaded from its checkpoints, in order.
  relight::MapsBands maps_bands(FitStage stage) {
    return [this, stage](const relight::MapsVisitor& visit) {
      for (int b = 0; b < count(); ++b) load_finished(b, stage), visit(maps.maps, first_row(b));
    };
  }
  // The field's rows on demand: the file's row (or tile row) holding y, read when not held.
  relight::FieldRows field_rows() {
    return [this](int y) -> const capture::ReflectanceField& {
      if (field_.height() > 0 && y >= field_.first_row() &&
          y < field_.first_row() + field_.height()) {
        return field_;
      }
      const int alignment = stream_.row_alignment(), y0 = y / alignment * alignment;
      return read_rows(y0, std::min(stream_.header().height(), y0 + alignment));
    };
  }

  relight::NormalMap normals;  // The band's, as loaded or fitted.
  relight::ModelMaps maps;

 private:
  const capture::ReflectanceField& read_rows(int y0, int y1) {
    const auto t0 = Clock::now();
    stream_.read_rows(y0, y1, field_);
    times_.read_seconds += seconds_since(t0);
    return field_;
  }

  capture::FieldStream& stream_;
  const BandCheckpoints& checkpoints_;
  const std::vector<Eigen::Vector3f> led_dirs_;
  BandFitTimes& times_;
  capture::ReflectanceField field_;
};

// Writes the maps' `files` from the bands' checkpoints of `stage`; returns their summed summary.
relight::FitSummary write_maps(Bands& bands, FitStage stage, const relight::ModelMaps& header,
                               int width, int height, const std::filesystem::path& out,
                               const ExrAttributes& attributes,
                               relight::ModelMapsWriter::Files files, const ProgressFn& progress) {
  relight::FitSummary summary;
  std::optional<relight::ModelMapsWriter> writer;
  for (int b = 0; b < bands.count(); ++b) {
    bands.load_finished(b, stage);
    relight::ModelMaps& maps = bands.maps;
    summary.add(maps.summary);
    if (!writer) {
      relight::ModelMaps file = header;
      file.shadows = maps.shadows;  // Its LEDs and words.
      writer.emplace(out, width, height, file, attributes, files);
    }
    writer->write_rows(maps);
    report(progress, "write maps (rows)", bands.end_row(b), height);
  }
  writer->commit();
  return summary;
}

}  // namespace

BandFit fit_in_bands(capture::FieldStream& stream, int rows, const relight::FitOptions& fit,
                     const BandCheckpoints& checkpoints, const RankSplit& split,
                     const std::filesystem::path& out, const ExrAttributes& attributes,
                     const ProgressFn& progress, BandFitTimes& times) {
  const capture::ReflectanceField& header = stream.header();
  const int width = header.width(), height = header.height();
  Bands bands(stream, rows, checkpoints, times);
  relight::FitOptions per_band = fit;
  per_band.materials = relight::FitMaterials::kPerPixel;
  per_band.progress = {};
  const long own_rows = bands.rows_mine(split);
  long done_rows = 0;
  relight::FitTimes spent;  // This rank's, this run's.
  // Each rank's bands: normals and per-pixel fits, from an earlier run's checkpoint when there
  // is one, else fitted and kept.
  for (int b = split.rank; b < bands.count(); b += split.size) {
    const long band_rows = bands.end_row(b) - bands.first_row(b);
    if (bands.load(b, FitStage::kPerPixel)) {
      times.resumed_rows += int(band_rows);
    } else {
      const capture::ReflectanceField& band = bands.read_field(b);
      const auto normals_start = Clock::now();
      bands.normals = relight::estimate_normals(band, fit.normals);
      spent.normals += seconds_since(normals_start);
      bands.maps = relight::fit_models(band, bands.normals, per_band);
      spent.add(bands.maps.summary.times);
      bands.save(b, FitStage::kPerPixel);
    }
    report(progress, "fit (rows)", done_rows += band_rows, own_rows);
  }
  split.wait();             // Every band is in its checkpoint.
  relight::ModelMaps file;  // The maps file's header: noise (as fit_models records it), materials.
  file.noise = fit.normals.noise;
  file.noise_source = fit.noise_source;
  BandFit result;
  FitStage written = FitStage::kPerPixel;
  const auto materials_start = Clock::now();
  if (fit.materials == relight::FitMaterials::kBasis) {
    relight::BasisMaterials basis;
    if (split.root()) {
      basis = relight::find_basis_materials(header, bands.field_rows(),
                                            bands.maps_bands(FitStage::kPerPixel), fit);
    }
    broadcast(split, basis);
    if (!basis.materials.empty()) {
      written = FitStage::kMaterials;
      file.materials = basis.materials;  // Their pixels counted below, on rank 0.
      done_rows = 0;
      for (int b = split.rank; b < bands.count(); b += split.size) {
        const bool resumed = bands.load(b, FitStage::kMaterials);
        if (!resumed) {
          bands.load_finished(b, FitStage::kPerPixel);
          bands.maps.materials = basis.materials;
          for (relight::Material& m : bands.maps.materials) m.pixels = 0;  // The band's own.
          relight::assign_basis_materials(header, bands.read_field(b), bands.normals, basis, fit,
                                          bands.maps, bands.first_row(b));
          bands.save(b, FitStage::kMaterials);
        }
        done_rows += bands.end_row(b) - bands.first_row(b);
        report(progress, "materials (rows)", done_rows, own_rows, resumed ? "resumed" : "");
      }
      split.wait();
      if (split.root()) {
        // Each material's pixels: those of its pool fit and those assigned it, counted in the
        // pass that groups the scene materials.
        const relight::MapsBands assigned = [&](const relight::MapsVisitor& visit) {
          for (int b = 0; b < bands.count(); ++b) {
            bands.load_finished(b, FitStage::kMaterials);
            for (size_t k = 0; k < file.materials.size(); ++k) {
              file.materials[k].pixels += bands.maps.materials[k].pixels;
            }
            visit(bands.maps.maps, bands.first_row(b));
          }
        };
        result.summary.scene_materials = relight::group_scene_materials(assigned, file.materials);
      }
    }
  }
  spent.materials += seconds_since(materials_start);
  // Under MPI rank 1 writes the previews while rank 0 writes the maps.
  using Files = relight::ModelMapsWriter::Files;
  bands.release_field();
  if (split.rank == 1) {
    (void)write_maps(bands, written, file, width, height, out, attributes, Files::kPreviews, {});
  }
  if (!split.root()) return result;
  const int scene_materials = result.summary.scene_materials;
  const auto writing_start = Clock::now();
  result.summary = write_maps(bands, written, file, width, height, out, attributes,
                              split.size > 1 ? Files::kMaps : Files::kMapsAndPreviews, progress);
  spent.writing = seconds_since(writing_start);
  spent.reading = times.read_seconds;
  result.summary.times = spent;
  result.summary.materials = int(file.materials.size());
  result.summary.scene_materials = scene_materials;
  result.materials = file.materials;
  return result;
}

}  // namespace ls::relight
