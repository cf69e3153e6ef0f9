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
calib::RobotModel loadRobot(const std::string& name_or_path);
/// The --chain ROOT:TIP option of every command with --robot (main.cpp adds it): which
/// serial chain of a URDF robot to use; empty: the default chain.
std::string& robotChainOption();
/// Reads a measurement file: accura's CSV format, or an instrument export through the mapping
/// file `map_path` when it is not empty (docs/measurement-mapping.md). Warns about unused columns.
calib::MeasurementSet readMeasurements(const std::string& path, const std::string& map_path, const calib::RobotDefinition& robot);
/// Prints a warning listing the columns of a measurement file accura does not use.
void warnUnknownColumns(const calib::MeasurementSet& set);
/// Adds the options that make a JobSettings (--robot, --tol, --base, --robroot, --payload-kg,
/// --temp-c, --program-tool, --program-base) to a command (accura compensate, batch, check);
/// the function returned reads them (InputError on a bad value). Defined in cmd_compensate.cpp.
std::function<postproc::JobSettings()> addJobOptions(CLI::App* c);
/// One row of an accuracy table: RMS mean p95 max (mm[, deg]).
void printStatsRow(const std::string& label, const calib::ErrorStats& s);

}  // namespace accura::cli
