// The diagnosis' floors and glitches (diagnose.h, docs/diagnosis.md step 2): a configuration
// measured many times names its odd row once (against the configuration's robust centre),
// and the validation file's repeats are glitch-screened like the fit data's before they join
// the repeatability.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "accura/calib/diagnose.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/simulate.h"
#include "test_util.h"

namespace accura::calib {
namespace {

const XyzAbc kTarget = {80, 40, 150, 0, 0, 0};  // tracker reflector on the flange (mm)

struct Campaign {
  RobotModel nominal, truth;
  MeasurementSet fit;
};

// 300 simulated poses of a KR 16 (geometric errors, 0.02 mm noise per axis, std columns), no
// configuration measured twice.
Campaign campaign(std::uint64_t seed, int poses = 300) {
  Campaign c;
  c.nominal = test::loadBundled("kuka_kr16");
  c.nominal.nominal.T_flange_tcp = toIsometry(kTarget);
  SimulateOptions o;
  o.poses = poses;
  o.seed = seed;
  o.noise_mm = 0.02;
  o.effects = {"geometric"};
  o.payloads_kg = {0, 8, 16};
  o.tool = kTarget;
  o.set_tool = true;
  o.write_std = true;
  c.truth = perturbModel(c.nominal, o);
  c.fit = simulateMeasurements(c.truth, o);
  for (size_t i = 0; i < c.fit.rows.size(); ++i) c.fit.rows[i].line = static_cast<int>(i) + 2;
  return c;
}

// `n` measurements of the configuration of `like` (its q and context), each the true point plus
// `noise` mm per axis; the rows listed in `odd` moved by `offset`. Lines from `first_line`.
std::vector<Measurement> repeated(const RobotModel& truth, const Measurement& like, int n, double noise,
                                  const std::vector<int>& odd, const Eigen::Vector3d& offset, int first_line,
                                  std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, noise);
  KinematicWorkspace ws;
  const Eigen::Vector3d p = forwardKinematics(truth, like.q, like.context, ws).translation();
  std::vector<Measurement> out;
  for (int k = 0; k < n; ++k) {
    Measurement r = like;
    r.line = first_line + k;
    r.p_world_mm = p + Eigen::Vector3d(g(rng), g(rng), g(rng));
    if (std::find(odd.begin(), odd.end(), k) != odd.end()) r.p_world_mm += offset;
    out.push_back(r);
  }
  return out;
}

// One configuration measured 20 times, one of them 1.5 mm off: the glitch list names that row
// once (not 19 pairs), 1.5 mm from the configuration's centre, and the other 19 measurements
// give the repeatability (3 x 18 = 54 degrees of freedom, the simulated 0.02 mm per axis).
TEST(DiagnoseGlitches, AConfigurationMeasuredManyTimesNamesItsOddRowOnce) {
  Campaign c = campaign(41);
  // the simulated points are the true robot's forward kinematics plus noise
  KinematicWorkspace ws;
  const Measurement& first = c.fit.rows.front();
  ASSERT_LT((forwardKinematics(c.truth, first.q, first.context, ws).translation() - first.p_world_mm).norm(), 0.15);
  const int first_line = 1000;
  const std::vector<Measurement> rep =
      repeated(c.truth, c.fit.rows[10], 20, 0.02, {7}, Eigen::Vector3d(1.5, 0, 0), first_line, 5);
  c.fit.rows.insert(c.fit.rows.end(), rep.begin(), rep.end());
  const Diagnosis d = diagnose(c.nominal, c.fit, nullptr, DiagnoseOptions{});
  const Floors& fl = d.floors;
  // the 20 measurements of row 10's configuration and row 10 itself: 21 rows, 210 pairs
  EXPECT_EQ(fl.repeat_pairs, 21 * 20 / 2);
  ASSERT_EQ(fl.glitches.size(), 1u) << diagnosisText(d);
  const RepeatPair& g = fl.glitches[0];
  EXPECT_EQ(g.line_a, first_line + 7);
  EXPECT_EQ(g.index_b, -1);
  EXPECT_EQ(g.measurements, 21);
  // 1.5 mm plus the noise of one row and of the median centre (0.02 mm per axis)
  EXPECT_NEAR(g.distance_mm, 1.5, 0.1);
  // the other 20 rows are the repeatability: 3 x 19 degrees of freedom, about 0.02 mm per axis
  EXPECT_EQ(fl.repeat_groups, 1);
  EXPECT_EQ(fl.repeat_dof, 57.0);
  EXPECT_NEAR(fl.repeat_std_axis_mm, 0.02, 0.006);  // relative sd 1/sqrt(114) = 9%: 3 sd
  EXPECT_NE(d.noise_floor_source.find("repeatability"), std::string::npos) << d.noise_floor_source;
  // the text names the row once, against the centre of its configuration
  const std::string text = diagnosisText(d);
  EXPECT_NE(text.find(":" + std::to_string(first_line + 7) + " (against the centre of its configuration's 21 measurements)"),
            std::string::npos)
      << text;
}

// A configuration measured twice keeps its pair: which row is wrong cannot be told.
TEST(DiagnoseGlitches, AConfigurationMeasuredTwiceNamesThePair) {
  Campaign c = campaign(42);
  // 40 configurations measured a second time, one of them 2 mm off
  for (int k = 0; k < 40; ++k) {
    const std::vector<Measurement> rep = repeated(c.truth, c.fit.rows[static_cast<size_t>(5 * k)], 1, 0.02, k == 3 ? std::vector<int>{0} : std::vector<int>{},
                                                  Eigen::Vector3d(0, 2.0, 0), 2000 + k, 100 + static_cast<std::uint64_t>(k));
    c.fit.rows.push_back(rep.front());
  }
  const Diagnosis d = diagnose(c.nominal, c.fit, nullptr, DiagnoseOptions{});
  const Floors& fl = d.floors;
  EXPECT_EQ(fl.repeat_pairs, 40);
  ASSERT_EQ(fl.glitches.size(), 1u) << diagnosisText(d);
  EXPECT_EQ(fl.glitches[0].line_a, 15 + 2);  // row 15 of the campaign (line 17)
  EXPECT_EQ(fl.glitches[0].line_b, 2003);
  EXPECT_EQ(fl.glitches[0].measurements, 2);
  EXPECT_NEAR(fl.glitches[0].distance_mm, 2.0, 0.15);
  EXPECT_EQ(fl.repeat_groups, 39);
  EXPECT_EQ(fl.repeat_dof, 3.0 * 39);
}

}  // namespace
}  // namespace accura::calib
