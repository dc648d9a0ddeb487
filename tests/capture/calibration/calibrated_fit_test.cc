// Fitting with the calibrated stage beats fitting with the drawing, on the perturbed simulated
// dome (tests/capture/calibration/perturbed_dome.h): per-pixel normals and the relighting of the
// fitted models, each against the simulator's truth, with the stage as drawn, as calibrated from
// the mirror-sphere and white-target photographs, and as truly built.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "lightstage/image_metrics.h"
#include "physics/envmap.h"
#include "relight/fit/fit.h"
#include "relight/fit/model_render.h"
#include "sim/ground_truth.h"
#include "sim/scene.h"
#include "tests/capture/calibration/perturbed_dome.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

constexpr int kFitImageSize = 48;

struct StageFit {
  const char* name;
  const Stage* stage;
  relight::ModelMaps maps;
};

TEST(CalibrationSim, FittingWithTheCalibratedStageBeatsTheDrawing) {
  const testing::DistantDome& dome = testing::distant_dome();
  Stage truth = dome.perturbed.truth;
  truth.camera.width = truth.camera.height = kFitImageSize;
  sim::SimStage sim_stage(truth, sim::default_scene(), /*seed=*/5);
  std::vector<StageFit> fits = {
      {"drawn", &dome.nominal, {}}, {"calibrated", &dome.calibrated, {}}, {"true", &truth, {}}};
  relight::FitOptions options;
  options.roughness_starts = {0.2};
  // The per-candidate LM the measurements below were taken with. The profiled solver (the
  // default) holds lobes to what the dome resolves, which halves the relighting
  // error (true stage: sky_sun 0.104, softbox 0.209) and leaves the three stages within 0.02 of
  // each other there: the relighting arm would no longer see the calibration.
  options.solver = relight::FitSolver::kEveryCandidateByLm;
  // Per-pixel models, as measured: basis materials pool every pixel of a material, so the wrong
  // light directions of the drawn stage no longer show pixel by pixel (softbox: drawn 0.298,
  // calibrated 0.350, true stage 0.339).
  options.materials = relight::FitMaterials::kPerPixel;
  for (StageFit& f : fits) {
    f.maps = relight::fit_models(testing::field_for(sim_stage, truth, *f.stage), options);
  }
  // Pixels every fit fitted (the same pixels for all three).
  Image mask(kFitImageSize, kFitImageSize, 1, 1.0f);
  for (const StageFit& f : fits) {
    for (int y = 0; y < kFitImageSize; ++y) {
      for (int x = 0; x < kFitImageSize; ++x) {
        if (f.maps.at(x, y, relight::kMapFlags) != 0) mask.at(x, y, 0) = 0;
      }
    }
  }
  int pixels = 0;
  for (float m : mask.pixels) pixels += m != 0;
  ASSERT_GT(pixels, kFitImageSize * kFitImageSize / 2);

  std::vector<double> normal_error_deg(fits.size(), 0.0);
  for (size_t i = 0; i < fits.size(); ++i) {
    for (const sim::SurfaceHit& h : sim_stage.hits()) {
      if (!h.hit || mask.at(h.pixel_x, h.pixel_y, 0) == 0) continue;
      const Eigen::Vector3d n(fits[i].maps.at(h.pixel_x, h.pixel_y, relight::kMapNormalX),
                              fits[i].maps.at(h.pixel_x, h.pixel_y, relight::kMapNormalY),
                              fits[i].maps.at(h.pixel_x, h.pixel_y, relight::kMapNormalZ));
      normal_error_deg[i] += capture::angle_between_deg(n, h.normal);
    }
    normal_error_deg[i] /= pixels;
  }
  std::printf("%d pixels: mean normal error %.3f deg drawn, %.3f calibrated, %.3f true stage\n",
              pixels, normal_error_deg[0], normal_error_deg[1], normal_error_deg[2]);
  // Measured: 0.882 deg drawn, 0.059 calibrated, 0.010 true stage: calibration removes 94% of
  // what the drawing's errors (2 deg RMS directions, 10% intensities and colours) cost.
  EXPECT_LT(normal_error_deg[1], normal_error_deg[0]);
  EXPECT_LT(normal_error_deg[1] - normal_error_deg[2],
            0.2 * (normal_error_deg[0] - normal_error_deg[2]));
  EXPECT_LT(normal_error_deg[1], 0.15);

  // Relighting over the spheres: the models cast no shadows, and the spheres' shadows on the
  // backdrop and the relief would swamp what the stages change.
  Image spheres = mask;
  for (const sim::SurfaceHit& h : sim_stage.hits()) {
    if (!h.hit || h.object >= int(sim_stage.scene().spheres.size())) {
      spheres.at(h.pixel_x, h.pixel_y, 0) = 0;
    }
  }
  for (const char* map_name : {"sky_sun.exr", "softbox_studio.exr"}) {
    const physics::EnvironmentMap map =
        physics::EnvironmentMap::load(testing::source_dir() / "data" / "envmaps" / map_name);
    sim::GroundTruthOptions gt;
    gt.directions_width = 128;
    gt.covered_by_leds = truth.led_directions();
    const Image reference = sim::render_ground_truth(sim_stage.scene(), truth.camera, map, gt);
    std::vector<double> error(fits.size());
    for (size_t i = 0; i < fits.size(); ++i) {
      relight::EnvironmentSampling sampling;
      sampling.covered_by_leds = fits[i].stage->led_directions();
      const Image relit = relight::render_models(
          fits[i].maps, relight::LightingForModels::environment(map, 0.0, sampling));
      error[i] = compare_images(relit, reference, &spheres).relative_rmse;
    }
    std::printf(
        "%s: fitted models relit, relative RMSE vs ground truth: drawn %.4f, calibrated "
        "%.4f, true stage %.4f\n",
        map_name, error[0], error[1], error[2]);
    // Measured: sky_sun drawn 0.2314, calibrated 0.1570, true stage 0.1493; softbox_studio
    // 0.4870, 0.3685, 0.3417: calibration removes 91% and 82% of what the drawing adds. The floor
    // (true stage) is the models' missing cast shadows and occlusion between the spheres.
    EXPECT_LT(error[1], error[0]);
    EXPECT_LT(error[1] - error[2], 0.35 * (error[0] - error[2]));
  }
}

}  // namespace
}  // namespace ls
