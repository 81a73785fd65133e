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

}  // namespace

void CellImage::AppendTo(std::string& out) const {
  Put(out, static_cast<uint32_t>(cells_.size()));
  Put(out, static_cast<uint32_t>(leaves_.size()));
  for (const Cell& c : cells_) {
    const int32_t o[3] = {c.origin.x, c.origin.y, c.origin.z};
    Put(out, o);
    Put(out, c.level);
    Put(out, static_cast<uint8_t>(c.active));
    Put(out, c.value);
    Put(out, c.leaf);
  }
  for (const Leaf& l : leaves_) Put(out, l);
}

StatusOr<CellImage> CellImage::ReadFrom(std::string_view& in) {
  uint32_t ncells = 0, nleaves = 0;
  if (!Get(in, &ncells) || !Get(in, &nleaves)) return DataLoss("cell image: counts truncated");
  constexpr size_t kCellBytes = 12 + 1 + 1 + 4 + 4;
  if (ncells > in.size() / kCellBytes || nleaves > ncells) {
    return Outside(
        "cell image: cells", std::to_string(ncells) + ", leaves=" + std::to_string(nleaves),
        std::string("what ") + std::to_string(in.size()) + " bytes hold", Status::Code::kDataLoss);
  }
  CellImage img;
  img.cells_.resize(ncells);
  for (uint32_t i = 0; i < ncells; ++i) {
    Cell& c = img.cells_[i];
    int32_t o[3];
    uint8_t active = 0;
    if (!Get(in, &o) || !Get(in, &c.level) || !Get(in, &active) || !Get(in, &c.value) ||
        !Get(in, &c.leaf)) {
      return DataLoss("cell image: cell " + std::to_string(i) + " truncated");
    }
    c.origin = {o[0], o[1], o[2]};
    c.active = active != 0;
    if (o[0] % kLeafDim || o[1] % kLeafDim || o[2] % kLeafDim || c.level > 4 ||
        (c.level == 0 && c.leaf >= nleaves) || (i > 0 && !CellLess(img.cells_[i - 1].origin, c.origin))) {
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
  img.leaves_.resize(nleaves);
  // An empty image has no buffer: memcpy's pointers must not be null, even for no bytes.
  if (nleaves > 0) std::memcpy(img.leaves_.data(), in.data(), nleaves * sizeof(Leaf));
  in.remove_prefix(nleaves * sizeof(Leaf));
  return img;
}

CellImage CellImage::Capture(const Sculpture& sculpture, const VoxelBox& box) {
  CellImage img;
  if (box.Empty()) return img;
  const Tree& tree = sculpture.impl().grid->tree();
  std::vector<Int3> cells = AllLeafCells(box);
  std::sort(cells.begin(), cells.end(), CellLess);
  img.cells_.reserve(cells.size());
  // Counted first so the copies land in one allocation (a stroke's footprint holds ~100 leaves).
  size_t leaves = 0;
  for (const Int3& c : cells) leaves += tree.probeConstLeaf(Coord(c.x, c.y, c.z)) != nullptr;
  img.leaves_.reserve(leaves);
  for (const Int3& c : cells) {
    const Coord xyz(c.x, c.y, c.z);
    Cell cell;
    cell.origin = c;
    if (const LeafT* leaf = tree.probeConstLeaf(xyz)) {
      cell.level = 0;
      cell.leaf = static_cast<uint32_t>(img.leaves_.size());
      Leaf& l = img.leaves_.emplace_back();
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
    img.cells_.push_back(cell);
  }
  return img;
}

void CellImage::Keep(const std::vector<Int3>& cells) {
  std::vector<Int3> keep = cells;
  std::sort(keep.begin(), keep.end(), CellLess);
  std::vector<Cell> kept;
  std::vector<Leaf> kept_leaves;
  for (const Cell& c : cells_) {
    if (!std::binary_search(keep.begin(), keep.end(), c.origin, CellLess)) continue;
    Cell k = c;
    if (c.level == 0) {
      k.leaf = static_cast<uint32_t>(kept_leaves.size());
      kept_leaves.push_back(leaves_[c.leaf]);
    }
    kept.push_back(k);
  }
  cells_ = std::move(kept);
  leaves_ = std::move(kept_leaves);
  cells_.shrink_to_fit();
  leaves_.shrink_to_fit();
}

const CellImage::Cell* CellImage::Find(const Int3& origin) const {
  auto it = std::lower_bound(cells_.begin(), cells_.end(), origin,
                             [](const Cell& c, const Int3& o) { return CellLess(c.origin, o); });
  return it != cells_.end() && it->origin == origin ? &*it : nullptr;
}

bool CellImage::Holds(const Int3& cell) const { return Find(cell) != nullptr; }

std::vector<Int3> CellImage::Cells() const {
  std::vector<Int3> out;
  out.reserve(cells_.size());
  for (const Cell& c : cells_) out.push_back(c.origin);
  return out;
}

size_t CellImage::MemoryBytes() const {
  return cells_.capacity() * sizeof(Cell) + leaves_.capacity() * sizeof(Leaf);
}

void CellImage::Clear() {
  cells_ = {};
  leaves_ = {};
}

size_t CellImage::RestoreAll(Sculpture& sculpture) const { return Restore(sculpture, Cells()); }

size_t CellImage::Restore(Sculpture& sculpture, const std::vector<Int3>& cells) const {
  Sculpture::Impl& impl = sculpture.impl();
  Tree& tree = impl.grid->tree();
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
    const Cell* c = Find(o);
    if (!c) continue;
    ++written;
    const Coord xyz(o.x, o.y, o.z);
    if (c->level == 0) {
      LeafT* leaf = tree.touchLeaf(xyz);
      const Leaf& l = leaves_[c->leaf];
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
    impl.bounds.expand(openvdb::CoordBBox(xyz, xyz.offsetBy(kLeafDim - 1)));
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
