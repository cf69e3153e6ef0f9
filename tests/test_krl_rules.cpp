// KRL semantics of the compensation (issue 12): S and T as the controller uses them (CP motions
// ignore the programmed S/T, PTP uses them), corrections that round to zero keep the text
// (the nominal robot returns every program byte for byte), named points keep their meaning
// (a split CIRC gets a new auxiliary point), external axes are refused.
//
// The simulated controller here implements the KUKA rules on its own (KUKA System Software 8,
// "Status and Turn": the programmed S/T are taken into account for PTP only; on CP motions
// Status is kept from the start and Turn follows the path): PTP solves the nominal IK on the
// programmed S/T, LIN steps along the commanded line with the nominal IK continued from the
// previous step. It does not call accura's compensation to choose a configuration.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"
#include "accura/calib/ik.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"
#include "accura/postproc/job.h"
#include "accura/postproc/krl.h"
#include "accura/postproc/program_io.h"
#include "accura/postproc/xml_program.h"
#include "test_util.h"

namespace accura::postproc {
namespace {

/// The KR 16 whose base is 0.2, -0.1, 0.3 mm off: a correction every target shows.
JobSettings kr16BaseOff() {
  JobSettings s;
  s.calibrated = test::loadBundled("kuka_kr16");
  s.calibrated.deviations.base_mm = Eigen::Vector3d(0.2, -0.1, 0.3);
  return s;
}

std::string aggregate(const Eigen::Isometry3d& T, int s, int t) {
  const calib::XyzAbc p = calib::toXyzAbc(T);
  return "{X " + formatMm(p.x_mm) + ",Y " + formatMm(p.y_mm) + ",Z " + formatMm(p.z_mm) + ",A " + formatDeg(p.a_deg) +
         ",B " + formatDeg(p.b_deg) + ",C " + formatDeg(p.c_deg) + ",S " + std::to_string(s) + ",T " + std::to_string(t) +
         ",E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}";
}

Eigen::VectorXd joints(std::initializer_list<double> v) {
  Eigen::VectorXd q(static_cast<Eigen::Index>(v.size()));
  Eigen::Index i = 0;
  for (double x : v) q[i++] = x;
  return q;
}

double distanceToSegment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d d = b - a;
  const double s = std::clamp(d.squaredNorm() > 0 ? (p - a).dot(d) / d.squaredNorm() : 0.0, 0.0, 1.0);
  return (p - (a + s * d)).norm();
}

/// A KUKA controller (nominal model) driving the real robot through a program of PTP and LIN
/// motions to Cartesian targets (world poses with the written S/T).
struct SimulatedKuka {
  calib::KinematicSolver controller, real;
  Eigen::VectorXd q;  ///< the controller's joints
  int status_changes_on_cp = 0;
  SimulatedKuka(const calib::RobotModel& c, const calib::RobotModel& r) : controller(c), real(r) {}

  /// PTP: the programmed S/T choose the solution.
  bool ptp(const Eigen::Isometry3d& T, int s, int t) {
    const calib::IkResult r = controller.inverse(T, calib::Configuration{s, t}, Eigen::VectorXd(), calib::IkOptions{});
    if (r.status != calib::IkStatus::kOk) return false;
    q = r.q;
    return true;
  }

  /// LIN: position linear, orientation by the shortest rotation, 0.5 mm steps, each solved
  /// from the previous joints (the programmed S/T play no part). Returns the real TCP positions.
  std::vector<Eigen::Vector3d> lin(const Eigen::Isometry3d& T_end) {
    const Eigen::Isometry3d T0 = controller.forward(q);
    const int s0 = calib::kukaConfiguration(controller.model(), q).status;
    const Eigen::Quaterniond r0(T0.linear()), r1(T_end.linear());
    const int n = std::max(2, static_cast<int>(std::ceil((T_end.translation() - T0.translation()).norm() / 0.5)));
    std::vector<Eigen::Vector3d> out;
    for (int i = 1; i <= n; ++i) {
      const double u = static_cast<double>(i) / n;
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.translation() = (1 - u) * T0.translation() + u * T_end.translation();
      T.linear() = r0.slerp(u, r1).toRotationMatrix();
      const calib::IkResult r = controller.inverse(T, calib::Configuration{}, q, calib::IkOptions{});
      EXPECT_EQ(r.status, calib::IkStatus::kOk) << r.message;
      if (r.status != calib::IkStatus::kOk) return out;
      q = r.q;
      if (calib::kukaConfiguration(controller.model(), q).status != s0) ++status_changes_on_cp;
      out.push_back(real.forward(q).translation());
    }
    return out;
  }
};

struct StCell {
  calib::RobotModel controller, real;
  StCell() {
    controller = test::loadBundled("kuka_kr16");
    controller.nominal.T_flange_tcp = calib::toIsometry({20, 0, 250, 0, -30, 0});
    calib::SimulateOptions o;
    o.effects = {"geometric", "joint_compliance"};
    o.set_station = false;
    o.seed = 5;
    real = calib::perturbModel(controller, o);
  }
  /// The target (in $BASE = $NULLFRAME = the robot base) of the nominal TCP at q.
  Eigen::Isometry3d target(const Eigen::VectorXd& q) const {
    return controller.nominal.T_world_base.inverse() * calib::KinematicSolver(controller).forward(q);
  }
};

TEST(KrlRules, CpTargetsWithStaleStatusAndTurnFollowThePathPtpKeepsItsBranch) {
  const StCell cell;
  const calib::KinematicSolver nominal(cell.controller);
  const Eigen::VectorXd q1 = joints({10, -80, 100, 20, 40, 30});
  const Eigen::VectorXd q2 = joints({25, -70, 95, 25, 45, 35});
  const Eigen::VectorXd q3 = joints({35, -75, 105, 15, 50, 20});
  const Eigen::VectorXd q4 = joints({30, -70, 100, 20, 45, -160});  // A6 < 0: its T bit chooses the branch
  const calib::Configuration c1 = calib::kukaConfiguration(cell.controller, q1), c2 = calib::kukaConfiguration(cell.controller, q2),
                      c3 = calib::kukaConfiguration(cell.controller, q3), c4 = calib::kukaConfiguration(cell.controller, q4);
  // the OLP wrote stale S/T into the LIN targets: another elbow bit, the A1 and A6 T bits flipped
  const int s2 = c2.status ^ 2, t2 = c2.turn ^ 1, s3 = c3.status, t3 = c3.turn ^ 32;
  ASSERT_NE(s2, c2.status);
  ASSERT_NE(t3, c3.turn);
  const std::string dir = test::tempDir("krl_st");
  test::writeText(dir + "/st.src",
                  "DEF st( )\n$TOOL={X 20,Y 0,Z 250,A 0,B -30,C 0}\n$BASE=$NULLFRAME\nPTP XP1\nLIN XP2\nLIN XP3\nPTP XP4\nEND\n");
  test::writeText(dir + "/st.dat", "DEFDAT st\nDECL E6POS XP1=" + aggregate(cell.target(q1), c1.status, c1.turn) +
                                       "\nDECL E6POS XP2=" + aggregate(cell.target(q2), s2, t2) +
                                       "\nDECL E6POS XP3=" + aggregate(cell.target(q3), s3, t3) +
                                       "\nDECL E6POS XP4=" + aggregate(cell.target(q4), c4.status, c4.turn) + "\nENDDAT\n");
  const Program in = readKrl(dir + "/st.src");
  JobSettings s;
  s.calibrated = cell.real;
  s.tol_mm = 0.05;
  const ProgramCompensation pc = compensateProgramReport(in, s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().message;
  // one warning for the program, naming the count and the first target
  int st_warnings = 0;
  for (const auto& w : pc.report.warnings)
    if (w.message.find("CP motions") != std::string::npos) {
      ++st_warnings;
      EXPECT_NE(w.message.find("2 target(s)"), std::string::npos) << w.message;
      EXPECT_NE(w.message.find("First: XP2"), std::string::npos) << w.message;
    }
  EXPECT_EQ(st_warnings, 1);
  // the written S/T of the CP targets are kept as written
  const KrlText text = writeKrl(pc.program);
  const std::string st2 = ",S " + std::to_string(s2) + ",T " + std::to_string(t2) + ",";
  const std::string st3 = ",S " + std::to_string(s3) + ",T " + std::to_string(t3) + ",";
  EXPECT_NE(text.dat.find(st2), std::string::npos) << text.dat;
  EXPECT_NE(text.dat.find(st3), std::string::npos) << text.dat;

  // run the written program: read back, executed by the simulated controller on the real robot
  const std::string out_dir = test::tempDir("krl_st_out");
  test::writeText(out_dir + "/st.src", text.src);
  test::writeText(out_dir + "/st.dat", text.dat);
  const Program written = readKrl(out_dir + "/st.src");
  ASSERT_EQ(written.motions.size(), pc.program.motions.size());
  auto run = [&](const Program& p, const std::vector<bool>& inserted) {
    SimulatedKuka kuka(cell.controller, cell.real);
    double path_mm = 0, ptp_mm = 0;
    size_t input = 0;  // the input motion this one belongs to
    for (size_t k = 0; k < p.motions.size(); ++k) {
      const Motion& m = p.motions[k];
      const Eigen::Isometry3d T = cell.controller.nominal.T_world_base * calib::toIsometry(m.target.xyzAbc());
      const Eigen::Isometry3d intended = cell.controller.nominal.T_world_base * calib::toIsometry(in.motions[input].target.xyzAbc());
      if (m.type == MotionType::kPtp) {
        EXPECT_TRUE(kuka.ptp(T, *m.target.status, *m.target.turn)) << "motion " << k;
        ptp_mm = std::max(ptp_mm, (kuka.real.forward(kuka.q).translation() - intended.translation()).norm());
      } else {
        const Eigen::Vector3d a = cell.controller.nominal.T_world_base * calib::toIsometry(in.motions[input - 1].target.xyzAbc()).translation();
        for (const Eigen::Vector3d& x : kuka.lin(T)) path_mm = std::max(path_mm, distanceToSegment(x, a, intended.translation()));
      }
      if (!inserted[k]) ++input;
    }
    EXPECT_EQ(kuka.status_changes_on_cp, 0);
    return std::make_pair(path_mm, ptp_mm);
  };
  std::vector<bool> inserted;
  for (const Motion& m : pc.program.motions) inserted.push_back(m.inserted);
  const auto compensated = run(written, inserted);
  EXPECT_LE(compensated.first, s.tol_mm + 0.005);  // mm: the tolerance plus the sampling margin
  EXPECT_LE(compensated.second, 1e-3);            // mm: the PTP targets land on their branch
  const auto original = run(in, std::vector<bool>(in.motions.size(), false));
  EXPECT_GT(original.first, 0.2);  // mm: the program as written misses the path
  EXPECT_GT(original.second, 0.2);
  // PTP XP4: the corrected target is on the written branch (A6 < 0), not the nearest one
  SimulatedKuka check(cell.controller, cell.real);
  ASSERT_TRUE(check.ptp(cell.controller.nominal.T_world_base * calib::toIsometry(written.motions.back().target.xyzAbc()), c4.status, c4.turn));
  EXPECT_LT(check.q[5], 0);
}

// ---------------------------------------------------------------------------------------------
// The nominal robot changes nothing

struct Case {
  std::string src;     ///< relative to the source tree
  std::string config;  ///< $config.dat, "" none
  std::string robot;   ///< robot file whose nominal model is used
};

TEST(KrlRules, TheNominalRobotReturnsEveryProgramByteForByte) {
  const std::vector<Case> cases = {
      {"tests/golden/compensate/seam.src", "tests/golden/compensate/$config.dat", "tests/golden/compensate/kr16_real.xml"},
      {"tests/golden/compensate/expected/seam.src", "tests/golden/compensate/$config.dat", "tests/golden/compensate/kr16_real.xml"},
      {"tests/golden/krl/kss8_inline/weld_seam.src", "tests/golden/krl/config/$config.dat", "tests/golden/compensate/kr16_real.xml"},
      {"tests/golden/xml/weld_seam.xml", "tests/golden/krl/config/$config.dat", "tests/golden/compensate/kr16_real.xml"},
  };
  for (const Case& c : cases) {
    ProgramReadOptions o;
    if (!c.config.empty()) o.config_path = test::sourcePath(c.config);
    const Program in = readProgram(test::sourcePath(c.src), o);
    JobSettings s;
    s.calibrated = calib::RobotModel::fromDefinition(calib::readRobotFile(test::sourcePath(c.robot)).nominal);
    const ProgramCompensation pc = compensateProgramReport(in, s);
    ASSERT_TRUE(pc.ok()) << c.src << ": " << pc.report.errors.front().where.str() << ": " << pc.report.errors.front().message;
    ASSERT_GT(pc.report.targets.size(), 2u) << c.src;
    // mm: nothing to correct but the tool the XML writes with 4 decimals (the model's tool is
    // the calibrated one, 0.5e-4 mm away): below what is written
    EXPECT_LT(pc.report.max_correction_mm, 5e-5) << c.src;
    EXPECT_EQ(pc.report.points_added, 0) << c.src;
    const std::vector<calib::OutputFile> files = renderProgram(pc.program, programFormat(c.src), "out" + c.src.substr(c.src.rfind('.')));
    EXPECT_EQ(files.front().text, test::readText(test::sourcePath(c.src))) << c.src;
    if (files.size() > 1) {
      EXPECT_EQ(files[1].text, test::readText(in.krl->dat_path)) << c.src;
    }
  }
}

TEST(KrlRules, AJointAtZeroKeepsTheWrittenTurn) {
  // XP1 puts A1 and A4 at 0 (Y 0, A 0, B 90): the IK's solution may come out at -1e-14 deg,
  // whose Turn bit differs from the written one. Either sign reaches the pose at the written
  // precision, so with nothing to correct the .dat comes back byte for byte, with no warning.
  const std::string dir = test::tempDir("krl_zero_turn");
  test::writeText(dir + "/p6.src",
                  "DEF p6( )\n$TOOL = $NULLFRAME\n$BASE = $NULLFRAME\nPTP {A1 0,A2 -90,A3 60,A4 10,A5 30,A6 0}\n"
                  "PTP XP1\nLIN XP2\nPTP XP3\nEND\n");
  const std::string dat =
      "DEFDAT p6\n"
      "DECL E6POS XP1={X 1015.737,Y 0.0,Z 1659.689,A 0.0,B 90.0,C 0.0,S 2,T 2}\n"
      "DECL E6POS XP2={X 1106.6248,Y -402.7785,Z 1540.9335,A -20.0,B 90.0,C 0.0,S 2,T 3}\n"
      "DECL E6POS XP3={X 1248.7522,Y 0.0,Z 806.418,A 0.0,B 90.0,C 0.0,S 6,T 18}\n"
      "ENDDAT\n";
  test::writeText(dir + "/p6.dat", dat);
  const Program in = readProgram(dir + "/p6.src");
  JobSettings s;
  s.calibrated = test::loadBundled("kuka_kr16");
  const ProgramCompensation pc = compensateProgramReport(in, s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().where.str() << ": " << pc.report.errors.front().message;
  EXPECT_LT(pc.report.max_correction_mm, 1e-6);
  for (const auto& w : pc.report.warnings) EXPECT_EQ(w.message.find("T of"), std::string::npos) << w.message;
  const std::vector<calib::OutputFile> files = renderProgram(pc.program, programFormat(dir + "/p6.src"), "out.src");
  ASSERT_EQ(files.size(), 2u);
  EXPECT_EQ(files[1].text, dat);
  std::filesystem::remove_all(dir);
}

TEST(KrlRules, AComponentUnchangedAtThePrecisionWrittenKeepsItsText) {
  Target t;
  t.setPose(calib::XyzAbc{100.0, 0.0, 20.0, 160.0, 10.0, 170.0});
  // 0.03 um and 4e-6 deg: below 1e-4 mm / 1e-5 deg
  EXPECT_FALSE(t.setPoseIfChanged(calib::XyzAbc{100.00003, 0.0, 20.0, 160.000004, 10.0, 170.0}));
  EXPECT_EQ(*t.pose[0], 100.0);
  EXPECT_TRUE(t.setPoseIfChanged(calib::XyzAbc{100.00003, 0.2, 20.0, 160.0, 10.0, 170.0}));
  EXPECT_EQ(*t.pose[0], 100.0);  // kept: its text is written back as it was
  EXPECT_EQ(*t.pose[1], 0.2);
  // in the file: only Y's text changes
  const std::string dir = test::tempDir("krl_round");
  test::writeText(dir + "/p.src", "DEF p( )\nLIN XP1\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 100.0,Y 0.0,Z 20.0,A 160.0,B 10.0,C 170.0,S 2,T 10}\nENDDAT\n");
  Program p = readKrl(dir + "/p.src");
  p.motions[0].target.modified = p.motions[0].target.setPoseIfChanged(calib::XyzAbc{100.00003, 0.2, 20.0, 160.0, 10.0, 170.0});
  EXPECT_EQ(writeKrl(p).dat, "DEFDAT p\nDECL E6POS XP1={X 100.0,Y 0.2000,Z 20.0,A 160.0,B 10.0,C 170.0,S 2,T 10}\nENDDAT\n");
}

// A partial aggregate (LIN {Z 500}) takes its missing components from where the controller
// stands when the motion starts. With the nominal robot nothing is corrected, so its text stays
// (it was written complete); a robot standing 0.3 mm higher (a pure translation: no component
// but Z changes) gets its Z corrected and nothing added, the complete target before it only its
// Z too.
TEST(KrlRules, APartialAggregateKeepsItsTextWhereTheCorrectionLeavesItsComponents) {
  const std::string dir = test::tempDir("krl_partial_text");
  const std::string src =
      "DEF p( )\n\tBAS (#INITMOV,0 )\n$TOOL={X 0,Y 0,Z 200,A 0,B 90,C 0}\n$BASE={x 900,y -300,z 200,a 30,b 0,c 0} ; base\n"
      "PTP {A1 10,A2 -80,A3 100,A4 20,A5 30,A6 40}\nPTP XP1\n"
      "LIN { X 1.35598E+02 , Y -264.075,Z 477.826 , A 115.342,B -63.826,C -129.097 } C_DIS\nLIN {Z 500}\nEND\n";
  test::writeText(dir + "/p.src", src);
  test::writeText(dir + "/p.dat",
                  "DEFDAT p\nDECL E6POS XP1={X 273.087,Y -127.407,Z 618.527,A 125.327,B -47.537,C -111.572,S 2,T 2,E1 0.0}\nENDDAT\n");
  JobSettings s;
  s.calibrated = test::loadBundled("kuka_kr16");
  s.tol_mm = 0.05;
  const ProgramCompensation nominal = compensateProgramReport(readKrl(dir + "/p.src"), s);
  ASSERT_TRUE(nominal.ok()) << nominal.report.errors.front().message;
  EXPECT_EQ(writeKrl(nominal.program).src, src);

  s.calibrated.deviations.base_mm = Eigen::Vector3d(0, 0, 0.3);
  const ProgramCompensation higher = compensateProgramReport(readKrl(dir + "/p.src"), s);
  ASSERT_TRUE(higher.ok()) << higher.report.errors.front().message;
  std::string expected = src;
  for (const auto& [from, to] : {std::make_pair(std::string("Z 477.826 ,"), std::string("Z 477.5260 ,")),
                                 std::make_pair(std::string("LIN {Z 500}"), std::string("LIN {Z 499.7000}"))})
    expected.replace(expected.find(from), from.size(), to);
  EXPECT_EQ(writeKrl(higher.program).src, expected);
}

// A partial aggregate corrected by a robot whose every component's correction differs: the
// program as written, run by a controller that fills the missing components from where it
// stands (the command before: the previous target as written, or the last point inserted
// before the statement), puts the real tool on the intended pose. (Written with only its own
// components corrected, it would carry the previous point's correction.)
TEST(KrlRules, ACorrectedPartialAggregateLandsWhereTheControllerFillsItFromItsPosition) {
  const StCell cell;
  const Eigen::VectorXd q1 = joints({10, -80, 100, 20, 40, 30});
  const calib::Configuration c1 = calib::kukaConfiguration(cell.controller, q1);
  const calib::XyzAbc p1 = calib::toXyzAbc(cell.target(q1));
  const std::string dir = test::tempDir("krl_partial_lands");
  // 40 mm down, then 300 mm along X and Y (points inserted at a tolerance of 5 um)
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL={X 20,Y 0,Z 250,A 0,B -30,C 0}\n$BASE=$NULLFRAME\nPTP XP1\nLIN {Z " +
                                      formatMm(p1.z_mm - 40) + "}\nLIN {X " + formatMm(p1.x_mm - 200) + ",Y " + formatMm(p1.y_mm + 220) +
                                      "} C_DIS\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1=" + aggregate(cell.target(q1), c1.status, c1.turn) + "\nENDDAT\n");
  const Program in = readKrl(dir + "/p.src");
  JobSettings s;
  s.calibrated = cell.real;
  s.tol_mm = 0.005;
  const ProgramCompensation pc = compensateProgramReport(in, s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().message;
  const KrlText text = writeKrl(pc.program);
  const std::string out = test::tempDir("krl_partial_lands_out");
  test::writeText(out + "/p.src", text.src);
  test::writeText(out + "/p.dat", text.dat);
  const Program written = readKrl(out + "/p.src");
  ASSERT_GT(written.motions.size(), in.motions.size());  // points were inserted before the last LIN
  // the intended poses: each partial target completed from the previous one as programmed
  std::vector<calib::XyzAbc> intended;
  for (const Motion& m : in.motions) {
    calib::XyzAbc v = intended.empty() ? p1 : intended.back();
    double* c[6] = {&v.x_mm, &v.y_mm, &v.z_mm, &v.a_deg, &v.b_deg, &v.c_deg};
    for (int k = 0; k < 6; ++k)
      if (m.target.pose[k]) *c[k] = *m.target.pose[k];
    intended.push_back(v);
  }
  // the controller runs the written program: a partial target from the position it stands at
  SimulatedKuka kuka(cell.controller, cell.real);
  ASSERT_EQ(written.motions.size(), pc.program.motions.size());
  calib::XyzAbc at{};
  size_t statement = 0;
  for (size_t k = 0; k < written.motions.size(); ++k) {
    const Motion& m = written.motions[k];
    calib::XyzAbc v = at;
    double* c[6] = {&v.x_mm, &v.y_mm, &v.z_mm, &v.a_deg, &v.b_deg, &v.c_deg};
    for (int i = 0; i < 6; ++i)
      if (m.target.pose[i]) *c[i] = *m.target.pose[i];
    const Eigen::Isometry3d T = cell.controller.nominal.T_world_base * calib::toIsometry(v);
    if (m.type == MotionType::kPtp) {
      ASSERT_TRUE(kuka.ptp(T, *m.target.status, *m.target.turn));
    } else {
      const calib::IkResult r = kuka.controller.inverse(T, calib::Configuration{}, kuka.q, calib::IkOptions{});
      ASSERT_EQ(r.status, calib::IkStatus::kOk);
      kuka.q = r.q;
    }
    at = v;
    if (!pc.program.motions[k].inserted) {
      // the end of an input statement: the real tool on the intended pose
      const Eigen::Isometry3d real = kuka.real.forward(kuka.q);
      const Eigen::Isometry3d want = cell.controller.nominal.T_world_base * calib::toIsometry(intended.at(statement));
      EXPECT_LT((real.translation() - want.translation()).norm(), 2e-3) << "statement " << statement;
      EXPECT_LT(calib::rotationAngleDeg(real.linear() * want.linear().transpose()), 2e-4) << "statement " << statement;
      ++statement;
    }
  }
  EXPECT_EQ(statement, in.motions.size());
}

// KSS $ORI_TYPE (Operating and Programming Instructions for System Integrators, "Orientation
// control"): #CONSTANT keeps the orientation the motion starts with and ignores the target's;
// #JOINT turns the wrist axes linearly to the target's orientation. Set by a statement, by an
// LDAT's ORI_TYP (BAS(#CP_PARAMS), SORI_TYP of the spline inline forms) or a WITH clause.
// A #CONSTANT LIN is compensated for the orientation the robot keeps, its written angles stay
// (the controller ignores them); a #JOINT one gets its end point compensated, its path (which
// accura does not predict) unchecked. (Before: the target was corrected for its written
// orientation, which the robot never takes: the position missed by the difference.)
// $ORI_TYPE / $CIRC_TYPE where the reader cannot follow them, as $TOOL and $BASE: set inside a
// branch (after it: whichever the run took), later in a loop (the next pass), by a routine the
// program calls, or a subroutine's (the caller's). Such a CP motion is kept and named, not
// compensated for a value the controller may not run; a program whose only value is the default
// (#VAR, #BASE) has nothing to follow.
TEST(KrlRules, AnOrientationControlTheReaderCannotFollowIsKeptAndNamed) {
  const std::string dir = test::tempDir("krl_ori_flow");
  auto read = [&](const std::string& value) {
    test::writeText(dir + "/p.src", "DEF p( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE={X 1200,Y 0,Z 400,A 0,B 0,C 0}\nPTP XP1\n"
                                    "IF $IN[1] THEN\n$ORI_TYPE = " + value + "\nENDIF\nLIN XP2\n$ORI_TYPE = #VAR\nLIN XP1\n"
                                    "LOOP\nLIN XP2\n$ORI_TYPE = " + value + "\nENDLOOP\n$ORI_TYPE = #VAR\nsetori( )\nLIN XP1\nsub( )\nEND\n"
                                    "DEF sub( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE={X 1200,Y 0,Z 400,A 0,B 0,C 0}\nPTP XP1\nLIN XP2\nEND\n"
                                    "DEF setori( )\n$ORI_TYPE = " + value + "\nEND\n");
    test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 100,Y 0,Z 100,A 0,B 90,C 0}\nDECL E6POS XP2={X 150,Y 50,Z 100,A 0,B 90,C 0}\nENDDAT\n");
    return readKrl(dir + "/p.src");
  };
  const Program p = read("#CONSTANT");
  ASSERT_EQ(p.motions.size(), 7u);
  // PTP XP1, LIN XP2 (after the IF), LIN XP1, LIN XP2 (in the LOOP), LIN XP1 (after setori), sub's PTP and LIN
  EXPECT_EQ(p.motions[1].ori_type, "?$ORI_TYPE is set inside the IF at line 5: after it, its value depends on the way the program ran");
  EXPECT_EQ(p.motions[2].ori_type, "");
  EXPECT_EQ(p.motions[3].ori_type, "?$ORI_TYPE is set later in the LOOP at line 11: the next pass runs this motion with the new value");
  EXPECT_EQ(p.motions[4].ori_type, "?setori (called at " + dir + "/p.src:16:1) sets $ORI_TYPE: its value after the call is not followed");
  EXPECT_EQ(p.motions[6].ori_type, "?a subroutine runs with the caller's $ORI_TYPE until it sets its own");
  JobSettings s;
  s.calibrated = calib::readRobotFile(test::sourcePath("tests/data/plugin/kr16_calibrated.xml"));
  const ProgramCompensation pc = compensateProgramReport(p, s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().message;
  std::set<int> kept;
  for (const ProgramIssue& w : pc.report.warnings)
    if (w.message.find("left unchanged (not compensated): its orientation control is not known here") != std::string::npos) kept.insert(w.where.line);
  EXPECT_EQ(kept, (std::set<int>{8, 12, 17, 24}));
  // converted to XML the motion would state a value it does not have: refused, naming it
  test::writeText(dir + "/q.src", "DEF q( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE={X 1200,Y 0,Z 400,A 0,B 0,C 0}\nPTP XP1\n"
                                  "IF $IN[1] THEN\n$ORI_TYPE = #CONSTANT\nENDIF\nLIN XP2\nEND\n");
  test::writeText(dir + "/q.dat", "DEFDAT q\nDECL E6POS XP1={X 100,Y 0,Z 100,A 0,B 90,C 0}\nDECL E6POS XP2={X 150,Y 50,Z 100,A 0,B 90,C 0}\nENDDAT\n");
  try {
    (void)writeXmlProgram(readKrl(dir + "/q.src"));
    ADD_FAILURE() << "expected the unknown orientation control to be refused";
  } catch (const calib::ArgumentError& e) {
    EXPECT_NE(std::string(e.what()).find("q.src:8:1: cannot write 'LIN XP2' as an XML motion: its orientation control is not known here"),
              std::string::npos)
        << e.what();
  }
  // only the default anywhere: nothing to follow, every motion with it
  for (const Motion& m : read("#VAR").motions) EXPECT_EQ(m.ori_type, "") << m.where.str();
  // an XML program names the value in any case, as KRL does (#constant is #CONSTANT)
  test::writeText(dir + "/r.src", "DEF r( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE={X 1200,Y 0,Z 400,A 0,B 0,C 0}\nPTP XP1\n"
                                  "$ORI_TYPE = #CONSTANT\nLIN XP2\nEND\n");
  test::writeText(dir + "/r.dat", "DEFDAT r\nDECL E6POS XP1={X 100,Y 0,Z 100,A 0,B 90,C 0}\nDECL E6POS XP2={X 150,Y 50,Z 100,A 0,B 90,C 0}\nENDDAT\n");
  std::string xml = writeXmlProgram(readKrl(dir + "/r.src"));
  const size_t at = xml.find("ori_type=\"#CONSTANT\"");
  ASSERT_NE(at, std::string::npos) << xml;
  xml.replace(at, std::string("ori_type=\"#CONSTANT\"").size(), "ori_type=\"#constant\"");
  test::writeText(dir + "/r.xml", xml);
  EXPECT_EQ(readXmlProgram(dir + "/r.xml").motions.at(1).ori_type, "#CONSTANT");
}

// An inline form's fold names its point without the X (`;FOLD LIN P2 ..;%{PE}..%P 1:LIN, 2:P2`,
// `Kuka.PointName=P2`; the pendant writes `LIN XP2`, `FDAT_ACT=FP2` from it: KSS-written folds,
// tests/golden/krl/kss8_inline, and public generators of them). A motion in it that goes to a new
// point (XP2_1) keeps the header, whose rewriting KUKA does not document (the form would look for
// an FDAT FP2_1 the program does not declare), and is named: re-opened on the pendant the form
// shows P2, and its Touch Up or OK would go back to XP2. (Before: nothing said so.)
TEST(KrlRules, AnInlineFormWhoseMotionGoesToANewPointIsNamed) {
  const std::string dir = test::tempDir("krl_fold_new_point");
  const std::string header = ";FOLD LIN P2 Vel=0.2 m/s CPDAT1 Tool[1] Base[0];%{PE}%R 8.3.31,%MKUKATPBASIS,%CMOVE,%VLIN,%P 1:LIN, 2:P2, 3:, 5:0.2, 7:CPDAT1\n";
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE={X 1200,Y 0,Z 400,A 0,B 0,C 0}\nPTP XP1\n" + header +
                                      "LIN XP2\n;ENDFOLD\n$BASE={X 1200,Y 10,Z 400,A 0,B 0,C 0}\n" + header + "LIN XP2\n;ENDFOLD\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 100,Y 0,Z 100,A 0,B 90,C 0}\nDECL E6POS XP2={X 150,Y 50,Z 100,A 0,B 90,C 0}\nENDDAT\n");
  JobSettings s;
  s.calibrated = calib::readRobotFile(test::sourcePath("tests/data/plugin/kr16_calibrated.xml"));
  const ProgramCompensation pc = compensateProgramReport(readKrl(dir + "/p.src"), s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().message;
  std::vector<std::string> folds;
  for (const ProgramIssue& w : pc.report.warnings)
    if (w.message.find("inline form") != std::string::npos) folds.push_back(w.where.str() + ": " + w.message);
  ASSERT_EQ(folds.size(), 1u);
  EXPECT_EQ(folds[0], dir + "/p.src:9:1: the inline form's fold names P2, but its motion (" + dir +
                          "/p.src:10:1) now goes to the new point XP2_1 (declared after XP2): re-opened on the pendant the form shows P2, "
                          "Touch Up teaches XP2 and OK writes the motion to XP2 back; the fold's header is kept (edit the motion as text, or "
                          "compensate again after editing)");
  const KrlText out = writeKrl(pc.program);
  EXPECT_NE(out.src.find("\n" + header + "LIN XP2_1\n;ENDFOLD\n"), std::string::npos) << out.src;
}

// The one rule by which the KRL reader, the KRL writer and the XML reader take a $ORI_TYPE /
// $CIRC_TYPE value (program.h): a constant in upper case, "" for the default, else as written.
TEST(KrlRules, OneRuleReadsAnOrientationControlValue) {
  EXPECT_EQ(orientationControlValue("#constant", false), "#CONSTANT");
  EXPECT_EQ(orientationControlValue("#Var", false), "");
  EXPECT_EQ(orientationControlValue("#VAR", true), "#VAR");  // not $CIRC_TYPE's default
  EXPECT_EQ(orientationControlValue("#base", true), "");
  EXPECT_EQ(orientationControlValue("#path", true), "#PATH");
  EXPECT_EQ(orientationControlValue("SORI_TYP(lcpdat1)", false), "SORI_TYP(lcpdat1)");
}

// BAS(#CP_PARAMS / #CP_DAT) runs BAS.SRC's CP_DAT: `$ORI_TYPE=LDAT_ACT.ORI_TYP`, #VAR where the
// LDAT has no ORI_TYP (ON_ERROR_PROCEED; KSS 8.x BAS.SRC, public copies e.g.
// github.com/Naqiu06/KUKA-Robotics KRC/R1/System/bas.src). An LDAT the files do not declare (a
// global one, another module's) has an ORI_TYP that is not known: where the program gives a
// value other than #VAR somewhere, its LIN is kept and named, as after a branch. (Before: the
// previous value was kept, and the LIN compensated for #CONSTANT the robot may not run.)
TEST(KrlRules, AnUndeclaredLdatLeavesTheOrientationControlNotKnown) {
  const std::string dir = test::tempDir("krl_ori_ldat");
  auto read = [&](const std::string& first) {
    test::writeText(dir + "/p.src", "DEF p( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE={X 1200,Y 0,Z 400,A 0,B 0,C 0}\nPTP XP1\n$ORI_TYPE = " + first +
                                        "\nLIN XP2\nLDAT_ACT=LCPDAT9\nBAS(#CP_PARAMS,0.2)\nLIN XP1\nLDAT_ACT=LCPDAT1\nBAS(#CP_PARAMS,0.2)\nLIN XP2\n"
                                        "$ORI_TYPE = #JOINT\nLDAT_ACT=LCPDAT2\nBAS(#CP_PARAMS,0.2)\nLIN XP1\nEND\n");
    test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 100,Y 0,Z 100,A 0,B 90,C 0}\nDECL E6POS XP2={X 150,Y 50,Z 100,A 0,B 90,C 0}\n"
                                    "DECL LDAT LCPDAT1={VEL 0.2,ACC 100.0,APO_DIST 10.0,ORI_TYP #CONSTANT}\nDECL LDAT LCPDAT2={VEL 0.2,ACC 100.0,APO_DIST 10.0}\nENDDAT\n");
    return readKrl(dir + "/p.src");
  };
  const Program p = read("#CONSTANT");
  ASSERT_EQ(p.motions.size(), 5u);
  EXPECT_EQ(p.motions[1].ori_type, "#CONSTANT");
  EXPECT_EQ(p.motions[2].ori_type, "?$ORI_TYPE is LDAT_ACT's ORI_TYP (BAS(#CP_PARAMS,0.2) at " + dir +
                                       "/p.src:8:1), but LDAT_ACT=LCPDAT9 (" + dir +
                                       "/p.src:7:1) names an LDAT the program's files do not declare (a global one: give --config $config.dat)");
  EXPECT_EQ(p.motions[3].ori_type, "#CONSTANT");  // LCPDAT1's
  EXPECT_EQ(p.motions[4].ori_type, "") << "LCPDAT2 has no ORI_TYP: CP_DAT sets #VAR";
  JobSettings s;
  s.calibrated = calib::readRobotFile(test::sourcePath("tests/data/plugin/kr16_calibrated.xml"));
  const ProgramCompensation pc = compensateProgramReport(p, s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().message;
  std::set<int> kept;
  for (const ProgramIssue& w : pc.report.warnings)
    if (w.message.find("left unchanged (not compensated): its orientation control is not known here: $ORI_TYPE is LDAT_ACT's ORI_TYP") != std::string::npos)
      kept.insert(w.where.line);
  EXPECT_EQ(kept, (std::set<int>{9}));
  // a program that gives no other value than #VAR has nothing to follow
  test::writeText(dir + "/q.src", "DEF q( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE={X 1200,Y 0,Z 400,A 0,B 0,C 0}\nPTP XP1\n"
                                  "LDAT_ACT=LCPDAT9\nBAS(#CP_PARAMS,0.2)\nLIN XP2\nEND\n");
  test::writeText(dir + "/q.dat", "DEFDAT q\nDECL E6POS XP1={X 100,Y 0,Z 100,A 0,B 90,C 0}\nDECL E6POS XP2={X 150,Y 50,Z 100,A 0,B 90,C 0}\nENDDAT\n");
  const Program q = readKrl(dir + "/q.src");
  ASSERT_EQ(q.motions.size(), 2u);
  EXPECT_EQ(q.motions[1].ori_type, "");
}

// BAS(#INITMOV) sets $ORI_TYPE and $CIRC_TYPE back to their defaults (KSS 8.x BAS.SRC, INITMOV:
// `$ORI_TYPE=#VAR`, `$CIRC_TYPE=DEF_CIRC_TYP`, #BASE in the $config.dat; public copies e.g.
// github.com/Naqiu06/KUKA-Robotics KRC/R1/System/bas.src): the motions after it run with #VAR,
// #BASE; a routine that calls it changes them. (Before: the value set before it was kept.)
TEST(KrlRules, InitmovSetsTheOrientationControlBack) {
  const std::string dir = test::tempDir("krl_ori_initmov");
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE={X 1200,Y 0,Z 400,A 0,B 0,C 0}\nPTP XP1\n"
                                  "$ORI_TYPE = #CONSTANT\n$CIRC_TYPE = #PATH\nCIRC XP2, XP1\nBAS (#INITMOV,0 )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n"
                                  "$BASE={X 1200,Y 0,Z 400,A 0,B 0,C 0}\nCIRC XP2, XP1\n$ORI_TYPE = #CONSTANT\nini( )\nLIN XP2\nEND\n"
                                  "DEF ini( )\nBAS (#INITMOV,0 )\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 100,Y 0,Z 100,A 0,B 90,C 0}\nDECL E6POS XP2={X 150,Y 50,Z 100,A 0,B 90,C 0}\nENDDAT\n");
  const Program p = readKrl(dir + "/p.src");
  ASSERT_EQ(p.motions.size(), 4u);
  EXPECT_EQ(p.motions[1].ori_type, "#CONSTANT");
  EXPECT_EQ(p.motions[1].circ_type, "#PATH");
  EXPECT_EQ(p.motions[2].ori_type, "");
  EXPECT_EQ(p.motions[2].circ_type, "");
  EXPECT_EQ(p.motions[3].ori_type, "?ini (called at " + dir + "/p.src:13:1) sets $ORI_TYPE: its value after the call is not followed");
}

TEST(KrlRules, AConstantOrientationLinIsCorrectedForTheOrientationTheRobotKeeps) {
  const StCell cell;
  const Eigen::VectorXd q1 = joints({10, -80, 100, 20, 40, 30});
  const Eigen::VectorXd q2 = joints({25, -70, 95, -10, 60, 80});  // the wrist turned: another orientation
  const Eigen::VectorXd q3 = joints({30, -75, 100, 0, 50, 40});
  const calib::Configuration c1 = calib::kukaConfiguration(cell.controller, q1);
  const calib::XyzAbc p1 = calib::toXyzAbc(cell.target(q1));
  const std::string dir = test::tempDir("krl_ori_constant");
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL={X 20,Y 0,Z 250,A 0,B -30,C 0}\n$BASE=$NULLFRAME\nPTP XP1\n$ORI_TYPE = #CONSTANT\nLIN XP2\n"
                                  "TOOL_DATA[1]={X 20,Y 0,Z 250,A 0,B -30,C 0}\nLDAT_ACT=LCPDAT1\nFDAT_ACT=FP3\nBAS(#CP_PARAMS,0.2)\nLIN XP3 C_DIS\nSLIN XP2 WITH $ORI_TYPE = SORI_TYP(LCPDAT2)\n"
                                  "IF $IN[1] THEN\nLIN XP3\nENDIF\nLIN XP2\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1=" + aggregate(cell.target(q1), c1.status, c1.turn) +
                                      "\nDECL E6POS XP2=" + aggregate(cell.target(q2), c1.status, c1.turn) +
                                      "\nDECL E6POS XP3=" + aggregate(cell.target(q3), c1.status, c1.turn) +
                                      "\nDECL LDAT LCPDAT1={VEL 0.2,ACC 100.0,APO_DIST 10.0,ORI_TYP #CONSTANT,CIRC_TYP #BASE}"
                                      "\nDECL LDAT LCPDAT2={VEL 0.2,ACC 100.0,APO_DIST 10.0,ORI_TYP #JOINT,CIRC_TYP #BASE}"
                                      "\nDECL FDAT FP3={TOOL_NO 1,BASE_NO 0,IPO_FRAME #BASE}\nENDDAT\n");
  const Program in = readKrl(dir + "/p.src");
  ASSERT_EQ(in.motions.size(), 6u);
  const char* const kOri[6] = {"", "#CONSTANT", "#CONSTANT", "#JOINT", "#CONSTANT", "#CONSTANT"};
  for (size_t k = 0; k < 6; ++k) EXPECT_EQ(in.motions[k].ori_type, kOri[k]) << k;
  JobSettings s;
  s.calibrated = cell.real;
  const ProgramCompensation pc = compensateProgramReport(in, s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().message;
  const auto warned = [&](int line, const std::string& what) {
    for (const ProgramIssue& w : pc.report.warnings)
      if (w.where.line == line && w.message.find(what) != std::string::npos) return true;
    return false;
  };
  EXPECT_TRUE(warned(12, "SLIN with $ORI_TYPE #JOINT")) << "the #JOINT SLIN";
  // after the IF the start is not known: the orientation a #CONSTANT LIN keeps is not either
  EXPECT_TRUE(warned(16, "LIN left unchanged (not compensated): $ORI_TYPE #CONSTANT keeps the orientation"));
  const KrlText text = writeKrl(pc.program);
  // the written angles of XP2 and XP3 stay (the controller ignores them), their positions change
  for (const auto& [name, q] : {std::make_pair("XP2", q2), std::make_pair("XP3", q3)}) {
    const calib::XyzAbc w = calib::toXyzAbc(cell.target(q));
    const std::string angles = ",A " + formatDeg(w.a_deg) + ",B " + formatDeg(w.b_deg) + ",C " + formatDeg(w.c_deg) + ",";
    const size_t at = text.dat.find(std::string("DECL E6POS ") + name + "={");
    ASSERT_NE(at, std::string::npos) << text.dat;
    const std::string decl = text.dat.substr(at, text.dat.find('\n', at) - at);
    EXPECT_NE(decl.find(angles), std::string::npos) << decl;
    EXPECT_EQ(decl.find("X " + formatMm(w.x_mm) + ","), std::string::npos) << decl;
  }
  // the controller runs the written program: PTP XP1, then LIN XP2 (and the points inserted
  // before it) with the orientation of the start kept, the written one ignored
  const std::vector<Motion>& written = pc.program.motions;
  SimulatedKuka kuka(cell.controller, cell.real);
  const Eigen::Isometry3d T1 = cell.controller.nominal.T_world_base * calib::toIsometry(written[0].target.xyzAbc());
  ASSERT_TRUE(kuka.ptp(T1, *written[0].target.status, *written[0].target.turn));
  const Eigen::Matrix3d R_start = kuka.controller.forward(kuka.q).linear();
  const Eigen::Vector3d intended_start = (cell.controller.nominal.T_world_base * calib::toIsometry(p1)).translation();
  const Eigen::Vector3d intended_end = (cell.controller.nominal.T_world_base * cell.target(q2)).translation();
  double path_error = 0;
  for (size_t k = 1; k < written.size(); ++k) {
    Eigen::Isometry3d T = cell.controller.nominal.T_world_base * calib::toIsometry(written[k].target.xyzAbc());
    T.linear() = R_start;  // #CONSTANT
    for (const Eigen::Vector3d& x : kuka.lin(T)) path_error = std::max(path_error, distanceToSegment(x, intended_start, intended_end));
    if (!written[k].inserted) break;  // LIN XP2 itself
  }
  EXPECT_LT((kuka.real.forward(kuka.q).translation() - intended_end).norm(), 2e-3);
  EXPECT_LT(path_error, s.tol_mm + 1e-3);
}

// KSS $CIRC_TYPE #PATH (a statement, an LDAT's CIRC_TYP, WITH .. SCIRC_TYP(LDAT)): the
// orientation of a circle turns with the path, which accura does not predict. The end point is
// compensated, the path not checked (a warning); with $ORI_TYPE #CONSTANT the robot ends on the
// start's orientation turned by the arc: kept and named. (Before: compensated as base-related.)
TEST(KrlRules, APathRelatedCircleIsCompensatedAtItsEndOrKeptAndNamed) {
  const std::string dir = test::tempDir("krl_circ_path");
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XP1\n$CIRC_TYPE = #PATH\n"
                                  "CIRC XP2, XP3\nSCIRC XP4, XP1 WITH $ORI_TYPE = #CONSTANT\nLIN XP3\n"
                                  "SCIRC XP4, XP1 WITH $CIRC_TYPE = SCIRC_TYP(LCPDAT1)\nEND\n");
  test::writeText(dir + "/p.dat",
                  "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2={X 1050,Y 50,Z 800,A 0,B 90,C 0}\n"
                  "DECL E6POS XP3={X 1000,Y 100,Z 800,A 0,B 90,C 0}\nDECL E6POS XP4={X 950,Y 50,Z 800,A 0,B 90,C 0}\n"
                  "DECL LDAT LCPDAT1={VEL 0.2,ORI_TYP #VAR,CIRC_TYP #BASE}\nENDDAT\n");
  const Program in = readKrl(dir + "/p.src");
  ASSERT_EQ(in.motions.size(), 5u);
  const char* const kCirc[5] = {"", "#PATH", "#PATH", "", ""};  // (only circles read it)
  for (size_t k = 0; k < 5; ++k) EXPECT_EQ(in.motions[k].circ_type, kCirc[k]) << k;
  const JobSettings s = kr16BaseOff();
  const ProgramCompensation pc = compensateProgramReport(in, s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().where.str() << ": " << pc.report.errors.front().message;
  EXPECT_EQ(pc.report.motions_left_unchanged, 1);
  const auto warned = [&](int line, const std::string& what) {
    for (const ProgramIssue& w : pc.report.warnings)
      if (w.where.line == line && w.message.find(what) != std::string::npos) return true;
    return false;
  };
  EXPECT_TRUE(warned(6, "CIRC with $CIRC_TYPE #PATH (the controller turns the orientation with the circle"));
  EXPECT_TRUE(warned(7, "SCIRC left unchanged (not compensated): its orientation control $CIRC_TYPE #PATH with $ORI_TYPE #CONSTANT"));
  // the end point compensated on its own: the real robot's base is 0.2, -0.1, 0.3 mm off, the
  // orientation the same, so the target moves by minus that offset
  const KrlText out = writeKrl(pc.program);
  EXPECT_NE(out.dat.find("DECL E6POS XP3={X 999.8000,Y 100.1000,Z 799.7000,A 0,B 90,C 0}"), std::string::npos) << out.dat;
  EXPECT_TRUE(pc.report.segments.empty() || pc.report.segments.front().motion.line != 6);  // its path not checked
}

TEST(KrlRules, APtpNextToAWristSingularityThatTurnsTheWristIsAWarning) {
  // the off-line program's joints: A5 0.1 deg from the wrist singularity; the real robot
  // reaches the pose only with A4 and A6 turned by degrees (they trade freely next to A5 = 0).
  // A second target with the wrist well bent: nothing to say.
  const StCell cell;
  const Eigen::VectorXd near = joints({0.3, -90, 95, 0.2, 0.1, -0.4}), bent = joints({10, -80, 100, 20, 45, 30});
  const calib::Configuration c_near = calib::kukaConfiguration(cell.controller, near), c_bent = calib::kukaConfiguration(cell.controller, bent);
  const std::string dir = test::tempDir("krl_posture");
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL = {X 20,Y 0,Z 250,A 0,B -30,C 0}\n$BASE = $NULLFRAME\n"
                                  "PTP {A1 0,A2 -90,A3 90,A4 0,A5 45,A6 0}\nPTP XP1\nPTP XP2\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1=" + aggregate(cell.target(near), c_near.status, c_near.turn) +
                                      "\nDECL E6POS XP2=" + aggregate(cell.target(bent), c_bent.status, c_bent.turn) + "\nENDDAT\n");
  JobSettings s;
  s.calibrated = cell.real;
  const ProgramCompensation pc = compensateProgramReport(readProgram(dir + "/p.src"), s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().message;
  // the expectation on its own: the real robot's joints for each pose on its S/T, against the
  // off-line joints
  const calib::KinematicSolver real(cell.real);
  auto change = [&](const Eigen::VectorXd& q, const calib::Configuration& c) {
    const calib::IkResult r = real.inverse(cell.target(q), c, q, calib::IkOptions{});
    EXPECT_EQ(r.status, calib::IkStatus::kOk) << r.message;
    return r.status == calib::IkStatus::kOk ? (r.q - q).cwiseAbs().maxCoeff() : 0.0;
  };
  EXPECT_GT(change(near, c_near), kPostureChangeDeg);
  EXPECT_LT(change(bent, c_bent), 1.0);
  std::vector<std::string> said;
  for (const auto& w : pc.report.warnings)
    if (w.message.find("another arm posture") != std::string::npos) said.push_back(w.message);
  ASSERT_EQ(said.size(), 1u);
  EXPECT_EQ(said[0].rfind("XP1: the compensated joints differ from the controller model's for this pose by up to ", 0), 0u) << said[0];
}

TEST(KrlRules, AnglesAreWrittenInTheFormTheProgramUses) {
  // (A, B, C) and (A + 180, 180 - B, C + 180) and any angle +- 360 are one rotation: the
  // written form is kept, so a correction that rounds to zero keeps the text
  Target t;
  t.setPose(calib::XyzAbc{1000.0, 0.0, 800.0, 0.0, 180.0, 0.0});
  EXPECT_FALSE(t.setPoseIfChanged(calib::XyzAbc{1000.0, 0.0, 800.0, 180.0, 0.0, -180.0}));
  EXPECT_EQ(*t.pose[4], 180.0);
  t.setPose(calib::XyzAbc{1000.0, 0.0, 800.0, 0.0, 0.0, -180.0});
  EXPECT_FALSE(t.setPoseIfChanged(calib::XyzAbc{1000.0, 0.0, 800.0, 0.0, 0.0, 180.0}));
  EXPECT_EQ(*t.pose[5], -180.0);
  // at B = +-90 only A - C (B = 90) or A + C (B = -90) is the rotation's: A 30, B 90, C 10 is
  // A 20, B 90, C 0, and A 30, B -90, C 10 is A 20, B -90, C 20
  t.setPose(calib::XyzAbc{1000.0, 0.0, 800.0, 30.0, 90.0, 10.0});
  EXPECT_FALSE(t.setPoseIfChanged(calib::XyzAbc{1000.0, 0.0, 800.0, 20.0, 90.0, 0.0}));
  EXPECT_EQ(*t.pose[3], 30.0);
  t.setPose(calib::XyzAbc{1000.0, 0.0, 800.0, 30.0, -90.0, 10.0});
  EXPECT_FALSE(t.setPoseIfChanged(calib::XyzAbc{1000.0, 0.0, 800.0, 20.0, -90.0, 20.0}));
  EXPECT_EQ(*t.pose[5], 10.0);
  // a real correction: the rotation it gives, in the angles nearest the written ones
  t.setPose(calib::XyzAbc{1000.0, 0.0, 800.0, 10.0, 170.0, 0.0});
  const Eigen::Matrix3d R = calib::toIsometry(calib::XyzAbc{0, 0, 0, 10.0, 170.0, 0.0}).linear() *
                            Eigen::AngleAxisd(0.01 * calib::kDegToRad, Eigen::Vector3d::UnitX()).toRotationMatrix();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  const calib::XyzAbc canonical = calib::toXyzAbc(T);
  EXPECT_GT(std::abs(canonical.b_deg - 170.0), 90.0);  // the library's own form is the other one
  EXPECT_TRUE(t.setPoseIfChanged(calib::XyzAbc{1000.0, 0.0, 800.0, canonical.a_deg, canonical.b_deg, canonical.c_deg}));
  EXPECT_NEAR(*t.pose[3], 10.0, 0.05);
  EXPECT_NEAR(*t.pose[4], 170.0, 0.05);
  EXPECT_NEAR(*t.pose[5], 0.0, 0.05);
  const Eigen::Matrix3d back = calib::toIsometry(t.xyzAbc()).linear();
  EXPECT_LT(calib::rotationAngleDeg(back * R.transpose()), 1e-9);
}

TEST(KrlRules, APointSharedByAPtpAndALinGetsThePtpsStatusAndTurn) {
  // PTP XP1, LIN XP2, LIN XP1 (approach, work, back): the PTP's correction moves A4 and A6
  // across 0, so its T changes; the LINs' S/T are not used by the controller, so the one
  // point serves both with the PTP's T (it used to be refused as two different corrections)
  const std::string dir = test::tempDir("krl_shared_ptp_lin");
  const std::string xp1 = "{X 1058.3862,Y -186.5680,Z 945.7945,A 169.93882,B 29.99997,C 179.95013,S 2,T 42}";
  test::writeText(dir + "/p.src",
                  "DEF p( )\n$TOOL = $NULLFRAME\n$BASE = $NULLFRAME\nPTP {A1 0,A2 -90,A3 90,A4 10,A5 45,A6 0}\n"
                  "PTP XP1\nLIN XP2\nLIN XP1\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1=" + xp1 +
                                      "\nDECL E6POS XP2={X 1171.1397,Y -206.4495,Z 915.1162,A 169.93882,B 29.99997,C 179.95013,S 2,T 42}\nENDDAT\n");
  // the same PTP alone: what XP1 must become
  test::writeText(dir + "/q.src", "DEF q( )\n$TOOL = $NULLFRAME\n$BASE = $NULLFRAME\nPTP {A1 0,A2 -90,A3 90,A4 10,A5 45,A6 0}\nPTP XP1\nEND\n");
  test::writeText(dir + "/q.dat", "DEFDAT q\nDECL E6POS XP1=" + xp1 + "\nENDDAT\n");
  JobSettings s;
  s.calibrated = calib::readRobotFile(test::sourcePath("tests/golden/compensate/kr16_real.xml"));
  const ProgramCompensation shared = compensateProgramReport(readProgram(dir + "/p.src"), s);
  ASSERT_TRUE(shared.ok()) << shared.report.errors.front().where.str() << ": " << shared.report.errors.front().message;
  const ProgramCompensation alone = compensateProgramReport(readProgram(dir + "/q.src"), s);
  ASSERT_TRUE(alone.ok());
  const KrlText a = writeKrl(shared.program), b = writeKrl(alone.program);
  const auto line = [](const std::string& text) {
    const size_t at = text.find("DECL E6POS XP1=");
    return text.substr(at, text.find('\n', at) - at);
  };
  EXPECT_EQ(line(a.dat), line(b.dat));
  EXPECT_EQ(line(a.dat).find("T 42}"), std::string::npos) << line(a.dat);  // the PTP's T, not the written one
}

// A point that is a motion's target and also a frame ($BASE = XFB): its correction written into
// its declaration would move the base, and every motion after it with it. The declaration keeps
// its value; the motion goes to a new point with the correction. Expected: XFB_1 is what XFB
// becomes in the same program without the frame statement, and XP1 (after it) is corrected as in
// a program that writes XFB's value as the base inline.
TEST(KrlRules, APointAlsoUsedAsAFrameKeepsItsValueAndTheMotionGetsANewPoint) {
  const std::string dir = test::tempDir("krl_point_as_frame");
  const std::string head = "DEF p( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XHOME\nLIN XFB\n";
  const std::string xfb = "{X 1000,Y 100,Z 600,A 0,B 90,C 0,S 2,T 2}";
  const std::string dat = "DEFDAT p\n  DECL E6POS XHOME={X 900,Y 0,Z 900,A 0,B 90,C 0,S 2,T 2}\n  DECL E6POS XFB=" + xfb +
                          "\n  DECL E6POS XP1={X 10,Y 20,Z 30,A 0,B 0,C 0,S 2,T 2}\nENDDAT\n";
  for (const char* d : {"/frame", "/alone", "/inline"}) std::filesystem::create_directories(dir + d);
  test::writeText(dir + "/frame/p.src", head + "$BASE=XFB\nLIN XP1\nEND\n");
  test::writeText(dir + "/alone/p.src", head + "END\n");
  test::writeText(dir + "/inline/p.src", head + "$BASE={X 1000,Y 100,Z 600,A 0,B 90,C 0}\nLIN XP1\nEND\n");
  for (const char* d : {"/frame", "/alone", "/inline"}) test::writeText(dir + d + "/p.dat", dat);
  JobSettings s;
  s.calibrated = calib::readRobotFile(test::sourcePath("tests/golden/compensate/kr16_real.xml"));
  std::map<std::string, KrlText> out;
  std::map<std::string, ProgramCompensation> pcs;
  for (const char* d : {"/frame", "/alone", "/inline"}) {
    pcs[d] = compensateProgramReport(readKrl(dir + d + "/p.src"), s);
    ASSERT_TRUE(pcs[d].ok()) << d << ": " << pcs[d].report.errors.front().message;
    out[d] = writeKrl(pcs[d].program);
  }
  const auto value = [](const std::string& text, const std::string& name) {
    const size_t at = text.find("DECL E6POS " + name + "=");
    if (at == std::string::npos) return std::string("(no ") + name + ")";
    const size_t b = text.find('=', at) + 1;
    return text.substr(b, text.find('\n', at) - b);
  };
  EXPECT_EQ(value(out["/frame"].dat, "XFB"), xfb);                                   // the frame keeps its value
  EXPECT_NE(value(out["/alone"].dat, "XFB"), xfb);                                   // (a correction there is)
  EXPECT_EQ(value(out["/frame"].dat, "XFB_1"), value(out["/alone"].dat, "XFB"));     // the motion's point
  EXPECT_NE(out["/frame"].dat.find("\n  DECL E6POS XFB_1="), std::string::npos);     // after XFB, indented like it
  EXPECT_LT(out["/frame"].dat.find("XFB="), out["/frame"].dat.find("XFB_1="));
  EXPECT_NE(out["/frame"].src.find("\nLIN XFB_1\n$BASE=XFB\n"), std::string::npos) << out["/frame"].src;
  EXPECT_EQ(value(out["/frame"].dat, "XP1"), value(out["/inline"].dat, "XP1"));
  EXPECT_NE(value(out["/frame"].dat, "XP1"), "{X 10,Y 20,Z 30,A 0,B 0,C 0,S 2,T 2}");
  bool said = false;
  for (const ProgramIssue& w : pcs["/frame"].report.warnings)
    said = said || (w.where.line == 5 && w.message.find("XFB is also read at " + dir + "/frame/p.src:6:7 ($BASE=XFB)") != std::string::npos &&
                    w.message.find("the new point XFB_1") != std::string::npos);
  EXPECT_TRUE(said);
  int reported = 0;  // the report names the point the motion goes to
  for (const TargetReport& tr : pcs["/frame"].report.targets) reported += tr.name == "XFB_1" && tr.new_point_replaces == "XFB";
  EXPECT_EQ(reported, 1);
  // a plain motion target, a CIRC's two points and a WITH clause's frame are told apart
  const std::string src = "DEF q( )\nLIN XP1 C_DIS\nCIRC XFB, XHOME\nSLIN XP1 WITH $BASE=XHOME\nEND\n";
  test::writeText(dir + "/q.src", src);
  test::writeText(dir + "/q.dat", "DEFDAT q\nDECL E6POS XHOME={X 1}\nDECL E6POS XFB={X 2}\nDECL E6POS XP1={X 3}\nENDDAT\n");
  const Program q = readKrl(dir + "/q.src");
  ASSERT_EQ(q.krl->values.size(), 3u);
  EXPECT_EQ(q.krl->values[0].read_elsewhere, dir + "/q.src:4:21 (SLIN XP1 WITH $BASE=XHOME)");
  EXPECT_EQ(q.krl->values[1].read_elsewhere, "");
  EXPECT_EQ(q.krl->values[2].read_elsewhere, "");
  // an array's element is read by its index (every element by a computed one); a subroutine's
  // parameter or own declaration of a point's name is not the data list's point
  test::writeText(dir + "/r.src", "DEF r( )\nLIN XPA[1]\nLIN XPA[2]\nLIN XP2\nIF XPA[1].X > 1 THEN\nENDIF\nEND\n"
                                  "DEF sub(XP2:IN)\nIF XP2.X > 0 THEN\nENDIF\nEND\nDEF sub2( )\nDECL E6POS XP3\nXP3 = {X 1}\nIF XP3.X > 0 THEN\nENDIF\nEND\n"
                                  "DEF sub3( )\nDECL INT I\nIF XPA[I].X > 0 THEN\nENDIF\nEND\n");
  test::writeText(dir + "/r.dat", "DEFDAT r\nDECL E6POS XPA[3]\nXPA[1]={X 1}\nXPA[2]={X 2}\nDECL E6POS XP2={X 3}\nDECL E6POS XP3={X 4}\nENDDAT\n");
  const Program r = readKrl(dir + "/r.src");
  ASSERT_EQ(r.krl->values.size(), 5u);  // (and sub2's assignment, in the .src)
  EXPECT_EQ(r.krl->values[0].read_elsewhere, dir + "/r.src:5:4 (IF XPA[1].X > 1 THEN)");   // XPA[1]
  EXPECT_EQ(r.krl->values[1].read_elsewhere, dir + "/r.src:20:4 (IF XPA[I].X > 0 THEN)");  // XPA[2], by XPA[I]
  EXPECT_EQ(r.krl->values[2].read_elsewhere, "");  // XP2: sub's parameter
  EXPECT_EQ(r.krl->values[3].read_elsewhere, "");  // XP3: sub2's own
}

// S and T written as bit strings ('B001010', as the inline forms and many OLP tools write them)
// are rewritten as bit strings when the correction changes them (T 'B001010' became T 34 next to
// an unchanged S 'B010'); decimal ones stay decimal. Expected: the same T as the decimal point's.
TEST(KrlRules, AChangedTurnKeepsTheFormItWasWrittenIn) {
  const std::string dir = test::tempDir("krl_turn_form");
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL = {X 20.0,Y 0.0,Z 250.0,A 0.0,B -30.0,C 0.0}\n$BASE = $NULLFRAME\n"
                                  "PTP {A1 0,A2 -90,A3 90,A4 0,A5 45,A6 0}\nPTP XP3\nPTP XP4\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\n"
                                  "DECL E6POS XP3={X 1058.3831,Y -186.5855,Z 945.7945,A 170.00540,B 30.00000,C 179.98985,S 'B010',T 'B001010'}\n"
                                  "DECL E6POS XP4={X 1058.3831,Y -186.5855,Z 945.7945,A 170.00540,B 30.00000,C 179.98985,S 2,T 10}\nENDDAT\n");
  JobSettings s;
  s.calibrated = calib::readRobotFile(test::sourcePath("tests/data/plugin/kr16_calibrated.xml"));
  const ProgramCompensation pc = compensateProgramReport(readKrl(dir + "/p.src"), s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().message;
  const std::string dat = writeKrl(pc.program).dat;
  const auto component = [&](const std::string& point, const std::string& name) {
    const size_t at = dat.find("," + name + " ", dat.find("DECL E6POS " + point + "=")) + 1;
    return dat.substr(at + name.size() + 1, dat.find_first_of(",}", at) - at - name.size() - 1);
  };
  ASSERT_NE(component("XP4", "T"), "10");  // the correction changes T (a joint crosses 0)
  int turn = 0;
  for (char c : component("XP3", "T").substr(2, 6)) turn = 2 * turn + (c - '0');
  EXPECT_EQ(turn, std::stoi(component("XP4", "T")));
  EXPECT_EQ(component("XP3", "T").size(), 9u) << component("XP3", "T");  // 'B' and six digits, quoted
  EXPECT_EQ(component("XP3", "S"), "'B010'");
  // batch prints a program's warnings as compensate does (it printed none: a T rewritten unseen)
  std::filesystem::create_directories(dir + "/in");
  for (const char* f : {"p.src", "p.dat"}) test::writeText(dir + "/in/" + f, test::readText(dir + "/" + f));
  const test::CliRun b = test::runAccuraIn(dir, "batch --robot " + test::sourcePath("tests/data/plugin/kr16_calibrated.xml") + " --in in --out out --jobs 1");
  ASSERT_EQ(b.code, 0) << b.err;
  EXPECT_NE(b.err.find("accura: warning: in/p.src:5:1: T of XP3 changed from 10 to "), std::string::npos) << b.err;
  EXPECT_NE(b.out.find(" warning(s), on stderr\n"), std::string::npos) << b.out;
}

// ---------------------------------------------------------------------------------------------
// External axes

// A target that moves an external axis (a track, a positioner) is a program the controller runs;
// the robot file models no external axes, so the motion is kept as written and named (it was
// refused), and the rest is compensated.
TEST(KrlRules, ATargetThatMovesAnExternalAxisIsKeptAndNamed) {
  const std::string dir = test::tempDir("krl_ext");
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XP1\nLIN XP2\nEND\n");
  const std::string xp2 = "DECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0,E1 0.0,E2 250.5}\n";
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0,E1 0.0}\n" + xp2 + "ENDDAT\n");
  const Program in = readKrl(dir + "/p.src");
  const JobSettings s = kr16BaseOff();
  const ProgramCompensation pc = compensateProgramReport(in, s);
  ASSERT_TRUE(pc.report.errors.empty()) << pc.report.errors.front().message;
  EXPECT_EQ(pc.report.motions_left_unchanged, 1);
  ASSERT_EQ(pc.report.warnings.size(), 1u);
  const ProgramIssue& w = pc.report.warnings.front();
  EXPECT_EQ(w.where.str(), dir + "/p.src:5:1");  // the LIN
  EXPECT_EQ(w.message,
            "LIN left unchanged (not compensated): XP2 moves external axes (E2 250.5000: a track or a positioner), which the robot "
            "file '" + s.calibrated.nominal.name + "' does not model; the position after it is not known");
  // the command line: exit 0, XP2 as written, XP1 corrected (by the base's 0.2, -0.1, 0.3 mm)
  test::writeText(dir + "/kr16.xml", test::readText(test::sourcePath("tests/golden/compensate/kr16_real.xml")));
  const test::CliRun r = test::runAccuraIn(dir, "compensate --robot kr16.xml --in p.src --out out");
  EXPECT_EQ(r.code, 0) << r.err;
  const std::string dat = test::readText(dir + "/out/p.dat");
  EXPECT_NE(dat.find(xp2), std::string::npos) << dat;
  EXPECT_EQ(dat.find("DECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0,E1 0.0}"), std::string::npos) << dat;
  EXPECT_NE(r.out.find("left unchanged"), std::string::npos) << r.out << r.err;
}

// An inline form whose FDAT has IPO_FRAME #TCP (an external TCP: the robot carries the part past
// a fixed tool) is a program the controller runs: that motion is kept as written and named (the
// program was refused), the others are compensated.
TEST(KrlRules, AMotionWithAnExternalTcpIsKeptAndNamed) {
  const std::string dir = test::tempDir("krl_ext_tcp");
  for (const char* f : {"seam.src", "$config.dat"}) test::writeText(dir + "/" + f, test::readText(test::sourcePath(std::string("examples/") + f)));
  std::string dat = test::readText(test::sourcePath("examples/seam.dat"));
  const std::string fp2 = "DECL FDAT FP2={TOOL_NO 1,BASE_NO 1,IPO_FRAME #";
  ASSERT_NE(dat.find(fp2 + "BASE"), std::string::npos);
  dat.replace(dat.find(fp2 + "BASE"), fp2.size() + 4, fp2 + "TCP");
  test::writeText(dir + "/seam.dat", dat);
  test::writeText(dir + "/kr16.xml", test::readText(test::sourcePath("tests/golden/compensate/kr16_real.xml")));
  const test::CliRun r = test::runAccuraIn(dir, "compensate --robot kr16.xml --in seam.src --config '$config.dat' --out out");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("seam.src:42:1: LIN left unchanged (not compensated): an external TCP (IPO_FRAME #TCP: the robot carries the part "
                       "past a fixed tool), which accura does not model; the position after it is not known"),
            std::string::npos)
      << r.err;
  const std::string out = test::readText(dir + "/out/seam.dat");
  const std::string xp2 = "DECL E6POS XP2={X 100.0,Y 0.0,Z 20.0,A 160.0,B 10.0,C 170.0,S 2,T 10,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}";
  ASSERT_NE(dat.find(xp2), std::string::npos);
  EXPECT_NE(out.find(xp2), std::string::npos) << out;  // the LIN's point as written
  EXPECT_EQ(out.find("DECL E6POS XP3={X 100.0,Y 500.0,Z 20.0,"), std::string::npos) << out;  // the next one corrected
}

// One point two motions need corrected differently (XP1 with a 100 mm tool, then with a 200 mm
// one) is a program the controller runs: the second motion goes to a new point of its own (it
// was refused: "give the motions their own points"). The new point's pose is the correction of
// XP1 for the 200 mm tool that a program of that motion alone gets.
TEST(KrlRules, APointTwoMotionsNeedCorrectedDifferentlyGetsAPointOfItsOwn) {
  const std::string dir = test::tempDir("krl_own_point");
  const std::string pose = "X 1000,Y 300,Z 700,A 20,B 60,C 10";
  test::writeText(dir + "/kr16.xml", test::readText(test::sourcePath("tests/golden/compensate/kr16_real.xml")));
  std::filesystem::create_directories(dir + "/both");
  std::filesystem::create_directories(dir + "/alone");
  const std::string src = "DEF p( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XP1\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\nLIN XP1\nEND\n";
  test::writeText(dir + "/both/p.src", src);
  test::writeText(dir + "/both/p.dat", "DEFDAT p\nDECL E6POS XP1={" + pose + ",S 6,T 59}\nENDDAT\n");
  test::writeText(dir + "/alone/p.src", "DEF p( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XP1\nEND\n");
  test::writeText(dir + "/alone/p.dat", "DEFDAT p\nDECL E6POS XP1={" + pose + ",S 6,T 51}\nENDDAT\n");
  const test::CliRun both = test::runAccuraIn(dir, "compensate --robot kr16.xml --in both/p.src --out both/out");
  ASSERT_EQ(both.code, 0) << both.err;
  EXPECT_NE(both.err.find("both/p.src:6:1: XP1 needs a different correction here than at both/p.src:4:1 (the same point with another "
                          "tool, base or path): this motion goes to a new point XP1_1 declared after XP1, which keeps the correction for "
                          "both/p.src:4:1"),
            std::string::npos)
      << both.err;
  const test::CliRun alone = test::runAccuraIn(dir, "compensate --robot kr16.xml --in alone/p.src --out alone/out");
  ASSERT_EQ(alone.code, 0) << alone.err;
  // the pose part of a corrected declaration (up to its S)
  const auto corrected = [](const std::string& dat, const std::string& name) {
    const size_t b = dat.find("DECL E6POS " + name + "={");
    return b == std::string::npos ? std::string("none") : dat.substr(b + 13 + name.size(), dat.find(",S ", b) - b - 13 - name.size());
  };
  const std::string out = test::readText(dir + "/both/out/p.dat"), ref = test::readText(dir + "/alone/out/p.dat");
  ASSERT_NE(corrected(ref, "XP1"), pose);  // (a correction)
  EXPECT_EQ(corrected(out, "XP1_1"), corrected(ref, "XP1")) << out << ref;
  EXPECT_NE(corrected(out, "XP1"), corrected(out, "XP1_1")) << out;
  EXPECT_NE(out.find("DECL E6POS XP1_1={" + corrected(ref, "XP1") + ",S 6,T 59}\n"), std::string::npos) << out;  // (a CP target's S/T as written)
  EXPECT_EQ(test::readText(dir + "/both/out/p.src"), "DEF p( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XP1\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\nLIN XP1_1\nEND\n");
}

// The same with an element of a point array (XPA[1]): the new point was named `XPA[1]_1`,
// declared `DECL E6POS XPA[1]_1=..` and moved to by `LIN XPA[1]_1`, which the controller does
// not load (a name is letters, digits, '_' and '$'). An element has no name to derive a new
// one from: the motion gets the correction as an inline aggregate, as a split CIRC's point of
// an array does. Expected: the pose the program of that motion alone writes for XP1.
TEST(KrlRules, AnArrayElementTwoMotionsNeedCorrectedDifferentlyGivesTheSecondAnInlineAggregate) {
  const std::string dir = test::tempDir("krl_own_element");
  const std::string pose = "X 1000,Y 300,Z 700,A 20,B 60,C 10";
  JobSettings s;
  s.calibrated = calib::readRobotFile(test::sourcePath("tests/golden/compensate/kr16_real.xml"));
  std::filesystem::create_directories(dir + "/both");
  std::filesystem::create_directories(dir + "/alone");
  test::writeText(dir + "/both/p.src", "DEF p( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XPA[1]\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\nLIN XPA[1]\nEND\n");
  test::writeText(dir + "/both/p.dat", "DEFDAT p\nDECL E6POS XPA[2]\nXPA[1]={" + pose + ",S 6,T 59}\nENDDAT\n");
  test::writeText(dir + "/alone/p.src", "DEF p( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XP1\nEND\n");
  test::writeText(dir + "/alone/p.dat", "DEFDAT p\nDECL E6POS XP1={" + pose + ",S 6,T 51}\nENDDAT\n");
  const ProgramCompensation both = compensateProgramReport(readKrl(dir + "/both/p.src"), s);
  const ProgramCompensation alone = compensateProgramReport(readKrl(dir + "/alone/p.src"), s);
  ASSERT_TRUE(both.ok() && alone.ok());
  bool said = false;
  for (const auto& w : both.report.warnings)
    said = said || (w.where.line == 6 && w.message == "XPA[1] needs a different correction here than at " + dir +
                                                           "/both/p.src:4:1 (the same point with another tool, base or path): this motion gets its "
                                                           "corrected value as an inline aggregate (XPA[1] has no name of its own to derive a new "
                                                           "point's from); XPA[1] keeps the correction for " + dir + "/both/p.src:4:1");
  EXPECT_TRUE(said);
  const std::string ref = test::lf(writeKrl(alone.program)).dat;
  const size_t b = ref.find("DECL E6POS XP1={");
  ASSERT_NE(b, std::string::npos);
  const std::string corrected = ref.substr(b + 16, ref.find(",S ", b) - b - 16);
  ASSERT_NE(corrected, pose);  // (a correction)
  const KrlText out = test::lf(writeKrl(both.program));
  EXPECT_EQ(out.src.substr(0, out.src.find("LIN ")), "DEF p( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XPA[1]\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n");
  EXPECT_EQ(out.src.find("XPA[1]_1"), std::string::npos) << out.src;
  EXPECT_EQ(out.dat.find("XPA[1]_1"), std::string::npos) << out.dat;
  EXPECT_NE(out.src.find("LIN {" + corrected + ","), std::string::npos) << out.src << ref;
}

// ---------------------------------------------------------------------------------------------
// Targets known only at run time

// A CIRC with CA (circular angle) ends elsewhere than its written target: the controller runs
// it, so it is kept as written and named, not refused; the motion after it starts afresh.
TEST(KrlRules, ACircWithACircularAngleIsKeptAndNamed) {
  const std::string dir = test::tempDir("krl_circ_ca");
  test::writeText(dir + "/p.src",
                  "DEF p( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XP1\nCIRC XP2, XP3, CA 90.0\nLIN XP1\nEND\n");
  test::writeText(dir + "/p.dat",
                  "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2={X 1050,Y 50,Z 800,A 0,B 90,C 0}\n"
                  "DECL E6POS XP3={X 1000,Y 100,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  const JobSettings s = kr16BaseOff();
  const ProgramCompensation pc = compensateProgramReport(readKrl(dir + "/p.src"), s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().where.str() << ": " << pc.report.errors.front().message;
  EXPECT_EQ(pc.report.motions_left_unchanged, 1);
  bool named = false;
  for (const ProgramIssue& w : pc.report.warnings)
    named = named || (w.where.line == 5 && w.message.find("CIRC left unchanged (not compensated): a CIRC with CA 90") != std::string::npos);
  EXPECT_TRUE(named);
  const KrlText out = writeKrl(pc.program);
  EXPECT_NE(out.src.find("\nCIRC XP2, XP3, CA 90.0\n"), std::string::npos) << out.src;
  EXPECT_NE(out.dat.find("DECL E6POS XP2={X 1050,Y 50,Z 800,A 0,B 90,C 0}"), std::string::npos) << out.dat;
  EXPECT_EQ(out.dat.find("DECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}"), std::string::npos) << out.dat;  // corrected
}

// A LIN_REL in an IF, then a partial LIN (its other components are wherever the robot is), and
// a point the program changes: the controller runs this program, so it is not refused. Those
// motions keep their text and are named in warnings; every other target is compensated.
TEST(KrlRules, MotionsToRunTimeTargetsAreKeptAndNamedTheRestIsCompensated) {
  const std::string dir = test::tempDir("krl_runtime");
  test::writeText(dir + "/p.src",
                  "DEF p( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XP1\nIF $IN[3] THEN\n  LIN_REL {X 1.0} C_DIS\nENDIF\n"
                  "LIN {Z 900}\nXP3 = XP2\nXP3.X = $POS_ACT.X\nLIN XP3\nLIN XP2\nEND\n");
  test::writeText(dir + "/p.dat",
                  "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\n"
                  "DECL E6POS XP3={X 1000,Y 100,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  const Program in = readKrl(dir + "/p.src");
  const JobSettings s = kr16BaseOff();
  const ProgramCompensation pc = compensateProgramReport(in, s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().where.str() << ": " << pc.report.errors.front().message;
  EXPECT_EQ(pc.report.motions_left_unchanged, 3);
  std::vector<std::string> unchanged;
  for (const ProgramIssue& w : pc.report.warnings)
    if (w.message.find("left unchanged (not compensated)") != std::string::npos) unchanged.push_back(std::to_string(w.where.line));
  EXPECT_EQ(unchanged, (std::vector<std::string>{"6", "8", "11"}));
  // XP1 and XP2 are corrected; the LIN_REL, the partial LIN and XP3 keep their text
  const KrlText out = writeKrl(pc.program);
  EXPECT_NE(out.src.find("\n  LIN_REL {X 1.0} C_DIS\n"), std::string::npos) << out.src;
  EXPECT_NE(out.src.find("\nLIN {Z 900}\n"), std::string::npos) << out.src;
  EXPECT_NE(out.dat.find("DECL E6POS XP3={X 1000,Y 100,Z 800,A 0,B 90,C 0}"), std::string::npos) << out.dat;
  EXPECT_EQ(out.dat.find("DECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}"), std::string::npos) << out.dat;
  // XP3 = XP2 reads XP2: corrected in place, XP2 would move XP3's motion, which is left as
  // written; XP2 keeps its value, and its own motion goes to the corrected copy XP2_1
  EXPECT_NE(out.dat.find("DECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2_1={"), std::string::npos) << out.dat;
  EXPECT_NE(out.src.find("\nLIN XP3\nLIN XP2_1\nEND"), std::string::npos) << out.src;
}

// A subroutine's parameter (DEF weld(XP2:IN) with DECL E6POS XP2) and a point it declares
// without a value hide the data list's points of their names: the motion goes where the call
// (or the run) says. Before, `LIN XP2` in weld corrected the data list's XP2 in place, a point
// the motion does not use, and counted the motion as compensated.
TEST(KrlRules, ASubroutinesParameterHidesTheDataListsPointOfItsName) {
  const std::string dir = test::tempDir("krl_param");
  const std::string src =
      "DEF p( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XP1\nweld(XP3)\nEND\n\n"
      "DEF weld(XP2:IN)\nDECL E6POS XP2\nDECL E6POS XP3\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nLIN XP2\nLIN XP3\nEND\n";
  const std::string dat =
      "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\n"
      "DECL E6POS XP3={X 1000,Y 200,Z 800,A 0,B 90,C 0}\nENDDAT\n";
  test::writeText(dir + "/p.src", src);
  test::writeText(dir + "/p.dat", dat);
  const JobSettings s = kr16BaseOff();
  const ProgramCompensation pc = compensateProgramReport(readKrl(dir + "/p.src"), s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().where.str() << ": " << pc.report.errors.front().message;
  std::vector<std::string> unchanged;
  for (const ProgramIssue& w : pc.report.warnings)
    if (w.message.find("left unchanged (not compensated)") != std::string::npos) unchanged.push_back(w.where.str() + ": " + w.message);
  const std::string at = dir + "/p.src:";
  EXPECT_EQ(unchanged, (std::vector<std::string>{
                           at + "13:1: LIN left unchanged (not compensated): XP2 is a parameter of weld: its value comes from the call; "
                                "the position after it is not known",
                           at + "14:1: LIN left unchanged (not compensated): XP3 is declared in weld without a value (" + at +
                               "10:12): the routine's own, not the data list's point; the position after it is not known"}));
  // XP2 and XP3 of the data list keep their text; only XP1 (the main program's PTP) is corrected
  const KrlText out = writeKrl(pc.program);
  EXPECT_EQ(out.src, src);
  EXPECT_EQ(out.dat, "DEFDAT p\nDECL E6POS XP1={X 999.8000,Y 0.1000,Z 799.7000,A 0,B 90,C 0}\n"
                     "DECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\nDECL E6POS XP3={X 1000,Y 200,Z 800,A 0,B 90,C 0}\nENDDAT\n");
}

// An element of a two-dimensional point array with constant indices (XPA[1,2]) is kept and
// named for what it is; the warning said its index was "computed at run time".
TEST(KrlRules, AnElementOfATwoDimensionalArrayIsKeptAndNamedForWhatItIs) {
  const std::string dir = test::tempDir("krl_array2");
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XPA[1,2]\nEND\n");
  const std::string dat = "DEFDAT p\nDECL E6POS XPA[2,2]\nXPA[1,2]={X 1000,Y 0,Z 800,A 0,B 90,C 0,S 2,T 10}\nENDDAT\n";
  test::writeText(dir + "/p.dat", dat);
  const JobSettings s = kr16BaseOff();
  const ProgramCompensation pc = compensateProgramReport(readKrl(dir + "/p.src"), s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().where.str() << ": " << pc.report.errors.front().message;
  ASSERT_EQ(pc.report.warnings.size(), 1u);
  EXPECT_EQ(pc.report.warnings[0].message,
            "PTP left unchanged (not compensated): the target 'XPA[1,2]' is an element of the multi-dimensional array XPA, which accura "
            "does not read (it corrects the elements of one-dimensional point arrays); the position after it is not known");
  EXPECT_EQ(writeKrl(pc.program).dat, dat);
}

// A spline block whose frames come from its WITH clause (SPLINE WITH $TOOL = STOOL2(FP1),
// $BASE = SBASE(FP1.BASE_NO)) is compensated as the same block after $TOOL = TOOL_DATA[2],
// $BASE = BASE_DATA[2] statements: the same corrected points, to the byte. (It was refused:
// "the tool of this motion is not known".)
TEST(KrlRules, ASplineBlockWithItsFramesInTheWithClauseIsCompensatedLikeOneAfterFrameStatements) {
  const std::string dir = test::tempDir("krl_spline_block");
  const std::string config = dir + "/$config.dat";
  test::writeText(config,
                  "DEFDAT $CONFIG\nDECL GLOBAL FRAME TOOL_DATA[16]\nTOOL_DATA[2]={X 0.0,Y 0.0,Z 200.0,A 0.0,B 90.0,C 0.0}\n"
                  "DECL GLOBAL FRAME BASE_DATA[32]\nBASE_DATA[2]={X 900.0,Y -300.0,Z 200.0,A 30.0,B 0.0,C 0.0}\nENDDAT\n");
  const std::string dat =
      "DEFDAT p\nDECL FDAT FP1={TOOL_NO 2,BASE_NO 2,IPO_FRAME #BASE,POINT2[] \" \"}\n"
      "DECL E6POS XP1={X 273.087,Y -127.407,Z 618.527,A 125.327,B -47.537,C -111.572,S 2,T 2}\n"
      "DECL E6POS XP2={X 135.598,Y -264.075,Z 477.826,A 115.342,B -63.826,C -129.097,S 2,T 2}\n"
      "DECL E6POS XP3={X 93.096,Y -259.890,Z 509.745,A 136.186,B -59.107,C -177.850,S 2,T 10}\nENDDAT\n";
  const std::string block = "  SPL XP1\n  SPL XP2\n  SLIN XP3\nENDSPLINE\nEND\n";
  std::filesystem::create_directories(dir + "/with");
  std::filesystem::create_directories(dir + "/frames");
  test::writeText(dir + "/with/p.src", "DEF p( )\nPTP {A1 10,A2 -80,A3 100,A4 20,A5 30,A6 40}\n"
                                       "SPLINE WITH $VEL.CP = 0.2, $TOOL = STOOL2(FP1), $BASE = SBASE(FP1.BASE_NO)\n" + block);
  test::writeText(dir + "/frames/p.src", "DEF p( )\nPTP {A1 10,A2 -80,A3 100,A4 20,A5 30,A6 40}\n"
                                         "$TOOL = TOOL_DATA[2]\n$BASE = BASE_DATA[2]\n$VEL.CP = 0.2\nSPLINE\n" + block);
  test::writeText(dir + "/with/p.dat", dat);
  test::writeText(dir + "/frames/p.dat", dat);
  const StCell cell;
  JobSettings s;
  s.calibrated = cell.real;
  s.tol_mm = 0.05;
  KrlReadOptions o;
  o.config_path = config;
  std::string written[2];
  int k = 0;
  for (const char* which : {"with", "frames"}) {
    const ProgramCompensation pc = compensateProgramReport(readKrl(dir + "/" + which + "/p.src", o), s);
    ASSERT_TRUE(pc.ok()) << which << ": " << pc.report.errors.front().where.str() << ": " << pc.report.errors.front().message;
    EXPECT_EQ(pc.report.targets.size(), 3u) << which;
    written[k++] = writeKrl(pc.program).dat;
  }
  EXPECT_NE(written[0], dat);  // corrected
  EXPECT_EQ(written[0], written[1]);
}

// A point of an array in the .dat (XPA[1]={X ..}) is corrected like a named point, in place:
// its aggregate gets the numbers a scalar point with the same value gets (XQ1 in a twin
// program), every other byte of the .dat stays. XPA[I] (an index computed at run time) is
// kept and named. (XPA[1] was "computed at run time", not compensated.)
TEST(KrlRules, AnArrayPointOfTheDataListIsCorrectedInPlaceLikeANamedPoint) {
  const std::string dir = test::tempDir("krl_array_point");
  const std::string head = "DEF p( )\nDECL INT I\n$TOOL = {X 0,Y 0,Z 200,A 0,B 90,C 0}\n$BASE = {X 900,Y -300,Z 200,A 30,B 0,C 0}\n"
                           "PTP {A1 10,A2 -80,A3 100,A4 20,A5 30,A6 40}\n";
  const std::string p1 = "{X 135.598,Y -264.075,Z 477.826,A 115.342,B -63.826,C -129.097,S 2,T 2,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}";
  const std::string p2 = "{X 93.096,Y -259.890,Z 509.745,A 136.186,B -59.107,C -177.850,S 2,T 10,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}";
  const std::string dat = "DEFDAT p\nDECL E6POS XPA[2] ; the pick points\nXPA[1]=" + p1 + "\nXPA[2]=" + p2 + "\nENDDAT\n";
  std::filesystem::create_directories(dir + "/array");
  std::filesystem::create_directories(dir + "/scalar");
  test::writeText(dir + "/array/p.src", head + "PTP XPA[1]\nLIN XPA[2]\nLIN XPA[I]\nEND\n");
  test::writeText(dir + "/array/p.dat", dat);
  test::writeText(dir + "/scalar/p.src", head + "PTP XQ1\nLIN XQ2\nEND\n");
  test::writeText(dir + "/scalar/p.dat", "DEFDAT p\nDECL E6POS XQ1=" + p1 + "\nDECL E6POS XQ2=" + p2 + "\nENDDAT\n");
  JobSettings s;
  s.calibrated = StCell().real;
  s.tol_mm = 10;  // no auxiliary points: the twin programs' LIN ends alike
  const ProgramCompensation array = compensateProgramReport(readKrl(dir + "/array/p.src"), s);
  ASSERT_TRUE(array.ok()) << array.report.errors.front().message;
  const ProgramCompensation scalar = compensateProgramReport(readKrl(dir + "/scalar/p.src"), s);
  ASSERT_TRUE(scalar.ok()) << scalar.report.errors.front().message;
  const std::string scalar_dat = writeKrl(scalar.program).dat;
  const auto value = [&](const std::string& name) {  // the aggregate written for a point of the twin
    const size_t at = scalar_dat.find("DECL E6POS " + name + "=");
    EXPECT_NE(at, std::string::npos) << scalar_dat;
    const size_t b = scalar_dat.find('{', at);
    return scalar_dat.substr(b, scalar_dat.find('}', b) + 1 - b);
  };
  EXPECT_NE(value("XQ1"), p1);
  EXPECT_NE(value("XQ2"), p2);
  const KrlText out = writeKrl(array.program);
  EXPECT_EQ(out.dat, "DEFDAT p\nDECL E6POS XPA[2] ; the pick points\nXPA[1]=" + value("XQ1") + "\nXPA[2]=" + value("XQ2") + "\nENDDAT\n");
  EXPECT_EQ(out.src, test::readText(dir + "/array/p.src"));
  ASSERT_EQ(array.report.targets.size(), 2u);
  EXPECT_EQ(array.report.targets[0].name, "XPA[1]");
  EXPECT_EQ(array.report.motions_left_unchanged, 1);
  int kept = 0;
  for (const ProgramIssue& w : array.report.warnings)
    if (w.message.find("XPA[I]") != std::string::npos) {
      ++kept;
      EXPECT_EQ(w.where.line, 8);
      EXPECT_NE(w.message.find("left unchanged (not compensated): the target 'XPA[I]' is an element of the array XPA whose index is computed at run time"),
                std::string::npos) << w.message;
    }
  EXPECT_EQ(kept, 1);
}

// A motion to an element of a point array chosen at run time (LIN XPA[I] in a loop, as a milling
// job of a public KSS backup runs its work points) is kept as written, but it goes to the element
// the index names, which another motion (LIN XPA[2]) corrects in place: on the robot it moves with
// that correction. It was not said (the loop's motion was "left unchanged", silently not so); a
// warning at it now names the corrected elements, as for a kept motion whose named point another
// motion corrects (docs/program-formats.md).
TEST(KrlRules, AMotionToAnArrayElementChosenAtRunTimeSaysWhichElementsAreCorrected) {
  const std::string dir = test::tempDir("krl_array_run_time");
  const std::string p1 = "{X 135.598,Y -264.075,Z 477.826,A 115.342,B -63.826,C -129.097,S 2,T 2,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}";
  const std::string p2 = "{X 93.096,Y -259.890,Z 509.745,A 136.186,B -59.107,C -177.850,S 2,T 10,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}";
  test::writeText(dir + "/p.src", "DEF p( )\nDECL INT I\n$TOOL = {X 0,Y 0,Z 200,A 0,B 90,C 0}\n$BASE = {X 900,Y -300,Z 200,A 30,B 0,C 0}\n"
                                  "PTP {A1 10,A2 -80,A3 100,A4 20,A5 30,A6 40}\nFOR I = 1 TO 2\n  LIN XPA[I] C_VEL\nENDFOR\n"
                                  "LIN XPA[2]\nPTP XPA[1]\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XPA[3]\nXPA[1]=" + p1 + "\nXPA[2]=" + p2 + "\nXPA[3]=" + p1 + "\nENDDAT\n");
  JobSettings s;
  s.calibrated = StCell().real;
  s.tol_mm = 10;
  const ProgramCompensation pc = compensateProgramReport(readKrl(dir + "/p.src"), s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().message;
  const std::string dat = writeKrl(pc.program).dat;
  EXPECT_EQ(dat.find("XPA[1]=" + p1), std::string::npos) << dat;  // both corrected in place (what the warning says)
  EXPECT_EQ(dat.find("XPA[2]=" + p2), std::string::npos) << dat;
  EXPECT_NE(dat.find("XPA[3]=" + p1), std::string::npos) << dat;  // no motion names it: as written
  std::vector<std::string> said;
  for (const ProgramIssue& w : pc.report.warnings)
    if (w.message.find("chosen at run time, and") != std::string::npos) said.push_back(w.where.str() + " " + w.message);
  ASSERT_EQ(said.size(), 1u);
  EXPECT_EQ(said[0], dir + "/p.src:7:3 this motion is left as written, but the element of the array it goes to is chosen at run time, and XPA[2] "
                     "(corrected for the motion at " + dir + "/p.src:9:1) and 1 more element(s) are corrected: where the index names a corrected "
                     "element, the motion moves with that correction, made for that motion's tool, base and path (give the motions their own "
                     "points to keep this one as written)");
}

// A point declared GLOBAL (DECL GLOBAL E6POS XG1 in a PUBLIC data list) is the value other
// modules go to as well: corrected for this program's tool and base, it moves them too. A
// warning at its declaration says so; a point of the program's own (XP2) gets none.
TEST(KrlRules, ACorrectedGlobalPointIsNamedAtItsDeclaration) {
  const std::string dir = test::tempDir("krl_global_point");
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL = {X 0,Y 0,Z 200,A 0,B 90,C 0}\n$BASE = {X 900,Y -300,Z 200,A 30,B 0,C 0}\n"
                                  "PTP {A1 10,A2 -80,A3 100,A4 20,A5 30,A6 40}\nPTP XP2\nLIN XG1\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p PUBLIC\n"
                                  "DECL E6POS XP2={X 273.087,Y -127.407,Z 618.527,A 125.327,B -47.537,C -111.572,S 2,T 2}\n"
                                  "DECL GLOBAL E6POS XG1={X 135.598,Y -264.075,Z 477.826,A 115.342,B -63.826,C -129.097,S 2,T 2}\nENDDAT\n");
  JobSettings s;
  s.calibrated = StCell().real;
  const ProgramCompensation pc = compensateProgramReport(readKrl(dir + "/p.src"), s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().message;
  std::vector<std::string> global;
  for (const ProgramIssue& w : pc.report.warnings)
    if (w.message.find("GLOBAL") != std::string::npos) global.push_back(w.where.str() + ": " + w.message);
  EXPECT_EQ(global, std::vector<std::string>{dir + "/p.dat:3:23: GLOBAL point XG1 corrected for this program's tool and base (the motion at " +
                                             dir + "/p.src:6:1): other modules that use it move with this correction"});
}

// A PTP to a Cartesian point declared in the $config.dat (XPICK), which accura never rewrites:
// the motion gets the corrected value as an inline aggregate (the numbers a twin program with
// XPICK in its own .dat gets in its declaration), with a warning; the $config.dat and the .dat
// stay. (It was a refusal: "cannot write the corrected value of XPICK".)
TEST(KrlRules, AMotionToACartesianPointOfTheConfigGetsItsCorrectedValueInline) {
  const std::string dir = test::tempDir("krl_config_point");
  const std::string xpick = "{X 135.598,Y -264.075,Z 477.826,A 115.342,B -63.826,C -129.097,S 2,T 2,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}";
  const std::string frames = "DEFDAT $CONFIG\nDECL GLOBAL FRAME TOOL_DATA[16]\nTOOL_DATA[2]={X 0.0,Y 0.0,Z 200.0,A 0.0,B 90.0,C 0.0}\n"
                             "DECL GLOBAL FRAME BASE_DATA[32]\nBASE_DATA[2]={X 900.0,Y -300.0,Z 200.0,A 30.0,B 0.0,C 0.0}\n"
                             "DECL GLOBAL E6AXIS XHOME={A1 0.0,A2 -90.0,A3 90.0,A4 0.0,A5 45.0,A6 0.0}\n";
  const std::string src = "DEF p( )\nBAS (#INITMOV,0 )\nBAS (#TOOL,2)\nBAS (#BASE,2)\nPTP XHOME\nPTP XPICK\nEND\n";
  std::filesystem::create_directories(dir + "/config");
  std::filesystem::create_directories(dir + "/twin");
  test::writeText(dir + "/config/$config.dat", frames + "DECL GLOBAL E6POS XPICK=" + xpick + "\nENDDAT\n");
  test::writeText(dir + "/config/p.src", src);
  test::writeText(dir + "/config/p.dat", "DEFDAT p\nENDDAT\n");
  test::writeText(dir + "/twin/$config.dat", frames + "ENDDAT\n");
  test::writeText(dir + "/twin/p.src", src);
  test::writeText(dir + "/twin/p.dat", "DEFDAT p\nDECL E6POS XPICK=" + xpick + "\nENDDAT\n");
  JobSettings s;
  s.calibrated = StCell().real;
  Program written[2];
  std::string text[2];
  int k = 0;
  for (const char* which : {"config", "twin"}) {
    KrlReadOptions o;
    o.config_path = dir + "/" + which + "/$config.dat";
    const ProgramCompensation pc = compensateProgramReport(readKrl(dir + "/" + which + "/p.src", o), s);
    ASSERT_TRUE(pc.ok()) << which << ": " << pc.report.errors.front().message;
    const KrlText out = writeKrl(pc.program);
    const std::string back = dir + "/" + which + "/out";
    std::filesystem::create_directories(back);
    test::writeText(back + "/p.src", out.src);
    test::writeText(back + "/p.dat", out.dat);
    written[k] = readKrl(back + "/p.src", o);
    text[k] = out.src;
    if (k == 0) {
      EXPECT_EQ(out.dat, "DEFDAT p\nENDDAT\n");
      int inline_warnings = 0;
      for (const ProgramIssue& w : pc.report.warnings)
        if (w.message.find("XPICK is declared in " + dir + "/config/$config.dat:7:25, which accura does not rewrite: this motion gets "
                           "its corrected value as an inline aggregate") == 0) {
          ++inline_warnings;
          EXPECT_EQ(w.where.line, 6);
        }
      EXPECT_EQ(inline_warnings, 1);
    }
    ++k;
  }
  // the statement holds the value the twin declares: the same numbers and S/T
  ASSERT_EQ(written[0].motions.size(), 2u);
  const Target& inl = written[0].motions[1].target;
  const Target& twin = written[1].motions[1].target;
  EXPECT_TRUE(inl.name.empty());
  EXPECT_EQ(twin.name, "XPICK");
  EXPECT_NE(*twin.pose[0], 135.598);  // corrected
  for (int c = 0; c < 6; ++c) EXPECT_EQ(*inl.pose[c], *twin.pose[c]) << c;
  EXPECT_EQ(*inl.status, *twin.status);
  EXPECT_EQ(*inl.turn, *twin.turn);
  // only that statement changed
  const size_t at = text[0].find("PTP {X ");
  ASSERT_NE(at, std::string::npos) << text[0];
  EXPECT_EQ(text[0].substr(0, at) + "PTP XPICK" + text[0].substr(text[0].find('\n', at)), src);
}

// ---------------------------------------------------------------------------------------------
// Named points keep their meaning

TEST(KrlRules, ASplitCircGetsANewAuxiliaryPointTheDeclaredOneKeepsItsValue) {
  const std::string g = test::sourcePath("tests/golden/compensate/");
  KrlReadOptions o;
  o.config_path = g + "$config.dat";
  const Program in = readKrl(g + "seam.src", o);
  JobSettings s;
  s.calibrated = calib::readRobotFile(g + "kr16_real.xml");
  s.tol_mm = 0.02;
  const ProgramCompensation pc = compensateProgramReport(in, s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().message;
  const Motion* circ_in = nullptr;
  for (const Motion& m : in.motions)
    if (m.type == MotionType::kCirc) circ_in = &m;
  ASSERT_NE(circ_in, nullptr);
  const std::string aux = circ_in->aux->name, end = circ_in->target.name;  // XP5, XP6
  ASSERT_FALSE(aux.empty());
  const KrlText out = writeKrl(pc.program);
  const std::string dat = test::readText(g + "seam.dat");
  // the auxiliary point's declaration is untouched; the new point follows it; the CIRC names it
  const size_t decl = dat.find("DECL E6POS " + aux + "=");
  ASSERT_NE(decl, std::string::npos);
  const std::string aux_line = dat.substr(decl, dat.find('\n', decl) + 1 - decl);
  const size_t at = out.dat.find(aux_line);
  ASSERT_NE(at, std::string::npos) << aux << " changed:\n" << out.dat;
  const std::string new_decl = "DECL E6POS " + aux + "_1={";
  EXPECT_EQ(out.dat.compare(at + aux_line.size(), new_decl.size(), new_decl), 0) << out.dat.substr(at, 400);
  EXPECT_NE(out.src.find("CIRC " + aux + "_1, " + end), std::string::npos);
  EXPECT_EQ(out.src.find("CIRC " + aux + ", " + end), std::string::npos);
  // only the new line differs in the .dat besides corrected values: one line more
  EXPECT_EQ(std::count(out.dat.begin(), out.dat.end(), '\n'), std::count(dat.begin(), dat.end(), '\n') + 1);
  // the report lists the new declaration
  int new_points = 0;
  for (const TargetReport& t : pc.report.targets)
    if (!t.new_point_replaces.empty()) {
      ++new_points;
      EXPECT_EQ(t.name, aux + "_1");
      EXPECT_EQ(t.new_point_replaces, aux);
      EXPECT_EQ(t.role, "aux");
      EXPECT_LT(t.correction_mm, 5.0);  // mm: a compensated point of the arc
    }
  EXPECT_EQ(new_points, 1);
  // read back: the new point is the last sub-arc's auxiliary point, the old one as it was
  const std::string dir = test::tempDir("krl_split");
  test::writeText(dir + "/seam.src", out.src);
  test::writeText(dir + "/seam.dat", out.dat);
  const Program back = readKrl(dir + "/seam.src", o);
  const Motion* circ = nullptr;
  for (const Motion& m : back.motions)
    if (m.type == MotionType::kCirc && m.aux && !m.aux->name.empty()) circ = &m;
  ASSERT_NE(circ, nullptr);
  EXPECT_EQ(circ->aux->name, aux + "_1");
  const Eigen::Vector3d d = calib::toIsometry(circ->aux->xyzAbc()).translation() - calib::toIsometry(circ_in->aux->xyzAbc()).translation();
  EXPECT_GT(d.norm(), 10.0);  // mm: another point of the arc, which the declared point could not hold
}

// A point that is a CIRC's auxiliary point and another motion's target: the split CIRC gets a
// new point, the declared one holds the other motion's correction (its report's dx, dy, dz).
TEST(KrlRules, ADeclaredPointUsedByAnotherMotionIsNeverRepurposed) {
  const StCell cell;
  const Eigen::VectorXd q1 = joints({-10, -70, 100, 10, 40, 20}), q2 = joints({15, -60, 90, 15, 45, 25}),
                        q3 = joints({35, -75, 105, 20, 50, 30});
  const calib::Configuration c1 = calib::kukaConfiguration(cell.controller, q1);
  const std::string dir = test::tempDir("krl_shared");
  test::writeText(dir + "/p.src",
                  "DEF p( )\n$TOOL={X 20,Y 0,Z 250,A 0,B -30,C 0}\n$BASE=$NULLFRAME\nPTP XP1\nCIRC XP2, XP3\nLIN XP2\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1=" + aggregate(cell.target(q1), c1.status, c1.turn) +
                                      "\nDECL E6POS XP2=" + aggregate(cell.target(q2), 2, 0) +
                                      "\nDECL E6POS XP3=" + aggregate(cell.target(q3), 2, 0) + "\nENDDAT\n");
  const Program in = readKrl(dir + "/p.src");
  JobSettings s;
  s.calibrated = cell.real;
  s.tol_mm = 0.01;
  const ProgramCompensation pc = compensateProgramReport(in, s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().message;
  ASSERT_GT(pc.report.points_added, 0);  // the arc was split
  const KrlText out = writeKrl(pc.program);
  EXPECT_NE(out.src.find("\nCIRC XP2_1, XP3\n"), std::string::npos) << out.src;
  EXPECT_NE(out.src.find("\nLIN XP2\n"), std::string::npos) << out.src;
  // XP2 = its written value + the LIN's correction
  const TargetReport* lin = nullptr;
  for (const TargetReport& t : pc.report.targets)
    if (t.name == "XP2" && t.motion_type == "LIN") lin = &t;
  ASSERT_NE(lin, nullptr);
  test::writeText(dir + "/o.src", out.src);
  test::writeText(dir + "/o.dat", out.dat);
  const Program back = readKrl(dir + "/o.src");
  const Target& xp2 = back.motions.back().target;
  ASSERT_EQ(xp2.name, "XP2");
  EXPECT_NEAR(*xp2.pose[0] - *in.motions[2].target.pose[0], lin->dx_mm, 1e-4);  // mm: the written precision
  EXPECT_NEAR(*xp2.pose[1] - *in.motions[2].target.pose[1], lin->dy_mm, 1e-4);
  EXPECT_NEAR(*xp2.pose[2] - *in.motions[2].target.pose[2], lin->dz_mm, 1e-4);
  EXPECT_GT(std::hypot(lin->dx_mm, lin->dy_mm, lin->dz_mm), 0.1);  // mm: a real correction
}

// The same with the points declared in the .src: the last sub-arc's auxiliary point becomes an
// inline aggregate (a DECL cannot follow statements), the declaration stays as it was.
TEST(KrlRules, ASplitCircWhosePointIsDeclaredInTheSrcGetsAnInlineAuxiliaryPoint) {
  const StCell cell;
  const Eigen::VectorXd q1 = joints({-10, -70, 100, 10, 40, 20}), q2 = joints({15, -60, 90, 15, 45, 25}),
                        q3 = joints({35, -75, 105, 20, 50, 30});
  const calib::Configuration c1 = calib::kukaConfiguration(cell.controller, q1);
  const std::string decl2 = "DECL E6POS XP2=" + aggregate(cell.target(q2), 2, 0);
  const std::string dir = test::tempDir("krl_src_decl");
  test::writeText(dir + "/p.src", "DEF p( )\n" + decl2 + "\nDECL E6POS XP3=" + aggregate(cell.target(q3), 2, 0) +
                                      "\n$TOOL={X 20,Y 0,Z 250,A 0,B -30,C 0}\n$BASE=$NULLFRAME\nPTP " +
                                      aggregate(cell.target(q1), c1.status, c1.turn) + "\nCIRC XP2, XP3\nEND\n");
  JobSettings s;
  s.calibrated = cell.real;
  s.tol_mm = 0.01;
  const ProgramCompensation pc = compensateProgramReport(readKrl(dir + "/p.src"), s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().message;
  ASSERT_GT(pc.report.points_added, 0);
  const std::string src = writeKrl(pc.program).src;
  EXPECT_NE(src.find("\n" + decl2 + "\n"), std::string::npos) << src;
  EXPECT_EQ(src.find("CIRC XP2,"), std::string::npos) << src;
  EXPECT_NE(src.find("\nCIRC {X "), std::string::npos) << src;
  EXPECT_NE(src.find("}, XP3\n"), std::string::npos) << src;
  int replaced = 0;
  for (const TargetReport& t : pc.report.targets) replaced += t.new_point_replaces == "XP2" && t.name.empty();
  EXPECT_EQ(replaced, 1);
}

TEST(KrlRules, NewPointNamesAreFreeInTheProgram) {
  const std::string dir = test::tempDir("krl_names");
  test::writeText(dir + "/p.src", "DEF p( )\nLIN XP4\nINT XP4_1\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP4={X 1,Y 2,Z 3,A 0,B 0,C 0}\nDECL INT xp4_2\nENDDAT\n");
  const Program p = readKrl(dir + "/p.src");
  EXPECT_EQ(newPointName(p, "XP4", {}), "XP4_3");
  EXPECT_EQ(newPointName(p, "XP4", {"XP4_3"}), "XP4_4");
  EXPECT_EQ(newPointName(p, "ABCDEFGHIJKLMNOPQRSTUVWXYZ", {}), "ABCDEFGHIJKLMNOPQRSTUV_1");  // 24 characters
}

}  // namespace
}  // namespace accura::postproc
