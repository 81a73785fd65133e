/// @brief `sculpt play`: the stroke script reader, the timed sender and the JSON summary.
#include "play_cmd.h"

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>
#include <vector>

#include "sculpt/client/client.h"
#include "sculpt/client/replica.h"
#include "sculpt/haptics/haptic_loop.h"
#include "sculpt/haptics/monitored_device.h"
#include "sculpt/haptics/sculpture_feed.h"
#include "sculpt/haptics/sculpture_snapshot.h"
#include "undo_cmd.h"

namespace sculpt::client {

// The stroke script (also printed by --help):
//
// {
//   "scene": "default",                 optional; --scene overrides it
//   "object": "clay",                   defaults for every stroke (each may override them)
//   "kind": "press",                    press | add | subtract | smooth | inflate | deflate
//   "tool": "sphere",                   sphere | ellipsoid | box | capsule
//   "size": [2.5, 0, 0],                world units (radius in x); a number means [r, 0, 0]
//   "speed": 60,                        press speed, world units per second
//   "amount": 0,                        inflate/deflate distance, smooth flow time
//   "strokes": [
//     {"t_ms": 0,                       when to send it, ms after the start
//      "poses": [[x, y, z, t_ms], ...]} world positions; t_ms after the stroke's t_ms
//   ]
// }
//
// A pose without t_ms is taken 1/120 s after the previous one. Strokes are sent in t_ms order
// (ties in file order).
const char kPlayScriptHelp[] =
    "Script (JSON): {\"scene\": \"default\", \"object\": \"clay\" (default: --object, else "
    "the scene's first object), \"kind\": \"press\", "
    "\"tool\": \"sphere\", \"size\": [2.5, 0, 0], \"speed\": 60, \"amount\": 0, \"strokes\": "
    "[{\"t_ms\": 0, \"poses\": [[x, y, z, t_ms], ...]}, ...]}. kind: press|add|subtract|"
    "smooth|inflate|deflate; tool: sphere|ellipsoid|box|capsule; size in world units (a number "
    "means [r, 0, 0]); stroke t_ms = ms after the start (when it is sent); pose t_ms = ms after "
    "the stroke's (default: previous + 8). A stroke may override object, kind, tool, size, "
    "speed and amount. Prints a JSON summary; exits 1 if a stroke is refused or un-acked, 2 "
    "for a bad script.\n\n"
    "Haptics (--haptics): joins as a sculptor with a replica of the object (all of it, or a box "
    "of half-size --interest-radius that follows the tool), runs the 1 kHz haptic loop on the "
    "replica's snapshots with a simulated device, and sends strokes of the script's kind and "
    "tool sampled from the device (--stroke-rate strokes/s, 4 poses each, only while the tool "
    "touches the clay). The device follows the script's poses as a trajectory (times as sent), "
    "or without --script a built-in path: approach the top of the object, press in, slide, "
    "lift (--duration s). Prints force and loop statistics (--json: as JSON: haptic_rate_hz, "
    "haptic_period_err_p99_us, haptic_ticks_over_2ms, haptic_snapshot_lag_p99_ms, "
    "haptic_torn_ticks with --verify-snapshots, force_max, ...).";

namespace {

// The dense window around the haptic tool: its radius plus this many voxels, so the tool's
// stencils stay inside while it moves between snapshots.
constexpr double kWindowMarginVoxels = 6;

using Clock = std::chrono::steady_clock;
using nlohmann::json;

struct ScriptStroke {
  uint64_t t_ms = 0;
  size_t index = 0;  // position in the file
  StrokeRequest request;
};

Status Bad(const std::string& path, const json& value, const std::string& allowed) {
  std::string text = value.dump();
  if (text.size() > 60) text = text.substr(0, 57) + "...";
  return InvalidArgument(path + "=" + text + " outside " + allowed);
}

Status ReadNumber(const json& j, const std::string& path, double lo, double hi, double* out) {
  if (!j.is_number() || !std::isfinite(j.get<double>()) || j.get<double>() < lo ||
      j.get<double>() > hi) {
    return Bad(path, j, "numbers in [" + json(lo).dump() + ", " + json(hi).dump() + "]");
  }
  *out = j.get<double>();
  return Status::Ok();
}

/// Reads the fields a stroke shares with the script's defaults into `r`.
Status ReadStrokeFields(const json& j, const std::string& path, StrokeRequest* r) {
  static const std::map<std::string, v1::EditKind> kKinds = {
      {"press", v1::EDIT_KIND_PRESS},       {"add", v1::EDIT_KIND_ADD},
      {"subtract", v1::EDIT_KIND_SUBTRACT}, {"smooth", v1::EDIT_KIND_SMOOTH},
      {"inflate", v1::EDIT_KIND_INFLATE},   {"deflate", v1::EDIT_KIND_DEFLATE}};
  static const std::map<std::string, v1::ToolKind> kTools = {{"sphere", v1::TOOL_KIND_SPHERE},
                                                             {"ellipsoid", v1::TOOL_KIND_ELLIPSOID},
                                                             {"box", v1::TOOL_KIND_BOX},
                                                             {"capsule", v1::TOOL_KIND_CAPSULE}};
  if (j.contains("object")) {
    if (!j["object"].is_string()) return Bad(path + ".object", j["object"], "strings");
    r->object = j["object"].get<std::string>();
  }
  if (j.contains("kind")) {
    const json& k = j["kind"];
    if (!k.is_string() || !kKinds.count(k.get<std::string>())) {
      return Bad(path + ".kind", k, "{press, add, subtract, smooth, inflate, deflate}");
    }
    r->kind = kKinds.at(k.get<std::string>());
  }
  if (j.contains("tool")) {
    const json& t = j["tool"];
    if (!t.is_string() || !kTools.count(t.get<std::string>())) {
      return Bad(path + ".tool", t, "{sphere, ellipsoid, box, capsule}");
    }
    r->tool = kTools.at(t.get<std::string>());
  }
  if (j.contains("size")) {
    const json& s = j["size"];
    if (s.is_number()) {
      double x = 0;
      SCULPT_RETURN_IF_ERROR(ReadNumber(s, path + ".size", 0, 1e6, &x));
      r->tool_size = {x, 0, 0};
    } else if (s.is_array() && s.size() == 3) {
      double v[3];
      for (int i = 0; i < 3; ++i) {
        SCULPT_RETURN_IF_ERROR(
            ReadNumber(s[i], path + ".size[" + std::to_string(i) + "]", 0, 1e6, &v[i]));
      }
      r->tool_size = {v[0], v[1], v[2]};
    } else {
      return Bad(path + ".size", s, "a number or [x, y, z]");
    }
  }
  if (j.contains("speed")) {
    SCULPT_RETURN_IF_ERROR(ReadNumber(j["speed"], path + ".speed", 0, 1e9, &r->speed));
  }
  if (j.contains("amount")) {
    SCULPT_RETURN_IF_ERROR(ReadNumber(j["amount"], path + ".amount", 0, 1e9, &r->amount));
  }
  return Status::Ok();
}

StatusOr<std::vector<ScriptStroke>> ParseScript(const json& script, std::string* scene,
                                                StrokeRequest* defaults_out = nullptr) {
  if (!script.is_object()) return Bad("script", script, "a JSON object");
  if (script.contains("scene")) {
    if (!script["scene"].is_string()) return Bad("scene", script["scene"], "strings");
    *scene = script["scene"].get<std::string>();
  }
  StrokeRequest defaults;
  defaults.object.clear();  // unnamed: --object, else the scene's first object (ResolveObject)
  SCULPT_RETURN_IF_ERROR(ReadStrokeFields(script, "script", &defaults));
  if (defaults_out) *defaults_out = defaults;
  if (!script.contains("strokes") || !script["strokes"].is_array()) {
    return Bad("strokes", script.value("strokes", json()), "an array of strokes");
  }
  std::vector<ScriptStroke> out;
  const json& strokes = script["strokes"];
  for (size_t i = 0; i < strokes.size(); ++i) {
    const std::string path = "strokes[" + std::to_string(i) + "]";
    const json& s = strokes[i];
    if (!s.is_object()) return Bad(path, s, "objects {t_ms, poses}");
    ScriptStroke st;
    st.index = i;
    st.request = defaults;
    SCULPT_RETURN_IF_ERROR(ReadStrokeFields(s, path, &st.request));
    double t = 0;
    if (s.contains("t_ms"))
      SCULPT_RETURN_IF_ERROR(ReadNumber(s["t_ms"], path + ".t_ms", 0, 1e10, &t));
    st.t_ms = static_cast<uint64_t>(t);
    st.request.t0_ms = st.t_ms;
    if (!s.contains("poses") || !s["poses"].is_array() || s["poses"].empty()) {
      return Bad(path + ".poses", s.value("poses", json()), "a non-empty array of poses");
    }
    const json& poses = s["poses"];
    uint32_t previous_t = 0;
    for (size_t k = 0; k < poses.size(); ++k) {
      const std::string pp = path + ".poses[" + std::to_string(k) + "]";
      const json& p = poses[k];
      if (!p.is_array() || (p.size() != 3 && p.size() != 4)) {
        return Bad(pp, p, "[x, y, z] or [x, y, z, t_ms]");
      }
      double v[4] = {0, 0, 0, k == 0 ? 0.0 : previous_t + 8.0};
      for (size_t c = 0; c < p.size(); ++c) {
        SCULPT_RETURN_IF_ERROR(ReadNumber(p[c], pp + "[" + std::to_string(c) + "]",
                                          c == 3 ? 0 : -1e9, c == 3 ? 65535 : 1e9, &v[c]));
      }
      codec::Pose pose;
      pose.position = {v[0], v[1], v[2]};
      pose.t_ms = static_cast<uint32_t>(v[3]);
      previous_t = pose.t_ms;
      st.request.poses.push_back(pose);
    }
    out.push_back(std::move(st));
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const ScriptStroke& a, const ScriptStroke& b) { return a.t_ms < b.t_ms; });
  return out;
}

double Percentile(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return 0;
  const size_t rank = static_cast<size_t>(std::ceil(q * static_cast<double>(sorted.size())));
  return sorted[std::clamp<size_t>(rank, 1, sorted.size()) - 1];
}

double Round3(double v) { return std::round(v * 1000.0) / 1000.0; }

json ErrorJson(const v1::Error& e) {
  return {{"client_seq", e.client_seq()},
          {"code", ErrorCodeName(e.code())},
          {"field", e.field()},
          {"value", e.value()},
          {"allowed_range", e.allowed_range()},
          {"message", e.message()}};
}

void Print(const json& j) { std::printf("%s\n", j.dump(2).c_str()); }

/// The client id to sculpt under: --client-id or $SCULPT_CLIENT_ID, else 0 (a random one). A
/// given id may have been used by an earlier run, whose sequences the server would take for
/// resends: then `co` numbers from the clock.
StatusOr<uint64_t> PlayClientId(const PlayOptions& options, ClientOptions* co) {
  const char* env = std::getenv(kClientIdEnv);
  if (options.client_id_text.empty() && (env == nullptr || *env == '\0')) return 0;
  SCULPT_ASSIGN_OR_RETURN(const uint64_t id, ResolveClientId(options.client_id_text));
  co->first_client_seq = ClockClientSeq();
  return id;
}

/// Connects, says hello as a sculptor and joins `scene`. On failure `stage` names the step that
/// failed ("connect", "hello" or "join"), for the report.
StatusOr<JoinedScene> ConnectAsSculptor(Client& client, const PlayOptions& options,
                                        const std::string& host, uint16_t port,
                                        const std::string& scene, uint64_t client_id,
                                        std::string* stage) {
  *stage = "connect";
  SCULPT_RETURN_IF_ERROR(client.Connect(host, port));
  *stage = "hello";
  SCULPT_RETURN_IF_ERROR(
      client.Hello(options.token, v1::ROLE_SCULPTOR, options.name, client_id).status());
  *stage = "join";
  return client.Join(scene);
}

double Smoothstep(double u) {
  u = std::clamp(u, 0.0, 1.0);
  return u * u * (3 - 2 * u);
}

Vec3 Lerp(const Vec3& a, const Vec3& b, double u) { return a + (b - a) * u; }

/// The built-in device path over `duration` seconds: approach the surface point `top` from above,
/// press half a tool radius in, hold, slide two radii along +x, lift back. Each leg eases in and
/// out, so the device's velocity has no steps.
std::function<Vec3(double)> ApproachAndPress(const Vec3& top, double tool_radius, double duration) {
  const Vec3 above = top + Vec3{0, 0, tool_radius + 2};
  const Vec3 in = top - Vec3{0, 0, 0.5 * tool_radius};
  const Vec3 slid = in + Vec3{2 * tool_radius, 0, 0};
  const Vec3 lifted = slid + (above - in);
  const double leg = duration / 4;
  return [=](double t) {
    if (t < leg) return Lerp(above, in, Smoothstep(t / leg));
    if (t < 2 * leg) return in;
    if (t < 3 * leg) return Lerp(in, slid, Smoothstep((t - 2 * leg) / leg));
    return Lerp(slid, lifted, Smoothstep((t - 3 * leg) / leg));
  };
}

/// The first point with phi <= 0 straight below `from`, stepping half a voxel, or nullopt.
std::optional<Vec3> SurfaceBelow(const levelset::Sculpture& s, const Vec3& from, double depth) {
  const double step = 0.5 * s.voxel_size();
  for (double d = 0; d <= depth; d += step) {
    const Vec3 p = from - Vec3{0, 0, d};
    if (s.SampleWorld(p) <= 0) return p;
  }
  return std::nullopt;
}

levelset::Aabb BoxAround(const Vec3& p, double r) { return {p - Vec3{r, r, r}, p + Vec3{r, r, r}}; }

Vec3 FromProto(const v1::Vec3f& v) { return {v.x(), v.y(), v.z()}; }

// The object each stroke sculpts: `forced` (--object) for all of them, else the script's, else
// the scene's first object. NotFound naming the scene's objects for a name the scene lacks.
Status ResolveObject(const v1::SceneInfo& info, const std::string& forced, StrokeRequest* defaults,
                     std::vector<ScriptStroke>* strokes) {
  if (info.objects_size() == 0) return NotFound("scene " + info.scene() + " has no objects");
  const std::string fallback = info.objects(0).name();
  auto resolve = [&](std::string* object) {
    if (!forced.empty()) *object = forced;
    if (object->empty()) *object = fallback;
  };
  resolve(&defaults->object);
  for (ScriptStroke& s : *strokes) resolve(&s.request.object);
  std::string names;
  for (const v1::ObjectInfo& o : info.objects()) names += (names.empty() ? "" : ", ") + o.name();
  auto known = [&](const std::string& name) {
    for (const v1::ObjectInfo& o : info.objects()) {
      if (o.name() == name) return true;
    }
    return false;
  };
  if (!known(defaults->object)) {
    return NotFound("object=" + defaults->object + " outside the scene's objects {" + names + "}");
  }
  for (const ScriptStroke& s : *strokes) {
    if (!known(s.request.object)) {
      return NotFound("strokes[" + std::to_string(s.index) + "].object=" + s.request.object +
                      " outside the scene's objects {" + names + "}");
    }
  }
  return Status::Ok();
}

json Vec3Json(const Vec3& v) { return json::array({Round3(v.x), Round3(v.y), Round3(v.z)}); }

int RunHaptics(const PlayOptions& options, const std::string& host, uint16_t port,
               const std::string& scene, StrokeRequest stroke_template,
               std::vector<ScriptStroke> script) {
  const PlayHapticsOptions& ho = options.haptics;
  haptics::HapticSettings hs;
  auto model = haptics::ParseForceModel(ho.model);
  if (!model.ok()) {
    spdlog::error("--model: {}", model.status().message());
    return 2;
  }
  hs.model = *model;
  hs.stiffness = ho.stiffness;
  hs.damping = ho.damping;
  hs.max_force = ho.max_force;
  hs.tool_radius = ho.tool_radius > 0 ? ho.tool_radius : stroke_template.tool_size.x;
  hs.tool_samples = ho.tool_samples;
  hs.tick_budget_us = haptics::kLoopTickBudgetUs;
  if (const Status s = haptics::ValidateHapticSettings(hs); !s.ok()) {
    spdlog::error("play --haptics: {}", s.message());
    return 2;
  }

  // The device's trajectory from the script: every pose at the time it would have been sent.
  std::vector<haptics::RecordedDevice::Point> points;
  for (const ScriptStroke& st : script) {
    for (const codec::Pose& p : st.request.poses) {
      const double t = (static_cast<double>(st.t_ms) + p.t_ms) / options.speedup / 1000.0;
      if (points.empty() || t > points.back().t) points.push_back({t, p.position});
    }
  }

  ClientOptions co;
  co.tls = options.tls;
  co.timeout = std::chrono::milliseconds(static_cast<int64_t>(options.timeout_s * 1000));
  co.skip_state = true;  // the replica loads its region through Subscribe
  auto client_id = PlayClientId(options, &co);
  if (!client_id.ok()) {
    spdlog::error("play: {}", client_id.status().ToString());
    return 2;
  }
  Client client(co);
  const auto fail = [&](const std::string& stage, const Status& s) {
    Print({{"server", options.server}, {"ok", false}, {"stage", stage}, {"error", s.message()}});
    return 1;
  };
  std::string stage;
  auto joined = ConnectAsSculptor(client, options, host, port, scene, *client_id, &stage);
  if (!joined.ok()) return fail(stage, joined.status());
  if (Status st = ResolveObject(joined->info, options.object, &stroke_template, &script);
      !st.ok()) {
    return fail("join", st);
  }
  const v1::ObjectInfo* object = nullptr;
  for (const v1::ObjectInfo& o : joined->info.objects()) {
    if (o.name() == stroke_template.object) object = &o;
  }
  if (!object) {
    return fail("join",
                NotFound("object=" + stroke_template.object + " outside the scene's objects"));
  }
  const Vec3 lo = FromProto(object->bounds_min()), hi = FromProto(object->bounds_max());
  // The built-in path starts above the middle of the object's top.
  const Vec3 above_top{0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), hi.z + hs.tool_radius + 2};
  const Vec3 start = points.empty() ? above_top : points.front().position;

  // Declared before the replica and the loop: both hold pointers into them.
  haptics::SnapshotPublisher publisher;
  haptics::SculptureFeed feed(&publisher, ho.verify_snapshots);
  ReplicaOptions ro;
  ro.object = stroke_template.object;
  ro.snapshot_interval = std::chrono::milliseconds(ho.snapshot_ms);
  if (ho.interest_radius > 0) {
    ro.interest = BoxAround(start, ho.interest_radius);
    // The built-in path looks for the surface straight below its start, wherever earlier
    // sculpting left it: the first region is the column down to the object's bottom.
    if (points.empty()) ro.interest->min.z = lo.z;
  }
  // Declared before the replica, whose thread reads them: the haptic loop's CPU once it has
  // one; the replay thread moves off it at its next snapshot.
  std::atomic<int> haptic_cpu{-1};
  std::atomic<bool> replica_pinned{false};
  bool replica_pin_tried = false;  // the replica's thread only
  Replica replica(client, ro);
  replica.SetSnapshotHandler([&feed, &haptic_cpu, &replica_pinned, &replica_pin_tried](
                                 std::shared_ptr<const levelset::Sculpture> s, uint64_t seq) {
    if (!replica_pin_tried && haptic_cpu.load() >= 0) {
      replica_pin_tried = true;
      replica_pinned = haptics::PinThreadAwayFromCpu(haptic_cpu.load());
    }
    feed.Publish(std::move(s), seq);
  });
  if (Status s = replica.Start(); !s.ok()) return fail("subscribe", s);
  // Not WaitIdle: under a steady stream of others' edits the queue need never be empty.
  std::shared_ptr<const levelset::Sculpture> first;
  const auto loaded_by = Clock::now() + co.timeout;
  if (replica.WaitLoaded(1, co.timeout)) {
    while (!(first = replica.Snapshot()) && Clock::now() < loaded_by) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }
  if (!first) {
    return fail("subscribe",
                Status(Status::Code::kUnavailable, "the replica published no snapshot in time"));
  }

  std::unique_ptr<haptics::HapticDevice> device;
  double duration_s = ho.duration_s;
  if (points.empty()) {
    auto top = SurfaceBelow(*first, above_top, hi.z - lo.z + hs.tool_radius + 2);
    if (!top) {
      return fail("path", NotFound("no surface below the top of object " + ro.object +
                                   (ho.interest_radius > 0 ? " inside the interest box" : "")));
    }
    device = std::make_unique<haptics::ScriptedDevice>(
        ApproachAndPress(*top, hs.tool_radius, duration_s));
  } else {
    duration_s = points.back().t + 0.25;
    auto recorded = haptics::RecordedDevice::FromPoints(points);
    if (!recorded.ok()) {
      spdlog::error("--script={}: {}", options.script, recorded.status().message());
      return 2;
    }
    device = std::make_unique<haptics::RecordedDevice>(std::move(recorded).value());
  }
  const double voxel = first->voxel_size();
  first.reset();
  haptics::MonitoredDevice monitor(device.get(), &publisher);
  auto loop = haptics::HapticLoop::Create(hs, &publisher, &monitor);
  if (!loop.ok()) {
    spdlog::error("play --haptics: {}", loop.status().message());
    return 2;
  }
  haptic_cpu = (*loop)->cpu();
  // Each snapshot carries the band around the tool densely (filled on the replica's thread), so
  // the loop's lookups are array reads, the first tick after a swap included.
  const double window_radius = hs.tool_radius + kWindowMarginVoxels * voxel;
  feed.SetWindow([l = loop->get()] { return l->SamplePose().position; }, window_radius);
  // The window reads the loop's pose: detach it before the loop goes, on every way out (the
  // replica, declared earlier, outlives the loop and may still publish).
  struct WindowDetach {
    haptics::SculptureFeed& feed;
    ~WindowDetach() { feed.SetWindow(nullptr, 0); }
  } window_detach{feed};

  std::mutex mu;
  json errors = json::array();
  client.SetEventHandler([&](const Event& e) {
    std::lock_guard<std::mutex> lock(mu);
    if (e.type == Event::Type::kError) {
      errors.push_back(ErrorJson(e.error));
    } else if (e.type == Event::Type::kDisconnected || e.type == Event::Type::kBye) {
      errors.push_back({{"code", "DISCONNECTED"}, {"message", e.reason}});
    }
  });

  // The stroke sender: samples the device pose through the loop's hook, 4 poses per stroke,
  // keeping only poses taken while the loop reports contact.
  constexpr size_t kPosesPerStroke = 4;
  const auto pose_period = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(1.0 / (ho.stroke_rate * kPosesPerStroke)));
  uint64_t poses_sent = 0, local_failures = 0, interest_moves = 0;
  Vec3 interest_centre = start;
  StrokeRequest stroke = stroke_template;
  stroke.poses.clear();
  // Without a script the strokes carve with the tool the user feels.
  if (options.script.empty()) stroke.tool_size = {hs.tool_radius, 0, 0};
  const auto send = [&] {
    if (stroke.poses.empty()) return;
    auto seq = client.SendStroke(stroke);
    if (seq.ok()) {
      poses_sent += stroke.poses.size();
    } else {
      ++local_failures;
      std::lock_guard<std::mutex> lock(mu);
      errors.push_back({{"code", "CLIENT"}, {"message", seq.status().message()}});
    }
    stroke.poses.clear();
  };
  if (Status s = (*loop)->Start(); !s.ok()) return fail("haptics", s);
  const auto start_time = Clock::now();
  const auto end_time = start_time + std::chrono::duration_cast<Clock::duration>(
                                         std::chrono::duration<double>(duration_s));
  for (auto next = start_time + pose_period; next < end_time; next += pose_period) {
    std::this_thread::sleep_until(next);
    const haptics::DeviceSample pose = (*loop)->SamplePose();
    const bool contact = (*loop)->stats().contact;
    const uint64_t now_ms = static_cast<uint64_t>(
        std::chrono::duration<double, std::milli>(Clock::now() - start_time).count());
    if (contact && std::isfinite(pose.position.x)) {
      if (stroke.poses.empty()) stroke.t0_ms = now_ms;
      codec::Pose p;
      p.position = pose.position;
      p.t_ms = static_cast<uint32_t>(now_ms - stroke.t0_ms);
      stroke.poses.push_back(p);
      if (stroke.poses.size() == kPosesPerStroke) send();
    } else {
      send();
    }
    feed.RecentreWindow();  // the tool left its window and no edit brought a new copy
    if (ho.interest_radius > 0 && std::isfinite(pose.position.x)) {
      // Move the box once the tool has crossed half of its half-size: the server sends the
      // new region while the tool is still well inside the old one.
      const Vec3 d = pose.position - interest_centre;
      if (std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)}) > 0.5 * ho.interest_radius) {
        interest_centre = pose.position;
        if (replica.MoveInterest(BoxAround(interest_centre, ho.interest_radius)).ok()) {
          ++interest_moves;
        }
      }
    }
  }
  send();
  (*loop)->Stop();
  const bool settled = client.WaitAllAcked(co.timeout);
  client.SetEventHandler(nullptr);
  replica.SetSnapshotHandler(nullptr);
  feed.CheckHeld();
  (void)client.Close("haptic session finished");

  const haptics::HapticLoopStats ls = (*loop)->stats();
  const haptics::MonitoredDevice::ForceStats fs = monitor.force_stats();
  const haptics::SculptureFeed::Stats feed_stats = feed.stats();
  const uint64_t torn_ticks = monitor.TicksOn(feed.changed_versions());
  const ReplicaStats rs = replica.stats();
  const ClientStats st = client.stats();
  const uint64_t refused = st.refused + local_failures;
  const uint64_t unacked = client.unacked();
  const bool ok = settled && refused == 0 && unacked == 0 && ls.ticks > 0 && torn_ticks == 0;
  const json torn = ho.verify_snapshots ? json(torn_ticks) : json(nullptr);
  std::lock_guard<std::mutex> lock(mu);
  const json report = {{"server", options.server},
                       {"scene", joined->info.scene()},
                       {"object", ro.object},
                       {"ok", ok},
                       {"model", haptics::ForceModelName(hs.model)},
                       {"stiffness", hs.stiffness},
                       {"tool_radius", hs.tool_radius},
                       {"trajectory", points.empty() ? "built-in" : "script"},
                       {"interest_radius", ho.interest_radius},
                       {"duration_s", Round3(duration_s)},
                       {"haptic_ticks", ls.ticks},
                       {"haptic_rate_hz", Round3(ls.rate_hz)},
                       {"haptic_tick_cost_p50_us", Round3(ls.tick_cost_p50_us)},
                       {"haptic_tick_cost_p99_us", Round3(ls.tick_cost_p99_us)},
                       {"haptic_tick_cost_max_us", Round3(ls.tick_cost_max_us)},
                       {"haptic_tick_budget_us", hs.tick_budget_us},
                       {"haptic_ticks_over_budget", ls.ticks_over_budget},
                       {"haptic_scheduling", ls.scheduling},
                       {"haptic_priority", ls.priority},
                       {"haptic_mlockall", ls.memory_locked},
                       {"haptic_cpu", ls.cpu},
                       {"replica_pinned_off_haptic_cpu", replica_pinned.load()},
                       {"haptic_period_err_p50_us", Round3(ls.period_err_p50_us)},
                       {"haptic_period_err_p99_us", Round3(ls.period_err_p99_us)},
                       {"haptic_period_err_max_us", Round3(ls.period_err_max_us)},
                       {"haptic_overruns", ls.overruns},
                       {"haptic_missed_deadlines", ls.missed_deadlines},
                       {"haptic_ticks_over_2ms", ls.ticks_over_2ms},
                       {"haptic_nan_samples", ls.nan_samples},
                       {"haptic_snapshots_seen", ls.snapshots_seen},
                       {"haptic_snapshot_lag_p50_ms", Round3(ls.snapshot_lag_p50_ms)},
                       {"haptic_snapshot_lag_p99_ms", Round3(ls.snapshot_lag_p99_ms)},
                       {"haptic_snapshot_lag_max_ms", Round3(ls.snapshot_lag_max_ms)},
                       {"haptic_torn_ticks", torn},
                       {"snapshots_published", feed_stats.published},
                       {"snapshots_sealed_checked", feed_stats.checked},
                       {"snapshots_changed_after_publish", feed_stats.changed},
                       {"snapshots_seal_ms", Round3(feed_stats.seal_ms)},
                       {"snapshot_windows", feed_stats.windows},
                       {"snapshot_windows_recentred", feed_stats.recentred},
                       {"snapshot_window_ms", Round3(feed_stats.window_ms)},
                       {"snapshot_window_radius", Round3(window_radius)},
                       {"force_max", Round3(fs.max_force)},
                       {"force_mean_in_contact", Round3(fs.mean_contact_force)},
                       {"force_contact_ticks", fs.contact_ticks},
                       {"force_first_contact_s", Round3(fs.first_contact_s)},
                       {"force_last", Vec3Json(fs.last_force)},
                       {"replica_region_loads", rs.region_loads},
                       {"replica_broadcasts_applied", rs.broadcasts_applied},
                       {"replica_hash_mismatches", rs.hash_mismatches},
                       {"replica_seq", rs.seq},
                       {"replica_apply_ms", Round3(rs.apply_ms)},
                       {"interest_moves", interest_moves},
                       {"strokes_sent", st.strokes_sent},
                       {"poses_sent", poses_sent},
                       {"acked", st.acks},
                       {"refused", refused},
                       {"unacked", unacked},
                       {"errors", errors}};
  if (ho.json) {
    Print(report);
  } else {
    std::printf(
        "haptics: %s model, stiffness %g, tool radius %g, %s trajectory, %.2f s\n"
        "loop: %llu ticks at %.1f Hz; tick cost p50 %.1f us, p99 %.1f us, max %.1f us; period "
        "error p99 %.1f us, max %.1f us; %llu missed deadlines, %llu periods over 2 ms; %s%s, "
        "%s, %llu ticks over a %g us budget\n"
        "snapshots: %llu published, %llu seen by the loop, lag p99 %.3f ms; %s torn ticks "
        "(%llu of %llu seals changed)\n"
        "force: max %.3f, mean in contact %.3f over %llu ticks, first contact at %.3f s\n"
        "strokes: %llu sent (%llu poses), %llu acked, %llu refused, %llu unacked; replica at "
        "seq %llu, %llu hash mismatches\n",
        haptics::ForceModelName(hs.model), hs.stiffness, hs.tool_radius,
        points.empty() ? "built-in" : "script", duration_s,
        static_cast<unsigned long long>(ls.ticks), ls.rate_hz, ls.tick_cost_p50_us,
        ls.tick_cost_p99_us, ls.tick_cost_max_us, ls.period_err_p99_us, ls.period_err_max_us,
        static_cast<unsigned long long>(ls.missed_deadlines),
        static_cast<unsigned long long>(ls.ticks_over_2ms), ls.scheduling.c_str(),
        ls.cpu >= 0 ? (" on CPU " + std::to_string(ls.cpu)).c_str() : "",
        ls.memory_locked ? "memory locked" : "memory not locked",
        static_cast<unsigned long long>(ls.ticks_over_budget), hs.tick_budget_us,
        static_cast<unsigned long long>(feed_stats.published),
        static_cast<unsigned long long>(ls.snapshots_seen), ls.snapshot_lag_p99_ms,
        ho.verify_snapshots ? std::to_string(torn_ticks).c_str() : "unchecked",
        static_cast<unsigned long long>(feed_stats.changed),
        static_cast<unsigned long long>(feed_stats.checked), fs.max_force, fs.mean_contact_force,
        static_cast<unsigned long long>(fs.contact_ticks), fs.first_contact_s,
        static_cast<unsigned long long>(st.strokes_sent),
        static_cast<unsigned long long>(poses_sent), static_cast<unsigned long long>(st.acks),
        static_cast<unsigned long long>(refused), static_cast<unsigned long long>(unacked),
        static_cast<unsigned long long>(rs.seq),
        static_cast<unsigned long long>(rs.hash_mismatches));
    for (const json& e : errors) std::printf("error: %s\n", e.dump().c_str());
  }
  return ok ? 0 : 1;
}

}  // namespace

void AddPlayHapticsOptions(CLI::App& play, PlayOptions& options) {
  PlayHapticsOptions& h = options.haptics;
  const std::string group = "Haptics";
  play.add_flag("--haptics", h.enabled,
                "Render forces at 1 kHz on a replica of the object with a simulated device and "
                "send strokes sampled from it (--script optional: the device's trajectory)")
      ->group(group);
  play.add_option("--model", h.model, "Force model: penalty | proxy")
      ->check(CLI::IsMember({"penalty", "proxy"}))
      ->capture_default_str()
      ->group(group);
  play.add_option("--stiffness", h.stiffness,
                  "Penalty kappa / proxy spring, force per world unit of penetration")
      ->check(CLI::Range(1e-6, haptics::kMaxStiffness))
      ->capture_default_str()
      ->group(group);
  play.add_option("--damping", h.damping,
                  "Proxy damper, force per unit speed (at least stiffness / 2000 at 1 kHz)")
      ->check(CLI::Range(0.0, haptics::kMaxStiffness))
      ->capture_default_str()
      ->group(group);
  play.add_option("--max-force", h.max_force, "Force clamp")
      ->check(CLI::Range(1e-6, haptics::kMaxHapticForce))
      ->capture_default_str()
      ->group(group);
  play.add_option("--tool-radius", h.tool_radius,
                  "Haptic tool radius, world units (0: the script's tool size, else 2.5)")
      ->check(CLI::Range(0.0, haptics::kMaxToolRadius))
      ->capture_default_str()
      ->group(group);
  play.add_option("--tool-samples", h.tool_samples, "Tool surface samples (penalty, contact)")
      ->check(CLI::Range(1, haptics::kMaxToolSamples))
      ->capture_default_str()
      ->group(group);
  play.add_option("--interest-radius", h.interest_radius,
                  "Replicate only a box of this half-size around the tool, moved as it goes "
                  "(0: the whole object)")
      ->check(CLI::Range(0.0, 1e6))
      ->capture_default_str()
      ->group(group);
  play.add_option("--stroke-rate", h.stroke_rate, "Strokes per second (4 device poses each)")
      ->check(CLI::Range(1.0, 250.0))
      ->capture_default_str()
      ->group(group);
  play.add_option("--duration", h.duration_s, "Length of the built-in path, seconds")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str()
      ->group(group);
  play.add_option("--snapshot-ms", h.snapshot_ms, "Replica snapshots at most this often, ms")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str()
      ->group(group);
  play.add_flag("--verify-snapshots", h.verify_snapshots,
                "Seal each snapshot by its state hash and check it again when let go, counting "
                "ticks that read a changed one (haptic_torn_ticks; costs two hashes of the "
                "replica per snapshot on the replica's thread)")
      ->group(group);
  play.add_flag("--json", h.json, "Print the haptic session's report as JSON")->group(group);
}

int RunPlay(const PlayOptions& options) {
  std::string scene;
  StrokeRequest defaults;
  StatusOr<std::vector<ScriptStroke>> strokes = std::vector<ScriptStroke>{};
  if (options.script.empty()) {
    if (!options.haptics.enabled) {
      spdlog::error("play: --script is required (optional only with --haptics)");
      return 2;
    }
  } else {
    std::ifstream in(options.script);
    if (!in) {
      spdlog::error("--script={}: cannot open", options.script);
      return 2;
    }
    json script = json::parse(in, nullptr, /*allow_exceptions=*/false);
    if (script.is_discarded()) {
      spdlog::error("--script={}: not valid JSON", options.script);
      return 2;
    }
    strokes = ParseScript(script, &scene, &defaults);
    if (!strokes.ok()) {
      spdlog::error("--script={}: {}", options.script, strokes.status().message());
      return 2;
    }
  }
  if (!options.scene.empty()) scene = options.scene;
  std::string host;
  uint16_t port = 0;
  if (const Status s = ParseServerAddress(options.server, &host, &port); !s.ok()) {
    spdlog::error("{}", s.message());
    return 2;
  }
  if (!(options.speedup > 0)) {
    spdlog::error("--speedup={} outside (0, inf)", options.speedup);
    return 2;
  }
  if (options.haptics.enabled) {
    return RunHaptics(options, host, port, scene, defaults, *strokes);
  }

  ClientOptions co;
  co.tls = options.tls;
  co.timeout = std::chrono::milliseconds(static_cast<int64_t>(options.timeout_s * 1000));
  auto client_id = PlayClientId(options, &co);
  if (!client_id.ok()) {
    spdlog::error("play: {}", client_id.status().ToString());
    return 2;
  }
  Client client(co);
  const auto fail = [&](const std::string& stage, const Status& s) {
    Print({{"server", options.server}, {"ok", false}, {"stage", stage}, {"error", s.message()}});
    return 1;
  };
  std::string stage;
  auto joined = ConnectAsSculptor(client, options, host, port, scene, *client_id, &stage);
  if (!joined.ok()) return fail(stage, joined.status());
  if (Status st = ResolveObject(joined->info, options.object, &defaults, &*strokes); !st.ok()) {
    return fail("join", st);
  }

  std::mutex mu;
  std::vector<double> latencies;
  std::map<uint64_t, size_t> stroke_of_seq;  // client_seq -> script index
  json errors = json::array();
  uint64_t first_seq = 0, last_seq = 0, duplicates = 0;
  client.SetEventHandler([&](const Event& e) {
    std::lock_guard<std::mutex> lock(mu);
    if (e.type == Event::Type::kAck) {
      if (e.ack.duplicate()) ++duplicates;
      latencies.push_back(e.latency_ms);
      if (e.ack.edits() > 0) {
        if (first_seq == 0 || e.ack.global_seq_first() < first_seq) {
          first_seq = e.ack.global_seq_first();
        }
        last_seq = std::max<uint64_t>(last_seq, e.ack.global_seq_first() + e.ack.edits() - 1);
      }
    } else if (e.type == Event::Type::kError) {
      json err = ErrorJson(e.error);
      auto it = stroke_of_seq.find(e.error.client_seq());
      if (it != stroke_of_seq.end()) err["stroke"] = it->second;
      errors.push_back(std::move(err));
    } else if (e.type == Event::Type::kDisconnected || e.type == Event::Type::kBye) {
      errors.push_back({{"code", "DISCONNECTED"}, {"message", e.reason}});
    }
  });

  const auto start = Clock::now();
  uint64_t local_failures = 0;
  for (const ScriptStroke& s : *strokes) {
    std::this_thread::sleep_until(
        start + std::chrono::duration_cast<Clock::duration>(
                    std::chrono::duration<double, std::milli>(s.t_ms / options.speedup)));
    auto seq = client.SendStroke(s.request);
    std::lock_guard<std::mutex> lock(mu);
    if (seq.ok()) {
      stroke_of_seq[*seq] = s.index;
    } else {
      // Refused before it left (packing): reported like a server refusal.
      ++local_failures;
      errors.push_back(
          {{"stroke", s.index}, {"code", "CLIENT"}, {"message", seq.status().message()}});
    }
  }
  const bool settled = client.WaitAllAcked(co.timeout);
  const double duration_s = std::chrono::duration<double>(Clock::now() - start).count();
  // Detached first: the end of the connection we close is not an error of the script.
  client.SetEventHandler(nullptr);
  (void)client.Close("script finished");

  const ClientStats st = client.stats();
  const uint64_t unacked = client.unacked();
  std::lock_guard<std::mutex> lock(mu);
  std::sort(latencies.begin(), latencies.end());
  const uint64_t refused = st.refused + local_failures;
  const bool ok = settled && refused == 0 && unacked == 0;
  Print({{"server", options.server},
         {"script", options.script},
         {"scene", joined->info.scene()},
         {"client_id", client.client_id()},
         {"ok", ok},
         {"strokes", strokes->size()},
         {"sent", st.strokes_sent},
         {"acked", st.acks},
         {"duplicates", duplicates},
         {"refused", refused},
         {"unacked", unacked},
         {"poses_applied", st.poses_acked},
         {"global_seq_first", first_seq},
         {"global_seq_last", last_seq},
         {"acks_in_order", st.acks_out_of_order == 0},
         {"stroke_ack_p50_ms", Round3(Percentile(latencies, 0.5))},
         {"stroke_ack_p99_ms", Round3(Percentile(latencies, 0.99))},
         {"stroke_ack_max_ms", Round3(latencies.empty() ? 0.0 : latencies.back())},
         {"duration_s", Round3(duration_s)},
         {"bytes_sent", st.bytes_sent},
         {"bytes_received", st.bytes_received},
         {"errors", errors}});
  return ok ? 0 : 1;
}

}  // namespace sculpt::client
