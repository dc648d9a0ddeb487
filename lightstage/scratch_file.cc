#include "lightstage/scratch_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "lightstage/errors.h"

namespace ls {

ScratchFile::ScratchFile(std::filesystem::path path, std::string needs, Lifetime lifetime)
    : path_(std::move(path)), needs_(std::move(needs)), lifetime_(lifetime) {
  const int truncate = lifetime_ == Lifetime::kTemporary ? O_TRUNC : 0;
  fd_ = ::open(path_.c_str(), O_RDWR | O_CREAT | truncate | O_CLOEXEC, 0600);
  if (fd_ < 0) fail("cannot create it");
}

ScratchFile::~ScratchFile() {
  if (fd_ >= 0) ::close(fd_);
  if (lifetime_ == Lifetime::kKept) return;
  std::error_code ignored;
  std::filesystem::remove(path_, ignored);
}

void ScratchFile::write(const float* values, std::size_t count, std::size_t at) {
  // pwrite does not write through its pointer; the shared transfer loop takes a char*.
  transfer(::pwrite, reinterpret_cast<char*>(const_cast<float*>(values)), count, at);
}

void ScratchFile::read(float* values, std::size_t count, std::size_t at) {
  transfer(::pread, reinterpret_cast<char*>(values), count, at);
}

void ScratchFile::reopen() {
  ::close(fd_);
  fd_ = ::open(path_.c_str(), O_RDWR | O_CLOEXEC);
  if (fd_ < 0) fail("cannot open it again");
}

void ScratchFile::sync() {
  if (::fdatasync(fd_) != 0) fail("making it durable (fdatasync)");
}

template <class Io>
void ScratchFile::transfer(Io io, char* bytes, std::size_t count, std::size_t at) {
  std::size_t left = count * sizeof(float);
  off_t position = off_t(at * sizeof(float));
  while (left > 0) {
    const ssize_t n = io(fd_, bytes, left, position);
    if (n == 0) fail("unexpected end", false);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("reading or writing");
    }
    bytes += n, left -= std::size_t(n), position += n;
  }
}

void ScratchFile::fail(const std::string& what, bool with_errno) const {
  throw StorageError(path_.string() + ": " + what +
                     (with_errno ? std::string(": ") + std::strerror(errno) : "") + " (" + needs_ +
                     ")");
}

}  // namespace ls
