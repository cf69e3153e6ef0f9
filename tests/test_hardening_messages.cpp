// Issue 14, messages: every robot-file and URDF error is FILE:LINE:COLUMN: expected ..., found
// ..., asserted to the letter; the column is computed here independently (the needle's
// occurrence on its line of the text written). The strict-contract fuzz findings (an empty XML
// document in every XML reader, a KRL aggregate with a component twice, a measurement outside
// the joint limits) are regression tests here, read from the fuzz corpus they were copied to;
// and absurd numbers in measurement files (denormal standard deviations, 1e308 positions) are
// rejected at the field.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "accura/calib/errors.h"
#include "accura/calib/import.h"
#include "accura/calib/measurements.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/urdf.h"
#include "accura/postproc/cell.h"
#include "accura/postproc/krl.h"
#include "accura/postproc/urscript.h"
#include "accura/postproc/xml_program.h"
#include "test_util.h"

namespace accura {
namespace {

/// One bad file: its text, where the error is (line, the text it starts at on that line, and
/// which occurrence of it: 0 = the first), and the message after "file:line:column: ".
struct Case {
  std::string text;
  int line;
  std::string at;
  std::string message;
  int nth = 0;
};

/// The column (1-based) of the nth occurrence of `needle` on line `line` of `text`.
int columnOf(const std::string& text, int line, const std::string& needle, int nth) {
  size_t start = 0;
  for (int l = 1; l < line; ++l) start = text.find('\n', start) + 1;
  const std::string l = text.substr(start, text.find('\n', start) - start);
  size_t p = l.find(needle);
  for (int k = 0; k < nth && p != std::string::npos; ++k) p = l.find(needle, p + 1);
  EXPECT_NE(p, std::string::npos) << "'" << needle << "' not on line " << line << ": " << l;
  return static_cast<int>(p) + 1;
}

template <class Read>
void expectErrors(const std::string& file_name, const std::vector<Case>& cases, Read read) {
  const std::string dir = test::tempDir("messages_" + file_name);
  for (const Case& c : cases) {
    const std::string path = dir + "/" + file_name;
    test::writeText(path, c.text);
    const std::string expected = path + ":" + std::to_string(c.line) + ":" +
                                 std::to_string(columnOf(c.text, c.line, c.at, c.nth)) + ": " + c.message;
    try {
      read(path);
      ADD_FAILURE() << "accepted:\n" << c.text;
    } catch (const calib::InputError& e) {
      EXPECT_EQ(std::string(e.what()), expected);
    }
  }
}

const std::string kHead =
    "<robot name=\"t\">\n"
    "  <base x_mm=\"0\" y_mm=\"0\" z_mm=\"0\" a_deg=\"0\" b_deg=\"0\" c_deg=\"0\"/>\n"
    "  <tool x_mm=\"0\" y_mm=\"0\" z_mm=\"0\" a_deg=\"0\" b_deg=\"0\" c_deg=\"0\"/>\n"
    "  <payload com_x_mm=\"0\" com_y_mm=\"0\" com_z_mm=\"0\"/>\n"
    "  <joints>\n";
const std::string kJoint =
    "    <joint name=\"j\" type=\"revolute\" a_mm=\"1\" alpha_deg=\"90\" d_mm=\"0\" theta0_deg=\"0\" direction=\"1\"\n"
    "           lower=\"-10\" upper=\"10\" mass_kg=\"1\" com_x_mm=\"0\" com_y_mm=\"0\" com_z_mm=\"0\"/>\n";
const std::string kTail = "  </joints>\n</robot>\n";

/// The valid robot file with `from` replaced by `to` (once).
std::string robot(const std::string& from, const std::string& to, const std::string& after_joints = "") {
  std::string t = kHead + kJoint + "  </joints>\n" + after_joints + "</robot>\n";
  const size_t p = t.find(from);
  EXPECT_NE(p, std::string::npos) << from;
  return t.replace(p, from.size(), to);
}

TEST(HardeningMessages, RobotFileErrorsCarryLineColumnExpectedFound) {
  const std::string cal = "  <calibration form=\"auto\">\n    <parameter name=\"j1_a\" value=\"1\" unit=\"mm\"/>\n  </calibration>\n";
  const std::vector<Case> cases = {
      {"", 1, "", "expected a robot file with root element <robot>, found an empty file"},
      {"  \n", 1, " ", "expected a robot file with root element <robot>, found only white space"},
      {"<!-- nothing -->\n", 1, "<", "expected a robot file with root element <robot>, found no element"},
      // a file that is not XML (a measurement CSV given as --robot): before, "expected well-formed
      // XML, found malformed text (an unescaped '<' or '&'?)"
      {"\n# KR 16, laser tracker\nq1,q2,q3,q4,q5,q6,x,y,z\n0,-90,90,0,45,0,1235.412,0.087,1410.236\n", 2, "#",
       "expected a robot file with root element <robot> (XML, which starts with '<'), found text that is not XML: '# KR 16, laser tracker'"},
      {kHead + "    <joint name=\"k\" a_mm=1/>\n" + kTail, 6, "<joint",
       "expected well-formed XML, found a malformed attribute (name=\"value\")"},
      // tinyxml2 names the element whose end tag does not match: <joints>
      {kHead + kJoint + "  </joint>\n</robot>\n", 5, "<joints", "expected well-formed XML, found an element whose end tag does not match its name"},
      {"<robo name=\"t\"/>\n", 1, "<robo", "expected root element <robot>, found <robo>"},
      {robot("<robot name=\"t\">", "<robot name=\"t\" colour=\"red\">"), 1, "colour=",
       "<robot>: expected one of the attributes name, source, found unknown attribute 'colour'"},
      {robot("<robot name=\"t\">", "<robot>"), 1, "<robot", "<robot>: expected an attribute 'name', found none"},
      {robot("  <payload", "  <gripper/>\n  <payload"), 4, "<gripper",
       "<robot>: expected one of the elements base, tool, payload, gravity, joints, calibration, found <gripper>"},
      {robot("  <tool x_mm", "  <tool/>\n  <tool x_mm"), 4, "<tool",
       "<robot>: expected one <tool> element, found a second one"},
      {robot("  <payload com_x_mm=\"0\" com_y_mm=\"0\" com_z_mm=\"0\"/>\n", ""), 1, "<robot",
       "<robot>: expected a <payload> element, found none"},
      {robot("y_mm=\"0\" z_mm=\"0\" a_deg=\"0\" b_deg=\"0\" c_deg=\"0\"/>\n  <tool", "y_mm=\" \" z_mm=\"0\" a_deg=\"0\" b_deg=\"0\" c_deg=\"0\"/>\n  <tool"),
       2, "y_mm=", "<base> attribute 'y_mm': expected a finite number, found ' '"},
      {robot("<tool x_mm=\"0\" y_mm=\"0\"", "<tool x_mm=\"0\" y_mm=\"-1e308\""), 3, "y_mm=",
       "<tool> attribute 'y_mm': expected a magnitude of at most 1e6, found '-1e308'"},
      {robot("com_y_mm=\"0\" com_z_mm=\"0\"/>\n  <joints>", "com_y_mm=\"nan\" com_z_mm=\"0\"/>\n  <joints>"), 4, "com_y_mm=",
       "<payload> attribute 'com_y_mm': expected a finite number, found 'nan'"},
      {robot("  <joints>\n", "  <joints count=\"1\">\n"), 5, "count=",
       "<joints>: expected no attributes, found unknown attribute 'count'"},
      {robot("<joint name=\"j\"", "<link name=\"j\""), 6, "<link", "<joints>: expected <joint>, found <link>"},
      {robot("type=\"revolute\"", "type=\"spherical\""), 6, "type=",
       "<joint> attribute 'type': expected 'revolute' or 'prismatic', found 'spherical'"},
      {robot("a_mm=\"1\"", "a_mm=\"1,5\""), 6, "a_mm=", "<joint> attribute 'a_mm': expected a finite number, found '1,5'"},
      {robot("d_mm=\"0\" ", ""), 6, "<joint", "<joint>: expected an attribute 'd_mm', found none"},
      {robot("direction=\"1\"", "direction=\"2\""), 6, "direction=", "<joint> attribute 'direction': expected 1 or -1, found '2'"},
      {robot("lower=\"-10\"", "lower=\"20\""), 7, "lower=", "<joint> 'j': expected lower < upper, found lower 20, upper 10"},
      {robot("upper=\"10\"", "upper=\"inf\""), 7, "upper=", "<joint> attribute 'upper': expected a finite number, found 'inf'"},
      {robot("lower=\"-10\"", "lower=\"-1e308\""), 7, "lower=", "<joint> attribute 'lower': expected a magnitude of at most 1e6, found '-1e308'"},
      {robot("mass_kg=\"1\"", "mass_kg=\"-1\""), 7, "mass_kg=", "<joint> attribute 'mass_kg': expected >= 0, found -1"},
      {robot("com_z_mm=\"0\"/>\n  </joints>", "com_z_mm=\"0\" colour=\"red\"/>\n  </joints>"), 7, "colour=",
       "<joint>: expected one of the attributes a_mm, alpha_deg, com_x_mm, com_y_mm, com_z_mm, d_mm, direction, lower, mass_kg, "
       "name, theta0_deg, type, upper, found unknown attribute 'colour'"},
      {kHead + kTail, 5, "<joints", "<joints>: expected at least one <joint>, found none"},
      {robot("", "", "  <calibration form=\"fine\"/>\n"), 9, "form=", "<calibration> attribute 'form': expected 'auto' or 'dh', found 'fine'"},
      {robot("", "", "  <calibration form=\"auto\">\n    <parameter name=\"j9_a\" value=\"1\" unit=\"mm\"/>\n  </calibration>\n"), 10, "name=",
       "<parameter> attribute 'name': expected a parameter of this robot and form 'auto', found unknown parameter name 'j9_a'"},
      {robot("", "", "  <calibration form=\"auto\">\n    <parameter name=\"j1_a\" value=\"1\" unit=\"deg\"/>\n  </calibration>\n"), 10, "unit=",
       "<parameter> 'j1_a': expected unit 'mm', found 'deg'"},
      {robot("", "", "  <calibration form=\"auto\">\n    <parameter name=\"j1_a\" value=\"1\" unit=\"mm\"/> <parameter name=\"j1_a\" value=\"2\" unit=\"mm\"/>\n  </calibration>\n"),
       10, "name=", "<calibration>: expected each parameter once, found 'j1_a' given twice", 1},
      {robot("", "", "  <calibration form=\"auto\">\n    <parameter name=\"j1_a\" value=\"1e309\" unit=\"mm\"/>\n  </calibration>\n"), 10, "value=",
       "<parameter> attribute 'value': expected a finite number, found '1e309'"},
      {robot("", "", "  <calibration form=\"auto\">\n    <spline/>\n  </calibration>\n"), 10, "<spline",
       "<calibration>: expected <parameter>, <joint_map> or <fit_range>, found <spline>"},
      {robot("", "", "  <calibration form=\"auto\">\n    <fit_range joint=\"2\" lower=\"0\" upper=\"1\" unit=\"deg\"/>\n  </calibration>\n"), 10, "joint=",
       "<fit_range> attribute 'joint': expected 1..1, found '2'"},
      {robot("", "", "  <calibration form=\"auto\">\n    <fit_range joint=\"1\" lower=\"0\" upper=\"1\" unit=\"mm\"/>\n  </calibration>\n"), 10, "unit=",
       "<fit_range> of joint 1: expected unit 'deg', found 'mm'"},
      {robot("", "", "  <calibration form=\"auto\">\n    <fit_range joint=\"1\" lower=\"0\" upper=\"1\" unit=\"deg\"/>\n"
                     "    <fit_range joint=\"1\" lower=\"0\" upper=\"2\" unit=\"deg\"/>\n  </calibration>\n"),
       11, "<fit_range", "<calibration>: expected one <fit_range> per joint, found a second one for joint 1"},
      {robot("", "", "  <calibration form=\"auto\">\n    <joint_map joint=\"1\" lower=\"0\" upper=\"1\" intervals=\"1\" taper=\"1\" unit=\"deg\">\n"
                     "      0 1 2 x3\n    </joint_map>\n  </calibration>\n"),
       11, "x3", "<joint_map> of joint 1: expected finite numbers of magnitude at most 1e6, found 'x3'"},
      {robot("", "", "  <calibration form=\"auto\">\n    <joint_map joint=\"1\" lower=\"0\" upper=\"1\" intervals=\"1\" taper=\"1\" unit=\"deg\">\n"
                     "      0 1 2\n    </joint_map>\n  </calibration>\n"),
       10, "<joint_map", "<joint_map> of joint 1: expected intervals + 3 = 4 values, found 3"},
      {robot("", "", "  <calibration form=\"auto\">\n    <joint_map joint=\"1\" lower=\"0\" upper=\"1\" intervals=\"0.5\" taper=\"1\" unit=\"deg\"/>\n  </calibration>\n"),
       10, "intervals=", "<joint_map> attribute 'intervals': expected an integer from 1 to 100000, found '0.5'"},
      {robot("", "", cal + "  <calibration form=\"auto\"/>\n"), 12, "<calibration", "<robot>: expected one <calibration> element, found a second one"},
  };
  expectErrors("robot.xml", cases, [](const std::string& p) { calib::readRobotFile(p); });
}

const std::string kUrdf =
    "<robot name=\"r\">\n"
    "  <link name=\"base\"/>\n"
    "  <link name=\"l1\">\n"
    "    <inertial><mass value=\"2\"/><inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial>\n"
    "  </link>\n"
    "  <joint name=\"j1\" type=\"revolute\">\n"
    "    <parent link=\"base\"/> <child link=\"l1\"/>\n"
    "    <origin xyz=\"0 0 0.5\" rpy=\"0 0 0\"/> <axis xyz=\"0 0 1\"/>\n"
    "    <limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/>\n"
    "  </joint>\n"
    "</robot>\n";

std::string urdf(const std::string& from, const std::string& to) {
  std::string t = kUrdf;
  const size_t p = t.find(from);
  EXPECT_NE(p, std::string::npos) << from;
  return t.replace(p, from.size(), to);
}

TEST(HardeningMessages, AFileEndingInsideAnElementSaysWhichIsOpen) {
  // a forgotten </robot> was "2:1: ... text that is not XML (outside the root element?)": the
  // error is at the end of the file and names the element left open and where it opened
  const std::string dir = test::tempDir("xml_unclosed");
  const auto messageOf = [&](const std::string& text) {
    test::writeText(dir + "/r.urdf", text);
    try {
      calib::readUrdfChain(dir + "/r.urdf");
    } catch (const calib::InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(messageOf(urdf("</robot>\n", "\n")), dir + "/r.urdf:10:11: expected well-formed XML, found the end of the file before "
                                                       "the element <robot> opened at 1:1 was closed (its end tag </robot> is missing)");
  // cut after the <limit> line: inside <joint> (6:3) inside <robot> (1:1); at the end of line 9
  const std::string cut = kUrdf.substr(0, kUrdf.find("  </joint>"));
  const int line9 = static_cast<int>(std::string("    <limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/>").size());
  EXPECT_EQ(messageOf(cut), dir + "/r.urdf:9:" + std::to_string(line9 + 1) +
                                ": expected well-formed XML, found the end of the file before the element <joint> opened at 6:3 was "
                                "closed (its end tag </joint> is missing, and then </robot> for <robot> at 1:1)");
  // cut inside a start tag
  EXPECT_EQ(messageOf(kUrdf.substr(0, kUrdf.find(" effort="))),
            dir + "/r.urdf:9:32: expected well-formed XML, found the end of the file inside the start tag <limit at 9:5 (its '>' is "
                  "missing, and then </joint> for <joint> at 6:3, </robot> for <robot> at 1:1)");
  // a mismatched end tag is still tinyxml2's message, at its line
  EXPECT_NE(messageOf(urdf("  </joint>\n", "  </joint>\n  </link>\n")).find("found an element whose end tag does not match its name"),
            std::string::npos);
  // an element after the root's end tag (a joint pasted after </robot>) was dropped silently
  EXPECT_EQ(messageOf(kUrdf + "  <joint name=\"tool0_joint\" type=\"fixed\"/>\n"),
            dir + "/r.urdf:" + std::to_string(1 + static_cast<int>(std::count(kUrdf.begin(), kUrdf.end(), '\n'))) +
                ":3: expected a URDF with root element <robot> and nothing after its end tag </robot>, found another element <joint>");
  // UTF-16 ("Unicode" in a Windows editor) is named, not read as bytes
  EXPECT_EQ(messageOf(std::string("\xFF\xFE<\0r\0", 6)),
            dir + "/r.urdf:1:1: expected a URDF with root element <robot> in UTF-8, found UTF-16 (byte-order mark FF FE): save it as UTF-8");
  // the robot file's reader shares it
  test::writeText(dir + "/r.xml", kHead + kJoint);
  try {
    calib::readRobotFile(dir + "/r.xml");
    ADD_FAILURE() << "accepted";
  } catch (const calib::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("found the end of the file before the element <joints> opened at 5:3 was closed (its end tag "
                                         "</joints> is missing, and then </robot> for <robot> at 1:1)"),
              std::string::npos) << e.what();
  }
}

TEST(HardeningMessages, UrdfErrorsCarryLineColumnExpectedFound) {
  // the valid URDF reads: one revolute joint, 500 mm up, limits in degrees
  {
    const std::string dir = test::tempDir("urdf_ok");
    test::writeText(dir + "/r.urdf", kUrdf);
    const calib::SerialChain chain = calib::readUrdfChain(dir + "/r.urdf");
    ASSERT_EQ(chain.joints.size(), 1u);
    EXPECT_NEAR(chain.joints[0].T_prev_joint.translation().z(), 500.0, 1e-12);  // mm
    EXPECT_NEAR(chain.joints[0].upper, 180.0 / 3.14159265358979323846, 1e-12);   // deg
  }
  const std::vector<Case> cases = {
      {"", 1, "", "expected a URDF with root element <robot>, found an empty file"},
      {urdf("<link name=\"l1\">", "<link name=\"l1\""), 3, "<link", "expected well-formed XML, found an element that is malformed or not closed"},
      {urdf("<robot name=\"r\">", "<robot>"), 1, "<robot", "<robot>: expected an attribute 'name', found none"},
      {urdf("<link name=\"l1\">", "<link name=\"base\">"), 3, "name=",
       "<link>: expected each link name once, found 'base' a second time (first at line 2)"},
      {urdf("<mass value=\"2\"/>", "<mass value=\"-2\"/>"), 4, "value=", "<mass> of link 'l1': expected 0 to 1e5 kg, found -2"},
      {urdf("ixy=\"0\"", "ixy=\"nan\""), 4, "ixy=", "<inertia> attribute 'ixy': expected a finite number, found 'nan'"},
      {urdf("type=\"revolute\"", "type=\"ball\""), 6, "type=",
       "joint 'j1' attribute 'type': expected revolute, continuous, prismatic, fixed, floating or planar, found 'ball'"},
      {urdf("<child link=\"l1\"/>", "<child link=\"l2\"/>"), 7, "link=", "joint 'j1': expected a declared link, found 'l2' (no <link name=\"l2\">)", 1},
      {urdf("<child link=\"l1\"/>", ""), 6, "<joint", "<joint name=\"j1\">: expected a <child> element, found none"},
      {urdf("<child link=\"l1\"/>", "<child link=\"l1\"/><child link=\"l1\"/>"), 7, "<child", "<joint>: expected one <child> element, found a second one", 1},
      {urdf("xyz=\"0 0 0.5\"", "xyz=\"0 0 1e308\""), 8, "xyz=",
       "<origin> attribute 'xyz': expected an offset of at most 100 m (URDF lengths are in metres), found 1e+308 m"},
      {urdf("rpy=\"0 0 0\"", "rpy=\"0 1e300 0\""), 8, "rpy=", "<origin> attribute 'rpy': expected angles of at most 1000 rad, found 1e+300 rad"},
      {urdf("xyz=\"0 0 0.5\"", "xyz=\"0 0\""), 8, "xyz=", "<origin> attribute 'xyz': expected three finite numbers, found '0 0'"},
      {urdf("<axis xyz=\"0 0 1\"/>", "<axis xyz=\"0 0 0\"/>"), 8, "xyz=", "joint 'j1' <axis> attribute 'xyz': expected a non-zero axis with components of at most 1e6, found '0 0 0'", 1},
      // the mutation campaign: urdfdom turned both into a joint without a direction (exit 3)
      {urdf("<axis xyz=\"0 0 1\"/>", "<axis xyz=\"0 1e308 1\"/>"), 8, "xyz=",
       "joint 'j1' <axis> attribute 'xyz': expected a non-zero axis with components of at most 1e6, found '0 1e308 1'", 1},
      {urdf("<axis xyz=\"0 0 1\"/>", "<axis xyzz=\"0 0 1\"/>"), 8, "<axis", "<axis>: expected an attribute 'xyz', found none"},
      {urdf("upper=\"1\"", "upper=\"1e308\""), 9, "upper=",
       "joint 'j1' <limit> attribute 'upper': expected radians (URDF limits are in rad: at most two turns, 12.566 rad, in magnitude), found '1e308'"},
      // degrees written into a URDF: +-170 "rad" were read as +-9740 deg
      {urdf("lower=\"-1\" upper=\"1\"", "lower=\"-170\" upper=\"170\""), 9, "lower=",
       "joint 'j1' <limit> attribute 'lower': expected radians (URDF limits are in rad: at most two turns, 12.566 rad, in magnitude), "
       "found '-170' (-9740.28 deg; degrees written as radians?)"},
      {urdf("lower=\"-1\"", "lower=\"2\""), 9, "lower=", "joint 'j1': <limit> expected lower < upper, found lower 2, upper 1"},
      {urdf(" effort=\"1\"", ""), 9, "<limit", "<limit>: expected an attribute 'effort', found none"},
      {urdf("<parent link=\"base\"/>", "<parent link=\"l1\"/>"), 7, "link=", "joint 'j1': expected a child link other than the parent, found 'l1' for both", 1},
      // the hour-long fuzz_urdf run: names urdfdom reads differently from the index (its model
      // then lacks the joint, and its null joint was dereferenced)
      {urdf("<joint name=\"j1\"", "<joint name=\"j&#10;1\""), 6, "name=",
       "<joint> attribute 'name': expected a name of UTF-8 text without control characters, found 'j\\x0A1'"},
      {urdf("<joint name=\"j1\"", "<joint name=\"j\xFF" "1\""), 6, "name=",
       "<joint> attribute 'name': expected a name of UTF-8 text without control characters, found 'j\\xFF1'"},
      {urdf("<joint name=\"j1\"", "<joint name=\"j&1\""), 6, "name=",
       "joint 'j&1': expected urdfdom (the URDF reader) to find this joint too, found it missing from its model: the two XML readers "
       "read its name differently (a bare '&' or a character reference in it?); write the name in plain characters"},
  };
  expectErrors("r.urdf", cases, [](const std::string& p) { calib::readUrdfChain(p); });
  {  // two turns (12.5 rad, 716 deg) are still radians: a joint of +-2 turns reads
    const std::string dir = test::tempDir("urdf_two_turns");
    test::writeText(dir + "/r.urdf", urdf("lower=\"-1\" upper=\"1\"", "lower=\"-12.5\" upper=\"12.5\""));
    EXPECT_NEAR(calib::readUrdfChain(dir + "/r.urdf").joints[0].upper, 12.5 * 180 / 3.14159265358979323846, 1e-9);
  }
  // fuzz_urdf found a hang: two links in a closed loop of joints beside the tree (each has a
  // parent, so the root count is 1, and the walks below the root never ended)
  const std::string loop = urdf("</robot>", "  <link name=\"l2\"/> <link name=\"l3\"/>\n"
                                           "  <joint name=\"j2\" type=\"fixed\"><parent link=\"l2\"/><child link=\"l3\"/></joint>\n"
                                           "  <joint name=\"j3\" type=\"fixed\"><parent link=\"l3\"/><child link=\"l2\"/></joint>\n</robot>");
  expectErrors("loop.urdf", {{loop, 13, "<joint",
                              "joint 'j3' closes a loop: expected every link below the root link 'base', found link 'l2' in a closed loop of joints"}},
               [](const std::string& p) { calib::readUrdfChain(p); });
  const std::string finding = test::readText(test::sourcePath("fuzz/corpus/urdf/finding_loop_beside_tree"));
  ASSERT_FALSE(finding.empty());
  try {
    calib::parseUrdfChain(finding, "f.urdf");
    ADD_FAILURE() << "read";
  } catch (const calib::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("closes a loop: expected every link below the root link 'base_link'"), std::string::npos) << e.what();
  }
}

/// The strict-contract findings of fuzz/findings/ (now in the corpus): each is an error with
/// line, column, expected and found.
TEST(HardeningMessages, FuzzFindingsGiveLocatedExpectedFound) {
  const auto expectStrict = [](const calib::InputError& e, const std::string& what_ends) {
    EXPECT_GE(e.line(), 1) << e.what();
    EXPECT_GE(e.column(), 1) << e.what();
    EXPECT_NE(e.message().find("expected"), std::string::npos) << e.what();
    const std::string what = e.what();
    ASSERT_GE(what.size(), what_ends.size()) << what;
    EXPECT_EQ(what.substr(what.size() - what_ends.size()), what_ends);
  };
  try {
    postproc::parseXmlProgram("", "empty.xml");
    ADD_FAILURE() << "an empty XML program read";
  } catch (const calib::InputError& e) {
    expectStrict(e, "empty.xml:1:1: expected an XML program with root element <program>, found an empty file");
  }
  // fuzz_xml_program: white space after '<' (tinyxml2 reads "< to" as the element <to>) is at
  // the '<', not at column 0
  try {
    postproc::parseXmlProgram("<program version=\"1\">\n  <motions>\n    < to/>\n  </motions>\n</program>\n", "p.xml");
    ADD_FAILURE() << "read";
  } catch (const calib::InputError& e) {
    expectStrict(e, "p.xml:3:5: unknown element <to> in <motions> (expected tool, base, ptp, lin, circ, sptp, slin, scirc, spl, passthrough)");
  }
  const std::string dir = test::tempDir("messages_findings");
  test::writeText(dir + "/empty.xml", "");
  try {
    postproc::readCellFile(dir + "/empty.xml");
    ADD_FAILURE() << "an empty cell file read";
  } catch (const calib::InputError& e) {
    expectStrict(e, "empty.xml:1:1: expected a cell file with root element <cell>, found an empty file");
  }
  // the KRL aggregate with E4 twice ($config.dat line 6), from the fuzz corpus
  const std::string config = test::readText(test::sourcePath("fuzz/corpus/krl_config/finding_component_twice"));
  ASSERT_FALSE(config.empty());
  test::writeText(dir + "/$config.dat", config);
  try {
    postproc::readKrlFrameTables(dir + "/$config.dat");
    ADD_FAILURE() << "a component given twice read";
  } catch (const calib::InputError& e) {
    const size_t line6 = [&] {
      size_t s = 0;
      for (int l = 1; l < 6; ++l) s = config.find('\n', s) + 1;
      return s;
    }();
    const int column = static_cast<int>(config.find("E4 0.0,E4", line6) + 7 - line6) + 1;  // the second E4
    expectStrict(e, "$config.dat:6:" + std::to_string(column) +
                        ": expected each component once in this aggregate, found E4 a second time");
  }
}

/// The two findings fuzz/run.sh used to tolerate (FUZZ_LENIENT): a mesh without faces, which
/// assimp rejected as a whole file ("Mesh contains no faces", no line), and a mapped export whose
/// header names a column twice (no "expected"). Each is now located by accura's own checks.
TEST(HardeningMessages, MeshesWithoutFacesAndRepeatedColumnNamesAreLocated) {
  const std::string dir = test::tempDir("messages_faces");
  struct MeshCase {
    const char* name;
    std::string bytes;
    const char* what_ends;
  };
  const std::string ply_head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
  std::string stl_binary(84, '\0');  // header and a triangle count of 0
  const std::vector<MeshCase> cases = {
      // the finding: the face's index list is not named vertex_indices, so assimp reads no face
      {"noindices.ply", ply_head + "element face 1\nproperty list uchar int vert_x_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
       "noindices.ply:7:1: element 'face': expected a property list of vertex indices (property list uchar int vertex_indices), found none"},
      {"noface.ply", ply_head + "end_header\n0 0 0\n1 0 0\n0 1 0\n",
       "noface.ply:1:1: expected an element 'face' in the PLY header (a mesh of faces), found none"},
      {"zero.ply", ply_head + "element face 0\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n",
       "zero.ply:7:1: element 'face': expected at least one face, found 0"},
      {"empty.stl", "solid s\nendsolid s\n", "empty.stl:2:1: expected at least one 'facet', found 'endsolid' with none before it"},
      // found by fuzz_mesh: a NUL in a comment made assimp's OBJ parser misread the faces after it
      {"nul.obj", std::string("# plate \x07\0\0 x\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", 46), "nul.obj:1:9: expected text, found the control byte 0x07"},
      // found by fuzz_mesh: w = 0 in "v x y z w" (assimp divides by it and rejects the whole file)
      {"w0.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0 0\nf 1 2 3\n", "w0.obj:3:9: expected a non-zero homogeneous w (the vertex is x/w, y/w, z/w), found '0'"},
      // found by fuzz_mesh: a carriage return alone ends a line for assimp, so the faces after it were misread
      {"cr.ply", ply_head + "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 \r0 0\n0 1 0\n3 0 1 2\n",
       "cr.ply:11:3: expected a line feed after the carriage return (CRLF line ends), found a carriage return alone"},
      // found by fuzz_mesh: assimp does not count '.2' as a vertex component, and the faces then point past the vertices
      {"dot.obj", "v 0 0 0\nv .2 0 0\nv 0 1 0\nf 1 2 3\n", "dot.obj:2:3: expected a number starting with a digit or a sign (write '0.5', not '.5'), found '.2'"},
      // found by fuzz_mesh: assimp does not take a vertical tab for a separator
      {"vt.obj", "v 0 0 0\nv 1 0 0\nv 0\v1 0\nf 1 2 3\n", "vt.obj:3:4: expected text, found the control byte 0x0B"},
      // found by fuzz_mesh: assimp reads a vertex's coordinates on its line only
      {"split.stl", "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0\n0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid s\n",
       "split.stl:4:11: expected the 3 coordinates of a vertex on its line, found the end of the line"},
      {"vt.stl", "solid s\nfacet normal 0 0 1\nouter loop\nvertex \v0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid s\n",
       "vt.stl:4:8: expected text, found the control byte 0x0B"},
      // found by fuzz_mesh: assimp skips an indented OBJ line, and the faces then pointed past the vertices
      {"indent.obj", "v 0 0 0\n v 1 0 0\nv 0 1 0\nf 1 2 3\n",
       "indent.obj:2:2: expected the statement 'v' at the start of its line (an indented line is skipped by the mesh reader), found it at column 2"},
      {"points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\np 1 2 3\n",
       "points.obj:5:1: expected at least one face ('f' with 3 or more vertex references), found none before the end of the file"},
  };
  for (const auto& c : cases) {
    test::writeText(dir + "/" + c.name, c.bytes);
    try {
      (void)postproc::loadMesh(dir + "/" + c.name, 1.0);
      ADD_FAILURE() << c.name << " read";
    } catch (const calib::InputError& e) {
      const std::string what = e.what();
      ASSERT_GE(what.size(), std::string(c.what_ends).size()) << what;
      EXPECT_EQ(what.substr(what.size() - std::string(c.what_ends).size()), c.what_ends);
    }
  }
  test::writeText(dir + "/binary.stl", stl_binary);
  try {
    (void)postproc::loadMesh(dir + "/binary.stl", 1.0);
    ADD_FAILURE() << "an STL of no triangles read";
  } catch (const calib::InputError& e) {
    EXPECT_EQ(e.message(), "at byte 80: expected at least one triangle, found a count of 0");
  }
  // a mapped export naming a column twice: at the second one (field 3 of the header line)
  const calib::RobotModel robot = calib::readRobotFile(calib::resolveRobotPath("ur10"));
  test::writeText(dir + "/e.map", "delimiter = ;\ndecimal = .\njoints = a, b, c, d, e, f\njoint_unit = deg\nposition = x, y, z\nposition_unit = mm\n");
  test::writeText(dir + "/e.csv", "a;b;A;c;d;e;f;x;y;z\n");
  try {
    const calib::MeasurementMapping mapping = calib::readMeasurementMapping(dir + "/e.map", robot.nominal);
    (void)calib::readMappedMeasurements(dir + "/e.csv", mapping, robot.nominal);
    ADD_FAILURE() << "a header naming a column twice read";
  } catch (const calib::InputError& e) {
    EXPECT_EQ(e.line(), 1);
    EXPECT_EQ(e.column(), 3);
    EXPECT_EQ(e.message(), "expected each column name once in the header, found 'A' a second time (first as column 1)");
  }
}

/// Found by the mutation campaign (fuzz/mutate.py): a NUL byte inside a KRL line is reported at
/// its line and column.
TEST(HardeningMessages, KrlNulByteAtItsColumn) {
  const std::string dir = test::tempDir("messages_krl_nul");
  test::writeText(dir + "/p.src", std::string("DEF p( )\nLIN {X\0 1}\nEND\n", 24));
  test::writeText(dir + "/p.dat", "DEFDAT p\nENDDAT\n");
  try {
    postproc::readKrl(dir + "/p.src");
    ADD_FAILURE() << "read";
  } catch (const calib::InputError& e) {
    EXPECT_EQ(std::string(e.what()), dir + "/p.src:2:7: expected a KRL text file, found a NUL byte (binary file?)");
  }
}

/// The measurement finding: a joint value outside the limits says what was expected, at the
/// field's column (the measurement format numbers the fields of a line from 1).
TEST(HardeningMessages, MeasurementValuesOutsideTheirRangesAreRejectedAtTheField) {
  const calib::RobotModel kr16 = test::loadBundled("kuka_kr16");
  const std::string dir = test::tempDir("messages_measurements");
  const std::string path = dir + "/m.csv";
  const std::string finding = test::readText(test::sourcePath("fuzz/corpus/measurements/finding_joint_limit"));
  ASSERT_FALSE(finding.empty());
  test::writeText(path, finding);
  try {
    calib::readMeasurementsCsv(path, kr16.nominal);
    ADD_FAILURE() << "read";
  } catch (const calib::InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              path + ":4:1: column 'q1': expected a joint value within the joint limits [-185, 185] deg, found -521.919078 deg");
  }
  const std::string header = "q1,q2,q3,q4,q5,q6,x,y,z,std_mm,weight\n";
  const std::string row = "0,-90,90,0,45,0,1000,0,1500,0.02,1\n";
  struct Bad {
    std::string row;
    int field;
    std::string message;
  };
  const std::vector<Bad> bad = {
      {"0,-90,90,0,45,0,1e308,0,1500,0.02,1\n", 7, "column 'x': expected a position within +-1e+07 mm, found '1e308'"},
      {"0,-90,90,0,45,0,1000,0,1500,1e-300,1\n", 10, "column 'std_mm': expected a standard deviation from 1e-06 to 1e+06, found '1e-300'"},
      {"0,-90,90,0,45,0,1000,0,1500,0.02,1e300\n", 11, "column 'weight': expected a weight from 1e-12 to 1e+12, found '1e300'"},
      {"0,-90,90,0,45,0,1000,0,1500,0.02\n", 11, "expected 11 fields as in the header, found 10"},
      {"0,-90,90,0,45,0,1000,0,1500,0.02,1,7\n", 12, "expected 11 fields as in the header, found 12"},
  };
  for (const Bad& b : bad) {
    test::writeText(path, header + row + b.row);
    try {
      calib::readMeasurementsCsv(path, kr16.nominal);
      ADD_FAILURE() << "read: " << b.row;
    } catch (const calib::InputError& e) {
      EXPECT_EQ(std::string(e.what()), path + ":3:" + std::to_string(b.field) + ": " + b.message);
    }
  }
  // the same file without the bad row reads, with the weight and std given
  test::writeText(path, header + row);
  const calib::MeasurementSet ok = calib::readMeasurementsCsv(path, kr16.nominal);
  ASSERT_EQ(ok.rows.size(), 1u);
  EXPECT_EQ(ok.rows[0].std_mm.x(), 0.02);
  test::writeText(path, header);
  try {
    calib::readMeasurementsCsv(path, kr16.nominal);
    ADD_FAILURE() << "a header alone read";
  } catch (const calib::InputError& e) {
    EXPECT_EQ(std::string(e.what()), path + ":1:1: expected at least one data row after the header, found none");
  }
}

}  // namespace
/// Found by strict fuzzing of the readers issue 12 added to: `set_tcp()` without its pose (the
/// message read past the empty argument list) and an XML motion with `approx_value` alone.
TEST(HardeningMessages, ProgramFuzzFindingsSayWhatWasExpected) {
  try {
    (void)postproc::parseUrScript("def p():\n  set_tcp()\nend\n", "p.script");
    ADD_FAILURE() << "set_tcp() read";
  } catch (const calib::InputError& e) {
    EXPECT_EQ(e.line(), 2);
    EXPECT_EQ(e.message(), "expected set_tcp(pose) with 1 argument, found 0");
  }
  const std::string xml =
      "<?xml version=\"1.0\"?>\n<program name=\"p\" version=\"1\">\n  <motions>\n"
      "    <ptp vel_percent=\"10\" approx_value=\"5\">\n"
      "      <axes a1=\"0\" a2=\"-90\" a3=\"90\" a4=\"0\" a5=\"0\" a6=\"0\"/>\n    </ptp>\n  </motions>\n</program>\n";
  try {
    (void)postproc::parseXmlProgram(xml, "p.xml");
    ADD_FAILURE() << "approx_value without approx read";
  } catch (const calib::InputError& e) {
    EXPECT_EQ(e.line(), 4);
    EXPECT_EQ(e.message(), "<ptp>: expected the attribute 'approx' with 'approx_value', found none");
  }
  // the hour-long fuzz_xml_program run: a program name holding a CR (&#13;) was written back raw
  // and read again as a LF (an XML reader normalises line ends), so the round trip changed it;
  // bytes that are not UTF-8 alike. Free-text attributes are UTF-8 without control characters.
  for (const auto& [attr, shown] : {std::pair<std::string, std::string>{"p&#13;q", "p\\x0Dq"}, {"p\xFF" "q", "p\\xFFq"}}) {
    std::string bad = xml;
    bad.replace(bad.find("approx_value=\"5\""), 16, "");
    bad.replace(bad.find("name=\"p\""), 8, "name=\"" + attr + "\"");
    try {
      (void)postproc::parseXmlProgram(bad, "p.xml");
      ADD_FAILURE() << "read: " << attr;
    } catch (const calib::InputError& e) {
      EXPECT_EQ(e.line(), 2);
      EXPECT_EQ(e.message(), "<program> attribute 'name': expected UTF-8 text without control characters, found '" + shown + "'");
    }
  }
}

}  // namespace accura
