// accura: the IK's numerics on the complete model (ik_internal.h): joint limits, singularity
// tests and certificates, Newton's method with Levenberg-Marquardt as the fallback.
#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "accura/calib/errors.h"
#include "ik_internal.h"

namespace accura::calib {

using detail::ClosedForm;
using detail::ClosedFormKind;
using namespace ik_detail;

RobotModel KinematicSolver::Impl::nominalLinks(const RobotModel& m) {
  RobotModel r = m;
  const Deviations d = m.deviations;
  r.deviations = Deviations::zero(m.dof(), d.gear_harmonics);
  r.deviations.base_mm = d.base_mm;
  r.deviations.base_rot_rad = d.base_rot_rad;
  r.deviations.tool_mm = d.tool_mm;
  r.deviations.tool_rot_rad = d.tool_rot_rad;
  return r;
}

KinematicSolver::Impl::Impl(const RobotModel& m) : model(m), chain(m), nominal_chain(nominalLinks(m)),
    closed_form(m.nominal), status_geometry(m.nominal) {
  n = m.dof();
  for (int i = 0; i < n; ++i) {
    const JointSpec& j = m.nominal.joints[static_cast<size_t>(i)];
    revolute[i] = j.type == JointType::kRevolute;
    lower[i] = j.lower;
    upper[i] = j.upper;
    theta0[i] = j.theta0_deg * kDegToRad;
    dir[i] = j.direction;
  }
  L = chain.length_scale_mm();
  for (int i = 0; i < n; ++i) step_limit[i] = revolute[i] ? 20.0 : 0.1 * L;
  for (int i = 0; i < n; ++i) wrap_band[i] = revolute[i] ? 180.0 : std::numeric_limits<double>::infinity();
  T_base_world = m.T_world_base().inverse();
  T_tcp_flange = m.T_flange_tcp().inverse();
  inv_L2 = 1.0 / (L * L);
  exact_closed_form = closed_form.kind() != ClosedFormKind::kNone && !hasDeviationsBeyondBaseTool(m);
}

Configuration KinematicSolver::Impl::configurationOf(const double* q) const {
  Configuration c;
  c.status = status_geometry.status(q);
  c.turn = turnBits(q, n);
  return c;
}

bool KinematicSolver::Impl::fitLimits(VecN& q, int turn, const VecN& ref, const IkOptions& o, bool strict,
    double slack, bool* moved) const {
  const bool check_sign = turn >= 0;
  const bool margin_zero = o.joint_margin == 0;
  if (margin_zero) {
    // the common case of every joint (below) in one pass without a branch per joint: nothing
    // to move
    // (the signs asked for: the Turn bits of q against `turn`, joints 0..n-1; n <= kMaxDof)
    bool all = !check_sign || ((turnBits(q.data(), n) ^ turn) & ((1 << n) - 1)) == 0;
    forEachJoint(n, [&](int i) {
      const double qi = q[i];
      // bitwise on purpose (no branch per comparison): as ints, which clang does not warn of
      all &= (int(qi >= lower[i] - slack) & int(qi <= upper[i] + slack) & int(std::abs(qi - ref[i]) <= wrap_band[i])) != 0;
    });
    if (all) return true;
  }
  for (int i = 0; i < n; ++i) {
    const double m = margin_zero ? 0.0 : margin(i, o);
    const double lo = lower[i] + m - slack, hi = upper[i] - m + slack;
    const bool want_negative = check_sign && ((turn >> i) & 1);
    const double qi = q[i];
    // the common case first: within the limits, the sign asked for, and (revolute) no other
    // value nearer to ref
    if (qi >= lo && qi <= hi && (!check_sign || (qi < 0) == want_negative) &&
        (!revolute[i] || std::abs(qi - ref[i]) <= 180.0))
      continue;
    if (!revolute[i]) {
      if (q[i] < lo || q[i] > hi) return false;
      if (strict && check_sign && (q[i] < 0) != want_negative) return false;
      continue;
    }
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
    const double before = q[i];
    if (found) {
      q[i] = best;
    } else if (found_any && !strict) {
      q[i] = best_any;
    } else {
      return false;
    }
    if (moved && q[i] != before) *moved = true;
  }
  return true;
}

VecN KinematicSolver::Impl::midRange() const {
  VecN q(n);
  for (int i = 0; i < n; ++i) q[i] = 0.5 * (lower[i] + upper[i]);
  return q;
}

void KinematicSolver::Impl::scaled(const Jac6N& J, Jac6N& Js) const {
  Js = J;
  Js.topRows<3>() /= L;
  for (int i = 0; i < n; ++i) Js.col(i) *= columnScale(i);
}

bool KinematicSolver::Impl::singularBelow(const Jac6N& J, double t) const {
  if (n == 6) {
    // G = A^T A - t^2 I (A^T A has the singular values of A A^T for a square A), A the
    // scaled Jacobian: only the lower triangle, which positiveDefinite6 reads (21 dot
    // products of 6, about half the instructions of the full fixed-size product)
    double a[6][6];  // a[c]: column c of A
    const double inv_L = 1.0 / L;
    for (int c = 0; c < 6; ++c) {
      const double* Jc = J.data() + 6 * c;
      const double s = columnScale(c);
      a[c][0] = Jc[0] * inv_L * s;
      a[c][1] = Jc[1] * inv_L * s;
      a[c][2] = Jc[2] * inv_L * s;
      a[c][3] = Jc[3] * s;
      a[c][4] = Jc[4] * s;
      a[c][5] = Jc[5] * s;
    }
    Eigen::Matrix<double, 6, 6> G;
    const double t2 = t * t;
    for (int j = 0; j < 6; ++j) {
      for (int i = j; i < 6; ++i) {
        const double* x = a[i];
        const double* y = a[j];
        G(i, j) = (x[0] * y[0] + x[1] * y[1]) + (x[2] * y[2] + x[3] * y[3]) + (x[4] * y[4] + x[5] * y[5]);
      }
      G(j, j) -= t2;
    }
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

double KinematicSolver::Impl::sigmaMinLowerBound(const Jac6N& J, const detail::Block6& block) const {
  if (n != 6) return 0;
  // det Js = det J * prod(column scales) / L^3 (three position rows divided by L)
  double col_scale = 1, frobenius2 = 0;
  const double inv_L = 1.0 / L;
  for (int c = 0; c < 6; ++c) {
    const double s = columnScale(c);
    col_scale *= s;
    const double* Jc = J.data() + 6 * c;
    const double p = (Jc[0] * Jc[0] + Jc[1] * Jc[1] + Jc[2] * Jc[2]) * inv_L * inv_L;
    const double r = Jc[3] * Jc[3] + Jc[4] * Jc[4] + Jc[5] * Jc[5];
    frobenius2 += (p + r) * s * s;
  }
  const double det = std::abs(block.determinant()) * col_scale * inv_L * inv_L * inv_L;
  if (!(frobenius2 > 0) || !std::isfinite(det)) return 0;
  const double x = 5.0 / frobenius2;
  const double bound = det * x * x * std::sqrt(x);
  return std::isfinite(bound) ? bound : 0.0;
}

bool KinematicSolver::Impl::singularAt(const Jac6N& J, const VecN& q, double t, IkWorkspace::Data* ws,
    const VecN* seed, const detail::Block6* block) const {
  // the bound computed when a test is first needed; a level it exceeds twice (its own
  // rounding, ~1e-14 relative, cannot matter) is answered without the test
  double sigma_lower = -1;
  const auto below = [&](double level) {
    if (block) {
      if (sigma_lower < 0) sigma_lower = sigmaMinLowerBound(J, *block);
      if (sigma_lower > 2 * level) return false;
    }
    return singularBelow(J, level);
  };
  if (!ws || chain.scaledJacobianLipschitz().empty()) return below(t);
  if (ws->cert_solver_id == id && ws->cert_level - jacobianChangeBound(q, ws->cert_q) > t) return false;
  double last_step_change = seed ? jacobianChangeBound(q, *seed) : 0.0;
  if (!(last_step_change >= 0)) last_step_change = 0;
  // the level: raised slowly while it holds, halved where it does not; not tried when the
  // region it would certify could not reach as far as the last step went (long steps)
  const double level = std::max(ws->next_level, 2 * t);
  if (level < 1 && level - t > 1.5 * last_step_change && !below(level)) {
    ws->cert_solver_id = id;
    ws->cert_q = q;
    ws->cert_level = level;
    ws->next_level = std::min(0.5, 1.25 * level);
    return false;
  }
  ws->next_level = std::max(0.5 * level, 2 * t);
  return below(t);
}

double KinematicSolver::Impl::minSingularValue(const Jac6N& J) const {
  Jac6N Js;
  scaled(J, Js);
  const Eigen::MatrixXd A = Js;
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(A);
  const auto& s = svd.singularValues();
  return s[s.size() - 1];
}

void KinematicSolver::Impl::poseErr(const Eigen::Isometry3d& T_target, const Eigen::Isometry3d& T, Vector6d& e) {
  e.head<3>() = T_target.translation() - T.translation();
  // rotation vector of dR = Rt R^T: half the skew part is sin(angle) times the axis; below
  // 0.1 (5.7 deg) scale it by angle / sin(angle) = asin(s) / s from its series (next term
  // 35 s^8 / 1152 < 4e-10 relative); logSO3 otherwise. Only the entries the skew part and
  // the trace need: dR(i, j) = Rt.row(i) . R.row(j)
  const Eigen::Matrix3d& Rt = T_target.linear();
  const Eigen::Matrix3d& R = T.linear();
  const auto dr = [&](int i, int j) { return Rt(i, 0) * R(j, 0) + Rt(i, 1) * R(j, 1) + Rt(i, 2) * R(j, 2); };
  const Eigen::Vector3d half(0.5 * (dr(2, 1) - dr(1, 2)), 0.5 * (dr(0, 2) - dr(2, 0)), 0.5 * (dr(1, 0) - dr(0, 1)));
  const double s2 = half.squaredNorm();
  if (s2 < 0.01 && dr(0, 0) + dr(1, 1) + dr(2, 2) > 0) {
    // (Estrin's scheme: two dependent steps after s2 instead of Horner's four)
    e.tail<3>() = half * ((1 + s2 * (1.0 / 6)) + (s2 * s2) * (3.0 / 40 + s2 * (5.0 / 112)));
  } else {
    e.tail<3>() = logSO3(Rt * R.transpose());
  }
}

KinematicSolver::Impl::Newton KinematicSolver::Impl::newton(VecN& q, const Eigen::Isometry3d& T_target,
    const PoseContext& ctx, const IkOptions& o, int max_iterations, FramePair& fp, bool f_valid,
    double polish_mm, double polish_rad, const Jac6N* J0, const detail::Block6* B0) const {
  using MatN = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxDof, kMaxDof>;
  Newton r;
  if (!f_valid) chain.evaluate(q.data(), ctx, *fp.cur);
  // the frames at q are *fp.cur; a trial is evaluated into *fp.tmp and the two swap roles
  // when it is accepted
  const KinematicFrames* const start = fp.cur;
  Vector6d e;
  poseErr(T_target, fp.cur->T_world_tcp, e);
  // the merit and the tests on squared norms (no square root in the loop nor on return: r.ep2 and
  // r.er2 are the squares)
  double merit = meritSquared(e);
  const double tol_mm2 = o.tol_mm * o.tol_mm, tol_rad2 = o.tol_rad * o.tol_rad;
  // converged at the tolerance; then, when polishing, up to kPolishSteps more while they
  // gain (a step that does not reduce the error ends it, converged)
  int polish_left = kPolishSteps;
  auto done = [&]() {
    const double ep2 = e.head<3>().squaredNorm(), er2 = e.tail<3>().squaredNorm();
    r.converged = ep2 <= tol_mm2 && er2 <= tol_rad2;
    if (r.converged) {
      const bool polished = polish_mm <= 0 || (ep2 <= polish_mm * polish_mm && er2 <= polish_rad * polish_rad);
      return polished || polish_left-- <= 0;
    }
    return r.iterations >= max_iterations;
  };
  auto result = [&]() {
    r.ep2 = e.head<3>().squaredNorm();
    r.er2 = e.tail<3>().squaredNorm();
    return r;
  };
  VecN qt(n), dq(n);
  Vector6d et;
  Jac6N J, Js;
  auto trial = [&](const VecN& step) {
    if (n == 6) {
      qt.head<6>() = q.head<6>() + step.head<6>();  // (the same sums, unrolled)
    } else {
      qt = q + step;
    }
    chain.evaluate(qt.data(), ctx, *fp.tmp, fp.cur);
    poseErr(T_target, fp.tmp->T_world_tcp, et);
    ++r.iterations;
    const double mt = meritSquared(et);
    if (!(mt < merit)) return false;
    if (n == 6) {
      q.head<6>() = qt.head<6>();
    } else {
      q += step;  // = qt (the same sum), without a copy
    }
    std::swap(fp.cur, fp.tmp);
    e = et;
    merit = mt;
    return true;
  };
  auto limitStep = [&](VecN& step) {
    // s = min(1, min_i limit_i / |step_i|): nothing to do unless a joint's step exceeds its
    // limit (the common case; one pass without a branch per joint)
    bool over = false;
    forEachJoint(n, [&](int i) { over |= std::abs(step[i]) > step_limit[i]; });
    if (!over) return;
    double s = 1;
    for (int i = 0; i < n; ++i)
      if (std::abs(step[i]) * s > step_limit[i]) s = step_limit[i] / std::abs(step[i]);
    step *= s;
  };

  if (n == 6) {
    // Newton with a square Jacobian
    const double tol_merit2 = tol_mm2 * inv_L2 + tol_rad2;
    constexpr double kRefresh2 = kRefreshAboveTol * kRefreshAboveTol;
    // the 3x3 block solve where its blocks are well conditioned, else the pivoted LU
    detail::Block6 block;
    const detail::Block6* fact = &block;  // the block factorisation in use
    detail::Lu6 lu;
    bool fresh = false, have = false, use_block = false, finished = false;
    while (!(finished = done())) {
      if (!have) {
        const Jac6N* Jq = J0 && f_valid && fp.cur == start ? J0 : nullptr;
        // J0 already factored (B0), else the factorisation of the Jacobian at q
        const detail::Block6* given = Jq ? B0 : nullptr;
        if (!Jq) {
          chain.jacobian(*fp.cur, J);
          Jq = &J;
        }
        J0 = nullptr;
        B0 = nullptr;
        use_block = given || block.factor(Jq->data());
        fact = given ? given : &block;
        if (!use_block && !lu.factor(Jq->data())) break;
        have = fresh = true;
      }
      dq = use_block ? fact->solve(e) : lu.solve(e);
      if (!allFinite<6>(dq.data())) break;
      limitStep(dq);
      const double before = merit;
      if (trial(dq)) {
        fresh = false;
        // slow, or still far from the tolerance (chord steps gain a fixed factor, a fresh
        // Newton step squares the error): refresh the Jacobian
        if (merit > 0.04 * before || merit > kRefresh2 * tol_merit2) have = false;
      } else if (r.converged) {
        return result();  // polishing reached the rounding level
      } else if (!fresh) {
        have = false;  // retry with the Jacobian at q
      } else {
        break;  // no descent along a fresh Newton step: Levenberg-Marquardt
      }
    }
    if (finished || done()) return result();  // (done() again only after a break)
  }

  // Levenberg-Marquardt in scaled variables: (Js^T Js + lambda I) dx = Js^T es
  double lambda = -1;
  while (!done()) {
    chain.jacobian(*fp.cur, J);
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
      for (int i = 0; i < n; ++i) dq[i] = dx[i] * columnScale(i);
      if (!dq.allFinite()) return result();
      limitStep(dq);
      if (trial(dq)) {
        accepted = true;
        lambda = std::max(lambda / 5, 1e-15 * scale);
      } else if (r.converged) {
        return result();  // polishing reached the rounding level
      } else {
        lambda *= 4;
        if (lambda > 1e6 * scale) return result();  // a local minimum of the error: stop
      }
    }
  }
  return result();
}

}  // namespace accura::calib
