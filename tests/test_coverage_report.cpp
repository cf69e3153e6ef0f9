// Issue 11, coverage in compensate: the targets whose real joint values lie outside the joint
// ranges the calibrated model was fitted on are warnings of the job itself, so the command's
// stderr, its JSON report (and through it batch and the plug-in) all carry them. Checked on the
// real UR10's calibrated model (fitted on Series_B, joint 1 only from -180 to -44.9 deg) and the
// URScript example, whose targets lie at joint 1 around 0 deg: each warning's numbers must agree
// with the model file's fit_range and with its own arithmetic (beyond = q - upper).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <map>
#include <regex>

#include "accura/calib/robot_io.h"
#include "test_util.h"

namespace accura {
namespace {

TEST(CoverageReport, TargetsOutsideTheFittedRangesAreWarningsOfTheReport) {
  const std::string g = test::sourcePath("tests/golden/urscript/");
  const std::string dir = test::tempDir("coverage_report");
  for (const char* f : {"ur10_calibrated.xml", "ur10_seam.script"}) test::writeText(dir + "/" + f, test::readText(g + f));
  const test::CliRun c = test::runAccuraIn(dir, "compensate --robot ur10_calibrated.xml --in ur10_seam.script --out out "
                                                "--base 507.9274,-3567.8484,-1224.8883,20.00939,-0.16910,0.00450 --json r.json");
  ASSERT_EQ(c.code, 0) << c.err;
  const calib::RobotModel model = calib::readRobotFile(dir + "/ur10_calibrated.xml");
  ASSERT_GE(model.deviations.fit_range.size(), 1u);
  const double lower = model.deviations.fit_range[0].lower, upper = model.deviations.fit_range[0].upper;

  const nlohmann::json report = nlohmann::json::parse(test::readText(dir + "/r.json"));
  const std::regex per_target(R"(lies outside the joint ranges the model was fitted on: joint 1 \(shoulder_pan\) at (-?[0-9.]+) deg \(fitted (-?[0-9.]+)\.\.(-?[0-9.]+) deg, ([0-9.]+) deg beyond\))");
  int targets_outside = 0;
  std::string summary;
  for (const auto& w : report.at("warnings")) {
    const std::string m = w.at("message").get<std::string>();
    std::smatch k;
    if (std::regex_search(m, k, per_target)) {
      ++targets_outside;
      const double q = std::stod(k[1]), lo = std::stod(k[2]), hi = std::stod(k[3]), beyond = std::stod(k[4]);
      EXPECT_NEAR(lo, lower, 0.005) << m;
      EXPECT_NEAR(hi, upper, 0.005) << m;
      EXPECT_GT(q, upper) << m;  // the example works in front of the robot, Series_B behind it
      EXPECT_NEAR(beyond, q - upper, 0.011) << m;
      // the same text on stderr, at the target's place
      EXPECT_NE(c.err.find(w.at("file").get<std::string>() + ":" + std::to_string(w.at("line").get<int>()) + ":" +
                           std::to_string(w.at("column").get<int>()) + ": " + m),
                std::string::npos)
          << m;
    } else if (m.find("outside the fitted joint ranges") != std::string::npos) {
      summary = m;
    }
  }
  const size_t n_targets = report.at("targets").size();
  EXPECT_EQ(targets_outside, 6);  // every end target; the arc's via point carries no joint values
  EXPECT_EQ(summary, std::to_string(targets_outside) + " of " + std::to_string(n_targets) +
                         " target(s) outside the fitted joint ranges; the correction there is an extrapolation");
}

// accura check says the same of the program's end points: each motion's end point outside the
// fitted ranges with its joint value, the range and how far beyond, then how many. Its joint values
// are the calibrated model's IK of the targets, as compensate's: the A1 of a line must agree with
// compensate's warning of that line, and the arithmetic with the model file's fit_range.
TEST(CoverageReport, CheckNamesTheEndPointsOutsideTheFittedRanges) {
  const std::string g = test::sourcePath("tests/golden/urscript/");
  const std::string dir = test::tempDir("coverage_check");
  for (const char* f : {"ur10_calibrated.xml", "ur10_seam.script"}) test::writeText(dir + "/" + f, test::readText(g + f));
  test::writeText(dir + "/cell.xml", "<?xml version=\"1.0\"?>\n<cell name=\"empty\">\n</cell>\n");
  const std::string base = " --base 507.9274,-3567.8484,-1224.8883,20.00939,-0.16910,0.00450";
  const test::CliRun comp = test::runAccuraIn(dir, "compensate --robot ur10_calibrated.xml --in ur10_seam.script --out out --json r.json" + base);
  ASSERT_EQ(comp.code, 0) << comp.err;
  const test::CliRun chk = test::runAccuraIn(dir, "check --robot ur10_calibrated.xml --cell cell.xml --in ur10_seam.script --json c.json" + base);
  ASSERT_EQ(chk.code, 0) << chk.out << chk.err;
  const calib::RobotModel model = calib::readRobotFile(dir + "/ur10_calibrated.xml");
  ASSERT_GE(model.deviations.fit_range.size(), 1u);
  const double upper = model.deviations.fit_range[0].upper;
  const std::regex a1(R"(joint 1 \(shoulder_pan\) at (-?[0-9.]+) deg \(fitted (-?[0-9.]+)\.\.(-?[0-9.]+) deg, ([0-9.]+) deg beyond\))");
  std::map<int, double> comp_q;  // line -> A1 of compensate's warning
  const nlohmann::json comp_report = nlohmann::json::parse(test::readText(dir + "/r.json"));
  for (const auto& w : comp_report.at("warnings")) {
    const std::string m = w.at("message").get<std::string>();
    std::smatch k;
    if (std::regex_search(m, k, a1)) comp_q[w.at("line").get<int>()] = std::stod(k[1]);
  }
  ASSERT_FALSE(comp_q.empty());
  const nlohmann::json report = nlohmann::json::parse(test::readText(dir + "/c.json"));
  int outside = 0, compared = 0;
  std::string summary;
  for (const auto& w : report.at("warnings")) {
    const std::string m = w.at("message").get<std::string>();
    std::smatch k;
    if (m.find("end point lies outside the joint ranges the model was fitted on") != std::string::npos) {
      ASSERT_TRUE(std::regex_search(m, k, a1)) << m;
      ++outside;
      const double q = std::stod(k[1]), beyond = std::stod(k[4]);
      EXPECT_NEAR(std::stod(k[3]), upper, 0.005) << m;
      EXPECT_NEAR(beyond, q - upper, 0.011) << m;
      const auto it = comp_q.find(w.at("line").get<int>());
      if (it != comp_q.end()) {
        ++compared;
        EXPECT_NEAR(q, it->second, 0.011) << m;  // the same IK of the same target (2 decimals, deg)
      }
      EXPECT_NE(chk.err.find(m), std::string::npos) << m;  // and on stderr
    } else if (m.find("outside the fitted joint ranges") != std::string::npos) {
      summary = m;
    }
  }
  EXPECT_EQ(outside, static_cast<int>(report.at("motions").size()));  // the whole seam lies in front of the robot
  EXPECT_EQ(compared, static_cast<int>(comp_q.size()));                // every target compensate named
  EXPECT_EQ(summary, std::to_string(outside) + " of " + std::to_string(outside) +
                         " end point(s) outside the fitted joint ranges; the model's correction there is an extrapolation");
}

}  // namespace
}  // namespace accura
