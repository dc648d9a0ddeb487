#include "sim/scene.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "lightstage/errors.h"
#include "tests/support/test_support.h"

namespace ls::sim {
namespace {

std::string minimal_scene(
    const std::string& sphere_fields = R"("center": [0, 0, 0], "radius": 0.5)",
    const std::string& material_fields = R"("albedo": [0.5, 0.5, 0.5])") {
  return R"({"materials": [{"name": "m", )" + material_fields + R"(}],
            "spheres": [{)" +
         sphere_fields + R"(, "material": "m"}]})";
}

// Expects parse_scene to throw an InputError whose message contains every one of `parts`.
void expect_error(const std::string& json, std::initializer_list<std::string> parts) {
  try {
    parse_scene(json, "bad_scene.json");
    ADD_FAILURE() << "no error for:\n" << json;
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("bad_scene.json"), std::string::npos) << what;
    for (const auto& part : parts) EXPECT_NE(what.find(part), std::string::npos) << what;
  }
}

TEST(SceneFile, ParsesAllObjectKinds) {
  const Scene scene = parse_scene(R"({
    "materials": [
      {"name": "shiny", "diffuse": "lambert", "albedo": [0.6, 0.2, 0.1],
       "specular": "phong", "ks": [0.3, 0.3, 0.3], "phong_exponent": 80},
      {"name": "clay", "diffuse": "oren-nayar", "albedo": [0.5, 0.4, 0.3], "sigma_deg": 30,
       "checker": {"albedo": [0.1, 0.1, 0.1], "cells": 4}}
    ],
    "spheres": [{"center": [0.1, 0.2, 0.3], "radius": 0.25, "material": "shiny"}],
    "planes": [{"center": [0, 0, -1], "normal": [0, 0, 2], "half_width": 1, "half_height": 2,
                "material": "clay"}],
    "height_fields": [{"center": [0, 0, -0.5], "half_width": 1, "half_height": 0.5,
                       "resolution": 33, "material": "clay",
                       "procedural": {"bumps": [{"x": 0, "y": 0, "height": 0.2, "width": 0.1}],
                                      "ridges": [{"amplitude": 0.01, "wavelength": 0.5}]}}]
  })",
                                  "all.json");
  ASSERT_EQ(scene.materials.size(), 2u);
  EXPECT_EQ(scene.materials[0].base.specular, physics::brdf::SpecularModel::kPhong);
  EXPECT_DOUBLE_EQ(scene.materials[0].base.phong_exponent, 80);
  EXPECT_EQ(scene.materials[1].base.diffuse, physics::brdf::DiffuseModel::kOrenNayar);
  EXPECT_NEAR(scene.materials[1].base.sigma_rad, 30 * physics::brdf::kPi / 180, 1e-12);
  ASSERT_TRUE(scene.materials[1].checker_albedo.has_value());
  EXPECT_EQ(scene.materials[1].checker_cells, 4);
  ASSERT_EQ(scene.spheres.size(), 1u);
  EXPECT_EQ(scene.spheres[0].material, 0);
  EXPECT_DOUBLE_EQ(scene.spheres[0].radius, 0.25);
  ASSERT_EQ(scene.planes.size(), 1u);
  EXPECT_NEAR(scene.planes[0].normal.norm(), 1.0, 1e-12);  // Normalised on load.
  EXPECT_EQ(scene.planes[0].material, 1);
  ASSERT_EQ(scene.height_fields.size(), 1u);
  const HeightField& hf = scene.height_fields[0];
  ASSERT_EQ(hf.heights.size(), 33u * 33u);
  // The bump's peak at the centre sample (16, 16): 0.2 plus the ridge's sin(0) = 0.
  EXPECT_NEAR(hf.heights[16 * 33 + 16], 0.2, 1e-6);
  // Far corner: only the ridge, amplitude 0.01.
  EXPECT_LE(std::abs(hf.heights[0]), 0.0101);
  EXPECT_EQ(scene.source, "all.json");
}

TEST(SceneFile, DemoFileIsTheDefaultScene) {
  const Scene file = load_scene(ls::testing::source_dir() / "data/scenes/demo.json");
  const Scene builtin = default_scene();
  ASSERT_EQ(file.materials.size(), builtin.materials.size());
  for (size_t i = 0; i < file.materials.size(); ++i) {
    EXPECT_EQ(file.materials[i].name, builtin.materials[i].name);
    EXPECT_EQ(file.materials[i].base.albedo, builtin.materials[i].base.albedo);
    EXPECT_EQ(file.materials[i].checker_albedo, builtin.materials[i].checker_albedo);
  }
  ASSERT_EQ(file.spheres.size(), 3u);
  ASSERT_EQ(file.spheres.size(), builtin.spheres.size());
  for (size_t i = 0; i < file.spheres.size(); ++i) {
    EXPECT_EQ(file.spheres[i].center, builtin.spheres[i].center);
    EXPECT_EQ(file.spheres[i].radius, builtin.spheres[i].radius);
  }
  ASSERT_EQ(file.planes.size(), builtin.planes.size());
  ASSERT_EQ(file.height_fields.size(), 1u);
  EXPECT_EQ(file.height_fields[0].heights, builtin.height_fields[0].heights);
}

TEST(SceneFile, ShippedExampleScenesLoad) {
  for (const auto& entry :
       std::filesystem::directory_iterator(ls::testing::source_dir() / "data/scenes")) {
    if (entry.path().extension() != ".json") continue;
    const Scene scene = load_scene(entry.path());
    EXPECT_FALSE(scene.materials.empty()) << entry.path();
    for (const auto& hf : scene.height_fields) EXPECT_FALSE(hf.description.empty());
  }
}

TEST(SceneFile, DefaultSceneIsPlausibleAndFillsTheView) {
  const Scene scene = default_scene();
  for (const auto& m : scene.materials) {
    EXPECT_EQ(m.base.validate(), "") << m.name;
    EXPECT_LE(m.base.albedo.maxCoeff(), 0.9) << m.name;
    if (m.checker_albedo) {
      EXPECT_LE(m.checker_albedo->maxCoeff(), 0.9) << m.name;
    }
  }
  // The backdrop covers the orthographic view [-1.2, 1.2]^2.
  ASSERT_FALSE(scene.planes.empty());
  EXPECT_GE(scene.planes[0].half_width, 1.2);
  EXPECT_GE(scene.planes[0].half_height, 1.2);
  for (const auto& s : scene.spheres) {
    EXPECT_LE(std::abs(s.center.x()) + s.radius, 1.2);
    EXPECT_LE(std::abs(s.center.y()) + s.radius, 1.2);
  }
}

TEST(SceneFile, LoadsFromDiskAndNamesTheFileInErrors) {
  ls::testing::TempDir dir;
  const auto good = dir / "good.json";
  std::ofstream(good) << minimal_scene();
  EXPECT_EQ(load_scene(good).spheres.size(), 1u);
  EXPECT_EQ(load_scene(good).source, good.string());

  const auto bad = dir / "typo.json";
  std::ofstream(bad) << minimal_scene(R"("center": [0, 0, 0], "radius": 0.5, "radus": 1)");
  try {
    load_scene(bad);
    ADD_FAILURE() << "typo accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(bad.string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("spheres[0].radus"), std::string::npos) << e.what();
  }
  EXPECT_THROW(load_scene(dir / "missing.json"), InputError);
}

TEST(SceneFile, Errors) {
  expect_error(R"({"materials": [)", {"not valid JSON"});
  expect_error(minimal_scene(R"("center": [0, 0, 0], "radius": -1)"),
               {"spheres[0].radius", "positive", "-1"});
  expect_error(minimal_scene(R"("center": [0, 0], "radius": 1)"), {"spheres[0].center", "3"});
  expect_error(minimal_scene(R"("center": [0, 0, 0], "radius": "big")"),
               {"spheres[0].radius", "number"});
  expect_error(minimal_scene(R"("center": [0, 0, 0], "radius": 1, "colour": 1)"),
               {"spheres[0].colour", "unknown field"});
  expect_error(minimal_scene(R"("center": [0, 0, 0])"), {"spheres[0].radius", "missing"});
  expect_error(minimal_scene(R"("center": [0, 0, 0], "radius": 1)", R"("albedo": [1.5, 0.5, 0.5])"),
               {"materials[0]", "albedo"});
  expect_error(minimal_scene(R"("center": [0, 0, 0], "radius": 1)", R"("diffuse": "matte")"),
               {"materials[0].diffuse", "lambert"});
  expect_error(minimal_scene(R"("center": [0, 0, 0], "radius": 1)",
                             R"("specular": "torrance-sparrow", "roughness": 0)"),
               {"materials[0]", "roughness"});
  expect_error(R"({"materials": [{"name": "m"}], "spheres": [{"center": [0, 0, 0], "radius": 1,
                  "material": "steel"}]})",
               {"spheres[0].material", "steel", "\"m\""});
  expect_error(R"({"materials": [{"name": "m"}, {"name": "m"}], "spheres": []})",
               {"materials[1].name", "unique"});
  expect_error(R"({"materials": [{"name": "m"}], "planes": [{"center": [0, 0, 0],
                  "normal": [0, 0, 0], "half_width": 1, "half_height": 1, "material": "m"}]})",
               {"planes[0].normal", "non-zero"});
  expect_error(R"({"materials": [{"name": "m"}], "height_fields": [{"center": [0, 0, 0],
                  "half_width": 1, "half_height": 1, "material": "m",
                  "procedural": {"bumps": [{"x": 0, "y": 0, "height": 1, "width": -2}]}}]})",
               {"height_fields[0].procedural.bumps[0].width", "positive"});
  expect_error(R"({"materials": [{"name": "m"}], "height_fields": [{"center": [0, 0, 0],
                  "half_width": 1, "half_height": 1, "material": "m"}]})",
               {"height_fields[0]", "procedural", "heights_image"});
  expect_error(R"({"materials": [{"name": "m"}], "cubes": []})", {"cubes", "unknown field"});
  expect_error(R"({"materials": [{"name": "m"}]})", {"at least one"});
}

}  // namespace
}  // namespace ls::sim
