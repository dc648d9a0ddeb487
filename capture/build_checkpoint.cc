#include "capture/build_checkpoint.h"

#include <nlohmann/json.hpp>
#include <type_traits>

#include "lightstage/image.h"
#include "lightstage/stage.h"

namespace ls::capture {

namespace fs = std::filesystem;

namespace {

constexpr const char* kLedMagic = "lightstage build led 1";
static_assert(std::is_trivially_copyable_v<TransferSample>);

// What must match for an earlier run's LEDs to be reused: the session (its stage, and every
// frame as saved: file, size, CRC) and the options that change the merge.
std::string identity_of(const Session& session, const BuildOptions& options) {
  nlohmann::json frames = nlohmann::json::array();
  for (const auto& [key, record] : session.frames()) {
    frames.push_back({record.file, record.bytes, record.crc32, record.exposure_s, record.gain});
  }
  return nlohmann::json{{"session", fs::absolute(session.dir()).string()},
                        {"stage", stage_to_json(session.stage())},
                        {"frames", frames},
                        {"time_step", options.time_step},
                        {"saturation_level", options.merge.saturation_level},
                        {"floor_level", options.merge.floor_level},
                        {"correct_drift", options.correct_drift}}
      .dump();
}

fs::path led_file(const fs::path& dir, int light) { return dir / ("led_" + std::to_string(light)); }

}  // namespace

BuildCheckpoint::BuildCheckpoint(const fs::path& out, const Session& session,
                                 const BuildOptions& options)
    : dir_(out, identity_of(session, options)) {}

std::optional<BuildCheckpoint::Led> BuildCheckpoint::load(int light) const {
  Led led;
  const bool read =
      read_record(led_file(dir_.dir(), light), kLedMagic, [&](const nlohmann::json& info) {
        led.saturated = info.at("saturated").get<long long>();
        led.transfer.resize(info.at("transfer").get<std::size_t>());
        return std::optional<std::vector<RecordTarget>>{
            {{led.transfer.data(), led.transfer.size() * sizeof(TransferSample)}}};
      });
  if (!read) return std::nullopt;  // Missing, cut short or longer: merged again.
  return led;
}

void BuildCheckpoint::save(int light, const Led& led) const {
  write_record(led_file(dir_.dir(), light), kLedMagic,
               {{"saturated", led.saturated}, {"transfer", led.transfer.size()}},
               {{led.transfer.data(), led.transfer.size() * sizeof(TransferSample)}});
}

}  // namespace ls::capture
