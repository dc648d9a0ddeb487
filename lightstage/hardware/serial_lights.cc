#include "lightstage/hardware/serial_lights.h"

#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <sstream>

#include "lightstage/errors.h"
#include "lightstage/progress.h"

namespace ls {

namespace {

constexpr int kFullLevel = 1000;
constexpr size_t kLongestReply = 256;

speed_t speed_of(int baud) {
  static const std::map<int, speed_t> kSpeeds = {
      {1200, B1200},     {2400, B2400},       {4800, B4800},       {9600, B9600},
      {19200, B19200},   {38400, B38400},     {57600, B57600},     {115200, B115200},
      {230400, B230400}, {460800, B460800},   {500000, B500000},   {576000, B576000},
      {921600, B921600}, {1000000, B1000000}, {2000000, B2000000}, {4000000, B4000000}};
  const auto it = kSpeeds.find(baud);
  return it == kSpeeds.end() ? B115200 : it->second;
}

// Replies are quoted whole (they are at most kLongestReply bytes and a line end).
constexpr std::size_t kWhole = std::string::npos;

}  // namespace

SerialLights::SerialLights(const Stage& stage)
    : port_(stage.led_driver.port), timeout_s_(stage.led_driver.timeout_s) {
  for (size_t i = 0; i < stage.leds.size(); ++i) {
    const Led& led = stage.leds[i];
    channel_of_led_.push_back(led.board_channel >= 0 ? led.board_channel : int(i));
    led_ids_.push_back(led.id);
  }
  level_of_led_.assign(channel_of_led_.size(), -1);  // Unknown until the first OFF.
  fd_ = ::open(port_.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC | O_NONBLOCK);
  if (fd_ < 0) {
    throw HardwareError("LED board on " + port_ +
                        " (led_driver.port): cannot open it: " + std::strerror(errno) +
                        (errno == EACCES ? " (is the user in the 'dialout' group?)" : ""));
  }
  try {
    start_board(stage.led_driver);
  } catch (...) {
    ::close(fd_);
    fd_ = -1;
    throw;
  }
}

void SerialLights::start_board(const LedDriverSpec& driver) {
  termios tio{};
  if (::tcgetattr(fd_, &tio) != 0) {
    throw HardwareError("LED board on " + port_ +
                        " (led_driver.port): not a serial line: " + std::strerror(errno));
  }
  ::cfmakeraw(&tio);
  tio.c_cflag |= CLOCAL | CREAD;
  tio.c_cc[VMIN] = 0;
  tio.c_cc[VTIME] = 0;
  ::cfsetispeed(&tio, speed_of(driver.baud));
  ::cfsetospeed(&tio, speed_of(driver.baud));
  ::tcsetattr(fd_, TCSANOW, &tio);
  ::tcflush(fd_, TCIOFLUSH);

  // The board may be booting (an Arduino resets when the port opens) and print a banner first:
  // ask until it answers or startup_s has passed.
  const Clock::time_point start = Clock::now();
  std::string last_reply;
  for (;;) {
    try {
      const std::string reply =
          command("ID", std::min(timeout_s_, std::max(0.05, driver.startup_s)));
      std::istringstream in(reply);
      std::string protocol;
      if (in >> protocol >> board_channels_ && protocol == driver.protocol) break;
      last_reply = "LED board on " + port_ + ": answered 'OK " + printable(reply, kWhole) +
                   "' to 'ID' (expected 'OK " + driver.protocol + " <channels>')";
    } catch (const HardwareError& e) {
      last_reply = e.what();
    }
    if (seconds_since(start) >= driver.startup_s) {
      throw HardwareError(last_reply + "; led_driver.startup_s gave it " +
                          std::to_string(driver.startup_s) + " s to start");
    }
  }
  for (size_t i = 0; i < channel_of_led_.size(); ++i) {
    if (channel_of_led_[i] >= board_channels_) {
      throw HardwareError(describe(int(i)) + ": the board has only " +
                          std::to_string(board_channels_) + " channels (leds[" + std::to_string(i) +
                          "].channel)");
    }
  }
  command("OFF", timeout_s_);
  level_of_led_.assign(channel_of_led_.size(), 0);
}

SerialLights::~SerialLights() {
  all_off();
  if (fd_ >= 0) ::close(fd_);
}

std::string SerialLights::describe(int led_index) const {
  return "LED " + std::to_string(led_ids_.at(size_t(led_index))) + " (board channel " +
         std::to_string(channel_of_led_.at(size_t(led_index))) + " on " + port_ + ")";
}

void SerialLights::write_all(const std::string& bytes) {
  size_t done = 0;
  const Clock::time_point start = Clock::now();
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n > 0) {
      done += size_t(n);
      continue;
    }
    if (n < 0 && errno != EAGAIN && errno != EINTR) {
      throw HardwareError("LED board on " + port_ + ": writing '" + printable(bytes, kWhole) +
                          "' failed: " + std::strerror(errno) + " (unplugged?)");
    }
    if (seconds_since(start) > timeout_s_) {
      throw HardwareError("LED board on " + port_ + ": the line did not take '" +
                          printable(bytes, kWhole) + "' within " + std::to_string(timeout_s_) +
                          " s");
    }
    pollfd p{fd_, POLLOUT, 0};
    ::poll(&p, 1, 10);
  }
}

std::string SerialLights::read_line(double timeout_s, const std::string& sent) {
  const Clock::time_point start = Clock::now();
  for (;;) {
    const size_t end = pending_.find('\n');
    if (end != std::string::npos) {
      std::string line = pending_.substr(0, end);
      pending_.erase(0, end + 1);
      if (!line.empty() && line.back() == '\r') line.pop_back();
      return line;
    }
    if (pending_.size() > kLongestReply) {
      const std::string shown = printable(pending_.substr(0, 64), kWhole);
      pending_.clear();
      throw HardwareError("LED board on " + port_ + ": answered '" + shown + "...' to '" + sent +
                          "' (no line end: wrong baud rate or not an lsled1 board?)");
    }
    const double left = timeout_s - seconds_since(start);
    if (left <= 0) {
      throw HardwareError(
          "LED board on " + port_ + ": no answer to '" + sent + "' within " +
          std::to_string(timeout_s) + " s (led_driver.timeout_s)" +
          (pending_.empty() ? "" : "; it sent '" + printable(pending_, kWhole) + "'"));
    }
    pollfd p{fd_, POLLIN, 0};
    const int ready = ::poll(&p, 1, int(std::ceil(left * 1000)));
    if (ready > 0 && (p.revents & (POLLHUP | POLLERR)) && !(p.revents & POLLIN)) {
      throw HardwareError("LED board on " + port_ + ": the line closed (unplugged?) after '" +
                          sent + "'");
    }
    if (ready <= 0) continue;
    char buffer[256];
    const ssize_t n = ::read(fd_, buffer, sizeof buffer);
    if (n > 0) pending_.append(buffer, size_t(n));
    if (n < 0 && errno != EAGAIN && errno != EINTR) {
      throw HardwareError("LED board on " + port_ + ": reading failed after '" + sent +
                          "': " + std::strerror(errno) + " (unplugged?)");
    }
  }
}

std::string SerialLights::command(const std::string& line, double timeout_s) {
  write_all(line + "\n");
  const std::string reply = read_line(timeout_s, line);
  if (reply == "OK") return "";
  if (reply.rfind("OK ", 0) == 0) return reply.substr(3);
  throw HardwareError(
      "LED board on " + port_ + ": answered '" + printable(reply, kWhole) + "' to '" + line + "'" +
      (reply.rfind("ERR", 0) == 0 ? "" : " (expected OK or ERR: not an lsled1 board?)"));
}

void SerialLights::set_light(int led_index, bool on) {
  if (led_index < 0 || led_index >= num_lights()) {
    throw HardwareError("LED board on " + port_ + ": no LED at index " + std::to_string(led_index));
  }
  const int level = on ? kFullLevel : 0;
  try {
    command(
        "SET " + std::to_string(channel_of_led_[size_t(led_index)]) + " " + std::to_string(level),
        timeout_s_);
  } catch (const HardwareError& e) {
    level_of_led_[size_t(led_index)] = -1;
    throw HardwareError(describe(led_index) + ": " + e.what());
  }
  level_of_led_[size_t(led_index)] = level;
}

void SerialLights::set_levels(const std::vector<double>& level) {
  check_levels(level, num_lights(), "LED board on " + port_);
  for (int i = 0; i < num_lights(); ++i) {
    const int value = int(std::lround(level[size_t(i)] * kFullLevel));
    if (value == level_of_led_[size_t(i)]) continue;
    command("SET " + std::to_string(channel_of_led_[size_t(i)]) + " " + std::to_string(value),
            timeout_s_);
    level_of_led_[size_t(i)] = value;
  }
}

void SerialLights::all_off() noexcept {
  if (fd_ < 0) return;
  try {
    command("OFF", timeout_s_);
    std::fill(level_of_led_.begin(), level_of_led_.end(), 0);
  } catch (const std::exception&) {
    // Nothing more to do from here: the error reached whoever asked the board last.
  }
}

}  // namespace ls
