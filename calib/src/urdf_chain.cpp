// accura: a serial chain of joint frames -> accura's complete model (DH / Hayati links, base
// and tool transforms), and the check of the conversion against the chain's own FK.
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "accura/calib/errors.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/text.h"
#include "accura/calib/urdf.h"
#include "urdf_common.h"

namespace accura::calib {
namespace {

using urdf_detail::linkFrame;

// Angle (rad) of the rotation about unit `z` taking `from` to `to` (both perpendicular to z).
double angleAbout(const Eigen::Vector3d& z, const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  return std::atan2(from.cross(to).dot(z), from.dot(to));
}

// Wraps an angle to (-pi, pi].
double wrapPi(double a) {
  a = std::remainder(a, 2 * kPi);
  return a <= -kPi ? a + 2 * kPi : a;
}

// Sets round-off to zero and snaps values within 1e-12 of an integer multiple of `unit`.
double tidy(double v, double unit) {
  const double k = std::round(v / unit);
  if (std::abs(v - k * unit) < 1e-12) return k * unit == 0.0 ? 0.0 : k * unit;
  return v;
}

// The pose with round-off set to zero (through x, y, z, A, B, C).
Eigen::Isometry3d tidyPose(const Eigen::Isometry3d& T) {
  XyzAbc p = toXyzAbc(T);
  p.x_mm = tidy(p.x_mm, 1.0);
  p.y_mm = tidy(p.y_mm, 1.0);
  p.z_mm = tidy(p.z_mm, 1.0);
  p.a_deg = tidy(p.a_deg, 90.0);
  p.b_deg = tidy(p.b_deg, 90.0);
  p.c_deg = tidy(p.c_deg, 90.0);
  return toIsometry(p);
}

// Unit vector of `v` with its component along unit `z` removed; `fallback` when too short.
Eigen::Vector3d perpendicular(const Eigen::Vector3d& v, const Eigen::Vector3d& z,
                              const Eigen::Vector3d& fallback) {
  Eigen::Vector3d p = v - v.dot(z) * z;
  if (p.norm() < 1e-6) p = fallback - fallback.dot(z) * z;
  if (p.norm() < 1e-6) p = z.unitOrthogonal();
  return p.normalized();
}

// Link parameters in internal units (rad, mm).
struct LinkParams {
  double theta = 0, d = 0, a = 0, alpha = 0, beta = 0;
  LinkForm form = LinkForm::kDH;
};

// Deterministic pseudo-random numbers in [0, 1) (splitmix64), so the check is repeatable.
struct Uniform {
  std::uint64_t s = 0x9E3779B97F4A7C15ull;
  double operator()() {
    std::uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return static_cast<double>(z >> 11) * (1.0 / 9007199254740992.0);
  }
};

}  // namespace

Eigen::Isometry3d serialChainFK(const SerialChain& chain, const Eigen::VectorXd& q) {
  if (q.size() != static_cast<Eigen::Index>(chain.joints.size()))
    throw ArgumentError("serial chain '" + chain.name + "': expected " + std::to_string(chain.joints.size()) +
                        " joint values, got " + std::to_string(q.size()));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (size_t k = 0; k < chain.joints.size(); ++k) {
    const ChainJoint& j = chain.joints[k];
    T = T * j.T_prev_joint;
    if (j.type == JointType::kRevolute) {
      T.rotate(Eigen::AngleAxisd(q[static_cast<Eigen::Index>(k)] * kDegToRad, j.axis));
    } else {
      T.translate(q[static_cast<Eigen::Index>(k)] * j.axis);
    }
  }
  return T * chain.T_last_tip;
}

ChainComparison compareModelWithChain(const RobotModel& model, const SerialChain& chain, int samples) {
  ChainComparison c;
  Uniform rnd;
  const int n = model.dof();
  Eigen::VectorXd q(n);
  for (int s = 0; s < samples; ++s) {
    for (int i = 0; i < n; ++i) {
      const JointSpec& j = model.nominal.joints[static_cast<size_t>(i)];
      const double lo = std::max(j.lower, -360.0), hi = std::min(j.upper, 360.0);
      q[i] = s == 0 ? 0.0 : lo + (hi - lo) * rnd();
    }
    const Eigen::Isometry3d A = forwardKinematics(model, q);
    const Eigen::Isometry3d B = serialChainFK(chain, q);
    c.max_position_mm = std::max(c.max_position_mm, (A.translation() - B.translation()).norm());
    c.max_rotation_rad = std::max(c.max_rotation_rad, logSO3(A.linear().transpose() * B.linear()).norm());
  }
  return c;
}

namespace {

/// The chain's joint axes at q = 0 in the root frame and what the DH frames are fitted to.
struct ChainAxes {
  std::vector<Eigen::Vector3d> P, U;  ///< a point of joint k's axis and its direction (positive q)
  std::vector<Eigen::Vector3d> Z;     ///< DH z axis of frame k-1 (along joint k)
  std::vector<int> direction;         ///< the sign between q and theta / d
  Eigen::Isometry3d G_tip = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Isometry3d> G_joint;  ///< child frames of the joints at q = 0 (for the COM)
  std::vector<Eigen::Isometry3d> R_frame;  ///< with a reference: its frames 0..n in the world at q = 0
  std::vector<LinkForm> ref_forms;         ///< with a reference: its link forms
};

/// An error about joint `j` of `chain`: located at the joint's entry in its source file when
/// the chain has one (an InputError), else an ArgumentError.
[[noreturn]] void failAtJoint(const SerialChain& chain, const ChainJoint& j, const std::string& what) {
  if (!chain.source.empty() && j.line > 0) throw InputError(chain.source, j.line, std::max(j.column, 1), what);
  throw ArgumentError(what);
}

ChainAxes chainAxes(const SerialChain& chain, const RobotDefinition* reference, FormPolicy policy) {
  const int n = static_cast<int>(chain.joints.size());
  ChainAxes c;
  c.P.resize(n);
  c.U.resize(n);
  c.G_joint.resize(n);
  Eigen::Isometry3d G = Eigen::Isometry3d::Identity();
  for (int k = 0; k < n; ++k) {
    const ChainJoint& j = chain.joints[static_cast<size_t>(k)];
    G = G * j.T_prev_joint;
    c.G_joint[k] = G;
    c.P[k] = G.translation();
    c.U[k] = (G.linear() * j.axis).normalized();
  }
  c.G_tip = G * chain.T_last_tip;
  if (reference) {
    RobotModel ref = RobotModel::fromDefinition(*reference, policy);
    KinematicWorkspace ws;
    flangePose(ref, Eigen::VectorXd::Zero(n), PoseContext{}, ws);
    for (const auto& F : ws.T_base_frame) c.R_frame.push_back(reference->T_world_base * F);
    c.ref_forms = ref.forms;
  }
  c.Z.resize(n);
  c.direction.assign(n, 1);
  for (int k = 0; k < n; ++k) {
    // without a reference: z along the joint's axis, except where the axis is the previous
    // joint's turned round (FANUC's and Yaskawa's J3 against J2 in their ROS-Industrial URDFs):
    // z then along the previous z, the joint turning the other way (direction -1), so the two
    // axes are parallel with alpha 0, not 180 deg (the closed-form IK and the Hayati form are
    // those of parallel axes: the same arm)
    // (two revolute joints: a prismatic one's direction also signs its gravity load)
    Eigen::Vector3d own = c.U[k];
    if (k > 0 && chain.joints[static_cast<size_t>(k)].type == JointType::kRevolute &&
        chain.joints[static_cast<size_t>(k - 1)].type == JointType::kRevolute && c.U[k].dot(c.Z[k - 1]) < -1 + 1e-12)
      own = c.Z[k - 1];  // (within 1.4e-6 rad)
    const Eigen::Vector3d hint = reference ? Eigen::Vector3d(c.R_frame[k].linear().col(2))
                                           : (k == 0 ? Eigen::Vector3d::UnitZ() : own);
    c.direction[k] = c.U[k].dot(hint) >= 0 ? 1 : -1;
    c.Z[k] = c.direction[k] * c.U[k];
    if (reference && c.direction[k] != reference->joints[static_cast<size_t>(k)].direction) {
      const ChainJoint& j = chain.joints[static_cast<size_t>(k)];
      const std::string what = "joint '" + j.name + "': expected it to turn the way joint '" +
                               reference->joints[static_cast<size_t>(k)].name + "' of the reference robot '" +
                               reference->name + "' turns (direction " +
                               std::to_string(reference->joints[static_cast<size_t>(k)].direction) +
                               "), found it turning the other way (direction " + std::to_string(c.direction[k]) +
                               ": its axis at q = 0 points against the reference's)";
      failAtJoint(chain, j, what);
    }
  }
  return c;
}

/// Frame 0: on axis 1, origin the foot of the perpendicular from the root's (or the reference
/// base's) origin, x from the root's (reference base's) x.
Eigen::Isometry3d baseFrame(const ChainAxes& c, bool reference) {
  const Eigen::Isometry3d base_hint = reference ? c.R_frame[0] : Eigen::Isometry3d::Identity();
  Eigen::Isometry3d F = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d o = c.P[0] + (base_hint.translation() - c.P[0]).dot(c.Z[0]) * c.Z[0];
  const Eigen::Vector3d x = perpendicular(base_hint.linear().col(0), c.Z[0], base_hint.linear().col(1));
  F.linear().col(0) = x;
  F.linear().col(1) = c.Z[0].cross(x);
  F.linear().col(2) = c.Z[0];
  F.translation() = o;
  return F;
}

/// Link i (< n - 1) from frame F to axis i+1: Hayati (frame i's origin where axis i+1 crosses
/// the plane normal to z at height d) or DH (the common normal of the two axes).
LinkParams innerLink(const SerialChain& chain, const RobotDefinition* reference, FormPolicy policy, const ChainAxes& c, int i,
                     const Eigen::Isometry3d& F) {
  const Eigen::Vector3d z = F.linear().col(2), x_prev = F.linear().col(0), o = F.translation();
  const Eigen::Vector3d& Zn = c.Z[i + 1];
  const Eigen::Vector3d& Pn = c.P[i + 1];
  const double s = z.cross(Zn).norm();
  const bool hayati = reference ? c.ref_forms[i] == LinkForm::kHayati
                                : policy == FormPolicy::kAuto && s < std::sin(kHayatiThresholdDeg * kDegToRad);
  const Eigen::Vector3d x_hint = reference ? Eigen::Vector3d(c.R_frame[i + 1].linear().col(0)) : x_prev;
  LinkParams L;
  Eigen::Vector3d x;
  // DH with exactly parallel axes where the reference uses DH (a UR's links 2 and 3, d = 0: its
  // nominal arm, an offsets-only calibration): the common normal may lie anywhere along the axis,
  // and the reference's d picks it; the link is then the Hayati construction with beta = 0
  const bool parallel_dh = !hayati && reference && s < 1e-9;
  if (hayati || parallel_dh) {
    L.form = parallel_dh ? LinkForm::kDH : LinkForm::kHayati;
    L.d = reference ? reference->joints[static_cast<size_t>(i)].d_mm : 0.0;
    const Eigen::Vector3d o2 = o + L.d * z;
    const double cz = Zn.dot(z);
    const Eigen::Vector3d B = Pn + ((o2 - Pn).dot(z) / cz) * Zn;
    Eigen::Vector3d v = B - o2;
    v -= v.dot(z) * z;
    if (v.norm() > 1e-9) {
      x = v.normalized();
      if (x.dot(x_hint) < 0) x = -x;
    } else {
      x = perpendicular(x_hint, z, x_prev);
    }
    L.a = v.dot(x);
    L.theta = angleAbout(z, x_prev, x);
    const Eigen::Vector3d y = z.cross(x);
    if (parallel_dh) {
      L.alpha = std::atan2(Zn.dot(x.cross(z)), Zn.dot(z));  // 0 or pi: the axes are parallel
      return L;
    }
    L.beta = std::asin(std::max(-1.0, std::min(1.0, Zn.dot(x))));
    L.alpha = std::atan2(-Zn.dot(y), Zn.dot(z));
    return L;
  }
  if (s < 1e-9) {
    const ChainJoint& j = chain.joints[static_cast<size_t>(i + 1)];
    const std::string what = "joint '" + j.name + "': expected an axis DH can describe after joint '" +
                             chain.joints[static_cast<size_t>(i)].name +
                             "' (the reference robot uses DH for link " + std::to_string(i + 1) +
                             "), found it parallel to that joint's axis";
    failAtJoint(chain, j, what);
  }
  L.form = LinkForm::kDH;
  x = z.cross(Zn).normalized();
  if (x.dot(x_hint) < 0 || (std::abs(x.dot(x_hint)) < 1e-9 && x.dot(z.cross(x_hint)) < 0)) x = -x;
  // Closest points of the two axes: o + t z and Pn + u Zn.
  const Eigen::Vector3d w0 = o - Pn;
  const double b = z.dot(Zn), dd = z.dot(w0), e = Zn.dot(w0), den = 1 - b * b;
  const double t = (b * e - dd) / den, u = (e - b * dd) / den;
  L.d = t;
  L.a = ((Pn + u * Zn) - (o + t * z)).dot(x);
  L.theta = angleAbout(z, x_prev, x);
  L.alpha = std::atan2(Zn.dot(x.cross(z)), Zn.dot(z));
  return L;
}

/// The last link (DH) from frame F: as close to the target frame as four parameters get.
LinkParams lastLink(const Eigen::Isometry3d& last_target, const Eigen::Isometry3d& F) {
  const Eigen::Vector3d z = F.linear().col(2), x_prev = F.linear().col(0), o = F.translation();
  LinkParams L;
  L.form = LinkForm::kDH;
  const Eigen::Vector3d pt = last_target.translation();
  const Eigen::Vector3d x = perpendicular(last_target.linear().col(0), z, last_target.linear().col(1));
  const Eigen::Vector3d Zt = last_target.linear().col(2);
  L.d = (pt - o).dot(z);
  L.a = (pt - o).dot(x);
  L.theta = angleAbout(z, x_prev, x);
  L.alpha = std::atan2(Zt.dot(x.cross(z)), Zt.dot(z));
  return L;
}

/// The reference robot with the chain as its deviations (base, links, tool); round-off of
/// transforms that are exact (1e-12 mm, 1e-15 rad) set to zero.
RobotModel referenceWithDeviations(const RobotDefinition& reference, FormPolicy policy, const Eigen::Isometry3d& F0,
                                   const std::vector<LinkParams>& links, const Eigen::Isometry3d& T_tool) {
  RobotModel model = RobotModel::fromDefinition(reference, policy);
  Deviations& dev = model.deviations;
  const Eigen::Isometry3d& Tb = reference.T_world_base;
  dev.base_mm = Tb.linear().transpose() * (F0.translation() - Tb.translation());
  dev.base_rot_rad = logSO3(Tb.linear().transpose() * F0.linear());
  for (size_t i = 0; i < links.size(); ++i) {
    const JointSpec& j = reference.joints[i];
    const LinkParams& L = links[i];
    LinkDeviation& d = dev.links[i];
    d.dtheta_rad = wrapPi(L.theta - j.theta0_deg * kDegToRad);
    d.dd_mm = L.d - j.d_mm;
    if (L.form == LinkForm::kHayati && j.type == JointType::kRevolute) d.dd_mm = 0;  // d kept
    d.da_mm = L.a - j.a_mm;
    d.dalpha_rad = wrapPi(L.alpha - j.alpha_deg * kDegToRad);
    d.dbeta_rad = L.beta;
  }
  const Eigen::Isometry3d& Tt = reference.T_flange_tcp;
  dev.tool_mm = Tt.linear().transpose() * (T_tool.translation() - Tt.translation());
  dev.tool_rot_rad = logSO3(Tt.linear().transpose() * T_tool.linear());
  const auto zap = [](double& v, double tiny) { if (std::abs(v) < tiny) v = 0; };
  for (int r = 0; r < 3; ++r) {
    zap(dev.base_mm[r], 1e-12);
    zap(dev.tool_mm[r], 1e-12);
    zap(dev.base_rot_rad[r], 1e-15);
    zap(dev.tool_rot_rad[r], 1e-15);
  }
  for (LinkDeviation& d : dev.links) {
    zap(d.dd_mm, 1e-12);
    zap(d.da_mm, 1e-12);
    zap(d.dtheta_rad, 1e-15);
    zap(d.dalpha_rad, 1e-15);
    zap(d.dbeta_rad, 1e-15);
  }
  return model;
}

/// A new robot definition of the chain's links (values tidied), its model in `policy`'s forms.
RobotModel newRobot(const SerialChain& chain, FormPolicy policy, const ChainAxes& c, const Eigen::Isometry3d& F0,
                    const std::vector<LinkParams>& links, const std::vector<Eigen::Isometry3d>& frames) {
  const int n = static_cast<int>(links.size());
  RobotDefinition def;
  def.name = chain.name;
  def.source = chain.source + " (serial chain " + chain.root_link + ":" + chain.tip_link + ")";
  def.T_world_base = tidyPose(F0);
  def.T_flange_tcp = tidyPose(frames[n].inverse() * c.G_tip);
  // ROS convention (REP-103): the root's z points up; gravity in the base (DH frame 0).
  def.gravity_base = def.T_world_base.linear().transpose() * Eigen::Vector3d(0, 0, -9.80665);
  for (int r = 0; r < 3; ++r) def.gravity_base[r] = tidy(def.gravity_base[r], 1.0);
  for (int i = 0; i < n; ++i) {
    const ChainJoint& cj = chain.joints[static_cast<size_t>(i)];
    const LinkParams& L = links[i];
    JointSpec s;
    s.name = cj.name;
    s.type = cj.type;
    s.a_mm = L.a;
    s.alpha_deg = L.alpha * kRadToDeg;
    s.d_mm = L.d;
    s.theta0_deg = L.theta * kRadToDeg;
    s.direction = c.direction[i];
    s.lower = cj.lower;
    s.upper = cj.upper;
    s.mass_kg = cj.mass_kg;
    // The joint's child frame and DH frame i+1 are fixed to the same body.
    const Eigen::Vector3d com = frames[i + 1].inverse() * (c.G_joint[i] * cj.com_mm);
    s.com_mm = cj.mass_kg > 0 ? com : Eigen::Vector3d::Zero();
    for (int r = 0; r < 3; ++r) s.com_mm[r] = tidy(s.com_mm[r], 1.0);
    def.joints.push_back(s);
  }
  RobotModel model = RobotModel::fromDefinition(def, policy);
  for (int i = 0; i < n; ++i) {
    if (model.forms[static_cast<size_t>(i)] != links[i].form) {
      // The form follows from alpha (robot.h); a link right at the threshold may flip. The
      // transform is the same at beta = 0, so only a non-zero beta is a problem.
      if (links[i].beta != 0.0)
        throw NumericalError("joint '" + def.joints[static_cast<size_t>(i)].name +
                             "': axes at the Hayati threshold angle, the form is ambiguous");
    }
    model.deviations.links[static_cast<size_t>(i)].dbeta_rad = links[i].beta;
  }
  return model;
}

}  // namespace

/// The steps: the chain's axes, frame 0, the links one by one (each frame from the previous),
/// the model (the reference's deviations, or a new robot), the check against the chain's FK.
RobotModel modelFromChain(const SerialChain& chain, const RobotDefinition* reference, FormPolicy policy,
                          double tol_mm) {
  const int n = static_cast<int>(chain.joints.size());
  if (n == 0) throw ArgumentError("serial chain '" + chain.name + "' (" + chain.source + "): no moving joint between '" +
                                  chain.root_link + "' and '" + chain.tip_link + "'");
  if (reference && reference->dof() != n)
    throw ArgumentError("serial chain '" + chain.name + "': " + std::to_string(n) + " joints, the reference robot '" +
                        reference->name + "' has " + std::to_string(reference->dof()));
  const ChainAxes c = chainAxes(chain, reference, policy);
  const Eigen::Isometry3d F0 = baseFrame(c, reference != nullptr);
  Eigen::Isometry3d F = F0;
  std::vector<LinkParams> links(n);
  std::vector<Eigen::Isometry3d> frames(n + 1);
  frames[0] = F0;
  // The target of the last link: the tip (or, with a reference, the flange its tool implies).
  const Eigen::Isometry3d last_target = reference ? c.G_tip * reference->T_flange_tcp.inverse() : c.G_tip;
  for (int i = 0; i < n; ++i) {
    LinkParams& L = links[i];
    L = i + 1 < n ? innerLink(chain, reference, policy, c, i, F) : lastLink(last_target, F);
    if (!reference) {
      L.d = tidy(L.d, 1.0);
      L.a = tidy(L.a, 1.0);
      L.theta = tidy(L.theta * kRadToDeg, 90.0) * kDegToRad;
      L.alpha = tidy(L.alpha * kRadToDeg, 90.0) * kDegToRad;
      L.beta = tidy(L.beta * kRadToDeg, 90.0) * kDegToRad;
    }
    F = F * linkFrame(L.theta, L.d, L.a, L.alpha, L.beta);
    frames[i + 1] = F;
  }
  RobotModel model = reference ? referenceWithDeviations(*reference, policy, F0, links, frames[n].inverse() * c.G_tip)
                               : newRobot(chain, policy, c, F0, links, frames);
  model.validate();

  const ChainComparison cmp = compareModelWithChain(model, chain);
  // tol_mm holds for an arm of up to a metre; beyond, rounding grows with the lengths (double
  // precision is relative), so the tolerance scales with the chain's extent
  double extent_mm = last_target.translation().norm();
  for (const Eigen::Isometry3d& f : frames) extent_mm = std::max(extent_mm, f.translation().norm());
  tol_mm *= std::max(1.0, extent_mm / 1000.0);
  const double tol_rad = tol_mm * (kChainCheckTolRad / kChainCheckTolMm);
  if (!(cmp.max_position_mm <= tol_mm) || !(cmp.max_rotation_rad <= tol_rad)) {
    throw NumericalError("converting the serial chain " + chain.root_link + ":" + chain.tip_link + " of '" +
                         chain.source + "' into accura's model: the model's FK differs from the chain's by " +
                         formatNumber("%.3g", cmp.max_position_mm) + " mm / " + formatNumber("%.3g", cmp.max_rotation_rad) +
                         " rad (allowed " + formatNumber("%.3g", tol_mm) + " mm / " + formatNumber("%.3g", tol_rad) + " rad)");
  }
  return model;
}

}  // namespace accura::calib
