#include "common/util/memory.h"

#include <fstream>
#include <sstream>
#include <string>

namespace placerec {

bool ReadResidentMemory(pid_t pid, ResidentMemory* memory) {
  std::ifstream status(pid == 0 ? std::string("/proc/self/status")
                                : "/proc/" + std::to_string(pid) + "/status");
  if (!status) return false;
  ResidentMemory read;
  bool have_current = false;
  std::string line;
  while (std::getline(status, line)) {
    std::istringstream fields(line);
    std::string key;
    double kib = 0;
    if (!(fields >> key >> kib)) continue;
    if (key == "VmRSS:") {
      read.current_mib = kib / 1024.0;
      have_current = true;
    } else if (key == "VmHWM:") {
      read.peak_mib = kib / 1024.0;
    }
  }
  // A zombie's status has no memory lines.
  if (!have_current) return false;
  *memory = read;
  return true;
}

}  // namespace placerec
