// Inverse kinematics of the complete model on the kinematic core: closed-form seeds of the
// nominal geometry (all branches), Newton's method on the complete model, KUKA Status/Turn.
// docs/compensation.md.
#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cmath>
#include <limits>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"
#include "accura/calib/ik.h"
#include "accura/calib/kinematic_core.h"
#include "closed_form.h"
#include "small_linalg.h"

namespace accura::calib {

using detail::ClosedForm;
using detail::ClosedFormKind;

const char* toString(IkStatus status) {
  switch (status) {
    case IkStatus::kOk: return "ok";
    case IkStatus::kUnreachable: return "unreachable";
    case IkStatus::kJointLimits: return "joint limits";
    case IkStatus::kSingular: return "singular";
    case IkStatus::kNoConfiguration: return "not reachable on the configuration asked for";
    case IkStatus::kNotConverged: return "not converged";
  }
  return "unknown";
}

bool IkOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!(tol_mm > 0 && tol_mm <= 1)) return fail("IK position tolerance must be in (0, 1] mm, got " + std::to_string(tol_mm));
  if (!(tol_rad > 0 && tol_rad <= 1e-3))
    return fail("IK orientation tolerance must be in (0, 1e-3] rad, got " + std::to_string(tol_rad));
  if (max_iterations < 1 || max_iterations > 10000)
    return fail("IK iterations must be in 1..10000, got " + std::to_string(max_iterations));
  if (!(joint_margin >= 0 && joint_margin < 90))
    return fail("joint margin must be in [0, 90) deg or mm, got " + std::to_string(joint_margin));
  if (!(singular_threshold >= 0 && singular_threshold < 1))
    return fail("singular threshold must be in [0, 1), got " + std::to_string(singular_threshold));
  return true;
}

bool configurationMatches(const Configuration& asked, const Configuration& actual) {
  if (asked.status >= 0 && asked.status != actual.status) return false;
  if (asked.turn >= 0 && asked.turn != actual.turn) return false;
  return true;
}

bool onlyTurnBitsNearZeroDiffer(const Configuration& asked, const Configuration& actual, const Eigen::VectorXd& q) {
  if (configurationMatches(asked, actual)) return false;
  if (asked.status >= 0 && actual.status != asked.status) return false;
  if (asked.turn < 0 || actual.turn < 0) return false;
  const long long flipped = static_cast<long long>(asked.turn ^ actual.turn);
  const int n = static_cast<int>(std::min<Eigen::Index>(q.size(), 30));
  if (flipped >> n) return false;  // a bit beyond the joints
  for (int i = 0; i < n; ++i)
    if ((flipped >> i & 1) && !(std::fabs(q[i]) <= kTurnBandDeg)) return false;
  return true;
}

namespace {

double wrap180(double deg) {
  if (deg >= -180.0 && deg < 180.0) return deg;
  double w = std::fmod(deg + 180.0, 360.0);
  if (w < 0) w += 360.0;
  return w - 180.0;  // [-180, 180)
}

/// What the Status bits need: the nominal geometry of the first five links.
struct StatusGeometry {
  bool defined = false;
  std::array<double, 5> theta0{}, d{}, a{}, ca{}, sa{}, dir{};
  std::array<bool, 5> trig{};  ///< link i needs cos / sin of its angle
  int last = 0;                ///< last of links 2..5 that moves the wrist point
  double c01 = 1, s01 = 0;     ///< cos / sin of theta0 of link 1
  double q3_stretched_deg = 0;

  explicit StatusGeometry(const RobotDefinition& robot) {
    if (robot.dof() < 6) return;
    for (int i = 0; i < 6; ++i)
      if (robot.joints[static_cast<size_t>(i)].type != JointType::kRevolute) return;
    defined = true;
    for (int i = 0; i < 5; ++i) {
      const JointSpec& j = robot.joints[static_cast<size_t>(i)];
      theta0[i] = j.theta0_deg * kDegToRad;
      d[i] = j.d_mm;
      a[i] = j.a_mm;
      ca[i] = std::cos(j.alpha_deg * kDegToRad);
      sa[i] = std::sin(j.alpha_deg * kDegToRad);
      dir[i] = j.direction;
    }
    c01 = std::cos(theta0[0]);
    s01 = std::sin(theta0[0]);
    for (int i = 1; i < 5; ++i)
      if (a[i] != 0 || d[i] != 0) last = i;
    for (int i = 1; i < 5; ++i) trig[i] = i < last || (i == last && a[i] != 0);
    // stretched: the frame-3 position of the wrist point, (a3, -sin(alpha3) d4), turned by
    // theta3 points along the upper arm (a2, 0)
    const double gamma = std::atan2(-sa[2] * d[3], a[2]);
    const double theta3 = (a[1] >= 0 ? 0.0 : kPi) - gamma;
    q3_stretched_deg = wrap180((theta3 - theta0[2]) * kRadToDeg / dir[2]);
  }

  /// The other elbow solution for the same wrist point (the planar arm of joints 2 and 3
  /// mirrored about the line to the wrist point), at least 1 deg from the stretched arm.
  void mirrorElbow(double* q) const {
    const double L3 = std::hypot(a[2], -sa[2] * d[3]);
    const double gamma = std::atan2(-sa[2] * d[3], a[2]);
    // beta: the angle of the forearm against the upper arm (0 stretched)
    const double theta3 = theta0[2] + dir[2] * q[2] * kDegToRad;
    double beta = std::remainder(theta3 + gamma - (a[1] >= 0 ? 0.0 : kPi), 2 * kPi);
    if (std::abs(beta) < kDegToRad) beta = beta < 0 ? -kDegToRad : kDegToRad;
    const double a2 = std::abs(a[1]);
    const double dtheta2 = 2 * std::atan2(L3 * std::sin(beta), a2 + L3 * std::cos(beta));
    q[1] += dtheta2 * kRadToDeg / dir[1];
    q[2] -= 2 * beta * kRadToDeg / dir[2];
  }

  /// The other solution of joint 1 for the same wrist point: theta1 reflected about the
  /// wrist point's azimuth (the two theta1 solutions are symmetric about it), at least 1 deg
  /// away.
  void mirrorShoulder(double* q) const {
    const Eigen::Vector2d p = wristInFrame1(q);
    double dtheta1 = std::remainder(2 * std::atan2(p.y(), p.x()) + kPi, 2 * kPi);
    if (std::abs(dtheta1) < kDegToRad) dtheta1 = dtheta1 < 0 ? -kDegToRad : kDegToRad;
    q[0] += dtheta1 * kRadToDeg / dir[0];
  }

  /// x, y of the wrist point (origin of DH frame 5, nominal) in the base turned by theta1.
  /// `cos_nominal`, `sin_nominal` (optional): cos / sin of theta0 + direction q per link.
  Eigen::Vector2d wristInFrame1(const double* q, const double* cos_nominal = nullptr,
                                const double* sin_nominal = nullptr) const {
    // The wrist point (origin of DH frame 5) in DH frame 1: links 2..5. The A1 frame is the
    // base turned by dir1 q1 = theta1 - theta0_1, so the wrist point's coordinates there are
    // Rz(theta0_1) ((a1, 0, d1) + Rx(alpha1) o): no angle of joint 1 is needed.
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    Eigen::Vector3d o = Eigen::Vector3d::Zero();
    for (int i = 1; i <= last; ++i) {
      double ct = 1, st = 0;
      if (trig[i] && cos_nominal) {
        ct = cos_nominal[i];
        st = sin_nominal[i];
      } else if (trig[i]) {
        const double th = theta0[i] + dir[i] * q[i] * kDegToRad;
        ct = std::cos(th);
        st = std::sin(th);
      }
      const Eigen::Vector3d x = ct * R.col(0) + st * R.col(1);
      o += a[i] * x + d[i] * R.col(2);
      if (i < last) {
        const Eigen::Vector3d y = -st * R.col(0) + ct * R.col(1);
        const Eigen::Vector3d z = R.col(2);
        R.col(0) = x;
        R.col(1) = ca[i] * y + sa[i] * z;
        R.col(2) = -sa[i] * y + ca[i] * z;
      }
    }
    return Eigen::Vector2d(a[0] + o.x(), ca[0] * o.y() - sa[0] * o.z());
  }

  /// The Status; `x_a1` (optional): the wrist point's x in the A1 frame (mm).
  int status(const double* q, double* x_a1 = nullptr, const double* cos_nominal = nullptr,
             const double* sin_nominal = nullptr) const {
    if (!defined) return -1;
    const Eigen::Vector2d p = wristInFrame1(q, cos_nominal, sin_nominal);
    const double x = c01 * p.x() - s01 * p.y();
    if (x_a1) *x_a1 = x;
    return (x < 0 ? 1 : 0) | elbowWristBits(q);
  }
  /// Bits 1 and 2 (they need no kinematics).
  int elbowWristBits(const double* q) const {
    int s = 0;
    if (wrap180(q[2] - q3_stretched_deg) >= 0) s |= 2;
    if (wrap180(q[4]) < 0) s |= 4;
    return s;
  }
};

int turnBits(const double* q, int n) {
  int t = 0;
  for (int i = 0; i < n && i < 30; ++i)
    if (q[i] < 0) t |= 1 << i;
  return t;
}

bool hasDeviationsBeyondBaseTool(const RobotModel& m) {
  const Deviations& d = m.deviations;
  for (const LinkDeviation& l : d.links)
    if (l.dtheta_rad != 0 || l.dd_mm != 0 || l.da_mm != 0 || l.dalpha_rad != 0 || l.dbeta_rad != 0) return true;
  for (const std::vector<double>* v : {&d.compliance, &d.gear_sin, &d.gear_cos, &d.joint_scale, &d.backlash})
    for (double x : *v)
      if (x != 0) return true;
  for (const JointMap& map : d.joint_map)
    for (double x : map.coef)
      if (x != 0) return true;
  return d.thermal_alpha_per_k != 0;
}

std::string formatPose(const Eigen::Isometry3d& T) {
  const XyzAbc p = toXyzAbc(T);
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(3);
  s << "{X " << p.x_mm << ", Y " << p.y_mm << ", Z " << p.z_mm << ", A " << p.a_deg << ", B " << p.b_deg
    << ", C " << p.c_deg << "}";
  return s.str();
}

}  // namespace

Configuration kukaConfiguration(const RobotModel& model, const Eigen::VectorXd& q) {
  if (q.size() != model.dof())
    throw ArgumentError("kukaConfiguration: expected " + std::to_string(model.dof()) + " joint values, got " +
                        std::to_string(q.size()));
  const StatusGeometry g(model.nominal);
  Configuration c;
  c.status = g.status(q.data());
  c.turn = turnBits(q.data(), model.dof());
  return c;
}

// ---------------------------------------------------------------------------------------

/// The stored solution of an IkWorkspace: the solver that found it (Impl::id; 0 = none), its
/// joint values and context, the frames and joint Jacobian there.
struct IkWorkspace::Data {
  std::uint64_t solver_id = 0;
  VecN q;
  double payload_kg = 0, temp_c = 0;
  std::vector<int> dir;
  KinematicFrames f;
  Jac6N J;
  /// Singularity certificate (KinematicSolver::Impl::singularAt): at cert_q the scaled
  /// Jacobian's smallest singular value was shown to exceed cert_level (solver cert_solver_id;
  /// 0 = none); next_level is the level the next certificate tries.
  std::uint64_t cert_solver_id = 0;
  VecN cert_q;
  double cert_level = 0;
  double next_level = 0.1;
  /// The stored solution's Status bit 0 and a lower bound of |x_a1| (mm; finish()).
  double x_a1_abs_lo = 0;
  bool x_a1_negative = false;

  bool holds(std::uint64_t id, const Eigen::VectorXd& seed, const PoseContext& ctx) const {
    if (solver_id == 0 || solver_id != id || seed.size() != q.size()) return false;
    for (Eigen::Index i = 0; i < seed.size(); ++i)
      if (seed[i] != q[i]) return false;
    return ctx.payload_kg == payload_kg && ctx.temp_c == temp_c && ctx.dir == dir;
  }
};

IkWorkspace::IkWorkspace() : data_(std::make_unique<Data>()) {}
IkWorkspace::~IkWorkspace() = default;
IkWorkspace::IkWorkspace(IkWorkspace&&) noexcept = default;
IkWorkspace& IkWorkspace::operator=(IkWorkspace&&) noexcept = default;
void IkWorkspace::clear() {
  if (data_) {
    data_->solver_id = 0;
    data_->cert_solver_id = 0;
  }
}
bool IkWorkspace::holdsSolution() const { return data_ && data_->solver_id != 0; }

namespace {
std::atomic<std::uint64_t> next_solver_id{1};
}  // namespace

struct KinematicSolver::Impl {
  RobotModel model;
  KinematicModel chain;
  /// The nominal links with this model's base and tool: where the closed form is exact.
  KinematicModel nominal_chain;
  ClosedForm closed_form;
  StatusGeometry status_geometry;
  bool exact_closed_form = false;  ///< no deviations beyond base and tool
  int n = 0;
  std::array<bool, kMaxDof> revolute{};
  std::array<double, kMaxDof> lower{}, upper{}, theta0{}, dir{};
  Eigen::Isometry3d T_base_world, T_tcp_flange;
  double L = 1;  ///< length scale (mm)
  /// Identifies this prepared model in IkWorkspace (unique in the process).
  const std::uint64_t id = next_solver_id.fetch_add(1);

  static RobotModel nominalLinks(const RobotModel& m) {
    RobotModel r = m;
    const Deviations d = m.deviations;
    r.deviations = Deviations::zero(m.dof(), d.gear_harmonics);
    r.deviations.base_mm = d.base_mm;
    r.deviations.base_rot_rad = d.base_rot_rad;
    r.deviations.tool_mm = d.tool_mm;
    r.deviations.tool_rot_rad = d.tool_rot_rad;
    return r;
  }

  explicit Impl(const RobotModel& m)
      : model(m), chain(m), nominal_chain(nominalLinks(m)), closed_form(m.nominal), status_geometry(m.nominal) {
    n = m.dof();
    for (int i = 0; i < n; ++i) {
      const JointSpec& j = m.nominal.joints[static_cast<size_t>(i)];
      revolute[i] = j.type == JointType::kRevolute;
      lower[i] = j.lower;
      upper[i] = j.upper;
      theta0[i] = j.theta0_deg * kDegToRad;
      dir[i] = j.direction;
    }
    T_base_world = m.T_world_base().inverse();
    T_tcp_flange = m.T_flange_tcp().inverse();
    L = chain.length_scale_mm();
    exact_closed_form = closed_form.kind() != ClosedFormKind::kNone && !hasDeviationsBeyondBaseTool(m);
  }

  Configuration configurationOf(const double* q) const {
    Configuration c;
    c.status = status_geometry.status(q);
    c.turn = turnBits(q, n);
    return c;
  }

  double margin(int i, const IkOptions& o) const { return std::min(o.joint_margin, 0.49 * (upper[i] - lower[i])); }

  /// Moves revolute joints by multiples of 360 deg into [lower + margin - slack,
  /// upper - margin + slack]. Per joint: a value with the sign the Turn bits `turn` ask for
  /// (-1: any) when there is one, else when `strict` is false any value; among those the one
  /// nearest to `ref`. False when a joint has no value.
  bool fitLimits(VecN& q, int turn, const VecN& ref, const IkOptions& o, bool strict, double slack = 0) const {
    for (int i = 0; i < n; ++i) {
      const double m = margin(i, o);
      const double lo = lower[i] + m - slack, hi = upper[i] - m + slack;
      const bool check_sign = turn >= 0;
      const bool want_negative = check_sign && ((turn >> i) & 1);
      if (!revolute[i]) {
        if (q[i] < lo || q[i] > hi) return false;
        if (strict && check_sign && (q[i] < 0) != want_negative) return false;
        continue;
      }
      // q itself: within the limits, the sign asked for, and no other value nearer to ref
      if (q[i] >= lo && q[i] <= hi && (!check_sign || (q[i] < 0) == want_negative) && std::abs(q[i] - ref[i]) <= 180.0)
        continue;
      double best = 0, best_any = 0;
      bool found = false, found_any = false;
      const double base = q[i] - 360.0 * std::round(q[i] / 360.0);
      for (int k = -3; k <= 3; ++k) {
        const double v = base + 360.0 * k;
        if (v < lo || v > hi) continue;
        if (!found_any || std::abs(v - ref[i]) < std::abs(best_any - ref[i])) best_any = v;
        found_any = true;
        if (check_sign && (v < 0) != want_negative) continue;
        if (!found || std::abs(v - ref[i]) < std::abs(best - ref[i])) best = v;
        found = true;
      }
      if (found) {
        q[i] = best;
      } else if (found_any && !strict) {
        q[i] = best_any;
      } else {
        return false;
      }
    }
    return true;
  }

  VecN midRange() const {
    VecN q(n);
    for (int i = 0; i < n; ++i) q[i] = 0.5 * (lower[i] + upper[i]);
    return q;
  }

  // Row and column scaling of the Jacobian: position rows / L, columns per rad (revolute)
  // or per L mm (prismatic): dimensionless.
  void scaled(const Jac6N& J, Jac6N& Js) const {
    Js = J;
    Js.topRows<3>() /= L;
    for (int i = 0; i < n; ++i) Js.col(i) *= revolute[i] ? kRadToDeg : L;
  }

  /// Smallest singular value of the scaled Jacobian below t? (Cholesky of the Gram matrix
  /// shifted by t^2: it fails exactly when some singular value is <= t.)
  bool singularBelow(const Jac6N& J, double t) const {
    if (n == 6) {
      // A^T A (same singular values as A A^T for a square A), A the scaled Jacobian as a
      // fixed-size matrix (vectorised product)
      Eigen::Matrix<double, 6, 6> A = J.leftCols<6>();
      A.topRows<3>() *= 1.0 / L;
      for (int c = 0; c < 6; ++c) A.col(c) *= revolute[c] ? kRadToDeg : L;
      Eigen::Matrix<double, 6, 6> G;
      G.noalias() = A.transpose() * A;
      G.diagonal().array() -= t * t;
      return !detail::positiveDefinite6(G);
    }
    Jac6N Js;
    scaled(J, Js);
    if (n > 6) {
      Eigen::Matrix<double, 6, 6> G;
      G.triangularView<Eigen::Lower>() = Js * Js.transpose();
      G.diagonal().array() -= t * t;
      return !detail::positiveDefinite6(G);
    }
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxDof, kMaxDof> G = Js.transpose() * Js;
    G.diagonal().array() -= t * t;
    Eigen::LLT<decltype(G)> llt(G);
    return llt.info() != Eigen::Success;
  }

  /// singularBelow(J, t) for the Jacobian J at q, skipped where a certificate stored in the
  /// workspace proves the answer: sigma_min(Js(q)) >= cert_level - B sum|q - cert_q| > t
  /// (Weyl: sigma_min moves by at most ||dJs||_2; B from scaledJacobianLipschitz, so only for
  /// chains where it is known). Otherwise the test runs at a higher level first, so that the
  /// next points along a path are covered: about one full test per degree of joint motion
  /// where sigma_min is large, every point next to a singularity.
  /// `last_step_change`: the bound of the Jacobian's change from the seed to q.
  bool singularAt(const Jac6N& J, const VecN& q, double t, IkWorkspace::Data* ws, double last_step_change) const {
    const std::vector<double>& B = chain.scaledJacobianLipschitz();
    if (!ws || B.empty()) return singularBelow(J, t);
    if (ws->cert_solver_id == id) {
      double change = 0;  // bound of ||Js(q) - Js(cert_q)||_2
      for (int i = 0; i < n; ++i) change += B[static_cast<size_t>(i)] * std::abs(q[i] - ws->cert_q[i]) * kDegToRad;
      if (ws->cert_level - change > t) return false;
    }
    if (!(last_step_change >= 0)) last_step_change = 0;
    // the level: raised slowly while it holds, halved where it does not; not tried when the
    // region it would certify could not reach as far as the last step went (long steps)
    const double level = std::max(ws->next_level, 2 * t);
    if (level < 1 && level - t > 1.5 * last_step_change && !singularBelow(J, level)) {
      ws->cert_solver_id = id;
      ws->cert_q = q;
      ws->cert_level = level;
      ws->next_level = std::min(0.5, 1.25 * level);
      return false;
    }
    ws->next_level = std::max(0.5 * level, 2 * t);
    return singularBelow(J, t);
  }

  double minSingularValue(const Jac6N& J) const {
    Jac6N Js;
    scaled(J, Js);
    const Eigen::MatrixXd A = Js;
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(A);
    const auto& s = svd.singularValues();
    return s[s.size() - 1];
  }

  // --- Newton's method on the complete model --------------------------------------------

  struct Newton {
    bool converged = false;
    int iterations = 0;
    double ep = 0, er = 0;  ///< final position (mm) and rotation (rad) errors
  };

  static void poseErr(const Eigen::Isometry3d& T_target, const Eigen::Isometry3d& T, Vector6d& e) {
    e.head<3>() = T_target.translation() - T.translation();
    const Eigen::Matrix3d dR = T_target.linear() * T.linear().transpose();
    // rotation vector of dR: half the skew part is sin(angle) times the axis; below 0.1
    // (5.7 deg) scale it by angle / sin(angle) = asin(s) / s from its series (next term
    // 35 s^8 / 1152 < 4e-10 relative); logSO3 otherwise
    const Eigen::Vector3d half(0.5 * (dR(2, 1) - dR(1, 2)), 0.5 * (dR(0, 2) - dR(2, 0)), 0.5 * (dR(1, 0) - dR(0, 1)));
    const double s2 = half.squaredNorm();
    if (s2 < 0.01 && dR.trace() > 0) {
      e.tail<3>() = half * (1 + s2 * (1.0 / 6 + s2 * (3.0 / 40 + s2 * (5.0 / 112))));
    } else {
      e.tail<3>() = logSO3(dR);
    }
  }

  double meritScaled(const Vector6d& e) const {
    return std::sqrt(e.head<3>().squaredNorm() / (L * L) + e.tail<3>().squaredNorm());
  }

  /// Newton's method, then Levenberg-Marquardt when a Newton step does not reduce the error.
  /// Newton reuses its Jacobian while each step gains at least a factor 5 (near the solution
  /// an iteration costs one FK). Every evaluation after the first counts as an iteration.
  /// `f` holds the frames at q on entry when `f_valid`, and on return.
  /// `J0` (optional, with `f_valid`): the joint Jacobian at q.
  Newton newton(VecN& q, const Eigen::Isometry3d& T_target, const PoseContext& ctx, const IkOptions& o,
                int max_iterations, KinematicFrames& f, bool f_valid = false, double polish_mm = 0,
                double polish_rad = 0, const Jac6N* J0 = nullptr) const {
    using MatN = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxDof, kMaxDof>;
    Newton r;
    if (!f_valid) chain.evaluate(q.data(), ctx, f);
    // frames at q (cur) and of the trial (tmp); swapped on acceptance, copied back at the end
    KinematicFrames ft;
    KinematicFrames* cur = &f;
    KinematicFrames* tmp = &ft;
    struct CopyBack {
      KinematicFrames*& cur;
      KinematicFrames& f;
      ~CopyBack() {
        if (cur != &f) f = *cur;
      }
    } copy_back{cur, f};
    Vector6d e;
    poseErr(T_target, f.T_world_tcp, e);
    double merit = meritScaled(e);
    // converged at the tolerance; then, when polishing, up to kPolishSteps more while they
    // gain (a step that does not reduce the error ends it, converged)
    int polish_left = kPolishSteps;
    auto done = [&]() {
      r.ep = e.head<3>().norm();
      r.er = e.tail<3>().norm();
      r.converged = r.ep <= o.tol_mm && r.er <= o.tol_rad;
      if (r.converged) {
        const bool polished = polish_mm <= 0 || (r.ep <= polish_mm && r.er <= polish_rad);
        return polished || polish_left-- <= 0;
      }
      return r.iterations >= max_iterations;
    };
    VecN qt(n), dq(n);
    Vector6d et;
    Jac6N J, Js;
    auto trial = [&](const VecN& step) {
      qt = q + step;
      chain.evaluate(qt.data(), ctx, *tmp, cur);
      poseErr(T_target, tmp->T_world_tcp, et);
      ++r.iterations;
      const double mt = meritScaled(et);
      if (!(mt < merit)) return false;
      q = qt;
      std::swap(cur, tmp);
      e = et;
      merit = mt;
      return true;
    };
    auto limitStep = [&](VecN& step) {
      double s = 1;
      for (int i = 0; i < n; ++i) {
        const double lim = revolute[i] ? 20.0 : 0.1 * L;  // deg / mm
        if (std::abs(step[i]) * s > lim) s = lim / std::abs(step[i]);
      }
      step *= s;
    };

    if (n == 6) {
      // Newton with a square Jacobian
      const double tol_merit = std::sqrt(o.tol_mm * o.tol_mm / (L * L) + o.tol_rad * o.tol_rad);
      detail::Lu6 lu;
      bool fresh = false, have = false;
      while (!done()) {
        if (!have) {
          if (J0 && f_valid && cur == &f) {
            J = *J0;
          } else {
            chain.jacobian(*cur, J);
          }
          J0 = nullptr;
          if (!lu.factor(Eigen::Matrix<double, 6, 6>(J))) break;
          have = fresh = true;
        }
        dq = lu.solve(e);
        if (!dq.allFinite()) break;
        limitStep(dq);
        const double before = merit;
        if (trial(dq)) {
          fresh = false;
          // slow, or still far from the tolerance (chord steps gain a fixed factor, a fresh
          // Newton step squares the error): refresh the Jacobian
          if (merit > 0.2 * before || merit > kRefreshAboveTol * tol_merit) have = false;
        } else if (r.converged) {
          return r;  // polishing reached the rounding level
        } else if (!fresh) {
          have = false;  // retry with the Jacobian at q
        } else {
          break;  // no descent along a fresh Newton step: Levenberg-Marquardt
        }
      }
      if (done()) return r;
    }

    // Levenberg-Marquardt in scaled variables: (Js^T Js + lambda I) dx = Js^T es
    double lambda = -1;
    while (!done()) {
      chain.jacobian(*cur, J);
      scaled(J, Js);
      const MatN A = Js.transpose() * Js;
      Vector6d es = e;
      es.head<3>() /= L;
      const VecN g = Js.transpose() * es;
      const double scale = std::max(1e-12, A.diagonal().maxCoeff());
      if (lambda < 0) lambda = 1e-6 * scale;
      bool accepted = false;
      while (!accepted && !done()) {
        MatN M = A;
        M.diagonal().array() += lambda;
        const VecN dx = M.ldlt().solve(g);
        for (int i = 0; i < n; ++i) dq[i] = dx[i] * (revolute[i] ? kRadToDeg : L);
        if (!dq.allFinite()) return r;
        limitStep(dq);
        if (trial(dq)) {
          accepted = true;
          lambda = std::max(lambda / 5, 1e-15 * scale);
        } else if (r.converged) {
          return r;  // polishing reached the rounding level
        } else {
          lambda *= 4;
          if (lambda > 1e6 * scale) return r;  // a local minimum of the error: stop
        }
      }
    }
    return r;
  }

  // --- closed-form seeds ------------------------------------------------------------------

  std::array<double, 6> thetaOf(const VecN& q) const {
    std::array<double, 6> t{};
    for (int i = 0; i < 6; ++i) t[i] = theta0[i] + dir[i] * q[i] * kDegToRad;
    return t;
  }

  VecN qOf(const detail::ThetaSolution& s) const {
    VecN q(n);
    for (int i = 0; i < 6; ++i) q[i] = (s.theta[i] - theta0[i]) * kRadToDeg / dir[i];
    return q;
  }

  /// A closed-form seed of branch `branch`, corrected for the model's deviations: the
  /// closed form is exact for the nominal links, so solve it for the target moved by the
  /// difference between the nominal and the complete model at the seed,
  /// T' = FK_nominal(q) FK_complete(q)^-1 T (twice). The branch code keeps the branch; near a
  /// singularity this handles the large redistribution between joints (A4 / A6 at A5 ~ 0)
  /// that Newton's method does poorly.
  void correctSeed(VecN& q, int branch, const Eigen::Isometry3d& T_target, const PoseContext& ctx) const {
    KinematicFrames fr, fn;
    double last_step = std::numeric_limits<double>::infinity();
    for (int pass = 0; pass < 8; ++pass) {
      chain.evaluate(q.data(), ctx, fr);
      nominal_chain.evaluate(q.data(), ctx, fn);
      const Eigen::Isometry3d T_moved = fn.T_world_tcp * fr.T_world_tcp.inverse() * T_target;
      detail::ThetaSolution s;
      if (!closed_form.solveBranch(T_base_world * T_moved * T_tcp_flange, thetaOf(q), branch, s)) return;
      VecN qn = qOf(s);
      // keep the representation (multiple of 360 deg) of q
      for (int i = 0; i < 6; ++i) qn[i] += 360.0 * std::round((q[i] - qn[i]) / 360.0);
      const double step = (qn - q).cwiseAbs().maxCoeff();
      if (!(step < last_step)) return;  // not contracting (next to a singularity): keep q
      q = qn;
      last_step = step;
      if (step < 1e-4) return;  // deg: Newton takes it from here
    }
  }

  struct Start {
    VecN q;
    int branch = -1;
    bool corrected = false;
    bool status_mismatch = false;
    double distance = 0;
  };

  /// Closed-form seeds for T_world_tcp, every branch, each joint moved by 360 deg where that
  /// puts it within the limits (a seed may lie up to kSeedSlackDeg outside: the real solution
  /// may be inside); the Turn bits asked for choose among the values, else nearest to ref.
  static constexpr double kSeedSlackDeg = 5.0;
  /// A warm start's solution is taken without the closed form when no joint moved more
  /// than kWarmAcceptDeg from the seed, or up to kWarmMaxDeg where the scaled Jacobian's
  /// smallest singular value exceeds the move in rad (deg / mm).
  static constexpr double kWarmAcceptDeg = 2.0;
  static constexpr double kWarmMaxDeg = 10.0;
  /// Newton steps after convergence while polishing (Compensator: to 1e-9 mm, 1e-12 rad).
  static constexpr int kPolishSteps = 3;
  /// Newton refreshes its Jacobian while the scaled error is above this many tolerances.
  static constexpr double kRefreshAboveTol = 30.0;
  void closedFormStarts(const Eigen::Isometry3d& T_world_tcp, const Configuration& config, const VecN& ref,
                        const IkOptions& o, bool correct_all, const PoseContext& ctx, std::vector<Start>& starts,
                        int& outside_limits, int& branches) const {
    std::array<detail::ThetaSolution, 8> sols;
    const Eigen::Isometry3d T06 = T_base_world * T_world_tcp * T_tcp_flange;
    branches = closed_form.solve(T06, thetaOf(ref), sols);
    outside_limits = 0;
    for (int k = 0; k < branches; ++k) {
      Start st;
      st.q = qOf(sols[k]);
      st.branch = sols[k].branch;
      if (!fitLimits(st.q, config.turn, ref, o, false, kSeedSlackDeg)) {
        ++outside_limits;
        continue;
      }
      bool duplicate = false;
      for (const Start& s : starts) duplicate = duplicate || (s.q - st.q).cwiseAbs().maxCoeff() < 1e-9;
      if (duplicate) continue;
      st.status_mismatch = config.status >= 0 && configurationOf(st.q.data()).status != config.status;
      if (correct_all) {
        // "nearest to the seed" is decided on the corrected seeds: next to a singularity the
        // nominal seeds may be degrees from the real solutions
        correctSeed(st.q, st.branch, T_world_tcp, ctx);
        st.corrected = true;
      }
      st.distance = (st.q - ref).squaredNorm();
      starts.push_back(st);
    }
    std::stable_sort(starts.begin(), starts.end(), [](const Start& x, const Start& y) {
      if (x.status_mismatch != y.status_mismatch) return !x.status_mismatch;
      return x.distance < y.distance;
    });
  }

  /// Starts for a robot without a closed form: the reference, then a fixed low-discrepancy
  /// set (Halton) over the joint ranges.
  std::vector<Start> multiStarts(const VecN& ref) const {
    std::vector<Start> s(1);
    s[0].q = ref;
    static const int primes[kMaxDof] = {2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37};
    for (int k = 1; k <= 48; ++k) {
      Start st;
      st.q.resize(n);
      for (int i = 0; i < n; ++i) {
        double f = 1, r = 0;
        for (int x = k; x > 0; x /= primes[i]) {
          f /= primes[i];
          r += f * (x % primes[i]);
        }
        st.q[i] = lower[i] + r * (upper[i] - lower[i]);
      }
      s.push_back(st);
    }
    return s;
  }

  // --- the solver -------------------------------------------------------------------------

  IkResult inverse(const Eigen::Isometry3d& T_target, const Configuration& config, const Eigen::VectorXd& seed,
                   const IkOptions& o, const PoseContext& ctx, double polish_mm = 0, double polish_rad = 0,
                   IkWorkspace::Data* ws = nullptr) const {
    std::string why;
    if (!o.IsValid(&why)) throw ArgumentError(why);
    if (seed.size() != 0 && seed.size() != n)
      throw ArgumentError("IK seed: expected " + std::to_string(n) + " joint values, got " + std::to_string(seed.size()));
    if (seed.size() != 0 && !seed.allFinite()) throw ArgumentError("IK seed: not finite");
    if (!T_target.matrix().allFinite()) throw ArgumentError("IK target: not finite");
    // with a workspace: its frames and Jacobian are those of the seed when it holds the seed;
    // it holds the answer only when the answer is kOk (stored in finish)
    const bool reuse = ws && ws->holds(id, seed, ctx);
    if (ws) ws->solver_id = 0;
    KinematicFrames f_local;
    KinematicFrames& f = ws ? ws->f : f_local;
    Jac6N J_local;
    Jac6N& J = ws ? ws->J : J_local;
    const VecN ref = seed.size() ? VecN(seed) : midRange();
    int iterations = 0;

    std::vector<IkResult> other_configuration;  // converged solutions on other configurations
    IkResult singular_solution;                 // the first singular one on the configuration
    bool have_singular = false;
    int limit_failures = 0;
    // A converged q (frames in f): limits, singularity, configuration. Returns true when
    // `out` is the answer.
    auto finish = [&](VecN q, Newton nt, bool warm, IkResult& out) -> bool {
      const VecN q_converged = q;
      if (!fitLimits(q, config.turn, ref, o, false)) {
        if (!warm) ++limit_failures;
        return false;
      }
      const double moved_deg = warm ? (q - ref).cwiseAbs().maxCoeff() : 0.0;
      if (warm && moved_deg > kWarmMaxDeg) return false;
      IkResult r;
      // Status bit 0 is the sign of x_a1, the wrist point's x in the A1 frame (mm), which moves
      // by at most L per rad of joint motion: with the seed's |x_a1| (at least x_a1_abs_lo)
      // from the workspace and a move too small to reach 0, the bit is the seed's and no
      // kinematics is needed; the workspace then keeps the smaller bound
      double moved_rad = 0;
      if (warm)
        for (int i = 0; i < std::min(n, 5); ++i) moved_rad += std::abs(q[i] - ref[i]) * kDegToRad;
      double x_a1 = 0, x_a1_abs_lo = 0;
      const bool bit0_known = warm && reuse && status_geometry.defined && ws->x_a1_abs_lo > L * moved_rad;
      if (bit0_known) {
        r.configuration.status = (ws->x_a1_negative ? 1 : 0) | status_geometry.elbowWristBits(q.data());
        x_a1_abs_lo = ws->x_a1_abs_lo - L * moved_rad;
      } else {
        chain.fillNominal(q.data(), f, status_geometry.last + 1);
        r.configuration.status = status_geometry.status(q.data(), &x_a1, f.cos_nominal.data(), f.sin_nominal.data());
        x_a1_abs_lo = std::abs(x_a1);
      }
      r.configuration.turn = turnBits(q.data(), n);
      // warm: accepted only next to the seed and on its Status (else another solution may be
      // nearer: next to a singularity two branches come close; the closed form decides)
      if (warm && status_geometry.defined) {
        if ((r.configuration.status & 6) != status_geometry.elbowWristBits(ref.data())) return false;
        // bit 0: recomputed for the seed only when the move could have crossed 0
        if (!bit0_known && std::abs(x_a1) <= L * moved_rad &&
            (status_geometry.status(ref.data()) & 1) != (r.configuration.status & 1))
          return false;
      }
      if (q != q_converged) {
        // moved by 360 deg: the same pose unless an effect depends on q itself (joint_scale)
        nt = newton(q, T_target, ctx, o, 5, f, false, polish_mm, polish_rad);
        iterations += nt.iterations;
        if (!nt.converged) return false;
      }
      r.q = q;
      r.position_error_mm = nt.ep;
      r.rotation_error_rad = nt.er;
      chain.jacobian(f, J);
      // warm and more than kWarmAcceptDeg from the seed: taken only where the Jacobian is
      // regular enough that no other solution can be nearer (another solution of the same pose
      // is about sigma_min rad away or more; docs/compensation.md)
      if (warm && moved_deg > kWarmAcceptDeg && singularBelow(J, std::max(o.singular_threshold, moved_deg * kDegToRad)))
        return false;
      double step_change = 0;  // bound of the scaled Jacobian's change since the seed
      if (warm && ws && !chain.scaledJacobianLipschitz().empty())
        for (int i = 0; i < n; ++i)
          step_change += chain.scaledJacobianLipschitz()[static_cast<size_t>(i)] * std::abs(q[i] - ref[i]) * kDegToRad;
      const bool singular = o.singular_threshold > 0 && singularAt(J, q, o.singular_threshold, ws, step_change);
      if (singular || o.compute_singular_value) r.min_singular_value = minSingularValue(J);
      if (!configurationMatches(config, r.configuration)) {
        if (warm) return false;
        r.status = IkStatus::kNoConfiguration;
        r.message = "reached with S " + std::to_string(r.configuration.status) + " T " +
                    std::to_string(r.configuration.turn) + ", not with the configuration asked for (S " +
                    std::to_string(config.status) + " T " + std::to_string(config.turn) + ")";
        other_configuration.push_back(r);
        return false;
      }
      if (singular) {
        // with a Status asked for, another start may find a regular solution on it: keep
        // this one and go on; with any Status the nearest solution decides: report it
        const auto asSingular = [&](IkResult solution) {
          solution.status = IkStatus::kSingular;
          std::ostringstream m;
          m << "singular: the smallest scaled singular value of the Jacobian is " << r.min_singular_value
            << ", below " << o.singular_threshold;
          solution.message = m.str();
          return solution;
        };
        if (!warm && config.status < 0) {
          out = asSingular(r);
          return true;
        }
        if (!warm && !have_singular) {
          singular_solution = asSingular(r);
          have_singular = true;
        }
        return false;
      }
      r.status = IkStatus::kOk;
      if (ws) {
        // f and J are at q: keep them for a solve seeded with this solution
        ws->solver_id = id;
        ws->q = q;
        ws->payload_kg = ctx.payload_kg;
        ws->temp_c = ctx.temp_c;
        ws->dir = ctx.dir;
        ws->x_a1_abs_lo = status_geometry.defined ? x_a1_abs_lo : 0.0;
        ws->x_a1_negative = (r.configuration.status & 1) != 0;
      }
      out = std::move(r);
      return true;
    };

    IkResult res;
    // 1. warm start: Newton from the seed, accepted when it stays near the seed
    if (seed.size()) {
      VecN q = ref;
      // (the Jacobian is copied in: finish() overwrites J)
      const Newton nt =
          newton(q, T_target, ctx, o, std::min(o.max_iterations, 12), f, reuse, polish_mm, polish_rad, reuse ? &J : nullptr);
      iterations += nt.iterations;
      if (nt.converged && finish(q, nt, true, res)) {
        res.iterations = iterations;
        return res;
      }
    }

    // 2. closed-form seeds (or a fixed set of starts): those with the Status asked for
    //    first, each group nearest to the reference first
    std::vector<Start> starts;
    int outside_limits = 0, branches = 0;
    const bool closed = closed_form.kind() != ClosedFormKind::kNone;
    if (closed) {
      const bool correct_all = !exact_closed_form && seed.size() && config.status < 0;
      closedFormStarts(T_target, config, ref, o, correct_all, ctx, starts, outside_limits, branches);
    } else {
      starts = multiStarts(ref);
      branches = static_cast<int>(starts.size());
    }
    bool any_converged = false;
    double best_ep = std::numeric_limits<double>::infinity(), best_er = best_ep;
    auto attempt = [&](VecN q, int branch, bool corrected, int max_iterations) -> bool {
      if (closed && !exact_closed_form && branch >= 0 && !corrected) correctSeed(q, branch, T_target, ctx);
      const Newton nt = newton(q, T_target, ctx, o, max_iterations, f, false, polish_mm, polish_rad);
      iterations += nt.iterations;
      if (!nt.converged) {
        if (nt.ep / o.tol_mm + nt.er / o.tol_rad < best_ep / o.tol_mm + best_er / o.tol_rad) {
          best_ep = nt.ep;
          best_er = nt.er;
        }
        return false;
      }
      any_converged = true;
      return finish(q, nt, false, res);
    };
    for (const Start& st : starts) {
      if (attempt(st.q, st.branch, st.corrected, o.max_iterations)) {
        res.iterations = iterations;
        return res;
      }
    }
    if (have_singular) {
      singular_solution.iterations = iterations;
      return singular_solution;
    }
    // 3. Status asked for but only found on other configurations: next to a boundary (the
    //    arm stretched, A5 ~ 0) the nominal seeds of both sides may lead to the same side.
    //    Mirror the converged solutions across the boundary and try again.
    if (config.status >= 0 && status_geometry.defined) {
      const std::vector<IkResult> found = other_configuration;
      for (const IkResult& r : found) {
        const int differ = r.configuration.status ^ config.status;
        if (differ == 0) continue;
        VecN q = r.q;
        if (differ & 1) status_geometry.mirrorShoulder(q.data());
        if (differ & 2) status_geometry.mirrorElbow(q.data());
        if (differ & 4) {
          const double side = (config.status & 4) ? -1.0 : 1.0;
          q[4] = side * std::max(std::abs(wrap180(q[4])), 1.0);
        }
        if (attempt(q, -1, false, o.max_iterations)) {
          res.iterations = iterations;
          return res;
        }
      }
    }
    // 4. next to a singularity of the nominal links (the wrist point near the first axis, a
    //    branch the nominal robot cannot reach) the closed-form seeds can miss a solution the
    //    real robot has: Newton / Levenberg-Marquardt from a fixed set of starts, the seed
    //    (or the middle of the ranges) first. Only reached when everything above failed.
    if (closed) {
      const bool none = branches == 0;  // far outside the workspace: a short search
      const std::vector<Start> more = multiStarts(ref);
      const size_t count = none ? 8 : more.size();
      for (size_t k = 0; k < count && k < more.size(); ++k) {
        if (attempt(more[k].q, -1, true, none ? std::min(o.max_iterations, 30) : o.max_iterations)) {
          res.iterations = iterations;
          return res;
        }
      }
    }
    if (!other_configuration.empty()) {
      IkResult r = other_configuration.front();
      r.iterations = iterations;
      return r;
    }
    IkResult fail;
    fail.iterations = iterations;
    std::ostringstream m;
    const std::string margin_note =
        o.joint_margin > 0 ? " (margin " + std::to_string(o.joint_margin) + ")" : std::string();
    if (closed && branches == 0) {
      fail.status = IkStatus::kUnreachable;
      m << "unreachable: " << formatPose(T_target) << " is outside the workspace";
    } else if (any_converged && limit_failures > 0) {
      fail.status = IkStatus::kJointLimits;
      m << "reachable only outside the joint limits" << margin_note;
    } else if (starts.empty()) {
      fail.status = IkStatus::kJointLimits;
      m << "reachable only outside the joint limits" << margin_note << " (" << outside_limits << " of "
        << branches << " branches)";
    } else {
      // every start ended in a local minimum of the error or ran out of iterations
      fail.status = best_ep > 10 * o.tol_mm || best_er > 10 * o.tol_rad ? IkStatus::kUnreachable
                                                                       : IkStatus::kNotConverged;
      m << (fail.status == IkStatus::kUnreachable ? "unreachable: " : "not converged: ") << formatPose(T_target)
        << ", smallest error " << best_ep << " mm, " << best_er << " rad after Newton from " << starts.size()
        << " start(s)";
    }
    fail.message = m.str();
    return fail;
  }
};

KinematicSolver::KinematicSolver(const RobotModel& model) : impl_(std::make_shared<const Impl>(model)) {}
KinematicSolver::~KinematicSolver() = default;
KinematicSolver::KinematicSolver(const KinematicSolver&) = default;
KinematicSolver& KinematicSolver::operator=(const KinematicSolver&) = default;

const RobotModel& KinematicSolver::model() const { return impl_->model; }
const KinematicModel& KinematicSolver::kinematicModel() const { return impl_->chain; }
int KinematicSolver::dof() const { return impl_->n; }

const char* KinematicSolver::closedForm() const {
  switch (impl_->closed_form.kind()) {
    case ClosedFormKind::kSphericalWrist: return "spherical_wrist";
    case ClosedFormKind::kThreeParallel: return "three_parallel";
    case ClosedFormKind::kNone: break;
  }
  return "none";
}

Eigen::Isometry3d KinematicSolver::forward(const Eigen::VectorXd& q, const PoseContext& context) const {
  if (q.size() != impl_->n)
    throw ArgumentError("expected " + std::to_string(impl_->n) + " joint values, got " + std::to_string(q.size()));
  KinematicFrames f;
  impl_->chain.evaluate(q.data(), context, f);
  return f.T_world_tcp;
}

Eigen::Isometry3d KinematicSolver::jacobian(const Eigen::VectorXd& q, const PoseContext& context,
                                            Eigen::Matrix<double, 6, Eigen::Dynamic>& J) const {
  if (q.size() != impl_->n)
    throw ArgumentError("expected " + std::to_string(impl_->n) + " joint values, got " + std::to_string(q.size()));
  KinematicFrames f;
  impl_->chain.evaluate(q.data(), context, f);
  Jac6N Jn;
  impl_->chain.jacobian(f, Jn);
  J = Jn;
  return f.T_world_tcp;
}

IkResult KinematicSolver::inverse(const Eigen::Isometry3d& T_world_tcp, const Configuration& config,
                                  const Eigen::VectorXd& seed, const IkOptions& options,
                                  const PoseContext& context) const {
  return impl_->inverse(T_world_tcp, config, seed, options, context);
}

IkResult KinematicSolver::inverse(const Eigen::Isometry3d& T_world_tcp, const Configuration& config,
                                  const Eigen::VectorXd& seed, const IkOptions& options, const PoseContext& context,
                                  IkWorkspace& workspace) const {
  if (!workspace.data_) workspace.data_ = std::make_unique<IkWorkspace::Data>();  // moved from
  return impl_->inverse(T_world_tcp, config, seed, options, context, 0, 0, workspace.data_.get());
}

IkResult KinematicSolver::inversePolished(const Eigen::Isometry3d& T_world_tcp, const Configuration& config,
                                          const Eigen::VectorXd& seed, const IkOptions& options,
                                          const PoseContext& context, double polish_mm, double polish_rad,
                                          IkWorkspace* workspace) const {
  IkWorkspace::Data* ws = nullptr;
  if (workspace) {
    if (!workspace->data_) workspace->data_ = std::make_unique<IkWorkspace::Data>();
    ws = workspace->data_.get();
  }
  return impl_->inverse(T_world_tcp, config, seed, options, context, polish_mm, polish_rad, ws);
}

std::vector<Eigen::VectorXd> KinematicSolver::closedFormSolutions(const Eigen::Isometry3d& T_world_tcp) const {
  std::vector<Eigen::VectorXd> out;
  const Impl& m = *impl_;
  if (m.closed_form.kind() == ClosedFormKind::kNone) return out;
  std::array<detail::ThetaSolution, 8> sols;
  std::array<double, 6> theta_ref{};
  const VecN mid = m.midRange();
  for (int i = 0; i < 6; ++i) theta_ref[i] = m.theta0[i] + m.dir[i] * mid[i] * kDegToRad;
  const int k = m.closed_form.solve(m.T_base_world * T_world_tcp * m.T_tcp_flange, theta_ref, sols);
  KinematicFrames f;
  Vector6d e;
  for (int s = 0; s < k; ++s) {
    // only exact solutions of the nominal links (not the seeds clamped at the workspace's
    // boundary)
    const VecN q0 = m.qOf(sols[s]);
    m.nominal_chain.evaluate(q0.data(), PoseContext{}, f);
    Impl::poseErr(T_world_tcp, f.T_world_tcp, e);
    if (!(e.head<3>().norm() < 1e-6 * m.L && e.tail<3>().norm() < 1e-9)) continue;
    // every representation of every joint within the limits
    std::vector<Eigen::VectorXd> partial{Eigen::VectorXd(6)};
    for (int i = 0; i < 6; ++i) {
      const double q = wrap180((sols[s].theta[i] - m.theta0[i]) * kRadToDeg / m.dir[i]);
      std::vector<Eigen::VectorXd> next;
      for (const Eigen::VectorXd& p : partial)
        for (int r = -3; r <= 3; ++r) {
          const double v = q + 360.0 * r;
          if (v < m.lower[i] || v > m.upper[i]) continue;
          Eigen::VectorXd x = p;
          x[i] = v;
          next.push_back(x);
        }
      partial.swap(next);
    }
    for (const Eigen::VectorXd& p : partial) out.push_back(p);
  }
  return out;
}

IkResult inverseKinematics(const RobotModel& model, const Eigen::Isometry3d& T_world_tcp, const Configuration& config,
                           const Eigen::VectorXd& seed, const IkOptions& options, double payload_kg) {
  PoseContext ctx;
  ctx.payload_kg = payload_kg;
  return inverseKinematics(model, T_world_tcp, config, seed, options, ctx);
}

IkResult inverseKinematics(const RobotModel& model, const Eigen::Isometry3d& T_world_tcp, const Configuration& config,
                           const Eigen::VectorXd& seed, const IkOptions& options, const PoseContext& context) {
  return KinematicSolver(model).inverse(T_world_tcp, config, seed, options, context);
}

}  // namespace accura::calib
