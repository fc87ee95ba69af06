// placerec-gateway: HTTPS in front of placerec-server for field devices (gateway/gateway.h).
// Exit codes: 0 after a clean stop (SIGINT, SIGTERM), 1 when it cannot start, 2 for bad flags.
#include <atomic>
#include <csignal>
#include <cstdio>
#include <optional>
#include <string>

#include "common/util/logging.h"
#include "common/util/options.h"
#include "gateway/gateway.h"

namespace placerec {
namespace {

// Set once the gateway serves; read by the signal handlers (a lock-free atomic is safe there).
std::atomic<Gateway*> g_gateway{nullptr};

void OnStopSignal(int) {
  if (Gateway* gateway = g_gateway.load(); gateway != nullptr) gateway->Stop();
}

void OnReloadSignal(int) {
  if (Gateway* gateway = g_gateway.load(); gateway != nullptr) gateway->RequestTokenReload();
}

constexpr char kUsage[] =
    "placerec-gateway --cert CERT.pem --key KEY.pem --tokens FILE --key-file KEYS [options]\n\n"
    "\"Where am I?\" over HTTPS for devices without LCM, and a web page for people in the field\n"
    "(https://HOST:PORT/). Endpoints, each with 'Authorization: Bearer TOKEN':\n"
    "  POST /v1/query                   a JPEG or PNG photo (the body, or the form field 'image')\n"
    "                                   -> the server's answer as JSON; queries only, the map\n"
    "                                   never changes\n"
    "  GET  /v1/status                  the server's last heartbeat\n"
    "  GET  /v1/site                    robots heard, recent loop closures and change alarms\n"
    "  GET  /v1/places/ID/thumbnail     the stored picture of a place (needs --db)\n"
    "  GET  /v1/alarms/ID/frame.jpg     a recent scene-change alarm's frame (and place.jpg)\n"
    "Errors are JSON {\"error\": \"...\"} with the HTTP status. The tokens file has one device "
    "per\n"
    "line: TOKEN DEVICE [key=KEY_ID] [expires=YYYY-MM-DDTHH:MM:SSZ]. DEVICE names the device's\n"
    "frames like a robot id; KEY_ID, a query key of --key-file, signs its queries (default: the\n"
    "gateway's --key-id), so the server's keys file can revoke that device alone. SIGHUP reads\n"
    "the tokens file and --key-file again at the next request (devices added, removed or\n"
    "changed, secrets changed; files that cannot be used change nothing, the log says why).\n"
    "scripts/make-cert.sh DIR makes a self-signed certificate for tests and demos.";

int Main(int argc, char** argv) {
  // A SIGHUP while the gateway starts (one meant for the server's keys, say) must not stop it;
  // its handler is installed once the gateway serves.
  signal(SIGHUP, SIG_IGN);
  GatewayOptions options;
  FlagParser parser(kUsage);
  parser.Add("cert", &options.cert_file, "PEM certificate of the HTTPS server");
  parser.Add("key", &options.key_file, "PEM private key of the certificate");
  parser.Add("tokens", &options.tokens_file, "device tokens file (see above)");
  parser.Add("host", &options.host, "address to listen on");
  parser.Add("port", &options.port, "port to listen on (0: any free port, printed at start)");
  parser.Add("web-dir", &options.web_dir,
             "folder of the web page (empty: the page shipped in gateway/web)");
  parser.Add("max-upload-bytes", &options.max_upload_bytes, "larger requests are refused with 413");
  parser.Add("requests-per-minute", &options.requests_per_minute,
             "queries a minute per token on average; more get 429 with Retry-After (reads: status, "
             "site, pictures, have ten times this rate and burst)");
  parser.Add("burst", &options.burst, "queries a token may send at once before the rate applies");
  parser.Add("max-waiting-queries", &options.max_waiting_queries,
             "queries waiting on the server at once, from all devices; more get 503 with "
             "Retry-After (the page and the overview stay served)");
  parser.Add("query-timeout", &options.query_timeout_s,
             "seconds to wait for the server's answer (then 504)");
  parser.Add("lcm-url", &options.client.lcm_url,
             "LCM URL of the placerec server's network (empty: LCM's default)");
  parser.Add("key-file", &options.client.key_file,
             "keys file holding the gateway's key: its queries are signed with it (a key with "
             "permission 'query' only; scripts/make-key.sh gateway query)");
  parser.Add("key-id", &options.client.key_id, "which key of --key-file (empty: its first)");
  parser.Add("db", &options.db,
             "the server's map (file or postgresql:// URL), read for place pictures (GET "
             "/v1/places/ID/thumbnail); empty: none shown");
  parser.Add("header-timeout", &options.connections.header_seconds,
             "seconds a connection has for its TLS handshake and headers; slower ones are cut, so "
             "that clients sending a byte at a time cannot hold the gateway's threads");
  parser.Add("max-connections-per-address", &options.connections.max_per_address,
             "connections one address may hold at once, more are cut (0: no limit; use 0 behind a "
             "reverse proxy, through which every connection comes from one address, and limit "
             "there)");
  parser.Add("retry-after", &options.client.retry_after_s,
             "seconds after which an unanswered query is sent again (same request id)");
  if (const std::optional<int> exit = parser.ParseOrExit(argc, argv, 1, "placerec-gateway")) {
    return *exit;
  }
  std::string error;
  if (!options.Check(&error)) {
    std::fprintf(stderr, "placerec-gateway: %s\n", error.c_str());
    return 2;
  }
  StatusOr<std::unique_ptr<Gateway>> gateway = Gateway::Create(options);
  if (!gateway.ok()) {
    std::fprintf(stderr, "placerec-gateway: %s\n", gateway.status().ToString().c_str());
    return 1;
  }
  g_gateway = gateway->get();
  struct sigaction action = {};
  action.sa_handler = OnStopSignal;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  struct sigaction reload = {};
  reload.sa_handler = OnReloadSignal;
  sigemptyset(&reload.sa_mask);
  sigaction(SIGHUP, &reload, nullptr);
  const Status served = (*gateway)->Serve();
  g_gateway = nullptr;
  if (!served.ok()) {
    std::fprintf(stderr, "placerec-gateway: %s\n", served.ToString().c_str());
    return 1;
  }
  return 0;
}

}  // namespace
}  // namespace placerec

int main(int argc, char** argv) {
  placerec::InitLogging(argv[0]);
  return placerec::Main(argc, argv);
}
