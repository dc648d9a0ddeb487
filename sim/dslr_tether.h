#pragma once
// A DSLR as libgphoto2 would show it, in software: the Tether (lightstage/hardware/tether.h) of the
// simulated DSLR dome. Its shots are the simulated stage's frames at the shutter speed and ISO set
// on it, written as DNG files behind a Bayer filter (dng_file.h); the files appear as events, a
// while after the shot in real time; it can be busy, lose a file, or vanish mid-session.
#include <chrono>
#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "lightstage/hardware/tether.h"

namespace ls::sim {

class SimulatedDslr : public Tether {
 public:
  // `sensor` renders the frames (3 channels, DN of `raw_bits`, the given black level in DN); it
  // must outlive this. `real_time`: a shot takes its exposure plus `shot_overhead_s` (mirror,
  // card write) before its file appears; otherwise at once.
  // `pixel_sites` (bayer_mosaic): 2 when the files are to be binned 2x2.
  SimulatedDslr(Camera& sensor, int raw_bits, unsigned black_level_dn, int pixel_sites,
                bool real_time, double shot_overhead_s = 0.4);

  std::string describe() const override { return "lightstage simulated DSLR (sim:usb)"; }
  std::optional<TetherSetting> setting(const std::string& name) override;
  void set_setting(const std::string& name, const std::string& value) override;
  void prepare(const FrameRequest& request) override { next_ = request; }
  void trigger() override;
  TetherEvent wait_event(double timeout_s) override;
  std::vector<std::uint8_t> download(const TetherFile& file) override;
  void remove(const TetherFile& file) override;

  // Faults, as real cameras show them.
  // The camera vanishes at the next trigger after this many shots: every call fails from then on.
  void disconnect_after_shots(int shots) { disconnect_after_ = shots; }
  void lose_file_of_shot(int shot) { lost_shot_ = shot; }  // Its file never appears (1-based).
  void busy_for_triggers(int triggers) { busy_triggers_ = triggers; }  // TetherBusy this often.
  int shots() const { return shots_; }
  size_t files_on_card() const { return card_.size(); }

 private:
  using Clock = std::chrono::steady_clock;
  void require_connected() const;

  Camera& sensor_;
  int raw_bits_;
  unsigned black_level_dn_;
  int pixel_sites_;
  bool real_time_;
  double shot_overhead_s_;
  std::map<std::string, TetherSetting> settings_;
  FrameRequest next_;
  int shots_ = 0;
  int disconnect_after_ = -1;
  bool gone_ = false;
  int lost_shot_ = -1;
  int busy_triggers_ = 0;
  struct Pending {
    Clock::time_point ready;
    TetherEvent event;
  };
  std::deque<Pending> events_;
  std::map<std::string, std::vector<std::uint8_t>> card_;  // By file name.
};

}  // namespace ls::sim
