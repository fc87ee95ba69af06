// Resident memory of a process as Linux reports it (/proc/PID/status), for logs, tests and
// benchmarks that report what a process holds.
#pragma once

#include <sys/types.h>

namespace placerec {

struct ResidentMemory {
  double current_mib = 0;  // VmRSS: resident now
  double peak_mib = 0;     // VmHWM: the most resident since the process started
};

// Reads `pid`'s resident memory (0: this process); false, and `memory` untouched, when the
// process does not exist or its status cannot be read.
bool ReadResidentMemory(pid_t pid, ResidentMemory* memory);

}  // namespace placerec
