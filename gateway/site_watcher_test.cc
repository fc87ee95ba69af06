#include "gateway/site_watcher.h"

#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <thread>

#include "gateway/gateway.h"
#include "placerec/change_t.hpp"
#include "placerec/result_t.hpp"

namespace placerec {
namespace {

// LCM's in-process queue: nothing goes on a network.
std::unique_ptr<SiteWatcher> StartWatcher() {
  StatusOr<std::unique_ptr<SiteWatcher>> watcher = SiteWatcher::Start("memq://", 5);
  EXPECT_TRUE(watcher.ok()) << watcher.status().ToString();
  return watcher.ok() ? std::move(*watcher) : nullptr;
}

result_t Answer(const std::string& robot) {
  result_t answer{};
  answer.robot = robot;
  answer.status = result_t::STATUS_OK;
  return answer;
}

change_t Alarm(const std::string& robot) {
  change_t change{};
  change.robot = robot;
  change.place_robot = "left";
  change.kind = change_t::KIND_APPEARED;
  return change;
}

// Anybody on the LCM network can publish: a robot id the server would refuse (one that is no
// UTF-8 made every later site overview fail to print) is not listed, and the list of robots
// stays bounded.
TEST(SiteWatcherTest, MessagesNamingNoValidRobotAreIgnoredAndRobotsAreBounded) {
  std::unique_ptr<SiteWatcher> watcher = StartWatcher();
  ASSERT_NE(watcher, nullptr);
  watcher->Hear(Answer("evil\xff"));
  watcher->Hear(Alarm("evil\xff"));
  watcher->Hear(Answer("right"));
  watcher->Hear(Answer("right"));
  nlohmann::json overview = watcher->Overview();
  ASSERT_EQ(overview["robots"].size(), 1u) << JsonText(overview);
  EXPECT_EQ(overview["robots"][0]["robot"], "right");
  EXPECT_EQ(overview["robots"][0]["frames"], 2);
  EXPECT_TRUE(overview["alarms"].empty()) << JsonText(overview);
  EXPECT_NO_THROW(JsonText(overview));

  for (size_t i = 0; i < SiteWatcher::kMaxRobots + 10; ++i) {
    watcher->Hear(Answer("robot-" + std::to_string(i)));
  }
  EXPECT_EQ(watcher->Overview()["robots"].size(), SiteWatcher::kMaxRobots);
}

// The gateway's own devices are not shown: where a person asked from, and their photo in an
// alarm, are nobody else's business (every device could read them in the overview).
TEST(SiteWatcherTest, TheGatewaysDevicesAreNotShown) {
  StatusOr<std::unique_ptr<SiteWatcher>> started = SiteWatcher::Start("memq://", 5, {"phone-anna"});
  ASSERT_TRUE(started.ok()) << started.status().ToString();
  SiteWatcher& watcher = **started;
  result_t asked = Answer("phone-anna");
  asked.loop_closure = true;
  asked.num_matches = 1;
  asked.matches.resize(1);
  asked.matches[0].robot = "left";
  watcher.Hear(asked);
  watcher.Hear(Alarm("phone-anna"));
  result_t patrol = asked;
  patrol.robot = "right";
  watcher.Hear(patrol);
  watcher.Hear(Alarm("right"));
  const nlohmann::json overview = watcher.Overview();
  ASSERT_EQ(overview["robots"].size(), 1u) << JsonText(overview);
  EXPECT_EQ(overview["robots"][0]["robot"], "right");
  ASSERT_EQ(overview["loop_closures"].size(), 1u) << JsonText(overview);
  EXPECT_EQ(overview["loop_closures"][0]["robot"], "right");
  ASSERT_EQ(overview["alarms"].size(), 1u) << JsonText(overview);
  EXPECT_EQ(overview["alarms"][0]["robot"], "right");
}

// A device added to the gateway's tokens file while it runs (SIGHUP) is hidden from then on,
// and what was kept of it before (an id heard as a robot's) is forgotten.
TEST(SiteWatcherTest, RobotsHiddenLaterAreForgotten) {
  std::unique_ptr<SiteWatcher> watcher = StartWatcher();
  ASSERT_NE(watcher, nullptr);
  result_t asked = Answer("phone-ben");
  asked.loop_closure = true;
  asked.num_matches = 1;
  asked.matches.resize(1);
  asked.matches[0].robot = "left";
  watcher->Hear(asked);
  watcher->Hear(Alarm("phone-ben"));
  result_t patrol = asked;
  patrol.robot = "right";
  watcher->Hear(patrol);
  ASSERT_EQ(watcher->Overview()["robots"].size(), 2u);
  watcher->HideRobots({"phone-ben"});
  watcher->Hear(asked);
  watcher->Hear(Alarm("phone-ben"));
  const nlohmann::json overview = watcher->Overview();
  EXPECT_EQ(JsonText(overview).find("phone-ben"), std::string::npos) << JsonText(overview);
  ASSERT_EQ(overview["robots"].size(), 1u) << JsonText(overview);
  ASSERT_EQ(overview["loop_closures"].size(), 1u) << JsonText(overview);
  EXPECT_EQ(overview["loop_closures"][0]["robot"], "right");
}

// Text that is no UTF-8 (a decoded URL path) is printed with replacement characters instead of
// an exception.
TEST(SiteWatcherTest, JsonTextReplacesBytesThatAreNoUtf8) {
  const std::string text = JsonText({{"error", std::string("no such page: /\xff")}});
  EXPECT_NE(text.find("no such page"), std::string::npos) << text;
}

// Alarm ids keep increasing across a restart of the gateway, so that a page left open never
// shows an earlier run's pictures for a new alarm of the same id.
TEST(SiteWatcherTest, AlarmIdsIncreaseAcrossARestart) {
  int64_t last = 0;
  {
    std::unique_ptr<SiteWatcher> first = StartWatcher();
    ASSERT_NE(first, nullptr);
    for (int i = 0; i < 3; ++i) first->Hear(Alarm("right"));
    const nlohmann::json alarms = first->Overview()["alarms"];
    ASSERT_EQ(alarms.size(), 3u);
    last = alarms[0]["id"].get<int64_t>();  // newest first
    EXPECT_EQ(alarms[2]["id"].get<int64_t>(), last - 2);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(5));
  std::unique_ptr<SiteWatcher> second = StartWatcher();
  ASSERT_NE(second, nullptr);
  second->Hear(Alarm("right"));
  EXPECT_GT(second->Overview()["alarms"][0]["id"].get<int64_t>(), last);
}

}  // namespace
}  // namespace placerec
