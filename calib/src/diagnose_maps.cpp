// accura: where the error of the diagnosis lies: maps over the workspace and the joints, the structure scan (diagnose.h, docs/diagnosis.md).
#include "diagnose_internal.h"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <set>

#include "accura/calib/errors.h"
#include "accura/calib/identify.h"
#include "accura/calib/kinematic_core.h"
#include "accura/calib/kinematics.h"
#include "dense_linalg.h"

namespace accura::calib {
namespace diagnose_detail {

// Where: maps, joint profiles, correlations

std::vector<std::vector<Correlation>> Diagnoser::scan(const std::vector<const std::vector<Eigen::Vector3d>*>& Es) const {
  const std::vector<Eigen::Vector3d>& E = *Es.at(0);
  const MeasurementSet& set = has_val_ ? val_ : fit_;
  const int n = M0_.dof();
  const int N = static_cast<int>(E.size());
  // joint Jacobian (position rows, per rad or mm) of each held-out pose at M0
  std::vector<Eigen::Matrix<double, 3, Eigen::Dynamic>> Jq(static_cast<size_t>(N));
  std::vector<Eigen::VectorXd> tau(static_cast<size_t>(N));
  // (what calib's jointJacobian and gravityLoads compute, on the core prepared once)
  const KinematicModel km(M0_);
  KinematicFrames frames, frames_links;
  LinkFrames links;
  Jac6N J;
  for (int i = 0; i < N; ++i) {
    const Measurement& r = set.rows[static_cast<size_t>(i)];
    if (r.q.size() != n) throw ArgumentError("diagnose scan: expected " + std::to_string(n) + " joint values");
    km.evaluate(r.q.data(), r.context, frames);
    km.jacobian(frames, J);
    Jq[i] = J.topRows(3);
    km.evaluate(r.q.data(), r.context, frames_links, nullptr, &links, true);
    tau[i] = Eigen::Map<const Eigen::VectorXd>(links.load.data(), n);
  }
  struct Variable {
    std::string name;
    std::vector<Eigen::VectorXd> f;  // feature functions, each N values
    Eigen::VectorXd raw;
  };
  std::vector<Variable> vars;
  auto centred = [](Eigen::VectorXd v) {
    v.array() -= v.mean();
    return v;
  };
  auto varies = [](const Eigen::VectorXd& v) { return v.size() > 1 && (v.maxCoeff() - v.minCoeff()) > 1e-9; };
  for (int j = 0; j < n; ++j) {
    const bool revolute = M0_.nominal.joints[j].type == JointType::kRevolute;
    Eigen::VectorXd q(N), s(N), c(N);
    for (int i = 0; i < N; ++i) {
      const double v = set.rows[static_cast<size_t>(i)].q[j] * (revolute ? kDegToRad : 1.0);
      q[i] = v;
      s[i] = std::sin(v);
      c[i] = std::cos(v);
    }
    if (!varies(q)) continue;
    // linear in q (a coupling, a scale) and periodic in q apart: each regression keeps few
    // columns, and so the power to see a small dependence in a few hundred poses
    vars.push_back({"q" + std::to_string(j + 1), {centred(q)}, q});
    if (revolute) vars.push_back({"q" + std::to_string(j + 1) + "_periodic", {s, c}, q});
  }
  for (int j = 0; j < n; ++j) {
    Eigen::VectorXd t(N);
    for (int i = 0; i < N; ++i) t[i] = tau[i][j];
    if (varies(t)) vars.push_back({"tau" + std::to_string(j + 1), {centred(t)}, t});
  }
  auto scalar = [&](const std::string& name, bool has, auto get) {
    if (!has) return;
    Eigen::VectorXd v(N);
    for (int i = 0; i < N; ++i) v[i] = get(set.rows[static_cast<size_t>(i)]);
    if (varies(v)) vars.push_back({name, {centred(v)}, v});
  };
  scalar("payload_kg", set.has_payload, [](const Measurement& r) { return r.context.payload_kg; });
  scalar("temp_c", set.has_temperature, [](const Measurement& r) { return r.context.temp_c; });
  scalar("time_s", set.has_time, [](const Measurement& r) { return r.time_s; });
  if (set.has_direction) {
    for (int j = 0; j < n; ++j)
      scalar("dir" + std::to_string(j + 1), true, [j](const Measurement& r) { return double(r.dir[static_cast<size_t>(j)]); });
  } else {
    // the approach direction from the pose sequence: sign of q_j(i) - q_j(i-1)
    for (int j = 0; j < n; ++j) {
      Eigen::VectorXd v(N);
      for (int i = 0; i < N; ++i)
        v[i] = i == 0 ? 1.0 : (set.rows[static_cast<size_t>(i)].q[j] >= set.rows[static_cast<size_t>(i - 1)].q[j] ? 1.0 : -1.0);
      if (varies(v)) vars.push_back({"approach" + std::to_string(j + 1), {centred(v)}, v});
    }
  }
  {
    // the order of measurement (drift): linear and quadratic in the row index
    Eigen::VectorXd v(N);
    for (int i = 0; i < N; ++i) v[i] = N > 1 ? double(i) / double(N - 1) : 0.0;
    const Eigen::VectorXd c = centred(v);
    if (varies(v)) vars.push_back({"order", {c, centred(c.array().square().matrix())}, v});
  }

  // folds for the regression
  std::vector<std::vector<int>> fold_rows(static_cast<size_t>(folds_));
  for (int i = 0; i < N; ++i) fold_rows[static_cast<size_t>(has_val_ ? i % folds_ : fold_[i])].push_back(i);
  // the residual sets as columns of Y (the regressions share their factorisations)
  const Eigen::Index K = static_cast<Eigen::Index>(Es.size());
  Eigen::MatrixXd Y(3 * N, K), D0(N, K);
  for (Eigen::Index k = 0; k < K; ++k) {
    if (static_cast<int>(Es[static_cast<size_t>(k)]->size()) != N) throw ArgumentError("diagnose scan: expected one residual per pose");
    for (int i = 0; i < N; ++i) {
      Y.block<3, 1>(3 * i, k) = (*Es[static_cast<size_t>(k)])[static_cast<size_t>(i)];
      D0(i, k) = (*Es[static_cast<size_t>(k)])[static_cast<size_t>(i)].squaredNorm();
    }
  }
  std::vector<std::vector<Correlation>> out(static_cast<size_t>(K));
  // Added-variable regressors (Frisch-Waugh): the geometric model took from the residual all it
  // could, so what a variable predicts beyond geometry is the part of its regressors outside
  // the geometric parameters' span at these poses. Unprojected, an effect that geometry absorbs
  // in part (a linear coupling of two joints: q_i times joint j's Jacobian column) leaves a
  // residual that its own regressors cannot reproduce, and the scan finds no structure in it.
  // Q: an orthonormal basis of the geometric columns (unit-weight rows, as the residuals).
  Eigen::MatrixXd Q;
  {
    const Eigen::MatrixXd& Jgeo = has_val_ ? JV_ : JF_;
    if (Jgeo.rows() != 3 * static_cast<Eigen::Index>(N))
      throw ArgumentError("diagnose scan: expected " + std::to_string(3 * N) + " Jacobian rows, got " + std::to_string(Jgeo.rows()));
    if (!G_.empty()) {
      Eigen::MatrixXd G = Jgeo(Eigen::all, G_);
      for (Eigen::Index c = 0; c < G.cols(); ++c) {
        const double norm = G.col(c).norm();
        if (norm > 0) G.col(c) /= norm;
      }
      Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(G);
      qr.setThreshold(1e-10);  // relative to the largest pivot of unit-norm columns
      Q = qr.householderQ() * Eigen::MatrixXd::Identity(G.rows(), qr.rank());
    }
  }
  // the regressors of each variable, in one buffer for all (no large allocation per variable)
  size_t most_f = 0;
  for (const Variable& var : vars) most_f = std::max(most_f, var.f.size());
  Eigen::MatrixXd X_all(3 * N, (n + 3) * static_cast<Eigen::Index>(most_f)), Xf, Yf;
  for (const Variable& var : vars) {
    const int per = n + 3;
    const int p = per * static_cast<int>(var.f.size());
    auto X = X_all.leftCols(p);
    for (int i = 0; i < N; ++i) {
      for (size_t k = 0; k < var.f.size(); ++k) {
        const double fv = var.f[k][i];
        X.block(3 * i, static_cast<Eigen::Index>(k) * per, 3, n) = fv * Jq[i];
        X.block(3 * i, static_cast<Eigen::Index>(k) * per + n, 3, 3) = fv * Eigen::Matrix3d::Identity();
      }
    }
    Eigen::VectorXd sc = X.colwise().norm();
    if (Q.cols() > 0) {
      X -= Q * (Q.transpose() * X);
      // a column geometry takes whole (to rounding) carries nothing beyond it
      for (Eigen::Index c = 0; c < p; ++c) {
        const double before = sc[c];
        sc[c] = X.col(c).norm();
        if (!(sc[c] > 1e-8 * before)) {
          X.col(c).setZero();
          sc[c] = 0;
        }
      }
    }
    for (Eigen::Index c = 0; c < p; ++c) sc[c] = sc[c] > 1e-12 ? sc[c] : 1.0;
    X = X * sc.cwiseInverse().asDiagonal();
    const Eigen::MatrixXd XtX = detail::gram(X);
    const Eigen::MatrixXd XtY = X.transpose() * Y;
    const double ridge = 1e-8;  // relative to unit-norm columns: keeps dependent columns solvable
    Eigen::MatrixXd D1(N, K);
    for (const std::vector<int>& rows : fold_rows) {
      if (rows.empty()) continue;
      // the training system: all rows minus the fold's
      Xf.resize(3 * static_cast<Eigen::Index>(rows.size()), p);
      Yf.resize(3 * static_cast<Eigen::Index>(rows.size()), K);
      for (size_t r = 0; r < rows.size(); ++r) {
        Xf.middleRows(3 * static_cast<Eigen::Index>(r), 3) = X.middleRows(3 * rows[r], 3);
        Yf.middleRows(3 * static_cast<Eigen::Index>(r), 3) = Y.middleRows(3 * rows[r], 3);
      }
      Eigen::MatrixXd M = XtX;
      detail::addGramLower(M, Xf, -1.0);
      M.diagonal().array() += ridge;
      const Eigen::MatrixXd C = M.selfadjointView<Eigen::Lower>().ldlt().solve(XtY - Xf.transpose() * Yf);
      const Eigen::MatrixXd Ef = Yf - Xf * C;
      for (size_t r = 0; r < rows.size(); ++r)
        for (Eigen::Index k = 0; k < K; ++k) D1(rows[r], k) = Ef.block<3, 1>(3 * static_cast<Eigen::Index>(r), k).squaredNorm();
    }
    // via: which joint's columns carry the fit on all poses
    Eigen::MatrixXd M = XtX;
    M.diagonal().array() += ridge;
    const Eigen::MatrixXd Call = M.ldlt().solve(XtY);
    for (Eigen::Index k = 0; k < K; ++k) {
      const std::vector<Eigen::Vector3d>& Ek = *Es[static_cast<size_t>(k)];
      const double sst = D0.col(k).sum();
      Correlation co;
      co.variable = var.name;
      co.r2_after = sst > 0 ? 1.0 - D1.col(k).sum() / sst : 0.0;
      co.p_after = pairedGain(D0.col(k), D1.col(k)).p;
      const Eigen::VectorXd c = Call.col(k);
      double best = -1;
      for (int j = 0; j <= n; ++j) {
        Eigen::VectorXd part = Eigen::VectorXd::Zero(3 * N);
        for (size_t f = 0; f < var.f.size(); ++f) {
          const Eigen::Index off = static_cast<Eigen::Index>(f) * per;
          if (j < n) part += X.col(off + j) * c[off + j];
          else part += X.middleCols(off + n, 3) * c.segment(off + n, 3);
        }
        if (part.squaredNorm() > best) {
          best = part.squaredNorm();
          co.via_joint_after = j < n ? j + 1 : 0;
        }
      }
      // Pearson correlation of |e| with the raw variable
      Eigen::VectorXd mag(N);
      for (int i = 0; i < N; ++i) mag[i] = Ek[static_cast<size_t>(i)].norm();
      const Eigen::VectorXd a = mag.array() - mag.mean(), b = var.raw.array() - var.raw.mean();
      const double den = a.norm() * b.norm();
      co.pearson_before = den > 0 ? a.dot(b) / den : 0.0;
      out[static_cast<size_t>(k)].push_back(co);
    }
  }
  return out;
}

void Diagnoser::where() {
  const MeasurementSet& set = has_val_ ? val_ : fit_;
  const int N = static_cast<int>(set.rows.size());
  const Eigen::Isometry3d T_base_world = M0_.T_world_base().inverse();
  std::vector<Eigen::Vector3d> pb(static_cast<size_t>(N));
  for (int i = 0; i < N; ++i) pb[i] = T_base_world * set.rows[static_cast<size_t>(i)].p_world_mm;
  auto rmsCells = [&](const std::vector<int>& cell, int cells, const std::vector<Eigen::Vector3d>& E, std::vector<double>* rms,
                      std::vector<int>* count) {
    std::vector<double> ss(static_cast<size_t>(cells), 0.0);
    count->assign(static_cast<size_t>(cells), 0);
    for (int i = 0; i < N; ++i) {
      if (cell[i] < 0) continue;
      ss[cell[i]] += E[i].squaredNorm();
      (*count)[cell[i]]++;
    }
    rms->assign(static_cast<size_t>(cells), kNaN);
    for (int c = 0; c < cells; ++c)
      if ((*count)[c] > 0) (*rms)[c] = std::sqrt(ss[c] / (*count)[c]);
  };
  auto edges = [](double lo, double hi, int k) {
    std::vector<double> e(static_cast<size_t>(k + 1));
    if (!(hi > lo)) hi = lo + 1;
    for (int i = 0; i <= k; ++i) e[i] = lo + (hi - lo) * i / k;
    return e;
  };
  auto bin = [](const std::vector<double>& e, double v) {
    const int k = static_cast<int>(e.size()) - 1;
    int b = static_cast<int>(std::floor((v - e[0]) / (e[k] - e[0]) * k));
    return std::clamp(b, 0, k - 1);
  };
  const int g = o_.grid_cells;
  for (int plane = 0; plane < 2; ++plane) {
    FieldMap fm;
    fm.plane = plane == 0 ? "base_xy" : "base_rz";
    fm.x_label = plane == 0 ? "x (mm, robot base)" : "radius from axis 1, r (mm)";
    fm.y_label = plane == 0 ? "y (mm, robot base)" : "height z (mm, robot base)";
    std::vector<double> xs(static_cast<size_t>(N)), ys(static_cast<size_t>(N));
    for (int i = 0; i < N; ++i) {
      xs[i] = plane == 0 ? pb[i].x() : std::hypot(pb[i].x(), pb[i].y());
      ys[i] = plane == 0 ? pb[i].y() : pb[i].z();
    }
    fm.x_edges_mm = edges(*std::min_element(xs.begin(), xs.end()), *std::max_element(xs.begin(), xs.end()), g);
    fm.y_edges_mm = edges(*std::min_element(ys.begin(), ys.end()), *std::max_element(ys.begin(), ys.end()), g);
    std::vector<int> cell(static_cast<size_t>(N));
    for (int i = 0; i < N; ++i) cell[i] = bin(fm.y_edges_mm, ys[i]) * g + bin(fm.x_edges_mm, xs[i]);
    rmsCells(cell, g * g, E0_, &fm.rms_before_mm, &fm.count);
    rmsCells(cell, g * g, E1_, &fm.rms_after_mm, &fm.count);
    for (int c = 0; c < g * g; ++c) {
      if (fm.count[c] < 3) continue;
      Region r;
      r.plane = fm.plane;
      r.x0_mm = fm.x_edges_mm[c % g];
      r.x1_mm = fm.x_edges_mm[c % g + 1];
      r.y0_mm = fm.y_edges_mm[c / g];
      r.y1_mm = fm.y_edges_mm[c / g + 1];
      r.count = fm.count[c];
      r.rms_before_mm = fm.rms_before_mm[c];
      r.rms_after_mm = fm.rms_after_mm[c];
      out_.worst_regions.push_back(r);
    }
    out_.fields.push_back(fm);
  }
  std::sort(out_.worst_regions.begin(), out_.worst_regions.end(),
            [](const Region& a, const Region& b) { return a.rms_before_mm > b.rms_before_mm; });
  if (out_.worst_regions.size() > 5) out_.worst_regions.resize(5);
  for (int j = 0; j < M0_.dof(); ++j) {
    JointProfile jp;
    jp.joint = j + 1;
    jp.name = M0_.nominal.joints[j].name;
    jp.unit = M0_.nominal.joints[j].type == JointType::kRevolute ? "deg" : "mm";
    double lo = 1e300, hi = -1e300;
    for (const Measurement& r : set.rows) {
      lo = std::min(lo, r.q[j]);
      hi = std::max(hi, r.q[j]);
    }
    jp.edges = edges(lo, hi, o_.joint_bins);
    std::vector<int> cell(static_cast<size_t>(N));
    for (int i = 0; i < N; ++i) cell[i] = bin(jp.edges, set.rows[static_cast<size_t>(i)].q[j]);
    rmsCells(cell, o_.joint_bins, E0_, &jp.rms_before_mm, &jp.count);
    rmsCells(cell, o_.joint_bins, E1_, &jp.rms_after_mm, &jp.count);
    out_.joints.push_back(jp);
  }
  std::vector<int> idx(static_cast<size_t>(N));
  std::iota(idx.begin(), idx.end(), 0);
  std::sort(idx.begin(), idx.end(), [&](int a, int b) { return E0_[a].squaredNorm() > E0_[b].squaredNorm(); });
  for (int k = 0; k < std::min(5, N); ++k) {
    const int i = idx[k];
    out_.worst_poses.push_back({set.rows[static_cast<size_t>(i)].line, i, E0_[i].norm(), E1_[i].norm()});
  }
}

}  // namespace diagnose_detail
}  // namespace accura::calib
