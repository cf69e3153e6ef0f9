// Mapped exports (import.h): a column name that repeats in the header is refused only when the
// mapping uses it; `ignore` ignores every column of a repeated name.
#include <gtest/gtest.h>

#include "accura/calib/errors.h"
#include "accura/calib/import.h"
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
