// placerec-gateway (issue 26 item 3): "where am I?" over HTTPS for field devices that have no
// LCM: a photo in, the server's answer as JSON out. It talks LCM to placerec-server through the
// client library, as a query-only robot named after the device (it never inserts), and serves
// the web page of gateway/web. Every request but the page carries a device's bearer token;
// every error is a JSON body {"error": "..."} that says what to do.
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "client/client.h"
#include "common/storage/landmark_store.h"
#include "common/util/status.h"
#include "gateway/access.h"
#include "gateway/connection_guard.h"
#include "gateway/site_watcher.h"

namespace httplib {
class SSLServer;
}  // namespace httplib

namespace placerec {

struct GatewayOptions {
  std::string host = "127.0.0.1";      // address to listen on
  int port = 8443;                     // 0: any free port (bound_port() tells which)
  std::string cert_file;               // PEM certificate (scripts/make-cert.sh makes a test one)
  std::string key_file;                // its PEM private key
  std::string tokens_file;             // device tokens (gateway/access.h TokenTable)
  std::string web_dir;                 // the page's files; empty: the shipped gateway/web
  int64_t max_upload_bytes = 8 << 20;  // larger photos are refused (413)
  double requests_per_minute = 30;     // queries per token, on average ...
  double burst = 10;                   // ... with bursts of this many; reads (status, site,
                                       // pictures) have kReadsPerQuery times both
  int max_waiting_queries = 8;         // queries waiting on the server at once; more get 503
  double query_timeout_s = 30;         // waiting for the server's answer
  size_t recent_loop_closures = 20;    // kept for the site overview
  ClientOptions client;                // LCM URL, retries
  // How long a connection may take to send its headers, and how many one address may hold at
  // once (gateway/connection_guard.h): a client sending a byte at a time cannot hold the threads.
  ConnectionGuardOptions connections;
  // The server's map (a file path or a postgresql:// URL), read for the places' stored pictures
  // (GET /v1/places/{id}/thumbnail); empty: the gateway shows none. Never written.
  std::string db;

  bool Check(std::string* error) const;
};

// One HTTP answer, independent of the HTTP library (tests call the handlers directly).
struct HttpReply {
  int status = 200;
  std::string content_type = "application/json";
  std::string body;
  double retry_after_s = 0;  // > 0: sent as Retry-After
};

class Gateway {
 public:
  static StatusOr<std::unique_ptr<Gateway>> Create(const GatewayOptions& options);
  ~Gateway();

  // POST /v1/query: `image` (JPEG or PNG bytes) asked as a query-only frame of the token's
  // device. 200 with the answer; 401 bad or expired token, 413 too large, 415 not JPEG/PNG,
  // 422 the server could not use the image, 429 over the rate, 502/503/504 server trouble.
  HttpReply Query(const std::string& authorization, const std::string& image);
  // GET /v1/status: the server's last heartbeat.
  HttpReply ServerStatus(const std::string& authorization);
  // GET /v1/site: heartbeat, robots heard, recent loop closures.
  HttpReply Site(const std::string& authorization);
  // GET /v1/places/{id}/thumbnail: the place's stored picture (JPEG) from the map (--db).
  HttpReply Thumbnail(const std::string& authorization, const std::string& place_id);
  // GET /v1/alarms/{id}/{frame|place}.jpg: a recent scene-change alarm's pictures (the frame
  // with the change's box, the stored place), as the server published them.
  HttpReply AlarmPicture(const std::string& authorization, const std::string& alarm_id,
                         const std::string& which);

  // Reads the tokens file again before the next request (SIGHUP; async-signal-safe).
  void RequestTokenReload() { token_reload_requested_ = true; }
  // Reads the tokens file again now: devices added, removed or changed there are served so from
  // the next request on, and every key's client is made anew (reading --key-file again: a
  // changed secret is used). A file that cannot be used changes nothing, and the error says why.
  // Devices are hidden from the site overview from the moment they are listed, and stay hidden
  // after their removal.
  Status ReloadTokens();

  // Listens and serves until Stop(); an error when it cannot listen.
  Status Serve();
  void Stop();
  int bound_port() const { return bound_port_; }

 private:
  Gateway(const GatewayOptions& options, TokenTable tokens);
  // The device of a valid token within its rate (of queries, or of reads); otherwise *refusal
  // is the answer to send.
  bool Admit(const std::string& authorization, bool query, DeviceToken* device, HttpReply* refusal);
  // The tokens in force, read again first when a reload was requested.
  std::shared_ptr<const TokenTable> Tokens();
  // One LCM client per key the devices' queries are signed with (DeviceToken::key_id; "" is the
  // gateway's own key, ClientOptions::key_id).
  using Clients = std::map<std::string, std::shared_ptr<PlacerecClient>>;
  // A client for every key id of `tokens`, each reading --key-file anew.
  StatusOr<Clients> ConnectClients(const TokenTable& tokens) const;
  // The client that signs with `key_id`; null when the tokens in force name no such key (they
  // were read again since the request's token was checked).
  std::shared_ptr<PlacerecClient> ClientFor(const std::string& key_id);

  GatewayOptions options_;
  std::mutex reload_mutex_;  // serialises reloads
  std::mutex tokens_mutex_;  // guards tokens_ and clients_ (the pointers, held briefly)
  std::shared_ptr<const TokenTable> tokens_;
  Clients clients_;  // a query keeps its client alive while a reload replaces the map
  std::atomic<bool> token_reload_requested_{false};
  RateLimiter query_limiter_;
  RateLimiter read_limiter_;
  std::atomic<int> waiting_queries_{0};
  // Queries of each device waiting on the server: at most half of max_waiting_queries (at least
  // one), so that one device cannot take every slot.
  std::mutex waiting_mutex_;
  std::map<std::string, int> waiting_by_device_;
  std::unique_ptr<SiteWatcher> watcher_;
  std::unique_ptr<LandmarkStore> map_;  // null without --db
  // Outlives http_: the connections' SSL objects, freed by the server's threads, call it.
  std::unique_ptr<ConnectionGuard> guard_;
  std::unique_ptr<httplib::SSLServer> http_;
  std::atomic<int64_t> next_sequence_{0};
  std::atomic<int> bound_port_{0};
};

// Reads (status, site overview, pictures) a device may make per query of its rate: they cost the
// server nothing, and the page fetches two pictures per alarm besides polling the overview.
constexpr double kReadsPerQuery = 10;
// Threads serving HTTPS requests, one per connection; at most
// GatewayOptions::max_waiting_queries of them wait on the server and one address holds at most
// ConnectionGuardOptions::max_per_address, so the page and the overview stay served. An idle
// thread costs a stack's address space, not memory.
constexpr int kHttpThreads = 64;
// After its headers, a request has kAnswerSeconds (plus, for a query, the query timeout) to be
// answered, and its body as many more seconds as it needs at kMinUploadBytesPerSecond (128
// kbit/s: a 1 MB photo, the page's largest, in 64 s); then the connection is cut.
constexpr double kAnswerSeconds = 30;
constexpr double kMinUploadBytesPerSecond = 16 * 1024;

// {"error": message} with `status`.
HttpReply ErrorReply(int status, const std::string& message);

// `json` as text; bytes that are no UTF-8 (a decoded URL path, a robot id heard on the network)
// become U+FFFD instead of an exception.
std::string JsonText(const nlohmann::json& json);

}  // namespace placerec
