#include "accura/calib/kinematics.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "accura/calib/errors.h"
#include "accura/calib/joint_map.h"

namespace accura {
namespace {

void checkJointCount(const RobotModel& model, const Eigen::VectorXd& q) {
  if (q.size() != model.dof()) {
    throw ArgumentError("expected " + std::to_string(model.dof()) + " joint values, got " +
                        std::to_string(q.size()));
  }
}

// Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta), written out (hot path).
Eigen::Isometry3d linkTransform(double theta, double d, double a, double alpha, double beta) {
  const double ct = std::cos(theta), st = std::sin(theta);
  const double ca = std::cos(alpha), sa = std::sin(alpha);
  Eigen::Isometry3d T;
  Eigen::Matrix3d R;
  R << ct, -st * ca, st * sa,
       st, ct * ca, -ct * sa,
       0, sa, ca;
  if (beta != 0.0) {
    const double cb = std::cos(beta), sb = std::sin(beta);
    Eigen::Matrix3d Ry;
    Ry << cb, 0, sb, 0, 1, 0, -sb, 0, cb;
    R = R * Ry;
  }
  T.linear() = R;
  T.translation() = Eigen::Vector3d(a * ct, a * st, d);
  T.makeAffine();
  return T;
}

struct LinkValues {
  double theta, d, a, alpha, beta;
};

// Thermal length scale (1 + alpha (temp_c - T_ref)) of the model in `context`.
double thermalScale(const RobotModel& model, const PoseContext& context) {
  const double alpha = model.deviations.thermal_alpha_per_k;
  if (alpha == 0.0) return 1.0;
  return 1.0 + alpha * (context.temp_c - kThermalReferenceC);
}

// Approach direction of joint i (0 when unknown).
double direction(const PoseContext& context, int i) {
  if (context.dir.empty()) return 0.0;
  if (static_cast<int>(context.dir.size()) <= i)
    throw ArgumentError("pose context: expected " + std::to_string(i + 1) + " or more approach directions, got " +
                        std::to_string(context.dir.size()));
  return context.dir[static_cast<size_t>(i)] >= 0 ? 1.0 : -1.0;
}

// The joint-space terms of the effect catalogue for joint i at q (deg or mm): rad for a
// revolute joint, mm for a prismatic one.
double jointEffects(const RobotModel& model, int i, double q, const PoseContext& context) {
  const Deviations& dev = model.deviations;
  const bool revolute = model.nominal.joints[i].type == JointType::kRevolute;
  const double qi = revolute ? q * kDegToRad : q;
  double t = 0;
  if (dev.joint_scale[i] != 0.0) t += dev.joint_scale[i] * qi;
  if (dev.backlash[i] != 0.0) t += 0.5 * dev.backlash[i] * direction(context, i);
  if (revolute) {
    const int H = dev.gear_harmonics;
    for (int h = 1; h <= H; ++h) {
      const double s = dev.gear_sin[i * H + h - 1], c = dev.gear_cos[i * H + h - 1];
      if (s != 0.0) t += s * std::sin(h * qi);
      if (c != 0.0) t += c * std::cos(h * qi);
    }
  }
  if (!dev.joint_map[i].empty()) t += jointMapValue(dev.joint_map[i], q);
  return t;
}

// True when any joint-space effect of the catalogue (gear, scale, backlash) is non-zero.
bool anyJointEffects(const Deviations& d) {
  // OR of the bit patterns without the sign bit: zero only when every value is +-0 (a short
  // dependency chain and no branches: this runs on every forward kinematics call)
  std::uint64_t acc = 0;
  auto fold = [&acc](const std::vector<double>& v) {
    for (double x : v) {
      std::uint64_t bits;
      std::memcpy(&bits, &x, sizeof bits);
      acc |= bits;
    }
  };
  fold(d.joint_scale);
  fold(d.backlash);
  fold(d.gear_sin);
  fold(d.gear_cos);
  for (const JointMap& m : d.joint_map) fold(m.coef);
  return (acc & ~(std::uint64_t(1) << 63)) != 0;
}

// DH values of link i with deviations, the load-dependent compliance term and, when
// `effects`, the joint-space effects of the catalogue; `scale` is the thermal length scale.
LinkValues linkValues(const RobotModel& model, int i, double q, double load, const PoseContext& context,
                      double scale, bool effects) {
  const JointSpec& j = model.nominal.joints[i];
  const LinkDeviation& dev = model.deviations.links[i];
  const double c = model.deviations.compliance[i];
  const double extra = effects ? jointEffects(model, i, q, context) : 0.0;
  LinkValues v;
  v.theta = j.theta0_deg * kDegToRad + dev.dtheta_rad;
  v.d = (j.d_mm + dev.dd_mm) * scale;
  if (j.type == JointType::kRevolute) {
    v.theta += j.direction * q * kDegToRad + c * load + extra;
  } else {
    v.d += j.direction * q + c * load + extra;
  }
  v.a = (j.a_mm + dev.da_mm) * scale;
  v.alpha = j.alpha_deg * kDegToRad + dev.dalpha_rad;
  v.beta = dev.dbeta_rad;
  return v;
}

bool anyCompliance(const RobotModel& model) {
  for (double c : model.deviations.compliance)
    if (c != 0.0) return true;
  return false;
}

// Frames 0..n in the base frame, deviations included.
// Loads are computed when a compliance is non-zero or `need_loads` (the Jacobian's
// compliance columns need them even at zero compliance).
void computeFrames(const RobotModel& model, const Eigen::VectorXd& q, const PoseContext& context,
                   KinematicWorkspace& ws, bool need_loads = false) {
  model.validate();
  checkJointCount(model, q);
  const int n = model.dof();
  ws.T_base_frame.resize(n + 1);
  ws.theta_rad.resize(n);
  ws.d_mm.resize(n);
  if (need_loads || anyCompliance(model)) {
    ws.load = gravityLoads(model, q, context);
  } else {
    ws.load.setZero(n);
  }
  const double scale = thermalScale(model, context);
  const bool effects = anyJointEffects(model.deviations);
  ws.T_base_frame[0].setIdentity();
  for (int i = 0; i < n; ++i) {
    const LinkValues v = linkValues(model, i, q[i], ws.load[i], context, scale, effects);
    ws.theta_rad[i] = v.theta;
    ws.d_mm[i] = v.d;
    ws.T_base_frame[i + 1] = ws.T_base_frame[i] * linkTransform(v.theta, v.d, v.a, v.alpha, v.beta);
  }
}

}  // namespace

Eigen::VectorXd gravityLoads(const RobotModel& model, const Eigen::VectorXd& q,
                             const PoseContext& context) {
  checkJointCount(model, q);
  const int n = model.dof();
  // nominal geometry
  std::vector<Eigen::Isometry3d> F(n + 1);
  F[0].setIdentity();
  for (int i = 0; i < n; ++i) {
    const JointSpec& j = model.nominal.joints[i];
    double theta = j.theta0_deg * kDegToRad, d = j.d_mm;
    if (j.type == JointType::kRevolute) {
      theta += j.direction * q[i] * kDegToRad;
    } else {
      d += j.direction * q[i];
    }
    F[i + 1] = F[i] * linkTransform(theta, d, j.a_mm, j.alpha_deg * kDegToRad, 0.0);
  }
  const Eigen::Vector3d g = model.nominal.gravity_base;
  // Accumulate, from the tip inwards, the total mass and first moment (kg*mm) of links i..n
  // and the payload.
  double mass = context.payload_kg;
  Eigen::Vector3d moment = context.payload_kg * (F[n] * model.nominal.payload_com_mm);
  Eigen::VectorXd load(n);
  for (int i = n - 1; i >= 0; --i) {
    const JointSpec& j = model.nominal.joints[i];
    mass += j.mass_kg;
    moment += j.mass_kg * (F[i + 1] * j.com_mm);
    const Eigen::Vector3d z = F[i].linear().col(2);
    const Eigen::Vector3d o = F[i].translation();
    if (j.type == JointType::kRevolute) {
      // sum m_j (c_j - o) x g, in N*mm -> N*m
      const Eigen::Vector3d r = moment - mass * o;
      load[i] = z.dot(r.cross(g)) * 1e-3;
    } else {
      load[i] = z.dot(mass * g);
    }
  }
  return load;
}

Eigen::Isometry3d flangePose(const RobotModel& model, const Eigen::VectorXd& q,
                             const PoseContext& context, KinematicWorkspace& ws) {
  computeFrames(model, q, context, ws);
  return ws.T_base_frame.back();
}

Eigen::Isometry3d forwardKinematics(const RobotModel& model, const Eigen::VectorXd& q,
                                    const PoseContext& context, KinematicWorkspace& ws) {
  computeFrames(model, q, context, ws);
  return model.T_world_base() * ws.T_base_frame.back() * model.T_flange_tcp();
}

Eigen::Isometry3d forwardKinematics(const RobotModel& model, const Eigen::VectorXd& q) {
  KinematicWorkspace ws;
  return forwardKinematics(model, q, PoseContext{}, ws);
}

std::vector<std::pair<std::string, std::string>> parameterGroups() {
  return {
      {"geometric", "the complete geometric model: base, tool, offsets, lengths, angles"},
      {"base", "T_world_base: 3 translations (mm), 3 rotations (deg)"},
      {"tool", "T_flange_tcp: 3 translations (mm), plus 3 rotations (deg) with orientation data"},
      {"offsets", "joint zero offsets (deg, or mm for prismatic joints)"},
      {"lengths", "DH lengths a and d (mm)"},
      {"angles", "DH twists alpha, Hayati beta, prismatic theta (deg)"},
      {"joint_compliance", "dtheta_i = c_i * tau_i, tau_i the gravity torque (urad/Nm)"},
      {"gear_periodic", "dtheta_i = sum_h s_ih sin(h q_i) + c_ih cos(h q_i), h = 1..H (deg)"},
      {"joint_scale", "dtheta_i = k_i q_i, gear ratio or encoder scale error (ppm)"},
      {"backlash", "dtheta_i = (b_i / 2) dir_i, from the dirN columns (deg; mm for prismatic joints)"},
      {"thermal", "a_i, d_i scale by 1 + alpha (temp_c - 20 C), one alpha per robot (ppm/K)"},
      {"joint_map", "dtheta_i = m_i(q_i), a smooth map over the joint's own angle where the fit data cover it (deg)"},
  };
}

const std::vector<std::string>& effectCatalogue() {
  static const std::vector<std::string> names = {"joint_compliance", "gear_periodic", "joint_scale", "backlash",
                                                 "thermal", "joint_map"};
  return names;
}

std::vector<ParamInfo> parameterLayout(const RobotModel& model) {
  std::vector<ParamInfo> L;
  const double deg = kRadToDeg;
  const char* axes[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k)
    L.push_back({static_cast<ParamKind>(static_cast<int>(ParamKind::kBaseX) + k), -1,
                 std::string("base_") + axes[k], "base", "mm", 1.0});
  for (int k = 0; k < 3; ++k)
    L.push_back({static_cast<ParamKind>(static_cast<int>(ParamKind::kBaseRx) + k), -1,
                 std::string("base_r") + axes[k], "base", "deg", deg});
  for (int k = 0; k < 3; ++k)
    L.push_back({static_cast<ParamKind>(static_cast<int>(ParamKind::kToolX) + k), -1,
                 std::string("tool_") + axes[k], "tool", "mm", 1.0});
  for (int k = 0; k < 3; ++k)
    L.push_back({static_cast<ParamKind>(static_cast<int>(ParamKind::kToolRx) + k), -1,
                 std::string("tool_r") + axes[k], "tool", "deg", deg});
  for (int i = 0; i < model.dof(); ++i) {
    const std::string j = "j" + std::to_string(i + 1) + "_";
    const bool revolute = model.nominal.joints[i].type == JointType::kRevolute;
    const bool hayati = model.forms[i] == LinkForm::kHayati;
    // the joint zero: dtheta of a revolute joint, dd of a prismatic one
    L.push_back({revolute ? ParamKind::kOffset : ParamKind::kD, i, j + "offset", "offsets",
                 revolute ? "deg" : "mm", revolute ? deg : 1.0});
    if (revolute && !hayati) L.push_back({ParamKind::kD, i, j + "d", "lengths", "mm", 1.0});
    if (!revolute) L.push_back({ParamKind::kTheta, i, j + "theta", "angles", "deg", deg});
    L.push_back({ParamKind::kA, i, j + "a", "lengths", "mm", 1.0});
    L.push_back({ParamKind::kAlpha, i, j + "alpha", "angles", "deg", deg});
    if (hayati) L.push_back({ParamKind::kBeta, i, j + "beta", "angles", "deg", deg});
  }
  for (int i = 0; i < model.dof(); ++i) {
    const bool revolute = model.nominal.joints[i].type == JointType::kRevolute;
    L.push_back({ParamKind::kCompliance, i, "j" + std::to_string(i + 1) + "_compliance",
                 "joint_compliance", revolute ? "urad/Nm" : "um/N", revolute ? 1e6 : 1e3});
  }
  const int H = model.deviations.gear_harmonics;
  for (int i = 0; i < model.dof(); ++i) {
    if (model.nominal.joints[i].type != JointType::kRevolute) continue;
    const std::string j = "j" + std::to_string(i + 1) + "_gear_";
    for (int h = 1; h <= H; ++h) {
      L.push_back({ParamKind::kGearSin, i, j + "s" + std::to_string(h), "gear_periodic", "deg", deg, h});
      L.push_back({ParamKind::kGearCos, i, j + "c" + std::to_string(h), "gear_periodic", "deg", deg, h});
    }
  }
  for (int i = 0; i < model.dof(); ++i)
    L.push_back({ParamKind::kJointScale, i, "j" + std::to_string(i + 1) + "_scale", "joint_scale", "ppm", 1e6});
  for (int i = 0; i < model.dof(); ++i) {
    const bool revolute = model.nominal.joints[i].type == JointType::kRevolute;
    L.push_back({ParamKind::kBacklash, i, "j" + std::to_string(i + 1) + "_backlash", "backlash",
                 revolute ? "deg" : "mm", revolute ? deg : 1.0});
  }
  L.push_back({ParamKind::kThermal, -1, "thermal_alpha", "thermal", "ppm/K", 1e6});
  for (int i = 0; i < model.dof(); ++i) {
    const JointMap& jm = model.deviations.joint_map[static_cast<size_t>(i)];
    const bool revolute = model.nominal.joints[i].type == JointType::kRevolute;
    for (int k = 0; k < static_cast<int>(jm.coef.size()); ++k)
      L.push_back({ParamKind::kJointMap, i, "j" + std::to_string(i + 1) + "_map_" + std::to_string(k), "joint_map",
                   revolute ? "deg" : "mm", revolute ? deg : 1.0, 0, k});
  }
  return L;
}

namespace {
double* slot(Deviations& dev, const ParamInfo& p) {
  switch (p.kind) {
    case ParamKind::kBaseX: return &dev.base_mm[0];
    case ParamKind::kBaseY: return &dev.base_mm[1];
    case ParamKind::kBaseZ: return &dev.base_mm[2];
    case ParamKind::kBaseRx: return &dev.base_rot_rad[0];
    case ParamKind::kBaseRy: return &dev.base_rot_rad[1];
    case ParamKind::kBaseRz: return &dev.base_rot_rad[2];
    case ParamKind::kToolX: return &dev.tool_mm[0];
    case ParamKind::kToolY: return &dev.tool_mm[1];
    case ParamKind::kToolZ: return &dev.tool_mm[2];
    case ParamKind::kToolRx: return &dev.tool_rot_rad[0];
    case ParamKind::kToolRy: return &dev.tool_rot_rad[1];
    case ParamKind::kToolRz: return &dev.tool_rot_rad[2];
    case ParamKind::kThermal: return &dev.thermal_alpha_per_k;
    default: break;
  }
  if (p.joint < 0 || p.joint >= static_cast<int>(dev.links.size()))
    throw ArgumentError("parameter " + p.name + ": joint index out of range");
  LinkDeviation& L = dev.links[p.joint];
  switch (p.kind) {
    case ParamKind::kOffset:
    case ParamKind::kTheta: return &L.dtheta_rad;
    case ParamKind::kD: return &L.dd_mm;
    case ParamKind::kA: return &L.da_mm;
    case ParamKind::kAlpha: return &L.dalpha_rad;
    case ParamKind::kBeta: return &L.dbeta_rad;
    case ParamKind::kCompliance: return &dev.compliance[p.joint];
    case ParamKind::kJointScale: return &dev.joint_scale[p.joint];
    case ParamKind::kBacklash: return &dev.backlash[p.joint];
    case ParamKind::kJointMap: {
      std::vector<double>& c = dev.joint_map[static_cast<size_t>(p.joint)].coef;
      if (p.index < 0 || p.index >= static_cast<int>(c.size()))
        throw ArgumentError("parameter " + p.name + ": joint map coefficient out of range");
      return &c[static_cast<size_t>(p.index)];
    }
    case ParamKind::kGearSin:
    case ParamKind::kGearCos: {
      const int H = dev.gear_harmonics;
      if (p.harmonic < 1 || p.harmonic > H)
        throw ArgumentError("parameter " + p.name + ": harmonic out of range 1.." + std::to_string(H));
      std::vector<double>& v = p.kind == ParamKind::kGearSin ? dev.gear_sin : dev.gear_cos;
      const size_t k = static_cast<size_t>(p.joint * H + p.harmonic - 1);
      if (k >= v.size()) throw ArgumentError("parameter " + p.name + ": gear_periodic values not sized");
      return &v[k];
    }
    default: break;
  }
  throw ArgumentError("parameter " + p.name + ": unknown kind");
}
}  // namespace

double getParameter(const Deviations& dev, const ParamInfo& p) {
  return *slot(const_cast<Deviations&>(dev), p);
}

void setParameter(Deviations& dev, const ParamInfo& p, double value) { *slot(dev, p) = value; }

Eigen::Isometry3d parameterJacobian(const RobotModel& model, const std::vector<ParamInfo>& layout,
                                    const Eigen::VectorXd& q, const PoseContext& context,
                                    KinematicWorkspace& ws, Eigen::MatrixXd& J) {
  const bool compliance_columns = std::any_of(layout.begin(), layout.end(), [](const ParamInfo& p) {
    return p.kind == ParamKind::kCompliance;
  });
  computeFrames(model, q, context, ws, compliance_columns);
  const int n = model.dof();
  const Eigen::Isometry3d T_wb = model.T_world_base();
  const Eigen::Isometry3d T_w_flange = T_wb * ws.T_base_frame[n];
  const Eigen::Isometry3d T_w_tcp = T_w_flange * model.T_flange_tcp();
  const Eigen::Vector3d p = T_w_tcp.translation();
  const Eigen::Matrix3d Jr_base = rightJacobianSO3(model.deviations.base_rot_rad);
  const Eigen::Matrix3d Jr_tool = rightJacobianSO3(model.deviations.tool_rot_rad);
  const Eigen::Matrix3d R_w_toolnom =
      T_w_flange.linear() * model.nominal.T_flange_tcp.linear();
  const Eigen::Matrix3d R_w_basenom = model.nominal.T_world_base.linear();

  const double scale = thermalScale(model, context);

  J.setZero(6, static_cast<Eigen::Index>(layout.size()));
  auto translation = [&](Eigen::Index col, const Eigen::Vector3d& u) { J.col(col).head<3>() = u; };
  auto rotation = [&](Eigen::Index col, const Eigen::Vector3d& u, const Eigen::Vector3d& o) {
    J.col(col).head<3>() = u.cross(p - o);
    J.col(col).tail<3>() = u;
  };
  // Intermediate frames of link i in the world: M0 = F_{i-1}, M1 = M0 Rz Tz, M2 = M1 Tx,
  // M3 = M2 Rx: the axes and origins the columns need, once per link.
  // Columns of ws.link_axes[i]: z0, o0, x1, o2, y3.
  ws.link_axes.resize(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    Eigen::Matrix<double, 3, 5>& A = ws.link_axes[static_cast<size_t>(i)];
    const Eigen::Matrix3d R0 = T_wb.linear() * ws.T_base_frame[i].linear();
    A.col(0) = R0.col(2);
    A.col(1) = T_wb * ws.T_base_frame[i].translation();
    const double ct = std::cos(ws.theta_rad[i]), st = std::sin(ws.theta_rad[i]);
    // M1 = M0 Rz(theta) Tz(d): x axis and origin
    A.col(2) = R0 * Eigen::Vector3d(ct, st, 0);
    const double a = (model.nominal.joints[i].a_mm + model.deviations.links[i].da_mm) * scale;
    A.col(3) = A.col(1) + ws.d_mm[i] * A.col(0) + a * A.col(2);
    // y axis of M3 = M2 Rx(alpha): Rz(theta) Rx(alpha) e_y in frame i-1
    const double alpha = model.nominal.joints[i].alpha_deg * kDegToRad + model.deviations.links[i].dalpha_rad;
    A.col(4) = R0 * Eigen::Vector3d(-st * std::cos(alpha), ct * std::cos(alpha), std::sin(alpha));
  }
  for (size_t k = 0; k < layout.size(); ++k) {
    const ParamInfo& P = layout[k];
    const Eigen::Index col = static_cast<Eigen::Index>(k);
    switch (P.kind) {
      case ParamKind::kBaseX:
      case ParamKind::kBaseY:
      case ParamKind::kBaseZ:
        translation(col, R_w_basenom.col(static_cast<int>(P.kind) - static_cast<int>(ParamKind::kBaseX)));
        continue;
      case ParamKind::kBaseRx:
      case ParamKind::kBaseRy:
      case ParamKind::kBaseRz: {
        const int a = static_cast<int>(P.kind) - static_cast<int>(ParamKind::kBaseRx);
        rotation(col, T_wb.linear() * Jr_base.col(a), T_wb.translation());
        continue;
      }
      case ParamKind::kToolX:
      case ParamKind::kToolY:
      case ParamKind::kToolZ:
        translation(col, R_w_toolnom.col(static_cast<int>(P.kind) - static_cast<int>(ParamKind::kToolX)));
        continue;
      case ParamKind::kToolRx:
      case ParamKind::kToolRy:
      case ParamKind::kToolRz: {
        const int a = static_cast<int>(P.kind) - static_cast<int>(ParamKind::kToolRx);
        rotation(col, T_w_tcp.linear() * Jr_tool.col(a), p);
        continue;
      }
      case ParamKind::kThermal: {
        // d/d alpha: every link length moves by (temp_c - T_ref) times its value
        const double dT = context.temp_c - kThermalReferenceC;
        Eigen::Vector3d u = Eigen::Vector3d::Zero();
        for (int i = 0; i < n; ++i) {
          const JointSpec& js = model.nominal.joints[i];
          const LinkDeviation& ld = model.deviations.links[i];
          u += (js.a_mm + ld.da_mm) * ws.link_axes[static_cast<size_t>(i)].col(2);
          u += (js.d_mm + ld.dd_mm) * ws.link_axes[static_cast<size_t>(i)].col(0);
        }
        translation(col, dT * u);
        continue;
      }
      default:
        break;
    }
    const int i = P.joint;
    if (i < 0 || i >= n) throw ArgumentError("parameterJacobian: parameter " + P.name + " has no joint of this robot");
    const bool revolute = model.nominal.joints[i].type == JointType::kRevolute;
    const Eigen::Matrix<double, 3, 5>& A = ws.link_axes[static_cast<size_t>(i)];
    const Eigen::Vector3d z0 = A.col(0), o0 = A.col(1), x1 = A.col(2), o2 = A.col(3);
    // the joint's own motion: rotation about z0 through o0, or translation along z0
    auto jointMotion = [&](double factor) {
      if (revolute) rotation(col, z0, o0); else translation(col, z0);
      J.col(col) *= factor;
    };
    const double q_joint = revolute ? q[i] * kDegToRad : q[i];
    switch (P.kind) {
      case ParamKind::kOffset:
      case ParamKind::kTheta:
        rotation(col, z0, o0);
        break;
      case ParamKind::kD:
        translation(col, scale * z0);
        break;
      case ParamKind::kA:
        translation(col, scale * x1);
        break;
      case ParamKind::kAlpha:
        rotation(col, x1, o2);
        break;
      case ParamKind::kBeta:
        rotation(col, A.col(4), o2);
        break;
      case ParamKind::kCompliance:
        jointMotion(ws.load[i]);
        break;
      case ParamKind::kGearSin:
        jointMotion(std::sin(P.harmonic * q_joint));
        break;
      case ParamKind::kGearCos:
        jointMotion(std::cos(P.harmonic * q_joint));
        break;
      case ParamKind::kJointScale:
        jointMotion(q_joint);
        break;
      case ParamKind::kBacklash:
        jointMotion(0.5 * direction(context, i));
        break;
      case ParamKind::kJointMap:
        jointMotion(jointMapBasisValue(model.deviations.joint_map[static_cast<size_t>(i)], q[i], P.index));
        break;
      default:
        throw ArgumentError("parameterJacobian: unexpected parameter " + P.name);
    }
  }
  return T_w_tcp;
}

Eigen::Matrix<double, 6, Eigen::Dynamic> jointJacobian(const RobotModel& model,
                                                       const Eigen::VectorXd& q,
                                                       const PoseContext& context,
                                                       KinematicWorkspace& ws) {
  computeFrames(model, q, context, ws);
  const int n = model.dof();
  const Eigen::Isometry3d T_wb = model.T_world_base();
  const Eigen::Vector3d p = (T_wb * ws.T_base_frame[n] * model.T_flange_tcp()).translation();
  Eigen::Matrix<double, 6, Eigen::Dynamic> Jq(6, n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Isometry3d M0 = T_wb * ws.T_base_frame[i];
    const Eigen::Vector3d z = M0.linear().col(2);
    const JointSpec& j = model.nominal.joints[i];
    // d(theta or d)/dq: the direction plus the q-dependent effects (joint_scale, gear)
    const Deviations& dev = model.deviations;
    double rate = j.direction + dev.joint_scale[i];
    if (j.type == JointType::kRevolute) {
      const double qi = q[i] * kDegToRad;
      const int H = dev.gear_harmonics;
      for (int h = 1; h <= H; ++h)
        rate += h * (dev.gear_sin[i * H + h - 1] * std::cos(h * qi) - dev.gear_cos[i * H + h - 1] * std::sin(h * qi));
      double map_slope = 0;  // rad per deg
      jointMapValue(dev.joint_map[static_cast<size_t>(i)], q[i], &map_slope);
      rate += map_slope * kRadToDeg;
      Jq.col(i).head<3>() = z.cross(p - M0.translation()) * (rate * kDegToRad);
      Jq.col(i).tail<3>() = z * (rate * kDegToRad);
    } else {
      double map_slope = 0;  // mm per mm
      jointMapValue(dev.joint_map[static_cast<size_t>(i)], q[i], &map_slope);
      rate += map_slope;
      Jq.col(i).head<3>() = z * rate;
      Jq.col(i).tail<3>().setZero();
    }
  }
  return Jq;
}

}  // namespace accura
