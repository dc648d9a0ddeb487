// Time-varying materials: closed forms, spatial variation, scene files, and a capture
// over time whose fields follow the process.
#include "sim/time_varying.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "capture/build_field.h"
#include "capture/field_file.h"
#include "lightstage/controller/sequencer.h"
#include "lightstage/errors.h"
#include "sim/ground_truth.h"
#include "sim/scene.h"
#include "sim/sim_stage.h"
#include "tests/support/test_support.h"

namespace ls::sim {
namespace {

const SceneMaterial& material_named(const Scene& scene, const std::string& name) {
  for (const SceneMaterial& m : scene.materials) {
    if (m.name == name) return m;
  }
  throw std::runtime_error("no material " + name);
}

void expect_same_material(const physics::brdf::Material& a, const physics::brdf::Material& b,
                          double tol, const std::string& what) {
  EXPECT_LE((a.albedo - b.albedo).norm(), tol) << what;
  EXPECT_LE((a.ks - b.ks).norm(), tol) << what;
  EXPECT_NEAR(a.roughness, b.roughness, tol) << what;
  EXPECT_NEAR(a.sigma_rad, b.sigma_rad, tol) << what;
  EXPECT_EQ(a.diffuse, b.diffuse) << what;
  EXPECT_EQ(a.specular, b.specular) << what;
}

TEST(TimeVaryingClosedForms, MatchHandComputedValues) {
  // Paint: k_s = (0.5 - 0.04) e^(-120/120) + 0.04 = 0.46 * 0.3678794 + 0.04.
  EXPECT_NEAR(exponential_value(0.5, 0.04, 1.0 / 120, 0.0, 120.0), 0.2092245, 1e-6);
  // Before the onset nothing has happened yet: t' = max(0, t - onset).
  EXPECT_DOUBLE_EQ(exponential_value(0.5, 0.04, 1.0 / 120, 30.0, 10.0), 0.5);
  // Beckmann m = 0.08 * 0.35 / ((0.35 - 0.08) e^-1 + 0.08) = 0.028 / 0.1793274.
  EXPECT_NEAR(beckmann_roughness_value(0.08, 0.35, 1.0 / 120, 0.0, 120.0), 0.1561399, 1e-6);
  EXPECT_NEAR(beckmann_roughness_value(0.08, 0.35, 1.0 / 120, 0.0, 0.0), 0.08, 1e-12);
  EXPECT_NEAR(beckmann_roughness_value(0.08, 0.35, 1.0 / 120, 0.0, 1e9), 0.35, 1e-12);
  // Wet drying: 1 / (1 + e^-1) at one time constant past the midpoint; 1/2 at it.
  EXPECT_NEAR(sigmoid_weight(1.0 / 30, 60.0, 90.0), 0.7310586, 1e-6);
  EXPECT_DOUBLE_EQ(sigmoid_weight(1.0 / 30, 60.0, 60.0), 0.5);
  EXPECT_NEAR(sigmoid_weight(1.0 / 30, 60.0, 30.0), 0.2689414, 1e-6);
  EXPECT_DOUBLE_EQ(sigmoid_weight(1.0, 0.0, -1e6), 0.0);  // No overflow either way.
  EXPECT_DOUBLE_EQ(sigmoid_weight(1.0, 0.0, 1e6), 1.0);
  // The blend's roughness is the paper's Beckmann curve at the same weight.
  physics::brdf::Material wet, dry;
  wet.roughness = 0.08;
  dry.roughness = 0.35;
  const double w = process_weight(ProcessKind::kPaintDrying, 1.0 / 120, 0.0, 120.0);
  EXPECT_NEAR(w, 1.0 - std::exp(-1.0), 1e-12);
  EXPECT_NEAR(blend_endpoints(wet, dry, w).roughness, 0.1561399, 1e-6);
}

TEST(TimeVaryingClosedForms, DustSettlingIsTheTransmittanceModel) {
  const Scene scene = time_varying_scene();
  const SceneMaterial& dusty = material_named(scene, "dusty-gloss");
  ASSERT_TRUE(dusty.process);
  EXPECT_EQ(dusty.process->kind, ProcessKind::kDustSettling);
  // On the stroke at s = 0.5: onset 0 + 0.5 * 60 s, rate 0.005 * (0.5 + 1.5 * 0.5) /s.
  const ProcessTruth truth = truth_at(dusty, 0.5, 0.5);
  ASSERT_TRUE(truth.varying);
  EXPECT_NEAR(truth.onset_s, 30.0, 1e-12);
  EXPECT_NEAR(truth.rate_per_s, 0.00625, 1e-12);
  const double tau = 200.0 - 30.0, transmittance = std::exp(-0.00625 * tau);
  const physics::brdf::Material m = material_at(dusty, 0.5, 0.5, 200.0);
  const Eigen::Vector3d rho_d(0.6, 0.1, 0.08), rho_dust(0.55, 0.5, 0.42), rho_s(0.45, 0.45, 0.45);
  // rho = (1 - T) rho_dust + T rho_d (diffuse) + e^(-lambda tau) rho_s (specular).
  EXPECT_LT((m.albedo - ((1 - transmittance) * rho_dust + transmittance * rho_d)).norm(), 1e-9);
  EXPECT_LT((m.ks - transmittance * rho_s).norm(), 1e-9);
  EXPECT_NEAR(m.roughness, 0.15, 1e-12);
  // Faster toward s = 1 (rate x 2 there), slower at s = 0 (x 0.5).
  EXPECT_NEAR(truth_at(dusty, 1.0, 0.5).rate_per_s, 0.01, 1e-12);
  EXPECT_NEAR(truth_at(dusty, 0.0, 0.5).rate_per_s, 0.0025, 1e-12);
  EXPECT_NEAR(truth_at(dusty, 1.0, 0.5).onset_s, 60.0, 1e-12);
}

TEST(TimeVaryingSpatial, SpreadingPatchOnsetsGrowWithDistanceAndOutsideIsStatic) {
  const Scene scene = time_varying_scene();
  const SceneMaterial& sand = material_named(scene, "wet-sand");
  // onset = 60 s + r / (0.001667 per s): 0 at the centre, r = 0.3 -> 180 s later.
  EXPECT_NEAR(truth_at(sand, 0.5, 0.5).onset_s, 60.0, 1e-9);
  EXPECT_NEAR(truth_at(sand, 0.8, 0.5).onset_s, 60.0 + 0.3 / 0.001667, 1e-6);
  EXPECT_NEAR(truth_at(sand, 0.5, 0.2).onset_s, 60.0 + 0.3 / 0.001667, 1e-6);
  EXPECT_NEAR(truth_at(sand, 0.7, 0.7).onset_s, 60.0 + std::sqrt(0.08) / 0.001667, 1e-6);
  for (const ProcessTruth& t : {truth_at(sand, 0.5, 0.5), truth_at(sand, 0.8, 0.5)}) {
    EXPECT_TRUE(t.varying);
    EXPECT_EQ(t.kind, ProcessKind::kWetDrying);
    EXPECT_NEAR(t.rate_per_s, 0.03333, 1e-12);
  }
  // A process that gives only "wet" dries to the material's own fields.
  EXPECT_TRUE(sand.process->dry.albedo.isApprox(sand.base.albedo, 1e-12));
  EXPECT_FALSE(sand.process->wet.albedo.isApprox(sand.base.albedo, 1e-3));
  // Beyond max_radius 0.45 the plane keeps its (dry) base at all times.
  const ProcessTruth outside = truth_at(sand, 0.5, 0.0);
  EXPECT_FALSE(outside.varying);
  expect_same_material(material_at(sand, 0.5, 0.0, 0.0), sand.base, 1e-12, "outside at 0");
  expect_same_material(material_at(sand, 0.5, 0.0, 500.0), sand.base, 1e-12, "outside at 500");
  // The front reaches r = 0.3 later: at 150 s the centre is half dry... more than the ring.
  const double w_centre = truth_at(sand, 0.5, 0.5).weight(150.0);
  const double w_ring = truth_at(sand, 0.8, 0.5).weight(150.0);
  EXPECT_NEAR(w_centre, 1.0 / (1.0 + std::exp(-0.03333 * 90.0)), 1e-9);
  EXPECT_GT(w_centre, w_ring);
}

TEST(TimeVaryingMaterials, StartWetAndEndDryAndConstantsStayPut) {
  const Scene scene = time_varying_scene();
  for (const char* name : {"drying-paint", "dusty-gloss", "wet-sand"}) {
    const SceneMaterial& m = material_named(scene, name);
    ASSERT_TRUE(m.process) << name;
    // The sigmoid is not exactly 0 at t = 0 (onset is its midpoint): start far before it.
    const double start = m.process->kind == ProcessKind::kWetDrying ? -1e6 : 0.0;
    for (const auto& st : {Eigen::Vector2d(0.5, 0.5), Eigen::Vector2d(0.9, 0.6)}) {
      const ProcessTruth truth = truth_at(m, st.x(), st.y());
      ASSERT_TRUE(truth.varying) << name;
      expect_same_material(material_at(m, st.x(), st.y(), start), m.process->wet, 1e-9,
                           std::string(name) + " wet");
      expect_same_material(material_at(m, st.x(), st.y(), 1e7), m.process->dry, 1e-9,
                           std::string(name) + " dry");
    }
  }
  const SceneMaterial& white = material_named(scene, "matte-white");
  EXPECT_FALSE(white.process);
  EXPECT_FALSE(truth_at(white, 0.5, 0.5).varying);
  expect_same_material(material_at(white, 0.5, 0.5, 300.0), white.base, 0.0, "constant");
  // Paint at t = 0 with onset 0 is exactly wet; its Oren-Nayar sigma moves to 20 degrees.
  const SceneMaterial& paint = material_named(scene, "drying-paint");
  EXPECT_NEAR(material_at(paint, 0.3, 0.3, 1e7).sigma_rad, 20 * physics::brdf::kPi / 180, 1e-9);
}

TEST(TimeVaryingScene, TheDataFileIsTheBuiltInSceneAndHitsReevaluateOverTime) {
  const Scene file = load_scene(testing::source_dir() / "data/scenes/time_varying.json");
  const Scene built_in = time_varying_scene();
  ASSERT_EQ(file.materials.size(), built_in.materials.size());
  for (size_t i = 0; i < file.materials.size(); ++i) {
    EXPECT_EQ(file.materials[i].name, built_in.materials[i].name);
    EXPECT_EQ(bool(file.materials[i].process), bool(built_in.materials[i].process));
  }
  EXPECT_TRUE(has_time_varying_materials(built_in));
  EXPECT_FALSE(has_time_varying_materials(default_scene()));

  CameraSpec camera;
  camera.width = camera.height = 48;
  const auto hits0 = trace_camera(built_in, camera);
  const auto hits_late = at_time(built_in, hits0, 1e6);
  const auto traced_late = trace_camera(built_in, camera, 1e6);
  int changed = 0, static_hits = 0;
  for (size_t p = 0; p < hits0.size(); ++p) {
    if (!hits0[p].hit) continue;
    ASSERT_GE(hits0[p].material_index, 0);
    const SceneMaterial& m = built_in.materials[hits0[p].material_index];
    const physics::brdf::Material expected =
        material_at(m, hits0[p].st.x(), hits0[p].st.y(), /*time_s=*/1e6);
    EXPECT_LT((hits_late[p].material.albedo - expected.albedo).norm(), 1e-12);
    EXPECT_LT((traced_late[p].material.ks - expected.ks).norm(), 1e-12);
    if ((hits_late[p].material.albedo - hits0[p].material.albedo).norm() > 1e-3) {
      ++changed;
    } else {
      ++static_hits;
    }
  }
  // Measured: 752 of the 2304 hits change (paint, dust and the wet patch), 1552 do not.
  EXPECT_GT(changed, 600);
  EXPECT_GT(static_hits, 300);  // The white sphere, the backdrop, the plane outside the patch.
}

std::string scene_error(const std::string& process_json) {
  const std::string text =
      R"({"materials": [{"name": "p", "specular": "torrance-sparrow", "ks": [0.3, 0.3, 0.3],
          "process": )" +
      process_json + "}]}";
  try {
    parse_scene(text, "paint.json");
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error for " << process_json;
  return "";
}

TEST(TimeVaryingScene, ProcessErrorsNameTheFileAndTheField) {
  const std::string kind = scene_error(R"({"kind": "rusting", "rate_per_s": 1})");
  EXPECT_NE(kind.find("paint.json"), std::string::npos) << kind;
  EXPECT_NE(kind.find("materials[0].process.kind"), std::string::npos) << kind;
  const std::string rate = scene_error(R"({"kind": "paint_drying", "rate_per_s": -2})");
  EXPECT_NE(rate.find("process.rate_per_s"), std::string::npos) << rate;
  const std::string missing = scene_error(R"({"kind": "paint_drying"})");
  EXPECT_NE(missing.find("rate_per_s"), std::string::npos) << missing;
  const std::string dusty_gloss =
      scene_error(R"({"kind": "dust_settling", "rate_per_s": 1, "dry": {"ks": [0.1, 0.1, 0.1]}})");
  EXPECT_NE(dusty_gloss.find("process.dry.ks"), std::string::npos) << dusty_gloss;
  const std::string wet_gloss =
      scene_error(R"({"kind": "wet_drying", "rate_per_s": 1, "dry": {"ks": [0.1, 0.1, 0.1]}})");
  EXPECT_NE(wet_gloss.find("process.dry.ks"), std::string::npos) << wet_gloss;
  const std::string wrong_key = scene_error(
      R"({"kind": "paint_drying", "rate_per_s": 1, "spatial": {"kind": "uniform", "speed_per_s": 1}})");
  EXPECT_NE(wrong_key.find("process.spatial.speed_per_s"), std::string::npos) << wrong_key;
  const std::string bad_endpoint =
      scene_error(R"({"kind": "paint_drying", "rate_per_s": 1, "wet": {"roughness": 0}})");
  EXPECT_NE(bad_endpoint.find("process.wet"), std::string::npos) << bad_endpoint;
  const std::string onset =
      scene_error(R"({"kind": "paint_drying", "rate_per_s": 1, "onset_s": -5})");
  EXPECT_NE(onset.find("process.onset_s"), std::string::npos) << onset;
  const std::string no_middle = scene_error(R"({"kind": "corroding", "rate_per_s": 1})");
  EXPECT_NE(no_middle.find("process.middle: missing"), std::string::npos) << no_middle;
  const std::string stray_middle =
      scene_error(R"({"kind": "paint_drying", "rate_per_s": 1, "middle": {}})");
  EXPECT_NE(stray_middle.find("process.middle"), std::string::npos) << stray_middle;
  const std::string slow_wetting =
      scene_error(R"({"kind": "wetting_drying", "rate_per_s": 1, "wetting_rate_per_s": 0.5})");
  EXPECT_NE(slow_wetting.find("process.wetting_rate_per_s"), std::string::npos) << slow_wetting;
  const std::string no_wetting = scene_error(R"({"kind": "wetting_drying", "rate_per_s": 1})");
  EXPECT_NE(no_wetting.find("process.wetting_rate_per_s: missing"), std::string::npos)
      << no_wetting;
}

// The two processes that are not monotone, in the rise-and-fall scene.
TEST(TimeVaryingClosedForms, CorrosionRisesAndFallsAndWettingReturnsDry) {
  const Scene scene = rise_and_fall_scene();
  const Scene file = load_scene(testing::source_dir() / "data/scenes/rise_and_fall.json");
  ASSERT_EQ(file.materials.size(), scene.materials.size());
  const SceneMaterial& metal = material_named(scene, "corroding-metal");
  ASSERT_TRUE(metal.process && metal.process->kind == ProcessKind::kCorroding);
  // At the spot's centre: onset 0, w = 1 - e^(-lambda t), lambda = 0.003333 /s. At w = 1/2 the
  // Bezier gives (wet + 2 middle + dry) / 4: red (0.073 + 0.34 + 0.057) / 4 = 0.1175, above both
  // ends.
  const ProcessTruth centre = truth_at(metal, 0.5, 0.5);
  const double half = std::log(2.0) / 0.003333;
  EXPECT_NEAR(centre.weight(half), 0.5, 1e-9);
  EXPECT_NEAR(centre.material(half).albedo.x(), 0.1175, 1e-9);
  EXPECT_NEAR(centre.material(0).albedo.x(), 0.073, 1e-12);
  EXPECT_NEAR(centre.material(1e7).albedo.x(), 0.057, 1e-9);
  // k_s falls monotonically; the roughness's reciprocal follows the same Bezier.
  EXPECT_NEAR(centre.material(half).ks.x(), (0.2 + 0.12 + 0.01) / 4, 1e-9);
  EXPECT_NEAR(1 / centre.material(half).roughness, (1 / 0.15 + 2 / 0.18 + 1 / 0.27) / 4, 1e-9);
  // Further from the spot the corrosion starts later: r = 0.2 -> 80 s.
  EXPECT_NEAR(truth_at(metal, 0.7, 0.5).onset_s, 80.0, 1e-6);

  const SceneMaterial& slab = material_named(scene, "stone-slab");
  ASSERT_TRUE(slab.process && slab.process->kind == ProcessKind::kWettingDrying);
  // At the stroke's start (s = 0): both rates x 0.7, onset 100 s. Dry before the onset, fully wet
  // at the wetness peak t* = ln(kappa / lambda) / (kappa - lambda), dry again long after.
  const ProcessTruth start = truth_at(slab, 0.0, 0.5);
  const double kappa = 0.025 * 0.7, lambda = 0.004 * 0.7;
  EXPECT_NEAR(start.wetting_rate_per_s, kappa, 1e-12);
  const double peak = 100 + std::log(kappa / lambda) / (kappa - lambda);
  EXPECT_NEAR(start.weight(50), 1.0, 1e-12);
  EXPECT_NEAR(start.weight(peak), 0.0, 1e-9);
  EXPECT_GT(start.weight(peak + 1), 0.0);
  EXPECT_GT(start.weight(1e5), 0.999);
  expect_same_material(start.material(peak), slab.process->wet, 1e-9, "wet at the peak");
  expect_same_material(start.material(50), slab.base, 1e-12, "dry before the onset");
}

// A sphere of paint drying fast (lambda = 0.1 /s), captured at 0, 10 and 30 s.
struct DryingCapture {
  Scene scene;
  Stage stage;
  std::vector<double> times{0.0, 10.0, 30.0};
  DryingCapture() {
    SceneMaterial paint;
    paint.name = "paint";
    MaterialProcess p;
    p.kind = ProcessKind::kPaintDrying;
    p.rate_per_s = 0.1;
    p.wet.specular = physics::brdf::SpecularModel::kTorranceSparrow;
    p.wet.diffuse = physics::brdf::DiffuseModel::kOrenNayar;
    p.wet.albedo = {0.1, 0.15, 0.4};
    p.wet.ks = {0.5, 0.5, 0.5};
    p.wet.roughness = 0.15;
    p.dry = p.wet;
    p.dry.albedo = {0.25, 0.4, 0.7};
    p.dry.ks = {0.05, 0.05, 0.05};
    p.dry.roughness = 0.35;
    p.dry.sigma_rad = 0.3;
    EXPECT_EQ(p.validate(), "");
    paint.base = p.wet;
    paint.process = p;
    scene.materials.push_back(paint);
    scene.spheres.push_back({{0, 0, 0}, 0.6, 0});
    stage = stage_with_directions({Eigen::Vector3d(0.3, 0.4, 1.0).normalized(),
                                   Eigen::Vector3d(-0.6, 0.2, 0.8).normalized(),
                                   Eigen::Vector3d(0.0, 1.0, 0.3).normalized()});
    stage.camera.width = stage.camera.height = 32;
    stage.camera.ortho_height_m = 1.6;
    stage.plan.times_s = times;
    stage.plan.time_steps = 3;
  }
};

TEST(TimeVaryingCapture, FieldsOverThreeStepsFollowThePaintDrying) {
  testing::TempDir tmp;
  DryingCapture setup;
  SimStage sim(setup.stage, setup.scene, /*seed=*/7);
  Session session = Session::create(tmp / "s", setup.stage, {});
  SequencerOptions options;
  options.sleep = [](double) {};
  ASSERT_EQ(run_capture(session, sim.lights(), sim.camera(), options).status,
            CaptureSummary::Status::kComplete);
  EXPECT_DOUBLE_EQ(sim.scene_time_s(), 30.0);  // The cache followed the frames' scene times.

  // The pixel where LED 0's highlight peaks: normal nearest the half vector of light and view.
  const Eigen::Vector3d light = setup.stage.leds[0].dir_in_stage.normalized();
  const Eigen::Vector3d half = (light + Eigen::Vector3d(0, 0, 1)).normalized();
  const std::vector<SurfaceHit> hits = trace_camera(setup.scene, setup.stage.camera);
  size_t peak = 0;
  for (size_t p = 0; p < hits.size(); ++p) {
    if (hits[p].hit && hits[p].normal.dot(half) > hits[peak].normal.dot(half)) peak = p;
  }
  ASSERT_TRUE(hits[peak].hit);
  const SurfaceHit& h = hits[peak];
  const auto g = physics::brdf::Geometry<double>::from_world(h.normal, light, h.wo);
  const MaterialProcess& p = *setup.scene.materials[0].process;

  std::vector<double> measured, expected;
  for (int t = 0; t < 3; ++t) {
    capture::BuildOptions build;
    build.time_step = t;
    const capture::ReflectanceField field = capture::build_field(session, build);
    EXPECT_DOUBLE_EQ(field.scene_time_s, setup.times[t]);
    // The closed forms, written out: every parameter from its own curve.
    const double time = setup.times[t];
    physics::brdf::Material m = p.wet;
    for (int c = 0; c < 3; ++c) {
      m.albedo[c] = exponential_value(p.wet.albedo[c], p.dry.albedo[c], p.rate_per_s, 0, time);
      m.ks[c] = exponential_value(p.wet.ks[c], p.dry.ks[c], p.rate_per_s, 0, time);
    }
    m.sigma_rad = exponential_value(p.wet.sigma_rad, p.dry.sigma_rad, p.rate_per_s, 0, time);
    m.roughness = beckmann_roughness_value(p.wet.roughness, p.dry.roughness, p.rate_per_s, 0, time);
    const double truth =
        physics::brdf::eval(m, g)[1] * g.cos_i;  // Green: R(x, l) = f cos(theta_i).
    const double value = field.at(h.pixel_x, h.pixel_y, /*light=*/0, /*c=*/1);
    // Measured (seed 7): 1.848 / 0.406 / 0.163 against 1.810 / 0.408 / 0.163 (2.1% at most).
    EXPECT_NEAR(value, truth, 0.04 * truth) << "time step " << t;
    measured.push_back(value);
    expected.push_back(truth);
  }
  // The highlight falls as the paint dries, by the predicted factors.
  EXPECT_GT(measured[0], measured[1]);
  EXPECT_GT(measured[1], measured[2]);
  EXPECT_NEAR(measured[2] / measured[0], expected[2] / expected[0],
              0.05 * expected[2] / expected[0]);
}

TEST(TimeVaryingCapture, GroundTruthTakesATime) {
  DryingCapture setup;
  CameraSpec camera = setup.stage.camera;
  camera.width = camera.height = 12;
  // A uniform white environment of radiance 1: a Lambert-like response, specular integrated too.
  Image white(64, 32, 3);
  std::fill(white.pixels.begin(), white.pixels.end(), 1.0f);
  const physics::EnvironmentMap map(white);
  GroundTruthOptions options;
  options.directions_width = 32;
  const Image at_zero = render_ground_truth(setup.scene, camera, map, options, 0.0);
  options.scene_time_s = 0.0;
  const Image also_zero = render_ground_truth(setup.scene, camera, map, options);
  const Image late = render_ground_truth(setup.scene, camera, map, options, 1e6);
  // The same scene frozen at 10 s (the closed-form material as a constant) renders the same.
  Scene frozen = setup.scene;
  frozen.materials[0].base = material_at(setup.scene.materials[0], 0.5, 0.5, 10.0);
  frozen.materials[0].process.reset();
  const Image at_ten = render_ground_truth(setup.scene, camera, map, options, 10.0);
  EXPECT_TRUE(testing::ImageNear(at_ten, render_ground_truth(frozen, camera, map, options), 1e-6));
  const int c = 6;  // Centre pixel: the sphere faces the camera.
  EXPECT_FLOAT_EQ(at_zero.at(c, c, 2), also_zero.at(c, c, 2));
  // Wet, glossy and dark, it reflects more of the white surround than when dry and matte
  // (1.168 against 0.678 in blue).
  EXPECT_GT(at_zero.at(c, c, 2), late.at(c, c, 2) * 1.3);
}

TEST(TimeVaryingCli, OverrunWarnsAndAllTimeStepsBuildsOneFieldPerStep) {
  testing::TempDir tmp;
  // Step 0 cannot be captured within a microsecond: it overruns, whatever the machine.
  const std::filesystem::path stage = tmp / "stage.json";
  std::ofstream(stage) << R"({"layout": {"type": "fibonacci", "count": 4, "min_elevation_deg": 0},
    "camera": {"width": 16, "height": 16},
    "plan": {"dark_frames": 1, "times_s": [0, 0.000001, 40]}})";
  const std::string cli = testing::cli_path().string();
  std::string out;
  ASSERT_EQ(
      testing::run_command(cli + " capture --quiet --stage " + stage.string() + " --scene " +
                               (testing::source_dir() / "data/scenes/time_varying.json").string() +
                               " --out " + (tmp / "s").string(),
                           &out),
      0)
      << out;
  EXPECT_NE(out.find("warning: time step 0 (scene time 0 s) took"), std::string::npos) << out;
  EXPECT_EQ(out.find("warning: time step 1"), std::string::npos) << out;  // 40 s is plenty.
  ASSERT_EQ(testing::run_command(cli + " build --quiet " + (tmp / "s").string() +
                                     " --all-time-steps --out " + (tmp / "fields").string(),
                                 &out),
            0)
      << out;
  const double times[] = {0.0, 0.000001, 40.0};
  for (int t = 0; t < 3; ++t) {
    char name[32];
    std::snprintf(name, sizeof name, "field_t%03d.exr", t);
    const capture::ReflectanceField field = capture::read_field(tmp / "fields" / name);
    EXPECT_DOUBLE_EQ(field.scene_time_s, times[t]) << name;
  }
}

}  // namespace
}  // namespace ls::sim
