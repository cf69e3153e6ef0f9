#include "accura/calib/kinematics.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "accura/calib/errors.h"
#include "accura/calib/kinematic_core.h"

namespace accura::calib {
namespace {

void checkJointCount(const RobotModel& model, const Eigen::VectorXd& q) {
  if (q.size() != model.dof()) {
    throw ArgumentError("expected " + std::to_string(model.dof()) + " joint values, got " +
                        std::to_string(q.size()));
  }
}

bool sameVector(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
}
bool sameIsometry(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c)
      if (a(r, c) != b(r, c)) return false;
  return true;
}

}  // namespace

// Every value the kinematic core reads. A new field of the model must be compared here and
// prepared in KinematicModel; the size checks below fail to compile until it is (x86-64).
#if defined(__x86_64__) && defined(__GLIBCXX__)
static_assert(sizeof(Deviations) == 304, "Deviations changed: compare the new field in sameKinematics()");
static_assert(sizeof(JointSpec) == 128, "JointSpec changed: compare the new field in sameKinematics()");
static_assert(sizeof(LinkDeviation) == 40, "LinkDeviation changed: compare the new field in sameKinematics()");
#endif
bool sameKinematics(const RobotModel& a, const RobotModel& b) {
  const RobotDefinition &na = a.nominal, &nb = b.nominal;
  if (na.joints.size() != nb.joints.size() || a.forms != b.forms) return false;
  for (size_t i = 0; i < na.joints.size(); ++i) {
    const JointSpec &x = na.joints[i], &y = nb.joints[i];
    if (x.type != y.type || x.a_mm != y.a_mm || x.alpha_deg != y.alpha_deg || x.d_mm != y.d_mm ||
        x.theta0_deg != y.theta0_deg || x.direction != y.direction || x.lower != y.lower || x.upper != y.upper ||
        x.mass_kg != y.mass_kg || !sameVector(x.com_mm, y.com_mm))
      return false;
  }
  if (!sameIsometry(na.T_world_base, nb.T_world_base) || !sameIsometry(na.T_flange_tcp, nb.T_flange_tcp) ||
      !sameVector(na.payload_com_mm, nb.payload_com_mm) || !sameVector(na.gravity_base, nb.gravity_base))
    return false;
  const Deviations &p = a.deviations, &r = b.deviations;
  if (!sameVector(p.base_mm, r.base_mm) || !sameVector(p.base_rot_rad, r.base_rot_rad) ||
      !sameVector(p.tool_mm, r.tool_mm) || !sameVector(p.tool_rot_rad, r.tool_rot_rad) ||
      p.gear_harmonics != r.gear_harmonics || p.thermal_alpha_per_k != r.thermal_alpha_per_k ||
      p.compliance != r.compliance || p.gear_sin != r.gear_sin || p.gear_cos != r.gear_cos ||
      p.joint_scale != r.joint_scale || p.backlash != r.backlash || p.links.size() != r.links.size() ||
      p.joint_map.size() != r.joint_map.size())
    return false;
  for (size_t i = 0; i < p.joint_map.size(); ++i) {
    const JointMap &x = p.joint_map[i], &y = r.joint_map[i];
    if (x.lower != y.lower || x.upper != y.upper || x.intervals != y.intervals || x.taper != y.taper ||
        x.period != y.period || x.coef != y.coef)
      return false;
  }
  for (size_t i = 0; i < p.links.size(); ++i) {
    const LinkDeviation &x = p.links[i], &y = r.links[i];
    if (x.dtheta_rad != y.dtheta_rad || x.dd_mm != y.dd_mm || x.da_mm != y.da_mm || x.dalpha_rad != y.dalpha_rad ||
        x.dbeta_rad != y.dbeta_rad)
      return false;
  }
  return true;
}

struct KinematicWorkspace::Prepared {
  RobotModel from;  ///< the values `model` was prepared from
  std::unique_ptr<KinematicModel> model;
  KinematicFrames frames;
  LinkFrames links;
};

KinematicWorkspace::KinematicWorkspace() = default;
KinematicWorkspace::~KinematicWorkspace() = default;
KinematicWorkspace::KinematicWorkspace(const KinematicWorkspace& o)
    : T_base_frame(o.T_base_frame), theta_rad(o.theta_rad), d_mm(o.d_mm), load(o.load) {}
KinematicWorkspace& KinematicWorkspace::operator=(const KinematicWorkspace& o) {
  T_base_frame = o.T_base_frame;
  theta_rad = o.theta_rad;
  d_mm = o.d_mm;
  load = o.load;
  return *this;
}
KinematicWorkspace::KinematicWorkspace(KinematicWorkspace&&) noexcept = default;
KinematicWorkspace& KinematicWorkspace::operator=(KinematicWorkspace&&) noexcept = default;

KinematicWorkspace::Prepared& KinematicWorkspace::prepare(const RobotModel& model) {
  if (prepared_ && prepared_->model && sameKinematics(prepared_->from, model)) return *prepared_;
  if (!prepared_) prepared_ = std::make_unique<Prepared>();
  prepared_->model.reset();
  prepared_->model = std::make_unique<KinematicModel>(model);  // validates
  prepared_->from = model;
  return *prepared_;
}

namespace {

// Evaluates the prepared model with its intermediate frames and publishes them in `ws`
// (frames in the base frame, angles, lengths, loads).
KinematicWorkspace::Prepared& evaluateFrames(const RobotModel& model, const Eigen::VectorXd& q,
                                             const PoseContext& context, KinematicWorkspace& ws) {
  checkJointCount(model, q);
  KinematicWorkspace::Prepared& P = ws.prepare(model);
  P.model->evaluate(q.data(), context, P.frames, nullptr, &P.links);
  const int n = model.dof();
  ws.T_base_frame.resize(static_cast<size_t>(n + 1));
  ws.theta_rad.resize(n);
  ws.d_mm.resize(n);
  ws.load.resize(n);
  for (int i = 0; i <= n; ++i)
    ws.T_base_frame[static_cast<size_t>(i)] = P.links.T_base_frame[static_cast<size_t>(i)];
  for (int i = 0; i < n; ++i) {
    ws.theta_rad[i] = P.links.theta_rad[static_cast<size_t>(i)];
    ws.d_mm[i] = P.links.d_mm[static_cast<size_t>(i)];
    ws.load[i] = P.links.load[static_cast<size_t>(i)];
  }
  return P;
}

}  // namespace

Eigen::VectorXd gravityLoads(const RobotModel& model, const Eigen::VectorXd& q,
                             const PoseContext& context) {
  checkJointCount(model, q);
  const KinematicModel km(model);
  KinematicFrames f;
  LinkFrames links;
  km.evaluate(q.data(), context, f, nullptr, &links, true);
  Eigen::VectorXd load(model.dof());
  for (int i = 0; i < model.dof(); ++i) load[i] = links.load[static_cast<size_t>(i)];
  return load;
}

Eigen::Isometry3d flangePose(const RobotModel& model, const Eigen::VectorXd& q,
                             const PoseContext& context, KinematicWorkspace& ws) {
  evaluateFrames(model, q, context, ws);
  return ws.T_base_frame.back();
}

Eigen::Isometry3d forwardKinematics(const RobotModel& model, const Eigen::VectorXd& q,
                                    const PoseContext& context, KinematicWorkspace& ws) {
  return evaluateFrames(model, q, context, ws).frames.T_world_tcp;
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
  for (int i = 0; i < model.dof() && !model.deviations.joint_map.empty(); ++i) {
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
      if (p.joint < 0 || p.joint >= static_cast<int>(dev.joint_map.size()))
        throw ArgumentError("parameter " + p.name + ": the model has no joint map on joint " + std::to_string(p.joint + 1));
      std::vector<double>& c = dev.joint_map[static_cast<size_t>(p.joint)].coef;
      if (p.index < 0 || p.index >= static_cast<int>(c.size()))
        throw ArgumentError("parameter " + p.name + ": joint map coefficient " + std::to_string(p.index) +
                            " out of range 0.." + std::to_string(static_cast<int>(c.size()) - 1));
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
  checkJointCount(model, q);
  KinematicWorkspace::Prepared& P = ws.prepare(model);
  return P.model->parameterJacobian(layout, q.data(), context, P.frames, P.links, J);
}

Eigen::Matrix<double, 6, Eigen::Dynamic> jointJacobian(const RobotModel& model,
                                                       const Eigen::VectorXd& q,
                                                       const PoseContext& context,
                                                       KinematicWorkspace& ws) {
  checkJointCount(model, q);
  KinematicWorkspace::Prepared& P = ws.prepare(model);
  P.model->evaluate(q.data(), context, P.frames);
  Jac6N J;
  P.model->jacobian(P.frames, J);
  return J;
}

}  // namespace accura::calib
