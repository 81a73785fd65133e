/// @brief Construction operations: library cells, extrusion, blending, subdivision.
#include "sculpt/hetero/construction.h"

#include <cmath>
#include <set>

#include "sculpt/core/check.h"
#include "sculpt/hetero/corner_block.h"

namespace sculpt::hetero {
namespace {

constexpr double kPi = 3.14159265358979323846;

Status CheckFace(const CompositeModel& model, const Face& f, const std::string& field) {
  SCULPT_RETURN_IF_ERROR(
      CheckRange(field + ".cell", f.cell, 0, static_cast<double>(model.cell_count()) - 1));
  SCULPT_RETURN_IF_ERROR(CheckRange(field + ".axis", f.axis, 0, 2));
  SCULPT_RETURN_IF_ERROR(CheckRange(field + ".side", f.side, 0, 1));
  return Status::Ok();
}

double WeldTolerance(const CompositeModel& model) {
  return 1e-9 * std::max(1.0, model.Bounds().Diagonal());
}

}  // namespace

int FaceIndex(int axis, int q, int j, int k) {
  switch (axis) {
    case 0: return Hyperpatch::Index(q, j, k);
    case 1: return Hyperpatch::Index(j, q, k);
    default: return Hyperpatch::Index(j, k, q);
  }
}

StatusOr<AddCellResult> AddCellChecked(CompositeModel* model, ValidityChecker* checker,
                                       const Hyperpatch& patch, CellSource source) {
  SCULPT_RETURN_IF_ERROR(patch.Validate("cell.points"));
  if (patch.materials() != model->materials()) {
    return Outside("cell.materials", std::to_string(patch.materials()),
                   std::string("[") + std::to_string(model->materials()) + ", " +
                       std::to_string(model->materials()) + "]");
  }
  AddCellResult r;
  // Case 1 before touching the model (§7.3.2 note: Case 2 assumes valid cells).
  const CellVerdict v = CheckCell(patch, checker->cell_options());
  if (!v.valid) {
    r.rejection = v.rejection;
    r.rejection.cell = static_cast<int>(model->cell_count());
    return r;
  }
  const auto cp = model->MakeCheckpoint();
  SCULPT_ASSIGN_OR_RETURN(r.cell, model->AddPatch(patch, WeldTolerance(*model)));
  const int cells[] = {r.cell};
  const auto rep = checker->CheckCells(*model, cells, /*stop_at_first=*/true);
  if (!rep.valid) {
    model->Rollback(cp);
    r.rejection = rep.rejections.front();
    r.cell = -1;
    return r;
  }
  r.added = true;
  (void)source;  // every source gets the full test; kept for callers' bookkeeping
  // Classify the corners the new cell shares (§9.1 step 2, claim 31).
  for (int c = 0; c < 8; ++c) {
    const uint32_t q = model->cell(r.cell).coef[static_cast<size_t>(
        Hyperpatch::Index((c & 4) ? 3 : 0, (c & 2) ? 3 : 0, (c & 1) ? 3 : 0))];
    const auto block = BuildCornerBlock(*model, q);
    if (!block.ok() || block->valence() < 2) continue;
    const CornerFlags f = ClassifyAndFlag(model, q);
    if (f.geometry_c1 || f.material_c1) r.c1_corners.push_back(block->corner);
  }
  return r;
}

StatusOr<Hyperpatch> LibraryBox(const Vec3& min, const Vec3& max, std::span<const double> a) {
  SCULPT_RETURN_IF_ERROR(CheckFinitePoint("box.min", min));
  SCULPT_RETURN_IF_ERROR(CheckFinitePoint("box.max", max));
  for (int c = 0; c < 3; ++c) {
    if (!(max[c] > min[c])) {
      return Outside(std::string("box.max[") + std::to_string(c) + "]", FormatNumber(max[c]),
                     std::string("(") + FormatNumber(min[c]) + ", inf)");
    }
  }
  Hyperpatch h(static_cast<int>(a.size()));
  SCULPT_RETURN_IF_ERROR(ValidateFractions("box.fractions", a, static_cast<int>(a.size())));
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      for (int k = 0; k < 4; ++k) {
        const int idx = Hyperpatch::Index(i, j, k);
        h.set_position(idx, {min.x + (max.x - min.x) * i / 3, min.y + (max.y - min.y) * j / 3,
                             min.z + (max.z - min.z) * k / 3});
        h.set_fractions(idx, a);
      }
  return h;
}

StatusOr<Hyperpatch> LibraryRingSector(double r0, double r1, double a0_deg, double a1_deg,
                                       double z0, double z1, std::span<const double> a) {
  SCULPT_RETURN_IF_ERROR(CheckRange("ring.r0", r0, 0, 1e9));
  SCULPT_RETURN_IF_ERROR(CheckRange("ring.r1", r1, r0 + 1e-12, 1e9));
  SCULPT_RETURN_IF_ERROR(CheckRange("ring.a0", a0_deg, -3600, 3600));
  SCULPT_RETURN_IF_ERROR(CheckRange("ring.a1", a1_deg, a0_deg + 1e-9, a0_deg + 90));
  SCULPT_RETURN_IF_ERROR(CheckRange("ring.z0", z0, -1e9, 1e9));
  SCULPT_RETURN_IF_ERROR(CheckRange("ring.z1", z1, z0 + 1e-12, 1e9));
  SCULPT_RETURN_IF_ERROR(ValidateFractions("ring.fractions", a, static_cast<int>(a.size())));
  Hyperpatch h(static_cast<int>(a.size()));
  const double t0 = a0_deg * kPi / 180, t1 = a1_deg * kPi / 180;
  const double kk = 4.0 / 3.0 * std::tan((t1 - t0) / 4);  // cubic arc handle length
  for (int i = 0; i < 4; ++i) {
    const double r = r0 + (r1 - r0) * i / 3;
    const Vec3 p0{r * std::cos(t0), r * std::sin(t0), 0}, p3{r * std::cos(t1), r * std::sin(t1), 0};
    const Vec3 arc[4] = {p0, p0 + Vec3{-std::sin(t0), std::cos(t0), 0} * (kk * r),
                         p3 - Vec3{-std::sin(t1), std::cos(t1), 0} * (kk * r), p3};
    for (int j = 0; j < 4; ++j)
      for (int k = 0; k < 4; ++k) {
        const int idx = Hyperpatch::Index(i, j, k);
        h.set_position(idx, arc[j] + Vec3{0, 0, z0 + (z1 - z0) * k / 3});
        h.set_fractions(idx, a);
      }
  }
  return h;
}

StatusOr<bool> IsExternalFace(const CompositeModel& model, const Face& face) {
  SCULPT_RETURN_IF_ERROR(CheckFace(model, face, "face"));
  const double tol = WeldTolerance(model);
  std::vector<Vec3> mine;
  for (int j = 0; j < 4; ++j)
    for (int k = 0; k < 4; ++k)
      mine.push_back(model.position(model.cell(face.cell).coef[static_cast<size_t>(
          FaceIndex(face.axis, face.side * 3, j, k))]));
  const Aabb box = model.CellBounds(face.cell);
  for (int c = 0; c < static_cast<int>(model.cell_count()); ++c) {
    if (c == face.cell || !box.Touches(model.CellBounds(c), tol)) continue;
    for (int axis = 0; axis < 3; ++axis) {
      for (int side = 0; side < 2; ++side) {
        int matched = 0;
        for (int j = 0; j < 4; ++j)
          for (int k = 0; k < 4; ++k) {
            const Vec3 p = model.position(
                model.cell(c).coef[static_cast<size_t>(FaceIndex(axis, side * 3, j, k))]);
            for (const Vec3& q : mine) {
              if ((p - q).Length() <= tol) {
                ++matched;
                break;
              }
            }
          }
        if (matched == 16) return false;
      }
    }
  }
  return true;
}

StatusOr<AddCellResult> Extrude(CompositeModel* model, ValidityChecker* checker, const Face& face,
                                std::array<double, 3> intervals) {
  SCULPT_RETURN_IF_ERROR(CheckFace(*model, face, "extrude.face"));
  for (int q = 0; q < 3; ++q) {
    SCULPT_RETURN_IF_ERROR(CheckRange("extrude.intervals[" + std::to_string(q) + "]",
                                      intervals[static_cast<size_t>(q)], 1e-9, 1e6));
  }
  SCULPT_ASSIGN_OR_RETURN(const bool external, IsExternalFace(*model, face));
  if (!external) {
    return InvalidArgument("extrude.face=(cell " + std::to_string(face.cell) + ", axis " +
                           std::to_string(face.axis) + ", side " + std::to_string(face.side) +
                           ") is internal (belongs to two cells, (7.8))");
  }
  const Hyperpatch src = model->CellPatch(face.cell);
  Hyperpatch h(model->materials());
  const int s = face.side * 3, in = face.side ? 2 : 1;
  for (int j = 0; j < 4; ++j) {
    for (int k = 0; k < 4; ++k) {
      const int si = FaceIndex(face.axis, s, j, k);
      const Vec3 ps = src.position(si);
      Vec3 dir = ps - src.position(FaceIndex(face.axis, in, j, k));
      const double len = dir.Length();
      if (!(len > 0)) {
        return InvalidArgument("extrude.face has a zero inward vector at (" + std::to_string(j) +
                               ", " + std::to_string(k) + ")");
      }
      dir = dir / len;
      double dist = 0;
      for (int q = 0; q < 4; ++q) {
        if (q > 0) dist += intervals[static_cast<size_t>(q - 1)];
        // Side 1 grows the new cell along +axis (surface at index 0), side 0 along −axis.
        const int idx = FaceIndex(face.axis, face.side ? q : 3 - q, j, k);
        h.set_position(idx, ps + dir * dist);
        h.set_fractions(idx, src.fractions(si));  // §9.2.1 step 4: copy the surface material
      }
    }
  }
  return AddCellChecked(model, checker, h, CellSource::kExtrusion);
}

StatusOr<AddCellResult> Blend(CompositeModel* model, ValidityChecker* checker, const Face& a,
                              const Face& b, bool continuous, std::array<bool, 2> flip_b) {
  SCULPT_RETURN_IF_ERROR(CheckFace(*model, a, "blend.a"));
  SCULPT_RETURN_IF_ERROR(CheckFace(*model, b, "blend.b"));
  if (a.cell == b.cell) {
    return InvalidArgument("blend.b.cell=" + std::to_string(b.cell) +
                           " must differ from blend.a.cell");
  }
  for (const Face* f : {&a, &b}) {
    SCULPT_ASSIGN_OR_RETURN(const bool external, IsExternalFace(*model, *f));
    if (!external) {
      return InvalidArgument("blend face of cell " + std::to_string(f->cell) + " is internal");
    }
  }
  const Hyperpatch pa = model->CellPatch(a.cell), pb = model->CellPatch(b.cell);
  Hyperpatch h(model->materials());
  const int sa = a.side * 3, ia = a.side ? 2 : 1, sb = b.side * 3, ib = b.side ? 2 : 1;
  for (int j = 0; j < 4; ++j) {
    for (int k = 0; k < 4; ++k) {
      const int jb = flip_b[0] ? 3 - j : j, kb = flip_b[1] ? 3 - k : k;
      const int ai = FaceIndex(a.axis, sa, j, k), bi = FaceIndex(b.axis, sb, jb, kb);
      const Vec3 A = pa.position(ai), B = pb.position(bi);
      Vec3 m1, m2;
      if (continuous) {
        m1 = A * 2.0 - pa.position(FaceIndex(a.axis, ia, j, k));  // (7.6)
        m2 = B * 2.0 - pb.position(FaceIndex(b.axis, ib, jb, kb));
      } else {
        m1 = A + (B - A) / 3.0;
        m2 = A + (B - A) * (2.0 / 3.0);
      }
      const Vec3 line[4] = {A, m1, m2, B};
      for (int q = 0; q < 4; ++q) {
        const int idx = FaceIndex(a.axis, a.side ? q : 3 - q, j, k);
        h.set_position(idx, line[q]);
        h.set_fractions(idx, q < 2 ? pa.fractions(ai) : pb.fractions(bi));
      }
    }
  }
  return AddCellChecked(model, checker, h, CellSource::kBlend);
}

Status SubdivideCell(CompositeModel* model, int cell, int axis, double t) {
  SCULPT_RETURN_IF_ERROR(
      CheckRange("subdivide.cell", cell, 0, static_cast<double>(model->cell_count()) - 1));
  SCULPT_RETURN_IF_ERROR(CheckRange("subdivide.axis", axis, 0, 2));
  SCULPT_RETURN_IF_ERROR(CheckRange("subdivide.t", t, 1e-6, 1 - 1e-6));
  const auto [lo, hi] = model->CellPatch(cell).Split(axis, t);
  const double tol = WeldTolerance(*model);
  // The first half reuses the original's boundary coefficients where they coincide.
  for (int s = 0; s < 64; ++s) {
    SCULPT_ASSIGN_OR_RETURN(const uint32_t q,
                            model->FindOrAddCoefficient(lo.position(s), lo.fractions(s), tol));
    model->ReplaceCellCoefficient(cell, s, q);
  }
  SCULPT_ASSIGN_OR_RETURN(const int added, model->AddPatch(hi, tol));
  (void)added;
  return Status::Ok();
}

}  // namespace sculpt::hetero
