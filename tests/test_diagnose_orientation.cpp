// The diagnosis' orientation residual of 6D data (diagnose.h, docs/diagnosis.md step 11):
// comparable with identify's. The measured point on the last joint's axis leaves wrist
// parameters that positions barely determine; a residual from the position-only fit measured
// how far they wandered, not the robot.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "accura/calib/diagnose.h"
#include "accura/calib/identify.h"
#include "accura/calib/simulate.h"
#include "test_util.h"

namespace accura::calib {
namespace {

const XyzAbc kTmac = {0, 0, 109, 0, 0, 0};  // the reflector on axis 6, 109 mm from the flange

RobotModel ur10WithTmac() {
  RobotModel nominal = test::loadBundled("ur10");
  nominal.nominal.T_flange_tcp = toIsometry(kTmac);
  return nominal;
}

// 6D campaign of 300 poses, 0.02 mm and 0.002 deg noise per axis, std columns
SimulateOptions campaign6d(std::uint64_t seed, const std::vector<std::string>& effects) {
  SimulateOptions o;
  o.poses = 300;
  o.seed = seed;
  o.noise_mm = 0.02;
  o.noise_deg = 0.002;
  o.orientation = true;
  o.write_std = true;
  o.effects = effects;
  o.tool = kTmac;
  o.set_tool = true;
  return o;
}

// A UR10 whose reflector sits on axis 6, 109 mm from the flange (as on the real UR10 of
// Series_B/C), 6D data with 0.02 mm and 0.002 deg noise per axis: the orientation residual of
// the geometric model is the orientation noise, sqrt(3) x 0.002 = 0.00346 deg (the angle of a
// rotation with three independent 0.002 deg components), and identify's on the same rows.
TEST(DiagnoseOrientation, ResidualIsThatOfIdentifyOnPositionsAndOrientations) {
  const RobotModel nominal = ur10WithTmac();
  const SimulateOptions o = campaign6d(61, {"geometric"});
  const RobotModel truth = perturbModel(nominal, o);
  const MeasurementSet fit = simulateMeasurements(truth, o);
  ASSERT_TRUE(fit.has_orientation);
  const Diagnosis d = diagnose(nominal, fit, nullptr, DiagnoseOptions{});
  ASSERT_EQ(d.identify_params, "geometric") << diagnosisText(d);
  const double noise = std::sqrt(3.0) * 0.002;
  EXPECT_GT(d.orientation_rms_before_deg, 0.8 * noise) << diagnosisText(d);
  EXPECT_LT(d.orientation_rms_before_deg, 1.2 * noise) << diagnosisText(d);
  EXPECT_EQ(d.orientation_rms_after_deg, d.orientation_rms_before_deg);  // nothing selected
  // identify on the same 6D rows (what a user compares it with)
  IdentifySummary s;
  identify(nominal, fit, IdentifyOptions{}, &s);
  ASSERT_TRUE(s.fit.has_orientation);
  EXPECT_NEAR(d.orientation_rms_before_deg, s.fit.rot_rms_deg, 0.1 * noise);
}

// 6D data: the diagnosis' linearised fits and refits use the orientations as identify fits them
// (DiagnoseOptions::use_orientation). A UR10 with the reflector on axis 6 and compliant joints:
// joint 2's compliance is determined better with the orientation rows than from the positions
// alone (a smaller sigma: the orientation carries the joint's deflection directly), and both
// estimates agree with the simulated truth.
TEST(DiagnoseOrientation, TheFitsUseTheOrientationsAsIdentifyDoes) {
  const RobotModel nominal = ur10WithTmac();
  SimulateOptions o = campaign6d(71, {"geometric", "joint_compliance"});
  o.payloads_kg = {0, 5, 10};
  const RobotModel truth = perturbModel(nominal, o);
  const MeasurementSet fit = simulateMeasurements(truth, o);
  DiagnoseOptions position_only;
  position_only.use_orientation = false;
  const Diagnosis d6 = diagnose(nominal, fit, nullptr, DiagnoseOptions{});
  const Diagnosis d3 = diagnose(nominal, fit, nullptr, position_only);
  EXPECT_FALSE(d6.orientation_ignored);
  EXPECT_TRUE(d3.orientation_ignored);
  auto j2 = [](const Diagnosis& d) {
    for (const EffectEvidence& e : d.selected)
      for (const EffectParameter& p : e.parameters)
        if (p.name == "j2_compliance") return p;
    ADD_FAILURE() << "joint 2's compliance not selected\n" << diagnosisText(d);
    return EffectParameter{};
  };
  const EffectParameter p6 = j2(d6), p3 = j2(d3);
  const double true_urad_per_nm = truth.deviations.compliance[1] * 1e6;
  EXPECT_NEAR(p6.value, true_urad_per_nm, 3 * p6.sigma) << p6.sigma;
  EXPECT_NEAR(p3.value, true_urad_per_nm, 3 * p3.sigma) << p3.sigma;
  EXPECT_GT(p6.sigma, 0);
  EXPECT_LT(p6.sigma, 0.95 * p3.sigma);
}

}  // namespace
}  // namespace accura::calib
