// Resident memory of a process as Linux reports it (/proc/PID/status): what the server logs when it
// returns free heap, what the soak test watches and what the benchmarks report per landmark.
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
