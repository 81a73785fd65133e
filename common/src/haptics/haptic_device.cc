/// @brief The simulated haptic devices: recorded playback and the spring-mass hand.
#include "sculpt/haptics/haptic_device.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>

#include "sculpt/core/check.h"

namespace sculpt::haptics {

StatusOr<RecordedDevice> RecordedDevice::FromPoints(std::vector<Point> points) {
  if (points.empty()) return InvalidArgument("RecordedDevice.points is empty, needs >= 1 point");
  for (size_t i = 0; i < points.size(); ++i) {
    const std::string field = "RecordedDevice.points[" + std::to_string(i) + "].t";
    if (!std::isfinite(points[i].t)) {
      return NotFinite(field, FormatNumber(points[i].t));
    }
    if (i > 0 && !(points[i].t > points[i - 1].t)) {
      return Outside(
          field, FormatNumber(points[i].t),
          std::string("(") + FormatNumber(points[i - 1].t) + ", inf): times must increase");
    }
  }
  return RecordedDevice(std::move(points));
}

StatusOr<RecordedDevice> RecordedDevice::Load(const std::string& path) {
  std::ifstream in(path);
  if (!in) return NotFound("cannot open recorded trajectory " + path);
  std::vector<Point> points;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    // strtod, unlike operator>>, reads "nan" (a recorded dropout).
    const char* s = line.c_str();
    double v[4];
    for (double& x : v) {
      char* end = nullptr;
      x = std::strtod(s, &end);
      if (end == s) {
        return InvalidArgument(path + ":" + std::to_string(number) + ": \"" + line +
                               "\" is not 't x y z'");
      }
      s = end;
    }
    points.push_back({v[0], {v[1], v[2], v[3]}});
  }
  return FromPoints(std::move(points));
}

Status RecordedDevice::Save(const std::string& path, const std::vector<Point>& points) {
  std::ofstream out(path);
  if (!out) return NotFound("cannot write recorded trajectory " + path);
  out.precision(17);
  out << "# t x y z\n";
  for (const Point& p : points) {
    out << p.t << ' ' << p.position.x << ' ' << p.position.y << ' ' << p.position.z << '\n';
  }
  return out ? Status::Ok() : Internal("write failed: " + path);
}

DeviceSample RecordedDevice::Read(double t) {
  // Playback moves forward; a time before the cursor restarts the search.
  if (cursor_ >= points_.size() || points_[cursor_].t > t) cursor_ = 0;
  while (cursor_ + 1 < points_.size() && points_[cursor_ + 1].t <= t) ++cursor_;
  const Point& a = points_[cursor_];
  if (t <= a.t || cursor_ + 1 == points_.size()) return DeviceSample{t, a.position, {}};
  const Point& b = points_[cursor_ + 1];
  const double s = (t - a.t) / (b.t - a.t);
  return DeviceSample{t, a.position + (b.position - a.position) * s, {}};
}

SpringMassHand::SpringMassHand(const Params& params, Vec3 start,
                               std::function<Vec3(double)> intent)
    : params_(params), intent_(std::move(intent)), position_(start) {}

void SpringMassHand::ApplyForce(const Vec3& force, double t) {
  if (!started_) {
    started_ = true;
    last_t_ = t;
    return;  // the first force acts from now on
  }
  const double dt = t - last_t_;
  last_t_ = t;
  if (!(dt > 0) || !force.IsFinite()) return;
  Vec3 total = force + params_.gravity * params_.mass;
  if (intent_ && params_.hand_stiffness > 0) {
    total += (intent_(t) - position_) * params_.hand_stiffness;
  }
  total -= velocity_ * params_.hand_damping;
  velocity_ += total * (dt / params_.mass);
  position_ += velocity_ * dt;
}

}  // namespace sculpt::haptics
