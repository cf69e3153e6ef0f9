// accura plug-in: the C interface (plugin/include/accura_plugin.h), a shell over postproc's
// Session (accura/postproc/session.h), where the frames, the models, the path loop, the
// validation of values, the registry of live handles and what every call does around its work
// (SessionRegistry::run / runOn / withSession: handle lookup, exceptions -> status and the
// calling thread's last error) live. Here: C structs <-> C++ values, the C-only checks.
// An accura_model* is a SessionRegistry key, never dereferenced.
#include "accura_plugin.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "accura/calib/file_io.h"
#include "accura/postproc/session.h"

using namespace accura;
using namespace accura::postproc;
using Slot = SessionRegistry::Slot;

static_assert(static_cast<int>(CallStatus::kInternal) == ACCURA_ERROR_INTERNAL && static_cast<int>(CallStatus::kInput) == ACCURA_ERROR_INPUT &&
                  static_cast<int>(CallStatus::kNotConverged) == ACCURA_ERROR_NOT_CONVERGED,
              "CallStatus is accura_status, value for value");
static_assert(static_cast<int>(CheckKind::kClearance) == ACCURA_CHECK_CLEARANCE, "CheckKind is accura_check_kind, value for value");

namespace {

SessionRegistry& registry() { return SessionRegistry::instance(); }
std::uintptr_t keyOf(const accura_model* m) { return reinterpret_cast<std::uintptr_t>(m); }
accura_status cstatus(CallStatus s) { return static_cast<accura_status>(s); }

/// SessionRegistry::run(), runOn() and withSession() with the C status.
template <class F>
accura_status run(const char* fn, F&& body) noexcept { return cstatus(SessionRegistry::run(fn, body)); }
template <class F>
accura_status guarded(const accura_model* model, const char* fn, F&& body) noexcept { return cstatus(registry().runOn(keyOf(model), fn, body)); }
template <class F>
accura_status withSession(const accura_model* model, const char* fn, CallPointers pointers, F&& body) noexcept {
  return cstatus(registry().withSession(keyOf(model), fn, pointers, body));
}

calib::XyzAbc xyz(const accura_pose& p) { return {p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg}; }
accura_pose cpose(const calib::XyzAbc& p) { return {p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg}; }
accura_configuration cconfig(const calib::Configuration& c) { return {c.status, c.turn}; }
calib::Configuration configOf(const accura_configuration* c, int dof) { return c ? checkedConfiguration(c->status, c->turn, dof) : calib::Configuration{}; }

void copyString(char* dst, size_t cap, const std::string& s) {
  const size_t n = std::min(cap - 1, s.size());
  std::memcpy(dst, s.data(), n);
  dst[n] = '\0';
}

/// The value a C caller gave an enum parameter or field, read as an int: any int is valid C,
/// but loading a value outside the enum's range as the enum is undefined behaviour in C++
/// (UBSan -fsanitize=enum reports it: issue 14's sanitizer build).
template <class E>
int cEnum(const E& e) {
  static_assert(sizeof(E) == sizeof(int), "C enums are int-sized");
  int v;
  std::memcpy(&v, &e, sizeof v);
  return v;
}

/// The motion type of motions[i] (LIN, CIRC and, when `ptp`, PTP).
int motionType(int type, size_t i, bool ptp) {
  return checkedInt(type, type == ACCURA_LIN || type == ACCURA_CIRC || (ptp && type == ACCURA_PTP), "motions[" + std::to_string(i) + "].type",
                    ptp ? "ACCURA_LIN, ACCURA_CIRC or ACCURA_PTP" : "ACCURA_LIN (0) or ACCURA_CIRC (1)");
}

/// The *_options_init functions: zeros, struct_size, then the defaults.
template <class O, class F>
accura_status initOptions(O* o, size_t struct_size, const char* fn, F&& defaults) noexcept {
  return run(fn, [&] {
    requirePointers({{o, "options"}});
    if (struct_size != sizeof(O))
      throw calib::ArgumentError("struct_size " + std::to_string(struct_size) + ", expected " + std::to_string(sizeof(O)));
    std::memset(o, 0, sizeof(O));
    o->struct_size = sizeof(O);
    defaults(*o);
  });
}

/// The caller's options (NULL: the defaults of `init`), their struct_size checked.
template <class O>
O optionsOr(const O* given, accura_status (*init)(O*, size_t), const char* what) {
  O o;
  init(&o, sizeof(O));
  if (given && given->struct_size != sizeof(O))
    throw calib::ArgumentError(std::string(what) + ": struct_size " + std::to_string(given->struct_size) + " does not match this library's " +
                               std::to_string(sizeof(O)) + " (header and library of different versions?)");
  return given ? *given : o;
}

/// The result with its padding zeroed: hosts may compare results byte for byte.
void fillPoseResult(const SessionPose& p, int dof, accura_pose_result* r) {
  std::memset(r, 0, sizeof *r);
  r->status = cstatus(callStatus(p.status));
  r->dof = dof;
  if (p.status != calib::IkStatus::kOk) return;
  r->command = cpose(p.command);
  r->configuration = cconfig(p.configuration);
  r->configuration_changed = p.configuration_changed ? 1 : 0;
  r->correction_mm = p.correction_mm;
  r->correction_deg = p.correction_deg;
  for (int i = 0; i < p.q_real.size() && i < ACCURA_MAX_JOINTS; ++i) r->q_real[i] = p.q_real[i];
}

ProgramReadOptions readOptions(const char* dat_path, const char* config_path) {
  ProgramReadOptions o;
  o.dat_path = dat_path ? dat_path : "";
  o.config_path = config_path ? config_path : "";
  return o;
}

}  // namespace

extern "C" {

ACCURA_API accura_status accura_version(int* major, int* minor, int* patch, int* abi_version) {
  if (major) *major = ACCURA_VERSION_MAJOR;
  if (minor) *minor = ACCURA_VERSION_MINOR;
  if (patch) *patch = ACCURA_VERSION_PATCH;
  if (abi_version) *abi_version = ACCURA_PLUGIN_ABI_VERSION;
  return ACCURA_OK;
}

ACCURA_API accura_status accura_status_name(accura_status status, const char** name_out) {
  static const char* const kNames[] = {"ACCURA_OK", "ACCURA_ERROR_NULL_ARGUMENT", "ACCURA_ERROR_INVALID_ARGUMENT",
                                       "ACCURA_ERROR_BUFFER_TOO_SMALL", "ACCURA_ERROR_INPUT", "ACCURA_ERROR_UNREACHABLE",
                                       "ACCURA_ERROR_JOINT_LIMITS", "ACCURA_ERROR_SINGULAR", "ACCURA_ERROR_NO_CONFIGURATION",
                                       "ACCURA_ERROR_NOT_CONVERGED", "ACCURA_ERROR_NUMERICAL", "ACCURA_ERROR_OUT_OF_MEMORY",
                                       "ACCURA_ERROR_INTERNAL"};
  return run("accura_status_name", [&] {
    requirePointers({{name_out, "name_out"}});
    const int s = cEnum(status);
    const bool known = s >= 0 && s < static_cast<int>(sizeof(kNames) / sizeof(kNames[0]));
    *name_out = known ? kNames[s] : "ACCURA_STATUS_UNKNOWN";
    if (!known) throw calib::ArgumentError("unknown status " + std::to_string(s));
  });
}

ACCURA_API accura_status accura_last_error(const accura_model* model, const char** message_out) {
  return message_out ? cstatus(registry().lastError(keyOf(model), message_out)) : ACCURA_ERROR_NULL_ARGUMENT;
}

ACCURA_API accura_status accura_model_create(accura_model** model_out) {
  return run("accura_model_create", [&] {
    requirePointers({{model_out, "model_out"}});
    *model_out = nullptr;
    *model_out = reinterpret_cast<accura_model*>(registry().create());
  });
}

ACCURA_API accura_status accura_model_free(accura_model* model) {
  return run("accura_model_free", [&] { registry().release(keyOf(model)); });
}

ACCURA_API accura_status accura_load_options_init(accura_load_options* o, size_t struct_size) {
  return initOptions(o, struct_size, "accura_load_options_init", [](accura_load_options& x) { x.temp_c = calib::kThermalReferenceC; });
}

ACCURA_API accura_status accura_model_load(accura_model* model, const char* calibrated_model, const accura_load_options* options) {
  return guarded(model, "accura_model_load", [&](Slot& slot) {
    requirePointers({{calibrated_model, "calibrated_model"}});
    const accura_load_options o = optionsOr(options, accura_load_options_init, "accura_load_options");
    SessionSettings s;
    s.calibrated_model = calibrated_model;
    if (o.controller_model) s.controller_model = o.controller_model;
    if (o.has_robroot_in_world) s.robroot_in_world = xyz(o.robroot_in_world);
    if (o.has_robroot_in_kukaworld) s.robroot_in_kukaworld = xyz(o.robroot_in_kukaworld);
    if (o.has_program_base) s.program_base = xyz(o.program_base);
    if (o.has_program_tool) s.program_tool = xyz(o.program_tool);
    s.payload_kg = o.payload_kg;
    s.temp_c = o.temp_c;
    s.max_joints = ACCURA_MAX_JOINTS;
    s.placement_setting = "robroot_in_world (accura_load_options)";
    slot.load(std::make_shared<const Session>(s));
  });
}

ACCURA_API accura_status accura_model_get_info(accura_model* model, accura_model_info* info) {
  return withSession(model, "accura_model_get_info", {{info, "info"}}, [&](const Session& s) {
    const calib::RobotModel& m = s.job().calibrated;
    *info = accura_model_info{};
    info->dof = m.dof();
    copyString(info->robot_name, sizeof(info->robot_name), m.nominal.name);
    info->robroot_in_world = cpose(calib::toXyzAbc(s.placement().T_world_robroot));
    info->calibrated_base_in_world = cpose(calib::toXyzAbc(m.T_world_base()));
    for (int i = 0; i < m.dof(); ++i) {
      info->lower[i] = m.nominal.joints[i].lower;
      info->upper[i] = m.nominal.joints[i].upper;
    }
  });
}

ACCURA_API accura_status accura_model_get_joints(accura_model* model, accura_joint* joints, size_t capacity, size_t* n_joints) {
  return withSession(model, "accura_model_get_joints", {{ifAny(capacity, joints), "joints"}}, [&](const Session& s) {
    const std::vector<calib::JointSpec>& js = s.job().calibrated.nominal.joints;
    if (n_joints) *n_joints = js.size();
    for (size_t i = 0; i < js.size() && i < capacity; ++i)
      joints[i] = {js[i].type == calib::JointType::kPrismatic ? 1 : 0, js[i].a_mm, js[i].alpha_deg, js[i].d_mm, js[i].theta0_deg,
                   js[i].direction, js[i].lower, js[i].upper};
    requireCapacity(js.size(), capacity, "the robot has " + std::to_string(js.size()) + " joints");
  });
}

ACCURA_API accura_status accura_forward_kinematics(accura_model* model, accura_which_model which, const double* q, size_t n_joints,
                                                   accura_pose* pose_out) {
  return withSession(model, "accura_forward_kinematics", {{q, "q"}, {pose_out, "pose_out"}}, [&](const Session& s) {
    const std::vector<double> qv = s.joints(q, n_joints);
    const int w = cEnum(which);
    checkedInt(w, w == ACCURA_CONTROLLER || w == ACCURA_REAL, "which", "ACCURA_CONTROLLER (0) or ACCURA_REAL (1)");
    *pose_out = cpose(s.forward(w == ACCURA_REAL, qv));
  });
}

ACCURA_API accura_status accura_joint_configuration(accura_model* model, const double* q, size_t n_joints,
                                                    accura_configuration* configuration_out) {
  return withSession(model, "accura_joint_configuration", {{q, "q"}, {configuration_out, "configuration_out"}}, [&](const Session& s) {
    *configuration_out = cconfig(s.configuration(s.joints(q, n_joints)));
  });
}

ACCURA_API accura_status accura_compensate_pose(accura_model* model, const accura_pose* target, const accura_configuration* configuration,
                                                accura_pose_result* result) {
  return withSession(model, "accura_compensate_pose", {{target, "target"}, {result, "result"}}, [&](const Session& s) {
    const SessionPose p = s.pose(xyz(*target), configOf(configuration, s.dof()));
    fillPoseResult(p, s.dof(), result);
    if (p.status != calib::IkStatus::kOk) throw CallError(callStatus(p.status), p.message);
  });
}

ACCURA_API accura_status accura_compensate_poses(accura_model* model, const accura_pose* targets,
                                                 const accura_configuration* configurations, size_t n, int continuous,
                                                 accura_pose_result* results, size_t* n_ok) {
  return guarded(model, "accura_compensate_poses", [&](Slot& slot) {
    if (n_ok) *n_ok = 0;
    if (n == 0) return;
    requirePointers({{targets, "targets"}, {results, "results"}});
    const auto s = slot.loaded();
    std::vector<calib::XyzAbc> t(n);
    std::vector<calib::Configuration> c(configurations ? n : 0);
    for (size_t i = 0; i < n; ++i) t[i] = xyz(targets[i]);
    for (size_t i = 0; i < c.size(); ++i) c[i] = configOf(&configurations[i], s->dof());
    const SessionPoses r = s->poses(t, c, continuous != 0);
    for (size_t i = 0; i < n; ++i) fillPoseResult(r.results[i], s->dof(), &results[i]);
    if (n_ok) *n_ok = r.n_ok;
    if (r.first_failed >= 0) throw CallError(callStatus(r.results[r.first_failed].status), r.message);
  });
}

ACCURA_API accura_status accura_compensate_path(accura_model* model, const accura_pose* start,
                                                const accura_configuration* start_configuration, const accura_path_motion* motions,
                                                size_t n_motions, double tol_mm, accura_path_point* points, size_t capacity,
                                                accura_path_result* result, accura_motion_report* reports) {
  return guarded(model, "accura_compensate_path", [&](Slot& slot) {
    requirePointers({{start, "start"}, {result, "result"}, {ifAny(n_motions, motions), "motions"}, {ifAny(capacity, points), "points"}});
    *result = accura_path_result{};
    result->failed_motion = -1;
    const auto s = slot.loaded();
    std::vector<SessionMotion> m(n_motions);
    for (size_t i = 0; i < n_motions; ++i)
      m[i] = {motionType(cEnum(motions[i].type), i, false) == ACCURA_CIRC ? PathType::kCirc : PathType::kLin, xyz(motions[i].aux),
              xyz(motions[i].end)};
    for (size_t i = 0; reports && i < n_motions; ++i) reports[i] = accura_motion_report{};
    const SessionPath p = s->path(xyz(*start), configOf(start_configuration, s->dof()), m, tol_mm);
    result->failed_motion = p.failed_motion;
    if (!p.ok())
      throw CallError(p.numerical ? CallStatus::kNumerical : p.status == calib::IkStatus::kOk ? CallStatus::kInternal : callStatus(p.status),
                      p.message);
    const SessionMotionNumbers& t = p.total;
    *result = {cpose(p.start.command), cconfig(p.start.configuration), p.points.size(), t.max_error_uncompensated_mm,
               t.max_error_before_mm,  t.max_error_after_mm,            t.max_error_bound_mm, t.points_added, -1};
    for (size_t i = 0; reports && i < n_motions; ++i) {
      const SessionMotionNumbers& n = p.motions[i];
      reports[i] = {n.length_mm, n.max_error_uncompensated_mm, n.max_error_before_mm, n.max_error_after_mm, n.max_error_bound_mm, n.points_added};
    }
    requireCapacity(p.points.size(), capacity, "the path has " + std::to_string(p.points.size()) + " points");
    for (size_t i = 0; i < p.points.size(); ++i) {
      const SessionPathPoint& q = p.points[i];
      accura_path_point& c = points[i];
      std::memset(&c, 0, sizeof c);  // padding too (as fillPoseResult)
      c.type = q.type == PathType::kCirc ? ACCURA_CIRC : ACCURA_LIN;
      c.aux = cpose(q.aux);
      c.end = cpose(q.end);
      c.configuration = cconfig(q.configuration);
      c.motion = q.motion;
      c.inserted = q.inserted ? 1 : 0;
    }
  });
}

ACCURA_API accura_status accura_program_options_init(accura_program_options* o, size_t struct_size) {
  return initOptions(o, struct_size, "accura_program_options_init", [](accura_program_options& x) { x.tol_mm = 0.05; });
}

namespace {
/// accura_compensate_program and accura_compensate_program_modules, their errors prefixed with
/// `function`.
accura_status compensateProgram(const char* function, accura_model* model, const char* program_path, const char* out_dir,
                                const accura_program_options* options, const char* const* task_modules, size_t n_task_modules,
                                accura_program_summary* summary) {
  return guarded(model, function, [&](Slot& slot) {
    requirePointers({{program_path, "program_path"}, {out_dir, "out_dir"}, {ifAny(n_task_modules, task_modules), "task_modules"}});
    // (an empty out_dir would be the host process's working directory, wherever that is)
    if (!*out_dir) throw calib::ArgumentError("out_dir: expected an output directory, found an empty string");
    const accura_program_options o = optionsOr(options, accura_program_options_init, "accura_program_options");
    ProgramFileRequest q;
    q.in_path = program_path;
    q.out_dir = out_dir;
    q.read = readOptions(o.dat_path, o.config_path);
    for (size_t i = 0; i < n_task_modules; ++i) {
      if (!task_modules[i]) throw CallError(CallStatus::kNullArgument, "task_modules[" + std::to_string(i) + "] is NULL");
      if (q.read.config_path.empty()) q.read.config_path = task_modules[i];
      else q.read.more_config_paths.push_back(task_modules[i]);
    }
    if (o.json_report_path) q.json_path = o.json_report_path;
    q.out_name = "out_dir";
    q.json_name = "json_report_path";
    const ProgramFileResult result = slot.loaded()->compensateProgramFile(q, o.tol_mm);
    const JobReport& r = result.report;
    if (!summary) return;
    *summary = {r.targets_corrected,  r.points_added,           static_cast<int>(r.segments.size()), static_cast<int>(r.warnings.size()),
                r.max_correction_mm, r.rms_correction_mm,      r.max_correction_deg,                r.max_error_uncompensated_mm,
                r.max_error_before_mm, r.max_error_after_mm, {}};
    copyString(summary->output_path, sizeof(summary->output_path),
               result.checked.files.empty() ? std::string() : result.checked.files.front().path);
  });
}
}  // namespace

ACCURA_API accura_status accura_compensate_program(accura_model* model, const char* program_path, const char* out_dir,
                                                   const accura_program_options* options, accura_program_summary* summary) {
  return compensateProgram("accura_compensate_program", model, program_path, out_dir, options, nullptr, 0, summary);
}

ACCURA_API accura_status accura_compensate_program_modules(accura_model* model, const char* program_path, const char* out_dir,
                                                           const accura_program_options* options, const char* const* task_modules,
                                                           size_t n_task_modules, accura_program_summary* summary) {
  return compensateProgram("accura_compensate_program_modules", model, program_path, out_dir, options, task_modules, n_task_modules, summary);
}

ACCURA_API accura_status accura_check_options_init(accura_check_options* o, size_t struct_size) {
  return initOptions(o, struct_size, "accura_check_options_init", [](accura_check_options& x) {
    const CheckThresholds t;
    x.use_cell_thresholds = 1;
    x.joint_margin_deg = t.joint_margin_deg;
    x.singular_threshold = t.singular_threshold;
    x.min_clearance_mm = t.min_clearance_mm;
  });
}

ACCURA_API accura_status accura_check_program(accura_model* model, const char* cell_path, const char* program_path,
                                              const accura_check_options* options, accura_check_summary* summary,
                                              accura_check_violation* violations, size_t capacity) {
  return guarded(model, "accura_check_program", [&](Slot& slot) {
    requirePointers({{cell_path, "cell_path"}, {program_path, "program_path"}, {summary, "summary"}, {ifAny(capacity, violations), "violations"}});
    const accura_check_options o = optionsOr(options, accura_check_options_init, "accura_check_options");
    std::optional<CheckThresholds> thresholds;
    if (!o.use_cell_thresholds) thresholds = CheckThresholds{o.joint_margin_deg, o.singular_threshold, o.min_clearance_mm};
    const CheckReport r = slot.loaded()->checkProgramFile(cell_path, program_path, readOptions(o.dat_path, o.config_path),
                                                          o.as_written ? CheckMode::kAsWritten : CheckMode::kIntended, thresholds);
    *summary = {r.passed() ? 1 : 0, r.violations.size(), static_cast<int>(r.unchecked.size()), r.samples,
                std::isfinite(r.min_clearance_mm) ? r.min_clearance_mm : 1e300, r.min_sigma, r.min_joint_margin};
    for (size_t i = 0; i < r.violations.size() && i < capacity; ++i) {
      const CheckViolation& v = r.violations[i];
      const Eigen::Vector3d& p = v.p_world_tcp_mm;
      violations[i] = {static_cast<int>(v.kind), v.motion_index, v.where.line, v.where.column, v.on_path ? 1 : 0, v.s, {p[0], p[1], p[2]},
                       v.value, v.limit, v.joint, {}};
      copyString(violations[i].message, sizeof(violations[i].message), v.message);
    }
    requireCapacity(r.violations.size(), capacity, std::to_string(r.violations.size()) + " violations", " (summary->n_violations)");
  });
}

ACCURA_API accura_status accura_write_options_init(accura_write_options* o, size_t struct_size) {
  return initOptions(o, struct_size, "accura_write_options_init", [](accura_write_options&) {});
}

ACCURA_API accura_status accura_write_program(accura_model* model, const char* path, const accura_program_motion* motions,
                                              size_t n_motions, const accura_write_options* options) {
  return guarded(model, "accura_write_program", [&](Slot& slot) {
    requirePointers({{path, "path"}, {options, "options"}, {ifAny(n_motions, motions), "motions"}});
    const accura_write_options o = optionsOr(options, accura_write_options_init, "accura_write_options");
    PoseProgram p;
    if (o.program_name) p.name = o.program_name;
    p.tool = xyz(o.tool);
    p.base = xyz(o.base);
    for (size_t i = 0; i < n_motions; ++i) {
      const accura_program_motion& c = motions[i];
      const int type = motionType(cEnum(c.type), i, true);
      checkedInt(c.n_joints, c.n_joints >= 0 && c.n_joints <= ACCURA_MAX_JOINTS, "motions[" + std::to_string(i) + "].n_joints",
                 "0.." + std::to_string(ACCURA_MAX_JOINTS));
      const MotionType t = type == ACCURA_PTP ? MotionType::kPtp : type == ACCURA_CIRC ? MotionType::kCirc : MotionType::kLin;
      p.motions.push_back({t, xyz(c.aux), xyz(c.end), c.approximate != 0, c.vel_m_s, std::vector<double>(c.joints, c.joints + c.n_joints)});
    }
    writePoseProgram(path, p, slot.session().get());  // a session is optional: it names the robot, gives S/T
  });
}

ACCURA_API accura_status accura_write_file(accura_model* model, const char* path, const char* data, size_t size) {
  return guarded(model, "accura_write_file", [&](Slot&) {
    requirePointers({{path, "path"}, {ifAny(size, data), "data"}});
    calib::createDirectories(std::filesystem::path(path).parent_path().string());
    calib::writeFilesAtomically({{path, std::string(data ? data : "", size)}});
  });
}

}  // extern "C"
