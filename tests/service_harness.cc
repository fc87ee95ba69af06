#include "tests/service_harness.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sched.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>

namespace placerec {
namespace testing_service {
namespace {

// Receive buffer asked for in the LCM URL; the kernel caps it at net.core.rmem_max.
constexpr int kReceiveBuffer = 4 << 20;

int ReadProcInt(const char* path) {
  std::ifstream in(path);
  int value = 0;
  in >> value;
  return value;
}

}  // namespace

Status EnterPrivateNetwork() {
  if (geteuid() != 0) {
    return Status::NotFound(
        "needs root for a private network namespace (unshare -n); CI runs "
        "as root");
  }
  if (unshare(CLONE_NEWNET) != 0) {
    return Status::NotFound(std::string("unshare(CLONE_NEWNET) failed: ") + std::strerror(errno));
  }
  // The loopback device is down in a new namespace; multicast needs it up, flagged, and routed.
  const std::string setup =
      "PATH=\"$PATH:/usr/sbin:/sbin\"; ip link set lo up && ip link set lo multicast on && "
      "ip route add 224.0.0.0/4 dev lo";
  const int rc = std::system(setup.c_str());
  if (rc != 0) {
    return Status::NotFound("could not set up loopback multicast in the namespace (" + setup +
                            " returned " + std::to_string(rc) + "; is iproute2 installed?)");
  }
  // Large messages need a large receive buffer; raise the cap where the kernel lets us.
  if (ReadProcInt("/proc/sys/net/core/rmem_max") < kReceiveBuffer) {
    std::ofstream("/proc/sys/net/core/rmem_max") << kReceiveBuffer;
  }
  return Status::Ok();
}

std::string TestLcmUrl() {
  return "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=" + std::to_string(kReceiveBuffer);
}

std::string HubLcmUrl(int port) { return "tcpq://127.0.0.1:" + std::to_string(port); }

std::string WriteTestKeys(const std::string& path,
                          const std::vector<std::pair<std::string, std::string>>& keys) {
  std::random_device device;
  std::ofstream out(path, std::ios::trunc);
  out << "# placerec keys: id permission key\n";
  for (const auto& [id, permission] : keys) {
    std::string hex;
    for (int i = 0; i < 64; ++i) hex += "0123456789abcdef"[device() % 16];
    out << id << " " << permission << " " << hex << "\n";
  }
  out.close();
  chmod(path.c_str(), 0600);
  return path;
}

std::string BinaryPath(const std::string& name) {
  return std::string(PLACEREC_BINARY_DIR) + "/bin/" + name;
}

std::string MakeTempDir(const std::string& prefix) {
  std::string pattern = ::testing::TempDir() + "/" + prefix + "XXXXXX";
  std::vector<char> buffer(pattern.begin(), pattern.end());
  buffer.push_back('\0');
  const char* made = mkdtemp(buffer.data());
  return made != nullptr ? std::string(made) : std::string();
}

void RemoveTempDir(const std::string& dir) {
  if (dir.empty()) return;
  if (::testing::Test::HasFailure()) {
    std::fprintf(stderr, "kept %s for inspection\n", dir.c_str());
    return;
  }
  std::error_code error;
  std::filesystem::remove_all(dir, error);
  if (error) std::fprintf(stderr, "cannot remove %s: %s\n", dir.c_str(), error.message().c_str());
}

std::string ReadTextFile(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream out;
  out << in.rdbuf();
  return out.str();
}

std::string Tail(const std::string& path, int lines) {
  std::ifstream in(path);
  std::deque<std::string> last;
  std::string line;
  while (std::getline(in, line)) {
    last.push_back(line);
    if (static_cast<int>(last.size()) > lines) last.pop_front();
  }
  std::string out = "--- last lines of " + path + " ---\n";
  for (const std::string& l : last) out += l + "\n";
  return out;
}

StatusOr<std::unique_ptr<ChildProcess>> ChildProcess::Start(const std::vector<std::string>& argv,
                                                            const std::string& log_path) {
  if (argv.empty()) return Status::InvalidArgument("no command");
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const int log = open(log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (log < 0) return Status::IoError("cannot open " + log_path);
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) {
    close(log);
    return Status::Internal(std::string("fork failed: ") + std::strerror(errno));
  }
  if (pid == 0) {
    // Only async-signal-safe calls between fork and exec.
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(127);
    dup2(log, STDOUT_FILENO);
    dup2(log, STDERR_FILENO);
    execv(args[0], args.data());
    _exit(127);
  }
  close(log);
  return std::unique_ptr<ChildProcess>(new ChildProcess(pid, log_path));
}

ChildProcess::~ChildProcess() {
  if (!reaped_) {
    kill(pid_, SIGKILL);
    waitpid(pid_, &status_, 0);
  }
}

bool ChildProcess::running() {
  if (reaped_) return false;
  const pid_t done = waitpid(pid_, &status_, WNOHANG);
  if (done == pid_) reaped_ = true;
  return !reaped_;
}

void ChildProcess::Signal(int signal) {
  if (!reaped_) kill(pid_, signal);
}

StatusOr<int> ChildProcess::Wait(double timeout_s) {
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::milliseconds(static_cast<int64_t>(timeout_s * 1000));
  while (running()) {
    if (std::chrono::steady_clock::now() > deadline) {
      return Status::Internal("process " + std::to_string(pid_) + " still runs after " +
                              std::to_string(timeout_s) + " s");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  if (WIFEXITED(status_)) return WEXITSTATUS(status_);
  if (WIFSIGNALED(status_)) return 128 + WTERMSIG(status_);
  return -1;
}

StatusOr<std::unique_ptr<ChildProcess>> StartServer(const std::string& db,
                                                    const std::vector<std::string>& extra_args,
                                                    const std::string& log_path,
                                                    PlacerecClient* client, double timeout_s) {
  std::vector<std::string> argv = {BinaryPath("placerec-server"), "--db", db, "--lcm-url",
                                   TestLcmUrl()};
  argv.insert(argv.end(), extra_args.begin(), extra_args.end());
  StatusOr<std::unique_ptr<ChildProcess>> server = ChildProcess::Start(argv, log_path);
  if (!server.ok()) return server.status();
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::milliseconds(static_cast<int64_t>(timeout_s * 1000));
  while (std::chrono::steady_clock::now() < deadline) {
    if (!(*server)->running()) {
      return Status::Internal("placerec-server exited at start-up\n" + Tail(log_path));
    }
    if (client->WaitForStatus(0.5).ok()) return server;
  }
  return Status::Internal("no heartbeat from placerec-server within " + std::to_string(timeout_s) +
                          " s\n" + Tail(log_path));
}

StatusOr<std::unique_ptr<ChildProcess>> StartLcmHub(int port, const std::string& log_path,
                                                    double timeout_s) {
  StatusOr<std::unique_ptr<ChildProcess>> hub =
      ChildProcess::Start({"/bin/bash", std::string(PLACEREC_SOURCE_DIR) + "/scripts/lcm-hub.sh",
                           "run", std::to_string(port)},
                          log_path);
  if (!hub.ok()) return hub.status();
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::milliseconds(static_cast<int64_t>(timeout_s * 1000));
  sockaddr_in address = {};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  while (std::chrono::steady_clock::now() < deadline) {
    if (!(*hub)->running()) return Status::Internal("the LCM hub exited\n" + Tail(log_path));
    const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const bool accepted =
        fd >= 0 && connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof(address)) == 0;
    if (fd >= 0) close(fd);
    if (accepted) return hub;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return Status::Internal("the LCM hub did not accept connections on port " + std::to_string(port) +
                          " within " + std::to_string(timeout_s) + " s\n" + Tail(log_path));
}

StatusOr<int> StopServer(ChildProcess* server, double timeout_s) {
  server->Signal(SIGTERM);
  return server->Wait(timeout_s);
}

}  // namespace testing_service
}  // namespace placerec
