// The PCA field's file (write, read) and its basis as a checkpoint record (save_basis,
// load_basis): relight/compact/pca_field.h.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "lightstage/checkpoint_dir.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "relight/compact/pca_field.h"

namespace ls::relight {
namespace {

template <class T>
void write_pod(std::ostream& out, const T& value) {
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}

template <class T>
T read_pod(std::istream& in, const std::string& file, const std::string& field) {
  T value;
  in.read(reinterpret_cast<char*>(&value), sizeof(T));
  if (!in) throw InputError(file + ": " + field + ": expected more data, got end of file");
  return value;
}

constexpr char kPcaMagic[] = "LSPCA1\n";

}  // namespace

// File layout (little-endian): "LSPCA1\n"; int32 width, height, lights, rank, tile_size;
// float64 rbf sigma (rad); per LED float64 x, y, z and uint8 valid; per tile (row-major over
// tiles) the L x k basis as float32, column by column; per pixel (row-major, row 0 at the top)
// k x 3 float32 coefficients, [j * 3 + c].
void PcaField::write(const std::filesystem::path& path) const {
  LS_CHECK(coefs_.size() == size_t(height_) * coefficients_per_row(), "PCA without coefficients");
  write(path, [&](int y, float* row) {
    std::copy_n(coefs_.data() + size_t(y) * coefficients_per_row(), coefficients_per_row(), row);
  });
}

double PcaField::header_bytes(int lights) {
  return double(sizeof(kPcaMagic) - 1) + 5 * sizeof(int32_t) + sizeof(double) +
         double(lights) * (3 * sizeof(double) + sizeof(uint8_t));
}

double PcaField::data_bytes(int width, int height, int lights, int rank, int tile_size) {
  const double tiles =
      tile_size > 0 ? std::ceil(double(width) / tile_size) * std::ceil(double(height) / tile_size)
                    : 1.0;
  return sizeof(float) * (tiles * lights * rank + double(width) * height * rank * 3);
}

void PcaField::write(const std::filesystem::path& path, const CoefficientRows& rows) const {
  std::ostringstream out;
  out.write(kPcaMagic, sizeof(kPcaMagic) - 1);
  for (int v : {width_, height_, num_lights(), rank_, tile_size_}) write_pod<int32_t>(out, v);
  write_pod<double>(out, sigma_rad_);
  for (int l = 0; l < num_lights(); ++l) {
    for (int i = 0; i < 3; ++i) write_pod<double>(out, lights_[size_t(l)].dir_in_stage(i));
    write_pod<uint8_t>(out, lights_[size_t(l)].valid ? 1 : 0);
  }
  for (const auto& basis : bases_) {
    out.write(reinterpret_cast<const char*>(basis.data()), basis.size() * sizeof(float));
  }
  AtomicFileWriter file(path);
  const std::string header = out.str();
  file.write(header.data(), header.size());
  std::vector<float> row(coefficients_per_row());
  for (int y = 0; y < height_; ++y) {
    rows(y, row.data());
    file.write(row.data(), row.size() * sizeof(float));
  }
  file.commit();
}

namespace {

constexpr const char* kBasisMagic = "lightstage pca basis 1";

}  // namespace

void PcaField::save_basis(const std::filesystem::path& file, const PcaSummary& summary) const {
  const nlohmann::json info = {{"width", width_},
                               {"height", height_},
                               {"lights", num_lights()},
                               {"rank", rank_},
                               {"tile_size", tile_size_},
                               {"tiles", bases_.size()},
                               {"sigma_rad", sigma_rad_},
                               {"summary",
                                {{"rank", summary.rank},
                                 {"auto_rank", summary.auto_rank},
                                 {"noise_variance", summary.noise_variance},
                                 {"noise_measured", summary.noise_measured},
                                 {"noise_method", summary.noise_method},
                                 {"residual_ms", summary.residual_ms},
                                 {"held_out_ms", summary.held_out_ms},
                                 {"mean_square", summary.mean_square},
                                 {"seconds", summary.seconds}}}};
  std::vector<RecordBytes> blocks;
  for (const Eigen::MatrixXf& basis : bases_) {
    blocks.push_back({basis.data(), std::size_t(basis.size()) * sizeof(float)});
  }
  write_record(file, kBasisMagic, info, blocks);
}

std::optional<PcaField> PcaField::load_basis(const std::filesystem::path& file,
                                             const capture::ReflectanceField& header,
                                             PcaSummary* summary) {
  PcaField out;
  PcaSummary sum;
  const auto place = [&](const nlohmann::json& info) -> std::optional<std::vector<RecordTarget>> {
    out.width_ = info.at("width").get<int>();
    out.height_ = info.at("height").get<int>();
    out.rank_ = info.at("rank").get<int>();
    out.tile_size_ = info.at("tile_size").get<int>();
    out.sigma_rad_ = info.at("sigma_rad").get<double>();
    if (out.width_ != header.width() || out.height_ != header.height() ||
        info.at("lights").get<int>() != header.num_lights() || out.rank_ < 1 ||
        out.rank_ > header.num_lights()) {
      return std::nullopt;
    }
    const nlohmann::json& j = info.at("summary");
    sum.rank = j.at("rank").get<int>();
    sum.auto_rank = j.at("auto_rank").get<bool>();
    sum.noise_variance = j.at("noise_variance").get<double>();
    sum.noise_measured = j.at("noise_measured").get<bool>();
    sum.noise_method = j.at("noise_method").get<std::string>();
    sum.residual_ms = j.at("residual_ms").get<std::vector<double>>();
    sum.held_out_ms = j.at("held_out_ms").get<std::vector<double>>();
    sum.mean_square = j.at("mean_square").get<double>();
    sum.seconds = j.at("seconds").get<double>();
    out.bases_.assign(info.at("tiles").get<std::size_t>(),
                      Eigen::MatrixXf(header.num_lights(), out.rank_));
    std::vector<RecordTarget> targets;
    for (Eigen::MatrixXf& basis : out.bases_) {
      targets.push_back({basis.data(), std::size_t(basis.size()) * sizeof(float)});
    }
    return targets;
  };
  if (!read_record(file, kBasisMagic, place)) return std::nullopt;
  if (out.bases_.size() !=
      size_t(out.tile_size_ > 0 ? out.tiles_x() * ((out.height_ - 1) / out.tile_size_ + 1) : 1)) {
    return std::nullopt;
  }
  out.lights_ = kept_lights(header.lights());
  out.interpolator_ = LightInterpolator(out.lights_, out.sigma_rad_);
  if (summary) *summary = sum;
  return out;
}

PcaField PcaField::read(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(file + ": cannot open for reading");
  char magic[sizeof(kPcaMagic) - 1];
  in.read(magic, sizeof(magic));
  if (!in || std::memcmp(magic, kPcaMagic, sizeof(magic)) != 0) {
    throw InputError(file + ": header: expected \"LSPCA1\", got something else (not a PCA field)");
  }
  PcaField out;
  out.width_ = read_pod<int32_t>(in, file, "width");
  out.height_ = read_pod<int32_t>(in, file, "height");
  const int lights = read_pod<int32_t>(in, file, "lights");
  out.rank_ = read_pod<int32_t>(in, file, "rank");
  out.tile_size_ = read_pod<int32_t>(in, file, "tile_size");
  auto check = [&](bool ok, const std::string& field, const std::string& what, long long got) {
    if (!ok) {
      throw InputError(file + ": " + field + ": expected " + what + ", got " + std::to_string(got));
    }
  };
  check(out.width_ > 0 && out.width_ <= 65536, "width", "1..65536", out.width_);
  check(out.height_ > 0 && out.height_ <= 65536, "height", "1..65536", out.height_);
  check(lights > 0 && lights <= 100000, "lights", "1..100000", lights);
  check(out.rank_ > 0 && out.rank_ <= lights, "rank", "1..lights", out.rank_);
  check(out.tile_size_ >= 0, "tile_size", ">= 0", out.tile_size_);
  out.sigma_rad_ = read_pod<double>(in, file, "rbf_sigma");
  if (!(out.sigma_rad_ > 0 && out.sigma_rad_ < M_PI)) {
    throw InputError(file + ": rbf_sigma: expected an angle in (0, pi) radians");
  }
  for (int l = 0; l < lights; ++l) {
    Eigen::Vector3d d;
    for (int i = 0; i < 3; ++i)
      d(i) = read_pod<double>(in, file, "lights[" + std::to_string(l) + "]");
    if (!(d.allFinite() && std::abs(d.norm() - 1) < 1e-3)) {
      throw InputError(file + ": lights[" + std::to_string(l) +
                       "].direction: expected a unit vector");
    }
    const bool valid = read_pod<uint8_t>(in, file, "lights") != 0;
    out.lights_.push_back({l, d, valid});
  }
  const int64_t tiles =
      out.tile_size_ > 0 ? int64_t(out.tiles_x()) * ((out.height_ - 1) / out.tile_size_ + 1) : 1;
  // The sizes the header claims must be in the file before anything of that size is allocated.
  const double claimed_bytes =
      data_bytes(out.width_, out.height_, lights, out.rank_, out.tile_size_);
  std::error_code error;
  const double left_bytes = double(std::filesystem::file_size(path, error)) - double(in.tellg());
  if (!error && claimed_bytes > left_bytes) {
    char sizes[96];  // Printed as doubles: a hostile header's claim does not fit an integer.
    std::snprintf(sizes, sizeof sizes, "expected %.0f bytes, got %.0f", claimed_bytes, left_bytes);
    throw InputError(file + ": bases and coefficients (as width, height, lights, rank and " +
                     "tile_size say): " + sizes);
  }
  for (int64_t t = 0; t < tiles; ++t) {
    Eigen::MatrixXf basis(lights, out.rank_);
    in.read(reinterpret_cast<char*>(basis.data()), basis.size() * sizeof(float));
    if (!in) {
      throw InputError(file + ": basis[" + std::to_string(t) + "]: expected " +
                       std::to_string(basis.size()) + " floats, got end of file");
    }
    if (!basis.allFinite()) {
      throw InputError(file + ": basis[" + std::to_string(t) + "]: expected finite values");
    }
    out.bases_.push_back(std::move(basis));
  }
  out.coefs_.resize(size_t(out.width_) * out.height_ * out.rank_ * 3);
  in.read(reinterpret_cast<char*>(out.coefs_.data()), out.coefs_.size() * sizeof(float));
  if (!in) {
    throw InputError(file + ": coefficients: expected " + std::to_string(out.coefs_.size()) +
                     " floats, got end of file");
  }
  for (float v : out.coefs_) {
    if (!std::isfinite(v)) throw InputError(file + ": coefficients: expected finite values");
  }
  in.peek();
  if (!in.eof()) throw InputError(file + ": coefficients: expected end of file, got more data");
  out.interpolator_ = LightInterpolator(out.lights_, out.sigma_rad_);
  return out;
}

}  // namespace ls::relight
