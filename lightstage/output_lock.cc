#include "lightstage/output_lock.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "lightstage/errors.h"
#include "lightstage/run_outputs.h"

namespace ls {

namespace fs = std::filesystem;

namespace {

// F_GETLK: the process whose lock on fd's file would block a write lock; nullopt when none.
std::optional<pid_t> lock_holder(int fd) {
  struct flock holder {};
  holder.l_type = F_WRLCK;
  holder.l_whence = SEEK_SET;
  if (::fcntl(fd, F_GETLK, &holder) != 0 || holder.l_type == F_UNLCK) return std::nullopt;
  return holder.l_pid;
}

// Whether fd is still the file at path (a releasing holder may have removed it meanwhile).
bool same_file(int fd, const fs::path& path) {
  struct stat open_file {
  }, named{};
  return ::fstat(fd, &open_file) == 0 && ::stat(path.c_str(), &named) == 0 &&
         open_file.st_dev == named.st_dev && open_file.st_ino == named.st_ino;
}

}  // namespace

WriterLock::WriterLock(const fs::path& lock_file, const std::string& busy, const std::string& then,
                       bool remove_file)
    : path_(lock_file), remove_file_(remove_file) {
  for (;;) {
    fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) {
      throw StorageError(path_.string() + ": cannot open the lock: " + std::strerror(errno));
    }
    struct flock lock {};
    lock.l_type = F_WRLCK;
    lock.l_whence = SEEK_SET;
    if (::fcntl(fd_, F_SETLK, &lock) != 0) {
      const std::optional<pid_t> pid = lock_holder(fd_);
      ::close(fd_);
      throw InputError(busy + (pid ? " (process " + std::to_string(*pid) + ")" : "") +
                       ": wait for it to end, or stop it" + then);
    }
    // Locked; but a holder that removes its file on release may have done so after we opened it.
    if (!remove_file_ || same_file(fd_, path_)) break;
    ::close(fd_);
  }
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd_, 0) != 0 || ::write(fd_, pid.data(), pid.size()) < 0) {
    // The lock holds without the note.
  }
}

WriterLock::~WriterLock() {
  if (remove_file_) ::unlink(path_.c_str());  // While still held: the next run makes a new one.
  ::close(fd_);                               // Releases the lock.
}

std::optional<pid_t> WriterLock::holder(const fs::path& lock_file) {
  const int fd = ::open(lock_file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return std::nullopt;
  const std::optional<pid_t> pid = lock_holder(fd);
  ::close(fd);
  return pid;
}

namespace {

fs::path lock_file_of(const fs::path& out) {
  const fs::path plain = out.has_filename() ? out : out.parent_path();  // "dir/" as "dir".
  return plain.string() + ".lock";
}

fs::path made_lock_file(const fs::path& out) {
  fs::path file = lock_file_of(out);
  if (!file.parent_path().empty()) {
    require_folder_can_be_made(file.parent_path());
    std::error_code error;
    fs::create_directories(file.parent_path(), error);
    if (error) {
      throw StorageError(file.parent_path().string() +
                         ": cannot create the folder: " + error.message());
    }
  }
  return file;
}

}  // namespace

OutputLock::OutputLock(const fs::path& out)
    : lock_(made_lock_file(out), out.string() + ": another lightstage run is writing it",
            ", or give another output", /*remove_file=*/true) {}

}  // namespace ls
