// The pipeline stage a thread is in, so that an exception thrown deep inside a library (e.g. an
// OpenCV cv::Exception, whose message names only OpenCV's own function) can be reported with the
// stage of ours it left: the server's "internal error" answers and log say "in recognize > change".
#pragma once

#include <string>

namespace placerec {

// Marks the scope of one named stage on this thread; stages nest ("analyze" > "sift"). When an
// exception leaves the scope, the innermost stage it left is recorded for FailedStage().
//
//   {
//     ScopedStage stage("sift");
//     features = ExtractFeatures(frame);
//   }
class ScopedStage {
 public:
  // `name` must outlive the stage (a string literal).
  explicit ScopedStage(const char* name);
  ~ScopedStage();
  ScopedStage(const ScopedStage&) = delete;
  ScopedStage& operator=(const ScopedStage&) = delete;

  // The stages the last exception left on this thread, outermost first and joined by " > "
  // (e.g. "recognize > change"); "" when no exception has left a stage since the thread last
  // entered one normally. Read it in the handler that caught the exception.
  static std::string FailedStage();

 private:
  const char* name_;
  const ScopedStage* parent_;
  int exceptions_at_entry_;
};

}  // namespace placerec
