#include "accura/calib/identify.h"

#include <ceres/ceres.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <set>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/kinematic_core.h"
#include "accura/calib/kinematics.h"

namespace accura {

namespace {
// A --params item: a group name, optionally restricted to some joints: "gear_periodic:j1+j2".
// Returns false with *error on a malformed item. `joints` is empty when all joints are meant.
bool parseGroupSpec(const std::string& spec, std::string* name, std::set<int>* joints, std::string* error) {
  const size_t colon = spec.find(':');
  *name = spec.substr(0, colon);
  joints->clear();
  if (colon == std::string::npos) return true;
  std::string rest = spec.substr(colon + 1);
  size_t pos = 0;
  while (pos <= rest.size()) {
    const size_t plus = rest.find('+', pos);
    const std::string item = rest.substr(pos, plus == std::string::npos ? std::string::npos : plus - pos);
    int j = 0;
    if (item.size() < 2 || item[0] != 'j' || item.find_first_not_of("0123456789", 1) != std::string::npos ||
        (j = std::atoi(item.c_str() + 1)) < 1) {
      *error = "parameter group '" + spec + "': expected joints as j1+j2+..., found '" + item + "'";
      return false;
    }
    joints->insert(j);
    if (plus == std::string::npos) break;
    pos = plus + 1;
  }
  return true;
}
}  // namespace

bool IdentifyOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (groups.empty()) return fail("no parameter group given");
  std::set<std::string> known;
  for (const auto& g : parameterGroups()) known.insert(g.first);
  for (const auto& g : groups) {
    std::string name, why;
    std::set<int> joints;
    if (!parseGroupSpec(g, &name, &joints, &why)) return fail(why);
    if (!known.count(name)) {
      std::string list;
      for (const auto& k : parameterGroups()) list += (list.empty() ? "" : ", ") + k.first;
      return fail("unknown parameter group '" + name + "' (expected one of: " + list + ")");
    }
  }
  if (!(std::isnan(position_std_mm) || position_std_mm > 0))
    return fail("position_std_mm must be > 0, got " + std::to_string(position_std_mm));
  if (!(std::isnan(orientation_std_deg) || orientation_std_deg > 0))
    return fail("orientation_std_deg must be > 0, got " + std::to_string(orientation_std_deg));
  if (loss != "none" && loss != "huber" && loss != "cauchy")
    return fail("loss must be none, huber or cauchy, got '" + loss + "'");
  if (!(loss_scale > 0)) return fail("loss_scale must be > 0");
  if (!(dependence_tol > 0 && dependence_tol < 1)) return fail("dependence_tol must be in (0, 1)");
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  return true;
}

std::string IdentifySummary::BriefReport() const {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "%s, %d iterations, cost %.6g -> %.6g, fit RMS %.4f mm (n=%d), %d parameters, "
                "condition number %.3g",
                termination.c_str(), iterations, initial_cost, final_cost, fit.rms_mm, fit.n,
                parameters_free, condition_number);
  return buf;
}

double registerFrame(RobotModel& model, const MeasurementSet& data, bool estimate_tool) {
  const size_t m = data.rows.size();
  if (m < 3) throw NumericalError("registration needs at least 3 measured points, got " + std::to_string(m));
  KinematicWorkspace ws;
  std::vector<Eigen::Isometry3d> F(m);  // T_base_flange
  for (size_t i = 0; i < m; ++i) F[i] = flangePose(model, data.rows[i].q, data.rows[i].context, ws);
  Eigen::Vector3d tool = model.T_flange_tcp().translation();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  const int rounds = estimate_tool ? 20 : 1;
  for (int round = 0; round < rounds; ++round) {
    // Kabsch: x_i = R p_i + t
    std::vector<Eigen::Vector3d> p(m);
    Eigen::Vector3d pc = Eigen::Vector3d::Zero(), xc = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < m; ++i) {
      p[i] = F[i] * tool;
      pc += p[i];
      xc += data.rows[i].p_world_mm;
    }
    pc /= double(m);
    xc /= double(m);
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    for (size_t i = 0; i < m; ++i) H += (p[i] - pc) * (data.rows[i].p_world_mm - xc).transpose();
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Eigen::Vector3d sv = svd.singularValues();
    if (sv[1] <= 1e-9 * std::max(1.0, sv[0]))
      throw NumericalError("registration: the measured points are collinear (singular values " +
                           std::to_string(sv[0]) + ", " + std::to_string(sv[1]) +
                           " mm^2); measure poses spread over the workspace");
    Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
    if ((svd.matrixV() * svd.matrixU().transpose()).determinant() < 0) D(2, 2) = -1;
    R = svd.matrixV() * D * svd.matrixU().transpose();
    t = xc - R * pc;
    if (!estimate_tool) break;
    // tool point: minimise sum |R (R_fi tool + p_fi) + t - x_i|^2 (linear in tool)
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < m; ++i) {
      const Eigen::Matrix3d Ai = R * F[i].linear();
      A += Ai.transpose() * Ai;
      b += Ai.transpose() * (data.rows[i].p_world_mm - t - R * F[i].translation());
    }
    const Eigen::Vector3d new_tool = A.ldlt().solve(b);
    const double change = (new_tool - tool).norm();
    tool = new_tool;
    if (change < 1e-9) break;
  }
  // T_world_base = T_nom * Trans(base_mm) * Exp(base_rot)
  Eigen::Isometry3d T_wb = Eigen::Isometry3d::Identity();
  T_wb.linear() = R;
  T_wb.translation() = t;
  const Eigen::Isometry3d D = model.nominal.T_world_base.inverse() * T_wb;
  model.deviations.base_mm = D.translation();
  model.deviations.base_rot_rad = logSO3(D.linear());
  if (estimate_tool) {
    // T_flange_tcp = T_nom * Trans(tool_mm) * Exp(tool_rot): translation part only
    const Eigen::Isometry3d& Tn = model.nominal.T_flange_tcp;
    model.deviations.tool_mm = Tn.linear().transpose() * (tool - Tn.translation());
  }
  // With orientation data and a tool to estimate: the tool rotation as the chordal mean.
  bool all_orient = estimate_tool;
  for (const auto& row : data.rows) all_orient = all_orient && row.has_orientation;
  if (all_orient) {
    const Eigen::Isometry3d T_flange_toolnom_trans = [&] {
      Eigen::Isometry3d T = model.nominal.T_flange_tcp;
      T.translate(model.deviations.tool_mm);
      return T;
    }();
    Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
    for (size_t i = 0; i < m; ++i) {
      const Eigen::Matrix3d R_pred = (T_wb * F[i] * T_flange_toolnom_trans).linear();
      S += R_pred.transpose() * data.rows[i].R_world_tcp.toRotationMatrix();
    }
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(S, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d D3 = Eigen::Matrix3d::Identity();
    if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) D3(2, 2) = -1;
    model.deviations.tool_rot_rad = logSO3(svd.matrixU() * D3 * svd.matrixV().transpose());
  }
  double s2 = 0;
  for (double e : positionErrors(model, data)) s2 += e * e;
  return std::sqrt(s2 / double(m));
}

namespace {

// Residual weights of one row: sqrt(weight) / sigma per component (position mm, rotation rad).
struct RowWeights {
  int dim = 3;
  Vector6d w = Vector6d::Ones();
};

// Evaluates all rows once per evaluation point (Ceres' EvaluationCallback) and hands each
// row's residual and Jacobian to its RowCost.
class Evaluator : public ceres::EvaluationCallback {
 public:
  Evaluator(RobotModel model, const std::vector<ParamInfo>& layout, const MeasurementSet& data,
            const std::vector<RowWeights>& weights, std::vector<double>* x)
      : model_(std::move(model)), layout_(layout), data_(data), weights_(weights), x_(x) {
    const size_t m = data.rows.size();
    residuals_.resize(m);
    jacobians_.resize(m);
  }

  void PrepareForEvaluation(bool evaluate_jacobians, bool new_evaluation_point) override {
    if (!new_evaluation_point && (have_jacobians_ || !evaluate_jacobians)) return;
    update();
    // the model prepared once per evaluation point (kinematic_core.h), then every row
    const KinematicModel core(model_);
    for (size_t i = 0; i < data_.rows.size(); ++i) {
      const Measurement& row = data_.rows[i];
      if (row.q.size() != core.dof())
        throw ArgumentError("expected " + std::to_string(core.dof()) + " joint values, got " +
                            std::to_string(row.q.size()));
      Eigen::Isometry3d T;
      if (evaluate_jacobians) {
        T = core.parameterJacobian(layout_, row.q.data(), row.context, frames_, links_, J_);
        const int dim = weights_[i].dim;
        jacobians_[i] = weights_[i].w.head(dim).asDiagonal() * J_.topRows(dim);
      } else {
        core.evaluate(row.q.data(), row.context, frames_);
        T = frames_.T_world_tcp;
      }
      residuals_[i] = rowResidual(i, T);
    }
    have_jacobians_ = evaluate_jacobians;
  }

  Vector6d rowResidual(size_t i, const Eigen::Isometry3d& T) const {
    const Measurement& row = data_.rows[i];
    Vector6d r = Vector6d::Zero();
    r.head<3>() = T.translation() - row.p_world_mm;
    if (weights_[i].dim == 6)
      r.tail<3>() = logSO3(T.linear() * row.R_world_tcp.toRotationMatrix().transpose());
    return weights_[i].w.cwiseProduct(r);
  }

  void update() {
    for (size_t k = 0; k < layout_.size(); ++k) setParameter(model_.deviations, layout_[k], (*x_)[k]);
  }

  const Vector6d& residual(size_t i) const { return residuals_[i]; }
  const Eigen::MatrixXd& jacobian(size_t i) const { return jacobians_[i]; }
  const RobotModel& model() const { return model_; }

 private:
  RobotModel model_;
  const std::vector<ParamInfo>& layout_;
  const MeasurementSet& data_;
  const std::vector<RowWeights>& weights_;
  std::vector<double>* x_;
  KinematicFrames frames_;
  LinkFrames links_;
  Eigen::MatrixXd J_;
  std::vector<Vector6d> residuals_;
  std::vector<Eigen::MatrixXd> jacobians_;
  bool have_jacobians_ = false;
};

struct Block {
  int start, size;
};

class RowCost : public ceres::CostFunction {
 public:
  RowCost(const Evaluator* ev, size_t row, int dim, const std::vector<Block>& blocks)
      : ev_(ev), row_(row), blocks_(blocks) {
    set_num_residuals(dim);
    for (const Block& b : blocks) mutable_parameter_block_sizes()->push_back(b.size);
  }
  bool Evaluate(double const* const* /*parameters*/, double* residuals,
                double** jacobians) const override {
    const int dim = num_residuals();
    const Vector6d& r = ev_->residual(row_);
    for (int k = 0; k < dim; ++k) residuals[k] = r[k];
    if (!jacobians) return true;
    const Eigen::MatrixXd& J = ev_->jacobian(row_);
    for (size_t b = 0; b < blocks_.size(); ++b) {
      if (!jacobians[b]) continue;
      const Block& B = blocks_[b];
      for (int k = 0; k < dim; ++k)
        for (int c = 0; c < B.size; ++c) jacobians[b][k * B.size + c] = J(k, B.start + c);
    }
    return true;
  }

 private:
  const Evaluator* ev_;
  size_t row_;
  std::vector<Block> blocks_;
};

// Weighted, stacked Jacobian of the given columns and the weighted residual at `model`.
void stackedJacobian(const RobotModel& model, const std::vector<ParamInfo>& layout,
                     const MeasurementSet& data, const std::vector<RowWeights>& weights,
                     Eigen::MatrixXd* J, Eigen::VectorXd* r) {
  int m = 0;
  for (const auto& w : weights) m += w.dim;
  J->resize(m, static_cast<Eigen::Index>(layout.size()));
  if (r) r->resize(m);
  KinematicWorkspace ws;
  Eigen::MatrixXd Ji;
  int row = 0;
  for (size_t i = 0; i < data.rows.size(); ++i) {
    const Measurement& meas = data.rows[i];
    const Eigen::Isometry3d T = parameterJacobian(model, layout, meas.q, meas.context, ws, Ji);
    const int dim = weights[i].dim;
    J->middleRows(row, dim) = weights[i].w.head(dim).asDiagonal() * Ji.topRows(dim);
    if (r) {
      Vector6d e = Vector6d::Zero();
      e.head<3>() = T.translation() - meas.p_world_mm;
      if (dim == 6) e.tail<3>() = logSO3(T.linear() * meas.R_world_tcp.toRotationMatrix().transpose());
      r->segment(row, dim) = weights[i].w.head(dim).cwiseProduct(e).head(dim);
    }
    row += dim;
  }
}

std::string fmtNum(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

double conditionOf(const Eigen::MatrixXd& Js, Eigen::VectorXd* sv) {
  if (Js.cols() == 0) return 1.0;
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Js.transpose() * Js);
  Eigen::VectorXd lambda = es.eigenvalues().cwiseMax(0.0);
  *sv = lambda.cwiseSqrt();
  const double smax = sv->maxCoeff(), smin = sv->minCoeff();
  if (!(smin > 1e-15 * smax)) return std::numeric_limits<double>::infinity();
  return smax / smin;
}

}  // namespace

RobotModel identify(const RobotModel& start, const MeasurementSet& data,
                    const IdentifyOptions& options, IdentifySummary* summary_out) {
  std::string why;
  if (!options.IsValid(&why)) throw ArgumentError("identify: " + why);
  start.validate();
  IdentifySummary summary;
  RobotModel model = start;
  const bool orientation = !data.rows.empty() && std::all_of(data.rows.begin(), data.rows.end(),
                                                             [](const Measurement& r) { return r.has_orientation; });
  std::map<std::string, std::set<int>> groups;  // group -> joints (1-based; empty: all)
  for (const auto& g : options.groups) {
    std::string name, spec_error;
    std::set<int> joints;
    parseGroupSpec(g, &name, &joints, &spec_error);  // validated by IsValid
    if (name == "geometric") {
      for (const char* s : {"base", "tool", "offsets", "lengths", "angles"}) groups[s] = joints;
    } else {
      groups[name] = joints;
    }
  }
  // The candidate parameters: those of the requested groups (tool rotation only with
  // orientation data). Every other deviation stays as it is in `start` and is not part of
  // the problem (nor of the Jacobian).
  std::vector<ParamInfo> layout;
  for (const ParamInfo& p : parameterLayout(model)) {
    auto g = groups.find(p.group);
    if (g == groups.end()) continue;
    if (!g->second.empty() && !g->second.count(p.joint + 1)) continue;
    if (!orientation && (p.kind == ParamKind::kToolRx || p.kind == ParamKind::kToolRy ||
                         p.kind == ParamKind::kToolRz))
      continue;
    layout.push_back(p);
  }
  const size_t P = layout.size();
  const int n_candidates = static_cast<int>(P);
  const int dim = orientation ? 6 : 3;
  const int m_eq = dim * static_cast<int>(data.rows.size());
  if (m_eq < n_candidates + 1) {
    throw InputError(data.file, 0, 0,
                     "too few rows for the parameters asked for: " + std::to_string(data.rows.size()) +
                         " rows give " + std::to_string(m_eq) + " equations, expected more than " +
                         std::to_string(n_candidates) + " (the number of parameters in " +
                         "the groups asked for); measure at least " +
                         std::to_string(n_candidates / dim + 1 + 1) + " poses, better 10 times as many");
  }

  // 1. Closed-form registration of the measurement frame (and the tool point).
  if (options.register_frame && groups.count("base")) {
    summary.registration_rms_mm = registerFrame(model, data, groups.count("tool") > 0);
  } else {
    double s2 = 0;
    for (double e : positionErrors(model, data)) s2 += e * e;
    summary.registration_rms_mm = std::sqrt(s2 / double(data.rows.size()));
  }

  // 2. Weights.
  const bool file_pos_std = data.has_std_position;
  const bool file_rot_std = data.has_std_orientation;
  double pos_std = options.position_std_mm, rot_std_deg = options.orientation_std_deg;
  const bool estimate_pos = !file_pos_std && std::isnan(pos_std);
  const bool estimate_rot = orientation && !file_rot_std && std::isnan(rot_std_deg);
  if (std::isnan(pos_std)) pos_std = 0.05;          // starting value, re-estimated below
  if (std::isnan(rot_std_deg)) rot_std_deg = 0.005;  // starting value, re-estimated below
  // Unmodelled error: when the stds of the data (or given ones) explain the residuals badly
  // (variance factor of a component type > kModelErrorFactor), an additive isotropic term
  // tau is estimated for that type so that sum e^2 / (s^2 + tau^2) equals its share of the
  // redundancy (variance-component estimation); weights become 1 / sqrt(s^2 + tau^2).
  double tau_pos_mm = 0, tau_rot_rad = 0;
  std::vector<RowWeights> weights(data.rows.size());
  auto baseStd = [&](const Measurement& r, int k) {  // mm or rad, before the weight column
    return k < 3 ? (file_pos_std ? r.std_mm[k] : pos_std)
                 : (file_rot_std ? r.std_rot_deg[k - 3] : rot_std_deg) * kDegToRad;
  };
  auto makeWeights = [&]() {
    for (size_t i = 0; i < data.rows.size(); ++i) {
      const Measurement& r = data.rows[i];
      RowWeights& w = weights[i];
      w.dim = dim;
      const double sw = std::sqrt(r.weight);
      for (int k = 0; k < 6; ++k) {
        const double s = baseStd(r, k), tau = k < 3 ? tau_pos_mm : tau_rot_rad;
        w.w[k] = sw / std::sqrt(s * s + tau * tau);
      }
    }
  };
  makeWeights();

  // 3. Identifiability on the scaled weighted Jacobian at the starting point.
  std::vector<int> cand_idx;
  for (size_t k = 0; k < P; ++k) cand_idx.push_back(static_cast<int>(k));
  Eigen::MatrixXd Jfull;
  stackedJacobian(model, layout, data, weights, &Jfull, nullptr);
  const Eigen::Index m = Jfull.rows();
  Eigen::MatrixXd Js(m, static_cast<Eigen::Index>(cand_idx.size()));
  for (size_t c = 0; c < cand_idx.size(); ++c) Js.col(c) = Jfull.col(cand_idx[c]);
  Eigen::VectorXd norms = Js.colwise().norm();
  std::vector<bool> free(P, false);
  std::vector<int> kept;  // indices into cand_idx
  Eigen::MatrixXd Q(m, 0);
  for (size_t c = 0; c < cand_idx.size(); ++c) {
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
      // which kept parameters does it depend on?
      Eigen::MatrixXd K(m, static_cast<Eigen::Index>(kept.size()));
      for (size_t j = 0; j < kept.size(); ++j) K.col(j) = Js.col(kept[j]) / norms[kept[j]];
      const Eigen::VectorXd coef = K.colPivHouseholderQr().solve(v);
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
    Q.conservativeResize(m, Q.cols() + 1);
    Q.col(Q.cols() - 1) = r / rho;
    kept.push_back(static_cast<int>(c));
    free[cand_idx[c]] = true;
  }
  {
    Eigen::MatrixXd Jn(m, static_cast<Eigen::Index>(cand_idx.size()));
    for (size_t c = 0; c < cand_idx.size(); ++c)
      Jn.col(c) = norms[c] > 0 ? Eigen::VectorXd(Js.col(c) / norms[c]) : Eigen::VectorXd(Js.col(c));
    Eigen::VectorXd sv;
    summary.condition_number_all = conditionOf(Jn, &sv);
    Eigen::MatrixXd Jk(m, static_cast<Eigen::Index>(kept.size()));
    for (size_t j = 0; j < kept.size(); ++j) Jk.col(j) = Js.col(kept[j]) / norms[kept[j]];
    summary.condition_number = conditionOf(Jk, &sv);
    if (sv.size() > 0) {
      double logsum = 0;
      for (Eigen::Index j = 0; j < sv.size(); ++j) logsum += std::log(std::max(sv[j], 1e-300));
      summary.observability_index = std::exp(logsum / double(sv.size())) / std::sqrt(double(m));
    }
  }
  const int p_free = static_cast<int>(kept.size());
  summary.parameters_free = p_free;
  summary.equations = static_cast<int>(m);

  // 4. Ceres problem: one parameter block per base, tool, joint, compliance.
  std::vector<double> x(P);
  for (size_t k = 0; k < P; ++k) x[k] = getParameter(model.deviations, layout[k]);
  std::vector<Block> blocks;
  auto blockKey = [&](const ParamInfo& p) -> std::string {
    if (p.group == "base" || p.group == "tool" || p.group == "joint_compliance") return p.group;
    return "j" + std::to_string(p.joint);
  };
  for (size_t k = 0; k < P;) {
    size_t e = k + 1;
    while (e < P && blockKey(layout[e]) == blockKey(layout[k])) ++e;
    blocks.push_back({static_cast<int>(k), static_cast<int>(e - k)});
    k = e;
  }

  auto solve = [&](bool robust, ceres::Solver::Summary* ceres_summary) {
    Evaluator evaluator(model, layout, data, weights, &x);
    ceres::Problem::Options popts;
    popts.cost_function_ownership = ceres::TAKE_OWNERSHIP;
    popts.loss_function_ownership = ceres::TAKE_OWNERSHIP;
    popts.manifold_ownership = ceres::TAKE_OWNERSHIP;
    popts.evaluation_callback = &evaluator;
    ceres::Problem problem(popts);
    std::vector<double*> ptrs;
    for (const Block& b : blocks) ptrs.push_back(&x[b.start]);
    for (size_t i = 0; i < data.rows.size(); ++i) {
      ceres::LossFunction* loss = nullptr;
      if (robust) {
        const double a = options.loss_scale * std::sqrt(double(dim));
        if (options.loss == "huber") loss = new ceres::HuberLoss(a);
        if (options.loss == "cauchy") loss = new ceres::CauchyLoss(a);
      }
      problem.AddResidualBlock(new RowCost(&evaluator, i, dim, blocks), loss, ptrs);
    }
    for (const Block& b : blocks) {
      std::vector<int> fixed_idx;
      for (int c = 0; c < b.size; ++c)
        if (!free[b.start + c]) fixed_idx.push_back(c);
      if (static_cast<int>(fixed_idx.size()) == b.size) {
        problem.SetParameterBlockConstant(&x[b.start]);
      } else if (!fixed_idx.empty()) {
        problem.SetManifold(&x[b.start], new ceres::SubsetManifold(b.size, fixed_idx));
      }
    }
    ceres::Solver::Options so;
    so.minimizer_type = ceres::TRUST_REGION;
    so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = options.max_iterations;
    so.function_tolerance = options.function_tolerance;
    so.parameter_tolerance = options.parameter_tolerance;
    so.gradient_tolerance = 1e-16;
    so.num_threads = 1;
    so.logging_type = ceres::SILENT;
    so.minimizer_progress_to_stdout = false;
    ceres::Solve(so, &problem, ceres_summary);
    for (size_t k = 0; k < P; ++k) setParameter(model.deviations, layout[k], x[k]);
  };

  // Residual RMS per component type, for variance-component estimation.
  auto componentStd = [&](bool robust_estimate, double* s_pos, double* s_rot_deg) {
    std::vector<double> pos, rot;
    KinematicWorkspace ws;
    for (const Measurement& r : data.rows) {
      const Eigen::Isometry3d T = forwardKinematics(model, r.q, r.context, ws);
      pos.push_back((T.translation() - r.p_world_mm).norm() * std::sqrt(r.weight));
      if (orientation)
        rot.push_back(logSO3(T.linear() * r.R_world_tcp.toRotationMatrix().transpose()).norm() *
                      std::sqrt(r.weight));
    }
    const double redundancy = std::max(1.0, double(m_eq - p_free)) / double(m_eq);
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
    if (orientation) *s_rot_deg = estimate(rot) * kRadToDeg;
  };

  ceres::Solver::Summary cs;
  {
    Eigen::MatrixXd J0;
    Eigen::VectorXd r0;
    stackedJacobian(model, layout, data, weights, &J0, &r0);
    summary.initial_cost = 0.5 * r0.squaredNorm();
  }
  const bool robust = options.loss != "none";
  // tau^2 for one component type (k0 = 0 position, 3 orientation): the root of
  // sum e^2 / (s^2 + tau^2) = share, by bisection (the left side falls with tau^2).
  auto modelErrorTerm = [&](int k0) {
    std::vector<double> e2, s2;
    KinematicWorkspace ws;
    const double a = options.loss_scale * std::sqrt(double(dim));
    for (size_t i = 0; i < data.rows.size(); ++i) {
      const Measurement& r = data.rows[i];
      const Eigen::Isometry3d T = forwardKinematics(model, r.q, r.context, ws);
      Vector6d e;
      e.head<3>() = T.translation() - r.p_world_mm;
      e.tail<3>() = orientation ? logSO3(T.linear() * r.R_world_tcp.toRotationMatrix().transpose())
                                : Eigen::Vector3d::Zero().eval();
      // with a robust loss, rows it down-weights do not inflate the model-error term
      if (robust && weights[i].w.cwiseProduct(e).norm() > a) continue;  // e.tail = 0 without orientation
      for (int k = k0; k < k0 + 3; ++k) {
        e2.push_back(e[k] * e[k] * r.weight);
        const double s = baseStd(r, k);
        s2.push_back(s * s);
      }
    }
    const double share = double(e2.size()) * std::max(1.0, double(m_eq - p_free)) / double(m_eq);
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
  };
  const bool file_or_given_pos = !estimate_pos, file_or_given_rot = orientation && !estimate_rot;
  if (estimate_pos || estimate_rot || options.model_error) {
    // Variance components: solve, re-estimate from the residuals, solve again.
    for (int round = 0; round < 4; ++round) {
      solve(robust, &cs);
      double change = 0;
      if (estimate_pos || estimate_rot) {
        double sp = pos_std, sr = rot_std_deg;
        componentStd(robust, &sp, &sr);
        if (estimate_pos) {
          change += std::abs(std::log(sp / pos_std));
          pos_std = std::max(sp, 1e-6);
        }
        if (estimate_rot) {
          change += std::abs(std::log(sr / rot_std_deg));
          rot_std_deg = std::max(sr, 1e-9);
        }
      }
      if (options.model_error) {
        if (file_or_given_pos) {
          const double t = modelErrorTerm(0);
          change += std::abs(t - tau_pos_mm) / std::max(t, 1e-9);
          tau_pos_mm = t;
        }
        if (file_or_given_rot) {
          const double t = modelErrorTerm(3);
          change += std::abs(t - tau_rot_rad) / std::max(t, 1e-12);
          tau_rot_rad = t;
        }
      }
      makeWeights();
      if (change < 0.01) break;
    }
  }
  solve(robust, &cs);
  summary.termination = std::string(ceres::TerminationTypeToString(cs.termination_type)) +
                        (cs.message.empty() ? "" : ": " + cs.message);
  summary.iterations = static_cast<int>(cs.iterations.size()) - 1;
  if (cs.termination_type == ceres::FAILURE)
    throw NumericalError("identification failed: " + cs.message);

  if (file_pos_std) summary.weighting = "position: per-row std columns of the data";
  else if (estimate_pos) summary.weighting = "position: std estimated from the residuals";
  else summary.weighting = "position: std given";
  if (orientation) {
    if (file_rot_std) summary.weighting += "; orientation: per-row std columns of the data";
    else if (estimate_rot) summary.weighting += "; orientation: std estimated from the residuals";
    else summary.weighting += "; orientation: std given";
  }
  if (data.has_weight) summary.weighting += "; times the per-row weight column";
  summary.model_error_mm = tau_pos_mm;
  summary.model_error_deg = tau_rot_rad * kRadToDeg;
  if (tau_pos_mm > 0 || tau_rot_rad > 0) {
    char buf[200];
    std::snprintf(buf, sizeof buf, "; plus an unmodelled-error term estimated from the residuals: %.4g mm, %.4g deg",
                  tau_pos_mm, tau_rot_rad * kRadToDeg);
    summary.weighting += buf;
  }
  summary.position_std_mm = file_pos_std ? std::numeric_limits<double>::quiet_NaN() : pos_std;
  summary.orientation_std_deg = (orientation && !file_rot_std) ? rot_std_deg : std::numeric_limits<double>::quiet_NaN();

  // 5. Uncertainties at the solution: Cov = s0^2 (J^T J)^-1 over the free parameters.
  Eigen::MatrixXd J;
  Eigen::VectorXd r;
  stackedJacobian(model, layout, data, weights, &J, &r);
  summary.final_cost = 0.5 * r.squaredNorm();
  std::vector<int> free_idx;
  for (size_t k = 0; k < P; ++k)
    if (free[k]) free_idx.push_back(static_cast<int>(k));
  Eigen::MatrixXd Jf(J.rows(), static_cast<Eigen::Index>(free_idx.size()));
  for (size_t c = 0; c < free_idx.size(); ++c) Jf.col(c) = J.col(free_idx[c]);
  const double dof_res = std::max(1.0, double(J.rows()) - double(free_idx.size()));
  summary.variance_factor = r.squaredNorm() / dof_res;
  Eigen::VectorXd sigma = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(free_idx.size()));
  if (!free_idx.empty()) {
    const Eigen::VectorXd scale = Jf.colwise().norm().cwiseMax(1e-300);
    const Eigen::MatrixXd Jn = Jf * scale.cwiseInverse().asDiagonal();
    const Eigen::MatrixXd N = Jn.transpose() * Jn;
    Eigen::LDLT<Eigen::MatrixXd> ldlt(N);
    if (ldlt.info() != Eigen::Success)
      throw NumericalError("identification: normal matrix is singular at the solution");
    const Eigen::MatrixXd Ninv = ldlt.solve(Eigen::MatrixXd::Identity(N.rows(), N.cols()));
    for (Eigen::Index c = 0; c < sigma.size(); ++c)
      sigma[c] = std::sqrt(std::max(0.0, summary.variance_factor * Ninv(c, c))) / scale[c];
  }
  for (size_t c = 0; c < free_idx.size(); ++c) {
    const ParamInfo& p = layout[free_idx[c]];
    summary.parameters.push_back({p.name, p.group, p.unit,
                                  getParameter(model.deviations, p) * p.display_scale,
                                  sigma[static_cast<Eigen::Index>(c)] * p.display_scale});
  }
  if (robust) {
    const double a = options.loss_scale * std::sqrt(double(dim));
    for (size_t i = 0; i < data.rows.size(); ++i) {
      if (r.segment(static_cast<Eigen::Index>(i) * dim, dim).norm() > a)
        summary.downweighted_lines.push_back(data.rows[i].line);
    }
  }
  summary.fit = evaluate(model, data);
  if (summary_out) *summary_out = summary;
  return model;
}

RobotModel registerStation(const RobotModel& model, const MeasurementSet& data,
                           IdentifySummary* summary) {
  IdentifyOptions o;
  o.groups = {"base"};
  return identify(model, data, o, summary);
}

}  // namespace accura
