// accura post-processor: simulated execution of a commanded path: the controller with its
// nominal IK, the real robot where those joints put it (the prediction the compensation and
// its tests rest on; docs/compensation.md). Compensator::execute (compensate.h) is the same
// with prepared models.
#pragma once

#include <Eigen/Geometry>
#include <vector>

#include "accura/calib/robot.h"
#include "accura/postproc/path.h"

namespace accura::postproc {

/// Simulated execution: the controller interpolates `commanded` (LIN: straight line and
/// slerp; CIRC: circle through start/aux/end, orientation interpolated), solves its own
/// (nominal) IK at every sample, keeping the configuration (nearest solution to the previous
/// sample, starting from q_start; empty q_start: the controller's solution nearest to the
/// middle of the joint ranges), and the real robot goes there. Returns the real tool poses
/// at both ends of every segment and at most `step_mm` (and 0.5 deg of orientation) apart.
/// Throws NumericalError when the controller cannot follow the path.
std::vector<Eigen::Isometry3d> simulateExecution(const calib::RobotModel& controller,
                                                 const calib::RobotModel& real,
                                                 const std::vector<PathSegment>& commanded,
                                                 const Eigen::VectorXd& q_start, double step_mm,
                                                 double payload_kg = 0);

}  // namespace accura::postproc
