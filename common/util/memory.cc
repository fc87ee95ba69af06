#include "common/util/memory.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

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

int64_t AvailableMemoryBytes() {
  std::ifstream meminfo("/proc/meminfo");
  std::string line;
  while (std::getline(meminfo, line)) {
    std::istringstream fields(line);
    std::string key;
    int64_t kib = 0;
    if (fields >> key >> kib && key == "MemAvailable:") return kib * 1024;
  }
  return -1;
}

int64_t ReadAhead(const std::string& path, double max_share) {
  const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return 0;
  struct stat info;
  const int64_t available = AvailableMemoryBytes();
  if (fstat(fd, &info) != 0 || !S_ISREG(info.st_mode) || available < 0 ||
      static_cast<double>(info.st_size) > max_share * static_cast<double>(available)) {
    close(fd);
    return 0;
  }
  posix_fadvise(fd, 0, 0, POSIX_FADV_SEQUENTIAL);
  std::vector<char> buffer(size_t{8} << 20);
  int64_t total = 0;
  for (;;) {
    const ssize_t n = read(fd, buffer.data(), buffer.size());
    if (n > 0) {
      total += n;
    } else if (n == 0 || errno != EINTR) {
      break;
    }
  }
  close(fd);
  return total;
}

}  // namespace placerec
