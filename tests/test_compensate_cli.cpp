// accura compensate / convert on the command line: the compensated golden program byte for
// byte (only corrected targets and inserted points differ from the input), checked by a
// simulated execution of the written file; the report; clear errors; inputs never touched.
//
// The golden files tests/golden/compensate/expected/ were written by
//   cd tests/golden/compensate && accura compensate --robot kr16_real.xml --in seam.src
//     --config '$config.dat' --out expected --tol 0.02 --json expected/report.json
// after checking them by hand and with the simulated execution below. kr16_real.xml is the
// "real" KR 16 of `accura simulate --seed 11 --effects geometric,joint_compliance --station
// 0,0,0,0,0,0 --tool <TOOL_DATA[1]>`, with small base errors added by hand.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/robot_io.h"
#include "accura/postproc/cell.h"
#include "accura/postproc/compensate.h"
#include "accura/postproc/krl.h"
#include "accura/postproc/xml_program.h"
#include "test_util.h"

namespace accura::postproc {
namespace {

using test::CliRun;
// Runs accura in `dir` (relative paths in the arguments).
CliRun accura(const std::string& dir, const std::string& args) { return test::runAccuraIn(dir, args); }

std::string golden(const std::string& rel) { return test::sourcePath("tests/golden/compensate/" + rel); }

// A temporary directory with the golden inputs.
std::string inputs(const std::string& name) {
  const std::string dir = test::tempDir(name);
  for (const char* f : {"seam.src", "seam.dat", "$config.dat", "kr16_real.xml"}) test::writeText(dir + "/" + f, test::readText(golden(f)));
  return dir;
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  std::string l;
  while (std::getline(in, l)) out.push_back(l);
  return out;
}

std::string trimmed(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t");
  return b == std::string::npos ? "" : s.substr(b);
}

TEST(CompensateCli, GoldenProgramByteForByte) {
  const std::string dir = inputs("comp_golden");
  const CliRun r = accura(dir, "compensate --robot kr16_real.xml --in seam.src --config '$config.dat' --out expected --tol 0.02 --json expected/report.json");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(test::readText(dir + "/expected/seam.src"), test::readText(golden("expected/seam.src")));
  EXPECT_EQ(test::readText(dir + "/expected/seam.dat"), test::readText(golden("expected/seam.dat")));
  EXPECT_EQ(test::readText(dir + "/expected/report.json"), test::readText(golden("expected/report.json")));
  // the inputs are untouched
  for (const char* f : {"seam.src", "seam.dat", "$config.dat", "kr16_real.xml"})
    EXPECT_EQ(test::readText(dir + "/" + f), test::readText(golden(f))) << f;
  EXPECT_NE(r.err.find("warning: seam.src:47:1: the predicted path error"), std::string::npos) << r.err;
}

TEST(CompensateCli, OnlyCorrectedTargetsAndInsertedPointsDiffer) {
  const nlohmann::json report = nlohmann::json::parse(test::readText(golden("expected/report.json")));
  const int added = report["totals"]["points_added"];
  ASSERT_GT(added, 0);
  // .src: every input line is in the output, in order; the output's other lines are inserted
  // motions (inline targets), or the inline LIN whose numbers changed
  const auto in = lines(test::readText(golden("seam.src")));
  const auto out = lines(test::readText(golden("expected/seam.src")));
  ASSERT_EQ(out.size(), in.size() + static_cast<size_t>(added));
  size_t i = 0;
  int inserted = 0, changed = 0;
  for (size_t o = 0; o < out.size(); ++o) {
    if (i < in.size() && out[o] == in[i]) {
      ++i;
      continue;
    }
    const std::string t = trimmed(out[o]);
    if (i < in.size() && t.rfind("CIRC XP5_1, XP6\r", 0) == 0 && trimmed(in[i]).rfind("CIRC XP5, XP6\r", 0) == 0) {
      ++i;  // the split CIRC names its new auxiliary point (XP5 keeps its meaning)
      continue;
    }
    const bool motion = t.rfind("LIN {", 0) == 0 || t.rfind("CIRC {", 0) == 0 || t.rfind("lin {", 0) == 0;
    ASSERT_TRUE(motion) << "unexpected line " << o + 1 << ": " << out[o];
    if (i < in.size() && o + 1 < out.size() && out[o + 1] != in[i] && trimmed(in[i]).rfind("lin {", 0) == 0 &&
        trimmed(out[o + 1]).rfind("lin {", 0) != 0) {
      ++changed;  // the inline target itself, corrected
      ++i;
    } else {
      ++inserted;
    }
    EXPECT_EQ(out[o].back(), '\r') << "CRLF kept";
  }
  EXPECT_EQ(i, in.size());
  EXPECT_EQ(inserted + changed, added + changed);
  // .dat: one line more (the new auxiliary point XP5_1, after XP5, which is unchanged); only
  // the E6POS declarations differ, and in them only X..C
  const auto din = lines(test::readText(golden("seam.dat")));
  auto dout = lines(test::readText(golden("expected/seam.dat")));
  ASSERT_EQ(din.size() + 1, dout.size());
  size_t added_decl = 0;
  for (size_t k = 0; k < dout.size(); ++k)
    if (dout[k].rfind("DECL E6POS XP5_1=", 0) == 0) added_decl = k;
  ASSERT_GT(added_decl, 0u);
  EXPECT_EQ(dout[added_decl - 1].substr(0, 16), "DECL E6POS XP5={");
  EXPECT_EQ(dout[added_decl].substr(dout[added_decl].find(",S ")), dout[added_decl - 1].substr(dout[added_decl - 1].find(",S ")));
  dout.erase(dout.begin() + static_cast<std::ptrdiff_t>(added_decl));
  int decl_changed = 0;
  for (size_t k = 0; k < din.size(); ++k) {
    if (din[k] == dout[k]) continue;
    ASSERT_EQ(din[k].rfind("DECL E6POS XP", 0), 0u) << din[k];
    EXPECT_EQ(din[k].substr(din[k].find(",S ")), dout[k].substr(dout[k].find(",S "))) << "S, T, E1..E6 unchanged";
    ++decl_changed;
  }
  EXPECT_EQ(decl_changed, 5);  // XP1..XP4, XP6; XP5 kept
}

// The written program, run by a simulated controller (nominal model, LIN/CIRC interpolation,
// nominal IK) on the simulated real robot (the model file): the real tool follows the intended
// path (the input program's) within the tolerance; the input program as it is misses it by
// about 2 mm.
TEST(CompensateCli, TheGoldenProgramFollowsTheIntendedPathInSimulation) {
  KrlReadOptions o;
  o.config_path = golden("$config.dat");
  const Program in = readKrl(golden("seam.src"), o);
  const Program out = readKrl(golden("expected/seam.src"), o);
  const nlohmann::json report = nlohmann::json::parse(test::readText(golden("expected/report.json")));
  const calib::RobotModel real = calib::readRobotFile(golden("kr16_real.xml"));
  calib::RobotModel controller = calib::RobotModel::fromDefinition(real.nominal);
  const Eigen::Isometry3d T_world_base1 = calib::toIsometry(*in.motions[1].base.value);
  controller.nominal.T_flange_tcp = calib::toIsometry(*in.motions[1].tool.value);
  ASSERT_LT((controller.nominal.T_flange_tcp.translation() - real.nominal.T_flange_tcp.translation()).norm(), 1e-6);

  auto world = [&](const Target& t) { return T_world_base1 * calib::toIsometry(t.xyzAbc()); };
  auto segment = [&](const Motion& m, const Eigen::Isometry3d& start) {
    PathSegment s;
    s.type = m.type == MotionType::kCirc ? PathType::kCirc : PathType::kLin;
    s.T_world_start = start;
    if (m.aux) s.T_world_aux = world(*m.aux);
    s.T_world_end = world(m.target);
    return s;
  };
  const double tol = 0.02;
  size_t o_index = 0;
  size_t seg = 0;
  for (size_t k = 0; k < in.motions.size(); ++k) {
    const Motion& mi = in.motions[k];
    const bool path = mi.type == MotionType::kLin || mi.type == MotionType::kCirc;
    if (!path) {
      ++o_index;
      continue;
    }
    const int added = report["segments"][seg]["points_added"];
    const double after = report["segments"][seg]["max_error_after_mm"];
    ++seg;
    // intended: from the previous input target to this one
    const PathSegment intended = segment(mi, world(in.motions[k - 1].target));
    // commanded: the written points, from the previous written target
    std::vector<PathSegment> commanded;
    Eigen::Isometry3d start = world(out.motions[o_index - 1].target);
    for (int a = 0; a <= added; ++a) {
      const Motion& mo = out.motions[o_index + static_cast<size_t>(a)];
      commanded.push_back(segment(mo, start));
      start = commanded.back().T_world_end;
    }
    o_index += static_cast<size_t>(added) + 1;
    // the controller starts on the configuration of the previous target
    const Target& prev = in.motions[k - 1].target;
    const calib::Configuration config{prev.status.value_or(-1), prev.turn.value_or(-1)};
    const calib::IkResult q0 = calib::inverseKinematics(controller, commanded.front().T_world_start, config, Eigen::VectorXd(), calib::IkOptions{});
    ASSERT_EQ(q0.status, calib::IkStatus::kOk) << q0.message;
    const double error = maxPathDeviation(simulateExecution(controller, real, commanded, q0.q, 1.0), {intended});
    EXPECT_LE(error, after + 0.002) << "segment " << seg;  // as predicted in the report
    if (mi.trigger_count == 0) {
      EXPECT_LE(error, tol + 0.002) << "segment " << seg;
    }
    // the program as it was
    const calib::IkResult qu = calib::inverseKinematics(controller, intended.T_world_start, config, Eigen::VectorXd(), calib::IkOptions{});
    ASSERT_EQ(qu.status, calib::IkStatus::kOk);
    const double uncompensated = maxPathDeviation(simulateExecution(controller, real, {intended}, qu.q, 1.0), {intended});
    EXPECT_GT(uncompensated, 1.0) << "segment " << seg;
    EXPECT_NEAR(uncompensated, report["segments"][seg - 1]["max_error_uncompensated_mm"].get<double>(), 0.01);
  }
  EXPECT_EQ(seg, report["segments"].size());
  EXPECT_EQ(o_index, out.motions.size());
}

TEST(CompensateCli, ConvertKrlToXmlAndBack) {
  const std::string dir = inputs("comp_convert");
  CliRun r = accura(dir, "convert --in seam.src --config '$config.dat' --out seam.xml");
  ASSERT_EQ(r.code, 0) << r.err;
  r = accura(dir, "convert --in seam.xml --out back/seam.src");
  EXPECT_EQ(r.code, 0) << r.err;  // the directory back/ is created, as compensate creates --out (issue 17)
  EXPECT_TRUE(std::ifstream(dir + "/back/seam.src").good());
  EXPECT_TRUE(std::ifstream(dir + "/back/seam.dat").good());
  r = accura(dir, "convert --in seam.xml --out seam_back.src");
  ASSERT_EQ(r.code, 0) << r.err;
  r = accura(dir, "convert --in seam_back.src --config '$config.dat' --out seam_back.xml");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(test::readText(dir + "/seam_back.xml"), test::readText(dir + "/seam.xml"));
  // the compensated XML program equals the compensated KRL program converted
  r = accura(dir, "compensate --robot kr16_real.xml --in seam.xml --out out_xml --tol 0.02");
  ASSERT_EQ(r.code, 0) << r.err;
  r = accura(dir, "convert --in '" + golden("expected/seam.src") + "' --config '$config.dat' --out golden.xml");
  ASSERT_EQ(r.code, 0) << r.err;
  // the same corrected points (the XML carries the frames with 4 decimals: 1e-4 mm apart).
  // The XML carries the TRIGGER (a pass-through statement bound to LIN XP3, as in KRL): the
  // same auxiliary points.
  const Program a = readXmlProgram(dir + "/out_xml/seam.xml");
  const Program b = readXmlProgram(dir + "/golden.xml");
  EXPECT_EQ(a.motions.size(), b.motions.size());
  int named = 0;
  for (const Motion& mb : b.motions) {
    if (mb.target.name.empty() || mb.target.kind != Target::Kind::kCartesian) continue;
    for (const Motion& ma : a.motions) {
      if (ma.target.name != mb.target.name) continue;
      ++named;
      for (int c = 0; c < 6; ++c) EXPECT_NEAR(*ma.target.pose[c], *mb.target.pose[c], 2e-3) << mb.target.name;
    }
  }
  EXPECT_EQ(named, 5);
  r = accura(dir, "convert --in seam.src --out seam.src");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("the output would overwrite the input"), std::string::npos) << r.err;
}

// A cell's program often leaves its frames to a routine of another module (MoveSettings(base,
// tool, ..)), which accura cannot read: the refusal names that call and the option that gives
// the frame it sets; KRL's own statements with parentheses (CAST_TO, PULSE) are not taken for one.
TEST(CompensateCli, FramesLeftToAnotherModulesRoutineNameTheCall) {
  const std::string dir = inputs("comp_external_frames");
  test::writeText(dir + "/cell.src",
                  "DEF cell()\n  CAST_TO(BUF[],OFS,1)\n  MoveSettings(1, 2)\n  PTP {A1 0,A2 -90,A3 90,A4 0,A5 45,A6 0}\n"
                  "  LIN {X 900,Y 0,Z 1100,A 0,B 90,C 0}\nEND\n");
  CliRun r = accura(dir, "compensate --robot kr16_real.xml --in cell.src --out o");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("cell.src:5:3: the tool of this motion is not known: $TOOL is not set in this file before this motion; "
                       "MoveSettings (called at cell.src:3:3), a routine this file does not define, may set it: give the frame it "
                       "sets with --program-tool x,y,z,A,B,C, or set $TOOL in the program"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/o/cell.src"));
}

// FreeCAD's compact KRL sets neither $TOOL nor $BASE: the controller's active frames are
// given on the command line; the numbers of the inline targets change, their comments stay.
TEST(CompensateCli, ProgramsWithoutFramesTakeThemFromTheCommandLine) {
  const std::string dir = inputs("comp_freecad");
  test::writeText(dir + "/Trajectory.src", test::readText(test::sourcePath("tests/golden/krl/freecad/Trajectory.src")));
  CliRun r = accura(dir, "compensate --robot kr16_real.xml --in Trajectory.src --out o");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("Trajectory.src:17:1: the tool of this motion is not known: $TOOL is not set before this motion"), std::string::npos)
      << r.err;
  r = accura(dir, "compensate --robot kr16_real.xml --in Trajectory.src --out o --program-tool 0,0,200,0,0,0 --program-base 0,0,0,0,0,0");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("Trajectory.src:17:1: LIN after a position that is not known"), std::string::npos) << r.err;
  const auto in = lines(test::readText(dir + "/Trajectory.src"));
  const auto out = lines(test::readText(dir + "/o/Trajectory.src"));
  ASSERT_EQ(in.size(), out.size());
  int changed = 0;
  for (size_t k = 0; k < in.size(); ++k) {
    if (in[k] == out[k]) continue;
    ++changed;
    EXPECT_EQ(in[k].rfind("LIN {X ", 0), 0u) << in[k];
    EXPECT_EQ(in[k].substr(in[k].find('}')), out[k].substr(out[k].find('}'))) << "the comment after the target stays";
  }
  EXPECT_EQ(changed, 3);
  EXPECT_FALSE(std::ifstream(dir + "/o/Trajectory.dat").good());  // no .dat in, none out
}

// A partial target takes its missing components from where the program meant the robot to
// be (the previous target as written, not as corrected): it is compensated exactly like the
// complete target, and written with every component whose corrected value differs from the
// controller's position before it (here all six: the same text as the complete target's).
TEST(CompensateCli, PartialTargetsAreCompletedFromTheIntendedPosition) {
  const std::string dir = inputs("comp_partial");
  const std::string head =
      "DEF p( )\n$TOOL={X 107.147003,Y 6.19999992E-05,Z 313.237,A 0.0,B 45.0,C 0.0}\n$BASE={X 950,Y -400,Z 300,A 90,B 0,C 0}\n"
      "PTP {X 1050,Y -250,Z 550,A 178.1,B 29.9,C -179.3,S 2,T 11}\n";
  test::writeText(dir + "/partial.src", head + "LIN {Z 420}\nEND\n");
  test::writeText(dir + "/full.src", head + "LIN {X 1050,Y -250,Z 420,A 178.1,B 29.9,C -179.3}\nEND\n");
  for (const char* p : {"partial.src", "full.src"}) {
    const CliRun r = accura(dir, std::string("compensate --robot kr16_real.xml --in ") + p + " --out out");
    ASSERT_EQ(r.code, 0) << r.err;
  }
  const auto partial = lines(test::readText(dir + "/out/partial.src"));
  const auto full = lines(test::readText(dir + "/out/full.src"));
  ASSERT_EQ(partial.size(), 6u);
  EXPECT_EQ(partial, full);
  EXPECT_EQ(partial[4].rfind("LIN {X 1050.", 0), 0u) << partial[4];
}

// A target next to a T-bit boundary: joint A6 within a fraction of a degree of 0, where the
// correction moves it across 0. The written T is the one of the joints the controller will
// take (its IK of the written pose on the written S/T puts the real tool on the intended
// pose), changed only for such joints and with a warning per target.
TEST(CompensateCli, TurnBitOfAJointNextToZeroIsRewrittenWithAWarning) {
  const std::string dir = inputs("comp_tbit");
  const calib::RobotModel real = calib::readRobotFile(golden("kr16_real.xml"));
  calib::RobotModel controller = calib::RobotModel::fromDefinition(real.nominal);
  const calib::XyzAbc tool = calib::toXyzAbc(real.nominal.T_flange_tcp);
  calib::XyzAbc base;
  base.x_mm = 950;
  base.y_mm = -400;
  base.z_mm = 300;
  base.a_deg = 90;
  const Eigen::Isometry3d T_world_base1 = calib::toIsometry(base);
  std::ostringstream src;
  src.setf(std::ios::fixed);
  src.precision(6);
  src << "DEF tbit( )\n$TOOL={X " << tool.x_mm << ",Y " << tool.y_mm << ",Z " << tool.z_mm << ",A " << tool.a_deg << ",B " << tool.b_deg
      << ",C " << tool.c_deg << "}\n$BASE={X 950,Y -400,Z 300,A 90,B 0,C 0}\n";
  std::vector<calib::Configuration> asked;
  for (int k = -15; k <= 15; ++k) {
    Eigen::VectorXd q(6);
    q << 10, -80, 95, 30, 45, 0.02 * k + 0.001;  // deg, never exactly 0
    const calib::Configuration c = calib::kukaConfiguration(controller, q);
    asked.push_back(c);
    const calib::XyzAbc t = calib::toXyzAbc(T_world_base1.inverse() * calib::KinematicSolver(controller).forward(q));
    src << "PTP {X " << t.x_mm << ",Y " << t.y_mm << ",Z " << t.z_mm << ",A " << t.a_deg << ",B " << t.b_deg << ",C " << t.c_deg << ",S " << c.status
        << ",T " << c.turn << "}\n";
  }
  src << "END\n";
  test::writeText(dir + "/tbit.src", src.str());
  const CliRun r = accura(dir, "compensate --robot kr16_real.xml --in tbit.src --out out");
  ASSERT_EQ(r.code, 0) << r.err;
  const Program in = readKrl(dir + "/tbit.src");
  const Program out = readKrl(dir + "/out/tbit.src");
  ASSERT_EQ(out.motions.size(), asked.size());
  const calib::KinematicSolver ctl(controller), rl(real);
  int flipped = 0;
  for (size_t k = 0; k < out.motions.size(); ++k) {
    const Target& t = out.motions[k].target;
    ASSERT_TRUE(t.status && t.turn);
    EXPECT_EQ(*t.status, asked[k].status) << k;
    // the controller on the written S/T reaches the written pose with joints whose T is the
    // written one, and the real robot there is on the intended pose
    const calib::IkResult qc = ctl.inverse(T_world_base1 * calib::toIsometry(t.xyzAbc()), calib::Configuration{*t.status, *t.turn},
                                    Eigen::VectorXd(), calib::IkOptions{});
    ASSERT_EQ(qc.status, calib::IkStatus::kOk) << k << " " << qc.message;
    EXPECT_EQ(calib::kukaConfiguration(controller, qc.q).turn, *t.turn) << k;
    const Eigen::Isometry3d intended = T_world_base1 * calib::toIsometry(in.motions[k].target.xyzAbc());
    EXPECT_LT((rl.forward(qc.q).translation() - intended.translation()).norm(), 1e-3) << k;
    if (*t.turn != asked[k].turn) {
      ++flipped;
      EXPECT_EQ(*t.turn ^ asked[k].turn, 1 << 5) << "only A6's bit: " << k;
      EXPECT_LT(std::abs(qc.q[5]), 1.0) << k;
    }
  }
  EXPECT_GT(flipped, 0);  // the grid straddles the correction of A6
  size_t warnings = 0;
  for (size_t p = r.err.find("T of "); p != std::string::npos; p = r.err.find("T of ", p + 1)) ++warnings;
  EXPECT_EQ(warnings, static_cast<size_t>(flipped)) << r.err;
}

// A target in the wrist singularity (the KR 16 at A1..A6 = 0,-90,90,0,0,0: A5 = 0, so A4 and A6
// turn about one axis and the Jacobian's smallest singular value is 0; accura fk gives X 1088,
// Z 1320, B 90 there): the error says "singular" once, then why (before: "singular: singular:
// the smallest ...", the status word and the IK's message both starting with it).
TEST(CompensateCli, ASingularTargetSaysSingularOnce) {
  const std::string dir = test::tempDir("comp_singular");
  test::writeText(dir + "/sing.src", "DEF sing( )\n$TOOL={X 0,Y 0,Z 0,A 0,B 0,C 0}\n$BASE={X 0,Y 0,Z 0,A 0,B 0,C 0}\n"
                                     "PTP {X 1088,Y 0,Z 1320,A 0,B 90,C 0}\nEND\n");
  // The controller runs a PTP to a point in the wrist singularity (KUKA: axis 4 at 0 deg or at
  // its start value, $SINGUL_POS[3], axis 6 adapted): kept as written and named, not refused
  const CliRun r = accura(dir, "compensate --robot kuka_kr16 --in sing.src --out o");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("accura: warning: sing.src:4:1: PTP left unchanged (not compensated): the inline target lies at a singularity "
                       "of the arm, where the controller chooses the axes by its own rule (the smallest scaled singular value of the "
                       "Jacobian is "),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.err.find("singular: singular"), std::string::npos) << r.err;
  EXPECT_EQ(test::readText(dir + "/o/sing.src"), test::readText(dir + "/sing.src"));
}

// A directory given as compensate's --in (a new user's tree of programs): said as a directory,
// with the command for a tree (before: "found ''", the directory's empty extension); a directory
// where convert expects a program is named as one too.
TEST(CompensateCli, ADirectoryGivenForAProgramIsSaidToBeOne) {
  const std::string dir = test::tempDir("comp_dir_in");
  std::filesystem::create_directories(dir + "/progs");
  CliRun r = accura(dir, "compensate --robot kuka_kr16 --in progs --out o");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("accura: error: progs: expected a program file (--in), found a directory; every program of a directory tree: "
                       "accura batch --in progs --out DIR"),
            std::string::npos)
      << r.err;
  r = accura(dir, "convert --in progs --out p.xml");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("progs: expected a program file ending in .src (KUKA KRL) or .xml (accura XML program) or .script (URScript) or "
                       ".mod/.modx/.sys/.sysx/.prg (ABB RAPID), found a directory"),
            std::string::npos)
      << r.err;
  // a directory given for the data list, the $config.dat or the cell: "it is a directory"
  // (before: "no such file", and for the cell "found an empty file")
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP {X 1000,Y 0,Z 800,A 0,B 90,C 0}\nEND\n");
  const auto message = [](const std::function<void()>& read) {
    try {
      read();
    } catch (const calib::InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  KrlReadOptions dat, config;
  dat.dat_path = dir + "/progs";
  config.config_path = dir + "/progs";
  EXPECT_EQ(message([&] { readKrl(dir + "/p.src", dat); }), dir + "/progs: cannot read the KRL data file: it is a directory");
  EXPECT_EQ(message([&] { readKrl(dir + "/p.src", config); }), dir + "/progs: cannot read the $config.dat: it is a directory");
  EXPECT_EQ(message([&] { readCellFile(dir + "/progs"); }), dir + "/progs: cannot read the cell file: it is a directory");
}

TEST(CompensateCli, ErrorsNameThePlaceAndWriteNothing) {
  const std::string dir = inputs("comp_err");
  // the output directory is the input's: the outputs would overwrite the inputs
  CliRun r = accura(dir, "compensate --robot kr16_real.xml --in seam.src --config '$config.dat' --out .");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("the output would overwrite the input"), std::string::npos) << r.err;
  EXPECT_EQ(test::readText(dir + "/seam.src"), test::readText(golden("seam.src")));
  EXPECT_EQ(test::readText(dir + "/seam.dat"), test::readText(golden("seam.dat")));
  // TOOL_DATA without the $config.dat
  r = accura(dir, "compensate --robot kr16_real.xml --in seam.src --out o1");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("seam.src:31:1: the tool of this motion is not known: $TOOL is TOOL_DATA[1] (set at seam.src:30:1), whose value needs the $config.dat (--config)"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(std::ifstream(dir + "/o1/seam.src").good());
  // an unreachable target and a malformed one
  std::string dat = test::readText(golden("seam.dat"));
  dat.replace(dat.find("X 400.0,Y -50.0"), 15, "X 4000.0,Y -50.0");
  test::writeText(dir + "/far.src", test::readText(golden("seam.src")));
  test::writeText(dir + "/far.dat", dat);
  r = accura(dir, "compensate --robot kr16_real.xml --in far.src --config '$config.dat' --out o2");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("accura: error: far.src:54:1: the LIN to XP4 cannot be compensated: unreachable"), std::string::npos) << r.err;
  EXPECT_FALSE(std::ifstream(dir + "/o2/far.src").good());
  // a model measured in a tracker's frame, without --base
  std::string model = test::readText(golden("kr16_real.xml"));
  model.replace(model.find("name=\"base_x\" value=\"0.84\""), 26, "name=\"base_x\" value=\"2400\"");
  test::writeText(dir + "/tracker.xml", model);
  r = accura(dir, "compensate --robot tracker.xml --in seam.src --config '$config.dat' --out o3");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("is 2400.0001 mm and 0.02502 deg from the nominal base"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("give --base x,y,z,A,B,C"), std::string::npos) << r.err;
  // ... with --base it works, and gives the golden's values (the same base error)
  r = accura(dir, "compensate --robot tracker.xml --base 2399.16,0,0,0,0,0 --in seam.src --config '$config.dat' --out o4 --tol 0.02");
  ASSERT_EQ(r.code, 0) << r.err;
  KrlReadOptions o;
  o.config_path = golden("$config.dat");
  const Program shifted = readKrl(dir + "/o4/seam.src", o), expected = readKrl(golden("expected/seam.src"), o);
  ASSERT_EQ(shifted.motions.size(), expected.motions.size());
  for (size_t k = 0; k < shifted.motions.size(); ++k)
    for (int c = 0; c < 6; ++c)
      if (expected.motions[k].target.pose[c]) {
        EXPECT_NEAR(*shifted.motions[k].target.pose[c], *expected.motions[k].target.pose[c], 2e-3) << k;
      }
  // a CIRC whose points are collinear
  test::writeText(dir + "/circ.src",
                  "DEF circ( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE={X 900,Y -350,Z 250,A 0,B 0,C 0}\n"
                  "PTP {X 100,Y 0,Z 150,A 160,B 10,C 170,S 2,T 10}\n"
                  "CIRC {X 150,Y 0,Z 150,A 160,B 10,C 170}, {X 200,Y 0,Z 150,A 160,B 10,C 170}\nEND\n");
  r = accura(dir, "compensate --robot kr16_real.xml --in circ.src --out o6");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("circ.src:5:1: this motion cannot be compensated: CIRC: start, auxiliary and end point are collinear"), std::string::npos)
      << r.err;
  // bad options
  r = accura(dir, "compensate --robot kr16_real.xml --in seam.src --config '$config.dat' --out o5 --tol -1");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--tol: expected a number in [0.001, 100] (mm), found '-1' (see accura compensate --help)"), std::string::npos) << r.err;
  r = accura(dir, "compensate --robot kr16_real.xml --in seam.txt --out o5");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("expected a program file ending in .src (KUKA KRL) or .xml"), std::string::npos) << r.err;
}

// An ABB task as a cell engineer has it: the program module, its tool and work object in
// calib.sys, its approach points in a module of global robtargets. `--config` was taken once
// (a second one: CLI11 refused or the last one won); it is now given once per module, each
// only read. The points of points.mod that motions correct go to new points of the program
// module (LOCAL, after its data): the golden module's corrections (tests/golden/rapid/expected,
// the module that declares everything itself), under new names, and nothing else changes.
TEST(CompensateCli, RapidTaskModulesGivenWithConfigEachOnce) {
  const std::string g = test::sourcePath("tests/golden/rapid/");
  const std::string dir = test::tempDir("comp_rapid_task");
  const std::vector<std::string> in = lines(test::readText(g + "irb120_seam.mod"));
  const std::vector<std::string> want = lines(test::readText(g + "expected/irb120_seam.mod"));
  ASSERT_EQ(trimmed(in[3]).substr(0, 14), "PERS tooldata ");
  ASSERT_EQ(trimmed(in[6]).substr(0, 20), "CONST robtarget p10 ");
  ASSERT_EQ(trimmed(in[7]).substr(0, 20), "CONST robtarget p20 ");
  // lines 4, 5 (torch, table) to calib.sys, 7 and 8 (p10, p20) to points.mod
  std::string program, expected;
  for (size_t k = 0; k < in.size(); ++k)
    if (k != 3 && k != 4 && k != 6 && k != 7) program += in[k] + "\n";
  test::writeText(dir + "/seam.mod", program);
  const std::string calib = "MODULE CalibData(SYSMODULE)\n" + in[3] + "\n" + in[4] + "\nENDMODULE\n";
  const std::string points = "MODULE Points\n" + in[6] + "\n" + in[7] + "\nENDMODULE\n";
  test::writeText(dir + "/calib.sys", calib);
  test::writeText(dir + "/points.mod", points);
  test::writeText(dir + "/irb120_real.xml", test::readText(g + "irb120_real.xml"));
  auto value = [](const std::string& line) { return line.substr(line.find(":= ") + 3, line.rfind(';') - line.find(":= ") - 3); };
  for (size_t k = 0; k < want.size(); ++k) {
    if (k == 3 || k == 4 || k == 6 || k == 7) continue;
    std::string l = want[k];
    for (const char* m : {"MoveJ p10,", "MoveL p20,"})
      if (l.find(m) != std::string::npos) l.replace(l.find(m), 9, std::string(m).substr(0, 9) + "_1");
    expected += l + "\n";
    if (trimmed(want[k]) == "VAR num seams := 0;")
      expected += "  LOCAL CONST robtarget p10_1 := " + value(want[6]) + ";\n  LOCAL CONST robtarget p20_1 := " + value(want[7]) + ";\n";
  }
  const CliRun r = accura(dir, "compensate --robot irb120_real.xml --in seam.mod --config calib.sys --config points.mod --out out");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(test::readText(dir + "/out/seam.mod"), expected);
  EXPECT_NE(r.err.find("seam.mod:14:5: p10 is declared in points.mod:2:26, a module given with --config, which accura only reads: this motion goes to "
                       "a new point p10_1 declared in this module (LOCAL, after its data) with the correction; p10 keeps its value"),
            std::string::npos)
      << r.err;
  // the modules given with --config are only read, and nothing else is written
  EXPECT_EQ(test::readText(dir + "/calib.sys"), calib);
  EXPECT_EQ(test::readText(dir + "/points.mod"), points);
  EXPECT_EQ(test::readText(dir + "/seam.mod"), program);
  size_t written = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir + "/out")) written += e.is_regular_file();
  EXPECT_EQ(written, 1u);
  // check and convert take them too
  const CliRun v = accura(dir, "convert --in seam.mod --config calib.sys --config points.mod --out conv/seam.xml");
  ASSERT_EQ(v.code, 0) << v.err;
  // a KRL program with two $config.dat: refused, naming both
  const std::string krl = inputs("comp_rapid_task_krl");
  const CliRun k = accura(krl, "compensate --robot kr16_real.xml --in seam.src --config '$config.dat' --config seam.dat --out o");
  EXPECT_EQ(k.code, 1);
  EXPECT_NE(k.err.find("--config: a KRL or XML program takes one $config.dat (the controller has one, KRC:\\R1\\System\\$config.dat), found 2: $config.dat "
                       "and seam.dat"),
            std::string::npos)
      << k.err;
  std::filesystem::remove_all(dir);
  std::filesystem::remove_all(krl);
}

}  // namespace
}  // namespace accura::postproc
