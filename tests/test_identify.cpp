// Identification on simulated campaigns: accuracy against the noise floor, parameters
// against the truth within 3 sigma, compliance, the Hayati form on a tilted UR10, and the
// registration of a tracker standing anywhere.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <Eigen/Cholesky>
#include <array>
#include <random>
#include <thread>

#include "../calib/src/dense_linalg.h"
#include "../calib/src/identify_internal.h"
#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"
#include "accura/calib/identify.h"
#include "accura/calib/joint_map.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/simulate.h"
#include "test_util.h"

namespace accura::calib {
namespace {

struct Campaign {
  RobotModel nominal, truth;
  MeasurementSet fit, validation;
};

Campaign makeCampaign(const std::string& robot, const SimulateOptions& base, int fit_poses, int val_poses) {
  Campaign c;
  c.nominal = test::loadBundled(robot);
  SimulateOptions o = base;
  c.truth = perturbModel(c.nominal, o);
  o.poses = fit_poses;
  c.fit = simulateMeasurements(c.truth, o);
  o.seed = base.seed + 1000;
  o.poses = val_poses;
  c.validation = simulateMeasurements(c.truth, o);
  return c;
}

// The truth expressed in the identified parameter set: structurally dependent deviations
// (j1_d with base_z, ...) show up in the parameters that were kept. Fitted on noise-free
// data of the truth; the fit must reproduce the truth exactly.
std::map<std::string, double> truthInIdentifiedSet(const RobotModel& start, const RobotModel& truth,
                                                   const SimulateOptions& sim, const IdentifyOptions& opt,
                                                   const IdentifySummary& noisy) {
  SimulateOptions o = sim;
  o.noise_mm = 0;
  o.noise_deg = 0;
  o.poses = 600;
  o.seed = sim.seed + 5000;
  const MeasurementSet exact = simulateMeasurements(truth, o);
  IdentifyOptions eo = opt;
  eo.position_std_mm = 0.01;
  IdentifySummary s;
  identify(start, exact, eo, &s);
  EXPECT_LT(s.fit.max_mm, 1e-6) << "the model cannot represent the truth exactly";
  std::vector<std::string> fixed_exact, fixed_noisy;
  for (const auto& f : s.fixed) fixed_exact.push_back(f.name);
  for (const auto& f : noisy.fixed) fixed_noisy.push_back(f.name);
  EXPECT_EQ(fixed_exact, fixed_noisy);
  std::map<std::string, double> out;
  for (const auto& p : s.parameters) out[p.name] = p.value;
  return out;
}

void expectWithin3Sigma(const IdentifySummary& s, const std::map<std::string, double>& truth) {
  int checked = 0;
  for (const auto& p : s.parameters) {
    auto it = truth.find(p.name);
    ASSERT_NE(it, truth.end()) << p.name;
    EXPECT_GT(p.sigma, 0) << p.name;
    EXPECT_LE(std::abs(p.value - it->second), 3 * p.sigma)
        << p.name << ": identified " << p.value << " +- " << p.sigma << " " << p.unit << ", truth " << it->second;
    ++checked;
  }
  EXPECT_GT(checked, 20);
}

SimulateOptions kr16Campaign() {
  SimulateOptions o;
  o.seed = 21;
  o.noise_mm = 0.02;
  o.tool = {80, 40, 150, 0, 0, 0};  // tracker target offset from the flange
  o.set_tool = true;
  return o;
}

// identify's residual stacking (identify_rows.cpp): the Jacobian of a row over x (every
// parameter of the layout, the joint maps' coefficients through their unit columns, and a
// second station's 6 parameters) against central differences of the row's pose, on a KR 16
// with every effect, maps on j1..j3 and rows from both stations.
// Stated stds far above what the residuals show (20 mm where 0.02 mm was meant) are said, with
// the factor; the positions alone are fitted the same (a common scale of the weights cancels).
TEST(Identify, StatedStdsFarAboveTheResidualsAreSaid) {
  SimulateOptions o;
  o.seed = 11;
  o.noise_mm = 0.02;
  const Campaign c = makeCampaign("kuka_kr16", o, 200, 20);
  IdentifyOptions right, wrong;
  right.position_std_mm = 0.02;
  wrong.position_std_mm = 20;
  IdentifySummary sr, sw;
  const RobotModel mr = identify(c.nominal, c.fit, right, &sr), mw = identify(c.nominal, c.fit, wrong, &sw);
  auto said = [](const IdentifySummary& s) {
    for (const std::string& w : s.warnings)
      if (w.rfind("the stated stds are about ", 0) == 0) return w;
    return std::string();
  };
  EXPECT_EQ(said(sr), "") << sr.variance_factor;
  const std::string w = said(sw);
  // variance factor: the per-axis residual variance over (20 mm)^2, about 1e-6 (within the
  // degrees of freedom the parameters take, 6%): the stds about 1000 times the residuals
  const double per_axis = sw.fit.rms_mm * sw.fit.rms_mm / 3;
  EXPECT_NEAR(sw.variance_factor, per_axis / 400, 0.1 * per_axis / 400);
  char expected[64];
  std::snprintf(expected, sizeof expected, "the stated stds are about %.0f times", 1.0 / std::sqrt(sw.variance_factor));
  EXPECT_EQ(w.rfind(expected, 0), 0u) << w;
  EXPECT_NE(w.find("check their unit"), std::string::npos) << w;
  EXPECT_NEAR(evaluate(mw, c.validation).rms_mm, evaluate(mr, c.validation).rms_mm, 1e-9);
}

TEST(Identify, StackedRowJacobianMatchesCentralDifferences) {
  using namespace identify_detail;
  std::mt19937_64 rng(41);
  RobotModel m = test::loadBundled("kuka_kr16");
  m.deviations = Deviations::zero(m.dof(), 2);
  for (int j = 0; j < 3; ++j) {
    const JointSpec& js = m.nominal.joints[static_cast<size_t>(j)];
    m.deviations.joint_map[static_cast<size_t>(j)] = makeJointMap(js.lower, js.upper, 10.0);  // deg
  }
  std::normal_distribution<double> nd(0, 1);
  const std::vector<ParamInfo> layout = parameterLayout(m);
  for (const ParamInfo& p : layout) {
    double s = p.unit == "mm" ? 0.3 : 2e-4;  // mm; rad (or dimensionless)
    if (p.kind == ParamKind::kCompliance) s = 1e-6;
    if (p.kind == ParamKind::kThermal) s = 1e-5;
    setParameter(m.deviations, p, s * nd(rng));
  }
  const JacobianPlan plan = makePlan(m, layout);
  Stations st;
  st.of_row = {0, 1, 1};
  st.extra = 1;
  st.offset = layout.size();
  std::vector<double> x(layout.size() + 6);
  for (size_t k = 0; k < layout.size(); ++k) x[k] = getParameter(m.deviations, layout[k]);
  const double station[6] = {120, -80, 40, 0.1, -0.2, 0.3};  // mm, rad
  for (int k = 0; k < 6; ++k) x[layout.size() + static_cast<size_t>(k)] = station[k];
  for (size_t i = 0; i < st.of_row.size(); ++i) {
    Measurement row;
    row.q = test::randomQ(m, rng);
    row.context.payload_kg = 10;
    row.context.temp_c = 28;
    row.context.dir = std::vector<int>(static_cast<size_t>(m.dof()), 1);
    RowStack stack(m, plan, st);
    const Eigen::Isometry3d T = stack.pose(x, row, i, true);
    const Eigen::MatrixXd J = stack.J();
    ASSERT_EQ(J.cols(), static_cast<Eigen::Index>(x.size()));
    for (size_t k = 0; k < x.size(); ++k) {
      const bool model_param = k < layout.size();
      double h = 1e-6;  // rad, dimensionless, or the station's mm
      if (model_param && layout[k].unit == "mm") h = 1e-4;
      if (!model_param && k < layout.size() + 3) h = 1e-4;
      if (model_param && layout[k].kind == ParamKind::kCompliance) h = 1e-8;
      if (model_param && layout[k].kind == ParamKind::kThermal) h = 1e-8;
      Eigen::Isometry3d Tpm[2];
      for (int side = 0; side < 2; ++side) {
        std::vector<double> xs = x;
        xs[k] += side == 0 ? h : -h;
        RobotModel ms = m;
        if (model_param) setParameter(ms.deviations, layout[k], xs[k]);
        RowStack s2(ms, plan, st);
        Tpm[side] = s2.pose(xs, row, i, false);
      }
      Vector6d fd;
      fd.head<3>() = (Tpm[0].translation() - Tpm[1].translation()) / (2 * h);
      fd.tail<3>() = logSO3(Tpm[0].linear() * Tpm[1].linear().transpose()) / (2 * h);
      const std::string name = model_param ? layout[k].name : "station_" + std::to_string(k - layout.size());
      EXPECT_LT((J.col(static_cast<Eigen::Index>(k)) - fd).norm() / std::max(1.0, fd.norm()), 1e-6)
          << "row " << i << " " << name << "\nanalytic " << J.col(static_cast<Eigen::Index>(k)).transpose()
          << "\nnumeric  " << fd.transpose();
    }
    EXPECT_LT((T.translation() - stack.pose(x, row, i, false).translation()).norm(), 1e-9);  // mm
    // the compact form (the normal equations' rows) holds the same columns, and only zeros
    // elsewhere: so it matches the central differences too
    const Eigen::Isometry3d Tc = stack.poseCompact(x, row, i);
    EXPECT_LT((Tc.translation() - T.translation()).norm(), 1e-12);
    Eigen::MatrixXd Jc = Eigen::MatrixXd::Zero(6, J.cols());
    for (size_t k = 0; k < stack.idx().size(); ++k) {
      ASSERT_GE(stack.idx()[k], 0);
      Jc.col(stack.idx()[k]) += stack.Jc().col(static_cast<Eigen::Index>(k));
    }
    const size_t n_map = static_cast<size_t>(std::count_if(layout.begin(), layout.end(), [](const ParamInfo& p) {
      return p.kind == ParamKind::kJointMap;
    }));
    EXPECT_EQ(stack.idx().size(), layout.size() - n_map + 3 * 4 + (st.of_row[i] > 0 ? 6 : 0));
    EXPECT_LT((Jc - J).norm(), 1e-12 * J.norm());
  }
}

// The joint maps' own Levenberg-Marquardt (identify_normal.cpp, normal equations pose by pose)
// against Ceres' on the same problem (a KR 16 with a cyclic error on j2 and j3, maps on both,
// two stations, the stds estimated: several solves): the same optimum.
TEST(Identify, JointMapSolverReachesCeresOptimum) {
  using namespace identify_detail;
  SimulateOptions sim = kr16Campaign();
  sim.poses = 240;
  Campaign c = makeCampaign("kuka_kr16", sim, 240, 10);
  for (Measurement& r : c.fit.rows)
    for (int j : {1, 2}) r.q[j] += 0.03 * std::sin(17 * r.q[j] * kDegToRad);  // deg
  MeasurementSet a = c.fit, b = c.fit;
  a.rows.resize(140);
  b.rows.erase(b.rows.begin(), b.rows.begin() + 140);
  const Eigen::Isometry3d moved = toIsometry({150, -60, 20, 2, -1, 3});  // the second station
  for (Measurement& r : b.rows) {
    r.p_world_mm = moved * r.p_world_mm;
    r.R_world_tcp = Eigen::Quaterniond(moved.linear() * r.R_world_tcp.toRotationMatrix());
  }
  IdentifyOptions o;
  o.groups = {"geometric", "joint_map:j2+j3@8deg"};
  o.joint_map_smoothing = 0.01;
  IdentifySummary sn, sc;
  const RobotModel mn = identify(c.nominal, {a, b}, o, &sn);
  RobotModel mc;
  {
    CeresForJointMaps ceres;
    mc = identify(c.nominal, {a, b}, o, &sc);
  }
  EXPECT_NE(sn.termination.find("CONVERGENCE"), std::string::npos) << sn.termination;
  EXPECT_NEAR(sn.final_cost, sc.final_cost, 1e-9 * sc.final_cost);
  EXPECT_NEAR(sn.fit.rms_mm, sc.fit.rms_mm, 1e-9 * sc.fit.rms_mm);
  ASSERT_EQ(sn.parameters.size(), sc.parameters.size());
  for (size_t k = 0; k < sn.parameters.size(); ++k) {
    EXPECT_EQ(sn.parameters[k].name, sc.parameters[k].name);
    EXPECT_NEAR(sn.parameters[k].value, sc.parameters[k].value, 1e-6 * sc.parameters[k].sigma) << sc.parameters[k].name;
    EXPECT_NEAR(sn.parameters[k].sigma, sc.parameters[k].sigma, 1e-9 * sc.parameters[k].sigma) << sc.parameters[k].name;
  }
  for (int j : {1, 2}) {
    const JointMap& n = mn.deviations.joint_map[static_cast<size_t>(j)];
    const JointMap& e = mc.deviations.joint_map[static_cast<size_t>(j)];
    ASSERT_EQ(n.coef.size(), e.coef.size());
    double amp = 0;
    for (double v : e.coef) amp = std::max(amp, std::abs(v));
    EXPECT_GT(amp, 1e-4);  // rad: the maps took the cyclic error
    for (size_t k = 0; k < n.coef.size(); ++k) EXPECT_NEAR(n.coef[k], e.coef[k], 1e-6 * amp) << "j" << j + 1 << " " << k;
  }
  const Eigen::Isometry3d dn = sn.T_world_base_per_set[1], dc = sc.T_world_base_per_set[1];
  EXPECT_LT((dn.translation() - dc.translation()).norm(), 1e-7);  // mm
}

// The dense Cholesky of the joint-map systems and J^T J of the diagnosis (LAPACK and BLAS
// through OpenBLAS) against Eigen's, on a symmetric positive definite matrix of the maps' size:
// the same factor, solution and product to the rounding; a matrix that is not positive definite
// is refused, not factorised.
TEST(Identify, DenseLinearAlgebraAgreesWithEigen) {
  std::mt19937 rng(5);
  std::normal_distribution<double> g(0.0, 1.0);
  const Eigen::Index n = 300;
  Eigen::MatrixXd A(n + 20, n);
  for (Eigen::Index c = 0; c < A.cols(); ++c)
    for (Eigen::Index r = 0; r < A.rows(); ++r) A(r, c) = g(rng);
  const Eigen::MatrixXd S = A.transpose() * A;
  Eigen::MatrixXd L = S;
  ASSERT_TRUE(detail::choleskyInPlace(L));
  const Eigen::LLT<Eigen::MatrixXd> llt(S);
  const Eigen::MatrixXd L_eigen = llt.matrixL();
  EXPECT_LT((Eigen::MatrixXd(L.triangularView<Eigen::Lower>()) - L_eigen).cwiseAbs().maxCoeff(), 1e-10 * L_eigen.cwiseAbs().maxCoeff());
  EXPECT_EQ(L(0, n - 1), S(0, n - 1));  // the strictly upper triangle is not touched
  Eigen::MatrixXd B(n, 2);
  for (Eigen::Index k = 0; k < B.size(); ++k) B.data()[k] = g(rng);
  Eigen::MatrixXd X = B;
  detail::choleskySolveInPlace(L, X);
  EXPECT_LT((S * X - B).cwiseAbs().maxCoeff(), 1e-8 * B.cwiseAbs().maxCoeff());
  Eigen::VectorXd x = B.col(0);
  detail::choleskySolveInPlace(L, x);
  EXPECT_LT((x - X.col(0)).cwiseAbs().maxCoeff(), 1e-12 * X.col(0).cwiseAbs().maxCoeff());
  Eigen::MatrixXd indefinite = S;
  indefinite(n / 2, n / 2) = -1;
  EXPECT_FALSE(detail::choleskyInPlace(indefinite));
  Eigen::MatrixXd rectangular(3, 4);
  EXPECT_THROW(detail::choleskyInPlace(rectangular), ArgumentError);
  Eigen::MatrixXd wrong_rows(n - 1, 1);
  EXPECT_THROW(detail::choleskySolveInPlace(L, wrong_rows), ArgumentError);
  // J^T J on the lower triangle, added with a factor; the upper triangle untouched
  Eigen::MatrixXd G = Eigen::MatrixXd::Constant(n, n, 7.0);
  detail::addGramLower(G, A, -0.5);
  const Eigen::MatrixXd expected = Eigen::MatrixXd::Constant(n, n, 7.0) - 0.5 * S;
  EXPECT_LT((Eigen::MatrixXd(G.triangularView<Eigen::Lower>()) - Eigen::MatrixXd(expected.triangularView<Eigen::Lower>()))
                .cwiseAbs()
                .maxCoeff(),
            1e-12 * S.cwiseAbs().maxCoeff());
  EXPECT_EQ(G(0, n - 1), 7.0);
  EXPECT_THROW(detail::addGramLower(G, rectangular), ArgumentError);
}

// The blocked Cholesky (blocks of 64 columns) on a size that ends in a partial block, against
// Eigen's LLT, and a non-positive pivot in that last block; the row-block scatter of J^T J into
// a larger matrix's lower triangle (the joint maps' accumulation) against the dense product.
TEST(Identify, DenseLinearAlgebraBlockedCholeskyAndScatteredGram) {
  std::mt19937 rng(9);
  std::normal_distribution<double> g(0.0, 1.0);
  const Eigen::Index n = 130;  // 64 + 64 + 2
  Eigen::MatrixXd A(n + 5, n);
  for (Eigen::Index k = 0; k < A.size(); ++k) A.data()[k] = g(rng);
  const Eigen::MatrixXd S = A.transpose() * A;
  Eigen::MatrixXd L = S;
  ASSERT_TRUE(detail::choleskyInPlace(L));
  const Eigen::MatrixXd L_eigen = Eigen::LLT<Eigen::MatrixXd>(S).matrixL();
  EXPECT_LT((Eigen::MatrixXd(L.triangularView<Eigen::Lower>()) - L_eigen).cwiseAbs().maxCoeff(), 1e-12 * L_eigen.cwiseAbs().maxCoeff());
  Eigen::MatrixXd last = S;
  last(n - 1, n - 1) = 0;  // the Schur complement's last pivot <= 0
  EXPECT_FALSE(detail::choleskyInPlace(last));

  const Eigen::Index big = 40;
  for (const int dim : {3, 6, 2}) {
    SCOPED_TRACE(dim);
    const Eigen::Index nc = 9;
    const std::vector<Eigen::Index> idx = {17, 3, 30, 4, 39, 0, 22, 11, 5};  // distinct, unordered
    Eigen::MatrixXd J(dim, nc);  // the row block's columns
    for (Eigen::Index k = 0; k < J.size(); ++k) J.data()[k] = g(rng);
    const Eigen::MatrixXd Jt = J.transpose();
    Eigen::MatrixXd N = Eigen::MatrixXd::Constant(big, big, 2.0);
    detail::scatterGramLower(N.data(), N.outerStride(), Jt.data(), nc, dim, idx.data(), -0.5);
    Eigen::MatrixXd expected = Eigen::MatrixXd::Constant(big, big, 2.0);
    for (Eigen::Index a = 0; a < nc; ++a)
      for (Eigen::Index c = 0; c < nc; ++c) {
        const Eigen::Index r = idx[static_cast<size_t>(a)], k = idx[static_cast<size_t>(c)];
        if (r >= k) expected(r, k) -= 0.5 * J.col(a).dot(J.col(c));  // the lower triangle only
      }
    EXPECT_LT((N - expected).cwiseAbs().maxCoeff(), 1e-14);
  }
}

// The same from two threads at once: Debian's single-threaded OpenBLAS is not safe for that
// (two calls may share a work buffer; a review measured about 1 wrong J^T J in 1000 this way),
// so every call is made under one lock. Each thread's results must equal the sequential ones
// to the last bit.
TEST(Identify, DenseLinearAlgebraIsSafeOnSeveralThreads) {
  std::mt19937 rng(9);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Eigen::MatrixXd> J(2, Eigen::MatrixXd(48, 24)), expected_gram(2), expected_factor(2);
  for (auto& m : J)
    for (Eigen::Index k = 0; k < m.size(); ++k) m.data()[k] = g(rng);
  for (int t = 0; t < 2; ++t) {
    expected_gram[t] = Eigen::MatrixXd::Zero(24, 24);
    detail::addGramLower(expected_gram[t], J[t]);
    expected_factor[t] = expected_gram[t];
    ASSERT_TRUE(detail::choleskyInPlace(expected_factor[t]));
  }
  std::array<int, 2> wrong{0, 0};
  auto work = [&](int t) {
    for (int k = 0; k < 5000; ++k) {
      Eigen::MatrixXd G = Eigen::MatrixXd::Zero(24, 24);
      detail::addGramLower(G, J[t]);
      Eigen::MatrixXd L = G;
      const bool ok = detail::choleskyInPlace(L);
      if (!ok || G != expected_gram[t] || L != expected_factor[t]) ++wrong[t];
    }
  };
  std::thread other(work, 1);
  work(0);
  other.join();
  EXPECT_EQ(wrong[0], 0);
  EXPECT_EQ(wrong[1], 0);
}

// With joint maps the Levenberg-Marquardt takes Gauss-Newton steps and ends because its steps
// (or the cost's changes) have become negligible, not because a crawl dipped under the
// tolerance. At Ceres' default initial trust-region radius, 1e4, the damping exceeded the
// smallest eigenvalues of the smoothed maps' system: every step fell short (rho = 1), and this
// solve took 7 steps and ended at a relative step of 7.2e-9 (tolerance 1e-8), the cost still
// falling by a third of the last step's decrease. Now the geometry (maps held at zero) and then
// the maps (the geometry held) take 2 steps each; the second stage ends with a relative cost
// change of 2.5e-11 (tolerance 1e-9).
TEST(Identify, JointMapSolveEndsAtTheOptimum) {
  SimulateOptions sim = kr16Campaign();
  sim.poses = 400;
  Campaign c = makeCampaign("kuka_kr16", sim, 400, 10);
  for (Measurement& r : c.fit.rows)
    for (int j : {1, 2}) r.q[j] += 0.03 * std::sin(17 * r.q[j] * kDegToRad);  // deg
  IdentifyOptions o;
  o.groups = {"geometric", "joint_map:j2+j3@3deg"};
  o.joint_map_smoothing = 0.003;
  o.position_std_mm = 0.02;  // given, and no unmodelled-error term: one solve per stage on fixed weights
  o.orientation_std_deg = 0.01;
  o.model_error = false;
  IdentifySummary s;
  identify(c.nominal, c.fit, o, &s);
  double last = std::numeric_limits<double>::infinity();
  for (const std::string key : {"Relative step_norm: ", "|cost_change|/cost: "}) {
    const size_t at = s.termination.find(key);
    if (at != std::string::npos) last = std::stod(s.termination.substr(at + key.size()));
  }
  EXPECT_LT(last, 1e-10) << s.termination;  // the tolerances are 1e-8 (step) and 1e-9 (cost)
  EXPECT_LE(s.iterations, 4);
}

TEST(Identify, Kr16GeometricReachesTheNoiseFloorAndTheTruth) {
  const SimulateOptions sim = kr16Campaign();
  Campaign c = makeCampaign("kuka_kr16", sim, 300, 300);
  // the identification starts from the nominal robot with the nominal target offset, with
  // the tracker 3 m away and turned 30 deg: only the closed-form registration finds it
  c.nominal.nominal.T_flange_tcp = toIsometry(sim.tool);
  IdentifyOptions opt;
  IdentifySummary s;
  const RobotModel cal = identify(c.nominal, c.fit, opt, &s);
  EXPECT_NE(s.termination.find("CONVERGENCE"), std::string::npos) << s.termination;
  // noise-only floor: the true robot against the same validation measurements
  const ErrorStats floor = evaluate(c.truth, c.validation);
  const ErrorStats val = evaluate(cal, c.validation);
  EXPECT_NEAR(floor.rms_mm, 0.02 * std::sqrt(3.0), 0.004);
  EXPECT_LE(val.rms_mm, 1.10 * floor.rms_mm) << "floor " << floor.rms_mm;
  // the nominal model is about a millimetre off: the test data is not trivial
  IdentifyOptions reg;
  reg.groups = {"base", "tool"};
  const ErrorStats nominal = evaluate(identify(c.nominal, c.fit, reg, nullptr), c.validation);
  EXPECT_GT(nominal.rms_mm, 0.5);
  // structural duplicates are reported by name
  std::map<std::string, std::string> fixed;
  for (const auto& f : s.fixed) fixed[f.name] = f.reason;
  ASSERT_TRUE(fixed.count("j1_d"));
  EXPECT_NE(fixed["j1_d"].find("base_z"), std::string::npos) << fixed["j1_d"];
  ASSERT_TRUE(fixed.count("j1_offset"));
  EXPECT_NE(fixed["j1_offset"].find("base_rz"), std::string::npos);
  EXPECT_TRUE(std::isfinite(s.condition_number));
  EXPECT_LT(s.condition_number, 1e4);
  EXPECT_FALSE(std::isfinite(s.condition_number_all) && s.condition_number_all < 1e8);
  EXPECT_GT(s.observability_index, 0);
  EXPECT_NEAR(s.variance_factor, 1.0, 0.2);  // std estimated from residuals
  expectWithin3Sigma(s, truthInIdentifiedSet(c.nominal, c.truth, sim, opt, s));
}

// Positions without std columns: the std is estimated from the residuals, and each estimate
// scales every row's weight alike, which leaves the least-squares solution where it is. The
// identification solves once, as with the std stated (no estimate, no unmodelled-error term),
// and ends at the same parameters (the solves the estimates used to add confirmed them with
// steps of ~1e-15 relative).
TEST(Identify, AWeightingThatScalesEveryRowAlikeIsNotSolvedAgain) {
  const SimulateOptions sim = kr16Campaign();
  Campaign c = makeCampaign("kuka_kr16", sim, 300, 10);
  c.nominal.nominal.T_flange_tcp = toIsometry(sim.tool);
  IdentifyOptions estimated;  // defaults: std from the residuals
  IdentifySummary se, sg;
  const RobotModel a = identify(c.nominal, c.fit, estimated, &se);
  IdentifyOptions stated;
  stated.position_std_mm = 0.02;
  stated.model_error = false;
  const RobotModel b = identify(c.nominal, c.fit, stated, &sg);
  EXPECT_EQ(se.weighting, "position: std estimated from the residuals");
  EXPECT_EQ(sg.weighting, "position: std given");
  ASSERT_EQ(se.parameters.size(), sg.parameters.size());
  for (size_t k = 0; k < se.parameters.size(); ++k)
    EXPECT_NEAR(se.parameters[k].value, sg.parameters[k].value, 1e-9 * std::max(1.0, std::abs(sg.parameters[k].value)))
        << se.parameters[k].name;  // display units (mm, deg)
  EXPECT_EQ(se.iterations, sg.iterations);
  KinematicWorkspace wa, wb;
  for (const Measurement& m : c.fit.rows)
    EXPECT_LT((forwardKinematics(a, m.q, m.context, wa).translation() - forwardKinematics(b, m.q, m.context, wb).translation()).norm(),
              1e-9);  // mm
}

TEST(Identify, MeasurementsInOtherUnitsAreRefusedNotFitted) {
  // positions in metres or joint angles in radians: the closed-form registration cannot bring
  // them near the model; identify says so instead of writing a model shrunk a thousandfold
  const SimulateOptions sim = kr16Campaign();
  Campaign c = makeCampaign("kuka_kr16", sim, 200, 10);
  c.nominal.nominal.T_flange_tcp = toIsometry(sim.tool);
  const IdentifyOptions opt;
  IdentifySummary good;
  identify(c.nominal, c.fit, opt, &good);
  EXPECT_LT(good.registration_rms_mm, 5.0);  // the same data in mm and deg: registered within a few mm
  auto refused = [&](const MeasurementSet& m) -> std::string {
    try {
      identify(c.nominal, m, opt, nullptr);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  MeasurementSet metres = c.fit, radians = c.fit;
  for (Measurement& r : metres.rows) r.p_world_mm *= 1e-3;
  for (Measurement& r : radians.rows) r.q *= kDegToRad;
  EXPECT_NE(refused(metres).find("expected measurements of KUKA KR 16 in mm and deg"), std::string::npos) << refused(metres);
  // the factor a unit leaves is found and said (before: "check the units (positions in mm, joint angles in deg)")
  EXPECT_NE(refused(radians).find("the joint angles fit at 180/pi times the values read: angles in rad read as deg"), std::string::npos)
      << refused(radians);
  EXPECT_NE(refused(metres).find("positions in m read as mm"), std::string::npos) << refused(metres);
}

TEST(Identify, Kr16WithComplianceAndSeveralPayloads) {
  SimulateOptions sim = kr16Campaign();
  sim.seed = 33;
  sim.effects = {"geometric", "joint_compliance"};
  sim.payloads_kg = {0, 8, 16};
  Campaign c = makeCampaign("kuka_kr16", sim, 300, 300);
  c.nominal.nominal.T_flange_tcp = toIsometry(sim.tool);
  IdentifyOptions opt;
  opt.groups = {"geometric", "joint_compliance"};
  IdentifySummary s;
  const RobotModel cal = identify(c.nominal, c.fit, opt, &s);
  const ErrorStats floor = evaluate(c.truth, c.validation);
  const ErrorStats val = evaluate(cal, c.validation);
  EXPECT_LE(val.rms_mm, 1.10 * floor.rms_mm) << "floor " << floor.rms_mm;
  // without compliance in the model the same data is clearly worse
  IdentifyOptions geo;
  IdentifySummary sg;
  const ErrorStats val_geo = evaluate(identify(c.nominal, c.fit, geo, &sg), c.validation);
  EXPECT_GT(val_geo.rms_mm, 1.5 * val.rms_mm);
  bool has_c2 = false;
  for (const auto& p : s.parameters) has_c2 |= p.name == "j2_compliance";
  EXPECT_TRUE(has_c2);
  expectWithin3Sigma(s, truthInIdentifiedSet(c.nominal, c.truth, sim, opt, s));
}

TEST(Identify, Ur10TiltedAxesNeedTheHayatiForm) {
  SimulateOptions sim;
  sim.seed = 44;
  sim.noise_mm = 0.02;
  sim.tool = {0, 60, 110, 0, 0, 0};
  sim.set_tool = true;
  Campaign c;
  c.nominal = test::loadBundled("ur10");
  c.nominal.nominal.T_flange_tcp = toIsometry(sim.tool);
  c.truth = perturbModel(c.nominal, sim);
  // joints 2-3-4 tilted by 0.05 deg from parallel (about the y axes of the Hayati form)
  for (int j : {1, 2}) c.truth.deviations.links[j].dbeta_rad = 0.05 * kDegToRad;
  sim.poses = 300;
  c.fit = simulateMeasurements(c.truth, sim);
  sim.seed += 1000;
  c.validation = simulateMeasurements(c.truth, sim);
  const ErrorStats floor = evaluate(c.truth, c.validation);

  IdentifySummary hay;
  const RobotModel cal = identify(c.nominal, c.fit, IdentifyOptions{}, &hay);
  EXPECT_LE(evaluate(cal, c.validation).rms_mm, 1.10 * floor.rms_mm);
  EXPECT_LT(hay.condition_number, 1e4);
  std::map<std::string, double> value;
  for (const auto& p : hay.parameters) value[p.name] = p.value;
  ASSERT_TRUE(value.count("j2_beta") && value.count("j3_beta"));

  // Forced DH on the same data: the d of parallel axes are rank deficient, and reported so.
  RobotModel dh = RobotModel::fromDefinition(c.nominal.nominal, FormPolicy::kDHOnly);
  IdentifySummary sdh;
  const RobotModel cal_dh = identify(dh, c.fit, IdentifyOptions{}, &sdh);
  EXPECT_FALSE(std::isfinite(sdh.condition_number_all) && sdh.condition_number_all < 1e8)
      << sdh.condition_number_all;
  std::map<std::string, std::string> fixed;
  for (const auto& f : sdh.fixed) fixed[f.name] = f.reason;
  ASSERT_TRUE(fixed.count("j3_d")) << "DH d of a link with parallel axes must be reported";
  EXPECT_NE(fixed["j3_d"].find("duplicates"), std::string::npos) << fixed["j3_d"];
  // and DH cannot represent the tilt: its held-out error stays well above the floor
  EXPECT_GT(evaluate(cal_dh, c.validation).rms_mm, 3 * floor.rms_mm);
}

TEST(Identify, RegistrationFindsATrackerStandingAnywhere) {
  // tracker metres away and turned by large angles in every axis
  SimulateOptions sim;
  sim.seed = 7;
  sim.station = {-4200, 2600, 1500, 145, -35, 60};
  sim.tool = {50, 0, 200, 0, 0, 0};
  sim.set_tool = true;
  sim.orientation = true;
  sim.noise_deg = 0.003;
  sim.poses = 120;
  Campaign c = makeCampaign("abb_irb120", sim, 120, 100);
  c.nominal.nominal.T_flange_tcp = toIsometry(sim.tool);
  IdentifySummary s;
  const RobotModel cal = identify(c.nominal, c.fit, IdentifyOptions{}, &s);
  const ErrorStats floor = evaluate(c.truth, c.validation);
  const ErrorStats val = evaluate(cal, c.validation);
  EXPECT_LE(val.rms_mm, 1.15 * floor.rms_mm);
  EXPECT_LE(val.rot_rms_deg, 1.15 * floor.rot_rms_deg);
  EXPECT_LT((cal.T_world_base().translation() - toIsometry(sim.station).translation()).norm(), 1.0);
}

TEST(Identify, RobustLossListsTheOutlierRows) {
  SimulateOptions sim = kr16Campaign();
  Campaign c = makeCampaign("kuka_kr16", sim, 200, 10);
  c.nominal.nominal.T_flange_tcp = toIsometry(sim.tool);
  for (size_t i = 0; i < c.fit.rows.size(); ++i) c.fit.rows[i].line = static_cast<int>(i) + 2;
  // three gross outliers (a beam break, a wrong target)
  c.fit.rows[10].p_world_mm.x() += 2.0;
  c.fit.rows[50].p_world_mm.y() -= 1.5;
  c.fit.rows[120].p_world_mm.z() += 3.0;
  IdentifyOptions opt;
  opt.loss = "huber";
  opt.position_std_mm = 0.02;
  IdentifySummary s;
  const RobotModel cal = identify(c.nominal, c.fit, opt, &s);
  EXPECT_EQ(s.downweighted_lines, (std::vector<int>{12, 52, 122}));
  // the fit is not dragged by the outliers: held-out error near the floor
  EXPECT_LE(evaluate(cal, c.validation).rms_mm, 1.3 * evaluate(c.truth, c.validation).rms_mm);
}

TEST(Identify, AGrossRowIsLeftOutAndNamed) {
  // A lost tracker beam reads as a point at the tracker's origin: metres from every other
  // row. Least squares would pull the registration and every parameter after it (the probe:
  // 226 mm fit RMS, j5_alpha -185 deg, exit 0). It is left out, named, and the fit is the
  // fit without it.
  SimulateOptions sim = kr16Campaign();
  Campaign c = makeCampaign("kuka_kr16", sim, 200, 100);
  c.nominal.nominal.T_flange_tcp = toIsometry(sim.tool);
  c.fit.file = "tracker.csv";
  for (size_t i = 0; i < c.fit.rows.size(); ++i) c.fit.rows[i].line = static_cast<int>(i) + 2;
  MeasurementSet clean = c.fit;
  c.fit.rows[17].p_world_mm = Eigen::Vector3d::Zero();
  IdentifySummary s;
  const RobotModel cal = identify(c.nominal, c.fit, IdentifyOptions{}, &s);
  ASSERT_EQ(s.excluded.size(), 1u);
  EXPECT_EQ(s.excluded[0].file, "tracker.csv");
  EXPECT_EQ(s.excluded[0].line, 19);
  EXPECT_GT(s.excluded[0].error_mm, 1000.0);
  ASSERT_FALSE(s.warnings.empty());
  EXPECT_NE(s.warnings[0].find("tracker.csv:19: left out of the fit"), std::string::npos) << s.warnings[0];
  EXPECT_EQ(s.fit.n, 199);
  // the same model as the fit without the row (the expectation on its own)
  clean.rows.erase(clean.rows.begin() + 17);
  const RobotModel expected = identify(c.nominal, clean, IdentifyOptions{}, nullptr);
  EXPECT_NEAR(evaluate(cal, c.validation).rms_mm, evaluate(expected, c.validation).rms_mm, 1e-9);
  EXPECT_LE(evaluate(cal, c.validation).rms_mm, 1.3 * evaluate(c.truth, c.validation).rms_mm);
}

TEST(Identify, ManyGrossRowsAreASecondStationNotGlitches) {
  // 10 % of the rows from a tracker moved by 400 mm: not a glitch to leave out; refused at the
  // first of them
  SimulateOptions sim = kr16Campaign();
  Campaign c = makeCampaign("kuka_kr16", sim, 200, 1);
  c.nominal.nominal.T_flange_tcp = toIsometry(sim.tool);
  c.fit.file = "two_stations.csv";
  for (size_t i = 0; i < c.fit.rows.size(); ++i) c.fit.rows[i].line = static_cast<int>(i) + 2;
  for (size_t i = 180; i < 200; ++i) c.fit.rows[i].p_world_mm.x() += 400.0;
  try {
    identify(c.nominal, c.fit, IdentifyOptions{}, nullptr);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "two_stations.csv");
    EXPECT_EQ(e.line(), 182);
    EXPECT_NE(std::string(e.what()).find("found 20 of 200 rows"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("a second station"), std::string::npos) << e.what();
  }
}

TEST(Identify, TooFewRowsIsAnInputError) {
  SimulateOptions sim = kr16Campaign();
  Campaign c = makeCampaign("kuka_kr16", sim, 8, 1);
  c.fit.file = "few.csv";
  try {
    identify(c.nominal, c.fit, IdentifyOptions{}, nullptr);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "few.csv");
    EXPECT_NE(std::string(e.what()).find("too few rows"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("8 rows give 24 equations"), std::string::npos) << e.what();
  }
}

TEST(Identify, OptionsAreValidated) {
  IdentifyOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why));
  o.groups = {"geometric", "elbow_magic"};
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("unknown parameter group 'elbow_magic'"), std::string::npos);
  o.groups = {"base"};
  o.loss = "l1";
  EXPECT_FALSE(o.IsValid(&why));
  o.loss = "none";
  o.groups = {"geometric", "gear_periodic:j1+j2"};
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.groups = {"gear_periodic:1+2"};
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("expected joints as j1+j2+..., found '1'"), std::string::npos) << why;
}

TEST(Identify, AGroupCanBeRestrictedToSomeJoints) {
  SimulateOptions sim = kr16Campaign();
  sim.effects = {"geometric", "joint_compliance"};
  sim.payloads_kg = {0, 16};
  Campaign c = makeCampaign("kuka_kr16", sim, 200, 10);
  c.nominal.nominal.T_flange_tcp = toIsometry(sim.tool);
  IdentifyOptions opt;
  opt.groups = {"geometric", "joint_compliance:j2+j3"};
  IdentifySummary s;
  identify(c.nominal, c.fit, opt, &s);
  std::vector<std::string> compliance;
  for (const auto& p : s.parameters)
    if (p.group == "joint_compliance") compliance.push_back(p.name);
  EXPECT_EQ(compliance, (std::vector<std::string>{"j2_compliance", "j3_compliance"}));
}

TEST(Identify, DataThatNoFrameRegistersIsRefusedNamingWhy) {
  // tracker data (the station 3 m away) with groups that have no 'base': nothing registers the
  // frame, and the fit would put the error into a compliance (the probe's 2.9 m "fit")
  SimulateOptions o;
  o.effects = {"geometric"};
  o.poses = 80;
  const RobotModel nominal = test::loadBundled("kuka_kr16");
  const RobotModel truth = perturbModel(nominal, o);
  const MeasurementSet data = simulateMeasurements(truth, o);
  IdentifyOptions compliance_only;
  compliance_only.groups = {"joint_compliance:j2"};
  try {
    identify(nominal, data, compliance_only, nullptr);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("have no 'base' to register the measurement frame"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--params base,joint_compliance:j2"), std::string::npos) << e.what();
  }
  // with base it fits (the same groups otherwise)
  compliance_only.groups = {"base", "joint_compliance:j2"};
  EXPECT_NO_THROW(identify(nominal, data, compliance_only, nullptr));
  // two data sets said to share a station that do not: the second moved by 100 mm
  MeasurementSet moved = data;
  moved.file = "moved.csv";
  for (Measurement& m : moved.rows) m.p_world_mm += Eigen::Vector3d(100, 0, 0);
  IdentifyOptions same;
  same.groups = {"geometric"};
  same.same_station = true;
  try {
    identify(nominal, std::vector<MeasurementSet>{data, moved}, same, nullptr);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("moved.csv: expected data sets that share one station"), std::string::npos) << e.what();
  }
  // each from its own station: they fit
  same.same_station = false;
  IdentifySummary s;
  identify(nominal, std::vector<MeasurementSet>{data, moved}, same, &s);
  EXPECT_LT(s.fit.rms_mm, 0.1);
}

TEST(Identify, OrientationsReadInAnotherConventionAreAWarning) {
  // The same tracker data, its orientations once as written and once turned about x by the
  // pose's own angle (what reading intrinsic angles as extrinsic ones does): the positions fit
  // either way, the turned orientations by degrees, which no robot is off by
  SimulateOptions o;
  o.effects = {"geometric"};
  o.orientation = true;
  o.poses = 120;
  o.seed = 7;
  const RobotModel nominal = test::loadBundled("kuka_kr16");
  const RobotModel truth = perturbModel(nominal, o);
  const MeasurementSet good = simulateMeasurements(truth, o);
  MeasurementSet turned = good;
  for (Measurement& m : turned.rows)
    m.R_world_tcp = Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * m.q[0] * kDegToRad, Eigen::Vector3d::UnitX())) * m.R_world_tcp;
  IdentifyOptions opt;
  IdentifySummary s_good, s_turned;
  identify(nominal, good, opt, &s_good);
  identify(nominal, turned, opt, &s_turned);
  auto warned = [](const IdentifySummary& s) {
    for (const std::string& w : s.warnings)
      if (w.find("the orientation data is likely read in another convention or unit") != std::string::npos) return true;
    return false;
  };
  EXPECT_LT(s_good.fit.rot_rms_deg, kImplausibleOrientationRmsDeg);
  EXPECT_FALSE(warned(s_good));
  EXPECT_GT(s_turned.fit.rot_rms_deg, kImplausibleOrientationRmsDeg);
  EXPECT_TRUE(warned(s_turned));
}

}  // namespace
}  // namespace accura::calib
