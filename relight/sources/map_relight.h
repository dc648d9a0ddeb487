#pragma once
// Relighting under an environment map: the one entry point for a field in memory, a field
// streamed from its file whatever its size, and a PCA. The map, turned about +Y, is split into its
// bright sources (a sun, a lamp: bright_sources.h) and the rest; the rest is relit by the LEDs'
// cells (relight/lighting/relight.h), each source at its true direction with moving shadows
// (field_sources.h), cast by the scene's shape recovered from the field where it agrees with the
// LEDs (shadow_geometry.h). The relight and render jobs, the benches and the viewer call it.
// Fitted models are not relit here: they are lit by distant lights sampled over the map
// (LightingForModels), which already put a sun at its direction, with no LED cells to split it
// from.
#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "capture/field.h"
#include "capture/field_file.h"
#include "lightstage/image.h"
#include "lightstage/progress.h"
#include "physics/envmap.h"
#include "relight/compact/pca_field.h"
#include "relight/sources/bright_sources.h"
#include "relight/sources/field_sources.h"

namespace ls::relight {

struct MapRelightOptions {
  // Dome coverage around each LED, radians; <= 0: the largest angle between neighbouring LEDs.
  double coverage_rad = 0.0;
  // Split the map's bright sources off and render them at their true direction; false: the whole
  // map by the LEDs' cells.
  bool bright_sources = true;
  // Cast their shadows by the scene's shape recovered from every LED's shadows, where it agrees
  // with the LEDs around the source; false: by the flows between the LEDs' shadows alone (no
  // seconds spent on the shape before the first image).
  bool source_geometry = true;
  // Bytes the sources may hold (FieldSources::bytes_needed); 0: no bound. Over it the shape is
  // left out, then the sources are relit by the cells with the rest, and MapRelit::note says so.
  std::size_t memory_bytes = 0;
  // A streamed field of more pixels than this has its sources (normals, shape, the LEDs' shadows
  // and flows) made on the field reduced to at most this many (each pixel the mean of a block),
  // and brought back to its size with the detail of the LEDs around each source
  // (guided_upsample.h): the shape's depth is at most 512 pixels a side anyway; 0: at the field's
  // size; else at least kFewestSourcePixels.
  std::size_t source_pixels = std::size_t(1) << 18;
  static constexpr std::size_t kFewestSourcePixels = 4096;
  BrightSourceOptions split;     // What counts as a bright source.
  std::string validate() const;  // Empty when valid, else the option and its range.
};

// The map's light as a dome of `lights` takes it, turned by rotation_deg about +Y: the cells'
// weights of the map without its bright sources (the whole map when !options.bright_sources),
// and the sources placed between the LEDs.
SplitLighting map_lighting(const physics::EnvironmentMap& map,
                           const std::vector<capture::FieldLight>& lights, double rotation_deg,
                           const MapRelightOptions& options);

// A map and a rotation about +Y, in degrees. The map must outlive the call it is given to.
struct MapRotation {
  const physics::EnvironmentMap* map = nullptr;
  double rotation_deg = 0.0;
};

// A field relit under one map and rotation.
struct MapRelit {
  Image image;             // The field's size, 3 channels, field units x irradiance.
  SplitLighting lighting;  // The cells' weights, what they leave uncovered, the sources split off.
  double weights_ms = 0;   // Splitting the map and integrating it over the cells.
  double relight_ms = 0;   // The cells.
  // The sources: their normals, LED shadows and shape when first needed, and their render. A
  // streamed field's are made once for every map (the same figure in each).
  double sources_ms = 0;
  bool geometry = false;  // Their shadows were cast by the recovered shape where it agrees.
  std::string note;  // Why the sources were not rendered as asked (memory); empty if they were.
};

// Several maps' images, in the order of the maps given.
struct MapRelitSet {
  std::vector<MapRelit> relit;
  double rows_pass_s = 0;  // A streamed field: the pass over its rows (and RowPass::gather).
  bool complete = true;    // False where RowPass::gather stopped this process: no sources added.
};

// How a streamed field's rows are relit: the row ranges [y0, y1) this process relights (empty:
// every row at once), and, once they are, what gathers the images (under MPI, onto one process).
// gather returns false on a process that stops there.
struct RowPass {
  std::vector<std::pair<int, int>> rows;
  std::function<bool(const std::vector<Image*>& images)> gather;
};

class MapRelighter {
 public:
  // A field in memory; it must outlive this.
  explicit MapRelighter(const capture::ReflectanceField& field, MapRelightOptions options = {});
  // A PCA, which must outlive this: the cells by its per-LED weights, the sources from its own
  // reconstruction (normals, each LED's image).
  explicit MapRelighter(const PcaField& pca, MapRelightOptions options = {});
  // A field read from its file, which must outlive this, a few MiB at a time: relight_all only.
  explicit MapRelighter(capture::FieldStream& stream, MapRelightOptions options = {});
  ~MapRelighter();
  MapRelighter(const MapRelighter&) = delete;
  MapRelighter& operator=(const MapRelighter&) = delete;

  const MapRelightOptions& options() const { return options_; }
  // The map's light as this field takes it (map_lighting).
  SplitLighting lighting(const physics::EnvironmentMap& map, double rotation_deg) const;
  // The field relit under `lighting` into `out` (made the field's size): the cells, then the
  // sources (`visibility` as for add_sources). Not for a streamed field.
  void render(const SplitLighting& lighting, Image& out,
              const std::vector<const Image*>& visibility = {});
  // Adds the sources of `lighting` inside the dome's coverage to `out` (the field's size), for a
  // caller that relit the cells itself (in half floats, on a GPU). visibility[i], where given:
  // the share of source i each pixel sees, instead of the LEDs' (FieldSources::add).
  // `use`: FieldSources::add's (a viewer renders by the flows until the shape is traced). False
  // when a source was rendered by the flows for want of its traced shape.
  bool add_sources(const SplitLighting& lighting, Image& out,
                   const std::vector<const Image*>& visibility = {},
                   FieldSources::ShapeUse use = FieldSources::ShapeUse::kTrace);
  // The scene's shape recovered (FieldSources::recover_geometry) when the options left it out:
  // on another thread beside add_sources (once add_sources has run), which casts the sources'
  // shadows by it once done. Not for a streamed field.
  void recover_geometry(const ProgressFn& progress);
  // The shape's visibility of the sources of `lighting` traced now (FieldSources::trace_shapes),
  // for add_sources to take; safe beside add_sources on another thread.
  void trace_shapes(const SplitLighting& lighting);
  // Whether `lighting` has a source add_sources renders (one inside the dome's coverage).
  static bool renders_sources(const SplitLighting& lighting);
  // The sources' normals and shape (as the options say) and the shadows of the LEDs around the
  // sources of `lightings`, now rather than when first rendered (a bench times them apart).
  void prepare(const std::vector<SplitLighting>& lightings, const ProgressFn& progress = {});

  // Relit under one map: lighting() and render(), timed. Not for a streamed field.
  MapRelit relight(const physics::EnvironmentMap& map, double rotation_deg);
  // Relit under each map and rotation, the sources within options.memory_bytes. A streamed field:
  // one pass over its rows (`pass`) for every map, then one over its bands for the sources (bands
  // within what the sources leave of the memory given).
  MapRelitSet relight_all(const std::vector<MapRotation>& maps, const RowPass& pass = {},
                          const ProgressFn& progress = {});

 private:
  // What every source shares: its lights and size, the options checked.
  MapRelighter(std::vector<capture::FieldLight> lights, int width, int height,
               MapRelightOptions options);
  // The cells then the sources into r.image under r.lighting, each timed.
  void render_timed(MapRelit& r);
  // Under options.memory_bytes: the shape left out, or the sources relit by the cells (`relit`'s
  // lightings redone from `maps`); the note says which (empty: they fit).
  std::string fit_in_memory(const std::vector<MapRotation>& maps, std::vector<MapRelit>& relit);
  void relight_streamed(const std::vector<MapRotation>& maps, const RowPass& pass,
                        const ProgressFn& progress, MapRelitSet& out);
  FieldSources& sources(const ProgressFn& progress = {});
  // How a streamed field is reduced for its sources (options_.source_pixels); 1: not.
  int source_factor() const;
  // The bytes the sources of `leds` LEDs in `triangles` triangles hold for `maps` images (with
  // the scene's shape when `geometry`), at the size source_factor() makes them.
  std::size_t sources_bytes(int leds, int triangles, int maps, bool geometry) const;
  // A streamed field's sources added to each of `relit` (source_factor() > 1): made on the field
  // reduced in bands, in one pass that also relights it by the LEDs around the sources at full
  // size and reduced (the guides).
  void add_reduced_sources(std::vector<MapRelit>& relit, const ProgressFn& progress);
  void render_cells(const SplitLighting& lighting, Image& out) const;

  const capture::ReflectanceField* field_ = nullptr;
  const PcaField* pca_ = nullptr;
  capture::FieldStream* stream_ = nullptr;
  MapRelightOptions options_;
  std::vector<capture::FieldLight> lights_;
  int width_ = 0, height_ = 0;
  bool geometry_ = true;                   // options_.source_geometry, unless memory left it out.
  std::unique_ptr<FieldSources> sources_;  // Made when first needed.
};

}  // namespace ls::relight
