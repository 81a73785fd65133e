#include "sculpt/skin/contour_codec.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

namespace sculpt::skin {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

double MaxError(const Polyline2& a, const Polyline2& b) {
  double e = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    e = std::max({e, std::abs(a[i].x - b[i].x), std::abs(a[i].y - b[i].y)});
  }
  return e;
}

std::vector<OrientedBall> Wavy(int n) {
  std::vector<OrientedBall> balls;
  for (int i = 0; i < n; ++i) {
    balls.push_back({{2.5 * i, 0.8 * std::sin(0.7 * i)}, 0.6 + 0.3 * std::cos(1.3 * i),
                     20 * kDeg * std::cos(0.7 * i)});
  }
  return balls;
}

TEST(ContourCodecTest, PolylineSetRoundTripsWithinHalfStep) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n(0, 1);
  std::vector<Polyline2> lines(3);
  for (int i = 0; i < 500; ++i) lines[0].push_back({std::cos(i * 0.01) * 7, std::sin(i * 0.01) * 7});
  for (int i = 0; i < 50; ++i) lines[1].push_back({1e6 + n(rng), -1e6 + n(rng)});  // noisy, far
  // lines[2] empty
  const double step = 1e-4;
  auto bytes = EncodeContours(lines, step);
  ASSERT_TRUE(bytes.ok()) << bytes.status();
  auto back = DecodeContours(*bytes);
  ASSERT_TRUE(back.ok()) << back.status();
  ASSERT_EQ(back->size(), 3u);
  for (int i = 0; i < 3; ++i) {
    ASSERT_EQ((*back)[i].size(), lines[i].size());
    EXPECT_LE(MaxError(lines[i], (*back)[i]), step / 2 * (1 + 1e-9));
  }
  // The smooth arc costs far less than float32 xy.
  auto arc = EncodeContours({lines[0]}, step);
  EXPECT_LT(arc->size(), 500 * 8 / 4);
}

TEST(ContourCodecTest, RejectsBadStepAndPoints) {
  EXPECT_NE(EncodeContours({{{0, 0}}}, 0).status().message().find("step=0 outside"),
            std::string::npos);
  EXPECT_FALSE(EncodeContours({{{0, 0}}}, std::nan("")).ok());
  const auto s = EncodeContours({{{0, 0}, {std::nan(""), 1}}}, 1e-3).status();
  EXPECT_NE(s.message().find("polylines[0][1]"), std::string::npos) << s;
  EXPECT_FALSE(EncodeContours({{{1e10, 0}}}, 1e-9).ok());  // 1e19 steps
}

TEST(ContourCodecTest, RejectsTruncatedAndCorruptInput) {
  std::vector<Polyline2> lines(1);
  for (int i = 0; i < 200; ++i) lines[0].push_back({i * 0.1, std::sin(i * 0.1)});
  const std::string bytes = *EncodeContours(lines, 1e-3);
  for (size_t cut = 0; cut < bytes.size(); cut += 7) {
    EXPECT_FALSE(DecodeContours(bytes.substr(0, cut)).ok()) << cut;
  }
  std::string bad = bytes;
  bad[0] = 'X';
  EXPECT_FALSE(DecodeContours(bad).ok());
  EXPECT_FALSE(DecodeContours(bytes + "z").ok());
  // A huge point count is refused before anything is allocated.
  std::string huge(bytes.substr(0, 14));
  huge += std::string("\x01\xff\xff\xff\xff\x0f", 6);
  EXPECT_FALSE(DecodeContours(huge).ok());
}

// Random bytes never crash the decoder.
TEST(ContourCodecTest, SurvivesFuzzedInput) {
  std::vector<Polyline2> lines(2);
  for (int i = 0; i < 100; ++i) lines[i % 2].push_back({i * 0.1, std::cos(i * 0.1)});
  const std::string bytes = *EncodeContours(lines, 1e-3);
  std::mt19937_64 rng(11);
  int decoded = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    std::string b = bytes;
    const int flips = 1 + static_cast<int>(rng() % 4);
    for (int f = 0; f < flips; ++f) b[13 + rng() % (b.size() - 13)] = static_cast<char>(rng());
    decoded += DecodeContours(b).ok();
  }
  EXPECT_LT(decoded, 2000);
}

TEST(ContourCodecTest, SnapshotAndUpdatesReproduceTheSkin) {
  auto skin = Skin::Build(Wavy(12));
  ASSERT_TRUE(skin.ok()) << skin.status();
  const double step = skin->chord_tolerance();
  ContourView view;
  const auto snap = EncodeSkinSnapshot(*skin);
  ASSERT_TRUE(snap.ok()) << snap.status();
  ASSERT_TRUE(view.Apply(*snap).ok());
  auto check = [&] {
    ASSERT_EQ(view.sections().size(), skin->sections().size());
    for (size_t k = 0; k < skin->sections().size(); ++k) {
      EXPECT_EQ(view.sections()[k].id, skin->section(k).id);
      EXPECT_EQ(view.sections()[k].version, skin->section(k).version);
      ASSERT_EQ(view.sections()[k].plus.size(), skin->section(k).plus.size());
      EXPECT_LE(MaxError(view.sections()[k].plus, skin->section(k).plus), step / 2 * 1.000001);
      EXPECT_LE(MaxError(view.sections()[k].minus, skin->section(k).minus), step / 2 * 1.000001);
    }
  };
  check();
  // Move a ball: the update carries its two sections only, and is much smaller.
  OrientedBall b = skin->balls()[5];
  b.c.y += 0.2;
  auto change = skin->SetBall(5, b);
  ASSERT_TRUE(change.ok());
  auto upd = EncodeSkinUpdate(*skin, *change);
  ASSERT_TRUE(upd.ok());
  EXPECT_LT(upd->size() * 3, snap->size());
  ASSERT_TRUE(view.Apply(*upd).ok());
  check();
  // Insert and remove splice the view.
  auto ins = skin->InsertBall(3, {{6.2, 1.4}, 0.4, 0});
  ASSERT_TRUE(ins.ok()) << ins.status();
  ASSERT_TRUE(view.Apply(*EncodeSkinUpdate(*skin, *ins)).ok());
  check();
  auto rem = skin->RemoveBall(0);
  ASSERT_TRUE(rem.ok());
  ASSERT_TRUE(view.Apply(*EncodeSkinUpdate(*skin, *rem)).ok());
  check();
  EXPECT_EQ(view.Chain(1).size(), skin->Chain(1).size());
  // An update that does not fit the view is refused and leaves it unchanged.
  ContourView empty;
  EXPECT_FALSE(empty.Apply(*EncodeSkinUpdate(*skin, *change)).ok());
  EXPECT_TRUE(empty.sections().empty());
  EXPECT_FALSE(EncodeSkinSnapshot(*skin, 2 * step).ok());  // step above the chord tolerance
}


// Found by tests/fuzz (contour target): a point count near 2^64 wrapped the running total past
// the cap, and the decoder then tried to allocate that many points (std::length_error).
TEST(ContourCodecTest, RejectsPointCountThatWrapsTheTotal) {
  const std::string bytes(
      "\x53\x4b\x43\x31\x01\x5b\x01\x4b\x43\x31\x00\x00\x00\x00\x02\x53\x4b\x43\x00\x00\x43\x00"
      "\x00\xff\xff\xff\xff\xff\xff\xff\xff\xff\x43\x31\x31\x01\x5b\x01\x4b\x43\x31\x43\x04\x00"
      "\x00\x00\xff\xff",
      48);
  const auto decoded = DecodeContours(bytes);
  EXPECT_FALSE(decoded.ok());
}

}  // namespace
}  // namespace sculpt::skin
