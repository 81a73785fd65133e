/// @brief LoadRun: N simulated sculptors and M viewers against one sculptd, and the JSON report of
/// what they saw (strokes, acks, latency stroke->ack, errors, bytes per client per second).
#ifndef SCULPT_CLIENT_LOADGEN_LOAD_RUN_H_
#define SCULPT_CLIENT_LOADGEN_LOAD_RUN_H_

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "sculpt/client/client.h"
#include "sculpt/core/status.h"

namespace sculpt::client {

struct LoadOptions {
  std::string server;  // HOST:PORT
  int sculptors = 4;
  int viewers = 0;
  double rate_hz = 120;      // pose samples per second per sculptor
  double seconds = 10;       // sending phase
  int poses_per_stroke = 4;  // a sculptor sends rate_hz / poses_per_stroke strokes per second
  uint64_t seed = 1;         // trajectories only; client ids are always fresh
  std::string sculptor_token = "sculpt-dev-sculptor";
  std::string viewer_token = "sculpt-dev-viewer";
  ClientTlsOptions tls;       // every client's TLS settings (off: plain TCP)
  std::string scene;          // empty: the server's default
  std::string object;         // empty: the scene's first object
  double tool_radius = 2.5;   // sphere tool, world units
  double press_speed = 60;    // Stroke.speed, world units per second
  double walk_speed = 60;     // tool motion over the surface, world units per second
  double depth = 1.0;         // poses this far inside the surface, world units
  double drain_seconds = 60;  // wait for the last acks after the sending phase
  int io_threads = 2;
  /// Replica clients (issue 4), each holding the whole object: in replay mode and in leaf-delta
  /// mode, so one run measures both on the same edits.
  int replay_replicas = 1;
  int leafdelta_replicas = 1;
  /// Viewers subscribe to Draco mesh chunks at this rate (0: no mesh subscription); the first
  /// viewer decodes every chunk it receives, to measure decode time.
  double viewer_mesh_hz = 10;
  /// One extra client runs the 1 kHz haptic loop (proxy model) on its own replica's snapshots,
  /// its simulated device pressing in and out of the object's top during the run (issue 5).
  bool haptic_client = false;
  /// One more sculptor (issue 15) that walks and strokes like the others and, every
  /// undo_every-th turn, undoes its own most recent stroke instead (0: no such client). The
  /// report's `undo_client` gives the undo latency and the other sculptors' stroke->ack latency
  /// for strokes in flight during an undo and otherwise.
  int undo_every = 0;
};

/// Late join: one replica client subscribes to the whole object; bytes and time until its
/// region is loaded.
StatusOr<nlohmann::ordered_json> RunLateJoin(const LoadOptions& options);

/// Mesh join: a replica client loads the object and lists the chunks holding surface
/// (mesh::AllChunks at chunk_voxels), then a new viewer subscribes to the mesh; the time from its
/// join (and from its subscription) until it holds every one of those chunks, and until 50% and
/// 99% of them. Under concurrent edits a listed chunk may be emptied before it is meshed; the run
/// then ends at `timeout_s` with `complete` false and the fractions reached.
StatusOr<nlohmann::ordered_json> RunMeshJoin(const LoadOptions& options, int chunk_voxels,
                                             double timeout_s);

/// Connects every client, runs the sending phase, waits for the acks and returns the report.
/// InvalidArgument for bad options; the connection's error when a client cannot join.
StatusOr<nlohmann::ordered_json> RunLoad(const LoadOptions& options);

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_LOADGEN_LOAD_RUN_H_
