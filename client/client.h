// libplacerec_client (DESIGN.md "Architecture"): what a robot or a handheld needs to use a
// placerec-server over LCM: encode an image, publish it as a frame on PLACEREC_FRAME, and wait
// for the answer on PLACEREC_RESULT_<robot> that carries the same robot, sequence number and
// request id. Links neither the pipeline nor SQLite; the generated LCM types stay in client.cc.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "common/util/status.h"

namespace lcm {
class LCM;
struct ReceiveBuffer;
}  // namespace lcm

namespace placerec {

struct SigningKey;  // proto/auth/signing.h

// How the image bytes of a frame are encoded (the values of frame_t::ENCODING_*).
enum class FrameEncoding : int8_t { kJpeg = 0, kPng = 1, kRawBgr8 = 2, kRawGray8 = 3 };

struct EncodedImage {
  FrameEncoding encoding = FrameEncoding::kJpeg;
  int width = 0;   // pixels; 0 when unknown (JPEG and PNG)
  int height = 0;  // pixels; 0 when unknown (JPEG and PNG)
  std::vector<uint8_t> bytes;
};

// Reads an image file for sending. JPEG and PNG files are sent as they are, so the server decodes
// exactly the bytes on disk (as placerec-eval does); other formats OpenCV reads go as raw BGR.
StatusOr<EncodedImage> EncodeImageFile(const std::string& path);
// An 8-bit BGR (CV_8UC3) or grey (CV_8UC1) image as raw pixels.
StatusOr<EncodedImage> EncodeRawImage(const cv::Mat& image);

struct OutgoingFrame {
  std::string robot;     // robot id, 1..47 bytes (names the answer channel)
  int64_t sequence = 0;  // the robot's frame number, increasing for inserted frames
  int64_t utime = 0;     // capture time, microseconds since the epoch
  bool insert = true;    // false: query only, the map and the robot's state stay unchanged
  EncodedImage image;
};

// What an answer says: the server's status codes (result_t::STATUS_*) plus two of the client's
// own, kTimeout (no answer in time) and kNotSent (LCM refused the message).
enum class AnswerCode {
  kOk,
  kBadRequest,
  kBadImage,
  kUnknownRobot,
  kOverloaded,
  kUnauthorised,
  kInternalError,
  kStorageError,
  kShuttingDown,
  kUnknownStatus,
  kTimeout,
  kNotSent,
};
const char* AnswerCodeName(AnswerCode code);

// ", seen: building x3, sign" for matched landmark classes; empty when there are none.
std::string DescribeClasses(const std::vector<std::pair<std::string, int>>& classes);

// An earlier place (a frame some robot inserted) that the frame matched.
struct MatchedPlace {
  std::string robot;
  int64_t sequence = 0;
  int64_t utime = 0;
  int64_t place_id = -1;
  double score = 0;  // geometric inliers; larger is stronger
  int matched_landmarks = 0;
  int matched_descriptors = 0;
  int inliers = -1;
  // Object classes of the place's matched landmarks with how many of each, most first.
  std::vector<std::pair<std::string, int>> classes;
};

// A scene change the server found at the matched place (protocol 5, seed §7.2.4).
struct ReportedChange {
  bool appeared = true;                     // false: a stored landmark disappeared
  int x = 0, y = 0, width = 0, height = 0;  // box in pixels of the frame as sent
  std::string object_class;                 // empty when unclassified
  float confidence = 0;                     // in [0, 1]
};

// A scene-change alarm from PLACEREC_CHANGE (change_t): one change at a known place.
struct SceneAlarm {
  std::string robot;  // the robot whose frame shows the change
  int64_t sequence = 0;
  int64_t request_id = 0;
  int64_t frame_utime = 0;
  int64_t place_id = -1;  // the stored place, and its robot, sequence and capture time
  std::string place_robot;
  int64_t place_sequence = 0;
  int64_t place_utime = 0;
  int change_index = 0;  // this change among the frame's num_frame_changes
  int num_frame_changes = 0;
  ReportedChange change;
  int frame_width = 0, frame_height = 0;  // the frame as sent, pixels
  std::vector<uint8_t> frame_jpeg;        // the frame, small, boxes drawn
  std::vector<uint8_t> place_jpeg;        // the stored place's thumbnail (may be empty)
};

// The answer to one frame.
struct FrameResult {
  AnswerCode code = AnswerCode::kTimeout;
  std::string message;  // what was wrong; empty when ok
  bool ok() const { return code == AnswerCode::kOk; }

  std::string robot;
  int64_t sequence = 0;
  int64_t request_id = 0;
  bool insert = true;
  bool loop_closure = false;            // the best match scored at least the server's threshold
  std::vector<MatchedPlace> matches;    // best first
  bool change_checked = false;          // compared with the best match's stored view
  std::vector<ReportedChange> changes;  // scene changes there, most confident first
  int keypoints = 0;
  int objects = 0;
  int landmarks = 0;  // landmarks this frame stored
  int stored_descriptors = 0;
  int64_t place_id = -1;  // the place stored for this frame; -1 when none
  // The sequence the robot's next insert should carry at least (protocol 6): after every
  // sequence of the robot the server has learned; -1 when it knows none, and on answers to
  // frames it did not process (proto/README.md).
  int64_t next_sequence = -1;
  int64_t map_places = 0;
  int64_t map_landmarks = 0;
  int64_t map_descriptors = 0;
  double queue_ms = 0;                                  // waiting in the server's queue
  double server_ms = 0;                                 // receipt to answer in the server
  std::vector<std::pair<std::string, double>> timings;  // per stage, milliseconds
  double latency_ms = 0;                                // publish to answer, measured by the client
};

// One line for people: "ok: 812 keypoints, 14 objects, 3 landmarks; best left #30 score 57 ...".
std::string DescribeResult(const FrameResult& result);

// The server's heartbeat (status_t).
struct ServerStatus {
  std::string version;
  std::string map;
  double uptime_s = 0;
  double map_open_ms = 0;
  int64_t map_places = 0;
  int64_t map_landmarks = 0;
  int64_t map_descriptors = 0;
  int queue_depth = 0;
  int queue_capacity = 0;
  int in_progress = 0;
  int workers = 0;
  int robots = 0;
  int64_t frames_answered = 0;
  int64_t frames_failed = 0;
  int64_t frames_overloaded = 0;
  int64_t messages_dropped = 0;
  double frames_per_second = 0;
};

struct ClientOptions {
  // LCM URL; empty uses LCM's default ($LCM_DEFAULT_URL, else udpm://239.255.76.67:7667?ttl=0).
  std::string lcm_url;
  // How long Send waits for an answer, seconds.
  double timeout_s = 60.0;
  // When no answer came within this many seconds, the frame is sent again with the same request
  // id (a datagram lost in a burst, or a server that was restarting), and again after each
  // further interval until the timeout; the server answers a frame it already processed from its
  // record instead of processing it twice. 0 never sends again.
  double retry_after_s = 5.0;
  // Once an answer to a frame came that is not signed with our key (a server without that key,
  // or one refusing it, answers unsigned), wait this many seconds more for a signed answer, then
  // give up with what the unsigned one said: a wrong key is told in seconds, not at the timeout.
  // Anyone on the network can send such an answer, so this is also how soon a forgery can make
  // the client give up on a frame whose genuine answer is slower. 0: wait the whole timeout.
  double untrusted_grace_s = 10.0;
  // A keys file (server/README.md "Keys"; scripts/make-key.sh): frames are signed with its key
  // and only answers the server signed with that key are accepted (others are ignored and named
  // in the timeout message). Empty: frames go unsigned (a server with --auth off).
  std::string key_file;
  // Which key of key_file to use; empty: its first.
  std::string key_id;

  bool Check(std::string* error) const;
};

// A frame that was published and whose answer has not been collected yet.
struct PendingFrame {
  std::string robot;
  int64_t sequence = 0;
  int64_t request_id = 0;
  std::chrono::steady_clock::time_point sent;
  // The encoded frame_t, unsigned, kept to send it again (ClientOptions::retry_after_s); each
  // send is signed anew (a new replay-guard counter).
  std::shared_ptr<const std::vector<uint8_t>> message;
  int sends = 1;  // how often Wait published it
};

// Thread-safe: several threads may publish and wait at once (e.g. one per robot).
class PlacerecClient {
 public:
  static StatusOr<std::unique_ptr<PlacerecClient>> Connect(const ClientOptions& options);
  ~PlacerecClient();
  PlacerecClient(const PlacerecClient&) = delete;
  PlacerecClient& operator=(const PlacerecClient&) = delete;

  // Publishes `frame` (subscribing to its answer channel first); the answer is collected in the
  // background. An error when LCM refuses the message.
  StatusOr<PendingFrame> Publish(const OutgoingFrame& frame);
  // Waits up to `timeout_s` for the answer, sending the frame again every
  // options().retry_after_s; code kTimeout when none came, or options().untrusted_grace_s after
  // an answer not signed with our key (its message then says what that answer said).
  FrameResult Wait(const PendingFrame& pending, double timeout_s);
  // Publish, then wait options.timeout_s.
  FrameResult Send(const OutgoingFrame& frame);

  // Called on the receive thread with every awaited answer as it arrives (e.g. to print loop
  // closures at once); Wait may return the answer while the callback still runs. Set it before
  // publishing. Returns once the callback it replaces no longer runs (except when called from
  // the callback itself).
  void SetAnswerCallback(std::function<void(const FrameResult&)> callback);

  // Subscribes to PLACEREC_CHANGE and calls `callback` on the receive thread with every
  // scene-change alarm from then on. Alarms are not signed, so anybody on the LCM network can
  // send one: those naming a robot id the server would refuse (for the frame or the place) are
  // dropped, so that a robot id can name a file, and bytes of the class that are no printable
  // ASCII become '?', so that it can be printed.
  Status WatchAlarms(std::function<void(const SceneAlarm&)> callback);

  // Waits for the next heartbeat published after this call.
  StatusOr<ServerStatus> WaitForStatus(double timeout_s);

  const ClientOptions& options() const { return options_; }

 private:
  explicit PlacerecClient(const ClientOptions& options);
  Status SubscribeFor(const std::string& robot);
  void OnResult(const lcm::ReceiveBuffer* buffer, const std::string& channel);
  void OnStatus(const lcm::ReceiveBuffer* buffer, const std::string& channel);
  void OnChange(const lcm::ReceiveBuffer* buffer, const std::string& channel);
  void ReceiveLoop();
  // Signs (when a key is set) and publishes an encoded unsigned frame; LCM's return code.
  int PublishFrame(const std::vector<uint8_t>& message);

  ClientOptions options_;
  std::unique_ptr<lcm::LCM> lcm_;
  std::mutex mutex_;
  std::condition_variable answered_;
  std::unordered_map<int64_t, PendingFrame> awaited_;  // by request id
  std::unordered_map<int64_t, FrameResult> answers_;   // by request id
  // Answers to awaited frames that were not signed with our key, by request id: what they said,
  // and when the first came.
  struct Untrusted {
    std::string said;
    std::chrono::steady_clock::time_point first;
  };
  std::unordered_map<int64_t, Untrusted> untrusted_;
  std::unique_ptr<SigningKey> key_;  // null: unsigned
  int64_t last_counter_ = 0;         // the last replay-guard counter signed (publish_mutex_)
  std::set<std::string> subscribed_;
  bool wildcard_subscribed_ = false;
  int64_t next_request_id_ = 0;
  std::function<void(const FrameResult&)> callback_;
  int callbacks_running_ = 0;  // answer callbacks running now on the receive thread (mutex_)
  std::function<void(const SceneAlarm&)> alarm_callback_;
  bool alarms_subscribed_ = false;
  ServerStatus last_status_;
  int64_t statuses_ = 0;
  bool stop_ = false;
  std::mutex publish_mutex_;
  std::thread receiver_;
};

}  // namespace placerec
