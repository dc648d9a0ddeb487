#pragma once
// A temporary file of floats beside an output, written and read at float offsets, and removed when
// destroyed: data larger than memory on its way into the output (a field built in bands: its LEDs'
// images; an RTI file compressed in bands: its coefficients).
#include <cstddef>
#include <filesystem>
#include <string>

namespace ls {

class ScratchFile {
 public:
  // Temporary: created empty, removed when destroyed. Kept: what an earlier run wrote there is
  // kept (a resumed build), and the file stays (its owner removes it once done with it).
  enum class Lifetime { kTemporary, kKept };
  // `needs`: what a failure means for the user, added to every error (e.g. "a field built in bands
  // needs free space for the whole field beside it"). StorageError naming the file when it cannot
  // be created.
  ScratchFile(std::filesystem::path path, std::string needs,
              Lifetime lifetime = Lifetime::kTemporary);
  ~ScratchFile();
  ScratchFile(const ScratchFile&) = delete;
  ScratchFile& operator=(const ScratchFile&) = delete;

  // `count` floats at float offset `at`; StorageError naming the file on a failed or short
  // transfer.
  void write(const float* values, std::size_t count, std::size_t at);
  void read(float* values, std::size_t count, std::size_t at);
  // What was written, made durable (fdatasync): before a record that says it is there.
  void sync();
  // Closed and opened again: on a file system shared between nodes (NFS), what other processes
  // wrote since is read, not pages this one cached before (close-to-open consistency).
  void reopen();
  const std::filesystem::path& path() const { return path_; }

 private:
  template <class Io>
  void transfer(Io io, char* bytes, std::size_t count, std::size_t at);
  [[noreturn]] void fail(const std::string& what, bool with_errno = true) const;

  std::filesystem::path path_;
  std::string needs_;
  Lifetime lifetime_;
  int fd_ = -1;
};

}  // namespace ls
