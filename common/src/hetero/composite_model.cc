/// @brief Composite heterogeneous hyperpatch: shared coefficient pool and cells.
#include "sculpt/hetero/composite_model.h"

#include <algorithm>
#include <cmath>

#include "sculpt/core/check.h"

namespace sculpt::hetero {
namespace {
// Weld buckets: coordinates rounded to this size; a lookup also scans the 26 neighbours.
constexpr double kWeldBucket = 1e-6;
}  // namespace

CompositeModel::CompositeModel(int materials) : materials_(std::clamp(materials, 1, kMaxMaterials)) {
  for (int i = 0; i < materials_; ++i) {
    material_info_.push_back({"material" + std::to_string(i), {0.5, 0.5, 0.5}});
  }
}

StatusOr<CompositeModel> CompositeModel::Create(std::vector<MaterialInfo> materials) {
  SCULPT_RETURN_IF_ERROR(CheckRange("model.materials.size", static_cast<double>(materials.size()),
                                    1, kMaxMaterials));
  for (size_t i = 0; i < materials.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      SCULPT_RETURN_IF_ERROR(CheckRange("model.materials[" + std::to_string(i) + "].colour[" +
                                            std::to_string(c) + "]",
                                        materials[i].colour[static_cast<size_t>(c)], 0.0, 1.0));
    }
  }
  CompositeModel m(static_cast<int>(materials.size()));
  m.material_info_ = std::move(materials);
  return m;
}

std::span<const double> CompositeModel::fractions(uint32_t c) const {
  return {fractions_.data() + static_cast<size_t>(c) * static_cast<size_t>(materials_),
          static_cast<size_t>(materials_)};
}

StatusOr<uint32_t> CompositeModel::AddCoefficient(const Vec3& p, std::span<const double> a) {
  SCULPT_RETURN_IF_ERROR(CheckFinitePoint("coefficient.p", p));
  SCULPT_RETURN_IF_ERROR(ValidateFractions("coefficient.a", a, materials_));
  const auto index = static_cast<uint32_t>(positions_.size());
  // `p` may be one of positions_ (copying a coefficient): the key is taken before push_back can
  // reallocate it away.
  const auto key = WeldKey(p);
  positions_.push_back(p);
  fractions_.insert(fractions_.end(), a.begin(), a.end());
  users_.emplace_back();
  weld_index_.emplace(key, index);
  return index;
}

std::tuple<int64_t, int64_t, int64_t> CompositeModel::WeldKey(const Vec3& p) const {
  return {static_cast<int64_t>(std::llround(p.x / kWeldBucket)),
          static_cast<int64_t>(std::llround(p.y / kWeldBucket)),
          static_cast<int64_t>(std::llround(p.z / kWeldBucket))};
}

StatusOr<uint32_t> CompositeModel::FindOrAddCoefficient(const Vec3& p, std::span<const double> a,
                                                        double tol) {
  if (tol >= 0 && p.IsFinite()) {
    const auto [kx, ky, kz] = WeldKey(p);
    uint32_t best = UINT32_MAX;
    for (int64_t dx = -1; dx <= 1; ++dx) {
      for (int64_t dy = -1; dy <= 1; ++dy) {
        for (int64_t dz = -1; dz <= 1; ++dz) {
          auto range = weld_index_.equal_range({kx + dx, ky + dy, kz + dz});
          for (auto it = range.first; it != range.second; ++it) {
            const uint32_t c = it->second;
            if (c >= positions_.size() || (positions_[c] - p).Length() > tol) continue;
            const auto f = fractions(c);
            bool same = f.size() == a.size();
            for (size_t m = 0; same && m < f.size(); ++m) same = std::abs(f[m] - a[m]) <= 1e-12;
            // The lowest index wins so the result does not depend on the map's bucket order.
            if (same) best = std::min(best, c);
          }
        }
      }
    }
    if (best != UINT32_MAX) return best;
  }
  return AddCoefficient(p, a);
}

std::vector<uint32_t> CompositeModel::CoincidentCoefficients(const Vec3& p, double tol) const {
  std::vector<uint32_t> out;
  if (!p.IsFinite()) return out;
  const auto [kx, ky, kz] = WeldKey(p);
  for (int64_t dx = -1; dx <= 1; ++dx)
    for (int64_t dy = -1; dy <= 1; ++dy)
      for (int64_t dz = -1; dz <= 1; ++dz) {
        auto range = weld_index_.equal_range({kx + dx, ky + dy, kz + dz});
        for (auto it = range.first; it != range.second; ++it) {
          if ((positions_[it->second] - p).Length() <= tol) out.push_back(it->second);
        }
      }
  std::sort(out.begin(), out.end());
  return out;
}

StatusOr<int> CompositeModel::AddCell(const std::array<uint32_t, 64>& coef) {
  for (int s = 0; s < 64; ++s) {
    if (coef[static_cast<size_t>(s)] >= positions_.size()) {
      return Outside(std::string("cell.coef[") + std::to_string(s) + "]",
                     std::to_string(coef[static_cast<size_t>(s)]),
                     std::string("[0, ") +
                         std::to_string(static_cast<long long>(positions_.size()) - 1) + "]");
    }
  }
  const int index = static_cast<int>(cells_.size());
  cells_.push_back({coef, next_version_++});
  for (uint32_t c : coef) {
    auto& u = users_[c];
    if (u.empty() || u.back() != index) u.push_back(index);
  }
  return index;
}

StatusOr<int> CompositeModel::AddPatch(const Hyperpatch& patch, double weld_tol) {
  if (patch.materials() != materials_) {
    return Outside(
        "patch.materials", std::to_string(patch.materials()),
        std::string("[") + std::to_string(materials_) + ", " + std::to_string(materials_) + "]");
  }
  SCULPT_RETURN_IF_ERROR(patch.Validate("patch.points"));
  std::array<uint32_t, 64> coef{};
  for (int s = 0; s < 64; ++s) {
    SCULPT_ASSIGN_OR_RETURN(coef[static_cast<size_t>(s)],
                            FindOrAddCoefficient(patch.position(s), patch.fractions(s), weld_tol));
  }
  return AddCell(coef);
}

void CompositeModel::Touch(uint32_t c) {
  for (int cell : users_[c]) cells_[static_cast<size_t>(cell)].version = next_version_++;
}

void CompositeModel::SetPosition(uint32_t c, const Vec3& p) {
  // Keep the weld index pointing at the new place.
  auto range = weld_index_.equal_range(WeldKey(positions_[c]));
  for (auto it = range.first; it != range.second; ++it) {
    if (it->second == c) {
      weld_index_.erase(it);
      break;
    }
  }
  positions_[c] = p;
  weld_index_.emplace(WeldKey(p), c);
  Touch(c);
}

void CompositeModel::SetFractions(uint32_t c, std::span<const double> a) {
  std::copy(a.begin(), a.end(), fractions_.begin() + static_cast<ptrdiff_t>(c) * materials_);
  Touch(c);
}

void CompositeModel::ReplaceCellCoefficient(int cell, int slot, uint32_t c) {
  auto& rec = cells_[static_cast<size_t>(cell)];
  const uint32_t old = rec.coef[static_cast<size_t>(slot)];
  rec.coef[static_cast<size_t>(slot)] = c;
  rec.version = next_version_++;
  if (std::find(rec.coef.begin(), rec.coef.end(), old) == rec.coef.end()) {
    auto& u = users_[old];
    u.erase(std::remove(u.begin(), u.end(), cell), u.end());
  }
  auto& nu = users_[c];
  if (std::find(nu.begin(), nu.end(), cell) == nu.end()) {
    nu.push_back(cell);
    std::sort(nu.begin(), nu.end());
  }
}

Hyperpatch CompositeModel::CellPatch(int cell) const {
  Hyperpatch h(materials_);
  const auto& rec = cells_[static_cast<size_t>(cell)];
  for (int s = 0; s < 64; ++s) {
    h.set_position(s, positions_[rec.coef[static_cast<size_t>(s)]]);
    h.set_fractions(s, fractions(rec.coef[static_cast<size_t>(s)]));
  }
  return h;
}

std::array<Vec3, 64> CompositeModel::CellNet(int cell) const {
  std::array<Vec3, 64> net;
  const auto& rec = cells_[static_cast<size_t>(cell)];
  for (size_t s = 0; s < 64; ++s) net[s] = positions_[rec.coef[s]];
  return net;
}

Aabb CompositeModel::CellBounds(int cell) const {
  Aabb b;
  for (uint32_t c : cells_[static_cast<size_t>(cell)].coef) b.Extend(positions_[c]);
  return b;
}

Aabb CompositeModel::Bounds() const {
  Aabb b;
  for (const Vec3& p : positions_) b.Extend(p);
  return b;
}

void CompositeModel::Rollback(const Checkpoint& cp) {
  while (cells_.size() > cp.cells) {
    const int index = static_cast<int>(cells_.size()) - 1;
    for (uint32_t c : cells_.back().coef) {
      auto& u = users_[c];
      u.erase(std::remove(u.begin(), u.end(), index), u.end());
    }
    cells_.pop_back();
  }
  while (positions_.size() > cp.coefficients) {
    const auto c = static_cast<uint32_t>(positions_.size() - 1);
    auto range = weld_index_.equal_range(WeldKey(positions_[c]));
    for (auto it = range.first; it != range.second; ++it) {
      if (it->second == c) {
        weld_index_.erase(it);
        break;
      }
    }
    corner_flags_.erase(c);
    positions_.pop_back();
    users_.pop_back();
    fractions_.resize(positions_.size() * static_cast<size_t>(materials_));
  }
}

CornerFlags CompositeModel::corner_flags(uint32_t corner) const {
  auto it = corner_flags_.find(corner);
  return it == corner_flags_.end() ? CornerFlags{} : it->second;
}

void CompositeModel::set_corner_flags(uint32_t corner, CornerFlags flags) {
  if (flags == CornerFlags{}) {
    corner_flags_.erase(corner);
  } else {
    corner_flags_[corner] = flags;
  }
}

}  // namespace sculpt::hetero
