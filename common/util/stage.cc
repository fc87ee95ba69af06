#include "common/util/stage.h"

#include <exception>

namespace placerec {
namespace {

thread_local const ScopedStage* current_stage = nullptr;

// The recorded path, innermost first; written during unwinding, so no allocation.
struct FailedPath {
  const char* names[ScopedStage::kMaxDepth];
  int depth = 0;
};
thread_local FailedPath failed_path;

}  // namespace

ScopedStage::ScopedStage(const char* name)
    : name_(name), parent_(current_stage), exceptions_at_entry_(std::uncaught_exceptions()) {
  // Entering a stage normally: any exception recorded earlier was handled.
  if (exceptions_at_entry_ == 0) failed_path.depth = 0;
  current_stage = this;
}

ScopedStage::~ScopedStage() {
  // Unwinding an exception that was thrown inside this stage: the innermost stage is destroyed
  // first and records the whole path; the stages around it leave the record alone.
  if (std::uncaught_exceptions() > exceptions_at_entry_ && failed_path.depth == 0) {
    for (const ScopedStage* s = this; s != nullptr && failed_path.depth < kMaxDepth;
         s = s->parent_) {
      failed_path.names[failed_path.depth++] = s->name_;
    }
  }
  current_stage = parent_;
}

std::string ScopedStage::TakeFailedStage() {
  std::string path;
  for (int i = failed_path.depth - 1; i >= 0; --i) {
    if (!path.empty()) path += " > ";
    path += failed_path.names[i];
  }
  failed_path.depth = 0;
  return path;
}

}  // namespace placerec
