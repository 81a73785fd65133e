/// @brief `sculpt undo|redo`: the subcommands' options, the session and the report.
#include "undo_cmd.h"

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <nlohmann/json.hpp>

#include "tls_flags.h"

namespace sculpt::client {
namespace {

using nlohmann::json;

constexpr int kMaxSteps = 4096;  // the server's largest per-author depth (limits.undo_depth)

/// "alice 2, bob 1"
std::string ReplayedBy(const v1::UndoAck& a) {
  std::string out;
  for (const v1::ReplayedEdits& r : a.replayed_by()) {
    if (!out.empty()) out += ", ";
    out += r.author() + " " + std::to_string(r.edits());
  }
  return out;
}

/// One line for an accepted step.
std::string Describe(const v1::UndoAck& a, const std::string& object) {
  const char* verb = a.redo() ? "redone" : "undone";
  if (a.duplicate()) {
    return std::string(verb) + " already: client_seq " + std::to_string(a.client_seq()) +
           " was applied before (a resend)";
  }
  std::string text = std::string(verb) + ": edit at seq " + std::to_string(a.target_seq()) +
                     " on " + object + " (logged as seq " + std::to_string(a.global_seq()) + "); ";
  if (a.replayed() == 0) {
    text += "no later edits replayed";
  } else {
    text += std::to_string(a.replayed()) + " later edit" + (a.replayed() == 1 ? "" : "s") +
            " replayed (" + ReplayedBy(a) + ")";
  }
  text += "; can undo " + std::to_string(a.undo_depth()) + " more, redo " +
          std::to_string(a.redo_depth());
  return text;
}

/// Why a step was refused, in words first, then the server's own error.
std::string Refusal(const v1::UndoAck& a, const std::string& object, uint64_t client_id) {
  const char* what = a.redo() ? "redo" : "undo";
  std::string lead;
  switch (a.error().code()) {
    case v1::ERROR_CODE_FAILED_PRECONDITION:
      lead = std::string("nothing to ") + what + " on " + object + " for client id " +
             std::to_string(client_id);
      break;
    case v1::ERROR_CODE_INVALID_ARGUMENT:
      lead = std::string("cannot ") + what + " further on " + object +
             ": older edits fell off the history";
      break;
    case v1::ERROR_CODE_PERMISSION_DENIED:
    case v1::ERROR_CODE_UNAUTHENTICATED:
      lead = std::string("not allowed to ") + what + " (sculptors only)";
      break;
    case v1::ERROR_CODE_MALFORMED:
      lead = std::string("this sculptd does not know ") + what + " (an older server)";
      break;
    default:
      lead = std::string(what) + " refused";
      break;
  }
  // The server's message already names the field and value; the rest of the Error repeats it.
  const v1::Error& e = a.error();
  return lead + " [" + ErrorCodeName(e.code()) + ": " +
         (e.message().empty() ? ErrorToStatus(e).message() : e.message()) + "]";
}

json StepJson(const v1::UndoAck& a) {
  json by = json::object();
  for (const v1::ReplayedEdits& r : a.replayed_by()) by[r.author()] = r.edits();
  return {{"client_seq", a.client_seq()}, {"duplicate", a.duplicate()},
          {"global_seq", a.global_seq()}, {"target_seq", a.target_seq()},
          {"replayed", a.replayed()},     {"replayed_by", by},
          {"undo_depth", a.undo_depth()}, {"redo_depth", a.redo_depth()}};
}

json ErrorJson(const v1::Error& e) {
  return {{"code", ErrorCodeName(e.code())}, {"field", e.field()}, {"value", e.value()},
          {"allowed_range", e.allowed_range()}, {"message", e.message()}};
}

}  // namespace

CLI::App* AddUndoCommand(CLI::App& app, bool redo, UndoCmdOptions& o) {
  o.redo = redo;
  const std::string verb = redo ? "redo" : "undo";
  CLI::App* cmd = app.add_subcommand(
      verb, redo ? "Put back your most recently undone edits on a running sculptd"
                 : "Take back your own most recent edits on a running sculptd; later edits by "
                   "others stay");
  cmd->footer(
      "Undo is per author: sculptd files every edit under the client id its client said Hello "
      "with (bound to the user on a server with named users), and " + verb +
      " acts on that id's edits only. Give the id the edits were made under with --client-id or "
      "$" + std::string(kClientIdEnv) + " (`sculpt play` uses the same, and prints its "
      "client_id). Each step prints the edit's sequence, how many later edits were replayed on "
      "top and by whom, and the undo and redo depth left. Exit status: 0 when every step was "
      "done, 1 when the server refused one (e.g. nothing to " + verb + ") or the connection "
      "failed, another non-zero code for bad options.");
  cmd->add_option("--server", o.server, "sculptd address HOST:PORT")->required();
  cmd->add_option("--object", o.object, "Object (default: the scene's first object)");
  cmd->add_option("--steps", o.steps, "How many edits to " + verb + ", most recent first")
      ->check(CLI::Range(1, kMaxSteps))
      ->capture_default_str();
  cmd->add_option("--client-id", o.client_id_text,
                  "The client id the edits were made under (default: $" +
                      std::string(kClientIdEnv) + ")");
  cmd->add_option("--scene", o.scene, "Scene (default: the server's)");
  cmd->add_option("--name", o.name, "Name shown to others")->capture_default_str();
  cmd->add_option("--timeout", o.timeout_s, "Seconds to wait for the connection and each answer")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  cmd->add_flag("--json", o.json, "Print the steps as JSON");
  AddTlsFlags(*cmd, &o.tls);
  return cmd;
}

StatusOr<uint64_t> ResolveClientId(const std::string& text) {
  std::string source = "--client-id";
  std::string value = text;
  if (value.empty()) {
    const char* env = std::getenv(kClientIdEnv);
    if (env == nullptr || *env == '\0') {
      return FailedPrecondition(
          "no client id: undo takes back the edits of one client id; give it with --client-id "
          "ID or $" + std::string(kClientIdEnv) + " (sculpt play prints its client_id)");
    }
    source = "$" + std::string(kClientIdEnv);
    value = env;
  }
  uint64_t id = 0;
  const char* last = value.data() + value.size();
  const auto r = std::from_chars(value.data(), last, id);
  if (r.ec != std::errc() || r.ptr != last || id == 0 || id >> 63 != 0) {
    return InvalidArgument(source + "=" + value + " outside [1, 2^63 - 1] (a decimal number)");
  }
  return id;
}

int RunUndo(const UndoCmdOptions& o) {
  const char* verb = o.redo ? "redo" : "undo";
  auto id = ResolveClientId(o.client_id_text);
  if (!id.ok()) {
    spdlog::error("{}: {}", verb, id.status().ToString());
    return 2;
  }
  std::string host;
  uint16_t port = 0;
  if (Status s = ParseServerAddress(o.server, &host, &port); !s.ok()) {
    spdlog::error("{}: {}", verb, s.ToString());
    return 2;
  }
  ClientOptions co;
  co.tls = o.tls;
  co.timeout = std::chrono::milliseconds(static_cast<int64_t>(o.timeout_s * 1000));
  co.skip_state = true;  // SceneInfo names the objects; the state is not needed
  // Earlier runs with this client id used lower sequences: the server takes any undo numbered
  // at or below the newest it logged for the id as a resend.
  co.first_client_seq = ClockClientSeq();
  Client client(co);
  const auto failed = [&](const char* stage, const Status& s) {
    spdlog::error("{}: {} {}: {}", verb, stage, o.server, s.ToString());
    return 1;
  };
  if (Status s = client.Connect(host, port); !s.ok()) return failed("connect to", s);
  auto welcome = client.Hello(o.token, v1::ROLE_SCULPTOR, o.name, *id);
  if (!welcome.ok()) return failed("hello to", welcome.status());
  auto joined = client.Join(o.scene);
  if (!joined.ok()) return failed("join on", joined.status());
  std::string object = o.object;
  if (object.empty() && joined->info.objects_size() > 0) object = joined->info.objects(0).name();

  json steps = json::array();
  json error = nullptr;
  int done = 0;
  int code = 0;
  for (int i = 0; i < o.steps; ++i) {
    auto seq = client.SendUndo(object, o.redo);
    if (!seq.ok()) {
      spdlog::error("{}: {}", verb, seq.status().ToString());
      code = seq.status().code() == Status::Code::kNotFound ? 2 : 1;
      error = {{"code", "CLIENT"}, {"message", seq.status().message()}};
      break;
    }
    auto ack = client.WaitUndoAck(*seq, co.timeout);
    if (!ack.ok()) {
      code = failed("waiting for the answer of", ack.status());
      error = {{"code", "CLIENT"}, {"message", ack.status().message()}};
      break;
    }
    if (!ack->accepted()) {
      if (!o.json) spdlog::error("{}: {}", verb, Refusal(*ack, object, *id));
      error = ErrorJson(ack->error());
      code = 1;
      break;
    }
    ++done;
    if (o.json) {
      steps.push_back(StepJson(*ack));
    } else {
      std::printf("%s\n", Describe(*ack, object).c_str());
    }
  }
  (void)client.Close(std::string(verb) + " done");
  if (o.json) {
    const json out = {{"server", o.server},   {"object", object},     {"client_id", *id},
                      {"redo", o.redo},       {"steps_requested", o.steps},
                      {"steps_done", done},   {"ok", code == 0},     {"steps", steps},
                      {"error", error}};
    std::printf("%s\n", out.dump(2).c_str());
  } else if (o.steps > 1) {
    std::printf("%s %d of %d step%s\n", o.redo ? "redid" : "undid", done, o.steps,
                o.steps == 1 ? "" : "s");
  }
  return code;
}

}  // namespace sculpt::client
