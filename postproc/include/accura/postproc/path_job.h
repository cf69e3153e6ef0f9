// accura post-processor: the compensation of a run of LIN / CIRC motions from a start pose, as
// the job (job.cpp) does it motion by motion, for callers that have poses rather than a
// program (the plug-in's accura_compensate_path). Frames: world (job.h).
#pragma once

#include <vector>

#include "accura/postproc/compensate.h"
#include "accura/postproc/job.h"

namespace accura::postproc {

/// The configuration rule of accura compensate for a pose: a compensation that lands on another
/// S/T than `asked` becomes kNoConfiguration (with a message), except Turn bits of joints
/// within kTurnBandDeg of 0 (the same arm posture: pc keeps the new bits and
/// configuration_changed).
void enforceConfiguration(const calib::Configuration& asked, PoseCompensation& pc);

/// A Cartesian target of a host (the plug-in's poses, a path's start) compensated like a PTP of
/// accura compensate (docs/compensation.md, section 2). A controller that reads S/T
/// (controllerReadsConfiguration): on `asked`, enforceConfiguration. One that reads none (a
/// Universal Robots arm): on askedConfiguration(asked, a seed given), i.e. the solution nearest
/// `seed` (the joints the robot stands on), without one on the Status asked as the guess of the
/// branch and the Turn of the solution nearest the middle of the joint ranges; the result's
/// configuration is the S/T of the joints reached and configuration_changed is never set
/// (the controller reads nothing the program would have to carry).
PoseCompensation compensateTarget(const Compensator& comp, const Eigen::Isometry3d& T_world_tcp, const calib::Configuration& asked,
                                  const Eigen::VectorXd& seed, const JobSettings& settings);

/// One LIN / CIRC segment compensated from where the real robot is: sets
/// intended.T_world_start to the real model's tool pose at `q_real` (in settings.context),
/// then Compensator::segment with settings.densify, settings.tol_mm and settings.ik.
SegmentCompensation compensateSegmentFrom(const Compensator& comp, PathSegment& intended, const calib::Configuration& config,
                                          const Eigen::VectorXd& q_real, const JobSettings& settings);

/// A path compensated: its start, then each motion from where the real robot ends the one
/// before.
struct PathCompensation {
  PoseCompensation start;
  std::vector<PathSegment> intended;          ///< the motions with their starts (world)
  std::vector<SegmentCompensation> segments;  ///< one per motion, up to the first that failed
  /// -1, or the motion that failed: numerical_error says why when it is not empty, else
  /// segments.back(); start.status != kOk: the start.
  int failed_motion = -1;
  /// The calib::NumericalError of motion failed_motion's geometry (a CIRC whose start,
  /// auxiliary and end point are collinear): segments holds the motions before it.
  std::string numerical_error;
  bool ok() const { return start.status == calib::IkStatus::kOk && failed_motion < 0; }
};

/// Compensates the start T_world_start (configuration `start_config`, compensateTarget without a seed),
/// then every motion of `motions` (their T_world_start is ignored) with
/// compensateSegmentFrom, stopping at the first failure (a calib::NumericalError of a motion
/// is that motion's failure: numerical_error). Throws like Compensator::segment otherwise.
PathCompensation compensatePath(const Compensator& comp, const Eigen::Isometry3d& T_world_start, const calib::Configuration& start_config,
                                const std::vector<PathSegment>& motions, const JobSettings& settings);

}  // namespace accura::postproc
