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

#include <memory>
#include <string>

#include "accura/calib/diagnose.h"
#include "accura/calib/geometry.h"
#include "accura/calib/identify.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"

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
const Campaign& campaign() {
  static const std::unique_ptr<Campaign> c = [] {
    auto out = std::make_unique<Campaign>();
    out->nominal = accura::calib::readRobotFile(accura::calib::resolveRobotPath("kuka_kr16"));
    out->nominal.nominal.T_flange_tcp = accura::calib::toIsometry(kTarget);
    accura::calib::SimulateOptions o;
    o.poses = 500;
    o.seed = 7;
    o.noise_mm = 0.02;
    o.effects = {"geometric", "joint_compliance"};
    o.payloads_kg = {0, 8, 16};
    o.tool = kTarget;
    o.set_tool = true;
    o.write_std = true;
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

}  // namespace

BENCHMARK_MAIN();
