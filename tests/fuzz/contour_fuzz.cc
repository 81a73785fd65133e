/// @brief libFuzzer target for the contour codec: skin::DecodeContours and ContourView::Apply on
/// arbitrary bytes (every format: SKC4, SKC3, SKC2, SKC1), and, for inputs starting with 'E', the
/// encoder on polylines made from the bytes: SKC4 alone, SKC3 alone and the default message must
/// decode to every point within step/sqrt(2).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string_view>
#include <vector>

#include "sculpt/skin/contour_codec.h"
// By path: the replay build (gcc, tests/fuzz/CMakeLists.txt) has no include directory for the
// codec's internals.
#include "../../common/src/skin/contour_codec_internal.h"

namespace {

using sculpt::skin::Polyline2;
using sculpt::skin::Vec2;

/// Polylines from bytes: a step byte, then per point a control byte (new line, closing, or a
/// move) and two int16 moves, so lines wander, turn, stop and jump.
void RoundTrip(const uint8_t* data, size_t size) {
  if (size < 2) return;
  const double step = std::ldexp(1.0, static_cast<int>(data[1] % 40) - 20);
  std::vector<Polyline2> lines(1);
  Vec2 at{0, 0};
  for (size_t i = 2; i + 5 <= size && lines.size() < 64; i += 5) {
    int16_t dx, dy;
    std::memcpy(&dx, data + i + 1, 2);
    std::memcpy(&dy, data + i + 3, 2);
    const uint8_t c = data[i];
    if (c < 8) {
      lines.emplace_back();
    } else if (c < 12 && !lines.back().empty()) {
      lines.back().push_back(lines.back().front());
      continue;
    }
    const double scale = std::ldexp(step, c % 16);
    at = at + Vec2{dx * scale, dy * scale};
    lines.back().push_back(at);
  }
  const double bound = step * 0.70710678118654752 * (1 + 1e-9);
  for (const auto& bytes : {sculpt::skin::internal::EncodeContoursSkc4(lines, step),
                            sculpt::skin::internal::EncodeContoursSkc3(lines, step),
                            sculpt::skin::EncodeContours(lines, step)}) {
    if (!bytes.ok()) std::abort();  // every coordinate here is within 2^52 steps
    const auto back = sculpt::skin::DecodeContours(*bytes);
    if (!back.ok() || back->size() != lines.size()) std::abort();
    for (size_t j = 0; j < lines.size(); ++j) {
      if ((*back)[j].size() != lines[j].size()) std::abort();
      for (size_t k = 0; k < lines[j].size(); ++k) {
        if (!(((*back)[j][k] - lines[j][k]).Length() <= bound)) std::abort();
      }
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  auto polylines = sculpt::skin::DecodeContours(bytes);
  (void)polylines;
  sculpt::skin::ContourView view;
  (void)view.Apply(bytes);
  if (size > 0 && data[0] == 'E') RoundTrip(data, size);
  return 0;
}
