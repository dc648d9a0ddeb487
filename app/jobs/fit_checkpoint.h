#pragma once
// The finished bands of a fit in bands of rows (lightstage fit --memory), kept beside the maps
// (OUT.partial/) until the maps are written, so that a fit that is killed resumes from the bands it
// finished. One EXR per band, its normals and per-pixel maps as float (exact), with the band's
// summary counts and the run's identity (field file, its size and time, options, band height) in
// an attribute; written atomically, so a band is there whole or not at all.
#include <filesystem>
#include <string>

#include "relight/fit/fit.h"
#include "relight/fit/normals.h"

namespace ls::jobs {

class BandCheckpoints {
 public:
  // identity: what must match for a band to be taken from an earlier run.
  BandCheckpoints(const std::filesystem::path& out, std::string identity);
  // The band of rows [y0, ...) from an earlier run with the same identity, or false (none, another
  // run's, or unreadable: the band is fitted again).
  bool load(int y0, relight::NormalMap& normals, relight::ModelMaps& maps) const;
  void save(int y0, const relight::NormalMap& normals, const relight::ModelMaps& maps) const;
  // Once the maps are written.
  void remove() const;

 private:
  std::filesystem::path file(int y0) const;
  std::filesystem::path dir_;
  std::string identity_;
};

// The identity of a fit of field_file with these options (their JSON) in bands of `rows`.
std::string fit_identity(const std::filesystem::path& field_file, const std::string& options_json,
                         int rows);

}  // namespace ls::jobs
