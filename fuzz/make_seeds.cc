// Writes the fuzz targets' seed corpora into OUT/<target>/ (scripts/fuzz.sh runs it before the
// targets): files written by lightstage's own writers — fields, model and temporal maps (as
// descriptions, fuzz_support.h), .lspca, .ptm and .rti files, sessions — and the stage and scene
// files the project ships. Hand-written seeds and the inputs of fixed findings are in
// fuzz/corpus/<target>/ (committed).
//   make_fuzz_seeds OUT SOURCE_DIR      (SOURCE_DIR: the checkout, for data/)
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "capture/field_file.h"
#include "fuzz/fuzz_fixtures.h"
#include "fuzz/fuzz_support.h"
#include "lightstage/session.h"
#include "lightstage/stage.h"
#include "relight/compact/pca_field.h"
#include "relight/compact/rti_fits.h"
#include "relight/compact/rti_io.h"

namespace {

namespace fs = std::filesystem;
using namespace ls;

std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

void write_seed(const fs::path& out, const std::string& target, const std::string& name,
                const std::string& bytes) {
  fs::create_directories(out / target);
  std::ofstream(out / target / name, std::ios::binary) << bytes;
}

void exr_seeds(const fs::path& out, const fs::path& scratch) {
  const capture::ReflectanceField field = fuzz::small_field(6);
  capture::write_field(scratch / "field.exr", field);
  write_seed(out, "field_exr_fuzz", "scanlines", fuzz::describe_exr(scratch / "field.exr"));
  capture::write_field(scratch / "tiled.exr", field, {}, /*tile_size=*/2);
  write_seed(out, "field_exr_fuzz", "tiled", fuzz::describe_exr(scratch / "tiled.exr"));
  // Half storage: its rows read from the mapping, its lightstage:storage attribute parsed.
  capture::write_field(scratch / "half.exr", field, {}, 0,
                       capture::choose_storage(field, capture::StorageChoice::kHalf));
  write_seed(out, "field_exr_fuzz", "half", fuzz::describe_exr(scratch / "half.exr"));

  relight::write_model_maps(scratch / "maps.exr", fuzz::small_model_maps());
  write_seed(out, "model_maps_fuzz", "materials", fuzz::describe_exr(scratch / "maps.exr"));
  relight::ModelMaps per_pixel = fuzz::small_model_maps();
  per_pixel.materials.clear();
  for (size_t i = 0; i < per_pixel.maps.num_pixels(); ++i) {
    per_pixel.maps.pixels[i * relight::kMapChannelCount + relight::kMapMaterial] = 0;
  }
  relight::write_model_maps(scratch / "per_pixel.exr", per_pixel);
  write_seed(out, "model_maps_fuzz", "per_pixel", fuzz::describe_exr(scratch / "per_pixel.exr"));

  relight::write_temporal_maps(scratch / "temporal.exr", fuzz::small_temporal_maps());
  write_seed(out, "temporal_maps_fuzz", "four_steps", fuzz::describe_exr(scratch / "temporal.exr"));
}

void compact_seeds(const fs::path& out, const fs::path& scratch) {
  const capture::ReflectanceField field = fuzz::small_field(20);
  relight::PcaOptions global;
  global.rank = 3;
  relight::PcaField::build(field, global).write(scratch / "global.lspca");
  write_seed(out, "pca_fuzz", "global", read_bytes(scratch / "global.lspca"));
  relight::PcaOptions tiled = global;
  tiled.rank = 2;
  tiled.tile_size = 2;
  relight::PcaField::build(field, tiled).write(scratch / "tiled.lspca");
  write_seed(out, "pca_fuzz", "tiled", read_bytes(scratch / "tiled.lspca"));

  const std::pair<const char*, relight::RtiFitOptions> formats[] = {
      {"ptm_rgb.ptm", {relight::RtiBasis::kPtm, false}},
      {"ptm_lrgb.ptm", {relight::RtiBasis::kPtm, true}},
      {"hsh2.rti", {relight::RtiBasis::kHsh2, false}},
      {"hsh3.rti", {relight::RtiBasis::kHsh3, false}}};
  for (const auto& [name, options] : formats) {
    const relight::RtiField fitted = relight::RtiField::fit(field, options);
    write_seed(out, "rti_fuzz", name, relight::encode_rti_file(relight::quantise(fitted)));
  }
}

// A session as a capture leaves it: the manifest, "--", the journal.
std::string session_seed(const fs::path& dir) {
  return fuzz::join_parts({read_bytes(dir / "manifest.json"), read_bytes(dir / "frames.jsonl")});
}

void session_seeds(const fs::path& out, const fs::path& scratch) {
  const Stage stage = fuzz::small_stage();
  const std::vector<PlannedFrame> plan = plan_frames(stage);
  Session interrupted = Session::create(scratch / "interrupted", stage, {"sim", "scene.json", 7});
  for (size_t i = 0; i < plan.size() / 2; ++i) {
    interrupted.record_frame(plan[i], fuzz::small_frame(plan[i]));
  }
  interrupted.record_led_signal(0, 0, 0.4);
  interrupted.mark_dead_led(1, "no signal above the dark frames");
  interrupted.record_time_step_overrun({0, 41.5, 30.0});
  interrupted.write_manifest("interrupted");
  write_seed(out, "session_fuzz", "interrupted", session_seed(scratch / "interrupted"));

  Session complete = Session::create(scratch / "complete", stage, {"sim", "", 1});
  for (const PlannedFrame& planned : plan)
    complete.record_frame(planned, fuzz::small_frame(planned));
  complete.write_manifest("complete");
  write_seed(out, "session_fuzz", "complete", session_seed(scratch / "complete"));
}

// The project's own stage and scene files, and the built-in stage as `lightstage stage --write`
// writes it.
void text_seeds(const fs::path& out, const fs::path& source_dir) {
  const fs::path data = source_dir / "data";
  for (const auto& [folder, target] :
       {std::pair{"stages", "stage_fuzz"}, {"scenes", "scene_fuzz"}}) {
    for (const auto& entry : fs::directory_iterator(data / folder)) {
      write_seed(out, target, entry.path().filename().string(), read_bytes(entry.path()));
    }
  }
  write_seed(out, "stage_fuzz", "built_in.json", stage_to_json(default_stage()));
  write_seed(out, "stage_fuzz", "session_fixture.json", stage_to_json(fuzz::small_stage()));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: make_fuzz_seeds OUT SOURCE_DIR\n";
    return 1;
  }
  const fs::path out = argv[1];
  const fs::path scratch = fuzz::work_dir() / "seeds";
  fs::create_directories(scratch);
  try {
    exr_seeds(out, scratch);
    compact_seeds(out, scratch);
    session_seeds(out, scratch);
    text_seeds(out, argv[2]);
  } catch (const std::exception& e) {
    std::cerr << "make_fuzz_seeds: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
