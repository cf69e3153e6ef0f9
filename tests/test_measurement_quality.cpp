// What a data set is worth before anything is fitted to it: a mapping that reads one column in
// two roles, rows written twice, the same data given twice, few distinct configurations, gross
// outliers a least-squares fit lets through, a validation from another station, a joint that
// never moves. Each is refused or said, with the numbers it rests on.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "accura/calib/diagnose.h"
#include "accura/calib/errors.h"
#include "accura/calib/identify.h"
#include "accura/calib/import.h"
#include "accura/calib/measurements.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"
#include "test_util.h"

namespace accura::calib {
namespace {

using test::CliRun;

// A mapping that gives one column of the export two roles is refused at the second mention
// (mapping file:line:column), naming the first: the column would be read as two quantities at
// once (a position both x and y, a temperature also a weight, a position also ignored).
TEST(MeasurementQuality, AMappingThatReadsOneColumnInTwoRolesIsRefused) {
  const std::string dir = test::tempDir("mq_map_twice");
  const RobotModel robot = readRobotFile(resolveRobotPath("ur10"));
  const std::string head = "delimiter = ;\n"              // 1
                           "decimal = ,\n"                // 2
                           "joints = J1, J2, J3, J4, J5, J6\n"  // 3
                           "joint_unit = deg\n";          // 4
  struct Case {
    std::string tail;  // lines 5..
    int line, column;
    std::string message;
  };
  const std::vector<Case> cases = {
      {"position = X, X, Z\nposition_unit = mm\n", 5, 15,
       "key 'position': expected each column in one role, found column 'X' mapped twice (first as position, line 5)"},
      {"position = X, Y, Z\nposition_unit = mm\ntemperature_c = Temp\n# the weight\nweight =  temp\n", 9, 11,
       "key 'weight': expected each column in one role, found column 'temp' mapped twice (first as temperature_c, line 7)"},
      {"position = X, Y, Z\nposition_unit = mm\nignore = Point ID, X\n", 7, 20,
       "key 'ignore': expected each column in one role, found column 'X' mapped twice (first as position, line 5)"},
      {"position = X, Y, Z\nposition_unit = mm\norientation = kuka_abc: A, B, J6\norientation_unit = deg\n", 7, 31,
       "key 'orientation': expected each column in one role, found column 'J6' mapped twice (first as joints, line 3)"},
  };
  for (const Case& c : cases) {
    test::writeText(dir + "/m.map", head + c.tail);
    try {
      (void)readMeasurementMapping(dir + "/m.map", robot.nominal);
      ADD_FAILURE() << "a column mapped twice was accepted:\n" << c.tail;
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), dir + "/m.map");
      EXPECT_EQ(e.line(), c.line) << c.tail;
      EXPECT_EQ(e.column(), c.column) << c.tail;
      EXPECT_EQ(e.message(), c.message);
    }
  }
  // the same columns each in one role: read
  test::writeText(dir + "/m.map", head + "position = X, Y, Z\nposition_unit = mm\ntemperature_c = Temp\nignore = Point ID\n");
  EXPECT_NO_THROW((void)readMeasurementMapping(dir + "/m.map", robot.nominal));
  // the command says where: exit 1, map:line:column
  test::writeText(dir + "/m.map", head + cases[0].tail);
  test::writeText(dir + "/e.csv", "J1;J2;J3;J4;J5;J6;X;Y;Z\n1;2;3;4;5;6;100;200;300\n");
  const CliRun r = test::runAccura("identify --robot ur10 --map " + dir + "/m.map --data " + dir + "/e.csv --out " + dir + "/o.xml");
  EXPECT_EQ(r.code, 1) << r.out << r.err;
  EXPECT_NE(r.err.find(dir + "/m.map:5:15: key 'position': expected each column in one role, found column 'X' mapped twice"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/o.xml"));
}

// A simulated KR 16 campaign (geometric errors, tracker 3 m away, 0.02 mm noise per axis) of
// `poses` distinct configurations, positions only, and the robot it measured.
struct Campaign {
  RobotModel nominal, truth;
  MeasurementSet set;
};
Campaign campaign(int poses, std::uint64_t seed, const std::string& file = "fit.csv") {
  Campaign c;
  c.nominal = test::loadBundled("kuka_kr16");
  SimulateOptions o;
  o.seed = seed;
  o.poses = poses;
  o.noise_mm = 0.02;
  o.tool = {80, 40, 150, 0, 0, 0};
  o.set_tool = true;
  c.truth = perturbModel(c.nominal, o);
  c.set = simulateMeasurements(c.truth, o);
  c.set.file = file;
  return c;
}

bool anyWarning(const std::vector<std::string>& warnings, const std::string& part) {
  return std::any_of(warnings.begin(), warnings.end(), [&](const std::string& w) { return w.find(part) != std::string::npos; });
}

// Fewer than 10 equations per parameter from distinct configurations is warned about whether or
// not some rows repeat a configuration (the warning was only given when one did): 25 distinct
// poses give 75 position equations for the 33 candidates of the KR 16's geometric model
// (6 base + 3 tool + 24 joint parameters), 2.3 per parameter.
TEST(MeasurementQuality, FewDistinctConfigurationsAreWarnedAboutWithoutRepeats) {
  const Campaign c = campaign(25, 61);
  IdentifySummary s;
  identify(c.nominal, c.set, IdentifyOptions{}, &s);
  EXPECT_EQ(s.poses, 25);
  EXPECT_EQ(s.configurations, 25);
  EXPECT_EQ(s.independent_equations, 75);
  EXPECT_EQ(static_cast<int>(s.parameters.size() + s.fixed.size()), 33);
  EXPECT_TRUE(s.few_configurations);
  EXPECT_TRUE(anyWarning(s.warnings, "few distinct joint configurations: 25 poses, each its own joint configuration: 75 independent "
                                     "equations for 33 parameters, fewer than 10 per parameter"))
      << ::testing::PrintToString(s.warnings);
  // 110 poses: 330 equations, 10 per parameter: no warning
  const Campaign enough = campaign(110, 62);
  IdentifySummary e;
  identify(enough.nominal, enough.set, IdentifyOptions{}, &e);
  EXPECT_EQ(e.independent_equations, 330);
  EXPECT_FALSE(e.few_configurations);
  EXPECT_FALSE(anyWarning(e.warnings, "few distinct joint configurations")) << ::testing::PrintToString(e.warnings);
  // the command prints it with --quiet too
  const std::string dir = test::tempDir("mq_few");
  writeMeasurementsCsv(dir + "/few.csv", c.set, 6);
  const CliRun r = test::runAccura("identify --robot kuka_kr16 --tool 80,40,150 --data " + dir + "/few.csv --holdout 0 --quiet --out " +
                                   dir + "/o.xml");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("WARNING: few distinct joint configurations: 25 poses, each its own joint configuration: 75 independent equations"),
            std::string::npos)
      << r.out;
}

}  // namespace
}  // namespace accura::calib
