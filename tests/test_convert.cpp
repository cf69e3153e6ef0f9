// convert never loses a statement (issue 12): what the motion model does not express (I/O,
// logic, interrupts, comments, declarations of other types) is carried verbatim through the
// XML format (<passthrough>) and written back into KRL byte for byte, in its place between the
// motions; what cannot be carried is refused, naming the line.
#include <gtest/gtest.h>

#include <sstream>

#include "accura/calib/errors.h"
#include "accura/postproc/krl.h"
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
  const KrlText back = writeKrl(from_xml);
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
}

}  // namespace
}  // namespace accura::postproc
