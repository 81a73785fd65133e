/// @brief SculptureSnapshot: trilinear phi on an owned grid through a per-thread accessor.
#include "sculpt/haptics/sculpture_snapshot.h"

#include <openvdb/openvdb.h>
#include <openvdb/tree/ValueAccessor.h>

#include <atomic>
#include <cmath>
#include <optional>

#include "levelset/sculpture_impl.h"

namespace sculpt::haptics {
namespace {

using Tree = openvdb::FloatTree;
// Unregistered (IsSafe = false): the tree of a snapshot never changes, so the accessor need not
// be told about topology changes, and constructing one costs no insertion into the tree's
// accessor registry.
using Accessor = openvdb::tree::ValueAccessor<const Tree, /*IsSafe=*/false>;

std::atomic<uint64_t> g_next_id{1};

// The accessor this thread last used, tagged with the id of the snapshot it reads. Ids are
// never reused, so a stale entry (its snapshot freed) is never matched, and it is only
// dereferenced from inside a method of the live snapshot with that id.
struct ThreadAccessor {
  uint64_t id = 0;
  std::optional<Accessor> accessor;
};
thread_local ThreadAccessor t_accessor;

Accessor& AccessorFor(uint64_t id, const Tree& tree) {
  if (t_accessor.id != id) {
    t_accessor.accessor.emplace(tree);
    t_accessor.id = id;
  }
  return *t_accessor.accessor;
}

double Trilinear(Accessor& acc, const openvdb::math::Transform& xform, const Vec3& p) {
  const openvdb::Vec3d u = xform.worldToIndex(openvdb::Vec3d(p.x, p.y, p.z));
  const double fx = std::floor(u.x()), fy = std::floor(u.y()), fz = std::floor(u.z());
  const double tx = u.x() - fx, ty = u.y() - fy, tz = u.z() - fz;
  const openvdb::Coord c(static_cast<int>(fx), static_cast<int>(fy), static_cast<int>(fz));
  double v[2][2][2];
  for (int k = 0; k < 2; ++k) {
    for (int j = 0; j < 2; ++j) {
      for (int i = 0; i < 2; ++i) {
        v[i][j][k] = acc.getValue(c.offsetBy(i, j, k));
      }
    }
  }
  const double x00 = v[0][0][0] + tx * (v[1][0][0] - v[0][0][0]);
  const double x10 = v[0][1][0] + tx * (v[1][1][0] - v[0][1][0]);
  const double x01 = v[0][0][1] + tx * (v[1][0][1] - v[0][0][1]);
  const double x11 = v[0][1][1] + tx * (v[1][1][1] - v[0][1][1]);
  const double y0 = x00 + ty * (x10 - x00);
  const double y1 = x01 + ty * (x11 - x01);
  return y0 + tz * (y1 - y0);
}

}  // namespace

SculptureSnapshot::SculptureSnapshot(const levelset::Sculpture& sculpture)
    : SculptureSnapshot(sculpture.Clone()) {}

SculptureSnapshot::SculptureSnapshot(levelset::Sculpture&& sculpture)
    : SculptureSnapshot(std::make_shared<const levelset::Sculpture>(std::move(sculpture))) {}

SculptureSnapshot::SculptureSnapshot(std::shared_ptr<const levelset::Sculpture> sculpture)
    : sculpture_(std::move(sculpture)),
      grid_(sculpture_->impl().grid.get()),
      voxel_size_(sculpture_->voxel_size()),
      id_(g_next_id.fetch_add(1, std::memory_order_relaxed)) {}

SculptureSnapshot::~SculptureSnapshot() = default;

double SculptureSnapshot::Phi(const Vec3& p) const {
  const auto& grid = *static_cast<const openvdb::FloatGrid*>(grid_);
  return Trilinear(AccessorFor(id_, grid.tree()), grid.transform(), p);
}

Vec3 SculptureSnapshot::Gradient(const Vec3& p) const {
  const auto& grid = *static_cast<const openvdb::FloatGrid*>(grid_);
  Accessor& acc = AccessorFor(id_, grid.tree());
  const double h = voxel_size_;
  auto d = [&](const Vec3& e) {
    return (Trilinear(acc, grid.transform(), p + e * h) -
            Trilinear(acc, grid.transform(), p - e * h)) /
           (2 * h);
  };
  return {d({1, 0, 0}), d({0, 1, 0}), d({0, 0, 1})};
}

}  // namespace sculpt::haptics
