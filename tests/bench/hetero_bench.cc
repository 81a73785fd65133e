/// @brief sculpt-bench hetero: validity check cost per cell and for a 1,000-cell model (cold and
/// after one edit), intent editing, the inverse map (point location for voxelisation), model
/// size, the materials half of voxelisation; `--write-scenes DIR` also writes the two example models (seed 001 ch. 10).
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
    const EditIntent in{corners[pick(rng)], {0, 0, 0}, {jitter(rng), jitter(rng), jitter(rng)}};
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
  doc["quick"] = quick;
  return doc;
}

}  // namespace sculpt::bench
