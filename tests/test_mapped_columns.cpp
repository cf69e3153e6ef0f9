// Mapped exports (import.h): a column name that repeats in the header is refused only when the
// mapping uses it; `ignore` ignores every column of a repeated name.
#include <gtest/gtest.h>

#include "accura/calib/errors.h"
#include "accura/calib/import.h"
#include "accura/calib/joint_map.h"
#include "accura/calib/robot_io.h"
#include "test_util.h"

namespace accura::calib {
namespace {

TEST(MappedColumns, ARepeatedNameTheMappingDoesNotUseIsNotRefused) {
  const std::string dir = test::tempDir("mapped_dup");
  const RobotModel robot = readRobotFile(resolveRobotPath("ur10"));
  // an export writing 'std' after every coordinate; the mapping reads the positions only
  const std::string csv = "a;b;c;d;e;f;x;std;y;std;z;std\n"
                          "10;-80;70;20;30;40;100,5;0,01;200;0,02;300;0,03\n"
                          "11;-81;71;21;31;41;101;0,01;201;0,02;301,25;0,03\n";
  test::writeText(dir + "/e.csv", csv);
  const std::string head = "delimiter = ;\ndecimal = ,\njoints = a, b, c, d, e, f\njoint_unit = deg\nposition = x, y, z\nposition_unit = mm\n";
  test::writeText(dir + "/e.map", head);
  MeasurementSet set = readMappedMeasurements(dir + "/e.csv", readMeasurementMapping(dir + "/e.map", robot.nominal), robot.nominal);
  ASSERT_EQ(set.rows.size(), 2u);
  EXPECT_DOUBLE_EQ(set.rows[0].p_world_mm.x(), 100.5);
  EXPECT_DOUBLE_EQ(set.rows[1].p_world_mm.z(), 301.25);
  EXPECT_DOUBLE_EQ(set.rows[1].q[5], 41.0);
  // the three 'std' columns are reported unused, each of them
  EXPECT_EQ(set.unknown_columns, (std::vector<std::string>{"std", "std", "std"}));
  // 'ignore = std' ignores all three
  test::writeText(dir + "/i.map", head + "ignore = std\n");
  set = readMappedMeasurements(dir + "/e.csv", readMeasurementMapping(dir + "/i.map", robot.nominal), robot.nominal);
  EXPECT_TRUE(set.unknown_columns.empty());
  EXPECT_EQ(set.rows.size(), 2u);
  // mapping the repeated name is ambiguous: refused at its second column (field 10 of line 1)
  test::writeText(dir + "/s.map", head + "position_std = std\n");
  try {
    (void)readMappedMeasurements(dir + "/e.csv", readMeasurementMapping(dir + "/s.map", robot.nominal), robot.nominal);
    ADD_FAILURE() << "a mapped column name that repeats was read";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 1);
    EXPECT_EQ(e.column(), 10);
    EXPECT_EQ(e.message(), "expected each column name once in the header, found 'std' a second time (first as column 8)");
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace accura::calib

namespace accura::calib {
namespace {

TEST(MappedColumns, DegreesReadAsRadiansAndARepeatedHeaderAreSaidSo) {
  const std::string dir = test::tempDir("mapped_unit");
  const RobotModel robot = readRobotFile(resolveRobotPath("ur10"));
  const std::string head = "delimiter = ;\ndecimal = .\njoints = a, b, c, d, e, f\njoint_unit = rad\nposition = x, y, z\nposition_unit = mm\n";
  test::writeText(dir + "/e.map", head);
  const MeasurementMapping m = readMeasurementMapping(dir + "/e.map", robot.nominal);
  // degrees in a column the mapping reads as radians: 100 rad is 5730 deg (beyond the UR10's
  // +-360), 100 deg is within them: the unit is suspected, naming the mapping's line
  test::writeText(dir + "/deg.csv", "a;b;c;d;e;f;x;y;z\n0.1;-1.2;1;0.3;0.4;0.5;1;2;3\n100;-80;70;20;30;40;1;2;3\n");
  try {
    (void)readMappedMeasurements(dir + "/deg.csv", m, robot.nominal);
    ADD_FAILURE() << "degrees read as radians";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.column(), 1);
    const std::string w = e.message();
    EXPECT_NE(w.find("found 5729.58 deg (100 rad)"), std::string::npos) << w;
    EXPECT_NE(w.find("the column looks like degrees"), std::string::npos) << w;
    EXPECT_NE(w.find("joint_unit = rad in " + dir + "/e.map:4"), std::string::npos) << w;
    EXPECT_EQ(w.find("within a turn"), std::string::npos) << w;
  }
  // the header again on line 4 (two exports joined): said as such, at line 4 column 1
  test::writeText(dir + "/two.csv", "a;b;c;d;e;f;x;y;z\n0.1;-1.2;1;0.3;0.4;0.5;1;2;3\n0.2;-1.2;1;0.3;0.4;0.5;1;2;3\n"
                                    "a;b;c;d;e;f;x;y;z\n0.3;-1.2;1;0.3;0.4;0.5;1;2;3\n");
  try {
    (void)readMappedMeasurements(dir + "/two.csv", m, robot.nominal);
    ADD_FAILURE() << "a repeated header read";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 4);
    EXPECT_EQ(e.column(), 1);
    EXPECT_NE(e.message().find("found the header row again (the header is line 1)"), std::string::npos) << e.message();
  }
  std::filesystem::remove_all(dir);
}

TEST(MappedColumns, AnExportWithCrLineEndsOrInUtf16IsNamedAsSuch) {
  const std::string dir = test::tempDir("mapped_text");
  const RobotModel robot = readRobotFile(resolveRobotPath("ur10"));
  test::writeText(dir + "/e.map", "delimiter = ;\ndecimal = ,\njoints = a, b, c, d, e, f\njoint_unit = deg\nposition = x, y, z\n"
                                  "position_unit = mm\n");
  const MeasurementMapping m = readMeasurementMapping(dir + "/e.map", robot.nominal);
  const std::string header = "a;b;c;d;e;f;x;y;z", row = "10;-80;70;20;30;40;100,5;200;300";
  const auto errorOf = [&](const std::string& text) {
    test::writeText(dir + "/e.csv", text);
    try {
      (void)readMappedMeasurements(dir + "/e.csv", m, robot.nominal);
      ADD_FAILURE() << "read";
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  // lines ending in CR only (a classic Mac OS export): was "e.csv:1:1: expected at least one data
  // row after the header, found none" (the file read as one line)
  EXPECT_EQ(errorOf(header + "\r" + row + "\r" + row + "\r"),
            dir + "/e.csv:1:1: expected lines that end in LF or CRLF, found a CR without LF after the text of line 1 (lines that end "
                  "in CR only, as classic Mac OS exports write them, 'CSV (Macintosh)'?): the file would read as one line; convert its "
                  "line ends (e.g. tr '\\r' '\\n' < in.csv > out.csv)");
  // UTF-16 (a spreadsheet's "Unicode Text"): was "e.csv:1:1: expected a column 'a' in the header, found none"
  std::string utf16 = "\xFF\xFE";
  for (char c : header + "\r\n" + row + "\r\n") utf16 += std::string(1, c) + '\0';
  EXPECT_EQ(errorOf(utf16), dir + "/e.csv:1:1: expected UTF-8 or ASCII text, found UTF-16 (the byte-order mark FF FE at the start of "
                                  "the file): save the export as UTF-8 text (a spreadsheet's 'CSV UTF-8', not 'Unicode Text')");
  // CRLF, a BOM and no final line end are read as before
  test::writeText(dir + "/ok.csv", "\xEF\xBB\xBF" + header + "\r\n" + row + "\r\n" + row);
  EXPECT_EQ(readMappedMeasurements(dir + "/ok.csv", m, robot.nominal).rows.size(), 2u);
  std::filesystem::remove_all(dir);
}

TEST(MappedColumns, ASignAfterAPlusIsNoNumber) {
  const std::string dir = test::tempDir("mapped_sign");
  const RobotModel robot = readRobotFile(resolveRobotPath("ur10"));
  test::writeText(dir + "/e.map", "delimiter = tab\ndecimal = .\njoints = a, b, c, d, e, f\njoint_unit = deg\nposition = x, y, z\n"
                                  "position_unit = m\n");
  const MeasurementMapping m = readMeasurementMapping(dir + "/e.map", robot.nominal);
  // '+-1.5' was read as -1.5 m (accura's own CSV refuses it); '+1.5' stays 1.5
  test::writeText(dir + "/e.csv", "a\tb\tc\td\te\tf\tx\ty\tz\n10\t-80\t70\t20\t30\t40\t+1.5\t0.2\t0.3\n10\t-80\t70\t20\t30\t40\t+-1.5\t0.2\t0.3\n");
  try {
    (void)readMappedMeasurements(dir + "/e.csv", m, robot.nominal);
    ADD_FAILURE() << "'+-1.5' read as a number";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), dir + "/e.csv:3:7: column 'x': expected a number with '.' as decimal mark, found '+-1.5'");
  }
  test::writeText(dir + "/ok.csv", "a\tb\tc\td\te\tf\tx\ty\tz\n10\t-80\t70\t20\t30\t40\t+1.5\t+.2\t-0.3\n");
  const MeasurementSet set = readMappedMeasurements(dir + "/ok.csv", m, robot.nominal);
  ASSERT_EQ(set.rows.size(), 1u);
  EXPECT_DOUBLE_EQ(set.rows[0].p_world_mm.x(), 1500.0);
  EXPECT_DOUBLE_EQ(set.rows[0].p_world_mm.y(), 200.0);
  EXPECT_DOUBLE_EQ(set.rows[0].p_world_mm.z(), -300.0);
  std::filesystem::remove_all(dir);
}

TEST(MappedColumns, TheHeaderAgainAfterAByteOrderMarkIsNamed) {
  // two exports with a byte-order mark each, joined byte for byte (cat a.csv b.csv): was
  // "two.csv:3:1: column 'a': expected a number with ',' as decimal mark, found '\xEF\xBB\xBF\"a\"'"
  const std::string dir = test::tempDir("mapped_bom_header");
  const RobotModel robot = readRobotFile(resolveRobotPath("ur10"));
  test::writeText(dir + "/e.map", "delimiter = ;\ndecimal = ,\njoints = a, b, c, d, e, f\njoint_unit = deg\nposition = x, y, z\n"
                                  "position_unit = mm\n");
  const std::string one = "\xEF\xBB\xBF\"a\";\"b\";\"c\";\"d\";\"e\";\"f\";\"x\";\"y\";\"z\"\r\n10;-80;70;20;30;40;100,5;200;300\r\n";
  test::writeText(dir + "/two.csv", one + one);
  try {
    (void)readMappedMeasurements(dir + "/two.csv", readMeasurementMapping(dir + "/e.map", robot.nominal), robot.nominal);
    ADD_FAILURE() << "a repeated header read";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), dir + "/two.csv:3:1: expected a data row, found the header row again (the header is line 1): two "
                                           "exports joined into one file? Split them, or delete the repeated header");
  }
  std::filesystem::remove_all(dir);
}

TEST(MappedColumns, OrientationInDegreesReadAsRadiansIsSaidSo) {
  // Euler angles in degrees under orientation_unit = rad: -178.9 rad is -10250 deg, beyond the
  // plausible range; was only "expected an angle within +-1e+04 deg, found '-178,9' (-10250.3 deg)"
  const std::string dir = test::tempDir("mapped_angle_unit");
  const RobotModel robot = readRobotFile(resolveRobotPath("ur10"));
  test::writeText(dir + "/e.map", "delimiter = ;\ndecimal = ,\njoints = a, b, c, d, e, f\njoint_unit = deg\nposition = x, y, z\n"
                                  "position_unit = mm\norientation = euler_intrinsic_xyz: rx, ry, rz\norientation_unit = rad\n");
  const MeasurementMapping m = readMeasurementMapping(dir + "/e.map", robot.nominal);
  test::writeText(dir + "/e.csv", "a;b;c;d;e;f;x;y;z;rx;ry;rz\n10;-80;70;20;30;40;100;200;300;0,5;-0,25;3\n"
                                  "10;-80;70;20;30;40;100;200;300;-90,5;-20,1;-178,9\n");
  try {
    (void)readMappedMeasurements(dir + "/e.csv", m, robot.nominal);
    ADD_FAILURE() << "degrees read as radians";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), dir + "/e.csv:3:12: column 'rz': expected an angle within +-1e+04 deg, found '-178,9' "
                                           "(-10250.2 deg): an angle beyond a turn in radians, and within a turn as degrees: the column "
                                           "looks like degrees, not the radians the mapping states (orientation_unit = rad in " +
                                           dir + "/e.map:8); check the mapping's orientation_unit");
  }
  std::filesystem::remove_all(dir);
}

TEST(MappedColumns, ExcursionsBelowTheRangeToleranceAreNotOutsideTheFit) {
  // a model with joint compliance fitted on j2 in -120..-30 deg: 5.7e-5 deg beyond (1e-6 rad, the
  // rounding of a radian export) is within kFitRangeTolerance (1e-3 deg); 2e-3 deg beyond is outside
  RobotModel model = readRobotFile(resolveRobotPath("ur10"));
  model.deviations.compliance.assign(6, 0.0);
  model.deviations.compliance[1] = 1e-6;
  model.deviations.fit_range.assign(6, JointRange{-170, 170});
  model.deviations.fit_range[1] = JointRange{-120, -30};
  EXPECT_DOUBLE_EQ(kFitRangeTolerance, 1e-3);
  Eigen::VectorXd q(6);
  q << 0, -30 + 1e-6 * 180 / 3.14159265358979, 20, 0, 0, 0;
  EXPECT_TRUE(outsideFitRanges(model, q).empty());
  q[1] = -120 - 5.7e-5;
  EXPECT_TRUE(outsideFitRanges(model, q).empty());
  q[1] = -30 + 2e-3;
  const auto out = outsideFitRanges(model, q);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].joint, 2);
  EXPECT_NEAR(out[0].beyond, 2e-3, 1e-12);
}

}  // namespace
}  // namespace accura::calib
