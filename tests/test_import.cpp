// Instrument exports read through mapping files: conventions, units, decimal comma, errors.
#include <gtest/gtest.h>

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

// An export in millimetres read through a mapping that says metres: identify doubts the units
// and names the mapping's unit keys with their lines, the place the user can fix them (before:
// "check the units (positions in mm, joint angles in deg)", accura's own, which the export
// does not have to use).
TEST(Import, IdentifyNamesTheMappingsUnitKeysWhenTheUnitsLookWrong) {
  const std::string dir = test::tempDir("import_units");
  test::writeText(dir + "/mm.map",
                  "# positions said to be in metres\n"
                  "delimiter = ,\ndecimal = .\n"
                  "joints = a1, a2, a3, a4, a5, a6\n"
                  "joint_unit = deg\n"                  // line 5
                  "position = px, py, pz\n"
                  "position_unit = m\n");               // line 7
  const RobotModel robot = test::loadBundled("kuka_kr16");
  std::mt19937_64 rng(7);
  std::string csv = "a1,a2,a3,a4,a5,a6,px,py,pz\n";
  for (int k = 0; k < 30; ++k) {
    const Eigen::VectorXd q = test::randomQ(robot, rng);
    const Eigen::Vector3d p = forwardKinematics(robot, q).translation();  // mm: the export's true unit
    char row[300];
    std::snprintf(row, sizeof row, "%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.4f,%.4f,%.4f\n", q[0], q[1], q[2], q[3], q[4], q[5], p.x(), p.y(), p.z());
    csv += row;
  }
  test::writeText(dir + "/e.csv", csv);
  const MeasurementMapping m = readMeasurementMapping(dir + "/mm.map", robot.nominal);
  const MeasurementSet s = readMappedMeasurements(dir + "/e.csv", m, robot.nominal);
  EXPECT_EQ(s.units_stated, "joint_unit = deg (" + dir + "/mm.map:5), position_unit = m (" + dir + "/mm.map:7)");
  try {
    identify(robot, s, IdentifyOptions{}, nullptr);
    FAIL() << "positions 1000 times too large were fitted";
  } catch (const InputError& e) {
    const std::string w = e.what();
    const std::string tail = "check the units the mapping states (joint_unit = deg (" + dir + "/mm.map:5), position_unit = m (" + dir +
                             "/mm.map:7)), the joint order and the robot file";
    ASSERT_GE(w.size(), tail.size()) << w;
    EXPECT_EQ(w.substr(w.size() - tail.size()), tail) << w;
  }
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
