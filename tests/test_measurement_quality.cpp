// What a data set is worth before anything is fitted to it: a mapping that reads one column in
// two roles, rows written twice, the same data given twice, few distinct configurations, gross
// outliers a least-squares fit lets through, a validation from another station, a joint that
// never moves. Each is refused or said, with the numbers it rests on.
#include <gtest/gtest.h>

#include <random>

#include <nlohmann/json.hpp>

#include "accura/calib/diagnose.h"
#include "accura/calib/errors.h"
#include "accura/calib/identify.h"
#include "accura/calib/import.h"
#include "accura/calib/kinematics.h"
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

// A tracker that did not update writes the last pose's reading again for the next pose: the
// row's measured values equal the row before it to the last bit at another configuration. It is
// named (the row and the row before it) and kept; the same reading at the same configuration is
// a row written twice (duplicatedRows), and equal readings that are not consecutive are not this.
TEST(MeasurementQuality, AReadingWrittenAgainForTheNextPoseIsNamed) {
  Campaign c = campaign(60, 5);
  for (size_t i = 0; i < c.set.rows.size(); ++i) c.set.rows[i].line = static_cast<int>(i) + 2;
  c.set.rows[7].p_world_mm = c.set.rows[6].p_world_mm;     // stale: lines 8 -> 9
  c.set.rows[20].p_world_mm = c.set.rows[12].p_world_mm;   // equal, not consecutive
  c.set.rows[25].q = c.set.rows[24].q;                      // written twice: same configuration
  c.set.rows[25].p_world_mm = c.set.rows[24].p_world_mm;
  const std::vector<DuplicatedRow> stale = staleReadings(c.set);
  ASSERT_EQ(stale.size(), 1u);
  EXPECT_EQ(stale[0].index, 7);
  EXPECT_EQ(stale[0].line, 9);
  EXPECT_EQ(stale[0].same_as_index, 6);
  EXPECT_EQ(stale[0].same_as_line, 8);
  EXPECT_EQ(staleReadingsWarning("fit.csv", stale),
            "1 row(s) of fit.csv carry the measured values of the row before them to the last digit at another joint "
            "configuration (fit.csv:9 = 8): most likely that row's reading written again (an instrument that did not update), "
            "not a measurement of their own pose; they are kept: check them, and delete the rows if so");
  EXPECT_EQ(staleReadingsWarning("fit.csv", {}), "");
  // another payload at the same joints is another pose of the robot too
  Campaign d = campaign(30, 5);
  d.set.rows[11].q = d.set.rows[10].q;
  d.set.rows[11].p_world_mm = d.set.rows[10].p_world_mm;
  d.set.rows[11].context.payload_kg = d.set.rows[10].context.payload_kg + 5;
  ASSERT_EQ(staleReadings(d.set).size(), 1u);
  EXPECT_EQ(staleReadings(d.set)[0].index, 11);
  // the diagnosis says it as a warning, and keeps the row (every pose is diagnosed)
  const Diagnosis diag = diagnose(c.nominal, c.set, nullptr, DiagnoseOptions{});
  EXPECT_TRUE(anyWarning(diag.warnings, "(fit.csv:9 = 8)"));
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

// The file `set` written to `path` and read back (lines as a reader numbers them).
MeasurementSet roundTrip(const MeasurementSet& set, const std::string& path, const RobotModel& robot) {
  writeMeasurementsCsv(path, set, robot.dof());
  return readMeasurementsCsv(path, robot.nominal);
}

// Every third row of a campaign written twice (an export that repeated it): the copies carry no
// information and count once in every statistic. The diagnosis of the file with the copies is
// the diagnosis of the file without them, number for number (held-out errors, floor, ranking,
// spectra, verdict), the copies named; identify's parameters and sigmas are those of the file
// without them (counted twice, the sigmas came out about sqrt(3/4) of these).
TEST(MeasurementQuality, RowsWrittenTwiceCountOnceInEveryStatistic) {
  const std::string dir = test::tempDir("mq_dup");
  const Campaign c = campaign(300, 63);
  const MeasurementSet base = roundTrip(c.set, dir + "/base.csv", c.nominal);
  MeasurementSet twice = c.set;
  twice.rows.clear();
  for (size_t i = 0; i < c.set.rows.size(); ++i) {
    twice.rows.push_back(c.set.rows[i]);
    if (i % 3 == 2) twice.rows.push_back(c.set.rows[i]);
  }
  const MeasurementSet dup = roundTrip(twice, dir + "/dup.csv", c.nominal);
  ASSERT_EQ(dup.rows.size(), 400u);
  const Diagnosis a = diagnose(c.nominal, base, nullptr, DiagnoseOptions{});
  const Diagnosis b = diagnose(c.nominal, dup, nullptr, DiagnoseOptions{});
  EXPECT_EQ(b.fit_poses, 300);
  EXPECT_EQ(b.verdict.effect, a.verdict.effect);
  EXPECT_EQ(b.verdict.explanation, a.verdict.explanation);
  EXPECT_EQ(b.identify_params, a.identify_params);
  EXPECT_EQ(b.baseline.n, a.baseline.n);
  EXPECT_DOUBLE_EQ(b.baseline.rms_mm, a.baseline.rms_mm);
  EXPECT_DOUBLE_EQ(b.baseline.max_mm, a.baseline.max_mm);
  EXPECT_DOUBLE_EQ(b.baseline.p95_mm, a.baseline.p95_mm);
  EXPECT_DOUBLE_EQ(b.noise_floor_mm, a.noise_floor_mm);
  ASSERT_EQ(b.ranking.size(), a.ranking.size());
  for (size_t k = 0; k < a.ranking.size(); ++k) {
    EXPECT_EQ(b.ranking[k].effect, a.ranking[k].effect);
    EXPECT_DOUBLE_EQ(b.ranking[k].p_value, a.ranking[k].p_value) << a.ranking[k].effect;
    EXPECT_DOUBLE_EQ(b.ranking[k].rms_after_mm, a.ranking[k].rms_after_mm) << a.ranking[k].effect;
  }
  ASSERT_EQ(b.spectra.size(), a.spectra.size());
  for (size_t k = 0; k < a.spectra.size(); ++k) {
    EXPECT_EQ(b.spectra[k].peak_cycles, a.spectra[k].peak_cycles);
    EXPECT_DOUBLE_EQ(b.spectra[k].peak_p, a.spectra[k].peak_p) << "j" << a.spectra[k].joint;
    EXPECT_DOUBLE_EQ(b.spectra[k].peak_amplitude_urad, a.spectra[k].peak_amplitude_urad) << "j" << a.spectra[k].joint;
  }
  // named, each against the row it copies, in the text and the JSON: the copies are rows 3, 6,
  // 9, ... of the campaign; in dup.csv the copy of row i (0-based, i % 3 == 2) follows it, on
  // line 2 + i + i / 3 + 1
  ASSERT_EQ(b.floors.duplicated_rows.size(), 100u);
  EXPECT_TRUE(a.floors.duplicated_rows.empty());
  EXPECT_EQ(b.floors.duplicated_rows[0].line_a, 2 + 2 + 0 + 1);
  EXPECT_EQ(b.floors.duplicated_rows[0].line_b, 2 + 2 + 0);
  EXPECT_EQ(b.floors.duplicated_rows[99].line_a, 2 + 299 + 99 + 1);
  EXPECT_EQ(b.floors.duplicated_rows[99].line_b, 2 + 299 + 99);
  const std::string text = diagnosisText(b);
  EXPECT_NE(text.find("accura diagnose: KUKA KR 16, 300 poses from " + dir + "/dup.csv"), std::string::npos) << text;
  EXPECT_NE(text.find("WARNING: 100 row(s) repeat an earlier row of their configuration exactly (every measured value equal): the "
                      "same measurement written twice, counted once (left out of the diagnosis): " +
                      dir + "/dup.csv:5 = " + dir + "/dup.csv:4 "),
            std::string::npos)
      << text;
  const auto j = nlohmann::json::parse(diagnosisJson(b));
  EXPECT_EQ(j["floors"]["duplicated_rows"][99]["row"], dir + "/dup.csv:" + std::to_string(2 + 299 + 99 + 1));
  EXPECT_EQ(j["floors"]["duplicated_rows"][99]["same_as"], dir + "/dup.csv:" + std::to_string(2 + 299 + 99));

  // identify: the same parameters and sigmas, the same count of poses and equations
  IdentifySummary sa, sb;
  identify(c.nominal, base, IdentifyOptions{}, &sa);
  identify(c.nominal, dup, IdentifyOptions{}, &sb);
  EXPECT_EQ(sb.poses, 300);
  EXPECT_EQ(sb.equations, sa.equations);
  ASSERT_EQ(sb.parameters.size(), sa.parameters.size());
  for (size_t k = 0; k < sa.parameters.size(); ++k) {
    EXPECT_DOUBLE_EQ(sb.parameters[k].value, sa.parameters[k].value) << sa.parameters[k].name;
    EXPECT_DOUBLE_EQ(sb.parameters[k].sigma, sa.parameters[k].sigma) << sa.parameters[k].name;
  }
  EXPECT_TRUE(anyWarning(sb.warnings, "100 row(s) of " + dir + "/dup.csv repeat an earlier row of their joint configuration exactly"))
      << ::testing::PrintToString(sb.warnings);
  // the command: the --holdout of the file with the copies is that of the file without them
  const CliRun ra = test::runAccura("identify --robot kuka_kr16 --tool 80,40,150 --data " + dir + "/base.csv --out " + dir +
                                    "/a.xml --json " + dir + "/a.json --quiet");
  const CliRun rb = test::runAccura("identify --robot kuka_kr16 --tool 80,40,150 --data " + dir + "/dup.csv --out " + dir +
                                    "/b.xml --json " + dir + "/b.json --quiet");
  ASSERT_EQ(ra.code, 0) << ra.err;
  ASSERT_EQ(rb.code, 0) << rb.err;
  const auto ja = nlohmann::json::parse(test::readText(dir + "/a.json")), jb = nlohmann::json::parse(test::readText(dir + "/b.json"));
  EXPECT_EQ(jb["validation"], ja["validation"]);
  EXPECT_EQ(jb["parameters"], ja["parameters"]);
  EXPECT_EQ(jb["identifiability"]["poses"], 240);
  EXPECT_NE(rb.out.find("WARNING: 100 row(s) of " + dir + "/dup.csv repeat an earlier row"), std::string::npos) << rb.out;
}

// The same measurements given twice (--data A --data A, or a byte copy of A under another name)
// would count every pose twice, as if measured twice: identify's sigmas sqrt(2) too small (with
// one shared station), the diagnosis' tests too significant. Refused, naming both files, by the
// command and by the library; a file that shares only some rows with another is refused too,
// counting them.
TEST(MeasurementQuality, TheSameDataGivenTwiceIsRefusedNamingBothFiles) {
  const std::string dir = test::tempDir("mq_twice");
  const Campaign c = campaign(120, 64);
  const MeasurementSet a = roundTrip(c.set, dir + "/A.csv", c.nominal);
  std::filesystem::copy_file(dir + "/A.csv", dir + "/A_copy.csv");
  MeasurementSet copy = a;
  copy.file = dir + "/A_copy.csv";
  const std::string same = "expected measurements of its own, found every one of its 120 rows identical to rows of " + dir +
                           "/A.csv (joint values and measured values equal to the last bit; the first: " + dir + "/A_copy.csv:2 = " +
                           dir + "/A.csv:2): the same measurements given twice would count twice";
  for (bool same_station : {false, true}) {
    IdentifyOptions o;
    o.same_station = same_station;
    try {
      identify(c.nominal, std::vector<MeasurementSet>{a, copy}, o, nullptr);
      ADD_FAILURE() << "identify fitted the same data twice";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), dir + "/A_copy.csv");
      EXPECT_EQ(e.line(), 2);
      EXPECT_NE(e.message().find(same), std::string::npos) << e.message();
    }
  }
  try {
    diagnose(c.nominal, std::vector<MeasurementSet>{a, copy}, false, nullptr, DiagnoseOptions{}, nullptr);
    ADD_FAILURE() << "diagnose took the same data twice";
  } catch (const InputError& e) {
    EXPECT_NE(e.message().find(same), std::string::npos) << e.message();
  }
  // a second file of 40 new poses and 10 rows of the first (rows 31..40, lines 33..42)
  const Campaign other = campaign(40, 65);
  MeasurementSet mixed = other.set;
  for (size_t i = 30; i < 40; ++i) mixed.rows.push_back(c.set.rows[i]);
  const MeasurementSet b = roundTrip(mixed, dir + "/B.csv", c.nominal);
  try {
    identify(c.nominal, std::vector<MeasurementSet>{a, b}, IdentifyOptions{}, nullptr);
    ADD_FAILURE() << "identify fitted 10 measurements twice";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), dir + "/B.csv");
    EXPECT_EQ(e.line(), 42);
    EXPECT_NE(e.message().find("found 10 of its 50 rows identical to rows of " + dir + "/A.csv (joint values and measured values equal "
                               "to the last bit; the first: " + dir + "/B.csv:42 = " + dir + "/A.csv:32)"),
              std::string::npos)
        << e.message();
  }
  // the command: the same file by two paths, or its copy; identify and diagnose; nothing written
  const std::string robot = "--robot kuka_kr16 --tool 80,40,150 ";
  for (const std::string& cmd : {"identify " + robot + "--out " + dir + "/o.xml", "diagnose " + robot + "--json " + dir + "/o.json"}) {
    CliRun r = test::runAccura(cmd + " --data " + dir + "/A.csv --data " + dir + "/../" + std::filesystem::path(dir).filename().string() +
                               "/A.csv");
    EXPECT_EQ(r.code, 1) << cmd << r.out;
    EXPECT_NE(r.err.find("accura: error: --data " + dir + "/../"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("/A.csv: expected each measurement file once, found the same file as --data " + dir + "/A.csv: its measurements "
                         "would count twice"),
              std::string::npos)
        << r.err;
    r = test::runAccura(cmd + " --data " + dir + "/A.csv --data " + dir + "/A_copy.csv");
    EXPECT_EQ(r.code, 1) << cmd << r.out;
    EXPECT_NE(r.err.find("accura: error: " + dir + "/A_copy.csv:2: " + same), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir + "/o.xml"));
    EXPECT_FALSE(std::filesystem::exists(dir + "/o.json"));
  }
}

// A validation file that holds rows of the fit data (the fit file given again, or part of it)
// measures the fit, not the accuracy on new poses: identify and diagnose refuse it at its first
// such row, naming the fit file's row and how many rows the two share, and write nothing. Rows
// written twice in a validation file count once (identify said nothing and counted them twice).
TEST(MeasurementQuality, AValidationOnTheFitDataIsRefusedAndItsRowsWrittenTwiceCountOnce) {
  const std::string dir = test::tempDir("mq_validate_fit");
  const Campaign c = campaign(120, 66);
  (void)roundTrip(c.set, dir + "/A.csv", c.nominal);
  // 40 new poses, then rows 11..15 of A (validation lines 42..46; A's lines 12..16)
  const Campaign other = campaign(40, 67);
  MeasurementSet mixed = other.set;
  for (size_t i = 10; i < 15; ++i) mixed.rows.push_back(c.set.rows[i]);
  (void)roundTrip(mixed, dir + "/V.csv", c.nominal);
  const std::string robot = "--robot kuka_kr16 --tool 80,40,150 --data " + dir + "/A.csv ";
  for (const std::string& cmd : {"identify " + robot + "--out " + dir + "/o.xml", "diagnose " + robot + "--json " + dir + "/o.json"}) {
    CliRun r = test::runAccura(cmd + " --validate " + dir + "/A.csv");
    EXPECT_EQ(r.code, 1) << cmd << r.out;
    EXPECT_NE(r.err.find("accura: error: " + dir + "/A.csv:2: expected held-out measurements, not in the fit data, found every one "
                         "of its 120 rows identical to rows of the fit data (joint values and measured values equal to the last bit; "
                         "the first: " + dir + "/A.csv:2 = " + dir + "/A.csv:2)"),
              std::string::npos)
        << cmd << "\n" << r.err;
    r = test::runAccura(cmd + " --validate " + dir + "/V.csv");
    EXPECT_EQ(r.code, 1) << cmd << r.out;
    EXPECT_NE(r.err.find("accura: error: " + dir + "/V.csv:42: expected held-out measurements, not in the fit data, found 5 of its 45 "
                         "rows identical to rows of the fit data (joint values and measured values equal to the last bit; the first: " +
                         dir + "/V.csv:42 = " + dir + "/A.csv:12)"),
              std::string::npos)
        << cmd << "\n" << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir + "/o.xml"));
    EXPECT_FALSE(std::filesystem::exists(dir + "/o.json"));
  }
  // a validation of 40 new poses with every 4th row written twice: identify's held-out figures
  // are those of the 40 poses once each
  MeasurementSet twice = other.set;
  twice.rows.clear();
  for (size_t i = 0; i < other.set.rows.size(); ++i) {
    twice.rows.push_back(other.set.rows[i]);
    if (i % 4 == 0) twice.rows.push_back(other.set.rows[i]);
  }
  (void)roundTrip(twice, dir + "/W.csv", c.nominal);
  (void)roundTrip(other.set, dir + "/W1.csv", c.nominal);
  const CliRun w = test::runAccura("identify " + robot + "--out " + dir + "/w.xml --json " + dir + "/w.json --validate " + dir + "/W.csv");
  const CliRun w1 = test::runAccura("identify " + robot + "--out " + dir + "/w1.xml --json " + dir + "/w1.json --validate " + dir + "/W1.csv");
  ASSERT_EQ(w.code, 0) << w.err;
  ASSERT_EQ(w1.code, 0) << w1.err;
  EXPECT_NE((w.out + w.err).find("10 row(s) of " + dir + "/W.csv repeat an earlier row of their joint configuration exactly"),
            std::string::npos)
      << w.out << w.err;
  const auto jw = nlohmann::json::parse(test::readText(dir + "/w.json")), jw1 = nlohmann::json::parse(test::readText(dir + "/w1.json"));
  EXPECT_EQ(jw["validation"]["n"].get<int>(), 40) << jw["validation"].dump();
  EXPECT_NEAR(jw["validation"]["rms_mm"].get<double>(), jw1["validation"]["rms_mm"].get<double>(), 1e-12);
  std::filesystem::remove_all(dir);
}

// The fit data exported again (another precision: joints to 1e-4 deg, positions to 1e-3 mm) are
// not the same bits, so refuseValidationInFitData lets them through; given as --validate they
// measure the fit. identify and diagnose say so; a real second measurement of the same
// configurations (tracker noise 0.01 mm) is not taken for one.
TEST(MeasurementQuality, TheFitDataExportedAgainAsAValidationIsSaidToBeThat) {
  const std::string dir = test::tempDir("mq_reexport");
  const Campaign c = campaign(120, 68);
  (void)roundTrip(c.set, dir + "/A.csv", c.nominal);
  MeasurementSet again = c.set, remeasured = c.set;
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0, 0.01);
  for (size_t i = 0; i < again.rows.size(); ++i) {
    Measurement& r = again.rows[i];
    for (Eigen::Index j = 0; j < r.q.size(); ++j) r.q[j] = std::round(r.q[j] * 1e4) / 1e4;
    for (int k = 0; k < 3; ++k) r.p_world_mm[k] = std::round(r.p_world_mm[k] * 1e3) / 1e3;
    for (int k = 0; k < 3; ++k) remeasured.rows[i].p_world_mm[k] += noise(rng);
  }
  (void)roundTrip(again, dir + "/V.csv", c.nominal);
  (void)roundTrip(remeasured, dir + "/W.csv", c.nominal);
  const MeasurementSet fit = readMeasurementsCsv(dir + "/A.csv", c.nominal.nominal);
  const MeasurementSet v = readMeasurementsCsv(dir + "/V.csv", c.nominal.nominal);
  EXPECT_NO_THROW(refuseValidationInFitData({fit}, v));  // (not the same bits)
  const std::string said = "120 of the 120 rows of " + dir + "/V.csv are rows of the fit data to within 0.001 deg in every joint and 0.002 "
                           "mm in every position component (the first: " + dir + "/V.csv:2 = " + dir + "/A.csv:2; at most ";
  EXPECT_EQ(validationLooksLikeFitDataWarning({fit}, v).rfind(said, 0), 0u) << validationLooksLikeFitDataWarning({fit}, v);
  EXPECT_EQ(validationLooksLikeFitDataWarning({fit}, readMeasurementsCsv(dir + "/W.csv", c.nominal.nominal)), "");
  // 59 of 120 rows from the fit: under half, not said; 60: said
  MeasurementSet half = readMeasurementsCsv(dir + "/W.csv", c.nominal.nominal);
  for (size_t i = 0; i < 59; ++i) half.rows[i] = v.rows[i];
  EXPECT_EQ(validationLooksLikeFitDataWarning({fit}, half), "");
  half.rows[59] = v.rows[59];
  EXPECT_EQ(validationLooksLikeFitDataWarning({fit}, half).rfind("60 of the 120 rows of", 0), 0u);
  const std::string robot = "--robot kuka_kr16 --tool 80,40,150 --data " + dir + "/A.csv ";
  for (const std::string& cmd : {"identify " + robot + "--out " + dir + "/o.xml", "diagnose " + robot + "--json " + dir + "/o.json"}) {
    CliRun r = test::runAccura(cmd + " --validate " + dir + "/V.csv");
    EXPECT_EQ(r.code, 0) << cmd << r.err;
    EXPECT_NE((r.out + r.err).find(said), std::string::npos) << cmd << "\n" << r.out << r.err;
    r = test::runAccura(cmd + " --validate " + dir + "/W.csv");
    EXPECT_EQ(r.code, 0) << cmd << r.err;
    EXPECT_EQ((r.out + r.err).find("are rows of the fit data"), std::string::npos) << cmd << "\n" << r.out << r.err;
  }
}

// The number printed right after `label` in `text` (NaN when the label is not there).
double numberAfter(const std::string& text, const std::string& label) {
  const size_t at = text.find(label);
  return at == std::string::npos ? std::nan("") : std::stod(text.substr(at + label.size()));
}

// identify --validate with a file measured from another tracker station, without
// --validate-station new: the validation is of another frame (metres off), and the run said
// "improved 1.0-fold" and nothing else. It now says so in place of the comparison, with the
// median error, the tracker the re-registration finds (where the simulation put it) and the
// remedy; a validation of the fit's station says nothing of the kind.
TEST(MeasurementQuality, AValidationFromAnotherStationIsSaidToBeOne) {
  const std::string dir = test::tempDir("mq_station");
  CliRun r = test::runAccura("simulate --robot kuka_kr16 --poses 150 --seed 21 --tool 80,40,150 --out " + dir + "/fit.csv --truth " +
                             dir + "/truth.xml");
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string other = "1900,-1300,-400,120,0.4,-0.3";  // the tracker turned 90 deg and moved
  r = test::runAccura("simulate --robot " + dir + "/truth.xml --effects none --poses 60 --seed 22 --station " + other + " --out " + dir +
                      "/other.csv");
  ASSERT_EQ(r.code, 0) << r.err;
  r = test::runAccura("simulate --robot " + dir + "/truth.xml --effects none --poses 60 --seed 23 --out " + dir + "/same.csv");
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string fit = "identify --robot kuka_kr16 --tool 80,40,150 --data " + dir + "/fit.csv --out " + dir + "/cal.xml --json " + dir +
                          "/s.json --quiet --validate " + dir;
  r = test::runAccura(fit + "/other.csv");
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string head = "  WARNING: the validation on " + dir + "/other.csv is grossly off: its median position error is ";
  ASSERT_NE(r.out.find(head), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("improved"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("WORSE"), std::string::npos) << r.out;
  // the median error: the written model's on the file
  const RobotModel truth = readRobotFile(dir + "/truth.xml");
  const RobotModel cal = readRobotFile(dir + "/cal.xml");
  std::vector<double> e = positionErrors(cal, readMeasurementsCsv(dir + "/other.csv", truth.nominal));
  std::nth_element(e.begin(), e.begin() + static_cast<long>(e.size() / 2), e.end());
  EXPECT_NEAR(numberAfter(r.out, head), e[e.size() / 2], 0.051);
  EXPECT_GT(e[e.size() / 2], 100.0);
  // the tracker where the simulation put it: T_fit_other = T_world_base(fit) T_world_base(other)^-1
  const Eigen::Isometry3d moved = truth.T_world_base() * toIsometry(XyzAbc{1900, -1300, -400, 120, 0.4, -0.3}).inverse();
  const std::string where = "It is likely measured from another tracker station: re-registering the station alone (6 parameters, the "
                            "robot held) puts its tracker ";
  const size_t at = r.out.find(where);
  ASSERT_NE(at, std::string::npos) << r.out;
  EXPECT_NEAR(std::stod(r.out.substr(at + where.size())), moved.translation().norm(), 0.11) << r.out;
  const size_t deg = r.out.find(" mm and ", at + where.size());
  ASSERT_NE(deg, std::string::npos);
  EXPECT_NEAR(std::stod(r.out.substr(deg + 8)), Eigen::AngleAxisd(moved.linear()).angle() * kRadToDeg, 0.011) << r.out;
  EXPECT_NEAR(Eigen::AngleAxisd(moved.linear()).angle() * kRadToDeg, 90.0, 0.1);
  EXPECT_NE(r.out.find(" mm. Validate it with --validate-station new\n"), std::string::npos) << r.out;
  const auto j = nlohmann::json::parse(test::readText(dir + "/s.json"));
  EXPECT_TRUE(anyWarning(j["warnings"].get<std::vector<std::string>>(), "Validate it with --validate-station new"));
  // --validate-station new validates it; a file of the fit's station is not said to be another's
  r = test::runAccura(fit + "/other.csv --validate-station new");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out.find("grossly off"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("position RMS improved"), std::string::npos) << r.out;
  r = test::runAccura(fit + "/same.csv");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out.find("grossly off"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("position RMS improved"), std::string::npos) << r.out;
}

// Poses of `truth` it was not fitted on (the same station and tool, 0.02 mm noise per axis).
MeasurementSet freshPoses(const RobotModel& truth, int poses, std::uint64_t seed) {
  SimulateOptions o;
  o.seed = seed;
  o.poses = poses;
  o.noise_mm = 0.02;
  o.effects = {"none"};
  o.set_station = false;
  o.set_tool = false;
  return simulateMeasurements(truth, o);
}

// 5 of 300 rows 30 mm off (below the 50 mm that leaves a row out as gross): a least-squares fit
// follows them with every parameter (fresh poses 0.6 mm off instead of the noise's 0.035), and
// the run only listed them as suspicious. A WARNING now counts and names them, states the test
// (more than 10 robust standard deviations) and recommends --loss huber, which takes the model
// back to the noise; a clean campaign and a robust fit say nothing of the kind.
TEST(MeasurementQuality, GrossOutliersInALeastSquaresFitRecommendARobustLoss) {
  Campaign c = campaign(300, 66);
  const std::vector<size_t> moved = {17, 80, 141, 202, 263};
  for (size_t k = 0; k < moved.size(); ++k)
    c.set.rows[moved[k]].p_world_mm += 30.0 * Eigen::Vector3d(k % 3 == 0, k % 3 == 1, k % 3 == 2);
  IdentifySummary ls, hu;
  const RobotModel ls_model = identify(c.nominal, c.set, IdentifyOptions{}, &ls);
  IdentifyOptions huber;
  huber.loss = "huber";
  const RobotModel hu_model = identify(c.nominal, c.set, huber, &hu);
  EXPECT_TRUE(ls.excluded.empty());  // (not gross by the 50 mm rule)
  std::string lines;
  for (size_t k = 0; k < moved.size(); ++k) lines += (k ? ", " : "") + c.set.file + ":" + std::to_string(c.set.rows[moved[k]].line);
  const std::string said = "5 row(s) lie more than 10 robust standard deviations from the fitted model (normalised residual ";
  EXPECT_TRUE(anyWarning(ls.warnings, said)) << ::testing::PrintToString(ls.warnings);
  EXPECT_TRUE(anyWarning(ls.warnings, " mm; " + lines + "): gross outliers")) << lines << ::testing::PrintToString(ls.warnings);
  EXPECT_TRUE(anyWarning(ls.warnings, "Check those rows, or fit with --loss huber, which down-weights them"));
  EXPECT_FALSE(anyWarning(hu.warnings, "robust standard deviations")) << ::testing::PrintToString(hu.warnings);
  // the advice is right: on fresh poses the robust fit is at the noise (3D RMS of 0.02 mm per
  // axis: 0.035 mm), the least-squares one far from it
  const MeasurementSet fresh = freshPoses(c.truth, 200, 67);
  const double ls_rms = evaluate(ls_model, fresh).rms_mm, hu_rms = evaluate(hu_model, fresh).rms_mm;
  EXPECT_GT(ls_rms, 0.2);
  EXPECT_LT(hu_rms, 0.045);
  // the campaign without the outliers: no such warning
  const Campaign clean = campaign(300, 66);
  IdentifySummary cs;
  identify(clean.nominal, clean.set, IdentifyOptions{}, &cs);
  EXPECT_FALSE(anyWarning(cs.warnings, "robust standard deviations")) << ::testing::PrintToString(cs.warnings);
}

// A campaign with joint 4 held at 30 deg (the same poses otherwise, measured on the same robot):
// the model is determined at that angle of joint 4 only. identify and diagnose say so, naming the
// joint and the angle; identify lists what it fixed for it, parameters of links 4 and 5 that the
// same poses with joint 4 moving do determine.
TEST(MeasurementQuality, AJointThatNeverMovesIsSaid) {
  const Campaign moving = campaign(300, 68);
  Campaign held = moving;
  KinematicWorkspace ws;
  for (Measurement& m : held.set.rows) {
    const Eigen::Vector3d noise = m.p_world_mm - forwardKinematics(moving.truth, m.q, m.context, ws).translation();
    m.q[3] = 30.0;
    m.p_world_mm = forwardKinematics(held.truth, m.q, m.context, ws).translation() + noise;
  }
  IdentifySummary sm, sh;
  identify(moving.nominal, moving.set, IdentifyOptions{}, &sm);
  identify(held.nominal, held.set, IdentifyOptions{}, &sh);
  EXPECT_FALSE(anyWarning(sm.warnings, "never moves")) << ::testing::PrintToString(sm.warnings);
  const std::string said = "joint 4 never moves in the data (held at 30 deg in all 300 rows, within 0.01 deg): the model holds only at "
                           "that angle. What needs joint 4's motion to be determined is fixed or absorbed by other parameters (this fit "
                           "fixed, of links 4 and 5: ";
  const auto w = std::find_if(sh.warnings.begin(), sh.warnings.end(), [&](const std::string& x) { return x.rfind(said, 0) == 0; });
  ASSERT_NE(w, sh.warnings.end()) << ::testing::PrintToString(sh.warnings);
  EXPECT_NE(w->find("), and the data say nothing of the robot at other angles of joint 4: measure poses with joint 4 moving over its "
                    "range"),
            std::string::npos)
      << *w;
  // what it lists: fixed here, of links 4 and 5, and determined when joint 4 moves
  const std::string list = w->substr(said.size(), w->find(')', said.size()) - said.size());
  std::vector<std::string> names;
  for (size_t a = 0; a <= list.size();) {
    const size_t b = std::min(list.find(", ", a), list.size());
    names.push_back(list.substr(a, b - a));
    a = b + 2;
  }
  ASSERT_GE(names.size(), 2u) << list;
  auto fixedIn = [](const IdentifySummary& s, const std::string& name) {
    return std::any_of(s.fixed.begin(), s.fixed.end(), [&](const FixedParameter& f) { return f.name == name; });
  };
  for (const std::string& n : names) {
    EXPECT_TRUE(n.rfind("j4_", 0) == 0 || n.rfind("j5_", 0) == 0) << n;
    EXPECT_TRUE(fixedIn(sh, n)) << n;
    EXPECT_FALSE(fixedIn(sm, n)) << n << " is fixed with joint 4 moving too";
  }
  // the diagnosis: the same warning (without the fit's list), in the text and the JSON
  const std::string held4 =
      "joint 4 never moves in the data (held at 30 deg in all 300 rows, within 0.01 deg): the model holds only at that angle. What "
      "needs joint 4's motion to be determined is fixed or absorbed by other parameters, and the data say nothing of the robot at "
      "other angles of joint 4: measure poses with joint 4 moving over its range";
  const Diagnosis d = diagnose(held.nominal, held.set, nullptr, DiagnoseOptions{});
  EXPECT_NE(diagnosisText(d).find("\nWARNING: " + held4 + "\n"), std::string::npos) << diagnosisText(d);
  EXPECT_EQ(nlohmann::json::parse(diagnosisJson(d))["warnings"], nlohmann::json::array({held4}));
  const Diagnosis dm = diagnose(moving.nominal, moving.set, nullptr, DiagnoseOptions{});
  EXPECT_EQ(diagnosisText(dm).find("never moves"), std::string::npos);
}

}  // namespace
}  // namespace accura::calib
