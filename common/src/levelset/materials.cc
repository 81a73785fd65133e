/// @brief Material fraction grids of a Sculpture: declaration, paint (seed 001 eq. 4.3), the
/// carry rule that edits apply, volumes, the simplex check, and their .vdb form.
#include "sculpt/levelset/materials.h"

#include <openvdb/tools/Interpolation.h>
#include <xxhash.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <set>
#include <tuple>

#include "materials_internal.h"
#include "sculpt/core/check.h"
#include "sculpt/hetero/material.h"
#include "sculpt/levelset/kernels.h"
#include "sculpture_impl.h"

namespace sculpt::levelset {
namespace {

using openvdb::Coord;
using openvdb::FloatGrid;

constexpr const char* kIndexMeta = "sculpt_material_index";
constexpr const char* kNameMeta = "sculpt_material_name";
constexpr const char* kColourMeta = "sculpt_material_colour";
constexpr size_t kMaxNameBytes = 64;

// Voxels within this many voxels outside the surface carry fractions too: the trilinear stencil of
// a surface point reads one voxel outside, and a viewer's vertex colours come from there.
constexpr double kOuterBandVoxels = 2.0;

FloatGrid::Ptr NewFractionGrid(const Sculpture::Impl& impl, float fill, const std::string& name) {
  FloatGrid::Ptr g = FloatGrid::create(fill);
  g->setTransform(impl.grid->transform().copy());
  g->setGridClass(openvdb::GRID_UNKNOWN);
  g->setName("material:" + name);
  return g;
}

Status RequireMaterials(const Sculpture& s) {
  if (s.impl().fractions.empty()) {
    return FailedPrecondition("the sculpture declares no materials (SetMaterials first)");
  }
  return Status::Ok();
}

Int3 LeafOf(const Coord& c) { return {c.x() & ~7, c.y() & ~7, c.z() & ~7}; }

bool LeafLess(const Int3& a, const Int3& b) {
  return std::tie(a.z, a.y, a.x) < std::tie(b.z, b.y, b.x);
}

void SortUnique(std::vector<Int3>& v) {
  std::sort(v.begin(), v.end(), LeafLess);
  v.erase(std::unique(v.begin(), v.end()), v.end());
}

// Applies `op(old, new)` at every voxel inside the tool that is inside the object or within
// kOuterBandVoxels of it. `op` writes the new vector from the old one (both of size n).
template <typename Op>
MaterialEditResult EditInTool(Sculpture& sculpture, const ToolShape& tool, Op op) {
  const auto t0 = std::chrono::steady_clock::now();
  Sculpture::Impl& impl = sculpture.impl();
  const size_t n = impl.fractions.size();
  const double dx = impl.dx();
  const float tau = static_cast<float>(kOuterBandVoxels * dx);
  const Aabb tb = ToolBounds(tool);
  const internal::IndexBox box = internal::WorldToIndexBox(tb.min, tb.max, dx, 1);
  FloatGrid::ConstAccessor phi = impl.grid->getConstAccessor();
  std::vector<FloatGrid::Accessor> acc;
  for (auto& g : impl.fractions) acc.push_back(g->getAccessor());
  std::vector<double> old(n), now(n);
  std::vector<float> stored(n), next(n);
  MaterialEditResult res;
  const bool sphere = tool.kind == ToolKind::kSphere;
  for (int z = box.min.z; z <= box.max.z; ++z) {
    for (int y = box.min.y; y <= box.max.y; ++y) {
      for (int x = box.min.x; x <= box.max.x; ++x) {
        const Vec3 p{x * dx, y * dx, z * dx};
        const double t =
            sphere ? (p - tool.center).Length() - tool.size.x : ToolSignedDistance(tool, p);
        if (t >= 0) continue;
        const Coord c(x, y, z);
        if (!(phi.getValue(c) < tau)) continue;
        for (size_t m = 0; m < n; ++m) {
          stored[m] = acc[m].getValue(c);
          old[m] = stored[m];
        }
        op(std::span<const double>(old), std::span<double>(now));
        internal::ToSimplexFloat(now, next);
        if (std::equal(next.begin(), next.end(), stored.begin())) continue;
        for (size_t m = 0; m < n; ++m) acc[m].setValueOn(c, next[m]);
        ++res.changed_voxels;
        const Int3 l = LeafOf(c);
        if (res.dirty_leaves.empty() || !(res.dirty_leaves.back() == l)) {
          res.dirty_leaves.push_back(l);
        }
      }
    }
  }
  SortUnique(res.dirty_leaves);
  res.elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

Status ValidatePaintTool(const Sculpture& s, const ToolShape& tool) {
  const double dx = s.voxel_size();
  return ValidateTool(tool, 0.5 * dx, kMaxPaintToolVoxels * dx);
}

void HashGrid(XXH3_state_t* st, const FloatGrid& g) {
  const float bg = g.background();
  XXH3_64bits_update(st, &bg, sizeof bg);
  for (auto leaf = g.tree().cbeginLeaf(); leaf; ++leaf) {
    const Coord o = leaf->origin();
    const int32_t oc[3] = {o.x(), o.y(), o.z()};
    XXH3_64bits_update(st, oc, sizeof oc);
    XXH3_64bits_update(st, leaf->buffer().data(), leaf->SIZE * sizeof(float));
  }
  for (auto it = g.tree().cbeginValueAll(); it; ++it) {
    if (it.isVoxelValue() || (*it == bg && !it.isValueOn())) continue;  // empty slots
    const Coord o = it.getCoord();
    const int32_t rec[4] = {o.x(), o.y(), o.z(), static_cast<int32_t>(it.getLevel())};
    XXH3_64bits_update(st, rec, sizeof rec);
    const float v = *it;
    XXH3_64bits_update(st, &v, sizeof v);
  }
}

}  // namespace

Status ValidateMaterialDecls(const std::vector<MaterialDecl>& materials) {
  if (materials.empty() || static_cast<int>(materials.size()) > kMaxSculptureMaterials) {
    return Outside("materials.size", std::to_string(materials.size()),
                   std::string("[1, ") + std::to_string(kMaxSculptureMaterials) + "]");
  }
  std::set<std::string> names;
  for (size_t i = 0; i < materials.size(); ++i) {
    const std::string f = "materials[" + std::to_string(i) + "]";
    const MaterialDecl& m = materials[i];
    if (m.name.empty() || m.name.size() > kMaxNameBytes) {
      return Outside(f + ".name.size", std::to_string(m.name.size()),
                     std::string("[1, ") + std::to_string(kMaxNameBytes) + "] bytes");
    }
    if (!names.insert(m.name).second) {
      return Outside(f + ".name", m.name, "the names not yet declared");
    }
    for (int c = 0; c < 3; ++c) {
      SCULPT_RETURN_IF_ERROR(
          CheckRange(f + ".colour[" + std::to_string(c) + "]", m.colour[c], 0.0, 1.0));
    }
  }
  return Status::Ok();
}

Status ValidateFractionVector(const std::string& field, std::span<const double> a, int materials) {
  // Seed 001 (4.2), the hyperpatch library's rule and tolerance; the sum is reported with nine
  // digits, so an excess of 2e-6 is visible in the message.
  static_assert(kFractionTolerance == hetero::kSimplexSumTolerance);
  if (static_cast<int>(a.size()) != materials) {
    return Outside(field + ".size", std::to_string(a.size()),
                   std::string("[") + std::to_string(materials) + ", " + std::to_string(materials) +
                       "] (one fraction per declared material)");
  }
  double sum = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    SCULPT_RETURN_IF_ERROR(CheckRange(field + "[" + std::to_string(i) + "]", a[i], 0.0, 1.0));
    sum += a[i];
  }
  if (std::abs(sum - 1.0) > kFractionTolerance) {
    char value[32];
    char range[96];
    std::snprintf(value, sizeof value, "%.9g", sum);
    std::snprintf(range, sizeof range, "[%.9g, %.9g] (fractions sum to 1)",
                  1.0 - kFractionTolerance, 1.0 + kFractionTolerance);
    return Outside(field + ".sum", value, range);
  }
  return Status::Ok();
}

Status SetMaterials(Sculpture& sculpture, const std::vector<MaterialDecl>& materials,
                    std::span<const double> fill) {
  SCULPT_RETURN_IF_ERROR(ValidateMaterialDecls(materials));
  const int n = static_cast<int>(materials.size());
  std::vector<double> f =
      fill.empty() ? hetero::PureMaterial(0, n) : std::vector<double>(fill.begin(), fill.end());
  SCULPT_RETURN_IF_ERROR(ValidateFractionVector("fill", f, n));
  std::vector<float> stored(static_cast<size_t>(n));
  internal::ToSimplexFloat(f, stored);
  Sculpture::Impl& impl = sculpture.impl();
  impl.materials = materials;
  impl.fractions.clear();
  for (int m = 0; m < n; ++m) {
    impl.fractions.push_back(NewFractionGrid(impl, stored[m], materials[m].name));
  }
  return Status::Ok();
}

int MaterialCount(const Sculpture& sculpture) {
  return static_cast<int>(sculpture.impl().fractions.size());
}

const std::vector<MaterialDecl>& Materials(const Sculpture& sculpture) {
  return sculpture.impl().materials;
}

StatusOr<std::vector<double>> FractionsAtVoxel(const Sculpture& sculpture, const Int3& v) {
  SCULPT_RETURN_IF_ERROR(RequireMaterials(sculpture));
  std::vector<double> out;
  for (const auto& g : sculpture.impl().fractions) {
    out.push_back(g->tree().getValue(Coord(v.x, v.y, v.z)));
  }
  return out;
}

StatusOr<std::vector<double>> FractionsAtWorld(const Sculpture& sculpture, const Vec3& p) {
  SCULPT_RETURN_IF_ERROR(RequireMaterials(sculpture));
  SCULPT_RETURN_IF_ERROR(CheckFinitePoint("point", p));
  std::vector<double> out;
  for (const auto& g : sculpture.impl().fractions) {
    // GridSampler keeps a reference to the accessor: it must outlive the sampler.
    const FloatGrid::ConstAccessor acc = g->getConstAccessor();
    openvdb::tools::GridSampler<FloatGrid::ConstAccessor, openvdb::tools::BoxSampler> sampler(
        acc, g->transform());
    out.push_back(sampler.wsSample(openvdb::Vec3d(p.x, p.y, p.z)));
  }
  return out;
}

StatusOr<std::array<double, 3>> ColourAtWorld(const Sculpture& sculpture, const Vec3& p) {
  auto a = FractionsAtWorld(sculpture, p);
  if (!a.ok()) return a.status();
  std::array<double, 3> rgb{0, 0, 0};
  const auto& decl = sculpture.impl().materials;
  for (size_t m = 0; m < a->size(); ++m) {
    for (int c = 0; c < 3; ++c) rgb[c] += (*a)[m] * decl[m].colour[c];
  }
  return rgb;
}

StatusOr<MaterialEditResult> PaintMaterial(Sculpture& sculpture, const ToolShape& tool,
                                           int material, double weight) {
  SCULPT_RETURN_IF_ERROR(RequireMaterials(sculpture));
  SCULPT_RETURN_IF_ERROR(ValidatePaintTool(sculpture, tool));
  const int n = MaterialCount(sculpture);
  SCULPT_RETURN_IF_ERROR(CheckRange("paint.material", material, 0, n - 1));
  SCULPT_RETURN_IF_ERROR(CheckRange("paint.weight", weight, 0.0, 1.0));
  const size_t mat = static_cast<size_t>(material);
  return EditInTool(sculpture, tool, [&](std::span<const double> a, std::span<double> out) {
    // Seed 001 eq. 4.3: e_material (+)_weight a; V is closed under it for weight in [0, 1].
    for (size_t m = 0; m < a.size(); ++m) {
      out[m] = weight * (m == mat ? 1.0 : 0.0) + (1.0 - weight) * a[m];
    }
  });
}

StatusOr<MaterialEditResult> FillMaterial(Sculpture& sculpture, const ToolShape& tool,
                                          std::span<const double> fractions) {
  SCULPT_RETURN_IF_ERROR(RequireMaterials(sculpture));
  SCULPT_RETURN_IF_ERROR(ValidatePaintTool(sculpture, tool));
  SCULPT_RETURN_IF_ERROR(
      ValidateFractionVector("fill.fractions", fractions, MaterialCount(sculpture)));
  return EditInTool(sculpture, tool, [&](std::span<const double>, std::span<double> out) {
    std::copy(fractions.begin(), fractions.end(), out.begin());
  });
}

std::vector<double> MaterialVolumes(const Sculpture& sculpture) {
  const Sculpture::Impl& impl = sculpture.impl();
  const size_t n = impl.fractions.size();
  std::vector<double> vol(n, 0.0);
  if (n == 0) return vol;
  const double dx = impl.dx();
  std::vector<FloatGrid::ConstAccessor> acc;
  for (const auto& g : impl.fractions) acc.push_back(g->getConstAccessor());
  // Leaf cell by leaf cell over the SDF's bounds (which enclose the band, hence the inside):
  // walking the tree's tile slots instead would visit every empty slot of its internal nodes.
  const openvdb::CoordBBox& bb = impl.bounds;
  if (bb.empty()) return vol;
  FloatGrid::ConstAccessor phi = impl.grid->getConstAccessor();
  for (int z = bb.min().z() & ~7; z <= bb.max().z(); z += 8) {
    for (int y = bb.min().y() & ~7; y <= bb.max().y(); y += 8) {
      for (int x = bb.min().x() & ~7; x <= bb.max().x(); x += 8) {
        const Coord c(x, y, z);
        if (const auto* leaf = phi.probeConstLeaf(c)) {
          for (auto v = leaf->cbeginValueAll(); v; ++v) {
            const double h = VolumeFraction(*v, dx);
            if (h == 0) continue;
            for (size_t m = 0; m < n; ++m) vol[m] += h * acc[m].getValue(v.getCoord());
          }
          continue;
        }
        // A tile of the SDF (the deep inside): a leaf of a fraction grid is summed, a tile of it
        // (which covers the whole cell) counts 512 times.
        const double h = VolumeFraction(phi.getValue(c), dx);
        if (h == 0) continue;
        for (size_t m = 0; m < n; ++m) {
          double sum = 0;
          if (const auto* fl = acc[m].probeConstLeaf(c)) {
            for (auto v = fl->cbeginValueAll(); v; ++v) sum += *v;
          } else {
            sum = 512.0 * acc[m].getValue(c);
          }
          vol[m] += h * sum;
        }
      }
    }
  }
  for (double& v : vol) v *= dx * dx * dx;
  return vol;
}

SimplexReport CheckSimplex(const Sculpture& sculpture) {
  SimplexReport r;
  const Sculpture::Impl& impl = sculpture.impl();
  const size_t n = impl.fractions.size();
  if (n == 0) return r;
  r.min_fraction = std::numeric_limits<double>::max();
  r.max_fraction = -std::numeric_limits<double>::max();
  std::vector<FloatGrid::ConstAccessor> acc;
  for (const auto& g : impl.fractions) acc.push_back(g->getConstAccessor());
  auto check = [&](const Coord* c) {
    double sum = 0;
    for (size_t m = 0; m < n; ++m) {
      const double v = c ? acc[m].getValue(*c) : impl.fractions[m]->background();
      if (!std::isfinite(v)) {
        ++r.non_finite;
        continue;
      }
      r.min_fraction = std::min(r.min_fraction, v);
      r.max_fraction = std::max(r.max_fraction, v);
      sum += v;
    }
    r.max_sum_error = std::max(r.max_sum_error, std::abs(sum - 1.0));
    ++r.vectors;
  };
  check(nullptr);
  // Values are piecewise constant between stored nodes, and tiles nest (one of two overlapping
  // tiles contains the other), so the leaves of any grid plus the tile origins of every grid
  // visit every distinct combination.
  std::vector<Int3> leaves;
  for (const auto& g : impl.fractions) {
    for (auto leaf = g->tree().cbeginLeaf(); leaf; ++leaf) leaves.push_back(LeafOf(leaf->origin()));
  }
  SortUnique(leaves);
  for (const Int3& l : leaves) {
    for (int z = 0; z < 8; ++z)
      for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) {
          const Coord c(l.x + x, l.y + y, l.z + z);
          check(&c);
        }
  }
  // A tile holding its grid's background adds no combination the background vector and the
  // other grids' tiles and leaves do not already cover.
  for (const auto& g : impl.fractions) {
    const float bg = g->background();
    for (auto it = g->tree().cbeginValueAll(); it; ++it) {
      if (it.isVoxelValue() || *it == bg) continue;
      const Coord c = it.getCoord();
      check(&c);
    }
  }
  return r;
}

uint64_t MaterialMemoryBytes(const Sculpture& sculpture) {
  uint64_t bytes = 0;
  for (const auto& g : sculpture.impl().fractions) bytes += g->memUsage();
  return bytes;
}

uint64_t MaterialStateHash(const Sculpture& sculpture) {
  const Sculpture::Impl& impl = sculpture.impl();
  if (impl.fractions.empty()) return 0;
  XXH3_state_t* st = XXH3_createState();
  XXH3_64bits_reset(st);
  for (const auto& g : impl.fractions) HashGrid(st, *g);
  const uint64_t h = XXH3_64bits_digest(st);
  XXH3_freeState(st);
  return h;
}

namespace internal {

void ToSimplexFloat(std::span<double> v, std::span<float> out) {
  double sum = 0;
  bool overshoot = false;
  for (double x : v) {
    if (!std::isfinite(x) || x < 0) overshoot = true;
    sum += x;
  }
  if (overshoot || std::abs(sum - 1.0) > kFractionTolerance || sum <= 0) {
    const hetero::Fractions p = hetero::ProjectToSimplex(v);
    std::copy(p.begin(), p.end(), v.begin());
  } else {
    for (double& x : v) x /= sum;
  }
  for (size_t m = 0; m < v.size(); ++m) out[m] = static_cast<float>(v[m]);
}

void CarryFractions(Sculpture::Impl& impl, const DenseField& before, const DenseField& after,
                    int margin) {
  if (impl.fractions.empty()) return;
  const size_t n = impl.fractions.size();
  const double dx = impl.dx();
  const float tau = static_cast<float>(kOuterBandVoxels * dx);
  const Int3 o = before.origin();
  const Int3 d = before.dims();
  // A voxel whose phi fell from >= 0 is where the surface moved out to (a push, the compensation
  // bulge, smoothing, an add). The material there is the material that moved: the nearest voxel
  // of the old inside behind it, along -grad phi (a semi-Lagrangian backtrace of the normal
  // motion to just behind the old surface). Nearest voxel, no interpolation: a copy cannot leave
  // the simplex. Voxels that lose material keep their (now outside) fractions, which is what the
  // viewer's outer stencil reads.
  const int max_steps = 2 * std::max(1, static_cast<int>(std::lround(impl.background() / dx))) + 2;
  struct Move {
    Coord target;
    Coord source;
  };
  std::vector<Move> moves;
  const auto& was = before.data();
  const auto& now = after.data();
  for (int k = margin; k < d.z - margin; ++k) {
    for (int j = margin; j < d.y - margin; ++j) {
      for (int i = margin; i < d.x - margin; ++i) {
        const size_t idx = before.Index(i, j, k);
        const float b = was[idx], a = now[idx];
        if (!(a < b) || b < 0.f || a >= tau) continue;
        const double gx = before.Clamped(i + 1, j, k) - before.Clamped(i - 1, j, k);
        const double gy = before.Clamped(i, j + 1, k) - before.Clamped(i, j - 1, k);
        const double gz = before.Clamped(i, j, k + 1) - before.Clamped(i, j, k - 1);
        const double len = std::sqrt(gx * gx + gy * gy + gz * gz);
        bool found = false;
        int si = 0, sj = 0, sk = 0;
        if (len > 1e-6 * dx) {
          const double nx = gx / len, ny = gy / len, nz = gz / len;
          for (int s = 0; s < max_steps && !found; ++s) {
            const double back = b / dx + 0.5 + 0.5 * s;  // voxels behind this one
            const int ii = static_cast<int>(std::lround(i - nx * back));
            const int jj = static_cast<int>(std::lround(j - ny * back));
            const int kk = static_cast<int>(std::lround(k - nz * back));
            if (!before.Contains(ii, jj, kk)) break;
            if (before.at(ii, jj, kk) < 0.f) {
              found = true;
              si = ii, sj = jj, sk = kk;
            }
          }
        }
        // At a kink (no gradient) or when the backtrace misses, the deepest inside voxel within
        // two voxels, the first in (z, y, x) order on a tie.
        for (int r = 1; r <= 2 && !found; ++r) {
          float best = 0.f;
          for (int dk = -r; dk <= r; ++dk)
            for (int dj = -r; dj <= r; ++dj)
              for (int di = -r; di <= r; ++di) {
                if (!before.Contains(i + di, j + dj, k + dk)) continue;
                const float v = before.at(i + di, j + dj, k + dk);
                if (v < best) {
                  best = v;
                  found = true;
                  si = i + di, sj = j + dj, sk = k + dk;
                }
              }
        }
        if (!found) continue;  // no material near: the voxel keeps what it holds
        moves.push_back({Coord(o.x + i, o.y + j, o.z + k), Coord(o.x + si, o.y + sj, o.z + sk)});
      }
    }
  }
  if (moves.empty()) return;
  std::vector<float> values(moves.size() * n);
  for (size_t m = 0; m < n; ++m) {
    FloatGrid::ConstAccessor acc = impl.fractions[m]->getConstAccessor();
    for (size_t v = 0; v < moves.size(); ++v) values[v * n + m] = acc.getValue(moves[v].source);
  }
  for (size_t m = 0; m < n; ++m) {
    FloatGrid::Accessor acc = impl.fractions[m]->getAccessor();
    for (size_t v = 0; v < moves.size(); ++v) {
      const float x = values[v * n + m];
      if (acc.getValue(moves[v].target) != x) acc.setValueOn(moves[v].target, x);
    }
  }
}

openvdb::GridPtrVec MaterialGridsForFile(const Sculpture::Impl& impl) {
  openvdb::GridPtrVec out;
  for (size_t m = 0; m < impl.fractions.size(); ++m) {
    FloatGrid::Ptr g = impl.fractions[m];
    const MaterialDecl& decl = impl.materials[m];
    g->setName("material:" + decl.name);
    g->setGridClass(openvdb::GRID_UNKNOWN);
    g->insertMeta(kIndexMeta, openvdb::Int32Metadata(static_cast<int32_t>(m)));
    g->insertMeta(kNameMeta, openvdb::StringMetadata(decl.name));
    g->insertMeta(kColourMeta, openvdb::Vec3DMetadata(
                                   openvdb::Vec3d(decl.colour[0], decl.colour[1], decl.colour[2])));
    out.push_back(g);
  }
  return out;
}

Status AdoptMaterialGrids(Sculpture::Impl& impl, const openvdb::GridPtrVec& grids) {
  std::vector<std::pair<int, FloatGrid::Ptr>> found;
  for (const auto& base : grids) {
    auto index = base->getMetadata<openvdb::Int32Metadata>(kIndexMeta);
    if (!index) continue;
    auto g = openvdb::gridPtrCast<FloatGrid>(base);
    if (!g) return DataLoss("material grid " + base->getName() + " is not a float grid");
    found.push_back({index->value(), g});
  }
  if (found.empty()) return Status::Ok();
  std::sort(found.begin(), found.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<MaterialDecl> decls;
  std::vector<FloatGrid::Ptr> fr;
  for (size_t m = 0; m < found.size(); ++m) {
    const auto& [index, g] = found[m];
    if (index != static_cast<int>(m)) {
      return Outside("material grid index", std::to_string(index),
                     std::string("{") + std::to_string(m) + "} (indices 0..n-1, each once)",
                     Status::Code::kDataLoss);
    }
    MaterialDecl d;
    if (auto name = g->getMetadata<openvdb::StringMetadata>(kNameMeta)) d.name = name->value();
    if (auto c = g->getMetadata<openvdb::Vec3DMetadata>(kColourMeta)) {
      d.colour = {c->value()[0], c->value()[1], c->value()[2]};
    }
    if (g->transform() != impl.grid->transform()) {
      return DataLoss("material grid " + d.name + ": transform differs from the SDF's");
    }
    decls.push_back(d);
    fr.push_back(g);
  }
  if (Status s = ValidateMaterialDecls(decls); !s.ok()) return DataLoss(s.message());
  impl.materials = std::move(decls);
  impl.fractions = std::move(fr);
  return Status::Ok();
}

void EncodeMaterialCells(const Sculpture::Impl& impl, const std::vector<Int3>& cells,
                         std::string& out) {
  const size_t n = impl.fractions.size();
  out.push_back(static_cast<char>(n));
  std::vector<float> values;
  for (const Int3& c : cells) {
    const Coord origin(c.x, c.y, c.z);
    for (size_t m = 0; m < n; ++m) {
      const FloatGrid& g = *impl.fractions[m];
      if (const auto* leaf = g.tree().probeConstLeaf(origin)) {
        out.push_back(1);
        values.insert(values.end(), leaf->buffer().data(), leaf->buffer().data() + leaf->SIZE);
      } else {
        out.push_back(0);
        const float v = g.tree().getValue(origin);
        out.append(reinterpret_cast<const char*>(&v), 4);
      }
    }
  }
  const size_t base = out.size();
  out.resize(base + values.size() * 4);
  const auto* vb = reinterpret_cast<const uint8_t*>(values.data());
  for (size_t plane = 0; plane < 4; ++plane) {
    char* dst = out.data() + base + plane * values.size();
    for (size_t i = 0; i < values.size(); ++i) dst[i] = static_cast<char>(vb[i * 4 + plane]);
  }
}

StatusOr<MaterialCells> DecodeMaterialCells(const Sculpture::Impl& impl, std::string_view block,
                                            size_t cells) {
  MaterialCells mc;
  if (block.empty()) return DataLoss("leaf records: materials block missing");
  mc.n = static_cast<uint8_t>(block[0]);
  block.remove_prefix(1);
  if (mc.n != impl.fractions.size()) {
    return Outside("leaf records: materials", std::to_string(mc.n),
                   std::string("{") + std::to_string(impl.fractions.size()) +
                       "} (the replica's declared materials)",
                   Status::Code::kDataLoss);
  }
  const size_t entries = cells * mc.n;
  if (block.size() < entries) {
    return Outside("leaf records: materials block size", std::to_string(block.size()),
                   std::string("[") + std::to_string(entries) + ", ...)", Status::Code::kDataLoss);
  }
  mc.type.resize(entries);
  mc.uniform.assign(entries, 0.f);
  mc.first.assign(entries, 0);
  size_t leaves = 0;
  for (size_t e = 0; e < entries; ++e) {
    if (block.empty()) return DataLoss("leaf records: materials block truncated");
    const uint8_t t = static_cast<uint8_t>(block[0]);
    block.remove_prefix(1);
    mc.type[e] = t;
    if (t == 0) {
      if (block.size() < 4) return DataLoss("leaf records: materials block truncated");
      std::memcpy(&mc.uniform[e], block.data(), 4);
      block.remove_prefix(4);
    } else if (t == 1) {
      mc.first[e] = leaves * 512;
      ++leaves;
    } else {
      return Outside("leaf records: material type", std::to_string(t), "{0, 1}",
                     Status::Code::kDataLoss);
    }
  }
  if (block.size() != leaves * 512 * 4) {
    return Outside("leaf records: material value bytes", std::to_string(block.size()),
                   std::string("{") + std::to_string(leaves * 512 * 4) + "}",
                   Status::Code::kDataLoss);
  }
  const size_t total = leaves * 512;
  mc.values.resize(total);
  auto* vb = reinterpret_cast<uint8_t*>(mc.values.data());
  for (size_t plane = 0; plane < 4; ++plane) {
    const char* src = block.data() + plane * total;
    for (size_t i = 0; i < total; ++i) vb[i * 4 + plane] = static_cast<uint8_t>(src[i]);
  }
  // Every voxel's vector must lie in the simplex (seed 001 (4.2)): what comes off the wire is
  // checked before anything is written.
  for (size_t c = 0; c < cells; ++c) {
    for (int v = 0; v < 512; ++v) {
      double sum = 0;
      for (size_t m = 0; m < mc.n; ++m) {
        const size_t e = c * mc.n + m;
        const double x = mc.type[e] == 0 ? mc.uniform[e] : mc.values[mc.first[e] + v];
        if (!std::isfinite(x) || x < -kFractionTolerance || x > 1 + kFractionTolerance) {
          return Outside(std::string("leaf records: record ") + std::to_string(c) + " voxel " +
                             std::to_string(v) + " fraction[" + std::to_string(m) + "]",
                         FormatNumber(x), "[0, 1]", Status::Code::kDataLoss);
        }
        sum += x;
      }
      if (std::abs(sum - 1.0) > kFractionTolerance) {
        char buf[160];
        std::snprintf(buf, sizeof buf,
                      "leaf records: record %zu voxel %d fractions.sum=%.9g outside [%.9g, %.9g]",
                      c, v, sum, 1.0 - kFractionTolerance, 1.0 + kFractionTolerance);
        return DataLoss(buf);
      }
      if (v == 0) {
        bool all_uniform = true;
        for (size_t m = 0; m < mc.n; ++m) all_uniform = all_uniform && mc.type[c * mc.n + m] == 0;
        if (all_uniform) break;  // one vector for the whole cell
      }
    }
  }
  return mc;
}

void ApplyMaterialCell(Sculpture::Impl& impl, const MaterialCells& mc, size_t record,
                       const Int3& origin) {
  const Coord o(origin.x, origin.y, origin.z);
  for (size_t m = 0; m < mc.n; ++m) {
    const size_t e = record * mc.n + m;
    FloatGrid& g = *impl.fractions[m];
    if (mc.type[e] == 0) {
      g.tree().addTile(1, o, mc.uniform[e], false);
    } else {
      auto* leaf = g.tree().touchLeaf(o);
      for (openvdb::Index i = 0; i < 512; ++i) leaf->setValueOn(i, mc.values[mc.first[e] + i]);
    }
  }
}

uint64_t MaterialCellsHash(const Sculpture::Impl& impl, const std::vector<Int3>& cells) {
  if (impl.fractions.empty()) return 0;
  XXH3_state_t* st = XXH3_createState();
  XXH3_64bits_reset(st);
  for (const auto& g : impl.fractions) {
    FloatGrid::ConstAccessor acc = g->getConstAccessor();
    for (const Int3& c : cells) {
      const Coord o(c.x, c.y, c.z);
      if (const auto* leaf = acc.probeConstLeaf(o)) {
        XXH3_64bits_update(st, leaf->buffer().data(), leaf->SIZE * sizeof(float));
      } else {
        const float v = acc.getValue(o);
        XXH3_64bits_update(st, &v, sizeof v);
      }
    }
  }
  const uint64_t h = XXH3_64bits_digest(st);
  XXH3_freeState(st);
  return h;
}

void ClearMaterialRegion(Sculpture::Impl& impl, const VoxelBox& box) {
  if (box.Empty()) return;
  for (auto& g : impl.fractions) {
    g->tree().fill(openvdb::CoordBBox(Coord(box.min.x, box.min.y, box.min.z),
                                      Coord(box.max.x, box.max.y, box.max.z)),
                   g->background(), false);
  }
}

void DeepCopyMaterials(Sculpture::Impl& impl) {
  for (auto& g : impl.fractions) g = g->deepCopy();
}

}  // namespace internal
}  // namespace sculpt::levelset
