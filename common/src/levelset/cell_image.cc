/// @brief CellImage: exact copies of leaf cells and their write-back, tree levels included.
#include "sculpt/levelset/cell_image.h"

#include <algorithm>
#include <cstring>
#include <tuple>

#include "sculpture_impl.h"

namespace sculpt::levelset {
namespace {

using openvdb::Coord;
using Tree = openvdb::FloatTree;
using Node2 = Tree::RootNodeType::ChildNodeType;
using Node1 = Node2::ChildNodeType;
using LeafT = Tree::LeafNodeType;

constexpr int kNode1Dim = Node1::DIM;  // 128
constexpr int kNode2Dim = Node2::DIM;  // 4096

bool CellLess(const Int3& a, const Int3& b) {
  return std::tie(a.z, a.y, a.x) < std::tie(b.z, b.y, b.x);
}

Int3 Floor(const Int3& c, int dim) {
  auto f = [dim](int v) { return v & ~(dim - 1); };
  return {f(c.x), f(c.y), f(c.z)};
}

// Whether a node holds no children and only tiles of one value and state.
template <typename NodeT>
bool Uniform(const NodeT& node, float value, bool active) {
  if (!node.getChildMask().isOff()) return false;
  for (auto it = node.cbeginValueAll(); it; ++it) {
    if (*it != value || it.isValueOn() != active) return false;
  }
  return true;
}

template <typename T>
void Put(std::string& s, const T& v) {
  s.append(reinterpret_cast<const char*>(&v), sizeof v);
}

template <typename T>
bool Get(std::string_view& s, T* v) {
  if (s.size() < sizeof(T)) return false;
  std::memcpy(v, s.data(), sizeof(T));
  s.remove_prefix(sizeof(T));
  return true;
}

const openvdb::FloatGrid& GridOf(const Sculpture::Impl& impl, int grid) {
  return grid < 0 ? *impl.grid : *impl.fractions[static_cast<size_t>(grid)];
}

}  // namespace

void CellImage::AppendPart(const Part& part, std::string& out) {
  Put(out, static_cast<uint32_t>(part.cells.size()));
  Put(out, static_cast<uint32_t>(part.leaves.size()));
  for (const Cell& c : part.cells) {
    const int32_t o[3] = {c.origin.x, c.origin.y, c.origin.z};
    Put(out, o);
    Put(out, c.level);
    Put(out, static_cast<uint8_t>(c.active));
    Put(out, c.value);
    Put(out, c.leaf);
  }
  for (const Leaf& l : part.leaves) Put(out, l);
}

void CellImage::AppendTo(std::string& out) const {
  AppendPart(sdf_, out);
  Put(out, static_cast<uint8_t>(fractions_.size()));
  for (const Part& p : fractions_) AppendPart(p, out);
}

StatusOr<CellImage::Part> CellImage::ReadPart(std::string_view& in) {
  uint32_t ncells = 0, nleaves = 0;
  if (!Get(in, &ncells) || !Get(in, &nleaves)) return DataLoss("cell image: counts truncated");
  constexpr size_t kCellBytes = 12 + 1 + 1 + 4 + 4;
  if (ncells > in.size() / kCellBytes || nleaves > ncells) {
    return Outside(
        "cell image: cells", std::to_string(ncells) + ", leaves=" + std::to_string(nleaves),
        std::string("what ") + std::to_string(in.size()) + " bytes hold", Status::Code::kDataLoss);
  }
  Part img;
  img.cells.resize(ncells);
  for (uint32_t i = 0; i < ncells; ++i) {
    Cell& c = img.cells[i];
    int32_t o[3];
    uint8_t active = 0;
    if (!Get(in, &o) || !Get(in, &c.level) || !Get(in, &active) || !Get(in, &c.value) ||
        !Get(in, &c.leaf)) {
      return DataLoss("cell image: cell " + std::to_string(i) + " truncated");
    }
    c.origin = {o[0], o[1], o[2]};
    c.active = active != 0;
    if (o[0] % kLeafDim || o[1] % kLeafDim || o[2] % kLeafDim || c.level > 4 ||
        (c.level == 0 && c.leaf >= nleaves) ||
        (i > 0 && !CellLess(img.cells[i - 1].origin, c.origin))) {
      return Outside(std::string("cell image: cell ") + std::to_string(i) +
                         " has an unaligned or unsorted origin, level",
                     std::to_string(c.level),
                     std::string("[0, 4] or leaf=") + std::to_string(c.leaf) + " outside [0, " +
                         std::to_string(nleaves) + ")",
                     Status::Code::kDataLoss);
    }
  }
  if (in.size() < static_cast<size_t>(nleaves) * sizeof(Leaf)) {
    return DataLoss("cell image: leaves truncated");
  }
  img.leaves.resize(nleaves);
  // An empty image has no buffer: memcpy's pointers must not be null, even for no bytes.
  if (nleaves > 0) std::memcpy(img.leaves.data(), in.data(), nleaves * sizeof(Leaf));
  in.remove_prefix(nleaves * sizeof(Leaf));
  return img;
}

StatusOr<CellImage> CellImage::ReadFrom(std::string_view& in, bool with_fractions) {
  CellImage img;
  SCULPT_ASSIGN_OR_RETURN(img.sdf_, ReadPart(in));
  if (!with_fractions) return img;
  uint8_t n = 0;
  if (!Get(in, &n)) return DataLoss("cell image: fraction grid count truncated");
  if (n > 64) {
    return Outside("cell image: fraction grids", std::to_string(n), "[0, 64]",
                   Status::Code::kDataLoss);
  }
  for (uint8_t m = 0; m < n; ++m) {
    SCULPT_ASSIGN_OR_RETURN(Part p, ReadPart(in));
    if (p.cells.size() != img.sdf_.cells.size()) {
      return Outside("cell image: fraction grid " + std::to_string(m) + " cells",
                     std::to_string(p.cells.size()),
                     "{" + std::to_string(img.sdf_.cells.size()) + "} (the SDF's)",
                     Status::Code::kDataLoss);
    }
    img.fractions_.push_back(std::move(p));
  }
  return img;
}

CellImage::Part CellImage::CapturePart(const Sculpture& sculpture, int grid,
                                       const std::vector<Int3>& cells) {
  Part img;
  const Tree& tree = GridOf(sculpture.impl(), grid).tree();
  img.cells.reserve(cells.size());
  // Counted first so the copies land in one allocation (a stroke's footprint holds ~100 leaves).
  size_t leaves = 0;
  for (const Int3& c : cells) leaves += tree.probeConstLeaf(Coord(c.x, c.y, c.z)) != nullptr;
  img.leaves.reserve(leaves);
  for (const Int3& c : cells) {
    const Coord xyz(c.x, c.y, c.z);
    Cell cell;
    cell.origin = c;
    if (const LeafT* leaf = tree.probeConstLeaf(xyz)) {
      cell.level = 0;
      cell.leaf = static_cast<uint32_t>(img.leaves.size());
      Leaf& l = img.leaves.emplace_back();
      const auto& mask = leaf->getValueMask();
      for (openvdb::Index32 w = 0; w < 8; ++w) {
        l.mask[w] = mask.template getWord<openvdb::Index64>(w);
      }
      std::memcpy(l.values, leaf->buffer().data(), sizeof l.values);
    } else {
      const int depth = tree.getValueDepth(xyz);  // 0 root tile .. 2 leaf-level tile, -1 none
      cell.level = static_cast<uint8_t>(depth < 0 ? 4 : 3 - depth);
      cell.value = tree.getValue(xyz);
      cell.active = tree.isValueOn(xyz);
    }
    img.cells.push_back(cell);
  }
  return img;
}

CellImage CellImage::Capture(const Sculpture& sculpture, const VoxelBox& box) {
  CellImage img;
  if (box.Empty()) return img;
  std::vector<Int3> cells = AllLeafCells(box);
  std::sort(cells.begin(), cells.end(), CellLess);
  img.sdf_ = CapturePart(sculpture, -1, cells);
  const int n = static_cast<int>(sculpture.impl().fractions.size());
  for (int m = 0; m < n; ++m) img.fractions_.push_back(CapturePart(sculpture, m, cells));
  return img;
}

void CellImage::KeepPart(Part& part, const std::vector<Int3>& keep) {
  std::vector<Cell> kept;
  std::vector<Leaf> kept_leaves;
  for (const Cell& c : part.cells) {
    if (!std::binary_search(keep.begin(), keep.end(), c.origin, CellLess)) continue;
    Cell k = c;
    if (c.level == 0) {
      k.leaf = static_cast<uint32_t>(kept_leaves.size());
      kept_leaves.push_back(part.leaves[c.leaf]);
    }
    kept.push_back(k);
  }
  part.cells = std::move(kept);
  part.leaves = std::move(kept_leaves);
  part.cells.shrink_to_fit();
  part.leaves.shrink_to_fit();
}

void CellImage::Keep(const std::vector<Int3>& cells) {
  std::vector<Int3> keep = cells;
  std::sort(keep.begin(), keep.end(), CellLess);
  KeepPart(sdf_, keep);
  for (Part& p : fractions_) KeepPart(p, keep);
}

const CellImage::Cell* CellImage::Part::Find(const Int3& origin) const {
  auto it = std::lower_bound(cells.begin(), cells.end(), origin,
                             [](const Cell& c, const Int3& o) { return CellLess(c.origin, o); });
  return it != cells.end() && it->origin == origin ? &*it : nullptr;
}

bool CellImage::Holds(const Int3& cell) const { return sdf_.Find(cell) != nullptr; }

std::vector<Int3> CellImage::Cells() const {
  std::vector<Int3> out;
  out.reserve(sdf_.cells.size());
  for (const Cell& c : sdf_.cells) out.push_back(c.origin);
  return out;
}

size_t CellImage::Part::MemoryBytes() const {
  return cells.capacity() * sizeof(Cell) + leaves.capacity() * sizeof(Leaf);
}

size_t CellImage::MemoryBytes() const {
  size_t n = sdf_.MemoryBytes() + fractions_.capacity() * sizeof(Part);
  for (const Part& p : fractions_) n += p.MemoryBytes();
  return n;
}

void CellImage::Clear() {
  sdf_ = {};
  fractions_ = {};
}

size_t CellImage::RestoreAll(Sculpture& sculpture) const { return Restore(sculpture, Cells()); }

size_t CellImage::Restore(Sculpture& sculpture, const std::vector<Int3>& cells) const {
  const size_t written = RestorePart(sdf_, sculpture, -1, cells);
  // An image taken under other materials than the sculpture holds now puts back no fractions
  // (the scene never redeclares materials while it runs).
  if (fractions_.size() == sculpture.impl().fractions.size()) {
    for (size_t m = 0; m < fractions_.size(); ++m) {
      RestorePart(fractions_[m], sculpture, static_cast<int>(m), cells);
    }
  }
  return written;
}

size_t CellImage::RestorePart(const Part& part, Sculpture& sculpture, int grid,
                              const std::vector<Int3>& cells) {
  Sculpture::Impl& impl = sculpture.impl();
  Tree& tree = (grid < 0 ? *impl.grid : *impl.fractions[static_cast<size_t>(grid)]).tree();
  // Cells that a node larger than a leaf held: that node is re-collapsed below once uniform.
  struct Collapse {
    Int3 origin;
    int level;  // 2: an internal node of leaf parents; 3: a root child
    float value;
    bool active;
    bool background;
  };
  std::vector<Collapse> collapse;
  size_t written = 0;
  for (const Int3& o : cells) {
    const Cell* c = part.Find(o);
    if (!c) continue;
    ++written;
    const Coord xyz(o.x, o.y, o.z);
    if (c->level == 0) {
      LeafT* leaf = tree.touchLeaf(xyz);
      const Leaf& l = part.leaves[c->leaf];
      openvdb::util::NodeMask<LeafT::LOG2DIM> mask;
      for (openvdb::Index32 w = 0; w < 8; ++w) mask.template getWord<openvdb::Index64>(w) = l.mask[w];
      leaf->setValueMask(mask);
      std::memcpy(leaf->buffer().data(), l.values, sizeof l.values);
    } else {
      const int depth = tree.getValueDepth(xyz);
      // A cell already held at a level above the leaf's parent with the same value needs nothing
      // (writing a leaf-level tile would split the node that holds it).
      const bool same = depth >= 0 && depth <= 1 && tree.getValue(xyz) == c->value &&
                        tree.isValueOn(xyz) == c->active;
      const bool same_bg = depth < 0 && c->level == 4;
      if (!same && !same_bg) tree.addTile(1, xyz, c->value, c->active);
      if (c->level >= 2) {
        collapse.push_back({Floor(o, kNode1Dim), 2, c->value, c->active, c->level == 4});
      }
      if (c->level >= 3) {
        collapse.push_back({Floor(o, kNode2Dim), 3, c->value, c->active, c->level == 4});
      }
    }
    if (grid < 0) impl.bounds.expand(openvdb::CoordBBox(xyz, xyz.offsetBy(kLeafDim - 1)));
  }
  if (collapse.empty()) return written;
  // Smaller nodes first, so that a root child whose leaf parents all collapsed collapses too.
  std::sort(collapse.begin(), collapse.end(), [](const Collapse& a, const Collapse& b) {
    return std::tie(a.level, a.origin.z, a.origin.y, a.origin.x) <
           std::tie(b.level, b.origin.z, b.origin.y, b.origin.x);
  });
  bool erase_background = false;
  for (size_t i = 0; i < collapse.size(); ++i) {
    const Collapse& c = collapse[i];
    if (i > 0 && collapse[i - 1].level == c.level && collapse[i - 1].origin == c.origin) continue;
    const Coord xyz(c.origin.x, c.origin.y, c.origin.z);
    if (c.level == 2) {
      const Node1* n = tree.probeConstNode<Node1>(xyz);
      if (n && Uniform(*n, c.value, c.active)) tree.addTile(2, xyz, c.value, c.active);
    } else {
      const Node2* n = tree.probeConstNode<Node2>(xyz);
      if (n && Uniform(*n, c.value, c.active)) {
        tree.addTile(3, xyz, c.value, c.active);
        erase_background = erase_background || c.background;
      }
    }
  }
  // A region that had no root entry gets none back (a background tile hashes unlike nothing).
  if (erase_background) tree.root().eraseBackgroundTiles();
  return written;
}

}  // namespace sculpt::levelset
