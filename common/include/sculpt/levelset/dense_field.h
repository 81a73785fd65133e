/// @brief DenseField: a dense box of level-set samples, the scratch space every local edit runs in.
#ifndef SCULPT_LEVELSET_DENSE_FIELD_H_
#define SCULPT_LEVELSET_DENSE_FIELD_H_

#include <cstddef>
#include <cstdint>
#include <vector>

namespace sculpt::levelset {

/// Integer voxel coordinate (index space).
struct Int3 {
  int x = 0, y = 0, z = 0;
  constexpr bool operator==(const Int3&) const = default;
};

/// A dense, x-fastest array of float samples covering the index box
/// [origin, origin + dims). Edits copy the region they touch out of the sparse grid into one of
/// these, run their stencils here, and write the interior back.
/// Thread safety: a value type; concurrent reads are safe, writes need external ordering.
class DenseField {
 public:
  DenseField() = default;
  DenseField(Int3 origin, Int3 dims, float fill)
      : origin_(origin), dims_(dims), data_(static_cast<size_t>(dims.x) * dims.y * dims.z, fill) {}

  Int3 origin() const { return origin_; }
  Int3 dims() const { return dims_; }
  size_t size() const { return data_.size(); }

  /// Linear index of local coordinate (i, j, k), 0 <= i < dims.x etc.
  size_t Index(int i, int j, int k) const {
    return (static_cast<size_t>(k) * dims_.y + j) * dims_.x + i;
  }
  float& at(int i, int j, int k) { return data_[Index(i, j, k)]; }
  float at(int i, int j, int k) const { return data_[Index(i, j, k)]; }
  /// Sample with the coordinate clamped into the box (zero-gradient boundary).
  float Clamped(int i, int j, int k) const {
    i = i < 0 ? 0 : (i >= dims_.x ? dims_.x - 1 : i);
    j = j < 0 ? 0 : (j >= dims_.y ? dims_.y - 1 : j);
    k = k < 0 ? 0 : (k >= dims_.z ? dims_.z - 1 : k);
    return data_[Index(i, j, k)];
  }
  bool Contains(int i, int j, int k) const {
    return i >= 0 && j >= 0 && k >= 0 && i < dims_.x && j < dims_.y && k < dims_.z;
  }

  std::vector<float>& data() { return data_; }
  const std::vector<float>& data() const { return data_; }

 private:
  Int3 origin_;
  Int3 dims_;
  std::vector<float> data_;
};

}  // namespace sculpt::levelset

#endif  // SCULPT_LEVELSET_DENSE_FIELD_H_
