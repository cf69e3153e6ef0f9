// KRL reader and writer: realistic programs (inline forms, spline inline forms, an OLP's
// expert KRL; CRLF and LF, mixed case, folds, logic, I/O) read and written back byte for byte;
// the motion model read from them against the values in the files; only corrected values and
// inserted points change; malformed targets are errors with file:line:column.
#include <gtest/gtest.h>

#include <filesystem>

#include "accura/calib/errors.h"
#include "accura/postproc/krl.h"
#include "accura/postproc/program_io.h"
#include "accura/postproc/xml_program.h"
#include "test_util.h"

namespace accura::postproc {
namespace {

std::string golden(const std::string& rel) { return test::sourcePath("tests/golden/krl/" + rel); }
std::string config() { return golden("config/$config.dat"); }

Program read(const std::string& rel, bool with_config = false) {
  KrlReadOptions o;
  if (with_config) o.config_path = config();
  return readKrl(golden(rel), o);
}

// The error of reading `src` (and `dat`) from a temporary directory.
calib::InputError readError(const std::string& src, const std::string& dat = "") {
  const std::string dir = test::tempDir("krl_err");
  test::writeText(dir + "/p.src", src);
  if (!dat.empty()) test::writeText(dir + "/p.dat", dat);
  try {
    readKrl(dir + "/p.src");
  } catch (const calib::InputError& e) {
    return e;
  }
  ADD_FAILURE() << "expected an InputError for:\n" << src;
  return calib::InputError("none");
}

TEST(Krl, NumberFormatsAreFixedAndNeverNegativeZero) {
  EXPECT_EQ(formatMm(1.23456), "1.2346");
  EXPECT_EQ(formatMm(-2.5), "-2.5000");
  EXPECT_EQ(formatMm(-0.00004), "0.0000");
  EXPECT_EQ(formatMm(-0.0), "0.0000");
  EXPECT_EQ(formatDeg(-1e-7), "0.00000");
  EXPECT_EQ(formatDeg(-179.999996), "-180.00000");
  EXPECT_EQ(calib::formatFixed(0.02, 4), "0.0200");
}

TEST(Krl, RealisticProgramsAreWrittenBackByteForByte) {
  for (const std::string rel : {"kss8_inline/weld_seam.src", "robodk/Pick_Place.src", "spline/glue_bead.src", "freecad/Trajectory.src",
                                "krc2/palette.src"}) {
    for (bool cfg : {false, true}) {
      const Program p = read(rel, cfg);
      ASSERT_TRUE(p.krl) << rel;
      const KrlText t = writeKrl(p);
      EXPECT_EQ(t.src, test::readText(golden(rel))) << rel;
      EXPECT_EQ(t.src, p.krl->src_text) << rel;
      if (!p.krl->dat_path.empty()) {
        EXPECT_EQ(t.dat, test::readText(p.krl->dat_path)) << rel;
      }
    }
  }
  // the test files are what they claim to be
  EXPECT_NE(test::readText(golden("kss8_inline/weld_seam.src")).find("\r\n"), std::string::npos);
  EXPECT_NE(test::readText(golden("kss8_inline/weld_seam.src")).find('\xfc'), std::string::npos);  // cp1252 comment
  EXPECT_EQ(test::readText(golden("robodk/Pick_Place.src")).find('\r'), std::string::npos);
  EXPECT_NE(test::readText(golden("robodk/Pick_Place.src")).back(), '\n');
}

TEST(Krl, InlineFormsGiveTheMotionModel) {
  const Program p = read("kss8_inline/weld_seam.src", true);
  EXPECT_EQ(p.name, "weld_seam");
  ASSERT_EQ(p.motions.size(), 7u);
  const MotionType types[] = {MotionType::kPtp, MotionType::kPtp, MotionType::kLin, MotionType::kLin,
                              MotionType::kCirc, MotionType::kLin, MotionType::kPtp};
  for (size_t i = 0; i < 7; ++i) EXPECT_EQ(p.motions[i].type, types[i]) << i;
  // PTP HOME: XHOME from the $config.dat, FHOME: TOOL_NO 0, BASE_NO 0
  const Motion& home = p.motions[0];
  EXPECT_TRUE(home.target_problem.empty()) << home.target_problem;
  EXPECT_EQ(home.target.kind, Target::Kind::kAxis);
  EXPECT_EQ(*home.target.axes[1], -90.0);
  EXPECT_EQ(*home.target.axes[4], 45.0);
  EXPECT_EQ(home.tool.source, FrameSetting::Source::kNull);
  EXPECT_EQ(home.where.line, 26);
  EXPECT_EQ(home.where.column, 1);
  // LIN P2 CONT: XP2 from the .dat, FP2 -> TOOL_DATA[1], BASE_DATA[1]; LCPDAT1 APO_DIST 10
  const Motion& p2 = p.motions[2];
  EXPECT_EQ(p2.target.name, "XP2");
  EXPECT_EQ(*p2.target.pose[0], 1210.5);
  EXPECT_EQ(*p2.target.pose[1], -180.25);
  EXPECT_EQ(*p2.target.pose[3], 178.100006);
  EXPECT_EQ(*p2.target.status, 2);
  EXPECT_EQ(*p2.target.turn, 11);
  EXPECT_EQ(*p2.target.ext[0], 0.0);
  EXPECT_EQ(p2.target.where.file, golden("kss8_inline/weld_seam.dat"));
  EXPECT_EQ(p2.target.where.line, 21);
  ASSERT_EQ(p2.approximation.size(), 2u);
  EXPECT_EQ(p2.approximation[0], Approximation::kCDis);
  EXPECT_EQ(*p2.approximation_value, 10.0);
  EXPECT_EQ(*p2.vel_m_s, 0.5);
  EXPECT_EQ(p2.tool.source, FrameSetting::Source::kData);
  EXPECT_EQ(p2.tool.index, 1);
  EXPECT_EQ(p2.tool.value->x_mm, 107.147003);
  EXPECT_EQ(p2.tool.value->y_mm, 6.19999992E-05);
  EXPECT_EQ(p2.tool.value->b_deg, 45.0);
  EXPECT_EQ(p2.base.index, 1);
  EXPECT_EQ(p2.base.value->x_mm, 950.0);
  EXPECT_EQ(p2.base.value->a_deg, 90.0);
  // LIN P3 without approximation, 0.02 m/s
  EXPECT_TRUE(p.motions[3].approximation.empty());
  EXPECT_EQ(*p.motions[3].vel_m_s, 0.02);
  // CIRC XP4, XP5
  const Motion& c = p.motions[4];
  ASSERT_TRUE(c.aux);
  EXPECT_EQ(c.aux->name, "XP4");
  EXPECT_EQ(*c.aux->pose[0], 1260.5);
  EXPECT_EQ(*c.target.pose[0], 1310.5);
  EXPECT_EQ(c.where.line, 62);
}

TEST(Krl, WithoutTheConfigGlobalNamesStayUnresolved) {
  const Program p = read("kss8_inline/weld_seam.src");
  EXPECT_NE(p.motions[0].target_problem.find("XHOME is not declared"), std::string::npos) << p.motions[0].target_problem;
  EXPECT_EQ(p.motions[0].tool.source, FrameSetting::Source::kUnknown);
  EXPECT_EQ(p.motions[0].tool.text, "TOOL_DATA[FHOME.TOOL_NO]");
  EXPECT_EQ(p.motions[2].tool.source, FrameSetting::Source::kData);
  EXPECT_EQ(p.motions[2].tool.index, 1);
  EXPECT_FALSE(p.motions[2].tool.value);
  EXPECT_TRUE(p.motions[2].target_problem.empty());
}

TEST(Krl, SplineInlineFormsReadTheWithClause) {
  const Program p = read("spline/glue_bead.src", true);
  ASSERT_EQ(p.motions.size(), 5u);
  const Motion& sptp = p.motions[1];
  EXPECT_TRUE(sptp.spline);
  EXPECT_EQ(sptp.type, MotionType::kPtp);
  EXPECT_EQ(*sptp.vel_percent, 100.0);
  EXPECT_EQ(sptp.tool.index, 2);
  EXPECT_EQ(sptp.tool.value->z_mm, 245.0);
  EXPECT_EQ(sptp.base.index, 3);
  EXPECT_EQ(sptp.base.value->x_mm, 1020.25);
  const Motion& slin = p.motions[2];
  EXPECT_EQ(slin.type, MotionType::kLin);
  EXPECT_EQ(slin.target.name, "XP2");  // declared in lower case: DECL e6pos xP2={x 412.5,...}
  EXPECT_EQ(*slin.target.pose[0], 412.5);
  EXPECT_EQ(*slin.target.pose[2], 20.0);
  ASSERT_EQ(slin.approximation.size(), 1u);
  EXPECT_EQ(slin.approximation[0], Approximation::kCSpl);
  EXPECT_EQ(*slin.approximation_value, 5.0);
  EXPECT_EQ(*slin.vel_m_s, 0.1);
  const Motion& scirc = p.motions[3];
  EXPECT_EQ(scirc.type, MotionType::kCirc);
  EXPECT_EQ(scirc.aux->name, "XP3");
  EXPECT_EQ(*scirc.aux->pose[1], -288.25);
  EXPECT_EQ(scirc.target.name, "XP4");
  // a WITH clause is valid for its motion only: the last SPTP HOME uses FHOME (tool 0)
  EXPECT_EQ(p.motions[4].tool.source, FrameSetting::Source::kNull);
}

// `DECL GLOBAL CONST ...` (a constant other modules see) in a data list: the keywords are read
// one after the other. The reader stopped on CONST after GLOBAL and never returned (the
// fuzzer's finding: `DECL GLOBAL GLOBAL ...` hung it the same way).
TEST(Krl, GlobalConstDeclarationsAreRead) {
  const std::string dir = test::tempDir("krl_global_const");
  test::writeText(dir + "/$config.dat",
                  "DEFDAT $CONFIG\nDECL GLOBAL CONST INT MAX_TOOLS=16\nDECL GLOBAL GLOBAL INT TWICE=1\n"
                  "DECL GLOBAL FRAME TOOL_DATA[16]\nTOOL_DATA[2]={X 0.0,Y 0.0,Z 200.0,A 0.0,B 90.0,C 0.0}\n"
                  "DECL CONST GLOBAL FRAME BASE_DATA[32]\nBASE_DATA[3]={X 900.0,Y -300.0,Z 200.0,A 30.0,B 0.0,C 0.0}\n"
                  "ENDDAT\n");
  const FrameTables t = readKrlFrameTables(dir + "/$config.dat");
  ASSERT_GT(t.tool.size(), 2u);
  ASSERT_TRUE(t.tool[2].has_value());
  EXPECT_DOUBLE_EQ(t.tool[2]->z_mm, 200.0);
  EXPECT_DOUBLE_EQ(t.tool[2]->b_deg, 90.0);
  ASSERT_GT(t.base.size(), 3u);
  ASSERT_TRUE(t.base[3].has_value());
  EXPECT_DOUBLE_EQ(t.base[3]->x_mm, 900.0);
  EXPECT_DOUBLE_EQ(t.base[3]->a_deg, 30.0);
}

// The KSS inline form of a spline block: SPLINE WITH $TOOL = STOOL2(FP1), $BASE =
// SBASE(FP1.BASE_NO) sets the frames of the block's motions (the FDAT's TOOL_NO / BASE_NO into
// the $config.dat's TOOL_DATA / BASE_DATA, as for a single motion's WITH); after ENDSPLINE the
// program's own frames hold again. A program written anew from the model sets the frames before
// the block (a block's segments cannot).
TEST(Krl, ASplineBlocksWithClauseSetsTheFramesOfItsMotions) {
  const std::string dir = test::tempDir("krl_spline_with");
  test::writeText(dir + "/$config.dat",
                  "DEFDAT $CONFIG\nDECL GLOBAL FRAME TOOL_DATA[16]\nTOOL_DATA[2]={X 0.0,Y 0.0,Z 200.0,A 0.0,B 90.0,C 0.0}\n"
                  "DECL GLOBAL FRAME BASE_DATA[32]\nBASE_DATA[2]={X 900.0,Y -300.0,Z 200.0,A 30.0,B 0.0,C 0.0}\nENDDAT\n");
  test::writeText(dir + "/p.src",
                  "DEF p( )\nPTP {A1 10,A2 -80,A3 100,A4 20,A5 30,A6 40}\n"
                  "SPLINE WITH $VEL.CP = 0.2, $TOOL = STOOL2(FP1), $BASE = SBASE(FP1.BASE_NO)\n  SPL XP1\n  SPL XP2\n  SLIN XP3\nENDSPLINE\n"
                  "SLIN XP1 WITH $TOOL = STOOL2(FP1), $BASE = SBASE(FP1.BASE_NO), $VEL = SVEL_CP(0.3, , LCPDAT1) C_SPL\n"
                  "PTP {A1 0}\nEND\n");
  test::writeText(dir + "/p.dat",
                  "DEFDAT p\nDECL FDAT FP1={TOOL_NO 2,BASE_NO 2,IPO_FRAME #BASE,POINT2[] \" \"}\n"
                  "DECL E6POS XP1={X 273.087,Y -127.407,Z 618.527,A 125.327,B -47.537,C -111.572,S 2,T 2}\n"
                  "DECL E6POS XP2={X 135.598,Y -264.075,Z 477.826,A 115.342,B -63.826,C -129.097,S 2,T 2}\n"
                  "DECL E6POS XP3={X 93.096,Y -259.890,Z 509.745,A 136.186,B -59.107,C -177.850,S 2,T 10}\nENDDAT\n");
  KrlReadOptions o;
  o.config_path = dir + "/$config.dat";
  const Program p = readKrl(dir + "/p.src", o);
  ASSERT_EQ(p.motions.size(), 6u);
  for (size_t i = 1; i <= 4; ++i) {
    const Motion& m = p.motions[i];
    EXPECT_EQ(m.tool.source, FrameSetting::Source::kData) << i;
    EXPECT_EQ(m.tool.index, 2) << i;
    ASSERT_TRUE(m.tool.value) << i;
    EXPECT_EQ(m.tool.value->z_mm, 200.0) << i;
    EXPECT_EQ(m.tool.value->b_deg, 90.0) << i;
    EXPECT_EQ(m.base.index, 2) << i;
    ASSERT_TRUE(m.base.value) << i;
    EXPECT_EQ(m.base.value->x_mm, 900.0) << i;
    EXPECT_EQ(m.base.value->a_deg, 30.0) << i;
  }
  EXPECT_EQ(p.motions[1].vel_m_s, 0.2);  // the block's $VEL.CP
  EXPECT_EQ(p.motions[3].vel_m_s, 0.2);
  EXPECT_EQ(p.motions[4].vel_m_s, 0.3);  // the single SLIN's own WITH
  EXPECT_EQ(p.motions[0].tool.source, FrameSetting::Source::kUnset);  // before the block
  EXPECT_EQ(p.motions[5].tool.source, FrameSetting::Source::kUnset);  // after ENDSPLINE: the program's frames
  EXPECT_EQ(p.motions[5].base.source, FrameSetting::Source::kUnset);

  // written anew (from the model, as from XML): $TOOL, $BASE and $VEL.CP before SPLINE, none inside
  Program fresh = p;
  fresh.krl.reset();
  const std::string src = test::lf(writeKrl(fresh).src);
  const size_t block = src.find("\nSPLINE\n"), end = src.find("\nENDSPLINE\n");
  ASSERT_NE(block, std::string::npos) << src;
  ASSERT_NE(end, std::string::npos) << src;
  EXPECT_LT(src.find("\n$TOOL=TOOL_DATA[2]\n"), block) << src;
  EXPECT_LT(src.find("\n$BASE=BASE_DATA[2]\n"), block) << src;
  EXPECT_LT(src.find("\n$VEL.CP=0.2000\n"), block) << src;
  EXPECT_EQ(src.substr(block, end - block).find('$'), std::string::npos) << src;
}

// A module of functions only (GLOBAL DEFFCT .. ENDFCT, no DEF; KRC backups hold many) is a module
// the controller loads: read, without motions, written back as it is; written in another form
// it is refused (there is no program to write). It was refused as "found no DEF line".
TEST(Krl, AModuleOfFunctionsOnlyIsReadAndWrittenBackAsItIs) {
  const std::string dir = test::tempDir("krl_functions_only");
  const std::string text = "&ACCESS RVP\r\n&REL 2\r\nGLOBAL DEFFCT REAL clamp(v:IN)\r\n  REAL v\r\n  IF v>100 THEN\r\n    RETURN 100\r\n"
                           "  ENDIF\r\n  RETURN v\r\nENDFCT\r\n";
  test::writeText(dir + "/tools.src", text);
  const Program p = readKrl(dir + "/tools.src");
  EXPECT_TRUE(p.motions.empty());
  EXPECT_EQ(p.name, "tools");
  EXPECT_EQ(p.krl_functions_only, "clamp (" + dir + "/tools.src:3:1)");
  EXPECT_EQ(writeKrl(p).src, text);
  for (const ProgramFormat f : {ProgramFormat::kXml, ProgramFormat::kRapid, ProgramFormat::kUrScript}) {
    try {
      renderProgram(p, f, dir + "/out");
      ADD_FAILURE() << "written";
    } catch (const calib::ArgumentError& e) {
      EXPECT_NE(std::string(e.what()).find("the module holds functions only (the first: clamp ("), std::string::npos) << e.what();
    }
  }
  // with its statements dropped it would be an empty program: refused too
  const test::CliRun drop = test::runAccuraIn(dir, "convert --in tools.src --out lib.mod --drop-unconvertible");
  EXPECT_EQ(drop.code, 1);
  EXPECT_NE(drop.err.find("the module holds functions only"), std::string::npos) << drop.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/lib.mod"));
  // without a DEFFCT either, still no program
  test::writeText(dir + "/none.src", "&ACCESS RVP\n$OUT[1]=TRUE\n");
  EXPECT_THROW(readKrl(dir + "/none.src"), calib::InputError);
}

// The data list is the module's: DEFDAT names the module (its file, or its DEF; any case). Another
// module's data list (DEFDAT other next to mism.src) is not this module's: its points would
// silently replace the program's.
TEST(Krl, ADataListOfAnotherModuleIsAnError) {
  const std::string dir = test::tempDir("krl_defdat_name");
  test::writeText(dir + "/mism.src", "DEF mism( )\nLIN XP1\nEND\n");
  test::writeText(dir + "/mism.dat", "&ACCESS RVP\nDEFDAT  other PUBLIC\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  try {
    readKrl(dir + "/mism.src");
    FAIL();
  } catch (const calib::InputError& e) {
    EXPECT_EQ(e.file(), dir + "/mism.dat");
    EXPECT_EQ(e.line(), 2);
    EXPECT_EQ(e.column(), 9);
    EXPECT_EQ(e.message(), "expected the data list of the module mism (DEFDAT mism), found DEFDAT other");
  }
  test::writeText(dir + "/mism.dat", "DEFDAT MISM\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  EXPECT_EQ(readKrl(dir + "/mism.src").motions.size(), 1u);
}

// A point of the $config.dat (PTP XHOME) is the controller's: through the XML it stays a
// reference (external="true", its values kept for the other languages), and KRL written anew
// does not declare it in the module's data list, where it would hide the $config.dat's. (It was
// declared there.) Corrected, it travels as a value without its name.
TEST(Krl, APointOfTheConfigDatStaysTheConfigDatsThroughTheXml) {
  const std::string dir = test::tempDir("krl_external_point");
  test::writeText(dir + "/$config.dat",
                  "DEFDAT $CONFIG\nDECL GLOBAL E6AXIS XHOME={A1 0,A2 -90,A3 90,A4 0,A5 45,A6 0}\n"
                  "DECL GLOBAL E6POS XPICK={X 1000,Y 0,Z 800,A 0,B 90,C 0,S 2,T 2}\nENDDAT\n");
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL=$NULLFRAME\n$BASE=$NULLFRAME\nPTP XHOME\nPTP XPICK\nPTP XHOME\nEND\n");
  KrlReadOptions o;
  o.config_path = dir + "/$config.dat";
  Program p = readKrl(dir + "/p.src", o);
  ASSERT_EQ(p.motions.size(), 3u);
  EXPECT_TRUE(p.motions[0].target.external);
  EXPECT_TRUE(p.motions[1].target.external);
  const std::string xml = writeXmlProgram(p);
  EXPECT_NE(xml.find("<axes name=\"XHOME\" type=\"E6AXIS\" external=\"true\" a1=\"0.0000\""), std::string::npos) << xml;
  test::writeText(dir + "/p.xml", xml);
  const Program back = readXmlProgram(dir + "/p.xml");
  EXPECT_TRUE(back.motions[0].target.external);
  const KrlText fresh = test::lf(writeKrl(back));
  EXPECT_EQ(fresh.dat.find("XHOME"), std::string::npos) << fresh.dat;
  EXPECT_EQ(fresh.dat.find("XPICK"), std::string::npos) << fresh.dat;
  EXPECT_NE(fresh.src.find("\nPTP XHOME\nPTP XPICK\nPTP XHOME\n"), std::string::npos) << fresh.src;
  // corrected: a value without the name, in the XML and in KRL written anew
  p.motions[1].target.setPose({1000.5, 0, 800, 0, 90, 0});
  p.motions[1].target.modified = true;
  const std::string corrected = writeXmlProgram(p);
  EXPECT_EQ(corrected.find("name=\"XPICK\""), std::string::npos) << corrected;
  EXPECT_NE(corrected.find("<pose type=\"E6POS\" x_mm=\"1000.5000\""), std::string::npos) << corrected;
  Program fresh_corrected = p;
  fresh_corrected.krl.reset();
  EXPECT_NE(test::lf(writeKrl(fresh_corrected).src).find("\nPTP {X 1000.5000,Y 0.0000,Z 800.0000,A 0.00000,B 90.00000,C 0.00000,S 2,T 2}\n"),
            std::string::npos)
      << test::lf(writeKrl(fresh_corrected).src);
}

// SLIN, SCIRC and SPTP are segments of a block (one path, no stop between them) inside SPLINE /
// PTP_SPLINE ... ENDSPLINE, motions of their own (each stops unless approximated) outside one:
// the model numbers the blocks, the XML keeps the numbers, and KRL written anew from it has the
// same blocks. (Written anew, every SLIN, SCIRC and SPTP came out of its block.)
TEST(Krl, SplineBlocksSurviveTheXmlRoundTrip) {
  const std::string dir = test::tempDir("krl_spline_blocks");
  const std::string body = "PTP XP1\nSPLINE\nSLIN XP2\nSPL XP3\nSCIRC XP4, XP5\nSPL XP6\nENDSPLINE\nSLIN XP3\n"
                           "PTP_SPLINE\nSPTP XP1\nSPTP XP2\nENDSPLINE\nSPLINE\nSPL XP4\nENDSPLINE\n";
  test::writeText(dir + "/p.src", "DEF p( )\n" + body + "END\n");
  std::string dat = "DEFDAT p\n";
  for (int k = 1; k <= 6; ++k)
    dat += "DECL E6POS XP" + std::to_string(k) + "={X " + std::to_string(900 + 20 * k) + ",Y 0,Z 800,A 0,B 90,C 0}\n";
  test::writeText(dir + "/p.dat", dat + "ENDDAT\n");
  const Program p = readKrl(dir + "/p.src");
  ASSERT_EQ(p.motions.size(), 9u);
  const int blocks[9] = {0, 1, 1, 1, 1, 0, 2, 2, 3};
  for (size_t k = 0; k < 9; ++k) {
    EXPECT_EQ(p.motions[k].spline_block, blocks[k]) << k;
    EXPECT_EQ(p.motions[k].ptp_spline_block, blocks[k] == 2) << k;
  }
  const std::string xml = writeXmlProgram(p);
  EXPECT_NE(xml.find("<sptp spline_block=\"2\" spline_block_type=\"PTP_SPLINE\">"), std::string::npos) << xml;
  const std::string path = dir + "/p.xml";
  test::writeText(path, xml);
  Program back = readXmlProgram(path);
  ASSERT_EQ(back.motions.size(), 9u);
  for (size_t k = 0; k < 9; ++k) EXPECT_EQ(back.motions[k].spline_block, blocks[k]) << k;
  const std::string src = test::lf(writeKrl(back).src);
  EXPECT_NE(src.find("\n" + body + "END\n"), std::string::npos) << src;
  // statements keep their side of SPLINE / ENDSPLINE (TIME_BLOCK inside, $OUT and an IF
  // around a LIN after it), and a segment's own speed stays its own (WITH), not a new block
  const std::string body2 = "PTP XP1\nSPLINE\n  TIME_BLOCK START\nSLIN XP2\nSLIN XP3\n  TIME_BLOCK END = 2.0\nENDSPLINE\n$OUT[1] = TRUE\n"
                            "IF $IN[1] THEN\nLIN XP1\nENDIF\nSPLINE\nSLIN XP2\nSLIN XP3 WITH $VEL.CP=0.2000\nENDSPLINE\n";
  test::writeText(dir + "/q.src", "DEF q( )\n" + body2 + "END\n");
  test::writeText(dir + "/q.dat", "DEFDAT q\n" + dat.substr(dat.find('\n') + 1) + "ENDDAT\n");
  test::writeText(dir + "/q.xml", writeXmlProgram(readKrl(dir + "/q.src")));
  const std::string q_back = test::lf(writeKrl(readXmlProgram(dir + "/q.xml")).src);
  EXPECT_NE(q_back.find("\n" + body2 + "END\n"), std::string::npos) << q_back;
  // an XML's block number on a motion that cannot be a segment is an error naming it
  test::writeText(path, "<program name=\"p\" version=\"1\"><motions><lin spline_block=\"1\"><pose x_mm=\"1\" y_mm=\"2\" z_mm=\"3\" "
                        "a_deg=\"0\" b_deg=\"0\" c_deg=\"0\"/></lin></motions></program>\n");
  try {
    readXmlProgram(path);
    FAIL();
  } catch (const calib::InputError& e) {
    EXPECT_EQ(e.line(), 1);
    EXPECT_NE(e.message().find("attribute 'spline_block': expected a positive block number on sptp, slin, scirc or spl, found '1' on lin"),
              std::string::npos)
        << e.message();
  }
}

// A point array of the data list (DECL E6POS XPA[3], then XPA[1]={X ..}) : each element given
// a value is a point of its own, as the reader takes TOOL_DATA[n]; an index the program
// computes (XPA[I]) or an element without a value stays a run-time target, and an array the
// program assigns in a loop is one at every element.
TEST(Krl, ThePointsOfAnArrayInTheDataListAreNamedPoints) {
  const std::string dir = test::tempDir("krl_array");
  const std::string dat =
      "DEFDAT p\nDECL E6POS XPA[3]\nXPA[1]={X 135.598,Y -264.075,Z 477.826,A 115.342,B -63.826,C -129.097,S 2,T 2,E1 0.0}\n"
      "xpa[2]={X 93.096,Y -259.890,Z 509.745,A 136.186,B -59.107,C -177.850,S 2,T 10}\nENDDAT\n";
  test::writeText(dir + "/p.dat", dat);
  test::writeText(dir + "/p.src", "DEF p( )\nDECL INT I\n$TOOL={X 0,Y 0,Z 200,A 0,B 90,C 0}\n$BASE=$NULLFRAME\n"
                                  "LIN XPA[1] C_DIS\nlin xpa[ 2 ]\nLIN XPA[I]\nLIN XPA[3]\nEND\n");
  const Program p = readKrl(dir + "/p.src");
  ASSERT_EQ(p.motions.size(), 4u);
  const Target& a = p.motions[0].target;
  EXPECT_EQ(p.motions[0].target_problem, "");
  EXPECT_EQ(a.name, "XPA[1]");
  EXPECT_EQ(a.type, "E6POS");
  EXPECT_EQ(a.pose[0], 135.598);
  EXPECT_EQ(a.pose[5], -129.097);
  EXPECT_EQ(a.turn, 2);
  EXPECT_EQ(a.where.file, dir + "/p.dat");
  EXPECT_EQ(a.where.line, 3);
  EXPECT_EQ(a.where.column, 8);
  EXPECT_EQ(p.motions[1].target_problem, "");
  EXPECT_EQ(p.motions[1].target.name, "XPA[2]");
  EXPECT_EQ(p.motions[1].target.pose[1], -259.890);
  EXPECT_EQ(p.motions[1].target.turn, 10);
  EXPECT_EQ(p.motions[2].target_problem, "the target 'XPA[I]' is an element of the array XPA whose index is computed at run time");
  EXPECT_EQ(p.motions[3].target_problem, "XPA[3] is not given a value (the array XPA is declared at " + dir + "/p.dat:2:12)");
  // written back unchanged, the array's declaration carried for a conversion
  EXPECT_EQ(writeKrl(p).dat, dat);
  bool declaration_carried = false;
  for (const PassThrough& s : p.passthrough) declaration_carried = declaration_carried || s.text == "DECL E6POS XPA[3]";
  EXPECT_TRUE(declaration_carried);

  // converted: the element goes into XML as its value (XML names no array element), the
  // array's lines stay in the data list; KRL -> XML -> KRL -> XML gives the same XML
  test::writeText(dir + "/p.src", "DEF p( )\nBAS (#INITMOV,0 )\n$TOOL={X 0,Y 0,Z 200,A 0,B 90,C 0}\n$BASE=$NULLFRAME\nLIN XPA[1]\nEND\n");
  const std::string xml = writeXmlProgram(readKrl(dir + "/p.src"));
  EXPECT_NE(xml.find("<pose x_mm=\"135.5980\""), std::string::npos) << xml;
  const std::string back = test::tempDir("krl_array_back");
  test::writeText(back + "/p.xml", xml);
  Program fresh = readXmlProgram(back + "/p.xml");
  const KrlText text = test::lf(writeKrl(fresh));
  EXPECT_NE(text.dat.find("\nDECL E6POS XPA[3]\nXPA[1]={X 135.598,"), std::string::npos) << text.dat;
  test::writeText(back + "/p.src", text.src);
  test::writeText(back + "/p.dat", text.dat);
  EXPECT_EQ(writeXmlProgram(readKrl(back + "/p.src")), xml);

  // XPA[2] = {..} in the main program's straight line is the element's value from there on
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 90,C 0}\n$BASE=$NULLFRAME\n"
                                  "LIN XPA[2]\nXPA[2]={X 1,Y 2,Z 3,A 0,B 0,C 0}\nLIN XPA[2]\nEND\n");
  const Program q = readKrl(dir + "/p.src");
  ASSERT_EQ(q.motions.size(), 2u);
  EXPECT_EQ(q.motions[0].target_problem, "");
  EXPECT_EQ(q.motions[0].target.pose[0], 93.096);
  EXPECT_EQ(q.motions[1].target_problem, "");
  EXPECT_EQ(q.motions[1].target.pose[0], 1.0);
  EXPECT_EQ(q.motions[1].target.where.file, dir + "/p.src");
  EXPECT_EQ(q.motions[1].target.where.line, 5);
  // assigned in a loop (any index): every element is a run-time value
  test::writeText(dir + "/p.src", "DEF p( )\nDECL INT I\n$TOOL={X 0,Y 0,Z 200,A 0,B 90,C 0}\n$BASE=$NULLFRAME\n"
                                  "LIN XPA[1]\nFOR I=1 TO 2\n  XPA[I].Z = 5\nENDFOR\nEND\n");
  const Program r = readKrl(dir + "/p.src");
  ASSERT_EQ(r.motions.size(), 1u);
  EXPECT_EQ(r.motions[0].target_problem, "XPA[1]: XPA is assigned at " + dir +
                                             "/p.src:7:3 inside a branch or a loop: its value at a motion depends on the way the program runs");
}

TEST(Krl, OlderInlineFormsWithBinaryStatusAndTurn) {
  // KRC2 inline forms: BAS(#PTP_DAT), BAS(#FRAMES), BAS(#VEL_PTP,v); the .dat is PALETTE.DAT
  const Program p = read("krc2/palette.src", true);
  EXPECT_EQ(p.krl->dat_path, golden("krc2/PALETTE.DAT"));
  ASSERT_EQ(p.motions.size(), 4u);
  const Motion& p1 = p.motions[1];
  EXPECT_EQ(*p1.target.status, 2);  // S 'B010'
  EXPECT_EQ(*p1.target.turn, 10);   // T 'B1010'
  EXPECT_EQ(p1.tool.index, 2);
  EXPECT_EQ(p1.tool.value->z_mm, 245.0);
  EXPECT_EQ(p1.base.index, 2);
  EXPECT_EQ(*p1.vel_percent, 80.0);
  EXPECT_EQ(*p1.approximation_value, 50.0);  // PPDAT1 APO_DIST
  EXPECT_EQ(*p.motions[2].vel_m_s, 0.3);
  EXPECT_EQ(p.motions[3].tool.source, FrameSetting::Source::kNull);  // FHOME: TOOL_NO 0
  // a corrected value keeps the literal style of S and T
  Program q = p;
  q.motions[2].target.setPose(calib::XyzAbc{512.6, 210, 120, 12.5, 5, 172});
  q.motions[2].target.modified = true;
  const KrlText t = writeKrl(q);
  EXPECT_NE(t.dat.find("DECL E6POS XP2={X 512.6000,Y 210.0,Z 120.0,A 12.5,B 5.0,C 172.0,S 'B010',T 'B1010',E1 0.0"),
            std::string::npos)
      << t.dat;
}

TEST(Krl, ExpertKrlWithMixedCaseAndPartialTargets) {
  const Program p = read("robodk/Pick_Place.src");
  EXPECT_EQ(p.name, "Pick_Place");
  ASSERT_EQ(p.motions.size(), 9u);
  EXPECT_EQ(p.motions[0].target.kind, Target::Kind::kAxis);
  EXPECT_EQ(*p.motions[0].target.axes[2], 90.0);
  EXPECT_EQ(p.motions[0].approximation[0], Approximation::kCPtp);
  EXPECT_EQ(*p.motions[0].approximation_value, 5.0);  // $apo.cptp = 5
  EXPECT_EQ(p.motions[1].type, MotionType::kLin);     // "Lin ... c_dis"
  EXPECT_EQ(p.motions[1].approximation[0], Approximation::kCDis);
  EXPECT_EQ(*p.motions[1].approximation_value, 1.0);
  EXPECT_EQ(*p.motions[1].vel_m_s, 0.5);
  EXPECT_EQ(p.motions[1].tool.source, FrameSetting::Source::kInline);
  EXPECT_EQ(p.motions[1].tool.value->z_mm, 200.0);
  EXPECT_EQ(p.motions[4].type, MotionType::kPtp);  // "ptp {X ..,S 2,T 10}"
  EXPECT_EQ(*p.motions[4].target.status, 2);
  EXPECT_EQ(*p.motions[4].target.turn, 11);
  const Target& partial = p.motions[6].target;  // LIN {Z 650.000}
  EXPECT_FALSE(partial.completePose());
  EXPECT_FALSE(partial.pose[0]);
  EXPECT_EQ(*partial.pose[2], 650.0);
  EXPECT_EQ(p.motions[7].type, MotionType::kCirc);  // "circ {..},{..} C_DIS"
  EXPECT_EQ(*p.motions[7].aux->pose[1], 400.0);
  EXPECT_EQ(*p.motions[7].target.pose[0], 1300.0);
}

TEST(Krl, OnlyCorrectedValuesChange) {
  Program p = read("kss8_inline/weld_seam.src", true);
  const std::string dat = test::readText(golden("kss8_inline/weld_seam.dat"));
  Target& t = p.motions[2].target;  // XP2
  t.setPose(calib::XyzAbc{1211.0, -180.12344, 612.75, 178.2, 29.9, -179.30001});
  t.modified = true;
  const KrlText out = writeKrl(p);
  EXPECT_EQ(out.src, p.krl->src_text);
  const std::string before =
      "DECL E6POS XP2={X 1210.5,Y -180.25,Z 612.75,A 178.100006,B 29.8999996,C -179.300003,S 2,T 11,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}";
  const std::string after =
      // Z and B are the same at the precision written (612.75, 29.9 = 29.8999996 at 1e-5 deg): their text stays
      "DECL E6POS XP2={X 1211.0000,Y -180.1234,Z 612.75,A 178.20000,B 29.8999996,C -179.30001,S 2,T 11,E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}";
  std::string expected = dat;
  ASSERT_NE(expected.find(before), std::string::npos);
  expected.replace(expected.find(before), before.size(), after);
  EXPECT_EQ(out.dat, expected);
}

TEST(Krl, AChangedTurnIsWrittenTheStatusKept) {
  Program p = read("kss8_inline/weld_seam.src", true);
  Target& t = p.motions[3].target;  // XP3, S 2, T 11
  t.turn = 10;
  t.modified = true;
  const KrlText out = writeKrl(p);
  // the pose is unchanged: its numbers keep their text
  EXPECT_NE(out.dat.find("DECL E6POS XP3={X 1210.5,Y 20.25,Z 612.75,A 178.100006,B 29.8999996,C -179.300003,S 2,T 10,E1 0.0,"),
            std::string::npos)
      << out.dat;
}

TEST(Krl, InsertedPointsCopyTheirMotionStatement) {
  Program p = read("spline/glue_bead.src", true);
  // an auxiliary point before SLIN XP2 and before the SCIRC
  Motion ins = p.motions[2];
  ins.inserted = true;
  Target t;
  t.setPose(calib::XyzAbc{412.5, -388.25, 90.0, -12.5, 2.5, 177.75});
  t.status = 2;
  t.turn = 2;
  ins.target = t;
  Motion circ = p.motions[3];
  circ.inserted = true;
  circ.aux = t;
  circ.target = t;
  std::vector<Motion> m = p.motions;
  m.insert(m.begin() + 3, circ);
  m.insert(m.begin() + 2, ins);
  p.motions = m;
  const KrlText out = writeKrl(p);
  const std::string src = p.krl->src_text;
  const std::string slin = "  SLIN XP2 WITH $VEL = SVEL_CP(0.1, , LCPDAT1)";
  const std::string agg = "{X 412.5000,Y -388.2500,Z 90.0000,A -12.50000,B 2.50000,C 177.75000,S 2,T 2}";
  std::string expected = src;
  const size_t at = expected.find(slin);
  ASSERT_NE(at, std::string::npos);
  const size_t eol = expected.find('\n', at);
  std::string line = expected.substr(at, eol + 1 - at);
  line.replace(line.find("XP2"), 3, agg);
  expected.insert(at, line);
  const size_t at2 = expected.find("  SCIRC XP3, XP4");
  ASSERT_NE(at2, std::string::npos);
  std::string line2 = expected.substr(at2, expected.find('\n', at2) + 1 - at2);
  line2.replace(line2.find("XP3, XP4"), 8, agg + ", " + agg);
  expected.insert(at2, line2);
  EXPECT_EQ(out.src, expected);
  EXPECT_EQ(out.dat, p.krl->dat_text);
}

TEST(Krl, APartialAggregateIsCompletedWhenCorrected) {
  Program p = read("robodk/Pick_Place.src");
  Target& t = p.motions[6].target;  // LIN {Z 650.000}
  t.setPose(calib::XyzAbc{1100.01, 300.02, 650.03, -150.0, 8.0, 172.0});
  t.modified = true;
  const KrlText out = writeKrl(p);
  std::string expected = p.krl->src_text;
  const std::string before = "LIN {Z 650.000}";
  expected.replace(expected.find(before), before.size(), "LIN {X 1100.0100,Y 300.0200,Z 650.0300,A -150.00000,B 8.00000,C 172.00000}");
  EXPECT_EQ(out.src, expected);
}

TEST(Krl, TheStartIsUnknownAfterACallABranchOrALoopAndInASubroutine) {
  // the position before a motion is the previous motion's target only when nothing between them
  // can move the robot elsewhere
  const std::string dir = test::tempDir("krl_flow");
  test::writeText(dir + "/p.src",
                  "DEF p( )\nDECL INT I\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\n"
                  "LIN XP1\n"                                          // 0: the program's start
                  "seam()\nLIN XP2\n"                                 // 1: after a call
                  "LIN XP1\n"                                          // 2
                  "IF $IN[1] THEN\n  LIN XP2\nELSE\n  LIN XP1\nENDIF\n"  // 3, 4: the other branch
                  "LIN XP2\n"                                          // 5: after the branches
                  "IF $IN[2] THEN\n  $OUT[2]=TRUE\nENDIF\n"
                  "PULSE($OUT[3],TRUE,0.5)\nSET_CD_PARAMS (0)\nLIN XP1\n"  // 6: no motion in the branch; built-ins and
                                                                        // other modules' functions (inline forms) do not move it
                  "FOR I=1 TO 3\n  LIN XP2\nENDFOR\n"                // 7: a loop's first motion
                  "LIN XP1\n"                                          // 8: after the loop
                  "END\n\nDEF seam( )\nLIN XP2\nEND\n");            // 9: a subroutine's first motion
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  const Program p = readKrl(dir + "/p.src");
  ASSERT_EQ(p.motions.size(), 10u);
  const std::vector<bool> expected = {false, true, false, false, true, true, false, true, true, true};
  for (size_t k = 0; k < expected.size(); ++k) EXPECT_EQ(p.motions[k].start_unknown, expected[k]) << "motion " << k;
}

// INTERRUPT DECL n WHEN .. DO handler( ) declares the handler, it does not call it (KRL: the
// handler runs when the condition fires, wherever the program is): the motion after the
// declaration starts where the one before it ended, as after INTERRUPT ON. A subroutine that
// declares an interrupt with a moving handler does not move the robot by that. (Before: the
// declaration counted as a call of the moving handler, the next LIN's path was not compensated.)
TEST(Krl, AnInterruptDeclarationIsNotACallOfItsHandler) {
  const std::string dir = test::tempDir("krl_interrupt_decl");
  test::writeText(dir + "/p.src",
                  "DEF p( )\r\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\r\n$BASE=$NULLFRAME\r\nLIN XP1\r\n"
                  "INTERRUPT DECL 5 WHEN $IN[7]==FALSE DO recover( )\r\nINTERRUPT ON 5\r\nLIN XP2\r\n"  // 1
                  "GLOBAL INTERRUPT DECL 6 WHEN $IN[8] DO recover( )\r\nLIN XP1\r\n"                // 2
                  "arm( )\r\nLIN XP2\r\n"                                                           // 3: arm() moves nothing
                  "recover( )\r\nLIN XP1\r\n"                                                       // 4: a call
                  "END\r\nDEF recover( )\r\nBRAKE\r\nLIN $POS_RET\r\nRESUME\r\nEND\r\n"
                  "DEF arm( )\r\nINTERRUPT DECL 7 WHEN $IN[9] DO recover( )\r\nINTERRUPT ON 7\r\nEND\r\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\r\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\r\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\r\nENDDAT\r\n");
  const Program p = readKrl(dir + "/p.src");
  ASSERT_EQ(p.motions.size(), 6u);
  const std::vector<bool> expected = {false, false, false, false, true, true};  // (5: recover's own, from anywhere)
  for (size_t k = 0; k < expected.size(); ++k) EXPECT_EQ(p.motions[k].start_unknown, expected[k]) << "motion " << k;
}

TEST(Krl, AFunctionThatMovesTheRobotIsCalledLikeASubroutine) {
  // a DEFFCT of the .src that moves the robot, called in an expression: the motion after the
  // call starts where the function left the robot, and the function's first motion wherever it
  // is called from; a function that does not move the robot changes nothing
  const std::string dir = test::tempDir("krl_deffct");
  test::writeText(dir + "/p.src",
                  "DEF p( )\nDECL REAL R\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\n"
                  "LIN XP1\n"                                          // 0: the program's start
                  "R = AWAY(2.0) * 0.5\nLIN XP2\n"                   // 1: after a call of a function that moves
                  "IF CHECK() > 0 THEN\n  $OUT[1]=TRUE\nENDIF\nLIN XP1\n"  // 2: CHECK does not move the robot
                  "END\n\nDEFFCT REAL AWAY(F:IN)\nREAL F\nLIN XP2\nRETURN F\nENDFCT\n"  // 3: a function's first motion
                  "\nGLOBAL DEFFCT INT CHECK( )\nRETURN 1\nENDFCT\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  const Program p = readKrl(dir + "/p.src");
  ASSERT_EQ(p.motions.size(), 4u);
  const std::vector<bool> expected = {false, true, false, true};
  for (size_t k = 0; k < expected.size(); ++k) EXPECT_EQ(p.motions[k].start_unknown, expected[k]) << "motion " << k;
  // a DEFFCT cut short: the error names ENDFCT and the line of the DEFFCT
  test::writeText(dir + "/p.src", "DEF p( )\nLIN XP1\nEND\n\nDEFFCT REAL AWAY( )\nLIN XP2\nRETURN 1.0\n");
  try {
    readKrl(dir + "/p.src");
    ADD_FAILURE() << "a DEFFCT without ENDFCT was read";
  } catch (const calib::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("expected ENDFCT closing the DEFFCT at line 5, found the end of the file"), std::string::npos)
        << e.what();
  }
}

TEST(Krl, AFrameSetInABranchOrALoopIsNotKnownAfterIt) {
  // $BASE set in one branch: the other branch runs with the base the IF was entered with, and
  // after ENDIF the base is whichever the run took: a run-time value (the motion is kept and
  // named, not corrected and split in the wrong base). A block that sets the frame it was
  // entered with changes nothing (inline forms set $TOOL/$BASE at every motion).
  const std::string dir = test::tempDir("krl_frame_branch");
  test::writeText(dir + "/p.src",
                  "DEF p( )\nDECL INT I\n$TOOL=TOOL_DATA[1]\n$BASE=BASE_DATA[1]\n"
                  "LIN XP1\n"                                                           // 0: base 1
                  "IF $IN[1] THEN\n  $BASE=BASE_DATA[2]\n  LIN XP2\n"                // 1: base 2
                  "ELSE\n  LIN XP1\nENDIF\n"                                          // 2: base 1 (the ELSE)
                  "LIN XP2\n"                                                           // 3: either
                  "$BASE=BASE_DATA[1]\n"
                  "IF $IN[2] THEN\n  $BASE=BASE_DATA[1]\nENDIF\n"
                  "LIN XP1\n"                                                           // 4: base 1 either way
                  "FOR I=1 TO 2\n  $TOOL=TOOL_DATA[2]\n  LIN XP2\nENDFOR\n"          // 5: tool 2
                  "LIN XP1\n"                                                           // 6: tool 1 or 2
                  "$TOOL=TOOL_DATA[1]\nGRIPPER()\nLIN XP2\n"                               // 7: the subroutine's
                  "END\n\nDEF GRIPPER( )\n$TOOL=TOOL_DATA[3]\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  const Program p = readKrl(dir + "/p.src");
  ASSERT_EQ(p.motions.size(), 8u);
  const std::vector<std::string> base = {"BASE_DATA[1]", "BASE_DATA[2]", "BASE_DATA[1]", "$BASE", "BASE_DATA[1]", "BASE_DATA[1]", "BASE_DATA[1]", "BASE_DATA[1]"};
  const std::vector<std::string> tool = {"TOOL_DATA[1]", "TOOL_DATA[1]", "TOOL_DATA[1]", "TOOL_DATA[1]", "TOOL_DATA[1]", "TOOL_DATA[2]", "$TOOL", "$TOOL"};
  for (size_t k = 0; k < base.size(); ++k) {
    EXPECT_EQ(p.motions[k].base.text, base[k]) << k;
    EXPECT_EQ(p.motions[k].tool.text, tool[k]) << k;
  }
  EXPECT_TRUE(p.motions[3].base.run_time);
  EXPECT_EQ(p.motions[3].base.note, "$BASE is set inside the IF at line 6: after it, its value depends on the way the program ran");
  EXPECT_TRUE(p.motions[6].tool.run_time);
  EXPECT_EQ(p.motions[6].tool.note, "$TOOL is set inside the FOR at line 18: after it, its value depends on the way the program ran");
  for (size_t k : {0u, 1u, 2u, 4u, 5u}) EXPECT_FALSE(p.motions[k].base.run_time || p.motions[k].tool.run_time) << k;
  EXPECT_TRUE(p.motions[7].tool.run_time);
  EXPECT_EQ(p.motions[7].tool.note, "GRIPPER (called here) sets $TOOL: the tool after the call is not followed");
  EXPECT_FALSE(p.motions[7].base.run_time);  // GRIPPER leaves $BASE alone
}

TEST(Krl, ALoopsNextPassAndASubroutineSeeTheFramesAndPointsOfTheRun) {
  // a motion before a frame change in its loop runs with the new frame on the next pass; a
  // subroutine runs with its caller's frames, and a point the program assigns has there the
  // value of the place it is called from
  const std::string dir = test::tempDir("krl_loop_sub");
  test::writeText(dir + "/p.src",
                  "DEF p( )\nDECL INT I\n$TOOL=TOOL_DATA[1]\n$BASE=BASE_DATA[1]\n"
                  "FOR I=1 TO 3\n  PTP XP1\n  $TOOL=TOOL_DATA[2]\n  LIN XP2\nENDFOR\n"   // 0: tool 1, then 2; 1: tool 2
                  "XP2={X 1000,Y 300,Z 800,A 0,B 90,C 0}\nSUB()\n"
                  "END\n\nDEF SUB( )\nLIN XP2\n"                                             // 2: the caller's tool; XP2 of the call
                  "$TOOL=TOOL_DATA[1]\n$BASE=BASE_DATA[1]\nLIN XP1\nEND\n");              // 3: its own frames, XP1 never assigned
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  const Program p = readKrl(dir + "/p.src");
  ASSERT_EQ(p.motions.size(), 4u);
  EXPECT_TRUE(p.motions[0].tool.run_time);
  EXPECT_EQ(p.motions[0].tool.note, "$TOOL is set later in the FOR at line 5: the next pass runs this motion with the new value");
  EXPECT_EQ(p.motions[1].tool.text, "TOOL_DATA[2]");
  EXPECT_TRUE(p.motions[2].tool.run_time);
  EXPECT_EQ(p.motions[2].tool.note, "a subroutine runs with the caller's $TOOL until it sets its own");
  EXPECT_EQ(p.motions[2].target_problem,
            "XP2 is assigned at " + dir + "/p.src:10:1: in a subroutine its value depends on where it is called");
  EXPECT_FALSE(p.motions[3].tool.run_time || p.motions[3].base.run_time);
  EXPECT_EQ(p.motions[3].target_problem, "");
}

TEST(Krl, NestedBlocksPassTheirMotionsOutAndBlocksWithoutMotionsChangeNothing) {
  const std::string dir = test::tempDir("krl_nested");
  test::writeText(dir + "/p.src",
                  "DEF p( )\nDECL INT I\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\n"
                  "LIN XP1\n"                                                      // 0
                  "IF $IN[1] THEN\n  LIN XP2\n  IF $IN[2] THEN\n    $OUT[1]=TRUE\n  ENDIF\nENDIF\n"  // 1
                  "LIN XP1\n"                             // 2: the outer branch moved (the nested IF did not)
                  "FOR I=1 TO 8\n  $OUT[I]=FALSE\nENDFOR\n"
                  "LIN XP2\n"                             // 3: a loop without motions
                  "GRIP()\nLIN XP1\n"                    // 4: a subroutine that does not move the robot
                  "PICK()\nLIN XP2\n"                    // 5: one that moves it through another
                  "END\n\nDEF GRIP( )\n$OUT[5]=TRUE\nEND\n\nDEF PICK( )\nAPPROACH()\nEND\n\nDEF APPROACH( )\nPTP XP1\nEND\n");  // 6
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  const Program p = readKrl(dir + "/p.src");
  ASSERT_EQ(p.motions.size(), 7u);
  const std::vector<bool> expected = {false, false, true, false, false, true, true};
  for (size_t k = 0; k < expected.size(); ++k) EXPECT_EQ(p.motions[k].start_unknown, expected[k]) << "motion " << k;
}

TEST(Krl, AFileCutShortIsAnErrorNotAShorterProgram) {
  const std::string dat = "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nENDDAT\n";
  EXPECT_NE(std::string(readError("DEF p( )\nPTP XP1\nLIN XP1\n", dat).what())
                .find("expected END closing the DEF at line 1, found the end of the file"),
            std::string::npos);
  EXPECT_NE(std::string(readError("DEF p( )\nLIN XP1\nEND\n", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\n").what())
                .find("p.dat:2:"),
            std::string::npos);
  EXPECT_NE(std::string(readError("DEF p( )\nLIN XP1\nEND\n", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\n").what())
                .find("expected ENDDAT closing the data list, found the end of the file"),
            std::string::npos);
  // an empty data file (written, not missing)
  const std::string dir = test::tempDir("krl_empty_dat");
  test::writeText(dir + "/p.src", "DEF p( )\nLIN XP1\nEND\n");
  test::writeText(dir + "/p.dat", "");
  try {
    readKrl(dir + "/p.src");
    ADD_FAILURE() << "an empty .dat was read";
  } catch (const calib::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("p.dat:1:1: expected a data list (DEFDAT name ... ENDDAT), found the end of the file"),
              std::string::npos)
        << e.what();
  }
  // an editor's byte order mark before DEF / DEFDAT and a DOS end-of-file mark after END / ENDDAT
  // are not text: read
  const std::string marks = test::tempDir("krl_marks");
  test::writeText(marks + "/p.src", "\xEF\xBB\xBF" "DEF p( )\nLIN XP1\nEND\n\x1A");
  test::writeText(marks + "/p.dat", "\xEF\xBB\xBF" "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nENDDAT\n\x1A");
  EXPECT_EQ(readKrl(marks + "/p.src").motions.size(), 1u);
  // an absurd value is bad input, as in RAPID and URScript
  EXPECT_NE(std::string(readError("DEF p( )\nLIN XP1\nEND\n", "DEFDAT p\nDECL E6POS XP1={X 1E30,Y 0,Z 800,A 0,B 90,C 0}\nENDDAT\n").what())
                .find("expected X within +-100000 (mm or deg), found '1E30'"),
            std::string::npos);
}

TEST(Krl, OnePointWithTwoDifferentCorrectionsIsAnError) {
  const std::string dir = test::tempDir("krl_twice");
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nLIN XP1\nLIN XP2\nLIN XP1\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  Program p = readKrl(dir + "/p.src");
  ASSERT_EQ(p.motions.size(), 3u);
  EXPECT_EQ(p.motions[0].target.value_id, p.motions[2].target.value_id);
  p.motions[0].target.setPose(calib::XyzAbc{1000.1, 0, 800, 0, 90, 0});
  p.motions[0].target.modified = true;
  p.motions[2].target.setPose(calib::XyzAbc{1000.2, 0, 800, 0, 90, 0});
  p.motions[2].target.modified = true;
  try {
    writeKrl(p);
    FAIL() << "expected an ArgumentError";
  } catch (const calib::ArgumentError& e) {
    EXPECT_NE(std::string(e.what()).find("XP1 needs a different correction here than at " + dir + "/p.src:4:1"), std::string::npos) << e.what();
  }
  // the same correction twice is fine
  p.motions[2].target.setPose(calib::XyzAbc{1000.1, 0, 800, 0, 90, 0});
  const KrlText out = writeKrl(p);
  EXPECT_NE(out.dat.find("DECL E6POS XP1={X 1000.1000,Y 0,Z 800,A 0,B 90,C 0}"), std::string::npos) << out.dat;
}

TEST(Krl, FrameTablesFromTheConfig) {
  const FrameTables t = readKrlFrameTables(config());
  ASSERT_GE(t.tool.size(), 4u);
  ASSERT_TRUE(t.tool[1]);
  EXPECT_EQ(t.tool[1]->z_mm, 313.237);
  EXPECT_EQ(t.tool[2]->x_mm, -12.5);
  EXPECT_EQ(t.tool[2]->b_deg, -30.0);
  ASSERT_GE(t.base.size(), 4u);
  EXPECT_EQ(t.base[3]->a_deg, -90.0);
  EXPECT_FALSE(t.tool.size() > 4 && t.tool[4]);
}

TEST(Krl, FramesAndPointsChangedInTheProgram) {
  const std::string dir = test::tempDir("krl_frames");
  test::writeText(dir + "/p.src",
                  "DEF p( )\n"
                  "TOOL_DATA[4]={X 1,Y 2,Z 3,A 0,B 0,C 0}\n"
                  "BAS(#TOOL,4)\n"
                  "$BASE={X 10,Y 20,Z 30,A 0,B 0,C 0}\n"
                  "$BASE={Z 40}\n"
                  "LIN XP1\n"
                  "XP1={X 5,Y 6,Z 7,A 0,B 0,C 0}\n"
                  "LIN XP1\n"
                  "XP1.X=8\n"
                  "PTP XP1\n"
                  "$TOOL=$TOOL:{X 1}\n"
                  "LIN {X 1,Y 2,Z 3,A 0,B 0,C 0}\n"
                  "END\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  const Program p = readKrl(dir + "/p.src");
  ASSERT_EQ(p.motions.size(), 4u);
  EXPECT_EQ(p.motions[0].tool.index, 4);
  EXPECT_EQ(p.motions[0].tool.value->z_mm, 3.0);
  EXPECT_EQ(p.motions[0].base.value->x_mm, 10.0);  // partial frame: the other components kept
  EXPECT_EQ(p.motions[0].base.value->z_mm, 40.0);
  EXPECT_EQ(*p.motions[0].target.pose[0], 1000.0);
  EXPECT_EQ(p.motions[1].target.where.file, dir + "/p.src");  // the new value, in the .src
  EXPECT_EQ(p.motions[1].target.where.line, 7);
  EXPECT_EQ(*p.motions[1].target.pose[0], 5.0);
  EXPECT_EQ(p.motions[0].target_problem, "");  // XP1={...} replaces the declared value whole
  // XP1.X=8 keeps the other components of the value motion 1 goes to: corrected, its correction
  // would carry into the PTP's target (half corrected); kept and named
  EXPECT_EQ(p.motions[1].target_problem,
            "XP1 is changed from its own value at " + dir + "/p.src:9:1: a correction of it here would carry into its new value");
  EXPECT_NE(p.motions[2].target_problem.find("XP1 is changed at run time (" + dir + "/p.src:9:1)"), std::string::npos)
      << p.motions[2].target_problem;
  EXPECT_EQ(p.motions[3].tool.source, FrameSetting::Source::kUnknown);
  EXPECT_EQ(p.motions[3].tool.text, "$TOOL:{X 1}");
}

TEST(Krl, FramesLinkedWithTheGeometricOperatorAreEvaluated) {
  // KRL's ':' links frames (A:B is T_A * T_B): $BASE=$BASE:{..} shifts the base in its own
  // axes, and a FRAME of the data list or one the program assigns is a frame like TOOL_DATA[n].
  // Expected values by hand: BASE_DATA[1] is X 100 turned A 90 about Z, so its own X 10 is the
  // world's Y 10.
  const std::string dir = test::tempDir("krl_frame_linkage");
  test::writeText(dir + "/p.src",
                  "DEF p( )\nDECL INT I\nDECL FRAME FB\n"
                  "BASE_DATA[1]={X 100,Y 0,Z 0,A 90,B 0,C 0}\nTOOL_DATA[1]={X 0,Y 0,Z 200,A 0,B 0,C 0}\n"
                  "$TOOL=TOOL_DATA[1]\n$BASE=BASE_DATA[1]:{X 10,Y 0,Z 0,A 0,B 0,C 0}\n"
                  "LIN XP1\n"                                                                  // 0
                  "$BASE=$BASE:{X 0,Y 0,Z 5,A 0,B 0,C 0}:{X 0,Y 0,Z 0,A 0,B 0,C 30}\n"
                  "$TOOL=$TOOL:{FRAME: X 0,Y 0,Z 50,A 0,B 0,C 0}\n"
                  "LIN XP1\n"                                                                  // 1
                  "FB={X 1,Y 2,Z 3,A 0,B 0,C 0}\n$BASE=FB\nLIN XP1\n"                      // 2
                  "$BASE=MYBASE:FB\nLIN XP1\n"                                                // 3
                  "$BASE=$BASE:{X 1}\nLIN XP1\n"                                              // 4: partial operand
                  "$BASE=$NULLFRAME\nFOR I=1 TO 2\n  $BASE=$BASE:{X 10,Y 0,Z 0,A 0,B 0,C 0}\n  LIN XP1\nENDFOR\n"  // 5
                  "END\n");
  test::writeText(dir + "/p.dat",
                  "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL FRAME MYBASE={X 0,Y 0,Z 0,A -90,B 0,C 0}\nENDDAT\n");
  const Program p = readKrl(dir + "/p.src");
  ASSERT_EQ(p.motions.size(), 6u);
  auto expectFrame = [](const FrameSetting& s, const calib::XyzAbc& v, const char* what) {
    ASSERT_TRUE(s.value) << what << ": " << s.text << " " << s.note;
    EXPECT_EQ(s.source, FrameSetting::Source::kInline) << what;
    const double got[6] = {s.value->x_mm, s.value->y_mm, s.value->z_mm, s.value->a_deg, s.value->b_deg, s.value->c_deg};
    const double want[6] = {v.x_mm, v.y_mm, v.z_mm, v.a_deg, v.b_deg, v.c_deg};
    for (int k = 0; k < 6; ++k) EXPECT_NEAR(got[k], want[k], 1e-9) << what << " component " << k;  // mm, deg
  };
  expectFrame(p.motions[0].base, {100, 10, 0, 90, 0, 0}, "BASE_DATA[1]:{X 10}");
  EXPECT_EQ(p.motions[0].base.text, "BASE_DATA[1]:{X 10,Y 0,Z 0,A 0,B 0,C 0}");
  // Z 5 along the base's Z, then 30 deg about its X (KUKA C)
  expectFrame(p.motions[1].base, {100, 10, 5, 90, 0, 30}, "$BASE:{Z 5}:{C 30}");
  expectFrame(p.motions[1].tool, {0, 0, 250, 0, 0, 0}, "$TOOL:{FRAME: Z 50}");
  expectFrame(p.motions[2].base, {1, 2, 3, 0, 0, 0}, "FB");
  // MYBASE turns -90 deg about Z: FB's X 1, Y 2 become X 2, Y -1
  expectFrame(p.motions[3].base, {2, -1, 3, -90, 0, 0}, "MYBASE:FB");
  EXPECT_EQ(p.motions[4].base.source, FrameSetting::Source::kUnknown);
  EXPECT_FALSE(p.motions[4].base.run_time);
  EXPECT_NE(p.motions[4].base.note.find("leaves out components of the frame"), std::string::npos) << p.motions[4].base.note;
  // in a loop each pass links the base once more: a run-time value, the motion kept as written
  EXPECT_TRUE(p.motions[5].base.run_time);
  EXPECT_EQ(p.motions[5].base.note, "it is composed from $BASE inside the FOR at line 20: each pass may compose another value");
}

// A frame table's entry chosen by a variable (a routine's parameter, a counter) is the run's
// value: the motion is kept as written and named, not refused with the whole program.
TEST(Krl, AFrameNumberComputedAtRunTimeIsARunTimeValue) {
  const std::string dir = test::tempDir("krl_frame_index");
  test::writeText(dir + "/p.src",
                  "DEF p( )\nDECL INT I\nI=2\n$TOOL=TOOL_DATA[1]\n$BASE=BASE_DATA[I]\nLIN XP1\n"  // 0
                  "BAS(#BASE,I)\nLIN XP1\n"                                                      // 1
                  "$BASE=BASE_DATA[I+1]:{X 0,Y 0,Z 5,A 0,B 0,C 0}\nLIN XP1\n"                    // 2
                  "$BASE=BASE_DATA[2]\nLIN XP1\n"                                                  // 3
                  "$BASE=BASE_DATA[2]:{X OFFS,Y 0,Z 0,A 0,B 0,C 0}\nLIN XP1\n"                    // 4: a variable
                  "$BASE={X -DX,Y 0,Z 0,A 0,B 0,C 0}\nLIN XP1\nEND\n");                           // 5: -variable
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  const Program p = readKrl(dir + "/p.src");
  ASSERT_EQ(p.motions.size(), 6u);
  for (size_t k : {0u, 1u, 2u, 4u, 5u}) {
    EXPECT_TRUE(p.motions[k].base.run_time) << k;
    EXPECT_FALSE(p.motions[k].base.known()) << k;
  }
  EXPECT_EQ(p.motions[0].base.note, "the index of BASE_DATA[I] is computed at run time");
  EXPECT_EQ(p.motions[1].base.note, "the frame's number is computed at run time");
  EXPECT_EQ(p.motions[2].base.note, "the index of BASE_DATA[I+1] is computed at run time");
  EXPECT_FALSE(p.motions[3].base.run_time);
  EXPECT_EQ(p.motions[3].base.text, "BASE_DATA[2]");
  EXPECT_EQ(p.motions[4].base.note, "the aggregate {X OFFS,Y 0,Z 0,A 0,B 0,C 0} holds values computed at run time ('OFFS')");
  EXPECT_NE(p.motions[5].base.note.find("the aggregate {X -DX,Y 0,Z 0,A 0,B 0,C 0} holds values accura does not evaluate"),
            std::string::npos)
      << p.motions[5].base.note;
}

TEST(Krl, APointAssignedInALoopOrASubroutineIsNotTakenFromTheText) {
  // the text before a motion is not the run before it: a point assigned in a loop (the next
  // pass sees the new value), a branch, or a subroutine (called before the motion) is a run-time
  // value at every motion that uses it
  const std::string dir = test::tempDir("krl_point_flow");
  test::writeText(dir + "/p.src",
                  "DEF p( )\nDECL INT I\n$TOOL=$NULLFRAME\n$BASE=$NULLFRAME\n"
                  "FOR I=1 TO 3\n  LIN XP1\n  XP1={X 1000,Y 0,Z 900,A 0,B 90,C 0}\nENDFOR\n"  // 0
                  "SHIFT()\nLIN XP2\n"                                                          // 1
                  "LIN XP3\n"                                                                     // 2: never assigned
                  "END\n\nDEF SHIFT( )\nXP2={X 1100,Y 0,Z 800,A 0,B 90,C 0}\nEND\n");
  test::writeText(dir + "/p.dat",
                  "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\n"
                  "DECL E6POS XP3={X 1000,Y 200,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  const Program p = readKrl(dir + "/p.src");
  ASSERT_EQ(p.motions.size(), 3u);
  EXPECT_EQ(p.motions[0].target_problem,
            "XP1 is assigned at " + dir + "/p.src:7:3 inside a branch or a loop: its value at a motion depends on the way the program runs");
  EXPECT_EQ(p.motions[1].target_problem,
            "XP2 is assigned at " + dir + "/p.src:15:1 inside a subroutine or a function: its value at a motion depends on the way the program runs");
  EXPECT_EQ(p.motions[2].target_problem, "");
}

TEST(Krl, MalformedTargetsAreErrorsWithTheirPlace) {
  struct Case {
    std::string src, dat;
    int line, column;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"DEF p( )\nLIN {X 10, Q 5}\nEND\n", "", 2, 12, "expected a component of a Cartesian target (X, Y, Z, A, B, C, S, T, E1..E6), found 'Q'"},
      {"DEF p( )\n  lin {X 10,Y 2,x 3}\nEND\n", "", 2, 17, "expected each component once in this aggregate, found x a second time"},
      {"DEF p( )\nLIN {X abc}\nEND\n", "", 2, 8, "expected a number for X, found 'abc'"},
      {"DEF p( )\nLIN {X 1,Y 2\nEND\n", "", 2, 13, "expected ',' or '}' after the value of Y, found the end of the statement"},
      {"DEF p( )\nLIN\nEND\n", "", 2, 4, "expected a target after LIN, found the end of the statement"},
      {"DEF p( )\nLIN {A1 0,A2 -90,A3 90,A4 0,A5 0,A6 0}\nEND\n", "", 2, 5, "expected a Cartesian target for LIN (E6POS, POS, FRAME), found an axis target"},
      {"DEF p( )\nCIRC XP1 XP2\nEND\n", "DEFDAT p\nDECL E6POS XP1={X 1}\nENDDAT\n", 2, 10, "expected ',' between the auxiliary point and the end point of CIRC, found 'XP2'"},
      {"DEF p( )\nLIN XP1\nEND\n", "DEFDAT p\nDECL E6POS XP1={X 1,Y 2,Z 3,A 0,B 0,S 2,C 9,E7 0}\nENDDAT\n", 2, 45,
       "expected a component of E6POS (X, Y, Z, A, B, C, S, T, E1..E6), found 'E7'"},
      {"DEF p( )\nEND\n", "DEFDAT p\nDECL POS XP1={X 1,Y 2,Z 3,A 0,B 0,C 9,S 2,T 1.5}\nENDDAT\n", 2, 45, "expected a non-negative integer for T, found '1.5'"},
      {"DEF p( )\nEND\n", "DEFDAT p\nDECL E6AXIS XP1={X 1}\nENDDAT\n", 2, 18, "expected a component of E6AXIS (A1..A6, E1..E6), found 'X'"},
      {"DEF p( )\nEND\n", "DEFDAT p\nDECL FRAME F1={X 1,S 2}\nENDDAT\n", 2, 20, "expected a component of FRAME (X, Y, Z, A, B, C), found 'S'"},
      {"DEF p( )\n$OUT[1]=TRUE\nMSG=\"open\nEND\n", "", 3, 5, "expected a closing '\"' for this string, found the end of the line"},
      {"DEF p( )\nPTP XP1 C_PTP XYZ\nEND\n", "", 2, 15, "expected an approximation flag (C_PTP, C_DIS, C_VEL, C_ORI, C_SPL) or WITH after the target, found 'XYZ'"},
      {"; no program here\n$OUT[1]=TRUE\n", "", 1, 1, "expected a KRL program (DEF name( ) ... END), found no DEF line"},
      {"DEF p( )\nSPL {X 1,Y 2,Z 3}\nEND\n", "", 2, 1, "expected SPL inside a SPLINE ... ENDSPLINE block, found it outside"},
      {"DEF p( )\nSPLINE\n  SPL {X 1,Y 2,Z 3}\n  LIN {X 1,Y 2,Z 4}\nENDSPLINE\nEND\n", "", 4, 3,
       "expected a spline segment (SPL, SLIN, SCIRC, SPTP) inside the SPLINE block, found LIN"},
      // the control structures as the compiler checks them
      {"DEF p( )\nIF TRUE THEN\n  $OUT[1]=TRUE\nEND\n", "", 4, 1, "expected ENDIF to close the IF at line 2, found END"},
      {"DEF p( )\nWAIT SEC 1\nENDLOOP\nEND\n", "", 3, 1, "expected ENDLOOP to close a LOOP, found no open LOOP"},
      {"DEF p( )\nFOR I=1 TO 3\n  IF I>1 THEN\n  ENDFOR\nENDIF\nEND\n", "", 4, 3, "expected ENDIF to close the IF at line 3, found ENDFOR"},
      {"DEF p( )\nWHILE TRUE\n  ELSE\nENDWHILE\nEND\n", "", 3, 3, "expected ELSE inside an IF, found it inside the WHILE at line 2 (not closed)"},
      {"DEF p( )\nCASE 1\nEND\n", "", 2, 1, "expected CASE inside a SWITCH, found it outside any block"},
      {"DEF p( )\nIF TRUE THEN\nSPLINE\n  SPL {X 1,Y 2,Z 3}\nENDIF\nENDSPLINE\nEND\n", "", 5, 1,
       "expected ENDSPLINE to close the SPLINE at line 3, found ENDIF"},
      {"DEF p( )\nENDSPLINE\nEND\n", "", 2, 1, "expected ENDSPLINE to close a SPLINE or PTP_SPLINE block, found no open block"},
      {"DEF p( )\nPTP_SPLINE\n  SLIN {X 1,Y 2,Z 3}\nENDSPLINE\nEND\n", "", 3, 3, "expected SPTP inside the PTP_SPLINE block, found SLIN"},
  };
  for (const Case& c : cases) {
    const calib::InputError e = readError(c.src, c.dat);
    EXPECT_EQ(e.line(), c.line) << e.what();
    EXPECT_EQ(e.column(), c.column) << e.what();
    EXPECT_EQ(e.message(), c.message) << e.what();
    const bool in_dat = !c.dat.empty() && e.file().size() > 4 && e.file().substr(e.file().size() - 4) == ".dat";
    EXPECT_EQ(in_dat, c.dat.find("E7") != std::string::npos || c.dat.find("T 1.5") != std::string::npos ||
                          c.dat.find("E6AXIS") != std::string::npos || c.dat.find("FRAME F1") != std::string::npos)
        << e.what();
  }
  // a binary file
  const std::string dir = test::tempDir("krl_bin");
  test::writeText(dir + "/b.src", std::string("DEF b( )\nLIN {X 1}\n\0\0", 22));
  try {
    readKrl(dir + "/b.src");
    FAIL();
  } catch (const calib::InputError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.column(), 1);  // the first NUL
    EXPECT_NE(e.message().find("NUL byte"), std::string::npos);
  }
}

TEST(Krl, UnknownStatementsPassThroughAndRunTimeTargetsAreFlagged) {
  const std::string dir = test::tempDir("krl_pass");
  const std::string src =
      "DEF p( )\n"
      "DECL INT I\n"
      "INTERRUPT DECL 3 WHEN $STOPMESS==TRUE DO IR_STOPM ( )\n"
      "TRIGGER WHEN DISTANCE=1 DELAY=0 DO $OUT[3]=TRUE\n"
      "$TOOL=TOOL_DATA[1]\n"
      "LIN XP1:{X 10} C_DIS\n"
      "PTP $AXIS_ACT\n"
      "LIN_REL {Z 10} #TOOL\n"
      "CIRC {X 1,Y 2,Z 3,A 0,B 0,C 0}, {X 2,Y 2,Z 3,A 0,B 0,C 0}, CA 90.5\n"
      "SWITCH I\nCASE 1\n  ANIN ON A=FACTOR*$ANIN[1]\nENDSWITCH\n"
      "END\n";
  test::writeText(dir + "/p.src", src);
  const Program p = readKrl(dir + "/p.src");
  ASSERT_EQ(p.motions.size(), 4u);
  EXPECT_EQ(p.motions[0].target_problem, "the target 'XP1:{X 10}' is computed at run time");
  EXPECT_EQ(p.motions[0].trigger_count, 1);
  EXPECT_EQ(p.motions[1].target_problem, "the target is the system variable $AXIS_ACT");
  EXPECT_TRUE(p.motions[2].relative);
  EXPECT_EQ(p.motions[2].target_problem, "a relative motion (LIN_REL)");
  EXPECT_EQ(*p.motions[3].circ_angle_deg, 90.5);
  EXPECT_EQ(writeKrl(p).src, src);
}

TEST(Krl, ANewProgramFromTheMotionModelReadsBackTheSame) {
  // KRL -> motion model -> new KRL (no text kept) -> motion model: the same motions
  for (const std::string rel : {"kss8_inline/weld_seam.src", "robodk/Pick_Place.src", "spline/glue_bead.src"}) {
    Program p = read(rel, true);
    const std::string xml = writeXmlProgram(p);
    p.krl.reset();
    const KrlText t = writeKrl(p);
    const std::string dir = test::tempDir("krl_new");
    test::writeText(dir + "/" + p.name + ".src", t.src);
    test::writeText(dir + "/" + p.name + ".dat", t.dat);
    KrlReadOptions o;
    o.config_path = config();
    const Program q = readKrl(dir + "/" + p.name + ".src", o);
    EXPECT_EQ(writeXmlProgram(q), xml) << rel << "\n" << t.src;
  }
}

}  // namespace
}  // namespace accura::postproc
