// accura post-processor: reach and clearance checks of a program in its cell
// (docs/checks.md: what is checked, how the paths are sampled and why nothing between the
// samples can be missed).
//
// For every programmed point and sampled along every LIN / CIRC path (and every PTP, in joint
// space, for the clearance):
//   reach        IK on the calibrated (real) model: the point must be reachable
//   joint_limit  every joint at least CheckThresholds::joint_margin_deg inside its limits
//   singularity  smallest singular value of the scaled joint Jacobian (dimensionless, see
//                docs/checks.md) at least CheckThresholds::singular_threshold
//   clearance    distance between the robot (link and tool shapes of the cell) and every
//                cell object at least CheckThresholds::min_clearance_mm (FCL distance
//                queries on OBBRSS bounding-volume hierarchies)
// and reports the first violation of each check on each motion.
//
// Units: mm and deg; frames as in job.h (world = the calibrated model's world = the cell).
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

#include "accura/calib/kinematics.h"
#include "accura/calib/robot.h"
#include "accura/postproc/cell.h"
#include "accura/postproc/compensate.h"
#include "accura/postproc/job.h"
#include "accura/postproc/program.h"

namespace accura::postproc {

/// Which joint values the robot takes at the program's points.
enum class CheckMode {
  /// The program's targets are where the tool must go (an OLP program, before compensation):
  /// q = IK of the calibrated model. This is what the robot does when it runs the
  /// compensated program (accura compensate), to within the compensation's path tolerance.
  kIntended,
  /// The program is run as written (e.g. a program already compensated): the controller
  /// solves its nominal IK, q = IK_controller(target), and the real robot's geometry is placed
  /// at those joints with the calibrated model.
  kAsWritten,
};
const char* toString(CheckMode mode);

struct CheckOptions {
  CheckThresholds thresholds;
  CheckMode mode = CheckMode::kIntended;
  /// Uniform pre-sampling of LIN / CIRC paths for reach, joint limits and singularities:
  /// samples at most this far apart (mm of TCP path, deg of tool rotation), and so that no
  /// joint moves more than max_joint_step_deg between two samples (more samples are inserted
  /// where it does). The clearance subdivides further as needed (docs/checks.md).
  double sample_step_mm = 1.0;
  double sample_step_deg = 0.5;
  double max_joint_step_deg = 0.5;
  /// Clearance between two samples is proven down to min_clearance_mm - resolution_mm: the
  /// subdivision stops when the motion bound between two samples is below this (mm).
  double resolution_mm = 0.01;
  /// Safety factor on the motion bound for Cartesian (LIN / CIRC) paths, whose joint path
  /// between two samples is curved (docs/checks.md). >= 1.
  double cartesian_bound_factor = 1.25;
  /// Distances of at least min_clearance_mm + exact_band_mm (mm) are computed only as far as
  /// needed: a lower bound that is itself at least that (a bounded FCL query: docs/checks.md,
  /// "Distance queries"), made exact on demand where the subdivision's proof needs more. The
  /// violations, the samples and the subdivision are those of exact distances; the per-motion
  /// smallest clearance is a lower bound when it is above the band. > 0; infinity: every
  /// distance exact (the unbounded FCL query).
  double exact_band_mm = 100.0;
  /// False (and why in *error, which may be null) when an option is out of range.
  bool IsValid(std::string* error) const;
};

enum class CheckKind { kReach, kJointLimit, kSingularity, kClearance };
/// "reach", "joint_limit", "singularity", "clearance".
const char* toString(CheckKind kind);

/// The first violation of one check on one motion.
struct CheckViolation {
  CheckKind kind = CheckKind::kReach;
  int motion_index = 0;        ///< 0-based index in Program::motions (or in the motions given)
  SourceLocation where;        ///< of the motion statement
  std::string motion_type;     ///< PTP, LIN, CIRC, SPTP, ...
  bool on_path = false;        ///< between the motion's start and its end (else: at the end point)
  double s = 1;                ///< path parameter in [0, 1] (LIN: fraction of the length;
                               ///< CIRC: of the arc angle; PTP: of the joint motion)
  double arc_mm = 0;           ///< TCP path length from the motion's start (mm; PTP: the chord)
  Eigen::Vector3d p_world_tcp_mm = Eigen::Vector3d::Zero();  ///< TCP position (world)
  Eigen::VectorXd q;           ///< joint values (deg / mm); empty when unreachable
  /// The measured quantity and its threshold, in `unit`:
  ///   reach: the IK status message, value = limit = 0
  ///   joint_limit: value = the joint's distance from its nearest limit (deg / mm; negative
  ///                outside the limits), limit = joint_margin_deg, `joint` set
  ///   singularity: value = sigma_min, limit = singular_threshold ("" : dimensionless)
  ///   clearance: value = distance (mm; 0 in contact), limit = min_clearance_mm
  double value = 0, limit = 0;
  double excess = 0;           ///< by how much: limit - value (> 0)
  std::string unit;
  int joint = -1;              ///< joint_limit: 0-based joint index
  std::string robot_part;      ///< clearance: the robot shape ("link 3", "tool")
  std::string obstacle;        ///< clearance: the cell object
  std::string message;         ///< one line for people
};

/// What was checked on one motion.
struct MotionCheck {
  int motion_index = 0;
  SourceLocation where;
  std::string motion_type;
  bool checked = false;        ///< false: could not be evaluated (see note)
  std::string note;
  int samples = 0;             ///< configurations evaluated (IK solves and distance sets)
  double length_mm = 0;        ///< TCP path length
  double min_clearance_mm = 0; ///< smallest distance at the samples (inf without geometry)
  double min_sigma = 0;        ///< smallest sigma_min at the samples (LIN/CIRC and end points)
  double min_joint_margin = 0; ///< smallest distance of a joint from its limits (deg / mm)
};

struct CheckReport {
  CheckMode mode = CheckMode::kIntended;
  CheckThresholds thresholds;
  std::vector<CheckViolation> violations;  ///< in program order; per motion ordered by s
  std::vector<MotionCheck> motions;        ///< one per motion of the program
  std::vector<ProgramIssue> unchecked;     ///< motions that could not be checked, and why
  std::vector<ProgramIssue> warnings;
  int samples = 0;                         ///< configurations evaluated in all
  long long distance_queries = 0;          ///< FCL distance calls
  double min_clearance_mm = 0;             ///< over all samples (inf without geometry)
  double min_sigma = 0;
  double min_joint_margin = 0;
  /// No violation and every motion checked.
  bool passed() const { return violations.empty() && unchecked.empty(); }
};

/// The robot geometry of a cell against its objects, prepared for repeated distance queries
/// (FCL BVHs of OBBRSS). Immutable after construction; queries are const but not
/// thread-safe (they share a kinematics workspace): one per thread. A copy is cheap and shares
/// the FCL geometry (read only; building the BVHs is the costly part: about 330 ms for 100k
/// triangles), so copies of one CellGeometry may be used by several threads at once.
class CellGeometry {
 public:
  /// Throws InputError (the cell file, line and column of the <link>'s joint attribute) when a
  /// link shape read from a cell file names a frame outside 1..robot.dof(), ArgumentError for
  /// such a shape of a Cell built in code.
  CellGeometry(const Cell& cell, const calib::RobotModel& robot);
  ~CellGeometry();
  CellGeometry(const CellGeometry&);
  CellGeometry(CellGeometry&&) noexcept;
  CellGeometry& operator=(CellGeometry&&) noexcept;

  /// True when this geometry was made for `robot` (the same joint count and the same frames
  /// to 1e-9 mm and 1e-9 rad at the middle of the joint ranges) and for a cell with these
  /// numbers of robot shapes and objects.
  bool madeFor(const Cell& cell, const calib::RobotModel& robot) const;

  /// Number of robot shapes (links and tool) and of cell objects.
  int robotShapes() const;
  int objects() const;
  const std::string& robotShapeName(int k) const;
  const std::string& objectName(int k) const;

  struct Distance {
    double mm = 0;        ///< >= 0; 0 in contact or penetrating
    int robot_shape = -1; ///< which robot shape and which object (-1: none)
    int object = -1;      ///< the nearest object (lower_bound: the one that gave the bound)
    /// mm is only a lower bound of the distance (then mm >= the exact_below_mm asked for).
    bool lower_bound = false;
  };
  /// Distance of each robot shape to the nearest object with the robot at joint values q
  /// (world frame from robot's forwardKinematics; the tool in the flange frame). Below
  /// `exact_below_mm` the distance is exact (the same value as an unbounded query); a distance
  /// of at least exact_below_mm may be replaced by a lower bound no smaller than exact_below_mm
  /// (lower_bound set): the distance of bounding volumes, or exact_below_mm itself when FCL's
  /// traversal, started from that distance instead of infinity, found nothing nearer (the
  /// bounded query: it prunes every bounding volume at least that far). Infinity: every
  /// distance exact. Returns per robot shape. `queries` (may be null) is increased by the
  /// number of FCL distance calls.
  std::vector<Distance> distances(const Eigen::VectorXd& q, const calib::PoseContext& context, double exact_below_mm,
                                  long long* queries = nullptr) const;
  /// The same for one robot shape (0 <= robot_shape < robotShapes(); ArgumentError otherwise).
  Distance distance(int robot_shape, const Eigen::VectorXd& q, const calib::PoseContext& context, double exact_below_mm,
                    long long* queries = nullptr) const;

  /// The bound used by the subdivision (docs/checks.md): for each robot shape, the largest
  /// distance (mm) any of its points can move when joint i moves by delta[i] (rad for revolute
  /// joints, mm for prismatic) is sum_i |delta[i]| * leverArm(shape, i); leverArm is 0 for
  /// joints that do not move the shape, 1 for a prismatic joint, and for a revolute joint an
  /// upper bound of the distance of the shape's points from the joint's axis in every
  /// configuration (mm).
  double leverArm(int robot_shape, int joint) const;

  /// Distance between one world-placed sphere and each object (exact, FCL): for tests.
  double sphereDistance(const Eigen::Vector3d& center_world_mm, double radius_mm, int object) const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

/// One motion to check, with its poses in the world (the form a CAD host or the plug-in
/// has). PTP motions with `q_end` set are axis targets.
struct WorldMotion {
  MotionType type = MotionType::kPtp;
  Eigen::Isometry3d T_world_tcp_end = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_world_tcp_aux = Eigen::Isometry3d::Identity();  ///< CIRC
  Eigen::VectorXd q_end;               ///< axis target (deg / mm); empty for a Cartesian one
  calib::Configuration configuration;         ///< S/T of a Cartesian end point (-1: any)
  /// Joints (deg / mm) whose nearest solution the controller takes for a Cartesian PTP end
  /// point (URScript get_inverse_kin's qnear); empty: the previous point's joints decide.
  Eigen::VectorXd q_near;
  Eigen::Isometry3d T_flange_tcp = Eigen::Isometry3d::Identity();  ///< tool of the motion
  SourceLocation where;
  std::string label;                   ///< motion type for reports (LIN, SLIN, ...)
};

/// Checks motions given in the world. `real`: the calibrated model (its tool is replaced by
/// each motion's T_flange_tcp unless that equals the real model's nominal tool within 1e-3 mm
/// and 1e-3 deg, in which case the calibrated tool is kept); `controller`: the nominal model
/// at the nominal base (used in CheckMode::kAsWritten; its tool is replaced likewise). The
/// first motion starts at its end point (no path before it). Throws ArgumentError for invalid
/// options or models of different joint counts, or a link shape outside 1..dof.
CheckReport checkMotions(const calib::RobotModel& real, const calib::RobotModel& controller, const Cell& cell,
                         const std::vector<WorldMotion>& motions, const CheckOptions& options,
                         const calib::PoseContext& context = {});

/// Checks a program (KRL or XML, program.h) in its cell: its targets are taken to the world
/// with the frames of `job` exactly as compensateProgram does (robot placement: the cell's
/// T_world_base when job.robroot_in_world is empty; $ROBROOT, $BASE, $TOOL, initial tool and
/// base); the controller is the nominal model of job.calibrated at that placement; the real
/// robot is job.calibrated. Motions that cannot be evaluated (unknown frames, run-time
/// targets, relative motions) go to CheckReport::unchecked. Throws InputError when the cell's
/// robot placement and job.robroot_in_world disagree (more than 1e-3 mm / deg) or the
/// calibrated base is further from the placement than job.max_base_offset_mm / _deg;
/// ArgumentError as checkMotions.
CheckReport checkProgram(const Program& program, const JobSettings& job, const Cell& cell, const CheckOptions& options);

/// The same with the cell's geometry prepared once for many programs (accura batch: the BVHs
/// are built once, not per program): `geometry` must be CellGeometry(cell, job.calibrated)
/// (ArgumentError otherwise, see CellGeometry::madeFor); it is copied, so one may serve several
/// threads at once. The report is the same as without it.
CheckReport checkProgram(const Program& program, const JobSettings& job, const Cell& cell, const CheckOptions& options,
                         const CellGeometry& geometry);

}  // namespace accura::postproc
