#include "accura/calib/geometry.h"

#include <cmath>
#include <sstream>
#include <vector>

#include "accura/calib/errors.h"

namespace accura::calib {

Eigen::Matrix3d rotationZYX(double a_rad, double b_rad, double c_rad) {
  return (Eigen::AngleAxisd(a_rad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(b_rad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(c_rad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Isometry3d toIsometry(const XyzAbc& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationZYX(p.a_deg * kDegToRad, p.b_deg * kDegToRad, p.c_deg * kDegToRad);
  T.translation() = Eigen::Vector3d(p.x_mm, p.y_mm, p.z_mm);
  return T;
}

XyzAbc toXyzAbc(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d R = T.linear();
  XyzAbc out;
  out.x_mm = T.translation().x();
  out.y_mm = T.translation().y();
  out.z_mm = T.translation().z();
  // R = Rz(A) Ry(B) Rx(C): R(2,0) = -sin B.
  const double sb = std::max(-1.0, std::min(1.0, -R(2, 0)));
  const double cb = std::hypot(R(0, 0), R(1, 0));
  const double b = std::atan2(sb, cb);
  double a, c;
  if (cb > 1e-12) {
    a = std::atan2(R(1, 0), R(0, 0));
    c = std::atan2(R(2, 1), R(2, 2));
  } else {  // gimbal lock: put everything into A
    c = 0;
    a = std::atan2(-R(0, 1), R(1, 1));
  }
  out.a_deg = a * kRadToDeg;
  out.b_deg = b * kRadToDeg;
  out.c_deg = c * kRadToDeg;
  return out;
}

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

Eigen::Matrix3d expSO3(const Eigen::Vector3d& r) {
  const double angle = r.norm();
  if (angle < 1e-12) return Eigen::Matrix3d::Identity() + skew(r);
  return Eigen::AngleAxisd(angle, r / angle).toRotationMatrix();
}

Eigen::Vector3d logSO3(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  double angle = aa.angle();
  Eigen::Vector3d axis = aa.axis();
  if (angle > kPi) {  // Eigen returns [0, pi] in practice; keep the guarantee explicit
    angle = 2 * kPi - angle;
    axis = -axis;
  }
  return axis * angle;
}

Eigen::Matrix3d rightJacobianSO3(const Eigen::Vector3d& r) {
  const double t = r.norm();
  const Eigen::Matrix3d K = skew(r);
  if (t < 1e-6) return Eigen::Matrix3d::Identity() - 0.5 * K + K * K / 6.0;
  const double t2 = t * t;
  return Eigen::Matrix3d::Identity() - (1 - std::cos(t)) / t2 * K +
         (t - std::sin(t)) / (t2 * t) * K * K;
}

Vector6d poseError(const Eigen::Isometry3d& T_world_measured,
                   const Eigen::Isometry3d& T_world_predicted) {
  Vector6d e;
  e.head<3>() = T_world_measured.translation() - T_world_predicted.translation();
  e.tail<3>() = logSO3(T_world_measured.linear() * T_world_predicted.linear().transpose());
  return e;
}

XyzAbc parseXyzAbc(const std::string& text, const std::string& what) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    char* end = nullptr;
    const double x = std::strtod(item.c_str(), &end);
    while (end && *end == ' ') ++end;
    if (item.empty() || end == item.c_str() || *end != '\0' || !std::isfinite(x)) {
      throw InputError(what + ": expected a number, found '" + item + "'");
    }
    v.push_back(x);
  }
  if (v.size() != 6 && v.size() != 3) {
    throw InputError(what + ": expected x,y,z or x,y,z,A,B,C (mm, deg), found " +
                     std::to_string(v.size()) + " values in '" + text + "'");
  }
  XyzAbc p;
  p.x_mm = v[0];
  p.y_mm = v[1];
  p.z_mm = v[2];
  if (v.size() == 6) {
    p.a_deg = v[3];
    p.b_deg = v[4];
    p.c_deg = v[5];
  }
  return p;
}

}  // namespace accura::calib
