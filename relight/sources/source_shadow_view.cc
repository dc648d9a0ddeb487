// A source's view of the recovered shape: the disc's rays per pixel, and where the shape agrees
// with what the LEDs around the source measured.
#include <tbb/parallel_for.h>

#include <algorithm>
#include <limits>
#include <mutex>
#include <numbers>
#include <numeric>
#include <opencv2/imgproc.hpp>

#include "lightstage/direction_index.h"
#include "physics/sphere.h"
#include "relight/sources/lit_bits.h"
#include "relight/sources/shadow_geometry.h"

namespace ls::relight {

namespace {

// A source within this share of the LED spacing from its nearest LED is near it: anywhere in a
// triangle of live LEDs (at most 0.58 of the way in an equilateral one), not in a hole dead LEDs
// left.
constexpr float kNearestDecides = 0.75f;
// Of a source's kDiscSamples rays, the outermost traced first (SourceShadowView::visibility).
constexpr int kDiscSamples = 16, kRimSamples = 6;

}  // namespace

SourceShadowView ShadowGeometry::view(const Eigen::Vector3d& dir, double radius_rad) const {
  SourceShadowView view;
  view.geometry_ = this;
  for (const Eigen::Vector3d& d : physics::disc_directions(dir, radius_rad, kDiscSamples)) {
    view.disc_.push_back(ray_direction(d.cast<float>()));
  }
  const Eigen::Vector3f c = dir.normalized().cast<float>();
  std::vector<int> leds(led_dirs_.size());
  std::iota(leds.begin(), leds.end(), 0);
  const size_t count = std::min<size_t>(kNearestLeds, leds.size());
  std::partial_sort(leds.begin(), leds.begin() + long(count), leds.end(), [&](int i, int j) {
    return led_dirs_[size_t(i)].dot(c) > led_dirs_[size_t(j)].dot(c);
  });
  for (size_t i = 0; i < count; ++i) view.nearest_agreement_.push_back(&agreement(leds[i]));
  // What the nearest LED measured has the last word at a pixel, unless dead LEDs left it far.
  if (count > 1) {
    const Eigen::Vector3d nearest = led_dirs_[size_t(leds[0])].cast<double>();
    double spacing = std::numbers::pi;
    for (size_t l = 0; l < led_dirs_.size(); ++l) {
      if (int(l) != leds[0]) {
        spacing = std::min(spacing, angle_between(nearest, led_dirs_[l].cast<double>()));
      }
    }
    view.nearest_decides_ = angle_between(c.cast<double>(), nearest) < kNearestDecides * spacing;
  }
  return view;
}

const std::vector<std::uint64_t>& ShadowGeometry::agreement(int led) const {
  {
    const std::lock_guard<std::mutex> lock(agreement_mutex_);
    const auto it = agreement_.find(led);
    if (it != agreement_.end()) return it->second;
  }
  // Made unlocked (a parallel pass): two sources reaching a new LED at once make it twice, and
  // keep the first.
  LitMask agrees(size_t(field_width_) * field_height_, 0);
  const ShadowRayDirection along = ray_direction(led_dirs_[size_t(led)]);
  tbb::parallel_for(0, field_height_, [&](int y) {
    const size_t row = size_t(std::min(y / scale_, height_ - 1)) * width_;
    for (int x = 0; x < field_width_; ++x) {
      const size_t p = size_t(y) * field_width_ + x;
      if (top_px_[row + size_t(std::min(x / scale_, width_ - 1))] == kNoSurface) continue;
      agrees[p] = lit_bit(led_lit_bits_[size_t(led)], p) == sees(ray_start(x, y), along);
    }
  });
  std::vector<std::uint64_t> bits = pack_lit_bits(agrees);
  const std::lock_guard<std::mutex> lock(agreement_mutex_);
  return agreement_.emplace(led, std::move(bits)).first->second;
}

std::optional<SourceShadowView::Visibility> SourceShadowView::visibility(int x, int y) const {
  const ShadowGeometry& g = *geometry_;
  const int px = std::min(x / g.scale_, g.width_ - 1), py = std::min(y / g.scale_, g.height_ - 1);
  if (g.top_px_[size_t(py) * g.width_ + px] == ShadowGeometry::kNoSurface) return std::nullopt;
  const size_t p = size_t(y) * g.field_width_ + x;
  int agreeing = 0;
  for (const std::vector<std::uint64_t>* agrees : nearest_agreement_)
    agreeing += lit_bit(*agrees, p);
  const bool nearest_agrees = nearest_agreement_.empty() || lit_bit(*nearest_agreement_[0], p);
  // The disc's rim first (disc_directions' last samples are its outermost): a shadow's edge
  // across the disc puts rim rays on both sides, so where they agree the disc is taken to (on the
  // 12-megapixel set 21 of 244k pixels come out otherwise than with every ray, by a sixteenth or
  // two; the rays traced fall to 0.4 of them).
  const ShadowRayStart from = g.ray_start(x, y);
  const int disc = int(disc_.size()), rim = std::min(kRimSamples, disc);
  int seen = 0;
  for (int i = disc - rim; i < disc; ++i) seen += g.sees(from, disc_[size_t(i)]);
  if (seen == rim) {
    seen = disc;
  } else if (seen > 0) {
    for (int i = 0; i < disc - rim; ++i) seen += g.sees(from, disc_[size_t(i)]);
  }
  const int needed = std::min<int>(ShadowGeometry::kAgreeing, int(nearest_agreement_.size()));
  return Visibility{float(seen) / float(disc), nearest_agrees || !nearest_decides_,
                    agreeing >= needed};
}

Image SourceShadowView::trusted_visibility() const {
  const int width = geometry_->field_width_, height = geometry_->field_height_;
  Image shape(width, height, 1, std::numeric_limits<float>::quiet_NaN());
  cv::Mat agrees = cv::Mat::zeros(height, width, CV_8U);
  tbb::parallel_for(0, height, [&](int y) {
    for (int x = 0; x < width; ++x) {
      const size_t p = size_t(y) * width + x;
      if (const auto v = visibility(x, y)) {
        if (v->nearest_agrees) shape.pixels[p] = v->share;
        agrees.data[p] = v->most_agree ? 1 : 0;
      }
    }
  });
  cv::Mat votes;
  cv::boxFilter(agrees, votes, CV_32F, cv::Size(3, 3), cv::Point(-1, -1), false,
                cv::BORDER_REPLICATE);
  for (size_t p = 0; p < shape.pixels.size(); ++p) {
    if (votes.ptr<float>()[p] < 5) shape.pixels[p] = std::numeric_limits<float>::quiet_NaN();
  }
  return shape;
}

}  // namespace ls::relight
