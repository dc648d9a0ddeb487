#include "lightstage/stage_devices.h"

#include <set>

namespace ls {

using nlohmann::json;

LedDriverSpec parse_led_driver(const JsonReader& r) {
  r.expect_object({"backend", "port", "baud", "protocol", "timeout_s", "startup_s"});
  LedDriverSpec d;
  if (r.has("backend")) d.backend = r["backend"].one_of({"gpio", "serial"});
  if (d.serial()) {
    if (!r.has("port")) r.fail("a \"port\" (the board's device, e.g. /dev/ttyACM0) for \"serial\"");
    d.port = r["port"].string();
    if (d.port.empty()) r["port"].fail("the board's device, e.g. /dev/ttyACM0");
  } else if (r.has("port")) {
    r["port"].fail("no port with \"backend\": \"gpio\" (LEDs name their lines)");
  }
  if (r.has("baud")) {
    d.baud = r["baud"].integer_in(1200, 4000000);
    static const std::set<int> kRates = {1200,   2400,    4800,    9600,   19200,  38400,
                                         57600,  115200,  230400,  460800, 500000, 576000,
                                         921600, 1000000, 2000000, 4000000};
    if (!kRates.count(d.baud)) r["baud"].fail("a standard rate (9600, 57600, 115200, ...)");
  }
  if (r.has("protocol")) d.protocol = r["protocol"].one_of({"lsled1"});
  if (r.has("timeout_s")) d.timeout_s = r["timeout_s"].number_in(0.001, 60, "(seconds)");
  if (r.has("startup_s")) d.startup_s = r["startup_s"].number_in(0, 60, "(seconds)");
  return d;
}

json led_driver_json(const LedDriverSpec& d) {
  json j = {{"backend", d.backend}};
  if (d.serial()) {
    j["port"] = d.port;
    j["baud"] = d.baud;
    j["protocol"] = d.protocol;
    j["timeout_s"] = d.timeout_s;
    j["startup_s"] = d.startup_s;
  }
  return j;
}

void check_board_channels(const JsonReader& leds, const std::vector<Led>& parsed) {
  std::set<int> channels;
  for (size_t i = 0; i < parsed.size(); ++i) {
    const int channel = parsed[i].board_channel >= 0 ? parsed[i].board_channel : int(i);
    if (!channels.insert(channel).second) {
      leds[i].fail("a board channel no other LED uses (channel " + std::to_string(channel) +
                   " is taken; an LED without \"channel\" takes its index in \"leds\")");
    }
  }
}

TetherSpec parse_tether(const JsonReader& r) {
  r.expect_object(
      {"settings", "base_iso", "shutter_setting", "iso_setting", "raw", "delete_from_camera"});
  TetherSpec t;
  if (r.has("settings")) {
    const JsonReader s = r["settings"];
    if (!s.value().is_object()) s.fail("an object of camera settings (\"f-number\": \"f/8\")");
    for (const auto& [name, value] : s.value().items()) {
      t.settings.emplace_back(name, s[name].string());
    }
  }
  if (r.has("base_iso")) t.base_iso = r["base_iso"].number_in(1, 1e6, "(the ISO of gain 1)");
  if (r.has("shutter_setting")) t.shutter_setting = r["shutter_setting"].string();
  if (r.has("iso_setting")) t.iso_setting = r["iso_setting"].string();
  if (r.has("raw")) {
    const JsonReader raw = r["raw"];
    raw.expect_object({"decode", "white_balance"});
    if (raw.has("decode")) {
      t.raw.mode = raw["decode"].one_of({"demosaic", "bin2x2"}) == "bin2x2"
                       ? RawDecodeOptions::Mode::kBin2x2
                       : RawDecodeOptions::Mode::kDemosaic;
    }
    if (raw.has("white_balance")) {
      const Eigen::Vector3d wb = raw["white_balance"].vec3();
      if (!(wb.array() > 0).all() || wb.maxCoeff() > 1) {
        raw["white_balance"].fail("three multipliers in (0, 1] (the largest 1)");
      }
      t.raw.white_balance = {wb.x(), wb.y(), wb.z()};
    }
  }
  if (r.has("delete_from_camera")) t.delete_from_camera = r["delete_from_camera"].boolean();
  return t;
}

json tether_json(const TetherSpec& t) {
  json settings = json::object();
  for (const auto& [name, value] : t.settings) settings[name] = value;
  return {{"settings", settings},
          {"base_iso", t.base_iso},
          {"shutter_setting", t.shutter_setting},
          {"iso_setting", t.iso_setting},
          {"raw",
           {{"decode", to_string(t.raw.mode)},
            {"white_balance", json::array({t.raw.white_balance[0], t.raw.white_balance[1],
                                           t.raw.white_balance[2]})}}},
          {"delete_from_camera", t.delete_from_camera}};
}

}  // namespace ls
