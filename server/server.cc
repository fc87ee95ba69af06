#include "server/server.h"

#include <malloc.h>
#include <poll.h>
#include <sched.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "common/pipeline/object_classes.h"
#include "common/util/logging.h"
#include "common/util/memory.h"
#include "proto/channels.h"
#include "server/protocol.h"

#ifndef PLACEREC_VERSION
#define PLACEREC_VERSION "unknown"
#endif

namespace placerec {
namespace {

// How long an insert waits for its place to come back through the map follower before indexing
// it itself (PlaceMap::IndexThroughFollower).
constexpr std::chrono::milliseconds kFollowerIndexTimeout(2000);

// Frames LCM may hold for the receive loop (see Run); bounds memory at this many messages.
constexpr int kLcmFrameQueue = 1024;

// This process's resident memory in MiB, 0 when it cannot be read.
double ResidentMiB() {
  ResidentMemory memory;
  return ReadResidentMemory(0, &memory) ? memory.current_mib : 0;
}

int64_t NowUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// ServerOptions::workers at most (and the most that 0, one per core, gives).
constexpr int kMaxWorkers = 256;

std::string DescribeUrl(const std::string& url) {
  if (!url.empty()) return url;
  const char* env = std::getenv("LCM_DEFAULT_URL");
  return env != nullptr && *env != '\0' ? std::string("LCM_DEFAULT_URL=") + env
                                        : std::string("LCM's default URL");
}

std::string DescribeUrls(const std::vector<std::string>& urls) {
  if (urls.empty()) return DescribeUrl("");
  std::string text;
  for (const std::string& url : urls) text += (text.empty() ? "" : " and ") + DescribeUrl(url);
  return text;
}

// What to check when LCM cannot open `url`.
std::string OpenAdvice(const std::string& url) {
  if (url.rfind("tcpq://", 0) == 0) {
    return "is the LCM TCP hub running at that address? (scripts/lcm-hub.sh start PORT)";
  }
  return "check the URL and that the network has multicast";
}

// Whole cores for `quota` microseconds of CPU per `period`, rounded up; 0 for no quota.
int CoresOfQuota(int64_t quota, int64_t period) {
  if (quota <= 0 || period <= 0) return 0;
  return static_cast<int>(std::min<int64_t>((quota + period - 1) / period, kMaxWorkers));
}

// The first line of a small file ("" when it does not read).
std::string FirstLine(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  return line;
}

}  // namespace

int CoresOfCpuMax(const std::string& cpu_max) {
  std::istringstream in(cpu_max);
  std::string quota;
  int64_t period = 0;
  if (!(in >> quota >> period) || quota == "max") return 0;
  char* end = nullptr;
  const long long value = std::strtoll(quota.c_str(), &end, 10);
  return *end == '\0' ? CoresOfQuota(value, period) : 0;
}

int CoresOfCfsQuota(const std::string& quota_us, const std::string& period_us) {
  char* quota_end = nullptr;
  char* period_end = nullptr;
  const long long quota = std::strtoll(quota_us.c_str(), &quota_end, 10);
  const long long period = std::strtoll(period_us.c_str(), &period_end, 10);
  if (quota_end == quota_us.c_str() || period_end == period_us.c_str()) return 0;
  return CoresOfQuota(quota, period);
}

int ServerOptions::ResolvedWorkers() const {
  if (workers > 0) return workers;
  // The cores this process may run on (taskset, a container's cpuset), not the machine's.
  // hardware_concurrency() is 0 when the machine does not say.
  int cores = static_cast<int>(std::thread::hardware_concurrency());
  cpu_set_t allowed;
  CPU_ZERO(&allowed);
  if (sched_getaffinity(0, sizeof(allowed), &allowed) == 0) cores = CPU_COUNT(&allowed);
  // A CPU quota of the cgroup the process runs in (a container's --cpus), as its own cgroup root
  // shows it (cgroup v2, or v1's cpu controller).
  int quota = CoresOfCpuMax(FirstLine("/sys/fs/cgroup/cpu.max"));
  if (quota == 0) {
    quota = CoresOfCfsQuota(FirstLine("/sys/fs/cgroup/cpu/cpu.cfs_quota_us"),
                            FirstLine("/sys/fs/cgroup/cpu/cpu.cfs_period_us"));
  }
  if (quota > 0) cores = std::min(cores, quota);
  return std::clamp(cores, 1, kMaxWorkers);
}

bool ServerOptions::Check(std::string* error) const {
  if (db_path.empty()) {
    *error = "--db must name the map file";
    return false;
  }
  if (workers < 0 || workers > kMaxWorkers) {
    *error = "--workers must be between 1 and 256, or 0 for one per core";
    return false;
  }
  if (queue_capacity < 1) {
    *error = "--queue must be at least 1";
    return false;
  }
  if (!(status_period_s > 0) || status_period_s > 3600) {
    *error = "--status-period must be positive and at most 3600 seconds";
    return false;
  }
  for (const std::string& robot : robots) {
    if (robot.empty()) {
      *error = "--robots must not name an empty robot id";
      return false;
    }
  }
  if (repair && IsPostgresUrl(db_path)) {
    *error = "--repair repairs SQLite map files; a PostgreSQL map is restored with its own tools";
    return false;
  }
  return auth.Check(error) && store.Check(error) && postgres.Check(error) &&
         follower.Check(error) && decode.Check(error) && sequence_rule.Check(error) &&
         recognizer.Check(error);
}

StatusOr<std::unique_ptr<Server>> Server::Create(const ServerOptions& options) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  StatusOr<Authenticator> auth = Authenticator::Create(options.auth, NowUtime());
  if (!auth.ok()) return auth.status();
  StatusOr<std::unique_ptr<Segmenter>> segmenter = MakeSegmenter(options.recognizer.analyzer);
  if (!segmenter.ok()) return segmenter.status();
  // Without the object classifiers the server refuses to start, with the loader's advice.
  StatusOr<std::unique_ptr<ObjectClassLabeler>> loaded =
      ObjectClassLabeler::LoadIfEnabled(options.recognizer.classes);
  if (!loaded.ok()) return loaded.status();
  std::shared_ptr<const ObjectClassLabeler> labeler = std::move(*loaded);
  if (options.repair) {
    StatusOr<MapRepairReport> repaired = RepairSqliteMap(options.db_path, options.store);
    if (!repaired.ok()) return repaired.status();
    if (repaired->rewritten) {
      LOG(WARNING) << "repaired map " << options.db_path << ": dropped " << repaired->places_dropped
                   << " damaged places, kept " << repaired->places_kept << " places ("
                   << repaired->landmarks_kept
                   << " landmarks); damage found: " << repaired->problems
                   << "; the damaged file is kept as " << repaired->damaged_copy
                   << (repaired->notes.empty() ? "" : "; kept otherwise than stored: ")
                   << repaired->notes;
    } else {
      LOG(INFO) << "map " << options.db_path << " is whole (" << repaired->places_kept
                << " places); nothing to repair";
    }
  }
  const bool postgres = IsPostgresUrl(options.db_path);
  StatusOr<std::unique_ptr<LandmarkStore>> store =
      postgres ? OpenPostgresStore(options.db_path, options.postgres)
               : OpenSqliteStore(options.db_path, options.store);
  if (!store.ok()) return store.status();
  StatusOr<std::unique_ptr<PlaceMap>> map =
      PlaceMap::Open(std::move(*store), EffectiveOptions(options.recognizer).index);
  if (!map.ok()) return map.status();
  std::unique_ptr<Server> server(new Server(options, std::move(*map), std::move(*segmenter),
                                            std::move(labeler), std::move(*auth)));
  if (postgres) {
    // From the last place loaded on: later ones, whoever inserts them, come through the feed.
    PlaceId last;
    server->map_->ForEachPlace([&last](const Place& place) {
      if (last < place.id) last = place.id;
    });
    Server* raw = server.get();
    server->follower_ = std::make_unique<MapFollower>(
        options.db_path, options.postgres, options.follower, server->map_.get(), last,
        [raw](const Place& place) { raw->processor_.NoteStored(place); });
    // Every server indexes every place in id order, its own ones included (PlaceMap).
    server->map_->IndexThroughFollower(kFollowerIndexTimeout);
    server->follower_->Start();
  }
  for (const std::unique_ptr<Network>& network : server->networks_) {
    // A tcpq URL whose hub does not answer leaves a "good" LCM without a connection.
    if (!network->lcm.good() || network->lcm.getFileno() < 0) {
      return Status::IoError("cannot open LCM (" + DescribeUrl(network->url) + "); " +
                             OpenAdvice(network->url));
    }
  }
  return server;
}

Server::Server(const ServerOptions& options, std::unique_ptr<PlaceMap> map,
               std::unique_ptr<Segmenter> segmenter,
               std::shared_ptr<const ObjectClassLabeler> labeler, Authenticator auth)
    : options_(options),
      map_(std::move(map)),
      processor_(options.recognizer, options.decode, map_.get(), std::move(segmenter),
                 options.sequence_rule, std::move(labeler)),
      auth_(std::move(auth)) {
  const std::vector<std::string> urls =
      options.lcm_urls.empty() ? std::vector<std::string>{""} : options.lcm_urls;
  for (const std::string& url : urls) {
    networks_.push_back(std::make_unique<Network>(this, networks_.size(), url));
  }
  queue_ = std::make_unique<LaneWorkQueue<Job>>(
      options_.ResolvedWorkers(), options_.queue_capacity, [this](Job& job) { Work(job); },
      [this] { idle_since_.store(std::chrono::steady_clock::now().time_since_epoch().count()); });
}

Server::~Server() {
  if (follower_) follower_->Stop();
  if (queue_) queue_->Shutdown();
}

Status Server::Run() {
  for (const std::unique_ptr<Network>& network : networks_) {
    network->subscription =
        network->lcm.subscribe(kFrameChannel, &Network::OnFrameMessage, network.get());
    if (network->subscription == nullptr) {
      return Status::Internal("cannot subscribe to PLACEREC_FRAME on " + DescribeUrl(network->url));
    }
    // LCM keeps at most 30 undispatched messages per subscription by default and silently drops
    // the rest; a burst from a fleet can exceed that before this loop dispatches them (each
    // dispatch only decodes and queues). Our own queue decides what is "overloaded".
    network->subscription->setQueueCapacity(kLcmFrameQueue);
  }
  const MapCounts counts = map_->Counts();
  LOG(INFO) << "placerec-server " << PLACEREC_VERSION << " serving " << map_->Describe() << " ("
            << counts.places << " places, " << counts.landmarks << " landmarks, loaded in "
            << map_->open_ms() << " ms) over " << DescribeUrls(options_.lcm_urls) << " with "
            << queue_->workers() << " workers, queue of " << options_.queue_capacity;
  if (options_.auth.enabled) {
    std::string ids;
    for (const std::string& id : auth_.KeyIds()) ids += (ids.empty() ? "" : ", ") + id;
    LOG(INFO) << "authentication on: frames must be signed with one of the keys of "
              << options_.auth.keys_file << " (" << ids << "); window " << options_.auth.window_s
              << " s";
    if (!auth_.warning().empty()) LOG(WARNING) << auth_.warning();
  } else {
    LOG(WARNING) << "AUTHENTICATION IS OFF (--auth off): any process that can publish on "
                 << DescribeUrls(options_.lcm_urls)
                 << " may insert frames under any robot's name and query the map, and answers "
                    "are unsigned. Use this on a lab LAN only; give --keys FILE everywhere else.";
  }
  const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(options_.status_period_s));
  auto next_status = std::chrono::steady_clock::now();
  Status result;
  while (!stop_requested_.load()) {
    if (reload_requested_.exchange(false) && options_.auth.enabled) {
      const Status reloaded = auth_.Reload();
      if (reloaded.ok()) {
        std::string ids;
        for (const std::string& id : auth_.KeyIds()) ids += (ids.empty() ? "" : ", ") + id;
        LOG(INFO) << "reloaded the keys file " << options_.auth.keys_file << ": " << ids;
        if (!auth_.warning().empty()) LOG(WARNING) << auth_.warning();
      } else {
        LOG(ERROR) << "could not reload the keys file, the old keys stay: " << reloaded.message();
      }
    }
    const auto now = std::chrono::steady_clock::now();
    TrimWhenIdle(now);
    if (now >= next_status) {
      PublishStatus();
      next_status += period;
      if (next_status < now) next_status = now + period;
    }
    const int wait_ms = static_cast<int>(std::min<int64_t>(
        100, std::chrono::duration_cast<std::chrono::milliseconds>(next_status - now).count() + 1));
    if (!HandleMessages(wait_ms) && !stop_requested_.load()) {
      result = Status::IoError("LCM stopped delivering messages on every network");
      break;
    }
  }
  // Every frame received is answered: what waits in the queue "shutting down", then what LCM
  // has received but not yet handed over (its subscription queue; unsubscribing would drop it
  // unanswered), which the stopped queue refuses and OnFrameMessage answers the same way.
  std::vector<Job> pending = queue_->Shutdown();
  for (Job& job : pending) {
    // No longer in flight, and copies that came on other networks meanwhile are told as well. (A
    // copy coming later is refused when unsigned; a signed one is a replay of its counter and is
    // dropped unanswered, as any replay.)
    const std::vector<size_t> also = answers_.Forget(job.frame);
    result_t answer = AnswerTemplate(job.frame);
    SetError(result_t::STATUS_SHUTTING_DOWN,
             "the server is shutting down; the frame was not processed", &answer);
    const SigningKey* key = job.key ? &*job.key : nullptr;
    for (const size_t copy : also) {
      result_t told = answer;
      Publish(&told, false, copy, key);
    }
    Publish(&answer, false, job.network, key);
  }
  const int drained = DrainReceivedFrames();
  for (const std::unique_ptr<Network>& network : networks_) {
    network->lcm.unsubscribe(network->subscription);
    network->subscription = nullptr;
  }
  PublishStatus();
  // The next start loads the descriptor index from this snapshot instead of growing it again.
  const Status saved = map_->SaveIndexSnapshot();
  LOG_IF(WARNING, !saved.ok()) << "cannot write the descriptor index snapshot: " << saved.message()
                               << "; the next start indexes what the last snapshot does not cover";
  LOG(INFO) << "placerec-server stopped; " << pending.size()
            << " queued frames answered 'shutting down', then " << drained
            << " messages received before the stop handled (frames answered the same); map "
            << map_->Describe() << " closed";
  return result;
}

int Server::DrainReceivedFrames() {
  // Bounded, in case senders keep sending: what arrives later is theirs to send again.
  constexpr double kDrainSeconds = 2.0;
  const auto until = std::chrono::steady_clock::now() +
                     std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                         std::chrono::duration<double>(kDrainSeconds));
  // Done once every network stayed quiet for kQuietMs: LCM's receive thread may still be moving
  // datagrams from the socket into its queue when the queue first looks empty.
  constexpr int kQuietMs = 50;
  int handled = 0;
  auto quiet_since = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() < until) {
    bool any = false;
    for (const std::unique_ptr<Network>& network : networks_) {
      if (network->failed) continue;
      if (network->lcm.handleTimeout(5) > 0) {
        any = true;
        ++handled;
      }
    }
    const auto now = std::chrono::steady_clock::now();
    if (any) {
      quiet_since = now;
    } else if (now - quiet_since >= std::chrono::milliseconds(kQuietMs)) {
      break;
    }
  }
  return handled;
}

bool Server::LeftToOtherServers(const std::string& robot) {
  std::string why;
  if (options_.robots.empty() || !IsValidWireRobotId(robot, &why) ||
      std::find(options_.robots.begin(), options_.robots.end(), robot) != options_.robots.end()) {
    return false;
  }
  if (not_ours_ == 0) {
    LOG(INFO) << "frames of robot '" << robot
              << "' are left to the other servers (not in --robots)";
  }
  ++not_ours_;
  return true;
}

bool Server::HandleMessages(int timeout_ms) {
  std::vector<pollfd> fds;
  for (const std::unique_ptr<Network>& network : networks_) {
    // A failed network is left out (poll skips negative descriptors).
    fds.push_back(pollfd{network->failed ? -1 : network->lcm.getFileno(), POLLIN, 0});
  }
  const int ready = poll(fds.data(), fds.size(), timeout_ms);
  if (ready < 0) return errno == EINTR;
  bool any_serving = false;
  for (size_t i = 0; i < fds.size(); ++i) {
    Network& network = *networks_[i];
    if (!network.failed && (fds[i].revents & (POLLIN | POLLHUP | POLLERR | POLLNVAL))) {
      // handleTimeout(0) dispatches what is there without blocking when nothing complete is.
      if ((fds[i].revents & POLLNVAL) || network.lcm.handleTimeout(0) < 0 ||
          network.lcm.getFileno() < 0) {
        network.failed = true;
        LOG(ERROR) << "LCM network " << DescribeUrl(network.url)
                   << " stopped delivering messages; the server goes on without it (restart it "
                      "to serve that network again: "
                   << OpenAdvice(network.url) << ")";
      }
    }
    any_serving = any_serving || !network.failed;
  }
  return any_serving;
}

void Server::OnFrameMessage(size_t network, const lcm::ReceiveBuffer* buffer,
                            const std::string& channel) {
  Job job;
  job.network = network;
  StatusOr<frame_t> frame = DecodeFrameMessage(buffer->data, buffer->data_size);
  if (!frame.ok()) {
    // A frame whose head is whole (robot and request id readable) is answered with the reason;
    // anything else is dropped.
    const StatusOr<frame_t> head = DecodeFrameHead(buffer->data, buffer->data_size);
    if (head.ok()) {
      if (LeftToOtherServers(head->robot)) return;
      RejectFrame(*head, "malformed frame: " + frame.status().message(), network);
      return;
    }
    stats_.Dropped();
    // Log the first few and then every hundredth, so that a flood cannot fill the disk.
    if (dropped_logged_ < 10 || dropped_logged_ % 100 == 0) {
      LOG(WARNING) << "dropped a " << buffer->data_size << "-byte message on " << channel
                   << " that is not a valid frame: " << frame.status().message();
    }
    ++dropped_logged_;
    return;
  }
  job.frame = std::move(*frame);
  std::string why;
  if (!IsValidWireRobotId(job.frame.robot, &why)) {
    // No lane and no channel of its own: answer at once on the shared error channel. No server's
    // --robots names such an id, so every server answers it (the sender takes the first).
    RejectFrame(job.frame, why, network);
    return;
  }
  if (LeftToOtherServers(job.frame.robot)) return;
  Authenticator::Verdict verdict =
      auth_.Check(job.frame, NowUtime(), buffer->data, buffer->data_size);
  if (!verdict.ok) {
    // Never queued: the map and the robot's state stay as they are.
    if (verdict.replayed) {
      // A copy that came on another network (a device on the robot LAN and the hub at once) is
      // owed the answer there: the genuine answer, so a copier gains nothing.
      result_t recorded;
      const SigningKey* copy_key = verdict.key ? &*verdict.key : nullptr;
      switch (answers_.CopyOnNetwork(job.frame, network, &recorded)) {
        case AnswerRecord::Seen::kAnswered:
          Publish(&recorded, false, network, copy_key);
          return;
        case AnswerRecord::Seen::kInFlight:
          return;
        case AnswerRecord::Seen::kNew:
          break;
      }
      // Not answered (Authenticator::Verdict::replayed): the original frame has its answer.
      if (replays_logged_ < 10 || replays_logged_ % 100 == 0) {
        LOG(WARNING) << "ignored a copy of frame " << job.frame.sequence << " of robot '"
                     << job.frame.robot << "' (" << verdict.message << "); not answered";
      }
      ++replays_logged_;
      return;
    }
    if (unauthorised_logged_ < 10 || unauthorised_logged_ % 100 == 0) {
      LOG(WARNING) << "refused frame " << job.frame.sequence << " of robot '" << job.frame.robot
                   << "' (" << (job.frame.insert ? "insert" : "query") << "): " << verdict.message;
    }
    ++unauthorised_logged_;
    RejectFrame(job.frame, verdict.message, network, result_t::STATUS_UNAUTHORISED,
                verdict.key ? &*verdict.key : nullptr);
    return;
  }
  job.key = std::move(verdict.key);
  const SigningKey* key = job.key ? &*job.key : nullptr;
  stats_.SawRobot(job.frame.robot);
  result_t recorded;
  switch (answers_.Begin(job.frame, &recorded, network)) {
    case AnswerRecord::Seen::kInFlight:
      VLOG(1) << "frame " << job.frame.sequence << " of robot '" << job.frame.robot
              << "' sent again while it is processed; its answer is on its way (on this "
              << "network too)";
      return;
    case AnswerRecord::Seen::kAnswered:
      VLOG(1) << "frame " << job.frame.sequence << " of robot '" << job.frame.robot
              << "' sent again: its answer is sent again";
      Publish(&recorded, false, network, key);
      return;
    case AnswerRecord::Seen::kNew:
      break;
  }
  const std::string robot = job.frame.robot;
  const std::optional<SigningKey> sender = job.key;  // `job` is moved into the queue
  key = sender ? &*sender : nullptr;
  LaneWorkQueue<Job>::PushResult pushed = queue_->Push(robot, &job);
  if (pushed.evicted) {
    const std::vector<size_t> also = answers_.Forget(pushed.evicted->frame);
    // The queue was full and `robot` held less than its share: the robot holding the most gave
    // way with its newest frame.
    result_t answer = AnswerTemplate(pushed.evicted->frame);
    SetError(result_t::STATUS_OVERLOADED,
             "server overloaded: robot '" + pushed.evicted_lane + "' held " +
                 std::to_string(pushed.evicted_lane_waiting) + " of the " +
                 std::to_string(pushed.waiting) +
                 " waiting frames, more than its share while robot '" + robot +
                 "' waited, so its newest frame gave way; it was not processed, send it again "
                 "later",
             &answer);
    const SigningKey* evicted_key = pushed.evicted->key ? &*pushed.evicted->key : nullptr;
    for (const size_t copy : also) {
      result_t told = answer;
      Publish(&told, false, copy, evicted_key);
    }
    Publish(&answer, false, pushed.evicted->network, evicted_key);
  }
  if (!pushed.queued) {
    const std::vector<size_t> also = answers_.Forget(job.frame);
    result_t answer = AnswerTemplate(job.frame);
    if (pushed.stopped) {
      SetError(result_t::STATUS_SHUTTING_DOWN,
               "the server is shutting down; the frame was not processed", &answer);
    } else {
      SetError(result_t::STATUS_OVERLOADED,
               "server overloaded: the queue is full (" + std::to_string(pushed.waiting) +
                   " frames waiting, " + std::to_string(pushed.lane_waiting) +
                   " of them this robot's, its share while other robots wait); the frame was "
                   "not processed, send it again later",
               &answer);
    }
    for (const size_t copy : also) {
      result_t told = answer;
      Publish(&told, false, copy, key);
    }
    Publish(&answer, false, network, key);
  }
}

void Server::RejectFrame(const frame_t& frame, const std::string& message, size_t network,
                         int8_t status, const SigningKey* key) {
  result_t answer = AnswerTemplate(frame);
  SetError(status, message, &answer);
  const MapCounts counts = map_->Counts();
  answer.map_places = counts.places;
  answer.map_landmarks = counts.landmarks;
  answer.map_descriptors = counts.descriptors;
  Publish(&answer, false, network, key);
}

void Server::Work(Job& job) {
  const double queue_ms = job.received.ElapsedMs();
  std::vector<change_t> alarms;
  result_t answer = processor_.Process(job.frame, &alarms);
  answer.queue_ms = queue_ms;
  answer.server_ms = job.received.ElapsedMs();
  if (answer.status == result_t::STATUS_OK) {
    VLOG(1) << job.frame.robot << " #" << job.frame.sequence << ": " << answer.objects
            << " objects, " << answer.landmarks << " landmarks, " << answer.num_matches
            << " matches, " << answer.server_ms << " ms";
    if (answer.loop_closure) {
      LOG(INFO) << "loop closure: " << job.frame.robot << " #" << job.frame.sequence << " revisits "
                << answer.matches[0].robot << " #" << answer.matches[0].sequence << " (score "
                << answer.matches[0].score << ")";
    }
  } else {
    LOG(WARNING) << "frame " << job.frame.sequence << " of robot '" << job.frame.robot
                 << "': " << WireStatusName(answer.status) << ": " << answer.message;
  }
  const std::vector<size_t> also = answers_.Finish(job.frame, answer);
  // Copies of the frame that came on other networks while it ran get the answer there.
  for (const size_t copy : also) {
    result_t told = answer;
    Publish(&told, false, copy, job.key ? &*job.key : nullptr);
  }
  Publish(&answer, true, job.network, job.key ? &*job.key : nullptr);
  for (change_t& alarm : alarms) PublishAlarm(&alarm);
}

void Server::PublishAlarm(change_t* alarm) {
  alarm->utime = NowUtime();
  LOG(INFO) << "scene change: " << alarm->robot << " #" << alarm->sequence << " at place "
            << alarm->place_id << " (" << alarm->place_robot << " #" << alarm->place_sequence
            << "): " << (alarm->kind == change_t::KIND_APPEARED ? "appeared" : "disappeared") << " "
            << (alarm->object_class.empty() ? "object" : alarm->object_class) << " at "
            << alarm->box[0] << "," << alarm->box[1] << " " << alarm->box[2] << "x" << alarm->box[3]
            << ", confidence " << alarm->confidence;
  // Operators may watch on any of the server's networks, like the heartbeat.
  for (const std::unique_ptr<Network>& network : networks_) {
    if (network->failed) continue;
    std::lock_guard lock(network->publish_mutex);
    if (network->lcm.publish(kChangeChannel, alarm) != 0) {
      LOG(ERROR) << "could not publish a scene-change alarm on " << DescribeUrl(network->url);
    }
  }
}

void Server::Publish(result_t* answer, bool processed, size_t network, const SigningKey* key) {
  answer->utime = NowUtime();
  if (key != nullptr) {
    SignAnswer(*key, answer);
  } else {
    ClearAnswerSignature(answer);
  }
  const std::string channel = ResultChannel(answer->robot);
  Network& to = *networks_[network];
  int rc = -1;
  if (!to.failed) {
    std::lock_guard lock(to.publish_mutex);
    rc = to.lcm.publish(channel, answer);
  }
  if (rc != 0) {
    LOG(ERROR) << "could not publish the answer to frame " << answer->sequence << " of robot '"
               << answer->robot << "' on " << channel << " of " << DescribeUrl(to.url);
  }
  stats_.Answered(processed, answer->status != result_t::STATUS_OK,
                  answer->status == result_t::STATUS_OVERLOADED);
}

void Server::TrimWhenIdle(std::chrono::steady_clock::time_point now) {
  // glibc keeps the memory a frame's analysis freed in its per-thread arenas, so without this
  // resident memory stays at the high-water mark of the busiest moment and says little about
  // what the map holds. Not after every frame: the next frame would fault the pages in again.
  constexpr std::chrono::seconds kIdleBeforeTrim(5);
  int64_t since = idle_since_.load();
  if (since == kNotIdle) return;
  const std::chrono::steady_clock::time_point idle(std::chrono::steady_clock::duration{since});
  if (now - idle < kIdleBeforeTrim || queue_->running() > 0 || queue_->depth() > 0) return;
  // A burst that ended since sets a later time: then wait for that one.
  if (!idle_since_.compare_exchange_strong(since, kNotIdle)) return;
  const double before = ResidentMiB();
  malloc_trim(0);
  LOG(INFO) << "no work for " << kIdleBeforeTrim.count()
            << " s: free heap memory returned to the system (resident " << before << " -> "
            << ResidentMiB() << " MiB)";
}

status_t Server::CurrentStatus() {
  const ServerStats::Snapshot s = stats_.Take();
  const MapCounts counts = map_->Counts();
  status_t status;
  status.utime = NowUtime();
  status.version = PLACEREC_VERSION;
  status.map = map_->Describe();
  status.uptime_s = s.uptime_s;
  status.map_open_ms = map_->open_ms();
  status.map_places = counts.places;
  status.map_landmarks = counts.landmarks;
  status.map_descriptors = counts.descriptors;
  status.queue_depth = queue_->depth();
  status.queue_capacity = queue_->capacity();
  status.in_progress = queue_->running();
  status.workers = queue_->workers();
  status.robots = s.robots;
  status.frames_answered = s.answered;
  status.frames_failed = s.failed;
  status.frames_overloaded = s.overloaded;
  status.messages_dropped = s.dropped;
  status.frames_per_second = s.frames_per_second;
  return status;
}

void Server::PublishStatus() {
  const status_t status = CurrentStatus();
  for (const std::unique_ptr<Network>& network : networks_) {
    if (network->failed) continue;
    std::lock_guard lock(network->publish_mutex);
    if (network->lcm.publish(kStatusChannel, &status) != 0) {
      LOG(WARNING) << "could not publish the status on " << kStatusChannel << " of "
                   << DescribeUrl(network->url);
    }
  }
}

}  // namespace placerec
