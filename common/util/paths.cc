#include "common/util/paths.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
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

Status MoveWithoutReplacing(const std::string& from, const std::string& to, MoveWay first) {
  const auto failed = [&](int error) {
    return Status::IoError("cannot create " + to + ": " + std::strerror(error));
  };
  // What a file system answers for a call it does not have; anything else (the name is taken,
  // no permission, no space, no `from`) is the answer.
  const auto unsupported = [](int error) {
    return error == EPERM || error == EOPNOTSUPP || error == ENOTSUP || error == ENOSYS ||
           error == EINVAL || error == EMLINK;
  };
  if (first == MoveWay::kHardLink) {
    if (::link(from.c_str(), to.c_str()) == 0) {
      if (::unlink(from.c_str()) != 0 && errno != ENOENT) {
        const int error = errno;
        ::unlink(to.c_str());
        return Status::IoError("cannot remove " + from + " after linking it to " + to + ": " +
                               std::strerror(error));
      }
      return Status::Ok();
    }
    if (!unsupported(errno)) return failed(errno);
  }
  if (first != MoveWay::kReserveAndRename) {
    if (::renameat2(AT_FDCWD, from.c_str(), AT_FDCWD, to.c_str(), RENAME_NOREPLACE) == 0) {
      return Status::Ok();
    }
    if (!unsupported(errno)) return failed(errno);
  }
  if (::access(from.c_str(), F_OK) != 0) return failed(errno);
  const int reserved = ::open(to.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (reserved < 0) return failed(errno);
  ::close(reserved);
  if (::rename(from.c_str(), to.c_str()) != 0) {
    const int error = errno;
    ::unlink(to.c_str());
    return failed(error);
  }
  return Status::Ok();
}

}  // namespace placerec
