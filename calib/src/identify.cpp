#include "accura/calib/identify.h"

#include <ceres/ceres.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/joint_map.h"
#include "accura/calib/kinematics.h"

namespace accura::calib {

namespace {
// A --params item: a group name, optionally restricted to some joints: "gear_periodic:j1+j2".
// Returns false with *error on a malformed item. `joints` is empty when all joints are meant.
// joint_map may end in "@KNOT" (knot spacing, e.g. "@3deg"): *knot gets it (NaN when absent).
bool parseGroupSpec(const std::string& full_spec, std::string* name, std::set<int>* joints, std::string* error,
                    double* knot = nullptr) {
  std::string spec = full_spec;
  if (knot) *knot = std::numeric_limits<double>::quiet_NaN();
  const size_t at = spec.find('@');
  if (at != std::string::npos) {
    if (spec.compare(0, 9, "joint_map") != 0) {
      *error = "parameter group '" + full_spec + "': only joint_map takes a knot spacing (@...)";
      return false;
    }
    double k = 0;
    std::string unit;
    if (!parseJointMapKnot(spec.substr(at + 1), &k, &unit, error)) {
      *error = "parameter group '" + full_spec + "': " + *error;
      return false;
    }
    if (knot) *knot = k;
    spec = spec.substr(0, at);
  }
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
  if (!(std::isnan(joint_map_knot) || (std::isfinite(joint_map_knot) && joint_map_knot > 0)))
    return fail("joint_map_knot must be > 0 (deg or mm), got " + std::to_string(joint_map_knot));
  if (!(std::isnan(joint_map_smoothing) || (std::isfinite(joint_map_smoothing) && joint_map_smoothing >= 0)))
    return fail("joint_map_smoothing must be >= 0, got " + std::to_string(joint_map_smoothing));
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

// Tracker stations. Rows of a data set s > 0 measured from its own station are predicted as
// T_s * T_world_tcp, T_s = (expSO3(w_s), t_s) a correction in the world frame; its 6
// parameters (t_s mm, w_s rad) follow the layout's parameters in x. Station 0 is the model's
// own T_world_base (no correction).
struct Stations {
  std::vector<int> of_row;  // station per row
  int extra = 0;            // number of stations beyond the first
  size_t offset = 0;        // x index of the first station parameter (= layout size)

  Eigen::Isometry3d transform(const std::vector<double>& x, int s) const {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    if (s <= 0) return T;
    const size_t o = offset + 6 * static_cast<size_t>(s - 1);
    T.linear() = expSO3(Eigen::Vector3d(x[o + 3], x[o + 4], x[o + 5]));
    T.translation() = Eigen::Vector3d(x[o], x[o + 1], x[o + 2]);
    return T;
  }
};

// How the Jacobian over the layout is computed: parameterJacobian on the layout without the
// joint maps' coefficients plus one unit column (a unit dtheta, or dd) per mapped joint; a
// coefficient's column is that unit column times its basis function at q (joint_map.h), and only
// 4 per mapped joint are non-zero: this keeps the cost independent of the maps' resolution.
struct JacobianPlan {
  std::vector<ParamInfo> columns;
  std::vector<int> x_of;               // x index of each column; -1: the unit column of a mapped joint
  std::vector<int> unit_joint;         // joint of each column (unit columns), else -1
  std::vector<std::vector<int>> map_x;  // per joint: x index of each map coefficient (empty: not mapped)
  size_t P = 0;                        // layout size
};

JacobianPlan makePlan(const RobotModel& model, const std::vector<ParamInfo>& layout) {
  JacobianPlan plan;
  plan.P = layout.size();
  plan.map_x.resize(static_cast<size_t>(model.dof()));
  for (size_t k = 0; k < layout.size(); ++k) {
    const ParamInfo& p = layout[k];
    if (p.kind == ParamKind::kJointMap) {
      std::vector<int>& mx = plan.map_x[static_cast<size_t>(p.joint)];
      const size_t K = model.deviations.joint_map[static_cast<size_t>(p.joint)].coef.size();
      if (mx.empty()) {
        mx.assign(K, -1);
        const bool revolute = model.nominal.joints[static_cast<size_t>(p.joint)].type == JointType::kRevolute;
        // the joint's own motion per unit dtheta (revolute) or dd (prismatic; the thermal length
        // scale of the dd column is 1 + O(1e-4): only the Jacobian, not the residual, sees it)
        plan.columns.push_back({revolute ? ParamKind::kOffset : ParamKind::kD, p.joint, "map_unit", "joint_map", "", 1.0});
        plan.x_of.push_back(-1);
        plan.unit_joint.push_back(p.joint);
      }
      mx[static_cast<size_t>(p.index)] = static_cast<int>(k);
      continue;
    }
    plan.columns.push_back(p);
    plan.x_of.push_back(static_cast<int>(k));
    plan.unit_joint.push_back(-1);
  }
  return plan;
}

// Pose of row i with its station applied and, with J, its Jacobian over x (6 x x.size()):
// the model's columns rotated into the station's world, then the station's 6 columns.
Eigen::Isometry3d rowPose(const RobotModel& model, const JacobianPlan& plan, const Stations& st,
                          const std::vector<double>& x, const Measurement& row, size_t i, KinematicWorkspace& ws,
                          Eigen::MatrixXd* Jtmp, Eigen::MatrixXd* J) {
  const int s = st.of_row[i];
  const Eigen::Index P = static_cast<Eigen::Index>(plan.P);
  Eigen::Isometry3d T = J ? parameterJacobian(model, plan.columns, row.q, row.context, ws, *Jtmp)
                          : forwardKinematics(model, row.q, row.context, ws);
  if (J) {
    J->setZero(6, static_cast<Eigen::Index>(x.size()));
    for (size_t c = 0; c < plan.columns.size(); ++c) {
      if (plan.x_of[c] >= 0) {
        J->col(plan.x_of[c]) = Jtmp->col(static_cast<Eigen::Index>(c));
        continue;
      }
      const int j = plan.unit_joint[c];
      double w[4];
      const int first = jointMapBasis(model.deviations.joint_map[static_cast<size_t>(j)], row.q[j], w);
      for (int k = 0; k < 4; ++k) {
        const int xi = plan.map_x[static_cast<size_t>(j)][static_cast<size_t>(first + k)];
        if (xi >= 0) J->col(xi) = Jtmp->col(static_cast<Eigen::Index>(c)) * w[k];
      }
    }
  }
  if (s == 0) return T;
  const Eigen::Isometry3d Ts = st.transform(x, s);
  T = Ts * T;
  if (J) {
    const Eigen::Matrix3d R = Ts.linear();
    J->topLeftCorner(3, P) = (R * J->topLeftCorner(3, P)).eval();
    J->block(3, 0, 3, P) = (R * J->block(3, 0, 3, P)).eval();
    const Eigen::Index c = static_cast<Eigen::Index>(st.offset) + 6 * (s - 1);
    J->block<3, 3>(0, c).setIdentity();
    const size_t o = st.offset + 6 * static_cast<size_t>(s - 1);
    // expSO3(w + dw) = expSO3(Jl dw) expSO3(w), Jl(w) = Jr(w)^T: a rotation about Jl e_k through t_s
    const Eigen::Matrix3d Jl = rightJacobianSO3(Eigen::Vector3d(x[o + 3], x[o + 4], x[o + 5])).transpose();
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d u = Jl.col(k);
      J->block<3, 1>(0, c + 3 + k) = u.cross(T.translation() - Ts.translation());
      J->block<3, 1>(3, c + 3 + k) = u;
    }
  }
  return T;
}

Vector6d rowError(const Eigen::Isometry3d& T, const Measurement& row, int dim) {
  Vector6d e = Vector6d::Zero();
  e.head<3>() = T.translation() - row.p_world_mm;
  if (dim == 6) e.tail<3>() = logSO3(T.linear() * row.R_world_tcp.toRotationMatrix().transpose());
  return e;
}

// Evaluates all rows once per evaluation point (Ceres' EvaluationCallback) and hands each
// row's residual and Jacobian to its RowCost.
class Evaluator : public ceres::EvaluationCallback {
 public:
  Evaluator(RobotModel model, const std::vector<ParamInfo>& layout, const JacobianPlan& plan, const Stations& stations,
            const MeasurementSet& data, const std::vector<RowWeights>& weights, std::vector<double>* x)
      : model_(std::move(model)), layout_(layout), plan_(plan), stations_(stations), data_(data), weights_(weights), x_(x) {
    const size_t m = data.rows.size();
    residuals_.resize(m);
    jacobians_.resize(m);
  }

  void PrepareForEvaluation(bool evaluate_jacobians, bool new_evaluation_point) override {
    if (!new_evaluation_point && (have_jacobians_ || !evaluate_jacobians)) return;
    update();
    for (size_t i = 0; i < data_.rows.size(); ++i) {
      const Measurement& row = data_.rows[i];
      const int dim = weights_[i].dim;
      const Eigen::Isometry3d T = rowPose(model_, plan_, stations_, *x_, row, i, ws_, &Jtmp_,
                                          evaluate_jacobians ? &J_ : nullptr);
      if (evaluate_jacobians) jacobians_[i] = weights_[i].w.head(dim).asDiagonal() * J_.topRows(dim);
      residuals_[i] = weights_[i].w.cwiseProduct(rowError(T, row, dim));
    }
    have_jacobians_ = evaluate_jacobians;
  }

  void update() {
    for (size_t k = 0; k < layout_.size(); ++k) setParameter(model_.deviations, layout_[k], (*x_)[k]);
  }

  const Vector6d& residual(size_t i) const { return residuals_[i]; }
  const Eigen::MatrixXd& jacobian(size_t i) const { return jacobians_[i]; }

 private:
  RobotModel model_;
  const std::vector<ParamInfo>& layout_;
  const JacobianPlan& plan_;
  const Stations& stations_;
  const MeasurementSet& data_;
  const std::vector<RowWeights>& weights_;
  std::vector<double>* x_;
  KinematicWorkspace ws_;
  Eigen::MatrixXd J_, Jtmp_;
  std::vector<Vector6d> residuals_;
  std::vector<Eigen::MatrixXd> jacobians_;
  bool have_jacobians_ = false;
};

struct Block {
  int start, size;
};

// One row's residual; depends on the parameter blocks `blocks` (indices into x).
class RowCost : public ceres::CostFunction {
 public:
  RowCost(const Evaluator* ev, size_t row, int dim, std::vector<Block> blocks)
      : ev_(ev), row_(row), blocks_(std::move(blocks)) {
    set_num_residuals(dim);
    for (const Block& b : blocks_) mutable_parameter_block_sizes()->push_back(b.size);
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

// A penalty row: sum over its blocks b and their entries c of a[b][c] x_b[c] (joint-map
// regularisation).
class LinearCost : public ceres::CostFunction {
 public:
  explicit LinearCost(std::vector<std::vector<double>> a) : a_(std::move(a)) {
    set_num_residuals(1);
    for (const auto& b : a_) mutable_parameter_block_sizes()->push_back(static_cast<int>(b.size()));
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    double r = 0;
    for (size_t b = 0; b < a_.size(); ++b)
      for (size_t c = 0; c < a_[b].size(); ++c) r += a_[b][c] * parameters[b][c];
    residuals[0] = r;
    if (jacobians)
      for (size_t b = 0; b < a_.size(); ++b)
        if (jacobians[b])
          for (size_t c = 0; c < a_[b].size(); ++c) jacobians[b][c] = a_[b][c];
    return true;
  }

 private:
  std::vector<std::vector<double>> a_;
};

// A weighted penalty row over x: coefficients by x index.
struct PenaltyRow {
  std::vector<std::pair<int, double>> terms;
};

// Weighted, stacked Jacobian over x and the weighted residual at `model`.
void stackedJacobian(const RobotModel& model, const JacobianPlan& plan, const Stations& st,
                     const std::vector<double>& x, const MeasurementSet& data,
                     const std::vector<RowWeights>& weights, Eigen::MatrixXd* J, Eigen::VectorXd* r) {
  int m = 0;
  for (const auto& w : weights) m += w.dim;
  J->resize(m, static_cast<Eigen::Index>(x.size()));
  if (r) r->resize(m);
  KinematicWorkspace ws;
  Eigen::MatrixXd Ji, Jtmp;
  int row = 0;
  for (size_t i = 0; i < data.rows.size(); ++i) {
    const Measurement& meas = data.rows[i];
    const Eigen::Isometry3d T = rowPose(model, plan, st, x, meas, i, ws, &Jtmp, &Ji);
    const int dim = weights[i].dim;
    J->middleRows(row, dim) = weights[i].w.head(dim).asDiagonal() * Ji.topRows(dim);
    if (r) r->segment(row, dim) = weights[i].w.cwiseProduct(rowError(T, meas, dim)).head(dim);
    row += dim;
  }
}

// The data with each row's measurement carried into station 0's world (p' = R^T (p - t),
// R' = R^T R): what the model predicts directly, for statistics.
MeasurementSet inStationZero(const MeasurementSet& data, const Stations& st, const std::vector<double>& x) {
  MeasurementSet out = data;
  for (size_t i = 0; i < out.rows.size(); ++i) {
    if (st.of_row[i] == 0) continue;
    const Eigen::Isometry3d Tinv = st.transform(x, st.of_row[i]).inverse();
    Measurement& m = out.rows[i];
    m.p_world_mm = Tinv * m.p_world_mm;
    m.R_world_tcp = Eigen::Quaterniond(Tinv.linear() * m.R_world_tcp.toRotationMatrix()).normalized();
  }
  return out;
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

// The groups of options.groups: name -> joints (1-based; empty: all), and the joint_map knot
// stated with '@' (NaN when none).
std::map<std::string, std::set<int>> parseGroups(const IdentifyOptions& options, double* map_knot) {
  std::map<std::string, std::set<int>> groups;
  *map_knot = std::numeric_limits<double>::quiet_NaN();
  for (const auto& g : options.groups) {
    std::string name, spec_error;
    std::set<int> joints;
    double knot = 0;
    parseGroupSpec(g, &name, &joints, &spec_error, &knot);  // validated by IsValid
    if (name == "geometric") {
      for (const char* s : {"base", "tool", "offsets", "lengths", "angles"}) groups[s] = joints;
    } else {
      groups[name] = joints;
    }
    if (name == "joint_map" && !std::isnan(knot)) *map_knot = knot;
  }
  return groups;
}

bool allOrientation(const MeasurementSet& data) {
  return !data.rows.empty() &&
         std::all_of(data.rows.begin(), data.rows.end(), [](const Measurement& r) { return r.has_orientation; });
}

// The rows of every set in one set (flags: those all sets have) and the set of each row.
MeasurementSet combine(const std::vector<MeasurementSet>& sets, std::vector<int>* set_of_row) {
  MeasurementSet data = sets[0];
  data.rows.clear();
  set_of_row->clear();
  for (size_t s = 0; s < sets.size(); ++s) {
    const MeasurementSet& d = sets[s];
    if (s > 0) {
      data.file += ", " + d.file;
      data.has_orientation = data.has_orientation && d.has_orientation;
      data.has_std_position = data.has_std_position && d.has_std_position;
      data.has_std_orientation = data.has_std_orientation && d.has_std_orientation;
      data.has_weight = data.has_weight || d.has_weight;
    }
    for (const Measurement& r : d.rows) {
      data.rows.push_back(r);
      set_of_row->push_back(static_cast<int>(s));
    }
  }
  return data;
}

// Stations per set, joint-map reports, suspicious rows and plausibility warnings.
void finishSummary(const RobotModel& model, const std::vector<MeasurementSet>& sets, const std::vector<int>& set_of_row,
                   const Stations& st, const std::vector<double>& x, const MeasurementSet& data0,
                   const Eigen::VectorXd& r, int dim, double smoothing, IdentifySummary* s) {
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
  std::vector<double> sorted = norms;
  std::nth_element(sorted.begin(), sorted.begin() + rows / 2, sorted.end());
  const double chi_median = dim == 6 ? 2.3660 : 1.5382, chi_limit = dim == 6 ? 5.278 : 4.594;
  const double scale = sorted[rows / 2] / chi_median;
  KinematicWorkspace ws;
  for (size_t i = 0; i < rows && scale > 0; ++i) {
    if (norms[i] / scale <= chi_limit) continue;
    const Measurement& m = data0.rows[i];
    const double e = (forwardKinematics(model, m.q, m.context, ws).translation() - m.p_world_mm).norm();
    s->suspicious.push_back({sets[static_cast<size_t>(set_of_row[i])].file, m.line, norms[i] / scale, e});
  }
  // plausibility of the estimates
  for (const ParameterEstimate& p : s->parameters) {
    const std::string v = p.name + " = " + fmtNum(p.value) + " +- " + fmtNum(p.sigma) + " " + p.unit;
    if (p.group == "joint_compliance" && p.value < 0 && p.value < -2 * p.sigma)
      s->warnings.push_back(v + ": a negative joint compliance is physically impossible (the joint would deflect "
                                "against its load): it absorbs an unmodelled error");
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

// One station per data set (station 0: the model's own), or one for all when `same`.
Stations stationsFor(const std::vector<int>& set_of_row, size_t sets, bool same) {
  Stations st;
  st.of_row.assign(set_of_row.size(), 0);
  if (!same) {
    st.of_row = set_of_row;
    st.extra = static_cast<int>(sets) - 1;
  }
  return st;
}

}  // namespace

RobotModel identify(const RobotModel& start, const MeasurementSet& data,
                    const IdentifyOptions& options, IdentifySummary* summary_out) {
  return identify(start, std::vector<MeasurementSet>{data}, options, summary_out);
}

namespace {
RobotModel identifyWithMapCv(const RobotModel& start, const std::vector<MeasurementSet>& sets,
                             const IdentifyOptions& options, double stated_knot, IdentifySummary* summary_out);
}  // namespace

RobotModel identify(const RobotModel& start, const std::vector<MeasurementSet>& sets,
                    const IdentifyOptions& options, IdentifySummary* summary_out) {
  std::string why;
  if (!options.IsValid(&why)) throw ArgumentError("identify: " + why);
  if (sets.empty()) throw ArgumentError("identify: no data set given");
  for (const auto& d : sets)
    if (d.rows.empty()) throw InputError(d.file, 0, 0, "expected measured rows, found none");
  start.validate();
  double stated_knot = 0;
  std::map<std::string, std::set<int>> groups = parseGroups(options, &stated_knot);
  if (std::isnan(stated_knot)) stated_knot = options.joint_map_knot;  // '@' overrides the option
  const bool want_map = groups.count("joint_map") > 0;
  if (want_map && (std::isnan(stated_knot) || std::isnan(options.joint_map_smoothing)))
    return identifyWithMapCv(start, sets, options, stated_knot, summary_out);

  IdentifySummary summary;
  RobotModel model = start;
  std::vector<int> set_of_row;
  const MeasurementSet data = combine(sets, &set_of_row);
  Stations st = stationsFor(set_of_row, sets.size(), options.same_station);
  const bool orientation = allOrientation(data);
  const int n = model.dof();

  // Coverage of the fit data, per joint.
  summary.coverage.assign(static_cast<size_t>(n), JointRange{});
  for (int j = 0; j < n; ++j) {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (const Measurement& r : data.rows) {
      lo = std::min(lo, r.q[j]);
      hi = std::max(hi, r.q[j]);
    }
    summary.coverage[static_cast<size_t>(j)] = {lo, hi};
  }
  // Joint maps: on the covered interval of each mapped joint.
  if (want_map) {
    const std::set<int>& mj = groups["joint_map"];
    for (int j = 0; j < n; ++j) {
      if (!mj.empty() && !mj.count(j + 1)) continue;
      const JointRange& c = summary.coverage[static_cast<size_t>(j)];
      const bool revolute = model.nominal.joints[static_cast<size_t>(j)].type == JointType::kRevolute;
      if (c.upper - c.lower < 2 * stated_knot) {
        summary.warnings.push_back("joint_map: j" + std::to_string(j + 1) + " covers only " +
                                   fmtNum(c.upper - c.lower) + (revolute ? " deg" : " mm") +
                                   " in the fit data (less than two knot spacings): no map for this joint");
        model.deviations.joint_map[static_cast<size_t>(j)] = JointMap{};
        continue;
      }
      model.deviations.joint_map[static_cast<size_t>(j)] = makeJointMap(c.lower, c.upper, stated_knot);
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
  const JacobianPlan plan = makePlan(model, layout);
  st.offset = P;
  const size_t X = P + 6 * static_cast<size_t>(st.extra);
  auto isMap = [&](size_t k) { return k < P && layout[k].kind == ParamKind::kJointMap; };
  size_t n_map = 0;
  for (size_t k = 0; k < P; ++k) n_map += isMap(k) ? 1 : 0;
  const bool sparse = n_map > 0;
  const int n_candidates = static_cast<int>(X);
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

  // 1. Closed-form registration of the measurement frame (and the tool point) on the first
  // station's rows; every further station registered in closed form against that model.
  std::vector<double> x(X, 0.0);
  {
    MeasurementSet first = data;
    first.rows.clear();
    for (size_t i = 0; i < data.rows.size(); ++i)
      if (st.of_row[i] == 0) first.rows.push_back(data.rows[i]);
    if (options.register_frame && groups.count("base")) registerFrame(model, first, groups.count("tool") > 0);
    for (int s = 1; s <= st.extra; ++s) {
      RobotModel other = model;
      registerFrame(other, sets[static_cast<size_t>(s)], false);
      const Eigen::Isometry3d Ts = other.T_world_base() * model.T_world_base().inverse();
      const Eigen::Vector3d w = logSO3(Ts.linear());
      const size_t o = P + 6 * static_cast<size_t>(s - 1);
      for (int k = 0; k < 3; ++k) {
        x[o + k] = Ts.translation()[k];
        x[o + 3 + k] = w[k];
      }
    }
    double s2 = 0;
    for (double e : positionErrors(model, inStationZero(data, st, x))) s2 += e * e;
    summary.registration_rms_mm = std::sqrt(s2 / double(data.rows.size()));
  }
  for (size_t k = 0; k < P; ++k) x[k] = getParameter(model.deviations, layout[k]);
  MeasurementSet data0 = inStationZero(data, st, x);  // refreshed after every solve

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

  // 3. Identifiability on the scaled weighted Jacobian at the starting point (the joint maps'
  // coefficients are not candidates here: they are regularised, see 4).
  std::vector<int> cand_idx;
  for (size_t k = 0; k < P; ++k)
    if (!isMap(k)) cand_idx.push_back(static_cast<int>(k));
  Eigen::MatrixXd Jfull;
  stackedJacobian(model, plan, st, x, data, weights, &Jfull, nullptr);
  const Eigen::Index m = Jfull.rows();
  Eigen::MatrixXd Js(m, static_cast<Eigen::Index>(cand_idx.size()));
  for (size_t c = 0; c < cand_idx.size(); ++c) Js.col(c) = Jfull.col(cand_idx[c]);
  Eigen::VectorXd norms = Js.colwise().norm();
  std::vector<bool> free(X, true);
  for (size_t k = 0; k < P; ++k)
    if (!isMap(k)) free[k] = false;
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
  const int p_free = static_cast<int>(kept.size() + n_map) + 6 * st.extra;
  summary.parameters_free = static_cast<int>(kept.size());
  summary.equations = static_cast<int>(m);

  // The joint maps' regularisation rows (x indices, weighted): smoothness (second differences,
  // sqrt(smoothing) * scale) and centring (no mean, no linear trend over the fit data;
  // kJointMapCentringWeight * scale), scale = the RMS norm of the map's weighted columns.
  std::vector<PenaltyRow> penalties;
  const double smoothing = options.joint_map_smoothing;
  for (int j = 0; j < n && sparse; ++j) {
    std::vector<int> cols;
    for (size_t k = 0; k < P; ++k)
      if (isMap(k) && layout[k].joint == j) cols.push_back(static_cast<int>(k));
    if (cols.empty()) continue;
    const JointMap& jm = model.deviations.joint_map[static_cast<size_t>(j)];
    double s2 = 0;
    for (int c : cols) s2 += Jfull.col(c).squaredNorm();
    const double scale = std::sqrt(std::max(s2 / double(cols.size()), 1e-300));
    auto add = [&](const std::vector<double>& a, double weight) {
      PenaltyRow row;
      for (size_t k = 0; k < a.size(); ++k)
        if (a[k] != 0) row.terms.push_back({cols[k], weight * a[k]});
      if (!row.terms.empty()) penalties.push_back(row);
    };
    if (smoothing > 0)
      for (const auto& a : jointMapSmoothnessRows(jm)) add(a, std::sqrt(smoothing) * scale);
    std::vector<double> qj;
    for (const Measurement& r : data.rows) qj.push_back(r.q[j]);
    const bool revolute = model.nominal.joints[static_cast<size_t>(j)].type == JointType::kRevolute;
    for (const auto& a : jointMapCentringRows(jm, qj, revolute ? kJointMapCentredHarmonics : 0)) {
      double nrm = 0;
      for (double v : a) nrm += v * v;
      if (nrm > 0) add(a, kJointMapCentringWeight * scale / std::sqrt(nrm));
    }
  }

  // 4. Ceres problem: one parameter block per base, tool, joint, compliance, extra station;
  // each joint-map coefficient its own block (a row depends on 4 of them per mapped joint:
  // sparse normal equations).
  std::vector<Block> blocks;
  std::vector<int> block_of(X, -1);
  auto blockKey = [&](size_t k) -> std::string {
    const ParamInfo& p = layout[k];
    // joint-map coefficients in blocks of 4 (a row touches 4 consecutive ones: at most 2 blocks)
    if (p.kind == ParamKind::kJointMap) return "map" + std::to_string(p.joint) + "_" + std::to_string(p.index / 4);
    if (p.group == "base" || p.group == "tool" || p.group == "joint_compliance") return p.group;
    return "j" + std::to_string(p.joint);
  };
  for (size_t k = 0; k < P;) {
    size_t e = k + 1;
    while (e < P && blockKey(e) == blockKey(k)) ++e;
    for (size_t c = k; c < e; ++c) block_of[c] = static_cast<int>(blocks.size());
    blocks.push_back({static_cast<int>(k), static_cast<int>(e - k)});
    k = e;
  }
  for (int s = 1; s <= st.extra; ++s) {
    const int o = static_cast<int>(P) + 6 * (s - 1);
    for (int c = 0; c < 6; ++c) block_of[static_cast<size_t>(o + c)] = static_cast<int>(blocks.size());
    blocks.push_back({o, 6});
  }
  // the blocks each row depends on
  std::vector<std::vector<int>> row_blocks(data.rows.size());
  for (size_t i = 0; i < data.rows.size(); ++i) {
    std::vector<int>& rb = row_blocks[i];
    for (size_t b = 0; b < blocks.size(); ++b) {
      const Block& B = blocks[b];
      if (isMap(static_cast<size_t>(B.start))) continue;
      if (static_cast<size_t>(B.start) >= P && (!sparse || B.start == static_cast<int>(P) + 6 * (st.of_row[i] - 1)))
        rb.push_back(static_cast<int>(b));
      else if (static_cast<size_t>(B.start) < P)
        rb.push_back(static_cast<int>(b));
    }
    if (!sparse) continue;
    for (int j = 0; j < n; ++j) {
      const JointMap& jm = model.deviations.joint_map[static_cast<size_t>(j)];
      if (jm.empty()) continue;
      double w[4];
      const int first = jointMapBasis(jm, data.rows[i].q[j], w);
      for (size_t k = 0; k < P; ++k)
        if (isMap(k) && layout[k].joint == j && layout[k].index >= first && layout[k].index < first + 4 &&
            std::find(rb.begin(), rb.end(), block_of[k]) == rb.end())
          rb.push_back(block_of[k]);
    }
  }

  auto solve = [&](bool robust, ceres::Solver::Summary* ceres_summary) {
    Evaluator evaluator(model, layout, plan, st, data, weights, &x);
    ceres::Problem::Options popts;
    popts.cost_function_ownership = ceres::TAKE_OWNERSHIP;
    popts.loss_function_ownership = ceres::TAKE_OWNERSHIP;
    popts.manifold_ownership = ceres::TAKE_OWNERSHIP;
    popts.evaluation_callback = &evaluator;
    ceres::Problem problem(popts);
    for (size_t i = 0; i < data.rows.size(); ++i) {
      ceres::LossFunction* loss = nullptr;
      if (robust) {
        const double a = options.loss_scale * std::sqrt(double(dim));
        if (options.loss == "huber") loss = new ceres::HuberLoss(a);
        if (options.loss == "cauchy") loss = new ceres::CauchyLoss(a);
      }
      std::vector<Block> bl;
      std::vector<double*> ptrs;
      for (int b : row_blocks[i]) {
        bl.push_back(blocks[static_cast<size_t>(b)]);
        ptrs.push_back(&x[static_cast<size_t>(blocks[static_cast<size_t>(b)].start)]);
      }
      problem.AddResidualBlock(new RowCost(&evaluator, i, dim, bl), loss, ptrs);
    }
    for (const PenaltyRow& pr : penalties) {
      // the blocks the row touches, and its coefficients laid out block by block
      std::vector<int> bl;
      for (const auto& t : pr.terms)
        if (std::find(bl.begin(), bl.end(), block_of[static_cast<size_t>(t.first)]) == bl.end())
          bl.push_back(block_of[static_cast<size_t>(t.first)]);
      std::vector<std::vector<double>> a;
      std::vector<double*> ptrs;
      for (int b : bl) {
        const Block& B = blocks[static_cast<size_t>(b)];
        std::vector<double> coef(static_cast<size_t>(B.size), 0.0);
        for (const auto& t : pr.terms)
          if (t.first >= B.start && t.first < B.start + B.size) coef[static_cast<size_t>(t.first - B.start)] = t.second;
        a.push_back(coef);
        ptrs.push_back(&x[static_cast<size_t>(B.start)]);
      }
      problem.AddResidualBlock(new LinearCost(a), nullptr, ptrs);
    }
    for (const Block& b : blocks) {
      if (!problem.HasParameterBlock(&x[static_cast<size_t>(b.start)])) continue;
      std::vector<int> fixed_idx;
      for (int c = 0; c < b.size; ++c)
        if (!free[static_cast<size_t>(b.start + c)]) fixed_idx.push_back(c);
      if (static_cast<int>(fixed_idx.size()) == b.size) {
        problem.SetParameterBlockConstant(&x[static_cast<size_t>(b.start)]);
      } else if (!fixed_idx.empty()) {
        problem.SetManifold(&x[static_cast<size_t>(b.start)], new ceres::SubsetManifold(b.size, fixed_idx));
      }
    }
    ceres::Solver::Options so;
    so.minimizer_type = ceres::TRUST_REGION;
    so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
    so.linear_solver_type = sparse ? ceres::SPARSE_NORMAL_CHOLESKY : ceres::DENSE_QR;
    so.max_num_iterations = options.max_iterations;
    so.function_tolerance = options.function_tolerance;
    so.parameter_tolerance = options.parameter_tolerance;
    if (sparse) {
      // hundreds of smoothed map coefficients: stop when the cost changes by less than 1e-9
      // relative (the maps' values then move by far less than their uncertainty)
      so.function_tolerance = std::max(so.function_tolerance, 1e-9);
      so.parameter_tolerance = std::max(so.parameter_tolerance, 1e-8);
    }
    if (getenv("ACCURA_DEBUG_ITER")) so.minimizer_progress_to_stdout = true;
    so.gradient_tolerance = 1e-16;
    so.num_threads = 1;
    so.logging_type = ceres::SILENT;
    ceres::Solve(so, &problem, ceres_summary);
    for (size_t k = 0; k < P; ++k) setParameter(model.deviations, layout[k], x[k]);
    data0 = inStationZero(data, st, x);
  };

  // Residual RMS per component type, for variance-component estimation.
  auto componentStd = [&](bool robust_estimate, double* s_pos, double* s_rot_deg) {
    std::vector<double> pos, rot;
    KinematicWorkspace ws;
    for (const Measurement& r : data0.rows) {
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
    stackedJacobian(model, plan, st, x, data, weights, &J0, &r0);
    summary.initial_cost = 0.5 * r0.squaredNorm();
  }
  const bool robust = options.loss != "none";
  // tau^2 for one component type (k0 = 0 position, 3 orientation): the root of
  // sum e^2 / (s^2 + tau^2) = share, by bisection (the left side falls with tau^2).
  auto modelErrorTerm = [&](int k0) {
    std::vector<double> e2, s2;
    KinematicWorkspace ws;
    const double a = options.loss_scale * std::sqrt(double(dim));
    for (size_t i = 0; i < data0.rows.size(); ++i) {
      const Measurement& r = data0.rows[i];
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

  // 5. Uncertainties at the solution: Cov = s0^2 (J^T J)^-1 over the free parameters (the
  // joint maps' penalty rows included: they make the maps' coefficients determined).
  Eigen::MatrixXd J;
  Eigen::VectorXd r;
  stackedJacobian(model, plan, st, x, data, weights, &J, &r);
  summary.final_cost = 0.5 * r.squaredNorm();
  std::vector<int> free_idx;
  for (size_t k = 0; k < X; ++k)
    if (free[k]) free_idx.push_back(static_cast<int>(k));
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
    const size_t k = static_cast<size_t>(free_idx[c]);
    if (k >= P || isMap(k)) continue;
    const ParamInfo& p = layout[k];
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
  summary.fit = evaluate(model, data0);
  finishSummary(model, sets, set_of_row, st, x, data0, r, dim, smoothing, &summary);
  // the fitted ranges belong to the model when it learnt something beyond the frames
  if (std::any_of(layout.begin(), layout.end(), [](const ParamInfo& p) { return p.group != "base" && p.group != "tool"; }))
    model.deviations.fit_range = summary.coverage;
  if (summary_out) *summary_out = summary;
  return model;
}

namespace {

// joint_map without a stated knot spacing or smoothness: fit without maps, choose both by
// blocked cross-validation on the problem linearised there, then identify with them.
RobotModel identifyWithMapCv(const RobotModel& start, const std::vector<MeasurementSet>& sets,
                             const IdentifyOptions& options, double stated_knot, IdentifySummary* summary_out) {
  IdentifyOptions o0 = options;
  o0.groups.clear();
  std::set<int> map_joints;
  for (const auto& g : options.groups) {
    std::string name, err;
    std::set<int> joints;
    parseGroupSpec(g, &name, &joints, &err);
    if (name == "joint_map") map_joints = joints;
    else o0.groups.push_back(g);
  }
  if (o0.groups.empty()) o0.groups = {"base"};
  IdentifySummary s0;
  const RobotModel m0 = identify(start, sets, o0, &s0);

  const std::vector<double> knots = std::isnan(stated_knot) ? jointMapKnotCandidates() : std::vector<double>{stated_knot};
  const std::vector<double> smoothings = std::isnan(options.joint_map_smoothing)
                                             ? jointMapSmoothingCandidates()
                                             : std::vector<double>{options.joint_map_smoothing};
  const double widest = *std::max_element(knots.begin(), knots.end());
  std::vector<int> cv_joints;
  std::vector<JointRange> ranges;
  for (int j = 0; j < m0.dof(); ++j) {
    if (!map_joints.empty() && !map_joints.count(j + 1)) continue;
    const JointRange& c = s0.coverage[static_cast<size_t>(j)];
    if (c.upper - c.lower < 2 * widest) continue;
    cv_joints.push_back(j);
    ranges.push_back(c);
  }
  IdentifyOptions o1 = options;
  o1.groups.clear();
  for (const auto& g : options.groups) o1.groups.push_back(g.substr(0, g.find('@')));
  JointMapCvResult cv;
  if (cv_joints.empty()) {
    cv.knot = knots[0];
    cv.smoothing = smoothings[0];
  } else {
    // the linearised problem at m0: its free parameters, the stations, a unit dtheta per joint
    std::vector<ParamInfo> L;
    std::set<std::string> free_names;
    for (const auto& p : s0.parameters) free_names.insert(p.name);
    for (const ParamInfo& p : parameterLayout(m0))
      if (free_names.count(p.name)) L.push_back(p);
    const size_t P0 = L.size();
    for (int j : cv_joints) {
      const bool revolute = m0.nominal.joints[static_cast<size_t>(j)].type == JointType::kRevolute;
      L.push_back({revolute ? ParamKind::kOffset : ParamKind::kD, j, "map_unit", "joint_map", "", 1.0});
    }
    std::vector<int> set_of_row;
    const MeasurementSet data = combine(sets, &set_of_row);
    Stations st = stationsFor(set_of_row, sets.size(), options.same_station);
    st.offset = L.size();
    std::vector<double> x(L.size() + 6 * static_cast<size_t>(st.extra), 0.0);
    for (size_t k = 0; k < L.size(); ++k) x[k] = getParameter(m0.deviations, L[k]);
    for (int s = 1; s <= st.extra; ++s) {
      const Eigen::Isometry3d Ts = s0.T_world_base_per_set[static_cast<size_t>(s)] * m0.T_world_base().inverse();
      const Eigen::Vector3d w = logSO3(Ts.linear());
      for (int k = 0; k < 3; ++k) {
        x[st.offset + 6 * static_cast<size_t>(s - 1) + static_cast<size_t>(k)] = Ts.translation()[k];
        x[st.offset + 6 * static_cast<size_t>(s - 1) + 3 + static_cast<size_t>(k)] = w[k];
      }
    }
    const bool orientation = allOrientation(data);
    const int dim = orientation ? 6 : 3;
    const double pos_std = std::isfinite(s0.position_std_mm) ? s0.position_std_mm : 0;
    const double rot_std = std::isfinite(s0.orientation_std_deg) ? s0.orientation_std_deg * kDegToRad : 0;
    const double tau_p = s0.model_error_mm, tau_r = s0.model_error_deg * kDegToRad;
    std::vector<size_t> set_size(sets.size(), 0), seen(sets.size(), 0);
    for (int s : set_of_row) ++set_size[static_cast<size_t>(s)];
    const int folds = 5;
    const JacobianPlan plan = makePlan(m0, L);
    std::vector<JointMapCvRow> rows(data.rows.size());
    KinematicWorkspace ws;
    Eigen::MatrixXd Jtmp, Jrow;
    const Eigen::Index nG = static_cast<Eigen::Index>(P0) + 6 * st.extra, nJ = static_cast<Eigen::Index>(cv_joints.size());
    for (size_t i = 0; i < data.rows.size(); ++i) {
      const Measurement& m = data.rows[i];
      Vector6d w;
      for (int k = 0; k < 6; ++k) {
        const double sd = k < 3 ? (data.has_std_position ? m.std_mm[k] : pos_std)
                                : (data.has_std_orientation ? m.std_rot_deg[k - 3] * kDegToRad : rot_std);
        const double tau = k < 3 ? tau_p : tau_r;
        w[k] = std::sqrt(m.weight) / std::sqrt(std::max(sd * sd + tau * tau, 1e-300));
      }
      const Eigen::Isometry3d T = rowPose(m0, plan, st, x, m, i, ws, &Jtmp, &Jrow);
      JointMapCvRow& row = rows[i];
      const auto W = w.head(dim).asDiagonal();
      row.G.resize(dim, nG);
      row.G.leftCols(static_cast<Eigen::Index>(P0)) = W * Jrow.topLeftCorner(dim, static_cast<Eigen::Index>(P0));
      if (st.extra > 0) row.G.rightCols(6 * st.extra) = W * Jrow.topRightCorner(dim, 6 * st.extra);
      row.U = W * Jrow.block(0, static_cast<Eigen::Index>(P0), dim, nJ);
      row.r = w.head(dim).cwiseProduct(rowError(T, m, dim).head(dim));
      row.q.resize(nJ);
      for (Eigen::Index j = 0; j < nJ; ++j) row.q[j] = m.q[cv_joints[static_cast<size_t>(j)]];
      row.w_pos = w.head<3>();
      const size_t s = static_cast<size_t>(set_of_row[i]);
      row.fold = static_cast<int>(folds * seen[s]++ / set_size[s]);
    }
    std::vector<int> harmonics;
    for (int j : cv_joints)
      harmonics.push_back(m0.nominal.joints[static_cast<size_t>(j)].type == JointType::kRevolute ? kJointMapCentredHarmonics : 0);
    cv = crossValidateJointMap(rows, ranges, harmonics, knots, smoothings, folds);
  }
  o1.joint_map_knot = cv.knot;
  o1.joint_map_smoothing = cv.smoothing;
  const RobotModel m1 = identify(start, sets, o1, summary_out);
  if (summary_out) {
    summary_out->joint_map_cv = cv.table;
    summary_out->joint_map_cv_baseline_mm = cv.baseline_rms_mm;
  }
  return m1;
}

}  // namespace

RobotModel registerStation(const RobotModel& model, const MeasurementSet& data,
                           IdentifySummary* summary) {
  IdentifyOptions o;
  o.groups = {"base"};
  return identify(model, data, o, summary);
}

}  // namespace accura::calib
