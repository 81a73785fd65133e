/// @brief libFuzzer target for the contour codec's range coder (common/src/skin/range_coder.h):
/// arbitrary bytes decode to bounded integers without reading outside them, and the integers
/// read from them, encoded again, decode to the same values.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>
#include <vector>

#include "range_coder.h"

using sculpt::skin::internal::BitModel;
using sculpt::skin::internal::IntModel;
using sculpt::skin::internal::kMaxCodedMagnitude;
using sculpt::skin::internal::RangeDecoder;
using sculpt::skin::internal::RangeEncoder;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  // Decode a mix of bits, raw bits and integers over four contexts, as the codec does.
  RangeDecoder dec(bytes);
  IntModel ints[4];
  BitModel bits[2];
  std::vector<int64_t> values;
  for (size_t i = 0; i < 4 * size + 8 && dec.consumed() <= size; ++i) {
    const int64_t v = dec.Int(ints[i % 4]);
    if (v > static_cast<int64_t>(kMaxCodedMagnitude) ||
        v < -static_cast<int64_t>(kMaxCodedMagnitude)) {
      std::abort();
    }
    values.push_back(v);
    values.push_back(dec.Bit(bits[i % 2]));
    values.push_back(static_cast<int64_t>(dec.Raw(static_cast<int>(i % 24))));
    if (!dec.ok()) break;
  }
  if (dec.consumed() > size + 5) std::abort();  // only the start may read zeros past the end
  // Round trip what was read.
  RangeEncoder enc;
  IntModel eints[4];
  BitModel ebits[2];
  for (size_t k = 0; k + 2 < values.size(); k += 3) {
    const size_t i = k / 3;
    enc.Int(eints[i % 4], values[k]);
    enc.Bit(ebits[i % 2], static_cast<int>(values[k + 1]));
    enc.Raw(static_cast<uint64_t>(values[k + 2]), static_cast<int>(i % 24));
  }
  const std::string out = enc.Finish();
  RangeDecoder again(out);
  IntModel dints[4];
  BitModel dbits[2];
  for (size_t k = 0; k + 2 < values.size(); k += 3) {
    const size_t i = k / 3;
    if (again.Int(dints[i % 4]) != values[k] || again.Bit(dbits[i % 2]) != values[k + 1] ||
        static_cast<int64_t>(again.Raw(static_cast<int>(i % 24))) != values[k + 2]) {
      std::abort();
    }
  }
  if (!again.ok() || again.consumed() != out.size()) std::abort();
  return 0;
}
