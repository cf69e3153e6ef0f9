// accura diagnose: where the remaining error lies, which effect of the catalogue causes it and
// how far it shrinks once that effect is modelled (docs/diagnosis.md).
#include <algorithm>
#include <cstdarg>
#include <cmath>
#include <ctime>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>

#include "accura/calib/joint_map.h"
#include "accura/calib/diagnose.h"
#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "accura/calib/identify.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/measurements.h"
#include "cli_util.h"
#include "commands.h"

namespace accura::cli {
namespace {

struct DiagnoseArgs {
  std::string robot;
  std::vector<std::string> data;  // one or more data sets, each its own station unless same_station
  bool same_station = false;
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
  bool position_only = false;
  std::string json;
  std::string report;
};

// The report's header and model section (diagnose.h calib::DiagnosisReportContext): when, which
// accura, which instrument and files, and the complete geometric model identified on the fit
// data with its sigmas and per-pose errors.
calib::DiagnosisReportContext reportContext(const DiagnoseArgs& a, const calib::RobotModel& start, const calib::MeasurementSet& data,
                                     const calib::Diagnosis& d) {
  calib::DiagnosisReportContext c;
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char date[32];
  std::strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", &utc);
  c.date_utc = date;
  c.version = std::string("accura ") + ACCURA_VERSION_STRING;
  c.instrument = "noise floor " + fmt("%.4f", d.noise_floor_mm) + " mm (3D RMS), from " + d.noise_floor_source;
  for (const std::string& f : a.data) c.data_files.push_back("fit: " + f);
  if (!a.validate.empty()) c.data_files.push_back("validation: " + a.validate);
  if (!a.map.empty()) c.data_files.push_back("mapping: " + a.map);
  if (!a.validate_map.empty()) c.data_files.push_back("validation mapping: " + a.validate_map);
  calib::IdentifyOptions o;
  o.groups = {"geometric"};
  calib::IdentifySummary s;
  const calib::RobotModel model = calib::identify(start, data, o, &s);
  for (const auto& p : s.parameters) c.parameters.push_back({p.name, p.value, p.sigma, p.unit, p.group == "base"});
  calib::KinematicWorkspace ws;
  for (const calib::Measurement& m : data.rows)
    c.residuals_mm.push_back(m.p_world_mm - calib::forwardKinematics(model, m.q, m.context, ws).translation());
  return c;
}

/// printf into a string (the warnings below hold several values).
std::string format(const char* f, ...) __attribute__((format(printf, 1, 2)));
std::string format(const char* f, ...) {
  va_list args, again;
  va_start(args, f);
  va_copy(again, args);
  const int n = std::vsnprintf(nullptr, 0, f, args);
  va_end(args);
  std::string out(static_cast<size_t>(std::max(n, 0)) + 1, '\0');
  std::vsnprintf(out.data(), out.size(), f, again);
  va_end(again);
  out.resize(static_cast<size_t>(std::max(n, 0)));
  return out;
}

/// What checkValidationSet finds: warnings (without the "accura: warning: " of stderr) and, for a
/// validation set of another station, the sentence the verdict leads with.
struct ValidationCheck {
  std::vector<std::string> warnings;
  std::string verdict_caveat;  ///< empty unless the validation set looks measured from another station
};

/// --validate is held-out data of the fit's station and joint ranges (--help): where it is not,
/// the verdict describes the difference, not the robot. Warnings: validation poses outside the
/// fit data's joint ranges (as identify says them), and a station that moved (re-registering
/// the station alone, the baseline model held, takes much of the validation residual away).
ValidationCheck checkValidationSet(const calib::Diagnosis& d, const calib::MeasurementSet& fit,
                                   const calib::MeasurementSet& validation, const std::string& file) {
  ValidationCheck out;
  const int dof = d.baseline_model.dof();
  const std::vector<calib::JointRange> covered = calib::jointRanges(fit, dof);
  int outside = 0;
  for (const calib::Measurement& r : validation.rows)
    for (int j = 0; j < dof; ++j)
      if (calib::beyondFitRange(covered[static_cast<size_t>(j)], r.q[j], calib::fitRangePeriod(d.baseline_model, j)) > 0) {
        ++outside;
        break;
      }
  if (outside > 0)
    out.warnings.push_back(format("%s: %d of %zu validation poses lie outside the joint ranges of the fit data: the held-out "
                               "errors there measure extrapolation, not the effects on the fitted ranges",
                               file.c_str(), outside, validation.rows.size()));
  calib::IdentifySummary rs;
  calib::RobotModel moved;
  try {
    moved = calib::registerStation(d.baseline_model, validation, &rs);
  } catch (const calib::InputError& e) {
    // no frame of the model holds the validation set (its units, joint order or robot wrong: the
    // registration says which, with the factor of a unit it finds): its held-out errors measure
    // that, not the robot (they were reported as the robot's, the verdict "unexplained")
    out.warnings.push_back(std::string(e.what()) + " (re-registering the validation set's station alone on it: its held-out errors "
                                                   "measure this, not the robot)");
    out.verdict_caveat = "The validation set " + file + " fits no frame of the model: re-registering its station alone on it "
                         "says: " + e.what() + ". The held-out errors below measure that, not the robot.";
    return out;
  } catch (const std::exception&) {
    return out;  // (a check that cannot run, degenerate points, says nothing; the diagnosis stands)
  }
  const Eigen::Isometry3d D = d.baseline_model.T_world_base().inverse() * moved.T_world_base();
  const double before = calib::evaluate(d.baseline_model, validation).rms_mm, after = rs.fit.rms_mm;
  const double moved_mm = D.translation().norm(), moved_deg = Eigen::AngleAxisd(D.linear()).angle() * calib::kRadToDeg;
  if ((moved_mm > 0.5 || moved_deg > 0.01) && after < 0.7 * before) {
    out.warnings.push_back(format("%s: looks measured from another station: re-registering the station alone (the geometric "
                               "model held) moves it %.3f mm and %.4f deg and takes its RMS from %.4f to %.4f mm; diagnose "
                               "expects --validate from the fit's station (identify --validate-station new re-registers one)",
                               file.c_str(), moved_mm, moved_deg, before, after));
    out.verdict_caveat = format("The validation set %s looks measured from another station (re-registering the station alone "
                             "moves it %.3f mm and %.4f deg and takes its RMS from %.4f to %.4f mm): the held-out errors below "
                             "hold the difference of the two stations, so this verdict describes that difference as much as "
                             "the robot. Diagnose with --validate from the fit's station, without --validate (cross-validation), "
                             "or with the file as a second --data (each its own station).",
                             file.c_str(), moved_mm, moved_deg, before, after);
  }
  return out;
}

int runDiagnose(const DiagnoseArgs& a) {
  if (a.json.empty() && a.report.empty())
    throw calib::InputError("diagnose: expected an output, --json diag.json and/or --report diag.html, found neither");
  // options that would have no effect are refused, not dropped without a word
  if (!a.validate_map.empty() && a.validate.empty())
    throw calib::InputError("--validate-map: expected together with --validate (the mapping of the validation file), found it without");
  if (a.same_station && a.data.size() < 2)
    throw calib::InputError("--same-station: expected several --data files (measured from one tracker station), found one");
  std::vector<std::string> inputs = {a.robot, a.validate, a.map, a.validate_map};
  inputs.insert(inputs.end(), a.data.begin(), a.data.end());
  // the outputs' directories and the overwrite guard before the diagnosis, not after it
  calib::refuseUnwritableOutputs({a.json, a.report}, inputs, "--json / --report");
  calib::RobotModel start = loadRobot(a.robot);
  if (!a.base.empty()) start.nominal.T_world_base = calib::toIsometry(parsePose6(a.base, "--base"));
  if (!a.tool.empty()) start.nominal.T_flange_tcp = calib::toIsometry(parseTool(a.tool, "--tool"));
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
  o.use_orientation = !a.position_only;
  std::string why;
  if (!o.IsValid(&why)) throw calib::InputError("diagnose: " + why);

  refuseRepeatedDataFiles(a.data);
  std::vector<calib::MeasurementSet> sets;
  for (const std::string& f : a.data) sets.push_back(readMeasurements(f, a.map, start.nominal));
  calib::refuseSharedMeasurements(sets);  // (a copy of a file under another name)
  calib::MeasurementSet validation;
  if (!a.validate.empty()) {
    validation = readMeasurements(a.validate, a.validate_map.empty() ? a.map : a.validate_map, start.nominal);
    calib::refuseValidationInFitData(sets, validation);
  }
  calib::StationSets stations;
  calib::Diagnosis d = calib::diagnose(start, sets, a.same_station, a.validate.empty() ? nullptr : &validation, o, &stations);
  const calib::MeasurementSet& data = stations.combined;
  ValidationCheck checked;
  if (!a.validate.empty()) {
    // the check sees the validation rows the diagnosis used: a lost beam left out as gross
    // (d.excluded) would otherwise pull the station's re-registration by metres
    calib::MeasurementSet screened = validation;
    screened.rows.clear();
    for (const calib::Measurement& r : validation.rows) {
      const bool gross = std::any_of(d.excluded.begin(), d.excluded.end(), [&](const calib::ExcludedRow& e) {
        return e.file == validation.file && e.line == r.line;
      });
      if (!gross) screened.rows.push_back(r);
    }
    checked = checkValidationSet(d, data, screened, a.validate);
  }
  // the verdict (text, JSON, report) leads with what its held-out errors hold
  if (!checked.verdict_caveat.empty()) d.verdict.explanation = checked.verdict_caveat + " " + d.verdict.explanation;
  if (sets.size() > 1) {
    std::printf("%zu data sets%s:\n", sets.size(), a.same_station ? ", one station" : ", each from its own station (registered by the geometric identification on all of them; the cross-validation registers a held-out set's station again on its rows)");
    for (size_t k = 0; k < sets.size(); ++k) {
      const Eigen::Isometry3d& T = stations.T_first_station[k];
      std::printf("  %s: %zu poses; station %zu, %.3f mm and %.4f deg from the first\n", sets[k].file.c_str(), sets[k].rows.size(), k + 1,
                  T.translation().norm(), Eigen::AngleAxisd(T.linear()).angle() * calib::kRadToDeg);
    }
  }
  std::printf("%s", calib::diagnosisText(d).c_str());
  // printed on stderr after the text (as before), and part of the JSON's and the report's warnings,
  // where they qualify the verdict that a reader of those outputs would otherwise take as is
  for (const std::string& w : checked.warnings) std::fprintf(stderr, "accura: warning: %s\n", w.c_str());
  d.warnings.insert(d.warnings.end(), checked.warnings.begin(), checked.warnings.end());
  // The JSON and the HTML report are one output set (all or nothing), never onto an input.
  std::vector<calib::OutputFile> outputs;
  if (!a.json.empty()) outputs.push_back({a.json, calib::diagnosisJson(d)});
  if (!a.report.empty()) outputs.push_back({a.report, calib::diagnosisHtml(d, reportContext(a, start, data, d))});
  calib::refuseToOverwrite(outputs, inputs, "--json / --report");
  calib::writeFilesAtomically(outputs);
  for (const calib::OutputFile& f : outputs) std::printf("wrote %s\n", f.path.c_str());
  return 0;
}

}  // namespace

void addDiagnoseCommand(CLI::App& app) {
  auto a = std::make_shared<DiagnoseArgs>();
  auto* c = app.add_subcommand("diagnose",
                               "where the remaining error lies, which unmodelled effect causes it, how far it shrinks");
  c->add_option("--robot", a->robot, "robot (file or bundled name; a calibrated model is a starting point)")->required();
  c->add_option("--data", a->data,
                "measurement CSV; give it more than once for several data sets, each from its own tracker station (6 parameters each) "
                "unless --same-station")
      ->required();
  c->add_flag("--same-station", a->same_station, "the --data files were measured from one tracker station");
  c->add_flag("--position-only", a->position_only,
              "6D data: fit the positions alone (default: the fits use the measured orientations too, as identify "
              "does; the held-out errors are positions either way)");
  c->add_option("--validate", a->validate, "held-out measurement CSV of the same robot and station "
                                           "(default: k-fold cross-validation over --data)");
  c->add_option("--map", a->map, "mapping file: how to read --data (and --validate) as exported by the instrument");
  c->add_option("--validate-map", a->validate_map, "mapping file for --validate when it differs from --map");
  c->add_option("--base", a->base, "nominal T_world_base x,y,z,A,B,C (mm, deg), as for identify");
  c->add_option("--tool", a->tool, "nominal T_flange_tcp x,y,z[,A,B,C] (mm, deg), as for identify");
  c->add_option("--effects", a->effects,
                "effects to test (default: the catalogue: joint_compliance, gear_periodic, joint_scale, backlash, thermal, joint_map)");
  addIntegerOption(c, "--harmonics", a->harmonics, "harmonics 1..H of gear_periodic", 1, calib::kMaxGearHarmonics)->capture_default_str();
  addIntegerOption(c, "--folds", a->folds, "folds of the cross-validation without --validate", 2, 20)->capture_default_str();
  addNumberOption(c, "--noise-mm", a->noise_mm,
                "measurement noise, 1 sigma per axis (mm) (default: from repeated poses, else from the std columns)",
                NumberRange{0, 100, true, "mm"});
  addNumberOption(c, "--alpha", a->alpha, "significance level of one selection round (Bonferroni over its blocks)", NumberRange{0, 0.5, true, ""})
      ->capture_default_str();
  addNumberOption(c, "--repeat-tol", a->repeat_tol,
                "two rows measure one joint configuration again when every joint agrees within this (deg; mm for "
                "prismatic joints): the repeatability floor",
                  NumberRange{0, 1, true, "deg; mm for prismatic joints"})
      ->capture_default_str();
  addNumberOption(c, "--robust-k", a->robust_k,
                "robust estimation: rows whose residual exceeds k robust standard deviations are down-weighted "
                "(Huber); 0 turns it off",
                  NumberRange{0, 1000, false, "robust standard deviations"})
      ->capture_default_str();
  c->add_option("--json", a->json, "write the diagnosis as JSON (--json, --report or both)");
  c->add_option("--report", a->report, "write the diagnosis as a self-contained HTML page");
  c->callback([=]() { exitCode() = runDiagnose(*a); });
}

}  // namespace accura::cli
