#pragma once
// The stage file's sections for DSLR domes (stage.cc reads and writes the rest): "led_driver", an
// LED's board "channel", and "camera": {"gphoto2": {...}}.
#include <nlohmann/json.hpp>

#include "lightstage/json_reader.h"
#include "lightstage/stage.h"

namespace ls {

LedDriverSpec parse_led_driver(const JsonReader& r);
nlohmann::json led_driver_json(const LedDriverSpec& driver);
// After the LEDs are read: each board channel used once; a serial driver's every LED a channel.
void check_board_channels(const JsonReader& leds, const std::vector<Led>& parsed);

TetherSpec parse_tether(const JsonReader& r);
nlohmann::json tether_json(const TetherSpec& tether);

}  // namespace ls
