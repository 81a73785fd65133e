// Child processes of the cluster tests: an etcd from Debian's etcd-server on free loopback ports
// with a temporary data directory, and sculptd members; each is killed and its directory
// removed when the object goes away (and killed with the test process, by PR_SET_PDEATHSIG).
#ifndef SCULPT_TESTS_CLUSTER_PROCESSES_H_
#define SCULPT_TESTS_CLUSTER_PROCESSES_H_

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "cluster/etcd_client.h"
#include "cluster/records.h"
#include "net/net.h"
#include "sculpt/client/client.h"

namespace sculpt::testing {

namespace fs = std::filesystem;

inline constexpr const char* kEtcdBinary = "/usr/bin/etcd";

inline bool HaveEtcd() { return access(kEtcdBinary, X_OK) == 0; }

/// Built with AddressSanitizer (build-asan: ASan and UBSan together).
#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif

/// A test's wait for sanitized members: 3x under the sanitizers, where a sculptd opening six
/// scenes took more than 10 s to listen and a join's scene state more than 5 s on 2 loaded cores.
inline std::chrono::milliseconds Scaled(std::chrono::milliseconds ms) {
  return kSanitized ? 3 * ms : ms;
}

/// The lease TTL for members of a test whose promoted member must reach etcd again within the TTL
/// after its restart (execv) to keep its lease and its other scenes' epochs: the default 2 s, but
/// 8 s under the sanitizers, where a sculptd's start-up alone, before it opens any scene (the
/// lease is kept alive from there on, ResumedLeaseKeeper), took 0.8 s on an idle machine and up
/// to 3.8 s on 2 cores at load 20 (docs/sanitizers.md, 2026-12-07).
inline int RestartLeaseTtlMs() { return kSanitized ? 8000 : 2000; }

/// A port the kernel just handed out and released (a small race with other processes, accepted
/// in tests: etcd needs its ports named on its command line).
inline uint16_t FreePort() {
  boost::asio::io_context io;
  boost::asio::ip::tcp::acceptor a(io, {boost::asio::ip::make_address("127.0.0.1"), 0});
  return a.local_endpoint().port();
}

/// What `sculpt ARGS` printed (stdout and stderr) and its exit code (-1 when it did not exit).
struct RunResult {
  int exit_code = -1;
  std::string output;
};

/// Runs the `sculpt` binary of SCULPT_BIN_DIR through the shell (arguments are test-made: no
/// quoting needed).
inline RunResult Sculpt(const std::string& args) {
  RunResult r;
  const std::string cmd = std::string(SCULPT_BIN_DIR) + "/sculpt " + args + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  if (p == nullptr) return r;
  std::array<char, 4096> buf;
  size_t n = 0;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  const int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

/// A fresh directory under the system's temporary folder, removed by the destructor unless
/// SCULPT_KEEP_TEST_DIRS is set (the members' logs explain a failure).
class TempDir {
 public:
  explicit TempDir(const std::string& stem) {
    std::string tmpl = (fs::temp_directory_path() / (stem + ".XXXXXX")).string();
    path_ = mkdtemp(tmpl.data()) ? fs::path(tmpl) : fs::path();
  }
  ~TempDir() {
    std::error_code ec;
    if (std::getenv("SCULPT_KEEP_TEST_DIRS") != nullptr) {
      std::fprintf(stderr, "kept %s (SCULPT_KEEP_TEST_DIRS)\n", path_.c_str());
    } else if (!path_.empty()) {
      fs::remove_all(path_, ec);
    }
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

/// fork + exec with stdout and stderr appended to `log`; the child dies with the test.
class ChildProcess {
 public:
  ChildProcess(std::vector<std::string> args, const fs::path& log) {
    // Everything the child needs is made before fork: only async-signal-safe calls after it.
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const std::string log_path = log.string();
    pid_ = fork();
    if (pid_ == 0) {
      prctl(PR_SET_PDEATHSIG, SIGKILL);
      const int fd = open(log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      if (fd >= 0) {
        dup2(fd, 1);
        dup2(fd, 2);
      }
      execv(argv[0], argv.data());
      _exit(127);
    }
  }
  ~ChildProcess() { Kill(SIGKILL); }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  pid_t pid() const { return pid_; }
  bool running() const { return pid_ > 0; }
  /// Sends `sig` and reaps the process.
  void Kill(int sig) {
    if (pid_ <= 0) return;
    kill(pid_, sig);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = -1;
  }
  /// Sends SIGSTOP and returns once every thread of the process is stopped (false after 5 s).
  /// kill() returns before the stop takes effect: the thread chosen to take the signal may be
  /// waiting for a core while the others run on, so on a loaded machine a "paused" member
  /// could still read, apply and acknowledge what a test sends right after the kill.
  bool Pause() {
    if (pid_ <= 0 || kill(pid_, SIGSTOP) != 0) return false;
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (std::chrono::steady_clock::now() < until) {
      if (AllThreadsStopped()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return false;
  }

 private:
  // Every /proc/<pid>/task/<tid>/stat in state T (stopped); the state follows the last ')'.
  bool AllThreadsStopped() const {
    std::error_code ec;
    size_t threads = 0;
    for (const auto& task : fs::directory_iterator(
             fs::path("/proc") / std::to_string(pid_) / "task", ec)) {
      std::ifstream in(task.path() / "stat");
      const std::string stat((std::istreambuf_iterator<char>(in)),
                             std::istreambuf_iterator<char>());
      const size_t paren = stat.rfind(')');
      if (paren == std::string::npos || paren + 2 >= stat.size()) return false;
      if (stat[paren + 2] != 'T' && stat[paren + 2] != 't') return false;
      ++threads;
    }
    return !ec && threads > 0;
  }

  pid_t pid_ = -1;
};

/// An etcd's client-port TLS: its certificate and key, the CA its clients' certificates must
/// chain to, and whether it requires one (--client-cert-auth).
struct EtcdTlsFiles {
  std::string cert_file;
  std::string key_file;
  std::string trusted_ca_file;
  bool client_cert_auth = false;
};

/// One etcd member on free loopback ports; endpoint() is its client URL (https:// with `tls`;
/// the peer port stays plain, a one-member cluster has no peer).
class EtcdProcess {
 public:
  explicit EtcdProcess(std::optional<EtcdTlsFiles> tls = std::nullopt) : dir_("sculpt-etcd") {
    client_port_ = FreePort();
    scheme_ = tls ? "https://" : "http://";
    const uint16_t peer = FreePort();
    const std::string client = endpoint();
    const std::string peer_url = "http://127.0.0.1:" + std::to_string(peer);
    std::vector<std::string> args{kEtcdBinary, "--name", "t", "--data-dir",
                                  (dir_.path() / "data").string(), "--listen-client-urls", client,
                                  "--advertise-client-urls", client, "--listen-peer-urls", peer_url,
                                  "--initial-advertise-peer-urls", peer_url, "--initial-cluster",
                                  "t=" + peer_url};
    if (tls) {
      args.insert(args.end(), {"--cert-file", tls->cert_file, "--key-file", tls->key_file});
      if (!tls->trusted_ca_file.empty()) {
        args.insert(args.end(), {"--trusted-ca-file", tls->trusted_ca_file});
      }
      if (tls->client_cert_auth) args.push_back("--client-cert-auth");
    }
    process_ = std::make_unique<ChildProcess>(std::move(args), dir_.path() / "etcd.log");
  }
  ~EtcdProcess() { process_.reset(); }

  std::string endpoint() const { return scheme_ + "127.0.0.1:" + std::to_string(client_port_); }
  uint16_t client_port() const { return client_port_; }
  const fs::path& dir() const { return dir_.path(); }
  ChildProcess& process() { return *process_; }

 private:
  TempDir dir_;  // first: outlives the process
  uint16_t client_port_ = 0;
  std::string scheme_;
  std::unique_ptr<ChildProcess> process_;
};

/// Polls `ready` every 20 ms until it holds or `limit` passes; true when it held.
template <typename F>
bool WaitFor(F ready, std::chrono::milliseconds limit) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < end) {
    if (ready()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return ready();
}

/// Why a test that needs etcd is skipped.
inline constexpr const char* kNoEtcd =
    "/usr/bin/etcd is missing: install Debian's etcd-server (deploy/install-deps.sh)";

/// A client of `etcd` once it answers (it takes about a second to elect itself); Unavailable,
/// naming its log, when it did not within 15 s. `tls`: the client's CA and certificate files
/// (its endpoints and timeout are set here).
inline StatusOr<std::unique_ptr<server::cluster::EtcdClient>> ConnectWhenReady(
    const EtcdProcess& etcd, server::cluster::EtcdClient::Options tls = {}) {
  tls.endpoints = {etcd.endpoint()};
  tls.timeout = std::chrono::milliseconds(500);
  auto c = server::cluster::EtcdClient::Create(std::move(tls));
  if (!c.ok()) return c.status();
  server::cluster::EtcdClient& client = **c;
  if (!WaitFor([&] { return client.Sync(client.Get("ping")).ok(); }, std::chrono::seconds(15))) {
    return Status(Status::Code::kUnavailable,
                  "etcd did not start; its log is in " + etcd.dir().string());
  }
  return c;
}

/// One sculptd cluster member (key prefix "t/"): its configuration file, data directory, log and
/// ports under `base`. Needs SCULPT_BIN_DIR (the directory of sculptd).
class Member {
 public:
  // `extra`: more lines of the [cluster] section; `listen`: a fixed port keeps the member's
  // address across restarts (a failover re-executes it with the same arguments).
  Member(const std::string& name, const std::string& etcd, const fs::path& base,
         const std::string& extra = "", const std::vector<std::string>& args = {},
         int lease_ttl_ms = 2000, const std::string& listen = "127.0.0.1:0")
      : name_(name), port_file_(base / (name + ".ports")) {
    const fs::path config = base / (name + ".toml");
    std::ofstream(config) << "[cluster]\netcd = [\"" << etcd << "\"]\nmember = \"" << name
                          << "\"\nlease_ttl_ms = " << lease_ttl_ms << "\nprefix = \"t/\"\n"
                          << extra;
    fs::remove(port_file_);
    std::vector<std::string> argv{std::string(SCULPT_BIN_DIR) + "/sculptd", "serve", "--config",
                                  config.string(), "--listen", listen, "--data",
                                  (base / (name + "-data")).string(), "--port-file",
                                  port_file_.string()};
    argv.insert(argv.end(), args.begin(), args.end());
    process_ = std::make_unique<ChildProcess>(argv, base / (name + ".log"));
  }
  // The TCP port once the member is registered in etcd and listening (0 after 10 s, 30 s
  // under the sanitizers).
  uint16_t WaitPort() {
    WaitFor(
        [&] {
          std::ifstream in(port_file_);
          unsigned p = 0;
          if (in >> p && p > 0) port_ = static_cast<uint16_t>(p);
          return port_ != 0;
        },
        Scaled(std::chrono::milliseconds(10000)));
    return port_;
  }
  uint16_t port() const { return port_; }
  ChildProcess& process() { return *process_; }

 private:
  std::string name_;
  fs::path port_file_;
  uint16_t port_ = 0;
  std::unique_ptr<ChildProcess> process_;
};

/// A sculptor's acknowledgements, as its client's event handler receives them: client_seq ->
/// the last global sequence of the stroke, to check that every acknowledged stroke survived.
/// Installs itself as the client's handler until Stop (or destruction).
class AckLog {
 public:
  explicit AckLog(client::Client& c) : client_(c) {
    c.SetEventHandler([this](const client::Event& e) {
      if (e.type != client::Event::Type::kAck) return;
      std::lock_guard<std::mutex> lock(mu_);
      acked_[e.ack.client_seq()] = e.ack.global_seq_first() + e.ack.edits() - 1;
    });
  }
  ~AckLog() { Stop(); }
  AckLog(const AckLog&) = delete;
  AckLog& operator=(const AckLog&) = delete;
  void Stop() { client_.SetEventHandler(nullptr); }
  size_t size() const {
    std::lock_guard<std::mutex> lock(mu_);
    return acked_.size();
  }
  // The highest global sequence acknowledged.
  uint64_t highest() const {
    std::lock_guard<std::mutex> lock(mu_);
    uint64_t h = 0;
    for (const auto& [cs, gs] : acked_) h = std::max(h, gs);
    return h;
  }

 private:
  client::Client& client_;
  mutable std::mutex mu_;
  std::map<uint64_t, uint64_t> acked_;
};

/// A test with its own etcd and a client of it (skipped without etcd). A fixture that starts
/// sculptd members stops them in its TearDown before calling this one's: etcd goes last.
class EtcdTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!HaveEtcd()) GTEST_SKIP() << kNoEtcd;
    etcd_ = std::make_unique<EtcdProcess>();
    auto c = ConnectWhenReady(*etcd_);
    ASSERT_TRUE(c.ok()) << c.status();
    etcd_client_ = std::move(c).value();
  }
  void TearDown() override {
    etcd_client_.reset();
    etcd_.reset();
  }

  // The records the members keep under the tests' prefix "t/" (nullopt: absent or unreadable).
  std::optional<server::cluster::OwnerRecord> OwnerOf(const std::string& scene) {
    return Read(keys_.Owner(scene), server::cluster::DecodeOwner);
  }
  std::optional<server::cluster::StandbyRecord> StandbyOf(const std::string& scene) {
    return Read(keys_.Standby(scene), server::cluster::DecodeStandby);
  }
  std::optional<server::cluster::MemberRecord> MemberOf(const std::string& name) {
    return Read(keys_.Member(name), server::cluster::DecodeMember);
  }
  // The scene's owner record once one is there held by `member` (any member when empty), or
  // nullopt after `limit`. Read once per check and kept: the key can be gone again a moment
  // later (a promoted member restarts), so a second read may find nothing.
  std::optional<server::cluster::OwnerRecord> AwaitOwner(const std::string& scene,
                                                         const std::string& member,
                                                         std::chrono::milliseconds limit) {
    std::optional<server::cluster::OwnerRecord> owner;
    const auto taken = [&] { return owner && (member.empty() || owner->member == member); };
    WaitFor(
        [&] {
          owner = OwnerOf(scene);
          return taken();
        },
        limit);
    return taken() ? owner : std::nullopt;
  }

  std::unique_ptr<EtcdProcess> etcd_;
  std::unique_ptr<server::cluster::EtcdClient> etcd_client_;

 private:
  template <typename Record>
  std::optional<Record> Read(const std::string& key,
                             StatusOr<Record> (*decode)(const std::string&)) {
    auto kv = etcd_client_->Sync(etcd_client_->Get(key));
    if (!kv.ok() || !kv->has_value()) return std::nullopt;
    auto r = decode((*kv)->value);
    if (!r.ok()) return std::nullopt;
    return *r;
  }
  const server::cluster::Keys keys_{"t/"};
};

}  // namespace sculpt::testing

#endif  // SCULPT_TESTS_CLUSTER_PROCESSES_H_
