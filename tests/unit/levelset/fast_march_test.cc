#include "sculpt/levelset/fast_march.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace sculpt::levelset {
namespace {

// A plane z = 3.25 (voxel units, dx = 0.5): the samples next to it are known, the rest free.
DenseField Plane(std::vector<MarchState>* state) {
  DenseField f({0, 0, 0}, {6, 5, 12}, 0.f);
  state->assign(f.size(), MarchState::kFree);
  for (int k = 0; k < 12; ++k) {
    for (int j = 0; j < 5; ++j) {
      for (int i = 0; i < 6; ++i) {
        const double d = 0.5 * (k - 3.25);
        const size_t idx = f.Index(i, j, k);
        // Free voxels carry only their sign; the march fills in the distance.
        f.data()[idx] = static_cast<float>(k == 3 || k == 4 ? d : (d < 0 ? -1e-3 : 1e-3));
        if (k == 3 || k == 4) (*state)[idx] = MarchState::kKnown;
      }
    }
  }
  return f;
}

TEST(FastMarchTest, MarchesAPlaneToItsExactDistances) {
  std::vector<MarchState> state;
  DenseField f = Plane(&state);
  const size_t computed = MarchDistance(f, state, 0.5, 100.0);
  EXPECT_EQ(computed, f.size() - 2 * 6 * 5);
  for (int k = 0; k < 12; ++k) {
    EXPECT_NEAR(f.at(2, 2, k), 0.5 * (k - 3.25), 1e-5) << k;
  }
  for (MarchState s : state) EXPECT_EQ(s, MarchState::kKnown);
}

TEST(FastMarchTest, VoxelsBeyondTheLimitTakeTheLimitWithTheirSign) {
  std::vector<MarchState> state;
  DenseField f = Plane(&state);
  MarchDistance(f, state, 0.5, 1.0);
  EXPECT_FLOAT_EQ(f.at(0, 0, 0), -1.0f);
  EXPECT_FLOAT_EQ(f.at(0, 0, 11), 1.0f);
  EXPECT_NEAR(f.at(0, 0, 2), -0.625, 1e-5);
}

TEST(FastMarchTest, IgnoredVoxelsAreNeitherReadNorWritten) {
  std::vector<MarchState> state;
  DenseField f = Plane(&state);
  for (int j = 0; j < 5; ++j) {
    for (int i = 0; i < 6; ++i) state[f.Index(i, j, 6)] = MarchState::kIgnored;
  }
  f.at(1, 1, 6) = 7.f;
  MarchDistance(f, state, 0.5, 100.0);
  EXPECT_FLOAT_EQ(f.at(1, 1, 6), 7.f);
  // Cut off by the ignored layer, the voxels above it are not reached and take the limit.
  EXPECT_FLOAT_EQ(f.at(1, 1, 9), 100.f);
  EXPECT_NEAR(f.at(1, 1, 5), 0.875, 1e-5);
}

// A march told the box its free voxels lie in gives the whole-field march's values bit for bit,
// and leaves the voxels outside the box alone.
TEST(FastMarchTest, AMarchInABoxMatchesTheWholeFieldMarch) {
  std::vector<MarchState> whole_state, box_state;
  DenseField whole = Plane(&whole_state);
  DenseField boxed = Plane(&box_state);
  // Free voxels only in i, j in [1, 4), k in [0, 9); the rest known at their distance to the
  // plane, except one voxel holding a sentinel value, to show nothing writes it.
  for (int k = 0; k < 12; ++k) {
    for (int j = 0; j < 5; ++j) {
      for (int i = 0; i < 6; ++i) {
        if (i >= 1 && i < 4 && j >= 1 && j < 4 && k < 9) continue;
        const size_t idx = whole.Index(i, j, k);
        whole_state[idx] = box_state[idx] = MarchState::kKnown;
        const float d = i == 5 && j == 4 && k == 11 ? 1e-3f : static_cast<float>(0.5 * (k - 3.25));
        whole.data()[idx] = boxed.data()[idx] = d;
      }
    }
  }
  const size_t n_whole = MarchDistance(whole, whole_state, 0.5, 1.5);
  const size_t n_box = MarchDistance(boxed, box_state, 0.5, 1.5, Int3{1, 1, 0}, Int3{4, 4, 9});
  EXPECT_EQ(n_whole, 3u * 3 * 7);  // k = 3 and 4 are known
  EXPECT_EQ(n_box, n_whole);
  for (size_t idx = 0; idx < whole.size(); ++idx) {
    EXPECT_EQ(whole.data()[idx], boxed.data()[idx]) << idx;
    EXPECT_EQ(box_state[idx], MarchState::kKnown) << idx;
  }
  // The plane's distances inside, up to the limit (k = 0 is 1.625 from the plane).
  EXPECT_FLOAT_EQ(boxed.at(2, 2, 0), -1.5f);
  EXPECT_NEAR(boxed.at(2, 2, 6), 1.375, 1e-5);
  // Outside the box nothing was written.
  EXPECT_FLOAT_EQ(boxed.at(5, 4, 11), 1e-3f);
}

TEST(FastMarchTest, InterfaceDistanceKeepsAnAxisCrossingWhereItIs) {
  std::vector<MarchState> state;
  const DenseField f = Plane(&state);
  // The crossing lies a quarter voxel above sample k = 3: 0.125 below it, 0.375 above k = 4.
  EXPECT_NEAR(InterfaceDistance(f, 2, 2, 3, 0.5), -0.125, 1e-6);
  EXPECT_NEAR(InterfaceDistance(f, 2, 2, 4, 0.5), 0.375, 1e-6);
  // Without a sign change among its 6 neighbours a voxel keeps its value.
  EXPECT_FLOAT_EQ(static_cast<float>(InterfaceDistance(f, 2, 2, 8, 0.5)), f.at(2, 2, 8));
}

}  // namespace
}  // namespace sculpt::levelset
