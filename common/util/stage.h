// The pipeline stage a thread is in, so that an exception thrown deep inside a library (e.g. an
// OpenCV cv::Exception, whose message names only OpenCV's own function) can be reported with the
// stage of ours it left: the server's "internal error" answers and log say "in recognize > change".
#pragma once

#include <string>

namespace placerec {

// Marks the scope of one named stage on this thread; stages nest ("analyze" > "sift"). When an
// exception leaves the scope, the innermost stage it left is recorded for TakeFailedStage().
// Recording allocates nothing (a destructor runs during unwinding, often of a bad_alloc).
//
//   {
//     ScopedStage stage("sift");
//     features = ExtractFeatures(frame);
//   }
//
// A handler that catches an exception inside a stage and goes on should call TakeFailedStage()
// (or ignore its result): the record is otherwise kept until a stage is next entered normally,
// and a later exception that leaves the outer stages would be reported with the inner one.
class ScopedStage {
 public:
  // `name` must outlive the stage (a string literal).
  explicit ScopedStage(const char* name);
  ~ScopedStage();
  ScopedStage(const ScopedStage&) = delete;
  ScopedStage& operator=(const ScopedStage&) = delete;

  // The stages the last exception left on this thread, outermost first and joined by " > "
  // (e.g. "recognize > change"; at most kMaxDepth names, the innermost kept); "" when no
  // exception has left a stage since the record was last taken or a stage was entered normally.
  // Clears the record: call it once, in the handler that caught the exception.
  static std::string TakeFailedStage();

  static constexpr int kMaxDepth = 16;

 private:
  const char* name_;
  const ScopedStage* parent_;
  int exceptions_at_entry_;
};

}  // namespace placerec
