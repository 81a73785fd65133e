/// @brief libFuzzer target for the leaf-record decoder (levelset::ApplyLeafRecords,
/// common/src/levelset/region.cc), what a replica applies from every LeafDelta.
///
/// Byte 0 of an input: bit 0: the sculpture declares two materials (SLR2 records) or none (SLR1);
/// bit 1: the records are clipped to a box; bit 2: the rest is the raw record payload, which the
/// target frames and compresses as EncodeLeafRecords does (so mutations reach the record parser
/// instead of zstd's checks), else it is the wire form as it is (raw size, zstd frame).
/// Fails (aborts) when
///  - a refused input changed the sculpture or its refusal is not DataLoss;
///  - an accepted input left something that is not a valid level set (CheckLevelSet's eight
///    checks: values within the band, inactive values at +-background, no active tiles, ...);
///  - the cells it wrote, encoded again and applied to a fresh copy, do not give the same leaves.
#include <tbb/global_control.h>
#include <zstd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>

#include "sculpt/levelset/materials.h"
#include "sculpt/levelset/region.h"
#include "sculpt/levelset/sculpture.h"

namespace {

using sculpt::levelset::Sculpture;

[[noreturn]] void Fail(const std::string& what) {
  std::fprintf(stderr, "leaf_records fuzz invariant failed: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

Sculpture MakeStart(bool materials) {
  sculpt::levelset::SculptureOptions o;
  o.voxel_size = 0.5;
  o.name = "clay";
  // A replica's starting point (region.h): cheap to copy and hash, so the fuzzer spends its time
  // in the decoder. The seeds' records come from a sphere with the same voxel size and band.
  auto s = sculpt::levelset::MakeEmptySculpture(o);
  if (!s.ok()) Fail(s.status().ToString());
  if (materials) {
    const sculpt::Status m = sculpt::levelset::SetMaterials(
        *s, {{"clay", {0.8, 0.5, 0.3}}, {"glaze", {0.2, 0.4, 0.9}}});
    if (!m.ok()) Fail(m.ToString());
  }
  return std::move(s).value();
}

// One thread: OpenVDB's parallel tree walks (CheckLevelSet, StateHash) would wake TBB's workers
// for every input, which on a loaded machine costs more than the walks.
const tbb::global_control kOneThread(tbb::global_control::max_allowed_parallelism, 1);

const Sculpture& Start(bool materials) {
  static const Sculpture plain = MakeStart(false);
  static const Sculpture painted = MakeStart(true);
  return materials ? painted : plain;
}

// The wire form of a raw payload: its size, then one zstd frame (EncodeLeafRecords' framing).
std::string Frame(std::string_view raw) {
  std::string out(8 + ZSTD_compressBound(raw.size()), '\0');
  const uint64_t raw_size = raw.size();
  std::memcpy(out.data(), &raw_size, 8);
  const size_t z = ZSTD_compress(out.data() + 8, out.size() - 8, raw.data(), raw.size(), 1);
  if (ZSTD_isError(z)) Fail(std::string("zstd: ") + ZSTD_getErrorName(z));
  out.resize(8 + z);
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace ls = sculpt::levelset;
  if (size < 1) return 0;
  const uint8_t flags = data[0];
  const bool materials = flags & 1;
  const std::string_view rest(reinterpret_cast<const char*>(data) + 1, size - 1);
  const std::string bytes = (flags & 4) ? Frame(rest) : std::string(rest);
  ls::VoxelBox clip;
  if (flags & 2) clip = ls::VoxelBox{{-8, -8, 0}, {7, 15, 7}};

  const Sculpture& start = Start(materials);
  Sculpture s = start.Clone();
  auto applied = ls::ApplyLeafRecords(s, bytes, clip);
  if (!applied.ok()) {
    if (applied.status().code() != sculpt::Status::Code::kDataLoss) {
      Fail("refused with " + applied.status().ToString());
    }
    static const uint64_t before[2] = {Start(false).StateHash(), Start(true).StateHash()};
    if (s.StateHash() != before[materials]) {
      Fail("refused, yet changed: " + applied.status().ToString());
    }
    return 0;
  }
  if (applied->cells.size() != applied->records) Fail("cells and records disagree");
  if (const sculpt::Status c = s.CheckLevelSet(8); !c.ok()) {
    Fail("accepted records left an invalid level set: " + c.ToString());
  }
  // What was written, sent again to a fresh copy, gives the same leaves.
  const std::string again = ls::EncodeLeafRecords(s, applied->cells, nullptr, 1);
  Sculpture copy = start.Clone();
  auto reapplied = ls::ApplyLeafRecords(copy, again);
  if (!reapplied.ok()) Fail("re-encoded records refused: " + reapplied.status().ToString());
  if (ls::LeavesHash(copy, applied->cells) != ls::LeavesHash(s, applied->cells)) {
    Fail("re-encoded records give other leaves");
  }
  return 0;
}
