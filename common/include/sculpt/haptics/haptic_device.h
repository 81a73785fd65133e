/// @brief HapticDevice: where the haptic loop reads the tool's pose and sends the force, and the
/// simulated devices that stand in for hardware (scripted, recorded, a spring-mass hand).
#ifndef SCULPT_HAPTICS_HAPTIC_DEVICE_H_
#define SCULPT_HAPTICS_HAPTIC_DEVICE_H_

#include <functional>
#include <string>
#include <vector>

#include "sculpt/core/status.h"
#include "sculpt/core/vec3.h"
#include "sculpt/haptics/haptic_renderer.h"

namespace sculpt::haptics {

/// A force-feedback device. The loop calls Read then ApplyForce once per tick with the loop's
/// time in seconds since it started.
/// Thread safety: called from the haptic loop's thread only.
class HapticDevice {
 public:
  virtual ~HapticDevice() = default;
  /// The pose at loop time t. A device may return a non-finite position (a dropout); the loop
  /// counts it and holds the force.
  virtual DeviceSample Read(double t) = 0;
  /// The force to render until the next call.
  virtual void ApplyForce(const Vec3& force, double t) = 0;
};

/// Follows a function of time; records the last force it was sent.
class ScriptedDevice : public HapticDevice {
 public:
  explicit ScriptedDevice(std::function<Vec3(double)> path) : path_(std::move(path)) {}
  DeviceSample Read(double t) override { return DeviceSample{t, path_(t), {}}; }
  void ApplyForce(const Vec3& force, double) override { last_force_ = force; }
  const Vec3& last_force() const { return last_force_; }

 private:
  std::function<Vec3(double)> path_;
  Vec3 last_force_;
};

/// Plays a recorded trajectory back, linearly interpolated between samples and held at either
/// end; "nan" coordinates in a recording replay as dropouts. Records the forces it is sent.
class RecordedDevice : public HapticDevice {
 public:
  struct Point {
    double t;
    Vec3 position;
  };
  /// Times must be finite and strictly increasing, with at least one point; InvalidArgument
  /// naming the index and value otherwise.
  static StatusOr<RecordedDevice> FromPoints(std::vector<Point> points);
  /// A text file of lines "t x y z" (seconds, world units); blank lines and lines starting with
  /// '#' are skipped. NotFound if it cannot be opened, InvalidArgument naming the line for a
  /// malformed one.
  static StatusOr<RecordedDevice> Load(const std::string& path);
  /// Writes points in the format Load reads.
  static Status Save(const std::string& path, const std::vector<Point>& points);

  DeviceSample Read(double t) override;
  void ApplyForce(const Vec3& force, double t) override { forces_.push_back({t, force}); }
  const std::vector<Point>& points() const { return points_; }
  /// Every force sent, with its time (Point::position holds the force).
  const std::vector<Point>& forces() const { return forces_; }

 private:
  explicit RecordedDevice(std::vector<Point> points) : points_(std::move(points)) {}
  std::vector<Point> points_;
  std::vector<Point> forces_;
  size_t cursor_ = 0;
};

/// A hand holding the device's handle, as a point mass that reacts to the rendered force: the
/// hand pulls the mass towards where the user means to be (`intent`, a function of time) through
/// a spring and damper, gravity acts on it, and the rendered force pushes it. Integrated by
/// semi-implicit Euler at each ApplyForce over the time since the previous one.
class SpringMassHand : public HapticDevice {
 public:
  struct Params {
    double mass = 0.05;           // mass units
    double hand_stiffness = 0.0;  // 0: the hand lets go (a dropped tool)
    double hand_damping = 0.0;
    Vec3 gravity{0, 0, 0};        // acceleration, world units / s^2
  };
  SpringMassHand(const Params& params, Vec3 start, std::function<Vec3(double)> intent = nullptr);

  DeviceSample Read(double t) override { return DeviceSample{t, position_, {}}; }
  void ApplyForce(const Vec3& force, double t) override;

  const Vec3& position() const { return position_; }
  const Vec3& velocity() const { return velocity_; }
  const Params& params() const { return params_; }

 private:
  Params params_;
  std::function<Vec3(double)> intent_;
  Vec3 position_, velocity_;
  double last_t_ = 0;
  bool started_ = false;
};

}  // namespace sculpt::haptics

#endif  // SCULPT_HAPTICS_HAPTIC_DEVICE_H_
