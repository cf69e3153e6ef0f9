// accura: internals of the inverse kinematics (ik.h), shared by its files:
//   ik.cpp         options, KUKA Status/Turn, the workspace, KinematicSolver's public calls
//   ik_newton.cpp  limits, singularity tests, Newton / Levenberg-Marquardt on the complete model
//   ik_solve.cpp   closed-form seeds and the solver (warm start, branches, the answer)
// Not a public header.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <sstream>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "accura/calib/geometry.h"
#include "accura/calib/ik.h"
#include "accura/calib/kinematic_core.h"
#include "accura/calib/text.h"
#include "closed_form.h"
#include "small_linalg.h"

namespace accura::calib {
namespace ik_detail {

inline double wrap180(double deg) {
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

/// True when all `count` values at `v` are finite (x * 0 is 0 for a finite x, NaN for an
/// infinite or NaN one; one sum, no branch per value).
inline bool allFinite(const double* v, Eigen::Index count) {
  double s = 0;
  for (Eigen::Index i = 0; i < count; ++i) s += v[i] * 0.0;
  return s == 0;
}

/// The same for N values, N known at compile time: Eigen's unrolled, vectorised sum (two
/// values per instruction, a tree of additions instead of a chain of N dependent ones).
template <int N>
inline bool allFinite(const double* v) {
  return (Eigen::Map<const Eigen::Array<double, N, 1>>(v) * 0.0).sum() == 0;
}

/// f(i) for every joint i < n; for six joints with a constant trip count, so that the compiler
/// unrolls the loop (the IK's per-joint tests and sums in the path-following hot path; the same
/// operations in the same order either way).
template <class F>
inline void forEachJoint(int n, F&& f) {
  if (n == 6) {
    for (int i = 0; i < 6; ++i) f(i);
  } else {
    for (int i = 0; i < n; ++i) f(i);
  }
}

inline int turnBits(const double* q, int n) {
  if (n == 6)  // (the same bits, unrolled)
    return static_cast<int>(q[0] < 0) | static_cast<int>(q[1] < 0) << 1 | static_cast<int>(q[2] < 0) << 2 |
           static_cast<int>(q[3] < 0) << 3 | static_cast<int>(q[4] < 0) << 4 | static_cast<int>(q[5] < 0) << 5;
  int t = 0;
  const int m = std::min(n, 30);
  for (int i = 0; i < m; ++i) t |= static_cast<int>(q[i] < 0) << i;  // (no branch per joint)
  return t;
}

inline bool hasDeviationsBeyondBaseTool(const RobotModel& m) {
  const Deviations& d = m.deviations;
  for (const LinkDeviation& l : d.links)
    if (l.dtheta_rad != 0 || l.dd_mm != 0 || l.da_mm != 0 || l.dalpha_rad != 0 || l.dbeta_rad != 0) return true;
  return d.hasEffectsBeyondGeometry();
}

inline std::string formatPose(const Eigen::Isometry3d& T) {
  const XyzAbc p = toXyzAbc(T);
  return "{X " + formatFixed(p.x_mm, 3) + ", Y " + formatFixed(p.y_mm, 3) + ", Z " + formatFixed(p.z_mm, 3) + ", A " +
         formatFixed(p.a_deg, 3) + ", B " + formatFixed(p.b_deg, 3) + ", C " + formatFixed(p.c_deg, 3) + "}";
}

/// Identifies each prepared solver in IkWorkspace (unique in the process).
extern std::atomic<std::uint64_t> next_solver_id;

}  // namespace ik_detail

/// The stored solution of an IkWorkspace: the solver that found it (Impl::id; 0 = none), its
/// joint values and context, the frames and joint Jacobian there.
struct IkWorkspace::Data {
  std::uint64_t solver_id = 0;
  VecN q;
  double payload_kg = 0, temp_c = 0;
  std::vector<int> dir;
  /// Two frame buffers: Newton evaluates its trial point into the other one and swaps the
  /// roles on acceptance (no copy); `cur` is the one at q.
  std::array<KinematicFrames, 2> frames;
  int cur = 0;
  Jac6N J;
  /// J factored in 3x3 blocks (6 joints; `block_valid` when the factorisation held): the next
  /// solve's first Newton step uses it, and its determinant bounds the smallest singular value
  /// from below (KinematicSolver::Impl::sigmaMinLowerBound).
  detail::Block6 block;
  bool block_valid = false;
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
  /// The stored solution's Status bits 1 and 2 (StatusGeometry::elbowWristBits; finish()).
  int elbow_wrist_bits = 0;

  bool holds(std::uint64_t id, const Eigen::VectorXd& seed, const PoseContext& ctx) const {
    if (solver_id == 0 || solver_id != id || seed.size() != q.size()) return false;
    // bit for bit (one comparison of the bytes)
    if (std::memcmp(seed.data(), q.data(), sizeof(double) * static_cast<size_t>(seed.size())) != 0) return false;
    return ctx.payload_kg == payload_kg && ctx.temp_c == temp_c && ctx.dir == dir;
  }
};

/// The frames at Newton's current point (`cur`) and a buffer for its trial point (`tmp`):
/// swapped on acceptance, so the frames are never copied.
struct FramePair {
  KinematicFrames* cur;
  KinematicFrames* tmp;
};

struct KinematicSolver::Impl {
  RobotModel model;
  KinematicModel chain;
  /// The nominal links with this model's base and tool: where the closed form is exact.
  KinematicModel nominal_chain;
  detail::ClosedForm closed_form;
  ik_detail::StatusGeometry status_geometry;
  bool exact_closed_form = false;  ///< no deviations beyond base and tool
  int n = 0;
  std::array<bool, kMaxDof> revolute{};
  std::array<double, kMaxDof> lower{}, upper{}, theta0{}, dir{};
  std::array<double, kMaxDof> step_limit{};  ///< longest Newton step per joint: 20 deg, 0.1 L mm
  /// fitLimits leaves a joint where it is when within this of the reference: 180 deg for a
  /// revolute joint (no other value nearer), infinite for a prismatic one
  std::array<double, kMaxDof> wrap_band{};
  Eigen::Isometry3d T_base_world, T_tcp_flange;
  double L = 1;  ///< length scale (mm)
  double inv_L2 = 1;  ///< 1 / L^2 (mm^-2)
  /// Identifies this prepared model in IkWorkspace (unique in the process).
  const std::uint64_t id = ik_detail::next_solver_id.fetch_add(1);

  static RobotModel nominalLinks(const RobotModel& m);

  explicit Impl(const RobotModel& m);

  Configuration configurationOf(const double* q) const;

  double margin(int i, const IkOptions& o) const { return std::min(o.joint_margin, 0.49 * (upper[i] - lower[i])); }

  /// Moves revolute joints by multiples of 360 deg into [lower + margin - slack,
  /// upper - margin + slack]. Per joint: a value with the sign the Turn bits `turn` ask for
  /// (-1: any) when there is one, else when `strict` is false any value; among those the one
  /// nearest to `ref`. False when a joint has no value. `moved` (optional): set to true when
  /// a joint was moved.
  bool fitLimits(VecN& q, int turn, const VecN& ref, const IkOptions& o, bool strict, double slack = 0,
                 bool* moved = nullptr) const;

  VecN midRange() const;

  // Row and column scaling of the Jacobian: position rows / L, columns per rad (revolute)
  // or per L mm (prismatic): dimensionless.
  void scaled(const Jac6N& J, Jac6N& Js) const;

  /// The scaled Jacobian's column scale of joint i: deg per rad (revolute), L (prismatic).
  double columnScale(int i) const { return revolute[i] ? kRadToDeg : L; }

  /// Smallest singular value of the scaled Jacobian below t? (Cholesky of the Gram matrix
  /// shifted by t^2: it fails exactly when some singular value is <= t.)
  bool singularBelow(const Jac6N& J, double t) const;

  /// singularBelow(J, t) for the Jacobian J at q, skipped where a certificate stored in the
  /// workspace proves the answer: sigma_min(Js(q)) >= cert_level - B sum|q - cert_q| > t
  /// (Weyl: sigma_min moves by at most ||dJs||_2; B from scaledJacobianLipschitz, so only for
  /// chains where it is known). Otherwise the test runs at a higher level first, so that the
  /// next points along a path are covered: about one full test per degree of joint motion
  /// where sigma_min is large, every point next to a singularity.
  /// `seed` (optional): where the last step started (the bound of the Jacobian's change from
  /// there to q decides whether a higher level is worth trying).
  /// `block` (optional): J factored in blocks; where its sigmaMinLowerBound exceeds a test's
  /// level twice, the test is answered without running (the same answer, the same bookkeeping).
  bool singularAt(const Jac6N& J, const VecN& q, double t, IkWorkspace::Data* ws, const VecN* seed,
                  const detail::Block6* block = nullptr) const;

  /// A lower bound of the scaled Jacobian's smallest singular value from J's determinant
  /// (`block`, the factorisation of J) and its Frobenius norm: with sigma_1..sigma_6 the singular
  /// values of Js = D_rows J D_cols, sigma_6 = |det Js| / (sigma_1 ... sigma_5) and, by the
  /// arithmetic-geometric mean, sigma_1^2 ... sigma_5^2 <= (|Js|_F^2 / 5)^5, so
  /// sigma_6 >= |det Js| (5 / |Js|_F^2)^(5/2). Six joints only (0 otherwise).
  double sigmaMinLowerBound(const Jac6N& J, const detail::Block6& block) const;

  /// Bound of ||Js(a) - Js(b)||_2 (scaledJacobianLipschitz, which must not be empty).
  double jacobianChangeBound(const VecN& a, const VecN& b) const {
    const std::vector<double>& B = chain.scaledJacobianLipschitz();
    double change = 0;
    for (int i = 0; i < n; ++i) change += B[static_cast<size_t>(i)] * std::abs(a[i] - b[i]) * kDegToRad;
    return change;
  }

  double minSingularValue(const Jac6N& J) const;

  // --- Newton's method on the complete model --------------------------------------------

  struct Newton {
    bool converged = false;
    int iterations = 0;
    /// final position (mm^2) and rotation (rad^2) errors, squared (the square roots only where
    /// an answer reports them: ep(), er())
    double ep2 = 0, er2 = 0;
    double ep() const { return std::sqrt(ep2); }
    double er() const { return std::sqrt(er2); }
  };

  static void poseErr(const Eigen::Isometry3d& T_target, const Eigen::Isometry3d& T, Vector6d& e);

  /// Squared scaled error: |dp|^2 / L^2 + |dphi|^2 (dimensionless).
  double meritSquared(const Vector6d& e) const {
    return e.head<3>().squaredNorm() * inv_L2 + e.tail<3>().squaredNorm();
  }

  /// Newton's method, then Levenberg-Marquardt when a Newton step does not reduce the error.
  /// Newton reuses its Jacobian while each step gains at least a factor 5 (near the solution
  /// an iteration costs one FK). Every evaluation after the first counts as an iteration.
  /// `*fp.cur` holds the frames at q on entry when `f_valid`, and on return (the pair's roles
  /// may be swapped). `J0` (optional, with `f_valid`): the joint Jacobian at q; `B0`
  /// (optional, with `J0`): J0 factored in blocks (Block6::factor returned true).
  Newton newton(VecN& q, const Eigen::Isometry3d& T_target, const PoseContext& ctx, const IkOptions& o,
                int max_iterations, FramePair& fp, bool f_valid = false, double polish_mm = 0,
                double polish_rad = 0, const Jac6N* J0 = nullptr, const detail::Block6* B0 = nullptr) const;

  // --- closed-form seeds ------------------------------------------------------------------

  std::array<double, 6> thetaOf(const VecN& q) const;

  VecN qOf(const detail::ThetaSolution& s) const;

  /// A closed-form seed of branch `branch`, corrected for the model's deviations: the
  /// closed form is exact for the nominal links, so solve it for the target moved by the
  /// difference between the nominal and the complete model at the seed,
  /// T' = FK_nominal(q) FK_complete(q)^-1 T (twice). The branch code keeps the branch; near a
  /// singularity this handles the large redistribution between joints (A4 / A6 at A5 ~ 0)
  /// that Newton's method does poorly.
  void correctSeed(VecN& q, int branch, const Eigen::Isometry3d& T_target, const PoseContext& ctx) const;

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
                        int& outside_limits, int& branches) const;

  /// Starts for a robot without a closed form: the reference, then a fixed low-discrepancy
  /// set (Halton) over the joint ranges.
  std::vector<Start> multiStarts(const VecN& ref) const;

  // --- the solver -------------------------------------------------------------------------

  /// The solver. `q_out` (optional): on kOk the solution is written there (dof values)
  /// instead of into IkResult::q, which stays empty (no allocation); it may alias `seed`.
  IkResult inverse(const Eigen::Isometry3d& T_target, const Configuration& config, const Eigen::VectorXd& seed,
                   const IkOptions& o, const PoseContext& ctx, double polish_mm = 0, double polish_rad = 0,
                   IkWorkspace::Data* ws = nullptr, double* q_out = nullptr) const;
};

}  // namespace accura::calib
