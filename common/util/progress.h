// Progress of long work (training, evaluation runs, dataset segmentation) on standard error.
// On a terminal one line is rewritten in place; anywhere else (a log file, CI) every report
// is a line of its own, and reports are thinned out so that a log stays short.
#pragma once

#include <cstddef>
#include <cstdio>

namespace placerec {

class ProgressLine {
 public:
  // `total` steps. On a terminal every step is reported, elsewhere every `log_every` steps;
  // the last step always is. `out` is the stream written to; whether it is a terminal is asked
  // once, here.
  ProgressLine(size_t total, size_t log_every, FILE* out = stderr);

  bool terminal() const { return terminal_; }

  // Whether step `done` (1-based) is reported.
  bool Due(size_t done) const;

  // Reports step `done` with a printf-style text when it is due: on a terminal in place of
  // the previous report (and a line break after the last step), elsewhere as one line.
  void Report(size_t done, const char* format, ...) __attribute__((format(printf, 3, 4)));

  // Wipes the in-place line on a terminal, so that other output starts on a clean line; does
  // nothing elsewhere, where every report already ended its line.
  void Clear();

 private:
  FILE* out_;
  bool terminal_;
  size_t total_;
  size_t every_;
};

}  // namespace placerec
