/// @brief `sculpt play`: the stroke script reader, the timed sender and the JSON summary.
#include "play_cmd.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>
#include <vector>

#include "sculpt/client/client.h"

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
    "Script (JSON): {\"scene\": \"default\", \"object\": \"clay\", \"kind\": \"press\", "
    "\"tool\": \"sphere\", \"size\": [2.5, 0, 0], \"speed\": 60, \"amount\": 0, \"strokes\": "
    "[{\"t_ms\": 0, \"poses\": [[x, y, z, t_ms], ...]}, ...]}. kind: press|add|subtract|"
    "smooth|inflate|deflate; tool: sphere|ellipsoid|box|capsule; size in world units (a number "
    "means [r, 0, 0]); stroke t_ms = ms after the start (when it is sent); pose t_ms = ms after "
    "the stroke's (default: previous + 8). A stroke may override object, kind, tool, size, "
    "speed and amount. Prints a JSON summary; exits 1 if a stroke is refused or un-acked, 2 "
    "for a bad script.";

namespace {

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

StatusOr<std::vector<ScriptStroke>> ParseScript(const json& script, std::string* scene) {
  if (!script.is_object()) return Bad("script", script, "a JSON object");
  if (script.contains("scene")) {
    if (!script["scene"].is_string()) return Bad("scene", script["scene"], "strings");
    *scene = script["scene"].get<std::string>();
  }
  StrokeRequest defaults;
  SCULPT_RETURN_IF_ERROR(ReadStrokeFields(script, "script", &defaults));
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

}  // namespace

int RunPlay(const PlayOptions& options) {
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
  std::string scene;
  auto strokes = ParseScript(script, &scene);
  if (!strokes.ok()) {
    spdlog::error("--script={}: {}", options.script, strokes.status().message());
    return 2;
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

  ClientOptions co;
  co.timeout = std::chrono::milliseconds(static_cast<int64_t>(options.timeout_s * 1000));
  Client client(co);
  const auto fail = [&](const std::string& stage, const Status& s) {
    Print({{"server", options.server}, {"ok", false}, {"stage", stage}, {"error", s.message()}});
    return 1;
  };
  if (Status s = client.Connect(host, port); !s.ok()) return fail("connect", s);
  auto welcome = client.Hello(options.token, v1::ROLE_SCULPTOR, options.name, 0);
  if (!welcome.ok()) return fail("hello", welcome.status());
  auto joined = client.Join(scene);
  if (!joined.ok()) return fail("join", joined.status());

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
