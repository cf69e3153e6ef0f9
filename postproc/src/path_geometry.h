// Internal: the controller's path interpolation (LIN, CIRC) and the geometric deviation from
// a path. docs/compensation.md.
#pragma once

#include <Eigen/Geometry>

#include "accura/postproc/path.h"

namespace accura::postproc::detail {

/// A segment prepared for interpolation: LIN p(s) = p0 + s (p1 - p0); CIRC p(s) = c +
/// r (cos(s A) e1 + sin(s A) e2), e1 towards the start, e2 = n x e1, A the arc angle through
/// the auxiliary point. Orientation: slerp from start to end over s.
struct PathGeometry {
  PathType type = PathType::kLin;
  Eigen::Vector3d p0, p1;
  Eigen::Vector3d c, n, e1, e2;
  double r = 0, arc = 0;  ///< radius (mm), arc angle (rad, in (0, 2 pi))
  double s_aux = 0.5;     ///< CIRC: the path parameter of the auxiliary point, in (0, 1)
  Eigen::Quaterniond q0, q1;
  double length_mm = 0, rotation_rad = 0;

  /// Throws NumericalError for a CIRC whose points are (nearly) collinear or coincide.
  explicit PathGeometry(const PathSegment& s);
  Eigen::Vector3d position(double s) const;
  Eigen::Isometry3d pose(double s) const;
  /// The deviation of a point from the curve as a vector whose norm is the distance to the
  /// whole line / whole circle: LIN the component perpendicular to the line, CIRC
  /// (height above the plane, distance from the axis - r, 0). A smooth function of the point
  /// (away from the circle's axis), used for the interpolation bound.
  Eigen::Vector3d deviation(const Eigen::Vector3d& p) const;
  /// Distance to the curve piece itself (segment / arc, ends included).
  double distance(const Eigen::Vector3d& p) const;
};

/// Samples of one commanded sub-segment: at least 16 and at most `step_mm` / `step_deg`
/// apart.
int sampleCount(const PathGeometry& g, double step_mm, double step_deg);

}  // namespace accura::postproc::detail
