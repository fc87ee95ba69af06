#include "common/util/stage.h"

#include <exception>
#include <vector>

namespace placerec {
namespace {

thread_local const ScopedStage* current_stage = nullptr;
thread_local std::string failed_stage;

}  // namespace

ScopedStage::ScopedStage(const char* name)
    : name_(name), parent_(current_stage), exceptions_at_entry_(std::uncaught_exceptions()) {
  // Entering a stage normally: any exception recorded earlier was handled.
  if (exceptions_at_entry_ == 0) failed_stage.clear();
  current_stage = this;
}

ScopedStage::~ScopedStage() {
  // Unwinding an exception that was thrown inside this stage: the innermost stage is destroyed
  // first and records the whole path; the stages around it leave the record alone.
  if (std::uncaught_exceptions() > exceptions_at_entry_ && failed_stage.empty()) {
    std::vector<const char*> names;
    for (const ScopedStage* s = this; s != nullptr; s = s->parent_) names.push_back(s->name_);
    for (auto it = names.rbegin(); it != names.rend(); ++it) {
      if (!failed_stage.empty()) failed_stage += " > ";
      failed_stage += *it;
    }
  }
  current_stage = parent_;
}

std::string ScopedStage::FailedStage() { return failed_stage; }

}  // namespace placerec
