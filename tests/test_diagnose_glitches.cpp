// The diagnosis' floors and glitches (diagnose.h, docs/diagnosis.md step 2): a configuration
// measured many times names its odd row once (against the configuration's robust centre),
// and the validation file's repeats are glitch-screened like the fit data's before they join
// the repeatability.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "accura/calib/diagnose.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/measurements.h"
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

struct ValidationWithGlitches {
  MeasurementSet set;
  std::vector<int> odd_lines;  // lines of the rows moved
};

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

// Rows written twice are not repeats: 12 configurations measured 4 times each (0.02 mm per axis)
// and 5 of those rows copied a second time, unchanged (an export that wrote them twice). The copies
// are named against the row they copy and left out: the pairs are those of the 48 measurements
// (12 x 6), the pooled scatter theirs (3 x 12 x 3 = 108 degrees of freedom, the value computed
// here from the 48 rows alone). With the copies in, 5 pairs of distance 0 would pull the median
// pair distance and the scatter down.
TEST(DiagnoseGlitches, RowsWrittenTwiceAreNamedAndLeftOutOfTheRepeatability) {
  Campaign c = campaign(43);
  const int first_line = 2000;
  std::vector<Measurement> rep;
  for (int k = 0; k < 12; ++k) {
    const std::vector<Measurement> r =
        repeated(c.truth, c.fit.rows[static_cast<size_t>(20 * k + 3)], 4, 0.02, {}, Eigen::Vector3d::Zero(), first_line + 10 * k,
                 static_cast<std::uint64_t>(100 + k));
    rep.insert(rep.end(), r.begin(), r.end());
  }
  // the expected scatter: the 48 measurements about their configurations' means (each
  // configuration's original row of the campaign, repeated() copies its q, is a 5th member)
  double ss = 0, dof = 0;
  for (int k = 0; k < 12; ++k) {
    std::vector<Eigen::Vector3d> g = {c.fit.rows[static_cast<size_t>(20 * k + 3)].p_world_mm};
    for (int m = 0; m < 4; ++m) g.push_back(rep[static_cast<size_t>(4 * k + m)].p_world_mm);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : g) mean += p;
    mean /= double(g.size());
    for (const auto& p : g) ss += (p - mean).squaredNorm();
    dof += 3.0 * double(g.size() - 1);
  }
  const std::vector<int> copied = {1, 9, 17, 30, 46};  // indices into rep
  std::vector<Measurement> copies;
  for (size_t k = 0; k < copied.size(); ++k) {
    Measurement r = rep[static_cast<size_t>(copied[k])];
    r.line = 3000 + static_cast<int>(k);
    copies.push_back(r);
  }
  c.fit.rows.insert(c.fit.rows.end(), rep.begin(), rep.end());
  c.fit.rows.insert(c.fit.rows.end(), copies.begin(), copies.end());
  const Diagnosis d = diagnose(c.nominal, c.fit, nullptr, DiagnoseOptions{});
  const Floors& fl = d.floors;
  ASSERT_EQ(fl.duplicated_rows.size(), copied.size()) << diagnosisText(d);
  for (size_t k = 0; k < copied.size(); ++k) {
    EXPECT_EQ(fl.duplicated_rows[k].line_a, 3000 + static_cast<int>(k));
    EXPECT_EQ(fl.duplicated_rows[k].line_b, rep[static_cast<size_t>(copied[k])].line);
  }
  EXPECT_EQ(fl.repeat_groups, 12);
  EXPECT_EQ(fl.repeat_pairs, 12 * 5 * 4 / 2);
  EXPECT_EQ(fl.repeat_dof, dof);
  EXPECT_NEAR(fl.repeat_std_axis_mm, std::sqrt(ss / dof), 1e-12);
  const std::string text = diagnosisText(d);
  EXPECT_NE(text.find("5 row(s) repeat an earlier row of their configuration exactly"), std::string::npos) << text;
  EXPECT_NE(text.find(":3000 = "), std::string::npos) << text;
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

// A validation set of 5 configurations measured 30 times each (0.02 mm per axis), 4 of its rows
// 1-2 mm off. Fit data without repeats. The validation repeats join the repeatability only
// glitch-screened: the 4 rows are named (validation file, their lines), the floor is the
// simulated noise (sqrt(3) x 0.02 = 0.0346 mm), and the floors' counts agree with each other.
ValidationWithGlitches validationWithGlitches(const Campaign& c) {
  ValidationWithGlitches v;
  v.set.file = "val.csv";
  v.set.has_std_position = c.fit.has_std_position;
  v.set.has_payload = c.fit.has_payload;
  v.set.has_temperature = c.fit.has_temperature;
  v.set.has_direction = c.fit.has_direction;
  v.set.has_time = c.fit.has_time;
  const std::vector<Eigen::Vector3d> offsets = {{1.2, 0, 0}, {0, -1.6, 0}, {0, 0, 2.0}, {1.0, 1.0, 0}};
  int line = 3;
  for (int k = 0; k < 5; ++k) {
    // configuration k: its 30 measurements; measurement 4k+3 of configuration k (k < 4) off
    std::vector<int> odd;
    if (k < 4) odd = {4 * k + 3};
    const std::vector<Measurement> rep = repeated(c.truth, c.fit.rows[static_cast<size_t>(37 * k + 1)], 30, 0.02, odd,
                                                  k < 4 ? offsets[static_cast<size_t>(k)] : Eigen::Vector3d::Zero(), line,
                                                  300 + static_cast<std::uint64_t>(k));
    if (k < 4) v.odd_lines.push_back(line + 4 * k + 3);
    v.set.rows.insert(v.set.rows.end(), rep.begin(), rep.end());
    line += 30;
  }
  return v;
}

TEST(DiagnoseGlitches, ValidationRepeatsAreScreenedBeforeTheyJoinTheFloor) {
  const Campaign c = campaign(43);
  const ValidationWithGlitches v = validationWithGlitches(c);
  const Diagnosis d = diagnose(c.nominal, c.fit, &v.set, DiagnoseOptions{});
  const Floors& fl = d.floors;
  // every pair of the validation file counted (the fit data has none): 5 x 30 x 29 / 2
  EXPECT_EQ(fl.repeat_pairs, 5 * 435);
  EXPECT_EQ(fl.repeat_pairs_validation, 5 * 435);
  EXPECT_EQ(fl.repeat_groups, 5);
  EXPECT_EQ(fl.repeat_groups_validation, 5);
  EXPECT_TRUE(std::isfinite(fl.median_pair_mm));
  // median distance of two measurements: sqrt(2) x 0.02 x 1.538 (the median of chi_3) = 0.0435 mm
  EXPECT_NEAR(fl.median_pair_mm, std::sqrt(2.0) * 0.02 * 1.538, 0.006);
  // the 4 odd rows, each once, by the validation file's lines
  ASSERT_EQ(fl.glitches.size(), 4u) << diagnosisText(d);
  std::vector<int> lines;
  for (const RepeatPair& g : fl.glitches) {
    EXPECT_TRUE(g.validation);
    EXPECT_EQ(g.index_b, -1);
    EXPECT_EQ(g.measurements, 30);
    lines.push_back(g.line_a);
  }
  std::sort(lines.begin(), lines.end());
  EXPECT_EQ(lines, v.odd_lines);
  EXPECT_NEAR(fl.glitches.front().distance_mm, 2.0, 0.1);  // the largest offset
  // the rest: 3 x (150 - 5 - 4) degrees of freedom of 0.02 mm per axis
  EXPECT_EQ(fl.repeat_dof, 3.0 * (150 - 5 - 4));
  EXPECT_NEAR(d.noise_std_axis_mm, 0.02, 0.002);  // relative sd 1/sqrt(846) = 3.4%: 3 sd
  EXPECT_NEAR(d.noise_floor_mm, std::sqrt(3.0) * 0.02, 0.0035);
  // and left out of the held-out statistics, as down-weighted rows are under cross-validation
  EXPECT_EQ(d.validation_glitch_rows_left_out, 4);
  EXPECT_EQ(d.validation_poses, 150 - 4);
  EXPECT_EQ(d.baseline.n, 150 - 4);
  EXPECT_LT(d.baseline.max_mm, 0.5);
  const std::string text = diagnosisText(d);
  EXPECT_EQ(text.find("nan"), std::string::npos) << text;
  EXPECT_NE(text.find("val.csv:" + std::to_string(v.odd_lines.front())), std::string::npos) << text;
  EXPECT_NE(text.find("5 configurations measured again (2175 pairs"), std::string::npos) << text;
}

// The command: a lost beam (0, 0, 0) in the validation file is left out as gross before the
// check for another station, which therefore stays silent (the station did not move).
TEST(DiagnoseGlitches, ALostBeamInTheValidationFileDoesNotLookLikeAnotherStation) {
  const std::string dir = test::tempDir("diag_lostbeam");
  const Campaign c = campaign(44);
  ValidationWithGlitches v = validationWithGlitches(c);
  // what the geometric model does not explain at the 5 configurations (0.4 mm each, its own
  // direction): re-registering the station on them moves it, but does not take 30% off the RMS
  const std::vector<Eigen::Vector3d> unmodelled = {{0.4, 0, 0}, {0, 0.4, 0}, {0, 0, -0.4}, {-0.23, 0.23, 0.23}, {0, -0.28, 0.28}};
  for (size_t i = 0; i < v.set.rows.size(); ++i) v.set.rows[i].p_world_mm += unmodelled[i / 30];
  writeMeasurementsCsv(dir + "/fit.csv", c.fit, c.nominal.dof());
  writeMeasurementsCsv(dir + "/val.csv", v.set, c.nominal.dof());
  const std::string cmd = "diagnose --robot kuka_kr16 --tool 80,40,150 --data fit.csv --validate val.csv --json d.json";
  const test::CliRun clean = test::runAccuraIn(dir, cmd);
  ASSERT_EQ(clean.code, 0) << clean.out << clean.err;
  EXPECT_EQ(clean.err.find("another station"), std::string::npos) << clean.err;
  v.set.rows[75].p_world_mm = Eigen::Vector3d::Zero();  // the beam lost
  writeMeasurementsCsv(dir + "/val.csv", v.set, c.nominal.dof());
  const test::CliRun r = test::runAccuraIn(dir, cmd);
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("left out of the diagnosis"), std::string::npos) << r.out;
  EXPECT_EQ(r.err.find("another station"), std::string::npos) << r.err;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace accura::calib
