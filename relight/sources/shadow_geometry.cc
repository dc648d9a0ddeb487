#include "relight/sources/shadow_geometry.h"

#include <tbb/combinable.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <numeric>

#include "lightstage/direction_index.h"
#include "lightstage/errors.h"
#include "relight/sources/depth_map_pixel.h"
#include "relight/sources/lit_bits.h"

namespace ls::relight {

namespace {

const char* const kPhase = "bright sources (the scene's shape)";

// Normals steeper than this (n_z, toward the camera) do not seed a region: their gradients are too
// large to integrate reliably (limbs, flanks); those over kLimbNz join a neighbouring region.
constexpr float kSeedNz = 0.5f;
constexpr float kLimbNz = 0.05f;
constexpr float kMaxGradient = 6.0f;  // Height change per pixel a normal may say.
// Neighbours whose normals differ by more than 35 degrees, or whose albedo chromaticities by more
// than 0.1, lie on different surfaces (a sphere's limb over the backdrop, relief over checker).
const float kSameSurfaceCos = float(std::cos(35.0 * std::numbers::pi / 180));
constexpr float kSameSurfaceChroma = 0.1f;
// Shares of the depth map's pixels: smaller regions are holes, filled around them; regions under
// the second continue their surroundings (at 256^2: 20 and 1000 pixels).
constexpr double kSmallestRegionShare = 3e-4;
constexpr double kPlacedRegionShare = 0.015;
// Scales of a floating region's relief tried when placing it: photometric normals flatten a
// sphere's rim (the fit averages over its shading), which makes its recovered height too low.
constexpr std::array<float, 4> kFloatingScales = {1.0f, 1.15f, 1.3f, 1.45f};
// Carving score: +1 for a measured shadow the placement casts, -kLitPenalty for a measured lit
// sample it shadows. A wrong shadow costs more than a missed one: normals too flat, and a limb
// the fit lost, make shapes too small, never too large.
constexpr double kLitPenalty = 3.0;

struct Neighbours {
  int at[4];  // -1 outside the image: left, right, up, down.
};
Neighbours neighbours(int p, int w, int h) {
  const int x = p % w, y = p / w;
  return {{x > 0 ? p - 1 : -1, x + 1 < w ? p + 1 : -1, y > 0 ? p - w : -1, y + 1 < h ? p + w : -1}};
}

// The field's fit averaged over scale x scale blocks.
struct DepthInput {
  int width = 0, height = 0;
  std::vector<Eigen::Vector3f> normal, albedo;
  std::vector<float> gx, gy;  // dz/dx, dz/dy in image axes (y down), from the normals.
};

DepthInput reduce_fit(const LambertianFit& fit, int scale) {
  DepthInput in;
  in.width = (fit.normal.width + scale - 1) / scale;
  in.height = (fit.normal.height + scale - 1) / scale;
  const size_t n = size_t(in.width) * in.height;
  in.normal.assign(n, Eigen::Vector3f::Zero());
  in.albedo.assign(n, Eigen::Vector3f::Zero());
  std::vector<int> count(n, 0);
  for (int y = 0; y < fit.normal.height; ++y) {
    for (int x = 0; x < fit.normal.width; ++x) {
      const size_t p = size_t(y) * fit.normal.width + x;
      const size_t q = size_t(y / scale) * in.width + x / scale;
      in.normal[q] += Eigen::Vector3f(&fit.normal.pixels[3 * p]);
      in.albedo[q] += Eigen::Vector3f(&fit.albedo.pixels[3 * p]);
      ++count[q];
    }
  }
  in.gx.assign(n, 0.0f);
  in.gy.assign(n, 0.0f);
  for (size_t q = 0; q < n; ++q) {
    in.albedo[q] /= float(std::max(count[q], 1));
    const float length = in.normal[q].norm();
    in.normal[q] = length > 0.5f * float(count[q]) ? Eigen::Vector3f(in.normal[q] / length)
                                                   : Eigen::Vector3f::Zero();
    const float nz = std::max(in.normal[q].z(), 1.0f / kMaxGradient);
    in.gx[q] = std::clamp(-in.normal[q].x() / nz, -kMaxGradient, kMaxGradient);
    in.gy[q] = std::clamp(in.normal[q].y() / nz, -kMaxGradient, kMaxGradient);
  }
  return in;
}

LitMask reduce_mask(const LitMask& full, int width, int height, const DepthInput& in, int scale) {
  if (scale == 1) return full;
  std::vector<int> lit(size_t(in.width) * in.height, 0), count(lit.size(), 0);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const size_t q = size_t(y / scale) * in.width + x / scale;
      lit[q] += full[size_t(y) * width + x];
      ++count[q];
    }
  }
  LitMask reduced(lit.size());
  for (size_t q = 0; q < lit.size(); ++q) reduced[q] = 2 * lit[q] >= count[q] ? 1 : 0;
  return reduced;
}

struct Edge {
  int a, b;    // Pixels, b right of or below a.
  float step;  // z_b - z_a.
};

// Surfaces: regions of pixels joined by edges whose normals and chromaticities agree.
struct Surfaces {
  std::vector<int> region;  // -1: none.
  std::vector<std::vector<int>> pixels;
  std::vector<Edge> edges;
  int background = -1;  // The largest.
};

Surfaces split_surfaces(const DepthInput& in) {
  const int w = in.width, h = in.height;
  const size_t n = size_t(w) * h;
  const auto usable = [&](int p, float min_nz) { return in.normal[size_t(p)].z() > min_nz; };
  const auto same = [&](int a, int b) {
    const Eigen::Vector3f ca = in.albedo[size_t(a)] / (in.albedo[size_t(a)].sum() + 1e-3f);
    const Eigen::Vector3f cb = in.albedo[size_t(b)] / (in.albedo[size_t(b)].sum() + 1e-3f);
    return in.normal[size_t(a)].dot(in.normal[size_t(b)]) > kSameSurfaceCos &&
           (ca - cb).norm() < kSameSurfaceChroma;
  };
  const auto step = [&](int a, int b) {
    return b == a + 1 ? 0.5f * (in.gx[size_t(a)] + in.gx[size_t(b)])
                      : 0.5f * (in.gy[size_t(a)] + in.gy[size_t(b)]);
  };
  Surfaces s;
  std::vector<int> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  const auto find = [&parent](int a) {
    while (parent[size_t(a)] != a) a = parent[size_t(a)] = parent[size_t(parent[size_t(a)])];
    return a;
  };
  std::vector<char> joined(n, 0);
  for (int p = 0; p < int(n); ++p) {
    if (!usable(p, kSeedNz)) continue;
    joined[size_t(p)] = 1;
    const Neighbours nb = neighbours(p, w, h);
    for (const int q : {nb.at[1], nb.at[3]}) {
      if (q < 0 || !usable(q, kSeedNz) || !same(p, q)) continue;
      s.edges.push_back({p, q, step(p, q)});
      parent[size_t(find(p))] = find(q);
    }
  }
  // Limbs grow back, each pixel onto its most similar joined neighbour.
  for (int pass = 0; pass < 64; ++pass) {
    bool grew = false;
    for (int p = 0; p < int(n); ++p) {
      if (joined[size_t(p)] || !usable(p, kLimbNz)) continue;
      int best = -1;
      float best_cos = kSameSurfaceCos;
      for (const int q : neighbours(p, w, h).at) {
        if (q < 0 || !joined[size_t(q)]) continue;
        const float c = in.normal[size_t(p)].dot(in.normal[size_t(q)]);
        if (c > best_cos) best_cos = c, best = q;
      }
      if (best < 0) continue;
      joined[size_t(p)] = 1;
      const int a = std::min(p, best), b = std::max(p, best);
      s.edges.push_back({a, b, step(a, b)});
      parent[size_t(find(p))] = find(best);
      grew = true;
    }
    if (!grew) break;
  }
  std::vector<std::vector<int>> by_root(n);
  for (int p = 0; p < int(n); ++p) {
    if (joined[size_t(p)]) by_root[size_t(find(p))].push_back(p);
  }
  s.region.assign(n, -1);
  for (auto& pixels : by_root) {
    if (double(pixels.size()) < kSmallestRegionShare * double(n)) continue;
    const int r = int(s.pixels.size());
    if (s.background < 0 || pixels.size() > s.pixels[size_t(s.background)].size()) s.background = r;
    for (const int p : pixels) s.region[size_t(p)] = r;
    s.pixels.push_back(std::move(pixels));
  }
  return s;
}

// Heights per region (least squares over its edges), each region's lowest at 0.
std::vector<float> integrate_surfaces(const Surfaces& s, size_t n) {
  std::vector<float> z(n, 0.0f);
  std::vector<int> local(n, -1);
  for (const auto& pixels : s.pixels) {
    for (size_t i = 0; i < pixels.size(); ++i) local[size_t(pixels[i])] = int(i);
  }
  std::vector<std::vector<Eigen::Triplet<double>>> triplets(s.pixels.size());
  std::vector<Eigen::VectorXd> rhs(s.pixels.size());
  for (size_t r = 0; r < s.pixels.size(); ++r) {
    rhs[r] = Eigen::VectorXd::Zero(long(s.pixels[r].size()));
    // A weak pull to 0 fixes the free constant.
    for (size_t i = 0; i < s.pixels[r].size(); ++i) triplets[r].emplace_back(i, i, 1e-6);
  }
  for (const Edge& e : s.edges) {
    const int r = s.region[size_t(e.a)];
    if (r < 0 || s.region[size_t(e.b)] != r) continue;
    const int a = local[size_t(e.a)], b = local[size_t(e.b)];
    auto& t = triplets[size_t(r)];
    t.emplace_back(a, a, 1);
    t.emplace_back(b, b, 1);
    t.emplace_back(a, b, -1);
    t.emplace_back(b, a, -1);
    rhs[size_t(r)][b] += e.step;
    rhs[size_t(r)][a] -= e.step;
  }
  for (size_t r = 0; r < s.pixels.size(); ++r) {
    const long m = long(s.pixels[r].size());
    Eigen::SparseMatrix<double> a(m, m);
    a.setFromTriplets(triplets[r].begin(), triplets[r].end());
    const Eigen::VectorXd solved =
        Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>(a).solve(rhs[r]);
    const double lowest = solved.minCoeff();
    for (long i = 0; i < m; ++i) z[size_t(s.pixels[r][size_t(i)])] = float(solved[i] - lowest);
  }
  return z;
}

// A region floats (a sphere, not a bump of the ground) when most of its rim is steep.
bool floats(const Surfaces& s, int r, const DepthInput& in) {
  int rim = 0, steep = 0;
  for (const int p : s.pixels[size_t(r)]) {
    bool at_rim = false;
    for (const int q : neighbours(p, in.width, in.height).at) {
      at_rim = at_rim || q < 0 || s.region[size_t(q)] != r;
    }
    if (!at_rim) continue;
    ++rim;
    steep += in.normal[size_t(p)].z() < kSeedNz;
  }
  return rim > 0 && 2 * steep > rim;
}

// The depth map as it is built: surface heights and the solid's reach below them.
struct Depth {
  int width = 0, height = 0;
  std::vector<float> top, thickness;  // Depth-map pixels; thickness infinite: attached.
};
constexpr float kAttached = 1e30f;

// Offsets of a region above the backdrop scored against the LEDs' measured shadows.
struct Carving {
  const Depth& depth;
  const Surfaces& surfaces;
  const std::vector<LitMask>& lit;  // Depth-map resolution.
  const std::vector<Eigen::Vector3f>& led_dirs;
  float lowest_offset = 0;  // Candidate i is offset lowest_offset + i.
  int candidates = 0;

  // The best offset of region r as it now lies in `depth` (at offset 0) and its score.
  std::pair<float, double> best_offset(int r) const {
    tbb::combinable<std::vector<double>> per_thread(
        [this] { return std::vector<double>(size_t(candidates) + 2, 0.0); });
    const Box box = box_of(r);
    float highest = -1e30f;  // Of any surface: above it a receiver's ray meets nothing.
    for (size_t p = 0; p < depth.top.size(); ++p) {
      if (surfaces.region[p] >= 0) highest = std::max(highest, depth.top[p]);
    }
    tbb::parallel_for(0, int(led_dirs.size()), [&](int l) {
      if (led_dirs[size_t(l)].z() < 0.1f) return;
      score_led(r, box, highest, l, per_thread.local());
    });
    std::vector<double> score(size_t(candidates) + 2, 0.0);
    per_thread.combine_each([&](const std::vector<double>& s) {
      for (size_t i = 0; i < s.size(); ++i) score[i] += s[i];
    });
    double run = 0, best = -1e300;
    int best_i = 0;
    for (int i = 0; i <= candidates; ++i) {
      run += score[size_t(i)];
      if (run > best) best = run, best_i = i;
    }
    return {lowest_offset + float(best_i), best};
  }

  // Where region r's pixels are, as the samples of a ray round to them: [x0, x1) x [y0, y1) in
  // continuous depth-map coordinates (pixel centres on integers).
  struct Box {
    float x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  };
  Box box_of(int r) const {
    int x0 = depth.width, x1 = -1, y0 = depth.height, y1 = -1;
    for (const int p : surfaces.pixels[size_t(r)]) {
      x0 = std::min(x0, p % depth.width), x1 = std::max(x1, p % depth.width);
      y0 = std::min(y0, p / depth.width), y1 = std::max(y1, p / depth.width);
    }
    return {float(x0) - 0.5f, float(x1) + 0.5f, float(y0) - 0.5f, float(y1) + 0.5f};
  }

  // The steps [first, last] of the ray from (x, y) along (dx, dy), `step` apart, that can fall in
  // `box` (a margin of a step each way for rounding); first > last when none can.
  static std::pair<int, int> steps_through(const Box& box, float x, float y, float dx, float dy,
                                           float step) {
    float enter = 0, leave = 1e30f;
    const auto slab = [&](float from, float along, float lo, float hi) {
      if (std::abs(along) < 1e-9f) {
        if (from < lo || from > hi) leave = -1;
        return;
      }
      float a = (lo - from) / along, b = (hi - from) / along;
      if (a > b) std::swap(a, b);
      enter = std::max(enter, a);
      leave = std::min(leave, b);
    };
    slab(x, dx, box.x0, box.x1);
    slab(y, dy, box.y0, box.y1);
    if (enter > leave) return {1, 0};
    return {std::max(1, int(enter / step) - 1), int(std::min(leave / step, 1e9f)) + 1};
  }

  // Adds +1 (measured shadow) or -kLitPenalty (measured lit) over the offsets at which region r
  // shadows a sample (occluder), or at which another region shadows r's sample (receiver); the
  // score is kept as differences, summed in best_offset. An occluder's ray is marched only where it
  // crosses r's box (`box`): nowhere else can it meet r (a ray leaves the map once, and the box is
  // inside it, so no step it skips could have ended the march); a receiver's only until it rises
  // past what any offset considered could put in its way (`highest` surface): the same sums in a
  // fraction of the steps.
  void score_led(int r, const Box& box, float highest, int l, std::vector<double>& score) const {
    const int w = depth.width, h = depth.height;
    const Eigen::Vector3f& d = led_dirs[size_t(l)];
    const float dx = d.x(), dy = -d.y(), dz = d.z();
    const float dxy = std::hypot(dx, dy);
    if (dxy < 1e-3f) return;
    const float step = 0.5f / dxy;
    for (int y = 0; y < h; y += 2) {
      for (int x = 0; x < w; x += 2) {
        const size_t p = size_t(y) * w + x;
        if (surfaces.region[p] < 0) continue;
        const bool receiver = surfaces.region[p] == r;
        const float start = depth.top[p] + 0.5f;
        float lo = 1e30f, hi = -1e30f;
        int first = 1, last = 2 * (w + h) - 1;
        if (!receiver) {
          const auto [enter, leave] = steps_through(box, float(x), float(y), dx, dy, step);
          first = std::max(first, enter);
          last = std::min(last, leave);
        } else {
          // Beyond it every step's top (highest - start - t dz) is under lowest_offset - 8.
          const float rises_past = (highest - start - (lowest_offset - 8)) / dz;
          last = std::min(last, int(std::min(std::max(rises_past, 0.0f) / step, 1e9f)) + 1);
        }
        for (int i = first; i <= last; ++i) {
          const float t = step * float(i);
          const int qx = pixel_of(float(x) + t * dx), qy = pixel_of(float(y) + t * dy);
          if (qx < 0 || qy < 0 || qx >= w || qy >= h) break;
          const size_t q = size_t(qy) * w + qx;
          const int rq = surfaces.region[q];
          if (receiver) {
            // Raised by o, r's ray meets q's solid for o in (top - thickness, top).
            if (rq == r || rq < 0) continue;
            const float top = depth.top[q] - start - t * dz;
            if (top < lowest_offset - 8) continue;
            lo = std::min(lo, top - std::min(depth.thickness[q], 1e6f));
            hi = std::max(hi, top);
          } else if (rq == r) {
            // Raised by o, q's solid holds the ray for o in (ray - top, ray - top + thickness).
            const float ray = start + t * dz;
            lo = std::min(lo, ray - depth.top[q]);
            hi = std::max(hi, ray - depth.top[q] + depth.thickness[q]);
          }
        }
        if (lo > hi) continue;
        const double v = lit[size_t(l)][p] ? -kLitPenalty : 1.0;
        const int a = std::clamp(int(std::ceil(lo - lowest_offset)), 0, candidates + 1);
        const int b =
            std::clamp(int(std::floor(hi - lowest_offset)), receiver ? -1 : 0, candidates);
        if (a > b) continue;
        score[size_t(a)] += v;
        score[size_t(b) + 1] -= v;
      }
    }
  }
};

bool placed_by_carving(const Surfaces& s, int r, size_t pixels) {
  return double(s.pixels[size_t(r)].size()) >= kPlacedRegionShare * double(pixels);
}

// Places each large region above the backdrop (and scales a floating one's relief) by carving;
// `placed()` after each.
void place_regions(Depth& depth, const Surfaces& s, const std::vector<float>& relief,
                   const std::vector<char>& floating, const std::vector<LitMask>& lit,
                   const std::vector<Eigen::Vector3f>& led_dirs,
                   const std::function<void()>& placed) {
  float bg_lo = 1e30f, bg_hi = -1e30f;
  for (const int p : s.pixels[size_t(s.background)]) {
    bg_lo = std::min(bg_lo, relief[size_t(p)]);
    bg_hi = std::max(bg_hi, relief[size_t(p)]);
  }
  const Carving carving{depth,     s,
                        lit,       led_dirs,
                        bg_lo - 8, int(bg_hi - bg_lo + float(std::max(depth.width, depth.height)))};
  for (int r = 0; r < int(s.pixels.size()); ++r) {
    if (r == s.background || !placed_by_carving(s, r, depth.top.size())) continue;
    const auto& pixels = s.pixels[size_t(r)];
    const auto lay = [&](float scale, float offset) {
      float highest = 0;
      for (const int p : pixels) highest = std::max(highest, scale * relief[size_t(p)]);
      // The hidden half mirrors the visible one about the silhouette, which lies below the
      // lowest recovered pixel (steep rims are lost) by what a sphere of the region's
      // silhouette area would add.
      const float below =
          std::max(0.0f, std::sqrt(float(pixels.size()) / float(std::numbers::pi)) - highest);
      for (const int p : pixels) {
        depth.top[size_t(p)] = scale * relief[size_t(p)] + offset;
        if (floating[size_t(r)])
          depth.thickness[size_t(p)] = 2 * (scale * relief[size_t(p)] + below) + 1;
      }
    };
    double best_score = -1e300;
    float best_scale = 1, best_offset = 0;
    for (const float scale :
         floating[size_t(r)] ? std::vector<float>(kFloatingScales.begin(), kFloatingScales.end())
                             : std::vector<float>{1.0f}) {
      lay(scale, 0);
      const auto [offset, score] = carving.best_offset(r);
      if (score > best_score) best_score = score, best_scale = scale, best_offset = offset;
    }
    lay(best_scale, best_offset);
    placed();
  }
}

// Small regions (bump tips cut off by their steep flanks) continue the surface around them: the
// median over their rim of the neighbour's height plus the normals' step.
void continue_small_regions(Depth& depth, const Surfaces& s, const std::vector<char>& floating,
                            const DepthInput& in) {
  for (int r = 0; r < int(s.pixels.size()); ++r) {
    if (r == s.background || placed_by_carving(s, r, depth.top.size())) continue;
    std::vector<float> offsets;
    for (const int p : s.pixels[size_t(r)]) {
      const Neighbours nb = neighbours(p, in.width, in.height);
      for (int k = 0; k < 4; ++k) {
        const int q = nb.at[k];
        if (q < 0 || s.region[size_t(q)] < 0 || s.region[size_t(q)] == r ||
            floating[size_t(s.region[size_t(q)])]) {
          continue;
        }
        const float gradient = k < 2 ? 0.5f * (in.gx[size_t(q)] + in.gx[size_t(p)])
                                     : 0.5f * (in.gy[size_t(q)] + in.gy[size_t(p)]);
        const float p_above_q = (k == 0 || k == 2) ? gradient : -gradient;  // q left of / above p
        offsets.push_back(depth.top[size_t(q)] + p_above_q - depth.top[size_t(p)]);
      }
    }
    if (offsets.empty()) continue;
    std::nth_element(offsets.begin(), offsets.begin() + long(offsets.size() / 2), offsets.end());
    for (const int p : s.pixels[size_t(r)]) {
      depth.top[size_t(p)] += offsets[offsets.size() / 2];
      depth.thickness[size_t(p)] = kAttached;
    }
  }
}

// Pixels of no region (normals too steep: flanks) take their highest attached neighbour's height.
void fill_holes(Depth& depth, std::vector<int> region, const std::vector<char>& floating) {
  const int w = depth.width, h = depth.height;
  for (int pass = 0; pass < 16; ++pass) {
    Depth next = depth;
    std::vector<int> next_region = region;
    bool filled = false;
    for (int p = 0; p < w * h; ++p) {
      if (region[size_t(p)] >= 0) continue;
      int best = -1;
      for (const int q : neighbours(p, w, h).at) {
        if (q >= 0 && region[size_t(q)] >= 0 &&
            (best < 0 || depth.top[size_t(q)] > depth.top[size_t(best)]))
          best = q;
      }
      if (best < 0 || floating[size_t(region[size_t(best)])]) continue;
      next.top[size_t(p)] = depth.top[size_t(best)];
      next.thickness[size_t(p)] = depth.thickness[size_t(best)];
      next_region[size_t(p)] = region[size_t(best)];
      filled = true;
    }
    depth = std::move(next);
    region = std::move(next_region);
    if (!filled) break;
  }
}

}  // namespace

ShadowGeometry::ShadowGeometry(const LambertianFit& fit,
                               const std::vector<Eigen::Vector3d>& led_dirs,
                               const std::function<LitMask(int led)>& lit_mask,
                               const ProgressFn& progress)
    : field_width_(fit.normal.width), field_height_(fit.normal.height) {
  LS_CHECK(field_width_ > 0 && field_height_ > 0, "ShadowGeometry: the Lambertian fit is empty");
  scale_ = (std::max(field_width_, field_height_) + kDepthMapSize - 1) / kDepthMapSize;
  const DepthInput in = reduce_fit(fit, scale_);
  width_ = in.width;
  height_ = in.height;
  // The regions the carving places, counted first: the phase's total is the LEDs and them.
  const Surfaces surfaces = split_surfaces(in);
  int to_place = 0;
  for (int r = 0; surfaces.background >= 0 && r < int(surfaces.pixels.size()); ++r) {
    to_place +=
        r != surfaces.background && placed_by_carving(surfaces, r, size_t(in.width) * in.height);
  }
  const int leds = int(led_dirs.size());
  std::vector<LitMask> lit(static_cast<size_t>(leds));
  led_lit_bits_.resize(size_t(leds));
  // The LEDs side by side (each mask is a serial pass over the field), as many at a time as
  // there are cores: progress after each few, where a viewer that no longer needs the shape stops
  // it.
  const int at_a_time = std::max(1, tbb::this_task_arena::max_concurrency());
  for (int first = 0; first < leds; first += at_a_time) {
    const int last = std::min(leds, first + at_a_time);
    tbb::parallel_for(first, last, [&](int l) {
      const LitMask mask = lit_mask(l);
      LS_CHECK(mask.size() == size_t(field_width_) * field_height_,
               "ShadowGeometry: LED " + std::to_string(l) + "'s mask is not the field's size");
      led_lit_bits_[size_t(l)] = pack_lit_bits(mask);
      lit[size_t(l)] = reduce_mask(mask, field_width_, field_height_, in, scale_);
    });
    report(progress, kPhase, last, leds + to_place);
  }
  for (int l = 0; l < leds; ++l)
    led_dirs_.push_back(led_dirs[size_t(l)].normalized().cast<float>());
  Depth depth{width_, height_, {}, {}};
  depth.top.assign(size_t(width_) * height_, kNoSurface);
  depth.thickness.assign(depth.top.size(), kAttached);
  if (surfaces.background >= 0) {
    const std::vector<float> relief = integrate_surfaces(surfaces, depth.top.size());
    std::vector<char> floating(surfaces.pixels.size(), 0);
    for (int r = 0; r < int(surfaces.pixels.size()); ++r) {
      floating[size_t(r)] = r != surfaces.background && floats(surfaces, r, in);
      for (const int p : surfaces.pixels[size_t(r)]) {
        depth.top[size_t(p)] = relief[size_t(p)];
        if (floating[size_t(r)]) depth.thickness[size_t(p)] = 2 * relief[size_t(p)] + 1;
      }
    }
    int placed = 0;
    place_regions(depth, surfaces, relief, floating, lit, led_dirs_,
                  [&] { report(progress, kPhase, leds + ++placed, leds + to_place); });
    continue_small_regions(depth, surfaces, floating, in);
    fill_holes(depth, surfaces.region, floating);
  }
  top_px_ = std::move(depth.top);
  thickness_px_ = std::move(depth.thickness);
  build_block_pyramid();
}

}  // namespace ls::relight
