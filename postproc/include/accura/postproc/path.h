// accura post-processor: LIN and CIRC path segments as the controller interpolates them, and
// the geometric deviation of sampled poses from a path (docs/compensation.md). Frames: world
// (cell), poses T_world_tcp; lengths mm, angles rad where said.
#pragma once

#include <Eigen/Geometry>
#include <vector>

namespace accura::postproc {

enum class PathType { kLin, kCirc };

/// A LIN or CIRC segment between two poses (world). For CIRC, `T_world_aux` is the auxiliary
/// point: the controller moves on the circle through start, aux and end (the aux point's
/// orientation is not used). Orientation: slerp from start to end over the path parameter
/// (LIN: fraction of the length; CIRC: fraction of the arc angle).
struct PathSegment {
  PathType type = PathType::kLin;
  Eigen::Isometry3d T_world_start = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_aux = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_end = Eigen::Isometry3d::Identity();
};

/// The pose at path parameter s in [0, 1] (LIN / CIRC interpolation as the controller does
/// it). Throws NumericalError for a CIRC whose three points are (nearly) collinear.
Eigen::Isometry3d interpolate(const PathSegment& segment, double s);
/// Length of the segment's position path (mm) and its orientation change (rad).
double pathLength(const PathSegment& segment);
double pathRotation(const PathSegment& segment);

/// Largest distance (mm) from the sampled poses' positions to the intended path (the union
/// of the intended segments' curves: line segments and circular arcs). Throws ArgumentError
/// when `intended` is empty.
double maxPathDeviation(const std::vector<Eigen::Isometry3d>& samples,
                        const std::vector<PathSegment>& intended);

/// Distance (mm) from a point to one segment's curve.
double distanceToPath(const Eigen::Vector3d& p_world, const PathSegment& segment);

}  // namespace accura::postproc
