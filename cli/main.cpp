// accura: command-line entry point. Subcommands are in commands.cpp.
#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>

#include "accura/calib/errors.h"
#include "commands.h"

int main(int argc, char** argv) {
  using namespace accura::cli;
  CLI::App app{"accura: identify a robot's real kinematics and make off-line programs land "
               "where the CAD model says"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "accura 0.1.0");

  FkArgs fk;
  auto* cfk = app.add_subcommand("fk", "print the tool pose at joint values (x,y,z mm; A,B,C deg)");
  cfk->add_option("--robot", fk.robot, "robot file or bundled robot name")->required();
  cfk->add_option("--q", fk.q, "joint values v1,...,vN (deg; mm for prismatic joints)")->required();
  cfk->add_option("--payload-kg", fk.payload_kg, "payload mass (kg), for compliance models");

  SimulateArgs sim;
  auto* csim = app.add_subcommand("simulate", "measurements of a perturbed robot, as a tracker sees it");
  csim->add_option("--robot", sim.robot, "nominal robot (file or bundled name)")->required();
  csim->add_option("--poses", sim.poses, "number of measured poses")->capture_default_str();
  csim->add_option("--seed", sim.seed, "random seed (errors and poses)")->capture_default_str();
  csim->add_option("--effects", sim.effects,
                   "errors of the real robot: geometric, joint_compliance, or none (the robot as given)")
      ->capture_default_str();
  csim->add_option("--noise-mm", sim.noise_mm, "position noise, 1 sigma per axis (mm)")->capture_default_str();
  csim->add_option("--noise-deg", sim.noise_deg, "orientation noise, 1 sigma per axis (deg)")->capture_default_str();
  csim->add_flag("--orientation", sim.orientation, "also measure the orientation (6D tracker)");
  csim->add_flag("--std", sim.write_std, "write std columns (the noise levels)");
  csim->add_option("--payloads", sim.payloads, "payload masses cycled over the poses (kg)")->capture_default_str();
  csim->add_option("--station", sim.station,
                   "T_world_base of the real robot, x,y,z,A,B,C (default: 3 m away, turned 30 deg)");
  csim->add_option("--tool", sim.tool, "the measured target on the flange, T_flange_tcp x,y,z[,A,B,C] (mm, deg)");
  csim->add_option("--error-scale", sim.error_scale, "scale of the random geometric errors")->capture_default_str();
  csim->add_option("--out", sim.out, "measurement CSV to write")->required();
  csim->add_option("--truth", sim.truth, "write the real robot as a calibrated model file");

  IdentifyArgs id;
  auto* cid = app.add_subcommand("identify", "identify the robot's parameters from measurements");
  cid->add_option("--robot", id.robot, "nominal or calibrated robot (file or bundled name)")->required();
  cid->add_option("--data", id.data, "measurement CSV to fit")->required();
  cid->add_option("--validate", id.validate, "held-out measurement CSV (same station)");
  cid->add_option("--holdout", id.holdout,
                  "without --validate: fraction of the poses held out for validation (every k-th)")
      ->capture_default_str();
  cid->add_option("--base", id.base, "nominal T_world_base x,y,z,A,B,C (mm, deg)");
  cid->add_option("--tool", id.tool, "nominal T_flange_tcp x,y,z[,A,B,C] (mm, deg)");
  cid->add_option("--params", id.params,
                  "parameter groups: geometric (default) = base,tool,offsets,lengths,angles; joint_compliance")
      ->capture_default_str();
  cid->add_option("--form", id.form, "auto (Hayati for parallel axes) or dh (force classic DH)")
      ->capture_default_str();
  cid->add_option("--loss", id.loss, "robust loss: none, huber, cauchy")->capture_default_str();
  cid->add_option("--loss-scale", id.loss_scale, "robust loss scale (residual sigmas)")->capture_default_str();
  cid->add_option("--std-mm", id.std_mm, "position std (mm) when the data has no std columns");
  cid->add_option("--std-deg", id.std_deg, "orientation std (deg) when the data has no std columns");
  cid->add_option("--out", id.out, "calibrated model file to write")->required();
  cid->add_option("--json", id.json, "summary JSON to write");
  cid->add_flag("--quiet", id.quiet, "print only the summary line and the validation");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    if (cfk->parsed()) return runFk(fk);
    if (csim->parsed()) return runSimulate(sim);
    if (cid->parsed()) return runIdentify(id);
  } catch (const accura::InputError& e) {
    std::cerr << "accura: error: " << e.what() << "\n";
    return 1;
  } catch (const accura::ArgumentError& e) {
    std::cerr << "accura: error: " << e.what() << "\n";
    return 1;
  } catch (const accura::NumericalError& e) {
    std::cerr << "accura: numerical error: " << e.what() << "\n";
    return 3;
  } catch (const std::exception& e) {
    std::cerr << "accura: internal error: " << e.what() << "\n";
    return 4;
  }
  return 0;
}
