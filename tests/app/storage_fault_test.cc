// A disk that fills up, before and during a capture, and a session directory that cannot be
// written. Each test mounts a small tmpfs; CTest runs this binary inside a private mount namespace
// (`unshare -m`), so the mounts are invisible to the rest of the machine and vanish with it.
#include <gtest/gtest.h>
#include <sys/mount.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "lightstage/image.h"
#include "lightstage/session.h"
#include "tests/app/cli_process.h"
#include "tests/support/test_support.h"

namespace ls {
namespace {

namespace fs = std::filesystem;
using testing::cli_path;
using testing::CountLines;
using testing::run_command;
using testing::Slurp;
using testing::Spawn;
using testing::WaitForFrames;
using testing::WriteSmallStage;

// A tmpfs of `size` at dir, unmounted when the test ends.
class SmallDisk {
 public:
  SmallDisk(const fs::path& dir, const std::string& size) : dir_(dir) {
    fs::create_directories(dir);
    const std::string options = "size=" + size;
    mounted_ = ::mount("tmpfs", dir.c_str(), "tmpfs", 0, options.c_str()) == 0;
  }
  ~SmallDisk() {
    if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
  }
  bool mounted() const { return mounted_; }
  bool make_read_only() {
    return ::mount(nullptr, dir_.c_str(), nullptr, MS_REMOUNT | MS_RDONLY, nullptr) == 0;
  }
  bool resize(const std::string& size) {
    const std::string options = "size=" + size;
    return ::mount(nullptr, dir_.c_str(), nullptr, MS_REMOUNT, options.c_str()) == 0;
  }

 private:
  fs::path dir_;
  bool mounted_ = false;
};

// Fills the disk holding dir until a write fails; returns the filler file.
fs::path FillDisk(const fs::path& dir) {
  const fs::path filler = dir / "filler";
  std::ofstream out(filler, std::ios::binary);
  const std::string block(64 * 1024, 'x');
  while (out.write(block.data(), block.size()) && out.flush()) {
  }
  return filler;
}

// Fills the disk holding dir but for about free_kib KiB; returns the filler file.
fs::path FillDiskLeaving(const fs::path& dir, int free_kib) {
  const fs::path filler = FillDisk(dir);
  const uintmax_t size = fs::file_size(filler), room = uintmax_t(free_kib) * 1024;
  fs::resize_file(filler, size > room ? size - room : 0);
  return filler;
}

TEST(StorageFault, CaptureThatCannotFitIsRefusedBeforeItStarts) {
  testing::TempDir tmp;
  const fs::path stage = WriteSmallStage(tmp.path());
  SmallDisk disk(tmp / "disk", "512k");  // The capture needs ~2.4 MiB at worst.
  ASSERT_TRUE(disk.mounted()) << "mount(tmpfs) failed: run inside unshare -m as root";
  std::string out;
  const int code = run_command(cli_path().string() + " capture --quiet --stage " + stage.string() +
                                   " --out " + (tmp / "disk" / "s").string(),
                               &out);
  EXPECT_EQ(code, 4) << out;
  EXPECT_NE(out.find("frames still to capture need up to"), std::string::npos) << out;
  EXPECT_NE(out.find((tmp / "disk" / "s").string()), std::string::npos) << out;
  EXPECT_EQ(CountLines(tmp / "disk" / "s" / "frames.jsonl"), 0) << "nothing may be captured";
}

TEST(StorageFault, ReadOnlySessionDiskIsRefusedBeforeCapture) {
  testing::TempDir tmp;
  const fs::path stage = WriteSmallStage(tmp.path());
  SmallDisk disk(tmp / "disk", "8m");
  ASSERT_TRUE(disk.mounted()) << "mount(tmpfs) failed: run inside unshare -m as root";
  ASSERT_TRUE(disk.make_read_only());
  std::string out;
  const int code = run_command(cli_path().string() + " capture --quiet --stage " + stage.string() +
                                   " --out " + (tmp / "disk" / "s").string(),
                               &out);
  EXPECT_EQ(code, 4) << out;
  EXPECT_NE(out.find((tmp / "disk" / "s").string()), std::string::npos) << out;
}

// The disk fills up part-way: the capture stops with exit 4, all LEDs off, every journaled frame
// intact on disk and nothing half-written counted; once space is freed, --resume completes to
// exactly the frames of an uninterrupted capture.
TEST(StorageFault, DiskFullDuringCaptureStopsCleanlyAndResumes) {
  testing::TempDir tmp;
  const fs::path stage = WriteSmallStage(tmp.path());
  const std::string cli = cli_path().string();
  std::string out;
  ASSERT_EQ(run_command(cli + " capture --quiet --stage " + stage.string() + " --out " +
                            (tmp / "whole").string(),
                        &out),
            0)
      << out;

  SmallDisk disk(tmp / "disk", "8m");
  ASSERT_TRUE(disk.mounted()) << "mount(tmpfs) failed: run inside unshare -m as root";
  const fs::path session_dir = tmp / "disk" / "s";
  const fs::path log = tmp / "capture.log";
  const pid_t pid = Spawn(
      {cli, "capture", "--quiet", "--stage", stage.string(), "--out", session_dir.string()}, log);
  WaitForFrames(session_dir, 30, pid);
  const fs::path filler = FillDisk(tmp / "disk");
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid) << "capture finished before the disk filled up";
  ASSERT_TRUE(WIFEXITED(status));
  const std::string messages = Slurp(log);
  EXPECT_EQ(WEXITSTATUS(status), 4) << messages;
  EXPECT_NE(messages.find("storage failure"), std::string::npos) << messages;
  EXPECT_NE(messages.find("--resume " + session_dir.string()), std::string::npos) << messages;

  // What the journal lists is on disk, whole, and nothing else is counted.
  const Session stopped = Session::open(session_dir);
  const size_t planned = plan_frames(stopped.stage()).size();
  ASSERT_GE(stopped.frames().size(), 20u);
  ASSERT_LT(stopped.frames().size(), planned) << "the disk filled up after the capture ended";
  for (const auto& [key, record] : stopped.frames()) {
    EXPECT_EQ(Slurp(session_dir / record.file), Slurp(tmp / "whole" / record.file)) << record.file;
  }

  fs::remove(filler);
  ASSERT_EQ(run_command(cli + " capture --quiet --resume " + session_dir.string(), &out), 0) << out;
  const Session resumed = Session::open(session_dir);
  ASSERT_EQ(resumed.frames().size(), planned);
  for (const auto& [key, record] : resumed.frames()) {
    ASSERT_EQ(Slurp(session_dir / record.file), Slurp(tmp / "whole" / record.file)) << record.file;
  }
  std::set<std::string> files;
  for (const auto& e : fs::directory_iterator(session_dir / "frames")) {
    files.insert(e.path().filename().string());
  }
  EXPECT_EQ(files.size(), planned) << "stray or temporary files left in frames/";
  EXPECT_NE(Slurp(session_dir / "manifest.json").find("\"complete\""), std::string::npos);
}

// What is on the disk at dir, by name.
std::set<std::string> Listing(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

// A field built off the small disk, for the commands that write onto it.
fs::path CaptureAndBuild(const testing::TempDir& tmp) {
  const fs::path stage = WriteSmallStage(tmp.path());
  const std::string cli = cli_path().string();
  std::string out;
  EXPECT_EQ(run_command(cli + " capture --quiet --stage " + stage.string() + " --out " +
                            (tmp / "s").string(),
                        &out),
            0)
      << out;
  EXPECT_EQ(run_command(cli + " build --quiet " + (tmp / "s").string() + " --out " +
                            (tmp / "f.exr").string(),
                        &out),
            0)
      << out;
  return tmp / "f.exr";
}

// An .lp set of 8-bit PNGs: a lit-from-the-light gradient per image, eight lights on a cone.
fs::path WriteLpSet(const fs::path& dir) {
  constexpr int kSize = 24;
  constexpr int kLights = 8;
  fs::create_directories(dir);
  std::string lp = std::to_string(kLights) + "\n";
  for (int l = 0; l < kLights; ++l) {
    const double phi = 2 * 3.14159265358979 * l / kLights;
    const double x = 0.6 * std::cos(phi), y = 0.6 * std::sin(phi), z = 0.8;
    std::vector<uint8_t> rgb(size_t(kSize) * kSize * 3);
    for (int py = 0; py < kSize; ++py) {
      for (int px = 0; px < kSize; ++px) {
        const double shade = 0.5 + 0.4 * (x * (px - kSize / 2) - y * (py - kSize / 2)) / kSize;
        for (int c = 0; c < 3; ++c) rgb[(size_t(py) * kSize + px) * 3 + c] = uint8_t(200 * shade);
      }
    }
    const std::string name = "light_" + std::to_string(l) + ".png";
    write_rgb8(dir / name, kSize, kSize, rgb.data());
    lp += name + " " + std::to_string(x) + " " + std::to_string(y) + " " + std::to_string(z) + "\n";
  }
  std::ofstream(dir / "set.lp") << lp;
  return dir / "set.lp";
}

// A full disk under every command that writes: exit 4 (storage), the path named, and nothing left
// on the disk by the run.
TEST(StorageFault, EveryCommandOnAFullDiskExitsFourNamingThePathAndLeavesNothing) {
  testing::TempDir tmp;
  const fs::path field = CaptureAndBuild(tmp);
  SmallDisk disk(tmp / "disk", "1m");
  ASSERT_TRUE(disk.mounted()) << "mount(tmpfs) failed: run inside unshare -m as root";
  FillDisk(tmp / "disk");
  std::string made;
  ASSERT_EQ(run_command(cli_path().string() + " compress --quiet " + field.string() +
                            " --format ptm --out " + (tmp / "r.ptm").string(),
                        &made),
            0)
      << made;
  const std::set<std::string> before = Listing(tmp / "disk");
  const std::string on_disk = (tmp / "disk").string() + "/";
  const std::string map = (testing::source_dir() / "data" / "envmaps" / "sky_sun.exr").string();
  const std::vector<std::string> commands = {
      "build --quiet " + (tmp / "s").string() + " --out " + on_disk + "f.exr",
      "relight --quiet " + field.string() + " --env " + map + " --out " + on_disk + "r",
      "fit --quiet " + field.string() + " --out " + on_disk + "m.exr",
      "normals --quiet " + field.string() + " --out " + on_disk + "n.exr",
      "compress --quiet " + field.string() + " --format pca --out " + on_disk + "p.lspca",
      "export openlime --quiet " + field.string() + " --out " + on_disk + "ol",
      "stage --write " + on_disk + "stage.json",
      "import --quiet " + WriteLpSet(tmp / "lp").string() + " --out " + on_disk + "i.exr",
      "import --quiet --memory 64K " + (tmp / "lp" / "set.lp").string() + " --out " + on_disk +
          "ib.exr",
      "render " + (tmp / "r.ptm").string() + " --light 0 0 1 --out " + on_disk + "r.exr",
      "envmaps --width 64 --out " + on_disk + "maps",
      "play " + (tmp / "s").string() + " --field " + field.string() + " --env " + map + " --out " +
          on_disk + "play",
  };
  for (const std::string& command : commands) {
    std::string out;
    EXPECT_EQ(run_command(cli_path().string() + " " + command, &out), 4) << command << "\n" << out;
    EXPECT_NE(out.find("storage error: " + on_disk), std::string::npos) << command << "\n" << out;
    EXPECT_EQ(Listing(tmp / "disk"), before) << command << " left files behind";
  }
}

// A capture or demo that fails on a full disk before its first frame says why ("No space left")
// and removes the session folder it made, and the folders above it that it made; a folder that
// was there stays, as it was.
TEST(StorageFault, CaptureThatFailsBeforeItsFirstFrameLeavesNoSession) {
  testing::TempDir tmp;
  const fs::path stage = WriteSmallStage(tmp.path());
  SmallDisk disk(tmp / "disk", "1m");
  ASSERT_TRUE(disk.mounted()) << "mount(tmpfs) failed: run inside unshare -m as root";
  fs::create_directories(tmp / "disk" / "mine");
  std::ofstream(tmp / "disk" / "mine" / "notes.txt") << "the user's";
  const std::string cli = cli_path().string();
  const std::string on_disk = (tmp / "disk").string() + "/";
  const std::vector<std::string> commands = {
      "capture --quiet --stage " + stage.string() + " --out " + on_disk + "a/b/sess",
      "capture --quiet --stage " + stage.string() + " --out " + on_disk + "mine",
      "demo --quiet --resolution 16 --no-truth --no-shared-maps --out " + on_disk + "demo",
  };
  for (const int free_kib : {0, 8, 16, 32}) {
    for (const std::string& command : commands) {
      const fs::path filler = FillDiskLeaving(tmp / "disk", free_kib);
      std::string out;
      const int code = run_command(cli + " " + command, &out);
      const std::string what = command + " with " + std::to_string(free_kib) + " KiB free\n" + out;
      EXPECT_EQ(code, 4) << what;
      if (free_kib == 0) {
        EXPECT_NE(out.find("No space left"), std::string::npos) << what;
      }
      EXPECT_EQ(Listing(tmp / "disk"), (std::set<std::string>{"filler", "mine"})) << what;
      EXPECT_EQ(Listing(tmp / "disk" / "mine"), std::set<std::string>{"notes.txt"}) << what;
      fs::remove(filler);
    }
  }
}

// fit, normals and fit --time on a disk with room for part of what they write (the maps, then
// their previews): each completes, or fails with exit 4 leaving neither maps nor previews; a run
// in bands may keep only its .partial/ folder, which it names.
TEST(StorageFault, FitsThatRunOutOfSpaceLeaveNeitherMapsNorPreviews) {
  testing::TempDir tmp;
  const fs::path field = CaptureAndBuild(tmp);
  const std::string cli = cli_path().string();
  std::string out;
  const fs::path lp = WriteLpSet(tmp / "lp");
  ASSERT_EQ(run_command(cli + " import --quiet " + lp.string() + " " + lp.string() +
                            " --interval 5 --out " + (tmp / "steps").string(),
                        &out),
            0)
      << out;
  SmallDisk disk(tmp / "disk", "2m");
  ASSERT_TRUE(disk.mounted()) << "mount(tmpfs) failed: run inside unshare -m as root";
  const std::string on_disk = (tmp / "disk").string() + "/";
  const std::vector<std::string> commands = {
      "fit --quiet " + field.string() + " --out " + on_disk + "m.exr",
      "normals --quiet " + field.string() + " --out " + on_disk + "n.exr",
      "fit --quiet --time " + (tmp / "steps").string() + " --out " + on_disk + "t.exr",
      "fit --quiet --memory 16K --time " + (tmp / "steps").string() + " --out " + on_disk +
          "tb.exr",
  };
  for (const std::string& command : commands) {
    bool failed_once = false;
    for (int free_kib = 0; free_kib <= 640; free_kib += 32) {
      const fs::path filler = FillDiskLeaving(tmp / "disk", free_kib);
      const int code = run_command(cli + " " + command, &out);
      const std::string what = command + " with " + std::to_string(free_kib) + " KiB free\n" + out;
      std::set<std::string> left = Listing(tmp / "disk");
      left.erase("filler");
      if (code == 0) break;
      failed_once = true;
      EXPECT_EQ(code, 4) << what;
      EXPECT_NE(out.find("storage error: " + on_disk), std::string::npos) << what;
      for (const std::string& name : left) {
        EXPECT_TRUE(name.ends_with(".partial") &&
                    out.find(on_disk + name + "/ kept for resuming") != std::string::npos)
            << name << " left behind by " << what;
        fs::remove_all(tmp / "disk" / name);
      }
      fs::remove(filler);
    }
    EXPECT_TRUE(failed_once) << command << " never ran out of space";
    for (const auto& e : fs::directory_iterator(tmp / "disk")) fs::remove_all(e.path());
  }
}

// A build in bands that runs out of space keeps what it finished for the next run, and says so;
// with space again, the same command completes and removes it.
TEST(StorageFault, BuildInBandsOnAFullDiskKeepsItsPartialFolderAndSaysSo) {
  testing::TempDir tmp;
  CaptureAndBuild(tmp);
  SmallDisk disk(tmp / "disk", "256k");  // The field's spill needs about 1 MiB.
  ASSERT_TRUE(disk.mounted()) << "mount(tmpfs) failed: run inside unshare -m as root";
  const fs::path out_file = tmp / "disk" / "f.exr";
  const std::string command = cli_path().string() + " build --quiet --memory 64K " +
                              (tmp / "s").string() + " --out " + out_file.string();
  std::string out;
  EXPECT_EQ(run_command(command, &out), 4) << out;
  EXPECT_NE(out.find("note: " + out_file.string() + ".partial/ kept for resuming"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("delete it to start over"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(out_file));
  ASSERT_TRUE(disk.resize("8m"));
  ASSERT_EQ(run_command(command, &out), 0) << out;
  EXPECT_TRUE(fs::exists(out_file));
  EXPECT_EQ(Listing(tmp / "disk"), std::set<std::string>{"f.exr"});
}

}  // namespace
}  // namespace ls
