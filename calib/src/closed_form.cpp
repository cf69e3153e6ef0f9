#include "closed_form.h"

#include <algorithm>
#include <cmath>

#include "accura/calib/geometry.h"

namespace accura::calib::detail {
namespace {

constexpr double kEps = 1e-9;
/// Arguments of acos / asin beyond +-1 by up to this are clamped (see ClosedForm::solve).
constexpr double kSlack = 0.02;
/// |sin theta5| below this: the wrist axes are aligned and theta4 / theta6 are not separable.
constexpr double kWristSingular = 1e-9;

Eigen::Matrix3d rotZ(double t) {
  const double c = std::cos(t), s = std::sin(t);
  Eigen::Matrix3d R;
  R << c, -s, 0, s, c, 0, 0, 0, 1;
  return R;
}

Eigen::Matrix3d rotZcs(double c, double s) {
  Eigen::Matrix3d R;
  R << c, -s, 0, s, c, 0, 0, 0, 1;
  return R;
}

Eigen::Matrix3d rotX(double t) {
  const double c = std::cos(t), s = std::sin(t);
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, c, -s, 0, s, c;
  return R;
}

/// acos / asin argument check: false when |x| > 1 + kSlack, else clamps x to [-1, 1].
bool clampUnit(double& x) {
  if (!(std::abs(x) <= 1.0 + kSlack)) return false;  // also rejects NaN
  x = std::clamp(x, -1.0, 1.0);
  return true;
}

}  // namespace

ClosedForm::ClosedForm(const RobotDefinition& robot) {
  if (robot.dof() != 6) return;
  for (int i = 0; i < 6; ++i) {
    const JointSpec& j = robot.joints[static_cast<size_t>(i)];
    if (j.type != JointType::kRevolute) return;
    d_[i] = j.d_mm;
    a_[i] = j.a_mm;
    alpha_[i] = j.alpha_deg * kDegToRad;
    sa_[i] = std::sin(alpha_[i]);
    ca_[i] = std::cos(alpha_[i]);
    Rx_[i] = rotX(alpha_[i]);
  }
  auto perpendicular = [&](int i) { return std::abs(ca_[i]) < kEps; };
  auto parallel = [&](int i) { return std::abs(sa_[i]) < kEps && ca_[i] > 0; };
  auto zero = [](double v) { return std::abs(v) < kEps; };
  const double L3 = std::hypot(a_[2], sa_[2] * d_[3]);
  if (perpendicular(0) && parallel(1) && perpendicular(2) && perpendicular(3) && perpendicular(4) &&
      zero(a_[3]) && zero(a_[4]) && zero(d_[4]) && zero(a_[5]) && !zero(a_[1]) && !zero(L3)) {
    kind_ = ClosedFormKind::kSphericalWrist;
  } else if (perpendicular(0) && parallel(1) && parallel(2) && perpendicular(3) && perpendicular(4) &&
             zero(a_[3]) && zero(a_[4]) && zero(a_[5]) && !zero(a_[1]) && !zero(a_[2])) {
    kind_ = ClosedFormKind::kThreeParallel;
  }
}

Eigen::Isometry3d ClosedForm::link(int i, double theta) const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotZ(theta) * rotX(alpha_[i]);
  T.translation() = Eigen::Vector3d(a_[i] * std::cos(theta), a_[i] * std::sin(theta), d_[i]);
  return T;
}

int ClosedForm::solveImpl(const Eigen::Isometry3d& T_0_6, const std::array<double, 6>& theta_ref, int only,
                          std::array<ThetaSolution, 8>& out) const {
  switch (kind_) {
    case ClosedFormKind::kSphericalWrist: return solveSphericalWrist(T_0_6, theta_ref, only, out);
    case ClosedFormKind::kThreeParallel: return solveThreeParallel(T_0_6, theta_ref, only, out);
    case ClosedFormKind::kNone: break;
  }
  return 0;
}

bool ClosedForm::solveBranch(const Eigen::Isometry3d& T_0_6, const std::array<double, 6>& theta_ref, int branch,
                             ThetaSolution& out) const {
  std::array<ThetaSolution, 8> sols;
  if (solveImpl(T_0_6, theta_ref, branch, sols) < 1) return false;
  out = sols[0];
  return true;
}

// The wrist point w = p - d6 z5 depends only on theta1..3. In the frame turned by theta1 its
// component along the first joint's normal is the constant offset h = d2 + d3 + cos(alpha3) d4
// (theta1: two solutions); in the plane of joints 2 and 3 it is a two-link arm
// (a2, |(a3, -sin(alpha3) d4)|) (theta3: elbow up / down; theta2 follows). The wrist
// M = R03^T R Rx(-alpha6) = Rz(t4) Rx(alpha4) Rz(t5) Rx(alpha5) Rz(t6): its third column is
// (cos t4 s5 sin t5, sin t4 s5 sin t5, -s4 s5 cos t5) (theta5: two signs; theta4, theta6).
int ClosedForm::solveSphericalWrist(const Eigen::Isometry3d& T, const std::array<double, 6>& ref, int only,
                                    std::array<ThetaSolution, 8>& out) const {
  const Eigen::Matrix3d R = T.linear();
  const Eigen::Vector3d z5 = R * Eigen::Vector3d(0, sa_[5], ca_[5]);
  const Eigen::Vector3d w = T.translation() - d_[5] * z5;
  const double s1 = sa_[0], s4 = sa_[3], s5 = sa_[4];
  const double h = d_[1] + d_[2] + ca_[2] * d_[3];
  const double r = std::hypot(w.x(), w.y());
  std::array<double, 2> t1{};
  int n1 = 0;
  if (r < 1e-9) {
    if (std::abs(h) > 1e-9) return 0;
    // wrist point on the first axis: theta1 is free (shoulder singularity)
    t1 = {ref[0], ref[0] + kPi};
    n1 = 2;
  } else {
    double k = s1 * h / r;
    if (!clampUnit(k)) return 0;
    const double phi = std::atan2(w.y(), w.x());
    t1 = {phi + std::asin(k), phi + kPi - std::asin(k)};
    n1 = 2;
  }
  const double b3 = -sa_[2] * d_[3];
  const double L3 = std::hypot(a_[2], b3);
  const double gamma = std::atan2(b3, a_[2]);
  const double a2 = a_[1];
  const Eigen::Matrix3d Rx6inv = rotX(-alpha_[5]);
  const Eigen::Matrix3d RRx6inv = R * Rx6inv;
  int count = 0;
  for (int i1 = 0; i1 < n1; ++i1) {
    if (only >= 0 && ((only >> 2) & 1) != i1) continue;
    const double th1 = t1[static_cast<size_t>(i1)];
    const double c1 = std::cos(th1), sn1 = std::sin(th1);
    const double u = c1 * w.x() + sn1 * w.y();
    const double x = u - a_[0];
    const double y = s1 * (w.z() - d_[0]);
    double c = (x * x + y * y - a2 * a2 - L3 * L3) / (2 * a2 * L3);
    if (!clampUnit(c)) continue;
    const double beta0 = std::acos(c);
    const Eigen::Matrix3d R01 = rotZcs(c1, sn1) * Rx_[0];
    for (int ib = 0; ib < 2; ++ib) {
      if (only >= 0 && ((only >> 1) & 1) != ib) continue;
      const double beta = ib == 0 ? beta0 : -beta0;
      const double th3 = beta - gamma;
      const double th2 = std::atan2(y, x) - std::atan2(L3 * std::sin(beta), a2 + L3 * std::cos(beta));
      const Eigen::Matrix3d R03 = R01 * rotZ(th2) * Rx_[1] * rotZ(th3) * Rx_[2];
      const Eigen::Matrix3d M = R03.transpose() * RRx6inv;
      double c5 = -s4 * s5 * M(2, 2);
      c5 = std::clamp(c5, -1.0, 1.0);
      const double s5abs = std::sqrt(std::max(0.0, 1 - c5 * c5));
      for (int is = 0; is < 2; ++is) {
        if (only >= 0 && (only & 1) != is && s5abs > kWristSingular) continue;
        const double sign = is == 0 ? 1.0 : -1.0;
        const double sn5 = sign * s5abs;
        double th4 = ref[3];
        if (s5abs > kWristSingular) {
          const double k = s5 * sign;
          th4 = std::atan2(k * M(1, 2), k * M(0, 2));
        }
        const Eigen::Matrix3d K = rotZ(th4) * Rx_[3] * rotZcs(c5, sn5) * Rx_[4];
        const Eigen::Matrix3d X = K.transpose() * M;
        const double th6 = std::atan2(X(1, 0), X(0, 0));
        ThetaSolution& o = out[static_cast<size_t>(count++)];
        o.theta = {th1, th2, th3, th4, std::atan2(sn5, c5), th6};
        o.branch = i1 * 4 + ib * 2 + is;
        if (s5abs <= kWristSingular) break;  // both signs are the same solution
      }
    }
  }
  return count;
}

// The point o5 = p - d6 z5 (z5 known from the target orientation) has the constant component
// D = d2 + d3 + d4 along the parallel axes z1 = s1 (sin t1, -cos t1, 0) (theta1: two
// solutions); z1 . z5 = -s4 s5 cos t5 (theta5: two signs); z1 seen from frame 5 fixes theta6;
// joints 2-4 are then a planar arm (a2, a3) with the sum t2 + t3 + t4 known (theta3: two).
int ClosedForm::solveThreeParallel(const Eigen::Isometry3d& T, const std::array<double, 6>& ref, int only,
                                   std::array<ThetaSolution, 8>& out) const {
  const Eigen::Matrix3d R = T.linear();
  const Eigen::Vector3d z5 = R * Eigen::Vector3d(0, sa_[5], ca_[5]);
  const Eigen::Vector3d o5 = T.translation() - d_[5] * z5;
  const double s1 = sa_[0], s4 = sa_[3], s5 = sa_[4];
  const double D = d_[1] + d_[2] + d_[3];
  const double r = std::hypot(o5.x(), o5.y());
  std::array<double, 2> t1{};
  if (r < 1e-9) {
    if (std::abs(D) > 1e-9) return 0;
    t1 = {ref[0], ref[0] + kPi};
  } else {
    double k = s1 * D / r;
    if (!clampUnit(k)) return 0;
    const double phi = std::atan2(o5.y(), o5.x());
    t1 = {phi + std::asin(k), phi + kPi - std::asin(k)};
  }
  const Eigen::Matrix3d Rx4inv = rotX(-alpha_[3]);
  const Eigen::Matrix3d Rx6 = rotX(alpha_[5]);
  const double a2 = a_[1], a3 = a_[2];
  int count = 0;
  for (int i1 = 0; i1 < 2; ++i1) {
    if (only >= 0 && ((only >> 2) & 1) != i1) continue;
    const double th1 = t1[static_cast<size_t>(i1)];
    const Eigen::Vector3d z1 = s1 * Eigen::Vector3d(std::sin(th1), -std::cos(th1), 0);
    const double c5 = std::clamp(-s4 * s5 * z1.dot(z5), -1.0, 1.0);
    const double s5abs = std::sqrt(std::max(0.0, 1 - c5 * c5));
    const Eigen::Vector3d wv = Rx6 * (R.transpose() * z1);
    for (int is = 0; is < 2; ++is) {
      if (only >= 0 && (only & 1) != is && s5abs > kWristSingular) continue;
      const double sign = is == 0 ? 1.0 : -1.0;
      const double sn5 = sign * s5abs;
      const double th5 = std::atan2(sn5, c5);
      double th6 = ref[5];
      if (s5abs > kWristSingular) th6 = (s4 * sn5 > 0 ? 0.0 : kPi) - std::atan2(wv.y(), wv.x());
      const Eigen::Isometry3d T14 = link(0, th1).inverse() * T * (link(4, th5) * link(5, th6)).inverse();
      const double x = T14.translation().x(), y = T14.translation().y();
      const Eigen::Matrix3d N = T14.linear() * Rx4inv;
      const double th234 = std::atan2(N(1, 0), N(0, 0));
      double c3 = (x * x + y * y - a2 * a2 - a3 * a3) / (2 * a2 * a3);
      if (clampUnit(c3)) {
        const double t3 = std::acos(c3);
        for (int ib = 0; ib < 2; ++ib) {
          if (only >= 0 && ((only >> 1) & 1) != ib) continue;
          const double th3 = ib == 0 ? t3 : -t3;
          const double th2 = std::atan2(y, x) - std::atan2(a3 * std::sin(th3), a2 + a3 * std::cos(th3));
          ThetaSolution& o = out[static_cast<size_t>(count++)];
          o.theta = {th1, th2, th3, th234 - th2 - th3, th5, th6};
          o.branch = i1 * 4 + ib * 2 + is;
        }
      }
      if (s5abs <= kWristSingular) break;
    }
  }
  return count;
}

}  // namespace accura::calib::detail
