#include "lightstage/progress.h"

#include <unistd.h>

#include <cstdio>

namespace ls {

ProgressReporter::ProgressReporter(std::string title, long total, bool quiet)
    : title_(std::move(title)),
      total_(total > 0 ? total : 1),
      quiet_(quiet),
      tty_(isatty(STDERR_FILENO)),
      start_(std::chrono::steady_clock::now()) {}

ProgressReporter::~ProgressReporter() {
  if (!finished_) done();
}

void ProgressReporter::update(long done, const std::string& detail) {
  std::lock_guard lock(mutex_);
  if (quiet_ || finished_) return;
  const auto now = std::chrono::steady_clock::now();
  if (tty_) {
    if (now - last_print_ < std::chrono::milliseconds(100) && done < total_) return;
  } else {
    const int decile = int(10 * done / total_);
    if (decile == last_decile_) return;
    last_decile_ = decile;
  }
  last_print_ = now;
  print(done, detail, false);
}

void ProgressReporter::done(const std::string& summary) {
  std::lock_guard lock(mutex_);
  if (finished_) return;
  finished_ = true;
  if (quiet_) return;
  print(total_, summary, true);
}

void ProgressReporter::print(long done, const std::string& detail, bool final) {
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const double fraction = double(done) / total_;
  char timing[48];
  if (final) {
    std::snprintf(timing, sizeof timing, "%.1f s", elapsed);
  } else if (fraction > 0.01) {
    const int left = int(elapsed / fraction * (1 - fraction) + 0.5);
    std::snprintf(timing, sizeof timing, "%d:%02d left", left / 60, left % 60);
  } else {
    std::snprintf(timing, sizeof timing, "...");
  }
  constexpr int kWidth = 24;
  const int filled = int(fraction * kWidth + 0.5);
  std::string bar(filled, '#');
  bar.resize(kWidth, ' ');
  std::fprintf(stderr, "%s%-10s [%s] %ld/%ld %3d%% %s %s%s", tty_ ? "\r\033[K" : "", title_.c_str(),
               bar.c_str(), done, total_, int(100 * fraction + 0.5), timing, detail.c_str(),
               (final || !tty_) ? "\n" : "");
  std::fflush(stderr);
}

}  // namespace ls
