#include "lightstage/hardware/gpiod_lights.h"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <gpiod.hpp>
#include <map>
#include <set>
#include <system_error>
#include <utility>

#include "lightstage/errors.h"

namespace ls {

// ---- GpioLights: the logic, independent of libgpiod --------------------------------------------

GpioLights::GpioLights(const Stage& stage, std::unique_ptr<GpioLineDriver> driver)
    : driver_(std::move(driver)) {
  LS_CHECK(driver_ != nullptr, "GpioLights needs a line driver");
  std::map<std::pair<std::string, int>, int> owner;  // (chip, line) -> LED id.
  for (size_t i = 0; i < stage.leds.size(); ++i) {
    const Led& led = stage.leds[i];
    const std::string field =
        stage.source + ": leds[" + std::to_string(i) + "] (id " + std::to_string(led.id) + ")";
    if (led.gpio_chip.empty()) {
      throw InputError(field + ": gpio_chip: expected a GPIO chip (e.g. \"gpiochip0\") for the " +
                       "gpiod back-end, got none");
    }
    if (led.gpio_line < 0) {
      throw InputError(field + ": gpio_line: expected a line offset >= 0, got " +
                       std::to_string(led.gpio_line));
    }
    const auto [it, inserted] = owner.emplace(std::make_pair(led.gpio_chip, led.gpio_line), led.id);
    if (!inserted) {
      throw InputError(field + ": gpio_line: " + led.gpio_chip + " line " +
                       std::to_string(led.gpio_line) + " is already used by LED " +
                       std::to_string(it->second));
    }
    leds_.push_back({led.id, led.gpio_chip, led.gpio_line, led.active_low, -1, false});
  }
  const CameraSync& sync = stage.camera.sync;
  if (sync.line_triggered()) {
    const std::string field = stage.source + ": camera.sync.gpio";
    if (sync.gpio_chip.empty() || sync.gpio_line < 0) {
      throw InputError(field + ": expected the GPIO chip and line wired to the camera's trigger " +
                       "input " + sync.input + " (camera.sync.trigger \"line\"), got none");
    }
    if (auto it = owner.find({sync.gpio_chip, sync.gpio_line}); it != owner.end()) {
      throw InputError(field + ": " + sync.gpio_chip + " line " + std::to_string(sync.gpio_line) +
                       " is already used by LED " + std::to_string(it->second));
    }
    trigger_ = {-1, sync.gpio_chip, sync.gpio_line, false, -1, false};
    trigger_pulse_s_ = sync.pulse_us * 1e-6;
  }
  for (size_t i = 0; i <= leds_.size(); ++i) {
    Line& l = i < leds_.size() ? leds_[i] : trigger_;
    if (l.line < 0) continue;  // No trigger line.
    try {
      l.handle = driver_->request_output(l.chip, l.line, level_for(l, /*on=*/false));
    } catch (const HardwareError& e) {
      all_off();
      driver_->release_all();
      throw HardwareError((i < leds_.size() ? describe(int(i)) : describe_trigger()) + ": " +
                          e.what());
    }
  }
}

void GpioLights::pulse_trigger() {
  if (trigger_.handle < 0) LightController::pulse_trigger();  // Throws: not line-triggered.
  try {
    driver_->set_level(trigger_.handle, true);
    std::this_thread::sleep_for(std::chrono::duration<double>(trigger_pulse_s_));
    driver_->set_level(trigger_.handle, false);
  } catch (const HardwareError& e) {
    try {
      driver_->set_level(trigger_.handle, false);
    } catch (const HardwareError&) {
      // The line is gone: the first failure is the one to report.
    }
    throw HardwareError(describe_trigger() + ": cannot pulse: " + e.what());
  }
}

std::string GpioLights::describe_trigger() const {
  return "trigger line camera.sync.gpio (" + trigger_.chip + " line " +
         std::to_string(trigger_.line) + ")";
}

GpioLights::~GpioLights() {
  all_off();
  driver_->release_all();
}

void GpioLights::set_light(int led_index, bool on) {
  stop_pwm();
  LS_CHECK(led_index >= 0 && led_index < num_lights(),
           "LED index " + std::to_string(led_index) + " of " + std::to_string(num_lights()));
  Line& l = leds_[led_index];
  try {
    driver_->set_level(l.handle, level_for(l, on));
  } catch (const HardwareError& e) {
    throw HardwareError(describe(led_index) + ": cannot switch " + (on ? "on" : "off") + ": " +
                        e.what());
  }
  l.on = on;
}

void GpioLights::all_off() noexcept {
  if (!stop_pwm()) drive_all_off(&last_error_);
}

// Every requested line to its off level, past failures (the last one kept in *error, if given).
void GpioLights::drive_all_off(std::string* error) noexcept {
  for (size_t i = 0; i < leds_.size(); ++i) {
    Line& l = leds_[i];
    if (l.handle < 0) continue;  // Never requested (constructor failed before it).
    try {
      driver_->set_level(l.handle, level_for(l, /*on=*/false));
      l.on = false;
    } catch (const std::exception& e) {
      try {
        if (error) *error = describe(int(i)) + ": cannot switch off: " + e.what();
      } catch (...) {
      }
    } catch (...) {
    }
  }
}

void GpioLights::set_pwm_period(double seconds) {
  LS_CHECK(seconds > 0, "PWM period " + std::to_string(seconds));
  pwm_period_s_ = seconds;
}

void GpioLights::set_levels(const std::vector<double>& level) {
  stop_pwm();
  check_levels(level, num_lights(), "GPIO lights");
  pwm_stop_ = false;
  pwm_failed_ = false;
  pwm_ = std::thread(&GpioLights::run_pwm, this, level);
}

void GpioLights::verify_levels() {
  if (pwm_failed_) throw HardwareError(pwm_error_);
}

// The PWM thread. Each period: the lit LEDs' lines on, one after another, each one's time noted;
// then each off level * period after its own on (switching takes time: timed from the period's
// start, the last lines switched on would be short-changed). Periods follow each other on the
// clock, not after the last event, so that a late wake-up does not stretch them.
void GpioLights::run_pwm(const std::vector<double>& level) {
  using Clock = std::chrono::steady_clock;
  const auto seconds = [](double s) {
    return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
  };
  const auto period = seconds(pwm_period_s_);
  std::vector<std::pair<Clock::time_point, int>> offs;  // When each LED goes off, this period.
  try {
    for (auto start = Clock::now(); !pwm_stop_; start += period) {
      offs.clear();
      for (size_t led = 0; led < level.size(); ++led) {
        if (!(level[led] > 0)) continue;
        Line& l = leds_[led];
        driver_->set_level(l.handle, level_for(l, true));
        l.on = true;
        if (level[led] < 1) {
          offs.emplace_back(Clock::now() + seconds(level[led] * pwm_period_s_), int(led));
        }
      }
      std::sort(offs.begin(), offs.end());
      for (const auto& [when, led] : offs) {
        std::this_thread::sleep_until(when);
        Line& l = leds_[size_t(led)];
        driver_->set_level(l.handle, level_for(l, false));
        l.on = false;
      }
      std::this_thread::sleep_until(start + period);
    }
  } catch (const std::exception& e) {
    pwm_error_ = std::string("GPIO lights: software PWM stopped: ") + e.what();
    pwm_failed_ = true;      // After the message: verify_levels reads it once this is set.
    drive_all_off(nullptr);  // As far as the lines still switch.
  }
}

// Ends the PWM thread and leaves every line off (the next pattern starts from dark). False when
// no pattern was running (nothing done).
bool GpioLights::stop_pwm() noexcept {
  if (!pwm_.joinable()) return false;
  pwm_stop_ = true;
  try {
    pwm_.join();
  } catch (...) {
  }
  drive_all_off(&last_error_);
  return true;
}

int GpioLights::count_on() const {
  return int(std::count_if(leds_.begin(), leds_.end(), [](const Line& l) { return l.on; }));
}

std::string GpioLights::describe(int led_index) const {
  const Line& l = leds_.at(led_index);
  return "LED " + std::to_string(l.id) + " (" + l.chip + " line " + std::to_string(l.line) +
         (l.active_low ? ", active-low)" : ", active-high)");
}

// ---- The libgpiod 1.6 driver: the only code that calls libgpiod
// ----------------------------------

namespace {

std::string errno_text(const std::system_error& e) {
  return e.code().message() + " (" + e.what() + ")";
}

class GpiodLineDriver : public GpioLineDriver {
 public:
  explicit GpiodLineDriver(std::string consumer) : consumer_(std::move(consumer)) {}
  ~GpiodLineDriver() override { release_all(); }

  int request_output(const std::string& chip_name, int offset, bool initial_high) override {
    const std::string where = chip_name + " line " + std::to_string(offset);
    gpiod::chip* chip = nullptr;
    if (auto it = chips_.find(chip_name); it != chips_.end()) {
      chip = &it->second;
    } else {
      try {
        chip = &chips_.emplace(chip_name, gpiod::chip(chip_name, gpiod::chip::OPEN_LOOKUP))
                    .first->second;
      } catch (const std::system_error& e) {
        throw HardwareError("GPIO chip \"" + chip_name + "\" cannot be opened: " + errno_text(e) +
                            "; `gpiodetect` lists the chips present");
      }
    }
    if (offset < 0 || unsigned(offset) >= chip->num_lines()) {
      throw HardwareError(where + ": no such line (the chip has " +
                          std::to_string(chip->num_lines()) + " lines, 0.." +
                          std::to_string(int(chip->num_lines()) - 1) + ")");
    }
    try {
      gpiod::line line = chip->get_line(unsigned(offset));
      if (line.is_used()) {
        const std::string holder = line.consumer();
        throw HardwareError(where + ": line is busy, held by \"" +
                            (holder.empty() ? std::string("another program") : holder) +
                            "\" (see `gpioinfo " + chip_name + "`)");
      }
      gpiod::line_request request;
      request.consumer = consumer_;
      request.request_type = gpiod::line_request::DIRECTION_OUTPUT;
      line.request(request, initial_high ? 1 : 0);
      lines_.push_back(line);
      return int(lines_.size()) - 1;
    } catch (const std::system_error& e) {
      throw HardwareError(where + ": cannot request as output: " + errno_text(e));
    } catch (const std::out_of_range& e) {
      throw HardwareError(where + ": no such line: " + e.what());
    }
  }

  void set_level(int handle, bool high) override {
    LS_CHECK(handle >= 0 && size_t(handle) < lines_.size(),
             "GPIO handle " + std::to_string(handle));
    try {
      lines_[size_t(handle)].set_value(high ? 1 : 0);
    } catch (const std::system_error& e) {
      throw HardwareError("set value: " + errno_text(e));
    }
  }

  void release_all() noexcept override {
    for (auto& line : lines_) {
      try {
        line.release();
      } catch (...) {
      }
    }
    lines_.clear();
  }

 private:
  std::string consumer_;
  std::map<std::string, gpiod::chip> chips_;
  std::vector<gpiod::line> lines_;
};

}  // namespace

std::unique_ptr<GpioLineDriver> make_gpiod_line_driver(const std::string& consumer) {
  return std::make_unique<GpiodLineDriver>(consumer);
}

std::vector<std::string> list_gpio_chips() {
  std::vector<std::string> out;
  try {
    for (const auto& chip : gpiod::make_chip_iter()) {
      out.push_back(chip.name() + " [" + chip.label() + "] (" + std::to_string(chip.num_lines()) +
                    " lines)");
    }
  } catch (const std::system_error&) {
    // No /dev/gpiochip* (or no permission): nothing to list.
  }
  return out;
}

}  // namespace ls
