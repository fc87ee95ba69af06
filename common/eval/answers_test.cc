#include "common/eval/answers.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

namespace placerec {
namespace {

std::string TempPath(const std::string& name) {
  return ::testing::TempDir() + "/placerec_answers_test_" + name;
}

std::string Slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

void Spit(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
}

TEST(AnswersTest, RoundTripsExactly) {
  const std::vector<Answer> answers = {
      {0, -1, 0.0},
      {1, 0, 0.1},
      {2, 1, 1e-7},
      {3, -1, 12345.678},
      {4, 2, -0.5},
      {5, 0, 1.0 / 3},
      {6, 5, 1e300},
      {7, 3, std::numeric_limits<double>::min()},
      {8, 7, 0.30000000000000004},
  };
  const std::string path = TempPath("round_trip.csv");
  ASSERT_TRUE(WriteAnswers(path, answers).ok());
  // Shortest text that reads back exactly, whatever the locale.
  const std::string start = "frame,reference,score\n0,-1,0\n1,0,0.1\n2,1,1e-07\n3,-1,12345.678\n";
  EXPECT_EQ(Slurp(path).substr(0, start.size()), start);
  StatusOr<std::vector<Answer>> read = ReadAnswers(path);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  ASSERT_EQ(read->size(), answers.size());
  for (size_t i = 0; i < answers.size(); ++i) {
    EXPECT_EQ((*read)[i].frame, answers[i].frame);
    EXPECT_EQ((*read)[i].reference, answers[i].reference);
    EXPECT_EQ((*read)[i].score, answers[i].score) << i;  // bit-exact, not approximately
  }
  std::remove(path.c_str());
}

TEST(AnswersTest, EmptyListWritesOnlyTheHeader) {
  const std::string path = TempPath("empty.csv");
  ASSERT_TRUE(WriteAnswers(path, {}).ok());
  EXPECT_EQ(Slurp(path), "frame,reference,score\n");
  StatusOr<std::vector<Answer>> read = ReadAnswers(path);
  ASSERT_TRUE(read.ok()) << read.status().ToString();
  EXPECT_TRUE(read->empty());
  std::remove(path.c_str());
}

TEST(AnswersTest, WriteRejectsBadAnswersAndUnwritablePaths) {
  const std::string path = TempPath("bad_write.csv");
  Status status = WriteAnswers(path, {{3, 3, 0.5}});
  EXPECT_EQ(status.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(status.message(), "answer 0 for " + path +
                                  ": reference 3 is not earlier than frame 3; a claim names an "
                                  "earlier frame, -1 means no claim");
  EXPECT_EQ(WriteAnswers(path, {{1, 0, std::numeric_limits<double>::quiet_NaN()}}).code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(WriteAnswers(TempPath("no_such_dir/a.csv"), {{1, 0, 0.5}}).code(),
            StatusCode::kIoError);
}

TEST(AnswersTest, ReadRejectsMalformedFilesNamingTheLine) {
  const std::string path = TempPath("bad_read.csv");
  auto error = [&](const std::string& text) {
    Spit(path, text);
    StatusOr<std::vector<Answer>> read = ReadAnswers(path);
    EXPECT_FALSE(read.ok()) << text;
    return read.ok() ? std::string() : read.status().message();
  };
  EXPECT_EQ(error("frame,score,reference\n0,-1,1\n"),
            path + ":1: header is 'frame,score,reference', expected 'frame,reference,score'");
  EXPECT_EQ(error("frame,reference,score\n0,-1,1\n1,0\n"),
            path +
                ":3: expected 3 fields (frame,reference,score), found 2; fields are separated "
                "by commas and may not contain one");
  EXPECT_EQ(error("frame,reference,score\n0,-1,1\n1,0,0,5\n"),
            path +
                ":3: expected 3 fields (frame,reference,score), found 4; fields are separated "
                "by commas and may not contain one");
  EXPECT_EQ(error("frame,reference,score\n\n1.5,0,1\n"),
            path + ":3: frame '1.5' is not an integer frame index");
  EXPECT_EQ(error("frame,reference,score\n1,none,1\n"),
            path + ":2: reference 'none' is not an integer frame index or -1");
  EXPECT_EQ(error("frame,reference,score\n1,0,high\n"), path + ":2: score 'high' is not a number");
  EXPECT_EQ(error("frame,reference,score\n1,0,nan\n"),
            path + ":2: score is NaN; give every answer a number (any value for -1)");
  EXPECT_EQ(error("frame,reference,score\n1,-2,0.5\n"),
            path + ":2: reference -2 is neither -1 (no claim) nor a frame");
  EXPECT_EQ(error("frame,reference,score\n2,0,0.5\n3,1,0.5\n2,1,0.4\n"),
            path +
                ":4: frame 2 already has an answer on line 2; write one row per frame (its "
                "best answer)");
  EXPECT_EQ(error(""), path + " is empty; it needs at least a header row");
  std::remove(path.c_str());
  StatusOr<std::vector<Answer>> missing = ReadAnswers(TempPath("missing.csv"));
  EXPECT_EQ(missing.status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace placerec
