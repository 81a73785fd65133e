/// @brief `sculpt history`: the subcommand's options, the request and the report.
#include "history_cmd.h"

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <ctime>
#include <nlohmann/json.hpp>

#include "sculpt/codec/history.h"
#include "tls_flags.h"

namespace sculpt::client {
namespace {

using nlohmann::json;

std::string KindName(const v1::HistoryEntry& e) {
  // Servers that name the kind (paints, ball edits, model intents) say it themselves.
  if (!e.kind_name().empty()) return e.kind_name();
  std::string kind;
  switch (e.kind()) {
    case v1::EDIT_KIND_PRESS: kind = "press"; break;
    case v1::EDIT_KIND_ADD: kind = "add"; break;
    case v1::EDIT_KIND_SUBTRACT: kind = "subtract"; break;
    case v1::EDIT_KIND_SMOOTH: kind = "smooth"; break;
    case v1::EDIT_KIND_INFLATE: kind = "inflate"; break;
    case v1::EDIT_KIND_DEFLATE: kind = "deflate"; break;
    default: kind = "unknown"; break;
  }
  return e.sweep() ? "sweep-" + kind : kind;
}

/// "2026-11-23T16:10:01.123Z"; "unknown" for 0 (an edit logged before times were kept).
std::string UtcTime(uint64_t ms) {
  if (ms == 0) return "unknown";
  const std::time_t s = static_cast<std::time_t>(ms / 1000);
  std::tm tm{};
  gmtime_r(&s, &tm);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900,
                tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec,
                static_cast<int>(ms % 1000));
  return buf;
}

json EntryJson(const v1::HistoryEntry& e) {
  json j = {{"seq", e.seq()},       {"author", e.author()},    {"kind", KindName(e)},
            {"poses", e.poses()},   {"time_ms", e.time_ms()},  {"time", UtcTime(e.time_ms())},
            {"undone", e.undone()}, {"undoable", e.undoable()}, {"user", e.user()}};
  if (e.epoch() != 0) j["epoch"] = e.epoch();  // cluster mode only: single-process output as before
  return j;
}

void PrintTable(const v1::HistoryAnswer& a, const std::string& server) {
  std::printf("history of %s on %s: %u shown, %u matching, %u held (newest first)\n",
              a.object().c_str(), server.c_str(), static_cast<unsigned>(a.entries_size()),
              a.matching(), a.held());
  if (!a.cleared().empty()) {
    std::printf("last cleared: %s (edits before it cannot be undone)\n", a.cleared().c_str());
  }
  if (a.entries_size() == 0) return;
  std::printf("%10s  %-24s  %-20s  %-14s  %5s  %s\n", "seq", "time (UTC)", "author", "kind",
              "poses", "state");
  for (const v1::HistoryEntry& e : a.entries()) {
    const char* state = e.undone() ? "undone" : e.undoable() ? "done, undoable" : "done";
    // Cluster mode: the ownership epoch the edit was logged under, after the state.
    const std::string epoch = e.epoch() != 0 ? ", epoch " + std::to_string(e.epoch()) : "";
    std::printf("%10llu  %-24s  %-20s  %-14s  %5u  %s%s\n",
                static_cast<unsigned long long>(e.seq()), UtcTime(e.time_ms()).c_str(),
                (e.user().empty() ? e.author() : e.user()).c_str(), KindName(e).c_str(), e.poses(),
                state, epoch.c_str());
  }
}

}  // namespace

const char* HistoryFallbackToken(const std::string& role) {
  return role == "sculptor" ? "sculpt-dev-sculptor" : "sculpt-dev-viewer";
}

CLI::App* AddHistoryCommand(CLI::App& app, HistoryCmdOptions& o) {
  CLI::App* cmd =
      app.add_subcommand("history",
                         "List an object's recent edits on a running sculptd: author, kind, time, "
                         "sequence, undone or not");
  cmd->footer(
      "The list is the server's undo history of the object: every edit since the oldest one an "
      "author can still undo or redo (at most limits.undo_depth per author), newest first. "
      "Authors are named as undo files edits: by client id (`sculpt play` prints its "
      "client_id). Times are the server's wall clock when the edit was committed, in UTC. In "
      "cluster mode the state ends with the ownership epoch the edit was logged under. "
      "Viewers may read the history: the default role is viewer (token from --token-file or "
      "$SCULPT_TOKEN, else the development viewer token). Exit status: 0 when listed, 1 when "
      "the server refused the request or the connection failed, another non-zero code for bad "
      "options.");
  cmd->add_option("--server", o.server, "sculptd address HOST:PORT")->required();
  cmd->add_option("--object", o.object, "Object (default: the scene's first object)");
  cmd->add_option("--author", o.author, "Only this author's edits (a client id, or a user's name on a server with named users)");
  cmd->add_option("--limit", o.limit, "At most this many edits, newest first")
      ->check(CLI::Range(1u, codec::kMaxHistoryLimit))
      ->capture_default_str();
  cmd->add_option("--role", o.role, "Role the token is for")
      ->check(CLI::IsMember({"viewer", "sculptor"}))
      ->capture_default_str();
  cmd->add_option("--scene", o.scene, "Scene (default: the server's)");
  cmd->add_option("--name", o.name, "Name shown to others")->capture_default_str();
  cmd->add_option("--timeout", o.timeout_s, "Seconds to wait for the connection and the answer")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  cmd->add_flag("--json", o.json, "Print the history as JSON");
  AddTlsFlags(*cmd, &o.tls);
  return cmd;
}

int RunHistory(const HistoryCmdOptions& o) {
  std::string host;
  uint16_t port = 0;
  if (Status s = ParseServerAddress(o.server, &host, &port); !s.ok()) {
    spdlog::error("history: {}", s.ToString());
    return 2;
  }
  ClientOptions co;
  co.tls = o.tls;
  co.timeout = std::chrono::milliseconds(static_cast<int64_t>(o.timeout_s * 1000));
  co.skip_state = true;  // SceneInfo names the objects; the state is not needed
  Client client(co);
  const auto failed = [&](const char* stage, const Status& s) {
    spdlog::error("history: {} {}: {}", stage, o.server, s.ToString());
    return 1;
  };
  if (Status s = client.Connect(host, port); !s.ok()) return failed("connect to", s);
  const v1::Role role = o.role == "sculptor" ? v1::ROLE_SCULPTOR : v1::ROLE_VIEWER;
  auto welcome = client.Hello(o.token, role, o.name, 0);
  if (!welcome.ok()) return failed("hello to", welcome.status());
  auto joined = client.Join(o.scene);
  if (!joined.ok()) return failed("join on", joined.status());
  auto answer = client.History(o.object, o.author, o.limit);
  (void)client.Close("history done");
  if (!answer.ok()) return failed("history of", answer.status());
  if (!o.json) {
    PrintTable(*answer, o.server);
    return 0;
  }
  json entries = json::array();
  for (const v1::HistoryEntry& e : answer->entries()) entries.push_back(EntryJson(e));
  const json out = {{"server", o.server},           {"object", answer->object()},
                    {"author", o.author},           {"limit", o.limit},
                    {"held", answer->held()},       {"matching", answer->matching()},
                    {"cleared", answer->cleared()}, {"entries", entries}};
  std::printf("%s\n", out.dump(2).c_str());
  return 0;
}

}  // namespace sculpt::client
