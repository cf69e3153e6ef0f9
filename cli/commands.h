// accura command line. Each subcommand lives in its own file and is added to the app by an
// add...Command(app) function (listed in main.cpp). Its callback stores the process exit code
// in exitCode() and throws accura::calib::InputError / ArgumentError / NumericalError on bad input
// (main prints them and sets the exit code).
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace accura::cli {

struct FkArgs {
  std::string robot;
  std::string q;
  double payload_kg = 0;
  std::string json;
};

struct SimulateArgs {
  std::string robot;
  int poses = 300;
  unsigned long long seed = 1;
  std::string effects = "geometric";
  double noise_mm = 0.02;
  double noise_deg = 0.002;
  bool noise_deg_given = false;    ///< --noise-deg on the command line (it needs --orientation)
  bool orientation = false;
  bool write_std = false;
  std::string payloads = "0";
  std::string station;  // empty: default station (unless effects == none)
  std::string tool;     // empty: the robot's tool
  double error_scale = 1.0;
  bool error_scale_given = false;  ///< --error-scale on the command line (it scales the geometric errors)
  std::string out;
  std::string truth;
  std::string json;
};

struct IdentifyArgs {
  std::string robot;
  std::vector<std::string> data;  // one or more files (each its own station unless same_station)
  bool same_station = false;
  double map_smoothing = -1;      // <0: joint_map smoothness chosen by cross-validation
  std::string validate;
  std::string map;             // mapping file for --data (and --validate) exports
  std::string validate_map;    // mapping file for --validate when it differs
  std::string validate_station = "same";  // same | new: re-register the station on --validate
  bool validate_station_given = false;     ///< --validate-station on the command line
  double holdout = 0.2;
  bool holdout_given = false;  ///< --holdout on the command line (its default applies to one --data file)
  std::string base;
  std::string tool;
  std::string params = "geometric";
  std::string form = "auto";
  std::string loss = "none";
  double loss_scale = 3.0;
  bool loss_scale_given = false;  ///< --loss-scale on the command line (it scales a robust loss only)
  double std_mm = -1;   // <0: from the data or estimated
  double std_deg = -1;
  std::string out;
  std::string json;
  bool quiet = false;
  bool verbose = false;
};

/// The exit code a subcommand's callback leaves for main (0 unless set).
int& exitCode();

void addFkCommand(CLI::App& app);
void addSimulateCommand(CLI::App& app);
void addIdentifyCommand(CLI::App& app);
void addConvertCommand(CLI::App& app);
void addCompensateCommand(CLI::App& app);
void addBatchCommand(CLI::App& app);
void addDiagnoseCommand(CLI::App& app);
void addSelfcheckCommand(CLI::App& app);
void addCheckCommand(CLI::App& app);
void addExportCommand(CLI::App& app);  // cmd_export.cpp

/// Writes text through a temporary file renamed into place (InputError on failure).
void writeTextAtomically(const std::string& path, const std::string& text);

/// Splits "a,b,c" into trimmed items (empty items are an InputError naming `what`).
std::vector<std::string> splitList(const std::string& text, const std::string& what);
/// Parses a comma-separated list of numbers, each within `r` (InputError naming `what` and
/// what was expected on a bad item: cli_util.h parseNumber).
struct NumberRange;
std::vector<double> parseNumbers(const std::string& text, const std::string& what, const NumberRange& r);

}  // namespace accura::cli
