// accura: measurement exports as instruments write them (laser tracker, CMM software),
// read through a mapping file that says which column is what and in which unit.
// Mapping format: docs/measurement-mapping.md.
#pragma once

#include <string>
#include <vector>

#include "accura/calib/measurements.h"
#include "accura/calib/robot.h"

namespace accura::calib {

/// How the columns of an export map onto a measurement (parsed mapping file).
struct MeasurementMapping {
  std::string file;                      ///< the mapping file (for messages)
  char delimiter = ',';                  ///< ',', ';', '\t'
  char decimal = '.';                    ///< '.' or ','
  std::vector<std::string> joints;       ///< one column per joint
  double joint_scale = 1.0;              ///< to deg (revolute): 1 for deg, 180/pi for rad
  double prismatic_scale = 1.0;          ///< to mm (prismatic joints): 1 for mm, 1000 for m
  std::vector<std::string> position;     ///< x, y, z columns
  double position_scale = 1.0;           ///< to mm
  std::string orientation_convention;    ///< "", quaternion_wxyz, quaternion_xyzw, kuka_abc,
                                         ///< euler_intrinsic_<axes>, euler_extrinsic_<axes>
  std::vector<std::string> orientation;  ///< 3 (angles) or 4 (quaternion) columns
  double angle_scale = 1.0;              ///< orientation angles to deg
  std::vector<std::string> position_std;     ///< 1 (isotropic) or 3 columns, position unit
  std::vector<std::string> orientation_std;  ///< 1 or 3 columns, orientation angle unit
  std::string weight, payload_kg, temperature_c, time_s;
  std::vector<std::string> directions;   ///< one column per joint (+1 / -1)
  std::vector<std::string> ignore;       ///< columns known to be of no use
  std::vector<std::pair<std::string, int>> key_lines;  ///< mapping file line of each key
};

/// Reads a mapping file. Throws InputError (mapping file:line:column) on a line that is not
/// `key = value` (a measurement file's header as the first such line: "this looks like a
/// measurement file, not a mapping"), an unknown key, a
/// missing required key, a bad unit or convention, a wrong number of columns, a column given
/// two roles (mapped twice, or mapped and ignored: at its second mention).
MeasurementMapping readMeasurementMapping(const std::string& path, const RobotDefinition& robot);

/// For the measurement readers: when `line`, the first line of a file given as measurements that
/// is neither blank nor a comment, is a mapping's `key = value` with one of the mapping's keys
/// (the mapping given as --data, the export as --map), what the file looks like and where each
/// belongs ("this looks like a mapping file, not a measurement file: ..."); else "".
std::string mappingFileNote(const std::string& line);

/// Reads an export through a mapping into accura's measurement form (mm, deg, world frame,
/// unit quaternions; orientation stds converted to stds about the world axes through the
/// Euler-angle Jacobian at each pose). Throws InputError with the export's file:line:column
/// for a missing column, a field that is not a number in the mapping's decimal format, a
/// row with the wrong number of fields, a joint outside its limits, a non-unit quaternion
/// (norm off by more than 1e-3), a non-positive std. Columns neither mapped nor ignored are
/// listed in MeasurementSet::unknown_columns; names under `ignore` the header does not have, in
/// MeasurementSet::ignored_absent_columns (not an error: nothing is lost).
MeasurementSet readMappedMeasurements(const std::string& path, const MeasurementMapping& mapping,
                                      const RobotDefinition& robot);

/// Rotation of a 3-angle convention ("kuka_abc", "euler_intrinsic_xyz", ...), angles in rad.
/// Throws ArgumentError on an unknown convention.
Eigen::Matrix3d rotationFromAngles(const std::string& convention, const Eigen::Vector3d& angles_rad);

}  // namespace accura::calib
