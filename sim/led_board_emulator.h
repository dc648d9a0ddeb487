#pragma once
// A serial LED board in software: the far end of a pseudo-terminal pair, speaking the lsled1
// protocol (lightstage/hardware/serial_lights.h) and driving whatever the caller wires to it (the
// simulated stage's LEDs), as a microcontroller drives its outputs. For the tests and the simulated
// DSLR dome; it can also stop answering or answer garbage, as broken boards do.
#include <atomic>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

namespace ls::sim {

class LedBoardEmulator {
 public:
  enum class Behaviour { kAnswers, kSilent, kGarbage };
  // `set_channel(channel, level)`: level in [0, 1]; `all_off()`: every channel off. Both run on
  // the emulator's thread, before the board's reply is sent.
  LedBoardEmulator(int channels, std::function<void(int, double)> set_channel,
                   std::function<void()> all_off);
  ~LedBoardEmulator();
  LedBoardEmulator(const LedBoardEmulator&) = delete;
  LedBoardEmulator& operator=(const LedBoardEmulator&) = delete;

  // The board's device, for a stage file's led_driver.port (/dev/pts/N).
  const std::string& port() const { return port_; }
  void set_behaviour(Behaviour behaviour) { behaviour_ = behaviour; }
  // Answers this many more commands, then behaves as `then`.
  void change_after(int commands, Behaviour then);
  int commands_seen() const { return commands_seen_; }

 private:
  void run();
  std::string answer(const std::string& line);

  int channels_;
  std::function<void(int, double)> set_channel_;
  std::function<void()> all_off_;
  int master_ = -1;
  int slave_ = -1;  // Held open so that the master never sees a hang-up between clients.
  std::string port_;
  std::atomic<Behaviour> behaviour_{Behaviour::kAnswers};
  std::atomic<int> change_in_{-1};
  std::atomic<Behaviour> change_to_{Behaviour::kAnswers};
  std::atomic<int> commands_seen_{0};
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace ls::sim
