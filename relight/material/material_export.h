#pragma once
// Captured materials in the formats people render with: a glTF 2.0 asset (the captured surface, a
// plane or the recovered shape, with the metallic-roughness textures, KHR_materials_specular for
// the dielectric strength) and a MaterialX document (Standard Surface with its textures), both from
// a GgxConversion (relight/material/ggx_conversion.h).
//
// Textures are PNG: base colour sRGB-encoded (glTF and MaterialX's srgb_texture say so), the others
// linear. The normal map is tangent space, 0.5 + 0.5 n, +Y up (glTF's and MaterialX's convention):
// on the plane, tangent = stage +X, bitangent = stage +Y, so the fit's stage-frame normals are the
// tangent-space ones; on a recovered shape they are put in its frames. Each texture is 8-bit unless
// its 8-bit codes would change the material by more than a quarter of the conversion's own error at
// more than 1% of the pixels: then 16-bit.
#include <filesystem>
#include <string>
#include <vector>

#include "relight/material/ggx_conversion.h"
#include "relight/material/surface_mesh.h"

namespace ls::relight {

struct WrittenTexture {
  std::string file;  // Name in the output folder.
  int bits = 8;      // 8 or 16.
};

struct MaterialExport {
  std::filesystem::path document;  // The .gltf or .mtlx written.
  std::vector<WrittenTexture> textures;
};

// DIR/NAME.gltf, DIR/NAME.bin and its PNG textures (DIR made if missing), on `mesh`
// (surface_mesh.h: the plane, or the recovered shape, whose tangent frames the normal texture is
// expressed in). glTF's +Y up is the stage's; the camera looked down -Z.
MaterialExport write_gltf(const GgxConversion& material, const std::filesystem::path& dir,
                          const std::string& name, const SurfaceMesh& mesh);

// DIR/NAME.mtlx (MaterialX 1.38, a standard_surface and its surfacematerial) and its PNG textures.
MaterialExport write_materialx(const GgxConversion& material, const std::filesystem::path& dir,
                               const std::string& name);

}  // namespace ls::relight
