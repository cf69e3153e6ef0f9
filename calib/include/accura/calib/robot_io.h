// accura: robot files (robots/*.xml and calibrated models). Schema: docs/robot-format.md.
#pragma once

#include <string>
#include <vector>

#include "accura/calib/robot.h"

namespace accura::calib {

/// Extra information written with a calibrated model (one per identified parameter).
struct ParameterRecord {
  std::string name;   ///< parameter name as in parameterLayout()
  double value = 0;   ///< display units
  double sigma = 0;   ///< one standard deviation, display units (NaN when unknown)
  std::string unit;
};

/// Reads a robot file: a nominal robot, or a calibrated model (a robot file with a
/// <calibration> element); a path ending in .urdf, or a file whose <robot> holds <link>s and no
/// <joints> (a URDF under another name), is read by readUrdfRobot (urdf.h) with its default chain. Throws InputError "file:line:column: expected ..., found ..." (the column of
/// the offending attribute, element or value) on malformed XML, missing or unknown
/// elements/attributes, non-numeric or non-finite values, numbers beyond 1e6 in magnitude,
/// inconsistent limits, bad direction, unknown parameter names or units in <calibration>.
RobotModel readRobotFile(const std::string& path);

/// Writes the model (nominal data plus, when any deviation is non-zero or `records` is not
/// empty, a <calibration> element) through a temporary file renamed into place.
/// `comment` is written as an XML comment at the top.
void writeRobotFile(const std::string& path, const RobotModel& model,
                    const std::vector<ParameterRecord>& records = {},
                    const std::string& comment = "");

/// The text writeRobotFile writes (for a command that writes it together with other outputs:
/// writeFilesAtomically, all or nothing). Throws ArgumentError when the model is invalid.
std::string robotFileText(const RobotModel& model, const std::vector<ParameterRecord>& records = {},
                          const std::string& comment = "");

/// Resolves --robot: an existing file path, or a name found in the robots directory
/// (ACCURA_ROBOTS_DIR environment variable, else <prefix>/share/accura/robots of an installed
/// accura (cmake --install), else the source tree's robots/), with or
/// without ".xml". Throws InputError listing the names available when nothing matches.
std::string resolveRobotPath(const std::string& name_or_path);

/// Names of the robots in the robots directory (file names without .xml), sorted.
std::vector<std::string> bundledRobotNames();

}  // namespace accura::calib
