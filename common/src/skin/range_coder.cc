/// @brief The adaptive binary range coder of the contour codec's curve coding.
#include "range_coder.h"

#include <bit>

namespace sculpt::skin::internal {
namespace {

constexpr uint32_t kOne = kProbOne;
constexpr int kAdapt = kProbAdapt;
constexpr uint32_t kTop = kRangeTop;

}  // namespace

void RangeEncoder::ShiftLow() {
  // A byte leaves only once no later carry can change it: 0xff bytes wait in cache_size_.
  if (static_cast<uint32_t>(low_) < 0xff000000u || (low_ >> 32) != 0) {
    const uint8_t carry = static_cast<uint8_t>(low_ >> 32);
    uint8_t b = cache_;
    do {
      out_.push_back(static_cast<char>(static_cast<uint8_t>(b + carry)));
      b = 0xff;
    } while (--cache_size_ != 0);
    cache_ = static_cast<uint8_t>(low_ >> 24);
  }
  ++cache_size_;
  low_ = (low_ & 0x00ffffffu) << 8;
}

void RangeEncoder::Bit(BitModel& m, int bit) {
  const uint32_t bound = (range_ >> kProbBits) * m.p;
  if (bit == 0) {
    range_ = bound;
    m.p = static_cast<uint16_t>(m.p + ((kOne - m.p) >> kAdapt));
  } else {
    low_ += bound;
    range_ -= bound;
    m.p = static_cast<uint16_t>(m.p - (m.p >> kAdapt));
  }
  while (range_ < kTop) {
    range_ <<= 8;
    ShiftLow();
  }
}

void RangeEncoder::Raw(uint64_t v, int count) {
  for (int i = count - 1; i >= 0; --i) {
    range_ >>= 1;
    if ((v >> i) & 1) low_ += range_;
    while (range_ < kTop) {
      range_ <<= 8;
      ShiftLow();
    }
  }
}

void RangeEncoder::Int(IntModel& m, int64_t v) {
  Bit(m.zero, v != 0);
  if (v == 0) return;
  Bit(m.sign, v < 0);
  const uint64_t mag = v < 0 ? 0 - static_cast<uint64_t>(v) : static_cast<uint64_t>(v);
  const int k = std::bit_width(mag) - 1;  // mag in [2^k, 2^(k+1)), k <= kMaxIntBucket
  for (int j = 0; j < k; ++j) Bit(m.length[j], 1);
  if (k < kMaxIntBucket) Bit(m.length[k], 0);
  if (k >= 1) {
    Bit(m.top[k], static_cast<int>((mag >> (k - 1)) & 1));
    Raw(mag, k - 1);
  }
}

std::string RangeEncoder::Finish() {
  for (int i = 0; i < 5; ++i) ShiftLow();
  return std::move(out_);
}

}  // namespace sculpt::skin::internal
