// accura: measured poses (laser tracker, CMM) read from CSV. Format: docs/measurement-format.md.
#pragma once

#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <limits>
#include <string>
#include <vector>

#include "accura/calib/kinematics.h"
#include "accura/calib/robot.h"

namespace accura::calib {

/// One measured pose.
struct Measurement {
  int line = 0;                  ///< 1-based line in the source file
  Eigen::VectorXd q;             ///< joint values: deg (revolute) or mm (prismatic)
  Eigen::Vector3d p_world_mm = Eigen::Vector3d::Zero();  ///< measured tool point, world
  bool has_orientation = false;
  Eigen::Quaterniond R_world_tcp = Eigen::Quaterniond::Identity();  ///< normalised
  /// One standard deviation per world axis; NaN where the file gives none.
  Eigen::Vector3d std_mm = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::Vector3d std_rot_deg = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  double weight = 1.0;           ///< relative weight (> 0); 1 when the file has none
  PoseContext context;           ///< payload_kg (0 when the file has no payload column)
  double temp_c = std::numeric_limits<double>::quiet_NaN();   ///< NaN when absent
  double time_s = std::numeric_limits<double>::quiet_NaN();   ///< NaN when absent
  std::vector<int> dir;          ///< +1/-1 per joint; empty when absent
};

/// A whole file of measurements and what its header held.
struct MeasurementSet {
  std::string file;
  std::vector<Measurement> rows;
  bool has_orientation = false;
  bool has_std_position = false;
  bool has_std_orientation = false;
  bool has_weight = false;
  bool has_payload = false;
  bool has_temperature = false;
  bool has_direction = false;
  bool has_time = false;
  std::vector<std::string> unknown_columns;  ///< header names accura does not use, in order
  /// Names a measurement mapping lists under `ignore` that the header does not have (read with
  /// readMappedMeasurements; nothing is lost, the caller says it).
  std::vector<std::string> ignored_absent_columns;
  /// Where the file's units are stated, for a message that doubts them: empty for accura's CSV
  /// (mm and deg by its format); for an export read through a mapping, its unit keys with their
  /// places ("joint_unit = rad (export.map:5), position_unit = mm (export.map:7)"), the place the
  /// user can fix them.
  std::string units_stated;
  /// The same, key by key, for a message that names the one to change: {"position_unit", "m",
  /// "export.map:7"}; empty for accura's CSV (mm and deg).
  struct StatedUnit {
    std::string key, unit, place;
  };
  std::vector<StatedUnit> units;
};

/// The kinds of measured values whose plausible ranges both readers (the CSV, and an
/// instrument's export read through a mapping file) enforce.
enum class MeasuredValue { kPositionMm, kAngleDeg, kStd, kWeight, kPayloadKg, kTemperatureC, kTimeS };

/// Empty when `v` is a plausible value of `kind`, else what was expected ("a position within
/// +-1e+07 mm"): positions within +-1e7 mm, angles within +-1e4 deg, standard deviations
/// (mm or deg) from 1e-6 to 1e6, weights from 1e-12 to 1e12, payloads from 0 to 1e5 kg,
/// temperatures from -273.15 to 1e4 deg C, times within +-1e12 s. Beyond them a value is a
/// corrupted file, not a measurement (a denormal std would make its weight infinite).
std::string implausibleMeasuredValue(MeasuredValue kind, double v);

/// Why the text of a measurement file (or a mapping) cannot be split into its lines as written,
/// as "expected ..., found ..." with the 1-based `line` where it shows (the file as a whole: 1);
/// empty when it can. Both readers refuse such a file as a whole with it, before reading any
/// line: UTF-16 text (a byte-order mark FF FE or FE FF; a NUL byte as the first or second byte:
/// UTF-16 without the mark, or a binary file), and a CR that ends a line without an LF (the line
/// ends of a classic Mac OS export), which would make the whole file one line: a header without
/// rows. A CR inside a '#' comment line of a file with LF line ends is passed over (a pasted note;
/// the comment is not read), as is a CR that ends the file. `content`: the file's bytes. Never
/// throws but std::bad_alloc.
std::string unsplittableText(const std::string& content, int* line);

/// The error both readers give for a row that names the header's columns again (two exports
/// joined into one file), the header being on line `header_line`. Never throws but
/// std::bad_alloc.
std::string headerRowAgainMessage(int header_line);

/// A measured joint value this far beyond a joint limit (deg; mm for a prismatic joint) is
/// still read: a limit from a URDF in radians is rounded (2.87979 rad is 164.99981 deg, and a
/// robot measured at its controller's limit of 165 deg is right).
constexpr double kJointLimitReadSlack = 0.01;

/// Whether joint value `v` (deg / mm) is within the joint's limits with kJointLimitReadSlack:
/// the one test of the measurement readers and of the commands that take joint values.
inline bool withinJointLimits(const JointSpec& joint, double v) {
  return v >= joint.lower - kJointLimitReadSlack && v <= joint.upper + kJointLimitReadSlack;
}

/// For a revolute joint with the limits -360..360 deg (what a URDF's continuous joint, which has
/// none, is given) and a value beyond them: "; ..." saying so and the value within one turn that
/// is the same pose ("539 deg is the pose of 179 deg"); empty otherwise.
std::string jointTurnNote(const JointSpec& joint, double v);

/// Reads a measurement CSV for `robot` (its dof and joint limits, with kJointLimitReadSlack,
/// are checked).
/// Throws InputError "FILE:LINE:COLUMN: expected ..., found ..." on: unreadable file, missing
/// or duplicate column, incomplete column group (qw without qx, std_x without std_y, ...),
/// a q column beyond the robot's joints, wrong field count, a field that is not a finite
/// number, a joint value outside its limits, dir not +1/-1, weight or std <= 0, a quaternion
/// whose norm is not 1 within 1e-3, and a file with no data row.
MeasurementSet readMeasurementsCsv(const std::string& path, const RobotDefinition& robot);

/// Two rows are one joint configuration measured again (a repeat) when every joint agrees within
/// this (deg, or mm for a prismatic joint) and payload and directions are the same: the
/// tolerance of diagnose's repeatability (DiagnoseOptions::repeat_tol) and of identify's count
/// of distinct configurations. 0.01 deg is a controller's repeat of a taught pose (encoder
/// resolution), far below the spacing of the poses of a calibration campaign.
constexpr double kRepeatTolerance = 0.01;

/// Repeated joint configurations of `set`: rows whose every joint agrees within `tol` (deg or
/// mm) with the same payload and directions, chained (union-find over the pairs). Returns the
/// groups of row indices (ascending within a group, groups ordered by their first row; a row
/// measured once is a group of one), and every pair (i < k) when `pairs` is given. With
/// `set_of_row`, only rows of the same data set are repeats.
std::vector<std::vector<int>> repeatedConfigurations(const MeasurementSet& set, double tol = kRepeatTolerance,
                                                     std::vector<std::pair<int, int>>* pairs = nullptr,
                                                     const std::vector<int>* set_of_row = nullptr);

/// A row that repeats an earlier row of its data set exactly (duplicatedRows()).
struct DuplicatedRow {
  int index = 0, line = 0;                  ///< the row (0-based, in the set as given) and its line
  int same_as_index = 0, same_as_line = 0;  ///< the earlier row it repeats
};

/// The rows of `set` that repeat an earlier row exactly: the same joint configuration
/// (repeatedConfigurations() with `tol`: every joint within tol, the same payload and
/// directions) and every measured value equal to the last bit (the position, and the
/// orientation when the rows have one). Such a row is the same measurement written twice (an
/// export that repeated it), not a second measurement of the configuration: it carries no new
/// information, and counted again it counts as independent evidence (the parameters' sigmas too
/// small, a repeatability of 0, spectral peaks and tests too significant). In row order, each
/// against the first row it equals.
std::vector<DuplicatedRow> duplicatedRows(const MeasurementSet& set, double tol = kRepeatTolerance);

/// Removes duplicatedRows() from `set`, so that each measurement counts once, and returns them.
std::vector<DuplicatedRow> removeDuplicatedRows(MeasurementSet& set, double tol = kRepeatTolerance);

/// The warning naming the rows of `file` removeDuplicatedRows() took out (how many, the first
/// ten as FILE:LINE = FILE:LINE); empty when there are none.
std::string duplicatedRowsWarning(const std::string& file, const std::vector<DuplicatedRow>& rows);

/// The rows of `set` whose measured values equal those of the row just before them to the last
/// bit (the position, and the orientation when both rows have one) while their joint
/// configuration differs (a joint beyond `tol`, deg or mm; another payload): an instrument does
/// not measure two poses to the same bits, so the reading is most likely the previous pose's
/// written again (a tracker that did not update before the export). Such a row is kept (an
/// export rounded coarsely can give two configurations that reach one point the same numbers)
/// and named: staleReadingsWarning(). Each as a DuplicatedRow: the row, and the row before it.
std::vector<DuplicatedRow> staleReadings(const MeasurementSet& set, double tol = kRepeatTolerance);

/// The warning naming staleReadings() of `file` (how many, the first ten as FILE:LINE = LINE);
/// empty when there are none.
std::string staleReadingsWarning(const std::string& file, const std::vector<DuplicatedRow>& rows);

/// Throws InputError when two of `sets` hold the same measurements: a row of a later set whose
/// joint values and measured values (the position, and the orientation when both rows have one)
/// equal a row of an earlier set to the last bit. The same file given twice, or a copy of it,
/// would count every such measurement twice (the parameters' sigmas sqrt(2) too small, every
/// test too significant). The error is at the later set's first such row (file:line) and names
/// the earlier set's file and row and how many rows the two share.
void refuseSharedMeasurements(const std::vector<MeasurementSet>& sets);

/// Throws InputError when the held-out set `validation` holds rows of the fit data `fit` (joint
/// values and measured values equal to the last bit, as refuseSharedMeasurements compares
/// them): a validation on measurements the fit has seen measures the fit, not the accuracy on
/// new poses. The error is at the validation's first such row and names the fit file's row and
/// how many rows the two share.
void refuseValidationInFitData(const std::vector<MeasurementSet>& fit, const MeasurementSet& validation);

/// Joints (deg or mm) and measured position components (mm) of a validation row within these
/// of a fit row's are the same measurement exported again (validationLooksLikeFitDataWarning):
/// a re-export in other units or at other precision (radians with 6 decimals: 6e-5 deg; metres
/// with 6 decimals: 5e-4 mm) moves the values by less; two measurements of one configuration by
/// a tracker (0.01-0.03 mm apart) rarely come this close in all three components.
constexpr double kReexportJointTol = 1e-3;
constexpr double kReexportPositionTolMm = 2e-3;

/// A warning when at least half of the held-out set `validation`'s rows are, to within
/// kReexportJointTol and kReexportPositionTolMm (the same payload), rows of the fit data `fit`:
/// most likely the fit's measurements exported again (other units, another precision, another
/// order of the columns), which refuseValidationInFitData, comparing bits, does not see. A
/// validation on them measures the fit. It names how many rows, the first pair as FILE:LINE =
/// FILE:LINE, and the largest difference found; empty otherwise. Never throws but
/// std::bad_alloc.
std::string validationLooksLikeFitDataWarning(const std::vector<MeasurementSet>& fit, const MeasurementSet& validation);

/// A joint that never moves in a data set: its 0-based index and the value it is held at (the
/// mean of its rows; deg or mm).
struct HeldJoint {
  int joint = 0;
  double value = 0;
};

/// The joints of `robot` whose values over the rows of `data` span at most `tol` (deg or mm; the
/// repeat tolerance: what a controller reports for one angle): the data determine the robot at
/// that angle of the joint only.
std::vector<HeldJoint> heldJoints(const MeasurementSet& data, const RobotDefinition& robot, double tol = kRepeatTolerance);

/// The warning for a held joint of a data set of `rows` rows: it never moves, the model holds at
/// that angle only; `fixed` (may be empty), the parameters of its link and the next one's that the
/// identification fixed.
std::string heldJointWarning(const RobotDefinition& robot, const HeldJoint& held, size_t rows, double tol,
                             const std::string& fixed = "");

/// The range of each of the first `dof` joints over the rows of `data` (deg or mm; the fit's
/// coverage). An empty `data` gives lower > upper for every joint.
std::vector<JointRange> jointRanges(const MeasurementSet& data, int dof);

/// The values of joint `joint` (0-based; deg or mm) over the rows of `data`, in row order.
std::vector<double> jointValues(const MeasurementSet& data, int joint);

/// The 3D RMS position noise the std columns state over every row of `sets` (mm): sqrt of the
/// mean of |std_mm|^2. NaN when no set has std columns or no row a finite std (null entries
/// are skipped).
double statedPositionNoiseRms(const std::vector<const MeasurementSet*>& sets);

/// The weight of one component of a measured row as identify weighs it (1/mm or 1/rad):
/// sqrt(row_weight) / sqrt(std^2 + tau^2), `std` the component's standard deviation (the std
/// column, or the stated or estimated std), `tau` the unmodelled-error term of its component
/// type (IdentifyOptions::model_error; same unit as std). Shared with the diagnosis, which fits
/// as identify does.
inline double rowComponentWeight(double row_weight, double std, double tau) {
  return std::sqrt(row_weight) / std::sqrt(std * std + tau * tau);
}

/// Writes measurements in the same format (every column the set has; fixed formatting:
/// q with 6 decimals, positions 6 decimals (mm), quaternions 9 decimals) through a
/// temporary file renamed into place. `comments` lines are written first, each prefixed "# ".
void writeMeasurementsCsv(const std::string& path, const MeasurementSet& set, int dof,
                          const std::vector<std::string>& comments = {});

/// The text writeMeasurementsCsv writes (for a command that writes it together with other
/// outputs, all or nothing). Throws ArgumentError when dof < 1 or the set is empty.
std::string measurementsCsvText(const MeasurementSet& set, int dof, const std::vector<std::string>& comments = {});

}  // namespace accura::calib
