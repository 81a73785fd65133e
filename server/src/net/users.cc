/// @brief Named users: the users file and the authenticator (users.h).
#include "net/users.h"

#include <fcntl.h>
#include <sodium.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <toml++/toml.h>

namespace sculpt::server {
namespace {

// crypto_pwhash limits of the hashes `sculptd user add` writes: Argon2id, the interactive
// operation count and 16 MiB (about 20 ms to verify). Tokens are 256 random bits, so the hash
// only has to keep a stolen users file from giving the tokens away, not to slow down guessing
// of a weak password.
constexpr unsigned long long kOpsLimit = crypto_pwhash_OPSLIMIT_INTERACTIVE;
constexpr size_t kMemLimit = 16u << 20;
// A verified (user, token) pair is trusted again without hashing for this long.
constexpr auto kVerifiedFor = std::chrono::minutes(10);

std::string Where(const std::string& path, const toml::node& n) {
  std::ostringstream os;
  os << path;
  if (n.source().begin) os << ":" << n.source().begin.line << ":" << n.source().begin.column;
  return os.str();
}

void EnsureSodium() {
  static const int ready = sodium_init();
  (void)ready;
}

std::string Blake(const std::string& token) {
  unsigned char h[crypto_generichash_BYTES];
  crypto_generichash(h, sizeof h, reinterpret_cast<const unsigned char*>(token.data()),
                     token.size(), nullptr, 0);
  return std::string(reinterpret_cast<const char*>(h), sizeof h);
}

// A hash of a token nobody has, verified for unknown names so that a wrong name costs the same
// time as a wrong token.
const std::string& DummyHash() {
  static const std::string h = [] {
    auto r = HashToken(NewToken());
    return r.ok() ? *r : std::string();
  }();
  return h;
}

}  // namespace

const char* UserRoleName(UserRole role) {
  return role == UserRole::kSculptor ? "sculptor" : "viewer";
}

Status CheckUserName(const std::string& field, const std::string& name) {
  const bool chars_ok = std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           c == '.' || c == '_' || c == '-';
  });
  if (name.empty() || name.size() > 64 || !chars_ok) {
    return InvalidArgument(field + " must be 1 to 64 characters of [A-Za-z0-9._-]");
  }
  return Status::Ok();
}

std::string NewToken() {
  EnsureSodium();
  unsigned char raw[32];
  randombytes_buf(raw, sizeof raw);
  char out[sodium_base64_ENCODED_LEN(32, sodium_base64_VARIANT_URLSAFE_NO_PADDING)];
  sodium_bin2base64(out, sizeof out, raw, sizeof raw, sodium_base64_VARIANT_URLSAFE_NO_PADDING);
  return out;
}

StatusOr<std::string> HashToken(const std::string& token) {
  EnsureSodium();
  char out[crypto_pwhash_STRBYTES];
  if (crypto_pwhash_str(out, token.data(), token.size(), kOpsLimit, kMemLimit) != 0) {
    return ResourceExhausted("crypto_pwhash_str: out of memory hashing a token");
  }
  return std::string(out);
}

bool VerifyToken(const std::string& hash, const std::string& token) {
  if (hash.empty() || hash.size() >= crypto_pwhash_STRBYTES) return false;
  return crypto_pwhash_str_verify(hash.c_str(), token.data(), token.size()) == 0;
}

StatusOr<UserTable> UserTable::Load(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return NotFound("users file " + path + " does not exist");
    return FailedPrecondition("users file " + path + ": " + std::strerror(errno));
  }
  if (!S_ISREG(st.st_mode)) return FailedPrecondition("users file " + path + " is not a file");
  if ((st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    return FailedPrecondition("users file " + path + " has mode " + mode +
                              ": it must not be readable or writable by group or others "
                              "(chmod 600 " + path + ")");
  }
  if (::access(path.c_str(), R_OK) != 0) {
    return FailedPrecondition("users file " + path + " is not readable: " + std::strerror(errno));
  }
  toml::table root;
  try {
    root = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    std::ostringstream os;
    os << "users file " << path << ":" << e.source().begin.line << ":" << e.source().begin.column
       << ": " << e.description();
    return InvalidArgument(os.str());
  }
  UserTable t;
  for (const auto& [key, node] : root) {
    if (key.str() != "users") {
      return InvalidArgument("users file " + Where(path, node) + ": unknown key " +
                             std::string(key.str()) + " (known: users)");
    }
  }
  const toml::array* users = root["users"].as_array();
  if (root.contains("users") && !users) {
    return InvalidArgument("users file " + path + ": users must be an array of tables [[users]]");
  }
  if (!users) return t;  // no users: nobody may connect
  for (size_t i = 0; i < users->size(); ++i) {
    const std::string entry = "users[" + std::to_string(i) + "]";
    const toml::table* u = (*users)[i].as_table();
    if (!u) return InvalidArgument("users file " + path + ": " + entry + " must be a table");
    for (const auto& [key, node] : *u) {
      if (key.str() != "name" && key.str() != "role" && key.str() != "token_hash") {
        return InvalidArgument("users file " + Where(path, node) + ": unknown key " + entry + "." +
                               std::string(key.str()) + " (known: name, role, token_hash)");
      }
    }
    User user;
    const auto name = (*u)["name"].value<std::string>();
    const auto role = (*u)["role"].value<std::string>();
    const auto hash = (*u)["token_hash"].value<std::string>();
    if (!name) return InvalidArgument("users file " + path + ": " + entry + ".name missing");
    SCULPT_RETURN_IF_ERROR(CheckUserName("users file " + path + ": " + entry + ".name", *name));
    if (!role || (*role != "sculptor" && *role != "viewer")) {
      return Outside(std::string("users file ") + path + ": " + entry + ".role", role.value_or(""),
                     "{sculptor, viewer}");
    }
    if (!hash || hash->rfind("$argon2", 0) != 0 || hash->size() >= crypto_pwhash_STRBYTES) {
      return InvalidArgument("users file " + path + ": " + entry +
                             ".token_hash is not a crypto_pwhash string (make users with "
                             "`sculptd user add NAME --role ROLE --users " +
                             path + "`)");
    }
    if (t.Find(*name)) {
      return InvalidArgument("users file " + path + ": " + entry + ".name=" + *name +
                             " appears twice");
    }
    user.name = *name;
    user.role = *role == "sculptor" ? UserRole::kSculptor : UserRole::kViewer;
    user.token_hash = *hash;
    t.users_.push_back(std::move(user));
  }
  return t;
}

Status UserTable::Save(const std::string& path) const {
  toml::array arr;
  for (const User& u : users_) {
    arr.push_back(toml::table{{"name", u.name}, {"role", UserRoleName(u.role)},
                              {"token_hash", u.token_hash}});
  }
  toml::table root{{"users", std::move(arr)}};
  std::ostringstream os;
  os << "# sculptd users: name, role and a crypto_pwhash hash of each token (never the token).\n"
     << "# Managed with `sculptd user add|remove`; sculptd re-reads it on SIGHUP.\n"
     << toml::toml_formatter(root) << "\n";
  const std::string text = os.str();
  const std::filesystem::path target(path);
  const std::string tmp = path + ".tmp";
  ::unlink(tmp.c_str());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) return FailedPrecondition("cannot create " + tmp + ": " + std::strerror(errno));
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      const std::string err = std::strerror(errno);
      ::close(fd);
      ::unlink(tmp.c_str());
      return FailedPrecondition("cannot write " + tmp + ": " + err);
    }
    done += static_cast<size_t>(n);
  }
  const bool synced = ::fsync(fd) == 0;
  ::close(fd);
  if (!synced || ::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string err = std::strerror(errno);
    ::unlink(tmp.c_str());
    return FailedPrecondition("cannot replace " + path + ": " + err);
  }
  const std::string dir =
      target.has_parent_path() ? target.parent_path().string() : std::string(".");
  if (const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
  return Status::Ok();
}

const User* UserTable::Find(const std::string& name) const {
  for (const User& u : users_) {
    if (u.name == name) return &u;
  }
  return nullptr;
}

void UserTable::Put(User user) {
  for (User& u : users_) {
    if (u.name == user.name) {
      u = std::move(user);
      return;
    }
  }
  users_.push_back(std::move(user));
}

bool UserTable::Remove(const std::string& name) {
  const auto it = std::find_if(users_.begin(), users_.end(),
                               [&](const User& u) { return u.name == name; });
  if (it == users_.end()) return false;
  users_.erase(it);
  return true;
}

StatusOr<std::unique_ptr<Authenticator>> Authenticator::Create(Options options) {
  if (sodium_init() < 0) return Internal("libsodium failed to initialise");
  std::unique_ptr<Authenticator> a(new Authenticator(std::move(options)));
  if (a->named_users()) {
    auto table = UserTable::Load(a->options_.users_file);
    if (!table.ok()) return table.status();
    a->table_ = std::make_shared<const UserTable>(std::move(table).value());
    (void)DummyHash();
    a->worker_ = std::thread([raw = a.get()] { raw->WorkerLoop(); });
  }
  return a;
}

Authenticator::Authenticator(Options options) : options_(std::move(options)) {}

Authenticator::~Authenticator() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  if (worker_.joinable()) worker_.join();
  // Whoever still waits hears that the server is going away.
  for (Job& j : jobs_) {
    AuthResult r;
    r.outcome = AuthResult::Outcome::kBusy;
    r.message = "server shutting down";
    j.done(std::move(r));
  }
}

Status Authenticator::Reload() {
  if (!named_users()) return Status::Ok();
  auto table = UserTable::Load(options_.users_file);
  if (!table.ok()) return table.status();
  std::lock_guard<std::mutex> lock(mu_);
  table_ = std::make_shared<const UserTable>(std::move(table).value());
  verified_.clear();  // a changed or removed token must be checked again
  return Status::Ok();
}

size_t Authenticator::user_count() const {
  std::lock_guard<std::mutex> lock(mu_);
  return table_ ? table_->users().size() : 0;
}

void Authenticator::Record(const std::string& source, const AuthResult& r) {
  std::lock_guard<std::mutex> lock(mu_);
  if (r.outcome == AuthResult::Outcome::kOk) {
    backoff_.erase(source);
    return;
  }
  if (r.outcome != AuthResult::Outcome::kUnauthenticated &&
      r.outcome != AuthResult::Outcome::kPermissionDenied) {
    return;
  }
  if (options_.first_backoff.count() <= 0) return;
  Backoff& b = backoff_[source];
  const auto now = std::chrono::steady_clock::now();
  // Failures are forgotten once an address has been quiet for the longest wait.
  if (now - b.last > options_.max_backoff) b.failures = 0;
  b.last = now;
  b.failures = std::min(b.failures + 1, 1 << 20);
  const int over = b.failures - options_.free_failures;
  if (over <= 0) return;
  const auto wait = std::min<std::chrono::milliseconds>(
      options_.max_backoff, options_.first_backoff * (int64_t{1} << std::min(over - 1, 20)));
  b.until = now + wait;
  // Forget sources long quiet, so the map stays bounded by recent offenders.
  if (backoff_.size() > 100000) {
    for (auto it = backoff_.begin(); it != backoff_.end();) {
      it = it->second.until < now && now - it->second.last > options_.max_backoff
               ? backoff_.erase(it)
               : std::next(it);
    }
  }
}

void Authenticator::Authenticate(const std::string& user, const std::string& token,
                                 UserRole role, const std::string& source, Done done) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto b = backoff_.find(source);
    const auto now = std::chrono::steady_clock::now();
    if (b != backoff_.end() && now < b->second.until) {
      AuthResult r;
      r.outcome = AuthResult::Outcome::kBackoff;
      const auto ms =
          std::chrono::duration_cast<std::chrono::milliseconds>(b->second.until - now).count();
      r.message = "retry after " + std::to_string(ms) + " ms (" +
                  std::to_string(b->second.failures) + " failed attempts from this address)";
      return done(std::move(r));
    }
  }
  Job job{user, token, source, role, std::move(done)};
  if (!named_users() || IsPeer(token, role)) {
    AuthResult r = Check(job);
    Record(source, r);
    return job.done(std::move(r));
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (jobs_.size() < options_.max_pending) {
      jobs_.push_back(std::move(job));
      cv_.notify_one();
      return;
    }
  }
  AuthResult r;
  r.outcome = AuthResult::Outcome::kBusy;
  r.message = "too many authentications in progress (" + std::to_string(options_.max_pending) +
              "); try again";
  job.done(std::move(r));
}

bool Authenticator::IsPeer(const std::string& token, UserRole role) const {
  if (options_.peer_token.empty() || role != UserRole::kViewer) return false;
  // Constant time and no early exit on length, like the shared tokens.
  const std::string a = Blake(token), b = Blake(options_.peer_token);
  return sodium_memcmp(a.data(), b.data(), a.size()) == 0;
}

AuthResult Authenticator::Check(const Job& job) {
  AuthResult r;
  if (IsPeer(job.token, job.role)) {
    r.outcome = AuthResult::Outcome::kOk;
    r.user = job.user;
    r.peer = true;
    return r;
  }
  if (!named_users()) {
    // The shared development tokens: constant-time, no early exit on length.
    const std::string& want =
        job.role == UserRole::kSculptor ? options_.sculptor_token : options_.viewer_token;
    const std::string a = Blake(job.token), b = Blake(want);
    if (sodium_memcmp(a.data(), b.data(), a.size()) == 0) {
      r.outcome = AuthResult::Outcome::kOk;
      r.user = job.user;
    }
    return r;
  }
  std::shared_ptr<const UserTable> table;
  const std::string key = job.user + '\n' + Blake(job.token);
  {
    std::lock_guard<std::mutex> lock(mu_);
    table = table_;
  }
  const User* u = table ? table->Find(job.user) : nullptr;
  bool verified = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = verified_.find(key);
    verified = u && it != verified_.end() &&
               std::chrono::steady_clock::now() - it->second < kVerifiedFor;
  }
  if (!verified) {
    verified = VerifyToken(u ? u->token_hash : DummyHash(), job.token) && u;
    if (verified) {
      std::lock_guard<std::mutex> lock(mu_);
      if (verified_.size() > 10000) verified_.clear();
      verified_[key] = std::chrono::steady_clock::now();
    }
  }
  if (!verified) return r;
  if (job.role == UserRole::kSculptor && u->role != UserRole::kSculptor) {
    r.outcome = AuthResult::Outcome::kPermissionDenied;
    r.message = "user " + u->name + " is a viewer";
    return r;
  }
  r.outcome = AuthResult::Outcome::kOk;
  r.user = u->name;
  r.named = true;
  return r;
}

void Authenticator::WorkerLoop() {
  for (;;) {
    Job job;
    {
      std::unique_lock<std::mutex> lock(mu_);
      cv_.wait(lock, [&] { return stop_ || !jobs_.empty(); });
      if (stop_) return;
      job = std::move(jobs_.front());
      jobs_.pop_front();
    }
    AuthResult r = Check(job);
    Record(job.source, r);
    job.done(std::move(r));
  }
}

}  // namespace sculpt::server
