// placerec-gateway end to end (issue 26 items 3 and 4), in a private network namespace: a robot
// inserts a real run over LCM; a field device asks over HTTPS (certificate checked against the
// self-signed one scripts/make-cert.sh made) and gets the places LCM gives for the same frames;
// every refusal is a JSON error with the right status and the map does not change; and a real
// browser (headless Chromium driven through chromedriver's WebDriver protocol) uploads a real
// frame on the gateway's page and shows the answer. The browser's screenshot is kept as
// build/test-artefacts/gateway-page.png.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <openssl/evp.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>
#include <httplib.h>
#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "client/client.h"
#include "common/eval/run.h"
#include "common/util/paths.h"
#include "gateway/gateway.h"
#include "placerec/change_t.hpp"
#include "proto/channels.h"
#include "tests/service_harness.h"

namespace placerec {
namespace {

using testing_service::BinaryPath;
using testing_service::ChildProcess;
using testing_service::MakeTempDir;
using testing_service::RemoveTempDir;
using testing_service::StartServer;
using testing_service::StopServer;
using testing_service::Tail;
using testing_service::TestLcmUrl;

constexpr int kPort = 18443;
constexpr char kToken[] = "field-device-token-0001";
constexpr char kOtherToken[] = "field-device-token-0002";
constexpr char kExpiredToken[] = "field-device-token-0003";
constexpr char kOwnKeyToken[] = "field-device-token-0004";  // signed with its own key "phone-4"
constexpr int kMapped = 40;  // corridor frames 0..39 go into the map; revisits begin at 40
constexpr int kBurst = 30;

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

class GatewayTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const Status network = testing_service::EnterPrivateNetwork();
    if (!network.ok()) GTEST_SKIP() << "gateway tests skipped: " << network.message();
    const std::string data = DataDir("", PLACEREC_DEFAULT_DATA_DIR) + "/rtabmap_indoor";
    StatusOr<placerec::Run> run = LoadRun(data, "corridor_loop");
    if (!run.ok())
      GTEST_SKIP() << "needs the shared data (PLACEREC_DATA): " << run.status().ToString();
    run_ = std::move(*run);
    dir_ = MakeTempDir("placerec_gateway_");
    ASSERT_FALSE(dir_.empty());
    const std::string make_cert = std::string(PLACEREC_SOURCE_DIR) + "/scripts/make-cert.sh";
    ASSERT_EQ(std::system(("bash '" + make_cert + "' '" + dir_ + "' >/dev/null").c_str()), 0);
    std::ofstream(dir_ + "/tokens") << "# test devices\n"
                                    << kToken << " phone-1\n"
                                    << kOtherToken << " phone-2\n"
                                    << kExpiredToken << " phone-3 expires=2020-01-01T00:00:00Z\n"
                                    << kOwnKeyToken << " phone-4 key=phone-4\n";

    // The robots may insert; the gateway and phone-4 only query (the gateway never inserts).
    // The gateway holds a copy of the keys: the server's file is changed by a test.
    keys_ = testing_service::WriteTestKeys(
        dir_ + "/keys", {{"robots", "both"}, {"gateway", "query"}, {"phone-4", "query"}});
    const std::string gateway_keys = dir_ + "/gateway-keys";
    std::filesystem::copy_file(keys_, gateway_keys);
    ClientOptions options;
    options.lcm_url = TestLcmUrl();
    options.key_file = keys_;
    options.key_id = "robots";
    options.timeout_s = 120;
    StatusOr<std::unique_ptr<PlacerecClient>> client = PlacerecClient::Connect(options);
    ASSERT_TRUE(client.ok()) << client.status().ToString();
    client_ = std::move(*client);
    StatusOr<std::unique_ptr<ChildProcess>> server =
        StartServer(dir_ + "/map.db", {"--keys", keys_}, dir_ + "/server.log", client_.get());
    ASSERT_TRUE(server.ok()) << server.status().ToString();
    server_ = std::move(*server);
    for (int f = 0; f < kMapped; ++f) {
      const FrameResult r = client_->Send(Frame(f, /*insert=*/true));
      ASSERT_TRUE(r.ok()) << DescribeResult(r) << Tail(server_->log_path());
    }

    gateway_ =
        StartGateway(kPort, {"--max-upload-bytes", "2000000", "--burst", std::to_string(kBurst)});
    ASSERT_NE(gateway_, nullptr);
  }

  // Starts placerec-gateway on `port` with the fixture's certificate, tokens, keys and map plus
  // `extra` flags, and waits until it answers; null (with the test failed) when it does not.
  std::unique_ptr<ChildProcess> StartGateway(int port, const std::vector<std::string>& extra) {
    std::vector<std::string> argv = {BinaryPath("placerec-gateway"),
                                     "--cert",
                                     dir_ + "/cert.pem",
                                     "--key",
                                     dir_ + "/key.pem",
                                     "--tokens",
                                     dir_ + "/tokens",
                                     "--key-file",
                                     dir_ + "/gateway-keys",
                                     "--key-id",
                                     "gateway",
                                     "--db",
                                     dir_ + "/map.db",
                                     "--port",
                                     std::to_string(port),
                                     "--lcm-url",
                                     TestLcmUrl()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    const std::string log = dir_ + "/gateway-" + std::to_string(port) + ".log";
    StatusOr<std::unique_ptr<ChildProcess>> gateway = ChildProcess::Start(argv, log);
    EXPECT_TRUE(gateway.ok()) << gateway.status().ToString();
    if (!gateway.ok()) return nullptr;
    // Listening once a request gets any HTTP answer.
    for (int i = 0; i < 100; ++i) {
      httplib::Result r = Https(port)->Get("/");
      if (r) return std::move(*gateway);
      if (!(*gateway)->running()) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    ADD_FAILURE() << "the gateway did not answer within 10 s\n" << Tail(log);
    return nullptr;
  }

  void TearDown() override {
    gateway_.reset();
    server_.reset();
    client_.reset();
    RemoveTempDir(dir_);
  }

  // Frame f of the corridor; inserted as robot "robot", asked as "field" (a device that inserts
  // nothing, so no recent past of its own is left out of its answers).
  OutgoingFrame Frame(int f, bool insert) const {
    OutgoingFrame frame;
    frame.robot = insert ? "robot" : "field";
    frame.sequence = f;
    frame.utime = run_.frames[f].utime;
    frame.insert = insert;
    StatusOr<EncodedImage> image = EncodeImageFile(run_.frames[f].image);
    EXPECT_TRUE(image.ok());
    if (image.ok()) frame.image = std::move(*image);
    return frame;
  }

  // An HTTPS client that checks the gateway's certificate against the test's own.
  std::unique_ptr<httplib::SSLClient> Https(int port = kPort) const {
    auto client = std::make_unique<httplib::SSLClient>("127.0.0.1", port);
    client->set_ca_cert_path((dir_ + "/cert.pem").c_str());
    client->enable_server_certificate_verification(true);
    client->set_read_timeout(120, 0);
    return client;
  }

  static httplib::Headers Bearer(const std::string& token) {
    return {{"Authorization", "Bearer " + token}};
  }

  // Status and JSON body of a request; the body must be JSON whatever the status.
  static std::pair<int, nlohmann::json> Json(const httplib::Result& r) {
    EXPECT_TRUE(r) << "no HTTP answer: " << httplib::to_string(r.error());
    if (!r) return {0, nullptr};
    const nlohmann::json body = nlohmann::json::parse(r->body, nullptr, false);
    EXPECT_FALSE(body.is_discarded()) << r->status << " " << r->body;
    EXPECT_EQ(r->get_header_value("Content-Type"), "application/json");
    return {r->status, body};
  }

  int64_t MapPlaces() {
    StatusOr<ServerStatus> status = client_->WaitForStatus(10);
    EXPECT_TRUE(status.ok());
    return status.ok() ? status->map_places : -1;
  }

  placerec::Run run_;
  std::string dir_;
  std::string keys_;
  std::unique_ptr<PlacerecClient> client_;
  std::unique_ptr<ChildProcess> server_;
  std::unique_ptr<ChildProcess> gateway_;
};

// The same frames asked over LCM and over HTTPS name the same places with the same scores.
TEST_F(GatewayTest, HttpsQueriesAnswerTheSamePlacesAsLcm) {
  const int64_t places = MapPlaces();
  int recognised = 0;
  std::vector<double> https_ms, lcm_ms;  // per frame: a new TLS connection each, as a phone
  for (int f = kMapped; f < kMapped + 8; ++f) {
    const OutgoingFrame frame = Frame(f, /*insert=*/false);
    const FrameResult lcm = client_->Send(frame);
    ASSERT_TRUE(lcm.ok()) << DescribeResult(lcm);
    const std::string bytes(frame.image.bytes.begin(), frame.image.bytes.end());
    const auto start = std::chrono::steady_clock::now();
    const auto [status, body] =
        Json(Https()->Post("/v1/query", Bearer(kToken), bytes, "image/jpeg"));
    https_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
            .count());
    lcm_ms.push_back(lcm.latency_ms);
    ASSERT_EQ(status, 200) << body.dump();
    EXPECT_EQ(body["device"], "phone-1");
    EXPECT_EQ(body["loop_closure"].get<bool>(), lcm.loop_closure) << f;
    ASSERT_EQ(body["matches"].size(), lcm.matches.size()) << f;
    for (size_t m = 0; m < lcm.matches.size(); ++m) {
      EXPECT_EQ(body["matches"][m]["place_id"].get<int64_t>(), lcm.matches[m].place_id) << f;
      EXPECT_EQ(body["matches"][m]["score"].get<double>(), lcm.matches[m].score) << f;
      EXPECT_EQ(body["matches"][m]["robot"], "robot");
    }
    EXPECT_EQ(body["change_checked"].get<bool>(), lcm.change_checked) << f;
    EXPECT_EQ(body["changes"].size(), lcm.changes.size()) << f;
    if (!lcm.matches.empty()) ++recognised;
  }
  EXPECT_GT(recognised, 0) << "no frame was recognised: the comparison says nothing";
  std::sort(https_ms.begin(), https_ms.end());
  std::sort(lcm_ms.begin(), lcm_ms.end());
  const double https_median = (https_ms[3] + https_ms[4]) / 2,
               lcm_median = (lcm_ms[3] + lcm_ms[4]) / 2;
  std::printf(
      "query latency, median of 8 frames: HTTPS through the gateway %.1f ms, LCM udpm "
      "%.1f ms (ratio %.2f)\n",
      https_median, lcm_median, https_median / lcm_median);
  RecordProperty("https_median_ms", std::to_string(https_median));
  RecordProperty("udpm_median_ms", std::to_string(lcm_median));
  // A multipart upload (curl -F image=@photo.jpg) is the same query.
  const std::string bytes = ReadBytes(run_.frames[kMapped].image);
  httplib::MultipartFormDataItems form = {{"image", bytes, "photo.jpg", "image/jpeg"}};
  const auto [status, body] = Json(Https()->Post("/v1/query", Bearer(kToken), form));
  EXPECT_EQ(status, 200) << body.dump();
  EXPECT_EQ(MapPlaces(), places) << "queries through the gateway changed the map";
}

// The matched place's stored picture comes from the server's map (--db), as the page shows it
// beside the photo; a place the map does not hold has none.
TEST_F(GatewayTest, TheMatchedPlacesPictureComesFromTheMap) {
  const std::string photo = ReadBytes(run_.frames[kMapped + 2].image);
  const auto [status, body] = Json(Https()->Post("/v1/query", Bearer(kToken), photo, "image/jpeg"));
  ASSERT_EQ(status, 200) << body.dump();
  ASSERT_FALSE(body["matches"].empty()) << body.dump();
  const std::string link = body["matches"][0]["thumbnail"].get<std::string>();
  httplib::Result picture = Https()->Get(link, Bearer(kToken));
  ASSERT_TRUE(picture);
  ASSERT_EQ(picture->status, 200) << picture->body;
  EXPECT_EQ(picture->get_header_value("Content-Type"), "image/jpeg");
  ASSERT_GT(picture->body.size(), 100u);
  EXPECT_EQ(picture->body.substr(0, 2), "\xff\xd8") << "not a JPEG";
  const auto [code, error] = Json(Https()->Get("/v1/places/999999/thumbnail", Bearer(kToken)));
  EXPECT_EQ(code, 404) << error.dump();
  EXPECT_NE(error["error"].get<std::string>().find("not in the map"), std::string::npos);
  httplib::Result anonymous = Https()->Get(link);
  ASSERT_TRUE(anonymous);
  EXPECT_EQ(anonymous->status, 401);
}

// A scene-change alarm the server publishes on PLACEREC_CHANGE shows in the site overview, with
// its two pictures served to devices with a token. (The server's side of alarms is
// tests/change_service_test.cc; here the alarm is published as the server does.)
TEST_F(GatewayTest, SceneChangeAlarmsShowInTheSiteOverview) {
  change_t alarm;
  alarm.utime = 1'700'000'000'000'000;
  alarm.robot = "robot";
  alarm.sequence = 41;
  alarm.request_id = 7;
  alarm.frame_utime = run_.frames[41].utime;
  alarm.place_id = 3;
  alarm.place_robot = "robot";
  alarm.place_sequence = 2;
  alarm.place_utime = run_.frames[2].utime;
  alarm.change_index = 0;
  alarm.num_frame_changes = 1;
  alarm.kind = change_t::KIND_APPEARED;
  const int32_t box[4] = {100, 80, 60, 40};
  std::copy(box, box + 4, alarm.box);
  alarm.object_class = "car";
  alarm.confidence = 0.75f;
  alarm.frame_width = 640;
  alarm.frame_height = 480;
  const std::string frame_jpeg = ReadBytes(run_.frames[41].image);
  const std::string place_jpeg = ReadBytes(run_.frames[2].image);
  alarm.frame_jpeg.assign(frame_jpeg.begin(), frame_jpeg.end());
  alarm.frame_jpeg_size = static_cast<int32_t>(alarm.frame_jpeg.size());
  alarm.place_jpeg.assign(place_jpeg.begin(), place_jpeg.end());
  alarm.place_jpeg_size = static_cast<int32_t>(alarm.place_jpeg.size());
  lcm::LCM lcm(TestLcmUrl());
  ASSERT_TRUE(lcm.good());
  // First a forged alarm whose frame_jpeg_size reads -1 (LCM's decoder would resize a vector to
  // that many bytes and throw): the gateway drops it and keeps serving.
  {
    change_t forged = alarm;
    forged.frame_jpeg.clear();
    forged.frame_jpeg_size = 0;
    forged.place_jpeg.clear();
    forged.place_jpeg_size = 0;
    std::vector<uint8_t> bytes(forged.getEncodedSize());
    ASSERT_GT(forged.encode(bytes.data(), 0, static_cast<int>(bytes.size())), 0);
    // The last 8 bytes are frame_jpeg_size and place_jpeg_size (both arrays empty).
    std::fill(bytes.end() - 8, bytes.end() - 4, 0xff);
    ASSERT_EQ(lcm.publish(kChangeChannel, bytes.data(), static_cast<unsigned>(bytes.size())), 0);
    ASSERT_EQ(lcm.publish(std::string(kResultChannelPrefix) + "forger", bytes.data(),
                          static_cast<unsigned>(bytes.size())),
              0);
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    ASSERT_TRUE(gateway_->running()) << "a forged alarm crashed the gateway\n"
                                     << Tail(gateway_->log_path());
  }
  ASSERT_EQ(lcm.publish(kChangeChannel, &alarm), 0);

  nlohmann::json listed;
  for (int attempt = 0; attempt < 50 && listed.is_null(); ++attempt) {
    const auto [code, site] = Json(Https()->Get("/v1/site", Bearer(kToken)));
    ASSERT_EQ(code, 200) << site.dump();
    if (!site["alarms"].empty()) listed = site["alarms"][0];
    if (listed.is_null()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_FALSE(listed.is_null()) << "the alarm never showed in /v1/site";
  EXPECT_EQ(listed["robot"], "robot");
  EXPECT_EQ(listed["kind"], "appeared");
  EXPECT_EQ(listed["class"], "car");
  EXPECT_EQ(listed["box"]["width"], 60);
  EXPECT_EQ(listed["place"]["place_id"], 3);
  httplib::Result frame = Https()->Get(listed["frame_picture"].get<std::string>(), Bearer(kToken));
  ASSERT_TRUE(frame);
  EXPECT_EQ(frame->status, 200);
  EXPECT_EQ(frame->body, frame_jpeg);
  httplib::Result place = Https()->Get(listed["place_picture"].get<std::string>(), Bearer(kToken));
  ASSERT_TRUE(place);
  EXPECT_EQ(place->body, place_jpeg);
  const auto [gone, error] = Json(Https()->Get("/v1/alarms/999/frame.jpg", Bearer(kToken)));
  EXPECT_EQ(gone, 404) << error.dump();
}

// Each refusal: the right HTTP status, a JSON error that says what to do, no map change.
TEST_F(GatewayTest, RefusalsAreJsonErrorsAndChangeNothing) {
  const int64_t places = MapPlaces();
  const std::string photo = ReadBytes(run_.frames[kMapped].image);
  struct Case {
    std::string name;
    httplib::Headers headers;
    std::string body;
    int status;
    std::string says;
  };
  const std::vector<Case> cases = {
      {"no token", {}, photo, 401, "Authorization: Bearer"},
      {"unknown token", Bearer("not-a-token-of-this-site"), photo, 401, "unknown token"},
      {"expired token", Bearer(kExpiredToken), photo, 401, "expired"},
      {"tampered token", Bearer(std::string(kToken) + "x"), photo, 401, "unknown token"},
      {"not an image", Bearer(kToken), "hello, where am I?", 415, "JPEG or PNG"},
      {"oversize upload", Bearer(kToken), std::string(3'000'000, '\xff'), 413, "larger"},
      {"truncated JPEG", Bearer(kToken), photo.substr(0, photo.size() / 2), 422, "bad image"},
  };
  for (const Case& c : cases) {
    const auto [status, body] =
        Json(Https()->Post("/v1/query", c.headers, c.body, "application/octet-stream"));
    EXPECT_EQ(status, c.status) << c.name << ": " << body.dump();
    ASSERT_TRUE(body.is_object() && body.contains("error")) << c.name;
    EXPECT_NE(body["error"].get<std::string>().find(c.says), std::string::npos)
        << c.name << ": " << body.dump();
  }
  // A SIGHUP (which reloads the server's keys) leaves the gateway serving.
  gateway_->Signal(SIGHUP);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ASSERT_TRUE(gateway_->running()) << "SIGHUP stopped the gateway";
  // A broken multipart upload (the library's own 400) says what to send.
  const auto [broken_status, broken] =
      Json(Https()->Post("/v1/query", Bearer(kToken), photo, "multipart/form-data; boundary=xyz"));
  EXPECT_EQ(broken_status, 400) << broken.dump();
  EXPECT_NE(broken.dump().find("form field 'image'"), std::string::npos) << broken.dump();
  // The gateway never inserts: there is no such endpoint.
  const auto [insert_status, insert_body] =
      Json(Https()->Post("/v1/insert", Bearer(kToken), photo, "image/jpeg"));
  EXPECT_EQ(insert_status, 404) << insert_body.dump();
  // Over the rate: the burst of queries passes (these are refused as no image, after the rate),
  // the next query gets 429 with Retry-After; the device's reads have a bucket of their own
  // (kReadsPerQuery times the rate: the page fetches two pictures per alarm), and other tokens
  // are not affected.
  std::unique_ptr<httplib::SSLClient> https = Https();
  int refused = 0;
  for (int i = 0; i < kBurst + 1; ++i) {
    httplib::Result r = https->Post("/v1/query", Bearer(kOtherToken), "hello", "image/jpeg");
    ASSERT_TRUE(r);
    if (r->status == 429) {
      ++refused;
      EXPECT_FALSE(r->get_header_value("Retry-After").empty());
      EXPECT_NE(r->body.find("try again in"), std::string::npos) << r->body;
    } else {
      EXPECT_EQ(r->status, 415) << r->body;
    }
  }
  EXPECT_EQ(refused, 1);
  // The bucket refills while the requests go (kReadsPerQuery / 2 a second), so the first
  // refusal comes at the burst or a little later.
  const int reads = static_cast<int>(kBurst * kReadsPerQuery);
  int answered = 0;
  for (int i = 0; i < 2 * reads; ++i) {
    httplib::Result r = https->Get("/v1/site", Bearer(kOtherToken));
    ASSERT_TRUE(r);
    if (r->status == 429) {
      EXPECT_NE(r->body.find("reads a minute"), std::string::npos) << r->body;
      break;
    }
    EXPECT_EQ(r->status, 200) << r->body;
    ++answered;
  }
  EXPECT_GE(answered, reads);
  EXPECT_LT(answered, 2 * reads) << "no read was refused";
  const auto [status_code, status] = Json(Https()->Get("/v1/status", Bearer(kToken)));
  EXPECT_EQ(status_code, 200);
  EXPECT_EQ(status["map_places"].get<int64_t>(), places);
  EXPECT_EQ(MapPlaces(), places);
}

// Requests no device would send, from anybody (no token): a path that is no UTF-8 once decoded
// (it made the error page's JSON throw outside the library's guard: the gateway died), and a
// large body without a Content-Length (chunked: the library read it whole into memory, past
// --max-upload-bytes, before any handler ran). Each gets a JSON error, and the gateway serves on.
TEST_F(GatewayTest, HostileRequestsNeitherStopTheGatewayNorFillItsMemory) {
  const auto [bad_path_status, bad_path_body] = Json(Https()->Get("/%FF%FE"));
  EXPECT_EQ(bad_path_status, 404) << bad_path_body.dump();
  ASSERT_TRUE(gateway_->running()) << Tail(gateway_->log_path());

  // 200 MB offered in 1 MB chunks; the gateway must refuse it before reading it (and close the
  // connection: writing on is then a broken pipe, not a reason for this test to die).
  std::signal(SIGPIPE, SIG_IGN);
  constexpr size_t kChunk = 1 << 20;
  constexpr size_t kOffered = 200 * kChunk;
  const std::string chunk(kChunk, '\xff');
  size_t sent = 0;
  httplib::Result chunked = Https()->Post(
      "/v1/query", Bearer(kToken),
      [&](size_t, httplib::DataSink& sink) {
        if (sent >= kOffered) {
          sink.done();
          return true;
        }
        if (!sink.write(chunk.data(), chunk.size())) return false;
        sent += chunk.size();
        return true;
      },
      "image/jpeg");
  ASSERT_TRUE(gateway_->running()) << Tail(gateway_->log_path());
  if (chunked) {  // the refusal may also arrive as a closed connection mid-upload
    EXPECT_EQ(chunked->status, 411) << chunked->body;
    EXPECT_NE(chunked->body.find("Content-Length"), std::string::npos) << chunked->body;
  }
  EXPECT_LT(sent, kOffered / 4) << "the gateway read " << sent << " bytes of a chunked body";
  // A Transfer-Encoding in capitals beside a small Content-Length, and the requests a refused
  // body holds: refused unread, and the connection closed, so that nothing in the body is read
  // as a request of its own.
  const std::string smuggled = "GET /v1/site HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer " +
                               std::string(kToken) + "\r\n\r\n";
  char size_line[32];
  std::snprintf(size_line, sizeof(size_line), "%zx\r\n", smuggled.size());
  const std::string body = std::string(size_line) + smuggled + "\r\n0\r\n\r\n";
  httplib::Headers headers = Bearer(kToken);
  headers.emplace("Transfer-Encoding", "CHUNKED");
  httplib::Result mixed = Https()->Post("/v1/query", headers, body, "image/jpeg");
  ASSERT_TRUE(mixed);
  EXPECT_EQ(mixed->status, 411) << mixed->body;
  EXPECT_EQ(mixed->get_header_value("Connection"), "close");
  const auto [site_code, site] = Json(Https()->Get("/v1/site", Bearer(kToken)));
  EXPECT_EQ(site_code, 200) << site.dump();

  // A body that says it is a terabyte, from anybody (no token) and from a device: refused before
  // it is read (the library used to read and discard it whole, at line rate, before its 413).
  for (const bool with_token : {false, true}) {
    size_t streamed = 0;
    httplib::Result huge = Https()->Post(
        "/v1/query", with_token ? Bearer(kToken) : httplib::Headers{}, size_t{1} << 40,
        [&](size_t, size_t, httplib::DataSink& sink) {
          if (streamed >= kOffered) return false;
          if (!sink.write(chunk.data(), chunk.size())) return false;
          streamed += chunk.size();
          return true;
        },
        "image/jpeg");
    ASSERT_TRUE(gateway_->running()) << Tail(gateway_->log_path());
    if (huge) {
      EXPECT_EQ(huge->status, with_token ? 413 : 401) << huge->body;
    }
    EXPECT_LT(streamed, kOffered / 4)
        << "the gateway read " << streamed << " bytes of a body over its limit";
  }
  // Methods no endpoint takes, whose bodies the library reads too (without a length, whole into
  // memory): refused unread.
  for (const bool with_length : {true, false}) {
    size_t streamed = 0;
    const auto provide = [&](size_t, httplib::DataSink& sink) {
      if (streamed >= kOffered) return false;
      if (!sink.write(chunk.data(), chunk.size())) return false;
      streamed += chunk.size();
      return true;
    };
    httplib::Result other =
        with_length ? Https()->Put(
                          "/v1/query", httplib::Headers{}, size_t{1} << 40,
                          [&](size_t offset, size_t, httplib::DataSink& sink) {
                            return provide(offset, sink);
                          },
                          "image/jpeg")
                    : Https()->Patch("/v1/query", httplib::Headers{}, provide, "image/jpeg");
    ASSERT_TRUE(gateway_->running()) << Tail(gateway_->log_path());
    if (other) {
      EXPECT_EQ(other->status, 405) << other->body;
    }
    EXPECT_LT(streamed, kOffered / 4) << "the gateway read " << streamed << " bytes of a "
                                      << (with_length ? "PUT" : "PATCH") << " body";
  }
}

// Queries waiting on a server that does not answer hold an HTTPS thread each until
// --query-timeout: beyond --max-waiting-queries the next query is refused at once (503 with
// Retry-After), and the overview is served meanwhile (eight such queries stalled the page).
TEST_F(GatewayTest, QueriesWaitingOnTheServerAreBoundedAndReadsAreServedMeanwhile) {
  server_.reset();  // stopped: no query is answered
  constexpr int kOtherPort = kPort + 1;
  std::unique_ptr<ChildProcess> gateway =
      StartGateway(kOtherPort, {"--max-waiting-queries", "1", "--query-timeout", "4"});
  ASSERT_NE(gateway, nullptr);
  const std::string photo = ReadBytes(run_.frames[kMapped].image);
  int first_status = 0;
  std::thread first([&] {
    httplib::Result r = Https(kOtherPort)->Post("/v1/query", Bearer(kToken), photo, "image/jpeg");
    first_status = r ? r->status : -1;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));  // the first one is waiting
  const auto started = std::chrono::steady_clock::now();
  httplib::Result second =
      Https(kOtherPort)->Post("/v1/query", Bearer(kOtherToken), photo, "image/jpeg");
  httplib::Result site = Https(kOtherPort)->Get("/v1/site", Bearer(kOtherToken));
  const double waited_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  first.join();
  ASSERT_TRUE(second);
  EXPECT_EQ(second->status, 503) << second->body;
  EXPECT_NE(second->body.find("waiting on the placerec server"), std::string::npos) << second->body;
  EXPECT_FALSE(second->get_header_value("Retry-After").empty());
  ASSERT_TRUE(site);
  EXPECT_EQ(site->status, 200) << site->body;
  EXPECT_LT(waited_s, 2.5) << "the refusal and the overview waited for the first query";
  EXPECT_EQ(first_status, 504);

  // One device may hold at most half of the slots: its third query waits for none, another
  // device's query still gets a slot (and times out, as nothing answers).
  std::unique_ptr<ChildProcess> shared =
      StartGateway(kOtherPort + 1, {"--max-waiting-queries", "4", "--query-timeout", "3"});
  ASSERT_NE(shared, nullptr);
  std::vector<int> statuses(3, 0);
  std::vector<std::thread> waiting;
  for (int i = 0; i < 2; ++i) {
    waiting.emplace_back([&, i] {
      httplib::Result r =
          Https(kOtherPort + 1)->Post("/v1/query", Bearer(kToken), photo, "image/jpeg");
      statuses[i] = r ? r->status : -1;
    });
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  httplib::Result third =
      Https(kOtherPort + 1)->Post("/v1/query", Bearer(kToken), photo, "image/jpeg");
  waiting.emplace_back([&] {
    httplib::Result r =
        Https(kOtherPort + 1)->Post("/v1/query", Bearer(kOtherToken), photo, "image/jpeg");
    statuses[2] = r ? r->status : -1;
  });
  for (std::thread& t : waiting) t.join();
  ASSERT_TRUE(third);
  EXPECT_EQ(third->status, 503) << third->body;
  EXPECT_NE(third->body.find("of this device"), std::string::npos) << third->body;
  EXPECT_EQ(statuses, (std::vector<int>{504, 504, 504}));
}

// Connections that send their TLS handshake a byte a second (a "slowloris"), from four addresses,
// more than the gateway has threads: they held every thread, and nobody else was served while
// they went on. Now one address holds at most --max-connections-per-address connections (the
// rest are cut at once), a new connection cuts the oldest of those still in their headers beyond
// half the threads, others are served meanwhile, and each slow one is cut once its handshake and
// headers take longer than --header-timeout.
TEST_F(GatewayTest, ClientsSendingAByteASecondNeitherHoldTheThreadsNorStayConnected) {
  const ConnectionGuardOptions limits;
  // 24 from 127.0.0.2 (more than one address may hold), 16 from each of .3, .4 and .5.
  std::vector<std::string> from_addresses(24, "127.0.0.2");
  for (const char* address : {"127.0.0.3", "127.0.0.4", "127.0.0.5"}) {
    from_addresses.insert(from_addresses.end(), 16, address);
  }
  const int kSlow = static_cast<int>(from_addresses.size());
  struct Slow {
    int fd = -1;
    double closed_after_s = -1;  // when the gateway closed it, seconds after the first byte
  };
  std::vector<Slow> slow(kSlow);
  for (int i = 0; i < kSlow; ++i) {
    Slow& s = slow[i];
    s.fd = socket(AF_INET, SOCK_STREAM, 0);
    ASSERT_GE(s.fd, 0) << std::strerror(errno);
    sockaddr_in from = {};
    from.sin_family = AF_INET;
    // Loopback addresses other than ours.
    inet_pton(AF_INET, from_addresses[i].c_str(), &from.sin_addr);
    ASSERT_EQ(bind(s.fd, reinterpret_cast<const sockaddr*>(&from), sizeof(from)), 0)
        << std::strerror(errno);
    sockaddr_in to = {};
    to.sin_family = AF_INET;
    to.sin_port = htons(kPort);
    inet_pton(AF_INET, "127.0.0.1", &to.sin_addr);
    ASSERT_EQ(connect(s.fd, reinterpret_cast<const sockaddr*>(&to), sizeof(to)), 0)
        << std::strerror(errno);
    // A TLS record header announcing a 512-byte handshake message; its bytes follow one a second.
    const unsigned char record[] = {0x16, 0x03, 0x01, 0x02, 0x00};
    ASSERT_EQ(send(s.fd, record, sizeof(record), MSG_NOSIGNAL),
              static_cast<ssize_t>(sizeof(record)));
  }
  const auto started = std::chrono::steady_clock::now();
  const auto elapsed_s = [&started] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  };
  const double give_up_s = limits.header_seconds + 10;
  std::atomic<bool> stop{false};
  std::thread dribble([&] {
    while (!stop && elapsed_s() < give_up_s) {
      for (Slow& s : slow) {
        if (s.closed_after_s >= 0) continue;
        char bytes[256];
        const ssize_t got = recv(s.fd, bytes, sizeof(bytes), MSG_DONTWAIT);
        bool closed = got == 0 || (got < 0 && errno != EAGAIN && errno != EWOULDBLOCK);
        const char zero = 0;
        if (!closed) closed = send(s.fd, &zero, 1, MSG_NOSIGNAL | MSG_DONTWAIT) < 0;
        if (closed) s.closed_after_s = elapsed_s();
      }
      for (int i = 0; i < 10 && !stop; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
      }
    }
  });

  // Meanwhile a device is served at once.
  std::this_thread::sleep_for(std::chrono::seconds(2));
  std::unique_ptr<httplib::SSLClient> https = Https();
  https->set_connection_timeout(10, 0);
  https->set_read_timeout(10, 0);
  const auto asked = std::chrono::steady_clock::now();
  httplib::Result status = https->Get("/v1/status", Bearer(kToken));
  const double answered_after_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - asked).count();
  EXPECT_TRUE(status) << "no answer while slow clients held the gateway: "
                      << httplib::to_string(status.error());
  if (status) {
    EXPECT_EQ(status->status, 200) << status->body;
  }
  EXPECT_LT(answered_after_s, 5);

  // Every slow connection is cut: those over the address's limit at once, the others once
  // their handshake took longer than the header timeout.
  while (elapsed_s() < give_up_s && std::any_of(slow.begin(), slow.end(), [](const Slow& s) {
           return s.closed_after_s < 0;
         })) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  stop = true;
  dribble.join();
  int at_once = 0;
  for (const Slow& s : slow) {
    close(s.fd);
    EXPECT_GE(s.closed_after_s, 0)
        << "a connection sending a byte a second was still open after " << give_up_s << " s";
    EXPECT_LT(s.closed_after_s, limits.header_seconds + 3);
    if (s.closed_after_s >= 0 && s.closed_after_s < limits.header_seconds / 2) ++at_once;
  }
  // At least those over one address's limit and those beyond the pending limit.
  EXPECT_GE(at_once, kSlow - limits.max_pending) << "of " << kSlow;
  ASSERT_TRUE(gateway_->running()) << Tail(gateway_->log_path());
  EXPECT_NE(
      ReadBytes(gateway_->log_path()).find("connection(s) that sent their request too slowly"),
      std::string::npos)
      << Tail(gateway_->log_path());
  const auto [after, after_body] = Json(Https()->Get("/v1/status", Bearer(kToken)));
  EXPECT_EQ(after, 200) << after_body.dump();
}

// A POST's claimed length bought its sender time before its token was checked: anybody could
// claim a megabyte and send it a byte a second, holding a thread for minutes. A body without a
// valid token is now refused unread beyond 64 KiB, and answered at once.
TEST_F(GatewayTest, AnAnonymousBodyIsRefusedBeforeItIsRead) {
  std::signal(SIGPIPE, SIG_IGN);  // writing on after the refusal is a broken pipe
  std::unique_ptr<httplib::SSLClient> https = Https();
  https->set_read_timeout(30, 0);
  size_t offered = 0;
  const auto started = std::chrono::steady_clock::now();
  httplib::Result slow = https->Post(
      "/v1/query", httplib::Headers{}, 1000000,  // under --max-upload-bytes (2,000,000)
      [&](size_t, size_t, httplib::DataSink& sink) {
        if (offered >= 20) return false;  // 20 bytes in 20 s, then give up
        std::this_thread::sleep_for(std::chrono::seconds(1));
        ++offered;
        return sink.write("x", 1);
      },
      "image/jpeg");
  const double took_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  EXPECT_LT(took_s, 5) << offered << " bytes read";
  if (slow) {  // the refusal may also arrive as a closed connection mid-upload
    EXPECT_EQ(slow->status, 401) << slow->body;
  }
  // A small body without a token is read and refused with the reason.
  const auto [small, small_body] = Json(Https()->Post("/v1/query", "hello", "image/jpeg"));
  EXPECT_EQ(small, 401) << small_body.dump();
  EXPECT_NE(small_body["error"].get<std::string>().find("Bearer"), std::string::npos);
}

// A device whose token names its own key (key=phone-4) is signed with it, so the server's keys
// file decides for that device alone: made insert-only there, its queries are refused (403)
// while the other devices, signed with the gateway's key, are answered.
TEST_F(GatewayTest, ADeviceWithItsOwnKeyCanBeRevokedAtTheServerAlone) {
  const std::string photo = ReadBytes(run_.frames[kMapped].image);
  const auto [before, before_body] =
      Json(Https()->Post("/v1/query", Bearer(kOwnKeyToken), photo, "image/jpeg"));
  ASSERT_EQ(before, 200) << before_body.dump() << Tail(server_->log_path());
  EXPECT_EQ(before_body["device"], "phone-4");
  {
    std::string text = testing_service::ReadTextFile(keys_);
    const size_t line = text.find("phone-4 query ");
    ASSERT_NE(line, std::string::npos) << text;
    text.replace(line, std::string("phone-4 query").size(), "phone-4 insert");
    std::ofstream(keys_, std::ios::trunc) << text;
  }
  server_->Signal(SIGHUP);
  int status = 200;
  nlohmann::json body;
  for (int attempt = 0; attempt < 20 && status == 200; ++attempt) {
    std::tie(status, body) =
        Json(Https()->Post("/v1/query", Bearer(kOwnKeyToken), photo, "image/jpeg"));
  }
  EXPECT_EQ(status, 403) << body.dump();
  EXPECT_NE(body.dump().find("phone-4"), std::string::npos) << body.dump();
  const auto [other, other_body] =
      Json(Https()->Post("/v1/query", Bearer(kToken), photo, "image/jpeg"));
  EXPECT_EQ(other, 200) << other_body.dump();
}

// Devices are added and removed with a SIGHUP, without a restart; a tokens file that cannot be
// used keeps the tokens in force. (The gateway ignored SIGHUP until 2026-12-07.)
TEST_F(GatewayTest, SighupReadsTheTokensFileAgain) {
  constexpr char kNewToken[] = "field-device-token-0005";
  constexpr char kUnknownKeyToken[] = "field-device-token-0006";
  const std::string log = dir_ + "/gateway-" + std::to_string(kPort) + ".log";
  // 401 for a token refused; 200, or 503 before the gateway heard the server's heartbeat.
  const auto status_of = [&](const std::string& token) {
    return Json(Https()->Get("/v1/status", Bearer(token))).first;
  };
  // The signal arrives on its own time: the next requests see the reload.
  const auto wait_for = [&](const std::function<bool()>& done) {
    for (int attempt = 0; attempt < 50; ++attempt) {
      if (done()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return false;
  };
  const auto log_count = [&](const std::string& text) {
    const std::string all = testing_service::ReadTextFile(log);
    int n = 0;
    for (size_t at = all.find(text); at != std::string::npos; at = all.find(text, at + 1)) ++n;
    return n;
  };
  ASSERT_EQ(status_of(kNewToken), 401);
  ASSERT_NE(status_of(kOtherToken), 401);

  std::ofstream(dir_ + "/tokens", std::ios::trunc) << kToken << " phone-1\n"
                                                   << kNewToken << " phone-5\n";
  gateway_->Signal(SIGHUP);
  ASSERT_TRUE(wait_for([&] { return status_of(kNewToken) != 401; })) << Tail(log);
  EXPECT_EQ(status_of(kOtherToken), 401) << "a removed device is refused";
  EXPECT_NE(status_of(kToken), 401);
  const std::string photo = ReadBytes(run_.frames[kMapped].image);
  const auto [asked, answer] =
      Json(Https()->Post("/v1/query", Bearer(kNewToken), photo, "image/jpeg"));
  ASSERT_EQ(asked, 200) << answer.dump() << Tail(log);
  EXPECT_EQ(answer["device"], "phone-5");
  // The new device's answer is heard on LCM like any other, but where it was never shows.
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const auto [site_status, site] = Json(Https()->Get("/v1/site", Bearer(kToken)));
  ASSERT_EQ(site_status, 200);
  EXPECT_EQ(site.dump().find("phone-5"), std::string::npos) << site.dump();

  // Files that cannot be used change nothing: a token too short, then a key the gateway's keys
  // file does not have.
  const int refused = log_count("the tokens in force stay");
  std::ofstream(dir_ + "/tokens", std::ios::trunc) << "short phone-6\n";
  gateway_->Signal(SIGHUP);
  ASSERT_TRUE(wait_for([&] {
    status_of(kToken);
    return log_count("the tokens in force stay") > refused;
  })) << Tail(log);
  EXPECT_NE(status_of(kNewToken), 401);
  EXPECT_EQ(status_of(kOtherToken), 401);
  std::ofstream(dir_ + "/tokens", std::ios::trunc) << kNewToken << " phone-5\n"
                                                   << kUnknownKeyToken << " phone-6 key=nobody\n";
  gateway_->Signal(SIGHUP);
  ASSERT_TRUE(wait_for([&] {
    status_of(kToken);
    return log_count("the tokens in force stay") > refused + 1;
  })) << Tail(log);
  EXPECT_EQ(status_of(kUnknownKeyToken), 401);
  EXPECT_NE(status_of(kToken), 401) << "the tokens in force stay";
  EXPECT_NE(testing_service::ReadTextFile(log).find("nobody"), std::string::npos) << Tail(log);
  EXPECT_TRUE(gateway_->running());
}

// A device's secret changed under the same key id, in the server's keys and the gateway's
// --key-file, is used after a SIGHUP to each: the gateway's clients are made anew (they were
// kept, so the device stayed refused until the gateway restarted).
TEST_F(GatewayTest, ASecretChangedUnderTheSameKeyIdIsUsedAfterSighup) {
  const std::string photo = ReadBytes(run_.frames[kMapped].image);
  const auto query = [&] {
    return Json(Https()->Post("/v1/query", Bearer(kOwnKeyToken), photo, "image/jpeg"));
  };
  ASSERT_EQ(query().first, 200) << Tail(server_->log_path());
  const std::string fresh = testing_service::ReadTextFile(
      testing_service::WriteTestKeys(dir_ + "/fresh-keys", {{"phone-4", "query"}}));
  const std::string line = fresh.substr(fresh.find("phone-4 "));
  for (const std::string& file : {keys_, dir_ + "/gateway-keys"}) {
    std::string text = testing_service::ReadTextFile(file);
    const size_t at = text.find("phone-4 ");
    ASSERT_NE(at, std::string::npos) << text;
    text.replace(at, text.find('\n', at) + 1 - at, line);
    std::ofstream(file, std::ios::trunc) << text;
  }
  server_->Signal(SIGHUP);
  int status = 200;
  for (int attempt = 0; attempt < 20 && status == 200; ++attempt) status = query().first;
  ASSERT_NE(status, 200) << "the server still takes the old secret";
  gateway_->Signal(SIGHUP);
  for (int attempt = 0; attempt < 20 && status != 200; ++attempt) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    status = query().first;
  }
  EXPECT_EQ(status, 200) << Tail(dir_ + "/gateway-" + std::to_string(kPort) + ".log");
}

// Decodes base64 (the WebDriver screenshot) with OpenSSL.
std::string DecodeBase64(const std::string& text) {
  std::string out(text.size() / 4 * 3 + 3, '\0');
  const int n = EVP_DecodeBlock(reinterpret_cast<unsigned char*>(out.data()),
                                reinterpret_cast<const unsigned char*>(text.data()),
                                static_cast<int>(text.size()));
  if (n < 0) return "";
  size_t size = static_cast<size_t>(n);
  if (!text.empty() && text.back() == '=') --size;  // EVP_DecodeBlock keeps padding bytes
  if (text.size() > 1 && text[text.size() - 2] == '=') --size;
  out.resize(size);
  return out;
}

// A person in the field: the page loads in headless Chromium, a real frame is chosen in its
// file input, and the page shows the place the map recognised.
TEST_F(GatewayTest, ThePageInARealBrowserShowsWhereAPhotoWasTaken) {
  const char* chromium = "/usr/bin/chromium";
  const char* chromedriver = "/usr/bin/chromedriver";
  ASSERT_TRUE(PathExists(chromium) && PathExists(chromedriver))
      << "needs Debian's chromium and chromium-driver (scripts/install-deps.sh installs them)";
  constexpr int kDriverPort = 19515;
  StatusOr<std::unique_ptr<ChildProcess>> driver = ChildProcess::Start(
      {chromedriver, "--port=" + std::to_string(kDriverPort)}, dir_ + "/chromedriver.log");
  ASSERT_TRUE(driver.ok()) << driver.status().ToString();
  httplib::Client webdriver("127.0.0.1", kDriverPort);
  webdriver.set_read_timeout(120, 0);
  auto call = [&](const std::string& method, const std::string& path,
                  const nlohmann::json& body = nlohmann::json::object()) {
    httplib::Result r = method == "GET" ? webdriver.Get(path.c_str())
                        : method == "DELETE"
                            ? webdriver.Delete(path.c_str())
                            : webdriver.Post(path.c_str(), body.dump(), "application/json");
    if (!r) return nlohmann::json();
    return nlohmann::json::parse(r->body, nullptr, false);
  };
  nlohmann::json session;
  for (int i = 0; i < 50 && !session.is_object(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    session =
        call("POST", "/session",
             {{"capabilities",
               {{"alwaysMatch",
                 {{"browserName", "chrome"},
                  {"goog:chromeOptions",
                   {{"binary", chromium},
                    {"args",
                     {"--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                      "--window-size=1000,1500",
                      // The page's certificate is the test's own: trust it by its SPKI hash would
                      // need the hash; the test checks the certificate over HTTPS above instead.
                      "--ignore-certificate-errors"}}}}}}}}});
  }
  ASSERT_TRUE(session.is_object() && session["value"].contains("sessionId"))
      << session.dump() << Tail(dir_ + "/chromedriver.log");
  const std::string base = "/session/" + session["value"]["sessionId"].get<std::string>();
  call("POST", base + "/url",
       {{"url", "https://127.0.0.1:" + std::to_string(kPort) + "/#token=" + kToken}});
  const nlohmann::json input =
      call("POST", base + "/element", {{"using", "css selector"}, {"value", "#photo"}});
  ASSERT_TRUE(input["value"].is_object()) << input.dump();
  const std::string element = input["value"].begin().value().get<std::string>();
  // A revisit of the mapped part (WebDriver wants a canonical path).
  const std::string photo = std::filesystem::canonical(run_.frames[kMapped + 2].image).string();
  const nlohmann::json typed =
      call("POST", base + "/element/" + element + "/value", {{"text", photo}});
  ASSERT_TRUE(typed["value"].is_null()) << "choosing the file failed: " << typed.dump();

  // Waits until the page shows an answer (or an error): its state and what it shows (status,
  // answer, the stored place's caption, the site overview).
  const auto await_answer = [&]() {
    std::string shown_state, text;
    for (int i = 0; i < 600; ++i) {
      const nlohmann::json shown =
          call("POST", base + "/execute/sync",
               {{"script",
                 "return [document.getElementById('answer-status').dataset.state,"
                 " document.getElementById('answer-status').textContent + ' | ' +"
                 " document.getElementById('answer').textContent + ' | ' +"
                 " document.getElementById('theirs-caption').textContent + ' | ' +"
                 " document.getElementById('site-status').textContent];"},
                {"args", nlohmann::json::array()}});
      if (shown["value"].is_array()) {
        shown_state = shown["value"][0].get<std::string>();
        text = shown["value"][1].get<std::string>();
      }
      if (shown_state == "done" || shown_state == "error" || (i == 50 && shown_state == "idle")) {
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    return std::make_pair(shown_state, text);
  };
  const auto [state, answer] = await_answer();

  // A phone's photo: the same view at 12 megapixels, over the gateway's upload limit (and more
  // than LCM's UDP multicast carries). The page sends a smaller JPEG of it and gets the answer.
  const cv::Mat view = cv::imread(run_.frames[kMapped + 2].image, cv::IMREAD_COLOR);
  ASSERT_FALSE(view.empty());
  cv::Mat large;
  cv::resize(view, large, cv::Size(4000, 4000 * view.rows / view.cols), 0, 0, cv::INTER_CUBIC);
  cv::Mat noise(large.size(), CV_16SC3);  // a camera's sensor noise: megabytes, as a phone's JPEG
  cv::randn(noise, 0, 4);
  large.convertTo(large, CV_16SC3);
  large += noise;
  large.convertTo(large, CV_8UC3);
  const std::string large_photo = dir_ + "/phone-photo.jpg";
  ASSERT_TRUE(cv::imwrite(large_photo, large, {cv::IMWRITE_JPEG_QUALITY, 100}));
  ASSERT_GT(std::filesystem::file_size(large_photo), 2000000u) << "not over the upload limit";
  call("POST", base + "/execute/sync",
       {{"script", "document.getElementById('answer-status').dataset.state = 'idle';"},
        {"args", nlohmann::json::array()}});
  call("POST", base + "/element/" + element + "/value",
       {{"text", std::filesystem::canonical(large_photo).string()}});
  const auto [large_state, large_answer] = await_answer();
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // pictures load, for the picture
  const nlohmann::json screenshot = call("GET", base + "/screenshot");
  if (screenshot["value"].is_string()) {
    const std::string artefacts = std::string(PLACEREC_BINARY_DIR) + "/test-artefacts";
    MakeDirectories(artefacts);
    std::ofstream(artefacts + "/gateway-page.png", std::ios::binary)
        << DecodeBase64(screenshot["value"].get<std::string>());
  }
  call("DELETE", base);
  EXPECT_EQ(state, "done") << answer;
  // The answer names a place of the robot that mapped the corridor, as LCM does.
  const FrameResult lcm = client_->Send(Frame(kMapped + 2, /*insert=*/false));
  ASSERT_TRUE(lcm.ok() && !lcm.matches.empty()) << DescribeResult(lcm);
  EXPECT_NE(answer.find("place #" + std::to_string(lcm.matches.front().place_id)),
            std::string::npos)
      << answer;
  EXPECT_NE(answer.find("seen by robot robot"), std::string::npos) << answer;
  EXPECT_NE(answer.find(std::to_string(MapPlaces()) + " places"), std::string::npos) << answer;
  EXPECT_EQ(large_state, "done") << large_answer;
  EXPECT_NE(large_answer.find("seen by robot robot"), std::string::npos) << large_answer;
}

}  // namespace
}  // namespace placerec
