/// @brief ClusterAgent: lease, membership, scene ownership and the routing table.
#include "cluster/cluster_agent.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>

#include "cluster/placement.h"
#include "cluster/standby_follower.h"

// Every call of a coroutine is made in its own statement and its awaitable then awaited
// (`auto x_call = F(args); auto x = co_await std::move(x_call);`): g++ 12 destroys temporaries
// of a co_await expression's arguments twice (heap corruption seen with a braced PutOp).
namespace sculpt::server::cluster {
namespace {

using Clock = OwnershipFence::Clock;

// The fence ends this much before the lease could end in etcd: a keep-alive's deadline is taken
// from when it was sent (etcd resets the TTL later than that), less a margin for the two clocks'
// rates and for the time between Check() and the ack leaving the process.
std::chrono::milliseconds Margin(std::chrono::milliseconds ttl) {
  return std::min(std::chrono::milliseconds(250), ttl / 8);
}

// Plain functions for what the coroutines log: g++ 12 mishandles string literals handed to
// templates inside a coroutine.
void LogEtcdTrouble(const std::string& what, const Status& s) {
  spdlog::warn("cluster: {}: {}", what, s.ToString());
}

// Runs this program again with `argv`. Every descriptor past stderr is closed on exec (the
// listening ports, the edit log, the old connections), so the new process binds its ports anew.
[[noreturn]] void Reexec(const std::vector<std::string>& argv) {
  std::vector<std::string> args = argv;
  std::vector<char*> raw;
  for (std::string& a : args) raw.push_back(a.data());
  raw.push_back(nullptr);
  spdlog::warn("cluster: restarting ({}) on the standby copy", args.empty() ? "?" : args[0]);
  spdlog::default_logger()->flush();
  if (::close_range(3, ~0U, CLOSE_RANGE_CLOEXEC) != 0) {
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator("/proc/self/fd", ec)) {
      const int fd = std::atoi(e.path().filename().c_str());
      if (fd > 2) (void)::fcntl(fd, F_SETFD, FD_CLOEXEC);
    }
  }
  ::execv("/proc/self/exe", raw.data());
  spdlog::critical("cluster: cannot restart after the promotion: execv failed; exiting so a "
                   "supervisor starts sculptd again");
  spdlog::default_logger()->flush();
  std::_Exit(75);
}

// "<lease id>:<pid>" of kResumeLeaseEnv: the lease when the PID is this process's, else 0
// (`why` says what was wrong with a token that names another process or does not parse).
int64_t ParseResumeToken(const std::string& token, std::string* why) {
  const size_t colon = token.find(':');
  int64_t lease = 0;
  long pid = 0;
  try {
    lease = std::stoll(token.substr(0, colon));
    pid = colon == std::string::npos ? 0 : std::stol(token.substr(colon + 1));
  } catch (...) {
    lease = 0;
  }
  if (lease != 0 && pid == static_cast<long>(::getpid())) return lease;
  *why = "not a lease of this process (pid " + std::to_string(::getpid()) + ")";
  return 0;
}

}  // namespace

int64_t ResumableLease() {
  const char* env = std::getenv(kResumeLeaseEnv);
  if (env == nullptr) return 0;
  std::string why;
  return ParseResumeToken(env, &why);
}

std::unique_ptr<ResumedLeaseKeeper> ResumedLeaseKeeper::StartIfResuming(
    const ClusterConfig& config, std::chrono::milliseconds limit) {
  const int64_t lease = ResumableLease();
  if (lease == 0) return nullptr;
  const auto every = std::chrono::milliseconds(std::max(50, config.lease_ttl_ms / 4));
  auto client = EtcdClient::Create({config.etcd, std::max(std::chrono::milliseconds(100), every),
                                    config.etcd_ca_file, config.etcd_cert_file,
                                    config.etcd_key_file});
  if (!client.ok()) return nullptr;
  return std::unique_ptr<ResumedLeaseKeeper>(
      new ResumedLeaseKeeper(std::move(client).value(), lease, every, limit));
}

ResumedLeaseKeeper::ResumedLeaseKeeper(std::unique_ptr<EtcdClient> etcd, int64_t lease,
                                       std::chrono::milliseconds every,
                                       std::chrono::milliseconds limit)
    : etcd_(std::move(etcd)), lease_(lease) {
  thread_ = std::thread([this, every, limit] { Run(every, limit); });
}

ResumedLeaseKeeper::~ResumedLeaseKeeper() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
  spdlog::info("cluster: lease {} kept alive {} time(s) while the scenes opened after the restart",
               lease_, kept_.load());
}

void ResumedLeaseKeeper::Run(std::chrono::milliseconds every, std::chrono::milliseconds limit) {
  const auto until = Clock::now() + limit;
  std::unique_lock<std::mutex> lock(mu_);
  while (!stop_) {
    lock.unlock();
    auto ttl = etcd_->Sync(etcd_->KeepAlive(lease_));
    lock.lock();
    if (ttl.ok()) {
      ++kept_;
    } else if (ttl.status().code() == Status::Code::kNotFound) {
      LogEtcdTrouble("the lease kept across the restart is gone while the scenes open",
                     ttl.status());
      return;
    } else {
      LogEtcdTrouble("keeping the lease alive while the scenes open", ttl.status());
    }
    if (Clock::now() + every >= until) {
      spdlog::warn("cluster: the scenes took more than {} ms to open after the restart: lease {} "
                   "is no longer kept alive until the agent starts",
                   limit.count(), lease_);
      return;
    }
    cv_.wait_for(lock, every, [&] { return stop_; });
  }
}

ClusterAgent::Slot::Slot(HostedScene h)
    : hosted(std::move(h)), fence(std::make_shared<OwnershipFence>(hosted.name)) {
  waiting_reason = "this member has not reached etcd yet";
}

ClusterAgent::ClusterAgent(ClusterConfig config, std::vector<HostedScene> scenes,
                           std::function<uint32_t()> sessions)
    : config_(std::move(config)),
      keys_{config_.prefix},
      sessions_(std::move(sessions)),
      tick_(std::max(50, config_.lease_ttl_ms / 4)) {
  for (HostedScene& h : scenes) {
    // A name given twice is one scene (one fence, one owner key).
    if (FindSlot(h.name)) continue;
    slots_.push_back(std::make_unique<Slot>(std::move(h)));
  }
}

ClusterAgent::~ClusterAgent() { Stop(); }

ClusterAgent::Slot* ClusterAgent::FindSlot(const std::string& scene) const {
  for (const auto& slot : slots_) {
    if (slot->hosted.name == scene) return slot.get();
  }
  return nullptr;
}

bool ClusterAgent::AnyFollowing() const {
  return std::any_of(slots_.begin(), slots_.end(),
                     [](const auto& slot) { return !slot->owned && slot->follower; });
}

std::shared_ptr<const OwnershipFence> ClusterAgent::fence(const std::string& scene) const {
  if (const Slot* slot = FindSlot(scene)) return slot->fence;
  // Fails closed: a scene this member does not host is never acknowledged through this agent.
  return std::make_shared<const OwnershipFence>(scene);
}

MemberRecord ClusterAgent::SelfRecord() const {
  MemberRecord m;
  m.name = config_.member;
  m.tcp = tcp_;
  m.http = http_;
  for (const auto& slot : slots_) {
    m.offers.push_back(slot->hosted.name);
    if (slot->owned) {
      m.owns.push_back(slot->hosted.name);
      m.owning.push_back({slot->hosted.name, slot->hosted.seq ? slot->hosted.seq() : 0,
                          slot->hosted.acks_async && slot->hosted.acks_async()});
    }
    if (slot->follower && slot->follower->ready()) {
      // Read now, not at the last tick: an owner moving its scene here waits on this figure.
      m.following.push_back({slot->hosted.name, slot->follower->durable_seq(), false,
                             slot->follower->divergences()});
    }
  }
  if (!m.owning.empty()) {
    m.scene_seq = m.owning.front().seq;
    m.acks_async = m.owning.front().acks_async;
  }
  if (!m.following.empty()) {
    m.follows = m.following.front().scene;
    m.follow_seq = m.following.front().seq;
  }
  m.sessions = sessions_ ? sessions_() : 0;
  m.standby = standby_.has_value();
  return m;
}

Status ClusterAgent::Start(const std::string& tcp, const std::string& http) {
  if (started_) return FailedPrecondition("ClusterAgent started twice");
  if (slots_.empty()) return InvalidArgument("ClusterAgent: no scene to host");
  auto client = EtcdClient::Create({config_.etcd, std::max(std::chrono::milliseconds(100), tick_),
                                    config_.etcd_ca_file, config_.etcd_cert_file,
                                    config_.etcd_key_file});
  if (!client.ok()) return client.status();
  etcd_ = std::move(client).value();
  tcp_ = tcp;
  http_ = http;
  started_ = true;
  // A promotion's restart (Promote, execv) left its lease here. Honoured only by the same process
  // (execv keeps the PID): then the image that held the lease no longer runs, so no other image
  // can acknowledge anything under it. Read once; a child of this process never inherits it.
  int64_t resume = 0;
  if (const char* env = std::getenv(kResumeLeaseEnv); env != nullptr) {
    const std::string token = env;
    ::unsetenv(kResumeLeaseEnv);
    std::string why;
    resume = ParseResumeToken(token, &why);
    if (resume == 0) spdlog::warn("cluster: {}={} ignored: {}", kResumeLeaseEnv, token, why);
  }
  // A loaded etcd (an fsync behind other writers) may answer one call later than the timeout:
  // an unanswered registration is tried again for up to 10 s before the start fails (under ASan
  // on 2 loaded cores a member exited on one timed-out put). Each try may resume the lease.
  Status registered = etcd_->Sync(Register(resume));
  const auto give_up = Clock::now() + std::chrono::seconds(10);
  while (!registered.ok() && registered.code() == Status::Code::kUnavailable &&
         Clock::now() < give_up) {
    LogEtcdTrouble("registering (trying again)", registered);
    std::this_thread::sleep_for(tick_);
    registered = etcd_->Sync(Register(resume));
  }
  if (!registered.ok()) {
    std::string list;
    for (const std::string& e : config_.etcd) list += (list.empty() ? "" : ", ") + e;
    // The check to try, with the TLS files this member uses (etcdctl needs them too).
    std::string etcdctl = "etcdctl --endpoints " + list;
    if (!config_.etcd_ca_file.empty()) etcdctl += " --cacert " + config_.etcd_ca_file;
    if (!config_.etcd_cert_file.empty()) {
      etcdctl += " --cert " + config_.etcd_cert_file + " --key " + config_.etcd_key_file;
    }
    return Status(registered.code(), "cluster: cannot register member " + config_.member +
                                         " with etcd at " + list + ": " + registered.message() +
                                         " (is etcd running? `" + etcdctl +
                                         " endpoint health`)");
  }
  place_from_ = Clock::now() + tick_;
  spdlog::info("cluster: member {} registered (tcp {}, http {}), lease TTL {} ms, {} scene{}{}",
               config_.member, tcp_, http_.empty() ? "off" : http_, config_.lease_ttl_ms,
               slots_.size(), slots_.size() == 1 ? "" : "s",
               resumed_ ? ", the lease kept across the restart" : "");
  // The routing table is filled before the first client can be told this member's ports.
  if (const Status read = etcd_->Sync(Refresh()); !read.ok())
    LogEtcdTrouble("reading the cluster", read);
  timer_ = std::make_unique<asio::steady_timer>(etcd_->io());
  keep_alive_timer_ = std::make_unique<asio::steady_timer>(etcd_->io());
  asio::co_spawn(etcd_->io(), KeepAliveLoop(), asio::detached);
  asio::co_spawn(etcd_->io(), Loop(), asio::detached);
  return Status::Ok();
}

std::string ClusterAgent::ResumeToken() const {
  const int64_t lease = lease_.load();
  if (lease == 0) return {};
  return std::to_string(lease) + ":" + std::to_string(::getpid());
}

void ClusterAgent::EnableStandby(StandbyOptions options) {
  if (!started_ && config_.standby) standby_ = std::move(options);
}

void ClusterAgent::RetireFollower(Slot& slot) {
  std::lock_guard<std::mutex> lock(retired_mu_);
  // Threads of followers already stopped are joined (a standby retrying a dead owner retires
  // one per attempt).
  for (auto it = retired_.begin(); it != retired_.end();) {
    if (it->done->load()) {
      it->thread.join();
      it = retired_.erase(it);
    } else {
      ++it;
    }
  }
  if (!slot.follower) return;
  // Its destructor may wait for a connect to time out: not on the agent's thread, whose
  // keep-alives must not stall.
  auto done = std::make_shared<std::atomic<bool>>(false);
  retired_.push_back({std::thread([f = std::shared_ptr<StandbyFollower>(std::move(slot.follower)),
                                   done]() mutable {
                        f.reset();
                        done->store(true);
                      }),
                      done});
}

void ClusterAgent::Stop() { Shutdown(/*revoke_lease=*/true); }

void ClusterAgent::Abandon() { Shutdown(/*revoke_lease=*/false); }

void ClusterAgent::Shutdown(bool revoke_lease) {
  if (stopping_.exchange(true)) return;
  for (const auto& slot : slots_) {
    slot->fence->Revoke();
    slot->owned_epoch = 0;
  }
  if (!etcd_) return;
  asio::post(etcd_->io(), [this] {
    if (timer_) timer_->cancel();
    if (keep_alive_timer_) keep_alive_timer_->cancel();
  });
  if (revoke_lease) {
    // Our keys go now rather than after the TTL: other members see this one leave at once. The
    // epoch records stay: this member, restarted, takes its scenes back with epoch + 1.
    auto revoke = [this]() -> asio::awaitable<Status> {
      if (lease_ == 0) co_return Status::Ok();
      auto call = etcd_->Revoke(lease_);
      co_return co_await std::move(call);
    };
    const Status s = etcd_->Sync(revoke());
    if (!s.ok())
      spdlog::warn("cluster: lease not revoked at stop ({}); it expires by itself", s.ToString());
  }
  etcd_->Halt();     // joins the agent's thread; the io_context (and the loop's frame) stays
  timer_.reset();    // before its io_context: a timer's service must outlive it
  keep_alive_timer_.reset();
  etcd_.reset();     // the loop's frame goes with its io_context
  for (const auto& slot : slots_) {
    slot->fence->Revoke();  // again: an acquisition may have completed while the lease went
    RetireFollower(*slot);
  }
  std::lock_guard<std::mutex> lock(retired_mu_);
  for (Retired& r : retired_) r.thread.join();
  retired_.clear();
}

asio::awaitable<Status> ClusterAgent::Register(int64_t resume) {
  if (resume != 0) {
    // The lease of the image before the execv: kept only if etcd still keeps it alive (then
    // every key under it, owner keys included, is still there: nobody else can have taken a
    // scene it owned).
    const auto sent = Clock::now();
    auto ttl_call = etcd_->KeepAlive(resume);
    auto ttl = co_await std::move(ttl_call);
    if (ttl.ok()) {
      lease_ = resume;
      resumed_ = true;
      const auto t = std::min(*ttl, std::chrono::milliseconds(config_.lease_ttl_ms));
      lease_valid_until_ = sent + t - Margin(t);
      auto put_call =
          etcd_->Put({keys_.Member(config_.member), EncodeMember(SelfRecord()), lease_});
      auto put = co_await std::move(put_call);
      co_return put.status();
    }
    LogEtcdTrouble("the lease kept across the restart is gone; registering anew", ttl.status());
  }
  const auto sent = Clock::now();
  auto lease_call = etcd_->Grant(std::chrono::milliseconds(config_.lease_ttl_ms));
  auto lease = co_await std::move(lease_call);
  if (!lease.ok()) co_return lease.status();
  lease_ = lease->id;
  // The fence follows the TTL asked for when etcd granted more (its minimum is 2 s).
  const auto ttl = std::min(lease->ttl, std::chrono::milliseconds(config_.lease_ttl_ms));
  lease_valid_until_ = sent + ttl - Margin(ttl);
  auto put_call = etcd_->Put({keys_.Member(config_.member), EncodeMember(SelfRecord()), lease_});
  auto put = co_await std::move(put_call);
  co_return put.status();
}

asio::awaitable<void> ClusterAgent::Loop() {
  // A standby following an owner reads the owner keys it follows every fast tick between two
  // full ticks: the takeover then starts within a fast tick of the owner's lease running out in
  // etcd, not up to a whole tick later (a quarter of the failover budget at the default TTL).
  const auto fast_tick = std::max(std::chrono::milliseconds(20), tick_ / 5);
  while (!stopping_) {
    co_await Tick();
    const auto next_full = Clock::now() + tick_;
    boost::system::error_code ec;
    bool full_now = false;
    while (!stopping_ && !full_now && AnyFollowing() && Clock::now() + fast_tick < next_full) {
      timer_->expires_after(fast_tick);
      co_await timer_->async_wait(asio::redirect_error(asio::use_awaitable, ec));
      if (stopping_) co_return;
      for (const auto& slot : slots_) {
        if (slot->owned || !slot->follower) continue;
        auto owner_call = etcd_->Get(keys_.Owner(slot->hosted.name));
        auto owner = co_await std::move(owner_call);
        if (stopping_) co_return;
        if (owner.ok() && !owner->has_value()) {
          full_now = true;  // gone: the full tick takes it over now
          break;
        }
        if (owner.ok()) {
          // A newer epoch than the one followed (epochs only grow): a new owner. The full tick
          // reads the scene's keys (checked against each other), stops the old follow and
          // follows the new owner now.
          auto o = DecodeOwner((*owner)->value);
          if (o.ok() && slot->follower && o->epoch > slot->follower->expected_epoch()) {
            full_now = true;
            break;
          }
        }
      }
    }
    if (stopping_) co_return;
    if (Clock::now() < next_full && !full_now) {
      timer_->expires_at(next_full);
      co_await timer_->async_wait(asio::redirect_error(asio::use_awaitable, ec));
    }
  }
}

asio::awaitable<void> ClusterAgent::KeepAliveLoop() {
  // Every tick from when the last keep-alive was sent, whatever the rest of the loop is doing:
  // a tick's etcd calls grow with the scenes hosted and followed (acquisitions, standby names,
  // a followed owner key read every fast tick), and on a slow member they took longer than the
  // lease once the keep-alive waited behind them (docs/sanitizers.md, 2026-12-07).
  boost::system::error_code ec;
  auto next = Clock::now() + tick_;
  while (!stopping_) {
    keep_alive_timer_->expires_at(next);
    co_await keep_alive_timer_->async_wait(asio::redirect_error(asio::use_awaitable, ec));
    if (stopping_) co_return;
    next = Clock::now() + tick_;
    co_await KeepLeaseAlive();
  }
}

asio::awaitable<void> ClusterAgent::Tick() {
  const Status refreshed = co_await Refresh();
  if (!refreshed.ok()) {
    ++etcd_failures_;
    LogEtcdTrouble("reading the cluster", refreshed);
    co_return;
  }
  if (stopping_) co_return;
  // Placement of the never-owned scenes, one pass over all of them (PlaceScenes): every member
  // reading the same records picks the same member for each, and several new scenes spread.
  std::map<std::string, std::string> picks;
  {
    std::lock_guard<std::mutex> lock(mu_);
    std::vector<std::string> never_owned;
    for (const MemberRecord& m : members_) {
      for (const std::string& scene : m.offers) {
        const auto it = scenes_.find(scene);
        if (it == scenes_.end() || (!it->second.epoch && !it->second.owner)) {
          never_owned.push_back(scene);
        }
      }
    }
    picks = PlaceScenes(members_, never_owned);
  }
  const bool may_place = Clock::now() >= place_from_;
  for (const auto& slot : slots_) {
    co_await MaybeAcquire(*slot, picks, may_place);
    if (stopping_) co_return;
  }
  std::vector<std::pair<Slot*, uint64_t>> promote;
  for (const auto& slot : slots_) {
    auto tend_call = TendStandby(*slot);
    const std::optional<uint64_t> dead = co_await std::move(tend_call);
    if (stopping_) co_return;
    if (dead) promote.emplace_back(slot.get(), *dead);
  }
  if (!promote.empty()) {
    co_await Promote(std::move(promote));
    if (stopping_) co_return;
  }
  for (const auto& slot : slots_) {
    co_await TendMove(*slot);
    if (stopping_) co_return;
  }
}

asio::awaitable<void> ClusterAgent::KeepLeaseAlive() {
  const auto sent = Clock::now();
  const int64_t lease = lease_;
  auto ttl_call = etcd_->KeepAlive(lease);
  auto ttl = co_await std::move(ttl_call);
  if (lease != lease_) co_return;  // registered anew meanwhile: this answer is of the old lease
  if (ttl.ok()) {
    const auto t = std::min(*ttl, std::chrono::milliseconds(config_.lease_ttl_ms));
    const auto now = Clock::now();
    if (lease_valid_until_ != Clock::time_point{} && now > lease_valid_until_) {
      // The fences had run out: the scenes acknowledged nothing for this long.
      spdlog::warn("cluster: lease keep-alive answered {} ms after the fences ran out (sent {} ms "
                   "before): a slow member or etcd",
                   std::chrono::duration_cast<std::chrono::milliseconds>(now - lease_valid_until_)
                       .count(),
                   std::chrono::duration_cast<std::chrono::milliseconds>(now - sent).count());
    }
    lease_valid_until_ = sent + t - Margin(t);
    for (const auto& slot : slots_) {
      if (slot->owned) slot->fence->Extend(lease_valid_until_);
    }
    co_return;
  }
  if (ttl.status().code() != Status::Code::kNotFound) {
    // etcd out of reach: the fences run out by themselves at lease_valid_until_.
    ++etcd_failures_;
    LogEtcdTrouble("lease keep-alive", ttl.status());
    co_return;
  }
  // The lease is gone (we were cut off past its TTL, or Stop revoked it): so is every key under
  // it.
  for (const auto& slot : slots_) {
    if (slot->owned) LoseOwnership(*slot, "its lease expired in etcd");
  }
  if (stopping_) co_return;
  LogEtcdTrouble("lease expired; registering again", ttl.status());
  const Status again = co_await Register(/*resume=*/0);
  if (!again.ok()) LogEtcdTrouble("registering again", again);
}

asio::awaitable<Status> ClusterAgent::Refresh() {
  auto put_call = etcd_->Put({keys_.Member(config_.member), EncodeMember(SelfRecord()), lease_});
  auto put = co_await std::move(put_call);
  if (!put.ok()) co_return put.status();
  // Members and scenes in one range, so at one revision: an acquisition writes the owner's
  // member record (its `owns`) in the txn that writes the scene's keys, so every member's view
  // counts a scene as owned exactly when it counts it in its owner's load, and placement
  // computed from two views of one revision agrees.
  auto all_call = etcd_->GetPrefix(keys_.prefix);
  auto all = co_await std::move(all_call);
  if (!all.ok()) co_return all.status();

  std::vector<MemberRecord> live;
  std::map<std::string, SceneState> table;
  const std::string members_prefix = keys_.Members();
  for (const KeyValue& kv : *all) {
    if (kv.key.compare(0, members_prefix.size(), members_prefix) == 0) {
      auto m = DecodeMember(kv.value);
      // Another member's record is untrusted input: a bad one is skipped, never fatal.
      if (m.ok() && kv.key == keys_.Member(m->name)) live.push_back(std::move(m).value());
      continue;
    }
    std::string scene, kind;
    if (!keys_.ParseSceneKey(kv.key, &scene, &kind)) continue;
    SceneState& st = table[scene];
    if (kind == "standby") {
      auto sb = DecodeStandby(kv.value);
      if (sb.ok()) {
        st.standby = std::move(sb).value();
        st.standby_mod_revision = kv.mod_revision;
      }
    } else if (kind == "move") {
      auto mv = DecodeMove(kv.value);
      if (mv.ok()) {
        st.move = std::move(mv).value();
        st.move_mod_revision = kv.mod_revision;
      }
    } else if (kind == "owner") {
      // An owner key not under a lease would outlive its owner: not honoured.
      auto o = DecodeOwner(kv.value);
      if (o.ok() && kv.lease != 0) {
        st.owner = std::move(o).value();
        st.owner_lease = kv.lease;
      }
    } else {
      auto e = DecodeEpoch(kv.value);
      if (e.ok()) {
        st.epoch = std::move(e).value();
        st.epoch_mod_revision = kv.mod_revision;
      }
    }
  }
  // An acquisition writes the owner key and the epoch record in one txn, so they agree: an owner
  // key that names another member or epoch than the scene's epoch record was not written by an
  // acquisition (a forged or stale claim) and is never routed to.
  for (auto& [scene, st] : table) {
    if (st.owner && (!st.epoch || st.epoch->member != st.owner->member ||
                     st.epoch->epoch != st.owner->epoch)) {
      spdlog::warn("cluster: scene {}: owner key names {} at epoch {} but its epoch record {}: "
                   "not honoured",
                   scene, st.owner->member, st.owner->epoch,
                   st.epoch ? "names " + st.epoch->member + " at epoch " +
                                  std::to_string(st.epoch->epoch)
                            : std::string("is missing"));
      st.owner.reset();
      st.owner_lease = 0;
    }
  }
  std::lock_guard<std::mutex> lock(mu_);
  members_ = std::move(live);
  scenes_ = std::move(table);
  co_return Status::Ok();
}

void ClusterAgent::LoseOwnership(Slot& slot, const std::string& why) {
  ++ownership_losses_;
  slot.fence->Revoke();
  slot.owned = false;
  slot.owned_epoch = 0;
  spdlog::error("cluster: member {} no longer owns scene {} ({}): acknowledging nothing for it",
                config_.member, slot.hosted.name, why);
}

std::pair<ClusterAgent::SceneState, std::vector<MemberRecord>> ClusterAgent::ReadTable(
    const std::string& scene) const {
  std::lock_guard<std::mutex> lock(mu_);
  const auto it = scenes_.find(scene);
  return {it != scenes_.end() ? it->second : SceneState{}, members_};
}

asio::awaitable<void> ClusterAgent::MaybeAcquire(Slot& slot,
                                                 const std::map<std::string, std::string>& picks,
                                                 bool may_place) {
  const std::string& scene = slot.hosted.name;
  const auto [st, members] = ReadTable(scene);
  if (slot.owned) {
    const bool ours = st.owner && st.owner->member == config_.member &&
                      st.owner->epoch == slot.owned_epoch.load();
    if (!ours) LoseOwnership(slot, "its owner key is gone or names another member");
    co_return;
  }
  if (st.owner && st.owner->member == config_.member && st.owner_lease == lease_.load()) {
    // The owner key names this member under the lease it holds now, with the epoch record of an
    // acquisition: this member acquired the scene under this lease. Either the process image
    // before a promotion's execv did (Start resumed its lease), or this image's acquire txn
    // succeeded and its answer was lost. No other image holds the lease (execv replaced the one
    // that did), the key could not have been taken from it while the lease lived, and the data
    // directory is the one the acquisition served from: owned again at the same epoch, without
    // a new one.
    slot.owned = true;
    slot.owned_epoch = st.owner->epoch;
    slot.fence->Grant(st.owner->epoch, lease_valid_until_);
    {
      std::lock_guard<std::mutex> lock(mu_);
      slot.waiting_reason.clear();
    }
    spdlog::info("cluster: member {} owns scene {} again at epoch {} (its owner key under lease "
                 "{}{})",
                 config_.member, scene, st.owner->epoch, lease_.load(),
                 resumed_ ? ", kept across the restart" : "");
    auto put_call =
        etcd_->Put({keys_.Member(config_.member), EncodeMember(SelfRecord()), lease_});
    auto put = co_await std::move(put_call);
    if (!put.ok()) LogEtcdTrouble("publishing the load", put.status());
    co_return;
  }
  if (st.owner) co_return;  // another member serves it; RouteScene redirects there
  // Who may take a scene without an owner: the member that held it last (it has the data; a
  // restart or a lease lost while cut off), or, for a scene never owned, the placement's pick.
  // A scene whose last owner is another member waits for it, except for the standby that owner
  // named, once its copy is this member's data directory (Promote, then this process restarted
  // on it).
  std::string reason;
  bool promoted = false;
  if (st.epoch) {
    if (st.epoch->member != config_.member) {
      const bool named = st.standby && st.standby->member == config_.member;
      promoted = named && standby_ &&
                 PromotedFromEpoch(slot.hosted.data_dir, scene) == st.epoch->epoch;
      if (!promoted) {
        reason = "its last owner " + st.epoch->member + " (epoch " +
                 std::to_string(st.epoch->epoch) + ") is gone" +
                 (st.standby ? "; its standby " + st.standby->member +
                                   (named ? " (this member) is taking it over"
                                          : " may take it over")
                             : "; it had no standby that followed its edits");
      }
    } else if (st.move && st.move->released && st.move->epoch == st.epoch->epoch &&
               st.move->member != config_.member) {
      // This member released the scene for a move: the target takes it over from its copy. It
      // is taken back only if the request is removed (`sculpt cluster move` timed out).
      reason = "it is being moved to member " + st.move->member +
               ", which takes it over from its copy";
    }
  } else if (const auto pick = picks.find(scene);
             pick != picks.end() && pick->second != config_.member) {
    reason = "placed on member " + pick->second + ", which has not taken it yet";
  } else if (pick == picks.end()) {
    reason = "no live member offers it yet";  // this member's record not read back yet
  } else if (!may_place) {
    reason = "this member places new scenes once the members starting with it are registered";
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    slot.waiting_reason = reason.empty() ? "being acquired by this member" : reason;
  }
  if (!reason.empty()) co_return;

  const uint64_t epoch = (st.epoch ? st.epoch->epoch : 0) + 1;
  OwnerRecord owner{config_.member, tcp_, http_, epoch};
  TxnRequest txn;
  // Nobody owns it, and nobody bumped the epoch since we read it.
  txn.compares = {{keys_.Owner(scene), Compare::Target::kCreateRevision, 0},
                  {keys_.Epoch(scene), Compare::Target::kModRevision, st.epoch_mod_revision}};
  // The standby named when we read (a promotion is the named standby's only).
  if (st.standby) {
    txn.compares.push_back(
        {keys_.Standby(scene), Compare::Target::kModRevision, st.standby_mod_revision});
  }
  // This member's record with the scene among its owned ones, in the same txn (see Refresh).
  MemberRecord self = SelfRecord();
  self.owns.push_back(scene);
  self.owning.push_back({scene, slot.hosted.seq ? slot.hosted.seq() : 0,
                         slot.hosted.acks_async && slot.hosted.acks_async()});
  self.scene_seq = self.owning.front().seq;
  self.acks_async = self.owning.front().acks_async;
  txn.success = {{keys_.Owner(scene), EncodeOwner(owner), lease_},
                 {keys_.Epoch(scene), EncodeEpoch({epoch, config_.member}), 0},
                 {keys_.Member(config_.member), EncodeMember(self), lease_}};
  auto r_call = etcd_->Txn(std::move(txn));
  auto r = co_await std::move(r_call);
  if (!r.ok()) {
    LogEtcdTrouble("acquiring scene " + scene, r.status());
    co_return;
  }
  if (!r->succeeded) co_return;  // another member was faster; the next Refresh shows it
  if (stopping_) co_return;      // Stop revokes the lease: the owner key goes with it
  slot.owned = true;
  slot.owned_epoch = epoch;
  slot.fence->Grant(epoch, lease_valid_until_);
  {
    std::lock_guard<std::mutex> lock(mu_);
    SceneState& mine = scenes_[scene];
    mine.owner = owner;
    mine.owner_lease = lease_;
    mine.epoch = EpochRecord{epoch, config_.member};
    slot.waiting_reason.clear();
  }
  spdlog::info("cluster: member {} owns scene {} at epoch {}{}", config_.member, scene, epoch,
               promoted ? " (took it over as the standby)" : "");
  ClearPromotedMarker(slot.hosted.data_dir);
  RetireFollower(slot);
  // The new load right away, so placement elsewhere sees it before the next tick.
  auto put_call = etcd_->Put({keys_.Member(config_.member), EncodeMember(SelfRecord()), lease_});
  auto put = co_await std::move(put_call);
  if (!put.ok()) LogEtcdTrouble("publishing the load", put.status());
}

asio::awaitable<std::optional<uint64_t>> ClusterAgent::TendStandby(Slot& slot) {
  const std::string& scene = slot.hosted.name;
  const auto [st, members] = ReadTable(scene);
  if (slot.owned) {
    RetireFollower(slot);
    if (config_.replication == "none") {
      // No standby: nobody follows, and a standby named under an earlier setting is dropped, so
      // no member takes the scene over from a copy this owner no longer feeds.
      if (st.standby) {
        auto del_call = etcd_->Delete(keys_.Standby(scene));
        auto del = co_await std::move(del_call);
        if (!del.ok()) LogEtcdTrouble("removing the standby (replication = none)", del.status());
      }
      co_return std::nullopt;
    }
    // The standby: the one named while it lives and may follow, else the least loaded other
    // live member that offers the scene and may follow (owned plus followed scenes).
    std::vector<MemberRecord> candidates;
    for (const MemberRecord& m : members) {
      if (m.name != config_.member && m.standby) candidates.push_back(m);
    }
    const bool keep = st.standby && std::any_of(candidates.begin(), candidates.end(),
                                                [&](const MemberRecord& m) {
                                                  return m.name == st.standby->member;
                                                });
    if (keep) co_return std::nullopt;
    const auto picks = PickStandbys(candidates, {scene});
    const auto pick = picks.find(scene);
    if (pick == picks.end()) co_return std::nullopt;
    StandbyRecord record{pick->second, slot.owned_epoch.load()};
    auto put_call = etcd_->Put({keys_.Standby(scene), EncodeStandby(record), 0});
    auto put = co_await std::move(put_call);
    if (!put.ok()) {
      LogEtcdTrouble("naming a standby", put.status());
    } else {
      spdlog::info("cluster: member {} is the standby of scene {} (epoch {})", pick->second,
                   scene, record.epoch);
      // Routing knows at once, not at the next Refresh: the standby may subscribe before it, and
      // its session is told apart by this name (its progress reports and the resend table that
      // comes with its region load). The member's load counts it too, so the next scene's
      // standby this tick goes elsewhere when it can.
      std::lock_guard<std::mutex> lock(mu_);
      scenes_[scene].standby = record;
      for (MemberRecord& m : members_) {
        if (m.name == pick->second) m.following.push_back({scene, 0, false});
      }
    }
    co_return std::nullopt;
  }
  // Fencing: the follow takes only the epoch etcd names. Once the scene's epoch moved on (a new
  // owner, or none yet), the old owner's stream is refused at once, also while this member waits
  // for the new owner or stops following.
  if (slot.follower && st.epoch && st.epoch->epoch != slot.follower->options().owner_epoch) {
    slot.follower->Supersede(st.epoch->epoch);
  }
  const bool named = standby_ && st.standby && st.standby->member == config_.member;
  if (!named) {
    RetireFollower(slot);
    co_return std::nullopt;
  }
  if (st.owner && st.owner->member != config_.member) {
    // Follow the owner; a new follow when the owner changed or the last one ended.
    const bool same_owner = slot.follower && slot.follower->options().owner_tcp == st.owner->tcp &&
                            slot.follower->options().owner_epoch == st.owner->epoch;
    const bool current = same_owner && !slot.follower->finished();
    const auto now = Clock::now();
    if (slot.follower && slot.follower->finished() && slot.ended_at == Clock::time_point{}) {
      spdlog::warn("cluster: following scene {} ended: {}", scene, slot.follower->failure());
      slot.ended_at = now;
    }
    // The same owner again only after a pause (a follow that fails at once, e.g. a scene of
    // several objects, must not reconnect every tick); a new owner at once.
    const bool wait = same_owner && !current && now - slot.ended_at < std::chrono::seconds(2);
    if (!current && !wait) {
      slot.ended_at = {};
      RetireFollower(slot);
      FollowerOptions fo;
      fo.data_dir = standby_->data_dir;
      fo.scene = scene;
      fo.member = config_.member;
      // The members' peer token when the cluster has one (the owner then takes only a session
      // that presented it for its standby); else the viewer token.
      fo.token = config_.peer_token.empty() ? standby_->token : config_.peer_token;
      fo.owner_tcp = st.owner->tcp;
      fo.tls = standby_->tls;
      fo.owner_epoch = st.owner->epoch;
      fo.stale_epoch_refusals = stale_epoch_refusals_;
      fo.divergences = standby_divergences_;
      fo.snapshot_every_records = standby_->snapshot_every_edits;
      fo.books = slot.hosted.books;
      slot.follower = std::make_unique<StandbyFollower>(std::move(fo));
    }
    if (slot.follower && slot.follower->ready()) slot.follow_seq = slot.follower->durable_seq();
    co_return std::nullopt;
  }
  if (st.owner || !st.epoch || st.epoch->member == config_.member) co_return std::nullopt;
  if (PromotedFromEpoch(slot.hosted.data_dir, scene) == st.epoch->epoch) {
    co_return std::nullopt;  // acquiring
  }
  // The owner is gone and this member is its standby: take over with the copy of that epoch.
  uint64_t copy_epoch = 0;
  if (!CurrentStandbyCopy(standby_->data_dir, scene, &copy_epoch) ||
      copy_epoch != st.epoch->epoch) {
    std::lock_guard<std::mutex> lock(mu_);
    slot.waiting_reason = "its last owner " + st.epoch->member + " (epoch " +
                          std::to_string(st.epoch->epoch) +
                          ") is gone and this member, its standby, holds no copy of that epoch";
    co_return std::nullopt;
  }
  co_return st.epoch->epoch;
}

asio::awaitable<void> ClusterAgent::Promote(std::vector<std::pair<Slot*, uint64_t>> promote) {
  if (standby_->restart_argv.empty()) {
    LogEtcdTrouble("promotion", FailedPrecondition("no command line to restart with"));
    co_return;
  }
  size_t promoted = 0;
  for (auto& [slot, dead_epoch] : promote) {
    spdlog::warn("cluster: the owner of scene {} (epoch {}) is gone: member {}, its standby, "
                 "takes it over",
                 slot->hosted.name, dead_epoch, config_.member);
    // Its log made durable and closed before the files move (the connection is gone already).
    // Both block (a sync, renames, fsyncs: 2 s on a loaded machine), so they run on a thread of
    // their own that owns what it touches, and the keep-alive loop goes on meanwhile: on this
    // thread they once outlasted the lease, and the member's other scenes went with it. The
    // thread is kept with the retired followers' threads, so a stop during the promotion waits
    // for the files to be moved rather than exiting in the middle of it.
    struct Work {
      std::unique_ptr<StandbyFollower> follower;
      std::string standby_dir, scene, data_dir;
      uint64_t epoch = 0;
      Status status;
    };
    auto work = std::make_shared<Work>();
    work->follower = std::move(slot->follower);
    work->standby_dir = standby_->data_dir;
    work->scene = slot->hosted.name;
    work->data_dir = slot->hosted.data_dir;
    work->epoch = dead_epoch;
    auto done = std::make_shared<std::atomic<bool>>(false);
    {
      std::lock_guard<std::mutex> lock(retired_mu_);
      retired_.push_back({std::thread([work, done] {
                            work->follower.reset();
                            work->status = PromoteStandbyCopy(work->standby_dir, work->scene,
                                                              work->data_dir, work->epoch);
                            done->store(true);
                          }),
                          done});
    }
    boost::system::error_code ec;
    asio::steady_timer wait(etcd_->io());
    while (!done->load()) {
      wait.expires_after(std::chrono::milliseconds(10));
      co_await wait.async_wait(asio::redirect_error(asio::use_awaitable, ec));
    }
    if (stopping_) co_return;
    if (!work->status.ok()) {
      LogEtcdTrouble("promotion of scene " + slot->hosted.name, work->status);
      continue;
    }
    ++promoted;
  }
  if (promoted == 0) co_return;
  // The restart keeps the lease (and with it this member's record and the owner keys of the
  // scenes it owns): revoking it would leave those scenes without an owner for the restart and
  // invite their standbys to take them over. The restarted process resumes the lease if it still
  // lives (Start, Register); the promoted scenes are acquired with epoch + 1 from their marker.
  // Safety: from here on this image acknowledges nothing (every fence revoked), and execv
  // replaces it in the same process, so the one image that may use the lease afterwards is the
  // restarted one, which opens the same data directories (docs/cluster.md, "Lease resume").
  for (const auto& slot : slots_) slot->fence->Revoke();
  const std::string token = ResumeToken();
  if (::setenv(kResumeLeaseEnv, token.c_str(), 1) != 0) {
    // Without it the restart registers a new lease; the owned scenes come back with epoch + 1
    // once the old lease expires (unless their standbys are faster).
    LogEtcdTrouble("promotion", Internal("cannot set " + std::string(kResumeLeaseEnv)));
  }
  // A fresh keep-alive: the restart has the whole TTL to reach etcd again.
  auto ttl_call = etcd_->KeepAlive(lease_);
  auto ttl = co_await std::move(ttl_call);
  if (!ttl.ok()) LogEtcdTrouble("keeping the lease alive before the restart", ttl.status());
  Reexec(standby_->restart_argv);
}

asio::awaitable<void> ClusterAgent::TendMove(Slot& slot) {
  const std::string& scene = slot.hosted.name;
  const auto [st, members] = ReadTable(scene);
  if (!slot.owned) {
    // Ownership lost meanwhile (LoseOwnership fenced already) or released: nothing to undo.
    slot.move_fenced = false;
    slot.move_mark.reset();
    co_return;
  }
  if (!st.move) {
    ResumeAfterMove(slot, "its move request was removed");
    slot.move_target.clear();
    co_return;
  }
  const MoveRecord& mv = *st.move;
  const uint64_t epoch = slot.owned_epoch.load();
  const auto target = std::find_if(members.begin(), members.end(),
                                   [&](const MemberRecord& m) { return m.name == mv.member; });
  const auto limit = std::max(std::chrono::milliseconds(10000), 4 * tick_);
  // A request this member cannot carry out is removed, with the reason in the log.
  std::string why;
  if (mv.member == config_.member) {
    why = mv.epoch < epoch ? "done, this member took it over at epoch " + std::to_string(epoch)
                           : "this member already owns it (epoch " + std::to_string(epoch) + ")";
  } else if (mv.epoch != epoch) {
    why = "its epoch " + std::to_string(mv.epoch) + " is stale (this member owns the scene at " +
          "epoch " + std::to_string(epoch) + ")";
  } else if (target == members.end()) {
    why = "member " + mv.member + " is not a live member";
  } else if (!target->standby) {
    why = "member " + mv.member + " may not follow a scene (its cluster.standby is false)";
  } else if (std::find(target->offers.begin(), target->offers.end(), scene) ==
             target->offers.end()) {
    why = "member " + mv.member + " does not offer scene " + scene;
  } else if (config_.replication == "none") {
    why = "the scene has replication = \"none\": no standby follows it";
  } else if (!slot.hosted.seq) {
    why = "this member cannot read its scene's sequence";
  } else if (slot.move_fenced && Clock::now() - slot.move_fenced_at > limit) {
    why = "member " + mv.member + "'s copy did not reach the last sequence within " +
          std::to_string(limit.count()) + " ms of the fence";
  }
  if (!why.empty()) {
    co_await DropMove(slot, st.move_mod_revision, mv.member, why);
    co_return;
  }
  if (slot.move_target != mv.member) {
    slot.move_target = mv.member;
    slot.move_mark.reset();
    spdlog::info("cluster: moving scene {} (epoch {}) to member {} as requested", scene, epoch,
                 mv.member);
  }
  if (!st.standby || st.standby->member != mv.member) {
    // The target follows first, as any standby does (TendStandby keeps it while it lives).
    StandbyRecord record{mv.member, epoch};
    auto put_call = etcd_->Put({keys_.Standby(scene), EncodeStandby(record), 0});
    auto put = co_await std::move(put_call);
    if (!put.ok()) {
      LogEtcdTrouble("naming the standby for a move", put.status());
      co_return;
    }
    spdlog::info("cluster: member {} is the standby of scene {} (epoch {}), for the move",
                 mv.member, scene, epoch);
    std::lock_guard<std::mutex> lock(mu_);
    scenes_[scene].standby = record;
    co_return;
  }
  // How far the target's copy is durable, as its member record said at its last refresh.
  const SceneProgress* follows = target->Following(scene);
  const uint64_t copy = follows ? follows->seq : 0;
  const uint64_t seq = slot.hosted.seq();
  if (!slot.move_fenced) {
    if (!follows) co_return;  // still loading its copy
    // Caught up: the copy holds what this member had when the target was first seen following,
    // so what remains after the fence is a few ticks of edits at most.
    if (!slot.move_mark) slot.move_mark = seq;
    if (copy < *slot.move_mark) co_return;
    slot.fence->Revoke();
    slot.move_fenced = true;
    slot.move_fenced_at = Clock::now();
    {
      std::lock_guard<std::mutex> lock(mu_);
      slot.moving_to = mv.member;
    }
    spdlog::info("cluster: scene {} fenced for the move to member {} (its copy holds seq {}, this "
                 "member seq {}): sequencing and acknowledging nothing more",
                 scene, mv.member, copy, seq);
    co_return;
  }
  if (copy < seq) co_return;  // the copy takes the last edits
  // Release: the owner key goes (still ours: the epoch record is unchanged since an acquisition
  // writes both) and the request says so, in one txn.
  MoveRecord released = mv;
  released.released = true;
  TxnRequest txn;
  txn.compares = {{keys_.Epoch(scene), Compare::Target::kModRevision, st.epoch_mod_revision},
                  {keys_.Move(scene), Compare::Target::kModRevision, st.move_mod_revision}};
  txn.success = {{keys_.Move(scene), EncodeMove(released), 0}};
  txn.success_deletes = {keys_.Owner(scene)};
  auto r_call = etcd_->Txn(std::move(txn));
  auto r = co_await std::move(r_call);
  if (!r.ok()) {
    LogEtcdTrouble("releasing scene " + scene + " for the move", r.status());
    co_return;
  }
  if (!r->succeeded) co_return;  // the request or the epoch changed: the next tick reads them
  slot.owned = false;
  slot.owned_epoch = 0;
  slot.move_fenced = false;
  slot.move_mark.reset();
  slot.move_target.clear();
  {
    std::lock_guard<std::mutex> lock(mu_);
    SceneState& mine = scenes_[scene];
    mine.owner.reset();
    mine.owner_lease = 0;
    mine.move = released;
    slot.moving_to.clear();
    slot.waiting_reason = "it is being moved to member " + mv.member +
                          ", which takes it over from its copy";
  }
  spdlog::info("cluster: member {} released scene {} (epoch {}, seq {}) to member {}, whose copy "
               "holds it: {} takes it over as its standby",
               config_.member, scene, epoch, seq, mv.member, mv.member);
  auto put_call = etcd_->Put({keys_.Member(config_.member), EncodeMember(SelfRecord()), lease_});
  auto put = co_await std::move(put_call);
  if (!put.ok()) LogEtcdTrouble("publishing the load", put.status());
}

asio::awaitable<void> ClusterAgent::DropMove(Slot& slot, int64_t mod_revision, std::string member,
                                             std::string why) {
  const std::string& scene = slot.hosted.name;
  // Only the request read (a newer one is judged on its own at the next tick).
  TxnRequest txn;
  txn.compares = {{keys_.Move(scene), Compare::Target::kModRevision, mod_revision}};
  txn.success_deletes = {keys_.Move(scene)};
  auto r_call = etcd_->Txn(std::move(txn));
  auto r = co_await std::move(r_call);
  if (!r.ok()) {
    LogEtcdTrouble("removing the move request of scene " + scene, r.status());
    co_return;
  }
  if (r->succeeded && member == config_.member) {
    spdlog::info("cluster: move request of scene {} to member {} removed: {}", scene, member,
                 why);
  } else if (r->succeeded) {
    spdlog::warn("cluster: move request of scene {} to member {} removed: {}", scene, member,
                 why);
  }
  ResumeAfterMove(slot, "its move request was removed");
  slot.move_target.clear();
}

void ClusterAgent::ResumeAfterMove(Slot& slot, const std::string& why) {
  slot.move_mark.reset();
  if (!slot.move_fenced) return;
  slot.move_fenced = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    slot.moving_to.clear();
  }
  if (slot.owned) slot.fence->Grant(slot.owned_epoch.load(), lease_valid_until_);
  spdlog::warn("cluster: scene {}: the move is off ({}): acknowledging again", slot.hosted.name,
               why);
}

uint64_t ClusterAgent::owned_epoch(const std::string& scene) const {
  const Slot* slot = FindSlot(scene);
  return slot && slot->fence->held() ? slot->owned_epoch.load() : 0;
}

std::vector<MemberAddress> ClusterAgent::LiveMembers() const {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<MemberAddress> out;
  out.reserve(members_.size());
  for (const MemberRecord& m : members_) out.push_back({m.name, m.tcp, m.http});
  return out;
}

Route ClusterAgent::RouteScene(const std::string& requested) const {
  Route r;
  r.scene = requested.empty() && !slots_.empty() ? slots_.front()->hosted.name : requested;
  const Slot* slot = FindSlot(r.scene);
  if (slot && slot->fence->held()) {
    r.kind = Route::Kind::kLocal;
    r.member = config_.member;
    r.epoch = slot->fence->epoch();
    std::lock_guard<std::mutex> lock(mu_);
    const auto it = scenes_.find(r.scene);
    if (it != scenes_.end() && it->second.standby) r.standby = it->second.standby->member;
    return r;
  }
  std::lock_guard<std::mutex> lock(mu_);
  const auto it = scenes_.find(r.scene);
  if (it != scenes_.end() && it->second.owner && it->second.owner->member != config_.member) {
    const OwnerRecord& o = *it->second.owner;
    r.kind = Route::Kind::kRedirect;
    r.member = o.member;
    r.tcp = o.tcp;
    r.http = o.http;
    r.epoch = o.epoch;
    return r;
  }
  if (slot) {
    r.kind = Route::Kind::kUnavailable;
    r.reason =
        "scene " + r.scene + " has no owner now: " +
        (it != scenes_.end() && it->second.owner
             ? (slot->moving_to.empty()
                    ? "this member's lease is not confirmed by etcd"
                    : "it is being moved to member " + slot->moving_to +
                          ", which takes it over once its copy holds every edit")
             : slot->waiting_reason);
    return r;
  }
  if (it != scenes_.end()) {
    r.kind = Route::Kind::kUnavailable;
    r.reason = "scene " + r.scene + " has no owner now" +
               (it->second.epoch ? " (last: " + it->second.epoch->member + ", epoch " +
                                       std::to_string(it->second.epoch->epoch) + ")"
                                 : std::string());
    return r;
  }
  return r;  // kUnknown
}

}  // namespace sculpt::server::cluster
