/// @brief The tyre and mechanical-part example models, built with the construction operations.
#include "sculpt/hetero/examples.h"

#include <cmath>

#include "sculpt/hetero/construction.h"
#include "sculpt/hetero/grid_editor.h"
#include "sculpt/hetero/validity.h"
#include "sculpt/core/check.h"

namespace sculpt::hetero {
namespace {

Status Added(const StatusOr<AddCellResult>& r, const std::string& what) {
  if (!r.ok()) return r.status();
  if (!r->added) return FailedPrecondition(what + " refused: " + r->rejection.ToString());
  return Status::Ok();
}

Hyperpatch Translate(Hyperpatch h, const Vec3& d) {
  for (int i = 0; i < 64; ++i) h.set_position(i, h.position(i) + d);
  return h;
}

}  // namespace

StatusOr<CompositeModel> BuildMotorcycleTyre(int sectors) {
  SCULPT_RETURN_IF_ERROR(CheckRange("tyre.sectors", sectors, 4, 1000));
  SCULPT_ASSIGN_OR_RETURN(
      CompositeModel m,
      CompositeModel::Create({{"carbon_black_compound", {0.15, 0.15, 0.15}},
                              {"silica_compound", {0.85, 0.85, 0.80}},
                              {"natural_rubber", {0.55, 0.35, 0.20}},
                              {"body_ply", {0.20, 0.30, 0.70}},
                              {"bead_steel", {0.75, 0.75, 0.78}}}));
  ValidityChecker checker;
  constexpr double kOuter = 30, kTread = 1.5, kPly = 1.0, kWall = 5.0, kBead = 1.5;
  constexpr double kHalfWidth = 9, kEdge = 1.5;
  const double z_cuts[4] = {-kHalfWidth, -kHalfWidth + kEdge, kHalfWidth - kEdge, kHalfWidth};
  // Tread compound across the width (z): carbon black rich at the left edge, silica rich at the
  // right, natural rubber binder throughout; linear in z, so continuous across cells (§4.3).
  auto tread = [&](double z) {
    const double t = (z + kHalfWidth) / (2 * kHalfWidth);
    return std::vector<double>{0.7 - 0.6 * t, 0.1 + 0.6 * t, 0.2, 0.0, 0.0};
  };
  const std::vector<double> ply = {0, 0, 0, 1, 0}, wall = {0, 0, 1, 0, 0}, bead = {0, 0, 0, 0, 1};
  const double step = 360.0 / sectors;
  for (int s = 0; s < sectors; ++s) {
    const double a0 = step * s, a1 = step * (s + 1);
    int tread_cells[3];
    for (int c = 0; c < 3; ++c) {
      SCULPT_ASSIGN_OR_RETURN(Hyperpatch h, LibraryRingSector(kOuter - kTread, kOuter, a0, a1,
                                                              z_cuts[c], z_cuts[c + 1], tread(0)));
      for (int i = 0; i < 64; ++i) h.set_fractions(i, tread(h.position(i).z));
      const auto r = AddCellChecked(&m, &checker, h, CellSource::kLibrary);
      SCULPT_RETURN_IF_ERROR(Added(r, "tread cell"));
      tread_cells[c] = r->cell;
    }
    for (int c = 0; c < 3; ++c) {
      // Body ply: extruded inwards from the tread's inner face, then one material.
      const auto p = Extrude(&m, &checker, {tread_cells[c], 0, 0}, {kPly / 3, kPly / 3, kPly / 3});
      SCULPT_RETURN_IF_ERROR(Added(p, "body ply"));
      SCULPT_RETURN_IF_ERROR(SetCellMaterial(&m, p->cell, ply));
      if (c == 1) continue;
      // Side wall and bead under the two edge cells.
      const auto w = Extrude(&m, &checker, {p->cell, 0, 0}, {kWall / 3, kWall / 3, kWall / 3});
      SCULPT_RETURN_IF_ERROR(Added(w, "side wall"));
      SCULPT_RETURN_IF_ERROR(SetCellMaterial(&m, w->cell, wall));
      const auto b = Extrude(&m, &checker, {w->cell, 0, 0}, {kBead / 3, kBead / 3, kBead / 3});
      SCULPT_RETURN_IF_ERROR(Added(b, "bead"));
      SCULPT_RETURN_IF_ERROR(SetCellMaterial(&m, b->cell, bead));
    }
  }
  const auto rep = checker.CheckModel(m);
  if (!rep.valid) return Internal("tyre model invalid: " + rep.rejections.front().ToString());
  return m;
}

StatusOr<CompositeModel> BuildMechanicalPart() {
  SCULPT_ASSIGN_OR_RETURN(CompositeModel m,
                          CompositeModel::Create({{"steel", {0.60, 0.62, 0.66}},
                                                  {"bronze", {0.80, 0.50, 0.20}},
                                                  {"aluminium", {0.90, 0.91, 0.93}}}));
  ValidityChecker checker;
  const std::vector<double> steel = {1, 0, 0}, bronze = {0, 1, 0};
  // (a) Two rings from the library: 8 sectors of 45° each (a 90° cubic arc meets requirement 1
  // only with equality in a single frame, so any later edit would need a split), centred at
  // x = 0 and x = 10.
  int ring_a[8], ring_b[8];
  for (int s = 0; s < 8; ++s) {
    const double a0 = -22.5 + 45.0 * s, a1 = a0 + 45.0;
    SCULPT_ASSIGN_OR_RETURN(const Hyperpatch ha, LibraryRingSector(1.0, 2.0, a0, a1, 0, 1, steel));
    auto ra = AddCellChecked(&m, &checker, ha, CellSource::kLibrary);
    SCULPT_RETURN_IF_ERROR(Added(ra, "ring A"));
    ring_a[s] = ra->cell;
    SCULPT_ASSIGN_OR_RETURN(const Hyperpatch hb, LibraryRingSector(1.0, 2.0, a0, a1, 0, 1, steel));
    auto rb = AddCellChecked(&m, &checker, Translate(hb, {10, 0, 0}), CellSource::kLibrary);
    SCULPT_RETURN_IF_ERROR(Added(rb, "ring B"));
    ring_b[s] = rb->cell;
  }
  // (b) A hub extruded upwards from ring A.
  int hub[8];
  for (int s = 0; s < 8; ++s) {
    const auto h = Extrude(&m, &checker, {ring_a[s], 2, 1}, {0.5, 0.5, 0.5});
    SCULPT_RETURN_IF_ERROR(Added(h, "hub"));
    hub[s] = h->cell;
  }
  // (d) A non-continuous blend from ring A's +x sector to ring B's −x sector. B's face runs
  // through the angle the other way, so its first in-face index is reversed (manual
  // correspondence, §9.2.2).
  const auto arm = Blend(&m, &checker, {ring_a[0], 0, 1}, {ring_b[4], 0, 1}, /*continuous=*/false,
                         {true, false});
  SCULPT_RETURN_IF_ERROR(Added(arm, "arm"));
  // (e) Subdivide the arm for detail at its centre.
  SCULPT_RETURN_IF_ERROR(SubdivideCell(&m, arm->cell, 0, 0.5));
  // (f) Geometry edit: raise the hub's top outer corner between sectors 0 and 1 by an intent.
  const uint32_t corner = m.cell(hub[0]).coef[Hyperpatch::Index(3, 3, 3)];
  EditIntent raise;
  raise.corner = corner;
  raise.displacement = {0, 0, 0.25};
  const auto edit = ApplyIntent(&m, &checker, raise);
  if (!edit.ok()) return edit.status();
  if (!edit->applied) return FailedPrecondition("hub edit refused: " + edit->rejection.ToString());
  // (g) Material: a cylindrical steel-to-bronze transition in the hub (bronze bearing surface on
  // the inside, graded over the inner two coefficient layers).
  for (int s = 0; s < 8; ++s) {
    for (int j = 0; j < 4; ++j)
      for (int k = 1; k < 4; ++k) {
        SCULPT_RETURN_IF_ERROR(SetPointMaterial(
            &m, m.cell(hub[s]).coef[static_cast<size_t>(Hyperpatch::Index(0, j, k))], bronze));
        SCULPT_ASSIGN_OR_RETURN(const Fractions mixed, Mix(bronze, steel, 0.5));
        SCULPT_RETURN_IF_ERROR(SetPointMaterial(
            &m, m.cell(hub[s]).coef[static_cast<size_t>(Hyperpatch::Index(1, j, k))], mixed));
      }
  }
  // (h) An aluminium-rich arm: its two cells get a steel/aluminium mix (eq. 4.3).
  SCULPT_ASSIGN_OR_RETURN(const Fractions arm_mix, Mix(std::vector<double>{0, 0, 1}, steel, 0.7));
  SCULPT_RETURN_IF_ERROR(SetCellMaterial(&m, arm->cell, arm_mix));
  SCULPT_RETURN_IF_ERROR(SetCellMaterial(&m, static_cast<int>(m.cell_count()) - 1, arm_mix));
  const auto rep = checker.CheckModel(m);
  if (!rep.valid) return Internal("mechanical part invalid: " + rep.rejections.front().ToString());
  return m;
}

}  // namespace sculpt::hetero
