#include "relight/compact/pca_bands.h"

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "lightstage/bands.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/scratch_file.h"

namespace ls::relight {

namespace fs = std::filesystem;

namespace {

// Split over ranks each rank finds the grams of its bands (PcaField::band_grams) and keeps them
// in a record in the checkpoint; rank 0 sums every band's in order (PcaGramBands).
constexpr const char* kGramsMagic = "lightstage pca band grams 1";

void save_grams(const fs::path& file, const PcaBandGrams& band) {
  std::vector<RecordBytes> blocks;
  for (const Eigen::MatrixXd& g : band.grams) {
    blocks.push_back({g.data(), std::size_t(g.size()) * sizeof(double)});
  }
  blocks.push_back({band.positive_sums.data(), band.positive_sums.size() * sizeof(double)});
  write_record(file, kGramsMagic,
               {{"first_row", band.first_row},
                {"grams", band.grams.size()},
                {"lights", band.grams.empty() ? 0 : band.grams[0].rows()},
                {"units", band.positive_sums.size()}},
               blocks);
}

PcaBandGrams load_grams(const fs::path& file) {
  PcaBandGrams band;
  const bool read = read_record(file, kGramsMagic, [&](const nlohmann::json& info) {
    band.first_row = info.at("first_row").get<int>();
    const auto lights = info.at("lights").get<Eigen::Index>();
    band.grams.assign(info.at("grams").get<std::size_t>(), Eigen::MatrixXd(lights, lights));
    band.positive_sums.resize(info.at("units").get<std::size_t>());
    std::vector<RecordTarget> targets;
    for (Eigen::MatrixXd& g : band.grams) {
      targets.push_back({g.data(), std::size_t(g.size()) * sizeof(double)});
    }
    targets.push_back({band.positive_sums.data(), band.positive_sums.size() * sizeof(double)});
    return std::optional<std::vector<RecordTarget>>{std::move(targets)};
  });
  if (!read) {
    throw InputError(file.string() + ": a band's Gram matrices are missing (did its rank fail?)");
  }
  return band;
}

// The basis: rank 0's from an earlier run's record, else from passes over the bands (split over
// ranks: every rank's grams of its bands, rank 0 summing them), saved in the record.
PcaField basis_in_bands(const PcaBandsInput& input, const PcaOptions& options,
                        const CheckpointDir& checkpoint, const RankSplit& split,
                        PcaSummary& summary) {
  const capture::ReflectanceField& header = input.header;
  const int height = header.height(), rows = input.rows;
  const fs::path basis_file = checkpoint.dir() / "basis.record";
  const auto grams_file = [&](int y0) {
    return checkpoint.dir() / ("grams_" + std::to_string(y0));
  };
  std::optional<PcaField> pca;
  if (split.root()) pca = PcaField::load_basis(basis_file, header, &summary);
  std::vector<double> have = {double(pca.has_value())};
  if (split.root() && !pca) {
    // Bands projected on another basis (one that could not be read back) are not kept.
    for (const auto& entry : fs::directory_iterator(checkpoint.dir())) {
      if (entry.path().filename().string().starts_with("band_")) fs::remove(entry.path());
    }
  }
  split.share(have);  // After rank 0 cleared what the others will write again.
  if (have[0] == 0 && !split.split()) {
    pca = PcaField::build_basis(header, input.bands, options, &summary);
    pca->save_basis(basis_file, summary);
  } else if (have[0] == 0) {
    capture::ReflectanceField band;
    BandPlan(height, rows).for_each_mine(split, [&](int, int y0, int y1) {
      input.read_rows(y0, y1, band);
      save_grams(grams_file(y0), PcaField::band_grams(band, options.tile_size));
    });
    split.wait();  // Every band's grams are in their records.
    if (split.root()) {
      const PcaGramBands grams = [&](const std::function<void(const PcaBandGrams&)>& visit) {
        for (int y0 = 0; y0 < height; y0 += rows) visit(load_grams(grams_file(y0)));
      };
      // The held-out rank rule's pass reads every band here, as one process would.
      pca = PcaField::build_basis(header, grams, capture::bands_of(input.read_rows, height, rows),
                                  options, &summary);
      pca->save_basis(basis_file, summary);
    }
  }
  split.wait();  // The basis is in its record.
  if (!pca) pca = PcaField::load_basis(basis_file, header, nullptr);
  if (!pca) throw InputError(basis_file.string() + ": rank 0's basis cannot be read here");
  return *std::move(pca);
}

}  // namespace

PcaField pca_in_bands(const PcaBandsInput& input, const PcaOptions& options,
                      const CheckpointDir& checkpoint, const fs::path& out, const RankSplit& split,
                      PcaSummary& summary, int& resumed_rows, const ProgressFn& progress) {
  const int height = input.header.height(), rows = input.rows;
  PcaField pca = basis_in_bands(input, options, checkpoint, split, summary);
  const std::size_t row_floats = pca.coefficients_per_row();
  ScratchFile spill(checkpoint.dir() / "coefficients.spill",
                    "the coefficients of a field compressed in bands are spilled beside the "
                    "output: they need its size free there",
                    ScratchFile::Lifetime::kKept);
  capture::ReflectanceField band;
  std::vector<float> coefs;
  BandPlan(height, rows).for_each_mine(split, [&](int, int y0, int y1) {
    const fs::path record = checkpoint.dir() / ("band_" + std::to_string(y0));
    const bool resumed = fs::exists(record);
    if (resumed) {
      resumed_rows += y1 - y0;
    } else {
      input.read_rows(y0, y1, band);
      coefs.resize(std::size_t(y1 - y0) * row_floats);
      pca.project_band(band, coefs.data());
      spill.write(coefs.data(), coefs.size(), std::size_t(y0) * row_floats);
      spill.sync();  // The rows are there before their record says so.
      write_file_atomic(record, "");
    }
    report(progress, "coefficients (rows)", y1, height, resumed ? "resumed" : "");
  });
  split.wait();  // Every band's coefficients are in the spill.
  if (!split.root()) return pca;
  spill.reopen();  // The others' rows as they wrote them (a file system shared between nodes).
  pca.write(out,
            [&](int y, float* row) { spill.read(row, row_floats, std::size_t(y) * row_floats); });
  return pca;
}

}  // namespace ls::relight
