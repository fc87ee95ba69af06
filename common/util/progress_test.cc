#include "common/util/progress.h"

#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

#include <cstdio>
#include <string>

#include <gtest/gtest.h>

namespace placerec {
namespace {

// Everything written to `file` so far.
std::string Contents(FILE* file) {
  std::fflush(file);
  std::rewind(file);
  std::string text;
  char buffer[256];
  size_t n;
  while ((n = std::fread(buffer, 1, sizeof buffer, file)) > 0) text.append(buffer, n);
  return text;
}

TEST(ProgressLineTest, InALogEveryDueReportIsALineOfItsOwn) {
  FILE* log = std::tmpfile();
  ASSERT_NE(log, nullptr);
  ProgressLine progress(/*total=*/7, /*log_every=*/3, log);
  EXPECT_FALSE(progress.terminal());
  for (size_t i = 1; i <= 7; ++i) progress.Report(i, "step %zu/%d", i, 7);
  progress.Clear();
  EXPECT_EQ(Contents(log), "step 3/7\nstep 6/7\nstep 7/7\n");
  std::fclose(log);
}

TEST(ProgressLineTest, DueEveryNStepsAndAtTheLast) {
  FILE* log = std::tmpfile();
  ASSERT_NE(log, nullptr);
  const ProgressLine progress(10, 4, log);
  EXPECT_FALSE(progress.Due(1));
  EXPECT_TRUE(progress.Due(4));
  EXPECT_FALSE(progress.Due(5));
  EXPECT_TRUE(progress.Due(8));
  EXPECT_TRUE(progress.Due(10));
  // An interval of 0 reports every step rather than dividing by zero.
  const ProgressLine every_step(3, 0, log);
  EXPECT_TRUE(every_step.Due(1));
  EXPECT_TRUE(every_step.Due(2));
  std::fclose(log);
}

TEST(ProgressLineTest, OnATerminalTheLineIsRewrittenInPlace) {
  // A pseudo-terminal: the progress writes to its secondary side, the test reads the primary.
  const int primary = posix_openpt(O_RDWR | O_NOCTTY);
  ASSERT_GE(primary, 0);
  ASSERT_EQ(grantpt(primary), 0);
  ASSERT_EQ(unlockpt(primary), 0);
  const char* name = ptsname(primary);
  ASSERT_NE(name, nullptr);
  FILE* terminal = std::fopen(name, "w");
  ASSERT_NE(terminal, nullptr);

  {
    ProgressLine progress(/*total=*/3, /*log_every=*/100, terminal);
    EXPECT_TRUE(progress.terminal());
    progress.Report(1, "a");
    progress.Report(2, "b");
    progress.Clear();
    progress.Report(3, "c");
  }
  std::fclose(terminal);

  std::string text;
  char buffer[256];
  ssize_t n;
  while ((n = read(primary, buffer, sizeof buffer)) > 0) {
    text.append(buffer, static_cast<size_t>(n));
    if (text.find('\n') != std::string::npos) break;
  }
  close(primary);
  // Each report wipes the line first; the terminal turns the last step's "\n" into "\r\n".
  EXPECT_EQ(text, "\r\033[Ka\r\033[Kb\r\033[K\r\033[Kc\r\n");
}

}  // namespace
}  // namespace placerec
