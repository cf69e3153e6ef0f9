// Instrument exports read through mapping files: conventions, units, decimal comma, errors.
#include <gtest/gtest.h>

#include <functional>
#include <random>

#include "accura/calib/errors.h"
#include "accura/calib/identify.h"
#include "accura/calib/import.h"
#include "accura/calib/kinematics.h"
#include "test_util.h"

namespace accura::calib {
namespace {

Eigen::Matrix3d R(char axis, double deg) {
  const Eigen::Vector3d a = axis == 'x' ? Eigen::Vector3d::UnitX() : axis == 'y' ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitZ();
  return Eigen::AngleAxisd(deg * kDegToRad, a).toRotationMatrix();
}

TEST(Import, RotationConventions) {
  const Eigen::Vector3d a(10, -25, 40);
  const Eigen::Vector3d r = a * kDegToRad;
  EXPECT_TRUE(rotationFromAngles("euler_intrinsic_xyz", r).isApprox(R('x', 10) * R('y', -25) * R('z', 40), 1e-12));
  EXPECT_TRUE(rotationFromAngles("euler_extrinsic_xyz", r).isApprox(R('z', 40) * R('y', -25) * R('x', 10), 1e-12));
  EXPECT_TRUE(rotationFromAngles("kuka_abc", r).isApprox(R('z', 10) * R('y', -25) * R('x', 40), 1e-12));
  EXPECT_TRUE(rotationFromAngles("euler_intrinsic_zyz", r).isApprox(R('z', 10) * R('y', -25) * R('z', 40), 1e-12));
  EXPECT_THROW(rotationFromAngles("euler_intrinsic_xqz", r), ArgumentError);
}

const char* kMap =
    "# test export\n"
    "delimiter = ;\n"
    "decimal = ,\n"
    "joints = J1, J2, J3, J4, J5, J6\n"
    "joint_unit = rad\n"
    "position = Pos X, Pos Y, Pos Z\n"
    "position_unit = m\n"
    "orientation = euler_intrinsic_xyz: RX, RY, RZ\n"
    "orientation_unit = deg\n"
    "position_std = SX, SY, SZ\n"
    "orientation_std = SR\n"
    "temperature_c = T\n"
    "ignore = Stamp\n";

RobotDefinition kr16() { return test::loadBundled("kuka_kr16").nominal; }

TEST(Import, ReadsDecimalCommaRadiansMetresAndEulerStds) {
  const std::string dir = test::tempDir("import_ok");
  test::writeText(dir + "/e.map", kMap);
  test::writeText(dir + "/e.csv",
                  "Stamp;J1;J2;J3;J4;J5;J6;Pos X;Pos Y;Pos Z;RX;RY;RZ;SX;SY;SZ;SR;T;Extra\n"
                  "1;0,5;-1;1,2;0;0,3;-0,1;1,25;-0,5;0,75;10;-25;40;0,00001;0,00002;0,00003;0,002;21,5;x\n");
  const MeasurementMapping m = readMeasurementMapping(dir + "/e.map", kr16());
  const MeasurementSet s = readMappedMeasurements(dir + "/e.csv", m, kr16());
  ASSERT_EQ(s.rows.size(), 1u);
  const Measurement& r = s.rows[0];
  EXPECT_NEAR(r.q[0], 0.5 * 180 / kPi, 1e-9);
  EXPECT_NEAR(r.q[1], -180 / kPi, 1e-9);
  EXPECT_NEAR(r.p_world_mm.x(), 1250, 1e-9);
  EXPECT_NEAR(r.p_world_mm.y(), -500, 1e-9);
  EXPECT_NEAR(r.p_world_mm.z(), 750, 1e-9);
  EXPECT_NEAR(r.std_mm.z(), 0.03, 1e-12);
  EXPECT_TRUE(r.R_world_tcp.toRotationMatrix().isApprox(R('x', 10) * R('y', -25) * R('z', 40), 1e-12));
  EXPECT_NEAR(r.temp_c, 21.5, 1e-12);
  // isotropic Euler stds: the world-axis stds follow from J = [x0, Rx y0, Rx Ry z0] (columns
  // the world directions of the three rotation axes), Sigma = s^2 J J^T.
  Eigen::Matrix3d J;
  J.col(0) = Eigen::Vector3d::UnitX();
  J.col(1) = R('x', 10) * Eigen::Vector3d::UnitY();
  J.col(2) = R('x', 10) * R('y', -25) * Eigen::Vector3d::UnitZ();
  const Eigen::Matrix3d S = 0.002 * 0.002 * J * J.transpose();
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(r.std_rot_deg[k], std::sqrt(S(k, k)), 1e-9);
  ASSERT_EQ(s.unknown_columns.size(), 1u);
  EXPECT_EQ(s.unknown_columns[0], "Extra");
  // the same export with every field in double quotes (spreadsheet style; a quoted field may
  // hold the delimiter, "" is one quote): the same numbers
  test::writeText(dir + "/q.csv",
                  "\"Stamp\";\"J1\";\"J2\";\"J3\";\"J4\";\"J5\";\"J6\";\"Pos X\";\"Pos Y\";\"Pos Z\";\"RX\";\"RY\";\"RZ\";\"SX\";\"SY\";\"SZ\";\"SR\";\"T\";\"Extra\"\n"
                  "\"1;a\";\"0,5\";\"-1\";\"1,2\";\"0\";\"0,3\";\"-0,1\";\"1,25\";\"-0,5\";\"0,75\";\"10\";\"-25\";\"40\";\"0,00001\";\"0,00002\";"
                  "\"0,00003\";\"0,002\";\"21,5\";\"say \"\"x\"\"\"\n");
  const MeasurementSet q = readMappedMeasurements(dir + "/q.csv", m, kr16());
  ASSERT_EQ(q.rows.size(), 1u);
  EXPECT_EQ(q.rows[0].q, r.q);
  EXPECT_EQ(q.rows[0].p_world_mm, r.p_world_mm);
  EXPECT_NEAR(q.rows[0].temp_c, 21.5, 1e-12);
  EXPECT_TRUE(s.ignored_absent_columns.empty());
  // the same export without the column the mapping leaves out (another series of the same data
  // set, written without its time stamp): the same numbers, the name said (was an error: the
  // whole file refused for a column nobody reads)
  test::writeText(dir + "/n.csv",
                  "J1;J2;J3;J4;J5;J6;Pos X;Pos Y;Pos Z;RX;RY;RZ;SX;SY;SZ;SR;T\n"
                  "0,5;-1;1,2;0;0,3;-0,1;1,25;-0,5;0,75;10;-25;40;0,00001;0,00002;0,00003;0,002;21,5\n");
  const MeasurementSet n = readMappedMeasurements(dir + "/n.csv", m, kr16());
  ASSERT_EQ(n.rows.size(), 1u);
  EXPECT_EQ(n.rows[0].q, r.q);
  EXPECT_EQ(n.rows[0].p_world_mm, r.p_world_mm);
  EXPECT_EQ(n.rows[0].R_world_tcp.coeffs(), r.R_world_tcp.coeffs());
  EXPECT_EQ(n.ignored_absent_columns, std::vector<std::string>{"Stamp"});
  EXPECT_TRUE(n.unknown_columns.empty());
}

// An export whose units are not the ones read: 30 KR 16 poses written in `pos_unit` (mm or m) and
// `joint_unit` (deg or rad), read through a mapping stating `map_pos` and `map_joint` (lines 5
// and 7), or as accura's CSV when `map_joint` is empty. What identify says.
std::string identifyWithWrongUnits(const std::string& name, const std::string& pos_unit, const std::string& joint_unit,
                                   const std::string& map_joint, const std::string& map_pos, std::string* dir_out,
                                   const std::string& position_columns = "px, py, pz") {
  const std::string dir = *dir_out = test::tempDir(name);
  const RobotModel robot = test::loadBundled("kuka_kr16");
  std::mt19937_64 rng(7);
  const bool own = map_joint.empty();
  std::string csv = own ? "q1,q2,q3,q4,q5,q6,x,y,z\n" : "a1,a2,a3,a4,a5,a6,px,py,pz\n";
  for (int k = 0; k < 30; ++k) {
    const Eigen::VectorXd q = test::randomQ(robot, rng);
    const Eigen::Vector3d p = forwardKinematics(robot, q).translation() * (pos_unit == "m" ? 1e-3 : 1.0);
    const Eigen::VectorXd qw = q * (joint_unit == "rad" ? kDegToRad : 1.0);
    char row[300];
    std::snprintf(row, sizeof row, "%.9f,%.9f,%.9f,%.9f,%.9f,%.9f,%.7f,%.7f,%.7f\n", qw[0], qw[1], qw[2], qw[3], qw[4], qw[5], p.x(), p.y(), p.z());
    csv += row;
  }
  test::writeText(dir + "/e.csv", csv);
  MeasurementSet s;
  if (own) {
    s = readMeasurementsCsv(dir + "/e.csv", robot.nominal);
  } else {
    test::writeText(dir + "/u.map",
                    "# the export's units as the mapping states them\n"
                    "delimiter = ,\ndecimal = .\n"
                    "joints = a1, a2, a3, a4, a5, a6\n"
                    "joint_unit = " + map_joint + "\n"        // line 5
                    "position = " + position_columns + "\n"
                    "position_unit = " + map_pos + "\n");     // line 7
    s = readMappedMeasurements(dir + "/e.csv", readMeasurementMapping(dir + "/u.map", robot.nominal), robot.nominal);
  }
  try {
    identify(robot, s, IdentifyOptions{}, nullptr);
  } catch (const InputError& e) {
    const std::string w = e.what();
    const size_t cut = w.find("mm RMS about their centre); ");
    return cut == std::string::npos ? w : w.substr(cut + 28);
  }
  return "fitted";
}

// An export in millimetres read through a mapping that says metres: identify says the factor it
// finds between the measured points and the model's and the mapping line to change (before: only
// "check the units the mapping states (joint_unit = deg (e.map:5), position_unit = m (e.map:7)),
// the joint order and the robot file", and the RMS of 947064.9 mm the user had to read as a
// factor 1000 himself). The same for an export in metres read as mm, joint angles in radians
// read as degrees and the reverse, and accura's CSV written in metres or radians.
TEST(Import, IdentifyNamesTheFactorAndTheMappingLineWhenTheUnitsAreWrong) {
  std::string dir, said;
  said = identifyWithWrongUnits("units_mm_as_m", "mm", "deg", "deg", "m", &dir);
  EXPECT_EQ(said,
            "the measured positions spread 1000.0 times as far as the model's points: positions in mm read as m (so converted, they lie "
            "0.0 mm RMS from the model's after registration): change position_unit = m (" + dir + "/u.map:7) to mm");
  said = identifyWithWrongUnits("units_m_as_mm", "m", "deg", "deg", "mm", &dir);
  EXPECT_EQ(said,
            "the measured positions spread 1/1000.0 as far as the model's points: positions in m read as mm (so converted, they lie "
            "0.0 mm RMS from the model's after registration): change position_unit = mm (" + dir + "/u.map:7) to m");
  said = identifyWithWrongUnits("units_rad_as_deg", "mm", "rad", "deg", "mm", &dir);
  EXPECT_EQ(said,
            "the joint angles fit at 180/pi times the values read: angles in rad read as deg (so converted, they lie 0.0 mm RMS from the "
            "model's after registration): change joint_unit = deg (" + dir + "/u.map:5) to rad");
  said = identifyWithWrongUnits("units_both", "m", "rad", "deg", "mm", &dir);
  EXPECT_EQ(said,
            "the measured positions spread 1/1000.0 as far as the model's points: positions in m read as mm, and the joint angles fit at "
            "180/pi times the values read: angles in rad read as deg (so converted, they lie 0.0 mm RMS from the model's after "
            "registration): change position_unit = mm (" + dir + "/u.map:7) to m, and change joint_unit = deg (" + dir + "/u.map:5) to rad");
  said = identifyWithWrongUnits("units_own_m", "m", "deg", "", "", &dir);
  EXPECT_EQ(said,
            "the measured positions spread 1/1000.0 as far as the model's points: positions in m read as mm (so converted, they lie 0.0 "
            "mm RMS from the model's after registration): convert the positions to mm (times 1000; accura's CSV is in mm and deg, "
            "docs/measurement-format.md), or read the file through a mapping file with position_unit = m (docs/measurement-mapping.md)");
  // the units right: fitted; y and z swapped (a mirror image, no rigid frame, no unit's factor):
  // what to check, as before
  EXPECT_EQ(identifyWithWrongUnits("units_right", "mm", "deg", "deg", "mm", &dir), "fitted");
  said = identifyWithWrongUnits("units_yz", "mm", "deg", "deg", "mm", &dir, "px, pz, py");
  EXPECT_EQ(said, "check the units the mapping states (joint_unit = deg (" + dir + "/u.map:5), position_unit = mm (" + dir +
                      "/u.map:7)), the joint order and the robot file");
}

TEST(Import, ATrailingDelimiterIsNamedAndReadAsInTheCsvFormat) {
  // an export whose every line ends with ';': the unused column was listed with an empty name
  // ("columns not used by accura: "); on the header or the rows only it is refused, and said
  const std::string dir = test::tempDir("import_trailing");
  test::writeText(dir + "/e.map", kMap);
  const std::string header = "Stamp;J1;J2;J3;J4;J5;J6;Pos X;Pos Y;Pos Z;RX;RY;RZ;SX;SY;SZ;SR;T";
  const std::string row = "1;0,5;-1;1,2;0;0,3;-0,1;1,25;-0,5;0,75;10;-25;40;0,00001;0,00002;0,00003;0,002;21,5";
  test::writeText(dir + "/e.csv", header + ";\n" + row + ";\n");
  const MeasurementMapping m = readMeasurementMapping(dir + "/e.map", kr16());
  const MeasurementSet s = readMappedMeasurements(dir + "/e.csv", m, kr16());
  ASSERT_EQ(s.rows.size(), 1u);
  ASSERT_EQ(s.unknown_columns.size(), 1u);
  EXPECT_EQ(s.unknown_columns[0], "an empty column at the end (a trailing ';')");
  const auto error = [&](const std::string& text) {
    test::writeText(dir + "/e.csv", text);
    try {
      readMappedMeasurements(dir + "/e.csv", m, kr16());
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(error(header + ";\n" + row + "\n"), dir + "/e.csv:2:19: expected 19 fields as in the header, found 18 (the header ends "
                                                   "with ';': an empty column at the end, which every row must have too)");
  EXPECT_EQ(error(header + "\n" + row + ";\n"), dir + "/e.csv:2:19: expected 18 fields as in the header, found 19 (the line ends "
                                                   "with ';', the header does not: a trailing delimiter on the rows only)");
  // a NUL byte in a field: shown, not cut at
  EXPECT_EQ(error(header + "\n" + std::string("1;0,5;-1;1,2;0;0,3;-0,1;1,25;-0,5;0,7\0;10", 41) + row.substr(row.find(";-25")) + "\n"),
            dir + "/e.csv:2:10: column 'Pos Z': expected a number with ',' as decimal mark, found '0,7\\0' (\\0 is a NUL byte: a "
                  "binary or corrupted file?)");
}

// A measurement file given as the mapping, or a mapping given as the measurements (--map and
// --data swapped): the error says which kind of file it is and where each belongs (before: "expected
// 'key = value', found 'Stamp;J1;...'", "expected a column 'J1' in the header, found none", "missing
// columns 'q1', ...": true, but not that the file was the other kind).
TEST(Import, AMeasurementFileGivenAsTheMappingAndAMappingGivenAsTheMeasurementsAreSaidSo) {
  const std::string dir = test::tempDir("import_swapped");
  test::writeText(dir + "/e.map", kMap);
  const std::string header = "Stamp;J1;J2;J3;J4;J5;J6;Pos X;Pos Y;Pos Z;RX;RY;RZ;SX;SY;SZ;SR;T";
  test::writeText(dir + "/e.csv", header + "\n1;0,5;-1;1,2;0;0,3;-0,1;1,25;-0,5;0,75;10;-25;40;0,00001;0,00002;0,00003;0,002;21,5\n");
  test::writeText(dir + "/own.csv", "# accura's own format\nq1,q2,q3,q4,q5,q6,x,y,z\n0,-90,90,0,0,0,1000,0,1200\n");
  const auto error = [](const std::function<void()>& f) {
    try {
      f();
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const std::string to_data =
      ": this looks like a measurement file, not a mapping: its first line is a row of 18 fields separated by ';'; give the "
      "measurements with --data (or --validate) and the mapping (key = value lines, docs/measurement-mapping.md) with --map";
  EXPECT_EQ(error([&] { readMeasurementMapping(dir + "/e.csv", kr16()); }),
            dir + "/e.csv:1:1: expected 'key = value', found '" + header.substr(0, 57) + "...'" + to_data);
  // accura's own CSV as the mapping: its header (after its comment), 9 fields separated by ','
  EXPECT_EQ(error([&] { readMeasurementMapping(dir + "/own.csv", kr16()); }),
            dir + "/own.csv:2:1: expected 'key = value', found 'q1,q2,q3,q4,q5,q6,x,y,z': this looks like a measurement file, not a "
                  "mapping: its first line is a row of 9 fields separated by ','; give the measurements with --data (or --validate) "
                  "and the mapping (key = value lines, docs/measurement-mapping.md) with --map");
  // a mapping's later line without '=' is a mapping's error, not a measurement file
  test::writeText(dir + "/typo.map", std::string(kMap) + "ignore2 ; x, y, z\n");
  EXPECT_EQ(error([&] { readMeasurementMapping(dir + "/typo.map", kr16()); }),
            dir + "/typo.map:14:1: expected 'key = value', found 'ignore2 ; x, y, z'");
  const std::string to_map =
      "this looks like a mapping file, not a measurement file: its first line 'delimiter = ;' is a mapping's key = value; give the "
      "mapping with --map (or --validate-map) and the measurements with --data (or --validate)";
  const MeasurementMapping m = readMeasurementMapping(dir + "/e.map", kr16());
  EXPECT_EQ(error([&] { readMappedMeasurements(dir + "/e.map", m, kr16()); }),
            dir + "/e.map:2:1: expected a header row naming the export's columns, found a line of a mapping: " + to_map);
  EXPECT_EQ(error([&] { readMeasurementsCsv(dir + "/e.map", kr16()); }),
            dir + "/e.map:2:1: expected a header row (q1..q6, x, y, z), found a line of a mapping: " + to_map);
}

void expectError(const std::string& map, const std::string& csv, const std::string& file_suffix, int line, int col,
                 const std::string& words) {
  const std::string dir = test::tempDir("import_bad");
  test::writeText(dir + "/e.map", map);
  test::writeText(dir + "/e.csv", csv);
  try {
    const MeasurementMapping m = readMeasurementMapping(dir + "/e.map", kr16());
    readMappedMeasurements(dir + "/e.csv", m, kr16());
    FAIL() << "expected InputError: " << words;
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), dir + "/" + file_suffix) << e.what();
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_EQ(e.column(), col) << e.what();
    EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
  }
}

TEST(Import, BadMappingsAndRowsSayWhereAndWhat) {
  const std::string header = "Stamp;J1;J2;J3;J4;J5;J6;Pos X;Pos Y;Pos Z;RX;RY;RZ;SX;SY;SZ;SR;T\n";
  const std::string row = "1;0;-1;1;0;0,3;0;1;0;1;0;0;0;0,1;0,1;0,1;0,1;20\n";
  std::string m = kMap;
  expectError(std::string(m).replace(m.find("joint_unit = rad"), 16, "joint_unit = grad"), header + row, "e.map", 5, 14,
              "key 'joint_unit': expected 'deg' or 'rad', found 'grad'");
  expectError(m + "colour = red\n", header + row, "e.map", 14, 1, "unknown key 'colour'");
  expectError(std::string(m).replace(m.find(", J6\n"), 5, "\n"), header + row, "e.map", 4, 10,
              "key 'joints': expected 6 column names, found 5");
  expectError(std::string(m).replace(m.find("euler_intrinsic_xyz"), 19, "euler_sideways_xyz"), header + row, "e.map",
              8, 15, "expected a convention");
  // two turns about one axis in a row: not a rotation convention (two degrees of freedom)
  expectError(std::string(m).replace(m.find("euler_intrinsic_xyz"), 19, "euler_intrinsic_xxz"), header + row, "e.map",
              8, 15, "consecutive ones different: e.g. xyz, zyx, zyz), found 'euler_intrinsic_xxz'");
  expectError(std::string(m).replace(m.find("euler_intrinsic_xyz"), 19, "euler_extrinsic_zzz"), header + row, "e.map",
              8, 15, "found 'euler_extrinsic_zzz'");
  expectError(m, "Stamp;J1;J2;J3;J4;J5;J6;Pos X;Pos Y;RX;RY;RZ;SX;SY;SZ;SR;T\n" + row, "e.csv", 1, 1,
              "expected a column 'Pos Z' in the header, found none (mapped as position in");
  expectError(m, header + "1;0;-1;1;0;0.3;0;1;0;1;0;0;0;0,1;0,1;0,1;0,1;20\n", "e.csv", 2, 6,
              "column 'J5': expected a number with ',' as decimal mark, found '0.3'");
  expectError(m, header + "1;0;-1;1;0;0,3;0;1;0;1;0;0;0;0,1;0,1;0,1;0,1\n", "e.csv", 2, 18,
              "expected 18 fields as in the header, found 17");
  expectError(m, header + "1;0;1;1;0;0,3;0;1;0;1;0;0;0;0,1;0,1;0,1;0,1;20\n", "e.csv", 2, 3,
              "column 'J2': expected a joint value within the joint limits [-155, 35] deg, found 57.2958 deg");
  expectError(m, header + "1;0;-1;1;0;0,3;0;1;0;1;0;0;0;0;0,1;0,1;0,1;20\n", "e.csv", 2, 14,
              "expected a standard deviation > 0");
  expectError(m, header, "e.csv", 1, 1, "expected at least one data row after the header");
  // absurd values: the CSV reader's ranges (implausibleMeasuredValue), in accura's units after the
  // mapping's scale (the mutation campaign: a position of 4294967297 left identify to diverge)
  expectError(m, header + "1;0;-1;1;0;0,3;0;1;4294967297,5;1;0;0;0;0,1;0,1;0,1;0,1;20\n", "e.csv", 2, 9,
              "column 'Pos Y': expected a position within +-1e+07 mm, found '4294967297,5'");
  expectError(m, header + "1;0;-1;1;0;0,3;0;1;0;1;0;0;0;0,1;0,1;0,1;0,1;1e5\n", "e.csv", 2, 18,
              "column 'T': expected a temperature from -273.15 to 1e+04 deg C, found '1e5'");
  expectError(m, header + "1;0;-1;1;0;0,3;0;1;0;1;0;0;0;1e-12;0,1;0,1;0,1;20\n", "e.csv", 2, 14,
              "column 'SX': expected a standard deviation from 1e-06 to 1e+06, found '1e-12' (1e-09 mm)");
  // whole-file errors at 1:1 (fuzz_mapping, the mutation campaign): a mapping without a key, an empty export
  expectError("", header + row, "e.map", 1, 1, "expected a key 'delimiter', found none");
  expectError(m, "", "e.csv", 1, 1, "expected a header row, found an empty file");
}

}  // namespace
}  // namespace accura::calib
