/// @brief Sculpture: primitives, file I/O, volume, state hash and the dense-region helpers.
#include "sculpt/levelset/sculpture.h"

#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <openvdb/io/File.h>
#include <openvdb/tools/Diagnostics.h>
#include <openvdb/tools/MeshToVolume.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/Prune.h>
#include <openvdb/tools/SignedFloodFill.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <xxhash.h>

#include <algorithm>
#include <assimp/Importer.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <sstream>
#include <unistd.h>

#include "sculpt/levelset/kernels.h"
#include "sculpt/core/check.h"
#include "sculpt/levelset/region.h"
#include "sculpture_grid.h"
#include "sculpture_impl.h"

namespace sculpt::levelset {
namespace {

using openvdb::Coord;
using openvdb::FloatGrid;

std::string Num(double v) { return FormatNumber(v); }

Status CheckPoint(const std::string& field, const Vec3& p) { return CheckFinitePoint(field, p); }

FloatGrid::Ptr NewGrid(const SculptureOptions& o) {
  internal::EnsureOpenVdbInitialized();
  const float bg = static_cast<float>(o.half_width * o.voxel_size);
  FloatGrid::Ptr grid = FloatGrid::create(bg);
  grid->setTransform(openvdb::math::Transform::createLinearTransform(o.voxel_size));
  grid->setGridClass(openvdb::GRID_LEVEL_SET);
  grid->setName(o.name);
  return grid;
}

// Fills the narrow band of an exact SDF over a world box, then flood-fills the inside sign.
// Leaf-sized blocks farther than the band plus their half-diagonal from the surface are skipped
// (an SDF is 1-Lipschitz), so cost follows the surface area, not the box volume.
Sculpture::Impl* FillFromSdf(const SculptureOptions& o, Vec3 lo, Vec3 hi,
                             const std::function<double(const Vec3&)>& sdf) {
  FloatGrid::Ptr grid = NewGrid(o);
  const double dx = o.voxel_size;
  const float bg = grid->background();
  const internal::IndexBox box = internal::WorldToIndexBox(lo, hi, dx, o.half_width + 2);
  auto acc = grid->getAccessor();
  const int kLeaf = 8;
  const double skip = bg + 0.5 * std::sqrt(3.0) * kLeaf * dx;
  auto floor8 = [](int v) { return v >= 0 ? (v / 8) * 8 : -(((-v) + 7) / 8) * 8; };
  for (int bz = floor8(box.min.z); bz <= box.max.z; bz += kLeaf) {
    for (int by = floor8(box.min.y); by <= box.max.y; by += kLeaf) {
      for (int bx = floor8(box.min.x); bx <= box.max.x; bx += kLeaf) {
        const Vec3 c{(bx + 3.5) * dx, (by + 3.5) * dx, (bz + 3.5) * dx};
        if (std::abs(sdf(c)) > skip) continue;
        for (int z = bz; z < bz + kLeaf; ++z) {
          for (int y = by; y < by + kLeaf; ++y) {
            for (int x = bx; x < bx + kLeaf; ++x) {
              const double d = sdf(Vec3{x * dx, y * dx, z * dx});
              if (std::abs(d) < bg) acc.setValueOn(Coord(x, y, z), static_cast<float>(d));
            }
          }
        }
      }
    }
  }
  openvdb::tools::signedFloodFill(grid->tree());
  openvdb::tools::pruneLevelSet(grid->tree());
  auto* impl = new Sculpture::Impl();
  impl->grid = grid;
  impl->name = o.name;
  impl->half_width = o.half_width;
  return impl;
}

Status ValidatePrimitiveSize(const SculptureOptions& o, const std::string& field, double v) {
  return CheckRange(field, v, o.voxel_size, kMaxPrimitiveVoxels * o.voxel_size);
}

void WriteObj(const std::vector<openvdb::Vec3s>& pts,
              const std::vector<openvdb::Vec3I>& tris, std::ofstream& out) {
  out << "# Sculpt mesh export\n";
  for (const auto& p : pts) out << "v " << p[0] << ' ' << p[1] << ' ' << p[2] << '\n';
  // OpenVDB's volumeToMesh winds faces clockwise seen from outside; OBJ wants counter-clockwise.
  for (const auto& t : tris) out << "f " << t[0] + 1 << ' ' << t[2] + 1 << ' ' << t[1] + 1 << '\n';
}

void WritePly(const std::vector<openvdb::Vec3s>& pts, const std::vector<openvdb::Vec3I>& tris,
              std::ofstream& out) {
  out << "ply\nformat binary_little_endian 1.0\ncomment Sculpt mesh export\n";
  out << "element vertex " << pts.size() << "\nproperty float x\nproperty float y\n"
      << "property float z\nelement face " << tris.size()
      << "\nproperty list uchar int vertex_indices\nend_header\n";
  for (const auto& p : pts) out.write(reinterpret_cast<const char*>(p.asPointer()), 12);
  for (const auto& t : tris) {
    const unsigned char n = 3;
    const int32_t idx[3] = {static_cast<int32_t>(t[0]), static_cast<int32_t>(t[2]),
                            static_cast<int32_t>(t[1])};
    out.write(reinterpret_cast<const char*>(&n), 1);
    out.write(reinterpret_cast<const char*>(idx), 12);
  }
}

}  // namespace

namespace internal {

void EnsureOpenVdbInitialized() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

const openvdb::FloatGrid& GridOf(const Sculpture& sculpture) { return *sculpture.impl().grid; }

IndexBox WorldToIndexBox(const Vec3& lo, const Vec3& hi, double dx, int pad) {
  IndexBox b;
  b.min = {static_cast<int>(std::floor(lo.x / dx)) - pad, static_cast<int>(std::floor(lo.y / dx)) - pad,
           static_cast<int>(std::floor(lo.z / dx)) - pad};
  b.max = {static_cast<int>(std::ceil(hi.x / dx)) + pad, static_cast<int>(std::ceil(hi.y / dx)) + pad,
           static_cast<int>(std::ceil(hi.z / dx)) + pad};
  return b;
}

DenseField ExtractDense(const FloatGrid& grid, const IndexBox& box) {
  DenseField f(box.min, box.Dims(), grid.background());
  const auto& tree = grid.tree();
  openvdb::FloatGrid::ConstAccessor acc = grid.getConstAccessor();
  const Int3 d = f.dims();
  // Walk leaf-aligned blocks so each leaf is looked up once, not once per voxel.
  auto floor8 = [](int v) { return v & ~7; };
  for (int bz = floor8(box.min.z); bz <= box.max.z; bz += 8) {
    for (int by = floor8(box.min.y); by <= box.max.y; by += 8) {
      for (int bx = floor8(box.min.x); bx <= box.max.x; bx += 8) {
        const Coord origin(bx, by, bz);
        const auto* leaf = tree.probeConstLeaf(origin);
        const float tile = leaf ? 0.f : acc.getValue(origin);
        // The leaf's values read straight from its buffer (offset x*64 + y*8 + z in the leaf).
        const float* values = leaf ? leaf->buffer().data() : nullptr;
        const int z0 = std::max(bz, box.min.z), z1 = std::min(bz + 7, box.max.z);
        const int y0 = std::max(by, box.min.y), y1 = std::min(by + 7, box.max.y);
        const int x0 = std::max(bx, box.min.x), x1 = std::min(bx + 7, box.max.x);
        for (int z = z0; z <= z1; ++z) {
          for (int y = y0; y <= y1; ++y) {
            float* row = &f.data()[f.Index(0, y - box.min.y, z - box.min.z)];
            if (!values) {
              std::fill(row + (x0 - box.min.x), row + (x1 - box.min.x) + 1, tile);
              continue;
            }
            const int yz = ((y & 7) << 3) | (z & 7);
            if (x1 - x0 == 7) {  // a whole row of the leaf: eight loads at fixed strides
              const float* column = values + yz;
              float* out = row + (x0 - box.min.x);
              for (int x = 0; x < 8; ++x) out[x] = column[x << 6];
              continue;
            }
            for (int x = x0; x <= x1; ++x) row[x - box.min.x] = values[((x & 7) << 6) | yz];
          }
        }
      }
    }
  }
  (void)d;
  return f;
}

double DenseInsideSum(const DenseField& phi, double dx) {
  double sum = 0;
  for (float v : phi.data()) sum += VolumeFraction(v, dx);
  return sum;
}

WriteBackResult WriteBack(FloatGrid& grid, const DenseField& before, const DenseField& after,
                          int margin, const int* lo, const int* hi) {
  WriteBackResult r;
  const float bg = grid.background();
  auto acc = grid.getAccessor();
  const Int3 o = after.origin();
  const Int3 d = after.dims();
  int from[3] = {margin, margin, margin};
  int to[3] = {d.x - margin, d.y - margin, d.z - margin};
  if (lo && hi) {
    for (int a = 0; a < 3; ++a) {
      from[a] = std::max(from[a], lo[a]);
      to[a] = std::min(to[a], hi[a]);
    }
  }
  // The leaves holding a changed voxel are marked in a grid of the box's leaves and listed from
  // it in (z, y, x) order: the sorted, unique list, without sorting one entry per run of voxels.
  int leaf_lo[3] = {0, 0, 0}, leaf_n[3] = {0, 0, 0};
  const int orig[3] = {o.x, o.y, o.z};
  for (int a = 0; a < 3; ++a) {
    if (from[a] >= to[a]) continue;
    leaf_lo[a] = (orig[a] + from[a]) >> 3;
    leaf_n[a] = ((orig[a] + to[a] - 1) >> 3) - leaf_lo[a] + 1;
  }
  std::vector<uint8_t> marked(static_cast<size_t>(leaf_n[0]) * leaf_n[1] * leaf_n[2], 0);
  for (int k = from[2]; k < to[2]; ++k) {
    for (int j = from[1]; j < to[1]; ++j) {
      uint8_t* leaf_row =
          marked.data() + (static_cast<size_t>(((o.z + k) >> 3) - leaf_lo[2]) * leaf_n[1] +
                           (((o.y + j) >> 3) - leaf_lo[1])) *
                              leaf_n[0];
      for (int i = from[0]; i < to[0]; ++i) {
        const size_t idx = after.Index(i, j, k);
        float v = after.data()[idx];
        if (v == before.data()[idx]) continue;
        const Coord c(o.x + i, o.y + j, o.z + k);
        if (v >= bg) {
          acc.setValueOff(c, bg);
        } else if (v <= -bg) {
          acc.setValueOff(c, -bg);
        } else {
          acc.setValueOn(c, v);
        }
        ++r.changed_voxels;
        leaf_row[((o.x + i) >> 3) - leaf_lo[0]] = 1;
      }
    }
  }
  std::vector<Int3> leaves;
  size_t n = 0;
  for (int z = 0; z < leaf_n[2]; ++z) {
    for (int y = 0; y < leaf_n[1]; ++y) {
      for (int x = 0; x < leaf_n[0]; ++x, ++n) {
        if (marked[n]) {
          leaves.push_back({(leaf_lo[0] + x) * 8, (leaf_lo[1] + y) * 8, (leaf_lo[2] + z) * 8});
        }
      }
    }
  }
  // Collapse leaves that became uniform and inactive, so the tree is canonical.
  for (const Int3& l : leaves) {
    const Coord origin(l.x, l.y, l.z);
    auto* leaf = grid.tree().probeLeaf(origin);
    if (!leaf || !leaf->isEmpty()) continue;
    const float first = leaf->getFirstValue();
    bool uniform = true;
    for (auto it = leaf->cbeginValueAll(); it; ++it) {
      if (*it != first) { uniform = false; break; }
    }
    if (uniform) grid.tree().addTile(1, origin, first, false);
  }
  r.dirty_leaves = std::move(leaves);
  return r;
}

}  // namespace internal

Status ValidateSculptureOptions(const SculptureOptions& o) {
  SCULPT_RETURN_IF_ERROR(CheckRange("voxel_size", o.voxel_size, kMinVoxelSize, kMaxVoxelSize));
  if (o.half_width < kMinHalfWidth || o.half_width > kMaxHalfWidth) {
    return Outside("half_width", std::to_string(o.half_width),
                   std::string("[") + std::to_string(kMinHalfWidth) + ", " +
                       std::to_string(kMaxHalfWidth) + "] voxels");
  }
  return Status::Ok();
}

Sculpture::Sculpture(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Sculpture::Sculpture(Sculpture&&) noexcept = default;
Sculpture& Sculpture::operator=(Sculpture&&) noexcept = default;
Sculpture::~Sculpture() = default;

class SculptureAccess {
 public:
  static Sculpture Make(std::unique_ptr<Sculpture::Impl> impl) {
    Sculpture s(std::move(impl));
    s.impl_->bounds = s.impl_->grid->evalActiveVoxelBoundingBox();
    s.impl_->volume = s.ComputeVolume();
    s.impl_->reference_volume = s.impl_->volume;
    return s;
  }
};

StatusOr<Sculpture> Sculpture::MakeSphere(const SculptureOptions& o, Vec3 c, double r) {
  SCULPT_RETURN_IF_ERROR(ValidateSculptureOptions(o));
  SCULPT_RETURN_IF_ERROR(CheckPoint("sphere.center", c));
  SCULPT_RETURN_IF_ERROR(ValidatePrimitiveSize(o, "sphere.radius", r));
  auto* impl = FillFromSdf(o, c - Vec3{r, r, r}, c + Vec3{r, r, r},
                           [c, r](const Vec3& p) { return (p - c).Length() - r; });
  return SculptureAccess::Make(std::unique_ptr<Impl>(impl));
}

StatusOr<Sculpture> Sculpture::MakeBox(const SculptureOptions& o, Vec3 lo, Vec3 hi) {
  SCULPT_RETURN_IF_ERROR(ValidateSculptureOptions(o));
  SCULPT_RETURN_IF_ERROR(CheckPoint("box.min", lo));
  SCULPT_RETURN_IF_ERROR(CheckPoint("box.max", hi));
  SCULPT_RETURN_IF_ERROR(ValidatePrimitiveSize(o, "box.size.x", hi.x - lo.x));
  SCULPT_RETURN_IF_ERROR(ValidatePrimitiveSize(o, "box.size.y", hi.y - lo.y));
  SCULPT_RETURN_IF_ERROR(ValidatePrimitiveSize(o, "box.size.z", hi.z - lo.z));
  const ToolShape box = ToolShape::Box((lo + hi) * 0.5, (hi - lo) * 0.5);
  auto* impl = FillFromSdf(o, lo, hi, [box](const Vec3& p) { return ToolSignedDistance(box, p); });
  return SculptureAccess::Make(std::unique_ptr<Impl>(impl));
}

StatusOr<Sculpture> Sculpture::MakeCapsule(const SculptureOptions& o, Vec3 a, Vec3 b, double r) {
  SCULPT_RETURN_IF_ERROR(ValidateSculptureOptions(o));
  SCULPT_RETURN_IF_ERROR(CheckPoint("capsule.a", a));
  SCULPT_RETURN_IF_ERROR(CheckPoint("capsule.b", b));
  SCULPT_RETURN_IF_ERROR(ValidatePrimitiveSize(o, "capsule.radius", r));
  SCULPT_RETURN_IF_ERROR(CheckRange("capsule.length", (b - a).Length(), 0,
                                    kMaxPrimitiveVoxels * o.voxel_size));
  const ToolShape cap = ToolShape::Capsule(a, b, r);
  const Aabb bb = ToolBounds(cap);
  auto* impl = FillFromSdf(o, bb.min, bb.max,
                           [cap](const Vec3& p) { return ToolSignedDistance(cap, p); });
  return SculptureAccess::Make(std::unique_ptr<Impl>(impl));
}

StatusOr<Sculpture> Sculpture::MakeTorus(const SculptureOptions& o, Vec3 c, double major,
                                         double minor) {
  SCULPT_RETURN_IF_ERROR(ValidateSculptureOptions(o));
  SCULPT_RETURN_IF_ERROR(CheckPoint("torus.center", c));
  SCULPT_RETURN_IF_ERROR(ValidatePrimitiveSize(o, "torus.minor_radius", minor));
  SCULPT_RETURN_IF_ERROR(ValidatePrimitiveSize(o, "torus.major_radius", major));
  if (minor >= major) {
    return Outside("torus.minor_radius", Num(minor),
                   std::string("(0, major_radius=") + Num(major) + ")");
  }
  const double R = major + minor;
  auto* impl = FillFromSdf(o, c - Vec3{R, R, minor}, c + Vec3{R, R, minor},
                           [c, major, minor](const Vec3& p) {
                             const Vec3 q = p - c;
                             const double ring = std::sqrt(q.x * q.x + q.y * q.y) - major;
                             return std::sqrt(ring * ring + q.z * q.z) - minor;
                           });
  return SculptureAccess::Make(std::unique_ptr<Impl>(impl));
}

StatusOr<Sculpture> Sculpture::FromMeshFile(const SculptureOptions& o, const std::string& path) {
  SCULPT_RETURN_IF_ERROR(ValidateSculptureOptions(o));
  if (!std::filesystem::exists(path)) return NotFound("mesh file " + path + " does not exist");
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(
      path, aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_PreTransformVertices);
  if (!scene || !scene->mRootNode) {
    return InvalidArgument("mesh file " + path + ": " + importer.GetErrorString());
  }
  std::vector<openvdb::Vec3s> points;
  std::vector<openvdb::Vec3I> tris;
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* mesh = scene->mMeshes[m];
    const auto base = static_cast<unsigned>(points.size());
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const aiVector3D& p = mesh->mVertices[v];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
        return InvalidArgument("mesh file " + path + ": vertex " + std::to_string(v) +
                               " is not finite");
      }
      points.emplace_back(p.x, p.y, p.z);
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices != 3) continue;
      tris.emplace_back(base + face.mIndices[0], base + face.mIndices[1], base + face.mIndices[2]);
    }
  }
  if (tris.empty()) return InvalidArgument("mesh file " + path + " has no triangles");
  FloatGrid::Ptr shape = NewGrid(o);
  const std::vector<openvdb::Vec4I> quads;
  internal::EnsureOpenVdbInitialized();
  FloatGrid::Ptr grid = openvdb::tools::meshToLevelSet<FloatGrid>(
      shape->transform(), points, tris, quads, static_cast<float>(o.half_width));
  grid->setName(o.name);
  grid->setGridClass(openvdb::GRID_LEVEL_SET);
  auto* impl = new Impl();
  impl->grid = grid;
  impl->name = o.name;
  impl->half_width = o.half_width;
  return SculptureAccess::Make(std::unique_ptr<Impl>(impl));
}

StatusOr<Sculpture> Sculpture::LoadVdb(const std::string& path) {
  internal::EnsureOpenVdbInitialized();
  if (!std::filesystem::exists(path)) return NotFound(".vdb file " + path + " does not exist");
  try {
    openvdb::io::File file(path);
    file.open();
    openvdb::GridPtrVecPtr grids = file.getGrids();
    file.close();
    for (auto& base : *grids) {
      auto grid = openvdb::gridPtrCast<FloatGrid>(base);
      if (!grid || grid->getGridClass() != openvdb::GRID_LEVEL_SET) continue;
      const double dx = grid->voxelSize()[0];
      auto impl = std::make_unique<Impl>();
      impl->grid = grid;
      impl->name = grid->getName();
      impl->half_width = static_cast<int>(std::lround(grid->background() / dx));
      if (auto m = grid->getMetadata<openvdb::StringMetadata>("scene_name")) impl->name = m->value();
      Sculpture s = SculptureAccess::Make(std::move(impl));
      if (auto m = grid->getMetadata<openvdb::DoubleMetadata>("reference_volume")) {
        s.set_reference_volume(m->value());
      }
      // The incrementally tracked volume, not a recomputation: compensation aims at reference
      // minus this, so recovery from a snapshot plus the log tail (and a replica loaded from
      // the file) must start from the very value the live server held.
      if (auto m = grid->getMetadata<openvdb::DoubleMetadata>("tracked_volume")) {
        s.impl().volume = m->value();
      }
      if (auto m = grid->getMetadata<openvdb::Int64Metadata>("edits_since_reinit")) {
        s.impl().edits_since_reinit = static_cast<uint64_t>(std::max<int64_t>(0, m->value()));
      }
      SCULPT_RETURN_IF_ERROR(internal::AdoptMaterialGrids(s.impl(), *grids));
      SCULPT_RETURN_IF_ERROR(ValidateSculptureOptions(
          SculptureOptions{dx, s.half_width(), s.name()}));
      return s;
    }
    return InvalidArgument(".vdb file " + path + " holds no float level-set grid");
  } catch (const std::exception& e) {
    return DataLoss(".vdb file " + path + ": " + e.what());
  }
}

namespace {
void StampMetadata(openvdb::FloatGrid& grid, const Sculpture::Impl& impl) {
  grid.setName(impl.name);
  grid.setGridClass(openvdb::GRID_LEVEL_SET);
  grid.insertMeta("voxel_size", openvdb::DoubleMetadata(impl.dx()));
  grid.insertMeta("half_width", openvdb::Int32Metadata(impl.half_width));
  grid.insertMeta("scene_name", openvdb::StringMetadata(impl.name));
  grid.insertMeta("reference_volume", openvdb::DoubleMetadata(impl.reference_volume));
  grid.insertMeta("tracked_volume", openvdb::DoubleMetadata(impl.volume));
  grid.insertMeta("edits_since_reinit",
                  openvdb::Int64Metadata(static_cast<int64_t>(impl.edits_since_reinit)));
}
}  // namespace

Status Sculpture::SaveVdb(const std::string& path) const {
  try {
    FloatGrid::Ptr grid = impl_->grid;
    StampMetadata(*grid, *impl_);
    const std::string tmp = path + ".tmp";
    openvdb::io::File file(tmp);
    openvdb::GridPtrVec grids{grid};
    for (auto& m : internal::MaterialGridsForFile(*impl_)) grids.push_back(m);  // one per material
    file.write(grids);
    file.close();
    std::filesystem::rename(tmp, path);
  } catch (const std::exception& e) {
    return Internal("writing " + path + ": " + e.what());
  }
  return Status::Ok();
}

namespace {
// A private temporary .vdb path (process id and a per-call address keep concurrent calls apart).
std::filesystem::path TempVdbPath(const void* tag) {
  return std::filesystem::temp_directory_path() /
         ("sculpt-" + std::to_string(::getpid()) + "-" +
          std::to_string(reinterpret_cast<uintptr_t>(tag)) + ".vdb");
}

struct RemoveOnExit {
  std::filesystem::path path;
  ~RemoveOnExit() {
    std::error_code ec;
    std::filesystem::remove(path, ec);
  }
};
}  // namespace

// Both directions go through a temporary file and SaveVdb/LoadVdb: OpenVDB 10's io::Stream
// crashes in its destructor after it threw on a malformed stream, io::File fails cleanly.
StatusOr<std::string> Sculpture::SerializeVdb() const {
  const RemoveOnExit tmp{TempVdbPath(this)};
  SCULPT_RETURN_IF_ERROR(SaveVdb(tmp.path.string()));
  std::ifstream in(tmp.path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (!in.eof() && in.fail()) return Internal("reading " + tmp.path.string() + " failed");
  return bytes;
}

StatusOr<Sculpture> Sculpture::DeserializeVdb(const std::string& bytes) {
  const RemoveOnExit tmp{TempVdbPath(&bytes)};
  {
    std::ofstream out(tmp.path, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!out) return Internal("cannot write temporary file " + tmp.path.string());
  }
  return LoadVdb(tmp.path.string());
}

StatusOr<MeshStats> Sculpture::ExportMesh(const std::string& path, double adaptivity) const {
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext != ".obj" && ext != ".ply") {
    return Outside("mesh path extension", ext, "{.obj, .ply}");
  }
  std::vector<openvdb::Vec3s> points;
  std::vector<openvdb::Vec3I> tris;
  std::vector<openvdb::Vec4I> quads;
  openvdb::tools::volumeToMesh(*impl_->grid, points, tris, quads, 0.0, adaptivity);
  tris.reserve(tris.size() + 2 * quads.size());
  for (const auto& q : quads) {
    tris.emplace_back(q[0], q[1], q[2]);
    tris.emplace_back(q[0], q[2], q[3]);
  }
  std::ofstream out(path, std::ios::binary);
  if (!out) return Internal("cannot open " + path + " for writing");
  if (ext == ".obj") {
    WriteObj(points, tris, out);
  } else {
    WritePly(points, tris, out);
  }
  if (!out) return Internal("write to " + path + " failed");
  return MeshStats{points.size(), tris.size()};
}

Sculpture Sculpture::Clone() const {
  auto impl = std::make_unique<Impl>(*impl_);
  impl->grid = impl_->grid->deepCopy();
  internal::DeepCopyMaterials(*impl);
  return Sculpture(std::move(impl));
}

double Sculpture::voxel_size() const { return impl_->dx(); }
int Sculpture::half_width() const { return impl_->half_width; }
const std::string& Sculpture::name() const { return impl_->name; }
double Sculpture::volume() const { return impl_->volume; }
double Sculpture::reference_volume() const { return impl_->reference_volume; }
void Sculpture::set_reference_volume(double v) { impl_->reference_volume = v; }

double Sculpture::ComputeVolume() const {
  const double dx = impl_->dx();
  double sum = 0;
  for (auto it = impl_->grid->tree().cbeginValueAll(); it; ++it) {
    sum += VolumeFraction(*it, dx) * static_cast<double>(it.getVoxelCount());
  }
  return sum * dx * dx * dx;
}

uint64_t Sculpture::StateHash() const {
  XXH3_state_t* st = XXH3_createState();
  XXH3_64bits_reset(st);
  const FloatGrid& g = *impl_->grid;
  const openvdb::Mat4d m = g.transform().baseMap()->getAffineMap()->getMat4();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      const double v = m(r, c);
      XXH3_64bits_update(st, &v, sizeof v);
    }
  }
  const float bg = g.background();
  XXH3_64bits_update(st, &bg, sizeof bg);
  // Leaves in tree order (the root table is sorted by coordinate, children by offset), so the
  // order is canonical; then the tiles.
  for (auto leaf = g.tree().cbeginLeaf(); leaf; ++leaf) {
    const Coord o = leaf->origin();
    const int32_t oc[3] = {o.x(), o.y(), o.z()};
    XXH3_64bits_update(st, oc, sizeof oc);
    const auto& mask = leaf->getValueMask();
    for (openvdb::Index32 w = 0; w < mask.WORD_COUNT; ++w) {
      const openvdb::Index64 word = mask.template getWord<openvdb::Index64>(w);
      XXH3_64bits_update(st, &word, sizeof word);
    }
    XXH3_64bits_update(st, leaf->buffer().data(), leaf->SIZE * sizeof(float));
  }
  for (auto it = g.tree().cbeginValueAll(); it; ++it) {
    if (it.isVoxelValue()) continue;
    const Coord o = it.getCoord();
    const int32_t rec[5] = {o.x(), o.y(), o.z(), static_cast<int32_t>(it.getLevel()),
                            it.isValueOn() ? 1 : 0};
    XXH3_64bits_update(st, rec, sizeof rec);
    const float v = *it;
    XXH3_64bits_update(st, &v, sizeof v);
  }
  const uint64_t h = XXH3_64bits_digest(st);
  XXH3_freeState(st);
  return h;
}

uint64_t Sculpture::ActiveVoxelCount() const { return impl_->grid->activeVoxelCount(); }
uint64_t Sculpture::LeafCount() const { return impl_->grid->tree().leafCount(); }
uint64_t Sculpture::MemoryBytes() const { return impl_->grid->memUsage(); }

Aabb Sculpture::WorldBounds() const {
  const openvdb::CoordBBox& bb = impl_->bounds;
  const double dx = impl_->dx();
  if (bb.empty()) return Aabb{{1, 1, 1}, {0, 0, 0}};
  return Aabb{{bb.min().x() * dx, bb.min().y() * dx, bb.min().z() * dx},
              {bb.max().x() * dx, bb.max().y() * dx, bb.max().z() * dx}};
}

Sculpture::EikonalReport Sculpture::MeasureEikonal() const {
  // Per leaf, a dense copy with a one-voxel halo and the kernels' one-sided (Godunov) measure,
  // which skips the kinks where a one-sided difference is meaningless (creases, medial axes).
  EikonalReport r;
  const double dx = impl_->dx();
  double sum = 0;
  uint64_t outside = 0;
  for (auto leaf = impl_->grid->tree().cbeginLeaf(); leaf; ++leaf) {
    if (leaf->isEmpty()) continue;
    const Coord o = leaf->origin();
    const internal::IndexBox box{{o.x() - 1, o.y() - 1, o.z() - 1},
                                 {o.x() + 8, o.y() + 8, o.z() + 8}};
    const DenseField f = internal::ExtractDense(*impl_->grid, box);
    VoxelList active;
    for (auto v = leaf->cbeginValueOn(); v; ++v) {
      const Coord c = v.getCoord();
      active.push_back(static_cast<uint32_t>(f.Index(c.x() - box.min.x, c.y() - box.min.y,
                                                      c.z() - box.min.z)));
    }
    for (uint32_t idx : active) {
      const VoxelList one{idx};
      const EikonalStats e = levelset::MeasureEikonal(f, one, dx, 2 * dx);
      if (e.samples == 0) continue;
      sum += e.mean_abs_error;
      if (e.max_abs_error > 0.5) ++outside;
      ++r.samples;
    }
  }
  if (r.samples > 0) {
    r.mean_abs_error = sum / r.samples;
    r.fraction_outside_half = static_cast<double>(outside) / r.samples;
  }
  return r;
}

Status Sculpture::CheckLevelSet(int checks) const {
  const std::string problem =
      openvdb::tools::checkLevelSet(*impl_->grid, static_cast<size_t>(std::clamp(checks, 1, 9)));
  if (!problem.empty()) return Internal("checkLevelSet: " + problem);
  return Status::Ok();
}

double Sculpture::SampleWorld(const Vec3& p) const {
  // GridSampler keeps a reference to the accessor: it must outlive the sampler, not be a temporary.
  const FloatGrid::ConstAccessor acc = impl_->grid->getConstAccessor();
  openvdb::tools::GridSampler<FloatGrid::ConstAccessor, openvdb::tools::BoxSampler> sampler(
      acc, impl_->grid->transform());
  return sampler.wsSample(openvdb::Vec3d(p.x, p.y, p.z));
}

}  // namespace sculpt::levelset

namespace sculpt::levelset {

StatusOr<Sculpture> MakeEmptySculpture(const SculptureOptions& o) {
  SCULPT_RETURN_IF_ERROR(ValidateSculptureOptions(o));
  auto impl = std::make_unique<Sculpture::Impl>();
  impl->grid = NewGrid(o);
  impl->name = o.name;
  impl->half_width = o.half_width;
  return SculptureAccess::Make(std::move(impl));
}

}  // namespace sculpt::levelset
