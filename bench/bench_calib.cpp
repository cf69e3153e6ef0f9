// accura benchmarks: forward kinematics, the analytic parameter Jacobian and the
// identification of the complete KUKA KR 16 model, each next to a peer measured in the same
// run (a hand-written naive DH chain, central finite differences, fewer poses / the
// registration alone), so that ratios can be read from one table. Single-threaded.
//
// Every simulated data set and model is built once, outside the timed loops (cached in
// function-local statics). Results are consumed with benchmark::DoNotOptimize.
#include <benchmark/benchmark.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "accura/calib/geometry.h"
#include "accura/calib/identify.h"
#include "accura/calib/kinematic_core.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/measurements.h"
#include "accura/calib/robot.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"

namespace {

using accura::calib::RobotModel;

constexpr int kPoses = 1000;
const accura::calib::XyzAbc kTool = {80, 40, 150, 0, 0, 0};  // tracker target on the flange (mm)

accura::calib::SimulateOptions campaignOptions(int poses) {
  accura::calib::SimulateOptions o;
  o.poses = poses;
  o.seed = 21;
  o.noise_mm = 0.02;
  o.tool = kTool;
  o.set_tool = true;
  return o;
}

/// The nominal KR 16 with the nominal target offset on the flange.
RobotModel nominalKr16() {
  RobotModel m = accura::calib::readRobotFile(accura::calib::resolveRobotPath("kuka_kr16"));
  m.nominal.T_flange_tcp = accura::calib::toIsometry(kTool);
  return m;
}

// ---------------------------------------------------------------------------------------
// The peer of forward kinematics: what a user writes by hand. Each link is the product of
// four generic 4x4 matrices Rz(theta) Tz(d) Tx(a) Rx(alpha), multiplied in turn; base and
// tool are 4x4 matrices too, so that it computes the same quantity (T_world_tcp).

struct NaiveLink {
  double theta0_rad, d_mm, a_mm, alpha_rad;
  int direction;
};

struct NaiveRobot {
  std::vector<NaiveLink> links;
  Eigen::Matrix4d T_world_base, T_flange_tcp;
};

Eigen::Matrix4d rotZ(double t) {
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
  M(0, 0) = std::cos(t); M(0, 1) = -std::sin(t);
  M(1, 0) = std::sin(t); M(1, 1) = std::cos(t);
  return M;
}
Eigen::Matrix4d rotX(double t) {
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
  M(1, 1) = std::cos(t); M(1, 2) = -std::sin(t);
  M(2, 1) = std::sin(t); M(2, 2) = std::cos(t);
  return M;
}
Eigen::Matrix4d transZ(double d) {
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
  M(2, 3) = d;
  return M;
}
Eigen::Matrix4d transX(double a) {
  Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
  M(0, 3) = a;
  return M;
}

Eigen::Matrix4d naiveForwardKinematics(const NaiveRobot& robot, const Eigen::VectorXd& q_deg) {
  Eigen::Matrix4d T = robot.T_world_base;
  for (size_t i = 0; i < robot.links.size(); ++i) {
    const NaiveLink& L = robot.links[i];
    const double theta = L.theta0_rad + L.direction * q_deg[static_cast<Eigen::Index>(i)] * accura::calib::kDegToRad;
    T = T * rotZ(theta) * transZ(L.d_mm) * transX(L.a_mm) * rotX(L.alpha_rad);
  }
  return T * robot.T_flange_tcp;
}

NaiveRobot naiveFrom(const RobotModel& model) {
  NaiveRobot r;
  for (const accura::calib::JointSpec& j : model.nominal.joints)
    r.links.push_back({j.theta0_deg * accura::calib::kDegToRad, j.d_mm, j.a_mm, j.alpha_deg * accura::calib::kDegToRad,
                       j.direction});
  r.T_world_base = model.nominal.T_world_base.matrix();
  r.T_flange_tcp = model.nominal.T_flange_tcp.matrix();
  return r;
}

// ---------------------------------------------------------------------------------------
// Shared data of the FK and Jacobian benchmarks: 1000 random joint vectors of the KR 16
// (within its limits, from simulateMeasurements) and the models.

struct KinematicsData {
  RobotModel nominal;          // nominal KR 16 (+ nominal tool)
  RobotModel truth;            // the same with non-zero geometric deviations (perturbModel)
  RobotModel truth_compliant;  // geometric deviations and joint compliance
  NaiveRobot naive;            // the nominal DH chain for the hand-written FK
  std::vector<accura::calib::ParamInfo> layout;  // the full parameter layout
  std::vector<Eigen::VectorXd> q;
  std::vector<accura::calib::PoseContext> context;
  double naive_max_diff_mm = 0;  // hand-written FK vs accura's FK at nominal
};

const KinematicsData& kinematicsData() {
  static const std::unique_ptr<KinematicsData> data = [] {
    auto d = std::make_unique<KinematicsData>();
    d->nominal = nominalKr16();
    accura::calib::SimulateOptions o = campaignOptions(kPoses);
    d->truth = accura::calib::perturbModel(d->nominal, o);
    accura::calib::SimulateOptions oc = o;
    oc.effects = {"geometric", "joint_compliance"};
    oc.payloads_kg = {0, 8, 16};
    d->truth_compliant = accura::calib::perturbModel(d->nominal, oc);
    d->naive = naiveFrom(d->nominal);
    d->layout = accura::calib::parameterLayout(d->truth);
    const accura::calib::MeasurementSet set = accura::calib::simulateMeasurements(d->truth_compliant, oc);
    for (const accura::calib::Measurement& m : set.rows) {
      d->q.push_back(m.q);
      d->context.push_back(m.context);  // payloads 0, 8, 16 kg cycled
    }
    // the peer must compute the same thing: compare at nominal
    accura::calib::KinematicWorkspace ws;
    for (size_t i = 0; i < d->q.size(); ++i) {
      const Eigen::Isometry3d T = accura::calib::forwardKinematics(d->nominal, d->q[i], {}, ws);
      const Eigen::Matrix4d N = naiveForwardKinematics(d->naive, d->q[i]);
      d->naive_max_diff_mm = std::max(d->naive_max_diff_mm, (T.matrix() - N).cwiseAbs().maxCoeff());
    }
    return d;
  }();
  return *data;
}

// ---------------------------------------------------------------------------------------
// 1. Forward kinematics

void fkCounters(benchmark::State& state, size_t poses) {
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(poses));
  state.counters["poses"] = static_cast<double>(poses);
  state.counters["ns_per_pose"] = benchmark::Counter(
      static_cast<double>(state.iterations() * poses),
      benchmark::Counter::kIsRate | benchmark::Counter::kInvert, benchmark::Counter::kIs1000);
}

/// The kinematic core as it is meant for repeated evaluation: the model prepared once
/// (KinematicModel, outside the loop, like the peer's link table), one KinematicFrames.
void fkAccura(benchmark::State& state, const RobotModel& model, bool with_payload) {
  const KinematicsData& d = kinematicsData();
  const accura::calib::KinematicModel core(model);
  accura::calib::KinematicFrames f;
  const accura::calib::PoseContext no_payload;
  double sum = 0;
  for (auto _ : state) {
    for (size_t i = 0; i < d.q.size(); ++i) {
      core.evaluate(d.q[i].data(), with_payload ? d.context[i] : no_payload, f);
      benchmark::DoNotOptimize(f.T_world_tcp);
      sum += f.T_world_tcp.translation().x();
    }
  }
  benchmark::DoNotOptimize(sum);
  fkCounters(state, d.q.size());
}

/// The convenience call forwardKinematics(model, q, context, ws): the workspace keeps the
/// prepared model (checked against the RobotModel's values on every call) and publishes the
/// intermediate frames in the base frame.
void fkAccuraWorkspace(benchmark::State& state, const RobotModel& model, bool with_payload) {
  const KinematicsData& d = kinematicsData();
  accura::calib::KinematicWorkspace ws;
  const accura::calib::PoseContext no_payload;
  double sum = 0;
  for (auto _ : state) {
    for (size_t i = 0; i < d.q.size(); ++i) {
      const Eigen::Isometry3d T =
          accura::calib::forwardKinematics(model, d.q[i], with_payload ? d.context[i] : no_payload, ws);
      benchmark::DoNotOptimize(T);
      sum += T.translation().x();
    }
  }
  benchmark::DoNotOptimize(sum);
  fkCounters(state, d.q.size());
}

void BM_FK_Accura(benchmark::State& state) { fkAccura(state, kinematicsData().truth, false); }
void BM_FK_Accura_Compliance(benchmark::State& state) {
  fkAccura(state, kinematicsData().truth_compliant, true);
}
void BM_FK_Accura_Workspace(benchmark::State& state) { fkAccuraWorkspace(state, kinematicsData().truth, false); }

void BM_FK_NaiveDH4x4_Peer(benchmark::State& state) {
  const KinematicsData& d = kinematicsData();
  double sum = 0;
  for (auto _ : state) {
    for (size_t i = 0; i < d.q.size(); ++i) {
      const Eigen::Matrix4d T = naiveForwardKinematics(d.naive, d.q[i]);
      benchmark::DoNotOptimize(T);
      sum += T(0, 3);
    }
  }
  benchmark::DoNotOptimize(sum);
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(d.q.size()));
  state.counters["poses"] = static_cast<double>(d.q.size());
  state.counters["max_diff_vs_accura_mm"] = d.naive_max_diff_mm;  // at nominal: same chain
}

// ---------------------------------------------------------------------------------------
// 2. Parameter Jacobian (full layout: base, tool, per-joint geometry, compliance)

/// Central finite differences of forwardKinematics, two FK calls per column. Same layout,
/// units and row convention as parameterJacobian: [dp_world (mm); dphi_world (rad)].
double fdStep(const accura::calib::ParamInfo& p) {
  if (p.unit == "mm") return 1e-4;      // mm
  if (p.unit == "deg") return 1e-6;     // rad internally
  if (p.unit == "urad/Nm") return 1e-7; // rad/(N*m): 0.1 urad/Nm, loads up to ~1e3 N*m
  return 1e-5;                          // mm/N (prismatic joints)
}

void finiteDifferenceJacobian(RobotModel& model, const std::vector<accura::calib::ParamInfo>& layout,
                              const Eigen::VectorXd& q, const accura::calib::PoseContext& context,
                              accura::calib::KinematicWorkspace& ws, Eigen::MatrixXd& J) {
  J.resize(6, static_cast<Eigen::Index>(layout.size()));
  for (size_t k = 0; k < layout.size(); ++k) {
    const accura::calib::ParamInfo& p = layout[k];
    const double v0 = accura::calib::getParameter(model.deviations, p);
    const double h = fdStep(p);
    accura::calib::setParameter(model.deviations, p, v0 + h);
    const Eigen::Isometry3d Tp = accura::calib::forwardKinematics(model, q, context, ws);
    accura::calib::setParameter(model.deviations, p, v0 - h);
    const Eigen::Isometry3d Tm = accura::calib::forwardKinematics(model, q, context, ws);
    accura::calib::setParameter(model.deviations, p, v0);
    const Eigen::Index c = static_cast<Eigen::Index>(k);
    J.col(c).head<3>() = (Tp.translation() - Tm.translation()) / (2 * h);
    J.col(c).tail<3>() = accura::calib::logSO3(Tp.linear() * Tm.linear().transpose()) / (2 * h);
  }
}

/// Largest column-relative difference between the analytic and the FD Jacobian over the
/// first `poses` poses. Columns that are (nearly) zero, such as the compliance of the
/// vertical axis 1 (no gravity torque) or of axis 6, are skipped: there the FD quotient is
/// pure rounding noise.
double jacobianAgreement(const KinematicsData& d, const RobotModel& start, int poses) {
  RobotModel model = start;
  accura::calib::KinematicWorkspace ws;
  Eigen::MatrixXd Ja, Jf;
  double worst = 0;
  for (int i = 0; i < poses; ++i) {
    accura::calib::parameterJacobian(model, d.layout, d.q[i], d.context[i], ws, Ja);
    finiteDifferenceJacobian(model, d.layout, d.q[i], d.context[i], ws, Jf);
    for (Eigen::Index c = 0; c < Ja.cols(); ++c) {
      const double scale = Ja.col(c).norm();
      if (scale < 1e-3) continue;
      worst = std::max(worst, (Ja.col(c) - Jf.col(c)).norm() / scale);
    }
  }
  return worst;
}

/// Arg 0: the model of the FK benchmark (geometric deviations); arg 1: geometric deviations
/// and joint compliance, payloads 0/8/16 kg cycled over the poses.
const RobotModel& jacobianModel(const benchmark::State& state) {
  const KinematicsData& d = kinematicsData();
  return state.range(0) ? d.truth_compliant : d.truth;
}

void BM_Jacobian_Accura(benchmark::State& state) {
  const KinematicsData& d = kinematicsData();
  const RobotModel& model = jacobianModel(state);
  accura::calib::KinematicWorkspace ws;
  Eigen::MatrixXd J;
  for (auto _ : state) {
    for (size_t i = 0; i < d.q.size(); ++i) {
      const Eigen::Isometry3d T = accura::calib::parameterJacobian(model, d.layout, d.q[i], d.context[i], ws, J);
      benchmark::DoNotOptimize(T);
      benchmark::DoNotOptimize(J.data());
      benchmark::ClobberMemory();
    }
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(d.q.size()));
  state.counters["columns"] = static_cast<double>(d.layout.size());
  state.counters["poses"] = static_cast<double>(d.q.size());
}

void BM_Jacobian_CentralFD_Peer(benchmark::State& state) {
  const KinematicsData& d = kinematicsData();
  RobotModel model = jacobianModel(state);  // a mutable copy: the FD perturbs its deviations
  accura::calib::KinematicWorkspace ws;
  Eigen::MatrixXd J;
  for (auto _ : state) {
    for (size_t i = 0; i < d.q.size(); ++i) {
      finiteDifferenceJacobian(model, d.layout, d.q[i], d.context[i], ws, J);
      benchmark::DoNotOptimize(J.data());
      benchmark::ClobberMemory();
    }
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(d.q.size()));
  state.counters["columns"] = static_cast<double>(d.layout.size());
  state.counters["poses"] = static_cast<double>(d.q.size());
  // outside the timed loop: the peer computes the same matrix
  state.counters["max_rel_diff_vs_analytic"] = jacobianAgreement(d, jacobianModel(state), 50);
}

// ---------------------------------------------------------------------------------------
// 3. Identification of the complete KR 16 model

struct IdentifyCase {
  RobotModel start;  // nominal + nominal target offset; the tracker frame is unknown
  RobotModel truth;
  accura::calib::MeasurementSet data, validation;
  accura::calib::IdentifyOptions options;
};

const IdentifyCase& identifyCase(int poses, bool compliance) {
  static std::map<std::pair<int, bool>, std::unique_ptr<IdentifyCase>> cache;
  auto& slot = cache[{poses, compliance}];
  if (!slot) {
    auto c = std::make_unique<IdentifyCase>();
    accura::calib::SimulateOptions o = campaignOptions(poses);
    if (compliance) {
      o.effects = {"geometric", "joint_compliance"};
      o.payloads_kg = {0, 8, 16};
      c->options.groups = {"geometric", "joint_compliance"};
    }
    c->start = nominalKr16();
    c->truth = accura::calib::perturbModel(c->start, o);
    c->data = accura::calib::simulateMeasurements(c->truth, o);
    o.seed += 1000;
    o.poses = 300;
    c->validation = accura::calib::simulateMeasurements(c->truth, o);
    slot = std::move(c);
  }
  return *slot;
}

void identifyBench(benchmark::State& state, bool compliance) {
  const int poses = static_cast<int>(state.range(0));
  const IdentifyCase& c = identifyCase(poses, compliance);
  accura::calib::IdentifySummary s;
  RobotModel cal;
  for (auto _ : state) {
    cal = accura::calib::identify(c.start, c.data, c.options, &s);
    benchmark::DoNotOptimize(cal.deviations.base_mm.data());
    benchmark::ClobberMemory();
  }
  const accura::calib::ErrorStats floor = accura::calib::evaluate(c.truth, c.validation);
  const accura::calib::ErrorStats val = accura::calib::evaluate(cal, c.validation);
  state.counters["poses"] = poses;
  state.counters["params"] = s.parameters_free;
  state.counters["iters_last_solve"] = s.iterations;  // the final Ceres solve only
  state.counters["reg_rms_mm"] = s.registration_rms_mm;
  state.counters["fit_rms_mm"] = s.fit.rms_mm;
  state.counters["val_rms_mm"] = val.rms_mm;      // independent poses, calibrated model
  state.counters["floor_rms_mm"] = floor.rms_mm;  // the same poses, the true robot (noise only)
  state.counters["cond"] = s.condition_number;
  state.counters["converged"] = s.termination.find("CONVERGENCE") != std::string::npos ? 1 : 0;
}

void BM_Identify_Geometric(benchmark::State& state) { identifyBench(state, false); }
void BM_Identify_GeometricCompliance(benchmark::State& state) { identifyBench(state, true); }

/// The closed-form registration alone (T_world_base and the tool point), as identify()
/// does it first: one flangePose per row plus the alternating Kabsch / tool rounds.
void BM_RegisterFrame(benchmark::State& state) {
  const int poses = static_cast<int>(state.range(0));
  const IdentifyCase& c = identifyCase(poses, false);
  double rms = 0;
  for (auto _ : state) {
    RobotModel m = c.start;
    rms = accura::calib::registerFrame(m, c.data, /*estimate_tool=*/true);
    benchmark::DoNotOptimize(m.deviations.base_mm.data());
    benchmark::DoNotOptimize(rms);
  }
  state.counters["poses"] = poses;
  state.counters["reg_rms_mm"] = rms;
}

// Identification with joint maps (issue 11): the geometric KR 16 campaign of 1500 poses with
// joint_map on j1..j3 at 3 deg knots, smoothness given (no cross-validation), against the same
// identification without maps measured in this run (BM_Identify_Geometric/1500).
void BM_Identify_GeometricJointMap(benchmark::State& state) {
  const IdentifyCase& c = identifyCase(static_cast<int>(state.range(0)), false);
  accura::calib::IdentifyOptions o = c.options;
  o.groups = {"geometric", "joint_map:j1+j2+j3@3deg"};
  o.joint_map_smoothing = 0.01;
  accura::calib::IdentifySummary s;
  RobotModel cal;
  for (auto _ : state) {
    cal = accura::calib::identify(c.start, c.data, o, &s);
    benchmark::DoNotOptimize(cal.deviations.base_mm.data());
    benchmark::ClobberMemory();
  }
  size_t coefficients = 0;
  for (const auto& m : cal.deviations.joint_map) coefficients += m.coef.size();
  state.counters["poses"] = static_cast<double>(state.range(0));
  state.counters["map_coefficients"] = static_cast<double>(coefficients);
  state.counters["val_rms_mm"] = accura::calib::evaluate(cal, c.validation).rms_mm;
}

}  // namespace

BENCHMARK(BM_Identify_GeometricJointMap)->Arg(1500)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Identify_Geometric)->Arg(1500)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FK_Accura)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FK_Accura_Compliance)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FK_Accura_Workspace)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FK_NaiveDH4x4_Peer)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Jacobian_Accura)->ArgName("compliance")->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Jacobian_CentralFD_Peer)->ArgName("compliance")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Identify_Geometric)->Arg(1000)->Arg(300)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RegisterFrame)->Arg(1000)->Arg(300)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Identify_GeometricCompliance)->Arg(1000)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
