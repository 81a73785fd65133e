/// @brief ClusterAgent: lease, membership, scene ownership and the routing table.
#include "cluster/cluster_agent.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
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

}  // namespace

ClusterAgent::ClusterAgent(ClusterConfig config, std::string scene,
                           std::function<uint32_t()> sessions)
    : config_(std::move(config)),
      scene_(std::move(scene)),
      keys_{config_.prefix},
      sessions_(std::move(sessions)),
      fence_(std::make_shared<OwnershipFence>(scene_)),
      tick_(std::max(50, config_.lease_ttl_ms / 4)) {
  waiting_reason_ = "this member has not reached etcd yet";
}

ClusterAgent::~ClusterAgent() { Stop(); }

MemberRecord ClusterAgent::SelfRecord() const {
  MemberRecord m;
  m.name = config_.member;
  m.tcp = tcp_;
  m.http = http_;
  m.offers = {scene_};
  if (owned_) {
    m.owns = {scene_};
    m.scene_seq = scene_seq_ ? scene_seq_() : 0;
    m.acks_async = acks_async_ && acks_async_();
  }
  m.sessions = sessions_ ? sessions_() : 0;
  m.standby = standby_.has_value();
  if (follower_ && follower_->ready()) {
    m.follows = follower_->options().scene;
    // Read now, not at the last tick: an owner moving its scene here waits on this figure.
    m.follow_seq = follower_->durable_seq();
  }
  return m;
}

Status ClusterAgent::Start(const std::string& tcp, const std::string& http) {
  if (started_) return FailedPrecondition("ClusterAgent started twice");
  auto client = EtcdClient::Create({config_.etcd, std::max(std::chrono::milliseconds(100), tick_),
                                    config_.etcd_ca_file, config_.etcd_cert_file,
                                    config_.etcd_key_file});
  if (!client.ok()) return client.status();
  etcd_ = std::move(client).value();
  tcp_ = tcp;
  http_ = http;
  started_ = true;
  const Status registered = etcd_->Sync(Register());
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
  spdlog::info("cluster: member {} registered (tcp {}, http {}), lease TTL {} ms", config_.member,
               tcp_, http_.empty() ? "off" : http_, config_.lease_ttl_ms);
  // The routing table is filled before the first client can be told this member's ports.
  if (const Status read = etcd_->Sync(Refresh()); !read.ok())
    LogEtcdTrouble("reading the cluster", read);
  timer_ = std::make_unique<asio::steady_timer>(etcd_->io());
  asio::co_spawn(etcd_->io(), Loop(), asio::detached);
  return Status::Ok();
}

void ClusterAgent::EnableStandby(StandbyOptions options) {
  if (!started_ && config_.standby) standby_ = std::move(options);
}

void ClusterAgent::RetireFollower() {
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
  if (!follower_) return;
  // Its destructor may wait for a connect to time out: not on the agent's thread, whose
  // keep-alives must not stall.
  auto done = std::make_shared<std::atomic<bool>>(false);
  retired_.push_back({std::thread([f = std::shared_ptr<StandbyFollower>(std::move(follower_)),
                                   done]() mutable {
                        f.reset();
                        done->store(true);
                      }),
                      done});
}

void ClusterAgent::Stop() {
  if (stopping_.exchange(true)) return;
  fence_->Revoke();
  owned_epoch_ = 0;
  if (!etcd_) return;
  asio::post(etcd_->io(), [this] {
    if (timer_) timer_->cancel();
  });
  // Our keys go now rather than after the TTL: other members see this one leave at once. The
  // epoch record stays: this member, restarted, takes its scene back with epoch + 1.
  auto revoke = [this]() -> asio::awaitable<Status> {
    if (lease_ == 0) co_return Status::Ok();
    auto call = etcd_->Revoke(lease_);
    co_return co_await std::move(call);
  };
  const Status s = etcd_->Sync(revoke());
  if (!s.ok())
    spdlog::warn("cluster: lease not revoked at stop ({}); it expires by itself", s.ToString());
  etcd_->Halt();     // joins the agent's thread; the io_context (and the loop's frame) stays
  timer_.reset();    // before its io_context: a timer's service must outlive it
  etcd_.reset();     // the loop's frame goes with its io_context
  fence_->Revoke();  // again: an acquisition may have completed while the lease was revoked
  RetireFollower();
  std::lock_guard<std::mutex> lock(retired_mu_);
  for (Retired& r : retired_) r.thread.join();
  retired_.clear();
}

asio::awaitable<Status> ClusterAgent::Register() {
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
  // A standby following its owner reads the owner key every fast tick between two full ticks:
  // the takeover then starts within a fast tick of the owner's lease running out in etcd, not up
  // to a whole tick later (a quarter of the failover budget at the default TTL).
  const auto fast_tick = std::max(std::chrono::milliseconds(20), tick_ / 5);
  while (!stopping_) {
    co_await Tick();
    const auto next_full = Clock::now() + tick_;
    boost::system::error_code ec;
    while (!stopping_ && !owned_ && follower_ && Clock::now() + fast_tick < next_full) {
      timer_->expires_after(fast_tick);
      co_await timer_->async_wait(asio::redirect_error(asio::use_awaitable, ec));
      if (stopping_) co_return;
      auto owner_call = etcd_->Get(keys_.Owner(scene_));
      auto owner = co_await std::move(owner_call);
      if (owner.ok() && !owner->has_value()) break;  // gone: the full tick takes it over now
      if (owner.ok()) {
        // A newer epoch than the one followed (epochs only grow): a new owner. The full tick
        // reads the scene's keys (checked against each other), stops the old follow and follows
        // the new owner now.
        auto o = DecodeOwner((*owner)->value);
        if (o.ok() && follower_ && o->epoch > follower_->expected_epoch()) break;
      }
    }
    if (stopping_) co_return;
    if (Clock::now() < next_full && !(follower_ && !owned_)) {
      timer_->expires_at(next_full);
      co_await timer_->async_wait(asio::redirect_error(asio::use_awaitable, ec));
    }
  }
}

asio::awaitable<void> ClusterAgent::Tick() {
  co_await KeepLeaseAlive();
  if (stopping_) co_return;
  const Status refreshed = co_await Refresh();
  if (!refreshed.ok()) {
    ++etcd_failures_;
    LogEtcdTrouble("reading the cluster", refreshed);
    co_return;
  }
  if (stopping_) co_return;
  co_await MaybeAcquire();
  if (stopping_) co_return;
  co_await TendStandby();
  if (stopping_) co_return;
  co_await TendMove();
}

asio::awaitable<void> ClusterAgent::KeepLeaseAlive() {
  const auto sent = Clock::now();
  auto ttl_call = etcd_->KeepAlive(lease_);
  auto ttl = co_await std::move(ttl_call);
  if (ttl.ok()) {
    const auto t = std::min(*ttl, std::chrono::milliseconds(config_.lease_ttl_ms));
    lease_valid_until_ = sent + t - Margin(t);
    if (owned_) fence_->Extend(lease_valid_until_);
    co_return;
  }
  if (ttl.status().code() != Status::Code::kNotFound) {
    // etcd out of reach: the fence runs out by itself at lease_valid_until_.
    ++etcd_failures_;
    LogEtcdTrouble("lease keep-alive", ttl.status());
    co_return;
  }
  // The lease is gone (we were cut off past its TTL, or Stop revoked it): so is every key under
  // it.
  if (owned_) LoseOwnership("its lease expired in etcd");
  if (stopping_) co_return;
  LogEtcdTrouble("lease expired; registering again", ttl.status());
  const Status again = co_await Register();
  if (!again.ok()) LogEtcdTrouble("registering again", again);
}

asio::awaitable<Status> ClusterAgent::Refresh() {
  auto put_call = etcd_->Put({keys_.Member(config_.member), EncodeMember(SelfRecord()), lease_});
  auto put = co_await std::move(put_call);
  if (!put.ok()) co_return put.status();
  auto members_call = etcd_->GetPrefix(keys_.Members());
  auto members = co_await std::move(members_call);
  if (!members.ok()) co_return members.status();
  auto scenes_call = etcd_->GetPrefix(keys_.Scenes());
  auto scenes = co_await std::move(scenes_call);
  if (!scenes.ok()) co_return scenes.status();

  std::vector<MemberRecord> live;
  for (const KeyValue& kv : *members) {
    auto m = DecodeMember(kv.value);
    // Another member's record is untrusted input: a bad one is skipped, never fatal.
    if (m.ok() && kv.key == keys_.Member(m->name)) live.push_back(std::move(m).value());
  }
  std::map<std::string, SceneState> table;
  for (const KeyValue& kv : *scenes) {
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
      if (o.ok() && kv.lease != 0) st.owner = std::move(o).value();
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
    }
  }
  std::lock_guard<std::mutex> lock(mu_);
  members_ = std::move(live);
  scenes_ = std::move(table);
  co_return Status::Ok();
}

void ClusterAgent::LoseOwnership(const std::string& why) {
  ++ownership_losses_;
  fence_->Revoke();
  owned_ = false;
  owned_epoch_ = 0;
  spdlog::error("cluster: member {} no longer owns scene {} ({}): acknowledging nothing for it",
                config_.member, scene_, why);
}

std::pair<ClusterAgent::SceneState, std::vector<MemberRecord>> ClusterAgent::ReadTable() const {
  std::lock_guard<std::mutex> lock(mu_);
  const auto it = scenes_.find(scene_);
  return {it != scenes_.end() ? it->second : SceneState{}, members_};
}

asio::awaitable<void> ClusterAgent::MaybeAcquire() {
  const auto [st, members] = ReadTable();
  if (owned_) {
    const bool ours =
        st.owner && st.owner->member == config_.member && st.owner->epoch == owned_epoch_.load();
    if (!ours) LoseOwnership("its owner key is gone or names another member");
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
                 PromotedFromEpoch(standby_->data_dir, scene_) == st.epoch->epoch;
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
  } else if (const auto pick = PickMember(members, scene_); pick && *pick != config_.member) {
    reason = "placed on member " + *pick + ", which has not taken it yet";
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    waiting_reason_ = reason.empty() ? "being acquired by this member" : reason;
  }
  if (!reason.empty()) co_return;

  const uint64_t epoch = (st.epoch ? st.epoch->epoch : 0) + 1;
  OwnerRecord owner{config_.member, tcp_, http_, epoch};
  TxnRequest txn;
  // Nobody owns it, and nobody bumped the epoch since we read it.
  txn.compares = {{keys_.Owner(scene_), Compare::Target::kCreateRevision, 0},
                  {keys_.Epoch(scene_), Compare::Target::kModRevision, st.epoch_mod_revision}};
  // The standby named when we read (a promotion is the named standby's only).
  if (st.standby) {
    txn.compares.push_back(
        {keys_.Standby(scene_), Compare::Target::kModRevision, st.standby_mod_revision});
  }
  txn.success = {{keys_.Owner(scene_), EncodeOwner(owner), lease_},
                 {keys_.Epoch(scene_), EncodeEpoch({epoch, config_.member}), 0}};
  auto r_call = etcd_->Txn(std::move(txn));
  auto r = co_await std::move(r_call);
  if (!r.ok()) {
    LogEtcdTrouble("acquiring scene " + scene_, r.status());
    co_return;
  }
  if (!r->succeeded) co_return;  // another member was faster; the next Refresh shows it
  if (stopping_) co_return;      // Stop revokes the lease: the owner key goes with it
  owned_ = true;
  owned_epoch_ = epoch;
  fence_->Grant(epoch, lease_valid_until_);
  {
    std::lock_guard<std::mutex> lock(mu_);
    SceneState& mine = scenes_[scene_];
    mine.owner = owner;
    mine.epoch = EpochRecord{epoch, config_.member};
    waiting_reason_.clear();
  }
  spdlog::info("cluster: member {} owns scene {} at epoch {}{}", config_.member, scene_, epoch,
               promoted ? " (took it over as the standby)" : "");
  if (standby_) ClearPromotedMarker(standby_->data_dir);
  RetireFollower();
  // The new load right away, so placement elsewhere sees it before the next tick.
  auto put_call = etcd_->Put({keys_.Member(config_.member), EncodeMember(SelfRecord()), lease_});
  auto put = co_await std::move(put_call);
  if (!put.ok()) LogEtcdTrouble("publishing the load", put.status());
}

asio::awaitable<void> ClusterAgent::TendStandby() {
  const auto [st, members] = ReadTable();
  if (owned_) {
    RetireFollower();
    if (config_.replication == "none") {
      // No standby: nobody follows, and a standby named under an earlier setting is dropped, so
      // no member takes the scene over from a copy this owner no longer feeds.
      if (st.standby) {
        auto del_call = etcd_->Delete(keys_.Standby(scene_));
        auto del = co_await std::move(del_call);
        if (!del.ok()) LogEtcdTrouble("removing the standby (replication = none)", del.status());
      }
      co_return;
    }
    // The standby: the one named while it lives and may follow, else the least loaded other
    // live member that offers the scene and may follow (every owner computes the same).
    std::vector<MemberRecord> candidates;
    for (const MemberRecord& m : members) {
      if (m.name != config_.member && m.standby) candidates.push_back(m);
    }
    const bool keep = st.standby && std::any_of(candidates.begin(), candidates.end(),
                                                [&](const MemberRecord& m) {
                                                  return m.name == st.standby->member;
                                                });
    if (keep) co_return;
    const auto pick = PickMember(candidates, scene_);
    if (!pick) co_return;
    StandbyRecord record{*pick, owned_epoch_.load()};
    auto put_call = etcd_->Put({keys_.Standby(scene_), EncodeStandby(record), 0});
    auto put = co_await std::move(put_call);
    if (!put.ok()) {
      LogEtcdTrouble("naming a standby", put.status());
    } else {
      spdlog::info("cluster: member {} is the standby of scene {} (epoch {})", *pick, scene_,
                   record.epoch);
      // Routing knows at once, not at the next Refresh: the standby may subscribe before it, and
      // its session is told apart by this name (its progress reports and the resend table that
      // comes with its region load).
      std::lock_guard<std::mutex> lock(mu_);
      scenes_[scene_].standby = record;
    }
    co_return;
  }
  // Fencing: the follow takes only the epoch etcd names. Once the scene's epoch moved on (a new
  // owner, or none yet), the old owner's stream is refused at once, also while this member waits
  // for the new owner or stops following.
  if (follower_ && st.epoch && st.epoch->epoch != follower_->options().owner_epoch) {
    follower_->Supersede(st.epoch->epoch);
  }
  const bool named = standby_ && st.standby && st.standby->member == config_.member;
  if (!named) {
    RetireFollower();
    co_return;
  }
  if (st.owner && st.owner->member != config_.member) {
    // Follow the owner; a new follow when the owner changed or the last one ended.
    const bool same_owner = follower_ && follower_->options().owner_tcp == st.owner->tcp &&
                            follower_->options().owner_epoch == st.owner->epoch;
    const bool current = same_owner && !follower_->finished();
    const auto now = Clock::now();
    if (follower_ && follower_->finished() && ended_at_ == Clock::time_point{}) {
      spdlog::warn("cluster: following scene {} ended: {}", scene_, follower_->failure());
      ended_at_ = now;
    }
    // The same owner again only after a pause (a follow that fails at once, e.g. a scene of
    // several objects, must not reconnect every tick); a new owner at once.
    const bool wait = same_owner && !current && now - ended_at_ < std::chrono::seconds(2);
    if (!current && !wait) {
      ended_at_ = {};
      RetireFollower();
      FollowerOptions fo;
      fo.data_dir = standby_->data_dir;
      fo.scene = scene_;
      fo.member = config_.member;
      // The members' peer token when the cluster has one (the owner then takes only a session
      // that presented it for its standby); else the viewer token.
      fo.token = config_.peer_token.empty() ? standby_->token : config_.peer_token;
      fo.owner_tcp = st.owner->tcp;
      fo.tls = standby_->tls;
      fo.owner_epoch = st.owner->epoch;
      fo.stale_epoch_refusals = stale_epoch_refusals_;
      fo.snapshot_every_records = standby_->snapshot_every_edits;
      follower_ = std::make_unique<StandbyFollower>(std::move(fo));
    }
    if (follower_ && follower_->ready()) follow_seq_ = follower_->durable_seq();
    co_return;
  }
  if (st.owner || !st.epoch || st.epoch->member == config_.member) co_return;
  if (PromotedFromEpoch(standby_->data_dir, scene_) == st.epoch->epoch) co_return;  // acquiring
  // The owner is gone and this member is its standby: take over with the copy of that epoch.
  uint64_t copy_epoch = 0;
  if (!CurrentStandbyCopy(standby_->data_dir, scene_, &copy_epoch) ||
      copy_epoch != st.epoch->epoch) {
    std::lock_guard<std::mutex> lock(mu_);
    waiting_reason_ = "its last owner " + st.epoch->member + " (epoch " +
                      std::to_string(st.epoch->epoch) +
                      ") is gone and this member, its standby, holds no copy of that epoch";
    co_return;
  }
  co_await Promote(st.epoch->epoch);
}

asio::awaitable<void> ClusterAgent::Promote(uint64_t dead_epoch) {
  spdlog::warn("cluster: the owner of scene {} (epoch {}) is gone: member {}, its standby, takes "
               "it over",
               scene_, dead_epoch, config_.member);
  if (follower_) {
    // Its log made durable and closed before the files move (the connection is gone already).
    follower_.reset();
  }
  if (standby_->restart_argv.empty()) {
    LogEtcdTrouble("promotion", FailedPrecondition("no command line to restart with"));
    co_return;
  }
  if (const Status s = PromoteStandbyCopy(standby_->data_dir, scene_, dead_epoch); !s.ok()) {
    LogEtcdTrouble("promotion", s);
    co_return;
  }
  // This member's keys go now; the restarted process registers anew and acquires.
  auto revoke_call = etcd_->Revoke(lease_);
  auto revoked = co_await std::move(revoke_call);
  if (!revoked.ok()) LogEtcdTrouble("revoking the lease before the restart", revoked);
  Reexec(standby_->restart_argv);
}

asio::awaitable<void> ClusterAgent::TendMove() {
  const auto [st, members] = ReadTable();
  if (!owned_) {
    // Ownership lost meanwhile (LoseOwnership fenced already) or released: nothing to undo.
    move_fenced_ = false;
    move_mark_.reset();
    co_return;
  }
  if (!st.move) {
    ResumeAfterMove("its move request was removed");
    move_target_.clear();
    co_return;
  }
  const MoveRecord& mv = *st.move;
  const uint64_t epoch = owned_epoch_.load();
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
  } else if (std::find(target->offers.begin(), target->offers.end(), scene_) ==
             target->offers.end()) {
    why = "member " + mv.member + " does not offer scene " + scene_;
  } else if (config_.replication == "none") {
    why = "the scene has replication = \"none\": no standby follows it";
  } else if (!scene_seq_) {
    why = "this member cannot read its scene's sequence";
  } else if (move_fenced_ && Clock::now() - move_fenced_at_ > limit) {
    why = "member " + mv.member + "'s copy did not reach the last sequence within " +
          std::to_string(limit.count()) + " ms of the fence";
  }
  if (!why.empty()) {
    co_await DropMove(st.move_mod_revision, mv.member, why);
    co_return;
  }
  if (move_target_ != mv.member) {
    move_target_ = mv.member;
    move_mark_.reset();
    spdlog::info("cluster: moving scene {} (epoch {}) to member {} as requested", scene_, epoch,
                 mv.member);
  }
  if (!st.standby || st.standby->member != mv.member) {
    // The target follows first, as any standby does (TendStandby keeps it while it lives).
    StandbyRecord record{mv.member, epoch};
    auto put_call = etcd_->Put({keys_.Standby(scene_), EncodeStandby(record), 0});
    auto put = co_await std::move(put_call);
    if (!put.ok()) {
      LogEtcdTrouble("naming the standby for a move", put.status());
      co_return;
    }
    spdlog::info("cluster: member {} is the standby of scene {} (epoch {}), for the move",
                 mv.member, scene_, epoch);
    std::lock_guard<std::mutex> lock(mu_);
    scenes_[scene_].standby = record;
    co_return;
  }
  // How far the target's copy is durable, as its member record said at its last refresh.
  const uint64_t copy = target->follows == scene_ ? target->follow_seq : 0;
  const uint64_t seq = scene_seq_();
  if (!move_fenced_) {
    if (target->follows != scene_) co_return;  // still loading its copy
    // Caught up: the copy holds what this member had when the target was first seen following,
    // so what remains after the fence is a few ticks of edits at most.
    if (!move_mark_) move_mark_ = seq;
    if (copy < *move_mark_) co_return;
    fence_->Revoke();
    move_fenced_ = true;
    move_fenced_at_ = Clock::now();
    {
      std::lock_guard<std::mutex> lock(mu_);
      moving_to_ = mv.member;
    }
    spdlog::info("cluster: scene {} fenced for the move to member {} (its copy holds seq {}, this "
                 "member seq {}): sequencing and acknowledging nothing more",
                 scene_, mv.member, copy, seq);
    co_return;
  }
  if (copy < seq) co_return;  // the copy takes the last edits
  // Release: the owner key goes (still ours: the epoch record is unchanged since an acquisition
  // writes both) and the request says so, in one txn.
  MoveRecord released = mv;
  released.released = true;
  TxnRequest txn;
  txn.compares = {{keys_.Epoch(scene_), Compare::Target::kModRevision, st.epoch_mod_revision},
                  {keys_.Move(scene_), Compare::Target::kModRevision, st.move_mod_revision}};
  txn.success = {{keys_.Move(scene_), EncodeMove(released), 0}};
  txn.success_deletes = {keys_.Owner(scene_)};
  auto r_call = etcd_->Txn(std::move(txn));
  auto r = co_await std::move(r_call);
  if (!r.ok()) {
    LogEtcdTrouble("releasing scene " + scene_ + " for the move", r.status());
    co_return;
  }
  if (!r->succeeded) co_return;  // the request or the epoch changed: the next tick reads them
  owned_ = false;
  owned_epoch_ = 0;
  move_fenced_ = false;
  move_mark_.reset();
  move_target_.clear();
  {
    std::lock_guard<std::mutex> lock(mu_);
    SceneState& mine = scenes_[scene_];
    mine.owner.reset();
    mine.move = released;
    moving_to_.clear();
    waiting_reason_ = "it is being moved to member " + mv.member +
                      ", which takes it over from its copy";
  }
  spdlog::info("cluster: member {} released scene {} (epoch {}, seq {}) to member {}, whose copy "
               "holds it: {} takes it over as its standby",
               config_.member, scene_, epoch, seq, mv.member, mv.member);
  auto put_call = etcd_->Put({keys_.Member(config_.member), EncodeMember(SelfRecord()), lease_});
  auto put = co_await std::move(put_call);
  if (!put.ok()) LogEtcdTrouble("publishing the load", put.status());
}

asio::awaitable<void> ClusterAgent::DropMove(int64_t mod_revision, std::string member,
                                             std::string why) {
  // Only the request read (a newer one is judged on its own at the next tick).
  TxnRequest txn;
  txn.compares = {{keys_.Move(scene_), Compare::Target::kModRevision, mod_revision}};
  txn.success_deletes = {keys_.Move(scene_)};
  auto r_call = etcd_->Txn(std::move(txn));
  auto r = co_await std::move(r_call);
  if (!r.ok()) {
    LogEtcdTrouble("removing the move request of scene " + scene_, r.status());
    co_return;
  }
  if (r->succeeded && member == config_.member) {
    spdlog::info("cluster: move request of scene {} to member {} removed: {}", scene_, member,
                 why);
  } else if (r->succeeded) {
    spdlog::warn("cluster: move request of scene {} to member {} removed: {}", scene_, member,
                 why);
  }
  ResumeAfterMove("its move request was removed");
  move_target_.clear();
}

void ClusterAgent::ResumeAfterMove(const std::string& why) {
  move_mark_.reset();
  if (!move_fenced_) return;
  move_fenced_ = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    moving_to_.clear();
  }
  if (owned_) fence_->Grant(owned_epoch_.load(), lease_valid_until_);
  spdlog::warn("cluster: scene {}: the move is off ({}): acknowledging again", scene_, why);
}

uint64_t ClusterAgent::owned_epoch() const { return fence_->held() ? owned_epoch_.load() : 0; }

std::vector<MemberAddress> ClusterAgent::LiveMembers() const {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<MemberAddress> out;
  out.reserve(members_.size());
  for (const MemberRecord& m : members_) out.push_back({m.name, m.tcp, m.http});
  return out;
}

Route ClusterAgent::RouteScene(const std::string& requested) const {
  Route r;
  r.scene = requested.empty() ? scene_ : requested;
  if (r.scene == scene_ && fence_->held()) {
    r.kind = Route::Kind::kLocal;
    r.member = config_.member;
    r.epoch = fence_->epoch();
    std::lock_guard<std::mutex> lock(mu_);
    const auto it = scenes_.find(scene_);
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
  if (r.scene == scene_) {
    r.kind = Route::Kind::kUnavailable;
    r.reason =
        "scene " + scene_ + " has no owner now: " +
        (it != scenes_.end() && it->second.owner
             ? (moving_to_.empty() ? "this member's lease is not confirmed by etcd"
                                   : "it is being moved to member " + moving_to_ +
                                         ", which takes it over once its copy holds every edit")
             : waiting_reason_);
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
