// accura post-processor: compensation of a whole program (frames, discrete compensation of
// every Cartesian target, auxiliary points on LIN/CIRC segments) on top of compensate.h.
//
// Frames (docs/program-formats.md, "Frames"):
//   world       the calibrated model's world: the frame its base was measured in (tracker,
//               cell). The OLP placed the robot at its nominal base T_world_robroot there
//               (the robot file's <base>, or --base).
//   $WORLD      the controller's world; T_robroot_kukaworld = inverse($ROBROOT), $ROBROOT the
//               robot base in the controller's $WORLD (identity unless --robroot: KUKA's
//               default, $WORLD = robot base).
//   $BASE       the program's base frame relative to $WORLD; targets are T_base_tcp.
//   So T_world_tcp = T_world_robroot * inverse($ROBROOT) * $BASE * target.
//   controller  nominal kinematics at T_world_robroot with the program's $TOOL (or the
//               kinematics the controller itself runs: JobSettings::controller_kinematics).
//   real        the calibrated model (its base, kinematics, compliance, ...) with the
//               calibrated tool when the program's $TOOL equals the model's nominal tool
//               within 1e-3 mm and 1e-3 deg (the tool that was calibrated), else with the
//               program's $TOOL taken as exact.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "accura/calib/errors.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/robot.h"
#include "accura/postproc/compensate.h"
#include "accura/postproc/program.h"

namespace accura::postproc {

/// The values a run's context and frames may take at every interface (the command line's
/// options, the plug-in's load options, a Session's poses): beyond them a value is bad input,
/// not an extrapolation.
inline constexpr double kMaxPayloadKg = 10000;                ///< payload (kg), from 0
inline constexpr double kMinTempC = -50, kMaxTempC = 150;     ///< arm temperature (deg C)
inline constexpr double kMaxFrameMm = 1e5;                    ///< |x|, |y|, |z| of a frame (mm): 100 m
inline constexpr double kMaxFrameDeg = 360;                   ///< |A|, |B|, |C| of a frame (deg)

/// A PTP target whose compensated joints differ from the nominal robot's joints for it by more
/// than this (deg; mm for a prismatic joint) gets a warning: the arm reaches the pose in
/// another posture than the off-line simulation (a wrist next to its singularity).
inline constexpr double kPostureChangeDeg = 5.0;

/// A URScript set_gravity whose direction differs from the model's <gravity> by more than this
/// (deg) gets a warning where the model has joint compliance: the mounting differs (about 1.7 %
/// of the gravity deflection per degree).
inline constexpr double kGravityDisagreeDeg = 1.0;

struct JobSettings {
  calib::RobotModel calibrated;  ///< the real robot (a calibrated model written by accura identify)
  /// Where the OLP placed the robot in the model's world (mm, deg); empty: the robot file's
  /// <base> (calibrated.nominal.T_world_base).
  std::optional<calib::XyzAbc> robroot_in_world;
  /// The controller's $ROBROOT (robot base in the controller's $WORLD); empty: identity.
  std::optional<calib::XyzAbc> robroot_in_kukaworld;
  double tol_mm = 0.05;  ///< bound on the predicted path error of LIN/CIRC segments
  calib::PoseContext context;   ///< payload, temperature of the real robot while it runs the program
  /// The program's tool is the calibrated one when it equals the model's nominal tool within
  /// these (mm, deg).
  double tool_match_mm = 1e-3;
  double tool_match_deg = 1e-3;
  /// The calibrated base may differ from the nominal base by at most this much (mm, deg):
  /// more means the model was measured in another frame (a tracker's) and --base is needed.
  double max_base_offset_mm = 50;
  double max_base_offset_deg = 5;
  /// $TOOL / $BASE (T_flange_tcp; $BASE relative to $WORLD; mm, deg) for the motions before
  /// the program sets them (programs that rely on the frames active on the controller).
  std::optional<calib::XyzAbc> initial_tool, initial_base;
  /// IK convergence for the written values: far below their last digit (1e-4 mm, 1e-5 deg),
  /// so that the digits written do not depend on the iterations that led there (the same
  /// bytes on every machine). Newton converges quadratically: about one more iteration.
  calib::IkOptions ik = [] {
    calib::IkOptions o;
    o.tol_mm = 1e-7;
    o.tol_rad = 1e-10;
    return o;
  }();
  DensifyOptions densify;  ///< tol_mm is taken from tol_mm above
  /// The arm's kinematics the controller itself runs, when they are not the nominal robot's:
  /// a UR controller runs its factory calibration (calibration.conf; `accura export --ur-deltas`
  /// makes this model). Its links' deviations are used; its base and tool are not (the
  /// placement and the program's tool apply). It must be a model of calibrated.nominal's robot
  /// (checkControllerRobot). Empty: the nominal robot. `calibrated` is then the real arm as
  /// identified (starting from the factory calibration, or not: it is the whole real arm).
  std::optional<calib::RobotModel> controller_kinematics;
};

/// One corrected target (in the program's base frame).
struct TargetReport {
  SourceLocation where;     ///< of the target's value
  SourceLocation motion;    ///< of the motion statement
  std::string name;         ///< point name, empty for an inline target
  std::string role;         ///< "end" or "aux"
  std::string motion_type;  ///< PTP, LIN, CIRC, SPTP, ...
  std::string instruction;  ///< the motion instruction as written (motionInstruction: MoveL, movej, LIN)
  double correction_mm = 0;   ///< |command - desired|
  double correction_deg = 0;  ///< rotation angle between command and desired
  double dx_mm = 0, dy_mm = 0, dz_mm = 0;  ///< command - desired, in the program's base frame
  bool calibrated_tool = false;            ///< the real model used the calibrated tool
  /// A new declared point (name) that replaces this one in the motion (the auxiliary point
  /// of the last sub-arc of a split CIRC: the declared one keeps its value); empty otherwise.
  std::string new_point_replaces;
  Eigen::VectorXd q_real;  ///< joint values the real robot takes at the target (deg / mm); empty: not known
};

/// One LIN / CIRC segment.
struct SegmentReport {
  SourceLocation motion;
  std::string motion_type;
  std::string instruction;  ///< as TargetReport::instruction
  double length_mm = 0;
  double max_error_uncompensated_mm = 0;  ///< the program as it was
  double max_error_before_mm = 0;         ///< endpoints compensated, no auxiliary points
  double max_error_after_mm = 0;          ///< with the auxiliary points written
  int points_added = 0;
  std::string note;  ///< why no points were added although needed, ...
};

struct ProgramIssue {
  SourceLocation where;
  std::string message;
};

struct JobReport {
  std::vector<TargetReport> targets;
  std::vector<SegmentReport> segments;
  std::vector<ProgramIssue> warnings;  ///< left unchanged, path not checked, ...
  std::vector<ProgramIssue> errors;    ///< why the program was not written
  int targets_corrected = 0;
  /// motions kept as written because their target is computed at run time (each one is in
  /// `warnings`)
  int motions_left_unchanged = 0;
  int points_added = 0;
  double max_correction_mm = 0, rms_correction_mm = 0, max_correction_deg = 0;
  double max_error_uncompensated_mm = 0, max_error_before_mm = 0, max_error_after_mm = 0;
  calib::XyzAbc robroot_in_world;          ///< the nominal base used
  calib::XyzAbc calibrated_base_in_world;  ///< the calibrated model's base
};

/// A program compensated, and its complete report (every total computed, its errors listed).
struct ProgramCompensation {
  Program program;   ///< meaningful only when ok()
  JobReport report;
  bool ok() const { return report.errors.empty(); }
};

/// Compensates every target of `program` (see the file comment): the program with the
/// corrected targets marked `modified` and the auxiliary points inserted (marked `inserted`,
/// before their motion). The targets that cannot be compensated (unreachable, singular, joint
/// limits, its S/T configuration would change, an unknown tool or base, a malformed or
/// run-time target on a LIN/CIRC) are returned in report.errors with their location, not
/// thrown (errors.h, "The rule"). Throws ArgumentError on invalid settings and InputError
/// when the calibrated base is far from the placement (placement.h, placeRobot).
/// Deterministic: the same inputs give the same output on every run and thread.
ProgramCompensation compensateProgramReport(const Program& program, const JobSettings& settings);

/// The arm a program's controller language needs, refused when `robot` is not one: a URScript
/// program (read from URScript, or carrying URScript lines after a conversion) runs on a
/// Universal Robots arm (6 revolute joints, joints 2, 3 and 4 parallel, no spherical wrist:
/// the controller's shoulder/elbow/wrist branches are that geometry's). Throws InputError
/// naming the program and the model otherwise. Used by compensate, check and batch.
void requireArmForProgram(const Program& program, const calib::RobotDefinition& robot);

/// The settings `program` runs with on its controller: a URScript program's poses are in the UR
/// controller's Base frame, UR's DH frame 0 (URScript manual; ur_calibration.h, urConventionOf),
/// which a robot read from ur_description's URDF from its root (base_link) has turned by 180 deg
/// about axis 1: without robroot_in_kukaworld (--robroot) that turn is set as $ROBROOT (the
/// robot's frame 0 in Base). Any other program or robot: `settings` as given. Used by
/// compensateProgramReport and checkProgram.
JobSettings settingsForProgram(const Program& program, const JobSettings& settings);

/// RAPID: a motion's tooldata or wobjdata that the program names but does not declare (a
/// system module's, Source::kUnset with its name) takes its value from --program-tool /
/// --program-base (JobSettings::initial_tool / initial_base), which give one frame. A second
/// such name (any case) is another frame on the controller, whose value accura does not have:
/// throws InputError at its first motion, naming both, when the setting is given. Used by
/// compensate, check and batch.
void requireOneUndeclaredFrame(const Program& program, const JobSettings& settings);

/// True for a Universal Robots arm (6 revolute joints, joints 2, 3 and 4 parallel, no spherical
/// wrist). Its controller reads no Status/Turn: a Cartesian PTP (movej(pose)) goes to the
/// solution nearest the current joints, so compensate and check ask no S/T a program carries.
bool universalRobotsArm(const calib::RobotDefinition& robot);

/// Whether the controller of `robot` reads the Status/Turn of a Cartesian target (KUKA; ABB's
/// confdata is read apart): false on a Universal Robots arm (universalRobotsArm). The one
/// place that decides it for accura compensate, accura check and the plug-in (Session).
bool controllerReadsConfiguration(const calib::RobotDefinition& robot);

/// The S/T the IK asks of a Cartesian target that carries `written` (docs/compensation.md,
/// section 2; a PTP's, and a CP motion's after an unknown position): `written` on a controller that reads them (`reads`,
/// controllerReadsConfiguration); on one that reads none, nothing after a known position
/// (`position_known`: the solution nearest the joints the robot stands on, as movej(pose)
/// takes it) and only the written Status, as the guess of the branch, after an unknown one.
/// A Turn asked there turned a joint at 0 deg whose real value lies a few hundredths below
/// 0 a full turn round (-0.03 -> 359.97 deg, inside the UR's +-360 deg) to keep its sign.
calib::Configuration askedConfiguration(bool reads, const calib::Configuration& written, bool position_known);

/// The InputError that lists every error of `report` (the first with its file:line:column).
/// Requires !report.errors.empty().
calib::InputError compensationError(const JobReport& report);

/// compensateProgramReport for callers that want an exception: fills `report` (may be null)
/// with the complete report, then throws compensationError(report) when a target cannot be
/// compensated.
Program compensateProgram(const Program& program, const JobSettings& settings, JobReport* report);

/// The real robot for a program tool (see "real" above): `calibrated` with its identified tool
/// when T_flange_tcp is its nominal tool within match_mm (mm) and match_deg (deg), else
/// `calibrated` with T_flange_tcp taken as exact (no tool deviations). `calibrated_tool`
/// (optional) says which of the two.
calib::RobotModel realModelForTool(const calib::RobotModel& calibrated, const Eigen::Isometry3d& T_flange_tcp, double match_mm,
                            double match_deg, bool* calibrated_tool = nullptr);

}  // namespace accura::postproc
