#pragma once
// How much memory this process may take: the system's figures, a check before large allocations
// (a file whose header claims too much is refused with a message, not a bad_alloc), and the one
// memory budget of a run (MemoryBudget, the --memory of every command).
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace ls {

// Memory the system can give now: MemAvailable (or free pages), within a tighter cgroup limit or
// what an address-space limit (ulimit -v) leaves.
std::size_t available_memory_bytes();

// This process's peak resident memory so far (VmHWM of /proc/self/status: this program's own,
// from its exec on), 0 where unknown.
std::size_t peak_resident_bytes();

// Throws InputError "<what> needs X GiB but only Y GiB of memory are available (at most 80% may be
// used); <advice>" when `bytes` exceed 80% of available_memory_bytes().
void require_memory(std::size_t bytes, const std::string& what, const std::string& advice);

// "512 MiB", "1.5 GiB", "20000 bytes": a size as a person reads it (powers of 1024).
std::string format_bytes(std::size_t bytes);

// The most memory a run holds for the field's data at once; larger work goes in bands of rows.
// Unset, it is default_bytes(): half of the memory available when the run starts. Every command's
// --memory is one (lightstage/memory_option.h binds it), and bounds:
//
//   command              what the budget bounds                      unset
//   build                the field's values (bands of rows spilled   default_bytes()
//                        to a file beside --out) and the LEDs merged
//                        in flight (a quarter of it)
//   import               the field's values, written in bands        kImageSetBytes (*)
//                        through a spill beside --out
//   fit                  the band of the field read at once (twice   default_bytes()
//                        with basis materials)
//   normals              the band of the field read at once          kNormalsBandBytes (***)
//   fit --time           every step's band and its fits together     default_bytes()
//   compress, export     the band of the field read at once; an .lp  default_bytes();
//   openlime             set's images are read in bands              .lp images:
//                                                                    kImageSetBytes (*)
//   relight              the compact sources' images (a sun or a     default_bytes()
//                        lamp rendered at its direction); the field
//                        itself is read a few MiB at a time (**)
//   view                 the field shown: a larger one opens at a    default_bytes()
//                        reduced resolution instead of in bands (**)
//   bench scale, rti     passed to every step's --memory             the bench's own
//
// (*) An OLAT image set is read image by image for every band: more than a few tens of rows do
// not make it faster, so unset it takes kImageSetBytes (at most default_bytes()); a given budget
// is used as given.
// (**) relight and view cannot go in bands of the field as the others do: relight bounds what it
// holds beside its streamed field, view shows less detail.
// (***) normals writes each band as it is done: larger bands hold more without going faster
// (a 12-megapixel, 41-light field: 23 s and 0.58 GiB in bands of 512 MiB, 50 s and 6.9 GiB whole
// on a 2-core machine with 23 GiB), so unset it takes kNormalsBandBytes (at most
// default_bytes()); a given budget is used as given.
class MemoryBudget {
 public:
  // Refused below this: no field's row fits in less.
  static constexpr std::size_t kMinimumBytes = std::size_t(16) << 10;
  // Accepted below this with a note (note()): real fields' rows take MiBs, so bands of a few
  // rows each, slowly.
  static constexpr std::size_t kSmallBytes = std::size_t(16) << 20;
  // Unset, what OLAT image sets are read in (see (*) above).
  static constexpr std::size_t kImageSetBytes = std::size_t(32) << 20;
  // Unset, the band normals reads (see (***) above).
  static constexpr std::size_t kNormalsBandBytes = std::size_t(512) << 20;

  MemoryBudget() = default;  // Unset: default_bytes().
  // Given in code (tests, benches); 0 is unset, as in the options files record.
  explicit MemoryBudget(std::size_t bytes);

  // "512M", "2G", "1.5GiB", "64MiB", "33554432": bytes, or with K, M, G or T (each with an
  // optional "B" or "iB"), powers of 1024, case ignored. Throws InputError naming `option` and
  // the text for what is not a size: empty, negative, zero, a fraction of a byte, an unknown
  // unit, beyond 2^64 bytes, or below kMinimumBytes.
  static MemoryBudget parse(std::string_view text, std::string_view option = "--memory");
  // The one default: half of available_memory_bytes(), read when called.
  static std::size_t default_bytes();

  bool given() const { return bytes_.has_value(); }
  // The budget: as given, else default_bytes().
  std::size_t bytes() const;
  // As given, else min(unset_bytes, default_bytes()) (OLAT image sets: kImageSetBytes).
  std::size_t bytes_or(std::size_t unset_bytes) const;
  // As given, else 0: what options files record (0: the default).
  std::size_t given_bytes() const { return bytes_.value_or(0); }
  // A warning for a given budget below kSmallBytes or above the memory available, naming
  // `option`; empty otherwise.
  std::string note(std::string_view option = "--memory") const;
  // "512 MiB", or "half of the memory available" when unset.
  std::string to_string() const;

  bool operator==(const MemoryBudget&) const = default;

 private:
  std::optional<std::size_t> bytes_;
};

}  // namespace ls
