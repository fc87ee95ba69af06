// Tests of the sequence rule (sequence_gate.h) on a clock the test moves: order within a run,
// a new run after the restart gap, stored sequences never reused (and the next free one named),
// and what a map holds at start-up.
#include "server/sequence_gate.h"

#include <chrono>
#include <cstdint>
#include <limits>
#include <string>

#include <gtest/gtest.h>

namespace placerec {
namespace {

using Clock = SequenceGate::Clock;
constexpr int64_t kMax = std::numeric_limits<int64_t>::max();

SequenceRuleOptions Gap(double seconds) {
  SequenceRuleOptions options;
  options.restart_gap_s = seconds;
  return options;
}

std::string Refusal(const SequenceGate& gate, const std::string& robot, int64_t sequence,
                    Clock::time_point now) {
  const StatusOr<SequenceGate::Admission> admission = gate.Admit(robot, sequence, now);
  if (admission.ok()) return "admitted";
  EXPECT_EQ(admission.status().code(), StatusCode::kInvalidArgument);
  return admission.status().message();
}

TEST(SequenceRuleOptionsTest, DefaultsPassAndBadGapsAreRefused) {
  std::string error;
  EXPECT_TRUE(SequenceRuleOptions().Check(&error)) << error;
  EXPECT_TRUE(Gap(0).Check(&error)) << error;
  EXPECT_FALSE(Gap(-1).Check(&error));
  EXPECT_NE(error.find("--robot-restart-gap"), std::string::npos) << error;
  EXPECT_FALSE(Gap(std::numeric_limits<double>::quiet_NaN()).Check(&error));
  EXPECT_FALSE(Gap(1e9).Check(&error));
}

TEST(SequenceGateTest, InOrderWithinTheGapAndANewRunAfterIt) {
  const Clock::time_point t0 = Clock::now();
  SequenceGate gate(Gap(5), t0);
  ASSERT_TRUE(gate.Admit("a", 7, t0).ok());  // an unknown robot starts anywhere
  gate.Accepted("a", 7, true, t0);
  EXPECT_EQ(*gate.Admit("a", 8, t0), SequenceGate::Admission::kSameRun);
  EXPECT_NE(Refusal(gate, "a", 6, t0 + std::chrono::seconds(4)).find("is not after 7"),
            std::string::npos);
  EXPECT_NE(Refusal(gate, "a", 7, t0).find("is not after 7"), std::string::npos);
  // Five seconds after its last accepted frame, a lower sequence is a restart.
  EXPECT_EQ(*gate.Admit("a", 0, t0 + std::chrono::seconds(5)), SequenceGate::Admission::kNewRun);
  // Other robots are not affected.
  EXPECT_EQ(*gate.Admit("b", 0, t0), SequenceGate::Admission::kSameRun);
}

TEST(SequenceGateTest, AForgedHugeSequenceLocksTheRobotOutOnlyForTheGap) {
  const Clock::time_point t0 = Clock::now();
  SequenceGate gate(Gap(5), t0);
  for (int64_t s = 0; s < 3; ++s) gate.Accepted("r", s, true, t0);
  gate.Accepted("r", kMax, true, t0 + std::chrono::seconds(1));  // forged
  EXPECT_NE(
      Refusal(gate, "r", 3, t0 + std::chrono::seconds(2)).find("not after " + std::to_string(kMax)),
      std::string::npos);
  EXPECT_EQ(*gate.Admit("r", 3, t0 + std::chrono::seconds(6)), SequenceGate::Admission::kNewRun);
  gate.Accepted("r", 3, true, t0 + std::chrono::seconds(6));
  EXPECT_EQ(*gate.Admit("r", 4, t0 + std::chrono::seconds(6)), SequenceGate::Admission::kSameRun);
  // The forged place stays: its sequence is never taken twice, and nothing is free after it.
  const std::string again = Refusal(gate, "r", kMax, t0 + std::chrono::seconds(60));
  EXPECT_NE(again.find("already in the map"), std::string::npos) << again;
  EXPECT_NE(again.find("no sequence after it is free"), std::string::npos) << again;
  EXPECT_EQ(gate.NextSequence("r"), -1);  // none after the largest
}

TEST(SequenceGateTest, StoredSequencesAreNeverReusedAndTheRobotIsToldToContinueAfterThemAll) {
  const Clock::time_point t0 = Clock::now();
  SequenceGate gate(Gap(0), t0);
  gate.Accepted("r", 0, true, t0);
  gate.Accepted("r", 1, true, t0);
  gate.Accepted("r", 2, false, t0);  // answered, showed nothing new: not stored
  gate.Accepted("r", 3, true, t0);
  gate.Accepted("r", 5, true, t0);
  gate.Accepted("r", 9, true, t0);
  // A robot that restarted from 0 is told to go on after its whole earlier run, not into the
  // gaps between its stored sequences (where its new frames would weave into the old run).
  const std::string reused = Refusal(gate, "r", 0, t0);
  EXPECT_EQ(reused,
            "sequence 0 of robot 'r' is already in the map: a robot's places are named by their "
            "sequence, so a restarted robot must not reuse one; continue from 10, after every "
            "sequence the robot has used");
  EXPECT_NE(Refusal(gate, "r", 3, t0).find("continue from 10"), std::string::npos);
  EXPECT_EQ(gate.NextSequence("r"), 10);
  EXPECT_EQ(gate.NextSequence("other"), -1);
  EXPECT_EQ(*gate.Admit("r", 10, t0), SequenceGate::Admission::kSameRun);
  // A lower sequence that is not stored still begins a new run after the restart gap ...
  EXPECT_EQ(*gate.Admit("r", 2, t0), SequenceGate::Admission::kNewRun);
  EXPECT_EQ(*gate.Admit("r", 4, t0), SequenceGate::Admission::kNewRun);
  // ... and the advice stays after the highest sequence of every run, stored or not.
  gate.Accepted("r", 4, true, t0);
  gate.Accepted("r", 11, false, t0);
  gate.Accepted("r", 7, true, t0);
  EXPECT_NE(Refusal(gate, "r", 5, t0).find("continue from 12"), std::string::npos);
  EXPECT_EQ(gate.NextSequence("r"), 12);
  // What the map holds, as the gate learned it (a refused insert of a stored sequence is looked
  // up among the places; others are not).
  EXPECT_TRUE(gate.IsStored("r", 3));
  EXPECT_FALSE(gate.IsStored("r", 2));
  EXPECT_FALSE(gate.IsStored("r", 11));
  EXPECT_FALSE(gate.IsStored("other", 0));
}

TEST(SequenceGateTest, AFrameOutOfOrderIsToldWhereToContinue) {
  const Clock::time_point t0 = Clock::now();
  SequenceGate gate(Gap(5), t0);
  gate.AddStored("r", 4);
  gate.AddStored("r", 9);
  const std::string late = Refusal(gate, "r", 7, t0 + std::chrono::seconds(1));
  EXPECT_NE(late.find("is not after 9 (frames of a robot must come in order: continue from 10"),
            std::string::npos)
      << late;
}

TEST(SequenceGateTest, AMapsPlacesSetTheLastSequenceAtStartUp) {
  const Clock::time_point start = Clock::now();
  SequenceGate gate(Gap(5), start);
  gate.AddStored("r", 4);
  gate.AddStored("r", 9);
  gate.AddStored("r", 6);
  // Right after start-up the robot's order still holds ...
  EXPECT_NE(Refusal(gate, "r", 7, start + std::chrono::seconds(1)).find("is not after 9"),
            std::string::npos);
  EXPECT_EQ(*gate.Admit("r", 10, start), SequenceGate::Admission::kSameRun);
  // ... and a restart is possible once the gap has passed since start-up.
  EXPECT_EQ(*gate.Admit("r", 0, start + std::chrono::seconds(5)), SequenceGate::Admission::kNewRun);
  EXPECT_NE(Refusal(gate, "r", 6, start + std::chrono::seconds(5)).find("already in the map"),
            std::string::npos);
}

// A place of an active robot that arrives from the shared map (PostgreSQL: another server, or this
// server's own insert coming back through its follower) does not make the robot look silent
// since start-up: the restart gap still counts from its last accepted insert.
TEST(SequenceGateTest, APlaceFromTheSharedMapKeepsAnActiveRobotsTime) {
  const Clock::time_point start = Clock::now();
  SequenceGate gate(Gap(5), start);
  const Clock::time_point t = start + std::chrono::seconds(60);
  ASSERT_TRUE(gate.Admit("r", 10, t).ok());
  gate.Accepted("r", 10, /*stored=*/true, t);
  gate.AddStored("r", 10);
  gate.AddStored("r", 11);
  EXPECT_NE(Refusal(gate, "r", 3, t + std::chrono::seconds(1)).find("is not after 11"),
            std::string::npos);
  EXPECT_EQ(*gate.Admit("r", 12, t + std::chrono::seconds(1)), SequenceGate::Admission::kSameRun);
  // A robot first heard of through the map counts as accepted at start-up.
  gate.AddStored("q", 4);
  EXPECT_EQ(*gate.Admit("q", 1, t), SequenceGate::Admission::kNewRun);
}

}  // namespace
}  // namespace placerec
