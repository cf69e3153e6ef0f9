// ABB RAPID (rapid.h): the motion model read from a module (units, frames, quaternions,
// Offs/RelTool, confdata), untouched modules written back byte for byte, malformed modules
// reported as file:line:column with expected/found, ConfJ/ConfL as the controller treats
// them, and the acceptance test of issue 12: the compensated module, executed by a simulated
// nominal ABB controller on a perturbed IRB 120, follows the intended path within the
// tolerance.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/ik.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/simulate.h"
#include "accura/postproc/batch.h"
#include "accura/postproc/execution.h"
#include "accura/postproc/job.h"
#include "accura/postproc/path.h"
#include "accura/postproc/program_io.h"
#include "accura/postproc/rapid.h"
#include "test_util.h"

namespace accura::postproc {
namespace {

using namespace accura::calib;

std::string example() { return test::readText(test::sourcePath("examples/irb120_seam.mod")); }

// R of a unit quaternion (w, x, y, z), written out from its definition (not Eigen's).
Eigen::Matrix3d quatMatrix(double w, double x, double y, double z) {
  Eigen::Matrix3d R;
  R << 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),  //
      2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),   //
      2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y);
  return R;
}

Eigen::Isometry3d poseOf(const Target& t) { return toIsometry(t.xyzAbc()); }

// The IRB 120 with the example's torch (tooldata torch: 150 mm along z).
RobotModel irb120WithTorch() {
  RobotModel m = test::loadBundled("abb_irb120");
  m.nominal.T_flange_tcp = toIsometry({0, 0, 150, 0, 0, 0});
  return m;
}

JobSettings settingsFor(const RobotModel& real) {
  JobSettings s;
  s.calibrated = real;
  s.tol_mm = 0.05;
  return s;
}

TEST(Rapid, ReadsTheMotionModelInTheWorkObject) {
  const Program p = parseRapid(example(), "irb120_seam.mod");
  EXPECT_EQ(p.name, "irb120_seam");
  ASSERT_EQ(p.motions.size(), 8u);
  const Motion& home = p.motions[0];
  EXPECT_EQ(home.type, MotionType::kPtp);
  EXPECT_EQ(home.target.kind, Target::Kind::kAxis);
  EXPECT_EQ(*home.target.axes[4], 30.0);
  EXPECT_TRUE(home.start_unknown);
  // MoveJ p10: the pose in the work object "table", the torch, confdata
  const Motion& j = p.motions[1];
  EXPECT_EQ(j.type, MotionType::kPtp);
  EXPECT_EQ(j.target.name, "p10");
  EXPECT_LT((poseOf(j.target).translation() - Eigen::Vector3d(40, 60, 120)).norm(), 1e-12);
  EXPECT_LT((poseOf(j.target).linear() - quatMatrix(0, 0, 1, 0)).norm(), 1e-12);
  ASSERT_TRUE(j.target.abb_conf.has_value());
  EXPECT_EQ(*j.target.abb_conf, (std::array<int, 4>{-1, 0, -1, 0}));
  ASSERT_TRUE(j.tool.value && j.base.value);
  EXPECT_LT((toIsometry(*j.tool.value).translation() - Eigen::Vector3d(0, 0, 150)).norm(), 1e-12);
  EXPECT_LT((toIsometry(*j.base.value).translation() - Eigen::Vector3d(300, -150, 100)).norm(), 1e-12);
  EXPECT_EQ(home.base.source, FrameSetting::Source::kNull);  // no \WObj: wobj0 (world)
  EXPECT_TRUE(j.approximation.size() == 1 && *j.approximation_value == 20);  // z20
  // speeds (mm/s -> m/s) and zones
  EXPECT_DOUBLE_EQ(*p.motions[2].vel_m_s, 0.2);
  EXPECT_TRUE(p.motions[2].approximation.empty());  // fine
  EXPECT_DOUBLE_EQ(*p.motions[3].approximation_value, 1.0);  // z1
  // MoveC p40, p50: circle point first
  EXPECT_EQ(p.motions[4].type, MotionType::kCirc);
  EXPECT_EQ(p.motions[4].aux->name, "p40");
  EXPECT_EQ(p.motions[4].target.name, "p50");
  // Offs(p60,0,0,100): p60 moved 100 mm along the work object's z
  EXPECT_LT((poseOf(p.motions[6].target).translation() - Eigen::Vector3d(40, 180, 120)).norm(), 1e-12);
  EXPECT_EQ(p.motions[6].target.value_id, -1);
  EXPECT_TRUE(p.motions[2].conf_monitored);
  // everything else is carried as RAPID text, in place
  std::vector<std::string> texts;
  for (const PassThrough& s : p.passthrough) texts.push_back(s.text);
  ASSERT_EQ(p.passthrough.size(), 6u);
  EXPECT_EQ(p.passthrough[0].text, "  CONST jointtarget home := [[0,0,0,0,30,0],[9E9,9E9,9E9,9E9,9E9,9E9]];");
  EXPECT_EQ(p.passthrough[0].section, PassThrough::Section::kData);
  EXPECT_EQ(p.passthrough[2].text, "    SetDO do_torch, 1;  ! arc on");
  EXPECT_EQ(p.passthrough[2].section, PassThrough::Section::kBody);
  EXPECT_EQ(p.passthrough[2].before_motion, 3u);
  EXPECT_EQ(p.passthrough[5].text, "    seams := seams + 1;");
  EXPECT_EQ(p.passthrough[5].before_motion, 7u);
}

TEST(Rapid, QuaternionsOffsAndRelToolAgainstTheirDefinitions) {
  // a quaternion written with 4 digits (norm 0.99998: normalised), RelTool about the tool's
  // axes, x then y then z, and a routine-scope declaration hiding the module's
  const std::string text =
      "MODULE m\n"
      "  CONST robtarget a := [[300,0,400],[0.7071,0,0.7071,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  PROC main()\n"
      "    CONST robtarget a := [[350,10,400],[0.5,0.5,0.5,0.5],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "    MoveL RelTool(a, 10, 20, 30 \\Rx:=90 \\Rz:=-90), v100, fine, tool0;\n"
      "    MoveL Offs(RelTool(a,0,0,5),1,2,3), v100, fine, tool0;\n"
      "  ENDPROC\n"
      "  PROC other()\n"
      "    MoveJ a, v100, fine, tool0;\n"
      "  ENDPROC\n"
      "ENDMODULE\n";
  const Program p = parseRapid(text, "q.mod");
  ASSERT_EQ(p.motions.size(), 3u);
  Eigen::Isometry3d A = Eigen::Isometry3d::Identity();
  A.translation() = Eigen::Vector3d(350, 10, 400);
  A.linear() = quatMatrix(0.5, 0.5, 0.5, 0.5);
  Eigen::Matrix3d Rx, Rz;
  Rx << 1, 0, 0, 0, 0, -1, 0, 1, 0;  // +90 deg about x
  Rz << 0, 1, 0, -1, 0, 0, 0, 0, 1;  // -90 deg about z
  const Eigen::Vector3d p1 = A * Eigen::Vector3d(10, 20, 30);
  EXPECT_LT((poseOf(p.motions[0].target).translation() - p1).norm(), 1e-9);
  EXPECT_LT((poseOf(p.motions[0].target).linear() - A.linear() * Rx * Rz).norm(), 1e-9);
  const Eigen::Vector3d p2 = A * Eigen::Vector3d(0, 0, 5) + Eigen::Vector3d(1, 2, 3);
  EXPECT_LT((poseOf(p.motions[1].target).translation() - p2).norm(), 1e-9);
  // the other routine sees the module's a: normalised 0.7071 -> 1/sqrt(2)
  const double n = std::sqrt(2 * 0.7071 * 0.7071);
  EXPECT_LT((poseOf(p.motions[2].target).linear() - quatMatrix(0.7071 / n, 0, 0.7071 / n, 0)).norm(), 1e-12);
  EXPECT_TRUE(p.motions[2].start_unknown);  // the first motion of a routine: called from anywhere
  EXPECT_FALSE(p.motions[1].start_unknown);
}

// Motion::start_unknown of every motion of a module whose body is `procs` (two robtargets a, b).
std::vector<bool> startsUnknown(const std::string& procs) {
  const Program p = parseRapid("MODULE m\n"
                               "  CONST robtarget a := [[300,0,400],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
                               "  CONST robtarget b := [[300,100,400],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n" +
                                   procs + "ENDMODULE\n",
                               "flow.mod");
  std::vector<bool> out;
  for (const Motion& m : p.motions) out.push_back(m.start_unknown);
  return out;
}

TEST(Rapid, TheStartIsUnknownAfterACallOrABranchAndInARoutine) {
  const std::string procs =
      "  PROC main()\n"
      "    MoveL a, v100, fine, tool0;\n"                 // 0: a routine's first motion
      "    Weld;\n    MoveL b, v100, fine, tool0;\n"     // 1: after a call of a routine
      "    MoveL a, v100, fine, tool0;\n"                 // 2
      "    IF di1 = 1 THEN\n      MoveL b, v100, fine, tool0;\n    ELSE\n      MoveL a, v100, fine, tool0;\n    ENDIF\n"  // 3, 4
      "    MoveL b, v100, fine, tool0;\n"                 // 5: after the branches
      "    WaitTime 1;\n    MoveL a, v100, fine, tool0;\n"  // 6: an instruction that does not move the robot
      "  ENDPROC\n"
      "  PROC Weld()\n"
      "    MoveL b, v100, fine, tool0;\n"                 // 7: a routine's first motion
      "  ENDPROC\n";
  EXPECT_EQ(startsUnknown(procs), (std::vector<bool>{true, true, false, false, true, true, false, true}));
}

TEST(Rapid, MotionsAfterALabelACompactIfOrACaseAreRead) {
  // The controller runs these motions. The reader used to take the whole line for the label, the
  // IF or the CASE, and their targets went uncompensated without a word.
  const std::string procs =
      "  PROC main()\n"
      "    MoveL a, v100, fine, tool0;\n"                                   // 0: a routine's first motion
      "    again: MoveL b, v100, fine, tool0;\n"                            // 1: after a label (a GOTO comes here)
      "    IF reg1 = 1 MoveL a, v100, fine, tool0;\n"                      // 2: when reg1 = 1, from b
      "    MoveL b, v100, fine, tool0;\n"                                   // 3: from a or from b
      "    IF DInput(di1) = 1 AND reg1 > 2 MoveJ a, v100, z10, tool0;\n"   // 4: from b
      "    MoveL b, v100, fine, tool0;\n"                                   // 5: from a or from b
      "    TEST reg1\n"
      "    CASE 1, 2: MoveL a, v100, fine, tool0;\n"                       // 6: from b
      "    DEFAULT: MoveL b, v100, fine, tool0;\n"                         // 7: another branch
      "    ENDTEST\n"
      "    IF reg1 = 3 GOTO again;\n"
      "    MoveL a, v100, fine, tool0;\n"                                   // 8: after a jump may be taken
      "  ENDPROC\n";
  EXPECT_EQ(startsUnknown(procs), (std::vector<bool>{true, true, false, true, false, true, false, true, true}));
  const std::string text = "MODULE m\n"
                           "  CONST robtarget a := [[300,0,400],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
                           "  CONST robtarget b := [[300,100,400],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n" +
                           procs + "ENDMODULE\n";
  Program p = parseRapid(text, "flow.mod");
  ASSERT_EQ(p.motions.size(), 9u);
  // where each motion is: line, column (after the label, the condition, the CASE's ':')
  const std::vector<std::pair<int, int>> where = {{5, 5}, {6, 12}, {7, 17}, {8, 5}, {9, 37}, {10, 5}, {12, 16}, {13, 14}, {16, 5}};
  for (size_t k = 0; k < where.size(); ++k) {
    EXPECT_EQ(p.motions[k].where.line, where[k].first) << k;
    EXPECT_EQ(p.motions[k].where.column, where[k].second) << k;
  }
  EXPECT_EQ(p.motions[4].type, MotionType::kPtp);
  EXPECT_EQ(writeRapid(p), text);  // read and written back unchanged
  // a corrected target is written where the conditional motion's robtarget is declared
  Target& t = p.motions[2].target;
  t.setPose(calib::XyzAbc{300.5, 0, 400, t.xyzAbc().a_deg, t.xyzAbc().b_deg, t.xyzAbc().c_deg});
  t.modified = true;
  const std::string out = writeRapid(p);
  EXPECT_NE(out.find("    IF reg1 = 1 MoveL a, v100, fine, tool0;\n"), std::string::npos) << out;
  EXPECT_NE(out.find("[[300.5000,0,400],"), std::string::npos) << out;
}

TEST(Rapid, MotionsAfterBlockWordsAndHeadersOverSeveralLinesAreRead) {
  // RAPID is free format: a statement may follow THEN, DO, ELSE, ENDIF or a CASE on the same
  // line, and a header may run over several lines. Each motion is read where it is; one that
  // shares its line with another statement gets no auxiliary points (they would repeat the
  // other statement or run outside its block): Motion::single_reason.
  const std::string text =
      "MODULE m\n"
      "  CONST robtarget a := [[300,0,400],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  CONST robtarget b := [[300,100,400],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  VAR num tc := 2;\n"
      "  LOCAL PROC main()\n"                                                           // line 5
      "    MoveL a, v100, fine, tool0;\n"                                                // 0
      "    IF reg1 = 1 THEN MoveL b, v100, fine, tool0;\n"                             // 1: after THEN
      "    ELSE MoveL a, v100, fine, tool0;\n"                                          // 2: after ELSE
      "    ENDIF MoveL b, v100, fine, tool0;\n"                                         // 3: after ENDIF
      "    WHILE reg2 > 0 DO MoveL a, v100, fine, tool0;\n    ENDWHILE\n"             // 4
      "    FOR i FROM 1 TO 3 DO MoveL b, v100, fine, tool0;\n    ENDFOR\n"            // 5
      "    TEST reg1 CASE 1: MoveL a, v100, fine, tool0;\n    ENDTEST\n"               // 6: a one-line TEST
      "    IF reg1 = 1 AND\n      reg2 = 2 THEN\n      MoveL b, v100, fine, tool0;\n    ENDIF\n"  // 7: line 18
      "    WHILE reg2 > 0\n      DO\n      MoveL a, v100, fine, tool0;\n    ENDWHILE\n"  // 8: line 22
      "    TEST reg1\n    CASE 1,\n      2:\n      MoveL b, v100, fine, tool0;\n    ENDTEST\n"  // 9: line 27
      "    MoveL a, v100, z10 \\Inpos:=inpos20, tool0;\n"                             // 10: a stop point (line 29)
      "    MoveL b, v100, z10, tool0 \\ID:=10;\n"                                      // 11: MultiMove
      "    MoveL a, v100 \\T:=tc, z10, tool0;\n"                                       // 12: a time in a variable
      "    SearchJ \\Stop, di1, sp, b, v100, tool0;\n"                                // 13: not modelled, named
      "  ENDPROC\n"
      "ENDMODULE\n";
  Program p = parseRapid(text, "free.mod");
  ASSERT_EQ(p.motions.size(), 14u);
  const std::vector<std::pair<int, int>> where = {{6, 5},  {7, 22}, {8, 10}, {9, 11}, {10, 23}, {12, 26}, {14, 23},
                                                  {18, 7}, {22, 7}, {27, 7}, {29, 5}, {30, 5},  {31, 5},  {32, 5}};
  for (size_t k = 0; k < where.size(); ++k) {
    EXPECT_EQ(p.motions[k].where.line, where[k].first) << k;
    EXPECT_EQ(p.motions[k].where.column, where[k].second) << k;
  }
  const std::string shares = "it shares its line with another statement";
  for (size_t k : {1u, 2u, 3u, 4u, 5u, 6u}) EXPECT_EQ(p.motions[k].single_reason, shares) << k;
  for (size_t k : {0u, 7u, 8u, 9u, 10u}) EXPECT_EQ(p.motions[k].single_reason, "") << k;
  EXPECT_NE(p.motions[11].single_reason.find("\\ID"), std::string::npos);
  EXPECT_NE(p.motions[12].single_reason.find("\\T:= is not a number"), std::string::npos);
  EXPECT_TRUE(p.motions[10].approximation.empty());  // \Inpos replaces the zone: a stop point
  EXPECT_FALSE(p.motions[11].approximation.empty());
  EXPECT_NE(p.motions[13].target_problem.find("SearchJ is a motion instruction accura does not model"), std::string::npos);
  EXPECT_EQ(writeRapid(p), text);  // read and written back unchanged
  // a TEST expression over two lines; a UTF-8 byte order mark (read past, written back)
  std::string two = text;
  two.replace(two.find("    TEST reg1\n    CASE 1,\n"), std::string("    TEST reg1\n    CASE 1,\n").size(), "    TEST reg1 +\n      reg2\n    CASE 1,\n");
  const Program q = parseRapid("\xEF\xBB\xBF" + two, "bom.mod");
  ASSERT_EQ(q.motions.size(), 14u);
  EXPECT_EQ(q.motions[9].where.line, 28);
  EXPECT_EQ(writeRapid(q), "\xEF\xBB\xBF" + two);
}

TEST(Rapid, RoutinesThatDoNotMoveAndPollingLoopsKeepTheStartKnown) {
  const std::string procs =
      "  PROC main()\n"
      "    MoveL a, v100, fine, tool0;\n"                            // 0: a routine's first motion
      "    Grip;\n    MoveL b, v100, fine, tool0;\n"                // 1: Grip does not move the robot
      "    WHILE DInput(di1) = 0 DO\n      WaitTime 0.1;\n    ENDWHILE\n"
      "    MoveL a, v100, fine, tool0;\n"                            // 2: a polling loop
      "    IF reg1 = 1 Dip;\n    MoveL b, v100, fine, tool0;\n"     // 3: a compact IF calling a routine that moves
      "    IF reg1 = 2 THEN\n      MoveL a, v100, fine, tool0;\n      IF reg2 = 1 THEN\n        SetDO do1, 1;\n      ENDIF\n    ENDIF\n"  // 4
      "    MoveL b, v100, fine, tool0;\n"                            // 5: the outer branch moved
      "  ENDPROC\n"
      "  PROC Grip()\n    SetDO do1, 1;\n    WaitTime 0.5;\n  ENDPROC\n"
      "  PROC Dip()\n    MoveL b, v100, fine, tool0;\n  ENDPROC\n";  // 6
  EXPECT_EQ(startsUnknown(procs), (std::vector<bool>{true, false, false, true, false, true, true}));
}

TEST(Rapid, ARobtargetSharedByMoveJAndMoveLTakesTheMoveJsConfdata) {
  // an approach point reused as the retract point: the MoveJ is compensated on its computed
  // quadrants (ConfJ\On needs them exactly), the MoveL keeps what is written (ConfL\On accepts
  // one quadrant off): the shared value gets the MoveJ's confdata, not an error
  const std::string text =
      "MODULE m\n"
      "  CONST robtarget p10 := [[400,0,500],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  CONST robtarget p20 := [[400,0,400],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  PROC main()\n"
      "    MoveL p10, v100, fine, tool0;\n"
      "    MoveJ p20, v100, fine, tool0;\n"
      "    MoveL p10, v100, fine, tool0;\n"
      "    MoveJ p10, v100, fine, tool0;\n"
      "  ENDPROC\n"
      "ENDMODULE\n";
  Program p = parseRapid(text, "shared.mod");
  ASSERT_EQ(p.motions.size(), 4u);
  for (size_t k : {0u, 2u, 3u}) {
    Target& t = p.motions[k].target;
    t.setPose(calib::XyzAbc{400.5, 0, 500, t.xyzAbc().a_deg, t.xyzAbc().b_deg, t.xyzAbc().c_deg});
    t.modified = true;
  }
  p.motions[3].target.abb_conf = std::array<int, 4>{0, -1, 0, 0};  // the MoveJ's quadrant of axis 4
  const std::string out = writeRapid(p);
  EXPECT_NE(out.find("CONST robtarget p10 := [[400.5000,0,500],[0,0,1,0],[0,-1,0,0],"), std::string::npos) << out;
  // two MoveJs that need different confdata are still an error
  p.motions[0].type = MotionType::kPtp;
  EXPECT_THROW(writeRapid(p), calib::ArgumentError);
}

TEST(Rapid, UntouchedModulesAreWrittenBackByteForByte) {
  std::string crlf;
  for (char c : example()) {
    if (c == '\n') crlf += '\r';
    crlf += c;
  }
  std::string no_final_newline = example();
  no_final_newline.pop_back();
  const std::string prg = "%%%\n  VERSION:1\n  LANGUAGE:ENGLISH\n%%%\n\nmodule M\n  proc Main()\n    movel [[1,2,3],[1,0,0,0],[0,0,0,1],[9e9,9e9,9e9,9e9,9e9,9e9]],v10,z0,tool0;\n  endproc\nendmodule";
  for (const std::string& text : {example(), crlf, no_final_newline, prg}) {
    const Program p = parseRapid(text, "x.mod");
    EXPECT_EQ(writeRapid(p), text);
  }
  EXPECT_EQ(parseRapid(prg, "x.prg").motions.size(), 1u);  // keywords are case-insensitive
  const std::string dir = test::tempDir("rapid_roundtrip");
  test::writeText(dir + "/in.prg", crlf);
  const test::CliRun r = test::runAccuraIn(dir, "convert --in in.prg --out out.mod");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(test::readText(dir + "/out.mod"), crlf);
}

std::string errorOf(const std::string& text) {
  try {
    parseRapid(text, "bad.mod");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

std::string inProc(const std::string& body) { return "MODULE m\n  PROC main()\n" + body + "  ENDPROC\nENDMODULE\n"; }

TEST(Rapid, MalformedModulesAreErrorsWithFileLineAndColumn) {
  EXPECT_EQ(errorOf(inProc("    MoveL [[1,2,3],[1,0,0,0],[0,0,0,0]], v100, fine, tool0;\n")),
            "bad.mod:3:11: expected a robtarget [[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax_a,..,eax_f]] with 4 items, found 3 in "
            "'[[1,2,3],[1,0,0,0],[0,0,0,0]]'");
  EXPECT_EQ(errorOf(inProc("    MoveL [[1,2,3],[1,0,0,0.5],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;\n")),
            "bad.mod:3:21: expected a unit quaternion (norm 1 within 0.001), found norm 1.118034");
  EXPECT_EQ(errorOf(inProc("    MoveL p10, v100, fine;\n")),
            "bad.mod:3:5: expected MoveL ToPoint, Speed, Zone, Tool (4 arguments), found 3 in 'MoveL p10, v100, fine;'");
  EXPECT_EQ(errorOf(inProc("    MoveL p10, v100, fine, tool0\n")), "bad.mod:3:33: expected ';' at the end of the statement 'MoveL p10, v100, fine, tool0', found ENDPROC");
  EXPECT_EQ(errorOf(inProc("    MoveC p1, p2, v100, z10, tool0;\n    x := (1];\n")),
            "bad.mod:4:12: expected ')' to close the '(' at bad.mod:4:10, found ']'");
  EXPECT_EQ(errorOf(inProc("    TPWrite \"arc on;\n")), "bad.mod:3:13: expected the closing '\"' of this string on its line, found the end of the line");
  EXPECT_EQ(errorOf(inProc("    MoveL [[1e999,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;\n")),
            "bad.mod:3:13: expected a finite number, found '1e999'");
  EXPECT_EQ(errorOf(inProc("    MoveL [[1,2,3E],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;\n")),
            "bad.mod:3:18: expected the digits of an exponent, found 'E]'");
  EXPECT_EQ(errorOf(inProc("    MoveL [[1,2,300000],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;\n")),
            "bad.mod:3:17: expected a position in mm within +-100000, found 300000");
  EXPECT_EQ(errorOf(inProc("    MoveL [[1,2,3],[1,0,0,0],[0,0.5,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;\n")),
            "bad.mod:3:33: expected an integer in confdata, found 0.5");
  EXPECT_EQ(errorOf(inProc("    MoveL [[1,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, [TRUE,1,2], tool0;\n")),
            "bad.mod:3:74: expected a zonedata [finep, pzone_tcp, pzone_ori, pzone_eax, zone_ori, zone_leax, zone_reax] with 7 items, found 3 in '[TRUE,1,2]'");
  EXPECT_EQ(errorOf("MODULE m\n  PERS tooldata t := [TRUE,[[0,0,1],[1,0,0,0]]];\nENDMODULE\n"),
            "bad.mod:2:22: expected a tooldata [robhold, [[x,y,z],[q1,q2,q3,q4]], loaddata] with 3 items, found 2 in '[TRUE,[[0,0,1],[1,0,0,0]]]'");
  EXPECT_EQ(errorOf("MODULE m\n  PERS wobjdata w := [1,TRUE,\"\",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\nENDMODULE\n"),
            "bad.mod:2:23: expected TRUE or FALSE for robhold of wobjdata w, found '1'");
  // found by fuzz_rapid: an offset that puts the point 9e9 mm away is an error, not a target
  EXPECT_EQ(errorOf(inProc("    MoveL Offs([[1,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]],09E+09,0,100), v100, fine, tool0;\n")),
            "bad.mod:3:72: expected an offset in mm within +-100000 in Offs, found '09E+09'");
  EXPECT_EQ(errorOf(inProc("    MoveL Offs(Offs([[90000,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]],9000,0,0),9000,0,0), v100, fine, tool0;\n")),
            "bad.mod:3:11: expected Offs(...) to give a position within +-100000 mm, found 108000.0000 in "
            "'Offs(Offs([[90000,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]],9000,0,...'");  // (quoted: 80 bytes at most)
  EXPECT_EQ(errorOf("  PROC main()\n  ENDPROC\n"), "bad.mod:1:3: expected MODULE before the first statement, found 'PROC'");
  EXPECT_EQ(errorOf("MODULE m\n  PROC main()\n  ENDPROC\n"), "bad.mod:4:1: expected ENDMODULE, found the end of the file");
  EXPECT_EQ(errorOf("MODULE m\n  PROC main()\nENDMODULE\n"), "bad.mod:3:1: expected ENDPROC of the routine main, found ENDMODULE");
  EXPECT_EQ(errorOf("MODULE m\n  MoveJ p, v10, z10, tool0;\nENDMODULE\n"), "bad.mod:2:3: expected MoveJ inside a routine (PROC), found it at module level");
  EXPECT_EQ(errorOf(""), "bad.mod:1:1: expected a RAPID module (MODULE name ... ENDMODULE), found an empty file");
  EXPECT_EQ(errorOf(std::string("MODULE m\n\0x", 11)), "bad.mod:2:1: expected a RAPID text file, found a NUL byte (binary file?)");
}

TEST(Rapid, CompensatingWithTheNominalRobotReturnsTheModuleByteForByte) {
  const Program p = parseRapid(example(), "irb120_seam.mod");
  const ProgramCompensation c = compensateProgramReport(p, settingsFor(irb120WithTorch()));
  ASSERT_TRUE(c.ok()) << c.report.errors.front().where.str() << ": " << c.report.errors.front().message;
  EXPECT_EQ(c.report.points_added, 0);
  EXPECT_LT(c.report.max_correction_mm, 1e-6);
  EXPECT_TRUE(c.report.warnings.empty());
  EXPECT_EQ(writeRapid(c.program), example());
}

TEST(Rapid, APrgWithSeveralModulesIsOneProgram) {
  // An S4C-era .prg holds every module of the program one after the other; their global data
  // are shared. It was refused ("expected one MODULE per file"). Each module's targets are
  // corrected as they are when the same routines and data stand in one module.
  const std::string head = "%%%\n  VERSION:1\n  LANGUAGE:ENGLISH\n%%%\n\n";
  const std::string data =
      "  PERS tooldata gun:=[TRUE,[[10,0,120],[0.9659258,0,0.258819,0]],[1.5,[0,0,50],[1,0,0,0],0,0,0]];\n"
      "  PERS wobjdata fix:=[FALSE,TRUE,\"\",[[300,-150,100],[0.9238795,0,0,0.3826834]],[[20,10,5],[0.9961947,0,0,0.0871557]]];\n"
      "  CONST robtarget p10:=[[203.914,-27.004,166.222],[0.04054039,-0.49091288,-0.86326515,-0.11015580],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n";
  const std::string main = "  PROC main()\n    MoveJ p10,v500,z10,gun\\WObj:=fix;\n    path2;\n  ENDPROC\n";
  const std::string data2 =
      "  CONST robtarget p20:=[[233.914,2.996,166.222],[0.04054039,-0.49091288,-0.86326515,-0.11015580],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n";
  const std::string path2 = "  PROC path2()\n    MoveL p20,v100,fine,gun\\WObj:=fix;\n  ENDPROC\n";
  const std::string two = head + "MODULE MAINMOD\n" + data + main + "ENDMODULE\n\nMODULE PATHS\n" + data2 + path2 + "ENDMODULE\n";
  const std::string one = head + "MODULE MAINMOD\n" + data + data2 + main + path2 + "ENDMODULE\n";
  const Program p2 = parseRapid(two, "two.prg"), p1 = parseRapid(one, "one.prg");
  EXPECT_EQ(p2.name, "MAINMOD");
  ASSERT_EQ(p2.motions.size(), 2u);
  // the nominal robot: byte for byte
  JobSettings nominal;
  nominal.calibrated = test::loadBundled("abb_irb120");
  const ProgramCompensation n = compensateProgramReport(p2, nominal);
  ASSERT_TRUE(n.ok()) << n.report.errors.front().where.str() << ": " << n.report.errors.front().message;
  EXPECT_EQ(writeRapid(n.program), two);
  // a perturbed robot: the same corrections as in one module
  SimulateOptions so;
  so.effects = {"geometric"};
  so.set_station = false;
  so.seed = 9;
  const JobSettings real = settingsFor(perturbModel(test::loadBundled("abb_irb120"), so));
  const ProgramCompensation c2 = compensateProgramReport(p2, real), c1 = compensateProgramReport(p1, real);
  ASSERT_TRUE(c2.ok()) << c2.report.errors.front().where.str() << ": " << c2.report.errors.front().message;
  ASSERT_TRUE(c1.ok());
  ASSERT_EQ(c1.program.motions.size(), c2.program.motions.size());
  for (size_t k = 0; k < c1.program.motions.size(); ++k) {
    const Eigen::Isometry3d a = poseOf(c1.program.motions[k].target), b = poseOf(c2.program.motions[k].target);
    EXPECT_LT((a.translation() - b.translation()).norm(), 1e-9) << k;
    EXPECT_GT((b.translation() - poseOf(p2.motions[k].target).translation()).norm(), 0.1) << k;  // corrected
  }
  EXPECT_NE(writeRapid(c2.program).find("ENDMODULE\n\nMODULE PATHS\n"), std::string::npos);
}

TEST(Rapid, AHomePositionAtZeroKeepsItsConfdata) {
  // axis 1, 4 and 6 at 0 (a home position written as [0,0,0,0]): the IK's solution may come
  // out at -1e-14 deg, in quadrant -1. Either quadrant reaches the pose at the written
  // precision, so with nothing to correct the module comes back byte for byte, and without a
  // warning that the correction moved an axis across a boundary.
  const std::string module =
      "MODULE home\n"
      "  CONST robtarget pHome:=[[364.3538,0,594],[0.5,0,0.8660254,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  CONST robtarget pDown:=[[343.4247,0,393.5199],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  PROC main()\n"
      "    MoveJ pHome, v500, fine, tool0;\n"
      "    MoveJ pDown, v500, fine, tool0;\n"
      "  ENDPROC\n"
      "ENDMODULE\n";
  const Program p = parseRapid(module, "home.mod");
  JobSettings s;
  s.calibrated = test::loadBundled("abb_irb120");
  const ProgramCompensation c = compensateProgramReport(p, s);
  ASSERT_TRUE(c.ok()) << c.report.errors.front().where.str() << ": " << c.report.errors.front().message;
  EXPECT_LT(c.report.max_correction_mm, 1e-6);
  EXPECT_TRUE(c.report.warnings.empty()) << c.report.warnings.front().message;
  EXPECT_EQ(writeRapid(c.program), module);
}

// confdata of joint values, against the geometry worked out by hand for the IRB 120: at
// q = 0 the wrist centre is 302 mm in front of axis 1 and the upper arm points forward, so
// the wrist centre is in front of the lower arm (cfx 0); axis 5 negative adds 1; the upper
// arm raised past the stretched position (q3 < -90 + atan(70/302) = -76.95 deg) puts the wrist
// behind the lower arm (+2); the lower arm tilted back by 100 deg puts the wrist centre behind
// axis 1 (+4).
TEST(Rapid, ConfdataOfJointValuesAgainstTheGeometry) {
  const RobotModel m = test::loadBundled("abb_irb120");
  auto conf = [&](double q1, double q2, double q3, double q4, double q5, double q6) {
    Eigen::VectorXd q(6);
    q << q1, q2, q3, q4, q5, q6;
    return abbConfdata(m, q);
  };
  EXPECT_EQ(conf(0, 0, 0, 0, 30, 0), (std::array<int, 4>{0, 0, 0, 0}));
  EXPECT_EQ(conf(-10, 0, 0, 100, -30, -200), (std::array<int, 4>{-1, 1, -3, 1}));
  EXPECT_EQ(conf(95, 30, -80, 0, 30, 0), (std::array<int, 4>{1, 0, 0, 2}));
  EXPECT_EQ(conf(0, 0, -80, 0, 30, 0), (std::array<int, 4>{0, 0, 0, 6}));  // upright lower arm: the wrist also behind axis 1
  EXPECT_EQ(conf(0, 0, -74, 0, 30, 0), (std::array<int, 4>{0, 0, 0, 0}));
  EXPECT_EQ(conf(0, -100, 0, 0, 30, 0), (std::array<int, 4>{0, 0, 0, 4}));
  for (int cfx = 0; cfx < 8; ++cfx) {  // the branch round trip through the KUKA Status
    const int s = kukaStatusOfCfx(cfx);
    const int back = ((s & 1) ? 4 : 0) + ((s & 2) ? 0 : 2) + ((s & 4) ? 1 : 0);
    EXPECT_EQ(back, cfx);
  }
  EXPECT_EQ(kukaStatusOfCfx(8), -1);
}

std::string moduleWith(const std::string& conf_statement, const std::string& move, const std::string& conf) {
  return "MODULE c\n  PROC main()\n    MoveAbsJ [[10,10,10,10,30,10],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;\n    " + conf_statement +
         "\n    " + move + " [[380,40,350],[0,0,1,0]," + conf + ",[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;\n  ENDPROC\nENDMODULE\n";
}

std::string confText(int cf1, int cf4, int cf6, int cfx) {
  return "[" + std::to_string(cf1) + "," + std::to_string(cf4) + "," + std::to_string(cf6) + "," + std::to_string(cfx) + "]";
}

RobotModel shiftedIrb120() {
  RobotModel real = test::loadBundled("abb_irb120");
  real.deviations.base_mm = Eigen::Vector3d(0.2, -0.1, 0.3);
  return real;
}

// RAPID lets an optional argument follow the one before it with or without a comma (RAPID
// kernel, function calls: <function argument> ::= .. | ',' <optional function argument>), and
// programs write RelTool(p,0,0,0,\Rz:=a): the whole module was refused ("expected RelTool(point,
// dx, dy, dz) with 4 arguments, found 5"), a program the controller runs.
TEST(Rapid, RelToolTakesItsRotationsAfterACommaAsTheControllerDoes) {
  auto module = [](const std::string& reltool) {
    return "MODULE m\n  CONST robtarget a := [[380,40,350],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n  PROC main()\n    ConfL\\Off;\n"
           "    MoveJ a, v100, fine, tool0;\n    MoveL " + reltool + ", v100, fine, tool0;\n  ENDPROC\nENDMODULE\n";
  };
  const std::string comma = module("RelTool(a, 0, 0, 10, \\Rx:=0, \\Rz:=90)");
  const Program p = parseRapid(comma, "r.mod");
  ASSERT_EQ(p.motions.size(), 2u);
  ASSERT_EQ(p.motions[1].target_problem, "");
  // a * Trans(0,0,10) * Rz(90): the tool's z is the world's -z (a turned 180 deg about y)
  Eigen::Matrix3d Rz;
  Rz << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  EXPECT_LT((poseOf(p.motions[1].target).translation() - Eigen::Vector3d(380, 40, 340)).norm(), 1e-9);
  EXPECT_LT((poseOf(p.motions[1].target).linear() - quatMatrix(0, 0, 1, 0) * Rz).norm(), 1e-9);
  // compensated (the base 0.2, -0.1, 0.3 mm off): the inline robtarget, as without the commas
  const ProgramCompensation c = compensateProgramReport(p, settingsFor(shiftedIrb120()));
  ASSERT_TRUE(c.ok()) << c.report.errors.front().message;
  const std::string written = writeRapid(c.program);
  EXPECT_NE(written.find("\n    MoveL [[379.8000,40.1000,339.7000],[0.000000000,0.707106781,0.707106781,0.000000000],[0,0,0,0],"
                         "[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;\n"),
            std::string::npos)
      << written;
  const ProgramCompensation c2 = compensateProgramReport(parseRapid(module("RelTool(a, 0, 0, 10 \\Rx:=0 \\Rz:=90)"), "r.mod"), settingsFor(shiftedIrb120()));
  ASSERT_TRUE(c2.ok()) << c2.report.errors.front().message;
  EXPECT_EQ(writeRapid(c2.program), written);
  // a rotation the controller computes, after a comma: kept as written and named
  const Program q = parseRapid(module("RelTool(a,0,0,10,\\Rz:=turn)"), "r.mod");
  ASSERT_EQ(q.motions.size(), 2u);
  EXPECT_EQ(q.motions[1].target_problem, "RelTool(...) at r.mod:6:11 has a rotation that is not a number or a CONST num ('turn')");
}

// Offs / RelTool with CONST num arguments (`CONST num dz := 100;`, the way production modules
// name their approach heights): a constant's value is the one written (RAPID: a CONST is
// never assigned), so the target is evaluated and compensated as with the numbers written out.
// A VAR / PERS num (changed while it runs) and a routine's datum or parameter that hides the
// constant stay run-time values: kept as written and named. Before: every name was a run-time
// value (MoveL left unchanged).
TEST(Rapid, OffsAndRelToolTakeTheValueOfACONSTNum) {
  auto module = [](const std::string& target, const std::string& local = "") {
    return "MODULE m\n  CONST robtarget a := [[380,40,350],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
           "  CONST num dz := 100;\n  CONST num turn := -9E1;\n  VAR num vz := 100;\n  PROC main()\n" + local + "    ConfL\\Off;\n"
           "    MoveJ a, v100, fine, tool0;\n    MoveL " + target + ", v100, fine, tool0;\n  ENDPROC\nENDMODULE\n";
  };
  const JobSettings s = settingsFor(shiftedIrb120());
  auto written = [&](const std::string& text) {
    const ProgramCompensation c = compensateProgramReport(parseRapid(text, "r.mod"), s);
    EXPECT_TRUE(c.ok()) << (c.ok() ? std::string() : c.report.errors.front().message);
    for (const ProgramIssue& w : c.report.warnings) EXPECT_EQ(w.message.find("left unchanged"), std::string::npos) << w.message;
    return writeRapid(c.program);
  };
  // the base is 0.2, -0.1, 0.3 mm off: Offs(a,0,0,100) = [380,40,450] is written 0.2, -0.1, 0.3 mm back
  const std::string offs = written(module("Offs(a, 0, 0, 100)"));
  EXPECT_NE(offs.find("\n    MoveL [[379.8000,40.1000,449.7000],"), std::string::npos) << offs;
  EXPECT_EQ(written(module("Offs(a, 0, 0, dz)")), offs);
  const std::string rel = written(module("RelTool(a, 0, 0, -100 \\Rz:=-90)"));
  EXPECT_NE(rel, written(module("RelTool(a, 0, 0, -100)")));  // (the rotation is taken)
  EXPECT_EQ(written(module("RelTool(a, 0, 0, -dz \\Rz:=turn)")), rel);
  // run-time values: kept, named
  auto problem = [&](const std::string& text) { return parseRapid(text, "r.mod").motions.at(1).target_problem; };
  EXPECT_EQ(problem(module("Offs(a, 0, 0, vz)")), "Offs(...) at r.mod:9:11 has an offset that is not a number or a CONST num ('vz')");
  EXPECT_EQ(problem(module("Offs(a, 0, 0, dz)", "    VAR num dz := 5;\n")),
            "Offs(...) at r.mod:10:11 has an offset that is not a number or a CONST num ('dz')");
  EXPECT_EQ(problem(module("Offs(a, 0, 0, dz)", "    CONST num dz := 5;\n")), "");
  EXPECT_EQ(problem(module("Offs(a, 0, 0, dz * 2)")), "Offs(...) at r.mod:9:11 has an offset that is not a number or a CONST num ('dz * 2')");
}

// A routine with optional parameters, declared as RAPID allows without a comma before them
// (RAPID kernel, <next parameter declaration> ::= .. | <optional parameter declaration>) and
// passed on as conditional arguments (\WObj?wo: given only when the caller gives wo). Before:
// `PROC approach(robtarget p10 \switch slow)` hid no module datum (p10 was not read as a
// parameter), so the module's p10 was corrected for a motion that goes where the call says;
// and `\WObj?wo` refused the module ("the wobjdata '?wo' is not declared with a value").
TEST(Rapid, OptionalParametersAndConditionalArgumentsAreTheCallersValues) {
  const std::string text =
      "MODULE m\n"
      "  CONST robtarget p10 := [[380,40,350],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  CONST robtarget p20 := [[380,40,300],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  PROC main()\n"
      "    approach p20;\n"
      "  ENDPROC\n"
      "  PROC approach(robtarget p10 \\PERS wobjdata wo \\switch slow)\n"
      "    MoveL p10, v100, fine, tool0;\n"
      "    MoveL p20, v100, fine, tool0 \\WObj?wo;\n"
      "  ENDPROC\n"
      "ENDMODULE\n";
  const Program p = parseRapid(text, "r.mod");
  ASSERT_EQ(p.motions.size(), 2u);
  EXPECT_EQ(p.motions[0].target_problem, "'p10' is a parameter of approach: its value comes from the call");
  const ProgramCompensation c = compensateProgramReport(p, settingsFor(shiftedIrb120()));
  ASSERT_TRUE(c.ok()) << c.report.errors.front().message;
  std::vector<std::string> warnings;
  for (const auto& w : c.report.warnings) warnings.push_back(w.where.str() + ": " + w.message);
  ASSERT_EQ(warnings.size(), 2u);
  EXPECT_EQ(warnings[0], "r.mod:8:5: MoveL left unchanged (not compensated): 'p10' is a parameter of approach: its value comes from the call; "
                         "the position after it is not known");
  EXPECT_EQ(warnings[1], "r.mod:9:5: MoveL left unchanged (not compensated): its base is a run-time value: the wobjdata is the conditional "
                         "argument '?wo' of approach: given or left out by the call; the position after it is not known");
  EXPECT_EQ(writeRapid(c.program), text);  // nothing this module's text says is corrected
}

// The joints the compensation of `move` to the test pose ends at, with monitoring off (the
// controller's nearest configuration).
Eigen::VectorXd jointsOff(const std::string& move) {
  const Program p = parseRapid(moduleWith(move == "MoveJ" ? "ConfJ\\Off;" : "ConfL\\Off;", move, "[0,0,0,0]"), "c.mod");
  const ProgramCompensation c = compensateProgramReport(p, settingsFor(shiftedIrb120()));
  EXPECT_TRUE(c.ok());
  return c.report.targets.back().q_real;
}

int quadrantOf(double q) { return static_cast<int>(std::floor(q / 90)); }

TEST(Rapid, ConfJOnGoesToTheProgrammedQuadrantsConfJOffToTheNearest) {
  const Eigen::VectorXd q = jointsOff("MoveJ");
  const std::array<int, 4> c = abbConfdata(test::loadBundled("abb_irb120"), q);
  // the same pose with axis 6 one turn away (within its +-400 deg): ConfJ\On goes there
  const double q6_other = q[5] > 0 ? q[5] - 360 : q[5] + 360;
  const std::string other = confText(c[0], c[1], quadrantOf(q6_other), c[3]);
  for (const bool on : {true, false}) {
    const Program p = parseRapid(moduleWith(on ? "ConfJ\\On;" : "ConfJ\\Off;", "MoveJ", other), "c.mod");
    const ProgramCompensation r = compensateProgramReport(p, settingsFor(shiftedIrb120()));
    ASSERT_TRUE(r.ok()) << r.report.errors.front().message;
    EXPECT_NEAR(r.report.targets.back().q_real[5], on ? q6_other : q[5], 1e-6);  // programmed turn / nearest
    EXPECT_NE(writeRapid(r.program).find(other), std::string::npos);            // confdata kept as written
  }
  // a quadrant of axis 1 the pose does not have: an error naming the target
  const std::string bad = confText(c[0] + 2, c[1], c[2], c[3]);
  const ProgramCompensation cb = compensateProgramReport(parseRapid(moduleWith("ConfJ\\On;", "MoveJ", bad), "c.mod"), settingsFor(shiftedIrb120()));
  ASSERT_FALSE(cb.ok());
  EXPECT_EQ(cb.report.errors.front().message, "the inline target is not reachable in its programmed confdata " + bad + " (ConfJ\\On; the compensated point has " +
                                                  confText(c[0], c[1], c[2], c[3]) + "; program that configuration, or ConfJ\\Off)");
}

// A point on a quadrant boundary of axis 1 (y = 0: q1 = 0, cf1 0) that the correction moves
// just across it (the real base 0.1 mm off in y): ConfJ\On updates cf1, with a warning. Three
// MoveJs go to the point: the warning was printed three times, once per MoveJ; it is said once
// for the point, naming the other two MoveJs and the count.
TEST(Rapid, AChangedConfdataIsSaidOncePerPointNamingItsMotions) {
  const std::string text =
      "MODULE m\n"
      "  CONST robtarget p10 := [[380,0,350],[0,0.258819045,0.965925826,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  CONST robtarget p20 := [[380,60,350],[0,0.258819045,0.965925826,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  PROC main()\n"
      "    MoveJ p10, v100, fine, tool0;\n"
      "    MoveJ p20, v100, fine, tool0;\n"
      "    MoveJ p10, v100, fine, tool0;\n"
      "    MoveJ p20, v100, fine, tool0;\n"
      "    MoveJ p10, v100, fine, tool0;\n"
      "  ENDPROC\n"
      "ENDMODULE\n";
  for (const double dy : {0.1, -0.1}) {
    RobotModel real = test::loadBundled("abb_irb120");
    real.deviations.base_mm = Eigen::Vector3d(0, dy, 0);
    const ProgramCompensation c = compensateProgramReport(parseRapid(text, "once.mod"), settingsFor(real));
    ASSERT_TRUE(c.ok()) << c.report.errors.front().message;
    std::vector<std::string> changed;
    for (const ProgramIssue& w : c.report.warnings)
      if (w.message.find("confdata of p10 changed") != std::string::npos) changed.push_back(w.where.str() + ": " + w.message);
    // the correction moves q1 off 0 by atan(0.1 / 380) = 0.015 deg: to quadrant -1 for one sign of dy
    const double q1 = c.report.targets.front().q_real[0];
    ASSERT_GT(std::abs(q1), 0.01);
    ASSERT_LT(std::abs(q1), 0.02);
    if (q1 > 0) {
      EXPECT_TRUE(changed.empty());
      continue;
    }
    ASSERT_EQ(changed.size(), 1u) << changed.back();
    const std::string got = confText(-1, 0, 0, 0);
    EXPECT_EQ(changed[0].substr(0, changed[0].find(":", 16)), "once.mod:5:5: confdata of p10 changed from [0,0,0,0] to " + got);
    EXPECT_NE(changed[0].find("(ConfJ\\On goes to the programmed quadrant); the same for the MoveJ(s) at once.mod:7:5, once.mod:9:5 (3 motions to this point)"),
              std::string::npos)
        << changed[0];
    EXPECT_NE(writeRapid(c.program).find("p10 := [[380,"), std::string::npos);
    return;
  }
  ADD_FAILURE() << "neither sign of the base's y offset moved q1 below 0";
}

TEST(Rapid, ConfLOnStopsBeyondOneQuadrantConfLOffFollowsThePath) {
  const Eigen::VectorXd q = jointsOff("MoveL");
  const std::array<int, 4> c = abbConfdata(test::loadBundled("abb_irb120"), q);
  const std::string path = confText(c[0], c[1], c[2], c[3]);
  // cf6 two quadrants off: the controller stops (ConfL\On); ConfL\Off follows the path
  const std::string two = confText(c[0], c[1], c[2] + 2, c[3]);
  const ProgramCompensation c_on = compensateProgramReport(parseRapid(moduleWith("ConfL\\On;", "MoveL", two), "c.mod"), settingsFor(shiftedIrb120()));
  ASSERT_FALSE(c_on.ok());
  EXPECT_EQ(c_on.report.errors.front().message,
            "ConfL\\On: the path reaches the inline target with confdata " + path + ", programmed " + two +
                " (axis 1, 4 or 6 more than one quadrant away, or another cfx): the controller stops here; program the confdata the path has, or ConfL\\Off");
  const ProgramCompensation c_off = compensateProgramReport(parseRapid(moduleWith("ConfL\\Off;", "MoveL", two), "c.mod"), settingsFor(shiftedIrb120()));
  ASSERT_TRUE(c_off.ok()) << c_off.report.errors.front().message;
  EXPECT_NEAR(c_off.report.targets.back().q_real[5], q[5], 1e-9);
  EXPECT_TRUE(c_off.report.warnings.empty());
  // one quadrant off: accepted by the controller, one warning for the program, kept as written
  const std::string one = confText(c[0], c[1], c[2] + 1, c[3]);
  const ProgramCompensation c_near = compensateProgramReport(parseRapid(moduleWith("ConfL\\On;", "MoveL", one), "c.mod"), settingsFor(shiftedIrb120()));
  ASSERT_TRUE(c_near.ok()) << c_near.report.errors.front().message;
  ASSERT_EQ(c_near.report.warnings.size(), 1u);
  EXPECT_NE(c_near.report.warnings[0].message.find("1 target(s) of MoveL/MoveC carry confdata that the path does not have"), std::string::npos);
  EXPECT_NE(writeRapid(c_near.program).find(one), std::string::npos);
}

// A RAPID module compensated with a robot of other than six axes (a SCARA: ABB's IRB 910SC is
// programmed in RAPID too): ABB's confdata [cf1,cf4,cf6,cfx] describe a 6-axis arm, so they are
// not interpreted there, kept as written, and one warning says so. Before: the seed in the
// programmed quadrants wrote axes 5 and 6 of the SCARA's 4-joint vector ("double free or
// corruption", the process killed).
TEST(Rapid, ConfdataAreNotInterpretedForARobotOfOtherThanSixAxes) {
  const ProgramCompensation r = compensateProgramReport(parseRapid(example(), "irb120_seam.mod"), settingsFor(test::loadBundled("scara")));
  ASSERT_TRUE(r.ok()) << r.report.errors.front().message;
  ASSERT_EQ(r.report.warnings.size(), 1u);
  EXPECT_EQ(r.report.warnings[0].where.str(), "irb120_seam.mod:18:5");  // MoveJ p10, the first target with confdata
  EXPECT_EQ(r.report.warnings[0].message,
            "the confdata of the RAPID targets are not interpreted for Adept Cobra s600 (SCARA, RRPR) (4 axes; ABB's confdata "
            "[cf1,cf4,cf6,cfx] describe a 6-axis arm): each target is compensated on the configuration nearest the robot's, and "
            "its confdata are kept as written. First: this motion");
  // the nominal robot: nothing to correct, the module comes back byte for byte
  EXPECT_EQ(writeRapid(r.program), example());
}

// The IRB 120's module compensated with a KUKA KR 16 as --robot (a wrong model given by
// mistake): its six targets with checked confdata (MoveJ p10, MoveL p20, p30, the MoveC's end
// p50, p60, Offs(p60,..): counted in examples/irb120_seam.mod) are all on other configurations
// there. The first message says the module looks written for another robot model, then the
// first target's own error (before: the confdata errors alone, target by target).
TEST(Rapid, AModuleForAnotherRobotModelIsSaidSoFirst) {
  const Program p = parseRapid(example(), "irb120_seam.mod");
  const ProgramCompensation r = compensateProgramReport(p, settingsFor(test::loadBundled("kuka_kr16")));
  ASSERT_FALSE(r.ok());
  const std::string head = "the module looks written for another robot model than KUKA KR 16 (--robot): 6 of its 6 targets with checked "
                           "confdata (ConfJ\\On, ConfL\\On) are reached on another configuration than the one programmed, while a "
                           "calibration moves a target by millimetres; check --robot. First: p10 is not reachable in its programmed "
                           "confdata [-1,0,-1,0] (ConfJ\\On; ";
  EXPECT_EQ(r.report.errors.front().message.substr(0, head.size()), head);
  EXPECT_EQ(r.report.errors.front().where.str(), "irb120_seam.mod:18:5");
  // the other errors are the targets' own, unchanged; only the first carries the verdict
  for (size_t k = 1; k < r.report.errors.size(); ++k)
    EXPECT_EQ(r.report.errors[k].message.find("another robot model"), std::string::npos) << r.report.errors[k].message;
}

// What the controller runs and accura does not model (external axes in use, a stationary tool, a
// work object a mechanical unit moves) or cannot evaluate (a target computed at run time) is kept
// as written and named: a program the controller runs is never refused (the first three were).
// A frame that is missing is the user's to give: an error.
TEST(Rapid, WhatAccuraCannotModelIsKeptNamingIt) {
  RobotModel real = test::loadBundled("abb_irb120");
  real.deviations.base_mm = Eigen::Vector3d(0.2, -0.1, 0.3);
  auto firstError = [&](const std::string& text) {
    const ProgramCompensation c = compensateProgramReport(parseRapid(text, "r.mod"), settingsFor(real));
    return c.report.errors.empty() ? std::string("no error") : c.report.errors.front().where.str() + ": " + c.report.errors.front().message;
  };
  auto firstWarning = [&](const std::string& text) {
    const ProgramCompensation c = compensateProgramReport(parseRapid(text, "r.mod"), settingsFor(real));
    EXPECT_TRUE(c.report.errors.empty()) << c.report.errors.front().message;
    return c.report.warnings.empty() ? std::string("no warning") : c.report.warnings.front().where.str() + ": " + c.report.warnings.front().message;
  };
  auto asWritten = [&](const std::string& text) {
    const ProgramCompensation c = compensateProgramReport(parseRapid(text, "r.mod"), settingsFor(real));
    return writeRapid(c.program) == text;
  };
  const std::string t = "[[380,40,350],[0,0,1,0],[0,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]]";
  // an external axis in use (a track)
  const std::string track = inProc("    MoveJ [[380,40,350],[0,0,1,0],[0,0,-1,0],[250,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;\n");
  EXPECT_EQ(firstWarning(track),
            "r.mod:3:5: MoveJ left unchanged (not compensated): the inline target moves external axes (eax_a 250.0000: a track or a "
            "positioner), which the robot file 'ABB IRB 120-3/0.58' does not model; the position after it is not known");
  EXPECT_TRUE(asWritten(track));
  // a stationary tool, a robot-held or coordinated work object
  const std::string stationary = "MODULE m\n  PERS tooldata st := [FALSE,[[0,0,100],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];\n  PROC main()\n    MoveJ " +
                                 t + ", v100, fine, st;\n  ENDPROC\nENDMODULE\n";
  const std::string w_st = firstWarning(stationary);
  EXPECT_EQ(w_st.rfind("r.mod:4:5: MoveJ left unchanged (not compensated): its tool: ", 0), 0u) << w_st;
  EXPECT_NE(w_st.find("tooldata st has robhold FALSE (a stationary tool with a robot-held work object), which accura does not model"),
            std::string::npos) << w_st;
  EXPECT_TRUE(asWritten(stationary));
  const std::string moved = "MODULE m\n  PERS wobjdata w := [FALSE,FALSE,\"STN1\",[[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n  PROC main()\n    MoveJ " +
                            t + ", v100, fine, tool0\\WObj:=w;\n  ENDPROC\nENDMODULE\n";
  const std::string w_mv = firstWarning(moved);
  EXPECT_EQ(w_mv.rfind("r.mod:4:5: MoveJ left unchanged (not compensated): its base: ", 0), 0u) << w_mv;
  EXPECT_NE(w_mv.find("wobjdata w has ufprog FALSE (a user frame moved by the mechanical unit \"STN1\"), which accura does not model"),
            std::string::npos) << w_mv;
  EXPECT_TRUE(asWritten(moved));
  // Offs of a point computed at run time, a robtarget assigned in the program: programs the
  // controller runs, so not refused: the motion is kept as written and named in a warning
  EXPECT_EQ(firstWarning(inProc("    MoveL Offs(CRobT(),0,0,10), v100, fine, tool0;\n")),
            "r.mod:3:5: MoveL left unchanged (not compensated): Offs(...) at r.mod:3:11 cannot be evaluated: 'CRobT()' is not a "
            "target accura can evaluate (a robtarget, a declared robtarget, Offs or RelTool of one); the position after it is not known");
  EXPECT_EQ(firstWarning("MODULE m\n  VAR robtarget p := " + t + ";\n  PROC main()\n    p := CRobT();\n    MoveL p, v100, fine, tool0;\n  ENDPROC\nENDMODULE\n"),
            "r.mod:5:5: MoveL left unchanged (not compensated): 'p' is assigned at r.mod:4:5: its value at run time is not the declared one; "
            "the position after it is not known");
  {
    // the rest is compensated, the run-time motion keeps its text
    const std::string tc = "[[380,40,350],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]]";
    const std::string text = inProc("    MoveJ " + tc + ", v100, fine, tool0;\n    MoveL Offs(CRobT(),0,0,10), v100, fine, tool0;\n");
    const ProgramCompensation c = compensateProgramReport(parseRapid(text, "r.mod"), settingsFor(real));
    ASSERT_TRUE(c.ok()) << c.report.errors.front().message;
    const std::string written = writeRapid(c.program);
    EXPECT_NE(written.find("\n    MoveL Offs(CRobT(),0,0,10), v100, fine, tool0;\n"), std::string::npos) << written;
    EXPECT_EQ(written.find("MoveJ " + tc), std::string::npos) << written;  // corrected (base 0.3 mm off)
  }
  // an undeclared tooldata: named, with the option that supplies it
  EXPECT_EQ(firstError(inProc("    MoveJ " + t + ", v100, fine, gun;\n")),
            "r.mod:3:5: the tool of this motion is not known: the tooldata 'gun' is not declared with a value in this module (give its TCP with "
            "--program-tool x,y,z,A,B,C, or the module that declares it with --config)");
}

// The simulated ABB controller, written here on its own: MoveAbsJ to its joints; MoveJ with
// ConfJ\On to the closed-form solution in the programmed quadrants of axes 1, 4, 6 with the
// programmed sign of axis 5, the nearest to the current joints; MoveL/MoveC interpolated with
// the nominal IK continuing from the current joints, and at the end of each the ConfL\On check
// (axes 1, 4, 6 within one quadrant of the programmed one). The real robot goes where those
// joints put it.
struct Execution {
  double path_mm = 0;   ///< largest distance of the real TCP from the intended path (MoveL/MoveC)
  double point_mm = 0;  ///< largest distance of the real TCP from an intended MoveJ pose
  bool stopped = false; ///< the ConfL/ConfJ check would stop the program
};

int quadrant(double q) { return static_cast<int>(std::floor(q / 90)); }

Execution execute(const Program& commanded, const std::vector<bool>& inserted, const Program& intended, const RobotModel& controller,
                  const RobotModel& real) {
  Execution run;
  KinematicSolver nominal(controller), truth(real);
  Eigen::VectorXd q(6);
  Eigen::Isometry3d at_cmd = Eigen::Isometry3d::Identity(), at_intended = at_cmd;
  size_t i = 0;
  std::vector<PathSegment> cmd_run, intended_run;
  Eigen::VectorXd q_run;
  auto world = [](const Motion& m, const Target& t) { return toIsometry(*m.base.value) * poseOf(t); };
  auto flush = [&] {
    if (cmd_run.empty()) return;
    const std::vector<Eigen::Isometry3d> samples = simulateExecution(controller, real, cmd_run, q_run, 0.2);
    run.path_mm = std::max(run.path_mm, maxPathDeviation(samples, intended_run));
    cmd_run.clear();
    intended_run.clear();
  };
  for (size_t n = 0; n < commanded.motions.size(); ++n) {
    const Motion& m = commanded.motions[n];
    if (m.type == MotionType::kPtp) {
      flush();
      if (m.target.kind == Target::Kind::kAxis) {
        for (int k = 0; k < 6; ++k) q[k] = *m.target.axes[k];
      } else {
        const std::array<int, 4> c = *m.target.abb_conf;
        double best = 1e300;
        for (const Eigen::VectorXd& s : nominal.closedFormSolutions(world(m, m.target))) {
          if (quadrant(s[0]) != c[0] || quadrant(s[3]) != c[1] || quadrant(s[5]) != c[2] || (s[4] < 0) != ((c[3] & 1) != 0)) continue;
          if ((s - q).norm() < best) best = (s - q).norm(), q = s;
        }
        run.stopped = run.stopped || best == 1e300;
        const Motion& im = intended.motions[i];
        run.point_mm = std::max(run.point_mm, (truth.forward(q).translation() - world(im, im.target).translation()).norm());
      }
      at_cmd = nominal.forward(q);
      const Motion& im = intended.motions[i];
      at_intended = im.target.kind == Target::Kind::kAxis ? truth.forward(q) : world(im, im.target);
      ++i;
      continue;
    }
    if (cmd_run.empty()) q_run = q;
    PathSegment s;
    s.type = m.type == MotionType::kCirc ? PathType::kCirc : PathType::kLin;
    s.T_world_start = at_cmd;
    s.T_world_end = world(m, m.target);
    if (m.aux) s.T_world_aux = world(m, *m.aux);
    cmd_run.push_back(s);
    at_cmd = s.T_world_end;
    const IkResult r = nominal.inverse(s.T_world_end, Configuration{}, q, IkOptions{});
    EXPECT_EQ(r.status, IkStatus::kOk);
    q = r.q;
    const std::array<int, 4> c = *m.target.abb_conf;
    if (m.conf_monitored)
      run.stopped = run.stopped || std::abs(quadrant(q[0]) - c[0]) > 1 || std::abs(quadrant(q[3]) - c[1]) > 1 || std::abs(quadrant(q[5]) - c[2]) > 1;
    if (!inserted[n]) {
      const Motion& im = intended.motions[i++];
      PathSegment is;
      is.type = s.type;
      is.T_world_start = at_intended;
      is.T_world_end = world(im, im.target);
      if (im.aux) is.T_world_aux = world(im, *im.aux);
      intended_run.push_back(is);
      at_intended = is.T_world_end;
    }
  }
  flush();
  return run;
}

// A MoveL with a time (\T) split into pieces: each piece gets its share of the time by its

/// A perturbed IRB 120 (three times the usual errors) and a tolerance of 0.005 mm: long moves
/// are split.
JobSettings splittingSettings() {
  SimulateOptions so;
  so.effects = {"geometric", "joint_compliance"};
  so.set_station = false;
  so.seed = 2;
  so.error_scale = 3;
  JobSettings s = settingsFor(perturbModel(irb120WithTorch(), so));
  s.tol_mm = 0.005;
  return s;
}

// length, so the move still takes it (a copied \T would make each piece take all of it).
TEST(Rapid, ASplitMoveLWithATimeGivesEachPieceItsShare) {
  std::string text = example();
  const std::string away = "MoveL Offs(p60,0,0,100), v200, z20, torch\\WObj:=table;";
  ASSERT_NE(text.find(away), std::string::npos);
  text.replace(text.find(away), away.size(), "MoveL Offs(p60,0,0,100), v200\\T:=7.5, z20, torch\\WObj:=table;");
  const JobSettings s = splittingSettings();
  const ProgramCompensation c = compensateProgramReport(parseRapid(text, "timed.mod"), s);
  ASSERT_TRUE(c.ok()) << c.report.errors.front().message;
  const Program back = parseRapid(writeRapid(c.program), "back.mod");
  std::vector<double> t, len;
  Eigen::Vector3d at = Eigen::Vector3d::Zero();
  for (const Motion& m : back.motions) {
    const double d = back.rapid->statements[static_cast<size_t>(m.statement_id)].duration_s;
    const Eigen::Vector3d to = m.target.completePose() ? poseOf(m.target).translation() : at;
    if (d > 0) {
      t.push_back(d);
      len.push_back((to - at).norm());
    }
    at = to;
  }
  ASSERT_GE(t.size(), 2u) << "the timed MoveL was not split at tol 0.005 mm";
  double sum_t = 0;
  EXPECT_LT(test::durationShareError(t, len, 7.5, &sum_t), 2e-4);  // s; 4 decimals written
  EXPECT_NEAR(sum_t, 7.5, 1e-9);
  // \T:= that is not a time is a located error
  EXPECT_THROW(parseRapid(inProc("    MoveL [[380,40,350],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100\\T:=-2, fine, tool0;\n"), "r.mod"),
               InputError);
}

TEST(Rapid, AMotionSharingItsLineGetsNoAuxiliaryPointsAndSaysSo) {
  // The seam's first line with another statement on it: split, its pieces would repeat the
  // assignment. Its end point is compensated, no point is inserted before it, and the warning
  // says why; written alone on its line, the same motion is split.
  std::string text = example();
  const std::string seam = "    MoveL p30, v20, z1, torch\\WObj:=table;\n";
  ASSERT_NE(text.find(seam), std::string::npos);
  std::string shared = text;
  shared.replace(shared.find(seam), seam.size(), "    seams := 0; MoveL p30, v20, z1, torch\\WObj:=table;\n");
  const JobSettings s = splittingSettings();
  const ProgramCompensation alone = compensateProgramReport(parseRapid(text, "alone.mod"), s);
  const ProgramCompensation with = compensateProgramReport(parseRapid(shared, "shared.mod"), s);
  ASSERT_TRUE(alone.ok() && with.ok());
  auto insertedBefore = [](const Program& p, int line) {
    int n = 0;
    for (const Motion& m : p.motions)
      if (m.inserted && m.where.line == line) ++n;
    return n;
  };
  const int line = parseRapid(text, "alone.mod").motions[3].where.line;  // MoveL p30
  EXPECT_GT(insertedBefore(alone.program, line), 0);
  EXPECT_EQ(insertedBefore(with.program, line), 0);
  bool warned = false;
  for (const auto& w : with.report.warnings)
    warned = warned || (w.where.line == line && w.message.find("it shares its line with another statement: no auxiliary points inserted") != std::string::npos);
  EXPECT_TRUE(warned);
  const std::string written = writeRapid(with.program);
  EXPECT_EQ(written.find("    seams := 0;"), written.rfind("    seams := 0;")) << written;  // the assignment is not repeated
  EXPECT_NE(written.find("    seams := 0; MoveL p30, v20, z1, torch\\WObj:=table;\n"), std::string::npos);
}

TEST(Rapid, RunTimeValuesAreKeptAndNamedNotTakenFromTheDeclaration) {
  // A routine's parameter hides the module datum of its name; a datum assigned while the module
  // runs is not its declared value; a program displacement moves every target after it. Such a
  // motion is kept as written and named (the controller runs it; the declaration would give a
  // wrong correction), the others are compensated.
  const std::string text =
      "MODULE m\n"
      "  PERS tooldata torch := [TRUE,[[0,0,150],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];\n"
      "  PERS wobjdata table := [FALSE,TRUE,\"\",[[300,-150,100],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n"
      "  PERS wobjdata moved := [FALSE,TRUE,\"\",[[300,-150,100],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n"
      "  CONST robtarget p10 := [[40,60,120],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  CONST robtarget p20 := [[40,60,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  PROC main()\n"
      "    MoveJ p10, v1000, z20, torch\\WObj:=table;\n"        // 0: compensated
      "    draw p20, torch;\n"
      "    moved.uframe.trans.x := 500;\n"
      "    MoveL p20, v200, fine, torch\\WObj:=moved;\n"         // 1: its work object is assigned
      "    PDispSet [[0,0,50],[1,0,0,0]];\n"
      "    MoveL p10, v200, fine, torch\\WObj:=table;\n"         // 2: displaced
      "    PDispOff;\n"
      "    MoveL p20, v200, fine, torch\\WObj:=table;\n"         // 3: compensated
      "  ENDPROC\n"
      "  PROC draw(robtarget p10, PERS tooldata torch)\n"
      "    MoveL p10, v200, fine, torch\\WObj:=table;\n"         // 4: both are the call's
      "  ENDPROC\n"
      "ENDMODULE\n";
  const Program p = parseRapid(text, "runtime.mod");
  ASSERT_EQ(p.motions.size(), 5u);
  EXPECT_EQ(p.motions[0].target_problem, "");
  EXPECT_TRUE(p.motions[1].base.run_time);
  EXPECT_EQ(p.motions[1].base.note, "the wobjdata 'moved' is assigned at runtime.mod:10:5: its value at run time is not the declared one");
  EXPECT_NE(p.motions[2].target_problem.find("a program displacement is active (PDispSet at runtime.mod:12:5)"), std::string::npos);
  EXPECT_EQ(p.motions[3].target_problem, "");
  EXPECT_EQ(p.motions[4].target_problem, "'p10' is a parameter of draw: its value comes from the call");
  EXPECT_TRUE(p.motions[4].tool.run_time);
  EXPECT_EQ(p.motions[4].tool.note, "the tooldata 'torch' is a parameter of draw: its value comes from the call");
  // compensated: 0 and 3 changed, 1, 2 and 4 kept and named, no error
  SimulateOptions so;
  so.effects = {"geometric"};
  so.set_station = false;
  so.seed = 4;
  const ProgramCompensation c = compensateProgramReport(p, settingsFor(perturbModel(irb120WithTorch(), so)));
  ASSERT_TRUE(c.ok()) << c.report.errors.front().message;
  EXPECT_EQ(c.report.motions_left_unchanged, 3);
  const std::string written = writeRapid(c.program);
  EXPECT_EQ(written.find("CONST robtarget p10 := [[40,60,120],"), std::string::npos);  // corrected for motion 0
  // p20 is also the argument of `draw p20, torch;` (line 9), whose MoveL goes to it: it keeps
  // its value, and motion 3's correction goes to a new point p20_1 declared after it
  // (copyRapidPointsReadElsewhere); motion 1, kept with p20, is then unchanged on the robot too
  EXPECT_NE(written.find("  CONST robtarget p20 := [[40,60,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
                         "  CONST robtarget p20_1 := [["),
            std::string::npos) << written;
  EXPECT_NE(written.find("    PDispOff;\n    MoveL p20_1, v200, fine, torch\\WObj:=table;\n"), std::string::npos) << written;
  EXPECT_NE(written.find("    MoveL p20, v200, fine, torch\\WObj:=moved;\n"), std::string::npos) << written;
  // the kept motion 2 moves with motion 0's correction of p10: said there, naming the motion the
  // correction is for (motion 4's p10 is the call's, not the module's)
  std::vector<std::string> moved;
  for (const auto& w : c.report.warnings)
    if (w.message.find("is left as written, but its point") != std::string::npos) moved.push_back(w.where.str() + " " + w.message);
  ASSERT_EQ(moved.size(), 1u);
  EXPECT_NE(moved[0].find("runtime.mod:13:5 this motion is left as written, but its point p10 is corrected for the motion at runtime.mod:8:5"),
            std::string::npos) << moved[0];
  bool copied = false;
  for (const auto& w : c.report.warnings)
    copied = copied || w.where.str() + " " + w.message ==
                           "runtime.mod:15:5 p20 is corrected for this motion and also read at runtime.mod:9:10 ('draw p20, torch;'), which the "
                           "correction must not move: the motion goes to a new point p20_1 declared after p20, which keeps its value";
  EXPECT_TRUE(copied);
}

TEST(Rapid, ARoutineCalledWithADisplacementActiveIsDisplaced) {
  // PDispSet ... work; ... PDispOff: work's targets (and those of the routines it calls) are
  // displaced; a routine called after PDispOff, or never with it, is not
  const std::string text =
      "MODULE m\n"
      "  CONST robtarget p10 := [[300,0,400],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  PROC main()\n"
      "    PDispSet [[0,0,50],[1,0,0,0]];\n"
      "    work;\n"
      "    PDispOff;\n"
      "    plain;\n"
      "  ENDPROC\n"
      "  PROC work()\n    MoveL p10, v200, fine, tool0;\n    deeper;\n  ENDPROC\n"   // 0
      "  PROC deeper()\n    MoveL p10, v200, fine, tool0;\n  ENDPROC\n"               // 1
      "  PROC plain()\n    MoveL p10, v200, fine, tool0;\n  ENDPROC\n"                // 2
      "ENDMODULE\n";
  const Program p = parseRapid(text, "pdisp.mod");
  ASSERT_EQ(p.motions.size(), 3u);
  EXPECT_EQ(p.motions[0].target_problem,
            "a program displacement is active (a call of work with PDispOn/PDispSet active at pdisp.mod:5:5): the robot goes to "
            "the displaced target, which accura does not model");
  EXPECT_NE(p.motions[1].target_problem.find("a call of deeper with PDispOn/PDispSet active at pdisp.mod:5:5"), std::string::npos);
  EXPECT_EQ(p.motions[2].target_problem, "");
}

TEST(Rapid, DataACallChangesAreRunTimeValues) {
  // changed without ':=': through a routine's INOUT or VAR parameter, by Add, as SearchL's
  // SearchPoint; a PERS parameter (how tooldata is passed) is read, not taken as changed
  const std::string text =
      "MODULE m\n"
      "  PERS tooldata torch := [TRUE,[[0,0,150],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];\n"
      "  CONST robtarget p10 := [[300,0,400],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  CONST robtarget p20 := [[300,100,400],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  PERS robtarget sp := [[300,50,400],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  VAR robtarget v1 := [[300,150,400],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  VAR robtarget v2 := [[300,200,400],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
      "  PROC main()\n"
      "    SearchL \\Stop, di1, sp, p20, v100, torch;\n"
      "    MoveL sp, v200, fine, torch;\n"      // 1
      "    shift v1, torch;\n"
      "    MoveL v1, v200, fine, torch;\n"      // 2
      "    Add v2.trans.z, 10;\n"
      "    MoveL v2, v200, fine, torch;\n"      // 3
      "    MoveL p10, v200, fine, torch;\n"     // 4
      "    ok := lift(p20);\n"
      "    MoveL p20, v200, fine, torch;\n"     // 5: changed by the function
      "    torch.tload.mass := 1.5;\n"          // (a load: the tool's frame stays)
      "  ENDPROC\n"
      "  PROC shift(INOUT robtarget p, PERS tooldata t)\n    p.trans.x := p.trans.x + 1;\n  ENDPROC\n"
      "  FUNC bool lift(INOUT robtarget pt)\n    pt.trans.z := pt.trans.z + 50;\n    RETURN TRUE;\n  ENDFUNC\n"
      "ENDMODULE\n";
  const Program p = parseRapid(text, "calls.mod");
  ASSERT_EQ(p.motions.size(), 6u);
  EXPECT_EQ(p.motions[5].target_problem, "'p20' is assigned at calls.mod:16:16: its value at run time is not the declared one");
  EXPECT_EQ(p.motions[1].target_problem, "'sp' is assigned at calls.mod:9:25: its value at run time is not the declared one");
  EXPECT_EQ(p.motions[2].target_problem, "'v1' is assigned at calls.mod:11:11: its value at run time is not the declared one");
  EXPECT_EQ(p.motions[3].target_problem, "'v2' is assigned at calls.mod:13:9: its value at run time is not the declared one");
  EXPECT_EQ(p.motions[4].target_problem, "");
  EXPECT_FALSE(p.motions[4].tool.run_time);  // torch passed as PERS: read
  EXPECT_TRUE(p.motions[4].tool.known());
}

TEST(Rapid, CompensatedModuleFollowsTheIntendedPathOnAPerturbedIrb120) {
  const RobotModel controller = irb120WithTorch();
  const Program intended = parseRapid(example(), "irb120_seam.mod");
  for (const std::uint64_t seed : {1, 2, 3}) {
    SimulateOptions so;
    so.effects = {"geometric", "joint_compliance"};
    so.error_scale = 1;
    so.set_station = false;
    so.seed = seed;
    const RobotModel real = perturbModel(controller, so);
    const ProgramCompensation c = compensateProgramReport(intended, settingsFor(real));
    ASSERT_TRUE(c.ok()) << c.report.errors.front().where.str() << ": " << c.report.errors.front().message;
    const std::string written = writeRapid(c.program);
    const Program commanded = parseRapid(written, "compensated.mod");  // what the controller runs
    ASSERT_EQ(commanded.motions.size(), intended.motions.size() + static_cast<size_t>(c.report.points_added));
    std::vector<bool> inserted;
    for (const Motion& m : c.program.motions) inserted.push_back(m.inserted);
    const Execution comp = execute(commanded, inserted, intended, controller, real);
    const Execution as_is = execute(intended, std::vector<bool>(intended.motions.size(), false), intended, controller, real);
    std::printf("seed %d: path %.4f mm compensated (predicted %.4f), %.4f mm as programmed; MoveJ poses %.5f / %.4f mm; %d points added\n",
                static_cast<int>(seed), comp.path_mm, c.report.max_error_after_mm, as_is.path_mm, comp.point_mm, as_is.point_mm,
                c.report.points_added);
    EXPECT_FALSE(comp.stopped) << "seed " << seed;
    EXPECT_LE(comp.path_mm, 0.05 + 2e-3) << "seed " << seed;  // tol + the 4-decimal writing and sampling
    EXPECT_LE(comp.point_mm, 1e-3) << "seed " << seed;
    EXPECT_GT(as_is.path_mm, 0.3) << "seed " << seed;
    // only corrected numbers and inserted lines differ; logic and comments are where they were
    EXPECT_NE(written.find("    SetDO do_torch, 1;  ! arc on\n    MoveL p30, v20, z1, torch\\WObj:=table;\n"), std::string::npos);
    EXPECT_NE(written.find("    seams := seams + 1;\n"), std::string::npos);
    // a split MoveC: a new declared circle point, p40 keeps its value (another motion may use it)
    if (c.report.points_added > 0) {
      EXPECT_NE(written.find("  CONST robtarget p40 := [[220,120,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"), std::string::npos);
      EXPECT_NE(written.find("CONST robtarget p40_1 := [["), std::string::npos);
      EXPECT_NE(written.find("MoveC p40_1, p50,"), std::string::npos);
    }
  }
}

// RobotWare turns the tool along a MoveC relative to the circle's path frame (CirPathMode
// \PathFrame, the default: "the reorientation is performed relative to the circular path"),
// accura's circle in the work object (\ObjectFrame, KUKA's #BASE). The two agree when the turn
// is about the circle's axis (the seam's constant orientation: its path is checked and split);
// a target tilted 10 deg about x at the end of a 150 deg arc is not path-checked and not split
// (points inserted with the work object's orientations would turn the torch by degrees from
// the path the controller runs), its points compensated, and the warning says by how much the
// rules differ: the gap computed here independently (rotation powers by angle-axis).
TEST(Rapid, AMoveCThatTurnsOtherThanAboutItsAxisIsNotPathCheckedUnderObjectFrameRules) {
  SimulateOptions so;
  so.effects = {"geometric", "joint_compliance"};
  so.error_scale = 1;
  so.set_station = false;
  so.seed = 1;
  JobSettings settings = settingsFor(perturbModel(irb120WithTorch(), so));
  settings.tol_mm = 0.01;
  // the seam as it is: its MoveC (constant orientation) is path-checked and split
  const ProgramCompensation plain = compensateProgramReport(parseRapid(example(), "irb120_seam.mod"), settings);
  ASSERT_TRUE(plain.ok());
  int circles = 0;
  for (const SegmentReport& sr : plain.report.segments) circles += sr.instruction == "MoveC" ? 1 : 0;
  EXPECT_EQ(circles, 1);
  for (const ProgramIssue& w : plain.report.warnings) EXPECT_EQ(w.message.find("about the circle's axis"), std::string::npos) << w.message;
  // p50 at 60 deg on the circle about (160, 120) (the arc from p30 at -90 deg: 150 deg), tilted
  const double A = 150 * kDegToRad, beta = 10 * kDegToRad;
  const Eigen::Matrix3d R0 = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix();  // [0,0,1,0]
  const Eigen::Matrix3d R1 = Eigen::AngleAxisd(beta, Eigen::Vector3d::UnitX()).toRotationMatrix() * R0;
  const Eigen::Quaterniond q1(R1);
  char p50[200];
  std::snprintf(p50, sizeof p50, "[[190,171.961524227,20],[%.9f,%.9f,%.9f,%.9f],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]]", q1.w(), q1.x(),
                q1.y(), q1.z());
  std::string module = example();
  const std::string was = "[[160,180,20],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]]";
  ASSERT_NE(module.find(was), std::string::npos);
  module.replace(module.find(was), was.size(), p50);
  const ProgramCompensation c = compensateProgramReport(parseRapid(module, "tilted.mod"), settings);
  ASSERT_TRUE(c.ok()) << c.report.errors.front().message;
  for (const SegmentReport& sr : c.report.segments) EXPECT_NE(sr.instruction, "MoveC");
  std::string said;
  for (const ProgramIssue& w : c.report.warnings)
    if (w.message.find("turns the tool other than about the circle's axis") != std::string::npos) said = w.message;
  ASSERT_FALSE(said.empty());
  EXPECT_EQ(said.rfind("MoveC to p50 turns the tool other than about the circle's axis: RobotWare turns it relative to the circle's path "
                       "(CirPathMode \\PathFrame, the default), up to ", 0), 0u) << said;
  // R(s) = Rz(s A) (Rz(-A) R1 R0^T)^s R0 against (R1 R0^T)^s R0, at the 65 points
  const Eigen::AngleAxisd abb(Eigen::Matrix3d(Eigen::AngleAxisd(-A, Eigen::Vector3d::UnitZ()).toRotationMatrix() * R1 * R0.transpose()));
  const Eigen::AngleAxisd obj(Eigen::Matrix3d(R1 * R0.transpose()));
  double gap = 0;
  for (int k = 0; k <= 64; ++k) {
    const double s = k / 64.0;
    const Eigen::Matrix3d Ra = Eigen::AngleAxisd(s * A, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(s * abb.angle(), abb.axis()) * R0;
    const Eigen::Matrix3d Ro = Eigen::AngleAxisd(s * obj.angle(), obj.axis()) * R0;
    gap = std::max(gap, rotationAngleDeg(Ra * Ro.transpose()));
  }
  EXPECT_GT(gap, 1.0);
  const size_t at = said.find("up to ") + 6;
  EXPECT_NEAR(std::stod(said.substr(at)), gap, 0.006) << said;
  // the targets are compensated all the same: p50's text changed, no point inserted for the MoveC
  const std::string written = writeRapid(c.program);
  EXPECT_EQ(written.find("p40_1"), std::string::npos);
  EXPECT_EQ(written.find(p50), std::string::npos);
}

// The golden files (tests/golden/rapid/README.md), byte for byte.
TEST(Rapid, GoldenFiles) {
  const std::string g = test::sourcePath("tests/golden/rapid/");
  const std::string dir = test::tempDir("rapid_golden");
  for (const char* f : {"irb120_real.xml", "irb120_seam.mod"}) test::writeText(dir + "/" + f, test::readText(g + f));
  const test::CliRun c = test::runAccuraIn(dir, "compensate --robot irb120_real.xml --in irb120_seam.mod --out expected --json expected/report.json");
  ASSERT_EQ(c.code, 0) << c.err;
  EXPECT_EQ(test::readText(dir + "/expected/irb120_seam.mod"), test::readText(g + "expected/irb120_seam.mod"));
  EXPECT_EQ(test::readText(dir + "/expected/report.json"), test::readText(g + "expected/report.json"));
  EXPECT_EQ(test::readText(dir + "/irb120_seam.mod"), example());  // the input untouched
  test::writeText(dir + "/line_arc.xml", test::readText(test::sourcePath("tests/data/rapid/line_arc.xml")));
  const test::CliRun v = test::runAccuraIn(dir, "convert --in line_arc.xml --out line_arc.mod");
  ASSERT_EQ(v.code, 0) << v.err;
  EXPECT_EQ(test::readText(dir + "/line_arc.mod"), test::readText(g + "line_arc.mod"));
  // the converted targets are the XML's, in the same work object
  const Program xml = readProgram(dir + "/line_arc.xml");
  const Program rapid = readProgram(dir + "/line_arc.mod");
  ASSERT_EQ(rapid.motions.size(), xml.motions.size());
  for (size_t k = 0; k < xml.motions.size(); ++k) {
    const Motion& a = xml.motions[k];
    const Motion& b = rapid.motions[k];
    if (a.target.kind == Target::Kind::kAxis) continue;
    const Eigen::Isometry3d want = toIsometry(*a.base.value) * poseOf(a.target);
    const Eigen::Isometry3d got = toIsometry(*b.base.value) * poseOf(b.target);
    EXPECT_LT((got.translation() - want.translation()).norm(), 1e-4) << k;
    EXPECT_LT((got.linear() - want.linear()).norm(), 1e-8) << k;
  }
}

TEST(Rapid, ConvertCarriesTheStatementsOrRefusesNamingTheLine) {
  const std::string dir = test::tempDir("rapid_convert");
  test::writeText(dir + "/seam.mod", example());
  // RAPID -> XML -> RAPID: the logic rides along as pass-through
  ASSERT_EQ(test::runAccuraIn(dir, "convert --in seam.mod --out seam.xml").code, 0);
  const test::CliRun back = test::runAccuraIn(dir, "convert --in seam.xml --out back.mod");
  ASSERT_EQ(back.code, 0) << back.err;
  const std::string b = test::readText(dir + "/back.mod");
  EXPECT_NE(b.find("    SetDO do_torch, 1;  ! arc on\n"), std::string::npos);
  EXPECT_NE(b.find("  VAR num seams := 0;\n"), std::string::npos);
  const Program p = readProgram(dir + "/back.mod");
  EXPECT_EQ(p.motions.size(), 8u);
  // RAPID -> KRL: the first statement KRL cannot carry, named
  const test::CliRun k = test::runAccuraIn(dir, "convert --in seam.mod --out seam.src");
  EXPECT_EQ(k.code, 1);
  EXPECT_NE(k.err.find("seam.mod:6:1: cannot convert the RAPID statement '  CONST jointtarget home := [[0,0,0,0,30,0],[9E9,9E9,9E9,9E9,9E9,9E9]];' to KRL"),
            std::string::npos)
      << k.err;
  // a motion-only module converts to KRL and URScript
  test::writeText(dir + "/lines.mod", inProc("    MoveJ [[380,40,350],[0,0,1,0],[0,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, z10, tool0;\n"
                                             "    MoveL Offs([[380,40,350],[0,0,1,0],[0,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]],0,50,0), v100, z10, tool0;\n"));
  const test::CliRun u = test::runAccuraIn(dir, "convert --in lines.mod --out lines.script");
  ASSERT_EQ(u.code, 0) << u.err;
  EXPECT_NE(test::readText(dir + "/lines.script").find("movel(p[0.3800000, 0.0900000, 0.3500000,"), std::string::npos);
  ASSERT_EQ(test::runAccuraIn(dir, "convert --in lines.mod --out lines.src").code, 0);
  // motions in a second routine: the other formats hold one main program; refused naming it
  test::writeText(dir + "/two.mod", "MODULE two\n  PROC main()\n    MoveJ [[380,40,350],[0,0,1,0],[0,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, z10, tool0;\n"
                                    "  ENDPROC\n  PROC side()\n    MoveJ [[380,40,300],[0,0,1,0],[0,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, z10, tool0;\n"
                                    "  ENDPROC\nENDMODULE\n");
  const test::CliRun two = test::runAccuraIn(dir, "convert --in two.mod --out two.xml");
  EXPECT_EQ(two.code, 1);
  EXPECT_NE(two.err.find("two.mod:5:1: cannot convert '  PROC side()': the motions of the routine on this line are outside main, the first routine with motions"),
            std::string::npos)
      << two.err;
}

// batch picks up .mod and .prg files; check runs the module in its cell: the smallest clearance
// against its analytic value (tests/data/rapid/irb120_table_cell.xml: sqrt(10^2 + 100^2) - 10).
TEST(Rapid, BatchAndCheckInTheCell) {
  const std::string dir = test::tempDir("rapid_batch");
  std::filesystem::create_directories(dir + "/in/cell2");
  test::writeText(dir + "/in/cell2/seam.mod", example());
  test::writeText(dir + "/in/cell2/old.prg", example());
  const test::CliRun b = test::runAccuraIn(dir, "batch --robot abb_irb120 --in in --out out --jobs 1");
  ASSERT_EQ(b.code, 0) << b.err;
  // the nominal robot with the module's own torch: nothing to correct
  EXPECT_EQ(test::readText(dir + "/out/cell2/seam.mod"), example());
  EXPECT_EQ(test::readText(dir + "/out/cell2/old.prg"), example());
  const test::CliRun c = test::runAccuraIn(dir, "check --robot abb_irb120 --cell " + test::sourcePath("tests/data/rapid/irb120_table_cell.xml") +
                                                    " --in " + test::sourcePath("examples/irb120_seam.mod"));
  ASSERT_EQ(c.code, 0) << c.err;
  EXPECT_NE(c.out.find("smallest clearance 90.499 mm"), std::string::npos) << c.out;
  EXPECT_NEAR(std::sqrt(10.0 * 10.0 + 100.0 * 100.0) - 10, 90.499, 5e-4);
}

// EGMRunPose (Externally Guided Motion: the robot goes where a sensor streams it, bypassing the
// path planning; public EGM modules run it between two Moves) was read as a statement that does
// not move the robot: the MoveL after it was compensated and its path predicted from the target
// before it, where the robot is not. It is a motion accura does not model (kept and named), and
// the next motion's start is not known; so are EGMRunJoint, EGMMoveL/EGMMoveC (an EGM-corrected
// path) and the path recorder's and the independent axes' moves.
TEST(Rapid, AnExternallyGuidedMotionMovesTheRobotWhereTheTextDoesNotSay) {
  const std::string text = inProc("    MoveJ [[380,-60,350],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;\n"
                                  "    EGMRunPose egmID1, EGM_STOP_HOLD \\X \\Y \\Z \\CondTime:=10 \\RampInTime:=0.05;\n"
                                  "    MoveL [[380,60,350],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;\n"
                                  "    EGMMoveL egmID1, [[380,0,350],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v10, fine, tool0;\n"
                                  "    PathRecMoveBwd;\n    IndAMove Station_A,2\\ToAbsNum:=90,20;\n");
  const Program p = parseRapid(text, "egm.mod");
  ASSERT_EQ(p.motions.size(), 6u);
  EXPECT_EQ(p.motions[1].target_problem, "EGMRunPose is a motion instruction accura does not model (MoveL, MoveJ, MoveC, MoveAbsJ)");
  EXPECT_EQ(p.motions[3].target_problem, "EGMMoveL is a motion instruction accura does not model (MoveL, MoveJ, MoveC, MoveAbsJ)");
  EXPECT_NE(p.motions[4].target_problem.find("PathRecMoveBwd"), std::string::npos);
  EXPECT_NE(p.motions[5].target_problem.find("IndAMove"), std::string::npos);
  EXPECT_EQ(writeRapid(p), text);
  const ProgramCompensation c = compensateProgramReport(p, settingsFor(shiftedIrb120()));
  ASSERT_TRUE(c.ok()) << c.report.errors.front().message;
  EXPECT_EQ(c.report.motions_left_unchanged, 4);
  bool unknown_start = false;
  for (const ProgramIssue& w : c.report.warnings)
    unknown_start = unknown_start || (w.where.line == 5 && w.message.find("after a position that is not known") != std::string::npos);
  EXPECT_TRUE(unknown_start);
}

// RobotStudio saves the modules of RobotWare 6 and later as .modx (system modules .sysx), the
// same RAPID text as .mod / .sys (public backups hold MODULE .. ENDMODULE in MainModule.modx,
// Module1.modx, CalibData.modx). They were refused ("expected a program file ending in ..
// .mod/.prg"): a module the controller loads. Read, compensated and converted as .mod; batch
// takes the program modules (.modx), not the controller's system modules (.sys, .sysx).
TEST(Rapid, ModulesSavedAsModxSysOrSysxAreRead) {
  for (const char* name : {"a.modx", "B.MODX", "user.sys", "c.sysx"}) EXPECT_EQ(programFormat(name), ProgramFormat::kRapid) << name;
  const std::string dir = test::tempDir("rapid_modx");
  std::filesystem::create_directories(dir + "/in");
  for (const char* name : {"in/seam.modx", "in/user.sys", "in/calib.sysx"}) test::writeText(dir + "/" + name, example());
  const Program mod = parseRapid(example(), "seam.mod");
  const Program modx = readProgram(dir + "/in/seam.modx");
  ASSERT_EQ(modx.motions.size(), mod.motions.size());
  EXPECT_EQ(writeRapid(modx), example());  // written back byte for byte, as a .mod is
  EXPECT_EQ(readProgram(dir + "/in/user.sys").motions.size(), mod.motions.size());
  // written as RAPID by the extension of the output
  const std::vector<calib::OutputFile> files = renderProgram(mod, programFormat(dir + "/out.sysx"), dir + "/out.sysx");
  ASSERT_EQ(files.size(), 1u);
  EXPECT_EQ(files[0].text, example());
  EXPECT_EQ(findPrograms(dir + "/in"), std::vector<std::string>{"seam.modx"});
}

// A module whose tooldata and wobjdata another module of its task declares (CalibData.mod,
// user.sys: RAPID's global data are visible in every module of the task), as public RobotStudio
// modules use `Servo\WObj:=pickTablew` and `\WObj:=dropTablew` declared elsewhere. Two work
// objects cannot both be --program-base: the module was refused ("not declared with a value in
// this module"; --config: "only for KRL and XML programs"), a program the controller runs.
// --config names that module: its data serve the names the module does not declare, and the
// module is compensated exactly as the one module that declares them itself.
TEST(Rapid, TheTasksToolAndWorkObjectsComeFromTheModuleGivenWithConfig) {
  const std::string torch = "  PERS tooldata torch := [TRUE,[[0,0,150],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];\n";
  const std::string table = "  PERS wobjdata table := [FALSE,TRUE,\"\",[[300,-150,100],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n";
  const std::string table2 = "  PERS wobjdata table2 := [FALSE,TRUE,\"\",[[300,-150,110],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n";
  std::string split = example();
  for (const std::string& line : {torch, table}) {
    ASSERT_NE(split.find(line), std::string::npos);
    split.erase(split.find(line), line.size());
  }
  for (const char* motion : {"MoveC p40, p50, v20, z1, torch\\WObj:=table;", "MoveL p60, v20, fine, torch\\WObj:=table;"}) {
    const std::string m = motion;
    ASSERT_NE(split.find(m), std::string::npos) << m;
    split.replace(split.find(m), m.size(), m.substr(0, m.size() - 1) + "2;");
  }
  const size_t decl = split.find("  CONST jointtarget home");
  const std::string whole = split.substr(0, decl) + torch + table + table2 + split.substr(decl);
  const std::string dir = test::tempDir("rapid_task_data");
  test::writeText(dir + "/seam.mod", split);
  test::writeText(dir + "/calib.sys", "MODULE CalibData(SYSMODULE)\n" + torch + table + table2 + "  LOCAL PERS tooldata spare := [TRUE,[[0,0,9],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];\nENDMODULE\n");
  ProgramReadOptions o;
  o.config_path = dir + "/calib.sys";
  const Program p = readProgram(dir + "/seam.mod", o);
  const ProgramCompensation a = compensateProgramReport(p, settingsFor(shiftedIrb120()));
  ASSERT_TRUE(a.ok()) << a.report.errors.front().message;
  const ProgramCompensation b = compensateProgramReport(parseRapid(whole, "seam.mod"), settingsFor(shiftedIrb120()));
  ASSERT_TRUE(b.ok()) << b.report.errors.front().message;
  std::string expected = writeRapid(b.program);
  expected.erase(expected.find(torch), torch.size() + table.size() + table2.size());
  const std::string written = writeRapid(a.program);
  EXPECT_EQ(written, expected);
  EXPECT_NE(written, split);  // (corrected: the base is 0.3 mm off)
  EXPECT_EQ(p.motions[5].base.text, "table2");
  ASSERT_TRUE(p.motions[5].base.value.has_value());
  EXPECT_NEAR(p.motions[5].base.value->z_mm, 110, 1e-12);
  // without it, the names are unknown and the message names the option; a $config.dat is not a module of the task
  const ProgramCompensation alone = compensateProgramReport(parseRapid(split, "seam.mod"), settingsFor(shiftedIrb120()));
  bool named = false;
  for (const ProgramIssue& e : alone.report.errors)
    named = named || e.message == "the base of this motion is not known: the wobjdata 'table2' is not declared with a value in this module (give "
                                  "its frame with --program-base x,y,z,A,B,C, or the module that declares it with --config)";
  EXPECT_TRUE(named);
  o.config_path = dir + "/$config.dat";
  try {
    readProgram(dir + "/seam.mod", o);
    ADD_FAILURE() << "a $config.dat read for a RAPID module";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--config: a KUKA $config.dat is only for KRL and XML programs"), std::string::npos) << e.what();
  }
}

// docs/rapid.md lists a NUL byte as an error: one in a comment, a string or the %%% header was
// read past (the comment and string scanners skipped it), and the module was compensated.
// Anywhere in the file it is the error, at its line and column.
TEST(Rapid, ANulByteInACommentAStringOrTheHeaderIsAnError) {
  const std::string nul(1, '\0');
  const std::string msg = "expected a RAPID text file, found a NUL byte (binary file?)";
  // in a comment on a statement's line (the tester's bad_nul.mod: "SetDO do_torch, 1;  ! arc<NUL>on")
  std::string text = example();
  const std::string arc = "SetDO do_torch, 1;  ! arc on";
  ASSERT_NE(text.find(arc), std::string::npos);
  text.replace(text.find(arc), arc.size(), "SetDO do_torch, 1;  ! arc" + nul + "on");
  EXPECT_EQ(errorOf(text), "bad.mod:20:30: " + msg);  // (line 20: "    SetDO", the NUL after "! arc")
  // in a string
  EXPECT_EQ(errorOf(inProc("    TPWrite \"a" + nul + "b\";\n")), "bad.mod:3:15: " + msg);
  // in a comment line of its own, and in a .prg's %%% header
  EXPECT_EQ(errorOf("MODULE m\n  ! x" + nul + "\n  PROC main()\n  ENDPROC\nENDMODULE\n"), "bad.mod:2:6: " + msg);
  EXPECT_EQ(errorOf("%%%\n  VERSION:1" + nul + "\n%%%\nMODULE m\nENDMODULE\n"), "bad.mod:2:12: " + msg);
  // the first of several
  EXPECT_EQ(errorOf("MODULE m" + nul + "\n  !" + nul + "\nENDMODULE\n"), "bad.mod:1:9: " + msg);
}

// An error quoted the offending text whole: 20000 nested '[' (the tester's bad_nest.mod) gave a
// 40 KB message. Every quoted excerpt is at most 80 bytes: its first 77 and "...", not cut
// inside a UTF-8 character.
TEST(Rapid, AnErrorQuotesAtMost80BytesOfTheText) {
  const std::string deep = std::string(20000, '[') + std::string(20000, ']');
  const std::string nest = errorOf(inProc("    MoveL " + deep + ", v100, fine, tool0;\n"));
  EXPECT_EQ(nest, "bad.mod:3:11: expected a robtarget [[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax_a,..,eax_f]] with 4 items, found 1 in '" +
                      std::string(77, '[') + "...'");
  // a statement without its ';' that runs on: 'TPWrite "x' and 2-byte characters (U+00E9): the
  // 77th byte would be the first of one, which is left out whole (76 bytes and "...")
  std::string e_acute;
  for (int k = 0; k < 200; ++k) e_acute += "\xC3\xA9";
  const std::string semi = errorOf(inProc("    TPWrite \"x" + e_acute + "\"\n"));
  std::string want_q = "TPWrite \"x";
  for (int k = 0; k < 33; ++k) want_q += "\xC3\xA9";
  ASSERT_EQ(want_q.size(), 76u);
  EXPECT_EQ(semi, "bad.mod:3:416: expected ';' at the end of the statement '" + want_q + "...', found ENDPROC");
  // a 5000-digit number in a position, a 3000-character name
  const std::string digits = "1" + std::string(4999, '0');
  EXPECT_EQ(errorOf(inProc("    MoveL [[1,2," + digits + "],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v100, fine, tool0;\n")),
            "bad.mod:3:17: expected a finite number, found '" + digits.substr(0, 77) + "...'");
  const std::string name(3000, 'q');
  EXPECT_EQ(errorOf(name + ";\n"), "bad.mod:1:1: expected MODULE before the first statement, found '" + name.substr(0, 77) + "...'");
}

// Offs/RelTool nested 20000 deep overflowed the stack (each level a call): a crash, not an
// error. Nesting is bounded; 100 levels are read.
TEST(Rapid, OffsNestedBeyondABoundIsAnErrorNotACrash) {
  auto nested = [](int n) {
    std::string s;
    for (int k = 0; k < n; ++k) s += "Offs(";
    s += "[[1,2,3],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]]";
    for (int k = 0; k < n; ++k) s += ",0,0,1)";
    return s;
  };
  const Program p = parseRapid(inProc("    MoveL " + nested(100) + ", v100, fine, tool0;\n"), "ok.mod");
  ASSERT_EQ(p.motions.size(), 1u);
  EXPECT_NEAR(poseOf(p.motions[0].target).translation().z(), 103.0, 1e-9);  // 3 + 100 x 1 mm
  // (column 511: the 101st Offs, after 100 x "Offs(" from column 11)
  EXPECT_EQ(errorOf(inProc("    MoveL " + nested(20000) + ", v100, fine, tool0;\n")),
            "bad.mod:3:511: expected Offs/RelTool nested at most 100 deep, found deeper nesting");
}

// The same program with its data first, in one module: the reference the tests of the data's
// scope compare with (targets of a perturbed IRB 120's compensation).
const std::string kTool = "  PERS tooldata tWeld:=[TRUE,[[0,0,150],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];\n";
const std::string kWobj = "  PERS wobjdata wTable:=[FALSE,TRUE,\"\",[[300,-150,100],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n";
const std::string kP10 = "  PERS robtarget p10:=[[40,60,120],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n";
const std::string kP20 = "  PERS robtarget p20:=[[40,60,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n";
const std::string kMain = "  PROC main()\n    ConfL\\Off;\n    MoveJ p10,v1000,z50,tWeld\\WObj:=wTable;\n    MoveL p20,v200,fine,tWeld\\WObj:=wTable;\n  ENDPROC\n";

JobSettings perturbedIrb120() {
  SimulateOptions so;
  so.effects = {"geometric"};
  so.set_station = false;
  so.seed = 9;
  return settingsFor(perturbModel(test::loadBundled("abb_irb120"), so));
}

/// The compensated targets of `text` (each motion's, in order); the compensation must succeed
/// without leaving a motion unchanged.
std::vector<Eigen::Isometry3d> compensatedTargets(const std::string& text, const std::string& name) {
  const ProgramCompensation c = compensateProgramReport(parseRapid(text, name), perturbedIrb120());
  EXPECT_TRUE(c.ok()) << name << ": " << (c.ok() ? std::string() : c.report.errors.front().message);
  EXPECT_EQ(c.report.motions_left_unchanged, 0) << name << ": " << (c.report.warnings.empty() ? "" : c.report.warnings.front().message);
  std::vector<Eigen::Isometry3d> out;
  for (const Motion& m : c.program.motions)
    if (m.target.completePose()) out.push_back(poseOf(m.target));
  return out;
}

// A .prg whose main module comes first and whose data module (tooldata, wobjdata, robtargets,
// all global) comes after it: the data were not found ("'p10' is not a robtarget declared
// with a value in this module"), every motion left unchanged with exit 0, and convert to XML
// wrote <ref name="p10"/>. The global data of a task are visible in every module whatever the
// order: the corrections are those of the same program in one module, data first.
TEST(Rapid, GlobalDataOfALaterModuleAreVisibleInEveryModule) {
  const std::string head = "%%%\n  VERSION:1\n  LANGUAGE:ENGLISH\n%%%\n\n";
  const std::string two = head + "MODULE mainmod\n" + kMain + "ENDMODULE\n\nMODULE datamod\n" + kTool + kWobj + kP10 + kP20 + "ENDMODULE\n";
  const std::string one = head + "MODULE mainmod\n" + kTool + kWobj + kP10 + kP20 + kMain + "ENDMODULE\n";
  const Program p = parseRapid(two, "r14_xmod.prg");
  ASSERT_EQ(p.motions.size(), 2u);
  for (const Motion& m : p.motions) {
    EXPECT_EQ(m.target_problem, "");
    ASSERT_TRUE(m.tool.value && m.base.value);
    EXPECT_LT((toIsometry(*m.tool.value).translation() - Eigen::Vector3d(0, 0, 150)).norm(), 1e-12);
    EXPECT_LT((toIsometry(*m.base.value).translation() - Eigen::Vector3d(300, -150, 100)).norm(), 1e-12);
  }
  EXPECT_LT((poseOf(p.motions[0].target).translation() - Eigen::Vector3d(40, 60, 120)).norm(), 1e-12);
  const std::vector<Eigen::Isometry3d> a = compensatedTargets(two, "two.prg"), b = compensatedTargets(one, "one.prg");
  ASSERT_EQ(a.size(), 2u);
  ASSERT_EQ(b.size(), 2u);
  for (size_t k = 0; k < 2; ++k) {
    EXPECT_LT((a[k].translation() - b[k].translation()).norm(), 1e-9) << k;
    EXPECT_LT((a[k].linear() - b[k].linear()).norm(), 1e-12) << k;
    EXPECT_GT((a[k].translation() - poseOf(p.motions[k].target).translation()).norm(), 0.1) << k;  // corrected
  }
  // written into the data module's declarations
  const ProgramCompensation c = compensateProgramReport(p, perturbedIrb120());
  const std::string written = writeRapid(c.program);
  EXPECT_EQ(written.find(kP10), std::string::npos);
  EXPECT_NE(written.find("ENDMODULE\n\nMODULE datamod\n" + kTool + kWobj + "  PERS robtarget p10:=[["), std::string::npos) << written;
  // convert to XML: the targets' values and the frames, not <ref name="p10"/>
  const std::string dir = test::tempDir("rapid_xmod");
  test::writeText(dir + "/r14_xmod.prg", two);
  const test::CliRun x = test::runAccuraIn(dir, "convert --in r14_xmod.prg --out r14.xml");
  ASSERT_EQ(x.code, 0) << x.err;
  const std::string xml = test::readText(dir + "/r14.xml");
  EXPECT_EQ(xml.find("<ref name="), std::string::npos) << xml;
  EXPECT_NE(xml.find("<pose name=\"p10\" x_mm=\"40.0000\" y_mm=\"60.0000\" z_mm=\"120.0000\""), std::string::npos) << xml;
  EXPECT_NE(xml.find("<tool source=\"inline\" x_mm=\"0.0000\" y_mm=\"0.0000\" z_mm=\"150.0000\""), std::string::npos) << xml;
  EXPECT_NE(xml.find("<base source=\"inline\" x_mm=\"300.0000\" y_mm=\"-150.0000\" z_mm=\"100.0000\""), std::string::npos) << xml;
}

// Module data declared after the routines that use them (the tester's r15_toolafter.mod: the
// tooldata and wobjdata after ENDPROC; r04_args.mod: a robtarget after ENDPROC) were "not
// declared with a value in this module" (an error, or the motion left unchanged). A module's
// data are visible to all its routines: the corrections are those of the data-first module.
TEST(Rapid, ModuleDataDeclaredAfterTheRoutinesAreVisibleToThem) {
  const std::string tool_after = "MODULE ToolAfter\n" + kP10 + kP20 + kMain + kTool + kWobj + "ENDMODULE\n";
  const std::string all_after = "MODULE AllAfter\n" + kMain + kTool + kWobj + kP10 + kP20 + "ENDMODULE\n";
  const std::string first = "MODULE First\n" + kTool + kWobj + kP10 + kP20 + kMain + "ENDMODULE\n";
  const std::vector<Eigen::Isometry3d> want = compensatedTargets(first, "first.mod");
  ASSERT_EQ(want.size(), 2u);
  for (const std::string* text : {&tool_after, &all_after}) {
    const std::vector<Eigen::Isometry3d> got = compensatedTargets(*text, "after.mod");
    ASSERT_EQ(got.size(), 2u);
    for (size_t k = 0; k < 2; ++k) EXPECT_LT((got[k].translation() - want[k].translation()).norm(), 1e-9) << *text << k;
  }
  const Program p = parseRapid(all_after, "after.mod");
  EXPECT_EQ(p.motions[1].target.where.line, 10);  // p20's value, after ENDPROC (line 10)
  // convert to XML: the tool is there
  const std::string dir = test::tempDir("rapid_after");
  test::writeText(dir + "/after.mod", tool_after);
  const test::CliRun x = test::runAccuraIn(dir, "convert --in after.mod --out after.xml");
  ASSERT_EQ(x.code, 0) << x.err;
  EXPECT_NE(test::readText(dir + "/after.xml").find("<tool source=\"inline\" x_mm=\"0.0000\" y_mm=\"0.0000\" z_mm=\"150.0000\""), std::string::npos);
}

// The scope rules kept with the module data read first: LOCAL data are their module's only (a
// LOCAL datum hides a global one of its name there), a routine's data are its own and hide the
// module's (also a routine's datum of another type), and a name whose value accura reads
// declared twice in one scope is an error naming both (the controller refuses it).
TEST(Rapid, LocalAndRoutineDataKeepTheirScope) {
  const std::string v1 = "[[40,60,120],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]]";
  const std::string v2 = "[[160,60,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]]";
  const std::string text =
      "MODULE a\n"
      "  PROC main()\n"
      "    MoveJ p10,v1000,z50,tool0;\n"          // 0: a's LOCAL p10 (declared after)
      "    MoveJ q,v1000,z50,tool0;\n"            // 1: b's LOCAL q: not visible here
      "    MoveJ r,v1000,z50,tool0;\n"            // 2: b's global r
      "    side;\n"
      "  ENDPROC\n"
      "  PROC side()\n"
      "    VAR num p10 := 1;\n"
      "    MoveJ p10,v1000,z50,tool0;\n"          // 3: side's num p10 hides the robtarget
      "  ENDPROC\n"
      "  LOCAL CONST robtarget p10 := " + v2 + ";\n"
      "ENDMODULE\n"
      "MODULE b\n"
      "  PROC work()\n"
      "    MoveJ p10,v1000,z50,tool0;\n"          // 4: b's global p10, not a's LOCAL one
      "    MoveJ q,v1000,z50,tool0;\n"            // 5: b's LOCAL q
      "  ENDPROC\n"
      "  CONST robtarget p10 := " + v1 + ";\n"
      "  LOCAL CONST robtarget q := " + v1 + ";\n"
      "  CONST robtarget r := " + v2 + ";\n"
      "ENDMODULE\n";
  const Program p = parseRapid(text, "scope.prg");
  ASSERT_EQ(p.motions.size(), 6u);
  auto x = [&](size_t k) { return poseOf(p.motions[k].target).translation().x(); };
  EXPECT_EQ(p.motions[0].target_problem, "");
  EXPECT_EQ(x(0), 160);
  EXPECT_EQ(p.motions[1].target_problem, "'q' is not a robtarget declared with a value in this module");
  EXPECT_EQ(p.motions[2].target_problem, "");
  EXPECT_EQ(x(2), 160);
  EXPECT_EQ(p.motions[3].target_problem, "'p10' is not a robtarget declared with a value in this module");
  EXPECT_EQ(p.motions[4].target_problem, "");
  EXPECT_EQ(x(4), 40);
  EXPECT_EQ(x(5), 40);
  // a routine's robtarget hides the module's there only (r07_shadow.mod)
  const Program sh = parseRapid("MODULE m\n  CONST robtarget p10 := " + v1 + ";\n  PROC main()\n    CONST robtarget p10 := " + v2 +
                                    ";\n    MoveJ p10,v1000,z50,tool0;\n  ENDPROC\n  PROC other()\n    MoveJ p10,v1000,z50,tool0;\n  ENDPROC\nENDMODULE\n",
                                "shadow.mod");
  ASSERT_EQ(sh.motions.size(), 2u);
  EXPECT_EQ(poseOf(sh.motions[0].target).translation().x(), 160);
  EXPECT_EQ(poseOf(sh.motions[1].target).translation().x(), 40);
  // two declarations of one name
  EXPECT_EQ(errorOf("MODULE a\n  CONST robtarget p10 := " + v1 + ";\nENDMODULE\nMODULE b\n  PERS robtarget p10 := " + v2 + ";\nENDMODULE\n"),
            "bad.mod:5:18: expected one declaration of 'p10' in the program's global data (its modules share the data that is not LOCAL), "
            "found a second (the first at bad.mod:2:19)");
  EXPECT_EQ(errorOf("MODULE a\n  CONST robtarget p10 := " + v1 + ";\n  PROC main()\n  ENDPROC\n  LOCAL CONST robtarget p10 := " + v2 + ";\nENDMODULE\n"),
            "bad.mod:5:25: expected one declaration of 'p10' in the module, found a second (the first at bad.mod:2:19)");
  EXPECT_EQ(errorOf("MODULE a\n  PROC main()\n    VAR tooldata t := [TRUE,[[0,0,1],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];\n"
                    "    VAR tooldata t := [TRUE,[[0,0,2],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];\n  ENDPROC\nENDMODULE\n"),
            "bad.mod:4:18: expected one declaration of 't' in the routine main, found a second (the first at bad.mod:3:18)");
  // the same persistent declared alike in two modules (a tool module and the main module): one
  // object they share, read; declared with different values, still the error
  const Program shared = parseRapid("MODULE a\n  PERS robtarget p10 := " + v1 + ";\n  PROC main()\n    MoveJ p10,v1000,z50,tool0;\n  ENDPROC\n"
                                    "ENDMODULE\nMODULE b\n  PERS robtarget p10 := " + v1 + ";\nENDMODULE\n", "shared.prg");
  ASSERT_EQ(shared.motions.size(), 1u);
  EXPECT_EQ(shared.motions[0].target_problem, "");
  EXPECT_EQ(poseOf(shared.motions[0].target).translation().x(), 40);
  EXPECT_NE(errorOf("MODULE a\n  PERS robtarget p10 := " + v1 + ";\nENDMODULE\nMODULE b\n  PERS robtarget p10 := " + v2 + ";\nENDMODULE\n")
                .find("expected one declaration of 'p10' in the program's global data"),
            std::string::npos);
  // a LOCAL datum of one module and a global one of another: both fine (each module its own)
  EXPECT_NO_THROW(parseRapid("MODULE a\n  LOCAL CONST robtarget p10 := " + v1 + ";\nENDMODULE\nMODULE b\n  CONST robtarget p10 := " + v2 + ";\nENDMODULE\n", "ok.prg"));
}

// A convert of a module whose tooldata is not declared in it (nor in another module of the
// file: a system module's) wrote an XML without tool, without a word (the tester's
// r15_toolafter.mod before its tool was found). Refused naming the motion and the tooldata;
// compensate still names the option that supplies it.
TEST(Rapid, ConvertRefusesAMotionWhoseToolOrWorkObjectIsNotDeclared) {
  const std::string dir = test::tempDir("rapid_notool");
  test::writeText(dir + "/notool.mod", "MODULE m\n" + kWobj + kP10 + "  PROC main()\n    MoveJ p10,v1000,z50,tSys\\WObj:=wTable;\n  ENDPROC\nENDMODULE\n");
  for (const char* out : {"notool.xml", "notool.src", "notool.script"}) {
    const test::CliRun c = test::runAccuraIn(dir, std::string("convert --in notool.mod --out ") + out);
    EXPECT_EQ(c.code, 1) << out;
    EXPECT_NE(c.err.find("notool.mod:5:5: cannot convert 'MoveJ p10,v1000,z50,tSys\\WObj:=wTable;': the tooldata 'tSys' is not declared with a "
                         "value in the program (a system module's?), so the converted motion would have no tool"),
              std::string::npos)
        << c.err;
    EXPECT_FALSE(std::filesystem::exists(dir + "/" + out));
  }
  test::writeText(dir + "/nowobj.mod", "MODULE m\n" + kTool + kP10 + "  PROC main()\n    MoveJ p10,v1000,z50,tWeld\\WObj:=wSys;\n  ENDPROC\nENDMODULE\n");
  const test::CliRun w = test::runAccuraIn(dir, "convert --in nowobj.mod --out nowobj.xml");
  EXPECT_EQ(w.code, 1);
  EXPECT_NE(w.err.find("nowobj.mod:5:5: cannot convert 'MoveJ p10,v1000,z50,tWeld\\WObj:=wSys;': the wobjdata 'wSys' is not declared"), std::string::npos)
      << w.err;
  // the same module into RAPID: as it is
  const test::CliRun r = test::runAccuraIn(dir, "convert --in notool.mod --out same.mod");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(test::readText(dir + "/same.mod"), test::readText(dir + "/notool.mod"));
}

// A robtarget corrected by one motion and also read elsewhere (the tester's r13_syntax.mod:
// `MoveL Offs(p20, 0, 0, dz)` with dz a VAR num is kept as written) silently moved that read
// with the correction. The reader records the first such read of each declaration; the
// compensation leaves the declaration as it is and sends the motions that correct it to a new
// point declared after it, with the value the point gets where nothing else reads it.
TEST(Rapid, APointAlsoReadElsewhereKeepsItsValueAndTheMotionsGoToANewPoint) {
  const std::string head = "MODULE m\n" + kTool + kWobj + "  VAR num dz:=50;\n" + kP10 + kP20;  // (a run-time value)
  const std::string moves_a = "  PROC main()\n    ConfL\\Off;\n    MoveJ p10,v1000,z50,tWeld\\WObj:=wTable;\n    MoveL p20,v200,fine,tWeld\\WObj:=wTable;\n";
  const std::string offs = "    MoveL Offs(p20,0,0,dz),v200,fine,tWeld\\WObj:=wTable;\n";
  const std::string moves_b = "    MoveL p20,v200,z10,tWeld\\WObj:=wTable;\n  ENDPROC\nENDMODULE\n";
  const std::string text = head + moves_a + offs + moves_b;  // (the Offs on line 11)
  const std::string alone = head + moves_a + moves_b;        // nothing else reads p20
  // the reader: where each point is read other than as a plain target
  const Program p = parseRapid(text, "r.mod");
  ASSERT_EQ(p.rapid->decls.size(), 2u);
  EXPECT_EQ(p.rapid->decls[0].read_elsewhere, "");
  EXPECT_EQ(p.rapid->decls[1].read_elsewhere, "r.mod:11:16 ('MoveL Offs(p20,0,0,dz),v200,fine,tWeld\\WObj:=wTable;')");
  const JobSettings real = perturbedIrb120();
  const ProgramCompensation c = compensateProgramReport(p, real), a = compensateProgramReport(parseRapid(alone, "alone.mod"), real);
  ASSERT_TRUE(c.ok() && a.ok());
  const std::string written = writeRapid(c.program), want = writeRapid(a.program);
  // alone: p20 corrected in its declaration; its value there is the new point's here
  const size_t at = want.find("  PERS robtarget p20:=[[");
  ASSERT_NE(at, std::string::npos);
  ASSERT_EQ(want.find(kP20), std::string::npos);
  const std::string corrected = want.substr(at + std::string("  PERS robtarget p20:=").size(), want.find(";\n", at) - at - std::string("  PERS robtarget p20:=").size());
  EXPECT_NE(written.find(kP20 + "  PERS robtarget p20_1 := " + corrected + ";\n"), std::string::npos) << written << want;
  EXPECT_NE(written.find("    MoveL p20_1,v200,fine,tWeld\\WObj:=wTable;\n" + offs + "    MoveL p20_1,v200,z10,tWeld\\WObj:=wTable;\n"), std::string::npos)
      << written;
  EXPECT_EQ(written.find("p20_1 :="), written.rfind("p20_1 :="));  // declared once
  // said at the first motion that corrects it, naming the read; the report names the new point
  bool said = false;
  for (const auto& w : c.report.warnings)
    said = said || w.where.str() + " " + w.message ==
                       "r.mod:10:5 p20 is corrected for this motion and also read at r.mod:11:16 ('MoveL Offs(p20,0,0,dz),v200,fine,"
                       "tWeld\\WObj:=wTable;'), which the correction must not move: the motion goes to a new point p20_1 declared after p20, "
                       "which keeps its value";
  EXPECT_TRUE(said);
  int renamed = 0;
  for (const TargetReport& t : c.report.targets) renamed += t.name == "p20_1" && t.new_point_replaces == "p20";
  EXPECT_EQ(renamed, 2);
  // read back: the Offs still reads p20's written value, the motions go to p20_1
  const Program back = parseRapid(written, "back.mod");
  ASSERT_EQ(back.motions.size(), 4u);
  EXPECT_EQ(back.motions[1].target.name, "p20_1");
  EXPECT_LT((poseOf(back.motions[1].target).translation() - poseOf(a.program.motions[1].target).translation()).norm(), 1e-4);
  // the nominal robot: byte for byte
  JobSettings nominal;
  nominal.calibrated = test::loadBundled("abb_irb120");
  const ProgramCompensation n = compensateProgramReport(p, nominal);
  ASSERT_TRUE(n.ok());
  EXPECT_EQ(writeRapid(n.program), text);
}

// What counts as a read elsewhere: an assignment's right-hand side, a call's argument, a
// condition, a declaration's value, a motion instruction accura does not model, an Offs the
// reader cannot evaluate; not a plain target, not an evaluated Offs (written as an inline
// robtarget when corrected), not the routine's parameter or datum of that name.
TEST(Rapid, TheReaderRecordsTheFirstReadOfEachRobtargetOtherThanAPlainTarget) {
  const std::string v = ":=[[40,60,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n";
  auto firstRead = [&](const std::string& body, const std::string& more = "") {
    const Program p = parseRapid("MODULE m\n  VAR robtarget pa" + v + "  CONST robtarget p20" + v + "  PROC main()\n" + body + "  ENDPROC\n" + more + "ENDMODULE\n", "r.mod");
    for (const RapidSource::Decl& d : p.rapid->decls)
      if (d.name == "p20") return d.read_elsewhere;
    return std::string("no p20");
  };
  EXPECT_EQ(firstRead("    MoveL p20,v200,fine,tool0;\n    MoveC p20,p20,v200,fine,tool0;\n    MoveL Offs(p20,0,0,10),v200,fine,tool0;\n"), "");
  EXPECT_EQ(firstRead("    MoveL p20,v200,fine,tool0;\n    pa := p20;\n"), "r.mod:6:11 ('pa := p20;')");
  EXPECT_EQ(firstRead("    pa.trans := p20.trans;\n"), "r.mod:5:17 ('pa.trans := p20.trans;')");
  EXPECT_EQ(firstRead("    draw p20;\n", "  PROC draw(robtarget p)\n  ENDPROC\n"), "r.mod:5:10 ('draw p20;')");
  EXPECT_EQ(firstRead("    IF p20.trans.z > 10 THEN\n    ENDIF\n"), "r.mod:5:8 ('IF p20.trans.z > 10 THEN')");
  EXPECT_EQ(firstRead("    VAR robtarget pb := p20;\n"), "r.mod:5:25 ('VAR robtarget pb := p20;')");
  EXPECT_EQ(firstRead("    SearchL \\Stop,di1,pa,p20,v200,tool0;\n"), "r.mod:5:26 ('SearchL \\Stop,di1,pa,p20,v200,tool0;')");
  EXPECT_EQ(firstRead("    MoveLDO p20,v200,fine,tool0,do1,1;\n    TriggC p20,p20,v200,gunon,fine,tool0;\n"), "");  // (compensated as MoveL's)
  EXPECT_EQ(firstRead("    MoveL RelTool(p20,0,0,n),v200,fine,tool0;\n"), "r.mod:5:19 ('MoveL RelTool(p20,0,0,n),v200,fine,tool0;')");
  EXPECT_EQ(firstRead("    MoveJ CalcRobT(CalcJointT(p20,tool0),tool0),v200,fine,tool0;\n"),
            "r.mod:5:31 ('MoveJ CalcRobT(CalcJointT(p20,tool0),tool0),v200,fine,tool0;')");
  // another routine's parameter or datum of the name is not the module's p20
  EXPECT_EQ(firstRead("", "  PROC other(robtarget p20)\n    pa := p20;\n  ENDPROC\n"), "");
  EXPECT_EQ(firstRead("", "  PROC other()\n    VAR robtarget p20" + v + "    pa := p20;\n  ENDPROC\n"), "");
}

// --program-tool / --program-base give the frame of one tooldata / wobjdata the module names
// but does not declare (a system module's, user.sys); a second undeclared name is another frame
// on the controller (ABB RAPID: each tooldata is a datum of its own), which the option does not
// give: refused naming both, not given the first one's TCP without a word. The same name in
// another case is the same datum (RAPID names are case-insensitive).
TEST(Rapid, OneProgramToolIsTheFrameOfOneUndeclaredToolNotOfEvery) {
  const std::string t1 = "[[380,40,350],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]]";
  const std::string t2 = "[[380,40,300],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]]";
  JobSettings s = settingsFor(test::loadBundled("abb_irb120"));
  s.initial_tool = XyzAbc{0, 0, 100, 0, 0, 0};
  const Program two = parseRapid(inProc("    MoveL " + t1 + ", v100, fine, tGripper;\n    MoveL " + t2 + ", v100, fine, tWeld;\n"), "r.mod");
  try {
    compensateProgramReport(two, s);
    ADD_FAILURE() << "two undeclared tooldata took one --program-tool";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              "r.mod:4:5: expected one tooldata that the program does not declare (--program-tool gives its TCP, taken for 'tGripper' at "
              "r.mod:3:5), found a second, 'tWeld', whose value the controller has and accura does not: declare it in the module");
  }
  // the same for work objects
  JobSettings sb = settingsFor(test::loadBundled("abb_irb120"));
  sb.initial_base = XyzAbc{0, 0, 0, 0, 0, 0};
  EXPECT_THROW(compensateProgramReport(parseRapid(inProc("    MoveL " + t1 + ", v100, fine, tool0\\WObj:=wA;\n    MoveL " + t2 +
                                                         ", v100, fine, tool0\\WObj:=wB;\n"), "r.mod"), sb),
               InputError);
  // one undeclared tool written in two cases: the option's TCP for both
  const ProgramCompensation one =
      compensateProgramReport(parseRapid(inProc("    MoveL " + t1 + ", v100, fine, tGripper;\n    MoveL " + t2 + ", v100, fine, TGRIPPER;\n"), "r.mod"), s);
  EXPECT_TRUE(one.ok());
}

// MoveJDO, MoveLSync, TriggL, MoveCDO (ABB, Technical reference manual - RAPID Instructions:
// each moves as MoveJ / MoveL / MoveC and sets a signal, calls a procedure or fires triggers
// besides) and ArcLStart, ArcC, ArcLEnd (arc welding: they move as MoveL / MoveC and weld)
// have their targets compensated as those of MoveJ / MoveL / MoveC: the module written
// is the one the plain instructions give (a different route, the instructions compensated since
// issue 12), with only the instruction lines as written. Their other arguments (\Conc, \T2,
// the signal, the procedure) are kept byte for byte, they are never split (the pieces would
// repeat the signal, the triggers, the procedure), and no other format takes them. Before:
// kept as written, uncompensated.
TEST(Rapid, MoveDoSyncTriggAndArcInstructionsHaveTheirTargetsCompensatedAsMoveLJC) {
  using Lines = std::vector<std::pair<std::string, std::string>>;
  const Lines sets[] = {
      {{"MoveJ p10, v1000, z20, torch\\WObj:=table;", "MoveJDO p10, v1000, z20, torch\\WObj:=table, do_gun, 0;"},
       {"MoveL p20, v200, fine, torch\\WObj:=table;", "MoveLSync p20, v200, fine, torch\\WObj:=table, \"gun_ready\";"},
       {"MoveL p30, v20, z1, torch\\WObj:=table;", "TriggL \\Conc, p30, v20, gunon \\T2:=gunoff, z1, torch\\WObj:=table;"},
       {"MoveC p40, p50, v20, z1, torch\\WObj:=table;", "MoveCDO p40, p50, v20, z1, torch\\WObj:=table, do_gun, 1;"}},
      // arc welding (RobotWare Arc: ArcLStart ToPoint, Speed, Seam, Weld [\Weave], Zone, Tool [\WObj] [\Track], as production modules write it)
      {{"MoveL p30, v20, z1, torch\\WObj:=table;", "ArcLStart p30, v20, seam1, weld1, z1, torch\\WObj:=table;"},
       {"MoveC p40, p50, v20, z1, torch\\WObj:=table;", "ArcC p40, p50, v20, seam1, weld1\\Weave:=weave1, z1, torch\\WObj:=table\\Track:=track1;"},
       {"MoveL p60, v20, fine, torch\\WObj:=table;", "ArcLEnd p60, v20, seam1, weld1\\Weave:=weave1, fine, torch\\WObj:=table;"}}};
  SimulateOptions so;
  so.effects = {"geometric", "joint_compliance"};
  so.set_station = false;
  so.seed = 2;
  JobSettings s = settingsFor(perturbModel(irb120WithTorch(), so));
  s.tol_mm = 10;  // (no piece in the plain module either)
  const ProgramCompensation plain = compensateProgramReport(parseRapid(example(), "plain.mod"), s);
  ASSERT_TRUE(plain.ok()) << plain.report.errors.front().message;
  const std::string written_plain = writeRapid(plain.program);
  ASSERT_NE(written_plain, example());  // (the targets are corrected)
  // a tolerance that splits the plain MoveLs and the MoveC
  JobSettings fine_tol = s;
  fine_tol.tol_mm = 0.001;
  const ProgramCompensation split = compensateProgramReport(parseRapid(example(), "plain.mod"), fine_tol);
  ASSERT_TRUE(split.ok());
  auto pieces = [](const ProgramCompensation& pc, const std::string& of) {
    int n = 0;
    for (const Motion& m : pc.program.motions) n += m.inserted && m.statement == of ? 1 : 0;
    return n;
  };
  for (const Lines& lines : sets) {
    auto special = [&](std::string text) {
      for (const auto& [plain_line, other] : lines) {
        const size_t at = text.find(plain_line);
        EXPECT_NE(at, std::string::npos) << plain_line;
        if (at != std::string::npos) text.replace(at, plain_line.size(), other);
      }
      return text;
    };
    const ProgramCompensation c = compensateProgramReport(parseRapid(special(example()), "other.mod"), s);
    ASSERT_TRUE(c.ok()) << c.report.errors.front().message;
    for (const ProgramIssue& w : c.report.warnings) EXPECT_EQ(w.message.find("left unchanged"), std::string::npos) << w.message;
    EXPECT_EQ(writeRapid(c.program), special(written_plain));
    // not split where the plain instruction is
    const ProgramCompensation kept = compensateProgramReport(parseRapid(special(example()), "other.mod"), fine_tol);
    ASSERT_TRUE(kept.ok());
    for (const auto& [plain_line, other] : lines) {
      if (plain_line.rfind("MoveJ", 0) != 0) {
        EXPECT_GT(pieces(split, plain_line), 0) << plain_line;
      }
      EXPECT_EQ(pieces(kept, other), 0) << other;
    }
    // another format would lose the signal, the triggers, the procedure, the weld: refused, named
    const std::string first = lines.front().second.substr(0, lines.front().second.find(' '));
    try {
      renderProgram(parseRapid(special(example()), "other.mod"), ProgramFormat::kXml, "other.xml");
      ADD_FAILURE() << first << " converted";
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find(first + " does more than move (a signal, a trigger, a procedure or a weld), which only RAPID carries"),
                std::string::npos) << e.what();
    }
  }
}

// RoboDK's ABB post-processor declares `PERS tooldata rdkTool` / `PERS wobjdata rdkWObj` with
// zero frames and assigns their values at the start of the routine, before every motion
// (`rdkTool := [TRUE,[[..],[..]],..];`). The controller runs the statements in order: the
// motions after the assignment use the assigned value. Every such module was left unchanged
// ("the tooldata 'rdkTool' is assigned at ...: its value at run time is not the declared one").
// Now the motions after a top-level assignment of a written-out value are compensated exactly
// as with that value declared (a different route: the declaration read since issue 12); a
// motion before it, an assignment in a branch, a field assignment, a label after it, a call of
// a routine that assigns it or a TRAP that does keep the motion as written, named.
TEST(Rapid, ATooldataAndWobjdataAssignedAtTheRoutineStartAreTheValueOfTheMotionsAfterIt) {
  const std::string tool = "[TRUE,[[0.000, 0.000, 150.000],[1.00000000, 0.00000000, 0.00000000, 0.00000000]],[1,[0,0,50],[1,0,0,0],0,0,0.005]]";
  const std::string wobj = "[FALSE, TRUE, \"\", [[300.000, -150.000, 100.000],[1.0, 0.0, 0.0, 0.0]],[[0,0,0],[1,0,0,0]]]";
  const std::string zero_tool = "[TRUE,[[0,0,0],[1,0,0,0]],[2,[0,0,15],[1,0,0,0],0,0,0.005]]";
  const std::string zero_wobj = "[FALSE, TRUE, \"\", [[0,0,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]]";
  const std::string moves =
      "    MoveL [[40.000, 60.000, 120.000],[0.00000000, 0.00000000, 1.00000000, 0.00000000],[-1,0,-1,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],"
      "[500,500,5000,1000],fine,rdkTool,\\WObj:=rdkWObj;\n"
      "    MoveL [[40.000, 60.000, 20.000],[0.00000000, 0.00000000, 1.00000000, 0.00000000],[-1,0,-1,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],"
      "[100.00,500,5000,1000],fine,rdkTool,\\WObj:=rdkWObj;\n";
  auto module = [&](const std::string& t, const std::string& w, const std::string& body, const std::string& more = "") {
    return "MODULE MOD_Prog1\n\nPERS tooldata rdkTool := " + t + ";\nPERS wobjdata rdkWObj := " + w + ";\n\nPROC Prog1()\n" + body +
           "ENDPROC\n" + more + "\nENDMODULE\n";
  };
  const std::string assign = "    rdkWObj := " + wobj + ";\n    rdkTool := " + tool + ";\n";
  const JobSettings s = perturbedIrb120();
  auto motionLines = [&](const std::string& text, int* left_unchanged) {
    const ProgramCompensation c = compensateProgramReport(parseRapid(text, "Prog1.mod"), s);
    EXPECT_TRUE(c.ok()) << (c.ok() ? std::string() : c.report.errors.front().message);
    *left_unchanged = 0;
    for (const ProgramIssue& w : c.report.warnings) *left_unchanged += w.message.find("left unchanged") != std::string::npos;
    std::string lines;
    std::istringstream in(writeRapid(c.program));
    for (std::string l; std::getline(in, l);)
      if (l.rfind("    Move", 0) == 0) lines += l + "\n";
    return lines;
  };
  int n_declared = -1, n_assigned = -1;
  const std::string declared = motionLines(module(tool, wobj, moves), &n_declared);
  ASSERT_NE(declared, moves);  // (corrected)
  EXPECT_EQ(n_declared, 0);
  EXPECT_EQ(motionLines(module(zero_tool, zero_wobj, "    ! Program generated by RoboDK\n" + assign + moves), &n_assigned), declared);
  EXPECT_EQ(n_assigned, 0);
  // run-time values: kept, named
  auto kept = [&](const std::string& text) {
    int n = 0;
    EXPECT_EQ(motionLines(text, &n), moves) << text;
    return n;
  };
  EXPECT_EQ(kept(module(zero_tool, zero_wobj, moves + assign)), 2);  // before the assignment
  EXPECT_EQ(kept(module(zero_tool, zero_wobj, "    IF reg1 = 1 THEN\n" + assign + "    ENDIF\n" + moves)), 2);
  EXPECT_EQ(kept(module(zero_tool, zero_wobj, assign + "    IF reg1 = 1 rdkTool.tframe.trans.z := 10;\n" + moves)), 2);
  EXPECT_EQ(kept(module(zero_tool, zero_wobj, assign + "    again:\n" + moves)), 2);
  // an error handler that assigns it (RETRY goes back into the body)
  EXPECT_EQ(kept(module(zero_tool, zero_wobj, assign + moves + "  ERROR\n    rdkTool := " + zero_tool + ";\n    RETRY;\n")), 2);
  // a loop whose body assigns it: from the second pass on its motions run after that assignment
  EXPECT_EQ(kept(module(zero_tool, zero_wobj, assign + "    WHILE TRUE DO\n" + moves + "      rdkTool := " + zero_tool + ";\n    ENDWHILE\n")), 2);
  // another routine that assigns it: a call of it between the assignment and the motions
  // (also through a routine that calls it) changes the value; a TRAP may run at any time
  const std::string other = "PROC other()\n    rdkTool := " + zero_tool + ";\nENDPROC\nPROC outer()\n    other;\nENDPROC\n";
  EXPECT_EQ(kept(module(zero_tool, zero_wobj, assign + "    other;\n" + moves, other)), 2);
  EXPECT_EQ(kept(module(zero_tool, zero_wobj, assign + "    outer;\n" + moves, other)), 2);
  EXPECT_EQ(kept(module(zero_tool, zero_wobj, assign + moves, "TRAP t1\n    rdkTool := " + zero_tool + ";\nENDTRAP\n")), 2);
  EXPECT_EQ(kept(module(zero_tool, zero_wobj, assign + moves, other + "TRAP t2\n    outer;\nENDTRAP\n")), 2);
  EXPECT_EQ(motionLines(module(zero_tool, zero_wobj, assign + moves, other), &n_assigned), declared);  // (not called)
  EXPECT_EQ(n_assigned, 0);
  EXPECT_EQ(motionLines(module(zero_tool, zero_wobj, assign + "    gripper;\n" + moves, "PROC gripper()\n    SetDO do1, 1;\nENDPROC\n"), &n_assigned),
            declared);
  EXPECT_EQ(n_assigned, 0);
  // RoboDK's module of several programs: each assigns the frames before its motions
  EXPECT_EQ(motionLines(module(zero_tool, zero_wobj, assign + moves, "PROC Prog2()\n" + assign + moves + "ENDPROC\n"), &n_assigned),
            declared + declared);
  EXPECT_EQ(n_assigned, 0);
  // the tool's load does not move its frame
  int n = -1;
  EXPECT_EQ(motionLines(module(zero_tool, zero_wobj, assign + "    rdkTool.tload.mass := 3;\n" + moves), &n), declared);
  EXPECT_EQ(n, 0);
}

// MoveExtJ moves one or several mechanical units without a TCP (ABB, Technical reference manual -
// RAPID Instructions, Functions and Data types, MoveExtJ): the arm's axes stay where they are.
// It made the next motion's start unknown, so the MoveL after it got no auxiliary points (and
// a \T split by the length of no path). Now the MoveL after it is compensated as if the
// MoveExtJ were not there (the same text, pieces and time shares), the MoveExtJ kept as written
// and named; a next target that gives an external axis (0 here: a track that may carry the
// robot and moved) starts from an unknown position, as before.
TEST(Rapid, MoveExtJLeavesTheArmWhereItWasForTheNextMotion) {
  const std::string seam = "    MoveL p30, v20, z1, torch\\WObj:=table;\n";
  const std::string timed = "    MoveL p30, v20\\T:=3, z1, torch\\WObj:=table;\n";
  const std::string ext = "    MoveExtJ jpos10, vrot10, fine;\n";
  const std::string arc_on = "    SetDO do_torch, 1;  ! arc on\n";
  auto with = [&](std::string text) {  // the MoveExtJ after the SetDO before MoveL p30 (and its pieces)
    const size_t at = text.find(arc_on);
    EXPECT_NE(at, std::string::npos);
    return at == std::string::npos ? text : text.insert(at + arc_on.size(), ext);
  };
  auto replaced = [&](std::string text, const std::string& from, const std::string& to) {
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return at == std::string::npos ? text : text.replace(at, from.size(), to);
  };
  const JobSettings s = splittingSettings();
  const std::string plain = replaced(example(), seam, timed);
  const ProgramCompensation a = compensateProgramReport(parseRapid(plain, "plain.mod"), s);
  const ProgramCompensation b = compensateProgramReport(parseRapid(with(plain), "ext.mod"), s);
  ASSERT_TRUE(a.ok() && b.ok());
  const int line = parseRapid(plain, "plain.mod").motions[3].where.line;  // MoveL p30
  int pieces = 0;
  for (const Motion& m : a.program.motions) pieces += m.inserted && m.where.line == line ? 1 : 0;
  ASSERT_GT(pieces, 0);  // (the plain MoveL p30 is split, so its start matters)
  EXPECT_EQ(writeRapid(b.program), with(writeRapid(a.program)));
  EXPECT_EQ(b.report.motions_left_unchanged, 1);
  ASSERT_FALSE(b.report.warnings.empty());
  bool named = false;
  for (const ProgramIssue& w : b.report.warnings)
    named = named || w.where.str() + ": " + w.message ==
                         "ext.mod:" + std::to_string(line) + ":5: MoveExtJ left unchanged (not compensated): MoveExtJ moves external axes only "
                         "(mechanical units without a TCP), which accura does not model; the robot arm does not move, so the next motion "
                         "starts where it was, unless that motion's target gives an external axis (a track may carry the robot)";
  EXPECT_TRUE(named);
  // p30 with its track axis given (0: compensated as the robot stands on it): after the
  // MoveExtJ its start is not known, so it is not split
  const std::string p30 = "CONST robtarget p30 := [[160,60,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];";
  const std::string track = replaced(plain, p30, "CONST robtarget p30 := [[160,60,20],[0,0,1,0],[-1,0,-1,0],[0,9E9,9E9,9E9,9E9,9E9]];");
  const ProgramCompensation c = compensateProgramReport(parseRapid(track, "track.mod"), s);
  const ProgramCompensation d = compensateProgramReport(parseRapid(with(track), "track_ext.mod"), s);
  ASSERT_TRUE(c.ok() && d.ok());
  int track_pieces = 0, after_ext = 0;
  for (const Motion& m : c.program.motions) track_pieces += m.inserted && m.where.line == line ? 1 : 0;
  for (const Motion& m : d.program.motions) after_ext += m.inserted && m.where.line == line + 1 ? 1 : 0;
  EXPECT_GT(track_pieces, 0);
  EXPECT_EQ(after_ext, 0);
}

// A required argument may be written with its parameter's name (ABB, Technical reference
// manual - RAPID kernel, procedure call: <required procedure argument> ::= [<identifier> ':=']
// <expression>; so does the public RAPID grammar of rapidchecker 0.1.5, parser/grammar.py:
// required_arg = Optional(identifier + ":=") + expression). `MoveL ToPoint:=p20, ...` was kept
// as written ("'ToPoint:=p20' is not a target accura can evaluate"), a named Tool was taken for
// an undeclared tooldata (an error), and a point or a frame passed by name to a routine that
// changes it (`SearchL di1, SearchPoint:=sp, ...`, an INOUT parameter) or after a named
// argument (`weld p30, Speed:=2;`) was not seen as changed or read. Now a named argument in its
// place is read as the positional one (the same corrections, written in place of the value);
// a name that is not its place's is kept as written and named.
TEST(Rapid, NamedRequiredArgumentsAreReadAsThePositionalOnes) {
  using Lines = std::vector<std::pair<std::string, std::string>>;
  const Lines named = {
      {"MoveAbsJ home, v1000, z50, torch;", "MoveAbsJ ToJointPos:=home, v1000, z50, torch;"},
      {"MoveJ p10, v1000, z20, torch\\WObj:=table;", "MoveJ \\Conc, ToPoint:=p10, Speed:=v1000, Zone:=z20, Tool:=torch\\WObj:=table;"},
      {"MoveL p20, v200, fine, torch\\WObj:=table;", "MoveL topoint:=p20, v200, fine, torch\\WObj:=table;"},
      {"MoveC p40, p50, v20, z1, torch\\WObj:=table;", "MoveC CirPoint:=p40, ToPoint:=p50, v20, z1, Tool:=torch\\WObj:=table;"}};
  const Lines offs = {{"MoveL Offs(p60,0,0,100), v200, z20, torch\\WObj:=table;", "MoveL ToPoint:=Offs(p60,0,0,100), v200, z20, torch\\WObj:=table;"}};
  auto special = [&](std::string text, const Lines& lines) {
    for (const auto& [plain_line, other] : lines) {
      const size_t at = text.find(plain_line);
      EXPECT_NE(at, std::string::npos) << plain_line;
      if (at != std::string::npos) text.replace(at, plain_line.size(), other);
    }
    return text;
  };
  SimulateOptions so;
  so.effects = {"geometric", "joint_compliance"};
  so.set_station = false;
  so.seed = 2;
  JobSettings s = settingsFor(perturbModel(irb120WithTorch(), so));
  s.tol_mm = 10;  // (no piece: the statements are written as they are)
  const ProgramCompensation plain = compensateProgramReport(parseRapid(example(), "plain.mod"), s);
  const ProgramCompensation c = compensateProgramReport(parseRapid(special(special(example(), named), offs), "named.mod"), s);
  ASSERT_TRUE(plain.ok() && c.ok()) << (c.ok() ? std::string() : c.report.errors.front().message);
  const std::string written_plain = writeRapid(plain.program);
  ASSERT_NE(written_plain, example());
  EXPECT_EQ(c.report.motions_left_unchanged, 0) << c.report.warnings.front().message;
  // (the corrected Offs is an inline robtarget, written in place of the named value)
  const std::string wait = "    WaitTime 0.5;\n    MoveL [[";
  std::string expected = special(written_plain, named);
  ASSERT_NE(expected.find(wait), std::string::npos);
  expected.replace(expected.find(wait), wait.size(), "    WaitTime 0.5;\n    MoveL ToPoint:=[[");
  EXPECT_EQ(writeRapid(c.program), expected);
  // a name that is not its place's: kept as written, named
  const std::string misplaced = special(example(), {{"MoveL p20, v200, fine, torch\\WObj:=table;", "MoveL Zone:=p20, v200, fine, torch\\WObj:=table;"}});
  const ProgramCompensation k = compensateProgramReport(parseRapid(misplaced, "r.mod"), s);
  ASSERT_TRUE(k.ok());
  EXPECT_EQ(k.report.motions_left_unchanged, 1);
  ASSERT_FALSE(k.report.warnings.empty());
  EXPECT_EQ(k.report.warnings.front().where.str() + ": " + k.report.warnings.front().message,
            "r.mod:19:5: MoveL left unchanged (not compensated): its argument 1 is named Zone, where MoveL's argument 1 is ToPoint: accura "
            "reads a named argument in its place only; the position after it is not known");
  EXPECT_NE(writeRapid(k.program).find("\n    MoveL Zone:=p20, v200, fine, torch\\WObj:=table;\n"), std::string::npos);
  // what a call changes or reads through a named argument
  const std::string t = "[[380,40,350],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]]";
  const Program q = parseRapid("MODULE m\n  VAR robtarget sp := " + t + ";\n  VAR robtarget pm := " + t + ";\n  CONST robtarget p30 := " + t + ";\n"
                               "  VAR robtarget pf := " + t + ";\n"
                               "  PROC main()\n"
                               "    SearchL di1, SearchPoint:=sp, sp, v100, tool0;\n"
                               "    MoveL sp, v100, fine, tool0;\n"
                               "    modify t:=pm;\n"
                               "    MoveL pm, v100, fine, tool0;\n"
                               "    MoveL p30, v100, fine, tool0;\n"
                               "    weld p30, Speed:=2;\n"
                               "    reg1 := changed(t:=pf);\n"
                               "    MoveL pf, v100, fine, tool0;\n"
                               "  ENDPROC\n"
                               "  FUNC num changed(INOUT robtarget t)\n    t.trans.x := 1;\n    RETURN 1;\n  ENDFUNC\n"
                               "  PROC modify(INOUT robtarget t)\n    t.trans.z := 10;\n  ENDPROC\n"
                               "  PROC weld(robtarget p, num speed)\n  ENDPROC\n"
                               "ENDMODULE\n",
                               "q.mod");
  ASSERT_EQ(q.motions.size(), 5u);
  EXPECT_EQ(q.motions[1].target_problem, "'sp' is assigned at q.mod:7:31: its value at run time is not the declared one");
  EXPECT_EQ(q.motions[2].target_problem, "'pm' is assigned at q.mod:9:15: its value at run time is not the declared one");
  EXPECT_TRUE(q.motions[3].target_problem.empty());
  EXPECT_EQ(q.motions[4].target_problem, "'pf' is assigned at q.mod:13:24: its value at run time is not the declared one");
  ASSERT_EQ(q.rapid->decls.size(), 4u);
  EXPECT_EQ(q.rapid->decls[2].read_elsewhere, "q.mod:12:10 ('weld p30, Speed:=2;')");
}

// Robtarget arrays: a motion to an element with a constant index (`MoveL pts{2}, ...`, also as
// `ToPoint:=pts{1}` and in a two-dimensional array) was kept uncorrected, named as a target
// accura cannot evaluate. The controller goes to the element's declared value, as to a scalar
// robtarget: the element is corrected in the array's value. Expected: the numbers of the same
// program written with scalar robtargets, compensated the same way; the rest of the array's
// text (the element no motion names, the blanks and line breaks between elements) as written.
const std::string kV1 = "[[40,60,120],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]]";
const std::string kV2 = "[[40,60,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]]";
const std::string kV3 = "[[80, 60, 20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]]";  // no motion names it

std::string arrayModule(const std::string& data, const std::string& a, const std::string& b) {
  return "MODULE m\n" + kTool + kWobj + data + "  PROC main()\n    ConfL\\Off;\n    MoveJ " + a + ",v1000,z50,tWeld\\WObj:=wTable;\n    MoveL " + b +
         ",v200,fine,tWeld\\WObj:=wTable;\n    MoveL ToPoint:=" + a + ",Speed:=v200,fine,tWeld\\WObj:=wTable;\n  ENDPROC\nENDMODULE\n";
}

/// The value written for the declaration `head` ("p1 := ") in `text`.
std::string declaredValue(const std::string& text, const std::string& head) {
  const size_t at = text.find(head);
  if (at == std::string::npos) return "(" + head + " not found)";
  const size_t b = at + head.size();
  return text.substr(b, text.find(";", b) - b);
}

TEST(Rapid, ArrayElementsWithAConstantIndexAreCorrectedInTheArraysValue) {
  const std::string scalar = arrayModule("  CONST robtarget p1 := " + kV1 + ";\n  CONST robtarget p2 := " + kV2 + ";\n", "p1", "p2");
  const std::string one = arrayModule("  CONST robtarget pts{3} := [" + kV1 + ",\n    " + kV2 + ", " + kV3 + "];\n", "pts{1}", "pts{ 2 }");
  const std::string two = arrayModule("  LOCAL PERS robtarget grid{2,2} := [[" + kV3 + "," + kV1 + "],[" + kV2 + "," + kV3 + "]];\n", "grid{1,2}", "grid{2,1}");
  const Program p = parseRapid(one, "one.mod");
  ASSERT_EQ(p.motions.size(), 3u);
  EXPECT_EQ(p.motions[1].target.name, "pts{ 2 }");
  EXPECT_EQ(p.motions[1].target_problem, "");
  EXPECT_LT((poseOf(p.motions[1].target).translation() - Eigen::Vector3d(40, 60, 20)).norm(), 1e-12);
  EXPECT_LT((poseOf(p.motions[2].target).translation() - Eigen::Vector3d(40, 60, 120)).norm(), 1e-12);
  EXPECT_EQ(p.motions[1].target.where.str(), "one.mod:5:5");  // the element's value
  const JobSettings real = perturbedIrb120();
  const ProgramCompensation s = compensateProgramReport(parseRapid(scalar, "s.mod"), real);
  ASSERT_TRUE(s.ok());
  ASSERT_EQ(s.report.motions_left_unchanged, 0);
  const std::string ws = writeRapid(s.program);
  const std::string c1 = declaredValue(ws, "p1 := "), c2 = declaredValue(ws, "p2 := ");
  ASSERT_NE(c1, kV1);  // (corrected)
  ASSERT_NE(c2, kV2);
  for (const std::string& text : {one, two}) {
    const ProgramCompensation c = compensateProgramReport(parseRapid(text, "a.mod"), real);
    ASSERT_TRUE(c.ok()) << text;
    EXPECT_EQ(c.report.motions_left_unchanged, 0) << text;
    std::string want = text;
    want.replace(want.find(kV1), kV1.size(), c1);
    want.replace(want.find(kV2), kV2.size(), c2);
    EXPECT_EQ(writeRapid(c.program), want);
  }
  // the nominal robot: byte for byte
  JobSettings nominal;
  nominal.calibrated = test::loadBundled("abb_irb120");
  for (const std::string& text : {one, two}) {
    const ProgramCompensation n = compensateProgramReport(parseRapid(text, "a.mod"), nominal);
    ASSERT_TRUE(n.ok());
    EXPECT_EQ(writeRapid(n.program), text);
  }
}

// An element whose index the controller computes (pts{i}), one outside the array (pts{4}), and
// the element of an array the program assigns are kept as written and named. A motion to pts{i}
// reads every element: pts{1} and pts{2}, corrected for the motions that name them, keep their
// value in the array (byte for byte) and those motions go to new scalar robtargets declared
// after the array, with the values the scalar program gets.
TEST(Rapid, ArrayElementsOfARunTimeIndexOrOutsideTheArrayAreKeptAndNamed) {
  const std::string head = "MODULE m\n" + kTool + kWobj;
  const std::string array = "  CONST robtarget pts{3} := [" + kV1 + ", " + kV2 + ", " + kV3 + "];\n";
  const std::string vp = "  VAR robtarget vp{2} := [" + kV1 + ", " + kV2 + "];\n";
  const std::string text = head + array + vp +
                           "  PROC main()\n    ConfL\\Off;\n    MoveJ pts{1},v1000,z50,tWeld\\WObj:=wTable;\n    MoveL pts{2},v200,fine,tWeld\\WObj:=wTable;\n"
                           "    FOR i FROM 1 TO 3 DO\n      MoveL pts{i},v200,fine,tWeld\\WObj:=wTable;\n    ENDFOR\n"
                           "    MoveL pts{4},v200,fine,tWeld\\WObj:=wTable;\n    vp{1} := CRobT();\n    MoveL vp{2},v200,fine,tWeld\\WObj:=wTable;\n"
                           "  ENDPROC\nENDMODULE\n";
  const Program p = parseRapid(text, "r.mod");
  ASSERT_EQ(p.motions.size(), 5u);
  EXPECT_EQ(p.motions[2].target_problem, "the index of 'pts{i}' is computed at run time");
  EXPECT_EQ(p.motions[3].target_problem,
            "'pts{4}' is outside the array pts{3} (declared at r.mod:4:19; indices from 1): the controller stops with an error when it runs this motion");
  EXPECT_EQ(p.motions[4].target_problem, "'vp{2}' is an element of vp, which is assigned at r.mod:14:5: its value at run time is not the declared one");
  ASSERT_EQ(p.rapid->decls.size(), 5u);  // pts{1..3}, vp{1..2}
  EXPECT_EQ(p.rapid->decls[1].name, "pts{2}");
  EXPECT_EQ(p.rapid->decls[1].read_elsewhere, "r.mod:11:13 ('MoveL pts{i},v200,fine,tWeld\\WObj:=wTable;')");
  const JobSettings real = perturbedIrb120();
  const std::string scalar = head + "  CONST robtarget p1 := " + kV1 + ";\n  CONST robtarget p2 := " + kV2 + ";\n" +
                             "  PROC main()\n    ConfL\\Off;\n    MoveJ p1,v1000,z50,tWeld\\WObj:=wTable;\n    MoveL p2,v200,fine,tWeld\\WObj:=wTable;\n"
                             "  ENDPROC\nENDMODULE\n";
  const ProgramCompensation s = compensateProgramReport(parseRapid(scalar, "s.mod"), real);
  ASSERT_TRUE(s.ok());
  const std::string ws = writeRapid(s.program);
  const ProgramCompensation c = compensateProgramReport(p, real);
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c.report.motions_left_unchanged, 3);
  const std::string w = writeRapid(c.program);
  const std::string want = head + array + "  CONST robtarget pts_1_1 := " + declaredValue(ws, "p1 := ") + ";\n  CONST robtarget pts_2_1 := " +
                           declaredValue(ws, "p2 := ") + ";\n" + vp +
                           "  PROC main()\n    ConfL\\Off;\n    MoveJ pts_1_1,v1000,z50,tWeld\\WObj:=wTable;\n    MoveL pts_2_1,v200,fine,tWeld\\WObj:=wTable;\n" +
                           text.substr(text.find("    FOR i"));
  EXPECT_EQ(w, want);
  std::set<std::string> said;
  for (const auto& m : c.report.warnings) said.insert(m.where.str() + " " + m.message);
  EXPECT_TRUE(said.count("r.mod:11:7 MoveL left unchanged (not compensated): the index of 'pts{i}' is computed at run time; the position after it is not known"));
  EXPECT_TRUE(said.count("r.mod:8:5 pts{1} is corrected for this motion and also read at r.mod:11:13 ('MoveL pts{i},v200,fine,tWeld\\WObj:=wTable;'), "
                         "which the correction must not move: the motion goes to a new point pts_1_1 declared after the array pts; pts{1} keeps its value"));
  int renamed = 0;
  for (const TargetReport& t : c.report.targets) renamed += (t.name == "pts_1_1" && t.new_point_replaces == "pts{1}") + (t.name == "pts_2_1" && t.new_point_replaces == "pts{2}");
  EXPECT_EQ(renamed, 2);
}

// What else names an element: a CONST num index is a constant (the element it names is read);
// the SearchPoint of SearchL is overwritten by the search (its array is a run-time value), and
// its ToPoint is read by an instruction accura does not model (that element's read elsewhere);
// an array without a value, another number of indices, an array parameter: kept and named.
TEST(Rapid, ArrayElementsOfConstantsSearchesParametersAndArraysWithoutAValue) {
  const std::string text = "MODULE m\n" + kTool + kWobj + "  CONST num k := 2;\n  CONST robtarget pts{3} := [" + kV1 + ", " + kV2 + ", " + kV3 +
                           "];\n  VAR robtarget sp{2} := [" + kV1 + ", " + kV2 + "];\n  VAR robtarget buf{4};\n  PROC main()\n"
                           "    MoveL pts{k},v200,fine,tWeld\\WObj:=wTable;\n    SearchL \\Stop, di1, sp{2}, pts{3}, v100, tWeld\\WObj:=wTable;\n"
                           "    MoveL sp{1},v200,fine,tWeld\\WObj:=wTable;\n    MoveL buf{1},v200,fine,tWeld\\WObj:=wTable;\n"
                           "    MoveL pts{1,2},v200,fine,tWeld\\WObj:=wTable;\n  ENDPROC\n  PROC side(robtarget arr{*})\n"
                           "    MoveL arr{1},v200,fine,tWeld\\WObj:=wTable;\n  ENDPROC\nENDMODULE\n";
  const Program p = parseRapid(text, "r.mod");
  ASSERT_EQ(p.motions.size(), 6u);
  EXPECT_EQ(p.motions[0].target_problem, "");
  EXPECT_LT((poseOf(p.motions[0].target).translation() - Eigen::Vector3d(40, 60, 20)).norm(), 1e-12);
  EXPECT_EQ(p.motions[2].target_problem, "'sp{1}' is an element of sp, which is assigned at r.mod:10:25: its value at run time is not the declared one");
  EXPECT_EQ(p.motions[3].target_problem, "'buf{1}' is an element of an array accura cannot read: the robtarget array buf is declared without a value");
  EXPECT_EQ(p.motions[4].target_problem, "'pts{1,2}' gives 2 index(es) of the array pts, which has 1 dimension(s)");
  EXPECT_EQ(p.motions[5].target_problem, "'arr{1}' is an element of arr, a parameter of side: its value comes from the call");
  ASSERT_EQ(p.rapid->decls.size(), 5u);  // pts{1..3}, sp{1..2}
  EXPECT_EQ(p.rapid->decls[0].read_elsewhere, "");
  EXPECT_EQ(p.rapid->decls[1].read_elsewhere, "");  // (pts{k}: a plain target)
  EXPECT_EQ(p.rapid->decls[2].read_elsewhere, "r.mod:10:32 ('SearchL \\Stop, di1, sp{2}, pts{3}, v100, tWeld\\WObj:=wTable;')");
}

// A MoveC to elements of an array split by the compensation: its last sub-arc's circle point
// is a new scalar robtarget declared after the array (pts_2_1), the element keeps its value, as
// p3 and p3_1 of the same program with scalar robtargets. Expected: that program's text, with
// the array's elements and names in place of the scalars.
TEST(Rapid, ASplitMoveCToArrayElementsGetsANewCirclePointAsTheScalarProgramDoes) {
  const std::string v4 = "[[120,100,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]]";
  const std::string body = "  PROC main()\n    ConfL\\Off;\n    MoveJ p1,v1000,fine,tWeld\\WObj:=wTable;\n    MoveC p3, p4,v200,fine,tWeld\\WObj:=wTable;\n  ENDPROC\nENDMODULE\n";
  const std::string scalar = "MODULE m\n" + kTool + kWobj + "  CONST robtarget p1 := " + kV1 + ";\n  CONST robtarget p3 := " + kV3 +
                             ";\n  CONST robtarget p4 := " + v4 + ";\n" + body;
  auto named = [](std::string t) {
    for (const auto& [from, to] : {std::pair<std::string, std::string>{"p1", "pts{1}"}, {"p3_1", "pts_2_1"}, {"p3", "pts{2}"}, {"p4", "pts{3}"}})
      for (size_t at = t.find(from); at != std::string::npos; at = t.find(from, at + to.size())) t.replace(at, from.size(), to);
    return t;
  };
  const std::string array = "MODULE m\n" + kTool + kWobj + "  CONST robtarget pts{3} := [" + kV1 + ", " + kV3 + ", " + v4 + "];\n" + named(body);
  const JobSettings s = splittingSettings();
  const ProgramCompensation cs = compensateProgramReport(parseRapid(scalar, "s.mod"), s), ca = compensateProgramReport(parseRapid(array, "a.mod"), s);
  ASSERT_TRUE(cs.ok() && ca.ok());
  ASSERT_GT(cs.report.points_added, 0);
  const std::string ws = writeRapid(cs.program);
  ASSERT_NE(ws.find("  CONST robtarget p3 := " + kV3 + ";\n  CONST robtarget p3_1 := "), std::string::npos) << ws;
  const std::string want = "MODULE m\n" + kTool + kWobj + "  CONST robtarget pts{3} := [" + declaredValue(ws, "p1 := ") + ", " + kV3 + ", " +
                           declaredValue(ws, "p4 := ") + "];\n  CONST robtarget pts_2_1 := " + declaredValue(ws, "p3_1 := ") + ";\n" +
                           named(ws.substr(ws.find("  PROC main()")));
  EXPECT_EQ(writeRapid(ca.program), want);
  EXPECT_EQ(ca.report.points_added, cs.report.points_added);
}

// A robtarget value accura cannot read (a CONST num in its position, a non-unit quaternion) is
// no error of the module: the controller loads it. Before, any such element of an array (and
// any such scalar) refused the whole module ("expected a number in a position [x,y,z] (mm),
// found 'x0'"), also when no motion went to it. Now the other elements and points are read and
// compensated; a motion to such a value is kept as written and named with the reason; a value of
// the wrong shape (3 items) is still an error.
TEST(Rapid, ARobtargetValueAccuraCannotReadIsNamedOnlyByTheMotionsThatGoToIt) {
  const std::string text = "MODULE m\n" + kTool + kWobj + "  CONST num x0 := 40;\n  CONST robtarget pts{3} := [" + kV1 +
                           ", [[x0,60,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]], [[40,60,20],[0,0,1,0.5],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]]];\n"
                           "  CONST robtarget ps := [[x0,60,120],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
                           "  CONST robtarget qs := [[40,60,20],[0,0,1,0.5],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
                           "  PROC main()\n    ConfL\\Off;\n    MoveJ pts{1},v1000,z50,tWeld\\WObj:=wTable;\n    MoveL pts{2},v200,fine,tWeld\\WObj:=wTable;\n"
                           "    MoveL qs,v200,fine,tWeld\\WObj:=wTable;\n  ENDPROC\nENDMODULE\n";
  const Program p = parseRapid(text, "u.mod");
  ASSERT_EQ(p.motions.size(), 3u);
  EXPECT_EQ(p.motions[0].target_problem, "");
  EXPECT_LT((poseOf(p.motions[0].target).translation() - Eigen::Vector3d(40, 60, 120)).norm(), 1e-12);
  EXPECT_EQ(p.motions[1].target_problem, "'pts{2}' is declared in the array pts with a value accura cannot read "
                                         "(u.mod:5:95: expected a number in a position [x,y,z] (mm), found 'x0')");
  EXPECT_EQ(p.motions[2].target_problem, "'qs' is declared with a value accura cannot read (u.mod:7:38: expected a unit quaternion (norm 1 within 0.001), found norm 1.118034)");
  ASSERT_EQ(p.rapid->decls.size(), 1u);  // pts{1}
  // compensated: pts{1} corrected in the array (as the scalar p1 of the same motions), the rest byte for byte
  const std::string scalar = arrayModule("  CONST robtarget p1 := " + kV1 + ";\n  CONST robtarget p2 := " + kV2 + ";\n", "p1", "p2");
  const JobSettings real = perturbedIrb120();
  const ProgramCompensation s = compensateProgramReport(parseRapid(scalar, "s.mod"), real);
  ASSERT_TRUE(s.ok());
  const ProgramCompensation c = compensateProgramReport(p, real);
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c.report.motions_left_unchanged, 2);
  std::string want = text;
  want.replace(want.find(kV1), kV1.size(), declaredValue(writeRapid(s.program), "p1 := "));
  EXPECT_NE(want, text);
  EXPECT_EQ(writeRapid(c.program), want);
  std::set<std::string> said;
  for (const auto& m : c.report.warnings) said.insert(m.where.str() + " " + m.message);
  EXPECT_TRUE(said.count("u.mod:12:5 MoveL left unchanged (not compensated): " + p.motions[2].target_problem + "; the position after it is not known"));
  // the wrong shape is still an error (the controller does not load it)
  EXPECT_EQ(errorOf("MODULE m\n  CONST robtarget pts{1} := [[[x0,60,20],[0,0,1,0],[-1,0,-1,0]]];\nENDMODULE\n"),
            "bad.mod:2:30: expected a robtarget [[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax_a,..,eax_f]] with 4 items, found 3 in "
            "'[[x0,60,20],[0,0,1,0],[-1,0,-1,0]]'");
}

// With --config, the task module's routines run in the task too: a PROC there that assigns its
// tooldata (`torch.tframe.trans.z := 250;`) or wobjdata makes them run-time values, as the same
// PROC in the program's own module does. Before, the task module's assignments were not read:
// the MoveL after `setTorch;` was compensated with the declared z = 150, without a word.
TEST(Rapid, DataTheConfigModuleAssignsAreRunTimeValues) {
  const std::string dir = test::tempDir("rapid_task_assigned");
  const std::string procs = "  PROC setTorch()\n    torch.tframe.trans.z := 250;\n  ENDPROC\n  PROC moveTable()\n    table := [FALSE,TRUE,\"\",[[310,-150,100],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n  ENDPROC\n";
  test::writeText(dir + "/calib.sys", "MODULE CalibData(SYSMODULE)\n" + kTool + "  PERS tooldata torch:=[TRUE,[[0,0,150],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];\n" +
                                          "  PERS wobjdata table:=[FALSE,TRUE,\"\",[[300,-150,100],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n" + kWobj + procs + "ENDMODULE\n");
  const std::string body = "  PROC main()\n    setTorch;\n    moveTable;\n    MoveL p10,v200,fine,torch\\WObj:=table;\n    MoveL p20,v200,fine,tWeld\\WObj:=wTable;\n"
                           "    torch := [TRUE,[[0,0,200],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];\n    MoveL p20,v200,fine,torch\\WObj:=wTable;\n  ENDPROC\n";
  test::writeText(dir + "/m1.mod", "MODULE m1\n" + kP10 + kP20 + body + "ENDMODULE\n");
  ProgramReadOptions o;
  o.config_path = dir + "/calib.sys";
  const Program p = readProgram(dir + "/m1.mod", o);
  ASSERT_EQ(p.motions.size(), 3u);
  EXPECT_TRUE(p.motions[0].tool.run_time);
  EXPECT_EQ(p.motions[0].tool.note, "the tooldata 'torch' is assigned at " + dir + "/calib.sys:7:5: its value at run time is not the declared one");
  EXPECT_TRUE(p.motions[0].base.run_time);
  EXPECT_EQ(p.motions[0].base.note, "the wobjdata 'table' is assigned at " + dir + "/calib.sys:10:5: its value at run time is not the declared one");
  // the data it does not assign keep their declared values
  ASSERT_TRUE(p.motions[1].tool.value && p.motions[1].base.value);
  EXPECT_NEAR(p.motions[1].tool.value->z_mm, 150, 1e-12);
  // after an assignment in this module's routine too: a call may run the task module's routine,
  // whose assignments this module does not see
  EXPECT_TRUE(p.motions[2].tool.run_time);
  // the same PROCs in the program's own module: the same reading, at that module's lines
  const Program q = parseRapid("MODULE m1\n" + kTool + "  PERS tooldata torch:=[TRUE,[[0,0,150],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];\n" +
                                   "  PERS wobjdata table:=[FALSE,TRUE,\"\",[[300,-150,100],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n" + kWobj + kP10 + kP20 + procs + body +
                                   "ENDMODULE\n",
                               "one.mod");
  ASSERT_EQ(q.motions.size(), 3u);
  EXPECT_EQ(q.motions[0].tool.note, "the tooldata 'torch' is assigned at one.mod:9:5: its value at run time is not the declared one");
  EXPECT_TRUE(q.motions[0].base.run_time);
  const ProgramCompensation c = compensateProgramReport(p, perturbedIrb120());
  bool named = false;
  for (const ProgramIssue& e : c.report.errors) named = named || (e.where.line == 7 && e.message.find("calib.sys:7:5") != std::string::npos);
  for (const ProgramIssue& e : c.report.warnings) named = named || (e.where.line == 7 && e.message.find("calib.sys:7:5") != std::string::npos);
  EXPECT_TRUE(named);
  std::filesystem::remove_all(dir);
}

// A new point's name is one the module given with --config does not use: its global data are
// the task's. Before, only the module's own text was looked at: with `CONST robtarget p10_1`
// declared in calib.sys, a point moved to with two tools got a second global p10_1 (the
// controller refuses the ambiguous name). Expected: p10_2, as when p10_1 is in the module.
TEST(Rapid, ANewPointIsNotNamedAsADatumOfTheConfigModule) {
  const std::string dir = test::tempDir("rapid_task_names");
  const std::string torch = "  PERS tooldata torch:=[TRUE,[[0,0,100],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];\n";
  const std::string taken = "  CONST robtarget p10_1:=[[0,0,0],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n";
  test::writeText(dir + "/calib.sys", "MODULE CalibData(SYSMODULE)\n" + kTool + torch + kWobj + taken + "ENDMODULE\n");
  const std::string body = "  PROC main()\n    ConfL\\Off;\n    MoveJ p10,v1000,fine,tWeld\\WObj:=wTable;\n    MoveJ p10,v1000,fine,torch\\WObj:=wTable;\n  ENDPROC\n";
  test::writeText(dir + "/m3.mod", "MODULE m3\n" + kP10 + body + "ENDMODULE\n");
  ProgramReadOptions o;
  o.config_path = dir + "/calib.sys";
  const ProgramCompensation c = compensateProgramReport(readProgram(dir + "/m3.mod", o), perturbedIrb120());
  ASSERT_TRUE(c.ok());
  // the same with every datum in one module (p10_1 there: the module's own name, avoided before too)
  const ProgramCompensation one =
      compensateProgramReport(parseRapid("MODULE m3\n" + kTool + torch + kWobj + taken + kP10 + body + "ENDMODULE\n", "m3.mod"), perturbedIrb120());
  ASSERT_TRUE(one.ok());
  std::string want = writeRapid(one.program);
  ASSERT_NE(want.find("p10_2"), std::string::npos) << want;
  want.erase(want.find(kTool), kTool.size() + torch.size() + kWobj.size() + taken.size());
  const std::string written = writeRapid(c.program);
  EXPECT_EQ(written, want);
  EXPECT_EQ(written.find("p10_1"), std::string::npos);
  std::filesystem::remove_all(dir);
}

// With --config given, a tool or work object it does not supply is said as what it is there:
// LOCAL in that module (invisible to the others: RAPID's LOCAL data), or not declared there.
// Before, the message still said "or the module that declares it with --config", as if none
// had been given.
TEST(Rapid, AToolLocalInTheConfigModuleOrNotDeclaredThereIsSaidSo) {
  const std::string dir = test::tempDir("rapid_task_local");
  test::writeText(dir + "/calib.sys", "MODULE CalibData(SYSMODULE)\n" + kWobj +
                                          "  LOCAL PERS tooldata spare:=[TRUE,[[0,0,9],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];\nENDMODULE\n");
  test::writeText(dir + "/m.mod", "MODULE m\n" + kP10 + "  PROC main()\n    MoveL p10,v200,fine,spare\\WObj:=wTable;\n    MoveL p10,v200,fine,tWeld\\WObj:=wBox;\n  ENDPROC\nENDMODULE\n");
  ProgramReadOptions o;
  o.config_path = dir + "/calib.sys";
  const Program p = readProgram(dir + "/m.mod", o);
  ASSERT_EQ(p.motions.size(), 2u);
  EXPECT_EQ(p.motions[0].tool.note, "the tooldata 'spare' is not declared with a value in this module, and is LOCAL in the module given with --config (" + dir +
                                        "/calib.sys:3:23): invisible to other modules (give its TCP with --program-tool x,y,z,A,B,C)");
  EXPECT_EQ(p.motions[1].tool.note, "the tooldata 'tWeld' is not declared with a value in this module nor in the module given with --config, " + dir +
                                        "/calib.sys (give its TCP with --program-tool x,y,z,A,B,C)");
  EXPECT_EQ(p.motions[1].base.note, "the wobjdata 'wBox' is not declared with a value in this module nor in the module given with --config, " + dir +
                                        "/calib.sys (give its frame with --program-base x,y,z,A,B,C)");
  std::filesystem::remove_all(dir);
}

// A RAPID task has several modules beside the program's: --config given more than once reads
// each (the tool from calib.sys, the work object and the robtargets from points.mod). Before,
// ProgramReadOptions took one module. A name two of them declare global is the controller's
// load error (one global name per task: ABB, RAPID reference manual, "Basic characteristics",
// Data scope; open_abb issue 29, "ambiguity of global variables"), naming both places; a PERS
// both declare is one persistent they share. KRL: the controller has one $config.dat, so a
// second is refused, naming both.
TEST(Rapid, ConfigGivenTwiceReadsBothModulesAndAGlobalNameInTwoIsAnError) {
  const std::string dir = test::tempDir("rapid_task_two");
  test::writeText(dir + "/calib.sys", "MODULE CalibData(SYSMODULE)\n" + kTool + "  CONST num pB_1 := 3;\nENDMODULE\n");
  const std::string points = "MODULE Points\n" + kWobj + "  CONST robtarget pA:=[[40,60,120],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n" +
                             "  VAR robtarget pB:=[[40,60,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n" +
                             "  PERS robtarget pC:=[[40,100,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n" +
                             "  CONST robtarget pA_1:=[[0,0,0],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\nENDMODULE\n";
  test::writeText(dir + "/points.mod", points);
  const std::string body = "  PROC main()\n    ConfL\\Off;\n    MoveJ pA,v1000,z50,tWeld\\WObj:=wTable;\n    MoveL pB,v200,fine,tWeld\\WObj:=wTable;\n"
                           "    MoveL pC,v200,fine,tWeld\\WObj:=wTable;\n  ENDPROC\n";
  const std::string module = "MODULE m\n  VAR num n := 0;\n" + body + "ENDMODULE\n";
  test::writeText(dir + "/m.mod", module);
  ProgramReadOptions o;
  setConfigPaths(o, {dir + "/calib.sys", dir + "/points.mod"});
  const Program p = readProgram(dir + "/m.mod", o);
  ASSERT_EQ(p.motions.size(), 3u);
  ASSERT_TRUE(p.motions[0].tool.value && p.motions[0].base.value);
  EXPECT_NEAR(p.motions[0].tool.value->z_mm, 150, 1e-12);   // calib.sys's tWeld
  EXPECT_NEAR(p.motions[0].base.value->x_mm, 300, 1e-12);   // points.mod's wTable
  EXPECT_EQ(p.motions[0].target_problem, "");
  EXPECT_NEAR(p.motions[0].target.xyzAbc().z_mm, 120, 1e-12);  // points.mod's pA
  EXPECT_EQ(p.motions[0].target.where.str(), dir + "/points.mod:3:23");
  EXPECT_NEAR(p.motions[1].target.xyzAbc().z_mm, 20, 1e-12);
  // a name declared global in both modules: the second names the first
  test::writeText(dir + "/points.mod", "MODULE Points\n  CONST num n2 := 1;\n  PERS tooldata tWeld:=[TRUE,[[0,0,160],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];\nENDMODULE\n");
  test::writeText(dir + "/calib.sys", "MODULE CalibData(SYSMODULE)\n  CONST tooldata tWeld:=[TRUE,[[0,0,150],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];\n"
                                      "  CONST num pB_1 := 3;\nENDMODULE\n");
  try {
    readProgram(dir + "/m.mod", o);
    ADD_FAILURE() << "tWeld declared global in two modules of the task";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), dir + "/points.mod:3:17: expected one declaration of 'tWeld' in the task's global data (the modules of a task share the data "
                                           "that is not LOCAL, and the controller refuses a task that declares one twice), found a second (the first at " +
                                           dir + "/calib.sys:2:18)");
  }
  // the program's own global datum and a --config module's: the same error
  test::writeText(dir + "/calib.sys", "MODULE CalibData(SYSMODULE)\n" + kTool + "  VAR num n := 1;\nENDMODULE\n");
  test::writeText(dir + "/points.mod", points);
  try {
    readProgram(dir + "/m.mod", o);
    ADD_FAILURE() << "n declared global in the program and in calib.sys";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), dir + "/calib.sys:3:11: expected one declaration of 'n' in the task's global data (the modules of a task share the data "
                                           "that is not LOCAL, and the controller refuses a task that declares one twice), found a second (the first at " +
                                           dir + "/m.mod:2:11)");
  }
  // a PERS both declare is one persistent (kTool is PERS tWeld)
  test::writeText(dir + "/calib.sys", "MODULE CalibData(SYSMODULE)\n" + kTool + "ENDMODULE\n");
  test::writeText(dir + "/points.mod", "MODULE Points\n" + kTool + kWobj + "ENDMODULE\n");
  EXPECT_EQ(readProgram(dir + "/m.mod", o).motions.size(), 3u);
  // ... but declared with another value in the other module: which one the task starts with
  // depends on the load order, an error as for two modules of one program
  test::writeText(dir + "/points.mod",
                  "MODULE Points\n  PERS tooldata tWeld:=[TRUE,[[0,0,200],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];\n" + kWobj + "ENDMODULE\n");
  try {
    readProgram(dir + "/m.mod", o);
    ADD_FAILURE() << "PERS tWeld declared with two values";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), dir + "/points.mod:2:17: expected the persistent 'tWeld' declared as at " + dir + "/calib.sys:2:17 (one object the "
                                           "modules of the task share), found another type or value: the value it starts with would depend on the "
                                           "order in which the controller loads the modules");
  }
  // a module is loaded once: given twice, or the program itself given as --config (a task's
  // folder), it is that one module, not a second declaration of each of its names
  test::writeText(dir + "/points.mod", points);
  test::writeText(dir + "/calib.sys", "MODULE CalibData(SYSMODULE)\n" + kTool + "ENDMODULE\n");
  setConfigPaths(o, {dir + "/calib.sys", dir + "/points.mod", dir + "/../" + std::filesystem::path(dir).filename().string() + "/points.mod", dir + "/m.mod"});
  const Program twice = readProgram(dir + "/m.mod", o);
  ASSERT_EQ(twice.motions.size(), 3u);
  EXPECT_NEAR(twice.motions[0].target.xyzAbc().z_mm, 120, 1e-12);  // points.mod's pA
  setConfigPaths(o, {dir + "/calib.sys", dir + "/points.mod"});
  // KRL: one $config.dat
  test::writeText(dir + "/a.src", "DEF a()\n  PTP {A1 0, A2 -90, A3 90, A4 0, A5 0, A6 0}\nEND\n");
  ProgramReadOptions k;
  setConfigPaths(k, {dir + "/$config.dat", dir + "/other.dat"});
  try {
    readProgram(dir + "/a.src", k);
    ADD_FAILURE() << "two $config.dat taken";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "--config: a KRL or XML program takes one $config.dat (the controller has one, KRC:\\R1\\System\\$config.dat), found 2: " + dir +
                                         "/$config.dat and " + dir + "/other.dat (the GLOBAL points of other programs' .dat files are found by accura batch in its tree)");
  }
  std::filesystem::remove_all(dir);
}

// A robtarget a module given with --config declares, which a motion of the program uses: it
// was kept as written and named ("not a robtarget declared with a value in this module"), not
// corrected. That module is only read, so the correction goes to a new point of the program's
// module, as a point needing a second correction does (Job::ownPoint): LOCAL (no other module
// of the task can declare its name too), after the module's data, named to avoid every name of
// the task (pA_1 is points.mod's, pB_1 calib.sys's), the motion redirected to it. Its value is
// the one the same module gets when it declares the point itself. A PERS robtarget is kept
// and named: its value is shared at run time, a copy would freeze it.
TEST(Rapid, ARobtargetOfAConfigModuleIsCorrectedIntoANewPointOfTheProgram) {
  const std::string dir = test::tempDir("rapid_task_points");
  const std::string a = "[[40,60,120],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]]";
  const std::string b = "[[40,60,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]]";
  test::writeText(dir + "/calib.sys", "MODULE CalibData(SYSMODULE)\n" + kTool + kWobj + "  CONST num pB_1 := 3;\nENDMODULE\n");
  const std::string points = "MODULE Points\n  CONST robtarget pA:=" + a + ";\n  VAR robtarget pB:=" + b + ";\n" +
                             "  PERS robtarget pC:=[[40,100,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n" +
                             "  CONST robtarget pA_1:=[[0,0,0],[1,0,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\nENDMODULE\n";
  test::writeText(dir + "/points.mod", points);
  const std::string body = "  PROC main()\n    ConfL\\Off;\n    MoveJ pA,v1000,z50,tWeld\\WObj:=wTable;\n    MoveL pB,v200,fine,tWeld\\WObj:=wTable;\n"
                           "    MoveL pA,v200,fine,tWeld\\WObj:=wTable;\n    MoveL pC,v200,fine,tWeld\\WObj:=wTable;\n  ENDPROC\n";
  const std::string module = "MODULE m\n  VAR num n := 0;\n" + body + "ENDMODULE\n";
  test::writeText(dir + "/m.mod", module);
  ProgramReadOptions o;
  setConfigPaths(o, {dir + "/calib.sys", dir + "/points.mod"});
  const Program p = readProgram(dir + "/m.mod", o);
  EXPECT_EQ(p.motions[3].target_problem, "'pC' is a PERS robtarget of " + dir + "/points.mod (" + dir + "/points.mod:4:18), a module given with --config: a "
                                         "persistent's value is shared at run time (the modules and tasks that use it, ModPos, write it), so its correction "
                                         "can be neither written there (that module is only read) nor frozen into a copy in this module");
  const ProgramCompensation c = compensateProgramReport(p, perturbedIrb120());
  ASSERT_TRUE(c.ok()) << c.report.errors.front().message;
  // the same module declaring pA and pB itself: the corrections the new points must carry
  const std::string whole = "MODULE m\n  VAR num n := 0;\n  CONST robtarget pA:=" + a + ";\n  VAR robtarget pB:=" + b + ";\n" +
                            "  PERS robtarget pC:=[[40,100,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n" + kTool + kWobj + body + "ENDMODULE\n";
  const ProgramCompensation w = compensateProgramReport(parseRapid(whole, "whole.mod"), perturbedIrb120());
  ASSERT_TRUE(w.ok());
  const std::string written = writeRapid(c.program);
  // the module as it was, with the two new points after its data and the motions going to them
  const size_t decl = written.find("  VAR num n := 0;\n") + std::string("  VAR num n := 0;\n").size();
  const size_t after = written.find("  PROC main()");
  ASSERT_NE(after, std::string::npos) << written;
  const std::string added = written.substr(decl, after - decl);
  std::string renamed = body;
  for (const char* m : {"MoveJ pA,", "MoveL pB,", "MoveL pA,"}) {
    const std::string from = m;
    renamed.replace(renamed.find(from), from.size(), from.substr(0, from.size() - 1) + "_2,");
  }
  EXPECT_EQ(written.substr(0, decl) + written.substr(after), "MODULE m\n  VAR num n := 0;\n" + renamed + "ENDMODULE\n");
  EXPECT_EQ(added.substr(0, added.find(":= ")), "  LOCAL CONST robtarget pA_2 ");
  ASSERT_NE(added.find("\n  LOCAL VAR robtarget pB_2 := [["), std::string::npos) << added;
  // their values: the corrections of the module that declares the points itself
  const std::string probe = "MODULE t\n" + added + "  PROC main()\n    MoveL pA_2,v100,fine,tool0;\n    MoveL pB_2,v100,fine,tool0;\n  ENDPROC\nENDMODULE\n";
  const Program t = parseRapid(probe, "t.mod");
  ASSERT_EQ(t.motions.size(), 2u);
  std::vector<const Motion*> programmed;  // (not the points a split inserts)
  for (const Motion& m : w.program.motions)
    if (!m.inserted) programmed.push_back(&m);
  ASSERT_EQ(programmed.size(), 4u);
  for (size_t k = 0; k < 2; ++k) {
    const Eigen::Isometry3d got = poseOf(t.motions[k].target), want = poseOf(programmed[k]->target);
    EXPECT_LT((got.translation() - want.translation()).norm(), 1e-4) << k;  // (written with 4 decimals)
    EXPECT_GT((want.translation() - poseOf(p.motions[k].target).translation()).norm(), 0.05) << k;  // (corrected)
  }
  // the warnings: one per new point, and the PERS kept
  std::vector<std::string> said;
  for (const ProgramIssue& i : c.report.warnings) said.push_back(i.where.str() + ": " + i.message);
  EXPECT_NE(std::find(said.begin(), said.end(), dir + "/m.mod:5:5: pA is declared in " + dir + "/points.mod:2:23, a module given with --config, which accura only "
                                                "reads: this motion goes to a new point pA_2 declared in this module (LOCAL, after its data) with the correction; "
                                                "pA keeps its value"),
            said.end());
  int new_points = 0;
  for (const std::string& m : said) new_points += m.find("a module given with --config, which accura only reads") != std::string::npos;
  EXPECT_EQ(new_points, 2);
  // the report names the new points
  int replaced = 0;
  for (const TargetReport& tr : c.report.targets) replaced += tr.new_point_replaces == "pA" && tr.name == "pA_2";
  EXPECT_EQ(replaced, 2);
  // with the nominal robot nothing is corrected: the module comes back byte for byte
  JobSettings nominal;
  nominal.calibrated = test::loadBundled("abb_irb120");
  const ProgramCompensation n = compensateProgramReport(p, nominal);
  ASSERT_TRUE(n.ok());
  EXPECT_EQ(writeRapid(n.program), module);
  EXPECT_EQ(test::readText(dir + "/points.mod"), points);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace accura::postproc
