#pragma once
// One process writes an output at a time. A WriterLock is an exclusive POSIX record lock on a
// lock file, held while it lives: the kernel drops it when its process ends, so the lock of a
// killed run is stale by construction and the next run takes it. The file holds the holder's
// process id, for people looking.
#include <sys/types.h>

#include <filesystem>
#include <optional>
#include <string>

namespace ls {

class WriterLock {
 public:
  // Takes the lock on `lock_file` (made if missing). When another process holds it: InputError
  // "<busy> (process N): wait for it to end, or stop it<then>". StorageError when the file cannot
  // be made. `remove_file`: the lock file is removed when the lock is released (an output's lock
  // beside it, which must not outlive the run).
  WriterLock(const std::filesystem::path& lock_file, const std::string& busy,
             const std::string& then, bool remove_file);
  ~WriterLock();
  WriterLock(const WriterLock&) = delete;
  WriterLock& operator=(const WriterLock&) = delete;

  // The process holding the lock on `lock_file`, without taking it; nullopt when none (or no
  // such file).
  static std::optional<pid_t> holder(const std::filesystem::path& lock_file);

 private:
  std::filesystem::path path_;
  int fd_ = -1;
  bool remove_file_ = false;
};

// The lock of an output file or folder OUT: OUT.lock beside it (its folder made when missing),
// removed when released. A second writer of OUT is refused naming the first's process.
class OutputLock {
 public:
  explicit OutputLock(const std::filesystem::path& out);

 private:
  WriterLock lock_;
};

}  // namespace ls
