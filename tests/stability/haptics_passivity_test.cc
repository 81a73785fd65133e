// Passivity (issue "Haptic rendering at 1 kHz", seed 000 §5 item 5): a tool dropped on a flat
// surface with the proxy model at the scene's stiffness, rendered at 1 kHz, comes to rest and
// its energy never grows.
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>

#include "sculpt/haptics/haptic_device.h"
#include "sculpt/haptics/haptic_renderer.h"
#include "sculpt/haptics/sculpture_snapshot.h"

namespace sculpt::haptics {
namespace {

TEST(HapticsPassivity, DroppedToolComesToRestWithoutGainingEnergy) {
  levelset::SculptureOptions o;
  o.voxel_size = 1.0;
  auto slab = levelset::Sculpture::MakeBox(o, {-30, -30, -20}, {30, 30, 0});
  ASSERT_TRUE(slab.ok());
  const std::shared_ptr<const SdfSampler> floor =
      std::make_shared<const SculptureSnapshot>(std::move(slab).value());

  HapticSettings s;  // the scene defaults: stiffness 1, damping 0.05, 1 kHz
  s.model = ForceModel::kProxy;
  s.tool_radius = 0;
  auto r = HapticRenderer::Create(s);
  ASSERT_TRUE(r.ok());
  SpringMassHand::Params p;
  p.mass = 0.05;
  p.gravity = {0, 0, -9.81};
  SpringMassHand hand(p, {0.3, -0.2, 1.0});  // let go 1 unit above the surface

  const double dt = 1.0 / s.rate_hz, g = 9.81;
  // Energy: kinetic + gravitational (zero at z = 0) + the proxy spring's.
  auto energy = [&](const TickOutput& out) {
    const Vec3 d = out.proxy - hand.position();
    const double spring = out.contact ? 0.5 * s.stiffness * d.LengthSqr() : 0.0;
    return 0.5 * p.mass * hand.velocity().LengthSqr() + p.mass * g * hand.position().z + spring;
  };
  const double e0 = p.mass * g * 1.0;
  double peak_after_contact = -1e300;
  double e_prev_window_max = e0;
  bool touched = false;
  const int ticks = 20000;  // 20 s of simulated time, 20k ticks
  double window_max = -1e300;
  for (int i = 0; i < ticks; ++i) {
    const double t = i * dt;
    const TickOutput& out = r->Tick(floor, hand.Read(t));
    hand.ApplyForce(out.force, t);
    const double e = energy(out);
    touched = touched || out.contact;
    // Never above the energy it was dropped with (a small allowance for the semi-implicit
    // integration of the hand).
    ASSERT_LE(e, e0 * 1.001) << "tick " << i;
    window_max = std::max(window_max, e);
    if ((i + 1) % 1000 == 0) {
      // The most energy held in each second never exceeds the previous second's.
      EXPECT_LE(window_max, e_prev_window_max + 1e-6 * e0) << "second " << (i + 1) / 1000;
      e_prev_window_max = window_max;
      window_max = -1e300;
    }
    if (touched) peak_after_contact = std::max(peak_after_contact, e);
  }
  EXPECT_TRUE(touched);
  // At rest: still, and sunk by m g / k into the spring.
  EXPECT_LT(hand.velocity().Length(), 1e-3);
  EXPECT_NEAR(hand.position().z, -p.mass * g / s.stiffness, 0.01);
  EXPECT_LE(peak_after_contact, e0 * 1.001);
}

}  // namespace
}  // namespace sculpt::haptics
