// accura: the kinematic core. The one implementation of the complete model's forward
// kinematics, joint Jacobian, parameter Jacobian and gravity loads (method.md sections 2-3);
// everything else (calib's forwardKinematics / jointJacobian / parameterJacobian,
// identification, diagnosis, simulation, the IK in ik.h, the post-processor, the plug-in)
// calls it.
//
// Style (Pinocchio's Model / Data): a KinematicModel is a RobotModel prepared once (constants
// precomputed: twist cosines and sines, Hayati rotations, base and tool, the effect tables)
// and immutable, so several threads may evaluate it at once; each thread passes its own
// KinematicFrames (and LinkFrames where the intermediate frames are needed).
// Joint values q are what the controller reads: degrees (revolute) or mm (prismatic).
// Frames: every pose and axis here is in the world frame (T_world_base applied).
//
// A new effect of the catalogue is written once, in calib/src/kinematic_core.cpp: its joint
// angle / length contribution and its derivative in jointEffects(), its table in
// KinematicModel::Link (filled in the constructor), its parameter columns in
// KinematicModel::parameterJacobian().
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <vector>

#include "accura/calib/robot.h"

namespace accura::calib {

struct PoseContext;
struct ParamInfo;

/// Most joints a KinematicModel takes (KinematicModel throws ArgumentError beyond).
constexpr int kMaxDof = 12;
/// Joint vector and joint Jacobian without heap allocation (at most kMaxDof joints).
using VecN = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxDof, 1>;
using Jac6N = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxDof>;

/// One evaluation of a KinematicModel (the per-thread `Data`): the joint axes and the tool
/// pose in the world, and what the next evaluation nearby can start from.
struct KinematicFrames {
  /// Joint i (0-based) turns about / slides along z[i] through o[i] (world, mm).
  std::array<Eigen::Vector3d, kMaxDof> o;
  std::array<Eigen::Vector3d, kMaxDof> z;
  std::array<double, kMaxDof> rate;  ///< d(theta_i or d_i)/dq_i (per rad / per mm)
  Eigen::Isometry3d T_world_tcp;
  /// The DH angle of each link and its cosine / sine: the next evaluation starts from them
  /// when it is near.
  std::array<double, kMaxDof> theta, cos_theta, sin_theta;
  /// The nominal DH angle of each link (theta0 + direction q) and its cosine / sine (gravity
  /// loads, KUKA Status): valid when `nominal_valid` (always for a compliant model; else see
  /// KinematicModel::fillNominal).
  std::array<double, kMaxDof> theta_nominal, cos_nominal, sin_nominal;
  bool nominal_valid = false;
};

/// The intermediate frames of one evaluation (what the parameter Jacobian and the cell
/// checks need besides KinematicFrames), in the BASE frame.
struct LinkFrames {
  /// Frames 0..n: T_base_frame[i] = A_1 ... A_i (frame 0 the base, n the flange).
  std::array<Eigen::Isometry3d, kMaxDof + 1> T_base_frame;
  /// Per link i, in the base frame: the x axis after Rz(theta_i) (the axis of a_i and
  /// alpha_i) and the y axis after Rx(alpha_i) (the axis of beta_i).
  std::array<Eigen::Vector3d, kMaxDof> x_after_theta, y_after_alpha;
  /// The DH angle (rad) and d (mm) actually used, thermal scale and every effect included.
  std::array<double, kMaxDof> theta_rad, d_mm;
  /// Gravity load per joint (N*m or N) at q, nominal geometry; zero unless the model is
  /// compliant or the loads were asked for.
  std::array<double, kMaxDof> load;
};

/// A RobotModel prepared for repeated evaluation. Immutable after construction.
class KinematicModel {
 public:
  /// Throws ArgumentError for an invalid model or more than kMaxDof joints.
  explicit KinematicModel(const RobotModel& model);

  int dof() const { return n_; }

  /// Frames and T_world_tcp at q (deg / mm; q[0..dof-1]) in `context`. With `near` (frames of
  /// a previous evaluation, not `f`) the cosine and sine of an angle within 0.1 rad of its
  /// value there come from the angle-addition formulas (series of the difference, 1e-18
  /// relative) instead of calls to sin / cos; for a compliant model the link angles come that
  /// way from the nominal ones (which the gravity loads need). With `links`, the
  /// intermediate frames too (the chain is then evaluated in the base frame and carried to the
  /// world at the end, as T_world_base * T_base_flange * T_flange_tcp); `need_loads` computes the gravity loads into links->load even
  /// when the model is not compliant. Throws ArgumentError when context.dir is non-empty and
  /// shorter than dof while the model has backlash.
  void evaluate(const double* q, const PoseContext& context, KinematicFrames& f,
                const KinematicFrames* near = nullptr, LinkFrames* links = nullptr,
                bool need_loads = false) const;
  /// Fills the nominal angles of the first `count` links of `f` (evaluated at q) when they
  /// are not valid.
  void fillNominal(const double* q, KinematicFrames& f, int count) const;
  /// Joint Jacobian of T_world_tcp from frames: rows [dp mm; dphi rad], columns per deg
  /// (revolute) or per mm (prismatic). Includes the q-dependent effects (joint_scale,
  /// gear_periodic); neglects compliance (its load depends on q too).
  void jacobian(const KinematicFrames& f, Jac6N& J) const;
  /// Analytic parameter Jacobian (method.md eq. 26-31) of the tool pose at q: J (6 x
  /// layout.size()), rows [dp_world (mm); dphi_world (rad)], column k the derivative with
  /// respect to layout[k] in internal units. Returns T_world_tcp. Throws ArgumentError for a
  /// parameter without a joint of this robot.
  Eigen::Isometry3d parameterJacobian(const std::vector<ParamInfo>& layout, const double* q,
                                      const PoseContext& context, KinematicFrames& f, LinkFrames& links,
                                      Eigen::MatrixXd& J) const;
  /// Gravity load on each joint at q (nominal geometry; see calib's gravityLoads) into
  /// load[0..dof-1]; `f` must hold the nominal angles at q (fillNominal).
  void gravityLoads(const double* q, double payload_kg, double* load, const KinematicFrames& f) const;
  /// Sum of the nominal link lengths |a_i| + |d_i| and the tool offset (mm, >= 1): the length
  /// that scales position rows against rotation rows.
  double length_scale_mm() const { return length_scale_mm_; }
  /// For a chain whose link angles are theta_c + direction q (revolute joints only; no
  /// compliance, joint_scale, gear_periodic, backlash or thermal scale): per joint k a bound
  /// B_k with ||Js(q1) - Js(q0)||_2 <= sum_k B_k |q1_k - q0_k| (rad), Js the joint Jacobian
  /// with its position rows divided by length_scale_mm() and columns per rad. Turning joint k
  /// rotates every later column rigidly about axis k (norm <= sqrt(1 + rho_i^2)) and moves the
  /// tool point, hence the position part of every column i <= k, by at most rho_k:
  /// B_k = sqrt(sum_{i>k} (1 + rho_i^2) + (k + 1) rho_k^2), rho_i = (|tool| + sum_{j>=i}
  /// |a_j| + |d_j|) / L >= |p - o_i| / L. Empty for any other chain.
  const std::vector<double>& scaledJacobianLipschitz() const { return jacobian_lipschitz_; }
  /// T_world_base and T_flange_tcp of the model (deviations included).
  const Eigen::Isometry3d& T_world_base() const { return T_world_base_; }
  const Eigen::Isometry3d& T_flange_tcp() const { return T_flange_tcp_; }

  /// The prepared constants of one link (internal; public for kinematic_core.cpp's helpers).
  struct Link {
    bool revolute = true;
    double dir = 1;
    double theta_c = 0;  ///< theta0 + dtheta (rad)
    double d_c = 0;      ///< d0 + dd (mm, before the thermal scale)
    double a = 0;        ///< a0 + da (mm, before the thermal scale)
    Eigen::Matrix3d M = Eigen::Matrix3d::Identity();  ///< Rx(alpha) Ry(beta)
    bool beta = false;                                 ///< beta != 0 (else M = Rx(alpha))
    double ca = 1, sa = 0;                             ///< cos / sin alpha
    double compliance = 0;
    // the joint-space effects of the catalogue (jointEffects)
    bool any_effect = false;  ///< any of the tables below non-zero
    double joint_scale = 0;
    double half_backlash = 0;
    bool gear = false;
    std::array<double, kMaxGearHarmonics> gs{}, gc{};
    JointMap map;  ///< joint_map (empty: none)
    // nominal geometry for the gravity loads
    double nom_theta0 = 0, nom_d = 0, nom_a = 0, nom_ca = 1, nom_sa = 0;
    double mass = 0;
    Eigen::Vector3d com = Eigen::Vector3d::Zero();
  };

 private:
  /// The frames along the chain from the link values evaluate() computed (f.cos_theta /
  /// f.sin_theta, d_link): in the world, or with kLinks in the base frame into `links`.
  template <bool kLinks>
  void chain(KinematicFrames& f, const double* d_link, double scale, LinkFrames* links) const;

  int n_ = 0;
  int harmonics_ = 0;
  std::vector<Link> links_;
  Eigen::Isometry3d T_world_base_, T_flange_tcp_;
  Eigen::Matrix3d R_world_base_;
  // what the base and tool columns of the parameter Jacobian need
  Eigen::Matrix3d R_world_basenom_, R_flange_toolnom_, Jr_base_, Jr_tool_;
  Eigen::Vector3d t_world_base_;
  double thermal_alpha_ = 0;
  bool compliant_ = false;
  bool backlash_ = false;
  bool any_joint_effect_ = false;  ///< an effect that depends on q (joint_scale, gear_periodic, joint_map)
  Eigen::Vector3d gravity_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d payload_com_ = Eigen::Vector3d::Zero();
  double length_scale_mm_ = 1;
  std::vector<double> jacobian_lipschitz_;
};

}  // namespace accura::calib
