/// @brief An adaptive binary range coder (the scheme of LZMA's rc: 12-bit probabilities adapted by
/// 1/32 of the error, carry-propagating 32-bit range) and a signed-integer binarisation on top of
/// it; the entropy coder of the contour codec's curve coding (SKC2) and of SKC3's side
/// information. Internal to sculpt::skin.
///
/// Written here rather than taken from a package: Debian's entropy coders (zstd's FSE, brotli,
/// Draco's rANS) code whole blocks with static tables, and the web client needs a decoder it can
/// mirror bit for bit (client/web/src/contour_codec.js does). Kept small: integer arithmetic only,
/// so every platform codes the same bytes.
#ifndef SCULPT_SKIN_RANGE_CODER_H_
#define SCULPT_SKIN_RANGE_CODER_H_

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace sculpt::skin::internal {

inline constexpr int kProbBits = 12;
inline constexpr uint32_t kProbOne = 1u << kProbBits;
inline constexpr int kProbAdapt = 5;  // a model moves 1/32 of the way to each bit it sees
inline constexpr uint32_t kRangeTop = 1u << 24;

/// The probability that the next bit is 0, in 1/4096; starts at one half. Value type.
struct BitModel {
  uint16_t p = 2048;
};

/// Largest magnitude a signed integer may have: 2^53 - 1 (exact as a JavaScript number).
inline constexpr int kMaxIntBucket = 52;
inline constexpr uint64_t kMaxCodedMagnitude = (1ull << (kMaxIntBucket + 1)) - 1;

/// The adaptive models of one kind of signed integer: a zero flag, a sign, the bit length of the
/// magnitude in unary (one model per length) and the bit below the leading one (one model per
/// length); the lower bits go raw. Value type.
struct IntModel {
  BitModel zero, sign;
  BitModel length[kMaxIntBucket];
  BitModel top[kMaxIntBucket + 1];
};

/// Writes bits and integers; Finish() returns the bytes. Not thread-safe; one per message.
class RangeEncoder {
 public:
  void Bit(BitModel& m, int bit);
  /// The `count` (0..63) low bits of `v`, most significant first, each at probability 1/2.
  void Raw(uint64_t v, int count);
  /// A signed integer with |v| <= kMaxCodedMagnitude (the caller checks; larger is a bug).
  void Int(IntModel& m, int64_t v);
  /// Flushes and returns everything written; the encoder is spent afterwards.
  std::string Finish();

 private:
  void ShiftLow();
  uint64_t low_ = 0;
  uint32_t range_ = 0xffffffffu;
  uint8_t cache_ = 0;
  uint64_t cache_size_ = 1;
  std::string out_;
};

/// Reads what a RangeEncoder wrote, from untrusted bytes: reads past the end see zeros and are
/// counted, so a caller checks ok() (the first byte was 0 and every byte read was there) and
/// consumed() == size after the last symbol. Never reads outside `bytes`. Not thread-safe.
class RangeDecoder {
 public:
  // Inline, as everything here: a decoder whose address never reaches an out-of-line function
  // keeps its range and code in registers (the contour decoder makes about eleven decisions a
  // point).
  explicit RangeDecoder(std::string_view bytes) : in_(bytes) {
    // The encoder's first byte is its initial cache, always 0 (a carry never reaches it).
    ok_ = !in_.empty() && in_[0] == 0;
    for (pos_ = 1; pos_ < 5; ++pos_) {
      code_ = (code_ << 8) | (pos_ < in_.size() ? static_cast<uint8_t>(in_[pos_]) : 0u);
    }
  }
  [[gnu::always_inline]] int Bit(BitModel& m) {
    // Branch-free selection: the bits of a residual are what the data makes them, so a branch
    // here would be mispredicted often.
    const uint32_t p = m.p;
    const uint32_t bound = (range_ >> kProbBits) * p;
    const int bit = code_ >= bound;
    const uint32_t sub = bit ? bound : 0;
    range_ = bit ? range_ - bound : bound;
    code_ -= sub;
    m.p = static_cast<uint16_t>(bit ? p - (p >> kProbAdapt) : p + ((kProbOne - p) >> kProbAdapt));
    // One byte always suffices: p stays in [31, 4065], so a bit leaves at least 31/4096 of a
    // range >= 2^24, i.e. >= 2^16.
    if (range_ < kRangeTop) Shift();
    return bit;
  }
  [[gnu::always_inline]] uint64_t Raw(int count) {
    uint64_t v = 0;
    for (int i = 0; i < count; ++i) {
      range_ >>= 1;
      // Corrupt input can leave code_ >= range_; the bit is then 1 and code_ stays inside.
      const uint32_t bit = code_ >= range_ ? 1 : 0;
      code_ -= bit ? range_ : 0;
      v = (v << 1) | bit;
      if (range_ < kRangeTop) Shift();  // range_ >= 2^23 here: one byte suffices
    }
    return v;
  }
  /// An integer as RangeEncoder::Int wrote it; |value| <= kMaxCodedMagnitude whatever the input.
  [[gnu::always_inline]] int64_t Int(IntModel& m) {
    if (!Bit(m.zero)) return 0;
    const bool negative = Bit(m.sign);
    int k = 0;
    while (k < kMaxIntBucket && Bit(m.length[k])) ++k;
    uint64_t mag = 1;
    if (k >= 1) {
      mag = (uint64_t{2} | static_cast<uint64_t>(Bit(m.top[k]))) << (k - 1);
      if (k >= 2) mag |= Raw(k - 1);
    }
    const int64_t s = static_cast<int64_t>(mag);
    return negative ? -s : s;
  }
  bool ok() const { return ok_ && pos_ <= in_.size(); }
  /// Bytes taken from the input so far (including the 5 of the start).
  size_t consumed() const { return pos_ < in_.size() ? pos_ : in_.size(); }

 private:
  [[gnu::always_inline]] void Shift() {
    // Past the end reads zeros; pos_ keeps counting, so ok() sees the overrun.
    const uint32_t b = pos_ < in_.size() ? static_cast<uint8_t>(in_[pos_]) : 0;
    ++pos_;
    range_ <<= 8;
    code_ = (code_ << 8) | b;
  }
  std::string_view in_;
  size_t pos_ = 0;
  uint32_t range_ = 0xffffffffu;
  uint32_t code_ = 0;
  bool ok_ = true;
};

}  // namespace sculpt::skin::internal

#endif  // SCULPT_SKIN_RANGE_CODER_H_
