// Reach and clearance checks of a program in its cell (check.h, docs/checks.md).
#include "accura/postproc/check.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/joint_map.h"
#include "accura/calib/text.h"
#include "accura/postproc/placement.h"

namespace accura::postproc {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
/// The IK model's joint limits are widened by this much (deg / mm) so that a point beyond a
/// limit still gets joint values and the report can say by how much.
constexpr double kWidenDeg = 30.0;
/// A distance made exact on demand (proven) is asked for this much (mm) beyond what the
/// decision needs, so that a lower bound that comes back decides it with a margin far above
/// rounding.
constexpr double kRefineMarginMm = 1.0;

/// Whose IK and FK define the path for one tool (the real model or the controller's) and
/// its IK with widened limits (ToolModels::check_ik).
struct ModeModels {
  const calib::RobotModel& mode_model;
  const calib::KinematicSolver& ik;
};

class Checker {
 public:
  /// `shared`: the geometry prepared for this cell and robot (copied: a copy shares the BVHs);
  /// null: built here.
  Checker(const calib::RobotModel& real, ModelFactory& models, const Cell& cell, const CheckOptions& o,
          const calib::PoseContext& context, CheckReport& r, const CellGeometry* shared)
      : real_(real), models_(models), opt_(o), t_(o.thresholds), context_(context), r_(r),
        geometry_(shared ? CellGeometry(*shared) : CellGeometry(cell, real)) {
    // scale of the singularity measure (docs/compensation.md, docs/checks.md)
    L_mm_ = real.nominal.T_flange_tcp.translation().norm();
    for (const auto& j : real.nominal.joints) L_mm_ += std::fabs(j.a_mm) + std::fabs(j.d_mm);
    L_mm_ = std::max(L_mm_, 1.0);
  }

  ModeModels models(const Eigen::Isometry3d& tool) {
    ToolModels& m = models_.forTool(tool);
    // intended: the tool rule of compensateProgram; as written: the controller's model
    const calib::RobotModel& mode = opt_.mode == CheckMode::kIntended ? m.real : m.controller;
    if (!m.check_ik) {
      calib::RobotModel wide = mode;
      for (auto& j : wide.nominal.joints) {
        j.lower -= kWidenDeg;
        j.upper += kWidenDeg;
      }
      m.check_ik = std::make_unique<calib::KinematicSolver>(wide);
    }
    return {mode, *m.check_ik};
  }

  /// sigma_min of the scaled joint Jacobian of the real model at q; `dominant`: the joints
  /// with the largest share in the singular direction.
  double sigmaMin(const Eigen::VectorXd& q, std::string* dominant) {
    const Eigen::Matrix<double, 6, Eigen::Dynamic> J = calib::jointJacobian(real_, q, context_, ws_);
    Eigen::MatrixXd S = J;
    for (int i = 0; i < S.cols(); ++i) {
      if (real_.nominal.joints[static_cast<size_t>(i)].type == calib::JointType::kRevolute) S.col(i) *= calib::kRadToDeg;
      else S.col(i) *= L_mm_;
    }
    S.topRows(3) /= L_mm_;
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(S, Eigen::ComputeFullV);
    const Eigen::Index k = svd.singularValues().size() - 1;
    if (dominant) {
      const Eigen::VectorXd v = svd.matrixV().col(k).cwiseAbs();
      dominant->clear();
      for (int i = 0; i < v.size(); ++i)
        if (v[i] >= 0.3) *dominant += (dominant->empty() ? "" : ", ") + real_.nominal.joints[static_cast<size_t>(i)].name;
    }
    return svd.singularValues()[k];
  }

  /// Smallest distance of a joint from its limits (deg / mm; negative outside) and which.
  std::pair<double, int> jointMargin(const Eigen::VectorXd& q) const {
    double best = kInf;
    int which = -1;
    for (int i = 0; i < q.size(); ++i) {
      const calib::JointSpec& j = real_.nominal.joints[static_cast<size_t>(i)];
      const double m = std::min(q[i] - j.lower, j.upper - q[i]);
      if (m < best) {
        best = m;
        which = i;
      }
    }
    return {best, which};
  }

  struct Sample {
    double s = 0;
    Eigen::VectorXd q;
    Eigen::VectorXd theta;  // rad (revolute) / mm (prismatic): what moves the geometry
    Eigen::Vector3d p_tcp = Eigen::Vector3d::Zero();
    /// per robot shape; exact below min_clearance + exact_band_mm, else possibly a lower
    /// bound (lower_bound), made exact on demand by proven() (hence mutable)
    mutable std::vector<CellGeometry::Distance> d;
  };

  Sample makeSample(double s, const Eigen::VectorXd& q, const ModeModels& tm) {
    Sample x;
    x.s = s;
    x.q = q;
    x.p_tcp = calib::forwardKinematics(tm.mode_model, q, context_, ws_).translation();
    // the real model's joint angles (rad) and d (mm) as used: what moves the geometry
    calib::forwardKinematics(real_, q, context_, ws_);
    x.theta.resize(q.size());
    for (int i = 0; i < q.size(); ++i)
      x.theta[i] = real_.nominal.joints[static_cast<size_t>(i)].type == calib::JointType::kRevolute ? ws_.theta_rad[i] : ws_.d_mm[i];
    if (geometry_.robotShapes() > 0 && geometry_.objects() > 0)
      x.d = geometry_.distances(q, context_, t_.min_clearance_mm + opt_.exact_band_mm, &r_.distance_queries);
    ++r_.samples;
    ++cur_->samples;
    for (const auto& d : x.d) cur_->min_clearance_mm = std::min(cur_->min_clearance_mm, d.mm);
    return x;
  }

  // ---- per-motion state
  struct First {
    std::optional<CheckViolation> v[4];
  };

  CheckViolation base(CheckKind kind, const WorldMotion& m, double s, double arc_mm, const Eigen::Vector3d& p,
                      const Eigen::VectorXd& q) const {
    CheckViolation v;
    v.kind = kind;
    v.motion_index = motion_index_;
    v.where = m.where;
    v.motion_type = m.label;
    v.on_path = s < 1.0;
    v.s = s;
    v.arc_mm = arc_mm;
    v.p_world_tcp_mm = p;
    v.q = q;
    return v;
  }

  std::string at(const CheckViolation& v) const {
    std::string w = v.on_path ? "on the path at s " + calib::formatFixed(v.s, 4) + " (" + calib::formatFixed(v.arc_mm, 2) + " mm from its start)" : "at the end point";
    // the frame named: the model's world (where its base was measured, e.g. the tracker's frame)
    return w + ", TCP (" + calib::formatFixed(v.p_world_tcp_mm.x(), 2) + ", " + calib::formatFixed(v.p_world_tcp_mm.y(), 2) + ", " + calib::formatFixed(v.p_world_tcp_mm.z(), 2) +
           ") mm in the model's world frame";
  }

  void record(First& f, CheckViolation v) {
    const int k = static_cast<int>(v.kind);
    if (f.v[k] && f.v[k]->s <= v.s) return;
    f.v[k] = std::move(v);
  }

  /// Joint limits and singularity at one configuration.
  void pointChecks(First& f, const WorldMotion& m, double s, double arc_mm, const Eigen::Vector3d& p, const Eigen::VectorXd& q,
                   bool singularity) {
    if (s >= 1.0 && fit_motion_ != motion_index_) {
      // issue 11: an end point outside the joint ranges the model's joint-dependent effects were
      // fitted on (the model's fit_range), as compensate reports its targets
      fit_motion_ = motion_index_;
      const std::vector<calib::OutsideFitRange> o = calib::outsideFitRanges(real_, q);
      if (!o.empty()) {
        if (outside_fit_ == 0) first_outside_ = m.where;
        ++outside_fit_;
        r_.warnings.push_back({m.where, calib::outsideFitRangeMessage(real_, "motion " + std::to_string(motion_index_ + 1) + " (" + m.label + ") end point", o)});
      }
    }
    const auto [margin, joint] = jointMargin(q);
    cur_->min_joint_margin = std::min(cur_->min_joint_margin, margin);
    if (margin < t_.joint_margin_deg) {
      CheckViolation v = base(CheckKind::kJointLimit, m, s, arc_mm, p, q);
      v.value = margin;
      v.limit = t_.joint_margin_deg;
      v.excess = t_.joint_margin_deg - margin;
      const calib::JointSpec& js = real_.nominal.joints[static_cast<size_t>(joint)];
      v.unit = js.type == calib::JointType::kRevolute ? "deg" : "mm";
      v.joint = joint;
      v.message = "joint limit: " + js.name + " = " + calib::formatFixed(q[joint], 3) + " " + v.unit + " is " + calib::formatFixed(std::abs(margin), 3) + " " + v.unit +
                  (margin < 0 ? " outside" : " inside") + " its limits [" + calib::formatFixed(js.lower, 1) + ", " + calib::formatFixed(js.upper, 1) + "]; required " +
                  calib::formatFixed(t_.joint_margin_deg, 3) + " " + v.unit + " inside (short by " + calib::formatFixed(v.excess, 3) + " " + v.unit + ") " + at(v) +
                  ", joints " + calib::formatList(q, 3);
      record(f, std::move(v));
    }
    if (singularity && t_.singular_threshold > 0) {
      std::string dominant;
      const double sigma = sigmaMin(q, &dominant);
      cur_->min_sigma = std::min(cur_->min_sigma, sigma);
      if (sigma < t_.singular_threshold) {
        CheckViolation v = base(CheckKind::kSingularity, m, s, arc_mm, p, q);
        v.value = sigma;
        v.limit = t_.singular_threshold;
        v.excess = t_.singular_threshold - sigma;
        v.message = "singularity: sigma_min " + calib::formatFixed(sigma, 6) + " below " + calib::formatFixed(t_.singular_threshold, 6) +
                    " (scaled joint Jacobian; the singular direction moves mostly " + dominant + ") " + at(v) + ", joints " + calib::formatList(q, 3);
        record(f, std::move(v));
      }
    }
  }

  void reach(First& f, const WorldMotion& m, double s, double arc_mm, const Eigen::Vector3d& p, const std::string& why) {
    CheckViolation v = base(CheckKind::kReach, m, s, arc_mm, p, Eigen::VectorXd());
    v.message = "reach: " + why + " " + at(v);
    record(f, std::move(v));
  }

  /// The first robot shape closer than the minimum at a sample, or -1.
  int clearanceViolation(const Sample& x) const {
    int worst = -1;
    for (size_t k = 0; k < x.d.size(); ++k)
      if (x.d[k].mm < t_.min_clearance_mm && (worst < 0 || x.d[k].mm < x.d[static_cast<size_t>(worst)].mm)) worst = static_cast<int>(k);
    return worst;
  }

  void clearance(First& f, const WorldMotion& m, const Sample& x, double arc_mm) {
    const int k = clearanceViolation(x);
    if (k < 0) return;
    const CellGeometry::Distance& d = x.d[static_cast<size_t>(k)];
    CheckViolation v = base(CheckKind::kClearance, m, x.s, arc_mm, x.p_tcp, x.q);
    v.value = d.mm;
    v.limit = t_.min_clearance_mm;
    v.excess = t_.min_clearance_mm - d.mm;
    v.unit = "mm";
    v.robot_part = geometry_.robotShapeName(d.robot_shape);
    v.obstacle = d.object >= 0 ? geometry_.objectName(d.object) : "";
    // the first violation of a motion is where the clearance first drops below the minimum:
    // found by bisection, it is often the crossing itself ("5.000 mm, short by 0.000 mm" reads
    // as no violation), so that case says so; the smallest clearance of the motion is its own field
    if (calib::formatFixed(v.excess, 3) == "0.000")
      v.message = "clearance: " + v.robot_part + " comes closer to " + v.obstacle + " than the required " + calib::formatFixed(t_.min_clearance_mm, 3) +
                  " mm from here on, " + at(v) + ", joints " + calib::formatList(x.q, 3);
    else
      v.message = "clearance: " + v.robot_part + " is " + calib::formatFixed(d.mm, 3) + " mm from " + v.obstacle + (d.mm <= 0 ? " (in contact)" : "") +
                  ", required " + calib::formatFixed(t_.min_clearance_mm, 3) + " mm (short by " + calib::formatFixed(v.excess, 3) + " mm) " + at(v) + ", joints " +
                  calib::formatList(x.q, 3);
    record(f, std::move(v));
  }

  /// Is the clearance between samples a and b proven (docs/checks.md)? For each robot shape:
  /// (d_a + d_b - M) / 2 >= min_clearance, M the bound on how far its points move. A distance
  /// that is only a lower bound (far: Sample::d) and fails it is asked again, exact below what
  /// the decision needs (plus kRefineMarginMm): the answer is then that of exact distances.
  bool proven(const Sample& a, const Sample& b, double factor, bool* below_resolution) {
    bool ok = true;
    bool small = true;
    for (size_t k = 0; k < a.d.size(); ++k) {
      double M = 0;
      for (int i = 0; i < a.theta.size(); ++i) M += std::fabs(b.theta[i] - a.theta[i]) * geometry_.leverArm(static_cast<int>(k), i);
      M *= factor;
      if (M > opt_.resolution_mm) small = false;
      if (!ok) continue;  // not proven already: the other shapes cannot change that
      const auto fails = [&]() { return 0.5 * (a.d[k].mm + b.d[k].mm - M) < t_.min_clearance_mm; };
      // exact wherever a distance is below the value that would prove the interval
      const auto refine = [&](const Sample& x, const Sample& other) {
        if (!x.d[k].lower_bound || !fails()) return;
        const double needed = 2 * t_.min_clearance_mm + M - other.d[k].mm + kRefineMarginMm;
        x.d[k] = geometry_.distance(static_cast<int>(k), x.q, context_, needed, &r_.distance_queries);
      };
      refine(a, b);  // a exact, or at least enough to prove it
      refine(b, a);  // then b likewise: what remains fails on exact values
      if (fails()) ok = false;
    }
    *below_resolution = small;
    return ok;
  }

  /// The first sample strictly inside (a, b) closer than the minimum, found by subdivision;
  /// `mid(s, left)` makes the sample at s (nullopt when it cannot: reach).
  std::optional<Sample> firstInside(const Sample& a, const Sample& b, double factor,
                                    const std::function<std::optional<Sample>(double, const Sample&)>& mid, int depth) {
    bool small = false;
    if (proven(a, b, factor, &small) || small) return std::nullopt;
    if (depth > 60) {
      r_.warnings.push_back({cur_->where, "clearance subdivision stopped at depth 60 near s " + calib::formatFixed(a.s, 9)});
      return std::nullopt;
    }
    const std::optional<Sample> m = mid(0.5 * (a.s + b.s), a);
    if (!m) return std::nullopt;  // reported by mid
    if (auto left = firstInside(a, *m, factor, mid, depth + 1)) return left;
    if (clearanceViolation(*m) >= 0) return m;
    return firstInside(*m, b, factor, mid, depth + 1);
  }

  // ---- motions

  void emit(First& f) {
    std::vector<CheckViolation> v;
    for (auto& x : f.v)
      if (x) v.push_back(std::move(*x));
    std::stable_sort(v.begin(), v.end(), [](const CheckViolation& a, const CheckViolation& b) { return a.s < b.s; });
    for (auto& x : v) r_.violations.push_back(std::move(x));
  }

  void run(const std::vector<WorldMotion>& motions, const std::vector<int>& indices, const std::vector<bool>& start_unknown) {
    std::optional<Sample> prev;
    const calib::RobotModel* prev_models = nullptr;  // the mode model of the previous motion (cached: its address names it)
    for (size_t mi = 0; mi < motions.size(); ++mi) {
      const WorldMotion& m = motions[mi];
      motion_index_ = indices[mi];
      MotionCheck mc;
      mc.motion_index = motion_index_;
      mc.where = m.where;
      mc.motion_type = m.label;
      mc.checked = true;
      mc.min_clearance_mm = kInf;
      mc.min_sigma = kInf;
      mc.min_joint_margin = kInf;
      cur_ = &mc;
      if (start_unknown[mi]) prev.reset();
      const ModeModels tm = models(m.T_flange_tcp);
      First f;
      try {
        if (prev && prev_models != &tm.mode_model) {
          // the tool changed: the start is the same joint values with the new tool
          prev = makeSample(0, prev->q, tm);
        }
        const bool cartesian_path = (m.type == MotionType::kLin || m.type == MotionType::kCirc);
        if (!m.q_end.size() && !cartesian_path) {
          ptpTo(f, m, tm, prev, solveEnd(f, m, tm, prev));
        } else if (m.q_end.size() && !cartesian_path) {
          ptpTo(f, m, tm, prev, m.q_end);
        } else if (!prev) {
          if (m.q_end.size()) ptpTo(f, m, tm, prev, m.q_end);
          else ptpTo(f, m, tm, prev, solveEnd(f, m, tm, prev));
          mc.note = m.label + " from a position that is not known (the first motion, or after one that could not be checked): its end point is checked, its path is not";
          r_.warnings.push_back({m.where, mc.note});
        } else {
          path(f, m, tm, prev);
        }
      } catch (const calib::NumericalError& e) {
        mc.checked = false;
        mc.note = std::string("cannot be checked: ") + e.what();
        r_.unchecked.push_back({m.where, mc.note});
        prev.reset();
      }
      prev_models = &tm.mode_model;
      emit(f);
      r_.motions.push_back(mc);
    }
    if (outside_fit_ > 0)
      r_.warnings.push_back({first_outside_, std::to_string(outside_fit_) + " of " + std::to_string(motions.size()) +
                                                 " end point(s) outside the fitted joint ranges; the model's correction there is an extrapolation"});
  }

  /// IK of a Cartesian end point (reach, configuration); nullopt after a reach violation.
  std::optional<Eigen::VectorXd> solveEnd(First& f, const WorldMotion& m, const ModeModels& tm, const std::optional<Sample>& prev) {
    calib::IkOptions o;
    o.joint_margin = 0;
    o.singular_threshold = 0;
    const Eigen::VectorXd seed = m.type == MotionType::kPtp && m.q_near.size() ? m.q_near : prev ? prev->q : Eigen::VectorXd();
    const calib::IkResult ik = tm.ik.inverse(m.T_world_tcp_end, m.configuration, seed, o, context_);
    if (ik.status == calib::IkStatus::kOk) return ik.q;
    std::string why = std::string(toString(ik.status)) + (ik.message.empty() ? "" : " (" + ik.message + ")");
    if (ik.status == calib::IkStatus::kJointLimits) why = "reachable only more than " + calib::formatFixed(kWidenDeg, 0) + " deg/mm beyond the joint limits";
    if (ik.status == calib::IkStatus::kNoConfiguration && ik.q.size()) {
      const calib::Configuration c = ik.configuration;
      why = "reachable only on configuration S " + std::to_string(c.status) + " T " + std::to_string(c.turn) + ", not on S " +
            std::to_string(m.configuration.status) + " T " + std::to_string(m.configuration.turn) + " the target names";
    }
    reach(f, m, 1.0, 0.0, m.T_world_tcp_end.translation(), why);
    return std::nullopt;
  }

  void ptpTo(First& f, const WorldMotion& m, const ModeModels& tm, std::optional<Sample>& prev, const std::optional<Eigen::VectorXd>& q_end) {
    if (!q_end) {
      prev.reset();
      return;
    }
    Sample end = makeSample(1.0, *q_end, tm);
    cur_->length_mm = prev ? (end.p_tcp - prev->p_tcp).norm() : 0.0;  // chord: the PTP path is not a line
    pointChecks(f, m, 1.0, cur_->length_mm, end.p_tcp, end.q, true);
    if (prev) {
      // joint-space motion: q(s) = q_a + s (q_b - q_a); the bound is exact for it (factor 1)
      const Eigen::VectorXd qa = prev->q, qb = *q_end;
      Sample start = *prev;
      start.s = 0;
      auto mid = [&](double s, const Sample&) -> std::optional<Sample> { return makeSample(s, qa + s * (qb - qa), tm); };
      if (auto v = firstInside(start, end, 1.0, mid, 0)) clearance(f, m, *v, (v->p_tcp - start.p_tcp).norm());
    }
    clearance(f, m, end, cur_->length_mm);
    prev = end;
  }

  void path(First& f, const WorldMotion& m, const ModeModels& tm, std::optional<Sample>& prev) {
    PathSegment seg;
    seg.type = m.type == MotionType::kCirc ? PathType::kCirc : PathType::kLin;
    seg.T_world_start = calib::forwardKinematics(tm.mode_model, prev->q, context_, ws_);
    seg.T_world_aux = m.T_world_tcp_aux;
    seg.T_world_end = m.q_end.size() ? calib::forwardKinematics(tm.mode_model, m.q_end, context_, ws_) : m.T_world_tcp_end;
    const double length = pathLength(seg);
    const double rot_deg = pathRotation(seg) * calib::kRadToDeg;
    cur_->length_mm = length;
    const int n0 = std::max(1, static_cast<int>(std::ceil(std::max(length / opt_.sample_step_mm, rot_deg / opt_.sample_step_deg))));
    calib::IkOptions o;
    o.joint_margin = 0;
    o.singular_threshold = 0;
    bool failed = false;
    // IK at s continuing from `left` (the configuration of the start, as the controller does)
    auto solve = [&](double s, const Sample& left) -> std::optional<Sample> {
      const Eigen::Isometry3d T = interpolate(seg, s);
      const calib::IkResult ik = tm.ik.inverse(T, calib::Configuration{}, left.q, o, context_);
      if (ik.status != calib::IkStatus::kOk) {
        std::string why = std::string(toString(ik.status)) + (ik.message.empty() ? "" : " (" + ik.message + ")");
        if (ik.status == calib::IkStatus::kJointLimits) why = "reachable only more than " + calib::formatFixed(kWidenDeg, 0) + " deg/mm beyond the joint limits";
        reach(f, m, s, s * length, T.translation(), why);
        failed = true;
        return std::nullopt;
      }
      return makeSample(s, ik.q, tm);
    };
    // pre-samples: uniform, then bisected until no joint moves more than max_joint_step_deg
    std::vector<Sample> xs;
    Sample start = *prev;
    start.s = 0;
    xs.push_back(start);
    std::function<bool(const Sample&, const Sample&, int, std::vector<Sample>&)> refine =
        [&](const Sample& a, const Sample& b, int depth, std::vector<Sample>& out) -> bool {
      if ((b.q - a.q).cwiseAbs().maxCoeff() <= opt_.max_joint_step_deg) {
        out.push_back(b);
        return true;
      }
      if (depth > 30) {  // a jump of the joint values: the path crosses a singularity
        std::string dominant;
        const double sigma = sigmaMin(b.q, &dominant);
        CheckViolation v = base(CheckKind::kSingularity, m, b.s, b.s * length, b.p_tcp, b.q);
        v.value = sigma;
        v.limit = t_.singular_threshold;
        v.excess = std::max(0.0, t_.singular_threshold - sigma);
        v.message = "singularity: the joint values jump by " + calib::formatFixed((b.q - a.q).cwiseAbs().maxCoeff(), 3) +
                    " deg within s " + calib::formatFixed(b.s - a.s, 9) + " (the path passes through a singularity; sigma_min " +
                    calib::formatFixed(sigma, 6) + ", direction " + dominant + ") " + at(v);
        record(f, std::move(v));
        failed = true;
        return false;
      }
      const std::optional<Sample> mid = solve(0.5 * (a.s + b.s), a);
      if (!mid) return false;
      return refine(a, *mid, depth + 1, out) && refine(*mid, b, depth + 1, out);
    };
    for (int k = 1; k <= n0 && !failed; ++k) {
      const std::optional<Sample> b = solve(static_cast<double>(k) / n0, xs.back());
      if (!b) break;
      if (!refine(xs.back(), *b, 0, xs)) break;
    }
    // point checks at every pre-sample but the start (the previous motion's end)
    for (size_t k = 1; k < xs.size(); ++k) pointChecks(f, m, xs[k].s, xs[k].s * length, xs[k].p_tcp, xs[k].q, true);
    // clearance: every pre-sample and the subdivision between them, first violation only
    auto mid = [&](double s, const Sample& left) { return solve(s, left); };
    for (size_t k = 1; k < xs.size(); ++k) {
      if (auto v = firstInside(xs[k - 1], xs[k], opt_.cartesian_bound_factor, mid, 0)) {
        clearance(f, m, *v, v->s * length);
        break;
      }
      if (clearanceViolation(xs[k]) >= 0) {
        clearance(f, m, xs[k], xs[k].s * length);
        break;
      }
    }
    if (failed || xs.back().s < 1.0) {
      prev.reset();
      return;
    }
    // the S/T written with a CP target are not used by the controller (Status kept from the
    // start, Turn along the path: docs/program-formats.md, "Status and Turn"): no check
    prev = xs.back();
  }

 private:
  const calib::RobotModel& real_;
  ModelFactory& models_;
  const CheckOptions& opt_;
  const CheckThresholds& t_;
  calib::PoseContext context_;
  CheckReport& r_;
  CellGeometry geometry_;
  double L_mm_ = 1;
  calib::KinematicWorkspace ws_;
  MotionCheck* cur_ = nullptr;
  int motion_index_ = 0;
  int fit_motion_ = -1;     // the motion whose end point was compared with the fitted ranges
  int outside_fit_ = 0;     // end points outside them
  SourceLocation first_outside_;
};

void finish(CheckReport& r) {
  r.min_clearance_mm = kInf;
  r.min_sigma = kInf;
  r.min_joint_margin = kInf;
  for (const auto& m : r.motions) {
    r.min_clearance_mm = std::min(r.min_clearance_mm, m.min_clearance_mm);
    r.min_sigma = std::min(r.min_sigma, m.min_sigma);
    r.min_joint_margin = std::min(r.min_joint_margin, m.min_joint_margin);
  }
}

CheckReport checkWorld(const calib::RobotModel& real, const calib::RobotModel& controller, ModelFactory& models, const Cell& cell, const std::vector<WorldMotion>& motions,
                       const std::vector<int>& indices, const std::vector<bool>& start_unknown, const CheckOptions& options,
                       const calib::PoseContext& context, CheckReport r, const CellGeometry* geometry) {
  std::string why;
  if (!options.IsValid(&why)) throw calib::ArgumentError("check options: " + why);
  if (real.dof() != controller.dof())
    throw calib::ArgumentError("check: the real model has " + std::to_string(real.dof()) + " joints, the controller " + std::to_string(controller.dof()));
  real.validate();
  controller.validate();
  r.mode = options.mode;
  r.thresholds = options.thresholds;
  if (geometry && !geometry->madeFor(cell, real))
    throw calib::ArgumentError("check: the prepared cell geometry was made for another cell or robot than the one checked");
  // objects but nothing of the robot to measure them against: say so, never a silent pass
  if (!cell.objects.empty() && cell.link_shapes.empty() && cell.tool_shapes.empty())
    r.warnings.push_back({SourceLocation{cell.file, 0, 0},
                          "clearance not checked: the cell has " + std::to_string(cell.objects.size()) +
                              " object(s) but no robot geometry (no <tool>, no <link>), so no distance was measured; add the tool "
                              "and link geometry to the cell file to check the clearance"});
  // a mesh only millimetres across is a file in metres (or inches) given units="mm", more
  // likely than a real part: a 2 m table read so is 2 mm and would leave its clearance unchecked
  const auto smallMesh = [&](const CellShape& s, const std::string& what) {
    if (!s.mesh || s.mesh->vertices_mm.empty()) return;
    Eigen::Vector3d lo = s.mesh->vertices_mm.front(), hi = lo;
    for (const auto& v : s.mesh->vertices_mm) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
    const double across = (hi - lo).norm();
    if (across < kSmallMesh_mm)
      r.warnings.push_back({SourceLocation{cell.file, s.line, s.column},
                            what + ": its mesh " + s.mesh->file + " is only " + calib::formatFixed(across, 3) +
                                " mm across: check the units the cell gives the file (a file in metres needs units=\"m\"); the check "
                                "measures it as it is"});
  };
  for (const CellShape& s : cell.objects) smallMesh(s, "object '" + s.name + "'");
  for (const auto& [joint, s] : cell.link_shapes) smallMesh(s, s.name);
  for (const CellShape& s : cell.tool_shapes) smallMesh(s, s.name);
  Checker c(real, models, cell, options, context, r, geometry);
  c.run(motions, indices, start_unknown);
  finish(r);
  return r;
}

}  // namespace

const char* toString(CheckMode mode) { return mode == CheckMode::kIntended ? "intended" : "as_written"; }

const char* toString(CheckKind kind) {
  switch (kind) {
    case CheckKind::kReach: return "reach";
    case CheckKind::kJointLimit: return "joint_limit";
    case CheckKind::kSingularity: return "singularity";
    case CheckKind::kClearance: return "clearance";
  }
  return "?";
}

bool CheckOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  // "expected ..., found VALUE": a NaN or an infinity is named as such, not as a value below 0
  auto check = [&](double v, bool ok, const char* name, const char* expected) {
    if (ok && std::isfinite(v)) return true;
    std::ostringstream m;
    m << name << ": expected " << expected << ", found " << v;
    return bad(m.str());
  };
  if (!check(thresholds.joint_margin_deg, thresholds.joint_margin_deg >= 0, "joint_margin_deg", "a finite angle >= 0 (deg)")) return false;
  if (!check(thresholds.singular_threshold, thresholds.singular_threshold >= 0, "singular_threshold", "a finite value >= 0")) return false;
  if (!check(thresholds.min_clearance_mm, thresholds.min_clearance_mm >= 0, "min_clearance_mm", "a finite distance >= 0 (mm)")) return false;
  if (!check(sample_step_mm, sample_step_mm > 0, "sample_step_mm", "a finite distance > 0 (mm)")) return false;
  if (!check(sample_step_deg, sample_step_deg > 0, "sample_step_deg", "a finite angle > 0 (deg)")) return false;
  if (!check(max_joint_step_deg, max_joint_step_deg > 0, "max_joint_step_deg", "a finite angle > 0 (deg)")) return false;
  if (!check(resolution_mm, resolution_mm > 0, "resolution_mm", "a finite distance > 0 (mm)")) return false;
  if (!check(cartesian_bound_factor, cartesian_bound_factor >= 1, "cartesian_bound_factor", "a finite factor >= 1")) return false;
  if (!(exact_band_mm > 0)) return bad("exact_band_mm must be > 0 (infinity: every distance exact)");
  return true;
}

CheckReport checkMotions(const calib::RobotModel& real, const calib::RobotModel& controller, const Cell& cell, const std::vector<WorldMotion>& motions,
                         const CheckOptions& options, const calib::PoseContext& context) {
  std::vector<int> idx(motions.size());
  for (size_t i = 0; i < motions.size(); ++i) idx[i] = static_cast<int>(i);
  for (const auto& m : motions)
    if (m.q_end.size() && m.q_end.size() != real.dof())
      throw calib::ArgumentError("checkMotions: an axis target has " + std::to_string(m.q_end.size()) + " values, the robot " + std::to_string(real.dof()) + " joints");
  ModelFactory models(real, controller);
  return checkWorld(real, controller, models, cell, motions, idx, std::vector<bool>(motions.size(), false), options, context, CheckReport{}, nullptr);
}

namespace {

CheckReport checkProgramWith(const Program& program, const JobSettings& given, const Cell& cell, const CheckOptions& options,
                             const CellGeometry* geometry) {
  requireArmForProgram(program, given.calibrated.nominal);
  const JobSettings job = settingsForProgram(program, given);  // (a URScript program's Base)
  requireOneUndeclaredFrame(program, job);
  CheckReport r;
  // frames and models, as compensateProgram (placement.h); the cell's <robot> is the placement
  // unless --base gives it
  const JobSettings placed = placedInCell(job, cell);
  ModelFactory models(placed, placeRobot(placed, "--base x,y,z,A,B,C or the cell file's <robot>"));
  const Eigen::Isometry3d T_world_kworld = models.placement().T_world_kworld;
  const calib::RobotModel controller = models.forTool(job.calibrated.nominal.T_flange_tcp).controller;

  std::vector<WorldMotion> wm;
  std::vector<int> idx;
  std::vector<bool> start_unknown;
  std::map<int, MotionCheck> skipped;
  bool unknown = false;  // the position before the next motion is not known
  std::optional<Eigen::Isometry3d> T_world_flange;  // where the program meant the flange to be
  std::optional<Eigen::VectorXd> q_known;
  const int dof = job.calibrated.dof();
  const bool reads_st = controllerReadsConfiguration(job.calibrated.nominal);
  for (size_t i = 0; i < program.motions.size(); ++i) {
    const Motion& m = program.motions[i];
    auto skip = [&](const std::string& why) {
      MotionCheck mc;
      mc.motion_index = static_cast<int>(i);
      mc.where = m.where;
      mc.motion_type = motionKeyword(m);
      mc.checked = false;
      mc.note = why;
      mc.min_clearance_mm = kInf;
      mc.min_sigma = kInf;
      mc.min_joint_margin = kInf;
      skipped[static_cast<int>(i)] = mc;
      r.unchecked.push_back({m.where, motionKeyword(m) + " not checked: " + why});
      unknown = true;
      T_world_flange.reset();
      q_known.reset();
    };
    if (!m.target_problem.empty()) { skip(m.target_problem); continue; }
    if (m.relative) { skip("relative motions (_REL) are not checked"); continue; }
    if (m.external_tcp) { skip("external TCP (IPO_FRAME #TCP) is not supported"); continue; }
    if (m.circ_angle_deg) { skip("CIRC with CA (circular angle) is not supported"); continue; }
    if (m.type == MotionType::kSpl) { skip("spline segments (SPL) are not checked"); continue; }
    std::optional<calib::XyzAbc> tool = m.tool.value, base = m.base.value;
    if (m.tool.source == FrameSetting::Source::kUnset && job.initial_tool) tool = job.initial_tool;
    if (m.base.source == FrameSetting::Source::kUnset && job.initial_base) base = job.initial_base;
    WorldMotion w;
    w.type = m.type;
    w.where = m.where;
    w.label = motionKeyword(m);
    const Eigen::Isometry3d T_flange_tcp = tool ? calib::toIsometry(*tool) : job.calibrated.nominal.T_flange_tcp;
    w.T_flange_tcp = T_flange_tcp;
    if (m.target.kind == Target::Kind::kAxis) {
      Eigen::VectorXd q(dof);
      bool known = true;
      for (int k = 0; k < dof; ++k) {
        if (k < 6 && m.target.axes[static_cast<size_t>(k)]) q[k] = *m.target.axes[static_cast<size_t>(k)];
        else if (q_known) q[k] = (*q_known)[k];
        else known = false;
      }
      if (!known) { skip("a partial axis target after an unknown position"); continue; }
      if (m.type == MotionType::kCirc) { skip("CIRC to an axis target"); continue; }
      w.q_end = q;
      q_known = q;
      calib::KinematicWorkspace ws;
      T_world_flange = calib::forwardKinematics(models.controllerFlange(), q, calib::PoseContext{}, ws);
    } else {
      if (!tool) { skip("the tool ($TOOL) of this motion is not known (--program-tool or --config)"); continue; }
      if (!base) { skip("the base ($BASE) of this motion is not known (--program-base or --config)"); continue; }
      const Eigen::Isometry3d T_world_progbase = T_world_kworld * calib::toIsometry(*base);
      auto complete = [&](Target t) -> std::optional<Eigen::Isometry3d> {
        if (!t.completePose()) {
          if (!T_world_flange) return std::nullopt;
          const calib::XyzAbc prevp = calib::toXyzAbc(T_world_progbase.inverse() * *T_world_flange * T_flange_tcp);
          const double p[6] = {prevp.x_mm, prevp.y_mm, prevp.z_mm, prevp.a_deg, prevp.b_deg, prevp.c_deg};
          for (size_t k = 0; k < 6; ++k)
            if (!t.pose[k]) t.pose[k] = p[k];
        }
        return T_world_progbase * calib::toIsometry(t.xyzAbc());
      };
      const auto end = complete(m.target);
      if (!end) { skip("a partial target after an unknown position"); continue; }
      w.T_world_tcp_end = *end;
      // the written S/T; a UR controller reads none (docs/compensation.md, section 2): the solution
      // nearest the joints before, the written Status only as the guess of the branch after an
      // unknown start
      w.configuration = askedConfiguration(reads_st, calib::Configuration{m.target.status.value_or(-1), m.target.turn.value_or(-1)},
                                           !(wm.empty() || unknown || m.start_unknown));
      if (m.qnear_deg && m.qnear_deg->size() == static_cast<size_t>(job.calibrated.dof()))
        w.q_near = Eigen::Map<const Eigen::VectorXd>(m.qnear_deg->data(), 6);
      if (m.type == MotionType::kCirc) {
        if (!m.aux) { skip("CIRC without an auxiliary point"); continue; }
        const auto aux = complete(*m.aux);
        if (!aux) { skip("a partial auxiliary point after an unknown position"); continue; }
        w.T_world_tcp_aux = *aux;
      }
      T_world_flange = *end * T_flange_tcp.inverse();
      q_known.reset();
    }
    wm.push_back(w);
    idx.push_back(static_cast<int>(i));
    start_unknown.push_back(unknown);
    unknown = false;
  }
  CheckReport out = checkWorld(job.calibrated, controller, models, cell, wm, idx, start_unknown, options, job.context, r, geometry);
  // motions in program order, the skipped ones included
  std::vector<MotionCheck> all;
  size_t k = 0;
  for (size_t i = 0; i < program.motions.size(); ++i) {
    auto it = skipped.find(static_cast<int>(i));
    if (it != skipped.end()) all.push_back(it->second);
    else if (k < out.motions.size()) all.push_back(out.motions[k++]);
  }
  out.motions = all;
  finish(out);
  return out;
}

}  // namespace

CheckReport checkProgram(const Program& program, const JobSettings& job, const Cell& cell, const CheckOptions& options) {
  return checkProgramWith(program, job, cell, options, nullptr);
}

CheckReport checkProgram(const Program& program, const JobSettings& job, const Cell& cell, const CheckOptions& options,
                         const CellGeometry& geometry) {
  return checkProgramWith(program, job, cell, options, &geometry);
}

}  // namespace accura::postproc
