#include "commands.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/identify.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/measurements.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"

namespace accura::cli {
namespace {

using nlohmann::ordered_json;

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

// JSON number or null for NaN / inf (JSON has neither).
ordered_json num(double v) { return std::isfinite(v) ? ordered_json(v) : ordered_json(nullptr); }

ordered_json statsJson(const ErrorStats& s) {
  ordered_json j;
  j["n"] = s.n;
  j["rms_mm"] = num(s.rms_mm);
  j["mean_mm"] = num(s.mean_mm);
  j["max_mm"] = num(s.max_mm);
  j["p95_mm"] = num(s.p95_mm);
  if (s.has_orientation) {
    j["rot_rms_deg"] = num(s.rot_rms_deg);
    j["rot_mean_deg"] = num(s.rot_mean_deg);
    j["rot_max_deg"] = num(s.rot_max_deg);
    j["rot_p95_deg"] = num(s.rot_p95_deg);
  }
  return j;
}

void writeTextAtomically(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) throw InputError(tmp, 0, 0, "cannot write file");
    f << text;
    f.flush();
    if (!f) {
      std::remove(tmp.c_str());
      throw InputError(tmp, 0, 0, "write failed");
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw InputError(path, 0, 0, "cannot rename temporary file into place");
  }
}

RobotModel loadRobot(const std::string& name) { return readRobotFile(resolveRobotPath(name)); }

void warnUnknownColumns(const MeasurementSet& set) {
  if (set.unknown_columns.empty()) return;
  std::string list;
  for (const auto& c : set.unknown_columns) list += (list.empty() ? "" : ", ") + c;
  std::cerr << "accura: warning: " << set.file << ": columns not used by accura: " << list << "\n";
}

void printStatsRow(const std::string& label, const ErrorStats& s) {
  std::printf("  %-12s %9.4f %9.4f %9.4f %9.4f", label.c_str(), s.rms_mm, s.mean_mm, s.p95_mm, s.max_mm);
  if (s.has_orientation)
    std::printf("   %8.5f %8.5f %8.5f %8.5f", s.rot_rms_deg, s.rot_mean_deg, s.rot_p95_deg, s.rot_max_deg);
  std::printf("\n");
}

}  // namespace

std::vector<std::string> splitList(const std::string& text, const std::string& what) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    item = trim(item);
    if (item.empty()) throw InputError(what + ": expected a comma-separated list, found an empty item in '" + text + "'");
    out.push_back(item);
  }
  if (out.empty()) throw InputError(what + ": expected a comma-separated list, found nothing");
  return out;
}

std::vector<double> parseNumbers(const std::string& text, const std::string& what) {
  std::vector<double> v;
  for (const auto& item : splitList(text, what)) {
    char* end = nullptr;
    const double x = std::strtod(item.c_str(), &end);
    if (end == item.c_str() || *end != '\0' || !std::isfinite(x))
      throw InputError(what + ": expected a number, found '" + item + "'");
    v.push_back(x);
  }
  return v;
}

int runFk(const FkArgs& a) {
  const RobotModel model = loadRobot(a.robot);
  const std::vector<double> q = parseNumbers(a.q, "--q");
  if (static_cast<int>(q.size()) != model.dof())
    throw InputError("--q: expected " + std::to_string(model.dof()) + " joint values for " +
                     model.nominal.name + ", found " + std::to_string(q.size()));
  Eigen::VectorXd qv = Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size()));
  for (int i = 0; i < model.dof(); ++i) {
    const JointSpec& j = model.nominal.joints[i];
    if (qv[i] < j.lower || qv[i] > j.upper)
      throw InputError("--q: joint " + std::to_string(i + 1) + " (" + j.name + "): expected a value within [" +
                       fmt("%g", j.lower) + ", " + fmt("%g", j.upper) + "], found " + fmt("%g", qv[i]));
  }
  if (!(a.payload_kg >= 0)) throw InputError("--payload-kg: expected a mass >= 0");
  KinematicWorkspace ws;
  PoseContext ctx;
  ctx.payload_kg = a.payload_kg;
  const XyzAbc p = toXyzAbc(forwardKinematics(model, qv, ctx, ws));
  std::printf("x=%.4f y=%.4f z=%.4f A=%.5f B=%.5f C=%.5f\n", p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg);
  return 0;
}

int runSimulate(const SimulateArgs& a) {
  const RobotModel nominal = loadRobot(a.robot);
  SimulateOptions o;
  o.poses = a.poses;
  o.seed = a.seed;
  o.effects = splitList(a.effects, "--effects");
  o.noise_mm = a.noise_mm;
  o.noise_deg = a.noise_deg;
  o.orientation = a.orientation;
  o.write_std = a.write_std;
  o.payloads_kg = parseNumbers(a.payloads, "--payloads");
  o.error_scale = a.error_scale;
  const bool none = o.effects.size() == 1 && o.effects[0] == "none";
  if (!a.station.empty()) {
    o.station = parseXyzAbc(a.station, "--station");
  } else {
    o.set_station = !none;
  }
  if (!a.tool.empty()) {
    o.tool = parseXyzAbc(a.tool, "--tool");
    o.set_tool = true;
  }
  std::string why;
  if (!o.IsValid(&why)) throw InputError("simulate: " + why);
  const RobotModel truth = perturbModel(nominal, o);
  const MeasurementSet set = simulateMeasurements(truth, o);
  std::vector<std::string> comments = {
      "accura simulate: " + nominal.nominal.name + ", " + std::to_string(o.poses) + " poses, seed " +
          std::to_string(o.seed) + ", effects " + a.effects,
      "noise " + fmt("%g", o.noise_mm) + " mm" + (o.orientation ? ", " + fmt("%g", o.noise_deg) + " deg" : std::string()) +
          " (1 sigma per axis); payloads " + a.payloads + " kg"};
  writeMeasurementsCsv(a.out, set, truth.dof(), comments);
  if (!a.truth.empty()) {
    writeRobotFile(a.truth, truth, {}, "accura simulate: the real robot behind " + a.out + " (seed " + std::to_string(o.seed) + ")");
  }
  std::printf("wrote %d simulated poses of %s to %s%s\n", o.poses, nominal.nominal.name.c_str(), a.out.c_str(),
              a.truth.empty() ? "" : (" and the real robot to " + a.truth).c_str());
  return 0;
}

int runIdentify(const IdentifyArgs& a) {
  RobotModel start = loadRobot(a.robot);
  if (a.form == "dh") {
    if (start.forms != chooseLinkForms(start.nominal, FormPolicy::kDHOnly)) {
      const Deviations dev = start.deviations;
      start = RobotModel::fromDefinition(start.nominal, FormPolicy::kDHOnly);
      start.deviations = dev;
      for (auto& l : start.deviations.links) l.dbeta_rad = 0;  // no beta in DH
    }
  } else if (a.form != "auto") {
    throw InputError("--form: expected 'auto' or 'dh', found '" + a.form + "'");
  }
  if (!a.base.empty()) start.nominal.T_world_base = toIsometry(parseXyzAbc(a.base, "--base"));
  if (!a.tool.empty()) start.nominal.T_flange_tcp = toIsometry(parseXyzAbc(a.tool, "--tool"));

  MeasurementSet data = readMeasurementsCsv(a.data, start.nominal);
  warnUnknownColumns(data);
  MeasurementSet validation;
  std::string validation_source;
  if (!a.validate.empty()) {
    validation = readMeasurementsCsv(a.validate, start.nominal);
    warnUnknownColumns(validation);
    validation_source = a.validate;
  } else {
    if (!(a.holdout >= 0 && a.holdout < 0.9))
      throw InputError("--holdout: expected a fraction in [0, 0.9), found " + fmt("%g", a.holdout));
    if (a.holdout > 0) {
      const int every = std::max(2, static_cast<int>(std::lround(1.0 / a.holdout)));
      MeasurementSet fit = data;
      fit.rows.clear();
      validation = data;
      validation.rows.clear();
      for (size_t i = 0; i < data.rows.size(); ++i)
        (i % every == static_cast<size_t>(every - 1) ? validation : fit).rows.push_back(data.rows[i]);
      data = fit;
      validation_source = "every " + std::to_string(every) + "th pose of " + a.data + " (held out)";
    }
  }

  IdentifyOptions opt;
  opt.groups = splitList(a.params, "--params");
  opt.loss = a.loss;
  opt.loss_scale = a.loss_scale;
  if (a.std_mm > 0) opt.position_std_mm = a.std_mm;
  if (a.std_deg > 0) opt.orientation_std_deg = a.std_deg;
  std::string why;
  if (!opt.IsValid(&why)) throw InputError("--params/--loss: " + why);

  IdentifySummary s;
  const RobotModel calibrated = identify(start, data, opt, &s);

  // Nominal model with only the measurement frame and the tool registered, for comparison.
  IdentifyOptions nominal_opt = opt;
  nominal_opt.groups = {"base", "tool"};
  nominal_opt.loss = "none";
  IdentifySummary ns;
  const RobotModel nominal_registered = identify(start, data, nominal_opt, &ns);

  const bool has_val = !validation.rows.empty();
  ErrorStats val, nom_val;
  if (has_val) {
    val = evaluate(calibrated, validation);
    nom_val = evaluate(nominal_registered, validation);
  }

  // Report
  const bool orient = data.has_orientation;
  std::printf("accura identify: %s, %zu poses from %s (%s)\n", start.nominal.name.c_str(), data.rows.size(),
              a.data.c_str(), orient ? "position and orientation" : "position only");
  std::printf("link forms:");
  for (int i = 0; i < start.dof(); ++i) std::printf(" j%d=%s", i + 1, start.forms[i] == LinkForm::kHayati ? "Hayati" : "DH");
  std::printf("\n");
  std::printf("registration: measurement frame in closed form, position RMS %.3f mm after registration\n",
              s.registration_rms_mm);
  std::printf("identifiability: %d parameters identified from %d equations; condition number %.4g "
              "(all %zu candidates: %s); observability index O1 %.4g\n",
              s.parameters_free, s.equations, s.condition_number, s.fixed.size() + s.parameters_free,
              std::isfinite(s.condition_number_all) ? fmt("%.4g", s.condition_number_all).c_str() : "inf (rank deficient)",
              s.observability_index);
  for (const auto& f : s.fixed) std::printf("  fixed %-16s %s\n", f.name.c_str(), f.reason.c_str());
  std::printf("weighting: %s", s.weighting.c_str());
  if (std::isfinite(s.position_std_mm)) std::printf(" [position std %.4g mm]", s.position_std_mm);
  if (std::isfinite(s.orientation_std_deg)) std::printf(" [orientation std %.4g deg]", s.orientation_std_deg);
  std::printf("; variance factor %.3f\n", s.variance_factor);
  std::printf("solver: %s\n", s.BriefReport().c_str());
  if (!s.downweighted_lines.empty()) {
    std::printf("robust loss down-weighted %zu rows, lines:", s.downweighted_lines.size());
    for (int l : s.downweighted_lines) std::printf(" %d", l);
    std::printf("\n");
  }
  if (!a.quiet) {
    std::printf("parameters (deviation from nominal, 1 sigma):\n");
    for (const auto& p : s.parameters)
      std::printf("  %-16s %14.6f +- %-12.6f %s\n", p.name.c_str(), p.value, p.sigma, p.unit.c_str());
  }
  std::printf("accuracy (position mm: RMS mean p95 max%s):\n", orient ? "; orientation deg: RMS mean p95 max" : "");
  printStatsRow("fit", s.fit);
  if (has_val) {
    std::printf("validation on %s, %d poses:\n", validation_source.c_str(), val.n);
    printStatsRow("nominal", nom_val);
    printStatsRow("calibrated", val);
    if (val.rms_mm > 0)
      std::printf("  position RMS improved %.1f-fold (%.4f -> %.4f mm)\n", nom_val.rms_mm / val.rms_mm,
                  nom_val.rms_mm, val.rms_mm);
  } else {
    std::printf("no validation data (--validate or --holdout): accuracy on held-out poses not known\n");
  }

  std::vector<ParameterRecord> records;
  for (const auto& p : s.parameters) records.push_back({p.name, p.value, p.sigma, p.unit});
  std::ostringstream comment;
  const XyzAbc b = toXyzAbc(calibrated.T_world_base()), t = toXyzAbc(calibrated.T_flange_tcp());
  comment << "accura identify: " << calibrated.nominal.name << " from " << a.data << " (" << data.rows.size()
          << " poses), groups " << a.params << "\n"
          << "calibrated T_world_base: " << fmt("%.4f", b.x_mm) << ", " << fmt("%.4f", b.y_mm) << ", "
          << fmt("%.4f", b.z_mm) << " mm, " << fmt("%.5f", b.a_deg) << ", " << fmt("%.5f", b.b_deg) << ", "
          << fmt("%.5f", b.c_deg) << " deg\n"
          << "calibrated T_flange_tcp: " << fmt("%.4f", t.x_mm) << ", " << fmt("%.4f", t.y_mm) << ", "
          << fmt("%.4f", t.z_mm) << " mm, " << fmt("%.5f", t.a_deg) << ", " << fmt("%.5f", t.b_deg) << ", "
          << fmt("%.5f", t.c_deg) << " deg\n"
          << "fit RMS " << fmt("%.4f", s.fit.rms_mm) << " mm"
          << (has_val ? ", validation RMS " + fmt("%.4f", val.rms_mm) + " mm (nominal " + fmt("%.4f", nom_val.rms_mm) + " mm)" : "");
  writeRobotFile(a.out, calibrated, records, comment.str());
  std::printf("wrote calibrated model %s\n", a.out.c_str());

  if (!a.json.empty()) {
    ordered_json j;
    j["robot"] = calibrated.nominal.name;
    j["data"] = a.data;
    j["validation_source"] = has_val ? ordered_json(validation_source) : ordered_json(nullptr);
    j["orientation"] = orient;
    j["groups"] = opt.groups;
    j["fit"] = statsJson(s.fit);
    j["validation"] = has_val ? statsJson(val) : ordered_json(nullptr);
    j["nominal_validation"] = has_val ? statsJson(nom_val) : ordered_json(nullptr);
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
                            {"fixed", fixed}};
    j["solver"] = {{"termination", s.termination},
                   {"iterations", s.iterations},
                   {"initial_cost", num(s.initial_cost)},
                   {"final_cost", num(s.final_cost)},
                   {"registration_rms_mm", num(s.registration_rms_mm)},
                   {"variance_factor", num(s.variance_factor)},
                   {"weighting", s.weighting},
                   {"position_std_mm", num(s.position_std_mm)},
                   {"orientation_std_deg", num(s.orientation_std_deg)}};
    j["downweighted_lines"] = s.downweighted_lines;
    j["unused_columns"] = data.unknown_columns;
    writeTextAtomically(a.json, j.dump(2) + "\n");
  }
  return 0;
}

}  // namespace accura::cli
