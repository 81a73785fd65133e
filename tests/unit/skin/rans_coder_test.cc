#include "skin/rans_coder.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>
#include <vector>

namespace sculpt::skin::internal {
namespace {

/// Tables of `n` symbols with geometric-ish weights, as the contour codec's residuals have.
std::vector<uint32_t> Table(std::mt19937_64& rng, int n) {
  std::vector<uint64_t> counts(n);
  for (int i = 0; i < n; ++i) counts[i] = 1 + (rng() % 1000) / (1 + i);
  return NormaliseCounts(counts);
}

TEST(RansCoderTest, RoundTripsSymbolsOnTwoLanesThroughSeveralTables) {
  std::mt19937_64 rng(1);
  std::vector<std::vector<uint32_t>> freq{
      Table(rng, 3), Table(rng, 40), Table(rng, kRansAlphabet), {kRansScale}};
  std::vector<std::vector<uint32_t>> start(freq.size());
  std::vector<RansSlot> slots(freq.size() * kRansScale);
  for (size_t t = 0; t < freq.size(); ++t) {
    ASSERT_TRUE(BuildRansSlots(freq[t], &slots[t * kRansScale]));
    start[t].assign(freq[t].size() + 1, 0);
    for (size_t i = 0; i < freq[t].size(); ++i) start[t][i + 1] = start[t][i] + freq[t][i];
  }
  struct Put {
    size_t table;
    uint32_t symbol;
  };
  std::vector<Put> puts;
  RansEncoder enc;
  for (int i = 0; i < 20000; ++i) {
    const size_t t = rng() % freq.size();
    // Draw by frequency so the stream looks like the data the tables describe.
    const uint32_t slot = rng() % kRansScale;
    uint32_t s = 0;
    while (start[t][s + 1] <= slot) ++s;
    puts.push_back({t, s});
    enc.Put(freq[t][s], start[t][s], i & 1);
  }
  const std::string bytes = enc.Finish();
  RansDecoder dec(bytes);
  for (size_t i = 0; i < puts.size(); ++i) {
    ASSERT_EQ(dec.Decode(&slots[puts[i].table * kRansScale], static_cast<int>(i & 1)),
              puts[i].symbol)
        << i;
  }
  EXPECT_TRUE(dec.ok());
}

// The unguarded step (for where the words are known to be there) reads the same symbols and
// leaves the same state as the guarded one, and each slot carries its symbol's tag.
TEST(RansCoderTest, UncheckedDecodeAndTagsMatchTheCheckedOnes) {
  std::mt19937_64 rng(2);
  std::vector<std::vector<uint32_t>> freq{Table(rng, 5), Table(rng, kRansAlphabet)};
  std::vector<uint8_t> tags(kRansAlphabet);
  for (int s = 0; s < kRansAlphabet; ++s) tags[s] = static_cast<uint8_t>((s * 7) % 4);
  std::vector<RansSlot> slots(freq.size() * kRansScale);
  for (size_t t = 0; t < freq.size(); ++t) {
    ASSERT_TRUE(BuildRansSlots(freq[t], &slots[t * kRansScale], tags.data()));
  }
  std::vector<std::pair<size_t, uint32_t>> puts;
  RansEncoder enc;
  for (int i = 0; i < 5000; ++i) {
    const size_t t = rng() % freq.size();
    const uint32_t s = static_cast<uint32_t>(rng() % freq[t].size());
    uint32_t start = 0;
    for (uint32_t k = 0; k < s; ++k) start += freq[t][k];
    puts.push_back({t, s});
    enc.Put(freq[t][s], start, i & 1);
  }
  const std::string bytes = enc.Finish();
  RansDecoder checked(bytes), unchecked(bytes);
  // In runs of 40 symbols, as the contour codec decodes a line: unguarded where the stream holds
  // a word for each.
  constexpr size_t kRun = 40;
  size_t unguarded = 0;
  for (size_t run = 0; run < puts.size(); run += kRun) {
    const bool guard = unchecked.words_left() < kRun;
    for (size_t i = run; i < std::min(run + kRun, puts.size()); ++i) {
      const RansSlot* table = &slots[puts[i].first * kRansScale];
      const int lane = static_cast<int>(i & 1);
      const RansSlot a = checked.DecodeSlot(table, lane);
      const RansSlot b =
          guard ? unchecked.DecodeSlot(table, lane) : unchecked.DecodeSlotUnchecked(table, lane);
      unguarded += !guard;
      ASSERT_EQ(SlotSymbol(a), puts[i].second) << i;
      ASSERT_EQ(a, b) << i;
      ASSERT_EQ(SlotTag(a), tags[puts[i].second]) << i;
      ASSERT_EQ(checked.words_left(), unchecked.words_left()) << i;
    }
  }
  EXPECT_GT(unguarded, puts.size() * 9 / 10);
  EXPECT_TRUE(checked.ok());
  EXPECT_TRUE(unchecked.ok());
}

TEST(RansCoderTest, EmptyStreamHoldsOnlyTheStates) {
  const std::string bytes = RansEncoder().Finish();
  EXPECT_EQ(bytes.size(), 8u);
  EXPECT_TRUE(RansDecoder(bytes).ok());
  EXPECT_FALSE(RansDecoder(bytes.substr(0, 7)).ok());
  EXPECT_FALSE(RansDecoder(bytes + std::string(2, '\0')).ok());
}

TEST(RansCoderTest, RejectsTruncatedStreams) {
  std::mt19937_64 rng(2);
  const std::vector<uint32_t> freq = Table(rng, 20);
  std::vector<RansSlot> slots(kRansScale);
  ASSERT_TRUE(BuildRansSlots(freq, slots.data()));
  std::vector<uint32_t> start(freq.size() + 1, 0);
  for (size_t i = 0; i < freq.size(); ++i) start[i + 1] = start[i] + freq[i];
  RansEncoder enc;
  for (int i = 0; i < 500; ++i) {
    const uint32_t s = static_cast<uint32_t>(rng() % freq.size());
    enc.Put(freq[s], start[s], i & 1);
  }
  const std::string bytes = enc.Finish();
  for (size_t n = 0; n < bytes.size(); ++n) {
    RansDecoder dec(std::string_view(bytes).substr(0, n));
    for (int i = 0; i < 500; ++i) dec.Decode(slots.data(), i & 1);
    EXPECT_FALSE(dec.ok()) << n;
  }
}

TEST(RansCoderTest, GarbageDecodesToSymbolsOfTheTable) {
  std::mt19937_64 rng(3);
  const std::vector<uint32_t> freq = Table(rng, 30);
  std::vector<RansSlot> slots(2 * kRansScale);
  ASSERT_TRUE(BuildRansSlots(freq, slots.data()));
  ASSERT_TRUE(BuildRansSlots({}, slots.data() + kRansScale));  // an empty table
  for (int trial = 0; trial < 200; ++trial) {
    std::string bytes(rng() % 64, '\0');
    for (char& c : bytes) c = static_cast<char>(rng());
    RansDecoder dec(bytes);
    for (int i = 0; i < 200; ++i) {
      EXPECT_LT(dec.Decode(slots.data(), i & 1), freq.size());
      EXPECT_EQ(dec.Decode(slots.data() + kRansScale, i & 1), kRansNoSymbol);
    }
  }
}

TEST(RansCoderTest, NormalisedCountsSumToTheScale) {
  std::mt19937_64 rng(4);
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<uint64_t> counts(1 + rng() % kRansAlphabet);
    for (uint64_t& c : counts) {
      c = rng() % 3 == 0 ? 0 : rng() % 2 ? 1 : rng() % 1000000000;
    }
    const std::vector<uint32_t> f = NormaliseCounts(counts);
    uint32_t sum = 0;
    for (size_t i = 0; i < f.size(); ++i) {
      EXPECT_EQ(f[i] == 0, counts[i] == 0) << i;
      sum += f[i];
    }
    bool any = false;
    for (uint64_t c : counts) any = any || c > 0;
    EXPECT_EQ(sum, any ? kRansScale : 0u);
  }
}

TEST(RansCoderTest, RejectsTablesThatDoNotSumToTheScale) {
  std::vector<RansSlot> slots(kRansScale);
  EXPECT_FALSE(BuildRansSlots({kRansScale - 1}, slots.data()));
  EXPECT_FALSE(BuildRansSlots({kRansScale, 1}, slots.data()));
  EXPECT_FALSE(BuildRansSlots(std::vector<uint32_t>(kRansAlphabet + 1, 1), slots.data()));
  EXPECT_TRUE(BuildRansSlots({kRansScale / 2, kRansScale / 2}, slots.data()));
}

TEST(RansCoderTest, TokensRoundTripEveryMagnitude) {
  std::vector<int64_t> values{0, 1, -1, 7, -8, 8, 15, 16, -17, 1000, -123456};
  for (int b = 0; b <= 40; ++b) {
    values.push_back(int64_t{1} << b);
    values.push_back(-(int64_t{1} << b));
    values.push_back((int64_t{1} << b) - 1);
  }
  for (int64_t v : values) {
    const Token t = MakeToken(v);
    ASSERT_GE(t.symbol, 0);
    ASSERT_LT(t.symbol, kRansAlphabet) << v;
    EXPECT_EQ(t.extra_bits, TokenExtraBits(t.symbol));
    EXPECT_EQ(TokenValue(t.symbol, t.extra), v);
  }
}

TEST(RansCoderTest, RawBitsRoundTripAndEndExactly) {
  std::mt19937_64 rng(5);
  BitWriter w;
  std::vector<std::pair<uint64_t, int>> puts;
  for (int i = 0; i < 1000; ++i) {
    const int n = static_cast<int>(rng() % 41);
    const uint64_t v = n ? rng() & ((uint64_t{1} << n) - 1) : 0;
    puts.push_back({v, n});
    w.Put(v, n);
  }
  const std::string bytes = w.Finish();
  BitReader r(bytes);
  for (const auto& [v, n] : puts) ASSERT_EQ(r.Get(n), v);
  EXPECT_TRUE(r.ok());
  BitReader shorter(std::string_view(bytes).substr(0, bytes.size() - 1));
  for (const auto& [v, n] : puts) shorter.Get(n);
  EXPECT_FALSE(shorter.ok());
  const std::string padded = bytes + '\0';  // the reader keeps a view: the bytes must outlive it
  BitReader longer(padded);
  for (const auto& [v, n] : puts) longer.Get(n);
  EXPECT_FALSE(longer.ok());
}

// Get2 (the contour decoder's read of a point's two symbols' raw bits) reads what two Gets read
// and ends alike: the same values past the end (zeros), the same ok() for a stream cut short by
// each of its last bytes, exactly as long, and with a byte too many; pairs of every size, from
// two direct symbols (0 + 0 bits) to pairs past one refill (41 + 41).
TEST(RansCoderTest, PairedRawReadsMatchTwoReads) {
  std::mt19937_64 rng(17);
  BitWriter w;
  std::vector<std::pair<int, int>> counts;
  for (int i = 0; i < 4000; ++i) {
    // Mostly short (as the codec's: most symbols are direct), some up to the token's 41 bits.
    const int c1 = rng() % 4 == 0 ? static_cast<int>(rng() % 42) : static_cast<int>(rng() % 4);
    const int c2 = rng() % 4 == 0 ? static_cast<int>(rng() % 42) : static_cast<int>(rng() % 4);
    counts.push_back({c1, c2});
    w.Put(c1 ? rng() & ((uint64_t{1} << c1) - 1) : 0, c1);
    w.Put(c2 ? rng() & ((uint64_t{1} << c2) - 1) : 0, c2);
  }
  const std::string bytes = w.Finish();
  auto mask = [](int c) { return (uint64_t{1} << c) - 1; };
  int compared = 0;
  for (size_t cut : {bytes.size() + 1, bytes.size(), bytes.size() - 1, bytes.size() - 7,
                     bytes.size() / 2, size_t{0}}) {
    std::string in = bytes.substr(0, std::min(cut, bytes.size()));
    if (cut > bytes.size()) in += '\0';
    BitReader one(in), two(in);
    for (const auto& [c1, c2] : counts) {
      uint64_t v1 = 0, v2 = 0;
      two.Get2(c1, mask(c1), c2, mask(c2), &v1, &v2);
      ASSERT_EQ(v1, one.Get(c1)) << cut;
      ASSERT_EQ(v2, one.Get(c2)) << cut;
      ++compared;
    }
    EXPECT_EQ(two.ok(), one.ok()) << cut;
    EXPECT_EQ(two.ok(), cut == bytes.size()) << cut;
  }
  EXPECT_EQ(compared, 6 * 4000);
}

}  // namespace
}  // namespace sculpt::skin::internal
