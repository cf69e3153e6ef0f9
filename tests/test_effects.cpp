// The effect catalogue in the model (kinematics.h): each effect against an independent
// expectation (the same motion written as a shifted joint value or as scaled DH lengths),
// the analytic Jacobian columns of every effect against central differences (with payload,
// temperature and directions in the context), the parameter names, the context read from a
// measurement file, and the simulated effects (including the out-of-catalogue coupling).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <random>

#include "accura/calib/errors.h"
#include "accura/calib/joint_map.h"
#include "accura/calib/kinematic_core.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/measurements.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"
#include "test_util.h"

namespace accura::calib {
namespace {

PoseContext randomContext(int dof, std::mt19937_64& rng) {
  PoseContext c;
  c.payload_kg = std::uniform_real_distribution<double>(0, 12)(rng);
  c.temp_c = std::uniform_real_distribution<double>(12, 32)(rng);
  c.dir.resize(static_cast<size_t>(dof));
  for (int& d : c.dir) d = (rng() & 1) ? 1 : -1;
  return c;
}

// A pose error small enough to be a difference of two FK results of the same model.
double poseDiff(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.matrix() - b.matrix()).topRows(3).cwiseAbs().maxCoeff();
}

// Each effect is a shift of the joint value (or a scaling of the DH lengths): the model with
// the effect at q equals the model without it at the shifted joint value.
TEST(Effects, JointEffectsEqualAShiftedJointValue) {
  std::mt19937_64 rng(4);
  for (const char* name : {"kuka_kr16", "scara"}) {
    const RobotModel base = test::loadBundled(name);
    const int n = base.dof();
    for (int trial = 0; trial < 10; ++trial) {
      const int i = static_cast<int>(rng() % static_cast<unsigned>(n));
      const JointSpec& j = base.nominal.joints[i];
      const bool revolute = j.type == JointType::kRevolute;
      const Eigen::VectorXd q = test::randomQ(base, rng);
      const PoseContext ctx = randomContext(n, rng);
      const double qi = revolute ? q[i] * kDegToRad : q[i];
      // expected joint-space term (rad or mm) of each effect, written from the formulas
      RobotModel scale = base, backlash = base, gear = base;
      scale.deviations.joint_scale[i] = 1.3e-4;
      const double d_scale = 1.3e-4 * qi;
      backlash.deviations.backlash[i] = revolute ? 0.02 * kDegToRad : 0.03;
      const double d_backlash = 0.5 * backlash.deviations.backlash[i] * ctx.dir[static_cast<size_t>(i)];
      double d_gear = 0;
      if (revolute) {
        const int H = base.deviations.gear_harmonics;
        gear.deviations.gear_sin[i * H + 0] = 0.01 * kDegToRad;
        gear.deviations.gear_cos[i * H + 1] = -0.007 * kDegToRad;
        d_gear = 0.01 * kDegToRad * std::sin(qi) - 0.007 * kDegToRad * std::cos(2 * qi);
      }
      KinematicWorkspace ws;
      for (auto [model, shift] : {std::pair<const RobotModel*, double>{&scale, d_scale}, {&backlash, d_backlash}, {&gear, d_gear}}) {
        // theta = theta0 + direction q + shift  <=>  q' = q + shift / direction (deg or mm)
        Eigen::VectorXd q_shifted = q;
        q_shifted[i] += (revolute ? shift * kRadToDeg : shift) / j.direction;
        const Eigen::Isometry3d expected = forwardKinematics(base, q_shifted, ctx, ws);
        const Eigen::Isometry3d got = forwardKinematics(*model, q, ctx, ws);
        EXPECT_LT(poseDiff(got, expected), 1e-9) << name << " joint " << i + 1;
      }
    }
  }
}

TEST(Effects, BacklashIsZeroWhenTheDirectionIsUnknownAndFlipsWithIt) {
  RobotModel m = test::loadBundled("kuka_kr16");
  const RobotModel nominal = m;
  m.deviations.backlash[1] = 0.05 * kDegToRad;
  Eigen::VectorXd q(6);
  q << 10, -80, 70, 20, 30, 40;
  KinematicWorkspace ws;
  PoseContext unknown;  // dir empty
  EXPECT_LT(poseDiff(forwardKinematics(m, q, unknown, ws), forwardKinematics(nominal, q, unknown, ws)), 1e-12);
  PoseContext plus, minus;
  plus.dir.assign(6, 1);
  minus.dir.assign(6, -1);
  const Eigen::Vector3d pp = forwardKinematics(m, q, plus, ws).translation();
  const Eigen::Vector3d pm = forwardKinematics(m, q, minus, ws).translation();
  const Eigen::Vector3d p0 = forwardKinematics(nominal, q, unknown, ws).translation();
  // the two sides are joint 2 turned by +-0.025 deg: on a circle of radius `lever` about the
  // axis, chord 2 lever sin(0.025 deg), midpoint lever (1 - cos(0.025 deg)) inside p0
  KinematicWorkspace w2;
  flangePose(nominal, q, unknown, w2);
  const Eigen::Vector3d o1 = w2.T_base_frame[1].translation();
  const Eigen::Vector3d z1 = w2.T_base_frame[1].linear().col(2);
  const Eigen::Vector3d r = p0 - o1;
  const double lever = (r - z1 * z1.dot(r)).norm();
  const double half = 0.025 * kDegToRad;
  EXPECT_NEAR((pp - pm).norm(), 2 * lever * std::sin(half), 1e-9);
  EXPECT_NEAR((0.5 * (pp + pm) - p0).norm(), lever * (1 - std::cos(half)), 1e-9);
  PoseContext short_dir;
  short_dir.dir.assign(1, 1);
  EXPECT_THROW(forwardKinematics(m, q, short_dir, ws), ArgumentError);
}

TEST(Effects, ThermalScalesEveryLinkLengthAboutTheReferenceTemperature) {
  std::mt19937_64 rng(9);
  for (const char* name : {"kuka_kr16", "ur10", "scara"}) {
    RobotModel m = test::loadBundled(name);
    m.deviations.links[1].da_mm = 0.4;  // the deviation scales too
    const double alpha = 23e-6, temp = 31.0;
    const double s = 1 + alpha * (temp - kThermalReferenceC);
    // independent: a robot whose DH lengths are the scaled ones
    RobotModel scaled = m;
    for (int i = 0; i < m.dof(); ++i) {
      JointSpec& j = scaled.nominal.joints[i];
      j.a_mm = (j.a_mm + m.deviations.links[i].da_mm) * s;
      j.d_mm = (j.d_mm + m.deviations.links[i].dd_mm) * s;
      scaled.deviations.links[i].da_mm = 0;
      scaled.deviations.links[i].dd_mm = 0;
    }
    m.deviations.thermal_alpha_per_k = alpha;
    PoseContext warm;
    warm.temp_c = temp;
    PoseContext reference;  // 20 C: no expansion
    RobotModel cold = m;
    cold.deviations.thermal_alpha_per_k = 0;
    KinematicWorkspace ws;
    for (int k = 0; k < 5; ++k) {
      const Eigen::VectorXd q = test::randomQ(m, rng);
      EXPECT_LT(poseDiff(forwardKinematics(m, q, warm, ws), forwardKinematics(scaled, q, warm, ws)), 1e-9) << name;
      EXPECT_LT(poseDiff(forwardKinematics(m, q, reference, ws), forwardKinematics(cold, q, reference, ws)), 1e-12)
          << name;
    }
  }
}

// Sets every parameter of the layout to a random value of realistic size.
void randomDeviations(RobotModel& m, std::mt19937_64& rng) {
  std::normal_distribution<double> nd(0, 1);
  for (const ParamInfo& p : parameterLayout(m)) {
    double s = p.unit == "deg" ? 0.05 * kDegToRad : 0.5;
    if (p.group == "base" && p.unit == "mm") s = 1000;
    if (p.group == "base" && p.unit == "deg") s = 0.5;
    if (p.group == "tool" && p.unit == "mm") s = 100;
    if (p.kind == ParamKind::kCompliance) s = p.unit == "urad/Nm" ? 2e-6 : 1e-3;
    if (p.kind == ParamKind::kJointScale) s = 2e-4;
    if (p.kind == ParamKind::kThermal) s = 20e-6;
    if (p.kind == ParamKind::kBacklash && p.unit == "mm") s = 0.02;
    setParameter(m.deviations, p, s * nd(rng));
  }
}

TEST(Effects, ParameterJacobianOfEveryEffectMatchesCentralDifferences) {
  std::mt19937_64 rng(12);
  for (const char* name : {"kuka_kr16", "ur10", "scara", "abb_irb120"}) {
    for (int H : {1, 2, 3}) {
      RobotModel m = test::loadBundled(name);
      m.deviations = Deviations::zero(m.dof(), H);
      randomDeviations(m, rng);
      const std::vector<ParamInfo> layout = parameterLayout(m);
      KinematicWorkspace ws;
      for (int trial = 0; trial < 3; ++trial) {
        const Eigen::VectorXd q = test::randomQ(m, rng);
        const PoseContext ctx = randomContext(m.dof(), rng);
        Eigen::MatrixXd J;
        const Eigen::Isometry3d T0 = parameterJacobian(m, layout, q, ctx, ws, J);
        EXPECT_LT(poseDiff(T0, forwardKinematics(m, q, ctx, ws)), 1e-9);
        const Eigen::VectorXd loads = gravityLoads(m, q, ctx);
        for (size_t k = 0; k < layout.size(); ++k) {
          const ParamInfo& P = layout[k];
          const double x0 = getParameter(m.deviations, P);
          // mm; rad or dimensionless: 1e-5 keeps the round-off of the difference (about 1e-12 mm
          // on positions 3 m from the origin, over 2h) far below the tolerance
          double h = P.unit == "mm" ? 1e-4 : 1e-5;
          if (P.kind == ParamKind::kCompliance) h = 1e-6 / std::max(1.0, std::abs(loads[P.joint]));
          if (P.kind == ParamKind::kThermal) h = 1e-8;  // 1/K: 1e-8 * 12 K * 2 m = 0.2 um
          RobotModel mp = m, mm = m;
          setParameter(mp.deviations, P, x0 + h);
          setParameter(mm.deviations, P, x0 - h);
          const Eigen::Isometry3d Tp = forwardKinematics(mp, q, ctx, ws);
          const Eigen::Isometry3d Tm = forwardKinematics(mm, q, ctx, ws);
          Vector6d fd;
          fd.head<3>() = (Tp.translation() - Tm.translation()) / (2 * h);
          fd.tail<3>() = logSO3(Tp.linear() * Tm.linear().transpose()) / (2 * h);
          const double scale = std::max(1.0, fd.norm());
          EXPECT_LT((J.col(static_cast<Eigen::Index>(k)) - fd).norm() / scale, 1e-6)
              << name << " H=" << H << " " << P.name << "\nanalytic " << J.col(static_cast<Eigen::Index>(k)).transpose()
              << "\nnumeric  " << fd.transpose();
        }
      }
    }
  }
}

TEST(Effects, JointJacobianIncludesScaleAndGearTerms) {
  std::mt19937_64 rng(6);
  RobotModel m = test::loadBundled("kuka_kr16");
  randomDeviations(m, rng);
  for (auto& c : m.deviations.compliance) c = 0;  // jointJacobian neglects compliance
  const int H = m.deviations.gear_harmonics;
  for (int i = 0; i < 6; ++i) {  // make the q-dependent terms large enough to matter
    m.deviations.joint_scale[i] = 0.02;
    m.deviations.gear_sin[i * H] = 0.01;
  }
  KinematicWorkspace ws;
  const PoseContext ctx = randomContext(6, rng);
  const Eigen::VectorXd q = test::randomQ(m, rng);
  const auto Jq = jointJacobian(m, q, ctx, ws);
  for (int i = 0; i < 6; ++i) {
    const double h = 1e-5;
    Eigen::VectorXd qp = q, qm = q;
    qp[i] += h;
    qm[i] -= h;
    const Eigen::Isometry3d Tp = forwardKinematics(m, qp, ctx, ws), Tm = forwardKinematics(m, qm, ctx, ws);
    Vector6d fd;
    fd.head<3>() = (Tp.translation() - Tm.translation()) / (2 * h);
    fd.tail<3>() = logSO3(Tp.linear() * Tm.linear().transpose()) / (2 * h);
    EXPECT_LT((Jq.col(i) - fd).norm() / std::max(1.0, fd.norm()), 1e-6) << "joint " << i + 1;
  }
}

TEST(Effects, ParameterNamesNameTheJointsAndGroupsAreTheCatalogue) {
  const RobotModel m = test::loadBundled("scara");  // joint 3 is prismatic
  std::vector<std::string> names;
  for (const ParamInfo& p : parameterLayout(m))
    if (p.group == "gear_periodic" || p.group == "joint_scale" || p.group == "backlash" || p.group == "thermal")
      names.push_back(p.name + ":" + p.unit);
  const std::vector<std::string> expected = {
      "j1_gear_s1:deg", "j1_gear_c1:deg", "j1_gear_s2:deg", "j1_gear_c2:deg", "j2_gear_s1:deg",
      "j2_gear_c1:deg", "j2_gear_s2:deg", "j2_gear_c2:deg", "j4_gear_s1:deg", "j4_gear_c1:deg",
      "j4_gear_s2:deg", "j4_gear_c2:deg", "j1_scale:ppm",   "j2_scale:ppm",   "j3_scale:ppm",
      "j4_scale:ppm",   "j1_backlash:deg", "j2_backlash:deg", "j3_backlash:mm", "j4_backlash:deg",
      "thermal_alpha:ppm/K"};
  EXPECT_EQ(names, expected);
  std::vector<std::string> groups;
  for (const auto& g : parameterGroups()) groups.push_back(g.first);
  for (const std::string& e : effectCatalogue())
    EXPECT_NE(std::find(groups.begin(), groups.end(), e), groups.end()) << e << " is not a parameter group";
}

TEST(Effects, ModelWithEffectsRoundTripsThroughARobotFile) {
  std::mt19937_64 rng(2);
  RobotModel m = test::loadBundled("kuka_kr16");
  randomDeviations(m, rng);
  const std::string dir = test::tempDir("effects_roundtrip");
  writeRobotFile(dir + "/m.xml", m);
  const RobotModel back = readRobotFile(dir + "/m.xml");
  KinematicWorkspace ws;
  for (int k = 0; k < 5; ++k) {
    const Eigen::VectorXd q = test::randomQ(m, rng);
    const PoseContext ctx = randomContext(6, rng);
    // parameters are written with 10 significant digits or better: positions agree to 1e-4 mm
    EXPECT_LT((forwardKinematics(m, q, ctx, ws).translation() - forwardKinematics(back, q, ctx, ws).translation()).norm(),
              1e-4);
  }
}

TEST(Effects, MeasurementFileFillsTheModelContext) {
  const RobotModel m = test::loadBundled("kuka_kr16");
  const std::string dir = test::tempDir("effects_context");
  test::writeText(dir + "/d.csv",
                  "q1,q2,q3,q4,q5,q6,x,y,z,payload_kg,temp_c,dir1,dir2,dir3,dir4,dir5,dir6\n"
                  "0,-90,90,0,45,0,1,2,3,8,24.5,1,-1,1,1,-1,-1\n");
  const MeasurementSet set = readMeasurementsCsv(dir + "/d.csv", m.nominal);
  ASSERT_EQ(set.rows.size(), 1u);
  EXPECT_EQ(set.rows[0].context.payload_kg, 8.0);
  EXPECT_EQ(set.rows[0].context.temp_c, 24.5);
  EXPECT_EQ(set.rows[0].context.dir, (std::vector<int>{1, -1, 1, 1, -1, -1}));
  test::writeText(dir + "/e.csv", "q1,q2,q3,q4,q5,q6,x,y,z\n0,-90,90,0,45,0,1,2,3\n");
  const MeasurementSet bare = readMeasurementsCsv(dir + "/e.csv", m.nominal);
  EXPECT_EQ(bare.rows[0].context.temp_c, kThermalReferenceC);
  EXPECT_TRUE(bare.rows[0].context.dir.empty());
}

// Simulated measurements carry every context column whatever the effect, and the effect
// shows up as the model says: the noise-free simulation equals the model's FK (or, for the
// coupling, FK at the coupled joint value).
TEST(Effects, SimulatedEffectsMatchTheModelAndCarryEveryContextColumn) {
  const RobotModel nominal = test::loadBundled("kuka_kr16");
  for (const char* effect : {"gear_periodic", "joint_scale", "backlash", "thermal", "unmodelled_coupling"}) {
    SimulateOptions o;
    o.poses = 20;
    o.seed = 5;
    o.noise_mm = 0;
    o.effects = {"geometric", effect};
    o.payloads_kg = {0, 10};
    o.repeat_every = 5;
    const RobotModel truth = perturbModel(nominal, o);
    const MeasurementSet set = simulateMeasurements(truth, o);
    EXPECT_TRUE(set.has_payload && set.has_temperature && set.has_direction && set.has_time) << effect;
    const JointCoupling c = defaultCoupling(truth);
    KinematicWorkspace ws;
    for (size_t k = 0; k < set.rows.size(); ++k) {
      const Measurement& r = set.rows[k];
      ASSERT_EQ(r.dir.size(), 6u);
      EXPECT_EQ(r.context.dir, r.dir);
      EXPECT_EQ(r.context.temp_c, r.temp_c);
      EXPECT_GE(r.temp_c, 18.0);
      EXPECT_LE(r.temp_c, 26.0);
      Eigen::VectorXd q = r.q;
      if (std::string(effect) == "unmodelled_coupling")
        q[c.to] += nominal.nominal.joints[c.to].direction * c.ratio * r.q[c.from] * kDegToRad * kRadToDeg;
      EXPECT_LT((forwardKinematics(truth, q, r.context, ws).translation() - r.p_world_mm).norm(), 1e-9) << effect;
      if (k % 5 == 4) {
        EXPECT_EQ(r.q, set.rows[k - 1].q) << "row " << k << " repeats the pose before it";
      }
    }
    // the effect is present in the truth (and nothing else of the catalogue)
    const Deviations& d = truth.deviations;
    const bool has_gear = std::any_of(d.gear_sin.begin(), d.gear_sin.end(), [](double v) { return v != 0; });
    const bool has_scale = std::any_of(d.joint_scale.begin(), d.joint_scale.end(), [](double v) { return v != 0; });
    const bool has_backlash = std::any_of(d.backlash.begin(), d.backlash.end(), [](double v) { return v != 0; });
    EXPECT_EQ(has_gear, std::string(effect) == "gear_periodic");
    EXPECT_EQ(has_scale, std::string(effect) == "joint_scale");
    EXPECT_EQ(has_backlash, std::string(effect) == "backlash");
    EXPECT_EQ(d.thermal_alpha_per_k != 0, std::string(effect) == "thermal");
  }
  // with coupling, the measured point differs from the model's FK at the recorded q
  SimulateOptions o;
  o.poses = 10;
  o.noise_mm = 0;
  o.effects = {"unmodelled_coupling"};
  o.set_station = false;
  const MeasurementSet set = simulateMeasurements(nominal, o);
  double max_dev = 0;
  KinematicWorkspace ws;
  for (const Measurement& r : set.rows)
    max_dev = std::max(max_dev, (forwardKinematics(nominal, r.q, r.context, ws).translation() - r.p_world_mm).norm());
  EXPECT_GT(max_dev, 0.05);  // 200 urad per rad of A4 (up to 6 rad) on a 158 mm lever
}

}  // namespace
}  // namespace accura::calib

namespace accura::calib {
namespace {

/// Removes every deviation but the geometric ones (links, base, tool): a plain chain, which
/// the core evaluates on its short path when every joint is revolute.
void keepGeometricDeviationsOnly(RobotModel& m) {
  Deviations& d = m.deviations;
  for (std::vector<double>* v : {&d.compliance, &d.gear_sin, &d.gear_cos, &d.joint_scale, &d.backlash})
    std::fill(v->begin(), v->end(), 0.0);
  for (JointMap& map : d.joint_map) map = JointMap{};
  d.thermal_alpha_per_k = 0;
}

// Central differences of the kinematic core itself (kinematic_core.h): every column of the
// parameter Jacobian (geometry, compliance and every effect of the catalogue) and the joint
// Jacobian, on every bundled robot in both forms (Hayati where axes are parallel, and DH
// everywhere), in a context with payload, temperature and approach directions.
TEST(KinematicCore, DerivativesOfEveryEffectOnEveryRobotInBothForms) {
  std::mt19937_64 rng(31);
  for (const char* name : {"kuka_kr16", "ur10", "scara", "abb_irb120"}) {
    for (FormPolicy policy : {FormPolicy::kAuto, FormPolicy::kDHOnly})
    // geometric: the geometric deviations alone (the core's short path for a plain chain of
    // revolute joints, kinematic_core.cpp), else every effect of the catalogue
    for (bool geometric : {false, true}) {
      RobotModel m = test::loadBundled(name, policy);
      // a joint map on every joint (6 intervals over its range): its coefficients join the layout
      m.deviations.joint_map.resize(static_cast<size_t>(m.dof()));
      for (int j = 0; j < m.dof(); ++j) {
        const JointSpec& js = m.nominal.joints[static_cast<size_t>(j)];
        m.deviations.joint_map[static_cast<size_t>(j)] = makeJointMap(js.lower, js.upper, (js.upper - js.lower) / 6);
      }
      randomDeviations(m, rng);
      bool all_revolute = true;
      for (const JointSpec& js : m.nominal.joints) all_revolute = all_revolute && js.type == JointType::kRevolute;
      if (geometric) keepGeometricDeviationsOnly(m);
      const KinematicModel core(m);
      // the short path is taken exactly for the plain chains (its Jacobian bound is known)
      EXPECT_EQ(!core.scaledJacobianLipschitz().empty(), geometric && all_revolute) << name;
      const std::vector<ParamInfo> layout = parameterLayout(m);
      ASSERT_EQ(std::any_of(layout.begin(), layout.end(), [](const ParamInfo& p) { return p.kind == ParamKind::kJointMap; }),
                !geometric);
      KinematicFrames f, fp, fm;
      LinkFrames links;
      for (int trial = 0; trial < 2; ++trial) {
        const Eigen::VectorXd q = test::randomQ(m, rng);
        const PoseContext ctx = randomContext(m.dof(), rng);
        Eigen::MatrixXd J;
        core.parameterJacobian(layout, q.data(), ctx, f, links, J);
        Eigen::VectorXd loads(m.dof());
        for (int i = 0; i < m.dof(); ++i) loads[i] = links.load[static_cast<size_t>(i)];
        for (size_t k = 0; k < layout.size(); ++k) {
          const ParamInfo& P = layout[k];
          const double x0 = getParameter(m.deviations, P);
          double h = P.unit == "mm" ? 1e-4 : 1e-5;  // mm; rad or dimensionless
          if (P.kind == ParamKind::kCompliance) h = 1e-6 / std::max(1.0, std::abs(loads[P.joint]));
          if (P.kind == ParamKind::kThermal) h = 1e-8;  // 1/K
          RobotModel mp = m, mm = m;
          setParameter(mp.deviations, P, x0 + h);
          setParameter(mm.deviations, P, x0 - h);
          KinematicModel(mp).evaluate(q.data(), ctx, fp);
          KinematicModel(mm).evaluate(q.data(), ctx, fm);
          Vector6d fd;
          fd.head<3>() = (fp.T_world_tcp.translation() - fm.T_world_tcp.translation()) / (2 * h);
          fd.tail<3>() = logSO3(fp.T_world_tcp.linear() * fm.T_world_tcp.linear().transpose()) / (2 * h);
          EXPECT_LT((J.col(static_cast<Eigen::Index>(k)) - fd).norm() / std::max(1.0, fd.norm()), 1e-6)
              << name << (policy == FormPolicy::kDHOnly ? " DH " : " auto ") << P.name << "\nanalytic "
              << J.col(static_cast<Eigen::Index>(k)).transpose() << "\nnumeric  " << fd.transpose();
        }
        // joint Jacobian (it neglects compliance: checked on the model without it)
        RobotModel stiff = m;
        for (double& c : stiff.deviations.compliance) c = 0;
        const KinematicModel stiff_core(stiff);
        stiff_core.evaluate(q.data(), ctx, f);
        Jac6N Jq;
        stiff_core.jacobian(f, Jq);
        for (int i = 0; i < m.dof(); ++i) {
          const double h = 1e-5;  // deg or mm
          Eigen::VectorXd qp = q, qm = q;
          qp[i] += h;
          qm[i] -= h;
          stiff_core.evaluate(qp.data(), ctx, fp);
          stiff_core.evaluate(qm.data(), ctx, fm);
          Vector6d fd;
          fd.head<3>() = (fp.T_world_tcp.translation() - fm.T_world_tcp.translation()) / (2 * h);
          fd.tail<3>() = logSO3(fp.T_world_tcp.linear() * fm.T_world_tcp.linear().transpose()) / (2 * h);
          EXPECT_LT((Jq.col(i) - fd).norm() / std::max(1.0, fd.norm()), 1e-6)
              << name << (policy == FormPolicy::kDHOnly ? " DH" : " auto") << " joint " << i + 1;
        }
      }
    }
  }
}

// An evaluation started from a nearby one (the angle-addition series) equals a fresh one.
TEST(KinematicCore, EvaluationFromANearbyOneEqualsAFreshOne) {
  std::mt19937_64 rng(32);
  for (const char* name : {"kuka_kr16", "scara", "kuka_kr16 geometric"}) {
    const std::string robot(name);
    const bool geometric = robot.find(" geometric") != std::string::npos;
    RobotModel m = test::loadBundled(robot.substr(0, robot.find(' ')));
    randomDeviations(m, rng);
    if (geometric) keepGeometricDeviationsOnly(m);  // the core's short path for a plain chain
    const KinematicModel core(m);
    EXPECT_EQ(!core.scaledJacobianLipschitz().empty(), geometric) << name;
    std::normal_distribution<double> step(0, 2);  // deg: inside and beyond the 0.1 rad series
    for (int trial = 0; trial < 20; ++trial) {
      const Eigen::VectorXd q0 = test::randomQ(m, rng);
      Eigen::VectorXd q1 = q0;
      for (int i = 0; i < m.dof(); ++i) q1[i] += step(rng) * (trial % 4 + 1);
      const PoseContext ctx = randomContext(m.dof(), rng);
      KinematicFrames f0, f1, fresh;
      core.evaluate(q0.data(), ctx, f0);
      core.evaluate(q1.data(), ctx, f1, &f0);
      core.evaluate(q1.data(), ctx, fresh);
      EXPECT_LT(poseDiff(f1.T_world_tcp, fresh.T_world_tcp), 1e-9) << name;  // mm (and rotation entries)
    }
  }
}

// The workspace keeps the model of the last call prepared: a change of any value must be
// seen (compared with a fresh workspace every time).
TEST(KinematicCore, WorkspaceNoticesEveryChangeOfTheModel) {
  std::mt19937_64 rng(33);
  RobotModel m = test::loadBundled("kuka_kr16");
  randomDeviations(m, rng);
  const PoseContext ctx = randomContext(m.dof(), rng);
  const Eigen::VectorXd q = test::randomQ(m, rng);
  KinematicWorkspace ws;
  const std::vector<ParamInfo> layout = parameterLayout(m);
  size_t moved_count = 0;
  for (const ParamInfo& P : layout) {
    const Eigen::Isometry3d before = forwardKinematics(m, q, ctx, ws);
    RobotModel changed = m;
    setParameter(changed.deviations, P, getParameter(m.deviations, P) + (P.unit == "mm" ? 0.1 : 1e-3));
    KinematicWorkspace fresh;
    const Eigen::Isometry3d expected = forwardKinematics(changed, q, ctx, fresh);
    moved_count += poseDiff(before, expected) > 1e-9;  // the change moves the tool
    EXPECT_EQ(poseDiff(forwardKinematics(changed, q, ctx, ws), expected), 0.0) << P.name;
  }
  // all but the compliance of joints without gravity load (A1 vertical, A6 on its axis)
  EXPECT_GE(moved_count, layout.size() - 2);
  RobotModel moved = m;
  moved.nominal.joints[2].a_mm += 0.5;
  forwardKinematics(m, q, ctx, ws);
  KinematicWorkspace fresh;
  EXPECT_EQ(poseDiff(forwardKinematics(moved, q, ctx, ws), forwardKinematics(moved, q, ctx, fresh)), 0.0);
  moved.nominal.T_flange_tcp.translation().x() += 1;
  EXPECT_EQ(poseDiff(forwardKinematics(moved, q, ctx, ws), forwardKinematics(moved, q, ctx, fresh)), 0.0);
}

}  // namespace
}  // namespace accura::calib

namespace accura::calib {
namespace {

// The core computes its sines and cosines itself: a forward kinematics with angles all over
// the circle (several turns) equals an independent DH product with the library's sin / cos.
TEST(KinematicCore, ForwardKinematicsEqualsALibraryDhProductOverSeveralTurns) {
  std::mt19937_64 rng(34);
  RobotModel m = test::loadBundled("abb_irb120", FormPolicy::kDHOnly);
  for (JointSpec& j : m.nominal.joints) {
    j.lower = -1000;
    j.upper = 1000;
  }
  const KinematicModel core(m);
  KinematicFrames f;
  std::uniform_real_distribution<double> u(-1000, 1000);  // deg
  double worst = 0;
  for (int k = 0; k < 2000; ++k) {
    Eigen::VectorXd q(6);
    for (int i = 0; i < 6; ++i) q[i] = u(rng);
    if (k < 8) q.setConstant(45.0 * k);  // the octant boundaries
    core.evaluate(q.data(), PoseContext{}, f);
    Eigen::Matrix4d T = m.T_world_base().matrix();
    for (int i = 0; i < 6; ++i) {
      const JointSpec& j = m.nominal.joints[static_cast<size_t>(i)];
      const double t = (j.theta0_deg + j.direction * q[i]) * kDegToRad, al = j.alpha_deg * kDegToRad;
      Eigen::Matrix4d A;
      A << std::cos(t), -std::sin(t) * std::cos(al), std::sin(t) * std::sin(al), j.a_mm * std::cos(t),
          std::sin(t), std::cos(t) * std::cos(al), -std::cos(t) * std::sin(al), j.a_mm * std::sin(t), 0,
          std::sin(al), std::cos(al), j.d_mm, 0, 0, 0, 1;
      T = T * A;
    }
    T = T * m.T_flange_tcp().matrix();
    worst = std::max(worst, (T - f.T_world_tcp.matrix()).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(worst, 1e-11);  // mm (and rotation entries): rounding of a 600 mm arm
}

}  // namespace
}  // namespace accura::calib
