#pragma once
// Basis materials (after Lensch et al. 2003, "Image-based reconstruction of spatial
// appearance and geometric detail", and Goldman et al. 2005, "Shape and spatially-varying BRDFs
// from photometric stereo"): a scene has a few materials, not one per pixel.
//
// From the per-pixel fits (relight/fit/fit.h):
//  1. Over-segment: the pixels that their own fit explains (reduced chi^2 within 4x the scene's
//     median) are clustered (k-means, at most 16k of them) on their log albedo, Oren-Nayar sigma
//     and k_s into at most FitOptions::max_materials clusters.
//  2. Fit each cluster's material on up to 96 of its pixels' samples together
//     (relight/fit/material_pool.h): every pixel p reflects w_p * material, with its own scalar
//     weight w_p >= 0 (shading, brightness texture), at its fitted normal. Alternating: the
//     weights in closed form, then the material's albedo and k_s in closed form (non-negative)
//     with its sigma or roughness searched over the pooled sums, as the per-pixel candidates do
//     (relight/fit/profiled_fit.h). A lobe that no single pixel constrains (a pixel that no LED
//     lights near its mirror direction) is constrained by the material's other pixels.
//  3. Merge: while merging two materials of near colour lowers the BIC of their typical pixel
//     (chi^2 per pixel, divided by the scene's dispersion, plus the materials' parameters times
//     ln of a pixel's residual count; material_pool.h says why), merge the pair that lowers it
//     most. The number of materials is the scene's, chosen by that BIC.
//  4. Every pixel gets the weights of one material, or two of the same model (Goldman et al.: a
//     pixel is a blend of at most two), at its fitted normal (or its photometric-stereo normal,
//     when its own fit chose another model and that normal explains it better). Its per-pixel
//     fit is kept (material 0) where the blend leaves 3x its residual variance, or the blend's
//     colour is another and the data tell them apart: no material explains the pixel. A pixel
//     whose own fit is of its material's model and colour keeps its own parameters where they
//     explain it better by BIC (kOwnParameters). The blend's weight is fitted on the samples it
//     leaves lit: a penumbra sample is shadow, which the fit's LED shadows render
//     (relight/fit/fit_shadows.h), not reflectance. A lobe pointing where the samples saw
//     shadows is flagged kLobeShadowed. The LED shadows are measured again for the new models.
//  5. Scene materials: two basis materials of one model and shape whose pixels tile one region
//     (each shares most of its boundary with the other: a checker, a print) are one material with
//     an albedo texture (Material::scene_material); edits by material select all of it.
// Samples, weights and conventions as in relight/fit/fit.h.
#include <functional>
#include <vector>

#include "capture/field.h"
#include "relight/fit/fit.h"
#include "relight/fit/normals.h"

namespace ls::relight {

// Replaces the per-pixel fits in `maps` (fit_models with FitMaterials::kPerPixel, from
// `normals`) by basis materials where they explain the pixel better; fills maps.materials, the
// material channels and the summary's counts.
void fit_basis_materials(const capture::ReflectanceField& field, const NormalMap& normals,
                         const FitOptions& options, ModelMaps& maps);

// A field's rows on demand: a field (or band of one) holding frame row y, which knows its
// first_row(). whole_field_rows gives the field itself for every row.
using FieldRows = std::function<const capture::ReflectanceField&(int y)>;
inline FieldRows whole_field_rows(const capture::ReflectanceField& field) {
  return [&field](int) -> const capture::ReflectanceField& { return field; };
}

// Model maps visited band by band, top to bottom: each band's rows of ModelMaps::maps and the
// frame row of its first row (a fit in bands of a field larger than memory never holds them
// whole). whole_maps visits one band, the maps themselves.
using MapsVisitor = std::function<void(const Image& maps, int first_row)>;
using MapsBands = std::function<void(const MapsVisitor& visit)>;
inline MapsBands whole_maps(const Image& maps) {
  return [&maps](const MapsVisitor& visit) { visit(maps, 0); };
}

// The steps apart, for a fit in bands whose maps are not held whole and whose bands may be
// assigned by several processes (lightstage fit --memory, and under MPI): steps 1-3 from two
// passes of the per-pixel maps and the rows of the pooled pixels (find_basis_materials; `header`
// has the field's lights and view), step 4 per band
// (assign_basis_materials), step 5 from one pass of the assigned maps (group_scene_materials).
struct BasisMaterials {
  std::vector<Material> materials;  // Empty: no pixel fit well enough to form one.
  double dispersion = 0;            // The scene's median reduced chi^2 (the BIC's scale).
};
BasisMaterials find_basis_materials(const capture::ReflectanceField& header, const FieldRows& rows,
                                    const MapsBands& maps, const FitOptions& options);
// Rewrites the band's rows of maps.maps with their blends of `basis`; adds the band's changes to
// maps.summary's counts and to maps.materials' pixels (maps.materials: basis.materials). The
// maps and normals hold the frame's rows from maps_first_row on (0: the whole frame).
void assign_basis_materials(const capture::ReflectanceField& header,
                            const capture::ReflectanceField& band, const NormalMap& normals,
                            const BasisMaterials& basis, const FitOptions& options, ModelMaps& maps,
                            int maps_first_row = 0);
// Sets every material's scene_material from the maps' material channel; returns their number.
int group_scene_materials(const MapsBands& maps, std::vector<Material>& materials);
int group_scene_materials(const Image& maps, std::vector<Material>& materials);

}  // namespace ls::relight
