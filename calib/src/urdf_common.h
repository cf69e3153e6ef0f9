// accura: helpers shared by the URDF and UR calibration readers / writers (internal).
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "accura/calib/kinematics.h"

namespace accura::calib::urdf_detail {

/// Shortest decimal text that reads back to the same double ("0" for +-0).
inline std::string shortestNumber(double v) {
  if (v == 0.0) return "0";
  char buf[40];
  for (int prec = 15; prec <= 17; ++prec) {
    std::snprintf(buf, sizeof buf, "%.*g", prec, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

/// URDF rpy (roll, pitch, yaw; R = Rz(yaw) Ry(pitch) Rx(roll)) of a rotation. Yaw first, then
/// pitch and roll from Rz(-yaw) R, which stays accurate near pitch = +-90 deg.
inline Eigen::Vector3d urdfRpy(const Eigen::Matrix3d& R) {
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  const Eigen::Matrix3d Rp = Eigen::AngleAxisd(-yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() * R;
  return Eigen::Vector3d(std::atan2(-Rp(1, 2), Rp(1, 1)), std::atan2(-Rp(2, 0), Rp(0, 0)), yaw);
}

/// Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta) (mm, rad), composed from elementary transforms
/// (kinematics.cpp writes the same product out by hand for speed; this one places frames).
inline Eigen::Isometry3d linkFrame(double theta, double d, double a, double alpha, double beta) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.rotate(Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ()));
  T.translate(Eigen::Vector3d(0, 0, d));
  T.translate(Eigen::Vector3d(a, 0, 0));
  T.rotate(Eigen::AngleAxisd(alpha, Eigen::Vector3d::UnitX()));
  T.rotate(Eigen::AngleAxisd(beta, Eigen::Vector3d::UnitY()));
  return T;
}

/// Link i's transform at q = 0 with its calibrated values (no thermal scale, no effects).
inline Eigen::Isometry3d calibratedLinkAtZero(const RobotModel& m, int i) {
  const JointSpec& j = m.nominal.joints[static_cast<size_t>(i)];
  const LinkDeviation& d = m.deviations.links[static_cast<size_t>(i)];
  return linkFrame(j.theta0_deg * kDegToRad + d.dtheta_rad, j.d_mm + d.dd_mm, j.a_mm + d.da_mm,
                   j.alpha_deg * kDegToRad + d.dalpha_rad, d.dbeta_rad);
}

/// Parameter groups of the geometric model (the rest are effects a kinematic table cannot hold).
inline bool isGeometricGroup(const std::string& group) {
  return group == "base" || group == "tool" || group == "offsets" || group == "lengths" || group == "angles";
}

/// The model's non-zero effect parameters (beyond geometry), one line per group:
/// "<group> (left out; <where> has no such effect): name = value unit, ...".
inline std::vector<std::string> effectsLeftOut(const RobotModel& model, const std::string& where) {
  std::map<std::string, std::string> by_group;
  for (const ParamInfo& p : parameterLayout(model)) {
    if (isGeometricGroup(p.group)) continue;
    const double v = getParameter(model.deviations, p);
    if (v == 0.0) continue;
    std::string& line = by_group[p.group];
    line += (line.empty() ? "" : ", ") + p.name + " = " + shortestNumber(v * p.display_scale) + " " + p.unit;
  }
  std::vector<std::string> out;
  for (const auto& [group, values] : by_group)
    out.push_back(group + " (left out; " + where + " has no such effect): " + values);
  return out;
}

/// The model with every effect beyond geometry set to zero.
inline RobotModel geometricPart(const RobotModel& model) {
  RobotModel g = model;
  for (const ParamInfo& p : parameterLayout(model))
    if (!isGeometricGroup(p.group)) setParameter(g.deviations, p, 0.0);
  return g;
}

}  // namespace accura::calib::urdf_detail
