/// @brief StandbyFollower: follow an owner's edit stream into a durable copy of its scene.
#include "cluster/standby_follower.h"

#include <spdlog/spdlog.h>

#include <cctype>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <variant>
#include <vector>

#include "scene/commit.h"
#include "scene/edit_history.h"
#include "scene/history_file.h"
#include "scene/history_replay.h"
#include "scene/models.h"
#include "scene/skins.h"
#include "sculpt/client/client.h"
#include "sculpt/codec/log_records.h"
#include "sculpt/codec/replica_sculpture.h"
#include "sculpt/codec/settings.h"
#include "sculpt/codec/stroke.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/region.h"
#include "sculpt/levelset/sculpture.h"
#include "store/durable_file.h"
#include "store/edit_log.h"
#include "store/recovery.h"
#include "store/resend_table.h"
#include "store/snapshot_store.h"

namespace sculpt::server::cluster {
namespace {

namespace fs = std::filesystem;

constexpr char kCurrent[] = "CURRENT";
constexpr char kPromoted[] = "cluster-promoted";

std::string ReadSmallFile(const fs::path& path) {
  std::ifstream in(path);
  std::string s;
  std::getline(in, s);
  return s;
}

}  // namespace

std::string StandbyDir(const std::string& data_dir, const std::string& scene) {
  return (fs::path(data_dir) / "standby" / scene).string();
}

std::optional<std::string> CurrentStandbyCopy(const std::string& data_dir, const std::string& scene,
                                              uint64_t* epoch) {
  const fs::path dir = StandbyDir(data_dir, scene);
  // "gen-<n> <owner epoch>"
  const std::string line = ReadSmallFile(dir / kCurrent);
  const size_t space = line.find(' ');
  const std::string gen = line.substr(0, space);
  if (epoch) {
    *epoch = 0;
    try {
      if (space != std::string::npos) *epoch = std::stoull(line.substr(space + 1));
    } catch (...) {
    }
  }
  if (gen.rfind("gen-", 0) != 0 || gen.find('/') != std::string::npos) return std::nullopt;
  std::error_code ec;
  if (!fs::is_directory(dir / gen / store::kSnapshotSubdir, ec)) return std::nullopt;
  return (dir / gen).string();
}

Status PromoteStandbyCopy(const std::string& data_dir, const std::string& scene,
                          const std::string& scene_dir, uint64_t dead_epoch) {
  const auto copy = CurrentStandbyCopy(data_dir, scene);
  if (!copy) {
    return FailedPrecondition("no complete standby copy of scene " + scene + " in " +
                              StandbyDir(data_dir, scene));
  }
  const fs::path root(scene_dir);
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                      std::chrono::system_clock::now().time_since_epoch())
                      .count();
  const fs::path aside =
      root / "superseded" / (std::to_string(dead_epoch) + "-" + std::to_string(ms));
  std::error_code ec;
  fs::create_directories(aside, ec);
  if (ec) return Internal("cannot create " + aside.string() + ": " + ec.message());
  for (const fs::directory_entry& e : fs::directory_iterator(root, ec)) {
    const std::string name = e.path().filename().string();
    // The member's copies and its other hosted scenes stay (they live under the configured
    // scene's directory, data_dir).
    if (name == "standby" || name == "superseded" || name == "scenes") continue;
    fs::rename(e.path(), aside / name, ec);
    if (ec) return Internal("cannot move " + e.path().string() + " aside: " + ec.message());
  }
  if (ec) return Internal("cannot list " + root.string() + ": " + ec.message());
  for (const fs::directory_entry& e : fs::directory_iterator(*copy, ec)) {
    fs::rename(e.path(), root / e.path().filename(), ec);
    if (ec) return Internal("cannot move " + e.path().string() + " in: " + ec.message());
  }
  if (ec) return Internal("cannot list " + *copy + ": " + ec.message());
  SCULPT_RETURN_IF_ERROR(store::WriteFileDurably((root / kPromoted).string(),
                                                 scene + " " + std::to_string(dead_epoch) + "\n"));
  fs::remove_all(StandbyDir(data_dir, scene), ec);  // its other generations; the copy is in
  spdlog::warn(
      "cluster: the standby copy of scene {} is now its data directory {} (what was "
      "there is in {})",
      scene, scene_dir, aside.string());
  return Status::Ok();
}

std::optional<uint64_t> PromotedFromEpoch(const std::string& scene_dir, const std::string& scene) {
  const std::string line = ReadSmallFile(fs::path(scene_dir) / kPromoted);
  const size_t space = line.rfind(' ');
  if (space == std::string::npos || line.substr(0, space) != scene) return std::nullopt;
  try {
    return std::stoull(line.substr(space + 1));
  } catch (...) {
    return std::nullopt;
  }
}

void ClearPromotedMarker(const std::string& scene_dir) {
  std::error_code ec;
  fs::remove(fs::path(scene_dir) / kPromoted, ec);
}

struct StandbyFollower::Impl {
  std::unique_ptr<client::Client> client;
  std::string object;
  levelset::ValidEditSettings settings;  // validated once, from the owner's SceneInfo
  double voxel_size = 1.0;
  std::optional<levelset::Sculpture> sculpture;
  fs::path gen;  // this follow's generation
  std::unique_ptr<store::SnapshotStore> snapshots;
  std::unique_ptr<store::EditLog> log;
  uint64_t seq = 0;                       // last sequence applied
  std::atomic<uint64_t> snapshot_seq{0};  // of the newest snapshot written
  uint64_t previous_snapshot_seq = 0;     // the log is kept from here (two snapshots' worth)
  uint64_t records_since_snapshot = 0;
  // Newest client_seq of each author's strokes, saved with each snapshot (the resend table), so
  // resends are still recognised once the log before it is dropped.
  std::map<std::pair<uint8_t, uint64_t>, uint64_t> resend;
  // The scene's skins and models as the owner's log makes them, saved with each snapshot
  // (opened at the first region load, from the book files it carries).
  SkinBook skins;
  ModelBook models;
  bool books = false;
  // The object's stroke undo history as the owner's is at `seq`: the owner's as of the region
  // load (LeafDelta.object_history), then every stroke, paint, sweep and object undo recorded
  // into it as the owner's Apply records them; saved beside each snapshot of the copy.
  std::optional<EditHistory> history;
  std::optional<HistoryReplay> replay;
};

bool IsBookFilePath(const std::string& path) {
  const size_t slash = path.find('/');
  if (slash == std::string::npos) return false;
  const std::string dir = path.substr(0, slash);
  const std::string file = path.substr(slash + 1);
  const size_t dot = file.rfind('.');
  if (dot == std::string::npos || dot == 0 || file.size() > 200) return false;
  const std::string name = file.substr(0, dot), ext = file.substr(dot);
  if (name.front() == '.') return false;
  for (char c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' && c != '-') {
      return false;
    }
  }
  if (dir == "skins") return ext == ".pb" || ext == ".history";
  if (dir == "models") return ext == ".json" || ext == ".history";
  return false;
}

StandbyFollower::StandbyFollower(FollowerOptions options)
    : options_(std::move(options)), impl_(std::make_shared<Impl>()) {
  expected_epoch_ = options_.owner_epoch;
  thread_ = std::thread([this] { Run(); });
}

StandbyFollower::~StandbyFollower() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
  // The client (and its I/O thread, which calls the handler above) goes before the queue and
  // the mutex it uses.
  if (impl_->client) impl_->client->SetReplicationHandler(nullptr);
  impl_->client.reset();
}

std::string StandbyFollower::failure() const {
  std::lock_guard<std::mutex> lock(mu_);
  return failure_;
}

uint64_t StandbyFollower::durable_seq() const {
  std::lock_guard<std::mutex> lock(mu_);
  if (!ready_ || !impl_->log) return 0;
  // Everything up to the snapshot is durable with it; the log holds what came since.
  return std::max(impl_->log->durable_seq(), impl_->snapshot_seq.load());
}

void StandbyFollower::Supersede(uint64_t epoch) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (epoch == expected_epoch_.load()) return;
    spdlog::warn(
        "cluster: standby of scene {}: etcd names epoch {} for its owner now, not epoch {} of the "
        "owner at {}: its stream is no longer taken",
        options_.scene, epoch, expected_epoch_.load(), options_.owner_tcp);
    expected_epoch_ = epoch;
    superseded_ = true;
  }
  cv_.notify_all();
}

void StandbyFollower::Run() {
  Impl& im = *impl_;
  auto fail = [&](const std::string& why) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      failure_ = why;
    }
    finished_ = true;
  };
  const FollowerOptions& o = options_;
  const size_t colon = o.owner_tcp.rfind(':');
  int port = 0;
  try {
    port = colon == std::string::npos ? 0 : std::stoi(o.owner_tcp.substr(colon + 1));
  } catch (...) {
  }
  if (port <= 0 || port > 65535) return fail("owner address " + o.owner_tcp + " has no port");
  client::ClientOptions co;
  co.skip_state = true;
  co.timeout = std::chrono::milliseconds(5000);
  // A region load is one frame: the object's leaves, plus its undo history and books for a
  // standby, several MB for a sculpted scene (5.5 MB at 1,336 strokes in the failover soak under
  // ASan), past a client's default 4 MB. The owner is a peer this member connected to itself.
  co.max_frame_bytes = 256u << 20;
  co.tls.enabled = o.tls.enabled;
  co.tls.ca_file = o.tls.ca_file;
  co.tls.cert_file = o.tls.cert_file;
  co.tls.key_file = o.tls.key_file;
  im.client = std::make_unique<client::Client>(co);
  Status s = im.client->Connect(o.owner_tcp.substr(0, colon), static_cast<uint16_t>(port));
  if (s.ok()) {
    // The peer token (cluster.peer_token) when the cluster has one: with it the owner knows this
    // session for its standby, named users or not.
    auto hello = im.client->Hello(o.token, v1::ROLE_VIEWER, "standby-" + o.member, 0);
    s = hello.status();
  }
  if (s.ok()) s = im.client->Join(o.scene).status();
  if (!s.ok())
    return fail("cannot join scene " + o.scene + " at " + o.owner_tcp + ": " + s.ToString());

  // The object and its settings, as a replica reads them (client/src/lib/replica.cc).
  const v1::SceneInfo info = im.client->scene_info();
  if (info.objects_size() != 1) {
    return fail("scene " + o.scene + " has " + std::to_string(info.objects_size()) +
                " objects: a standby follows scenes of one object only (docs/cluster.md)");
  }
  const v1::ObjectInfo& obj = info.objects(0);
  auto settings = codec::SettingsFromProto(info.edit_settings());
  if (!settings.ok()) return fail(settings.status().ToString());
  auto empty = codec::EmptyReplicaSculpture(info, obj);
  if (!empty.ok()) return fail(empty.status().ToString());
  im.object = obj.name();
  im.settings = *settings;
  im.voxel_size = obj.voxel_size();
  im.sculpture.emplace(std::move(empty).value());

  // A new generation beside the current one; older incomplete ones are removed.
  const fs::path dir = StandbyDir(o.data_dir, o.scene);
  std::error_code ec;
  fs::create_directories(dir, ec);
  std::string current = ReadSmallFile(dir / kCurrent);
  current = current.substr(0, current.find(' '));
  uint64_t next = 1;
  for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("gen-", 0) != 0) continue;
    try {
      next = std::max<uint64_t>(next, std::stoull(name.substr(4)) + 1);
    } catch (...) {
    }
    if (name != current) fs::remove_all(e.path(), ec);
  }
  im.gen = dir / ("gen-" + std::to_string(next));
  fs::create_directories(im.gen, ec);
  if (ec) return fail("cannot create " + im.gen.string() + ": " + ec.message());
  auto snaps = store::SnapshotStore::Open((im.gen / store::kSnapshotSubdir).string());
  if (!snaps.ok()) return fail(snaps.status().ToString());
  im.snapshots = std::move(snaps).value();

  im.client->SetReplicationHandler([this](v1::ServerMessage&& m) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      queue_.push_back(std::make_unique<v1::ServerMessage>(std::move(m)));
    }
    cv_.notify_all();
  });
  v1::ClientMessage sub;
  sub.mutable_subscribe()->set_object(im.object);
  sub.mutable_subscribe()->set_mode(v1::REPLICA_MODE_REPLAY);
  sub.mutable_subscribe()->set_have_seq(0);
  if (s = im.client->SendMessage(sub); !s.ok()) return fail("subscribe: " + s.ToString());
  spdlog::info("cluster: following scene {} at {} (epoch {}) into {}", o.scene, o.owner_tcp,
               o.owner_epoch, im.gen.string());

  // Synchronous replication: the owner acknowledges an edit only once this says the copy holds
  // it durably. Sent from the log's sync thread (one per group sync) and after each snapshot;
  // the client queues it for its I/O thread.
  auto report_progress = [this](uint64_t durable) {
    Impl& m = *impl_;
    const uint64_t seq = std::max(durable, m.snapshot_seq.load());
    if (seq == 0 || !m.client) return;
    v1::ClientMessage pm;
    pm.mutable_replica_progress()->set_object(m.object);
    pm.mutable_replica_progress()->set_durable_seq(seq);
    (void)m.client->SendMessage(pm);
  };
  auto resync = [&] {
    v1::ClientMessage m;
    m.mutable_set_interest()->set_object(im.object);
    (void)im.client->SendMessage(m);
  };
  // The object as held now, durable at `seq`: after a region load, or an edit the log cannot
  // hold. The first one completes the generation: its log starts after it and CURRENT names it.
  auto snapshot = [&](uint64_t seq) -> Status {
    // As the owner: the log durable, the resend table at seq, the snapshot, a new segment;
    // the segments before the previous snapshot go (a damaged newest one leaves the older).
    // The first snapshot (the region load) has no log before it but its table all the same.
    if (im.log) SCULPT_RETURN_IF_ERROR(im.log->Sync());
    {
      store::ResendTable table;
      table.seq = seq;
      table.last = im.resend;
      SCULPT_RETURN_IF_ERROR(
          store::SaveResendTable((im.gen / store::kResendTableFile).string(), table));
    }
    SCULPT_RETURN_IF_ERROR(im.snapshots->Write(seq, im.object, *im.sculpture));
    // The history after its snapshot, as the owner's rounds write it: recovery of the copy
    // loads it with the snapshot and undoes what the owner could undo at seq.
    if (im.history) {
      SCULPT_RETURN_IF_ERROR(WriteHistoryFile(im.gen.string(), im.object, seq,
                                              HistoryFileBytes(*im.history, seq)));
    }
    // The books as of seq, before the log rolls (the records they hold may then go).
    if (im.books && (!im.skins.Save(seq) || !im.models.Save(seq))) {
      return Internal("the copy's skins or models at seq " + std::to_string(seq) +
                      " were not saved in " + im.gen.string());
    }
    im.snapshot_seq = seq;
    im.records_since_snapshot = 0;
    if (im.log) {
      im.log->Roll();
      if (im.previous_snapshot_seq > 0) {
        SCULPT_RETURN_IF_ERROR(im.log->DropSegmentsBefore(im.previous_snapshot_seq));
      }
      im.previous_snapshot_seq = seq;
    }
    if (!im.log) {
      store::FsyncPolicy policy;  // group commit: a standby logs at the owner's rate
      store::RecoveryReport report;
      auto log = store::EditLog::Open((im.gen / store::kLogSubdir).string(), policy, &report);
      if (!log.ok()) return log.status();
      SCULPT_RETURN_IF_ERROR((*log)->StartAfter(seq));
      (*log)->OnDurable(report_progress);
      {
        std::lock_guard<std::mutex> lock(mu_);
        im.log = std::move(log).value();
      }
      SCULPT_RETURN_IF_ERROR(store::WriteFileDurably(
          (dir / kCurrent).string(),
          im.gen.filename().string() + " " + std::to_string(o.owner_epoch) + "\n"));
      for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
        const std::string name = e.path().filename().string();
        if (name.rfind("gen-", 0) == 0 && e.path() != im.gen) fs::remove_all(e.path(), ec);
      }
      ready_ = true;
      spdlog::info("cluster: standby copy of scene {} complete at seq {}", o.scene, seq);
    }
    report_progress(seq);  // the snapshot holds everything up to seq durably
    return Status::Ok();
  };

  // Fencing: only the epoch of the owner etcd names is taken. Anything else (an owner that lost
  // the scene and has not noticed, a new owner on the old address) is refused before it touches
  // the copy, and the follow ends.
  auto check_epoch = [&](const v1::ServerMessage& m) -> Status {
    const bool delta = m.has_leaf_delta();
    const bool records = m.has_log_records();
    if (!delta && !records && !m.has_edit()) return Status::Ok();
    const uint64_t got = delta     ? m.leaf_delta().epoch()
                         : records ? m.log_records().epoch()
                                   : m.edit().epoch();
    const uint64_t want = expected_epoch_.load();
    if (got == want) return Status::Ok();
    ++refusals_;
    if (o.stale_epoch_refusals) ++*o.stale_epoch_refusals;
    const uint64_t seq = delta     ? m.leaf_delta().global_seq()
                         : records ? m.log_records().first_seq()
                                   : m.edit().global_seq_first();
    const std::string why = "scene " + o.scene + ": refused " +
                            (delta     ? "a LeafDelta"
                             : records ? "LogRecords"
                                       : "an EditBroadcast") +
                            " at seq " + std::to_string(seq) + " of epoch " + std::to_string(got) +
                            " from " + o.owner_tcp + ": the owner etcd names holds epoch " +
                            std::to_string(want) + " (nothing of it applied or logged)";
    spdlog::warn("cluster: standby {}; ending the connection, the owner is read from etcd again",
                 why);
    return Status(Status::Code::kFailedPrecondition, why);
  };

  // The owner's books as of a region load: its files written into the generation (only the
  // names a book file has), then opened as recovery opens them; a load without files (no skins
  // or models) opens them as configured.
  auto load_books = [&](const v1::LeafDelta& d) -> Status {
    for (const v1::BookFile& f : d.book_files()) {
      if (!IsBookFilePath(f.path())) {
        return InvalidArgument("LeafDelta.book_files path \"" + f.path().substr(0, 80) +
                               "\" is not one of skins/<name>.pb, skins/<name>.history, "
                               "models/<name>.json, models/<name>.history");
      }
      const fs::path path = im.gen / f.path();
      fs::create_directories(path.parent_path(), ec);
      SCULPT_RETURN_IF_ERROR(store::WriteFileDurably(path.string(), f.data()));
    }
    im.skins.set_undo_depth(o.books.undo_depth);
    im.models.set_undo_depth(o.books.undo_depth);
    SCULPT_RETURN_IF_ERROR(im.skins.Open(o.books.skins, im.gen.string(), nullptr));
    SCULPT_RETURN_IF_ERROR(im.models.Open(o.books.objects, im.gen.string()));
    im.books = true;
    return Status::Ok();
  };

  // The owner's stroke undo history as of a region load. Without it (an older owner) or when
  // it does not parse, the copy's history starts empty and says why, as a restart from a
  // snapshot without its history file does.
  auto load_history = [&](const v1::LeafDelta& d) {
    EditHistoryOptions ho;
    ho.depth_per_author = static_cast<int>(o.books.undo_depth);
    im.history.emplace(ho);
    im.replay.emplace(im.settings);
    if (d.global_seq() == 0) return;  // the scene as configured: nothing before it to undo
    const std::string at = std::to_string(d.global_seq());
    if (d.object_history().empty()) {
      spdlog::warn("cluster: standby: the region load at seq {} came without the owner's undo "
                   "history: after a failover, strokes before it cannot be undone",
                   d.global_seq());
      im.history->Clear("the standby's copy was loaded at seq " + at +
                        " without the owner's undo history");
      return;
    }
    auto parsed = ParseHistoryFile(d.object_history(), d.global_seq(), ho);
    if (!parsed.ok()) {
      spdlog::warn("cluster: standby: the owner's undo history at seq {} is not usable: {}",
                   d.global_seq(), parsed.status().ToString());
      im.history->Clear("the owner's undo history sent with the region load at seq " + at +
                        " was not usable");
      return;
    }
    im.history = std::move(parsed).value();
  };

  // Records of edits no broadcast carries, logged as the owner logged them and replayed into
  // the books and the object's undo history; their object changes (paint, sweep, undo) follow as a LeafDelta of the same
  // sequence, which snapshots the copy. No snapshot here: the object does not hold them yet.
  auto log_records = [&](const v1::LogRecords& r) -> Status {
    if (!im.log || r.records_size() == 0) return Status::Ok();  // before the load: in it
    const uint64_t first = r.first_seq();
    const uint64_t last = first + static_cast<uint64_t>(r.records_size()) - 1;
    if (first <= im.seq) return Status::Ok();  // already in a region load
    std::vector<std::string> payloads(r.records().begin(), r.records().end());
    std::vector<LoggedEdit> edits;
    for (size_t i = 0; i < payloads.size(); ++i) {
      SCULPT_ASSIGN_OR_RETURN(LoggedEdit e, DecodeLogRecord(first + i, payloads[i]));
      if (const uint64_t epoch = codec::RecordEpoch(e.record); epoch != r.epoch()) {
        return InvalidArgument("LogRecords record at seq " + std::to_string(first + i) +
                               " names epoch " + std::to_string(epoch) + ", the message epoch " +
                               std::to_string(r.epoch()));
      }
      edits.push_back(std::move(e));
    }
    SCULPT_RETURN_IF_ERROR(payloads.size() == 1 ? im.log->Append(first, payloads.front())
                                                : im.log->AppendGroup(first, payloads));
    for (size_t i = 0; i < edits.size(); ++i) {
      const LoggedEdit& e = edits[i];
      const uint64_t seq = first + i;
      if (e.completes) {
        uint64_t& newest = im.resend[{static_cast<uint8_t>(e.stream), e.client_id}];
        newest = std::max(newest, e.client_seq);
      }
      // Through the object's history as the owner applied it (and as recovery replays it):
      // the paint, sweep or undo whose leaves follow, or a stroke the kernel refused again.
      if (im.history && (e.object.empty() || e.object == im.object)) {
        SCULPT_RETURN_IF_ERROR(im.replay->Apply(*im.sculpture, *im.history, seq, e.record));
      }
      if (!im.books) continue;
      if (auto* b = std::get_if<codec::BallEditRecord>(&e.record)) im.skins.Replay(seq, *b);
      if (auto* mr = std::get_if<codec::ModelRecord>(&e.record)) im.models.Replay(seq, *mr);
      if (auto* u = std::get_if<codec::UndoRecord>(&e.record)) {
        if (u->target_book == codec::kUndoModelBook) im.models.ReplayUndo(seq, *u);
        if (u->target_book == codec::kUndoSkinBook) im.skins.ReplayUndo(seq, *u);
      }
    }
    im.seq = last;
    im.records_since_snapshot += payloads.size();
    return Status::Ok();
  };

  auto apply = [&](v1::ServerMessage& m) -> Status {
    SCULPT_RETURN_IF_ERROR(check_epoch(m));
    if (m.has_log_records()) return log_records(m.log_records());
    if (m.has_leaf_delta()) {
      const v1::LeafDelta& d = m.leaf_delta();
      if (d.object() != im.object) return Status::Ok();
      levelset::VoxelBox region;
      if (d.region_min_size() == 3 && d.region_max_size() == 3) {
        region.min = {d.region_min(0), d.region_min(1), d.region_min(2)};
        region.max = {d.region_max(0), d.region_max(1), d.region_max(2)};
      }
      if (d.replace_region()) levelset::ClearRegion(*im.sculpture, region);
      auto r = levelset::ApplyLeafRecords(*im.sculpture, d.records());
      if (!r.ok()) {
        spdlog::warn("cluster: standby: leaf records at seq {} refused: {}", d.global_seq(),
                     r.status().ToString());
        resync();
        return Status::Ok();
      }
      levelset::RestoreReplayState(*im.sculpture,
                                   {d.volume(), d.reference_volume(), d.edits_since_reinit()});
      if (d.replace_region()) {
        SCULPT_RETURN_IF_ERROR(load_books(d));
        load_history(d);
        // The owner's resend table at the load's sequence: without it, a client resending an
        // edit inside the load after a failover would have it applied twice.
        if (d.resend_table_size() == 0 && d.global_seq() > 0) {
          spdlog::warn("cluster: standby: the region load at seq {} came without the owner's "
                       "resend table (not yet named standby there?): resends of edits before it "
                       "may be applied again after a failover",
                       d.global_seq());
        }
        if (d.resend_table_size() > 0) im.resend.clear();  // else what the log gave stays
        for (const v1::ResendEntry& e : d.resend_table()) {
          if (e.stream() > static_cast<uint32_t>(ResendStream::kUndos)) {
            spdlog::warn("cluster: standby: resend entry of stream {} outside [0, {}] ignored",
                         e.stream(), static_cast<int>(ResendStream::kUndos));
            continue;
          }
          uint64_t& newest = im.resend[{static_cast<uint8_t>(e.stream()), e.client_id()}];
          newest = std::max(newest, e.client_seq());
        }
      }
      im.seq = std::max(im.seq, d.global_seq());
      return snapshot(d.global_seq());
    }
    if (!m.has_edit()) return Status::Ok();
    const v1::EditBroadcast& b = m.edit();
    if (b.object() != im.object) return Status::Ok();
    if (!im.log) return Status::Ok();  // before the region load: it is in the load
    std::vector<levelset::EditRequest> reqs;
    std::vector<std::string> payloads;
    const uint64_t author = b.records_size() > 0 ? b.records(0).client_id() : b.client_id();
    uint64_t commit_ms = 0;  // logged with the last pose: the history view's time
    if (b.records_size() > 0) {
      for (const v1::EditRecord& r : b.records()) {
        codec::StrokePoseRecord p;
        p.global_seq = r.global_seq();
        p.client_id = r.client_id();
        p.client_seq = r.client_seq();
        p.object = r.object().empty() ? b.object() : r.object();
        p.pose_index = r.pose_index();
        p.pose_count = r.pose_count();
        p.commit_ms = r.commit_ms();
        commit_ms = std::max(commit_ms, p.commit_ms);
        p.edit = codec::EditFromRecord(r);
        p.user = r.user();
        reqs.push_back(p.edit);
        std::string payload = codec::EncodeLogRecord(p);
        codec::AppendRecordUser(&payload, p.user);
        codec::AppendRecordEpoch(&payload, b.epoch());  // the epoch the owner sequenced it under
        payloads.push_back(std::move(payload));
      }
    } else {
      v1::Stroke stroke = b.stroke();
      stroke.set_object(b.object());
      auto decoded = codec::DecodeStroke(stroke, codec::ReplicaLimits(im.voxel_size));
      if (!decoded.ok()) {
        spdlog::warn("cluster: standby: broadcast stroke does not decode: {}",
                     decoded.status().ToString());
        resync();
        return Status::Ok();
      }
      const uint32_t n = static_cast<uint32_t>(decoded->edits.size());
      const uint64_t now_ms =
          static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::milliseconds>(
                                    std::chrono::system_clock::now().time_since_epoch())
                                    .count());
      for (uint32_t i = 0; i < n; ++i) {
        codec::StrokePoseRecord p;
        p.global_seq = b.global_seq_first() + i;
        p.client_id = b.client_id();
        p.client_seq = b.stroke().client_seq();
        p.object = b.object();
        p.pose_index = i;
        p.pose_count = n;
        // The owner's commit time is not in the broadcast: the time this copy logged it.
        if (i + 1 == n) p.commit_ms = commit_ms = now_ms;
        p.edit = decoded->edits[i];
        reqs.push_back(codec::AsLogged(p.edit));
        std::string payload = codec::EncodeLogRecord(p);
        codec::AppendRecordEpoch(&payload, b.epoch());  // the epoch the owner sequenced it under
        payloads.push_back(std::move(payload));
      }
    }
    if (reqs.empty()) return Status::Ok();
    const uint64_t first = b.global_seq_first();
    const uint64_t last = first + reqs.size() - 1;
    if (first <= im.seq) return Status::Ok();  // already in a region load
    SCULPT_RETURN_IF_ERROR(im.log->AppendGroup(first, payloads));
    {
      uint64_t& newest = im.resend[{static_cast<uint8_t>(ResendStream::kStrokes), author}];
      newest = std::max(newest,
                        b.records_size() > 0 ? b.records(0).client_seq() : b.stroke().client_seq());
    }
    im.records_since_snapshot += payloads.size();
    const levelset::ReplayState state{b.volume(), b.reference_volume(), b.edits_since_reinit()};
    // Recorded in the copy's undo history as the owner's Apply records it: the pre-image of
    // what it writes, under its author, at its last sequence.
    PreparedEdit prepared;
    if (im.history) {
      levelset::RestoreReplayState(*im.sculpture, state);
      prepared = im.history->Prepare(*im.sculpture, reqs, im.settings);
      prepared.wall_ms = commit_ms;
    }
    auto res = levelset::ReplayEdits(*im.sculpture, reqs, im.settings, state);
    if (res.ok() && im.history) {
      im.history->Commit(std::move(prepared), last, HistoryAuthor(author), *res, *im.sculpture);
    }
    im.seq = last;
    uint64_t actual = 0;
    if (res.ok()) actual = levelset::LeavesHash(*im.sculpture, res->dirty_leaves);
    if (!res.ok() || actual != b.leaves_hash()) {
      // Diverged: said to the owner (it counts and logs it), and the object is loaded anew,
      // which snapshots this copy past the bad edit.
      spdlog::warn("cluster: standby of scene {} diverged at seq {} ({}): loading it anew", o.scene,
                   last, res.ok() ? "leaves hash" : res.status().ToString());
      ++divergences_;
      if (o.divergences) ++*o.divergences;
      v1::ClientMessage dm;
      v1::DivergenceReport* d = dm.mutable_divergence();
      d->set_object(im.object);
      d->set_global_seq(last);
      d->set_expected_hash(b.leaves_hash());
      d->set_actual_hash(actual);
      (void)im.client->SendMessage(dm);
      resync();
    } else if (o.snapshot_every_records > 0 &&
               im.records_since_snapshot >= o.snapshot_every_records) {
      return snapshot(last);
    }
    return Status::Ok();
  };

  std::unique_lock<std::mutex> lock(mu_);
  while (!stop_) {
    cv_.wait_for(lock, std::chrono::milliseconds(100),
                 [&] { return stop_ || !queue_.empty() || superseded_; });
    if (stop_) break;
    if (queue_.empty()) {
      if (superseded_) {
        lock.unlock();
        fail("etcd names epoch " + std::to_string(expected_epoch_.load()) + " for scene " +
             o.scene + "'s owner, not the epoch " + std::to_string(o.owner_epoch) +
             " followed at " + o.owner_tcp);
        lock.lock();
        break;
      }
      if (!im.client->connected()) {
        lock.unlock();
        fail("the connection to the owner at " + o.owner_tcp + " ended");
        lock.lock();
        break;
      }
      continue;
    }
    std::unique_ptr<v1::ServerMessage> m = std::move(queue_.front());
    queue_.pop_front();
    lock.unlock();
    const Status st = apply(*m);
    lock.lock();
    if (!st.ok()) {
      lock.unlock();
      spdlog::error("cluster: standby of scene {}: {}; following stops", o.scene, st.ToString());
      fail(st.ToString());
      lock.lock();
      break;
    }
  }
  lock.unlock();
  im.client->SetReplicationHandler(nullptr);
  im.client->DropConnection();
  if (im.log) {
    (void)im.log->Sync();
    im.log->OnDurable(nullptr);  // the client goes before the log (the destructor syncs again)
  }
  finished_ = true;
}

}  // namespace sculpt::server::cluster
