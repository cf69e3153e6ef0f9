// Inverse kinematics of the complete model on the kinematic core: closed-form seeds of the
// nominal geometry (all branches), Newton's method on the complete model, KUKA Status/Turn.
// docs/compensation.md.
#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"
#include "accura/calib/ik.h"
#include "accura/calib/kinematic_core.h"
#include "ik_internal.h"

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

std::string configurationDifference(const Configuration& asked, const Configuration& actual) {
  std::string out;
  const auto add = [&out](const std::string& part) { out += (out.empty() ? "" : ", ") + part; };
  if (asked.status >= 0 && actual.status >= 0) {
    const int d = asked.status ^ actual.status;
    if (d & 1) add("the side of axis 1 the wrist point lies on (overhead area)");
    if (d & 2) add("the elbow (joint 3 on the other side of the stretched arm)");
    if (d & 4) add("the wrist flip (the sign of joint 5)");
  } else if (asked.status >= 0) {
    add("the Status");
  }
  if (asked.turn >= 0 && actual.turn >= 0) {
    const int d = asked.turn ^ actual.turn;
    for (int i = 0; i < 30; ++i)
      if (d & (1 << i)) add("the sign of joint " + std::to_string(i + 1));
  } else if (asked.turn >= 0) {
    add("the Turn");
  }
  return out;
}

std::string configurationMismatch(const Configuration& asked, const Configuration& actual) {
  const auto said = [](const Configuration& c) {
    std::string out;
    if (c.status >= 0) out = "S " + std::to_string(c.status);
    if (c.turn >= 0) out += (out.empty() ? "T " : " T ") + std::to_string(c.turn);
    return out;
  };
  return said(actual) + ", not with the configuration asked for (" + said(asked) + "): it differs in " +
         configurationDifference(asked, actual);
}

bool onlyTurnBitsNearZeroDiffer(const Configuration& asked, const Configuration& actual, const Eigen::VectorXd& q,
                                double band_deg) {
  if (configurationMatches(asked, actual)) return false;
  if (asked.status >= 0 && actual.status != asked.status) return false;
  if (asked.turn < 0 || actual.turn < 0) return false;
  const long long flipped = static_cast<long long>(asked.turn ^ actual.turn);
  const int n = static_cast<int>(std::min<Eigen::Index>(q.size(), 30));
  if (flipped >> n) return false;  // a bit beyond the joints
  for (int i = 0; i < n; ++i)
    if ((flipped >> i & 1) && !(std::fabs(q[i]) <= band_deg)) return false;
  return true;
}

using namespace ik_detail;


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

namespace ik_detail {
std::atomic<std::uint64_t> next_solver_id{1};
}  // namespace ik_detail



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

IkStatus KinematicSolver::follow(const Eigen::Isometry3d& T_world_tcp, const Configuration& config, Eigen::VectorXd& q,
                                 const IkOptions& options, const PoseContext& context, IkWorkspace& workspace,
                                 IkResult* answer) const {
  if (!workspace.data_) workspace.data_ = std::make_unique<IkWorkspace::Data>();  // moved from
  // cold (empty q): the solution needs the room (the only allocation)
  const bool cold = q.size() == 0;
  Eigen::VectorXd out;
  if (cold) out.resize(impl_->n);
  IkResult r = impl_->inverse(T_world_tcp, config, q, options, context, 0, 0, workspace.data_.get(),
                              cold ? out.data() : q.data());
  const IkStatus status = r.status;
  if (status == IkStatus::kOk) {
    if (cold) q.swap(out);
  } else if (answer) {
    *answer = std::move(r);
  }
  return status;
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
