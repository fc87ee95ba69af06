// Who may send what (issue 26 item 2, proto/README.md "Signed frames"): the server's keys
// (a keys file, reloaded on SIGHUP) and the check of every frame before it is queued: a valid
// HMAC-SHA256 under a known key, a signing time within the window, a counter not used before with
// the key, and the key's permission (insert, query or both). Used by the receive loop only (one
// thread); what it returns carries a copy of the key, so answers can be signed by workers.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/util/status.h"
#include "placerec/frame_t.hpp"
#include "proto/auth/signing.h"

namespace placerec {

struct AuthOptions {
  // Off only on a lab LAN: every frame is accepted and answers are unsigned.
  bool enabled = true;
  // The keys file (format: server/README.md "Keys"); a server with authentication on refuses to
  // start without one (MissingKeysAdvice), so the defaults serve nobody until keys are given.
  std::string keys_file;
  // A frame's signing time (frame_t::auth_utime) may differ from the server's clock by at most
  // this many seconds; the server remembers each key's counters for this long.
  double window_s = 30.0;

  bool Check(std::string* error) const;
};

// What to do when authentication is on and no keys file was given.
std::string MissingKeysAdvice();

class Authenticator {
 public:
  // What the check of one frame decided.
  struct Verdict {
    bool ok = false;
    std::string message;  // why not, and what to do; empty when ok
    // The sender's key when the frame is signed with it (even when refused for its time or a
    // permission), so that the answer can be signed; nullopt otherwise (answer unsigned).
    std::optional<SigningKey> key;
    // A copy of a frame already accepted (its counter, with the same signature): not to be
    // answered. The sender has its answer (or gets it), and a signed refusal that echoes the
    // sender's request id would be taken by its client for the answer: anyone who can copy frames
    // on the network could veto every frame. Another frame reusing a counter is refused (and
    // answered) as before.
    bool replayed = false;
  };

  // Reads the keys file. `start_utime` is when the server starts serving (microseconds since
  // the epoch): frames signed before it are refused, since counters seen before a restart are
  // not remembered.
  static StatusOr<Authenticator> Create(const AuthOptions& options, int64_t start_utime);

  // Reads the keys file again (SIGHUP). Keys whose id and secret did not change keep their replay
  // state, also when removed and added back within the window. On error the old keys stay and the
  // error says why.
  Status Reload();

  // Checks `frame`, decoded from the `size` bytes at `received` (null: its encoding is
  // checked), that arrived at `now_utime` (microseconds since the epoch). Accepted counters are
  // remembered.
  Verdict Check(const frame_t& frame, int64_t now_utime, const void* received = nullptr,
                size_t size = 0);

  // Ids of the keys now loaded, for logs.
  std::vector<std::string> KeyIds() const;
  // A warning from the last read of the keys file (file mode), or empty.
  const std::string& warning() const { return warning_; }

 private:
  // The counters one key has used within the window, and the largest one forgotten since.
  struct ReplayState {
    // An accepted frame: when it was signed (microseconds) and the first bytes of its signature,
    // which tell a copy of it from another frame that reuses its counter.
    struct Used {
      int64_t utime = 0;
      uint64_t signature = 0;
    };
    std::string secret;                // of the key the counters were used with
    std::map<int64_t, Used> counters;  // by counter
    int64_t floor = INT64_MIN;         // counters at or below it are refused
  };

  Authenticator(AuthOptions options, int64_t start_utime)
      : options_(std::move(options)), start_utime_(start_utime) {}

  void Forget(ReplayState* state, int64_t now_utime) const;

  AuthOptions options_;
  int64_t start_utime_ = 0;
  std::vector<SigningKey> keys_;
  // By key id; a removed key's state stays while it holds counters of the window, so that the
  // key added back within it does not accept its frames again.
  std::map<std::string, ReplayState> replay_;
  int64_t last_check_utime_ = 0;  // the latest now_utime given to Check
  std::string warning_;
};

}  // namespace placerec
