#include "lightstage/stage.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "lightstage/direction_index.h"
#include "lightstage/errors.h"
#include "lightstage/json_reader.h"
#include "lightstage/stage_devices.h"

namespace ls {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr double kSameDirectionRad = 1e-6;

Led parse_led(const JsonReader& r, size_t index) {
  r.expect_object({"id", "direction", "position", "color", "intensity", "gpio", "channel"});
  Led led;
  led.id = r.has("id") ? r["id"].integer_in(0, 1 << 20) : int(index);
  if (r.has("direction") == r.has("position")) {
    r.fail("exactly one of \"direction\" (unit vector toward the LED) or \"position\" (metres)");
  }
  if (r.has("direction")) {
    led.dir_in_stage = r["direction"].unit_vec3();
  } else {
    const Eigen::Vector3d p = r["position"].vec3();
    const double distance_m = p.stableNorm();
    if (!(distance_m > 1e-6) || !(distance_m < 1e6)) {
      r["position"].fail("a position away from the stage centre, within 1000 km of it (metres)");
    }
    led.dir_in_stage = p / distance_m;
    led.distance_m = distance_m;
  }
  if (r.has("color")) {
    const JsonReader c = r["color"];
    led.color_gain = c.fits_float().vec3();
    if ((led.color_gain.array() < 0).any()) c.fail("three non-negative colour gains");
  }
  if (r.has("intensity"))
    led.intensity = r["intensity"].fits_float().positive("(irradiance at the origin)");
  if (r.has("gpio")) {
    const JsonReader g = r["gpio"];
    g.expect_object({"chip", "line", "active_low"});
    led.gpio_chip = g["chip"].string();
    led.gpio_line = g["line"].integer_in(0, 4095);
    if (g.has("active_low")) led.active_low = g["active_low"].boolean();
  }
  if (r.has("channel")) led.board_channel = r["channel"].integer_in(0, 4095);
  return led;
}

CameraResponse parse_response(const JsonReader& r, const fs::path& base_dir) {
  r.expect_object({"type", "gamma", "file"});
  CameraResponse response;
  const std::string type = r["type"].one_of({"linear", "gamma", "table", "recover"});
  if (type == "linear") response.kind = CameraResponse::Kind::kLinear;
  if (type == "gamma") {
    response.kind = CameraResponse::Kind::kGamma;
    response.gamma = r["gamma"].number_in(0.2, 5.0);
  }
  if (type == "table") {
    response.kind = CameraResponse::Kind::kTable;
    const fs::path file = r["file"].string();
    response.table_file = file.is_absolute() ? file : base_dir / file;
  }
  if (type == "recover") response.kind = CameraResponse::Kind::kRecover;
  return response;
}

CameraSync parse_sync(const JsonReader& r) {
  r.expect_object({"trigger", "input", "gpio", "pulse_us", "exposure_active_output"});
  CameraSync sync;
  if (r.has("trigger")) sync.trigger = r["trigger"].one_of({"software", "line"});
  if (r.has("input")) sync.input = r["input"].string();
  if (r.has("gpio")) {
    const JsonReader g = r["gpio"];
    g.expect_object({"chip", "line"});
    sync.gpio_chip = g["chip"].string();
    sync.gpio_line = g["line"].integer_in(0, 4095);
  }
  if (r.has("pulse_us")) sync.pulse_us = r["pulse_us"].number_in(1, 1e5, "(microseconds)");
  if (r.has("exposure_active_output")) {
    sync.exposure_active_output = r["exposure_active_output"].string();
  }
  if (sync.input.empty()) r["input"].fail("the camera's trigger input, e.g. \"Line0\"");
  if (sync.line_triggered() && sync.exposure_active_output == sync.input) {
    r["exposure_active_output"].fail("an output line other than the trigger input \"" + sync.input +
                                     "\"");
  }
  return sync;
}

CameraSpec parse_camera(const JsonReader& r, const fs::path& base_dir) {
  r.expect_object({"backend", "device", "width", "height", "channels", "bit_depth", "bracket",
                   "response", "radiometric_scale", "fov_y_deg", "distance_m", "ortho_height_m",
                   "timeout_s", "retries", "sync", "simulated_sensor", "gphoto2"});
  CameraSpec cam;
  if (r.has("backend")) {
    cam.backend = r["backend"].one_of({"sim", "aravis", "v4l2", "gphoto2", "sim-dslr"});
  }
  if (r.has("gphoto2")) cam.tether = parse_tether(r["gphoto2"]);
  if (r.has("device")) cam.device_id = r["device"].string();
  if (r.has("width")) cam.width = r["width"].integer_in(1, 16384);
  if (r.has("height")) cam.height = r["height"].integer_in(1, 16384);
  if (r.has("channels")) {
    cam.channels = r["channels"].integer_in(1, 3);
    if (cam.channels == 2) r["channels"].fail("1 (mono) or 3 (RGB)");
  }
  if (r.has("bit_depth")) cam.bit_depth = r["bit_depth"].integer_in(8, 16);
  if (r.has("bracket")) {
    const JsonReader b = r["bracket"];
    if (b.size() == 0) b.fail("at least one exposure step");
    cam.bracket.clear();
    for (size_t i = 0; i < b.size(); ++i) {
      const JsonReader step = b[i];
      step.expect_object({"exposure_s", "gain"});
      ExposureStep s;
      s.exposure_s = step["exposure_s"].positive("(seconds)");
      if (s.exposure_s > 3600) step["exposure_s"].fail("an exposure of at most an hour (3600 s)");
      if (step.has("gain")) s.gain = step["gain"].positive("(linear gain)");
      for (const ExposureStep& earlier : cam.bracket) {
        if (earlier.exposure_s * earlier.gain == s.exposure_s * s.gain) {
          step.fail("an exposure (exposure_s x gain) the bracket has not had yet");
        }
      }
      cam.bracket.push_back(s);
    }
  }
  if (r.has("response")) cam.response = parse_response(r["response"], base_dir);
  if (r.has("radiometric_scale"))
    cam.radiometric_scale = r["radiometric_scale"].fits_float().positive();
  if (r.has("fov_y_deg")) cam.fov_y_deg = r["fov_y_deg"].number_in(0, 170, "(0 = orthographic)");
  if (r.has("distance_m")) cam.distance_m = r["distance_m"].positive("(metres)");
  if (r.has("ortho_height_m")) cam.ortho_height_m = r["ortho_height_m"].positive("(metres)");
  if (r.has("timeout_s")) cam.timeout_s = r["timeout_s"].positive("(seconds)");
  if (r.has("retries")) cam.retries = r["retries"].integer_in(0, 100);
  if (r.has("sync")) cam.sync = parse_sync(r["sync"]);
  if (r.has("simulated_sensor")) {
    const JsonReader s = r["simulated_sensor"];
    s.expect_object({"full_well_e", "read_noise_e", "dark_current_e_per_s", "black_level",
                     "real_time", "dead_leds"});
    auto& sim = cam.simulated;
    if (s.has("full_well_e")) sim.full_well_e = s["full_well_e"].positive("(electrons)");
    if (s.has("read_noise_e")) sim.read_noise_e = s["read_noise_e"].number_in(0, 1e4);
    if (s.has("dark_current_e_per_s")) {
      sim.dark_current_e_per_s = s["dark_current_e_per_s"].number_in(0, 1e9);
    }
    if (s.has("black_level")) sim.black_level = s["black_level"].number_in(0, 0.5);
    if (s.has("real_time")) sim.real_time = s["real_time"].boolean();
    if (s.has("dead_leds")) {
      const JsonReader ids = s["dead_leds"];
      for (size_t i = 0; i < ids.size(); ++i) {
        sim.dead_led_ids.push_back(ids[i].integer_in(0, 1 << 20));
      }
    }
  }
  return cam;
}

CapturePlan parse_plan(const JsonReader& r, const std::vector<Led>& leds, int bracket_steps) {
  r.expect_object({"led_order", "dark_frames", "settle_s", "time_steps", "interval_s", "times_s",
                   "reference_led", "reference_every", "led_exposures"});
  CapturePlan plan;
  std::set<int> known;  // The LED ids the plan may name.
  for (const auto& led : leds) known.insert(led.id);
  // The id of an LED in "leds" at `field`.
  const auto led_id = [&](const JsonReader& field) {
    const int id = field.integer_in(0, 1 << 20);
    if (!known.count(id)) field.fail("the id of an LED in \"leds\"");
    return id;
  };
  if (r.has("led_order")) {
    const JsonReader order = r["led_order"];
    std::set<int> seen;
    for (size_t i = 0; i < order.size(); ++i) {
      const int id = led_id(order[i]);
      if (!seen.insert(id).second) order[i].fail("each LED id once (this one repeats)");
      plan.led_order.push_back(id);
    }
  }
  if (r.has("reference_led")) {
    plan.reference_led = led_id(r["reference_led"]);
  }
  if (r.has("reference_every")) {
    if (!r.has("reference_led")) {
      r["reference_every"].fail("a \"reference_led\" beside it (the LED shot every N LEDs)");
    }
    plan.reference_every = r["reference_every"].integer_in(1, 100000);
  }
  // A frame's plan key holds 8 bits of repeat (session.cc: sequence_key).
  if (plan.reference_shots(int(leds.size())) > 255) {
    (r.has("reference_every") ? r["reference_every"] : r["reference_led"])
        .fail("a reference_every of at least " + std::to_string((int(leds.size()) + 253) / 254) +
              " for " + std::to_string(leds.size()) +
              " LEDs: at most 255 reference shots per time step");
  }
  if (r.has("led_exposures")) {
    const JsonReader list = r["led_exposures"];
    for (size_t i = 0; i < list.size(); ++i) {
      const JsonReader entry = list[i];
      entry.expect_object({"led", "exposures"});
      const int id = led_id(entry["led"]);
      if (plan.led_exposures.count(id)) entry["led"].fail("each LED once (this one repeats)");
      const JsonReader steps = entry["exposures"];
      if (steps.size() == 0) steps.fail("at least one bracket step");
      std::vector<int>& chosen = plan.led_exposures[id];
      for (size_t k = 0; k < steps.size(); ++k) {
        chosen.push_back(steps[k].integer_in(0, bracket_steps - 1));
        if (k > 0 && chosen[k] <= chosen[k - 1]) steps[k].fail("bracket steps in increasing order");
      }
    }
  }
  if (r.has("dark_frames")) plan.dark_frames = r["dark_frames"].integer_in(1, 64);
  if (r.has("settle_s")) plan.settle_s = r["settle_s"].number_in(0, 60, "(seconds)");
  if (r.has("time_steps")) plan.time_steps = r["time_steps"].integer_in(1, 100000);
  if (r.has("interval_s")) plan.interval_s = r["interval_s"].number_in(0, 1e6, "(seconds)");
  if (r.has("times_s")) {
    const JsonReader times = r["times_s"];
    if (r.has("time_steps") || r.has("interval_s")) {
      times.fail("either \"times_s\" or \"time_steps\" and \"interval_s\", not both");
    }
    if (times.size() == 0 || times.size() > 100000) times.fail("a list of 1 to 100000 times");
    for (size_t i = 0; i < times.size(); ++i) {
      const double t = times[i].number_in(0, 1e9, "(seconds, >= 0)");
      if (i > 0 && !(t > plan.times_s.back())) {
        std::ostringstream expected;
        expected << "a time greater than the previous one (" << plan.times_s.back()
                 << " s): times_s must increase";
        times[i].fail(expected.str());
      }
      plan.times_s.push_back(t);
    }
    plan.time_steps = int(plan.times_s.size());
  }
  return plan;
}

StageCalibration parse_calibration(const JsonReader& r, const fs::path& base_dir) {
  r.expect_object({"flat_field", "reference_z_m"});
  StageCalibration calibration;
  if (r.has("flat_field")) {
    const fs::path file = r["flat_field"].string();
    if (file.empty()) r["flat_field"].fail("a file name (the flat-field side car, .exr)");
    // Absolute: a session's manifest keeps the stage, and must still find the file from there.
    calibration.flat_field =
        fs::absolute(file.is_absolute() ? file : base_dir / file).lexically_normal();
  }
  if (r.has("reference_z_m")) {
    calibration.reference_z_m = r["reference_z_m"].number_in(-100, 100, "(metres)");
  }
  return calibration;
}

std::vector<Eigen::Vector3d> layout_directions(const JsonReader& r) {
  r.expect_object({"type", "frequency", "count", "min_elevation_deg"});
  const std::string type = r["type"].one_of({"geodesic", "fibonacci"});
  const double min_elev =
      r.has("min_elevation_deg") ? r["min_elevation_deg"].number_in(-90, 89) : -11.5;
  if (type == "geodesic")
    return geodesic_dome_directions(r["frequency"].integer_in(1, 32), min_elev);
  return fibonacci_dome_directions(r["count"].integer_in(1, 100000), min_elev);
}

// What the camera section says of the LEDs: a trigger line of its own (not an LED's), and
// simulated dead LEDs that are LEDs of the stage, each once, not all of them.
void check_camera_against_leds(const JsonReader& r, const Stage& stage) {
  const CameraSync& sync = stage.camera.sync;
  if (sync.line_triggered()) {
    const JsonReader s = r["sync"];
    if (!s.has("gpio")) {
      s.fail(
          "a \"gpio\" {\"chip\", \"line\"} with \"trigger\": \"line\" (the line the stage "
          "pulses to trigger the camera)");
    }
    for (const Led& led : stage.leds) {
      if (led.gpio_line == sync.gpio_line && led.gpio_chip == sync.gpio_chip) {
        s["gpio"].fail("a trigger line that no LED uses (LED " + std::to_string(led.id) +
                       " is on " + sync.gpio_chip + " line " + std::to_string(sync.gpio_line) +
                       ")");
      }
    }
  }
  if (!r.has("simulated_sensor") || !r["simulated_sensor"].has("dead_leds")) return;
  const JsonReader ids = r["simulated_sensor"]["dead_leds"];
  const std::vector<int>& dead = stage.camera.simulated.dead_led_ids;
  std::set<int> seen;
  for (std::size_t i = 0; i < dead.size(); ++i) {
    if (stage.led_index(dead[i]) < 0) ids[i].fail("the id of an LED in \"leds\"");
    if (!seen.insert(dead[i]).second) ids[i].fail("each LED id once (this one repeats)");
  }
  if (seen.size() == stage.leds.size()) {
    ids.fail("some LED left alive (every LED is listed: the field would hold nothing)");
  }
}

json vec_json(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }

}  // namespace

double CapturePlan::step_time_s(int t) const {
  if (!times_s.empty()) return times_s.at(size_t(t));
  return t * interval_s;
}

int CapturePlan::reference_shots(int leds) const {
  if (reference_led < 0) return 0;
  return (leds + reference_every - 1) / reference_every + 1;  // Every N LEDs, and after the last.
}

double CapturePlan::step_interval_s(int t) const {
  if (t + 1 >= time_steps) return 0.0;
  return step_time_s(t + 1) - step_time_s(t);
}

int Stage::led_index(int id) const {
  for (size_t i = 0; i < leds.size(); ++i) {
    if (leds[i].id == id) return int(i);
  }
  return -1;
}

std::vector<int> Stage::capture_order() const {
  std::vector<int> order;
  if (plan.led_order.empty()) {
    for (size_t i = 0; i < leds.size(); ++i) order.push_back(int(i));
  } else {
    for (int id : plan.led_order) order.push_back(led_index(id));
  }
  return order;
}

std::vector<int> Stage::exposures_of(int led_index) const {
  if (auto it = plan.led_exposures.find(leds.at(size_t(led_index)).id);
      it != plan.led_exposures.end()) {
    return it->second;
  }
  std::vector<int> all(camera.bracket.size());
  for (size_t e = 0; e < all.size(); ++e) all[e] = int(e);
  return all;
}

std::vector<Eigen::Vector3d> Stage::led_directions() const {
  std::vector<Eigen::Vector3d> dirs;
  dirs.reserve(leds.size());
  for (const auto& led : leds) dirs.push_back(led.dir_in_stage);
  return dirs;
}

Stage parse_stage(std::string_view json_text, const std::string& source_name) {
  const json doc = JsonReader::parse(json_text, source_name);
  const JsonReader r(doc, source_name);
  r.expect_object({"name", "leds", "layout", "led_driver", "camera", "plan", "coverage_radius_deg",
                   "calibration"});
  const fs::path base_dir = fs::path(source_name).parent_path();

  Stage stage = default_stage();
  stage.source = source_name;
  if (r.has("name")) stage.name = r["name"].string();
  if (r.has("leds") == r.has("layout")) {
    r.fail("exactly one of \"leds\" (a list of LEDs) or \"layout\" (a generated dome)");
  }
  if (r.has("leds")) {
    const JsonReader leds = r["leds"];
    if (leds.size() == 0) leds.fail("at least one LED");
    stage.leds.clear();
    std::set<int> ids;
    std::set<std::pair<std::string, int>> lines;
    for (size_t i = 0; i < leds.size(); ++i) {
      stage.leds.push_back(parse_led(leds[i], i));
      const Led& led = stage.leds.back();
      if (!ids.insert(led.id).second) leds[i]["id"].fail("a unique LED id");
      if (led.gpio_line >= 0 && !lines.insert({led.gpio_chip, led.gpio_line}).second) {
        leds[i]["gpio"].fail("a line no other LED drives (two LEDs on one line light together)");
      }
    }
    check_board_channels(leds, stage.leds);
    // Two LEDs in one place are one light counted twice: every per-LED solid angle and fit
    // would weigh it double.
    std::vector<Eigen::Vector3d> directions;
    for (const Led& led : stage.leds) directions.push_back(led.dir_in_stage);
    const DirectionIndex index(directions);
    for (size_t i = 0; i < directions.size(); ++i) {
      if (!(index.nearest_other_angle(int(i)) < kSameDirectionRad)) continue;
      for (const int j : index.within(directions[i], kSameDirectionRad)) {
        if (size_t(j) < i) {
          leds[i].fail("an LED in a place of its own (LED " +
                       std::to_string(stage.leds[size_t(j)].id) + " is in the same direction)");
        }
      }
    }
  } else {
    stage.leds = stage_with_directions(layout_directions(r["layout"])).leds;
  }
  if (r.has("led_driver")) stage.led_driver = parse_led_driver(r["led_driver"]);
  if (r.has("camera")) {
    stage.camera = parse_camera(r["camera"], base_dir);
    check_camera_against_leds(r["camera"], stage);
  }
  if (stage.camera.bracket.empty()) stage.camera.bracket = default_stage().camera.bracket;
  if (r.has("plan")) {
    stage.plan = parse_plan(r["plan"], stage.leds, int(stage.camera.bracket.size()));
  }
  if (r.has("calibration")) stage.calibration = parse_calibration(r["calibration"], base_dir);
  if (r.has("coverage_radius_deg")) {
    stage.coverage_radius_deg = r["coverage_radius_deg"].number_in(0, 180, "(0 = automatic)");
  }
  return stage;
}

Stage load_stage(const fs::path& path) {
  std::error_code ignored;
  if (fs::is_directory(path, ignored)) {
    throw InputError(path.string() + ": a folder, not a stage file (give the stage's .json file)");
  }
  std::ifstream in(path);
  if (!in) throw InputError(path.string() + ": cannot open stage file");
  std::stringstream text;
  text << in.rdbuf();
  return parse_stage(text.str(), path.string());
}

void require_stage_files(const Stage& stage) {
  const auto require_file = [&](const fs::path& file, const std::string& field) {
    std::error_code ignored;
    if (!fs::is_regular_file(file, ignored)) {
      throw InputError(
          stage.source + ": " + field + ": " + file.string() +
          (fs::is_directory(file, ignored) ? " is a folder, not a file" : " not found"));
    }
  };
  if (!stage.calibration.flat_field.empty()) {
    require_file(stage.calibration.flat_field, "calibration.flat_field");
  }
  if (stage.camera.response.kind == CameraResponse::Kind::kTable) {
    require_file(stage.camera.response.table_file, "camera.response.file");
  }
}

std::string stage_to_json(const Stage& stage) {
  json leds = json::array();
  for (const auto& led : stage.leds) {
    json j = {{"id", led.id}, {"color", vec_json(led.color_gain)}, {"intensity", led.intensity}};
    if (led.distance_m) {
      j["position"] = vec_json(led.dir_in_stage * *led.distance_m);
    } else {
      j["direction"] = vec_json(led.dir_in_stage);
    }
    if (led.gpio_line >= 0) {
      j["gpio"] = {
          {"chip", led.gpio_chip}, {"line", led.gpio_line}, {"active_low", led.active_low}};
    }
    if (led.board_channel >= 0) j["channel"] = led.board_channel;
    leds.push_back(j);
  }
  const CameraSpec& c = stage.camera;
  json bracket = json::array();
  for (const auto& s : c.bracket)
    bracket.push_back({{"exposure_s", s.exposure_s}, {"gain", s.gain}});
  json response;
  switch (c.response.kind) {
    case CameraResponse::Kind::kLinear:
      response = {{"type", "linear"}};
      break;
    case CameraResponse::Kind::kGamma:
      response = {{"type", "gamma"}, {"gamma", c.response.gamma}};
      break;
    case CameraResponse::Kind::kTable:
      response = {{"type", "table"}, {"file", c.response.table_file.string()}};
      break;
    case CameraResponse::Kind::kRecover:
      response = {{"type", "recover"}};
      break;
  }
  json camera = {{"backend", c.backend},
                 {"device", c.device_id},
                 {"width", c.width},
                 {"height", c.height},
                 {"channels", c.channels},
                 {"bit_depth", c.bit_depth},
                 {"bracket", bracket},
                 {"response", response},
                 {"radiometric_scale", c.radiometric_scale},
                 {"fov_y_deg", c.fov_y_deg},
                 {"distance_m", c.distance_m},
                 {"ortho_height_m", c.ortho_height_m},
                 {"timeout_s", c.timeout_s},
                 {"retries", c.retries},
                 {"sync",
                  {{"trigger", c.sync.trigger},
                   {"input", c.sync.input},
                   {"pulse_us", c.sync.pulse_us},
                   {"exposure_active_output", c.sync.exposure_active_output}}},
                 {"simulated_sensor",
                  {{"full_well_e", c.simulated.full_well_e},
                   {"read_noise_e", c.simulated.read_noise_e},
                   {"dark_current_e_per_s", c.simulated.dark_current_e_per_s},
                   {"black_level", c.simulated.black_level},
                   {"real_time", c.simulated.real_time},
                   {"dead_leds", c.simulated.dead_led_ids}}}};
  if (c.sync.gpio_line >= 0) {
    camera["sync"]["gpio"] = {{"chip", c.sync.gpio_chip}, {"line", c.sync.gpio_line}};
  }
  if (c.backend == "gphoto2" || c.backend == "sim-dslr") camera["gphoto2"] = tether_json(c.tether);
  json plan = {{"dark_frames", stage.plan.dark_frames}, {"settle_s", stage.plan.settle_s}};
  if (stage.plan.times_s.empty()) {
    plan["time_steps"] = stage.plan.time_steps;
    plan["interval_s"] = stage.plan.interval_s;
  } else {
    plan["times_s"] = stage.plan.times_s;
  }
  if (!stage.plan.led_order.empty()) plan["led_order"] = stage.plan.led_order;
  if (!stage.plan.led_exposures.empty()) {
    json chosen = json::array();
    for (const auto& [id, steps] : stage.plan.led_exposures) {
      chosen.push_back({{"led", id}, {"exposures", steps}});
    }
    plan["led_exposures"] = chosen;
  }
  if (stage.plan.reference_led >= 0) {
    plan["reference_led"] = stage.plan.reference_led;
    plan["reference_every"] = stage.plan.reference_every;
  }
  json doc = {{"name", stage.name},
              {"coverage_radius_deg", stage.coverage_radius_deg},
              {"leds", leds},
              {"camera", camera},
              {"plan", plan}};
  if (stage.led_driver.serial()) doc["led_driver"] = led_driver_json(stage.led_driver);
  if (!stage.calibration.flat_field.empty() || stage.calibration.reference_z_m != 0.0) {
    json calibration = {{"reference_z_m", stage.calibration.reference_z_m}};
    if (!stage.calibration.flat_field.empty()) {
      calibration["flat_field"] = stage.calibration.flat_field.string();
    }
    doc["calibration"] = calibration;
  }
  return doc.dump(2) + "\n";
}

}  // namespace ls
