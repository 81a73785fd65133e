/// @brief LoadRun: connects the simulated clients, paces the sculptors' strokes from one driver
/// thread, collects acks on the clients' I/O threads and builds the report.
#include "loadgen/load_run.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <thread>
#include <vector>

#include "loadgen/surface_walk.h"
#include "sculpt/client/client.h"
#include "sculpt/client/mesh_view.h"
#include "sculpt/client/replica.h"
#include "sculpt/haptics/haptic_device.h"
#include "sculpt/haptics/haptic_loop.h"
#include "sculpt/haptics/sculpture_feed.h"
#include "sculpt/mesh/chunk_mesher.h"

namespace sculpt::client {
namespace {

using Clock = std::chrono::steady_clock;
using json = nlohmann::ordered_json;

double Seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

double Round3(double v) { return std::round(v * 1000.0) / 1000.0; }

/// Nearest-rank percentile of sorted values (0 for none).
double Percentile(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return 0;
  const size_t rank = static_cast<size_t>(std::ceil(q * static_cast<double>(sorted.size())));
  return sorted[std::clamp<size_t>(rank, 1, sorted.size()) - 1];
}

json LatencyJson(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return {{"p50_ms", Round3(Percentile(v, 0.50))},
          {"p99_ms", Round3(Percentile(v, 0.99))},
          {"max_ms", Round3(v.empty() ? 0.0 : v.back())}};
}

/// SplitMix64: decorrelates the per-sculptor seeds derived from one --seed.
uint64_t Mix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

/// What a client's handler saw; written on its I/O thread, read after the run.
struct Observed {
  std::mutex mu;
  std::vector<double> latencies_ms;
  std::vector<double> edit_ms;  // Ack.summary.elapsed_ms: the server's time for the last pose
  std::map<std::string, uint64_t> errors_by_code;
  std::vector<std::string> first_errors;  // a few messages, for the report
  std::vector<std::string> disconnects;
  uint64_t presence = 0;
  std::vector<std::pair<Clock::time_point, double>> acked_at;  // receipt time, latency
};

// The undo client's requests and answers (issue 15).
struct UndoSeen {
  std::mutex mu;
  std::map<uint64_t, Clock::time_point> sent;  // by client_seq
  std::vector<std::pair<Clock::time_point, Clock::time_point>> in_flight;  // sent, answered
  std::vector<double> undo_ms;
  std::vector<double> replayed;
  uint64_t refused = 0;
  std::vector<std::string> first_refusals;
};

struct SimClient {
  std::string name;
  bool sculptor = false;
  std::unique_ptr<Client> client;
  std::unique_ptr<SurfaceWalk> walk;
  std::shared_ptr<Observed> seen = std::make_shared<Observed>();
  ClientStats at_start;  // counters when the sending phase began
  Clock::time_point next_send;
  uint64_t send_failures = 0;
  uint64_t reconnect_failures = 0;
  std::unique_ptr<Replica> replica;  // replica clients only
  std::unique_ptr<MeshView> view;    // viewers subscribed to meshes
  v1::ReplicaMode mode = v1::REPLICA_MODE_UNSPECIFIED;
};

// Stroke send times by (client_id, client_seq), for edit->replica-visible latency.
struct SendTimes {
  std::mutex mu;
  std::map<std::pair<uint64_t, uint64_t>, Clock::time_point> at;
  std::vector<double> visible_ms[3];  // by ReplicaMode
};

Client::EventHandler MakeHandler(std::shared_ptr<Observed> seen) {
  return [seen](const Event& e) {
    std::lock_guard<std::mutex> lock(seen->mu);
    switch (e.type) {
      case Event::Type::kAck:
        // Duplicates answer a resend; their latency measures the reconnect, not the server.
        if (!e.ack.duplicate()) {
          seen->latencies_ms.push_back(e.latency_ms);
          seen->edit_ms.push_back(e.ack.summary().elapsed_ms());
          seen->acked_at.emplace_back(Clock::now(), e.latency_ms);
        }
        break;
      case Event::Type::kError:
        ++seen->errors_by_code[ErrorCodeName(e.error.code())];
        if (seen->first_errors.size() < 5) {
          seen->first_errors.push_back(ErrorToStatus(e.error).message());
        }
        break;
      case Event::Type::kPresence:
        ++seen->presence;
        break;
      case Event::Type::kUndoAck:
        // Only the undo client sends undos; its own handler times them (UndoSeen).
        break;
      case Event::Type::kBye:
      case Event::Type::kDisconnected:
        if (seen->disconnects.size() < 5) seen->disconnects.push_back(e.reason);
        break;
    }
  };
}

/// Connects, says hello and joins `scene`, the errors prefixed with `who`. A join the server
/// refuses over its pending-join limit (RESOURCE_EXHAUSTED; the session stays open) is asked
/// again with backoff from 10 ms to 1 s for up to 60 s, each retry counted in `retries`, so a
/// client beside a join flood is measured rather than dropped.
StatusOr<JoinedScene> EnterScene(Client& client, const std::string& host, uint16_t port,
                                 const std::string& token, v1::Role role, const std::string& who,
                                 const std::string& scene, std::atomic<uint64_t>* retries) {
  const auto named = [&who](const Status& s) { return Status(s.code(), who + ": " + s.message()); };
  if (Status s = client.Connect(host, port); !s.ok()) return named(s);
  auto welcome = client.Hello(token, role, "loadgen-" + who, NewClientId());
  if (!welcome.ok()) return named(welcome.status());
  const auto give_up = Clock::now() + std::chrono::seconds(60);
  auto backoff = std::chrono::milliseconds(10);
  for (;;) {
    auto joined = client.Join(scene);
    if (joined.ok()) return joined;
    if (joined.status().code() != Status::Code::kResourceExhausted || Clock::now() > give_up) {
      return named(joined.status());
    }
    ++*retries;
    std::this_thread::sleep_for(backoff);
    backoff = std::min(2 * backoff, std::chrono::milliseconds(1000));
  }
}

Status CheckOptions(const LoadOptions& o) {
  const auto bad = [](const std::string& field, double v, const std::string& range) {
    return InvalidArgument("--" + field + "=" + std::to_string(v) + " outside " + range);
  };
  if (o.sculptors < 0 || o.sculptors > 4096) return bad("sculptors", o.sculptors, "[0, 4096]");
  if (o.viewers < 0 || o.viewers > 4096) return bad("viewers", o.viewers, "[0, 4096]");
  if (o.sculptors + o.viewers == 0)
    return InvalidArgument("--sculptors + --viewers=0 outside [1, 8192]");
  if (!(o.rate_hz > 0 && o.rate_hz <= 10000)) return bad("rate", o.rate_hz, "(0, 10000]");
  if (!(o.seconds > 0 && o.seconds <= 86400)) return bad("seconds", o.seconds, "(0, 86400]");
  if (o.poses_per_stroke < 1 || o.poses_per_stroke > 1024) {
    return bad("poses-per-stroke", o.poses_per_stroke, "[1, 1024]");
  }
  if (!(o.depth >= 0 && o.depth < 64)) return bad("depth", o.depth, "[0, 64)");
  if (o.io_threads < 1 || o.io_threads > 64) return bad("io-threads", o.io_threads, "[1, 64]");
  if (!(o.viewer_mesh_hz >= 0 && o.viewer_mesh_hz <= 120)) {
    return bad("viewer-mesh-hz", o.viewer_mesh_hz, "[0, 120]");
  }
  if (o.replay_replicas < 0 || o.replay_replicas > 64) {
    return bad("replay-replicas", o.replay_replicas, "[0, 64]");
  }
  if (o.leafdelta_replicas < 0 || o.leafdelta_replicas > 64) {
    return bad("leafdelta-replicas", o.leafdelta_replicas, "[0, 64]");
  }
  if (o.undo_every < 0 || o.undo_every > 1000) return bad("undo-every", o.undo_every, "[0, 1000]");
  // A stroke spans (K - 1) / rate seconds; its t_ms offsets are 16-bit milliseconds.
  if ((o.poses_per_stroke - 1) * 1000.0 / o.rate_hz > 65535) {
    return InvalidArgument("--poses-per-stroke / --rate: a stroke spans more than 65.535 s");
  }
  return Status::Ok();
}

}  // namespace

StatusOr<nlohmann::ordered_json> RunLoad(const LoadOptions& o) {
  SCULPT_RETURN_IF_ERROR(CheckOptions(o));
  std::string host;
  uint16_t port = 0;
  SCULPT_RETURN_IF_ERROR(ParseServerAddress(o.server, &host, &port));

  std::vector<std::shared_ptr<IoThread>> io;
  for (int i = 0; i < o.io_threads; ++i) io.push_back(std::make_shared<IoThread>());

  std::vector<SimClient> clients(static_cast<size_t>(o.sculptors + o.viewers));
  v1::SceneInfo info;
  uint64_t state_bytes_at_join = 0;
  std::atomic<uint64_t> join_retries{0};  // joins asked again after a pending-join refusal
  const auto t_setup = Clock::now();
  for (size_t i = 0; i < clients.size(); ++i) {
    SimClient& c = clients[i];
    c.sculptor = i < static_cast<size_t>(o.sculptors);
    const size_t index = c.sculptor ? i : i - static_cast<size_t>(o.sculptors);
    c.name = (c.sculptor ? "sculptor-" : "viewer-") + std::to_string(index);
    ClientOptions co;
    co.tls = o.tls;
    co.io = io[i % io.size()];
    c.client = std::make_unique<Client>(co);
    c.client->SetEventHandler(MakeHandler(c.seen));
    // Fresh ids every run (EnterScene): the server remembers the highest client_seq per id
    // across restarts, so an id derived from --seed would make a second run's strokes look like
    // resends.
    auto joined = EnterScene(*c.client, host, port, c.sculptor ? o.sculptor_token : o.viewer_token,
                             c.sculptor ? v1::ROLE_SCULPTOR : v1::ROLE_VIEWER, c.name, o.scene,
                             &join_retries);
    if (!joined.ok()) return joined.status();
    if (i == 0) info = joined->info;
    if (!c.sculptor && o.viewer_mesh_hz > 0 && joined->info.objects_size() > 0) {
      c.view = std::make_unique<MeshView>(
          *c.client, o.object.empty() ? joined->info.objects(0).name() : o.object,
          /*decode_on_receipt=*/index == 0);
      SCULPT_RETURN_IF_ERROR(c.view->Subscribe(o.viewer_mesh_hz));
    }
    for (const auto& [name, bytes] : joined->state) state_bytes_at_join += bytes.size();
  }
  const double setup_s = Seconds(Clock::now() - t_setup);

  // The undo client (issue 15): a sculptor outside `clients`, so the totals stay the others'.
  std::unique_ptr<SimClient> undoer;
  auto undo_seen = std::make_shared<UndoSeen>();
  if (o.undo_every > 0) {
    undoer = std::make_unique<SimClient>();
    undoer->name = "undoer";
    undoer->sculptor = true;
    ClientOptions co;
    co.tls = o.tls;
    co.io = io[0];
    co.skip_state = true;
    undoer->client = std::make_unique<Client>(co);
    const Client::EventHandler base = MakeHandler(undoer->seen);
    undoer->client->SetEventHandler([base, undo_seen](const Event& e) {
      if (e.type != Event::Type::kUndoAck) return base(e);
      const auto now = Clock::now();
      std::lock_guard<std::mutex> lock(undo_seen->mu);
      auto it = undo_seen->sent.find(e.undo_ack.client_seq());
      if (it != undo_seen->sent.end()) undo_seen->in_flight.emplace_back(it->second, now);
      if (!e.undo_ack.accepted()) {
        ++undo_seen->refused;
        if (undo_seen->first_refusals.size() < 3) {
          undo_seen->first_refusals.push_back(ErrorToStatus(e.undo_ack.error()).message());
        }
        return;
      }
      undo_seen->undo_ms.push_back(e.latency_ms);
      undo_seen->replayed.push_back(e.undo_ack.replayed());
    });
    auto joined = EnterScene(*undoer->client, host, port, o.sculptor_token, v1::ROLE_SCULPTOR,
                             "undoer", o.scene, &join_retries);
    if (!joined.ok()) return joined.status();
  }

  // Replica clients: whole-object replicas in replay and in leaf-delta mode.
  auto times = std::make_shared<SendTimes>();
  std::vector<SimClient> replicas(static_cast<size_t>(o.replay_replicas + o.leafdelta_replicas));
  for (size_t i = 0; i < replicas.size(); ++i) {
    SimClient& c = replicas[i];
    c.mode = i < static_cast<size_t>(o.replay_replicas) ? v1::REPLICA_MODE_REPLAY
                                                         : v1::REPLICA_MODE_LEAF_DELTA;
    c.name = std::string(c.mode == v1::REPLICA_MODE_REPLAY ? "replay-" : "leafdelta-") +
             std::to_string(i);
    ClientOptions co;
    co.tls = o.tls;
    co.io = io[i % io.size()];
    co.skip_state = true;
    c.client = std::make_unique<Client>(co);
    c.client->SetEventHandler(MakeHandler(c.seen));
    auto joined = EnterScene(*c.client, host, port, o.viewer_token, v1::ROLE_VIEWER, c.name,
                             o.scene, &join_retries);
    if (!joined.ok()) return joined.status();
    ReplicaOptions ro;
    ro.object = o.object.empty() && joined->info.objects_size() > 0 ? joined->info.objects(0).name()
                                                                    : o.object;
    ro.mode = c.mode;
    c.replica = std::make_unique<Replica>(*c.client, ro);
    const int kind = static_cast<int>(c.mode);
    c.replica->SetAppliedHandler([times, kind](const AppliedEdit& e) {
      const auto now = Clock::now();
      std::lock_guard<std::mutex> lock(times->mu);
      auto it = times->at.find({e.client_id, e.client_seq});
      if (it != times->at.end()) {
        times->visible_ms[kind].push_back(
            std::chrono::duration<double, std::milli>(now - it->second).count());
      }
    });
    SCULPT_RETURN_IF_ERROR(c.replica->Start());
    if (!c.replica->WaitLoaded(1, std::chrono::seconds(60))) {
      return Status(Status::Code::kUnavailable, c.name + ": region not loaded within 60 s");
    }
  }

  // The walk follows the object's surface as SceneInfo bounds it: the bounds hold the centres
  // of the active voxels, which reach up to half_width voxels outside the surface, so the
  // outermost centre lies about (half_width - 1) voxels out (26.5 for the default sphere of
  // radius 24, voxel 0.5, half-width 6).
  const v1::ObjectInfo* object = nullptr;
  for (const v1::ObjectInfo& obj : info.objects()) {
    if (o.object.empty() ? object == nullptr : obj.name() == o.object) object = &obj;
  }
  if (o.sculptors > 0 && object == nullptr) {
    return NotFound("--object=" + o.object + " outside the scene's objects");
  }
  Vec3 center, extent;
  double radius = 0;
  if (object != nullptr) {
    const Vec3 lo{object->bounds_min().x(), object->bounds_min().y(), object->bounds_min().z()};
    const Vec3 hi{object->bounds_max().x(), object->bounds_max().y(), object->bounds_max().z()};
    center = (lo + hi) * 0.5;
    extent = (hi - lo) * 0.5;
    const double band = (static_cast<double>(object->half_width()) - 1.0) * object->voxel_size();
    radius = std::min({extent.x, extent.y, extent.z}) - band;
    if (!(radius > o.depth + o.tool_radius)) {
      return FailedPrecondition("object " + object->name() + ": surface radius " +
                                std::to_string(radius) + " from its bounds is too small to walk");
    }
  }

  const double stroke_period = o.poses_per_stroke / o.rate_hz;
  const double pose_dt = 1.0 / o.rate_hz;
  // The haptic client (issue 5): a replica publishing snapshots every 2 ms into the loop's
  // publisher, and a scripted device pressing 1.5 units in and out of the object's top at 1 Hz.
  std::atomic<int> haptic_cpu{-1};  // outlives the replica, whose thread reads it
  std::unique_ptr<haptics::SnapshotPublisher> publisher;
  std::unique_ptr<haptics::SculptureFeed> feed;
  std::unique_ptr<haptics::ScriptedDevice> device;
  // The loop before the replica: the replica's thread reads the loop's pose (the window), so
  // the replica must go first.
  std::unique_ptr<haptics::HapticLoop> loop;
  std::unique_ptr<Client> haptic_conn;
  std::unique_ptr<Replica> haptic_replica;
  if (o.haptic_client && object != nullptr) {
    publisher = std::make_unique<haptics::SnapshotPublisher>();
    feed = std::make_unique<haptics::SculptureFeed>(publisher.get(), /*seal=*/false);
    ClientOptions co;
    co.tls = o.tls;
    co.io = io[0];
    co.skip_state = true;
    haptic_conn = std::make_unique<Client>(co);
    auto j = EnterScene(*haptic_conn, host, port, o.viewer_token, v1::ROLE_VIEWER, "haptic",
                        o.scene, &join_retries);
    if (!j.ok()) return j.status();
    ReplicaOptions ro;
    ro.object = object->name();
    ro.snapshot_interval = std::chrono::milliseconds(2);
    haptic_replica = std::make_unique<Replica>(*haptic_conn, ro);
    haptics::SculptureFeed* f = feed.get();
    // The replay thread keeps off the haptic loop's CPU (chosen at Create, below), from its
    // first snapshot after that on.
    std::atomic<int>* cpu = &haptic_cpu;
    haptic_replica->SetSnapshotHandler(
        [f, cpu, tried = false](std::shared_ptr<const levelset::Sculpture> s, uint64_t seq) mutable {
          if (!tried && cpu->load() >= 0) {
            tried = true;
            haptics::PinThreadAwayFromCpu(cpu->load());
          }
          f->Publish(std::move(s), seq);
        });
    SCULPT_RETURN_IF_ERROR(haptic_replica->Start());
    if (!haptic_replica->WaitLoaded(1, std::chrono::seconds(60))) {
      return Status(Status::Code::kUnavailable, "haptic client: region not loaded within 60 s");
    }
    const Vec3 top = center + Vec3{0, 0, radius};
    device = std::make_unique<haptics::ScriptedDevice>([top](double t) {
      return top + Vec3{0, 0, 1.0 - 2.5 * (0.5 - 0.5 * std::cos(2 * M_PI * t))};
    });
    haptics::HapticSettings hs;
    hs.tick_budget_us = haptics::kLoopTickBudgetUs;
    auto l = haptics::HapticLoop::Create(hs, publisher.get(), device.get());
    if (!l.ok()) return l.status();
    loop = std::move(l).value();
    haptic_cpu = loop->cpu();
    // Snapshots carry the band around the tool densely (filled on the replica's thread).
    feed->SetWindow([lp = loop.get()] { return lp->SamplePose().position; },
                    hs.tool_radius + 6 * object->voxel_size());
    // Wait for a first snapshot so the loop renders from the start.
    const auto until = Clock::now() + std::chrono::seconds(30);
    while (!haptic_replica->Snapshot() && Clock::now() < until) {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    SCULPT_RETURN_IF_ERROR(loop->Start());
  }

  const auto t_start = Clock::now();
  for (SimClient& c : replicas) c.at_start = c.client->stats();  // after the region loads
  for (size_t i = 0; i < clients.size(); ++i) {
    SimClient& c = clients[i];
    c.at_start = c.client->stats();
    if (!c.sculptor) continue;
    c.walk = std::make_unique<SurfaceWalk>(Mix(o.seed * 0x100000001b3ull + i), center, radius,
                                           o.depth, o.walk_speed);
    // Staggered so the sculptors' strokes do not all leave in the same instant.
    c.next_send =
        t_start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(
                      stroke_period * static_cast<double>(i) / std::max(1, o.sculptors)));
  }
  if (undoer) {
    // Its walk starts where sculptor-0's does, so the others' strokes overlap what it undoes.
    undoer->walk = std::make_unique<SurfaceWalk>(Mix(o.seed * 0x100000001b3ull), center, radius,
                                                 o.depth, o.walk_speed);
    undoer->next_send = t_start + std::chrono::duration_cast<Clock::duration>(
                                      std::chrono::duration<double>(stroke_period * 0.5));
  }
  int undoer_turns = 0;

  // The driver: one thread paces every sculptor; a stroke carries the poses sampled since the
  // previous one, timestamped at the sampling rate.
  const auto t_stop = t_start + std::chrono::duration_cast<Clock::duration>(
                                    std::chrono::duration<double>(o.seconds));
  for (;;) {
    SimClient* due = nullptr;
    for (SimClient& c : clients) {
      if (c.sculptor && c.next_send < t_stop && (!due || c.next_send < due->next_send)) due = &c;
    }
    if (undoer && undoer->next_send < t_stop && (!due || undoer->next_send < due->next_send)) {
      due = undoer.get();
    }
    if (due == nullptr) break;
    if (due == undoer.get() && ++undoer_turns % o.undo_every == 0) {
      std::this_thread::sleep_until(due->next_send);
      std::lock_guard<std::mutex> lock(undo_seen->mu);
      const auto seq = due->client->SendUndo(object->name());
      if (seq.ok()) {
        undo_seen->sent[*seq] = Clock::now();
      } else {
        ++due->send_failures;
      }
      due->next_send +=
          std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(stroke_period));
      continue;
    }
    std::this_thread::sleep_until(due->next_send);
    if (!due->client->connected()) {
      // The server dropped it: reconnect (resending what is un-acked), at most once a period.
      if (!due->client->Reconnect().ok()) ++due->reconnect_failures;
    }
    StrokeRequest s;
    s.object = object->name();
    s.kind = v1::EDIT_KIND_PRESS;
    s.tool = v1::TOOL_KIND_SPHERE;
    s.tool_size = {o.tool_radius, 0, 0};
    s.speed = o.press_speed;
    s.t0_ms = static_cast<uint64_t>(Seconds(Clock::now() - t_start) * 1000.0);
    for (int k = 0; k < o.poses_per_stroke; ++k) {
      codec::Pose p;
      p.position = due->walk->Next(pose_dt);
      p.t_ms = static_cast<uint32_t>(std::lround(k * pose_dt * 1000.0));
      s.poses.push_back(p);
    }
    {
      // Recorded before the send, so a fast replica never sees its edit before the time exists.
      std::lock_guard<std::mutex> lock(times->mu);
      const auto seq = due->client->SendStroke(s);
      if (!seq.ok()) {
        ++due->send_failures;
      } else {
        times->at[{due->client->client_id(), *seq}] = Clock::now();
      }
    }
    due->next_send +=
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(stroke_period));
  }
  const auto t_sent = Clock::now();

  const auto drain_deadline = t_sent + std::chrono::duration_cast<Clock::duration>(
                                           std::chrono::duration<double>(o.drain_seconds));
  for (SimClient& c : clients) {
    if (!c.sculptor) continue;
    const auto left = std::max(Clock::duration::zero(), drain_deadline - Clock::now());
    c.client->WaitAllAcked(std::chrono::duration_cast<std::chrono::milliseconds>(left));
  }
  if (undoer) {
    const auto left = std::max(Clock::duration::zero(), drain_deadline - Clock::now());
    undoer->client->WaitAllAcked(std::chrono::duration_cast<std::chrono::milliseconds>(left));
  }
  uint64_t last_seq = 0;
  for (SimClient& c : clients) last_seq = std::max(last_seq, c.client->stats().last_global_seq);
  for (SimClient& c : replicas) {
    const auto left = std::max(Clock::duration::zero(), drain_deadline - Clock::now());
    c.replica->WaitForSeq(last_seq, std::chrono::duration_cast<std::chrono::milliseconds>(left));
  }
  const auto t_end = Clock::now();
  const double duration_s = Seconds(t_end - t_start);

  json per_client = json::array();
  std::vector<double> all_latencies, all_edit_ms;
  std::map<std::string, uint64_t> errors_by_code;
  uint64_t sent = 0, acked = 0, refused = 0, unacked = 0, errors = 0, duplicates = 0,
           poses_acked = 0, final_seq = 0, viewer_bytes = 0, viewer_bytes_window = 0, presence = 0,
           reconnects = 0;
  uint64_t up[2] = {0, 0}, down[2] = {0, 0};  // [viewer, sculptor], within the window
  bool in_order = true;
  for (SimClient& c : clients) {
    const ClientStats st = c.client->stats();
    const uint64_t pending = c.client->unacked();
    std::lock_guard<std::mutex> lock(c.seen->mu);
    const uint64_t bytes_up = st.bytes_sent - c.at_start.bytes_sent;
    const uint64_t bytes_down = st.bytes_received - c.at_start.bytes_received;
    up[c.sculptor] += bytes_up;
    down[c.sculptor] += bytes_down;
    sent += st.strokes_sent;
    acked += st.acks;
    refused += st.refused;
    unacked += pending;
    errors += st.errors;
    duplicates += st.duplicate_acks;
    poses_acked += st.poses_acked;
    presence += st.presence;
    reconnects += st.reconnects;
    final_seq = std::max(final_seq, st.last_global_seq);
    in_order = in_order && st.acks_out_of_order == 0;
    if (!c.sculptor) {
      viewer_bytes += st.bytes_received;
      viewer_bytes_window += bytes_down;
    }
    for (const auto& [code, n] : c.seen->errors_by_code) errors_by_code[code] += n;
    all_latencies.insert(all_latencies.end(), c.seen->latencies_ms.begin(),
                         c.seen->latencies_ms.end());
    all_edit_ms.insert(all_edit_ms.end(), c.seen->edit_ms.begin(), c.seen->edit_ms.end());
    json entry = {{"name", c.name},
                  {"role", c.sculptor ? "sculptor" : "viewer"},
                  {"client_id", c.client->client_id()},
                  {"bytes_up", bytes_up},
                  {"bytes_down", bytes_down},
                  {"bytes_down_total", st.bytes_received},
                  {"server_errors", st.errors},
                  {"presence_updates", st.presence},
                  {"connected_at_end", c.client->connected()}};
    if (c.sculptor) {
      entry["strokes_sent"] = st.strokes_sent;
      entry["strokes_acked"] = st.acks;
      entry["strokes_refused"] = st.refused;
      entry["strokes_unacked"] = pending;
      entry["duplicate_acks"] = st.duplicate_acks;
      entry["acks_in_order"] = st.acks_out_of_order == 0;
      entry["last_global_seq"] = st.last_global_seq;
      entry["stroke_ack"] = LatencyJson(c.seen->latencies_ms);
      entry["send_failures"] = c.send_failures;
      entry["reconnects"] = st.reconnects;
      entry["reconnect_failures"] = c.reconnect_failures;
    }
    if (!c.seen->first_errors.empty()) entry["first_errors"] = c.seen->first_errors;
    if (!c.seen->disconnects.empty()) entry["disconnects"] = c.seen->disconnects;
    per_client.push_back(std::move(entry));
  }
  std::sort(all_latencies.begin(), all_latencies.end());
  std::sort(all_edit_ms.begin(), all_edit_ms.end());

  const double n_clients = static_cast<double>(clients.size());
  const auto per_s = [duration_s](double bytes, double n) {
    return n > 0 && duration_s > 0 ? Round3(bytes / n / duration_s) : 0.0;
  };
  json report = {
      {"strokes_sent", sent},
      {"strokes_acked", acked},
      {"strokes_refused", refused},
      {"strokes_unacked", unacked},
      {"acks_in_order", in_order},
      {"stroke_ack_p50_ms", Round3(Percentile(all_latencies, 0.50))},
      {"stroke_ack_p99_ms", Round3(Percentile(all_latencies, 0.99))},
      {"stroke_ack_max_ms", Round3(all_latencies.empty() ? 0.0 : all_latencies.back())},
      {"server_errors", errors},
      {"server_errors_by_code", errors_by_code},
      {"bytes_up_per_client_per_s", per_s(static_cast<double>(up[0] + up[1]), n_clients)},
      {"bytes_down_per_client_per_s", per_s(static_cast<double>(down[0] + down[1]), n_clients)},
      {"sculptor_bytes_up_per_s", per_s(static_cast<double>(up[1]), o.sculptors)},
      {"sculptor_bytes_down_per_s", per_s(static_cast<double>(down[1]), o.sculptors)},
      {"viewer_bytes_down_per_s", per_s(static_cast<double>(down[0]), o.viewers)},
      {"viewers_received_bytes", viewer_bytes},
      {"viewers_received_bytes_in_window", viewer_bytes_window},
      {"state_bytes_at_join", state_bytes_at_join},
      {"join_retries", join_retries.load()},
      {"duration_s", Round3(duration_s)},
      {"send_s", Round3(Seconds(t_sent - t_start))},
      {"drain_s", Round3(Seconds(t_end - t_sent))},
      {"setup_s", Round3(setup_s)},
      {"duplicate_acks", duplicates},
      {"poses_acked", poses_acked},
      {"edits_acked_per_s", per_s(static_cast<double>(poses_acked), 1)},
      {"offered_edits_per_s", Round3(o.sculptors * o.rate_hz)},
      {"server_edit_ms_p50", Round3(Percentile(all_edit_ms, 0.50))},
      {"server_edit_ms_p99", Round3(Percentile(all_edit_ms, 0.99))},
      {"final_global_seq", final_seq},
      {"presence_updates", presence},
      {"reconnects", reconnects},
      {"config",
       {{"server", o.server},
        {"scene", info.scene()},
        {"object", object ? object->name() : ""},
        {"sculptors", o.sculptors},
        {"viewers", o.viewers},
        {"rate_hz", o.rate_hz},
        {"poses_per_stroke", o.poses_per_stroke},
        {"strokes_per_second_per_sculptor", Round3(o.rate_hz / o.poses_per_stroke)},
        {"seconds", o.seconds},
        {"seed", o.seed},
        {"tool_radius", o.tool_radius},
        {"press_speed", o.press_speed},
        {"walk_speed", o.walk_speed},
        {"depth", o.depth},
        {"surface_radius", Round3(radius)}}},
      {"clients", per_client},
  };

  if (undoer) {
    // The others' strokes in flight (sent .. acked) while an undo was (sent .. answered).
    std::vector<double> during, otherwise;
    std::lock_guard<std::mutex> ulock(undo_seen->mu);
    for (SimClient& c : clients) {
      if (!c.sculptor) continue;
      std::lock_guard<std::mutex> lock(c.seen->mu);
      for (const auto& [at, ms] : c.seen->acked_at) {
        const auto sent_at = at - std::chrono::duration_cast<Clock::duration>(
                                      std::chrono::duration<double, std::milli>(ms));
        const bool overlaps =
            std::any_of(undo_seen->in_flight.begin(), undo_seen->in_flight.end(),
                        [&](const auto& u) { return sent_at <= u.second && at >= u.first; });
        (overlaps ? during : otherwise).push_back(ms);
      }
    }
    std::vector<double> replayed = undo_seen->replayed;
    std::sort(replayed.begin(), replayed.end());
    const ClientStats st = undoer->client->stats();
    json u = {{"undo_every", o.undo_every},
              {"strokes_acked", st.acks},
              {"undos_sent", st.undos_sent},
              {"undos_accepted", undo_seen->undo_ms.size()},
              {"undos_refused", undo_seen->refused},
              {"undo_ms", LatencyJson(undo_seen->undo_ms)},
              {"replayed_p50", Percentile(replayed, 0.5)},
              {"replayed_max", replayed.empty() ? 0.0 : replayed.back()},
              {"others_stroke_ack_during_undo", LatencyJson(during)},
              {"others_strokes_during_undo", during.size()},
              {"others_stroke_ack_otherwise", LatencyJson(otherwise)},
              {"others_strokes_otherwise", otherwise.size()}};
    if (!undo_seen->first_refusals.empty()) u["first_refusals"] = undo_seen->first_refusals;
    report["undo_client"] = std::move(u);
  }

  // Replication (issue 4): bytes each replica client received during the run, per second.
  uint64_t mode_bytes[3] = {0, 0, 0};
  int mode_count[3] = {0, 0, 0};
  uint64_t mismatches = 0, replica_errors = 0;
  json replica_entries = json::array();
  for (SimClient& c : replicas) {
    const ClientStats st = c.client->stats();
    const ReplicaStats rs = c.replica->stats();
    const int kind = static_cast<int>(c.mode);
    mode_bytes[kind] += st.bytes_received - c.at_start.bytes_received;
    ++mode_count[kind];
    mismatches += rs.hash_mismatches;
    replica_errors += rs.errors;
    replica_entries.push_back({{"name", c.name},
                               {"bytes_down", st.bytes_received - c.at_start.bytes_received},
                               {"region_load_bytes", rs.load_bytes},
                               {"edit_payload_bytes", rs.bytes},
                               {"broadcasts_applied", rs.broadcasts_applied},
                               {"deltas_applied", rs.deltas_applied},
                               {"hash_mismatches", rs.hash_mismatches},
                               {"errors", rs.errors},
                               {"seq", rs.seq},
                               {"apply_ms_total", Round3(rs.apply_ms)}});
  }
  std::vector<double> vis_replay, vis_delta;
  {
    std::lock_guard<std::mutex> lock(times->mu);
    vis_replay = times->visible_ms[v1::REPLICA_MODE_REPLAY];
    vis_delta = times->visible_ms[v1::REPLICA_MODE_LEAF_DELTA];
  }
  std::sort(vis_replay.begin(), vis_replay.end());
  std::sort(vis_delta.begin(), vis_delta.end());
  const double replay_bps = per_s(static_cast<double>(mode_bytes[v1::REPLICA_MODE_REPLAY]),
                                  mode_count[v1::REPLICA_MODE_REPLAY]);
  const double delta_bps = per_s(static_cast<double>(mode_bytes[v1::REPLICA_MODE_LEAF_DELTA]),
                                 mode_count[v1::REPLICA_MODE_LEAF_DELTA]);
  report["replica_bytes_down_per_s"] = replay_bps;
  {
    // The replication payload alone (broadcasts), without presence and acks.
    uint64_t payload = 0;
    for (SimClient& c : replicas) {
      if (c.mode == v1::REPLICA_MODE_REPLAY) payload += c.replica->stats().bytes;
    }
    report["replica_edit_payload_bytes_per_s"] =
        per_s(static_cast<double>(payload), mode_count[v1::REPLICA_MODE_REPLAY]);
  }
  report["leafdelta_bytes_down_per_s"] = delta_bps;
  report["leafdelta_over_replay_bytes"] = replay_bps > 0 ? Round3(delta_bps / replay_bps) : 0.0;
  report["edit_visible_p50_ms"] = Round3(Percentile(vis_replay, 0.50));
  report["edit_visible_p99_ms"] = Round3(Percentile(vis_replay, 0.99));
  report["edit_visible_samples"] = vis_replay.size();
  report["leafdelta_visible_p50_ms"] = Round3(Percentile(vis_delta, 0.50));
  report["leafdelta_visible_p99_ms"] = Round3(Percentile(vis_delta, 0.99));
  report["hash_mismatches"] = mismatches;
  {
    std::vector<double> enc, dec;
    uint64_t chunks = 0, draco_bytes = 0;
    for (SimClient& c : clients) {
      if (!c.view) continue;
      const MeshViewStats ms = c.view->stats();
      chunks += ms.chunks_received;
      draco_bytes += ms.bytes;
      if (enc.empty()) enc = ms.encode_ms;
      dec.insert(dec.end(), ms.decode_ms.begin(), ms.decode_ms.end());
    }
    std::sort(enc.begin(), enc.end());
    std::sort(dec.begin(), dec.end());
    report["viewer_mesh_hz"] = o.viewer_mesh_hz;
    report["viewer_chunks_received"] = chunks;
    report["viewer_draco_bytes"] = draco_bytes;
    report["draco_chunk_encode_ms_p50"] = Round3(Percentile(enc, 0.50));
    report["draco_chunk_encode_ms_p99"] = Round3(Percentile(enc, 0.99));
    report["draco_chunk_decode_ms_p50"] = Round3(Percentile(dec, 0.50));
    report["draco_chunk_decode_ms_p99"] = Round3(Percentile(dec, 0.99));
  }
  report["replica_errors"] = replica_errors;
  report["replicas"] = replica_entries;
  report["config"]["replay_replicas"] = o.replay_replicas;
  report["config"]["leafdelta_replicas"] = o.leafdelta_replicas;

  if (loop) {
    loop->Stop();
    const haptics::HapticLoopStats hst = loop->stats();
    report["haptic_rate_hz"] = Round3(hst.rate_hz);
    report["haptic_period_err_p99_us"] = Round3(hst.period_err_p99_us);
    report["haptic_period_err_max_us"] = Round3(hst.period_err_max_us);
    report["haptic_ticks_over_2ms"] = hst.ticks_over_2ms;
    report["haptic_missed_deadlines"] = hst.missed_deadlines;
    report["haptic_overruns"] = hst.overruns;
    report["haptic_tick_cost_p50_us"] = Round3(hst.tick_cost_p50_us);
    report["haptic_tick_cost_p99_us"] = Round3(hst.tick_cost_p99_us);
    report["haptic_tick_cost_max_us"] = Round3(hst.tick_cost_max_us);
    report["haptic_period_err_p50_us"] = Round3(hst.period_err_p50_us);
    report["haptic_ticks_over_budget"] = hst.ticks_over_budget;
    report["haptic_scheduling"] = hst.scheduling;
    report["haptic_mlockall"] = hst.memory_locked;
    report["haptic_cpu"] = hst.cpu;
    report["haptic_snapshot_windows"] = feed->stats().windows;
    report["haptic_snapshot_window_ms"] = Round3(feed->stats().window_ms);
    report["haptic_snapshot_lag_p50_ms"] = Round3(hst.snapshot_lag_p50_ms);
    report["haptic_snapshot_lag_p99_ms"] = Round3(hst.snapshot_lag_p99_ms);
    report["haptic_snapshots_seen"] = hst.snapshots_seen;
    report["haptic_ticks"] = hst.ticks;
    haptic_replica->SetSnapshotHandler(nullptr);
    haptic_replica.reset();
    (void)haptic_conn->Close("load run finished");
  }
  for (SimClient& c : replicas) c.replica.reset();
  for (SimClient& c : replicas) (void)c.client->Close("load run finished");
  for (SimClient& c : clients) c.view.reset();
  for (SimClient& c : clients) (void)c.client->Close("load run finished");
  return report;
}

StatusOr<nlohmann::ordered_json> RunLateJoin(const LoadOptions& o) {
  std::string host;
  uint16_t port = 0;
  SCULPT_RETURN_IF_ERROR(ParseServerAddress(o.server, &host, &port));
  const auto t0 = Clock::now();
  ClientOptions co;
  co.tls = o.tls;
  co.skip_state = true;
  co.timeout = std::chrono::seconds(60);
  Client client(co);
  std::atomic<uint64_t> join_retries{0};
  auto joined = EnterScene(client, host, port, o.viewer_token, v1::ROLE_VIEWER, "late-join",
                           o.scene, &join_retries);
  if (!joined.ok()) return joined.status();
  ReplicaOptions ro;
  ro.object = o.object.empty() && joined->info.objects_size() > 0 ? joined->info.objects(0).name()
                                                                  : o.object;
  Replica replica(client, ro);
  SCULPT_RETURN_IF_ERROR(replica.Start());
  if (!replica.WaitLoaded(1, std::chrono::seconds(120))) {
    return Status(Status::Code::kUnavailable, "late join: region not loaded within 120 s");
  }
  const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  const ClientStats st = client.stats();
  const ReplicaStats rs = replica.stats();
  json r = {{"late_join_bytes", st.bytes_received},
            {"late_join_ms", Round3(ms)},
            {"region_load_bytes", rs.load_bytes},
            {"apply_ms", Round3(rs.apply_ms)},
            {"object", ro.object},
            {"server", o.server}};
  for (const v1::ObjectInfo& obj : joined->info.objects()) {
    if (obj.name() != ro.object) continue;
    r["voxel_size"] = obj.voxel_size();
    r["half_width"] = obj.half_width();
    r["bounds_min"] = {obj.bounds_min().x(), obj.bounds_min().y(), obj.bounds_min().z()};
    r["bounds_max"] = {obj.bounds_max().x(), obj.bounds_max().y(), obj.bounds_max().z()};
  }
  (void)client.Close("late join measured");
  return r;
}

StatusOr<nlohmann::ordered_json> RunMeshJoin(const LoadOptions& o, int chunk_voxels,
                                             double timeout_s) {
  std::string host;
  uint16_t port = 0;
  SCULPT_RETURN_IF_ERROR(ParseServerAddress(o.server, &host, &port));
  mesh::ChunkMeshOptions mo;
  mo.chunk_voxels = chunk_voxels;
  SCULPT_RETURN_IF_ERROR(mesh::ValidateChunkMeshOptions(mo));
  ClientOptions co;
  co.tls = o.tls;
  co.skip_state = true;
  co.timeout = std::chrono::seconds(60);
  co.max_frame_bytes = 256u << 20;  // a large object's region arrives as one load
  std::atomic<uint64_t> join_retries{0};
  // The chunks a complete mesh holds, from the object as a replica loads it.
  std::string object = o.object;
  std::set<std::array<int, 3>> expected;
  double replica_ms = 0;
  {
    const auto t0 = Clock::now();
    Client client(co);
    auto joined = EnterScene(client, host, port, o.viewer_token, v1::ROLE_VIEWER,
                             "mesh-join-replica", o.scene, &join_retries);
    if (!joined.ok()) return joined.status();
    if (object.empty() && joined->info.objects_size() > 0) object = joined->info.objects(0).name();
    ReplicaOptions ro;
    ro.object = object;
    ro.snapshot_interval = std::chrono::milliseconds(10);
    Replica replica(client, ro);
    SCULPT_RETURN_IF_ERROR(replica.Start());
    if (!replica.WaitLoaded(1, std::chrono::seconds(120))) {
      return Status(Status::Code::kUnavailable, "mesh join: region not loaded within 120 s");
    }
    replica_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    auto snap = replica.Snapshot();
    for (int i = 0; !snap && i < 500; ++i) {  // published on the replica's thread
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      snap = replica.Snapshot();
    }
    if (!snap) return Status(Status::Code::kUnavailable, "mesh join: replica has no snapshot");
    for (const mesh::ChunkKey& k : mesh::AllChunks(*snap, mo)) expected.insert({k.x, k.y, k.z});
    (void)client.Close("mesh join: chunks listed");
  }
  if (expected.empty()) return Status(Status::Code::kFailedPrecondition, "mesh join: no surface");
  // The new viewer: every chunk key it receives, and when the expected set fills.
  std::mutex mu;
  std::set<std::array<int, 3>> got;
  size_t hits = 0;
  uint64_t frames = 0, bytes = 0, wrong_voxels = 0;
  Client viewer(co);
  const auto t_join = Clock::now();
  auto joined = EnterScene(viewer, host, port, o.viewer_token, v1::ROLE_VIEWER, "mesh-join",
                           o.scene, &join_retries);
  if (!joined.ok()) return joined.status();
  viewer.SetReplicationHandler([&](v1::ServerMessage&& m) {
    if (!m.has_mesh_chunk() || m.mesh_chunk().object() != object) return;
    const v1::MeshChunk& c = m.mesh_chunk();
    if (c.key_size() != 3) return;
    std::lock_guard<std::mutex> lock(mu);
    ++frames;
    bytes += c.draco().size();
    if (static_cast<int>(c.chunk_voxels()) != chunk_voxels) ++wrong_voxels;
    const std::array<int, 3> key{c.key(0), c.key(1), c.key(2)};
    if (got.insert(key).second && expected.count(key)) ++hits;
  });
  const auto t_sub = Clock::now();
  v1::ClientMessage sub;
  sub.mutable_viewer_subscribe()->set_object(object);
  sub.mutable_viewer_subscribe()->set_max_rate_hz(static_cast<float>(o.viewer_mesh_hz));
  SCULPT_RETURN_IF_ERROR(viewer.SendMessage(sub));
  const size_t n = expected.size();
  const size_t at50 = (n + 1) / 2, at99 = std::max<size_t>(1, (n * 99 + 99) / 100);
  double ms50 = -1, ms99 = -1, ms100 = -1;
  auto ms = [&](Clock::time_point from) {
    return Round3(std::chrono::duration<double, std::milli>(Clock::now() - from).count());
  };
  const auto deadline = t_sub + std::chrono::duration_cast<Clock::duration>(
                                    std::chrono::duration<double>(timeout_s));
  size_t reached = 0;
  while (Clock::now() < deadline) {
    {
      std::lock_guard<std::mutex> lock(mu);
      reached = hits;
    }
    if (ms50 < 0 && reached >= at50) ms50 = ms(t_sub);
    if (ms99 < 0 && reached >= at99) ms99 = ms(t_sub);
    if (reached >= n) {
      ms100 = ms(t_sub);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  const double join_ms = std::chrono::duration<double, std::milli>(t_sub - t_join).count();
  viewer.SetReplicationHandler(nullptr);
  std::lock_guard<std::mutex> lock(mu);
  json r = {{"object", object},
            {"chunk_voxels", chunk_voxels},
            {"expected_chunks", n},
            {"received_expected_chunks", reached},
            {"complete", reached >= n},
            {"join_ms", Round3(join_ms)},
            {"subscribe_to_50pct_ms", ms50},
            {"subscribe_to_99pct_ms", ms99},
            {"subscribe_to_complete_ms", ms100},
            {"join_to_complete_ms", ms100 < 0 ? -1.0 : Round3(join_ms + ms100)},
            {"chunk_frames", frames},
            {"chunk_draco_bytes", bytes},
            {"chunks_with_other_chunk_voxels", wrong_voxels},
            {"replica_load_ms", Round3(replica_ms)},
            {"timeout_s", timeout_s},
            {"server", o.server}};
  (void)viewer.Close("mesh join measured");
  return r;
}

}  // namespace sculpt::client
