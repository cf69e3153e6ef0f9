// accura post-processor: discrete compensation of targets (method.md section 4) and auxiliary
// points on continuous paths. The paths themselves (LIN / CIRC segments, interpolation,
// deviation) are in path.h, the simulated execution in execution.h (both included here); the
// IK and the S/T configuration are calib's (accura/calib/ik.h). The method, the
// tolerances and why the path sampling is fine enough: docs/compensation.md.
//
// Frames: every pose here is T_world_tcp in the world (cell) frame. The caller converts
// program targets ($BASE / $TOOL) to the world and back. Two models take part:
//   controller: what the robot controller believes (nominal kinematics at the nominal base
//               where the OLP placed the robot, the program's tool);
//   real:       the calibrated model (identified base, kinematics, compliance and the other
//               effects; the calibrated tool when the program uses the tool that was
//               calibrated, else the program's).
// Joint values: deg (revolute), mm (prismatic), as in calib.
// The inverse kinematics of the complete model is calib's (accura/calib/ik.h).
// The state of the arm that the real model needs besides q (payload, temperature, approach
// directions) is a calib PoseContext; the overloads taking `double payload_kg` use a default
// context with that payload.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

#include "accura/calib/ik.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/robot.h"
#include "accura/postproc/execution.h"
#include "accura/postproc/path.h"

namespace accura::postproc {

// The inverse kinematics lives in calib (accura/calib/ik.h); its names are also visible here.

/// Discrete compensation of one pose: q' = IK_real(desired), command = FK_controller(q').
/// The controller's own IK, asked for `command` with `configuration`, returns q', so the
/// real robot lands on the desired pose. Once within the IK tolerance, q' is polished (a few
/// more Newton steps while they gain) to about 1e-9 mm and 1e-12 rad, so that the command is
/// the exact solution far below any printed resolution: the same output on every machine.
struct PoseCompensation {
  calib::IkStatus status = calib::IkStatus::kNotConverged;
  std::string message;
  Eigen::Isometry3d T_world_tcp_command = Eigen::Isometry3d::Identity();
  Eigen::VectorXd q_real;            ///< joints that put the real tool on the desired pose
  /// S/T of q_real: what the program must carry with the command.
  calib::Configuration configuration;
  /// The program asked for a configuration (`config`, where not -1) that q_real does not
  /// have: the compensation moves the target across a configuration boundary (next to a
  /// singularity). status is still kOk and the result valid with `configuration`; report it.
  bool configuration_changed = false;
  double correction_mm = 0;          ///< |command - desired| position
  double correction_deg = 0;         ///< rotation angle between command and desired
};
/// Throws ArgumentError for invalid options, a seed of the wrong size or models of different
/// joint counts.
PoseCompensation compensatePose(const calib::RobotModel& controller, const calib::RobotModel& real,
                                const Eigen::Isometry3d& T_world_tcp_desired,
                                const calib::Configuration& config, const Eigen::VectorXd& seed,
                                const calib::IkOptions& options, double payload_kg = 0);

/// The path tolerances accepted (mm): the command line's --tol, the plug-in's tol_mm and
/// DensifyOptions::tol_mm.
inline constexpr double kMinTolMm = 0.001, kMaxTolMm = 100;

struct DensifyOptions {
  double tol_mm = 0.05;          ///< max predicted deviation of the real path (position)
  double sample_step_mm = 1.0;   ///< path sampling for the error prediction (see docs)
  double sample_step_deg = 0.5;  ///< the same for the orientation (pure reorientations)
  int max_points_per_segment = 500;
  calib::IkOptions ik;
  bool IsValid(std::string* error) const;
};

/// A continuous segment, compensated: `commanded` are the sub-segments to send, in order
/// (commanded.front().T_world_start is the compensated start, each T_world_end the
/// compensated end or auxiliary point; for CIRC each sub-segment has its own aux).
struct SegmentCompensation {
  calib::IkStatus status = calib::IkStatus::kNotConverged;
  std::string message;
  std::vector<PathSegment> commanded;
  /// Real joint values at each commanded[i].T_world_end (its configuration: take
  /// kukaConfiguration of it); the last one seeds the next segment.
  std::vector<Eigen::VectorXd> q_real_end;
  Eigen::VectorXd q_real_start;           ///< real joint values at the start
  double max_error_uncompensated_mm = 0;  ///< the program as it is, run on the real robot
  double max_error_before_mm = 0;  ///< endpoints compensated, no auxiliary points
  double max_error_after_mm = 0;   ///< with the auxiliary points (largest sampled error)
  /// Upper bound of the error after, between the samples too (sampled maximum plus the
  /// interpolation bound of docs/compensation.md); <= tol_mm when status is kOk.
  double max_error_bound_mm = 0;
  int points_added = 0;            ///< commanded.size() - 1: new targets inserted
};

/// The controller and the real robot, prepared once for many targets and segments (the
/// free functions above build one per call). Thread-safe const methods.
class Compensator {
 public:
  /// Throws ArgumentError when the two models have different joint counts or are invalid.
  Compensator(const calib::RobotModel& controller, const calib::RobotModel& real);
  const calib::KinematicSolver& controller() const { return controller_; }
  const calib::KinematicSolver& real() const { return real_; }

  /// compensatePose. `seed`: the real joint values of the previous point (empty: none); the
  /// real model is evaluated in `context`, the controller in a default context.
  PoseCompensation pose(const Eigen::Isometry3d& T_world_tcp_desired, const calib::Configuration& config,
                        const Eigen::VectorXd& seed, const calib::IkOptions& options,
                        const calib::PoseContext& context = {}) const;
  /// Compensates a LIN / CIRC segment with auxiliary points (SegmentCompensation). Greedy:
  /// each piece as long as the tolerance allows (docs/compensation.md). Failures
  /// (unreachable, singular, tolerance not met within max_points_per_segment) come back in
  /// `status` / `message` with `commanded` empty. Throws ArgumentError for invalid options
  /// and NumericalError for a CIRC without a circle (collinear points).
  /// `seed`: the real joint values at the segment's start (the previous
  /// point's q_real; the start continues from them); empty: the start is solved with
  /// `config`. `config` is the S/T the program gives the segment's end target: like the
  /// controller on LIN / CIRC, every point along the segment keeps the configuration of the
  /// start (nearest solution), so the end may differ from `config`: compare
  /// kukaConfiguration(q_real_end.back()) with it.
  SegmentCompensation segment(const PathSegment& intended, const calib::Configuration& config,
                              const Eigen::VectorXd& seed, const DensifyOptions& options,
                              const calib::PoseContext& context = {}) const;
  /// The real tool poses when the controller executes `commanded` from joint values
  /// `q_controller_start` (see simulateExecution). Throws NumericalError when the controller
  /// cannot follow the path (unreachable, joint limits, singular).
  std::vector<Eigen::Isometry3d> execute(const std::vector<PathSegment>& commanded,
                                         const Eigen::VectorXd& q_controller_start, double step_mm,
                                         const calib::PoseContext& context = {}) const;

 private:
  calib::KinematicSolver controller_;
  calib::KinematicSolver real_;
};

}  // namespace accura::postproc
