/// @brief SculptureSnapshot: an immutable copy of a sculpture that the haptic loop samples.
#ifndef SCULPT_HAPTICS_SCULPTURE_SNAPSHOT_H_
#define SCULPT_HAPTICS_SCULPTURE_SNAPSHOT_H_

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "sculpt/haptics/penalty.h"
#include "sculpt/levelset/sculpture.h"

namespace sculpt::haptics {

/// phi and its gradient on a deep copy of a Sculpture (trilinear phi in the narrow band, the
/// gradient by central differences of it over one voxel, as SculptureSdf). Unlike SculptureSdf
/// it owns its copy, so a publisher can hand it to the haptic loop and keep editing, and each
/// reading thread keeps one unregistered OpenVDB accessor for it (seed 000 §8: one accessor per
/// haptic thread), so consecutive samples of a tick hit the accessor's node cache.
/// Thread safety: immutable after construction; any number of threads may sample it.
class SculptureSnapshot : public SdfSampler {
 public:
  /// Takes a copy of `sculpture` (Sculpture::Clone, a deep copy).
  explicit SculptureSnapshot(const levelset::Sculpture& sculpture);
  /// Adopts `sculpture`, which nobody else may hold.
  explicit SculptureSnapshot(levelset::Sculpture&& sculpture);
  /// Shares an immutable copy made by someone else (the client's replica publishes one), with no
  /// further copy. Whoever made it must never edit it again. A null pointer is refused by
  /// dereference: callers check it first.
  explicit SculptureSnapshot(std::shared_ptr<const levelset::Sculpture> sculpture);
  /// As above, with a dense copy of the grid's values within `window_radius` (world units, at
  /// most kMaxWindowHalf voxels) of `window_centre`, made here, on the publisher's thread: a
  /// lookup whose whole stencil lies inside reads it instead of the tree, so the haptic tool's
  /// lookups cost an array read, also on the first tick after a swap (no node cache to warm).
  /// The values are the tree's, so results are the same bits. Each value's central differences
  /// are kept beside it (three doubles: 7x the window's memory, about 0.2 MB for a 21-voxel
  /// box), so phi with the gradient reads 8 corners, not 32. A non-finite centre or a
  /// non-positive radius makes no window.
  /// With `previous` (the snapshot published before this one; may be null), also compares the
  /// two windows where they overlap, so ChangeSince(previous) knows how far phi moved there
  /// (about 10 k values: microseconds, on the publisher's thread).
  SculptureSnapshot(std::shared_ptr<const levelset::Sculpture> sculpture, const Vec3& window_centre,
                    double window_radius, const SculptureSnapshot* previous = nullptr);
  ~SculptureSnapshot() override;
  static constexpr int kMaxWindowHalf = 32;

  double Phi(const Vec3& p) const override;
  Vec3 Gradient(const Vec3& p) const override;
  /// One read of the gradient's stencil gives the value too: the 32-corner central difference
  /// on the tree, the 8 corners and their stored differences in the dense window.
  void PhiAndGradient(const Vec3& p, double* phi, Vec3* gradient) const override;
  double cell_size() const override { return voxel_size_; }
  /// Bound 0 everywhere when `previous` is a snapshot of the same sculpture; the largest
  /// difference of the overlapping window values when this one was made with `previous` as its
  /// predecessor (the box: the points whose cell corners all lie in the overlap); else false.
  bool ChangeSince(const SdfSampler& previous, double* bound, Vec3* lo, Vec3* hi) const override;

  const levelset::Sculpture& sculpture() const { return *sculpture_; }
  /// A process-unique id (never reused), distinct for every snapshot constructed.
  uint64_t id() const { return id_; }
  /// Values in the dense window (0: none).
  size_t window_values() const { return window_.size(); }

  /// Lookups made by the calling thread on any snapshot, by kind (phi alone reads 8 corners;
  /// phi with the gradient a 32-corner stencil) and by where the values came from (the dense
  /// window, or the tree when the stencil is not wholly inside the window or there is none).
  /// Thread-local counters, never reset: take differences. For tests and the benchmark.
  struct LookupCounts {
    uint64_t window_phi = 0, window_stencil = 0, tree_phi = 0, tree_stencil = 0;
    uint64_t total() const { return window_phi + window_stencil + tree_phi + tree_stencil; }
    uint64_t tree() const { return tree_phi + tree_stencil; }
    LookupCounts operator-(const LookupCounts& o) const {
      return {window_phi - o.window_phi, window_stencil - o.window_stencil,
              tree_phi - o.tree_phi, tree_stencil - o.tree_stencil};
    }
  };
  static LookupCounts ThreadLookupCounts();

 private:
  std::shared_ptr<const levelset::Sculpture> sculpture_;
  // The sculpture's openvdb::FloatGrid (kept out of this header), looked up once: Phi runs
  // thousands of times a tick, and the chain of pointers to the grid showed in its cost.
  const void* grid_;
  double voxel_size_;
  uint64_t id_;
  // World to index as the grid's map computes it, without its virtual call, when the map is an
  // axis-aligned scale and translation (a level set's is): (p - translate_) * inv_scale_, the
  // same bits. Also the index-to-world gradient map (times inv_scale_).
  // Defined here, not in the .cc: an exported member of a shared library is not inlined there
  // (another library could interpose it), and these run for every lookup.
  void ToIndex(const Vec3& p, double (&u)[3]) const {
    if (!scale_map_) return ToIndexThroughMap(p, u);
    u[0] = (p.x - translate_[0]) * inv_scale_[0];
    u[1] = (p.y - translate_[1]) * inv_scale_[1];
    u[2] = (p.z - translate_[2]) * inv_scale_[2];
  }
  void ToIndexThroughMap(const Vec3& p, double (&u)[3]) const;
  bool scale_map_ = false;
  double translate_[3] = {0, 0, 0}, inv_scale_[3] = {1, 1, 1};
  // The dense window: values on index box window_lo_ + [0, window_n_), x fastest.
  // Whether the cells origin + [from, to] on every axis lie inside the window.
  bool InWindow(const int (&origin)[3], int from, int to) const {
    return !window_.empty() && origin[0] + from >= window_lo_.x &&
           origin[0] + to < window_lo_.x + window_n_.x && origin[1] + from >= window_lo_.y &&
           origin[1] + to < window_lo_.y + window_n_.y && origin[2] + from >= window_lo_.z &&
           origin[2] + to < window_lo_.z + window_n_.z;
  }
  // The window value at cell `origin` (which the caller checked lies inside).
  const float* WindowAt(const int (&origin)[3]) const {
    const ptrdiff_t nx = window_n_.x, nxy = nx * window_n_.y;
    return window_.data() + (origin[0] - window_lo_.x) + (origin[1] - window_lo_.y) * nx +
           (origin[2] - window_lo_.z) * nxy;
  }
  levelset::Int3 window_lo_{0, 0, 0}, window_n_{0, 0, 0};
  std::vector<float> window_;
  // Per window value, its central differences along x, y and z (v[+1] - v[-1], in index units),
  // made with the window, so a gradient reads its 8 corners instead of a 32-value stencil.
  std::unique_ptr<double[]> window_diff_;
  // Against the window of the snapshot with id change_base_id_ (0: none): the largest value
  // difference in their overlap, and the world box where it bounds phi's change.
  uint64_t change_base_id_ = 0;
  double change_bound_ = 0;
  Vec3 change_lo_, change_hi_;
};

}  // namespace sculpt::haptics

#endif  // SCULPT_HAPTICS_SCULPTURE_SNAPSHOT_H_
