#pragma once
// How much memory this process may take, checked before large allocations so that a file whose
// header claims too much is refused with a message instead of ending in bad_alloc.
#include <cstddef>
#include <string>

namespace ls {

// Memory the system can give now: MemAvailable (or free pages), within a tighter cgroup limit.
std::size_t available_memory_bytes();

// This process's peak resident memory so far (VmHWM of /proc/self/status: this program's own,
// from its exec on), 0 where unknown.
std::size_t peak_resident_bytes();

// Throws InputError "<what> needs X GiB but only Y GiB of memory are available (at most 80% may be
// used); <advice>" when `bytes` exceed 80% of available_memory_bytes().
void require_memory(std::size_t bytes, const std::string& what, const std::string& advice);

}  // namespace ls
