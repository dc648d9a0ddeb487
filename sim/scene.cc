#include "sim/scene.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "lightstage/angles.h"
#include "lightstage/errors.h"
#include "lightstage/image.h"
#include "lightstage/json_reader.h"

namespace ls::sim {

namespace {

// The BRDF fields of `r` over `start` (fields not given keep start's values).
physics::brdf::Material parse_brdf(
    const JsonReader& r, const physics::brdf::Material& start = physics::brdf::Material()) {
  physics::brdf::Material m = start;
  if (r.has("diffuse")) {
    m.diffuse = r["diffuse"].one_of({"lambert", "oren-nayar"}) == "lambert"
                    ? physics::brdf::DiffuseModel::kLambert
                    : physics::brdf::DiffuseModel::kOrenNayar;
  }
  if (r.has("albedo")) m.albedo = r["albedo"].vec3();
  if (r.has("sigma_deg")) m.sigma_rad = r["sigma_deg"].number_in(0, 90, "(degrees)") * kDegToRad;
  if (r.has("specular")) {
    const std::string s = r["specular"].one_of({"none", "torrance-sparrow", "phong"});
    m.specular = s == "none"               ? physics::brdf::SpecularModel::kNone
                 : s == "torrance-sparrow" ? physics::brdf::SpecularModel::kTorranceSparrow
                                           : physics::brdf::SpecularModel::kPhong;
  }
  if (r.has("ks")) m.ks = r["ks"].vec3();
  if (r.has("roughness")) m.roughness = r["roughness"].number();
  if (r.has("phong_exponent")) m.phong_exponent = r["phong_exponent"].number();
  return m;
}

std::filesystem::path resolve(const std::string& file, const std::string& source_name) {
  std::filesystem::path p(file);
  if (p.is_relative() && source_name.find('<') == std::string::npos) {
    p = std::filesystem::path(source_name).parent_path() / p;
  }
  return p;
}

MaterialProcess parse_process(const JsonReader& r, const physics::brdf::Material& base,
                              const std::string& source) {
  r.expect_object(
      {"kind", "rate_per_s", "onset_s", "wet", "dry", "middle", "wetting_rate_per_s", "spatial"});
  MaterialProcess p;
  const std::string kind = r["kind"].one_of(
      {"paint_drying", "wet_drying", "dust_settling", "corroding", "wetting_drying"});
  p.kind = kind == "paint_drying"    ? ProcessKind::kPaintDrying
           : kind == "wet_drying"    ? ProcessKind::kWetDrying
           : kind == "dust_settling" ? ProcessKind::kDustSettling
           : kind == "corroding"     ? ProcessKind::kCorroding
                                     : ProcessKind::kWettingDrying;
  p.rate_per_s = r["rate_per_s"].positive("(1/s)");
  if (r.has("middle") && p.kind != ProcessKind::kCorroding)
    r["middle"].fail("no middle for " + kind);
  if (p.kind == ProcessKind::kWettingDrying) {
    p.wetting_rate_per_s = r["wetting_rate_per_s"].positive("(1/s)");  // Required.
  } else if (r.has("wetting_rate_per_s")) {
    r["wetting_rate_per_s"].fail("no wetting_rate_per_s for " + kind);
  }
  if (r.has("onset_s")) p.onset_s = r["onset_s"].number_in(0, 1e9, "(seconds)");
  auto endpoint = [&](const char* key, const physics::brdf::Material& start,
                      bool required = false) {
    if (!required && !r.has(key)) return start;  // r[key] throws "missing" when required.
    const JsonReader e = r[key];
    e.expect_object(
        {"diffuse", "albedo", "sigma_deg", "specular", "ks", "roughness", "phong_exponent"});
    return parse_brdf(e, start);
  };
  // Both endpoints start from the material's own fields, so a process that gives only "wet" dries
  // to the material itself. Dust is the exception: its dry end is the wet surface under dust,
  // without gloss and with the same roughness (validate() requires that).
  p.wet = endpoint("wet", base);
  physics::brdf::Material dry_start = base;
  if (p.kind == ProcessKind::kDustSettling) {
    dry_start = p.wet;
    dry_start.ks.setZero();
  }
  p.dry = endpoint("dry", dry_start);
  if (p.kind == ProcessKind::kCorroding) p.middle = endpoint("middle", p.wet, /*required=*/true);
  if (r.has("spatial")) {
    const JsonReader sp = r["spatial"];
    sp.expect_object({"kind", "center", "speed_per_s", "max_radius", "stroke_duration_s",
                      "rate_scale_at_start", "rate_scale_at_end", "band_center",
                      "band_half_width"});
    SpatialVariation& v = p.spatial;
    const std::string k = sp["kind"].one_of({"uniform", "spreading_patch", "stroke"});
    v.kind = k == "uniform"           ? SpatialVariation::Kind::kUniform
             : k == "spreading_patch" ? SpatialVariation::Kind::kSpreadingPatch
                                      : SpatialVariation::Kind::kStroke;
    auto allow = [&](const char* key, SpatialVariation::Kind only) {
      if (sp.has(key) && v.kind != only) sp[key].fail(std::string("no ") + key + " for " + k);
      return sp.has(key);
    };
    using K = SpatialVariation::Kind;
    if (allow("center", K::kSpreadingPatch)) {
      const JsonReader c = sp["center"];
      if (c.size() != 2) c.fail("[s, t] (two numbers in [0, 1])");
      v.center = {c[0].number_in(0, 1), c[1].number_in(0, 1)};
    }
    if (allow("speed_per_s", K::kSpreadingPatch)) {
      v.speed_per_s = sp["speed_per_s"].positive("((s, t) units per second)");
    }
    if (allow("max_radius", K::kSpreadingPatch)) {
      v.max_radius = sp["max_radius"].number_in(0, 2, "((s, t) units; 0 = the whole object)");
    }
    if (allow("stroke_duration_s", K::kStroke)) {
      v.stroke_duration_s = sp["stroke_duration_s"].number_in(0, 1e9, "(seconds)");
    }
    if (allow("rate_scale_at_start", K::kStroke)) {
      v.rate_scale_at_start = sp["rate_scale_at_start"].positive("(rate multiplier at s = 0)");
    }
    if (allow("rate_scale_at_end", K::kStroke)) {
      v.rate_scale_at_end = sp["rate_scale_at_end"].positive("(rate multiplier at s = 1)");
    }
    if (allow("band_center", K::kStroke)) v.band_center = sp["band_center"].number_in(0, 1);
    if (allow("band_half_width", K::kStroke)) {
      v.band_half_width = sp["band_half_width"].positive("(along t)");
    }
  }
  const std::string problem = p.validate();
  if (!problem.empty()) throw InputError(source + ": " + r.path() + "." + problem);
  return p;
}

SceneMaterial parse_material(const JsonReader& r, const std::string& source) {
  r.expect_object({"name", "diffuse", "albedo", "sigma_deg", "specular", "ks", "roughness",
                   "phong_exponent", "checker", "albedo_texture", "process"});
  SceneMaterial m;
  m.name = r["name"].string();
  if (m.name.empty()) r["name"].fail("a non-empty material name");
  m.base = parse_brdf(r);
  const std::string problem = m.base.validate();
  if (!problem.empty()) throw InputError(source + ": " + r.path() + ": " + problem);
  if (r.has("checker")) {
    const JsonReader c = r["checker"];
    c.expect_object({"albedo", "cells"});
    m.checker_albedo = c["albedo"].vec3();
    physics::brdf::Material alt = m.base;
    alt.albedo = *m.checker_albedo;
    const std::string alt_problem = alt.validate();
    if (!alt_problem.empty()) {
      throw InputError(source + ": " + c.path() + ".albedo: " + alt_problem);
    }
    if (c.has("cells")) m.checker_cells = c["cells"].integer_in(1, 4096);
  }
  if (r.has("albedo_texture")) {
    if (m.checker_albedo) {
      r["albedo_texture"].fail("either a checker or an albedo_texture, not both");
    }
    m.albedo_texture = resolve(r["albedo_texture"].string(), source);
    if (!std::filesystem::exists(m.albedo_texture)) {
      throw InputError(source + ": " + r.path() +
                       ".albedo_texture: file not found: " + m.albedo_texture.string());
    }
  }
  if (r.has("process")) {
    if (m.checker_albedo || !m.albedo_texture.empty()) {
      r["process"].fail("no checker or albedo_texture together with a process");
    }
    m.process = parse_process(r["process"], m.base, source);
  }
  return m;
}

int material_ref(const JsonReader& r, const std::vector<SceneMaterial>& materials) {
  const std::string name = r.string();
  for (size_t i = 0; i < materials.size(); ++i) {
    if (materials[i].name == name) return int(i);
  }
  std::string known;
  for (const auto& m : materials) known += (known.empty() ? "" : ", ") + ("\"" + m.name + "\"");
  r.fail("the name of a material (" + (known.empty() ? std::string("none defined") : known) + ")");
}

// Procedural heights: Gaussian bumps and sinusoidal ridges, in metres over the base rectangle.
void fill_procedural(HeightField& hf, const JsonReader& r) {
  r.expect_object({"bumps", "ridges"});
  struct Bump {
    double x, y, height, width;
  };
  struct Ridge {
    double amplitude, wavelength, direction_rad, phase_rad;
  };
  std::vector<Bump> bumps;
  std::vector<Ridge> ridges;
  std::ostringstream desc;
  if (r.has("bumps")) {
    const JsonReader list = r["bumps"];
    for (size_t i = 0; i < list.size(); ++i) {
      const JsonReader b = list[i];
      b.expect_object({"x", "y", "height", "width"});
      bumps.push_back({b["x"].number(), b["y"].number(), b["height"].number(),
                       b["width"].positive("(metres, Gaussian sigma)")});
    }
    desc << bumps.size() << " Gaussian bumps";
  }
  if (r.has("ridges")) {
    const JsonReader list = r["ridges"];
    for (size_t i = 0; i < list.size(); ++i) {
      const JsonReader g = list[i];
      g.expect_object({"amplitude", "wavelength", "direction_deg", "phase_deg"});
      ridges.push_back({g["amplitude"].number(), g["wavelength"].positive("(metres)"),
                        g.number_or("direction_deg", 0.0) * kDegToRad,
                        g.number_or("phase_deg", 0.0) * kDegToRad});
    }
    desc << (bumps.empty() ? "" : " + ") << ridges.size() << " sinusoidal ridges";
  }
  hf.description = desc.str();
  const int n = hf.resolution;
  hf.heights.assign(size_t(n) * n, 0.0f);
  for (int i = 0; i < n; ++i) {
    // Local coordinates relative to the centre; row 0 at +Y.
    const double y = hf.half_height * (1.0 - 2.0 * i / (n - 1));
    for (int j = 0; j < n; ++j) {
      const double x = hf.half_width * (2.0 * j / (n - 1) - 1.0);
      double h = 0.0;
      for (const Bump& b : bumps) {
        const double r2 = (x - b.x) * (x - b.x) + (y - b.y) * (y - b.y);
        h += b.height * std::exp(-0.5 * r2 / (b.width * b.width));
      }
      for (const Ridge& g : ridges) {
        const double along = x * std::cos(g.direction_rad) + y * std::sin(g.direction_rad);
        h += g.amplitude * std::sin(2.0 * physics::brdf::kPi * along / g.wavelength + g.phase_rad);
      }
      hf.heights[size_t(i) * n + j] = float(h);
    }
  }
}

// Heights from an image's first channel (bilinearly resampled), times height_scale metres.
void fill_from_image(HeightField& hf, const std::filesystem::path& file, double scale) {
  const Image img = read_image(file);
  const int n = hf.resolution;
  hf.heights.assign(size_t(n) * n, 0.0f);
  for (int i = 0; i < n; ++i) {
    const double fy = std::clamp(double(i) / (n - 1) * (img.height - 1), 0.0, img.height - 1.0);
    const int y0 = int(fy), y1 = std::min(y0 + 1, img.height - 1);
    for (int j = 0; j < n; ++j) {
      const double fx = std::clamp(double(j) / (n - 1) * (img.width - 1), 0.0, img.width - 1.0);
      const int x0 = int(fx), x1 = std::min(x0 + 1, img.width - 1);
      const double tx = fx - x0, ty = fy - y0;
      const double v = (1 - ty) * ((1 - tx) * img.at(x0, y0, 0) + tx * img.at(x1, y0, 0)) +
                       ty * ((1 - tx) * img.at(x0, y1, 0) + tx * img.at(x1, y1, 0));
      hf.heights[size_t(i) * n + j] = float(v * scale);
    }
  }
  hf.description = "heights from " + file.string();
}

// The demo scene (data/scenes/demo.json holds the same text): three spheres across the top half of
// the 2.4 m view, a relief across the bottom half whose bumps shadow each other and the backdrop,
// and a checkered backdrop filling the frame (also for a perspective camera at 4 m).
constexpr std::string_view kDefaultSceneJson = R"json({
  "materials": [
    {"name": "matte-white", "diffuse": "lambert", "albedo": [0.8, 0.78, 0.75]},
    {"name": "glossy-red", "diffuse": "lambert", "albedo": [0.65, 0.12, 0.08],
     "specular": "torrance-sparrow", "ks": [0.4, 0.4, 0.4], "roughness": 0.2},
    {"name": "rough-clay", "diffuse": "oren-nayar", "albedo": [0.7, 0.45, 0.25], "sigma_deg": 25},
    {"name": "green-relief", "diffuse": "lambert", "albedo": [0.35, 0.55, 0.3]},
    {"name": "checker-backdrop", "diffuse": "lambert", "albedo": [0.55, 0.55, 0.55],
     "checker": {"albedo": [0.2, 0.22, 0.28], "cells": 10}}
  ],
  "spheres": [
    {"center": [-0.74, 0.48, 0.0], "radius": 0.34, "material": "matte-white"},
    {"center": [0.0, 0.48, 0.0], "radius": 0.34, "material": "glossy-red"},
    {"center": [0.74, 0.48, 0.0], "radius": 0.34, "material": "rough-clay"}
  ],
  "planes": [
    {"center": [0.0, 0.0, -0.6], "normal": [0, 0, 1], "half_width": 2.0, "half_height": 2.0,
     "material": "checker-backdrop"}
  ],
  "height_fields": [
    {"center": [0.0, -0.62, -0.55], "half_width": 1.05, "half_height": 0.45, "resolution": 128,
     "material": "green-relief",
     "procedural": {
       "bumps": [
         {"x": -0.70, "y": 0.05, "height": 0.30, "width": 0.09},
         {"x": -0.30, "y": -0.15, "height": 0.18, "width": 0.12},
         {"x": 0.05, "y": 0.12, "height": 0.25, "width": 0.07},
         {"x": 0.40, "y": -0.10, "height": 0.22, "width": 0.10},
         {"x": 0.78, "y": 0.10, "height": 0.15, "width": 0.14},
         {"x": -0.05, "y": -0.25, "height": 0.10, "width": 0.05}
       ],
       "ridges": [{"amplitude": 0.02, "wavelength": 0.25, "direction_deg": 0}]
     }}
  ]
}
)json";

// The time-varying scene (data/scenes/time_varying.json holds the same text).
constexpr std::string_view kTimeVaryingSceneJson = R"json({
  "materials": [
    {"name": "drying-paint", "diffuse": "oren-nayar", "specular": "torrance-sparrow",
     "process": {"kind": "paint_drying", "rate_per_s": 0.008333, "onset_s": 0,
       "wet": {"albedo": [0.08, 0.16, 0.45], "sigma_deg": 0, "ks": [0.5, 0.5, 0.5],
               "roughness": 0.08},
       "dry": {"albedo": [0.25, 0.42, 0.75], "sigma_deg": 20, "ks": [0.04, 0.04, 0.04],
               "roughness": 0.35},
       "spatial": {"kind": "uniform"}}},
    {"name": "matte-white", "diffuse": "lambert", "albedo": [0.8, 0.78, 0.75]},
    {"name": "dusty-gloss", "diffuse": "lambert", "albedo": [0.6, 0.1, 0.08],
     "specular": "torrance-sparrow", "ks": [0.45, 0.45, 0.45], "roughness": 0.15,
     "process": {"kind": "dust_settling", "rate_per_s": 0.005, "onset_s": 0,
       "dry": {"albedo": [0.55, 0.5, 0.42]},
       "spatial": {"kind": "stroke", "stroke_duration_s": 60, "rate_scale_at_start": 0.5,
                   "rate_scale_at_end": 2.0}}},
    {"name": "wet-sand", "diffuse": "lambert", "albedo": [0.5, 0.42, 0.33],
     "process": {"kind": "wet_drying", "rate_per_s": 0.03333, "onset_s": 60,
       "wet": {"albedo": [0.14, 0.11, 0.08]},
       "spatial": {"kind": "spreading_patch", "center": [0.5, 0.5], "speed_per_s": 0.001667,
                   "max_radius": 0.45}}},
    {"name": "grey-backdrop", "diffuse": "lambert", "albedo": [0.4, 0.4, 0.4]}
  ],
  "spheres": [
    {"center": [-0.74, 0.48, 0.0], "radius": 0.34, "material": "drying-paint"},
    {"center": [0.0, 0.48, 0.0], "radius": 0.3, "material": "matte-white"},
    {"center": [0.74, 0.48, 0.0], "radius": 0.34, "material": "dusty-gloss"}
  ],
  "planes": [
    {"center": [0.0, -0.55, -0.2], "normal": [0, 0, 1], "half_width": 1.0, "half_height": 0.45,
     "material": "wet-sand"},
    {"center": [0.0, 0.0, -0.6], "normal": [0, 0, 1], "half_width": 2.0, "half_height": 2.0,
     "material": "grey-backdrop"}
  ]
}
)json";

// The rise-and-fall scene (data/scenes/rise_and_fall.json holds the same text).
constexpr std::string_view kRiseAndFallSceneJson = R"json({
  "materials": [
    {"name": "corroding-metal", "diffuse": "lambert", "specular": "torrance-sparrow",
     "process": {"kind": "corroding", "rate_per_s": 0.003333, "onset_s": 0,
       "wet": {"albedo": [0.073, 0.055, 0.045], "ks": [0.2, 0.2, 0.2], "roughness": 0.15},
       "middle": {"albedo": [0.17, 0.07, 0.045], "ks": [0.06, 0.06, 0.06], "roughness": 0.18},
       "dry": {"albedo": [0.057, 0.075, 0.065], "ks": [0.01, 0.01, 0.01], "roughness": 0.27},
       "spatial": {"kind": "spreading_patch", "center": [0.5, 0.5], "speed_per_s": 0.0025}}},
    {"name": "stone-slab", "diffuse": "lambert", "albedo": [0.55, 0.47, 0.38],
     "specular": "torrance-sparrow", "ks": [0, 0, 0], "roughness": 0.2,
     "process": {"kind": "wetting_drying", "rate_per_s": 0.004, "wetting_rate_per_s": 0.025,
       "onset_s": 100,
       "wet": {"albedo": [0.2, 0.16, 0.12], "ks": [0.12, 0.12, 0.12]},
       "spatial": {"kind": "stroke", "stroke_duration_s": 300, "rate_scale_at_start": 0.7,
                   "rate_scale_at_end": 1.4}}},
    {"name": "matte-white", "diffuse": "lambert", "albedo": [0.8, 0.78, 0.75]},
    {"name": "grey-backdrop", "diffuse": "lambert", "albedo": [0.4, 0.4, 0.4]}
  ],
  "spheres": [
    {"center": [-0.45, 0.32, 0.0], "radius": 0.42, "material": "corroding-metal"},
    {"center": [0.55, 0.38, 0.0], "radius": 0.3, "material": "matte-white"}
  ],
  "planes": [
    {"center": [0.0, -0.55, -0.2], "normal": [0, 0, 1], "half_width": 1.0, "half_height": 0.4,
     "material": "stone-slab"},
    {"center": [0.0, 0.0, -0.6], "normal": [0, 0, 1], "half_width": 2.0, "half_height": 2.0,
     "material": "grey-backdrop"}
  ]
}
)json";

}  // namespace

int object_index_of_plane(const Scene& scene, int plane) {
  return int(scene.spheres.size()) + plane;
}

int object_index_of_height_field(const Scene& scene, int height_field) {
  return int(scene.spheres.size() + scene.planes.size()) + height_field;
}

Scene parse_scene(std::string_view json_text, const std::string& source_name) {
  const nlohmann::json doc = JsonReader::parse(json_text, source_name);
  const JsonReader r(doc, source_name);
  r.expect_object({"materials", "spheres", "planes", "height_fields"});
  Scene scene;
  scene.source = source_name;
  const JsonReader materials = r["materials"];
  if (materials.size() == 0) materials.fail("at least one material");
  for (size_t i = 0; i < materials.size(); ++i) {
    SceneMaterial m = parse_material(materials[i], source_name);
    for (const auto& other : scene.materials) {
      if (other.name == m.name) materials[i]["name"].fail("a unique material name");
    }
    scene.materials.push_back(std::move(m));
  }
  if (r.has("spheres")) {
    const JsonReader list = r["spheres"];
    for (size_t i = 0; i < list.size(); ++i) {
      const JsonReader s = list[i];
      s.expect_object({"center", "radius", "material"});
      Sphere sphere;
      sphere.center = s["center"].vec3();
      sphere.radius = s["radius"].positive("(metres)");
      sphere.material = material_ref(s["material"], scene.materials);
      scene.spheres.push_back(sphere);
    }
  }
  if (r.has("planes")) {
    const JsonReader list = r["planes"];
    for (size_t i = 0; i < list.size(); ++i) {
      const JsonReader p = list[i];
      p.expect_object({"center", "normal", "half_width", "half_height", "material"});
      Plane plane;
      plane.center = p["center"].vec3();
      plane.normal = p["normal"].unit_vec3();
      plane.half_width = p["half_width"].positive("(metres)");
      plane.half_height = p["half_height"].positive("(metres)");
      plane.material = material_ref(p["material"], scene.materials);
      scene.planes.push_back(plane);
    }
  }
  if (r.has("height_fields")) {
    const JsonReader list = r["height_fields"];
    for (size_t i = 0; i < list.size(); ++i) {
      const JsonReader h = list[i];
      h.expect_object({"center", "half_width", "half_height", "resolution", "material",
                       "procedural", "heights_image", "height_scale"});
      HeightField hf;
      hf.center = h["center"].vec3();
      hf.half_width = h["half_width"].positive("(metres)");
      hf.half_height = h["half_height"].positive("(metres)");
      if (h.has("resolution")) hf.resolution = h["resolution"].integer_in(2, 4096);
      hf.material = material_ref(h["material"], scene.materials);
      if (h.has("procedural") == h.has("heights_image")) {
        throw InputError(source_name + ": " + h.path() +
                         ": expected exactly one of \"procedural\" or \"heights_image\"");
      }
      if (h.has("procedural")) {
        if (h.has("height_scale")) h["height_scale"].fail("no height_scale with procedural");
        fill_procedural(hf, h["procedural"]);
      } else {
        const auto file = resolve(h["heights_image"].string(), source_name);
        if (!std::filesystem::exists(file)) {
          throw InputError(source_name + ": " + h.path() +
                           ".heights_image: file not found: " + file.string());
        }
        fill_from_image(hf, file, h.has("height_scale") ? h["height_scale"].number() : 1.0);
      }
      scene.height_fields.push_back(std::move(hf));
    }
  }
  if (scene.spheres.empty() && scene.planes.empty() && scene.height_fields.empty()) {
    throw InputError(source_name +
                     ": (top level): expected at least one sphere, plane or height "
                     "field, got none");
  }
  return scene;
}

Scene load_scene(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string() + ": cannot open scene file");
  std::ostringstream text;
  text << in.rdbuf();
  return parse_scene(text.str(), path.string());
}

Scene default_scene() {
  // Parsed from text so that data/scenes/demo.json (the same text) is provably this scene.
  Scene scene = parse_scene(kDefaultSceneJson, "<built-in>");
  return scene;
}

}  // namespace ls::sim

namespace ls::sim {

Scene time_varying_scene() { return parse_scene(kTimeVaryingSceneJson, "<built-in>"); }

Scene rise_and_fall_scene() { return parse_scene(kRiseAndFallSceneJson, "<built-in>"); }

bool has_time_varying_materials(const Scene& scene) {
  for (const SceneMaterial& m : scene.materials) {
    if (m.process) return true;
  }
  return false;
}

}  // namespace ls::sim
