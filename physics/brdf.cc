#include "physics/brdf.h"

#include <cmath>
#include <sstream>

namespace ls::physics::brdf {

namespace {

std::string format_parameter(double v) {
  if (std::isnan(v)) return "nan";
  std::ostringstream s;
  s << v;
  return s.str();
}

// NaN fails every comparison, so each check is written as "inside the range" and negated.
std::string check_range(const std::string& name, double value, double lo, bool lo_open, double hi,
                        const std::string& range_text) {
  const bool above_lo = lo_open ? value > lo : value >= lo;
  if (above_lo && value <= hi) return "";
  return name + " must be in " + range_text + ", got " + format_parameter(value);
}

std::string check_rgb(const std::string& name, const Eigen::Vector3d& v, double hi,
                      const std::string& range_text) {
  const char* channel[3] = {".r", ".g", ".b"};
  for (int c = 0; c < 3; ++c) {
    std::string error = check_range(name + channel[c], v[c], 0.0, false, hi, range_text);
    if (!error.empty()) return error;
  }
  return "";
}

}  // namespace

std::string Material::validate() const {
  // Only the parameters of the lobes in use are checked: the others are ignored by eval().
  std::string error = check_rgb("albedo", albedo, 1.0, "[0, 1]");
  if (error.empty() && diffuse == DiffuseModel::kOrenNayar) {
    error = check_range("sigma_rad", sigma_rad, 0.0, false, kPi / 2, "[0, pi/2]");
  }
  if (error.empty() && specular != SpecularModel::kNone) {
    error = check_rgb("ks", ks, HUGE_VAL, "[0, inf)");
    if (error.empty() && !std::isfinite(ks.sum())) {
      error = "ks must be finite, got (" + format_parameter(ks[0]) + ", " +
              format_parameter(ks[1]) + ", " + format_parameter(ks[2]) + ")";
    }
  }
  if (error.empty() && specular == SpecularModel::kTorranceSparrow) {
    error = check_range("roughness", roughness, 0.0, true, 1.0, "(0, 1]");
  }
  if (error.empty() && specular == SpecularModel::kPhong) {
    error = check_range("phong_exponent", phong_exponent, 1.0, false, 1e4, "[1, 10000]");
  }
  return error;
}

}  // namespace ls::physics::brdf
