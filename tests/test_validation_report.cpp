// What identify reports about its validation set: suspicious validation rows (as for the fit
// rows), and no orientation statistics when the fit never identified the tool's rotation.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "accura/calib/measurements.h"
#include "accura/calib/robot_io.h"
#include "test_util.h"

namespace accura::calib {
namespace {

using test::CliRun;
CliRun run(const std::string& args) { return test::runAccura(args); }

TEST(ValidationReport, AGlitchInTheValidationSetIsFlaggedAsInTheFitSet) {
  // a simulated KR 16 (0.02 mm noise per axis: validation errors of ~0.04 mm after calibration);
  // one validation row moved 3 mm (a glitch far below the 50 mm of a gross row): flagged by its
  // line, its error 3 mm within the noise
  const std::string dir = test::tempDir("valrep_glitch");
  CliRun r = run("simulate --robot kuka_kr16 --poses 200 --seed 5 --tool 80,40,150 --out " + dir + "/fit.csv --truth " + dir + "/truth.xml");
  ASSERT_EQ(r.code, 0) << r.err;
  r = run("simulate --robot " + dir + "/truth.xml --effects none --poses 100 --seed 6 --out " + dir + "/val.csv");
  ASSERT_EQ(r.code, 0) << r.err;
  const RobotModel kr16 = readRobotFile(resolveRobotPath("kuka_kr16"));
  MeasurementSet val = readMeasurementsCsv(dir + "/val.csv", kr16.nominal);
  val.rows[40].p_world_mm += Eigen::Vector3d(0, 3.0, 0);
  writeMeasurementsCsv(dir + "/val.csv", val, 6);
  const int glitch_line = readMeasurementsCsv(dir + "/val.csv", kr16.nominal).rows[40].line;
  r = run("identify --robot kuka_kr16 --tool 80,40,150 --data " + dir + "/fit.csv --validate " + dir + "/val.csv --out " + dir +
          "/cal.xml --json " + dir + "/s.json --quiet");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(test::readText(dir + "/s.json"));
  ASSERT_TRUE(j.contains("validation_suspicious_rows")) << r.out;
  ASSERT_EQ(j["validation_suspicious_rows"].size(), 1u) << j["validation_suspicious_rows"];
  EXPECT_EQ(j["validation_suspicious_rows"][0]["line"], glitch_line);
  EXPECT_EQ(j["validation_suspicious_rows"][0]["file"], dir + "/val.csv");
  EXPECT_NEAR(j["validation_suspicious_rows"][0]["error_mm"].get<double>(), 3.0, 0.15);
  EXPECT_NE(r.out.find("1 suspicious validation row(s)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(dir + "/val.csv:" + std::to_string(glitch_line)), std::string::npos) << r.out;
  std::filesystem::remove_all(dir);
}

TEST(ValidationReport, APositionOnlyFitReportsNoOrientationErrors) {
  // the target turned 90 deg on the flange (as the IPA data's T-Mac); the fit data has positions
  // only, so the tool's rotation is never identified: the 6D validation's orientation error
  // would be the 90 deg of the mounting. Not reported, and said why
  const std::string dir = test::tempDir("valrep_orient");
  CliRun r = run("simulate --robot kuka_kr16 --poses 150 --seed 7 --tool 80,40,150,90,0,0 --out " + dir + "/fit.csv --truth " + dir +
                 "/truth.xml");
  ASSERT_EQ(r.code, 0) << r.err;
  r = run("simulate --robot " + dir + "/truth.xml --effects none --poses 60 --seed 8 --orientation --out " + dir + "/val.csv");
  ASSERT_EQ(r.code, 0) << r.err;
  r = run("identify --robot kuka_kr16 --tool 80,40,150 --data " + dir + "/fit.csv --validate " + dir + "/val.csv --out " + dir +
          "/cal.xml --json " + dir + "/s.json");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(test::readText(dir + "/s.json"));
  EXPECT_FALSE(j["orientation"].get<bool>());
  EXPECT_FALSE(j["validation"].contains("rot_rms_deg")) << j["validation"];
  EXPECT_FALSE(j["nominal_validation"].contains("rot_rms_deg")) << j["nominal_validation"];
  EXPECT_EQ(j["validation"]["n"], 60);
  EXPECT_LT(j["validation"]["rms_mm"].get<double>(), 0.1);  // the positions are still validated
  ASSERT_TRUE(j.contains("validation_orientation"));
  EXPECT_NE(j["validation_orientation"].get<std::string>().find("the tool's rotation was never identified"), std::string::npos);
  EXPECT_NE(r.out.find("orientation errors not reported"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("orientation deg: RMS"), std::string::npos) << r.out;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace accura::calib
