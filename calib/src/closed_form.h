// Internal: closed-form inverse kinematics of the nominal geometry of two families of 6R
// robots (all 8 branches). Derivations: docs/compensation.md.
//   kSphericalWrist: alpha1 = +-90, alpha2 = 0, alpha3 = +-90, a4 = a5 = d5 = a6 = 0,
//                    alpha4 = alpha5 = +-90 (KUKA KR 16, ABB IRB 120, most 6R arms);
//   kThreeParallel:  alpha1 = +-90, alpha2 = alpha3 = 0, alpha4 = alpha5 = +-90,
//                    a4 = a5 = a6 = 0 (Universal Robots).
#pragma once

#include <Eigen/Geometry>
#include <array>

#include "accura/calib/robot.h"

namespace accura::calib::detail {

enum class ClosedFormKind { kNone, kSphericalWrist, kThreeParallel };

/// One solution: DH angles theta_1..6 (rad) and its branch: bit 2 the theta1 solution, bit 1
/// the elbow, bit 0 the wrist (theta5 sign). The same code gives the same branch for nearby
/// poses (the closed form is continuous in the pose within a branch).
struct ThetaSolution {
  std::array<double, 6> theta;
  int branch = 0;
};

class ClosedForm {
 public:
  /// Detects the family from the nominal DH values (tolerance 1e-9).
  explicit ClosedForm(const RobotDefinition& robot);
  ClosedFormKind kind() const { return kind_; }

  /// Solutions for T_0_6 (DH frame 0 -> DH frame 6, nominal). `theta_ref` fills the free
  /// angle at a singularity (theta1 with the wrist point on the first axis, theta4 / theta6
  /// with the wrist axes aligned). Arguments of acos / asin up to 1 + slack are clamped
  /// (the pose is at most a few mm outside the nominal workspace: the seed of a calibrated
  /// robot that reaches a little further). Returns the number written (0..8).
  int solve(const Eigen::Isometry3d& T_0_6, const std::array<double, 6>& theta_ref,
            std::array<ThetaSolution, 8>& out) const {
    return solveImpl(T_0_6, theta_ref, -1, out);
  }
  /// The solution of one branch (ThetaSolution::branch); false when that branch has none.
  bool solveBranch(const Eigen::Isometry3d& T_0_6, const std::array<double, 6>& theta_ref, int branch,
                   ThetaSolution& out) const;

 private:
  int solveImpl(const Eigen::Isometry3d& T, const std::array<double, 6>& ref, int only,
                std::array<ThetaSolution, 8>& out) const;
  int solveSphericalWrist(const Eigen::Isometry3d& T, const std::array<double, 6>& ref, int only,
                          std::array<ThetaSolution, 8>& out) const;
  int solveThreeParallel(const Eigen::Isometry3d& T, const std::array<double, 6>& ref, int only,
                         std::array<ThetaSolution, 8>& out) const;
  Eigen::Isometry3d link(int i, double theta) const;

  ClosedFormKind kind_ = ClosedFormKind::kNone;
  std::array<double, 6> d_{}, a_{}, alpha_{}, sa_{}, ca_{};
  std::array<Eigen::Matrix3d, 6> Rx_;  ///< Rx(alpha_i)
};

}  // namespace accura::calib::detail
