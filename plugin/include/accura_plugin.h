/*
 * accura plug-in: the C interface for CAD / OLP hosts (libaccura_plugin.so).
 *
 * One header, C89/C99 compatible, no C++ types. Reference: docs/plugin.md.
 *
 * Units and frames (project-wide, docs/method.md):
 *   lengths in mm, angles in deg; a pose is x, y, z (mm) and A, B, C (deg) with
 *   R = Rz(A) Ry(B) Rx(C) (KUKA). Joint values in deg (mm for prismatic joints).
 *   Poses given to and returned by the compensation calls are T_base_tcp: the tool ($TOOL)
 *   in the program's base frame ($BASE, relative to the controller's $WORLD), exactly what a
 *   KRL or XML program holds. The world of the calibrated model and where the OLP placed the
 *   robot in it are set when the model is loaded (accura_load_options).
 *
 * Status codes: every call returns an accura_status. ACCURA_OK is 0. On any other status
 * the call's outputs are unspecified unless said otherwise, and accura_last_error() gives a
 * message (file:line:column for bad files, the path for a missing one).
 *
 * Threads: every call may run at the same time as any other, on one handle or on several.
 * The loaded model is immutable (accura_model_load replaces it atomically; calls already
 * running finish with the model they started with); every call uses its own workspace. The
 * last error is kept per handle and per thread: accura_last_error(h) returns the message of
 * the last failed call that the calling thread made on h. accura_model_free while another
 * thread's call on the same handle runs lets that call finish; calls that start later get
 * ACCURA_ERROR_INVALID_ARGUMENT.
 *
 * Handles: an accura_model* is a key, not an address; keys are never reused. A handle used
 * after accura_model_free (or a pointer that accura_model_create did not return) is detected:
 * ACCURA_ERROR_INVALID_ARGUMENT, never a read of freed memory.
 *
 * No C++ exception crosses this interface: every failure, out of memory included, becomes a
 * status. NULL pointers and wrong sizes give ACCURA_ERROR_NULL_ARGUMENT or
 * ACCURA_ERROR_INVALID_ARGUMENT, with a message: in the handle, or, for a call without a live
 * handle (a NULL or freed handle, the *_options_init calls, accura_status_name), for the
 * calling thread through accura_last_error(NULL, &message).
 */
#ifndef ACCURA_PLUGIN_H
#define ACCURA_PLUGIN_H

#include <stddef.h>

#if defined(_WIN32)
#define ACCURA_API __declspec(dllexport)
#elif defined(__GNUC__) || defined(__clang__)
#define ACCURA_API __attribute__((visibility("default")))
#else
#define ACCURA_API
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* The ABI version of this header: a host compares it with accura_version()'s abi_version and
 * refuses a library with another one. Raised on every incompatible change of a declaration
 * or struct below. 2: accura_program_motion carries the arm's joint values (n_joints,
 * joints), accura_joint_configuration. */
#define ACCURA_PLUGIN_ABI_VERSION 2

/* Largest joint count the fixed-size arrays below hold. */
#define ACCURA_MAX_JOINTS 12

typedef enum accura_status {
  ACCURA_OK = 0,
  ACCURA_ERROR_NULL_ARGUMENT = 1,    /* a required pointer was NULL */
  ACCURA_ERROR_INVALID_ARGUMENT = 2, /* a value out of range or not finite, a wrong struct_size
                                        or count, a handle without a model */
  ACCURA_ERROR_BUFFER_TOO_SMALL = 3, /* an output array is too small: the count output says how
                                        many elements are needed (the other outputs are set) */
  ACCURA_ERROR_INPUT = 4,            /* a file is missing, unreadable or malformed (message:
                                        file:line:column, what was expected, what was found) */
  ACCURA_ERROR_UNREACHABLE = 5,      /* no joint values put the tool there */
  ACCURA_ERROR_JOINT_LIMITS = 6,     /* reachable only outside the joint limits */
  ACCURA_ERROR_SINGULAR = 7,         /* at or too close to a singularity */
  ACCURA_ERROR_NO_CONFIGURATION = 8, /* reachable, but not on the S/T configuration asked for */
  ACCURA_ERROR_NOT_CONVERGED = 9,    /* IK did not converge, or a path tolerance not met */
  ACCURA_ERROR_NUMERICAL = 10,       /* a numerical failure (e.g. a CIRC through 3 collinear
                                        points) */
  ACCURA_ERROR_OUT_OF_MEMORY = 11,
  ACCURA_ERROR_INTERNAL = 12         /* a bug: please report the message */
} accura_status;

/* Opaque handle: a calibrated model with its frames, ready for compensation. */
typedef struct accura_model accura_model;

/* x, y, z (mm), A, B, C (deg), R = Rz(A) Ry(B) Rx(C). */
typedef struct accura_pose {
  double x_mm, y_mm, z_mm;
  double a_deg, b_deg, c_deg;
} accura_pose;

/* KUKA configuration: Status and Turn bits (postproc/include/accura/postproc/compensate.h:
 * T bit i set when joint i+1 < 0; S bit 0 overhead, bit 1 elbow, bit 2 A5 < 0). -1: not
 * specified (any).
 * A Universal Robots arm (the model's geometry: joints 2-4 parallel, no spherical wrist) has a
 * controller that reads no S/T (movej(pose) takes the solution nearest the current joints), and
 * the compensation calls ask none of it, as `accura compensate` does (docs/compensation.md,
 * section 2): a pose without a seed on the Status given, as the guess of the branch, and the
 * Turn of the solution nearest the middle of the joint ranges (a joint at 0 deg whose real value
 * lies a few hundredths below 0 stays there, not a full turn round to keep its Turn bit); a pose
 * continued from the previous one (accura_compensate_poses, continuous 1) on the solution nearest
 * its joints, whatever S/T were given. The configuration returned is then the S/T of the joints
 * reached (KUKA's rule on q_real), for information, and configuration_changed is 0. */
typedef struct accura_configuration {
  int status;
  int turn;
} accura_configuration;

/* ---------------------------------------------------------------------------------------- */
/* Version and messages */

/* The library's version (major.minor.patch) and its ABI version (compare with
 * ACCURA_PLUGIN_ABI_VERSION). Any pointer may be NULL (that part is not returned). */
ACCURA_API accura_status accura_version(int* major, int* minor, int* patch, int* abi_version);

/* A constant English name of a status ("ACCURA_ERROR_INPUT"); unknown values give
 * "ACCURA_STATUS_UNKNOWN" (and ACCURA_ERROR_INVALID_ARGUMENT). */
ACCURA_API accura_status accura_status_name(accura_status status, const char** name_out);

/* The message of the last failed call the calling thread made on `model` ("" when none):
 * valid until the calling thread's next failing call on `model` or accura_model_free (calls
 * that succeed neither clear nor move it). `model` NULL: ACCURA_OK and the message of the
 * calling thread's last failed call without a live handle (valid until its next such failing
 * call); a handle that is not live: that message too, and ACCURA_ERROR_INVALID_ARGUMENT. */
ACCURA_API accura_status accura_last_error(const accura_model* model, const char** message_out);

/* ---------------------------------------------------------------------------------------- */
/* Model */

/* A new handle without a model (every compensation call on it gives
 * ACCURA_ERROR_INVALID_ARGUMENT until accura_model_load succeeds). Free with accura_model_free. */
ACCURA_API accura_status accura_model_create(accura_model** model_out);
/* Frees the handle (NULL: nothing to do; a handle already freed: ACCURA_ERROR_INVALID_ARGUMENT). */
ACCURA_API accura_status accura_model_free(accura_model* model);

/* How the model is placed and used. Initialise with accura_load_options_init. */
typedef struct accura_load_options {
  size_t struct_size; /* sizeof(accura_load_options), set by accura_load_options_init */
  /* The robot the controller believes in: a robot file or a bundled robot name (kuka_kr16,
   * ...). NULL: the nominal data of the calibrated model file (what `accura compensate`
   * does). When given it must be the calibrated model's nominal robot (same joints, DH
   * values within 1e-9): a check that the host loaded the model of the right robot. */
  const char* controller_model;
  /* Where the OLP placed the robot in the calibrated model's world (accura compensate
   * --base). has_... = 0: the robot file's <base>. */
  int has_robroot_in_world;
  accura_pose robroot_in_world;
  /* The controller's $ROBROOT (robot base in its $WORLD; --robroot). 0: identity. */
  int has_robroot_in_kukaworld;
  accura_pose robroot_in_kukaworld;
  /* $BASE (relative to $WORLD) of the poses and paths given to the compensation calls, and
   * for the motions of a program before it sets $BASE (--program-base). 0: identity. */
  int has_program_base;
  accura_pose program_base;
  /* $TOOL (T_flange_tcp) of the poses and paths, and for the motions of a program before it
   * sets $TOOL (--program-tool). 0: the model's nominal tool (the calibrated tool is then
   * used by the real robot). A tool equal to the model's nominal tool within 1e-3 mm / deg
   * is the calibrated one; any other is taken as exact. */
  int has_program_tool;
  accura_pose program_tool;
  double payload_kg; /* payload while the program runs (kg, in [0, 10000]), for compliance models */
  double temp_c;     /* arm temperature (deg C, in [-50, 150]), for thermal models; default 20 */
} accura_load_options;

/* Fills `options` with the defaults. `struct_size` must be sizeof(accura_load_options) of the
 * caller (ACCURA_ERROR_INVALID_ARGUMENT otherwise). */
ACCURA_API accura_status accura_load_options_init(accura_load_options* options, size_t struct_size);

/* Loads a calibrated model (a robot file written by `accura identify`, or a bundled robot
 * name: nominal = real) into `model`, replacing any model it held. `options` NULL: defaults.
 * ACCURA_ERROR_INPUT for a missing or malformed file (the message names it), a controller
 * model that is not the calibrated model's robot, or a calibrated base more than 50 mm /
 * 5 deg from the placement (the model was measured in another frame: set
 * has_robroot_in_world). ACCURA_ERROR_INVALID_ARGUMENT for an option out of range: payload
 * or temperature beyond the ranges above, a pose beyond +-100000 mm or +-360 deg. On failure
 * the handle keeps the model it had. */
ACCURA_API accura_status accura_model_load(accura_model* model, const char* calibrated_model,
                                           const accura_load_options* options);

typedef struct accura_model_info {
  int dof;                   /* joint count */
  char robot_name[128];      /* the robot file's name attribute (truncated, NUL-terminated) */
  accura_pose robroot_in_world;          /* the placement used (mm, deg) */
  accura_pose calibrated_base_in_world;  /* the calibrated model's base */
  double lower[ACCURA_MAX_JOINTS];       /* joint limits (deg / mm) */
  double upper[ACCURA_MAX_JOINTS];
} accura_model_info;
ACCURA_API accura_status accura_model_get_info(accura_model* model, accura_model_info* info);

/* One joint of the nominal robot (the robot file's DH form: link i = Rz(direction * q +
 * theta0) Tz(d) Tx(a) Rx(alpha); docs/robot-format.md). */
typedef struct accura_joint {
  int prismatic;               /* 0: revolute (q in deg), 1: prismatic (q in mm) */
  double a_mm, alpha_deg, d_mm, theta0_deg;
  int direction;               /* +1 or -1 */
  double lower, upper;         /* limits (deg / mm) */
} accura_joint;
/* The nominal robot's joints: writes min(dof, capacity) of them; `n_joints` (may be NULL)
 * gets the dof. ACCURA_ERROR_BUFFER_TOO_SMALL when capacity < dof. */
ACCURA_API accura_status accura_model_get_joints(accura_model* model, accura_joint* joints, size_t capacity,
                                                 size_t* n_joints);

typedef enum accura_which_model {
  ACCURA_CONTROLLER = 0, /* the nominal model at the placement, with the program tool */
  ACCURA_REAL = 1        /* the calibrated model (payload and temperature of the options) */
} accura_which_model;

/* T_base_tcp (program base frame, program tool) of `which` at joint values q (n_joints =
 * dof). */
ACCURA_API accura_status accura_forward_kinematics(accura_model* model, accura_which_model which,
                                                   const double* q, size_t n_joints,
                                                   accura_pose* pose_out);

/* The configuration of joint values q (n_joints = dof, deg / mm) by KUKA's rule (see
 * accura_configuration; the nominal geometry, what the controller computes): what a PTP to a
 * Cartesian target must carry for the arm to take these joints. */
ACCURA_API accura_status accura_joint_configuration(accura_model* model, const double* q, size_t n_joints,
                                                    accura_configuration* configuration_out);

/* ---------------------------------------------------------------------------------------- */
/* Discrete compensation (method.md section 4): q' = IK_real(target), command = FK_nominal(q') */

typedef struct accura_pose_result {
  accura_status status;        /* ACCURA_OK or why this pose has no compensation */
  accura_pose command;         /* the pose to send the controller (program base frame) */
  accura_configuration configuration; /* S/T of q_real: the program must carry it (a UR arm:
                                          the configuration reached, see accura_configuration) */
  int configuration_changed;   /* 1: the configuration asked for differs (see compensate.h);
                                  always 0 on a UR arm (its controller reads no S/T) */
  double correction_mm;        /* |command - target| (position) */
  double correction_deg;       /* rotation angle between command and target */
  int dof;
  double q_real[ACCURA_MAX_JOINTS]; /* joint values that put the real tool on the target */
} accura_pose_result;

/* Compensates one pose. `configuration` NULL: any (the branch nearest to the middle of the
 * joint ranges); on a UR arm only its Status is asked (see accura_configuration). The pose's
 * own failure (unreachable, ...) is the returned status and result->status. */
ACCURA_API accura_status accura_compensate_pose(accura_model* model, const accura_pose* target,
                                                const accura_configuration* configuration,
                                                accura_pose_result* result);

/* Compensates n poses; results[i] has each pose's status. `configurations` NULL or n
 * entries. `continuous` 0: each pose independently (the same as accura_compensate_pose);
 * 1: each pose continues from the real joints of the previous successful one (the solution
 * nearest to it, as along a program). Returns ACCURA_OK when every pose succeeded, else the
 * status of the first that failed (the others are still computed); *n_ok (may be NULL)
 * counts the successes. */
ACCURA_API accura_status accura_compensate_poses(accura_model* model, const accura_pose* targets,
                                                 const accura_configuration* configurations,
                                                 size_t n, int continuous,
                                                 accura_pose_result* results, size_t* n_ok);

/* ---------------------------------------------------------------------------------------- */
/* Continuous paths: compensation and auxiliary points */

/* ACCURA_PTP only in programs written by accura_write_program (a path is LIN and CIRC). */
typedef enum accura_motion_type { ACCURA_LIN = 0, ACCURA_CIRC = 1, ACCURA_PTP = 2 } accura_motion_type;

/* One motion of a path; it starts where the previous one ends (the first at the path's
 * start). `aux` is the CIRC auxiliary point (its orientation is not used); ignored for LIN. */
typedef struct accura_path_motion {
  int type; /* accura_motion_type */
  accura_pose aux;
  accura_pose end;
} accura_path_motion;

/* One motion to send, in order: the compensated, densified path. */
typedef struct accura_path_point {
  int type;          /* accura_motion_type */
  accura_pose aux;   /* CIRC: the compensated auxiliary point */
  accura_pose end;   /* the compensated end point (program base frame) */
  accura_configuration configuration; /* S/T of the real joints at `end` */
  int motion;        /* index of the intended motion it belongs to */
  int inserted;      /* 1: an auxiliary point added inside the motion, 0: its end point */
} accura_path_point;

typedef struct accura_motion_report {
  double length_mm;                  /* of the intended motion */
  double max_error_uncompensated_mm; /* the path as it is, run on the real robot */
  double max_error_before_mm;        /* end points compensated, no auxiliary points */
  double max_error_after_mm;         /* with the auxiliary points (largest sampled error) */
  double max_error_bound_mm;         /* bound between the samples too (<= tol_mm) */
  int points_added;
} accura_motion_report;

typedef struct accura_path_result {
  accura_pose start_command;         /* the compensated start: send it first (e.g. PTP) */
  accura_configuration start_configuration;
  size_t n_points;                   /* motions to send (points written or needed) */
  double max_error_uncompensated_mm; /* maxima over the motions (mm) */
  double max_error_before_mm;
  double max_error_after_mm;
  double max_error_bound_mm;
  int points_added;
  int failed_motion;                 /* index of the motion that failed, -1 when none */
} accura_path_result;

/* Compensates a path from `start` through `n_motions` LIN / CIRC motions and inserts
 * auxiliary points until the predicted deviation of the real tool from the intended path is
 * below tol_mm (in [0.001, 100]) everywhere (see docs/compensation.md). The start is solved as
 * accura_compensate_pose solves a pose (a UR arm: only the Status of `start_configuration`);
 * every point after it continues on the solution nearest the joints before. Writes up to `capacity` points
 * (`points` may be NULL when capacity is 0); when more are needed returns
 * ACCURA_ERROR_BUFFER_TOO_SMALL with result->n_points the count needed (call again).
 * `reports` (NULL or n_motions entries) gets each motion's numbers. `start_configuration`
 * NULL: any. On a failing motion: its status (ACCURA_ERROR_NUMERICAL for a CIRC whose start,
 * auxiliary and end point are collinear or coincide), result->failed_motion set and the
 * message naming it ("motion 1 cannot be compensated: ..."). */
ACCURA_API accura_status accura_compensate_path(accura_model* model, const accura_pose* start,
                                                const accura_configuration* start_configuration,
                                                const accura_path_motion* motions, size_t n_motions,
                                                double tol_mm, accura_path_point* points,
                                                size_t capacity, accura_path_result* result,
                                                accura_motion_report* reports);

/* ---------------------------------------------------------------------------------------- */
/* Programs */

typedef struct accura_program_options {
  size_t struct_size;      /* sizeof(accura_program_options), set by accura_program_options_init */
  const char* dat_path;    /* KRL: the .dat (NULL: next to the .src) */
  const char* config_path; /* $config.dat: TOOL_DATA / BASE_DATA (NULL: none) */
  double tol_mm;           /* path tolerance (mm, in [0.001, 100]; default 0.05) */
  const char* json_report_path; /* NULL: none; else the report of `accura compensate --json`,
                                   the same bytes for the same program and settings */
} accura_program_options;
ACCURA_API accura_status accura_program_options_init(accura_program_options* options, size_t struct_size);

typedef struct accura_program_summary {
  int targets_corrected;
  int points_added;
  int segments;
  int warnings;
  double max_correction_mm, rms_correction_mm, max_correction_deg;
  double max_error_uncompensated_mm, max_error_before_mm, max_error_after_mm;
  char output_path[1024];  /* the program written (the .src or .xml; NUL-terminated) */
} accura_program_summary;

/* Compensates a program file (KRL .src with its .dat, or XML: by the extension) into
 * out_dir (created when missing) under the same file name, as `accura compensate` does with
 * the model's settings: every file through a temporary file renamed into place, the input
 * never overwritten (ACCURA_ERROR_INPUT when out_dir would overwrite it). ACCURA_ERROR_INPUT
 * for a missing or malformed program and for targets that cannot be compensated (the message
 * lists each with file:line:column). `summary` may be NULL. */
ACCURA_API accura_status accura_compensate_program(accura_model* model, const char* program_path,
                                                   const char* out_dir,
                                                   const accura_program_options* options,
                                                   accura_program_summary* summary);

/* The same for an ABB RAPID module with the other modules of its task (`accura compensate
 * --config` given once per module: CalibData.mod, user.sys, a module of global robtargets;
 * docs/rapid.md): `task_modules`, `n_task_modules` paths (each read only, never written), taken
 * after options->config_path when that is set. A name two of them declare global is
 * ACCURA_ERROR_INPUT naming both places; a KRL or XML program with more than one $config.dat
 * too (the controller has one). n_task_modules 0: accura_compensate_program. */
ACCURA_API accura_status accura_compensate_program_modules(accura_model* model, const char* program_path,
                                                           const char* out_dir,
                                                           const accura_program_options* options,
                                                           const char* const* task_modules,
                                                           size_t n_task_modules,
                                                           accura_program_summary* summary);

/* ---------------------------------------------------------------------------------------- */
/* Reach and clearance checks (docs/checks.md) */

typedef enum accura_check_kind {
  ACCURA_CHECK_REACH = 0,
  ACCURA_CHECK_JOINT_LIMIT = 1,
  ACCURA_CHECK_SINGULARITY = 2,
  ACCURA_CHECK_CLEARANCE = 3
} accura_check_kind;

typedef struct accura_check_options {
  size_t struct_size;      /* sizeof(accura_check_options), set by accura_check_options_init */
  const char* dat_path;    /* as in accura_program_options */
  const char* config_path;
  int as_written;          /* 0: the targets are where the tool must go (an OLP program before
                              compensation); 1: the program runs as written (compensated) */
  int use_cell_thresholds; /* 1 (default): the thresholds of the cell file; 0: those below */
  double joint_margin_deg; /* required distance from the joint limits (deg / mm) */
  double singular_threshold; /* smallest singular value of the scaled Jacobian (dimensionless) */
  double min_clearance_mm; /* required distance between robot and cell objects (mm) */
} accura_check_options;
ACCURA_API accura_status accura_check_options_init(accura_check_options* options, size_t struct_size);

typedef struct accura_check_violation {
  int kind;                /* accura_check_kind */
  int motion_index;        /* 0-based motion of the program */
  int line, column;        /* of the motion statement in its file */
  int on_path;             /* 1: between the motion's start and end; 0: at the end point */
  double s;                /* path parameter in [0, 1] */
  double p_world_tcp_mm[3];
  double value, limit;     /* the measured quantity and its threshold (unit as check.h) */
  int joint;               /* joint_limit: 0-based joint; else -1 */
  char message[512];       /* one line (truncated, NUL-terminated) */
} accura_check_violation;

typedef struct accura_check_summary {
  int passed;              /* 1: no violation and every motion checked */
  size_t n_violations;     /* violations found (written or needed) */
  int unchecked;           /* motions that could not be checked */
  int samples;
  double min_clearance_mm; /* over all samples (a huge value without cell geometry) */
  double min_sigma;
  double min_joint_margin;
} accura_check_summary;

/* Checks a program (KRL or XML) in its cell (a cell file, docs/cell-format.md) with the
 * model and its frames: reach on the calibrated model, joint limits, singularities, and the
 * clearance between the robot and the cell's objects along every path. The check's findings
 * are data, not errors: ACCURA_OK with summary->passed 0 when there are violations. Writes up
 * to `capacity` violations (`violations` may be NULL when capacity is 0);
 * ACCURA_ERROR_BUFFER_TOO_SMALL when there are more (summary->n_violations says how many).
 * ACCURA_ERROR_INPUT for a missing or malformed cell or program file. */
ACCURA_API accura_status accura_check_program(accura_model* model, const char* cell_path,
                                              const char* program_path,
                                              const accura_check_options* options,
                                              accura_check_summary* summary,
                                              accura_check_violation* violations, size_t capacity);

/* ---------------------------------------------------------------------------------------- */
/* Writing programs */

/* One motion of a program to write (program base frame, T_base_tcp). */
typedef struct accura_program_motion {
  int type;          /* accura_motion_type: ACCURA_PTP, ACCURA_LIN or ACCURA_CIRC */
  accura_pose aux;   /* CIRC: the auxiliary point; ignored otherwise */
  accura_pose end;
  int approximate;   /* 1: approximated (KRL C_PTP for PTP, C_DIS for LIN / CIRC) */
  double vel_m_s;    /* LIN / CIRC path speed (m/s, up to 10; <= 0: not set) */
  /* The arm's joint values at `end` (deg / mm; n_joints 0: none, else the dof of the model
   * loaded on the handle): the configuration the arm takes there. A PTP carries it in the
   * controller's terms (KRL: S and T of its target, accura_joint_configuration); LIN and CIRC
   * keep the configuration they start in and do not use it. The joints must put the tool
   * (accura_write_options, with the placement's $ROBROOT) on `end` within 0.01 mm and
   * 0.01 deg: ACCURA_ERROR_INVALID_ARGUMENT otherwise, and without a loaded model. */
  int n_joints;
  double joints[ACCURA_MAX_JOINTS];
} accura_program_motion;

typedef struct accura_write_options {
  size_t struct_size;        /* sizeof(accura_write_options), set by accura_write_options_init */
  const char* program_name;  /* NULL: the file name without its extension; an identifier (a letter, _ or $, then letters, digits, _ or $; at most 64 characters), else ACCURA_ERROR_INVALID_ARGUMENT */
  accura_pose tool;          /* $TOOL (T_flange_tcp) of every motion */
  accura_pose base;          /* $BASE of every motion (relative to $WORLD; default identity) */
} accura_write_options;
ACCURA_API accura_status accura_write_options_init(accura_write_options* options, size_t struct_size);

/* Writes a new program in the controller language of the path's extension (.src: KUKA KRL,
 * with the .dat next to it; .xml: accura's XML program; .script: URScript; .mod or .prg: ABB
 * RAPID; the extension in any case) with the writers of `accura compensate` and `accura
 * convert` (KRL and XML values at 1e-4 mm and 1e-5 deg; a URScript or RAPID program's first
 * comment says "written by the accura plug-in (accura_write_program)"), every file through a
 * temporary file renamed into place. ACCURA_ERROR_INVALID_ARGUMENT for a motion type or pose
 * that is not valid, ACCURA_ERROR_INPUT for another extension or a file that cannot be
 * written. `model` holds
 * the error message (no model need be loaded, except for motions with joint values; a loaded
 * model names the robot of an XML program). */
ACCURA_API accura_status accura_write_program(accura_model* model, const char* path, const accura_program_motion* motions,
                                              size_t n_motions, const accura_write_options* options);

/* Writes `size` bytes to `path` (its directory created) through a temporary file renamed
 * into place: the one writer of accura's outputs, for a host's own files (e.g. a kinematic
 * table). ACCURA_ERROR_INPUT when the file cannot be written. */
ACCURA_API accura_status accura_write_file(accura_model* model, const char* path, const char* data, size_t size);

#ifdef __cplusplus
}
#endif

#endif /* ACCURA_PLUGIN_H */
