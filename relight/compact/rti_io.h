#pragma once
// The RTI interchange formats, in the layouts RTIViewer and relight/OpenLIME read:
//
//  .ptm (PTM_1.2, HP Labs; uncompressed PTM_FORMAT_RGB and PTM_FORMAT_LRGB):
//    "PTM_1.2\n" "PTM_FORMAT_RGB\n" (or _LRGB) "<width>\n" "<height>\n"
//    "<6 scales>\n" "<6 integer biases>\n", then bytes, rows bottom to top:
//    RGB: three blocks (R, G, B), each rows x pixels x 6 coefficients;
//    LRGB: rows x pixels x 6 luminance coefficients, then rows x pixels x 3 colour bytes.
//    Coefficient a_j = (byte - bias_j) * scale_j, in 8-bit code units (255 = white), order
//    u^2, v^2, uv, u, v, 1. LRGB pixel value = colour_byte / 255 * L(u, v).
//  .rti (HSH, RTIViewer's "#HSH1.2"): text header "#HSH1.2\n", comment lines starting with '#',
//    "3\n" (HSH), "<width> <height> 3\n", "<terms> 2 1\n", then terms float32 scales and terms
//    float32 biases (little-endian), then bytes, rows TOP to bottom (RTIViewer's Hsh::loadData and
//    relight read row j at offset j * width; older lightstage files, written bottom to top, read
//    upside down), per pixel the R terms, G terms, B terms: coefficient = byte / 255 * scale_j +
//    bias_j; the evaluated value is 1 at white.
//
// Values in the files are display units (white = 255 codes for PTM, 1 for HSH); fields are in
// field units. By default the values are display-referred: the sRGB codes of gain x field units,
// fitted as such (RtiFitOptions::srgb_gain), which is how RTIViewer, relight and OpenLIME show
// them (no transfer curve applied). A linear .rti (gain x field units) is for lightstage's own use.
// The gain defaults to the brightest fitted sample becoming white. The .rti writer records it and
// the encoding in comment lines "#lightstage field_gain <g>", "#lightstage encoding sRGB|linear",
// so reading it back relights in field units; .ptm has no room for them, so a .ptm reads back as
// sRGB with gain 1 ("white is 1").
//
// Quantisation is per coefficient over the whole image (as the reference builders do): PTM range
// [min(min_j, 0), max(max_j, 0)] onto integer bias and 0..255; HSH [min_j, max_j] onto 0..255.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "lightstage/rank_split.h"
#include "relight/compact/rti_fits.h"

namespace ls::relight {

enum class RtiFileFormat { kPtmRgb, kPtmLrgb, kHsh };

// A quantised file as it is stored (rows top to bottom here; the .ptm encoder flips them).
struct RtiFile {
  RtiFileFormat format = RtiFileFormat::kHsh;
  int width = 0, height = 0;
  int terms = 0;                   // 6 for PTM; 4, 9 or 16 for HSH.
  std::vector<float> scale, bias;  // Per term (PTM biases are integers).
  // Per pixel (row-major, row 0 at the top): PTM RGB and HSH: 3 x terms, [c * terms + j];
  // PTM LRGB: 6 luminance bytes then 3 colour bytes.
  std::vector<uint8_t> data;
  double field_gain = 0.0;  // Display units per field unit, when the file records it (.rti).
  // The coefficients are of sRGB codes (white = 1) of field_gain x field units, as every RTI viewer
  // shows them: always for .ptm (the format has no room to say otherwise); for .rti unless the file
  // says "#lightstage encoding linear" (or is an older lightstage file: a gain and no encoding).
  bool srgb = true;

  int bytes_per_pixel() const { return format == RtiFileFormat::kPtmLrgb ? 9 : 3 * terms; }
};

// Field -> file. gain: display units (white = 1) per field unit; <= 0: 1 / max_sample_value. A
// display-referred field (fitted with srgb_gain) is stored as it is, with its own gain.
RtiFile quantise(const RtiField& field, double gain = 0.0);

// quantise in two steps, so that a field fitted band by band (larger than memory) is
// quantised byte for byte as the whole: add() every band's coefficients (the ranges), then
// header() (scales, biases, gain; no data) and quantise() each band's pixels.
class RtiQuantiser {
 public:
  RtiQuantiser(RtiBasis basis, bool lrgb, int width, int height);
  // `pixels` pixels' coefficients (and LRGB colours) as RtiField holds them; their largest sample.
  void add(const float* coefs, const float* colors, size_t pixels, float max_sample);
  // srgb: the coefficients added are display-referred already (RtiFitOptions::srgb_gain = gain),
  // quantised as they are; the gain is recorded.
  RtiFile header(double gain = 0.0, bool srgb = false) const;
  // Into `bytes` as RtiFile::data lays them out.
  void quantise(const RtiFile& header, const float* coefs, const float* colors, size_t pixels,
                uint8_t* bytes) const;

 private:
  static double lrgb_magnitude(const float* color);
  double code(double v, double gain) const;
  RtiBasis basis_;
  bool lrgb_;
  int width_, height_, terms_;
  std::vector<double> lo_, hi_;  // Per term, of the coefficients (LRGB: times the magnitude).
  float max_sample_ = 0;
};
// File -> field, in field units when the file records its gain, else in display units (white 1);
// an sRGB file's field is display-referred (RtiField::display_gain) and relights in those units.
RtiField dequantise(const RtiFile& file);

// Exact byte (de)serialisation. decode throws InputError "<name>: <field>: expected X, got Y".
std::string encode_rti_file(const RtiFile& file);
// The same bytes from `header` (data unused) and its rows, for a file larger than memory: row(y,
// bytes) fills row y as RtiFile::data lays it out (asked top to bottom for .rti; for .ptm bottom to
// top once per block: 3 times RGB, twice LRGB); write(data, size) takes the bytes in file order.
using RtiRowFn = std::function<void(int y, uint8_t* bytes)>;
using RtiBytesFn = std::function<void(const void* data, size_t size)>;
void encode_rti_rows(const RtiFile& header, const RtiRowFn& row, const RtiBytesFn& write);
RtiFile decode_rti_file(const std::string& bytes, const std::string& name);

void write_rti_file(const std::filesystem::path& path, const RtiFile& file);  // Atomic.

// write_rti_file(path, quantise(RtiField::fit(header, bands, options), gain)) byte for byte, for
// a field larger than memory: each band's coefficients spilled to a file in `kept_dir`
// (a CheckpointDir's, beside `path`), then quantised and written row by row: it holds a band's
// coefficients, not the image's. The spill and a record of each band fitted stay there for a
// killed run to resume from: a band with a record is read back, not fitted (the caller removes the
// folder once the file is written). Under MPI (`split`) each rank fits its share of the bands (a
// band not its own may be visited without its values), waits for the others, and rank 0 takes
// theirs from their records and writes the file (the others return once their bands are in).
struct RtiWritten {
  std::string name;  // RtiField::name().
  int lights_used = 0;
  double bytes_per_pixel = 0;
  int resumed_rows = 0;  // Rows whose coefficients an earlier run had fitted (kept_dir).
};
RtiWritten write_rti_file_in_bands(const std::filesystem::path& path,
                                   const capture::ReflectanceField& header,
                                   const capture::FieldBands& bands, const RtiFitOptions& options,
                                   double gain, const std::filesystem::path& kept_dir,
                                   const RankSplit& split = {});
RtiFile read_rti_file(const std::filesystem::path& path);

}  // namespace ls::relight
