#include "skin/range_coder.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

namespace sculpt::skin::internal {
namespace {

TEST(RangeCoderTest, RoundTripsBitsRawBitsAndIntegers) {
  std::mt19937_64 rng(7);
  std::vector<int64_t> ints;
  for (int i = 0; i < 5000; ++i) {
    const int shift = static_cast<int>(rng() % 54);
    int64_t v = static_cast<int64_t>(rng() & ((1ull << shift) - 1) & kMaxCodedMagnitude);
    if (rng() & 1) v = -v;
    ints.push_back(i % 3 == 0 ? v : static_cast<int64_t>(rng() % 5) - 2);  // mostly small
  }
  ints.push_back(static_cast<int64_t>(kMaxCodedMagnitude));
  ints.push_back(-static_cast<int64_t>(kMaxCodedMagnitude));
  RangeEncoder enc;
  IntModel im[3];
  BitModel bm[2];
  for (size_t i = 0; i < ints.size(); ++i) {
    enc.Int(im[i % 3], ints[i]);
    enc.Bit(bm[i % 2], (i % 7) == 0);
    enc.Raw(i, static_cast<int>(i % 40));
  }
  const std::string bytes = enc.Finish();
  RangeDecoder dec(bytes);
  IntModel dm[3];
  BitModel db[2];
  for (size_t i = 0; i < ints.size(); ++i) {
    ASSERT_EQ(dec.Int(dm[i % 3]), ints[i]) << i;
    ASSERT_EQ(dec.Bit(db[i % 2]), (i % 7) == 0 ? 1 : 0) << i;
    ASSERT_EQ(dec.Raw(static_cast<int>(i % 40)), i & ((1ull << (i % 40)) - 1)) << i;
  }
  EXPECT_TRUE(dec.ok());
  EXPECT_EQ(dec.consumed(), bytes.size());
}

// A skewed source costs what its entropy says, within the adaptation's overhead.
TEST(RangeCoderTest, AdaptsToASkewedSource) {
  std::mt19937_64 rng(3);
  RangeEncoder enc;
  BitModel m;
  const int n = 100000;
  for (int i = 0; i < n; ++i) enc.Bit(m, rng() % 100 < 3);  // p(1) = 0.03: 0.194 bits each
  const std::string bytes = enc.Finish();
  EXPECT_LT(bytes.size() * 8.0 / n, 0.194 * 1.15);
  EXPECT_GT(bytes.size() * 8.0 / n, 0.194 * 0.9);
}

TEST(RangeCoderTest, CountsReadsPastTheEnd) {
  RangeEncoder enc;
  IntModel m;
  for (int i = 0; i < 100; ++i) enc.Int(m, i * 1000);
  const std::string bytes = enc.Finish();
  RangeDecoder dec(std::string_view(bytes).substr(0, bytes.size() / 2));
  IntModel dm;
  for (int i = 0; i < 100; ++i) dec.Int(dm);
  EXPECT_FALSE(dec.ok());
}

TEST(RangeCoderTest, RejectsANonZeroFirstByte) {
  const std::string bytes("\x01\x00\x00\x00\x00", 5);
  RangeDecoder dec(bytes);
  EXPECT_FALSE(dec.ok());
}

TEST(RangeCoderTest, RejectsEmptyAndShortInput) {
  for (const std::string_view bytes : {std::string_view(), std::string_view("\0\0\0", 3)}) {
    RangeDecoder dec(bytes);
    EXPECT_FALSE(dec.ok()) << bytes.size();
    EXPECT_EQ(dec.consumed(), bytes.size());
  }
}

// The decoder renormalises with one byte per decision (a probability stays in [31, 4065] of
// 4096, so a decision leaves at least 2^16 of a range of at least 2^24): the rarest bit at the
// most skewed probability, then raw bits, still decode.
TEST(RangeCoderTest, RoundTripsAtTheMostSkewedProbabilities) {
  RangeEncoder enc;
  BitModel m;
  std::vector<int> bits;
  for (int round = 0; round < 4; ++round) {
    for (int i = 0; i < 2000; ++i) bits.push_back(round % 2);
    bits.push_back(1 - round % 2);
  }
  uint16_t lo = m.p, hi = m.p;
  for (size_t i = 0; i < bits.size(); ++i) {
    lo = std::min(lo, m.p);
    hi = std::max(hi, m.p);
    enc.Bit(m, bits[i]);
    if (i % 500 == 0) enc.Raw(0x2aaaaaaaaaull, 38);
  }
  EXPECT_EQ(lo, 31);
  EXPECT_EQ(hi, 4065);
  const std::string bytes = enc.Finish();
  RangeDecoder dec(bytes);
  BitModel dm;
  for (size_t i = 0; i < bits.size(); ++i) {
    ASSERT_EQ(dec.Bit(dm), bits[i]) << i;
    if (i % 500 == 0) {
      ASSERT_EQ(dec.Raw(38), 0x2aaaaaaaaaull) << i;
    }
  }
  EXPECT_TRUE(dec.ok());
  EXPECT_EQ(dec.consumed(), bytes.size());
}

// Garbage never yields a magnitude beyond the cap nor reads outside the input.
TEST(RangeCoderTest, GarbageDecodesToBoundedValues) {
  std::mt19937_64 rng(9);
  for (int trial = 0; trial < 200; ++trial) {
    std::string bytes(1 + rng() % 64, '\0');
    for (char& c : bytes) c = static_cast<char>(rng());
    bytes[0] = 0;
    RangeDecoder dec(bytes);
    IntModel m;
    for (int i = 0; i < 50; ++i) {
      const int64_t v = dec.Int(m);
      ASSERT_LE(v < 0 ? -v : v, static_cast<int64_t>(kMaxCodedMagnitude));
    }
    EXPECT_LE(dec.consumed(), bytes.size());
  }
}

}  // namespace
}  // namespace sculpt::skin::internal
