/// @brief SurfaceWalk: great-circle steps with a Gaussian random turn.
#include "loadgen/surface_walk.h"

#include <cmath>

namespace sculpt::client {
namespace {

Vec3 Normalized(const Vec3& v) {
  const double n = v.Length();
  return n > 0 ? v / n : Vec3{1, 0, 0};
}

// Any unit vector perpendicular to `d`.
Vec3 Perpendicular(const Vec3& d) {
  const Vec3 axis = std::abs(d.x) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
  return Normalized(d.Cross(axis));
}

}  // namespace

SurfaceWalk::SurfaceWalk(uint64_t seed, Vec3 center, double radius, double depth, double speed,
                         double turn_rate)
    : center_(center),
      radius_(radius),
      depth_(depth),
      speed_(speed),
      turn_rate_(turn_rate),
      rng_(seed) {
  dir_ = Normalized({normal_(rng_), normal_(rng_), normal_(rng_)});
  const Vec3 t = Perpendicular(dir_);
  const double a = std::uniform_real_distribution<double>(0, 2 * M_PI)(rng_);
  heading_ = Normalized(t * std::cos(a) + dir_.Cross(t) * std::sin(a));
}

Vec3 SurfaceWalk::Next(double dt) {
  // Great-circle step: rotate dir and heading together in their plane.
  const double angle = speed_ * dt / radius_;
  const Vec3 d = dir_ * std::cos(angle) + heading_ * std::sin(angle);
  const Vec3 h = heading_ * std::cos(angle) - dir_ * std::sin(angle);
  dir_ = Normalized(d);
  // Random turn about dir; re-orthogonalise so rounding does not lift the heading off the
  // tangent plane over thousands of steps.
  const double turn = turn_rate_ * std::sqrt(std::max(dt, 0.0)) * normal_(rng_);
  const Vec3 side = dir_.Cross(h);
  Vec3 turned = h * std::cos(turn) + side * std::sin(turn);
  turned = turned - dir_ * turned.Dot(dir_);
  heading_ = turned.Length() > 1e-9 ? Normalized(turned) : Perpendicular(dir_);
  return Position();
}

Vec3 SurfaceWalk::Position() const { return center_ + dir_ * (radius_ - depth_); }

}  // namespace sculpt::client
