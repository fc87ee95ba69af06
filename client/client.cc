#include "client/client.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <random>
#include <sstream>

#include <lcm/lcm-cpp.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/util/logging.h"
#include "placerec/change_t.hpp"
#include "placerec/frame_t.hpp"
#include "placerec/result_t.hpp"
#include "placerec/status_t.hpp"
#include "proto/auth/signing.h"
#include "proto/channels.h"
#include "proto/decode.h"

namespace placerec {
namespace {

// `text` with every byte that is no printable ASCII as '?': text from the network that is
// printed (a forged alarm's class, an untrusted answer's message) cannot drive the terminal.
std::string Printable(std::string text) {
  for (char& c : text) {
    if (c < 0x20 || c > 0x7e) c = '?';  // char is signed: bytes from 0x80 on are negative
  }
  return text;
}

// Answers LCM may hold for the receive thread; its default of 30 would drop answers to a long
// burst of frames before they are dispatched.
constexpr int kLcmAnswerQueue = 4096;

AnswerCode CodeFromWire(int8_t status) {
  switch (status) {
    case result_t::STATUS_OK:
      return AnswerCode::kOk;
    case result_t::STATUS_BAD_REQUEST:
      return AnswerCode::kBadRequest;
    case result_t::STATUS_BAD_IMAGE:
      return AnswerCode::kBadImage;
    case result_t::STATUS_UNKNOWN_ROBOT:
      return AnswerCode::kUnknownRobot;
    case result_t::STATUS_OVERLOADED:
      return AnswerCode::kOverloaded;
    case result_t::STATUS_UNAUTHORISED:
      return AnswerCode::kUnauthorised;
    case result_t::STATUS_INTERNAL_ERROR:
      return AnswerCode::kInternalError;
    case result_t::STATUS_STORAGE_ERROR:
      return AnswerCode::kStorageError;
    case result_t::STATUS_SHUTTING_DOWN:
      return AnswerCode::kShuttingDown;
    default:
      return AnswerCode::kUnknownStatus;
  }
}

int64_t NowUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// "unauthorised" and so on, for a result_t status code.
std::string WireStatusText(int8_t status) {
  const AnswerCode code = CodeFromWire(status);
  return code == AnswerCode::kUnknownStatus ? "status " + std::to_string(status)
                                            : AnswerCodeName(code);
}

FrameResult FromWire(const result_t& answer) {
  FrameResult r;
  r.code = CodeFromWire(answer.status);
  r.message = answer.message;
  if (r.code == AnswerCode::kUnknownStatus) {
    r.message = "unknown status " + std::to_string(answer.status) + ": " + r.message;
  }
  r.robot = answer.robot;
  r.sequence = answer.sequence;
  r.request_id = answer.request_id;
  r.insert = answer.insert;
  r.loop_closure = answer.loop_closure;
  for (const match_t& m : answer.matches) {
    MatchedPlace place;
    place.robot = m.robot;
    place.sequence = m.sequence;
    place.utime = m.utime;
    place.place_id = m.place_id;
    place.score = m.score;
    place.matched_landmarks = m.matched_landmarks;
    place.matched_descriptors = m.matched_descriptors;
    place.inliers = m.inliers;
    const size_t classes = std::min(m.classes.size(), m.class_counts.size());
    for (size_t i = 0; i < classes; ++i)
      place.classes.emplace_back(m.classes[i], m.class_counts[i]);
    r.matches.push_back(std::move(place));
  }
  r.change_checked = answer.change_checked;
  const size_t changes = std::min({static_cast<size_t>(std::max(answer.num_changes, 0)),
                                   answer.change_kinds.size(), answer.change_boxes.size(),
                                   answer.change_classes.size(), answer.change_confidences.size()});
  for (size_t i = 0; i < changes; ++i) {
    ReportedChange change;
    change.appeared = answer.change_kinds[i] == result_t::CHANGE_APPEARED;
    if (answer.change_boxes[i].size() == 4) {
      change.x = answer.change_boxes[i][0];
      change.y = answer.change_boxes[i][1];
      change.width = answer.change_boxes[i][2];
      change.height = answer.change_boxes[i][3];
    }
    change.object_class = answer.change_classes[i];
    change.confidence = answer.change_confidences[i];
    r.changes.push_back(std::move(change));
  }
  r.keypoints = answer.keypoints;
  r.objects = answer.objects;
  r.landmarks = answer.landmarks;
  r.stored_descriptors = answer.stored_descriptors;
  r.place_id = answer.place_id;
  r.next_sequence = answer.next_sequence;
  r.map_places = answer.map_places;
  r.map_landmarks = answer.map_landmarks;
  r.map_descriptors = answer.map_descriptors;
  r.queue_ms = answer.queue_ms;
  r.server_ms = answer.server_ms;
  for (const stage_time_t& t : answer.timings) r.timings.emplace_back(t.stage, t.ms);
  return r;
}

// Robot ids made of these characters are subscribed to by their exact channel name; LCM treats a
// subscription as a regular expression, so others are covered by one pattern and filtered here.
bool IsPlainChannelText(const std::string& text) {
  for (unsigned char c : text) {
    if (!std::isalnum(c) && c != '_' && c != '-') return false;
  }
  return true;
}

}  // namespace

std::string DescribeClasses(const std::vector<std::pair<std::string, int>>& classes) {
  std::string text;
  for (const auto& [name, count] : classes) {
    text += text.empty() ? ", seen: " : ", ";
    text += name;
    if (count > 1) text += " x" + std::to_string(count);
  }
  return text;
}

const char* AnswerCodeName(AnswerCode code) {
  switch (code) {
    case AnswerCode::kOk:
      return "ok";
    case AnswerCode::kBadRequest:
      return "bad request";
    case AnswerCode::kBadImage:
      return "bad image";
    case AnswerCode::kUnknownRobot:
      return "unknown robot";
    case AnswerCode::kOverloaded:
      return "overloaded";
    case AnswerCode::kUnauthorised:
      return "unauthorised";
    case AnswerCode::kInternalError:
      return "internal error";
    case AnswerCode::kStorageError:
      return "storage error";
    case AnswerCode::kShuttingDown:
      return "shutting down";
    case AnswerCode::kUnknownStatus:
      return "unknown status";
    case AnswerCode::kTimeout:
      return "timeout";
    case AnswerCode::kNotSent:
      return "not sent";
  }
  return "unknown status";
}

std::string DescribeResult(const FrameResult& r) {
  std::ostringstream out;
  out << AnswerCodeName(r.code);
  if (!r.ok()) {
    out << ": " << r.message;
    return out.str();
  }
  out << ": " << r.keypoints << " keypoints, " << r.objects << " objects, " << r.landmarks
      << " landmarks stored";
  if (r.matches.empty()) {
    out << "; no matching place";
  } else {
    const MatchedPlace& best = r.matches.front();
    char score[32];
    std::snprintf(score, sizeof(score), "%.0f", best.score);
    out << "; best place: robot " << best.robot << " #" << best.sequence << " (score " << score
        << ", " << best.matched_landmarks << " landmarks matched" << DescribeClasses(best.classes)
        << ")" << (r.loop_closure ? " -- loop closure" : "");
  }
  if (!r.changes.empty()) {
    out << "; " << r.changes.size() << " scene change" << (r.changes.size() == 1 ? "" : "s");
  }
  return out.str();
}

StatusOr<EncodedImage> EncodeImageFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::NotFound("cannot read " + path);
  EncodedImage image;
  image.bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  const std::vector<uint8_t>& b = image.bytes;
  if (b.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF) {
    image.encoding = FrameEncoding::kJpeg;
    return image;
  }
  if (b.size() >= 8 && b[0] == 0x89 && b[1] == 'P' && b[2] == 'N' && b[3] == 'G') {
    image.encoding = FrameEncoding::kPng;
    return image;
  }
  const cv::Mat decoded = cv::imread(path, cv::IMREAD_COLOR);
  if (decoded.empty()) return Status::BadImage(path + " is not an image OpenCV can read");
  return EncodeRawImage(decoded);
}

StatusOr<EncodedImage> EncodeRawImage(const cv::Mat& image) {
  if (image.empty() || image.depth() != CV_8U || (image.channels() != 3 && image.channels() != 1)) {
    return Status::InvalidArgument("raw frames must be 8-bit BGR or grey images");
  }
  EncodedImage encoded;
  encoded.encoding = image.channels() == 3 ? FrameEncoding::kRawBgr8 : FrameEncoding::kRawGray8;
  encoded.width = image.cols;
  encoded.height = image.rows;
  const cv::Mat continuous = image.isContinuous() ? image : image.clone();
  encoded.bytes.assign(continuous.data,
                       continuous.data + continuous.total() * continuous.elemSize());
  return encoded;
}

bool ClientOptions::Check(std::string* error) const {
  if (!(timeout_s > 0)) {
    *error = "--timeout must be positive (seconds)";
    return false;
  }
  if (!(retry_after_s >= 0) || retry_after_s > 3600) {
    *error = "--retry-after must be between 0 and 3600 seconds";
    return false;
  }
  if (!(untrusted_grace_s >= 0) || untrusted_grace_s > 3600) {
    *error = "--untrusted-grace must be between 0 and 3600 seconds";
    return false;
  }
  if (key_file.empty() && !key_id.empty()) {
    *error = "--key-id needs --key-file";
    return false;
  }
  return true;
}

PlacerecClient::PlacerecClient(const ClientOptions& options)
    : options_(options), lcm_(std::make_unique<lcm::LCM>(options.lcm_url)) {
  // Request ids only need to differ between the clients that share a robot id at one time.
  std::random_device device;
  next_request_id_ = (static_cast<int64_t>(device()) << 31 ^ device()) & 0x3fffffffffffffff;
}

StatusOr<std::unique_ptr<PlacerecClient>> PlacerecClient::Connect(const ClientOptions& options) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  std::unique_ptr<PlacerecClient> client(new PlacerecClient(options));
  if (!options.key_file.empty()) {
    std::string warning;
    StatusOr<std::vector<SigningKey>> keys = ReadKeysFile(options.key_file, &warning);
    if (!keys.ok()) return keys.status();
    if (!warning.empty()) LOG(WARNING) << warning;
    const SigningKey* key = FindKey(*keys, options.key_id);
    if (key == nullptr) {
      return Status::InvalidArgument(options.key_id.empty()
                                         ? "the key file " + options.key_file + " holds no key"
                                         : "the key file " + options.key_file + " has no key '" +
                                               options.key_id + "'");
    }
    client->key_ = std::make_unique<SigningKey>(*key);
  }
  // A tcpq URL whose hub does not answer leaves a "good" LCM without a connection.
  if (!client->lcm_->good() || client->lcm_->getFileno() < 0) {
    const bool tcpq = options.lcm_url.rfind("tcpq://", 0) == 0;
    return Status::IoError("cannot open LCM" +
                           (options.lcm_url.empty() ? std::string(" with its default URL")
                                                    : " with URL " + options.lcm_url) +
                           (tcpq ? "; is the LCM TCP hub running at that address? "
                                   "(scripts/lcm-hub.sh start PORT on the hub's machine)"
                                 : "; check the URL and that the network has multicast"));
  }
  if (client->lcm_->subscribe(kStatusChannel, &PlacerecClient::OnStatus, client.get()) == nullptr) {
    return Status::IoError("cannot subscribe to the placerec channels");
  }
  lcm::Subscription* invalid =
      client->lcm_->subscribe(kInvalidRobotResultChannel, &PlacerecClient::OnResult, client.get());
  if (invalid == nullptr) return Status::IoError("cannot subscribe to the placerec channels");
  invalid->setQueueCapacity(kLcmAnswerQueue);
  client->receiver_ = std::thread([c = client.get()] { c->ReceiveLoop(); });
  return client;
}

PlacerecClient::~PlacerecClient() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  if (receiver_.joinable()) receiver_.join();
}

void PlacerecClient::ReceiveLoop() {
  for (;;) {
    {
      std::lock_guard lock(mutex_);
      if (stop_) return;
    }
    // A tcpq connection that broke leaves no descriptor to wait on.
    if (lcm_->getFileno() < 0 || lcm_->handleTimeout(50) < 0) {
      LOG(ERROR) << "LCM stopped delivering messages"
                 << (options_.lcm_url.rfind("tcpq://", 0) == 0 ? " (the LCM TCP hub went away?)"
                                                               : "");
      return;
    }
  }
}

Status PlacerecClient::SubscribeFor(const std::string& robot) {
  std::string why;
  if (!IsValidWireRobotId(robot, &why)) return Status::Ok();  // answered on the shared channel
  std::lock_guard lock(mutex_);
  if (IsPlainChannelText(robot)) {
    if (subscribed_.count(robot) > 0) return Status::Ok();
    lcm::Subscription* subscription =
        lcm_->subscribe(ResultChannel(robot), &PlacerecClient::OnResult, this);
    if (subscription == nullptr) {
      return Status::IoError("cannot subscribe to " + ResultChannel(robot));
    }
    subscription->setQueueCapacity(kLcmAnswerQueue);
    subscribed_.insert(robot);
    return Status::Ok();
  }
  if (wildcard_subscribed_) return Status::Ok();
  lcm::Subscription* subscription =
      lcm_->subscribe(std::string(kResultChannelPrefix) + ".*", &PlacerecClient::OnResult, this);
  if (subscription == nullptr) {
    return Status::IoError(std::string("cannot subscribe to ") + kResultChannelPrefix + ".*");
  }
  subscription->setQueueCapacity(kLcmAnswerQueue);
  wildcard_subscribed_ = true;
  return Status::Ok();
}

StatusOr<PendingFrame> PlacerecClient::Publish(const OutgoingFrame& frame) {
  PLACEREC_RETURN_IF_ERROR(SubscribeFor(frame.robot));
  frame_t message;
  message.utime = frame.utime;
  message.sequence = frame.sequence;
  message.insert = frame.insert;
  message.encoding = static_cast<int8_t>(frame.image.encoding);
  message.width = frame.image.width;
  message.height = frame.image.height;
  message.robot = frame.robot;
  ClearFrameSignature(&message);
  message.size = static_cast<int32_t>(frame.image.bytes.size());
  message.data = frame.image.bytes;
  PendingFrame pending;
  pending.robot = frame.robot;
  pending.sequence = frame.sequence;
  {
    std::lock_guard lock(mutex_);
    pending.request_id = next_request_id_++;
    pending.sent = std::chrono::steady_clock::now();
    awaited_[pending.request_id] = pending;
  }
  message.request_id = pending.request_id;
  auto bytes = std::make_shared<std::vector<uint8_t>>(message.getEncodedSize());
  message.encode(bytes->data(), 0, static_cast<int>(bytes->size()));
  pending.message = bytes;
  const int rc = PublishFrame(*bytes);
  if (rc != 0) {
    std::lock_guard lock(mutex_);
    awaited_.erase(pending.request_id);
    return Status::IoError("LCM could not send the frame (" +
                           std::to_string(frame.image.bytes.size()) + " image bytes)");
  }
  return pending;
}

FrameResult PlacerecClient::Wait(const PendingFrame& pending, double timeout_s) {
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                            std::chrono::duration<double>(timeout_s));
  const auto retry = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(options_.retry_after_s));
  const bool retries = options_.retry_after_s > 0 && pending.message != nullptr;
  auto next_send = pending.sent + retry;
  int sends = pending.sends;
  const auto grace = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(options_.untrusted_grace_s));
  // Until when to wait for a signed answer once an untrusted one came.
  const auto give_up = [&] {
    const auto it = untrusted_.find(pending.request_id);
    return it == untrusted_.end() || options_.untrusted_grace_s <= 0
               ? deadline
               : std::min(deadline, it->second.first + grace);
  };
  std::unique_lock lock(mutex_);
  for (;;) {
    if (answers_.count(pending.request_id) > 0) break;
    const auto stop = give_up();
    if (std::chrono::steady_clock::now() >= stop) break;
    // Woken by an answer (trusted or not), or at the time to send again or to stop.
    answered_.wait_until(lock, retries ? std::min(stop, next_send) : stop);
    if (answers_.count(pending.request_id) > 0) break;
    if (retries && std::chrono::steady_clock::now() >= next_send) {
      if (std::chrono::steady_clock::now() + retry / 2 < give_up()) {
        // No answer yet: send the same frame (same request id) again.
        lock.unlock();
        if (PublishFrame(*pending.message) == 0) ++sends;
        next_send = std::chrono::steady_clock::now() + retry;
        lock.lock();
      } else {
        // Too little time is left for its answer to count: no more sending (the time to give up
        // only comes closer), and no waking at a passed sending time, which would spin.
        next_send = std::chrono::steady_clock::time_point::max();
      }
    }
  }
  auto it = answers_.find(pending.request_id);
  auto untrusted = untrusted_.find(pending.request_id);
  std::string ignored;
  if (untrusted != untrusted_.end()) {
    ignored = std::move(untrusted->second.said);
    untrusted_.erase(untrusted);
  }
  if (it == answers_.end()) {
    awaited_.erase(pending.request_id);  // a late answer is ignored
    FrameResult timeout;
    timeout.code = AnswerCode::kTimeout;
    timeout.robot = pending.robot;
    timeout.sequence = pending.sequence;
    timeout.request_id = pending.request_id;
    char text[200];
    if (ignored.empty()) {
      std::snprintf(text, sizeof(text),
                    "no answer within %.1f s, sent %d time%s (is placerec-server running on this "
                    "LCM network?)",
                    timeout_s, sends, sends == 1 ? "" : "s");
      timeout.message = text;
    } else {
      // The server (or something posing as it) answered, but not with our key.
      std::snprintf(text, sizeof(text), "; no answer signed with this key came (sent %d time%s)",
                    sends, sends == 1 ? "" : "s");
      timeout.message = ignored + text +
                        ": check that --key-file holds the key the server's --keys file has "
                        "for this robot or device";
    }
    return timeout;
  }
  FrameResult result = std::move(it->second);
  answers_.erase(it);
  return result;
}

FrameResult PlacerecClient::Send(const OutgoingFrame& frame) {
  StatusOr<PendingFrame> pending = Publish(frame);
  if (!pending.ok()) {
    FrameResult result;
    result.code = AnswerCode::kNotSent;
    result.message = pending.status().message();
    result.robot = frame.robot;
    result.sequence = frame.sequence;
    return result;
  }
  return Wait(*pending, options_.timeout_s);
}

void PlacerecClient::SetAnswerCallback(std::function<void(const FrameResult&)> callback) {
  std::unique_lock lock(mutex_);
  callback_ = std::move(callback);
  // The callback replaced may still run on the receive thread (unless this is that thread):
  // once this returns, it has ended, so its captures may go.
  if (std::this_thread::get_id() != receiver_.get_id()) {
    answered_.wait(lock, [this] { return callbacks_running_ == 0; });
  }
}

void PlacerecClient::OnResult(const lcm::ReceiveBuffer* buffer, const std::string& channel) {
  const auto now = std::chrono::steady_clock::now();
  result_t answer;
  if (!DecodeLcmMessage(buffer->data, buffer->data_size, &answer)) {
    LOG(WARNING) << "dropped a " << buffer->data_size << "-byte message on " << channel
                 << " that is not a placerec.result_t";
    return;
  }
  if (channel != kInvalidRobotResultChannel && channel != ResultChannel(answer.robot)) return;
  if (key_ != nullptr && !AnswerSignatureValid(answer, *key_, buffer->data, buffer->data_size)) {
    // Not the server's answer to our frame (or a server without our key): ignored, but kept to
    // explain a timeout.
    std::lock_guard lock(mutex_);
    auto it = awaited_.find(answer.request_id);
    if (it != awaited_.end() && it->second.sequence == answer.sequence) {
      Untrusted& untrusted = untrusted_[answer.request_id];
      if (untrusted.said.empty()) untrusted.first = now;
      untrusted.said =
          "an answer not signed with key '" + key_->id + "' was ignored (" +
          (answer.key_id.empty() ? std::string("unsigned") : "signed as '" + answer.key_id + "'") +
          "; it said: " + WireStatusText(answer.status) +
          (answer.message.empty() ? "" : ": " + Printable(answer.message)) + ")";
      answered_.notify_all();
    }
    return;
  }
  FrameResult result = FromWire(answer);
  std::function<void(const FrameResult&)> callback;
  {
    std::lock_guard lock(mutex_);
    auto it = awaited_.find(answer.request_id);
    // Answers to other clients' frames (or to frames given up on) are not ours. The echoed robot
    // id may be cut short (see result_t).
    if (it == awaited_.end() || it->second.sequence != answer.sequence ||
        it->second.robot.compare(0, answer.robot.size(), answer.robot) != 0) {
      return;
    }
    result.latency_ms = std::chrono::duration<double, std::milli>(now - it->second.sent).count();
    awaited_.erase(it);
    callback = callback_;
    // Waiting for the answer ends now, not after the callback: a Wait that timed out while the
    // callback ran reported a timeout for a frame the callback had been given the answer to.
    if (!callback) {
      answers_[answer.request_id] = std::move(result);
      answered_.notify_all();
      return;
    }
    answers_[answer.request_id] = result;
    ++callbacks_running_;
    answered_.notify_all();
  }
  // Counted down however the callback ends, so that SetAnswerCallback never waits for ever.
  struct Ended {
    PlacerecClient* client;
    ~Ended() {
      std::lock_guard lock(client->mutex_);
      --client->callbacks_running_;
      client->answered_.notify_all();
    }
  } ended{this};
  callback(result);
}

void PlacerecClient::OnStatus(const lcm::ReceiveBuffer* buffer, const std::string& channel) {
  status_t message;
  if (!DecodeLcmMessage(buffer->data, buffer->data_size, &message)) {
    LOG(WARNING) << "dropped a " << buffer->data_size << "-byte message on " << channel
                 << " that is not a placerec.status_t";
    return;
  }
  ServerStatus s;
  s.version = message.version;
  s.map = message.map;
  s.uptime_s = message.uptime_s;
  s.map_open_ms = message.map_open_ms;
  s.map_places = message.map_places;
  s.map_landmarks = message.map_landmarks;
  s.map_descriptors = message.map_descriptors;
  s.queue_depth = message.queue_depth;
  s.queue_capacity = message.queue_capacity;
  s.in_progress = message.in_progress;
  s.workers = message.workers;
  s.robots = message.robots;
  s.frames_answered = message.frames_answered;
  s.frames_failed = message.frames_failed;
  s.frames_overloaded = message.frames_overloaded;
  s.messages_dropped = message.messages_dropped;
  s.frames_per_second = message.frames_per_second;
  std::lock_guard lock(mutex_);
  last_status_ = s;
  ++statuses_;
  answered_.notify_all();
}

Status PlacerecClient::WatchAlarms(std::function<void(const SceneAlarm&)> callback) {
  std::lock_guard lock(mutex_);
  alarm_callback_ = std::move(callback);
  if (alarms_subscribed_) return Status::Ok();
  lcm::Subscription* subscription =
      lcm_->subscribe(kChangeChannel, &PlacerecClient::OnChange, this);
  if (subscription == nullptr) {
    return Status::IoError(std::string("cannot subscribe to ") + kChangeChannel);
  }
  subscription->setQueueCapacity(kLcmAnswerQueue);
  alarms_subscribed_ = true;
  return Status::Ok();
}

void PlacerecClient::OnChange(const lcm::ReceiveBuffer* buffer, const std::string& channel) {
  change_t message;
  if (!DecodeLcmMessage(buffer->data, buffer->data_size, &message)) {
    LOG(WARNING) << "dropped a " << buffer->data_size << "-byte message on " << channel
                 << " that is not a placerec.change_t";
    return;
  }
  std::string why;
  if (!IsValidWireRobotId(message.robot, &why) || !IsValidWireRobotId(message.place_robot, &why)) {
    LOG(WARNING) << "dropped an alarm on " << channel << " naming a robot the server refuses ("
                 << why << "): not from a placerec server";
    return;
  }
  SceneAlarm alarm;
  alarm.robot = message.robot;
  alarm.sequence = message.sequence;
  alarm.request_id = message.request_id;
  alarm.frame_utime = message.frame_utime;
  alarm.place_id = message.place_id;
  alarm.place_robot = message.place_robot;
  alarm.place_sequence = message.place_sequence;
  alarm.place_utime = message.place_utime;
  alarm.change_index = message.change_index;
  alarm.num_frame_changes = message.num_frame_changes;
  alarm.change.appeared = message.kind == change_t::KIND_APPEARED;
  alarm.change.x = message.box[0];
  alarm.change.y = message.box[1];
  alarm.change.width = message.box[2];
  alarm.change.height = message.box[3];
  alarm.change.object_class = Printable(message.object_class);
  alarm.change.confidence = message.confidence;
  alarm.frame_width = message.frame_width;
  alarm.frame_height = message.frame_height;
  alarm.frame_jpeg.assign(message.frame_jpeg.begin(), message.frame_jpeg.end());
  alarm.place_jpeg.assign(message.place_jpeg.begin(), message.place_jpeg.end());
  std::function<void(const SceneAlarm&)> callback;
  {
    std::lock_guard lock(mutex_);
    callback = alarm_callback_;
  }
  if (callback) callback(alarm);
}

int PlacerecClient::PublishFrame(const std::vector<uint8_t>& message) {
  std::lock_guard lock(publish_mutex_);
  if (key_ == nullptr) {
    return lcm_->publish(kFrameChannel, message.data(), static_cast<unsigned int>(message.size()));
  }
  frame_t frame;
  if (frame.decode(message.data(), 0, static_cast<int>(message.size())) < 0) return -1;
  // The counter increases within this client and across its restarts (it starts from the clock).
  const int64_t now = NowUtime();
  last_counter_ = std::max(last_counter_ + 1, now);
  SignFrame(*key_, last_counter_, now, &frame);
  const std::vector<uint8_t> bytes = EncodeFrame(frame);
  return lcm_->publish(kFrameChannel, bytes.data(), static_cast<unsigned int>(bytes.size()));
}

StatusOr<ServerStatus> PlacerecClient::WaitForStatus(double timeout_s) {
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                            std::chrono::duration<double>(timeout_s));
  std::unique_lock lock(mutex_);
  const int64_t seen = statuses_;
  if (!answered_.wait_until(lock, deadline, [&] { return statuses_ > seen; })) {
    return Status::NotFound("no status from a placerec-server within " + std::to_string(timeout_s) +
                            " s");
  }
  return last_status_;
}

}  // namespace placerec
