/// @brief `sculpt-bench edit`: per-edit latency against object size, the naive whole-grid OpenVDB
/// pipeline for comparison, and volume drift over a long run of press strokes.
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetFilter.h>
#include <openvdb/tools/LevelSetMeasure.h>
#include <openvdb/tools/LevelSetSphere.h>
#include <openvdb/tools/LevelSetUtil.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <thread>
#include <string>
#include <vector>

#include "bench_common.h"
#include "levelset/sculpture_grid.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::bench {
namespace {

using levelset::EditKind;
using levelset::EditRequest;
using levelset::EditResult;
using levelset::EditSettings;
using levelset::Sculpture;
using levelset::SculptureOptions;
using levelset::ToolShape;

constexpr double kVoxel = 1.0;

/// A tool on the sphere's surface along `dir` that reaches `penetration` voxels into it. The
/// press moves one voxel per stroke sample (speed * dt = 1 voxel).
EditRequest ToolOnSurface(EditKind kind, const Vec3& dir, double sphere_r,
                          const EditBenchOptions& o) {
  EditRequest r;
  r.kind = kind;
  const double tr = o.tool_radius * kVoxel;
  r.tool = ToolShape::Sphere(dir * (sphere_r + tr - o.penetration * kVoxel), tr);
  r.speed = 1.0 * kVoxel;
  r.dt = 1.0;
  return r;
}

/// Per-kind accumulators.
struct KindStats {
  Samples wall_ms;  // steady_clock around the whole ApplyEdit call (validation included)
  Samples edit_ms;  // EditResult::elapsed_ms (measured inside ApplyEdit, after validation)
  double changed_voxels = 0;
  double dirty_leaves = 0;
  double substeps = 0;
  double compensation_iterations = 0;
  int reinit_edits = 0;
  int compensation_failed = 0;
  int fallback_csg = 0;
  int unchanged = 0;
  double max_abs_residual = 0;
  levelset::EditStageTimes stages;  // summed over the timed edits

  void Add(const EditResult& r, double wall) {
    stages.block += r.stage_ms.block;
    stages.operators += r.stage_ms.operators;
    stages.islands += r.stage_ms.islands;
    stages.compensation += r.stage_ms.compensation;
    stages.reinit += r.stage_ms.reinit;
    stages.resolve += r.stage_ms.resolve;
    stages.write_back += r.stage_ms.write_back;
    wall_ms.Add(wall);
    edit_ms.Add(r.elapsed_ms);
    changed_voxels += static_cast<double>(r.changed_voxels);
    dirty_leaves += static_cast<double>(r.dirty_leaves.size());
    substeps += r.substeps;
    compensation_iterations += r.compensation_iterations;
    reinit_edits += r.reinit_passes > 0 ? 1 : 0;
    compensation_failed += r.compensation_failed ? 1 : 0;
    fallback_csg += r.press_fallback_csg ? 1 : 0;
    unchanged += r.changed ? 0 : 1;
    max_abs_residual = std::max(max_abs_residual, std::abs(r.compensation_residual));
  }
  Json ToJson() const {
    const double n = std::max<double>(1, static_cast<double>(wall_ms.size()));
    return Json{{"wall_ms", wall_ms.Summary()},
                {"edit_ms", edit_ms.Summary()},
                {"mean_changed_voxels", changed_voxels / n},
                {"mean_dirty_leaves", dirty_leaves / n},
                {"mean_substeps", substeps / n},
                {"mean_compensation_iterations", compensation_iterations / n},
                {"edits_with_reinit", reinit_edits},
                {"compensation_failed", compensation_failed},
                {"press_fallback_csg", fallback_csg},
                {"unchanged_edits", unchanged},
                {"max_abs_compensation_residual", max_abs_residual},
                {"mean_stage_ms", Json{{"block", stages.block / n},
                                       {"operators", stages.operators / n},
                                       {"islands", stages.islands / n},
                                       {"compensation", stages.compensation / n},
                                       {"reinit", stages.reinit / n},
                                       {"resolve", stages.resolve / n},
                                       {"write_back", stages.write_back / n}}}};
  }
};

StatusOr<EditResult> TimedEdit(Sculpture& s, const EditRequest& r, const EditSettings& settings,
                               double* wall_ms) {
  const auto t0 = Clock::now();
  StatusOr<EditResult> res = levelset::ApplyEdit(s, r, settings);
  *wall_ms = MsSince(t0);
  return res;
}

/// Poses per stroke in the "stroke" run, as sculpt-loadgen sends them.
constexpr int kStrokePoses = 4;

/// A server-like stroke: kStrokePoses press poses one voxel apart along a tangent of the sphere
/// at `dir` (sculpt-loadgen's walk at 60 world units/s and 120 Hz with voxel 0.5), applied as one
/// batch as sculptd applies a stroke.
std::vector<EditRequest> StrokeOnSurface(const Vec3& dir, const Vec3& tangent_seed,
                                         double sphere_r, const EditBenchOptions& o) {
  Vec3 t = tangent_seed - dir * tangent_seed.Dot(dir);
  t = t.LengthSqr() > 1e-12 ? t * (1.0 / t.Length()) : Vec3{-dir.y, dir.x, 0};
  std::vector<EditRequest> poses;
  for (int i = 0; i < kStrokePoses; ++i) {
    Vec3 d = dir * sphere_r + t * ((i - 0.5 * (kStrokePoses - 1)) * kVoxel);
    d = d * (1.0 / d.Length());
    poses.push_back(ToolOnSurface(EditKind::kPress, d, sphere_r, o));
  }
  return poses;
}

std::string HexHash(uint64_t h) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

/// The naive pipeline on a copy of the grid: a fog mask of the tool, a masked
/// LevelSetFilter::offset that carves `penetration`, then levelSetVolume.
Json RunNaive(const openvdb::FloatGrid& original, double sphere_r, int edits, uint64_t seed,
              const EditBenchOptions& o) {
  openvdb::FloatGrid::Ptr grid = original.deepCopy();
  std::mt19937_64 rng(seed);
  Samples total, mask_ms, filter_ms, volume_ms;
  const double v0 = openvdb::tools::levelSetVolume(*grid);
  double vol = v0;
  const double tr = o.tool_radius * kVoxel;
  for (int i = 0; i < edits; ++i) {
    const Vec3 dir = RandomDirection(rng);
    const Vec3 c = dir * (sphere_r + tr - o.penetration * kVoxel);
    const auto t0 = Clock::now();
    openvdb::FloatGrid::Ptr mask = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
        static_cast<float>(tr), openvdb::Vec3f(static_cast<float>(c.x), static_cast<float>(c.y),
                                               static_cast<float>(c.z)),
        static_cast<float>(kVoxel));
    openvdb::tools::sdfToFogVolume(*mask);
    const double t_mask = MsSince(t0);
    const auto t1 = Clock::now();
    {
      openvdb::tools::LevelSetFilter<openvdb::FloatGrid> filter(*grid);
      filter.offset(static_cast<float>(o.penetration * kVoxel), mask.get());
    }
    const double t_filter = MsSince(t1);
    const auto t2 = Clock::now();
    vol = openvdb::tools::levelSetVolume(*grid);
    const double t_vol = MsSince(t2);
    const double t_total = MsSince(t0);
    total.Add(t_total);
    mask_ms.Add(t_mask);
    filter_ms.Add(t_filter);
    volume_ms.Add(t_vol);
    Progress("edit: naive r=%g edit %d/%d: %.0f ms (mask %.1f, filter %.0f, volume %.1f)",
             sphere_r, i + 1, edits, t_total, t_mask, t_filter, t_vol);
  }
  return Json{{"radius_voxels", sphere_r},
              {"edits", edits},
              {"pipeline",
               "createLevelSetSphere(tool) + sdfToFogVolume -> LevelSetFilter<FloatGrid>::offset("
               "penetration, &mask) with the tracker's defaults -> levelSetVolume"},
              {"total_ms", total.Summary()},
              {"mask_ms", mask_ms.Summary()},
              {"filter_offset_ms", filter_ms.Summary()},
              {"level_set_volume_ms", volume_ms.Summary()},
              {"volume_before", v0},
              {"volume_after", vol}};
}

/// Edits of each kind on one sphere.
Json RunRadius(double R, const EditBenchOptions& o, Json* naive_out) {
  SculptureOptions so;
  so.voxel_size = kVoxel;
  so.name = "bench-sphere";
  Progress("edit: r=%g: building sphere (voxel %g, half-width %d)", R, kVoxel, so.half_width);
  const auto tb = Clock::now();
  StatusOr<Sculpture> made = Sculpture::MakeSphere(so, Vec3{0, 0, 0}, R * kVoxel);
  const double build_s = MsSince(tb) / 1000.0;
  if (!made.ok()) return Json{{"radius_voxels", R}, {"error", made.status().ToString()}};
  Sculpture s = std::move(made).value();
  Json out{{"radius_voxels", R},
           {"build_s", build_s},
           {"active_voxels", s.ActiveVoxelCount()},
           {"leaves", s.LeafCount()},
           {"memory_bytes", s.MemoryBytes()},
           {"bytes_per_active_voxel",
            static_cast<double>(s.MemoryBytes()) / static_cast<double>(s.ActiveVoxelCount())},
           {"volume", s.volume()}};
  Progress("edit: r=%g: built in %.2f s, %llu active voxels, %.1f MB", R, build_s,
           static_cast<unsigned long long>(s.ActiveVoxelCount()), s.MemoryBytes() / 1e6);

  if (naive_out != nullptr) {
    *naive_out = RunNaive(levelset::internal::GridOf(s), R, o.naive_edits, o.seed ^ 0x9e3779b97f4a7c15ULL, o);
  }

  EditSettings settings{};
  settings.repair_band_every_edit = o.repair_band_every_edit;
  out["repair_band_every_edit"] = settings.repair_band_every_edit;
  std::mt19937_64 rng(o.seed + static_cast<uint64_t>(R) + 1);

  // What validation costs on its own (ApplyEdit validates before its own clock starts).
  {
    Samples validate_ms, bounds_ms;
    for (int i = 0; i < 20; ++i) {
      const EditRequest r = ToolOnSurface(EditKind::kPress, RandomDirection(rng), R, o);
      auto t0 = Clock::now();
      const Status st = levelset::ValidateEditRequest(s, r, settings);
      validate_ms.Add(MsSince(t0));
      t0 = Clock::now();
      const levelset::Aabb bb = s.WorldBounds();
      bounds_ms.Add(MsSince(t0));
      if (!st.ok() || bb.min.x > bb.max.x) {
        out["validation_error"] = StatusText(st);
        break;
      }
    }
    out["validate_request_ms"] = validate_ms.Summary();
    out["world_bounds_ms"] = bounds_ms.Summary();
  }

  // Each kind starts from the fresh sphere. "press_equal_work" is the press with a looser
  // absolute compensation tolerance of 1 voxel^3 (the default is 0.25 voxel^3). It was added when
  // the tolerance was relative and let presses on large objects skip compensation; it is kept as
  // a second size-independence check at a different tolerance. Inflate and deflate move the
  // surface by the request's default amount, 1 world unit (2 voxels), under the tool.
  struct Run {
    const char* name;
    EditKind kind;
    EditSettings settings;
  };
  EditSettings equal_work = settings;
  equal_work.compensation_tolerance_voxels = 1.0;
  // "stroke" is a batch of kStrokePoses presses (StrokeOnSurface), timed per batch.
  const Run runs[] = {{"press", EditKind::kPress, settings},
                      {"stroke", EditKind::kPress, settings},
                      {"add", EditKind::kAdd, settings},
                      {"subtract", EditKind::kSubtract, settings},
                      {"press_equal_work", EditKind::kPress, equal_work},
                      {"inflate", EditKind::kInflate, settings},
                      {"deflate", EditKind::kDeflate, settings}};
  out["press_equal_work_compensation_tolerance_voxels3"] = equal_work.compensation_tolerance_voxels;
  out["default_compensation_tolerance_voxels3"] =
      settings.compensation_tolerance_voxels;
  Json after = Json::object();
  for (const Run& run : runs) {
    if (!o.kinds.empty() &&
        std::find(o.kinds.begin(), o.kinds.end(), std::string(run.name)) == o.kinds.end()) {
      continue;
    }
    Progress("edit: r=%g: %d warm-up + %d timed %s edits (on a fresh copy)", R, o.warmup, o.edits,
             run.name);
    Sculpture work = s.Clone();
    std::mt19937_64 krng(o.seed + static_cast<uint64_t>(R));  // the same spots for every kind
    KindStats ks;
    std::string error;
    const bool stroke = std::string(run.name) == "stroke";
    for (int i = 0; i < o.warmup + o.edits; ++i) {
      const Vec3 dir = RandomDirection(krng);
      double wall = 0;
      StatusOr<EditResult> res = InvalidArgument("no edit");
      if (stroke) {
        const std::vector<EditRequest> poses =
            StrokeOnSurface(dir, RandomDirection(krng), R, o);
        const auto t0 = Clock::now();
        res = levelset::ApplyEdits(work, poses, run.settings);
        wall = MsSince(t0);
      } else {
        res = TimedEdit(work, ToolOnSurface(run.kind, dir, R, o), run.settings, &wall);
      }
      if (!res.ok()) {
        error = res.status().ToString();
        break;
      }
      if (i >= o.warmup) ks.Add(*res, wall);
    }
    Json k = ks.ToJson();
    if (!error.empty()) k["error"] = error;
    out[run.name] = k;
    const double recomputed = work.ComputeVolume();
    after[run.name] = Json{{"volume_tracked", work.volume()},
                           {"volume_recomputed", recomputed},
                           {"tracked_vs_recomputed_rel",
                            std::abs(work.volume() - recomputed) / std::abs(recomputed)},
                           {"volume_vs_initial_rel",
                            (recomputed - s.reference_volume()) / s.reference_volume()},
                           {"check_level_set", StatusText(work.CheckLevelSet())},
                           {"active_voxels", work.ActiveVoxelCount()},
                           {"state_hash", HexHash(work.StateHash())}};
    Progress("edit: r=%g: %s wall p50 %.3f ms p99 %.3f ms (in-call p50 %.3f ms p99 %.3f ms)", R,
             run.name, ks.wall_ms.P(0.5), ks.wall_ms.P(0.99), ks.edit_ms.P(0.5),
             ks.edit_ms.P(0.99));
  }
  out["after_edits"] = after;
  return out;
}

/// Many random press strokes on one sphere: does the volume stay put?
Json RunStrokes(const EditBenchOptions& o) {
  SculptureOptions so;
  so.voxel_size = kVoxel;
  so.name = "bench-strokes";
  const double R = o.stroke_radius;
  Progress("edit: strokes: building r=%g sphere, then %d press strokes", R, o.strokes);
  StatusOr<Sculpture> made = Sculpture::MakeSphere(so, Vec3{0, 0, 0}, R * kVoxel);
  if (!made.ok()) return Json{{"error", made.status().ToString()}};
  Sculpture s = std::move(made).value();
  const double v0 = s.volume();
  const EditSettings settings{};
  std::mt19937_64 rng(o.seed * 7919 + 17);
  KindStats ks;
  Json checkpoints = Json::array();
  double max_drift = 0;
  double max_drift_tracked = 0;
  double max_drift_recomputed = 0;
  std::string error;
  auto checkpoint = [&](int done) {
    const double vt = s.volume();
    const double vr = s.ComputeVolume();
    const double dt = std::abs(vt - v0) / v0;
    const double dr = std::abs(vr - v0) / v0;
    max_drift_tracked = std::max(max_drift_tracked, dt);
    max_drift_recomputed = std::max(max_drift_recomputed, dr);
    max_drift = std::max({max_drift, dt, dr});
    checkpoints.push_back(Json{{"strokes", done},
                               {"volume_tracked", vt},
                               {"volume_recomputed", vr},
                               {"reference_volume", s.reference_volume()},
                               {"drift_rel_tracked", dt},
                               {"drift_rel_recomputed", dr}});
    Progress("edit: strokes %d/%d: drift tracked %.2e, recomputed %.2e", done, o.strokes, dt, dr);
  };
  const auto t0 = Clock::now();
  for (int i = 0; i < o.strokes; ++i) {
    const EditRequest r = ToolOnSurface(EditKind::kPress, RandomDirection(rng), R, o);
    double wall = 0;
    StatusOr<EditResult> res = TimedEdit(s, r, settings, &wall);
    if (!res.ok()) {
      error = "stroke " + std::to_string(i) + ": " + res.status().ToString();
      break;
    }
    ks.Add(*res, wall);
    if ((i + 1) % o.checkpoint_every == 0 && i + 1 != o.strokes) checkpoint(i + 1);
  }
  const double run_s = MsSince(t0) / 1000.0;
  checkpoint(static_cast<int>(ks.wall_ms.size()));
  const Sculpture::EikonalReport eik = s.MeasureEikonal();
  Json out{{"radius_voxels", R},
           {"strokes", ks.wall_ms.size()},
           {"run_s", run_s},
           {"volume_initial", v0},
           {"reference_volume_final", s.reference_volume()},
           {"volume_drift_rel", max_drift},
           {"volume_drift_rel_tracked_max", max_drift_tracked},
           {"volume_drift_rel_recomputed_max", max_drift_recomputed},
           {"press", ks.ToJson()},
           {"check_level_set", StatusText(s.CheckLevelSet())},
           {"check_level_set_with_gradient", StatusText(s.CheckLevelSet(9))},
           {"eikonal",
            Json{{"mean_abs_error", eik.mean_abs_error},
                 {"fraction_outside_half", eik.fraction_outside_half},
                 {"samples", eik.samples}}},
           {"active_voxels_final", s.ActiveVoxelCount()},
           {"checkpoints", checkpoints}};
  if (!error.empty()) out["error"] = error;
  return out;
}

double PressP(const Json& radius, const char* field, double q) {
  if (!radius.contains("press")) return std::numeric_limits<double>::quiet_NaN();
  const Json& s = radius["press"][field];
  return q == 0.5 ? s["p50"].get<double>() : s["p99"].get<double>();
}

}  // namespace

Json RunEditBench(const EditBenchOptions& o) {
  const std::set<double> naive(o.naive_radii.begin(), o.naive_radii.end());
  Json radii = Json::array();
  Json naive_runs = Json::array();
  std::vector<double> order = o.radii;
  for (double r : naive) {
    if (std::find(order.begin(), order.end(), r) == order.end()) order.push_back(r);
  }
  for (double R : order) {
    Json nv;
    const bool do_naive = naive.count(R) > 0 && o.naive_edits > 0;
    Json r = RunRadius(R, o, do_naive ? &nv : nullptr);
    if (do_naive) naive_runs.push_back(nv);
    if (std::find(o.radii.begin(), o.radii.end(), R) != o.radii.end()) radii.push_back(r);
  }

  auto find_radius = [&](double R) -> const Json* {
    for (const Json& r : radii) {
      if (r["radius_voxels"].get<double>() == R && r.contains("press")) return &r;
    }
    return nullptr;
  };
  // Size independence: press p99 at the largest radius over press p99 at radius 128 (the
  // smallest radius when 128 was not run, e.g. --quick). Also p50 and p99 ratios of every kind,
  // from the wall clock and from ApplyEdit's own clock.
  Json ratios;
  {
    std::vector<double> rs = o.radii;
    std::sort(rs.begin(), rs.end());
    const double num = rs.empty() ? 0 : rs.back();
    const double den =
        std::find(rs.begin(), rs.end(), 128.0) != rs.end() ? 128.0 : (rs.empty() ? 0 : rs.front());
    const Json* a = find_radius(num);
    const Json* b = find_radius(den);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    auto ratio = [&](const char* kind, const char* clock, const char* q) {
      if (!a || !b || !a->contains(kind) || !b->contains(kind)) return nan;
      return (*a)[kind][clock][q].get<double>() / (*b)[kind][clock][q].get<double>();
    };
    ratios["size_independence_p99_ratio"] = ratio("press", "wall_ms", "p99");
    ratios["size_independence_radii"] = Json::array({num, den});
    Json per_kind;
    for (const char* kind :
         {"press", "stroke", "add", "subtract", "press_equal_work", "inflate", "deflate"}) {
      per_kind[kind] = Json{{"wall_p50", ratio(kind, "wall_ms", "p50")},
                            {"wall_p99", ratio(kind, "wall_ms", "p99")},
                            {"in_call_p50", ratio(kind, "edit_ms", "p50")},
                            {"in_call_p99", ratio(kind, "edit_ms", "p99")}};
    }
    ratios["size_ratio_by_kind"] = per_kind;
  }
  // Speed-up: naive p50 over our press p50 at radius 128 (the largest naive radius otherwise).
  {
    double at = 0;
    for (const Json& n : naive_runs) {
      const double R = n["radius_voxels"].get<double>();
      if (!find_radius(R)) continue;
      if (R == 128.0) {
        at = R;
        break;
      }
      at = std::max(at, R);
    }
    double naive_p50 = std::numeric_limits<double>::quiet_NaN();
    for (const Json& n : naive_runs) {
      if (n["radius_voxels"].get<double>() == at) naive_p50 = n["total_ms"]["p50"].get<double>();
    }
    const Json* ours = find_radius(at);
    ratios["speedup_vs_naive_p50"] =
        ours ? naive_p50 / PressP(*ours, "wall_ms", 0.5) : std::numeric_limits<double>::quiet_NaN();
    ratios["speedup_vs_naive_radius"] = at;
    ratios["speedup_vs_naive_p50_in_call"] =
        ours ? naive_p50 / PressP(*ours, "edit_ms", 0.5) : std::numeric_limits<double>::quiet_NaN();
  }

  Json strokes;
  if (!o.skip_strokes && o.strokes > 0) strokes = RunStrokes(o);

  Json doc;
  doc["benchmark"] = "edit";
  doc["config"] = Json{{"quick", o.quick},
                       {"voxel_size", kVoxel},
                       {"half_width_voxels", SculptureOptions{}.half_width},
                       {"tool", "sphere"},
                       {"tool_radius_voxels", o.tool_radius},
                       {"penetration_voxels", o.penetration},
                       {"press_speed_voxels_per_dt", 1.0},
                       {"edits_per_kind", o.edits},
                       {"warmup_per_kind", o.warmup},
                       {"naive_edits", o.naive_edits},
                       {"strokes", o.strokes},
                       {"seed", o.seed},
                       {"settings",
                        "EditSettings{} (upwind/RK2, CFL 0.5, shell compensation, Newton to "
                        "0.25 voxel^3, reinit at mean Eikonal error > 0.05, 4 upwind iterations)"},
                       {"timing",
                        "wall_ms: steady_clock around the whole ApplyEdit call (validation "
                        "included); edit_ms: EditResult::elapsed_ms (ApplyEdit's own clock, "
                        "which starts after validation). Ratios use wall_ms; *_in_call use "
                        "edit_ms."},
                       {"hardware_threads", std::thread::hardware_concurrency()},
                       {"openvdb", OPENVDB_LIBRARY_VERSION_STRING}};
  doc["goals"] = Json{{"size_independence_p99_ratio_max", 1.25},
                      {"speedup_vs_naive_p50_min", 300},
                      {"volume_drift_rel_max", 5e-4}};
  doc["size_independence_p99_ratio"] = ratios["size_independence_p99_ratio"];
  doc["speedup_vs_naive_p50"] = ratios["speedup_vs_naive_p50"];
  doc["volume_drift_rel"] =
      strokes.is_object() && strokes.contains("volume_drift_rel") ? strokes["volume_drift_rel"]
                                                                   : Json(nullptr);
  doc["ratios"] = ratios;
  doc["radii"] = radii;
  doc["naive"] = naive_runs;
  doc["strokes_run"] = strokes;
  return doc;
}

}  // namespace sculpt::bench
