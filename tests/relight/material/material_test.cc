// Captured materials out of lightstage: the GGX conversion against the physics of its BRDF, the
// glTF and MaterialX files against the Khronos validator and MaterialX's own validation, and a
// material captured on a plane rendered on a sphere and a mesh against the simulator's ground
// truth of the same material on the same shapes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <map>
#include <numbers>

#include "lightstage/image.h"
#include "lightstage/stage.h"
#include "physics/envmap.h"
#include "relight/fit/fit.h"
#include "relight/material/ggx_conversion.h"
#include "relight/material/material_export.h"
#include "relight/material/shape_render.h"
#include "relight/material/surface_mesh.h"
#include "relight/sources/field_sources.h"
#include "sim/ground_truth.h"
#include "sim/noisy_field.h"
#include "sim/scene.h"
#include "tests/support/test_support.h"

namespace ls::relight {
namespace {

namespace fs = std::filesystem;
using physics::brdf::Geometry;

// Integral over the hemisphere of f(wi, wo) cos(theta_i) d wi, per channel, by the midpoint rule
// in (cos theta, phi).
template <class Brdf>
Eigen::Vector3d albedo_integral(const Brdf& brdf, const Eigen::Vector3d& wo) {
  constexpr int kTheta = 2000, kPhi = 400;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int i = 0; i < kTheta; ++i) {
    const double z = (i + 0.5) / kTheta, r = std::sqrt(1 - z * z);
    for (int j = 0; j < kPhi; ++j) {
      const double phi = 2 * std::numbers::pi * (j + 0.5) / kPhi;
      const Eigen::Vector3d wi(r * std::cos(phi), r * std::sin(phi), z);
      sum += brdf(Geometry<double>::from_local(wi, wo)) * z;
    }
  }
  return sum * (2 * std::numbers::pi / (kTheta * kPhi));
}

TEST(GgxBrdf, LambertBaseAloneReflectsItsAlbedo) {
  // Strength 0: (1 - 0) base / pi, whose cos-weighted integral is the base exactly.
  const Eigen::Vector3d base(0.8, 0.5, 0.2);
  const Eigen::Vector3d total =
      albedo_integral([&](const Geometry<double>& g) { return ggx_brdf(g, base, 0.5, 0.0, 0.04); },
                      Eigen::Vector3d(0.3, 0, 0.954).normalized());
  EXPECT_NEAR(total.x(), 0.8, 1e-4);
  EXPECT_NEAR(total.z(), 0.2, 1e-4);
}

TEST(GgxBrdf, MirrorLikeLobeReflectsAtMostWhatArrives) {
  // F = 1 (f0 = 1), no base: the cos-weighted integral is the lobe's directional albedo seen from
  // the normal: at most 1 (energy conservation), near 1 for a smooth lobe (single scattering loses
  // little at a = 0.09) and well below it for a rough one (a = 1 loses ~2/3 to multiple scattering,
  // which the glTF BRDF leaves out).
  for (const auto& [roughness, at_least] : {std::pair{0.3, 0.97}, {0.5, 0.9}, {1.0, 0.25}}) {
    const Eigen::Vector3d total = albedo_integral(
        [&](const Geometry<double>& g) {
          return ggx_brdf(g, Eigen::Vector3d::Zero(), roughness, 1.0, 1.0);
        },
        Eigen::Vector3d::UnitZ());
    EXPECT_LE(total.x(), 1.0 + 1e-3) << roughness;
    EXPECT_GT(total.x(), at_least) << roughness;
  }
}

// One pixel of model maps with the given material (normal +Z).
ModelMaps one_pixel(FitModel model, const Eigen::Vector3d& albedo, double sigma, double ks,
                    double roughness) {
  ModelMaps maps;
  maps.maps = Image(1, 1, kMapChannelCount);
  float* m = maps.maps.pixels.data();
  m[kMapNormalZ] = 1;
  for (int c = 0; c < 3; ++c) m[kMapAlbedoR + c] = float(albedo[c]);
  m[kMapSigma] = float(sigma);
  m[kMapKs] = float(ks);
  m[kMapRoughness] = float(roughness);
  m[kMapModel] = float(int(model));
  maps.summary.pixels = maps.summary.fitted = 1;
  return maps;
}

TEST(GgxConversion, LambertIsExactAndTheDemoMaterialsAreClose) {
  // Lambert is GGX with no lobe: exact.
  const GgxConversion lambert =
      convert_to_ggx(one_pixel(FitModel::kLambert, Eigen::Vector3d(0.8, 0.78, 0.75), 0, 0, 0.2));
  EXPECT_NEAR(lambert.base_color.pixels[0], 0.8, 1e-5);
  EXPECT_EQ(lambert.strength.pixels[0], 0.0f);
  EXPECT_LT(lambert.error.pixels[0], 1e-5);
  // The demo's glossy red (Lambert + Torrance-Sparrow, k_s 0.4, Beckmann m 0.2) and rough clay
  // (Oren-Nayar, sigma 25 deg): Beckmann and GGX lobes, Oren-Nayar and Lambert differ in shape, so
  // no GGX material matches them exactly; and glTF's diffuse is attenuated by (1 - w F), so a red
  // albedo of 0.65 under an F0 of 0.4 needs a base above 1 (clamped). Regression guards on the
  // measured errors (glossy 19.2%, clay 9.0%, 2026-12-06), 1 point above.
  const GgxConversion glossy = convert_to_ggx(
      one_pixel(FitModel::kLambertTorranceSparrow, Eigen::Vector3d(0.65, 0.12, 0.08), 0, 0.4, 0.2));
  std::cout << "glossy red: base " << glossy.base_color.pixels[0] << ", roughness "
            << glossy.roughness.pixels[0] << ", strength " << glossy.strength.pixels[0] << ", f0 "
            << glossy.f0 << ", error " << glossy.error.pixels[0] << "\n";
  EXPECT_NEAR(glossy.f0, 0.4, 1e-6);
  EXPECT_LT(glossy.error.pixels[0], 0.20);
  const GgxConversion clay = convert_to_ggx(one_pixel(
      FitModel::kOrenNayar, Eigen::Vector3d(0.7, 0.45, 0.25), 25 * std::numbers::pi / 180, 0, 0.2));
  std::cout << "rough clay: base " << clay.base_color.pixels[0] << ", error "
            << clay.error.pixels[0] << "\n";
  EXPECT_LT(clay.error.pixels[0], 0.10);
}

// A swatch: a plane filling an orthographic 64 x 64 view of a 150-LED dome, one material over it
// (its texture coordinates span the image, texel centres at the pixels'), fitted per pixel.
constexpr int kSwatch = 128;
Stage swatch_stage(int size = kSwatch) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(150, -11.5));
  stage.camera.width = stage.camera.height = size;
  return stage;
}
sim::Scene one_object(const sim::SceneMaterial& material) {
  sim::Scene scene;
  scene.materials = {material};
  return scene;
}
ModelMaps fit_swatch(const sim::SceneMaterial& material) {
  sim::Scene scene = one_object(material);
  const double half = 0.5 * swatch_stage().camera.ortho_height_m;
  scene.planes.push_back({Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), half, half, 0});
  FitOptions options;
  options.materials = FitMaterials::kPerPixel;
  const capture::ReflectanceField field =
      sim::render_noisy_field(swatch_stage(), scene, options.normals.noise.as_field_noise(), 5);
  return fit_models(field, options);
}
sim::SceneMaterial demo_material(const std::string& name) {
  for (const sim::SceneMaterial& m : sim::default_scene().materials) {
    if (m.name == name) return m;
  }
  ADD_FAILURE() << name;
  return {};
}

// Mean absolute difference over mean truth, all channels, where both images have the shape.
double relative_error(const Image& render, const Image& truth) {
  double diff = 0, sum = 0;
  for (size_t i = 0; i < truth.num_pixels(); ++i) {
    if (render.pixels[i * 4 + 3] < 1 || truth.pixels[i * truth.channels] <= 0) continue;
    for (int c = 0; c < 3; ++c) {
      diff += std::abs(render.pixels[i * 4 + c] - truth.pixels[i * truth.channels + c]);
      sum += truth.pixels[i * truth.channels + c];
    }
  }
  return diff / sum;
}

// A gentle bump (no cast shadows to speak of) over the 2 x 2 square, as the simulator's height
// field and as an OBJ of the same grid (vertex normals from the same central differences).
constexpr int kGrid = 65;
double bump(double x, double y) { return 0.25 * std::exp(-(x * x + y * y) / 0.35); }
sim::HeightField bump_field() {
  sim::HeightField field;
  field.half_width = field.half_height = 1.0;
  field.resolution = kGrid;
  for (int i = 0; i < kGrid; ++i) {
    for (int j = 0; j < kGrid; ++j) {
      field.heights.push_back(float(bump(-1 + 2.0 * j / (kGrid - 1), 1 - 2.0 * i / (kGrid - 1))));
    }
  }
  return field;
}
fs::path write_bump_obj(const fs::path& path) {
  std::ofstream obj(path);
  const double step = 2.0 / (kGrid - 1);
  for (int i = 0; i < kGrid; ++i) {
    for (int j = 0; j < kGrid; ++j) {
      const double x = -1 + j * step, y = 1 - i * step;
      const double dx = (bump(x + step, y) - bump(x - step, y)) / (2 * step);
      const double dy = (bump(x, y + step) - bump(x, y - step)) / (2 * step);
      const Eigen::Vector3d n = Eigen::Vector3d(-dx, -dy, 1).normalized();
      obj << "v " << x << " " << y << " " << bump(x, y) << "\n"
          << "vt " << double(j) / (kGrid - 1) << " " << 1 - double(i) / (kGrid - 1) << "\n"
          << "vn " << n.x() << " " << n.y() << " " << n.z() << "\n";
    }
  }
  const auto at = [](int i, int j) { return std::to_string(i * kGrid + j + 1); };
  const auto corner = [&](int i, int j) { return at(i, j) + "/" + at(i, j) + "/" + at(i, j); };
  for (int i = 0; i + 1 < kGrid; ++i) {
    for (int j = 0; j + 1 < kGrid; ++j) {
      obj << "f " << corner(i, j) << " " << corner(i + 1, j) << " " << corner(i + 1, j + 1) << "\n"
          << "f " << corner(i, j) << " " << corner(i + 1, j + 1) << " " << corner(i, j + 1) << "\n";
    }
  }
  return path;
}

// The demo plane's material (a checker of two Lambertian albedos) and the demo's glossy red, each
// captured on a swatch, rendered on a sphere and on a mesh under a shipped map, against the
// simulator's ground truth of the same material on the same shape. Bounds: regression guards on
// the measured errors (printed), with margin.
TEST(MaterialOnShapes, SwatchOnASphereAndAMeshMatchesTheSimulatedTruth) {
  testing::TempDir tmp;
  const physics::EnvironmentMap map =
      physics::EnvironmentMap::load(testing::source_dir() / "data/envmaps/softbox_studio.exr");
  EnvironmentSampling sampling;
  sampling.directions_width = 128;
  const LightingForModels lighting = LightingForModels::environment(map, 0.0, sampling);
  sim::GroundTruthOptions truth_options;
  truth_options.directions_width = 128;
  const Mesh mesh = read_obj(write_bump_obj(tmp / "bump.obj"));
  CameraSpec camera = swatch_stage().camera;
  camera.width = camera.height = 96;
  ShapeRenderOptions shape;
  shape.width = shape.height = camera.width;
  // Bounds: regression guards 1.3x over the errors measured on 2026-12-06 (checker 3.6% on the
  // sphere, where its 128 texels are magnified and the blend across each cell's edge shows, 1.1%
  // on the mesh; glossy red 0.27%, 0.34%).
  const std::map<std::string, std::pair<double, double>> bounds = {
      {"checker-backdrop", {0.046, 0.014}}, {"glossy-red", {0.0035, 0.0045}}};
  for (const char* name : {"checker-backdrop", "glossy-red"}) {
    const sim::SceneMaterial material = demo_material(name);
    const ModelMaps maps = fit_swatch(material);
    sim::Scene sphere = one_object(material);
    sphere.spheres.push_back({Eigen::Vector3d::Zero(), 1.0, 0});
    shape.shape = Shape::kSphere;
    const double on_sphere =
        relative_error(render_on_shape(maps, lighting, shape),
                       sim::render_ground_truth(sphere, camera, map, truth_options));
    sim::Scene bumpy = one_object(material);
    bumpy.height_fields.push_back(bump_field());
    shape.shape = Shape::kMesh;
    shape.mesh = &mesh;
    const double on_mesh =
        relative_error(render_on_shape(maps, lighting, shape),
                       sim::render_ground_truth(bumpy, camera, map, truth_options));
    std::cout << name << ": relative error on a sphere " << on_sphere << ", on a mesh " << on_mesh
              << "\n";
    EXPECT_LT(on_sphere, bounds.at(name).first) << name;
    EXPECT_LT(on_mesh, bounds.at(name).second) << name;
  }
}

// The demo scene (spheres, a relief, the checker backdrop) at 64 x 64, fitted as lightstage fit
// does (basis materials), converted once for the file tests.
class DemoExport : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    FitOptions options;
    const capture::ReflectanceField field = sim::render_noisy_field(
        swatch_stage(64), sim::default_scene(), options.normals.noise.as_field_noise(), 3);
    maps_ = new ModelMaps(fit_models(field, options));
    field_ = new capture::ReflectanceField(field);
    material_ = new GgxConversion(convert_to_ggx(*maps_));
    std::cout << "demo conversion: median " << material_->median_error << ", p95 "
              << material_->p95_error << ", f0 " << material_->f0 << "\n";
  }
  static void TearDownTestSuite() {
    delete field_;
    delete material_;
    delete maps_;
  }
  static ModelMaps* maps_;
  static GgxConversion* material_;
  static capture::ReflectanceField* field_;
};
capture::ReflectanceField* DemoExport::field_ = nullptr;
ModelMaps* DemoExport::maps_ = nullptr;
GgxConversion* DemoExport::material_ = nullptr;

// A Node.js validator's command line (tests/tools), or empty, with the reason, when Node.js or the
// packages scripts/setup.sh installs are missing.
std::string validator(const std::string& script) {
  const fs::path tools(LIGHTSTAGE_NODE_TOOLS);
  // The marker scripts/setup.sh leaves once both packages installed whole.
  if (std::system("command -v node >/dev/null 2>&1") != 0 || !fs::exists(tools / ".installed-1")) {
    std::cout << "skipped: no Node.js or no validators in " << tools
              << " (scripts/setup.sh installs them)\n";
    return {};
  }
  return "NODE_PATH=" + (tools / "node_modules").string() + " node " +
         (testing::source_dir() / "tests/tools" / script).string() + " ";
}

TEST_F(DemoExport, GltfPassesTheKhronosValidatorWithNoErrorsOrWarnings) {
  testing::TempDir tmp;
  const MaterialExport files =
      write_gltf(*material_, tmp / "gltf", "demo", plane_mesh(64, 64, 1.0));
  ASSERT_EQ(files.textures.size(), 4u);
  // The base colour comes back from its PNG as written: sRGB-encoded, within half a code.
  const Image base = read_image(tmp / "gltf" / files.textures[0].file);
  const double code = files.textures[0].bits == 16 ? 65535.0 : 255.0;
  for (size_t i = 0; i < base.pixels.size(); i += 97) {
    EXPECT_NEAR(base.pixels[i], srgb_encode(material_->base_color.pixels[i]), 0.51 / code) << i;
  }
  const std::string command = validator("validate_gltf.js");
  if (command.empty()) GTEST_SKIP();
  std::string out;
  EXPECT_EQ(testing::run_command(command + (tmp / "gltf" / "demo.gltf").string(), &out), 0) << out;
  EXPECT_NE(out.find("errors=0 warnings=0"), std::string::npos) << out;
  std::cout << out;
}

TEST_F(DemoExport, MaterialXLoadsInMaterialXsOwnValidation) {
  testing::TempDir tmp;
  const MaterialExport files = write_materialx(*material_, tmp / "mtlx", "demo");
  const std::string command = validator("validate_mtlx.js");
  if (command.empty()) GTEST_SKIP();
  std::string out;
  EXPECT_EQ(testing::run_command(command + files.document.string(), &out), 0) << out;
  EXPECT_NE(out.find("VALID"), std::string::npos) << out;
  // And the validation can fail: a Standard Surface input of the wrong type is refused.
  std::string text = testing::file_bytes(files.document);
  text.replace(text.find("name=\"base\" type=\"float\""), 25, "name=\"base\" type=\"color3\"");
  std::ofstream(tmp / "mtlx" / "broken.mtlx") << text;
  EXPECT_NE(testing::run_command(command + (tmp / "mtlx" / "broken.mtlx").string(), &out), 0)
      << out;
}

// A real renderer agrees: Blender 3.4 (Cycles, CPU) imports the glTF of the demo's fitted maps
// and renders it from the camera under a shipped map; lightstage renders the fitted maps
// themselves on the same plane. They differ by the conversion's error (GGX for Beckmann lobes,
// Lambert for Oren-Nayar), Principled's own Fresnel and Cycles' sampling noise.
TEST_F(DemoExport, BlenderRendersTheGltfAsLightstageRendersTheMaps) {
  if (std::system("command -v blender >/dev/null 2>&1") != 0) {
    std::cout << "skipped: no blender (scripts/setup.sh installs Debian's)\n";
    GTEST_SKIP();
  }
  testing::TempDir tmp;
  const MaterialExport files =
      write_gltf(*material_, tmp / "gltf", "demo", plane_mesh(64, 64, 2.0));
  const fs::path env = testing::source_dir() / "data/envmaps/softbox_studio.exr";
  constexpr int kResolution = 64;
  std::string out;
  ASSERT_EQ(testing::run_command(
                "blender -b --factory-startup --python-exit-code 1 --python " +
                    (testing::source_dir() / "tests/tools/blender_render_gltf.py").string() +
                    " -- " + files.document.string() + " " + env.string() + " " +
                    (tmp / "blender.exr").string() + " 128 " + std::to_string(kResolution),
                &out),
            0)
      << out;
  const Image blender = read_image(tmp / "blender.exr");
  ShapeRenderOptions plane;
  plane.shape = Shape::kPlane;
  plane.width = plane.height = kResolution;
  EnvironmentSampling sampling;
  sampling.directions_width = 128;
  const Image own = render_on_shape(
      *maps_, LightingForModels::environment(physics::EnvironmentMap::load(env), 0, sampling),
      plane);
  ASSERT_EQ(blender.width, own.width);
  double diff = 0, sum = 0;
  for (size_t i = 0; i < own.num_pixels(); ++i) {
    if (own.pixels[i * 4 + 3] < 1) continue;
    for (int c = 0; c < 3; ++c) {
      diff += std::abs(blender.pixels[i * blender.channels + c] - own.pixels[i * 4 + c]);
      sum += own.pixels[i * 4 + c];
    }
  }
  std::cout << "Blender against lightstage: relative error " << diff / sum
            << "; the conversion's own: median " << material_->median_error << ", p95 "
            << material_->p95_error << "\n";
  // The whole image differs by less than the conversion's 95th-percentile error per pixel (measured
  // 10.5% against 15.8%, 2026-12-06): what Blender renders is the converted material.
  EXPECT_LT(diff / sum, material_->p95_error);
}

// The commands: export gltf and materialx print the conversion's error and write their files;
// render --shape writes the image; a shape that is neither named nor an OBJ is refused.
TEST_F(DemoExport, CommandsExportAndRenderOnAShape) {
  testing::TempDir tmp;
  write_model_maps(tmp / "maps.exr", *maps_);
  const std::string cli = testing::cli_path().string() + " ";
  std::string out;
  ASSERT_EQ(testing::run_command(cli + "export gltf --quiet " + (tmp / "maps.exr").string() +
                                     " --out " + (tmp / "g").string(),
                                 &out),
            0)
      << out;
  EXPECT_NE(out.find("conversion error"), std::string::npos) << out;
  for (const char* file :
       {"maps.gltf", "maps.bin", "base_color.png", "normal.png", "metallic_roughness.png",
        "specular_strength.png", "conversion_error.png"}) {
    EXPECT_TRUE(fs::exists(tmp / "g" / file)) << file;
  }
  ASSERT_EQ(testing::run_command(cli + "export materialx --quiet " + (tmp / "maps.exr").string() +
                                     " --out " + (tmp / "x").string(),
                                 &out),
            0)
      << out;
  EXPECT_TRUE(fs::exists(tmp / "x" / "maps.mtlx"));
  const std::string env = (testing::source_dir() / "data/envmaps/sky_sun.exr").string();
  ASSERT_EQ(testing::run_command(cli + "render " + (tmp / "maps.exr").string() +
                                     " --shape cylinder --tiles 2 --resolution 48 --env " + env +
                                     " --out " + (tmp / "c.exr").string(),
                                 &out),
            0)
      << out;
  const Image cylinder = read_image(tmp / "c.exr");
  EXPECT_EQ(cylinder.width, 48);
  EXPECT_TRUE(fs::exists(tmp / "c.png"));
  EXPECT_EQ(
      testing::run_command(cli + "render " + (tmp / "maps.exr").string() + " --shape cube --env " +
                               env + " --out " + (tmp / "d.exr").string(),
                           &out),
      2)
      << out;
  EXPECT_NE(out.find("--shape"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(tmp / "d.exr"));
}

// The glTF on the scene's shape recovered from the field: valid, and its matte sphere stands above
// the backdrop by the simulator's 0.94 m (top at z = 0.34, backdrop at z = -0.6).
TEST_F(DemoExport, GltfOnTheRecoveredShapeIsValidAndStandsAsTheSceneDid) {
  FieldSources sources(*field_);
  sources.recover_geometry();
  const SurfaceMesh mesh = shape_mesh(*sources.geometry(), 64, 64, 2.4);
  ASSERT_GT(mesh.indices.size(), 3000u);
  const auto z_near = [&](float x, float y) {
    size_t best = 0;
    for (size_t v = 0; v < mesh.positions.size(); ++v) {
      if ((mesh.positions[v].head<2>() - Eigen::Vector2f(x, y)).norm() <
          (mesh.positions[best].head<2>() - Eigen::Vector2f(x, y)).norm()) {
        best = v;
      }
    }
    return mesh.positions[best].z();
  };
  const float relief = z_near(-0.74f, 0.48f) - z_near(-1.1f, 1.1f);
  std::cout << "matte sphere's top above the backdrop: " << relief << " m (truth 0.94)\n";
  EXPECT_NEAR(relief, 0.94, 0.15);
  testing::TempDir tmp;
  const MaterialExport files = write_gltf(*material_, tmp / "shape", "demo", mesh);
  const std::string command = validator("validate_gltf.js");
  if (command.empty()) GTEST_SKIP();
  std::string out;
  EXPECT_EQ(testing::run_command(command + files.document.string(), &out), 0) << out;
  EXPECT_NE(out.find("errors=0 warnings=0"), std::string::npos) << out;
}

}  // namespace
}  // namespace ls::relight
