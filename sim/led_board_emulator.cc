#include "sim/led_board_emulator.h"

#include <fcntl.h>
#include <poll.h>
#include <stdlib.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <sstream>

#include "lightstage/errors.h"

namespace ls::sim {

LedBoardEmulator::LedBoardEmulator(int channels, std::function<void(int, double)> set_channel,
                                   std::function<void()> all_off)
    : channels_(channels), set_channel_(std::move(set_channel)), all_off_(std::move(all_off)) {
  master_ = ::posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
  char name[128] = {};
  if (master_ < 0 || ::grantpt(master_) != 0 || ::unlockpt(master_) != 0 ||
      ::ptsname_r(master_, name, sizeof name) != 0) {
    const std::string why = std::strerror(errno);
    if (master_ >= 0) ::close(master_);
    throw HardwareError("LED board emulator: no pseudo-terminal: " + why);
  }
  port_ = name;
  slave_ = ::open(name, O_RDWR | O_NOCTTY | O_CLOEXEC);
  thread_ = std::thread([this] { run(); });
}

LedBoardEmulator::~LedBoardEmulator() {
  stop_ = true;
  thread_.join();
  if (slave_ >= 0) ::close(slave_);
  ::close(master_);
}

void LedBoardEmulator::change_after(int commands, Behaviour then) {
  change_to_ = then;
  change_in_ = commands;
}

std::string LedBoardEmulator::answer(const std::string& line) {
  std::istringstream in(line);
  std::string verb;
  in >> verb;
  if (verb == "ID") return "OK lsled1 " + std::to_string(channels_);
  if (verb == "OFF") {
    all_off_();
    return "OK";
  }
  if (verb == "SET") {
    int channel = -1, level = -1;
    if (!(in >> channel >> level) || channel < 0 || channel >= channels_ || level < 0 ||
        level > 1000) {
      return "ERR SET needs a channel 0.." + std::to_string(channels_ - 1) + " and a level 0..1000";
    }
    set_channel_(channel, level / 1000.0);
    return "OK";
  }
  return "ERR unknown command";
}

void LedBoardEmulator::run() {
  std::string pending;
  while (!stop_) {
    pollfd p{master_, POLLIN, 0};
    if (::poll(&p, 1, 20) <= 0 || !(p.revents & POLLIN)) continue;
    char buffer[256];
    const ssize_t n = ::read(master_, buffer, sizeof buffer);
    if (n <= 0) continue;
    pending.append(buffer, size_t(n));
    for (size_t end; (end = pending.find('\n')) != std::string::npos;) {
      std::string line = pending.substr(0, end);
      pending.erase(0, end + 1);
      if (!line.empty() && line.back() == '\r') line.pop_back();
      ++commands_seen_;
      if (change_in_ >= 0 && change_in_-- == 0) behaviour_ = change_to_.load();
      std::string reply;
      switch (behaviour_.load()) {
        case Behaviour::kAnswers:
          reply = answer(line) + "\n";
          break;
        case Behaviour::kSilent:
          break;
        case Behaviour::kGarbage:
          reply = "\x7f~\x03#K\xfe\n";
          break;
      }
      if (!reply.empty() && ::write(master_, reply.data(), reply.size()) < 0) return;
    }
  }
}

}  // namespace ls::sim
