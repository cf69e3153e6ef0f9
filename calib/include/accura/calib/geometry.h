// accura: rigid transforms, KUKA A,B,C angles and the SO(3) helpers the models use.
//
// Frame convention (project-wide, written down once):
//   A pose T_a_b maps coordinates in frame b to frame a: p_a = T_a_b * p_b.
//   Lengths in millimetres, angles at interfaces in degrees, inside computations in radians.
//   KUKA A,B,C: R = Rz(A) * Ry(B) * Rx(C).
#pragma once

#include <Eigen/Geometry>
#include <string>

namespace accura::calib {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;
constexpr double kRadToDeg = 180.0 / kPi;

/// A pose as written in files and on the command line: x, y, z in mm; A, B, C in degrees
/// with R = Rz(A) Ry(B) Rx(C) (KUKA convention).
struct XyzAbc {
  double x_mm = 0, y_mm = 0, z_mm = 0;
  double a_deg = 0, b_deg = 0, c_deg = 0;
};

/// The transform of an x,y,z,A,B,C pose.
Eigen::Isometry3d toIsometry(const XyzAbc& pose);

/// The x,y,z,A,B,C of a transform. B is in [-90, 90] deg; at B = +-90 deg (gimbal lock) C is
/// set to 0 and A carries the whole rotation about z.
XyzAbc toXyzAbc(const Eigen::Isometry3d& T);

/// Rotation Rz(A) Ry(B) Rx(C), angles in radians.
Eigen::Matrix3d rotationZYX(double a_rad, double b_rad, double c_rad);

/// Skew-symmetric matrix [v]x with [v]x w = v x w.
Eigen::Matrix3d skew(const Eigen::Vector3d& v);

/// exp of a rotation vector (rad) and its inverse. logSO3 returns a vector of norm <= pi.
Eigen::Matrix3d expSO3(const Eigen::Vector3d& rotation_vector_rad);
Eigen::Vector3d logSO3(const Eigen::Matrix3d& R);

/// Right Jacobian of SO(3): expSO3(r + dr) = expSO3(r) * expSO3(Jr(r) dr) to first order.
Eigen::Matrix3d rightJacobianSO3(const Eigen::Vector3d& r);

/// The pose error between a measured and a predicted pose as a 6-vector in the frame of
/// `T_world_measured`: [position difference (mm, world); rotation vector (rad, world) of
/// R_measured * R_predicted^T].
Vector6d poseError(const Eigen::Isometry3d& T_world_measured,
                   const Eigen::Isometry3d& T_world_predicted);

/// Parses "x,y,z,A,B,C" (mm, deg). Throws InputError naming `what` on a malformed list.
XyzAbc parseXyzAbc(const std::string& text, const std::string& what);

}  // namespace accura::calib
