#include "accura/calib/robot.h"

#include <cmath>

#include "accura/calib/errors.h"

namespace accura::calib {

std::vector<LinkForm> chooseLinkForms(const RobotDefinition& robot, FormPolicy policy) {
  const int n = robot.dof();
  std::vector<LinkForm> forms(n, LinkForm::kDH);
  if (policy == FormPolicy::kDHOnly) return forms;
  const double threshold = std::sin(kHayatiThresholdDeg * kDegToRad);
  for (int i = 0; i + 1 < n; ++i) {
    // angle between z_{i-1} and z_i is alpha_i (mod 180 deg)
    if (std::abs(std::sin(robot.joints[i].alpha_deg * kDegToRad)) < threshold) {
      forms[i] = LinkForm::kHayati;
    }
  }
  return forms;
}

bool Deviations::hasEffectsBeyondGeometry() const {
  for (const std::vector<double>* v : {&compliance, &gear_sin, &gear_cos, &joint_scale, &backlash})
    for (double x : *v)
      if (x != 0) return true;
  for (const JointMap& map : joint_map)
    for (double x : map.coef)
      if (x != 0) return true;
  return thermal_alpha_per_k != 0;
}

Deviations Deviations::zero(int dof, int gear_harmonics) {
  if (gear_harmonics < 1 || gear_harmonics > kMaxGearHarmonics)
    throw ArgumentError("gear harmonics: expected 1.." + std::to_string(kMaxGearHarmonics) + ", got " +
                        std::to_string(gear_harmonics));
  Deviations d;
  d.links.assign(dof, LinkDeviation{});
  d.compliance.assign(dof, 0.0);
  d.gear_harmonics = gear_harmonics;
  d.gear_sin.assign(static_cast<size_t>(dof * gear_harmonics), 0.0);
  d.gear_cos.assign(static_cast<size_t>(dof * gear_harmonics), 0.0);
  d.joint_scale.assign(dof, 0.0);
  d.backlash.assign(dof, 0.0);
  d.joint_map.assign(dof, JointMap{});
  return d;
}

RobotModel RobotModel::fromDefinition(const RobotDefinition& robot, FormPolicy policy) {
  RobotModel m;
  m.nominal = robot;
  m.forms = chooseLinkForms(robot, policy);
  m.deviations = Deviations::zero(robot.dof());
  return m;
}

Eigen::Isometry3d RobotModel::T_world_base() const {
  Eigen::Isometry3d T = nominal.T_world_base;
  T.translate(deviations.base_mm);
  T.rotate(expSO3(deviations.base_rot_rad));
  return T;
}

Eigen::Isometry3d RobotModel::T_flange_tcp() const {
  Eigen::Isometry3d T = nominal.T_flange_tcp;
  T.translate(deviations.tool_mm);
  T.rotate(expSO3(deviations.tool_rot_rad));
  return T;
}

void RobotModel::validate() const {
  const size_t n = nominal.joints.size();
  if (n == 0) throw ArgumentError("robot model has no joints");
  if (forms.size() != n)
    throw ArgumentError("robot model: expected " + std::to_string(n) + " link forms, got " +
                        std::to_string(forms.size()));
  if (deviations.links.size() != n)
    throw ArgumentError("robot model: expected " + std::to_string(n) +
                        " link deviations, got " + std::to_string(deviations.links.size()));
  if (deviations.compliance.size() != n)
    throw ArgumentError("robot model: expected " + std::to_string(n) +
                        " compliance values, got " +
                        std::to_string(deviations.compliance.size()));
  const int H = deviations.gear_harmonics;
  if (H < 1 || H > kMaxGearHarmonics)
    throw ArgumentError("robot model: gear harmonics must be 1.." + std::to_string(kMaxGearHarmonics) +
                        ", got " + std::to_string(H));
  const auto check = [&](const std::vector<double>& v, size_t expected, const char* what) {
    if (v.size() != expected)
      throw ArgumentError(std::string("robot model: expected ") + std::to_string(expected) + " " + what +
                          " values, got " + std::to_string(v.size()));
  };
  check(deviations.gear_sin, n * static_cast<size_t>(H), "gear_periodic sine");
  check(deviations.gear_cos, n * static_cast<size_t>(H), "gear_periodic cosine");
  check(deviations.joint_scale, n, "joint_scale");
  check(deviations.backlash, n, "backlash");
  if (deviations.joint_map.size() != n)
    throw ArgumentError("robot model: expected " + std::to_string(n) + " joint maps (empty or not), got " +
                        std::to_string(deviations.joint_map.size()));
  for (size_t i = 0; i < n; ++i) {
    const JointMap& m = deviations.joint_map[i];
    if (m.empty()) continue;
    const std::string j = "robot model: joint_map of joint " + std::to_string(i + 1) + ": ";
    if (!(std::isfinite(m.lower) && std::isfinite(m.upper) && m.lower < m.upper))
      throw ArgumentError(j + "expected lower < upper, got " + std::to_string(m.lower) + ", " + std::to_string(m.upper));
    if (m.intervals < 1 || m.coef.size() != static_cast<size_t>(m.intervals) + 3)
      throw ArgumentError(j + "expected intervals + 3 = " + std::to_string(m.intervals + 3) + " coefficients, got " +
                          std::to_string(m.coef.size()));
    if (!(std::isfinite(m.taper) && m.taper > 0))
      throw ArgumentError(j + "expected a taper width > 0, got " + std::to_string(m.taper));
    // the interval and its tapers within one period (rounding of a file's values allowed)
    if (!(m.period == 0 || (std::isfinite(m.period) && m.period + 1e-6 >= m.upper - m.lower + 2 * m.taper)))
      throw ArgumentError(j + "expected a period of 0 (none) or at least the covered interval and its tapers, " +
                          std::to_string(m.upper - m.lower + 2 * m.taper) + ", got " + std::to_string(m.period));
    for (double c : m.coef)
      if (!std::isfinite(c)) throw ArgumentError(j + "non-finite coefficient");
  }
  if (!deviations.fit_range.empty() && deviations.fit_range.size() != n)
    throw ArgumentError("robot model: expected " + std::to_string(n) + " fitted joint ranges or none, got " +
                        std::to_string(deviations.fit_range.size()));
}

}  // namespace accura::calib
