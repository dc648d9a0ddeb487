#pragma once
// A bright source (bright_sources.h) rendered from a reflectance field at its true direction,
// between the LEDs that sampled the field:
//  - Shading: the pixel's Lambertian term at the source's direction (normal and albedo from
//    photometric stereo), plus what the LEDs around the source show beyond their own Lambertian
//    term (gloss), each LED's carried toward the source along the optical flow between the LEDs'
//    gloss images (a highlight moves with the light instead of showing once per LED) and
//    blended with the source's barycentric weights in their spherical Delaunay triangle.
//  - Visibility: per LED of the triangle, the signed distance in pixels from each pixel to the edge
//    of that LED's cast shadow (a shadowed sample is under half of its Lambertian term). Each
//    LED's distances are carried toward the source along the optical flow between the LEDs'
//    distance images (DIS flow; multi-image morphing, in the spirit of Fuchs et al. 2007's flow
//    between one-light images), weighted by the source's barycentric weights, then blended with
//    those weights: a shadow's edge moves with the light instead of cross-fading between two or
//    three offset copies. The edge is ramped over the penumbra a disc of the source's radius
//    casts: half-width = radius x how fast the edge moves between the LEDs (flow length per
//    radian), at least half a pixel.
// Values are in field units per unit irradiance, like the field: out += E (.) (V S + (1 - V) A),
// with A what the shadowed LEDs still see (light bounced into the shadow).
// Near-LED fields are lit along the LEDs' nominal directions here.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "lightstage/image.h"
#include "relight/sources/bright_sources.h"

namespace ls::relight {

struct LedTriangle {
  std::array<int, 3> leds{};        // Light indices of the field.
  std::array<double, 3> weights{};  // Barycentric: >= 0, sum 1; sum_k w_k l_k is along the source.
};

// The spherical Delaunay triangle of the usable LEDs (unit directions) that holds `dir`, found
// among its 12 nearest LEDs (the empty-circumcircle test run there). Outside every triangle but
// within coverage_rad of an LED: that LED alone, weight 1. Farther: nullopt (the dome has no light
// there; integrate_environment reports such light as uncovered).
std::optional<LedTriangle> led_triangle(const std::vector<Eigen::Vector3d>& unit_dirs,
                                        const std::vector<bool>& usable, const Eigen::Vector3d& dir,
                                        double coverage_rad);

// Each pixel's Lambertian fit (relight::estimate_normals): unit normal, (0,0,0) where unknown, and
// albedo per channel (R = albedo / pi * cos).
struct LambertianFit {
  Image normal;
  Image albedo;
};

// Which pixels an LED lit (1) and left in its cast shadow (0): a sample under half of its
// Lambertian term is shadowed; where that term is too dark to tell, the nearest told pixel's
// answer. `rgb`: the LED's image (width x height x 3, field units).
using LitMask = std::vector<std::uint8_t>;
LitMask led_lit_mask(const Eigen::Vector3d& led_dir, const std::vector<float>& rgb,
                     const LambertianFit& fit);

// One LED's image (width x height x 3, field units) and the signed distance from each pixel to the
// edge of its cast shadow, in pixels: > 0 lit, < 0 shadowed, clamped to +-max(width, height) / 4.
struct LedShadow {
  Eigen::Vector3d dir{0, 1, 0};
  int width = 0, height = 0;
  std::vector<float> rgb;
  // What the LED shows beyond the pixel's Lambertian term where lit (highlights), 0 in shadow.
  std::vector<float> gloss_rgb;
  std::vector<float> edge_distance_px;
};
LedShadow led_shadow(const Eigen::Vector3d& led_dir, std::vector<float> rgb,
                     const LambertianFit& fit);

// Where what LED `from` shows at each pixel lies under LED `to`: dense optical flow (DIS, Kroeger
// et al. 2016), (dx, dy) per pixel, row-major; of the shadow edges between the signed-distance
// images, and of the highlights between the gloss images (log scaled).
struct LedPairFlow {
  std::vector<float> shadow, gloss;
};
LedPairFlow led_pair_flow(const LedShadow& from, const LedShadow& to);

// Adds the light of `source` (its direction in the stage frame: the map's, rotated with it) to
// `out` (width x height x 3). shadows[k] is the LedShadow of
// triangle.leds[k]; flows[k][j] the led_pair_flow from shadows[k] to shadows[j], needed (not
// null) for every other LED j where LED k weighs at least kMinTriangleWeight (toward an LED of no
// weight for the penumbra's width: how fast the edges move). `visibility`, when given
// (1 channel, the field's size), is the share of the source each pixel sees, used instead of the
// visibility interpolated from the LEDs' shadows: a simulator's exact one (sim::
// render_source_visibility) measures how much of the error is the shadows' and how much the
// shading's. `shape`, when given (1 channel, the field's size), is the share of the source the
// scene's recovered shape lets each pixel see where it is trusted, NaN where the flows decide
// (shape_visibility, shadow_geometry.h).
inline constexpr double kMinTriangleWeight = 1e-3;
using PairFlows = std::array<std::array<const LedPairFlow*, 3>, 3>;
void add_bright_source(const std::array<const LedShadow*, 3>& shadows, const PairFlows& flows,
                       const LedTriangle& triangle, const BrightSource& source,
                       const LambertianFit& fit, Image& out, const Image* visibility = nullptr,
                       const Image* shape = nullptr);

}  // namespace ls::relight
