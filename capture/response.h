#pragma once
// The camera response: digital number (DN) -> normalised linear exposure in [0, 1] (1 = the
// exposure that reads full scale). Stored as a lookup table per channel over all 2^bit_depth DN
// values.
#include <vector>

#include "lightstage/image.h"
#include "lightstage/stage.h"

namespace ls::capture {

class ResponseCurve {
 public:
  static ResponseCurve linear(int bit_depth, int channels);
  static ResponseCurve gamma(double gamma, int bit_depth, int channels);  // DN/max = x^(1/gamma)
  // From CameraResponse (linear, gamma or table file). kRecover needs data: see recover_response.
  static ResponseCurve from_spec(const CameraResponse& spec, int bit_depth, int channels);
  // The camera's given response, or linear for one still to be recovered: for measures that are
  // ratios of like signals (drift, each pixel's best exposure), which a monotone response hardly
  // changes.
  static ResponseCurve given_or_linear(const CameraSpec& camera);

  int bit_depth() const { return bit_depth_; }
  int channels() const { return channels_; }
  float to_linear(int dn, int c) const { return lut_[size_t(c) * size_ + dn]; }
  const std::vector<float>& lut() const { return lut_; }

  ResponseCurve(int bit_depth, int channels, std::vector<float> lut);

 private:
  int bit_depth_ = 0;
  int channels_ = 0;
  size_t size_ = 0;
  std::vector<float> lut_;  // channels * 2^bit_depth, monotone non-decreasing per channel.
};

// Recovers the response from bracketed frames of a static scene (Debevec & Malik via OpenCV's photo
// module, which works on 8-bit data: frames are reduced to 8 bits for the solve and the 256-entry
// curve is interpolated back to full bit depth). Normalised so that full scale maps to 1.
// Debevec & Malik (a smoothness-regularised least-squares solve) or Robertson et al. (iterative
// maximum likelihood, no smoothness term); both from OpenCV's photo module.
enum class ResponseMethod { kDebevec, kRobertson };
ResponseCurve recover_response(const std::vector<const RawFrame*>& frames,
                               const std::vector<double>& exposure_s,
                               ResponseMethod method = ResponseMethod::kDebevec);

}  // namespace ls::capture
