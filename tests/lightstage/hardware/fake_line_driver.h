#pragma once
// A GPIO line driver that records levels, for testing GpioLights without a GPIO chip.
#include <atomic>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "lightstage/errors.h"
#include "lightstage/hardware/gpiod_lights.h"

namespace ls::testing {

struct FakeGpio {
  std::set<std::string> chips{"gpiochip0"};
  int lines_per_chip = 32;
  std::map<std::pair<std::string, int>, std::string> held_by_others;
  std::map<std::pair<std::string, int>, bool> level;  // Requested lines and their level.
  std::set<int> failing_handles;                      // set_level throws for these.
  int releases = 0;
  std::atomic<int> sets{0};  // set_level calls (software PWM runs them on its own thread).
  // Called on every set_level with the line and its new level: what is wired to the line.
  std::function<void(const std::pair<std::string, int>& line, bool high)> wire;
};

class FakeLineDriver : public GpioLineDriver {
 public:
  explicit FakeLineDriver(FakeGpio& gpio) : gpio_(gpio) {}
  int request_output(const std::string& chip, int line, bool initial_high) override {
    if (!gpio_.chips.count(chip)) throw HardwareError("GPIO chip \"" + chip + "\" not found");
    if (line >= gpio_.lines_per_chip) throw HardwareError("no such line");
    const auto key = std::make_pair(chip, line);
    if (auto it = gpio_.held_by_others.find(key); it != gpio_.held_by_others.end()) {
      throw HardwareError("line is busy, held by \"" + it->second + "\"");
    }
    gpio_.level[key] = initial_high;
    handles_.push_back(key);
    return int(handles_.size()) - 1;
  }
  void set_level(int handle, bool high) override {
    if (gpio_.failing_handles.count(handle)) throw HardwareError("EIO");
    gpio_.level[handles_.at(handle)] = high;
    ++gpio_.sets;
    if (gpio_.wire) gpio_.wire(handles_.at(handle), high);
  }
  void release_all() noexcept override {
    for (const auto& key : handles_) gpio_.level.erase(key);
    handles_.clear();
    ++gpio_.releases;
  }

 private:
  FakeGpio& gpio_;
  std::vector<std::pair<std::string, int>> handles_;
};

}  // namespace ls::testing
