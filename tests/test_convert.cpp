// convert never loses a statement (issue 12): what the motion model does not express (I/O,
// logic, interrupts, comments, declarations of other types) is carried verbatim through the
// XML format (<passthrough>) and written back into KRL byte for byte, in its place between the
// motions; what cannot be carried is refused, naming the line.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"
#include "accura/calib/robot_io.h"
#include "accura/postproc/job.h"
#include "accura/postproc/krl.h"
#include "accura/postproc/program_io.h"
#include "accura/postproc/rapid.h"
#include "accura/postproc/xml_program.h"
#include "test_util.h"

namespace accura::postproc {
namespace {

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  std::string l;
  while (std::getline(in, l)) {
    if (!l.empty() && l.back() == '\r') l.pop_back();
    out.push_back(l);
  }
  return out;
}

size_t indexOf(const std::vector<std::string>& v, const std::string& s, size_t from = 0) {
  for (size_t i = from; i < v.size(); ++i)
    if (v[i] == s) return i;
  return std::string::npos;
}

Program readSeam() {
  KrlReadOptions o;
  o.config_path = test::sourcePath("examples/$config.dat");
  return readKrl(test::sourcePath("examples/seam.src"), o);
}

TEST(Convert, KrlToXmlToKrlKeepsEveryStatementInItsPlace) {
  const Program krl = readSeam();
  const std::string xml = writeXmlProgram(krl);
  const Program from_xml = parseXmlProgram(xml, "seam.xml");
  const KrlText back = test::lf(writeKrl(from_xml));
  const std::vector<std::string> src = lines(back.src);

  // the statements a weld needs, byte for byte (indentation and comments included)
  const char* const kept[] = {"$OUT[17]=TRUE", "IF $IN[12]==TRUE THEN", "  $OUT[20]=TRUE ; clean the torch next cycle", "ENDIF",
                              "$OUT[17]=FALSE", "    GLOBAL INTERRUPT DECL 3 WHEN $STOPMESS==TRUE DO IR_STOPM ( )",
                              "    INTERRUPT ON 3 ", "; approach the fixture"};
  for (const char* k : kept) EXPECT_NE(indexOf(src, k), std::string::npos) << k << "\n" << back.src;
  // in their place: torch on after LIN XP2, before LIN XP3; off after the CIRC, then the IF
  const size_t lin2 = indexOf(src, "LIN XP2"), on = indexOf(src, "$OUT[17]=TRUE"), lin3 = indexOf(src, "LIN XP3");
  const size_t circ = indexOf(src, "CIRC XP4, XP5"), off = indexOf(src, "$OUT[17]=FALSE"), if_ = indexOf(src, "IF $IN[12]==TRUE THEN");
  const size_t lin6 = indexOf(src, "LIN XP6 C_DIS C_DIS");
  ASSERT_NE(lin2, std::string::npos);
  ASSERT_NE(lin6, std::string::npos);
  EXPECT_LT(lin2, on);
  EXPECT_LT(on, lin3);
  EXPECT_LT(circ, off);
  EXPECT_LT(off, if_);
  EXPECT_LT(if_, lin6);
  // the .dat's own declarations
  EXPECT_NE(back.dat.find("\nDECL INT SUCCESS\n"), std::string::npos) << back.dat;
  EXPECT_NE(back.dat.find("\nEXT  BAS (BAS_COMMAND  :IN,REAL  :IN )\n"), std::string::npos) << back.dat;

  // read back: the same pass-through statements, before the same motions, and the same XML
  const std::string dir = test::tempDir("convert_seam");
  test::writeText(dir + "/seam.src", back.src);
  test::writeText(dir + "/seam.dat", back.dat);
  KrlReadOptions o;
  o.config_path = test::sourcePath("examples/$config.dat");
  const Program again = readKrl(dir + "/seam.src", o);
  ASSERT_EQ(again.passthrough.size(), krl.passthrough.size());
  for (size_t i = 0; i < krl.passthrough.size(); ++i) {
    EXPECT_EQ(again.passthrough[i].text, krl.passthrough[i].text) << i;
    EXPECT_EQ(again.passthrough[i].before_motion, krl.passthrough[i].before_motion) << krl.passthrough[i].text;
    EXPECT_EQ(again.passthrough[i].section, krl.passthrough[i].section) << krl.passthrough[i].text;
  }
  EXPECT_EQ(writeXmlProgram(again), xml);
}

TEST(Convert, TheMotionModelsLinesAreNotCarried) {
  const Program krl = readSeam();
  for (const PassThrough& s : krl.passthrough) {
    // what the model writes anew (frames, speeds, data sets, motions, folds) is not carried
    for (const char* model : {"FDAT_ACT", "PDAT_ACT", "LDAT_ACT", "#PTP_PARAMS", "#CP_PARAMS", "PTP ", "LIN ", "CIRC ", ";FOLD", ";ENDFOLD",
                              "DECL E6POS", "DECL FDAT", "DEF ", "&ACCESS"})
      EXPECT_EQ(s.text.find(model), std::string::npos) << s.where.str() << ": " << s.text;
  }
  EXPECT_GE(krl.passthrough.size(), 10u);
}

// Of $VEL and $APO the motion model holds $VEL.CP and $APO.CDIS/CPTP/CVEL/CORI. The orientation
// speeds ($VEL.ORI1, $VEL.ORI2: deg/s, BAS.SRC's DEF_VEL_ORI1/2; a CP motion runs no faster than
// they allow) and an assignment of the whole structure are statements of their own: carried in
// their places. (Before: read as part of the model and so not carried, they were lost, and the
// KRL written anew, after its BAS(#INITMOV), turned the tool at the default speeds.)
TEST(Convert, TheOrientationSpeedsAndWholeStructuresOfVelAndApoAreCarried) {
  const std::string dir = test::tempDir("convert_vel_ori");
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL=$NULLFRAME\n$BASE=$NULLFRAME\n$VEL.CP=0.2\n$VEL.ORI1=100\n$VEL.ORI2 = 90\nPTP XP1\n"
                                  "LIN XP2\n$VEL={CP 0.3,ORI1 150,ORI2 150}\n$APO={CVEL 80,CPTP 20,CDIS 5,CORI 5}\n$APO.CDIS=7\nLIN XP1 C_DIS\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  const Program krl = readKrl(dir + "/p.src");
  std::vector<std::string> carried;
  for (const PassThrough& s : krl.passthrough) carried.push_back(s.text);
  EXPECT_EQ(carried, (std::vector<std::string>{"$VEL.ORI1=100", "$VEL.ORI2 = 90", "$VEL={CP 0.3,ORI1 150,ORI2 150}",
                                               "$APO={CVEL 80,CPTP 20,CDIS 5,CORI 5}"}));
  ASSERT_EQ(krl.motions.size(), 3u);
  EXPECT_EQ(*krl.motions[1].vel_m_s, 0.2);  // $VEL.CP and $APO.CDIS: the model's, not carried
  EXPECT_EQ(*krl.motions[2].approximation_value, 7.0);
  const std::vector<std::string> back = lines(writeKrl(parseXmlProgram(writeXmlProgram(krl), "p.xml")).src);
  const size_t ori1 = indexOf(back, "$VEL.ORI1=100"), lin = indexOf(back, "LIN XP2");
  ASSERT_NE(ori1, std::string::npos);
  EXPECT_EQ(indexOf(back, "$VEL.ORI2 = 90"), ori1 + 1);
  EXPECT_LT(ori1, lin);
  EXPECT_LT(lin, indexOf(back, "$VEL={CP 0.3,ORI1 150,ORI2 150}"));
  EXPECT_LT(indexOf(back, "$APO={CVEL 80,CPTP 20,CDIS 5,CORI 5}"), indexOf(back, "LIN XP1 C_DIS"));
  EXPECT_EQ(indexOf(back, "$VEL.CP=0.2"), std::string::npos);  // written anew, in the model's format
}

TEST(Convert, TheDefsParametersAndAPointDeclaredWithoutAValueSurviveTheRoundTrip) {
  // without them the converted program does not compile: `count` and `lp1` would be undeclared
  const std::string dir = test::tempDir("convert_params");
  test::writeText(dir + "/p.src",
                  "DEF p(count :IN)\n  INT count\n  DECL E6POS lp1\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nLIN XP1\n"
                  "  lp1 = XP1\n  lp1.Z = lp1.Z + 50\nLIN lp1\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  const Program krl = readKrl(dir + "/p.src");
  EXPECT_EQ(krl.krl_parameters, "count :IN");
  const std::string xml = writeXmlProgram(krl);
  EXPECT_NE(xml.find("<program name=\"p\" krl_parameters=\"count :IN\" version=\"1\">"), std::string::npos) << xml;
  const KrlText back = test::lf(writeKrl(parseXmlProgram(xml, "p.xml")));
  EXPECT_NE(back.src.find("\nDEF p(count :IN)\n  INT count\n  DECL E6POS lp1\n"), std::string::npos) << back.src;
  EXPECT_EQ(back.dat.find("lp1"), std::string::npos) << back.dat;  // declared once, where the program had it
}

// A point with a value that no motion of the model names (a GLOBAL point other modules use, one
// the program only reads, a motion's target changed at run time, one a subroutine declares) is
// not declared by the KRL written anew from the model: its declaration is carried as written.
// (Before: dropped, and the converted program did not compile, 'XP9' undeclared.)
// A line declaring several points, of which the model declares some (a motion names them) and
// carries the others: only the others travel, so that KRL written anew declares each point once
// (the whole line carried declared XP1 twice: the module did not compile).
TEST(Convert, ALineDeclaringSeveralPointsCarriesOnlyThoseTheModelDoesNotDeclare) {
  const std::string dir = test::tempDir("convert_multi_decl");
  test::writeText(dir + "/m.src", "DEF m( )\nDECL E6POS XP3={X 1000,Y 30,Z 800,A 0,B 90,C 0},XP8={X 1,Y 8,Z 3,A 0,B 0,C 0}\n"
                                  "$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XP1\nLIN XP3\nIF XP9.X > 0 THEN\nLIN XP2\nENDIF\n"
                                  "XTMP=XP8\nEND\n");
  test::writeText(dir + "/m.dat", "DEFDAT m\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0},XP9={X 1,Y 2,Z 3,A 0,B 0,C 0} ; two\n"
                                  "DECL E6POS XP2={X 1000,Y 50,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  const Program p = readKrl(dir + "/m.src");
  std::vector<std::string> carried;
  for (const PassThrough& s : p.passthrough)
    if (s.text.find("DECL") != std::string::npos) carried.push_back(s.text);
  EXPECT_EQ(carried, (std::vector<std::string>{"DECL E6POS XP8={X 1,Y 8,Z 3,A 0,B 0,C 0}", "DECL E6POS XP9={X 1,Y 2,Z 3,A 0,B 0,C 0} ; two"}));
  // KRL written anew from its XML declares every point once
  test::writeText(dir + "/m.xml", writeXmlProgram(p));
  const KrlText k = writeKrl(readXmlProgram(dir + "/m.xml"));
  for (const char* name : {"XP1=", "XP2=", "XP3=", "XP8=", "XP9="}) {
    const std::string all = k.src + k.dat;
    const size_t first = all.find(name);
    EXPECT_NE(first, std::string::npos) << name << "\n" << all;
    EXPECT_EQ(all.find(name, first + 1), std::string::npos) << name << "\n" << all;
  }
}

TEST(Convert, APointNoMotionOfTheModelNamesKeepsItsDeclaration) {
  const std::string dir = test::tempDir("convert_unnamed_points");
  test::writeText(dir + "/p.src",
                  "DEF p( )\r\nDECL E6POS XLOC={X 5,Y 6,Z 7,A 0,B 90,C 0}\r\nDECL E6POS XUSED={X 1000,Y 50,Z 800,A 0,B 90,C 0}\r\n"
                  "$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\r\n$BASE=XFB\r\nPTP XP1\r\nLIN XUSED\r\nIF XP9.X>0 THEN\r\n  $OUT[1]=TRUE\r\nENDIF\r\n"
                  "XTMP=XP8\r\nXTMP=XLOC\r\nFOR I=1 TO 3\r\n  LIN XP2\r\n  XP2.Z=XP2.Z+10\r\nENDFOR\r\nEND\r\nDEF sub( )\r\n"
                  "DECL E6POS XSUB={X 1,Y 2,Z 3,A 0,B 90,C 0}\r\nXTMP=XSUB\r\nEND\r\n");
  const std::string g1 = "DECL GLOBAL E6POS XG1={X 100.0,Y 50.0,Z 30.0,A 160.0,B 10.0,C 170.0,S 2,T 10}";
  const std::string p2 = "DECL E6POS XP2={X 1000,Y 0,Z 700,A 0,B 90,C 0}";
  const std::string p8 = "DECL E6POS XP8={X 1000,Y 80,Z 800,A 0,B 90,C 0}";
  const std::string p9 = "DECL E6POS XP9={X 1000,Y 90,Z 800,A 0,B 90,C 0}";
  const std::string fb = "DECL FRAME XFB={X 10,Y 0,Z 0,A 0,B 0,C 0}";
  test::writeText(dir + "/p.dat", "DEFDAT p PUBLIC\r\n" + g1 + "\r\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\r\n" + p2 + "\r\n" +
                                      p8 + "\r\n" + p9 + "\r\n" + fb + "\r\nDECL E6POS XTMP\r\nDECL INT I\r\nENDDAT\r\n");
  const Program krl = readKrl(dir + "/p.src");
  const std::string xml = writeXmlProgram(krl);
  const KrlText back = writeKrl(parseXmlProgram(xml, "p.xml"));
  const std::vector<std::string> dat = lines(back.dat), src = lines(back.src);
  for (const std::string& d : {g1, p2, p8, p9, fb}) EXPECT_NE(indexOf(dat, d), std::string::npos) << d << "\n" << back.dat;
  EXPECT_NE(indexOf(src, "DECL E6POS XLOC={X 5,Y 6,Z 7,A 0,B 90,C 0}"), std::string::npos) << back.src;
  EXPECT_NE(indexOf(src, "DECL E6POS XSUB={X 1,Y 2,Z 3,A 0,B 90,C 0}"), std::string::npos) << back.src;
  // the points the motions name are declared once, by the model
  for (const char* name : {"XP1=", "XUSED=", "XP2="}) {
    size_t n = 0;
    for (const std::string& l : dat) n += l.find(std::string(" ") + name) != std::string::npos;
    for (const std::string& l : src) n += l.find(std::string(" ") + name) != std::string::npos;
    EXPECT_EQ(n, 1u) << name << "\n" << back.src << back.dat;
  }
  EXPECT_NE(indexOf(dat, "DECL E6POS XUSED={X 1000.0000,Y 50.0000,Z 800.0000,A 0.00000,B 90.00000,C 0.00000}"), std::string::npos)
      << back.dat;
  // and the converted program reads back with the same declarations (its XML differs from the
  // first only by the INI fold the writer gave the program, which had none)
  const std::string again = test::tempDir("convert_unnamed_points_again");
  test::writeText(again + "/p.src", back.src);
  test::writeText(again + "/p.dat", back.dat);
  const std::string xml2 = writeXmlProgram(readKrl(again + "/p.src"));
  EXPECT_EQ(xml2, xml.substr(0, xml.find("    <tool ")) + "    <passthrough language=\"KRL\">  BAS (#INITMOV,0 )</passthrough>\n" +
                      xml.substr(xml.find("    <tool ")));
}

// KUKA's orientation control ($ORI_TYPE, $CIRC_TYPE) of each CP motion travels through the XML
// (ori_type, circ_type) and comes back into KRL written anew: a statement before a LIN or CIRC
// (none where a carried statement already sets it), a spline motion's own WITH. (Before: the
// values of an LDAT and of a WITH clause were lost, the robot ran #VAR where the program said
// #CONSTANT or #JOINT.)
TEST(Convert, TheOrientationControlOfEachMotionSurvivesTheRoundTrip) {
  const std::string dir = test::tempDir("convert_ori_type");
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL=$NULLFRAME\n$BASE=$NULLFRAME\nPTP XP1\n$ORI_TYPE = #CONSTANT\nLIN XP2\n"
                                  "LDAT_ACT=LCPDAT1\nFDAT_ACT=FP1\nBAS(#CP_PARAMS,0.2)\nCIRC XP3, XP1\nSLIN XP2 WITH $ORI_TYPE = #CONSTANT\n"
                                  "SPLINE WITH $ORI_TYPE = #VAR\nSPL XP1\nENDSPLINE\nLIN XP2\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\n"
                                  "DECL E6POS XP3={X 1050,Y 50,Z 800,A 0,B 90,C 0}\nDECL FDAT FP1={TOOL_NO 0,BASE_NO 0,IPO_FRAME #BASE}\n"
                                  "DECL LDAT LCPDAT1={VEL 0.2,APO_DIST 10,ORI_TYP #JOINT,CIRC_TYP #PATH}\nENDDAT\n");
  const Program krl = readKrl(dir + "/p.src");
  ASSERT_EQ(krl.motions.size(), 6u);
  const char* const kOri[6] = {"", "#CONSTANT", "#JOINT", "#CONSTANT", "", "#JOINT"};
  for (size_t k = 0; k < 6; ++k) EXPECT_EQ(krl.motions[k].ori_type, kOri[k]) << k;
  EXPECT_EQ(krl.motions[2].circ_type, "#PATH");
  const std::string xml = writeXmlProgram(krl);
  EXPECT_NE(xml.find("<circ vel_m_s=\"0.2000\" ori_type=\"#JOINT\" circ_type=\"#PATH\">"), std::string::npos) << xml;
  const KrlText back = test::lf(writeKrl(parseXmlProgram(xml, "p.xml")));
  EXPECT_NE(back.src.find("\n$ORI_TYPE = #CONSTANT\nLIN XP2\n"), std::string::npos) << back.src;  // carried, not doubled
  EXPECT_NE(back.src.find("\n$ORI_TYPE=#JOINT\n$CIRC_TYPE=#PATH\n$VEL.CP=0.2000\nCIRC XP3, XP1\nSLIN XP2 WITH $ORI_TYPE=#CONSTANT\n"), std::string::npos)
      << back.src;
  EXPECT_NE(back.src.find("\nSPLINE\nSPL XP1 WITH $ORI_TYPE=#VAR\nENDSPLINE\nLIN XP2\n"), std::string::npos) << back.src;
  // read back: every motion runs with the orientation control it had
  const std::string again = test::tempDir("convert_ori_type_again");
  test::writeText(again + "/p.src", back.src);
  test::writeText(again + "/p.dat", back.dat);
  const Program krl2 = readKrl(again + "/p.src");
  ASSERT_EQ(krl2.motions.size(), 6u);
  for (size_t k = 0; k < 6; ++k) {
    EXPECT_EQ(krl2.motions[k].ori_type, kOri[k]) << k;
    EXPECT_EQ(krl2.motions[k].circ_type, krl.motions[k].circ_type) << k;
  }
  // an XML attribute where it means nothing is an error naming it
  try {
    parseXmlProgram("<program version=\"1\"><motions><ptp ori_type=\"#CONSTANT\"><pose x_mm=\"1\" y_mm=\"2\" z_mm=\"3\" a_deg=\"0\" "
                    "b_deg=\"0\" c_deg=\"0\"/></ptp></motions></program>\n",
                    "q.xml");
    FAIL();
  } catch (const calib::InputError& e) {
    EXPECT_NE(e.message().find("attribute 'ori_type': expected it on a CP motion"), std::string::npos) << e.message();
  }
}

// A relative motion's coordinate system (KSS: `LIN_REL {Z -100} #TOOL` moves along the tool's
// axes, `#BASE`, the default, along the base's; "Without an optional frame argument, LIN_REL
// defaults to Base coordinates. Append #TOOL for Tool-relative motion.") survives KRL -> XML ->
// KRL. (Before: the reader skipped `#TOOL`, and the KRL written anew moved along the base.)
TEST(Convert, ARelativeMotionInTheToolFrameKeepsItsFrame) {
  const std::string dir = test::tempDir("convert_rel_tool");
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL=$NULLFRAME\n$BASE=$NULLFRAME\nPTP {A1 0,A2 -90,A3 90,A4 0,A5 45,A6 0}\n"
                                  "LIN_REL {Z -10.0} C_DIS #TOOL\nLIN_REL {Z 10.0} #BASE\nCIRC_REL {X 25,Y 25},{X 50,Y 0} #tool\n"
                                  "PTP_REL {A6 10}\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nENDDAT\n");
  const Program krl = readKrl(dir + "/p.src");
  ASSERT_EQ(krl.motions.size(), 5u);
  const bool kInTool[5] = {false, true, false, true, false};
  for (size_t k = 0; k < 5; ++k) EXPECT_EQ(krl.motions[k].relative_in_tool, kInTool[k]) << k;
  const std::string xml = writeXmlProgram(krl);
  EXPECT_NE(xml.find("<lin approx=\"C_DIS\" relative=\"true\" relative_frame=\"tool\">"), std::string::npos) << xml;
  EXPECT_NE(xml.find("<circ relative=\"true\" relative_frame=\"tool\">"), std::string::npos) << xml;
  const std::vector<std::string> back = lines(writeKrl(parseXmlProgram(xml, "p.xml")).src);
  EXPECT_NE(indexOf(back, "LIN_REL {Z -10.0000} C_DIS #TOOL"), std::string::npos) << writeKrl(parseXmlProgram(xml, "p.xml")).src;
  EXPECT_NE(indexOf(back, "LIN_REL {Z 10.0000}"), std::string::npos);
  EXPECT_NE(indexOf(back, "CIRC_REL {X 25.0000,Y 25.0000}, {X 50.0000,Y 0.0000} #TOOL"), std::string::npos);
  EXPECT_NE(indexOf(back, "PTP_REL {A6 10.0000}"), std::string::npos);
  // the XML attribute where it means nothing is an error naming it
  try {
    parseXmlProgram("<program version=\"1\"><motions><lin relative_frame=\"tool\"><pose z_mm=\"1\"/></lin></motions></program>\n", "q.xml");
    FAIL();
  } catch (const calib::InputError& e) {
    EXPECT_NE(e.message().find("attribute 'relative_frame': expected 'base' or 'tool' on a motion with relative=\"true\", found 'tool' on a "
                               "motion that is not relative"),
              std::string::npos)
        << e.message();
  }
}

// The line end of KRL: a file read from KRL keeps its own (CRLF stays CRLF, also in the lines
// the compensation inserts and declares); KRL written anew has CRLF, the line end of the
// controller's own files (the KSS HMI runs on Windows: the inline-form programs of
// tests/golden/krl/kss8_inline and krc2, examples/seam.src). (Before: KRL written anew had LF,
// and a CRLF program through XML came back with LF.)
TEST(Convert, KrlKeepsItsLineEndsAndKrlWrittenAnewHasTheControllersCrlf) {
  auto bareLf = [](const std::string& text) {
    for (size_t i = 0; i < text.size(); ++i)
      if (text[i] == '\n' && (i == 0 || text[i - 1] != '\r')) return true;
    return false;
  };
  // KRC's seam (CRLF) through XML and back; RoboDK's program (LF) too
  for (const std::string& f : {std::string("examples/seam.src"), std::string("tests/golden/krl/robodk/Pick_Place.src")}) {
    KrlReadOptions o;
    if (f == "examples/seam.src") o.config_path = test::sourcePath("examples/$config.dat");
    const KrlText back = writeKrl(parseXmlProgram(writeXmlProgram(readKrl(test::sourcePath(f), o)), "p.xml"));
    EXPECT_FALSE(bareLf(back.src)) << f << "\n" << back.src;
    EXPECT_FALSE(bareLf(back.dat)) << f << "\n" << back.dat;
    EXPECT_EQ(back.src.substr(0, 21), "&ACCESS RVP\r\n&REL 1\r\n") << f;
  }
  // a CRLF program compensated: corrected in place, a point declared anew, CRLF throughout
  const std::string dir = test::tempDir("convert_crlf");
  const std::string src = "DEF p( )\r\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\r\n$BASE={X 1200,Y 0,Z 400,A 0,B 0,C 0}\r\nPTP XP1\r\nLIN XP2\r\n"
                          "$BASE={X 1200,Y 10,Z 400,A 0,B 0,C 0}\r\nLIN XP2\r\nEND\r\n";
  const std::string dat = "DEFDAT p\r\nDECL E6POS XP1={X 100,Y 0,Z 100,A 0,B 90,C 0}\r\nDECL E6POS XP2={X 150,Y 50,Z 100,A 0,B 90,C 0}\r\nENDDAT\r\n";
  test::writeText(dir + "/p.src", src);
  test::writeText(dir + "/p.dat", dat);
  JobSettings s;
  s.calibrated = calib::readRobotFile(test::sourcePath("tests/data/plugin/kr16_calibrated.xml"));
  const ProgramCompensation pc = compensateProgramReport(readKrl(dir + "/p.src"), s);
  ASSERT_TRUE(pc.ok()) << pc.report.errors.front().message;
  const KrlText out = writeKrl(pc.program);
  EXPECT_NE(out.src, src);
  EXPECT_NE(out.dat.find("\r\nDECL E6POS XP2_1={"), std::string::npos) << out.dat;  // XP2 in another base: a point of its own
  EXPECT_FALSE(bareLf(out.src)) << out.src;
  EXPECT_FALSE(bareLf(out.dat)) << out.dat;
}

// A carried BAS(#INITMOV, ..) sets $ORI_TYPE / $CIRC_TYPE back to #VAR / #BASE (BAS.SRC's
// INITMOV): KRL written anew says the value again after it where a motion needs another one, and
// nothing where it needs the default. (Before: the writer took the value set before it as still
// active, and a #CONSTANT LIN after it ran #VAR.)
TEST(Convert, KrlWrittenAnewSaysTheOrientationControlAgainAfterInitmov) {
  const std::string dir = test::tempDir("convert_ori_initmov");
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL=$NULLFRAME\n$BASE=$NULLFRAME\nPTP XP1\n$ORI_TYPE = #CONSTANT\nLIN XP2\n"
                                  "BAS (#INITMOV,0 )\n$TOOL=$NULLFRAME\n$BASE=$NULLFRAME\nLIN XP1\nLIN XP2\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  std::string xml = writeXmlProgram(readKrl(dir + "/p.src"));
  // the LIN XP2 after INITMOV made #CONSTANT in the XML (as an OLP would): said again
  const size_t last = xml.rfind("<lin>");
  ASSERT_NE(last, std::string::npos) << xml;
  xml.replace(last, 5, "<lin ori_type=\"#CONSTANT\">");
  const KrlText back = test::lf(writeKrl(parseXmlProgram(xml, "p.xml")));
  EXPECT_NE(back.src.find("\n$ORI_TYPE = #CONSTANT\nLIN XP2\nBAS (#INITMOV,0 )\nLIN XP1\n$ORI_TYPE=#CONSTANT\nLIN XP2\nEND\n"), std::string::npos)
      << back.src;
}

// RAPID and URScript have no orientation control: their path motions turn the orientation from
// the start's to the target's (KUKA's #VAR). A KRL LIN with $ORI_TYPE #CONSTANT keeps the
// orientation it starts with (KSS 8.x, "Orientation control LIN, CIRC"): converted exactly, to its
// target with the start's orientation. #JOINT (and $CIRC_TYPE #PATH, a #CONSTANT start that is not
// known) cannot be said: refused naming the motion, or with --drop-unconvertible converted without
// it and listed. (Before: the setting was dropped silently, the robot turned to the written
// orientation the KUKA program never reaches.)
TEST(Convert, AnOrientationControlRapidAndUrScriptCannotSayIsWrittenExactlyOrRefused) {
  const std::string dir = test::tempDir("convert_ori_other");
  test::writeText(dir + "/p.src", "DEF p( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XP1\n$ORI_TYPE = #CONSTANT\nLIN XP2\nLIN XP3\n"
                                  "$ORI_TYPE = #JOINT\nLIN XP2\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0,S 2,T 2}\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 10,B 80,C 5,S 2,T 2}\n"
                                  "DECL E6POS XP3={X 1050,Y 50,Z 800,A 20,B 70,C 0,S 2,T 2}\nENDDAT\n");
  const Program krl = readKrl(dir + "/p.src");
  ASSERT_EQ(krl.motions.size(), 4u);
  for (const auto& [format, language] : {std::make_pair(ProgramFormat::kRapid, "RAPID"), std::make_pair(ProgramFormat::kUrScript, "URScript")}) {
    try {
      (void)renderProgram(krl, format, dir + "/out");
      ADD_FAILURE() << "expected the #JOINT LIN to be refused in " << language;
    } catch (const calib::ArgumentError& e) {
      EXPECT_NE(std::string(e.what()).find(dir + "/p.src:9:1: cannot convert 'LIN XP2' to " + language +
                                           ": its orientation control $ORI_TYPE #JOINT cannot be carried"),
                std::string::npos)
          << e.what();
    }
    std::vector<PassThrough> dropped;
    const Program out = dropUnconvertible(krl, format, &dropped);
    // (the statements setting it are KRL's: dropped and listed too)
    ASSERT_EQ(dropped.size(), 3u);
    EXPECT_EQ(dropped[0].text, "$ORI_TYPE = #CONSTANT");
    EXPECT_EQ(dropped[1].text, "$ORI_TYPE = #JOINT");
    EXPECT_EQ(dropped[2].where.line, 9);
    EXPECT_EQ(dropped[2].text, std::string("orientation control $ORI_TYPE #JOINT of LIN XP2 (the controller turns the wrist axes linearly; ") +
                                   language + " has no such setting)");
    // written and read back: the #CONSTANT LINs go to their positions with XP1's orientation,
    // the last LIN to XP2 as written
    const std::string file = dir + (format == ProgramFormat::kRapid ? "/p.mod" : "/p.script");
    test::writeText(file, renderProgram(out, format, file).at(0).text);
    const Program back = readProgram(file);
    ASSERT_EQ(back.motions.size(), 4u);
    const double xyz[4][3] = {{1000, 0, 800}, {1000, 100, 800}, {1050, 50, 800}, {1000, 100, 800}};
    const double abc[4][3] = {{0, 90, 0}, {0, 90, 0}, {0, 90, 0}, {10, 80, 5}};
    for (size_t k = 0; k < 4; ++k) {
      const calib::XyzAbc want{xyz[k][0], xyz[k][1], xyz[k][2], abc[k][0], abc[k][1], abc[k][2]};
      // (a URScript pose is the TCP in the robot base: the tool's flange-side frame is set_tcp's)
      const Eigen::Isometry3d got = calib::toIsometry(back.motions[k].target.xyzAbc());
      EXPECT_LT((got.translation() - calib::toIsometry(want).translation()).norm(), 1e-3) << language << " " << k;
      EXPECT_LT((got.linear() - calib::toIsometry(want).linear()).norm(), 1e-5) << language << " " << k;
    }
  }
  // a #CONSTANT LIN whose start is not known (the program's first motion) cannot be written exactly
  test::writeText(dir + "/q.src", "DEF q( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE=$NULLFRAME\n$ORI_TYPE = #CONSTANT\nLIN XP2\nEND\n");
  test::writeText(dir + "/q.dat", "DEFDAT q\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 10,B 80,C 5,S 2,T 2}\nENDDAT\n");
  try {
    (void)renderProgram(readKrl(dir + "/q.src"), ProgramFormat::kRapid, dir + "/q.mod");
    ADD_FAILURE() << "expected the #CONSTANT LIN without a known start to be refused";
  } catch (const calib::ArgumentError& e) {
    EXPECT_NE(std::string(e.what()).find("q.src:5:1: cannot convert 'LIN XP2' to RAPID: its orientation control $ORI_TYPE #CONSTANT cannot be carried "
                                         "(it keeps the orientation the robot has at its start, which is not known here"),
              std::string::npos)
        << e.what();
  }
}

TEST(Convert, AnUnknownStartTravelsThroughXml) {
  // compensating the XML must not densify the segment after a branch the KRL program has
  const std::string dir = test::tempDir("convert_start");
  test::writeText(dir + "/p.src",
                  "DEF p( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nLIN XP1\nIF $IN[1] THEN\n  LIN XP2\nENDIF\nLIN XP1\nEND\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nDECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  const std::string xml = writeXmlProgram(readKrl(dir + "/p.src"));
  const Program back = parseXmlProgram(xml, "p.xml");
  ASSERT_EQ(back.motions.size(), 3u);
  EXPECT_FALSE(back.motions[1].start_unknown);
  EXPECT_TRUE(back.motions[2].start_unknown) << xml;
  EXPECT_NE(xml.find("start_unknown=\"true\""), std::string::npos) << xml;
}

TEST(Convert, BytesThatAreNotUtf8RoundTripThroughXml) {
  Program p;
  p.name = "p";
  PassThrough s;
  s.language = "KRL";
  s.text = "; Schwei\xfc" "naht  ";  // cp1252, trailing blanks
  p.passthrough.push_back(s);
  s.text = "  WAIT SEC 0.5 ; <&>";
  p.passthrough.push_back(s);
  const std::string xml = writeXmlProgram(p);
  EXPECT_NE(xml.find("encoding=\"hex\""), std::string::npos) << xml;
  EXPECT_NE(xml.find("&lt;&amp;&gt;"), std::string::npos) << xml;
  const Program back = parseXmlProgram(xml, "p.xml");
  ASSERT_EQ(back.passthrough.size(), 2u);
  EXPECT_EQ(back.passthrough[0].text, p.passthrough[0].text);
  EXPECT_EQ(back.passthrough[1].text, p.passthrough[1].text);
}

TEST(Convert, WhatCannotBeCarriedIsRefusedNamingTheLine) {
  // a motion of a local subroutine: the motion model holds the main program's only
  const std::string dir = test::tempDir("convert_refuse");
  test::writeText(dir + "/p.src",
                  "DEF p( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nLIN {X 1000,Y 0,Z 800,A 0,B 90,C 0}\nsub( )\nEND\n"
                  "DEF sub( )\n  LIN {X 1000,Y 50,Z 800,A 0,B 90,C 0}\nEND\n");
  const Program p = readKrl(dir + "/p.src");
  try {
    writeXmlProgram(p);
    ADD_FAILURE() << "expected a refusal";
  } catch (const calib::ArgumentError& e) {
    EXPECT_NE(std::string(e.what()).find(dir + "/p.src:8:1"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("local subroutine"), std::string::npos) << e.what();
  }
  // written back as KRL the program is unchanged
  EXPECT_EQ(writeKrl(p).src, test::readText(dir + "/p.src"));
  // another language's statement cannot go into KRL
  const std::string xml =
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<program name=\"p\" version=\"1\">\n  <motions>\n"
      "    <passthrough language=\"RAPID\">SetDO doTorch, 1;</passthrough>\n"
      "    <ptp>\n      <axes a1=\"0\" a2=\"-90\" a3=\"90\" a4=\"0\" a5=\"0\" a6=\"0\"/>\n    </ptp>\n  </motions>\n</program>\n";
  const Program x = parseXmlProgram(xml, "p.xml");
  try {
    writeKrl(x);
    ADD_FAILURE() << "expected a refusal";
  } catch (const calib::ArgumentError& e) {
    EXPECT_NE(std::string(e.what()).find("p.xml:4:5"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("RAPID"), std::string::npos) << e.what();
  }
  // the command line: exit 1 with the place, nothing written
  const test::CliRun r = test::runAccuraIn(dir, "convert --in p.src --out p.xml");
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("p.src:8:1"), std::string::npos) << r.err;
  EXPECT_FALSE(std::ifstream(dir + "/p.xml").good());
}

TEST(Convert, MalformedPassThroughIsAnErrorWithItsPlace) {
  auto error = [](const std::string& element) -> std::string {
    const std::string xml = "<?xml version=\"1.0\"?>\n<program version=\"1\">\n  <motions>\n    " + element + "\n  </motions>\n</program>\n";
    try {
      parseXmlProgram(xml, "p.xml");
    } catch (const calib::InputError& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_NE(error("<passthrough>$OUT[1]=TRUE</passthrough>").find("p.xml:4:5: <passthrough>: expected attribute 'language'"),
            std::string::npos);
  EXPECT_NE(error("<passthrough language=\"KRL\" section=\"head\">x</passthrough>").find("expected body, trailer or data, found 'head'"),
            std::string::npos);
  EXPECT_NE(error("<passthrough language=\"KRL\" encoding=\"hex\">4g</passthrough>").find("expected hexadecimal digits, found 'g'"),
            std::string::npos);
  EXPECT_NE(error("<passthrough language=\"KRL\" colour=\"red\">x</passthrough>").find("unknown attribute 'colour'"), std::string::npos);
  // the attributes of carried source lines
  const std::pair<const char*, const char*> carried[] = {
      {"role=\"decl\" line=\"3\"", "expected motion, model or comment, found 'decl'"},
      {"line=\"3\" eol=\"cr\"", "expected lf, crlf or none, found 'cr'"},
      {"role=\"model\"", "expected the attribute 'line' with 'role' or 'eol' (a line carried with its place), found none"}};
  for (const auto& c : carried)
    EXPECT_NE(error(std::string("<passthrough language=\"RAPID\" ") + c.first + ">x</passthrough>").find(c.second), std::string::npos) << c.first;
}

// RAPID -> XML -> RAPID and URScript -> XML -> URScript give the source back byte for byte
// (issue 12: comments, tooldata load, confdata, Offs expressions, names, line ends), also
// after the XML program is compensated with the nominal robot; every bundled example and
// golden file, and the line-end variants (CRLF, no final newline) of one.
struct RoundTrip {
  std::string path;  // the program (its extension gives the format)
  std::string robot; // bundled robot, nominal ("": not compensated, the targets are out of its reach)
};

std::string throughXml(const std::string& dir, const std::string& name, const std::string& text, const calib::RobotModel* nominal) {
  const std::string in = dir + "/" + name;
  test::writeText(in, text);
  const Program p = readProgram(in);
  const std::string xml = dir + "/" + name + ".xml";
  test::writeText(xml, renderProgram(p, ProgramFormat::kXml, xml).at(0).text);
  Program x = readProgram(xml);
  if (nominal) {
    JobSettings s;
    s.calibrated = *nominal;
    s.tol_mm = 0.05;
    x = compensateProgram(x, s, nullptr);
  }
  const std::string out = dir + "/back_" + name;
  return renderProgram(x, programFormat(in), out).at(0).text;
}

TEST(Convert, RapidAndUrScriptThroughXmlComeBackByteForByte) {
  const std::string dir = test::tempDir("convert_round_trip");
  const RoundTrip files[] = {{"examples/irb120_seam.mod", "abb_irb120"},
                             {"tests/golden/rapid/irb120_seam.mod", "abb_irb120"},
                             {"tests/golden/rapid/line_arc.mod", "abb_irb120"},
                             {"tests/golden/rapid/expected/irb120_seam.mod", "abb_irb120"},
                             {"examples/ur10_seam.script", "ur10"},
                             {"tests/golden/urscript/ur10_seam.script", "ur10"},
                             {"tests/golden/urscript/weld_seam.script", ""},
                             {"tests/golden/urscript/expected/ur10_seam.script", "ur10"},
                             {"tests/data/urscript/polyscope_export.script", "ur10"}};
  int n = 0;
  for (const RoundTrip& f : files) {
    const std::string text = test::readText(test::sourcePath(f.path));
    const std::string ext = f.path.substr(f.path.rfind('.'));
    const std::string name = "p" + std::to_string(n++) + ext;
    EXPECT_EQ(throughXml(dir, name, text, nullptr), text) << f.path;
    if (!f.robot.empty()) {
      const calib::RobotModel nominal = test::loadBundled(f.robot);
      EXPECT_EQ(throughXml(dir, name, text, &nominal), text) << f.path << " compensated with the nominal " << f.robot;
    }
    // CRLF line ends, and no newline after the last line
    std::string crlf;
    for (char c : text) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
    EXPECT_EQ(throughXml(dir, name, crlf, nullptr), crlf) << f.path << " with CRLF";
    // a line of blanks only and a tab after the first line
    const std::string blanks = text.substr(0, text.find('\n') + 1) + "   \n\t\n" + text.substr(text.find('\n') + 1);
    EXPECT_EQ(throughXml(dir, name, blanks, nullptr), blanks) << f.path << " with blank lines";
    const std::string open_end = text.substr(0, text.find_last_not_of('\n') + 1);
    EXPECT_EQ(throughXml(dir, name, open_end, nullptr), open_end) << f.path << " without a final newline";
  }
  // the XML holds what the motion model cannot: the tooldata's load, confdata, the Offs
  // expression, a comment, each as its line
  const std::string x = test::readText(dir + "/p0.mod.xml");
  for (const char* k : {"role=\"model\" line=\"4\">  PERS tooldata torch := [TRUE,[[0,0,150],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];</passthrough>",
                        "role=\"comment\" line=\"2\">  ! Weld seam", "abb_conf=\"-1,0,-1,0\"",
                        "role=\"motion\" line=\"26\">    MoveL Offs(p60,0,0,100), v200, z20, torch\\WObj:=table;</passthrough>",
                        "line=\"20\">    SetDO do_torch, 1;  ! arc on</passthrough>"})
    EXPECT_NE(x.find(k), std::string::npos) << k << "\n" << x;
}

// A target changed in the XML goes back into the carried RAPID text: its declaration's numbers
// only; a motion that no longer matches its carried statement is refused naming it.
TEST(Convert, ChangedXmlTargetsGoIntoTheCarriedRapidText) {
  const std::string dir = test::tempDir("convert_carried_change");
  const std::string text = test::readText(test::sourcePath("examples/irb120_seam.mod"));
  test::writeText(dir + "/seam.mod", text);
  Program x = parseXmlProgram(renderProgram(readProgram(dir + "/seam.mod"), ProgramFormat::kXml, dir + "/seam.xml").at(0).text, "seam.xml");
  ASSERT_EQ(x.motions.size(), 8u);
  calib::XyzAbc p30 = x.motions[3].target.xyzAbc();  // MoveL p30
  p30.x_mm += 0.25;
  x.motions[3].target.setPose(p30);
  const std::string back = writeRapid(x);
  std::string want = text;
  const std::string old_decl = "CONST robtarget p30 := [[160,60,20]";
  want.replace(want.find(old_decl), old_decl.size(), "CONST robtarget p30 := [[160.2500,60,20]");
  EXPECT_EQ(back, want);
  x.motions[3].type = MotionType::kPtp;
  try {
    writeRapid(x);
    ADD_FAILURE() << "a motion unlike its carried statement was written";
  } catch (const calib::ArgumentError& e) {
    EXPECT_NE(std::string(e.what()).find("differs from its carried statement at line 21"), std::string::npos) << e.what();
  }
}

// Compensated as XML, written back as RAPID: the module the direct compensation writes
// (tests/golden/rapid/expected), up to the XML's rounding (1e-4 mm, 1e-5 deg): the same lines
// outside the targets, the same points (the split CIRC's new point p40_1 declared beside p40,
// which keeps its value), the same inserted motion.
TEST(Convert, CompensatedThroughXmlGivesTheDirectlyCompensatedModule) {
  const std::string dir = test::tempDir("convert_compensated_xml");
  const std::string g = test::sourcePath("tests/golden/rapid/");
  test::writeText(dir + "/seam.mod", test::readText(g + "irb120_seam.mod"));
  const Program x = parseXmlProgram(renderProgram(readProgram(dir + "/seam.mod"), ProgramFormat::kXml, dir + "/seam.xml").at(0).text,
                                    dir + "/seam.xml");
  JobSettings s;
  s.calibrated = calib::readRobotFile(g + "irb120_real.xml");
  s.tol_mm = 0.05;
  const std::string direct = test::readText(g + "expected/irb120_seam.mod");
  // compensated as XML; and compensated as RAPID in memory (its inserted motion has no line of
  // its own), then through XML
  const Program compensated = compensateProgram(readProgram(dir + "/seam.mod"), s, nullptr);
  const std::string in_memory = writeRapid(parseXmlProgram(renderProgram(compensated, ProgramFormat::kXml, dir + "/c.xml").at(0).text, "c.xml"));
  for (const std::string& via_xml : {writeRapid(compensateProgram(x, s, nullptr)), in_memory}) {
  const Program a = parseRapid(via_xml, "via_xml.mod"), b = parseRapid(direct, "direct.mod");
  ASSERT_EQ(a.motions.size(), b.motions.size());
  for (size_t k = 0; k < a.motions.size(); ++k) {
    std::vector<std::pair<const Target*, const Target*>> ts = {{&a.motions[k].target, &b.motions[k].target}};
    if (a.motions[k].aux) ts.emplace_back(&*a.motions[k].aux, &*b.motions[k].aux);
    for (const auto& t : ts) {
      EXPECT_EQ(t.first->name, t.second->name) << k;
      if (t.first->kind != Target::Kind::kCartesian) continue;
      const Eigen::Isometry3d A = calib::toIsometry(t.first->xyzAbc()), B = calib::toIsometry(t.second->xyzAbc());
      EXPECT_LT((A.translation() - B.translation()).norm(), 2e-4) << k;
      EXPECT_LT(calib::rotationAngleDeg(A.linear() * B.linear().transpose()), 1e-4) << k;
      EXPECT_EQ(t.first->abb_conf, t.second->abb_conf) << k;
    }
  }
  // every line that holds no robtarget value is the same
  const std::vector<std::string> la = lines(via_xml), lb = lines(direct);
  ASSERT_EQ(la.size(), lb.size());
  for (size_t i = 0; i < la.size(); ++i) {
    if (la[i].find("[[") == std::string::npos) {
      EXPECT_EQ(la[i], lb[i]) << i + 1;
    }
  }
  }
}

// Between vendors the carried lines are refused at the first statement the target cannot hold;
// --drop-unconvertible keeps the motions and lists every line it leaves out.
TEST(Convert, DropUnconvertibleListsEveryDroppedLine) {
  const std::string dir = test::tempDir("convert_drop");
  const std::string text = test::readText(test::sourcePath("examples/irb120_seam.mod"));
  test::writeText(dir + "/seam.mod", text);
  ASSERT_EQ(test::runAccuraIn(dir, "convert --in seam.mod --out seam.xml").code, 0);
  const test::CliRun refused = test::runAccuraIn(dir, "convert --in seam.xml --out seam.src");
  EXPECT_EQ(refused.code, 1);
  EXPECT_NE(refused.err.find("cannot convert the RAPID statement '  CONST jointtarget home := [[0,0,0,0,30,0],[9E9,9E9,9E9,9E9,9E9,9E9]];' to KRL"),
            std::string::npos)
      << refused.err;
  // ... and names the option that converts the motions without it (before: the refusal alone)
  EXPECT_NE(refused.err.find("to KRL: it is outside the motion model and only RAPID can carry it (convert --drop-unconvertible leaves "
                             "such statements out and lists them)\n"),
            std::string::npos)
      << refused.err;
  const test::CliRun r = test::runAccuraIn(dir, "convert --in seam.mod --out seam.src --drop-unconvertible --json drop.json");
  ASSERT_EQ(r.code, 0) << r.err;
  // the lines of the module that are statements outside the motion model, independently:
  // not blank, not a comment, not a move, not a declaration of a robtarget/tooldata/wobjdata,
  // not the module/routine frame or ConfL
  std::vector<std::pair<int, std::string>> want;
  const std::vector<std::string> ls = lines(text);
  for (size_t i = 0; i < ls.size(); ++i) {
    const std::string& l = ls[i];
    const size_t b = l.find_first_not_of(' ');
    if (b == std::string::npos || l[b] == '!') continue;
    const std::string w = l.substr(b, l.find_first_of(" ;(", b) - b);
    if (w == "MODULE" || w == "ENDMODULE" || w == "PROC" || w == "ENDPROC" || w == "ConfL" || w.rfind("Move", 0) == 0) continue;
    if (l.find(" robtarget ") != std::string::npos || l.find(" tooldata ") != std::string::npos || l.find(" wobjdata ") != std::string::npos)
      continue;
    want.emplace_back(static_cast<int>(i + 1), l);
  }
  ASSERT_EQ(want.size(), 6u);  // jointtarget, VAR num, SetDO x2, WaitTime, seams := ...
  const nlohmann::json j = nlohmann::json::parse(test::readText(dir + "/drop.json"));
  ASSERT_EQ(j["dropped"].size(), want.size()) << j.dump(2);
  for (size_t k = 0; k < want.size(); ++k) {
    EXPECT_EQ(j["dropped"][k]["line"].get<int>(), want[k].first);
    EXPECT_EQ(j["dropped"][k]["text"].get<std::string>(), want[k].second);
    EXPECT_NE(r.err.find("seam.mod:" + std::to_string(want[k].first) + ":1: dropped '" + want[k].second + "'"), std::string::npos) << r.err;
  }
  // the motions are all there
  KrlReadOptions o;
  EXPECT_EQ(readKrl(dir + "/seam.src", o).motions.size(), 8u);
  // URScript -> KRL: its three statements that are not motions, set_tcp or pose assignments
  test::writeText(dir + "/ur.script", test::readText(test::sourcePath("examples/ur10_seam.script")));
  const test::CliRun u = test::runAccuraIn(dir, "convert --in ur.script --out ur.src --drop-unconvertible");
  ASSERT_EQ(u.code, 0) << u.err;
  for (const char* d : {"ur.script:6:3: dropped '  set_payload(1.2)'", "ur.script:13:3: dropped '  set_digital_out(0, True)  # arc on'",
                        "ur.script:17:3: dropped '  set_digital_out(0, False)  # arc off'"})
    EXPECT_NE(u.err.find(d), std::string::npos) << d << "\n" << u.err;
  EXPECT_NE(u.out.find("3 dropped"), std::string::npos) << u.out;
}

// Dropping an if/else around motions ran both branches one after the other (a loop's body once):
// the converted program took a path the original never did. Refused, naming the statement and
// the motion; a branch without motions inside is still dropped.
TEST(Convert, DroppingABranchOrALoopAroundMotionsIsRefused) {
  const std::string dir = test::tempDir("convert_drop_flow");
  test::writeText(dir + "/b.script", "def branch():\n  set_tcp(p[0,0,0.15,0,0,0])\n  movej([-1.5707963, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0.0])\n"
                                     "  if get_standard_digital_in(0):\n    movel(p[-0.35, 0.7, 0.2, 3.1415927, 0, 0])\n  else:\n"
                                     "    movel(p[-0.35, 0.7, 0.5, 3.1415927, 0, 0])\n  end\nend\n");
  const test::CliRun ur = test::runAccuraIn(dir, "convert --in b.script --out b.mod --drop-unconvertible");
  EXPECT_EQ(ur.code, 1);
  EXPECT_NE(ur.err.find("b.script:4:3: cannot drop '  if get_standard_digital_in(0):': it branches or loops around the motion at "
                        "b.script:5:5, which would then run unconditionally"),
            std::string::npos)
      << ur.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/b.mod"));
  const std::string head = "DEF k( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP {A1 0,A2 -90,A3 90,A4 0,A5 45,A6 0}\n";
  test::writeText(dir + "/loop.src", head + "FOR I=1 TO 3\n  LIN {X 1000,Y 0,Z 800,A 0,B 90,C 0}\nENDFOR\nEND\n");
  const test::CliRun loop = test::runAccuraIn(dir, "convert --in loop.src --out loop.script --drop-unconvertible");
  EXPECT_EQ(loop.code, 1);
  EXPECT_NE(loop.err.find("loop.src:5:1: cannot drop 'FOR I=1 TO 3': it branches or loops around the motion at loop.src:6:3"), std::string::npos)
      << loop.err;
  test::writeText(dir + "/io.src", head + "IF $IN[1] THEN\n  $OUT[2]=TRUE\nENDIF\nLIN {X 1000,Y 0,Z 800,A 0,B 90,C 0}\nEND\n");
  const test::CliRun io = test::runAccuraIn(dir, "convert --in io.src --out io.script --drop-unconvertible");
  EXPECT_EQ(io.code, 0) << io.err;
  EXPECT_NE(io.err.find("io.src:5:1: dropped 'IF $IN[1] THEN'"), std::string::npos) << io.err;
}

}  // namespace
// A statement on the line of a motion (legal RAPID) is not the motion model's: converting the
// module is refused at that line rather than carrying the SetDO inside the motion's line, where
// another format would lose it without a word.
TEST(Convert, AStatementBesideAMotionOnItsLineIsNotLost) {
  const std::string dir = test::tempDir("convert_same_line");
  std::string text = test::readText(test::sourcePath("examples/irb120_seam.mod"));
  const std::string motion = "    MoveL p20, v200, fine, torch\\WObj:=table;";
  const size_t at = text.find(motion + "\n");
  ASSERT_NE(at, std::string::npos);
  text.insert(at + motion.size(), " SetDO do_torch, 1;");
  const int line = static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n')) + 1;
  test::writeText(dir + "/seam.mod", text);
  for (const char* out : {"seam.src", "seam.xml", "seam.script"}) {
    const test::CliRun r = test::runAccuraIn(dir, std::string("convert --in seam.mod --out ") + out);
    EXPECT_EQ(r.code, 1) << out;
    EXPECT_NE(r.err.find("seam.mod:" + std::to_string(line) + ":1: cannot carry this RAPID line through the conversion: it holds a motion and another statement"),
              std::string::npos)
        << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir + "/" + out)) << out;
  }
}

namespace {

// A move's programmed time (URScript movel's t, RAPID's \T:=) was dropped by a conversion
// without a word: the converted move ran at its speed instead of taking the time. It is
// carried where the language can say it (RAPID \T:=, URScript t=, XML time_s), a split move's
// pieces each with their share; where it cannot (KRL), the conversion is refused naming the
// motion, or --drop-unconvertible converts without it and lists it.
const char* kTimedScript =
    "def timed():\n"
    "  set_tcp(p[0,0,0.15,0,0,0])\n"
    "  movej([-1.5707963, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0.0], a=1.4, v=1.05)\n"
    "  movel(p[-0.35, 0.7, 0.2, 3.1415927, 0, 0], a=1.2, v=0.25, t=4)\n"
    "end\n";
const char* kTimedModule =
    "MODULE TimeMod\n"
    "  PERS tooldata tWeld:=[TRUE,[[0,0,150],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];\n"
    "  CONST robtarget p10:=[[340,-90,120],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
    "  CONST robtarget p20:=[[340,-90,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];\n"
    "  PROC main()\n"
    "    MoveJ p10,v1000,fine,tWeld;\n"
    "    MoveL p20,v200\\T:=4,fine,tWeld;\n"
    "  ENDPROC\n"
    "ENDMODULE\n";

TEST(Convert, AMovesTimeIsCarriedOrTheConversionRefusedNamingIt) {
  const std::string dir = test::tempDir("convert_time");
  test::writeText(dir + "/u07.script", kTimedScript);
  test::writeText(dir + "/r18.mod", kTimedModule);
  // URScript -> RAPID: \T:=; read back, the move takes 4 s
  ASSERT_EQ(test::runAccuraIn(dir, "convert --in u07.script --out u07.mod").code, 0);
  const Program m = readProgram(dir + "/u07.mod");
  ASSERT_EQ(m.motions.size(), 2u);
  EXPECT_FALSE(m.motions[0].duration_s.has_value());
  ASSERT_TRUE(m.motions[1].duration_s.has_value());
  EXPECT_EQ(*m.motions[1].duration_s, 4.0);
  EXPECT_EQ(m.rapid->statements[1].duration_s, 4.0);
  EXPECT_NE(test::readText(dir + "/u07.mod").find("[250.0000,500,5000,1000]\\T:=4.0000, fine, accura_tool1;"), std::string::npos);
  // RAPID -> URScript: t=; read back, 4 s
  ASSERT_EQ(test::runAccuraIn(dir, "convert --in r18.mod --out r18.script").code, 0);
  EXPECT_NE(test::readText(dir + "/r18.script").find("  movel(p20, v=0.2000, t=4.0000)\n"), std::string::npos);
  const Program u = readProgram(dir + "/r18.script");
  ASSERT_EQ(u.motions.size(), 2u);
  EXPECT_EQ(u.motions[1].duration_s.value_or(0), 4.0);
  // through XML (time_s) and back: byte for byte; the same language: byte for byte
  for (const std::string& f : {std::string("u07.script"), std::string("r18.mod")}) {
    const std::string stem = f.substr(0, f.find('.'));
    ASSERT_EQ(test::runAccuraIn(dir, "convert --in " + f + " --out " + stem + ".xml").code, 0);
    EXPECT_NE(test::readText(dir + "/" + stem + ".xml").find("source_line=\"" + std::string(stem == "u07" ? "4" : "7") + "\" time_s=\"4.0000\">"),
              std::string::npos)
        << test::readText(dir + "/" + stem + ".xml");
    EXPECT_EQ(readProgram(dir + "/" + stem + ".xml").motions[1].duration_s.value_or(0), 4.0);
    ASSERT_EQ(test::runAccuraIn(dir, "convert --in " + stem + ".xml --out back_" + f).code, 0);
    EXPECT_EQ(test::readText(dir + "/back_" + f), test::readText(dir + "/" + f));
    ASSERT_EQ(test::runAccuraIn(dir, "convert --in " + f + " --out same_" + f).code, 0);
    EXPECT_EQ(test::readText(dir + "/same_" + f), test::readText(dir + "/" + f));
  }
  // -> KRL: refused naming the motion, nothing written
  const test::CliRun k = test::runAccuraIn(dir, "convert --in r18.mod --out r18.src");
  EXPECT_EQ(k.code, 1);
  EXPECT_NE(k.err.find("r18.mod:7:5: cannot convert 'MoveL p20,v200\\T:=4,fine,tWeld;' to KRL: its time 4.0000 s cannot be carried, KRL has no "
                       "per-motion time"),
            std::string::npos)
      << k.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/r18.src"));
  const test::CliRun ku = test::runAccuraIn(dir, "convert --in u07.script --out u07.src");
  EXPECT_EQ(ku.code, 1);
  EXPECT_NE(ku.err.find("u07.script:4:3: cannot convert 'movel(p[-0.35, 0.7, 0.2, 3.1415927, 0, 0], a=1.2, v=0.25, t=4)' to KRL"), std::string::npos)
      << ku.err;
  // --drop-unconvertible: converted without it, listed (stderr and the report)
  const test::CliRun d = test::runAccuraIn(dir, "convert --in u07.script --out u07.src --drop-unconvertible --json drop.json");
  ASSERT_EQ(d.code, 0) << d.err;
  EXPECT_NE(d.err.find("u07.script:4:3: dropped 'time 4.0000 s of movel(p[-0.35, 0.7, 0.2, 3.1415927, 0, 0], a=1.2, v=0.25, t=4) (KRL has no "
                       "per-motion time)'"),
            std::string::npos)
      << d.err;
  const nlohmann::json j = nlohmann::json::parse(test::readText(dir + "/drop.json"));
  ASSERT_EQ(j["dropped"].size(), 1u);
  EXPECT_EQ(j["dropped"][0]["line"], 4);
  EXPECT_EQ(readProgram(dir + "/u07.src").motions.size(), 2u);
}

TEST(Convert, ATimeAnotherLanguageCannotSayIsRefusedAndXmlChecksIt) {
  const std::string dir = test::tempDir("convert_time_refused");
  std::string text = kTimedModule;
  // a time computed at run time: no other format can carry it
  const std::string timed = "MoveL p20,v200\\T:=4,fine,tWeld;";
  text.replace(text.find(timed), timed.size(), "MoveL p20,v200\\T:=tm,fine,tWeld;");
  test::writeText(dir + "/expr.mod", text);
  for (const char* out : {"expr.xml", "expr.script", "expr.src"}) {
    const test::CliRun c = test::runAccuraIn(dir, std::string("convert --in expr.mod --out ") + out);
    EXPECT_EQ(c.code, 1) << out;
    EXPECT_NE(c.err.find("expr.mod:7:5: cannot "), std::string::npos) << out << c.err;
    EXPECT_NE(c.err.find("its time"), std::string::npos) << out << c.err;
    EXPECT_NE(c.err.find("tm"), std::string::npos) << out << c.err;
  }
  const test::CliRun d = test::runAccuraIn(dir, "convert --in expr.mod --out expr.xml --drop-unconvertible");
  ASSERT_EQ(d.code, 0) << d.err;
  EXPECT_NE(d.err.find("expr.mod:7:5: dropped 'time 'tm' of MoveL p20,v200\\T:=tm,fine,tWeld;"), std::string::npos) << d.err;
  // a MoveC with a time: URScript's movec has none
  test::writeText(dir + "/arc.mod", "MODULE arc\n  PROC main()\n    MoveJ [[340,-90,120],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]],v1000,fine,tool0;\n"
                                    "    MoveC [[360,-70,120],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]],[[380,-90,120],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]],v100\\T:=2,fine,tool0;\n"
                                    "  ENDPROC\nENDMODULE\n");
  const test::CliRun a = test::runAccuraIn(dir, "convert --in arc.mod --out arc.script");
  EXPECT_EQ(a.code, 1);
  EXPECT_NE(a.err.find("arc.mod:4:5: cannot convert"), std::string::npos) << a.err;
  EXPECT_NE(a.err.find("URScript's movec has no time t"), std::string::npos) << a.err;
  // XML: time_s must be a time; a carried statement's time must be the XML's
  test::writeText(dir + "/r18.mod", kTimedModule);
  ASSERT_EQ(test::runAccuraIn(dir, "convert --in r18.mod --out r18.xml").code, 0);
  const std::string xml = test::readText(dir + "/r18.xml");
  const std::string attr = "time_s=\"4.0000\"";
  ASSERT_NE(xml.find(attr), std::string::npos);
  std::string bad = xml;
  bad.replace(bad.find(attr), attr.size(), "time_s=\"-1\"");
  test::writeText(dir + "/bad.xml", bad);
  const test::CliRun b = test::runAccuraIn(dir, "convert --in bad.xml --out bad.mod");
  EXPECT_EQ(b.code, 1);
  EXPECT_NE(b.err.find("attribute 'time_s': expected the move's time in (0, 1e6] s, found -1.0000"), std::string::npos) << b.err;
  std::string other = xml;
  other.replace(other.find(attr), attr.size(), "time_s=\"5.0000\"");
  test::writeText(dir + "/other.xml", other);
  const test::CliRun o = test::runAccuraIn(dir, "convert --in other.xml --out other.mod");
  EXPECT_EQ(o.code, 1);
  EXPECT_NE(o.err.find("differs from its carried statement at line 7"), std::string::npos) << o.err;
}

// An XML program compensated with points inserted gives each piece of a timed move its share
// of the time (by length), adding up to it; written back into its carried RAPID, the \T:= of
// the pieces add up to the time too.
TEST(Convert, ATimedMoveSplitInXmlGivesEachPieceItsShare) {
  const std::string dir = test::tempDir("convert_time_split");
  test::writeText(dir + "/r18.mod", kTimedModule);
  const Program x = parseXmlProgram(renderProgram(readProgram(dir + "/r18.mod"), ProgramFormat::kXml, dir + "/r18.xml").at(0).text, "r18.xml");
  JobSettings s;
  s.calibrated = calib::readRobotFile(test::sourcePath("tests/golden/rapid/irb120_real.xml"));
  s.tol_mm = 0.001;
  const Program c = compensateProgram(x, s, nullptr);
  const Program back = parseXmlProgram(writeXmlProgram(c), "c.xml");
  std::vector<double> t, len;
  ASSERT_TRUE(back.motions.front().target.kind == Target::Kind::kCartesian);
  Eigen::Vector3d at = calib::toIsometry(back.motions.front().target.xyzAbc()).translation();
  for (size_t k = 1; k < back.motions.size(); ++k) {
    const Eigen::Vector3d to = calib::toIsometry(back.motions[k].target.xyzAbc()).translation();
    ASSERT_TRUE(back.motions[k].duration_s.has_value()) << k;
    t.push_back(*back.motions[k].duration_s);
    len.push_back((to - at).norm());
    at = to;
  }
  ASSERT_GE(t.size(), 2u) << "not split at tol 0.001 mm";
  double sum = 0;
  EXPECT_LT(test::durationShareError(t, len, 4.0, &sum), 2e-4);
  EXPECT_NEAR(sum, 4.0, 1e-9);
  const Program mod = parseRapid(writeRapid(back), "back.mod");
  double sum_mod = 0;
  for (const Motion& m : mod.motions) sum_mod += m.duration_s.value_or(0);
  EXPECT_NEAR(sum_mod, 4.0, 1e-9);
  EXPECT_EQ(mod.motions.size(), back.motions.size());
}

}  // namespace

}  // namespace accura::postproc
