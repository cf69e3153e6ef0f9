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

  addFkCommand(app);
  addSimulateCommand(app);
  addIdentifyCommand(app);
  addConvertCommand(app);
  addCompensateCommand(app);
  addBatchCommand(app);
  addDiagnoseCommand(app);
  addSelfcheckCommand(app);
  addCheckCommand(app);

  try {
    try {
      app.parse(argc, argv);  // runs the chosen subcommand's callback
    } catch (const CLI::ParseError& e) {
      return app.exit(e);
    }
    return exitCode();
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
}
