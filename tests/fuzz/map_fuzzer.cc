// libFuzzer target: loading a map from bytes (common/storage/sqlite_store.h and
// common/pipeline/place_map.h), as the server opens a map file at start-up: the bytes are written
// to a file of this process, opened (schema version, quick_check, migration), and every place
// and landmark is loaded into the index. Errors are expected; crashes, hangs and sanitizer
// reports are the findings. scripts/fuzz.sh runs it.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <utility>

#include "common/pipeline/place_map.h"
#include "common/storage/sqlite_store.h"
#include "common/util/logging.h"

namespace {

std::string MapPath() {
  const char* dir = std::getenv("TMPDIR");
  return std::string(dir != nullptr && *dir != '\0' ? dir : "/tmp") + "/placerec_map_fuzz_" +
         std::to_string(getpid()) + ".db";
}

void RemoveMap(const std::string& path) {
  for (const char* suffix : {"", "-wal", "-shm", "-journal"}) std::remove((path + suffix).c_str());
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
  placerec::InitLogging((*argv)[0]);
  FLAGS_minloglevel = google::GLOG_ERROR;  // not a line per input
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace placerec;
  static const std::string path = MapPath();
  RemoveMap(path);
  {
    std::FILE* file = std::fopen(path.c_str(), "wb");
    if (file == nullptr) return 0;
    const size_t written = std::fwrite(data, 1, size, file);
    std::fclose(file);
    if (written != size) return 0;
  }
  SqliteStoreOptions options;
  options.must_exist = true;
  options.synchronous_full = false;
  StatusOr<std::unique_ptr<LandmarkStore>> store = OpenSqliteStore(path, options);
  if (store.ok()) {
    StatusOr<std::unique_ptr<PlaceMap>> map =
        PlaceMap::Open(std::move(*store), LandmarkIndexOptions());
    if (map.ok()) (void)(*map)->Counts();
  }
  RemoveMap(path);
  return 0;
}
