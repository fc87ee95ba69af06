#include "common/util/logging.h"

#include <cstdlib>

namespace placerec {

void InitLogging(const char* argv0) {
  static bool initialized = false;
  if (initialized) return;
  initialized = true;
  if (std::getenv("GLOG_logtostderr") == nullptr && std::getenv("GLOG_log_dir") == nullptr) {
    FLAGS_logtostderr = true;
  }
  google::InitGoogleLogging(argv0);
}

}  // namespace placerec
