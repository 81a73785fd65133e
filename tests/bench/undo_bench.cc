/// @brief sculpt-bench undo: per-user undo latency with 0, 10 and 30 later overlapping strokes by
/// others (and of a paint under 0 and 10 later overlapping paints), the cost of recording each
/// edit, and the memory an undo step holds (issue 15).
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "bench_common.h"
#include "scene/edit_history.h"
#include "sculpt/codec/paint_messages.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/materials.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::bench {
namespace {

using levelset::EditKind;
using levelset::EditRequest;

// A stroke of `poses` sphere poses along the surface of a sphere of radius R around the origin,
// starting at direction `dir`, each pose `penetration` voxels deep.
std::vector<EditRequest> SurfaceStroke(const Vec3& dir, const Vec3& tangent, double R,
                                       double tool_r, double penetration, int poses,
                                       double step, EditKind kind) {
  std::vector<EditRequest> reqs;
  for (int i = 0; i < poses; ++i) {
    Vec3 d = dir + tangent * (step * i / R);
    d = d / d.Length();
    EditRequest r;
    r.kind = kind;
    r.tool = levelset::ToolShape::Sphere(d * (R + tool_r - penetration), tool_r);
    r.speed = 30;
    r.dt = 1.0 / 120;
    r.amount = 0.5;
    reqs.push_back(r);
  }
  return reqs;
}

Vec3 Tangent(const Vec3& dir, std::mt19937_64& rng) {
  Vec3 t = RandomDirection(rng);
  t = t - dir * t.Dot(dir);
  const double l = t.Length();
  return l > 1e-6 ? t / l : Vec3{dir.y, -dir.x, 0};
}

// Paint undo: A paints a sphere of radius `tool_r` on the surface, B, C and D then paint 0 or 10
// times within two tool radii of it (other materials in turn), then A undoes. Paints move no
// tracked scalar, so an undo replays exactly the later paints whose boxes meet what it restored.
Json PaintUndo(double radius, int trials, std::mt19937_64& rng) {
  levelset::SculptureOptions so;
  so.voxel_size = 1.0;
  auto made = levelset::Sculpture::MakeSphere(so, {0, 0, 0}, radius);
  if (!made.ok()) return Json{{"error", made.status().ToString()}};
  levelset::Sculpture sculpture = std::move(made).value();
  const Status declared = levelset::SetMaterials(
      sculpture,
      {{"clay", {0.8, 0.5, 0.3}}, {"gold", {1.0, 0.85, 0.1}}, {"jade", {0.1, 0.7, 0.4}}});
  if (!declared.ok()) return Json{{"error", declared.ToString()}};
  server::EditHistory history;
  std::uniform_real_distribution<double> jitter(-1, 1);
  const double tool_r = 5;
  const char* others[3] = {"B", "C", "D"};
  uint64_t seq = 0;
  Samples paint_ms;
  Json results = Json::array();
  auto paint_at = [&](const Vec3& dir, uint32_t material) {
    codec::Paint p;
    p.object = "clay";
    p.tool = levelset::ToolKind::kSphere;
    p.tool_size = {tool_r, tool_r, tool_r};
    p.position = dir * radius;
    p.material = material;
    p.weight = 0.75;
    return p;
  };
  for (int later : {0, 10}) {
    Samples undo_ms, replayed, dirty, ratio;
    for (int t = 0; t < trials; ++t) {
      const Vec3 dir = RandomDirection(rng);
      double later_apply_ms = 0;
      auto run = [&](const std::string& author, const codec::Paint& p) -> Status {
        const auto t0 = Clock::now();
        auto res = history.ApplyPaint(sculpture, ++seq, author, p);
        const double ms = MsSince(t0);
        paint_ms.Add(ms);
        if (author != "A") later_apply_ms += ms;
        return res.status();
      };
      if (Status s = run("A", paint_at(dir, 1)); !s.ok()) return Json{{"error", s.ToString()}};
      for (int i = 0; i < later; ++i) {
        Vec3 d = dir + Tangent(dir, rng) * (jitter(rng) * 2 * tool_r / radius);
        d = d / d.Length();
        if (Status s = run(others[i % 3], paint_at(d, 2 - i % 2)); !s.ok()) {
          return Json{{"error", s.ToString()}};
        }
      }
      auto u = history.Undo(sculpture, "A");
      if (!u.ok()) return Json{{"error", u.status().ToString()}};
      undo_ms.Add(u->elapsed_ms);
      replayed.Add(u->replayed);
      dirty.Add(static_cast<double>(u->dirty_leaves.size()));
      if (later > 0) ratio.Add(u->elapsed_ms / later_apply_ms);
    }
    Progress("paint undo with %d later paints: p50 %.2f ms, p99 %.2f ms", later, undo_ms.P(0.5),
             undo_ms.P(0.99));
    results.push_back(Json{{"later_overlapping_paints", later},
                           {"trials", trials},
                           {"undo_ms", undo_ms.Summary()},
                           {"replayed_mean", replayed.Mean()},
                           {"undo_over_their_apply_time", later > 0 ? ratio.Summary() : Json()},
                           {"dirty_leaves_mean", dirty.Mean()}});
  }
  return Json{{"materials", 3},
              {"tool_radius_voxels", tool_r},
              {"weight", 0.75},
              {"later_authors", "B, C, D in turn, within two tool radii, materials 2 and 1"},
              {"paint_ms", paint_ms.Summary()},
              {"results", results}};
}

}  // namespace

Json RunUndoBench(bool quick, double radius, int trials, uint64_t seed) {
  if (quick) {
    radius = std::min(radius, 48.0);
    trials = std::min(trials, 4);
  }
  levelset::SculptureOptions so;
  so.voxel_size = 1.0;
  auto made = levelset::Sculpture::MakeSphere(so, {0, 0, 0}, radius);
  if (!made.ok()) return Json{{"error", made.status().ToString()}};
  levelset::Sculpture sculpture = std::move(made).value();
  const levelset::ValidEditSettings settings;  // the defaults
  server::EditHistory history;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> jitter(-1, 1);
  const double tool_r = 5, penetration = 2;
  const EditKind kinds[4] = {EditKind::kPress, EditKind::kPress, EditKind::kAdd,
                             EditKind::kSmooth};
  const char* others[3] = {"B", "C", "D"};
  uint64_t seq = 0;
  Samples apply_ms, record_ms, prepare_ms, commit_ms, record_bytes;
  Json results = Json::array();
  for (int later : {0, 10, 30}) {
    Samples undo_ms, replayed, dirty, ratio;
    for (int t = 0; t < trials; ++t) {
      const Vec3 dir = RandomDirection(rng);
      const Vec3 tan = Tangent(dir, rng);
      double later_apply_ms = 0;  // the kernel time of the strokes the undo will replay
      auto run = [&](const std::string& author, const std::vector<EditRequest>& reqs) {
        const auto t0 = Clock::now();
        server::PreparedEdit p = history.Prepare(sculpture, reqs, settings);
        const double prep = MsSince(t0);
        const auto t1 = Clock::now();
        auto res = levelset::ApplyEdits(sculpture, reqs, settings);
        const double applied = MsSince(t1);
        apply_ms.Add(applied);
        if (author != "A") later_apply_ms += applied;
        if (!res.ok()) return;
        const uint64_t before = history.MemoryBytes();
        const auto t2 = Clock::now();
        history.Commit(std::move(p), ++seq, author, *res, sculpture);
        const double commit = MsSince(t2);
        record_ms.Add(prep + commit);
        prepare_ms.Add(prep);
        commit_ms.Add(commit);
        if (history.MemoryBytes() > before) {
          record_bytes.Add(static_cast<double>(history.MemoryBytes() - before));
        }
      };
      run("A", SurfaceStroke(dir, tan, radius, tool_r, penetration, 4, 1.5, EditKind::kPress));
      for (int i = 0; i < later; ++i) {
        // Others' strokes across A's: start within two tool radii of it, any direction.
        Vec3 d = dir + Tangent(dir, rng) * (jitter(rng) * 2 * tool_r / radius);
        d = d / d.Length();
        run(others[i % 3], SurfaceStroke(d, Tangent(d, rng), radius, 0.8 * tool_r, penetration, 4,
                                         1.5, kinds[i % 4]));
      }
      auto u = history.Undo(sculpture, "A");
      if (!u.ok()) return Json{{"error", u.status().ToString()}};
      undo_ms.Add(u->elapsed_ms);
      replayed.Add(u->replayed);
      dirty.Add(static_cast<double>(u->dirty_leaves.size()));
      if (later > 0) ratio.Add(u->elapsed_ms / later_apply_ms);
    }
    Progress("undo with %d later strokes: p50 %.2f ms, p99 %.2f ms", later, undo_ms.P(0.5),
             undo_ms.P(0.99));
    results.push_back(Json{{"later_overlapping_strokes", later},
                           {"trials", trials},
                           {"undo_ms", undo_ms.Summary()},
                           {"replayed_mean", replayed.Mean()},
                           // Undo time over the time the same strokes took when first applied:
                           // what an undo costs in units of the kernel, on any machine.
                           {"undo_over_their_apply_time", later > 0 ? ratio.Summary() : Json()},
                           {"dirty_leaves_mean", dirty.Mean()}});
  }
  // Memory of a full undo stack: one author's 64 strokes spread over the surface.
  server::EditHistory deep;
  for (int i = 0; i < 64; ++i) {
    const Vec3 dir = RandomDirection(rng);
    auto res = deep.Apply(sculpture, ++seq, "A",
                          SurfaceStroke(dir, Tangent(dir, rng), radius, tool_r, penetration, 4,
                                        1.5, EditKind::kPress),
                          settings);
    if (!res.ok()) return Json{{"error", res.status().ToString()}};
  }
  const double object_bytes = static_cast<double>(sculpture.MemoryBytes());
  const Json paint_undo = PaintUndo(radius, trials, rng);
  return Json{
      {"sphere_radius_voxels", radius},
      {"tool_radius_voxels", tool_r},
      {"poses_per_stroke", 4},
      {"later_kinds", "press, press, add, smooth (by B, C, D in turn), tool 0.8x A's"},
      {"results", results},
      {"apply_ms", apply_ms.Summary()},
      {"record_overhead_ms", record_ms.Summary()},
      {"prepare_ms", prepare_ms.Summary()},
      {"commit_ms", commit_ms.Summary()},
      {"bytes_per_step", record_bytes.Summary()},
      {"depth_64", Json{{"steps", deep.size()},
                        {"bytes", deep.MemoryBytes()},
                        {"bytes_per_step", static_cast<double>(deep.MemoryBytes()) /
                                               static_cast<double>(std::max<size_t>(1, deep.size()))},
                        {"object_bytes", object_bytes},
                        {"ratio_to_object", static_cast<double>(deep.MemoryBytes()) / object_bytes}}},
      {"paint_undo", paint_undo}};
}

}  // namespace sculpt::bench
