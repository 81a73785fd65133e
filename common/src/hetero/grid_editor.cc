/// @brief Intent expansion with automatic C1 maintenance, and material edits.
#include "sculpt/hetero/grid_editor.h"

#include <algorithm>
#include <map>
#include <set>

#include "sculpt/core/check.h"

namespace sculpt::hetero {
namespace {

Status CheckCorner(const CompositeModel& model, uint32_t corner, const std::string& field) {
  if (corner >= model.coefficient_count()) {
    return Outside(field, std::to_string(corner),
                   std::string("[0, ") +
                       std::to_string(static_cast<long long>(model.coefficient_count()) - 1) + "]");
  }
  return Status::Ok();
}

// The cell's corner slot at `p`, or false.
bool CornerSlot(const CompositeModel& model, int cell, const Vec3& p, int slot[3]) {
  for (int c = 0; c < 8; ++c) {
    const int s[3] = {(c & 4) ? 3 : 0, (c & 2) ? 3 : 0, (c & 1) ? 3 : 0};
    const uint32_t q = model.cell(cell).coef[static_cast<size_t>(Hyperpatch::Index(s[0], s[1], s[2]))];
    if ((model.position(q) - p).Length() <= 1e-9) {
      slot[0] = s[0];
      slot[1] = s[1];
      slot[2] = s[2];
      return true;
    }
  }
  return false;
}

// Copy-on-write: gives `cell` its own copy of slot `slot` when another cell outside `keep`
// uses the coefficient. Returns the coefficient the cell now owns at that slot.
StatusOr<uint32_t> OwnSlot(CompositeModel* model, int cell, int slot, const std::set<int>& keep) {
  const uint32_t q = model->cell(cell).coef[static_cast<size_t>(slot)];
  bool foreign = false;
  for (int u : model->users(q)) foreign |= keep.count(u) == 0;
  if (!foreign) return q;
  const std::vector<double> a(model->fractions(q).begin(), model->fractions(q).end());
  SCULPT_ASSIGN_OR_RETURN(const uint32_t copy, model->AddCoefficient(model->position(q), a));
  // Every slot of this cell (and of the other kept cells) that used q moves to the copy.
  for (int c : keep) {
    for (int s = 0; s < 64; ++s) {
      if (model->cell(c).coef[static_cast<size_t>(s)] == q) model->ReplaceCellCoefficient(c, s, copy);
    }
  }
  return copy;
}

}  // namespace

StatusOr<std::vector<CoefficientMove>> ExpandIntent(const CompositeModel& model,
                                                    const EditIntent& intent) {
  SCULPT_RETURN_IF_ERROR(CheckCorner(model, intent.corner, "intent.corner"));
  for (int a = 0; a < 3; ++a) {
    SCULPT_RETURN_IF_ERROR(CheckRange("intent.offset[" + std::to_string(a) + "]",
                                      intent.offset[static_cast<size_t>(a)], -1, 1));
  }
  SCULPT_RETURN_IF_ERROR(CheckFinitePoint("intent.displacement", intent.displacement));
  for (int a = 0; a < 3; ++a) {
    SCULPT_RETURN_IF_ERROR(CheckRange("intent.displacement[" + std::to_string(a) + "]",
                                      intent.displacement[a], -kMaxDisplacement, kMaxDisplacement));
  }
  if (intent.cell != -1) {
    SCULPT_RETURN_IF_ERROR(CheckRange("intent.cell", intent.cell, 0,
                                      static_cast<double>(model.cell_count()) - 1));
  }
  SCULPT_ASSIGN_OR_RETURN(const CornerBlock block, BuildCornerBlock(model, intent.corner));
  const CornerFlags flags = intent.set_flags ? *intent.set_flags : model.corner_flags(block.corner);
  if (flags.geometry_c1 && !block.regular) {
    Rejection r;
    r.reason = Reason::kIrregularCorner;
    r.detail = "corner " + std::to_string(block.corner) + " has valence " +
               std::to_string(block.valence()) + " and no consistent 3x3x3 block";
    return r.ToStatus();
  }
  const auto& e = intent.offset;
  std::map<uint32_t, Vec3> moves;
  if (flags.geometry_c1) {
    // δ·Π_{a: e_a≠0} d_a e_a over the block (seed 001 §5.1 INFERENCE; keeps (7.6) on all axes).
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          const int d[3] = {dx, dy, dz};
          int f = 1;
          for (int a = 0; a < 3; ++a) {
            if (e[static_cast<size_t>(a)] != 0) f *= d[a] * e[static_cast<size_t>(a)];
          }
          if (f == 0) continue;
          for (uint32_t q : block.coefs[static_cast<size_t>(BlockIndex(dx, dy, dz))]) {
            moves[q] += intent.displacement * static_cast<double>(f);
          }
        }
      }
    }
  } else if (block.regular && intent.cell == -1) {
    const auto& at = block.coefs[static_cast<size_t>(BlockIndex(e[0], e[1], e[2]))];
    if (at.empty()) {
      const std::string offset = std::string("(") + std::to_string(e[0]) + ", " +
                                 std::to_string(e[1]) + ", " + std::to_string(e[2]) + ")";
      const std::string corner = std::to_string(block.corner);
      return FieldViolation(Status::Code::kInvalidArgument, "intent.offset", offset,
                            "offsets naming a coefficient at corner " + corner,
                            "intent.offset=" + offset + " names no coefficient at corner " + corner);
    }
    for (uint32_t q : at) moves[q] += intent.displacement;
  } else {
    // Irregular corner: the offset is in the named cell's index space, pointing into the cell.
    if (intent.cell < 0) {
      return Outside("intent.cell", "-1",
                     std::string("[0, ") +
                         std::to_string(static_cast<long long>(model.cell_count()) - 1) +
                         "] (required at an irregular corner)");
    }
    int slot[3];
    if (!CornerSlot(model, intent.cell, model.position(block.corner), slot)) {
      const std::string cell = std::to_string(intent.cell);
      const std::string corner = std::to_string(block.corner);
      return FieldViolation(Status::Code::kInvalidArgument, "intent.cell", cell,
                            "cells meeting corner " + corner,
                            "intent.cell=" + cell + " does not meet corner " + corner);
    }
    int idx[3];
    for (int a = 0; a < 3; ++a) {
      idx[a] = slot[a] + e[static_cast<size_t>(a)];
      const int lo = slot[a] == 0 ? 0 : 2, hi = slot[a] == 0 ? 1 : 3;
      if (idx[a] < lo || idx[a] > hi) {
        return Outside(std::string("intent.offset[") + std::to_string(a) + "]",
                       std::to_string(e[static_cast<size_t>(a)]),
                       std::string("[") + std::to_string(lo - slot[a]) + ", " +
                           std::to_string(hi - slot[a]) + std::string("] (points out of cell ") +
                           std::to_string(intent.cell) + ")");
      }
    }
    const uint32_t q = model.cell(intent.cell)
                           .coef[static_cast<size_t>(Hyperpatch::Index(idx[0], idx[1], idx[2]))];
    // Coincident copies (unshared entries at the same place) move together to keep C0.
    for (const auto& v : block.coefs) {
      if (std::find(v.begin(), v.end(), q) != v.end()) {
        for (uint32_t r : v) moves[r] += intent.displacement;
      }
    }
    if (moves.empty()) moves[q] += intent.displacement;
  }
  std::vector<CoefficientMove> out;
  for (const auto& [q, d] : moves) {
    if (d.LengthSqr() > 0) out.push_back({q, d});
  }
  return out;
}

Status EnforceGeometryC1(CompositeModel* model, uint32_t corner) {
  SCULPT_ASSIGN_OR_RETURN(const CornerBlock block, BuildCornerBlock(*model, corner));
  if (!block.regular) {
    Rejection r;
    r.reason = Reason::kIrregularCorner;
    r.detail = "corner " + std::to_string(block.corner) + " is not a regular block";
    return r.ToStatus();
  }
  for (int axis = 0; axis < 3; ++axis) {
    for (int a = -1; a <= 1; ++a) {
      for (int b = -1; b <= 1; ++b) {
        int idx[3];
        for (int t = -1; t <= 1; ++t) {
          int d[3];
          d[axis] = t;
          d[(axis + 1) % 3] = a;
          d[(axis + 2) % 3] = b;
          idx[t + 1] = BlockIndex(d[0], d[1], d[2]);
        }
        const auto &lo = block.coefs[static_cast<size_t>(idx[0])],
                   &mid = block.coefs[static_cast<size_t>(idx[1])],
                   &hi = block.coefs[static_cast<size_t>(idx[2])];
        if (lo.empty() || mid.empty() || hi.empty()) continue;
        // (7.6): h^m_1 = 2 h_* − h^l_2.
        const Vec3 target = model->position(mid.front()) * 2.0 - model->position(lo.front());
        for (uint32_t q : hi) model->SetPosition(q, target);
      }
    }
  }
  return Status::Ok();
}

StatusOr<EditOutcome> ApplyIntent(CompositeModel* model, ValidityChecker* checker,
                                  const EditIntent& intent) {
  EditOutcome out;
  SCULPT_RETURN_IF_ERROR(CheckCorner(*model, intent.corner, "intent.corner"));
  SCULPT_ASSIGN_OR_RETURN(const CornerBlock block0, BuildCornerBlock(*model, intent.corner));
  const CornerFlags old_flags = model->corner_flags(block0.corner);
  // Everything the edit may change, to undo a refused edit exactly.
  std::map<uint32_t, std::pair<Vec3, std::vector<double>>> saved;
  for (const auto& v : block0.coefs) {
    for (uint32_t q : v) {
      saved[q] = {model->position(q), {model->fractions(q).begin(), model->fractions(q).end()}};
    }
  }
  auto undo = [&] {
    for (const auto& [q, pa] : saved) {
      if (model->position(q) != pa.first) model->SetPosition(q, pa.first);
      const auto f = model->fractions(q);
      if (!std::equal(f.begin(), f.end(), pa.second.begin())) model->SetFractions(q, pa.second);
    }
    model->set_corner_flags(block0.corner, old_flags);
  };
  if (intent.set_flags) {
    if (intent.set_flags->geometry_c1 && !old_flags.geometry_c1) {
      const Status s = EnforceGeometryC1(model, block0.corner);
      if (!s.ok()) {
        undo();
        out.rejection.reason = Reason::kIrregularCorner;
        out.rejection.detail = s.message();
        return out;
      }
    }
    if (intent.set_flags->material_c1 && !old_flags.material_c1) {
      // Copy rule: the corner's distribution on all its block neighbours (§7.4).
      const std::vector<double> a(model->fractions(block0.corner).begin(),
                                  model->fractions(block0.corner).end());
      for (const auto& v : block0.coefs) {
        for (uint32_t q : v) model->SetFractions(q, a);
      }
    }
    model->set_corner_flags(block0.corner, *intent.set_flags);
  }
  auto moves = ExpandIntent(*model, intent);
  if (!moves.ok()) {
    undo();
    if (moves.status().code() == Status::Code::kFailedPrecondition) {
      out.rejection.reason = Reason::kIrregularCorner;
      out.rejection.detail = moves.status().message();
      return out;
    }
    return moves.status();
  }
  std::set<int> touched(block0.cells.begin(), block0.cells.end());
  for (const CoefficientMove& m : *moves) {
    if (!saved.count(m.coef)) {
      saved[m.coef] = {model->position(m.coef),
                       {model->fractions(m.coef).begin(), model->fractions(m.coef).end()}};
    }
    const Vec3 p = model->position(m.coef) + m.delta;
    if (!p.IsFinite()) {
      undo();
      return InvalidArgument("intent.displacement moves coefficient " + std::to_string(m.coef) +
                             " to a non-finite position");
    }
    model->SetPosition(m.coef, p);
    for (int c : model->users(m.coef)) touched.insert(c);
  }
  out.touched_cells.assign(touched.begin(), touched.end());
  // Validate after ordering, against the authoritative state (seed 001 §10.2, §10.5).
  const auto rep = checker->CheckCells(*model, out.touched_cells, /*stop_at_first=*/true);
  if (!rep.valid) {
    undo();
    out.rejection = rep.rejections.front();
    return out;
  }
  out.applied = true;
  out.moves = std::move(*moves);
  return out;
}

Status SetPointMaterial(CompositeModel* model, uint32_t coef, std::span<const double> a) {
  SCULPT_RETURN_IF_ERROR(CheckCorner(*model, coef, "coefficient"));
  SCULPT_RETURN_IF_ERROR(ValidateFractions("fractions", a, model->materials()));
  model->SetFractions(coef, a);
  return Status::Ok();
}

Status SetCellMaterial(CompositeModel* model, int cell, std::span<const double> a) {
  SCULPT_RETURN_IF_ERROR(
      CheckRange("cell", cell, 0, static_cast<double>(model->cell_count()) - 1));
  SCULPT_RETURN_IF_ERROR(ValidateFractions("fractions", a, model->materials()));
  const std::set<int> keep{cell};
  for (int s = 0; s < 64; ++s) {
    SCULPT_ASSIGN_OR_RETURN(const uint32_t q, OwnSlot(model, cell, s, keep));
    model->SetFractions(q, a);
  }
  return Status::Ok();
}

Status SetRegionMaterial(CompositeModel* model, const Aabb& region, std::span<const double> a) {
  SCULPT_RETURN_IF_ERROR(CheckFinitePoint("region.min", region.min));
  SCULPT_RETURN_IF_ERROR(CheckFinitePoint("region.max", region.max));
  SCULPT_RETURN_IF_ERROR(ValidateFractions("fractions", a, model->materials()));
  for (uint32_t q = 0; q < model->coefficient_count(); ++q) {
    if (region.Contains(model->position(q), 0.0)) model->SetFractions(q, a);
  }
  return Status::Ok();
}

Status SetCornerMaterial(CompositeModel* model, uint32_t corner, std::span<const double> a,
                         std::span<const int> selected_cells) {
  SCULPT_RETURN_IF_ERROR(CheckCorner(*model, corner, "corner"));
  SCULPT_RETURN_IF_ERROR(ValidateFractions("fractions", a, model->materials()));
  SCULPT_ASSIGN_OR_RETURN(const CornerBlock block, BuildCornerBlock(*model, corner));
  std::set<int> keep(selected_cells.begin(), selected_cells.end());
  for (int c : keep) {
    if (!std::binary_search(block.cells.begin(), block.cells.end(), c)) {
      return InvalidArgument("selected_cells contains " + std::to_string(c) +
                             ", which does not meet corner " + std::to_string(block.corner));
    }
  }
  // Every sharing cell selected, or none: the rule applies to all of them (§8.2).
  if (keep.empty()) keep.insert(block.cells.begin(), block.cells.end());
  const Vec3 p = model->position(block.corner);
  for (int c : keep) {
    int slot[3];
    if (!CornerSlot(*model, c, p, slot)) continue;
    for (int dx = 0; dx <= 1; ++dx) {
      for (int dy = 0; dy <= 1; ++dy) {
        for (int dz = 0; dz <= 1; ++dz) {
          const int s = Hyperpatch::Index(slot[0] + (slot[0] == 0 ? dx : -dx),
                                          slot[1] + (slot[1] == 0 ? dy : -dy),
                                          slot[2] + (slot[2] == 0 ? dz : -dz));
          SCULPT_ASSIGN_OR_RETURN(const uint32_t q, OwnSlot(model, c, s, keep));
          model->SetFractions(q, a);
        }
      }
    }
  }
  return Status::Ok();
}

}  // namespace sculpt::hetero
