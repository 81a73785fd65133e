/// @brief The in-process scripted sculpting session behind `sculpt demo`.
#ifndef SCULPT_CLIENT_DEMO_H_
#define SCULPT_CLIENT_DEMO_H_

#include <string>

#include "sculpt/core/status.h"

namespace sculpt::client {

struct DemoOptions {
  std::string out_dir = "demo-output";
  double radius = 24.0;       // sphere radius, world units (mm)
  double voxel_size = 0.5;    // world units per voxel
  int strokes = 240;          // press samples along the scripted paths
  unsigned seed = 7;
};

/// Runs the default scene (a sphere of clay), plays a scripted session (press strokes around
/// the equator with shell volume compensation, a subtracted hole, an added knob, smoothing), and
/// writes sculpture.vdb, sculpture.ply and summary.json into out_dir.
Status RunDemo(const DemoOptions& options);

}  // namespace sculpt::client

#endif  // SCULPT_CLIENT_DEMO_H_
