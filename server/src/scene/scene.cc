/// @brief The scene actor: global order, durable log, compute thread, acks once durable.
#include "scene/scene.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <exception>
#include <filesystem>
#include <fstream>
#include <future>
#include <iterator>
#include <variant>

#include "scene/answer_once.h"
#include "scene/edit_history.h"
#include "scene/history_file.h"
#include "scene/history_replay.h"
#include "scene/models.h"
#include "scene/paint.h"
#include "scene/skins.h"
#include "sculpt/codec/frame.h"
#include "sculpt/core/check.h"
#include "sculpt/core/thread_priority.h"
#include "sculpt/hetero/model_io.h"
#include "sculpt/levelset/materials.h"
#include "sculpt/levelset/region.h"
#include "sculpt/levelset/voxelize_model.h"
#include "store/edit_log.h"
#include "store/recovery.h"
#include "store/resend_table.h"
#include "store/snapshot_store.h"

namespace sculpt::server {
namespace {

// A recovery that replayed half of min(this, snapshot_every_edits) records, or took this long,
// snapshots at once (in the background), so repeated crashes cannot stack up replay time.
constexpr uint64_t kPromptSnapshotAfterReplay = 1000;
constexpr double kPromptSnapshotAfterSeconds = 0.25;
// Stroke apply time since the last snapshot after which one is taken, however few the edits:
// start-up after a crash replays at most about this long (plus loading the snapshots).
constexpr double kMaxTailApplySeconds = 1.0;
// The join worker's nice value, as the mesher's (MeshFeed::Options::nice).
constexpr int kBackgroundNice = 10;

double NowSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// The server's wall clock, ms since 1970: when a stroke was committed (the history view).
uint64_t WallClockMs() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::milliseconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

StatusOr<levelset::Sculpture> MakeShape(const SceneConfig& scene, const ObjectConfig& o) {
  levelset::SculptureOptions opts;
  opts.voxel_size = scene.voxel_size;
  opts.half_width = scene.half_width;
  opts.name = o.name;
  if (o.primitive == "model") {
    // A composite hyperpatch model voxelised into an empty object (seed 001 §10.3): its solid
    // into the SDF, its materials into the fraction grids the scene declared.
    SCULPT_ASSIGN_OR_RETURN(levelset::Sculpture s, levelset::MakeEmptySculpture(opts));
    if (!scene.materials.empty()) {
      SCULPT_RETURN_IF_ERROR(levelset::SetMaterials(s, scene.materials));
    }
    auto model = hetero::LoadModel(o.model);
    if (!model.ok()) {
      return Status(model.status().code(),
                    "scene.objects " + o.name + ".model=" + o.model + ": " +
                        model.status().message());
    }
    auto v = levelset::VoxelizeModel(s, *model);
    if (!v.ok()) {
      return Status(v.status().code(),
                    "scene.objects " + o.name + ".model=" + o.model + ": " + v.status().message());
    }
    spdlog::info("object {}: voxelised {} ({} boundary triangles, {} voxels located) in {:.0f} ms",
                 o.name, o.model, v->boundary_triangles, v->located_voxels,
                 v->mesh_ms + v->sdf_ms + v->materials_ms);
    return s;
  }
  if (o.primitive == "sphere") return levelset::Sculpture::MakeSphere(opts, o.center, o.radius);
  if (o.primitive == "box") {
    return levelset::Sculpture::MakeBox(opts, o.center - o.size * 0.5, o.center + o.size * 0.5);
  }
  if (o.primitive == "capsule") {
    return levelset::Sculpture::MakeCapsule(opts, o.center, o.end, o.radius);
  }
  if (o.primitive == "torus") {
    return levelset::Sculpture::MakeTorus(opts, o.center, o.radius, o.minor_radius);
  }
  return Outside("scene.objects.primitive", o.primitive, "{sphere, box, capsule, torus}");
}

// Every object carries the scene's materials (uniform material 0 until painted).
StatusOr<levelset::Sculpture> MakeObject(const SceneConfig& scene, const ObjectConfig& o) {
  SCULPT_ASSIGN_OR_RETURN(levelset::Sculpture s, MakeShape(scene, o));
  if (!scene.materials.empty() && levelset::Materials(s) != scene.materials) {
    SCULPT_RETURN_IF_ERROR(levelset::SetMaterials(s, scene.materials));
  }
  return s;
}

// The mesh feed's chunking, rate cap and Draco settings from the scene file.
MeshFeed::Options MeshFeedOptions(const SceneConfig& scene) {
  MeshFeed::Options o;
  o.chunk.chunk_voxels = scene.mesh_chunk_voxels;
  o.max_rate_hz = scene.mesh_max_rate_hz;
  o.frame_pad_voxels =
      (scene.bounds_margin + 2 * scene.max_tool_size) / scene.voxel_size + 2 * scene.half_width;
  o.position_bits = scene.mesh_position_bits;
  o.speed = scene.mesh_speed;
  return o;
}

}  // namespace

Scene::Scene(const ServerConfig& config)
    : mesh_feed_(MeshFeedOptions(config.scene),
                 MeshFeed::Source{
                     [this](std::function<void()> run, std::function<void(const Status&)> fail) {
                       PostFirst("mesh snapshot", std::move(fail), std::move(run));
                     },
                     [this](const std::string& object) -> const levelset::Sculpture* {
                       auto it = sculptures_.find(object);
                       return it == sculptures_.end() ? nullptr : &it->second;
                     },
                     [this] { return applied_seq_.load(); },
                     [this] { task_stats_.failures++; },
                     // Warm the viewers' chunk cache at open: the first viewer after a restart
                     // is sent cached chunks while sculptors hold the core.
                     [this] {
                       std::vector<std::string> names;
                       for (const auto& [name, sculpture] : sculptures_) names.push_back(name);
                       return names;
                     }}),
      config_(config) {}

StatusOr<std::unique_ptr<Scene>> Scene::Open(const ServerConfig& config) {
  SCULPT_RETURN_IF_ERROR(ValidateConfig(config));
  std::unique_ptr<Scene> scene(new Scene(config));
  SCULPT_ASSIGN_OR_RETURN(scene->settings_,
                          levelset::ValidEditSettings::Validate(EditSettingsFor(config.scene)));

  store::RecoveryOptions ro;
  for (const ObjectConfig& o : config.scene.objects) ro.objects.push_back(o.name);
  ro.log.fsync.mode = config.fsync == "always" ? store::FsyncPolicy::Mode::kAlways
                                               : store::FsyncPolicy::Mode::kGroup;
  ro.log.fsync.group_ms = config.group_commit_ms;
  const SceneConfig& sc = config.scene;
  auto make_initial = [&sc](const std::string& name) -> StatusOr<levelset::Sculpture> {
    for (const ObjectConfig& o : sc.objects) {
      if (o.name == name) return MakeObject(sc, o);
    }
    return NotFound("object " + name);
  };
  auto route = [&sc](const store::LogRecord& rec) -> StatusOr<std::string> {
    SCULPT_ASSIGN_OR_RETURN(LoggedEdit e, DecodeLogRecord(rec.seq, rec.payload));
    if (auto* m = std::get_if<codec::ModelRecord>(&e.record)) return m->edit.object;
    if (e.object.empty()) {
      // A ball edit changes no object (its skin is replayed below); any object lets it pass.
      if (sc.objects.empty()) {
        return FailedPrecondition("edit log record seq " + std::to_string(rec.seq) +
                                  " (a ball edit) in a scene without objects");
      }
      return sc.objects.front().name;
    }
    return e.object;
  };
  // Strokes (a stroke's poses as one batch once all are logged), paints, sweeps and object
  // undos go through the object's undo history as live, so an undo replays to the same state.
  HistoryReplay replay(scene->settings_);
  Scene* raw_scene = scene.get();
  auto apply = [&replay, raw_scene](levelset::Sculpture& s, const store::LogRecord& rec) -> Status {
    SCULPT_ASSIGN_OR_RETURN(LoggedEdit e, DecodeLogRecord(rec.seq, rec.payload));
    EditHistory& history = raw_scene->HistoryOf(e.object.empty() ? s.name() : e.object);
    return replay.Apply(s, history, rec.seq, e.record);
  };
  // Each object's undo history as kept with the snapshot it is loaded from, before the tail
  // is replayed through it.
  ro.on_loaded = [raw_scene](const std::string& object, uint64_t snapshot_seq) {
    raw_scene->LoadHistory(object, snapshot_seq);
  };
  // Every record says the ownership epoch it was sequenced under (0 on a single process):
  // recovery refuses a log in which a stale owner wrote after a newer one.
  ro.epoch_of = [](const store::LogRecord& rec) -> StatusOr<uint64_t> {
    SCULPT_ASSIGN_OR_RETURN(codec::EditLogRecord r, codec::DecodeLogRecord(rec.seq, rec.payload));
    return codec::RecordEpoch(r);
  };
  const double t0 = NowSeconds();
  SCULPT_ASSIGN_OR_RETURN(store::RecoveredScene rec,
                          store::Recover(config.data_dir, ro, make_initial, route, apply));
  scene->sculptures_ = std::move(rec.sculptures);
  scene->log_ = std::move(rec.log);
  scene->snapshots_ = std::move(rec.snapshots);
  scene->next_seq_ = rec.last_seq + 1;
  scene->epoch_runs_ = std::move(rec.epoch_runs);
  for (const auto& [seq, epoch] : scene->epoch_runs_) {
    scene->highest_epoch_ = std::max(scene->highest_epoch_, epoch);
  }
  scene->applied_seq_ = rec.last_seq;
  scene->replication_.set_versions_floor(rec.last_seq);
  scene->replication_.set_resend_table(&scene->resend_.entries());
  // A region load to the standby carries the books as of its sequence: saved (as a snapshot
  // would) into a staging directory beside the data, read back, and removed. The owner's own
  // files are not touched.
  scene->replication_.set_book_files([raw_books = scene.get()](uint64_t seq) {
    namespace fs = std::filesystem;
    const fs::path staging = fs::path(raw_books->config_.data_dir) / ".standby-books";
    std::error_code ec;
    fs::remove_all(staging, ec);
    std::vector<std::pair<std::string, std::string>> files;
    if (!raw_books->skins_.SaveTo(staging.string(), seq) ||
        !raw_books->models_.SaveTo(staging.string(), seq)) {
      spdlog::error(
          "the books at seq {} could not be staged for the standby: its copy starts "
          "from the scene's configured skins and models",
          seq);
    } else {
      for (const fs::directory_entry& e : fs::recursive_directory_iterator(staging, ec)) {
        if (!e.is_regular_file()) continue;
        const std::string rel = fs::relative(e.path(), staging).generic_string();
        if (rel.size() > 4 && rel.compare(rel.size() - 4, 4, ".tmp") == 0) continue;
        std::ifstream in(e.path(), std::ios::binary);
        files.emplace_back(
            rel, std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()));
      }
    }
    fs::remove_all(staging, ec);
    return files;
  });
  // And the object's stroke undo history as of its sequence, as a snapshot round keeps it, so
  // the copy's snapshots carry the history this scene's would.
  scene->replication_.set_object_history([raw_scene](const std::string& object, uint64_t seq) {
    return HistoryFileBytes(raw_scene->HistoryOf(object), seq);
  });
  // Snapshots carry the fraction grids; a data directory written under other materials would
  // give replicas and viewers a declaration the objects do not hold.
  for (auto& [name, sculpture] : scene->sculptures_) {
    if (levelset::Materials(sculpture) == config.scene.materials) continue;
    if (levelset::MaterialCount(sculpture) == 0) {
      spdlog::warn("object {}: recovered without materials; declaring the scene's", name);
      SCULPT_RETURN_IF_ERROR(levelset::SetMaterials(sculpture, config.scene.materials));
      continue;
    }
    return FailedPrecondition("object " + name + " in " + config.data_dir + " holds " +
                              std::to_string(levelset::MaterialCount(sculpture)) +
                              " materials other than scene.materials (" +
                              std::to_string(config.scene.materials.size()) +
                              "): restore the scene's materials or start from a new data_dir");
  }
  scene->recovery_summary_ =
      "recovered " + std::to_string(scene->sculptures_.size()) + " object(s) at seq " +
      std::to_string(rec.last_seq) + " (" + std::to_string(rec.report.replayed_records) +
      " records replayed" +
      (rec.report.dropped_tail_bytes
           ? ", dropped a torn tail of " + std::to_string(rec.report.dropped_tail_bytes) + " bytes"
           : std::string()) +
      (rec.report.skipped_snapshots.empty()
           ? std::string()
           : ", skipped damaged snapshot(s) " + [&] {
               std::string all;
               for (const std::string& s : rec.report.skipped_snapshots) {
                 all += (all.empty() ? "" : "; ") + s;
               }
               return all;
             }()) +
      ") in " + std::to_string(NowSeconds() - t0) + " s";
  scene->skins_.set_undo_depth(scene->config_.limits.undo_depth);
  scene->models_.set_undo_depth(scene->config_.limits.undo_depth);
  SCULPT_RETURN_IF_ERROR(
      scene->skins_.Open(scene->config_.scene.skins, scene->config_.data_dir, &scene->resend_));
  SCULPT_RETURN_IF_ERROR(
      scene->models_.Open(scene->config_.scene.objects, scene->config_.data_dir));
  // One pass over the log: the newest client sequence of every complete edit (resends after a
  // restart are recognised), and the ball edits and model intents past their files.
  SCULPT_RETURN_IF_ERROR(scene->log_->ForEachFrom(0, [&](const store::LogRecord& lr) -> Status {
    SCULPT_ASSIGN_OR_RETURN(LoggedEdit e, DecodeLogRecord(lr.seq, lr.payload));
    if (e.completes) scene->resend_.Record(e.stream, e.client_id, e.client_seq);
    std::visit(
        [&](const auto& r) {
          if (!r.user.empty()) scene->NameAuthor(r.client_id, r.user);
        },
        e.record);
    if (auto* b = std::get_if<codec::BallEditRecord>(&e.record)) scene->skins_.Replay(lr.seq, *b);
    if (auto* m = std::get_if<codec::ModelRecord>(&e.record)) scene->models_.Replay(lr.seq, *m);
    if (auto* u = std::get_if<codec::UndoRecord>(&e.record)) {
      if (u->target_book == codec::kUndoModelBook) scene->models_.ReplayUndo(lr.seq, *u);
      if (u->target_book == codec::kUndoSkinBook) scene->skins_.ReplayUndo(lr.seq, *u);
    }
    return Status::Ok();
  }));
  // Resends of edits whose records were dropped with the log before the last snapshot.
  const std::string table_path =
      (std::filesystem::path(config.data_dir) / store::kResendTableFile).string();
  if (auto table = store::LoadResendTable(table_path); table.ok()) {
    for (const auto& [key, client_seq] : table->last) {
      if (key.first > static_cast<uint8_t>(ResendStream::kUndos)) continue;
      scene->resend_.Record(static_cast<ResendStream>(key.first), key.second, client_seq);
    }
  } else if (table.status().code() != Status::Code::kNotFound) {
    spdlog::error("{}; resends of edits before seq {} may be applied again",
                  table.status().ToString(), scene->log_->base_seq());
  } else if (scene->log_->base_seq() > 0) {
    spdlog::warn("{} is missing but the log starts after seq {}: resends of edits before it may "
                 "be applied again", table_path, scene->log_->base_seq());
  }
  {
    // Snapshots that loaded are a complete round: the next complete round trims up to it.
    uint64_t oldest = UINT64_MAX;
    for (const auto& [object, seq] : rec.snapshot_seq) oldest = std::min(oldest, seq);
    scene->last_round_seq_ = oldest == UINT64_MAX ? 0 : oldest;
  }
  scene->last_snapshot_time_ = NowSeconds();
  {
    std::lock_guard<std::mutex> lock(scene->info_mu_);
    scene->RefreshInfoLocked();
  }
  {
    AckGate::Options gate;
    gate.sync = config.cluster.enabled() && config.cluster.replication == "sync";
    gate.fallback = std::chrono::milliseconds(config.cluster.sync_fallback_ms);
    scene->acks_ = std::make_unique<AckGate>(std::move(gate));
  }
  Scene* raw = scene.get();
  scene->log_->OnDurable([raw](uint64_t d) { raw->ReleaseDurable(d); });
  // Replayed edits count towards the next snapshot, and a long replay snapshots right away (the
  // clone on the compute thread, the write in the background): otherwise a server killed more
  // often than it reaches snapshot_every_edits replays an ever longer tail at each start.
  scene->edits_since_snapshot_ = rec.report.replayed_records;
  scene->tail_apply_s_ = NowSeconds() - t0;
  scene->thread_ = std::thread([raw] { raw->Run(); });
  scene->join_worker_ = std::thread([raw] { raw->JoinLoop(); });
  const uint64_t every = config.snapshot_every_edits > 0 ? config.snapshot_every_edits
                                                         : kPromptSnapshotAfterReplay;
  const bool snapshots_on = config.snapshot_every_edits > 0 || config.snapshot_every_seconds > 0;
  if (snapshots_on && rec.report.replayed_records > 0 &&
      (rec.report.replayed_records >= std::min(every, kPromptSnapshotAfterReplay) / 2 ||
       NowSeconds() - t0 >= kPromptSnapshotAfterSeconds)) {
    raw->Post("snapshot after replay", [raw] { raw->MaybeSnapshot(/*force=*/true); });
  }
  scene->mesh_feed_.Start();
  return scene;
}

Scene::~Scene() {
  mesh_feed_.Stop();  // the mesher first: it waits on jobs of the compute thread
  {
    std::lock_guard<std::mutex> lock(jobs_mu_);
    stop_ = true;
  }
  jobs_cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  {
    // After the compute thread, whose join tasks feed the worker: the join being serialised
    // finishes, the ones still queued are answered Unavailable.
    std::lock_guard<std::mutex> lock(join_mu_);
    join_stop_ = true;
  }
  join_cv_.notify_all();
  if (join_worker_.joinable()) join_worker_.join();
  if (log_) {
    (void)log_->Sync();
    log_->OnDurable(nullptr);
  }
  if (snapshots_) (void)snapshots_->WaitIdle();
  // Its timer thread may answer (a fall-back) until it is gone: it goes before the members its
  // answers read.
  acks_.reset();
}

namespace {
thread_local uint64_t current_requester = 0;
}  // namespace

Scene::RequesterScope::RequesterScope(uint64_t requester) : previous_(current_requester) {
  current_requester = requester;
}

Scene::RequesterScope::~RequesterScope() { current_requester = previous_; }

uint64_t Scene::CurrentRequester() { return current_requester; }

void Scene::Post(const char* operation, std::function<void(const Status&)> fail,
                 std::function<void()> run) {
  Post(FairQueue<Job>::kSystem, operation, std::move(fail), std::move(run));
}

void Scene::Post(uint64_t requester, const char* operation,
                 std::function<void(const Status&)> fail, std::function<void()> run) {
  {
    std::lock_guard<std::mutex> lock(jobs_mu_);
    jobs_.Push(requester, {operation, std::move(run), std::move(fail)});
    queue_depth_.store(jobs_.size(), std::memory_order_relaxed);
  }
  jobs_cv_.notify_one();
}

void Scene::PostFirst(const char* operation, std::function<void(const Status&)> fail,
                      std::function<void()> run) {
  {
    std::lock_guard<std::mutex> lock(jobs_mu_);
    jobs_.PushPriority({operation, std::move(run), std::move(fail)});
    queue_depth_.store(jobs_.size(), std::memory_order_relaxed);
  }
  jobs_cv_.notify_one();
}

void Scene::InjectTaskFaultForTesting(std::function<void(const std::string&)> hook) {
  mesh_feed_.InjectFaultForTesting(hook);
  std::lock_guard<std::mutex> lock(jobs_mu_);
  fault_hook_ = std::move(hook);
}

namespace {

// What a requester of a task that threw is told: the operation as the field's value, so a client
// sees which request failed; the exception's text stays in the server log.
Status TaskFailed(const char* operation) {
  return Outside("compute_task", operation,
                 "tasks that completed: it threw (logged by the server, which keeps serving)",
                 Status::Code::kInternal);
}

// Runs `fn`; an exception from it is logged, counted and returned as TaskFailed.
template <typename Fn>
Status RunGuarded(const char* thread, const char* operation, Scene::TaskStats& stats, Fn&& fn) {
  std::string what;
  try {
    fn();
    return Status::Ok();
  } catch (const std::exception& e) {
    what = e.what();
  } catch (...) {
    what = "an exception of unknown type";
  }
  stats.failures++;
  spdlog::error("{}: task '{}' threw: {}; its requester gets INTERNAL, the thread serves on",
                thread, operation, what);
  return TaskFailed(operation);
}

}  // namespace

void Scene::Run() {
  for (;;) {
    Job job;
    std::function<void(const std::string&)> hook;
    {
      std::unique_lock<std::mutex> lock(jobs_mu_);
      jobs_cv_.wait(lock, [this] { return stop_ || !jobs_.empty(); });
      if (jobs_.empty()) return;  // stop_ and drained
      uint64_t requester = 0;
      job = jobs_.Pop(&requester);
      queue_depth_.store(jobs_.size(), std::memory_order_relaxed);
      task_stats_.passed_over.store(jobs_.passed_over(), std::memory_order_relaxed);
      task_stats_.waiting_sessions.store(jobs_.waiting_requesters(), std::memory_order_relaxed);
      if (fault_hook_) hook = fault_hook_;
    }
    // The job's wall time is what it kept every other requester waiting: its requester's cost.
    const auto started = std::chrono::steady_clock::now();
    // The exception boundary: OpenVDB (and allocation) may throw from any task. The scene's
    // members stay as the task left them and its requester is told it failed. An edit that threw
    // after reaching the log is still in the log, so the next recovery applies it even though
    // the live scene may lack it: the log stays the truth.
    const Status s = RunGuarded("compute thread", job.operation, task_stats_, [&] {
      if (hook) hook(job.operation);
      job.run();
    });
    if (!s.ok() && job.fail) {
      (void)RunGuarded("compute thread", job.operation, task_stats_, [&] { job.fail(s); });
    }
    const auto cost = std::chrono::duration_cast<std::chrono::nanoseconds>(
        std::chrono::steady_clock::now() - started);
    std::lock_guard<std::mutex> lock(jobs_mu_);
    jobs_.Done(static_cast<uint64_t>(cost.count()));
  }
}

// A stroke: its poses' records are built and checked against the object first, so a stroke is
// refused whole before anything reaches the log; then they are applied as one batch (one block,
// one compensation, one reinitialisation), from the records, exactly as recovery and replicas
// apply them.
struct Scene::StrokeOp final : EditOp {
  StrokeOp(uint64_t client, codec::DecodedStroke s, StrokeDone d)
      : client(client), stroke(std::move(s)), done(std::move(d)) {}
  const char* operation() const override { return "stroke"; }
  ResendStream stream() const override { return ResendStream::kStrokes; }
  uint64_t client_id() const override { return client; }
  uint64_t client_seq() const override { return stroke.client_seq; }

  Status Prepare(Scene& scene, uint64_t first_seq, std::vector<std::string>* records) override {
    last_seq = first_seq + stroke.edits.size() - 1;
    auto it = scene.sculptures_.find(stroke.object);
    if (it == scene.sculptures_.end()) {
      return Outside("Stroke.object", stroke.object, "the scene's objects",
                     Status::Code::kNotFound);
    }
    const uint32_t n = static_cast<uint32_t>(stroke.edits.size());
    batch.reserve(n);
    for (uint32_t i = 0; i < n; ++i) {
      codec::StrokePoseRecord r;
      r.global_seq = first_seq + i;
      r.client_id = client;
      r.client_seq = stroke.client_seq;
      r.object = stroke.object;
      r.pose_index = i;
      r.pose_count = n;
      if (i + 1 == n) r.commit_ms = commit_ms = WallClockMs();
      r.edit = stroke.edits[i];
      // Applied as logged (float-rounded), exactly as recovery and replicas replay it.
      batch.push_back(codec::AsLogged(r.edit));
      SCULPT_RETURN_IF_ERROR(levelset::ValidateEditRequest(it->second, batch.back(),
                                                           scene.settings_));
      records->push_back(codec::EncodeLogRecord(r));
    }
    return CheckWork(it->second, scene.settings_, scene.config_.limits.max_stroke_work);
  }

  // A job is never interrupted: a stroke of several poses may ask at most `limit` voxel-poses
  // of kernel work (its poses times the voxels of the block they read), so one client's stroke
  // keeps the others waiting for a bounded time. The refusal says how many of its poses fit.
  Status CheckWork(const levelset::Sculpture& sculpture, const levelset::EditSettings& settings,
                   uint64_t limit) const {
    const size_t n = batch.size();
    if (n <= 1 || Work(sculpture, settings, n) <= limit) return Status::Ok();
    size_t fit = 1;
    while (fit + 1 < n && Work(sculpture, settings, fit + 1) <= limit) ++fit;
    return Outside("Stroke.pose_count",
                   std::to_string(n) + " poses asking " +
                       std::to_string(Work(sculpture, settings, n)) + " voxel-poses",
                   "poses x block voxels <= " + std::to_string(limit) +
                       " (limits.max_stroke_work); split the stroke: its first " +
                       std::to_string(fit) + " poses fit",
                   Status::Code::kResourceExhausted);
  }
  // The kernel work of the batch's first `poses` poses, in voxel-poses.
  uint64_t Work(const levelset::Sculpture& sculpture, const levelset::EditSettings& settings,
                size_t poses) const {
    const std::vector<levelset::EditRequest> first(batch.begin(), batch.begin() + poses);
    const levelset::EditFootprint f = levelset::FootprintOf(sculpture, first, settings);
    auto side = [](int lo, int hi) { return static_cast<uint64_t>(std::max(0, hi - lo + 1)); };
    return side(f.min.x, f.max.x) * side(f.min.y, f.max.y) * side(f.min.z, f.max.z) * poses;
  }

  Applied Apply(Scene& scene) override {
    levelset::Sculpture& sculpture = scene.sculptures_.at(stroke.object);
    Applied a;
    a.object = stroke.object;
    a.bounds_may_change = true;
    Applied::Replay replay;
    replay.source = &stroke.source;
    replay.before = levelset::CaptureReplayState(sculpture);
    replay.footprint = levelset::FootprintOf(sculpture, batch, scene.settings_);
    // Recorded in the object's undo history (the pre-image of what it writes), as recovery
    // records it.
    auto res =
        scene.HistoryOf(stroke.object)
            .Apply(sculpture, last_seq, HistoryAuthor(client), batch, scene.settings_, commit_ms);
    if (res.ok()) {
      result = std::move(res).value();
      a.dirty_leaves = result.dirty_leaves;
      a.replay = replay;
    } else {
      // Logged and refused by the kernel, as recovery will refuse it: nothing changed.
      a.status = res.status();
    }
    return a;
  }

  void Answer(const CommitOutcome& o) override {
    StrokeOutcome out;
    out.client_seq = o.client_seq;
    out.duplicate = o.duplicate;
    out.global_seq_first = o.global_seq_first;
    out.edits = o.records;
    // A stroke the kernel refused after logging counts as applied, as it always has: the log is
    // the truth and replays it identically.
    if (o.records == 0) out.status = o.status;
    out.last = std::move(result);
    done(out);
  }

  uint64_t client;
  codec::DecodedStroke stroke;
  StrokeDone done;
  uint64_t last_seq = 0;
  uint64_t commit_ms = 0;  // logged with the last pose: the history view's time
  std::vector<levelset::EditRequest> batch;
  levelset::EditResult result;
};

void Scene::Submit(uint64_t client_id, codec::DecodedStroke stroke, StrokeDone done) {
  Commit(std::make_shared<StrokeOp>(client_id, std::move(stroke), AnswerOnce(std::move(done))));
}

size_t Scene::acks_awaiting_durability() const { return acks_->held(); }

LatencyHistogram::Snapshot Scene::log_sync_seconds() const { return log_->sync_seconds(); }

void Scene::ReleaseDurable(uint64_t durable_seq) { acks_->LocalDurable(durable_seq); }

void Scene::MaybeSnapshot(bool force) {
  const bool by_count = (force && edits_since_snapshot_ > 0) ||
                        (config_.snapshot_every_edits > 0 &&
                         edits_since_snapshot_ >= config_.snapshot_every_edits);
  const bool by_time = config_.snapshot_every_seconds > 0 && edits_since_snapshot_ > 0 &&
                       NowSeconds() - last_snapshot_time_ >= config_.snapshot_every_seconds;
  // Replay repeats the live apply, so the apply time since the snapshot bounds start-up after a
  // crash: past kMaxTailApplySeconds a snapshot is due whatever the edit count says.
  const bool by_cost = (config_.snapshot_every_edits > 0 || config_.snapshot_every_seconds > 0) &&
                       edits_since_snapshot_ > 0 && tail_apply_s_ >= kMaxTailApplySeconds;
  if (!by_count && !by_time && !by_cost) return;
  const uint64_t seq = next_seq_ - 1;
  // A snapshot must never hold an edit the log could still lose (group commit): sync first.
  if (const Status s = log_->Sync(); !s.ok()) {
    spdlog::error("edit log sync before snapshot failed: {}", s.ToString());
    return;
  }
  // The resend table, skins and models at `seq` are durable before the round can let the log
  // go; a round with any failure trims nothing.
  const bool side_files_saved =
      SaveResendTable(seq) & models_.Save(seq) & skins_.Save(seq);
  struct Round {
    std::atomic<size_t> remaining;
    std::atomic<bool> failed;
  };
  auto round = std::make_shared<Round>();
  round->remaining = sculptures_.size();
  round->failed = !side_files_saved;
  for (auto& [name, sculpture] : sculptures_) {
    // The clone and the undo history's bytes are the only work on the compute thread; the
    // writes happen in the background, the history's after its snapshot's.
    auto history = std::make_shared<const std::string>(HistoryFileBytes(HistoryOf(name), seq));
    snapshots_->WriteAsync(seq, name, sculpture.Clone(),
                           [this, seq, name = name, round, history](Status s) {
      if (s.ok()) s = WriteHistoryFile(config_.data_dir, name, seq, *history);
      // kUnavailable: superseded by a newer snapshot before it was written, which is fine.
      if (!s.ok() && s.code() != Status::Code::kUnavailable) {
        spdlog::warn("snapshot of {} at seq {} failed: {}", name, seq, s.ToString());
      }
      if (!s.ok()) round->failed = true;
      if (--round->remaining == 0 && !round->failed) OnSnapshotRoundDurable(seq);
    });
  }
  log_->Roll();
  edits_since_snapshot_ = 0;
  tail_apply_s_ = 0;
  last_snapshot_time_ = NowSeconds();
}

bool Scene::SaveResendTable(uint64_t seq) {
  store::ResendTable table;
  table.seq = seq;
  for (const auto& [key, client_seq] : resend_.entries()) {
    if (client_seq > 0) table.last[key] = client_seq;
  }
  const std::string path =
      (std::filesystem::path(config_.data_dir) / store::kResendTableFile).string();
  if (const Status s = store::SaveResendTable(path, table); !s.ok()) {
    spdlog::error("resend table at seq {} not saved (the log is kept): {}", seq, s.ToString());
    return false;
  }
  return true;
}

void Scene::OnSnapshotRoundDurable(uint64_t seq) {
  // Runs on the snapshot writer thread.
  uint64_t drop_to = 0;
  {
    std::lock_guard<std::mutex> lock(trim_mu_);
    if (seq <= last_round_seq_) return;
    drop_to = last_round_seq_;
    last_round_seq_ = seq;
  }
  if (drop_to == 0) return;
  if (const Status s = log_->DropSegmentsBefore(drop_to); !s.ok()) {
    spdlog::warn("edit log trim up to seq {} failed (retried at the next snapshot): {}", drop_to,
                 s.ToString());
  }
}

void Scene::RefreshInfoLocked() {
  SceneSummary& info = info_;
  info.scene = config_.scene.name;
  info.global_seq = applied_seq_.load();
  info.min_tool_size = config_.scene.min_tool_size;
  info.max_tool_size = config_.scene.max_tool_size;
  info.max_speed = config_.scene.max_speed;
  info.edit_settings = settings_;
  info.replica_halo_voxels = kReplicaHaloVoxels;
  info.effects = config_.scene.effects;
  info.materials = config_.scene.materials;
  info.objects.clear();
  for (auto& [name, s] : sculptures_) {
    ObjectSummary& o = info.objects.emplace_back();
    o.name = name;
    o.voxel_size = s.voxel_size();
    o.half_width = static_cast<uint32_t>(s.half_width());
    auto b = bounds_.find(name);
    o.bounds = b != bounds_.end() ? b->second : s.WorldBounds();
    if (b == bounds_.end()) bounds_[name] = o.bounds;
    o.volume = s.volume();
    o.reference_volume = s.reference_volume();
  }
  info.skins.clear();
  for (const SkinConfig& k : config_.scene.skins) {
    info.skins.push_back({k.name, k.origin, k.u, k.v});
  }
}

SceneSummary Scene::Info() const {
  std::lock_guard<std::mutex> lock(info_mu_);
  return info_;
}

StatusOr<codec::StrokeLimits> Scene::LimitsFor(const std::string& object) const {
  std::lock_guard<std::mutex> lock(info_mu_);
  auto b = bounds_.find(object);
  if (b == bounds_.end()) {
    return Outside("Stroke.object", object, "the scene's objects", Status::Code::kNotFound);
  }
  codec::StrokeLimits l;
  l.voxel_size = config_.scene.voxel_size;
  l.max_poses = config_.limits.max_poses_per_stroke;
  l.min_tool_size = config_.scene.min_tool_size;
  l.max_tool_size = config_.scene.max_tool_size;
  l.max_speed = config_.scene.max_speed;
  l.max_amount = config_.scene.max_amount;
  l.bounds = b->second;
  l.bounds_margin = config_.scene.bounds_margin;
  return l;
}

size_t Scene::pending_joins() const {
  std::lock_guard<std::mutex> lock(join_mu_);
  return joins_pending_;
}

void Scene::RequestJoinState(std::function<void(StatusOr<JoinState>)> done, uint64_t client_id) {
  const size_t limit = config_.limits.max_pending_joins;
  {
    std::unique_lock<std::mutex> lock(join_mu_);
    if (join_stop_) {
      lock.unlock();
      return done(Status(Status::Code::kUnavailable, "scene is shutting down"));
    }
    if (joins_pending_ >= limit) {
      const size_t wanted = joins_pending_ + 1;
      lock.unlock();
      task_stats_.joins_refused++;
      return done(Outside("limits.max_pending_joins", std::to_string(wanted),
                          std::string("[1, ") + std::to_string(limit) +
                              "] late joins prepared at once; join again shortly",
                          Status::Code::kResourceExhausted));
    }
    ++joins_pending_;
  }
  // Answered exactly once, by whichever step ends the join; the slot is free before the answer
  // goes out, so a joiner that retries at once finds it.
  auto answer = AnswerOnce(std::function<void(StatusOr<JoinState>)>(
      [this, done = std::move(done)](StatusOr<JoinState> result) {
        {
          std::lock_guard<std::mutex> lock(join_mu_);
          --joins_pending_;
        }
        done(std::move(result));
      }));
  auto fail = [answer](const Status& st) { answer(st); };
  Post(CurrentRequester(), "join state copy", fail, [this, answer, fail, client_id] {
    // Only the deep copies happen on the compute thread (milliseconds); serialising them waits
    // for the join worker, so a late joiner never stalls the others' edits.
    auto info = std::make_shared<SceneSummary>();
    {
      std::lock_guard<std::mutex> lock(info_mu_);
      *info = info_;
    }
    auto copies = std::make_shared<std::vector<std::pair<std::string, levelset::Sculpture>>>();
    for (auto& [name, s] : sculptures_) copies->emplace_back(name, s.Clone());
    std::array<uint64_t, kResendStreams> committed{};
    for (size_t i = 0; i < kResendStreams; ++i) {
      committed[i] = resend_.CommittedUpTo(static_cast<ResendStream>(i), client_id);
    }
    JoinWork work;
    work.fail = fail;
    work.run = [answer, info, copies, committed](bool cancelled) {
      if (cancelled) return answer(Status(Status::Code::kUnavailable, "scene is shutting down"));
      JoinState js;
      js.info = *info;
      js.committed_up_to = committed;
      for (size_t i = 0; i < copies->size(); ++i) {
        auto& [name, copy] = (*copies)[i];
        auto bytes = copy.SerializeVdb();
        if (!bytes.ok()) return answer(bytes.status());
        js.objects.emplace_back(name, std::move(bytes).value());
        js.info.objects[i].state_hash = copy.StateHash();
      }
      answer(std::move(js));
    };
    {
      std::lock_guard<std::mutex> lock(join_mu_);
      join_queue_.push_back(std::move(work));
    }
    join_cv_.notify_one();
  });
}

void Scene::JoinLoop() {
  // Serialising an object for a late joiner is background work, like meshing for viewers:
  // where it shares a core with the compute thread, the edits get the larger share, so a flood
  // of joins slows the joins, not the sculptors.
  if (const Status s = LowerThreadPriority(kBackgroundNice); !s.ok()) {
    spdlog::warn("join worker: nice {} not applied: {}", kBackgroundNice, s.message());
  }
  for (;;) {
    JoinWork job;
    std::function<void(const std::string&)> hook;
    bool cancelled = false;
    {
      std::unique_lock<std::mutex> lock(join_mu_);
      join_cv_.wait(lock, [this] { return join_stop_ || !join_queue_.empty(); });
      if (join_queue_.empty()) return;  // stopped and drained
      job = std::move(join_queue_.front());
      join_queue_.pop_front();
      cancelled = join_stop_;
    }
    {
      std::lock_guard<std::mutex> lock(jobs_mu_);
      if (fault_hook_) hook = fault_hook_;
    }
    // A serialisation that throws is answered Internal (AnswerOnce drops a second answer).
    const Status s = RunGuarded("join worker", "join state serialisation", task_stats_, [&] {
      if (hook && !cancelled) hook("join state serialisation");
      job.run(cancelled);
    });
    if (!s.ok()) {
      (void)RunGuarded("join worker", "join state serialisation", task_stats_,
                       [&] { job.fail(s); });
    }
  }
}

void Scene::Flush() {
  std::promise<void> applied;
  // Each of these tasks sets its promise as its last step, so `fail` runs only when it did not.
  auto fail = [&applied](const Status&) { applied.set_value(); };
  Post("flush", fail, [&applied] { applied.set_value(); });
  applied.get_future().wait();
  (void)log_->Sync();
  ReleaseDurable(log_->durable_seq());
  if (snapshots_) (void)snapshots_->WaitIdle();
}

void Scene::FlushAndSnapshot() {
  std::promise<void> taken;
  auto fail = [&taken](const Status&) { taken.set_value(); };
  Post("snapshot", fail, [this, &taken] {
    MaybeSnapshot(/*force=*/true);
    taken.set_value();
  });
  taken.get_future().wait();
  Flush();
}

uint64_t Scene::StateHash(const std::string& object) {
  std::promise<uint64_t> p;
  auto fail = [&p](const Status&) { p.set_value(0); };
  Post("state hash", fail, [&] {
    auto it = sculptures_.find(object);
    p.set_value(it == sculptures_.end() ? 0 : it->second.StateHash());
  });
  return p.get_future().get();
}

// ---------------------------------------------------------------------------------------------
// Replicas and viewers: requests onto the compute thread, answered by the replication hub and the
// mesh feed there.

void Scene::Subscribe(ReplicaSink sink, codec::ReplicaSubscription req,
                      std::function<void(Status)> done) {
  auto once = AnswerOnce(std::move(done));
  auto fail = [once](const Status& st) { once(st); };
  Post(CurrentRequester(), "subscribe", fail,
       [this, sink = std::move(sink), req = std::move(req), once]() mutable {
         auto it = sculptures_.find(req.object);
         replication_.Subscribe(std::move(sink), req,
                                it == sculptures_.end() ? nullptr : &it->second,
                                applied_seq_.load(), once);
       });
}

void Scene::SetInterest(uint64_t session_id, codec::InterestChange req,
                        std::function<void(Status)> done) {
  auto once = AnswerOnce(std::move(done));
  auto fail = [once](const Status& st) { once(st); };
  Post(CurrentRequester(), "set interest", fail, [this, session_id, req = std::move(req), once] {
    auto it = sculptures_.find(req.object);
    replication_.SetInterest(session_id, req, it == sculptures_.end() ? nullptr : &it->second,
                             applied_seq_.load(), once);
  });
}

void Scene::Unsubscribe(uint64_t session_id) {
  Post(CurrentRequester(), "unsubscribe", [this, session_id] {
    replication_.Unsubscribe(session_id);
  });
}

void Scene::ReportDivergence(uint64_t session_id, const codec::Divergence& report) {
  replication_.ReportDivergence(session_id, report);
}

uint64_t Scene::RegionHash(const std::string& object, const levelset::VoxelBox& box) {
  std::promise<uint64_t> p;
  auto fail = [&p](const Status&) { p.set_value(0); };
  Post("region hash", fail, [&] {
    auto it = sculptures_.find(object);
    p.set_value(it == sculptures_.end() ? 0 : levelset::RegionHash(it->second, box));
  });
  return p.get_future().get();
}

void Scene::SubscribeViewer(ReplicaSink sink, codec::ViewerSubscription req,
                            std::function<void(Status)> done) {
  auto once = AnswerOnce(std::move(done));
  auto fail = [once](const Status& st) { once(st); };
  Post(CurrentRequester(), "viewer", fail,
       [this, sink = std::move(sink), req = std::move(req), once]() mutable {
         auto it = sculptures_.find(req.object);
         once(mesh_feed_.AddViewer(std::move(sink), req,
                                   it == sculptures_.end() ? nullptr : &it->second));
       });
}

void Scene::UnsubscribeViewer(uint64_t session_id) {
  Post(CurrentRequester(), "viewer unsubscribe",
       [this, session_id] { mesh_feed_.RemoveViewer(session_id); });
}

bool Scene::Inspect(const std::string& object,
                    const std::function<void(const levelset::Sculpture&)>& fn) {
  std::promise<bool> p;
  auto fail = [&p](const Status&) { p.set_value(false); };
  Post("inspect", fail, [&] {
    auto it = sculptures_.find(object);
    if (it != sculptures_.end()) fn(it->second);
    p.set_value(it != sculptures_.end());
  });
  return p.get_future().get();
}

}  // namespace sculpt::server
