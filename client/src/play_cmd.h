/// @brief `sculpt play`: sends a stroke script (poses over time) to a running sculptd as a
/// sculptor, waits for the acks and prints a JSON summary; with --haptics, renders forces at
/// 1 kHz on a replica of the object and sends strokes sampled from a simulated device.
#ifndef SCULPT_CLIENT_PLAY_CMD_H_
#define SCULPT_CLIENT_PLAY_CMD_H_

#include <string>

#include "sculpt/client/client.h"

namespace CLI {
class App;
}  // namespace CLI

namespace sculpt::client {

/// `sculpt play --haptics`: the haptic session's settings.
struct PlayHapticsOptions {
  bool enabled = false;
  std::string model = "proxy";  // penalty | proxy
  double stiffness = 1.0;       // force per world unit of penetration
  double damping = 0.05;        // proxy damper, force per unit speed
  double max_force = 20.0;
  double tool_radius = 0;  // 0: the script's tool size, else 2.0
  int tool_samples = 128;
  double interest_radius = 0;     // 0: replicate the whole object
  double stroke_rate = 30;        // strokes per second, 4 poses each sampled from the device
  double duration_s = 3;          // the built-in path's length
  int snapshot_ms = 5;            // replica snapshots at most this often
  bool verify_snapshots = false;  // seal each snapshot by state hash, count torn ticks
  bool json = false;              // the end report as JSON (else text)
};

struct PlayOptions {
  std::string server;  // HOST:PORT
  std::string script;  // path of the JSON stroke script
  std::string token = "sculpt-dev-sculptor";
  ClientTlsOptions tls;
  std::string name = "sculpt-play";
  std::string scene;      // empty: the script's "scene", else the server's default
  std::string object;     // empty: the script's "object", else the scene's first object
  double timeout_s = 30;  // for the last acks after the last stroke
  double speedup = 1;     // divides every time in the script
  // The client id to sculpt under (--client-id, else $SCULPT_CLIENT_ID, else a random one):
  // `sculpt undo` with the same id takes these strokes back.
  std::string client_id_text;
  PlayHapticsOptions haptics;
};

/// The stroke script format, shown by `sculpt play --help`.
extern const char kPlayScriptHelp[];

/// Adds --haptics and its options to the `play` subcommand, storing into `options`.
void AddPlayHapticsOptions(CLI::App& play, PlayOptions& options);

/// Runs the script, or with --haptics the haptic session (the script, if given, is the device's
/// trajectory). Prints the summary on stdout. Returns the process exit code: 0 when every stroke
/// was acked, 1 when one was refused or un-acked or the connection failed, 2 for a script that
/// does not parse (the error names the JSON path) or bad options.
int RunPlay(const PlayOptions& options);

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_PLAY_CMD_H_
