// accura: command-line entry point. Subcommands are in commands.cpp.
#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>
#include <string>

#include "accura/calib/errors.h"
#include "cli_util.h"
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
  addExportCommand(app);
  // --chain for URDF robots, wherever a robot is accepted (cli_util.h: loadRobot)
  for (CLI::App* sub : app.get_subcommands({}))
    if (sub->get_option_no_throw("--robot"))
      sub->add_option("--chain", robotChainOption(),
                      "URDF robots: the serial chain ROOT_LINK:TIP_LINK (default: root link to tool0, "
                      "else to the end of the only moving branch)");

  // an unknown command is named as such (CLI11 would only say that a subcommand is required)
  if (argc > 1 && argv[1][0] != '-') {
    bool known = false;
    std::string names;
    for (const CLI::App* sub : app.get_subcommands({})) {
      known = known || sub->get_name() == argv[1];
      names += (names.empty() ? "" : ", ") + sub->get_name();
    }
    if (!known) {
      std::cerr << "accura: error: expected a command (" << names << "), found '" << argv[1] << "'\n";
      return 1;
    }
  }
  try {
    try {
      app.parse(argc, argv);  // runs the chosen subcommand's callback
    } catch (const CLI::CallForHelp& e) {
      return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
      return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
      return app.exit(e);
    } catch (const CLI::ParseError& e) {
      // bad usage: exit status 1 like any other bad input, with a pointer to the help
      std::cerr << "accura: error: " << e.what() << " (see accura --help, accura <command> --help)\n";
      return 1;
    }
    return exitCode();
  } catch (const accura::calib::InputError& e) {
    std::cerr << "accura: error: " << e.what() << "\n";
    return 1;
  } catch (const accura::calib::ArgumentError& e) {
    std::cerr << "accura: error: " << e.what() << "\n";
    return 1;
  } catch (const accura::calib::NumericalError& e) {
    std::cerr << "accura: numerical error: " << e.what() << "\n";
    return 3;
  } catch (const std::exception& e) {
    std::cerr << "accura: internal error: " << e.what() << "\n";
    return 4;
  }
}
