/// @brief Client: one connection to sculptd (Hello, JoinScene, strokes with de-duplicated resends,
/// acks, presence, errors), its I/O on a background thread, and helpers for CLI clients.
#ifndef SCULPT_CLIENT_CLIENT_H_
#define SCULPT_CLIENT_CLIENT_H_

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sculpt/codec/stroke.h"
#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"
#include "sculpt/v1/sculpt.pb.h"

namespace sculpt::client {

/// One io_context run by one thread. Several clients may share one (a load generator with
/// hundreds of connections needs a few threads, not hundreds); their handlers then run one at a
/// time on that thread. Thread safety: construct and destroy from one thread; it is destroyed
/// only after every Client using it (clients hold a reference).
class IoThread {
 public:
  IoThread();
  ~IoThread();
  IoThread(const IoThread&) = delete;
  IoThread& operator=(const IoThread&) = delete;

  struct Impl;
  Impl& impl() { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

/// TLS to a sculptd whose configuration has tls.cert_file (its TCP port then speaks only TLS).
struct ClientTlsOptions {
  bool enabled = false;
  /// PEM CA certificates the server's certificate must chain to; empty: the system's store.
  std::string ca_file;
  /// Check that the certificate names the server (a DNS name or an IP address).
  bool verify_server_name = true;
  /// The name to check and to send as SNI; empty: the host given to Connect.
  std::string server_name;
  /// A client certificate and its key (PEM), for servers with tls.client_ca_file.
  std::string cert_file;
  std::string key_file;
};

struct ClientOptions {
  /// Shared I/O thread; null: the client starts its own.
  std::shared_ptr<IoThread> io;
  /// Limit of every blocking call (Connect, Hello, Join, Close).
  std::chrono::milliseconds timeout{10000};
  /// Strokes kept for resending before SendStroke refuses more (ResourceExhausted).
  size_t max_unacked = 100000;
  /// Events kept in the queue when no handler is set; the oldest are dropped beyond it.
  size_t max_queued_events = 1u << 16;
  /// Largest frame accepted from the server (a state chunk is 256 KiB).
  uint32_t max_frame_bytes = 4u << 20;
  /// Join without the objects' .vdb state (a replica loads its region through Subscribe).
  bool skip_state = false;
  /// The first client_seq given to a stroke or an undo. The server takes any client_seq not
  /// above the highest it logged for a client_id as a resend, so a run that reuses the client_id
  /// of an earlier run must start above every sequence that run used (`sculpt undo` starts at
  /// the clock in microseconds, ClockClientSeq()). Never 0.
  uint64_t first_client_seq = 1;
  /// TLS on the connection (off: plain TCP).
  ClientTlsOptions tls;
  /// Cluster mode: other members (HOST:PORT). Reconnect() tries them in turn when the server
  /// it knew does not answer or cannot serve the scene (its machine died, it lost the scene);
  /// any member redirects to the scene's owner. After these, Reconnect() also tries the members
  /// the last join's SceneInfo.cluster_members named (Client::learnt_members()).
  std::vector<std::string> cluster_members;
};

/// A stroke as the caller describes it; SendStroke packs the poses (proto/README.md, "Packed
/// poses") against the object's voxel size from SceneInfo, around the middle of the stroke.
struct StrokeRequest {
  std::string object = "clay";
  v1::EditKind kind = v1::EDIT_KIND_PRESS;
  v1::ToolKind tool = v1::TOOL_KIND_SPHERE;
  Vec3 tool_size{2.5, 0, 0};  // world units: radius in x for sphere and capsule
  double speed = 60;          // press speed, world units per second
  double amount = 0;          // inflate/deflate distance, smooth flow time
  uint64_t t0_ms = 0;         // client clock of the first pose
  std::vector<codec::Pose> poses;
};

/// What the server sent, for the caller.
struct Event {
  enum class Type {
    kAck,           // `ack`; `latency_ms` from the stroke's last write to this ack
    kError,         // `error`; `refused` when it dropped a pending stroke (`client_seq`)
    kPresence,      // `presence`
    kBye,           // the server ends the session: `reason`
    kDisconnected,  // the connection is gone (`reason`); un-acked strokes wait for Reconnect().
                    // Connections a Join or Reconnect closes on its way (a redirect, a member
                    // that refused) say so too: reconnect only when joined() is false.
    kUndoAck,       // `undo_ack` (accepted or not); `latency_ms` from its request's write
  };
  Type type = Type::kAck;
  v1::Ack ack;
  v1::Error error;
  v1::Presence presence;
  v1::UndoAck undo_ack;
  std::string reason;
  double latency_ms = 0;
  bool refused = false;
};

/// The scene as a join delivered it: SceneInfo and each object's assembled .vdb bytes at
/// info.global_seq() (levelset::Sculpture::DeserializeVdb reads them).
struct JoinedScene {
  v1::SceneInfo info;
  std::map<std::string, std::string> state;
};

/// Counters since construction (all connections).
struct ClientStats {
  uint64_t bytes_sent = 0;
  uint64_t bytes_received = 0;
  uint64_t state_bytes_received = 0;  // StateChunk payloads
  uint64_t strokes_sent = 0;          // distinct strokes (client_seq values)
  uint64_t strokes_resent = 0;        // frames written again after a reconnect
  uint64_t acks = 0;                  // acks that settled a pending stroke
  uint64_t duplicate_acks = 0;        // of those, `duplicate = true`
  uint64_t stray_acks = 0;            // acks for no pending stroke (already settled)
  uint64_t refused = 0;               // pending strokes dropped by an Error (undos: below)
  uint64_t errors = 0;                // every Error received
  uint64_t presence = 0;
  uint64_t acks_out_of_order = 0;  // fresh acks whose global_seq_first did not increase
  uint64_t last_global_seq = 0;    // highest global sequence seen in an ack
  uint64_t poses_acked = 0;        // sum of Ack.edits over fresh (non-duplicate) acks
  uint64_t events_dropped = 0;     // queue overflow (no handler and nobody draining)
  uint64_t reconnects = 0;
  uint64_t redirects = 0;  // cluster mode: JoinScene answers naming another member, followed
  uint64_t replication_messages = 0;  // EditBroadcast, LeafDelta, MeshChunk
  uint64_t undos_sent = 0;            // distinct undo and redo requests
  uint64_t undos_resent = 0;          // of the frames written again after a reconnect
  uint64_t undo_acks = 0;             // UndoAcks that settled a pending request (any outcome)
  uint64_t undos_refused = 0;         // pending requests settled by a refusal (ack or Error)
};

/// A connection to sculptd. The I/O runs on an IoThread (its own, or a shared one); the caller's
/// thread makes the blocking calls (Connect, Hello, Join, Reconnect, Close, the Wait* calls),
/// each bounded by options.timeout.
///
/// Strokes: SendStroke assigns strictly increasing client_seq values and keeps every stroke until
/// its Ack or a refusing Error arrives. Frames queued while a write is in flight leave together
/// in one write. After a lost connection, Reconnect() connects, says Hello with the same
/// client_id, joins the same scene and resends every un-acked stroke in client_seq order, before
/// any newer stroke: the server recognises the ones it already applied (Ack.duplicate) by the
/// highest client_seq it logged for the client_id, so a newer stroke overtaking an older resend
/// would make the older one look applied. Strokes sent while disconnected wait for the resend.
/// The JoinScene declares the pending requests' client_seq ranges (JoinScene.resends, at most
/// 5 s of Welcome.max_strokes_per_second), so the server takes no rate-limit tokens for them.
///
/// Undo and redo: SendUndo numbers its request from the same counter as strokes (the server
/// de-duplicates undos on their own sequence, so gaps are harmless, and an Error naming a
/// client_seq then names exactly one request), keeps it until its UndoAck or a refusing Error,
/// and resends it with the strokes, in client_seq order, after a reconnect: an undo sent after a
/// stroke reaches the server after it, so it never takes back the stroke before.
///
/// Events (acks, undo acks, errors, presence, bye, disconnect) go to the handler if one is set,
/// else to a bounded queue read with NextEvent / DrainEvents.
///
/// Thread safety: every public method may be called from any thread, except that the blocking
/// calls must not be made from an event handler (it runs on the I/O thread they wait on), and a
/// Client must not be destroyed from its own handler.
class Client {
 public:
  using EventHandler = std::function<void(const Event&)>;

  explicit Client(ClientOptions options = {});
  /// Says Bye (bounded by the timeout) and closes.
  ~Client();
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  /// Opens a TCP connection (closing any previous one), with a TLS handshake when options.tls
  /// is enabled. Unavailable when the host does not resolve, the connection is refused, the
  /// handshake fails (the text names the reason: "certificate has expired", "hostname
  /// mismatch", ...) or the timeout passes; InvalidArgument naming the option for a TLS file
  /// that cannot be loaded.
  Status Connect(const std::string& host, uint16_t port);
  /// Authenticates. Returns the Welcome, or the server's Error as a Status (ErrorToStatus: the
  /// code name, field, value, allowed range and message in the text), Unavailable when the
  /// connection drops or the timeout passes. client_id 0 picks a random one (NewClientId): the
  /// id must be stable across reconnects and never reused by another run, since the server
  /// remembers the highest client_seq of every id it has logged.
  StatusOr<v1::Welcome> Hello(const std::string& token, v1::Role role, const std::string& name,
                              uint64_t client_id);
  /// Joins a scene (empty: the server's default) and waits for SceneInfo and every StateChunk;
  /// then resends the un-acked strokes. The server's Error (e.g. NOT_FOUND) as a Status;
  /// DataLoss for chunks out of order; Unavailable on a drop or timeout.
  /// Cluster mode (docs/cluster.md): when the member answers with a Redirect to the scene's
  /// owner, the client closes that connection (a kDisconnected event names the owner), connects
  /// to the owner, says Hello again with the same arguments and joins there; later Reconnect()
  /// calls go to the owner. One redirect is followed: Unavailable for a second one, and for a
  /// redirect to an address that does not parse.
  StatusOr<JoinedScene> Join(const std::string& scene = "");
  /// Drops any connection, then Connect + Hello + Join with the last arguments; the un-acked
  /// strokes are resent with their client_seq. FailedPrecondition before a first Join.
  Status Reconnect();

  /// Packs and queues a stroke; returns its client_seq. FailedPrecondition before Join (the
  /// voxel size is needed to pack), NotFound for an object not in SceneInfo, InvalidArgument
  /// from PackPoses (a pose too far from the middle of the stroke, decreasing t_ms), and
  /// ResourceExhausted past options.max_unacked. Sent now if joined, else at the next Join.
  /// A stroke the server refuses (any Error naming its client_seq: validation, rate limit,
  /// INTERNAL) is dropped, not retried: to try again, send it anew (a new client_seq), since the
  /// server's de-duplication takes any client_seq below the highest applied one as a resend.
  StatusOr<uint64_t> SendStroke(const StrokeRequest& stroke);
  /// Queues a stroke built by the caller (client_seq is overwritten); for strokes the server is
  /// expected to refuse. Same errors as SendStroke except the packing ones.
  StatusOr<uint64_t> SendStrokeMessage(v1::Stroke stroke);
  /// Sends a presence-only tool position. FailedPrecondition when not joined.
  Status SendHover(const Vec3& position, double radius);

  /// Queues an undo (`redo` false) or a redo of this client's own most recent edit of `object`
  /// (empty: the scene's first object); returns its client_seq. The server files edits under the
  /// Hello's client_id: only that id's edits are taken back. FailedPrecondition before Join,
  /// NotFound for an object not in SceneInfo, InvalidArgument for a scene without objects,
  /// ResourceExhausted past options.max_unacked (strokes and undos together). Sent now if
  /// joined, else at the next Join.
  StatusOr<uint64_t> SendUndo(const std::string& object, bool redo = false);
  /// The answer to the undo or redo `client_seq`, as the server sent it: accepted (duplicate set
  /// for a resend it had applied already) or not (`error` says why: FAILED_PRECONDITION for
  /// nothing to undo or redo, INVALID_ARGUMENT beyond the history's depth). An Error that
  /// refused the request before it reached the history (a viewer, the rate limit, a server
  /// that does not know undo: MALFORMED) comes back the same way, as an UndoAck with accepted
  /// false and that error. Unavailable when `timeout` passes, or at once when the connection is
  /// lost (the request stays pending for Reconnect(); call again after it); NotFound for a
  /// client_seq that is neither pending nor answered (each answer is returned once).
  StatusOr<v1::UndoAck> WaitUndoAck(uint64_t client_seq, std::chrono::milliseconds timeout);
  /// SendUndo, then WaitUndoAck within options.timeout. Returns the accepted UndoAck (target_seq,
  /// replayed, replayed_by, undo_depth, redo_depth); a refused one as ErrorToStatus(error)
  /// (FailedPrecondition "ERROR_CODE_FAILED_PRECONDITION ...: nothing to undo ..."), and the
  /// errors of SendUndo and WaitUndoAck.
  StatusOr<v1::UndoAck> Undo(const std::string& object = "");
  StatusOr<v1::UndoAck> Redo(const std::string& object = "");

  /// The history view (issue 15): `object`'s recent edits (empty: the scene's first object) as
  /// the server's undo history holds them, newest first, only `author`'s when set (the name
  /// undo files edits under: the client id in decimal), at most `limit` (0: the server's 50;
  /// it accepts up to 1000). Viewers may ask. Waits up to options.timeout. A refusal comes back
  /// as ErrorToStatus(error): InvalidArgument naming the field (limit above 1000, a name over 64
  /// bytes), NotFound for an unknown object, MALFORMED from a server that does not know the
  /// request; FailedPrecondition when not joined; Unavailable on timeout or a lost connection.
  StatusOr<v1::HistoryAnswer> History(const std::string& object = "",
                                      const std::string& author = "", uint32_t limit = 0);

  /// Waits until no stroke is pending (acked or refused) and every event up to then has been
  /// delivered (handler returned, or queued). False on timeout, or early when the connection is
  /// lost with strokes pending.
  bool WaitAllAcked(std::chrono::milliseconds timeout);
  /// The next queued event, or nullopt after `timeout`.
  std::optional<Event> NextEvent(std::chrono::milliseconds timeout);
  std::vector<Event> DrainEvents();
  /// Events go to `handler` (on the I/O thread; it must not block) instead of the queue. Pass
  /// nullptr to return to the queue; returns only once no call of the old handler is running.
  void SetEventHandler(EventHandler handler);

  /// Replication messages (EditBroadcast, LeafDelta, MeshChunk; ContourUpdate and SkinAck for a
  /// SkinClient) go to `handler`, called on the
  /// I/O thread under the client's lock: it must only queue the message (Replica does).
  void SetReplicationHandler(std::function<void(v1::ServerMessage&&)> handler);
  /// Queues any client message (Subscribe, SetInterest, DivergenceReport, ViewerSubscribe).
  /// FailedPrecondition when not joined.
  Status SendMessage(const v1::ClientMessage& message);
  /// Says Bye, flushes what is queued and closes. Un-acked strokes stay pending. Ok if already
  /// closed.
  Status Close(const std::string& reason = "client done");
  /// Ends the connection as a network failure would, without a Bye: the sending side is shut
  /// down after what was already queued, so the server reads every frame written, then the
  /// socket closes without waiting for acks. Un-acked strokes stay pending for Reconnect().
  void DropConnection();

  bool joined() const;
  bool connected() const;
  size_t unacked() const;
  std::vector<uint64_t> UnackedSeqs() const;
  uint64_t client_id() const;
  v1::Welcome welcome() const;
  v1::SceneInfo scene_info() const;
  /// Cluster mode: the members' TCP addresses (HOST:PORT) the last join that listed any named
  /// in SceneInfo.cluster_members (valid, distinct, at most kMaxLearntMembers); Reconnect()
  /// tries them after ClientOptions::cluster_members. Empty on a single process.
  std::vector<std::string> learnt_members() const;
  ClientStats stats() const;

  struct Impl;

 private:
  std::shared_ptr<IoThread> io_;  // first: destroyed after impl_ lets go of its sockets
  std::shared_ptr<Impl> impl_;
};

/// The Error as a Status: `ERROR_CODE_X <field>=<value> outside <range>: <message>` (parts that
/// are empty are left out), with the nearest Status code.
Status ErrorToStatus(const v1::Error& error);
/// The short name of an error code ("PERMISSION_DENIED").
std::string ErrorCodeName(v1::ErrorCode code);
/// A random non-zero client id.
uint64_t NewClientId();
/// A first client_seq for ClientOptions::first_client_seq that is above every sequence an earlier
/// run of a client on this machine used, unless it sent more than a million edits a second or
/// the clock went back: the wall clock in microseconds since 1970.
uint64_t ClockClientSeq();
/// Splits "HOST:PORT" (IPv6 as "[::1]:7420"). InvalidArgument naming the text otherwise.
Status ParseServerAddress(const std::string& text, std::string* host, uint16_t* port);

/// At most this many members learnt from SceneInfo.cluster_members are kept.
inline constexpr size_t kMaxLearntMembers = 64;

/// Connects (over TLS with `tls`), joins as `role` and returns the scene's current state, then
/// says Bye. Errors as Connect, Hello and Join.
StatusOr<JoinedScene> FetchScene(const std::string& address, const std::string& token,
                                 v1::Role role = v1::ROLE_VIEWER, const std::string& scene = "",
                                 std::chrono::milliseconds timeout = std::chrono::seconds(30),
                                 const ClientTlsOptions& tls = {});

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_CLIENT_H_
