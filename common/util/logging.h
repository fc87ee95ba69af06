// One logger for the whole project: glog. Executables call InitLogging once in main().
#pragma once

#include <glog/logging.h>

namespace placerec {

// Logs to stderr (not to files) at INFO and above unless GLOG_* environment variables say
// otherwise.
void InitLogging(const char* argv0);

}  // namespace placerec
