// URDF import and export (urdf.h): public robot descriptions against their own FK (computed
// here from the XML with a separate, deliberately plain implementation), malformed files,
// mimic / branch / loop errors, the bundled robots' round trips, check_urdf on the export.
#include <gtest/gtest.h>
#include <tinyxml2.h>

#include <cmath>
#include <map>
#include <random>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/ur_calibration.h"
#include "accura/calib/urdf.h"
#include "test_util.h"

namespace accura::calib {
namespace {

using test::sourcePath;

// ---- An independent URDF FK: tinyxml2, explicit rotation matrices, metres -> mm. ----
struct PlainJoint {
  std::string type, parent, child;
  double xyz[3] = {0, 0, 0}, rpy[3] = {0, 0, 0}, axis[3] = {1, 0, 0};
};

void readTriple(const tinyxml2::XMLElement* e, const char* attr, double* out) {
  if (!e || !e->Attribute(attr)) return;
  std::istringstream in(e->Attribute(attr));
  in >> out[0] >> out[1] >> out[2];
}

Eigen::Matrix3d rpyMatrix(const double* rpy) {
  const double cr = std::cos(rpy[0]), sr = std::sin(rpy[0]);
  const double cp = std::cos(rpy[1]), sp = std::sin(rpy[1]);
  const double cy = std::cos(rpy[2]), sy = std::sin(rpy[2]);
  Eigen::Matrix3d Rx, Ry, Rz;
  Rx << 1, 0, 0, 0, cr, -sr, 0, sr, cr;
  Ry << cp, 0, sp, 0, 1, 0, -sp, 0, cp;
  Rz << cy, -sy, 0, sy, cy, 0, 0, 0, 1;
  return Rz * Ry * Rx;  // URDF: fixed-axis roll about x, then pitch about y, then yaw about z
}

Eigen::Matrix3d rodrigues(Eigen::Vector3d k, double angle) {
  k.normalize();
  Eigen::Matrix3d K;
  K << 0, -k.z(), k.y(), k.z(), 0, -k.x(), -k.y(), k.x(), 0;
  return Eigen::Matrix3d::Identity() + std::sin(angle) * K + (1 - std::cos(angle)) * K * K;
}

// T_root_tip (mm) of a URDF file at q (deg / mm for the moving joints from root to tip).
Eigen::Matrix4d plainFK(const std::string& path, const std::string& root, const std::string& tip,
                        const Eigen::VectorXd& q) {
  tinyxml2::XMLDocument doc;
  EXPECT_EQ(doc.LoadFile(path.c_str()), tinyxml2::XML_SUCCESS);
  std::map<std::string, PlainJoint> by_child;
  for (auto* j = doc.RootElement()->FirstChildElement("joint"); j; j = j->NextSiblingElement("joint")) {
    PlainJoint p;
    p.type = j->Attribute("type");
    p.parent = j->FirstChildElement("parent")->Attribute("link");
    p.child = j->FirstChildElement("child")->Attribute("link");
    readTriple(j->FirstChildElement("origin"), "xyz", p.xyz);
    readTriple(j->FirstChildElement("origin"), "rpy", p.rpy);
    readTriple(j->FirstChildElement("axis"), "xyz", p.axis);
    by_child[p.child] = p;
  }
  std::vector<PlainJoint> path_joints;
  for (std::string l = tip; l != root; l = by_child.at(l).parent) path_joints.insert(path_joints.begin(), by_child.at(l));
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  int k = 0;
  for (const auto& j : path_joints) {
    Eigen::Matrix4d O = Eigen::Matrix4d::Identity();
    O.topLeftCorner<3, 3>() = rpyMatrix(j.rpy);
    O.topRightCorner<3, 1>() = 1000.0 * Eigen::Vector3d(j.xyz[0], j.xyz[1], j.xyz[2]);
    Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
    const Eigen::Vector3d axis(j.axis[0], j.axis[1], j.axis[2]);
    if (j.type == "revolute" || j.type == "continuous") {
      M.topLeftCorner<3, 3>() = rodrigues(axis, q[k++] * M_PI / 180.0);
    } else if (j.type == "prismatic") {
      M.topRightCorner<3, 1>() = q[k++] * axis.normalized();
    }
    T = T * O * M;
  }
  EXPECT_EQ(k, q.size());
  return T;
}

struct Mismatch {
  double pos_mm = 0, rot = 0;
};

// Largest difference between the accura model's FK and the plain URDF FK on `samples` random q.
Mismatch compareWithPlain(const RobotModel& m, const std::string& path, const std::string& root,
                          const std::string& tip, int samples = 200) {
  std::mt19937_64 rng(7);
  Mismatch w;
  for (int s = 0; s < samples; ++s) {
    const Eigen::VectorXd q = test::randomQ(m, rng);
    const Eigen::Isometry3d A = forwardKinematics(m, q);
    const Eigen::Matrix4d B = plainFK(path, root, tip, q);
    w.pos_mm = std::max(w.pos_mm, (A.translation() - B.topRightCorner<3, 1>()).norm());
    w.rot = std::max(w.rot, (A.linear() - B.topLeftCorner<3, 3>()).cwiseAbs().maxCoeff());
  }
  return w;
}

struct PublicUrdf {
  const char* file;
  const char* root;
  const char* tip;
  int dof;
};

// Public industrial arm descriptions (tests/data/urdf/README.md): fixed joints, rpy offsets,
// axes along -z, y, -x, links declared after their joints; default chains.
TEST(Urdf, PublicDescriptionsMatchTheirOwnFK) {
  for (const PublicUrdf& u : {PublicUrdf{"kr16_2.urdf", "base_link", "tool0", 6},
                              PublicUrdf{"irb2400.urdf", "base_link", "tool0", 6},
                              PublicUrdf{"panda_arm.urdf", "panda_link0", "panda_link8", 7},
                              PublicUrdf{"ur10.urdf", "world", "tool0", 6},
                              PublicUrdf{"ur5_robot.urdf", "base_link", "ee_link", 6}}) {
    SCOPED_TRACE(u.file);
    const std::string path = sourcePath(std::string("tests/data/urdf/") + u.file);
    const RobotModel m = readRobotFile(path);  // the .urdf dispatch, default chain
    ASSERT_EQ(m.dof(), u.dof);
    const Mismatch w = compareWithPlain(m, path, u.root, u.tip);
    EXPECT_LT(w.pos_mm, 1e-9);
    EXPECT_LT(w.rot, 1e-12);
  }
}

// A URDF saved under another name (robot_description.xml, as ROS dumps it) is read as the URDF it
// is, not rejected as a robot file with an unknown <link>: the same model as from the .urdf.
TEST(Urdf, AUrdfNamedXmlIsReadAsUrdf) {
  const std::string dir = test::tempDir("urdf_as_xml");
  const std::string urdf = test::sourcePath("tests/data/urdf/ur10.urdf");
  writeFileAtomically(dir + "/robot_description.xml", test::readText(urdf));
  const RobotModel a = readRobotFile(urdf), b = readRobotFile(dir + "/robot_description.xml");
  ASSERT_EQ(b.dof(), 6);
  Eigen::VectorXd q(6);
  q << 10, -70, 80, -20, 30, 40;
  EXPECT_LT((forwardKinematics(a, q).matrix() - forwardKinematics(b, q).matrix()).cwiseAbs().maxCoeff(), 1e-12);
  // a robot file that is neither: still the robot file's message
  writeFileAtomically(dir + "/bad.xml", "<robot name=\"r\">\n  <joint/>\n</robot>\n");
  try {
    readRobotFile(dir + "/bad.xml");
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.xml:2:"), std::string::npos) << e.what();
  }
}

TEST(Urdf, KukaKr16ConvertsToTheKnownDH) {
  // The KR 16's DH table (robots/README.md): a = 260, 680, -35 / 35, 0, 0, 0; d1 = 675,
  // d4 = +-670, d6 = +-158; A1 turns about -z: direction -1 with z0 up.
  const RobotModel m = readUrdfRobot(sourcePath("tests/data/urdf/kr16_2.urdf"));
  const auto& j = m.nominal.joints;
  EXPECT_EQ(j[0].direction, -1);
  EXPECT_NEAR(j[0].d_mm, 675, 1e-12);
  EXPECT_NEAR(std::abs(j[0].a_mm), 260, 1e-12);
  EXPECT_NEAR(std::abs(j[1].a_mm), 680, 1e-12);
  EXPECT_NEAR(std::abs(j[2].a_mm), 35, 1e-12);
  EXPECT_NEAR(std::abs(j[3].d_mm), 670, 1e-12);
  EXPECT_NEAR(std::abs(j[5].d_mm), 158, 1e-12);
  EXPECT_TRUE(m.nominal.T_world_base.isApprox(Eigen::Isometry3d::Identity(), 1e-15));
  // tool0 is a DH frame of the last link: nothing left for the tool
  EXPECT_LT(m.nominal.T_flange_tcp.translation().norm(), 1e-12);
  EXPECT_LT((m.nominal.T_flange_tcp.linear() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  // joint limits: rad -> deg
  EXPECT_NEAR(j[1].lower, -2.705260340591211 * 180 / M_PI, 1e-12);
  EXPECT_NEAR(j[1].upper, 0.6108652381980153 * 180 / M_PI, 1e-12);
  // A2 and A3 are parallel: Hayati there, DH elsewhere
  EXPECT_EQ(m.forms[1], LinkForm::kHayati);
  EXPECT_EQ(m.forms[0], LinkForm::kDH);
  // The bundled kuka_kr16.xml (FreeCAD's DH table, an independent source) is the same robot:
  // flange poses (tool0 = KUKA $FLANGE) agree at random joint vectors.
  const RobotModel bundled = test::loadBundled("kuka_kr16");
  std::mt19937_64 rng(8);
  for (int s = 0; s < 200; ++s) {
    const Eigen::VectorXd q = test::randomQ(bundled, rng);
    const Eigen::Isometry3d A = forwardKinematics(bundled, q), B = forwardKinematics(m, q);
    EXPECT_LT((A.translation() - B.translation()).norm(), 1e-9);
    EXPECT_LT((A.linear() - B.linear()).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(Urdf, Ur10BaseFrames) {
  // ur_description: base_link is REP-103 (x forward), the controller's 'Base' (URDF 'base'
  // = base_link turned 180 deg about z) is UR's DH frame 0. At zero joints the pendant shows
  // the flange at (-1184.3, -256.141, 11.6) mm in Base, so (+1184.3, +256.141, 11.6) in
  // base_link (robots/README.md).
  const std::string path = sourcePath("tests/data/urdf/ur10.urdf");
  const Eigen::VectorXd q0 = Eigen::VectorXd::Zero(6);
  const RobotModel in_base = readUrdfRobot(path, "base:tool0");
  const Eigen::Vector3d p_base = forwardKinematics(in_base, q0).translation();
  EXPECT_NEAR(p_base.x(), -1184.3, 1e-6);
  EXPECT_NEAR(p_base.y(), -256.141, 1e-6);
  EXPECT_NEAR(p_base.z(), 11.6, 1e-6);
  const RobotModel in_base_link = readUrdfRobot(path, "base_link:tool0");
  const Eigen::Vector3d p_link = forwardKinematics(in_base_link, q0).translation();
  EXPECT_NEAR(p_link.x(), 1184.3, 1e-6);
  EXPECT_NEAR(p_link.y(), 256.141, 1e-6);
  // The bundled ur10.xml (DH frame 0 = world) agrees with the URDF's 'base' frame everywhere,
  // to the URDF's own rounding of pi/2 (1.570796327: 2e-10 rad, 2.6e-7 mm at 1.3 m).
  const RobotModel bundled = test::loadBundled("ur10");
  std::mt19937_64 rng(3);
  double worst = 0;
  for (int s = 0; s < 100; ++s) {
    const Eigen::VectorXd q = test::randomQ(bundled, rng);
    worst = std::max(worst, (forwardKinematics(bundled, q).translation() - forwardKinematics(in_base, q).translation()).norm());
  }
  EXPECT_LT(worst, 1e-6);
  EXPECT_GT(worst, 1e-9);  // the URDF's rounded pi/2 is visible: a real comparison
}

TEST(Urdf, MassesAndCentresOfMassAreCarriedIntoDHFrames) {
  // UR10: the URDF's inertials (ur_description) are UR's dynamics table; in DH frames they
  // are the bundled ur10.xml's values (robots/README.md): masses 7.1 .. 0.365 kg, and gravity
  // loads equal to the bundled model's at any q.
  const RobotModel m = readUrdfRobot(sourcePath("tests/data/urdf/ur10.urdf"), "base:tool0");
  const RobotModel b = test::loadBundled("ur10");
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(m.nominal.joints[i].mass_kg, b.nominal.joints[i].mass_kg, 1e-12);
  std::mt19937_64 rng(5);
  for (int s = 0; s < 20; ++s) {
    const Eigen::VectorXd q = test::randomQ(b, rng);
    const Eigen::VectorXd gm = gravityLoads(m, q, PoseContext{});
    const Eigen::VectorXd gb = gravityLoads(b, q, PoseContext{});
    // The URDF places the upper arm's and forearm's COM 380 / 240 mm from the joint as UR's
    // table does (a -0.232 + 0.612 = 0.380 m): same loads to the URDF's rounding.
    EXPECT_LT((gm - gb).cwiseAbs().maxCoeff(), 1e-3) << gm.transpose() << "\n" << gb.transpose();
  }
}

// A calibrated model with every geometric deviation non-zero (base, tool, offsets, lengths,
// angles, Hayati betas) and, optionally, the effects URDF cannot hold.
RobotModel perturbed(const std::string& robot, bool effects) {
  RobotModel m = test::loadBundled(robot);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  for (const ParamInfo& p : parameterLayout(m)) {
    const bool geometric = p.group == "base" || p.group == "tool" || p.group == "offsets" || p.group == "lengths" ||
                           p.group == "angles";
    if (!geometric && !effects) continue;
    const double scale = p.unit == "mm" ? 0.5 : p.unit == "deg" ? 0.05 : 20.0;  // display units
    setParameter(m.deviations, p, u(rng) * scale / p.display_scale);
  }
  return m;
}

// Every bundled robot: its exported URDF, read by the plain FK above, is the model's geometry
// (URDF equivalence), and import(export) is the identity to 1e-9 mm.
TEST(Urdf, BundledRobotsExportImportIdentity) {
  const std::string dir = test::tempDir("urdf_bundled");
  for (const std::string& name : bundledRobotNames()) {
    for (bool calibrated : {false, true}) {
      SCOPED_TRACE(name + (calibrated ? " calibrated" : " nominal"));
      const RobotModel m = calibrated ? perturbed(name, false) : test::loadBundled(name);
      const UrdfText u = modelToUrdf(m);
      const std::string path = dir + "/" + name + ".urdf";
      writeFileAtomically(path, u.text);
      // independent FK of the written file
      const Mismatch w = compareWithPlain(m, path, "world", "tool0");
      EXPECT_LT(w.pos_mm, 1e-9);
      EXPECT_LT(w.rot, 1e-12);
      // import
      const RobotModel back = readRobotFile(path);
      ASSERT_EQ(back.dof(), m.dof());
      std::mt19937_64 rng(1);
      double worst = 0;
      for (int s = 0; s < 200; ++s) {
        const Eigen::VectorXd q = test::randomQ(m, rng);
        worst = std::max(worst, (forwardKinematics(back, q).translation() - forwardKinematics(m, q).translation()).norm());
        EXPECT_LT((forwardKinematics(back, q).linear() - forwardKinematics(m, q).linear()).cwiseAbs().maxCoeff(), 1e-12);
      }
      EXPECT_LT(worst, 1e-9);
      for (int i = 0; i < m.dof(); ++i) {
        EXPECT_EQ(back.nominal.joints[i].name, m.nominal.joints[i].name);
        EXPECT_NEAR(back.nominal.joints[i].lower, m.nominal.joints[i].lower, 1e-9);
        EXPECT_NEAR(back.nominal.joints[i].upper, m.nominal.joints[i].upper, 1e-9);
        EXPECT_NEAR(back.nominal.joints[i].mass_kg, m.nominal.joints[i].mass_kg, 1e-12);
      }
      // gravity loads (masses and COMs through the URDF) agree at random q; they use the
      // nominal geometry, so only the nominal model's are the same
      for (int s = 0; s < 10 && !calibrated; ++s) {
        const Eigen::VectorXd q = test::randomQ(m, rng);
        EXPECT_LT((gravityLoads(back, q, PoseContext{}) - gravityLoads(m, q, PoseContext{})).cwiseAbs().maxCoeff(), 1e-9);
      }
      // check_urdf (urdfdom's own checker) loads it
      const std::string cmd = "check_urdf '" + path + "' > '" + dir + "/check.txt' 2>&1";
      EXPECT_EQ(std::system(cmd.c_str()), 0) << test::readText(dir + "/check.txt");
      EXPECT_NE(test::readText(dir + "/check.txt").find("Successfully Parsed XML"), std::string::npos);
    }
  }
  std::filesystem::remove_all(dir);
}

TEST(Urdf, ExportListsWhatUrdfCannotHold) {
  const RobotModel m = perturbed("kuka_kr16", true);
  const UrdfText u = modelToUrdf(m);
  std::string all;
  for (const auto& s : u.not_represented) all += s + "\n";
  // (the perturbed base is turned by up to 0.05 deg: gravity is no longer along -z of 'world')
  for (const char* group : {"joint_compliance", "gear_periodic", "joint_scale", "backlash", "thermal", "payload centre of mass",
                            "inertia tensors", "effort and velocity", "gravity"}) {
    EXPECT_NE(all.find(group), std::string::npos) << group << " missing in:\n" << all;
    EXPECT_NE(u.text.find(group), std::string::npos) << group << " missing in the XML comment";
  }
  // the geometry still round-trips: FK of the import equals the model without the effects
  RobotModel geometric = m;
  for (const ParamInfo& p : parameterLayout(m))
    if (p.group != "base" && p.group != "tool" && p.group != "offsets" && p.group != "lengths" && p.group != "angles")
      setParameter(geometric.deviations, p, 0.0);
  const SerialChain chain = parseUrdfChain(u.text, "mem.urdf", "world:tool0");
  const ChainComparison c = compareModelWithChain(geometric, chain, 100);
  EXPECT_LT(c.max_position_mm, 1e-9);
  // the nominal robot's gravity is along -z of world: nothing to say about it
  for (const auto& line : modelToUrdf(test::loadBundled("kuka_kr16")).not_represented)
    EXPECT_EQ(line.find("gravity"), std::string::npos) << line;
  // ... and differs from the full model (the effects are real and were left out, not ignored)
  EXPECT_GT(compareModelWithChain(m, chain, 100).max_position_mm, 1e-3);
}

// ---- Errors ----

std::string errorOf(const std::string& text, const std::string& chain = "") {
  try {
    parseUrdfChain(text, "bad.urdf", chain);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

const char* kTwoJoint = R"(<robot name="r">
  <link name="a"/>
  <link name="b"/>
  <link name="c"/>
  <joint name="j1" type="revolute">
    <parent link="a"/><child link="b"/>
    <origin xyz="0 0 0.5" rpy="0 0 0"/>
    <axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <joint name="j2" type="revolute">
    <parent link="b"/><child link="c"/>
    <origin xyz="0.3 0 0" rpy="0 0 0"/>
    <axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
</robot>
)";

std::string replaced(std::string s, const std::string& from, const std::string& to) {
  const size_t pos = s.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  return s.replace(pos, from.size(), to);
}

TEST(Urdf, MalformedFilesGiveFileAndLine) {
  EXPECT_EQ(errorOf(kTwoJoint), "no error");
  struct Case {
    std::string text, expected;
  };
  const std::vector<Case> cases = {
      {replaced(kTwoJoint, "</robot>", "</robt>"), "bad.urdf:1"},  // XML: tinyxml2 names the element left open
      {replaced(kTwoJoint, "<axis xyz=\"0 1 0\"/>", "<axis xyz=\"0 1 0/>"), "bad.urdf:14"},        // XML: open quote
      {replaced(kTwoJoint, "xyz=\"0.3 0 0\"", "xyz=\"0.3 0\""), "bad.urdf:13"},                     // 2 numbers
      {replaced(kTwoJoint, "xyz=\"0.3 0 0\"", "xyz=\"0.3 nan 0\""), "bad.urdf:13"},                 // non-finite
      {replaced(kTwoJoint, "xyz=\"0.3 0 0\"", "xyz=\"300 0 0\""), "bad.urdf:13"},                   // absurd
      {replaced(kTwoJoint, "<axis xyz=\"0 1 0\"/>", "<axis xyz=\"0 0 0\"/>"), "bad.urdf:14"},       // zero axis
      {replaced(kTwoJoint, "<child link=\"c\"/>", "<child link=\"x\"/>"), "bad.urdf:12"},           // unknown link (at link=)
      {replaced(kTwoJoint, "lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/>\n  </joint>\n</robot>",
                "lower=\"1\" upper=\"-1\" effort=\"1\" velocity=\"1\"/>\n  </joint>\n</robot>"),
       "bad.urdf:15"},                                                                                 // lower >= upper
      {replaced(kTwoJoint, "type=\"revolute\">\n    <parent link=\"b\"/>", "type=\"hinge\">\n    <parent link=\"b\"/>"),
       "bad.urdf:11"},                                                                                 // type
      {replaced(kTwoJoint, "<parent link=\"b\"/><child link=\"c\"/>", "<parent link=\"b\"/><child link=\"b\"/>"),
       "bad.urdf:12"},                                                                                 // self loop (at link=)
      {replaced(kTwoJoint, "<link name=\"c\"/>", "<link name=\"c\"><inertial><mass value=\"-2\"/>"
                                                 "<inertia ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"/>"
                                                 "</inertial></link>"),
       "bad.urdf:4"},                                                                                  // mass
      {replaced(kTwoJoint, " effort=\"1\" velocity=\"1\"/>\n  </joint>\n</robot>", "/>\n  </joint>\n</robot>"),
       "bad.urdf:15"},                                                                                 // urdfdom: no effort
  };
  for (const Case& c : cases) {
    const std::string e = errorOf(c.text);
    EXPECT_EQ(e.rfind(c.expected + ":", 0), 0u) << "expected " << c.expected << ", got: " << e;
  }
  // What only urdfdom checks (here a <dynamics> value) is mapped to the line of the joint its
  // message names.
  const std::string e = errorOf(replaced(kTwoJoint, "<axis xyz=\"0 1 0\"/>", "<axis xyz=\"0 1 0\"/><dynamics damping=\"x\"/>"));
  EXPECT_EQ(e.rfind("bad.urdf:11:3: expected a URDF urdfdom accepts, found one it rejects: damping value (x) is not a valid float", 0), 0u) << e;
  // missing file
  EXPECT_THROW(readUrdfRobot("/nonexistent/robot.urdf"), InputError);
}

// The vendors' ROS packages ship the arm as xacro sources (kr6r900sixx_macro.xacro,
// ur.urdf.xacro); given one, the user hears that it is a xacro source, not the symptom it causes
// (a <robot> without a name, an accura robot file with an unknown attribute 'xmlns:xacro').
TEST(Urdf, AnUnexpandedXacroFileIsNamedAsSuch) {
  const std::string xacro =
      "<?xml version=\"1.0\"?>\n"
      "<robot xmlns:xacro=\"http://wiki.ros.org/xacro\">\n"
      "  <xacro:include filename=\"$(find kuka_kr6_support)/urdf/kr6r900sixx_macro.xacro\"/>\n"
      "  <xacro:kuka_kr6r900sixx prefix=\"\"/>\n"
      "</robot>\n";
  const std::string expected =
      ":3:3: expected a URDF (xacro's output: xacro FILE.xacro > FILE.urdf), found the xacro element "
      "<xacro:include>: the file is an unexpanded xacro source";
  EXPECT_EQ(errorOf(xacro), "bad.urdf" + expected);
  // under its own name, where --robot reads a robot file unless it holds a URDF
  const std::string dir = test::tempDir("urdf_xacro");
  test::writeText(dir + "/kr6r900sixx.urdf.xacro", xacro);
  try {
    readRobotFile(dir + "/kr6r900sixx.urdf.xacro");
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), dir + "/kr6r900sixx.urdf.xacro" + expected);
  }
  // a macro's body: the element inside a joint
  EXPECT_EQ(errorOf(replaced(kTwoJoint, "<origin xyz=\"0.3 0 0\" rpy=\"0 0 0\"/>", "<xacro:insert_block name=\"origin\"/>")),
            "bad.urdf:13:5: expected a URDF (xacro's output: xacro FILE.xacro > FILE.urdf), found the xacro element "
            "<xacro:insert_block>: the file is an unexpanded xacro source");
  // an expression left in a value says so
  EXPECT_EQ(errorOf(replaced(kTwoJoint, "rpy=\"0 0 0\"/>\n    <axis xyz=\"0 1 0\"/>", "rpy=\"0 0 ${pi/2}\"/>\n    <axis xyz=\"0 1 0\"/>")),
            "bad.urdf:13:27: <origin> attribute 'rpy': expected three finite numbers, found '0 0 ${pi/2}' (an unexpanded "
            "xacro expression: give accura xacro's output, xacro FILE.xacro > FILE.urdf)");
  EXPECT_EQ(errorOf(replaced(kTwoJoint, "lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/>\n  </joint>\n</robot>",
                             "lower=\"-1\" upper=\"1\" effort=\"${effort}\" velocity=\"1\"/>\n  </joint>\n</robot>")),
            "bad.urdf:15:33: <limit> attribute 'effort': expected a finite number, found '${effort}' (an unexpanded "
            "xacro expression: give accura xacro's output, xacro FILE.xacro > FILE.urdf)");
  // a declaration alone changes nothing: the URDF ROS reads
  EXPECT_EQ(errorOf(replaced(kTwoJoint, "<link name=\"a\"/>", "<xacro:property name=\"pi\" value=\"3.1415926535897931\"/>\n"
                                                             "  <xacro:arg name=\"prefix\" default=\"\"/><link name=\"a\"/>")),
            "no error");
  // a number that is merely wrong gets no such note
  EXPECT_EQ(errorOf(replaced(kTwoJoint, "xyz=\"0.3 0 0\"", "xyz=\"0.3 0 x\"")),
            "bad.urdf:13:13: <origin> attribute 'xyz': expected three finite numbers, found '0.3 0 x'");
}

TEST(Urdf, LoopsMimicBranchesAndChainsAreNamed) {
  // a second parent for link c: a closed loop
  const std::string loop = replaced(kTwoJoint, "</robot>", R"(  <joint name="j3" type="fixed">
    <parent link="a"/><child link="c"/>
  </joint>
</robot>)");
  std::string e = errorOf(loop);
  EXPECT_NE(e.find("bad.urdf:18:"), std::string::npos) << e;  // its <child link="c">
  EXPECT_NE(e.find("'j3' closes a loop"), std::string::npos) << e;

  // mimic joint on the chain
  const std::string mimic = replaced(kTwoJoint, "<axis xyz=\"0 1 0\"/>", "<axis xyz=\"0 1 0\"/><mimic joint=\"j1\"/>");
  e = errorOf(mimic);
  EXPECT_NE(e.find("bad.urdf:14:"), std::string::npos) << e;  // the <mimic> element
  EXPECT_NE(e.find("'j2'"), std::string::npos) << e;
  EXPECT_NE(e.find("mimics joint 'j1'"), std::string::npos) << e;

  // a moving branch off link b (moved by j1) on the chain a:c, its link d weighing 2 kg
  const std::string branch = replaced(kTwoJoint, "</robot>", R"(  <link name="d"><inertial><mass value="2"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <joint name="pan" type="continuous">
    <parent link="b"/><child link="d"/>
    <axis xyz="1 0 0"/>
  </joint>
</robot>)");
  e = errorOf(branch, "a:c");
  EXPECT_NE(e.find("bad.urdf:18"), std::string::npos) << e;
  EXPECT_NE(e.find("'pan'"), std::string::npos) << e;
  EXPECT_NE(e.find("branches off the chain"), std::string::npos) << e;
  EXPECT_NE(e.find("weigh 2 kg"), std::string::npos) << e;
  // without --chain the default cannot choose: the error says where and how
  e = errorOf(branch);
  EXPECT_NE(e.find("--chain"), std::string::npos) << e;
  // the chain a:d is serial (j1, pan); c then branches off link b, which j1 moves: j2 is a
  // branch of a:d, fine because its link c has no mass (it loads no joint), refused with 1 kg
  EXPECT_EQ(parseUrdfChain(branch, "branch.urdf", "a:d").joints.size(), 2u);
  e = errorOf(replaced(branch, "<link name=\"c\"/>", R"(<link name="c"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>)"), "a:d");
  EXPECT_NE(e.find("'j2'"), std::string::npos) << e;
  // unknown link in --chain
  e = errorOf(kTwoJoint, "a:zz");
  EXPECT_NE(e.find("no link 'zz'"), std::string::npos) << e;

  // a prismatic and a continuous joint are fine; continuous gets -360..360 deg
  const std::string mixed = replaced(replaced(kTwoJoint, "type=\"revolute\">\n    <parent link=\"a\"/>",
                                              "type=\"prismatic\">\n    <parent link=\"a\"/>"),
                                     "type=\"revolute\">\n    <parent link=\"b\"/>", "type=\"continuous\">\n    <parent link=\"b\"/>");
  const SerialChain chain = parseUrdfChain(mixed, "mixed.urdf");
  ASSERT_EQ(chain.joints.size(), 2u);
  EXPECT_EQ(chain.joints[0].type, JointType::kPrismatic);
  EXPECT_NEAR(chain.joints[0].lower, -1000, 1e-12);  // m -> mm
  EXPECT_EQ(chain.joints[1].lower, -360);
  const RobotModel m = modelFromChain(chain);
  const Eigen::Vector2d q(250, 30);  // mm, deg
  // tip: a -> (0,0,500 + 250) -> Tx(300) then Ry(30) at the tip's origin
  EXPECT_LT((forwardKinematics(m, q).translation() - Eigen::Vector3d(300, 0, 750)).norm(), 1e-12);
}

// Two revolute joints a -> b -> hand, then two fingers on prismatic joints off the hand (the
// second a mimic), as franka_description's panda with its hand.
const char* kHand = R"(<robot name="arm_with_hand">
  <link name="a"/> <link name="b"/> <link name="hand"/>
  <link name="finger_l"><inertial><mass value="1.5"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <link name="finger_r"><inertial><mass value="1.5"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0 0 0.5"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="b"/><child link="hand"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="finger_joint1" type="prismatic"><parent link="hand"/><child link="finger_l"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 1 0"/><limit lower="0" upper="0.04" effort="20" velocity="0.2"/></joint>
  <joint name="finger_joint2" type="prismatic"><parent link="hand"/><child link="finger_r"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 -1 0"/><limit lower="0" upper="0.04" effort="20" velocity="0.2"/><mimic joint="finger_joint1"/></joint>
</robot>
)";

TEST(Urdf, TheDefaultChainErrorSuggestsOnlyChainsThatRead) {
  // the tree branches at the hand into the two fingers: a chain into one finger has the other
  // branching off the hand, which j2 moves (refused); the arm up to the hand, fingers as its
  // load, reads. The suggestion was the refused one (--chain a:finger_l).
  EXPECT_EQ(errorOf(kHand), "bad.urdf:2:37: expected one default chain, found the tree branching at link 'hand' into finger_l, "
                            "finger_r; choose one with --chain ROOT:TIP: --chain a:hand (the moving joints beyond its tip are "
                            "the last joint's load, like a gripper's fingers)");
  EXPECT_EQ(parseUrdfChain(kHand, "hand.urdf", "a:hand").joints.size(), 2u);
  EXPECT_NE(errorOf(kHand, "a:finger_l").find("found joint 'finger_joint2' (prismatic), which branches off the chain a:finger_l"),
            std::string::npos);
  // two arms on a fixed torso: each arm's chain reads (the other branches off the fixed root)
  const std::string two_arms = replaced(replaced(kTwoJoint, "<link name=\"c\"/>", "<link name=\"c\"/><link name=\"d\"/>"), "</robot>",
                                        R"(  <joint name="k1" type="revolute"><parent link="a"/><child link="d"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>)");
  EXPECT_NE(errorOf(two_arms).find("found the tree branching at link 'a' into b, d; choose one with --chain ROOT:TIP: --chain a:c or "
                                   "--chain a:d"),
            std::string::npos) << errorOf(two_arms);
}

TEST(Urdf, TheLastJointCarriesTheGripperFingers) {
  // the fingers (1.5 kg each, prismatic, one a mimic) branch off the hand, beyond the chain a:hand:
  // j2 carries them (it had none of their mass: 0 kg), at the fingers' zero: their links'
  // origins 0.1 m above the hand's, the hand at (0.3, 0, 0.5) m at q = 0
  const RobotModel m = modelFromChain(parseUrdfChain(kHand, "hand.urdf", "a:hand"));
  EXPECT_EQ(m.nominal.joints[1].mass_kg, 3.0);
  EXPECT_EQ(m.nominal.joints[0].mass_kg, 0.0);
  const Eigen::Isometry3d frame2 = forwardKinematics(m, Eigen::Vector2d(0, 0)) * m.nominal.T_flange_tcp.inverse();
  EXPECT_LT((frame2 * m.nominal.joints[1].com_mm - Eigen::Vector3d(300, 0, 600)).norm(), 1e-9)
      << (frame2 * m.nominal.joints[1].com_mm).transpose();
  // the same with the hand's own mass and a tip below it (a TCP off the hand: the fingers now
  // branch off a link between the last joint and the tip): 0.8 kg at the hand, 3 kg 0.1 m up
  std::string with_tcp = replaced(kHand, "<link name=\"hand\"/>",
                                  "<link name=\"hand\"><inertial><mass value=\"0.8\"/><inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" "
                                  "iyz=\"0\" izz=\"1\"/></inertial></link><link name=\"tcp\"/>");
  with_tcp = replaced(with_tcp, "</robot>", "  <joint name=\"hand-tcp\" type=\"fixed\"><parent link=\"hand\"/><child link=\"tcp\"/>"
                                            "<origin xyz=\"0 0 0.2\"/></joint>\n</robot>");
  const RobotModel t = modelFromChain(parseUrdfChain(with_tcp, "tcp.urdf", "a:tcp"));
  EXPECT_DOUBLE_EQ(t.nominal.joints[1].mass_kg, 3.8);
  const Eigen::Isometry3d t2 = forwardKinematics(t, Eigen::Vector2d(0, 0)) * t.nominal.T_flange_tcp.inverse();
  EXPECT_LT((t2 * t.nominal.joints[1].com_mm - Eigen::Vector3d(300, 0, 500 + 3.0 * 100 / 3.8)).norm(), 1e-9);
  // gravity: j2 (axis y through the hand) turned by 45 deg: the fingers' 3 kg 0.1 m from it
  const Eigen::VectorXd g = gravityLoads(t, Eigen::Vector2d(0, 45), PoseContext{});
  EXPECT_NEAR(std::abs(g[1]), 3.0 * 9.80665 * 0.1 * std::sqrt(0.5), 1e-9) << g.transpose();
}

TEST(Urdf, FkTakesTheMeasurementReadersSlackAtALimit) {
  // a limit of 6.283 rad is 359.98938 deg: the CSV reader takes 0.01 deg beyond a limit
  // (kJointLimitReadSlack), fk refused 359.995; now the same slack, and no more
  const std::string dir = test::tempDir("urdf_fk_slack");
  test::writeText(dir + "/r.urdf", replaced(replaced(kTwoJoint, "lower=\"-1\" upper=\"1\"", "lower=\"-6.283\" upper=\"6.283\""),
                                            "type=\"revolute\">\n    <parent link=\"b\"/>", "type=\"continuous\">\n    <parent link=\"b\"/>"));
  test::CliRun r = test::runAccuraIn(dir, "fk --robot r.urdf --q 359.995,0");
  EXPECT_EQ(r.code, 0) << r.err;
  r = test::runAccuraIn(dir, "fk --robot r.urdf --q 360,0");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--q: joint 1 (j1): expected a value within [-359.9893827, 359.9893827], found 360"),
            std::string::npos) << r.err;
  // the continuous joint (-360..360 deg): 539 deg refused, the message says which pose it is
  r = test::runAccuraIn(dir, "fk --robot r.urdf --q 0,539");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("found 539; -360..360 deg is also what a joint without limits (a URDF's continuous joint) is given: 539 deg "
                       "is the pose of 179 deg"),
            std::string::npos) << r.err;
}

TEST(Urdf, ConversionCheckCatchesAWrongModel) {
  // modelFromChain's check is real: compareModelWithChain sees a 1 um change of one length.
  const SerialChain chain = readUrdfChain(sourcePath("tests/data/urdf/irb2400.urdf"));
  RobotModel m = modelFromChain(chain);
  EXPECT_LT(compareModelWithChain(m, chain).max_position_mm, 1e-9);
  m.deviations.links[2].da_mm = 1e-3;
  EXPECT_GT(compareModelWithChain(m, chain).max_position_mm, 1e-4);
}

TEST(Urdf, CommandLine) {
  const std::string dir = test::tempDir("urdf_cli");
  // export: the file, and what it leaves out on stderr
  test::CliRun r = test::runAccuraIn(dir, "export --robot kuka_kr16 --format urdf --out k.urdf");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("not represented: payload centre of mass (0, 0, 100) mm"), std::string::npos) << r.err;
  EXPECT_NE(test::readText(dir + "/k.urdf").find("payload centre of mass"), std::string::npos);
  // the URDF works wherever a robot does, with --chain; same flange pose as the robot file
  const test::CliRun a = test::runAccuraIn(dir, "fk --robot k.urdf --chain base_link:flange --q 10,-80,70,20,30,40");
  const test::CliRun b = test::runAccuraIn(dir, "fk --robot kuka_kr16 --q 10,-80,70,20,30,40");
  ASSERT_EQ(a.code, 0) << a.err;
  EXPECT_EQ(a.out, b.out);
  r = test::runAccuraIn(dir, "fk --robot k.urdf --chain base_link:nowhere --q 0,0,0,0,0,0");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("no link 'nowhere'"), std::string::npos) << r.err;
  r = test::runAccuraIn(dir, "fk --robot kuka_kr16 --chain a:b --q 0,0,0,0,0,0");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("expected a URDF robot"), std::string::npos) << r.err;
  // a malformed URDF: file:line on stderr, exit code 1
  test::writeText(dir + "/bad.urdf", replaced(kTwoJoint, "xyz=\"0.3 0 0\"", "xyz=\"0.3 0 zero\""));
  r = test::runAccuraIn(dir, "fk --robot bad.urdf --q 0,0");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("bad.urdf:13:"), std::string::npos) << r.err;
  // UR's factory calibration -> calibrated robot file -> usable everywhere; deltas back out
  r = test::runAccuraIn(dir, "export --robot ur10 --ur-deltas " + sourcePath("tests/data/urdf/ur_forum_calibration.conf") +
                                 " --format robot --out ur10_cal.xml");
  ASSERT_EQ(r.code, 0) << r.err;
  const RobotModel cal = readRobotFile(dir + "/ur10_cal.xml");
  EXPECT_NE(cal.deviations.links[2].dbeta_rad, 0.0);
  r = test::runAccuraIn(dir, "export --robot ur10_cal.xml --format ur-deltas --out back.conf");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("delta_d = -92.52"), std::string::npos) << r.err;  // flagged
  const UrDeltas back = readUrCalibrationConf(dir + "/back.conf");
  EXPECT_NEAR(back.d_m[2], -92.5270326908668181, 1e-6);  // m, through the robot file's 12 digits
  // the same on ur_description's URDF (UR's table in other frames: rewritten, not refused), and
  // the deltas written back from it name the table they belong to
  r = test::runAccuraIn(dir, "export --robot " + sourcePath("tests/data/urdf/ur10.urdf") + " --ur-deltas " +
                                 sourcePath("tests/data/urdf/ur_forum_calibration.conf") + " --format robot --out urdf_cal.xml");
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::runAccuraIn(dir, "export --robot urdf_cal.xml --format ur-deltas --out back2.conf");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("the deltas are relative to the nominal table of 'ur10' in UR's convention: d = [0.1273, 0, 0, 0.163941, "
                       "0.1157, 0.0922] m, a = [0, -0.612, -0.5723, 0, 0, 0] m, alpha = [90, 0, 0, 90, -90, 0] deg"),
            std::string::npos) << r.err;
  EXPECT_NEAR(readUrCalibrationConf(dir + "/back2.conf").d_m[2], -92.5270326908668181, 1e-6);
  // a chain that is not a UR arm's: the fix named
  r = test::runAccuraIn(dir, "export --robot " + sourcePath("tests/data/urdf/panda_arm.urdf") + " --ur-deltas " +
                                 sourcePath("tests/data/urdf/ur_forum_calibration.conf") + " --format robot --out p.xml");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("UR's factory calibration is for the 6 joints of a UR arm, found 7 joints in 'panda' (from a URDF: "
                       "choose the arm's own chain with --chain ROOT:TIP, e.g. --chain base:tool0 on ur_description's URDF)"),
            std::string::npos) << r.err;
  r = test::runAccuraIn(dir, "export --robot kuka_kr16 --format ur-yaml");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("joint 'A3': a UR table has theta0 0 on every joint, found -90 deg in UR's convention"), std::string::npos) << r.err;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace accura::calib
