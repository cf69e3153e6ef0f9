// The joint_map effect (calib/joint_map.h): the spline and its taper against independent
// expectations, the analytic Jacobian columns against central finite differences, the robot
// file round trip, identification of a per-joint cyclic error on a simulated robot, and
// several data sets each from its own station.
#include <gtest/gtest.h>

#include <Eigen/QR>

#include <cmath>
#include <limits>
#include <map>
#include <filesystem>

#include "accura/calib/errors.h"
#include "accura/calib/identify.h"
#include "accura/calib/joint_map.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"
#include "test_util.h"

namespace accura::calib {
namespace {


// A map on [lower, upper] whose coefficients sample amp * sin(cycles * q + phase) at the
// coefficients' Greville points (q in deg; cycles per revolution).
JointMap cyclicMap(double lower, double upper, double knot, double amp_rad, double cycles, double phase) {
  JointMap m = makeJointMap(lower, upper, knot);
  for (size_t k = 0; k < m.coef.size(); ++k) {
    const double q = m.lower + (static_cast<double>(k) - 1.0) * m.knot();
    m.coef[k] = amp_rad * std::sin(cycles * q * kDegToRad + phase);
  }
  return m;
}

TEST(JointMap, ReproducesLinearFunctionsAndIsZeroBeyondTheTaper) {
  // cubic B-splines reproduce a linear function from its values at the Greville points
  JointMap m = makeJointMap(-50, 70, 4);
  EXPECT_EQ(m.intervals, 30);
  EXPECT_DOUBLE_EQ(m.knot(), 4.0);
  for (size_t k = 0; k < m.coef.size(); ++k) m.coef[k] = 1e-3 * (2.0 + 0.01 * (m.lower + (k - 1.0) * m.knot()));
  for (double q : {-50.0, -13.3, 0.0, 42.7, 70.0}) {
    double slope = 0;
    EXPECT_NEAR(jointMapValue(m, q, &slope), 1e-3 * (2.0 + 0.01 * q), 1e-15) << q;
    EXPECT_NEAR(slope, 1e-5, 1e-15) << q;
  }
  // continuous at the ends, tapered to zero over one knot, zero beyond
  const double edge = jointMapValue(m, 70.0);
  EXPECT_NEAR(jointMapValue(m, 70.0 + 1e-9), edge, 1e-12);
  EXPECT_NEAR(jointMapValue(m, 72.0), 0.5 * edge, 1e-15);  // half way: cosine taper 0.5
  EXPECT_EQ(jointMapValue(m, 74.0), 0.0);
  EXPECT_EQ(jointMapValue(m, 200.0), 0.0);
  EXPECT_EQ(jointMapValue(m, -54.0), 0.0);
  EXPECT_EQ(jointMapValue(JointMap{}, 3.0), 0.0);
}

TEST(JointMap, SlopeMatchesFiniteDifferences) {
  const JointMap m = cyclicMap(-100, 80, 2.5, 5e-4, 17, 0.3);
  const double h = 1e-6;  // deg
  for (double q : {-103.1, -100.0 - 0.4, -99.9, -37.21, 0.0, 12.5, 79.3, 81.7}) {
    double slope = 0;
    jointMapValue(m, q, &slope);
    const double fd = (jointMapValue(m, q + h) - jointMapValue(m, q - h)) / (2 * h);
    EXPECT_NEAR(slope, fd, 1e-9) << q;  // rad per deg
  }
}

TEST(JointMap, CentringRowsMeasureMeanAndTrend) {
  JointMap m = cyclicMap(0, 90, 3, 1e-3, 17, 0.0);
  std::vector<double> q;
  for (int i = 0; i <= 900; ++i) q.push_back(0.1 * i);
  const auto rows = jointMapCentringRows(m, q, 2);
  ASSERT_EQ(rows.size(), 6u);
  // the row applied to the coefficients equals the mean of the map over q (independent sum)
  double mean = 0, dot = 0;
  for (double v : q) mean += jointMapValue(m, v) / double(q.size());
  for (size_t k = 0; k < m.coef.size(); ++k) dot += rows[0][k] * m.coef[k];
  EXPECT_NEAR(dot, mean, 1e-15);
  // the sin(q) row equals the mean of m(q) sin(q) (q in rad)
  double ms = 0, dots = 0;
  for (double v : q) ms += jointMapValue(m, v) * std::sin(v * kDegToRad) / double(q.size());
  for (size_t k = 0; k < m.coef.size(); ++k) dots += rows[2][k] * m.coef[k];
  EXPECT_NEAR(dots, ms, 1e-15);
  // a constant map has no trend
  for (double& c : m.coef) c = 1.0;
  double trend = 0;
  for (size_t k = 0; k < m.coef.size(); ++k) trend += rows[1][k] * m.coef[k];
  EXPECT_NEAR(trend, 0.0, 1e-12);
}

TEST(JointMap, TooManyCoefficientsAreRefusedBeforeAnySolve) {
  // six joints over 180 deg each: 0.5 deg gives 6 x (360 + 3) = 2178 coefficients (within the
  // limit), 0.1 deg 6 x 1803 = 10818 (refused, naming the spacing that fits)
  const std::vector<JointRange> six(6, JointRange{-90, 90});
  EXPECT_NO_THROW(checkJointMapSize(six, 0.5));
  try {
    checkJointMapSize(six, 0.1);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("gives 10818 map coefficients"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("a spacing of at least 0.4"), std::string::npos) << e.what();
  }
  // identify refuses it at once, with the smoothing stated or chosen by cross-validation
  SimulateOptions o;
  o.effects = {"geometric"};
  o.poses = 100;
  const RobotModel nominal = test::loadBundled("kuka_kr16");
  const MeasurementSet data = simulateMeasurements(perturbModel(nominal, o), o);
  for (const double smoothing : {0.003, std::numeric_limits<double>::quiet_NaN()}) {
    IdentifyOptions io;
    io.groups = {"geometric", "joint_map@0.01deg"};
    io.joint_map_smoothing = smoothing;
    EXPECT_THROW(identify(nominal, data, io, nullptr), InputError) << smoothing;
  }
}

TEST(JointMap, KnotSpacingIsParsedWithItsUnit) {
  double k = 0;
  std::string unit, error;
  EXPECT_TRUE(parseJointMapKnot("3deg", &k, &unit, &error));
  EXPECT_EQ(k, 3.0);
  EXPECT_EQ(unit, "deg");
  EXPECT_TRUE(parseJointMapKnot("2.5", &k, &unit, &error));
  EXPECT_EQ(k, 2.5);
  for (const char* bad : {"", "deg", "-1deg", "0", "3 deg", "3rad", "nan"})
    EXPECT_FALSE(parseJointMapKnot(bad, &k, &unit, &error)) << bad;
  IdentifyOptions o;
  o.groups = {"geometric", "joint_map:j2+j3@3deg"};
  EXPECT_TRUE(o.IsValid(&error)) << error;
  o.groups = {"gear_periodic@3deg"};
  EXPECT_FALSE(o.IsValid(&error));
  o.groups = {"joint_map@x"};
  EXPECT_FALSE(o.IsValid(&error));
}

RobotModel ur10WithMaps() {
  RobotModel m = test::loadBundled("ur10");
  m.deviations.joint_map[1] = cyclicMap(-150, 20, 3, 6e-4, 17, 0.2);
  m.deviations.joint_map[2] = cyclicMap(-120, 130, 2, 4e-4, 17, 1.1);
  m.deviations.links[2].da_mm = 0.3;
  m.deviations.compliance[1] = 2e-6;
  return m;
}

TEST(JointMap, JacobianColumnsMatchCentralFiniteDifferences) {
  const RobotModel model = ur10WithMaps();
  std::vector<ParamInfo> layout;
  for (const ParamInfo& p : parameterLayout(model))
    if (p.kind == ParamKind::kJointMap) layout.push_back(p);
  ASSERT_EQ(layout.size(), model.deviations.joint_map[1].coef.size() + model.deviations.joint_map[2].coef.size());
  PoseContext ctx;
  KinematicWorkspace ws;
  Eigen::MatrixXd J;
  // inside both maps, in j2's lower taper, beyond j2's taper
  for (const Eigen::VectorXd& q : {(Eigen::VectorXd(6) << 10, -47.3, 33.1, -80, 95, 12).finished(),
                                   (Eigen::VectorXd(6) << -30, -151.2, -119.9, 40, -60, 0).finished(),
                                   (Eigen::VectorXd(6) << 70, 30, 100, 0, 45, -90).finished()}) {
    const Eigen::Isometry3d T = parameterJacobian(model, layout, q, ctx, ws, J);
    double max_abs = 0;
    for (size_t k = 0; k < layout.size(); ++k) {
      const double h = 1e-6;  // rad
      RobotModel plus = model, minus = model;
      setParameter(plus.deviations, layout[k], getParameter(model.deviations, layout[k]) + h);
      setParameter(minus.deviations, layout[k], getParameter(model.deviations, layout[k]) - h);
      const Eigen::Isometry3d Tp = forwardKinematics(plus, q, ctx, ws), Tm = forwardKinematics(minus, q, ctx, ws);
      Vector6d fd;
      fd.head<3>() = (Tp.translation() - Tm.translation()) / (2 * h);
      fd.tail<3>() = logSO3(Tp.linear() * Tm.linear().transpose()) / (2 * h);
      EXPECT_LT((J.col(static_cast<Eigen::Index>(k)) - fd).norm(), 1e-5 * std::max(1.0, fd.norm()))
          << layout[k].name << " at q1 " << q[0];  // mm/rad and rad/rad
      max_abs = std::max(max_abs, fd.norm());
      (void)T;
    }
    EXPECT_GT(max_abs, 100.0);  // some coefficient moves the tool (mm per rad) at each pose
  }
}

TEST(JointMap, JointJacobianIncludesTheMapSlope) {
  const RobotModel model = ur10WithMaps();
  const Eigen::VectorXd q = (Eigen::VectorXd(6) << 10, -47.3, 33.1, -80, 95, 12).finished();
  KinematicWorkspace ws;
  PoseContext ctx;
  const auto Jq = jointJacobian(model, q, ctx, ws);
  // compliance is neglected by jointJacobian: compare on the model without it
  RobotModel nc = model;
  nc.deviations.compliance.assign(6, 0.0);
  const auto Jn = jointJacobian(nc, q, ctx, ws);
  for (int i = 1; i <= 2; ++i) {
    const double h = 1e-5;  // deg
    Eigen::VectorXd qp = q, qm = q;
    qp[i] += h;
    qm[i] -= h;
    const Eigen::Isometry3d Tp = forwardKinematics(nc, qp, ctx, ws), Tm = forwardKinematics(nc, qm, ctx, ws);
    const Eigen::Vector3d fd = (Tp.translation() - Tm.translation()) / (2 * h);
    EXPECT_LT((Jn.col(i).head<3>() - fd).norm(), 1e-6) << "joint " << i + 1;  // mm per deg
    // the map's slope is part of it: without the map the column differs by more than that
    RobotModel nm = nc;
    nm.deviations.joint_map[static_cast<size_t>(i)] = JointMap{};
    EXPECT_GT((jointJacobian(nm, q, ctx, ws).col(i).head<3>() - fd).norm(), 1e-4) << "joint " << i + 1;
  }
  (void)Jq;
}

TEST(JointMap, RobotFileKeepsMapsAndFittedRanges) {
  RobotModel m = ur10WithMaps();
  m.deviations.fit_range.assign(6, JointRange{-10, 10});
  m.deviations.fit_range[1] = {-150, 20};
  const std::string dir = test::tempDir("joint_map_io");
  writeRobotFile(dir + "/m.xml", m);
  const RobotModel r = readRobotFile(dir + "/m.xml");
  ASSERT_EQ(r.deviations.joint_map[2].coef.size(), m.deviations.joint_map[2].coef.size());
  EXPECT_EQ(r.deviations.fit_range[1].lower, -150);
  EXPECT_EQ(r.deviations.fit_range[1].upper, 20);
  EXPECT_TRUE(r.deviations.joint_map[0].empty());
  for (const Eigen::VectorXd& q : {(Eigen::VectorXd(6) << 10, -47.3, 33.1, -80, 95, 12).finished(),
                                   (Eigen::VectorXd(6) << -30, -151.2, -119.9, 40, -60, 0).finished()})
    EXPECT_LT((forwardKinematics(r, q).translation() - forwardKinematics(m, q).translation()).norm(), 1e-9);  // mm
  // a map with a wrong number of values is an error with the file's line
  std::string text = test::readText(dir + "/m.xml");
  const size_t pos = text.find("intervals=\"");
  text.replace(pos, 11, "intervals=\"1");  // e.g. 56 -> 156 intervals: too few values
  test::writeText(dir + "/bad.xml", text);
  try {
    readRobotFile(dir + "/bad.xml");
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("values, found"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("bad.xml:"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

// Which joints of a pose lie outside the fitted ranges, and by how much (compensate's warning).
TEST(JointMap, OutsideFitRangesNamesTheJointsOfFittedEffects) {
  RobotModel m = ur10WithMaps();  // maps on some joints
  Eigen::VectorXd q(6);
  q << 10, -47.3, 33.1, -80, 95, 12;
  // no fitted ranges: the maps' intervals (joint 2 -150..20, joint 3 -120..130) are the ranges;
  // the other joints have none to compare with
  m.deviations.fit_range.clear();
  std::vector<OutsideFitRange> o = outsideFitRanges(m, q);
  EXPECT_TRUE(o.empty());
  q[1] = 27.5;
  o = outsideFitRanges(m, q);
  ASSERT_EQ(o.size(), 1u);
  EXPECT_EQ(o[0].joint, 2);
  EXPECT_NEAR(o[0].beyond, 7.5, 1e-12);  // deg
  // with fitted ranges and a compliance every joint depends on: joint 2 at -47.3 lies 12.7 deg
  // above -150..-60, joint 5 at 95 lies 5 deg above 0..90, the others inside
  q[1] = -47.3;
  m.deviations.fit_range.assign(6, JointRange{-180, 180});
  m.deviations.fit_range[1] = {-150, -60};
  m.deviations.fit_range[4] = {0, 90};
  o = outsideFitRanges(m, q);
  ASSERT_EQ(o.size(), 2u);
  EXPECT_EQ(o[0].joint, 2);
  EXPECT_NEAR(o[0].beyond, 12.7, 1e-9);
  EXPECT_EQ(o[1].joint, 5);
  EXPECT_NEAR(o[1].beyond, 5.0, 1e-9);
  EXPECT_THROW(outsideFitRanges(m, Eigen::VectorXd::Zero(5)), ArgumentError);
}

// A simulated tracker campaign: 0.02 mm noise per axis, written in std columns.
SimulateOptions trackerCampaign(std::uint64_t seed) {
  SimulateOptions sim;
  sim.seed = seed;
  sim.noise_mm = 0.02;
  sim.write_std = true;
  return sim;
}

// The robot perturbed as `sim` says, with a cyclic error of 17 cycles per revolution (0.5 mrad)
// on joints 2 and 3 over their whole ranges and 5 deg beyond.
RobotModel cyclicTruth(const RobotModel& nominal, const SimulateOptions& sim) {
  RobotModel truth = perturbModel(nominal, sim);
  for (int j : {1, 2}) {
    const JointSpec& js = nominal.nominal.joints[static_cast<size_t>(j)];
    truth.deviations.joint_map[static_cast<size_t>(j)] = cyclicMap(js.lower - 5, js.upper + 5, 1.0, 5e-4, 17, 0.7 * j);
  }
  return truth;
}

// A KR 16 whose joints 2 and 3 carry a cyclic error of 17 cycles per revolution (0.5 mrad):
// the geometric model cannot follow it; joint_map recovers it, all but its projection on the
// slow functions a map leaves to the parametric effects (a constant, a trend and harmonics 1
// and 2 over the fit data, kJointMapCentredHarmonics; here about 8% of the sine's amplitude, and
// the maps are fitted after the geometry, to what it leaves).
TEST(JointMap, IdentifyRecoversACyclicJointErrorToTheNoiseFloor) {
  const RobotModel nominal = test::loadBundled("kuka_kr16");
  SimulateOptions sim;
  sim.seed = 11;
  sim.noise_mm = 0.02;
  const RobotModel truth = cyclicTruth(nominal, sim);
  sim.poses = 1500;
  const MeasurementSet fit = simulateMeasurements(truth, sim);
  sim.seed = 12;
  sim.poses = 400;
  const MeasurementSet val = simulateMeasurements(truth, sim);
  const double floor_mm = 0.02 * std::sqrt(3.0);  // RMS of the 3-D noise

  IdentifyOptions geo;
  geo.groups = {"geometric"};
  IdentifySummary sg;
  const RobotModel g = identify(nominal, fit, geo, &sg);
  const double rms_geo = evaluate(g, val).rms_mm;
  EXPECT_GT(rms_geo, 5 * floor_mm);

  IdentifyOptions mo;
  mo.groups = {"geometric", "joint_map:j2+j3@3deg"};
  mo.joint_map_smoothing = 0.01;
  IdentifySummary sm;
  const RobotModel mm = identify(nominal, fit, mo, &sm);
  const double rms_map = evaluate(mm, val).rms_mm;
  EXPECT_LT(rms_map, 0.2 * rms_geo);
  EXPECT_LT(rms_map, 2.5 * floor_mm) << "geometric alone " << rms_geo;
  ASSERT_EQ(sm.joint_maps.size(), 2u);
  // the map lives on the fit data's range of the joint, nowhere else
  EXPECT_EQ(sm.joint_maps[0].joint, 2);
  EXPECT_DOUBLE_EQ(sm.joint_maps[0].lower, sm.coverage[1].lower);
  EXPECT_DOUBLE_EQ(sm.joint_maps[0].upper, sm.coverage[1].upper);
  EXPECT_TRUE(mm.deviations.joint_map[0].empty());
  // the recovered map follows the truth up to the slow functions it is kept free of
  const JointMap& got = mm.deviations.joint_map[1];
  const JointMap& want = truth.deviations.joint_map[1];
  std::vector<double> qs, d;
  for (double q = got.lower; q <= got.upper; q += 0.5) {
    qs.push_back(q);
    d.push_back(jointMapValue(got, q) - jointMapValue(want, q));
  }
  // remove the best combination of 1, q and harmonics 1 and 2 from the difference, then compare
  // with the amplitude 5e-4 rad
  Eigen::MatrixXd X(static_cast<Eigen::Index>(qs.size()), 2 + 2 * kJointMapCentredHarmonics);
  for (size_t i = 0; i < qs.size(); ++i) {
    const Eigen::Index r = static_cast<Eigen::Index>(i);
    X(r, 0) = 1;
    X(r, 1) = qs[i] / 100;
    for (int h = 1; h <= kJointMapCentredHarmonics; ++h) {
      X(r, 2 * h) = std::sin(h * qs[i] * kDegToRad);
      X(r, 2 * h + 1) = std::cos(h * qs[i] * kDegToRad);
    }
  }
  const Eigen::VectorXd dv = Eigen::Map<const Eigen::VectorXd>(d.data(), static_cast<Eigen::Index>(d.size()));
  const Eigen::VectorXd fast = dv - X * X.colPivHouseholderQr().solve(dv);
  const double rr = fast.squaredNorm(), nq = double(qs.size());
  EXPECT_LT(std::sqrt(rr / nq), 0.15 * 5e-4 / std::sqrt(2.0));  // rad: within 15% of the sine's RMS
  // outside the fitted range of j2 the model has no map
  Eigen::VectorXd q = Eigen::VectorXd::Zero(6);
  q[1] = got.upper + 2 * got.taper;
  EXPECT_EQ(jointMapValue(got, q[1]), 0.0);
}

// The cross-validation tries the knot spacings from the widest down and a finer one only while
// the last one gained: a slow error (3 cycles per revolution, which 3 deg knots already follow)
// stops the search after 2 deg; a fast one (60 cycles, a 6 deg period: two 3 deg knots a period
// cannot follow it) needs every spacing tried. (40 cycles, a 9 deg period, was the fast case until
// the maps' coefficients the data barely reach were pulled to zero, jointMapSparseRows: that
// regularises the 3 deg knots' fit, 0.088 -> 0.083 mm held out, and the 2 deg knots' gain fell
// from 11 % to 5.5 %.)
TEST(JointMap, CrossValidationTriesFinerKnotsOnlyWhileTheyGain) {
  const RobotModel nominal = test::loadBundled("kuka_kr16");
  for (const double cycles : {3.0, 60.0}) {
    SimulateOptions sim;
    sim.seed = 21;
    sim.noise_mm = 0.02;
    RobotModel truth = perturbModel(nominal, sim);
    const JointSpec& js = nominal.nominal.joints[1];
    truth.deviations.joint_map[1] = cyclicMap(js.lower - 5, js.upper + 5, 0.5, 5e-4, cycles, 0.4);
    sim.poses = 600;
    const MeasurementSet fit = simulateMeasurements(truth, sim);
    IdentifyOptions o;
    o.groups = {"geometric", "joint_map:j2"};
    IdentifySummary s;
    identify(nominal, fit, o, &s);
    std::map<double, double> best;  // knot -> its best held-out RMS
    for (const auto& c : s.joint_map_cv)
      best[c.knot] = best.count(c.knot) ? std::min(best[c.knot], c.cv_rms_mm) : c.cv_rms_mm;
    SCOPED_TRACE(cycles);
    ASSERT_TRUE(best.count(3.0) && best.count(2.0));
    if (cycles == 3.0) {
      EXPECT_GE(best[2.0], best[3.0]);
      EXPECT_EQ(s.joint_map_cv_knots_not_tried, std::vector<double>{1.5});
      EXPECT_EQ(best.count(1.5), 0u);
    } else {
      EXPECT_LT(best[2.0], 0.5 * best[3.0]);  // 3 deg knots do not follow a 6 deg period (0.072 vs 0.241 mm)
      EXPECT_TRUE(s.joint_map_cv_knots_not_tried.empty());
      EXPECT_EQ(best.count(1.5), 1u);
    }
  }
}

// The interval a map is defined on leaves out a sparse tail: 1000 values spread evenly over
// [-190, -128] and one more at -90 (Series_C's joint 2 reaches -90 deg with one pose). The mean
// count per 3 deg window is 1001 * 3 / 100 = 30.03, a fifth of it 6.006, so an end needs 7
// values within 3 deg: the upper end is the bulk's, the lower end stays.
TEST(JointMap, SupportLeavesOutSparseTails) {
  std::vector<double> q;
  for (int i = 0; i < 1000; ++i) q.push_back(-190.0 + 62.0 * i / 999.0);
  q.push_back(-90.0);
  const JointRange r = jointMapSupport(q);
  EXPECT_DOUBLE_EQ(r.lower, -190.0);
  // the highest value with 7 values within 3 deg below it: the bulk's top, -128 (spacing 0.062)
  EXPECT_DOUBLE_EQ(r.upper, -128.0);
  // without the tail, the whole range
  q.pop_back();
  const JointRange all = jointMapSupport(q);
  EXPECT_DOUBLE_EQ(all.lower, -190.0);
  EXPECT_DOUBLE_EQ(all.upper, -128.0);
  // a lone value at each end: both ends move in to the bulk
  q.push_back(-250.0);
  q.push_back(-100.0);
  const JointRange both = jointMapSupport(q);
  EXPECT_DOUBLE_EQ(both.lower, -190.0);
  EXPECT_DOUBLE_EQ(both.upper, -128.0);
  // two clusters 3 values each, nothing dense enough to trim to: the whole range
  const JointRange few = jointMapSupport({0.0, 0.5, 1.0, 50.0, 50.5, 51.0});
  EXPECT_DOUBLE_EQ(few.lower, 0.0);
  EXPECT_DOUBLE_EQ(few.upper, 51.0);
  EXPECT_THROW(jointMapSupport({}), ArgumentError);
  EXPECT_THROW(jointMapSupport({1.0, 2.0}, 0.0), ArgumentError);
  EXPECT_THROW(jointMapSupport({1.0, 2.0}, std::nan("")), ArgumentError);
}

// A revolute joint's map is a function of its angle modulo one turn (the gear's and the
// encoder's errors repeat with each turn; a UR's joints turn +-360 deg): the map, the FK and the
// Jacobian at q and q +- 360 deg are the same; data from two turns make one turn's interval; a
// pose a turn away from the fitted range is not outside it; the robot file keeps the period.
TEST(JointMap, ARevoluteJointsMapRepeatsWithEachTurn) {
  JointMap m = makeJointMap(-175, -52, 3, 360);
  EXPECT_EQ(m.period, 360.0);
  for (size_t k = 0; k < m.coef.size(); ++k) m.coef[k] = 5e-4 * std::sin(17 * (m.lower + (k - 1.0) * m.knot()) * kDegToRad);
  for (double q : {-170.2, -120.0, -53.5, -52.0 + 0.4 * m.taper}) {
    double s0 = 0, s1 = 0, s2 = 0;
    const double v = jointMapValue(m, q, &s0);
    EXPECT_NE(v, 0.0) << q;
    EXPECT_NEAR(jointMapValue(m, q + 360, &s1), v, 1e-15) << q;  // rad
    EXPECT_NEAR(jointMapValue(m, q - 720, &s2), v, 1e-15) << q;
    EXPECT_NEAR(s1, s0, 1e-12) << q;  // rad per deg
    EXPECT_NEAR(s2, s0, 1e-12) << q;
    // the slope a turn away against central differences there
    const double h = 1e-6;  // deg
    EXPECT_NEAR((jointMapValue(m, q + 360 + h) - jointMapValue(m, q + 360 - h)) / (2 * h), s1, 1e-9) << q;
  }
  // away from the interval on the circle: zero in every turn (100 deg is 85 deg below -175 a turn down)
  for (double q : {100.0, -260.0, 0.0, 460.0}) EXPECT_EQ(jointMapValue(m, q), 0.0) << q;
  // without a period, as before: zero a turn away
  JointMap flat = m;
  flat.period = 0;
  EXPECT_EQ(jointMapValue(flat, -120.0 + 360), 0.0);
  // an interval wider than a turn less its tapers is narrowed about its centre
  const JointMap wide = makeJointMap(-200, 200, 3, 360);
  EXPECT_NEAR(wide.lower, -177.0, 1e-12);
  EXPECT_NEAR(wide.upper, 177.0, 1e-12);
  EXPECT_LE(wide.upper - wide.lower + 2 * wide.taper, 360.0 + 1e-9);
  EXPECT_EQ(makeJointMap(-10, 10, 200, 360).period, 0.0);  // a knot spacing that would leave less than half a turn
  EXPECT_THROW(makeJointMap(-10, 10, 3, -360), ArgumentError);

  // the support: data in two turns of the same angles (-250..-200 and 110..160 deg) make one
  // interval of 50 deg (without a period: 410 deg), and data across +-180 deg one of 20 deg
  std::vector<double> two_turns, across;
  for (int i = 0; i <= 500; ++i) {
    two_turns.push_back(-250.0 + 0.1 * i);
    two_turns.push_back(110.0 + 0.1 * i);
  }
  for (int i = 0; i <= 100; ++i) {
    across.push_back(170.0 + 0.1 * i);
    across.push_back(-190.0 + 0.1 * i);  // 170..180 deg a turn down
    across.push_back(-180.0 + 0.1 * i);
  }
  const JointRange r2 = jointMapSupport(two_turns, kJointMapSupportWindow, 360);
  EXPECT_NEAR(r2.upper - r2.lower, 50.0, 1e-9);
  EXPECT_NEAR(std::remainder(r2.lower + 250.0, 360.0), 0.0, 1e-9);
  EXPECT_NEAR(jointMapSupport(two_turns).upper - jointMapSupport(two_turns).lower, 410.0, 1e-9);
  const JointRange ra = jointMapSupport(across, kJointMapSupportWindow, 360);
  EXPECT_NEAR(ra.upper - ra.lower, 20.0, 1e-9);
  // data within one turn keep their values bit for bit
  const JointRange one = jointMapSupport({-175.5, -120.25, -52.125}, kJointMapSupportWindow, 360);
  EXPECT_EQ(one.lower, -175.5);
  EXPECT_EQ(one.upper, -52.125);

  // the complete model: FK and parameter Jacobian at q and with joint 1 a turn away
  RobotModel model = test::loadBundled("ur10");
  model.deviations.joint_map[0] = m;
  const std::vector<ParamInfo> layout = parameterLayout(model);
  PoseContext ctx;
  KinematicWorkspace ws;
  Eigen::VectorXd q(6);
  q << -120, -80, 60, -40, 90, 10;
  Eigen::MatrixXd J0, J1;
  const Eigen::Isometry3d T0 = parameterJacobian(model, layout, q, ctx, ws, J0);
  Eigen::VectorXd q1 = q;
  q1[0] += 360;
  const Eigen::Isometry3d T1 = parameterJacobian(model, layout, q1, ctx, ws, J1);
  EXPECT_LT((T1.translation() - T0.translation()).norm(), 1e-9);  // mm
  for (size_t k = 0; k < layout.size(); ++k) {
    const Eigen::Index c = static_cast<Eigen::Index>(k);
    if (layout[k].kind == ParamKind::kJointScale) continue;  // d/d(scale) is q itself: not periodic
    EXPECT_LT((J1.col(c) - J0.col(c)).norm(), 1e-9 * std::max(1.0, J0.col(c).norm())) << layout[k].name;
  }
  // the map moves the tool there (so the equality is not the nominal robot's periodicity alone)
  RobotModel nomap = model;
  nomap.deviations.joint_map[0] = JointMap{};
  EXPECT_GT((forwardKinematics(nomap, q1, ctx, ws).translation() - T1.translation()).norm(), 0.05);  // mm

  // a pose a turn away from the fitted range is inside it
  model.deviations.fit_range.assign(6, JointRange{-360, 360});
  model.deviations.fit_range[0] = {-175, -52};
  EXPECT_TRUE(outsideFitRanges(model, q1).empty());
  q1[0] = 100;  // 85 deg below -175 a turn down
  const std::vector<OutsideFitRange> o = outsideFitRanges(model, q1);
  ASSERT_EQ(o.size(), 1u);
  EXPECT_NEAR(o[0].beyond, 85.0, 1e-9);  // deg
  EXPECT_NEAR(beyondFitRange({-175, -52}, 100, 0), 152.0, 1e-12);
  // a joint scale does not repeat: then the range is q's own
  model.deviations.joint_scale[0] = 1e-4;
  EXPECT_EQ(fitRangePeriod(model, 0), 0.0);

  // the robot file keeps the period; without the attribute (older files) there is none
  model.deviations.joint_scale[0] = 0;
  const std::string dir = test::tempDir("joint_map_period");
  writeRobotFile(dir + "/m.xml", model);
  const RobotModel back = readRobotFile(dir + "/m.xml");
  EXPECT_EQ(back.deviations.joint_map[0].period, 360.0);
  std::string text = test::readText(dir + "/m.xml");
  const size_t at = text.find(" period=\"360\"");
  ASSERT_NE(at, std::string::npos);
  test::writeText(dir + "/old.xml", std::string(text).erase(at, 13));
  EXPECT_EQ(readRobotFile(dir + "/old.xml").deviations.joint_map[0].period, 0.0);
  test::writeText(dir + "/bad.xml", std::string(text).replace(at, 13, " period=\"100\""));
  try {
    readRobotFile(dir + "/bad.xml");
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("attribute 'period': expected 360 (one turn), at least the interval and its tapers"), std::string::npos)
        << e.what();
  }
  std::filesystem::remove_all(dir);
}

// Joint 6 held at one angle, written -90 deg in half the poses and 270 deg in the others: the
// values span a turn, the angles none. No map of that joint (a warning says why), the rest of the
// identification as usual; before, the map's interval came out empty and identify threw.
TEST(JointMap, AJointHeldAtOneAngleWrittenATurnApartGetsNoMap) {
  const RobotModel nominal = test::loadBundled("ur10");
  SimulateOptions sim = trackerCampaign(31);
  sim.poses = 200;
  const RobotModel truth = perturbModel(nominal, sim);
  MeasurementSet data = simulateMeasurements(truth, sim);
  KinematicWorkspace ws;
  for (size_t i = 0; i < data.rows.size(); ++i) {
    Measurement& m = data.rows[i];
    m.q[5] = i % 2 ? -90.0 : 270.0;
    m.p_world_mm = forwardKinematics(truth, m.q, m.context, ws).translation();
  }
  EXPECT_EQ(jointMapSupport(jointValues(data, 5), kJointMapSupportWindow, 360).upper -
                jointMapSupport(jointValues(data, 5), kJointMapSupportWindow, 360).lower,
            0.0);
  IdentifyOptions o;
  o.groups = {"geometric", "joint_map:j5+j6@3deg"};
  IdentifySummary s;
  const RobotModel cal = identify(nominal, data, o, &s);
  EXPECT_TRUE(cal.deviations.joint_map[5].empty());
  EXPECT_FALSE(cal.deviations.joint_map[4].empty());
  bool warned = false;
  for (const std::string& w : s.warnings) warned = warned || w.find("joint_map: j6 covers only 0 deg") != std::string::npos;
  EXPECT_TRUE(warned);
  EXPECT_LT(s.fit.rms_mm, 0.1);  // mm: the geometry fitted (noise 0.02 mm per axis)
}

// Inside the interval: the coefficients the data barely reach are pulled to zero. Values evenly
// over 0..100 deg (10 per deg) but for a gap 40..60 deg holding one value at 50 (Series_B's joint
// 3 near 0 deg): every coefficient whose basis lies inside the gap gets a row, none whose basis
// lies in the dense part, not even at the interval's ends (where a boundary coefficient's basis
// reaches into the interval only in part); without the gap, no row at all.
TEST(JointMap, SparseRowsPullTheCoefficientsOfAGapToZero) {
  std::vector<double> q;
  for (int i = 0; i <= 1000; ++i) {
    const double v = 0.1 * i;
    if (v < 40.0 || v > 60.0) q.push_back(v);
  }
  q.push_back(50.0);
  const JointMap map = makeJointMap(0.0, 100.0, 3.0);
  const size_t K = map.coef.size();
  // each coefficient's basis support, probed
  std::vector<double> lo(K, 1e9), hi(K, -1e9);
  for (int s = 0; s <= 100000; ++s) {
    const double v = -10.0 + 120.0 * s / 100000.0;
    double w[4];
    const int f = jointMapBasis(map, v, w);
    for (int k = 0; f >= 0 && k < 4; ++k)
      if (w[k] > 0) {
        lo[static_cast<size_t>(f + k)] = std::min(lo[static_cast<size_t>(f + k)], v);
        hi[static_cast<size_t>(f + k)] = std::max(hi[static_cast<size_t>(f + k)], v);
      }
  }
  std::vector<bool> pulled(K, false);
  for (const auto& r : jointMapSparseRows(map, q)) {
    ASSERT_EQ(r.size(), K);
    int ones = 0;
    for (size_t k = 0; k < K; ++k) {
      if (r[k] == 0) continue;
      EXPECT_EQ(r[k], 1.0);
      pulled[k] = true;
      ++ones;
    }
    EXPECT_EQ(ones, 1);
  }
  int inside = 0;
  for (size_t k = 0; k < K; ++k) {
    if (lo[k] >= 40.0 && hi[k] <= 60.0) {
      EXPECT_TRUE(pulled[k]) << k;
      ++inside;
    }
    if (hi[k] < 40.0 || lo[k] > 60.0) {
      EXPECT_FALSE(pulled[k]) << k << " " << lo[k] << ".." << hi[k];
    }
  }
  EXPECT_GE(inside, 3);  // a 20 deg gap holds the bases of at least 3 coefficients of 3 deg knots
  std::vector<double> even;
  for (int i = 0; i <= 1000; ++i) even.push_back(0.1 * i);
  EXPECT_TRUE(jointMapSparseRows(map, even).empty());
}

// The maps are fitted after the other parameters, to what those leave: the geometric
// parameters and the station of a fit with maps are those of the fit without them (the same
// weighting rounds; the map solve holds them), to a thousandth of their sigma.
TEST(JointMap, MapsLeaveTheGeometricFitAsItIs) {
  const RobotModel nominal = test::loadBundled("kuka_kr16");
  SimulateOptions sim = trackerCampaign(11);
  const RobotModel truth = cyclicTruth(nominal, sim);
  sim.poses = 600;
  const MeasurementSet fit = simulateMeasurements(truth, sim);
  IdentifyOptions o;
  o.groups = {"geometric"};
  IdentifySummary sg;
  identify(nominal, fit, o, &sg);
  o.groups = {"geometric", "joint_map:j2+j3@3deg"};
  o.joint_map_smoothing = 0.003;
  IdentifySummary sm;
  identify(nominal, fit, o, &sm);
  std::map<std::string, ParameterEstimate> with;
  for (const ParameterEstimate& p : sm.parameters) with[p.name] = p;
  int compared = 0;
  for (const ParameterEstimate& p : sg.parameters) {
    ASSERT_TRUE(with.count(p.name)) << p.name;
    EXPECT_LT(std::abs(with[p.name].value - p.value), 1e-3 * p.sigma) << p.name;
    ++compared;
  }
  EXPECT_GT(compared, 20);
  EXPECT_LT(sm.fit.rms_mm, 0.8 * sg.fit.rms_mm);  // the maps did take the cyclic error
}

// identify's fit with maps agrees with the cross-validation that chose their knots and
// smoothness: the smoothness is relative to the data's weight in the final weighting (the
// unmodelled-error term estimated), as in the cross-validation. Scaled to the first round's
// weights instead (the tracker's stds alone), the penalty was far stronger than chosen and the
// fit on all data came out worse than the held-out error (the KR 16 bench: 0.179 against 0.091 mm).
TEST(JointMap, FitAgreesWithTheCrossValidationThatChoseTheSmoothing) {
  const RobotModel nominal = test::loadBundled("kuka_kr16");
  SimulateOptions sim = trackerCampaign(9);
  RobotModel truth = perturbModel(nominal, sim);
  sim.poses = 800;
  MeasurementSet fit = simulateMeasurements(truth, sim);
  // a 17-cycle error of 0.5 mrad on joints 2 and 3, at the measured points (the std columns say
  // 0.02 mm: the identification has to estimate an unmodelled-error term)
  KinematicWorkspace ws;
  for (Measurement& r : fit.rows) {
    Eigen::VectorXd q = r.q;
    for (int j : {1, 2}) q[j] += 0.5e-3 * kRadToDeg * std::sin(17 * r.q[j] * kDegToRad + j);
    r.p_world_mm += forwardKinematics(truth, q, r.context, ws).translation() - forwardKinematics(truth, r.q, r.context, ws).translation();
  }
  IdentifyOptions o;
  o.groups = {"geometric", "joint_map"};
  IdentifySummary s;
  identify(nominal, fit, o, &s);
  ASSERT_FALSE(s.joint_map_cv.empty());
  double best = std::numeric_limits<double>::infinity();
  for (const auto& c : s.joint_map_cv) best = std::min(best, c.cv_rms_mm);
  EXPECT_GT(s.model_error_mm, 0.0);
  EXPECT_LT(s.fit.rms_mm, best) << "the fit on all data is worse than the held-out error of the choice";
}

TEST(JointMap, SeveralDataSetsEachFromItsOwnStation) {
  const RobotModel nominal = test::loadBundled("kuka_kr16");
  SimulateOptions sim;
  sim.seed = 21;
  sim.poses = 250;
  const RobotModel truth = perturbModel(nominal, sim);
  const MeasurementSet a = simulateMeasurements(truth, sim);
  // the same robot seen from a second station: 1.5 m aside, turned 20 deg
  RobotModel truth2 = truth;
  truth2.nominal.T_world_base = toIsometry(XyzAbc{-900.0, 2600.0, -400.0, -70.0, -0.2, 0.5});
  sim.seed = 22;
  const MeasurementSet b = simulateMeasurements(truth2, sim);
  IdentifyOptions o;
  o.groups = {"geometric"};
  IdentifySummary s;
  const RobotModel m = identify(nominal, std::vector<MeasurementSet>{a, b}, o, &s);
  ASSERT_EQ(s.T_world_base_per_set.size(), 2u);
  // T_world_base itself shares structurally dependent parts with j1_d / j1_offset (the truth's
  // are absorbed there); the station of B relative to A is free of them
  const Eigen::Isometry3d rel = s.T_world_base_per_set[1] * s.T_world_base_per_set[0].inverse();
  const Eigen::Isometry3d rel_true = truth2.T_world_base() * truth.T_world_base().inverse();
  EXPECT_LT((rel.translation() - rel_true.translation()).norm(), 0.1);  // mm
  EXPECT_LT(Eigen::AngleAxisd(rel.linear() * rel_true.linear().transpose()).angle() * kRadToDeg, 0.001);  // deg
  EXPECT_LT(s.fit.rms_mm, 0.05);  // noise 0.02 mm per axis
  EXPECT_EQ(s.fit.n, 500);
  // told (wrongly) that they share a station: refused, naming the second set (it used to fit
  // them into one station and leave metres unexplained)
  o.same_station = true;
  try {
    identify(nominal, std::vector<MeasurementSet>{a, b}, o, nullptr);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("expected data sets that share one station"), std::string::npos) << e.what();
  }
  (void)m;
}


// A periodic term holds over a joint's limits when the data cover 162 deg or more, or reach
// within a fifth of their width of both limits (a joint that turns less than half a turn).
TEST(JointMap, APeriodicTermHoldsWhereTheDataReachTheJointsLimits) {
  JointSpec j3;  // the IRB 120's joint 3
  j3.lower = -110;
  j3.upper = 70;
  EXPECT_TRUE(periodicTermHoldsOverLimits(j3, -98.7, 60.5));    // 11.3 deg beyond, width 159.2: 7 %
  EXPECT_TRUE(periodicTermHoldsOverLimits(j3, -95.0, 55.0));    // 15 deg beyond, width 150: 10 %
  EXPECT_FALSE(periodicTermHoldsOverLimits(j3, -80.0, 50.0));   // 30 deg beyond, width 130: 23 %
  JointSpec ur;  // a UR joint, +-360 deg
  ur.lower = -360;
  ur.upper = 360;
  EXPECT_FALSE(periodicTermHoldsOverLimits(ur, -180, -45));     // Series_B's joint 1: 135 deg of 720
  EXPECT_TRUE(periodicTermHoldsOverLimits(ur, -100, 62));       // 162 deg: told apart from offset and scale
  EXPECT_FALSE(periodicTermHoldsOverLimits(ur, -100, 61.9));
  JointSpec free;  // no limits known (upper <= lower)
  EXPECT_FALSE(periodicTermHoldsOverLimits(free, -98.7, 60.5));
  EXPECT_TRUE(periodicTermHoldsOverLimits(free, -100, 62));
  JointSpec slide;
  slide.type = JointType::kPrismatic;
  slide.lower = 0;
  slide.upper = 100;
  EXPECT_FALSE(periodicTermHoldsOverLimits(slide, 0, 100));     // no period
}

}  // namespace
}  // namespace accura::calib
