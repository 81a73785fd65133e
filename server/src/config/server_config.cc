/// @brief Reading and checking sculptd's TOML configuration.
#include "config/server_config.h"
#include "config/seats.h"

#include "sculpt/core/check.h"
#include "sculpt/levelset/sweep.h"
#include "sculpt/skin/oriented_ball.h"
#include "sculpt/skin/skin.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <sstream>
#include <toml++/toml.h>

#include <boost/asio/ip/address.hpp>

namespace sculpt::server {
namespace {

Status Range(const std::string& key, double v, double lo, double hi) {
  return CheckRange(key, v, lo, hi);
}

Status OneOf(const std::string& key, const std::string& v, std::initializer_list<const char*> ok) {
  std::string list;
  for (const char* o : ok) {
    if (v == o) return Status::Ok();
    list += (list.empty() ? "" : ", ") + std::string(o);
  }
  return Outside(key, v, std::string("{") + list + "}");
}

template <typename T>
void Get(const toml::table& t, const char* key, T* out) {
  if (auto v = t[key].value<T>()) *out = *v;
}

void GetVec(const toml::table& t, const char* key, Vec3* out) {
  if (const toml::array* a = t[key].as_array(); a && a->size() == 3) {
    double c[3];
    for (size_t i = 0; i < 3; ++i) c[i] = (*a)[i].value<double>().value_or(NAN);
    *out = {c[0], c[1], c[2]};
  }
}

// A skin: name, plane, method, tolerance, and the chain (fields in range, admissible pairs).
Status ValidateSkinConfig(const std::string& k, const SkinConfig& c) {
  if (c.name.empty() || c.name.size() > 64) return InvalidArgument(k + ".name must be 1..64 bytes");
  levelset::SweepPlane plane{c.origin, c.u, c.v};
  SCULPT_RETURN_IF_ERROR(levelset::ValidatePlane(k, plane));
  SCULPT_RETURN_IF_ERROR(skin::ParseMethod(c.method).status());
  SCULPT_RETURN_IF_ERROR(Range(k + ".chord_tolerance", c.chord_tolerance, 0, 1e3));
  if (c.balls.size() < 2 || c.balls.size() > kMaxSkinBalls) {
    return Outside(k + ".balls.size", std::to_string(c.balls.size()),
                   std::string("[2, ") + std::to_string(kMaxSkinBalls) + "]");
  }
  std::vector<skin::OrientedBall> balls;
  for (size_t i = 0; i < c.balls.size(); ++i) {
    const std::string b = k + ".balls[" + std::to_string(i) + "]";
    const auto& v = c.balls[i];
    SCULPT_RETURN_IF_ERROR(Range(b + ".x", v[0], -kMaxSkinCoordinate, kMaxSkinCoordinate));
    SCULPT_RETURN_IF_ERROR(Range(b + ".y", v[1], -kMaxSkinCoordinate, kMaxSkinCoordinate));
    SCULPT_RETURN_IF_ERROR(Range(b + ".r", v[2], kMinSkinRadius, kMaxSkinCoordinate));
    SCULPT_RETURN_IF_ERROR(Range(b + ".theta", v[3], -kMaxSkinTheta, kMaxSkinTheta));
    balls.push_back({{v[0], v[1]}, v[2], v[3]});
  }
  const Status chain = skin::ValidateChain(balls);
  if (!chain.ok()) return InvalidArgument(k + ".balls: " + chain.message());
  return Status::Ok();
}

// Refuses keys the file's reader does not know, naming the key and where it is, so a typo
// ("snapshot_every_edit") is not silently ignored.
Status CheckKeys(const std::string& path, const toml::table& t, const std::string& where,
                 std::initializer_list<std::string_view> known) {
  for (const auto& [key, node] : t) {
    if (std::find(known.begin(), known.end(), key.str()) != known.end()) continue;
    std::string list;
    for (std::string_view k : known) list += (list.empty() ? "" : ", ") + std::string(k);
    std::ostringstream os;
    os << "config file " << path;
    if (key.source().begin) os << ":" << key.source().begin.line << ":" << key.source().begin.column;
    os << ": unknown key " << (where.empty() ? "" : where + ".") << key.str() << " (known in "
       << (where.empty() ? "the top level" : where) << ": " << list << ")";
    return InvalidArgument(os.str());
  }
  return Status::Ok();
}

// cluster.peer_token's length in characters: 16 at least (`openssl rand -hex 16` gives 32).
constexpr size_t kMinPeerToken = 16;
constexpr size_t kMaxPeerToken = 1024;

// A host clients can be sent to: not a wildcard address.
bool IsWildcardHost(const std::string& host) {
  return host.empty() || host == "0.0.0.0" || host == "::" || host == "[::]";
}

// scene.also: each a scene name as scene.name is (1..64 bytes), restricted further to
// [A-Za-z0-9._-] and not "." or "..", since it names a directory under data_dir/scenes/.
Status ValidateAlsoScenes(const SceneConfig& s) {
  if (s.also.size() > kMaxAlsoScenes) {
    return Outside("scene.also.size", std::to_string(s.also.size()),
                   "[0, " + std::to_string(kMaxAlsoScenes) + "]");
  }
  for (size_t i = 0; i < s.also.size(); ++i) {
    const std::string& n = s.also[i];
    const std::string k = "scene.also[" + std::to_string(i) + "]";
    const bool chars_ok = std::all_of(n.begin(), n.end(), [](char ch) {
      return std::isalnum(static_cast<unsigned char>(ch)) || ch == '.' || ch == '_' || ch == '-';
    });
    if (n.empty() || n.size() > 64 || !chars_ok || n == "." || n == "..") {
      return Outside(k, n, "1..64 bytes of [A-Za-z0-9._-], not \".\" or \"..\"");
    }
    if (n == s.name) {
      return Outside(k, n, "names other than scene.name=" + s.name + " (hosted already)");
    }
    for (size_t j = 0; j < i; ++j) {
      if (s.also[j] == n) {
        return Outside(k, n, "names not already in scene.also (scene.also[" + std::to_string(j) +
                                 "] is the same)");
      }
    }
  }
  return Status::Ok();
}

Status ValidateClusterConfig(const ServerConfig& c) {
  const ClusterConfig& k = c.cluster;
  SCULPT_RETURN_IF_ERROR(OneOf("cluster.replication", k.replication, {"sync", "async", "none"}));
  SCULPT_RETURN_IF_ERROR(Range("cluster.sync_fallback_ms", k.sync_fallback_ms, 0, 600000));
  if (!k.peer_token.empty()) {
    // The value is a secret: the error names its length, never its characters.
    if (k.peer_token.size() < kMinPeerToken || k.peer_token.size() > kMaxPeerToken) {
      return Outside("cluster.peer_token",
                     "(hidden, " + std::to_string(k.peer_token.size()) + " characters)",
                     "[" + std::to_string(kMinPeerToken) + ", " + std::to_string(kMaxPeerToken) +
                         "] characters (e.g. `openssl rand -hex 16`)");
    }
    if (k.peer_token == c.viewer_token || k.peer_token == c.sculptor_token) {
      return InvalidArgument(
          "cluster.peer_token equals the shared viewer_token or sculptor_token: every holder of "
          "that token could pass for a member's standby; choose a secret of its own");
    }
    if (!k.enabled()) {
      return InvalidArgument(
          "cluster.peer_token is set but cluster.etcd is empty: the peer token is for cluster "
          "members; leave out the [cluster] section for a single process");
    }
  }
  if (!k.peer_ca_file.empty()) {
    if (!k.enabled()) {
      return InvalidArgument("cluster.peer_ca_file=" + k.peer_ca_file +
                             " is set but cluster.etcd is empty: it is for connections between "
                             "cluster members; leave out the [cluster] section for a single process");
    }
    std::error_code ec;
    if (!std::filesystem::is_regular_file(k.peer_ca_file, ec)) {
      return InvalidArgument("cluster.peer_ca_file=" + k.peer_ca_file +
                             " is not a readable file (PEM CA certificates the other members' "
                             "certificates chain to)");
    }
  }
  if (!k.enabled()) {
    if (!k.member.empty() || !k.advertise.empty() || !k.advertise_http.empty()) {
      return InvalidArgument(
          "cluster.etcd is empty but cluster.member=" + k.member +
          " is set: cluster mode needs etcd endpoints (etcd = [\"http://HOST:PORT\"]); leave "
          "out the [cluster] section for a single process");
    }
    for (auto [key, value] : {std::pair{"cluster.etcd_ca_file", &k.etcd_ca_file},
                              std::pair{"cluster.etcd_cert_file", &k.etcd_cert_file},
                              std::pair{"cluster.etcd_key_file", &k.etcd_key_file}}) {
      if (!value->empty()) {
        return InvalidArgument(std::string(key) + "=" + *value +
                               " is set but cluster.etcd is empty: it is for TLS to etcd in "
                               "cluster mode; leave out the [cluster] section for a single "
                               "process");
      }
    }
    return Status::Ok();
  }
  if (k.etcd.size() > 16) {
    return Outside("cluster.etcd.size", std::to_string(k.etcd.size()), "[1, 16]");
  }
  const bool etcd_https = k.etcd.front().rfind("https://", 0) == 0;
  for (size_t i = 0; i < k.etcd.size(); ++i) {
    const std::string key = "cluster.etcd[" + std::to_string(i) + "]";
    std::string rest = k.etcd[i];
    const bool https = rest.rfind("https://", 0) == 0;
    if (https != etcd_https) {
      return Outside(key, k.etcd[i],
                     std::string(etcd_https ? "https" : "http") +
                         "://HOST:PORT as cluster.etcd[0]: every endpoint is TLS or none is");
    }
    if (https) rest = rest.substr(8);
    if (rest.rfind("http://", 0) == 0) rest = rest.substr(7);
    while (!rest.empty() && rest.back() == '/') rest.pop_back();
    std::string host;
    uint16_t port = 0;
    if (rest.find('/') != std::string::npos || !ParseHostPort(rest, &host, &port).ok() ||
        port == 0 || host.empty()) {
      return Outside(key, k.etcd[i], "http(s)://HOST:PORT with PORT in [1, 65535]");
    }
    if (!https && !IsLoopbackListen(rest) && !c.tls.allow_plaintext) {
      return InvalidArgument(key + "=" + k.etcd[i] +
                             " is beyond loopback and etcd is reached in plaintext: use "
                             "https:// (cluster.etcd_ca_file) or set tls.allow_plaintext = true "
                             "to accept that");
    }
  }
  for (auto [key, value] : {std::pair{"cluster.etcd_ca_file", &k.etcd_ca_file},
                            std::pair{"cluster.etcd_cert_file", &k.etcd_cert_file},
                            std::pair{"cluster.etcd_key_file", &k.etcd_key_file}}) {
    if (value->empty()) continue;
    if (!etcd_https) {
      return InvalidArgument(std::string(key) + "=" + *value +
                             " is set but cluster.etcd[0]=" + k.etcd.front() +
                             " is http://: the etcd TLS files are for https:// endpoints");
    }
    std::error_code ec;
    if (!std::filesystem::is_regular_file(*value, ec)) {
      return InvalidArgument(std::string(key) + "=" + *value +
                             " is not a readable file (a PEM file: CA certificates for "
                             "etcd_ca_file, the client certificate and its key for "
                             "etcd_cert_file and etcd_key_file)");
    }
  }
  if (k.etcd_cert_file.empty() != k.etcd_key_file.empty()) {
    const char* missing =
        k.etcd_cert_file.empty() ? "cluster.etcd_cert_file" : "cluster.etcd_key_file";
    return InvalidArgument(std::string(missing) +
                           " is empty: a client certificate for etcd needs both "
                           "cluster.etcd_cert_file and cluster.etcd_key_file");
  }
  constexpr const char* kNameChars =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789._-";
  if (k.member.empty() || k.member.size() > 64 ||
      k.member.find_first_not_of(kNameChars) != std::string::npos) {
    return Outside("cluster.member", k.member, "1 to 64 characters of [A-Za-z0-9._-]");
  }
  for (auto [key, value] : {std::pair{"cluster.advertise", &k.advertise},
                            std::pair{"cluster.advertise_http", &k.advertise_http}}) {
    if (value->empty()) continue;
    std::string host;
    uint16_t port = 0;
    if (!ParseHostPort(*value, &host, &port).ok() || port == 0 || IsWildcardHost(host)) {
      return Outside(key, *value,
                     "HOST:PORT clients can reach (no wildcard host, PORT in [1, 65535])");
    }
  }
  if (k.advertise.empty()) {
    std::string host;
    uint16_t port = 0;
    SCULPT_RETURN_IF_ERROR(ParseHostPort(c.listen, &host, &port));
    if (IsWildcardHost(host)) {
      return InvalidArgument("cluster.advertise is empty and listen=" + c.listen +
                             " is a wildcard address: name the HOST:PORT other members send "
                             "clients to (cluster.advertise)");
    }
  }
  SCULPT_RETURN_IF_ERROR(Range("cluster.lease_ttl_ms", k.lease_ttl_ms, 1000, 60000));
  if (k.prefix.empty() || k.prefix.size() > 128) {
    return Outside("cluster.prefix", k.prefix, "1 to 128 bytes");
  }
  return Status::Ok();
}

}  // namespace

Status LoadConfigFile(const std::string& path, ServerConfig* c) {
  if (!std::filesystem::exists(path)) return NotFound("config file " + path + " does not exist");
  toml::table root;
  try {
    root = toml::parse_file(path);
  } catch (const toml::parse_error& e) {
    std::ostringstream os;
    os << "config file " << path << ":" << e.source().begin.line << ":"
       << e.source().begin.column << ": " << e.description();
    return InvalidArgument(os.str());
  }
  SCULPT_RETURN_IF_ERROR(
      CheckKeys(path, root, "", {"server", "limits", "scene", "tls", "cluster"}));
  if (const toml::table* t = root["cluster"].as_table()) {
    SCULPT_RETURN_IF_ERROR(
        CheckKeys(path, *t, "cluster",
                  {"etcd", "member", "advertise", "advertise_http", "lease_ttl_ms", "prefix",
                   "standby", "replication", "sync_fallback_ms", "peer_token",
                   "peer_ca_file", "etcd_ca_file", "etcd_cert_file", "etcd_key_file"}));
    if (const toml::node* e = t->get("etcd")) {
      const toml::array* a = e->as_array();
      if (!a) return Outside("cluster.etcd", "not an array", "arrays of \"http://HOST:PORT\"");
      c->cluster.etcd.clear();
      for (const auto& x : *a) {
        if (!x.is_string()) return Outside("cluster.etcd", "not a string", "\"http://HOST:PORT\"");
        c->cluster.etcd.push_back(x.value_or(std::string()));
      }
    }
    Get(*t, "member", &c->cluster.member);
    Get(*t, "advertise", &c->cluster.advertise);
    Get(*t, "advertise_http", &c->cluster.advertise_http);
    Get(*t, "lease_ttl_ms", &c->cluster.lease_ttl_ms);
    Get(*t, "prefix", &c->cluster.prefix);
    Get(*t, "standby", &c->cluster.standby);
    Get(*t, "replication", &c->cluster.replication);
    Get(*t, "sync_fallback_ms", &c->cluster.sync_fallback_ms);
    Get(*t, "peer_token", &c->cluster.peer_token);
    Get(*t, "peer_ca_file", &c->cluster.peer_ca_file);
    Get(*t, "etcd_ca_file", &c->cluster.etcd_ca_file);
    Get(*t, "etcd_cert_file", &c->cluster.etcd_cert_file);
    Get(*t, "etcd_key_file", &c->cluster.etcd_key_file);
    // Relative to the config file's folder, as the [tls] files are.
    for (std::string* file : {&c->cluster.peer_ca_file, &c->cluster.etcd_ca_file,
                              &c->cluster.etcd_cert_file, &c->cluster.etcd_key_file}) {
      if (!file->empty() && std::filesystem::path(*file).is_relative()) {
        *file = (std::filesystem::path(path).parent_path() / *file).lexically_normal().string();
      }
    }
  }
  if (const toml::table* t = root["tls"].as_table()) {
    SCULPT_RETURN_IF_ERROR(CheckKeys(path, *t, "tls",
                                     {"cert_file", "key_file", "client_ca_file", "allow_plaintext"}));
    // Relative paths are taken from the config file's folder, as objects' model files are.
    auto get_path = [&](const char* key, std::string* out) {
      Get(*t, key, out);
      if (!out->empty() && std::filesystem::path(*out).is_relative()) {
        *out = (std::filesystem::path(path).parent_path() / *out).lexically_normal().string();
      }
    };
    get_path("cert_file", &c->tls.cert_file);
    get_path("key_file", &c->tls.key_file);
    get_path("client_ca_file", &c->tls.client_ca_file);
    Get(*t, "allow_plaintext", &c->tls.allow_plaintext);
  }
  if (const toml::table* s = root["server"].as_table()) {
    SCULPT_RETURN_IF_ERROR(CheckKeys(path, *s, "server",
                                     {"listen", "data_dir", "io_threads", "fsync", "group_commit_ms",
                                      "snapshot_every_edits", "snapshot_every_seconds",
                                      "sculptor_token", "viewer_token", "users_file", "presence_hz"}));
    Get(*s, "listen", &c->listen);
    Get(*s, "data_dir", &c->data_dir);
    Get(*s, "io_threads", &c->io_threads);
    Get(*s, "fsync", &c->fsync);
    Get(*s, "group_commit_ms", &c->group_commit_ms);
    int64_t every = static_cast<int64_t>(c->snapshot_every_edits);
    Get(*s, "snapshot_every_edits", &every);
    c->snapshot_every_edits = static_cast<uint64_t>(std::max<int64_t>(0, every));
    Get(*s, "snapshot_every_seconds", &c->snapshot_every_seconds);
    Get(*s, "sculptor_token", &c->sculptor_token);
    Get(*s, "viewer_token", &c->viewer_token);
    Get(*s, "users_file", &c->users_file);
    if (!c->users_file.empty() && std::filesystem::path(c->users_file).is_relative()) {
      // Relative to the configuration file, as scene model paths are.
      c->users_file = (std::filesystem::path(path).parent_path() / c->users_file).string();
    }
    Get(*s, "presence_hz", &c->presence_hz);
  }
  if (const toml::table* l = root["limits"].as_table()) {
    SCULPT_RETURN_IF_ERROR(CheckKeys(
        path, *l, "limits",
        {"max_frame_bytes", "max_poses_per_stroke", "max_stroke_work", "strokes_per_second", "stroke_burst",
         "poses_per_second", "pose_burst", "violations_before_disconnect",
         "max_clients_per_scene", "auth_timeout_ms", "auth_backoff_ms",
         "auth_free_failures", "send_queue_bytes", "max_pending_joins", "max_sessions",
         "max_connections_per_source", "reserved_sculptor_seats", "join_timeout_ms",
         "idle_timeout_ms", "frame_timeout_ms", "requests_per_second", "request_burst",
         "source_rate_factor", "undo_depth"}));
    int64_t v = c->limits.max_frame_bytes;
    Get(*l, "max_frame_bytes", &v);
    c->limits.max_frame_bytes = static_cast<uint32_t>(std::clamp<int64_t>(v, 0, 1ll << 31));
    v = c->limits.max_poses_per_stroke;
    Get(*l, "max_poses_per_stroke", &v);
    c->limits.max_poses_per_stroke = static_cast<uint32_t>(std::clamp<int64_t>(v, 0, 1 << 20));
    v = static_cast<int64_t>(c->limits.max_stroke_work);
    Get(*l, "max_stroke_work", &v);
    c->limits.max_stroke_work = static_cast<uint64_t>(std::max<int64_t>(v, 0));
    Get(*l, "strokes_per_second", &c->limits.strokes_per_second);
    Get(*l, "stroke_burst", &c->limits.stroke_burst);
    Get(*l, "poses_per_second", &c->limits.poses_per_second);
    Get(*l, "pose_burst", &c->limits.pose_burst);
    Get(*l, "violations_before_disconnect", &c->limits.violations_before_disconnect);
    v = c->limits.max_clients_per_scene;
    Get(*l, "max_clients_per_scene", &v);
    c->limits.max_clients_per_scene = static_cast<uint32_t>(std::clamp<int64_t>(v, 0, 1 << 20));
    Get(*l, "auth_timeout_ms", &c->limits.auth_timeout_ms);
    Get(*l, "auth_backoff_ms", &c->limits.auth_backoff_ms);
    Get(*l, "auth_free_failures", &c->limits.auth_free_failures);
    v = static_cast<int64_t>(c->limits.send_queue_bytes);
    Get(*l, "send_queue_bytes", &v);
    c->limits.send_queue_bytes = static_cast<size_t>(std::max<int64_t>(0, v));
    v = c->limits.max_pending_joins;
    Get(*l, "max_pending_joins", &v);
    c->limits.max_pending_joins = static_cast<uint32_t>(std::clamp<int64_t>(v, 0, 1 << 20));
    v = c->limits.undo_depth;
    Get(*l, "undo_depth", &v);
    c->limits.undo_depth = static_cast<uint32_t>(std::clamp<int64_t>(v, 0, 1 << 20));
    for (auto [key, out] : {std::pair{"max_sessions", &c->limits.max_sessions},
                            std::pair{"max_connections_per_source",
                                      &c->limits.max_connections_per_source},
                            std::pair{"reserved_sculptor_seats",
                                      &c->limits.reserved_sculptor_seats}}) {
      v = *out;
      Get(*l, key, &v);
      *out = static_cast<uint32_t>(std::clamp<int64_t>(v, 0, 1 << 24));
    }
    Get(*l, "join_timeout_ms", &c->limits.join_timeout_ms);
    Get(*l, "idle_timeout_ms", &c->limits.idle_timeout_ms);
    Get(*l, "frame_timeout_ms", &c->limits.frame_timeout_ms);
    Get(*l, "requests_per_second", &c->limits.requests_per_second);
    Get(*l, "request_burst", &c->limits.request_burst);
    Get(*l, "source_rate_factor", &c->limits.source_rate_factor);
  }
  if (const toml::table* s = root["scene"].as_table()) {
    SceneConfig& sc = c->scene;
    SCULPT_RETURN_IF_ERROR(CheckKeys(
        path, *s, "scene",
        {"name", "voxel_size", "half_width", "min_tool_size", "max_tool_size", "max_speed",
         "max_amount", "bounds_margin", "mesh_position_bits", "mesh_speed", "mesh_max_rate_hz",
         "mesh_chunk_voxels", "effects", "objects", "materials", "skins", "also"}));
    Get(*s, "name", &sc.name);
    if (s->contains("also")) {
      const toml::array* a = (*s)["also"].as_array();
      if (!a) return Outside("scene.also", "not an array", "arrays of scene names [\"b\", \"c\"]");
      sc.also.clear();
      for (const auto& x : *a) {
        if (!x.is_string()) return Outside("scene.also", "not a string", "scene names \"b\"");
        sc.also.push_back(x.value_or(std::string()));
      }
    }
    Get(*s, "voxel_size", &sc.voxel_size);
    Get(*s, "half_width", &sc.half_width);
    Get(*s, "min_tool_size", &sc.min_tool_size);
    Get(*s, "max_tool_size", &sc.max_tool_size);
    Get(*s, "max_speed", &sc.max_speed);
    Get(*s, "max_amount", &sc.max_amount);
    Get(*s, "bounds_margin", &sc.bounds_margin);
    Get(*s, "mesh_position_bits", &sc.mesh_position_bits);
    Get(*s, "mesh_speed", &sc.mesh_speed);
    Get(*s, "mesh_max_rate_hz", &sc.mesh_max_rate_hz);
    Get(*s, "mesh_chunk_voxels", &sc.mesh_chunk_voxels);
    if (const toml::table* e = (*s)["effects"].as_table()) {
      SCULPT_RETURN_IF_ERROR(CheckKeys(path, *e, "scene.effects",
                                       {"volume_preservation", "smoothing", "islands",
                                        "min_island_volume", "contours", "materials",
                                        "band_repair"}));
      Get(*e, "volume_preservation", &sc.effects.volume_preservation);
      Get(*e, "smoothing", &sc.effects.smoothing);
      Get(*e, "islands", &sc.effects.islands);
      Get(*e, "min_island_volume", &sc.effects.min_island_volume);
      Get(*e, "contours", &sc.effects.contours);
      Get(*e, "band_repair", &sc.effects.band_repair);
      if (const toml::array* m = (*e)["materials"].as_array()) {
        sc.effects.materials.clear();
        for (const auto& x : *m) sc.effects.materials.push_back(x.value_or(std::string()));
      }
    }
    if (const toml::array* objects = (*s)["objects"].as_array()) {
      sc.objects.clear();
      for (const auto& node : *objects) {
        const toml::table* o = node.as_table();
        if (!o) return InvalidArgument("scene.objects entries must be tables");
        SCULPT_RETURN_IF_ERROR(CheckKeys(
            path, *o, "scene.objects[" + std::to_string(sc.objects.size()) + "]",
            {"name", "primitive", "center", "radius", "minor_radius", "size", "end", "model"}));
        ObjectConfig oc;
        Get(*o, "name", &oc.name);
        Get(*o, "primitive", &oc.primitive);
        GetVec(*o, "center", &oc.center);
        Get(*o, "radius", &oc.radius);
        Get(*o, "minor_radius", &oc.minor_radius);
        GetVec(*o, "size", &oc.size);
        GetVec(*o, "end", &oc.end);
        Get(*o, "model", &oc.model);
        if (!oc.model.empty() && std::filesystem::path(oc.model).is_relative()) {
          oc.model = (std::filesystem::path(path).parent_path() / oc.model).lexically_normal().string();
        }
        sc.objects.push_back(oc);
      }
    }
    if (const toml::array* materials = (*s)["materials"].as_array()) {
      sc.materials.clear();
      for (size_t i = 0; i < materials->size(); ++i) {
        const toml::table* t = (*materials)[i].as_table();
        const std::string k = "scene.materials[" + std::to_string(i) + "]";
        if (!t) return InvalidArgument(k + " outside tables {name = \"...\", colour = [r, g, b]}");
        SCULPT_RETURN_IF_ERROR(CheckKeys(path, *t, k, {"name", "colour"}));
        levelset::MaterialDecl m;
        Get(*t, "name", &m.name);
        if (const toml::node* c = t->get("colour")) {
          const toml::array* a = c->as_array();
          if (!a || a->size() != 3) return InvalidArgument(k + ".colour outside arrays of 3 numbers");
          for (size_t j = 0; j < 3; ++j) m.colour[j] = (*a)[j].value<double>().value_or(NAN);
        }
        sc.materials.push_back(m);
      }
    }
    if (const toml::array* skins = (*s)["skins"].as_array()) {
      sc.skins.clear();
      for (const auto& node : *skins) {
        const toml::table* t = node.as_table();
        if (!t) return InvalidArgument("scene.skins entries must be tables");
        SCULPT_RETURN_IF_ERROR(
            CheckKeys(path, *t, "scene.skins[" + std::to_string(sc.skins.size()) + "]",
                      {"name", "origin", "u", "v", "method", "chord_tolerance", "balls"}));
        SkinConfig k;
        Get(*t, "name", &k.name);
        GetVec(*t, "origin", &k.origin);
        GetVec(*t, "u", &k.u);
        GetVec(*t, "v", &k.v);
        Get(*t, "method", &k.method);
        Get(*t, "chord_tolerance", &k.chord_tolerance);
        if (const toml::array* balls = (*t)["balls"].as_array()) {
          for (size_t i = 0; i < balls->size(); ++i) {
            const toml::array* b = (*balls)[i].as_array();
            if (!b || b->size() != 4) {
              return InvalidArgument("scene.skins[" + std::to_string(sc.skins.size()) +
                                     "].balls[" + std::to_string(i) +
                                     "] outside arrays of 4 numbers [x, y, r, theta]");
            }
            std::array<double, 4> v;
            for (size_t j = 0; j < 4; ++j) v[j] = (*b)[j].value<double>().value_or(NAN);
            k.balls.push_back(v);
          }
        }
        sc.skins.push_back(k);
      }
    }
  }
  return Status::Ok();
}

Status ParseHostPort(const std::string& text, std::string* host, uint16_t* port) {
  const size_t colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == text.size()) {
    return InvalidArgument("listen=" + text + " is not HOST:PORT");
  }
  std::string h = text.substr(0, colon);
  if (h.size() > 2 && h.front() == '[' && h.back() == ']') h = h.substr(1, h.size() - 2);
  int p = 0;
  for (size_t i = colon + 1; i < text.size(); ++i) {
    if (text[i] < '0' || text[i] > '9' || p > 65535) {
      return Outside("listen port", text.substr(colon + 1), "[0, 65535]");
    }
    p = p * 10 + (text[i] - '0');
  }
  if (p > 65535) return Outside("listen port", std::to_string(p), "[0, 65535]");
  *host = h;
  *port = static_cast<uint16_t>(p);
  return Status::Ok();
}

bool IsLoopbackListen(const std::string& listen) {
  std::string host;
  uint16_t port = 0;
  if (!ParseHostPort(listen, &host, &port).ok()) return false;
  if (host == "localhost") return true;
  boost::system::error_code ec;
  const auto address = boost::asio::ip::make_address(host, ec);
  return !ec && address.is_loopback();
}

Status ValidateConfig(const ServerConfig& c) {
  std::string host;
  uint16_t port = 0;
  SCULPT_RETURN_IF_ERROR(ParseHostPort(c.listen, &host, &port));
  const TlsConfig& tls = c.tls;
  if (tls.enabled() != !tls.key_file.empty()) {
    return InvalidArgument(tls.enabled() ? "tls.key_file is empty but tls.cert_file=" +
                                               tls.cert_file + " is set: TLS needs both"
                                         : "tls.cert_file is empty but tls.key_file=" +
                                               tls.key_file + " is set: TLS needs both");
  }
  if (!tls.enabled() && !tls.client_ca_file.empty()) {
    return InvalidArgument("tls.client_ca_file=" + tls.client_ca_file +
                           " is set without tls.cert_file and tls.key_file");
  }
  if (!tls.enabled() && !tls.allow_plaintext && !IsLoopbackListen(c.listen)) {
    return InvalidArgument("listen=" + c.listen +
                           " is beyond loopback without TLS: set tls.cert_file and tls.key_file "
                           "(--tls-cert, --tls-key), or tls.allow_plaintext = true "
                           "(--allow-plaintext) to send tokens and strokes in clear");
  }
  if (c.data_dir.empty()) return InvalidArgument("data_dir is empty");
  SCULPT_RETURN_IF_ERROR(Range("io_threads", c.io_threads, 1, 64));
  SCULPT_RETURN_IF_ERROR(OneOf("fsync", c.fsync, {"always", "group"}));
  SCULPT_RETURN_IF_ERROR(Range("group_commit_ms", c.group_commit_ms, 1, 1000));
  SCULPT_RETURN_IF_ERROR(Range("snapshot_every_seconds", c.snapshot_every_seconds, 0, 86400));
  if (c.sculptor_token.size() < 8) return InvalidArgument("sculptor_token shorter than 8 bytes");
  if (c.viewer_token.size() < 8) return InvalidArgument("viewer_token shorter than 8 bytes");
  if (c.sculptor_token == c.viewer_token) {
    return InvalidArgument("sculptor_token equals viewer_token: roles would be indistinguishable");
  }
  const ServerConfig defaults;
  if (!IsLoopbackListen(c.listen) && c.users_file.empty() &&
      (c.sculptor_token == defaults.sculptor_token || c.viewer_token == defaults.viewer_token)) {
    return InvalidArgument(
        "listen=" + c.listen + " is not a loopback address and the development tokens are in "
        "force: name a users file (server.users_file; `sculptd user add NAME --role sculptor "
        "--users FILE` makes one) or set your own sculptor_token and viewer_token in the "
        "configuration file or in SCULPT_SCULPTOR_TOKEN / SCULPT_VIEWER_TOKEN");
  }
  SCULPT_RETURN_IF_ERROR(Range("presence_hz", c.presence_hz, 0.1, 120));
  const LimitsConfig& l = c.limits;
  SCULPT_RETURN_IF_ERROR(Range("limits.max_frame_bytes", l.max_frame_bytes, 1024, 64 << 20));
  SCULPT_RETURN_IF_ERROR(Range("limits.max_poses_per_stroke", l.max_poses_per_stroke, 1, 1024));
  SCULPT_RETURN_IF_ERROR(
      Range("limits.max_stroke_work", l.max_stroke_work, uint64_t{1} << 16, uint64_t{1} << 40));
  SCULPT_RETURN_IF_ERROR(Range("limits.strokes_per_second", l.strokes_per_second, 1, 1e5));
  SCULPT_RETURN_IF_ERROR(Range("limits.stroke_burst", l.stroke_burst, 1, 1e6));
  SCULPT_RETURN_IF_ERROR(Range("limits.poses_per_second", l.poses_per_second, 1, 1e6));
  SCULPT_RETURN_IF_ERROR(Range("limits.pose_burst", l.pose_burst, 1, 1e7));
  SCULPT_RETURN_IF_ERROR(
      Range("limits.violations_before_disconnect", l.violations_before_disconnect, 1, 1e6));
  SCULPT_RETURN_IF_ERROR(Range("limits.max_clients_per_scene", l.max_clients_per_scene, 1, 1e5));
  SCULPT_RETURN_IF_ERROR(Range("limits.auth_timeout_ms", l.auth_timeout_ms, 10, 600000));
  SCULPT_RETURN_IF_ERROR(Range("limits.auth_backoff_ms", l.auth_backoff_ms, 0, 60000));
  SCULPT_RETURN_IF_ERROR(Range("limits.auth_free_failures", l.auth_free_failures, 0, 1000));
  SCULPT_RETURN_IF_ERROR(
      Range("limits.send_queue_bytes", static_cast<double>(l.send_queue_bytes), 64 << 10, 1e10));
  SCULPT_RETURN_IF_ERROR(Range("limits.max_pending_joins", l.max_pending_joins, 1, 1024));
  SCULPT_RETURN_IF_ERROR(Range("limits.undo_depth", l.undo_depth, 1, 4096));
  SCULPT_RETURN_IF_ERROR(Range("limits.max_sessions", l.max_sessions, 1, 1e6));
  SCULPT_RETURN_IF_ERROR(
      Range("limits.max_connections_per_source", l.max_connections_per_source, 1, l.max_sessions));
  SCULPT_RETURN_IF_ERROR(Range("limits.reserved_sculptor_seats", l.reserved_sculptor_seats, 0,
                               1e5));
  SCULPT_RETURN_IF_ERROR(Range("limits.join_timeout_ms", l.join_timeout_ms, 0, 3.6e6));
  SCULPT_RETURN_IF_ERROR(Range("limits.idle_timeout_ms", l.idle_timeout_ms, 0, 8.64e7));
  SCULPT_RETURN_IF_ERROR(Range("limits.frame_timeout_ms", l.frame_timeout_ms, 10, 3.6e6));
  SCULPT_RETURN_IF_ERROR(Range("limits.requests_per_second", l.requests_per_second, 1, 1e6));
  SCULPT_RETURN_IF_ERROR(Range("limits.request_burst", l.request_burst, 4, 1e7));
  SCULPT_RETURN_IF_ERROR(Range("limits.source_rate_factor", l.source_rate_factor, 1, 1e4));
  const SceneConfig& s = c.scene;
  if (s.name.empty() || s.name.size() > 64) return InvalidArgument("scene.name must be 1..64 bytes");
  SCULPT_RETURN_IF_ERROR(Range("scene.voxel_size", s.voxel_size, levelset::kMinVoxelSize,
                               levelset::kMaxVoxelSize));
  SCULPT_RETURN_IF_ERROR(
      Range("scene.half_width", s.half_width, levelset::kMinHalfWidth, levelset::kMaxHalfWidth));
  SCULPT_RETURN_IF_ERROR(Range("scene.min_tool_size", s.min_tool_size, 0.25 * s.voxel_size,
                               64 * s.voxel_size));
  SCULPT_RETURN_IF_ERROR(Range("scene.max_tool_size", s.max_tool_size, s.min_tool_size,
                               64 * s.voxel_size));
  SCULPT_RETURN_IF_ERROR(Range("scene.max_speed", s.max_speed, 0, 1e4 * s.voxel_size));
  SCULPT_RETURN_IF_ERROR(Range("scene.max_amount", s.max_amount, 0, 32 * s.voxel_size));
  SCULPT_RETURN_IF_ERROR(Range("scene.bounds_margin", s.bounds_margin, 0, 1e6));
  SCULPT_RETURN_IF_ERROR(Range("scene.mesh_position_bits", s.mesh_position_bits, 8, 24));
  SCULPT_RETURN_IF_ERROR(Range("scene.mesh_speed", s.mesh_speed, 0, 10));
  SCULPT_RETURN_IF_ERROR(Range("scene.mesh_max_rate_hz", s.mesh_max_rate_hz, 0.1, 120));
  SCULPT_RETURN_IF_ERROR(Range("scene.mesh_chunk_voxels", s.mesh_chunk_voxels, 8, 256));
  if (s.mesh_chunk_voxels % 8 != 0) {
    return Outside("scene.mesh_chunk_voxels", std::to_string(s.mesh_chunk_voxels),
                   "multiples of 8 in [8, 256]");
  }
  SCULPT_RETURN_IF_ERROR(OneOf("scene.effects.volume_preservation", s.effects.volume_preservation,
                               {"none", "shell", "global"}));
  SCULPT_RETURN_IF_ERROR(
      OneOf("scene.effects.islands", s.effects.islands, {"keep", "remove_small"}));
  SCULPT_RETURN_IF_ERROR(
      Range("scene.effects.min_island_volume", s.effects.min_island_volume, 0, 1e30));
  SCULPT_RETURN_IF_ERROR(OneOf("scene.effects.band_repair", s.effects.band_repair,
                               {"where_needed", "every_edit"}));
  if (!s.effects.materials.empty()) {
    return InvalidArgument(
        "scene.effects.materials is replaced by [scene] materials = [{name = \"...\", colour = "
        "[r, g, b]}, ...]; move the names there");
  }
  if (!s.materials.empty()) {
    const Status m = levelset::ValidateMaterialDecls(s.materials);
    if (!m.ok()) return InvalidArgument("scene.materials: " + m.message());
  }
  if (s.objects.empty()) return InvalidArgument("scene.objects is empty");
  for (size_t i = 0; i < s.objects.size(); ++i) {
    const ObjectConfig& o = s.objects[i];
    const std::string k = "scene.objects[" + std::to_string(i) + "]";
    if (o.name.empty() || o.name.size() > 64) return InvalidArgument(k + ".name must be 1..64 bytes");
    for (size_t j = 0; j < i; ++j) {
      if (s.objects[j].name == o.name) return InvalidArgument(k + ".name=" + o.name + " repeats");
    }
    SCULPT_RETURN_IF_ERROR(
        OneOf(k + ".primitive", o.primitive, {"sphere", "box", "capsule", "torus", "model"}));
    if (o.primitive == "model" && o.model.empty()) {
      return Outside(k + ".model", "",
                     "paths of a hetero model JSON file (primitive \"model\" needs one)");
    }
    if (o.primitive == "model" && s.materials.empty()) {
      return InvalidArgument(k +
                             ".primitive=model needs scene.materials (the model's materials, "
                             "same count, declared for every object)");
    }
    if (!o.center.IsFinite()) return InvalidArgument(k + ".center is not finite");
  }
  for (size_t i = 0; i < s.skins.size(); ++i) {
    SCULPT_RETURN_IF_ERROR(ValidateSkinConfig("scene.skins[" + std::to_string(i) + "]", s.skins[i]));
    for (size_t j = 0; j < i; ++j) {
      if (s.skins[j].name == s.skins[i].name) {
        return InvalidArgument("scene.skins[" + std::to_string(i) + "].name=" + s.skins[i].name +
                               " repeats");
      }
    }
  }
  SCULPT_RETURN_IF_ERROR(ValidateAlsoScenes(s));
  return ValidateClusterConfig(c);
}

std::vector<std::string> HostedScenes(const ServerConfig& c) {
  std::vector<std::string> names{c.scene.name};
  names.insert(names.end(), c.scene.also.begin(), c.scene.also.end());
  return names;
}

std::string SceneDataDir(const ServerConfig& c, const std::string& scene) {
  if (scene == c.scene.name) return c.data_dir;
  return (std::filesystem::path(c.data_dir) / "scenes" / scene).string();
}

ServerConfig ConfigForScene(const ServerConfig& c, const std::string& scene) {
  ServerConfig copy = c;
  copy.data_dir = SceneDataDir(c, scene);
  copy.scene.name = scene;
  copy.scene.also.clear();  // the copy describes one scene (Scene::Open validates it)
  return copy;
}

uint32_t ViewerSeats(const LimitsConfig& l) {
  return l.max_clients_per_scene - std::min(l.reserved_sculptor_seats, l.max_clients_per_scene / 2);
}

levelset::EditSettings EditSettingsFor(const SceneConfig& s) {
  levelset::EditSettings e;
  const std::string& vp = s.effects.volume_preservation;
  e.compensation = vp == "none"     ? levelset::CompensationRegion::kNone
                   : vp == "global" ? levelset::CompensationRegion::kGlobal
                                    : levelset::CompensationRegion::kShell;
  e.islands = s.effects.islands == "keep" ? levelset::IslandPolicy::kKeep
                                          : levelset::IslandPolicy::kRemoveSmall;
  e.min_island_volume = s.effects.min_island_volume;
  e.repair_band_every_edit = s.effects.band_repair == "every_edit";
  e.min_tool_voxels = s.min_tool_size / s.voxel_size;
  e.max_tool_voxels = s.max_tool_size / s.voxel_size;
  e.max_speed_voxels = std::max(1.0, s.max_speed / s.voxel_size);
  e.max_amount_voxels = std::max(1.0, s.max_amount / s.voxel_size);
  return e;
}

}  // namespace sculpt::server
