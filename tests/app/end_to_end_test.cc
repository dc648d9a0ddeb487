// The whole slice against ground truth: simulated capture -> session -> field -> relighting.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>
#include <numeric>
#include <set>

#include "lightstage/direction_index.h"
#include "physics/envmap.h"
#include "relight/fit/normals.h"
#include "relight/lighting/light_cells.h"
#include "relight/lighting/relight.h"
#include "relight/sources/field_sources.h"
#include "sim/ground_truth.h"
#include "tests/app/e2e_fixtures.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

using physics::EnvironmentMap;

Image ConstantMap(float radiance, int width = 256) { return Image(width, width / 2, 3, radiance); }

sim::Scene LoneSphere(double albedo) {
  sim::Scene scene;
  sim::SceneMaterial m;
  m.name = "matte";
  m.base.albedo = Eigen::Vector3d::Constant(albedo);
  scene.materials.push_back(m);
  scene.spheres.push_back({{0, 0, 0}, 0.9, 0});
  return scene;
}

Image HitMask(const std::vector<sim::SurfaceHit>& hits, int width, int height) {
  Image mask(width, height, 1);
  for (size_t i = 0; i < hits.size(); ++i) mask.pixels[i] = hits[i].hit ? 1.0f : 0.0f;
  return mask;
}

// A Lambertian sphere under a constant environment L = c has radiance rho * c everywhere
// (irradiance pi * c, Lambert BRDF rho / pi): the closed form, through the whole pipeline.
TEST(EndToEnd, LambertianSphereUnderConstantEnvironmentMatchesClosedForm) {
  testing::TempDir tmp;
  // A full-sphere dome, so that no direction is uncovered.
  Stage stage = stage_with_directions(fibonacci_dome_directions(300, -90));
  stage.camera.width = stage.camera.height = 64;
  const double albedo = 0.7, c = 0.5;
  const sim::Scene scene = LoneSphere(albedo);
  const auto field = testing::CaptureAndBuild(tmp / "s", stage, scene);

  const EnvironmentMap map(ConstantMap(float(c)));
  const auto weights = relight::integrate_environment(map, stage.led_directions());
  EXPECT_LT(weights.uncovered_fraction(), 1e-9);
  const Image relit = relight::relight(field, weights);

  const auto hits = sim::trace_camera(scene, stage.camera);
  // Keep away from the silhouette, where a pixel is part sphere, part background.
  Image mask = HitMask(hits, 64, 64);
  for (size_t i = 0; i < hits.size(); ++i) {
    if (hits[i].hit && hits[i].normal.z() < 0.2) mask.pixels[i] = 0;
  }
  const Image expected(64, 64, 3, float(albedo * c));
  const auto err = testing::compare_images(relit, expected, &mask);
  std::cout << "Lambertian sphere, constant map, 300 LEDs: relative RMSE " << err.relative_rmse
            << ", worst " << err.max_abs / (albedo * c) << " relative\n";
  // Measured 0.15% relative RMSE, 0.45% worst pixel (discretisation of the clamped cosine at 300
  // LEDs, plus camera noise).
  EXPECT_TRUE(testing::ImageNear(relit, expected, 0.004, &mask));
}

// Under a map that is exactly one LED's cell (radiance 1/Omega_l inside it, 0 elsewhere), E_l = 1
// and every other weight is 0, so relighting returns that LED's own field image.
TEST(EndToEnd, MapOfOneLedsCellReturnsThatLedsImage) {
  testing::TempDir tmp;
  Stage stage = stage_with_directions(fibonacci_dome_directions(40, -10));
  stage.camera.width = stage.camera.height = 48;
  const auto field = testing::CaptureAndBuild(tmp / "s", stage, sim::default_scene());
  const auto dirs = stage.led_directions();
  const int W = 512, H = 256;
  for (int led : {0, 17, 39}) {
    Image map(W, H, 3, 0.0f);
    const EnvironmentMap probe(Image(W, H, 3));
    double cell_sr = 0;
    std::vector<int> in_cell(W * H, 0);
    for (int y = 0; y < H; ++y) {
      for (int x = 0; x < W; ++x) {
        const Eigen::Vector3d d = probe.pixel_direction(x, y);
        int best = 0;
        for (int l = 1; l < int(dirs.size()); ++l) {
          if (d.dot(dirs[l]) > d.dot(dirs[best])) best = l;
        }
        const double coverage = max_nearest_neighbour_angle(dirs);
        if (best == led && std::acos(std::min(1.0, d.dot(dirs[best]))) <= coverage) {
          in_cell[y * W + x] = 1;
          cell_sr += probe.pixel_solid_angle_sr(y);
        }
      }
    }
    for (int i = 0; i < W * H; ++i) {
      for (int ch = 0; ch < 3; ++ch) map.pixels[i * 3 + ch] = in_cell[i] ? float(1 / cell_sr) : 0.f;
    }
    const auto weights = relight::integrate_environment(EnvironmentMap(map), dirs, 0.0, 0.0, {},
                                                        /*supersample=*/1);
    for (int l = 0; l < int(dirs.size()); ++l) {
      for (int ch = 0; ch < 3; ++ch) {
        EXPECT_NEAR(weights.irradiance_rgb[l * 3 + ch], l == led ? 1.0 : 0.0, 1e-5) << l;
      }
    }
    const Image relit = relight::relight(field, weights);
    Image own(48, 48, 3);
    for (int y = 0; y < 48; ++y) {
      for (int x = 0; x < 48; ++x) {
        for (int ch = 0; ch < 3; ++ch) own.at(x, y, ch) = field.at(x, y, led, ch);
      }
    }
    EXPECT_TRUE(testing::ImageNear(relit, own, 1e-5)) << "LED " << led;
  }
}

// The demo scene captured on the built-in dome at size x size pixels, and its field.
struct DemoCapture {
  explicit DemoCapture(int size) : stage(sized(default_stage(), size)) {}
  static Stage sized(Stage stage, int size) {
    stage.camera.width = stage.camera.height = size;
    return stage;
  }
  testing::TempDir tmp;
  Stage stage;
  sim::Scene scene = sim::default_scene();
  capture::ReflectanceField field = testing::CaptureAndBuild(tmp / "s", stage, scene);
};

// The demo scene (matte, rough, glossy spheres, a shadowing height field, a checkered plane)
// relit from its simulated capture on the built-in dome, against ground truth rendered directly
// from the scene under each shipped map (restricted to what the dome covers): by LED cells alone,
// and with the maps' compact sources split off and rendered at their true direction.
TEST(EndToEnd, DemoSceneRelitMatchesGroundTruthUnderEachShippedMap) {
  const DemoCapture demo(96);
  const Stage& stage = demo.stage;
  const sim::Scene& scene = demo.scene;
  const capture::ReflectanceField& field = demo.field;
  const auto dirs = stage.led_directions();
  // Relative RMSE measured at 151 LEDs, 96x96, seed 1, 128-wide quadrature, by cells: sky_sun
  // 0.117, softbox_studio 0.035, small_source 0.185 (a 2-degree source falls into one 14-degree
  // cell: its shadows and highlights come from the LED's direction, not the source's). Asserted
  // with ~1.4x margin.
  // With bright sources, their shadows cast by the scene's shape recovered from the LEDs' shadows
  // where it agrees with them: sky_sun measured 0.0457, asserted at the target 0.05;
  // small_source 0.0643 here (0.056 in the demo's 256^2, under the 0.06), asserted at 0.07:
  // by the flows alone it measured 0.096 (the spheres' shadows on the relief move 20-40 pixels
  // between LEDs and change shape). softbox_studio has no bright source.
  struct Case {
    const char* name;
    double cells_bound, split_bound;
  };
  const Case cases[] = {{"sky_sun.exr", 0.16, 0.05},
                        {"softbox_studio.exr", 0.05, 0.05},
                        {"small_source.exr", 0.26, 0.07}};
  std::vector<relight::SplitLighting> splits;
  std::set<int> source_leds;
  for (const Case& c : cases) {
    const EnvironmentMap map =
        EnvironmentMap::load(testing::source_dir() / "data" / "envmaps" / c.name);
    splits.push_back(relight::split_lighting(map, field.lights(), 0.0, 0.0, true));
    for (const int led : splits.back().leds()) source_leds.insert(led);
  }
  const relight::FieldSources sources(field, capture::whole_field(field),
                                      {source_leds.begin(), source_leds.end()}, true);
  relight::FieldSources on_demand(field);  // Each LED's shadow when needed.
  on_demand.recover_geometry();
  for (size_t m = 0; m < std::size(cases); ++m) {
    const Case& c = cases[m];
    const EnvironmentMap map =
        EnvironmentMap::load(testing::source_dir() / "data" / "envmaps" / c.name);
    const Image cells = relight::relight(field, relight::integrate_environment(map, dirs));
    Image split = relight::relight(field, splits[m].weights);
    sources.add(splits[m], split);
    Image split_on_demand = relight::relight(field, splits[m].weights);
    on_demand.add(splits[m], split_on_demand);
    EXPECT_EQ(split_on_demand.pixels, split.pixels) << c.name;
    sim::GroundTruthOptions gt;
    gt.directions_width = 128;
    gt.covered_by_leds = dirs;
    gt.coverage_radius_rad = max_nearest_neighbour_angle(dirs);
    const Image truth = sim::render_ground_truth(scene, stage.camera, map, gt);
    const auto cells_err = testing::compare_images(cells, truth);
    const auto split_err = testing::compare_images(split, truth);
    std::cout << c.name << ": relative RMSE by cells " << cells_err.relative_rmse
              << ", with bright sources " << split_err.relative_rmse << "\n";
    EXPECT_TRUE(testing::ImageNear(cells, truth, c.cells_bound)) << c.name;
    EXPECT_TRUE(testing::ImageNear(split, truth, c.split_bound)) << c.name;
    // Splitting never makes a map worse than the cells did.
    EXPECT_LE(split_err.relative_rmse, cells_err.relative_rmse + 1e-6) << c.name;
  }
}

// A source at an LED's own direction casts that LED's shadows, softened to the penumbra its size
// casts: how fast the edges move comes from the flows toward the triangle's other LEDs, though
// they weigh nothing there. Measured against the same render with the visibility traced in the
// scene (sim::render_source_visibility), so that only the shadows differ.
TEST(EndToEnd, ASourceAtAnLedsDirectionCastsThePenumbraOfItsSize) {
  const DemoCapture demo(64);
  const auto dirs = demo.stage.led_directions();
  const double radius = 2.0 * M_PI / 180;
  // The LED nearest elevation 50 deg, azimuth 30 deg: it lights the spheres and the relief, and
  // the spheres' shadows fall on the relief.
  const Eigen::Vector3d aim(std::cos(50 * M_PI / 180) * std::cos(M_PI / 6),
                            std::sin(50 * M_PI / 180),
                            std::cos(50 * M_PI / 180) * std::sin(M_PI / 6));
  const int led = DirectionIndex(dirs).nearest(aim);
  ASSERT_GE(led, 0);
  relight::PlacedSource source;
  source.in_stage.dir = dirs[size_t(led)];
  source.in_stage.radius_rad = radius;
  source.in_stage.irradiance_rgb = Eigen::Vector3d::Ones();
  source.triangle =
      relight::led_triangle(dirs, {}, source.in_stage.dir, max_nearest_neighbour_angle(dirs));
  ASSERT_TRUE(source.triangle.has_value());
  relight::SplitLighting lighting;
  lighting.sources.push_back(source);
  const relight::FieldSources sources(demo.field);
  Image interpolated(64, 64, 3), exact(64, 64, 3);
  sources.add(lighting, interpolated);
  const Image visibility =
      sim::render_source_visibility(demo.scene, demo.stage.camera, source.in_stage.dir, radius);
  sources.add(lighting, exact, {&visibility});
  const double error = testing::compare_images(interpolated, exact).relative_rmse;
  std::cout << "source at LED " << led << ": relative RMSE against exact visibility " << error
            << "\n";
  // Measured 0.064 (seed 1); 0.079 when the flows toward LEDs of no weight were not made and the
  // shadow came out hard. Asserted at 0.07: the hard shadow's figure trips it.
  EXPECT_LT(error, 0.07);
}

// The two LEDs nearest a small source dead (zero samples, flagged invalid, as a capture leaves
// them): the source falls between the live LEDs around them, and the shape is recovered from the
// live LEDs alone; the render stays finite and close to the truth.
TEST(EndToEnd, ASmallSourceBetweenDeadLedsIsRenderedFromTheLiveOnes) {
  DemoCapture demo(96);
  capture::ReflectanceField& field = demo.field;
  const EnvironmentMap map =
      EnvironmentMap::load(testing::source_dir() / "data" / "envmaps" / "small_source.exr");
  const auto dirs = demo.stage.led_directions();
  const relight::SplitLighting before =
      relight::split_lighting(map, field.lights(), 0.0, 0.0, true);
  ASSERT_EQ(before.sources.size(), 1u);
  const Eigen::Vector3d toward = before.sources[0].in_stage.dir;
  std::vector<int> order(dirs.size());
  std::iota(order.begin(), order.end(), 0);
  std::partial_sort(order.begin(), order.begin() + 2, order.end(), [&](int a, int b) {
    return dirs[size_t(a)].dot(toward) > dirs[size_t(b)].dot(toward);
  });
  std::vector<Eigen::Vector3d> live;
  for (int l = 0; l < int(dirs.size()); ++l) {
    if (l == order[0] || l == order[1]) {
      field.lights()[size_t(l)].valid = false;
      field.set_light_image(l, std::vector<float>(3 * size_t(96 * 96), 0.0f));
    } else {
      live.push_back(dirs[size_t(l)]);
    }
  }
  const relight::SplitLighting split = relight::split_lighting(map, field.lights(), 0.0, 0.0, true);
  ASSERT_TRUE(split.sources[0].triangle.has_value());
  for (const int led : split.sources[0].triangle->leds) {
    EXPECT_TRUE(field.lights()[size_t(led)].valid) << led;
  }
  relight::FieldSources sources(field);
  sources.recover_geometry();
  Image relit = relight::relight(field, split.weights);
  sources.add(split, relit);
  for (const float v : relit.pixels) ASSERT_TRUE(std::isfinite(v));
  sim::GroundTruthOptions gt;
  gt.directions_width = 128;
  gt.covered_by_leds = live;
  gt.coverage_radius_rad = max_nearest_neighbour_angle(live);
  const Image truth = sim::render_ground_truth(demo.scene, demo.stage.camera, map, gt);
  const double error = testing::compare_images(relit, truth).relative_rmse;
  std::cout << "small_source with its two nearest LEDs dead: relative RMSE " << error << "\n";
  // Measured 0.089 (0.064 with every LED live; by the cells 0.18): asserted under 0.1.
  EXPECT_LT(error, 0.1);
}

// The scene's shape recovered from the field (relight/sources/shadow_geometry.h) against the
// simulator's: heights toward the camera above the backdrop, per object, in pixels; its progress
// counts to one total.
TEST(EndToEnd, TheShapeRecoveredFromTheLedsShadowsMatchesTheScene) {
  const DemoCapture demo(96);
  const relight::NormalMap normals = relight::estimate_normals(demo.field, {});
  const relight::LambertianFit fit{normals.normal, normals.albedo};
  std::vector<Eigen::Vector3d> dirs;
  for (const capture::FieldLight& light : demo.field.lights()) dirs.push_back(light.dir_in_stage);
  long progress_done = 0, progress_total = 0;
  const relight::ShadowGeometry shape(
      fit, dirs,
      [&](int led) {
        std::vector<float> rgb;
        for (size_t p = 0; p < size_t(96 * 96); ++p) {
          const float* v = demo.field.values().data() + 3 * (p * dirs.size() + size_t(led));
          rgb.insert(rgb.end(), v, v + 3);
        }
        return relight::led_lit_mask(dirs[size_t(led)], rgb, fit);
      },
      [&](const std::string&, long done, long total, const std::string&) {
        // One total for the phase, never exceeded.
        EXPECT_LE(done, total);
        EXPECT_TRUE(progress_total == 0 || total == progress_total)
            << total << " after " << progress_total;
        progress_total = total;
        progress_done = done;
      });
  EXPECT_EQ(progress_done, progress_total);
  ASSERT_EQ(shape.scale(), 1);
  const double px_per_m = demo.stage.camera.height / demo.stage.camera.ortho_height_m;
  const double backdrop_z = demo.scene.planes[0].center.z();
  std::map<int, std::vector<double>> errors;  // Object: |recovered - true| over its pixels.
  for (const sim::SurfaceHit& hit : sim::trace_camera(demo.scene, demo.stage.camera)) {
    const float top = shape.heights()[size_t(hit.pixel_y) * 96 + hit.pixel_x];
    if (!hit.hit || top == relight::ShadowGeometry::kNoSurface) continue;
    errors[hit.object].push_back(std::abs(top - (hit.position.z() - backdrop_z) * px_per_m));
  }
  // A ray skips the blocks of the depth map it has risen above (ShadowGeometry::sees): the same
  // answers as stepping through every half pixel (kRayStartPx above its own top, at scale 1).
  const auto marched = [&](int x, int y, const Eigen::Vector3f& dir) {
    const int w = shape.width(), h = shape.height();
    const float dx = dir.x(), dy = -dir.y(), dz = dir.z(), step = 0.5f / std::hypot(dx, dy);
    const std::vector<float>&top = shape.heights(), &thickness = shape.thicknesses();
    const float start = top[size_t(y) * w + x] + 0.1f;
    for (int i = 1; i < 4 * (w + h); ++i) {
      const float t = step * float(i);
      const int qx = int(float(x) + t * dx + 1.5f) - 1, qy = int(float(y) + t * dy + 1.5f) - 1;
      if (qx < 0 || qy < 0 || qx >= w || qy >= h) return true;
      const float ray = start + t * dz;
      const size_t q = size_t(qy) * w + qx;
      if ((qx != x || qy != y) && ray < top[q] && ray > top[q] - thickness[q]) return false;
    }
    return true;
  };
  long shadowed = 0;
  for (const double elevation : {12.0, 30.0, 55.0, 80.0}) {
    for (const double azimuth : {-150.0, -40.0, 35.0, 120.0}) {
      const double el = elevation * std::numbers::pi / 180, az = azimuth * std::numbers::pi / 180;
      const Eigen::Vector3f dir(float(std::cos(el) * std::cos(az)),
                                float(std::cos(el) * std::sin(az)), float(std::sin(el)));
      for (int y = 0; y < 96; ++y) {
        for (int x = 0; x < 96; ++x) {
          if (shape.heights()[size_t(y) * 96 + x] == relight::ShadowGeometry::kNoSurface) continue;
          const bool seen = marched(x, y, dir);
          shadowed += !seen;
          ASSERT_EQ(shape.sees(x, y, dir), seen)
              << x << "," << y << " at " << elevation << ", " << azimuth;
        }
      }
    }
  }
  EXPECT_GT(shadowed, 1000);  // The rays meet the spheres and the relief, not only the sky.

  // Spheres 0-2 (radius 13.6 px, centres 24 px above the backdrop) and the relief (4): the median
  // error over each measured 1.15, 0.45, 0.35 and 0.74 px; asserted under 2 px, a seventh of a
  // sphere's radius (placed by continuity instead of by the shadows they measured 25 px).
  for (const int object : {0, 1, 2, 4}) {
    std::vector<double>& e = errors[object];
    ASSERT_GT(e.size(), 100u) << object;
    std::nth_element(e.begin(), e.begin() + long(e.size() / 2), e.end());
    std::cout << "object " << object << ": median height error " << e[e.size() / 2] << " px\n";
    EXPECT_LT(e[e.size() / 2], 2.0) << object;
  }
}

}  // namespace
}  // namespace ls
