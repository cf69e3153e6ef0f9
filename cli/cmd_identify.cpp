#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "accura/calib/json_text.h"
#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "accura/calib/identify.h"
#include "accura/calib/import.h"
#include "accura/calib/joint_map.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/measurements.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"
#include "cli_util.h"
#include "commands.h"

namespace accura::cli {
namespace {
using nlohmann::ordered_json;

/// --holdout: the fraction of the poses held out (0: none; at most half: the fit keeps at least
/// every other configuration). The one range: the option's parser refuses anything outside it.
const NumberRange kHoldoutRange{0, 0.5, false, ""};

/// "2nd", "3rd", "5th", "11th", "21st": which of every n poses --holdout keeps.
std::string ordinal(int n) {
  const int last2 = n % 100, last = n % 10;
  const char* suffix = (last2 >= 11 && last2 <= 13) ? "th" : last == 1 ? "st" : last == 2 ? "nd" : last == 3 ? "rd" : "th";
  return std::to_string(n) + suffix;
}

/// The start model of --robot in the link forms of --form, with --base and --tool.
calib::RobotModel startModel(const IdentifyArgs& a) {
  calib::RobotModel start = loadRobot(a.robot);
  if (a.form == "dh") {
    if (start.forms != calib::chooseLinkForms(start.nominal, calib::FormPolicy::kDHOnly)) {
      const calib::Deviations dev = start.deviations;
      start = calib::RobotModel::fromDefinition(start.nominal, calib::FormPolicy::kDHOnly);
      start.deviations = dev;
      for (auto& l : start.deviations.links) l.dbeta_rad = 0;  // no beta in DH
    }
  } else if (a.form != "auto") {
    throw calib::InputError("--form: expected 'auto' or 'dh', found '" + a.form + "'");
  }
  if (!a.base.empty()) start.nominal.T_world_base = calib::toIsometry(parsePose6(a.base, "--base"));
  if (!a.tool.empty()) start.nominal.T_flange_tcp = calib::toIsometry(parseTool(a.tool, "--tool"));
  return start;
}

/// --validate-station new on fewer distinct configurations than this is warned about: the
/// station's 6 parameters take 6 of the 3M position equations, 2/M of a random error's variance
/// (20% at M = 10: the RMS reads 11% low), more below.
constexpr int kMinStationConfigurations = 10;
/// worseAdvice: the nominal robot counts as at the measurement noise when its validation RMS is
/// within this factor of the 3D RMS the std columns state (a registered nominal model on a
/// robot without errors comes to about 1.03 of it).
constexpr double kNominalAtNoise = 1.2;

/// A validation said to be from the fit's station (--validate-station same, --holdout) is gross
/// when its median position error exceeds both kGrossValidationFloorMm and
/// calib::kGrossRowMedianFactor times the fit's RMS (what makes a single row gross against its
/// set's median): a robot registered in its tracker's frame is within millimetres even
/// uncalibrated (the KR 16 example 1.7 mm RMS, the real UR10 1.0 mm; 3.3 mm at most), and a
/// calibrated model extrapolated beyond its joint ranges is off by a fraction of that. Such a
/// validation is of another frame: another station (the common case), robot or unit.
constexpr double kGrossValidationFloorMm = 5.0;
/// Re-registering the station alone explains a validation (as diagnose's check of --validate):
/// it moves the station more than this (mm or deg) and takes more than 30% off the RMS.
constexpr double kStationMovedMm = 0.5, kStationMovedDeg = 0.01, kStationRmsShare = 0.7;

/// Validation poses outside the joint ranges of the fit, per joint: how many and how far.
struct Outside {
  int count = 0;
  double max = 0;
  std::vector<int> lines;
};

/// Everything one identify run has found, for the report, the model file's comment and --json.
struct IdentifyRun {
  calib::RobotModel start;
  std::vector<calib::MeasurementSet> sets;  ///< the fit data, one set per --data
  std::string data_names;                   ///< "a.csv, b.csv"
  size_t n_rows = 0;
  bool orient = true;                       ///< every set has orientations
  calib::MeasurementSet validation;         ///< --validate or the --holdout poses (may be empty)
  std::string validation_source;
  std::string holdout_note;                 ///< --holdout: how many poses it keeps from the fit
  std::vector<std::string> data_warnings;   ///< about the --data files as read (rows written twice)
  calib::IdentifyOptions opt;
  calib::IdentifySummary s;
  calib::RobotModel calibrated;
  calib::ErrorStats val, nom_val;           ///< on the validation data: calibrated, nominal registered
  std::string station_note;                 ///< --validate-station new: how far the station moved
  std::string orientation_note;             ///< why the validation's orientation errors are not reported
  std::string gross_validation;             ///< a validation of the fit's station grossly off: why (else empty)
  std::vector<calib::SuspiciousRow> val_suspicious;  ///< suspicious validation rows
  std::vector<Outside> outside;             ///< per joint
  int outside_rows = 0;

  bool hasValidation() const { return !validation.rows.empty(); }
  const char* unitOf(int j) const {
    return start.nominal.joints[static_cast<size_t>(j)].type == calib::JointType::kRevolute ? "deg" : "mm";
  }
};

/// Reads --data and the validation data (--validate, else every n-th pose of --holdout).
void readData(const IdentifyArgs& a, IdentifyRun& r) {
  if (a.validate_station != "same" && a.validate_station != "new")
    throw calib::InputError("--validate-station: expected 'same' or 'new', found '" + a.validate_station + "'");
  if (a.validate_station == "new" && a.validate.empty())
    throw calib::InputError("--validate-station new: expected a --validate file measured from another station");
  if (a.data.empty()) throw calib::InputError("--data: expected at least one measurement file");
  // options of the validation file without one: refused, not dropped without a word
  if (a.validate.empty()) {
    if (!a.validate_map.empty())
      throw calib::InputError("--validate-map: expected together with --validate (the mapping of the validation file), found it without");
    if (a.validate_station_given)
      throw calib::InputError("--validate-station " + a.validate_station +
                              ": expected together with --validate (the station of the validation file), found it without");
  }
  if (a.same_station && a.data.size() < 2)
    throw calib::InputError("--same-station: expected several --data files (measured from one tracker station), found one");
  refuseRepeatedDataFiles(a.data);
  for (const std::string& f : a.data) r.sets.push_back(readMeasurements(f, a.map, r.start.nominal));
  calib::refuseSharedMeasurements(r.sets);  // (a copy of a file under another name)
  for (const std::string& f : a.data) r.data_names += (r.data_names.empty() ? "" : ", ") + f;
  // a row written twice is one measurement: counted once in the fit, in a --holdout and in the
  // validation alike; a reading written again for the next pose is named
  const auto screenRows = [&](calib::MeasurementSet& set) {
    for (const std::string& w : {calib::duplicatedRowsWarning(set.file, calib::removeDuplicatedRows(set)),
                                 calib::staleReadingsWarning(set.file, calib::staleReadings(set))})
      if (!w.empty()) r.data_warnings.push_back(w);
  };
  for (calib::MeasurementSet& set : r.sets) screenRows(set);
  if (!a.validate.empty() && a.holdout_given && a.holdout > 0)
    throw calib::InputError("--holdout and --validate: expected one of them (the validation poses come from the --validate file or "
                            "from the --data file), found both");
  if (!a.validate.empty()) {
    r.validation = readMeasurements(a.validate, a.validate_map.empty() ? a.map : a.validate_map, r.start.nominal);
    calib::refuseValidationInFitData(r.sets, r.validation);
    screenRows(r.validation);
    if (std::string w = calib::validationLooksLikeFitDataWarning(r.sets, r.validation); !w.empty()) r.data_warnings.push_back(w);
    r.validation_source = a.validate;
    return;
  }
  // (a.holdout is within kHoldoutRange: the option's parser refuses anything else)
  if (a.holdout <= 0) return;
  if (r.sets.size() > 1) {
    // each set has its own station: a held-out file (--validate) says which station it is from
    if (a.holdout_given)
      throw calib::InputError("--holdout: with several --data files give --validate (a held-out file) instead");
    return;  // (the default holdout is for one --data file)
  }
  calib::MeasurementSet& data = r.sets[0];
  const int every = std::max(2, static_cast<int>(std::lround(1.0 / a.holdout)));
  // every k-th joint configuration with all its repeats (measurements.h): a configuration held
  // out must not also be in the fit, else the holdout measures the repeatability, not the model
  // (without repeats: every k-th pose)
  const std::vector<std::vector<int>> configs = calib::repeatedConfigurations(data);
  std::vector<bool> held(data.rows.size(), false);
  int held_configs = 0;
  for (size_t g = 0; g < configs.size(); ++g) {
    if (g % every != static_cast<size_t>(every - 1)) continue;
    ++held_configs;
    for (int i : configs[g]) held[static_cast<size_t>(i)] = true;
  }
  calib::MeasurementSet fit = data;
  fit.rows.clear();
  r.validation = data;
  r.validation.rows.clear();
  for (size_t i = 0; i < data.rows.size(); ++i) (held[i] ? r.validation : fit).rows.push_back(data.rows[i]);
  data = fit;
  const bool repeats = configs.size() < held.size();
  r.validation_source = repeats ? "every " + ordinal(every) + " joint configuration of " + r.data_names + " with its repeats (" +
                                      std::to_string(held_configs) + " of " + std::to_string(configs.size()) + " distinct configurations, held out)"
                                : "every " + ordinal(every) + " pose of " + r.data_names + " (held out)";
  r.holdout_note = " (" + std::to_string(r.validation.rows.size()) + " of the file's " + std::to_string(fit.rows.size() + r.validation.rows.size()) +
                   " poses are held out for validation, --holdout " + fmt("%g", a.holdout) + ": --holdout 0 fits them all)";
}

calib::IdentifyOptions identifyOptions(const IdentifyArgs& a) {
  calib::IdentifyOptions opt;
  opt.groups = splitList(a.params, "--params");
  opt.loss = a.loss;
  opt.loss_scale = a.loss_scale;
  if (a.std_mm > 0) opt.position_std_mm = a.std_mm;
  if (a.std_deg > 0) opt.orientation_std_deg = a.std_deg;
  if (a.map_smoothing >= 0) opt.joint_map_smoothing = a.map_smoothing;
  opt.same_station = a.same_station;
  std::string why;
  // the numbers are range-checked by their options; what IsValid finds is --loss's or --params'
  if (!opt.IsValid(&why)) throw calib::InputError((why.rfind("loss", 0) == 0 ? "--loss: " : "--params: ") + why);
  // an option of a fit that does not happen is refused, not dropped without a word
  if (a.loss_scale_given && a.loss == "none")
    throw calib::InputError("--loss-scale: expected together with --loss huber or cauchy (the scale of a robust loss), found --loss none");
  if (a.map_smoothing >= 0 &&
      std::none_of(opt.groups.begin(), opt.groups.end(), [](const std::string& g) { return g.rfind("joint_map", 0) == 0; }))
    throw calib::InputError("--map-smoothing: expected together with joint_map in --params (the smoothness of the joint maps it fits), found --params " +
                            a.params);
  return opt;
}

/// calib::identify on the fit data; too few rows: the error says how many poses --holdout took.
calib::RobotModel identifyFit(const IdentifyRun& r, const calib::IdentifyOptions& o, calib::IdentifySummary* s) {
  try {
    return calib::identify(r.start, r.sets, o, s);
  } catch (const calib::InputError& e) {
    const std::string what = e.what();
    if (r.holdout_note.empty() || (what.find("too few rows") == std::string::npos && what.find("too few distinct") == std::string::npos)) throw;
    throw calib::InputError(std::string(e.what()) + r.holdout_note);
  }
}

/// Empty, or why a validation of the fit's station is grossly off (kGrossValidationFloorMm): its
/// median error against the fit's RMS, and whether re-registering the station alone (the robot
/// held) explains it, as diagnose checks its --validate: the likely cause named, the remedy given.
std::string grossValidation(const IdentifyRun& r) {
  std::vector<double> e = calib::positionErrors(r.calibrated, r.validation);
  if (e.empty()) return "";
  std::nth_element(e.begin(), e.begin() + static_cast<std::ptrdiff_t>(e.size() / 2), e.end());
  const double median = e[e.size() / 2], fit = r.s.fit.rms_mm;
  if (!(median > kGrossValidationFloorMm && median > calib::kGrossRowMedianFactor * fit)) return "";
  std::string w = "the validation on " + r.validation_source + " is grossly off: its median position error is " + fmt("%.1f", median) +
                  " mm, more than " + fmt("%.0f", kGrossValidationFloorMm) + " mm and " + fmt("%.0f", calib::kGrossRowMedianFactor) +
                  " times the fit's RMS (" + fmt("%.4f", fit) +
                  " mm), which no robot's own error makes on poses measured from the fit's station: its figures describe another "
                  "frame, not the model. ";
  calib::IdentifySummary st;
  try {
    const calib::RobotModel moved = calib::registerStation(r.calibrated, r.validation, &st);
    // the validation's tracker in the fit's tracker frame: T_fit_val = T_fit_base T_val_base^-1
    const Eigen::Isometry3d D = r.calibrated.T_world_base() * moved.T_world_base().inverse();
    const double mm = D.translation().norm(), deg = Eigen::AngleAxisd(D.linear()).angle() * calib::kRadToDeg;
    const std::string re = "re-registering the station alone (6 parameters, the robot held) puts its tracker " + fmt("%.1f", mm) +
                           " mm and " + fmt("%.2f", deg) + " deg from the fit's and takes the RMS from " + fmt("%.4f", r.val.rms_mm) +
                           " to " + fmt("%.4f", st.fit.rms_mm) + " mm";
    if ((mm > kStationMovedMm || deg > kStationMovedDeg) && st.fit.rms_mm < kStationRmsShare * r.val.rms_mm)
      return w + "It is likely measured from another tracker station: " + re + ". Validate it with --validate-station new";
    return w + "Another station does not explain it (" + re + "): check that it measures this robot, in mm and deg, with the fit "
               "data's joint order and columns";
  } catch (const std::exception& ex) {
    return w + "Re-registering the station on it failed (" + ex.what() + "): check that it measures this robot, in mm and deg";
  }
}

/// The errors on the validation data of the calibrated model and of the nominal model with only
/// the measurement frame and the tool registered (--validate-station new: the station
/// re-registered for both, robot parameters held fixed).
void validate(const IdentifyArgs& a, IdentifyRun& r) {
  calib::IdentifyOptions nominal_opt = r.opt;
  nominal_opt.groups = {"base", "tool"};
  nominal_opt.loss = "none";
  calib::IdentifySummary ns;
  const calib::RobotModel nominal_registered = identifyFit(r, nominal_opt, &ns);
  r.outside.assign(static_cast<size_t>(r.start.dof()), Outside{});
  if (!r.hasValidation()) return;
  // gross rows (a lost beam) would decide the validation's RMS: left out and named
  const std::vector<calib::ExcludedRow> gross = calib::removeGrossRows(r.calibrated, r.validation, a.validate_station == "new", false);
  for (const std::string& w : calib::excludedRowWarnings(gross, "the validation")) r.s.warnings.push_back(w);
  if (a.validate_station == "new") {
    // another station: re-register it (6 parameters), robot parameters held fixed. The station
    // is placed in closed form from the measured positions (orientations only refine it), so it
    // needs 3 distinct, non-collinear points, and it absorbs part of the model's error at them:
    // with M distinct configurations, 6 of the 3M position equations, 2/M of a random error's
    // variance on average (below kMinStationConfigurations more than a fifth: the RMS reads more
    // than 10% low; more for a smooth error over few nearby poses)
    const int poses = static_cast<int>(r.validation.rows.size());
    const int configs = static_cast<int>(calib::repeatedConfigurations(r.validation).size());
    const std::string counted = std::to_string(poses) + " poses, " + std::to_string(configs) + " distinct joint configuration" +
                                (configs == 1 ? "" : "s");
    if (configs < 3)
      throw calib::InputError(a.validate, 0, 0,
                              "--validate-station new: expected at least 3 distinct joint configurations to re-register the station on "
                              "(6 parameters, placed from the measured positions, which must not be collinear; the orientations only "
                              "refine it), found " + counted + ": the station would absorb the model's error there and the "
                              "validation would read as the repeatability. Validate on more distinct configurations, or from the "
                              "fit's station (--validate-station same)");
    calib::IdentifySummary st, nst;
    calib::RobotModel cal_st, nom_st;
    try {
      cal_st = calib::registerStation(r.calibrated, r.validation, &st);
      nom_st = calib::registerStation(nominal_registered, r.validation, &nst);
    } catch (const calib::NumericalError& e) {
      throw calib::NumericalError(a.validate + ": --validate-station new: " + e.what() + " (" + counted +
                                  "; the station is placed from the measured positions)");
    }
    if (configs < kMinStationConfigurations)
      r.s.warnings.push_back(
          "--validate-station new re-registered the station (6 parameters) on " + a.validate + ": " + counted + ", fewer than " +
          std::to_string(kMinStationConfigurations) + ". The station absorbs part of the error at so few points (6 of the " +
          std::to_string(3 * configs) + " position equations: the RMS of a random error reads " +
          fmt("%.0f", 100.0 * (1.0 - std::sqrt(std::max(0.0, 1.0 - 2.0 / configs)))) +
          "% low on average, a smooth one more): the validation RMS, nominal and calibrated, understates the error. Validate "
          "on more distinct configurations, or from the fit's station");
    const Eigen::Isometry3d moved = r.calibrated.T_world_base().inverse() * cal_st.T_world_base();
    r.station_note = "validation station re-registered on " + a.validate + " (6 parameters, robot held fixed): base moved " +
                     fmt("%.3f", moved.translation().norm()) + " mm, " +
                     fmt("%.4f", Eigen::AngleAxisd(moved.linear()).angle() * calib::kRadToDeg) + " deg";
    r.val = calib::evaluate(cal_st, r.validation);
    r.nom_val = calib::evaluate(nom_st, r.validation);
    r.val_suspicious = calib::suspiciousRows(cal_st, r.validation);
  } else {
    r.val = calib::evaluate(r.calibrated, r.validation);
    r.nom_val = calib::evaluate(nominal_registered, r.validation);
    r.val_suspicious = calib::suspiciousRows(r.calibrated, r.validation);
    r.gross_validation = grossValidation(r);
  }
  // a fit without orientations never identified the tool's rotation: the model's orientation is
  // the start tool's, and an orientation error against 6D validation data measures how the target
  // is mounted, not the robot
  const bool fit_orientation = std::all_of(r.sets.begin(), r.sets.end(), [](const calib::MeasurementSet& d) { return d.has_orientation; });
  if (!fit_orientation && r.val.has_orientation) {
    r.val.has_orientation = r.nom_val.has_orientation = false;
    r.orientation_note = "orientation errors not reported: " + r.validation_source + " has orientations, but the fit data has none, "
                         "so the tool's rotation was never identified (the model carries the start tool's); an orientation error "
                         "would measure how the target is mounted, not the robot";
  }
  // validation poses outside the joint ranges of the fit: per joint, how many and how far
  for (const calib::Measurement& m : r.validation.rows) {
    bool any = false;
    for (int j = 0; j < r.start.dof(); ++j) {
      const double d = calib::beyondFitRange(r.s.coverage[static_cast<size_t>(j)], m.q[j], calib::fitRangePeriod(r.calibrated, j));
      if (d <= calib::kFitRangeTolerance) continue;  // the rounding of a radian export is not outside
      Outside& o = r.outside[static_cast<size_t>(j)];
      ++o.count;
      o.max = std::max(o.max, d);
      if (o.lines.size() < 20) o.lines.push_back(m.line);
      any = true;
    }
    r.outside_rows += any ? 1 : 0;
  }
}

/// The data sets, the fit's joint ranges and link forms, identifiability, weighting, solver
/// and joint maps (not with --quiet).
void printSetup(const IdentifyArgs& a, const IdentifyRun& r) {
  const calib::IdentifySummary& s = r.s;
  if (r.sets.size() > 1) {
    std::printf("data sets: %zu, %s\n", r.sets.size(),
                r.opt.same_station ? "one tracker station shared (--same-station)"
                                   : "each from its own tracker station (6 station parameters per set beyond the first)");
    for (size_t k = 0; k < r.sets.size(); ++k) {
      const calib::XyzAbc b = calib::toXyzAbc(s.T_world_base_per_set[k]);
      std::printf("  %s: %zu poses, T_world_base %.3f, %.3f, %.3f mm, %.4f, %.4f, %.4f deg\n", r.sets[k].file.c_str(),
                  r.sets[k].rows.size(), b.x_mm, b.y_mm, b.z_mm, b.a_deg, b.b_deg, b.c_deg);
    }
  }
  const int dof = r.start.dof();
  std::printf("joint ranges of the fit data (the model is fitted there; joint-dependent effects are not "
              "extrapolated beyond):");
  for (int j = 0; j < dof; ++j)
    std::printf(" j%d %.1f..%.1f %s%s", j + 1, s.coverage[static_cast<size_t>(j)].lower, s.coverage[static_cast<size_t>(j)].upper,
                r.unitOf(j), j + 1 < dof ? ";" : "\n");
  std::printf("link forms:");
  for (int i = 0; i < dof; ++i) std::printf(" j%d=%s", i + 1, r.start.forms[i] == calib::LinkForm::kHayati ? "Hayati" : "DH");
  std::printf("\n");
  std::printf("registration: measurement frame in closed form, position RMS %.3f mm after registration\n",
              s.registration_rms_mm);
  // repeats add equations, not information: the distinct configurations are counted too
  const std::string distinct = s.configurations < s.poses
                                   ? " (" + std::to_string(s.poses) + " poses, " + std::to_string(s.configurations) +
                                         " distinct configurations: " + std::to_string(s.independent_equations) + " independent equations)"
                                   : "";
  std::printf("identifiability: %d parameters identified from %d equations%s; condition number %.4g "
              "(all %zu candidates: %s); observability index O1 %.4g\n",
              s.parameters_free, s.equations, distinct.c_str(), s.condition_number, s.fixed.size() + s.parameters_free,
              std::isfinite(s.condition_number_all) ? fmt("%.4g", s.condition_number_all).c_str() : "inf (rank deficient)",
              s.observability_index);
  for (const auto& f : s.fixed) std::printf("  fixed %-16s %s\n", f.name.c_str(), f.reason.c_str());
  std::printf("weighting: %s", s.weighting.c_str());
  if (std::isfinite(s.position_std_mm)) std::printf(" [position std %.4g mm]", s.position_std_mm);
  if (std::isfinite(s.orientation_std_deg)) std::printf(" [orientation std %.4g deg]", s.orientation_std_deg);
  std::printf("; variance factor %.3f\n", s.variance_factor);
  // the user's language first, the solver's on request (--verbose)
  const bool converged = s.termination.rfind("CONVERGENCE", 0) == 0 || s.termination.rfind("USER_SUCCESS", 0) == 0;
  // what else was fitted beside the robot's parameters: further stations, map coefficients
  int map_coefficients = 0;
  for (const auto& mrep : s.joint_maps) map_coefficients += mrep.coefficients;
  const int stations = static_cast<int>(s.T_world_base_per_set.size()) > 1 && !a.same_station
                           ? static_cast<int>(s.T_world_base_per_set.size()) - 1 : 0;
  std::string also;
  if (stations > 0) also += " + " + std::to_string(6 * stations) + " of the further station" + (stations > 1 ? "s" : "");
  if (map_coefficients > 0) also += " + " + std::to_string(map_coefficients) + " joint-map coefficients";
  std::printf("solver: %s after %d iterations; fit RMS %.4f mm over %d poses, %d parameters%s\n",
              converged ? "converged" : "stopped before converging (the iteration limit; --verbose says why)",
              s.iterations, s.fit.rms_mm, s.fit.n, s.parameters_free, also.c_str());
  if (a.verbose) std::printf("solver details (Ceres): %s\n", s.BriefReport().c_str());
  if (!s.joint_map_cv.empty()) {
    // what the cross-validation chose: both, or the smoothness alone when the knot spacing was stated
    std::set<double> knots;
    for (const auto& c : s.joint_map_cv) knots.insert(c.knot);
    const bool knot_stated = knots.size() == 1 && s.joint_map_cv_knots_not_tried.empty();
    std::printf("joint_map: %s by blocked cross-validation (5 contiguous blocks of each data set), held-out position RMS "
                "(mm); without maps %.4f:\n",
                knot_stated ? ("smoothness (knot spacing stated: " + fmt("%g", *knots.begin()) + ")").c_str() : "knot spacing and smoothness",
                s.joint_map_cv_baseline_mm);
    for (const auto& c : s.joint_map_cv)
      std::printf("  knot %-5g smoothing %-6g %.4f\n", c.knot, c.smoothing, c.cv_rms_mm);
    if (!s.joint_map_cv_knots_not_tried.empty()) {
      std::string finer;
      for (double k : s.joint_map_cv_knots_not_tried) finer += (finer.empty() ? "" : ", ") + fmt("%g", k);
      std::printf("  knot %s not tried: the finest spacing tried was no better than the one before it\n", finer.c_str());
    }
  }
  for (const auto& mrep : s.joint_maps) {
    // a map the run did not fit (held as the start model has it) has no smoothing of this run
    const std::string smoothing = std::isfinite(mrep.smoothing) ? "smoothing " + fmt("%g", mrep.smoothing) : "held from the start model";
    std::printf("joint_map j%d: %.1f..%.1f %s, knot %.3g %s, %d coefficients, %s; amplitude %.4g %s, "
                "RMS over the fit data %.4g %s; zero outside the interval (taper of one knot)\n",
                mrep.joint, mrep.lower, mrep.upper, mrep.unit.c_str(), mrep.knot, mrep.unit.c_str(), mrep.coefficients,
                smoothing.c_str(), mrep.amplitude, mrep.unit.c_str(), mrep.rms, mrep.unit.c_str());
  }
}

/// Suspicious and down-weighted rows, the station (also as --base takes it), the parameters and
/// the fit's accuracy (not with --quiet).
void printFit(const IdentifyRun& r) {
  const calib::IdentifySummary& s = r.s;
  if (!s.suspicious.empty()) {
    std::printf("suspicious rows (normalised residual above the chi quantile 0.9999; check them for glitches):\n");
    for (size_t k = 0; k < s.suspicious.size() && k < 20; ++k)
      std::printf("  %s:%d  normalised %.1f, position error %.3f mm\n", s.suspicious[k].file.c_str(),
                  s.suspicious[k].line, s.suspicious[k].normalised, s.suspicious[k].error_mm);
    if (s.suspicious.size() > 20) std::printf("  ... and %zu more (see --json)\n", s.suspicious.size() - 20);
  }
  if (!s.downweighted_lines.empty()) {
    std::printf("robust loss down-weighted %zu rows, lines:", s.downweighted_lines.size());
    for (int l : s.downweighted_lines) std::printf(" %d", l);
    std::printf("\n");
  }
  // the station (group base) is where the robot stands in the tracker's frame: a pose, not a
  // deviation of the robot from its nominal model
  bool station = false;
  for (const auto& p : s.parameters) station = station || p.group == "base";
  if (station) {
    std::printf("tracker station (T_world_base: the robot base in the measurement frame, 1 sigma):\n");
    for (const auto& p : s.parameters)
      if (p.group == "base") std::printf("  %-16s %14.6f +- %-12.6f %s\n", p.name.c_str(), p.value, p.sigma, p.unit.c_str());
    const calib::XyzAbc b = calib::toXyzAbc(r.calibrated.T_world_base());
    std::printf("  as --base x,y,z,A,B,C (mm, deg; what compensate --base takes): %.4f,%.4f,%.4f,%.5f,%.5f,%.5f\n", b.x_mm, b.y_mm,
                b.z_mm, b.a_deg, b.b_deg, b.c_deg);
  }
  std::printf("robot parameters (deviation from the nominal model, 1 sigma):\n");
  for (const auto& p : s.parameters)
    if (p.group != "base") std::printf("  %-16s %14.6f +- %-12.6f %s\n", p.name.c_str(), p.value, p.sigma, p.unit.c_str());
  std::printf("accuracy (position mm: RMS mean p95 max%s):\n", r.orient ? "; orientation deg: RMS mean p95 max" : "");
  printStatsRow("fit", s.fit);
}

/// Why a calibrated model may be worse than the nominal one on the validation poses, as far as
/// the run knows: the nominal robot already at the noise the validation's std columns state
/// (nothing to correct: the loss is the fitted parameters' uncertainty), few distinct
/// configurations in the fit, effects beyond the geometric model extrapolated outside the fitted
/// joint ranges, or the geometric model itself fitted on a small part of them.
std::string worseAdvice(const IdentifyRun& r) {
  std::vector<std::string> why;
  const calib::IdentifySummary& s = r.s;
  {
    const double noise_mm = calib::statedPositionNoiseRms({&r.validation});  // NaN without std columns
    if (noise_mm > 0 && r.nom_val.rms_mm <= kNominalAtNoise * noise_mm)
      why.push_back("the nominal robot is already at the measurement noise on these poses, " + fmt("%.4f", r.nom_val.rms_mm) +
                    " mm against " + fmt("%.4f", noise_mm) +
                    " mm from the std columns: there is nothing to correct, and the loss is the fitted parameters' "
                    "uncertainty; keep the nominal model");
  }
  if (s.few_configurations)
    why.push_back("the fit has only " + std::to_string(s.configurations) + " distinct joint configurations (" + std::to_string(s.poses) +
                  " poses): measure more distinct ones");
  if (2 * r.outside_rows > r.val.n) {
    static const std::set<std::string> geometric = {"geometric", "base", "tool", "offsets", "lengths", "angles"};
    const bool effects = std::any_of(r.opt.groups.begin(), r.opt.groups.end(), [](const std::string& g) {
      return !geometric.count(g.substr(0, g.find_first_of(":@")));
    });
    why.push_back(effects ? "most lie outside the fitted joint ranges: the effects fitted there are extrapolated; try without them "
                            "(if the geometric model alone is worse too, measure fit poses that cover these ranges)"
                          : "most lie outside the fitted joint ranges, and only the geometric model was fitted: measure fit poses "
                            "that cover the joint ranges the robot is used in");
  }
  std::string out;
  for (const std::string& w : why) out += (out.empty() ? " (" : "; ") + w;
  return out.empty() ? out : out + ")";
}

/// The warning when the calibrated model is worse than the nominal one on the validation poses
/// (empty when it is not): printed, in the JSON's warnings and in the model file's comment.
/// Below 1.1-fold the loss is given in percent ("1.0-fold WORSE" said nothing).
std::string worseWarning(const IdentifyRun& r) {
  // (a validation grossly off compares nothing: grossValidation says so instead)
  if (!r.hasValidation() || !(r.val.rms_mm > r.nom_val.rms_mm) || !r.gross_validation.empty()) return "";
  const double ratio = r.val.rms_mm / r.nom_val.rms_mm;
  return "position RMS " + (ratio < 1.1 ? fmt("%.1f%%", 100.0 * (ratio - 1.0)) : fmt("%.1f-fold", ratio)) +
         " WORSE than the nominal robot's (" + fmt("%.4f", r.nom_val.rms_mm) + " -> " + fmt("%.4f", r.val.rms_mm) +
         " mm): the calibrated model does not carry over to these poses" + worseAdvice(r);
}

/// The validation's accuracy, nominal against calibrated, and whether it is an extrapolation
/// (poses outside the fit's joint ranges; --quiet: without the other notes).
void printValidation(const IdentifyArgs& a, const IdentifyRun& r) {
  if (!r.hasValidation()) {
    std::printf("no validation data (%s): accuracy on held-out poses not known\n",
                a.data.size() > 1 ? "--validate; --holdout takes its poses from a single --data file" : "--validate or --holdout");
    return;
  }
  std::printf("validation on %s, %d poses (position mm: RMS mean p95 max%s):\n", r.validation_source.c_str(), r.val.n,
              r.orient && r.val.has_orientation ? "; orientation deg: RMS mean p95 max" : "");
  if (!a.quiet && !r.station_note.empty()) std::printf("  %s\n", r.station_note.c_str());
  if (!r.orientation_note.empty()) std::printf("  %s\n", r.orientation_note.c_str());
  if (!r.val_suspicious.empty()) {
    // as for the fit rows (printFit): a glitch in the validation set decides its max and moves its RMS
    std::printf("  %zu suspicious validation row(s) (normalised residual above the chi quantile 0.9999; check them for glitches):",
                r.val_suspicious.size());
    for (size_t k = 0; k < r.val_suspicious.size() && k < (a.quiet ? 1u : 20u); ++k)
      std::printf("%s%s:%d (%.3f mm)", k ? ", " : " ", r.val_suspicious[k].file.c_str(), r.val_suspicious[k].line,
                  r.val_suspicious[k].error_mm);
    if (r.val_suspicious.size() > (a.quiet ? 1u : 20u)) std::printf(", ... (see --json)");
    std::printf("\n");
  }
  if (r.outside_rows > 0) {
    // what the calibrated model does there: its joint maps are zero, its other joint-dependent
    // effects extrapolated; only the geometry when it has neither
    const calib::Deviations& d = r.calibrated.deviations;
    const auto any = [](const std::vector<double>& v) { return std::any_of(v.begin(), v.end(), [](double x) { return x != 0; }); };
    const bool maps = std::any_of(d.joint_map.begin(), d.joint_map.end(), [](const calib::JointMap& m) { return !m.empty(); });
    std::vector<std::string> extrapolated;
    if (any(d.gear_sin) || any(d.gear_cos)) extrapolated.push_back("gear_periodic");
    if (any(d.joint_scale)) extrapolated.push_back("joint_scale");
    if (any(d.compliance)) extrapolated.push_back("joint_compliance");
    std::string what;
    for (size_t k = 0; k < extrapolated.size(); ++k)
      what += (k == 0 ? "" : k + 1 == extrapolated.size() ? " and " : ", ") + extrapolated[k];
    if (!extrapolated.empty()) what = "its " + what + (extrapolated.size() == 1 ? " is" : " are") + " extrapolated";
    if (maps) what = "the model's joint maps are zero there" + (what.empty() ? std::string() : "; " + what);
    if (what.empty()) what = "the model has no joint-dependent effect beyond the geometry, which the fit did not see there";
    std::printf("  %d of %d validation poses %s outside the joint ranges of the fit data (%s):", r.outside_rows, r.val.n,
                r.outside_rows == 1 ? "lies" : "lie", what.c_str());
    const char* separator = " ";
    for (int j = 0; j < r.start.dof(); ++j) {
      const Outside& o = r.outside[static_cast<size_t>(j)];
      if (o.count == 0) continue;
      std::printf("%sj%d %d pose%s, up to %.3g %s", separator, j + 1, o.count, o.count == 1 ? "" : "s", o.max, r.unitOf(j));
      separator = "; ";
    }
    std::printf("\n");
  } else if (!a.quiet) {
    std::printf("  every validation pose lies within the joint ranges of the fit data\n");
  }
  printStatsRow("nominal", r.nom_val);
  printStatsRow("calibrated", r.val);
  if (!r.gross_validation.empty())  // (in place of an improvement that compares two other frames)
    std::printf("  WARNING: %s\n", r.gross_validation.c_str());
  else if (r.val.rms_mm > 0 && r.val.rms_mm <= r.nom_val.rms_mm)
    std::printf("  position RMS improved %.1f-fold (%.4f -> %.4f mm)\n", r.nom_val.rms_mm / r.val.rms_mm, r.nom_val.rms_mm,
                r.val.rms_mm);
  else if (r.val.rms_mm > 0)
    std::printf("  WARNING: %s\n", worseWarning(r).c_str());
}

/// The comment at the top of the calibrated model file.
std::string modelComment(const IdentifyArgs& a, const IdentifyRun& r) {
  std::ostringstream comment;
  const calib::XyzAbc b = calib::toXyzAbc(r.calibrated.T_world_base()), t = calib::toXyzAbc(r.calibrated.T_flange_tcp());
  comment << "accura identify: " << r.calibrated.nominal.name << " from " << r.data_names << " (" << r.n_rows
          << " poses), groups " << a.params << "\n"
          << "calibrated T_world_base: " << fmt("%.4f", b.x_mm) << ", " << fmt("%.4f", b.y_mm) << ", "
          << fmt("%.4f", b.z_mm) << " mm, " << fmt("%.5f", b.a_deg) << ", " << fmt("%.5f", b.b_deg) << ", "
          << fmt("%.5f", b.c_deg) << " deg\n"
          << "calibrated T_flange_tcp: " << fmt("%.4f", t.x_mm) << ", " << fmt("%.4f", t.y_mm) << ", "
          << fmt("%.4f", t.z_mm) << " mm, " << fmt("%.5f", t.a_deg) << ", " << fmt("%.5f", t.b_deg) << ", "
          << fmt("%.5f", t.c_deg) << " deg\n"
          << "fit RMS " << fmt("%.4f", r.s.fit.rms_mm) << " mm"
          << (r.hasValidation() ? ", validation RMS " + fmt("%.4f", r.val.rms_mm) + " mm (nominal " + fmt("%.4f", r.nom_val.rms_mm) + " mm)" : "");
  for (const auto& w : r.s.warnings) comment << "\nWARNING: " << w;
  if (!r.gross_validation.empty()) comment << "\nWARNING: " << r.gross_validation;
  if (const std::string w = worseWarning(r); !w.empty()) comment << "\nWARNING: " << w;
  return comment.str();
}

/// The --json report.
ordered_json identifyJson(const IdentifyArgs& a, const IdentifyRun& r) {
  const calib::IdentifySummary& s = r.s;
  const bool has_val = r.hasValidation();
  ordered_json j;
  j["robot"] = r.calibrated.nominal.name;
  j["data"] = a.data.size() == 1 ? ordered_json(a.data[0]) : ordered_json(a.data);
  j["validation_source"] = has_val ? ordered_json(r.validation_source) : ordered_json(nullptr);
  j["validation_station"] = has_val ? ordered_json(r.station_note.empty() ? "same as the fit" : r.station_note)
                                    : ordered_json(nullptr);
  j["orientation"] = r.orient;
  j["groups"] = r.opt.groups;
  j["fit"] = statsJson(s.fit);
  j["validation"] = has_val ? statsJson(r.val) : ordered_json(nullptr);
  j["nominal_validation"] = has_val ? statsJson(r.nom_val) : ordered_json(nullptr);
  if (!r.orientation_note.empty()) j["validation_orientation"] = r.orientation_note;
  ordered_json params = ordered_json::array();
  for (const auto& p : s.parameters)
    params.push_back({{"name", p.name}, {"group", p.group}, {"value", num(p.value)}, {"sigma", num(p.sigma)}, {"unit", p.unit}});
  j["parameters"] = params;
  ordered_json fixed = ordered_json::array();
  for (const auto& f : s.fixed) fixed.push_back({{"name", f.name}, {"reason", f.reason}});
  j["identifiability"] = {{"condition_number", num(s.condition_number)},
                          {"condition_number_all_candidates", num(s.condition_number_all)},
                          {"observability_index", num(s.observability_index)},
                          {"parameters_free", s.parameters_free},
                          {"equations", s.equations},
                          {"poses", s.poses},
                          {"distinct_configurations", s.configurations},
                          {"independent_equations", s.independent_equations},
                          {"fixed", fixed}};
  j["solver"] = {{"termination", s.termination},
                 {"iterations", s.iterations},
                 {"initial_cost", num(s.initial_cost)},
                 {"final_cost", num(s.final_cost)},
                 {"registration_rms_mm", num(s.registration_rms_mm)},
                 {"variance_factor", num(s.variance_factor)},
                 {"weighting", s.weighting},
                 {"position_std_mm", num(s.position_std_mm)},
                 {"orientation_std_deg", num(s.orientation_std_deg)},
                 {"model_error_mm", num(s.model_error_mm)},
                 {"model_error_deg", num(s.model_error_deg)}};
  j["downweighted_lines"] = s.downweighted_lines;
  ordered_json cov = ordered_json::array();
  for (int jn = 0; jn < r.start.dof(); ++jn)
    cov.push_back({{"joint", jn + 1}, {"lower", num(s.coverage[static_cast<size_t>(jn)].lower)},
                   {"upper", num(s.coverage[static_cast<size_t>(jn)].upper)}, {"unit", r.unitOf(jn)}});
  j["fit_joint_ranges"] = cov;
  ordered_json stations = ordered_json::array();
  for (size_t k = 0; k < r.sets.size(); ++k) {
    const calib::XyzAbc station = calib::toXyzAbc(s.T_world_base_per_set[k]);
    stations.push_back({{"file", r.sets[k].file}, {"poses", r.sets[k].rows.size()},
                        {"T_world_base", {num(station.x_mm), num(station.y_mm), num(station.z_mm), num(station.a_deg), num(station.b_deg), num(station.c_deg)}}});
  }
  j["data_sets"] = stations;
  j["same_station"] = r.opt.same_station;
  ordered_json maps = ordered_json::array();
  for (const auto& mrep : s.joint_maps)
    maps.push_back({{"joint", mrep.joint}, {"lower", num(mrep.lower)}, {"upper", num(mrep.upper)},
                    {"knot", num(mrep.knot)}, {"coefficients", mrep.coefficients}, {"smoothing", num(mrep.smoothing)},
                    {"amplitude", num(mrep.amplitude)}, {"rms", num(mrep.rms)}, {"unit", mrep.unit}});
  j["joint_maps"] = maps;
  ordered_json cvj = ordered_json::array();
  for (const auto& c : s.joint_map_cv)
    cvj.push_back({{"knot", num(c.knot)}, {"smoothing", num(c.smoothing)}, {"cv_rms_mm", num(c.cv_rms_mm)}});
  ordered_json not_tried = ordered_json::array();
  for (double k : s.joint_map_cv_knots_not_tried) not_tried.push_back(num(k));
  j["joint_map_cv"] = {{"baseline_rms_mm", num(s.joint_map_cv_baseline_mm)}, {"candidates", cvj},
                       {"knots_not_tried", not_tried}};
  ordered_json sus = ordered_json::array();
  for (const auto& row : s.suspicious)
    sus.push_back({{"file", row.file}, {"line", row.line}, {"normalised", num(row.normalised)}, {"error_mm", num(row.error_mm)}});
  j["suspicious_rows"] = sus;
  if (has_val) {
    ordered_json vsus = ordered_json::array();
    for (const auto& row : r.val_suspicious)
      vsus.push_back({{"file", row.file}, {"line", row.line}, {"normalised", num(row.normalised)}, {"error_mm", num(row.error_mm)}});
    j["validation_suspicious_rows"] = vsus;
  }
  ordered_json excl = ordered_json::array();
  for (const auto& row : s.excluded)
    excl.push_back({{"file", row.file}, {"line", row.line}, {"error_mm", num(row.error_mm)}, {"median_mm", num(row.median_mm)}});
  j["excluded_rows"] = excl;  // gross rows left out of the fit
  j["warnings"] = s.warnings;
  if (!r.gross_validation.empty()) j["warnings"].push_back(r.gross_validation);
  if (const std::string w = worseWarning(r); !w.empty()) j["warnings"].push_back(w);
  if (has_val) {
    ordered_json out = ordered_json::array();
    for (int jn = 0; jn < r.start.dof(); ++jn) {
      const Outside& o = r.outside[static_cast<size_t>(jn)];
      if (o.count > 0)
        out.push_back({{"joint", jn + 1}, {"poses", o.count}, {"max_beyond", num(o.max)}, {"unit", r.unitOf(jn)},
                       {"first_lines", o.lines}});
    }
    j["validation_outside_fit_ranges"] = {{"poses", r.outside_rows}, {"joints", out}};
  }
  j["unused_columns"] = r.sets[0].unknown_columns;
  return j;
}

/// The steps: the start model, the data, the fit, the validation, the report, the files.
int runIdentify(const IdentifyArgs& a) {
  IdentifyRun r;
  r.start = startModel(a);
  readData(a, r);
  // the outputs' directories and the overwrite guard before the fit, not after it
  std::vector<std::string> inputs = a.data;
  for (const std::string* f : {&a.robot, &a.validate, &a.map, &a.validate_map}) inputs.push_back(*f);
  calib::refuseUnwritableOutputs({a.out, a.json}, inputs, "--out / --json");
  r.opt = identifyOptions(a);
  // the file's std columns win (--help): say so rather than drop the option without a word
  for (const calib::MeasurementSet& set : r.sets) {
    if (a.std_mm > 0 && set.has_std_position)
      std::fprintf(stderr, "accura: warning: --std-mm %g not used for %s: its std columns give each row's position std\n", a.std_mm,
                   set.file.c_str());
    if (a.std_deg > 0 && set.has_std_orientation)
      std::fprintf(stderr, "accura: warning: --std-deg %g not used for %s: its std columns give each row's orientation std\n", a.std_deg,
                   set.file.c_str());
    else if (a.std_deg > 0 && !set.has_orientation)
      std::fprintf(stderr, "accura: warning: --std-deg %g not used for %s: it has no orientation columns (positions only)\n", a.std_deg,
                   set.file.c_str());
  }
  r.calibrated = identifyFit(r, r.opt, &r.s);
  r.s.warnings.insert(r.s.warnings.begin(), r.data_warnings.begin(), r.data_warnings.end());
  for (const auto& d : r.sets) r.n_rows += d.rows.size();
  validate(a, r);
  for (const auto& d : r.sets) r.orient = r.orient && d.has_orientation;

  std::printf("accura identify: %s, %zu poses from %s (%s)\n", r.start.nominal.name.c_str(), r.n_rows, r.data_names.c_str(),
              r.orient ? "position and orientation" : "position only");
  // --quiet: the summary line, warnings, the validation and the file written (see --help)
  if (!a.quiet) printSetup(a, r);
  for (const auto& w : r.s.warnings) std::printf("WARNING: %s\n", w.c_str());
  if (a.quiet && !r.s.suspicious.empty())  // (listed in full without --quiet and in the JSON)
    std::printf("%zu suspicious row(s) (normalised residual above the chi quantile 0.9999), the first %s:%d: check them for glitches\n",
                r.s.suspicious.size(), r.s.suspicious.front().file.c_str(), r.s.suspicious.front().line);
  if (!a.quiet) printFit(r);
  printValidation(a, r);

  std::vector<calib::ParameterRecord> records;
  for (const auto& p : r.s.parameters) records.push_back({p.name, p.value, p.sigma, p.unit});
  // The model and the summary are one output set, written together or not at all; neither may
  // land on an input.
  std::vector<calib::OutputFile> outputs = {{a.out, calib::robotFileText(r.calibrated, records, modelComment(a, r))}};
  if (!a.json.empty()) outputs.push_back({a.json, calib::jsonText(identifyJson(a, r))});
  calib::refuseToOverwrite(outputs, inputs, "--out / --json");
  calib::writeFilesAtomically(outputs);
  std::printf("wrote calibrated model %s\n", a.out.c_str());
  return 0;
}

}  // namespace

void addIdentifyCommand(CLI::App& app) {
  auto id = std::make_shared<IdentifyArgs>();
  auto* cid = app.add_subcommand("identify", "identify the robot's parameters from measurements");
  cid->add_option("--robot", id->robot, "nominal or calibrated robot (file or bundled name)")->required();
  cid->add_option("--data", id->data,
                  "measurement CSV to fit; give it more than once for several data sets, each from its own tracker "
                  "station (6 parameters each) unless --same-station")
      ->required();
  cid->add_flag("--same-station", id->same_station, "the --data files were measured from one tracker station");
  addNumberOption(cid, "--map-smoothing", id->map_smoothing,
                  "joint_map smoothness (relative weight of the second differences; default: chosen by blocked "
                  "cross-validation on the fit data)",
                  NumberRange{0, 1e12, false, ""});
  cid->add_option("--validate", id->validate, "held-out measurement CSV (from the fit's station; another: --validate-station new)");
  cid->add_option("--map", id->map, "mapping file: how to read --data (and --validate) as exported by the instrument");
  cid->add_option("--validate-map", id->validate_map, "mapping file for --validate when it differs from --map");
  cid->add_option("--validate-station", id->validate_station,
                  "same: --validate was measured from the fit's station; new: re-register the station (6 "
                  "parameters) on it with the robot's parameters held fixed")
      ->capture_default_str();
  addNumberOption(cid, "--holdout", id->holdout,
                  "without --validate: fraction held out for validation (every k-th joint configuration with its repeats; every k-th pose when there are none)",
                  kHoldoutRange)
      ->capture_default_str();
  cid->add_option("--base", id->base, "nominal T_world_base x,y,z,A,B,C (mm, deg)");
  cid->add_option("--tool", id->tool, "nominal T_flange_tcp x,y,z[,A,B,C] (mm, deg)");
  cid->add_option("--params", id->params,
                  "parameter groups: geometric (default) = base,tool,offsets,lengths,angles; and the effect catalogue: "
                  "joint_compliance, gear_periodic, joint_scale, backlash, thermal, joint_map. Restrict to joints with "
                  ":j1+j2; joint_map takes a knot spacing with @, e.g. joint_map:j1+j2+j3@3deg (default: chosen by "
                  "blocked cross-validation)")
      ->capture_default_str();
  cid->add_option("--form", id->form, "auto (Hayati for parallel axes) or dh (force classic DH)")
      ->capture_default_str();
  cid->add_option("--loss", id->loss, "robust loss: none, huber, cauchy")->capture_default_str();
  addNumberOption(cid, "--loss-scale", id->loss_scale, "robust loss scale (residual sigmas)", NumberRange{0, 1000, true, "sigmas"})->capture_default_str();
  addNumberOption(cid, "--std-mm", id->std_mm, "position std (mm) when the data has no std columns", NumberRange{0, 1000, true, "mm"});
  addNumberOption(cid, "--std-deg", id->std_deg, "orientation std (deg) when the data has no std columns", NumberRange{0, 180, true, "deg"});
  cid->add_option("--out", id->out, "calibrated model file to write")->required();
  cid->add_option("--json", id->json, "summary JSON to write");
  auto* quiet = cid->add_flag("--quiet", id->quiet,
                               "print only what matters: the summary line, warnings (gross rows left out among them), how many "
                               "rows are suspicious, the validation (nominal and calibrated, and the poses outside the fit's "
                               "joint ranges) and the file written");
  cid->add_flag("--verbose", id->verbose, "also print the solver's own report (Ceres: termination, cost)")->excludes(quiet);
  cid->callback([=]() {
    id->holdout_given = cid->count("--holdout") > 0;
    id->validate_station_given = cid->count("--validate-station") > 0;
    id->loss_scale_given = cid->count("--loss-scale") > 0;
    exitCode() = runIdentify(*id);
  });
}

}  // namespace accura::cli
