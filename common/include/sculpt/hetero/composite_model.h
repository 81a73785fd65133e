/// @brief The composite heterogeneous Bézier hyperpatch (seed 001 §6.4, (6.7)): many cells whose
/// 64 coefficients are indices into one shared pool of (position, fractions) coefficients.
#ifndef SCULPT_HETERO_COMPOSITE_MODEL_H_
#define SCULPT_HETERO_COMPOSITE_MODEL_H_

#include <array>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <tuple>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"
#include "sculpt/hetero/hyperpatch.h"
#include "sculpt/hetero/material.h"

namespace sculpt::hetero {

/// Application-level meaning of one primary material (the model itself needs only n, §5).
struct MaterialInfo {
  std::string name;
  std::array<double, 3> colour{0.5, 0.5, 0.5};  // linear RGB in [0, 1]
};

/// Per-corner continuity flags, kept separately for geometry and material (§7.4, §11.1-6).
struct CornerFlags {
  bool geometry_c1 = false;
  bool material_c1 = false;
  bool operator==(const CornerFlags&) const = default;
};

/// One parametric cell: 64 pool indices (Hyperpatch::Index order) and a version that changes
/// whenever one of its coefficients does (the validity caches key on it, §7.3.2).
struct CellRecord {
  std::array<uint32_t, 64> coef{};
  uint64_t version = 0;
};

/// A composite model. Not thread-safe: one writer (the scene's compute thread); const methods
/// may run concurrently with each other.
class CompositeModel {
 public:
  /// A model with `materials` primary materials named "material0".. (n must be in [1, 16]).
  explicit CompositeModel(int materials = 1);
  /// InvalidArgument when the list is empty, longer than kMaxMaterials or a colour is outside
  /// [0, 1].
  static StatusOr<CompositeModel> Create(std::vector<MaterialInfo> materials);

  int materials() const { return materials_; }
  const std::vector<MaterialInfo>& material_info() const { return material_info_; }

  size_t coefficient_count() const { return positions_.size(); }
  size_t cell_count() const { return cells_.size(); }
  const Vec3& position(uint32_t c) const { return positions_[c]; }
  std::span<const double> fractions(uint32_t c) const;
  const CellRecord& cell(int index) const { return cells_[static_cast<size_t>(index)]; }
  /// Cells that reference coefficient `c`.
  const std::vector<int>& users(uint32_t c) const { return users_[c]; }

  /// Appends a coefficient after validating it (field "coefficient"). Returns its index.
  StatusOr<uint32_t> AddCoefficient(const Vec3& p, std::span<const double> a);
  /// The index of an existing coefficient with the same position (within `tol`) and the same
  /// fractions (within 1e-12), or a new one. Sharing coefficients is how cells glue (6.8).
  StatusOr<uint32_t> FindOrAddCoefficient(const Vec3& p, std::span<const double> a, double tol);

  /// Every coefficient within `tol` of p (ascending); `tol` should be below 1e-6.
  std::vector<uint32_t> CoincidentCoefficients(const Vec3& p, double tol) const;

  /// Appends a cell of existing coefficients. InvalidArgument naming the slot when an index is
  /// out of range. Returns the cell index.
  StatusOr<int> AddCell(const std::array<uint32_t, 64>& coef);
  /// Adds a patch's 64 coefficients (welded to existing ones when `weld_tol` >= 0) and a cell.
  StatusOr<int> AddPatch(const Hyperpatch& patch, double weld_tol);

  /// Unvalidated writes used by the editors after they validated the whole edit; bump the
  /// versions of every cell that uses the coefficient.
  void SetPosition(uint32_t c, const Vec3& p);
  void SetFractions(uint32_t c, std::span<const double> a);
  /// Replaces slot `slot` of cell `cell` with coefficient `c` (copy-on-write for material edits).
  void ReplaceCellCoefficient(int cell, int slot, uint32_t c);

  /// The cell as a standalone patch (positions and fractions copied out of the pool).
  Hyperpatch CellPatch(int cell) const;
  /// Only the positions of the cell's net.
  std::array<Vec3, 64> CellNet(int cell) const;
  Aabb CellBounds(int cell) const;
  /// Box of every coefficient.
  Aabb Bounds() const;

  /// The size of a restore point (cells and coefficients are append-only between them).
  struct Checkpoint {
    size_t cells = 0;
    size_t coefficients = 0;
  };
  Checkpoint MakeCheckpoint() const { return {cells_.size(), positions_.size()}; }
  /// Drops every cell and coefficient added after `cp` (refusing an addition).
  void Rollback(const Checkpoint& cp);

  /// Continuity flags of a corner, keyed by the pool index of its corner coefficient.
  CornerFlags corner_flags(uint32_t corner) const;
  void set_corner_flags(uint32_t corner, CornerFlags flags);
  const std::map<uint32_t, CornerFlags>& all_corner_flags() const { return corner_flags_; }

 private:
  void Touch(uint32_t c);
  std::tuple<int64_t, int64_t, int64_t> WeldKey(const Vec3& p) const;

  int materials_ = 1;
  std::vector<MaterialInfo> material_info_;
  std::vector<Vec3> positions_;
  std::vector<double> fractions_;  // materials_ per coefficient
  std::vector<std::vector<int>> users_;
  std::vector<CellRecord> cells_;
  std::map<uint32_t, CornerFlags> corner_flags_;
  std::multimap<std::tuple<int64_t, int64_t, int64_t>, uint32_t> weld_index_;
  uint64_t next_version_ = 1;
};

}  // namespace sculpt::hetero

#endif  // SCULPT_HETERO_COMPOSITE_MODEL_H_
