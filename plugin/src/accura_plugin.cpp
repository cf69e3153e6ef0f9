// accura plug-in: the C interface (plugin/include/accura_plugin.h) over calib and postproc.
//
// Every exported function runs its body inside guarded(): C++ exceptions (std::bad_alloc
// included) become a status and a message stored for the calling thread in the handle.
#include "accura_plugin.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <mutex>
#include <new>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/robot_io.h"
#include "accura/postproc/batch.h"
#include "accura/postproc/cell.h"
#include "accura/postproc/check.h"
#include "accura/postproc/compensate.h"
#include "accura/postproc/job.h"
#include "accura/postproc/path_job.h"
#include "accura/postproc/placement.h"
#include "accura/postproc/program_io.h"

#ifndef ACCURA_VERSION_MAJOR
#define ACCURA_VERSION_MAJOR 0
#define ACCURA_VERSION_MINOR 0
#define ACCURA_VERSION_PATCH 0
#endif

namespace fs = std::filesystem;
using namespace accura;
using namespace accura::postproc;

namespace {

/// A failure with its status (thrown inside the guarded bodies).
struct PluginError {
  accura_status status;
  std::string message;
};

[[noreturn]] void fail(accura_status s, const std::string& message) { throw PluginError{s, message}; }

/// The immutable model of a handle: everything a compensation call needs.
struct State {
  JobSettings job;                       ///< the settings of accura compensate
  Eigen::Isometry3d T_world_progbase;    ///< $BASE of the poses and paths in the world
  std::unique_ptr<ModelFactory> models;  ///< the placement and the models (placement.h)
  /// The models of the $TOOL of the poses and paths, with their Compensator (built at load:
  /// nothing in State changes afterwards, so that threads share it).
  const ToolModels* tool = nullptr;
};

}  // namespace

struct accura_model {
  std::mutex mutex;                      ///< guards state (the pointer) and errors
  std::shared_ptr<const State> state;
  std::unordered_map<std::thread::id, std::string> errors;
};

namespace {

void setError(accura_model* m, const std::string& message) noexcept {
  if (!m) return;
  try {
    std::lock_guard<std::mutex> lock(m->mutex);
    m->errors[std::this_thread::get_id()] = message;
  } catch (...) {  // out of memory while storing the message: the status still says it
  }
}

template <class F>
accura_status guarded(accura_model* m, const char* fn, F&& body) noexcept {
  try {
    return body();
  } catch (const PluginError& e) {
    setError(m, std::string(fn) + ": " + e.message);
    return e.status;
  } catch (const calib::InputError& e) {
    setError(m, std::string(fn) + ": " + e.what());
    return ACCURA_ERROR_INPUT;
  } catch (const calib::ArgumentError& e) {
    setError(m, std::string(fn) + ": " + e.what());
    return ACCURA_ERROR_INVALID_ARGUMENT;
  } catch (const calib::NumericalError& e) {
    setError(m, std::string(fn) + ": " + e.what());
    return ACCURA_ERROR_NUMERICAL;
  } catch (const std::bad_alloc&) {
    setError(m, std::string(fn) + ": out of memory");
    return ACCURA_ERROR_OUT_OF_MEMORY;
  } catch (const std::exception& e) {
    setError(m, std::string(fn) + ": internal error: " + e.what());
    return ACCURA_ERROR_INTERNAL;
  } catch (...) {
    setError(m, std::string(fn) + ": internal error: unknown exception");
    return ACCURA_ERROR_INTERNAL;
  }
}

void need(const void* p, const char* what) {
  if (!p) fail(ACCURA_ERROR_NULL_ARGUMENT, std::string(what) + " is NULL");
}

std::shared_ptr<const State> stateOf(accura_model* m) {
  std::shared_ptr<const State> s;
  {
    std::lock_guard<std::mutex> lock(m->mutex);
    s = m->state;
  }
  if (!s) fail(ACCURA_ERROR_INVALID_ARGUMENT, "no model loaded on this handle (call accura_model_load first)");
  return s;
}

calib::XyzAbc toXyz(const accura_pose& p) { return {p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg}; }
accura_pose toC(const calib::XyzAbc& p) { return {p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg}; }

/// The pose as given (finite, else ACCURA_ERROR_INVALID_ARGUMENT naming `what`).
calib::XyzAbc checkedXyz(const accura_pose& p, const std::string& what) {
  const double v[6] = {p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg};
  for (double x : v)
    if (!std::isfinite(x)) fail(ACCURA_ERROR_INVALID_ARGUMENT, what + ": expected finite x, y, z (mm), A, B, C (deg), found a NaN or infinity");
  return toXyz(p);
}

Eigen::Isometry3d checkedPose(const accura_pose& p, const std::string& what) { return calib::toIsometry(checkedXyz(p, what)); }

/// S in 0..7 (three bits) or -1 (any), T in 0..2^dof - 1 (a bit per joint) or -1.
calib::Configuration configOf(const accura_configuration* c, int dof) {
  if (!c) return {};
  const long long max_turn = (1LL << std::min(dof, 30)) - 1;
  if (c->status < -1 || c->status > 7 || c->turn < -1 || c->turn > max_turn)
    fail(ACCURA_ERROR_INVALID_ARGUMENT, "configuration: expected S in 0..7 and T in 0.." + std::to_string(max_turn) +
                                            " (a bit per joint), or -1 (any), found S " + std::to_string(c->status) + ", T " +
                                            std::to_string(c->turn));
  return {c->status, c->turn};
}

accura_configuration toC(const calib::Configuration& c) { return {c.status, c.turn}; }

accura_status statusOf(calib::IkStatus s) {
  switch (s) {
    case calib::IkStatus::kOk: return ACCURA_OK;
    case calib::IkStatus::kUnreachable: return ACCURA_ERROR_UNREACHABLE;
    case calib::IkStatus::kJointLimits: return ACCURA_ERROR_JOINT_LIMITS;
    case calib::IkStatus::kSingular: return ACCURA_ERROR_SINGULAR;
    case calib::IkStatus::kNoConfiguration: return ACCURA_ERROR_NO_CONFIGURATION;
    case calib::IkStatus::kNotConverged: return ACCURA_ERROR_NOT_CONVERGED;
  }
  return ACCURA_ERROR_INTERNAL;
}

void copyString(char* dst, size_t cap, const std::string& s) {
  if (cap == 0) return;
  const size_t n = std::min(cap - 1, s.size());
  std::memcpy(dst, s.data(), n);
  dst[n] = '\0';
}

/// A robot file path or a bundled robot name; a path that does not exist is named as such.
std::string resolveModel(const std::string& name_or_path, const char* what) {
  std::error_code ec;
  const bool looks_like_path = name_or_path.find('/') != std::string::npos || fs::path(name_or_path).extension() == ".xml";
  if (looks_like_path && !fs::exists(name_or_path, ec))
    fail(ACCURA_ERROR_INPUT, name_or_path + ": the " + what + " file does not exist (expected a robot file, e.g. a calibrated model " +
                                 "written by accura identify, or a bundled robot name)");
  return calib::resolveRobotPath(name_or_path);
}

std::shared_ptr<State> buildState(const std::string& calibrated_path, const accura_load_options& o) {
  auto s = std::make_shared<State>();
  JobSettings& job = s->job;
  job.calibrated = calib::readRobotFile(resolveModel(calibrated_path, "calibrated_model"));
  if (job.calibrated.dof() > ACCURA_MAX_JOINTS)
    fail(ACCURA_ERROR_INPUT, calibrated_path + ": expected at most " + std::to_string(ACCURA_MAX_JOINTS) + " joints, found " +
                                 std::to_string(job.calibrated.dof()));
  if (o.controller_model) {
    const std::string p = o.controller_model;
    const calib::RobotModel controller = calib::readRobotFile(resolveModel(p, "controller_model"));
    checkControllerRobot(job.calibrated.nominal, controller.nominal, p);
  }
  if (o.has_robroot_in_world) job.robroot_in_world = toXyz(o.robroot_in_world);
  if (o.has_robroot_in_kukaworld) job.robroot_in_kukaworld = toXyz(o.robroot_in_kukaworld);
  if (o.has_program_base) job.initial_base = toXyz(o.program_base);
  if (o.has_program_tool) job.initial_tool = toXyz(o.program_tool);
  for (const auto* p : {&o.robroot_in_world, &o.robroot_in_kukaworld, &o.program_base, &o.program_tool}) checkedPose(*p, "load options");
  if (!(o.payload_kg >= 0) || !std::isfinite(o.payload_kg))
    fail(ACCURA_ERROR_INVALID_ARGUMENT, "payload_kg: expected a finite mass >= 0 (kg), found " + std::to_string(o.payload_kg));
  if (!std::isfinite(o.temp_c)) fail(ACCURA_ERROR_INVALID_ARGUMENT, "temp_c: expected a finite temperature (deg C)");
  job.context.payload_kg = o.payload_kg;
  job.context.temp_c = o.temp_c;

  // Frames and models as compensateProgram takes them (placement.h)
  s->models = std::make_unique<ModelFactory>(job, placeRobot(job, "robroot_in_world (accura_load_options)"));
  const Eigen::Isometry3d T_kworld_progbase = job.initial_base ? calib::toIsometry(*job.initial_base) : Eigen::Isometry3d::Identity();
  s->T_world_progbase = s->models->placement().T_world_kworld * T_kworld_progbase;
  s->tool = &s->models->compensator(job.initial_tool ? calib::toIsometry(*job.initial_tool) : job.calibrated.nominal.T_flange_tcp);
  return s;
}

void fillPoseResult(const State& s, const Eigen::Isometry3d& T_world_target, const PoseCompensation& pc, accura_pose_result* r) {
  *r = accura_pose_result{};
  r->status = statusOf(pc.status);
  r->dof = s.job.calibrated.dof();
  if (pc.status != calib::IkStatus::kOk) return;
  r->command = toC(calib::toXyzAbc(s.T_world_progbase.inverse() * pc.T_world_tcp_command));
  r->configuration = toC(pc.configuration);
  r->configuration_changed = pc.configuration_changed ? 1 : 0;
  r->correction_mm = (pc.T_world_tcp_command.translation() - T_world_target.translation()).norm();
  r->correction_deg = rotationAngleDeg(pc.T_world_tcp_command.linear() * T_world_target.linear().transpose());
  for (int i = 0; i < pc.q_real.size() && i < ACCURA_MAX_JOINTS; ++i) r->q_real[i] = pc.q_real[i];
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

const char* statusNameOf(int s) {
  switch (s) {
    case ACCURA_OK: return "ACCURA_OK";
    case ACCURA_ERROR_NULL_ARGUMENT: return "ACCURA_ERROR_NULL_ARGUMENT";
    case ACCURA_ERROR_INVALID_ARGUMENT: return "ACCURA_ERROR_INVALID_ARGUMENT";
    case ACCURA_ERROR_BUFFER_TOO_SMALL: return "ACCURA_ERROR_BUFFER_TOO_SMALL";
    case ACCURA_ERROR_INPUT: return "ACCURA_ERROR_INPUT";
    case ACCURA_ERROR_UNREACHABLE: return "ACCURA_ERROR_UNREACHABLE";
    case ACCURA_ERROR_JOINT_LIMITS: return "ACCURA_ERROR_JOINT_LIMITS";
    case ACCURA_ERROR_SINGULAR: return "ACCURA_ERROR_SINGULAR";
    case ACCURA_ERROR_NO_CONFIGURATION: return "ACCURA_ERROR_NO_CONFIGURATION";
    case ACCURA_ERROR_NOT_CONVERGED: return "ACCURA_ERROR_NOT_CONVERGED";
    case ACCURA_ERROR_NUMERICAL: return "ACCURA_ERROR_NUMERICAL";
    case ACCURA_ERROR_OUT_OF_MEMORY: return "ACCURA_ERROR_OUT_OF_MEMORY";
    case ACCURA_ERROR_INTERNAL: return "ACCURA_ERROR_INTERNAL";
  }
  return nullptr;
}

void makeParentDir(const std::string& path) {
  std::error_code ec;
  const fs::path dir = fs::path(path).parent_path();
  if (!dir.empty()) fs::create_directories(dir, ec);
  if (ec) fail(ACCURA_ERROR_INPUT, dir.string() + ": cannot create the directory: " + ec.message());
}

void checkStructSize(size_t given, size_t expected, const char* what) {
  if (given != expected)
    fail(ACCURA_ERROR_INVALID_ARGUMENT, std::string(what) + ": struct_size " + std::to_string(given) + " does not match this library's " +
                                            std::to_string(expected) + " (header and library of different versions?)");
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
  if (!name_out) return ACCURA_ERROR_NULL_ARGUMENT;
  const char* n = statusNameOf(cEnum(status));
  *name_out = n ? n : "ACCURA_STATUS_UNKNOWN";
  return n ? ACCURA_OK : ACCURA_ERROR_INVALID_ARGUMENT;
}

ACCURA_API accura_status accura_last_error(const accura_model* model, const char** message_out) {
  if (!model || !message_out) return ACCURA_ERROR_NULL_ARGUMENT;
  accura_model* m = const_cast<accura_model*>(model);
  try {
    std::lock_guard<std::mutex> lock(m->mutex);
    // the string stays in the map (and its buffer unchanged) until this thread's next failing
    // call on the handle, which is later than the documented lifetime
    std::string& e = m->errors[std::this_thread::get_id()];
    *message_out = e.c_str();
    return ACCURA_OK;
  } catch (...) {
    *message_out = "";
    return ACCURA_ERROR_OUT_OF_MEMORY;
  }
}

ACCURA_API accura_status accura_model_create(accura_model** model_out) {
  if (!model_out) return ACCURA_ERROR_NULL_ARGUMENT;
  *model_out = new (std::nothrow) accura_model();
  return *model_out ? ACCURA_OK : ACCURA_ERROR_OUT_OF_MEMORY;
}

ACCURA_API accura_status accura_model_free(accura_model* model) {
  delete model;  // nothing in the destructors throws
  return ACCURA_OK;
}

ACCURA_API accura_status accura_load_options_init(accura_load_options* o, size_t struct_size) {
  if (!o) return ACCURA_ERROR_NULL_ARGUMENT;
  if (struct_size != sizeof(accura_load_options)) return ACCURA_ERROR_INVALID_ARGUMENT;
  std::memset(o, 0, sizeof(*o));
  o->struct_size = sizeof(*o);
  o->temp_c = calib::kThermalReferenceC;
  return ACCURA_OK;
}

ACCURA_API accura_status accura_model_load(accura_model* model, const char* calibrated_model, const accura_load_options* options) {
  if (!model) return ACCURA_ERROR_NULL_ARGUMENT;
  return guarded(model, "accura_model_load", [&]() {
    need(calibrated_model, "calibrated_model");
    accura_load_options o;
    accura_load_options_init(&o, sizeof(o));
    if (options) {
      checkStructSize(options->struct_size, sizeof(accura_load_options), "accura_load_options");
      o = *options;
    }
    std::shared_ptr<const State> s = buildState(calibrated_model, o);
    std::lock_guard<std::mutex> lock(model->mutex);
    model->state = std::move(s);
    return ACCURA_OK;
  });
}

ACCURA_API accura_status accura_model_get_info(accura_model* model, accura_model_info* info) {
  if (!model) return ACCURA_ERROR_NULL_ARGUMENT;
  return guarded(model, "accura_model_get_info", [&]() {
    need(info, "info");
    const auto s = stateOf(model);
    *info = accura_model_info{};
    const calib::RobotModel& m = s->job.calibrated;
    info->dof = m.dof();
    copyString(info->robot_name, sizeof(info->robot_name), m.nominal.name);
    info->robroot_in_world = toC(calib::toXyzAbc(s->models->placement().T_world_robroot));
    info->calibrated_base_in_world = toC(calib::toXyzAbc(m.T_world_base()));
    for (int i = 0; i < m.dof(); ++i) {
      info->lower[i] = m.nominal.joints[i].lower;
      info->upper[i] = m.nominal.joints[i].upper;
    }
    return ACCURA_OK;
  });
}

ACCURA_API accura_status accura_model_get_joints(accura_model* model, accura_joint* joints, size_t capacity, size_t* n_joints) {
  if (!model) return ACCURA_ERROR_NULL_ARGUMENT;
  return guarded(model, "accura_model_get_joints", [&]() {
    if (capacity > 0) need(joints, "joints");
    const auto s = stateOf(model);
    const std::vector<calib::JointSpec>& js = s->job.calibrated.nominal.joints;
    if (n_joints) *n_joints = js.size();
    for (size_t i = 0; i < js.size() && i < capacity; ++i)
      joints[i] = {js[i].type == calib::JointType::kPrismatic ? 1 : 0, js[i].a_mm, js[i].alpha_deg, js[i].d_mm, js[i].theta0_deg,
                   js[i].direction, js[i].lower, js[i].upper};
    if (capacity < js.size())
      fail(ACCURA_ERROR_BUFFER_TOO_SMALL, "the robot has " + std::to_string(js.size()) + " joints, the buffer holds " + std::to_string(capacity));
    return ACCURA_OK;
  });
}

ACCURA_API accura_status accura_forward_kinematics(accura_model* model, accura_which_model which, const double* q, size_t n_joints,
                                                   accura_pose* pose_out) {
  if (!model) return ACCURA_ERROR_NULL_ARGUMENT;
  return guarded(model, "accura_forward_kinematics", [&]() {
    need(q, "q");
    need(pose_out, "pose_out");
    const auto s = stateOf(model);
    const int dof = s->job.calibrated.dof();
    if (n_joints != static_cast<size_t>(dof))
      fail(ACCURA_ERROR_INVALID_ARGUMENT, "expected " + std::to_string(dof) + " joint values, got " + std::to_string(n_joints));
    const int which_value = cEnum(which);
    if (which_value != ACCURA_CONTROLLER && which_value != ACCURA_REAL)
      fail(ACCURA_ERROR_INVALID_ARGUMENT, "which: expected ACCURA_CONTROLLER (0) or ACCURA_REAL (1), found " + std::to_string(which_value));
    Eigen::VectorXd qv(dof);
    for (int i = 0; i < dof; ++i) {
      if (!std::isfinite(q[i])) fail(ACCURA_ERROR_INVALID_ARGUMENT, "q[" + std::to_string(i) + "] is not finite");
      qv[i] = q[i];
    }
    const Eigen::Isometry3d T = which == ACCURA_REAL ? s->tool->compensator->real().forward(qv, s->job.context) : s->tool->compensator->controller().forward(qv);
    *pose_out = toC(calib::toXyzAbc(s->T_world_progbase.inverse() * T));
    return ACCURA_OK;
  });
}

ACCURA_API accura_status accura_compensate_pose(accura_model* model, const accura_pose* target, const accura_configuration* configuration,
                                                accura_pose_result* result) {
  if (!model) return ACCURA_ERROR_NULL_ARGUMENT;
  return guarded(model, "accura_compensate_pose", [&]() {
    need(target, "target");
    need(result, "result");
    const auto s = stateOf(model);
    const Eigen::Isometry3d T_world = s->T_world_progbase * checkedPose(*target, "target");
    const calib::Configuration asked = configOf(configuration, s->job.calibrated.dof());
    PoseCompensation pc = s->tool->compensator->pose(T_world, asked, Eigen::VectorXd(), s->job.ik, s->job.context);
    enforceConfiguration(asked, pc);
    fillPoseResult(*s, T_world, pc, result);
    if (pc.status != calib::IkStatus::kOk) fail(result->status, pc.message.empty() ? std::string(toString(pc.status)) : pc.message);
    return ACCURA_OK;
  });
}

ACCURA_API accura_status accura_compensate_poses(accura_model* model, const accura_pose* targets,
                                                 const accura_configuration* configurations, size_t n, int continuous,
                                                 accura_pose_result* results, size_t* n_ok) {
  if (!model) return ACCURA_ERROR_NULL_ARGUMENT;
  return guarded(model, "accura_compensate_poses", [&]() {
    if (n_ok) *n_ok = 0;
    if (n == 0) return ACCURA_OK;
    need(targets, "targets");
    need(results, "results");
    const auto s = stateOf(model);
    // validate everything first: a bad argument fails the call before any work
    std::vector<Eigen::Isometry3d> T_world(n);
    std::vector<calib::Configuration> configs(n);
    for (size_t i = 0; i < n; ++i) {
      T_world[i] = s->T_world_progbase * checkedPose(targets[i], "targets[" + std::to_string(i) + "]");
      configs[i] = configOf(configurations ? &configurations[i] : nullptr, s->job.calibrated.dof());
    }
    accura_status first = ACCURA_OK;
    std::string first_message;
    size_t ok = 0;
    Eigen::VectorXd seed;
    for (size_t i = 0; i < n; ++i) {
      PoseCompensation pc = s->tool->compensator->pose(T_world[i], configs[i], continuous ? seed : Eigen::VectorXd(), s->job.ik, s->job.context);
      enforceConfiguration(configs[i], pc);
      fillPoseResult(*s, T_world[i], pc, &results[i]);
      if (pc.status == calib::IkStatus::kOk) {
        ++ok;
        seed = pc.q_real;
      } else if (first == ACCURA_OK) {
        first = results[i].status;
        first_message = "pose " + std::to_string(i) + ": " + (pc.message.empty() ? std::string(toString(pc.status)) : pc.message);
      }
    }
    if (n_ok) *n_ok = ok;
    if (first != ACCURA_OK) fail(first, first_message + " (" + std::to_string(n - ok) + " of " + std::to_string(n) + " poses failed)");
    return ACCURA_OK;
  });
}

ACCURA_API accura_status accura_compensate_path(accura_model* model, const accura_pose* start,
                                                const accura_configuration* start_configuration, const accura_path_motion* motions,
                                                size_t n_motions, double tol_mm, accura_path_point* points, size_t capacity,
                                                accura_path_result* result, accura_motion_report* reports) {
  if (!model) return ACCURA_ERROR_NULL_ARGUMENT;
  return guarded(model, "accura_compensate_path", [&]() {
    need(start, "start");
    need(result, "result");
    if (n_motions > 0) need(motions, "motions");
    if (capacity > 0) need(points, "points");
    *result = accura_path_result{};
    result->failed_motion = -1;
    if (!(tol_mm > 0) || !std::isfinite(tol_mm))
      fail(ACCURA_ERROR_INVALID_ARGUMENT, "tol_mm: expected a positive distance (mm), found " + std::to_string(tol_mm));
    const auto s = stateOf(model);
    const Eigen::Isometry3d T_world_start = s->T_world_progbase * checkedPose(*start, "start");
    std::vector<PathSegment> intended(n_motions);
    for (size_t i = 0; i < n_motions; ++i) {
      const std::string w = "motions[" + std::to_string(i) + "]";
      const int type_value = cEnum(motions[i].type);
      if (type_value != ACCURA_LIN && type_value != ACCURA_CIRC)
        fail(ACCURA_ERROR_INVALID_ARGUMENT, w + ".type: expected ACCURA_LIN (0) or ACCURA_CIRC (1), found " + std::to_string(type_value));
      intended[i].type = motions[i].type == ACCURA_CIRC ? PathType::kCirc : PathType::kLin;
      intended[i].T_world_end = s->T_world_progbase * checkedPose(motions[i].end, w + ".end");
      if (intended[i].type == PathType::kCirc) intended[i].T_world_aux = s->T_world_progbase * checkedPose(motions[i].aux, w + ".aux");
    }
    if (reports)
      for (size_t i = 0; i < n_motions; ++i) reports[i] = accura_motion_report{};
    JobSettings job = s->job;
    job.tol_mm = tol_mm;
    const calib::Configuration asked_start = configOf(start_configuration, job.calibrated.dof());
    const PathCompensation pc = compensatePath(*s->tool->compensator, T_world_start, asked_start, intended, job);
    if (pc.start.status != calib::IkStatus::kOk)
      fail(statusOf(pc.start.status), std::string("the start cannot be compensated: ") + toString(pc.start.status) +
                                          (pc.start.message.empty() ? "" : ": " + pc.start.message));
    if (pc.failed_motion >= 0) {
      const SegmentCompensation& sc = pc.segments.back();
      result->failed_motion = pc.failed_motion;
      fail(sc.status == calib::IkStatus::kOk ? ACCURA_ERROR_INTERNAL : statusOf(sc.status), "motion " + std::to_string(pc.failed_motion) +
           " cannot be compensated: " + toString(sc.status) + (sc.message.empty() ? "" : ": " + sc.message));
    }
    const auto inBase = [&](const Eigen::Isometry3d& T_world) { return toC(calib::toXyzAbc(s->T_world_progbase.inverse() * T_world)); };
    result->start_command = inBase(pc.start.T_world_tcp_command);
    result->start_configuration = toC(pc.start.configuration);
    std::vector<accura_path_point> out;
    for (size_t i = 0; i < n_motions; ++i) {
      const SegmentCompensation& sc = pc.segments[i];
      for (size_t k = 0; k < sc.commanded.size(); ++k) {
        accura_path_point p{};
        p.type = motions[i].type;
        p.end = inBase(sc.commanded[k].T_world_end);
        if (intended[i].type == PathType::kCirc) p.aux = inBase(sc.commanded[k].T_world_aux);
        p.configuration = toC(calib::kukaConfiguration(s->tool->compensator->controller().model(), sc.q_real_end[k]));
        p.motion = static_cast<int>(i);
        p.inserted = k + 1 < sc.commanded.size() ? 1 : 0;
        out.push_back(p);
      }
      if (reports)
        reports[i] = {pathLength(pc.intended[i]), sc.max_error_uncompensated_mm, sc.max_error_before_mm, sc.max_error_after_mm,
                      sc.max_error_bound_mm, sc.points_added};
      result->max_error_uncompensated_mm = std::max(result->max_error_uncompensated_mm, sc.max_error_uncompensated_mm);
      result->max_error_before_mm = std::max(result->max_error_before_mm, sc.max_error_before_mm);
      result->max_error_after_mm = std::max(result->max_error_after_mm, sc.max_error_after_mm);
      result->max_error_bound_mm = std::max(result->max_error_bound_mm, sc.max_error_bound_mm);
      result->points_added += sc.points_added;
    }
    result->n_points = out.size();
    if (out.size() > capacity)
      fail(ACCURA_ERROR_BUFFER_TOO_SMALL, "the path has " + std::to_string(out.size()) + " points, the buffer holds " + std::to_string(capacity));
    std::copy(out.begin(), out.end(), points);
    return ACCURA_OK;
  });
}

ACCURA_API accura_status accura_program_options_init(accura_program_options* o, size_t struct_size) {
  if (!o) return ACCURA_ERROR_NULL_ARGUMENT;
  if (struct_size != sizeof(accura_program_options)) return ACCURA_ERROR_INVALID_ARGUMENT;
  std::memset(o, 0, sizeof(*o));
  o->struct_size = sizeof(*o);
  o->tol_mm = 0.05;
  return ACCURA_OK;
}

ACCURA_API accura_status accura_compensate_program(accura_model* model, const char* program_path, const char* out_dir,
                                                   const accura_program_options* options, accura_program_summary* summary) {
  if (!model) return ACCURA_ERROR_NULL_ARGUMENT;
  return guarded(model, "accura_compensate_program", [&]() {
    need(program_path, "program_path");
    need(out_dir, "out_dir");
    accura_program_options o;
    accura_program_options_init(&o, sizeof(o));
    if (options) {
      checkStructSize(options->struct_size, sizeof(accura_program_options), "accura_program_options");
      o = *options;
    }
    if (!(o.tol_mm > 0) || !std::isfinite(o.tol_mm))
      fail(ACCURA_ERROR_INVALID_ARGUMENT, "tol_mm: expected a positive distance (mm), found " + std::to_string(o.tol_mm));
    const auto s = stateOf(model);
    JobSettings job = s->job;
    job.tol_mm = o.tol_mm;
    std::error_code ec;
    if (!fs::exists(program_path, ec)) fail(ACCURA_ERROR_INPUT, std::string(program_path) + ": the program file does not exist");
    ProgramFileRequest request;
    request.in_path = program_path;
    request.out_dir = out_dir;
    if (o.dat_path) request.read.dat_path = o.dat_path;
    if (o.config_path) request.read.config_path = o.config_path;
    if (o.json_report_path) request.json_path = o.json_report_path;
    request.out_name = "out_dir";
    request.json_name = "json_report_path";
    const ProgramFileResult result = compensateProgramFile(request, job);
    const JobReport& report = result.report;
    const std::vector<calib::OutputFile>& files = result.checked.files;
    if (summary) {
      *summary = accura_program_summary{};
      summary->targets_corrected = report.targets_corrected;
      summary->points_added = report.points_added;
      summary->segments = static_cast<int>(report.segments.size());
      summary->warnings = static_cast<int>(report.warnings.size());
      summary->max_correction_mm = report.max_correction_mm;
      summary->rms_correction_mm = report.rms_correction_mm;
      summary->max_correction_deg = report.max_correction_deg;
      summary->max_error_uncompensated_mm = report.max_error_uncompensated_mm;
      summary->max_error_before_mm = report.max_error_before_mm;
      summary->max_error_after_mm = report.max_error_after_mm;
      copyString(summary->output_path, sizeof(summary->output_path), files.empty() ? std::string() : files.front().path);
    }
    return ACCURA_OK;
  });
}

ACCURA_API accura_status accura_check_options_init(accura_check_options* o, size_t struct_size) {
  if (!o) return ACCURA_ERROR_NULL_ARGUMENT;
  if (struct_size != sizeof(accura_check_options)) return ACCURA_ERROR_INVALID_ARGUMENT;
  std::memset(o, 0, sizeof(*o));
  o->struct_size = sizeof(*o);
  o->use_cell_thresholds = 1;
  const CheckThresholds t;
  o->joint_margin_deg = t.joint_margin_deg;
  o->singular_threshold = t.singular_threshold;
  o->min_clearance_mm = t.min_clearance_mm;
  return ACCURA_OK;
}

ACCURA_API accura_status accura_check_program(accura_model* model, const char* cell_path, const char* program_path,
                                              const accura_check_options* options, accura_check_summary* summary,
                                              accura_check_violation* violations, size_t capacity) {
  if (!model) return ACCURA_ERROR_NULL_ARGUMENT;
  return guarded(model, "accura_check_program", [&]() {
    need(cell_path, "cell_path");
    need(program_path, "program_path");
    need(summary, "summary");
    if (capacity > 0) need(violations, "violations");
    accura_check_options o;
    accura_check_options_init(&o, sizeof(o));
    if (options) {
      checkStructSize(options->struct_size, sizeof(accura_check_options), "accura_check_options");
      o = *options;
    }
    const auto s = stateOf(model);
    std::error_code ec;
    if (!fs::exists(cell_path, ec)) fail(ACCURA_ERROR_INPUT, std::string(cell_path) + ": the cell file does not exist");
    if (!fs::exists(program_path, ec)) fail(ACCURA_ERROR_INPUT, std::string(program_path) + ": the program file does not exist");
    const Cell cell = readCellFile(cell_path);
    ProgramReadOptions read;
    if (o.dat_path) read.dat_path = o.dat_path;
    if (o.config_path) read.config_path = o.config_path;
    const Program program = readProgram(program_path, read);
    CheckOptions co;
    co.mode = o.as_written ? CheckMode::kAsWritten : CheckMode::kIntended;
    if (o.use_cell_thresholds) {
      co.thresholds = cell.thresholds;
    } else {
      co.thresholds.joint_margin_deg = o.joint_margin_deg;
      co.thresholds.singular_threshold = o.singular_threshold;
      co.thresholds.min_clearance_mm = o.min_clearance_mm;
    }
    std::string why;
    if (!co.IsValid(&why)) fail(ACCURA_ERROR_INVALID_ARGUMENT, why);
    const CheckReport r = checkProgram(program, s->job, cell, co);
    *summary = accura_check_summary{};
    summary->passed = r.passed() ? 1 : 0;
    summary->n_violations = r.violations.size();
    summary->unchecked = static_cast<int>(r.unchecked.size());
    summary->samples = r.samples;
    summary->min_clearance_mm = std::isfinite(r.min_clearance_mm) ? r.min_clearance_mm : 1e300;
    summary->min_sigma = r.min_sigma;
    summary->min_joint_margin = r.min_joint_margin;
    for (size_t i = 0; i < r.violations.size() && i < capacity; ++i) {
      const CheckViolation& v = r.violations[i];
      accura_check_violation& c = violations[i];
      c = accura_check_violation{};
      c.kind = static_cast<int>(v.kind == CheckKind::kReach        ? ACCURA_CHECK_REACH
                                : v.kind == CheckKind::kJointLimit ? ACCURA_CHECK_JOINT_LIMIT
                                : v.kind == CheckKind::kSingularity ? ACCURA_CHECK_SINGULARITY
                                                                    : ACCURA_CHECK_CLEARANCE);
      c.motion_index = v.motion_index;
      c.line = v.where.line;
      c.column = v.where.column;
      c.on_path = v.on_path ? 1 : 0;
      c.s = v.s;
      for (int k = 0; k < 3; ++k) c.p_world_tcp_mm[k] = v.p_world_tcp_mm[k];
      c.value = v.value;
      c.limit = v.limit;
      c.joint = v.joint;
      copyString(c.message, sizeof(c.message), v.message);
    }
    if (r.violations.size() > capacity)
      fail(ACCURA_ERROR_BUFFER_TOO_SMALL,
           std::to_string(r.violations.size()) + " violations, the buffer holds " + std::to_string(capacity) + " (summary->n_violations)");
    return ACCURA_OK;
  });
}

ACCURA_API accura_status accura_write_options_init(accura_write_options* o, size_t struct_size) {
  if (!o) return ACCURA_ERROR_NULL_ARGUMENT;
  if (struct_size != sizeof(accura_write_options)) return ACCURA_ERROR_INVALID_ARGUMENT;
  std::memset(o, 0, sizeof(*o));
  o->struct_size = sizeof(*o);
  return ACCURA_OK;
}

ACCURA_API accura_status accura_write_program(accura_model* model, const char* path, const accura_program_motion* motions,
                                              size_t n_motions, const accura_write_options* options) {
  if (!model) return ACCURA_ERROR_NULL_ARGUMENT;
  return guarded(model, "accura_write_program", [&]() {
    need(path, "path");
    need(options, "options");
    if (n_motions > 0) need(motions, "motions");
    checkStructSize(options->struct_size, sizeof(accura_write_options), "accura_write_options");
    const ProgramFormat format = programFormat(path);
    Program p;
    p.name = options->program_name ? options->program_name : fs::path(path).stem().string();
    std::shared_ptr<const State> s;
    {
      std::lock_guard<std::mutex> lock(model->mutex);
      s = model->state;
    }
    if (s) p.robot = s->job.calibrated.nominal.name;
    FrameSetting tool, base;
    tool.source = base.source = FrameSetting::Source::kInline;
    tool.value = checkedXyz(options->tool, "options.tool");
    base.value = checkedXyz(options->base, "options.base");
    for (size_t i = 0; i < n_motions; ++i) {
      const accura_program_motion& c = motions[i];
      const std::string w = "motions[" + std::to_string(i) + "]";
      Motion m;
      const int type_value = cEnum(c.type);
      if (type_value != ACCURA_PTP && type_value != ACCURA_LIN && type_value != ACCURA_CIRC)
        fail(ACCURA_ERROR_INVALID_ARGUMENT, w + ".type: expected ACCURA_LIN, ACCURA_CIRC or ACCURA_PTP, found " + std::to_string(type_value));
      m.type = c.type == ACCURA_PTP ? MotionType::kPtp : c.type == ACCURA_CIRC ? MotionType::kCirc : MotionType::kLin;
      m.target.setPose(checkedXyz(c.end, w + ".end"));
      if (m.type == MotionType::kCirc) {
        m.aux = Target{};
        m.aux->setPose(checkedXyz(c.aux, w + ".aux"));
      }
      if (c.approximate) m.approximation = {m.type == MotionType::kPtp ? Approximation::kCPtp : Approximation::kCDis};
      if (!std::isfinite(c.vel_m_s)) fail(ACCURA_ERROR_INVALID_ARGUMENT, w + ".vel_m_s: expected a finite speed (m/s)");
      if (m.type != MotionType::kPtp && c.vel_m_s > 0) m.vel_m_s = c.vel_m_s;
      m.tool = tool;
      m.base = base;
      p.motions.push_back(m);
    }
    makeParentDir(path);
    calib::writeFilesAtomically(renderProgram(p, format, path));
    return ACCURA_OK;
  });
}

ACCURA_API accura_status accura_write_file(accura_model* model, const char* path, const char* data, size_t size) {
  if (!model) return ACCURA_ERROR_NULL_ARGUMENT;
  return guarded(model, "accura_write_file", [&]() {
    need(path, "path");
    if (size > 0) need(data, "data");
    makeParentDir(path);
    calib::writeFilesAtomically({{path, std::string(data ? data : "", size)}});
    return ACCURA_OK;
  });
}

}  // extern "C"
