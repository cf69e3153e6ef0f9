// accura: the identification's Ceres problem (identify_internal.h): Levenberg-Marquardt on the
// stacked rows of identify_rows.cpp. Joint maps without a robust loss go to solveNormal
// (identify_normal.cpp), which follows the same iteration on the normal equations.
#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>

#include "accura/calib/joint_map.h"
#include "identify_internal.h"

namespace accura::calib::identify_detail {
namespace {

// Evaluates all rows once per evaluation point (Ceres' EvaluationCallback) into one stacked,
// weighted residual and Jacobian, which the cost functions read.
class Evaluator : public ceres::EvaluationCallback {
 public:
  Evaluator(const Problem& pb, std::vector<double>* x)
      : pb_(pb), model_(pb.model), x_(x), rows_(model_, pb.plan, pb.st), J_(pb.solve_J), r_(pb.solve_r) {
    int m = 0;
    for (const RowWeights& w : pb.weights) {
      offset_.push_back(m);
      m += w.dim;
    }
  }

  void PrepareForEvaluation(bool evaluate_jacobians, bool new_evaluation_point) override {
    if (!new_evaluation_point && (have_jacobians_ || !evaluate_jacobians)) return;
    have_jacobians_ = evaluate_jacobians;
    if (evaluate_jacobians && pb_.lastAt(*x_)) {
      J_ = pb_.last.J;
      r_ = pb_.last.r;
      return;
    }
    for (size_t k = 0; k < pb_.layout.size(); ++k) setParameter(model_.deviations, pb_.layout[k], (*x_)[k]);
    rows_.prepare(model_);
    rows_.stack(*x_, pb_.data, pb_.weights, evaluate_jacobians ? &J_ : nullptr, &r_);
    if (evaluate_jacobians) pb_.keep(*x_, J_, r_);
  }

  /// Weighted residual and Jacobian (over x) of all rows; row i starts at offset(i).
  const Eigen::VectorXd& residual() const { return r_; }
  const Eigen::MatrixXd& jacobian() const { return J_; }
  int offset(size_t i) const { return offset_[i]; }

 private:
  const Problem& pb_;
  RobotModel model_;
  std::vector<double>* x_;
  RowStack rows_;
  std::vector<int> offset_;
  Eigen::MatrixXd& J_;  ///< pb.solve_J (one buffer for all solves)
  Eigen::VectorXd& r_;
  bool have_jacobians_ = false;
};


// Rows [first, first + count) of the evaluator's stacked residual (one pose, or all poses in
// one residual block when there is no robust loss and no sparse structure: Ceres' per-block
// bookkeeping then costs nothing); depends on the parameter blocks `blocks` (indices into x).
class RowCost : public ceres::CostFunction {
 public:
  RowCost(const Evaluator* ev, int first, int count, std::vector<Block> blocks)
      : ev_(ev), first_(first), blocks_(std::move(blocks)) {
    set_num_residuals(count);
    for (const Block& b : blocks_) mutable_parameter_block_sizes()->push_back(b.size);
  }
  bool Evaluate(double const* const* /*parameters*/, double* residuals, double** jacobians) const override {
    const int count = num_residuals();
    const Eigen::VectorXd& r = ev_->residual();
    for (int k = 0; k < count; ++k) residuals[k] = r[first_ + k];
    if (!jacobians) return true;
    const Eigen::MatrixXd& J = ev_->jacobian();
    for (size_t b = 0; b < blocks_.size(); ++b) {
      if (!jacobians[b]) continue;
      const Block& B = blocks_[b];
      Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(jacobians[b], count, B.size) =
          J.block(first_, B.start, count, B.size);
    }
    return true;
  }

 private:
  const Evaluator* ev_;
  int first_;
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

// Parameter blocks: one per base, tool, joint, compliance, extra station; the joint-map
// coefficients in blocks of 4 (a row depends on 4 of them per mapped joint, so at most 2
// blocks: sparse normal equations). Per row, the blocks it depends on.
struct BlockLayout {
  std::vector<Block> blocks;
  std::vector<int> block_of;                // per x index
  std::vector<std::vector<int>> row_blocks;  // per row
};

BlockLayout blockLayout(const Problem& pb) {
  BlockLayout bl;
  const size_t P = pb.P;
  bl.block_of = parameterBlocks(pb, &bl.blocks);
  bl.row_blocks.resize(pb.data.rows.size());
  for (size_t i = 0; i < pb.data.rows.size(); ++i) {
    std::vector<int>& rb = bl.row_blocks[i];
    for (size_t b = 0; b < bl.blocks.size(); ++b) {
      const Block& B = bl.blocks[b];
      if (pb.isMap(static_cast<size_t>(B.start))) continue;
      if (static_cast<size_t>(B.start) >= P &&
          (!pb.sparse || B.start == static_cast<int>(P) + 6 * (pb.st.of_row[i] - 1)))
        rb.push_back(static_cast<int>(b));
      else if (static_cast<size_t>(B.start) < P)
        rb.push_back(static_cast<int>(b));
    }
    if (!pb.sparse) continue;
    for (int j = 0; j < pb.model.dof(); ++j) {
      const JointMap& jm = pb.model.deviations.joint_map[static_cast<size_t>(j)];
      if (jm.empty()) continue;
      double w[4];
      const int first = jointMapBasis(jm, pb.data.rows[i].q[j], w);
      for (size_t k = 0; k < P; ++k)
        if (pb.isMap(k) && pb.layout[k].joint == j && pb.layout[k].index >= first && pb.layout[k].index < first + 4 &&
            std::find(rb.begin(), rb.end(), bl.block_of[k]) == rb.end())
          rb.push_back(bl.block_of[k]);
    }
  }
  return bl;
}

thread_local bool t_ceres_for_maps = false;

}  // namespace

CeresForJointMaps::CeresForJointMaps() : before_(t_ceres_for_maps) { t_ceres_for_maps = true; }
CeresForJointMaps::~CeresForJointMaps() { t_ceres_for_maps = before_; }

std::vector<int> parameterBlocks(const Problem& pb, std::vector<Block>* blocks) {
  const size_t P = pb.P;
  std::vector<int> block_of(pb.X, -1);
  blocks->clear();
  auto blockKey = [&](size_t k) -> std::string {
    const ParamInfo& p = pb.layout[k];
    if (p.kind == ParamKind::kJointMap) return "map" + std::to_string(p.joint) + "_" + std::to_string(p.index / 4);
    if (p.group == "base" || p.group == "tool" || p.group == "joint_compliance") return p.group;
    return "j" + std::to_string(p.joint);
  };
  for (size_t k = 0; k < P;) {
    size_t e = k + 1;
    while (e < P && blockKey(e) == blockKey(k)) ++e;
    for (size_t c = k; c < e; ++c) block_of[c] = static_cast<int>(blocks->size());
    blocks->push_back({static_cast<int>(k), static_cast<int>(e - k)});
    k = e;
  }
  for (int s = 1; s <= pb.st.extra; ++s) {
    const int o = static_cast<int>(P) + 6 * (s - 1);
    for (int c = 0; c < 6; ++c) block_of[static_cast<size_t>(o + c)] = static_cast<int>(blocks->size());
    blocks->push_back({o, 6});
  }
  return block_of;
}

SolveResult solve(Problem& pb, const IdentifyOptions& options, bool robust) {
  if (pb.sparse && !robust && !t_ceres_for_maps) return solveNormal(pb, options);
  const BlockLayout L = blockLayout(pb);
  std::vector<double>& x = pb.x;
  Evaluator evaluator(pb, &x);
  ceres::Problem::Options popts;
  popts.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  popts.loss_function_ownership = ceres::TAKE_OWNERSHIP;
  popts.manifold_ownership = ceres::TAKE_OWNERSHIP;
  popts.evaluation_callback = &evaluator;
  ceres::Problem problem(popts);
  auto rowCost = [&](size_t i, int first, int count, ceres::LossFunction* loss) {
    std::vector<Block> bl;
    std::vector<double*> ptrs;
    for (int b : L.row_blocks[i]) {
      bl.push_back(L.blocks[static_cast<size_t>(b)]);
      ptrs.push_back(&x[static_cast<size_t>(L.blocks[static_cast<size_t>(b)].start)]);
    }
    problem.AddResidualBlock(new RowCost(&evaluator, first, count, bl), loss, ptrs);
  };
  if (!robust && !pb.sparse) {
    rowCost(0, 0, pb.m_eq, nullptr);  // every row depends on every block: one residual block for all
  } else {
    for (size_t i = 0; i < pb.data.rows.size(); ++i) {
      ceres::LossFunction* loss = nullptr;
      if (robust) {
        const double a = options.loss_scale * std::sqrt(double(pb.dim));
        if (options.loss == "huber") loss = new ceres::HuberLoss(a);
        if (options.loss == "cauchy") loss = new ceres::CauchyLoss(a);
      }
      rowCost(i, evaluator.offset(i), pb.dim, loss);
    }
  }
  for (const PenaltyRow& pr : pb.penalties) {
    // the blocks the row touches, and its coefficients laid out block by block
    std::vector<int> bl;
    for (const auto& t : pr.terms)
      if (std::find(bl.begin(), bl.end(), L.block_of[static_cast<size_t>(t.first)]) == bl.end())
        bl.push_back(L.block_of[static_cast<size_t>(t.first)]);
    std::vector<std::vector<double>> a;
    std::vector<double*> ptrs;
    for (int b : bl) {
      const Block& B = L.blocks[static_cast<size_t>(b)];
      std::vector<double> coef(static_cast<size_t>(B.size), 0.0);
      for (const auto& t : pr.terms)
        if (t.first >= B.start && t.first < B.start + B.size) coef[static_cast<size_t>(t.first - B.start)] = t.second;
      a.push_back(coef);
      ptrs.push_back(&x[static_cast<size_t>(B.start)]);
    }
    problem.AddResidualBlock(new LinearCost(a), nullptr, ptrs);
  }
  for (const Block& b : L.blocks) {
    if (!problem.HasParameterBlock(&x[static_cast<size_t>(b.start)])) continue;
    std::vector<int> fixed_idx;
    for (int c = 0; c < b.size; ++c)
      if (!pb.free[static_cast<size_t>(b.start + c)]) fixed_idx.push_back(c);
    if (static_cast<int>(fixed_idx.size()) == b.size) {
      problem.SetParameterBlockConstant(&x[static_cast<size_t>(b.start)]);
    } else if (!fixed_idx.empty()) {
      problem.SetManifold(&x[static_cast<size_t>(b.start)], new ceres::SubsetManifold(b.size, fixed_idx));
    }
  }
  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  // dense: Eigen's Householder QR. (The normal equations or LAPACK's QR are faster but end
  // the solves with the KR 16's compliance or a second station by "minimum trust region
  // radius" after a dozen steps that the rounding rejects; Eigen's ends by step size.)
  so.linear_solver_type = pb.sparse ? ceres::SPARSE_NORMAL_CHOLESKY : ceres::DENSE_QR;
  so.max_num_iterations = options.max_iterations;
  so.function_tolerance = options.function_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  if (pb.sparse) {
    // hundreds of smoothed map coefficients: stop when the cost changes by less than 1e-9
    // relative (the maps' values then move by far less than their uncertainty)
    so.function_tolerance = std::max(so.function_tolerance, 1e-9);
    so.parameter_tolerance = std::max(so.parameter_tolerance, 1e-8);
    so.initial_trust_region_radius = kJointMapInitialRadius;
  }
  if (getenv("ACCURA_DEBUG_ITER")) so.minimizer_progress_to_stdout = true;
  so.gradient_tolerance = 1e-16;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary cs;
  ceres::Solve(so, &problem, &cs);
  for (size_t k = 0; k < pb.P; ++k) setParameter(pb.model.deviations, pb.layout[k], x[k]);
  pb.data0 = inStationZero(pb.data, pb.st, x);
  SolveResult res;
  res.termination = std::string(ceres::TerminationTypeToString(cs.termination_type)) +
                    (cs.message.empty() ? "" : ": " + cs.message);
  res.iterations = static_cast<int>(cs.iterations.size()) - 1;
  res.failure = cs.termination_type == ceres::FAILURE;
  res.message = cs.message;
  return res;
}

}  // namespace accura::calib::identify_detail
