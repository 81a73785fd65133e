/// @brief The scripted in-process sculpting session of `sculpt demo`.
#include "demo.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <vector>

#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::client {
namespace {

using levelset::EditKind;
using levelset::EditRequest;
using levelset::ToolShape;

struct Totals {
  int edits = 0;
  double ms = 0;
  double max_ms = 0;
  uint64_t changed_voxels = 0;
  int reinit_passes = 0;
  int islands_found = 0;
};

}  // namespace

Status RunDemo(const DemoOptions& o) {
  std::error_code ec;
  std::filesystem::create_directories(o.out_dir, ec);
  if (ec) return Internal("cannot create output folder " + o.out_dir + ": " + ec.message());

  levelset::SculptureOptions so;
  so.voxel_size = o.voxel_size;
  so.name = "demo-sphere";
  const Vec3 center{0, 0, 0};
  SCULPT_ASSIGN_OR_RETURN(levelset::Sculpture sculpture,
                          levelset::Sculpture::MakeSphere(so, center, o.radius));
  const double v0 = sculpture.volume();
  const uint64_t hash0 = sculpture.StateHash();
  spdlog::info("scene: sphere r={} voxel={} -> {} active voxels, volume {:.2f}", o.radius,
               o.voxel_size, sculpture.ActiveVoxelCount(), v0);

  levelset::EditSettings settings;  // shell compensation, upwind/RK2, Eikonal-triggered reinit
  settings.islands = levelset::IslandPolicy::kRemoveSmall;
  settings.min_island_volume = 4.0 * std::pow(o.voxel_size, 3) * 64;

  nlohmann::json edits = nlohmann::json::array();
  Totals totals;
  auto apply = [&](const char* label, const EditRequest& r) -> Status {
    SCULPT_ASSIGN_OR_RETURN(levelset::EditResult res, levelset::ApplyEdit(sculpture, r, settings));
    ++totals.edits;
    totals.ms += res.elapsed_ms;
    totals.max_ms = std::max(totals.max_ms, res.elapsed_ms);
    totals.changed_voxels += res.changed_voxels;
    totals.reinit_passes += res.reinit_passes;
    totals.islands_found += res.islands_found;
    edits.push_back({{"label", label},
                     {"kind", levelset::EditKindName(r.kind)},
                     {"changed_voxels", res.changed_voxels},
                     {"dirty_leaves", res.dirty_leaves.size()},
                     {"volume_before", res.volume_before},
                     {"volume_after", res.volume_after},
                     {"substeps", res.substeps},
                     {"reinit_passes", res.reinit_passes},
                     {"compensation_iterations", res.compensation_iterations},
                     {"islands_removed", res.islands_removed},
                     {"elapsed_ms", res.elapsed_ms}});
    return Status::Ok();
  };

  // 1. A finger dragged around the equator and up a meridian: press samples at 120 Hz.
  const double tool_r = 2.5;
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < o.strokes; ++i) {
    const double t = static_cast<double>(i) / o.strokes;
    const double a = 2 * M_PI * t;
    const double lift = 0.35 * std::sin(4 * a);  // a wavy groove
    const Vec3 dir{std::cos(a) * std::cos(lift), std::sin(a) * std::cos(lift), std::sin(lift)};
    const double depth = 1.2 + jitter(rng);
    EditRequest r;
    r.kind = EditKind::kPress;
    r.tool = ToolShape::Sphere(dir * (o.radius + tool_r - depth), tool_r);
    r.speed = 60.0;  // mm/s
    r.dt = 1.0 / 120.0;
    SCULPT_RETURN_IF_ERROR(apply("groove", r));
    if ((i + 1) % 60 == 0) {
      spdlog::info("groove {}/{}: volume {:.2f} (reference {:.2f})", i + 1, o.strokes,
                   sculpture.volume(), sculpture.reference_volume());
    }
  }
  // 2. A hole drilled through the north pole with a capsule, a knob added on the south pole.
  {
    EditRequest r;
    r.kind = EditKind::kSubtract;
    r.tool = ToolShape::Capsule({0, 0, o.radius * 0.55}, {0, 0, o.radius * 1.2}, 3.0);
    SCULPT_RETURN_IF_ERROR(apply("hole", r));
    r.kind = EditKind::kAdd;
    r.tool = ToolShape::Sphere({0, 0, -o.radius - 2.0}, 5.0);
    SCULPT_RETURN_IF_ERROR(apply("knob", r));
  }
  // 3. Smooth the seam of the knob, inflate a cheek, deflate the other.
  {
    EditRequest r;
    r.kind = EditKind::kSmooth;
    r.tool = ToolShape::Sphere({0, 0, -o.radius + 1.0}, 5.0);
    r.amount = 2.0;
    SCULPT_RETURN_IF_ERROR(apply("smooth-knob", r));
    r.kind = EditKind::kInflate;
    r.tool = ToolShape::Ellipsoid({o.radius * 0.7, -o.radius * 0.7, 0}, {6, 4, 4});
    r.amount = 1.5;
    SCULPT_RETURN_IF_ERROR(apply("inflate-cheek", r));
    r.kind = EditKind::kDeflate;
    r.tool = ToolShape::Ellipsoid({-o.radius * 0.7, o.radius * 0.7, 0}, {6, 4, 4});
    SCULPT_RETURN_IF_ERROR(apply("deflate-cheek", r));
  }
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  const double recomputed = sculpture.ComputeVolume();
  const Status check = sculpture.CheckLevelSet();
  const std::string vdb = o.out_dir + "/sculpture.vdb";
  const std::string ply = o.out_dir + "/sculpture.ply";
  SCULPT_RETURN_IF_ERROR(sculpture.SaveVdb(vdb));
  SCULPT_ASSIGN_OR_RETURN(levelset::MeshStats mesh, sculpture.ExportMesh(ply));

  char hash_hex[17], hash0_hex[17];
  std::snprintf(hash_hex, sizeof hash_hex, "%016llx",
                static_cast<unsigned long long>(sculpture.StateHash()));
  std::snprintf(hash0_hex, sizeof hash0_hex, "%016llx", static_cast<unsigned long long>(hash0));
  nlohmann::json summary = {
      {"scene", {{"primitive", "sphere"}, {"radius", o.radius}, {"voxel_size", o.voxel_size},
                 {"half_width_voxels", sculpture.half_width()}}},
      {"volume_before", v0},
      {"volume_after", sculpture.volume()},
      {"volume_after_recomputed", recomputed},
      {"reference_volume", sculpture.reference_volume()},
      {"press_volume_drift_rel", (sculpture.volume() - sculpture.reference_volume()) /
                                     sculpture.reference_volume()},
      {"edits", totals.edits},
      {"edit_ms_mean", totals.ms / std::max(1, totals.edits)},
      {"edit_ms_max", totals.max_ms},
      {"wall_seconds", wall_s},
      {"changed_voxels", totals.changed_voxels},
      {"reinit_passes", totals.reinit_passes},
      {"islands_found", totals.islands_found},
      {"active_voxels", sculpture.ActiveVoxelCount()},
      {"level_set_check", check.ok() ? "clean" : check.message()},
      {"state_hash_before", hash0_hex},
      {"state_hash", hash_hex},
      {"mesh", {{"file", "sculpture.ply"}, {"vertices", mesh.vertices}, {"triangles", mesh.triangles}}},
      {"vdb", "sculpture.vdb"},
      {"edit_log", edits}};
  std::ofstream out(o.out_dir + "/summary.json");
  out << summary.dump(2) << '\n';
  if (!out) return Internal("cannot write " + o.out_dir + "/summary.json");
  spdlog::info("{} edits in {:.2f} s (mean {:.2f} ms, max {:.2f} ms); volume {:.2f} -> {:.2f} "
               "(reference {:.2f}); level set {}",
               totals.edits, wall_s, totals.ms / std::max(1, totals.edits), totals.max_ms, v0,
               sculpture.volume(), sculpture.reference_volume(),
               check.ok() ? "clean" : check.message());
  spdlog::info("wrote {}, {} ({} triangles), {}/summary.json", vdb, ply, mesh.triangles,
               o.out_dir);
  return Status::Ok();
}

}  // namespace sculpt::client
