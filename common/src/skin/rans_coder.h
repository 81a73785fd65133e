/// @brief A static-table rANS coder of whole symbols (SKC3's point coder): per-message frequency
/// tables of at most kRansAlphabet symbols at 11-bit precision, two interleaved 32-bit states
/// sharing one stream of 16-bit words, one table lookup per decoded symbol; and the token scheme
/// that maps a signed integer to a symbol plus raw extra bits (a separate bit stream).
/// Internal to sculpt::skin.
///
/// Written here rather than taken from a package: Debian ships no library with a public
/// table-driven entropy coder API (zstd's FSE and Huff0 are internal to libzstd, brotli and zlib
/// expose only whole-stream compression, Draco's rANS reads its own symbol format with adaptive
/// precision), and the web client needs a decoder it can mirror bit for bit
/// (client/web/src/contour_codec.js does). Integer arithmetic only.
#ifndef SCULPT_SKIN_RANS_CODER_H_
#define SCULPT_SKIN_RANS_CODER_H_

#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

namespace sculpt::skin::internal {

inline constexpr int kRansScaleBits = 10;
inline constexpr uint32_t kRansScale = 1u << kRansScaleBits;
inline constexpr uint32_t kRansLow = 1u << 16;  // states live in [2^16, 2^32)

/// Tokens: a zigzagged integer below kTokenDirect is its own symbol; above, the symbol names its
/// bit length and the bit under the leading one, and the bits below those go raw.
inline constexpr int kTokenDirectBits = 4;
inline constexpr int kTokenDirect = 1 << kTokenDirectBits;
inline constexpr int kTokenMaxBits = 42;  // zigzag values below 2^42: |v| < 2^41
inline constexpr int kRansAlphabet = kTokenDirect + 2 * (kTokenMaxBits - kTokenDirectBits);
inline constexpr int64_t kMaxTokenMagnitude = (int64_t{1} << 40);

/// A signed integer's symbol and its raw extra bits (count and value). |v| <= kMaxTokenMagnitude.
struct Token {
  int symbol = 0;
  int extra_bits = 0;
  uint64_t extra = 0;
};
Token MakeToken(int64_t v);
/// The extra bit count of a symbol (0 for the direct ones).
constexpr int TokenExtraBits(int symbol) {
  return symbol < kTokenDirect ? 0 : (symbol - kTokenDirect) / 2 + kTokenDirectBits - 1;
}
/// The integer of a symbol and its extra bits.
inline int64_t TokenValue(int symbol, uint64_t extra) {
  uint64_t zz;
  if (symbol < kTokenDirect) {
    zz = static_cast<uint64_t>(symbol);
  } else {
    const int n = (symbol - kTokenDirect) / 2 + kTokenDirectBits - 1;  // raw, under the top two
    zz = ((uint64_t{2} | static_cast<uint64_t>((symbol - kTokenDirect) & 1)) << n) | extra;
  }
  return static_cast<int64_t>(zz >> 1) ^ -static_cast<int64_t>(zz & 1);
}

/// Scales symbol counts to frequencies summing to kRansScale, every used symbol at least 1.
/// Empty (all zero) counts give an empty table (all zero).
std::vector<uint32_t> NormaliseCounts(const std::vector<uint64_t>& counts);

/// The decoder's view of one table: per slot, the symbol (7 bits), a 2-bit tag the caller gives
/// each symbol, slot - start of the symbol (kRansScaleBits) and its frequency (above), in one word
/// so a table stays small in cache.
using RansSlot = uint32_t;
inline constexpr int kSlotTagShift = 7;
inline constexpr int kSlotBiasShift = kSlotTagShift + 2;
inline constexpr int kSlotFreqShift = kSlotBiasShift + kRansScaleBits;
inline constexpr RansSlot MakeSlot(uint32_t freq, uint32_t bias, uint32_t symbol,
                                   uint32_t tag = 0) {
  return (freq << kSlotFreqShift) | (bias << kSlotBiasShift) | (tag << kSlotTagShift) | symbol;
}
inline constexpr uint32_t SlotSymbol(RansSlot s) { return s & 127; }
/// The tag of the symbol a slot decodes (0 for a slot of an empty table).
inline constexpr uint32_t SlotTag(RansSlot s) { return (s >> kSlotTagShift) & 3; }
/// A symbol value that marks a slot of an empty table (its use is a decode error).
inline constexpr uint16_t kRansNoSymbol = kRansAlphabet;

/// Fills `slots` (kRansScale entries) from frequencies that sum to kRansScale (or are all zero:
/// every slot then decodes kRansNoSymbol and leaves the state as it was), each symbol s's slots
/// tagged tags[s] (0-3; none if `tags` is null). False if they sum to anything else or there are
/// more than kRansAlphabet.
bool BuildRansSlots(const std::vector<uint32_t>& freq, RansSlot* slots,
                    const uint8_t* tags = nullptr);

/// Collects symbols with their frequency tables and state (0 or 1), then writes them in reverse.
/// Not thread-safe.
class RansEncoder {
 public:
  /// `freq` and `start` of the symbol in its table; `lane` is 0 or 1.
  void Put(uint32_t freq, uint32_t start, int lane) { syms_.push_back({freq, start, lane}); }
  /// The words of every symbol put, little-endian bytes, the states first.
  std::string Finish() const;

 private:
  struct Sym {
    uint32_t freq, start;
    int lane;
  };
  std::vector<Sym> syms_;
};

/// Reads RansEncoder's stream from untrusted bytes: past the end reads zeros and is noted, so a
/// caller checks ok() at the end (every word was there, every word was read, both states back
/// at their start). Never reads outside `bytes`.
class RansDecoder {
 public:
  explicit RansDecoder(std::string_view bytes)
      : p_(reinterpret_cast<const uint8_t*>(bytes.data())),
        end_(p_ + (bytes.size() & ~size_t{1})),
        odd_(bytes.size() & 1) {
    // Two statements each: the operands of | are unsequenced.
    x0_ = Word() << 16;
    x0_ |= Word();
    x1_ = Word() << 16;
    x1_ |= Word();
  }
  /// The next symbol of `lane` (0 or 1) from `table` (kRansScale slots).
  [[gnu::always_inline]] uint32_t Decode(const RansSlot* table, int lane) {
    return SlotSymbol(DecodeSlot(table, lane));
  }
  /// The slot of the next symbol (its symbol and tag).
  [[gnu::always_inline]] RansSlot DecodeSlot(const RansSlot* table, int lane) {
    // Two named states rather than an array, so both stay in registers.
    return lane == 0 ? Step<true>(table, x0_) : Step<true>(table, x1_);
  }
  /// DecodeSlot without the end-of-stream guard: only while words_left() is at least the number
  /// of symbols still to decode (a symbol takes at most one word).
  [[gnu::always_inline]] RansSlot DecodeSlotUnchecked(const RansSlot* table, int lane) {
    return lane == 0 ? Step<false>(table, x0_) : Step<false>(table, x1_);
  }
  /// The 16-bit words not yet read.
  size_t words_left() const { return static_cast<size_t>(end_ - p_) / 2; }
  /// True when the stream was read exactly and ended where the encoder began.
  bool ok() const { return !overrun_ && !odd_ && p_ == end_ && x0_ == kRansLow && x1_ == kRansLow; }
  bool overrun() const { return overrun_; }

 private:
  template <bool kChecked>
  [[gnu::always_inline]] RansSlot Step(const RansSlot* table, uint32_t& state) {
    uint32_t x = state;
    const RansSlot s = table[x & (kRansScale - 1)];
    x = (s >> kSlotFreqShift) * (x >> kRansScaleBits) + ((s >> kSlotBiasShift) & (kRansScale - 1));
    // Branch-free renormalisation: whether a word is due is what the data makes it, so a branch
    // would be mispredicted about once in three symbols. Checked, the load is guarded by a branch
    // that only the stream's end takes.
    const bool need = x < kRansLow;
    uint32_t w;
    if constexpr (kChecked) {
      const bool have = p_ != end_;
      w = have ? static_cast<uint32_t>(p_[0]) | (static_cast<uint32_t>(p_[1]) << 8) : 0;
      overrun_ |= need & !have;
      p_ += (need & have) ? 2 : 0;
      x = need ? (x << 16) | w : x;
    } else {
      // A select: GCC makes a branch of `need ? y : x` here (mispredicted about once in three
      // symbols) and of any mask form a longer chain, so on x86-64 it is written as the cmov it
      // should be; shifting by 16 * need cost a variable shift and four more instructions.
      w = static_cast<uint32_t>(p_[0]) | (static_cast<uint32_t>(p_[1]) << 8);
      const uint32_t y = (x << 16) | w;
#if defined(__x86_64__) && defined(__GNUC__)
      uint32_t n;
      asm("xorl %k[n], %k[n]\n\t"
          "cmpl $0xffff, %[x]\n\t"
          "cmovbe %[y], %[x]\n\t"
          "setbe %b[n]"
          : [x] "+r"(x), [n] "=&r"(n)
          : [y] "r"(y)
          : "cc");
      p_ += 2 * n;
#else
      x ^= (y ^ x) & (0u - static_cast<uint32_t>(need));
      p_ += need ? 2 : 0;
#endif
    }
    state = x;
    return s;
  }
  [[gnu::always_inline]] uint32_t Word() {
    if (p_ == end_) {
      overrun_ = true;
      return 0;
    }
    const uint32_t w = static_cast<uint32_t>(p_[0]) | (static_cast<uint32_t>(p_[1]) << 8);
    p_ += 2;
    return w;
  }
  const uint8_t* p_;
  const uint8_t* end_;
  bool odd_;
  bool overrun_ = false;
  uint32_t x0_ = 0, x1_ = 0;
};

/// Raw bits, least significant first, packed into bytes from the low end.
class BitWriter {
 public:
  void Put(uint64_t v, int count);  // count <= 57
  std::string Finish() const;

 private:
  std::string out_;
  uint64_t acc_ = 0;
  int n_ = 0;
};

/// Reads BitWriter's bits from untrusted bytes; past the end reads zeros and is noted.
class BitReader {
 public:
  explicit BitReader(std::string_view bytes)
      : p_(reinterpret_cast<const uint8_t*>(bytes.data())), end_(p_ + bytes.size()) {}
  /// `count` <= 48 bits (0 reads nothing).
  [[gnu::always_inline]] uint64_t Get(int count) { return Get(count, (uint64_t{1} << count) - 1); }
  /// Get(count) with its mask, 2^count - 1, from the caller's table.
  [[gnu::always_inline]] uint64_t Get(int count, uint64_t mask) {
    if (n_ < count) [[unlikely]]
      Refill(count);
    const uint64_t v = acc_ & mask;
    acc_ >>= count;
    n_ -= count;
    return v;
  }
  /// Get(c1, m1) then Get(c2, m2), with one test for a refill where the two fit one (c1 + c2 <= 56,
  /// so one refill of eight bytes covers both): the same bits, the same end-of-stream note.
  [[gnu::always_inline]] void Get2(int c1, uint64_t m1, int c2, uint64_t m2, uint64_t* v1,
                                   uint64_t* v2) {
    const int c = c1 + c2;
    if (n_ < c) [[unlikely]] {
      if (c > 56) {
        *v1 = Get(c1, m1);
        *v2 = Get(c2, m2);
        return;
      }
      Refill(c);
    }
    *v1 = acc_ & m1;
    acc_ >>= c1;
    *v2 = acc_ & m2;
    acc_ >>= c2;
    n_ -= c;
  }
  /// True when no read went past the end and every whole byte was used (the unused bits of the
  /// last byte are zero).
  bool ok() const { return !overrun_ && p_ == end_ && n_ < 8 && acc_ == 0; }

 private:
  [[gnu::always_inline]] void Refill(int count) {
    if (end_ - p_ >= 8) {
      // Eight bytes at once, as many whole ones counted as fit. The bits above n_ then hold the
      // bytes not yet counted, which the next refill ORs in again at the same place.
      uint64_t v;
      std::memcpy(&v, p_, 8);
      if constexpr (std::endian::native == std::endian::big) v = __builtin_bswap64(v);
      acc_ |= v << n_;
      const int take = (63 - n_) >> 3;
      p_ += take;
      n_ += 8 * take;
      return;
    }
    while (n_ <= 56 && p_ < end_) {
      acc_ |= static_cast<uint64_t>(*p_++) << n_;
      n_ += 8;
    }
    if (n_ < count) {  // past the end: zeros
      overrun_ = true;
      n_ = count;
    }
  }
  const uint8_t* p_;
  const uint8_t* end_;
  uint64_t acc_ = 0;
  int n_ = 0;
  bool overrun_ = false;
};

}  // namespace sculpt::skin::internal

#endif  // SCULPT_SKIN_RANS_CODER_H_
