// accura: Universal Robots' per-arm factory calibration, in and out.
//
// The controller keeps DH deltas per joint (calibration.conf, section [mounting]: delta_theta,
// delta_a, delta_d, delta_alpha; also sent with the nominal DH by the KinematicsInfo message).
// UR's formula, in the controller's Base frame (= DH frame 0; ROS 'base', i.e. 'base_link'
// turned 180 deg about z) to the tool flange:
//   T_base_flange(q) = prod_i Rz(q_i + dtheta_i) Tz(d_i + dd_i) Tx(a_i + da_i) Rx(alpha_i + dalpha_i)
// with the nominal a_i, d_i, alpha_i of the model and nominal theta_i = 0. DH cannot describe
// nearly parallel axes, so for joints 2-4 the deltas hold lengths of metres (tens of metres are
// common) that cancel. UR's ROS driver (ur_calibration) turns them into per-joint origins
// (x y z roll pitch yaw, metres and radians) that ur_description uses as URDF joint origins:
// the "kinematics" YAML.
//
// accura reads both into a calibrated model: the nominal UR robot (the bundled one, direction
// +1, theta0 0, or the arm read from a URDF in its own frames: urConventionOf) plus small
// deviations in its Hayati form, and writes the deltas back.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "accura/calib/robot.h"
#include "accura/calib/urdf.h"

namespace accura::calib {

/// Tolerance of the UR conversions' check (mm): the deltas' lengths of tens of metres cancel,
/// and their own rounding reaches 1e-8 mm.
constexpr double kUrCheckTolMm = 1e-6;

/// The most a factory calibration may move the flange from the nominal arm's (mm, deg; largest
/// over 64 joint vectors): a real one moves it by a few millimetres (tests/data/urdf's forum file:
/// up to about 5 mm on a UR10). More is another arm type's calibration (a UR5's on a UR10: about 400 mm) or a
/// corrupted file.
constexpr double kMaxUrFactoryCorrectionMm = 20.0;
constexpr double kMaxUrFactoryCorrectionDeg = 2.0;

/// DH deltas per joint, as in calibration.conf: rad and metres.
struct UrDeltas {
  std::vector<double> theta_rad, a_m, d_m, alpha_rad;  ///< one per joint each
};

/// Reads the [mounting] section of a UR calibration.conf. Throws InputError (file:line) on a
/// missing key, a list without exactly `dof` finite numbers, a key given twice.
UrDeltas readUrCalibrationConf(const std::string& path, int dof = 6);

/// The calibration.conf text ([mounting] with the four delta lists, 17 significant digits).
std::string formatUrCalibrationConf(const UrDeltas& deltas);

/// Throws ArgumentError unless `nominal` is a UR-style DH robot: revolute joints, direction
/// +1, theta0 0, identity base and tool, and as many joints as the deltas hold.
void checkUrNominal(const RobotDefinition& nominal, const UrDeltas* deltas = nullptr);

/// A robot's nominal DH table in UR's convention. UR's table has direction +1 and theta0 0 on
/// every joint and starts at the Base frame; a robot read from a URDF (or written otherwise) may
/// describe the same arm with joints turning about -z (direction -1), x axes of the other sign
/// (theta0 180 deg, a and alpha negated), a frame 0 turned about axis 1 (ROS's base_link is UR's
/// Base turned by 180 deg) or a flange turned about axis n. These are rewritten exactly:
///   T_frame0_flange(q) = T_frame0_urbase * T_urbase_urflange(q) * T_urflange_flange
/// with the robot's DH frame 0 and flange on the left and right and UR's table in the middle.
/// A theta0 within kMaxUrFactoryCorrectionDeg of 0 or 180 deg (a calibrated URDF's) is folded:
/// UR's table gets 0 and `folded_theta0_deg` the rest (a delta_theta); an alpha within
/// kUrAngleSnapDeg of a multiple of 90 deg (pi/2 rounded in a URDF, 1.570796327) is that multiple.
struct UrConvention {
  /// The table: direction +1, theta0 0, identity base and tool; the robot's names, limits,
  /// masses (centres of mass in the new frames), payload and gravity (in the new frame 0).
  RobotDefinition ur;
  Eigen::Isometry3d T_frame0_urbase = Eigen::Isometry3d::Identity();    ///< a rotation
  Eigen::Isometry3d T_urflange_flange = Eigen::Isometry3d::Identity();  ///< a rotation
  std::vector<double> folded_theta0_deg;  ///< one per joint
  bool rewritten = false;                 ///< whether the table differs from the robot's
};
constexpr double kUrAngleSnapDeg = 1e-6;

/// The robot's nominal in UR's convention. Throws ArgumentError naming the joint and the fix when
/// the chain cannot be written so exactly: a prismatic joint, a theta0 more than
/// kMaxUrFactoryCorrectionDeg from 0 and 180 deg on an inner link (or on the last one with a
/// non-zero a): not a UR arm's chain (choose the arm with --chain ROOT:TIP).
UrConvention urConventionOf(const RobotDefinition& nominal);

/// UR's formula above at q (deg): T_base_flange in mm.
Eigen::Isometry3d urFlangePose(const RobotDefinition& nominal, const UrDeltas& deltas, const Eigen::VectorXd& q_deg);

/// The serial chain of UR's formula (root = Base, tip = flange; mm).
SerialChain urDeltaChain(const RobotDefinition& nominal, const UrDeltas& deltas);

/// The calibrated accura model of a UR arm: `nominal` (the bundled robot, e.g. ur10.xml, or the
/// arm read from a URDF) with the deltas as deviations in its Hayati form (the lengths stay the
/// arm's real lengths), checked: FK equals T_world_base * T_frame0_urbase * (UR's formula on
/// urConventionOf(nominal).ur) * T_urflange_flange * T_flange_tcp to kUrCheckTolMm
/// (modelFromChain); a theta0 folded by urConventionOf is replaced by the delta. Throws
/// ArgumentError (urConventionOf; deltas that move the flange by more than
/// kMaxUrFactoryCorrectionMm / Deg from the nominal arm's), NumericalError when the check fails.
RobotModel modelFromUrDeltas(const RobotDefinition& nominal, const UrDeltas& deltas);

/// accura model -> UR deltas for the same nominal: the model's calibrated chain from DH frame 0
/// to the flange, in UR's convention (urConventionOf), rewritten in pure DH: the deltas are
/// relative to urConventionOf(model.nominal).ur (a folded theta0 is in delta_theta). `not_represented` lists what the deltas cannot hold
/// (the base deviation: where the Base stands in the measurement frame, not exported; the tool
/// deviation: set it in the TCP; the
/// effects beyond geometry; a near-parallel pair of axes, where DH needs a length above 1 m).
/// `max_difference_mm`: largest flange position difference between UR's formula with the
/// deltas and the model's flange chain over 64 random joint vectors.
struct UrDeltasFromModel {
  UrDeltas deltas;
  std::vector<std::string> not_represented;
  double max_difference_mm = 0;
  RobotDefinition table;         ///< the nominal table the deltas are relative to (urConventionOf)
  bool table_rewritten = false;  ///< whether it differs from the model's own nominal
};
UrDeltasFromModel urDeltasFromModel(const RobotModel& model);

/// ur_calibration's YAML ("kinematics:" then shoulder, upper_arm, forearm, wrist_1, wrist_2,
/// wrist_3, each with x y z roll pitch yaw, metres / radians; roll pitch yaw read as URDF rpy,
/// the way ur_description applies them). Reads the chain from Base to the flange. Block style
/// with any indentation (the first link's is the links'), a link as a flow mapping
/// ({x: 0, ...}), quoted numbers and a "---" document start are read; "hash" is skipped.
/// Throws InputError (file:line:column) on a missing, repeated or non-numeric entry, a tab in
/// the indentation, an unknown key.
SerialChain readUrCalibrationYaml(const std::string& path);

/// The same chain as a calibrated model of `nominal` (as modelFromUrDeltas; the same size check,
/// named by the path). ArgumentError naming the distance when the YAML's arm fits only with UR's
/// Base moved along axis 1 from `nominal`'s DH frame 0 (a URDF read from a root on a mount).
RobotModel modelFromUrCalibrationYaml(const RobotDefinition& nominal, const std::string& path);

/// The highest shoulder above UR's Base of any UR arm (mm): d1 is 89.2 (UR5) to 236.3 (UR20,
/// UR30); a YAML's shoulder z above this places the arm on whatever stood under the model's root.
constexpr double kMaxUrShoulderHeightMm = 300.0;

/// The YAML of a model's flange chain (DH frame 0 to the flange, in UR's convention:
/// urConventionOf), `not_represented` as in
/// urDeltasFromModel (plus a non-zero a or alpha of the last link, which the six entries cannot
/// hold). Throws ArgumentError for a model without 6 revolute joints, and for one whose shoulder
/// stands more than kMaxUrShoulderHeightMm from DH frame 0 along axis 1 (no UR arm's does: a root
/// on a mount, whose height the YAML's shoulder entry would add to the arm's own).
std::string formatUrCalibrationYaml(const RobotModel& model, std::vector<std::string>* not_represented);

}  // namespace accura::calib
