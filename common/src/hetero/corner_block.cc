/// @brief Corner blocks and per-corner continuity classification.
#include "sculpt/hetero/corner_block.h"

#include <algorithm>
#include <cmath>
#include <set>

namespace sculpt::hetero {
namespace {

constexpr int kCornerSlots[8][3] = {{0, 0, 0}, {0, 0, 3}, {0, 3, 0}, {0, 3, 3},
                                    {3, 0, 0}, {3, 0, 3}, {3, 3, 0}, {3, 3, 3}};

bool SameFractions(std::span<const double> a, std::span<const double> b, double tol) {
  for (size_t m = 0; m < a.size(); ++m) {
    if (std::abs(a[m] - b[m]) > tol) return false;
  }
  return true;
}

}  // namespace

StatusOr<CornerBlock> BuildCornerBlock(const CompositeModel& model, uint32_t corner, double tol) {
  if (corner >= model.coefficient_count()) {
    return Outside("corner", std::to_string(corner),
                   std::string("[0, ") +
                       std::to_string(static_cast<long long>(model.coefficient_count()) - 1) + "]");
  }
  const Vec3 p = model.position(corner);
  CornerBlock block;
  block.octant_cell.fill(-1);
  uint32_t key = UINT32_MAX;
  // Gather (cell, corner slot) pairs whose corner coefficient sits at p. Candidates come from
  // the cells using any coefficient at p; scanning all cells keeps duplicates (unshared entries).
  struct Hit {
    int cell;
    int slot[3];
  };
  std::vector<Hit> hits;
  // Only cells using a coefficient at p can have a corner there.
  std::set<int> candidates;
  for (uint32_t q : model.CoincidentCoefficients(p, tol)) {
    candidates.insert(model.users(q).begin(), model.users(q).end());
  }
  for (int c : candidates) {
    const auto& rec = model.cell(c);
    for (const auto& s : kCornerSlots) {
      const uint32_t q = rec.coef[static_cast<size_t>(Hyperpatch::Index(s[0], s[1], s[2]))];
      if ((model.position(q) - p).Length() <= tol) {
        hits.push_back({c, {s[0], s[1], s[2]}});
        key = std::min(key, q);
      }
    }
  }
  if (hits.empty()) {
    const std::string value = std::to_string(corner);
    return FieldViolation(Status::Code::kNotFound, "corner", value, "corners of the model's cells",
                          "corner=" + value + " is not a corner of any cell");
  }
  block.corner = key;
  bool consistent = true;
  std::set<int> cells;
  for (const Hit& h : hits) {
    cells.insert(h.cell);
    // The cell extends towards + along axis a when the corner is at index 0.
    int sign[3], octant = 0;
    for (int a = 0; a < 3; ++a) {
      sign[a] = h.slot[a] == 0 ? 1 : -1;
      if (sign[a] > 0) octant |= 4 >> a;
    }
    if (block.octant_cell[static_cast<size_t>(octant)] >= 0) consistent = false;
    block.octant_cell[static_cast<size_t>(octant)] = h.cell;
    for (int dx = 0; dx <= 1; ++dx) {
      for (int dy = 0; dy <= 1; ++dy) {
        for (int dz = 0; dz <= 1; ++dz) {
          const int idx = Hyperpatch::Index(h.slot[0] + sign[0] * dx, h.slot[1] + sign[1] * dy,
                                            h.slot[2] + sign[2] * dz);
          const uint32_t q = model.cell(h.cell).coef[static_cast<size_t>(idx)];
          auto& v = block.coefs[static_cast<size_t>(
              BlockIndex(sign[0] * dx, sign[1] * dy, sign[2] * dz))];
          if (std::find(v.begin(), v.end(), q) == v.end()) v.push_back(q);
        }
      }
    }
  }
  block.cells.assign(cells.begin(), cells.end());
  for (auto& v : block.coefs) std::sort(v.begin(), v.end());
  // Consistent axes: every block position's coefficients coincide in position.
  for (const auto& v : block.coefs) {
    for (uint32_t q : v) {
      if ((model.position(q) - model.position(v.front())).Length() > tol) consistent = false;
    }
  }
  // Box-shaped octant set: a product of per-axis sign sets.
  std::set<int> sx, sy, sz;
  int count = 0;
  for (int o = 0; o < 8; ++o) {
    if (block.octant_cell[static_cast<size_t>(o)] < 0) continue;
    ++count;
    sx.insert(o & 4);
    sy.insert(o & 2);
    sz.insert(o & 1);
  }
  const bool box = count == static_cast<int>(sx.size() * sy.size() * sz.size());
  block.regular = consistent && box && static_cast<int>(hits.size()) == count &&
                  static_cast<int>(block.cells.size()) == count;
  return block;
}

CornerContinuity ClassifyCorner(const CompositeModel& model, const CornerBlock& block,
                                double tol) {
  CornerContinuity c;
  c.geometry_c0 = true;
  c.material_c0 = true;
  for (const auto& v : block.coefs) {
    for (uint32_t q : v) {
      if ((model.position(q) - model.position(v.front())).Length() > tol) c.geometry_c0 = false;
      if (!SameFractions(model.fractions(q), model.fractions(v.front()), tol)) {
        c.material_c0 = false;
      }
    }
  }
  if (!block.regular) return c;
  // (7.5) along each axis: h(+1) − h(0) = h(0) − h(−1) wherever all three positions exist.
  bool any_line = false, geo = c.geometry_c0, mat = c.material_c0;
  const int n = model.materials();
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
        any_line = true;
        const Vec3 vl = model.position(mid.front()) - model.position(lo.front());
        const Vec3 vm = model.position(hi.front()) - model.position(mid.front());
        if ((vl - vm).Length() > tol) geo = false;
        const auto fl = model.fractions(lo.front()), fm = model.fractions(mid.front()),
                   fh = model.fractions(hi.front());
        for (int m = 0; m < n; ++m) {
          if (std::abs((fm[m] - fl[m]) - (fh[m] - fm[m])) > tol) mat = false;
        }
      }
    }
  }
  c.geometry_c1 = any_line && geo;
  c.material_c1 = any_line && mat;
  return c;
}

std::vector<uint32_t> CornerPoints(const CompositeModel& model, double tol) {
  std::set<uint32_t> keys;
  std::vector<std::pair<Vec3, uint32_t>> seen;
  for (int c = 0; c < static_cast<int>(model.cell_count()); ++c) {
    for (const auto& s : kCornerSlots) {
      const uint32_t q = model.cell(c).coef[static_cast<size_t>(Hyperpatch::Index(s[0], s[1], s[2]))];
      keys.insert(q);
    }
  }
  // Collapse coincident corner entries onto the lowest index.
  std::vector<uint32_t> out;
  for (uint32_t q : keys) {
    bool dup = false;
    for (uint32_t r : out) {
      if ((model.position(r) - model.position(q)).Length() <= tol) {
        dup = true;
        break;
      }
    }
    if (!dup) out.push_back(q);
  }
  return out;
}

CornerFlags ClassifyAndFlag(CompositeModel* model, uint32_t corner, double tol) {
  const auto block = BuildCornerBlock(*model, corner, tol);
  if (!block.ok()) return {};
  const CornerContinuity c = ClassifyCorner(*model, *block, tol);
  const CornerFlags flags{block->regular && c.geometry_c1, block->regular && c.material_c1};
  model->set_corner_flags(block->corner, flags);
  return flags;
}

}  // namespace sculpt::hetero
