// How long one HTTPS connection may hold one of the gateway's threads, and how many one address
// may hold at once. The HTTP library serves each connection on a thread of a fixed pool and bounds
// only each single read (5 s), so a client that sends its TLS handshake or its headers a byte at
// a time, on as many connections as there are threads, stops the gateway for everybody (a
// "slowloris"). The guard cuts (shuts down) a connection that has not sent its headers within
// ConnectionGuardOptions::header_seconds of its handshake's start, or that outlives the time its
// request was given after them (ExtendCurrent); cuts at once a connection of an address that
// already holds max_per_address; and cuts the oldest connection still in its handshake or headers
// when more than max_pending are. It works through the OpenSSL context, the only per-connection
// hook the library offers: a connection is registered when its TLS handshake starts (in the thread
// that serves it) and forgotten when its SSL object is freed.
#pragma once

#include <openssl/ssl.h>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <thread>

#include "common/util/status.h"

namespace placerec {

struct ConnectionGuardOptions {
  // Seconds a connection has for its TLS handshake and its request line and headers (Apache's
  // mod_reqtimeout gives 20 to 40 s for the headers).
  double header_seconds = 20;
  // Connections one address may hold at once; more are cut at once; 0: no limit (behind a
  // reverse proxy, whose address every connection has). A browser opens up to six to one host,
  // and several phones may share one address behind a carrier's NAT. An IPv6 address counts by
  // its /64 prefix, which one host or one home network has whole.
  int max_per_address = 16;
  // Connections still in their handshake or headers at once; a new one beyond cuts the oldest
  // of them (0: no limit). Quick clients pass this phase in milliseconds, so those that linger
  // in it, from however many addresses, cannot hold every thread.
  int max_pending = 32;

  bool Check(std::string* error) const;
};

class ConnectionGuard {
 public:
  using Clock = std::chrono::steady_clock;

  explicit ConnectionGuard(const ConnectionGuardOptions& options);
  ~ConnectionGuard();  // stops the watchdog; install no guard on a context that outlives it

  // Registers every TLS connection of `ctx` from its handshake on (an info callback and an ex
  // data slot of the SSL objects; the context's own callbacks must not be set elsewhere).
  Status Install(SSL_CTX* ctx);

  // Gives the connection served by the calling thread `seconds` from now to finish (called once
  // its headers are read, with the time its body and answer may take). No-op on a thread that
  // serves no registered connection.
  static void ExtendCurrent(double seconds);

  // Connections registered now, and cut so far (for tests and the log).
  size_t open_connections() const;
  int64_t cut_connections() const;

 private:
  struct Connection {
    int fd = -1;  // our own duplicate of the socket: its number stays ours until Forget
    std::string address;
    Clock::time_point deadline;
    bool headers_done = false;  // Extend was called: past the handshake and headers
    bool cut = false;
  };
  // The ex data slots (one per process): the guard of a context, the ticket of an SSL object
  // (freed with it, which forgets the connection).
  static int ContextIndex();
  static int SslIndex();
  static void OnInfo(const SSL* ssl, int where, int ret);
  static void OnFree(void* parent, void* ptr, CRYPTO_EX_DATA* data, int index, long argl,
                     void* argp);
  void Register(SSL* ssl);
  void Forget(uint64_t id);
  void Extend(uint64_t id, double seconds);
  // Shuts down a connection's socket (mutex_ held): its thread's next read or write fails.
  void Cut(Connection* connection);
  void Watch();

  const ConnectionGuardOptions options_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  uint64_t next_id_ = 1;
  std::map<uint64_t, Connection> connections_;
  int64_t cut_ = 0;
  int64_t cut_logged_ = 0;
  Clock::time_point logged_at_;
  std::thread watchdog_;
};

}  // namespace placerec
