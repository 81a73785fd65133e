/// @brief FairQueue: the scene's compute-thread queue. Each requester's jobs run in the order it
/// posted them; between requesters the next job is chosen by the compute time each has used.
#ifndef SCULPT_SERVER_SCENE_FAIR_QUEUE_H_
#define SCULPT_SERVER_SCENE_FAIR_QUEUE_H_

#include <algorithm>
#include <cstdint>
#include <deque>
#include <set>
#include <tuple>
#include <unordered_map>
#include <utility>

namespace sculpt::server {

/// A queue of jobs for one consumer thread, in three lanes:
///   - priority (the scene's own background work, e.g. the mesher's copies): FIFO, served first;
///   - ordered (the scene's own work that must see every job posted before it: Flush, hashes,
///     inspections): FIFO, each served once every client job posted before it has run, and
///     before any client job posted after it;
///   - one FIFO per requester (a client session): between requesters, start-time fair queueing
///     on measured cost. A requester's virtual time is the sum of the costs of its jobs; the
///     next job is the head of the waiting requester with the smallest virtual start, ties by
///     posting order. A requester that becomes active again starts at the virtual time of the
///     job in service: idle time banks no credit, and a debt it ran up while others waited is
///     kept until the virtual time passes it (the end of a busy period forgives every debt).
///     So a requester with a backlog delays another's single job by at most the one job of its
///     own in service, whatever the backlog.
/// The consumer calls Pop, runs the job, then Done with the job's cost, one job at a time.
/// Not thread-safe: the owner guards it (Scene::jobs_mu_).
template <typename Job>
class FairQueue {
 public:
  /// Requester 0: the scene's own work (the ordered lane).
  static constexpr uint64_t kSystem = 0;

  /// Scene work served ahead of everything else.
  void PushPriority(Job job) { priority_.push_back(std::move(job)); }
  /// Scene work served after every job posted before it.
  void PushOrdered(Job job) { ordered_.push_back({next_ticket_++, std::move(job)}); }
  /// A requester's job; requester kSystem is the ordered lane.
  void Push(uint64_t requester, Job job) {
    if (requester == kSystem) return PushOrdered(std::move(job));
    const uint64_t ticket = next_ticket_++;
    Flow& f = flows_[requester];
    f.jobs.push_back({ticket, std::move(job)});
    ++client_jobs_;
    if (f.jobs.size() == 1 && !(in_service_ && requester_ == requester)) {
      // Newly active: no credit for the time it was idle.
      idle_.erase({f.finish, requester});
      f.start = std::max(f.finish, vtime_);
      ready_.insert({f.start, ticket, requester});
    }
  }

  bool empty() const { return priority_.empty() && ordered_.empty() && client_jobs_ == 0; }
  size_t size() const { return priority_.size() + ordered_.size() + client_jobs_; }
  /// Requesters with a job waiting.
  size_t waiting_requesters() const { return ready_.size(); }
  /// Times a job was chosen while an older job of another requester waited.
  uint64_t passed_over() const { return passed_over_; }

  /// Takes the next job (the queue must not be empty and no job may be in service); sets
  /// `*requester` to its requester (kSystem for the scene's own lanes).
  Job Pop(uint64_t* requester) {
    in_service_ = true;
    if (!priority_.empty()) {
      Job job = std::move(priority_.front());
      priority_.pop_front();
      requester_ = *requester = kSystem;
      return job;
    }
    auto pick = ready_.begin();
    if (!ordered_.empty()) {
      // Only client jobs posted before the ordered head may go first.
      const uint64_t before = ordered_.front().first;
      while (pick != ready_.end() && std::get<1>(*pick) > before) ++pick;
      if (pick == ready_.end()) {
        Job job = std::move(ordered_.front().second);
        ordered_.pop_front();
        requester_ = *requester = kSystem;
        return job;
      }
    }
    const auto [start, ticket, who] = *pick;
    for (const auto& r : ready_) {
      if (std::get<1>(r) < ticket) {
        ++passed_over_;
        break;
      }
    }
    ready_.erase(pick);
    vtime_ = start;
    // Idle requesters whose debt the virtual time has passed are forgotten.
    while (!idle_.empty() && idle_.begin()->first <= vtime_) {
      flows_.erase(idle_.begin()->second);
      idle_.erase(idle_.begin());
    }
    Flow& f = flows_.at(who);
    Job job = std::move(f.jobs.front().second);
    f.jobs.pop_front();
    --client_jobs_;
    requester_ = *requester = who;
    return job;
  }

  /// The job Pop returned has run; `cost` (any unit, e.g. nanoseconds) is charged to its
  /// requester.
  void Done(uint64_t cost) {
    in_service_ = false;
    if (requester_ == kSystem) return;
    Flow& f = flows_.at(requester_);
    f.finish = f.start + std::max<uint64_t>(cost, 1);
    if (!f.jobs.empty()) {
      f.start = f.finish;
      ready_.insert({f.start, f.jobs.front().first, requester_});
    } else {
      idle_.insert({f.finish, requester_});
    }
    max_finish_ = std::max(max_finish_, f.finish);
    if (client_jobs_ == 0) {
      // The end of a busy period: what anyone ran while nobody else waited is no debt.
      vtime_ = max_finish_;
      flows_.clear();
      idle_.clear();
    }
  }

 private:
  struct Flow {
    std::deque<std::pair<uint64_t, Job>> jobs;  // ticket, job
    uint64_t start = 0;   // virtual start of its head job
    uint64_t finish = 0;  // virtual finish of its last job run
  };
  uint64_t next_ticket_ = 1;
  uint64_t vtime_ = 0;  // virtual start of the client job in service (or last served)
  uint64_t max_finish_ = 0;
  std::deque<Job> priority_;
  std::deque<std::pair<uint64_t, Job>> ordered_;  // ticket, job
  std::unordered_map<uint64_t, Flow> flows_;
  // Requesters with a job waiting, by (virtual start, ticket of their head job, requester).
  std::set<std::tuple<uint64_t, uint64_t, uint64_t>> ready_;
  // Requesters with nothing queued whose last virtual finish is still ahead: (finish, requester).
  std::set<std::pair<uint64_t, uint64_t>> idle_;
  size_t client_jobs_ = 0;
  uint64_t passed_over_ = 0;
  bool in_service_ = false;
  uint64_t requester_ = kSystem;  // of the job in service
};

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_SCENE_FAIR_QUEUE_H_
