#pragma once
// The three materials the fit tests and the fit failure sweeps tell apart: a matte Lambertian, a
// rough Oren-Nayar (sigma 30 deg) and a glossy Lambert + Torrance-Sparrow. Region r of a scene
// uses material r ("region0".."region2").
#include "physics/brdf.h"
#include "sim/scene.h"

namespace ls::sim {

enum Region { kMatte = 0, kRough = 1, kGlossy = 2 };

physics::brdf::Material region_material(int region);  // kMatte, kRough or kGlossy.
void add_region_materials(Scene& scene);              // Appends region0..region2.
// The fit tests' scene: the three materials on three spheres of radius 0.4 in a row along x
// (centres -0.9, 0, 0.9); sphere r uses material r, so object index = region.
Scene three_region_spheres();

}  // namespace ls::sim
