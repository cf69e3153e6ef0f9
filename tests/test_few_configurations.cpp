// Fit and validation sets with few distinct joint configurations (many repeats): identify counts
// the distinct configurations (repeatedConfigurations, the definition diagnose's repeatability
// uses), refuses a fit they cannot determine, warns when they barely do, and keeps the repeats
// of one configuration together in the --holdout.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <random>

#include "accura/calib/diagnose.h"
#include "accura/calib/errors.h"
#include "accura/calib/identify.h"
#include "accura/calib/measurements.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"
#include "test_util.h"

namespace accura::calib {
namespace {

using test::CliRun;
CliRun run(const std::string& args) { return test::runAccura(args); }

// `configs` distinct simulated KR 16 poses (position only), each measured `repeats` times in a
// row: the same joint values, 0.01 mm of extra noise per axis on each repeat.
struct Repeated {
  RobotModel nominal, truth;
  MeasurementSet set;
};
Repeated repeatedCampaign(int configs, int repeats, std::uint64_t seed) {
  Repeated c;
  c.nominal = test::loadBundled("kuka_kr16");
  SimulateOptions o;
  o.seed = seed;
  o.noise_mm = 0.02;
  o.tool = {80, 40, 150, 0, 0, 0};
  o.set_tool = true;
  c.truth = perturbModel(c.nominal, o);
  o.poses = configs;
  const MeasurementSet distinct = simulateMeasurements(c.truth, o);
  c.set = distinct;
  c.set.rows.clear();
  c.set.file = "repeats.csv";
  std::mt19937 rng(static_cast<unsigned>(seed));
  std::normal_distribution<double> noise(0.0, 0.01);
  for (const Measurement& m : distinct.rows)
    for (int k = 0; k < repeats; ++k) {
      Measurement r = m;
      r.line = static_cast<int>(c.set.rows.size()) + 2;
      r.p_world_mm += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
      c.set.rows.push_back(r);
    }
  return c;
}

TEST(FewConfigurations, RepeatsDoNotCountAsInformationAboutTheGeometry) {
  // 8 configurations x 25 repeats, positions only: 8 x 3 = 24 independent equations, fewer than
  // the complete geometric model's candidates (the KR 16's position-only geometric model has
  // more than 24): refused, naming the file and the counts, instead of a model that passes
  // exactly through the 8 configurations
  const Repeated few = repeatedCampaign(8, 25, 41);
  ASSERT_EQ(few.set.rows.size(), 200u);
  EXPECT_EQ(repeatedConfigurations(few.set).size(), 8u);
  try {
    identify(few.nominal, few.set, IdentifyOptions{}, nullptr);
    FAIL() << "8 distinct configurations fitted 30 parameters";
  } catch (const InputError& e) {
    const std::string w = e.what();
    EXPECT_EQ(e.file(), "repeats.csv");
    EXPECT_NE(w.find("too few distinct joint configurations"), std::string::npos) << w;
    EXPECT_NE(w.find("200 poses hold only 8 distinct joint configurations"), std::string::npos) << w;
    EXPECT_NE(w.find("24 independent equations"), std::string::npos) << w;
  }
  // 20 configurations x 8 repeats: 60 independent equations, more than the parameters but
  // fewer than 10 per parameter: fitted, counted and warned about
  const Repeated some = repeatedCampaign(20, 8, 42);
  IdentifySummary s;
  identify(some.nominal, some.set, IdentifyOptions{}, &s);
  EXPECT_EQ(s.poses, 160);
  EXPECT_EQ(s.configurations, 20);
  EXPECT_EQ(s.independent_equations, 60);
  EXPECT_EQ(s.equations, 480);
  EXPECT_TRUE(s.few_configurations);
  bool warned = false;
  for (const std::string& w : s.warnings)
    warned = warned || (w.find("few distinct joint configurations: 160 poses hold only 20 distinct") != std::string::npos &&
                        w.find("60 independent equations") != std::string::npos);
  EXPECT_TRUE(warned);
  // a repeat is a configuration within 0.01 deg: a joint 0.02 deg away is another configuration
  MeasurementSet apart = some.set;
  for (size_t i = 0; i < apart.rows.size(); ++i) apart.rows[i].q[5] += 0.02 * double(i % 8);
  IdentifySummary sa;
  identify(some.nominal, apart, IdentifyOptions{}, &sa);
  EXPECT_EQ(sa.configurations, 160);
  EXPECT_EQ(sa.independent_equations, 480);
  EXPECT_FALSE(sa.few_configurations);
  for (const std::string& w : sa.warnings) EXPECT_EQ(w.find("distinct joint configurations"), std::string::npos) << w;
}

TEST(FewConfigurations, DiagnoseRefusesRepeatsOfFewConfigurationsCountingThem) {
  // 8 configurations x 25 repeats: the diagnosis's baseline (the complete geometric model,
  // position only: 6 base + 3 tool position + 4 x 6 joint parameters = 33) cannot be determined
  // by 8 x 3 = 24 independent equations. Refused before any refit, naming the file and counting
  // the rows and configurations (not a "normal matrix is singular" from a refit further on)
  const Repeated few = repeatedCampaign(8, 25, 41);
  ASSERT_EQ(few.set.rows.size(), 200u);
  const std::string counts = "200 poses hold only 8 distinct joint configurations";
  try {
    diagnose(few.nominal, few.set, nullptr, DiagnoseOptions{});
    FAIL() << "diagnosed 8 distinct configurations";
  } catch (const InputError& e) {
    const std::string w = e.what();
    EXPECT_EQ(e.file(), "repeats.csv");
    EXPECT_NE(w.find("too few distinct joint configurations"), std::string::npos) << w;
    EXPECT_NE(w.find(counts), std::string::npos) << w;
    EXPECT_NE(w.find("24 independent equations, expected more than 33"), std::string::npos) << w;
  }
  // what the command says: the file, the counts, exit code 1 (an input error), nothing written
  const std::string dir = test::tempDir("few_diagnose");
  writeMeasurementsCsv(dir + "/repeats.csv", few.set, 6);
  const CliRun r = run("diagnose --robot kuka_kr16 --data " + dir + "/repeats.csv --json " + dir + "/d.json");
  EXPECT_EQ(r.code, 1) << r.err << r.out;
  EXPECT_NE(r.err.find(dir + "/repeats.csv: too few distinct joint configurations"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(counts), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("singular"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/d.json"));
  std::filesystem::remove_all(dir);
}

// 12 configurations x 10 repeats are enough for the baseline on all rows (36 independent
// equations), not on 2 folds: each fold's training rows hold 6 configurations (60 rows, 18
// equations for the baseline's parameters). The error says so with the counts (it used to end at "singular on a
// fold").
TEST(FewConfigurations, AFoldWithTooFewConfigurationsSaysSo) {
  const Repeated c = repeatedCampaign(12, 10, 47);
  // the baseline's parameters: those the geometric identification on all rows keeps free
  IdentifyOptions g;
  g.groups = {"geometric"};
  IdentifySummary s;
  identify(c.nominal, c.set, g, &s);
  const size_t parameters = s.parameters.size();
  ASSERT_GT(parameters, 18u);
  DiagnoseOptions o;
  o.folds = 2;
  try {
    diagnose(c.nominal, c.set, nullptr, o);
    FAIL() << "diagnosed 6 distinct configurations per fold";
  } catch (const NumericalError& e) {
    const std::string w = e.what();
    EXPECT_NE(w.find("singular on a fold: its 60 fit rows hold only 6 distinct joint configurations"), std::string::npos) << w;
    EXPECT_NE(w.find("18 independent position equations for " + std::to_string(parameters) + " parameters"), std::string::npos) << w;
  }
}

TEST(FewConfigurations, TheHoldoutKeepsTheRepeatsOfAConfigurationTogether) {
  // 60 configurations x 4 repeats in a row: every 5th configuration held out with its repeats,
  // 12 of them (48 rows); the fit keeps the other 48 configurations (192 rows). Held out row by
  // row, every configuration would be on both sides: the fit would hold all 60.
  const std::string dir = test::tempDir("few_holdout");
  const Repeated c = repeatedCampaign(60, 4, 43);
  writeMeasurementsCsv(dir + "/fit.csv", c.set, 6);
  const CliRun r = run("identify --robot kuka_kr16 --tool 80,40,150 --data " + dir + "/fit.csv --out " + dir + "/cal.xml --json " +
                       dir + "/s.json");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  const auto j = nlohmann::json::parse(test::readText(dir + "/s.json"));
  ASSERT_TRUE(j["identifiability"].contains("distinct_configurations")) << r.out;
  EXPECT_EQ(j["identifiability"]["poses"], 192);
  EXPECT_EQ(j["identifiability"]["distinct_configurations"], 48);
  EXPECT_EQ(j["identifiability"]["independent_equations"], 144);
  EXPECT_EQ(j["validation"]["n"], 48);
  EXPECT_NE(j["validation_source"].get<std::string>().find("12 of 60 distinct configurations"), std::string::npos)
      << j["validation_source"];
  EXPECT_NE(r.out.find("192 poses, 48 distinct configurations: 144 independent equations"), std::string::npos) << r.out;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace accura::calib

namespace accura::calib {
namespace {

TEST(FewConfigurations, AValidationStationNeedsDistinctConfigurations) {
  // the fit: 150 distinct simulated poses; the validations from another station: 5, 2 and 1
  // distinct configurations x 10 repeats
  const std::string dir = test::tempDir("few_station");
  CliRun r = run("simulate --robot kuka_kr16 --poses 150 --seed 9 --tool 80,40,150 --out " + dir + "/fit.csv --truth " + dir +
                 "/truth.xml");
  ASSERT_EQ(r.code, 0) << r.err;
  r = run("simulate --robot " + dir + "/truth.xml --effects none --poses 5 --seed 10 --station 500,300,-200,60,0,0 --out " + dir +
          "/five.csv");
  ASSERT_EQ(r.code, 0) << r.err;
  const RobotModel kr16 = readRobotFile(resolveRobotPath("kuka_kr16"));
  const MeasurementSet five = readMeasurementsCsv(dir + "/five.csv", kr16.nominal);
  auto repeated = [&](int configs, const std::string& name) {
    MeasurementSet s = five;
    s.rows.clear();
    // (each repeat measured anew: 1 um apart, not the same row written twice, which counts once)
    for (int c = 0; c < configs; ++c)
      for (int k = 0; k < 10; ++k) {
        s.rows.push_back(five.rows[static_cast<size_t>(c)]);
        s.rows.back().p_world_mm.x() += 0.001 * k;
      }
    writeMeasurementsCsv(dir + "/" + name, s, 6);
  };
  repeated(5, "v5.csv");
  repeated(2, "v2.csv");
  repeated(1, "v1.csv");
  const std::string fit = "identify --robot kuka_kr16 --tool 80,40,150 --data " + dir + "/fit.csv --out " + dir + "/cal.xml --validate-station new --validate " + dir;
  // 5 configurations: validated, with a warning that counts them and says what it means:
  // 6 of 15 equations, sqrt(1 - 2/5) = 0.775 of a random error's RMS, 23% low
  r = run(fit + "/v5.csv --json " + dir + "/s.json");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = nlohmann::json::parse(test::readText(dir + "/s.json"));
  bool warned = false;
  for (const auto& w : j["warnings"]) {
    const std::string t = w.get<std::string>();
    warned = warned || (t.find("--validate-station new re-registered the station (6 parameters) on " + dir + "/v5.csv: 50 poses, 5 "
                                "distinct joint configurations, fewer than 10") != std::string::npos &&
                        t.find("6 of the 15 position equations") != std::string::npos && t.find("reads 23% low") != std::string::npos);
  }
  EXPECT_TRUE(warned) << j["warnings"];
  // 2 and 1 configurations: refused, naming the validation file
  for (const char* v : {"v2.csv", "v1.csv"}) {
    r = run(fit + "/" + v);
    EXPECT_EQ(r.code, 1) << v << r.out;
    EXPECT_NE(r.err.find(dir + "/" + v + ": --validate-station new: expected at least 3 distinct joint configurations"), std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find(v[1] == '2' ? "found 20 poses, 2 distinct joint configurations" : "found 10 poses, 1 distinct joint configuration:"),
              std::string::npos)
        << r.err;
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace accura::calib
