/// @brief libFuzzer target for skin::DecodeContours on arbitrary bytes.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "sculpt/skin/contour_codec.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto polylines =
      sculpt::skin::DecodeContours(std::string_view(reinterpret_cast<const char*>(data), size));
  (void)polylines;
  return 0;
}
