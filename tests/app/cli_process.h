#pragma once
// Running the lightstage executable as a separate process, as a user does: for tests that kill,
// interrupt or starve it.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include "lightstage/image.h"
#include "lightstage/stage.h"

namespace ls::testing {

inline std::string Slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

inline int CountLines(const std::filesystem::path& p) {
  std::ifstream in(p);
  int n = 0;
  std::string line;
  while (std::getline(in, line)) n += !line.empty();
  return n;
}

// A stage small enough to capture in a few seconds, exposing in real time (about 1.7 s in all) so
// that a test can stop it part-way.
inline std::filesystem::path WriteSmallStage(const std::filesystem::path& dir) {
  Stage stage = stage_with_directions(fibonacci_dome_directions(30, -10));
  stage.camera.width = stage.camera.height = 48;
  stage.camera.simulated.real_time = true;
  write_file_atomic(dir / "stage.json", stage_to_json(stage));
  return dir / "stage.json";
}

// Starts the command with stderr to `stderr_file` (or /dev/null); returns its pid.
inline pid_t Spawn(const std::vector<std::string>& args,
                   const std::filesystem::path& stderr_file = "/dev/null") {
  const pid_t pid = fork();
  if (pid == 0) {
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    if (!freopen(stderr_file.c_str(), "w", stderr)) _exit(126);
    execv(argv[0], argv.data());
    _exit(127);
  }
  return pid;
}

// Waits until the session's journal has at least n lines (or the process ends).
inline void WaitForFrames(const std::filesystem::path& session, int n, pid_t pid) {
  for (int i = 0; i < 2000; ++i) {
    if (CountLines(session / "frames.jsonl") >= n) return;
    int status;
    if (waitpid(pid, &status, WNOHANG) == pid) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

}  // namespace ls::testing
