// XML programs: the reader against hand-written values, byte-identical write-back of the
// canonical form, KRL -> XML -> KRL keeping the motion model, the vocabulary against the schema
// file, and errors with file:line:column.
#include <gtest/gtest.h>
#include <tinyxml2.h>

#include <functional>

#include "accura/calib/errors.h"
#include "accura/postproc/job.h"
#include "accura/postproc/krl.h"
#include "accura/postproc/program_io.h"
#include "accura/postproc/rapid.h"
#include "accura/postproc/urscript.h"
#include "accura/postproc/xml_program.h"
#include "test_util.h"

namespace accura::postproc {
namespace {

TEST(XmlProgram, ReadsEveryElementOfTheFormat) {
  FrameTables tables;
  tables.base.resize(4);
  tables.base[3] = calib::XyzAbc{1020.25, -35.5, 410, -90, 0, 0};
  const Program p = readXmlProgram(test::golden("xml/cell_program.xml"), &tables);
  EXPECT_EQ(p.name, "cell_program");
  EXPECT_EQ(p.robot, "KUKA KR 16");
  ASSERT_EQ(p.motions.size(), 7u);
  const Motion& home = p.motions[0];
  EXPECT_EQ(home.type, MotionType::kPtp);
  EXPECT_EQ(home.target.kind, Target::Kind::kAxis);
  EXPECT_EQ(home.target.name, "XHOME");
  EXPECT_EQ(*home.target.axes[1], -90.0);
  EXPECT_EQ(*home.target.ext[0], 0.0);
  EXPECT_FALSE(home.target.ext[1]);
  EXPECT_EQ(*home.vel_percent, 50.0);
  EXPECT_EQ(home.tool.source, FrameSetting::Source::kInline);
  EXPECT_EQ(home.tool.value->z_mm, 200.0);
  EXPECT_EQ(home.base.source, FrameSetting::Source::kNull);
  EXPECT_EQ(home.where.line, 8);
  EXPECT_EQ(home.where.column, 5);
  const Motion& lin = p.motions[1];
  EXPECT_EQ(lin.base.source, FrameSetting::Source::kData);
  EXPECT_EQ(lin.base.index, 3);
  EXPECT_EQ(lin.base.value->x_mm, 1020.25);  // resolved from the tables
  EXPECT_EQ(*lin.target.pose[1], -20.5);
  EXPECT_EQ(*lin.target.pose[5], -179.5);
  EXPECT_EQ(*lin.target.status, 2);
  EXPECT_EQ(*lin.target.turn, 35);
  EXPECT_EQ(lin.approximation, std::vector<Approximation>{Approximation::kCDis});
  EXPECT_EQ(*lin.approximation_value, 5.0);
  EXPECT_EQ(*lin.vel_m_s, 0.25);
  const Target& partial = p.motions[2].target;
  EXPECT_FALSE(partial.pose[0]);
  EXPECT_EQ(*partial.pose[2], 45.25);
  const Motion& circ = p.motions[3];
  EXPECT_EQ(circ.type, MotionType::kCirc);
  EXPECT_EQ(*circ.aux->pose[0], 150.0);
  EXPECT_EQ(*circ.target.pose[0], 200.0);
  EXPECT_EQ(*circ.circ_angle_deg, 90.0);
  const Motion& slin = p.motions[4];
  EXPECT_TRUE(slin.spline);
  EXPECT_TRUE(slin.external_tcp);
  EXPECT_EQ(slin.tool.source, FrameSetting::Source::kUnknown);
  EXPECT_EQ(slin.tool.text, "STOOL2(FX)");
  EXPECT_TRUE(p.motions[5].relative);
  EXPECT_EQ(p.motions[5].target_problem, "a relative motion");
  EXPECT_EQ(p.motions[6].target.name, "XPARK");
  EXPECT_EQ(p.motions[6].target_problem, "XPARK is declared outside the program");
}

TEST(XmlProgram, CanonicalFilesAreWrittenBackByteForByte) {
  const std::string text = test::readText(test::golden("xml/weld_seam.xml"));
  const Program p = readXmlProgram(test::golden("xml/weld_seam.xml"));
  EXPECT_EQ(writeXmlProgram(p), text);
  // a hand-written file is written back as it is while nothing changes (compensating with the
  // nominal robot); once a target changes it becomes canonical, then stays
  const std::string hand = test::readText(test::golden("xml/cell_program.xml"));
  Program changed = readXmlProgram(test::golden("xml/cell_program.xml"));
  EXPECT_EQ(writeXmlProgram(changed), hand);
  changed.motions[1].target.modified = true;
  const std::string once = writeXmlProgram(changed);
  EXPECT_NE(once, hand);
  EXPECT_EQ(writeXmlProgram(parseXmlProgram(once, "once.xml")), once);
  EXPECT_NE(once.find("<pose z_mm=\"45.2500\"/>"), std::string::npos) << once;
  EXPECT_NE(once.find("<tool source=\"unknown\" text=\"STOOL2(FX)\"/>"), std::string::npos) << once;
}

// Comments are the user's data: a compensated XML program keeps every comment of the input
// (inside <motions> where it was; before <motions> at their start, after it at their end), and a
// conversion writes them as comments of the other language, one per line.
TEST(XmlProgram, CommentsAreKeptWhenTheProgramChangesAndConvertedToKrlComments) {
  const std::string text =
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!-- from the OLP -->\n<program name=\"p\" version=\"1\">\n"
      "  <!-- cell 4 -->\n  <motions>\n    <tool source=\"inline\" x_mm=\"0\" y_mm=\"0\" z_mm=\"200\" a_deg=\"0\" b_deg=\"0\" c_deg=\"0\"/>\n"
      "    <base source=\"null\"/>\n    <!-- approach,\n         slowly -->\n"
      "    <lin vel_m_s=\"0.1\">\n      <pose x_mm=\"1000\" y_mm=\"0\" z_mm=\"800\" a_deg=\"0\" b_deg=\"90\" c_deg=\"0\"/>\n    </lin>\n"
      "    <!-- the seam -->\n"
      "    <lin vel_m_s=\"0.1\">\n      <!-- 100 mm -->\n      <pose x_mm=\"1000\" y_mm=\"100\" z_mm=\"800\" a_deg=\"0\" b_deg=\"90\" c_deg=\"0\"/>\n    </lin>\n"
      "  </motions>\n  <!-- end -->\n</program>\n";
  Program p = parseXmlProgram(text, "c.xml");
  ASSERT_EQ(p.motions.size(), 2u);
  EXPECT_EQ(writeXmlProgram(p), text);  // unchanged: the bytes as read
  p.motions[1].target.modified = true;
  const std::string out = writeXmlProgram(p);
  const std::vector<std::string> comments = {"<!-- from the OLP -->", "<!-- cell 4 -->", "<!-- approach,\n         slowly -->",
                                             "<!-- the seam -->", "<!-- 100 mm -->", "<!-- end -->"};
  size_t at = 0;
  for (const std::string& c : comments) {  // each one, in order
    const size_t found = out.find(c, at);
    ASSERT_NE(found, std::string::npos) << c << " in\n" << out;
    at = found + c.size();
  }
  // the seam's comment stays between the two motions, the end's after the last
  EXPECT_LT(out.find("<!-- the seam -->"), out.find("y_mm=\"100.0000\""));
  EXPECT_GT(out.find("<!-- the seam -->"), out.find("<lin"));
  EXPECT_GT(out.find("<!-- end -->"), out.rfind("</lin>"));
  EXPECT_EQ(writeXmlProgram(parseXmlProgram(out, "out.xml")), out);
  // into KRL: comment lines where the comments were
  const KrlText k = test::lf(writeKrl(withoutCarriedLines(p, "KRL")));
  for (const char* c : {"; from the OLP\n", "; cell 4\n", "; approach,\n", ";         slowly\n", "; the seam\n", "; end\n"})
    EXPECT_NE(k.src.find(c), std::string::npos) << c << " in\n" << k.src;
  EXPECT_LT(k.src.find("; the seam"), k.src.find("Y 100"));
  EXPECT_GT(k.src.find("; the seam"), k.src.find("LIN"));
  // a comment that reads like a KRL fold marker does not open a fold
  Program f = parseXmlProgram(std::string(text).replace(text.find("<!-- the seam -->"), 17, "<!--FOLD seam-->"), "f.xml");
  const KrlText kf = test::lf(writeKrl(withoutCarriedLines(f, "KRL")));
  EXPECT_NE(kf.src.find("; FOLD seam\n"), std::string::npos) << kf.src;
  EXPECT_EQ(kf.src.find(";FOLD seam"), std::string::npos) << kf.src;
  // into URScript too (it was refused: "the URScript statement '# approach,' is not a motion"),
  // where the comments were
  const std::string ur = writeUrScript(withoutCarriedLines(p, "URScript"));
  for (const char* c : {"\n  # from the OLP\n  # cell 4\n", "\n  # the seam\n  # 100 mm\n  movel(", "\n  # end\nend\n"})
    EXPECT_NE(ur.find(c), std::string::npos) << c << " in\n" << ur;
  // a comment line of one robot language is one of another: KRL ';' into RAPID '!' and URScript
  // '#' (a Latin-1 byte as UTF-8 in a script); a fold marker is not a comment
  const std::string dir = test::tempDir("xml_comments_across");
  test::writeText(dir + "/c.src", "DEF c( )\n; approach the part\n;FOLD PTP HOME\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE=$NULLFRAME\n"
                                  "PTP {A1 0,A2 -90,A3 90,A4 0,A5 45,A6 0}\n;ENDFOLD\n  ; Werkst\xFC" "ck 4711  \nEND\n");
  const Program krl = readKrl(dir + "/c.src");
  const std::string rapid = writeRapid(withoutCarriedLines(krl, "RAPID"));
  EXPECT_NE(rapid.find("\n    ! approach the part\n"), std::string::npos) << rapid;
  EXPECT_NE(rapid.find("\n    ! Werkst\xFC" "ck 4711\n  ENDPROC"), std::string::npos) << rapid;
  const std::string script = writeUrScript(withoutCarriedLines(krl, "URScript"));
  EXPECT_NE(script.find("\n  # approach the part\n  set_tcp("), std::string::npos) << script;
  EXPECT_NE(script.find("\n  # Werkst\xC3\xBC" "ck 4711\nend\n"), std::string::npos) << script;
  EXPECT_EQ(script.find("FOLD"), std::string::npos) << script;
  // RAPID '!' and URScript '#' comments the other way (they were dropped); an inline form's
  // parameter line is the editor's, not a comment
  test::writeText(dir + "/m.mod", "MODULE m\n  ! module comment\n  PERS tooldata t1:=[TRUE,[[0,0,150],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];\n"
                                  "  PROC main()\n    ! body comment\n    MoveL [[500,0,500],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]],v100,fine,t1;\n"
                                  "    ! last\n  ENDPROC\nENDMODULE\n");
  const Program mod = readProgram(dir + "/m.mod");
  const std::vector<calib::OutputFile> to_krl = renderProgram(mod, ProgramFormat::kKrl, dir + "/m.src", "");
  EXPECT_NE(to_krl[0].text.find("\r\n; body comment\r\n$TOOL="), std::string::npos) << to_krl[0].text;
  EXPECT_NE(to_krl[0].text.find("\r\n; last\r\nEND\r\n"), std::string::npos) << to_krl[0].text;
  const std::vector<calib::OutputFile> to_ur = renderProgram(mod, ProgramFormat::kUrScript, dir + "/m.script", "");
  EXPECT_NE(to_ur[0].text.find("\n  # body comment\n  set_tcp("), std::string::npos) << to_ur[0].text;
  test::writeText(dir + "/s.script", "def s():\n  # body comment\n  set_tcp(p[0,0,0.15,0,0,0])\n  movel(p[0.5,0,0.5,3.14159,0,0])\n  # last\nend\n");
  const Program ur_in = readProgram(dir + "/s.script");
  EXPECT_NE(renderProgram(ur_in, ProgramFormat::kRapid, dir + "/s.mod", "")[0].text.find("\n    ! body comment\n"), std::string::npos);
  EXPECT_NE(renderProgram(ur_in, ProgramFormat::kKrl, dir + "/s.src", "")[0].text.find("\r\n; last\r\nEND\r\n"), std::string::npos);
  PassThrough params;
  params.language = "KRL";
  params.text = ";Params IlfProvider=kukaroboter.basistech.inlineforms.movement.spline; Kuka.PointName=P1";
  EXPECT_FALSE(commentText(params));
  params.text = "  ; a note";
  EXPECT_EQ(commentText(params), std::optional<std::string>(" a note"));
  // the language XML is the comments' own: a <passthrough> of it is refused
  const std::string fake = std::string(text).replace(text.find("<!-- the seam -->"), 17,
                                                     "<passthrough language=\"XML\">--><ptp/><!--</passthrough>");
  EXPECT_THROW(parseXmlProgram(fake, "fake.xml"), calib::InputError);
}

// A point the data list declares GLOBAL is used by other modules by its name: through XML and
// back into KRL it stays GLOBAL (a $config.dat's point, the controller's own, is not declared
// GLOBAL again in the program's data list).
TEST(XmlProgram, AGlobalPointStaysGlobalThroughXml) {
  const std::string dir = test::tempDir("xml_global");
  // (the program assigns the $config.dat's XHOME a value of its own: still the controller's point)
  test::writeText(dir + "/pg.src", "DEF pg( )\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP XP1\nLIN XP2\n"
                                   "XHOME={A1 0,A2 -90,A3 90,A4 0,A5 30,A6 0}\nPTP XHOME\nEND\n");
  test::writeText(dir + "/pg.dat",
                  "DEFDAT pg PUBLIC\nDECL GLOBAL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0,S 2,T 2}\n"
                  "DECL E6POS XP2={X 1000,Y 100,Z 800,A 0,B 90,C 0,S 2,T 2}\nENDDAT\n");
  test::writeText(dir + "/config.dat", "DEFDAT $CONFIG\nDECL GLOBAL E6AXIS XHOME={A1 0,A2 -90,A3 90,A4 0,A5 45,A6 0}\nENDDAT\n");
  KrlReadOptions o;
  o.config_path = dir + "/config.dat";
  const Program k = readKrl(dir + "/pg.src", o);
  ASSERT_EQ(k.motions.size(), 3u);
  EXPECT_TRUE(k.motions[0].target.global);
  EXPECT_FALSE(k.motions[1].target.global);
  EXPECT_FALSE(k.motions[2].target.global);  // the $config.dat's
  const std::string xml = writeXmlProgram(k);
  EXPECT_NE(xml.find("<pose name=\"XP1\" type=\"E6POS\" global=\"true\""), std::string::npos) << xml;
  EXPECT_EQ(xml.find("name=\"XP2\" type=\"E6POS\" global"), std::string::npos) << xml;
  const Program x = parseXmlProgram(xml, "pg.xml");
  EXPECT_TRUE(x.motions[0].target.global);
  const KrlText back = test::lf(writeKrl(withoutCarriedLines(x, "KRL")));
  EXPECT_NE(back.dat.find("DEFDAT pg PUBLIC\n"), std::string::npos) << back.dat;
  EXPECT_NE(back.dat.find("\nDECL GLOBAL E6POS XP1={"), std::string::npos) << back.dat;
  EXPECT_NE(back.dat.find("\nDECL E6POS XP2={"), std::string::npos) << back.dat;
  // the $config.dat's XHOME is not declared in the program's data list, where it would hide
  // the controller's (the program's assignment of it travels as its statement)
  EXPECT_EQ(back.dat.find("XHOME"), std::string::npos) << back.dat;
  EXPECT_NE(back.src.find("\nXHOME={A1 0,A2 -90,A3 90,A4 0,A5 30,A6 0}\nPTP XHOME\n"), std::string::npos) << back.src;
  // the attribute is checked
  std::string bad = xml;
  bad.replace(bad.find("global=\"true\""), 13, "global=\"yes\"");
  try {
    parseXmlProgram(bad, "bad.xml");
    FAIL() << "expected an InputError";
  } catch (const calib::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("attribute 'global': expected true or false, found 'yes'"), std::string::npos) << e.what();
  }
}

TEST(XmlProgram, KrlToXmlToKrlKeepsTheMotions) {
  KrlReadOptions o;
  o.config_path = test::golden("krl/config/$config.dat");
  const Program krl = readKrl(test::golden("krl/kss8_inline/weld_seam.src"), o);
  const std::string xml = writeXmlProgram(krl);
  EXPECT_EQ(xml, test::readText(test::golden("xml/weld_seam.xml")));
  const Program back = parseXmlProgram(xml, "weld_seam.xml");
  ASSERT_EQ(back.motions.size(), krl.motions.size());
  for (size_t i = 0; i < krl.motions.size(); ++i) {
    const Motion& a = krl.motions[i];
    const Motion& b = back.motions[i];
    EXPECT_EQ(a.type, b.type) << i;
    EXPECT_EQ(a.target.name, b.target.name) << i;
    EXPECT_EQ(a.target.kind, b.target.kind) << i;
    for (int k = 0; k < 6; ++k) {
      EXPECT_EQ(a.target.pose[k].has_value(), b.target.pose[k].has_value()) << i;
      if (a.target.pose[k]) {
        EXPECT_NEAR(*a.target.pose[k], *b.target.pose[k], 0.5e-4) << i;  // 4-5 decimals
      }
      if (a.target.axes[k]) {
        EXPECT_NEAR(*a.target.axes[k], *b.target.axes[k], 0.5e-4) << i;
      }
    }
    EXPECT_EQ(a.target.status, b.target.status) << i;
    EXPECT_EQ(a.approximation, b.approximation) << i;
    EXPECT_EQ(a.tool.source, b.tool.source) << i;
    EXPECT_EQ(a.tool.index, b.tool.index) << i;
    EXPECT_EQ(a.base.index, b.base.index) << i;
  }
  // and to KRL again: a new .src/.dat with the same points
  const KrlText t = test::lf(writeKrl(back));
  EXPECT_NE(t.src.find("\nLIN XP2 C_DIS C_DIS\n"), std::string::npos) << t.src;
  EXPECT_NE(t.src.find("\nCIRC XP4, XP5\n"), std::string::npos) << t.src;
  EXPECT_NE(t.src.find("\n$TOOL=TOOL_DATA[1]\n"), std::string::npos) << t.src;
  EXPECT_NE(t.dat.find("DECL E6POS XP4={X 1260.5000,Y 70.2500,Z 612.7500,A 178.10001,B 29.90000,C -179.30000,S 2,T 11,"),
            std::string::npos)
      << t.dat;
}

// element -> attributes declared in the schema (attributes of the element's type, its
// attribute groups, resolved).
std::map<std::string, std::set<std::string>> schemaVocabulary(const std::string& path) {
  tinyxml2::XMLDocument doc;
  EXPECT_EQ(doc.LoadFile(path.c_str()), tinyxml2::XML_SUCCESS);
  const tinyxml2::XMLElement* schema = doc.RootElement();
  std::map<std::string, const tinyxml2::XMLElement*> types, groups;
  for (const auto* e = schema->FirstChildElement(); e; e = e->NextSiblingElement()) {
    const std::string n = e->Name();
    if (n == "xs:complexType") types[e->Attribute("name")] = e;
    if (n == "xs:attributeGroup") groups[e->Attribute("name")] = e;
  }
  std::function<void(const tinyxml2::XMLElement*, std::set<std::string>&)> attrs = [&](const tinyxml2::XMLElement* t,
                                                                                        std::set<std::string>& out) {
    for (const auto* c = t->FirstChildElement(); c; c = c->NextSiblingElement()) {
      const std::string n = c->Name();
      if (n == "xs:attribute") out.insert(c->Attribute("name"));
      if (n == "xs:attributeGroup") attrs(groups.at(c->Attribute("ref")), out);
      if (n == "xs:simpleContent" || n == "xs:extension") attrs(c, out);  // an element with text
    }
  };
  std::map<std::string, std::set<std::string>> v;
  std::function<void(const tinyxml2::XMLElement*)> walk = [&](const tinyxml2::XMLElement* e) {
    for (const auto* c = e->FirstChildElement(); c; c = c->NextSiblingElement()) {
      if (std::string(c->Name()) == "xs:element") {
        std::set<std::string>& out = v[c->Attribute("name")];
        if (c->Attribute("type")) {
          const tinyxml2::XMLElement* t = types.at(c->Attribute("type"));
          attrs(t, out);
          walk(t);
        } else if (const auto* ct = c->FirstChildElement("xs:complexType")) {
          attrs(ct, out);
          walk(ct);
        }
      } else {
        walk(c);
      }
    }
  };
  walk(schema);
  return v;
}

TEST(XmlProgram, TheSchemaFileDeclaresWhatTheReaderAccepts) {
  const auto schema = schemaVocabulary(test::sourcePath("postproc/schema/accura-program.xsd"));
  const auto& reader = xmlProgramVocabulary();
  EXPECT_EQ(schema.size(), reader.size());
  for (const auto& [element, attributes] : reader) {
    ASSERT_TRUE(schema.count(element)) << "<" << element << "> is not in the schema";
    EXPECT_EQ(schema.at(element), attributes) << "<" << element << ">";
  }
}

TEST(XmlProgram, ErrorsNameFileLineAndColumn) {
  struct Case {
    std::string body;  // inside <motions>
    int line, column;
    std::string message;
  };
  const std::string head = "<?xml version=\"1.0\"?>\n<program version=\"1\">\n  <motions>\n";
  const std::vector<Case> cases = {
      {"    <lin><pose x_mm=\"1\" y_mm=\"abc\"/></lin>\n", 4, 10, "<pose> attribute 'y_mm': expected a finite number, found 'abc'"},
      {"    <lin speed=\"1\"><pose x_mm=\"1\"/></lin>\n", 4, 5,
       "<lin>: unknown attribute 'speed' (expected one of: approx, approx_value, ca_deg, circ_type, conf_monitored, external_tcp, ori_type, relative, relative_frame, source_line, spline_block, spline_block_type, start_unknown, time_s, vel_m_s, vel_percent)"},
      {"    <move/>\n", 4, 5, "unknown element <move> in <motions> (expected tool, base, ptp, lin, circ, sptp, slin, scirc, spl, passthrough)"},
      {"    <lin/>\n", 4, 5, "<lin>: expected a target (<pose>, <axes> or <ref>), found nothing"},
      {"    <lin><axes a1=\"0\"/></lin>\n", 4, 10, "<lin>: expected a Cartesian target (<pose>), found <axes>"},
      {"    <circ><pose x_mm=\"1\"/></circ>\n", 4, 11, "<circ>: expected an <aux> (auxiliary point) first, found <pose>"},
      {"    <ptp><pose x_mm=\"1\" s=\"-1\"/></ptp>\n", 4, 10, "<pose> attribute 's': expected a non-negative integer, found '-1'"},
      {"    <tool source=\"inline\" x_mm=\"1\"/>\n", 4, 5,
       "<tool>: expected all of x_mm, y_mm, z_mm, a_deg, b_deg, c_deg or none, found 1 of them"},
      {"    <base source=\"data\"/>\n", 4, 5, "<base source=\"data\">: expected attribute 'index' >= 1"},
      {"    <lin approx=\"C_DIS FAST\"><pose x_mm=\"1\"/></lin>\n", 4, 5,
       "<lin> attribute 'approx': expected C_PTP, C_DIS, C_VEL, C_ORI or C_SPL, found 'FAST'"},
      {"    <ptp><pose/></ptp>\n", 4, 10, "<pose>: expected the target's values (a target declared elsewhere is a <ref name=\"..\"/>)"},
  };
  for (const Case& c : cases) {
    const std::string text = head + c.body + "  </motions>\n</program>\n";
    try {
      parseXmlProgram(text, "bad.xml");
      ADD_FAILURE() << "expected an InputError for " << c.body;
    } catch (const calib::InputError& e) {
      EXPECT_EQ(e.file(), "bad.xml");
      EXPECT_EQ(e.line(), c.line) << e.what();
      EXPECT_EQ(e.column(), c.column) << e.what();
      EXPECT_EQ(e.message(), c.message) << e.what();
    }
  }
  try {
    parseXmlProgram("<?xml version=\"1.0\"?>\n<program version=\"2\"><motions/></program>\n", "v.xml");
    ADD_FAILURE();
  } catch (const calib::InputError& e) {
    EXPECT_EQ(e.message(), "<program> attribute 'version': expected 1, found '2'");
    EXPECT_EQ(e.line(), 2);
  }
  try {
    parseXmlProgram("<?xml version=\"1.0\"?>\n<program version=\"1\">\n<motions>\n</program>\n", "m.xml");
    ADD_FAILURE();
  } catch (const calib::InputError& e) {
    EXPECT_NE(e.message().find("expected well-formed XML"), std::string::npos);
    EXPECT_EQ(e.line(), 3);  // tinyxml2 names the element left open
  }
}

// A linear move whose orientation turns by about 180 deg can be interpolated either way round:
// warned once per motion, naming it and its line, when the turn is within 2 deg of 180 deg
// (here 179 and 179.5 deg about the world z axis: warned; 170 deg: not).
TEST(XmlProgram, LinearMoveTurningAboutHalfATurnIsWarned) {
  auto pose = [](double a) {
    return "      <pose x_mm=\"1200\" y_mm=\"0\" z_mm=\"800\" a_deg=\"" + std::to_string(a) + "\" b_deg=\"0\" c_deg=\"180\"/>\n";
  };
  const std::string xml = "<?xml version=\"1.0\"?>\n<program version=\"1\">\n  <motions>\n"   // lines 1-3
                          "    <tool source=\"null\"/>\n    <base source=\"null\"/>\n"          // 4-5
                          "    <ptp>\n" + pose(0) + "    </ptp>\n"                              // 6-8
                          "    <lin>\n" + pose(179) + "    </lin>\n"                            // 9-11
                          "    <lin>\n" + pose(9) + "    </lin>\n"                              // 12-14
                          "    <lin>\n" + pose(-170.5) + "    </lin>\n"                         // 15-17
                          "  </motions>\n</program>\n";
  const Program p = parseXmlProgram(xml, "turn.xml");
  JobSettings s;
  s.calibrated = test::loadBundled("kuka_kr16");
  s.tol_mm = 0.05;
  const ProgramCompensation c = compensateProgramReport(p, s);
  std::vector<std::pair<int, std::string>> half;
  for (const ProgramIssue& w : c.report.warnings)
    if (w.message.find("within 2 deg of 180 deg") != std::string::npos) half.emplace_back(w.where.line, w.message);
  ASSERT_EQ(half.size(), 2u);
  EXPECT_EQ(half[0].first, 9);
  EXPECT_NE(half[0].second.find("lin to the inline target turns the tool's orientation by 179.0 deg"), std::string::npos) << half[0].second;
  EXPECT_EQ(half[1].first, 15);
  EXPECT_NE(half[1].second.find("by 179.5 deg"), std::string::npos) << half[1].second;
}

}  // namespace
}  // namespace accura::postproc
