#pragma once
// The three materials the fit tests and the fit failure sweeps tell apart: a matte Lambertian, a
// rough Oren-Nayar (sigma 30 deg) and a glossy Lambert + Torrance-Sparrow. Region r of a scene
// uses material r ("region0".."region2").
#include "relight/lighting/brdf.h"
#include "sim/scene.h"

namespace ls::sim {

enum Region { kMatte = 0, kRough = 1, kGlossy = 2 };

brdf::Material region_material(int region);  // kMatte, kRough or kGlossy.
void add_region_materials(Scene& scene);     // Appends region0..region2.

}  // namespace ls::sim
