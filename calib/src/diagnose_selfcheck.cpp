// accura: the diagnosis checked blind on simulated robots whose effect is known (diagnose.h).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

#include "accura/calib/diagnose.h"
#include "accura/calib/errors.h"
#include "accura/calib/identify.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"

namespace accura {

bool SelfcheckOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (robots.empty()) return fail("expected at least one robot");
  if (seeds.empty()) return fail("expected at least one seed");
  if (noise_mm.empty()) return fail("expected at least one noise level");
  for (double n : noise_mm)
    if (!(n > 0 && std::isfinite(n))) return fail("noise levels must be > 0 mm");
  if (injected.empty()) return fail("expected at least one injected effect");
  const std::vector<std::string>& cat = effectCatalogue();
  for (const std::string& e : injected)
    if (e != "none" && e != "unmodelled_coupling" && std::find(cat.begin(), cat.end(), e) == cat.end())
      return fail("unknown injected effect '" + e + "' (expected none, unmodelled_coupling or a catalogue name)");
  if (poses < 60) return fail("poses must be >= 60, got " + std::to_string(poses));
  if (validation_poses < 20) return fail("validation_poses must be >= 20");
  if (truth_poses < 20) return fail("truth_poses must be >= 20");
  return diagnose.IsValid(error);
}

namespace {

// Payload masses the simulated campaign cycles through: 0, half and full rated load.
std::vector<double> payloadsFor(const std::string& robot) {
  if (robot.find("kr16") != std::string::npos) return {0, 8, 16};
  if (robot.find("ur10") != std::string::npos) return {0, 5, 10};
  if (robot.find("irb120") != std::string::npos) return {0, 1.5, 3};
  return {0, 5, 10};
}

std::string expectedVerdict(const std::string& injected) {
  if (injected == "none") return "none";
  if (injected == "unmodelled_coupling") return "unexplained";
  return injected;
}

double rmsOn(const RobotModel& model, const MeasurementSet& data) { return evaluate(model, data).rms_mm; }

}  // namespace

SelfcheckResult runSelfcheck(const SelfcheckOptions& options,
                             const std::function<void(const SelfcheckCase&)>& progress) {
  std::string why;
  if (!options.IsValid(&why)) throw ArgumentError("selfcheck: " + why);
  SelfcheckResult result;
  const XyzAbc target = {80, 40, 150, 0, 0, 0};  // the tracker's reflector on the flange (mm)
  int k = 0;
  for (size_t ri = 0; ri < options.robots.size(); ++ri) {
    const std::string& robot = options.robots[ri];
    RobotModel nominal = readRobotFile(resolveRobotPath(robot));
    nominal.nominal.T_flange_tcp = toIsometry(target);
    for (size_t ei = 0; ei < options.injected.size(); ++ei) {
      const std::string& injected = options.injected[ei];
      for (size_t ni = 0; ni < options.noise_mm.size(); ++ni) {
        for (std::uint64_t seed : options.seeds) {
          const auto t0 = std::chrono::steady_clock::now();
          SelfcheckCase c;
          c.robot = robot;
          c.injected = injected;
          c.expected = expectedVerdict(injected);
          c.seed = seed;
          c.noise_mm = options.noise_mm[ni];
          const int mode = k++ % 3;  // 0: std columns, CV; 1: repeated poses, CV; 2: std columns, validation set
          SimulateOptions o;
          o.poses = options.poses;
          o.seed = seed * 1000 + ri * 100 + ei * 10 + ni;
          o.noise_mm = c.noise_mm;
          o.effects = {"geometric"};
          if (injected != "none") o.effects.push_back(injected);
          o.payloads_kg = payloadsFor(robot);
          o.tool = target;
          o.set_tool = true;
          o.write_std = mode != 1;
          o.repeat_every = mode == 1 ? 10 : 0;
          if (injected == "unmodelled_coupling") {
            JointCoupling jc = defaultCoupling(nominal);
            // 150..250 urad per rad (or the prismatic equivalent), either sign
            const double u = 0.75 + 0.5 * std::fmod(0.618034 * double(o.seed), 1.0);
            jc.ratio *= (o.seed % 2 ? 1.0 : -1.0) * u;
            o.coupling = jc;
          }
          c.noise_source = mode == 1 ? "repeated poses" : "std columns";
          c.validation = mode == 2 ? "validation set" : "cross-validation";
          const RobotModel truth = perturbModel(nominal, o);
          MeasurementSet data = simulateMeasurements(truth, o);
          data.file = "simulated " + robot + " seed " + std::to_string(o.seed);
          MeasurementSet validation;
          if (mode == 2) {
            SimulateOptions ov = o;
            ov.poses = options.validation_poses;
            ov.seed = o.seed + 500000;
            validation = simulateMeasurements(truth, ov);
            validation.file = "simulated validation";
          }
          SimulateOptions ot = o;
          ot.poses = options.truth_poses;
          ot.seed = o.seed + 900000;
          ot.repeat_every = 0;
          const MeasurementSet fresh = simulateMeasurements(truth, ot);
          const Diagnosis d = diagnose(nominal, data, mode == 2 ? &validation : nullptr, options.diagnose);
          c.verdict = d.verdict.effect;
          c.joints = d.verdict.joints;
          c.right = c.verdict == c.expected;
          c.estimated_before_mm = d.baseline.rms_mm;
          c.estimated_after_mm = d.verdict.validation_rms_after_mm;
          c.true_before_mm = rmsOn(d.baseline_model, fresh);
          c.true_after_mm = rmsOn(d.final_model, fresh);
          SimulateOptions oc = ot;
          oc.noise_mm = 0;
          c.systematic_mm = rmsOn(d.baseline_model, simulateMeasurements(truth, oc));
          c.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          if (c.right) ++result.right;
          result.cases.push_back(c);
          if (progress) progress(c);
        }
      }
    }
  }
  return result;
}

std::string SelfcheckResult::confusionTable() const {
  std::vector<std::string> rows, cols = {"none"};
  for (const std::string& e : effectCatalogue()) cols.push_back(e);
  cols.push_back("unexplained");
  std::map<std::pair<std::string, std::string>, int> n;
  for (const SelfcheckCase& c : cases) {
    if (std::find(rows.begin(), rows.end(), c.injected) == rows.end()) rows.push_back(c.injected);
    if (std::find(cols.begin(), cols.end(), c.verdict) == cols.end()) cols.push_back(c.verdict);
    n[{c.injected, c.verdict}]++;
  }
  std::ostringstream s;
  char buf[64];
  s << "injected \\ verdict   ";
  for (const std::string& c : cols) {
    std::snprintf(buf, sizeof buf, " %*s", std::max<int>(5, static_cast<int>(c.size())), c.c_str());
    s << buf;
  }
  s << "   right\n";
  for (const std::string& r : rows) {
    std::snprintf(buf, sizeof buf, "%-20s", r.c_str());
    s << buf;
    int total = 0, row_right = 0;
    for (const std::string& c : cols) {
      const int v = n.count({r, c}) ? n.at({r, c}) : 0;
      total += v;
      if (c == expectedVerdict(r)) row_right = v;
      std::snprintf(buf, sizeof buf, " %*d", std::max<int>(5, static_cast<int>(c.size())), v);
      s << buf;
    }
    std::snprintf(buf, sizeof buf, "   %d/%d\n", row_right, total);
    s << buf;
  }
  std::snprintf(buf, sizeof buf, "right verdicts: %d of %zu (%.1f%%)\n", right, cases.size(),
                cases.empty() ? 0.0 : 100.0 * right / double(cases.size()));
  s << buf;
  return s.str();
}

std::string SelfcheckResult::shrinkTable() const {
  std::ostringstream s;
  s << "robot        injected             noise  floor from      held-out by       systematic  verdict              "
       "estimated RMS before -> after   true (fresh poses) before -> after (mm)\n";
  for (const SelfcheckCase& c : cases) {
    char buf[400];
    std::snprintf(buf, sizeof buf, "%-12s %-20s %.3f  %-15s %-17s %10.4f  %-20s %8.4f -> %.4f %18.4f -> %.4f%s\n", c.robot.c_str(),
                  c.injected.c_str(), c.noise_mm, c.noise_source.c_str(), c.validation.c_str(), c.systematic_mm, c.verdict.c_str(),
                  c.estimated_before_mm, c.estimated_after_mm, c.true_before_mm, c.true_after_mm, c.right ? "" : "   WRONG");
    s << buf;
  }
  return s.str();
}

}  // namespace accura
