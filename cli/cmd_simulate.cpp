#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/json_text.h"
#include "accura/calib/file_io.h"
#include "accura/calib/identify.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/measurements.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"
#include "cli_util.h"
#include "commands.h"

namespace accura::cli {
namespace {
using nlohmann::ordered_json;

int runSimulate(const SimulateArgs& a) {
  const calib::RobotModel nominal = loadRobot(a.robot);
  calib::SimulateOptions o;
  o.poses = a.poses;
  o.seed = a.seed;
  o.effects = splitList(a.effects, "--effects");
  o.noise_mm = a.noise_mm;
  o.noise_deg = a.noise_deg;
  o.orientation = a.orientation;
  o.write_std = a.write_std;
  o.payloads_kg = parseNumbers(a.payloads, "--payloads", kPayloadRange);
  o.error_scale = a.error_scale;
  const bool none = o.effects.size() == 1 && o.effects[0] == "none";
  // options that would have no effect are refused, not dropped without a word
  if (a.noise_deg_given && !a.orientation)
    throw calib::InputError("--noise-deg: expected together with --orientation (the noise of the measured orientation), found it without");
  if (a.error_scale_given && std::find(o.effects.begin(), o.effects.end(), "geometric") == o.effects.end())
    throw calib::InputError("--error-scale: expected together with geometric in --effects (the scale of the random geometric errors), found --effects " +
                            a.effects);
  if (!a.station.empty()) {
    o.station = parsePose6(a.station, "--station");
  } else {
    o.set_station = !none;
  }
  if (!a.tool.empty()) {
    o.tool = parseTool(a.tool, "--tool");
    o.set_tool = true;
  }
  std::string why;
  if (!o.IsValid(&why)) throw calib::InputError("simulate: " + why);
  const calib::RobotModel truth = calib::perturbModel(nominal, o);
  const calib::MeasurementSet set = calib::simulateMeasurements(truth, o);
  std::vector<std::string> comments = {
      "accura simulate: " + nominal.nominal.name + ", " + std::to_string(o.poses) + " poses, seed " +
          std::to_string(o.seed) + ", effects " + a.effects,
      "noise " + fmt("%g", o.noise_mm) + " mm" + (o.orientation ? ", " + fmt("%g", o.noise_deg) + " deg" : std::string()) +
          " (1 sigma per axis); payloads " + a.payloads + " kg"};
  // The measurements and the real robot are one output set (all or nothing), never onto the input.
  std::vector<calib::OutputFile> outputs = {{a.out, calib::measurementsCsvText(set, truth.dof(), comments)}};
  if (!a.truth.empty())
    outputs.push_back({a.truth, calib::robotFileText(truth, {}, "accura simulate: the real robot behind " + a.out +
                                                                     " (seed " + std::to_string(o.seed) + ")")});
  if (!a.json.empty()) {
    ordered_json j;
    j["robot"] = nominal.nominal.name;
    j["poses"] = o.poses;
    j["seed"] = o.seed;
    j["effects"] = o.effects;
    j["noise_mm"] = o.noise_mm;
    j["noise_deg"] = o.orientation ? num(o.noise_deg) : ordered_json(nullptr);
    j["payloads_kg"] = o.payloads_kg;
    const calib::XyzAbc st = calib::toXyzAbc(truth.T_world_base());
    j["T_world_base"] = {num(st.x_mm), num(st.y_mm), num(st.z_mm), num(st.a_deg), num(st.b_deg), num(st.c_deg)};
    j["out"] = a.out;
    j["truth"] = a.truth.empty() ? ordered_json(nullptr) : ordered_json(a.truth);
    outputs.push_back({a.json, calib::jsonText(j)});
  }
  calib::refuseToOverwrite(outputs, {a.robot}, "--out / --truth / --json");
  calib::writeFilesAtomically(outputs);
  std::printf("wrote %d simulated poses of %s to %s%s\n", o.poses, nominal.nominal.name.c_str(), a.out.c_str(),
              a.truth.empty() ? "" : (" and the real robot to " + a.truth).c_str());
  return 0;
}

}  // namespace

void addSimulateCommand(CLI::App& app) {
  auto sim = std::make_shared<SimulateArgs>();
  auto* csim = app.add_subcommand("simulate", "measurements of a perturbed robot, as a tracker sees it");
  csim->add_option("--robot", sim->robot, "nominal robot (file or bundled name)")->required();
  addIntegerOption(csim, "--poses", sim->poses, "number of measured poses", 1, 1000000)->capture_default_str();
  addIntegerOption(csim, "--seed", sim->seed, "random seed (errors and poses)", 0ULL, ~0ULL)->capture_default_str();
  csim->add_option("--effects", sim->effects,
                   "errors of the real robot: geometric and effects of the catalogue (joint_compliance, gear_periodic, "
                   "joint_scale, backlash, thermal), or none (the robot as given)")
      ->capture_default_str();
  addNumberOption(csim, "--noise-mm", sim->noise_mm, "position noise, 1 sigma per axis (mm)", NumberRange{0, 100, false, "mm"})->capture_default_str();
  addNumberOption(csim, "--noise-deg", sim->noise_deg, "orientation noise, 1 sigma per axis (deg)", NumberRange{0, 10, false, "deg"})->capture_default_str();
  csim->add_flag("--orientation", sim->orientation, "also measure the orientation (6D tracker)");
  csim->add_flag("--std", sim->write_std, "write std columns (the noise levels)");
  csim->add_option("--payloads", sim->payloads, "payload masses cycled over the poses (kg)")->capture_default_str();
  csim->add_option("--station", sim->station,
                   "T_world_base of the real robot, x,y,z,A,B,C (default: 3 m away, turned 30 deg)");
  csim->add_option("--tool", sim->tool, "the measured target on the flange, T_flange_tcp x,y,z[,A,B,C] (mm, deg)");
  addNumberOption(csim, "--error-scale", sim->error_scale, "scale of the random geometric errors", NumberRange{0, 1000, false, ""})->capture_default_str();
  csim->add_option("--out", sim->out, "measurement CSV to write")->required();
  csim->add_option("--truth", sim->truth, "write the real robot as a calibrated model file");
  csim->add_option("--json", sim->json, "also write what was simulated as JSON (robot, poses, seed, effects, station)");
  csim->callback([=]() {
    sim->noise_deg_given = csim->count("--noise-deg") > 0;
    sim->error_scale_given = csim->count("--error-scale") > 0;
    exitCode() = runSimulate(*sim);
  });
}

}  // namespace accura::cli
