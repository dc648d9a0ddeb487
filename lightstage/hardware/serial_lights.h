#pragma once
// LEDs switched by a microcontroller board on a serial line (USB CDC /dev/ttyACM*, a USB-serial
// adapter /dev/ttyUSB*), as the Arduino sketches of RTI domes do. The protocol, "lsled1", is
// plain text, one command a line, each answered by one line (docs/hardware.md writes it out):
//   host: "ID"                     board: "OK lsled1 <channels>"
//   host: "SET <channel> <level>"  board: "OK"   level 0 (off) .. 1000 (full on)
//   host: "OFF"                    board: "OK"   every channel off
//   any line the board cannot do:  board: "ERR <reason>"
// The controller waits for each reply: a board that stops answering, or answers anything else, is
// a HardwareError naming the port and the command, never a frame under the wrong light.
#include <string>
#include <vector>

#include "lightstage/hardware.h"
#include "lightstage/stage.h"

namespace ls {

class SerialLights : public LightController {
 public:
  // Opens stage.led_driver.port raw at its baud rate, waits up to startup_s for the board to
  // answer "ID" (an Arduino reboots when its port opens), checks it has a channel for every LED,
  // and switches everything off. HardwareError naming the port otherwise.
  explicit SerialLights(const Stage& stage);
  ~SerialLights() override;
  SerialLights(const SerialLights&) = delete;
  SerialLights& operator=(const SerialLights&) = delete;

  int num_lights() const override { return int(channel_of_led_.size()); }
  void set_light(int led_index, bool on) override;
  // The board dims (PWM or constant-current): each LED at its level, continuously.
  void set_levels(const std::vector<double>& level) override;
  void all_off() noexcept override;

  int board_channels() const { return board_channels_; }
  // "LED 12 (board channel 12 on /dev/ttyACM0)".
  std::string describe(int led_index) const;

 private:
  void start_board(const LedDriverSpec& driver);  // Line settings, ID, channels, all off.
  // Sends one command line and returns the board's reply (without "OK"), or throws.
  std::string command(const std::string& line, double timeout_s);
  std::string read_line(double timeout_s, const std::string& sent);
  void write_all(const std::string& bytes);

  std::string port_;
  int fd_ = -1;
  double timeout_s_ = 1.0;
  std::vector<int> channel_of_led_;
  std::vector<int> led_ids_;
  std::vector<int> level_of_led_;  // Last level sent (0..1000), to send only changes.
  int board_channels_ = 0;
  std::string pending_;  // Bytes read past the last line.
};

}  // namespace ls
