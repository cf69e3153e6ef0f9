// accura: the robot definition (nominal data read from robots/*.xml) and the complete
// kinematic model (nominal data plus identified deviations).
//
// Link transform of joint i (1-based), from frame i-1 to frame i:
//   DH form:     A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)            (Paul 1981)
//   Hayati form: A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i) Ry(beta_i)  (beta nominal 0)
//   revolute:  theta_i = theta0_i + direction_i * q_i + dtheta_i,  d_i = d0_i + dd_i
//   prismatic: theta_i = theta0_i + dtheta_i,  d_i = d0_i + direction_i * q_i + dd_i
// In the Hayati form the nominal d_i is kept as a constant and its error is not a parameter
// (it is replaced by beta_i); at nominal both forms give exactly the same transform.
// Tool pose in the world: T_world_tcp = T_world_base * A_1 ... A_n * T_flange_tcp.
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "accura/calib/geometry.h"

namespace accura::calib {

enum class JointType { kRevolute, kPrismatic };
enum class LinkForm { kDH, kHayati };

/// One joint and the link it moves, as in the robot file.
struct JointSpec {
  std::string name;
  JointType type = JointType::kRevolute;
  double a_mm = 0;
  double alpha_deg = 0;
  double d_mm = 0;
  double theta0_deg = 0;
  int direction = 1;          ///< +1 or -1: sign between q (controller) and theta / d
  double lower = 0;           ///< joint limit on q: deg (revolute) or mm (prismatic)
  double upper = 0;
  double mass_kg = 0;         ///< mass of link i (moved by joint i)
  Eigen::Vector3d com_mm = Eigen::Vector3d::Zero();  ///< centre of mass in DH frame i
};

/// Nominal robot, as read from a robot file.
struct RobotDefinition {
  std::string name;
  std::string source;  ///< where the data comes from (free text)
  std::vector<JointSpec> joints;
  Eigen::Isometry3d T_world_base = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_flange_tcp = Eigen::Isometry3d::Identity();
  Eigen::Vector3d payload_com_mm = Eigen::Vector3d::Zero();  ///< in the flange frame
  /// Gravity in the robot base frame (m/s^2): the mounting (floor, wall, ceiling) is a
  /// property of the installation, independent of where a tracker stands.
  Eigen::Vector3d gravity_base = Eigen::Vector3d(0, 0, -9.80665);

  int dof() const { return static_cast<int>(joints.size()); }
};

/// Angle between consecutive joint axes below which the Hayati form is used (deg).
/// Link i (1 <= i < n) uses Hayati when the angle between z_{i-1} and z_i, i.e. alpha_i
/// taken modulo 180 deg, is below this threshold. The last link always uses DH: its d is the
/// flange distance, which is well defined.
constexpr double kHayatiThresholdDeg = 2.0;

/// Form selection for a whole robot.
enum class FormPolicy {
  kAuto,    ///< Hayati for (nearly) parallel consecutive axes, DH elsewhere (the default)
  kDHOnly,  ///< classic DH everywhere (only to demonstrate its ill-conditioning)
};

/// The forms chosen for each link under a policy.
std::vector<LinkForm> chooseLinkForms(const RobotDefinition& robot, FormPolicy policy);

/// Default number of harmonics of the gear_periodic effect (harmonics 1 and 2).
constexpr int kDefaultGearHarmonics = 2;
/// Largest number of harmonics of the gear_periodic effect.
constexpr int kMaxGearHarmonics = 4;
/// Reference temperature of the thermal effect (deg C): the link lengths of the robot file
/// (and their identified deviations) are the lengths at this temperature.
constexpr double kThermalReferenceC = 20.0;

/// joint_map: a per-joint 1-D error map over the joint's own value q (calib/joint_map.h).
/// A uniform cubic B-spline on the covered interval [lower, upper] (the range of q the fit
/// data cover; deg for a revolute joint, mm for a prismatic one) with `intervals` knot
/// intervals of width knot = (upper - lower) / intervals and intervals + 3 coefficients.
/// Outside the interval the map goes to zero: its value at the nearer end times a cosine taper
/// that falls from 1 to 0 over `taper` (same unit as q), zero beyond: continuous in q.
/// Empty (no coefficients) = no map on this joint.
struct JointMap {
  double lower = 0;          ///< start of the covered interval (deg or mm)
  double upper = 0;          ///< end of the covered interval (deg or mm)
  int intervals = 0;         ///< number of knot intervals (>= 1 when coef is not empty)
  double taper = 0;          ///< width of the taper to zero outside [lower, upper] (> 0)
  /// 360 (deg) for a revolute joint's map: a function of the joint's angle modulo one turn
  /// (q and q + 360 are the same angle of the gear and the encoder, so the map holds there
  /// too); then upper - lower <= period. 0: a function of q itself (prismatic joints, and maps
  /// of model files written before the period was, which have no `period` attribute).
  double period = 0;
  std::vector<double> coef;  ///< B-spline coefficients: rad (revolute) or mm (prismatic)
  bool empty() const { return coef.empty(); }
  double knot() const { return intervals > 0 ? (upper - lower) / intervals : 0.0; }
};

/// Range of a joint's values covered by the data a model was fitted on (deg or mm).
struct JointRange {
  double lower = 0, upper = 0;
};

/// Deviations of one link from nominal (internal units: mm, rad).
struct LinkDeviation {
  double dtheta_rad = 0;  ///< joint zero offset (revolute) / rotation about z (prismatic)
  double dd_mm = 0;       ///< DH d error (zero offset for prismatic joints)
  double da_mm = 0;
  double dalpha_rad = 0;
  double dbeta_rad = 0;   ///< Hayati beta (only in the Hayati form)
};

/// Every deviation the complete model can carry. Zero everywhere = the nominal robot.
/// Base and tool deviations are right-multiplied corrections:
///   T_world_base = T_world_base_nominal * Trans(base_mm) * Exp(base_rot_rad)
///   T_flange_tcp = T_flange_tcp_nominal * Trans(tool_mm) * Exp(tool_rot_rad)
struct Deviations {
  Eigen::Vector3d base_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d base_rot_rad = Eigen::Vector3d::Zero();  ///< rotation vector
  Eigen::Vector3d tool_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d tool_rot_rad = Eigen::Vector3d::Zero();  ///< rotation vector
  std::vector<LinkDeviation> links;                        ///< one per joint
  /// Joint compliance c_i: dtheta_i = c_i * tau_i (rad per N*m; for a prismatic joint
  /// dd_i = c_i * f_i, mm per N), tau_i the gravity torque about axis i (see gravityLoads).
  std::vector<double> compliance;

  // The effect catalogue beyond geometry and compliance (docs/diagnosis.md). Every term is
  // added to the DH angle theta_i of a revolute joint, or to d_i of a prismatic one.
  /// Number of harmonics H of gear_periodic (per joint 2H values below).
  int gear_harmonics = kDefaultGearHarmonics;
  /// gear_periodic: dtheta_i = sum_{h=1..H} (gear_sin[i*H+h-1] sin(h q_i) +
  /// gear_cos[i*H+h-1] cos(h q_i)), q_i in rad (rad; revolute joints only, zero and not a
  /// parameter for prismatic joints).
  std::vector<double> gear_sin, gear_cos;
  /// joint_scale: dtheta_i = k_i q_i (q_i in rad; prismatic: dd_i = k_i q_i, q_i in mm);
  /// dimensionless (gear ratio or encoder scale error).
  std::vector<double> joint_scale;
  /// backlash: dtheta_i = (b_i / 2) dir_i, dir_i = +1/-1 the approach direction of the pose
  /// (PoseContext::dir); b_i the full width (rad; mm for prismatic joints).
  std::vector<double> backlash;
  /// thermal: the link lengths a_i and d_i (nominal plus deviation; for a prismatic joint the
  /// constant part of d_i) scale by (1 + thermal_alpha * (temp_c - kThermalReferenceC)),
  /// 1/K; one coefficient for the whole arm. Base and tool are not scaled.
  double thermal_alpha_per_k = 0;
  /// joint_map: dtheta_i = m_i(q_i) (rad; prismatic: dd_i = m_i(q_i), mm), one JointMap per
  /// joint (empty when the joint has none). See JointMap and calib/joint_map.h.
  std::vector<JointMap> joint_map;
  /// The joint ranges of the data the model was fitted on (one per joint; empty when not
  /// known, e.g. a nominal robot). Informative: written in the model file so that users of the
  /// model can tell when a pose lies outside what the fit saw.
  std::vector<JointRange> fit_range;

  /// Zero deviations sized for `dof` joints and `gear_harmonics` harmonics (1..4).
  static Deviations zero(int dof, int gear_harmonics = kDefaultGearHarmonics);
  /// True when an effect beyond the geometry is not zero: joint compliance, gear_periodic,
  /// joint_scale, backlash, thermal, a joint map (what no controller runs).
  bool hasEffectsBeyondGeometry() const;
};

/// The complete model: nominal definition, link forms, deviations. Immutable once built;
/// per-thread scratch space lives in KinematicWorkspace (kinematics.h).
struct RobotModel {
  RobotDefinition nominal;
  std::vector<LinkForm> forms;
  Deviations deviations;

  /// The nominal model of a robot (zero deviations) with forms chosen by `policy`.
  static RobotModel fromDefinition(const RobotDefinition& robot,
                                   FormPolicy policy = FormPolicy::kAuto);
  int dof() const { return nominal.dof(); }
  /// Calibrated T_world_base and T_flange_tcp (nominal with base/tool deviations applied).
  Eigen::Isometry3d T_world_base() const;
  Eigen::Isometry3d T_flange_tcp() const;
  /// Throws ArgumentError when sizes disagree (forms, links, compliance, effect vectors vs
  /// dof and gear_harmonics) or gear_harmonics is outside 1..kMaxGearHarmonics.
  void validate() const;
};

}  // namespace accura::calib
