/// @brief The thesis's 2D experiment setups (seed 000 §3.2 local carve, §3.3 volume compensation)
/// on a 201x201 one-voxel slab, evolved through the production kernels of kernels.h.
#ifndef SCULPT_LEVELSET_THESIS_REPRO_H_
#define SCULPT_LEVELSET_THESIS_REPRO_H_

#include <cstdint>
#include <vector>

#include "sculpt/levelset/dense_field.h"
#include "sculpt/levelset/kernels.h"

namespace sculpt::levelset::thesis {

/// The thesis's Cartesian grid (seed 000 §3 "Common setup", §9 erratum 10): the square domain
/// [0, length]^2 cut into `intervals` intervals per axis, nodes at (i*h, j*h), i, j = 0..intervals.
/// The default is the thesis's n = 200 intervals, 201x201 nodes, h = 0.5.
struct GridSpec {
  int intervals = 200;
  double length = 100.0;

  double h() const { return length / intervals; }
  int nodes() const { return intervals + 1; }
  /// A field of nodes() x nodes() x 1 voxels (the one-voxel slab), origin 0, filled with `fill`.
  DenseField MakeField(float fill) const;
};

/// 2D point in world units.
struct Point2 {
  double x = 0, y = 0;
};

enum class ShapeKind : uint8_t { kCircle = 0, kRectangle = 1 };

/// A circle (radius `half_x`) or an axis-aligned rectangle (half-extents `half_x`, `half_y`).
/// Sizes are half-sizes, as the MATLAB code reads `r` (seed 000 §9 erratum 11): the thesis's
/// "square of side 9" tool is Rectangle(c, 9, 9), an 18x18 square.
struct Shape2D {
  ShapeKind kind = ShapeKind::kCircle;
  Point2 center{50.0, 50.0};
  double half_x = 18.0;
  double half_y = 18.0;

  static Shape2D Circle(Point2 c, double radius) { return {ShapeKind::kCircle, c, radius, radius}; }
  static Shape2D Rectangle(Point2 c, double half_x, double half_y) {
    return {ShapeKind::kRectangle, c, half_x, half_y};
  }
  static Shape2D Square(Point2 c, double half_side) { return Rectangle(c, half_side, half_side); }
};

/// The thesis's material: circle r = 18 at (50, 50) (seed 000 §3.2, §4).
inline Shape2D ThesisMaterial() { return Shape2D::Circle({50.0, 50.0}, 18.0); }
/// The thesis's circle tool: r = 9 at (65, 63).
inline Shape2D ThesisCircleTool() { return Shape2D::Circle({65.0, 63.0}, 9.0); }
/// The thesis's square tool: half-side 9 at (65, 63).
inline Shape2D ThesisSquareTool() { return Shape2D::Square({65.0, 63.0}, 9.0); }

/// Exact signed distance of the material shape at (x, y), negative inside (App. A.1): the circle
/// sqrt((x-cx)^2 + (y-cy)^2) - r; the rectangle the exact box SDF (max of the axis distances
/// inside and on the axis bands, the corner distance elsewhere).
double ShapeSignedDistance(const Shape2D& shape, double x, double y);

/// The material SDF sampled at every node of `grid`.
DenseField MaterialField(const Shape2D& material, const GridSpec& grid);

/// Indicator chi_Gamma of the tool region on the nodes (seed 000 §3.2): 1 where
/// (x0-X)^2 + (y0-Y)^2 <= r^2 (circle) or |X-x0| <= a and |Y-y0| <= b (rectangle), else 0.
/// Same layout as the field (x fastest).
std::vector<uint8_t> ToolMask(const Shape2D& tool, const GridSpec& grid);

/// The explicit tool samples of App. A.1. Circle: the k+1 points r(cos 2 pi i/k, sin 2 pi i/k) + c,
/// i = 0..k (the last repeats the first). Rectangle: k1 = ceil(k/4) points per edge, 4*k1 in all,
/// each edge starting at a corner (top edge from the top-left corner going right, then the right
/// edge going down, the bottom edge going left, the left edge going up).
std::vector<Point2> ToolSamples(const Shape2D& tool, int k);

/// Bilinear interpolation of phi at (x, y) from the four nodes of the containing cell (eq. 3.1).
/// Points outside the domain are clamped into it.
double Bilinear(const DenseField& phi, const GridSpec& grid, double x, double y);

/// Number of samples with interpolated phi <= 0: the thesis's collision count (seed 000 §2.4).
int CountCollidingSamples(const DenseField& phi, const GridSpec& grid,
                          const std::vector<Point2>& samples);

/// Pointwise area of the material, h^2 * #{phi <= 0} (seed 000 §2.9, `Volg` without a mask).
double PointwiseArea(const DenseField& phi, double h);
/// Vol_{Gamma^c}: h^2 * #{phi <= 0 and mask == 0} (`Volg` with ph2 = 1 - chi_Gamma).
double PointwiseAreaOutside(const DenseField& phi, const std::vector<uint8_t>& mask, double h);
/// Material left inside the tool footprint: h^2 * #{phi <= 0 and mask != 0}.
double PointwiseAreaInside(const DenseField& phi, const std::vector<uint8_t>& mask, double h);

/// Area of the material pieces that lie wholly inside the mask: h^2 times the node count of the
/// 4-connected components of {phi <= 0} none of whose nodes is outside the mask. After a carve
/// these are the disconnected islands of seed 000 §3.2 / §5 item 9.
double IslandAreaInside(const DenseField& phi, const std::vector<uint8_t>& mask, double h);

/// Active voxel list of the nodes with mask == want.
VoxelList MaskVoxels(const std::vector<uint8_t>& mask, bool want);

/// Settings of the thesis's `reinit_SD(ph, h, h, 0.9, 'WENO', 1)` (seed 000 §2.8): one
/// Sussman-Smereka-Osher step, WENO5, forward Euler. kClamp: every node takes part, as in the
/// toolbox, whose ghost nodes are linear extrapolations.
MotionSettings ReinitSettings();
/// `reinit_SD`'s alpha (seed 000 §2.8, §4).
inline constexpr double kReinitAlpha = 0.9;

/// The CFL number to pass to Reinitialize (pseudo-step cfl * h) so that its step equals
/// `reinit_SD`'s: the toolbox's `get_dt_normal` takes dt = alpha / max(H1/dx + H2/dy) with
/// H_a = |S(phi0)| phi_a^2 / |grad phi|, i.e. dt = alpha h / max |S(phi0)| |grad phi| over the
/// grid, with first-order Godunov one-sided differences (the toolbox's `select_der_normal`)
/// standing in for its WENO ones. On a signed distance function this is alpha / sqrt(2) (the
/// maximum sits on the skeleton, e.g. the circle's centre); after a carve step, where |grad phi|
/// reaches ~100 at the rim of Gamma, it is ~100 times smaller. A fixed pseudo-step of 0.9 h is
/// not monotone there: the circle carve at dt = 1 with a reinit every pass then grows 1863 area
/// units of spurious material and runs 54 passes instead of 4.
double ReinitSdCfl(const DenseField& phi, double h, double alpha);

/// Local deformation (seed 000 §2.9 Algorithm 2 with accion = 1, App. A.3 `objdef`).
struct CarveSetup {
  GridSpec grid;
  Shape2D material = ThesisMaterial();
  Shape2D tool = ThesisCircleTool();
  double speed = 7.0;  ///< v, the tool speed (seed 000 §4).
  double dt = 1.0;
  int samples = 50;      ///< k, tool samples (REPRO: 50 matches the thesis's counts).
  int reinit_every = 0;  ///< 0 = never; N = after every pass whose number is a multiple of N.
  /// 0: `reinit_SD`'s adaptive pseudo-step (ReinitSdCfl); > 0: a fixed pseudo-step of this * h.
  double reinit_fixed_cfl = 0;
  int max_passes = 100000;
  /// The thesis's scheme: central differences, forward Euler, adiabatic border (seed 000 §2.7).
  MotionSettings motion{SpatialScheme::kCentral, TemporalScheme::kRk1, Boundary::kAdiabatic};
};

struct CarveResult {
  /// Passes of the thesis's loop, including the final pass that finds no colliding sample: the
  /// number the thesis's tables print (4 / 13 / 97 for the circle tool).
  int thesis_iterations = 0;
  int updates = 0;  ///< Evolution steps actually applied (thesis_iterations - 1 on a normal stop).
  int reinits = 0;
  bool hit_pass_limit = false;
  double initial_area = 0;           ///< Pointwise area before the carve.
  double final_area = 0;             ///< Pointwise area after it.
  double area_removed = 0;           ///< initial_area - final_area.
  double area_stranded = 0;          ///< Material left inside the tool footprint.
  double island_area = 0;            ///< The part of it cut off from the rest (IslandAreaInside).
  bool tool_region_cleared = false;  ///< No node of Gamma is inside the material any more.
  DenseField phi;                    ///< The final field.
};

/// Runs phi <- phi + dt * v * |grad phi| * chi_Gamma (NormalMotionStep with F = -v on the Gamma
/// nodes) while some tool sample has bilinear phi <= 0, checking before each step, with an
/// optional reinit every `reinit_every` passes (counted as the thesis does: floor(passes / N)).
CarveResult RunLocalCarve(const CarveSetup& setup);

/// The two compensation equations of seed 000 §2.9 (`ecuacion`).
enum class CompensationForm : uint8_t {
  kDelta = 1,     ///< phi <- phi + dt * dif * delta_eps(phi) * chi_{Gamma^c}   (5.6, code sign)
  kGradient = 2,  ///< phi <- phi + dt * dif * |grad phi| * chi_{Gamma^c}       (5.8, code sign)
};

/// Volume compensation (Algorithm 2 with accion = 2, App. A.3 `objdef`) on the uncarved material.
struct CompensationSetup {
  GridSpec grid;
  Shape2D material = ThesisMaterial();
  Shape2D tool = ThesisCircleTool();
  CompensationForm form = CompensationForm::kDelta;
  double dt = 1.0;
  double eps_factor = 1.5;  ///< delta_eps half-width in units of h (`dlcon`: eps = 1.5 h).
  int reinit_every = 0;
  double reinit_fixed_cfl = 0;  ///< As in CarveSetup.
  int max_passes = 25;
  /// |dif| above this counts as blow-up; <= 0 means Vol0 (the material would have to more than
  /// double, or vanish). A pointwise area can never exceed the domain, so the field itself is also
  /// checked: non-finite values or |phi| > 1e6 * length are blow-up.
  double blowup_abs_dif = 0;
  int tail_window = 6;  ///< Passes looked at by the stall and oscillation detection.
  /// Scheme of the |grad phi| form (the delta form is pointwise). Thesis default: central, RK1,
  /// adiabatic.
  MotionSettings motion{SpatialScheme::kCentral, TemporalScheme::kRk1, Boundary::kAdiabatic};
};

struct CompensationResult {
  /// dif = Vol_{Gamma^c} - Vol0 measured at the start of each pass, before that pass's update.
  std::vector<double> dif_history;
  double initial_area = 0;  ///< Vol0, the pointwise total area (c).
  double final_dif = 0;     ///< Last entry of dif_history.
  double final_abs_dif = 0;
  int passes = 0;  ///< dif_history.size().
  int updates = 0;
  int reinits = 0;
  bool converged = false;  ///< dif reached exactly 0 (the thesis's stopping test).
  bool diverged = false;
  /// The last tail_window |dif| values are all equal and non-zero.
  bool stalled = false;
  /// dif changed sign at least twice within the last tail_window passes (without diverging).
  bool oscillating = false;
  std::vector<double> tail_abs_dif;  ///< The last (up to) tail_window |dif| values.
  DenseField phi;
};

/// Runs the compensation loop until dif == 0, max_passes passes, or blow-up.
CompensationResult RunCompensation(const CompensationSetup& setup);

}  // namespace sculpt::levelset::thesis

#endif  // SCULPT_LEVELSET_THESIS_REPRO_H_
