/// @brief SurfaceWalk: a seeded random walk of a tool over a sphere's surface, for simulated
/// sculptors.
#ifndef SCULPT_CLIENT_LOADGEN_SURFACE_WALK_H_
#define SCULPT_CLIENT_LOADGEN_SURFACE_WALK_H_

#include <cstdint>
#include <random>

#include "sculpt/core/vec3.h"

namespace sculpt::client {

/// Moves along great circles of a sphere at a fixed speed, turning by a random angle each step
/// (Gaussian, seeded), and yields the point `depth` inside the surface under the tool.
/// Thread safety: none; one walk per sculptor.
class SurfaceWalk {
 public:
  /// `radius` and `depth` in world units, `speed` in world units per second along the surface,
  /// `turn_rate` the standard deviation of the heading change in radians per sqrt(second).
  SurfaceWalk(uint64_t seed, Vec3 center, double radius, double depth, double speed,
              double turn_rate = 2.0);

  /// Advances by `dt` seconds and returns the new tool position.
  Vec3 Next(double dt);
  /// The tool position now.
  Vec3 Position() const;

 private:
  Vec3 center_;
  double radius_;
  double depth_;
  double speed_;
  double turn_rate_;
  Vec3 dir_;      // unit vector from the centre to the surface point under the tool
  Vec3 heading_;  // unit tangent the tool moves along
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
};

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_LOADGEN_SURFACE_WALK_H_
