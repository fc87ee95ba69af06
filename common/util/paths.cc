#include "common/util/paths.h"

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <system_error>

namespace placerec {
namespace {

std::string Resolve(const std::string& flag_value, const char* env, const std::string& fallback) {
  if (!flag_value.empty()) return flag_value;
  if (const char* value = std::getenv(env); value != nullptr && value[0] != '\0') return value;
  return fallback;
}

}  // namespace

std::string DataDir(const std::string& flag_value, const std::string& build_default) {
  return Resolve(flag_value, "PLACEREC_DATA", build_default);
}

std::string ModelsDir(const std::string& flag_value, const std::string& build_default) {
  return Resolve(flag_value, "PLACEREC_MODELS", build_default);
}

bool PathExists(const std::string& path) {
  std::error_code ec;
  return std::filesystem::exists(path, ec);
}

bool MakeDirectories(const std::string& path) {
  std::error_code ec;
  std::filesystem::create_directories(path, ec);
  // An existing folder that cannot be written in (its permissions, a read-only file system) is
  // refused too: a command finds out before its work, not when it writes its results.
  return std::filesystem::is_directory(path, ec) && access(path.c_str(), W_OK | X_OK) == 0;
}

}  // namespace placerec
