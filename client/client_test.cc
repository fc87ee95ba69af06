#include "client/client.h"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "client/fleet.h"
#include "client/run_feeder.h"

namespace placerec {
namespace {

std::string TempPath(const std::string& name) {
  return ::testing::TempDir() + "/placerec_client_test_" + name;
}

cv::Mat TestImage() {
  cv::Mat image(40, 60, CV_8UC3);
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) image.at<cv::Vec3b>(y, x) = cv::Vec3b(x * 4, y * 6, 90);
  }
  return image;
}

std::vector<uint8_t> FileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

TEST(ClientEncodeTest, JpegAndPngGoAsTheyAre) {
  for (const char* ext : {".jpg", ".png"}) {
    const std::string path = TempPath(std::string("image") + ext);
    ASSERT_TRUE(cv::imwrite(path, TestImage()));
    StatusOr<EncodedImage> encoded = EncodeImageFile(path);
    ASSERT_TRUE(encoded.ok()) << encoded.status().ToString();
    EXPECT_EQ(encoded->encoding,
              std::string(ext) == ".jpg" ? FrameEncoding::kJpeg : FrameEncoding::kPng);
    EXPECT_EQ(encoded->width, 0);
    EXPECT_EQ(encoded->bytes, FileBytes(path));
    std::remove(path.c_str());
  }
}

TEST(ClientEncodeTest, OtherFormatsGoRaw) {
  const std::string path = TempPath("image.bmp");
  ASSERT_TRUE(cv::imwrite(path, TestImage()));
  StatusOr<EncodedImage> encoded = EncodeImageFile(path);
  ASSERT_TRUE(encoded.ok()) << encoded.status().ToString();
  EXPECT_EQ(encoded->encoding, FrameEncoding::kRawBgr8);
  EXPECT_EQ(encoded->width, 60);
  EXPECT_EQ(encoded->height, 40);
  ASSERT_EQ(encoded->bytes.size(), 60u * 40u * 3u);
  const cv::Mat image = TestImage();
  EXPECT_EQ(0, std::memcmp(encoded->bytes.data(), image.data, encoded->bytes.size()));
  std::remove(path.c_str());

  cv::Mat grey(20, 30, CV_8UC1, cv::Scalar(7));
  StatusOr<EncodedImage> raw = EncodeRawImage(grey);
  ASSERT_TRUE(raw.ok());
  EXPECT_EQ(raw->encoding, FrameEncoding::kRawGray8);
  EXPECT_EQ(raw->bytes.size(), 600u);
  EXPECT_FALSE(EncodeRawImage(cv::Mat(4, 4, CV_32FC1)).ok());
}

TEST(ClientEncodeTest, MissingAndUnreadableFiles) {
  EXPECT_EQ(EncodeImageFile(TempPath("missing.jpg")).status().code(), StatusCode::kNotFound);
  const std::string path = TempPath("text.txt");
  std::ofstream(path) << "not an image";
  EXPECT_EQ(EncodeImageFile(path).status().code(), StatusCode::kBadImage);
  std::remove(path.c_str());
}

TEST(ClientTest, DescribesAnswers) {
  FrameResult r;
  r.code = AnswerCode::kOk;
  r.keypoints = 800;
  r.objects = 12;
  r.landmarks = 3;
  EXPECT_EQ(DescribeResult(r),
            "ok: 800 keypoints, 12 objects, 3 landmarks stored; no matching place");
  MatchedPlace m;
  m.robot = "left";
  m.sequence = 30;
  m.score = 57;
  m.matched_landmarks = 5;
  r.matches.push_back(m);
  r.loop_closure = true;
  EXPECT_NE(DescribeResult(r).find("best place: robot left #30 (score 57, 5 landmarks matched) -- "
                                   "loop closure"),
            std::string::npos);
  r.matches[0].classes = {{"building", 4}, {"sign", 1}};
  EXPECT_NE(DescribeResult(r).find("(score 57, 5 landmarks matched, seen: building x4, sign) -- "
                                   "loop closure"),
            std::string::npos)
      << DescribeResult(r);
  r.code = AnswerCode::kBadImage;
  r.message = "bytes do not start with a JPEG signature";
  EXPECT_EQ(DescribeResult(r), "bad image: bytes do not start with a JPEG signature");
  EXPECT_STREQ(AnswerCodeName(AnswerCode::kOverloaded), "overloaded");
}

TEST(ClientTest, OptionsAreChecked) {
  std::string error;
  EXPECT_TRUE(ClientOptions().Check(&error));
  EXPECT_TRUE(FeedOptions().Check(&error));
  ClientOptions bad;
  bad.timeout_s = 0;
  EXPECT_FALSE(bad.Check(&error));
  FeedOptions window;
  window.window = 0;
  EXPECT_FALSE(window.Check(&error));
}

TEST(ClientTest, BadUrlIsReported) {
  ClientOptions options;
  options.lcm_url = "nosuchprovider://";
  StatusOr<std::unique_ptr<PlacerecClient>> client = PlacerecClient::Connect(options);
  ASSERT_FALSE(client.ok());
  EXPECT_NE(client.status().message().find("nosuchprovider://"), std::string::npos);
}

// Publishes frame 3 of robot "left" (three bytes that are no image).
StatusOr<PendingFrame> PublishFrameOfLeft(PlacerecClient* client) {
  OutgoingFrame frame;
  frame.robot = "left";
  frame.sequence = 3;
  frame.image.bytes = {1, 2, 3};
  return client->Publish(frame);
}

// memq:// keeps messages inside this process, so no server answers: the wait times out with a
// message instead of hanging.
TEST(ClientTest, NoServerMeansTimeout) {
  ClientOptions options;
  options.lcm_url = "memq://";
  StatusOr<std::unique_ptr<PlacerecClient>> client = PlacerecClient::Connect(options);
  ASSERT_TRUE(client.ok()) << client.status().ToString();
  StatusOr<PendingFrame> pending = PublishFrameOfLeft(client->get());
  ASSERT_TRUE(pending.ok()) << pending.status().ToString();
  const FrameResult result = (*client)->Wait(*pending, 0.2);
  EXPECT_EQ(result.code, AnswerCode::kTimeout);
  EXPECT_EQ(result.sequence, 3);
  EXPECT_NE(result.message.find("no answer within 0.2 s"), std::string::npos);
  EXPECT_FALSE((*client)->WaitForStatus(0.1).ok());
}

// The last part of a wait, too short for a frame sent again to be answered in time, is waited
// idle: it was a busy loop (the passed time to send again woke the wait at once, over and over).
TEST(ClientTest, TheEndOfAWaitWithoutResendingIsIdle) {
  ClientOptions options;
  options.lcm_url = "memq://";
  options.retry_after_s = 1.0;
  StatusOr<std::unique_ptr<PlacerecClient>> client = PlacerecClient::Connect(options);
  ASSERT_TRUE(client.ok()) << client.status().ToString();
  StatusOr<PendingFrame> pending = PublishFrameOfLeft(client->get());
  ASSERT_TRUE(pending.ok()) << pending.status().ToString();
  // At 1 s, 0.4 s before the end, less than half the retry interval is left: not sent again.
  const std::clock_t cpu_before = std::clock();
  const FrameResult result = (*client)->Wait(*pending, 1.4);
  const double cpu_s = static_cast<double>(std::clock() - cpu_before) / CLOCKS_PER_SEC;
  EXPECT_EQ(result.code, AnswerCode::kTimeout);
  // A busy loop spends much of the last 0.4 s on a core; an idle wait next to nothing.
  EXPECT_LT(cpu_s, 0.1) << "the wait kept a core busy";
}

// A run of one frame, `image`, for the fleet to replay.
placerec::Run OneFrameRun(const std::string& image) {
  placerec::Run run;
  run.name = "one";
  run.frames.push_back({0, "r", image, 1000000});
  return run;
}

// A client on LCM's in-process queue, where nothing answers, that never resends.
StatusOr<std::unique_ptr<PlacerecClient>> ClientWithoutServer() {
  ClientOptions options;
  options.lcm_url = "memq://";
  options.retry_after_s = 0;
  return PlacerecClient::Connect(options);
}

// A frame's timeout runs from its publication. The fleet's collector waited a whole timeout for
// each frame in turn, so with no server 10 frames of a 1 s run took 10 timeouts (20 s) instead
// of about one, and an answer later than the timeout counted as ok.
TEST(FleetTest, NoServerEndsOneTimeoutAfterTheLastFrame) {
  const std::string image = TempPath("fleet.png");
  ASSERT_TRUE(cv::imwrite(image, TestImage()));
  const placerec::Run run = OneFrameRun(image);
  StatusOr<std::unique_ptr<PlacerecClient>> client = ClientWithoutServer();
  ASSERT_TRUE(client.ok()) << client.status().ToString();
  FleetOptions options;
  options.robots = 1;
  options.rate_hz = 10;
  options.duration_s = 1;
  options.timeout_s = 2;
  options.progress = false;
  const auto started = std::chrono::steady_clock::now();
  StatusOr<FleetReport> report = RunFleet(client->get(), run, options);
  const double took_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->frames, 10);
  EXPECT_EQ(report->summary["timed_out"].get<int>(), 10);
  EXPECT_EQ(report->summary["answered_ok_per_second"].get<double>(), 0.0);
  EXPECT_LT(took_s, 5.0) << "10 frames of 1 s with a 2 s timeout";
  std::remove(image.c_str());
}

// Options a fleet cannot run with: a duration of more frames than an int holds sent one frame,
// and a long prefix was cut to 31 bytes, so that every robot had the same id.
TEST(FleetTest, OptionsThatCannotWorkAreRefused) {
  FleetOptions options;
  std::string error;
  ASSERT_TRUE(options.Check(&error)) << error;
  EXPECT_EQ(FleetRobotId("fleet", 7), "fleet007");
  EXPECT_EQ(FleetRobotId("fleet", 1234), "fleet1234");
  options.duration_s = 1e10;
  EXPECT_FALSE(options.Check(&error));
  options.duration_s = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(options.Check(&error));
  options.duration_s = 60;
  options.robot_prefix = "site_alpha_building_7_floor_2_lift_lobby_east_";
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("--robot-prefix"), std::string::npos) << error;
  options.robot_prefix = "site/a";
  EXPECT_FALSE(options.Check(&error));
  options.robot_prefix = "site_alpha_building_7_floor_2_";
  EXPECT_TRUE(options.Check(&error)) << error;
}

// Ctrl-C in a fleet run lost everything: nothing stopped it, and the process died without its
// report. A stop now ends the sending at once; the report covers the frames sent.
TEST(FleetTest, AStopEndsTheSendingAndTheReportSaysSo) {
  const std::string image = TempPath("fleet_stop.png");
  ASSERT_TRUE(cv::imwrite(image, TestImage()));
  const placerec::Run run = OneFrameRun(image);
  StatusOr<std::unique_ptr<PlacerecClient>> client = ClientWithoutServer();
  ASSERT_TRUE(client.ok()) << client.status().ToString();
  std::atomic<bool> stop{false};
  FleetOptions options;
  options.robots = 2;
  options.rate_hz = 0.05;  // one frame each 20 s: the stop comes while the robots wait
  options.duration_s = 100;
  options.timeout_s = 0.5;
  options.progress = false;
  options.stop = &stop;
  std::thread stopper([&stop] {
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    stop = true;
  });
  const auto started = std::chrono::steady_clock::now();
  StatusOr<FleetReport> report = RunFleet(client->get(), run, options);
  const double took_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  stopper.join();
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_LT(took_s, 3.0);
  EXPECT_TRUE(report->summary["interrupted"].get<bool>());
  EXPECT_LE(report->frames, 2);  // each robot's first frame at most
  std::remove(image.c_str());
}

}  // namespace
}  // namespace placerec
