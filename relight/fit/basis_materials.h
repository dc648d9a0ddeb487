#pragma once
// Basis materials (issue 15; after Lensch et al. 2003, "Image-based reconstruction of spatial
// appearance and geometric detail", and Goldman et al. 2005, "Shape and spatially-varying BRDFs
// from photometric stereo"): a scene has a few materials, not one per pixel.
//
// From the per-pixel fits (relight/fit/fit.h):
//  1. Over-segment: the pixels that their own fit explains are clustered (k-means) on their log
//     albedo, Oren-Nayar sigma and k_s into at most FitOptions::max_materials clusters.
//  2. Fit each cluster's material on its pixels' samples together: every pixel p reflects
//     w_p * material, with its own scalar weight w_p >= 0 (shading, texture in brightness), at its
//     fitted normal. Alternating: the weights in closed form, then the material's albedo and k_s
//     in closed form (non-negative) with its sigma or roughness searched, as the per-pixel
//     candidates do (relight/fit/profiled_fit.h), over the pooled sums. A lobe no single pixel
//     constrains (a pixel that no LED lights near its mirror direction) is constrained by the
//     material's other pixels.
//  3. Merge: while merging two materials lowers the scene's BIC (chi^2 over every pixel, from up
//     to kPoolPixels pixels per material scaled to the material's size, plus the materials'
//     parameters times ln of the scene's residual count), merge the pair that lowers it most.
//  4. Every pixel gets the weights of one material, or two of the same model (Goldman et al.: a
//     pixel is a blend of at most two), at its fitted normal (or its photometric-stereo normal,
//     when its own fit chose another model and that normal explains it better); its per-pixel
//     fit is kept (material 0) where that fit's BIC is lower: no material explains the pixel.
// Samples, weights and conventions as in relight/fit/fit.h.
#include "capture/field.h"
#include "relight/fit/fit.h"
#include "relight/fit/normals.h"

namespace ls::relight {

// Replaces the per-pixel fits in `maps` (fit_models with FitMaterials::kPerPixel, from
// `normals`) by basis materials where they explain the pixel better; fills maps.materials, the
// material channels and the summary's counts.
void fit_basis_materials(const capture::ReflectanceField& field, const NormalMap& normals,
                         const FitOptions& options, ModelMaps& maps);

}  // namespace ls::relight
