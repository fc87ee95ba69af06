// placerec-client: the command line of libplacerec_client (see client/commands.h).
#include <cstdio>
#include <cstring>

#include "client/commands.h"
#include "common/util/logging.h"

int main(int argc, char** argv) {
  placerec::InitLogging(argv[0]);
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0) {
    std::printf("%s\n", placerec::kClientUsage);
    return argc < 2 ? placerec::kExitUsage : placerec::kExitOk;
  }
  const char* command = argv[1];
  if (std::strcmp(command, "send") == 0) return placerec::SendCommand(argc, argv);
  if (std::strcmp(command, "query") == 0) return placerec::QueryCommand(argc, argv);
  if (std::strcmp(command, "status") == 0) return placerec::StatusCommand(argc, argv);
  if (std::strcmp(command, "watch") == 0) return placerec::WatchCommand(argc, argv);
  if (std::strcmp(command, "run") == 0) {
    return placerec::RunCommand(argc, argv, PLACEREC_DEFAULT_DATA_DIR);
  }
  if (std::strcmp(command, "fleet") == 0) {
    return placerec::FleetCommand(argc, argv, PLACEREC_DEFAULT_DATA_DIR);
  }
  std::fprintf(stderr, "placerec-client: unknown command '%s'\n%s\n", command,
               placerec::kClientUsage);
  return placerec::kExitUsage;
}
