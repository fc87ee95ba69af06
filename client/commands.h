// The commands of placerec-client (send, query, status, run, fleet, watch), each parsing its own
// flags from argv[2..] and returning the process exit code.
#pragma once

#include <string>

namespace placerec {

constexpr int kExitOk = 0;      // every request got an answer with status ok
constexpr int kExitFailed = 1;  // an answer timed out or carried an error, or I/O failed
constexpr int kExitUsage = 2;   // bad arguments
// run and fleet stopped by SIGINT or SIGTERM, after writing the report of the frames sent.
constexpr int kExitInterrupted = 130;

extern const char kClientUsage[];

int SendCommand(int argc, const char* const* argv);
int QueryCommand(int argc, const char* const* argv);
int StatusCommand(int argc, const char* const* argv);
// `data_default` is where datasets given by name are looked for without PLACEREC_DATA.
int RunCommand(int argc, const char* const* argv, const std::string& data_default);
// Prints every scene-change alarm (PLACEREC_CHANGE) as it arrives and saves its pictures.
int WatchCommand(int argc, const char* const* argv);
int FleetCommand(int argc, const char* const* argv, const std::string& data_default);

}  // namespace placerec
