#include <gtest/gtest.h>

#include <random>
#include <system_error>
#include <tuple>

#include "accura/calib/errors.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/robot_io.h"
#include "test_util.h"

namespace accura::calib {
namespace {

TEST(RobotIo, BundledRobotsLoad) {
  const auto names = bundledRobotNames();
  for (const char* n : {"abb_irb120", "kuka_kr16", "scara", "ur10"})
    EXPECT_NE(std::find(names.begin(), names.end(), n), names.end()) << n;
  const RobotModel kr16 = test::loadBundled("kuka_kr16");
  ASSERT_EQ(kr16.dof(), 6);
  EXPECT_EQ(kr16.nominal.joints[0].direction, -1);
  EXPECT_DOUBLE_EQ(kr16.nominal.joints[1].lower, -155);
  EXPECT_DOUBLE_EQ(kr16.nominal.joints[0].mass_kg, 80);
  EXPECT_DOUBLE_EQ(kr16.nominal.payload_com_mm.z(), 100);
  EXPECT_EQ(kr16.forms[1], LinkForm::kHayati);  // A2-A3 parallel
  EXPECT_EQ(kr16.forms[0], LinkForm::kDH);
  const RobotModel scara = test::loadBundled("scara");
  bool prismatic = false;
  for (const auto& j : scara.nominal.joints) prismatic |= j.type == JointType::kPrismatic;
  EXPECT_TRUE(prismatic);
}

TEST(RobotIo, CalibratedModelRoundTrip) {
  RobotModel m = test::loadBundled("ur10");
  std::mt19937_64 rng(4);
  std::normal_distribution<double> n(0, 1);
  for (const ParamInfo& p : parameterLayout(m)) setParameter(m.deviations, p, 1e-3 * n(rng) * (p.unit == "mm" ? 100 : 1));
  const std::string dir = test::tempDir("robot_io");
  const std::string path = dir + "/cal.xml";
  writeRobotFile(path, m, {}, "test -- comment");
  const RobotModel back = readRobotFile(path);
  for (double q : {0.0, 30.0, -75.0}) {
    const Eigen::VectorXd qv = Eigen::VectorXd::Constant(6, q);
    EXPECT_LT((forwardKinematics(m, qv).matrix() - forwardKinematics(back, qv).matrix()).cwiseAbs().maxCoeff(), 1e-8);
  }
  // written twice: byte-identical (deterministic output)
  writeRobotFile(dir + "/cal2.xml", back, {}, "test -- comment");
  EXPECT_EQ(test::readText(path), test::readText(dir + "/cal2.xml"));
  for (const auto& e : std::filesystem::directory_iterator(dir))  // no temporary file left behind
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
}

void expectRobotError(const std::string& name, const std::string& xml, int line, const std::string& words) {
  const std::string dir = test::tempDir("robot_bad");
  const std::string path = dir + "/" + name + ".xml";
  test::writeText(path, xml);
  try {
    readRobotFile(path);
    FAIL() << "expected InputError for " << name;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
  }
}

const char* kHead =
    "<robot name=\"t\">\n"
    "  <base x_mm=\"0\" y_mm=\"0\" z_mm=\"0\" a_deg=\"0\" b_deg=\"0\" c_deg=\"0\"/>\n"
    "  <tool x_mm=\"0\" y_mm=\"0\" z_mm=\"0\" a_deg=\"0\" b_deg=\"0\" c_deg=\"0\"/>\n"
    "  <payload com_x_mm=\"0\" com_y_mm=\"0\" com_z_mm=\"0\"/>\n"
    "  <joints>\n";

TEST(RobotIo, BadFilesGiveFileLineAndWhat) {
  const std::string good_joint =
      "    <joint name=\"j\" type=\"revolute\" a_mm=\"1\" alpha_deg=\"90\" d_mm=\"0\" theta0_deg=\"0\" direction=\"1\" "
      "lower=\"-10\" upper=\"10\" mass_kg=\"1\" com_x_mm=\"0\" com_y_mm=\"0\" com_z_mm=\"0\"/>\n";
  expectRobotError("unknown_attr", std::string(kHead) +
                       "    <joint name=\"j\" type=\"revolute\" a_mm=\"1\" alpha_deg=\"90\" d_mm=\"0\" theta0_deg=\"0\" direction=\"1\" "
                       "lower=\"-10\" upper=\"10\" mass_kg=\"1\" com_x_mm=\"0\" com_y_mm=\"0\" com_z_mm=\"0\" colour=\"red\"/>\n"
                       "  </joints>\n</robot>\n",
                   6, "unknown attribute 'colour'");
  expectRobotError("bad_number", std::string(kHead) +
                       "    <joint name=\"j\" type=\"revolute\" a_mm=\"1,5\" alpha_deg=\"90\" d_mm=\"0\" theta0_deg=\"0\" direction=\"1\" "
                       "lower=\"-10\" upper=\"10\" mass_kg=\"1\" com_x_mm=\"0\" com_y_mm=\"0\" com_z_mm=\"0\"/>\n"
                       "  </joints>\n</robot>\n",
                   6, "'a_mm': expected a finite number, found '1,5'");
  // hexadecimal (which strtod would read as 680) is not a number of the format
  expectRobotError("hex_number", std::string(kHead) +
                       "    <joint name=\"j\" type=\"revolute\" a_mm=\"0x2A8\" alpha_deg=\"90\" d_mm=\"0\" theta0_deg=\"0\" direction=\"1\" "
                       "lower=\"-10\" upper=\"10\" mass_kg=\"1\" com_x_mm=\"0\" com_y_mm=\"0\" com_z_mm=\"0\"/>\n"
                       "  </joints>\n</robot>\n",
                   6, "'a_mm': expected a finite number, found '0x2A8'");
  // two joints of one name
  expectRobotError("same_name", std::string(kHead) + good_joint + good_joint + "  </joints>\n</robot>\n", 7,
                   "<joint>: expected a name of its own, found 'j', the name of joint 1");
  expectRobotError("bad_direction", std::string(kHead) +
                       "    <joint name=\"j\" type=\"revolute\" a_mm=\"1\" alpha_deg=\"90\" d_mm=\"0\" theta0_deg=\"0\" direction=\"2\" "
                       "lower=\"-10\" upper=\"10\" mass_kg=\"1\" com_x_mm=\"0\" com_y_mm=\"0\" com_z_mm=\"0\"/>\n"
                       "  </joints>\n</robot>\n",
                   6, "expected 1 or -1, found '2'");
  expectRobotError("limits", std::string(kHead) +
                       "    <joint name=\"j\" type=\"revolute\" a_mm=\"1\" alpha_deg=\"90\" d_mm=\"0\" theta0_deg=\"0\" direction=\"1\" "
                       "lower=\"10\" upper=\"-10\" mass_kg=\"1\" com_x_mm=\"0\" com_y_mm=\"0\" com_z_mm=\"0\"/>\n"
                       "  </joints>\n</robot>\n",
                   6, "expected lower < upper");
  expectRobotError("missing", std::string(kHead) +
                       "    <joint name=\"j\" type=\"revolute\" a_mm=\"1\" alpha_deg=\"90\" theta0_deg=\"0\" direction=\"1\" "
                       "lower=\"-10\" upper=\"10\" mass_kg=\"1\" com_x_mm=\"0\" com_y_mm=\"0\" com_z_mm=\"0\"/>\n"
                       "  </joints>\n</robot>\n",
                   6, "expected an attribute 'd_mm', found none");
  expectRobotError("malformed", std::string(kHead) + good_joint + "    <joint name=\"k\" a_mm=1/>\n  </joints>\n</robot>\n", 7,
                   "expected well-formed XML");
  expectRobotError("unknown_param", std::string(kHead) + good_joint +
                       "  </joints>\n  <calibration form=\"auto\">\n    <parameter name=\"j9_a\" value=\"1\" unit=\"mm\"/>\n"
                       "  </calibration>\n</robot>\n",
                   9, "unknown parameter name 'j9_a'");
  expectRobotError("wrong_unit", std::string(kHead) + good_joint +
                       "  </joints>\n  <calibration form=\"auto\">\n    <parameter name=\"j1_a\" value=\"1\" unit=\"deg\"/>\n"
                       "  </calibration>\n</robot>\n",
                   9, "expected unit 'mm', found 'deg'");
}

// What an element holds besides its attributes is never ignored: a child element where the
// format has none (a <limit> inside a <joint>, written as in a URDF) and text (a value put
// between the tags) are errors at the child's '<' or at the text.
TEST(RobotIo, ChildrenAndTextWhereTheFormatHasNoneAreErrors) {
  const std::string joint_attrs =
      "name=\"j\" type=\"revolute\" a_mm=\"1\" alpha_deg=\"90\" d_mm=\"0\" theta0_deg=\"0\" direction=\"1\" "
      "lower=\"-10\" upper=\"10\" mass_kg=\"1\" com_x_mm=\"0\" com_y_mm=\"0\" com_z_mm=\"0\"";
  const std::string joint = "    <joint " + joint_attrs + "/>\n";
  const std::string tail = "  </joints>\n</robot>\n";
  struct Case {
    std::string name, xml;
    int line;
    std::string line_text, at, says;
  };
  const std::string limit_line = "    <joint " + joint_attrs + "><limit lower=\"-5\" upper=\"5\"/></joint>";
  const std::string base_line = "  <base x_mm=\"0\" y_mm=\"0\" z_mm=\"0\" a_deg=\"0\" b_deg=\"0\" c_deg=\"0\">500</base>";
  const std::string param_line = "    <parameter name=\"j1_a\" value=\"1\" unit=\"mm\">0.5</parameter>";
  const std::string range_line = "    <fit_range joint=\"1\" lower=\"-5\" upper=\"5\" unit=\"deg\"><note/></fit_range>";
  std::string head_with_text_base = kHead;
  head_with_text_base.replace(head_with_text_base.find("  <base"), head_with_text_base.find("\n", head_with_text_base.find("  <base")) -
                                                                        head_with_text_base.find("  <base"), base_line);
  const std::vector<Case> cases = {
      {"joint_child", std::string(kHead) + limit_line + "\n" + tail, 6, limit_line, "<limit", "<joint>: expected no child elements, found <limit>"},
      {"base_text", head_with_text_base + joint + tail, 2, base_line, "500", "<base>: expected no text, found '500'"},
      {"joints_text", std::string(kHead) + "    A1\n" + joint + tail, 6, "    A1", "A1", "<joints>: expected no text, found 'A1'"},
      {"param_text", std::string(kHead) + joint + "  </joints>\n  <calibration form=\"auto\">\n" + param_line + "\n  </calibration>\n</robot>\n", 9,
       param_line, "0.5", "<parameter>: expected no text, found '0.5'"},
      {"range_child", std::string(kHead) + joint + "  </joints>\n  <calibration form=\"auto\">\n" + range_line + "\n  </calibration>\n</robot>\n", 9,
       range_line, "<note", "<fit_range>: expected no child elements, found <note>"},
      {"robot_text", std::string(kHead) + joint + "  </joints>\n  end\n</robot>\n", 8, "  end", "end", "<robot>: expected no text, found 'end'"},
  };
  for (const Case& c : cases) {
    const std::string path = test::tempDir("robot_content") + "/" + c.name + ".xml";
    test::writeText(path, c.xml);
    try {
      readRobotFile(path);
      ADD_FAILURE() << "accepted: " << c.name;
    } catch (const InputError& e) {
      const int column = static_cast<int>(c.line_text.find(c.at)) + 1;
      EXPECT_EQ(std::string(e.what()), path + ":" + std::to_string(c.line) + ":" + std::to_string(column) + ": " + c.says) << c.name;
    }
  }
  // comments are no content
  const std::string path = test::tempDir("robot_content") + "/comment.xml";
  test::writeText(path, std::string(kHead) + "    <!-- the first axis -->\n    <joint " + joint_attrs + "><!-- A1 --></joint>\n" + tail);
  EXPECT_EQ(readRobotFile(path).nominal.joints.at(0).upper, 10.0);
}

// Gravity is m/s^2: a vector in mm/s^2, in g or zero would scale every gravity load of the
// compliance model silently (by 1000, 1/9.81 or to nothing).
TEST(RobotIo, GravityInOtherUnitsIsAnError) {
  const std::string joint =
      "    <joint name=\"j\" type=\"revolute\" a_mm=\"1\" alpha_deg=\"90\" d_mm=\"0\" theta0_deg=\"0\" direction=\"1\" "
      "lower=\"-10\" upper=\"10\" mass_kg=\"1\" com_x_mm=\"0\" com_y_mm=\"0\" com_z_mm=\"0\"/>\n";
  const auto withGravity = [&](const std::string& name, const std::string& xyz) {
    std::string xml = kHead;
    xml.insert(xml.find("  <joints>"), "  <gravity " + xyz + "/>\n");
    const std::string path = test::tempDir("robot_gravity") + "/" + name + ".xml";
    test::writeText(path, xml + joint + "  </joints>\n</robot>\n");
    return path;
  };
  for (const auto& [name, xyz, magnitude] : std::vector<std::tuple<std::string, std::string, std::string>>{
           {"mm", "x=\"0\" y=\"0\" z=\"-9806.65\"", "9806.65 (mm/s^2?)"},
           {"g", "x=\"0\" y=\"0\" z=\"-1\"", "1 (in g?)"},
           {"zero", "x=\"0\" y=\"0\" z=\"0\"", "0"},
           {"tilted_mm", "x=\"3000\" y=\"0\" z=\"-4000\"", "5000"}}) {
    const std::string path = withGravity(name, xyz);
    try {
      readRobotFile(path);
      ADD_FAILURE() << "accepted gravity " << xyz;
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()), path + ":5:3: <gravity>: expected the gravity vector in m/s^2, of magnitude about 9.81 (9 to 10.5; "
                                              "standard 0 0 -9.80665), found magnitude " + magnitude);
    }
  }
  // floor, ceiling, a wall (tilted), a rounded 10: read as written
  EXPECT_EQ(readRobotFile(withGravity("floor", "x=\"0\" y=\"0\" z=\"-9.80665\"")).nominal.gravity_base.z(), -9.80665);
  EXPECT_EQ(readRobotFile(withGravity("ceiling", "x=\"0\" y=\"0\" z=\"9.81\"")).nominal.gravity_base.z(), 9.81);
  EXPECT_EQ(readRobotFile(withGravity("wall", "x=\"-6\" y=\"0\" z=\"-8\"")).nominal.gravity_base.x(), -6.0);
  EXPECT_EQ(readRobotFile(withGravity("rounded", "x=\"0\" y=\"0\" z=\"-10\"")).nominal.gravity_base.z(), -10.0);
}

TEST(RobotIo, ResolveByNameOrPath) {
  EXPECT_NE(resolveRobotPath("kuka_kr16").find("robots/kuka_kr16.xml"), std::string::npos);
  EXPECT_NE(resolveRobotPath("ur10.xml").find("robots/ur10.xml"), std::string::npos);
  try {
    resolveRobotPath("kr1000");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("found 'kr1000'"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("kuka_kr16"), std::string::npos);
    EXPECT_EQ(std::string(e.what()).find("--robot"), std::string::npos);  // a library message: no CLI option in it
  }
  // a directory is named as one (the plug-in's model_load("/tmp") said "--robot: ...")
  try {
    resolveRobotPath(test::tempDir("robot_dir"));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("(a directory)"), std::string::npos) << e.what();
  }
  // a path where nothing is (a mistyped model file): said so (before: the bare name)
  const std::string missing = test::tempDir("robot_missing") + "/kr16_calbrated.xml";
  try {
    resolveRobotPath(missing);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "expected a robot file or one of the bundled robots (abb_irb120, kuka_kr16, scara, ur10), found '" +
                                         missing + "' (no such file)");
  }
  // a path that cannot be looked at (here through a file; likewise a directory without search
  // permission): its reason, not "no such file"
  const std::string through = test::tempDir("robot_missing") + "/afile";
  test::writeText(through, "x");
  try {
    resolveRobotPath(through + "/model.xml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "expected a robot file or one of the bundled robots (abb_irb120, kuka_kr16, scara, ur10), found '" +
                                         through + "/model.xml' (" + std::make_error_code(std::errc::not_a_directory).message() + ")");
  }
}

}  // namespace
}  // namespace accura::calib
