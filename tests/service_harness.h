// What the server + client integration tests share: a private network namespace per test (so that
// no LCM traffic leaves the test and parallel tests cannot hear each other), child processes that
// die with the test, and starting placerec-server and waiting for its heartbeat.
#pragma once

#include <sys/types.h>

#include <memory>
#include <string>
#include <vector>

#include "client/client.h"
#include "common/util/status.h"

namespace placerec {
namespace testing_service {

// Moves this process (and the children it starts later) into a new network namespace with only
// the loopback device, up, with multicast and a route for 224.0.0.0/4 (DESIGN.md "LCM protocol").
// Fails, saying why, when not root or when unshare is not allowed; callers skip the test then.
Status EnterPrivateNetwork();

// The LCM URL every process of a test uses: LCM's default group, TTL 0, and a receive buffer big
// enough for raw frames (up to net.core.rmem_max).
std::string TestLcmUrl();

// The LCM URL of a TCP hub on this machine's loopback (tcpq, for remote devices).
std::string HubLcmUrl(int port);

// Writes a keys file (mode 600, proto/auth/signing.h format) with a new random key for each
// (id, permission), permission being insert, query or both; returns `path`.
std::string WriteTestKeys(const std::string& path,
                          const std::vector<std::pair<std::string, std::string>>& keys);

// PLACEREC_BINARY_DIR/bin/<name>.
std::string BinaryPath(const std::string& name);

// A fresh directory under the test temp dir.
std::string MakeTempDir(const std::string& prefix);
// Removes a MakeTempDir directory and everything in it, unless the current test has failed:
// then it stays for inspection and its path is printed. Empty `dir`: nothing to do.
void RemoveTempDir(const std::string& dir);

std::string ReadTextFile(const std::string& path);
// The last `lines` lines of a log, for failure messages.
std::string Tail(const std::string& path, int lines = 30);

// A child process whose stdout and stderr go to a file. It gets SIGKILL when the test process
// (the thread that started it) dies, and when this object is destroyed while it still runs.
class ChildProcess {
 public:
  static StatusOr<std::unique_ptr<ChildProcess>> Start(const std::vector<std::string>& argv,
                                                       const std::string& log_path);
  ~ChildProcess();

  pid_t pid() const { return pid_; }
  const std::string& log_path() const { return log_path_; }
  bool running();
  void Signal(int signal);
  // Waits up to `timeout_s` for the process to end; its exit code, or 128 + the signal that
  // killed it. DeadlineExceeded-like error (Internal) on timeout.
  StatusOr<int> Wait(double timeout_s);

 private:
  ChildProcess(pid_t pid, std::string log_path) : pid_(pid), log_path_(std::move(log_path)) {}
  pid_t pid_;
  std::string log_path_;
  bool reaped_ = false;
  int status_ = 0;
};

// Starts placerec-server on `db` with the test URL plus `extra_args`, logging to `log_path`, and
// waits (through `client`) for its first heartbeat.
StatusOr<std::unique_ptr<ChildProcess>> StartServer(const std::string& db,
                                                    const std::vector<std::string>& extra_args,
                                                    const std::string& log_path,
                                                    PlacerecClient* client, double timeout_s = 60);

// Starts LCM's TCP hub (scripts/lcm-hub.sh run PORT) logging to `log_path` and waits until it
// accepts connections on 127.0.0.1:PORT.
StatusOr<std::unique_ptr<ChildProcess>> StartLcmHub(int port, const std::string& log_path,
                                                    double timeout_s = 30);

// Sends SIGTERM and waits for a clean exit; the exit code.
StatusOr<int> StopServer(ChildProcess* server, double timeout_s = 60);

}  // namespace testing_service
}  // namespace placerec
