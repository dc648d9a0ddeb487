// Quantised PCA planes with RBF or bilinear interpolation between the lights
// (relight/compact/plane_field.h).
#include "relight/compact/plane_field.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <optional>
#include <tuple>

#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "relight/compact/leading_eigenvectors.h"
#include "relight/compact/plane_interpolation.h"

namespace ls::relight {

namespace {

// Basis row p's value i (of D = dims x 3) as stored: the mean in display units (p = 0), else
// eigenvector p - 1.
double basis_value(const PlaneField& f, int p, size_t i) {
  const double byte = f.basis[size_t(p) * size_t(f.dims()) * 3 + i];
  return p == 0 ? byte / 255.0 : (byte - 127.0) / f.range[size_t(p - 1)];
}

// The decoded basis: (planes + 1) x D.
Eigen::MatrixXd decoded_basis(const PlaneField& f) {
  const Eigen::Index d = Eigen::Index(f.dims()) * 3;
  Eigen::MatrixXd out(f.planes + 1, d);
  for (int p = 0; p <= f.planes; ++p) {
    for (Eigen::Index i = 0; i < d; ++i) out(p, i) = basis_value(f, p, size_t(i));
  }
  return out;
}

}  // namespace

const char* to_string(PlaneInterpolation interpolation) {
  return interpolation == PlaneInterpolation::kRbf ? "rbf" : "bilinear";
}

std::string PlaneFieldOptions::validate() const {
  if (planes == 0 && !from_data) return "planes: 0 (from the data) needs from_data";
  if (planes != 0 && (planes < 3 || planes % 3 != 0)) {
    return "planes: expected a positive multiple of 3 (OpenLIME reads three a JPEG), got " +
           std::to_string(planes);
  }
  if (!(sigma > 0 && sigma < 10)) return "sigma: expected (0, 10)";
  if (resolution < 3 || resolution > 20) return "resolution: expected 3..20 (relight's range)";
  if (!(regularization >= 0 && std::isfinite(regularization))) return "regularization: >= 0";
  if (!(gain >= 0 && std::isfinite(gain))) return "gain: expected >= 0";
  if (max_pca_pixels < 1) return "max_pca_pixels: expected >= 1";
  return {};
}

int PlaneField::dims() const {
  return interpolation == PlaneInterpolation::kRbf ? int(lights.size()) : resolution * resolution;
}

std::string PlaneField::name() const {
  return std::string(to_string(interpolation)) + " " + std::to_string(planes) + " planes";
}

double PlaneField::bytes_per_pixel() const {
  const double pixels = std::max(1.0, double(width_) * height_);
  if (stored_bytes > 0) return double(stored_bytes) / pixels;
  return planes + double(basis.size()) / pixels;
}

namespace {

// A pixel's display values at the `used` lights (sRGB-encoded, light i channel k at 3 i + k: the
// "raw" vector), and its vector in the basis's space: the raw vector itself for RBF, resampled to
// the bilinear grid's nodes otherwise. The resampling is linear, so statistics and coefficients are
// taken on the raw vectors and carried through it once, not per pixel.
struct PixelVectors {
  std::vector<int> used;     // The field's lights the basis is built on.
  Eigen::MatrixXd resample;  // D x 3 used (dims x used per channel); empty: identity (RBF).
  float gain = 1;

  Eigen::Index raw_size() const { return 3 * Eigen::Index(used.size()); }
  // False, and v untouched, for a pixel whose raw vector is 0 (outside an imported set's mask).
  bool raw(const float* values, double* v) const {
    bool any = false;
    for (size_t i = 0; i < used.size() && !any; ++i) {
      for (int k = 0; k < 3; ++k) any = any || values[3 * used[i] + k] != 0;
    }
    if (!any) return false;
    for (size_t i = 0; i < used.size(); ++i) {
      for (int k = 0; k < 3; ++k)
        v[3 * i + size_t(k)] = srgb_encode(gain * values[3 * used[i] + k]);
    }
    return true;
  }
};

// The grid's values from the lights' per channel, as one D x 3 n matrix on raw vectors.
Eigen::MatrixXd per_channel(const Eigen::MatrixXd& resample) {
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(3 * resample.rows(), 3 * resample.cols());
  for (Eigen::Index j = 0; j < resample.rows(); ++j) {
    for (Eigen::Index i = 0; i < resample.cols(); ++i) {
      for (int k = 0; k < 3; ++k) out(3 * j + k, 3 * i + k) = resample(j, i);
    }
  }
  return out;
}

// The valid lights in front of the image plane: their directions into out.lights, their indices
// returned.
std::vector<int> place_lights(const capture::ReflectanceField& field, PlaneField& out) {
  std::vector<int> used;
  for (int l = 0; l < field.num_lights(); ++l) {
    const Eigen::Vector3d d = field.lights()[size_t(l)].dir_in_stage.normalized();
    if (!field.lights()[size_t(l)].valid || !(d.z() > 0)) continue;
    used.push_back(l);
    // As info.json prints them (3 decimals), so that this and the files read back render alike.
    out.lights.push_back((d * 1000).array().round() / 1000);
  }
  return used;
}

struct PixelStatistics {
  Eigen::RowVectorXd mean;
  Eigen::MatrixXd covariance;

  // The statistics of the vectors resample * v (resample empty: these).
  PixelStatistics resampled(const Eigen::MatrixXd& resample) const {
    if (resample.size() == 0) return *this;
    return {mean * resample.transpose(), resample * covariance * resample.transpose()};
  }
};

// Row slices of a block of pixel vectors, each added to its own Gram matrix by its own task and
// the matrices summed at the end: the same sums in the same order on any number of threads.
constexpr int kGramSlices = 4;

// The mean and covariance of the raw vectors over evenly strided pixels (frame index a multiple
// of the stride), accumulated in blocks; with kept_rows (one zero row per pixel taken), each
// pixel's raw vector too.
PixelStatistics strided_statistics(const capture::ReflectanceField& field,
                                   const capture::FieldBands& bands,
                                   const PixelVectors& pixel_vector, long stride,
                                   Eigen::MatrixXd* kept_rows = nullptr) {
  const long width = field.width();
  const Eigen::Index d = pixel_vector.raw_size();
  std::vector<Eigen::MatrixXd> grams(kGramSlices, Eigen::MatrixXd::Zero(d, d));
  Eigen::RowVectorXd sum = Eigen::RowVectorXd::Zero(d);
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> block(1024, d);
  long taken = 0, rows = 0;
  const auto flush = [&] {
    const long slice = (rows + kGramSlices - 1) / kGramSlices;
    tbb::parallel_for(0, kGramSlices, [&](int k) {
      const long first = k * slice, count = std::min(rows, first + slice) - first;
      if (count <= 0) return;
      grams[size_t(k)].selfadjointView<Eigen::Lower>().rankUpdate(
          block.middleRows(first, count).transpose());
    });
    rows = 0;
  };
  bands([&](const capture::ReflectanceField& band) {
    const long first = band.first_row() * width, end = first + long(band.height()) * width;
    for (long p = (first + stride - 1) / stride * stride; p < end; p += stride) {
      ++taken;  // A zero vector counts, adding nothing to the sums.
      if (!pixel_vector.raw(band.pixel(int(p % width), int((p - first) / width)),
                            block.row(rows).data())) {
        continue;
      }
      if (kept_rows) kept_rows->row(taken - 1) = block.row(rows);
      sum += block.row(rows++);
      if (rows == block.rows()) flush();
    }
  });
  flush();
  for (int k = 1; k < kGramSlices; ++k) grams[0] += grams[size_t(k)];
  PixelStatistics out;
  out.mean = sum / double(taken);
  out.covariance = Eigen::MatrixXd(grams[0].selfadjointView<Eigen::Lower>()) / double(taken) -
                   out.mean.transpose() * out.mean;
  return out;
}

// The pixel vectors' mean and the covariance's leading eigenvectors (largest first): the basis
// of up to that many planes.
struct PrincipalAxes {
  Eigen::RowVectorXd mean;
  Eigen::MatrixXd eigenvectors;
};

PrincipalAxes principal_axes(const PixelStatistics& statistics, int planes) {
  return {statistics.mean, leading_eigenvectors(statistics.covariance, planes).vectors};
}

// The planes the options' choice may try at most (choose_plane_options): its axes are found for
// this many at once.
constexpr int kMostChoicePlanes = 30;

// The training sample of the options' choice, which builds a basis for every option it tries on
// the same pixels: their raw vectors (one row each) and statistics, made once, and the axes of the
// last grid tried (RBF's vectors are the raw ones whatever sigma; a bilinear grid's follow from the
// raw statistics), so that the eigensolve, most of a build, runs once per grid.
struct TrainingVectors {
  Eigen::MatrixXd rows;  // pixels x raw size; empty until first used.
  PixelStatistics raw;
  std::tuple<int, double, double> grid{-1, 0.0, 0.0};  // What `axes` were made for.
  PrincipalAxes axes;
  // The last field built, for its grid and planes: RBF's sigma changes only how it is displayed.
  std::optional<PlaneField> built;
};

std::tuple<int, double, double> grid_of(const PlaneFieldOptions& options) {
  if (options.interpolation == PlaneInterpolation::kRbf) return {0, 0.0, 0.0};
  return {options.resolution, options.sigma, options.regularization};
}

// The basis as stored, into out.basis and out.range: the mean truncated to a byte, each of the
// covariance's largest eigenvectors scaled to +-127.
void store_basis(const PrincipalAxes& axes, PlaneField& out) {
  const Eigen::Index d = axes.mean.size();
  out.basis.resize(size_t(out.planes + 1) * size_t(d));
  out.range.resize(size_t(out.planes));
  for (Eigen::Index i = 0; i < d; ++i) {
    out.basis[size_t(i)] = uint8_t(std::clamp(axes.mean(i) * 255.0, 0.0, 255.0));
  }
  for (int p = 0; p < out.planes; ++p) {
    const Eigen::VectorXd e = axes.eigenvectors.col(p);
    const double largest = e.cwiseAbs().maxCoeff();
    out.range[size_t(p)] = float(largest > 0 ? 127.0 / largest : 1.0);
    for (Eigen::Index i = 0; i < d; ++i) {
      out.basis[size_t(p + 1) * size_t(d) + size_t(i)] =
          uint8_t(std::clamp(127.0 + out.range[size_t(p)] * e(i), 0.0, 255.0));
    }
  }
}

// The least-squares fit of a pixel's vector to the basis as stored (relight projects on the
// unquantised one), on its raw vector: coefficients (code units, 0..255 scale) = solve * raw -
// offset.
struct CoefficientFit {
  Eigen::MatrixXd solve;   // planes x raw size
  Eigen::VectorXd offset;  // planes

  CoefficientFit(const PlaneField& f, const Eigen::MatrixXd& resample) {
    const Eigen::MatrixXd stored = decoded_basis(f);
    const Eigen::MatrixXd eigen_rows = stored.bottomRows(f.planes);
    const Eigen::MatrixXd on_basis =
        (eigen_rows * eigen_rows.transpose()).ldlt().solve(eigen_rows) * 255.0;  // planes x D
    solve = resample.size() == 0 ? on_basis : Eigen::MatrixXd(on_basis * resample);
    offset = on_basis * stored.row(0).transpose();
  }
};

// Each pixel's coefficients (pixels x planes, each pixel's planes together) from its raw vector
// in `rows`.
std::vector<float> fit_coefficients(const Eigen::MatrixXd& rows, const CoefficientFit& fit) {
  const Eigen::MatrixXf c =
      ((fit.solve * rows.transpose()).colwise() - fit.offset).cast<float>();  // planes x pixels
  return std::vector<float>(c.data(), c.data() + c.size());
}

// The same over the field's bands, each pixel's raw vector made as it is fitted.
std::vector<float> fit_coefficients(const capture::FieldBands& bands,
                                    const PixelVectors& pixel_vector, const CoefficientFit& fit,
                                    int width, long pixels) {
  const int planes = int(fit.offset.size());
  std::vector<float> coefficients(size_t(pixels) * size_t(planes));
  bands([&](const capture::ReflectanceField& band) {
    tbb::parallel_for(tbb::blocked_range<int>(0, band.height()), [&](const auto& band_rows) {
      Eigen::VectorXd raw(pixel_vector.raw_size());
      for (int y = band_rows.begin(); y < band_rows.end(); ++y) {
        for (int x = 0; x < band.width(); ++x) {
          const Eigen::VectorXd c = pixel_vector.raw(band.pixel(x, y), raw.data())
                                        ? Eigen::VectorXd(fit.solve * raw - fit.offset)
                                        : Eigen::VectorXd(-fit.offset);
          float* to = coefficients.data() +
                      (size_t(band.first_row() + y) * size_t(width) + size_t(x)) * size_t(planes);
          for (int p = 0; p < planes; ++p) to[p] = float(c(p));
        }
      }
    });
  });
  return coefficients;
}

// Scale and bias per plane from the 0.25% and 99.75% quantiles of every stride-th pixel's
// coefficients (relight's rangeQuantile), and the coefficients as byte codes with them.
void quantise_coefficients(const std::vector<float>& coefficients, long stride, PlaneField& out) {
  const long pixels = long(coefficients.size() / size_t(out.planes));
  out.scale.resize(size_t(out.planes));
  out.bias.resize(size_t(out.planes));
  std::vector<float> sample;
  for (int p = 0; p < out.planes; ++p) {
    sample.clear();
    for (long q = 0; q < pixels; q += stride) {
      sample.push_back(coefficients[size_t(q) * size_t(out.planes) + size_t(p)]);
    }
    const auto at = [&](double f) {
      auto it = sample.begin() + std::ptrdiff_t(f * double(sample.size() - 1));
      std::nth_element(sample.begin(), it, sample.end());
      return double(*it);
    };
    const double lo = at(0.0025), hi = std::max(at(0.9975), lo + 1e-3);
    out.scale[size_t(p)] = float((hi - lo) / 255.0);
    out.bias[size_t(p)] = float(-lo / (hi - lo));
  }
  out.codes.resize(coefficients.size());
  for (size_t i = 0; i < coefficients.size(); ++i) {
    const size_t p = i % size_t(out.planes);
    const double code = 255.0 * (coefficients[i] / 255.0 / out.scale[p] + out.bias[p]);
    out.codes[i] = uint8_t(std::clamp(std::round(code), 0.0, 255.0));
  }
}

// PlaneField::build with every option given (gain resolved, planes > 0): two passes over the
// bands, the covariance's and the coefficients'. With `training`, `field` is the choice's
// training sample (in memory, every pixel taken), whose vectors are made once.
PlaneField build_planes(const capture::ReflectanceField& field, const capture::FieldBands& bands,
                        const PlaneFieldOptions& options, TrainingVectors* training = nullptr) {
  PlaneField out;
  out.set_size(field.width(), field.height());
  out.interpolation = options.interpolation;
  out.planes = options.planes;
  out.sigma = options.sigma;
  out.resolution = options.resolution;
  PixelVectors pixel_vector;
  pixel_vector.used = place_lights(field, out);
  const Eigen::Index n = Eigen::Index(pixel_vector.used.size());
  const Eigen::Index d = Eigen::Index(out.dims()) * 3;
  if (n < 3 || d < out.planes) {
    throw InputError(field.source + ": lights: " + std::to_string(out.planes) + " planes need " +
                     std::to_string(out.planes / 3) + " or more valid LEDs in front of the image " +
                     "plane, got " + std::to_string(n));
  }
  out.gain = options.gain;
  if (options.interpolation == PlaneInterpolation::kBilinear) {
    pixel_vector.resample = per_channel(openlime::bilinear_resampling(
        out.lights, options.resolution, options.sigma, options.regularization));
  }
  pixel_vector.gain = float(out.gain);
  const long pixels = long(field.width()) * field.height();
  const long stride = std::max(1L, pixels / options.max_pca_pixels);
  if (!training) {
    store_basis(
        principal_axes(
            strided_statistics(field, bands, pixel_vector, stride).resampled(pixel_vector.resample),
            out.planes),
        out);
    const CoefficientFit fit(out, pixel_vector.resample);
    quantise_coefficients(fit_coefficients(bands, pixel_vector, fit, field.width(), pixels), stride,
                          out);
    return out;
  }
  LS_CHECK(stride == 1, "a training sample larger than max_pca_pixels");
  if (training->rows.size() == 0) {
    training->rows = Eigen::MatrixXd::Zero(pixels, pixel_vector.raw_size());
    training->raw = strided_statistics(field, bands, pixel_vector, stride, &training->rows);
  }
  if (training->grid != grid_of(options) || training->axes.eigenvectors.cols() < out.planes) {
    training->grid = grid_of(options);
    training->axes =
        principal_axes(training->raw.resampled(pixel_vector.resample),
                       int(std::min<Eigen::Index>(d, std::max(out.planes, kMostChoicePlanes))));
    training->built.reset();
  }
  if (training->built && training->built->planes == out.planes) {
    PlaneField same = *training->built;
    same.sigma = out.sigma;
    return same;
  }
  store_basis(training->axes, out);
  quantise_coefficients(
      fit_coefficients(training->rows, CoefficientFit(out, pixel_vector.resample)), stride, out);
  training->built = out;
  return out;
}

// The 8-bit sRGB PSNR of `options` on `held` lights of `pixels`, built from `train` (its vectors
// kept in `training`).
double held_out_psnr(const capture::ReflectanceField& train, const PlaneFieldOptions& options,
                     const std::vector<Eigen::Vector3d>& held_dirs,
                     const std::vector<float>& held_codes, TrainingVectors& training) {
  const PlaneField f = build_planes(train, capture::whole_field(train), options, &training);
  std::vector<float> rgb;
  double squared = 0;
  const size_t per_light = size_t(train.width()) * 3;
  for (size_t h = 0; h < held_dirs.size(); ++h) {
    f.display_into(held_dirs[h], rgb);
    for (size_t i = 0; i < per_light; ++i) {
      const double d =
          std::round(255.0 * std::clamp(rgb[i], 0.0f, 1.0f)) - held_codes[h * per_light + i];
      squared += d * d;
    }
  }
  const double rmse = std::sqrt(squared / double(held_codes.size()));
  return rmse > 0 ? 20 * std::log10(255.0 / rmse) : 200.0;
}

}  // namespace

PlaneFieldOptions choose_plane_options(const capture::ReflectanceField& field,
                                       PlaneFieldOptions options) {
  return choose_plane_options(field, capture::whole_field(field), options);
}

PlaneFieldOptions choose_plane_options(const capture::ReflectanceField& field,
                                       const capture::FieldBands& bands,
                                       PlaneFieldOptions options) {
  if (const std::string e = options.validate(); !e.empty()) {
    throw InputError(field.source + ": planes: " + e);
  }
  // One pass over the bands (when there is something to find): the brightest sample (for the
  // default gain) and the values of every light at evenly strided pixels (frame index i * stride),
  // to choose on.
  const long width = field.width(), pixels = width * field.height();
  const long count = std::min(pixels, 16384L), stride = pixels / count;
  const size_t values = size_t(field.num_lights()) * 3;
  std::vector<float> strided(size_t(count) * values);
  float brightest = 0;
  const bool choose = options.from_data;
  if (choose || !(options.gain > 0)) {
    bands([&](const capture::ReflectanceField& band) {
      if (!(options.gain > 0)) brightest = std::max(brightest, band.largest_value());
      const long first = band.first_row() * width, end = first + long(band.height()) * width;
      for (long p = (first + stride - 1) / stride * stride; p < end && p / stride < count;
           p += stride) {
        const float* v = band.pixel(int(p % width), int((p - first) / width));
        std::copy(v, v + values, strided.begin() + std::ptrdiff_t(size_t(p / stride) * values));
      }
    });
  }
  if (!(options.gain > 0)) options.gain = brightest > 0 ? 1.0 / brightest : 1.0;
  options.from_data = false;
  std::vector<int> train, held;
  for (int l = 0, k = 0; l < field.num_lights(); ++l) {
    const capture::FieldLight& light = field.lights()[size_t(l)];
    if (!light.valid || !(light.dir_in_stage.normalized().z() > 0)) continue;
    (k++ % 5 == 2 ? held : train).push_back(l);
  }
  if (!choose || held.size() < 3) {  // Too few lights to hold any out: relight's defaults.
    if (options.planes == 0) options.planes = 9;
    return options;
  }
  // The training lights at the strided pixels, one row; the held-out lights' codes.
  std::vector<capture::FieldLight> lights;
  lights.reserve(train.size());
  for (const int l : train) lights.push_back(field.lights()[size_t(l)]);
  capture::ReflectanceField sample(int(count), 1, lights);
  std::vector<Eigen::Vector3d> held_dirs;
  held_dirs.reserve(held.size());
  for (const int l : held) held_dirs.push_back(field.lights()[size_t(l)].dir_in_stage);
  std::vector<float> held_codes(held.size() * size_t(count) * 3);
  const auto gain = float(options.gain);
  for (long i = 0; i < count; ++i) {
    const float* v = strided.data() + size_t(i) * values;
    for (size_t t = 0; t < train.size(); ++t) {
      for (int c = 0; c < 3; ++c) sample.at(int(i), 0, int(t), c) = v[3 * train[t] + c];
    }
    for (size_t h = 0; h < held.size(); ++h) {
      for (int c = 0; c < 3; ++c) {
        held_codes[(h * size_t(count) + size_t(i)) * 3 + size_t(c)] =
            srgb8_code(gain * v[3 * held[h] + c]);
      }
    }
  }
  TrainingVectors training;
  const auto psnr = [&](const PlaneFieldOptions& o) {
    return held_out_psnr(sample, o, held_dirs, held_codes, training);
  };
  PlaneFieldOptions probe = options;
  probe.planes = std::min(options.planes > 0 ? options.planes : 18, 3 * int(train.size()) / 3 * 3);
  double best = -1;
  if (options.interpolation == PlaneInterpolation::kRbf) {
    for (const double sigma : {0.05, 0.07, 0.09, 0.11, 0.13, 0.16, 0.2, 0.25, 0.3}) {
      probe.sigma = sigma;
      if (const double db = psnr(probe); db > best) best = db, options.sigma = sigma;
    }
  } else {
    for (const int resolution : {6, 8, 10, 12, 14, 16}) {
      probe.resolution = resolution;
      if (const double db = psnr(probe); db > best) best = db, options.resolution = resolution;
    }
  }
  probe.sigma = options.sigma;
  probe.resolution = options.resolution;
  // With every light the spacing is sqrt(5/4) closer than among the training ones.
  options.sigma *= std::sqrt(double(train.size()) / double(train.size() + held.size()));
  if (options.planes == 0) {
    std::vector<std::pair<int, double>> scores;
    for (int planes = 3; planes <= kMostChoicePlanes && planes <= 3 * int(train.size());
         planes += 3) {
      probe.planes = planes;
      scores.emplace_back(planes, psnr(probe));
      best = std::max(best, scores.back().second);
    }
    for (const auto& [planes, db] : scores) {
      if (db >= best - 0.25) {
        options.planes = planes;
        break;
      }
    }
  }
  return options;
}

PlaneField PlaneField::build(const capture::ReflectanceField& field,
                             const PlaneFieldOptions& options) {
  return build(field, capture::whole_field(field), options);
}

PlaneField PlaneField::build(const capture::ReflectanceField& header,
                             const capture::FieldBands& bands, const PlaneFieldOptions& options) {
  return build_planes(header, bands, choose_plane_options(header, bands, options));
}

std::vector<float> PlaneField::weights_at(const Eigen::Vector3d& dir) const {
  const Eigen::Vector3d l = openlime::viewer_light(dir);
  const int dim = dims();
  std::vector<std::pair<int, double>> nodes;
  if (interpolation == PlaneInterpolation::kRbf) {
    const Eigen::VectorXd w = openlime::rbf_weights(lights, l, sigma, 0.001);
    for (int i = 0; i < dim; ++i) {
      if (w(i) > 0) nodes.emplace_back(i, w(i));
    }
  } else {
    int node[4];
    double weight[4];
    openlime::bilinear_nodes(l, resolution, node, weight);
    for (int q = 0; q < 4; ++q) nodes.emplace_back(node[q], weight[q]);
  }
  std::vector<float> out(size_t(planes + 1) * 3, 0.0f);
  for (int p = 0; p <= planes; ++p) {
    for (const auto& [i, w] : nodes) {
      for (int k = 0; k < 3; ++k) {
        out[size_t(p) * 3 + size_t(k)] += float(w * basis_value(*this, p, size_t(i) * 3 + k));
      }
    }
  }
  return out;
}

void PlaneField::display_into(const Eigen::Vector3d& dir, std::vector<float>& rgb) const {
  const std::vector<float> w = weights_at(dir);
  rgb.resize(size_t(width_) * height_ * 3);
  const size_t pixels = size_t(width_) * height_;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, pixels), [&](const auto& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const uint8_t* c = codes.data() + i * size_t(planes);
      float v[3] = {w[0], w[1], w[2]};
      for (int p = 0; p < planes; ++p) {
        const float coefficient = (float(c[p]) / 255.0f - bias[size_t(p)]) * scale[size_t(p)];
        for (int k = 0; k < 3; ++k) v[k] += w[size_t(p + 1) * 3 + size_t(k)] * coefficient;
      }
      for (int k = 0; k < 3; ++k) rgb[i * 3 + size_t(k)] = v[k];
    }
  });
}

void PlaneField::relight_into(const LightingForModels& lighting, Image& out) const {
  if (out.width != width_ || out.height != height_ || out.channels != 3) {
    out = Image(width_, height_, 3);
  }
  out.channel_names = {"R", "G", "B"};
  std::fill(out.pixels.begin(), out.pixels.end(), 0.0f);
  std::vector<float> display;
  // Display values are not linear in the light: each light's picture is decoded, then weighed.
  for (size_t k = 0; k < lighting.dirs_in_stage.size(); ++k) {
    const Eigen::Vector3d dir = lighting.dirs_in_stage[k].cast<double>().normalized();
    if (!(dir.z() > 0)) continue;  // Behind the image plane: no light the planes know.
    display_into(dir, display);
    const Eigen::Vector3f e = lighting.irradiance_rgb[k] / float(gain);
    for (size_t i = 0; i < display.size(); ++i) {
      out.pixels[i] += e[int(i % 3)] * srgb_decode(display[i]);
    }
  }
}

}  // namespace ls::relight
