/// @brief Leaf versions, leaf records and region hashes for replication (issue 4).
#include "sculpt/levelset/region.h"

#include <xxhash.h>
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <tuple>

#include "materials_internal.h"
#include "sculpture_impl.h"

namespace sculpt::levelset {
namespace {

using openvdb::Coord;
using openvdb::FloatGrid;

constexpr char kMagic[4] = {'S', 'L', 'R', '1'};
// The same records followed by a materials block (materials_internal.h) when the sculpture
// declares materials.
constexpr char kMagicMaterials[4] = {'S', 'L', 'R', '2'};
constexpr uint8_t kUniform = 0;
constexpr uint8_t kLeaf = 1;
constexpr int kLeafVoxels = kLeafDim * kLeafDim * kLeafDim;
constexpr int kMaskBytes = kLeafVoxels / 8;
// Origins beyond this many voxels from 0 are refused (OpenVDB coordinates are int32; a
// replica's interest box is bounded far below this).
constexpr int kMaxCoord = 1 << 28;
// A decoded payload larger than this is refused before allocation (a 256-MiB region).
constexpr size_t kMaxRaw = 256u << 20;

int Floor8(int v) { return v & ~7; }

uint64_t Key(const Int3& o) {
  // 21 bits per axis of the leaf index, offset to be non-negative.
  const uint64_t x = static_cast<uint64_t>((o.x >> 3) + (1 << 20)) & 0x1FFFFF;
  const uint64_t y = static_cast<uint64_t>((o.y >> 3) + (1 << 20)) & 0x1FFFFF;
  const uint64_t z = static_cast<uint64_t>((o.z >> 3) + (1 << 20)) & 0x1FFFFF;
  return x | (y << 21) | (z << 42);
}

Int3 Unkey(uint64_t k) {
  auto axis = [](uint64_t v) { return (static_cast<int>(v & 0x1FFFFF) - (1 << 20)) * 8; };
  return {axis(k), axis(k >> 21), axis(k >> 42)};
}

bool CellLess(const Int3& a, const Int3& b) {
  return std::tie(a.z, a.y, a.x) < std::tie(b.z, b.y, b.x);
}

bool CellInBox(const Int3& o, const VoxelBox& b) {
  return o.x + kLeafDim - 1 >= b.min.x && o.x <= b.max.x && o.y + kLeafDim - 1 >= b.min.y &&
         o.y <= b.max.y && o.z + kLeafDim - 1 >= b.min.z && o.z <= b.max.z;
}

void Put(std::string& s, const void* p, size_t n) { s.append(static_cast<const char*>(p), n); }

template <typename T>
bool Get(std::string_view& s, T* v) {
  if (s.size() < sizeof(T)) return false;
  std::memcpy(v, s.data(), sizeof(T));
  s.remove_prefix(sizeof(T));
  return true;
}

}  // namespace

bool VoxelBox::Contains(const VoxelBox& o) const {
  if (o.Empty()) return true;
  return !Empty() && o.min.x >= min.x && o.min.y >= min.y && o.min.z >= min.z &&
         o.max.x <= max.x && o.max.y <= max.y && o.max.z <= max.z;
}

bool VoxelBox::Intersects(const VoxelBox& o) const { return !Intersection(o).Empty(); }

VoxelBox VoxelBox::Intersection(const VoxelBox& o) const {
  VoxelBox r;
  r.min = {std::max(min.x, o.min.x), std::max(min.y, o.min.y), std::max(min.z, o.min.z)};
  r.max = {std::min(max.x, o.max.x), std::min(max.y, o.max.y), std::min(max.z, o.max.z)};
  return r;
}

VoxelBox VoxelBox::Dilated(int v) const {
  if (Empty()) return *this;
  auto clamp = [](int64_t x) {
    return static_cast<int>(std::clamp<int64_t>(x, -kMaxCoord, kMaxCoord));
  };
  VoxelBox r;
  r.min = {clamp(int64_t{min.x} - v), clamp(int64_t{min.y} - v), clamp(int64_t{min.z} - v)};
  r.max = {clamp(int64_t{max.x} + v), clamp(int64_t{max.y} + v), clamp(int64_t{max.z} + v)};
  return r;
}

uint64_t VoxelBox::Volume() const {
  if (Empty()) return 0;
  const double v = (double(max.x) - min.x + 1) * (double(max.y) - min.y + 1) *
                   (double(max.z) - min.z + 1);
  return v >= 1.8e19 ? std::numeric_limits<uint64_t>::max() : static_cast<uint64_t>(v);
}

VoxelBox WorldToVoxelBox(const Sculpture& sculpture, const Vec3& lo, const Vec3& hi) {
  const double dx = sculpture.voxel_size();
  auto idx = [&](double w, bool up) {
    const double v = up ? std::ceil(w / dx) : std::floor(w / dx);
    return static_cast<int>(std::clamp(v, double(-kMaxCoord), double(kMaxCoord)));
  };
  VoxelBox b;
  b.min = {idx(lo.x, false), idx(lo.y, false), idx(lo.z, false)};
  b.max = {idx(hi.x, true), idx(hi.y, true), idx(hi.z, true)};
  return b;
}

void LeafVersions::Record(const std::vector<Int3>& leaves, uint64_t seq) {
  for (const Int3& l : leaves) versions_[Key(l)] = seq;
}

uint64_t LeafVersions::Get(const Int3& leaf) const {
  auto it = versions_.find(Key({Floor8(leaf.x), Floor8(leaf.y), Floor8(leaf.z)}));
  return it == versions_.end() ? 0 : it->second;
}

std::vector<Int3> LeafVersions::NewerThan(uint64_t seq, const VoxelBox& box) const {
  std::vector<Int3> out;
  for (const auto& [k, v] : versions_) {
    if (v <= seq) continue;
    const Int3 o = Unkey(k);
    if (!box.Empty() && !CellInBox(o, box)) continue;
    out.push_back(o);
  }
  std::sort(out.begin(), out.end(), CellLess);
  return out;
}

std::vector<Int3> OccupiedLeafCells(const Sculpture& sculpture, const VoxelBox& box) {
  std::vector<Int3> out;
  if (box.Empty()) return out;
  const FloatGrid& g = *sculpture.impl().grid;
  const float bg = g.background();
  for (auto leaf = g.tree().cbeginLeaf(); leaf; ++leaf) {
    const Coord o = leaf->origin();
    const Int3 c{o.x(), o.y(), o.z()};
    if (CellInBox(c, box)) out.push_back(c);
  }
  // Tiles of another value than the background (the inside): every leaf cell they cover that
  // lies in the box.
  for (auto it = g.tree().cbeginValueAll(); it; ++it) {
    if (it.isVoxelValue() || *it == bg) continue;
    openvdb::CoordBBox tb;
    it.getBoundingBox(tb);
    const VoxelBox t{{tb.min().x(), tb.min().y(), tb.min().z()},
                     {tb.max().x(), tb.max().y(), tb.max().z()}};
    const VoxelBox in = t.Intersection(box);
    if (in.Empty()) continue;
    for (int z = Floor8(in.min.z); z <= in.max.z; z += kLeafDim) {
      for (int y = Floor8(in.min.y); y <= in.max.y; y += kLeafDim) {
        for (int x = Floor8(in.min.x); x <= in.max.x; x += kLeafDim) out.push_back({x, y, z});
      }
    }
  }
  std::sort(out.begin(), out.end(), CellLess);
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::vector<Int3> AllLeafCells(const VoxelBox& box) {
  std::vector<Int3> out;
  if (box.Empty()) return out;
  for (int z = Floor8(box.min.z); z <= box.max.z; z += kLeafDim) {
    for (int y = Floor8(box.min.y); y <= box.max.y; y += kLeafDim) {
      for (int x = Floor8(box.min.x); x <= box.max.x; x += kLeafDim) out.push_back({x, y, z});
    }
  }
  return out;
}

std::string EncodeLeafRecords(const Sculpture& sculpture, const std::vector<Int3>& cells,
                              const LeafVersions* versions, int level, LeafRecordStats* stats) {
  const FloatGrid& g = *sculpture.impl().grid;
  const float bg = g.background();
  FloatGrid::ConstAccessor acc = g.getConstAccessor();
  // Layout before compression: header, then per record origin (3 x int32), version (uint64),
  // type (uint8), and for a leaf: value mask, sign mask of inactive voxels, active count
  // (uint16); then all active values of all leaves, byte-shuffled (the four bytes of every
  // float in four planes), which zstd compresses far better than interleaved floats.
  std::string head;
  std::vector<float> values;
  head.append(kMagic, 4);
  const uint32_t n = static_cast<uint32_t>(cells.size());
  Put(head, &n, 4);
  LeafRecordStats st;
  for (const Int3& c : cells) {
    const int32_t o[3] = {c.x, c.y, c.z};
    Put(head, o, sizeof o);
    const uint64_t ver = versions ? versions->Get(c) : 0;
    Put(head, &ver, 8);
    const auto* leaf = g.tree().probeConstLeaf(Coord(c.x, c.y, c.z));
    ++st.records;
    if (!leaf) {
      head.push_back(static_cast<char>(kUniform));
      const float v = acc.getValue(Coord(c.x, c.y, c.z));
      Put(head, &v, 4);
      ++st.uniform;
      continue;
    }
    ++st.leaves;
    head.push_back(static_cast<char>(kLeaf));
    uint8_t mask[kMaskBytes] = {};
    uint8_t sign[kMaskBytes] = {};
    uint16_t count = 0;
    for (int i = 0; i < kLeafVoxels; ++i) {
      const float v = leaf->getValue(static_cast<openvdb::Index>(i));
      if (leaf->isValueOn(static_cast<openvdb::Index>(i))) {
        mask[i >> 3] |= static_cast<uint8_t>(1u << (i & 7));
        values.push_back(v);
        ++count;
      } else if (v < 0) {
        sign[i >> 3] |= static_cast<uint8_t>(1u << (i & 7));
      }
    }
    Put(head, mask, sizeof mask);
    Put(head, sign, sizeof sign);
    Put(head, &count, 2);
  }
  (void)bg;
  std::string raw = std::move(head);
  const size_t base = raw.size();
  raw.resize(base + values.size() * 4);
  const auto* vb = reinterpret_cast<const uint8_t*>(values.data());
  for (int plane = 0; plane < 4; ++plane) {
    char* dst = raw.data() + base + plane * values.size();
    for (size_t i = 0; i < values.size(); ++i) dst[i] = static_cast<char>(vb[i * 4 + plane]);
  }
  if (!sculpture.impl().fractions.empty()) {
    std::memcpy(raw.data(), kMagicMaterials, 4);
    internal::EncodeMaterialCells(sculpture.impl(), cells, raw);
  }
  std::string out;
  const uint64_t raw_size = raw.size();
  out.resize(8 + ZSTD_compressBound(raw.size()));
  std::memcpy(out.data(), &raw_size, 8);
  // With zstd's content checksum, so a corrupted payload is refused, not applied.
  ZSTD_CCtx* cctx = ZSTD_createCCtx();
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_compressionLevel, level);
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_checksumFlag, 1);
  const size_t z = ZSTD_compress2(cctx, out.data() + 8, out.size() - 8, raw.data(), raw.size());
  ZSTD_freeCCtx(cctx);
  out.resize(ZSTD_isError(z) ? 8 : 8 + z);
  st.raw_bytes = raw.size();
  st.compressed_bytes = out.size();
  if (stats) *stats = st;
  return out;
}

StatusOr<LeafApplyResult> ApplyLeafRecords(Sculpture& sculpture, std::string_view bytes,
                                           const VoxelBox& clip) {
  uint64_t raw_size = 0;
  if (!Get(bytes, &raw_size)) return DataLoss("leaf records: size header missing");
  if (raw_size > kMaxRaw || raw_size < 8) {
    return Outside("leaf records: raw_size", std::to_string(raw_size),
                   std::string("[8, ") + std::to_string(kMaxRaw) + "]", Status::Code::kDataLoss);
  }
  const unsigned long long frame = ZSTD_getFrameContentSize(bytes.data(), bytes.size());
  if (frame != raw_size) return DataLoss("leaf records: zstd frame size does not match raw_size");
  std::string raw(raw_size, '\0');
  const size_t got = ZSTD_decompress(raw.data(), raw.size(), bytes.data(), bytes.size());
  if (ZSTD_isError(got) || got != raw_size) {
    return DataLoss(std::string("leaf records: zstd: ") +
                    (ZSTD_isError(got) ? ZSTD_getErrorName(got) : "short"));
  }
  std::string_view s(raw);
  if (s.size() < 8 || (std::memcmp(s.data(), kMagic, 4) != 0 &&
                        std::memcmp(s.data(), kMagicMaterials, 4) != 0)) {
    return DataLoss("leaf records: magic outside {SLR1, SLR2}");
  }
  const bool has_materials = std::memcmp(s.data(), kMagicMaterials, 4) == 0;
  if (has_materials != !sculpture.impl().fractions.empty()) {
    return DataLoss(std::string("leaf records: magic=") + (has_materials ? "SLR2" : "SLR1") +
                    " outside {" + (has_materials ? "SLR1" : "SLR2") +
                    "} (materials declared here: " +
                    std::to_string(sculpture.impl().fractions.size()) + ")");
  }
  s.remove_prefix(4);
  uint32_t n = 0;
  Get(s, &n);
  struct Rec {
    Int3 o;
    uint64_t version;
    uint8_t type;
    float uniform;
    const uint8_t* mask;
    const uint8_t* sign;
    uint16_t count;
  };
  // Each record takes at least 21 bytes: a count above that is a lie, refused before reserving.
  if (n > s.size() / 21) {
    return Outside("leaf records: count", std::to_string(n),
                   std::string("[0, ") + std::to_string(s.size() / 21) + "] for the payload size",
                   Status::Code::kDataLoss);
  }
  FloatGrid& g = *sculpture.impl().grid;
  const float bg = g.background();
  std::vector<Rec> recs;
  recs.reserve(n);
  uint64_t total_values = 0;
  for (uint32_t i = 0; i < n; ++i) {
    Rec r{};
    int32_t o[3];
    if (!Get(s, &o) || !Get(s, &r.version) || !Get(s, &r.type)) {
      return DataLoss("leaf records: record " + std::to_string(i) + " truncated");
    }
    for (int a = 0; a < 3; ++a) {
      if (o[a] % kLeafDim != 0 || o[a] < -kMaxCoord || o[a] > kMaxCoord) {
        return Outside(std::string("leaf records: origin[") + std::to_string(a) + "]",
                       std::to_string(o[a]), "multiples of 8 in [-2^28, 2^28]",
                       Status::Code::kDataLoss);
      }
    }
    r.o = {o[0], o[1], o[2]};
    if (r.type == kUniform) {
      if (!Get(s, &r.uniform) || !std::isfinite(r.uniform)) {
        return DataLoss("leaf records: uniform value of record " + std::to_string(i) +
                        " missing or not finite");
      }
      // It becomes an inactive tile: outside or inside, +-background like every inactive value.
      if (r.uniform != bg && r.uniform != -bg) {
        return Outside("leaf records: uniform value of record " + std::to_string(i),
                       std::to_string(r.uniform),
                       "{-" + std::to_string(bg) + ", " + std::to_string(bg) + "} (+-background)",
                       Status::Code::kDataLoss);
      }
    } else if (r.type == kLeaf) {
      if (s.size() < 2 * kMaskBytes + 2) {
        return DataLoss("leaf records: leaf record " + std::to_string(i) + " truncated");
      }
      r.mask = reinterpret_cast<const uint8_t*>(s.data());
      r.sign = r.mask + kMaskBytes;
      s.remove_prefix(2 * kMaskBytes);
      Get(s, &r.count);
      int pop = 0;
      for (int b = 0; b < kMaskBytes; ++b) pop += __builtin_popcount(r.mask[b]);
      if (pop != r.count) {
        return Outside("leaf records: count",
                       std::to_string(r.count) + " of record " + std::to_string(i),
                       std::string("{") + std::to_string(pop) + "} (its mask's population)",
                       Status::Code::kDataLoss);
      }
      total_values += r.count;
    } else {
      return Outside("leaf records: type", std::to_string(r.type), "{0, 1}",
                     Status::Code::kDataLoss);
    }
    recs.push_back(r);
  }
  std::string_view material_block;
  if (has_materials && s.size() > total_values * 4) {
    material_block = s.substr(total_values * 4);
    s = s.substr(0, total_values * 4);
  }
  if (s.size() != total_values * 4) {
    return Outside("leaf records: value bytes", std::to_string(s.size()),
                   std::string("{") + std::to_string(total_values * 4) + "}",
                   Status::Code::kDataLoss);
  }
  internal::MaterialCells materials;
  if (has_materials) {
    auto mc = internal::DecodeMaterialCells(sculpture.impl(), material_block, recs.size());
    if (!mc.ok()) return mc.status();
    materials = std::move(mc).value();
  }
  std::vector<float> values(total_values);
  auto* vb = reinterpret_cast<uint8_t*>(values.data());
  for (int plane = 0; plane < 4; ++plane) {
    const char* src = s.data() + plane * total_values;
    for (uint64_t i = 0; i < total_values; ++i) vb[i * 4 + plane] = static_cast<uint8_t>(src[i]);
  }
  for (float v : values) {
    if (!std::isfinite(v) || std::abs(v) >= bg) {
      return DataLoss("leaf records: an active value outside (-background, background)");
    }
  }
  // Validated whole: now write.
  LeafApplyResult res;
  uint64_t next = 0;
  for (size_t ri = 0; ri < recs.size(); ++ri) {
    const Rec& r = recs[ri];
    const uint64_t first = next;
    next += r.count;
    if (!clip.Empty() && !CellInBox(r.o, clip)) continue;
    if (has_materials) internal::ApplyMaterialCell(sculpture.impl(), materials, ri, r.o);
    const Coord origin(r.o.x, r.o.y, r.o.z);
    if (r.type == kUniform) {
      g.tree().addTile(1, origin, r.uniform, false);
    } else {
      auto* leaf = g.tree().touchLeaf(origin);
      uint64_t k = first;
      for (int i = 0; i < kLeafVoxels; ++i) {
        const auto idx = static_cast<openvdb::Index>(i);
        if (r.mask[i >> 3] & (1u << (i & 7))) {
          leaf->setValueOn(idx, values[k++]);
        } else {
          leaf->setValueOff(idx, (r.sign[i >> 3] & (1u << (i & 7))) ? -bg : bg);
        }
      }
    }
    auto& b = sculpture.impl().bounds;
    b.expand(openvdb::CoordBBox(origin, origin.offsetBy(kLeafDim - 1)));
    ++res.records;
    res.max_version = std::max(res.max_version, r.version);
    res.cells.push_back(r.o);
  }
  return res;
}

uint64_t LeavesHash(const Sculpture& sculpture, const std::vector<Int3>& cells) {
  const FloatGrid& g = *sculpture.impl().grid;
  FloatGrid::ConstAccessor acc = g.getConstAccessor();
  XXH3_state_t* st = XXH3_createState();
  XXH3_64bits_reset(st);
  for (const Int3& c : cells) {
    const int32_t o[3] = {c.x, c.y, c.z};
    XXH3_64bits_update(st, o, sizeof o);
    const auto* leaf = g.tree().probeConstLeaf(Coord(c.x, c.y, c.z));
    if (leaf) {
      const auto& mask = leaf->getValueMask();
      for (openvdb::Index32 w = 0; w < mask.WORD_COUNT; ++w) {
        const openvdb::Index64 word = mask.template getWord<openvdb::Index64>(w);
        XXH3_64bits_update(st, &word, sizeof word);
      }
      XXH3_64bits_update(st, leaf->buffer().data(), leaf->SIZE * sizeof(float));
    } else {
      const float v = acc.getValue(Coord(c.x, c.y, c.z));
      XXH3_64bits_update(st, &v, sizeof v);
    }
  }
  // The fractions of the same cells, when the sculpture declares materials (replicas converge on
  // them too); without materials the hash is what it always was.
  if (!sculpture.impl().fractions.empty()) {
    const uint64_t m = internal::MaterialCellsHash(sculpture.impl(), cells);
    XXH3_64bits_update(st, &m, sizeof m);
  }
  const uint64_t h = XXH3_64bits_digest(st);
  XXH3_freeState(st);
  return h;
}

uint64_t RegionHash(const Sculpture& sculpture, const VoxelBox& box) {
  if (box.Empty()) return 0;
  const FloatGrid& g = *sculpture.impl().grid;
  XXH3_state_t* st = XXH3_createState();
  XXH3_64bits_reset(st);
  // Slab by slab, so a large box does not need one dense copy.
  for (int z = box.min.z; z <= box.max.z; z += kLeafDim) {
    internal::IndexBox slab{{box.min.x, box.min.y, z},
                            {box.max.x, box.max.y, std::min(box.max.z, z + kLeafDim - 1)}};
    const DenseField f = internal::ExtractDense(g, slab);
    XXH3_64bits_update(st, f.data().data(), f.size() * sizeof(float));
  }
  const uint64_t h = XXH3_64bits_digest(st);
  XXH3_freeState(st);
  return h;
}

void ClearRegion(Sculpture& sculpture, const VoxelBox& box) {
  if (box.Empty()) return;
  FloatGrid& g = *sculpture.impl().grid;
  g.tree().fill(openvdb::CoordBBox(Coord(box.min.x, box.min.y, box.min.z),
                                   Coord(box.max.x, box.max.y, box.max.z)),
                g.background(), false);
  internal::ClearMaterialRegion(sculpture.impl(), box);
}

}  // namespace sculpt::levelset
