#include "common/eval/scoring.h"

#include <gtest/gtest.h>

namespace placerec {
namespace {

// Ten frames of one robot. Revisit frames: 5 (of 0 and 1), 6 (of 1), 7 (of 2), 8 (of 3); frame 9
// is new. So there are 4 revisit frames.
placerec::Run TenFrameRun() {
  placerec::Run run;
  run.name = "ten";
  for (int i = 0; i < 10; ++i) run.frames.push_back({i, "r", "f.jpg", i});
  run.positives = {{5, 0}, {5, 1}, {6, 1}, {7, 2}, {8, 3}};
  run.is_revisit = {false, false, false, false, false, true, true, true, true, false};
  run.num_revisits = 4;
  return run;
}

TEST(ScoringTest, HandWorkedCaseWithTies) {
  const placerec::Run run = TenFrameRun();
  const std::vector<Answer> answers = {
      {4, -1, 0.95},  // no claim: ignored whatever its score
      {5, 0, 0.9},    // TP
      {6, 1, 0.8},    // TP  } same score: enter together
      {7, 0, 0.8},    // FP  }
      {8, 3, 0.5},    // TP
      {9, 4, 0.3},    // FP (9 is not a revisit)
      {0, -1, 0.0},   // no claim; frames 1..3 have no answer at all
  };
  // By hand, sweeping the distinct claim scores downwards (4 revisit frames):
  //   threshold  TP FP  precision  recall  F1                                 AP term
  //   0.9         1  0  1          1/4     2*1*(1/4)/(5/4) = 2/5              1/4 * 1
  //   0.8         2  1  2/3        2/4     2*(2/3)*(1/2)/(7/6) = 4/7          1/4 * 2/3
  //   0.5         3  1  3/4        3/4     3/4                                1/4 * 3/4
  //   0.3         3  2  3/5        3/4     2*(3/5)*(3/4)/(27/20) = 2/3        0 * 3/5
  // R@100P = 1/4 at 0.9 (without ties, 6 before 7 would wrongly give 1/2 at 0.8).
  // max F1 = 3/4 at 0.5 with P = R = 3/4.
  // AP = 1/4 + 1/6 + 3/16 = (12 + 8 + 9) / 48 = 29/48.
  StatusOr<RunScore> score = ScoreAnswers(run, answers);
  ASSERT_TRUE(score.ok()) << score.status().ToString();
  EXPECT_EQ(score->frames, 10);
  EXPECT_EQ(score->revisit_frames, 4);
  EXPECT_EQ(score->answered_frames, 5);
  EXPECT_DOUBLE_EQ(score->recall_at_100_precision, 0.25);
  EXPECT_DOUBLE_EQ(score->threshold_at_100_precision, 0.9);
  EXPECT_DOUBLE_EQ(score->max_f1, 0.75);
  EXPECT_DOUBLE_EQ(score->threshold_at_max_f1, 0.5);
  EXPECT_DOUBLE_EQ(score->precision_at_max_f1, 0.75);
  EXPECT_DOUBLE_EQ(score->recall_at_max_f1, 0.75);
  EXPECT_DOUBLE_EQ(score->average_precision, 29.0 / 48.0);

  ASSERT_EQ(score->curve.size(), 4u);
  const double thresholds[] = {0.9, 0.8, 0.5, 0.3};
  const int tps[] = {1, 2, 3, 3};
  const int fps[] = {0, 1, 1, 2};
  const double precisions[] = {1.0, 2.0 / 3.0, 0.75, 0.6};
  const double recalls[] = {0.25, 0.5, 0.75, 0.75};
  for (int i = 0; i < 4; ++i) {
    SCOPED_TRACE(i);
    EXPECT_DOUBLE_EQ(score->curve[i].threshold, thresholds[i]);
    EXPECT_EQ(score->curve[i].true_positives, tps[i]);
    EXPECT_EQ(score->curve[i].false_positives, fps[i]);
    EXPECT_DOUBLE_EQ(score->curve[i].precision, precisions[i]);
    EXPECT_DOUBLE_EQ(score->curve[i].recall, recalls[i]);
  }

  // The order of the answers does not matter.
  std::vector<Answer> reversed(answers.rbegin(), answers.rend());
  StatusOr<RunScore> again = ScoreAnswers(run, reversed);
  ASSERT_TRUE(again.ok());
  EXPECT_DOUBLE_EQ(again->recall_at_100_precision, 0.25);
  EXPECT_DOUBLE_EQ(again->average_precision, 29.0 / 48.0);
}

TEST(ScoringTest, SummariesCarryTheScoreAndTheDecision) {
  const placerec::Run run = TenFrameRun();
  StatusOr<RunScore> score = ScoreAnswers(run, {{5, 0, 0.9}, {9, 4, 0.3}});
  ASSERT_TRUE(score.ok());
  const nlohmann::json s = ScoreSummary(run, 10, *score);
  EXPECT_EQ(s["run"], "ten");
  EXPECT_EQ(s["revisit_frames"], 4);
  EXPECT_EQ(s["answered_frames"], 2);
  EXPECT_DOUBLE_EQ(s["recall_at_100_precision"].get<double>(), 0.25);
  const nlohmann::json d = DecisionSummary(1, 1, 4);
  EXPECT_DOUBLE_EQ(d["precision"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(d["recall"].get<double>(), 0.25);
  EXPECT_DOUBLE_EQ(DecisionSummary(0, 0, 0)["precision"].get<double>(), 1.0);
}

TEST(ScoringTest, NoClaimsScoresZero) {
  const placerec::Run run = TenFrameRun();
  for (const std::vector<Answer>& answers :
       {std::vector<Answer>{}, std::vector<Answer>{{5, -1, 0.9}, {6, -1, 0.1}}}) {
    StatusOr<RunScore> score = ScoreAnswers(run, answers);
    ASSERT_TRUE(score.ok()) << score.status().ToString();
    EXPECT_EQ(score->answered_frames, 0);
    EXPECT_EQ(score->recall_at_100_precision, 0.0);
    EXPECT_EQ(score->max_f1, 0.0);
    EXPECT_EQ(score->average_precision, 0.0);
    EXPECT_TRUE(score->curve.empty());
  }
}

TEST(ScoringTest, AllCorrectScoresOne) {
  const placerec::Run run = TenFrameRun();
  // Distinct scores, and a correct claim for every revisit frame (5 may name 0 or 1).
  StatusOr<RunScore> score =
      ScoreAnswers(run, {{5, 1, 0.4}, {6, 1, 0.9}, {7, 2, 0.7}, {8, 3, 0.6}, {9, -1, 0.8}});
  ASSERT_TRUE(score.ok()) << score.status().ToString();
  EXPECT_EQ(score->recall_at_100_precision, 1.0);
  EXPECT_EQ(score->threshold_at_100_precision, 0.4);
  EXPECT_EQ(score->max_f1, 1.0);
  EXPECT_EQ(score->average_precision, 1.0);
  EXPECT_EQ(score->curve.size(), 4u);
}

TEST(ScoringTest, FirstClaimWrongGivesNoRecallAtFullPrecision) {
  const placerec::Run run = TenFrameRun();
  // 0.9: TP0 FP1 (P 0, R 0); 0.5: TP1 FP1 (P 1/2, R 1/4). AP = 0*0 + 1/4*1/2 = 1/8;
  // max F1 = 2*(1/2)*(1/4)/(3/4) = 1/3.
  StatusOr<RunScore> score = ScoreAnswers(run, {{9, 0, 0.9}, {6, 1, 0.5}});
  ASSERT_TRUE(score.ok()) << score.status().ToString();
  EXPECT_EQ(score->recall_at_100_precision, 0.0);
  EXPECT_EQ(score->threshold_at_100_precision, 0.0);
  EXPECT_DOUBLE_EQ(score->max_f1, 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(score->average_precision, 0.125);
}

TEST(ScoringTest, RejectsDuplicateAndOutOfRunAnswers) {
  const placerec::Run run = TenFrameRun();
  StatusOr<RunScore> score = ScoreAnswers(run, {{5, 0, 0.9}, {5, 1, 0.8}});
  ASSERT_FALSE(score.ok());
  EXPECT_EQ(score.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(score.status().message(), "frame 5 has two answers; give one per frame (its best)");

  score = ScoreAnswers(run, {{10, 0, 0.9}});
  ASSERT_FALSE(score.ok());
  EXPECT_EQ(score.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(score.status().message(),
            "answer for frame 10, but run 'ten' has frames 0..9; were the answers computed on "
            "another run?");
  EXPECT_FALSE(ScoreAnswers(run, {{-1, -1, 0.9}}).ok());
  // Even a "no claim" answer must be for a frame of the run.
  EXPECT_FALSE(ScoreAnswers(run, {{12, -1, 0.0}}).ok());
}

}  // namespace
}  // namespace placerec
