// accura: the diagnosis checked blind on simulated robots whose effect is known (diagnose.h).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

#include <Eigen/Geometry>

#include "accura/calib/diagnose.h"
#include "accura/calib/errors.h"
#include "accura/calib/identify.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"

namespace accura::calib {

const std::vector<std::string>& realDataCases() {
  static const std::vector<std::string> cases = {"cyclic_fine", "outliers", "two_effects", "partial_cyclic", "partial_range"};
  return cases;
}

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
  const std::vector<std::string>& real = realDataCases();
  for (const std::string& e : injected)
    if (e != "none" && e != "unmodelled_coupling" && std::find(cat.begin(), cat.end(), e) == cat.end() &&
        std::find(real.begin(), real.end(), e) == real.end())
      return fail("unknown injected effect '" + e +
                  "' (expected none, unmodelled_coupling, a catalogue name or a real-data case: cyclic_fine, outliers, "
                  "two_effects, partial_cyclic, partial_range)");
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
  if (injected == "unmodelled_coupling" || injected == "cyclic_fine") return "unexplained";
  if (injected == "partial_cyclic") return "unexplained/partial";
  if (injected == "outliers") return "joint_compliance";
  if (injected == "two_effects") return "backlash+joint_compliance";
  if (injected == "partial_range") return "gear_periodic";
  return injected;
}

// A per-joint error dq_j(q_j) (deg) of the real robot: the measured points move by the
// difference it makes (the file records the commanded joint values).
void addJointError(const RobotModel& truth, MeasurementSet* set, const std::function<double(int, double)>& dq_deg) {
  KinematicWorkspace ws;
  for (Measurement& r : set->rows) {
    Eigen::VectorXd q = r.q;
    for (Eigen::Index j = 0; j < q.size(); ++j) q[j] += dq_deg(static_cast<int>(j), r.q[j]);
    r.p_world_mm += forwardKinematics(truth, q, r.context, ws).translation() -
                    forwardKinematics(truth, r.q, r.context, ws).translation();
  }
}

// Deterministic uniform numbers in [0, 1) from a seed (splitmix64).
double uniform(std::uint64_t* state) {
  std::uint64_t z = (*state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  z ^= z >> 31;
  return double(z >> 11) * (1.0 / 9007199254740992.0);
}

double rmsOn(const RobotModel& model, const MeasurementSet& data) { return evaluate(model, data).rms_mm; }

// The catalogue effects the expected verdict of a case names ("backlash+joint_compliance": two).
std::vector<std::string> expectedEffects(const std::string& expected) {
  std::vector<std::string> out;
  const std::vector<std::string>& cat = effectCatalogue();
  std::stringstream in(expected);
  for (std::string e; std::getline(in, e, '+');)
    if (std::find(cat.begin(), cat.end(), e) != cat.end()) out.push_back(e);
  return out;
}

// How far effect `e` of `truth` moves the tool points beyond what the complete geometric model
// and the other injected effects `others` absorb (mm): the RMS of that model identified on
// noise-free poses `so` of the truth (which carries the injected effects only). Alone, the part
// of the effect geometry cannot take; beside another effect, the part neither can.
double footprintMm(const RobotModel& nominal, const RobotModel& truth, const std::vector<std::string>& others, SimulateOptions so) {
  so.noise_mm = 0;
  so.write_std = false;
  so.repeat_every = 0;
  const MeasurementSet m = simulateMeasurements(truth, so);
  IdentifyOptions io;
  io.groups = {"geometric"};
  io.groups.insert(io.groups.end(), others.begin(), others.end());
  IdentifySummary s;
  return rmsOn(identify(nominal, m, io, &s), m);
}

// The verdict of one case as the confusion table shows it, and whether it is right.
void judgeCase(const Diagnosis& d, const std::vector<int>& outlier_rows, const int k_fine[2], SelfcheckCase* c) {
  const std::string& injected = c->injected;
  c->verdict = d.verdict.effect;
  c->joints = d.verdict.joints;
  if (d.verdict.effects.size() > 1 && d.verdict.effect != "unexplained") {
    c->verdict.clear();
    std::vector<std::string> names = d.verdict.effects;
    std::sort(names.begin(), names.end());
    for (const std::string& e : names) c->verdict += (c->verdict.empty() ? "" : "+") + e;
  }
  if (d.verdict.effect == "unexplained" && !d.verdict.effects.empty() && injected != "unmodelled_coupling" &&
      injected != "cyclic_fine")
    c->verdict = "unexplained/partial";
  c->right = c->verdict == c->expected;
  if (!c->right && !c->expected_detectable.empty() && c->verdict == c->expected_detectable) c->right = c->right_by_limit = true;
  if (injected == "outliers") {
    // at least 80% of the gross outliers among the rows the robust estimation down-weighted
    int found = 0;
    for (int i : outlier_rows)
      for (const DownWeighted& w : d.downweighted) found += w.index == i;
    c->right = c->right && found >= 0.8 * double(outlier_rows.size());
  }
  if (injected == "cyclic_fine") {
    // the spectrum finds one of the injected joints at its number of cycles (+-1)
    bool seen = false;
    for (const JointSpectrum& sp : d.spectra)
      if ((sp.joint == 2 || sp.joint == 3) && std::abs(sp.peak_cycles_before - k_fine[sp.joint - 2]) <= 1 && sp.peak_p_before < 0.01)
        seen = true;
    c->right = c->right && seen;
  }
  if (injected == "partial_range") {
    // the user's path never makes new data (fresh poses over every joint's range) worse; the
    // part of the effect on the partly covered joint may stay unexplained
    const bool named = std::find(d.verdict.effects.begin(), d.verdict.effects.end(), "gear_periodic") != d.verdict.effects.end();
    c->right = (c->right || c->verdict == "none" || named) && c->true_after_mm <= 1.02 * c->true_before_mm;
  }
  if (!c->right) c->right_by_limit = false;
}

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
          const bool real_case = std::find(realDataCases().begin(), realDataCases().end(), injected) != realDataCases().end();
          if (injected != "none" && !real_case) o.effects.push_back(injected);
          if (injected == "outliers") o.effects.push_back("joint_compliance");
          if (injected == "two_effects") o.effects = {"geometric", "joint_compliance", "backlash"};
          if (injected == "partial_range") o.effects.push_back("gear_periodic");
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
          // the per-joint error of the real-data cases: many cycles per revolution on joints 2
          // and 3 (strain-wave gear, encoder), or a 2-cycle part plus a 17-cycle part on joint 2
          std::uint64_t rng = o.seed * 7919 + 17;
          int k_fine[2] = {11 + static_cast<int>(13 * uniform(&rng)), 11 + static_cast<int>(13 * uniform(&rng))};
          const double a_fine[2] = {(0.3 + 0.4 * uniform(&rng)) * 1e-3 * kRadToDeg, (0.3 + 0.4 * uniform(&rng)) * 1e-3 * kRadToDeg};
          const double ph[3] = {6.283 * uniform(&rng), 6.283 * uniform(&rng), 6.283 * uniform(&rng)};
          std::function<double(int, double)> joint_error;
          if (injected == "cyclic_fine")
            joint_error = [=](int j, double q) {
              if (j != 1 && j != 2) return 0.0;
              return a_fine[j - 1] * std::sin(k_fine[j - 1] * q * kDegToRad + ph[j - 1]);
            };
          if (injected == "partial_cyclic")
            joint_error = [=](int j, double q) {
              if (j != 1) return 0.0;
              return a_fine[0] * std::sin(2 * q * kDegToRad + ph[0]) + 0.6 * a_fine[1] * std::sin(17 * q * kDegToRad + ph[1]);
            };
          auto simulate = [&](const SimulateOptions& so) {
            MeasurementSet m = simulateMeasurements(truth, so);
            if (joint_error) addJointError(truth, &m, joint_error);
            return m;
          };
          MeasurementSet data;
          if (injected == "partial_range") {
            // the fit data cover only the middle third of joint 1's range; fresh poses all of it
            SimulateOptions wide = o;
            wide.poses = 3 * o.poses;
            const MeasurementSet all = simulate(wide);
            double lo = 1e300, hi = -1e300;
            for (const Measurement& r : all.rows) {
              lo = std::min(lo, r.q[0]);
              hi = std::max(hi, r.q[0]);
            }
            data = all;
            data.rows.clear();
            for (const Measurement& r : all.rows)
              if (r.q[0] > lo + (hi - lo) / 3 && r.q[0] < lo + 2 * (hi - lo) / 3 && static_cast<int>(data.rows.size()) < o.poses)
                data.rows.push_back(r);
          } else {
            data = simulate(o);
          }
          std::vector<int> outlier_rows;
          if (injected == "outliers") {
            // 2% gross outliers of 0.5-3 mm in random directions
            for (size_t i = 0; i < data.rows.size(); ++i) {
              if (uniform(&rng) >= 0.02) continue;
              Eigen::Vector3d u(uniform(&rng) - 0.5, uniform(&rng) - 0.5, uniform(&rng) - 0.5);
              if (!(u.norm() > 1e-3)) u = Eigen::Vector3d::UnitZ();
              data.rows[i].p_world_mm += (0.5 + 2.5 * uniform(&rng)) * u.normalized();
              outlier_rows.push_back(static_cast<int>(i));
            }
          }
          data.file = "simulated " + robot + " seed " + std::to_string(o.seed);
          MeasurementSet validation;
          if (mode == 2) {
            SimulateOptions ov = o;
            ov.poses = options.validation_poses;
            ov.seed = o.seed + 500000;
            validation = simulate(ov);
            validation.file = "simulated validation";
          }
          SimulateOptions ot = o;
          ot.poses = options.truth_poses;
          ot.seed = o.seed + 900000;
          ot.repeat_every = 0;
          const MeasurementSet fresh = simulate(ot);
          const Diagnosis d = diagnose(nominal, data, mode == 2 ? &validation : nullptr, options.diagnose);
          c.estimated_before_mm = d.baseline.rms_mm;
          c.estimated_after_mm = d.verdict.validation_rms_after_mm;
          c.true_before_mm = rmsOn(d.baseline_model, fresh);
          c.true_after_mm = rmsOn(d.final_model, fresh);
          SimulateOptions oc = ot;
          oc.noise_mm = 0;
          c.systematic_mm = rmsOn(d.baseline_model, simulate(oc));
          // an injected effect the data cannot show (its footprint below the detection limit)
          // may go unnamed: the verdict without it counts as right too
          if (injected != "partial_range") {
            c.detection_limit_mm = 8.0 * c.noise_mm / std::sqrt(double(data.rows.size()));
            std::vector<std::string> seen;
            const std::vector<std::string> effects = expectedEffects(c.expected);
            for (const std::string& e : effects) {
              std::vector<std::string> others;
              for (const std::string& x : effects)
                if (x != e) others.push_back(x);
              c.footprints_mm.emplace_back(e, footprintMm(nominal, truth, others, ot));
              if (c.footprints_mm.back().second >= c.detection_limit_mm) seen.push_back(e);
            }
            if (seen.size() < effects.size()) {
              for (const std::string& e : seen) c.expected_detectable += (c.expected_detectable.empty() ? "" : "+") + e;
              if (seen.empty()) c.expected_detectable = "none";
            }
          }
          judgeCase(d, outlier_rows, k_fine, &c);
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
  std::map<std::string, int> row_right;  // by c.right: some cases accept more than one verdict
  for (const SelfcheckCase& c : cases) {
    row_right[c.injected] += c.right;
    if (std::find(rows.begin(), rows.end(), c.injected) == rows.end()) rows.push_back(c.injected);
    if (std::find(cols.begin(), cols.end(), c.verdict) == cols.end()) cols.push_back(c.verdict);
    n[{c.injected, c.verdict}]++;
  }
  std::ostringstream s;
  char buf[160];
  s << "injected \\ verdict   ";
  for (const std::string& c : cols) {
    std::snprintf(buf, sizeof buf, " %*s", std::max<int>(5, static_cast<int>(c.size())), c.c_str());
    s << buf;
  }
  s << "   right\n";
  for (const std::string& r : rows) {
    std::snprintf(buf, sizeof buf, "%-20s", r.c_str());
    s << buf;
    int total = 0;
    for (const std::string& c : cols) {
      const int v = n.count({r, c}) ? n.at({r, c}) : 0;
      total += v;
      std::snprintf(buf, sizeof buf, " %*d", std::max<int>(5, static_cast<int>(c.size())), v);
      s << buf;
    }
    std::snprintf(buf, sizeof buf, "   %d/%d\n", row_right[r], total);
    s << buf;
  }
  std::snprintf(buf, sizeof buf, "right verdicts: %d of %zu (%.1f%%)\n", right, cases.size(),
                cases.empty() ? 0.0 : 100.0 * right / double(cases.size()));
  s << buf;
  const auto by_limit = std::count_if(cases.begin(), cases.end(), [](const SelfcheckCase& c) { return c.right_by_limit; });
  if (by_limit > 0) {
    std::snprintf(buf, sizeof buf, "  of them %d right by the detection limit (an injected effect the data cannot show left unnamed)\n",
                  static_cast<int>(by_limit));
    s << buf;
  }
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
    if (!c.expected_detectable.empty()) {
      s << "             (the data can show " << c.expected_detectable << ", not " << c.expected << ": footprint";
      for (const auto& [e, mm] : c.footprints_mm) {
        std::snprintf(buf, sizeof buf, " %s %.4f mm", e.c_str(), mm);
        s << buf;
      }
      std::snprintf(buf, sizeof buf, ", detection limit %.4f mm%s)\n", c.detection_limit_mm, c.right_by_limit ? "; right by it" : "");
      s << buf;
    }
  }
  return s.str();
}

}  // namespace accura::calib
