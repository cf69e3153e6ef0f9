// accura diagnose: where the remaining error lies, which effect of the catalogue causes it and
// how far it shrinks once that effect is modelled (docs/diagnosis.md).
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>

#include "accura/calib/diagnose.h"
#include "accura/calib/errors.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/measurements.h"
#include "cli_util.h"
#include "commands.h"

namespace accura::cli {
namespace {

struct DiagnoseArgs {
  std::string robot;
  std::string data;
  std::string validate;
  std::string map;           // mapping file for instrument exports
  std::string validate_map;  // mapping file for --validate when it differs
  std::string base;
  std::string tool;
  std::string effects;  // empty: the whole catalogue
  int harmonics = calib::kDefaultGearHarmonics;
  int folds = 5;
  double noise_mm = -1;  // <0: from repeated poses or std columns
  double alpha = 0.01;
  double repeat_tol = 0.01;
  double robust_k = 4.03;
  std::string json;
  std::string report;
};

int runDiagnose(const DiagnoseArgs& a) {
  calib::RobotModel start = loadRobot(a.robot);
  if (!a.base.empty()) start.nominal.T_world_base = calib::toIsometry(calib::parseXyzAbc(a.base, "--base"));
  if (!a.tool.empty()) start.nominal.T_flange_tcp = calib::toIsometry(calib::parseXyzAbc(a.tool, "--tool"));
  calib::DiagnoseOptions o;
  if (!a.effects.empty()) o.effects = splitList(a.effects, "--effects");
  o.gear_harmonics = a.harmonics;
  o.folds = a.folds;
  if (a.noise_mm == 0 || (a.noise_mm < 0 && a.noise_mm != -1))
    throw calib::InputError("--noise-mm: expected a standard deviation > 0 mm, found " + fmt("%g", a.noise_mm));
  if (a.noise_mm > 0) o.noise_std_mm = a.noise_mm;
  o.alpha = a.alpha;
  o.repeat_tol = a.repeat_tol;
  o.robust_k = a.robust_k;
  std::string why;
  if (!o.IsValid(&why)) throw calib::InputError("diagnose: " + why);

  const calib::MeasurementSet data = readMeasurements(a.data, a.map, start.nominal);
  calib::MeasurementSet validation;
  if (!a.validate.empty())
    validation = readMeasurements(a.validate, a.validate_map.empty() ? a.map : a.validate_map, start.nominal);
  const calib::Diagnosis d = calib::diagnose(start, data, a.validate.empty() ? nullptr : &validation, o);
  std::printf("%s", calib::diagnosisText(d).c_str());
  if (!a.json.empty()) {
    writeTextAtomically(a.json, calib::diagnosisJson(d));
    std::printf("wrote %s\n", a.json.c_str());
  }
  if (!a.report.empty()) {
    writeTextAtomically(a.report, calib::diagnosisHtml(d));
    std::printf("wrote %s\n", a.report.c_str());
  }
  return 0;
}

}  // namespace

void addDiagnoseCommand(CLI::App& app) {
  auto a = std::make_shared<DiagnoseArgs>();
  auto* c = app.add_subcommand("diagnose",
                               "where the remaining error lies, which unmodelled effect causes it, how far it shrinks");
  c->add_option("--robot", a->robot, "robot (file or bundled name; a calibrated model is a starting point)")->required();
  c->add_option("--data", a->data, "measurement CSV")->required();
  c->add_option("--validate", a->validate, "held-out measurement CSV of the same robot and station "
                                           "(default: k-fold cross-validation over --data)");
  c->add_option("--map", a->map, "mapping file: how to read --data (and --validate) as exported by the instrument");
  c->add_option("--validate-map", a->validate_map, "mapping file for --validate when it differs from --map");
  c->add_option("--base", a->base, "nominal T_world_base x,y,z,A,B,C (mm, deg), as for identify");
  c->add_option("--tool", a->tool, "nominal T_flange_tcp x,y,z[,A,B,C] (mm, deg), as for identify");
  c->add_option("--effects", a->effects,
                "effects to test (default: the catalogue: joint_compliance, gear_periodic, joint_scale, backlash, thermal)");
  c->add_option("--harmonics", a->harmonics, "harmonics 1..H of gear_periodic")->capture_default_str();
  c->add_option("--folds", a->folds, "folds of the cross-validation without --validate")->capture_default_str();
  c->add_option("--noise-mm", a->noise_mm,
                "measurement noise, 1 sigma per axis (mm) (default: from repeated poses, else from the std columns)");
  c->add_option("--alpha", a->alpha, "significance level of one selection round (Bonferroni over its blocks)")
      ->capture_default_str();
  c->add_option("--repeat-tol", a->repeat_tol,
                "two rows measure one joint configuration again when every joint agrees within this (deg; mm for "
                "prismatic joints): the repeatability floor")
      ->capture_default_str();
  c->add_option("--robust-k", a->robust_k,
                "robust estimation: rows whose residual exceeds k robust standard deviations are down-weighted "
                "(Huber); 0 turns it off")
      ->capture_default_str();
  c->add_option("--json", a->json, "write the diagnosis as JSON")->required();
  c->add_option("--report", a->report, "write the diagnosis as a self-contained HTML page");
  c->callback([=]() { exitCode() = runDiagnose(*a); });
}

}  // namespace accura::cli
