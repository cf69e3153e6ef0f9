// accura post-processor: a calibrated model loaded once and placed with the frames of its
// poses, for hosts that compensate poses, paths and programs one call at a time. The plug-in
// (plugin/src/accura_plugin.cpp) is a C shell over this file: its handle is a SessionRegistry
// key whose slot holds a Session.
//
// Frames: every pose given to and returned by a Session is T_base_tcp, the program's $TOOL in
// its $BASE (x, y, z mm; A, B, C deg), as a KRL or XML program holds it. The Session takes it
// to the world of job.h (T_world_tcp = T_world_robroot * inverse($ROBROOT) * $BASE * pose)
// with SessionSettings::program_base and back; the program tool is SessionSettings::
// program_tool (default: the model's nominal tool, whose real counterpart is the calibrated
// one; job.h, "real"). Joint values: deg (mm for prismatic joints).
//
// Errors (errors.h, "The rule"): a value that is not finite or out of range throws
// calib::ArgumentError naming it; a missing or malformed file, or a placement too far from the
// calibrated base, throws calib::InputError. A pose the robot cannot reach is a result (calib::IkStatus).
// A host's calls turn both into a CallStatus and a message (Host calls, below).
//
// Threads: a Session is immutable after construction; every const method may run on several
// threads at once (each call uses its own workspace).
#pragma once

#include <cstdint>
#include <initializer_list>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

#include "accura/calib/robot.h"
#include "accura/postproc/batch.h"
#include "accura/postproc/check.h"
#include "accura/postproc/job.h"
#include "accura/postproc/placement.h"
#include "accura/postproc/program_io.h"

namespace accura::postproc {

/// What a host gives when it loads a model (the plug-in's accura_load_options).
struct SessionSettings {
  /// A robot file written by accura identify, or a bundled robot name (nominal = real).
  std::string calibrated_model;
  /// The robot the controller believes in (robot file or bundled name); empty: the nominal
  /// data of the calibrated model. When given it must be a model of that nominal robot
  /// (checkControllerRobot: the host loaded the model of the right robot), and its link
  /// deviations are the kinematics the controller runs (JobSettings::controller_kinematics: a
  /// UR controller's factory calibration, exported with accura export --ur-deltas).
  std::string controller_model;
  std::optional<calib::XyzAbc> robroot_in_world;      ///< JobSettings::robroot_in_world
  std::optional<calib::XyzAbc> robroot_in_kukaworld;  ///< $ROBROOT; empty: identity
  std::optional<calib::XyzAbc> program_base;          ///< $BASE of the poses; empty: identity
  std::optional<calib::XyzAbc> program_tool;          ///< $TOOL of the poses; empty: nominal tool
  double payload_kg = 0;                       ///< >= 0, finite
  double temp_c = calib::kThermalReferenceC;          ///< finite
  int max_joints = 12;                         ///< more joints: calib::InputError (fixed arrays)
  std::string placement_setting = "robroot_in_world";  ///< names the placement in messages
};

/// One pose compensated (compensate.h's PoseCompensation in the program's base frame).
struct SessionPose {
  calib::IkStatus status = calib::IkStatus::kNotConverged;
  std::string message;  ///< why status is not kOk (always set then)
  calib::XyzAbc command;       ///< the pose to send the controller
  calib::Configuration configuration;  ///< S/T of q_real
  bool configuration_changed = false;
  double correction_mm = 0;   ///< |command - target| (position)
  double correction_deg = 0;  ///< rotation angle between command and target
  Eigen::VectorXd q_real;     ///< joints that put the real tool on the target
};

/// Several poses compensated.
struct SessionPoses {
  std::vector<SessionPose> results;  ///< one per target
  size_t n_ok = 0;                   ///< the successes
  int first_failed = -1;             ///< the first pose that failed, -1 when none
  std::string message;               ///< "pose I: WHY (K of N poses failed)" of that one
};

/// One motion of a path: LIN or CIRC (aux: the auxiliary point; its orientation not used).
struct SessionMotion {
  PathType type = PathType::kLin;
  calib::XyzAbc aux, end;
};

/// One motion to send, in order: the compensated, densified path.
struct SessionPathPoint {
  PathType type = PathType::kLin;
  calib::XyzAbc aux, end;              ///< compensated (aux: CIRC only)
  calib::Configuration configuration;  ///< S/T of the real joints at `end`
  int motion = 0;               ///< the intended motion it belongs to
  bool inserted = false;        ///< an auxiliary point inside the motion (else its end point)
};

/// The numbers of one intended motion (SegmentCompensation), or their maxima and sums.
struct SessionMotionNumbers {
  double length_mm = 0;
  double max_error_uncompensated_mm = 0, max_error_before_mm = 0, max_error_after_mm = 0, max_error_bound_mm = 0;
  int points_added = 0;
};

struct SessionPath {
  /// kOk, or why the start (failed_motion -1) or motion failed_motion cannot be compensated;
  /// message says which. On a failure the other fields are those up to it.
  calib::IkStatus status = calib::IkStatus::kOk;
  std::string message;
  int failed_motion = -1;
  /// Motion failed_motion's geometry has no solution (a CIRC whose points are collinear;
  /// CallStatus::kNumerical); status stays kOk.
  bool numerical = false;
  SessionPose start;                          ///< the compensated start: send it first
  std::vector<SessionPathPoint> points;       ///< every motion's points, in order
  std::vector<SessionMotionNumbers> motions;  ///< one per intended motion
  SessionMotionNumbers total;                 ///< maxima of the errors, sums of length and points
  bool ok() const { return status == calib::IkStatus::kOk && failed_motion < 0; }
};

/// The S/T configuration a host asked for: S in 0..7 (three bits) or -1 (any), T in
/// 0..2^dof - 1 (a bit per joint) or -1. Throws calib::ArgumentError otherwise.
calib::Configuration checkedConfiguration(int status, int turn, int dof);

/// `pose` when its six values are finite; else throws calib::ArgumentError naming `what`.
const calib::XyzAbc& checkedPose(const calib::XyzAbc& pose, const std::string& what);

class Session {
 public:
  /// Reads and places the models (see SessionSettings). Throws calib::InputError for a missing or
  /// malformed robot file (a path that does not exist is named as such), a controller model
  /// that is not the calibrated model's robot, more than max_joints joints, a calibrated base
  /// far from the placement (placeRobot); calib::ArgumentError for a pose, payload or temperature
  /// that is not finite or out of range.
  explicit Session(const SessionSettings& settings);

  const JobSettings& job() const { return job_; }
  const Placement& placement() const { return models_->placement(); }
  int dof() const { return job_.calibrated.dof(); }

  /// q[0..n) as joint values of this robot: throws calib::ArgumentError "expected DOF joint
  /// values, got N" when n is not dof() (checked before q is read; q may be null when n is 0).
  std::vector<double> joints(const double* q, size_t n) const;

  /// T_base_tcp of the controller model (`real` false: nominal at the placement with the
  /// program tool) or of the real (calibrated) model at joints q (dof values, finite; else
  /// calib::ArgumentError).
  calib::XyzAbc forward(bool real, const std::vector<double>& q) const;

  /// S/T of joints q (dof finite values, deg / mm; else calib::ArgumentError) by KUKA's rule
  /// (calib::kukaConfiguration on the nominal geometry, what the controller computes).
  calib::Configuration configuration(const std::vector<double>& q) const;
  /// configuration(q) of the arm's joints at a program target T_base_tcp written with $TOOL
  /// `tool` and $BASE `base` (relative to $WORLD; the placement's $ROBROOT applies). Throws
  /// calib::ArgumentError naming `what` when q is not valid or does not put the tool on the
  /// target within kJointsOnTargetMm / kJointsOnTargetDeg (joints of another target).
  calib::Configuration configurationAt(const std::vector<double>& q, const calib::XyzAbc& T_base_tcp, const calib::XyzAbc& tool,
                                       const calib::XyzAbc& base, const std::string& what) const;
  static constexpr double kJointsOnTargetMm = 0.01;
  static constexpr double kJointsOnTargetDeg = 0.01;

  /// Compensates one pose (compensateTarget: the configuration rule of a PTP of accura
  /// compensate; a Universal Robots arm's controller reads no S/T, so only the Status of
  /// `asked` is asked, as the guess of the branch, and nothing after a seed); `seed`: real
  /// joints to continue from (empty: none).
  SessionPose pose(const calib::XyzAbc& target, const calib::Configuration& asked, const Eigen::VectorXd& seed = Eigen::VectorXd()) const;
  /// Compensates every target (asked: empty or one per target; every value validated before
  /// any work). `continuous`: each pose continues from the real joints of the previous
  /// successful one; every pose is computed, failed or not.
  SessionPoses poses(const std::vector<calib::XyzAbc>& targets, const std::vector<calib::Configuration>& asked,
                                 bool continuous) const;
  /// Compensates a path from `start` through LIN / CIRC motions with auxiliary points until the
  /// predicted deviation is below tol_mm (> 0, finite; else calib::ArgumentError): compensatePath
  /// (path_job.h), the loop of accura compensate.
  SessionPath path(const calib::XyzAbc& start, const calib::Configuration& start_config, const std::vector<SessionMotion>& motions,
                   double tol_mm) const;

  /// compensateProgramFile (batch.h) with this model's settings and tol_mm (> 0, finite).
  /// Throws calib::InputError for a program file that does not exist, else as compensateProgramFile.
  ProgramFileResult compensateProgramFile(const ProgramFileRequest& request, double tol_mm) const;

  /// checkProgram (check.h) of the program file in the cell file with this model's settings:
  /// the cell's thresholds, or `thresholds` when given. Throws calib::InputError for a file that does
  /// not exist or is malformed, calib::ArgumentError for thresholds that are not valid.
  CheckReport checkProgramFile(const std::string& cell_path, const std::string& program_path, const ProgramReadOptions& read,
                               CheckMode mode, const std::optional<CheckThresholds>& thresholds) const;

 private:
  JobSettings job_;
  std::vector<std::string> model_files_;  ///< the robot files read (never overwritten by an output)
  std::unique_ptr<ModelFactory> models_;
  Eigen::Isometry3d T_world_progbase_ = Eigen::Isometry3d::Identity();
  const Compensator* comp_ = nullptr;  ///< the models of the program tool (built here)

  Eigen::Isometry3d toWorld(const calib::XyzAbc& T_base_tcp, const std::string& what) const;
  calib::XyzAbc toBase(const Eigen::Isometry3d& T_world_tcp) const;
  /// q as a vector: dof finite values, else calib::ArgumentError ("WHAT: expected N joint
  /// values, got M", "WHAT[i] is not finite"; `what` empty: no prefix, q[i]).
  Eigen::VectorXd jointVector(const std::vector<double>& q, const std::string& what) const;
};

// ---------------------------------------------------------------------------------------------
// Host calls: what every entry point of a host interface does around its work (each of the
// plug-in's C functions is one SessionRegistry::run, runOn or withSession).

/// How a host call ended: the plug-in's accura_status, the same values in the same order.
enum class CallStatus {
  kOk,
  kNullArgument,     ///< a required pointer was null (requirePointers)
  kInvalidArgument,  ///< calib::ArgumentError, a handle not live or without a model
  kBufferTooSmall,   ///< requireCapacity
  kInput,            ///< calib::InputError
  kUnreachable,      ///< kUnreachable .. kNotConverged: calib::IkStatus's failures, its order
  kJointLimits,
  kSingular,
  kNoConfiguration,
  kNotConverged,
  kNumerical,    ///< calib::NumericalError
  kOutOfMemory,  ///< std::bad_alloc, std::length_error (a count too large to hold)
  kInternal,     ///< any other exception: a bug
};

/// kOk for IkStatus::kOk, else the failure of the same name.
CallStatus callStatus(calib::IkStatus status);

/// A failure of a host call with its status, thrown by the call's own checks (other
/// exceptions get their status from their type: SessionRegistry::run).
struct CallError : std::runtime_error {
  CallError(CallStatus s, const std::string& message) : std::runtime_error(message), status(s) {}
  CallStatus status;
};

/// The required pointers of a call with their parameter names.
using CallPointers = std::initializer_list<std::pair<const void*, const char*>>;
/// Throws CallError kNullArgument "NAME is NULL" for the first required pointer that is null.
void requirePointers(CallPointers pointers);
/// `p`, or a stand-in that is not null when `n` is 0 (nothing is read through it): for an array
/// that may be null when it is empty.
const void* ifAny(size_t n, const void* p);
/// Throws CallError kBufferTooSmall "WHAT, the buffer holds CAPACITY AFTER" when `needed`
/// elements do not fit in `capacity`.
void requireCapacity(size_t needed, size_t capacity, const std::string& what, const char* after = "");
/// `value` when `allowed`, else throws calib::ArgumentError "WHAT: expected EXPECTED, found
/// VALUE": an enum or a count that a host passes as an int.
int checkedInt(int value, bool allowed, const std::string& what, const std::string& expected);

/// The sessions of a host's handles (the plug-in's accura_model*): keys, not addresses, never 0
/// and never reused, so that a key used after release() (or never made) is found to be dead
/// instead of reading freed memory. Each key's Slot holds its session (none until loaded) and
/// the last error of each thread. Every method may run on several threads at once.
class SessionRegistry {
 public:
  class Slot {
   public:
    /// The loaded session, null when none: the caller keeps it alive while it uses it (a
    /// later load() or release() lets the call finish with it).
    std::shared_ptr<const Session> session() const;
    /// session(), or CallError kInvalidArgument when no model is loaded.
    std::shared_ptr<const Session> loaded() const;
    void load(std::shared_ptr<const Session> session);
    /// The calling thread's last error on this slot ("" when none); the string stays valid
    /// until this thread's next setError() on the slot or the slot's end.
    const std::string& error();
    void setError(std::string text);

   private:
    mutable std::mutex mutex_;
    std::shared_ptr<const Session> session_;
    std::unordered_map<std::thread::id, std::string> errors_;
  };

  /// The registry of the process: never destroyed (a host may call while its statics go).
  static SessionRegistry& instance();
  /// A new live key with an empty slot (a multiple of 16, so never 0 nor a small integer).
  std::uintptr_t create();
  /// Forgets `key` (0: nothing); throws CallError kInvalidArgument when it is not live. Calls
  /// that hold its slot finish with it.
  void release(std::uintptr_t key);
  /// The slot of a live key; null when `key` is not live.
  std::shared_ptr<Slot> find(std::uintptr_t key) const;
  /// The slot of a live key; throws CallError kNullArgument "model is NULL" for 0,
  /// kInvalidArgument "not a live handle ..." for a key that is not live.
  std::shared_ptr<Slot> live(std::uintptr_t key) const;

  /// Runs body() for the call `fn` made without a handle: kOk, or the status of its exception
  /// (CallError: its own; calib::InputError kInput, calib::ArgumentError kInvalidArgument,
  /// calib::NumericalError kNumerical, std::bad_alloc / std::length_error kOutOfMemory "out of memory", any other
  /// kInternal "internal error: WHAT") with the message "FN: WHAT" kept as the calling
  /// thread's last error without a handle (lastError(0)). Never throws: running out of memory
  /// while keeping the message keeps the status.
  template <class F>
  static CallStatus run(const char* fn, F&& body) noexcept {
    try {
      body();
      return CallStatus::kOk;
    } catch (...) {
      return failed(fn, nullptr);
    }
  }
  /// run() of body(slot) on the slot of `key` (live()): the slot is held while the body runs
  /// (a release() from another thread lets it finish) and the body's failure is kept there
  /// for the calling thread; a key that is not live fails as live() says, its message kept as
  /// for run().
  template <class F>
  CallStatus runOn(std::uintptr_t key, const char* fn, F&& body) noexcept {
    std::shared_ptr<Slot> slot;
    try {
      slot = live(key);
      body(*slot);
      return CallStatus::kOk;
    } catch (...) {
      return failed(fn, slot.get());
    }
  }
  /// runOn(): the required pointers checked (requirePointers), then body(the slot's loaded
  /// session; none: kInvalidArgument).
  template <class F>
  CallStatus withSession(std::uintptr_t key, const char* fn, CallPointers pointers, F&& body) noexcept {
    return runOn(key, fn, [&](Slot& slot) {
      requirePointers(pointers);
      body(*slot.loaded());
    });
  }
  /// *message: the calling thread's last error on the live `key` ("" when none; valid until its
  /// next failing call on the key or the key's release); kOk. For key 0 its last error without
  /// a handle (run(); valid until its next such failure), kOk; for a key that is not live that
  /// message too, and kInvalidArgument. Out of memory: "" and kOutOfMemory. Never throws.
  CallStatus lastError(std::uintptr_t key, const char** message) const noexcept;

 private:
  mutable std::mutex mutex_;
  std::unordered_map<std::uintptr_t, std::shared_ptr<Slot>> live_;
  std::uintptr_t last_id_ = 0;

  /// The status of the exception being handled, its message "FN: WHAT" kept in `slot` for the
  /// calling thread (null: as its last error without a handle).
  static CallStatus failed(const char* fn, Slot* slot) noexcept;
};

/// One motion of a program written from poses (program base frame, T_base_tcp).
struct PoseProgramMotion {
  MotionType type = MotionType::kLin;  ///< kPtp, kLin or kCirc
  calib::XyzAbc aux, end;                     ///< aux: kCirc only
  bool approximate = false;            ///< KRL C_PTP for PTP, C_DIS for LIN / CIRC
  double vel_m_s = 0;                  ///< LIN / CIRC path speed (m/s; <= 0: not set; finite)
  /// The arm's joints at `end` (deg / mm; empty: none): a PTP's S/T (Session::configurationAt).
  std::vector<double> joints;
};

/// A program to write from poses: every motion with the same $TOOL and $BASE.
struct PoseProgram {
  std::string name;   ///< empty: the file name without its extension
  std::string robot;  ///< the robot named in an XML program (empty: the session's, if any)
  calib::XyzAbc tool, base;  ///< $TOOL (T_flange_tcp), $BASE (relative to $WORLD)
  std::vector<PoseProgramMotion> motions;
};

/// Writes `program` in the controller language of path's extension (renderProgram: .src KRL
/// with its .dat, .xml accura's XML) through calib::writeFilesAtomically, the directory created.
/// A PTP with joints gets their S/T (session->configurationAt; LIN / CIRC keep the
/// configuration they start in: no S/T). Throws calib::ArgumentError for a pose or speed that
/// is not finite (naming "motions[I].end", ...), joints without a session or not at their
/// target; calib::InputError for another extension or a file that cannot be written.
void writePoseProgram(const std::string& path, const PoseProgram& program, const Session* session = nullptr);

}  // namespace accura::postproc
