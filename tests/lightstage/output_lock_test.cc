// One writer per output (OutputLock), and nothing left by a run that fails (RunOutputs).
#include "lightstage/output_lock.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>

#include "lightstage/errors.h"
#include "lightstage/run_outputs.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

namespace fs = std::filesystem;

// Runs `body` in a child process; its exit code.
template <class Body>
int InChild(Body body) {
  const pid_t pid = fork();
  if (pid == 0) _exit(body());
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(OutputLock, ASecondWriterIsRefusedNamingTheFirstAndTheLockFileGoesWithTheLock) {
  testing::TempDir tmp;
  const fs::path out = tmp / "new" / "field.exr";
  const std::string holder = "(process " + std::to_string(getpid()) + ")";
  {
    const OutputLock lock(out);
    EXPECT_TRUE(fs::exists(tmp / "new" / "field.exr.lock"));
    EXPECT_EQ(InChild([&] {
                try {
                  const OutputLock second(out);
                  return 1;
                } catch (const InputError& e) {
                  const std::string msg = e.what();
                  return msg.find(out.string()) != std::string::npos &&
                                 msg.find(holder) != std::string::npos
                             ? 0
                             : 2;
                }
              }),
              0);
  }
  EXPECT_FALSE(fs::exists(tmp / "new" / "field.exr.lock"));
  EXPECT_EQ(InChild([&] {
              const OutputLock again(out);
              return 0;
            }),
            0);
  // A folder output ("dir/") locks as "dir".
  const OutputLock folder(tmp / "relit/");
  EXPECT_TRUE(fs::exists(tmp / "relit.lock"));
}

TEST(OutputLock, HolderSaysWhoHoldsALockWithoutTakingIt) {
  testing::TempDir tmp;
  EXPECT_FALSE(WriterLock::holder(tmp / "none.lock").has_value());
  {
    const WriterLock lock(tmp / "x.lock", "busy", "", /*remove_file=*/false);
    EXPECT_EQ(InChild([&] { return WriterLock::holder(tmp / "x.lock") == getppid() ? 0 : 1; }), 0);
  }
  EXPECT_FALSE(WriterLock::holder(tmp / "x.lock").has_value());
}

TEST(RunOutputs, AFailedRunRemovesTheFolderItMadeOrTheFilesItWrote) {
  testing::TempDir tmp;
  {
    RunOutputs outputs(tmp / "made");
    fs::create_directories(tmp / "made");
    std::ofstream(tmp / "made" / "a.png") << "a";
  }
  EXPECT_FALSE(fs::exists(tmp / "made"));
  fs::create_directories(tmp / "there");
  std::ofstream(tmp / "there" / "mine.txt") << "kept";
  {
    RunOutputs outputs(tmp / "there");
    outputs.add(tmp / "there" / "b.png");
    std::ofstream(tmp / "there" / "b.png") << "b";
  }
  EXPECT_TRUE(fs::exists(tmp / "there" / "mine.txt"));
  EXPECT_FALSE(fs::exists(tmp / "there" / "b.png"));
  {
    RunOutputs outputs(tmp / "done");
    fs::create_directories(tmp / "done");
    outputs.keep();
  }
  EXPECT_TRUE(fs::exists(tmp / "done"));
}

TEST(RunOutputs, AFailedRunRemovesTheFoldersItMadeAboveItsOwnAndTheFoldersItWasToldOf) {
  testing::TempDir tmp;
  {
    RunOutputs outputs(tmp / "a" / "b" / "out/");
    fs::create_directories(tmp / "a" / "b" / "out" / "frames");
  }
  EXPECT_FALSE(fs::exists(tmp / "a"));
  fs::create_directories(tmp / "mine");
  {
    RunOutputs outputs(tmp / "mine");
    outputs.add(tmp / "mine" / "frames");
    fs::create_directories(tmp / "mine" / "frames");
    std::ofstream(tmp / "mine" / "frames" / "f.png") << "f";
  }
  EXPECT_TRUE(fs::exists(tmp / "mine"));
  EXPECT_FALSE(fs::exists(tmp / "mine" / "frames"));
}

}  // namespace
}  // namespace ls
