// accura selfcheck: the diagnosis run blind on simulated robots with a known, withheld effect
// (docs/diagnosis.md): a confusion table of injected effect against verdict, and the
// estimated against the true shrink.
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "accura/calib/json_text.h"
#include "accura/calib/diagnose.h"
#include "accura/calib/errors.h"
#include "cli_util.h"
#include "commands.h"

namespace accura::cli {
namespace {
using nlohmann::ordered_json;

struct SelfcheckArgs {
  std::string robots = "kuka_kr16,ur10";
  std::string seeds = "1,2,3,4,5";
  std::string noise = "0.01,0.03";
  std::string injected;  // empty: none, the catalogue, unmodelled_coupling
  int poses = 300;
  double target = 0.95;
  std::string json;
};

// {effect: footprint (mm)} of the injected catalogue effects of a case (SelfcheckCase::footprints_mm).
ordered_json footprints(const calib::SelfcheckCase& c) {
  ordered_json j = ordered_json::object();
  for (const auto& [e, mm] : c.footprints_mm) j[e] = num(mm);
  return j;
}

int runSelfcheck(const SelfcheckArgs& a) {
  calib::SelfcheckOptions o;
  o.robots = splitList(a.robots, "--robots");
  o.seeds.clear();
  for (double s : parseNumbers(a.seeds, "--seeds", NumberRange{0, 1e15, false, ""})) {
    if (!(s >= 0 && s == std::floor(s) && s < 1e12)) throw calib::InputError("--seeds: expected whole numbers >= 0, found " + fmt("%g", s));
    o.seeds.push_back(static_cast<std::uint64_t>(s));
  }
  o.noise_mm = parseNumbers(a.noise, "--noise-mm", NumberRange{0, 100, true, "mm"});
  if (!a.injected.empty()) o.injected = splitList(a.injected, "--inject");
  o.poses = a.poses;
  if (!(a.target > 0 && a.target <= 1)) throw calib::InputError("--target: expected a fraction in (0, 1], found " + fmt("%g", a.target));
  std::string why;
  if (!o.IsValid(&why)) throw calib::InputError("selfcheck: " + why);
  const size_t total = o.robots.size() * o.injected.size() * o.noise_mm.size() * o.seeds.size();
  std::printf("accura selfcheck: %zu cases (robots x injected effects x noise levels x seeds), each diagnosed blind\n", total);
  size_t done = 0;
  const calib::SelfcheckResult r = accura::calib::runSelfcheck(o, [&](const calib::SelfcheckCase& c) {
    ++done;
    std::printf("  [%3zu/%zu] %-10s %-20s noise %.3f mm (%s, %s): verdict %-17s %s (%.2f s)\n", done, total, c.robot.c_str(),
                c.injected.c_str(), c.noise_mm, c.noise_source.c_str(), c.validation.c_str(), c.verdict.c_str(),
                c.right ? "right" : "WRONG", c.seconds);
    std::fflush(stdout);
  });
  std::printf("\nconfusion table (rows: injected and withheld from the model; columns: the diagnosis' verdict)\n%s",
              r.confusionTable().c_str());
  std::printf("\nestimated vs true shrink (held-out RMS of the geometric model -> with the selected effects; true: the same "
              "two models on %d fresh poses)\n%s",
              o.truth_poses, r.shrinkTable().c_str());
  const double fraction = r.cases.empty() ? 0.0 : double(r.right) / double(r.cases.size());
  const bool pass = fraction >= a.target;
  std::printf("\n%s: %.1f%% right verdicts (target %.0f%%)\n", pass ? "PASS" : "FAIL", 100 * fraction, 100 * a.target);
  if (!a.json.empty()) {
    ordered_json j;
    j["right"] = r.right;
    j["cases_total"] = r.cases.size();
    j["fraction_right"] = fraction;
    j["target"] = a.target;
    ordered_json cases = ordered_json::array();
    for (const calib::SelfcheckCase& c : r.cases)
      cases.push_back({{"robot", c.robot},
                       {"injected", c.injected},
                       {"expected", c.expected},
                       {"verdict", c.verdict},
                       {"joints", c.joints},
                       {"right", c.right},
                       {"seed", c.seed},
                       {"noise_mm", c.noise_mm},
                       {"noise_floor_from", c.noise_source},
                       {"held_out_by", c.validation},
                       {"estimated_rms_before_mm", num(c.estimated_before_mm)},
                       {"estimated_rms_after_mm", num(c.estimated_after_mm)},
                       {"true_rms_before_mm", num(c.true_before_mm)},
                       {"true_rms_after_mm", num(c.true_after_mm)},
                       {"systematic_rms_mm", num(c.systematic_mm)},
                       {"detection_limit_mm", num(c.detection_limit_mm)},
                       {"footprints_mm", footprints(c)},
                       {"expected_detectable", c.expected_detectable},
                       {"right_by_limit", c.right_by_limit},
                       {"seconds", num(c.seconds)}});
    j["cases"] = cases;
    writeTextAtomically(a.json, calib::jsonText(j));
    std::printf("wrote %s\n", a.json.c_str());
  }
  return pass ? 0 : 2;
}

}  // namespace

void addSelfcheckCommand(CLI::App& app) {
  auto a = std::make_shared<SelfcheckArgs>();
  auto* c = app.add_subcommand("selfcheck", "check the diagnosis blind on simulated robots with a withheld effect");
  c->add_option("--robots", a->robots, "robots to simulate (bundled names or files)")->capture_default_str();
  c->add_option("--seeds", a->seeds, "random seeds")->capture_default_str();
  c->add_option("--noise-mm", a->noise, "noise levels, 1 sigma per axis (mm)")->capture_default_str();
  c->add_option("--inject", a->injected,
                "effects to inject and withhold (default: none, the catalogue (joint_compliance, gear_periodic, "
                "joint_scale, backlash, thermal), unmodelled_coupling (outside the catalogue), and the cases real data "
                "bring: cyclic_fine, outliers, two_effects, partial_cyclic, partial_range)");
  addIntegerOption(c, "--poses", a->poses, "measured poses per case", 1, 1000000)->capture_default_str();
  addNumberOption(c, "--target", a->target, "fraction of right verdicts needed for exit code 0", NumberRange{0, 1, false, ""})->capture_default_str();
  c->add_option("--json", a->json, "write every case as JSON");
  c->callback([=]() { exitCode() = runSelfcheck(*a); });
}

}  // namespace accura::cli
