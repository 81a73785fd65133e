/// @brief `sculpt`: the command-line client. Subcommands: demo, info, export, play, thesis, skin,
/// undo, redo, history, cluster status, cluster move, cluster rebalance.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <tuple>

#include "demo.h"
#ifdef SCULPT_CLI_CLUSTER
#include "cluster_cmd.h"
#endif
#include "history_cmd.h"
#include "play_cmd.h"
#include "sculpt/client/client.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/mesh/chunk_mesher.h"
#include "sculpt/mesh/glb_writer.h"
#include "sculpt/mesh/mesh_stats.h"
#include "skin_cmd.h"
#include "tls_flags.h"
#include "token_flags.h"
#include "thesis_cmd.h"
#include "undo_cmd.h"

namespace {

using nlohmann::json;

json Vec3Json(const sculpt::v1::Vec3f& v) { return json::array({v.x(), v.y(), v.z()}); }

std::string Hex(uint64_t v) {
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(v));
  return hex;
}

/// `sculpt info --server`: the scene as a viewer sees it on joining, as JSON.
int RemoteInfo(const std::string& server, const std::string& token, const std::string& scene,
               const sculpt::client::ClientTlsOptions& tls) {
  auto joined = sculpt::client::FetchScene(server, token, sculpt::v1::ROLE_VIEWER, scene,
                                           std::chrono::seconds(30), tls);
  if (!joined.ok()) {
    spdlog::error("{}: {}", server, joined.status().ToString());
    return 1;
  }
  const sculpt::v1::SceneInfo& info = joined->info;
  json objects = json::array();
  for (const sculpt::v1::ObjectInfo& o : info.objects()) {
    auto state = joined->state.find(o.name());
    objects.push_back({{"name", o.name()},
                       {"voxel_size", o.voxel_size()},
                       {"half_width", o.half_width()},
                       {"bounds_min", Vec3Json(o.bounds_min())},
                       {"bounds_max", Vec3Json(o.bounds_max())},
                       {"volume", o.volume()},
                       {"reference_volume", o.reference_volume()},
                       {"state_hash", Hex(o.state_hash())},
                       {"state_bytes", state == joined->state.end() ? 0 : state->second.size()}});
  }
  const sculpt::v1::Effects& e = info.effects();
  const json out = {{"server", server},
                    {"scene", info.scene()},
                    {"global_seq", info.global_seq()},
                    {"min_tool_size", info.min_tool_size()},
                    {"max_tool_size", info.max_tool_size()},
                    {"max_speed", info.max_speed()},
                    {"effects",
                     {{"volume_preservation", e.volume_preservation()},
                      {"smoothing", e.smoothing()},
                      {"islands", e.islands()},
                      {"min_island_volume", e.min_island_volume()},
                      {"band_repair", e.band_repair()}}},
                    {"objects", objects}};
  std::printf("%s\n", out.dump(2).c_str());
  return 0;
}

struct ExportArgs {
  std::string in, out, format, server, token, object, scene;
  double adaptivity = 0.0;
  sculpt::client::ClientTlsOptions tls;
};

/// `sculpt export`: a .vdb file or a server's current state, written as .vdb, .obj, .ply or .glb
/// (glTF 2.0 binary, Draco-compressed with KHR_draco_mesh_compression).
int Export(const ExportArgs& a) {
  if (a.in.empty() == a.server.empty()) {
    spdlog::error("export: give either a .vdb file or --server HOST:PORT (not both)");
    return 2;
  }
  std::string ext = std::filesystem::path(a.out).extension().string();
  if (!ext.empty()) ext.erase(0, 1);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  const std::string format = a.format.empty() ? ext : a.format;
  if (format != "vdb" && format != "obj" && format != "ply" && format != "glb") {
    spdlog::error(
        "export: format={} outside {{vdb, obj, ply, glb}} (from --format or the --out "
        "extension)",
        format.empty() ? "(none)" : format);
    return 2;
  }
  std::string out = a.out;
  if (ext.empty()) {
    out += "." + format;
  } else if (ext != format) {
    spdlog::error("export: --format {} but --out {} ends in .{}", format, a.out, ext);
    return 2;
  }

  std::optional<sculpt::levelset::Sculpture> sculpture;
  if (!a.in.empty()) {
    auto s = sculpt::levelset::Sculpture::LoadVdb(a.in);
    if (!s.ok()) {
      spdlog::error("{}", s.status().ToString());
      return 1;
    }
    sculpture.emplace(std::move(s).value());
  } else {
    auto joined = sculpt::client::FetchScene(a.server, a.token, sculpt::v1::ROLE_VIEWER, a.scene,
                                             std::chrono::seconds(30), a.tls);
    if (!joined.ok()) {
      spdlog::error("{}: {}", a.server, joined.status().ToString());
      return 1;
    }
    std::string name = a.object;
    if (name.empty() && joined->info.objects_size() > 0) name = joined->info.objects(0).name();
    auto state = joined->state.find(name);
    if (state == joined->state.end()) {
      spdlog::error("export: --object={} outside the scene's objects", name);
      return 2;
    }
    auto s = sculpt::levelset::Sculpture::DeserializeVdb(state->second);
    if (!s.ok()) {
      spdlog::error("{}", s.status().ToString());
      return 1;
    }
    spdlog::info("{}: object {} at global seq {} ({} bytes, state hash {})", a.server, name,
                 joined->info.global_seq(), state->second.size(), Hex(s->StateHash()));
    sculpture.emplace(std::move(s).value());
  }
  if (format == "vdb") {
    if (const sculpt::Status s = sculpture->SaveVdb(out); !s.ok()) {
      spdlog::error("{}", s.ToString());
      return 1;
    }
    spdlog::info("wrote {}: {} active voxels", out, sculpture->ActiveVoxelCount());
    return 0;
  }
  if (format == "glb") {
    auto g = sculpt::mesh::WriteGlb(*sculpture, out);
    if (!g.ok()) {
      spdlog::error("{}", g.status().ToString());
      return 1;
    }
    spdlog::info("wrote {}: {} vertices, {} triangles (Draco)", out, g->vertices, g->triangles);
    return 0;
  }
  auto m = sculpture->ExportMesh(out, a.adaptivity);
  if (!m.ok()) {
    spdlog::error("{}", m.status().ToString());
    return 1;
  }
  spdlog::info("wrote {}: {} vertices, {} triangles", out, m->vertices, m->triangles);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"sculpt: the Sculpt command-line client"};
  app.require_subcommand(1);

  sculpt::client::DemoOptions demo;
  CLI::App* demo_cmd = app.add_subcommand(
      "demo", "Run the scripted sculpting session on the default scene and write its results");
  demo_cmd->add_option("--out", demo.out_dir, "Output folder")->capture_default_str();
  demo_cmd->add_option("--radius", demo.radius, "Sphere radius (world units)")
      ->check(CLI::Range(2.0, 200.0))
      ->capture_default_str();
  demo_cmd->add_option("--voxel-size", demo.voxel_size, "Voxel size (world units)")
      ->check(CLI::Range(0.05, 10.0))
      ->capture_default_str();
  demo_cmd->add_option("--strokes", demo.strokes, "Press samples in the scripted groove")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  demo_cmd->add_option("--seed", demo.seed, "Random seed for the stroke jitter")
      ->capture_default_str();

  std::string vdb_path, info_server, info_token, info_scene;
  CLI::App* info_cmd = app.add_subcommand(
      "info", "Print a .vdb sculpture's statistics, or a running server's scene (--server)");
  info_cmd->add_option("file", vdb_path, ".vdb file")->check(CLI::ExistingFile);
  info_cmd->add_option("--server", info_server, "sculptd address HOST:PORT (joins as a viewer)");
  sculpt::client::TokenFlags info_token_flags;
  info_token_flags.fallback = "sculpt-dev-viewer";
  sculpt::client::AddTokenFlags(*info_cmd, &info_token_flags, "Viewer token");
  info_cmd->add_option("--scene", info_scene, "Scene (default: the server's)");
  sculpt::client::ClientTlsOptions info_tls;
  sculpt::client::AddTlsFlags(*info_cmd, &info_tls);
  bool info_mesh_stats = false;
  info_cmd->add_flag("--mesh-stats", info_mesh_stats,
                     "With a .vdb file: also mesh it as viewers see it and print its topology "
                     "(open and non-manifold edges, pieces, genus, signed volume)");

  ExportArgs ex;
  CLI::App* export_cmd = app.add_subcommand(
      "export",
      "Write a .vdb sculpture, or a running server's current state, as VDB, OBJ, PLY or GLB");
  export_cmd->add_option("file", ex.in, ".vdb file (or --server)")->check(CLI::ExistingFile);
  export_cmd->add_option("--out", ex.out, "Output file (.vdb, .obj, .ply or .glb)")->required();
  export_cmd
      ->add_option("--format", ex.format, "vdb | obj | ply | glb (default: the --out extension)")
      ->check(CLI::IsMember({"vdb", "obj", "ply", "glb"}));
  export_cmd->add_option("--adaptivity", ex.adaptivity, "volumeToMesh adaptivity")
      ->check(CLI::Range(0.0, 1.0));
  export_cmd->add_option("--server", ex.server,
                         "Fetch the current state from sculptd at HOST:PORT as a viewer");
  sculpt::client::TokenFlags export_token;
  export_token.fallback = "sculpt-dev-viewer";
  sculpt::client::AddTokenFlags(*export_cmd, &export_token, "Viewer token");
  export_cmd->add_option("--object", ex.object, "Object to export (default: the scene's first)");
  export_cmd->add_option("--scene", ex.scene, "Scene (default: the server's)");
  sculpt::client::AddTlsFlags(*export_cmd, &ex.tls);

  sculpt::client::PlayOptions play;
  CLI::App* play_cmd = app.add_subcommand(
      "play", "Send a stroke script to a running sculptd as a sculptor; print a JSON summary");
  play_cmd->footer(sculpt::client::kPlayScriptHelp);
  play_cmd->add_option("--server", play.server, "sculptd address HOST:PORT")->required();
  play_cmd
      ->add_option("--script", play.script,
                   "Stroke script (JSON; format below; optional with --haptics)")
      ->check(CLI::ExistingFile);
  sculpt::client::TokenFlags play_token;
  play_token.fallback = "sculpt-dev-sculptor";
  sculpt::client::AddTokenFlags(*play_cmd, &play_token, "Sculptor token");
  play_cmd->add_option("--object", play.object,
                       "Object every stroke sculpts (default: the script's \"object\", else the "
                       "scene's first object)");
  play_cmd->add_option("--name", play.name, "Name shown to others")->capture_default_str();
  play_cmd->add_option("--client-id", play.client_id_text,
                       "Client id to sculpt under, which `sculpt undo --client-id` takes back "
                       "(default: $SCULPT_CLIENT_ID, else a random one; printed as client_id)");
  play_cmd->add_option("--scene", play.scene, "Scene (default: the script's, else the server's)");
  play_cmd->add_option("--timeout", play.timeout_s, "Seconds to wait for the last acks")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  play_cmd->add_option("--speedup", play.speedup, "Play the script this many times faster")
      ->check(CLI::Range(0.001, 1e6))
      ->capture_default_str();
  sculpt::client::AddPlayHapticsOptions(*play_cmd, play);
  sculpt::client::AddTlsFlags(*play_cmd, &play.tls);

  CLI::App* thesis_cmd = app.add_subcommand(
      "thesis", "Rerun the thesis's 2D carve and compensation experiments; print JSON");

  sculpt::client::SkinCmdOptions skin_opts;
  CLI::App* skin_cmd = sculpt::client::AddSkinCommand(app, skin_opts);

  sculpt::client::UndoCmdOptions undo_opts, redo_opts;
  CLI::App* undo_cmd = sculpt::client::AddUndoCommand(app, /*redo=*/false, undo_opts);
  CLI::App* redo_cmd = sculpt::client::AddUndoCommand(app, /*redo=*/true, redo_opts);
  sculpt::client::TokenFlags undo_token, redo_token;
  undo_token.fallback = redo_token.fallback = "sculpt-dev-sculptor";
  sculpt::client::AddTokenFlags(*undo_cmd, &undo_token, "Sculptor token");
  sculpt::client::AddTokenFlags(*redo_cmd, &redo_token, "Sculptor token");
  sculpt::client::HistoryCmdOptions history_opts;
  CLI::App* history_cmd = sculpt::client::AddHistoryCommand(app, history_opts);
  sculpt::client::TokenFlags history_token;
  history_token.fallback = sculpt::client::HistoryFallbackToken("viewer");
  sculpt::client::AddTokenFlags(*history_cmd, &history_token, "Token of the --role");

#ifdef SCULPT_CLI_CLUSTER
  sculpt::client::ClusterStatusOptions cluster_opts;
  sculpt::client::ClusterMoveOptions cluster_move_opts;
  sculpt::client::ClusterRebalanceOptions cluster_rebalance_opts;
  const sculpt::client::ClusterCommands cluster_cmds = sculpt::client::AddClusterCommand(
      app, cluster_opts, cluster_move_opts, cluster_rebalance_opts);
#endif

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0 after printing; a refused option exits 2, as each command's
    // help says (CLI11's own codes, 105 for a failed check and so on, say nothing more).
    return app.exit(e) == 0 ? 0 : 2;
  }

  // Secrets come from a file or the environment; a token flag stops here with directions.
  for (auto [cmd, flags, token] : {std::tuple{info_cmd, &info_token_flags, &info_token},
                                   std::tuple{export_cmd, &export_token, &ex.token},
                                   std::tuple{play_cmd, &play_token, &play.token},
                                   std::tuple{undo_cmd, &undo_token, &undo_opts.token},
                                   std::tuple{redo_cmd, &redo_token, &redo_opts.token},
                                   std::tuple{history_cmd, &history_token, &history_opts.token}}) {
    if (!cmd->parsed()) continue;
    if (cmd == history_cmd) {
      flags->fallback = sculpt::client::HistoryFallbackToken(history_opts.role);
    }
    auto t = sculpt::client::ResolveTokenFlags(*flags);
    if (!t.ok()) {
      spdlog::error("{}: {}", cmd->get_name(), t.status().ToString());
      return 2;
    }
    *token = *t;
  }

#ifdef SCULPT_CLI_CLUSTER
  if (*cluster_cmds.status) return sculpt::client::RunClusterStatus(cluster_opts);
  if (*cluster_cmds.move) return sculpt::client::RunClusterMove(cluster_move_opts);
  if (*cluster_cmds.rebalance) {
    return sculpt::client::RunClusterRebalance(cluster_rebalance_opts);
  }
#endif
  if (*skin_cmd) return sculpt::client::RunSkin(skin_opts);
  if (*undo_cmd) return sculpt::client::RunUndo(undo_opts);
  if (*redo_cmd) return sculpt::client::RunUndo(redo_opts);
  if (*history_cmd) return sculpt::client::RunHistory(history_opts);

  if (*thesis_cmd) {
    std::printf("%s\n", sculpt::client::RunThesisReproduction().c_str());
    return 0;
  }

  if (*demo_cmd) {
    const sculpt::Status s = sculpt::client::RunDemo(demo);
    if (!s.ok()) {
      spdlog::error("demo failed: {}", s.ToString());
      return 1;
    }
    return 0;
  }
  if (*play_cmd) return sculpt::client::RunPlay(play);
  if (*info_cmd) {
    if (vdb_path.empty() == info_server.empty()) {
      spdlog::error("info: give either a .vdb file or --server HOST:PORT (not both)");
      return 2;
    }
    if (!info_server.empty()) return RemoteInfo(info_server, info_token, info_scene, info_tls);
    auto s = sculpt::levelset::Sculpture::LoadVdb(vdb_path);
    if (!s.ok()) {
      spdlog::error("{}", s.status().ToString());
      return 1;
    }
    nlohmann::json j = {{"name", s->name()},
                        {"voxel_size", s->voxel_size()},
                        {"half_width", s->half_width()},
                        {"active_voxels", s->ActiveVoxelCount()},
                        {"volume", s->volume()},
                        {"reference_volume", s->reference_volume()},
                        {"state_hash", Hex(s->StateHash())}};
    if (info_mesh_stats) {
      const sculpt::mesh::MeshTopology t =
          sculpt::mesh::ComputeTopology(sculpt::mesh::MeshWhole(*s));
      j["mesh"] = {{"vertices", t.vertices},
                   {"triangles", t.faces},
                   {"boundary_edges", t.boundary_edges},
                   {"non_manifold_edges", t.non_manifold_edges},
                   {"inconsistent_edges", t.inconsistent_edges},
                   {"components", t.components},
                   {"euler_characteristic", t.euler},
                   {"genus", t.genus},
                   {"signed_volume", t.signed_volume},
                   {"signed_volume_over_tracked", s->volume() > 0 ? t.signed_volume / s->volume()
                                                                  : 0.0}};
    }
    std::printf("%s\n", j.dump().c_str());
    return 0;
  }
  if (*export_cmd) return Export(ex);
  return 0;
}
