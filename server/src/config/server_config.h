/// @brief sculptd's configuration: the scene (objects, voxel size, effects) and the server
/// (listen address, data directory, tokens, limits), read from TOML and overridden by flags.
#ifndef SCULPT_SERVER_CONFIG_SERVER_CONFIG_H_
#define SCULPT_SERVER_CONFIG_SERVER_CONFIG_H_

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "sculpt/codec/skin_messages.h"
#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/materials.h"

namespace sculpt::server {

/// One object of the scene, built from a primitive at first start, or (primitive "model") by
/// voxelising a composite heterogeneous hyperpatch model file (issue 7).
struct ObjectConfig {
  std::string name = "clay";
  std::string primitive = "sphere";  // sphere | box | capsule | torus | model
  std::string model;                  // model: a hetero model JSON file (relative paths are
                                      // taken from the config file's folder when loaded)
  Vec3 center{0, 0, 0};
  double radius = 24.0;               // sphere, capsule; torus major radius
  double minor_radius = 6.0;          // torus
  Vec3 size{32, 32, 32};              // box edge lengths
  Vec3 end{0, 0, 16};                 // capsule second end (center is the first)
};

/// A ball skin of the scene (issue 6): a sketch plane (origin, unit orthogonal in-plane axes u
/// and v) and an ordered chain of oriented balls in its coordinates.
struct SkinConfig {
  std::string name = "skin";
  Vec3 origin{0, 0, 0};
  Vec3 u{1, 0, 0};
  Vec3 v{0, 1, 0};
  std::string method = "hybrid";  // naive | offset | hybrid
  double chord_tolerance = 0;     // world units; 0: 1e-3 of the smallest radius
  std::vector<std::array<double, 4>> balls;  // x, y, r, theta (radians)
};

/// Limits of a skin's balls (config and wire), world units and radians: the wire decoder's.
using codec::kMaxSkinBalls;
using codec::kMaxSkinCoordinate;
using codec::kMinSkinRadius;
using codec::kMaxSkinTheta;

/// The effects the scene calls for; nothing else is computed (ARCHITECTURE principle 2).
struct EffectsConfig {
  std::string volume_preservation = "shell";  // none | shell | global
  bool smoothing = true;                      // smooth strokes allowed
  std::string islands = "remove_small";       // keep | remove_small
  double min_island_volume = 8.0;             // world units^3
  std::vector<std::string> materials;         // use SceneConfig::materials: must be empty
  bool contours = false;                      // serve skin contours and object slices
  /// where_needed: the sliver and band repair run after inflate, deflate and box edits only;
  /// every_edit: after every edit (EditSettings::repair_band_every_edit: fewer band defects,
  /// about 5x a press's kernel cost; docs/benchmarks.md "Invariants under random edits").
  std::string band_repair = "where_needed";
};

struct SceneConfig {
  std::string name = "default";
  /// Further scenes this process hosts beside `name` (`[scene] also = ["b", "c"]`, `sculptd serve
  /// --also-scene NAME`), each with every other setting of this table; at most kMaxAlsoScenes,
  /// names of 1..64 bytes of [A-Za-z0-9._-] (they name directories: SceneDataDir), none repeated
  /// nor equal to `name`. Not with [cluster] yet.
  std::vector<std::string> also;
  double voxel_size = 0.5;
  int half_width = 6;
  std::vector<ObjectConfig> objects{ObjectConfig{}};
  std::vector<SkinConfig> skins;  // [[scene.skins]]
  /// Declared materials (issue 7), `materials = [{name = "...", colour = [r, g, b]}, ...]`:
  /// every object then carries fraction grids (1..16 materials, unique names, colours in
  /// [0, 1]). Empty: no material grids.
  std::vector<levelset::MaterialDecl> materials;
  EffectsConfig effects;
  double min_tool_size = 0.5;   // world units
  double max_tool_size = 16.0;
  double max_speed = 2000.0;    // world units per second
  double max_amount = 8.0;
  double bounds_margin = 16.0;  // poses must lie within the object bounds grown by this
  // Viewers' Draco mesh chunks (issue 4).
  int mesh_position_bits = 14;    // Draco position quantisation
  int mesh_speed = 5;             // Draco encoder speed, 0 (smallest) .. 10 (fastest)
  double mesh_max_rate_hz = 30;   // updates per second at most, whatever a viewer asks
  int mesh_chunk_voxels = 32;     // chunk edge, a multiple of 8
};

struct LimitsConfig {
  uint32_t max_frame_bytes = 1u << 20;
  uint32_t max_poses_per_stroke = 32;
  /// A stroke of more than one pose may ask at most this much kernel work: its poses times the
  /// voxels of the block the kernel reads for it (levelset::FootprintOf), in voxel-poses. The
  /// compute thread never interrupts a job, so this bounds how long one stroke can keep every
  /// other sculptor waiting; a single pose is always allowed (max_tool_size bounds it). Clients
  /// learn it from Welcome and split longer strokes.
  uint64_t max_stroke_work = uint64_t{4} << 20;
  double strokes_per_second = 240;  // token bucket rate per client
  double stroke_burst = 60;         // bucket size
  double poses_per_second = 960;    // each pose is an edit: bounds the work one client queues
  double pose_burst = 480;
  int violations_before_disconnect = 20;
  uint32_t max_clients_per_scene = 64;
  int auth_timeout_ms = 5000;
  /// After auth_free_failures failed authentications from one address, its next attempt waits
  /// auth_backoff_ms, doubling with each failure up to 30 s (a success resets it).
  int auth_backoff_ms = 250;
  int auth_free_failures = 5;
  size_t send_queue_bytes = 8u << 20;  // per session; then coalesce, then disconnect
  // Late joins being prepared at once (waiting for the scene's copy or its serialisation, one
  // worker); past it a join is refused with RESOURCE_EXHAUSTED. Bounds the copies held.
  uint32_t max_pending_joins = 8;
  // Strokes each author can undo per object (issue 15); older ones fall off the history.
  uint32_t undo_depth = 64;

  // Connections (docs/limits.md). Sessions on the TCP port and WebSocket sessions alike, from
  // accept to close, authenticated or not; past a cap a connection gets an Error and a Bye.
  uint32_t max_sessions = 1024;
  uint32_t max_connections_per_source = 64;  // per IP address
  // Seats of max_clients_per_scene that viewers may not take: viewers alone cannot fill a scene.
  uint32_t reserved_sculptor_seats = 4;
  // An authenticated session must join within this; 0: no limit.
  int join_timeout_ms = 10000;
  // A joined session that sends nothing for this long is closed; 0 (default): never, since the
  // protocol has no keep-alive and a passive viewer legitimately sends nothing.
  int idle_timeout_ms = 0;
  // A frame whose first byte has arrived must be complete within this (slowloris).
  int frame_timeout_ms = 10000;
  // Every request that is not an edit costs tokens of this bucket (a join 4, a subscription 2,
  // a SetInterest 1, a divergence report 2, a hover 0.05, a connection 1: docs/limits.md).
  double requests_per_second = 30;
  double request_burst = 100;
  // One source address may use this many clients' worth of every rate above (strokes, poses,
  // requests), whatever the number of its connections; a named user, one client's worth.
  double source_rate_factor = 4;
};

/// TLS on the TCP port and the HTTP port (HTTPS, WSS). Off while cert_file is empty; then only
/// loopback addresses may be listened on unless allow_plaintext is set.
struct TlsConfig {
  std::string cert_file;       // PEM: the server's certificate, then any intermediates
  std::string key_file;        // PEM: its private key (unencrypted)
  std::string client_ca_file;  // PEM: CAs whose client certificates the TCP port requires;
                               // empty: no client certificate is asked for
  bool allow_plaintext = false;  // listen beyond loopback without TLS (logged as a warning)
  bool enabled() const { return !cert_file.empty(); }
};

/// Cluster mode (issue 17, docs/cluster.md): off while `etcd` is empty, and then sculptd is the
/// single process it always was.
struct ClusterConfig {
  std::vector<std::string> etcd;  // etcd client URLs, all http://HOST:PORT or all https://
  /// https:// endpoints only: PEM CAs etcd's certificate must chain to (empty: the system's
  /// store); the certificate must also name the endpoint's host.
  std::string etcd_ca_file;
  /// https:// endpoints only, both or neither: the client certificate and its unencrypted key
  /// presented to an etcd started with --client-cert-auth.
  std::string etcd_cert_file;
  std::string etcd_key_file;
  std::string member;             // this member's name, unique in the cluster
  /// HOST:PORT clients are sent to for this member's TCP port; empty: listen's host with the
  /// bound port (listen must then name a host, not a wildcard).
  std::string advertise;
  /// HOST:PORT of this member's HTTP port (WebSocket clients); empty: the HTTP port's host and
  /// bound port.
  std::string advertise_http;
  /// The lease TTL of this member's keys: a dead owner's scenes are free again after it, and an
  /// owner cut off from etcd stops acknowledging before it.
  int lease_ttl_ms = 2000;
  /// Prefix of every key this cluster keeps in etcd.
  std::string prefix = "sculpt/";
  /// This member may be chosen as another owner's standby: it follows that owner's edit stream
  /// into `<data_dir>/standby/` and takes the scene over when the owner's lease expires.
  bool standby = true;
  /// How this member's scene is replicated while it owns it (a member hosts one scene, so this is
  /// that scene's setting; give every member of the scene the same one):
  /// - "async" (default): a standby follows; an edit is acknowledged once the owner's log has it.
  /// - "sync": an edit is acknowledged only once the owner's log and the standby's copy have it;
  ///   an ack held longer than `sync_fallback_ms` for the standby (none connected, or stuck)
  ///   falls back to async until the standby catches up, said in the log and in /metrics.
  /// - "none": the owner names no standby (a failover has no copy to take over).
  std::string replication = "async";
  /// "sync": how long an acknowledgement waits for the standby before the scene falls back to
  /// async; 0: never (strict, PostgreSQL's synchronous_commit with no standby: acks wait).
  int sync_fallback_ms = 1000;
  /// The members' shared secret (16 to 1024 characters, the same on every member; never logged).
  /// A follower says Hello with it, and an owner takes a session for its standby (progress acks,
  /// the resend table with a region load) only when that session presented it and is named
  /// `standby-<the named standby>`; it is accepted also when named users are configured. Empty:
  /// the standby is recognised by its Hello name alone, on the viewer token (warned at start-up).
  std::string peer_token;
  /// PEM CAs the other members' TCP certificates must chain to. A member follows its owner over
  /// TLS when this is set or its own port speaks TLS (tls.cert_file; the CA is then the
  /// system's store unless this names one): a cluster is TLS on every member or on none. The
  /// owner's certificate must name the host of its advertised address, and the follower
  /// presents this member's tls.cert_file and key_file to owners that ask for a client
  /// certificate (tls.client_ca_file).
  std::string peer_ca_file;
  bool enabled() const { return !etcd.empty(); }
  /// Whether this member connects to other members over TLS (see peer_ca_file).
  bool PeerTls(const TlsConfig& tls) const { return !peer_ca_file.empty() || tls.enabled(); }
};

struct ServerConfig {
  std::string listen = "127.0.0.1:7420";
  std::string data_dir = "./sculpt-data";
  int io_threads = 2;
  std::string fsync = "group";  // always | group
  int group_commit_ms = 5;
  uint64_t snapshot_every_edits = 5000;
  double snapshot_every_seconds = 60;
  std::string sculptor_token = "sculpt-dev-sculptor";
  std::string viewer_token = "sculpt-dev-viewer";
  /// Named users (net/users.h): when set, a Hello names a user of this file and presents that
  /// user's token; the two shared tokens above are then not accepted.
  std::string users_file;
  double presence_hz = 10;
  LimitsConfig limits;
  SceneConfig scene;
  TlsConfig tls;
  ClusterConfig cluster;
};

/// Most scenes `scene.also` may name.
constexpr size_t kMaxAlsoScenes = 64;

/// The scenes this process hosts: scene.name (the default scene), then scene.also in order.
std::vector<std::string> HostedScenes(const ServerConfig& config);

/// The data directory of hosted scene `scene`: config.data_dir itself for scene.name (the layout
/// a single-scene process always had), `<data_dir>/scenes/<scene>` for the others.
std::string SceneDataDir(const ServerConfig& config, const std::string& scene);

/// A copy of `config` for one hosted scene (what Scene::Open takes): data_dir is
/// SceneDataDir(config, scene), scene.name is `scene` and scene.also is empty; the other
/// settings are shared.
ServerConfig ConfigForScene(const ServerConfig& config, const std::string& scene);

/// Reads a TOML file into `config` (keys not present keep their values). InvalidArgument naming
/// the key, value and allowed range for a bad value; NotFound for a missing file.
Status LoadConfigFile(const std::string& path, ServerConfig* config);

/// Checks every value (ranges, enums, unsupported effects). InvalidArgument naming the key.
Status ValidateConfig(const ServerConfig& config);

/// The kernel settings the scene's effects call for.
levelset::EditSettings EditSettingsFor(const SceneConfig& scene);

/// True when HOST of "HOST:PORT" is a loopback address (127.0.0.0/8, ::1, localhost).
bool IsLoopbackListen(const std::string& listen);

/// Splits "HOST:PORT". InvalidArgument for a malformed address.
Status ParseHostPort(const std::string& text, std::string* host, uint16_t* port);

}  // namespace sculpt::server

#endif  // SCULPT_SERVER_CONFIG_SERVER_CONFIG_H_
