/// @brief `sculpt undo` and `sculpt redo`: take back (or put back) a sculptor's own most recent
/// edits on a running sculptd, and say what the server did (issue 15).
#ifndef SCULPT_CLIENT_UNDO_CMD_H_
#define SCULPT_CLIENT_UNDO_CMD_H_

#include <cstdint>
#include <string>

#include "sculpt/client/client.h"

namespace CLI {
class App;
}  // namespace CLI

namespace sculpt::client {

/// The environment variable both `sculpt play` and `sculpt undo|redo` read the client id from
/// when --client-id is not given.
inline constexpr char kClientIdEnv[] = "SCULPT_CLIENT_ID";

struct UndoCmdOptions {
  bool redo = false;
  std::string server;  // HOST:PORT
  std::string token;   // resolved by main from --token-file / $SCULPT_TOKEN
  std::string scene;   // empty: the server's default
  std::string object;  // empty: the scene's first object
  std::string client_id_text;  // --client-id, else $SCULPT_CLIENT_ID
  std::string name = "sculpt-undo";
  int steps = 1;
  double timeout_s = 10;
  bool json = false;
  ClientTlsOptions tls;
};

/// Adds the `undo` (or, with `redo`, the `redo`) subcommand and its options, storing into
/// `options` (which must outlive parsing); the caller adds the token flags.
CLI::App* AddUndoCommand(CLI::App& app, bool redo, UndoCmdOptions& options);

/// The client id to present: `text` (from --client-id) when given, else $SCULPT_CLIENT_ID.
/// InvalidArgument naming the flag or variable for text that is not a decimal in [1, 2^63 - 1];
/// FailedPrecondition with directions when neither is set.
StatusOr<uint64_t> ResolveClientId(const std::string& text);

/// Connects as a sculptor with that client id, sends up to `steps` undos (redos) of `object`
/// one after another and prints each answer (text, or JSON with --json). Returns the exit
/// code: 0 when every step was done, 1 when the server refused one (nothing to undo, beyond the
/// history, not a sculptor; the steps before it are printed) or the connection failed, 2 for
/// bad options.
int RunUndo(const UndoCmdOptions& options);

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_UNDO_CMD_H_
