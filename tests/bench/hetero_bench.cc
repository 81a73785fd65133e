/// @brief sculpt-bench hetero: validity check cost per cell and for a 1,000-cell model (cold and
/// after one edit), intent editing, the inverse map (point location for voxelisation), model
/// size, the materials half of voxelisation; material fractions in the sculpture (paint, press
/// with and without materials, memory per active voxel, voxelising the tyre);
/// `--write-scenes DIR` also writes the two example models (seed 001 ch. 10).
#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "bench_common.h"
#include "sculpt/hetero/boundary.h"
#include "sculpt/hetero/composite_model.h"
#include "sculpt/hetero/examples.h"
#include "sculpt/hetero/grid_editor.h"
#include "sculpt/hetero/inverse_map.h"
#include "sculpt/hetero/model_io.h"
#include "sculpt/hetero/validity.h"
#include "sculpt/levelset/edit.h"
#include "sculpt/levelset/materials.h"
#include "sculpt/levelset/region.h"
#include "sculpt/levelset/sculpture.h"
#include "sculpt/levelset/voxelize_model.h"

namespace sculpt::bench {
namespace {

using namespace sculpt::hetero;  // NOLINT: bench-local

double UsSince(Clock::time_point t0) { return MsSince(t0) * 1000.0; }

// Single-cell test cost over every cell of `m` (cold: no cache), `rounds` times.
Samples CellCheckCost(const CompositeModel& m, int rounds) {
  Samples us;
  std::vector<Hyperpatch> cells;
  for (int c = 0; c < static_cast<int>(m.cell_count()); ++c) cells.push_back(m.CellPatch(c));
  for (int r = 0; r < rounds; ++r) {
    for (const Hyperpatch& h : cells) {
      const auto t0 = Clock::now();
      const CellVerdict v = CheckCell(h);
      us.Add(UsSince(t0));
      if (!v.valid) Progress("unexpected invalid cell: %s", v.rejection.ToString().c_str());
    }
  }
  return us;
}

// Material fractions in the sculpture (issue 7) on a radius-128 sphere (voxel 1, the edit
// bench's sphere): paint p99 with 3 materials; the edit bench's press (tool radius 5 voxels, 2
// voxels deep, 1 voxel per step) on a copy with materials and one without, alternating which
// goes first so both see the same machine load; memory per active voxel of both afterwards.
void MaterialsInSculpture(bool quick, Json& doc) {
  namespace ls = sculpt::levelset;
  const double R = 128;
  ls::SculptureOptions so;
  so.voxel_size = 1.0;
  so.name = "bench-sphere";
  Progress("materials: building the radius-%g sphere", R);
  auto made = ls::Sculpture::MakeSphere(so, {0, 0, 0}, R);
  if (!made.ok()) {
    doc["materials_error"] = StatusText(made.status());
    return;
  }
  ls::Sculpture plain = std::move(made).value();
  ls::Sculpture mat = plain.Clone();
  const Status declared = ls::SetMaterials(
      mat, {{"clay", {0.8, 0.5, 0.3}}, {"wax", {0.9, 0.9, 0.7}}, {"stone", {0.4, 0.4, 0.45}}});
  if (!declared.ok()) {
    doc["materials_error"] = StatusText(declared);
    return;
  }
  // Declared but not yet painted: every fraction grid is its background alone.
  doc["bytes_per_active_voxel_with_materials_unpainted"] =
      static_cast<double>(mat.MemoryBytes() + ls::MaterialMemoryBytes(mat)) /
      static_cast<double>(mat.ActiveVoxelCount());
  std::mt19937_64 rng(20261122);
  const int edits = quick ? 10 : 300;
  std::vector<Vec3> dirs;
  for (int i = 0; i < edits; ++i) dirs.push_back(RandomDirection(rng));

  // Paint: a brush of radius 8 voxels centred on the surface, material i mod 3, weight 0.5.
  const double paint_radius = 8;
  Samples paint;
  double paint_voxels = 0;
  for (int i = 0; i < edits; ++i) {
    const auto t0 = Clock::now();
    const auto r = ls::PaintMaterial(mat, ls::ToolShape::Sphere(dirs[i] * R, paint_radius), i % 3,
                                     0.5);
    paint.Add(MsSince(t0));
    if (!r.ok()) {
      doc["materials_error"] = StatusText(r.status());
      return;
    }
    paint_voxels += static_cast<double>(r->changed_voxels);
  }
  doc["paint_p99_ms"] = paint.P(0.99);
  doc["paint_ms"] = paint.Summary();
  doc["paint_tool_radius_voxels"] = paint_radius;
  doc["paint_mean_changed_voxels"] = paint_voxels / edits;
  Json by_radius = Json::array();
  for (double pr : {4.0, 16.0, 32.0}) {
    Samples ms;
    for (int i = 0; i < (quick ? 3 : 50); ++i) {
      const auto t0 = Clock::now();
      const auto r = ls::PaintMaterial(mat, ls::ToolShape::Sphere(dirs[i] * R, pr), (i + 1) % 3,
                                       0.25);
      ms.Add(MsSince(t0));
      if (!r.ok()) break;
    }
    by_radius.push_back({{"tool_radius_voxels", pr}, {"ms", ms.Summary()}});
  }
  doc["paint_by_radius"] = by_radius;

  // Press where the paint went, so the carry rule copies mixed vectors.
  Progress("materials: %d presses with and without materials", edits);
  const ls::EditSettings settings{};
  Samples with, without;
  for (int i = 0; i < edits; ++i) {
    ls::EditRequest req;
    req.kind = ls::EditKind::kPress;
    req.tool = ls::ToolShape::Sphere(dirs[i] * (R + 5 - 2), 5);
    req.speed = 1;
    req.dt = 1;
    for (int k = 0; k < 2; ++k) {
      const bool materials = (k == 0) == (i % 2 == 0);
      ls::Sculpture& target = materials ? mat : plain;
      const auto t0 = Clock::now();
      const auto r = ls::ApplyEdit(target, req, settings);
      (materials ? with : without).Add(MsSince(t0));
      if (!r.ok()) {
        doc["materials_error"] = StatusText(r.status());
        return;
      }
    }
  }
  doc["press_p99_ms_with_materials"] = with.P(0.99);
  doc["press_p99_ms_without_materials"] = without.P(0.99);
  doc["press_ms_with_materials"] = with.Summary();
  doc["press_ms_without_materials"] = without.Summary();
  doc["press_p99_ratio"] = with.P(0.99) / without.P(0.99);
  // The sculpting kernel does not look at the materials: both SDFs are the same.
  doc["sdf_identical_with_and_without_materials"] = plain.StateHash() == mat.StateHash();
  const double active = static_cast<double>(plain.ActiveVoxelCount());
  doc["bytes_per_active_voxel_without_materials"] = static_cast<double>(plain.MemoryBytes()) / active;
  doc["bytes_per_active_voxel_with_materials"] =
      static_cast<double>(mat.MemoryBytes() + ls::MaterialMemoryBytes(mat)) /
      static_cast<double>(mat.ActiveVoxelCount());
  doc["material_grid_bytes"] = ls::MaterialMemoryBytes(mat);
  const ls::SimplexReport rep = ls::CheckSimplex(mat);
  doc["simplex_max_sum_error"] = rep.max_sum_error;
  doc["simplex_min_fraction"] = rep.min_fraction;

  // Voxelising the 8-sector tyre (boundary -> SDF union, inverse map -> fractions) vs voxel size.
  auto tyre = BuildMotorcycleTyre(8);
  if (!tyre.ok()) return;
  const MaterialVolumes exact = IntegrateVolumes(*tyre);
  Json vox = Json::array();
  for (double h : quick ? std::vector<double>{1.0} : std::vector<double>{1.0, 0.5, 0.25}) {
    ls::SculptureOptions to;
    to.voxel_size = h;
    to.half_width = 4;
    to.name = "tyre";
    auto empty = ls::MakeEmptySculpture(to);
    if (!empty.ok()) continue;
    ls::Sculpture s = std::move(empty).value();
    const auto t0 = Clock::now();
    const auto r = ls::VoxelizeModel(s, *tyre);
    const double ms = MsSince(t0);
    if (!r.ok()) {
      vox.push_back({{"voxel_size", h}, {"error", StatusText(r.status())}});
      continue;
    }
    const std::vector<double> vol = ls::MaterialVolumes(s);
    double worst = 0;
    for (size_t m = 0; m < vol.size(); ++m) {
      worst = std::max(worst, std::abs(vol[m] - exact.per_material[m]) / exact.total);
    }
    vox.push_back({{"voxel_size", h},
                   {"total_ms", ms},
                   {"mesh_ms", r->mesh_ms},
                   {"sdf_ms", r->sdf_ms},
                   {"materials_ms", r->materials_ms},
                   {"located_voxels", r->located_voxels},
                   {"filled_voxels", r->filled_voxels},
                   {"unreached_voxels", r->unreached_voxels},
                   {"volume_error_rel", (s.volume() - exact.total) / exact.total},
                   {"material_volume_error_rel_max", worst},
                   {"active_voxels", s.ActiveVoxelCount()},
                   {"bytes_per_active_voxel_with_materials",
                    static_cast<double>(s.MemoryBytes() + ls::MaterialMemoryBytes(s)) /
                        static_cast<double>(s.ActiveVoxelCount())}});
    Progress("materials: tyre voxelised at %g in %.0f ms", h, ms);
  }
  doc["voxelise_tyre"] = vox;
}

}  // namespace

Json RunHeteroBench(bool quick, const std::string& write_scenes) {
  Json doc;
  if (!write_scenes.empty()) {
    const auto tyre = BuildMotorcycleTyre();
    const auto part = BuildMechanicalPart();
    if (!tyre.ok() || !part.ok()) {
      doc["error"] = StatusText(tyre.ok() ? part.status() : tyre.status());
      return doc;
    }
    const std::string tp = write_scenes + "/" + kTyreSceneFile;
    const std::string pp = write_scenes + "/" + kMechanicalPartSceneFile;
    const Status s1 = SaveModel(*tyre, tp, "motorcycle tyre",
                                "Seed 001 §10.2: a racing motorcycle tyre, tread of three blended "
                                "compounds (carbon black left, silica right), body ply, side walls, "
                                "beads. Built by hetero::BuildMotorcycleTyre().");
    const Status s2 = SaveModel(*part, pp, "mechanical part",
                                "Seed 001 §10.1/§9.3: two rings, an extruded hub with a cylindrical "
                                "steel-to-bronze transition, a subdivided blended arm. Built by "
                                "hetero::BuildMechanicalPart().");
    doc["scenes_written"] = {tp, pp};
    if (!s1.ok() || !s2.ok()) doc["error"] = StatusText(s1.ok() ? s2 : s1);
    return doc;
  }

  // 1. Single-cell validity on the tyre's cells (curved, thin, realistic).
  Progress("building the 8-sector tyre");
  const auto tyre8 = BuildMotorcycleTyre(8);
  if (!tyre8.ok()) {
    doc["error"] = StatusText(tyre8.status());
    return doc;
  }
  const Samples cell = CellCheckCost(*tyre8, quick ? 1 : 20);
  // The median: the machine is shared, and a mean is at the mercy of one descheduled thread.
  doc["validity_us_per_cell"] = cell.P(0.5);
  doc["validity_us_per_cell_summary"] = cell.Summary();

  // 2. A 1,000-cell model: the tyre with 100 sectors of 3.6°.
  const int sectors = quick ? 10 : 100;
  Progress("building the %d-sector tyre", sectors);
  const auto t_build = Clock::now();
  auto big = BuildMotorcycleTyre(sectors);
  const double build_ms = MsSince(t_build);
  if (!big.ok()) {
    doc["error"] = StatusText(big.status());
    return doc;
  }
  Samples cold_ms;
  ValidityChecker::Report rep;
  for (int r = 0; r < (quick ? 1 : 5); ++r) {
    ValidityChecker checker;
    const auto t0 = Clock::now();
    rep = checker.CheckModel(*big);
    cold_ms.Add(MsSince(t0));
  }
  doc["model_cells"] = big->cell_count();
  doc["model_coefficients"] = big->coefficient_count();
  doc["model_valid"] = rep.valid;
  doc["pairs_tested"] = rep.pairs_tested;
  doc["build_with_checks_ms"] = build_ms;
  // Scale to 1,000 cells when the quick model is smaller.
  doc["validity_ms_1000_cells"] =
      cold_ms.P(0.5) * 1000.0 / static_cast<double>(big->cell_count());
  doc["validity_ms_model_summary"] = cold_ms.Summary();

  // 3. Editing by intents: a corner move on the tread, validated against the cached model.
  ValidityChecker checker;
  checker.CheckModel(*big);
  std::mt19937_64 rng(7);
  const std::vector<uint32_t> corners = CornerPoints(*big);
  std::uniform_int_distribution<size_t> pick(0, corners.size() - 1);
  std::uniform_real_distribution<double> jitter(-0.05, 0.05);
  Samples apply_us, recheck_ms;
  int refused = 0;
  const int edits = quick ? 20 : 300;
  for (int e = 0; e < edits; ++e) {
    EditIntent in;
    in.corner = corners[pick(rng)];
    in.displacement = {jitter(rng), jitter(rng), jitter(rng)};
    const auto t0 = Clock::now();
    const auto out = ApplyIntent(&*big, &checker, in);
    apply_us.Add(UsSince(t0));
    if (!out.ok() || !out->applied) ++refused;
    const auto t1 = Clock::now();
    const auto r = checker.CheckModel(*big);
    recheck_ms.Add(MsSince(t1));
    if (!r.valid) Progress("model invalid after an accepted edit: %s", r.rejections[0].ToString().c_str());
  }
  doc["intent_apply_us"] = apply_us.Summary();
  doc["intents_refused"] = refused;
  doc["validity_ms_after_edit"] = recheck_ms.Summary();

  // 4. The inverse map: point location at random points of the 8-sector tyre's box.
  Progress("inverse map");
  const auto t_map = Clock::now();
  const InverseMap map(*tyre8);
  doc["inverse_map_build_ms"] = MsSince(t_map);
  const Aabb box = map.bounds();
  std::uniform_real_distribution<double> ux(box.min.x, box.max.x), uy(box.min.y, box.max.y),
      uz(box.min.z, box.max.z);
  const int points = quick ? 2000 : 200000;
  int inside = 0;
  const auto t_loc = Clock::now();
  for (int i = 0; i < points; ++i) inside += map.Locate({ux(rng), uy(rng), uz(rng)}).has_value();
  doc["inverse_map_us_per_point"] = UsSince(t_loc) / points;
  doc["inverse_map_inside_fraction"] = static_cast<double>(inside) / points;

  // 5. The materials half of voxelisation: sample A at every voxel centre of the tyre's box
  //    through the inverse map, and compare the sampled material volumes with the quadrature.
  const MaterialVolumes exact = IntegrateVolumes(*tyre8);
  Json vox = Json::array();
  for (double h : quick ? std::vector<double>{2.0} : std::vector<double>{1.0, 0.5}) {
    const int nx = static_cast<int>(std::ceil((box.max.x - box.min.x) / h));
    const int ny = static_cast<int>(std::ceil((box.max.y - box.min.y) / h));
    const int nz = static_cast<int>(std::ceil((box.max.z - box.min.z) / h));
    std::vector<double> vol(static_cast<size_t>(tyre8->materials()), 0.0), a(vol.size());
    int64_t in = 0;
    const auto t0 = Clock::now();
    // A scan along z, each voxel hinted with its predecessor's location, as a voxeliser would.
    std::optional<Location> prev;
    for (int x = 0; x < nx; ++x)
      for (int y = 0; y < ny; ++y)
        for (int z = 0; z < nz; ++z) {
          const Vec3 p = box.min + Vec3{(x + 0.5) * h, (y + 0.5) * h, (z + 0.5) * h};
          const auto loc = map.Locate(p, prev ? &*prev : nullptr);
          if (loc) prev = loc;
          if (!loc) continue;
          ++in;
          for (size_t m = 0; m < a.size(); ++m) vol[m] += loc->materials[m] * h * h * h;
        }
    const double ms = MsSince(t0);
    double worst = 0;
    for (size_t m = 0; m < vol.size(); ++m) {
      worst = std::max(worst, std::abs(vol[m] - exact.per_material[m]) / exact.total);
    }
    vox.push_back({{"voxel_size", h},
                   {"voxel_centres", static_cast<int64_t>(nx) * ny * nz},
                   {"inside", in},
                   {"sample_ms", ms},
                   {"us_per_inside_voxel", ms * 1000.0 / std::max<int64_t>(in, 1)},
                   {"material_volume_error_rel_max", worst}});
    Progress("materials sampled at voxel size %g: %.0f ms", h, ms);
  }
  doc["material_sampling"] = vox;
  const auto t_mesh = Clock::now();
  const auto mesh = ExternalBoundaryMesh(*tyre8, 6);
  doc["boundary_mesh_ms"] = MsSince(t_mesh);
  doc["boundary_mesh_triangles"] = mesh.ok() ? mesh->triangles.size() : 0;
  doc["boundary_mesh_open_edges"] = mesh.ok() ? mesh->open_edges : 0;

  // 6. Size of a model: the pool form (float64 here) and its JSON file.
  const std::string json = ModelToJson(*tyre8);
  doc["tyre_json_bytes"] = json.size();
  doc["tyre_bytes_per_cell_pool"] =
      static_cast<double>(tyre8->coefficient_count() * (3 + tyre8->materials()) * sizeof(double) +
                          tyre8->cell_count() * 64 * sizeof(uint32_t)) /
      static_cast<double>(tyre8->cell_count());
  MaterialsInSculpture(quick, doc);
  doc["quick"] = quick;
  return doc;
}

}  // namespace sculpt::bench
