/// @brief `sculpt history`: an object's recent edits on a running sculptd, as its undo history
/// holds them: author, kind, commit time, sequence, undone or not (issue 15).
#ifndef SCULPT_CLIENT_HISTORY_CMD_H_
#define SCULPT_CLIENT_HISTORY_CMD_H_

#include <cstdint>
#include <string>

#include "sculpt/client/client.h"

namespace CLI {
class App;
}  // namespace CLI

namespace sculpt::client {

struct HistoryCmdOptions {
  std::string server;           // HOST:PORT
  std::string token;            // resolved by main from --token-file / $SCULPT_TOKEN
  std::string role = "viewer";  // viewer | sculptor: the role the token is for
  std::string scene;            // empty: the server's default
  std::string object;           // empty: the scene's first object
  std::string author;           // empty: every author
  uint32_t limit = 20;
  std::string name = "sculpt-history";
  double timeout_s = 10;
  bool json = false;
  ClientTlsOptions tls;
};

/// Adds the `history` subcommand and its options, storing into `options` (which must outlive
/// parsing); the caller adds the token flags.
CLI::App* AddHistoryCommand(CLI::App& app, HistoryCmdOptions& options);

/// The development token of `role` ("viewer" or "sculptor").
const char* HistoryFallbackToken(const std::string& role);

/// Connects with the role's token, joins, asks for the history view and prints it (a table, or
/// JSON with --json). Returns the exit code: 0 when printed, 1 when the server refused the
/// request (unknown object, a field out of range, an older server) or the connection failed,
/// 2 for a bad --server (CLI11 rejects the other bad options before this runs).
int RunHistory(const HistoryCmdOptions& options);

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_HISTORY_CMD_H_
