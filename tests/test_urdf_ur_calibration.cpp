// Universal Robots' factory calibration (ur_calibration.h): DH deltas and ur_calibration's
// YAML into calibrated accura models and back, against UR's own formula and the flange
// positions UR's ur_calibration test pins for a UR10.
#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>
#include <map>
#include <tuple>
#include <random>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/ur_calibration.h"
#include "accura/calib/urdf.h"
#include "test_util.h"

namespace accura::calib {
namespace {

// UR's formula written out independently: prod Rz(q + dtheta) Tz(d) Tx(a) Rx(alpha), metres.
Eigen::Matrix4d urFormula(const double d[6], const double a[6], const double theta[6], const double alpha[6],
                          const Eigen::VectorXd& q_rad) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  for (int i = 0; i < 6; ++i) {
    const double ct = std::cos(q_rad[i] + theta[i]), st = std::sin(q_rad[i] + theta[i]);
    const double ca = std::cos(alpha[i]), sa = std::sin(alpha[i]);
    Eigen::Matrix4d A;
    A << ct, -st * ca, st * sa, a[i] * ct,
         st, ct * ca, -ct * sa, a[i] * st,
         0, sa, ca, d[i],
         0, 0, 0, 1;
    T = T * A;
  }
  return T;
}

// The UR10 of ur_calibration/test/calibration_test.cpp (UniversalRobots/Universal_Robots_ROS_Driver):
// ideal DH (d, a, alpha) and a real-looking set of calibration deltas (d, a, theta, alpha).
const double kD[6] = {0.1273, 0, 0, 0.163941, 0.1157, 0.0922};
const double kA[6] = {0, -0.612, -0.5723, 0, 0, 0};
const double kAlpha[6] = {M_PI / 2, 0, 0, M_PI / 2, -M_PI / 2, 0};
const double kDeltaD[6] = {0.00065609212979853, 1.4442162376284788, 0.854147723854608,
                           -2.2989425877563705, -1.573498686836816e-05, 1.9072435590711256e-05};
const double kDeltaA[6] = {4.6311376834935676e-05, -0.00012568315331862312, 0.00186216581161458,
                           9.918593870679266e-05, 4.215462720453189e-06, 0};
const double kDeltaTheta[6] = {-7.290070070824746e-05, -0.01713897289704999, -0.03707159413492756,
                               0.054279462160583214, 1.488984257025741e-07, 1.551499479707493e-05};
const double kDeltaAlpha[6] = {0.000211987863869334, -0.0072553625957652995, -0.013483226769541364,
                               0.0013495820227329425, -0.001263136163679901, 0};

UrDeltas testDeltas() {
  UrDeltas d;
  d.theta_rad.assign(kDeltaTheta, kDeltaTheta + 6);
  d.a_m.assign(kDeltaA, kDeltaA + 6);
  d.d_m.assign(kDeltaD, kDeltaD + 6);
  d.alpha_rad.assign(kDeltaAlpha, kDeltaAlpha + 6);
  return d;
}

UrDeltas zeroDeltas() {
  UrDeltas d;
  d.theta_rad.assign(6, 0);
  d.a_m.assign(6, 0);
  d.d_m.assign(6, 0);
  d.alpha_rad.assign(6, 0);
  return d;
}

Eigen::VectorXd deg(const Eigen::VectorXd& rad) { return rad * (180.0 / M_PI); }

TEST(UrCalibration, FlangePositionsPinnedByUrsTest) {
  const RobotDefinition ur10 = test::loadBundled("ur10").nominal;
  const RobotModel m = modelFromUrDeltas(ur10, zeroDeltas());
  struct Pin {
    Eigen::VectorXd q;
    Eigen::Vector3d p_m;
  };
  Eigen::VectorXd q1(6), q2(6), q3(6), q4(6);
  q1 << 0, 0, 0, 0, 0, 0;
  q2 << M_PI_2, -M_PI_4, M_PI_2, -M_PI_4, 0, 0;
  q3 << -1.6007002035724084976209269370884, -1.7271001974688928726209269370884, -2.2029998938189905288709269370884,
      -0.80799991289247685699592693708837, 1.59510004520416259765625, -0.03099996248354131012092693708837;
  q4 << 1.32645022869110107421875, 2.426007747650146484375, 5.951572895050048828125, 1.27409040927886962890625,
      -0.54105216661562138824592693708837, 0.122173048555850982666015625;
  const double s2 = std::sqrt(2.0);
  const std::vector<Pin> pins = {
      {q1, Eigen::Vector3d(kA[1] + kA[2], -(kD[3] + kD[5]), kD[0] - kD[4])},
      {q2, Eigen::Vector3d(kD[3] + kD[5], kA[1] / s2 + kA[2] / s2, kD[0] - kA[1] / s2 + kA[2] / s2 - kD[4])},
      {q3, Eigen::Vector3d(-0.179925914147547, -0.606869755162764, 0.230789102067257)},
      {q4, Eigen::Vector3d(0.39922988003280424074148413637886, 0.59688365069340565405298093537567,
                           -0.6677819040276375961440180617501)},
  };
  for (const Pin& pin : pins) {
    const Eigen::Vector3d p = forwardKinematics(m, deg(pin.q)).translation();
    EXPECT_LT((p - 1000.0 * pin.p_m).norm(), 1e-6) << p.transpose();  // mm; UR's test pins 1e-10 m
  }
  // The controller's view at zero: (-1184.3, -256.141, 11.6) mm in Base = DH frame 0.
  EXPECT_NEAR(forwardKinematics(m, deg(q1)).translation().x(), -1184.3, 1e-9);
}

TEST(UrCalibration, DeltasImportEqualsUrsFormulaWithoutHugeLengths) {
  const RobotDefinition ur10 = test::loadBundled("ur10").nominal;
  const UrDeltas deltas = testDeltas();
  const RobotModel m = modelFromUrDeltas(ur10, deltas);
  double d_tot[6], a_tot[6], al_tot[6];
  for (int i = 0; i < 6; ++i) {
    d_tot[i] = kD[i] + kDeltaD[i];
    a_tot[i] = kA[i] + kDeltaA[i];
    al_tot[i] = kAlpha[i] + kDeltaAlpha[i];
  }
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-2 * M_PI, 2 * M_PI);
  double worst_mm = 0, worst_rot = 0;
  for (int s = 0; s < 1000; ++s) {
    Eigen::VectorXd q(6);
    for (int i = 0; i < 6; ++i) q[i] = u(rng);
    const Eigen::Matrix4d U = urFormula(d_tot, a_tot, kDeltaTheta, al_tot, q);
    const Eigen::Isometry3d A = forwardKinematics(m, deg(q));
    worst_mm = std::max(worst_mm, (A.translation() - 1000.0 * U.topRightCorner<3, 1>()).norm());
    worst_rot = std::max(worst_rot, (A.linear() - U.topLeftCorner<3, 3>()).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(worst_mm, 1e-6);
  EXPECT_LT(worst_rot, 1e-12);
  // The deltas' d of joints 2-4 are metres (1.44, 0.85, -2.30 m); the model's deviations are
  // at most 1.02 mm and 0.77 deg: Hayati links keep d, the parallel-axis lengths stay the arm's lengths.
  EXPECT_EQ(m.forms[1], LinkForm::kHayati);
  EXPECT_EQ(m.forms[2], LinkForm::kHayati);
  for (int i = 0; i < 6; ++i) {
    const LinkDeviation& d = m.deviations.links[i];
    EXPECT_LT(std::abs(d.dd_mm), 1.1) << i;   // largest: j3_a 1.02 mm
    EXPECT_LT(std::abs(d.da_mm), 1.1) << i;
    EXPECT_LT(std::abs(d.dtheta_rad), 0.8 * M_PI / 180) << i;  // largest: j3_alpha 0.77 deg
    EXPECT_LT(std::abs(d.dalpha_rad), 0.8 * M_PI / 180) << i;
    EXPECT_LT(std::abs(d.dbeta_rad), 0.8 * M_PI / 180) << i;
  }
  EXPECT_LT(m.deviations.base_mm.norm() + m.deviations.tool_mm.norm(), 1e-9);
  // ... and it is a calibrated robot file identify can start from: write, read, same FK
  const std::string dir = test::tempDir("ur_deltas");
  writeRobotFile(dir + "/ur10_cal.xml", m);
  const RobotModel back = readRobotFile(dir + "/ur10_cal.xml");
  Eigen::VectorXd q(6);
  q << 10, -70, 80, -30, 45, 120;
  EXPECT_LT((forwardKinematics(back, q).translation() - forwardKinematics(m, q).translation()).norm(), 1e-6);
  std::filesystem::remove_all(dir);
}

TEST(UrCalibration, AnotherArmsCalibrationOrAnAbsurdDeltaIsRefused) {
  // A factory calibration moves the flange by millimetres (the forum file: a few mm on the
  // UR10); one that moves it by more is another arm's or corrupted, and is refused by name.
  const RobotDefinition ur10 = test::loadBundled("ur10").nominal;
  UrDeltas d = readUrCalibrationConf(test::sourcePath("tests/data/urdf/ur_forum_calibration.conf"));
  const RobotModel m = modelFromUrDeltas(ur10, d);
  // the size the check measures, on its own: the flange of the calibrated model against the nominal one
  const RobotModel nominal = RobotModel::fromDefinition(ur10);
  Eigen::VectorXd q(6);
  q << 10, -60, 80, -30, 90, 20;
  const double moved = (forwardKinematics(m, q).translation() - forwardKinematics(nominal, q).translation()).norm();
  EXPECT_GT(moved, 1.0);
  EXPECT_LT(moved, kMaxUrFactoryCorrectionMm);
  d.a_m[0] += 0.5;  // half a metre on the first link: not a calibration of this arm
  try {
    modelFromUrDeltas(ur10, d);
    FAIL() << "expected an ArgumentError";
  } catch (const ArgumentError& e) {
    EXPECT_NE(std::string(e.what()).find("expected the factory calibration of a Universal Robots UR10 (CB3) (the flange within 20 mm and 2 deg"),
              std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("found one that moves it by up to 50"), std::string::npos) << e.what();
  }
}

TEST(UrCalibration, ControllerFileWithTensOfMetres) {
  // A real calibration.conf (tests/data/urdf/ur_forum_calibration.conf): delta_d up to 92.5 m.
  const UrDeltas d = readUrCalibrationConf(test::sourcePath("tests/data/urdf/ur_forum_calibration.conf"));
  EXPECT_DOUBLE_EQ(d.d_m[2], -92.5270326908668181);
  EXPECT_DOUBLE_EQ(d.theta_rad[3], -0.57016974724960845);
  // The robot type is not stated: take the UR10 nominal; the FK check is the same for any.
  const RobotDefinition ur10 = test::loadBundled("ur10").nominal;
  const RobotModel m = modelFromUrDeltas(ur10, d);
  double dd[6], aa[6], al[6];
  for (int i = 0; i < 6; ++i) {
    dd[i] = kD[i] + d.d_m[i];
    aa[i] = kA[i] + d.a_m[i];
    al[i] = kAlpha[i] + d.alpha_rad[i];
  }
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> u(-M_PI, M_PI);
  double worst = 0;
  for (int s = 0; s < 500; ++s) {
    Eigen::VectorXd q(6);
    for (int i = 0; i < 6; ++i) q[i] = u(rng);
    const Eigen::Matrix4d U = urFormula(dd, aa, d.theta_rad.data(), al, q);
    worst = std::max(worst, (forwardKinematics(m, deg(q)).translation() - 1000.0 * U.topRightCorner<3, 1>()).norm());
  }
  EXPECT_LT(worst, 1e-6);
  for (int i = 0; i < 6; ++i) {  // no length in the model is a DH artefact
    EXPECT_LT(std::abs(m.nominal.joints[i].d_mm + m.deviations.links[i].dd_mm), 200.0) << i;
    EXPECT_LT(std::abs(m.nominal.joints[i].a_mm + m.deviations.links[i].da_mm), 700.0) << i;
  }
}

TEST(UrCalibration, DeltasRoundTrip) {
  const RobotDefinition ur10 = test::loadBundled("ur10").nominal;
  const UrDeltas deltas = testDeltas();
  const RobotModel m = modelFromUrDeltas(ur10, deltas);
  const UrDeltasFromModel back = urDeltasFromModel(m);
  EXPECT_LT(back.max_difference_mm, 1e-6);
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(back.deltas.d_m[i], kDeltaD[i], 1e-9) << i;  // m
    EXPECT_NEAR(back.deltas.a_m[i], kDeltaA[i], 1e-12) << i;
    EXPECT_NEAR(back.deltas.theta_rad[i], kDeltaTheta[i], 1e-11) << i;
    EXPECT_NEAR(back.deltas.alpha_rad[i], kDeltaAlpha[i], 1e-12) << i;
  }
  // the huge DH lengths are flagged
  std::string all;
  for (const auto& s : back.not_represented) all += s + "\n";
  EXPECT_NE(all.find("'shoulder_lift': delta_d"), std::string::npos) << all;
  // a model with a base deviation and compliance: both flagged, the flange chain still exact
  RobotModel c = m;
  c.deviations.base_mm = Eigen::Vector3d(1, 2, 3);
  c.deviations.compliance[1] = 1e-5;
  const UrDeltasFromModel cb = urDeltasFromModel(c);
  all.clear();
  for (const auto& s : cb.not_represented) all += s + "\n";
  EXPECT_NE(all.find("base deviation"), std::string::npos) << all;
  EXPECT_NE(all.find("joint_compliance"), std::string::npos) << all;
  // an identified model's base deviation is where the arm stands in the tracker's frame, not a
  // mounting to set on the controller: said so (UR's installation mounting is only its tilt)
  EXPECT_NE(all.find("base deviation (1, 2, 3) mm, rotation vector (0, 0, 0) deg: where the arm's Base stands in the world "
                     "frame the model was identified in (the measurement frame: the laser tracker's or CMM's station), not "
                     "part of the arm's calibration and not exported (UR's table starts at the Base frame)"),
            std::string::npos) << all;
  EXPECT_EQ(all.find("mounting"), std::string::npos) << all;
  std::vector<std::string> yaml_notes;
  formatUrCalibrationYaml(c, &yaml_notes);
  ASSERT_FALSE(yaml_notes.empty());
  EXPECT_EQ(yaml_notes[0].rfind("base deviation (1, 2, 3) mm, rotation vector (0, 0, 0) deg: where the arm's Base stands", 0), 0u)
      << yaml_notes[0];
  EXPECT_LT(cb.max_difference_mm, 1e-6);
  // calibration.conf text reads back bit for bit
  const std::string dir = test::tempDir("ur_conf");
  writeFileAtomically(dir + "/calibration.conf", formatUrCalibrationConf(back.deltas));
  const UrDeltas again = readUrCalibrationConf(dir + "/calibration.conf");
  for (int i = 0; i < 6; ++i) EXPECT_EQ(again.d_m[i], back.deltas.d_m[i]);
  std::filesystem::remove_all(dir);
}

// Axes 2, 3 and 4 exactly parallel, as UR's table has them (DH, d = 0): the nominal arm and a
// calibration that changes only the offsets and lengths in the plane. The common normal of two
// parallel axes lies anywhere along them; the table's d picks it. (The export refused: "found it
// parallel to that joint's axis".) Expected: the deltas put in.
TEST(UrCalibration, DeltasOfParallelAxesAreExported) {
  const RobotModel nominal = test::loadBundled("ur10");
  const UrDeltasFromModel zero = urDeltasFromModel(nominal);
  EXPECT_LT(zero.max_difference_mm, 1e-9);
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(zero.deltas.theta_rad[i], 0.0, 1e-15) << i;
    EXPECT_NEAR(zero.deltas.a_m[i], 0.0, 1e-15) << i;
    EXPECT_NEAR(zero.deltas.d_m[i], 0.0, 1e-15) << i;
    EXPECT_NEAR(zero.deltas.alpha_rad[i], 0.0, 1e-15) << i;
  }
  UrDeltas in;
  in.theta_rad = {1.1e-05, -0.000312, 0.00041, -0.00021, 5.3e-05, 2.2e-05};
  in.a_m = {0, 0.00012, 0.00031, 0, 0, 0};
  in.d_m = {0.00015, 0, 0, 0, 0, 0};
  in.alpha_rad = {0, 0, 0, 0, 0, 0};
  const UrDeltasFromModel back = urDeltasFromModel(modelFromUrDeltas(nominal.nominal, in));
  EXPECT_LT(back.max_difference_mm, 1e-9);
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(back.deltas.theta_rad[i], in.theta_rad[i], 1e-12) << i;  // rad
    EXPECT_NEAR(back.deltas.a_m[i], in.a_m[i], 1e-12) << i;              // m
    EXPECT_NEAR(back.deltas.d_m[i], in.d_m[i], 1e-12) << i;
    EXPECT_NEAR(back.deltas.alpha_rad[i], in.alpha_rad[i], 1e-12) << i;
  }
}

TEST(UrCalibration, YamlRoundTripEqualsUrsFormula) {
  const RobotDefinition ur10 = test::loadBundled("ur10").nominal;
  const RobotModel m = modelFromUrDeltas(ur10, testDeltas());
  std::vector<std::string> notes;
  const std::string yaml = formatUrCalibrationYaml(m, &notes);
  const std::string dir = test::tempDir("ur_yaml");
  writeFileAtomically(dir + "/cal.yaml", yaml);
  const RobotModel y = modelFromUrCalibrationYaml(ur10, dir + "/cal.yaml");
  double d_tot[6], a_tot[6], al_tot[6];
  for (int i = 0; i < 6; ++i) {
    d_tot[i] = kD[i] + kDeltaD[i];
    a_tot[i] = kA[i] + kDeltaA[i];
    al_tot[i] = kAlpha[i] + kDeltaAlpha[i];
  }
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-M_PI, M_PI);
  double worst = 0;
  for (int s = 0; s < 300; ++s) {
    Eigen::VectorXd q(6);
    for (int i = 0; i < 6; ++i) q[i] = u(rng);
    const Eigen::Matrix4d U = urFormula(d_tot, a_tot, kDeltaTheta, al_tot, q);
    worst = std::max(worst, (forwardKinematics(y, deg(q)).translation() - 1000.0 * U.topRightCorner<3, 1>()).norm());
  }
  EXPECT_LT(worst, 1e-6);
  // the nominal UR10's YAML: shoulder z = d1 in metres (ur_description's default 0.1273)
  const std::string nominal_yaml = formatUrCalibrationYaml(RobotModel::fromDefinition(ur10), nullptr);
  EXPECT_NE(nominal_yaml.find("  shoulder:\n    x: 0\n    y: 0\n    z: 0.1273\n"), std::string::npos) << nominal_yaml;
  // the hash ur_description's xacro reads (marked as accura's: not the factory calibration's)
  EXPECT_NE(yaml.find("\n  hash: calib_accura_"), std::string::npos) << yaml;
  // the same YAML as other writers format it: a document start, 4-space indentation, quoted
  // numbers, one link as a flow mapping: the same chain
  std::string other = "---\n";
  std::istringstream lines(yaml);
  for (std::string l; std::getline(lines, l);) {
    const size_t indent = l.find_first_not_of(' ');
    std::string text = l.substr(indent);
    const size_t colon = text.find(": ");
    if (indent == 4 && colon != std::string::npos) text = text.substr(0, colon) + ": \"" + text.substr(colon + 2) + "\"";
    other += std::string(2 * indent, ' ') + text + "\n";
  }
  const size_t wrist_3 = other.find("    wrist_3:\n"), hash = other.find("    hash:");
  ASSERT_NE(wrist_3, std::string::npos);
  std::string flow = "    wrist_3: {";
  std::istringstream entries(other.substr(wrist_3 + 13, hash - wrist_3 - 13));
  for (std::string l; std::getline(entries, l);) flow += (flow.back() == '{' ? "" : ", ") + l.substr(l.find_first_not_of(' '));
  other = other.substr(0, wrist_3) + flow + "}\n" + other.substr(hash);
  writeFileAtomically(dir + "/other.yaml", other);
  const RobotModel o = modelFromUrCalibrationYaml(ur10, dir + "/other.yaml");
  Eigen::VectorXd q(6);
  q << 10, -70, 80, -30, 45, 120;
  EXPECT_LT((forwardKinematics(o, q).translation() - forwardKinematics(y, q).translation()).norm(), 1e-9) << other;
  std::filesystem::remove_all(dir);
}

// The largest position (mm) and rotation (rad) differences of T_a * FK(a, q) and T_b * FK(b, q) over
// 200 joint vectors within +-180 deg.
std::pair<double, double> worstDifference(const RobotModel& a, const Eigen::Isometry3d& T_a, const RobotModel& b,
                                          const Eigen::Isometry3d& T_b) {
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(-180, 180);
  double mm = 0, rad = 0;
  for (int s = 0; s < 200; ++s) {
    Eigen::VectorXd q(6);
    for (int i = 0; i < 6; ++i) q[i] = s == 0 ? 0.0 : u(rng);
    const Eigen::Isometry3d A = T_a * forwardKinematics(a, q), B = T_b * forwardKinematics(b, q);
    mm = std::max(mm, (A.translation() - B.translation()).norm());
    rad = std::max(rad, Eigen::AngleAxisd(A.linear().transpose() * B.linear()).angle());
  }
  return {mm, rad};
}

TEST(UrCalibration, TheArmOfAUrdfTakesUrsTableInUrsConvention) {
  // ur_description's UR10 (tests/data/urdf/ur10.urdf) read as a robot: its DH frame 0 is ROS's
  // base_link (x forward: UR's Base turned by 180 deg about z, the URDF's base_link -> base
  // joint), its x axes give a = +612 mm, alpha_1 = -90 deg and theta0_6 = -180 deg (a frame
  // turned about the last axis). UR's table is the same arm: the factory deltas apply to it.
  const RobotModel ur10 = test::loadBundled("ur10");
  const UrDeltas deltas = testDeltas();
  const RobotModel reference = modelFromUrDeltas(ur10.nominal, deltas);  // UR's own table and frames
  const std::string urdf = test::sourcePath("tests/data/urdf/ur10.urdf");
  const RobotModel from_urdf = readUrdfRobot(urdf);
  ASSERT_EQ(from_urdf.nominal.joints[5].theta0_deg, -180.0);  // what used to be refused
  const UrConvention c = urConventionOf(from_urdf.nominal);
  EXPECT_TRUE(c.rewritten);
  for (int i = 0; i < 6; ++i) {  // exactly the bundled table (UR's), pi/2 rounded in the URDF snapped
    const JointSpec &u = c.ur.joints[i], &b = ur10.nominal.joints[i];
    EXPECT_DOUBLE_EQ(u.d_mm, b.d_mm) << i;  // (metres to mm: round-off)
    EXPECT_DOUBLE_EQ(u.a_mm, b.a_mm) << i;
    EXPECT_EQ(u.alpha_deg, b.alpha_deg) << i;
    EXPECT_EQ(u.theta0_deg, 0.0) << i;
    EXPECT_EQ(u.direction, 1) << i;
    EXPECT_EQ(c.folded_theta0_deg[i], 0.0) << i;
  }
  const Eigen::Isometry3d half_turn_z(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()));
  EXPECT_TRUE(c.T_frame0_urbase.isApprox(half_turn_z, 1e-15)) << c.T_frame0_urbase.matrix();
  // (the half turn of frame 0 turns every x axis: theta0_6 -180 deg becomes 0, tool0 is UR's flange)
  EXPECT_TRUE(c.T_urflange_flange.isApprox(Eigen::Isometry3d::Identity(), 0)) << c.T_urflange_flange.matrix();
  // the calibrated model: UR's formula in the URDF's frames, world = base_link = Base turned by 180 deg
  const RobotModel m = modelFromUrDeltas(from_urdf.nominal, deltas);
  auto [mm, rad] = worstDifference(m, Eigen::Isometry3d::Identity(), reference, half_turn_z);
  EXPECT_LT(mm, 1e-9);
  EXPECT_LT(rad, 1e-12);
  // ... and against UR's formula written out here (metres of delta_d: UR's own round-off)
  double d_tot[6], a_tot[6], al_tot[6];
  for (int i = 0; i < 6; ++i) {
    d_tot[i] = kD[i] + kDeltaD[i];
    a_tot[i] = kA[i] + kDeltaA[i];
    al_tot[i] = kAlpha[i] + kDeltaAlpha[i];
  }
  Eigen::VectorXd q(6);
  q << 0.3, -1.2, 1.4, -0.5, 0.8, 2.1;
  const Eigen::Vector3d p_ur = 1000.0 * urFormula(d_tot, a_tot, kDeltaTheta, al_tot, q).topRightCorner<3, 1>();
  EXPECT_LT((forwardKinematics(m, deg(q)).translation() - half_turn_z * p_ur).norm(), 1e-6);
  // with --chain base:tool0 the world is UR's Base
  const RobotModel in_base = modelFromUrDeltas(readUrdfRobot(urdf, "base:tool0").nominal, deltas);
  std::tie(mm, rad) = worstDifference(in_base, Eigen::Isometry3d::Identity(), reference, Eigen::Isometry3d::Identity());
  EXPECT_LT(mm, 1e-9);
  EXPECT_LT(rad, 1e-12);
  // mounted on a ceiling 2 m up: axis 1 points down, joint 1 has direction -1 in the model,
  // which a half turn of frame 0 about x makes UR's +1
  std::string text = test::readText(urdf);
  const std::string mount = "<origin rpy=\"0 0 0\" xyz=\"0 0 0\"/>\n    <parent link=\"world\"/>";
  ASSERT_NE(text.find(mount), std::string::npos);
  text.replace(text.find(mount), mount.size(), "<origin rpy=\"3.141592653589793 0 0\" xyz=\"0 0 2\"/>\n    <parent link=\"world\"/>");
  const std::string dir = test::tempDir("ur_urdf_convention");
  test::writeText(dir + "/ceiling.urdf", text);
  const RobotModel ceiling = readUrdfRobot(dir + "/ceiling.urdf");
  EXPECT_EQ(ceiling.nominal.joints[0].direction, -1);
  const RobotModel mc = modelFromUrDeltas(ceiling.nominal, deltas);
  Eigen::Isometry3d T_world_base = Eigen::Isometry3d::Identity();  // world -> base_link -> Base
  T_world_base.translation() = Eigen::Vector3d(0, 0, 2000);
  T_world_base.rotate(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
  T_world_base = T_world_base * half_turn_z;
  std::tie(mm, rad) = worstDifference(mc, Eigen::Isometry3d::Identity(), reference, T_world_base);
  EXPECT_LT(mm, 1e-9);
  EXPECT_LT(rad, 1e-12);
  // back out of the model from the URDF (as identify would have it: plus a base deviation, the
  // tracker's frame): the same deltas, the same YAML chain as UR's table with the deltas
  RobotModel identified = m;
  identified.deviations.base_mm = Eigen::Vector3d(2400, -1700, -600);
  identified.deviations.base_rot_rad = Eigen::Vector3d(0, 0, 0.5);
  const UrDeltasFromModel back = urDeltasFromModel(identified);
  EXPECT_TRUE(back.table_rewritten);
  EXPECT_LT(back.max_difference_mm, 1e-6);
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(back.deltas.d_m[i], kDeltaD[i], 1e-9) << i;
    EXPECT_NEAR(back.deltas.a_m[i], kDeltaA[i], 1e-12) << i;
    EXPECT_NEAR(back.deltas.theta_rad[i], kDeltaTheta[i], 1e-11) << i;
    EXPECT_NEAR(back.deltas.alpha_rad[i], kDeltaAlpha[i], 1e-11) << i;
  }
  std::vector<std::string> notes;
  test::writeText(dir + "/cal.yaml", formatUrCalibrationYaml(identified, &notes));
  ASSERT_FALSE(notes.empty());
  EXPECT_EQ(notes[0].rfind("base deviation (2400, -1700, -600) mm", 0), 0u) << notes[0];
  const RobotModel from_yaml = modelFromUrCalibrationYaml(ur10.nominal, dir + "/cal.yaml");
  std::tie(mm, rad) = worstDifference(from_yaml, Eigen::Isometry3d::Identity(), reference, Eigen::Isometry3d::Identity());
  EXPECT_LT(mm, 1e-9);
  EXPECT_LT(rad, 1e-12);
  std::filesystem::remove_all(dir);
}

// ur_description's URDF with the arm on a 0.8 m pedestal (its xacro's origin argument: world ->
// base_link): read from its root, DH frame 0 lies at the pedestal's foot and d1 holds the pedestal,
// which the YAML's shoulder entry (from UR's Base) does not. The YAML of this very arm was refused
// as "the calibration of another arm type"; now the message names the mount and the chain that
// reads, and that chain takes the YAML.
TEST(UrCalibration, AYamlOnAnArmReadFromItsMountSaysWhereTheBaseIs) {
  const RobotModel ur10 = test::loadBundled("ur10");
  const RobotModel reference = modelFromUrDeltas(ur10.nominal, testDeltas());  // shoulder z 127.3 + 0.656 mm
  const std::string dir = test::tempDir("ur_yaml_pedestal");
  test::writeText(dir + "/cal.yaml", formatUrCalibrationYaml(reference, nullptr));
  std::string text = test::readText(test::sourcePath("tests/data/urdf/ur10.urdf"));
  const std::string mount = "<origin rpy=\"0 0 0\" xyz=\"0 0 0\"/>\n    <parent link=\"world\"/>";
  ASSERT_NE(text.find(mount), std::string::npos);
  text.replace(text.find(mount), mount.size(), "<origin rpy=\"0 0 0\" xyz=\"0 0 0.8\"/>\n    <parent link=\"world\"/>");
  test::writeText(dir + "/pedestal.urdf", text);
  try {
    modelFromUrCalibrationYaml(readUrdfRobot(dir + "/pedestal.urdf").nominal, dir + "/cal.yaml");
    FAIL() << "accepted";
  } catch (const ArgumentError& e) {
    EXPECT_EQ(std::string(e.what()),
              dir + "/cal.yaml: expected UR's Base at the robot's DH frame 0, the shoulder 927.3 mm from it (d1 of 'ur10' in UR's "
                    "convention), found the shoulder 128.0 mm from UR's Base in the YAML: the robot's DH frame 0 lies about 799.3 mm "
                    "from the arm's Base along axis 1 (a mount between the chain's root and the arm), where the YAML cannot place "
                    "the arm (from a URDF: read the arm from its own base with --chain base:tool0 on ur_description's URDF)");
  }
  // the arm read from its own base: UR's formula with the deltas, world = Base
  const RobotModel m = modelFromUrCalibrationYaml(readUrdfRobot(dir + "/pedestal.urdf", "base:tool0").nominal, dir + "/cal.yaml");
  auto [mm, rad] = worstDifference(m, Eigen::Isometry3d::Identity(), reference, Eigen::Isometry3d::Identity());
  EXPECT_LT(mm, 1e-9);
  EXPECT_LT(rad, 1e-12);
  // the calibration of another arm type on the mount is still that
  RobotModel other = reference;
  other.nominal.joints[1].a_mm = 425;  // a UR5e's upper arm
  test::writeText(dir + "/other.yaml", formatUrCalibrationYaml(other, nullptr));
  try {
    modelFromUrCalibrationYaml(readUrdfRobot(dir + "/pedestal.urdf").nominal, dir + "/other.yaml");
    FAIL() << "accepted";
  } catch (const ArgumentError& e) {
    EXPECT_NE(std::string(e.what()).find("the calibration of another arm type"), std::string::npos) << e.what();
  }
  // the YAML of the arm read from its mount would lift it by the pedestal once more (shoulder z
  // 0.9273 m where the arm's is 0.1273): refused; read from its own base, the arm's 0.1273 m
  try {
    formatUrCalibrationYaml(readUrdfRobot(dir + "/pedestal.urdf"), nullptr);
    FAIL() << "written";
  } catch (const ArgumentError& e) {
    EXPECT_EQ(std::string(e.what()),
              "UR calibration YAML: expected the shoulder within 300 mm of UR's Base (d1 of every UR arm: 89.2 to 236.3 mm), found "
              "it 927.3 mm from the DH frame 0 of 'ur10' along axis 1: its chain's root stands on a mount, whose height the YAML "
              "cannot hold (written, it would lift the arm by it once more); from a URDF, read the arm from its own base with "
              "--chain base:tool0");
  }
  const std::string own = formatUrCalibrationYaml(readUrdfRobot(dir + "/pedestal.urdf", "base:tool0"), nullptr);
  EXPECT_NE(own.find("  shoulder:\n    x: 0\n    y: 0\n    z: 0.1273"), std::string::npos) << own;
  std::filesystem::remove_all(dir);
}

TEST(UrCalibration, ACalibratedDescriptionFoldsItsTheta0IntoTheDeltas) {
  // ur_description with a calibration applied (its joint origins from a ur_calibration YAML):
  // link 1's theta0 is -0.0042 deg off UR's 0 (delta_theta_1), the others too. Its YAML is
  // the arm's own (exact), its deltas are relative to its own table (said so: not UR's).
  const RobotModel ur10 = test::loadBundled("ur10");
  const RobotModel reference = modelFromUrDeltas(ur10.nominal, testDeltas());
  const std::string yaml = formatUrCalibrationYaml(reference, nullptr);
  // the YAML's six origins as ur_description's joints, with its base_link / base frames
  std::map<std::string, std::map<std::string, std::string>> v;
  std::istringstream lines(yaml);
  std::string link;
  for (std::string l; std::getline(lines, l);) {
    if (l.rfind("    ", 0) == 0) v[link][l.substr(4, l.find(':') - 4)] = l.substr(l.find(": ") + 2);
    else if (l.rfind("  ", 0) == 0) link = l.substr(2, l.find(':') - 2);
  }
  const char* const links[6] = {"shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3"};
  std::string urdf = "<robot name=\"ur10_calibrated\">\n<link name=\"base_link\"/><link name=\"base_link_inertia\"/><link name=\"base\"/>"
                     "<link name=\"flange\"/><link name=\"tool0\"/>\n"
                     "<joint name=\"base_link-base_link_inertia\" type=\"fixed\"><parent link=\"base_link\"/><child link=\"base_link_inertia\"/>"
                     "<origin xyz=\"0 0 0\" rpy=\"0 0 3.141592653589793\"/></joint>\n"
                     "<joint name=\"base_link-base_fixed_joint\" type=\"fixed\"><parent link=\"base_link\"/><child link=\"base\"/>"
                     "<origin xyz=\"0 0 0\" rpy=\"0 0 3.141592653589793\"/></joint>\n";
  std::string parent = "base_link_inertia";
  for (const char* l : links) {
    urdf += std::string("<link name=\"") + l + "_link\"/><joint name=\"" + l + "_joint\" type=\"revolute\"><parent link=\"" + parent +
            "\"/><child link=\"" + l + "_link\"/><origin xyz=\"" + v[l]["x"] + " " + v[l]["y"] + " " + v[l]["z"] + "\" rpy=\"" +
            v[l]["roll"] + " " + v[l]["pitch"] + " " + v[l]["yaw"] +
            "\"/><axis xyz=\"0 0 1\"/><limit lower=\"-6.283185307179586\" upper=\"6.283185307179586\" effort=\"330\" velocity=\"2.09\"/></joint>\n";
    parent = std::string(l) + "_link";
  }
  urdf += "<joint name=\"wrist_3-flange\" type=\"fixed\"><parent link=\"wrist_3_link\"/><child link=\"flange\"/>"
          "<origin xyz=\"0 0 0\" rpy=\"0 -1.5707963267948966 -1.5707963267948966\"/></joint>\n"
          "<joint name=\"flange-tool0\" type=\"fixed\"><parent link=\"flange\"/><child link=\"tool0\"/>"
          "<origin xyz=\"0 0 0\" rpy=\"1.5707963267948966 0 1.5707963267948966\"/></joint>\n</robot>\n";
  const std::string dir = test::tempDir("ur_calibrated_urdf");
  test::writeText(dir + "/cal.urdf", urdf);
  for (const std::string chain : {"base:tool0", ""}) {
    const RobotModel m = readUrdfRobot(dir + "/cal.urdf", chain);
    EXPECT_NEAR(m.nominal.joints[0].theta0_deg, kDeltaTheta[0] * 180 / M_PI, 2e-3) << chain;  // (-0.0042 deg; the rest from the other joints)
    const UrConvention c = urConventionOf(m.nominal);
    EXPECT_NE(c.folded_theta0_deg[0], 0.0) << chain;
    EXPECT_EQ(c.ur.joints[0].theta0_deg, 0.0) << chain;
    // its YAML read onto the bundled UR10: the same arm, in the Base frame
    test::writeText(dir + "/back.yaml", formatUrCalibrationYaml(m, nullptr));
    const RobotModel back = modelFromUrCalibrationYaml(ur10.nominal, dir + "/back.yaml");
    auto [mm, rad] = worstDifference(back, Eigen::Isometry3d::Identity(), reference, Eigen::Isometry3d::Identity());
    EXPECT_LT(mm, 1e-9) << chain;
    EXPECT_LT(rad, 1e-12) << chain;
    // deltas relative to its own table: exact for that table, link 1's theta0 in delta_theta_1
    const UrDeltasFromModel d = urDeltasFromModel(m);
    EXPECT_TRUE(d.table_rewritten);
    EXPECT_LT(d.max_difference_mm, 1e-6) << chain;
    EXPECT_NEAR(d.deltas.theta_rad[0], c.folded_theta0_deg[0] * M_PI / 180, 1e-15) << chain;
    // UR's factory deltas on it would apply the calibration twice: refused by name
    try {
      modelFromUrDeltas(m.nominal, testDeltas());
      ADD_FAILURE() << "no error";
    } catch (const ArgumentError& e) {
      EXPECT_NE(std::string(e.what()).find("joint 'shoulder_joint': expected UR's nominal table (theta0 0 or 180 deg), found "),
                std::string::npos) << e.what();
    }
  }
  std::filesystem::remove_all(dir);
}

TEST(UrCalibration, AByteOrderMarkIsNotPartOfTheText) {
  // Windows editors start a file with a UTF-8 byte-order mark; the CSV, mapping, URDF and robot
  // file readers skip it, and so do the calibration.conf and YAML readers: the same numbers
  const std::string dir = test::tempDir("ur_bom");
  const UrDeltas deltas = testDeltas();
  const std::string conf = formatUrCalibrationConf(deltas);
  test::writeText(dir + "/bom.conf", "\xEF\xBB\xBF" + conf);
  const UrDeltas read = readUrCalibrationConf(dir + "/bom.conf");
  for (int i = 0; i < 6; ++i) {
    EXPECT_EQ(read.theta_rad[i], kDeltaTheta[i]) << i;
    EXPECT_EQ(read.d_m[i], kDeltaD[i]) << i;
  }
  const RobotDefinition ur10 = test::loadBundled("ur10").nominal;
  const std::string yaml = formatUrCalibrationYaml(modelFromUrDeltas(ur10, deltas), nullptr);
  test::writeText(dir + "/plain.yaml", yaml);
  test::writeText(dir + "/bom.yaml", "\xEF\xBB\xBF" + yaml);
  const SerialChain plain = readUrCalibrationYaml(dir + "/plain.yaml"), bom = readUrCalibrationYaml(dir + "/bom.yaml");
  ASSERT_EQ(bom.joints.size(), 6u);
  for (size_t k = 0; k < 6; ++k) {
    EXPECT_TRUE(bom.joints[k].T_prev_joint.isApprox(plain.joints[k].T_prev_joint, 0)) << k;
    EXPECT_EQ(bom.joints[k].line, plain.joints[k].line) << k;
  }
  // an error on the first line still names it (the mark is not counted as text there either)
  test::writeText(dir + "/bad.yaml", "\xEF\xBB\xBFkinematic:\n");
  try {
    readUrCalibrationYaml(dir + "/bad.yaml");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.yaml:1:1: expected 'kinematics:', found 'kinematic:'"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

TEST(UrCalibration, MalformedFilesGiveFileLineColumnExpectedFound) {
  const std::string dir = test::tempDir("ur_bad");
  const std::string good = "[mounting]\ndelta_theta = [0, 0, 0, 0, 0, 0]\ndelta_a = [0, 0, 0, 0, 0, 0]\n"
                           "delta_d = [0, 0, 0, 0, 0, 0]\ndelta_alpha = [0, 0, 0, 0, 0, 0]\n";
  struct Case {
    std::string text, expected;
  };
  const std::vector<Case> cases = {
      {"[mounting]\ndelta_theta = [0, 0, 0, 0, 0]\n", "c.conf:2:15: delta_theta: expected 6 values, found 5"},
      {"[mounting]\ndelta_theta = [0, 0, x, 0, 0, 0]\n", "c.conf:2:22: delta_theta: expected a finite number, found 'x'"},
      {good + "delta_a = [0, 0, 0, 0, 0, 0]\n", "c.conf:6:1: delta_a given twice (first at line 3)"},
      {"[mounting]\ndelta_theta = [0, 0, 0, 0, 0, 0]\ndelta_a = [0, 0, 0, 0, 0, 0]\n",
       "c.conf:1:1: expected 'delta_alpha = [...]' in [mounting], found none"},
      {"", "c.conf:1:1: expected a section [mounting] with delta_theta, delta_a, delta_d and delta_alpha, found an empty file"},
      // UR's controller writes [mounting] (forum.universal-robots.com topic 18921, tests/data/urdf/ur_forum_calibration.conf)
      {"[Mounting]\ndelta_theta = [0, 0, 0, 0, 0, 0]\n",
       "c.conf:1:1: expected the section header [mounting] (in lower case, as UR's controller writes calibration.conf), found '[Mounting]'"},
      {"# no section\n\n  delta_theta = [0, 0, 0, 0, 0, 0]\n",
       "c.conf:3:3: expected the section header [mounting] before 'delta_theta = ...' (UR's controller writes the deltas in section "
       "[mounting]), found no section header"},
      {"[other]\ndelta_theta = [0, 0, 0, 0, 0, 0]\n[more]\n",
       "c.conf:1:1: expected a section [mounting] with delta_theta, delta_a, delta_d and delta_alpha, found only the section(s) [other], [more]"},
      {"[mounting]\ndelta_d = [0, 0, 5000, 0, 0, 0]\n", "c.conf:2:18: delta_d value 3: expected a DH delta of at most 1000 m, found 5000 m"},
      {"[mounting]\n  delta_d = 0\n", "c.conf:2:13: delta_d: expected a list [v1, ..., v6], found '0'"},
      {"[mounting\n", "c.conf:1:1: expected a section header like [mounting], found '[mounting'"},
  };
  // each case's text written to `path` and read by `read`: an InputError with the expected text
  const auto expectErrors = [](const std::vector<Case>& all, const std::string& path, const auto& read) {
    for (const Case& c : all) {
      test::writeText(path, c.text);
      try {
        read(path);
        ADD_FAILURE() << "no error for " << c.text;
      } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(c.expected), std::string::npos) << e.what();
      }
    }
  };
  expectErrors(cases, dir + "/c.conf", [](const std::string& p) { readUrCalibrationConf(p); });
  const std::vector<Case> yaml = {
      {"kinematics:\n  shoulder:\n    x: 0\n    y: zero\n", "k.yaml:4:8: shoulder.y: expected a finite number, found 'zero'"},
      {"kinematics:\n  shoulder:\n    w: 0\n", "k.yaml:3:5: 'shoulder': expected a key x, y, z, roll, pitch or yaw, found 'w'"},
      {"kinematics:\n  shoulder:\n    x: 0\n", "k.yaml:2:3: 'shoulder': expected 'y: value', found none"},
      {"", "k.yaml:1:1: kinematics: expected an entry 'shoulder:', found none"},
      {"kinematics:\n  shoulder:\n    yaw: 0x10\n", "k.yaml:3:10: shoulder.yaw: expected an angle of at most a turn (2 pi rad), found 16 rad"},
      {"kinematics:\n  shoulder:\n    z: 1e23\n", "k.yaml:3:8: shoulder.z: expected an offset of at most 1000 m, found 1e+23 m"},
      {"kinematics:\n  shoulder:\n    z: 0.1\n    z: 0.5\n", "k.yaml:4:5: 'shoulder.z': expected one value, found a second one (the first at line 3)"},
      {"kinematics:\n  shoulder:\n\tz: 0.1\n", "k.yaml:3:1: expected spaces for the indentation (YAML allows no tabs there), found a tab"},
  };
  expectErrors(yaml, dir + "/k.yaml", [](const std::string& p) { readUrCalibrationYaml(p); });
  // a YAML that reads but turns a joint against the UR10's (wrist_2's axis flipped by its roll):
  // at that joint's entry (the fitted chain carries the entry's line and column)
  const RobotDefinition ur10 = test::loadBundled("ur10").nominal;
  std::string flipped = formatUrCalibrationYaml(RobotModel::fromDefinition(ur10), nullptr);
  const size_t wrist_2 = flipped.find("  wrist_2:"), roll = flipped.find("roll: ", wrist_2);
  ASSERT_NE(roll, std::string::npos);
  flipped.replace(roll, flipped.find('\n', roll) - roll, "roll: -1.5707963267948966");
  const int line = 1 + static_cast<int>(std::count(flipped.begin(), flipped.begin() + static_cast<std::ptrdiff_t>(wrist_2), '\n'));
  test::writeText(dir + "/f.yaml", flipped);
  try {
    modelFromUrCalibrationYaml(ur10, dir + "/f.yaml");
    ADD_FAILURE() << "no error for\n" << flipped;
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("f.yaml:" + std::to_string(line) + ":3: joint '" + ur10.joints[4].name +
                                         "': expected it to turn the way joint '" + ur10.joints[4].name +
                                         "' of the reference robot"),
              std::string::npos)
        << e.what();
  }
  std::filesystem::remove_all(dir);
}

// export writes its --out to a temporary file renamed into place, and never over one of its
// inputs: the controller's calibration.conf (its joint checksums and status would be lost to a
// file of the four delta lists), the ur_calibration YAML or the robot file (by path or by the
// bundled name) are refused, exit 1, each left byte for byte.
TEST(UrCalibration, ExportNeverOverwritesItsInputs) {
  const std::string dir = test::tempDir("ur_export_inputs");
  // the bundled robots from a copy (a regression must not overwrite the source tree's)
  std::filesystem::create_directories(dir + "/robots");
  test::writeText(dir + "/robots/ur10.xml", test::readText(test::sourcePath("robots/ur10.xml")));
  ASSERT_EQ(::setenv("ACCURA_ROBOTS_DIR", (dir + "/robots").c_str(), 1), 0);
  struct Unset {
    ~Unset() { ::unsetenv("ACCURA_ROBOTS_DIR"); }
  } unset;
  const std::string conf = test::readText(test::sourcePath("tests/data/urdf/ur_forum_calibration.conf"));
  test::writeText(dir + "/calibration.conf", conf);
  test::CliRun r = test::runAccuraIn(dir, "export --robot ur10 --ur-deltas calibration.conf --format robot --out ur10_cal.xml");
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::runAccuraIn(dir, "export --robot ur10 --format ur-yaml --out ur10.yaml");
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string cal = test::readText(dir + "/ur10_cal.xml"), yaml = test::readText(dir + "/ur10.yaml");
  const std::string bundled = test::readText(dir + "/robots/ur10.xml");
  const std::vector<std::tuple<std::string, std::string, std::string>> runs = {
      {"export --robot ur10 --ur-deltas calibration.conf --format ur-deltas --out calibration.conf", "calibration.conf", "calibration.conf"},
      {"export --robot ur10 --ur-deltas calibration.conf --format robot --out ./calibration.conf", "./calibration.conf", "calibration.conf"},
      {"export --robot ur10 --ur-yaml ur10.yaml --format ur-yaml --out ur10.yaml", "ur10.yaml", "ur10.yaml"},
      {"export --robot ur10_cal.xml --format robot --out ur10_cal.xml", "ur10_cal.xml", "ur10_cal.xml"},
      {"export --robot ur10_cal.xml --format urdf --out " + dir + "/ur10_cal.xml", dir + "/ur10_cal.xml", "ur10_cal.xml"},
      {"export --robot ur10 --format robot --out robots/ur10.xml", "robots/ur10.xml", dir + "/robots/ur10.xml"},
  };
  for (const auto& [args, out, in] : runs) {
    r = test::runAccuraIn(dir, args);
    EXPECT_EQ(r.code, 1) << args;
    EXPECT_EQ(r.err, "accura: error: " + out + ": the output would overwrite the input " + in + ": choose another --out\n") << args;
  }
  EXPECT_EQ(test::readText(dir + "/calibration.conf"), conf);
  EXPECT_EQ(test::readText(dir + "/ur10.yaml"), yaml);
  EXPECT_EQ(test::readText(dir + "/ur10_cal.xml"), cal);
  EXPECT_EQ(test::readText(dir + "/robots/ur10.xml"), bundled);
  // another name is written as before
  r = test::runAccuraIn(dir, "export --robot ur10_cal.xml --format ur-deltas --out back.conf");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NEAR(readUrCalibrationConf(dir + "/back.conf").d_m[2], -92.5270326908668181, 1e-6);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace accura::calib
