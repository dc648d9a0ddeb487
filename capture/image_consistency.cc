#include "capture/image_consistency.h"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "lightstage/statistics.h"

namespace ls::capture {

namespace {

// The pixels the correlation is taken over: where the images hold signal (their mean above 1% of
// its 99th percentile), eroded so that a mask's edge, the same in every image whatever its
// content, does not pin the alignment.
cv::Mat signal_region(const ConsistencyStack& stack) {
  const int w = stack.width(), h = stack.height();
  cv::Mat mean(h, w, CV_32F, cv::Scalar(0));
  for (int l = 0; l < stack.lights(); ++l) {
    const cv::Mat image(h, w, CV_32F, const_cast<float*>(stack.image(l).data()));
    mean += image;
  }
  std::vector<float> sorted(mean.begin<float>(), mean.end<float>());
  const auto p99 = sorted.begin() + std::ptrdiff_t(double(sorted.size() - 1) * 0.99);
  std::nth_element(sorted.begin(), p99, sorted.end());
  cv::Mat region = mean > 0.01f * *p99;
  constexpr int kErodePx = 4;  // Of the check's images: beyond the shifts worth finding.
  cv::erode(
      region, region,
      cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * kErodePx + 1, 2 * kErodePx + 1)));
  return region;
}

// Zero-mean normalised correlation of a and b over the region (ECC's measure, unaligned).
double correlation(const cv::Mat& a, const cv::Mat& b, const cv::Mat& region) {
  cv::Scalar mean_a, std_a, mean_b, std_b;
  cv::meanStdDev(a, mean_a, std_a, region);
  cv::meanStdDev(b, mean_b, std_b, region);
  if (std_a[0] <= 0 || std_b[0] <= 0) return 0;
  cv::Mat product = (a - mean_a[0]).mul(b - mean_b[0]);
  return cv::mean(product, region)[0] / (std_a[0] * std_b[0]);
}

// Every image clipped at twice its pixel's median over the images. A Lambertian pixel's values
// over a dome's lights stay within it; highlights (up to a hundred times brighter) would otherwise
// decide the correlation alone, and the smooth prediction cannot place them.
void clip_at_pixel_medians(ConsistencyStack& stack) {
  const size_t pixels = size_t(stack.width()) * stack.height();
  tbb::parallel_for(size_t(0), pixels, [&](size_t p) {
    std::vector<float> values(size_t(stack.lights()));
    for (int l = 0; l < stack.lights(); ++l) values[size_t(l)] = stack.image(l)[p];
    const auto mid = values.begin() + std::ptrdiff_t(values.size() / 2);
    std::nth_element(values.begin(), mid, values.end());
    const float ceiling = 2 * *mid;
    for (int l = 0; l < stack.lights(); ++l) {
      stack.image(l)[p] = std::min(stack.image(l)[p], ceiling);
    }
  });
}

// For every light, the others nearest first (by angle): the neighbourhoods the prediction, the
// usual misfit and the search for another light's image take their lights from.
using NearestLights = std::vector<std::vector<int>>;
NearestLights nearest_lights(const ConsistencyStack& stack) {
  NearestLights nearest(size_t(stack.lights()));
  for (int l = 0; l < stack.lights(); ++l) {
    std::vector<int>& order = nearest[size_t(l)];
    for (int k = 0; k < stack.lights(); ++k) {
      if (k != l) order.push_back(k);
    }
    const Eigen::Vector3d& d = stack.dirs()[size_t(l)];
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
      return stack.dirs()[size_t(a)].dot(d) > stack.dirs()[size_t(b)].dot(d);
    });
  }
  return nearest;
}

Eigen::Map<const Eigen::VectorXf> image_vector(const ConsistencyStack& stack, int l) {
  return {stack.image(l).data(), Eigen::Index(stack.image(l).size())};
}

// What the images in use (but its own) predict for light `target`'s image: per pixel, a
// quadratic in the light direction (in the tangent plane at the target) fitted by least squares
// to the kNeighbours lights nearest the target. Local, so that a highlight moving between
// neighbouring lights is followed; the same weights for every pixel, so the prediction is one
// weighted sum of images.
constexpr int kNeighbours = 12;
Eigen::VectorXf predict(const ConsistencyStack& stack, const NearestLights& nearest,
                        const std::vector<char>& in_use, int target) {
  std::vector<int> used;
  for (int k : nearest[size_t(target)]) {
    if (used.size() == size_t(kNeighbours)) break;
    if (in_use[size_t(k)]) used.push_back(k);
  }
  // The tangent plane's axes at the target's direction d.
  const Eigen::Vector3d& d = stack.dirs()[size_t(target)];
  const Eigen::Vector3d u = d.unitOrthogonal(), v = d.cross(u);
  Eigen::MatrixXd a(used.size(), 6);
  for (size_t i = 0; i < used.size(); ++i) {
    const Eigen::Vector3d& dk = stack.dirs()[size_t(used[i])];
    const double x = dk.dot(u), y = dk.dot(v);
    a.row(Eigen::Index(i)) << 1, x, y, x * x, x * y, y * y;
  }
  // The fit's value at d (x = y = 0) as weights of the neighbours' images: e0^T (A^T A)^-1 A^T,
  // damped so that a neighbourhood on one side of the target does not extrapolate wildly.
  Eigen::MatrixXd normal = a.transpose() * a;
  normal.diagonal().tail(5).array() += 1e-4 * normal(0, 0);
  const Eigen::VectorXd weights = a * normal.ldlt().solve(Eigen::VectorXd::Unit(6, 0));
  Eigen::VectorXf predicted = Eigen::VectorXf::Zero(Eigen::Index(stack.image(target).size()));
  for (size_t i = 0; i < used.size(); ++i) {
    predicted += float(weights(Eigen::Index(i))) * image_vector(stack, used[i]);
  }
  return predicted;
}

struct Judged {
  double shift_x = 0, shift_y = 0;    // Check pixels.
  double aligned = 0, unaligned = 0;  // Correlations.
};

cv::Mat image_mat(const ConsistencyStack& stack, const float* data) {
  return {stack.height(), stack.width(), CV_32F, const_cast<float*>(data)};
}

// Image l against its prediction from the others.
Judged judge(const ConsistencyStack& stack, const Eigen::VectorXf& predicted, const cv::Mat& region,
             int l) {
  const cv::Mat image = image_mat(stack, stack.image(l).data());
  const cv::Mat expected = image_mat(stack, predicted.data());
  Judged j;
  j.unaligned = correlation(expected, image, region);
  cv::Mat warp = cv::Mat::eye(2, 3, CV_32F);
  try {
    j.aligned = cv::findTransformECC(
        expected, image, warp, cv::MOTION_TRANSLATION,
        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 50, 1e-4), region, 5);
    j.shift_x = warp.at<float>(0, 2);
    j.shift_y = warp.at<float>(1, 2);
  } catch (const cv::Exception&) {
    // ECC gives up when the two do not correlate: unaligned is what they are.
    j.aligned = j.unaligned;
  }
  if (!std::isfinite(j.aligned) || j.aligned < j.unaligned) {
    j.aligned = j.unaligned;
    j.shift_x = j.shift_y = 0;
  }
  return j;
}

// The usual misfit (1 - correlation) near light l: the median over the images in use whose
// lights are nearest it (a sixth of them, at least nine), itself left out. Near, not over the
// whole set: a grazing light's shadows are less smooth than a frontal one's, and at the edge of
// the dome the prediction extrapolates.
double usual_misfit(const NearestLights& nearest, const std::vector<Judged>& judged,
                    const std::vector<char>& in_use, int l) {
  const std::vector<int>& order = nearest[size_t(l)];
  const auto others = size_t(
      std::count_if(order.begin(), order.end(), [&](int k) { return in_use[size_t(k)] != 0; }));
  const size_t count = std::min(others, std::max<size_t>(9, others / 6));
  std::vector<double> misfits;
  for (int k : order) {
    if (misfits.size() == count) break;
    if (in_use[size_t(k)]) misfits.push_back(1 - judged[size_t(k)].aligned);
  }
  return median(misfits);
}

// The light (other than l) at which image l correlates best, as it is, with what the other
// images predict, and that correlation ({-1, -1} when there is none): another light's image looks
// like that light's prediction.
std::pair<int, double> best_other_light(const ConsistencyStack& stack, const NearestLights& nearest,
                                        const std::vector<Eigen::VectorXf>& predicted,
                                        const cv::Mat& region, int l) {
  const cv::Mat image = image_mat(stack, stack.image(l).data());
  // Not l's nearest neighbours: at the edge of the dome an image's own prediction extrapolates
  // and its neighbour's may fit it better.
  const Eigen::Vector3d& d = stack.dirs()[size_t(l)];
  const double closest = d.dot(stack.dirs()[size_t(nearest[size_t(l)].front())]);
  const double beyond = std::cos(1.5 * std::acos(std::clamp(closest, -1.0, 1.0)));
  std::pair<int, double> best{-1, -1.0};
  for (int k = 0; k < stack.lights(); ++k) {
    if (k == l || stack.dirs()[size_t(k)].dot(d) > beyond) continue;
    const double c = correlation(image_mat(stack, predicted[size_t(k)].data()), image, region);
    if (c > best.second) best = {k, c};
  }
  return best;
}

// Image l's verdict, judged against the images in use: `predicted` holds every light's
// prediction, `mean` its image's mean (before clipping), `median_mean` the median image's.
ImageVerdict verdict(const ConsistencyStack& stack, const NearestLights& nearest,
                     const std::vector<Eigen::VectorXf>& predicted,
                     const std::vector<Judged>& judged, const std::vector<char>& in_use,
                     const cv::Mat& region, double mean, double median_mean,
                     const ConsistencyOptions& options, int l) {
  // An image that fits its prediction this much worse than the images lit near it is looked at
  // more closely (another light's?); flagged only when something explains it, or when it fits
  // max_misfit_ratio times worse.
  constexpr double kSuspectRatio = 3;
  // A shift explains an image when, moved, it fits about as well as its neighbours, or four
  // times better than as it is (a textured object's fine detail is not predicted so well).
  constexpr double kShiftedRatio = 2, kShiftedGain = 4;
  constexpr double kMisfitFloor = 1e-3;
  const Judged& j = judged[size_t(l)];
  ImageVerdict v;
  v.shift_x_px = j.shift_x * stack.scale();
  v.shift_y_px = j.shift_y * stack.scale();
  v.correlation = j.aligned;
  // Below a misfit of 1e-3 (correlation 0.999) images agree as well as any real set's can:
  // a noiseless set's edge lights are not 50 times worse for fitting to 0.999.
  const double usual = std::max(usual_misfit(nearest, judged, in_use, l), kMisfitFloor);
  v.misfit_ratio = (1 - j.aligned) / usual;
  const double own_misfit = 1 - j.unaligned, aligned_misfit = 1 - j.aligned;
  // A misregistration moves a photograph by pixels, not by a tenth of the frame: a larger
  // alignment follows moving structure (long cast shadows under sparse lights), not a shift.
  const double shift = std::hypot(j.shift_x, j.shift_y);
  const bool shift_explains = shift >= options.max_shift_px &&
                              shift <= 0.1 * std::min(stack.width(), stack.height()) &&
                              aligned_misfit < 0.5 * own_misfit;
  char text[240];
  if (mean < 1e-3 * median_mean) {
    v.flagged = true;
    v.kind = ImageProblemKind::kBlack;
    std::snprintf(text, sizeof text, "black: its mean is %.2g of the median image's",
                  mean / median_mean);
  } else if (shift_explains || own_misfit > kSuspectRatio * usual) {
    // Another light's image (a swapped file, a wrong line) matches that light's prediction
    // as it is; on a smooth object it also aligns to its own by a shift, so this comes first.
    const auto [other, other_correlation] = best_other_light(stack, nearest, predicted, region, l);
    const double other_misfit = 1 - other_correlation;
    if (other >= 0 && other_misfit < 0.5 * own_misfit && other_misfit < aligned_misfit) {
      v.flagged = true;
      v.kind = ImageProblemKind::kOtherLight;
      const double degrees =
          std::acos(
              std::clamp(stack.dirs()[size_t(l)].dot(stack.dirs()[size_t(other)]), -1.0, 1.0)) *
          180 / M_PI;
      std::snprintf(text, sizeof text,
                    "another light's image: it matches what the other images predict at "
                    "image %d's light, %.0f degrees from its own (correlation %.3f there, "
                    "%.3f at its own)",
                    other + 1, degrees, other_correlation, j.unaligned);
    } else if (shift_explains &&
               (v.misfit_ratio <= kShiftedRatio || aligned_misfit * kShiftedGain <= own_misfit)) {
      v.flagged = true;
      v.kind = ImageProblemKind::kShifted;
      std::snprintf(text, sizeof text,
                    "shifted by (%+.1f, %+.1f) px against what the other images predict at "
                    "its light (correlation %.3f aligned, %.3f as it is)",
                    v.shift_x_px, v.shift_y_px, j.aligned, j.unaligned);
    } else if (shift_explains) {
      // On a smooth object another light's image looks like its own moved: aligned, it
      // still fits worse than its neighbours do.
      v.flagged = true;
      v.kind = ImageProblemKind::kUnexplained;
      std::snprintf(text, sizeof text,
                    "unlike its light (another light's image?): correlation %.3f with what the "
                    "other images predict there even moved by (%+.1f, %+.1f) px, %.1fx the "
                    "usual misfit of the images lit near it",
                    j.aligned, v.shift_x_px, v.shift_y_px, v.misfit_ratio);
    }
  }
  if (!v.flagged && v.misfit_ratio > options.max_misfit_ratio) {
    v.flagged = true;
    v.kind = ImageProblemKind::kUnexplained;
    std::snprintf(text, sizeof text,
                  "unlike its light: correlation %.3f with what the other images predict "
                  "there, %.1fx the usual misfit of the images lit near it",
                  j.aligned, v.misfit_ratio);
  }
  if (v.flagged) v.reason = text;
  return v;
}

}  // namespace

ConsistencyStack::ConsistencyStack(int width, int height, std::vector<Eigen::Vector3d> dirs)
    : source_width_(width), source_height_(height), dirs_(std::move(dirs)) {
  const std::size_t per_image =
      std::min(kMaxImagePixels, kMaxSamples / std::max<size_t>(1, dirs_.size()));
  scale_ = std::max(1.0, std::sqrt(double(width) * height / double(per_image)));
  width_ = std::max(1, int(std::lround(width / scale_)));
  height_ = std::max(1, int(std::lround(height / scale_)));
  images_.resize(dirs_.size());
}

void ConsistencyStack::add(int light, const std::vector<float>& rgb) {
  cv::Mat grey(source_height_, source_width_, CV_32F);
  const float* in = rgb.data();
  for (auto it = grey.begin<float>(); it != grey.end<float>(); ++it, in += 3) {
    *it = (in[0] + in[1] + in[2]) / 3;
  }
  std::vector<float>& out = images_[std::size_t(light)];
  out.resize(std::size_t(width_) * height_);
  cv::Mat small(height_, width_, CV_32F, out.data());
  if (grey.size() == small.size()) {
    grey.copyTo(small);
  } else {
    cv::resize(grey, small, small.size(), 0, 0, cv::INTER_AREA);
  }
}

std::vector<int> ConsistencyReport::flagged() const {
  std::vector<int> out;
  for (size_t l = 0; l < images.size(); ++l) {
    if (images[l].flagged) out.push_back(int(l));
  }
  return out;
}

ConsistencyReport check_image_consistency(ConsistencyStack& stack,
                                          const ConsistencyOptions& options) {
  ConsistencyReport report;
  const int n = stack.lights();
  report.images.resize(size_t(n));
  for (int l = 0; l < n; ++l) {
    if (!stack.has(l)) {
      report.not_checked = "image " + std::to_string(l + 1) + " was not read";
      return report;
    }
  }
  if (n < kMinImagesToCheck) {
    report.not_checked = std::to_string(n) + " images, fewer than the " +
                         std::to_string(kMinImagesToCheck) + " a prediction from the others needs";
    return report;
  }
  const cv::Mat region = signal_region(stack);
  if (cv::countNonZero(region) < 64) {
    report.not_checked = "too few pixels hold signal in every image";
    return report;
  }
  // Each image's mean over the region, before clipping: what tells a black image.
  std::vector<double> means;
  means.reserve(size_t(n));
  for (int l = 0; l < n; ++l) {
    means.push_back(cv::mean(image_mat(stack, stack.image(l).data()), region)[0]);
  }
  clip_at_pixel_medians(stack);
  const NearestLights nearest = nearest_lights(stack);
  std::vector<char> in_use(size_t(n), 1);
  std::vector<Judged> judged{size_t(n)};
  std::vector<Eigen::VectorXf> predicted{size_t(n)};
  constexpr int kMaxRounds = 6;
  while (report.rounds < kMaxRounds) {
    ++report.rounds;
    // Every light's image as the images in use (but its own) predict it.
    tbb::parallel_for(0, n, [&](int l) {
      predicted[size_t(l)] = predict(stack, nearest, in_use, l);
      judged[size_t(l)] = judge(stack, predicted[size_t(l)], region, l);
    });
    std::vector<double> used_means;
    for (int l = 0; l < n; ++l) {
      if (in_use[size_t(l)]) used_means.push_back(means[size_t(l)]);
    }
    const double median_mean = median(used_means);
    std::vector<char> next(size_t(n), 1);
    for (int l = 0; l < n; ++l) {
      report.images[size_t(l)] = verdict(stack, nearest, predicted, judged, in_use, region,
                                         means[size_t(l)], median_mean, options, l);
      next[size_t(l)] = !report.images[size_t(l)].flagged;
    }
    if (next == in_use) break;
    in_use = next;
  }
  return report;
}

}  // namespace ls::capture
