#include "evaluation/bench_support.h"

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <iterator>

#include "capture/build_field.h"
#include "lightstage/controller/sequencer.h"
#include "lightstage/errors.h"
#include "lightstage/session.h"
#include "sim/sim_stage.h"

namespace ls::evaluation {

namespace fs = std::filesystem;

using Clock = std::chrono::steady_clock;

capture::ReflectanceField capture_sim_field(const Stage& stage, const sim::Scene& scene,
                                            const fs::path& session_dir, const std::string& phase,
                                            const ProgressFn& progress) {
  fs::remove_all(session_dir);
  capture::ReflectanceField field;
  {
    Session session = Session::create(session_dir, stage, {"sim", "", 1});
    sim::SimStage sim_stage(stage, scene, 1);
    const long total = long(plan_frames(stage).size());
    SequencerOptions options;
    options.sleep = [](double) {};
    options.on_progress = [&](const std::string&, long done, long, const std::string&) {
      if (done < total) report(progress, phase, done, total);
    };
    run_capture(session, sim_stage.lights(), sim_stage.camera(), options);
    report(progress, phase, total, total);
    field = capture::build_field(session, {});
  }
  fs::remove_all(session_dir);
  return field;
}

Measured run_process(const std::vector<std::string>& argv, const fs::path& log) {
  std::vector<char*> args;
  args.reserve(argv.size() + 1);
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const std::string log_name = log.string();
  const auto t0 = Clock::now();
  const pid_t pid = fork();
  if (pid < 0) throw InputError("bench: cannot start " + argv[0]);
  if (pid == 0) {  // Only async-signal-safe calls until exec.
    const int fd = open(log_name.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) dup2(fd, 1), dup2(fd, 2);
    execvp(args[0], args.data());
    _exit(127);
  }
  int status = 0;
  rusage usage{};
  wait4(pid, &status, 0, &usage);
  Measured m{std::chrono::duration<double>(Clock::now() - t0).count(),
             double(usage.ru_maxrss) / 1024.0,
             {}};
  std::ifstream printed(log);
  m.output.assign(std::istreambuf_iterator<char>(printed), std::istreambuf_iterator<char>());
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::string command;
    for (const std::string& a : argv) command += a + " ";
    throw InputError("bench: '" + command + "' failed (exit " +
                     std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) + "): see " +
                     log_name);
  }
  return m;
}

std::vector<physics::EnvironmentMap> load_maps(const std::vector<fs::path>& paths) {
  std::vector<physics::EnvironmentMap> maps;
  maps.reserve(paths.size());
  for (const fs::path& path : paths) maps.push_back(physics::EnvironmentMap::load(path));
  return maps;
}

void throw_if_invalid(const std::string& error) {
  if (!error.empty()) throw InputError(error);
}

}  // namespace ls::evaluation
