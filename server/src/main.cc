/// @brief sculptd: the authoritative Sculpt server. `sculptd serve [--config scene.toml] ...`,
/// `sculptd repair --data DIR [--dry-run]`.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <filesystem>
#include <memory>
#include <thread>
#include <vector>

#include "cluster/cluster_agent.h"
#include "config/server_config.h"
#include "net/http_server.h"
#include "net/metrics.h"
#include "net/server.h"
#include "net/users.h"
#include "net/tls.h"
#include "scene/scene.h"
#include "store/edit_log.h"

namespace {

// The web client: the build's output if there is one, else the installed copy.
std::filesystem::path DefaultWebRoot() {
  std::error_code ec;
  for (const char* dir : {SCULPT_WEB_BUILD_DIR, SCULPT_WEB_SOURCE_DIST_DIR}) {
    if (std::filesystem::is_directory(dir, ec)) return dir;
  }
  return SCULPT_WEB_INSTALL_DIR;
}

// Written whole and renamed into place, so a reader polling for the file never sees half.
bool WritePortFile(const std::string& path, uint16_t tcp_port, uint16_t http_port) {
  const std::string tmp = path + ".tmp";
  FILE* f = std::fopen(tmp.c_str(), "w");
  if (!f) return false;
  const bool ok = std::fprintf(f, "%u\n%u\n", tcp_port, http_port) > 0;
  if (std::fclose(f) != 0 || !ok) return false;
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  return !ec;
}

// `sculptd user add|remove|list`: the users file is read, changed and written back atomically;
// a new token is printed once and only its hash is kept.
int UserCommand(const std::string& verb, const std::string& file, const std::string& name,
                const std::string& role) {
  using sculpt::server::UserTable;
  UserTable table;
  auto loaded = UserTable::Load(file);
  if (loaded.ok()) {
    table = std::move(loaded).value();
  } else if (verb != "add" || loaded.status().code() != sculpt::Status::Code::kNotFound) {
    spdlog::error("{}", loaded.status().ToString());
    return 1;
  }
  if (verb == "list") {
    for (const auto& u : table.users()) {
      std::printf("%s %s\n", u.name.c_str(), sculpt::server::UserRoleName(u.role));
    }
    return 0;
  }
  if (const sculpt::Status n = sculpt::server::CheckUserName("NAME", name); !n.ok()) {
    spdlog::error("{}", n.message());
    return 2;
  }
  if (verb == "remove") {
    if (!table.Remove(name)) {
      spdlog::error("{}: no user {}", file, name);
      return 1;
    }
  } else {
    const std::string token = sculpt::server::NewToken();
    auto hash = sculpt::server::HashToken(token);
    if (!hash.ok()) {
      spdlog::error("{}", hash.status().ToString());
      return 1;
    }
    table.Put({name, role == "sculptor" ? sculpt::server::UserRole::kSculptor
                                        : sculpt::server::UserRole::kViewer,
               *hash});
    if (const sculpt::Status s = table.Save(file); !s.ok()) {
      spdlog::error("{}", s.ToString());
      return 1;
    }
    std::printf("%s\n", token.c_str());
    std::fprintf(stderr,
                 "user %s (%s) saved in %s. The token above is shown this once; give it to the "
                 "user (the client takes it from a file or the environment). A running sculptd "
                 "picks the change up on SIGHUP.\n",
                 name.c_str(), role.c_str(), file.c_str());
    return 0;
  }
  if (const sculpt::Status s = table.Save(file); !s.ok()) {
    spdlog::error("{}", s.ToString());
    return 1;
  }
  std::fprintf(stderr, "user %s removed from %s (a running sculptd: send SIGHUP)\n", name.c_str(),
               file.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  using sculpt::server::ServerConfig;
  CLI::App app{"sculptd: the authoritative Sculpt server"};
  app.require_subcommand(1);
  CLI::App* serve = app.add_subcommand(
      "serve", "Serve one scene, or several with --also-scene (defaults need no file)");

  std::string config_path;
  std::string listen, data_dir, fsync, sculptor_token, viewer_token;
  int io_threads = 0, group_ms = 0;
  int64_t snapshot_every = -1;
  std::string port_file;
  serve->add_option("--config", config_path, "TOML scene/server file (see deploy/scene.toml)")
      ->check(CLI::ExistingFile);
  serve->add_option("--listen", listen, "HOST:PORT to listen on (default 127.0.0.1:7420; port 0 "
                                        "picks a free one)");
  serve->add_option("--data", data_dir, "Data directory: edit log and snapshots "
                                        "(default ./sculpt-data; scenes beside scene.name in "
                                        "its scenes/NAME)");
  std::vector<std::string> also_scenes;
  serve->add_option("--also-scene", also_scenes,
                    "Host this scene too, beside scene.name, with the same [scene] settings; "
                    "repeatable, appended to scene.also (docs/scenes.md)");
  serve->add_option("--fsync", fsync, "Edit log durability: always | group (default group)")
      ->check(CLI::IsMember({"always", "group"}));
  serve->add_option("--group-commit-ms", group_ms, "Group commit window (default 5 ms)")
      ->check(CLI::Range(1, 1000));
  serve->add_option("--io-threads", io_threads, "Network threads (default 2)")
      ->check(CLI::Range(1, 64));
  serve->add_option("--snapshot-every", snapshot_every, "Snapshot every N edits (default 5000)")
      ->check(CLI::Range(int64_t{0}, int64_t{1} << 40));
  // Accepted only to be refused with directions: a flag's value is visible to every local user
  // in `ps`.
  serve->add_option("--sculptor-token", sculptor_token,
                    "Refused: secrets do not go on the command line (see --users, "
                    "SCULPT_SCULPTOR_TOKEN)");
  serve->add_option("--viewer-token", viewer_token,
                    "Refused: secrets do not go on the command line (see --users, "
                    "SCULPT_VIEWER_TOKEN)");
  std::string users_file;
  serve->add_option("--users", users_file,
                    "Users file: named users, each with a role and a token hash (see `sculptd user "
                    "add`); re-read on SIGHUP. Without one, the shared sculptor and viewer tokens "
                    "(configuration file or SCULPT_SCULPTOR_TOKEN / SCULPT_VIEWER_TOKEN; the "
                    "development tokens on loopback only)");
  serve->add_option("--port-file", port_file,
                    "Write the bound ports to this file once listening: the TCP port on the first "
                    "line, the HTTP port (0 when off) on the second");
  std::string http_listen, web_root;
  size_t http_max_connections = 0;
  int http_idle_ms = 0;
  serve->add_option("--http", http_listen,
                    "HOST:PORT of the HTTP port (web client, /ws, /metrics, /healthz, /readyz), or "
                    "'off' (default 127.0.0.1:7421; port 0 when --listen's port is 0)");
  serve->add_option("--web-root", web_root,
                    "Directory of the web client's files (default: the build's client/web/dist, "
                    "else the installed share/sculpt/web)");
  std::vector<std::string> allowed_origins;
  serve->add_option("--http-allow-origin", allowed_origins,
                    "Another origin whose pages may open /ws (e.g. a dev server "
                    "http://localhost:5173); repeatable. The page's own origin always may");
  serve->add_option("--http-max-connections", http_max_connections,
                    "Open HTTP connections and WebSocket sessions at most (default 512)")
      ->check(CLI::Range(size_t{1}, size_t{100000}));
  serve->add_option("--http-idle-timeout-ms", http_idle_ms,
                    "Close an HTTP connection that sends no request for this long (default 15000)")
      ->check(CLI::Range(100, 3600000));

  // Limits an operator sets most often; the rest are in the configuration file's [limits]
  // (deploy/scene.toml, docs/limits.md). A flag overrides the file.
  const sculpt::server::LimitsConfig ld;
  int64_t max_sessions = -1, max_per_source = -1, reserved_seats = -1, max_clients = -1;
  int auth_timeout = -1, join_timeout = -1, idle_timeout = -1, frame_timeout = -1;
  int64_t send_queue = -1, stroke_work = -1;
  double strokes_rate = -1, requests_rate = -1, source_factor = -1;
  auto* limits = serve->add_option_group("Limits", "Per-client and per-address limits "
                                                   "(config [limits]; docs/limits.md)");
  limits->add_option("--max-sessions", max_sessions,
                     "Open sessions at most, TCP and WebSocket, authenticated or not (default " +
                         std::to_string(ld.max_sessions) + ")")
      ->check(CLI::Range(int64_t{1}, int64_t{1000000}));
  limits->add_option("--max-connections-per-source", max_per_source,
                     "Open sessions from one IP address at most (default " +
                         std::to_string(ld.max_connections_per_source) + ")")
      ->check(CLI::Range(int64_t{1}, int64_t{1000000}));
  limits->add_option("--max-clients-per-scene", max_clients,
                     "Joined clients per scene at most (default " +
                         std::to_string(ld.max_clients_per_scene) + ")")
      ->check(CLI::Range(int64_t{1}, int64_t{100000}));
  limits->add_option("--reserved-sculptor-seats", reserved_seats,
                     "Seats of the scene viewers may not take (default " +
                         std::to_string(ld.reserved_sculptor_seats) + ")")
      ->check(CLI::Range(int64_t{0}, int64_t{100000}));
  limits->add_option("--auth-timeout-ms", auth_timeout,
                     "A connection must authenticate (and finish TLS) within this (default " +
                         std::to_string(ld.auth_timeout_ms) + ")")
      ->check(CLI::Range(10, 600000));
  limits->add_option("--join-timeout-ms", join_timeout,
                     "An authenticated session must join within this; 0: no limit (default " +
                         std::to_string(ld.join_timeout_ms) + ")")
      ->check(CLI::Range(0, 3600000));
  limits->add_option("--idle-timeout-ms", idle_timeout,
                     "Close a joined session that sends nothing for this long; 0: never "
                     "(default 0: passive viewers send nothing)")
      ->check(CLI::Range(0, 86400000));
  limits->add_option("--frame-timeout-ms", frame_timeout,
                     "A frame begun must be complete within this (slow senders; default " +
                         std::to_string(ld.frame_timeout_ms) + ")")
      ->check(CLI::Range(10, 3600000));
  limits->add_option("--send-queue-bytes", send_queue,
                     "Per-session send queue bound; a client that does not read is dropped past "
                     "it (default " + std::to_string(ld.send_queue_bytes) + ")")
      ->check(CLI::Range(int64_t{64} << 10, int64_t{10000000000}));
  limits->add_option("--max-stroke-work", stroke_work,
                     "A stroke's poses times the voxels its edits read, at most (one pose is "
                     "always allowed): bounds how long one stroke holds up the others (default " +
                         std::to_string(ld.max_stroke_work) + ")")
      ->check(CLI::Range(int64_t{1} << 16, int64_t{1} << 40));
  limits->add_option("--strokes-per-second", strokes_rate,
                     "Stroke rate per client (token bucket; default " +
                         std::to_string(static_cast<int>(ld.strokes_per_second)) + ")")
      ->check(CLI::Range(1.0, 1e5));
  limits->add_option("--requests-per-second", requests_rate,
                     "Request cost per client per second (joins, subscriptions, SetInterest, ...; "
                     "default " + std::to_string(static_cast<int>(ld.requests_per_second)) + ")")
      ->check(CLI::Range(1.0, 1e6));
  limits->add_option("--source-rate-factor", source_factor,
                     "One IP address gets this many clients' worth of every rate, whatever its "
                     "number of connections (default " +
                         std::to_string(static_cast<int>(ld.source_rate_factor)) + ")")
      ->check(CLI::Range(1.0, 1e4));

  std::string tls_cert, tls_key, tls_client_ca;
  bool allow_plaintext = false;
  serve->add_option("--tls-cert", tls_cert,
                    "PEM certificate chain: TLS on the TCP port and HTTPS/WSS on the HTTP port "
                    "(config tls.cert_file)");
  serve->add_option("--tls-key", tls_key, "PEM private key of --tls-cert (config tls.key_file)");
  serve->add_option("--tls-client-ca", tls_client_ca,
                    "PEM CA file: the TCP port then requires client certificates it signed "
                    "(server-to-server traffic; config tls.client_ca_file)");
  serve->add_flag("--allow-plaintext", allow_plaintext,
                  "Listen beyond loopback without TLS (config tls.allow_plaintext; logged as a "
                  "warning)");
  bool check_only = false;
  serve->add_flag("--check", check_only,
                  "Check the configuration (file, flags, environment, TLS files) and exit: 0 "
                  "when it would start, 2 with the reason; opens no scene, port or etcd "
                  "connection");

  CLI::App* repair = app.add_subcommand(
      "repair", "Make a damaged edit log start again, saying exactly which edits it gives up");
  std::string repair_dir;
  bool dry_run = false;
  repair->add_option("--data", repair_dir, "Data directory (its log/ is repaired)")->required();
  repair->add_flag("--dry-run", dry_run, "Only say what would be discarded");

  CLI::App* user = app.add_subcommand("user", "Manage the named users of a users file");
  user->require_subcommand(1);
  std::string user_file, user_name, user_role = "sculptor";
  CLI::App* user_add = user->add_subcommand(
      "add", "Add a user (or give an existing one a new token): prints the new token once");
  user_add->add_option("NAME", user_name, "User name: 1 to 64 characters of [A-Za-z0-9._-]")
      ->required();
  user_add->add_option("--role", user_role, "sculptor | viewer")
      ->check(CLI::IsMember({"sculptor", "viewer"}))
      ->capture_default_str();
  user_add->add_option("--users", user_file, "Users file (created, mode 0600, if missing)")
      ->required();
  CLI::App* user_remove = user->add_subcommand("remove", "Remove a user");
  user_remove->add_option("NAME", user_name, "User name")->required();
  user_remove->add_option("--users", user_file, "Users file")->required();
  CLI::App* user_list = user->add_subcommand("list", "List the users and their roles");
  user_list->add_option("--users", user_file, "Users file")->required();

  CLI11_PARSE(app, argc, argv);
  // Each line reaches the log as it is written: stdout redirected to a file is block-buffered,
  // and a process killed with SIGKILL (a failover, a crash) would lose the lines that explain it.
  spdlog::flush_on(spdlog::level::info);

  if (user->parsed()) return UserCommand(user_add->parsed() ? "add" : user_remove->parsed() ? "remove" : "list",
                                         user_file, user_name, user_role);

  if (repair->parsed()) {
    const std::string log_dir = (std::filesystem::path(repair_dir) / "log").string();
    auto report = sculpt::server::store::EditLog::Repair(log_dir, dry_run);
    if (!report.ok()) {
      spdlog::error("repair of {}: {}", log_dir, report.status().ToString());
      return 1;
    }
    if (report->clean) {
      std::printf("%s: nothing to repair\n", log_dir.c_str());
      return 0;
    }
    std::printf("%s %s:\n", dry_run ? "a repair would" : "repaired", log_dir.c_str());
    for (const std::string& a : report->actions) std::printf("  %s\n", a.c_str());
    std::printf("%s:\n", dry_run ? "acknowledged edits it would discard" : "discarded");
    for (const std::string& d : report->discarded) std::printf("  %s\n", d.c_str());
    return 0;
  }

  ServerConfig config;
  if (!config_path.empty()) {
    const sculpt::Status s = sculpt::server::LoadConfigFile(config_path, &config);
    if (!s.ok()) {
      spdlog::error("{}", s.ToString());
      return 2;
    }
  }
  if (!listen.empty()) config.listen = listen;
  if (!data_dir.empty()) config.data_dir = data_dir;
  config.scene.also.insert(config.scene.also.end(), also_scenes.begin(), also_scenes.end());
  if (!fsync.empty()) config.fsync = fsync;
  if (group_ms > 0) config.group_commit_ms = group_ms;
  if (io_threads > 0) config.io_threads = io_threads;
  if (snapshot_every >= 0) config.snapshot_every_edits = static_cast<uint64_t>(snapshot_every);
  if (!sculptor_token.empty() || !viewer_token.empty()) {
    spdlog::error(
        "--sculptor-token and --viewer-token are refused: a command line is visible to every "
        "local user. Put the tokens in the configuration file's [server] section (readable by "
        "sculptd only), in the environment (SCULPT_SCULPTOR_TOKEN, SCULPT_VIEWER_TOKEN), or use "
        "named users (--users FILE; `sculptd user add NAME --role sculptor --users FILE`)");
    return 2;
  }
  if (const char* t = std::getenv("SCULPT_SCULPTOR_TOKEN"); t && *t) config.sculptor_token = t;
  if (const char* t = std::getenv("SCULPT_VIEWER_TOKEN"); t && *t) config.viewer_token = t;
  if (!users_file.empty()) config.users_file = users_file;
  if (!tls_cert.empty()) config.tls.cert_file = tls_cert;
  if (!tls_key.empty()) config.tls.key_file = tls_key;
  if (!tls_client_ca.empty()) config.tls.client_ca_file = tls_client_ca;
  if (allow_plaintext) config.tls.allow_plaintext = true;
  sculpt::server::LimitsConfig& l = config.limits;
  if (max_sessions > 0) l.max_sessions = static_cast<uint32_t>(max_sessions);
  if (max_per_source > 0) l.max_connections_per_source = static_cast<uint32_t>(max_per_source);
  if (max_clients > 0) l.max_clients_per_scene = static_cast<uint32_t>(max_clients);
  if (reserved_seats >= 0) l.reserved_sculptor_seats = static_cast<uint32_t>(reserved_seats);
  if (auth_timeout >= 0) l.auth_timeout_ms = auth_timeout;
  if (join_timeout >= 0) l.join_timeout_ms = join_timeout;
  if (idle_timeout >= 0) l.idle_timeout_ms = idle_timeout;
  if (frame_timeout >= 0) l.frame_timeout_ms = frame_timeout;
  if (send_queue > 0) l.send_queue_bytes = static_cast<size_t>(send_queue);
  if (stroke_work > 0) l.max_stroke_work = static_cast<uint64_t>(stroke_work);
  if (strokes_rate > 0) l.strokes_per_second = strokes_rate;
  if (requests_rate > 0) l.requests_per_second = requests_rate;
  if (source_factor > 0) l.source_rate_factor = source_factor;
  if (const sculpt::Status s = sculpt::server::ValidateConfig(config); !s.ok()) {
    spdlog::error("configuration: {}", s.ToString());
    return 2;
  }
  if (config.tls.enabled()) {
    // The files are read now, so a bad one stops start-up before the scene is opened.
    auto tls = sculpt::server::MakeServerTlsContext(config.tls, true);
    if (!tls.ok()) {
      spdlog::error("configuration: {}", tls.status().ToString());
      return 2;
    }
  }
  const std::vector<std::string> hosted = sculpt::server::HostedScenes(config);
  if (check_only) {
    std::string scenes = config.scene.name;
    for (const std::string& name : config.scene.also) {
      scenes += ", " + name + " (" + sculpt::server::SceneDataDir(config, name) + ")";
    }
    std::printf("configuration is valid: listen %s, data %s, %s %s%s%s\n",
                config.listen.c_str(), config.data_dir.c_str(),
                hosted.size() == 1 ? "scene" : "scenes", scenes.c_str(),
                config.tls.enabled() ? ", TLS" : "",
                config.cluster.enabled()
                    ? (", cluster member " + config.cluster.member +
                       (config.cluster.peer_token.empty() ? ", no peer token"
                                                          : ", peer token set"))
                          .c_str()
                    : "");
    return 0;
  }

  // After a promotion's restart the lease it keeps lives only its TTL: kept alive while the
  // scenes open (which may take longer), until the agent starts.
  std::unique_ptr<sculpt::server::cluster::ResumedLeaseKeeper> lease_keeper;
  if (config.cluster.enabled()) {
    lease_keeper = sculpt::server::cluster::ResumedLeaseKeeper::StartIfResuming(config.cluster);
  }
  // Every hosted scene in its own data directory; the first, scene.name, is the default one.
  std::vector<std::unique_ptr<sculpt::server::Scene>> scenes;
  std::vector<sculpt::server::Scene*> scene_ptrs;
  for (const std::string& name : hosted) {
    const ServerConfig scene_config = sculpt::server::ConfigForScene(config, name);
    auto opened = sculpt::server::Scene::Open(scene_config);
    if (!opened.ok()) {
      spdlog::error("cannot open the scene in {}: {}", scene_config.data_dir,
                    opened.status().ToString());
      return 1;
    }
    spdlog::info("scene '{}': {}", name, (*opened)->recovery_summary());
    scenes.push_back(std::move(opened).value());
    scene_ptrs.push_back(scenes.back().get());
  }
  sculpt::server::Scene* const scene = scenes.front().get();

  sculpt::server::asio::io_context io;
  sculpt::server::Server server(io, config, scene_ptrs);
  // Cluster mode (issue 17, docs/cluster.md): the scene is fenced and joins are routed from the
  // first connection on; the agent reaches etcd once the ports are known.
  std::unique_ptr<sculpt::server::cluster::ClusterAgent> cluster;
  if (config.cluster.enabled()) {
    if (config.cluster.peer_token.empty()) {
      spdlog::warn("cluster: no cluster.peer_token: standby sessions are recognised by their "
                   "Hello name alone, so any holder of the viewer token can pass for a standby "
                   "(and a cluster of named users only cannot follow); set the same peer_token "
                   "on every member");
    }
    // Every scene this process hosts, each in its own data directory and fenced on its own.
    std::vector<sculpt::server::cluster::HostedScene> offered;
    for (sculpt::server::Scene* sc : scene_ptrs) {
      const ServerConfig scene_config = sculpt::server::ConfigForScene(config, sc->name());
      offered.push_back({.name = sc->name(),
                         .data_dir = sculpt::server::SceneDataDir(config, sc->name()),
                         .seq = [sc] { return sc->global_seq(); },
                         .acks_async = [sc] { return sc->acks().fallen_back(); },
                         .books = {.skins = scene_config.scene.skins,
                                   .objects = scene_config.scene.objects,
                                   .undo_depth = scene_config.limits.undo_depth}});
    }
    cluster = std::make_unique<sculpt::server::cluster::ClusterAgent>(
        config.cluster, std::move(offered),
        [&server] { return static_cast<uint32_t>(server.JoinedSeats().joined); });
    for (sculpt::server::Scene* sc : scene_ptrs) sc->set_ownership_fence(cluster->fence(sc->name()));
    server.set_router(cluster.get());
    // A standby follows another owner's scene and, on failover, restarts on its copy.
    sculpt::server::cluster::StandbyOptions standby{
        .data_dir = config.data_dir,
        .token = config.viewer_token,
        .restart_argv = std::vector<std::string>(argv, argv + argc),
        .snapshot_every_edits = config.snapshot_every_edits,
        .tls = {}};
    // Over TLS when the cluster's ports speak it (one rule for every member: peer_ca_file).
    standby.tls.enabled = config.cluster.PeerTls(config.tls);
    standby.tls.ca_file = config.cluster.peer_ca_file;
    standby.tls.cert_file = config.tls.cert_file;
    standby.tls.key_file = config.tls.key_file;
    cluster->EnableStandby(std::move(standby));
  }
  auto port = server.Start();
  if (!port.ok()) {
    spdlog::error("{}", port.status().ToString());
    return 1;
  }
  spdlog::info("listening on {} (port {}{}), data {}, fsync {}", config.listen, *port,
               config.tls.enabled() ? config.tls.client_ca_file.empty()
                                          ? ", TLS"
                                          : ", TLS with client certificates"
                                    : "",
               config.data_dir, config.fsync);

  std::unique_ptr<sculpt::server::HttpServer> http;
  uint16_t http_port = 0;
  if (http_listen != "off") {
    sculpt::server::HttpConfig hc;
    if (!http_listen.empty()) {
      hc.listen = http_listen;
    } else if (config.listen.size() >= 2 &&
               config.listen.compare(config.listen.size() - 2, 2, ":0") == 0) {
      // An ephemeral TCP port (tests, scripts running side by side) gets an ephemeral HTTP port.
      hc.listen = "127.0.0.1:0";
    }
    hc.web_root = web_root.empty() ? DefaultWebRoot() : std::filesystem::path(web_root);
    if (http_max_connections > 0) hc.max_connections = http_max_connections;
    if (http_idle_ms > 0) hc.idle_timeout_ms = http_idle_ms;
    hc.allowed_origins = allowed_origins;
    http = std::make_unique<sculpt::server::HttpServer>(io, hc, server);
    auto hp = http->Start();
    if (!hp.ok()) {
      spdlog::error("{}", hp.status().ToString());
      return 1;
    }
    http_port = *hp;
    if (cluster) {
      // http goes before cluster (declared after it), so the source never outlives the agent.
      http->AddMetricsSource(
          [agent = cluster.get()](sculpt::server::MetricsWriter& w) { agent->WriteMetrics(w); });
    }
    spdlog::info("http on {} (port {}): open {}://{}:{}/ ; web root {}", hc.listen, http_port,
                 config.tls.enabled() ? "https" : "http",
                 hc.listen.substr(0, hc.listen.rfind(':')), http_port, hc.web_root.string());
  }
  if (cluster) {
    // What other members send clients to: the configured addresses, else the bound ports on
    // the listen hosts (ValidateConfig refused a wildcard host without cluster.advertise).
    auto on_bound = [](const std::string& listen, uint16_t bound) {
      return listen.substr(0, listen.rfind(':')) + ":" + std::to_string(bound);
    };
    const std::string tcp = !config.cluster.advertise.empty() ? config.cluster.advertise
                                                              : on_bound(config.listen, *port);
    std::string http_address;
    if (http) {
      http_address = !config.cluster.advertise_http.empty()
                         ? config.cluster.advertise_http
                         : on_bound(http_listen.empty() || http_listen == "off"
                                        ? std::string("127.0.0.1:0")
                                        : http_listen,
                                    http_port);
      const std::string host = http_address.substr(0, http_address.rfind(':'));
      if (host == "0.0.0.0" || host == "::" || host == "[::]") {
        spdlog::warn("cluster: the HTTP port listens on a wildcard address and "
                     "cluster.advertise_http is not set: redirects name no WebSocket address");
        http_address.clear();
      }
    }
    lease_keeper.reset();  // its last keep-alive answered: Start has the whole TTL
    if (const sculpt::Status s = cluster->Start(tcp, http_address); !s.ok()) {
      spdlog::error("{}", s.ToString());
      return 1;
    }
  }
  if (!port_file.empty() && !WritePortFile(port_file, *port, http_port)) {
    spdlog::error("cannot write the port file {}", port_file);
    return 1;
  }
  // SIGHUP re-reads the users file; a bad file leaves the users in force and says why.
  sculpt::server::asio::signal_set hangups(io, SIGHUP);
  std::function<void(const boost::system::error_code&, int)> on_hangup =
      [&](const boost::system::error_code& ec, int) {
        if (ec) return;
        if (config.users_file.empty()) {
          spdlog::info("SIGHUP: no users file to re-read");
        } else {
          (void)server.ReloadUsers();
        }
        hangups.async_wait(on_hangup);
      };
  hangups.async_wait(on_hangup);
  sculpt::server::asio::signal_set signals(io, SIGINT, SIGTERM);
  signals.async_wait([&](const boost::system::error_code&, int sig) {
    spdlog::info("signal {}: shutting down", sig);
    // Leaves the cluster first: the lease is revoked, so the scene is fenced and others see
    // this member gone at once.
    if (cluster) cluster->Stop();
    server.Stop();
    if (http) http->Stop();
    for (const auto& s : scenes) s->FlushAndSnapshot();
    hangups.cancel();
    io.stop();
  });
  std::vector<std::thread> threads;
  for (int i = 1; i < config.io_threads; ++i) threads.emplace_back([&io] { io.run(); });
  io.run();
  for (auto& t : threads) t.join();
  if (scenes.size() == 1) {
    spdlog::info("stopped at seq {}", scene->global_seq());
  } else {
    for (const auto& s : scenes) {
      spdlog::info("scene '{}' stopped at seq {}", s->name(), s->global_seq());
    }
  }
  return 0;
}
