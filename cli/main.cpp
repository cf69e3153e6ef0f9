// accura: command-line entry point. Subcommands are in cmd_*.cpp (declared in commands.h).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <vector>
#include <exception>
#include <iostream>
#include <string>

#include "accura/calib/errors.h"
#include "cli_util.h"
#include "commands.h"

namespace {

// Edit distance of two option names (short: a few dozen characters), for "did you mean".
size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diag = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

// CLI11 says "The following arguments were not expected: 5 --payload" for an unknown option:
// name the first unknown option of the command instead, with the nearest known one.
std::string unknownOptionMessage(const CLI::App& command, int argc, char** argv) {
  for (int k = 2; k < argc; ++k) {
    std::string arg = argv[k];
    if (arg.size() < 2 || arg[0] != '-' || arg == "--") continue;
    if (arg[1] != '-' && std::isdigit(static_cast<unsigned char>(arg[1]))) continue;  // a negative number
    arg = arg.substr(0, arg.find('='));
    if (command.get_option_no_throw(arg) != nullptr) continue;
    std::string best;
    size_t best_d = 3;  // suggest only what is close: 2 edits at most, or a prefix either way
    for (const CLI::Option* o : command.get_options()) {
      for (const std::string& n : o->get_lnames()) {
        const std::string known = "--" + n;
        size_t d = editDistance(arg, known);
        if (known.rfind(arg, 0) == 0 || arg.rfind(known, 0) == 0) d = std::min<size_t>(d, 1);
        if (d < best_d) best_d = d, best = known;
      }
    }
    return "expected an option of accura " + command.get_name() + ", found '" + arg + "'" +
           (best.empty() ? std::string() : " (did you mean " + best + "?)");
  }
  return "";
}

// CLI11 says "--tol: At Most 1 required but received 2" for an option given twice and "--tol: 1
// required NUMBER:in [0.001, 100] (mm) missing" for one given without its value: say what was
// expected and what was found, as every other error does. Any other message is kept.
std::string argumentMismatchMessage(const std::string& what) {
  const size_t colon = what.find(": ");
  if (colon == std::string::npos) return what;
  const std::string name = what.substr(0, colon), rest = what.substr(colon + 2);
  const std::string at_most = "At Most 1 required but received ";
  if (rest.rfind(at_most, 0) == 0)
    return name + ": expected once, found it given " + rest.substr(at_most.size()) + " times (give it once)";
  const std::string one = "1 required ", missing = " missing";
  if (rest.rfind(one, 0) == 0 && rest.size() > one.size() + missing.size() &&
      rest.compare(rest.size() - missing.size(), missing.size(), missing) == 0)
    return name + ": expected a value (" + rest.substr(one.size(), rest.size() - one.size() - missing.size()) + "), found none";
  return what;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace accura::cli;
  CLI::App app{"accura: identify a robot's real kinematics and make off-line programs land "
               "where the CAD model says"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "accura " ACCURA_VERSION_STRING);

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

  // an unknown command is named as such (CLI11 would only say that a subcommand is required);
  // `accura help` is `accura --help`, `accura help CMD` is `accura CMD --help`
  const bool asks_help = argc > 1 && std::string(argv[1]) == "help";
  if (asks_help && (argc > 3 || (argc == 3 && argv[2][0] == '-'))) {
    std::cerr << "accura: error: expected 'accura help' or 'accura help COMMAND', found '" << argv[argc - 1]
              << "' after help (see accura --help)\n";
    return 1;
  }
  const int command_arg = asks_help ? 2 : 1;
  if (argc > command_arg && argv[command_arg][0] != '-') {
    bool known = false;
    std::string names;
    for (const CLI::App* sub : app.get_subcommands({})) {
      known = known || sub->get_name() == argv[command_arg];
      names += (names.empty() ? "" : ", ") + sub->get_name();
    }
    if (!known) {
      std::cerr << "accura: error: expected a command (" << names << (asks_help ? "" : "; or help") << "), found '"
                << argv[command_arg] << "' (see accura --help)\n";
      return 1;
    }
  }
  std::string help_flag = "--help";
  std::vector<char*> help_argv;
  if (asks_help) {  // parsed as the --help it stands for, so that both print the same text
    help_argv = {argv[0]};
    if (argc == 3) help_argv.push_back(argv[2]);
    help_argv.push_back(help_flag.data());
    argc = static_cast<int>(help_argv.size());
    argv = help_argv.data();
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
    } catch (const CLI::ExtrasError& e) {
      const CLI::App* command = nullptr;
      for (const CLI::App* sub : app.get_subcommands({}))
        if (argc > 1 && sub->get_name() == argv[1]) command = sub;
      const std::string what = command ? unknownOptionMessage(*command, argc, argv) : std::string();
      // no unknown option: a stray value (CLI11 lists it after the colon)
      std::string stray = e.what();
      stray = stray.substr(stray.find(':') == std::string::npos ? 0 : stray.find(':') + 2);
      std::cerr << "accura: error: "
                << (what.empty() ? "expected options of accura" + (command ? " " + command->get_name() : std::string()) +
                                       " and their values, found the stray argument(s) " + stray
                                 : what)
                << " (see accura "
                << (command ? command->get_name() + " " : std::string()) << "--help)\n";
      return 1;
    } catch (const CLI::ParseError& e) {
      // bad usage: exit status 1 like any other bad input, with a pointer to the help
      // the help to see is the command's (argv[1] is a known command here), else accura's
      const std::string help = argc > 1 && argv[1][0] != '-' ? std::string("accura ") + argv[1] + " --help"
                                                             : std::string("accura --help");
      const std::string what = dynamic_cast<const CLI::ArgumentMismatch*>(&e) ? argumentMismatchMessage(e.what()) : e.what();
      std::cerr << "accura: error: " << what << " (see " << help << ")\n";
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
