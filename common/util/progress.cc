#include "common/util/progress.h"

#include <unistd.h>

#include <algorithm>
#include <cstdarg>

namespace placerec {

ProgressLine::ProgressLine(size_t total, size_t log_every, FILE* out)
    : out_(out),
      terminal_(isatty(fileno(out)) == 1),
      total_(total),
      every_(terminal_ ? 1 : std::max<size_t>(1, log_every)) {}

bool ProgressLine::Due(size_t done) const { return done == total_ || done % every_ == 0; }

void ProgressLine::Report(size_t done, const char* format, ...) {
  if (!Due(done)) return;
  if (terminal_) std::fputs("\r\033[K", out_);
  va_list args;
  va_start(args, format);
  std::vfprintf(out_, format, args);
  va_end(args);
  if (!terminal_ || done == total_) std::fputc('\n', out_);
  std::fflush(out_);
}

void ProgressLine::Clear() {
  if (terminal_) std::fputs("\r\033[K", out_);
}

}  // namespace placerec
