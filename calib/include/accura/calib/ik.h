// accura: inverse kinematics of the complete model on the kinematic core (kinematic_core.h):
// closed-form seeds of the nominal geometry (all branches), Newton's method on the complete
// model, the path workspace and its singularity certificate, KUKA Status / Turn. The method
// and the tolerances: docs/compensation.md.
//
// Frames: every pose here is T_world_tcp in the world (cell) frame. Joint values: deg
// (revolute), mm (prismatic). The state of the arm besides q (payload, temperature, approach
// directions) is a PoseContext; the overloads taking `double payload_kg` use a default context
// with that payload.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

#include "accura/calib/kinematic_core.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/robot.h"

namespace accura::calib {

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

/// What differs between the configuration `asked` and `actual`, said as the arm's posture for
/// users of any controller (an ABB or UR user does not read KUKA's bits): e.g. "the wrist flip
/// (the sign of joint 5), the sign of joint 1". Only parts `asked` specifies (not -1); empty when they
/// match. Never throws but std::bad_alloc.
std::string configurationDifference(const Configuration& asked, const Configuration& actual);

/// The configuration `actual` said against the one `asked` for, KUKA's numbers and then the
/// posture: "S 6 T 25, not with the configuration asked for (S 2): it differs in the wrist flip
/// (the sign of joint 5)". A part `asked` leaves open (-1) is not written. The IK's and the
/// compensation's messages put it after "reached with " and "reachable only with ". Never
/// throws but std::bad_alloc.
std::string configurationMismatch(const Configuration& asked, const Configuration& actual);

/// Joints within this band of 0 (deg) may flip their Turn bit by a correction: the same arm
/// posture, and the controller needs the new sign to find the joints.
constexpr double kTurnBandDeg = 1.0;
/// A joint this close (deg) to 0 or to a quadrant boundary has either sign (quadrant) at the
/// precision a program writes its poses (1e-3 mm at a metre's reach is 6e-5 deg): a written
/// Turn bit or ABB cf1/cf4/cf6 that differs from the solution's only there still holds.
constexpr double kJointAtBoundaryDeg = 1e-5;
/// True when `actual` (the configuration of joints `q`, deg) differs from `asked` only in Turn
/// bits of joints within `band_deg` of 0: the Status (when asked) equal, every other Turn
/// bit asked for equal. False when they match exactly (nothing differs) or differ otherwise.
bool onlyTurnBitsNearZeroDiffer(const Configuration& asked, const Configuration& actual, const Eigen::VectorXd& q,
                                double band_deg = kTurnBandDeg);

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
/// Its forward kinematics is the kinematic core's (kinematic_core.h), the same as
/// forwardKinematics. Throws ArgumentError for an invalid model. Immutable: const methods
/// may be called from several threads at once.
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

  /// T_world_tcp at q, equal to forwardKinematics. Throws ArgumentError on a size
  /// mismatch.
  Eigen::Isometry3d forward(const Eigen::VectorXd& q_deg_mm, const PoseContext& context = {}) const;
  /// Joint Jacobian (as jointJacobian) and T_world_tcp.
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
  /// Path following without allocation: the same solve as inverse(T_world_tcp, config, q,
  /// options, context, workspace), seeded with `q` (dof values; empty: cold). On kOk `q`
  /// becomes the solution (the workspace holds it, so the next call seeded with it starts
  /// from its frames); otherwise `q` is left as it was and `*answer`, when given, receives
  /// the whole answer (status, message, a solution on another configuration, ...). Returns
  /// the status. Throws as inverse().
  IkStatus follow(const Eigen::Isometry3d& T_world_tcp, const Configuration& config, Eigen::VectorXd& q,
                  const IkOptions& options, const PoseContext& context, IkWorkspace& workspace,
                  IkResult* answer = nullptr) const;

  /// Every closed-form solution of the nominal links (with this model's base and tool)
  /// within the joint limits, each joint on every representation within its limits (so a
  /// +-360 deg joint gives two): what seeds inverse(). Empty for closedForm() == "none" or
  /// when the nominal links cannot reach the pose. For a model without deviations beyond
  /// base and tool these are its exact solutions.
  std::vector<Eigen::VectorXd> closedFormSolutions(const Eigen::Isometry3d& T_world_tcp) const;

  /// inverse(), then, once within the tolerance, polished: up to a few more Newton steps
  /// while they gain, towards polish_mm / polish_rad (the post-processor's compensatePose
  /// polishes to about 1e-9 mm and 1e-12 rad so that its output is the same on every
  /// machine). polish_mm <= 0: no polishing.
  IkResult inversePolished(const Eigen::Isometry3d& T_world_tcp, const Configuration& config,
                           const Eigen::VectorXd& seed, const IkOptions& options, const PoseContext& context,
                           double polish_mm, double polish_rad, IkWorkspace* workspace = nullptr) const;

  /// The prepared complete model this solver evaluates (kinematic_core.h).
  const KinematicModel& kinematicModel() const;

  struct Impl;

 private:
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

}  // namespace accura::calib
