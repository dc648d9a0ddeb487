#include "relight/compact/pca_field.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <mutex>
#include <sstream>

#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"

namespace ls::relight {

namespace {

void ensure_rgb_image(Image& out, int width, int height) {
  if (out.width != width || out.height != height || out.channels != 3 ||
      out.pixels.size() != size_t(width) * height * 3) {
    out = Image(width, height, 3);
  }
  out.channel_names = {"R", "G", "B"};
}

// Sum over the (pixel, channel) samples of a pixel rectangle of v v^T, v = the L light samples.
Eigen::MatrixXd gram_of_rect(const capture::ReflectanceField& field, int x0, int y0, int x1,
                             int y1) {
  const int num_lights = field.num_lights();
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(num_lights, num_lights);
  constexpr int kBlockPixels = 128;  // Samples per rank update: 3 x 128 columns.
  Eigen::MatrixXd block(num_lights, 3 * kBlockPixels);
  int filled = 0;
  auto flush = [&] {
    if (filled == 0) return;
    gram.selfadjointView<Eigen::Lower>().rankUpdate(block.leftCols(3 * filled));
    filled = 0;
  };
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) {
      const float* v = field.pixel(x, y);
      for (int c = 0; c < 3; ++c) {
        double* col = block.col(3 * filled + c).data();
        for (int l = 0; l < num_lights; ++l) col[l] = v[3 * l + c];
      }
      if (++filled == kBlockPixels) flush();
    }
  }
  flush();
  return gram.selfadjointView<Eigen::Lower>();
}

struct Spectrum {
  Eigen::VectorXd values;   // Descending, >= 0.
  Eigen::MatrixXd vectors;  // Columns in the same order.
};

Spectrum eigen_descending(const Eigen::MatrixXd& gram) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(gram);
  LS_CHECK(solver.info() == Eigen::Success, "PCA: eigen-decomposition of the Gram matrix failed");
  const int n = int(gram.rows());
  Spectrum s{Eigen::VectorXd(n), Eigen::MatrixXd(n, n)};
  for (int j = 0; j < n; ++j) {
    s.values(j) = std::max(0.0, solver.eigenvalues()(n - 1 - j));
    s.vectors.col(j) = solver.eigenvectors().col(n - 1 - j);
  }
  return s;
}

// Held-out error of every rank (see PcaRankRule::kHeldOutLights): the training lights' Gram is a
// sub-matrix of the full one, so only its eigen-decomposition and the predictions are new.
std::vector<double> held_out_errors(const capture::ReflectanceField& field,
                                    const capture::FieldBands& bands, const Eigen::MatrixXd& gram,
                                    int max_rank, double sigma_rad) {
  std::vector<int> train, test;
  for (int l = 0; l < field.num_lights(); ++l) {
    if (!field.lights()[l].valid) continue;
    (l % 5 == 2 ? test : train).push_back(l);
  }
  if (test.empty() || train.size() < 2) return {};
  const int nt = int(train.size()), nh = int(test.size());
  Eigen::MatrixXd gram_train(nt, nt);
  for (int i = 0; i < nt; ++i) {
    for (int j = 0; j < nt; ++j) gram_train(i, j) = gram(train[i], train[j]);
  }
  const Spectrum spectrum = eigen_descending(gram_train);
  const int k_max = std::min(max_rank, nt);
  const Eigen::MatrixXd basis = spectrum.vectors.leftCols(k_max);  // nt x K
  std::vector<Eigen::Vector3d> train_dirs;
  for (int l : train) train_dirs.push_back(field.lights()[l].dir_in_stage);
  const LightInterpolator interpolator(capture::lights_along(train_dirs), sigma_rad);
  Eigen::MatrixXd r(nh, nt);
  std::vector<double> w;
  for (int h = 0; h < nh; ++h) {
    interpolator.weights_at(field.lights()[test[h]].dir_in_stage, w);
    for (int i = 0; i < nt; ++i) r(h, i) = w[i];
  }
  const Eigen::MatrixXf predict = (r * basis).cast<float>();        // nh x K
  const Eigen::MatrixXf project = basis.transpose().cast<float>();  // K x nt
  const long pixels = long(field.width()) * field.height();
  const long stride = std::max<long>(1, pixels / 65536);
  std::mutex mutex;
  std::vector<double> errors(k_max + 1, 0.0);
  const long width = field.width();
  bands([&](const capture::ReflectanceField& band) {
    // The sampled pixels (every stride-th of the frame) in this band's rows.
    const long first = band.first_row() * width, end = first + band.height() * width;
    tbb::parallel_for(
        tbb::blocked_range<long>((first + stride - 1) / stride, (end + stride - 1) / stride),
        [&](const tbb::blocked_range<long>& range) {
          std::vector<double> local(k_max + 1, 0.0);
          Eigen::VectorXf v(nt), truth(nh), pred(nh), c(k_max);
          for (long i = range.begin(); i < range.end(); ++i) {
            const long p = i * stride - first;
            const float* values = band.pixel(int(p % width), int(p / width));
            for (int ch = 0; ch < 3; ++ch) {
              for (int t = 0; t < nt; ++t) v(t) = values[3 * train[t] + ch];
              for (int h = 0; h < nh; ++h) truth(h) = values[3 * test[h] + ch];
              c.noalias() = project * v;
              pred.setZero();
              local[0] += (pred - truth).squaredNorm();
              for (int k = 0; k < k_max; ++k) {
                pred += predict.col(k) * c(k);
                local[k + 1] += (pred - truth).squaredNorm();
              }
            }
          }
          std::lock_guard<std::mutex> lock(mutex);
          for (int k = 0; k <= k_max; ++k) errors[k] += local[k];
        });
  });
  const double count = 3.0 * nh * double((pixels + stride - 1) / stride);
  for (double& e : errors) e /= count;
  return errors;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// PcaField

std::string PcaOptions::validate() const {
  if (rank < 0)
    return "rank: expected 0 (automatic) or a positive number, got " + std::to_string(rank);
  if (max_rank < 1) return "max_rank: expected >= 1, got " + std::to_string(max_rank);
  if (tile_size < 0)
    return "tile_size: expected 0 (global) or > 0, got " + std::to_string(tile_size);
  if (!(rbf_sigma_rad >= 0 && rbf_sigma_rad < M_PI)) return "rbf_sigma_rad: expected [0, pi)";
  if (!(keep_above_noise > 0)) return "keep_above_noise: expected > 0";
  if (!(held_out_tolerance_db >= 0 && std::isfinite(held_out_tolerance_db))) {
    return "held_out_tolerance_db: expected >= 0";
  }
  return "";
}

int PcaSummary::held_out_best_rank() const {
  if (held_out_ms.size() < 2) return 0;
  return int(std::min_element(held_out_ms.begin() + 1, held_out_ms.end()) - held_out_ms.begin());
}

std::string PcaSummary::to_string() const {
  std::ostringstream s;
  s << "PCA rank " << rank << (auto_rank ? " (automatic)" : "");
  if (const int best = held_out_best_rank();
      auto_rank && best > 0 && rank < int(held_out_ms.size())) {
    s << std::setprecision(3) << " from held-out LEDs: "
      << 10 * std::log10(held_out_ms[size_t(rank)] / held_out_ms[size_t(best)])
      << " dB from the best (rank " << best << " of the " << held_out_ms.size() - 1 << " tried)"
      << std::setprecision(6);
  }
  s << ", noise variance " << noise_variance << " per value ("
    << (noise_measured ? "measured: " : "estimated: ") << noise_method << "), residual "
    << (rank < int(residual_ms.size()) ? residual_ms[rank] : 0) << " per value, " << seconds
    << " s";
  return s.str();
}

int PcaField::tiles_x() const {
  return tile_size_ > 0 ? (width_ - 1) / tile_size_ + 1 : 1;  // No overflow for any tile size.
}

int PcaField::tile_of(int x, int y) const {
  return tile_size_ > 0 ? (y / tile_size_) * tiles_x() + x / tile_size_ : 0;
}

namespace {

// The global Gram matrix is summed over sub-bands of this many rows (computed in parallel): about
// 4096 pixels, a power of two so that bands of a tiled file's tile rows hold whole sub-bands.
int gram_rows(int width) { return int(std::bit_floor(unsigned(std::max(1, 4096 / width)))); }

// The positive values of rows [y0, y1) of a band, summed in order (the noise floor's).
double positive_sum_of(const capture::ReflectanceField& band, int y0, int y1) {
  double sum = 0;
  const std::size_t row = std::size_t(band.width()) * 3 * band.num_lights();
  for (std::size_t i = std::size_t(y0) * row; i < std::size_t(y1) * row; ++i) {
    const float v = band.values()[i];
    sum += v > 0 ? v : 0;
  }
  return sum;
}

}  // namespace

PcaBandGrams PcaField::band_grams(const capture::ReflectanceField& band, int tile_size) {
  const int width = band.width(), height = band.frame_height(), y0 = band.first_row();
  const int y1 = y0 + band.height();
  const bool tiles = tile_size > 0 && tile_size < std::max(width, height);
  const int unit = tiles ? tile_size : gram_rows(width);  // Rows of a sub-band or tile row.
  const int units = (band.height() + unit - 1) / unit;
  PcaBandGrams out;
  out.first_row = y0;
  const int tiles_x = tiles ? (width + tile_size - 1) / tile_size : 1;
  out.grams.resize(std::size_t(units) * tiles_x);
  out.positive_sums.resize(std::size_t(units));
  tbb::parallel_for(0, int(out.grams.size()), [&](int g) {
    const int u = g / tiles_x, x0 = (g % tiles_x) * tile_size * tiles;
    const int x1 = tiles ? std::min(width, x0 + tile_size) : width;
    out.grams[std::size_t(g)] =
        gram_of_rect(band, x0, u * unit, x1, std::min(y1 - y0, (u + 1) * unit));
  });
  for (int u = 0; u < units; ++u) {
    out.positive_sums[std::size_t(u)] =
        positive_sum_of(band, u * unit, std::min(y1 - y0, (u + 1) * unit));
  }
  return out;
}

namespace {

// Gram matrices per tile of tile_size pixels (0: one, the sum of every sub-band's in order) from
// every band's grams, in band order, and the sum of the positive values (for the noise floor).
std::vector<Eigen::MatrixXd> tile_gram_matrices(const capture::ReflectanceField& header,
                                                const PcaGramBands& grams, int tile_size,
                                                int tiles_x, int tiles_y, double* positive_sum) {
  const int num_lights = header.num_lights();
  std::vector<Eigen::MatrixXd> tile_grams(size_t(tiles_x) * tiles_y);
  if (tile_size == 0) tile_grams[0] = Eigen::MatrixXd::Zero(num_lights, num_lights);
  *positive_sum = 0;
  grams([&](const PcaBandGrams& band) {
    if (tile_size > 0) {
      const size_t first = size_t(band.first_row / tile_size) * tiles_x;
      for (size_t g = 0; g < band.grams.size(); ++g) tile_grams[first + g] = band.grams[g];
    } else {
      for (const auto& g : band.grams) tile_grams[0] += g;
    }
    if (header.noise.measured) {
      for (const double p : band.positive_sums) *positive_sum += p;
    }
  });
  return tile_grams;
}

// The noise floor per value: from the field's measured noise, else from the spectrum's tail.
void estimate_noise_floor(const capture::ReflectanceField& field, const Spectrum& global,
                          double positive_sum, int valid_lights, double samples, double values,
                          PcaSummary& sum) {
  if (field.noise.measured) {
    sum.noise_variance =
        field.noise.read_variance + field.noise.shot_variance_per_unit * positive_sum / values;
    sum.noise_measured = true;
    sum.noise_method = field.noise.method.empty() ? "field noise" : field.noise.method;
    return;
  }
  std::vector<double> spectrum(global.values.data(),
                               global.values.data() + std::max(valid_lights, 1));
  const size_t tenth = spectrum.size() - 1 - (spectrum.size() - 1) / 10;  // Descending order.
  const double spread = std::pow(1 - std::sqrt(std::max(valid_lights, 1) / samples), 2);
  sum.noise_variance = spectrum[tenth] / (samples * spread);
  sum.noise_measured = false;
  sum.noise_method = "10th percentile of the PCA eigenvalues (Marchenko-Pastur lower edge)";
}

// The rank: options.rank, or (0) the first component at the noise floor, or the best on held-out
// LEDs (PcaRankRule::kHeldOutLights).
int choose_rank(const capture::ReflectanceField& field, const capture::FieldBands& bands,
                const PcaOptions& options, const Spectrum& global,
                const Eigen::MatrixXd& global_gram, int valid_lights, double samples,
                PcaSummary& sum) {
  const int max_rank = std::min(options.max_rank, std::max(valid_lights, 1));
  int rank = options.rank;
  if (rank == 0) {
    sum.auto_rank = true;
    rank = max_rank;
    for (int k = 1; k <= max_rank; ++k) {
      // Component k (0-based) is the first one left out.
      if (k >= valid_lights ||
          global.values(k) / samples <= options.keep_above_noise * sum.noise_variance) {
        rank = k;
        break;
      }
    }
  }
  if (options.rank == 0 && options.rank_rule == PcaRankRule::kHeldOutLights) {
    sum.held_out_ms = held_out_errors(field, bands, global_gram, max_rank, options.rbf_sigma_rad);
    if (const int best_rank = sum.held_out_best_rank(); best_rank > 0) {
      const double best = sum.held_out_ms[size_t(best_rank)];
      const double within = std::pow(10.0, options.held_out_tolerance_db / 10);
      for (int k = 1; k < int(sum.held_out_ms.size()); ++k) {
        if (sum.held_out_ms[k] <= within * best) {
          rank = k;
          break;
        }
      }
    }
  }
  return std::min(rank, max_rank);
}

}  // namespace

PcaField PcaField::build(const capture::ReflectanceField& field, const PcaOptions& options,
                         PcaSummary* summary) {
  return build(field, capture::whole_field(field), options, summary);
}

int PcaField::band_alignment(int width, int height, const PcaOptions& options) {
  return options.tile_size > 0 && options.tile_size < std::max(width, height) ? options.tile_size
                                                                              : gram_rows(width);
}

PcaField PcaField::build(const capture::ReflectanceField& field, const capture::FieldBands& bands,
                         const PcaOptions& options, PcaSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  PcaSummary sum;
  PcaField out = build_basis(field, bands, options, &sum);
  out.coefs_.assign(size_t(out.width_) * out.height_ * out.rank_ * 3, 0.0f);
  bands([&](const capture::ReflectanceField& band) {
    out.project_band(band,
                     out.coefs_.data() + size_t(band.first_row()) * out.coefficients_per_row());
  });
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (summary) *summary = sum;
  return out;
}

void PcaField::project_band(const capture::ReflectanceField& band, float* coefs) const {
  const int y0 = band.first_row(), num_lights = band.num_lights(), rank = rank_;
  tbb::parallel_for(tbb::blocked_range<int>(y0, y0 + band.height()), [&](const auto& rows) {
    for (int y = rows.begin(); y < rows.end(); ++y) {
      for (int x = 0; x < width_; ++x) {
        const Eigen::MatrixXf& basis = bases_[tile_of(x, y)];
        Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>> v(
            band.pixel(x, y - y0), num_lights, 3);
        Eigen::Map<Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>> c(
            coefs + (size_t(y - y0) * width_ + x) * rank * 3, rank, 3);
        c.noalias() = basis.transpose() * v;
      }
    }
  });
}

PcaField PcaField::build_basis(const capture::ReflectanceField& field,
                               const capture::FieldBands& bands, const PcaOptions& options,
                               PcaSummary* summary) {
  const int tile_size = options.tile_size;
  return build_basis(
      field,
      [&](const std::function<void(const PcaBandGrams&)>& visit) {
        bands([&](const capture::ReflectanceField& band) { visit(band_grams(band, tile_size)); });
      },
      bands, options, summary);
}

PcaField PcaField::build_basis(const capture::ReflectanceField& field, const PcaGramBands& grams,
                               const capture::FieldBands& bands, const PcaOptions& options,
                               PcaSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  if (const std::string e = options.validate(); !e.empty()) {
    throw InputError(field.source + ": PCA options: " + e);
  }
  const int width = field.width(), height = field.height(), num_lights = field.num_lights();
  if (width == 0 || height == 0 || num_lights == 0) {
    throw InputError(field.source + ": field: expected pixels and lights to compress, got " +
                     std::to_string(width) + "x" + std::to_string(height) + " pixels and " +
                     std::to_string(num_lights) + " lights");
  }
  PcaField out;
  out.width_ = width;
  out.height_ = height;
  out.tile_size_ = options.tile_size >= std::max(width, height) ? 0 : options.tile_size;
  out.lights_ = kept_lights(field.lights());
  int valid_lights = 0;
  for (const capture::FieldLight& light : out.lights_) valid_lights += light.valid ? 1 : 0;

  // Gram matrices per tile (global: bands of rows, summed).
  const int tx = out.tiles_x();
  const int ty = out.tile_size_ > 0 ? (height + out.tile_size_ - 1) / out.tile_size_ : 1;
  double positive_sum = 0;
  const std::vector<Eigen::MatrixXd> tile_grams =
      tile_gram_matrices(field, grams, out.tile_size_, tx, ty, &positive_sum);
  Eigen::MatrixXd global_gram = Eigen::MatrixXd::Zero(num_lights, num_lights);
  for (const auto& g : tile_grams) global_gram += g;
  const Spectrum global = eigen_descending(global_gram);
  std::vector<Spectrum> spectra(tile_grams.size());
  if (out.tile_size_ > 0) {
    tbb::parallel_for(0, int(tile_grams.size()),
                      [&](int t) { spectra[t] = eigen_descending(tile_grams[t]); });
  } else {
    spectra[0] = global;
  }

  // Residual per value after k terms, for the bases actually used.
  const double samples = 3.0 * double(width) * height;  // (pixel, channel) vectors.
  const double values = samples * std::max(valid_lights, 1);
  std::vector<double> residual(num_lights + 1, 0.0);
  for (const Spectrum& s : spectra) {
    double tail = 0;
    for (int k = num_lights; k >= 0; --k) {
      residual[k] += tail / values;
      if (k > 0) tail += s.values(k - 1);
    }
  }

  PcaSummary sum;
  sum.mean_square = global.values.sum() / values;
  estimate_noise_floor(field, global, positive_sum, valid_lights, samples, values, sum);
  const int rank =
      choose_rank(field, bands, options, global, global_gram, valid_lights, samples, sum);
  out.rank_ = rank;
  for (const Spectrum& s : spectra) out.bases_.push_back(s.vectors.leftCols(rank).cast<float>());

  out.sigma_rad_ = options.rbf_sigma_rad;
  out.interpolator_ = LightInterpolator(out.lights_, options.rbf_sigma_rad);
  out.sigma_rad_ = out.interpolator_.sigma_rad();

  sum.rank = rank;
  sum.residual_ms = residual;
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (summary) *summary = sum;
  return out;
}

std::string PcaField::name() const {
  return "pca k=" + std::to_string(rank_) +
         (tile_size_ > 0 ? " tile " + std::to_string(tile_size_) : "");
}

double PcaField::bytes_per_pixel() const {
  const double pixels = double(width_) * height_;
  const double basis_bytes = double(bases_.size()) * num_lights() * rank_ * sizeof(float);
  return 3.0 * rank_ * sizeof(float) + (pixels > 0 ? basis_bytes / pixels : 0);
}

float PcaField::reconstruct(int x, int y, int light, int c) const {
  const Eigen::MatrixXf& basis = bases_[tile_of(x, y)];
  const float* coef = coefs_.data() + (size_t(y) * width_ + x) * rank_ * 3;
  float v = 0;
  for (int j = 0; j < rank_; ++j) v += basis(light, j) * coef[3 * j + c];
  return v;
}

std::vector<capture::FieldLight> PcaField::kept_lights(
    const std::vector<capture::FieldLight>& lights) {
  std::vector<capture::FieldLight> kept;
  kept.reserve(lights.size());
  for (size_t l = 0; l < lights.size(); ++l) {
    kept.push_back({int(l), lights[l].dir_in_stage, lights[l].valid});
  }
  return kept;
}

capture::ReflectanceField PcaField::header() const {
  return capture::ReflectanceField::without_values(width_, height_, lights_);
}

capture::FieldBands PcaField::reconstruction_bands(int rows) const {
  LS_CHECK(rows > 0, "PcaField::reconstruction_bands: rows must be positive");
  return [this, rows](const capture::BandVisitor& visit) {
    const capture::ReflectanceField head = header();
    for (int y0 = 0; y0 < height_; y0 += rows) {
      const int band_rows = std::min(rows, height_ - y0);
      capture::ReflectanceField band(width_, band_rows, head.lights());
      band.set_band(y0, height_);
      tbb::parallel_for(0, band_rows, [&](int y) {
        for (int x = 0; x < width_; ++x) {
          float* v = band.pixel(x, y);
          for (int l = 0; l < num_lights(); ++l) {
            for (int c = 0; c < 3; ++c) v[3 * l + c] = reconstruct(x, y0 + y, l, c);
          }
        }
      });
      visit(band);
    }
  };
}

std::vector<float> PcaField::led_image(int led) const {
  LS_CHECK(led >= 0 && led < num_lights(), "PcaField::led_image: no light " + std::to_string(led));
  std::vector<float> one_led(3 * size_t(num_lights()), 0.0f);
  std::fill_n(one_led.begin() + 3 * long(led), 3, 1.0f);
  Image image;
  relight_led_weights_into(one_led.data(), image);
  return std::move(image.pixels);
}

void PcaField::relight_into(const LightingForModels& lights, Image& out) const {
  const std::vector<float> e = interpolator_.led_irradiance(lights);
  relight_led_weights_into(e.data(), out);
}

void PcaField::relight_led_weights_into(const float* led_irradiance_rgb, Image& out) const {
  ensure_rgb_image(out, width_, height_);
  const int num = num_lights();
  Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>> e(led_irradiance_rgb,
                                                                               num, 3);
  // Per tile: the lighting in the basis, k x 3 (row-major, like the coefficients).
  std::vector<Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>> w(bases_.size());
  for (size_t t = 0; t < bases_.size(); ++t) w[t].noalias() = bases_[t].transpose() * e;
  const int count = 3 * rank_;
  float* out_pixels = out.pixels.data();
  const int rows_per_task = std::max(1, 16384 / std::max(1, width_));
  tbb::parallel_for(
      tbb::blocked_range<int>(0, height_, rows_per_task), [&](const tbb::blocked_range<int>& rows) {
        for (int y = rows.begin(); y < rows.end(); ++y) {
          for (int x = 0; x < width_; ++x) {
            const float* __restrict coef = coefs_.data() + (size_t(y) * width_ + x) * count;
            const float* __restrict wt = w[tile_of(x, y)].data();
            float r = 0, g = 0, b = 0;
            for (int i = 0; i < count; i += 3) {
              r += coef[i] * wt[i];
              g += coef[i + 1] * wt[i + 1];
              b += coef[i + 2] * wt[i + 2];
            }
            float* o = out_pixels + (size_t(y) * width_ + x) * 3;
            o[0] = r;
            o[1] = g;
            o[2] = b;
          }
        }
      });
}

std::vector<float> PcaField::project_led_weights(const float* led_irradiance_rgb) const {
  Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>> e(led_irradiance_rgb,
                                                                               num_lights(), 3);
  std::vector<float> out(bases_.size() * size_t(rank_) * 3);
  for (size_t t = 0; t < bases_.size(); ++t) {
    Eigen::Map<Eigen::Matrix<float, Eigen::Dynamic, 3, Eigen::RowMajor>> w(
        out.data() + t * size_t(rank_) * 3, rank_, 3);
    w.noalias() = bases_[t].transpose() * e;
  }
  return out;
}

}  // namespace ls::relight
