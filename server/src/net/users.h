/// @brief Named users: who may connect, in which role, proven by a token whose libsodium
/// `crypto_pwhash` hash (never the token) is kept in a users file; and the authenticator a
/// session asks, which verifies off the network threads, remembers recent successes and makes
/// a source address that keeps failing wait longer and longer.
///
/// Users file (TOML, readable by its owner only):
///   [[users]]
///   name = "alice"                      # 1..64 bytes of [A-Za-z0-9._-]
///   role = "sculptor"                   # sculptor | viewer (a sculptor may also join as viewer)
///   token_hash = "$argon2id$v=19$..."   # crypto_pwhash_str of the token (sculptd user add)
#ifndef SCULPT_SERVER_NET_USERS_H_
#define SCULPT_SERVER_NET_USERS_H_

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "sculpt/core/status.h"

namespace sculpt::server {

enum class UserRole { kSculptor, kViewer };
const char* UserRoleName(UserRole role);

struct User {
  std::string name;
  UserRole role = UserRole::kViewer;
  std::string token_hash;  // crypto_pwhash_str output
};

/// The users of one users file. A value type.
class UserTable {
 public:
  /// Reads and checks a users file: NotFound when missing, FailedPrecondition when unreadable or
  /// readable or writable by group or others (the reason says which mode bits), InvalidArgument
  /// naming the entry and key for a malformed file, an unknown key, a bad name or role, a hash
  /// that is not a crypto_pwhash string, or a duplicate name.
  static StatusOr<UserTable> Load(const std::string& path);
  /// Writes the table to `path` atomically (a temporary file of mode 0600, fsync, rename,
  /// directory fsync).
  Status Save(const std::string& path) const;

  const User* Find(const std::string& name) const;
  /// Adds or replaces a user.
  void Put(User user);
  /// False when there was no such user.
  bool Remove(const std::string& name);
  const std::vector<User>& users() const { return users_; }

 private:
  std::vector<User> users_;
};

/// InvalidArgument unless `name` is 1..64 bytes of [A-Za-z0-9._-].
Status CheckUserName(const std::string& field, const std::string& name);
/// A fresh random token (32 random bytes, URL-safe base64 without padding).
std::string NewToken();
/// crypto_pwhash_str of `token` with the limits users files use.
StatusOr<std::string> HashToken(const std::string& token);
/// True when `token` matches `hash` (crypto_pwhash_str_verify; constant in the token's content).
bool VerifyToken(const std::string& hash, const std::string& token);

/// Who a Hello turned out to be from, or why not.
struct AuthResult {
  enum class Outcome {
    kOk,
    kUnauthenticated,   // wrong token or no such user (never said which)
    kPermissionDenied,  // the user does not have the requested role
    kBackoff,           // the source failed recently and must wait (`message` says how long)
    kBusy,              // the verification queue is full
  };
  Outcome outcome = Outcome::kUnauthenticated;
  std::string user;      // kOk: the authenticated name
  bool named = false;    // kOk: from a users file (false: a shared token or the peer token)
  /// kOk: a cluster member (a viewer Hello presenting the configured peer token); `user` is then
  /// the name its Hello claimed, e.g. "standby-b".
  bool peer = false;
  std::string message;
};

/// Decides who a Hello is from. A viewer presenting the peer token (when one is configured) is a
/// cluster member, decided at once in constant time, users file or not. Without a users file it compares the two shared tokens of the
/// configuration (constant time); with one, it verifies the claimed user's token hash on a
/// worker thread of its own (a hash takes milliseconds by design and must not stall sessions),
/// caching successes for a while. A source address that keeps failing waits before its next
/// attempt is even looked at: after `free_failures` failures, `first_backoff`, doubling with
/// each further failure up to `max_backoff`; a success resets it.
/// Thread-safe.
class Authenticator {
 public:
  struct Options {
    std::string users_file;            // empty: the shared tokens
    std::string sculptor_token, viewer_token;
    /// The cluster members' shared secret (cluster.peer_token); empty: no peers. A viewer Hello
    /// presenting it is a peer, with or without a users file.
    std::string peer_token;
    size_t max_pending = 64;           // verifications queued at most; beyond: refused
    int free_failures = 5;             // failures per source before the backoff starts
    std::chrono::milliseconds first_backoff{250};  // 0: no backoff
    std::chrono::milliseconds max_backoff{30000};
  };
  using Done = std::function<void(AuthResult)>;

  /// Loads the users file when one is named (its errors are returned).
  static StatusOr<std::unique_ptr<Authenticator>> Create(Options options);
  ~Authenticator();

  /// Authenticates `user` (the Hello's client_name) presenting `token` for `role`, from
  /// `source` (an address without port). `done` runs exactly once, on the worker or at once.
  void Authenticate(const std::string& user, const std::string& token, UserRole role,
                    const std::string& source, Done done);

  /// Re-reads the users file (SIGHUP). On error the previous table stays in force.
  Status Reload();
  bool named_users() const { return !options_.users_file.empty(); }
  size_t user_count() const;

 private:
  struct Job {
    std::string user, token, source;
    UserRole role;
    Done done;
  };
  explicit Authenticator(Options options);
  void WorkerLoop();
  AuthResult Check(const Job& job);
  /// True when `role` is the viewer's and `token` equals the configured peer token.
  bool IsPeer(const std::string& token, UserRole role) const;
  void Record(const std::string& source, const AuthResult& r);

  Options options_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::shared_ptr<const UserTable> table_;
  std::deque<Job> jobs_;
  bool stop_ = false;
  struct Backoff {
    int failures = 0;
    std::chrono::steady_clock::time_point until, last;
  };
  std::map<std::string, Backoff> backoff_;
  // user + '\n' + BLAKE2b(token) -> when it was last verified.
  std::map<std::string, std::chrono::steady_clock::time_point> verified_;
  std::thread worker_;
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_NET_USERS_H_
