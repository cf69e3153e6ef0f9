// URScript reader and writer internals (urscript.h): pose conversions and the evaluation of
// pose expressions, shared by both.
#pragma once

#include <Eigen/Geometry>
#include <map>

#include "accura/postproc/urscript.h"

namespace accura::postproc::ur_detail {

/// T (mm) of p[x, y, z, rx, ry, rz] (metres, rotation vector in radians).
Eigen::Isometry3d poseOf(const double v[6]);
/// The value of pose expression `id` of `src` (mm); literals found in `override` (literal ->
/// pose, mm) take that value.
Eigen::Isometry3d evaluate(const UrScriptSource& src, int id, const std::map<int, Eigen::Isometry3d>* override = nullptr);
/// pose_add(a, b): positions added, rotations a.R * b.R (URScript manual, pose_add).
Eigen::Isometry3d poseAdd(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b);

}  // namespace accura::postproc::ur_detail
