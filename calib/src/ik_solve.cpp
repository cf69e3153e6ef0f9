// accura: the IK solver (ik_internal.h): closed-form seeds of the nominal geometry (all
// branches) corrected for the model's deviations, warm starts, the answer and its status.
#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>

#include "accura/calib/errors.h"
#include "ik_internal.h"

namespace accura::calib {

using detail::ClosedForm;
using detail::ClosedFormKind;
using namespace ik_detail;

std::array<double, 6> KinematicSolver::Impl::thetaOf(const VecN& q) const {
  std::array<double, 6> t{};
  for (int i = 0; i < 6; ++i) t[i] = theta0[i] + dir[i] * q[i] * kDegToRad;
  return t;
}

VecN KinematicSolver::Impl::qOf(const detail::ThetaSolution& s) const {
  VecN q(n);
  for (int i = 0; i < 6; ++i) q[i] = (s.theta[i] - theta0[i]) * kRadToDeg / dir[i];
  return q;
}

void KinematicSolver::Impl::correctSeed(VecN& q, int branch, const Eigen::Isometry3d& T_target,
    const PoseContext& ctx) const {
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

void KinematicSolver::Impl::closedFormStarts(const Eigen::Isometry3d& T_world_tcp, const Configuration& config,
    const VecN& ref, const IkOptions& o, bool correct_all, const PoseContext& ctx, std::vector<Start>& starts,
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

std::vector<KinematicSolver::Impl::Start> KinematicSolver::Impl::multiStarts(const VecN& ref) const {
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

// inverse() is about 245 lines on purpose: one decision sequence (the warm start, the
// closed-form seeds, the mirrored configurations, the fallback starts, the failure's message)
// over the per-call state its lambdas finish() and attempt() update; cut into functions, that
// state would travel through eight parameters.
IkResult KinematicSolver::Impl::inverse(const Eigen::Isometry3d& T_target, const Configuration& config,
    const Eigen::VectorXd& seed, const IkOptions& o, const PoseContext& ctx, double polish_mm,
    double polish_rad, IkWorkspace::Data* ws, double* q_out) const {
  if (!o.IsValid(nullptr)) {
    std::string why;
    o.IsValid(&why);
    throw ArgumentError(why);
  }
  if (seed.size() != 0 && seed.size() != n)
    throw ArgumentError("IK seed: expected " + std::to_string(n) + " joint values, got " + std::to_string(seed.size()));
  if (!allFinite<16>(T_target.matrix().data())) throw ArgumentError("IK target: not finite");
  // with a workspace: its frames and Jacobian are those of the seed when it holds the seed;
  // it holds the answer only when the answer is kOk (stored in finish)
  const bool reuse = ws && ws->holds(id, seed, ctx);
  // (a seed the workspace holds is, bit for bit, a solution found: finite)
  if (!reuse && !allFinite(seed.data(), seed.size())) throw ArgumentError("IK seed: not finite");
  if (ws) ws->solver_id = 0;
  std::array<KinematicFrames, 2> f_local;
  FramePair fp = ws ? FramePair{&ws->frames[static_cast<size_t>(ws->cur)], &ws->frames[static_cast<size_t>(1 - ws->cur)]}
                    : FramePair{&f_local[0], &f_local[1]};
  Jac6N J_local;
  Jac6N& J = ws ? ws->J : J_local;
  const VecN ref = seed.size() ? VecN(seed) : midRange();
  int iterations = 0;

  std::vector<IkResult> other_configuration;  // converged solutions on other configurations
  // the first singular one on the configuration (rare: allocated when found, not zeroed on
  // every call as an optional's room is)
  std::unique_ptr<IkResult> singular_solution;
  int limit_failures = 0;
  // A converged q (frames in *fp.cur): limits, singularity, configuration. Returns true when
  // `out` is the answer.
  auto finish = [&](VecN& q, Newton nt, bool warm, IkResult& out) -> bool {
    bool moved_360 = false;
    if (!fitLimits(q, config.turn, ref, o, false, 0, &moved_360)) {
      if (!warm) ++limit_failures;
      return false;
    }
    // the largest joint move from the seed (deg / mm), and the sum of the first five (rad)
    double moved_deg = 0, moved_rad = 0;
    if (warm) {
      forEachJoint(n, [&](int i) {
        const double d = std::abs(q[i] - ref[i]);
        moved_deg = std::max(moved_deg, d);
        if (i < 5) moved_rad += d * kDegToRad;
      });
    }
    if (warm && moved_deg > kWarmMaxDeg) return false;
    Configuration conf;  // (the IkResult is built only where it is the answer)
    // Status bit 0 is the sign of x_a1, the wrist point's x in the A1 frame (mm), which moves
    // by at most L per rad of joint motion: with the seed's |x_a1| (at least x_a1_abs_lo)
    // from the workspace and a move too small to reach 0, the bit is the seed's and no
    // kinematics is needed; the workspace then keeps the smaller bound
    double x_a1 = 0, x_a1_abs_lo = 0;
    const bool bit0_known = warm && reuse && status_geometry.defined && ws->x_a1_abs_lo > L * moved_rad;
    if (bit0_known) {
      conf.status = (ws->x_a1_negative ? 1 : 0) | status_geometry.elbowWristBits(q.data());
      x_a1_abs_lo = ws->x_a1_abs_lo - L * moved_rad;
    } else {
      chain.fillNominal(q.data(), *fp.cur, status_geometry.last + 1);
      conf.status = status_geometry.status(q.data(), &x_a1, fp.cur->cos_nominal.data(), fp.cur->sin_nominal.data());
      x_a1_abs_lo = std::abs(x_a1);
    }
    conf.turn = turnBits(q.data(), n);
    // warm: accepted only next to the seed and on its Status (else another solution may be
    // nearer: next to a singularity two branches come close; the closed form decides)
    if (warm && status_geometry.defined) {
      // (reused: the seed is the stored solution, whose bits the workspace keeps)
      const int seed_bits = reuse ? ws->elbow_wrist_bits : status_geometry.elbowWristBits(ref.data());
      if ((conf.status & 6) != seed_bits) return false;
      // bit 0: recomputed for the seed only when the move could have crossed 0
      if (!bit0_known && std::abs(x_a1) <= L * moved_rad &&
          (status_geometry.status(ref.data()) & 1) != (conf.status & 1))
        return false;
    }
    if (moved_360) {
      // moved by 360 deg: the same pose unless an effect depends on q itself (joint_scale)
      nt = newton(q, T_target, ctx, o, 5, fp, false, polish_mm, polish_rad);
      iterations += nt.iterations;
      if (!nt.converged) return false;
    }
    chain.jacobian(*fp.cur, J);
    // with a workspace, J factored now (the next solve's first Newton step takes this
    // factorisation instead of computing the same one); its determinant bounds the smallest
    // scaled singular value from below: where the bound clears a test's level twice, the test
    // is answered
    if (ws) ws->block_valid = n == 6 && ws->block.factor(J.data());
    const detail::Block6* factored = ws && ws->block_valid ? &ws->block : nullptr;
    // warm and more than kWarmAcceptDeg from the seed: taken only where the Jacobian is
    // regular enough that no other solution can be nearer (another solution of the same pose
    // is about sigma_min rad away or more; docs/compensation.md)
    // Passed, this test shows sigma_min above the singularity threshold too: the singularity
    // test is then answered, and the workspace keeps the proof as its certificate when it
    // reaches further than the one it holds.
    bool regular = false;
    if (warm && moved_deg > kWarmAcceptDeg) {
      const double t_move = std::max(o.singular_threshold, moved_deg * kDegToRad);
      if (!(factored && sigmaMinLowerBound(J, *factored) > 2 * t_move) && singularBelow(J, t_move)) return false;
      regular = true;
      if (ws && !chain.scaledJacobianLipschitz().empty() &&
          (ws->cert_solver_id != id || ws->cert_level - jacobianChangeBound(q, ws->cert_q) < t_move)) {
        ws->cert_solver_id = id;
        ws->cert_q = q;
        ws->cert_level = t_move;
      }
    }
    const bool singular =
        !regular && o.singular_threshold > 0 &&
        singularAt(J, q, o.singular_threshold, ws, warm ? &ref : nullptr, factored);
    const double min_singular_value = singular || o.compute_singular_value ? minSingularValue(J) : 0.0;
    // an answer at q (status, configuration, errors, smallest singular value)
    const auto answer = [&](IkResult& a, IkStatus status) {
      a.status = status;
      a.configuration = conf;
      a.position_error_mm = nt.ep();
      a.rotation_error_rad = nt.er();
      a.min_singular_value = min_singular_value;
    };
    if (!configurationMatches(config, conf)) {
      if (warm) return false;
      IkResult r;
      answer(r, IkStatus::kNoConfiguration);
      r.q = q;
      r.message = "reached with " + configurationMismatch(config, conf);
      other_configuration.push_back(std::move(r));
      return false;
    }
    if (singular) {
      // with a Status asked for, another start may find a regular solution on it: keep
      // this one and go on; with any Status the nearest solution decides: report it
      const auto asSingular = [&](IkResult& solution) {
        answer(solution, IkStatus::kSingular);
        solution.q = q;
        std::ostringstream m;
        m << "the smallest scaled singular value of the Jacobian is " << min_singular_value << ", below "
          << o.singular_threshold;
        solution.message = m.str();
      };
      if (!warm && config.status < 0) {
        asSingular(out);
        return true;
      }
      if (!warm && !singular_solution) {
        singular_solution = std::make_unique<IkResult>();
        asSingular(*singular_solution);
      }
      return false;
    }
    // `out` is still a default IkResult here (written only when finish() returns true)
    answer(out, IkStatus::kOk);
    // the solution: into the caller's array (no allocation; `seed` may be that array: it is
    // not read after this), else into the answer
    if (q_out) {
      std::copy(q.data(), q.data() + n, q_out);
    } else {
      out.q = q;
    }
    if (ws) {
      // f and J are at q: keep them for a solve seeded with this solution
      ws->solver_id = id;
      ws->cur = fp.cur == &ws->frames[0] ? 0 : 1;
      ws->q = q;
      ws->payload_kg = ctx.payload_kg;
      ws->temp_c = ctx.temp_c;
      if (!reuse) ws->dir = ctx.dir;  // (reused: the same, holds() compared them)
      ws->x_a1_abs_lo = status_geometry.defined ? x_a1_abs_lo : 0.0;
      ws->x_a1_negative = (conf.status & 1) != 0;
      ws->elbow_wrist_bits = conf.status & 6;
    }
    return true;
  };

  // the answer: every return below returns `res` (constructed in the caller's place); it is
  // written only when finish() returns true, so it is a default IkResult until then
  IkResult res;
  // 1. warm start: Newton from the seed, accepted when it stays near the seed
  if (seed.size()) {
    VecN q = ref;
    // (the Jacobian is copied in: finish() overwrites J)
    const Newton nt =
        newton(q, T_target, ctx, o, std::min(o.max_iterations, 12), fp, reuse, polish_mm, polish_rad, reuse ? &J : nullptr,
               reuse && ws->block_valid ? &ws->block : nullptr);
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
    const Newton nt = newton(q, T_target, ctx, o, max_iterations, fp, false, polish_mm, polish_rad);
    iterations += nt.iterations;
    if (!nt.converged) {
      if (nt.ep() / o.tol_mm + nt.er() / o.tol_rad < best_ep / o.tol_mm + best_er / o.tol_rad) {
        best_ep = nt.ep();
        best_er = nt.er();
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
  if (singular_solution) {
    res = std::move(*singular_solution);
    res.iterations = iterations;
    return res;
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
    res = other_configuration.front();
    res.iterations = iterations;
    return res;
  }
  IkResult& fail = res;
  fail.iterations = iterations;
  std::ostringstream m;
  const std::string margin_note =
      o.joint_margin > 0 ? " (margin " + std::to_string(o.joint_margin) + ")" : std::string();
  if (closed && branches == 0) {
    fail.status = IkStatus::kUnreachable;
    m << "the TCP pose " << formatPose(T_target) << " (mm, deg; the model's world frame) is outside the workspace";
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
    m << "the TCP pose " << formatPose(T_target) << " (mm, deg; the model's world frame): smallest error " << best_ep << " mm, " << best_er << " rad after Newton from " << starts.size()
      << " start(s)";
  }
  fail.message = m.str();
  return res;
}

}  // namespace accura::calib
