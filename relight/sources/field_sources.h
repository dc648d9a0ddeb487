#pragma once
// The pieces of relighting a field under a map with its bright sources split off: the rest of the
// map by LED cells (relight/lighting/relight.h), each source at its true direction with moving
// shadows (source_render.h), from the field's own Lambertian fit and the images of the LEDs
// around the sources. Fields in memory and streamed ones alike (capture::FieldBands). Callers
// relight through map_relight.h, which assembles them.
#include <array>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "capture/field.h"
#include "relight/lighting/light_cells.h"
#include "relight/sources/bright_sources.h"
#include "relight/sources/shadow_geometry.h"
#include "relight/sources/source_render.h"

namespace ls::relight {

struct PlacedSource {
  BrightSource in_stage;                // The map's source, its direction rotated with the map.
  std::optional<LedTriangle> triangle;  // Unset: outside the dome's coverage, not rendered.
};

// A map's light as the field is relit with it: cell weights of what is left once the compact
// sources are split off (all of the map when `split` is false), and the sources.
struct SplitLighting {
  LightWeights weights;
  std::vector<PlacedSource> sources;
  // What was split off and what it left uncovered, one line for the operator.
  std::string report() const;
  // The LEDs whose images the sources need.
  std::vector<int> leds() const;
};

// coverage_rad <= 0: the largest nearest-neighbour angle between the field's LEDs.
SplitLighting split_lighting(const physics::EnvironmentMap& map,
                             const std::vector<capture::FieldLight>& lights, double rotation_deg,
                             double coverage_rad, bool split,
                             const BrightSourceOptions& options = {});

// The field's Lambertian fit and the LedShadow of each LED its sources fall between.
class FieldSources {
 public:
  // A streamed field: the fit and the shadows of `leds`, in one pass over its bands; add() needs no
  // other LED. with_geometry: the scene's shape too (recover_geometry, `progress` per LED), from
  // every LED's image held during the pass.
  FieldSources(const capture::ReflectanceField& header, const capture::FieldBands& bands,
               const std::vector<int>& leds, bool with_geometry = false,
               const ProgressFn& progress = {});
  // A field in memory (it must outlive this): the fit now, each LED's shadow when a source first
  // falls next to it (a sun turning with the map in the viewer).
  explicit FieldSources(const capture::ReflectanceField& field);
  // Any representation of a field (a PCA): the fit from its bands now, and each LED's image
  // (width x height x 3, field units) from led_image when a source first falls next to it.
  using LedImageFn = std::function<std::vector<float>(int led)>;
  FieldSources(const capture::ReflectanceField& header, const capture::FieldBands& bands,
               LedImageFn led_image);
  // The scene's shape from every usable LED's shadows (shadow_geometry.h), for add() to cast the
  // sources' shadows by where it agrees with the LEDs: seconds at 256^2 (more LEDs, larger maps:
  // longer). Needs the LEDs' images (not the streamed constructor's). Progress per LED and
  // region placed. It reads only what construction made: another thread may add() meanwhile (by
  // the flows until it is done; a viewer's frames).
  void recover_geometry(const ProgressFn& progress = {});
  // The geometry `other` recovered, for this view of the same field (no second recovery).
  void use_geometry_of(const FieldSources& other);
  // The shape recover_geometry found (null before): for a mesh of the scene (export gltf).
  const ShadowGeometry* geometry() const { return geometry_.get(); }
  // The shadows of `leds` now rather than when a source first falls next to them.
  void prepare(const std::vector<int>& leds);
  // Memory it takes for a field of width x height with `leds` LED shadows and the flows of
  // `triangles` LED triangles: the fit (6 floats a pixel), each LED (image, gloss and distance: 7)
  // and each triangle's 6 ordered pairs (4 each). 11 GiB at 24 MP with one source. With the
  // geometry of `all_leds` LEDs, their images while it is recovered (3 each) and their masks, and
  // the shape's visibility of the last directions kept (kShapesKept, 1 each).
  static std::size_t bytes_needed(int width, int height, int leds, int triangles, int all_leds = 0);
  // Adds every source of `lighting` that has a triangle to `out` (the field's size, 3 channels).
  // The flows between a triangle's LEDs are computed when first needed and kept: a sun that stays
  // between the same LEDs (a rotation's small steps, a viewer's frames) costs one pass per pixel.
  // visibility[i], where given, is the share of lighting.sources[i] each pixel sees
  // (add_bright_source), instead of the one interpolated from the LEDs' shadows.
  // With the recovered shape, each source's shadows are cast by it where it is trusted
  // (SourceShadowView::trusted_visibility): traced when first needed and kept for the next call
  // at the same direction (ShapeUse::kTrace), or only where traced before (kIfTraced: a viewer's
  // frame renders by the flows alone until trace_shapes, on another thread, has traced it).
  // Returns false when a source was rendered by the flows for want of its traced shape.
  enum class ShapeUse { kTrace, kIfTraced };
  bool add(const SplitLighting& lighting, Image& out,
           const std::vector<const Image*>& visibility = {}, ShapeUse use = ShapeUse::kTrace) const;
  // Traces the shape's visibility of each source of `lighting` add() has not kept yet.
  void trace_shapes(const SplitLighting& lighting) const;

 private:
  // The fit over the bands (and led_dirs_), calling `also` with each band after it.
  void read_fit(const capture::ReflectanceField& header, const capture::FieldBands& bands,
                const capture::BandVisitor& also);
  const LedShadow& shadow(int led) const;
  PairFlows flows_of(const LedTriangle& triangle, const std::array<const LedShadow*, 3>& shadows,
                     std::unique_lock<std::mutex>& lock) const;

  LambertianFit fit_;
  std::vector<Eigen::Vector3d> led_dirs_;
  // The shape from each usable LED's lit mask (mask_of(led)).
  std::shared_ptr<const ShadowGeometry> recovered(const std::function<LitMask(int led)>& mask_of,
                                                  const ProgressFn& progress) const;
  // geometry_ as it is now (recover_geometry may set it on another thread).
  std::shared_ptr<const ShadowGeometry> current_geometry() const;

  LedImageFn led_image_;                            // Set: shadows made on demand.
  std::vector<bool> usable_;                        // Per LED: not flagged dead.
  std::shared_ptr<const ShadowGeometry> geometry_;  // Set under mutex_.
  mutable std::mutex mutex_;  // add() may run on several threads; it fills the caches.
  mutable std::map<int, LedShadow> shadows_;
  mutable std::map<std::pair<int, int>, LedPairFlow> flows_;
  // The shape's trusted visibility per source direction and radius (the last few: a viewer's sun).
  static constexpr std::size_t kShapesKept = 4;
  using ShapeKey = std::array<double, 4>;
  mutable std::map<ShapeKey, std::shared_ptr<const Image>> shapes_;
  // A source's traced shape by `geometry`: kept, traced now (when `trace`), or null.
  std::shared_ptr<const Image> shape_of(const ShadowGeometry& geometry, const PlacedSource& source,
                                        bool trace) const;
};

}  // namespace ls::relight
