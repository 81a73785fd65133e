/// @brief `sculpt play`: sends a stroke script (poses over time) to a running sculptd as a
/// sculptor, waits for the acks and prints a JSON summary.
#ifndef SCULPT_CLIENT_PLAY_CMD_H_
#define SCULPT_CLIENT_PLAY_CMD_H_

#include <string>

namespace sculpt::client {

struct PlayOptions {
  std::string server;  // HOST:PORT
  std::string script;  // path of the JSON stroke script
  std::string token = "sculpt-dev-sculptor";
  std::string name = "sculpt-play";
  std::string scene;      // empty: the script's "scene", else the server's default
  double timeout_s = 30;  // for the last acks after the last stroke
  double speedup = 1;     // divides every time in the script
};

/// The stroke script format, shown by `sculpt play --help`.
extern const char kPlayScriptHelp[];

/// Runs the script. Prints the JSON summary on stdout. Returns the process exit code: 0 when
/// every stroke was acked, 1 when one was refused or un-acked or the connection failed, 2 for a
/// script that does not parse (the error names the JSON path).
int RunPlay(const PlayOptions& options);

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_PLAY_CMD_H_
