/// @brief The static-table rANS coder's encoder side, table building and tokens.
#include "rans_coder.h"

#include <algorithm>
#include <bit>

namespace sculpt::skin::internal {

Token MakeToken(int64_t v) {
  const uint64_t zz = (static_cast<uint64_t>(v) << 1) ^ static_cast<uint64_t>(v >> 63);
  Token t;
  if (zz < kTokenDirect) {
    t.symbol = static_cast<int>(zz);
    return t;
  }
  const int nb = std::bit_width(zz);
  t.extra_bits = nb - 2;
  t.symbol =
      kTokenDirect + 2 * (nb - kTokenDirectBits - 1) + static_cast<int>((zz >> (nb - 2)) & 1);
  t.extra = zz & ((uint64_t{1} << t.extra_bits) - 1);
  return t;
}

std::vector<uint32_t> NormaliseCounts(const std::vector<uint64_t>& counts) {
  std::vector<uint32_t> freq(counts.size(), 0);
  uint64_t total = 0;
  for (uint64_t c : counts) total += c;
  if (total == 0) return freq;
  int64_t sum = 0;
  for (size_t i = 0; i < counts.size(); ++i) {
    if (counts[i] == 0) continue;
    const double f = static_cast<double>(counts[i]) * kRansScale / static_cast<double>(total);
    freq[i] = std::max<uint32_t>(1, static_cast<uint32_t>(f + 0.5));
    sum += freq[i];
  }
  // Rounding leaves the sum a little off: take from (or give to) the most frequent symbols, whose
  // code lengths change least.
  while (sum != static_cast<int64_t>(kRansScale)) {
    size_t best = 0;
    for (size_t i = 1; i < freq.size(); ++i) {
      if (freq[i] > freq[best]) best = i;
    }
    if (sum > static_cast<int64_t>(kRansScale)) {
      // Spread the cut over the largest ones so none drops far.
      const int64_t cut = std::min<int64_t>(sum - kRansScale, std::max<int64_t>(1, freq[best] / 8));
      freq[best] -= static_cast<uint32_t>(cut);
      sum -= cut;
    } else {
      freq[best] += static_cast<uint32_t>(kRansScale - sum);
      sum = kRansScale;
    }
  }
  return freq;
}

bool BuildRansSlots(const std::vector<uint32_t>& freq, RansSlot* slots, const uint8_t* tags) {
  if (freq.size() > static_cast<size_t>(kRansAlphabet)) return false;
  uint32_t sum = 0;
  for (uint32_t f : freq) {
    if (f > kRansScale) return false;
    sum += f;
  }
  if (sum == 0) {
    for (uint32_t s = 0; s < kRansScale; ++s) {
      slots[s] = MakeSlot(kRansScale, s, kRansNoSymbol);
    }
    return true;
  }
  if (sum != kRansScale) return false;
  uint32_t start = 0;
  for (size_t i = 0; i < freq.size(); ++i) {
    const uint32_t tag = tags ? tags[i] & 3u : 0u;
    for (uint32_t k = 0; k < freq[i]; ++k) {
      slots[start + k] = MakeSlot(freq[i], k, static_cast<uint32_t>(i), tag);
    }
    start += freq[i];
  }
  return true;
}

std::string RansEncoder::Finish() const {
  uint32_t x[2] = {kRansLow, kRansLow};
  std::vector<uint16_t> words;  // in emission order; the decoder reads them reversed
  words.reserve(syms_.size() / 2 + 4);
  for (size_t i = syms_.size(); i-- > 0;) {
    const Sym& s = syms_[i];
    uint32_t& st = x[s.lane];
    const uint64_t x_max = static_cast<uint64_t>((kRansLow >> kRansScaleBits) << 16) * s.freq;
    if (st >= x_max) {
      words.push_back(static_cast<uint16_t>(st & 0xffff));
      st >>= 16;
    }
    st = ((st / s.freq) << kRansScaleBits) + (st % s.freq) + s.start;
  }
  words.push_back(static_cast<uint16_t>(x[1] & 0xffff));
  words.push_back(static_cast<uint16_t>(x[1] >> 16));
  words.push_back(static_cast<uint16_t>(x[0] & 0xffff));
  words.push_back(static_cast<uint16_t>(x[0] >> 16));
  std::string out;
  out.reserve(2 * words.size());
  for (size_t i = words.size(); i-- > 0;) {
    out.push_back(static_cast<char>(words[i] & 0xff));
    out.push_back(static_cast<char>(words[i] >> 8));
  }
  return out;
}

void BitWriter::Put(uint64_t v, int count) {
  if (count == 0) return;
  acc_ |= (v & ((uint64_t{1} << count) - 1)) << n_;
  n_ += count;
  while (n_ >= 8) {
    out_.push_back(static_cast<char>(acc_ & 0xff));
    acc_ >>= 8;
    n_ -= 8;
  }
}

std::string BitWriter::Finish() const {
  std::string out = out_;
  if (n_ > 0) out.push_back(static_cast<char>(acc_ & 0xff));
  return out;
}

}  // namespace sculpt::skin::internal
