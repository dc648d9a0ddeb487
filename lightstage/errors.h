#pragma once
// Two tiers of errors (STYLE.md):
//  * InputError / HardwareError: recoverable, caused by the user's files or the devices. The
//    message names the file (or device), the field and what was expected; the CLI prints it and
//    exits non-zero.
//  * StorageError: an output that cannot be written (a full disk, no permission, a folder that
//    vanished); the message names the path. It is an InputError, so that code which reports an
//    input's failure reports it too; the CLI exits 4 for it, not 2.
//  * LS_CHECK: a broken invariant inside the program; it prints the values involved and aborts.
#include <stdexcept>
#include <string>
#include <string_view>

namespace ls {

// Bytes as a message may quote them (a line of a file, a device's reply): those that are not
// printable ASCII as \xNN, so that a binary file or a garbled line never writes raw bytes to the
// terminal; at most `max_chars` of them, then "...".
std::string printable(std::string_view bytes, std::size_t max_chars = 80);

class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class StorageError : public InputError {
 public:
  using InputError::InputError;
};

class HardwareError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A camera that did not deliver a frame in time; the sequencer retries these.
class CameraTimeout : public HardwareError {
 public:
  using HardwareError::HardwareError;
};

[[noreturn]] void check_failed(const char* expr, const char* file, int line,
                               const std::string& what);

}  // namespace ls

#define LS_CHECK(cond, what)                                          \
  do {                                                                \
    if (!(cond)) ::ls::check_failed(#cond, __FILE__, __LINE__, what); \
  } while (0)
