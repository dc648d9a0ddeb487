#include "capture/response.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/photo.hpp>
#include <sstream>
#include <string>

#include "lightstage/errors.h"

namespace ls::capture {
namespace {

size_t lut_size_for(int bit_depth) { return size_t(1) << bit_depth; }

void check_shape(int bit_depth, int channels, const std::string& what) {
  if (bit_depth < 1 || bit_depth > 16) {
    throw InputError(what + ": bit depth must be 1 to 16, got " + std::to_string(bit_depth));
  }
  if (channels < 1 || channels > 4) {
    throw InputError(what + ": channels must be 1 to 4, got " + std::to_string(channels));
  }
}

// Splits a line into numbers; returns false at the first token that is not a number.
bool parse_numbers(const std::string& line, std::vector<double>* values, std::string* bad_token) {
  values->clear();
  std::istringstream in(line);
  std::string token;
  while (in >> token) {
    // Columns may be separated by commas as well as white space.
    std::replace(token.begin(), token.end(), ',', ' ');
    std::istringstream parts(token);
    std::string part;
    while (parts >> part) {
      size_t used = 0;
      double v = 0;
      try {
        v = std::stod(part, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != part.size()) {
        *bad_token = part;
        return false;
      }
      values->push_back(v);
    }
  }
  return true;
}

ResponseCurve load_table(const std::filesystem::path& file, int bit_depth, int channels) {
  const std::string name = file.string();
  std::ifstream in(file);
  if (!in) throw InputError(name + ": cannot open camera response table");
  const size_t expected = lut_size_for(bit_depth);
  std::vector<std::vector<double>> rows;
  rows.reserve(expected);
  std::vector<int> row_line;
  int columns = -1;
  int first_line = 0;
  std::string line;
  std::vector<double> values;
  for (int line_no = 1; std::getline(in, line); ++line_no) {
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::string bad;
    if (!parse_numbers(line, &values, &bad)) {
      throw InputError(name + ":" + std::to_string(line_no) + ": expected a number, got '" + bad +
                       "'");
    }
    if (values.empty()) continue;  // Blank or comment line.
    if (values.size() != 1 && int(values.size()) != channels) {
      throw InputError(name + ":" + std::to_string(line_no) + ": expected 1 or " +
                       std::to_string(channels) + " columns, got " + std::to_string(values.size()));
    }
    if (columns < 0) {
      columns = int(values.size());
      first_line = line_no;
    } else if (int(values.size()) != columns) {
      throw InputError(name + ":" + std::to_string(line_no) + ": expected " +
                       std::to_string(columns) + " columns like line " +
                       std::to_string(first_line) + ", got " + std::to_string(values.size()));
    }
    for (size_t c = 0; c < values.size(); ++c) {
      if (!std::isfinite(values[c])) {
        throw InputError(name + ":" + std::to_string(line_no) + ": value " + std::to_string(c + 1) +
                         " is not finite");
      }
    }
    if (!rows.empty()) {
      for (size_t c = 0; c < values.size(); ++c) {
        if (values[c] < rows.back()[c]) {
          throw InputError(name + ":" + std::to_string(line_no) + ": response must be monotone " +
                           "non-decreasing, but column " + std::to_string(c + 1) + " drops from " +
                           std::to_string(rows.back()[c]) + " to " + std::to_string(values[c]));
        }
      }
    }
    if (rows.size() == expected) {
      throw InputError(name + ":" + std::to_string(line_no) + ": expected " +
                       std::to_string(expected) + " values (one per DN of a " +
                       std::to_string(bit_depth) + "-bit camera), found more");
    }
    rows.push_back(values);
    row_line.push_back(line_no);
  }
  if (rows.size() != expected) {
    throw InputError(name + ":" + std::to_string(row_line.empty() ? 1 : row_line.back()) +
                     ": expected " + std::to_string(expected) + " values (one per DN of a " +
                     std::to_string(bit_depth) + "-bit camera), got " +
                     std::to_string(rows.size()));
  }
  // Tables may be in any linear unit: normalise so that full scale reads 1.
  std::vector<float> lut(size_t(channels) * expected);
  for (int c = 0; c < channels; ++c) {
    const int col = columns == 1 ? 0 : c;
    const double full_scale = rows.back()[col];
    if (!(full_scale > 0)) {
      throw InputError(name + ":" + std::to_string(row_line.back()) +
                       ": the value at full scale must be positive, got " +
                       std::to_string(full_scale));
    }
    for (size_t dn = 0; dn < expected; ++dn) {
      lut[size_t(c) * expected + dn] = float(rows[dn][col] / full_scale);
    }
  }
  return ResponseCurve(bit_depth, channels, std::move(lut));
}

}  // namespace

ResponseCurve::ResponseCurve(int bit_depth, int channels, std::vector<float> lut)
    : bit_depth_(bit_depth),
      channels_(channels),
      size_(lut_size_for(bit_depth)),
      lut_(std::move(lut)) {
  check_shape(bit_depth, channels, "camera response");
  LS_CHECK(lut_.size() == size_ * size_t(channels),
           "response LUT has " + std::to_string(lut_.size()) + " entries, expected " +
               std::to_string(size_ * size_t(channels)));
  for (int c = 0; c < channels; ++c) {
    for (size_t dn = 0; dn < size_; ++dn) {
      const float v = lut_[size_t(c) * size_ + dn];
      LS_CHECK(std::isfinite(v), "response LUT value not finite at DN " + std::to_string(dn));
      LS_CHECK(dn == 0 || v >= lut_[size_t(c) * size_ + dn - 1],
               "response LUT not monotone at DN " + std::to_string(dn));
    }
  }
}

ResponseCurve ResponseCurve::linear(int bit_depth, int channels) {
  check_shape(bit_depth, channels, "linear camera response");
  const size_t n = lut_size_for(bit_depth);
  const double max_dn = double(n - 1);
  std::vector<float> lut(n * size_t(channels));
  for (int c = 0; c < channels; ++c) {
    for (size_t dn = 0; dn < n; ++dn) lut[size_t(c) * n + dn] = float(double(dn) / max_dn);
  }
  return ResponseCurve(bit_depth, channels, std::move(lut));
}

ResponseCurve ResponseCurve::gamma(double gamma, int bit_depth, int channels) {
  check_shape(bit_depth, channels, "gamma camera response");
  if (!(gamma > 0) || !std::isfinite(gamma)) {
    throw InputError("gamma camera response: gamma must be a positive number, got " +
                     std::to_string(gamma));
  }
  const size_t n = lut_size_for(bit_depth);
  const double max_dn = double(n - 1);
  std::vector<float> lut(n * size_t(channels));
  for (int c = 0; c < channels; ++c) {
    // The camera wrote DN/max = x^(1/gamma); invert it.
    for (size_t dn = 0; dn < n; ++dn) {
      lut[size_t(c) * n + dn] = float(std::pow(double(dn) / max_dn, gamma));
    }
  }
  return ResponseCurve(bit_depth, channels, std::move(lut));
}

ResponseCurve ResponseCurve::given_or_linear(const CameraSpec& camera) {
  if (camera.response.kind == CameraResponse::Kind::kRecover) {
    return linear(camera.bit_depth, camera.channels);
  }
  return from_spec(camera.response, camera.bit_depth, camera.channels);
}

ResponseCurve ResponseCurve::from_spec(const CameraResponse& spec, int bit_depth, int channels) {
  switch (spec.kind) {
    case CameraResponse::Kind::kLinear:
      return linear(bit_depth, channels);
    case CameraResponse::Kind::kGamma:
      return gamma(spec.gamma, bit_depth, channels);
    case CameraResponse::Kind::kTable:
      return load_table(spec.table_file, bit_depth, channels);
    case CameraResponse::Kind::kRecover:
      break;
  }
  throw InputError(
      "camera response 'recover' needs bracketed frames: use recover_response (build_field does)");
}

namespace {

void check_bracket(const std::vector<const RawFrame*>& frames,
                   const std::vector<double>& exposure_s) {
  if (frames.size() < 2) {
    throw InputError("response recovery needs at least 2 frames of a bracket, got " +
                     std::to_string(frames.size()));
  }
  if (frames.size() != exposure_s.size()) {
    throw InputError("response recovery: " + std::to_string(frames.size()) + " frames but " +
                     std::to_string(exposure_s.size()) + " exposure times");
  }
  const RawFrame& first = *frames[0];
  if (first.channels != 1 && first.channels != 3) {
    throw InputError("response recovery needs 1- or 3-channel frames, got " +
                     std::to_string(first.channels));
  }
  check_shape(first.bit_depth, first.channels, "response recovery");
  for (size_t i = 0; i < frames.size(); ++i) {
    const RawFrame& f = *frames[i];
    if (f.width != first.width || f.height != first.height || f.channels != first.channels ||
        f.bit_depth != first.bit_depth || f.pixels.size() != first.pixels.size() ||
        f.pixels.size() != size_t(f.width) * f.height * f.channels) {
      throw InputError("response recovery: frame " + std::to_string(i) +
                       " differs in size, channels or bit depth from frame 0");
    }
    if (!(exposure_s[i] > 0) || !std::isfinite(exposure_s[i])) {
      throw InputError("response recovery: exposure " + std::to_string(i) +
                       " must be positive, got " + std::to_string(exposure_s[i]));
    }
  }
}

// OpenCV's Debevec solver works on 8-bit, 3-channel images: reduce DN to 8 bits (rounded) and
// replicate a single channel. Channels are solved independently, so RGB vs BGR does not matter.
std::vector<cv::Mat> to_8bit_bgr(const std::vector<const RawFrame*>& frames) {
  const int max_dn = (1 << frames[0]->bit_depth) - 1;
  std::vector<uint8_t> to8(size_t(max_dn) + 1);
  for (int dn = 0; dn <= max_dn; ++dn) to8[dn] = uint8_t(std::lround(dn * 255.0 / max_dn));
  std::vector<cv::Mat> images;
  for (const RawFrame* frame : frames) {
    const RawFrame& f = *frame;
    cv::Mat m(f.height, f.width, CV_8UC3);
    for (int y = 0; y < f.height; ++y) {
      uint8_t* row = m.ptr<uint8_t>(y);
      for (int x = 0; x < f.width; ++x) {
        for (int c = 0; c < 3; ++c) {
          const int src_c = f.channels == 1 ? 0 : c;
          const uint16_t dn = std::min<int>(f.at(x, y, src_c), max_dn);
          row[x * 3 + c] = to8[dn];
        }
      }
    }
    images.push_back(m);
  }
  return images;
}

// Interpolate the 256-entry curve to the full bit depth. The curve is only known up to scale, so
// it is normalised to read 1 at full scale. Its top end is the least constrained part of the
// solve (clipped samples pile up at 255, where OpenCV's weights do not reach 0), and measured on
// a gamma-2.2 camera it overshoots by ~60% at 255: so the values above kFitEnd are replaced by a
// power law fitted in log-log over [kFitBegin, kFitEnd] (exact for linear and gamma cameras),
// extrapolated to 255. A running max then enforces monotonicity. Writes lut[0, 2^bit_depth).
void curve_to_lut(const cv::Mat& curve, int c, int max_dn, float* lut) {
  constexpr int kFitBegin = 96;
  constexpr int kFitEnd = 224;
  const size_t n = size_t(max_dn) + 1;
  std::vector<double> g(256);
  for (int i = 0; i < 256; ++i) {
    g[i] = double(curve.at<cv::Vec3f>(i, 0)[c]);
    if (!std::isfinite(g[i])) {
      throw InputError("response recovery failed: the recovered curve is not finite at value " +
                       std::to_string(i) + " (is the bracket of a static, well-exposed scene?)");
    }
  }
  // Least squares: log g(z) = a + b * log(z / 255).
  double s_u = 0, s_v = 0, s_uu = 0, s_uv = 0;
  int count = 0;
  for (int z = kFitBegin; z <= kFitEnd; ++z) {
    if (!(g[z] > 0)) continue;
    const double u = std::log(z / 255.0);
    const double v = std::log(g[z]);
    s_u += u, s_v += v, s_uu += u * u, s_uv += u * v, ++count;
  }
  const double det = count * s_uu - s_u * s_u;
  if (count < 8 || !(det > 0)) {
    throw InputError(
        "response recovery failed: the recovered curve is not positive over the mid range "
        "(is the bracket of a static, well-exposed scene?)");
  }
  const double slope = (count * s_uv - s_u * s_v) / det;
  const double intercept = (s_v - slope * s_u) / count;
  for (int z = kFitEnd + 1; z < 256; ++z) g[z] = std::exp(intercept + slope * std::log(z / 255.0));
  double running = -std::numeric_limits<double>::infinity();
  for (int i = 0; i < 256; ++i) {
    running = std::max(running, g[i]);
    g[i] = running;
  }
  const double full_scale = g[255];
  if (!(full_scale > 0) || !std::isfinite(full_scale)) {
    throw InputError("response recovery failed: the recovered curve is not positive at full scale");
  }
  for (size_t dn = 0; dn < n; ++dn) {
    const double p = double(dn) * 255.0 / max_dn;
    const int i0 = std::min(int(p), 254);
    const double t = p - i0;
    const double v = (g[i0] * (1 - t) + g[i0 + 1] * t) / full_scale;
    lut[dn] = float(v);
  }
  // Interpolation of a non-decreasing sequence stays non-decreasing, but float rounding may not:
  // enforce it exactly.
  for (size_t dn = 1; dn < n; ++dn) {
    float& v = lut[dn];
    v = std::max(v, lut[dn - 1]);
  }
}

}  // namespace

ResponseCurve recover_response(const std::vector<const RawFrame*>& frames,
                               const std::vector<double>& exposure_s, ResponseMethod method) {
  check_bracket(frames, exposure_s);
  const RawFrame& first = *frames[0];
  const int max_dn = (1 << first.bit_depth) - 1;
  std::vector<cv::Mat> images = to_8bit_bgr(frames);
  std::vector<float> times(exposure_s.begin(), exposure_s.end());
  // OpenCV solves the system by SVD, cubic in the sample count: 300 samples take ~0.6 s (1000 take
  // 7 s). With 12-bit noise reduced to 8 bits the default smoothness (10) lets the curve wiggle by
  // +-5%; lambda 100 keeps a gamma-2.2 curve within 2% above 10% of full scale (response_test).
  cv::Ptr<cv::CalibrateCRF> calibrate;
  if (method == ResponseMethod::kRobertson) {
    // Every pixel (no sampling), iterative maximum likelihood, no smoothness term: on a simulated
    // 12-bit gamma-2.2 bracket reduced to 8 bits it errs by up to 20% in the mid range where
    // Debevec errs by 1% (tests/capture/calibration/robertson_test.cc), so Debevec stays the
    // default.
    calibrate = cv::createCalibrateRobertson(/*max_iter=*/100, /*threshold=*/0.001f);
  } else {
    calibrate = cv::createCalibrateDebevec(/*samples=*/300, /*lambda=*/100.0f, /*random=*/false);
  }
  cv::Mat curve;  // 256 x 1, CV_32FC3: exposure (arbitrary scale) per 8-bit value.
  calibrate->process(images, curve, times);
  LS_CHECK(curve.rows == 256 && curve.type() == CV_32FC3,
           "unexpected response curve shape " + std::to_string(curve.rows));

  const size_t n = size_t(max_dn) + 1;
  std::vector<float> lut(n * size_t(first.channels));
  for (int c = 0; c < first.channels; ++c)
    curve_to_lut(curve, c, max_dn, lut.data() + size_t(c) * n);
  return ResponseCurve(first.bit_depth, first.channels, std::move(lut));
}

}  // namespace ls::capture
