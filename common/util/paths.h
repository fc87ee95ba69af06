// Where the evaluation data and trained models are: a flag wins, then the environment
// (PLACEREC_DATA, PLACEREC_MODELS), then the build's defaults (../shared/data, models/).
#pragma once

#include <string>

#include "common/util/status.h"

namespace placerec {

std::string DataDir(const std::string& flag_value, const std::string& build_default);
std::string ModelsDir(const std::string& flag_value, const std::string& build_default);
bool PathExists(const std::string& path);
// Creates a directory and its parents; false when it could not be created, or exists but cannot
// be written in.
bool MakeDirectories(const std::string& path);

// Ways to put a file at a name without replacing what is there, in the order they are tried.
enum class MoveWay {
  kHardLink,          // link(2), then `from` removed
  kRenameNoReplace,   // renameat2(2) with RENAME_NOREPLACE (Linux 3.15; ext4, XFS, btrfs and
                      // tmpfs have it, the kernel's FAT and exFAT drivers since later kernels)
  kReserveAndRename,  // the name taken with O_CREAT | O_EXCL, then `from` renamed over it
};

// Puts the closed file `from` at `to` unless a file `to` exists (another process may create it
// meanwhile, so the check is part of the move), trying the ways from `first` on: a way the file
// system does not have (no hard links on FAT, exFAT and many FUSE file systems; no
// RENAME_NOREPLACE on many FUSE ones) passes to the next. The last way protects `to` only from
// writers that also create it exclusively (these three ways, O_EXCL), and a process killed
// between its two steps leaves an empty file at `to`. On error `from` is where it was and `to`
// as it was.
Status MoveWithoutReplacing(const std::string& from, const std::string& to,
                            MoveWay first = MoveWay::kHardLink);

}  // namespace placerec
