// Resident memory of a process as Linux reports it (/proc/PID/status), for logs, tests and
// benchmarks that report what a process holds.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <string>

namespace placerec {

struct ResidentMemory {
  double current_mib = 0;  // VmRSS: resident now
  double peak_mib = 0;     // VmHWM: the most resident since the process started
};

// Reads `pid`'s resident memory (0: this process); false, and `memory` untouched, when the
// process does not exist or its status cannot be read.
bool ReadResidentMemory(pid_t pid, ResidentMemory* memory);

// Memory the system could give a process now without swapping (MemAvailable of /proc/meminfo:
// free memory plus the page cache it may reclaim), bytes; -1 when it cannot be read.
int64_t AvailableMemoryBytes();

// Reads the file at `path` once from start to end, so that the page cache holds it: a reader that
// then visits its pages in another order (SQLite's quick_check walking its trees) finds them in
// memory instead of waiting on the disk for each. A disk reads a file in order many times faster
// than page by page. Skipped when the file is larger than `max_share` of the available memory (it
// would push itself out again). Returns the bytes read: 0 when skipped or unreadable.
int64_t ReadAhead(const std::string& path, double max_share);

}  // namespace placerec
