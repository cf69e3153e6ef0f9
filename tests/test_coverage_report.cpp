// Issue 11, coverage in compensate: the targets whose real joint values lie outside the joint
// ranges the calibrated model was fitted on are warnings of the job itself, so the command's
// stderr, its JSON report (and through it batch and the plug-in) all carry them. Checked on the
// real UR10's calibrated model (fitted on Series_B, joint 1 only from -180 to -44.9 deg) and the
// URScript example, whose targets lie at joint 1 around 0 deg: each warning's numbers must agree
// with the model file's fit_range and with its own arithmetic (beyond = q - upper).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
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

}  // namespace
}  // namespace accura
