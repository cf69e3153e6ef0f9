// A calibrated model loaded once for a host's calls (see session.h).
#include "accura/postproc/session.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <new>
#include <sstream>
#include <stdexcept>

#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "accura/calib/geometry.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/text.h"
#include "accura/postproc/cell.h"
#include "accura/postproc/path_job.h"

namespace fs = std::filesystem;

namespace accura::postproc {
namespace {

/// A robot file path or a bundled robot name; a path that does not exist is named as such.
calib::RobotModel readModel(const std::string& name_or_path, const char* what) {
  std::error_code ec;
  const bool looks_like_path = name_or_path.find('/') != std::string::npos || fs::path(name_or_path).extension() == ".xml";
  if (looks_like_path && !fs::exists(name_or_path, ec))
    throw calib::InputError(name_or_path + ": the " + what + " file does not exist (expected a robot file, e.g. a calibrated model " +
                     "written by accura identify, or a bundled robot name)");
  return calib::readRobotFile(calib::resolveRobotPath(name_or_path));
}

void requireFile(const std::string& path, const char* what) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw calib::InputError(path + ": the " + what + " file does not exist");
}

void checkTolerance(double tol_mm) {
  if (!(tol_mm >= kMinTolMm && tol_mm <= kMaxTolMm)) {
    std::ostringstream m;
    m << "tol_mm: expected a path tolerance in [" << kMinTolMm << ", " << kMaxTolMm << "] mm, found " << tol_mm;
    throw calib::ArgumentError(m.str());
  }
}

/// The calling thread's last error of a call without a live handle (SessionRegistry::run).
thread_local std::string t_unbound_error;
const char* const kNotLive = "not a live handle (freed by accura_model_free, or not made by accura_model_create)";

/// A value of an option as a message shows it: 3 decimals, or nan / inf / -inf (formatFixed
/// takes finite numbers only); a magnitude of 1e15 or more in exponent form ("1e+300": with
/// 3 decimals it took 305 digits of a host's error dialog).
std::string shownValue(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  if (std::abs(v) >= 1e15) return calib::formatNumber("%.6g", v);
  return calib::formatFixed(v, 3);
}

std::string failureText(calib::IkStatus status, const std::string& message) {
  return message.empty() ? std::string(calib::toString(status)) : message;
}

}  // namespace

calib::Configuration checkedConfiguration(int status, int turn, int dof) {
  const long long max_turn = (1LL << std::min(dof, 30)) - 1;
  if (status < -1 || status > 7 || turn < -1 || turn > max_turn)
    throw calib::ArgumentError("configuration: expected S in 0..7 and T in 0.." + std::to_string(max_turn) + " (a bit per joint), or -1 (any), found S " +
                        std::to_string(status) + ", T " + std::to_string(turn));
  return {status, turn};
}

const calib::XyzAbc& checkedPose(const calib::XyzAbc& p, const std::string& what) {
  for (double x : {p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg})
    if (!std::isfinite(x)) throw calib::ArgumentError(what + ": expected finite x, y, z (mm), A, B, C (deg), found a NaN or infinity");
  for (double x : {p.x_mm, p.y_mm, p.z_mm})
    if (std::abs(x) > kMaxFrameMm)
      throw calib::ArgumentError(what + ": expected x, y, z within +-" + calib::formatFixed(kMaxFrameMm, 0) + " mm, found " +
                                 shownValue(x));
  for (double x : {p.a_deg, p.b_deg, p.c_deg})
    if (std::abs(x) > kMaxFrameDeg)
      throw calib::ArgumentError(what + ": expected A, B, C within +-" + calib::formatFixed(kMaxFrameDeg, 0) + " deg, found " +
                                 shownValue(x));
  return p;
}

Session::Session(const SessionSettings& s) {
  job_.calibrated = readModel(s.calibrated_model, "calibrated_model");
  model_files_ = {s.calibrated_model};
  if (!s.controller_model.empty()) model_files_.push_back(s.controller_model);
  if (job_.calibrated.dof() > s.max_joints)
    throw calib::InputError(s.calibrated_model + ": expected at most " + std::to_string(s.max_joints) + " joints, found " +
                     std::to_string(job_.calibrated.dof()));
  if (!s.controller_model.empty()) {
    // the kinematics the controller runs (its nominal robot, or a UR's factory calibration):
    // the command lands where its own kinematics put it (JobSettings::controller_kinematics)
    calib::RobotModel controller = readModel(s.controller_model, "controller_model");
    checkControllerRobot(job_.calibrated.nominal, controller.nominal, s.controller_model);
    job_.controller_kinematics = std::move(controller);
  }
  for (const auto* p : {&s.robroot_in_world, &s.robroot_in_kukaworld, &s.program_base, &s.program_tool})
    if (*p) checkedPose(**p, "load options");
  if (!(s.payload_kg >= 0 && s.payload_kg <= kMaxPayloadKg))
    throw calib::ArgumentError("payload_kg: expected a finite mass in [0, " + calib::formatFixed(kMaxPayloadKg, 0) + "] kg, found " +
                               shownValue(s.payload_kg));
  if (!(s.temp_c >= kMinTempC && s.temp_c <= kMaxTempC))
    throw calib::ArgumentError("temp_c: expected a finite temperature in [" + calib::formatFixed(kMinTempC, 0) + ", " +
                               calib::formatFixed(kMaxTempC, 0) + "] deg C, found " + shownValue(s.temp_c));
  job_.robroot_in_world = s.robroot_in_world;
  job_.robroot_in_kukaworld = s.robroot_in_kukaworld;
  job_.initial_base = s.program_base;
  job_.initial_tool = s.program_tool;
  job_.context.payload_kg = s.payload_kg;
  job_.context.temp_c = s.temp_c;
  // frames and models as compensateProgram takes them (placement.h)
  models_ = std::make_unique<ModelFactory>(job_, placeRobot(job_, s.placement_setting));
  const Eigen::Isometry3d T_kworld_progbase = s.program_base ? calib::toIsometry(*s.program_base) : Eigen::Isometry3d::Identity();
  T_world_progbase_ = models_->placement().T_world_kworld * T_kworld_progbase;
  comp_ = models_->compensator(s.program_tool ? calib::toIsometry(*s.program_tool) : job_.calibrated.nominal.T_flange_tcp).compensator.get();
}

Eigen::Isometry3d Session::toWorld(const calib::XyzAbc& T_base_tcp, const std::string& what) const {
  return T_world_progbase_ * calib::toIsometry(checkedPose(T_base_tcp, what));
}

calib::XyzAbc Session::toBase(const Eigen::Isometry3d& T_world_tcp) const { return calib::toXyzAbc(T_world_progbase_.inverse() * T_world_tcp); }

Eigen::VectorXd Session::jointVector(const std::vector<double>& q, const std::string& what) const {
  if (q.size() != static_cast<size_t>(dof()))
    throw calib::ArgumentError((what.empty() ? "" : what + ": ") + "expected " + std::to_string(dof()) + " joint values, got " +
                               std::to_string(q.size()));
  Eigen::VectorXd qv(dof());
  for (int i = 0; i < dof(); ++i) {
    if (!std::isfinite(q[i])) throw calib::ArgumentError((what.empty() ? "q" : what) + "[" + std::to_string(i) + "] is not finite");
    qv[i] = q[i];
  }
  return qv;
}

std::vector<double> Session::joints(const double* q, size_t n) const {
  if (n != static_cast<size_t>(dof()))
    throw calib::ArgumentError("expected " + std::to_string(dof()) + " joint values, got " + std::to_string(n));
  return std::vector<double>(q, q + n);
}

calib::XyzAbc Session::forward(bool real, const std::vector<double>& q) const {
  const Eigen::VectorXd qv = jointVector(q, "");
  return toBase(real ? comp_->real().forward(qv, job_.context) : comp_->controller().forward(qv));
}

calib::Configuration Session::configuration(const std::vector<double>& q) const {
  return calib::kukaConfiguration(models_->controllerFlange(), jointVector(q, ""));
}

calib::Configuration Session::configurationAt(const std::vector<double>& q, const calib::XyzAbc& T_base_tcp, const calib::XyzAbc& tool,
                                              const calib::XyzAbc& base, const std::string& what) const {
  const Eigen::VectorXd qv = jointVector(q, what);
  const Eigen::Isometry3d T_world_flange = calib::forwardKinematics(models_->controllerFlange(), qv);
  const Eigen::Isometry3d T_base_tcp_q =
      (placement().T_world_kworld * calib::toIsometry(base)).inverse() * T_world_flange * calib::toIsometry(tool);
  const Eigen::Isometry3d T_target = calib::toIsometry(T_base_tcp);
  const double mm = (T_base_tcp_q.translation() - T_target.translation()).norm();
  const double deg = calib::rotationAngleDeg(T_base_tcp_q.linear() * T_target.linear().transpose());
  if (!(mm <= kJointsOnTargetMm && deg <= kJointsOnTargetDeg))
    throw calib::ArgumentError(what + ": the joint values put the tool " + calib::formatFixed(mm, 4) + " mm and " + calib::formatFixed(deg, 4) +
                               " deg from the target (expected the arm's joints at it, within " + calib::formatFixed(kJointsOnTargetMm, 2) +
                               " mm and " + calib::formatFixed(kJointsOnTargetDeg, 2) + " deg)");
  return calib::kukaConfiguration(models_->controllerFlange(), qv);
}

SessionPose Session::pose(const calib::XyzAbc& target, const calib::Configuration& asked, const Eigen::VectorXd& seed) const {
  // the configuration rule of a PTP of accura compensate (a UR arm's controller reads no S/T)
  const PoseCompensation pc = compensateTarget(*comp_, toWorld(target, "target"), asked, seed, job_);
  SessionPose r;
  r.status = pc.status;
  if (pc.status != calib::IkStatus::kOk) {
    r.message = failureText(pc.status, pc.message);
    return r;
  }
  r.command = toBase(pc.T_world_tcp_command);
  r.configuration = pc.configuration;
  r.configuration_changed = pc.configuration_changed;
  r.correction_mm = pc.correction_mm;
  r.correction_deg = pc.correction_deg;
  r.q_real = pc.q_real;
  return r;
}

SessionPoses Session::poses(const std::vector<calib::XyzAbc>& targets, const std::vector<calib::Configuration>& asked, bool continuous) const {
  if (!asked.empty() && asked.size() != targets.size())
    throw calib::ArgumentError("expected " + std::to_string(targets.size()) + " configurations, got " + std::to_string(asked.size()));
  // validate everything first: a bad argument fails the call before any work
  for (size_t i = 0; i < targets.size(); ++i) checkedPose(targets[i], "targets[" + std::to_string(i) + "]");
  SessionPoses r;
  r.results.reserve(targets.size());
  Eigen::VectorXd seed;
  for (size_t i = 0; i < targets.size(); ++i) {
    r.results.push_back(pose(targets[i], asked.empty() ? calib::Configuration{} : asked[i], continuous ? seed : Eigen::VectorXd()));
    const SessionPose& p = r.results.back();
    if (p.status == calib::IkStatus::kOk) {
      ++r.n_ok;
      seed = p.q_real;
    } else if (r.first_failed < 0) {
      r.first_failed = static_cast<int>(i);
      r.message = "pose " + std::to_string(i) + ": " + p.message;
    }
  }
  if (r.first_failed >= 0)
    r.message += " (" + std::to_string(targets.size() - r.n_ok) + " of " + std::to_string(targets.size()) + " poses failed)";
  return r;
}

SessionPath Session::path(const calib::XyzAbc& start, const calib::Configuration& start_config, const std::vector<SessionMotion>& motions,
                          double tol_mm) const {
  checkTolerance(tol_mm);
  const Eigen::Isometry3d T_world_start = toWorld(start, "start");
  std::vector<PathSegment> intended(motions.size());
  for (size_t i = 0; i < motions.size(); ++i) {
    const std::string w = "motions[" + std::to_string(i) + "]";
    intended[i].type = motions[i].type;
    intended[i].T_world_end = toWorld(motions[i].end, w + ".end");
    if (motions[i].type == PathType::kCirc) intended[i].T_world_aux = toWorld(motions[i].aux, w + ".aux");
  }
  JobSettings job = job_;
  job.tol_mm = tol_mm;
  const PathCompensation pc = compensatePath(*comp_, T_world_start, start_config, intended, job);
  SessionPath r;
  if (pc.start.status != calib::IkStatus::kOk) {
    r.status = pc.start.status;
    r.message = std::string("the start cannot be compensated: ") + calib::toString(pc.start.status) +
                (pc.start.message.empty() ? "" : ": " + pc.start.message);
    return r;
  }
  if (pc.failed_motion >= 0 && !pc.numerical_error.empty()) {
    r.numerical = true;
    r.failed_motion = pc.failed_motion;
    r.message = "motion " + std::to_string(pc.failed_motion) + " cannot be compensated: " + pc.numerical_error;
    return r;
  }
  if (pc.failed_motion >= 0) {
    const SegmentCompensation& sc = pc.segments.back();
    r.status = sc.status;
    r.failed_motion = pc.failed_motion;
    r.message = "motion " + std::to_string(pc.failed_motion) + " cannot be compensated: " + calib::toString(sc.status) +
                (sc.message.empty() ? "" : ": " + sc.message);
    return r;
  }
  r.start.status = calib::IkStatus::kOk;
  r.start.command = toBase(pc.start.T_world_tcp_command);
  r.start.configuration = pc.start.configuration;
  r.start.q_real = pc.start.q_real;
  for (size_t i = 0; i < motions.size(); ++i) {
    const SegmentCompensation& sc = pc.segments[i];
    for (size_t k = 0; k < sc.commanded.size(); ++k) {
      SessionPathPoint p;
      p.type = motions[i].type;
      p.end = toBase(sc.commanded[k].T_world_end);
      if (p.type == PathType::kCirc) p.aux = toBase(sc.commanded[k].T_world_aux);
      p.configuration = calib::kukaConfiguration(comp_->controller().model(), sc.q_real_end[k]);
      p.motion = static_cast<int>(i);
      p.inserted = k + 1 < sc.commanded.size();
      r.points.push_back(p);
    }
    const SessionMotionNumbers n = {pathLength(pc.intended[i]), sc.max_error_uncompensated_mm, sc.max_error_before_mm,
                                    sc.max_error_after_mm,      sc.max_error_bound_mm,          sc.points_added};
    r.motions.push_back(n);
    SessionMotionNumbers& t = r.total;
    t.length_mm += n.length_mm;
    t.max_error_uncompensated_mm = std::max(t.max_error_uncompensated_mm, n.max_error_uncompensated_mm);
    t.max_error_before_mm = std::max(t.max_error_before_mm, n.max_error_before_mm);
    t.max_error_after_mm = std::max(t.max_error_after_mm, n.max_error_after_mm);
    t.max_error_bound_mm = std::max(t.max_error_bound_mm, n.max_error_bound_mm);
    t.points_added += n.points_added;
  }
  return r;
}

ProgramFileResult Session::compensateProgramFile(const ProgramFileRequest& request, double tol_mm) const {
  checkTolerance(tol_mm);
  requireFile(request.in_path, "program");
  JobSettings job = job_;
  job.tol_mm = tol_mm;
  ProgramFileRequest q = request;
  q.other_inputs.insert(q.other_inputs.end(), model_files_.begin(), model_files_.end());
  return postproc::compensateProgramFile(q, job);
}

CheckReport Session::checkProgramFile(const std::string& cell_path, const std::string& program_path, const ProgramReadOptions& read,
                                      CheckMode mode, const std::optional<CheckThresholds>& thresholds) const {
  requireFile(cell_path, "cell");
  requireFile(program_path, "program");
  const Cell cell = readCellFile(cell_path);
  const Program program = readProgram(program_path, read);
  CheckOptions options;
  options.mode = mode;
  options.thresholds = thresholds ? *thresholds : cell.thresholds;
  std::string why;
  if (!options.IsValid(&why)) throw calib::ArgumentError(why);
  return checkProgram(program, job_, cell, options);
}

CallStatus callStatus(calib::IkStatus status) {
  switch (status) {
    case calib::IkStatus::kOk: return CallStatus::kOk;
    case calib::IkStatus::kUnreachable: return CallStatus::kUnreachable;
    case calib::IkStatus::kJointLimits: return CallStatus::kJointLimits;
    case calib::IkStatus::kSingular: return CallStatus::kSingular;
    case calib::IkStatus::kNoConfiguration: return CallStatus::kNoConfiguration;
    case calib::IkStatus::kNotConverged: return CallStatus::kNotConverged;
  }
  return CallStatus::kInternal;
}

void requirePointers(CallPointers pointers) {
  for (const auto& p : pointers)
    if (!p.first) throw CallError(CallStatus::kNullArgument, std::string(p.second) + " is NULL");
}

const void* ifAny(size_t n, const void* p) { return n > 0 ? p : ""; }

void requireCapacity(size_t needed, size_t capacity, const std::string& what, const char* after) {
  if (needed > capacity)
    throw CallError(CallStatus::kBufferTooSmall, what + ", the buffer holds " + std::to_string(capacity) + after);
}

int checkedInt(int value, bool allowed, const std::string& what, const std::string& expected) {
  if (!allowed) throw calib::ArgumentError(what + ": expected " + expected + ", found " + std::to_string(value));
  return value;
}

std::shared_ptr<const Session> SessionRegistry::Slot::session() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return session_;
}

std::shared_ptr<const Session> SessionRegistry::Slot::loaded() const {
  std::shared_ptr<const Session> s = session();
  if (!s) throw CallError(CallStatus::kInvalidArgument, "no model loaded on this handle (call accura_model_load first)");
  return s;
}

void SessionRegistry::Slot::load(std::shared_ptr<const Session> session) {
  std::lock_guard<std::mutex> lock(mutex_);
  session_ = std::move(session);
}

const std::string& SessionRegistry::Slot::error() {
  std::lock_guard<std::mutex> lock(mutex_);
  return errors_[std::this_thread::get_id()];  // the node (and its string) stays until erased
}

void SessionRegistry::Slot::setError(std::string text) {
  std::lock_guard<std::mutex> lock(mutex_);
  errors_[std::this_thread::get_id()] = std::move(text);
}

SessionRegistry& SessionRegistry::instance() {
  static SessionRegistry* r = new SessionRegistry();
  return *r;
}

std::uintptr_t SessionRegistry::create() {
  auto slot = std::make_shared<Slot>();
  std::lock_guard<std::mutex> lock(mutex_);
  const std::uintptr_t key = ++last_id_ << 4;  // never 0, never reused (2^60 keys)
  live_.emplace(key, std::move(slot));
  return key;
}

void SessionRegistry::release(std::uintptr_t key) {
  if (key == 0) return;
  std::shared_ptr<Slot> slot;  // destroyed after the lock is released, once no call holds it
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = live_.find(key);
  if (it == live_.end()) throw CallError(CallStatus::kInvalidArgument, kNotLive);
  slot = std::move(it->second);
  live_.erase(it);
}

std::shared_ptr<SessionRegistry::Slot> SessionRegistry::find(std::uintptr_t key) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = live_.find(key);
  return it == live_.end() ? nullptr : it->second;
}

std::shared_ptr<SessionRegistry::Slot> SessionRegistry::live(std::uintptr_t key) const {
  if (key == 0) throw CallError(CallStatus::kNullArgument, "model is NULL");
  std::shared_ptr<Slot> slot = find(key);
  if (!slot) throw CallError(CallStatus::kInvalidArgument, kNotLive);
  return slot;
}

CallStatus SessionRegistry::lastError(std::uintptr_t key, const char** message) const noexcept {
  *message = "";
  try {
    const std::shared_ptr<Slot> slot = key ? find(key) : nullptr;
    *message = slot ? slot->error().c_str() : t_unbound_error.c_str();  // the slot outlives `slot` (held by live_)
    return slot || key == 0 ? CallStatus::kOk : CallStatus::kInvalidArgument;
  } catch (...) {
    return CallStatus::kOutOfMemory;
  }
}

CallStatus SessionRegistry::failed(const char* fn, Slot* slot) noexcept {
  CallStatus status = CallStatus::kInternal;
  try {
    std::string text;
    const auto set = [&](CallStatus s, const char* prefix, const char* what) {
      status = s;  // first: running out of memory while copying the message keeps the status
      text = std::string(fn) + ": " + prefix + what;
    };
    try {
      throw;
    } catch (const CallError& e) {
      set(e.status, "", e.what());
    } catch (const calib::InputError& e) {
      set(CallStatus::kInput, "", e.what());
    } catch (const calib::ArgumentError& e) {
      set(CallStatus::kInvalidArgument, "", e.what());
    } catch (const calib::NumericalError& e) {
      set(CallStatus::kNumerical, "", e.what());
    } catch (const std::bad_alloc&) {
      set(CallStatus::kOutOfMemory, "", "out of memory");
    } catch (const std::length_error&) {  // a count beyond what a container can hold (SIZE_MAX)
      set(CallStatus::kOutOfMemory, "", "out of memory (a count too large to hold)");
    } catch (const std::exception& e) {
      set(CallStatus::kInternal, "internal error: ", e.what());
    } catch (...) {
      set(CallStatus::kInternal, "internal error: ", "unknown exception");
    }
    if (slot) slot->setError(std::move(text));
    else t_unbound_error = std::move(text);
  } catch (...) {  // out of memory while keeping the message: the status still says it
  }
  return status;
}

void writePoseProgram(const std::string& path, const PoseProgram& spec, const Session* session) {
  const ProgramFormat format = programFormat(path);
  Program p;
  p.name = spec.name.empty() ? fs::path(path).stem().string() : spec.name;
  // the name becomes the program's DEF / MODULE / def line
  if (!isDeclarableName(p.name))
    throw calib::ArgumentError(std::string(spec.name.empty() ? "the file's name" : "program_name") +
                               ": expected a program name (a letter, '_' or '$', then letters, digits, '_' or '$'; at most 64 "
                               "characters), found '" + calib::printableBytes(p.name) + "'");
  p.robot = spec.robot.empty() && session ? session->job().calibrated.nominal.name : spec.robot;
  p.written_by = "the accura plug-in (accura_write_program)";
  FrameSetting tool, base;
  tool.source = base.source = FrameSetting::Source::kInline;
  tool.value = checkedPose(spec.tool, "tool");
  base.value = checkedPose(spec.base, "base");
  for (size_t i = 0; i < spec.motions.size(); ++i) {
    const PoseProgramMotion& c = spec.motions[i];
    const std::string w = "motions[" + std::to_string(i) + "]";
    Motion m;
    m.type = c.type;
    m.target.setPose(checkedPose(c.end, w + ".end"));
    if (m.type == MotionType::kCirc) {
      m.aux = Target{};
      m.aux->setPose(checkedPose(c.aux, w + ".aux"));
    }
    if (c.approximate) m.approximation = {m.type == MotionType::kPtp ? Approximation::kCPtp : Approximation::kCDis};
    if (!(c.vel_m_s <= 10)) throw calib::ArgumentError(w + ".vel_m_s: expected a path speed up to 10 m/s (0: not set), found " + shownValue(c.vel_m_s));
    if (m.type != MotionType::kPtp && c.vel_m_s > 0) m.vel_m_s = c.vel_m_s;
    if (!c.joints.empty() && !session)
      throw calib::ArgumentError(w + ".joints: the configuration needs the robot's geometry: load a model first");
    if (!c.joints.empty() && m.type == MotionType::kPtp) {
      const calib::Configuration st = session->configurationAt(c.joints, c.end, spec.tool, spec.base, w + ".joints");
      m.target.status = st.status;
      m.target.turn = st.turn;
    }
    m.tool = tool;
    m.base = base;
    p.motions.push_back(m);
  }
  calib::createDirectories(fs::path(path).parent_path().string());
  calib::writeFilesAtomically(renderProgram(p, format, path));
}

}  // namespace accura::postproc
