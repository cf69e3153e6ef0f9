// accura: the identification's analysis (identify_internal.h): identifiability of the
// candidates, the weights (variance components, unmodelled error), the uncertainties and the
// summary's diagnostics.
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "accura/calib/errors.h"
#include "accura/calib/joint_map.h"
#include "dense_linalg.h"
#include "identify_internal.h"

namespace accura::calib::identify_detail {
namespace {

// Condition number of a matrix J from its Gram matrix N = J^T J (and its singular values).
double conditionOf(const Eigen::MatrixXd& N, Eigen::VectorXd* sv) {
  if (N.cols() == 0) return 1.0;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(N);
  Eigen::VectorXd lambda = es.eigenvalues().cwiseMax(0.0);
  *sv = lambda.cwiseSqrt();
  const double smax = sv->maxCoeff(), smin = sv->minCoeff();
  if (!(smin > 1e-15 * smax)) return std::numeric_limits<double>::infinity();
  return smax / smin;
}

}  // namespace

std::string fmtNum(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

bool Problem::lastAt(const std::vector<double>& xs) const {
  if (!last.valid || last.x != xs || last.weights.size() != weights.size()) return false;
  for (size_t i = 0; i < weights.size(); ++i)
    if (last.weights[i].dim != weights[i].dim || last.weights[i].w != weights[i].w) return false;
  return true;
}

void Problem::keep(const std::vector<double>& xs, const Eigen::MatrixXd& J, const Eigen::VectorXd& r) const {
  last.x = xs;
  last.weights = weights;
  last.J = J;
  last.r = r;
  last.valid = true;
}

void Problem::stack(Eigen::MatrixXd* J, Eigen::VectorXd* r) const {
  if (lastAt(x)) {
    if (J) *J = last.J;
    if (r) *r = last.r;
    return;
  }
  RowStack rows(model, plan, st);
  Eigen::VectorXd r_local;
  Eigen::VectorXd& rr = r ? *r : r_local;
  rows.stack(x, data, weights, J, &rr);
  if (J) keep(x, *J, rr);
}

// The weighted Jacobian's columns row by row from the compact rows (the stacked Jacobian over
// hundreds of map coefficients is never formed): col_sq gets every column's squared norm over
// x; each non-zero column block of a row goes to visit(first equation, x index, column).
template <class Visit>
void weightedColumns(const Problem& pb, Eigen::VectorXd* col_sq, const Visit& visit) {
  col_sq->setZero(static_cast<Eigen::Index>(pb.X));
  RowStack rows(pb.model, pb.plan, pb.st);
  Eigen::Index row = 0;
  for (size_t i = 0; i < pb.data.rows.size(); ++i) {
    rows.poseCompact(pb.x, pb.data.rows[i], i);
    const int dim = pb.weights[i].dim;
    const Eigen::MatrixXd Jw = pb.weights[i].w.head(dim).asDiagonal() * rows.Jc().topRows(dim);
    for (size_t k = 0; k < rows.idx().size(); ++k) {
      const int xi = rows.idx()[k];
      if (xi < 0) continue;
      const Eigen::VectorXd col = Jw.col(static_cast<Eigen::Index>(k));
      (*col_sq)[xi] += col.squaredNorm();
      visit(row, xi, col);
    }
    row += dim;
  }
}

void refreshPenaltyRows(Problem& pb, double smoothing) {
  if (!pb.sparse) return;
  Eigen::VectorXd col_sq;
  weightedColumns(pb, &col_sq, [](Eigen::Index, int, const Eigen::VectorXd&) {});
  pb.penalties.clear();
  penaltyRows(pb, smoothing, col_sq);
}

// Identifiability on the scaled weighted Jacobian at the starting point (the joint maps'
// coefficients are not candidates here: they are regularised, see penaltyRows).
int identifiability(Problem& pb, const IdentifyOptions& options, IdentifySummary& summary, Eigen::VectorXd* col_sq) {
  const size_t P = pb.P;
  const std::vector<ParamInfo>& layout = pb.layout;
  auto isMap = [&](size_t k) { return pb.isMap(k); };
  std::vector<int> cand_idx;
  for (size_t k = 0; k < P; ++k)
    if (!isMap(k)) cand_idx.push_back(static_cast<int>(k));
  Eigen::MatrixXd Js;
  if (!pb.sparse) {
    Eigen::MatrixXd Jfull;
    pb.stack(&Jfull, nullptr);  // kept for the solve's first evaluation
    *col_sq = Jfull.colwise().squaredNorm().transpose();
    Js.resize(Jfull.rows(), static_cast<Eigen::Index>(cand_idx.size()));
    for (size_t c = 0; c < cand_idx.size(); ++c) Js.col(c) = Jfull.col(cand_idx[c]);
  } else {
    // joint maps: the candidates' columns and the squared column norms from the compact rows
    // (the stacked Jacobian over hundreds of map coefficients is never formed)
    std::vector<int> cand_of(pb.X, -1);
    for (size_t c = 0; c < cand_idx.size(); ++c) cand_of[static_cast<size_t>(cand_idx[c])] = static_cast<int>(c);
    Js.setZero(pb.m_eq, static_cast<Eigen::Index>(cand_idx.size()));
    weightedColumns(pb, col_sq, [&](Eigen::Index row, int xi, const Eigen::VectorXd& col) {
      if (cand_of[static_cast<size_t>(xi)] >= 0) Js.block(row, cand_of[static_cast<size_t>(xi)], col.size(), 1) = col;
    });
  }
  const Eigen::Index m = Js.rows();
  Eigen::VectorXd norms = Js.colwise().norm();
  // the columns scaled to unit norm and their Gram matrix (the conditions and the explanation
  // of a dependent parameter are computed from it)
  Eigen::MatrixXd Jn(m, static_cast<Eigen::Index>(cand_idx.size()));
  for (size_t c = 0; c < cand_idx.size(); ++c)
    Jn.col(c) = norms[c] > 0 ? Eigen::VectorXd(Js.col(c) / norms[c]) : Eigen::VectorXd(Js.col(c));
  Eigen::MatrixXd Gram = detail::gram(Jn);
  std::vector<bool>& free = pb.free;
  free.assign(pb.X, true);
  for (size_t k = 0; k < P; ++k)
    if (!isMap(k)) free[k] = false;
  std::vector<int> kept;  // indices into cand_idx
  Eigen::MatrixXd Qall(m, static_cast<Eigen::Index>(cand_idx.size()));  // orthonormal basis of the kept columns
  for (size_t c = 0; c < cand_idx.size(); ++c) {
    const auto Q = Qall.leftCols(static_cast<Eigen::Index>(kept.size()));
    const ParamInfo& p = layout[cand_idx[c]];
    const double colmax = norms.maxCoeff();
    if (!(norms[c] > 1e-12 * colmax)) {
      summary.fixed.push_back({p.name, "has no effect on these measurements (zero Jacobian column)"});
      continue;
    }
    const Eigen::VectorXd v = Js.col(c) / norms[c];
    Eigen::VectorXd r = v;
    for (int pass = 0; pass < 2; ++pass) r -= Q * (Q.transpose() * r);
    const double rho = r.norm();
    if (rho < options.dependence_tol) {
      // which kept parameters does it depend on? (least squares of v on the kept columns, by
      // their normal equations: the kept columns are independent to dependence_tol)
      const Eigen::Index nk = static_cast<Eigen::Index>(kept.size());
      Eigen::MatrixXd Gk(nk, nk);
      Eigen::VectorXd gv(nk);
      for (Eigen::Index a = 0; a < nk; ++a) {
        gv[a] = Gram(kept[a], static_cast<Eigen::Index>(c));
        for (Eigen::Index b = 0; b < nk; ++b) Gk(a, b) = Gram(kept[a], kept[b]);
      }
      const Eigen::VectorXd coef = Gk.colPivHouseholderQr().solve(gv);
      std::vector<std::pair<double, std::string>> parts;
      for (Eigen::Index j = 0; j < coef.size(); ++j)
        parts.push_back({std::abs(coef[j]), layout[cand_idx[kept[j]]].name});
      std::sort(parts.begin(), parts.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
      std::string names;
      for (size_t j = 0; j < parts.size() && j < 3; ++j) {
        if (j > 0 && parts[j].first < 0.3 * parts[0].first) break;
        names += (names.empty() ? "" : ", ") + parts[j].second;
      }
      std::string reason;
      if (rho < 1e-8) {
        reason = "duplicates " + names + " (linearly dependent, relative residual " + fmtNum(rho) + ")";
      } else {
        reason = "not determined by these measurements: nearly dependent on " + names +
                 " (relative residual " + fmtNum(rho) + " < " + fmtNum(options.dependence_tol) + ")";
      }
      summary.fixed.push_back({p.name, reason});
      continue;
    }
    Qall.col(static_cast<Eigen::Index>(kept.size())) = r / rho;
    kept.push_back(static_cast<int>(c));
    free[cand_idx[c]] = true;
  }
  {
    Eigen::VectorXd sv;
    summary.condition_number_all = conditionOf(Gram, &sv);
    summary.condition_number = conditionOf(Gram(kept, kept), &sv);
    if (sv.size() > 0) {
      double logsum = 0;
      for (Eigen::Index j = 0; j < sv.size(); ++j) logsum += std::log(std::max(sv[j], 1e-300));
      summary.observability_index = std::exp(logsum / double(sv.size())) / std::sqrt(double(m));
    }
  }
  summary.parameters_free = static_cast<int>(kept.size());
  summary.equations = static_cast<int>(m);
  return static_cast<int>(kept.size());
}

// The joint maps' regularisation rows (x indices, weighted): smoothness (second differences,
// sqrt(smoothing) * scale) and centring (no mean, no linear trend over the fit data;
// kJointMapCentringWeight * scale), scale = the RMS norm of the map's weighted columns.
void penaltyRows(Problem& pb, double smoothing, const Eigen::VectorXd& col_sq) {
  const size_t P = pb.P;
  const std::vector<ParamInfo>& layout = pb.layout;
  const RobotModel& model = pb.model;
  std::vector<PenaltyRow>& penalties = pb.penalties;
  auto isMap = [&](size_t k) { return pb.isMap(k); };
  for (int j = 0; j < model.dof() && pb.sparse; ++j) {
    std::vector<int> cols;
    for (size_t k = 0; k < P; ++k)
      if (isMap(k) && layout[k].joint == j) cols.push_back(static_cast<int>(k));
    if (cols.empty()) continue;
    const JointMap& jm = model.deviations.joint_map[static_cast<size_t>(j)];
    double s2 = 0;
    for (int c : cols) s2 += col_sq[c];
    const double scale = std::sqrt(std::max(s2 / double(cols.size()), 1e-300));
    auto add = [&](const std::vector<double>& a, double weight) {
      PenaltyRow row;
      for (size_t k = 0; k < a.size(); ++k)
        if (a[k] != 0) row.terms.push_back({cols[k], weight * a[k]});
      if (!row.terms.empty()) penalties.push_back(row);
    };
    if (smoothing > 0)
      for (const auto& a : jointMapSmoothnessRows(jm)) add(a, std::sqrt(smoothing) * scale);
    const std::vector<double> qj = jointValues(pb.data, j);
    const bool revolute = model.nominal.joints[static_cast<size_t>(j)].type == JointType::kRevolute;
    for (const auto& a : jointMapCentringRows(jm, qj, revolute ? kJointMapCentredHarmonics : 0)) {
      double nrm = 0;
      for (double v : a) nrm += v * v;
      if (nrm > 0) add(a, kJointMapCentringWeight * scale / std::sqrt(nrm));
    }
    for (const auto& a : jointMapSparseRows(jm, qj)) add(a, kJointMapSparseWeight * scale);
  }
}

Weighting::Weighting(const Problem& pb, const IdentifyOptions& options) {
  file_pos = pb.data.has_std_position;
  file_rot = pb.data.has_std_orientation;
  pos_std_mm = options.position_std_mm;
  rot_std_deg = options.orientation_std_deg;
  estimate_pos = !file_pos && std::isnan(pos_std_mm);
  estimate_rot = pb.orientation && !file_rot && std::isnan(rot_std_deg);
  if (std::isnan(pos_std_mm)) pos_std_mm = 0.05;    // starting value, re-estimated
  if (std::isnan(rot_std_deg)) rot_std_deg = 0.005;  // starting value, re-estimated
}

double Weighting::baseStd(const Measurement& r, int k) const {
  return k < 3 ? (file_pos ? r.std_mm[k] : pos_std_mm) : (file_rot ? r.std_rot_deg[k - 3] : rot_std_deg) * kDegToRad;
}

void Weighting::apply(Problem& pb) const {
  pb.weights.resize(pb.data.rows.size());
  for (size_t i = 0; i < pb.data.rows.size(); ++i) {
    const Measurement& r = pb.data.rows[i];
    RowWeights& w = pb.weights[i];
    w.dim = pb.dim;
    for (int k = 0; k < 6; ++k) w.w[k] = rowComponentWeight(r.weight, baseStd(r, k), k < 3 ? tau_pos_mm : tau_rot_rad);
  }
}

namespace {

// Errors of every row (in station 0's world) at the model: position (mm), rotation (rad).
std::vector<Vector6d> rowErrors(const Problem& pb) {
  const KinematicModel km(pb.model);
  KinematicFrames f;
  LinkFrames links;  // the chain through the base frame, as forwardKinematics evaluates it
  std::vector<Vector6d> out;
  out.reserve(pb.data0.rows.size());
  for (const Measurement& r : pb.data0.rows) {
    km.evaluate(r.q.data(), r.context, f, nullptr, &links);
    out.push_back(rowError(f.T_world_tcp, r, pb.orientation ? 6 : 3));
  }
  return out;
}

// Residual RMS per component type (variance-component estimation): position mm, rotation deg.
void componentStd(const Problem& pb, const std::vector<Vector6d>& errors, bool robust_estimate, int p_free,
                  double* s_pos, double* s_rot_deg) {
  std::vector<double> pos, rot;
  for (size_t i = 0; i < errors.size(); ++i) {
    const double sw = std::sqrt(pb.data0.rows[i].weight);
    pos.push_back(errors[i].head<3>().norm() * sw);
    if (pb.orientation) rot.push_back(errors[i].tail<3>().norm() * sw);
  }
  const double redundancy = std::max(1.0, double(pb.m_eq - p_free)) / double(pb.m_eq);
  auto estimate = [&](std::vector<double>& v) {
    if (robust_estimate) {  // median of a chi(3) variable is 1.5382 sigma
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      return v[v.size() / 2] / 1.5382;
    }
    double s2 = 0;
    for (double e : v) s2 += e * e;
    return std::sqrt(s2 / (3.0 * double(v.size()) * redundancy));
  };
  *s_pos = estimate(pos);
  if (pb.orientation) *s_rot_deg = estimate(rot) * kRadToDeg;
}

// tau for one component type (k0 = 0 position, 3 orientation): tau^2 the root of
// sum e^2 / (s^2 + tau^2) = share, by bisection (the left side falls with tau^2).
double modelErrorTerm(const Problem& pb, const Weighting& wt, const std::vector<Vector6d>& errors,
                      const IdentifyOptions& options, int k0, int p_free) {
  const bool robust = options.loss != "none";
  std::vector<double> e2, s2;
  const double a = options.loss_scale * std::sqrt(double(pb.dim));
  for (size_t i = 0; i < pb.data0.rows.size(); ++i) {
    const Measurement& r = pb.data0.rows[i];
    const Vector6d& e = errors[i];  // e.tail = 0 without orientation
    // with a robust loss, rows it down-weights do not inflate the model-error term
    if (robust && pb.weights[i].w.cwiseProduct(e).norm() > a) continue;
    for (int k = k0; k < k0 + 3; ++k) {
      e2.push_back(e[k] * e[k] * r.weight);
      const double s = wt.baseStd(r, k);
      s2.push_back(s * s);
    }
  }
  const double share = double(e2.size()) * std::max(1.0, double(pb.m_eq - p_free)) / double(pb.m_eq);
  auto f = [&](double t2) {
    double sum = 0;
    for (size_t i = 0; i < e2.size(); ++i) sum += e2[i] / (s2[i] + t2);
    return sum - share;
  };
  if (f(0) <= 0) return 0.0;
  double lo = 0, hi = 1e-30;
  for (double v : e2) hi = std::max(hi, v);
  hi *= 4;  // f(hi) < 0: every term below 1/4
  for (int it = 0; it < 200 && hi - lo > 1e-12 * hi; ++it) {
    const double mid = 0.5 * (lo + hi);
    (f(mid) > 0 ? lo : hi) = mid;
  }
  return std::sqrt(0.5 * (lo + hi));
}

}  // namespace

double Weighting::reestimate(const Problem& pb, const IdentifyOptions& options, int p_free) {
  const bool robust = options.loss != "none";
  const std::vector<Vector6d> errors = rowErrors(pb);
  double change = 0;
  if (estimate_pos || estimate_rot) {
    double sp = pos_std_mm, sr = rot_std_deg;
    componentStd(pb, errors, robust, p_free, &sp, &sr);
    if (estimate_pos) {
      change += std::abs(std::log(sp / pos_std_mm));
      pos_std_mm = std::max(sp, 1e-6);
    }
    if (estimate_rot) {
      change += std::abs(std::log(sr / rot_std_deg));
      rot_std_deg = std::max(sr, 1e-9);
    }
  }
  if (options.model_error) {
    if (!estimate_pos) {  // stds from the file or given
      const double t = modelErrorTerm(pb, *this, errors, options, 0, p_free);
      change += std::abs(t - tau_pos_mm) / std::max(t, 1e-9);
      tau_pos_mm = t;
    }
    if (pb.orientation && !estimate_rot) {
      const double t = modelErrorTerm(pb, *this, errors, options, 3, p_free);
      change += std::abs(t - tau_rot_rad) / std::max(t, 1e-12);
      tau_rot_rad = t;
    }
  }
  return change;
}

void Weighting::describe(const Problem& pb, IdentifySummary& summary) const {
  if (file_pos) summary.weighting = "position: per-row std columns of the data";
  else if (estimate_pos) summary.weighting = "position: std estimated from the residuals";
  else summary.weighting = "position: std given";
  if (pb.orientation) {
    if (file_rot) summary.weighting += "; orientation: per-row std columns of the data";
    else if (estimate_rot) summary.weighting += "; orientation: std estimated from the residuals";
    else summary.weighting += "; orientation: std given";
  }
  if (pb.data.has_weight) summary.weighting += "; times the per-row weight column";
  summary.model_error_mm = tau_pos_mm;
  summary.model_error_deg = tau_rot_rad * kRadToDeg;
  if (tau_pos_mm > 0 || tau_rot_rad > 0) {
    char buf[200];
    std::snprintf(buf, sizeof buf, "; plus an unmodelled-error term estimated from the residuals: %.4g mm, %.4g deg",
                  tau_pos_mm, tau_rot_rad * kRadToDeg);
    summary.weighting += buf;
  }
  summary.position_std_mm = file_pos ? std::numeric_limits<double>::quiet_NaN() : pos_std_mm;
  summary.orientation_std_deg =
      (pb.orientation && !file_rot) ? rot_std_deg : std::numeric_limits<double>::quiet_NaN();
}

// Cov = s0^2 (J^T J)^-1 over the free parameters (the joint maps' penalty rows included: they
// make the maps' coefficients determined).
void uncertainties(Problem& pb, const IdentifyOptions& options, bool robust, IdentifySummary& summary,
                   Eigen::VectorXd* r_out) {
  const size_t X = pb.X, P = pb.P;
  const std::vector<PenaltyRow>& penalties = pb.penalties;
  const std::vector<ParamInfo>& layout = pb.layout;
  const int dim = pb.dim;
  Eigen::VectorXd& r = *r_out;
  const FreeColumns fc(pb);
  const std::vector<int>& free_idx = fc.x_of;
  Eigen::VectorXd sigma = Eigen::VectorXd::Zero(fc.n);
  if (pb.sparse) {
    // joint maps: from the normal equations accumulated pose by pose, and only the sigmas that
    // are reported (not the maps' coefficients): a Cholesky factorisation and a solve per
    // reported parameter instead of the inverse (N: its lower triangle, in the solves' workspace)
    Eigen::MatrixXd& N = pb.normal_N;
    rowNormalEquations(pb, pb.model, pb.x, fc, &N, nullptr, &r);
    addPenaltyNormal(pb, fc, nullptr, &N, nullptr);
    summary.final_cost = 0.5 * r.squaredNorm();
    const double dof_res = std::max(1.0, double(r.size()) - double(fc.n));
    summary.variance_factor = r.squaredNorm() / dof_res;
    std::vector<Eigen::Index> reported;
    for (Eigen::Index c = 0; c < fc.n; ++c) {
      const size_t k = static_cast<size_t>(free_idx[static_cast<size_t>(c)]);
      if (k < P && !pb.isMap(k)) reported.push_back(c);
    }
    if (fc.n > 0 && !reported.empty()) {
      const Eigen::VectorXd scale = N.diagonal().cwiseSqrt().cwiseMax(1e-300);
      const auto Nn = scale.cwiseInverse().asDiagonal() * N * scale.cwiseInverse().asDiagonal();
      Eigen::MatrixXd E = Eigen::MatrixXd::Zero(fc.n, static_cast<Eigen::Index>(reported.size()));
      for (size_t a = 0; a < reported.size(); ++a) E(reported[a], static_cast<Eigen::Index>(a)) = 1;
      Eigen::MatrixXd Ninv_cols;
      Eigen::MatrixXd& L = pb.normal_M;
      L = Nn;
      if (detail::choleskyInPlace(L)) {
        Ninv_cols = E;
        detail::choleskySolveInPlace(L, Ninv_cols);
      } else {  // semi-definite: as the dense path (LDLT reads the lower triangle)
        Eigen::LDLT<Eigen::MatrixXd> ldlt(Nn);
        if (ldlt.info() != Eigen::Success)
          throw NumericalError("identification: normal matrix is singular at the solution");
        Ninv_cols = ldlt.solve(E);
      }
      for (size_t a = 0; a < reported.size(); ++a) {
        const Eigen::Index c = reported[a];
        sigma[c] = std::sqrt(std::max(0.0, summary.variance_factor * Ninv_cols(c, static_cast<Eigen::Index>(a)))) / scale[c];
      }
    }
  } else {
    Eigen::MatrixXd J;
    pb.stack(&J, &r);
    summary.final_cost = 0.5 * r.squaredNorm();
    std::vector<int> col_of(X, -1);
    for (size_t c = 0; c < free_idx.size(); ++c) col_of[static_cast<size_t>(free_idx[c])] = static_cast<int>(c);
    Eigen::MatrixXd Jf = Eigen::MatrixXd::Zero(J.rows() + static_cast<Eigen::Index>(penalties.size()),
                                               static_cast<Eigen::Index>(free_idx.size()));
    for (size_t c = 0; c < free_idx.size(); ++c) Jf.col(c).head(J.rows()) = J.col(free_idx[c]);
    for (size_t k = 0; k < penalties.size(); ++k)
      for (const auto& t : penalties[k].terms)
        if (col_of[static_cast<size_t>(t.first)] >= 0)
          Jf(J.rows() + static_cast<Eigen::Index>(k), col_of[static_cast<size_t>(t.first)]) = t.second;
    const double dof_res = std::max(1.0, double(J.rows()) - double(free_idx.size()));
    summary.variance_factor = r.squaredNorm() / dof_res;
    if (!free_idx.empty()) {
      const Eigen::VectorXd scale = Jf.colwise().norm().cwiseMax(1e-300);
      const Eigen::MatrixXd Jn = Jf * scale.cwiseInverse().asDiagonal();
      const Eigen::MatrixXd N = detail::gram(Jn);
      Eigen::LDLT<Eigen::MatrixXd> ldlt(N);
      if (ldlt.info() != Eigen::Success)
        throw NumericalError("identification: normal matrix is singular at the solution");
      const Eigen::MatrixXd Ninv = ldlt.solve(Eigen::MatrixXd::Identity(N.rows(), N.cols()));
      for (Eigen::Index c = 0; c < sigma.size(); ++c)
        sigma[c] = std::sqrt(std::max(0.0, summary.variance_factor * Ninv(c, c))) / scale[c];
    }
  }
  for (size_t c = 0; c < free_idx.size(); ++c) {
    const size_t k = static_cast<size_t>(free_idx[c]);
    if (k >= P || pb.isMap(k)) continue;
    const ParamInfo& p = layout[k];
    summary.parameters.push_back({p.name, p.group, p.unit,
                                  getParameter(pb.model.deviations, p) * p.display_scale,
                                  sigma[static_cast<Eigen::Index>(c)] * p.display_scale});
  }
  if (robust) {
    const double a = options.loss_scale * std::sqrt(double(dim));
    for (size_t i = 0; i < pb.data.rows.size(); ++i) {
      if (r.segment(static_cast<Eigen::Index>(i) * dim, dim).norm() > a)
        summary.downweighted_lines.push_back(pb.data.rows[i].line);
    }
  }
}

// Stations per set, joint-map reports, suspicious rows and plausibility warnings.
void finishSummary(const Problem& pb, const std::vector<MeasurementSet>& sets, const Eigen::VectorXd& r,
                   double smoothing, IdentifySummary* s) {
  const RobotModel& model = pb.model;
  const std::vector<int>& set_of_row = pb.set_of_row;
  const Stations& st = pb.st;
  const std::vector<double>& x = pb.x;
  const MeasurementSet& data0 = pb.data0;
  const int dim = pb.dim;
  for (size_t k = 0; k < sets.size(); ++k) {
    int station = 0;
    for (size_t i = 0; i < set_of_row.size(); ++i)
      if (set_of_row[i] == static_cast<int>(k)) {
        station = st.of_row[i];
        break;
      }
    s->T_world_base_per_set.push_back(st.transform(x, station) * model.T_world_base());
  }
  for (int j = 0; j < model.dof(); ++j) {
    const JointMap& jm = model.deviations.joint_map[static_cast<size_t>(j)];
    if (jm.empty()) continue;
    const bool revolute = model.nominal.joints[static_cast<size_t>(j)].type == JointType::kRevolute;
    const double unit = revolute ? kRadToDeg : 1.0;
    JointMapReport rep;
    rep.joint = j + 1;
    rep.unit = revolute ? "deg" : "mm";
    rep.lower = jm.lower;
    rep.upper = jm.upper;
    rep.knot = jm.knot();
    rep.coefficients = static_cast<int>(jm.coef.size());
    rep.smoothing = smoothing;
    rep.amplitude = jointMapAmplitude(jm) * unit;
    double s2 = 0;
    for (const Measurement& m : data0.rows) s2 += std::pow(jointMapValue(jm, m.q[j]) * unit, 2);
    rep.rms = std::sqrt(s2 / double(std::max<size_t>(data0.rows.size(), 1)));
    s->joint_maps.push_back(rep);
    if (rep.amplitude > (revolute ? 1.0 : 1.0))
      s->warnings.push_back("joint_map j" + std::to_string(j + 1) + ": amplitude " + fmtNum(rep.amplitude) + " " +
                            rep.unit + " is above 1 " + rep.unit +
                            " (physically implausible for a gear or encoder error: the map absorbs something else)");
  }
  // suspicious rows: normalised residual above the chi quantile 0.9999 with dim degrees of freedom
  const size_t rows = data0.rows.size();
  std::vector<double> norms(rows);
  for (size_t i = 0; i < rows; ++i) norms[i] = r.segment(static_cast<Eigen::Index>(i) * dim, dim).norm();
  const KinematicModel km(model);
  KinematicFrames f;
  for (const auto& [i, normalised] : suspiciousResiduals(norms, dim)) {
    const Measurement& m = data0.rows[i];
    km.evaluate(m.q.data(), m.context, f);
    const double e = (f.T_world_tcp.translation() - m.p_world_mm).norm();
    s->suspicious.push_back({sets[static_cast<size_t>(set_of_row[i])].file, m.line, normalised, e});
  }
  // plausibility of the estimates
  for (const ParameterEstimate& p : s->parameters) {
    const std::string v = p.name + " = " + fmtNum(p.value) + " +- " + fmtNum(p.sigma) + " " + p.unit;
    if (p.group == "joint_compliance" && p.value < 0 && p.value < -2 * p.sigma)
      s->warnings.push_back(v + ": a negative joint compliance is physically impossible (the joint would deflect "
                                "against its load): it absorbs an unmodelled error");
    if (p.group == "joint_compliance" && std::abs(p.value) > 1e4)
      s->warnings.push_back(v + ": a joint compliance above 10000 urad/Nm (0.6 deg under 1 Nm) is physically implausible: "
                                "the data does not determine it (too little torque on this joint: poses with payloads)");
    if (p.group == "thermal" && ((p.value < 0 && p.value < -2 * p.sigma) || p.value > 50))
      s->warnings.push_back(v + ": a thermal expansion coefficient outside 0..50 ppm/K (steel 11.5, aluminium 23) "
                                "is physically implausible");
  }
  const int H = model.deviations.gear_harmonics;
  for (int j = 0; j < model.dof(); ++j)
    for (int h = 0; h < H; ++h) {
      const size_t k = static_cast<size_t>(j * H + h);
      const double amp = std::hypot(model.deviations.gear_sin[k], model.deviations.gear_cos[k]) * kRadToDeg;
      if (amp > 1.0)
        s->warnings.push_back("gear_periodic j" + std::to_string(j + 1) + " harmonic " + std::to_string(h + 1) +
                              ": amplitude " + fmtNum(amp) + " deg is above 1 deg (physically implausible)");
    }
}

}  // namespace accura::calib::identify_detail

namespace accura::calib {

std::vector<std::pair<size_t, double>> suspiciousResiduals(const std::vector<double>& norms, int dim) {
  std::vector<std::pair<size_t, double>> out;
  const size_t rows = norms.size();
  if (rows == 0) return out;
  std::vector<double> sorted = norms;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(rows / 2), sorted.end());
  const double chi_median = dim == 6 ? 2.3660 : 1.5382, chi_limit = dim == 6 ? 5.278 : 4.594;
  const double scale = sorted[rows / 2] / chi_median;
  for (size_t i = 0; i < rows && scale > 0; ++i)
    if (norms[i] / scale > chi_limit) out.push_back({i, norms[i] / scale});
  return out;
}

std::vector<SuspiciousRow> suspiciousRows(const RobotModel& model, const MeasurementSet& data) {
  std::vector<double> norms, errors;
  const KinematicModel km(model);
  KinematicFrames f;
  for (const Measurement& m : data.rows) {
    km.evaluate(m.q.data(), m.context, f);
    const Eigen::Vector3d e = f.T_world_tcp.translation() - m.p_world_mm;
    errors.push_back(e.norm());
    // unweighted: on validation data the model's error dominates, not the instrument's (the fit
    // adds an unmodelled-error term to the stds for the same reason; weighted by the std columns
    // alone, Series_C would flag 164 of its 2773 rows at 0.4-1 mm)
    norms.push_back(e.norm());
  }
  std::vector<SuspiciousRow> out;
  for (const auto& [i, normalised] : suspiciousResiduals(norms, 3))
    out.push_back({data.file, data.rows[i].line, normalised, errors[i]});
  return out;
}

}  // namespace accura::calib
