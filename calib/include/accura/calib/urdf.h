// accura: robot models from and to URDF (ROS, MoveIt, simulators, the vendors' description
// packages), and the conversion of any serial chain of joint frames into accura's complete
// model (robot.h). docs/robot-format.md, section "URDF", describes the rules.
//
// Units: a SerialChain is in accura's units (mm, deg for joint values and limits, rad inside
// transforms); URDF files are in metres and radians.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "accura/calib/robot.h"

namespace accura::calib {

/// One moving joint of a serial chain, the way a URDF (or UR's calibration) describes it:
/// a constant transform to the joint frame, then a motion along / about a unit axis given in
/// that joint frame.
struct ChainJoint {
  std::string name;
  JointType type = JointType::kRevolute;
  /// From the frame of the previous moving joint (after its motion), or from the chain's root
  /// for the first joint, to this joint's frame at q = 0 (mm). Fixed joints in between are
  /// folded in.
  Eigen::Isometry3d T_prev_joint = Eigen::Isometry3d::Identity();
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  ///< unit vector in the joint frame
  double lower = -360;  ///< limits on q: deg (revolute) or mm (prismatic)
  double upper = 360;
  /// Mass (kg) rigidly moved by this joint up to the next moving joint, and its centre of mass
  /// in this joint's frame after the motion (mm).
  double mass_kg = 0;
  Eigen::Vector3d com_mm = Eigen::Vector3d::Zero();
  int line = 0;    ///< line of the joint in its source file (0 when unknown), for errors
  int column = 0;  ///< and its column there (0 when unknown)
};

/// A serial chain: T_root_tip(q) = T_prev_joint_1 M_1(q_1) T_prev_joint_2 M_2(q_2) ...
/// M_n(q_n) T_last_tip, with M_k a rotation of q_k (deg) about axis_k (revolute) or a
/// translation of q_k (mm) along it (prismatic).
struct SerialChain {
  std::string name;         ///< robot name
  std::string source;       ///< file the chain came from (for errors and the model's source)
  std::string root_link, tip_link;
  std::vector<ChainJoint> joints;
  Eigen::Isometry3d T_last_tip = Eigen::Isometry3d::Identity();  ///< mm
};

/// T_root_tip of the chain at q (deg / mm), composed joint by joint as written above; an
/// implementation independent of accura's DH kinematics, used to check conversions.
/// Throws ArgumentError when q.size() differs from the number of joints.
Eigen::Isometry3d serialChainFK(const SerialChain& chain, const Eigen::VectorXd& q_deg_mm);

/// Tolerances of the check made by modelFromChain.
constexpr double kChainCheckTolMm = 1e-9;     ///< position of the tip (mm)
constexpr double kChainCheckTolRad = 1e-12;   ///< orientation of the tip (rad)

/// Converts a serial chain into accura's complete model. Frame 0 lies on the first axis
/// (its origin the foot of the perpendicular from the chain root's origin, x from the root's
/// x), link i uses DH when axes i and i+1 make an angle of kHayatiThresholdDeg or more and the
/// Hayati form (d = 0, extra Ry(beta) in the deviations) when they are nearly parallel, the
/// last link always DH with its x taken from the tip's; T_world_base (world = the chain's
/// root) and T_flange_tcp take what is left. Tiny round-off (|v| < 1e-12 mm or deg) is set to 0.
///
/// With `reference` (a nominal robot of the same structure), the result is that robot plus
/// deviations instead: same names, limits, masses, forms and directions; the chain's geometry
/// goes into the base, link (dtheta, dd, da, dalpha, dbeta) and tool deviations, with d of
/// the Hayati links kept at the reference's.
///
/// The result is checked: forwardKinematics of the model equals serialChainFK on 64
/// pseudo-random joint vectors within the limits to kChainCheckTolMm / kChainCheckTolRad,
/// else NumericalError naming the largest difference. Throws ArgumentError for an empty chain,
/// a joint count differing from the reference's, a joint turning the other way than the
/// reference's, or a non-last link whose reference form is DH but whose axes are parallel.
/// `policy` kDHOnly forces DH on every link (only to write DH tables such as UR's deltas,
/// which is ill-conditioned for nearly parallel axes and fails for exactly parallel ones).
/// `tol_mm`: the position tolerance of the check for a chain that stays within a metre of its
/// base frame, scaled by its extent in metres beyond (rounding is relative; the rotation's is
/// the scaled tol_mm * 1e-3 rad/mm);
/// looser only for chains whose own numbers are ill-conditioned (UR's DH deltas: lengths of
/// tens of metres that cancel, 1e-6 mm).
RobotModel modelFromChain(const SerialChain& chain, const RobotDefinition* reference = nullptr,
                          FormPolicy policy = FormPolicy::kAuto, double tol_mm = kChainCheckTolMm);

/// Largest tip position difference (mm) and rotation difference (rad) between the model and
/// the chain over `samples` pseudo-random joint vectors within the limits (seeded, repeatable).
struct ChainComparison {
  double max_position_mm = 0;
  double max_rotation_rad = 0;
};
ChainComparison compareModelWithChain(const RobotModel& model, const SerialChain& chain,
                                      int samples = 64);

/// Reads the serial chain `chain_spec` ("root_link:tip_link"; empty: the default, see
/// docs/robot-format.md) of a URDF file. The file is parsed twice: with tinyxml2, to check it
/// and to give file:line:column for every error (malformed XML, missing or non-numeric attributes,
/// unknown link names, a link with two parents, an unexpanded xacro source, ...), then with urdfdom, whose model gives
/// the data. Fixed joints are folded into their neighbours; continuous joints get the limits
/// -360..360 deg. Throws InputError (file:line:column) on a malformed file, an unknown link in
/// chain_spec, a mimic, floating or planar joint on the chain, a moving joint branching off
/// a link that a chain joint other than the last moves, or limits with lower >= upper. What the
/// last joint carries beyond the chain (gripper fingers on any joints) is its load (mass_kg,
/// com_mm), those joints at zero.
SerialChain readUrdfChain(const std::string& path, const std::string& chain_spec = "");
/// The same for URDF text in memory; `file_name` is used in the error messages.
SerialChain parseUrdfChain(const std::string& urdf_text, const std::string& file_name,
                           const std::string& chain_spec = "");

/// readUrdfChain + modelFromChain: the robot model of a URDF. The model's name is the URDF's
/// robot name, its source names the file and chain.
RobotModel readUrdfRobot(const std::string& path, const std::string& chain_spec = "");

/// A model as URDF text.
struct UrdfText {
  std::string text;
  /// What URDF cannot hold and the text therefore leaves out (one line each; also written as an
  /// XML comment at the top of the text). Empty when the URDF holds the whole model.
  std::vector<std::string> not_represented;
};

/// The calibrated geometry of `model` as URDF: links world -> base_link (fixed, T_world_base)
/// -> one link per joint (joint origin = the calibrated DH/Hayati link transform of the
/// previous link, axis +-z) -> flange (DH frame n, fixed) -> tool0 (fixed, T_flange_tcp).
/// Joint names are the model's; limits, masses and centres of mass are carried over. What URDF
/// cannot hold (compliance, gear_periodic, joint_scale, backlash, thermal, gravity direction,
/// payload centre of mass, the missing inertia tensors and effort / velocity limits) is listed.
/// The text is checked: read back (readUrdfRobot), its FK equals the model's to
/// kChainCheckTolMm, else NumericalError. Throws ArgumentError on an invalid model.
UrdfText modelToUrdf(const RobotModel& model);

}  // namespace accura::calib
