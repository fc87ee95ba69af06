#include "common/util/paths.h"

#include <fcntl.h>
#include <sys/stat.h>
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
  // What a file system answers for a call it does not have (FUSE answers EINVAL for a rename
  // with flags it cannot pass on); anything else (the name is taken, no permission, no space, no
  // `from`) is the answer. Passing on is safe: no later way replaces a file either.
  const auto unsupported = [](int error) {
    return error == EPERM || error == EOPNOTSUPP || error == ENOSYS || error == EINVAL ||
           error == EMLINK;
  };
  if (first == MoveWay::kHardLink) {
    if (::link(from.c_str(), to.c_str()) == 0) {
      // The move stands; a `from` that cannot be removed is only a second name of the file.
      ::unlink(from.c_str());
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
  if (::access(from.c_str(), F_OK) != 0) {
    return Status::IoError("cannot move " + from + ": " + std::strerror(errno));
  }
  const int reserved = ::open(to.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (reserved < 0) return failed(errno);
  struct stat placeholder;
  const bool known = ::fstat(reserved, &placeholder) == 0;
  ::close(reserved);
  if (!known || ::rename(from.c_str(), to.c_str()) != 0) {
    const int error = known ? errno : EIO;
    // Only the placeholder is removed, never a file another process put there meanwhile.
    struct stat now;
    if (known && ::lstat(to.c_str(), &now) == 0 && now.st_dev == placeholder.st_dev &&
        now.st_ino == placeholder.st_ino && now.st_size == 0) {
      ::unlink(to.c_str());
    }
    return failed(error);
  }
  return Status::Ok();
}

}  // namespace placerec
