#include "lightstage/controller/frame_checks.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace ls {

namespace {

constexpr int kGrid = 16;              // Regions per side of the bracket comparison.
constexpr size_t kMaxSamples = 65536;  // Pixels sampled per frame: the checks cost microseconds.
constexpr int kMinRegionValues = 16;   // Values a region needs to be judged.
constexpr double kNoiseSigmas = 5.0;
constexpr double kRelativeTolerance = 0.10;
// And more than 2 DN in the shorter exposure: below, a black level off by a fraction of a DN
// (a sensor's drift, read noise clipped at zero) would pass for a fault in dim regions.
constexpr double kMinDifferenceDn = 2.0;
constexpr double kBadRegionShare = 0.02;
constexpr double kSaturatedFraction = 0.98;  // Of full scale: such values are left out.

// Sampling stride (both axes) that keeps at most ~kMaxSamples pixels.
int sample_stride(const RawFrame& frame) {
  const double pixels = double(frame.width) * frame.height;
  return std::max(1, int(std::sqrt(pixels / double(kMaxSamples))));
}

struct RegionSums {
  int n = 0;
  double diff = 0, diff2 = 0, level = 0;
};

// Compares frames a and b region by region; the rows of the regions that disagree are returned in
// first_row/last_row (-1 when none do). True when the pair disagrees.
bool pair_disagrees(const BracketFrame& a, const BracketFrame& b, const DnToLinear& to_linear,
                    int* bad_regions, int* judged_regions, int* first_row, int* last_row) {
  const RawFrame& fa = *a.raw;
  const RawFrame& fb = *b.raw;
  const int w = fa.width, h = fa.height, channels = fa.channels;
  const double max_dn = fa.max_value();
  const auto linear = [&](double dn, int c) {
    if (to_linear) return to_linear(std::clamp(int(std::lround(dn)), 0, int(max_dn)), c);
    return dn / max_dn;
  };
  const double scale_a = 1.0 / (a.exposure_s * a.gain), scale_b = 1.0 / (b.exposure_s * b.gain);
  // A difference in the units above times this is DN of the shorter exposure.
  const double min_scale = std::min(a.exposure_s * a.gain, b.exposure_s * b.gain);
  const int stride = sample_stride(fa);
  std::vector<RegionSums> regions(size_t(kGrid) * kGrid);
  for (int y = 0; y < h; y += stride) {
    const int gy = std::min(kGrid - 1, y * kGrid / h);
    for (int x = 0; x < w; x += stride) {
      const int gx = std::min(kGrid - 1, x * kGrid / w);
      RegionSums& r = regions[size_t(gy) * kGrid + gx];
      for (int c = 0; c < channels; ++c) {
        const size_t i = (size_t(y) * w + x) * channels + c;
        const uint16_t dn_a = fa.pixels[i], dn_b = fb.pixels[i];
        if (dn_a >= kSaturatedFraction * max_dn || dn_b >= kSaturatedFraction * max_dn) continue;
        const double va = (linear(dn_a, c) - linear((*a.dark)[i], c)) * scale_a;
        const double vb = (linear(dn_b, c) - linear((*b.dark)[i], c)) * scale_b;
        ++r.n;
        r.diff += va - vb;
        r.diff2 += (va - vb) * (va - vb);
        r.level += 0.5 * (va + vb);
      }
    }
  }
  *bad_regions = *judged_regions = 0;
  std::vector<int> bad_in_row(kGrid, 0), judged_in_row(kGrid, 0);
  for (int k = 0; k < kGrid * kGrid; ++k) {
    const RegionSums& r = regions[size_t(k)];
    if (r.n < kMinRegionValues) continue;
    const double mean = r.diff / r.n, level = r.level / r.n;
    const double variance = std::max(0.0, r.diff2 / r.n - mean * mean);
    const double standard_error = std::sqrt(variance / (r.n - 1));
    ++*judged_regions;
    ++judged_in_row[size_t(k / kGrid)];
    if (std::abs(mean) > kNoiseSigmas * standard_error &&
        std::abs(mean) > kRelativeTolerance * std::abs(level) &&
        std::abs(mean) * min_scale * max_dn > kMinDifferenceDn) {
      ++*bad_regions;
      ++bad_in_row[size_t(k / kGrid)];
    }
  }
  // The rows where the disagreement is: region rows with a quarter of their regions bad (a torn
  // frame's lower part), else every row with any.
  *first_row = *last_row = -1;
  for (const double share : {0.25, 0.0}) {
    for (int gy = 0; gy < kGrid; ++gy) {
      if (bad_in_row[size_t(gy)] == 0 ||
          bad_in_row[size_t(gy)] < share * judged_in_row[size_t(gy)]) {
        continue;
      }
      if (*first_row < 0) *first_row = gy * h / kGrid;
      *last_row = (gy + 1) * h / kGrid - 1;
    }
    if (*first_row >= 0) break;
  }
  return *bad_regions >= 2 && *bad_regions >= kBadRegionShare * *judged_regions;
}

}  // namespace

std::string dark_frame_problem(const RawFrame& frame, double max_fraction) {
  if (frame.pixels.empty() || frame.width < 1 || frame.height < 1) return "the frame is empty";
  // Region means: light lights regions, while hot pixels, isolated, hardly move a region's mean.
  const int stride = sample_stride(frame);
  std::vector<double> sum(size_t(kGrid) * kGrid, 0.0);
  std::vector<int> count(sum.size(), 0);
  for (int y = 0; y < frame.height; y += stride) {
    const int gy = std::min(kGrid - 1, y * kGrid / frame.height);
    for (int x = 0; x < frame.width; x += stride) {
      const size_t region =
          size_t(gy) * kGrid + size_t(std::min(kGrid - 1, x * kGrid / frame.width));
      for (int c = 0; c < frame.channels; ++c) {
        sum[region] += frame.pixels[(size_t(y) * frame.width + x) * frame.channels + c];
        ++count[region];
      }
    }
  }
  std::vector<double> means;
  for (size_t r = 0; r < sum.size(); ++r) {
    if (count[r] > 0) means.push_back(sum[r] / count[r]);
  }
  const double brightest = *std::max_element(means.begin(), means.end());
  std::nth_element(means.begin(), means.begin() + long(means.size() / 2), means.end());
  const double spread = (brightest - means[means.size() / 2]) / double(frame.max_value());
  if (spread <= max_fraction) return {};
  char text[200];
  std::snprintf(text, sizeof text,
                "light in a dark frame: its brightest region exceeds the median region by %.2f%% "
                "of full scale (allowed %.2f%%): an LED stuck on, or light in the room",
                spread * 100, max_fraction * 100);
  return text;
}

std::vector<std::string> bracket_problems(const std::vector<BracketFrame>& frames,
                                          const DnToLinear& to_linear) {
  const size_t n = frames.size();
  std::vector<std::string> problems(n);
  if (n < 2) return problems;
  if (frames[0].raw == nullptr) return problems;
  for (const BracketFrame& f : frames) {
    const RawFrame& first = *frames[0].raw;
    if (f.raw == nullptr || f.dark == nullptr || f.raw->width != first.width ||
        f.raw->height != first.height || f.raw->channels != first.channels ||
        f.dark->size() != f.raw->pixels.size() || !(f.exposure_s > 0) || !(f.gain > 0)) {
      return problems;
    }
  }
  // disagree[i][j]: how frames i and j disagree, or "" when they agree.
  std::vector<std::vector<std::string>> disagree(n, std::vector<std::string>(n));
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = i + 1; j < n; ++j) {
      int bad = 0, judged = 0, first_row = -1, last_row = -1;
      if (!pair_disagrees(frames[i], frames[j], to_linear, &bad, &judged, &first_row, &last_row)) {
        continue;
      }
      char text[160];
      std::snprintf(text, sizeof text, "in %d of %d regions (rows %d-%d)", bad, judged, first_row,
                    last_row);
      disagree[i][j] = disagree[j][i] = text;
    }
  }
  for (size_t i = 0; i < n; ++i) {
    size_t against = n;  // The first frame it disagrees with.
    int disagreements = 0;
    for (size_t j = 0; j < n; ++j) {
      if (j == i || disagree[i][j].empty()) continue;
      ++disagreements;
      if (against == n) against = j;
    }
    if (disagreements < int(n) - 1 || disagreements == 0) continue;
    problems[i] = "disagrees with the bracket's exposure " +
                  std::to_string(frames[against].exposure_index) + " " + disagree[i][against] +
                  " once both are made linear and divided by exposure and gain: a torn, partial "
                  "or stale frame, one from another LED, or a wrong exposure";
  }
  return problems;
}

}  // namespace ls
