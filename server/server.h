// placerec-server (DESIGN.md "Architecture"): holds one site's landmark map (SQLite, or PostgreSQL
// shared with other servers) and answers frames from many robots over LCM. The receive loop decodes
// each message on PLACEREC_FRAME and queues it in its robot's lane (server/work_queue.h); workers
// run the pipeline (server/frame_processor.h), the map commits the frame's landmarks, and only then
// is the answer published on PLACEREC_RESULT_<robot>. A heartbeat goes to PLACEREC_STATUS every
// second.
#pragma once

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "common/image/image.h"
#include "common/pipeline/place_map.h"
#include "common/pipeline/recognizer.h"
#include "common/storage/postgres_store.h"
#include "common/storage/sqlite_store.h"
#include "common/util/status.h"
#include "common/util/timer.h"
#include "placerec/change_t.hpp"
#include "placerec/frame_t.hpp"
#include "placerec/result_t.hpp"
#include "placerec/status_t.hpp"
#include "server/answer_record.h"
#include "server/authenticator.h"
#include "server/frame_processor.h"
#include "server/map_follower.h"
#include "server/sequence_gate.h"
#include "server/server_stats.h"
#include "server/work_queue.h"

namespace placerec {

struct ServerOptions {
  // The map: a SQLite file (created when missing, reloaded when present), or a PostgreSQL URL
  // (postgresql://... or postgres://..., IsPostgresUrl) of a map several servers share; each
  // then follows the others' inserts (server/map_follower.h).
  std::string db_path = "placerec.db";
  // The robots (and devices) this server answers; empty: every one. Servers sharing one LCM
  // network and one PostgreSQL map split the robots between them with disjoint lists; frames of
  // robots not listed are left to the other servers (no answer from this one).
  std::vector<std::string> robots;
  // LCM URLs, one per network the server serves at once, e.g.
  // "udpm://239.255.76.67:7667?ttl=1" for the robot LAN and "tcpq://127.0.0.1:7700" for remote
  // devices through an LCM TCP hub (scripts/lcm-hub.sh). Each frame's answer goes back on the
  // network the frame came from; heartbeats go to all. Empty (or an empty URL) uses LCM's
  // default: the LCM_DEFAULT_URL environment variable, else udpm://239.255.76.67:7667?ttl=0.
  std::vector<std::string> lcm_urls;
  // Worker threads running the pipeline; frames of one robot never run at once. 0: one per core
  // of the machine (ResolvedWorkers), so that with OpenCV held to one thread per frame
  // (--opencv-threads 1) a larger machine still keeps every core busy when robots are many.
  int workers = 0;
  // Frames waiting for a worker before new ones are answered "overloaded".
  int queue_capacity = 16;
  // Seconds between two heartbeats on PLACEREC_STATUS.
  double status_period_s = 1.0;
  // Before serving, repair a damaged map (RepairSqliteMap): drop the places that do not read
  // back whole, keep the damaged file as <db>.damaged and log how many places were dropped. A
  // damaged map is refused at start-up otherwise.
  bool repair = false;
  // Who may send frames (keys file, on by default; server/README.md "Keys").
  AuthOptions auth;
  SqliteStoreOptions store;
  PostgresStoreOptions postgres;
  MapFollowerOptions follower;
  DecodeOptions decode;
  SequenceRuleOptions sequence_rule;
  RecognizerOptions recognizer;

  bool Check(std::string* error) const;
  // The worker threads the server runs: `workers`, or for 0 the cores this process may use (its
  // CPU affinity, and a cgroup's CPU quota where one is set: a container given 2 CPUs of a large
  // host runs 2), at least 1, at most 256.
  int ResolvedWorkers() const;
};

// Whole cores a cgroup CPU quota allows, rounded up: cgroup v2's cpu.max text ("max 100000": no
// quota, "200000 100000": 2), or v1's cpu.cfs_quota_us and cpu.cfs_period_us (-1: no quota). 0
// when there is no quota or the text does not read.
int CoresOfCpuMax(const std::string& cpu_max);
int CoresOfCfsQuota(const std::string& quota_us, const std::string& period_us);

class Server {
 public:
  // Opens the map (loading every stored landmark) and LCM. Errors name the file or URL.
  static StatusOr<std::unique_ptr<Server>> Create(const ServerOptions& options);
  ~Server();

  // Serves until Stop() is called, then answers the frames still queued with "shutting down",
  // lets the running ones finish (their answers go out) and returns. An error only when LCM
  // fails.
  Status Run();

  // Asks Run() to return within about 0.1 s. Async-signal-safe: may be called from a signal
  // handler or another thread.
  void Stop() { stop_requested_.store(true); }

  // Asks Run() to read the keys file again (SIGHUP). Async-signal-safe. A file that does not
  // read keeps the old keys, and the log says why.
  void ReloadKeys() { reload_requested_.store(true); }

  // What the next heartbeat would say.
  status_t CurrentStatus();

 private:
  struct Job {
    frame_t frame;
    Timer received;      // since the message arrived
    size_t network = 0;  // index in networks_ of the network the frame came on
    // The sender's key (frames signed with a known key): its answer is signed with it.
    std::optional<SigningKey> key;
  };

  // One LCM network the server serves (ServerOptions::lcm_urls).
  struct Network {
    Network(Server* server, size_t index, const std::string& url)
        : server(server), index(index), url(url), lcm(url) {}
    void OnFrameMessage(const lcm::ReceiveBuffer* buffer, const std::string& channel) {
      server->OnFrameMessage(index, buffer, channel);
    }
    Server* server;
    size_t index;
    std::string url;  // as given; empty for LCM's default
    lcm::LCM lcm;
    std::mutex publish_mutex;
    lcm::Subscription* subscription = nullptr;
    // Set by the receive loop when LCM stopped delivering (e.g. the TCP hub went away); a failed
    // network is neither read nor written again.
    std::atomic<bool> failed{false};
  };

  Server(const ServerOptions& options, std::unique_ptr<PlaceMap> map,
         std::unique_ptr<Segmenter> segmenter, std::shared_ptr<const ObjectClassLabeler> labeler,
         Authenticator auth);
  void OnFrameMessage(size_t network, const lcm::ReceiveBuffer* buffer, const std::string& channel);
  void Work(Job& job);
  // Gives the heap's free pages back to the system once the queue has had no work for 5 s.
  void TrimWhenIdle(std::chrono::steady_clock::time_point now);
  // Publishes `answer` on its robot's channel of network `network`, signed with `key` (unsigned
  // when null); `processed` says whether a worker ran the frame.
  void Publish(result_t* answer, bool processed, size_t network, const SigningKey* key);
  // Publishes a scene-change alarm on PLACEREC_CHANGE of every network.
  void PublishAlarm(change_t* alarm);
  // Answers `frame` at once, unprocessed, with `status` (STATUS_BAD_REQUEST by default),
  // `message` and the map's size, signed with `key` when given.
  void RejectFrame(const frame_t& frame, const std::string& message, size_t network,
                   int8_t status = result_t::STATUS_BAD_REQUEST, const SigningKey* key = nullptr);
  void PublishStatus();
  // Waits up to `timeout_ms` for messages on every network and dispatches them; false when
  // every network's LCM failed.
  bool HandleMessages(int timeout_ms);
  // At a stop, with the queue shut down: hands every message LCM has received to OnFrameMessage
  // (which answers the frames "shutting down") until the networks stay quiet for 50 ms, for at
  // most two seconds. The number handled.
  int DrainReceivedFrames();
  // Whether another server answers `robot` (a valid id that --robots does not name); counts and
  // logs it. Receive loop only.
  bool LeftToOtherServers(const std::string& robot);

  ServerOptions options_;
  std::unique_ptr<PlaceMap> map_;
  FrameProcessor processor_;
  std::vector<std::unique_ptr<Network>> networks_;
  // Follows the other servers' inserts into map_ (PostgreSQL maps only); stopped first.
  std::unique_ptr<MapFollower> follower_;
  ServerStats stats_;
  // Frames in flight and recent answers per robot, so that a re-sent frame is not processed twice.
  AnswerRecord answers_;
  std::atomic<bool> stop_requested_{false};
  std::atomic<bool> reload_requested_{false};
  // When the queue last ran out of work (steady clock ticks), kNotIdle once the heap was trimmed
  // after it (TrimWhenIdle: free heap pages go back to the system after 5 s without work).
  static constexpr int64_t kNotIdle = -1;
  std::atomic<int64_t> idle_since_{kNotIdle};
  // Used by the receive loop only.
  Authenticator auth_;
  int64_t dropped_logged_ = 0;
  int64_t not_ours_ = 0;  // frames of robots other servers answer (ServerOptions::robots)
  int64_t unauthorised_logged_ = 0;
  int64_t replays_logged_ = 0;  // copies of accepted frames ignored
  // Last: its workers use everything above, so it is destroyed (joined) first.
  std::unique_ptr<LaneWorkQueue<Job>> queue_;
};

}  // namespace placerec
