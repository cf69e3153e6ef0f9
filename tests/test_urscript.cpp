// URScript (urscript.h): the motion model read from a script (units, frames, expressions),
// untouched programs written back byte for byte, malformed programs reported as
// file:line:column with expected/found, and the acceptance test of issue 12: the compensated
// script, executed by a simulated nominal UR controller on a perturbed UR10, follows the
// intended path within the tolerance.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>

#include "accura/calib/errors.h"
#include "accura/calib/ik.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"
#include "accura/calib/ur_calibration.h"
#include "accura/calib/urdf.h"
#include "accura/postproc/check.h"
#include "accura/postproc/compensate.h"
#include "accura/postproc/job.h"
#include "accura/postproc/program_io.h"
#include "accura/postproc/urscript.h"
#include "accura/postproc/xml_program.h"
#include "test_util.h"

namespace accura::postproc {
namespace {

using namespace accura::calib;

// The seam of the first example (joint 1 near 0 deg; tests/golden/urscript/README.md): the numbers
// below are its. The bundled example (README) is the same seam turned to where Series_B measured.
std::string example() { return test::readText(test::sourcePath("tests/golden/urscript/ur10_seam.script")); }
std::string bundledExample() { return test::readText(test::sourcePath("examples/ur10_seam.script")); }

// The TCP pose T_base_tcp a p[...] means (metres, rotation vector), computed here on its own
// from the axis-angle formula (Rodrigues), not with the reader's code.
Eigen::Isometry3d rodrigues(double x, double y, double z, double rx, double ry, double rz) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z) * 1000;
  const Eigen::Vector3d r(rx, ry, rz);
  const double th = r.norm();
  if (th > 0) {
    const Eigen::Vector3d k = r / th;
    Eigen::Matrix3d K;
    K << 0, -k.z(), k.y(), k.z(), 0, -k.x(), -k.y(), k.x(), 0;
    T.linear() = Eigen::Matrix3d::Identity() + std::sin(th) * K + (1 - std::cos(th)) * K * K;
  }
  return T;
}

Eigen::Isometry3d poseOf(const Target& t) { return toIsometry(t.xyzAbc()); }

// The UR10 with the example's TCP (set_tcp(p[0, 0, 0.15, 0, 0, 0])).
RobotModel ur10WithTorch() {
  RobotModel m = test::loadBundled("ur10");
  m.nominal.T_flange_tcp = toIsometry({0, 0, 150, 0, 0, 0});
  return m;
}

TEST(UrScript, WaitLoopsAndFunctionsThatDoNotMoveKeepTheStartKnown) {
  // PolyScope writes a Wait DI as a while loop; a URCap pastes its gripper helpers as defs
  const std::string a = "p[0.5,0.1,0.4,0,3.14,0]", b = "p[0.5,0.2,0.4,0,3.14,0]";
  const std::string text = "def prog():\n"
                           "  def rq_close():\n    set_digital_out(0, True)\n    sleep(0.5)\n  end\n"
                           "  movel(" + a + ")\n"                                                   // 0: after a function's text
                           "  while (not(get_standard_digital_in(0) == True)):\n    sync()\n  end\n"
                           "  movel(" + b + ")\n"                                                   // 1: a loop without motions
                           "  rq_close()\n  movel(" + a + ")\n"                                    // 2: a helper that does not move
                           "  if x:\n    movel(" + b + ")\n    if y:\n      sync()\n    end\n  end\n"  // 3
                           "  movel(" + a + ")\n"                                                   // 4: the outer branch moved
                           "end\n";
  const Program p = parseUrScript(text, "wait.script");
  ASSERT_EQ(p.motions.size(), 5u);
  const std::vector<bool> expected = {true, false, false, false, true};
  for (size_t k = 0; k < expected.size(); ++k) EXPECT_EQ(p.motions[k].start_unknown, expected[k]) << "motion " << k;
}

TEST(UrScript, TheStartIsUnknownAfterACallABranchOrALoopAndInAFunction) {
  const std::string a = "p[0.5,0.1,0.4,0,3.14,0]", b = "p[0.5,0.2,0.4,0,3.14,0]";
  const std::string text = "def prog():\n"
                           "  def dip():\n    movel(" + a + ")\n  end\n"   // 0: a function's first motion
                           "  movel(" + a + ")\n"                            // 1: after the function's text
                           "  dip()\n  movel(" + b + ")\n"                 // 2: after a call
                           "  movel(" + a + ")\n"                            // 3
                           "  if x:\n    movel(" + b + ")\n  else:\n    movel(" + a + ")\n  end\n"  // 4, 5: the other branch
                           "  movel(" + b + ")\n"                            // 6: after the branches
                           "  set_digital_out(1, True)\n  movel(" + a + ")\n"  // 7: a built-in does not move the robot
                           "  while y:\n    movel(" + b + ")\n  end\n"     // 8: a loop's first motion
                           "end\n";
  const Program p = parseUrScript(text, "flow.script");
  ASSERT_EQ(p.motions.size(), 9u);
  const std::vector<bool> expected = {true, true, true, false, false, true, true, false, true};
  for (size_t k = 0; k < expected.size(); ++k) EXPECT_EQ(p.motions[k].start_unknown, expected[k]) << "motion " << k;
  // a script cut short
  try {
    parseUrScript("def prog():\n  movel(" + a + ")\n", "cut.script");
    ADD_FAILURE() << "a def without end was read";
  } catch (const calib::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("expected end closing the block at cut.script:1:1, found the end of the file"), std::string::npos)
        << e.what();
  }
}

TEST(UrScript, ServoAndSpeedCommandsAreNamedAndTheStartAfterThemIsUnknown) {
  // servoj / servoc / speedj / speedl move the robot in ways accura does not model: the motion
  // after each starts where it left the robot; servoc's Cartesian target is kept as a motion
  // whose target cannot be evaluated (left as written, named in a warning). The start is also
  // unknown after a thread that moves the robot is started, and after force control.
  const std::string a = "p[0.5,0.1,0.4,0,3.14,0]", b = "p[0.5,0.2,0.4,0,3.14,0]";
  const std::string text = "def prog():\n"
                           "  movel(" + a + ")\n"                                                  // 0
                           "  servoj([0,-1.57,1.57,-1.57,-1.57,0], t=0.5)\n"
                           "  movel(" + b + ")\n"                                                  // 1
                           "  servoc(" + a + ", a=1.2, v=0.25, r=0)\n"                              // 2
                           "  movel(" + b + ")\n"                                                  // 3
                           "  speedl([0,0,0.1,0,0,0], 0.5, 1.0)\n  stopl(1.0)\n"
                           "  movel(" + a + ")\n"                                                  // 4
                           "  thread mover():\n    movel(" + b + ")\n    return False\n  end\n"  // 5: a thread's first motion
                           "  thrd = run mover()\n  join thrd\n  movel(" + a + ")\n"             // 6
                           "  force_mode(p[0,0,0,0,0,0], [0,0,1,0,0,0], [0,0,10,0,0,0], 2, [0.1,0.1,0.1,0.1,0.1,0.1])\n"
                           "  end_force_mode()\n  movel(" + b + ")\n"                            // 7
                           "end\n";
  const Program p = parseUrScript(text, "servo.script");
  ASSERT_EQ(p.motions.size(), 8u);  // movel x7, servoc
  const std::vector<bool> expected = {true, true, false, true, true, true, true, true};
  for (size_t k = 0; k < expected.size(); ++k) EXPECT_EQ(p.motions[k].start_unknown, expected[k]) << "motion " << k;
  EXPECT_NE(p.motions[2].target_problem.find("servoc is a motion accura does not model"), std::string::npos);
  for (size_t k : {0u, 1u, 3u, 4u, 5u, 6u, 7u}) EXPECT_EQ(p.motions[k].target_problem, "") << k;
  EXPECT_EQ(writeUrScript(p), text);  // nothing changed: written back byte for byte
  const Program bom = parseUrScript("\xEF\xBB\xBF" + text, "bom.script");  // a UTF-8 byte order mark: read past
  EXPECT_EQ(bom.motions.size(), p.motions.size());
  EXPECT_EQ(writeUrScript(bom), "\xEF\xBB\xBF" + text);
}

TEST(UrScript, ATcpSetInABranchAFunctionOrAtRunTimeIsNotTakenFromTheText) {
  const std::string a = "p[0.5,0.1,0.4,0,3.14,0]", b = "p[0.5,0.2,0.4,0,3.14,0]";
  const std::string text = "def prog():\n"
                           "  def grip():\n    set_tcp(p[0,0,0.2,0,0,0])\n  end\n"
                           "  set_tcp(p[0,0,0.1,0,0,0])\n"
                           "  movel(" + a + ")\n"                                            // 0: 0.1
                           "  if x:\n    set_tcp(p[0,0,0.15,0,0,0])\n    movel(" + b + ")\n"  // 1: 0.15
                           "  else:\n    movel(" + a + ")\n  end\n"                        // 2: 0.1 (the else)
                           "  movel(" + b + ")\n"                                            // 3: either
                           "  set_tcp(p[0,0,0.1,0,0,0])\n  movel(" + a + ")\n"              // 4: 0.1
                           "  grip()\n  movel(" + b + ")\n"                                 // 5: grip's
                           "  set_tcp(get_tcp_offset())\n  movel(" + a + ")\n"              // 6: the controller's
                           "end\n";
  const Program p = parseUrScript(text, "tcp.script");
  ASSERT_EQ(p.motions.size(), 7u);
  const std::vector<double> z = {100, 150, 100, -1, 100, -1, -1};
  for (size_t k = 0; k < z.size(); ++k) {
    if (z[k] < 0) {
      EXPECT_TRUE(p.motions[k].tool.run_time) << k;
      EXPECT_FALSE(p.motions[k].tool.known()) << k;
    } else {
      ASSERT_TRUE(p.motions[k].tool.known()) << k;
      EXPECT_NEAR(p.motions[k].tool.value->z_mm, z[k], 1e-9) << k;
    }
  }
  EXPECT_EQ(p.motions[3].tool.note, "set_tcp is called inside the if at tcp.script:7:3: after it, the tool depends on the way the program ran");
  EXPECT_EQ(p.motions[5].tool.note, "the function grip (tcp.script:2:3) calls set_tcp: the tool after the call is not followed");
  // compensated: the run-time tools are kept and named, not an error
  SimulateOptions so;
  so.effects = {"geometric"};
  so.set_station = false;
  so.seed = 5;
  const RobotModel ur10 = test::loadBundled("ur10");
  JobSettings js;
  js.calibrated = perturbModel(ur10, so);
  const ProgramCompensation c = compensateProgramReport(p, js);
  ASSERT_TRUE(c.ok()) << c.report.errors.front().message;
  EXPECT_EQ(c.report.motions_left_unchanged, 3);
}

TEST(UrScript, ReadsTheMotionModelInMetresAndRotationVectors) {
  const Program p = parseUrScript(example(), "ur10_seam.script");
  EXPECT_EQ(p.name, "ur10_seam");
  ASSERT_EQ(p.motions.size(), 8u);
  // movej(home): joint positions (rad) -> an axis target (deg), never changed
  const Motion& home = p.motions[0];
  EXPECT_EQ(home.type, MotionType::kPtp);
  EXPECT_EQ(home.target.kind, Target::Kind::kAxis);
  const double j[6] = {0, -90, 90, -90, -90, 0};
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(*home.target.axes[k], j[k], 1e-5);  // 1.5707963 rad written: 3e-6 deg short
  // the TCP from set_tcp, the Base frame of the controller
  ASSERT_TRUE(home.tool.value.has_value());
  EXPECT_NEAR(home.tool.value->z_mm, 150, 1e-12);
  ASSERT_TRUE(home.base.value.has_value());
  EXPECT_TRUE(toIsometry(*home.base.value).isApprox(Eigen::Isometry3d::Identity(), 1e-15));
  // movej(get_inverse_kin(approach, qnear=home)): a Cartesian PTP
  const Motion& approach = p.motions[1];
  EXPECT_EQ(approach.type, MotionType::kPtp);
  EXPECT_EQ(approach.target.name, "approach");
  const Eigen::Isometry3d expect = rodrigues(-0.7, -0.35, 0.3, 2.2214415, 2.2214415, 0);
  EXPECT_LT((poseOf(approach.target).matrix() - expect.matrix()).norm(), 1e-9);
  // pi/sqrt(2) about (1,1,0)/sqrt(2): the tool's z down, its x along the base's y
  Eigen::Matrix3d down;
  down << 0, 1, 0, 1, 0, 0, 0, 0, -1;
  EXPECT_LT((poseOf(approach.target).linear() - down).norm(), 1e-7);
  // pose_trans(approach, p[0, 0, 0.1, ..]): 100 mm along the tool's z (down): z 300 -> 200 mm
  const Motion& start = p.motions[2];
  EXPECT_EQ(start.type, MotionType::kLin);
  EXPECT_EQ(start.target.name, "seam_start");
  EXPECT_LT((poseOf(start.target).translation() - Eigen::Vector3d(-700, -350, 200)).norm(), 1e-5);
  ASSERT_TRUE(start.vel_m_s.has_value());
  EXPECT_DOUBLE_EQ(*start.vel_m_s, 0.05);
  EXPECT_TRUE(start.approximation.empty());
  // movec: via point and end point
  const Motion& arc = p.motions[4];
  EXPECT_EQ(arc.type, MotionType::kCirc);
  ASSERT_TRUE(arc.aux.has_value());
  EXPECT_LT((poseOf(*arc.aux).translation() - Eigen::Vector3d(-780, 130, 200)).norm(), 1e-9);
  EXPECT_LT((poseOf(arc.target).translation() - Eigen::Vector3d(-860, 50, 200)).norm(), 1e-9);
  EXPECT_TRUE(arc.approximation.empty());  // r=0: an exact stop
  // pose_add(p, p[0, 0, 0.1, ..]): positions added (z 200 + 100 mm), rotations multiplied
  const Motion& retreat = p.motions[6];
  EXPECT_LT((poseOf(retreat.target).translation() - Eigen::Vector3d(-860, -350, 300)).norm(), 1e-9);
  EXPECT_LT((poseOf(retreat.target).linear() - down).norm(), 1e-7);
  // r=0.02 m: the approximation, C_DIS 20 mm
  ASSERT_EQ(retreat.approximation.size(), 1u);
  EXPECT_EQ(retreat.approximation[0], Approximation::kCDis);
  EXPECT_NEAR(*retreat.approximation_value, 20, 1e-12);
  // places: line and column of the statement and of the target
  EXPECT_EQ(approach.where.str(), "ur10_seam.script:11:3");
  EXPECT_EQ(arc.target.where.str(), "ur10_seam.script:15:61");
  // the logic is kept as text: set_payload, set_digital_out (twice)
  ASSERT_EQ(p.urscript->others.size(), 3u);
  EXPECT_EQ(p.urscript->others[1].text, "set_digital_out(0, True)");
}

TEST(UrScript, RotationVectorsAndPoseArithmeticAgainstTheirDefinitions) {
  // a rotation of 90 deg about z: A = 90, B = C = 0; pose_add rotates by a.R * b.R and adds
  // the positions; pose_trans composes
  const Program p = parseUrScript(
      "a = p[0.1, 0.2, 0.3, 0, 0, 1.5707963267948966]\n"
      "b = p[0.01, 0.02, 0.03, 0.5, 0, 0]\n"
      "movel(a)\n"
      "movel(pose_add(a, b))\n"
      "movel(pose_trans(a, b))\n",
      "t.script");
  ASSERT_EQ(p.motions.size(), 3u);
  const XyzAbc a = p.motions[0].target.xyzAbc();
  EXPECT_NEAR(a.x_mm, 100, 1e-12);
  EXPECT_NEAR(a.a_deg, 90, 1e-12);
  EXPECT_NEAR(a.b_deg, 0, 1e-12);
  EXPECT_NEAR(a.c_deg, 0, 1e-12);
  const Eigen::Isometry3d A = rodrigues(0.1, 0.2, 0.3, 0, 0, kPi / 2), B = rodrigues(0.01, 0.02, 0.03, 0.5, 0, 0);
  const Eigen::Isometry3d add = poseOf(p.motions[1].target);
  EXPECT_LT((add.translation() - Eigen::Vector3d(110, 220, 330)).norm(), 1e-9);
  EXPECT_LT((add.linear() - A.linear() * B.linear()).norm(), 1e-12);
  EXPECT_LT(((poseOf(p.motions[2].target)).matrix() - (A * B).matrix()).norm(), 1e-9);
}

TEST(UrScript, UntouchedProgramsAreWrittenBackByteForByte) {
  std::string crlf;
  for (char c : example()) {
    if (c == '\n') crlf += '\r';
    crlf += c;
  }
  std::string no_final_newline = example();
  no_final_newline.pop_back();
  for (const std::string& text : {example(), crlf, no_final_newline, std::string("movel(p[.1,-.2,.3,0,3.1416,0])  # tight\n")}) {
    const Program p = parseUrScript(text, "x.script");
    EXPECT_EQ(writeUrScript(p), text);
  }
  // a program as PolyScope exports it (threads, $ markers, global waypoints, get_inverse_kin
  // with qnear): two motions, the rest kept as text; the nominal robot changes nothing
  const std::string ps = test::readText(test::sourcePath("tests/data/urscript/polyscope_export.script"));
  const Program p = parseUrScript(ps, "polyscope_export.script");
  ASSERT_EQ(p.motions.size(), 2u);
  EXPECT_EQ(p.motions[0].target.name, "Waypoint_1_p");
  EXPECT_EQ(p.motions[1].target.name, "Waypoint_2_p");
  EXPECT_NEAR(p.motions[1].target.xyzAbc().x_mm, -716.509730192, 1e-9);
  RobotModel ur10 = test::loadBundled("ur10");
  JobSettings s;
  s.calibrated = ur10;
  const ProgramCompensation c = compensateProgramReport(p, s);
  ASSERT_TRUE(c.ok()) << c.report.errors.front().message;
  EXPECT_EQ(writeUrScript(c.program), ps);
  // and through the command line: convert a .script into a .script
  const std::string dir = test::tempDir("ur_roundtrip");
  test::writeText(dir + "/in.script", crlf);
  const test::CliRun r = test::runAccuraIn(dir, "convert --in in.script --out out.script");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(test::readText(dir + "/out.script"), crlf);
}

std::string errorOf(const std::string& text) {
  try {
    parseUrScript(text, "bad.script");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(UrScript, MalformedProgramsAreErrorsWithFileLineAndColumn) {
  EXPECT_EQ(errorOf("def f():\n  movel(p[0.1, 0.2, 0.3, 0, 0], a=1.2)\nend\n"),
            "bad.script:2:9: expected p[x, y, z, rx, ry, rz] with 6 numbers, found 5 in 'p[0.1, 0.2, 0.3, 0, 0]'");
  EXPECT_EQ(errorOf("def f():\n  movel(p[0.1, 0.2, 0.3, 0, 0, 0]\nend\n"),
            "bad.script:2:8: expected ')' to close this '(', found the end of the file");
  EXPECT_EQ(errorOf("movel(p[0.1, 0.2, 0.3, 0, 0, 0], speed=0.1)\n"),
            "bad.script:1:34: expected an argument of movel (pose, a, v, t, r), found 'speed'");
  EXPECT_EQ(errorOf("movel(p[0.1, 0.2, 0.3, 0, 0, 0], v=0.1, v=0.2)\n"),
            "bad.script:1:41: expected each argument of movel once, found 'v' given twice");
  EXPECT_EQ(errorOf("x = 1\nmovel(p[0.1, 0.2, 0.3, 0, 0, 0], r=-0.01)\n"),
            "bad.script:2:36: expected a blend radius in [0, 10] m, found -0.01");
  EXPECT_EQ(errorOf("popup(\"arc on)\n"), "bad.script:1:7: expected the closing '\"' of this string on its line, found the end of the line");
  EXPECT_EQ(errorOf("movej(p[1e999, 0, 0, 0, 0, 0])\n"), "bad.script:1:9: expected a finite number, found '1e999'");
  EXPECT_EQ(errorOf("def p():\n  movel(p[0.1, 0.2, 1e+, 0, 3.1416, 0], a=1.2, v=0.25)\nend\n"),
            "bad.script:2:22: expected the digits of an exponent, found 'e+,'");
  EXPECT_EQ(errorOf("movej(p[650, 0, 0, 0, 0, 0])\n"), "bad.script:1:9: expected a position in metres within +-100, found 650");
  EXPECT_EQ(errorOf("movec(p[0.1, 0.2, 0.3, 0, 0, 0])\n"), "bad.script:1:1: expected the argument 'pose_to' of movec, found none");
  EXPECT_EQ(errorOf("if x:\n  y = (1]\nend\n"), "bad.script:2:9: expected ')' to close the '(' at bad.script:2:7, found ']'");
  EXPECT_EQ(errorOf("movej([0, 0, 0, 0, 0])\n"), "bad.script:1:7: expected 6 joint positions [q1, .., q6] (rad), found 5");
  // binary
  EXPECT_EQ(errorOf(std::string("movel(p1)\n\0x", 12)), "bad.script:2:1: expected a URScript text file, found a NUL byte (binary file?)");
}

JobSettings settingsFor(const RobotModel& real) {
  JobSettings s;
  s.calibrated = real;
  s.tol_mm = 0.05;
  return s;
}

/// The "real" robot of the configuration tests: `controller` with geometric deviations (seed 4),
/// its station untouched.
RobotModel realUr10(const RobotModel& controller) {
  SimulateOptions so;
  so.effects = {"geometric"};
  so.set_station = false;
  so.seed = 4;
  return perturbModel(controller, so);
}

/// The solution of `robot` for T_world_tcp nearest `to` in joint space: every closed-form
/// branch polished on the robot (independent of the compensation's own solver path); empty
/// when none converges.
Eigen::VectorXd nearestSolution(const RobotModel& robot, const Eigen::Isometry3d& T, const Eigen::VectorXd& to) {
  const KinematicSolver ik(robot);
  Eigen::VectorXd best;
  for (const Eigen::VectorXd& seed : ik.closedFormSolutions(T)) {
    const IkResult r = ik.inverse(T, kukaConfiguration(robot, seed), seed, IkOptions{});
    if (r.status != IkStatus::kOk) continue;
    if (best.size() == 0 || (r.q - to).norm() < (best - to).norm()) best = r.q;
  }
  return best;
}

TEST(UrScript, GetInverseKinTakesTheSolutionNearestToQnear) {
  // PolyScope writes every MoveJ waypoint as movej(get_inverse_kin(Waypoint_n_p,
  // qnear=Waypoint_n_q)); the controller then takes the solution nearest qnear, not the one
  // nearest to where the robot stands (URScript manual, get_inverse_kin). Here the robot
  // stands with the shoulder up (q2 = +11.5 deg) and qnear asks for the shoulder down.
  const std::string qnear = "[-1.5707963, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0.0]";
  const std::string script =
      "def q():\n"
      "  set_tcp(p[0.0, 0.0, 0.15, 0.0, 0.0, 0.0])\n"
      "  movej([-1.5707963, 0.2, -1.5707963, -1.5707963, -1.5707963, 0.0], a=1.4, v=1.05)\n"
      "  movej(get_inverse_kin(p[-.350, .700, .300, 3.1415927, 0.0, 0.0], qnear=" + qnear + "), a=1.4, v=1.05)\n"
      "end\n";
  const RobotModel controller = ur10WithTorch();
  const RobotModel real = realUr10(controller);
  const Program p = parseUrScript(script, "q.script");
  ASSERT_EQ(p.motions.size(), 2u);
  ASSERT_TRUE(p.motions[1].qnear_deg.has_value());
  EXPECT_NEAR((*p.motions[1].qnear_deg)[1], -90.0, 1e-5);
  const ProgramCompensation c = compensateProgramReport(p, settingsFor(real));
  ASSERT_TRUE(c.ok()) << c.report.errors.front().where.str() << ": " << c.report.errors.front().message;
  // the expectation on its own: every solution of the real robot for the pose (from each
  // closed-form branch), the one nearest qnear in joint space, commanded through the controller
  const Eigen::Isometry3d T = rodrigues(-.350, .700, .300, 3.1415927, 0.0, 0.0);
  const KinematicSolver controller_ik(controller);
  Eigen::VectorXd q_near(6), q_up(6);
  q_near << -90, -90, 90, -90, -90, 0;
  q_up << -90, 11.459156, -90, -90, -90, 0;
  auto nearest = [&](const Eigen::VectorXd& to) { return nearestSolution(real, T, to); };
  const Eigen::VectorXd q_real = nearest(q_near), q_real_up = nearest(q_up);
  ASSERT_EQ(q_real.size(), 6);
  ASSERT_EQ(q_real_up.size(), 6);
  const Eigen::Vector3d expected = controller_ik.forward(q_real).translation();
  const Eigen::Vector3d from_the_robot = controller_ik.forward(q_real_up).translation();
  // the two branches need corrections that differ by more than 0.3 mm: the test tells them apart
  EXPECT_GT((expected - from_the_robot).norm(), 0.3);
  const Eigen::Vector3d written = poseOf(c.program.motions[1].target).translation();
  EXPECT_LT((written - expected).norm(), 1e-3);  // the 7 decimals written (0.1 um) and the IK's polish
  // qnear stays as written
  EXPECT_NE(writeUrScript(c.program).find("qnear=" + qnear + "), a=1.4"), std::string::npos);
}

TEST(UrScript, ALoopsFirstMoveKeepsTheConfigurationTheRobotStandsIn) {
  // A movel at a loop's start (after the movej before it, or after the loop's own end) has no
  // known start, and a pose names no configuration: the controller moves linearly from
  // wherever the robot stands, on its configuration. The guess is the configuration of the
  // last position known (the movej: elbow on the side of q2 = -90 deg), not the solution
  // nearest the middle of the joint ranges (the other branch, q2 near +5 deg: 1-3 mm off).
  const std::string script =
      "def loop():\n"
      "  set_tcp(p[0.0, 0.0, 0.15, 0.0, 0.0, 0.0])\n"
      "  movej([-1.5707963, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0.0])\n"
      "  while True:\n"
      "    movel(p[-0.412576, 0.629499, 0.395540, 3.129234, 0.0, -0.051327])\n"
      "    movel(p[-0.262466, 0.544422, 0.487802, 3.1415927, 0.0, 0.0])\n"
      "  end\n"
      "end\n";
  const RobotModel controller = ur10WithTorch();
  const RobotModel real = realUr10(controller);
  const Program p = parseUrScript(script, "loop.script");
  ASSERT_EQ(p.motions.size(), 3u);
  ASSERT_TRUE(p.motions[1].start_unknown);
  const ProgramCompensation c = compensateProgramReport(p, settingsFor(real));
  ASSERT_TRUE(c.ok()) << c.report.errors.front().where.str() << ": " << c.report.errors.front().message;
  // the expectation on its own: the real robot's solution nearest the movej's joints (each
  // closed-form branch polished on the real robot), commanded through the controller
  const KinematicSolver controller_ik(controller);
  Eigen::VectorXd q_movej(6), q_mid(6);
  q_movej << -90, -90, 90, -90, -90, 0;
  for (int i = 0; i < 6; ++i) q_mid[i] = 0.5 * (controller.nominal.joints[i].lower + controller.nominal.joints[i].upper);
  const Eigen::Isometry3d T = rodrigues(-0.412576, 0.629499, 0.395540, 3.129234, 0.0, -0.051327);
  auto nearest = [&](const Eigen::VectorXd& to) { return nearestSolution(real, T, to); };
  const Eigen::VectorXd q_real = nearest(q_movej), q_other = nearest(q_mid);
  ASSERT_EQ(q_real.size(), 6);
  ASSERT_EQ(q_other.size(), 6);
  const Eigen::Vector3d expected = controller_ik.forward(q_real).translation();
  // the other branch needs a correction more than 0.3 mm different: the test tells them apart
  EXPECT_GT((expected - controller_ik.forward(q_other).translation()).norm(), 0.3);
  const Eigen::Vector3d written = poseOf(c.program.motions[1].target).translation();
  EXPECT_LT((written - expected).norm(), 1e-3);
  // and the warning says which configuration was taken
  bool said = false;
  for (const auto& w : c.report.warnings)
    said = said || (w.where.line == 5 && w.message.find("configuration of the last position known (after the motion at loop.script:3") != std::string::npos);
  EXPECT_TRUE(said);
}

TEST(UrScript, ATargetWithJointsAtZeroIsNotTurnedByItsKukaTurnBits) {
  // A UR controller has no Status/Turn: movej(pose) takes the solution nearest the joints the
  // robot stands on (URScript manual, movej / get_inverse_kin). A program in the neutral XML
  // format made for the UR (an OLP's) may still carry KUKA S/T: here those of the joints
  // {0, -60, 80, -110, -90, 0}, T 26 (joints 1 and 6 at exactly 0: their Turn bits clear).
  // The real arm reaches the pose with joints 1 and 6 a few hundredths of a degree below 0;
  // solved on the written Turn bits they went a full turn round (359.97 deg), and the LIN
  // after it, turning them further up, ran into their 360 deg limit and was refused.
  const RobotModel controller = ur10WithTorch();
  SimulateOptions so;
  so.effects = {"geometric"};
  so.set_station = false;
  so.seed = 2;
  const RobotModel real = perturbModel(controller, so);
  const KinematicSolver nominal(controller);
  Eigen::VectorXd q_home(6), q_a(6), q_b(6);
  q_home << 0, -90, 90, -90, -90, 0;
  q_a << 0, -60, 80, -110, -90, 0;
  q_b << 5, -60, 80, -110, -90, 5;
  const Eigen::Isometry3d T_a = nominal.forward(q_a), T_b = nominal.forward(q_b);
  const Configuration st_a = kukaConfiguration(controller, q_a);
  ASSERT_EQ(st_a.turn, 26);  // joints 1 and 6 at 0: bits 0 and 5 clear
  auto pose = [](const Eigen::Isometry3d& T, const Configuration& c) {
    const XyzAbc p = toXyzAbc(T);
    char b[400];
    std::snprintf(b, sizeof b, "<pose x_mm=\"%.6f\" y_mm=\"%.6f\" z_mm=\"%.6f\" a_deg=\"%.7f\" b_deg=\"%.7f\" c_deg=\"%.7f\" s=\"%d\" t=\"%d\"/>",
                  p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg, c.status, c.turn);
    return std::string(b);
  };
  const std::string xml = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<program name=\"zero\" version=\"1\">\n  <motions>\n"
                          "    <ptp><axes a1=\"0\" a2=\"-90\" a3=\"90\" a4=\"-90\" a5=\"-90\" a6=\"0\"/></ptp>\n"
                          "    <ptp>" + pose(T_a, st_a) + "</ptp>\n"
                          "    <lin>" + pose(T_b, st_a) + "</lin>\n  </motions>\n</program>\n";
  const Program p = parseXmlProgram(xml, "zero.xml");
  ASSERT_EQ(p.motions.size(), 3u);
  JobSettings s = settingsFor(real);
  s.initial_tool = XyzAbc{0, 0, 150, 0, 0, 0};  // the torch of the model (ur10WithTorch)
  s.initial_base = XyzAbc{0, 0, 0, 0, 0, 0};
  const ProgramCompensation c = compensateProgramReport(p, s);
  ASSERT_TRUE(c.ok()) << c.report.errors.front().where.str() << ": " << c.report.errors.front().message;
  ASSERT_EQ(c.program.motions.size(), 3u);  // the LIN: no point added on 100 mm of a 0.05 mm tolerance
  // the expectation on its own: the UR runs the written poses, each from the joints it stands
  // on (its IK's solution nearest them: every closed-form branch polished on the controller
  // model), and the real arm's FK of those joints is the intended pose
  const Eigen::VectorXd q_exec_a = nearestSolution(controller, poseOf(c.program.motions[1].target), q_home);
  ASSERT_EQ(q_exec_a.size(), 6);
  const Eigen::VectorXd q_exec_b = nearestSolution(controller, poseOf(c.program.motions[2].target), q_exec_a);
  ASSERT_EQ(q_exec_b.size(), 6);
  const KinematicSolver real_fk(real);
  EXPECT_LT((real_fk.forward(q_exec_a).translation() - T_a.translation()).norm(), 1e-3);
  EXPECT_LT(rotationAngleDeg(real_fk.forward(q_exec_a).linear() * T_a.linear().transpose()), 1e-4);
  EXPECT_LT((real_fk.forward(q_exec_b).translation() - T_b.translation()).norm(), 1e-3);
  // the arm stays where the program put it (no joint a turn round): joints 1 and 6 within 0.5 deg of 0
  EXPECT_LT((q_exec_a - q_a).cwiseAbs().maxCoeff(), 0.5);
  EXPECT_LT((q_exec_b - q_b).cwiseAbs().maxCoeff(), 0.5);
  // at least one of joints 1 and 6 lies below 0 on the real arm: the case of the Turn bit
  EXPECT_TRUE(q_exec_a[0] < 0 || q_exec_a[5] < 0) << q_exec_a.transpose();
  // the S/T are kept as written (the UR does not read them)
  EXPECT_EQ(*c.program.motions[1].target.status, st_a.status);
  EXPECT_EQ(*c.program.motions[1].target.turn, st_a.turn);
  // accura check follows the same rule: on the written Turn bits the end point had joint 1 at
  // 359.97 deg and the LIN ran it past 360 (two joint-limit violations); the margin is that of
  // the joints the arm takes (joint 4 at about -110 deg is the nearest to its limit)
  CheckOptions o;
  o.thresholds.joint_margin_deg = 1.0;
  const CheckReport r = checkProgram(p, s, Cell{}, o);
  EXPECT_TRUE(r.passed()) << (r.violations.empty() ? std::string() : r.violations.front().message);
  const double largest = std::max(q_exec_a.cwiseAbs().maxCoeff(), q_exec_b.cwiseAbs().maxCoeff());
  EXPECT_NEAR(r.min_joint_margin, 360.0 - largest, 0.5);
}

TEST(UrScript, AControllerThatRunsItsFactoryCalibrationIsNotCorrectedTwice) {
  // A UR controller runs its factory calibration (calibration.conf), not the nominal DH: the
  // compensation must command the pose that the controller's own kinematics turn into the
  // joints the real arm needs (JobSettings::controller_kinematics). The real arm here is the
  // factory calibration plus 0.2 mrad on the shoulder; its identified model holds both.
  const RobotDefinition ur10 = test::loadBundled("ur10").nominal;
  const RobotModel factory = modelFromUrDeltas(ur10, readUrCalibrationConf(test::sourcePath("tests/data/urdf/ur_forum_calibration.conf")));
  RobotModel real = factory;
  real.deviations.links[1].dtheta_rad += 2e-4;
  real.nominal.T_flange_tcp = toIsometry({0, 0, 150, 0, 0, 0});  // the program's TCP is the model's (exact)
  const std::string script =
      "def f():\n"
      "  set_tcp(p[0.0, 0.0, 0.15, 0.0, 0.0, 0.0])\n"
      "  movej([-1.5707963, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0.0], a=1.4, v=1.05)\n"
      "  movej(get_inverse_kin(p[-.350, .700, .300, 3.1415927, 0.0, 0.0], qnear=[-1.5707963, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0.0]))\n"
      "end\n";
  const Program p = parseUrScript(script, "f.script");
  const Eigen::Isometry3d T = rodrigues(-.350, .700, .300, 3.1415927, 0.0, 0.0);
  // the controller, on its own: the factory kinematics with the program's TCP, the solution
  // nearest qnear; where the real arm then is
  RobotModel controller = factory;
  controller.nominal.T_flange_tcp = toIsometry({0, 0, 150, 0, 0, 0});
  const KinematicSolver controller_ik(controller), real_fk(real);
  Eigen::VectorXd qnear(6);
  qnear << -90, -90, 90, -90, -90, 0;
  auto landed = [&](const ProgramCompensation& c) {
    const IkResult r = controller_ik.inverse(poseOf(c.program.motions[1].target), Configuration{}, qnear, IkOptions{});
    EXPECT_EQ(r.status, IkStatus::kOk);
    return (real_fk.forward(r.q).translation() - T.translation()).norm();
  };
  JobSettings s = settingsFor(real);
  s.controller_kinematics = factory;
  const ProgramCompensation with = compensateProgramReport(p, s);
  ASSERT_TRUE(with.ok()) << with.report.errors.front().message;
  EXPECT_LT(landed(with), 1e-3);  // the 7 decimals written (0.1 um) and the IK's tolerance
  // the nominal robot as the controller's model applies the factory calibration a second time
  const ProgramCompensation twice = compensateProgramReport(p, settingsFor(real));
  ASSERT_TRUE(twice.ok());
  EXPECT_GT(landed(twice), 1.0);
  // a model with effects a controller does not run is refused by name
  RobotModel compliant = factory;
  compliant.deviations.compliance[1] = 1e-6;
  s.controller_kinematics = compliant;
  try {
    compensateProgramReport(p, s);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("expected a geometric model"), std::string::npos) << e.what();
  }
}

TEST(UrScript, APayloadTheProgramSetsIsSaidWhereTheModelDependsOnIt) {
  // set_payload changes the load the arm runs with; the compensation takes one payload
  // (--payload-kg): with a compliant model that is said, with a geometric one there is nothing to say
  const std::string script =
      "def l():\n  set_tcp(p[0.0, 0.0, 0.15, 0.0, 0.0, 0.0])\n  set_payload(10.0)\n"
      "  movej([-1.5707963, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0.0], a=1.4, v=1.05)\n"
      "  movel(p[-.350, .700, .300, 3.1415927, 0.0, 0.0], a=1.2, v=0.25)\nend\n";
  const Program p = parseUrScript(script, "l.script");
  auto said = [](const ProgramCompensation& c) {
    for (const auto& w : c.report.warnings)
      if (w.message.find("the program sets its payload here ('set_payload(10.0)')") != std::string::npos) return w.where.str();
    return std::string();
  };
  SimulateOptions so;
  so.effects = {"geometric", "joint_compliance"};
  so.set_station = false;
  so.seed = 2;
  EXPECT_EQ(said(compensateProgramReport(p, settingsFor(perturbModel(ur10WithTorch(), so)))), "l.script:3:3");
  // the payload the compensation takes is the program's: nothing to say
  JobSettings ten = settingsFor(perturbModel(ur10WithTorch(), so));
  ten.context.payload_kg = 10.0;
  EXPECT_EQ(said(compensateProgramReport(p, ten)), "");
  so.effects = {"geometric"};
  EXPECT_EQ(said(compensateProgramReport(p, settingsFor(perturbModel(ur10WithTorch(), so)))), "");
}

TEST(UrScript, AMountingTheProgramSetsIsSaidWhereItDiffersFromTheModels) {
  // set_gravity(d): d points away from the earth's centre, in Base (URScript manual; PolyScope
  // writes the installation's mounting so, here a wall mount as a public PolyScope export has
  // it). The model's joint compliance bends the arm under its <gravity> (0, 0, -9.80665): a
  // wall mount is 90 deg from it, a floor mount nothing to say, a geometric model neither.
  auto said = [](const std::string& gravity, const std::vector<std::string>& effects) {
    const Program p = parseUrScript("def g():\n  set_tcp(p[0.0, 0.0, 0.15, 0.0, 0.0, 0.0])\n  " + gravity +
                                        "\n  movej([-1.5707963, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0.0], a=1.4, v=1.05)\n"
                                        "  movel(p[-.350, .700, .300, 3.1415927, 0.0, 0.0], a=1.2, v=0.25)\nend\n",
                                    "g.script");
    SimulateOptions so;
    so.effects = effects;
    so.set_station = false;
    so.seed = 2;
    const ProgramCompensation c = compensateProgramReport(p, settingsFor(perturbModel(ur10WithTorch(), so)));
    EXPECT_TRUE(c.ok());
    for (const auto& w : c.report.warnings)
      if (w.message.find("mounting") != std::string::npos) return w.where.str() + ": " + w.message;
    return std::string();
  };
  const std::vector<std::string> compliant = {"geometric", "joint_compliance"};
  EXPECT_EQ(said("set_gravity([-9.82, 1.803904735144051E-15, 6.013015783813504E-16])", compliant),
            "g.script:3:3: the program sets the arm's mounting here ('set_gravity([-9.82, 1.803904735144051E-15, 6.013015783813504E-16])': "
            "gravity along (1.000, 0.000, 0.000) in the robot's frame 0, 90.0 deg from the model's <gravity> (0.000, 0.000, -1.000)); "
            "the model's joint compliance bends the arm under its own <gravity>, so the deflections corrected are those of another "
            "mounting (give the robot file the gravity of this one)");
  EXPECT_EQ(said("set_gravity([0.0, 0.0, 9.82])", compliant), "");
  // 0.5 deg of tilt is within kGravityDisagreeDeg; 2 deg is not
  EXPECT_EQ(said("set_gravity([0, " + std::to_string(9.82 * std::sin(0.5 * kDegToRad)) + ", " + std::to_string(9.82 * std::cos(0.5 * kDegToRad)) + "])", compliant), "");
  EXPECT_NE(said("set_gravity([0, " + std::to_string(9.82 * std::sin(2 * kDegToRad)) + ", " + std::to_string(9.82 * std::cos(2 * kDegToRad)) + "])", compliant)
                .find(", 2.0 deg from the model's <gravity>"),
            std::string::npos);
  EXPECT_NE(said("set_gravity(g_dir)", compliant).find("'set_gravity(g_dir)': accura cannot read its direction"), std::string::npos);
  EXPECT_EQ(said("set_gravity([-9.82, 0, 0])", {"geometric"}), "");
  EXPECT_EQ(said("textmsg(\"set_gravity([-9.82, 0, 0])\")", compliant), "");  // a string is no statement
  // blanks before the parenthesis are the same statement
  EXPECT_NE(said("set_gravity ([-9.82, 0.0, 0.0])", compliant).find("90.0 deg from the model's <gravity>"), std::string::npos);
}

TEST(UrScript, AProgramToolTheScriptReplacesBeforeItsFirstMotionIsSaidWhereTheyDiffer) {
  // --program-tool is the TCP active before the program sets one; a set_tcp before the first
  // motion (PolyScope writes the installation's TCP so) makes every motion run with the
  // script's TCP, as on the controller: a different --program-tool is said, not silently dropped
  auto said = [](const std::string& script, const XyzAbc& tool) {
    JobSettings s = settingsFor(ur10WithTorch());
    s.initial_tool = tool;
    const ProgramCompensation c = compensateProgramReport(parseUrScript(script, "t.script"), s);
    EXPECT_TRUE(c.ok());
    for (const auto& w : c.report.warnings)
      if (w.message.find("--program-tool") != std::string::npos) return w.where.str() + ": " + w.message;
    return std::string();
  };
  const std::string moves = "  movej([-1.5707963, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0.0])\n"
                            "  movel(p[-.350, .700, .300, 3.1415927, 0.0, 0.0])\n";
  const std::string first = "def t():\n  set_tcp(p[0.0, 0.0, 0.15, 0.0, 0.0, 0.0])\n" + moves + "end\n";
  EXPECT_EQ(said(first, {0, 0, 200, 0, 0, 0}),
            "t.script:2:3: --program-tool is not used: the program sets its TCP here (set_tcp(p[0.0, 0.0, 0.15, 0.0, 0.0, 0.0])) before its "
            "first motion, and every motion runs with the program's TCP, 50.000 mm and 0.000 deg from --program-tool's (check which TCP "
            "the cell uses)");
  EXPECT_EQ(said(first, {0, 0, 150, 0, 0, 0}), "");  // the same TCP: nothing to say
  // a motion before the set_tcp runs with --program-tool: it is used
  EXPECT_EQ(said("def t():\n" + moves + "  set_tcp(p[0.0, 0.0, 0.15, 0.0, 0.0, 0.0])\n" + moves + "end\n", {0, 0, 200, 0, 0, 0}), "");
  // the first motion runs with a TCP accura cannot evaluate: no set_tcp with a value comes
  // before it, so none is said to (the one after the first motion is not "before its first")
  EXPECT_EQ(said("def t():\n  set_tcp(pose_inv(tt))\n" + moves + "  set_tcp(p[0.0, 0.0, 0.15, 0.0, 0.0, 0.0])\n" + moves + "end\n",
                 {0, 0, 100, 0, 0, 0}),
            "");
}

TEST(UrScript, GetInverseKinArgumentsAreReadOrNamed) {
  const std::string pose = "p[-.350, .700, .300, 3.1415927, 0.0, 0.0]";
  auto read = [&](const std::string& call) {
    return parseUrScript("def q():\n  movej(" + call + ", a=1.4, v=1.05)\nend\n", "q.script");
  };
  // positional qnear and the controller's error bounds
  const Program positional = read("get_inverse_kin(" + pose + ", [0, -1.5, 1.5, -1.5, -1.5, 0], 1e-10, 1e-10)");
  ASSERT_TRUE(positional.motions[0].qnear_deg.has_value());
  EXPECT_NEAR((*positional.motions[0].qnear_deg)[1], -1.5 * kRadToDeg, 1e-9);
  EXPECT_TRUE(positional.motions[0].target_problem.empty());
  // no qnear: the joints where the robot stands decide (nothing to read)
  EXPECT_FALSE(read("get_inverse_kin(" + pose + ")").motions[0].qnear_deg.has_value());
  // a qnear accura cannot evaluate, or another TCP: the branch or the pose is not known
  EXPECT_NE(read("get_inverse_kin(" + pose + ", qnear=joints_of_the_day)").motions[0].target_problem.find("qnear"),
            std::string::npos);
  // the controller's defaults written out: the current joints, the active TCP
  const Program defaults = read("get_inverse_kin(" + pose + ", qnear=get_actual_joint_positions(), tcp=get_tcp_offset())");
  EXPECT_TRUE(defaults.motions[0].target_problem.empty()) << defaults.motions[0].target_problem;
  EXPECT_FALSE(defaults.motions[0].qnear_deg.has_value());
  EXPECT_NE(read("get_inverse_kin(" + pose + ", tcp=p[0, 0, 0.1, 0, 0, 0])").motions[0].target_problem.find("tcp="),
            std::string::npos);
  // an argument get_inverse_kin does not have: file:line:column, expected and found
  try {
    read("get_inverse_kin(" + pose + ", qfar=[0, 0, 0, 0, 0, 0])");
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("q.script:2:"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("found 'qfar'"), std::string::npos) << e.what();
  }
}

TEST(UrScript, CompensatingWithTheNominalRobotReturnsTheProgramByteForByte) {
  const Program p = parseUrScript(example(), "ur10_seam.script");
  const ProgramCompensation c = compensateProgramReport(p, settingsFor(ur10WithTorch()));
  ASSERT_TRUE(c.ok()) << c.report.errors.front().where.str() << ": " << c.report.errors.front().message;
  EXPECT_EQ(c.report.points_added, 0);
  EXPECT_LT(c.report.max_correction_mm, 1e-6);
  EXPECT_EQ(writeUrScript(c.program), example());
}

TEST(UrScript, PosesAreInTheControllersBaseFrameDhFrameZero) {
  // The real robot's base turned by delta about z: a point p (Base frame) is reached by
  // commanding Rz(-delta) p, i.e. the correction (dx, dy) = delta (p_y, -p_x). Were the poses
  // read in a frame turned 180 deg (ROS base_link), the sign would flip.
  RobotModel real = ur10WithTorch();
  const double delta = 1e-4;  // rad
  real.deviations.base_rot_rad = Eigen::Vector3d(0, 0, delta);
  const Program p = parseUrScript(
      "set_tcp(p[0, 0, 0.15, 0, 0, 0])\nmovej([0, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0])\n"
      "movej(p[-0.8, -0.2, 0.4, 2.2214415, 2.2214415, 0])\n",
      "frame.script");
  const ProgramCompensation c = compensateProgramReport(p, settingsFor(real));
  ASSERT_TRUE(c.ok()) << c.report.errors.front().message;
  ASSERT_EQ(c.report.targets.size(), 1u);
  const TargetReport& t = c.report.targets[0];
  EXPECT_NEAR(t.dx_mm, delta * -200, 1e-4);
  EXPECT_NEAR(t.dy_mm, -delta * -800, 1e-4);
  EXPECT_NEAR(t.dz_mm, 0, 1e-4);
}

TEST(UrScript, PosesAreInUrsBaseWhenTheRobotComesFromUrDescriptionsUrdf) {
  // ur_description's chain from its root ('world', = base_link) has DH frame 0 turned 180 deg
  // about z from UR's Base (docs/robot-format.md, "Frames"); URScript poses are in Base
  // (URScript manual: p[x, y, z, rx, ry, rz] in the robot's base frame). The same real arm (the
  // forum's factory calibration) read three ways (the bundled UR10, the URDF from 'base' and
  // from its root) gets the same corrections: the bundled one's frame is pinned by
  // PosesAreInTheControllersBaseFrameDhFrameZero.
  const UrDeltas deltas = readUrCalibrationConf(test::sourcePath("tests/data/urdf/ur_forum_calibration.conf"));
  const std::string urdf = test::sourcePath("tests/data/urdf/ur10.urdf");
  const Program p = parseUrScript(
      "set_tcp(p[0, 0, 0.15, 0, 0, 0])\nmovej([-1.5707963, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0])\n"
      "movel(p[-0.35, 0.7, 0.3, 3.1415927, 0, 0])\nmovel(p[0.05, 0.7, 0.3, 3.1415927, 0, 0])\n",
      "root.script");
  auto corrections = [&](const RobotDefinition& nominal) {
    const ProgramCompensation c = compensateProgramReport(p, settingsFor(modelFromUrDeltas(nominal, deltas)));
    EXPECT_TRUE(c.ok()) << (c.report.errors.empty() ? std::string() : c.report.errors.front().message);
    std::vector<Eigen::Vector3d> d;
    for (const TargetReport& t : c.report.targets) d.emplace_back(t.dx_mm, t.dy_mm, t.dz_mm);
    return d;
  };
  const std::vector<Eigen::Vector3d> bundled = corrections(test::loadBundled("ur10").nominal);
  ASSERT_EQ(bundled.size(), 2u);
  EXPECT_GT(bundled[0].norm(), 1.0);  // the factory calibration moves the TCP by millimetres
  for (const char* chain : {"base:tool0", ""}) {
    const std::vector<Eigen::Vector3d> d = corrections(readUrdfRobot(urdf, chain).nominal);
    ASSERT_EQ(d.size(), bundled.size()) << chain;
    for (size_t k = 0; k < d.size(); ++k) EXPECT_LT((d[k] - bundled[k]).norm(), 1e-4) << "chain '" << chain << "' target " << k;
  }
}

// The simulated UR controller: joint targets as given; a Cartesian movej to the IK solution
// nearest the current joints (the UR rule); movel/movec interpolated (LIN / CIRC) with the
// nominal IK; the real robot goes where those joints put it.
struct Execution {
  double path_mm = 0;   ///< largest distance of the real TCP from the intended path (movel/movec)
  double point_mm = 0;  ///< largest distance of the real TCP from an intended movej pose
};

// `inserted`: which motions of `commanded` are inserted points (the compensator's marks; the
// script read back does not have them).
Execution execute(const Program& commanded, const std::vector<bool>& inserted, const Program& intended, const RobotModel& controller,
                  const RobotModel& real) {
  Execution run;
  KinematicSolver nominal(controller), truth(real);
  Eigen::VectorXd q(6);
  Eigen::Isometry3d at_cmd = Eigen::Isometry3d::Identity(), at_intended = at_cmd;
  size_t i = 0;  // index in intended
  std::vector<PathSegment> cmd_run, intended_run;
  Eigen::VectorXd q_run;
  auto flush = [&] {
    if (cmd_run.empty()) return;
    const std::vector<Eigen::Isometry3d> samples = simulateExecution(controller, real, cmd_run, q_run, 0.2);
    run.path_mm = std::max(run.path_mm, maxPathDeviation(samples, intended_run));
    cmd_run.clear();
    intended_run.clear();
  };
  for (size_t n = 0; n < commanded.motions.size(); ++n) {
    const Motion& m = commanded.motions[n];
    const Eigen::Isometry3d target = m.target.kind == Target::Kind::kCartesian ? poseOf(m.target) : Eigen::Isometry3d::Identity();
    if (m.type == MotionType::kPtp) {
      flush();
      if (m.target.kind == Target::Kind::kAxis) {
        for (int k = 0; k < 6; ++k) q[k] = *m.target.axes[k];
      } else {
        const IkResult r = nominal.inverse(target, Configuration{}, q, IkOptions{});
        EXPECT_EQ(r.status, IkStatus::kOk);
        q = r.q;
        run.point_mm = std::max(run.point_mm, (truth.forward(q).translation() - poseOf(intended.motions[i].target).translation()).norm());
      }
      at_cmd = nominal.forward(q);
      at_intended = intended.motions[i].target.kind == Target::Kind::kAxis ? truth.forward(q) : poseOf(intended.motions[i].target);
      ++i;
      continue;
    }
    if (cmd_run.empty()) q_run = q;
    PathSegment s;
    s.type = m.type == MotionType::kCirc ? PathType::kCirc : PathType::kLin;
    s.T_world_start = at_cmd;
    s.T_world_end = target;
    if (m.aux) s.T_world_aux = poseOf(*m.aux);
    cmd_run.push_back(s);
    at_cmd = target;
    const IkResult r = nominal.inverse(target, Configuration{}, q, IkOptions{});
    EXPECT_EQ(r.status, IkStatus::kOk);
    q = r.q;
    if (!inserted[n]) {
      const Motion& im = intended.motions[i++];
      PathSegment is;
      is.type = s.type;
      is.T_world_start = at_intended;
      is.T_world_end = poseOf(im.target);
      if (im.aux) is.T_world_aux = poseOf(*im.aux);
      intended_run.push_back(is);
      at_intended = is.T_world_end;
    }
  }
  flush();
  return run;
}

// A movel with a time t split into pieces: each piece gets its share of t by its length, so
// the motion still takes t (a copied t would make each piece take all of it).
TEST(UrScript, ASplitMovelWithATimeGivesEachPieceItsShare) {
  const RobotModel controller = ur10WithTorch();
  SimulateOptions so;
  so.effects = {"geometric", "joint_compliance"};
  so.set_station = false;
  so.seed = 1;
  const std::string text =
      "def timed():\n  set_tcp(p[0, 0, 0.15, 0, 0, 0])\n  movej([0, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0])\n"
      "  movel(p[-0.7, -0.2, 0.3, 2.2214415, 2.2214415, 0], a=1.2, v=0.25, r=0)\n"
      "  movel(p[-0.7, 0.4, 0.5, 2.0, 2.4, 0.3], 1.2, 0.25, 6, 0)\nend\n";
  JobSettings s = settingsFor(perturbModel(controller, so));
  s.tol_mm = 0.01;
  const Program in = parseUrScript(text, "timed.script");
  const ProgramCompensation c = compensateProgramReport(in, s);
  ASSERT_TRUE(c.ok()) << c.report.errors.front().message;
  const Program back = parseUrScript(writeUrScript(c.program), "back.script");
  // the pieces of the timed movel: the motions after the untimed one
  std::vector<double> t, len;
  Eigen::Vector3d at = poseOf(back.motions[1].target).translation();
  for (size_t i = 2; i < back.motions.size(); ++i) {
    const UrScriptSource::Statement& st = back.urscript->statements[static_cast<size_t>(back.motions[i].statement_id)];
    t.push_back(st.duration_s);
    const Eigen::Vector3d to = poseOf(back.motions[i].target).translation();
    len.push_back((to - at).norm());
    at = to;
  }
  ASSERT_GE(t.size(), 2u) << "the timed movel was not split at tol 0.01 mm";
  double sum_t = 0;
  EXPECT_LT(test::durationShareError(t, len, 6.0, &sum_t), 2e-4);  // s; 4 decimals written
  EXPECT_NEAR(sum_t, 6.0, 1e-9);
}

TEST(UrScript, CompensatedScriptFollowsTheIntendedPathOnAPerturbedUr10) {
  const RobotModel controller = ur10WithTorch();
  const Program intended = parseUrScript(example(), "ur10_seam.script");
  for (const std::uint64_t seed : {1, 2, 3}) {
    SimulateOptions so;
    so.effects = {"geometric", "joint_compliance"};
    so.error_scale = 1;
    so.set_station = false;
    so.seed = seed;
    const RobotModel real = perturbModel(controller, so);
    JobSettings s = settingsFor(real);
    s.tol_mm = 0.05;
    const ProgramCompensation c = compensateProgramReport(intended, s);
    ASSERT_TRUE(c.ok()) << c.report.errors.front().where.str() << ": " << c.report.errors.front().message;
    // the written script, read back, is what the controller runs
    const std::string written = writeUrScript(c.program);
    const Program commanded = parseUrScript(written, "compensated.script");
    EXPECT_EQ(commanded.motions.size(), intended.motions.size() + static_cast<size_t>(c.report.points_added));
    std::vector<bool> inserted;
    for (const Motion& m : c.program.motions) inserted.push_back(m.inserted);
    ASSERT_EQ(inserted.size(), commanded.motions.size());
    const Execution comp = execute(commanded, inserted, intended, controller, real);
    const Execution as_is = execute(intended, std::vector<bool>(intended.motions.size(), false), intended, controller, real);
    std::printf("seed %d: path %.4f mm compensated (predicted %.4f), %.4f mm as programmed; movej poses %.5f / %.4f mm; %d points added\n",
                static_cast<int>(seed), comp.path_mm, c.report.max_error_after_mm, as_is.path_mm, comp.point_mm, as_is.point_mm,
                c.report.points_added);
    EXPECT_LE(comp.path_mm, s.tol_mm + 2e-3) << "seed " << seed;   // + the 7-decimal writing (0.1 um) and sampling
    EXPECT_LE(comp.point_mm, 1e-3) << "seed " << seed;             // movej poses: the digits written
    EXPECT_GT(as_is.path_mm, 0.3) << "seed " << seed;
    EXPECT_GT(as_is.point_mm, 0.3) << "seed " << seed;
    // only corrected numbers and inserted lines differ; the logic is where it was
    EXPECT_NE(written.find("  set_digital_out(0, True)  # arc on\n"), std::string::npos);
    EXPECT_NE(written.find("  global approach = p["), std::string::npos);
    EXPECT_NE(written.find("  movej(home, a=1.4, v=1.05)\n"), std::string::npos);
  }
}

TEST(UrScript, ExpressionsAreCorrectedInTheirOffsetAndRunTimePosesAreNamed) {
  RobotModel real = ur10WithTorch();
  real.deviations.base_mm = Eigen::Vector3d(0.3, -0.2, 0.1);
  // pose_trans(feature, p[offset]): the feature stays, the offset is corrected so that the
  // expression gives the compensated pose
  const std::string text =
      "set_tcp(p[0, 0, 0.15, 0, 0, 0])\n"
      "feature = p[-0.8, -0.2, 0.3, 0, 0, 0.3]\n"
      "movej(p[-0.7, -0.2, 0.4, 2.2214415, 2.2214415, 0])\n"
      "movej(pose_trans(feature, p[0.05, 0.02, 0.1, 3.1415927, 0, 0]))\n";
  const ProgramCompensation c = compensateProgramReport(parseUrScript(text, "f.script"), settingsFor(real));
  ASSERT_TRUE(c.ok()) << c.report.errors.front().message;
  const std::string out = writeUrScript(c.program);
  EXPECT_NE(out.find("feature = p[-0.8, -0.2, 0.3, 0, 0, 0.3]\n"), std::string::npos) << out;
  const Program back = parseUrScript(out, "f.script");
  // a pure base translation: every command is the target moved by -base_mm
  ASSERT_EQ(back.motions.size(), 2u);
  for (int k : {0, 1}) {
    const Eigen::Vector3d d = poseOf(back.motions[k].target).translation() - poseOf(parseUrScript(text, "f").motions[k].target).translation();
    EXPECT_LT((d + Eigen::Vector3d(0.3, -0.2, 0.1)).norm(), 1e-4) << k;  // 0.1 um digits
  }
  // a pose the controller computes at run time: a program the controller runs, so not refused:
  // the motion is kept as written and named in a warning
  const Program rt = parseUrScript("set_tcp(p[0, 0, 0.15, 0, 0, 0])\nmovej([0, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0])\n"
                                   "movel(pose_trans(get_actual_tcp_pose(), p[0, 0, 0.01, 0, 0, 0]))\n",
                                   "rt.script");
  const ProgramCompensation e = compensateProgramReport(rt, settingsFor(real));
  EXPECT_TRUE(e.report.errors.empty()) << e.report.errors.front().message;
  ASSERT_EQ(e.report.warnings.size(), 1u);
  EXPECT_EQ(e.report.warnings[0].where.str(), "rt.script:3:1");
  EXPECT_EQ(e.report.warnings[0].message,
            "movel left unchanged (not compensated): pose_trans(...) at rt.script:3:7 cannot be evaluated: "
            "get_actual_tcp_pose(...) is computed by the controller at run time (accura evaluates p[...], pose variables, "
            "pose_trans and pose_add); the position after it is not known");
  ASSERT_EQ(e.program.motions.size(), 2u);
  EXPECT_EQ(e.program.motions[1].target_problem, rt.motions[1].target_problem);
}

TEST(UrScript, AVariableAssignedAgainInTheLoopOfItsMotionIsNamed) {
  const Program p = parseUrScript(
      "set_tcp(p[0, 0, 0.15, 0, 0, 0])\nmovej([0, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0])\n"
      "p1 = p[-0.7, -0.2, 0.3, 2.2214415, 2.2214415, 0]\n"
      "while True:\n  movel(p1)\n  p1 = p[-0.7, -0.1, 0.3, 2.2214415, 2.2214415, 0]\nend\nmovel(p1)\n",
      "loop.script");
  ASSERT_EQ(p.motions.size(), 3u);
  EXPECT_EQ(p.motions[1].target_problem,
            "'p1' is assigned again at loop.script:6:3 in the loop that runs this motion: its value on the next pass is not the one it has here");
  // after the loop: the value before it (no pass) or one a pass assigned (a break may come
  // before the assignment): not known
  EXPECT_EQ(p.motions[2].target_problem,
            "'p1' is assigned inside the while at loop.script:4:1: after it, its value depends on the way the program ran");
}

TEST(UrScript, VariablesFollowBranchesFunctionsAndLocalScope) {
  // a branch starts with the values the if was entered with, and after it a variable a branch
  // assigned is not known; a function's assignment of a program variable runs where it is
  // called; a local of a function hides the program variable of its name only inside it
  const std::string text = "def prog():\n"
                           "  set_tcp(p[0,0,0.1,0,0,0])\n"
                           "  def pick():\n    target = p[0.5,0.3,0.4,0,3.14,0]\n  end\n"     // assigns a program variable
                           "  def show():\n    local a = p[0.5,0.9,0.4,0,3.14,0]\n    textmsg(a)\n  end\n"
                           "  a = p[0.5,0.1,0.4,0,3.14,0]\n"
                           "  target = p[0.5,0.2,0.4,0,3.14,0]\n"
                           "  movel(a)\n"                                                    // 0: a, y 100
                           "  if x:\n    a = p[0.5,0.15,0.4,0,3.14,0]\n    movel(a)\n"       // 1: y 150
                           "  else:\n    movel(a)\n  end\n"                                // 2: y 100 (the else)
                           "  movel(a)\n"                                                    // 3: either
                           "  movel(target)\n"                                               // 4: y 200
                           "  pick()\n  movel(target)\n"                                    // 5: pick's
                           "end\n";
  const Program p = parseUrScript(text, "vars.script");
  ASSERT_EQ(p.motions.size(), 6u);
  const std::vector<double> y = {100, 150, 100, -1, 200, -1};
  for (size_t k = 0; k < y.size(); ++k) {
    if (y[k] < 0) {
      EXPECT_NE(p.motions[k].target_problem, "") << k;
    } else {
      ASSERT_EQ(p.motions[k].target_problem, "") << k;
      EXPECT_NEAR(p.motions[k].target.xyzAbc().y_mm, y[k], 1e-9) << k;
    }
  }
  EXPECT_EQ(p.motions[3].target_problem, "'a' is assigned inside the if at vars.script:13:3: after it, its value depends on the way the program ran");
  EXPECT_EQ(p.motions[5].target_problem,
            "'target' is assigned by pick (at vars.script:3:3), called at vars.script:21:3: its value after the call is not followed");
}

TEST(UrScript, AFunctionThatCallsOneThatSetsTheTcpOrAVariableSetsThemToo) {
  // f only calls g; g sets the TCP and assigns a program variable: on the controller a call of
  // f runs g's set_tcp and assignment, so after f() the tool and the variable are not the text's
  const std::string text = "def prog():\n"
                           "  global wp = p[0.5,0.1,0.4,0,3.14,0]\n"
                           "  def g():\n    set_tcp(p[0,0.05,0.25,0,0,0])\n    wp = p[0.5,0.2,0.4,0,3.14,0]\n  end\n"
                           "  def f():\n    g()\n  end\n"
                           "  set_tcp(p[0,0,0.15,0,0,0])\n"
                           "  movel(wp)\n"     // 0: tool 0.15, y 100
                           "  f()\n"
                           "  movel(wp)\n"     // 1: g's tool and value
                           "end\n";
  const Program p = parseUrScript(text, "calls.script");
  ASSERT_EQ(p.motions.size(), 2u);
  ASSERT_TRUE(p.motions[0].tool.known());
  EXPECT_NEAR(p.motions[0].tool.value->z_mm, 150, 1e-9);
  EXPECT_EQ(p.motions[0].target_problem, "");
  EXPECT_NEAR(p.motions[0].target.xyzAbc().y_mm, 100, 1e-9);
  EXPECT_TRUE(p.motions[1].tool.run_time);
  EXPECT_FALSE(p.motions[1].tool.known());
  EXPECT_EQ(p.motions[1].tool.note, "the function f (calls.script:7:3) calls set_tcp: the tool after the call is not followed");
  EXPECT_EQ(p.motions[1].target_problem,
            "'wp' is assigned by f (at calls.script:7:3), called at calls.script:12:3: its value after the call is not followed");
}

TEST(UrScript, AFunctionDefinedAfterItsCallerIsFollowedThroughTheCall) {
  // f calls g, which the text defines after f: g exists when f() runs, so f() sets g's TCP
  const std::string text = "def prog():\n"
                           "  global wp = p[0.5,0.1,0.4,0,3.14,0]\n"
                           "  def f():\n    g()\n  end\n"
                           "  def g():\n    set_tcp(p[0,0.05,0.25,0,0,0])\n    wp = p[0.5,0.2,0.4,0,3.14,0]\n  end\n"
                           "  set_tcp(p[0,0,0.15,0,0,0])\n"
                           "  f()\n"
                           "  movel(wp)\n"
                           "end\n";
  const Program p = parseUrScript(text, "order.script");
  ASSERT_EQ(p.motions.size(), 1u);
  EXPECT_TRUE(p.motions[0].tool.run_time);
  EXPECT_EQ(p.motions[0].tool.note, "the function g (order.script:6:3), which f calls, calls set_tcp: the tool after the call is not followed");
  EXPECT_EQ(p.motions[0].target_problem,
            "'wp' is assigned by g (at order.script:6:3), which f calls, called at order.script:11:3: its value after the call is not followed");
}

TEST(UrScript, ALoopsNextPassAndAFunctionSeeTheToolAndValuesOfTheRun) {
  const std::string a = "p[0.5,0.1,0.4,0,3.14,0]";
  const std::string text = "def prog():\n"
                           "  set_tcp(p[0,0,0.1,0,0,0])\n"
                           "  pose = " + a + "\n"
                           "  def f():\n    movel(pose)\n  end\n"                       // 0: the caller's tool and pose
                           "  while x:\n    movel(" + a + ")\n    set_tcp(p[0,0,0.3,0,0,0])\n  end\n"  // 1: next pass: 0.3
                           "  f()\n"
                           "end\n";
  const Program p = parseUrScript(text, "run.script");
  ASSERT_EQ(p.motions.size(), 2u);
  EXPECT_EQ(p.motions[0].target_problem, "in the function f, 'pose' has the value it has where the function is called");
  EXPECT_TRUE(p.motions[0].tool.run_time);
  EXPECT_EQ(p.motions[0].tool.note, "a function runs with the tool of the place it is called from until it calls set_tcp");
  EXPECT_TRUE(p.motions[1].tool.run_time);
  EXPECT_EQ(p.motions[1].tool.note, "set_tcp is called later in the while at run.script:7:3: the next pass runs this motion with the new tool");
}

TEST(UrScript, ConvertCarriesTheMotionModelOrRefusesNamingTheLine) {
  const std::string dir = test::tempDir("ur_convert");
  test::writeText(dir + "/seam.script", example());
  // the example holds logic (set_payload, set_digital_out): XML carries it (every line, see
  // test_convert.cpp), KRL cannot: refused, naming the first line
  ASSERT_EQ(test::runAccuraIn(dir, "convert --in seam.script --out seam.xml").code, 0);
  const test::CliRun r = test::runAccuraIn(dir, "convert --in seam.script --out seam.src");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("seam.script:6:3: cannot convert to KRL: the URScript statement 'set_payload(1.2)' is not a motion, set_tcp or "
                       "pose assignment, and the conversion carries the motion model only (2 more such statement(s)); convert "
                       "--drop-unconvertible leaves such statements out and lists them\n"),
            std::string::npos)
      << r.err;
  // motions only: URScript -> XML -> URScript keeps every pose (to the 7 decimals written)
  const std::string motions =
      "def m():\n  set_tcp(p[0.0, 0.0, 0.15, 0.0, 0.0, 0.0])\n  movej([0, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0])\n"
      "  a = p[-0.7, -0.35, 0.3, 2.2214415, 2.2214415, 0.0]\n  movel(a, v=0.05)\n"
      "  movec(p[-0.78, -0.27, 0.3, 2.2214415, 2.2214415, 0.0], p[-0.86, -0.35, 0.3, 2.2214415, 2.2214415, 0.0], v=0.01, r=0.002)\n"
      "  movel(pose_trans(a, p[0, 0, -0.05, 0, 0, 0]))\nend\n";
  test::writeText(dir + "/m.script", motions);
  const test::CliRun a = test::runAccuraIn(dir, "convert --in m.script --out m.xml");
  ASSERT_EQ(a.code, 0) << a.err;
  const test::CliRun b = test::runAccuraIn(dir, "convert --in m.xml --out m2.script");
  ASSERT_EQ(b.code, 0) << b.err;
  const Program p1 = parseUrScript(motions, "m.script");
  const Program p2 = readUrScript(dir + "/m2.script");
  ASSERT_EQ(p2.motions.size(), p1.motions.size());
  for (size_t k = 0; k < p1.motions.size(); ++k) {
    EXPECT_EQ(p2.motions[k].type, p1.motions[k].type);
    if (p1.motions[k].target.kind == Target::Kind::kAxis) continue;
    EXPECT_LT((poseOf(p2.motions[k].target).translation() - poseOf(p1.motions[k].target).translation()).norm(), 1e-3);
    EXPECT_LT((poseOf(p2.motions[k].target).linear() - poseOf(p1.motions[k].target).linear()).norm(), 1e-6);
  }
  EXPECT_NEAR(*p2.motions[2].approximation_value, 2, 1e-9);
  EXPECT_NEAR(*p2.motions[1].vel_m_s, 0.05, 1e-12);
  ASSERT_TRUE(p2.motions[1].tool.value.has_value());
  EXPECT_NEAR(p2.motions[1].tool.value->z_mm, 150, 1e-9);
  // KRL with logic ($OUT) into URScript: refused naming the KRL line
  const test::CliRun k = test::runAccuraIn(dir, "convert --in " + test::sourcePath("examples/seam.src") + " --out s.script");
  EXPECT_NE(k.code, 0);
  EXPECT_NE(k.err.find("examples/seam.src:45: cannot convert to URScript: the KRL statement '$OUT[17]=TRUE' is not a motion, frame or speed"),
            std::string::npos)
      << k.err;
  // ... and says which option converts it without such statements
  EXPECT_NE(k.err.find("URScript output carries the motion model only (convert --drop-unconvertible leaves such statements out and lists "
                       "them)"),
            std::string::npos)
      << k.err;
}

// convert's summary counts the statements it carries verbatim: the bundled example's
// set_payload and two set_digital_out, which the XML holds as <passthrough> without a role
// (before: "0 other statements carried verbatim", the URScript reader keeps them in its source,
// not in the program's pass-through list).
TEST(UrScript, ConvertCountsTheStatementsItCarries) {
  const std::string dir = test::tempDir("ur_convert_count");
  test::writeText(dir + "/seam.script", bundledExample());
  const test::CliRun x = test::runAccuraIn(dir, "convert --in seam.script --out seam.xml");
  ASSERT_EQ(x.code, 0) << x.err;
  EXPECT_EQ(x.out, "wrote seam.xml\naccura convert: 8 motions, 3 other statements carried verbatim from seam.script\n");
  const std::string xml = test::readText(dir + "/seam.xml");
  std::vector<std::string> carried;
  for (size_t at = xml.find("<passthrough language=\"URScript\" line="); at != std::string::npos;
       at = xml.find("<passthrough language=\"URScript\" line=", at + 1)) {
    const size_t text = xml.find('>', at) + 1;
    carried.push_back(xml.substr(text, xml.find("</passthrough>", text) - text));
  }
  EXPECT_EQ(carried, (std::vector<std::string>{"  set_payload(1.2)", "  set_digital_out(0, True)  # arc on",
                                               "  set_digital_out(0, False)  # arc off"}));
  // the same count into URScript, from the script and from the XML; none into KRL with
  // --drop-unconvertible (the three dropped)
  const test::CliRun s = test::runAccuraIn(dir, "convert --in seam.script --out copy.script");
  EXPECT_EQ(s.out, "wrote copy.script\naccura convert: 8 motions, 3 other statements carried verbatim from seam.script\n");
  const test::CliRun back = test::runAccuraIn(dir, "convert --in seam.xml --out back.script");
  EXPECT_EQ(back.out, "wrote back.script\naccura convert: 8 motions, 3 other statements carried verbatim from seam.xml\n");
  const test::CliRun krl = test::runAccuraIn(dir, "convert --in seam.script --out seam.src --drop-unconvertible");
  EXPECT_EQ(krl.out, "wrote seam.src\nwrote seam.dat\naccura convert: 8 motions, 0 other statements carried verbatim, 3 dropped from seam.script\n");
}

// The golden files (tests/golden/urscript/README.md): the example compensated with the real
// UR10's calibrated model, and the XML weld seam converted to URScript, byte for byte; the
// converted poses are the XML targets moved into the Base frame ($BASE * target, computed here).
TEST(UrScript, GoldenFiles) {
  const std::string g = test::sourcePath("tests/golden/urscript/");
  const std::string dir = test::tempDir("ur_golden");
  for (const char* f : {"ur10_calibrated.xml", "ur10_seam.script"}) test::writeText(dir + "/" + f, test::readText(g + f));
  test::writeText(dir + "/weld_seam.xml", test::readText(test::sourcePath("tests/golden/xml/weld_seam.xml")));
  const test::CliRun c = test::runAccuraIn(dir, "compensate --robot ur10_calibrated.xml --in ur10_seam.script --out expected "
                                                "--base 507.9274,-3567.8484,-1224.8883,20.00939,-0.16910,0.00450 --json expected/report.json");
  ASSERT_EQ(c.code, 0) << c.err;
  EXPECT_EQ(test::readText(dir + "/expected/ur10_seam.script"), test::readText(g + "expected/ur10_seam.script"));
  EXPECT_EQ(test::readText(dir + "/expected/report.json"), test::readText(g + "expected/report.json"));
  EXPECT_EQ(test::readText(dir + "/ur10_seam.script"), example());  // the input untouched
  // the XML carries the KRL program's logic ($OUT, WAIT, IF) as pass-through: URScript written from
  // the motion model cannot hold it, so the conversion is refused at the first such statement ...
  const test::CliRun refused = test::runAccuraIn(dir, "convert --in weld_seam.xml --out weld_seam.script");
  EXPECT_EQ(refused.code, 1);
  EXPECT_NE(refused.err.find("weld_seam.xml:26:5: cannot convert to URScript: the KRL statement '$OUT[17]=TRUE' is not a motion"),
            std::string::npos)
      << refused.err;
  EXPECT_NE(refused.err.find("(convert --drop-unconvertible leaves such statements out and lists them)"), std::string::npos) << refused.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/weld_seam.script"));
  // ... or, asked to, it keeps the motions and lists every pass-through statement it leaves out
  const std::string xml_text = test::readText(dir + "/weld_seam.xml");
  // (a KRL comment, ';' or in hex 3b, becomes a URScript comment: not dropped)
  size_t carried = 0;
  for (size_t at = xml_text.find("<passthrough language=\"KRL\""); at != std::string::npos;
       at = xml_text.find("<passthrough language=\"KRL\"", at + 1)) {
    const size_t text = xml_text.find('>', at) + 1;
    const size_t first = xml_text.find_first_not_of(' ', text);
    if (xml_text[first] != ';' && xml_text.compare(first, 2, "3b") != 0) ++carried;
  }
  const test::CliRun v = test::runAccuraIn(dir, "convert --in weld_seam.xml --out weld_seam.script --drop-unconvertible");
  ASSERT_EQ(v.code, 0) << v.err;
  size_t dropped = 0;
  for (size_t at = v.err.find(": dropped '"); at != std::string::npos; at = v.err.find(": dropped '", at + 1)) ++dropped;
  EXPECT_EQ(dropped, carried);
  EXPECT_EQ(test::readText(dir + "/weld_seam.script"), test::readText(g + "weld_seam.script"));
  // without its logic lines the XML converts as the .src would: the INI housekeeping and the
  // .dat's declarations (EXT BAS, DECL) are the motion model's, not statements URScript loses
  const auto logic = [](const std::string& line) {
    for (const char* l : {"$OUT[", "WAIT SEC", ">IF ", ">ELSE<", ">ENDIF<"})
      if (line.find(l) != std::string::npos) return true;
    return false;
  };
  std::string motions_only;
  for (size_t b = 0; b < xml_text.size();) {
    const size_t e = std::min(xml_text.find('\n', b), xml_text.size());
    const std::string line = xml_text.substr(b, e - b);
    if (!logic(line)) motions_only += line + "\n";
    b = e + 1;
  }
  test::writeText(dir + "/motions_only.xml", motions_only);
  const test::CliRun m = test::runAccuraIn(dir, "convert --in motions_only.xml --out motions_only.script");
  ASSERT_EQ(m.code, 0) << m.err;
  const Program xml = readProgram(dir + "/weld_seam.xml");
  const Program ur = readUrScript(dir + "/weld_seam.script");
  ASSERT_EQ(ur.motions.size(), xml.motions.size());
  for (size_t k = 0; k < xml.motions.size(); ++k) {
    const Motion& a = xml.motions[k];
    const Motion& b = ur.motions[k];
    EXPECT_EQ(b.target.name, a.target.name) << k;
    if (a.target.kind == Target::Kind::kAxis) {
      for (int j = 0; j < 6; ++j) EXPECT_NEAR(*b.target.axes[j], *a.target.axes[j], 1e-5) << k;
      continue;
    }
    const Eigen::Isometry3d want = toIsometry(*a.base.value) * poseOf(a.target);
    EXPECT_LT((poseOf(b.target).translation() - want.translation()).norm(), 1e-4) << k;  // 0.1 um written
    EXPECT_LT((poseOf(b.target).linear() - want.linear()).norm(), 1e-6) << k;
  }
}

// A URScript program needs the model of a UR arm: with a KUKA model it is refused (before, it was
// "compensated" on the KR 16's geometry without a word); the UR10 and a UR5 URDF are UR arms.
TEST(UrScript, AModelThatIsNoUniversalRobotsArmIsRefused) {
  const std::string dir = test::tempDir("ur_not_ur");
  test::writeText(dir + "/seam.script", example());
  const test::CliRun k = test::runAccuraIn(dir, "compensate --robot kuka_kr16 --in seam.script --out out");
  EXPECT_EQ(k.code, 1);
  EXPECT_NE(k.err.find("seam.script: expected a Universal Robots arm for a URScript program (joints 2, 3 and 4 parallel, no "
                       "spherical wrist: the controller's shoulder/elbow/wrist branches are that geometry's), found 'KUKA KR 16'"),
            std::string::npos)
      << k.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/out/seam.script"));
  EXPECT_EQ(test::runAccuraIn(dir, "compensate --robot abb_irb120 --in seam.script --out out").code, 1);
  const test::CliRun u = test::runAccuraIn(dir, "compensate --robot ur10 --in seam.script --out out");
  EXPECT_EQ(u.code, 0) << u.err;
  // check follows the same rule (requireArmForProgram): refused with the KUKA model, in the UR10's cell
  const std::string cell = test::sourcePath("tests/data/urscript/ur10_table_cell.xml");
  const test::CliRun c = test::runAccuraIn(dir, "check --robot kuka_kr16 --cell " + cell + " --in seam.script");
  EXPECT_EQ(c.code, 1);
  EXPECT_NE(c.err.find("seam.script: expected a Universal Robots arm for a URScript program"), std::string::npos) << c.err;
  EXPECT_NE(c.err.find("found 'KUKA KR 16'"), std::string::npos) << c.err;
  // and a program converted from URScript into XML carries its lines: the same rule
  ASSERT_EQ(test::runAccuraIn(dir, "convert --in seam.script --out seam.xml").code, 0);
  const test::CliRun x = test::runAccuraIn(dir, "compensate --robot kuka_kr16 --in seam.xml --out out");
  EXPECT_EQ(x.code, 1);
  EXPECT_NE(x.err.find("seam.xml: expected a Universal Robots arm for a URScript program"), std::string::npos) << x.err;
}

// batch picks up .script files; check runs the script in its cell: the smallest clearance
// against its analytic value (tests/data/urscript/ur10_table_cell.xml: sqrt(30^2 + 100^2) - 10).
TEST(UrScript, BatchAndCheckInTheCell) {
  const std::string dir = test::tempDir("ur_batch");
  std::filesystem::create_directories(dir + "/in/cell2");
  test::writeText(dir + "/in/cell2/seam.script", example());
  const test::CliRun b = test::runAccuraIn(dir, "batch --robot ur10 --in in --out out --jobs 1");
  ASSERT_EQ(b.code, 0) << b.err;
  EXPECT_EQ(test::readText(dir + "/out/cell2/seam.script"), example());  // the nominal robot: nothing to correct
  const test::CliRun c = test::runAccuraIn(dir, "check --robot ur10 --cell " + test::sourcePath("tests/data/urscript/ur10_table_cell.xml") +
                                                    " --in " + test::sourcePath("tests/golden/urscript/ur10_seam.script") + " --json check.json");
  ASSERT_EQ(c.code, 0) << c.err;
  EXPECT_NE(c.out.find("smallest clearance 94.403 mm"), std::string::npos) << c.out;
  EXPECT_NEAR(std::sqrt(30.0 * 30.0 + 100.0 * 100.0) - 10, 94.403, 5e-4);
}

// The README's example: the real UR10 calibrated from its laser-tracker data (Series_B of the
// ipa data set, geometric + joint compliance), then the bundled URScript seam compensated
// with it. The robot stands where the tracker found it (--base: the calibrated base), so the
// corrections are the arm's own errors: about 0.5 mm (the calibrated model's RMS against the
// nominal one on this data is 1.1 mm at the T-Mac, 0.4 mm after: the same order).
TEST(UrScript, RealUr10CalibratedThenTheExampleCompensated) {
  const std::string dir = test::tempDir("ur_real");
  const std::string data = test::sourcePath("tests/data/ipa-robot-accuracy/series_b_joint_configurations.csv");
  const test::CliRun id = test::runAccuraIn(dir, "identify --robot ur10 --map " + test::sourcePath("docs/mappings/ipa_robot_accuracy.map") +
                                                     " --data " + data +
                                                     " --tool 0.0868,0,109,90,0,0 --params geometric,joint_compliance --out ur10_calibrated.xml");
  ASSERT_EQ(id.code, 0) << id.err;
  const XyzAbc b = toXyzAbc(readRobotFile(dir + "/ur10_calibrated.xml").T_world_base());
  const std::string base = formatMm(b.x_mm) + "," + formatMm(b.y_mm) + "," + formatMm(b.z_mm) + "," + formatDeg(b.a_deg) + "," +
                           formatDeg(b.b_deg) + "," + formatDeg(b.c_deg);
  test::writeText(dir + "/ur10_seam.script", bundledExample());
  const test::CliRun c = test::runAccuraIn(dir, "compensate --robot ur10_calibrated.xml --in ur10_seam.script --out out --base " + base +
                                                    " --json out/report.json");
  ASSERT_EQ(c.code, 0) << c.err;
  const nlohmann::json report = nlohmann::json::parse(test::readText(dir + "/out/report.json"));
  const nlohmann::json t = report["totals"];
  EXPECT_EQ(t["targets_corrected"], 7);
  // the bundled seam lies inside the joint ranges Series_B covers: no extrapolation warning
  for (const auto& w : report["warnings"]) EXPECT_EQ(w["message"].get<std::string>().find("outside the joint ranges"), std::string::npos) << w;
  EXPECT_EQ(c.err.find("outside the fitted joint ranges"), std::string::npos) << c.err;
  EXPECT_GT(t["max_correction_mm"].get<double>(), 0.3);
  EXPECT_LT(t["max_correction_mm"].get<double>(), 1.5);
  EXPECT_GT(t["max_error_uncompensated_mm"].get<double>(), 0.3);
  EXPECT_LE(t["max_error_after_mm"].get<double>(), 0.05);
  // only the p[...] numbers and the inserted lines differ
  const Program in = parseUrScript(bundledExample(), "in");
  const Program out = readUrScript(dir + "/out/ur10_seam.script");
  EXPECT_EQ(out.motions.size(), in.motions.size() + t["points_added"].get<size_t>());
  EXPECT_EQ(out.urscript->others.size(), in.urscript->others.size());
  for (size_t k = 0; k < in.urscript->others.size(); ++k) EXPECT_EQ(out.urscript->others[k].text, in.urscript->others[k].text);
}

// A NUL byte in a comment or a string was read past (the comment and string scanners skipped
// it); anywhere in the file it is the error, at its line and column.
TEST(UrScript, ANulByteInACommentOrAStringIsAnError) {
  const std::string nul(1, '\0');
  const std::string msg = "expected a URScript text file, found a NUL byte (binary file?)";
  EXPECT_EQ(errorOf("def f():\n  # a" + nul + "b\n  movel(p[0.1, 0.2, 0.3, 0, 0, 0])\nend\n"), "bad.script:2:6: " + msg);
  EXPECT_EQ(errorOf("def f():\n  popup(\"a" + nul + "b\")\nend\n"), "bad.script:2:11: " + msg);
}

// Errors quoted the offending text whole; every quoted excerpt is at most 80 bytes (its first
// 77 and "...").
TEST(UrScript, AnErrorQuotesAtMost80BytesOfTheText) {
  const std::string name(5000, 'z');
  EXPECT_EQ(errorOf("movel(p[0.1, 0.2, 0.3, 0, 0, 0], " + name + "=1)\n"),
            "bad.script:1:34: expected an argument of movel (pose, a, v, t, r), found '" + name.substr(0, 77) + "...'");
  const std::string digits = "1" + std::string(3000, '0');
  EXPECT_EQ(errorOf("movej(p[" + digits + ", 0, 0, 0, 0, 0])\n"), "bad.script:1:9: expected a finite number, found '" + digits.substr(0, 77) + "...'");
  std::string five = "p[" + std::string(200, '1') + ", 0, 0, 0, 0]";
  EXPECT_EQ(errorOf("movel(" + five + ")\n"), "bad.script:1:7: expected p[x, y, z, rx, ry, rz] with 6 numbers, found 5 in '" + five.substr(0, 77) + "...'");
}

// pose_trans nested 20000 deep, or a chain of 100000 pose variables each built on the one
// before, overflowed the stack (a call per level): a crash, not an error. Both are bounded.
TEST(UrScript, PosesNestedOrChainedBeyondABoundAreAnErrorNotACrash) {
  auto nested = [](int n) {
    std::string s;
    for (int k = 0; k < n; ++k) s += "pose_trans(p[0, 0, 0.001, 0, 0, 0], ";
    s += "p[0.1, 0.2, 0.3, 0, 0, 0]";
    return s + std::string(static_cast<size_t>(n), ')');
  };
  const Program p = parseUrScript("movel(" + nested(100) + ")\n", "ok.script");
  ASSERT_EQ(p.motions.size(), 1u);
  EXPECT_NEAR(p.motions[0].target.xyzAbc().z_mm, 400.0, 1e-9);  // 300 + 100 x 1 mm
  // (column 3607: the 101st pose_trans, after 100 x 36 bytes from column 7)
  EXPECT_EQ(errorOf("movel(" + nested(20000) + ")\n"), "bad.script:1:3607: expected pose_trans/pose_add nested at most 100 deep, found deeper nesting");
  std::string chain = "q0 = p[0.1, 0.2, 0.3, 0, 0, 0]\n";
  for (int k = 1; k <= 1000; ++k) chain += "q" + std::to_string(k) + " = pose_trans(q" + std::to_string(k - 1) + ", p[0, 0, 0.0001, 0, 0, 0])\n";
  const Program c = parseUrScript(chain + "movel(q1000)\n", "ok.script");
  ASSERT_EQ(c.motions.size(), 1u);
  EXPECT_NEAR(c.motions[0].target.xyzAbc().z_mm, 400.0, 1e-9);  // 300 + 1000 x 0.1 mm
  for (int k = 1001; k <= 100000; ++k) chain += "q" + std::to_string(k) + " = pose_trans(q" + std::to_string(k - 1) + ", p[0, 0, 0.0001, 0, 0, 0])\n";
  EXPECT_EQ(errorOf(chain + "movel(q100000)\n"),
            "bad.script:1002:9: expected a pose built of at most 1000 pose_trans/pose_add (through the variables it uses), found a deeper one");
}

// An empty .script (0 bytes, blanks, or comments only) was accepted, and compensate and convert
// wrote an empty program with exit 0 (an empty .mod or .src is an error). It is an error at
// 1:1; a script of statements without a motion is a program (read, 0 motions).
TEST(UrScript, AScriptWithoutAStatementIsAnError) {
  const std::string want = "bad.script:1:1: expected a URScript program (def name(): ... end, or its statements such as movel(...)), found an empty file";
  EXPECT_EQ(errorOf(""), want);
  EXPECT_EQ(errorOf(" \r\n\t\n\n"), want);
  EXPECT_EQ(errorOf("# exported by PolyScope\n\n  # nothing else\n"), want + " (only comments and blank lines)");
  const Program io = parseUrScript("set_digital_out(1, True)\n", "io.script");
  EXPECT_EQ(io.motions.size(), 0u);
  // the command line: exit 1, the error, nothing written
  const std::string dir = test::tempDir("ur_empty");
  test::writeText(dir + "/empty.script", "");
  const test::CliRun c = test::runAccuraIn(dir, "convert --in empty.script --out out/empty.mod");
  EXPECT_EQ(c.code, 1);
  EXPECT_NE(c.err.find("empty.script:1:1: expected a URScript program"), std::string::npos) << c.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/out/empty.mod"));
  const test::CliRun k = test::runAccuraIn(dir, "compensate --robot ur10 --in empty.script --out comp");
  EXPECT_EQ(k.code, 1);
  EXPECT_NE(k.err.find("empty.script:1:1: expected a URScript program"), std::string::npos) << k.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/comp/empty.script"));
}

}  // namespace
}  // namespace accura::postproc
