/// @brief sculpt-bench haptics: the cost of one haptic tick (penalty and proxy, 32/128/512 tool
/// samples) on a radius-128 sphere, and the 1 kHz loop's own timing while snapshots are swapped.
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <memory>
#include <numbers>
#include <thread>

#include "bench_common.h"
#include "sculpt/haptics/haptic_loop.h"
#include "sculpt/haptics/haptic_renderer.h"
#include "sculpt/haptics/sculpture_snapshot.h"

namespace sculpt::bench {
namespace {

using haptics::DeviceSample;
using haptics::ForceModel;
using haptics::HapticRenderer;
using haptics::HapticSettings;

constexpr double kSphereRadius = 128;  // voxels (voxel size 1)
constexpr double kToolRadius = 4;
constexpr double kPenetration = 1;
constexpr double kSpeed = 20;  // voxels per second along the surface
constexpr double kWindowMargin = 6;  // voxels of dense window beyond the tool's radius

// The tool centre sliding along a great circle of the sphere, kPenetration deep.
Vec3 PathAt(double t) {
  const double r = kSphereRadius + kToolRadius - kPenetration;
  const double a = kSpeed * t / r;
  return Vec3{r * std::cos(a), r * std::sin(a) * 0.6, r * std::sin(a) * 0.8};
}

HapticSettings Settings(ForceModel model, int samples, double budget_us = 0) {
  HapticSettings s;
  s.model = model;
  // The tick-cost runs measure the whole tick: no budget unless asked for.
  s.tick_budget_us = budget_us;
  s.tool_radius = kToolRadius;
  s.tool_samples = samples;
  // The proxy keeps the tool sphere's centre on phi = tool radius (inside the 6-voxel band).
  s.proxy_radius = model == ForceModel::kProxy ? kToolRadius : 0.0;
  return s;
}

// `swap_every` > 0: alternate between `sdf` and `other` every that many ticks, as a replica
// publishing at 120 Hz does to a 1 kHz loop (the first tick after a swap knows no phi).
Json TickCost(const std::shared_ptr<const haptics::SdfSampler>& sdf,
              const std::shared_ptr<const haptics::SdfSampler>& other, ForceModel model,
              int samples, int ticks, double budget_us = 0, int swap_every = 0) {
  auto r = HapticRenderer::Create(Settings(model, samples, budget_us));
  if (!r.ok()) return Json{{"error", r.status().ToString()}};
  Samples us, swap_us;
  int contact = 0, over_budget = 0;
  double evaluated = 0, skipped = 0;
  for (int i = -200; i < ticks; ++i) {  // 200 untimed ticks reach steady contact
    const double t = (i + 200) * 1e-3;
    const DeviceSample d{t, PathAt(t), {}};
    const bool swapped = swap_every > 0 && (i + 200) % swap_every == 0;
    const auto& field = swap_every > 0 && ((i + 200) / swap_every) % 2 ? other : sdf;
    const auto t0 = Clock::now();
    const haptics::TickOutput& o = r->Tick(field, d);
    const double cost = std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
    if (i < 0) continue;
    us.Add(cost);
    if (swapped) swap_us.Add(cost);
    contact += o.contact ? 1 : 0;
    over_budget += o.over_budget ? 1 : 0;
    evaluated += o.samples_evaluated;
    skipped += o.samples_skipped;
  }
  Json j = us.Summary();
  j["p999"] = us.P(0.999);
  j["contact_fraction"] = static_cast<double>(contact) / ticks;
  j["samples_evaluated_mean"] = evaluated / ticks;
  j["samples_skipped_mean"] = skipped / ticks;
  if (budget_us > 0) {
    j["budget_us"] = budget_us;
    j["ticks_over_budget"] = over_budget;
    j["max_over_budget_us"] = std::max(0.0, us.P(1.0) - budget_us);
  }
  if (swap_every > 0) {
    j["swap_every_ticks"] = swap_every;
    j["swap_tick"] = swap_us.Summary();
  }
  return j;
}

// FNV-1a over the bits of every timed tick's force: two builds that print the same hash gave
// the same forces (a change to the tick's arithmetic shows here before it shows in a figure).
struct ForceHash {
  uint64_t h = 1469598103934665603ull;
  void Add(const Vec3& f) {
    for (double v : {f.x, f.y, f.z}) {
      uint64_t bits;
      std::memcpy(&bits, &v, sizeof bits);
      for (int i = 0; i < 8; ++i) {
        h ^= (bits >> (8 * i)) & 0xff;
        h *= 1099511628211ull;
      }
    }
  }
  std::string Hex() const {
    char buf[17];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
    return buf;
  }
};

// As a replica feeding the loop does: a new snapshot of the same sculpture every `swap_every`
// ticks, each with a dense window of the band around the tool where the tick starts (filled
// untimed, as the replica's thread does; its cost is reported apart).
Json WindowTickCost(const std::shared_ptr<const levelset::Sculpture>& sculpture,
                    const std::shared_ptr<const levelset::Sculpture>& copy, ForceModel model,
                    int samples, int ticks, int swap_every, double budget_us = 0) {
  auto r = HapticRenderer::Create(Settings(model, samples, budget_us));
  if (!r.ok()) return Json{{"error", r.status().ToString()}};
  Samples us, swap_us, fill_ms;
  int over_budget = 0;
  // Lookups per tick (SculptureSnapshot's thread counters), on ticks right after a swap and on
  // the others, and how many of them fell back to the tree.
  Samples lookups, swap_lookups, stencils, swap_stencils;
  uint64_t tree_lookups = 0;
  ForceHash force_hash;
  std::shared_ptr<const haptics::SculptureSnapshot> snap;
  std::deque<std::shared_ptr<const haptics::SculptureSnapshot>> retained;
  for (int i = -200; i < ticks; ++i) {
    const double t = (i + 200) * 1e-3;
    const bool swapped = (i + 200) % swap_every == 0;
    if (swapped) {
      // Alternately the sculpture and a separate copy of it, as a replica's successive copies
      // are: each new window is compared with the previous one (SculptureFeed does the same).
      const auto f0 = Clock::now();
      snap = std::make_shared<const haptics::SculptureSnapshot>(
          ((i + 200) / swap_every) % 2 ? copy : sculpture, PathAt(t), kToolRadius + kWindowMargin,
          snap.get());
      fill_ms.Add(MsSince(f0));
      // Kept alive as SnapshotPublisher keeps its last kRetained: the tick that lets go of the
      // previous snapshot is not the one that frees it.
      retained.push_back(snap);
      if (retained.size() > haptics::SnapshotPublisher::kRetained) retained.pop_front();
    }
    const auto n0 = haptics::SculptureSnapshot::ThreadLookupCounts();
    const auto t0 = Clock::now();
    const haptics::TickOutput& o = r->Tick(snap, DeviceSample{t, PathAt(t), {}});
    const double cost = std::chrono::duration<double, std::micro>(Clock::now() - t0).count();
    const auto n = haptics::SculptureSnapshot::ThreadLookupCounts() - n0;
    if (i < 0) continue;
    us.Add(cost);
    if (swapped) swap_us.Add(cost);
    (swapped ? swap_lookups : lookups).Add(static_cast<double>(n.total()));
    (swapped ? swap_stencils : stencils)
        .Add(static_cast<double>(n.window_stencil + n.tree_stencil));
    tree_lookups += n.tree();
    over_budget += o.over_budget ? 1 : 0;
    force_hash.Add(o.force);
  }
  Json j = us.Summary();
  j["p999"] = us.P(0.999);
  j["swap_every_ticks"] = swap_every;
  j["swap_tick"] = swap_us.Summary();
  j["window_fill_ms"] = fill_ms.Summary();
  j["swaps_carried"] = r->swaps_carried();
  j["swaps"] = r->swaps();
  j["force_hash"] = force_hash.Hex();
  j["lookups_per_tick"] = Json{{"other_mean", lookups.Mean()},
                               {"other_max", lookups.Max()},
                               {"swap_mean", swap_lookups.Mean()},
                               {"swap_max", swap_lookups.Max()},
                               {"stencils_other_mean", stencils.Mean()},
                               {"stencils_swap_mean", swap_stencils.Mean()},
                               {"tree_fallbacks", tree_lookups}};
  if (budget_us > 0) {
    j["budget_us"] = budget_us;
    j["ticks_over_budget"] = over_budget;
    j["max_over_budget_us"] = std::max(0.0, us.P(1.0) - budget_us);
    j["p99_over_budget_us"] = std::max(0.0, us.P(0.99) - budget_us);
  }
  return j;
}

// The real thread for `seconds`, following the same path, while another thread publishes a
// snapshot (alternating two prepared ones) at `publish_hz`, as replica updates would arrive.
// `sculpture` non-null: each published snapshot is a new one of it with a dense window around
// the loop's current pose (as SculptureFeed::SetWindow does), instead of alternating a and b.
Json LoopRun(const std::shared_ptr<const haptics::SdfSampler>& a,
             const std::shared_ptr<const haptics::SdfSampler>& b, double seconds,
             double publish_hz,
             const std::shared_ptr<const levelset::Sculpture>& sculpture = nullptr,
             const std::shared_ptr<const levelset::Sculpture>& copy = nullptr) {
  haptics::SnapshotPublisher pub;
  pub.Publish(a);
  haptics::ScriptedDevice device(PathAt);
  // The loop runs with the loop's budget, as `sculpt play --haptics` does.
  HapticSettings settings = Settings(ForceModel::kProxy, 128, haptics::kLoopTickBudgetUs);
  auto loop = haptics::HapticLoop::Create(settings, &pub, &device);
  if (!loop.ok()) return Json{{"error", loop.status().ToString()}};
  std::atomic<bool> stop{false};
  std::shared_ptr<const haptics::SculptureSnapshot> last;  // the publisher thread's
  std::thread publisher([&] {
    const auto period = std::chrono::duration<double>(1.0 / publish_hz);
    auto next = Clock::now();
    for (int i = 0; !stop.load(); ++i) {
      next += std::chrono::duration_cast<Clock::duration>(period);
      std::this_thread::sleep_until(next);
      if (sculpture) {
        // A separate copy every other time, each window compared with the previous one.
        last = std::make_shared<const haptics::SculptureSnapshot>(
            i % 2 && copy ? copy : sculpture, (*loop)->SamplePose().position,
            kToolRadius + kWindowMargin, last.get());
        pub.Publish(last);
      } else {
        pub.Publish(i % 2 ? a : b);
      }
    }
  });
  if (Status s = (*loop)->Start(); !s.ok()) {
    stop = true;
    publisher.join();
    return Json{{"error", s.ToString()}};
  }
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  (*loop)->Stop();
  stop = true;
  publisher.join();
  const haptics::HapticLoopStats s = (*loop)->stats();
  return Json{{"seconds", seconds},
              {"publish_hz", publish_hz},
              {"dense_window", sculpture != nullptr},
              {"scheduling", s.scheduling},
              {"priority", s.priority},
              {"mlockall", s.memory_locked},
              {"cpu", s.cpu},
              {"tick_budget_us", settings.tick_budget_us},
              {"ticks_over_budget", s.ticks_over_budget},
              {"ticks", s.ticks},
              {"haptic_rate_hz", s.rate_hz},
              {"tick_cost_p50_us", s.tick_cost_p50_us},
              {"tick_cost_p99_us", s.tick_cost_p99_us},
              {"tick_cost_p999_us", s.tick_cost_p999_us},
              {"tick_cost_max_us", s.tick_cost_max_us},
              {"haptic_period_err_p50_us", s.period_err_p50_us},
              {"haptic_period_err_p99_us", s.period_err_p99_us},
              {"haptic_period_err_max_us", s.period_err_max_us},
              {"overruns", s.overruns},
              {"missed_deadlines", s.missed_deadlines},
              {"haptic_ticks_over_2ms", s.ticks_over_2ms},
              {"snapshots_seen", s.snapshots_seen},
              {"haptic_snapshot_lag_p50_ms", s.snapshot_lag_p50_ms},
              {"haptic_snapshot_lag_p99_ms", s.snapshot_lag_p99_ms},
              {"haptic_snapshot_lag_max_ms", s.snapshot_lag_max_ms}};
}

}  // namespace

Json RunHapticsBench(bool quick) {
  const int ticks = quick ? 2000 : 20000;
  const double loop_seconds = quick ? 0.5 : 10.0;
  levelset::SculptureOptions o;
  o.voxel_size = 1.0;
  Progress("haptics: building a radius-%g sphere", kSphereRadius);
  auto sphere = levelset::Sculpture::MakeSphere(o, {0, 0, 0}, kSphereRadius);
  if (!sphere.ok()) return Json{{"error", sphere.status().ToString()}};
  auto shared = std::make_shared<const levelset::Sculpture>(std::move(sphere).value());
  auto a = std::make_shared<const haptics::SculptureSnapshot>(*shared);
  auto b = std::make_shared<const haptics::SculptureSnapshot>(shared);
  // A second, separate copy of the same sphere (a replica publishes a new copy per update).
  auto copy = std::make_shared<const levelset::Sculpture>(shared->Clone());

  Json doc{{"sphere_radius_voxels", kSphereRadius}, {"tool_radius_voxels", kToolRadius},
           {"penetration_voxels", kPenetration},    {"speed_voxels_per_s", kSpeed},
           {"ticks_per_configuration", ticks},      {"quick", quick}};
  Json configs = Json::array();
  for (ForceModel model : {ForceModel::kPenalty, ForceModel::kProxy}) {
    for (int n : {32, 128, 512}) {
      Progress("haptics: %s, %d samples, %d ticks", haptics::ForceModelName(model), n, ticks);
      Json c = TickCost(a, b, model, n, ticks);
      const std::string key = std::string(haptics::ForceModelName(model)) + "_";
      doc[key + "p50_us_" + std::to_string(n)] = c["p50"];
      doc[key + "p99_us_" + std::to_string(n)] = c["p99"];
      doc[key + "p999_us_" + std::to_string(n)] = c["p999"];
      doc[key + "max_us_" + std::to_string(n)] = c["max"];
      configs.push_back(Json{{"model", haptics::ForceModelName(model)}, {"samples", n},
                             {"tick_us", std::move(c)}});
    }
  }
  doc["configurations"] = std::move(configs);
  // Snapshot swaps every 8 ticks (120 Hz at 1 kHz): the cost of the tick right after a swap.
  Progress("haptics: penalty, 128 samples, snapshot swapped every 8 ticks");
  doc["penalty_128_swap_every_8"] = TickCost(a, b, ForceModel::kPenalty, 128, ticks, 0, 8);
  // As the replica feeds the loop: a new snapshot every 8 ticks with a dense window around
  // the tool (the production path of `sculpt play --haptics`).
  for (ForceModel model : {ForceModel::kPenalty, ForceModel::kProxy}) {
    for (int n : {128, 512}) {
      Progress("haptics: %s, %d samples, windowed snapshots every 8 ticks",
               haptics::ForceModelName(model), n);
      Json c = WindowTickCost(shared, copy, model, n, ticks, 8);
      const std::string key = std::string("window_") + haptics::ForceModelName(model) + "_";
      doc[key + "p50_us_" + std::to_string(n)] = c["p50"];
      doc[key + "p99_us_" + std::to_string(n)] = c["p99"];
      doc[key + "swap_tick_p99_us_" + std::to_string(n)] = c["swap_tick"]["p99"];
      doc[key + "detail_" + std::to_string(n)] = std::move(c);
    }
  }
  // A budget that binds: the tick stops when it is spent; how far past it a tick ends.
  for (double budget : {5.0, 10.0}) {
    Progress("haptics: penalty, 512 samples, budget %g us, windowed swaps every 8 ticks", budget);
    doc["penalty_512_budget_" + std::to_string(static_cast<int>(budget)) + "us"] =
        WindowTickCost(shared, copy, ForceModel::kPenalty, 512, ticks, 8, budget);
  }
  // The goals (tick cost without a budget, as measured above).
  const auto p99 = [&](const char* key) { return doc[key].get<double>(); };
  doc["goals"] = Json{
      {"tick_p99_us_128", 10},
      {"tick_p99_us_512", 40},
      {"penalty_128_met", p99("penalty_p99_us_128") <= 10},
      {"proxy_128_met", p99("proxy_p99_us_128") <= 10},
      {"penalty_512_met", p99("penalty_p99_us_512") <= 40},
      {"proxy_512_met", p99("proxy_p99_us_512") <= 40},
      {"window_penalty_128_met", p99("window_penalty_p99_us_128") <= 10},
      {"window_proxy_128_met", p99("window_proxy_p99_us_128") <= 10},
      {"window_penalty_512_met", p99("window_penalty_p99_us_512") <= 40},
      {"window_proxy_512_met", p99("window_proxy_p99_us_512") <= 40},
      {"max_over_budget_us_goal", 5}};
  // The figures the flags are taken from, side by side.
  Json& goals = doc["goals"];
  for (const char* m : {"penalty", "proxy"}) {
    for (int n : {128, 512}) {
      const std::string tail = std::string(m) + "_p99_us_" + std::to_string(n);
      goals[tail] = doc[tail];
      goals["window_" + tail] = doc["window_" + tail];
      // The "the first tick after a swap costs what the others do": the swap tick's
      // p99 and its lookups against the other ticks'.
      const Json& w = doc[std::string("window_") + m + "_detail_" + std::to_string(n)];
      const std::string key = std::string("window_") + m + "_" + std::to_string(n);
      goals[key + "_swap_tick_p99_us"] = w["swap_tick"]["p99"];
      goals[key + "_swap_tick_lookups_mean"] = w["lookups_per_tick"]["swap_mean"];
      goals[key + "_other_tick_lookups_mean"] = w["lookups_per_tick"]["other_mean"];
      goals[key + "_swap_tick_lookups_as_others"] =
          w["lookups_per_tick"]["swap_mean"].get<double>() <=
          1.05 * w["lookups_per_tick"]["other_mean"].get<double>();
      goals[key + "_tree_fallbacks"] = w["lookups_per_tick"]["tree_fallbacks"];
    }
  }
  // Past the budget: p99 (the max is the thread preempted, not the tick; it is in the detail).
  for (const char* b : {"5", "10"}) {
    const Json& d = doc[std::string("penalty_512_budget_") + b + "us"];
    goals[std::string("budget_") + b + "us_p99_over_us"] = d["p99_over_budget_us"];
    goals[std::string("budget_") + b + "us_p99_over_met"] = d["p99_over_budget_us"].get<double>() <= 5;
  }
  Progress("haptics: the loop thread for %.1f s with snapshots swapped at 120 Hz", loop_seconds);
  doc["loop"] = LoopRun(a, b, loop_seconds, 120.0);
  Progress("haptics: the loop thread for %.1f s with windowed snapshots at 120 Hz", loop_seconds);
  doc["loop_window"] = LoopRun(a, b, loop_seconds, 120.0, shared, copy);
  // The two questions apart: what a tick costs (timed alone, no budget, 128 and 512
  // samples, on windowed snapshots as the replica publishes them and on the tree), and how well
  // the real loop thread holds its period, with the scheduling it obtained.
  Json tick = Json::object();
  for (const char* m : {"penalty", "proxy"}) {
    for (int n : {128, 512}) {
      const std::string tail = std::string(m) + "_" + std::to_string(n);
      const std::string w = std::string("window_") + m + "_";
      tick[tail] = Json{{"p50_us", doc[w + "p50_us_" + std::to_string(n)]},
                        {"p99_us", doc[w + "p99_us_" + std::to_string(n)]},
                        {"tree_p50_us", doc[std::string(m) + "_p50_us_" + std::to_string(n)]},
                        {"tree_p99_us", doc[std::string(m) + "_p99_us_" + std::to_string(n)]}};
    }
  }
  Json period = Json::object();
  for (const char* l : {"loop", "loop_window"}) {
    const Json& r = doc[l];
    period[l] = Json{{"rate_hz", r["haptic_rate_hz"]},
                     {"period_err_p50_us", r["haptic_period_err_p50_us"]},
                     {"period_err_p99_us", r["haptic_period_err_p99_us"]},
                     {"period_err_max_us", r["haptic_period_err_max_us"]},
                     {"ticks_over_2ms", r["haptic_ticks_over_2ms"]},
                     {"scheduling", r["scheduling"]},
                     {"priority", r["priority"]},
                     {"mlockall", r["mlockall"]},
                     {"cpu", r["cpu"]}};
  }
  doc["tick_and_period"] = Json{{"tick_us", std::move(tick)}, {"period", std::move(period)}};
  return doc;
}

}  // namespace sculpt::bench
