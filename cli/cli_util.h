// Helpers shared by the subcommands (internal to the command-line tool).
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>

#include "accura/calib/identify.h"
#include "accura/calib/measurements.h"
#include "accura/calib/robot.h"
#include "accura/postproc/job.h"

namespace accura::cli {

/// printf-style formatting of one number.
std::string fmt(const char* format, double v);
/// JSON number, or null for NaN / inf (JSON has neither).
nlohmann::ordered_json num(double v);
/// {n, rms_mm, mean_mm, max_mm, p95_mm[, rot_*_deg]}
nlohmann::ordered_json statsJson(const calib::ErrorStats& s);
/// Reads --robot (a path or a bundled robot name; a .urdf through urdf.h, with --chain).
calib::RobotModel loadRobot(const std::string& name_or_path, const std::string& option = "--robot");
/// The --chain ROOT:TIP option of every command with --robot (main.cpp adds it): which
/// serial chain of a URDF robot to use; empty: the default chain.
std::string& robotChainOption();
/// Reads a measurement file: accura's CSV format, or an instrument export through the mapping
/// file `map_path` when it is not empty (docs/measurement-mapping.md). Warns about unused columns.
calib::MeasurementSet readMeasurements(const std::string& path, const std::string& map_path, const calib::RobotDefinition& robot);
/// Refuses (InputError) a measurement file given twice among `files` (the same file by any path:
/// std::filesystem::equivalent), naming both: its measurements would count twice. A byte copy
/// under another name is caught once read (calib::refuseSharedMeasurements).
void refuseRepeatedDataFiles(const std::vector<std::string>& files, const std::string& option = "--data");
/// Prints a warning listing the columns of a measurement file accura does not use, and one
/// listing the names its mapping leaves out (`ignore`) that the file does not have.
void warnUnknownColumns(const calib::MeasurementSet& set);
/// Adds the options that make a JobSettings (--robot, --controller, --tol, --base, --robroot,
/// --payload-kg, --temp-c, --program-tool, --program-base) to a command (accura compensate,
/// batch, check); the function returned reads them (calib::InputError on a bad value);
/// *model_files (when given) becomes a function returning --robot and --controller where they
/// name files (not bundled names): inputs no output may overwrite. Defined in cmd_compensate.cpp.
std::function<postproc::JobSettings()> addJobOptions(CLI::App* c, std::function<std::vector<std::string>()>* model_files = nullptr);
/// A numeric option's accepted values: a finite number within [lo, hi] (lo itself excluded
/// when lo_open), in `unit` (empty: dimensionless). Issue 14: NaN, infinities, 1e308,
/// denormals and absurd values are bad input, never a silent default.
struct NumberRange {
  double lo;
  double hi;
  bool lo_open;
  std::string unit;
};
/// A payload: 0 to 10 t (kg).
inline const NumberRange kPayloadRange{0, postproc::kMaxPayloadKg, false, "kg"};
/// The one validated numeric-option parser of every command: adds `name` to `c`, storing in
/// `value`; a value that is not a plain finite number within `r` is a usage error (exit 1)
/// naming the option and what was expected: "--std-mm: expected a number in (0, 1000] (mm),
/// found 'nan'". The default of `value` is kept when the option is not given.
CLI::Option* addNumberOption(CLI::App* c, const std::string& name, double& value, const std::string& help,
                             const NumberRange& r);
/// The same for counts and seeds: a plain decimal integer within [lo, hi] ("1e3", "0x10",
/// "2.5" and values beyond hi are rejected with the option named).
CLI::Option* addIntegerOption(CLI::App* c, const std::string& name, int& value, const std::string& help, long long lo,
                              long long hi);
CLI::Option* addIntegerOption(CLI::App* c, const std::string& name, unsigned long long& value, const std::string& help,
                              unsigned long long lo, unsigned long long hi);
/// --config of compensate, check, convert and batch: once per file, in the order given (a RAPID
/// task's modules; one $config.dat for KRL and XML, postproc::readProgram refuses a second).
CLI::Option* addConfigOption(CLI::App* c, std::vector<std::string>& paths, const std::string& help);
/// The text check behind addNumberOption, for numbers inside list options ("--payloads"):
/// the parsed value, or calib::InputError "<what>: expected a number in [lo, hi] (unit), found '<text>'".
double parseNumber(const std::string& text, const std::string& what, const NumberRange& r);
/// A pose option that must have six values x,y,z,A,B,C (mm, deg): --base, --robroot, --station,
/// --program-tool, --program-base. Three values are an error, not zero angles (issue 17).
calib::XyzAbc parsePose6(const std::string& text, const std::string& what);
/// A tool option x,y,z or x,y,z,A,B,C (mm, deg): a measured point on the flange has no orientation.
calib::XyzAbc parseTool(const std::string& text, const std::string& what);

/// One row of an accuracy table: RMS mean p95 max (mm[, deg]).
void printStatsRow(const std::string& label, const calib::ErrorStats& s);

}  // namespace accura::cli
