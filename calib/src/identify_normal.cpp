// accura: the identification with joint maps and no robust loss (identify_internal.h): the
// normal equations accumulated pose by pose, and a Levenberg-Marquardt on them that follows
// Ceres' trust-region iteration (ceres/trust_region_minimizer.cc and
// levenberg_marquardt_strategy.cc, Ceres 2.x) step for step.
//
// Why: a row depends on every geometric parameter but on only 4 coefficients per mapped joint,
// and the maps have hundreds of coefficients. Ceres needs the stacked Jacobian (rows x
// parameters, 100 MB for the real UR10's two series) written at every evaluation; here each
// row's compact Jacobian (RowStack::poseCompact) goes into J^T J and J^T r at once, the
// constant penalty rows' A^T A is added once, and every step is one dense Cholesky
// factorisation of the (parameters x parameters) matrix.
#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "identify_internal.h"
#include "dense_linalg.h"

namespace accura::calib::identify_detail {

FreeColumns::FreeColumns(const Problem& pb) {
  col_of.assign(pb.X, -1);
  for (size_t k = 0; k < pb.X; ++k)
    if (pb.free[k]) {
      col_of[k] = static_cast<int>(n++);
      x_of.push_back(static_cast<int>(k));
    }
}

namespace {

// One row's J^T J (Jt: its weighted free columns transposed, column a's component d at Jt[a + d
// stride]; the first nn of them the non-map columns, the rest map coefficients) into the lower
// triangles of the three parts of the normal matrix: non-map x non-map into the compact G (pg x
// pg, by the columns' compact indices gidx), map x non-map into the compact Mg (a map column's
// pg entries contiguous, at Mg + col * pg), map x map into N itself. The compact parts keep the
// entries every row touches in the cache (scattered straight into N, a megabytes-large matrix,
// they missed it: perf had half of the accumulation on the load and store of N's entry).
template <int Dim>
void accumulateRow(const double* Jt, Eigen::Index stride, int dim, Eigen::Index nn, Eigen::Index nc,
                   const Eigen::Index* cols, const Eigen::Index* gidx, double* G, Eigen::Index pg, double* Mg, double* N,
                   Eigen::Index ld) {
  const int D = Dim > 0 ? Dim : dim;
  auto dot = [&](Eigen::Index a, Eigen::Index c) {
    double v = Jt[c] * Jt[a];
    for (int d = 1; d < D; ++d) v += Jt[c + d * stride] * Jt[a + d * stride];
    return v;
  };
  for (Eigen::Index a = 0; a < nn; ++a)
    for (Eigen::Index c = a; c < nn; ++c) {
      const Eigen::Index ga = gidx[a], gc = gidx[c];
      G[(ga < gc ? ga : gc) * pg + (ga < gc ? gc : ga)] += dot(a, c);
    }
  for (Eigen::Index m = nn; m < nc; ++m) {
    double* row = Mg + cols[m] * pg;
    for (Eigen::Index a = 0; a < nn; ++a) row[gidx[a]] += dot(m, a);
  }
  for (Eigen::Index a = nn; a < nc; ++a)
    for (Eigen::Index c = a; c < nc; ++c) {
      const Eigen::Index ia = cols[a], ic = cols[c];
      N[(ia < ic ? ia : ic) * ld + (ia < ic ? ic : ia)] += dot(a, c);
    }
}

}  // namespace

double rowNormalEquations(const Problem& pb, const RobotModel& model, const std::vector<double>& x,
                          const FreeColumns& fc, Eigen::MatrixXd* N, Eigen::VectorXd* g, Eigen::VectorXd* r) {
  RowStack rows(model, pb.plan, pb.st);
  if (N) N->setZero(fc.n, fc.n);
  if (g) g->setZero(fc.n);
  if (r) r->resize(pb.m_eq);
  // the free columns' compact indices among the non-map ones (-1: a map coefficient) and back
  std::vector<Eigen::Index> compact(static_cast<size_t>(fc.n), -1), non_map;
  for (Eigen::Index c = 0; c < fc.n; ++c)
    if (!pb.isMap(static_cast<size_t>(fc.x_of[static_cast<size_t>(c)]))) {
      compact[static_cast<size_t>(c)] = static_cast<Eigen::Index>(non_map.size());
      non_map.push_back(c);
    }
  const Eigen::Index pg = static_cast<Eigen::Index>(non_map.size());
  Eigen::MatrixXd G, Mg;
  if (N) {
    G.setZero(pg, pg);
    Mg.setZero(pg, fc.n);  // column c: map column c's entries
  }
  // JwT: the row's weighted free columns, transposed (a component's values contiguous over the
  // columns), the non-map ones first
  Eigen::MatrixXd JwT;
  Eigen::VectorXd ed;
  std::vector<Eigen::Index> cols, gidx;
  std::vector<int> order;
  double ss = 0;
  Eigen::Index row = 0;
  const Eigen::Index ld = N ? N->outerStride() : 0;
  for (size_t i = 0; i < pb.data.rows.size(); ++i) {
    const Measurement& meas = pb.data.rows[i];
    const RowWeights& w = pb.weights[i];
    const int dim = w.dim;
    const Eigen::Isometry3d T = N ? rows.poseCompact(x, meas, i) : rows.pose(x, meas, i, false);
    ed = w.w.cwiseProduct(rowError(T, meas, dim)).head(dim);
    ss += ed.squaredNorm();
    if (r) r->segment(row, dim) = ed;
    row += dim;
    if (!N) continue;
    // the free columns of this row: the non-map ones, then the map coefficients
    cols.clear();
    gidx.clear();
    order.clear();
    const std::vector<int>& idx = rows.idx();
    for (int pass = 0; pass < 2; ++pass)
      for (size_t k = 0; k < idx.size(); ++k) {
        if (idx[k] < 0) continue;
        const int c = fc.col_of[static_cast<size_t>(idx[k])];
        if (c < 0 || (compact[static_cast<size_t>(c)] >= 0) != (pass == 0)) continue;
        order.push_back(static_cast<int>(k));
        cols.push_back(c);
        if (pass == 0) gidx.push_back(compact[static_cast<size_t>(c)]);
      }
    const Eigen::Index nc = static_cast<Eigen::Index>(cols.size()), nn = static_cast<Eigen::Index>(gidx.size());
    JwT.resize(nc, dim);
    for (Eigen::Index a = 0; a < nc; ++a)
      JwT.row(a) = w.w.head(dim).cwiseProduct(rows.Jc().col(order[static_cast<size_t>(a)]).head(dim)).transpose();
    if (g) {
      for (Eigen::Index a = 0; a < nc; ++a) (*g)[cols[static_cast<size_t>(a)]] += JwT.row(a).dot(ed);
    }
    if (dim == 3)
      accumulateRow<3>(JwT.data(), nc, dim, nn, nc, cols.data(), gidx.data(), G.data(), pg, Mg.data(), N->data(), ld);
    else if (dim == 6)
      accumulateRow<6>(JwT.data(), nc, dim, nn, nc, cols.data(), gidx.data(), G.data(), pg, Mg.data(), N->data(), ld);
    else
      accumulateRow<0>(JwT.data(), nc, dim, nn, nc, cols.data(), gidx.data(), G.data(), pg, Mg.data(), N->data(), ld);
  }
  if (N) {
    // the compact parts into N's lower triangle (a pair's larger column index is the row)
    double* Nd = N->data();
    for (Eigen::Index b = 0; b < pg; ++b)
      for (Eigen::Index a = b; a < pg; ++a) {
        const Eigen::Index ca = non_map[static_cast<size_t>(a)], cb = non_map[static_cast<size_t>(b)];
        Nd[std::min(ca, cb) * ld + std::max(ca, cb)] += G(a, b);
      }
    for (Eigen::Index c = 0; c < fc.n; ++c) {
      if (compact[static_cast<size_t>(c)] >= 0) continue;
      for (Eigen::Index a = 0; a < pg; ++a) {
        const Eigen::Index ca = non_map[static_cast<size_t>(a)];
        Nd[std::min(ca, c) * ld + std::max(ca, c)] += Mg(a, c);
      }
    }
  }
  return 0.5 * ss;
}

Eigen::VectorXd penaltyValues(const Problem& pb, const std::vector<double>& x) {
  Eigen::VectorXd v = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(pb.penalties.size()));
  for (size_t k = 0; k < pb.penalties.size(); ++k)
    for (const auto& t : pb.penalties[k].terms) v[static_cast<Eigen::Index>(k)] += t.second * x[static_cast<size_t>(t.first)];
  return v;
}

void addPenaltyNormal(const Problem& pb, const FreeColumns& fc, const Eigen::VectorXd* value, Eigen::MatrixXd* N,
                      Eigen::VectorXd* g) {
  for (size_t k = 0; k < pb.penalties.size(); ++k) {
    const auto& terms = pb.penalties[k].terms;
    for (const auto& a : terms) {
      const int ca = fc.col_of[static_cast<size_t>(a.first)];
      if (ca < 0) continue;
      if (g) (*g)[ca] += a.second * (*value)[static_cast<Eigen::Index>(k)];
      if (!N) continue;
      for (const auto& b : terms) {
        const int cb = fc.col_of[static_cast<size_t>(b.first)];
        if (cb >= ca) (*N)(cb, ca) += a.second * b.second;  // the lower triangle
      }
    }
  }
}

namespace {

std::string format(const char* fmt, double a, double b) {
  char buf[200];
  std::snprintf(buf, sizeof buf, fmt, a, b);
  return buf;
}

// Ceres' Levenberg-Marquardt step in the scaled variables: (Ns + diagonal / radius) z = gs,
// step = -z (Ns: its lower triangle; M: the workspace, factorised in place), *model_change the
// decrease the linear model predicts. False: an invalid step (no factorisation, or no
// predicted decrease).
bool lmStep(const Eigen::MatrixXd& Ns, const Eigen::VectorXd& gs, const Eigen::VectorXd& diagonal, double radius,
            Eigen::MatrixXd& M, Eigen::VectorXd* step, double* model_change) {
  M.resize(Ns.rows(), Ns.cols());
  M.triangularView<Eigen::Lower>() = Ns;
  M.diagonal() += diagonal / radius;
  if (!detail::choleskyInPlace(M)) return false;
  *step = -gs;
  detail::choleskySolveInPlace(M, *step);
  const Eigen::VectorXd Nstep = Ns.selfadjointView<Eigen::Lower>() * *step;
  *model_change = -(step->dot(gs) + 0.5 * step->dot(Nstep));
  return step->allFinite() && *model_change > 0;
}

}  // namespace

SolveResult solveNormal(Problem& pb, const IdentifyOptions& options) {
  // Ceres' settings as solve() makes them for joint maps (and its defaults)
  const double function_tolerance = std::max(options.function_tolerance, 1e-9);
  const double parameter_tolerance = std::max(options.parameter_tolerance, 1e-8);
  const double gradient_tolerance = 1e-16, min_relative_decrease = 1e-3;
  const double min_radius = 1e-32, max_radius = 1e16, min_diagonal = 1e-6, max_diagonal = 1e32;
  const int max_invalid = 5;

  const FreeColumns fc(pb);
  const Eigen::Index n = fc.n;
  // x's norm in Ceres counts every entry of a parameter block with a free entry (the fixed
  // ones of a partly fixed block included)
  std::vector<Block> blocks;
  const std::vector<int> block_of = parameterBlocks(pb, &blocks);
  std::vector<bool> active(blocks.size(), false);
  for (size_t k = 0; k < pb.X; ++k)
    if (pb.free[k]) active[static_cast<size_t>(block_of[k])] = true;
  auto norm = [&](const std::vector<double>& v) {
    double s = 0;
    for (size_t k = 0; k < pb.X; ++k)
      if (active[static_cast<size_t>(block_of[k])]) s += v[k] * v[k];
    return std::sqrt(s);
  };

  // the penalty rows are linear: A^T A once (from their few terms: A is sparse). The (n x n)
  // matrices are the problem's workspaces, kept for every solve of it (a fresh allocation of
  // megabytes has its pages faulted in and cleared again each time); lower triangles only.
  Eigen::MatrixXd& AtA = pb.normal_AtA;
  AtA.setZero(n, n);
  addPenaltyNormal(pb, fc, nullptr, &AtA, nullptr);

  RobotModel model = pb.model;
  // cost at xs; with N and g also the normal equations (penalty rows included)
  auto evaluate = [&](const std::vector<double>& xs, Eigen::MatrixXd* N, Eigen::VectorXd* g) {
    for (size_t k = 0; k < pb.P; ++k) setParameter(model.deviations, pb.layout[k], xs[k]);
    const Eigen::VectorXd pv = penaltyValues(pb, xs);
    const double cost = rowNormalEquations(pb, model, xs, fc, N, g, nullptr) + 0.5 * pv.squaredNorm();
    if (N) {
      N->triangularView<Eigen::Lower>() += AtA;
      addPenaltyNormal(pb, fc, &pv, nullptr, g);
    }
    return cost;
  };

  std::vector<double>& x = pb.x;
  // Ns: the normal matrix, scaled in place after each evaluation
  Eigen::MatrixXd &Ns = pb.normal_N, &M = pb.normal_M;
  Eigen::VectorXd g;
  double cost = evaluate(x, &Ns, &g);
  // Jacobi scaling, from the first Jacobian
  const Eigen::VectorXd scale = (Eigen::VectorXd::Ones(n) + Ns.diagonal().cwiseSqrt()).cwiseInverse();
  auto scaled = [&]() {
    for (Eigen::Index c = 0; c < n; ++c)
      Ns.col(c).tail(n - c) = (Ns.col(c).tail(n - c).cwiseProduct(scale.tail(n - c))) * scale[c];
    return Eigen::VectorXd(scale.cwiseProduct(g));
  };
  Eigen::VectorXd gs = scaled();
  double gmax = n > 0 ? g.cwiseAbs().maxCoeff() : 0.0;

  double radius = kJointMapInitialRadius, decrease_factor = 2, x_norm = -1;  // Ceres: no norm before a first step
  bool successful = true, reuse_diagonal = false;
  int iteration = 0, invalid = 0;
  Eigen::VectorXd diagonal;
  SolveResult res;
  std::string type = "NO_CONVERGENCE";
  std::vector<double> candidate;
  while (true) {
    // end of an iteration: its checks
    res.iterations = iteration;
    if (iteration >= options.max_iterations) {
      res.message = "Maximum number of iterations reached. Number of iterations: " + std::to_string(iteration) + ".";
      break;
    }
    if (successful && gmax <= gradient_tolerance) {
      type = "CONVERGENCE";
      res.message = format("Gradient tolerance reached. Gradient max norm: %e <= %e", gmax, gradient_tolerance);
      break;
    }
    if (radius <= min_radius) {
      type = "CONVERGENCE";
      res.message = format("Minimum trust region radius reached. Trust region radius: %e <= %e", radius, min_radius);
      break;
    }
    ++iteration;
    if (!reuse_diagonal) diagonal = Ns.diagonal().cwiseMax(min_diagonal).cwiseMin(max_diagonal);
    Eigen::VectorXd step;
    double model_change = 0;
    if (!lmStep(Ns, gs, diagonal, radius, M, &step, &model_change)) {
      if (++invalid >= max_invalid) {
        type = "FAILURE";
        res.message = "Number of consecutive invalid steps more than Solver::Options::max_num_consecutive_invalid_steps: " +
                      std::to_string(max_invalid);
        res.failure = true;
        res.iterations = iteration - 1;
        break;
      }
      radius /= decrease_factor;
      decrease_factor *= 2;
      reuse_diagonal = true;
      successful = false;
      continue;
    }
    invalid = 0;
    const Eigen::VectorXd delta = step.cwiseProduct(scale);
    candidate = x;
    for (Eigen::Index c = 0; c < n; ++c) candidate[static_cast<size_t>(fc.x_of[static_cast<size_t>(c)])] += delta[c];
    const double candidate_cost = evaluate(candidate, nullptr, nullptr);
    const double step_norm = delta.norm();
    if (step_norm <= parameter_tolerance * (x_norm + parameter_tolerance)) {
      type = "CONVERGENCE";
      res.message = format("Parameter tolerance reached. Relative step_norm: %e <= %e.",
                           step_norm / (x_norm + parameter_tolerance), parameter_tolerance);
      res.iterations = iteration - 1;
      break;
    }
    const double cost_change = cost - candidate_cost;
    if (std::abs(cost_change) <= function_tolerance * cost) {
      type = "CONVERGENCE";
      res.message = format("Function tolerance reached. |cost_change|/cost: %e <= %e", std::abs(cost_change) / cost,
                           function_tolerance);
      res.iterations = iteration - 1;
      break;
    }
    const double rho = cost_change / model_change;
    if (rho > min_relative_decrease) {
      x.swap(candidate);
      x_norm = norm(x);
      cost = evaluate(x, &Ns, &g);
      gs = scaled();
      gmax = g.cwiseAbs().maxCoeff();
      radius = std::min(max_radius, radius / std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3)));
      decrease_factor = 2;
      reuse_diagonal = false;
      successful = true;
    } else {
      radius /= decrease_factor;
      decrease_factor *= 2;
      reuse_diagonal = true;
      successful = false;
    }
  }
  for (size_t k = 0; k < pb.P; ++k) setParameter(pb.model.deviations, pb.layout[k], x[k]);
  pb.data0 = inStationZero(pb.data, pb.st, x);
  res.termination = type + (res.message.empty() ? "" : ": " + res.message);
  return res;
}

}  // namespace accura::calib::identify_detail
