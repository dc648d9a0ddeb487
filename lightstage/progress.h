#pragma once
// Progress for long work, on stderr: a live bar on a terminal ("capture [#####     ] 120/453
// 26% 0:14 left"), a line per 10% otherwise (logs, CI). Thread-safe; at most ~10 updates a second.
#include <chrono>
#include <mutex>
#include <string>

namespace ls {

class ProgressReporter {
 public:
  ProgressReporter(std::string title, long total, bool quiet = false);
  ~ProgressReporter();  // Finishes the line.
  void update(long done, const std::string& detail = "");
  void done(const std::string& summary = "");

 private:
  void print(long done, const std::string& detail, bool final);
  std::string title_;
  long total_;
  bool quiet_;
  bool tty_;
  bool finished_ = false;
  int last_decile_ = -1;
  std::chrono::steady_clock::time_point start_, last_print_;
  std::mutex mutex_;
};

}  // namespace ls
