/// @brief sculpt-loadgen: N simulated sculptors and M viewers in one process against a running
/// sculptd; prints a JSON report (strokes sent/acked, stroke->ack latency, errors, bytes).
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <utility>

#include "loadgen/load_run.h"
#include "tls_flags.h"
#include "token_flags.h"

int main(int argc, char** argv) {
  sculpt::client::LoadOptions o;
  bool as_json = false;
  CLI::App app{
      "sculpt-loadgen: simulated sculptors and viewers against a running sculptd.\n"
      "Each sculptor walks a press brush (sphere tool) over the object's surface with a seeded\n"
      "random walk, poses --depth inside the surface (radius from SceneInfo bounds less the\n"
      "band), sampled at --rate and sent --poses-per-stroke to a stroke. Viewers join and read.\n"
      "Latency is steady_clock from the write of a stroke to its Ack. Byte rates count the\n"
      "window from the first stroke to the last ack (joins excluded), per client.\n"
      "Report keys: strokes_sent, strokes_acked, strokes_refused, strokes_unacked,\n"
      "acks_in_order, duration_s, stroke_ack_p50_ms/p99_ms/max_ms, server_errors,\n"
      "bytes_up_per_client_per_s, bytes_down_per_client_per_s, viewers_received_bytes,\n"
      "final_global_seq, join_retries (joins asked again after a pending-join refusal),\n"
      "clients[] (per-client counts)."};
  app.add_option("--server", o.server, "sculptd address HOST:PORT")->required();
  app.add_option("--sculptors", o.sculptors, "Simulated sculptors")->capture_default_str();
  app.add_option("--viewers", o.viewers, "Simulated viewers")->capture_default_str();
  app.add_option("--rate", o.rate_hz, "Pose samples per second per sculptor")
      ->capture_default_str();
  app.add_option("--seconds", o.seconds, "Length of the sending phase")->capture_default_str();
  app.add_option("--poses-per-stroke", o.poses_per_stroke, "Poses per stroke message")
      ->capture_default_str();
  app.add_option("--seed", o.seed, "Seed of the trajectories")->capture_default_str();
  // The environment variables are sculptd's, so one shell can start both.
  sculpt::client::TokenFlags sculptor_token, viewer_token;
  sculptor_token.flag = "--sculptor-token";
  sculptor_token.file_flag = "--sculptor-token-file";
  sculptor_token.env = "SCULPT_SCULPTOR_TOKEN";
  sculptor_token.fallback = o.sculptor_token;
  viewer_token.flag = "--viewer-token";
  viewer_token.file_flag = "--viewer-token-file";
  viewer_token.env = "SCULPT_VIEWER_TOKEN";
  viewer_token.fallback = o.viewer_token;
  sculpt::client::AddTokenFlags(app, &sculptor_token, "Sculptor token");
  sculpt::client::AddTokenFlags(app, &viewer_token, "Viewer token");
  app.add_option("--scene", o.scene, "Scene to join (default: the server's)");
  sculpt::client::AddTlsFlags(app, &o.tls);
  app.add_option("--object", o.object, "Object to sculpt (default: the scene's first)");
  app.add_option("--tool-radius", o.tool_radius, "Sphere tool radius, world units")
      ->capture_default_str();
  app.add_option("--press-speed", o.press_speed, "Press speed, world units/s")
      ->capture_default_str();
  app.add_option("--walk-speed", o.walk_speed, "Tool speed over the surface, world units/s")
      ->capture_default_str();
  app.add_option("--depth", o.depth, "Poses this far inside the surface, world units")
      ->capture_default_str();
  app.add_option("--drain-seconds", o.drain_seconds, "Wait this long for the last acks")
      ->capture_default_str();
  app.add_option("--io-threads", o.io_threads, "Client I/O threads shared by all clients")
      ->capture_default_str();
  app.add_option("--replay-replicas", o.replay_replicas,
                 "Whole-object replica clients in replay mode (edit broadcasts)")
      ->capture_default_str();
  app.add_option("--leafdelta-replicas", o.leafdelta_replicas,
                 "Whole-object replica clients in leaf-delta mode (the same edits as leaves)")
      ->capture_default_str();
  app.add_option("--viewer-mesh-hz", o.viewer_mesh_hz,
                 "Viewers subscribe to Draco mesh chunks at this rate (0: none)")
      ->capture_default_str();
  app.add_flag("--haptic-client", o.haptic_client,
               "One more client runs the 1 kHz haptic loop on its replica; report its timing");
  bool late_join = false;
  app.add_flag("--late-join", late_join,
               "Only measure a late join: one replica loads the whole object (bytes, ms)");
  bool mesh_join = false;
  int mesh_chunk_voxels = 32;
  double mesh_join_timeout_s = 120;
  app.add_flag("--mesh-join", mesh_join,
               "Only measure a mesh join: time until a new viewer holds every surface chunk "
               "(subscribing at --viewer-mesh-hz)");
  app.add_option("--mesh-chunk-voxels", mesh_chunk_voxels,
                 "--mesh-join: the server's scene.mesh_chunk_voxels")
      ->capture_default_str();
  app.add_option("--mesh-join-timeout", mesh_join_timeout_s,
                 "--mesh-join: give up after this many seconds")
      ->capture_default_str();
  app.add_option("--undo-every", o.undo_every,
                 "Add one sculptor that undoes its own last stroke every N-th turn (0: none)")
      ->capture_default_str();
  app.add_flag("--json", as_json, "Print the JSON report (otherwise a short summary)");
  CLI11_PARSE(app, argc, argv);
  for (auto [flags, token] :
       {std::pair{&sculptor_token, &o.sculptor_token}, std::pair{&viewer_token, &o.viewer_token}}) {
    auto t = sculpt::client::ResolveTokenFlags(*flags);
    if (!t.ok()) {
      spdlog::error("{}", t.status().ToString());
      return 2;
    }
    *token = *t;
  }

  if (mesh_join) {
    auto mj = sculpt::client::RunMeshJoin(o, mesh_chunk_voxels, mesh_join_timeout_s);
    if (!mj.ok()) {
      spdlog::error("mesh join failed: {}", mj.status().ToString());
      return 1;
    }
    if (as_json) {
      std::printf("%s\n", mj->dump(2).c_str());
    } else {
      std::printf("mesh join: %zu of %zu chunks, complete %.1f ms after subscribing\n",
                  (*mj)["received_expected_chunks"].get<size_t>(),
                  (*mj)["expected_chunks"].get<size_t>(),
                  (*mj)["subscribe_to_complete_ms"].get<double>());
    }
    return (*mj)["complete"].get<bool>() ? 0 : 3;
  }

  if (late_join) {
    auto lj = sculpt::client::RunLateJoin(o);
    if (!lj.ok()) {
      spdlog::error("late join failed: {}", lj.status().ToString());
      return 1;
    }
    if (as_json) {
      std::printf("%s\n", lj->dump(2).c_str());
    } else {
      std::printf("late join: %llu bytes in %.1f ms\n",
                  (*lj)["late_join_bytes"].get<unsigned long long>(),
                  (*lj)["late_join_ms"].get<double>());
    }
    return 0;
  }

  auto report = sculpt::client::RunLoad(o);
  if (!report.ok()) {
    spdlog::error("load run failed: {}", report.status().ToString());
    return 1;
  }
  const nlohmann::ordered_json& r = *report;
  if (as_json) {
    std::printf("%s\n", r.dump(2).c_str());
    return 0;
  }
  std::printf(
      "%d sculptors, %d viewers, %.1f s: %llu strokes sent, %llu acked, %llu refused, %llu "
      "un-acked; stroke->ack p50 %.2f ms, p99 %.2f ms, max %.2f ms; %llu server errors; "
      "%.0f B/s up, %.0f B/s down per client; acks in order: %s; final global seq %llu\n",
      o.sculptors, o.viewers, r["duration_s"].get<double>(),
      r["strokes_sent"].get<unsigned long long>(), r["strokes_acked"].get<unsigned long long>(),
      r["strokes_refused"].get<unsigned long long>(),
      r["strokes_unacked"].get<unsigned long long>(), r["stroke_ack_p50_ms"].get<double>(),
      r["stroke_ack_p99_ms"].get<double>(), r["stroke_ack_max_ms"].get<double>(),
      r["server_errors"].get<unsigned long long>(), r["bytes_up_per_client_per_s"].get<double>(),
      r["bytes_down_per_client_per_s"].get<double>(), r["acks_in_order"].get<bool>() ? "yes" : "no",
      r["final_global_seq"].get<unsigned long long>());
  return 0;
}
