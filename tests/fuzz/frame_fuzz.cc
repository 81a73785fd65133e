/// @brief libFuzzer target for codec::FrameReader: arbitrary bytes fed in arbitrary chunks.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "sculpt/codec/frame.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 2) return 0;
  // First byte: the maximum frame size (small, so the length check is reached); second: the chunk
  // size the "socket" delivers.
  const uint32_t max = 1u + data[0] * 4u;
  const size_t chunk = 1u + data[1];
  data += 2;
  size -= 2;
  sculpt::codec::FrameReader reader(max);
  size_t offset = 0;
  while (offset < size) {
    const size_t n = size - offset < chunk ? size - offset : chunk;
    reader.Feed(reinterpret_cast<const char*>(data + offset), n);
    offset += n;
    for (;;) {
      auto next = reader.Next();
      if (!next.ok()) return 0;  // oversized header: the caller closes
      if (!next->has_value()) break;
      if ((*next)->size() > max) std::abort();
    }
    if (reader.buffered() > offset) std::abort();
  }
  return 0;
}
