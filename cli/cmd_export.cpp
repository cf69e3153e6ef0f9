// accura export: a robot model (accura robot file, URDF, optionally with UR's factory
// calibration applied) written as URDF, accura robot file, UR DH deltas or ur_calibration YAML.
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/ur_calibration.h"
#include "accura/calib/urdf.h"
#include "cli_util.h"
#include "commands.h"

namespace accura::cli {
namespace {

struct ExportArgs {
  std::string robot;
  std::string format;
  std::string out;
  std::string ur_deltas;  // UR calibration.conf applied to --robot (a nominal UR)
  std::string ur_yaml;    // ur_calibration YAML applied to --robot
};

int runExport(const ExportArgs& a) {
  calib::RobotModel model = loadRobot(a.robot);
  if (!a.out.empty()) {
    // the robot file and the controller's calibration.conf / YAML are inputs, never overwritten
    // (an exported calibration.conf holds the deltas only, not the controller's checksums)
    std::vector<std::string> inputs = {a.ur_deltas, a.ur_yaml};
    try {
      inputs.push_back(calib::resolveRobotPath(a.robot));
    } catch (const calib::InputError&) {
    }
    calib::refuseToOverwrite({{a.out, ""}}, inputs, "--out");
  }
  if (!a.ur_deltas.empty() && !a.ur_yaml.empty())
    throw calib::InputError("--ur-deltas and --ur-yaml: expected one of them, found both");
  if (!a.ur_deltas.empty() || !a.ur_yaml.empty()) {
    if (model.dof() != 6)
      throw calib::InputError("--robot " + a.robot + ": UR's factory calibration is for the 6 joints of a UR arm, found " +
                              std::to_string(model.dof()) + " joints in '" + model.nominal.name +
                              "' (from a URDF: choose the arm's own chain with --chain ROOT:TIP, e.g. --chain base:tool0 on "
                              "ur_description's URDF)");
    for (const calib::ParamInfo& p : calib::parameterLayout(model))
      if (calib::getParameter(model.deviations, p) != 0.0)
        throw calib::InputError("--robot " + a.robot + ": UR's factory calibration applies to a nominal UR robot, found a "
                         "calibrated model (parameter " + p.name + " is not zero)");
    try {
      model = !a.ur_deltas.empty() ? calib::modelFromUrDeltas(model.nominal, calib::readUrCalibrationConf(a.ur_deltas, model.dof()))
                                   : calib::modelFromUrCalibrationYaml(model.nominal, a.ur_yaml);
    } catch (const calib::ArgumentError& e) {
      const std::string file = a.ur_deltas.empty() ? a.ur_yaml : a.ur_deltas, what = e.what();
      throw calib::InputError(what.rfind(file, 0) == 0 ? what : file + ": " + what);  // the file named once
    }
  }
  std::string text;
  std::vector<std::string> lost;
  if (a.format == "urdf") {
    calib::UrdfText u = calib::modelToUrdf(model);
    text = u.text;
    lost = u.not_represented;
  } else if (a.format == "ur-deltas") {
    const calib::UrDeltasFromModel d = calib::urDeltasFromModel(model);
    text = calib::formatUrCalibrationConf(d.deltas);
    lost = d.not_represented;
    std::cerr << "accura export: UR's formula with these deltas reproduces the model's flange chain to "
              << fmt("%.2g", d.max_difference_mm) << " mm\n";
    if (d.table_rewritten) {  // the model's nominal in UR's convention: say which table the deltas belong to
      std::string dd, aa, al;
      for (const calib::JointSpec& j : d.table.joints) {
        dd += (dd.empty() ? "" : ", ") + fmt("%.10g", j.d_mm / 1000.0);
        aa += (aa.empty() ? "" : ", ") + fmt("%.10g", j.a_mm / 1000.0);
        al += (al.empty() ? "" : ", ") + fmt("%.10g", j.alpha_deg);
      }
      std::cerr << "accura export: the deltas are relative to the nominal table of '" << model.nominal.name
                << "' in UR's convention: d = [" << dd << "] m, a = [" << aa << "] m, alpha = [" << al
                << "] deg; UR's controller adds them to its own table of the arm type, which must be the same\n";
    }
  } else if (a.format == "ur-yaml") {
    text = calib::formatUrCalibrationYaml(model, &lost);
  } else if (a.format == "robot") {
    if (a.out.empty()) throw calib::InputError("--format robot: expected --out FILE.xml");
    calib::writeRobotFile(a.out, model, {}, "Written by accura export from " + a.robot +
                                         (a.ur_deltas.empty() ? "" : " with UR deltas " + a.ur_deltas) +
                                         (a.ur_yaml.empty() ? "" : " with the UR YAML " + a.ur_yaml));
    return 0;
  } else {
    throw calib::InputError("--format: expected urdf, robot, ur-deltas or ur-yaml, found '" + a.format + "'");
  }
  for (const std::string& s : lost) std::cerr << "accura export: not represented: " << s << "\n";
  if (a.out.empty()) {
    std::cout << text;
  } else {
    calib::writeFileAtomically(a.out, text);
  }
  return 0;
}

}  // namespace

void addExportCommand(CLI::App& app) {
  auto args = std::make_shared<ExportArgs>();
  auto* c = app.add_subcommand("export", "write a robot model as URDF, accura robot file, UR DH deltas or UR YAML");
  c->add_option("--robot", args->robot, "robot file (.xml, .urdf) or bundled robot name")->required();
  c->add_option("--format", args->format, "urdf | robot | ur-deltas (calibration.conf) | ur-yaml (ur_calibration)")
      ->required();
  c->add_option("--out", args->out, "output file (default: standard output; required for --format robot)");
  c->add_option("--ur-deltas", args->ur_deltas,
                "apply a UR controller's calibration.conf ([mounting] delta_theta, delta_a, delta_d, delta_alpha) to "
                "the nominal UR --robot first");
  c->add_option("--ur-yaml", args->ur_yaml,
                "apply a ur_calibration YAML (kinematics: shoulder ... wrist_3) to the nominal UR --robot first");
  c->callback([=]() { exitCode() = runExport(*args); });
}

}  // namespace accura::cli
