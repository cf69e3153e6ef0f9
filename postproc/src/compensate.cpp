// Discrete compensation (method.md section 4) and auxiliary points on LIN / CIRC segments.
// docs/compensation.md explains the error prediction and why its sampling is fine enough.
#include <algorithm>
#include <cmath>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"
#include "accura/calib/text.h"
#include "accura/postproc/compensate.h"
#include "path_geometry.h"

namespace accura::postproc {

using detail::PathGeometry;

bool DensifyOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (!(tol_mm >= kMinTolMm && tol_mm <= kMaxTolMm)) {
    std::ostringstream m;
    m << "path tolerance must be in [" << kMinTolMm << ", " << kMaxTolMm << "] mm, got " << tol_mm;
    return fail(m.str());
  }
  if (!(sample_step_mm >= 0.01 && sample_step_mm <= 100))
    return fail("sample step must be in [0.01, 100] mm, got " + std::to_string(sample_step_mm));
  if (!(sample_step_deg >= 0.01 && sample_step_deg <= 10))
    return fail("sample step must be in [0.01, 10] deg, got " + std::to_string(sample_step_deg));
  if (max_points_per_segment < 0 || max_points_per_segment > 100000)
    return fail("max points per segment must be in 0..100000, got " + std::to_string(max_points_per_segment));
  return ik.IsValid(error);
}

// ---------------------------------------------------------------------------------------

Compensator::Compensator(const calib::RobotModel& controller, const calib::RobotModel& real) : controller_(controller), real_(real) {
  if (controller.dof() != real.dof())
    throw calib::ArgumentError("compensation: the controller model has " + std::to_string(controller.dof()) +
                        " joints, the real model " + std::to_string(real.dof()));
}

PoseCompensation Compensator::pose(const Eigen::Isometry3d& T_desired, const calib::Configuration& config,
                                   const Eigen::VectorXd& seed, const calib::IkOptions& options,
                                   const calib::PoseContext& context) const {
  PoseCompensation out;
  const calib::IkResult r = real_.inversePolished(T_desired, config, seed, options, context, 1e-9, 1e-12);
  const bool have_q = r.status == calib::IkStatus::kOk || (r.status == calib::IkStatus::kNoConfiguration && r.q.size() > 0);
  if (!have_q) {
    out.status = r.status;
    out.message = r.message;
    return out;
  }
  out.status = calib::IkStatus::kOk;
  out.q_real = r.q;
  out.configuration = r.configuration;
  out.configuration_changed = r.status == calib::IkStatus::kNoConfiguration;
  if (out.configuration_changed)
    out.message = "the compensation changes the configuration: " + r.message;
  out.T_world_tcp_command = controller_.forward(r.q);
  out.correction_mm = (out.T_world_tcp_command.translation() - T_desired.translation()).norm();
  out.correction_deg = calib::rotationAngleDeg(out.T_world_tcp_command.linear() * T_desired.linear().transpose());
  return out;
}


// ---------------------------------------------------------------------------------------
// Auxiliary points

namespace {

/// The error of one commanded sub-segment against the intended path.
struct Prediction {
  calib::IkStatus status = calib::IkStatus::kOk;
  std::string message;
  double max_mm = 0;    ///< largest sampled distance to the intended curve
  double bound_mm = 0;  ///< max_mm plus the interpolation bound (docs/compensation.md)
  Eigen::VectorXd q_end;  ///< the controller's joints at the end
};

}  // namespace

struct SegmentWork {
  const Compensator& comp;
  const PathGeometry& intended;
  const DensifyOptions& opt;
  const calib::PoseContext& ctx;
  calib::IkOptions controller_ik;

  SegmentWork(const Compensator& c, const PathGeometry& i, const DensifyOptions& o, const calib::PoseContext& x)
      : comp(c), intended(i), opt(o), ctx(x) {
    // the controller's IK along the path: converged far below the tolerance, so that the
    // second differences of the error see the path, not the solver (1e-5 mm, 1e-8 rad)
    controller_ik = o.ik;
    controller_ik.tol_mm = 1e-5;
    controller_ik.tol_rad = 1e-8;
  }

  /// Runs the controller along `cmd` from joints q_start (its joints at the start of cmd),
  /// the real robot following, with `m` samples.
  Prediction predict(const PathGeometry& cmd, const Eigen::VectorXd& q_start, int m) const {
    Prediction p;
    Eigen::VectorXd q = q_start, q_prev = q_start;
    calib::IkWorkspace ws;  // each solve continues from the previous solution
    Eigen::Vector3d D_prev2 = Eigen::Vector3d::Zero(), D_prev = Eigen::Vector3d::Zero();
    double max_second = 0;
    for (int i = 0; i <= m; ++i) {
      const double s = static_cast<double>(i) / m;
      if (i > 0) {
        calib::IkResult failure;
        const calib::IkStatus status =
            comp.controller().follow(cmd.pose(s), calib::Configuration{}, q, controller_ik, calib::PoseContext{}, ws, &failure);
        if (status != calib::IkStatus::kOk) {
          p.status = status;
          std::ostringstream msg;
          msg << "the controller's IK fails " << calib::formatFixed(cmd.length_mm * s, 4) << " mm along the commanded path: "
              << failure.message;
          p.message = msg.str();
          return p;
        }
        // a revolute joint a turn away from the last sample: the line took it past its limit,
        // where the controller stops (software limit), and its IK answered with the value 360
        // deg away, the same pose; no continuous motion moves a joint so far between samples
        const calib::RobotDefinition& robot = comp.controller().model().nominal;
        for (int j = 0; j < robot.dof(); ++j) {
          const calib::JointSpec& spec = robot.joints[static_cast<size_t>(j)];
          const double moved = q[j] - q_prev[j];
          if (spec.type != calib::JointType::kRevolute || !(std::abs(moved) > 180.0)) continue;
          const double limit = moved < 0 ? spec.upper : spec.lower;  // the limit the joint ran into
          p.status = calib::IkStatus::kNoConfiguration;
          p.message = "along the commanded path the controller takes joint " + std::to_string(j + 1) + " (" + spec.name + ") from " +
                      calib::formatFixed(q_prev[j], 2) + " deg past its limit " + calib::formatFixed(limit, 2) + " deg " +
                      calib::formatFixed(100 * s, 0) + " % along it (the controller stops there; the pose is reached only with the joint at " +
                      calib::formatFixed(q[j], 2) + " deg): the target lies too near the limit for its correction; move it away from the limit";
          return p;
        }
      }
      q_prev = q;
      const Eigen::Vector3d x = comp.real().forward(q, ctx).translation();
      const Eigen::Vector3d D = intended.deviation(x);
      p.max_mm = std::max(p.max_mm, intended.distance(x));
      if (i >= 2) max_second = std::max(max_second, (D - 2 * D_prev + D_prev2).norm());
      D_prev2 = D_prev;
      D_prev = D;
    }
    // |D| between two samples exceeds the larger sampled |D| by at most h^2/8 max|D''|;
    // max|D''| <= 2 max|second difference| / h^2 (a factor 2 of margin): max_second / 4.
    p.bound_mm = p.max_mm + max_second / 4;
    p.q_end = q;
    return p;
  }

  /// The commanded sub-segment from (command, real joints) at sa to the intended pose at
  /// sb: the end (and for CIRC the middle as auxiliary point) compensated.
  struct Piece {
    calib::IkStatus status = calib::IkStatus::kOk;
    std::string message;
    PathSegment commanded;
    Eigen::VectorXd q_end;
  };
  Piece piece(double sa, double sb, const Eigen::Isometry3d& C_start, const Eigen::VectorXd& q_start) const {
    Piece pc;
    pc.commanded.type = intended.type;
    pc.commanded.T_world_start = C_start;
    calib::Configuration keep;
    keep.status = calib::kukaConfiguration(comp.real().model(), q_start).status;
    auto compensate = [&](double s, Eigen::Isometry3d& C, Eigen::VectorXd& q) -> bool {
      const PoseCompensation r = comp.pose(intended.pose(s), keep, q_start, opt.ik, ctx);
      if (r.status != calib::IkStatus::kOk || r.configuration_changed) {
        pc.status = r.status == calib::IkStatus::kOk ? calib::IkStatus::kNoConfiguration : r.status;
        std::ostringstream m;
        m << "the intended path at " << calib::formatFixed(intended.length_mm * s, 4) << " mm: " << r.message;
        pc.message = m.str();
        return false;
      }
      C = r.T_world_tcp_command;
      q = r.q_real;
      return true;
    };
    if (!compensate(sb, pc.commanded.T_world_end, pc.q_end)) return pc;
    if (intended.type == PathType::kCirc) {
      // the whole arc keeps the program's auxiliary point (its place on the arc), a piece
      // gets the middle of its arc
      const double s_aux = sa == 0 && sb == 1 ? intended.s_aux : 0.5 * (sa + sb);
      Eigen::VectorXd q_aux;
      if (!compensate(s_aux, pc.commanded.T_world_aux, q_aux)) return pc;
    }
    return pc;
  }
};

SegmentCompensation Compensator::segment(const PathSegment& intended_segment, const calib::Configuration& config,
                                         const Eigen::VectorXd& seed, const DensifyOptions& options,
                                         const calib::PoseContext& context) const {
  std::string why;
  if (!options.IsValid(&why)) throw calib::ArgumentError(why);
  SegmentCompensation out;
  const PathGeometry intended(intended_segment);  // throws for a degenerate CIRC
  const SegmentWork w(*this, intended, options, context);
  auto failed = [&](calib::IkStatus s, const std::string& m) {
    out.status = s;
    out.message = m;
    out.commanded.clear();
    out.q_real_end.clear();
    return out;
  };

  // the start: continuing from the seed (the real joints of the previous point), or without
  // a seed on the configuration asked for
  const PoseCompensation start =
      pose(intended_segment.T_world_start, seed.size() ? calib::Configuration{} : config, seed, options.ik, context);
  if (start.status != calib::IkStatus::kOk) return failed(start.status, "the start of the segment: " + start.message);
  out.q_real_start = start.q_real;
  const Eigen::Isometry3d C0 = start.T_world_tcp_command;

  // uncompensated: the controller runs the intended segment from its own solution
  {
    calib::IkOptions o = options.ik;
    // the controller continues from the joints the robot stands on: the solution nearest to
    // them, whatever its S/T (a joint at exactly 0 deg flips a T bit on a hair's difference)
    const calib::IkResult r0 = controller_.inverse(intended_segment.T_world_start, calib::Configuration{}, start.q_real, o);
    if (r0.status != calib::IkStatus::kOk)
      return failed(r0.status, "the controller cannot reach the start of the segment: " + r0.message);
    const Prediction p = w.predict(intended, r0.q, sampleCount(intended, options.sample_step_mm, options.sample_step_deg));
    if (p.status != calib::IkStatus::kOk) return failed(p.status, "uncompensated: " + p.message);
    out.max_error_uncompensated_mm = p.max_mm;
  }

  // greedy: extend each sub-segment as far as the tolerance allows
  const double tol = options.tol_mm;
  double sa = 0;
  Eigen::Isometry3d Ca = C0;
  Eigen::VectorXd qa = start.q_real;
  while (sa < 1) {
    // the largest end sb in (sa, 1] whose piece meets 0.9 tol on the coarse sampling
    double lo = sa, hi = 2;  // lo: largest feasible end so far; hi: smallest infeasible
    double sb = 1;
    bool have = false;
    SegmentWork::Piece best;
    Prediction best_pred;
    double best_sb = sa;
    for (int attempt = 0; attempt < 12; ++attempt) {
      const SegmentWork::Piece pc = w.piece(sa, sb, Ca, qa);
      if (pc.status != calib::IkStatus::kOk) return failed(pc.status, pc.message);
      const Prediction coarse = w.predict(PathGeometry(pc.commanded), qa, 16);
      if (coarse.status != calib::IkStatus::kOk) return failed(coarse.status, coarse.message);
      const bool feasible = coarse.bound_mm <= tol;
      if (feasible) {
        if (sb > best_sb) {
          best = pc;
          best_pred = coarse;
          best_sb = sb;
          have = true;
        }
        lo = std::max(lo, sb);
        if (sb >= 1 || coarse.bound_mm >= 0.75 * tol) break;  // at the end, or close to the limit
      } else {
        hi = std::min(hi, sb);
      }
      // the error grows with the square of the length: aim at 0.9 tol, inside (lo, hi)
      double next = sa + (sb - sa) * std::clamp(std::sqrt(0.9 * tol / std::max(coarse.bound_mm, 1e-12)), 0.3, 3.0);
      if (!(next > lo && next < hi)) next = hi <= 1 ? 0.5 * (lo + hi) : std::min(1.0, 2 * lo - sa);
      next = std::min(next, 1.0);
      if (std::abs(next - sb) < 1e-9 || hi - lo < 1e-9) break;
      sb = next;
    }
    if (!have) {
      std::ostringstream m;
      m << "the tolerance " << tol << " mm cannot be met near " << calib::formatFixed(intended.length_mm * sa, 4)
        << " mm along the segment (the error does not shrink with shorter pieces: a singularity?)";
      return failed(calib::IkStatus::kNotConverged, m.str());
    }
    // fine check of the accepted piece; shrink while it fails
    for (int shrink = 0;; ++shrink) {
      const PathGeometry cmd(best.commanded);
      const Prediction fine = w.predict(cmd, qa, sampleCount(cmd, options.sample_step_mm, options.sample_step_deg));
      if (fine.status != calib::IkStatus::kOk) return failed(fine.status, fine.message);
      if (fine.bound_mm <= tol) {
        best_pred = fine;
        break;
      }
      if (shrink >= 20) return failed(calib::IkStatus::kNotConverged, "the tolerance cannot be met (fine check)");
      best_sb = sa + 0.85 * (best_sb - sa);
      best = w.piece(sa, best_sb, Ca, qa);
      if (best.status != calib::IkStatus::kOk) return failed(best.status, best.message);
    }
    // the controller, run over the piece, must end on the real joints of its end
    if ((best_pred.q_end - best.q_end).cwiseAbs().maxCoeff() > 1e-3) {
      Eigen::Index worst = 0;
      const double differs = (best_pred.q_end - best.q_end).cwiseAbs().maxCoeff(&worst);
      return failed(calib::IkStatus::kNoConfiguration,
                    "at " + calib::formatFixed(intended.length_mm * best_sb, 1) + " mm of the " + calib::formatFixed(intended.length_mm, 1) +
                        " mm path the controller, following the line from the configuration it started in, has the joints " +
                        calib::formatList(best_pred.q_end, 2) + " where the target needs " + calib::formatList(best.q_end, 2) + " (deg, mm for a prismatic joint; joint " +
                        std::to_string(worst + 1) + " differs by " + calib::formatFixed(differs, 2) + "): the line crosses a configuration boundary (a wrist or elbow flip, or a singularity); split the motion "
                        "or program it as a PTP");
    }
    out.commanded.push_back(best.commanded);
    out.q_real_end.push_back(best.q_end);
    out.max_error_after_mm = std::max(out.max_error_after_mm, best_pred.max_mm);
    out.max_error_bound_mm = std::max(out.max_error_bound_mm, best_pred.bound_mm);
    if (static_cast<int>(out.commanded.size()) > options.max_points_per_segment + 1) {
      std::ostringstream m;
      m << "more than " << options.max_points_per_segment << " auxiliary points needed for " << tol << " mm";
      return failed(calib::IkStatus::kNotConverged, m.str());
    }
    sa = best_sb;
    Ca = best.commanded.T_world_end;
    qa = best.q_end;
  }

  // before: the endpoints (and the CIRC auxiliary point) compensated, nothing inserted
  {
    const SegmentWork::Piece whole = w.piece(0, 1, C0, start.q_real);
    if (whole.status != calib::IkStatus::kOk) return failed(whole.status, whole.message);
    const PathGeometry cmd(whole.commanded);
    const Prediction p = w.predict(cmd, start.q_real, sampleCount(cmd, options.sample_step_mm, options.sample_step_deg));
    if (p.status != calib::IkStatus::kOk) return failed(p.status, "endpoints compensated: " + p.message);
    out.max_error_before_mm = p.max_mm;
  }
  out.points_added = static_cast<int>(out.commanded.size()) - 1;
  out.status = calib::IkStatus::kOk;
  return out;
}

// ---------------------------------------------------------------------------------------
// Free functions: one Compensator per call

PoseCompensation compensatePose(const calib::RobotModel& controller, const calib::RobotModel& real, const Eigen::Isometry3d& T_desired,
                                const calib::Configuration& config, const Eigen::VectorXd& seed, const calib::IkOptions& options,
                                double payload_kg) {
  calib::PoseContext ctx;
  ctx.payload_kg = payload_kg;
  return Compensator(controller, real).pose(T_desired, config, seed, options, ctx);
}


}  // namespace accura::postproc
