// accura post-processor: inverse kinematics of the complete model, discrete compensation of
// targets (method.md section 4) and auxiliary points on continuous paths. The method, the
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
// The state of the arm that the real model needs besides q (payload, temperature, approach
// directions) is a calib PoseContext; the overloads taking `double payload_kg` use a default
// context with that payload.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

#include "accura/calib/kinematics.h"
#include "accura/calib/robot.h"

namespace accura::postproc {

/// KUKA configuration: Status and Turn bits; -1 when not specified.
///   Turn:   bit i (i = 0..dof-1) set when joint i+1 is negative (q_i < 0).
///   Status: bit 0 set when the wrist point (origin of DH frame 5: the intersection of the
///           wrist axes on a spherical wrist) has a negative x in the A1 frame (the base
///           frame turned with A1): the "overhead area"; bit 1 set when A3 >= phi, phi the
///           A3 angle at which the arm is stretched (the origin of DH frame 4, the wrist point
///           on a spherical wrist, on the line through the A2 and A3 axes; phi = 0 when A3 and
///           A4 have no offset, -2.99 deg on a KR 16); bit 2 set when A5, taken into
///           [-180, 180), is negative. (KUKA's home {0, -90, 90, 0, 0, 0}: S 2, T 2.)
/// Status is computed from the nominal geometry (what the controller computes) and is
/// defined for robots with 6 or more joints, the first 6 revolute; otherwise -1.
struct Configuration {
  int status = -1;
  int turn = -1;
  bool operator==(const Configuration& o) const { return status == o.status && turn == o.turn; }
  bool operator!=(const Configuration& o) const { return !(*this == o); }
};

/// S and T of joint values q (KUKA definition above). Throws ArgumentError when q.size() is
/// not the model's dof.
Configuration kukaConfiguration(const RobotModel& model, const Eigen::VectorXd& q);

/// True when `actual` satisfies `asked` (every part of `asked` that is not -1 is equal).
bool configurationMatches(const Configuration& asked, const Configuration& actual);

/// Joints within this band of 0 (deg) may flip their Turn bit by a correction: the same arm
/// posture, and the controller needs the new sign to find the joints.
constexpr double kTurnBandDeg = 1.0;
/// True when `actual` (the configuration of joints `q`, deg) differs from `asked` only in Turn
/// bits of joints within kTurnBandDeg of 0: the Status (when asked) equal, every other Turn
/// bit asked for equal. False when they match exactly (nothing differs) or differ otherwise.
bool onlyTurnBitsNearZeroDiffer(const Configuration& asked, const Configuration& actual, const Eigen::VectorXd& q);

struct IkOptions {
  double tol_mm = 1e-3;    ///< position convergence: 1 um
  double tol_rad = 1e-6;   ///< orientation convergence: 1 urad
  int max_iterations = 100;
  double joint_margin = 0; ///< required distance from the joint limits (deg or mm)
  /// A solution whose scaled joint Jacobian (docs/compensation.md: position rows divided by
  /// the sum of the link lengths and the tool offset, columns per radian) has a smallest
  /// singular value below this is
  /// reported as kSingular (dimensionless; on a KR 16 the wrist gives about 0.25 |A5|, A5
  /// in rad, so 1e-4 is A5 within about 0.02 deg of 0; 0 turns the check off).
  double singular_threshold = 1e-4;
  /// Compute IkResult::min_singular_value exactly (an SVD, about 10 us) for every solution;
  /// otherwise only for singular ones.
  bool compute_singular_value = false;
  bool IsValid(std::string* error) const;
};

enum class IkStatus {
  kOk,
  kUnreachable,       ///< no joint values put the tool there (outside the workspace)
  kJointLimits,       ///< reachable only outside the joint limits (with the margin)
  kSingular,          ///< at or too close to a singularity to be trusted
  kNoConfiguration,   ///< reachable, but not on the configuration (S/T) asked for
  kNotConverged,
};
const char* toString(IkStatus status);

struct IkResult {
  IkStatus status = IkStatus::kNotConverged;
  /// kOk: the solution. kNoConfiguration: a solution on another configuration when one was
  /// found (the pose is reached; see `configuration`), else empty. kSingular: the converged
  /// joint values at the singularity. Otherwise empty.
  Eigen::VectorXd q;
  Configuration configuration;    ///< kukaConfiguration(q) when q is set
  double position_error_mm = 0;   ///< |p(q) - p_target| (world)
  double rotation_error_rad = 0;  ///< angle of R(q) R_target^T
  int iterations = 0;             ///< Newton iterations (all candidates tried)
  /// Smallest singular value of the scaled joint Jacobian at q (dimensionless, see
  /// IkOptions::singular_threshold): exact for kSingular or with compute_singular_value;
  /// otherwise 0 (not computed; the solution is then known to be further from a singularity
  /// than singular_threshold).
  double min_singular_value = 0;
  std::string message;            ///< why, when status != kOk
};

/// One thread's scratch for following a path with a KinematicSolver (the per-thread `Data`
/// next to the constant model): the frames and the joint Jacobian of the last solution that
/// inverse() returned with it. Pass the same workspace to successive inverse() calls along a
/// path, each seeded with the previous solution: when the seed is that solution bit for bit
/// (same solver, same PoseContext), Newton starts from the stored frames and Jacobian instead
/// of evaluating the model at the seed again (one forward kinematics and one Jacobian fewer
/// per solve). In every other case it is simply not used. The answer is the same as without
/// it to rounding (the stored frames equal a fresh evaluation to ~1e-15 relative). Not
/// shareable between threads while in use; cheap to create (one allocation).
class IkWorkspace {
 public:
  IkWorkspace();
  ~IkWorkspace();
  IkWorkspace(IkWorkspace&&) noexcept;
  IkWorkspace& operator=(IkWorkspace&&) noexcept;
  IkWorkspace(const IkWorkspace&) = delete;
  IkWorkspace& operator=(const IkWorkspace&) = delete;
  /// Forget the stored solution.
  void clear();
  /// True when it holds a solution (of any solver).
  bool holdsSolution() const;

  struct Data;

 private:
  friend class KinematicSolver;
  std::unique_ptr<Data> data_;
};

/// A robot model prepared for fast repeated forward and inverse kinematics: chain constants,
/// the closed-form solver of its nominal geometry when it has one, and the joint limits.
/// Construction checks the prepared chain against calib's forwardKinematics (throws
/// NumericalError when they disagree by more than 1e-9 mm: an effect of the model this
/// solver does not know) and throws ArgumentError for an invalid model. Immutable: const
/// methods may be called from several threads at once.
class KinematicSolver {
 public:
  explicit KinematicSolver(const RobotModel& model);
  ~KinematicSolver();
  KinematicSolver(const KinematicSolver&);
  KinematicSolver& operator=(const KinematicSolver&);

  const RobotModel& model() const;
  int dof() const;
  /// Which closed form seeds the IK: "spherical_wrist" (KR 16, IRB 120: 6R, three wrist axes
  /// meeting in a point), "three_parallel" (UR: joints 2-4 parallel) or "none" (multi-start
  /// Newton from a fixed set of starts).
  const char* closedForm() const;

  /// T_world_tcp at q, equal to calib's forwardKinematics. Throws ArgumentError on a size
  /// mismatch.
  Eigen::Isometry3d forward(const Eigen::VectorXd& q_deg_mm, const PoseContext& context = {}) const;
  /// Joint Jacobian (as calib's jointJacobian) and T_world_tcp.
  Eigen::Isometry3d jacobian(const Eigen::VectorXd& q_deg_mm, const PoseContext& context,
                             Eigen::Matrix<double, 6, Eigen::Dynamic>& J) const;

  /// Inverse kinematics on the complete model (see inverseKinematics below).
  IkResult inverse(const Eigen::Isometry3d& T_world_tcp, const Configuration& config,
                   const Eigen::VectorXd& seed, const IkOptions& options,
                   const PoseContext& context = {}) const;
  /// The same, continuing along a path with `workspace` (see IkWorkspace): faster when
  /// `seed` is the solution the previous call with this workspace returned; on kOk the
  /// workspace holds this solution, otherwise it is cleared.
  IkResult inverse(const Eigen::Isometry3d& T_world_tcp, const Configuration& config,
                   const Eigen::VectorXd& seed, const IkOptions& options, const PoseContext& context,
                   IkWorkspace& workspace) const;

  /// Every closed-form solution of the nominal links (with this model's base and tool)
  /// within the joint limits, each joint on every representation within its limits (so a
  /// +-360 deg joint gives two): what seeds inverse(). Empty for closedForm() == "none" or
  /// when the nominal links cannot reach the pose. For a model without deviations beyond
  /// base and tool these are its exact solutions.
  std::vector<Eigen::VectorXd> closedFormSolutions(const Eigen::Isometry3d& T_world_tcp) const;

  struct Impl;

 private:
  friend class Compensator;
  /// inverse(), then polished to polish_mm / polish_rad (see compensatePose).
  IkResult inversePolished(const Eigen::Isometry3d& T_world_tcp, const Configuration& config,
                           const Eigen::VectorXd& seed, const IkOptions& options, const PoseContext& context,
                           double polish_mm, double polish_rad, IkWorkspace* workspace = nullptr) const;
  std::shared_ptr<const Impl> impl_;
};

/// Inverse kinematics of the complete model `model` (base, tool, deviations, every effect in
/// `context`) for T_world_tcp, converged to tol_mm and tol_rad on the complete model.
/// `config`: the S/T branch to take (-1 parts: any). `seed`: optional warm start (empty =
/// cold). With a seed and any Status, the solution continuing from the seed: Newton from the
/// seed when it stays within 2 deg of it (10 deg where the Jacobian is well conditioned) on
/// the seed's Status, else the closed-form branch nearest to the seed; without a seed, the
/// branch nearest to the middle of the joint ranges. Seeds: the closed form of the nominal
/// links (all 8 branches) corrected for the deviations, then Newton's method (and
/// Levenberg-Marquardt) on the complete model; docs/compensation.md has the whole order.
/// Never returns a wrong point: status says why there is none. Throws ArgumentError when the
/// seed has the wrong size, the target is not finite or the options are invalid.
/// Each call prepares the model (a few us); use KinematicSolver for many calls.
IkResult inverseKinematics(const RobotModel& model, const Eigen::Isometry3d& T_world_tcp,
                           const Configuration& config, const Eigen::VectorXd& seed,
                           const IkOptions& options, double payload_kg = 0);
IkResult inverseKinematics(const RobotModel& model, const Eigen::Isometry3d& T_world_tcp,
                           const Configuration& config, const Eigen::VectorXd& seed,
                           const IkOptions& options, const PoseContext& context);

/// Discrete compensation of one pose: q' = IK_real(desired), command = FK_controller(q').
/// The controller's own IK, asked for `command` with `configuration`, returns q', so the
/// real robot lands on the desired pose. Once within the IK tolerance, q' is polished (a few
/// more Newton steps while they gain) to about 1e-9 mm and 1e-12 rad, so that the command is
/// the exact solution far below any printed resolution: the same output on every machine.
struct PoseCompensation {
  IkStatus status = IkStatus::kNotConverged;
  std::string message;
  Eigen::Isometry3d T_world_tcp_command = Eigen::Isometry3d::Identity();
  Eigen::VectorXd q_real;            ///< joints that put the real tool on the desired pose
  /// S/T of q_real: what the program must carry with the command.
  Configuration configuration;
  /// The program asked for a configuration (`config`, where not -1) that q_real does not
  /// have: the compensation moves the target across a configuration boundary (next to a
  /// singularity). status is still kOk and the result valid with `configuration`; report it.
  bool configuration_changed = false;
  double correction_mm = 0;          ///< |command - desired| position
  double correction_deg = 0;         ///< rotation angle between command and desired
};
/// Throws ArgumentError for invalid options, a seed of the wrong size or models of different
/// joint counts.
PoseCompensation compensatePose(const RobotModel& controller, const RobotModel& real,
                                const Eigen::Isometry3d& T_world_tcp_desired,
                                const Configuration& config, const Eigen::VectorXd& seed,
                                const IkOptions& options, double payload_kg = 0);

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

struct DensifyOptions {
  double tol_mm = 0.05;          ///< max predicted deviation of the real path (position)
  double sample_step_mm = 1.0;   ///< path sampling for the error prediction (see docs)
  double sample_step_deg = 0.5;  ///< the same for the orientation (pure reorientations)
  int max_points_per_segment = 500;
  IkOptions ik;
  bool IsValid(std::string* error) const;
};

/// A continuous segment, compensated: `commanded` are the sub-segments to send, in order
/// (commanded.front().T_world_start is the compensated start, each T_world_end the
/// compensated end or auxiliary point; for CIRC each sub-segment has its own aux).
struct SegmentCompensation {
  IkStatus status = IkStatus::kNotConverged;
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
  Compensator(const RobotModel& controller, const RobotModel& real);
  const KinematicSolver& controller() const { return controller_; }
  const KinematicSolver& real() const { return real_; }

  /// compensatePose. `seed`: the real joint values of the previous point (empty: none); the
  /// real model is evaluated in `context`, the controller in a default context.
  PoseCompensation pose(const Eigen::Isometry3d& T_world_tcp_desired, const Configuration& config,
                        const Eigen::VectorXd& seed, const IkOptions& options,
                        const PoseContext& context = {}) const;
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
  SegmentCompensation segment(const PathSegment& intended, const Configuration& config,
                              const Eigen::VectorXd& seed, const DensifyOptions& options,
                              const PoseContext& context = {}) const;
  /// The real tool poses when the controller executes `commanded` from joint values
  /// `q_controller_start` (see simulateExecution). Throws NumericalError when the controller
  /// cannot follow the path (unreachable, joint limits, singular).
  std::vector<Eigen::Isometry3d> execute(const std::vector<PathSegment>& commanded,
                                         const Eigen::VectorXd& q_controller_start, double step_mm,
                                         const PoseContext& context = {}) const;

 private:
  KinematicSolver controller_;
  KinematicSolver real_;
};

/// Simulated execution: the controller interpolates `commanded` (LIN: straight line and
/// slerp; CIRC: circle through start/aux/end, orientation interpolated), solves its own
/// (nominal) IK at every sample, keeping the configuration (nearest solution to the previous
/// sample, starting from q_start; empty q_start: the controller's solution nearest to the
/// middle of the joint ranges), and the real robot goes there. Returns the real tool poses
/// at both ends of every segment and at most `step_mm` (and 0.5 deg of orientation) apart.
/// Throws NumericalError when the controller cannot follow the path.
std::vector<Eigen::Isometry3d> simulateExecution(const RobotModel& controller,
                                                 const RobotModel& real,
                                                 const std::vector<PathSegment>& commanded,
                                                 const Eigen::VectorXd& q_start, double step_mm,
                                                 double payload_kg = 0);

/// Largest distance (mm) from the sampled poses' positions to the intended path (the union
/// of the intended segments' curves: line segments and circular arcs). Throws ArgumentError
/// when `intended` is empty.
double maxPathDeviation(const std::vector<Eigen::Isometry3d>& samples,
                        const std::vector<PathSegment>& intended);

/// Distance (mm) from a point to one segment's curve.
double distanceToPath(const Eigen::Vector3d& p_world, const PathSegment& segment);

}  // namespace accura::postproc
