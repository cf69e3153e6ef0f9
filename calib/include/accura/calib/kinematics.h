// accura: forward kinematics, gravity loads and the analytic parameter Jacobian of the
// complete model (method.md sections 2-3).
//
// Style: a constant RobotModel and a per-thread KinematicWorkspace; free functions.
// Joint values q are what the controller reads: degrees (revolute) or mm (prismatic).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

#include "accura/calib/robot.h"

namespace accura::calib {

/// What the model needs to know about a measured pose besides q.
/// A default PoseContext is the reference state: no payload, the thermal reference
/// temperature (no expansion), approach directions unknown (no backlash term: the middle of
/// the backlash band).
struct PoseContext {
  double payload_kg = 0;                 ///< payload mass at the robot's payload centre of mass
  double temp_c = kThermalReferenceC;    ///< temperature of the arm (deg C), for `thermal`
  /// Approach direction of each joint, +1 or -1 (for `backlash`); empty when unknown.
  std::vector<int> dir;
};

class KinematicModel;

/// Scratch space for one thread. Sized on first use; reuse it across calls. It keeps the
/// model of the last call prepared (kinematic_core.h: twist cosines and sines, base, tool,
/// effect tables), so calls with the same RobotModel values skip the preparation; a
/// different model is detected by comparing its values. Copies start without it.
struct KinematicWorkspace {
  /// Frames 0..n in the base frame, deviations included (forwardKinematics, flangePose).
  std::vector<Eigen::Isometry3d> T_base_frame;
  Eigen::VectorXd theta_rad;                    ///< DH angles actually used
  Eigen::VectorXd d_mm;                         ///< DH d actually used
  Eigen::VectorXd load;                         ///< gravity torque (N*m) / force (N) per joint

  KinematicWorkspace();
  ~KinematicWorkspace();
  KinematicWorkspace(const KinematicWorkspace&);
  KinematicWorkspace& operator=(const KinematicWorkspace&);
  KinematicWorkspace(KinematicWorkspace&&) noexcept;
  KinematicWorkspace& operator=(KinematicWorkspace&&) noexcept;

  /// The prepared model for `model` (prepared now unless the last one is for equal values)
  /// and this thread's frames. Throws ArgumentError for an invalid model.
  struct Prepared;
  Prepared& prepare(const RobotModel& model);

 private:
  std::unique_ptr<Prepared> prepared_;
};

/// True when the two models have the same values in everything the kinematics reads
/// (nominal links, masses, base, tool, payload centre, gravity, forms, every deviation).
bool sameKinematics(const RobotModel& a, const RobotModel& b);

/// Gravity load on each joint at q (nominal geometry; link masses and payload_kg):
/// revolute joint i: torque (N*m) about axis z_{i-1} exerted by gravity on links i..n and
/// the payload; prismatic joint i: force (N) along z_{i-1}. Gravity is the robot's
/// gravity_base vector.
Eigen::VectorXd gravityLoads(const RobotModel& model, const Eigen::VectorXd& q_deg_mm,
                             const PoseContext& context);

/// T_world_tcp of the complete model at q (mm). Throws ArgumentError when q.size() != dof.
Eigen::Isometry3d forwardKinematics(const RobotModel& model, const Eigen::VectorXd& q_deg_mm,
                                    const PoseContext& context, KinematicWorkspace& ws);
/// Convenience overload with its own workspace and zero payload.
Eigen::Isometry3d forwardKinematics(const RobotModel& model, const Eigen::VectorXd& q_deg_mm);

/// T_base_flange of the complete model, joint deviations included, base and tool excluded.
Eigen::Isometry3d flangePose(const RobotModel& model, const Eigen::VectorXd& q_deg_mm,
                             const PoseContext& context, KinematicWorkspace& ws);

// ---------------------------------------------------------------------------------------
// Parameters of the complete model

/// Which physical quantity a parameter is.
enum class ParamKind {
  kBaseX, kBaseY, kBaseZ, kBaseRx, kBaseRy, kBaseRz,
  kToolX, kToolY, kToolZ, kToolRx, kToolRy, kToolRz,
  kOffset,      ///< joint zero of a revolute joint: dtheta
  kTheta,       ///< dtheta of a prismatic joint (rotation about its axis)
  kD,           ///< dd: DH d of a revolute DH link, or the joint zero of a prismatic one
  kA, kAlpha,
  kBeta,        ///< Hayati beta
  kCompliance,
  kGearSin,     ///< gear_periodic: coefficient of sin(h q_i), h = ParamInfo::harmonic
  kGearCos,     ///< gear_periodic: coefficient of cos(h q_i)
  kJointScale,  ///< joint_scale k_i
  kBacklash,    ///< backlash b_i (full width)
  kThermal,     ///< thermal expansion coefficient alpha (one per robot, joint = -1)
  kJointMap,    ///< joint_map: B-spline coefficient ParamInfo::index of joint's map (joint_map.h)
};

/// One scalar parameter. Internal units: mm, rad, rad/(N*m) or mm/N.
struct ParamInfo {
  ParamKind kind;
  int joint = -1;          ///< 0-based joint index for per-joint parameters, else -1
  std::string name;        ///< e.g. "base_x", "tool_rz", "j2_beta", "j3_compliance"
  std::string group;       ///< base, tool, offsets, lengths, angles, or an effect name
                           ///< (joint_compliance, gear_periodic, joint_scale, backlash, thermal)
  std::string unit;        ///< display unit: mm, deg, urad/Nm, um/N, ppm, ppm/K
  double display_scale;    ///< display value = internal value * display_scale
  int harmonic = 0;        ///< 1..H for kGearSin / kGearCos, else 0
  int index = 0;           ///< coefficient index for kJointMap, else 0
};

/// Every parameter the model can carry, in a fixed order: base (6), tool (6), per joint
/// offset, then the form's geometric parameters (DH revolute: d, a, alpha; Hayati revolute:
/// a, alpha, beta; prismatic: theta, a, alpha [, beta]), then compliance per joint, then the
/// effect catalogue: gear_periodic per revolute joint (jN_gear_s1, jN_gear_c1, ... up to
/// harmonic H; deg), joint_scale per joint (jN_scale; ppm), backlash per joint
/// (jN_backlash; deg or mm), thermal (thermal_alpha; ppm/K), then joint_map for each joint
/// whose map is not empty (jN_map_K, K = 0..intervals+2; deg or mm).
/// The order is also the priority used when dependent parameters are fixed.
std::vector<ParamInfo> parameterLayout(const RobotModel& model);

/// Reads / writes a parameter value (internal units) in the deviations.
double getParameter(const Deviations& dev, const ParamInfo& p);
void setParameter(Deviations& dev, const ParamInfo& p, double value);

/// Group names accepted by --params, with their meaning (for help texts and errors).
std::vector<std::pair<std::string, std::string>> parameterGroups();

/// The effect catalogue (docs/diagnosis.md): joint_compliance, gear_periodic, joint_scale,
/// backlash, thermal; each is also a parameter group.
const std::vector<std::string>& effectCatalogue();

/// Analytic parameter Jacobian (method.md eq. 26-31) of the tool pose at q:
/// J (6 x layout.size()), rows [dp_world (mm); dphi_world (rad)], column k the derivative
/// with respect to layout[k] in internal units. Each column is the small motion of one
/// intermediate frame carried to the tool: a translation along unit axis u adds u to dp;
/// a rotation about u through point o adds u x (p_tcp - o) to dp and u to dphi.
/// Also returns T_world_tcp. Throws ArgumentError on size mismatch.
Eigen::Isometry3d parameterJacobian(const RobotModel& model, const std::vector<ParamInfo>& layout,
                                    const Eigen::VectorXd& q_deg_mm, const PoseContext& context,
                                    KinematicWorkspace& ws, Eigen::MatrixXd& J);

/// Geometric (joint-space) Jacobian of T_world_tcp at q: rows [dp (mm); dphi (rad)], column
/// i per degree (revolute) or per mm (prismatic) of q_i. Includes the joint_scale and
/// gear_periodic terms (they depend on q); neglects compliance (its load depends on q too).
Eigen::Matrix<double, 6, Eigen::Dynamic> jointJacobian(const RobotModel& model,
                                                       const Eigen::VectorXd& q_deg_mm,
                                                       const PoseContext& context,
                                                       KinematicWorkspace& ws);

}  // namespace accura::calib
