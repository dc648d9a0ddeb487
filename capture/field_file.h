#pragma once
// A reflectance field's file: OpenEXR, read and written whole, written band by band
// (FieldWriter), or read band by band (FieldStream) for a field larger than memory. The field
// itself, its lights and its pixel geometry are capture/field.h's.
#include <cstddef>
#include <filesystem>
#include <memory>

#include "capture/exr_band_reader.h"
#include "capture/field.h"
#include "capture/half_storage.h"
#include "lightstage/image.h"
#include "lightstage/memory.h"

namespace ls::capture {

// OpenEXR, float, one channel per LED and colour named "led042.R" etc., pixel-interleaved (which
// is exactly the in-memory layout); LED directions, validity, (where finite) saturation ceilings
// and (near LEDs) positions in the "lightstage:lights" attribute ({id, dir, valid, saturates_at:
// [r, g, b], position: [x, y, z]}; saturates_at and position are optional on read, absent = never
// saturates, distant); the view in "lightstage:view" (optional); `attributes` as given (e.g. the
// options the field was built with).
// tile_size > 0: a tiled EXR of tile_size^2 tiles, each holding every LED of its pixels, so a
// region is read without the rest of its rows; 0: scanlines.
// storage: half values (capture/half_storage.h) or float, recorded in "lightstage:storage".
void write_field(const std::filesystem::path& path, const ReflectanceField& field,
                 const ExrAttributes& attributes = {}, int tile_size = 0,
                 FieldStorage storage = {});
// The storage a choice gives this field: half where asked, or (auto) where check_half passes;
// float otherwise. *check, when given: the check (half or auto; untouched for float).
FieldStorage choose_storage(const ReflectanceField& field, StorageChoice choice,
                            HalfCheck* check = nullptr);
ReflectanceField read_field(const std::filesystem::path& path);

// A field file written band by band, top to bottom (a field built or imported without holding it):
// the header (lights, noise, view, time) from `header` (its values unused), the file as
// write_field's. Written under a temporary name; finish() renames it into place once every row is
// written, and a writer destroyed before that removes it: no partial field is ever left.
class FieldWriter {
 public:
  FieldWriter(const std::filesystem::path& path, const ReflectanceField& header,
              const ExrAttributes& attributes = {}, int tile_size = 0, FieldStorage storage = {});
  ~FieldWriter();
  FieldWriter(const FieldWriter&) = delete;
  FieldWriter& operator=(const FieldWriter&) = delete;
  // Rows [y0, y0 + band.height()): the next rows, whole tile rows where tiled.
  void write_rows(int y0, const ReflectanceField& band);
  void finish();

 private:
  struct File;
  std::unique_ptr<File> file_;
  int width_, height_, next_row_ = 0;
};

// A field on disk read in bands of rows, every LED of a band's pixels at once, so that a field
// larger than memory can be streamed; scanline or tiled files alike. A band is a
// ReflectanceField of the band's rows (its lights, noise and time the file's); it knows nothing
// of its place in the image, so per-pixel light directions (near LEDs) need y offset by the band's
// first row. Errors as read_field's.
class FieldStream {
 public:
  explicit FieldStream(const std::filesystem::path& path);
  ~FieldStream();
  FieldStream(const FieldStream&) = delete;
  FieldStream& operator=(const FieldStream&) = delete;

  int width() const { return header_.width(); }
  int height() const { return header_.height(); }
  // The file's lights, noise, time and view, with no pixels.
  const ReflectanceField& header() const { return header_; }
  // How the file holds its values (read back as floats either way).
  const FieldStorage& storage() const { return storage_; }
  // The rows of a band that fits in `bytes` (reading adds a buffer of about 8 MiB), at least one
  // tile row (tiled files) or one row, whole tiles where the file is tiled.
  int rows_within(std::size_t bytes) const;
  // Bands start on multiples of this (the file's tile height; 1 for scanline files).
  int row_alignment() const;
  // The rows of a band for a memory budget: rows_within(budget.bytes()).
  int band_rows(const MemoryBudget& budget) const;
  // Rows [y0, y1) into band (reallocated only when its size changes).
  void read_rows(int y0, int y1, ReflectanceField& band);
  // Rows [y0, y1) into dst: (y1 - y0) * width() pixels in the field's layout.
  void read_rows_into(int y0, int y1, float* dst);
  // Rows [y0, y1) as the file holds them, in pieces of about 8 MiB (capture/exr_band_reader.h),
  // for a consumer that sums over each pixel's values (relighting): no band is held at all.
  void read_rows_planar(int y0, int y1, const PlanarVisitor& visit);
  // The file in bands of `rows` rows (one band held at a time), each read when visited.
  FieldBands bands(int rows);

 private:
  struct File;
  std::unique_ptr<File> file_;
  ReflectanceField header_;
  FieldStorage storage_;
};

}  // namespace ls::capture
