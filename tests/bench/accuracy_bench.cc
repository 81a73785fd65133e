/// @brief `sculpt-bench accuracy`: what accuracy costs in time. One fixed press scenario run under
/// different voxel sizes, schemes, reinitialisation policies and compensation methods; each run
/// is timed and compared with a high-resolution reference run.
#include <openvdb/openvdb.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "bench_common.h"
#include "levelset/sculpture_grid.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::bench {
namespace {

using levelset::CompensationMethod;
using levelset::CompensationRegion;
using levelset::EditKind;
using levelset::EditRequest;
using levelset::EditResult;
using levelset::EditSettings;
using levelset::Sculpture;
using levelset::SculptureOptions;
using levelset::SpatialScheme;
using levelset::TemporalScheme;
using levelset::ToolShape;

enum class Reinit { kThreshold, kNever, kEvery };

// EditSettings::reinit_spatial (the scheme of the reinitialisation) is newer than this bench's
// first version; these keep the bench building against a library with or without it.
template <typename S>
constexpr bool HasReinitSpatial() {
  return requires(S s) { s.reinit_spatial; };
}
template <typename S>
void SetReinitSpatial(S& s, SpatialScheme sp) {
  if constexpr (HasReinitSpatial<S>()) s.reinit_spatial = sp;
}
template <typename S>
const char* ReinitSpatialName(const S& s);

struct Config {
  std::string label;  // no spaces (gnuplot labels)
  std::string group;  // which factor it varies
  double voxel = 0.5;
  SpatialScheme spatial = SpatialScheme::kUpwind;  // the library default (EditSettings::motion)
  TemporalScheme temporal = TemporalScheme::kRk2;
  Reinit reinit = Reinit::kThreshold;
  bool reinit_weno5 = false;  // reinitialise with WENO5 instead of the library's default scheme
  double reinit_threshold = -1;  // < 0: the library's default Eikonal threshold
  CompensationMethod method = CompensationMethod::kNewton;
  CompensationRegion region = CompensationRegion::kShell;
};

const char* SpatialName(SpatialScheme s) {
  switch (s) {
    case SpatialScheme::kCentral: return "central";
    case SpatialScheme::kUpwind: return "upwind";
    case SpatialScheme::kWeno5: return "weno5";
  }
  return "?";
}
const char* TemporalName(TemporalScheme t) {
  switch (t) {
    case TemporalScheme::kRk1: return "rk1";
    case TemporalScheme::kRk2: return "rk2";
    case TemporalScheme::kRk3: return "rk3";
  }
  return "?";
}
const char* ReinitName(Reinit r) {
  switch (r) {
    case Reinit::kThreshold: return "threshold";
    case Reinit::kNever: return "never";
    case Reinit::kEvery: return "every_edit";
  }
  return "?";
}
const char* MethodName(CompensationMethod m, CompensationRegion region) {
  if (region == CompensationRegion::kNone) return "none";
  switch (m) {
    case CompensationMethod::kNewton: return "newton";
    case CompensationMethod::kGradientDescentDelta: return "gradient_descent_delta";
    case CompensationMethod::kGradientDescentGrad: return "gradient_descent_grad";
  }
  return "?";
}

template <typename S>
const char* ReinitSpatialName(const S& s) {
  if constexpr (HasReinitSpatial<S>()) {
    return SpatialName(s.reinit_spatial);
  } else {
    return SpatialName(s.motion.spatial);  // older library: reinit used the motion scheme
  }
}

std::string Fmt(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

EditSettings ToSettings(const Config& c) {
  EditSettings s;  // library defaults, then the factor under test
  s.motion.spatial = c.spatial;
  s.motion.temporal = c.temporal;
  s.compensation = c.region;
  s.compensation_method = c.method;
  if (c.reinit == Reinit::kNever) s.reinit_iterations = 0;
  if (c.reinit == Reinit::kEvery) s.reinit_every_k = 1;
  if (c.reinit_weno5) SetReinitSpatial(s, SpatialScheme::kWeno5);
  if (c.reinit_threshold >= 0) s.reinit_eikonal_threshold = c.reinit_threshold;
  return s;
}

Json ConfigJson(const Config& c) {
  const EditSettings s = ToSettings(c);
  return Json{{"label", c.label},
              {"group", c.group},
              {"voxel_size", c.voxel},
              {"spatial", SpatialName(c.spatial)},
              {"temporal", TemporalName(c.temporal)},
              {"cfl", s.cfl},
              {"reinit", ReinitName(c.reinit)},
              {"reinit_spatial", ReinitSpatialName(s)},
              {"reinit_iterations", s.reinit_iterations},
              {"reinit_every_k", s.reinit_every_k},
              {"reinit_eikonal_threshold", s.reinit_eikonal_threshold},
              {"compensation", MethodName(c.method, c.region)}};
}

/// The fixed scenario: `strokes` press samples of a sphere tool along a short wavy path over the
/// sphere's north cap, each reaching `penetration` into the original surface.
std::vector<EditRequest> Scenario(const AccuracyBenchOptions& o) {
  std::vector<EditRequest> out;
  const int n = std::max(1, o.strokes);
  for (int i = 0; i < n; ++i) {
    const double t = n > 1 ? static_cast<double>(i) / (n - 1) : 0.5;
    const double theta = -0.35 + 0.7 * t;
    Vec3 d{std::sin(theta), 0.2 * std::sin(2 * M_PI * t), std::cos(theta)};
    d = d / d.Length();
    EditRequest r;
    r.kind = EditKind::kPress;
    r.tool = ToolShape::Sphere(d * (o.sphere_radius + o.tool_radius - o.penetration),
                               o.tool_radius);
    r.speed = 0.5;  // world units per unit time: a stroke sample moves 0.5 world units
    r.dt = 1.0;
    out.push_back(r);
  }
  return out;
}

struct RunResult {
  std::optional<Sculpture> sculpture;
  Samples ms;
  double v0 = 0;
  double build_s = 0;
  int reinit_edits = 0;
  long substeps = 0;
  int compensation_failed = 0;
  int fallback_csg = 0;
  double max_abs_residual = 0;
  std::string error;
};

RunResult RunScenario(const Config& c, const AccuracyBenchOptions& o, bool edit = true) {
  RunResult out;
  SculptureOptions so;
  so.voxel_size = c.voxel;
  so.name = "accuracy-" + c.label;
  const auto tb = Clock::now();
  StatusOr<Sculpture> made = Sculpture::MakeSphere(so, Vec3{0, 0, 0}, o.sphere_radius);
  out.build_s = MsSince(tb) / 1000.0;
  if (!made.ok()) {
    out.error = made.status().ToString();
    return out;
  }
  out.sculpture.emplace(std::move(made).value());
  Sculpture& s = *out.sculpture;
  out.v0 = s.reference_volume();
  if (!edit) return out;
  const EditSettings settings = ToSettings(c);
  for (const EditRequest& r : Scenario(o)) {
    const auto t0 = Clock::now();
    StatusOr<EditResult> res = levelset::ApplyEdit(s, r, settings);
    const double ms = MsSince(t0);
    if (!res.ok()) {
      out.error = res.status().ToString();
      return out;
    }
    out.ms.Add(ms);
    out.reinit_edits += res->reinit_passes > 0 ? 1 : 0;
    out.substeps += res->substeps;
    out.compensation_failed += res->compensation_failed ? 1 : 0;
    out.fallback_csg += res->press_fallback_csg ? 1 : 0;
    out.max_abs_residual = std::max(out.max_abs_residual, std::abs(res->compensation_residual));
  }
  return out;
}

struct ShapeError {
  double mean = 0, rms = 0, max = 0;
  Vec3 max_at;  // the vertex with the largest error
  size_t samples = 0;
};

/// |phi_test| (trilinear, world units) over the given points (reference mesh vertices).
ShapeError MeasureShape(const Sculpture& test, const std::vector<openvdb::Vec3s>& pts) {
  ShapeError e;
  if (pts.empty()) return e;
  double sum = 0, sum2 = 0;
  for (const auto& p : pts) {
    const double d = std::abs(test.SampleWorld(Vec3{p.x(), p.y(), p.z()}));
    sum += d;
    sum2 += d * d;
    if (d > e.max) {
      e.max = d;
      e.max_at = Vec3{p.x(), p.y(), p.z()};
    }
  }
  e.samples = pts.size();
  e.mean = sum / static_cast<double>(pts.size());
  e.rms = std::sqrt(sum2 / static_cast<double>(pts.size()));
  return e;
}

/// The vertices near the strokes: within 2.5 tool radii of some tool centre (the tool, its
/// compensation shell of one tool radius and a margin). The rest of the sphere is untouched, so
/// averaging over it only dilutes the differences between configurations.
std::vector<openvdb::Vec3s> EditedRegion(const std::vector<openvdb::Vec3s>& pts,
                                         const AccuracyBenchOptions& o) {
  const std::vector<EditRequest> strokes = Scenario(o);
  const double r2 = std::pow(2.5 * o.tool_radius, 2);
  std::vector<openvdb::Vec3s> out;
  for (const auto& p : pts) {
    const Vec3 q{p.x(), p.y(), p.z()};
    for (const EditRequest& e : strokes) {
      if ((q - e.tool.center).LengthSqr() <= r2) {
        out.push_back(p);
        break;
      }
    }
  }
  return out;
}

std::vector<Config> Configs(const AccuracyBenchOptions& o) {
  std::vector<Config> out;
  const double b = o.base_voxel;
  auto base = [&](std::string label, std::string group) {
    Config c;
    c.label = std::move(label);
    c.group = std::move(group);
    c.voxel = b;
    return c;
  };
  // Schemes at the base voxel size (the full grid, or one factor at a time).
  const SpatialScheme spatial[] = {SpatialScheme::kUpwind, SpatialScheme::kWeno5};
  const TemporalScheme temporal[] = {TemporalScheme::kRk1, TemporalScheme::kRk2,
                                     TemporalScheme::kRk3};
  for (SpatialScheme sp : spatial) {
    for (TemporalScheme tm : temporal) {
      const bool is_default = sp == SpatialScheme::kUpwind && tm == TemporalScheme::kRk2;
      const bool one_factor = sp == SpatialScheme::kUpwind || tm == TemporalScheme::kRk2;
      if (!o.scheme_grid && !one_factor) continue;
      Config c = base(is_default ? "default" : std::string(SpatialName(sp)) + "-" + TemporalName(tm),
                      is_default ? "default" : "scheme");
      c.spatial = sp;
      c.temporal = tm;
      out.push_back(c);
    }
  }
  for (double v : o.voxel_sizes) {
    if (v == b) continue;
    Config c = base("dx" + Fmt(v), "voxel_size");
    c.voxel = v;
    out.push_back(c);
  }
  {
    Config c = base("reinit-never", "reinit");
    c.reinit = Reinit::kNever;
    out.push_back(c);
    c = base("reinit-every", "reinit");
    c.reinit = Reinit::kEvery;
    out.push_back(c);
    // The previous default, kept so the current one (0.05) is checked against it in one run.
    c = base("reinit-thr0.15", "reinit");
    c.reinit_threshold = 0.15;
    out.push_back(c);
    if (HasReinitSpatial<EditSettings>()) {
      c = base("reinit-weno5", "reinit");
      c.reinit_weno5 = true;
      out.push_back(c);
    }
  }
  {
    Config c = base("gd-delta", "compensation");
    c.method = CompensationMethod::kGradientDescentDelta;
    out.push_back(c);
    c = base("gd-grad", "compensation");
    c.method = CompensationMethod::kGradientDescentGrad;
    out.push_back(c);
    c = base("no-comp", "compensation");
    c.region = CompensationRegion::kNone;
    out.push_back(c);
  }
  return out;
}

}  // namespace

Json RunAccuracyBench(const AccuracyBenchOptions& o) {
  // Reference: the finest voxel size with the most accurate schemes.
  Config ref;
  ref.label = "reference";
  ref.group = "reference";
  ref.voxel = o.reference_voxel;
  ref.spatial = SpatialScheme::kWeno5;
  ref.temporal = TemporalScheme::kRk3;
  ref.method = CompensationMethod::kNewton;
  Progress("accuracy: reference run (voxel %g, weno5/rk3/newton, %d strokes)", ref.voxel,
           o.strokes);
  RunResult rr = RunScenario(ref, o);
  if (!rr.error.empty()) return Json{{"benchmark", "accuracy"}, {"error", rr.error}};
  const Sculpture& rs = *rr.sculpture;
  std::vector<openvdb::Vec3s> ref_pts;
  {
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(levelset::internal::GridOf(rs), ref_pts, quads, 0.0);
  }
  const std::vector<openvdb::Vec3s> ref_edited = EditedRegion(ref_pts, o);
  const double ref_volume = rs.ComputeVolume();
  Progress("accuracy: reference: %.1f ms/edit, %zu mesh vertices", rr.ms.Mean(), ref_pts.size());
  Json reference = ConfigJson(ref);
  reference["ms_per_edit"] = rr.ms.Mean();
  reference["ms_per_edit_p50"] = rr.ms.P(0.5);
  reference["build_s"] = rr.build_s;
  reference["mesh_vertices"] = ref_pts.size();
  reference["mesh_vertices_edited_region"] = ref_edited.size();
  reference["volume_initial"] = rr.v0;
  reference["volume_final"] = ref_volume;
  reference["volume_error_rel"] = std::abs(ref_volume - rr.v0) / rr.v0;
  reference["eikonal_mean_abs_error"] = rs.MeasureEikonal().mean_abs_error;
  reference["check_level_set"] = StatusText(rs.CheckLevelSet());

  // Scale of the edit: the untouched sphere (at the base voxel size) against the reference.
  Json scale;
  {
    Config c;
    c.voxel = o.base_voxel;
    c.label = "unedited";
    RunResult u = RunScenario(c, o, /*edit=*/false);
    if (u.error.empty()) {
      const ShapeError e = MeasureShape(*u.sculpture, ref_pts);
      const ShapeError l = MeasureShape(*u.sculpture, ref_edited);
      scale = Json{{"voxel_size", c.voxel},
                   {"shape_error_mean", e.mean},
                   {"shape_error_max", e.max},
                   {"shape_error_edited_mean", l.mean},
                   {"shape_error_edited_rms", l.rms}};
    }
  }

  Json rows = Json::array();
  std::ostringstream dat;
  dat << "# sculpt-bench accuracy: one row per configuration\n"
      << "# idx label group voxel_size ms_per_edit shape_error_mean shape_error_max "
         "volume_error_rel eikonal_mean_abs_error shape_error_edited_mean "
         "shape_error_edited_rms\n";
  int idx = 0;
  for (const Config& c : Configs(o)) {
    Progress("accuracy: %s (voxel %g, %s/%s, reinit %s, compensation %s)", c.label.c_str(),
             c.voxel, SpatialName(c.spatial), TemporalName(c.temporal), ReinitName(c.reinit),
             MethodName(c.method, c.region));
    // Repeat the scenario: the time is the median of the runs' mean per edit (a shared machine
    // is noisy), and the final states must hash equal (edits are deterministic).
    RunResult r = RunScenario(c, o);
    Json row = ConfigJson(c);
    Samples run_means;
    run_means.Add(r.ms.Mean());
    bool deterministic = true;
    for (int rep = 1; rep < o.repeats && r.error.empty(); ++rep) {
      RunResult again = RunScenario(c, o);
      if (!again.error.empty()) {
        r.error = again.error;
        break;
      }
      run_means.Add(again.ms.Mean());
      deterministic &= again.sculpture->StateHash() == r.sculpture->StateHash();
    }
    if (!r.error.empty()) {
      row["error"] = r.error;
      rows.push_back(row);
      continue;
    }
    const double ms_per_edit = run_means.P(0.5);
    const Sculpture& s = *r.sculpture;
    const double v = s.ComputeVolume();
    const ShapeError e = MeasureShape(s, ref_pts);
    const ShapeError l = MeasureShape(s, ref_edited);
    const Sculpture::EikonalReport eik = s.MeasureEikonal();
    row["ms_per_edit"] = ms_per_edit;
    row["ms_per_edit_runs"] = run_means.values;
    row["ms_per_edit_p50_first_run"] = r.ms.P(0.5);
    row["ms_per_edit_max_first_run"] = r.ms.Max();
    row["deterministic"] = deterministic;
    row["edits"] = r.ms.size();
    row["substeps_per_edit"] = static_cast<double>(r.substeps) / std::max<size_t>(1, r.ms.size());
    row["edits_with_reinit"] = r.reinit_edits;
    row["compensation_failed"] = r.compensation_failed;
    row["press_fallback_csg"] = r.fallback_csg;
    row["max_abs_compensation_residual"] = r.max_abs_residual;
    row["volume_initial"] = r.v0;
    row["volume_final"] = v;
    row["volume_final_tracked"] = s.volume();
    row["volume_error_rel"] = std::abs(v - r.v0) / r.v0;
    row["volume_error_rel_tracked"] = std::abs(s.volume() - r.v0) / r.v0;
    row["volume_vs_reference_final_rel"] = std::abs(v - ref_volume) / ref_volume;
    row["shape_error_mean"] = e.mean;
    row["shape_error_rms"] = e.rms;
    row["shape_error_max"] = e.max;
    row["shape_error_max_at"] = Json::array({e.max_at.x, e.max_at.y, e.max_at.z});
    row["shape_error_edited_mean"] = l.mean;
    row["shape_error_edited_rms"] = l.rms;
    row["eikonal_mean_abs_error"] = eik.mean_abs_error;
    row["eikonal_fraction_outside_half"] = eik.fraction_outside_half;
    row["check_level_set"] = StatusText(s.CheckLevelSet());
    rows.push_back(row);
    char line[512];
    std::snprintf(line, sizeof line, "%d %s %s %g %.6g %.6g %.6g %.6g %.6g %.6g %.6g\n", idx,
                  c.label.c_str(), c.group.c_str(), c.voxel, ms_per_edit, e.mean, e.max,
                  std::abs(v - r.v0) / r.v0, eik.mean_abs_error, l.mean, l.rms);
    dat << line;
    ++idx;
    Progress("accuracy: %s: %.2f ms/edit, shape mean %.4f (edited region %.4f) max %.4f, "
             "volume error %.2e",
             c.label.c_str(), ms_per_edit, e.mean, l.mean, e.max, std::abs(v - r.v0) / r.v0);
  }
  if (!o.out_dat.empty()) {
    std::ofstream f(o.out_dat);
    f << dat.str();
    if (!f) Progress("accuracy: could not write %s", o.out_dat.c_str());
  }

  const EditSettings d{};
  Json doc;
  doc["benchmark"] = "accuracy";
  doc["config"] = Json{
      {"quick", o.quick},
      {"scenario",
       "sphere of radius " + Fmt(o.sphere_radius) + " world units (half-width 6 voxels); " +
           std::to_string(o.strokes) + " press samples of a sphere tool of radius " +
           Fmt(o.tool_radius) + " along a wavy path over the north cap (0.7 rad long), each "
           "reaching " + Fmt(o.penetration) + " world units into the original surface; speed*dt "
           "= 0.5 world units"},
      {"base_voxel_size", o.base_voxel},
      {"reference_voxel_size", o.reference_voxel},
      {"shape_error", "mean / rms / max of |phi_test| (trilinear, world units) over the vertices "
                      "of the reference's volumeToMesh mesh; *_edited_* over the vertices within "
                      "2.5 tool radii of a stroke's tool centre"},
      {"volume_error", "|ComputeVolume(final) - V0| / V0, V0 = the scene's initial (reference) "
                       "volume"},
      {"repeats", o.repeats},
      {"timing", "wall ms around ApplyEdit: mean over the scenario's edits, median over " +
                     std::to_string(o.repeats) + " runs of the scenario"},
      {"library_defaults",
       Json{{"spatial", SpatialName(d.motion.spatial)},
            {"temporal", TemporalName(d.motion.temporal)},
            {"cfl", d.cfl},
            {"compensation", MethodName(d.compensation_method, d.compensation)},
            {"reinit_eikonal_threshold", d.reinit_eikonal_threshold},
            {"reinit_spatial", ReinitSpatialName(d)},
            {"reinit_iterations", d.reinit_iterations}}}};
  doc["reference"] = reference;
  doc["unedited_sphere_vs_reference"] = scale;
  doc["configurations"] = rows;
  return doc;
}

}  // namespace sculpt::bench
