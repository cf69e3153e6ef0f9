// The diagnosis' orientation residual of 6D data (diagnose.h, docs/diagnosis.md step 11):
// comparable with identify's. The measured point on the last joint's axis leaves wrist
// parameters that positions barely determine; a residual from the position-only fit measured
// how far they wandered, not the robot.
#include <gtest/gtest.h>

#include <cmath>

#include "accura/calib/diagnose.h"
#include "accura/calib/identify.h"
#include "accura/calib/simulate.h"
#include "test_util.h"

namespace accura::calib {
namespace {

// A UR10 whose reflector sits on axis 6, 109 mm from the flange (as on the real UR10 of
// Series_B/C), 6D data with 0.02 mm and 0.002 deg noise per axis: the orientation residual of
// the geometric model is the orientation noise, sqrt(3) x 0.002 = 0.00346 deg (the angle of a
// rotation with three independent 0.002 deg components), and identify's on the same rows.
TEST(DiagnoseOrientation, ResidualIsThatOfIdentifyOnPositionsAndOrientations) {
  RobotModel nominal = test::loadBundled("ur10");
  const XyzAbc tool = {0, 0, 109, 0, 0, 0};
  nominal.nominal.T_flange_tcp = toIsometry(tool);
  SimulateOptions o;
  o.poses = 300;
  o.seed = 61;
  o.noise_mm = 0.02;
  o.noise_deg = 0.002;
  o.orientation = true;
  o.write_std = true;
  o.effects = {"geometric"};
  o.tool = tool;
  o.set_tool = true;
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

}  // namespace
}  // namespace accura::calib
