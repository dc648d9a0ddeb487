#pragma once
// LEDs on GPIO lines (libgpiod). The logic — which line belongs to which LED, polarity, the all-off
// bookkeeping and the error messages — lives in GpioLights and is tested with a fake line driver;
// the libgpiod 1.6 calls live only in gpiod_lights.cc behind GpioLineDriver (Debian 13 moves to the
// incompatible 2.x API: one file to port).
#include <atomic>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "lightstage/hardware.h"
#include "lightstage/stage.h"

namespace ls {

// Physical output lines. Values are electrical levels (true = high); polarity is GpioLights' job.
class GpioLineDriver {
 public:
  virtual ~GpioLineDriver() = default;
  // Requests `line` of `chip` as an output driven to `initial_high` and returns a handle for
  // set_level. Throws HardwareError naming the chip and line when the chip does not exist, the line
  // is out of range or another program holds it.
  virtual int request_output(const std::string& chip, int line, bool initial_high) = 0;
  virtual void set_level(int handle, bool high) = 0;  // Throws HardwareError.
  // Releases every requested line (also done by the destructor). Must not throw.
  virtual void release_all() noexcept = 0;
};

// The libgpiod 1.6 driver. `consumer` is the name other programs (gpioinfo) see on the lines.
std::unique_ptr<GpioLineDriver> make_gpiod_line_driver(const std::string& consumer = "lightstage");

class GpioLights : public LightController {
 public:
  // Requests every LED's line once, all driven off. Throws InputError when the stage file gives an
  // LED no line (or two LEDs the same line), HardwareError naming the LED id, chip and line when a
  // line cannot be requested; lines already requested are switched off and released first.
  GpioLights(const Stage& stage, std::unique_ptr<GpioLineDriver> driver);
  ~GpioLights() override;
  GpioLights(const GpioLights&) = delete;
  GpioLights& operator=(const GpioLights&) = delete;

  int num_lights() const override { return int(leds_.size()); }
  void set_light(int led_index, bool on) override;
  // Software PWM: every period the lines of the LEDs with a level > 0 go on one after another and
  // each goes off level * period after it actually went on, on a thread
  // of its own until set_light, set_levels or all_off (which leave every line off first). Timing
  // rests on the kernel's sleeps (tens of microseconds of jitter). Every lit LED is on at once for
  // part of each period: the supply must carry them together.
  void set_levels(const std::vector<double>& level) override;
  double level_period_s() const override { return pwm_period_s_; }
  void verify_levels() override;  // HardwareError when the PWM thread failed (all lines off).
  // camera.sync.trigger "line": the trigger line (camera.sync.gpio) high for camera.sync.pulse_us.
  void pulse_trigger() override;
  void set_pwm_period(double seconds);  // Default 10 ms.
  // Drives every line to its off level; keeps going past failures (remembered in last_error()).
  void all_off() noexcept override;

  bool is_on(int led_index) const { return leds_.at(led_index).on; }
  int count_on() const;
  const std::string& last_error() const { return last_error_; }
  // "LED 12 (gpiochip0 line 4, active-low)", for messages and `lightstage check`.
  std::string describe(int led_index) const;
  std::string describe_trigger() const;  // "trigger line camera.sync.gpio (gpiochip0 line 17)".

 private:
  struct Line {
    int id = 0;
    std::string chip;
    int line = -1;
    bool active_low = false;
    int handle = -1;
    bool on = false;
  };
  bool level_for(const Line& l, bool on) const { return on != l.active_low; }
  bool stop_pwm() noexcept;
  void drive_all_off(std::string* error) noexcept;
  void run_pwm(const std::vector<double>& level);

  std::unique_ptr<GpioLineDriver> driver_;
  std::vector<Line> leds_;
  Line trigger_;  // Wired to the camera's trigger input; handle -1 when not line-triggered.
  double trigger_pulse_s_ = 0.0;
  std::string last_error_;
  double pwm_period_s_ = 0.01;
  std::atomic<bool> pwm_stop_{false};
  std::atomic<bool> pwm_failed_{false};
  std::string pwm_error_;  // Written by the thread before pwm_failed_, read after it.
  std::thread pwm_;
};

// GPIO chips present on this machine ("gpiochip0 [pinctrl-bcm2711] (58 lines)"); empty when none.
std::vector<std::string> list_gpio_chips();

}  // namespace ls
