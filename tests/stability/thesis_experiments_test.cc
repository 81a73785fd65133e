/// @brief Reproduces the thesis's 2D local-carve and volume-compensation experiments (seed 000
/// §3.2, §3.3; testable claims 8-13 and the upwind fix of claims 21-22) through the production
/// kernels.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "sculpt/levelset/kernels.h"
#include "sculpt/levelset/thesis_repro.h"

namespace sculpt::levelset::thesis {
namespace {

CarveResult Carve(const Shape2D& tool, double dt, int reinit_every = 0) {
  CarveSetup setup;
  setup.tool = tool;
  setup.dt = dt;
  setup.reinit_every = reinit_every;
  return RunLocalCarve(setup);
}

CompensationResult Compensate(CompensationForm form, double dt, int max_passes) {
  CompensationSetup setup;
  setup.form = form;
  setup.dt = dt;
  setup.max_passes = max_passes;
  return RunCompensation(setup);
}

std::string History(const CompensationResult& r) {
  std::string s;
  for (double d : r.dif_history) s += std::to_string(d) + " ";
  return s;
}

// The setup itself (seed 000 §3 "Common setup", §9 errata 10-11): 201x201 nodes, h = 0.5, the
// circle r = 18 holds 1013.25 area units pointwise, 932.5 of them outside the circle tool (REPRO
// of §3.3), and the tools have the sample counts of App. A.1.
TEST(ThesisExperiments, SetupMatchesTheDigestRepro) {
  const GridSpec grid;
  EXPECT_EQ(grid.nodes(), 201);
  EXPECT_DOUBLE_EQ(grid.h(), 0.5);
  const DenseField phi = MaterialField(ThesisMaterial(), grid);
  EXPECT_DOUBLE_EQ(PointwiseArea(phi, grid.h()), 1013.25);
  const std::vector<uint8_t> gamma = ToolMask(ThesisCircleTool(), grid);
  EXPECT_DOUBLE_EQ(PointwiseAreaOutside(phi, gamma, grid.h()), 932.5);
  EXPECT_DOUBLE_EQ(PointwiseAreaInside(phi, gamma, grid.h()), 80.75);
  EXPECT_EQ(ToolSamples(ThesisCircleTool(), 50).size(), 51u);
  EXPECT_EQ(ToolSamples(ThesisSquareTool(), 50).size(), 52u);
  // Bilinear interpolation (eq. 3.1) is exact for the plane phi = x - 2y.
  DenseField plane = grid.MakeField(0.0f);
  for (int j = 0; j < grid.nodes(); ++j) {
    for (int i = 0; i < grid.nodes(); ++i) plane.at(i, j, 0) = static_cast<float>(i - 2.0 * j);
  }
  EXPECT_NEAR(Bilinear(plane, grid, 10.3, 20.85), (10.3 - 2 * 20.85) / grid.h(), 1e-4);
}

// Claim 8 (seed 000 §3.2 Figs. 6.13/6.16/6.19, §7): the circle tool (r = 9 at (65,63)) carves the
// circle material at v = 7 with central differences and forward Euler until no tool sample has
// phi <= 0, in 4 / 13 / 97 iterations at dt = 1 / 0.1 / 0.01 (the thesis counts the final pass;
// the digest's REPRO, which does not, gets 3 / 12 / 96).
TEST(ThesisExperiments, CircleToolIterationCounts) {
  const double dts[] = {1.0, 0.1, 0.01};
  const int thesis[] = {4, 13, 97};
  for (int n = 0; n < 3; ++n) {
    const CarveResult r = Carve(ThesisCircleTool(), dts[n]);
    SCOPED_TRACE(testing::Message() << "dt=" << dts[n]);
    EXPECT_FALSE(r.hit_pass_limit);
    EXPECT_NEAR(r.thesis_iterations, thesis[n], 1);
    EXPECT_EQ(r.updates, r.thesis_iterations - 1);
  }
}

// Claim 9 (seed 000 §3.2 Figs. 6.22/6.25/6.28, §5 item 9): the square tool (half-side 9, the
// digest's half-size reading, §9 erratum 11) stops after 3 / 7 / 55 iterations, and because only
// the tool's boundary samples are checked, a disconnected island of material stays inside the
// tool footprint at dt = 0.1 and 0.01 (REPRO: 32.75 / 35.5 area units), not at dt = 1.
TEST(ThesisExperiments, SquareToolIterationCountsAndIsland) {
  const double dts[] = {1.0, 0.1, 0.01};
  const int thesis[] = {3, 7, 55};
  for (int n = 0; n < 3; ++n) {
    const CarveResult r = Carve(ThesisSquareTool(), dts[n]);
    SCOPED_TRACE(testing::Message() << "dt=" << dts[n]);
    EXPECT_FALSE(r.hit_pass_limit);
    EXPECT_NEAR(r.thesis_iterations, thesis[n], 1);
    if (n == 0) {
      EXPECT_TRUE(r.tool_region_cleared);
      EXPECT_EQ(r.area_stranded, 0.0);
    } else {
      EXPECT_FALSE(r.tool_region_cleared);
      EXPECT_GT(r.area_stranded, 20.0);
      // All of it is cut off from the material outside the tool: a true island.
      EXPECT_EQ(r.island_area, r.area_stranded);
    }
  }
}

// Claim 10 (seed 000 §3.2 REPRO, §7): the circle carve removes 80.75 of the 1013.25 pointwise area
// units whatever dt (exactly the material inside Gamma: nodes outside Gamma never move); the square
// carve at dt = 1 removes 106.75.
TEST(ThesisExperiments, CarveRemovedArea) {
  for (double dt : {1.0, 0.1, 0.01}) {
    const CarveResult r = Carve(ThesisCircleTool(), dt);
    SCOPED_TRACE(testing::Message() << "dt=" << dt);
    EXPECT_DOUBLE_EQ(r.initial_area, 1013.25);
    EXPECT_NEAR(r.area_removed, 80.75, 1.0);
    EXPECT_TRUE(r.tool_region_cleared);
  }
  EXPECT_NEAR(Carve(ThesisSquareTool(), 1.0).area_removed, 106.75, 1.5);
}

// Claim 11 (seed 000 §3.2 Figs. 6.14/6.17/6.20, 6.23/6.26/6.29, §9 erratum 6): reinitialisation
// (`reinit_SD(ph,h,h,0.9,'WENO',1)`, one step with the toolbox's adaptive pseudo-step, see
// ReinitSdCfl) leaves the circle carve practically unchanged: 4 / 13 / 97 iterations with reinit
// every 1 / 2 / 10 passes and 4 / 6 / 9 reinits (floor(iterations / frequency)). With the square
// tool the stranded remnant survives reinitialisation, as the thesis says ("with or without
// reinit"): at dt = 0.1 (reinit every 2) it is a true island (22 units); at dt = 0.01 (reinit
// every 5) the 27-29 units left in the footprint are an island or hang on to the rest through a
// single node at the tool's left edge, depending on the WENO details of the reinit, so only the
// stranded area is asserted. The thesis's 3 / 8 / 71 iterations become 3 / 8 / 64-65 here: the
// last is only asserted to exceed the no-reinit 55, as the thesis's does.
TEST(ThesisExperiments, CarveWithReinitIsPracticallyUnchanged) {
  const double dts[] = {1.0, 0.1, 0.01};
  const int circle_every[] = {1, 2, 10};
  const int circle_iterations[] = {4, 13, 97};
  const int circle_reinits[] = {4, 6, 9};
  for (int n = 0; n < 3; ++n) {
    const CarveResult r = Carve(ThesisCircleTool(), dts[n], circle_every[n]);
    SCOPED_TRACE(testing::Message() << "circle dt=" << dts[n]);
    EXPECT_FALSE(r.hit_pass_limit);
    EXPECT_NEAR(r.thesis_iterations, circle_iterations[n], 1);
    EXPECT_EQ(r.reinits, r.thesis_iterations / circle_every[n]);
    EXPECT_NEAR(r.reinits, circle_reinits[n], 1);
    EXPECT_NEAR(r.area_removed, 80.75, 1.0);
    EXPECT_TRUE(r.tool_region_cleared);
  }
  const int square_every[] = {1, 2, 5};
  for (int n = 0; n < 3; ++n) {
    const CarveResult r = Carve(ThesisSquareTool(), dts[n], square_every[n]);
    SCOPED_TRACE(testing::Message() << "square dt=" << dts[n]);
    EXPECT_FALSE(r.hit_pass_limit);
    EXPECT_EQ(r.reinits, r.thesis_iterations / square_every[n]);
    if (n == 0) {
      EXPECT_EQ(r.thesis_iterations, 3);
      EXPECT_NEAR(r.area_removed, 106.75, 1.5);
    } else {
      EXPECT_GT(r.area_stranded, 20.0);
    }
    if (n == 1) {
      EXPECT_NEAR(r.thesis_iterations, 8, 1);
      EXPECT_GT(r.island_area, 20.0);
    }
    if (n == 2) {
      EXPECT_GT(r.thesis_iterations, 55);
    }
  }
}

// Claim 12 (seed 000 §3.3 Fig. 6.33, §7): compensation with the delta_eps form (eps = 1.5 h),
// dt = 1, no reinit, on the uncarved circle with the circle tool: |Vol_{Gamma^c} - c| stalls at 2
// (the thesis stopped after 12 iterations; REPRO: -80.75, -7, -5.5, -5.5, then -2.0 for ever).
TEST(ThesisExperiments, DeltaCompensationStallsAtTwo) {
  const CompensationResult r = Compensate(CompensationForm::kDelta, 1.0, 25);
  SCOPED_TRACE(History(r));
  EXPECT_FALSE(r.diverged);
  EXPECT_FALSE(r.converged);
  EXPECT_EQ(r.passes, 25);
  EXPECT_DOUBLE_EQ(r.dif_history.front(), -80.75);
  EXPECT_NEAR(r.final_abs_dif, 2.0, 0.5);
  EXPECT_TRUE(r.stalled);
  // Already at the stall value by the thesis's 12th iteration.
  EXPECT_EQ(r.dif_history[11], r.final_dif);
}

// Claim 13 (seed 000 §3.3 Figs. 6.42/6.43, §5 item 6, §7): the |grad phi| form (5.8) is unstable
// at dt = 1 and dt = 0.1 (REPRO: blows up within 3-4 iterations) and stable at dt = 0.01 with a
// final |error| of 0.5 (REPRO: dif oscillates -0.5, -0.5, +1.0, so the bound is 1.0).
TEST(ThesisExperiments, GradientCompensationStabilityDependsOnDt) {
  for (double dt : {1.0, 0.1}) {
    const CompensationResult r = Compensate(CompensationForm::kGradient, dt, 25);
    SCOPED_TRACE(testing::Message() << "dt=" << dt << ": " << History(r));
    EXPECT_TRUE(r.diverged);
    EXPECT_LE(r.passes, 10);
  }
  const CompensationResult r = Compensate(CompensationForm::kGradient, 0.01, 25);
  SCOPED_TRACE(History(r));
  EXPECT_FALSE(r.diverged);
  EXPECT_LE(r.final_abs_dif, 1.0);
  EXPECT_LE(*std::max_element(r.tail_abs_dif.begin(), r.tail_abs_dif.end()), 1.0);
  EXPECT_TRUE(r.oscillating);
}

// The project's fix (seed 000 §7 claims 21-22, §5 items 6-7): with first-order upwind in space,
// forward Euler in time and dt chosen so the standard CFL number dt * max|F| / h is below 1, the
// |grad phi| compensation does not diverge. In this loop the normal speed is F = -dif, so the
// "v" of the CFL number is the largest |dif|, the first one (80.75); dt = 0.9 h / 80.75 ~ 0.0056.
// Here the CFL bound is also below the volume-controller bound dt * L < 2 (L ~ 100 the perimeter
// outside the tool, seed 000 §3.3 INFERENCE); at CFL 16 (dt = 0.1) upwind diverges like central.
TEST(ThesisExperiments, UpwindGradientCompensationUnderCflDoesNotDiverge) {
  const GridSpec grid;
  const DenseField phi = MaterialField(ThesisMaterial(), grid);
  const std::vector<uint8_t> gamma = ToolMask(ThesisCircleTool(), grid);
  const double dif0 = PointwiseAreaOutside(phi, gamma, grid.h()) - PointwiseArea(phi, grid.h());
  const double dt = MaxStableStep(std::fabs(dif0), grid.h(), 0.9);
  ASSERT_LT(dt * std::fabs(dif0) / grid.h(), 1.0);

  CompensationSetup setup;
  setup.form = CompensationForm::kGradient;
  setup.motion = MotionSettings{SpatialScheme::kUpwind, TemporalScheme::kRk1, Boundary::kClamp};
  setup.dt = dt;
  setup.max_passes = 60;
  const CompensationResult r = RunCompensation(setup);
  SCOPED_TRACE(History(r));
  EXPECT_FALSE(r.diverged);
  // |dif| never grows past its first value, so the CFL number stays below 1 on every step.
  for (double d : r.dif_history) EXPECT_LE(std::fabs(d), std::fabs(dif0));
  EXPECT_LE(r.final_abs_dif, 1.0);

  setup.dt = 0.1;
  setup.max_passes = 25;
  EXPECT_TRUE(RunCompensation(setup).diverged);
}

}  // namespace
}  // namespace sculpt::levelset::thesis
