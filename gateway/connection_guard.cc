#include "gateway/connection_guard.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <utility>

#include "common/util/logging.h"

namespace placerec {
namespace {

// What an SSL object carries: its guard and its connection's id there.
struct Ticket {
  ConnectionGuard* guard = nullptr;
  uint64_t id = 0;
};

// The connection the calling thread serves (a copy: its SSL object may be freed elsewhere).
thread_local Ticket t_current;

// Seconds between the watchdog's looks, and between two log lines about cut connections.
constexpr auto kWatchInterval = std::chrono::milliseconds(250);
constexpr auto kLogInterval = std::chrono::seconds(60);

// The peer's address as text ("" when the socket has none); an IPv6 peer's /64 prefix (an IPv4
// peer seen through IPv6, ::ffff:a.b.c.d, stays whole).
std::string PeerAddress(int fd) {
  sockaddr_storage peer = {};
  socklen_t length = sizeof(peer);
  if (getpeername(fd, reinterpret_cast<sockaddr*>(&peer), &length) != 0) return "";
  char text[INET6_ADDRSTRLEN] = {};
  const void* address = nullptr;
  if (peer.ss_family == AF_INET) {
    address = &reinterpret_cast<const sockaddr_in*>(&peer)->sin_addr;
  } else if (peer.ss_family == AF_INET6) {
    auto* in6 = &reinterpret_cast<sockaddr_in6*>(&peer)->sin6_addr;
    if (!IN6_IS_ADDR_V4MAPPED(in6)) std::fill(in6->s6_addr + 8, in6->s6_addr + 16, 0);
    address = in6;
  } else {
    return "";
  }
  return inet_ntop(peer.ss_family, address, text, sizeof(text)) != nullptr ? text : "";
}

}  // namespace

bool ConnectionGuardOptions::Check(std::string* error) const {
  if (!(header_seconds > 0)) {
    *error = "header_seconds must be positive";
    return false;
  }
  if (max_per_address < 0 || max_pending < 0) {
    *error = "max_per_address and max_pending must be 0 (no limit) or more";
    return false;
  }
  return true;
}

int ConnectionGuard::ContextIndex() {
  static const int index = SSL_CTX_get_ex_new_index(0, nullptr, nullptr, nullptr, nullptr);
  return index;
}

int ConnectionGuard::SslIndex() {
  static const int index =
      SSL_get_ex_new_index(0, nullptr, nullptr, nullptr, &ConnectionGuard::OnFree);
  return index;
}

ConnectionGuard::ConnectionGuard(const ConnectionGuardOptions& options)
    : options_(options), watchdog_([this] { Watch(); }) {}

ConnectionGuard::~ConnectionGuard() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  watchdog_.join();
  for (auto& [id, connection] : connections_) close(connection.fd);
}

Status ConnectionGuard::Install(SSL_CTX* ctx) {
  if (ctx == nullptr) return Status::InvalidArgument("no TLS context to guard");
  if (ContextIndex() < 0 || SslIndex() < 0 || SSL_CTX_set_ex_data(ctx, ContextIndex(), this) != 1) {
    return Status::Internal("OpenSSL gave no ex data slot for the connection guard");
  }
  SSL_CTX_set_info_callback(ctx, &ConnectionGuard::OnInfo);
  return Status::Ok();
}

void ConnectionGuard::OnInfo(const SSL* ssl, int where, int /*ret*/) {
  // A server's handshake starts before its first read (and again at a TLS 1.2 renegotiation,
  // where the connection is registered already).
  if ((where & SSL_CB_HANDSHAKE_START) == 0) return;
  SSL* mutable_ssl = const_cast<SSL*>(ssl);
  if (SSL_get_ex_data(mutable_ssl, SslIndex()) != nullptr) return;
  auto* guard =
      static_cast<ConnectionGuard*>(SSL_CTX_get_ex_data(SSL_get_SSL_CTX(ssl), ContextIndex()));
  if (guard != nullptr) guard->Register(mutable_ssl);
}

void ConnectionGuard::OnFree(void* /*parent*/, void* ptr, CRYPTO_EX_DATA* /*data*/, int /*index*/,
                             long /*argl*/, void* /*argp*/) {
  auto* ticket = static_cast<Ticket*>(ptr);
  if (ticket == nullptr) return;
  ticket->guard->Forget(ticket->id);
  if (t_current.guard == ticket->guard && t_current.id == ticket->id) t_current = Ticket();
  delete ticket;
}

void ConnectionGuard::Register(SSL* ssl) {
  const int fd = SSL_get_fd(ssl);
  if (fd < 0) return;
  Connection connection;
  connection.fd = fcntl(fd, F_DUPFD_CLOEXEC, 0);
  if (connection.fd < 0) {
    // Out of descriptors: the connection cannot be watched, so it is not served either.
    shutdown(fd, SHUT_RDWR);
    return;
  }
  connection.address = PeerAddress(fd);
  connection.deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                           std::chrono::duration<double>(options_.header_seconds));
  auto* ticket = new Ticket{this, 0};
  std::lock_guard<std::mutex> lock(mutex_);
  ticket->id = next_id_++;
  int held = 0;
  int pending = 0;
  for (const auto& [id, other] : connections_) {
    if (other.cut) continue;
    if (other.address == connection.address) ++held;
    if (!other.headers_done) ++pending;
  }
  Connection& added = connections_[ticket->id] = std::move(connection);
  if (options_.max_per_address > 0 && held >= options_.max_per_address) {
    Cut(&added);
  } else if (options_.max_pending > 0 && pending >= options_.max_pending) {
    // The oldest connection still in its handshake or headers makes room (ids grow with time).
    for (auto& [id, other] : connections_) {
      if (!other.cut && !other.headers_done) {
        Cut(&other);
        break;
      }
    }
  }
  if (SSL_set_ex_data(ssl, SslIndex(), ticket) != 1) {
    // Without its ticket the connection would never be forgotten: refuse it instead.
    Cut(&added);
    close(added.fd);
    connections_.erase(ticket->id);
    delete ticket;
    return;
  }
  t_current = *ticket;
}

void ConnectionGuard::Forget(uint64_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = connections_.find(id);
  if (it == connections_.end()) return;
  close(it->second.fd);
  connections_.erase(it);
}

void ConnectionGuard::ExtendCurrent(double seconds) {
  const Ticket current = t_current;
  if (current.guard != nullptr) current.guard->Extend(current.id, seconds);
}

void ConnectionGuard::Extend(uint64_t id, double seconds) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = connections_.find(id);
  if (it == connections_.end() || it->second.cut) return;
  it->second.headers_done = true;
  it->second.deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                           std::chrono::duration<double>(seconds));
}

size_t ConnectionGuard::open_connections() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return connections_.size();
}

int64_t ConnectionGuard::cut_connections() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return cut_;
}

void ConnectionGuard::Cut(Connection* connection) {
  shutdown(connection->fd, SHUT_RDWR);
  connection->cut = true;
  ++cut_;
}

void ConnectionGuard::Watch() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (!wake_.wait_for(lock, kWatchInterval, [this] { return stopping_; })) {
    const Clock::time_point now = Clock::now();
    for (auto& [id, connection] : connections_) {
      if (!connection.cut && connection.deadline < now) Cut(&connection);
    }
    if (cut_ > cut_logged_ && (cut_logged_ == 0 || now - logged_at_ >= kLogInterval)) {
      LOG(WARNING) << "placerec-gateway: cut " << cut_ - cut_logged_
                   << " connection(s) that sent their request too slowly (over "
                   << options_.header_seconds << " s for the handshake and headers), came from "
                   << "an address that held " << options_.max_per_address
                   << " connections already (behind a reverse proxy, every connection comes from "
                   << "its address: --max-connections-per-address 0, and limit there), or were "
                   << "the oldest of " << options_.max_pending << " still in their headers";
      cut_logged_ = cut_;
      logged_at_ = now;
    }
  }
}

}  // namespace placerec
