#include "capture/build_checkpoint.h"

#include <fstream>
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
                        {"floor_level", options.merge.floor_level}}
      .dump();
}

fs::path led_file(const fs::path& dir, int light) { return dir / ("led_" + std::to_string(light)); }

}  // namespace

BuildCheckpoint::BuildCheckpoint(const fs::path& out, const Session& session,
                                 const BuildOptions& options)
    : dir_(out, identity_of(session, options)) {}

std::optional<BuildCheckpoint::Led> BuildCheckpoint::load(int light) const {
  std::ifstream in(led_file(dir_.dir(), light), std::ios::binary);
  if (!in) return std::nullopt;
  Led led;
  try {
    std::string magic, header;
    if (!std::getline(in, magic) || magic != kLedMagic || !std::getline(in, header)) {
      return std::nullopt;
    }
    const nlohmann::json info = nlohmann::json::parse(header);
    led.saturated = info.at("saturated").get<long long>();
    led.transfer.resize(info.at("transfer").get<std::size_t>());
  } catch (const nlohmann::json::exception&) {
    return std::nullopt;
  }
  const auto bytes = std::streamsize(led.transfer.size() * sizeof(TransferSample));
  if (!in.read(reinterpret_cast<char*>(led.transfer.data()), bytes) ||
      in.peek() != std::char_traits<char>::eof()) {
    return std::nullopt;  // Cut short or longer: merged again.
  }
  return led;
}

void BuildCheckpoint::save(int light, const Led& led) const {
  AtomicFileWriter out(led_file(dir_.dir(), light));
  const std::string header =
      std::string(kLedMagic) + "\n" +
      nlohmann::json{{"saturated", led.saturated}, {"transfer", led.transfer.size()}}.dump() + "\n";
  out.write(header.data(), header.size());
  out.write(led.transfer.data(), led.transfer.size() * sizeof(TransferSample));
  out.commit();
}

}  // namespace ls::capture
