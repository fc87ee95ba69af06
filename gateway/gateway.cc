#include "gateway/gateway.h"

#include <httplib.h>

#include <charconv>
#include <chrono>
#include <set>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "common/storage/postgres_store.h"
#include "common/storage/sqlite_store.h"
#include "common/util/logging.h"
#include "proto/auth/signing.h"

namespace placerec {
namespace {

// A device's body over --max-upload-bytes but at most this many times it is read and dropped
// before its 413 (so that the answer reaches it); a larger one is refused unread.
constexpr int64_t kMaxDiscardedUploadFactor = 4;
// A body without a valid token is read (to answer 401 after it) only up to this many bytes.
constexpr int64_t kMaxAnonymousBodyBytes = 64 * 1024;

int64_t NowUnix() {
  return std::chrono::duration_cast<std::chrono::seconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

int64_t NowMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// The image's encoding from its first bytes; false when it is neither JPEG nor PNG.
bool SniffEncoding(const std::string& bytes, FrameEncoding* encoding) {
  if (bytes.size() >= 3 && static_cast<unsigned char>(bytes[0]) == 0xFF &&
      static_cast<unsigned char>(bytes[1]) == 0xD8 &&
      static_cast<unsigned char>(bytes[2]) == 0xFF) {
    *encoding = FrameEncoding::kJpeg;
    return true;
  }
  if (bytes.size() >= 8 && bytes.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0) {
    *encoding = FrameEncoding::kPng;
    return true;
  }
  return false;
}

// The HTTP status for a server answer that is not ok.
int HttpStatusOf(AnswerCode code) {
  switch (code) {
    case AnswerCode::kBadImage:
      return 422;
    case AnswerCode::kUnauthorised:
      return 403;
    case AnswerCode::kOverloaded:
    case AnswerCode::kShuttingDown:
      return 503;
    case AnswerCode::kTimeout:
      return 504;
    default:
      return 502;
  }
}

nlohmann::json AnswerJson(const FrameResult& r) {
  nlohmann::json matches = nlohmann::json::array();
  for (const MatchedPlace& m : r.matches) {
    nlohmann::json classes = nlohmann::json::array();
    for (const auto& [name, count] : m.classes)
      classes.push_back({{"class", name}, {"count", count}});
    matches.push_back({{"robot", m.robot},
                       {"sequence", m.sequence},
                       {"utime", m.utime},
                       {"place_id", m.place_id},
                       {"score", m.score},
                       {"inliers", m.inliers},
                       {"matched_landmarks", m.matched_landmarks},
                       {"classes", classes},
                       {"thumbnail", "/v1/places/" + std::to_string(m.place_id) + "/thumbnail"}});
  }
  nlohmann::json changes = nlohmann::json::array();
  for (const ReportedChange& c : r.changes) {
    changes.push_back({{"kind", c.appeared ? "appeared" : "disappeared"},
                       {"box", {{"x", c.x}, {"y", c.y}, {"width", c.width}, {"height", c.height}}},
                       {"class", c.object_class},
                       {"confidence", c.confidence}});
  }
  return {{"status", "ok"},
          {"loop_closure", r.loop_closure},
          {"change_checked", r.change_checked},
          {"changes", changes},
          {"matches", matches},
          {"keypoints", r.keypoints},
          {"objects", r.objects},
          {"map_places", r.map_places},
          {"server_ms", r.server_ms},
          {"latency_ms", r.latency_ms}};
}

// A whole decimal number (the ids of URL paths).
bool ParseInt64(const std::string& text, int64_t* value) {
  const char* end = text.data() + text.size();
  const auto [next, error] = std::from_chars(text.data(), end, *value);
  return error == std::errc() && next == end && !text.empty();
}

// "Bearer TOKEN" -> TOKEN; empty when the header is missing or of another scheme.
std::string BearerToken(const std::string& authorization) {
  static const std::string kScheme = "Bearer ";
  if (authorization.size() <= kScheme.size() || authorization.compare(0, kScheme.size(), kScheme)) {
    return "";
  }
  return authorization.substr(kScheme.size());
}

}  // namespace

bool GatewayOptions::Check(std::string* error) const {
  if (cert_file.empty() || key_file.empty()) {
    *error =
        "--cert and --key are required (PEM files; scripts/make-cert.sh DIR makes a "
        "self-signed pair for tests and demos)";
    return false;
  }
  if (tokens_file.empty()) {
    *error = "--tokens is required: a file of `TOKEN DEVICE [key=KEY_ID] [expires=...]` lines";
    return false;
  }
  if (port < 0 || port > 65535) {
    *error = "--port must be in [0, 65535]";
    return false;
  }
  if (max_upload_bytes < 1024) {
    *error = "--max-upload-bytes must be at least 1024";
    return false;
  }
  if (!(requests_per_minute > 0) || !(burst >= 1)) {
    *error = "--requests-per-minute must be > 0 and --burst >= 1";
    return false;
  }
  if (max_waiting_queries < 1 || max_waiting_queries >= kHttpThreads) {
    *error = "--max-waiting-queries must be 1 to " + std::to_string(kHttpThreads - 1) +
             " (of the gateway's " + std::to_string(kHttpThreads) + " HTTPS threads)";
    return false;
  }
  if (!(query_timeout_s > 0)) {
    *error = "--query-timeout must be > 0 seconds";
    return false;
  }
  if (!(connections.header_seconds > 0)) {
    *error = "--header-timeout must be > 0 seconds";
    return false;
  }
  if (connections.max_per_address < 0) {
    *error = "--max-connections-per-address must be 0 (no limit) or more";
    return false;
  }
  return client.Check(error);
}

std::string JsonText(const nlohmann::json& json) {
  return json.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

HttpReply ErrorReply(int status, const std::string& message) {
  HttpReply reply;
  reply.status = status;
  reply.body = JsonText(nlohmann::json{{"error", message}});
  return reply;
}

namespace {

// The tokens file at `path`; an error also when it lists no device.
StatusOr<TokenTable> LoadTokens(const std::string& path) {
  StatusOr<TokenTable> tokens = TokenTable::Load(path);
  if (tokens.ok() && tokens->size() == 0) {
    return Status::InvalidArgument(path + " lists no device: nobody could use the gateway");
  }
  return tokens;
}

// Warns of every key the gateway signs with (its own, --key-id or the file's first, and the
// devices' own keys that the tokens file names) that may insert: a query key is enough.
void WarnOfInsertKeys(const GatewayOptions& options, const TokenTable& tokens) {
  if (options.client.key_file.empty()) return;
  std::string warning;
  StatusOr<std::vector<SigningKey>> keys = ReadKeysFile(options.client.key_file, &warning);
  if (!keys.ok() || keys->empty()) return;
  std::set<std::string> ids = {options.client.key_id.empty() ? keys->front().id
                                                             : options.client.key_id};
  for (const std::string& key_id : tokens.KeyIds()) {
    if (!key_id.empty()) ids.insert(key_id);
  }
  for (const std::string& id : ids) {
    const SigningKey* key = FindKey(*keys, id);
    if (key != nullptr && key->may_insert) {
      LOG(WARNING) << "key '" << id << "' of " << options.client.key_file
                   << " may insert: the gateway only queries, so a query-only key is enough "
                      "and limits what a stolen key can do";
    }
  }
}

}  // namespace

StatusOr<std::unique_ptr<Gateway>> Gateway::Create(const GatewayOptions& options) {
  std::string error;
  if (!options.Check(&error)) return Status::InvalidArgument(error);
  StatusOr<TokenTable> tokens = LoadTokens(options.tokens_file);
  if (!tokens.ok()) return tokens.status();
  if (options.client.key_file.empty()) {
    LOG(WARNING) << "no --key-file: the gateway's queries go unsigned, and only a placerec-server "
                    "started with --auth off answers them; give it a query key "
                    "(scripts/make-key.sh gateway query) that the server's --keys file has";
  }
  WarnOfInsertKeys(options, *tokens);
  std::unique_ptr<Gateway> gateway(new Gateway(options, std::move(*tokens)));
  StatusOr<Gateway::Clients> clients = gateway->ConnectClients(*gateway->tokens_);
  if (!clients.ok()) return clients.status();
  gateway->clients_ = std::move(*clients);
  StatusOr<std::unique_ptr<SiteWatcher>> watcher = SiteWatcher::Start(
      options.client.lcm_url, options.recent_loop_closures, gateway->tokens_->Devices());
  if (!watcher.ok()) return watcher.status();
  gateway->watcher_ = std::move(*watcher);
  if (!options.db.empty()) {
    // The server's map, read only for pictures; it must exist (the server made it).
    SqliteStoreOptions store;
    store.read_only = true;     // nothing in the server's map changes through the gateway
    store.quick_check = false;  // the server checks the map; this reads a few rows
    StatusOr<std::unique_ptr<LandmarkStore>> map =
        IsPostgresUrl(options.db) ? OpenPostgresStore(options.db, PostgresStoreOptions())
                                  : OpenSqliteStore(options.db, store);
    if (!map.ok()) {
      return Status(map.status().code(),
                    "--db: " + map.status().message() + " (give the map placerec-server serves)");
    }
    gateway->map_ = std::move(*map);
  }
  gateway->http_ =
      std::make_unique<httplib::SSLServer>(options.cert_file.c_str(), options.key_file.c_str());
  if (!gateway->http_->is_valid()) {
    return Status::InvalidArgument("cannot use the certificate " + options.cert_file +
                                   " with the key " + options.key_file +
                                   " (PEM files that belong together; scripts/make-cert.sh DIR "
                                   "makes a pair)");
  }
  gateway->guard_ = std::make_unique<ConnectionGuard>(options.connections);
  if (Status guarded = gateway->guard_->Install(gateway->http_->ssl_context()); !guarded.ok()) {
    return guarded;
  }
  return gateway;
}

StatusOr<Gateway::Clients> Gateway::ConnectClients(const TokenTable& tokens) const {
  Clients clients;
  for (const std::string& key_id : tokens.KeyIds()) {
    ClientOptions client_options = options_.client;
    if (!key_id.empty()) {
      if (options_.client.key_file.empty()) {
        return Status::InvalidArgument(options_.tokens_file + " names key '" + key_id +
                                       "' for a device: give --key-file with that key");
      }
      client_options.key_id = key_id;
    }
    StatusOr<std::unique_ptr<PlacerecClient>> client = PlacerecClient::Connect(client_options);
    if (!client.ok()) {
      return Status(
          client.status().code(),
          (key_id.empty() ? "the gateway's key" : "the key of a device, '" + key_id + "'") +
              std::string(": ") + client.status().message());
    }
    clients[key_id] = std::move(*client);
  }
  return clients;
}

std::shared_ptr<PlacerecClient> Gateway::ClientFor(const std::string& key_id) {
  std::lock_guard lock(tokens_mutex_);
  const auto found = clients_.find(key_id);
  return found != clients_.end() ? found->second : nullptr;
}

Status Gateway::ReloadTokens() {
  // Reading the files and connecting the clients happen outside tokens_mutex_, which every
  // request takes: requests go on with the tokens in force meanwhile.
  std::lock_guard reloading(reload_mutex_);
  StatusOr<TokenTable> tokens = LoadTokens(options_.tokens_file);
  if (!tokens.ok()) return tokens.status();
  // Every key's client anew: a secret changed in --key-file under the same id is read again.
  StatusOr<Clients> clients = ConnectClients(*tokens);
  if (!clients.ok()) return clients.status();
  WarnOfInsertKeys(options_, *tokens);
  // Hidden before any of them can ask: a device's answers never show in the overview.
  watcher_->HideRobots(tokens->Devices());
  auto table = std::make_shared<const TokenTable>(std::move(*tokens));
  std::shared_ptr<const TokenTable> before_table;
  {
    std::lock_guard lock(tokens_mutex_);
    before_table = std::move(tokens_);
    tokens_ = table;
    clients_.swap(*clients);  // the old clients go when their last query is answered
  }
  const std::set<std::string> before = before_table->Devices();
  const std::set<std::string> after = table->Devices();
  int added = 0;
  for (const std::string& device : after) added += before.count(device) == 0 ? 1 : 0;
  int removed = 0;
  for (const std::string& device : before) removed += after.count(device) == 0 ? 1 : 0;
  LOG(INFO) << "read " << options_.tokens_file << " again: " << table->size() << " tokens of "
            << after.size() << " devices (" << added << " added, " << removed << " removed)";
  return Status::Ok();
}

std::shared_ptr<const TokenTable> Gateway::Tokens() {
  if (token_reload_requested_.exchange(false)) {
    if (const Status reloaded = ReloadTokens(); !reloaded.ok()) {
      LOG(ERROR) << "SIGHUP: the tokens file was not read again, the tokens in force stay: "
                 << reloaded.ToString();
    }
  }
  std::lock_guard lock(tokens_mutex_);
  return tokens_;
}

Gateway::Gateway(const GatewayOptions& options, TokenTable tokens)
    : options_(options),
      tokens_(std::make_shared<const TokenTable>(std::move(tokens))),
      query_limiter_(options.requests_per_minute, options.burst),
      read_limiter_(options.requests_per_minute * kReadsPerQuery, options.burst * kReadsPerQuery) {}

Gateway::~Gateway() { Stop(); }

bool Gateway::Admit(const std::string& authorization, bool query, DeviceToken* device,
                    HttpReply* refusal) {
  const std::string token = BearerToken(authorization);
  if (token.empty()) {
    *refusal = ErrorReply(401, "send the device's token as 'Authorization: Bearer TOKEN'");
    return false;
  }
  StatusOr<DeviceToken> who = Tokens()->Authenticate(token, NowUnix());
  if (!who.ok()) {
    *refusal = ErrorReply(401, who.status().message());
    return false;
  }
  double retry_after_s = 0;
  RateLimiter& limiter = query ? query_limiter_ : read_limiter_;
  if (!limiter.Allow(token, RateLimiter::Clock::now(), &retry_after_s)) {
    const double per_minute = options_.requests_per_minute * (query ? 1 : kReadsPerQuery);
    *refusal = ErrorReply(429, "more than " + std::to_string(static_cast<int>(per_minute)) +
                                   (query ? " queries" : " reads") +
                                   " a minute from this device; try again in " +
                                   std::to_string(static_cast<int>(retry_after_s + 0.999)) + " s");
    refusal->retry_after_s = retry_after_s;
    return false;
  }
  *device = *who;
  return true;
}

HttpReply Gateway::Query(const std::string& authorization, const std::string& image) {
  DeviceToken device;
  HttpReply refusal;
  if (!Admit(authorization, /*query=*/true, &device, &refusal)) return refusal;
  if (static_cast<int64_t>(image.size()) > options_.max_upload_bytes) {
    return ErrorReply(413, "the photo has " + std::to_string(image.size()) +
                               " bytes; the limit is " + std::to_string(options_.max_upload_bytes) +
                               " (send a smaller JPEG)");
  }
  OutgoingFrame frame;
  if (!SniffEncoding(image, &frame.image.encoding)) {
    return ErrorReply(415,
                      "send a JPEG or PNG photo (as the request body, or the form field "
                      "'image')");
  }
  // A bounded number wait on the server (each holds an HTTPS thread up to --query-timeout).
  struct Waiting {
    std::atomic<int>* count;
    ~Waiting() { --*count; }
  } waiting{&waiting_queries_};
  if (++waiting_queries_ > options_.max_waiting_queries) {
    HttpReply busy = ErrorReply(
        503, std::to_string(options_.max_waiting_queries) +
                 " queries are waiting on the placerec server; try again in a few seconds");
    busy.retry_after_s = 5;
    return busy;
  }
  const int per_device = std::max(1, options_.max_waiting_queries / 2);
  struct DeviceWaiting {
    Gateway* gateway;
    std::string device;
    ~DeviceWaiting() {
      std::lock_guard lock(gateway->waiting_mutex_);
      if (--gateway->waiting_by_device_[device] <= 0) gateway->waiting_by_device_.erase(device);
    }
  };
  int device_waiting = 0;
  {
    std::lock_guard lock(waiting_mutex_);
    device_waiting = ++waiting_by_device_[device.device];
  }
  const DeviceWaiting device_slot{this, device.device};
  if (device_waiting > per_device) {
    HttpReply busy = ErrorReply(503, std::to_string(per_device) +
                                         " queries of this device are waiting on the placerec "
                                         "server; wait for their answers");
    busy.retry_after_s = 5;
    return busy;
  }
  frame.image.bytes.assign(image.begin(), image.end());
  frame.robot = device.device;
  frame.sequence = next_sequence_++;
  frame.utime = NowMicros();
  frame.insert = false;  // the gateway never changes the map
  const std::shared_ptr<PlacerecClient> client = ClientFor(device.key_id);
  if (client == nullptr) {
    return ErrorReply(401,
                      "the gateway's tokens were just read again and no longer name this "
                      "device's key; ask the gateway's operator");
  }
  StatusOr<PendingFrame> pending = client->Publish(frame);
  if (!pending.ok())
    return ErrorReply(502, "cannot reach the server: " + pending.status().message());
  const FrameResult result = client->Wait(*pending, options_.query_timeout_s);
  if (!result.ok()) {
    // An answer the client ignored (not signed with the key the query was signed with, e.g. the
    // server does not know that key) says why the device got none.
    const size_t ignored = result.message.find("an answer not signed");
    std::string why;
    if (result.code == AnswerCode::kTimeout && ignored != std::string::npos) {
      why =
          "the placerec server answered, but not with the gateway's key: its operator must "
          "give placerec-gateway --key-file with a query key of the server's --keys file (" +
          result.message.substr(ignored) + ")";
    } else if (result.code == AnswerCode::kTimeout) {
      why = "no answer from the placerec server within " +
            std::to_string(static_cast<int>(options_.query_timeout_s)) +
            " s; is it running on the gateway's LCM network?";
    } else if (result.code == AnswerCode::kUnauthorised) {
      why = "unauthorised: the placerec server refused the query of device '" + device.device +
            "' (its operator must give placerec-gateway --key-file with a query key that the "
            "server's --keys file has): " +
            result.message;
    } else {
      why = std::string(AnswerCodeName(result.code)) + ": " + result.message;
    }
    return ErrorReply(HttpStatusOf(result.code), why);
  }
  nlohmann::json body = AnswerJson(result);
  body["device"] = device.device;
  HttpReply reply;
  reply.body = JsonText(body);
  return reply;
}

HttpReply Gateway::ServerStatus(const std::string& authorization) {
  DeviceToken device;
  HttpReply refusal;
  if (!Admit(authorization, /*query=*/false, &device, &refusal)) return refusal;
  const nlohmann::json status = watcher_->LastStatus();
  if (status.is_null()) {
    return ErrorReply(503,
                      "no heartbeat from a placerec server yet; is it running on the "
                      "gateway's LCM network?");
  }
  HttpReply reply;
  reply.body = JsonText(status);
  return reply;
}

HttpReply Gateway::Site(const std::string& authorization) {
  DeviceToken device;
  HttpReply refusal;
  if (!Admit(authorization, /*query=*/false, &device, &refusal)) return refusal;
  HttpReply reply;
  reply.body = JsonText(watcher_->Overview());
  return reply;
}

HttpReply Gateway::Thumbnail(const std::string& authorization, const std::string& place_id) {
  DeviceToken device;
  HttpReply refusal;
  if (!Admit(authorization, /*query=*/false, &device, &refusal)) return refusal;
  if (map_ == nullptr) {
    return ErrorReply(404, "no place pictures here: the gateway was started without --db MAP");
  }
  int64_t id = 0;
  if (!ParseInt64(place_id, &id)) return ErrorReply(404, "no place " + place_id);
  StatusOr<std::vector<uint8_t>> jpeg = map_->LoadThumbnail(PlaceId(id));
  if (!jpeg.ok()) return ErrorReply(502, "cannot read the map: " + jpeg.status().message());
  if (jpeg->empty()) {
    return ErrorReply(404, "no picture of place " + place_id +
                               ": it is not in the map, or was stored before maps kept pictures");
  }
  HttpReply reply;
  reply.content_type = "image/jpeg";
  reply.body.assign(jpeg->begin(), jpeg->end());
  return reply;
}

HttpReply Gateway::AlarmPicture(const std::string& authorization, const std::string& alarm_id,
                                const std::string& which) {
  DeviceToken device;
  HttpReply refusal;
  if (!Admit(authorization, /*query=*/false, &device, &refusal)) return refusal;
  int64_t id = 0;
  std::vector<uint8_t> jpeg;
  if (!ParseInt64(alarm_id, &id) || !watcher_->AlarmPicture(id, which == "place", &jpeg)) {
    return ErrorReply(404, "no alarm " + alarm_id + " among the recent ones");
  }
  if (jpeg.empty()) return ErrorReply(404, "alarm " + alarm_id + " has no " + which + " picture");
  HttpReply reply;
  reply.content_type = "image/jpeg";
  reply.body.assign(jpeg.begin(), jpeg.end());
  return reply;
}

Status Gateway::Serve() {
  httplib::SSLServer& http = *http_;
  http.new_task_queue = [] { return new httplib::ThreadPool(kHttpThreads); };
  // One request per connection: a request refused before its body is read (411 below) leaves
  // that body on the connection, where the library would read it as further requests; the
  // library decides to keep a connection from the request alone. A new TLS handshake per request
  // is the price (milliseconds; the page polls every 5 s).
  http.set_keep_alive_max_count(1);
  http.set_payload_max_length(static_cast<size_t>(options_.max_upload_bytes));
  auto send = [](const HttpReply& reply, httplib::Response& res) {
    res.status = reply.status;
    res.set_header("Cache-Control", "no-store");
    if (reply.retry_after_s > 0) {
      res.set_header("Retry-After", std::to_string(static_cast<int>(reply.retry_after_s + 0.999)));
    }
    res.set_content(reply.body, reply.content_type.c_str());
  };
  http.Post("/v1/query", [&](const httplib::Request& req, httplib::Response& res) {
    const std::string& image = req.is_multipart_form_data() && req.has_file("image")
                                   ? req.get_file_value("image").content
                                   : req.body;
    send(Query(req.get_header_value("Authorization"), image), res);
  });
  http.Get("/v1/status", [&](const httplib::Request& req, httplib::Response& res) {
    send(ServerStatus(req.get_header_value("Authorization")), res);
  });
  http.Get("/v1/site", [&](const httplib::Request& req, httplib::Response& res) {
    send(Site(req.get_header_value("Authorization")), res);
  });
  http.Get(R"(/v1/alarms/(\d+)/(frame|place)\.jpg)", [&](const httplib::Request& req,
                                                         httplib::Response& res) {
    send(AlarmPicture(req.get_header_value("Authorization"), req.matches[1], req.matches[2]), res);
  });
  http.Get(R"(/v1/places/(\d+)/thumbnail)",
           [&](const httplib::Request& req, httplib::Response& res) {
             send(Thumbnail(req.get_header_value("Authorization"), req.matches[1]), res);
           });
  const std::string web_dir = options_.web_dir.empty() ? PLACEREC_WEB_DIR : options_.web_dir;
  if (!http.set_mount_point("/", web_dir)) {
    return Status::NotFound("the web page's folder " + web_dir + " does not exist (--web-dir)");
  }
  // A body must say its length, so that --max-upload-bytes holds before anything is read: the
  // library reads a chunked body whole, whatever its size, before any handler runs. So any
  // Transfer-Encoding (whatever its case, also beside a Content-Length) is refused unread.
  // A body without a valid token is read only when small (kMaxAnonymousBodyBytes, so that the
  // handler's 401 reaches the client: a server closing on an unread body may reset the
  // connection before the client reads the answer), within kAnswerSeconds; a larger one is
  // refused unread (401). A device's body over --max-upload-bytes is refused at once when it
  // claims more than kMaxDiscardedUploadFactor times the limit (413); up to that it is read and
  // dropped before the library's 413. Only a device's body gets the time its length needs
  // (ConnectionGuard): anybody else's claimed length bought a slow sender minutes.
  // This handler runs before any body is read.
  http.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    // The headers are in: the connection has kAnswerSeconds to finish, unless a device's body
    // needs more (below).
    ConnectionGuard::ExtendCurrent(kAnswerSeconds);
    const auto refuse = [&res](int status, const std::string& why) {
      res.status = status;
      res.set_content(JsonText({{"error", why}}), "application/json");
      return httplib::Server::HandlerResponse::Handled;
    };
    // The library reads a body for PUT, PATCH, DELETE ... too (one without a length unbounded):
    // no endpoint takes them, so they are refused unread.
    if (req.method != "GET" && req.method != "HEAD" && req.method != "POST") {
      return refuse(405, "method " + req.method +
                             " not allowed: GET the page and the overview, POST /v1/query a photo");
    }
    const bool encoded = req.has_header("Transfer-Encoding");
    if (!encoded && req.method != "POST") return httplib::Server::HandlerResponse::Unhandled;
    if (encoded || !req.has_header("Content-Length")) {
      return refuse(411,
                    "send the photo with a Content-Length header (a chunked body, or one without "
                    "a length, is not read)");
    }
    int64_t length = 0;
    if (!ParseInt64(req.get_header_value("Content-Length"), &length) || length < 0) {
      return refuse(400, "the Content-Length header is no number of bytes");
    }
    const std::string token = BearerToken(req.get_header_value("Authorization"));
    const StatusOr<DeviceToken> who =
        token.empty() ? StatusOr<DeviceToken>(Status::InvalidArgument(
                            "send the device's token as 'Authorization: Bearer TOKEN'"))
                      : Tokens()->Authenticate(token, NowUnix());
    if (!who.ok()) {
      if (length > kMaxAnonymousBodyBytes) return refuse(401, who.status().message());
      return httplib::Server::HandlerResponse::Unhandled;  // the handler answers 401
    }
    if (length / kMaxDiscardedUploadFactor > options_.max_upload_bytes) {
      return refuse(413, "the photo has " + std::to_string(length) + " bytes; the limit is " +
                             std::to_string(options_.max_upload_bytes) + " (send a smaller JPEG)");
    }
    ConnectionGuard::ExtendCurrent(kAnswerSeconds +
                                   static_cast<double>(length) / kMinUploadBytesPerSecond +
                                   options_.query_timeout_s);
    return httplib::Server::HandlerResponse::Unhandled;
  });
  // Every error, including the library's own (404, 405, 413 ...), is a JSON body. The library
  // calls this outside its exception guard: nothing here may throw.
  http.set_error_handler([](const httplib::Request& req, httplib::Response& res) {
    if (!res.body.empty()) return;
    try {
      std::string message = "HTTP " + std::to_string(res.status);
      if (res.status == 404) message = "no such page or endpoint: " + req.path;
      if (res.status == 413) message = "the request is larger than the gateway accepts";
      if (res.status == 405) message = "method not allowed on " + req.path;
      if (res.status == 400) {
        message =
            "malformed request (its request line or headers, a broken multipart upload, or a body "
            "that ended early): send the photo as the request body, or as the form field 'image'";
      }
      if (res.status == 414) message = "the request's URL is too long";
      res.set_content(JsonText({{"error", message}}), "application/json");
    } catch (const std::exception&) {
      res.set_content(R"({"error":"the request cannot be answered"})", "application/json");
    }
  });
  http.set_default_headers({{"X-Content-Type-Options", "nosniff"}});
  const int port =
      options_.port == 0
          ? http.bind_to_any_port(options_.host.c_str())
          : (http.bind_to_port(options_.host.c_str(), options_.port) ? options_.port : -1);
  if (port < 0) {
    return Status::IoError("cannot listen on " + options_.host + ":" +
                           std::to_string(options_.port) + " (in use, or not allowed)");
  }
  bound_port_ = port;
  LOG(INFO) << "placerec-gateway: https://" << options_.host << ":" << port << "/";
  if (!http.listen_after_bind()) return Status::IoError("the HTTPS server stopped with an error");
  return Status::Ok();
}

void Gateway::Stop() {
  if (http_) http_->stop();
}

}  // namespace placerec
