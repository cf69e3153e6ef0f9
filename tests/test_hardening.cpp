// Issue 14, cell input: the reproducers of tests/data/hardening/ (each crashed, hung or was
// half-read) run through `accura check` on a copy and give exit 1 with the located message,
// writing nothing; and loadMesh / readCellFile reject the neighbouring malformations (a
// truncated binary STL, a face count that wraps assimp's 32-bit size check, blank, hex and
// out-of-range numbers) with file:line:column, expected and found, while well-formed PLY, STL
// and OBJ files still read to the geometry they hold.
#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <limits>
#include <set>

#include "accura/calib/errors.h"
#include "accura/postproc/cell.h"
#include "test_util.h"

namespace accura::postproc {
namespace {

namespace fs = std::filesystem;

/// A copy of a folder of tests/data/hardening/ in a fresh temporary directory, removed again
/// when the test ends (the reproducers are read-only and some commands used to overwrite
/// their inputs).
class Scratch {
 public:
  explicit Scratch(const std::string& name, const std::string& data_folder = "") {
    dir_ = fs::temp_directory_path() / ("accura_hardening_" + std::to_string(::getpid()) + "_" + name);
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    if (!data_folder.empty()) {
      for (const auto& e : fs::directory_iterator(test::sourcePath("tests/data/hardening/" + data_folder))) {
        fs::copy_file(e.path(), dir_ / e.path().filename());
        fs::permissions(dir_ / e.path().filename(), fs::perms::owner_read | fs::perms::owner_write, fs::perm_options::add);
      }
    }
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string dir() const { return dir_.string(); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  /// Names and contents of the files in the directory (the CLI's .stdout/.stderr aside).
  std::set<std::pair<std::string, std::string>> snapshot() const {
    std::set<std::pair<std::string, std::string>> s;
    for (const auto& e : fs::recursive_directory_iterator(dir_)) {
      const std::string name = e.path().filename().string();
      if (name == ".stdout" || name == ".stderr") continue;
      s.insert({fs::relative(e.path(), dir_).string(), e.is_regular_file() ? test::readText(e.path().string()) : "<dir>"});
    }
    return s;
  }

 private:
  fs::path dir_;
};

struct Reproducer {
  const char* folder;
  const char* message;  ///< the whole error line accura prints
};

// The message of each reproducer, to the letter: the cell file's place of the <object> or
// <capsule> attribute, then the mesh file's line:column (binary: byte offset), what was
// expected and what was found.
const Reproducer kReproducers[] = {
    {"MIN1_ply_face_index_segv",
     "accura: error: cell.xml:3:20: <object> file 'm.ply': m.ply:13:7: expected a vertex index 0..2 in 'face' 1 of 1, found 2147483647\n"},
    {"MIN2_ply_face_index_oob_read_exit0",
     "accura: error: cell.xml:3:20: <object> file 'm.ply': m.ply:13:7: expected a vertex index 0..2 in 'face' 1 of 1, found 7\n"},
    {"MIN3_ply_header_truncated_hang",
     "accura: error: cell.xml:3:20: <object> file 'm.ply': m.ply:4:1: expected a PLY header line (format, element, property, comment, "
     "obj_info, end_header), found 'end_hea'\n"},
    {"MIN4_ply_missing_faces_abort",
     "accura: error: cell.xml:3:20: <object> file 'm.ply': m.ply:13:1: expected 'face' 1 of 1, found the end of the file (a truncated file?)\n"},
    {"MIN5_ply_binary_truncated_segv",
     "accura: error: cell.xml:3:20: <object> file 'm.ply': m.ply: at byte 169: expected x of 'vertex' 1 of 3 (4 bytes), found the end of the "
     "file (a truncated file?)\n"},
    {"MIN6_cell_capsule_1e300_fcl_abort",
     "accura: error: cell.xml:4:78: <capsule> z1_mm: expected a value within +-100000 mm (100 m: no robot cell is larger), found -1e300\n"},
    {"MIN7_cell_capsule_long_hang",
     "accura: error: cell.xml:4:18: <capsule> x0_mm: expected a value within +-100000 mm (100 m: no robot cell is larger), found 2147483648\n"},
    {"D14_half_read_mesh_accepted",
     "accura: error: cell.xml:3:20: <object> file 't.stl': t.stl:7:12: expected 'endfacet', found the end of the file (a truncated file?)\n"},
};

TEST(Hardening, CellReproducersExitOneWithTheLocatedMessageAndWriteNothing) {
  for (const Reproducer& r : kReproducers) {
    SCOPED_TRACE(r.folder);
    const Scratch s(r.folder, r.folder);
    const auto before = s.snapshot();
    const auto start = std::chrono::steady_clock::now();
    const test::CliRun run = test::runAccuraIn(s.dir(), "check --robot kuka_kr16 --cell cell.xml --in p.src");
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_EQ(run.code, 1) << run.err;
    EXPECT_EQ(run.err, r.message);
    EXPECT_EQ(run.out, "");
    EXPECT_EQ(s.snapshot(), before);  // nothing written, nothing changed
    EXPECT_LT(seconds, 30.0);         // MIN3 looped for ever, MIN7 ran for minutes (s; a loaded sanitizer build takes < 2)
  }
}

TEST(Hardening, CompensateWithTheFclAbortCellWritesNothing) {
  const Scratch s("min6_compensate", "MIN6_cell_capsule_1e300_fcl_abort");
  const auto before = s.snapshot();
  const test::CliRun run = test::runAccuraIn(s.dir(), "compensate --robot kuka_kr16 --cell cell.xml --in p.src --out out");
  EXPECT_EQ(run.code, 1) << run.err;
  EXPECT_NE(run.err.find("cell.xml:4:78: <capsule> z1_mm: expected a value within +-100000 mm"), std::string::npos) << run.err;
  EXPECT_EQ(s.snapshot(), before);  // no out/ directory, no program
}

TEST(Hardening, ObjCutInsideItsLastFace) {
  const Scratch s("d14_obj", "D14_half_read_mesh_accepted");
  try {
    loadMesh(s.path("t.obj"), 1.0);
    ADD_FAILURE() << "the cut OBJ was read";
  } catch (const calib::InputError& e) {
    EXPECT_EQ(e.line(), 6);
    EXPECT_EQ(e.column(), 6);
    EXPECT_EQ(e.message(), "'f': expected 3 or more vertex references, found 2 (a truncated line?)");
  }
  // the same file with its face complete and its last line ended reads as 2 triangles
  test::writeText(s.path("t.obj"), "v 0 0 0\nv 100 0 0\nv 0 100 0\nv 100 100 0\nf 1 2 3\nf 2 4 3\n");
  const Mesh m = loadMesh(s.path("t.obj"), 1.0);
  EXPECT_EQ(m.triangles.size(), 2u);
  EXPECT_EQ(m.vertices_mm.size(), 4u);
}

/// The InputError loadMesh throws for a file of this text (fails the test when it reads).
calib::InputError meshError(const Scratch& s, const std::string& name, const std::string& text, double scale = 1.0) {
  test::writeText(s.path(name), text);
  try {
    loadMesh(s.path(name), scale);
  } catch (const calib::InputError& e) {
    return e;
  }
  ADD_FAILURE() << name << " was read: " << text.substr(0, 200);
  return calib::InputError("");
}

const char* kPlyHeader =
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n";

TEST(Hardening, PlyBodiesAreCheckedLineByLine) {
  const Scratch s("ply");
  const std::string v = "0 0 0\n100 0 0\n0 100 0\n";
  // well-formed: one triangle of area 5000 mm^2
  test::writeText(s.path("ok.ply"), kPlyHeader + v + "3 0 1 2\n");
  const Mesh ok = loadMesh(s.path("ok.ply"), 1.0);
  ASSERT_EQ(ok.triangles.size(), 1u);
  const auto& t = ok.triangles[0];
  EXPECT_NEAR(0.5 * (ok.vertices_mm[t[1]] - ok.vertices_mm[t[0]]).cross(ok.vertices_mm[t[2]] - ok.vertices_mm[t[0]]).norm(), 5000.0, 1e-9);

  struct Case {
    std::string body;
    int line, column;
    std::string message;
  };
  const Case cases[] = {
      {v + "3 0 1 -1\n", 13, 7, "expected a vertex index 0..2 in 'face' 1 of 1, found -1"},
      {v + "3 0 1\n", 13, 6, "expected 3 values of vertex_indices in 'face' 1 of 1 on line 13, found 2 (a truncated line?)"},
      {v + "2 0 1\n", 13, 1, "expected a face of 3 or more vertices ('face' 1 of 1), found 2"},
      {v + "3 0 1 2\n4 5 6\n", 14, 1, "expected the end of the file after the declared elements, found '4'"},
      {"0 0 0\n100 0 nan\n0 100 0\n3 0 1 2\n", 11, 7, "expected z of 'vertex' 2 of 3 (a finite decimal number), found 'nan'"},
      {"0 0 0\n100 0 0x10\n0 100 0\n3 0 1 2\n", 11, 7, "expected z of 'vertex' 2 of 3 (a finite decimal number), found '0x10'"},
      {"0 0 0\n100 0 0 7\n0 100 0\n3 0 1 2\n", 11, 9, "expected the end of 'vertex' 2 of 3 (one element a line), found '7'"},
      {"0 0 0\n100000.5 0 0\n0 100 0\n3 0 1 2\n", 11, 1,
       "x of 'vertex' 2 of 3: expected a coordinate within 100 m of the mesh origin, found 100000.500000 (100.000500 m)"},
      {v + "300 0 1 2\n", 13, 1, "expected the number of values of vertex_indices in 'face' 1 of 1 (an integer 0..255), found '300'"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.body);
    const calib::InputError e = meshError(s, "m.ply", kPlyHeader + c.body);
    EXPECT_EQ(e.line(), c.line);
    EXPECT_EQ(e.column(), c.column);
    EXPECT_EQ(e.message(), c.message);
  }
  // a coordinate within 100 m in metres is beyond it in mm once scaled (scale 1000: 0.2 m is fine, 101 m is not)
  const calib::InputError far = meshError(s, "m.ply", kPlyHeader + std::string("0 0 0\n101 0 0\n0 0.2 0\n3 0 1 2\n"), 1000.0);
  EXPECT_EQ(far.line(), 11);
  EXPECT_NE(far.message().find("found 101.000000 (101.000000 m)"), std::string::npos) << far.what();
  // header errors
  const calib::InputError type = meshError(s, "m.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty flaot x\n");
  EXPECT_EQ(type.line(), 4);
  EXPECT_EQ(type.column(), 10);
  EXPECT_EQ(type.message(), "expected a PLY type (char, uchar, short, ushort, int, uint, float, double, int8 .. float64), found 'flaot'");
  const calib::InputError scalar = meshError(s, "m.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                                                  "element face 1\nproperty int vertex_indices\nend_header\n");
  EXPECT_EQ(scalar.line(), 8);
  EXPECT_EQ(scalar.column(), 10);
  EXPECT_EQ(scalar.message(), "expected the vertex indices of a face as a list of an integer type (property list uchar int vertex_indices), found 'int'");
  const calib::InputError no_end = meshError(s, "m.ply", "ply\nformat ascii 1.0\nelement vertex 0\n");
  EXPECT_EQ(no_end.line(), 4);
  EXPECT_EQ(no_end.message(), "expected the PLY header to end with 'end_header', found the end of the file");
}

std::string le32(uint32_t x) {
  std::string s(4, '\0');
  for (int k = 0; k < 4; ++k) s[static_cast<size_t>(k)] = static_cast<char>((x >> (8 * k)) & 0xff);
  return s;
}
std::string f32(float f) {
  uint32_t b;
  std::memcpy(&b, &f, 4);
  return le32(b);
}

TEST(Hardening, BinaryPlyAndStlSizesAreChecked) {
  const Scratch s("binary");
  // binary PLY: 3 vertices, one face; complete, then one byte short, then a face index of 3
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  std::string body;
  for (const float x : {0.f, 0.f, 0.f, 100.f, 0.f, 0.f, 0.f, 100.f, 0.f}) body += f32(x);
  const std::string face = std::string(1, '\3') + le32(0) + le32(1) + le32(2);
  test::writeText(s.path("ok.ply"), header + body + face);
  EXPECT_EQ(loadMesh(s.path("ok.ply"), 1.0).triangles.size(), 1u);
  const calib::InputError short_face = meshError(s, "m.ply", header + body + face.substr(0, face.size() - 1));
  EXPECT_EQ(short_face.message(),
            "at byte " + std::to_string(header.size() + 36 + 9) + ": expected vertex_indices of 'face' 1 of 1 (4 bytes), found the end of the file (a truncated file?)");
  const calib::InputError index = meshError(s, "m.ply", header + body + std::string(1, '\3') + le32(0) + le32(1) + le32(3));
  EXPECT_EQ(index.message(), "at byte " + std::to_string(header.size() + 36 + 9) + ": expected a vertex index 0..2 in 'face' 1 of 1, found 3");

  // binary STL: 80-byte header, count, 50 bytes a triangle
  std::string tri = f32(0) + f32(0) + f32(1);
  for (const float x : {0.f, 0.f, 0.f, 100.f, 0.f, 0.f, 0.f, 100.f, 0.f}) tri += f32(x);
  tri += std::string(2, '\0');
  const std::string head(80, 'b');
  test::writeText(s.path("ok.stl"), head + le32(1) + tri);
  EXPECT_EQ(loadMesh(s.path("ok.stl"), 1.0).triangles.size(), 1u);
  const calib::InputError cut = meshError(s, "m.stl", head + le32(2) + tri);
  EXPECT_EQ(cut.message(), "at byte 80: expected a binary STL of 84 + 50 x N bytes (N = 2 triangles at byte 80: 184 bytes), found 134 bytes (a truncated file?)");
  // 84 + 50 x 2147483649 = 107374182534 = 25 x 2^32 + 134: 134 in assimp's 32-bit arithmetic
  const calib::InputError wrap = meshError(s, "m.stl", head + le32(2147483649u) + tri);
  EXPECT_EQ(wrap.message(), "at byte 80: expected a binary STL of 84 + 50 x 2147483649 = 107374182534 bytes, found 134 bytes");
  std::string inf_tri = tri;
  inf_tri.replace(12 + 4, 4, f32(std::numeric_limits<float>::infinity()));
  const calib::InputError inf = meshError(s, "m.stl", head + le32(1) + inf_tri);
  EXPECT_EQ(inf.message(), "at byte 100: triangle 1 of 1: expected a finite coordinate, found inf");
}

TEST(Hardening, AsciiStlEndsWithEndsolid) {
  const Scratch s("stl");
  const std::string facet = "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 100 0 0\nvertex 0 100 0\nendloop\nendfacet\n";
  test::writeText(s.path("ok.stl"), "solid t\n" + facet + "endsolid t\n");
  EXPECT_EQ(loadMesh(s.path("ok.stl"), 1.0).triangles.size(), 1u);
  const calib::InputError no_end = meshError(s, "m.stl", "solid t\n" + facet);
  EXPECT_EQ(no_end.line(), 9);
  EXPECT_EQ(no_end.column(), 1);
  EXPECT_EQ(no_end.message(), "expected 'facet' or 'endsolid', found the end of the file (a truncated file?)");
  const calib::InputError two = meshError(s, "m.stl", "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\n");
  EXPECT_EQ(two.line(), 6);
  EXPECT_EQ(two.message(), "expected 'vertex' (a facet has 3 vertices), found 'endloop'");
  const calib::InputError junk = meshError(s, "m.stl", "solid t\n" + facet + "endsolid t\ngarbage\n");
  EXPECT_EQ(junk.line(), 10);
  EXPECT_EQ(junk.message(), "expected 'solid' or the end of the file, found 'garbage'");
}

TEST(Hardening, CellNumbersAreDecimalAndWithinTheCell) {
  const Scratch s("cell");
  fs::copy_file(test::sourcePath("tests/data/cell/box_100mm.stl"), s.path("box.stl"));
  struct Case {
    std::string element, attribute, message;
  };
  const std::string kNumber = "' (a finite decimal number: not blank, hex, inf, nan or beyond 1e308)";
  const Case cases[] = {
      {"<object name=\"b\" file=\"box.stl\" units=\"mm\" x_mm=\" \"/>", "x_mm", "<object> x_mm: expected a number, found ' " + kNumber},
      {"<object name=\"b\" file=\"box.stl\" units=\"mm\" y_mm=\"0x10\"/>", "y_mm", "<object> y_mm: expected a number, found '0x10" + kNumber},
      {"<object name=\"b\" file=\"box.stl\" units=\"mm\" z_mm=\"1e309\"/>", "z_mm", "<object> z_mm: expected a number, found '1e309" + kNumber},
      {"<object name=\"b\" file=\"box.stl\" units=\"mm\" a_deg=\"720\"/>", "a_deg", "<object> a_deg: expected a value within +-360 deg, found 720"},
      {"<robot x_mm=\"-100001\"/>", "x_mm", "<robot> x_mm: expected a value within +-100000 mm (100 m: no robot cell is larger), found -100001"},
      {"<tool><capsule x0_mm=\"0\" y0_mm=\"0\" z0_mm=\"0\" x1_mm=\"0\" y1_mm=\"0\" z1_mm=\"0\" radius_mm=\"2e5\"/></tool>", "radius_mm",
       "<capsule> radius_mm: expected a value within +-100000 mm (100 m: no robot cell is larger), found 2e5"},
      {"<thresholds min_clearance_mm=\"1e6\"/>", "min_clearance_mm",
       "<thresholds> min_clearance_mm: expected a value within +-100000 mm (100 m: no robot cell is larger), found 1e6"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.element);
    test::writeText(s.path("cell.xml"), "<cell name=\"t\">\n  " + c.element + "\n</cell>\n");
    try {
      readCellFile(s.path("cell.xml"));
      ADD_FAILURE() << "read";
    } catch (const calib::InputError& e) {
      EXPECT_EQ(e.file(), s.path("cell.xml"));
      EXPECT_EQ(e.line(), 2);
      // the column of the attribute's name on line 2 ("  " + element), 1-based
      EXPECT_EQ(e.column(), static_cast<int>(("  " + c.element).find(" " + c.attribute + "=")) + 2);
      EXPECT_EQ(e.message(), c.message);
    }
  }
  // blanks around a number are allowed; the placement is read exactly
  test::writeText(s.path("cell.xml"), "<cell name=\"t\">\n  <object name=\"b\" file=\"box.stl\" units=\"mm\" x_mm=\" 1500 \" z_mm=\"-99999.5\"/>\n</cell>\n");
  const Cell cell = readCellFile(s.path("cell.xml"));
  ASSERT_EQ(cell.objects.size(), 1u);
  EXPECT_EQ(cell.objects[0].T_parent_shape.translation(), Eigen::Vector3d(1500, 0, -99999.5));
}

}  // namespace
}  // namespace accura::postproc
