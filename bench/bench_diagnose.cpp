// accura benchmark: the diagnosis of 500 measured poses of a KUKA KR 16 with the whole effect
// catalogue (joint_compliance, gear_periodic with 2 harmonics, joint_scale, backlash,
// thermal; 5-fold cross-validation), next to its peers measured in the same run: one
// identification of the complete geometric model on the same poses, and the diagnosis with a
// separate validation set. Single-threaded. Target (issue 11): the diagnosis, with robust
// estimation, blocked cross-validation and the per-joint spectrum, under 1 s.
//
// The data sets are simulated once, outside the timed loops. Results are consumed with
// benchmark::DoNotOptimize.
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "accura/calib/diagnose.h"
#include "accura/calib/geometry.h"
#include "accura/calib/identify.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"
#include "../calib/src/identify_internal.h"  // CeresForJointMaps: the peer solver

namespace {

using accura::calib::MeasurementSet;
using accura::calib::RobotModel;

const accura::calib::XyzAbc kTarget = {80, 40, 150, 0, 0, 0};  // tracker reflector on the flange (mm)

struct Campaign {
  RobotModel nominal;
  MeasurementSet fit, validation;
};

// KR 16 with geometric errors and joint compliance under 0, 8 and 16 kg; 500 poses with std
// columns (0.02 mm), and 200 held-out poses of the same robot.
// The KR 16 with the reflector on its flange, and a simulated campaign of it (std columns, 0.02 mm).
std::unique_ptr<Campaign> kr16(accura::calib::SimulateOptions* o, int poses, std::uint64_t seed,
                               const std::vector<std::string>& effects) {
  auto out = std::make_unique<Campaign>();
  out->nominal = accura::calib::readRobotFile(accura::calib::resolveRobotPath("kuka_kr16"));
  out->nominal.nominal.T_flange_tcp = accura::calib::toIsometry(kTarget);
  o->poses = poses;
  o->seed = seed;
  o->noise_mm = 0.02;
  o->effects = effects;
  o->tool = kTarget;
  o->set_tool = true;
  o->write_std = true;
  return out;
}

const Campaign& campaign() {
  static const std::unique_ptr<Campaign> c = [] {
    accura::calib::SimulateOptions o;
    o.payloads_kg = {0, 8, 16};
    auto out = kr16(&o, 500, 7, {"geometric", "joint_compliance"});
    const RobotModel truth = accura::calib::perturbModel(out->nominal, o);
    out->fit = accura::calib::simulateMeasurements(truth, o);
    o.poses = 200;
    o.seed = 8;
    out->validation = accura::calib::simulateMeasurements(truth, o);
    return out;
  }();
  return *c;
}

void BM_Diagnose500PosesWholeCatalogueCrossValidated(benchmark::State& state) {
  const Campaign& c = campaign();
  std::string verdict;
  for (auto _ : state) {
    const accura::calib::Diagnosis d = accura::calib::diagnose(c.nominal, c.fit, nullptr, accura::calib::DiagnoseOptions{});
    verdict = d.verdict.effect;
    benchmark::DoNotOptimize(d.verdict.validation_rms_after_mm);
  }
  state.SetLabel("verdict " + verdict);
}
BENCHMARK(BM_Diagnose500PosesWholeCatalogueCrossValidated)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// The same diagnosis doing only the work it did when issue 15 was filed (commit 8b1cf54): the
// catalogue without joint_map, no robust passes, no blocked cross-validation, no per-joint
// spectrum. Its peer is that commit's BM_Diagnose500PosesWholeCatalogueCrossValidated, built
// from a worktree and run alternately with this one (bench/README.md): the same campaign, the
// same verdict and held-out RMS in the label.
void BM_Diagnose500PosesIssue15Work(benchmark::State& state) {
  const Campaign& c = campaign();
  accura::calib::DiagnoseOptions o;
  for (const std::string& e : accura::calib::effectCatalogue())
    if (e != "joint_map") o.effects.push_back(e);
  o.robust_k = 0;
  o.blocked_folds = 0;
  o.spectrum_max_cycles = 0;
  std::string label;
  for (auto _ : state) {
    const accura::calib::Diagnosis d = accura::calib::diagnose(c.nominal, c.fit, nullptr, o);
    label = "verdict " + d.verdict.effect + " held-out " + std::to_string(d.verdict.validation_rms_after_mm) + " mm";
    benchmark::DoNotOptimize(d.verdict.validation_rms_after_mm);
  }
  state.SetLabel(label);
}
BENCHMARK(BM_Diagnose500PosesIssue15Work)->Unit(benchmark::kMillisecond)->MinTime(2.0);

void BM_Diagnose500PosesWholeCatalogueValidationSet(benchmark::State& state) {
  const Campaign& c = campaign();
  for (auto _ : state) {
    const accura::calib::Diagnosis d = accura::calib::diagnose(c.nominal, c.fit, &c.validation, accura::calib::DiagnoseOptions{});
    benchmark::DoNotOptimize(d.verdict.validation_rms_after_mm);
  }
}
BENCHMARK(BM_Diagnose500PosesWholeCatalogueValidationSet)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Peer: one identification of the complete geometric model on the same 500 poses.
void BM_IdentifyGeometric500Poses(benchmark::State& state) {
  const Campaign& c = campaign();
  accura::calib::IdentifyOptions o;
  o.groups = {"geometric"};
  for (auto _ : state) {
    const RobotModel m = accura::calib::identify(c.nominal, c.fit, o, nullptr);
    benchmark::DoNotOptimize(m.deviations.base_mm);
  }
}
BENCHMARK(BM_IdentifyGeometric500Poses)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Identification with joint maps (issue 11 target: 1500 poses well under a second): a KR 16 with a
// per-joint cyclic error (17 cycles per revolution, 0.5 mrad, joints 2 and 3) on top of geometric
// errors, 1500 poses; the maps of every joint, knot spacing and smoothness chosen by blocked
// cross-validation (the default) or stated (3 deg, 0.003). Peer: the geometric model alone on
// the same poses.
const Campaign& campaign1500() {
  static const std::unique_ptr<Campaign> c = [] {
    accura::calib::SimulateOptions o;
    auto out = kr16(&o, 1500, 9, {"geometric"});
    const RobotModel truth = accura::calib::perturbModel(out->nominal, o);
    out->fit = accura::calib::simulateMeasurements(truth, o);
    accura::calib::KinematicWorkspace ws;
    for (accura::calib::Measurement& r : out->fit.rows) {
      Eigen::VectorXd q = r.q;
      for (int j : {1, 2}) q[j] += 0.5e-3 * accura::calib::kRadToDeg * std::sin(17 * r.q[j] * accura::calib::kDegToRad + j);
      r.p_world_mm += accura::calib::forwardKinematics(truth, q, r.context, ws).translation() -
                      accura::calib::forwardKinematics(truth, r.q, r.context, ws).translation();
    }
    return out;
  }();
  return *c;
}

void identify1500(benchmark::State& state, const std::vector<std::string>& groups, double smoothing, bool ceres = false) {
  const Campaign& c = campaign1500();
  accura::calib::IdentifyOptions o;
  o.groups = groups;
  if (!std::isnan(smoothing)) o.joint_map_smoothing = smoothing;
  double rms = 0;
  for (auto _ : state) {
    accura::calib::IdentifySummary s;
    std::unique_ptr<accura::calib::identify_detail::CeresForJointMaps> peer;
    if (ceres) peer = std::make_unique<accura::calib::identify_detail::CeresForJointMaps>();
    const RobotModel m = accura::calib::identify(c.nominal, c.fit, o, &s);
    rms = s.fit.rms_mm;
    benchmark::DoNotOptimize(m.deviations.base_mm);
  }
  state.SetLabel("fit RMS " + std::to_string(rms) + " mm");
}

void BM_IdentifyJointMaps1500PosesChosenByCv(benchmark::State& state) {
  identify1500(state, {"geometric", "joint_map"}, std::nan(""));
}
BENCHMARK(BM_IdentifyJointMaps1500PosesChosenByCv)->Unit(benchmark::kMillisecond)->MinTime(2.0);

void BM_IdentifyJointMaps1500PosesStated(benchmark::State& state) {
  identify1500(state, {"geometric", "joint_map@3deg"}, 0.003);
}
BENCHMARK(BM_IdentifyJointMaps1500PosesStated)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Peers of the two above: the same identifications with Ceres' sparse Levenberg-Marquardt on
// the stacked Jacobian instead of the normal equations accumulated pose by pose
// (identify_normal.cpp); the cross-validation itself is the same code in both.
void BM_IdentifyJointMaps1500PosesChosenByCvCeres(benchmark::State& state) {
  identify1500(state, {"geometric", "joint_map"}, std::nan(""), true);
}
BENCHMARK(BM_IdentifyJointMaps1500PosesChosenByCvCeres)->Unit(benchmark::kMillisecond)->MinTime(2.0);

void BM_IdentifyJointMaps1500PosesStatedCeres(benchmark::State& state) {
  identify1500(state, {"geometric", "joint_map@3deg"}, 0.003, true);
}
BENCHMARK(BM_IdentifyJointMaps1500PosesStatedCeres)->Unit(benchmark::kMillisecond)->MinTime(2.0);

void BM_IdentifyGeometric1500Poses(benchmark::State& state) { identify1500(state, {"geometric"}, std::nan("")); }
BENCHMARK(BM_IdentifyGeometric1500Poses)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace

BENCHMARK_MAIN();
