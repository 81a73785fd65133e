/// @brief The haptic loop thread, its lock-free statistics and the pose seqlock.
#include "sculpt/haptics/haptic_loop.h"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <thread>
#include <vector>

namespace sculpt::haptics {
namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

// Counts values into fixed-width bins with relaxed atomics, so the loop never blocks on a
// reader; the last bin takes everything above the range. The exact maximum is kept beside.
class AtomicHistogram {
 public:
  AtomicHistogram(double bin_width, size_t bins) : width_(bin_width), bins_(bins + 1) {}
  void Add(double v) {
    if (!(v >= 0)) v = 0;
    const size_t i = std::min(bins_.size() - 1, static_cast<size_t>(v / width_));
    bins_[i].fetch_add(1, std::memory_order_relaxed);
    count_.fetch_add(1, std::memory_order_relaxed);
    double m = max_.load(std::memory_order_relaxed);
    while (v > m && !max_.compare_exchange_weak(m, v, std::memory_order_relaxed)) {
    }
  }
  // Upper edge of the bin holding quantile q (the exact max for the overflow bin).
  double Quantile(double q) const {
    const uint64_t n = count_.load(std::memory_order_relaxed);
    if (n == 0) return 0;
    const uint64_t rank = static_cast<uint64_t>(std::ceil(q * static_cast<double>(n)));
    uint64_t seen = 0;
    for (size_t i = 0; i < bins_.size(); ++i) {
      seen += bins_[i].load(std::memory_order_relaxed);
      if (seen >= std::max<uint64_t>(rank, 1)) {
        return i + 1 == bins_.size() ? Max() : std::min(Max(), (i + 1) * width_);
      }
    }
    return Max();
  }
  double Max() const { return max_.load(std::memory_order_relaxed); }

 private:
  double width_;
  std::vector<std::atomic<uint64_t>> bins_;
  std::atomic<uint64_t> count_{0};
  std::atomic<double> max_{0};
};

// Each kind of refusal is logged once per process, not once per loop.
std::atomic<bool> g_logged_sched{false}, g_logged_mlock{false}, g_logged_cpu{false};

void LogOnce(std::atomic<bool>& logged, const std::string& message) {
  if (!logged.exchange(true)) std::fprintf(stderr, "haptic loop: %s\n", message.c_str());
}

// mlockall is a property of the process: tried once, its result shared by every loop. Only
// where the limit cannot bite later: with MCL_FUTURE and a finite RLIMIT_MEMLOCK, an allocation
// that would pass the limit fails instead of being made. MCL_ONFAULT locks pages as they are
// touched; without it MCL_FUTURE would fault in every new mapping whole (thread stacks,
// allocator arenas) when it is made.
int LockMemoryOnce() {
  static const int result = [] {
    rlimit limit{};
    const bool unlimited =
        getrlimit(RLIMIT_MEMLOCK, &limit) == 0 && limit.rlim_cur == RLIM_INFINITY;
    if (!unlimited && geteuid() != 0) return EPERM;
    int flags = MCL_CURRENT | MCL_FUTURE;
#ifdef MCL_ONFAULT
    flags |= MCL_ONFAULT;
#endif
    return mlockall(flags) == 0 ? 0 : errno;
  }();
  return result;
}

int ChooseCpu(int requested) {
  if (requested != HapticLoopOptions::kAutoCpu) return std::max(requested, -1);
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) != 0 || CPU_COUNT(&set) < 2) return -1;
  for (int c = CPU_SETSIZE - 1; c >= 0; --c) {
    if (CPU_ISSET(c, &set)) return c;
  }
  return -1;
}

}  // namespace

bool PinThreadAwayFromCpu(int cpu) {
  if (cpu < 0 || cpu >= CPU_SETSIZE) return false;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) != 0) return false;
  CPU_CLR(cpu, &set);
  if (CPU_COUNT(&set) == 0) return false;
  return pthread_setaffinity_np(pthread_self(), sizeof(set), &set) == 0;
}

SnapshotPublisher::SnapshotPublisher() : latest_(std::make_shared<const Snapshot>()) {}

void SnapshotPublisher::Publish(std::shared_ptr<const SdfSampler> sdf) {
  std::deque<std::shared_ptr<const Snapshot>> dropped;
  {
    std::lock_guard<std::mutex> lock(publish_mu_);
    const uint64_t version = next_version_++;
    latest_ = std::make_shared<const Snapshot>(Snapshot{std::move(sdf), version, Clock::now()});
    retained_.push_back(latest_);
    latest_version_.store(version, std::memory_order_release);
    while (retained_.size() > kRetained) {
      dropped.push_back(std::move(retained_.front()));
      retained_.pop_front();
    }
  }
  // Dropped after the unlock, so freeing a large grid (on this thread, unless the loop still
  // holds it) never keeps the loop's TryUpdate from taking the new snapshot.
}

std::shared_ptr<const Snapshot> SnapshotPublisher::Current() const {
  std::lock_guard<std::mutex> lock(publish_mu_);
  return latest_;
}

bool SnapshotPublisher::TryUpdate(std::shared_ptr<const Snapshot>* held) const {
  if ((*held)->version == latest_version_.load(std::memory_order_acquire)) return false;
  std::unique_lock<std::mutex> lock(publish_mu_, std::try_to_lock);
  if (!lock.owns_lock()) return false;  // a publisher is inside Publish: next tick
  // Copying the pointer only counts a reference; the snapshot the loop held is let go after
  // the unlock, and the publisher's retained copies keep it from being freed here.
  std::shared_ptr<const Snapshot> latest = latest_;
  lock.unlock();
  held->swap(latest);
  return true;
}

struct HapticLoop::Impl {
  Impl(const HapticSettings& s, HapticRenderer r, SnapshotPublisher* p, HapticDevice* d,
       const HapticLoopOptions& o)
      : settings(s),
        options(o),
        cpu(ChooseCpu(o.cpu)),
        renderer(std::move(r)),
        publisher(p),
        device(d),
        cost_us(0.1, 20000),
        period_err_us(1.0, 20000),
        lag_ms(0.01, 10000) {}

  void Run();
  // On the loop thread, before the first tick: affinity, scheduling class, memory lock.
  void SetUpThread();
  void PublishPose(const DeviceSample& s, const TickOutput& out);

  HapticSettings settings;
  HapticLoopOptions options;
  int cpu;  // chosen at Create, so a replica can keep off it before the loop starts
  HapticRenderer renderer;
  SnapshotPublisher* publisher;
  HapticDevice* device;
  std::thread thread;
  std::atomic<bool> running{false};
  std::atomic<bool> stop{false};

  AtomicHistogram cost_us, period_err_us, lag_ms;
  std::atomic<uint64_t> ticks{0}, overruns{0}, missed{0}, over_2ms{0}, nan_samples{0},
      snapshots_seen{0}, over_budget{0};
  // What SetUpThread got; set once on the loop thread before the first tick.
  std::atomic<bool> set_up{false}, fifo{false}, memory_locked{false};
  std::atomic<int> priority{0}, pinned_cpu{-1};
  std::atomic<int64_t> start_ns{0}, last_tick_ns{0};

  // Seqlock over the latest pose and force: the loop is the only writer; readers retry while
  // the sequence is odd or changed under them. Every field is an atomic, so there is no race.
  std::atomic<uint64_t> seq{0};
  std::array<std::atomic<double>, 11> pose{};  // t, x, y, z, qw, qx, qy, qz, fx, fy, fz
  std::atomic<bool> contact{false};
};

void HapticLoop::Impl::PublishPose(const DeviceSample& s, const TickOutput& out) {
  const uint64_t v = seq.load(std::memory_order_relaxed);
  seq.store(v + 1, std::memory_order_relaxed);
  std::atomic_thread_fence(std::memory_order_release);
  const double values[11] = {s.time,          s.position.x,    s.position.y,    s.position.z,
                             s.orientation.w, s.orientation.x, s.orientation.y, s.orientation.z,
                             out.force.x,     out.force.y,     out.force.z};
  for (size_t i = 0; i < pose.size(); ++i) pose[i].store(values[i], std::memory_order_relaxed);
  contact.store(out.contact, std::memory_order_relaxed);
  seq.store(v + 2, std::memory_order_release);
}

void HapticLoop::Impl::SetUpThread() {
  if (cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpu, &set);
    const int err = pthread_setaffinity_np(pthread_self(), sizeof(set), &set);
    if (err == 0) {
      pinned_cpu.store(cpu);
    } else {
      LogOnce(g_logged_cpu, "cannot pin to CPU " + std::to_string(cpu) + " (" +
                                std::strerror(err) + "); running unpinned");
    }
  }
  if (options.realtime) {
    sched_param param{};
    param.sched_priority = std::clamp(options.priority, sched_get_priority_min(SCHED_FIFO),
                                      sched_get_priority_max(SCHED_FIFO));
    const int err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
    if (err == 0) {
      fifo.store(true);
      priority.store(param.sched_priority);
    } else {
      LogOnce(g_logged_sched, std::string("SCHED_FIFO refused (") + std::strerror(err) +
                                  "); running at SCHED_OTHER, its period will follow the load");
    }
  }
  if (options.lock_memory) {
    const int err = LockMemoryOnce();
    if (err == 0) {
      memory_locked.store(true);
    } else {
      LogOnce(g_logged_mlock, std::string("mlockall not done (") + std::strerror(err) +
                                  "); pages may be faulted in during a tick");
    }
  }
  set_up.store(true);
}

void HapticLoop::Impl::Run() {
  SetUpThread();
  const auto period = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(1.0 / settings.rate_hz));
  const double period_us = Seconds(period) * 1e6;
  const Clock::time_point start = Clock::now();
  start_ns.store(start.time_since_epoch().count(), std::memory_order_relaxed);
  Clock::time_point deadline = start + period;
  Clock::time_point previous_wake{};
  uint64_t version = 0;
  DeviceSample last_good;
  // Taken once here, before the first tick, waiting for a publisher if need be; each tick then
  // only tries for a newer one.
  std::shared_ptr<const Snapshot> snap = publisher->Current();
  while (!stop.load(std::memory_order_relaxed)) {
    std::this_thread::sleep_until(deadline);
    const Clock::time_point wake = Clock::now();
    if (previous_wake != Clock::time_point{}) {
      const double actual_us = Seconds(wake - previous_wake) * 1e6;
      period_err_us.Add(std::abs(actual_us - period_us));
      if (actual_us > 2000) over_2ms.fetch_add(1, std::memory_order_relaxed);
    }
    previous_wake = wake;

    // The only shared state touched: one atomic load, and a try_lock when a newer snapshot
    // has been published.
    publisher->TryUpdate(&snap);
    if (snap->version != version) {
      version = snap->version;
      if (version != 0) {
        snapshots_seen.fetch_add(1, std::memory_order_relaxed);
        lag_ms.Add(Seconds(wake - snap->published) * 1e3);
      }
    }
    const double t = Seconds(wake - start);
    DeviceSample sample = device->Read(t);
    const TickOutput& out = renderer.Tick(snap->sdf, sample);
    device->ApplyForce(out.force, t);
    if (out.over_budget) over_budget.fetch_add(1, std::memory_order_relaxed);
    if (out.nan_ignored) {
      nan_samples.fetch_add(1, std::memory_order_relaxed);
      sample = last_good;  // the stroke sender keeps the last real pose
    } else {
      last_good = sample;
    }
    PublishPose(sample, out);

    const Clock::time_point done = Clock::now();
    const double cost = Seconds(done - wake) * 1e6;
    cost_us.Add(cost);
    if (cost > period_us) overruns.fetch_add(1, std::memory_order_relaxed);
    ticks.fetch_add(1, std::memory_order_relaxed);
    last_tick_ns.store(done.time_since_epoch().count(), std::memory_order_relaxed);

    deadline += period;
    if (done >= deadline) {
      // Late by more than a period: skip the lost slots rather than firing a burst of ticks.
      const auto behind = (done - deadline) / period + 1;
      missed.fetch_add(static_cast<uint64_t>(behind), std::memory_order_relaxed);
      deadline += period * behind;
    }
  }
}

StatusOr<std::unique_ptr<HapticLoop>> HapticLoop::Create(const HapticSettings& settings,
                                                         SnapshotPublisher* publisher,
                                                         HapticDevice* device,
                                                         const HapticLoopOptions& options) {
  if (publisher == nullptr) return InvalidArgument("HapticLoop.publisher is null");
  if (device == nullptr) return InvalidArgument("HapticLoop.device is null");
  auto renderer = HapticRenderer::Create(settings);
  if (!renderer.ok()) return renderer.status();
  return std::unique_ptr<HapticLoop>(new HapticLoop(
      std::make_unique<Impl>(settings, std::move(renderer).value(), publisher, device, options)));
}

HapticLoop::HapticLoop(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

HapticLoop::~HapticLoop() { Stop(); }

Status HapticLoop::Start() {
  if (impl_->running.load()) return FailedPrecondition("HapticLoop is already running");
  impl_->stop.store(false);
  impl_->running.store(true);
  impl_->thread = std::thread([this] { impl_->Run(); });
  return Status::Ok();
}

void HapticLoop::Stop() {
  if (!impl_->running.load()) return;
  impl_->stop.store(true);
  if (impl_->thread.joinable()) impl_->thread.join();
  impl_->running.store(false);
}

bool HapticLoop::running() const { return impl_->running.load(); }

HapticLoopStats HapticLoop::stats() const {
  const Impl& m = *impl_;
  HapticLoopStats s;
  s.ticks = m.ticks.load(std::memory_order_relaxed);
  const int64_t start = m.start_ns.load(std::memory_order_relaxed);
  const int64_t last = m.last_tick_ns.load(std::memory_order_relaxed);
  s.elapsed_s = s.ticks > 0 ? Seconds(Clock::duration(last - start)) : 0;
  s.rate_hz = s.elapsed_s > 0 ? static_cast<double>(s.ticks) / s.elapsed_s : 0;
  s.tick_cost_p50_us = m.cost_us.Quantile(0.5);
  s.tick_cost_p99_us = m.cost_us.Quantile(0.99);
  s.tick_cost_p999_us = m.cost_us.Quantile(0.999);
  s.tick_cost_max_us = m.cost_us.Max();
  s.period_err_p50_us = m.period_err_us.Quantile(0.5);
  s.period_err_p99_us = m.period_err_us.Quantile(0.99);
  s.period_err_max_us = m.period_err_us.Max();
  s.overruns = m.overruns.load(std::memory_order_relaxed);
  s.missed_deadlines = m.missed.load(std::memory_order_relaxed);
  s.ticks_over_2ms = m.over_2ms.load(std::memory_order_relaxed);
  s.nan_samples = m.nan_samples.load(std::memory_order_relaxed);
  s.snapshots_seen = m.snapshots_seen.load(std::memory_order_relaxed);
  s.snapshot_lag_p50_ms = m.lag_ms.Quantile(0.5);
  s.snapshot_lag_p99_ms = m.lag_ms.Quantile(0.99);
  s.snapshot_lag_max_ms = m.lag_ms.Max();
  s.ticks_over_budget = m.over_budget.load(std::memory_order_relaxed);
  if (m.set_up.load()) {
    s.scheduling = m.fifo.load() ? "SCHED_FIFO" : "SCHED_OTHER";
    s.priority = m.priority.load();
    s.memory_locked = m.memory_locked.load();
    s.cpu = m.pinned_cpu.load();
  }
  for (;;) {
    const uint64_t v0 = m.seq.load(std::memory_order_acquire);
    if (v0 & 1) continue;
    s.last_force = {m.pose[8].load(std::memory_order_relaxed),
                    m.pose[9].load(std::memory_order_relaxed),
                    m.pose[10].load(std::memory_order_relaxed)};
    s.contact = m.contact.load(std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_acquire);
    if (m.seq.load(std::memory_order_relaxed) == v0) break;
  }
  return s;
}

int HapticLoop::cpu() const { return impl_->cpu; }

DeviceSample HapticLoop::SamplePose() const {
  const Impl& m = *impl_;
  for (;;) {
    const uint64_t v0 = m.seq.load(std::memory_order_acquire);
    if (v0 & 1) continue;
    double v[8];
    for (int i = 0; i < 8; ++i) v[i] = m.pose[i].load(std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_acquire);
    if (m.seq.load(std::memory_order_relaxed) == v0) {
      return DeviceSample{v[0], {v[1], v[2], v[3]}, Quat{v[4], v[5], v[6], v[7]}};
    }
  }
}

}  // namespace sculpt::haptics
