// Issue 17's failover rounds, shared by the 20-round soak (label soak, run by hand:
// `build/bin/cluster_soak_tests`) and the 3-round test in `make test` (cluster_tests): three
// members with synchronous replication, 4 sculptors at 60 Hz joined through any member, and N
// rounds of kill -9 of the scene's owner. Each round: the owner dies, its standby takes over,
// the clients reconnect through the members they know (no user action) and resend what was not
// acknowledged, and the killed member comes back and follows as a standby again. At the end
// every stroke every client sent has been acknowledged, and the scene's sequence is exactly the
// poses of those strokes: nothing acknowledged was lost and nothing was applied twice; no copy
// diverged from its owner (each standby checks every edit's leaves hash). Prints the
// failover time (kill -9 to the first stroke acknowledged by the new owner) p50/p99 as JSON.
#ifndef SCULPT_TESTS_CLUSTER_FAILOVER_ROUNDS_H_
#define SCULPT_TESTS_CLUSTER_FAILOVER_ROUNDS_H_

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <iterator>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "cluster/processes.h"
#include "cluster/records.h"
#include "sculpt/client/client.h"

namespace sculpt::server::cluster::soak {

using sculpt::testing::Member;
using sculpt::testing::WaitFor;
using std::chrono::milliseconds;
using Clock = std::chrono::steady_clock;

const Keys kKeys{"t/"};
constexpr int kSculptors = 4;
// Under the sanitizers an owner on 2 loaded cores applied fewer strokes than 60 Hz sculptors sent
// (ClusterMoveTest ended with 300-1,260 of them unacknowledged, none lost): a third of the rate
// there; what the sanitizer run checks is the failover paths' memory safety.
constexpr int kRateHz = sculpt::testing::kSanitized ? 20 : 60;

// One simulated sculptor: a 2-pose stroke every 1/60 s while joined; a closed connection is
// reconnected through the members it was given (Reconnect), with a back-off.
class Sculptor {
 public:
  Sculptor(int index, uint16_t port, std::vector<std::string> members)
      : index_(index), options_(Options(std::move(members))), client_(options_) {
    ok_ = client_.Connect("127.0.0.1", port).ok() &&
          client_.Hello("sculpt-dev-sculptor", v1::ROLE_SCULPTOR, "soak-" + std::to_string(index),
                        0)
              .ok() &&
          client_.Join("").ok();
    if (ok_) thread_ = std::thread([this] { Run(); });
  }
  ~Sculptor() { Stop(); }

  bool ok() const { return ok_; }
  void Stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  int sent() const { return sent_; }
  std::string refusals() const {
    std::lock_guard<std::mutex> lock(mu_);
    std::string out;
    for (const auto& [why, n] : refusals_) out += std::to_string(n) + " x " + why + "\n";
    return out;
  }
  std::string last_error() const {
    std::lock_guard<std::mutex> lock(mu_);
    return last_error_;
  }
  sculpt::client::Client& client() { return client_; }
  // Acks seen since `t` (the clock of the soak).
  bool AckedSince(Clock::time_point t) const {
    return last_ack_ns_.load() >= t.time_since_epoch().count();
  }

 private:
  static sculpt::client::ClientOptions Options(std::vector<std::string> members) {
    sculpt::client::ClientOptions o;
    // A sanitized owner under load took more than 3 s to answer a join (the scene's state).
    o.timeout = milliseconds(sculpt::testing::kSanitized ? 10000 : 3000);
    o.cluster_members = std::move(members);
    return o;
  }
  void Run() {
    auto next = Clock::now();
    bool reconnect = false;
    Clock::time_point retry_at{};
    milliseconds backoff(50);
    while (!stop_) {
      next += std::chrono::microseconds(1000000 / kRateHz);
      std::this_thread::sleep_until(next);
      sculpt::client::StrokeRequest stroke;
      const double x = -6.0 + 3.0 * index_, y = (sent_ % 24) * 0.25;
      stroke.poses = {{{x, y, 22.5}, 0}, {{x, y + 0.2, 22.5}, 8}};
      // A sculptor's hand waits while the client says it is reconnecting: what was in flight at
      // the failure is resent on the new connection, nothing piles up behind it (a backlog of
      // seconds would run into the stroke rate limit and be refused).
      if (client_.joined() && client_.SendStroke(stroke).ok()) ++sent_;
      for (const sculpt::client::Event& e : client_.DrainEvents()) {
        if (e.type == sculpt::client::Event::Type::kAck) {
          last_ack_ns_ = Clock::now().time_since_epoch().count();
        }
        // Also the attempts inside a Reconnect that failed (or were redirected) say
        // kDisconnected: only a client that is not joined now reconnects, else a stale event
        // tore down the connection the last Reconnect made.
        if (e.type == sculpt::client::Event::Type::kDisconnected && !client_.joined()) {
          reconnect = true;
        }
        if (e.type == sculpt::client::Event::Type::kError && e.refused) {
          std::lock_guard<std::mutex> lock(mu_);
          ++refusals_[e.error.message().substr(0, 160)];
        }
      }
      // A failed reconnect waits before the next, doubling from 50 ms to 800 ms: the members
      // limit connections per second from one address, and 4 sculptors retrying at 60 Hz
      // through 3 members each exceed it.
      if (reconnect && Clock::now() >= retry_at) {
        const Status r = client_.Reconnect();
        if (r.ok()) {
          reconnect = false;
          backoff = milliseconds(50);
        } else {
          std::lock_guard<std::mutex> lock(mu_);
          last_error_ = r.ToString();
          retry_at = Clock::now() + backoff;
          backoff = std::min(backoff * 2, milliseconds(800));
        }
      }
      if (reconnect) next = Clock::now();  // a failed reconnect took its time; no burst after
    }
  }

  int index_;
  sculpt::client::ClientOptions options_;
  sculpt::client::Client client_;
  bool ok_ = false;
  std::atomic<bool> stop_{false};
  std::atomic<int> sent_{0};
  std::atomic<int64_t> last_ack_ns_{0};
  mutable std::mutex mu_;
  std::string last_error_;                 // of the last failed Reconnect
  std::map<std::string, int> refusals_;    // why strokes were refused, and how often
  std::thread thread_;
};

// Under ASan a new owner is several times slower and reads the sculptors' strokes in bursts.
// Their resends are declared in the JoinScene and take no tokens (JoinScene.resends), but the
// strokes made after the JoinScene went out (while the slow join and the paced resends are under
// way, 60 a second) are new strokes, charged: they follow the resends paced at 3/4 of the
// Welcome's rate, and a slow owner reading them in a clump refuses those past the stroke burst
// of 60 (docs/cluster.md, "Failover rounds"). The same happens to the Release build on a loaded
// machine (CI on 2 cores at load 6-7 refused 18 and 20 strokes once). These limits raise the
// bursts; appended to a member's configuration.
inline std::string RaisedBurstLimits() { return "[limits]\nstroke_burst = 2000\npose_burst = 20000\n"; }
// The sanitizer run is there for the failover paths' memory safety: it always raises the bursts.
inline std::string SanitizerLimits() {
#if defined(__SANITIZE_ADDRESS__)
  return RaisedBurstLimits();
#else
  return "";
#endif
}

class FailoverSoakTest : public sculpt::testing::EtcdTest {
 protected:
  void TearDown() override {
    members_.clear();
    EtcdTest::TearDown();
  }
  // Member `name` (a, b or c) started anew on its own data directory.
  Member& Start(const std::string& name) {
    // Strict sync (sync_fallback_ms = 0: never fall back to async): with a fall-back, an owner
    // whose standby is still loading acknowledges alone, and its death then loses those acks,
    // as designed; the soak checks the strict promise.
    // A fixed port per member, as in a deployment: a restarted or promoted member keeps its
    // address, so the sculptors' list of members stays true.
    if (ports_.count(name) == 0) ports_[name] = sculpt::testing::FreePort();
    members_[name] = std::make_unique<Member>(
        name, etcd_->endpoint(), dir_.path(),
        "replication = \"sync\"\nsync_fallback_ms = 0\n" +
            (raised_bursts_ ? RaisedBurstLimits() : SanitizerLimits()),
        std::vector<std::string>{"--http", "127.0.0.1:0"}, 2000,
        "127.0.0.1:" + std::to_string(ports_[name]));
    return *members_[name];
  }
  template <typename T>
  std::optional<T> Read(const std::string& key, StatusOr<T> (*decode)(const std::string&)) {
    auto kv = etcd_client_->Sync(etcd_client_->Get(key));
    if (!kv.ok() || !kv->has_value()) return std::nullopt;
    auto v = decode((*kv)->value);
    return v.ok() ? std::optional<T>(*v) : std::nullopt;
  }
  std::optional<OwnerRecord> Owner() { return Read<OwnerRecord>(kKeys.Owner("default"), DecodeOwner); }
  std::optional<StandbyRecord> Standby() {
    return Read<StandbyRecord>(kKeys.Standby("default"), DecodeStandby);
  }
  std::optional<MemberRecord> MemberOf(const std::string& name) {
    return Read<MemberRecord>(kKeys.Member(name), DecodeMember);
  }
  // Every member's TCP address as etcd has it now.
  std::vector<std::string> Addresses() {
    std::vector<std::string> out;
    for (const char* n : {"a", "b", "c"}) {
      if (auto m = MemberOf(n)) out.push_back(m->tcp);
    }
    return out;
  }

  // The end of each member's log and what etcd says, for a failure's message.
  std::string Diagnosis() {
    std::string out;
    auto o = Owner();
    out += "owner: " + (o ? o->member + " epoch " + std::to_string(o->epoch) + " at " + o->tcp
                          : std::string("none")) + "\n";
    for (const char* n : {"a", "b", "c"}) {
      std::ifstream in(dir_.path() / (std::string(n) + ".log"));
      std::vector<std::string> lines;
      for (std::string l; std::getline(in, l);) lines.push_back(l);
      out += std::string("--- ") + n + ".log\n";
      for (size_t i = lines.size() > 12 ? lines.size() - 12 : 0; i < lines.size(); ++i) {
        out += lines[i] + "\n";
      }
    }
    return out;
  }

  // Waits until etcd names an owner and a standby whose copy follows the scene.
  bool OwnerWithAFollowingStandby(milliseconds limit) {
    return WaitFor(
        [&] {
          auto o = Owner();
          auto s = Standby();
          auto m = s ? MemberOf(s->member) : std::nullopt;
          return o && m && m->follows == "default";
        },
        limit);
  }

  // kill -9 of the scene's owner `rounds` times under the sculptors; see the file comment.
  // The rounds in `make test` run on machines whose load they do not control, so they raise the
  // stroke bursts: what they check is that failover loses and repeats nothing, not the rate
  // limit. The soak (run by hand on a quiet machine) keeps the default limits.
  bool raised_bursts_ = false;

  void RunRounds(int rounds) {
    for (const char* n : {"a", "b", "c"}) {
      ASSERT_NE(Start(n).WaitPort(), 0) << n << " did not start; see " << dir_.path();
    }
    ASSERT_TRUE(OwnerWithAFollowingStandby(milliseconds(20000)))
        << "no owner with a following standby; see " << dir_.path();
    const std::vector<std::string> addresses = Addresses();
    ASSERT_EQ(addresses.size(), 3u);

    std::vector<std::unique_ptr<Sculptor>> sculptors;
    for (int i = 0; i < kSculptors; ++i) {
      // Each joins through a different member (redirected to the owner), knowing all three.
      const std::string& via = addresses[i % 3];
      sculptors.push_back(std::make_unique<Sculptor>(
          i, static_cast<uint16_t>(std::stoi(via.substr(via.rfind(':') + 1))), addresses));
      ASSERT_TRUE(sculptors.back()->ok()) << "sculptor " << i << " could not join";
    }
    const uint64_t initial_seq = 0;  // a fresh scene: nothing before the sculptors

    std::vector<double> failover_ms;
    for (int round = 0; round < rounds; ++round) {
      std::this_thread::sleep_for(milliseconds(1500));  // sculpting under a healthy pair
      const auto owner = Owner();
      ASSERT_TRUE(owner.has_value()) << "round " << round;
      const std::string victim = owner->member;
      const auto killed = Clock::now();
      const auto killed_wall = std::chrono::system_clock::now();
      std::optional<Clock::time_point> owned_at;  // when etcd first named the new owner
      members_[victim]->process().Kill(SIGKILL);
      // The first stroke acknowledged by the new owner: any sculptor's ack after the new owner
      // holds the scene.
      ASSERT_TRUE(WaitFor(
          [&] {
            auto o = Owner();
            if (!o || o->member == victim) return false;
            if (!owned_at) owned_at = Clock::now();
            return std::any_of(sculptors.begin(), sculptors.end(),
                               [&](const auto& s) { return s->AckedSince(killed); });
          },
          milliseconds(20000)))
          << "round " << round << ": no ack after " << victim << " was killed\n" << Diagnosis()
          << [&] {
               std::string c;
               for (auto& sc : sculptors) {
                 c += "sculptor: joined " + std::to_string(sc->client().joined()) + ", unacked " +
                      std::to_string(sc->client().unacked()) + ", acks " +
                      std::to_string(sc->client().stats().acks) + ", reconnects " +
                      std::to_string(sc->client().stats().reconnects) + ", last error " +
                      sc->last_error() + "\n";
               }
               return c;
             }();
      failover_ms.push_back(
          std::chrono::duration<double, std::milli>(Clock::now() - killed).count());
      // The killed member comes back on its data directory and follows the new owner.
      ASSERT_NE(Start(victim).WaitPort(), 0) << "round " << round << ": " << victim;
      ASSERT_TRUE(OwnerWithAFollowingStandby(milliseconds(30000)))
          << "round " << round << ": no standby follows again\n" << Diagnosis();
      // The wall clock of the kill finds the round in the members' logs (SCULPT_KEEP_TEST_DIRS).
      const std::time_t t = std::chrono::system_clock::to_time_t(killed_wall);
      char when[32];
      std::strftime(when, sizeof when, "%H:%M:%S", std::gmtime(&t));
      std::fprintf(stderr, "round %d: %s killed at %s UTC, owner after %.0f ms, failover %.0f ms\n",
                   round + 1, victim.c_str(), when,
                   std::chrono::duration<double, std::milli>(*owned_at - killed).count(),
                   failover_ms.back());
    }

    for (auto& s : sculptors) s->Stop();
    uint64_t strokes = 0;
    for (auto& s : sculptors) {
      // Whatever is pending is resent once connected: wait for every answer.
      for (int attempt = 0; attempt < 20 && s->client().unacked() > 0; ++attempt) {
        if (!s->client().joined()) (void)s->client().Reconnect();
        // A sanitized owner under load drained a backlog of 100 strokes more slowly.
        (void)s->client().WaitAllAcked(sculpt::testing::Scaled(milliseconds(1000)));
      }
      EXPECT_EQ(s->client().unacked(), 0u);
      EXPECT_EQ(s->client().stats().refused, 0u) << s->refusals();
      strokes += static_cast<uint64_t>(s->sent());
    }
    const auto owner = Owner();
    ASSERT_TRUE(owner.has_value());
    sculpt::client::ClientOptions options;
    options.timeout = milliseconds(5000);
    sculpt::client::Client viewer(options);
    const std::string& tcp = owner->tcp;
    ASSERT_TRUE(
        viewer.Connect("127.0.0.1", static_cast<uint16_t>(std::stoi(tcp.substr(tcp.rfind(':') + 1))))
            .ok());
    ASSERT_TRUE(viewer.Hello("sculpt-dev-viewer", v1::ROLE_VIEWER, "soak-viewer", 0).ok());
    auto joined = viewer.Join("");
    ASSERT_TRUE(joined.ok()) << joined.status();
    // Every stroke applied exactly once: 2 poses each.
    EXPECT_EQ(joined->info.global_seq(), initial_seq + 2 * strokes);
    // Every standby replayed every edit to the owner's leaves hash (a mismatch is logged by the
    // standby as "diverged" and loads the object anew).
    for (const char* n : {"a", "b", "c"}) {
      std::ifstream in(dir_.path() / (std::string(n) + ".log"));
      const std::string log((std::istreambuf_iterator<char>(in)),
                            std::istreambuf_iterator<char>());
      EXPECT_EQ(log.find("diverged"), std::string::npos) << "member " << n << " diverged";
    }

    std::sort(failover_ms.begin(), failover_ms.end());
    auto at = [&](double q) {
      return failover_ms[std::min(failover_ms.size() - 1,
                                  static_cast<size_t>(q * static_cast<double>(failover_ms.size())))];
    };
    std::printf(
        "{\"rounds\": %zu, \"sculptors\": %d, \"rate_hz\": %d, \"replication\": \"sync\", "
        "\"lease_ttl_ms\": 2000, \"strokes\": %llu, \"failover_ms_p50\": %.0f, "
        "\"failover_ms_p99\": %.0f, \"failover_ms_max\": %.0f}\n",
        failover_ms.size(), kSculptors, kRateHz, static_cast<unsigned long long>(strokes), at(0.5),
        at(0.99), failover_ms.back());
  }

  sculpt::testing::TempDir dir_{"sculpt-failover-soak"};
  std::map<std::string, std::unique_ptr<Member>> members_;
  std::map<std::string, uint16_t> ports_;
};

}  // namespace sculpt::server::cluster::soak

#endif  // SCULPT_TESTS_CLUSTER_FAILOVER_ROUNDS_H_
