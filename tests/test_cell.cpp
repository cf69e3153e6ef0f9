// Cell geometry: meshes read with assimp (STL ASCII and binary, OBJ in metres, PLY quads), the
// cell file and its errors (file:line), FCL distances against analytic distances and a
// brute-force point/triangle distance, and the motion bound of the clearance subdivision.
#include <gtest/gtest.h>

#include <cctype>
#include <limits>
#include <random>
#include <set>

#include "accura/calib/errors.h"
#include "accura/calib/kinematics.h"
#include "accura/postproc/cell.h"
#include "accura/postproc/check.h"
#include "accura_plugin.h"
#include "test_util.h"

namespace accura::postproc {
namespace {

std::string fixture(const std::string& name) { return test::sourcePath("tests/data/cell/" + name); }

void bbox(const Mesh& m, Eigen::Vector3d* lo, Eigen::Vector3d* hi) {
  *lo = m.vertices_mm.front();
  *hi = *lo;
  for (const auto& v : m.vertices_mm) {
    *lo = lo->cwiseMin(v);
    *hi = hi->cwiseMax(v);
  }
}

double area(const Mesh& m) {
  double a = 0;
  for (const auto& t : m.triangles)
    a += 0.5 * (m.vertices_mm[t[1]] - m.vertices_mm[t[0]]).cross(m.vertices_mm[t[2]] - m.vertices_mm[t[0]]).norm();
  return a;
}

// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5).
Eigen::Vector3d closestOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

double bruteForceDistance(const Mesh& m, const Eigen::Isometry3d& T_world_mesh, const Eigen::Vector3d& p_world) {
  const Eigen::Vector3d p = T_world_mesh.inverse() * p_world;
  double best = 1e300;
  for (const auto& t : m.triangles)
    best = std::min(best, (closestOnTriangle(p, m.vertices_mm[t[0]], m.vertices_mm[t[1]], m.vertices_mm[t[2]]) - p).norm());
  return best;
}

TEST(CellMesh, AsciiStlCube) {
  const Mesh m = loadMesh(fixture("box_100mm.stl"), 1.0);
  EXPECT_EQ(m.triangles.size(), 12u);
  std::set<std::array<double, 3>> corners;
  for (const auto& v : m.vertices_mm) corners.insert({v.x(), v.y(), v.z()});
  EXPECT_EQ(corners.size(), 8u);
  Eigen::Vector3d lo, hi;
  bbox(m, &lo, &hi);
  EXPECT_NEAR((lo - Eigen::Vector3d::Constant(-50)).norm(), 0, 1e-9);
  EXPECT_NEAR((hi - Eigen::Vector3d::Constant(50)).norm(), 0, 1e-9);
  EXPECT_NEAR(area(m), 6 * 100.0 * 100.0, 1e-6);
}

TEST(CellMesh, BinaryStlPost) {
  const Mesh m = loadMesh(fixture("post_binary.stl"), 1.0);
  EXPECT_EQ(m.triangles.size(), 12u);
  Eigen::Vector3d lo, hi;
  bbox(m, &lo, &hi);
  EXPECT_NEAR((lo - Eigen::Vector3d(-5, -5, 0)).norm(), 0, 1e-4);
  EXPECT_NEAR((hi - Eigen::Vector3d(5, 5, 600)).norm(), 0, 1e-4);
  EXPECT_NEAR(area(m), 4 * 10.0 * 600.0 + 2 * 100.0, 1e-3);
}

TEST(CellMesh, ObjInMetresScaledToMm) {
  const Mesh m = loadMesh(fixture("plate_m.obj"), 1000.0);
  EXPECT_EQ(m.triangles.size(), 12u);
  Eigen::Vector3d lo, hi;
  bbox(m, &lo, &hi);
  EXPECT_NEAR(lo.norm(), 0, 1e-6);
  EXPECT_NEAR((hi - Eigen::Vector3d(200, 100, 50)).norm(), 0, 1e-4);
  EXPECT_NEAR(area(m), 2 * (200.0 * 100 + 200.0 * 50 + 100.0 * 50), 1e-2);
}

TEST(CellMesh, PlyQuadsAreTriangulated) {
  const Mesh m = loadMesh(fixture("box_quads.ply"), 25.4);  // as if the file were in inches
  EXPECT_EQ(m.triangles.size(), 12u);
  EXPECT_NEAR(area(m), 6 * (100.0 * 25.4) * (100.0 * 25.4), 1e-1);
}

TEST(CellMesh, ErrorsNameTheFile) {
  for (const char* name : {"empty.stl", "not_a_mesh.obj", "missing.stl"}) {
    try {
      loadMesh(fixture(name), 1.0);
      ADD_FAILURE() << name << " was read";
    } catch (const calib::InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("expected"), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(loadMesh(fixture("box_100mm.stl"), 0.0), calib::ArgumentError);
}

std::string writeCell(const std::string& dir, const std::string& body) {
  const std::string path = dir + "/cell.xml";
  test::writeText(path, "<?xml version=\"1.0\"?>\n<cell name=\"t\">\n" + body + "</cell>\n");
  return path;
}

TEST(CellFile, ReadsObjectsRobotToolLinksAndThresholds) {
  const std::string dir = test::tempDir("cell_read");
  const std::string stl = fixture("box_100mm.stl"), obj = fixture("plate_m.obj");
  const std::string path = writeCell(dir,
                                     "  <thresholds joint_margin_deg=\"2.5\" min_clearance_mm=\"8\"/>\n"
                                     "  <robot x_mm=\"100\" y_mm=\"-50\" z_mm=\"0\" a_deg=\"90\"/>\n"
                                     "  <object name=\"box\" file=\"" + stl + "\" units=\"mm\" x_mm=\"1000\" z_mm=\"300\" c_deg=\"30\"/>\n"
                                     "  <object name=\"plate\" file=\"" + obj + "\" units=\"m\"/>\n"
                                     "  <link joint=\"3\"><capsule x0_mm=\"0\" y0_mm=\"0\" z0_mm=\"0\" x1_mm=\"0\" y1_mm=\"0\" z1_mm=\"-600\" radius_mm=\"90\"/></link>\n"
                                     "  <tool file=\"" + stl + "\" units=\"cm\" z_mm=\"50\"/>\n");
  const Cell c = readCellFile(path);
  ASSERT_EQ(c.objects.size(), 2u);
  EXPECT_EQ(c.objects[0].name, "box");
  EXPECT_NEAR((c.objects[0].T_parent_shape.translation() - Eigen::Vector3d(1000, 0, 300)).norm(), 0, 1e-12);
  EXPECT_NEAR((c.objects[0].T_parent_shape.linear() - calib::rotationZYX(0, 0, 30 * calib::kDegToRad)).norm(), 0, 1e-12);
  EXPECT_EQ(c.objects[0].line, 5);
  ASSERT_TRUE(c.T_world_base.has_value());
  EXPECT_NEAR((c.T_world_base->translation() - Eigen::Vector3d(100, -50, 0)).norm(), 0, 1e-12);
  EXPECT_NEAR((c.T_world_base->linear() - calib::rotationZYX(calib::kPi / 2, 0, 0)).norm(), 0, 1e-12);
  ASSERT_EQ(c.link_shapes.size(), 1u);
  EXPECT_EQ(c.link_shapes[0].first, 3);
  ASSERT_TRUE(c.link_shapes[0].second.capsule.has_value());
  EXPECT_EQ(c.link_shapes[0].second.capsule->radius_mm, 90);
  ASSERT_EQ(c.tool_shapes.size(), 1u);
  Eigen::Vector3d lo, hi;
  bbox(*c.tool_shapes[0].mesh, &lo, &hi);
  EXPECT_NEAR(hi.x(), 500, 1e-9);  // cm -> mm
  EXPECT_EQ(c.thresholds.joint_margin_deg, 2.5);
  EXPECT_EQ(c.thresholds.min_clearance_mm, 8);
  EXPECT_EQ(c.thresholds.singular_threshold, CheckThresholds{}.singular_threshold);  // documented default
}

// Every error names file:line:column (1-based; the column of the attribute's name for an
// attribute, of the element's '<' for an element) and what was expected and found. The
// expected column is where the test's own text has that attribute or tag (`at`: the
// occurrence of the needle on the error's line, `nth` counting from 0 for a repeated one).
TEST(CellFile, ErrorsGiveFileLineColumnExpectedFound) {
  const std::string dir = test::tempDir("cell_errors");
  const std::string stl = fixture("box_100mm.stl");
  struct Case {
    std::string body;
    int line;
    std::string at;  // the attribute or tag the error is at ("" : no column, malformed XML)
    std::string says;
    int nth = 0;
  };
  const std::string cap = "<capsule x0_mm=\"0\" y0_mm=\"0\" z0_mm=\"0\" x1_mm=\"0\" y1_mm=\"0\" z1_mm=\"1\" radius_mm=\"2\"/>";
  const std::vector<Case> cases = {
      {"  <object name=\"a\" file=\"" + stl + "\" units=\"mm\"/>\n  <object name=\"b\" file=\"" + stl + "\" units=\"yard\"/>\n", 4, "units=",
       "expected mm, cm, m, inch or ft, found 'yard'"},
      {"  <object name=\"a\" file=\"" + stl + "\" units=\"mm\" x_mm=\"1O0\"/>\n", 3, "x_mm=", "expected a number, found '1O0'"},
      {"  <object name=\"a\" file=\"" + stl + "\" units=\"mm\" color=\"red\"/>\n", 3, "color=", "found 'color'"},
      {"\n\n  <fixture name=\"a\"/>\n", 5, "<fixture", "found <fixture>"},
      {"  <object name=\"a\" file=\"" + stl + "\"/>\n", 3, "<object", "expected the attribute units"},
      {"  <object name=\"a\" file=\"nowhere.stl\" units=\"mm\"/>\n", 3, "file=", "nowhere.stl"},
      {"  <object name=\"a\" file=\"" + fixture("empty.stl") + "\" units=\"mm\"/>\n", 3, "file=", "empty.stl"},
      {"  <tool><capsule x0_mm=\"0\" y0_mm=\"0\" z0_mm=\"0\" x1_mm=\"0\" y1_mm=\"0\" z1_mm=\"1\" radius_mm=\"-2\"/></tool>\n", 3, "radius_mm=",
       "expected a positive radius"},
      {"  <link joint=\"0\">" + cap + "</link>\n", 3, "joint=", "expected the joint number"},
      // two elements on one line: the second <object>'s name (a repeated name), and an attribute
      // name that also occurs inside another attribute's value and a comment before it
      {"  <object name=\"a\">" + cap + "</object> <object name=\"a\">" + cap + "</object>\n", 3, "name=", "expected a unique name", 1},
      {"  <!-- <tool name=\"1\"> --><tool x_mm=\"name=\" name=\"1\"/>\n", 3, "name=", "found 'name'", 2},
      // an attribute on a continuation line of its element
      {"  <object name=\"a\"\n          file=\"" + stl + "\"\n   units=\"yards\"/>\n", 5, "units=", "found 'yards'"},
      {"  <thresholds min_clearance_mm=\"-1\"/>\n", 3, "min_clearance_mm=", "expected a distance >= 0"},
      {"  <robot/><robot x_mm=\"1\"/>\n", 3, "<robot", "found a second one", 1},
      {"  <tool><sphere/></tool>\n", 3, "<sphere", "expected <capsule> children only"},
      {"  <object name=\"a\" file=\"" + stl + "\" units=\"mm\">\n", 0, "", "expected well-formed XML"},
  };
  for (const Case& c : cases) {
    const std::string path = writeCell(dir, c.body);
    try {
      readCellFile(path);
      ADD_FAILURE() << "accepted: " << c.body;
    } catch (const calib::InputError& e) {
      EXPECT_NE(std::string(e.what()).find(c.says), std::string::npos) << e.what();
      EXPECT_EQ(e.file(), path);
      if (c.line == 0) {
        EXPECT_GT(e.line(), 0) << e.what();  // tinyxml2 gives the line of malformed XML, not the column
        continue;
      }
      // the expected column: the needle's occurrence on that line of the file's text
      const std::string text = test::readText(path);
      size_t start = 0;
      for (int l = 1; l < c.line; ++l) start = text.find('\n', start) + 1;
      const std::string line = text.substr(start, text.find('\n', start) - start);
      size_t at = line.find(c.at);
      for (int k = 0; k < c.nth; ++k) at = line.find(c.at, at + 1);
      ASSERT_NE(at, std::string::npos) << c.at;
      const int column = static_cast<int>(at) + 1;
      EXPECT_EQ(e.line(), c.line) << e.what();
      EXPECT_EQ(e.column(), column) << e.what();
      EXPECT_EQ(std::string(e.what()).rfind(path + ":" + std::to_string(c.line) + ":" + std::to_string(column) + ": ", 0), 0u) << e.what();
    }
  }
  // the columns of a few of them, counted by hand: "  <object name=..." has '<' at 3 and
  // "name" at 11
  try {
    readCellFile(writeCell(dir, "  <object name=\"a\" units=\"mm\"/>\n"));
    ADD_FAILURE();
  } catch (const calib::InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(dir + "/cell.xml:3:20: <object>: expected units only with a file attribute", 0), 0u) << e.what();
  }
  try {
    readCellFile(writeCell(dir, "  <object name=\"\"/>\n"));
    ADD_FAILURE();
  } catch (const calib::InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(dir + "/cell.xml:3:11: <object>: expected a non-empty attribute name, found an empty one", 0), 0u)
        << e.what();
  }
  try {
    readCellFile(writeCell(dir, "  <object/>\n"));
    ADD_FAILURE();
  } catch (const calib::InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(dir + "/cell.xml:3:3: <object>: expected a non-empty attribute name, found none", 0), 0u) << e.what();
  }
}

// What an element holds besides its attributes is never ignored: a <capsule> inside a capsule
// (a 300 mm torch body that would be left out of the clearance check) and text in any element
// are errors at the child's '<' or the text's first character.
TEST(CellFile, ChildrenAndTextWhereTheFormatHasNoneAreErrors) {
  const std::string dir = test::tempDir("cell_content");
  const std::string cap = "<capsule x0_mm=\"0\" y0_mm=\"0\" z0_mm=\"0\" x1_mm=\"0\" y1_mm=\"0\" z1_mm=\"60\" radius_mm=\"20\"";
  struct Case {
    std::string body, at, says;
  };
  const std::vector<Case> cases = {
      {"  <tool>" + cap + "><capsule x0_mm=\"0\" y0_mm=\"0\" z0_mm=\"0\" x1_mm=\"0\" y1_mm=\"0\" z1_mm=\"900\" radius_mm=\"300\"/></capsule></tool>\n",
       "<capsule x0_mm=\"0\" y0_mm=\"0\" z0_mm=\"0\" x1_mm=\"0\" y1_mm=\"0\" z1_mm=\"900\"", "<capsule>: expected no children, found <capsule>"},
      {"  <tool>" + cap + ">torch</capsule></tool>\n", "torch", "<capsule>: expected no text, found 'torch'"},
      {"  <tool>MIG torch " + cap + "/></tool>\n", "MIG", "<tool>: expected no text, found 'MIG torch'"},
      {"  <object name=\"post\">" + cap + "/>60 mm</object>\n", "60 mm", "<object>: expected no text, found '60 mm'"},
      {"  <thresholds min_clearance_mm=\"5\">10</thresholds>\n", "10", "<thresholds>: expected no text, found '10'"},
      {"  <robot z_mm=\"10\">500</robot>\n", "500", "<robot>: expected no text, found '500'"},
      {"  <tool>" + cap + "/></tool> fixture\n", "fixture", "<cell>: expected no text, found 'fixture'"},
  };
  for (const Case& c : cases) {
    const std::string path = writeCell(dir, c.body);
    try {
      readCellFile(path);
      ADD_FAILURE() << "accepted: " << c.body;
    } catch (const calib::InputError& e) {
      // line 3 (after the declaration and <cell>), the column of the child's '<' or of the text
      const int column = static_cast<int>(c.body.find(c.at)) + 1;
      EXPECT_EQ(std::string(e.what()), path + ":3:" + std::to_string(column) + ": " + c.says) << c.body;
    }
  }
  // comments and white space are no content
  const Cell ok = readCellFile(writeCell(dir, "  <tool>\n    <!-- torch -->\n    " + cap + "/>\n  </tool>\n"));
  ASSERT_EQ(ok.tool_shapes.size(), 1u);
  ASSERT_TRUE(ok.tool_shapes[0].capsule);
  EXPECT_EQ(ok.tool_shapes[0].capsule->radius_mm, 20.0);
}

// The <robot> element's position is kept for the message when it disagrees with --base.
TEST(CellFile, RobotElementPosition) {
  const std::string dir = test::tempDir("cell_robot_pos");
  const Cell c = readCellFile(writeCell(dir, "  <thresholds/>\n    <robot z_mm=\"10\"/>\n"));
  EXPECT_EQ(c.robot_line, 4);
  EXPECT_EQ(c.robot_column, 5);
  ASSERT_TRUE(c.T_world_base);
  EXPECT_NEAR(c.T_world_base->translation().z(), 10, 1e-12);
}

calib::RobotModel kr16() { return test::loadBundled("kuka_kr16"); }

TEST(CellDistance, FclSphereToBoxEqualsAnalyticAndBruteForce) {
  Cell cell;
  CellShape box;
  box.mesh = loadMesh(fixture("box_100mm.stl"), 1.0);
  box.name = "box";
  box.T_parent_shape = calib::toIsometry(calib::XyzAbc{800, -200, 400, 30, -20, 10});
  cell.objects.push_back(box);
  const CellGeometry g(cell, kr16());
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-150, 150);
  int outside = 0;
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector3d p_box(u(rng), u(rng), u(rng));
    const Eigen::Vector3d excess = (p_box.cwiseAbs() - Eigen::Vector3d::Constant(50)).cwiseMax(0.0);
    if (excess.norm() == 0) continue;  // inside the (hollow) box: not a surface distance
    ++outside;
    const double radius = 3.0;
    const double analytic = std::max(0.0, excess.norm() - radius);
    const Eigen::Vector3d p_world = box.T_parent_shape * p_box;
    EXPECT_NEAR(g.sphereDistance(p_world, radius, 0), analytic, 1e-6) << p_box.transpose();
    EXPECT_NEAR(bruteForceDistance(*box.mesh, box.T_parent_shape, p_world) - radius, excess.norm() - radius, 1e-9);
  }
  EXPECT_GT(outside, 150);
}

// Triangles without area (a CAD export's corner repeated, a sliver of three collinear corners)
// are left out: with one in the box, the sphere's distance is the box's (FCL gave 0 mm for a
// sphere 20 mm away).
TEST(CellDistance, TrianglesWithoutAreaAreLeftOut) {
  const std::string dir = test::tempDir("cell_degenerate");
  std::string stl = test::readText(fixture("box_100mm.stl"));
  const size_t end = stl.rfind("endsolid");
  ASSERT_NE(end, std::string::npos);
  stl.insert(end, "facet normal 0 0 0\nouter loop\nvertex 0 0 50\nvertex 0 0 50\nvertex 0 0 50\nendloop\nendfacet\n"
                  "facet normal 0 0 0\nouter loop\nvertex -50 50 50\nvertex 0 50 50\nvertex 50 50 50\nendloop\nendfacet\n");
  test::writeText(dir + "/box.stl", stl);
  const Mesh plain = loadMesh(fixture("box_100mm.stl"), 1.0), degenerate = loadMesh(dir + "/box.stl", 1.0);
  EXPECT_EQ(degenerate.triangles.size(), plain.triangles.size());
  Cell cell;
  CellShape box;
  box.mesh = degenerate;
  box.name = "box";
  cell.objects.push_back(box);
  const CellGeometry g(cell, kr16());
  EXPECT_NEAR(g.sphereDistance(Eigen::Vector3d(0, 0, 80), 10, 0), 20.0, 1e-9);
}

// A facet without area whose normal the exporter wrote as nan or inf (the normals are not used):
// read, the facet left out; a normal that is no number is still an error at it.
TEST(CellMesh, AsciiStlNormalsOfNanOrInfAreRead) {
  const std::string dir = test::tempDir("cell_stl_nan_normal");
  std::string stl = test::readText(fixture("box_100mm.stl"));
  const size_t end = stl.rfind("endsolid");
  ASSERT_NE(end, std::string::npos);
  std::string with = stl;
  with.insert(end, "facet normal nan nan nan\nouter loop\nvertex 0 0 50\nvertex 0 0 50\nvertex 0 0 50\nendloop\nendfacet\n"
                   "facet normal -NaN +inf -Infinity\nouter loop\nvertex -50 50 50\nvertex 0 50 50\nvertex 50 50 50\nendloop\nendfacet\n");
  test::writeText(dir + "/nan.stl", with);
  EXPECT_EQ(loadMesh(dir + "/nan.stl", 1.0).triangles.size(), loadMesh(fixture("box_100mm.stl"), 1.0).triangles.size());
  std::string bad = stl;
  bad.insert(end, "facet normal 0 n/a 0\nouter loop\nvertex 0 0 50\nvertex 1 0 50\nvertex 0 1 50\nendloop\nendfacet\n");
  test::writeText(dir + "/bad.stl", bad);
  const int line = 1 + static_cast<int>(std::count(stl.begin(), stl.begin() + static_cast<long>(end), '\n'));
  try {
    loadMesh(dir + "/bad.stl", 1.0);
    FAIL() << "expected an InputError";
  } catch (const calib::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.stl:" + std::to_string(line) + ":16: expected a component of the facet's normal"),
              std::string::npos) << e.what();
  }
}

// ASCII STL as CAD tools write it: after blank lines and spaces it is read (assimp needs 'solid'
// first); in upper case (which assimp cannot read) it is named so, not a "truncated binary STL".
TEST(CellMesh, AsciiStlAfterBlankLinesAndInUpperCase) {
  const std::string dir = test::tempDir("cell_stl_forms");
  const std::string stl = test::readText(fixture("box_100mm.stl"));
  test::writeText(dir + "/lead.stl", "\n\n  " + stl);
  EXPECT_EQ(loadMesh(dir + "/lead.stl", 1.0).triangles.size(), loadMesh(fixture("box_100mm.stl"), 1.0).triangles.size());
  std::string upper = stl;
  for (char& ch : upper) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
  test::writeText(dir + "/upper.stl", upper);
  try {
    loadMesh(dir + "/upper.stl", 1.0);
    FAIL() << "expected an InputError";
  } catch (const calib::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("upper.stl:1:1: expected an ASCII STL's keywords in lower case"), std::string::npos) << e.what();
  }
  // the box given in metres but read as mm: 0.1 mm across, a unit mistake, named at 1:1
  try {
    loadMesh(fixture("box_100mm.stl"), 0.001);
    FAIL() << "expected an InputError";
  } catch (const calib::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("box_100mm.stl:1:1: expected an object at least 1 mm across, found one of 0.1732 mm"),
              std::string::npos) << e.what();
  }
}

// COLLADA: its <unit> (which assimp applies) must be the cell's units, and its coordinates are
// taken as written (a Z_UP file is not turned to Y-up).
TEST(CellMesh, ColladaUnitAndUpAxis) {
  const std::string dir = test::tempDir("cell_collada");
  // a cube of half size `half` centred at (0, 0, z0), in the file's units
  auto dae = [&](const std::string& name, const std::string& meter, const std::string& up, double half, double z0) {
    std::string pos;
    for (int k = 0; k < 8; ++k)
      pos += std::to_string((k & 1) ? half : -half) + " " + std::to_string((k & 2) ? half : -half) + " " +
             std::to_string(z0 + ((k & 4) ? half : -half)) + " ";
    const std::string idx = "0 2 1 1 2 3 4 5 6 5 7 6 0 1 4 1 5 4 2 6 3 3 6 7 0 4 2 2 4 6 1 3 5 3 7 5";
    test::writeText(dir + "/" + name,
                    "<?xml version=\"1.0\"?>\n<COLLADA xmlns=\"http://www.collada.org/2005/11/COLLADASchema\" version=\"1.4.1\">\n"
                    "<asset><unit meter=\"" + meter + "\" name=\"u\"/><up_axis>" + up + "</up_axis></asset>\n"
                    "<library_geometries><geometry id=\"g\"><mesh>\n"
                    "<source id=\"p\"><float_array id=\"pa\" count=\"24\">" + pos + "</float_array>"
                    "<technique_common><accessor source=\"#pa\" count=\"8\" stride=\"3\"><param name=\"X\" type=\"float\"/>"
                    "<param name=\"Y\" type=\"float\"/><param name=\"Z\" type=\"float\"/></accessor></technique_common></source>\n"
                    "<vertices id=\"v\"><input semantic=\"POSITION\" source=\"#p\"/></vertices>\n"
                    "<triangles count=\"12\"><input semantic=\"VERTEX\" source=\"#v\" offset=\"0\"/><p>" + idx + "</p></triangles>\n"
                    "</mesh></geometry></library_geometries>\n"
                    "<library_visual_scenes><visual_scene id=\"s\"><node id=\"n\"><instance_geometry url=\"#g\"/></node></visual_scene>"
                    "</library_visual_scenes>\n<scene><instance_visual_scene url=\"#s\"/></scene>\n</COLLADA>\n");
    return dir + "/" + name;
  };
  auto extent = [](const Mesh& m) {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
    for (const auto& v : m.vertices_mm) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
    return std::make_pair(lo, hi);
  };
  // a 100 mm cube in a file in millimetres (Y_UP), the cell saying mm: 100 mm (it was read as 0.1 mm)
  const auto [lo_mm, hi_mm] = extent(loadMesh(dae("mm.dae", "0.001", "Y_UP", 50, 0), 1.0));
  EXPECT_NEAR(hi_mm.x() - lo_mm.x(), 100.0, 1e-4);
  EXPECT_NEAR(hi_mm.z(), 50.0, 1e-4);
  // the same cube 200 mm up in a Z_UP file in metres: as written (it was turned about x, to y 200)
  const auto [lo_z, hi_z] = extent(loadMesh(dae("zup.dae", "1", "Z_UP", 0.05, 0.2), 1000.0));
  EXPECT_NEAR(lo_z.z(), 150.0, 1e-4);
  EXPECT_NEAR(hi_z.z(), 250.0, 1e-4);
  EXPECT_NEAR(hi_z.y(), 50.0, 1e-4);
  // a unit written in single precision (SketchUp's inch) is that unit
  const auto [lo_in, hi_in] = extent(loadMesh(dae("inch.dae", "0.02539999969303608", "Z_UP", 1, 0), 25.4));
  EXPECT_NEAR(hi_in.x() - lo_in.x(), 50.8, 1e-4);
  // the cell's units against the file's own: refused, naming both
  try {
    loadMesh(dae("mm2.dae", "0.001", "Z_UP", 50, 0), 1000.0);
    FAIL() << "expected an InputError";
  } catch (const calib::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("expected the cell's units to be the file's own"), std::string::npos) << e.what();
  }
}

// A sphere on the flange against the box: CellGeometry::distances places the tool with the
// robot's forward kinematics.
TEST(CellDistance, ToolSphereOnTheRobot) {
  const calib::RobotModel robot = kr16();
  Cell cell;
  CellShape box;
  box.mesh = loadMesh(fixture("box_100mm.stl"), 1.0);
  box.name = "box";
  box.T_parent_shape = calib::toIsometry(calib::XyzAbc{1100, 0, 900, 0, 0, 0});
  cell.objects.push_back(box);
  CellShape tool;
  tool.capsule = Capsule{Eigen::Vector3d(0, 0, 120), Eigen::Vector3d(0, 0, 120), 20};
  tool.name = "tool";
  cell.tool_shapes.push_back(tool);
  const CellGeometry g(cell, robot);
  std::mt19937_64 rng(7);
  for (int k = 0; k < 50; ++k) {
    Eigen::VectorXd q = test::randomQ(robot, rng);
    calib::RobotModel flange = robot;
    flange.nominal.T_flange_tcp = Eigen::Isometry3d::Identity();
    const Eigen::Vector3d c_world = calib::forwardKinematics(flange, q) * Eigen::Vector3d(0, 0, 120);
    const Eigen::Vector3d p_box = c_world - Eigen::Vector3d(1100, 0, 900);
    const Eigen::Vector3d excess = (p_box.cwiseAbs() - Eigen::Vector3d::Constant(50)).cwiseMax(0.0);
    if (excess.norm() == 0) continue;
    const double expected = std::max(0.0, excess.norm() - 20);
    const auto d = g.distances(q, calib::PoseContext{}, 1e9);
    ASSERT_EQ(d.size(), 1u);
    EXPECT_NEAR(d[0].mm, expected, 1e-6);
    // beyond exact_below_mm a lower bound may come back, never more than the distance
    const auto lb = g.distances(q, calib::PoseContext{}, 0.0);
    EXPECT_LE(lb[0].mm, expected + 1e-9);
  }
}

// The bounded query (check.h: CellGeometry::distances with exact_below_mm): below the bound
// it gives the unbounded query's distance bit for bit (and the same object), at or above it a
// lower bound in [bound, distance]. Several objects (an STL box, the post, the plate OBJ in
// metres, a capsule) and robot shapes of every kind (tool sphere, tool mesh, link capsule), so
// that the cull by bounding boxes, the bound carried from one object to the next, shape/mesh
// and mesh/mesh queries are all exercised; distance() of one shape equals distances().
TEST(CellDistance, BoundedQueryIsExactBelowTheBoundAndALowerBoundAbove) {
  const calib::RobotModel robot = kr16();
  Cell cell;
  auto object = [&](const std::string& file, double scale, const calib::XyzAbc& at, const std::string& name) {
    CellShape o;
    o.mesh = loadMesh(fixture(file), scale);
    o.T_parent_shape = calib::toIsometry(at);
    o.name = name;
    cell.objects.push_back(o);
  };
  object("box_100mm.stl", 1.0, {1100, 0, 900, 0, 0, 0}, "box");
  object("post_binary.stl", 1.0, {900, 400, 300, 30, 0, 0}, "post");
  object("plate_m.obj", 1000.0, {1000, -500, 500, 0, 0, 0}, "plate");
  CellShape pillar;
  pillar.capsule = Capsule{Eigen::Vector3d(600, -700, 0), Eigen::Vector3d(600, -700, 1500), 80};
  pillar.name = "pillar";
  cell.objects.push_back(pillar);
  CellShape sphere;
  sphere.capsule = Capsule{Eigen::Vector3d(0, 0, 120), Eigen::Vector3d(0, 0, 120), 20};
  sphere.name = "tool";
  cell.tool_shapes.push_back(sphere);
  CellShape tool_mesh;
  tool_mesh.mesh = loadMesh(fixture("box_100mm.stl"), 0.5);
  tool_mesh.T_parent_shape = calib::toIsometry(calib::XyzAbc{0, 0, 40, 0, 0, 0});
  tool_mesh.name = "tool body";
  cell.tool_shapes.push_back(tool_mesh);
  CellShape arm;
  arm.capsule = Capsule{Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, -400), 60};
  arm.name = "link 3";
  cell.link_shapes.emplace_back(3, arm);
  const CellGeometry g(cell, robot);
  ASSERT_EQ(g.robotShapes(), 3);
  std::mt19937_64 rng(11);
  int below = 0, above = 0, second_object = 0;
  for (int k = 0; k < 300; ++k) {
    const Eigen::VectorXd q = test::randomQ(robot, rng);
    const auto exact = g.distances(q, calib::PoseContext{}, std::numeric_limits<double>::infinity());
    for (double bound : {20.0, 105.0, 400.0}) {
      const auto d = g.distances(q, calib::PoseContext{}, bound);
      ASSERT_EQ(d.size(), 3u);
      for (int s = 0; s < 3; ++s) {
        const auto& e = exact[static_cast<size_t>(s)];
        const auto& b = d[static_cast<size_t>(s)];
        EXPECT_FALSE(e.lower_bound);
        EXPECT_EQ(b.robot_shape, s);
        if (e.mm < bound) {
          ++below;
          if (e.object > 0) ++second_object;
          EXPECT_EQ(b.mm, e.mm) << "q " << q.transpose() << " shape " << s << " bound " << bound;  // bit for bit
          EXPECT_EQ(b.object, e.object);
          EXPECT_FALSE(b.lower_bound);
        } else {
          ++above;
          EXPECT_TRUE(b.lower_bound);
          EXPECT_GE(b.mm, bound);
          EXPECT_LE(b.mm, e.mm);
        }
        const auto one = g.distance(s, q, calib::PoseContext{}, bound);
        EXPECT_EQ(one.mm, b.mm);
        EXPECT_EQ(one.object, b.object);
        EXPECT_EQ(one.lower_bound, b.lower_bound);
      }
    }
  }
  // both sides of the bound were exercised, and objects other than the first nearest
  EXPECT_GT(below, 150);
  EXPECT_GT(above, 150);
  EXPECT_GT(second_object, 20);
  EXPECT_THROW(g.distance(3, Eigen::VectorXd::Zero(6), calib::PoseContext{}, 1.0), calib::ArgumentError);
}

// The motion bound of the subdivision: no point of a shape moves further than
// sum_i |dtheta_i| leverArm(shape, i) when the joints move linearly from q_a to q_b.
TEST(CellDistance, MotionBoundHoldsOnRandomMoves) {
  const calib::RobotModel robot = kr16();
  Cell cell;
  for (int j = 1; j <= 6; ++j) {
    CellShape s;
    s.capsule = Capsule{Eigen::Vector3d(30, -40, 10), Eigen::Vector3d(-200, 50, -300), 60};
    s.name = "link " + std::to_string(j);
    cell.link_shapes.emplace_back(j, s);
  }
  CellShape tool;
  tool.capsule = Capsule{Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0, 100, 250), 15};
  tool.name = "tool";
  cell.tool_shapes.push_back(tool);
  CellShape floor;
  floor.capsule = Capsule{Eigen::Vector3d(0, 0, -5000), Eigen::Vector3d(0, 0, -5000), 1};
  floor.name = "far";
  cell.objects.push_back(floor);
  const CellGeometry g(cell, robot);
  ASSERT_EQ(g.robotShapes(), 7);
  EXPECT_EQ(g.leverArm(0, 1), 0.0);  // joint 2 does not move link 1
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> step(-8, 8);
  calib::KinematicWorkspace ws;
  double tightest = 0;
  // 200 moves are 860000 FK evaluations: 30 s under the sanitizers, which check the code on 25
  const int moves = test::kUnderSanitizers ? 25 : 200;
  for (int k = 0; k < moves; ++k) {
    const Eigen::VectorXd qa = test::randomQ(robot, rng);
    Eigen::VectorXd qb = qa;
    for (int i = 0; i < 6; ++i) qb[i] += step(rng);
    for (int s = 0; s < 7; ++s) {
      const int frame = s < 6 ? s + 1 : 6;
      const Capsule& cap = s < 6 ? cell.link_shapes[static_cast<size_t>(s)].second.capsule.value() : tool.capsule.value();
      double bound = 0;
      for (int i = 0; i < 6; ++i) bound += std::fabs(qb[i] - qa[i]) * calib::kDegToRad * g.leverArm(s, i);
      // the path length of surface points of the capsule (end caps, farthest from the axes)
      double moved = 0;
      for (const Eigen::Vector3d& c : std::vector<Eigen::Vector3d>{cap.p0_mm, cap.p1_mm})
        for (const Eigen::Vector3d& dir : std::vector<Eigen::Vector3d>{Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ(),
                                                                     -Eigen::Vector3d::UnitX(), -Eigen::Vector3d::UnitY(), -Eigen::Vector3d::UnitZ()}) {
          const Eigen::Vector3d p = c + cap.radius_mm * dir;
          double len = 0;
          Eigen::Vector3d last;
          for (int t = 0; t <= 50; ++t) {
            calib::forwardKinematics(robot, qa + (qb - qa) * (t / 50.0), calib::PoseContext{}, ws);
            const Eigen::Vector3d w = ws.T_base_frame[static_cast<size_t>(frame)] * p;
            if (t > 0) len += (w - last).norm();
            last = w;
          }
          moved = std::max(moved, len);
        }
      EXPECT_LE(moved, bound) << "shape " << s;
      tightest = std::max(tightest, moved / bound);
    }
  }
  EXPECT_GT(tightest, 0.3);  // a bound, but not a uselessly loose one
}

// A cell file's <link joint="7"> on a six-axis robot (a cell made for a seventh axis, or for
// another robot): the error was an ArgumentError at the <capsule>'s '<' (3:20), and a plug-in
// host got ACCURA_ERROR_INVALID_ARGUMENT, the status of its own wrong argument, for a mistake in
// the user's cell file. Now it is an InputError at the joint attribute (3:9), as joint="0" is,
// and the plug-in's accura_check_program says ACCURA_ERROR_INPUT.
TEST(CellDistance, ALinkOfAJointTheRobotLacksIsAnErrorOfTheCellFile) {
  const std::string dir = test::tempDir("cell_link_joint");
  const std::string path = writeCell(dir,
                                     "  <tool><capsule x0_mm=\"0\" y0_mm=\"0\" z0_mm=\"0\" x1_mm=\"0\" y1_mm=\"0\" z1_mm=\"9\" radius_mm=\"5\"/></tool>\n"
                                     "  <link joint=\"7\"><capsule x0_mm=\"0\" y0_mm=\"0\" z0_mm=\"0\" x1_mm=\"0\" y1_mm=\"0\" z1_mm=\"1\" radius_mm=\"2\"/></link>\n");
  const Cell cell = readCellFile(path);
  try {
    CellGeometry g(cell, kr16());
    ADD_FAILURE() << "accepted a link of joint 7";
  } catch (const calib::InputError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), 4);
    EXPECT_EQ(e.column(), 9);
    EXPECT_EQ(e.message(), "<link> joint: expected 1..6 (the robot has 6 joints), found 7");
  }
  // the plug-in: an error of the input file
  const std::string program = dir + "/p.src";
  test::writeText(program, "DEF p( )\n$TOOL={X 0,Y 0,Z 0,A 0,B 0,C 0}\n$BASE={X 0,Y 0,Z 0,A 0,B 0,C 0}\nPTP {X 1000,Y 0,Z 800,A 0,B 90,C 0}\nEND\n");
  accura_model* m = nullptr;
  ASSERT_EQ(accura_model_create(&m), ACCURA_OK);
  ASSERT_EQ(accura_model_load(m, "kuka_kr16", nullptr), ACCURA_OK);
  accura_check_options o;
  ASSERT_EQ(accura_check_options_init(&o, sizeof(o)), ACCURA_OK);
  accura_check_summary summary{};
  EXPECT_EQ(accura_check_program(m, path.c_str(), program.c_str(), &o, &summary, nullptr, 0), ACCURA_ERROR_INPUT);
  const char* message = nullptr;
  accura_last_error(m, &message);
  EXPECT_EQ(std::string(message ? message : ""),
            "accura_check_program: " + path + ":4:9: <link> joint: expected 1..6 (the robot has 6 joints), found 7");
  accura_model_free(m);
}

TEST(CellDistance, LinkOutsideTheRobotIsAnError) {
  Cell cell;
  CellShape s;
  s.capsule = Capsule{Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), 1};
  cell.link_shapes.emplace_back(7, s);
  EXPECT_THROW(CellGeometry(cell, kr16()), calib::ArgumentError);
}

}  // namespace
}  // namespace accura::postproc
