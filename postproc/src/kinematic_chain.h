// Internal: a RobotModel prepared for fast forward kinematics and joint Jacobians (the hot
// path of the IK). Computes exactly what calib's forwardKinematics / jointJacobian compute
// (every effect of the complete model); KinematicSolver checks the two against each other
// when it is built.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <vector>

#include "accura/calib/kinematics.h"
#include "accura/calib/robot.h"

namespace accura::postproc::detail {

constexpr int kMaxDof = 12;
using VecN = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxDof, 1>;
using Jac6N = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxDof>;

/// Frames of one evaluation, in the world: joint i (0-based) turns about z[i] through o[i].
struct ChainFrames {
  std::array<Eigen::Vector3d, kMaxDof> o;
  std::array<Eigen::Vector3d, kMaxDof> z;
  std::array<double, kMaxDof> rate;  ///< d(theta_i or d_i)/dq_i (per rad / per mm)
  Eigen::Isometry3d T_world_tcp;
  /// The DH angle of each link and its cosine / sine: the next evaluation starts from them
  /// when it is near.
  std::array<double, kMaxDof> theta, cos_theta, sin_theta;
  /// The nominal DH angle of each link (theta0 + direction q) and its cosine / sine (gravity
  /// loads, KUKA Status): valid when `nominal_valid` (always for a compliant model; else see
  /// KinematicChain::fillNominal).
  std::array<double, kMaxDof> theta_nominal, cos_nominal, sin_nominal;
  bool nominal_valid = false;
};

class KinematicChain {
 public:
  explicit KinematicChain(const RobotModel& model);

  int dof() const { return n_; }
  /// Frames and T_world_tcp at q (deg / mm). With `near` (frames of a previous evaluation,
  /// not `f`) the cosine and sine of an angle within 0.1 rad of its value there come from the
  /// angle-addition formulas (series of the difference, 1e-18 relative) instead of calls to
  /// sin / cos; for a compliant model the link angles come that way from the nominal ones
  /// (which the gravity loads need).
  void evaluate(const double* q, const PoseContext& context, ChainFrames& f,
                const ChainFrames* near = nullptr) const;
  /// Fills the nominal angles of the first `count` links of `f` (evaluated at q) when they
  /// are not valid.
  void fillNominal(const double* q, ChainFrames& f, int count) const;
  /// Joint Jacobian from frames: rows [dp mm; dphi rad], columns per deg (revolute) or mm.
  void jacobian(const ChainFrames& f, Jac6N& J) const;
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

 private:
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
    double joint_scale = 0;
    double half_backlash = 0;
    bool gear = false;
    std::array<double, kMaxGearHarmonics> gs{}, gc{};
    // nominal geometry for the gravity loads
    double nom_theta0 = 0, nom_d = 0, nom_a = 0, nom_ca = 1, nom_sa = 0;
    double mass = 0;
    Eigen::Vector3d com = Eigen::Vector3d::Zero();
  };

  void gravityLoads(const double* q, double payload_kg, double* load, const ChainFrames& f) const;

  int n_ = 0;
  int harmonics_ = 0;
  std::vector<Link> links_;
  Eigen::Matrix3d R_world_base_;
  Eigen::Vector3d t_world_base_;
  Eigen::Isometry3d T_flange_tcp_;
  double thermal_alpha_ = 0;
  bool compliant_ = false;
  bool backlash_ = false;
  bool any_joint_effect_ = false;  ///< joint_scale or gear_periodic somewhere
  Eigen::Vector3d gravity_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d payload_com_ = Eigen::Vector3d::Zero();
  double length_scale_mm_ = 1;
  std::vector<double> jacobian_lipschitz_;
};

}  // namespace accura::postproc::detail
