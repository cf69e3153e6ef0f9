// Compensation of a whole program (see job.h).
#include "accura/postproc/job.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <iomanip>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"
#include "accura/calib/joint_map.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/text.h"
#include "accura/calib/ur_calibration.h"
#include "accura/postproc/krl.h"
#include "accura/postproc/path_job.h"
#include "accura/postproc/placement.h"
#include "accura/postproc/rapid.h"
#include "accura/postproc/urscript.h"
#include "excerpt.h"
#include "path_geometry.h"

namespace accura::postproc {
namespace {

std::string targetLabel(const Target& t) { return t.name.empty() ? std::string("the inline target") : t.name; }

/// The name a new RAPID point is derived from: the point's own, or for an element of a
/// robtarget array, which has none to add a suffix to, the array's name and the indices in
/// `name` as they are written there, letters and digits only (`pts{2}` -> pts_2, `grid{ 1, 3 }`
/// -> grid_1_3, `pts{k}` -> pts_k; a new point pts_2_1 is a scalar robtarget declared after the
/// array). `name` is the motion's target as written for the new point of a motion that needs
/// another correction and for a split MoveC's circle point (`MoveJ pts{k}` -> pts_k_1), the
/// element's declaration name for the new point of an element read elsewhere
/// (copyPointsReadElsewhere: `pts{2}` -> pts_2_1, also when the motion writes pts{k}).
std::string rapidPointBase(const std::string& name) {
  const size_t open = name.find('{');
  if (open == std::string::npos || name.back() != '}' || !isDeclarableName(name.substr(0, open))) return name;
  std::string base = name.substr(0, open), item;
  for (size_t i = open + 1; i < name.size(); ++i) {
    const char c = name[i];
    if (std::isalnum(static_cast<unsigned char>(c)) || c == '_') {
      item += c;
    } else if (c == ',' || c == '}') {  // (a sign or blanks: left out)
      base += "_" + (item.empty() ? std::string("i") : item);
      item.clear();
    }
  }
  return base;
}

/// Where a new point for `name` is declared and that `name` keeps its value, in a warning's
/// words: "p20, which keeps", or for an element of a robtarget array "the array pts; pts{2}
/// keeps" (KRL's XPA[1] gets no new point).
std::string declaredAfterAndKeeps(const std::string& name) {
  const size_t open = name.find('{');
  return open == std::string::npos ? name + ", which keeps" : "the array " + name.substr(0, open) + "; " + name + " keeps";
}

std::string frameHint(const FrameSetting& f, const char* var) {
  std::string s = std::string(var) + " ";
  switch (f.source) {
    case FrameSetting::Source::kUnset:
      if (!f.note.empty()) return f.note;  // the reader's own hint (URScript: set_tcp)
      return s + "is not set before this motion (assign " + var + " or use BAS(#" + (std::string(var) == "$TOOL" ? "TOOL" : "BASE") +
             ",n) in the program, or give the frame active on the controller with " +
             (std::string(var) == "$TOOL" ? "--program-tool" : "--program-base") + " x,y,z,A,B,C)";
    case FrameSetting::Source::kData:
      return s + "is " + f.text + " (set at " + f.where.str() + "), whose value needs the $config.dat (--config)" ;
    default:
      return s + "is '" + f.text + "' (set at " + f.where.str() + "), which accura cannot evaluate" + (f.note.empty() ? "" : ": " + f.note);
  }
}

}  // namespace

// A URScript program runs on a Universal Robots controller, whose arm has joints 2, 3 and 4
// parallel and no spherical wrist (alpha 90, 0, 0, 90, -90, 0 up to sign; a4 = a5 = a6 = 0): its
// shoulder/elbow/wrist branches (docs/urscript.md) are those of that geometry. Another arm
// (a KUKA or ABB model given by mistake) would be compensated into nonsense without a word.
bool universalRobotsArm(const calib::RobotDefinition& d) {
  if (d.dof() != 6) return false;
  const double alpha[6] = {90, 0, 0, 90, 90, 0};
  for (int i = 0; i < 6; ++i) {
    const calib::JointSpec& j = d.joints[static_cast<size_t>(i)];
    if (j.type != calib::JointType::kRevolute) return false;
    const double a = std::fmod(std::fabs(j.alpha_deg), 180.0);
    if (std::min(std::fabs(a - alpha[i]), 180.0 - std::fabs(a - alpha[i])) > 1.0) return false;
    if (i >= 3 && std::fabs(j.a_mm) > 1.0) return false;
  }
  return true;
}

bool controllerReadsConfiguration(const calib::RobotDefinition& robot) { return !universalRobotsArm(robot); }

calib::Configuration askedConfiguration(bool reads, const calib::Configuration& written, bool position_known) {
  if (reads) return written;
  return position_known ? calib::Configuration{} : calib::Configuration{written.status, -1};
}

namespace {

class Job {
 public:
  Job(const JobSettings& s, JobReport* r)
      : s_(s), r_(*r), models_(s, placeRobot(s)), reads_st_(controllerReadsConfiguration(s.calibrated.nominal)) {
    r_.robroot_in_world = calib::toXyzAbc(models_.placement().T_world_robroot);
    r_.calibrated_base_in_world = calib::toXyzAbc(models_.placement().T_world_calbase);
  }

  void error(const SourceLocation& w, const std::string& msg) { r_.errors.push_back({w, msg}); }
  void warning(const SourceLocation& w, const std::string& msg) { r_.warnings.push_back({w, msg}); }

  // The pose (program base frame) of a world pose.
  calib::XyzAbc toProgram(const Eigen::Isometry3d& T_world_progbase, const Eigen::Isometry3d& T_world_tcp) const {
    return calib::toXyzAbc(T_world_progbase.inverse() * T_world_tcp);
  }

  /// The corrected pose `p` (program base) into `t`; a correction that rounds to zero at the
  /// written precision leaves `t` as it was (not modified: its text is written back unchanged).
  /// `before`: for a partial target, the command the controller stands at when the motion's
  /// statement starts (program base and tool; commandBefore).
  void setPose(Target& t, const calib::XyzAbc& p, const std::optional<calib::XyzAbc>& before = std::nullopt) {
    if (t.completePose() || !before) {
      if (t.setPoseIfChanged(p) || t.new_declaration) t.modified = true;
      return;
    }
    // A partial aggregate (LIN {Z 500}): KSS takes its missing components from the position the
    // robot is at when the motion starts -- the command before it (the previous target as
    // corrected, or the last point inserted before the statement) -- not from the intended
    // position accura completed it with. The target the controller runs is the written
    // components plus those: when that is the corrected pose at the written precision, the text
    // stays as it is (the nominal robot returns it byte for byte). Otherwise the written
    // components are corrected, and a missing one is added where the corrected pose needs
    // another value than the controller would take: left out, it would carry the previous
    // point's correction, not this one's.
    const double b[6] = {before->x_mm, before->y_mm, before->z_mm, before->a_deg, before->b_deg, before->c_deg};
    Target as_run = t;
    for (int k = 0; k < 6; ++k)
      if (!as_run.pose[k]) as_run.pose[k] = b[k];
    if (!as_run.setPoseIfChanged(p)) {
      if (t.new_declaration) t.modified = true;
      return;
    }
    const auto text = [](int k, double v) { return k < 3 ? formatMm(v) : formatDeg(v); };
    for (int k = 0; k < 6; ++k)
      if (t.pose[k] || text(k, *as_run.pose[k]) != text(k, b[k])) t.pose[k] = as_run.pose[k];
    t.modified = true;
  }

  /// CP motions (LIN, CIRC, their spline and relative forms, SPL): the controller keeps the
  /// Status of the start and lets Turn follow the path; the programmed S/T are not used
  /// (docs/program-formats.md, "Status and Turn"). The target was compensated on the
  /// configuration the robot has along the path; S/T are kept as written, a disagreement is
  /// collected for the one warning of the program (flushCpConfigurations).
  void noteCpConfiguration(const Motion& m, const Target& t, const Compensator& comp, const Eigen::VectorXd& q) {
    if (!t.status && !t.turn) return;
    const calib::Configuration asked{t.status.value_or(-1), t.turn.value_or(-1)};
    const calib::Configuration got = calib::kukaConfiguration(comp.controller().model(), q);
    if (calib::configurationMatches(asked, got)) return;
    if (cp_disagree_.empty())
      cp_first_ = targetLabel(t) + " (" + m.where.str() + "): written S " + std::to_string(asked.status) + ", T " +
                  std::to_string(asked.turn) + ", along the path S " + std::to_string(got.status) + ", T " + std::to_string(got.turn);
    cp_disagree_.push_back(targetLabel(t));
    if (!cp_where_.line) cp_where_ = m.where;
  }

  /// A program that sets its payload (URScript set_payload, KRL $LOAD) runs its motions with
  /// loads the compensation does not follow: it takes one payload for every motion
  /// (JobSettings::context, --payload-kg). Said once, at the first such statement, where the
  /// model's joint compliance makes the correction depend on the load.
  void notePayloadChanges(const Program& in) {
    bool compliant = false;
    for (double c : s_.calibrated.deviations.compliance) compliant = compliant || c != 0;
    if (!compliant) return;
    std::vector<std::pair<SourceLocation, std::string>> loads;
    // the mass a statement sets, read at `from`: the payload the compensation takes is nothing to say
    const auto sameMass = [&](const char* from) {
      char* stop = nullptr;
      const double kg = std::strtod(from, &stop);
      return stop != from && std::abs(kg - s_.context.payload_kg) <= 1e-9;
    };
    if (in.urscript)
      for (const auto& o : in.urscript->others)
        for (const char* call : {"set_payload(", "set_target_payload("}) {
          // the call by its whole name (not set_payload_cog): set_payload(m, ...)
          const size_t at = o.text.find(call);
          if (at == std::string::npos || (at > 0 && (std::isalnum(static_cast<unsigned char>(o.text[at - 1])) || o.text[at - 1] == '_')))
            continue;
          if (!sameMass(o.text.c_str() + at + std::strlen(call))) loads.push_back({o.where, o.text});
          break;
        }
    for (const PassThrough& p : in.passthrough) {
      if (p.language != "KRL") continue;
      // an assignment to $LOAD or $LOAD.M at the statement's start ($LOAD.M = m, $LOAD = {M m, ...}),
      // not a comparison or a read
      std::string up = p.text.substr(0, p.text.find(';'));  // before a comment
      for (char& ch : up) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
      const size_t first = up.find_first_not_of(" \t");
      if (first == std::string::npos || up.compare(first, 5, "$LOAD") != 0) continue;
      const size_t eq = up.find('=', first);
      if (eq == std::string::npos || (eq + 1 < up.size() && up[eq + 1] == '=')) continue;
      const size_t m = up.find('M', eq);
      const bool whole = up.compare(first, 7, "$LOAD.M") == 0;
      const char* mass = whole ? up.c_str() + eq + 1 : m != std::string::npos ? up.c_str() + m + 1 : nullptr;
      if (!mass || !sameMass(mass)) loads.push_back({p.where, p.text});
    }
    if (loads.empty()) return;
    warning(loads.front().first, "the program sets its payload here ('" + loads.front().second + "'" +
                                     (loads.size() > 1 ? ", and " + std::to_string(loads.size() - 1) + " more time(s)" : std::string()) +
                                     "); the compensation takes one payload for every motion, " +
                                     calib::formatFixed(s_.context.payload_kg, 2) +
                                     " kg (--payload-kg), and the model's joint compliance makes the correction depend on it");
  }

  /// A URScript program's set_gravity(d) states the arm's mounting: d is the acceleration "away
  /// from the earth's centre" in Base (URScript manual, set_gravity: [0, 0, 9.82] on a floor).
  /// The model's joint compliance bends the arm under its gravity_base (the robot file's
  /// <gravity>, in DH frame 0); a d more than kGravityDisagreeDeg from its opposite (a wall or
  /// ceiling mount, a tilted base) means the deflections corrected are another mounting's, and
  /// a d accura cannot read (a variable) leaves the mounting unknown: said once, at the first.
  void noteGravity(const Program& in) {
    bool compliant = false;
    for (double c : s_.calibrated.deviations.compliance) compliant = compliant || c != 0;
    if (!compliant || !in.urscript) return;
    // Base -> DH frame 0 (settingsForProgram's $ROBROOT: frame 0 in Base)
    const Eigen::Matrix3d R_frame0_base =
        s_.robroot_in_kukaworld ? Eigen::Matrix3d(calib::toIsometry(*s_.robroot_in_kukaworld).linear().transpose()) : Eigen::Matrix3d::Identity();
    Eigen::Vector3d model = s_.calibrated.nominal.gravity_base.normalized();
    for (int k = 0; k < 3; ++k) model[k] = std::abs(model[k]) < 1e-12 ? 0.0 : model[k];
    for (const UrScriptSource::Gravity& o : in.urscript->gravity) {
      const Eigen::Vector3d d = o.d ? Eigen::Vector3d((*o.d)[0], (*o.d)[1], (*o.d)[2]) : Eigen::Vector3d::Zero();
      std::string problem;
      if (!(d.norm() > 0)) {
        problem = "accura cannot read its direction: the mounting the arm runs with is not known";
      } else {
        Eigen::Vector3d g = R_frame0_base * -d.normalized();
        const double deg = std::acos(std::clamp(g.dot(model), -1.0, 1.0)) * calib::kRadToDeg;
        if (!(deg > kGravityDisagreeDeg)) continue;
        for (int k = 0; k < 3; ++k) g[k] = std::abs(g[k]) < 5e-4 ? 0.0 : g[k];  // (no "-0.000")
        std::ostringstream m;
        m.setf(std::ios::fixed);
        m.precision(3);
        m << "gravity along (" << g.x() << ", " << g.y() << ", " << g.z() << ") in the robot's frame 0, " << std::setprecision(1) << deg
          << " deg from the model's <gravity> (" << std::setprecision(3) << model.x() << ", " << model.y() << ", " << model.z() << ")";
        problem = m.str();
      }
      warning(o.where, "the program sets the arm's mounting here ('" + o.text + "': " + problem +
                           "); the model's joint compliance bends the arm under its own <gravity>, so the deflections corrected are those "
                           "of another mounting (give the robot file the gravity of this one)");
      return;
    }
  }

  /// --program-tool is the TCP active on the controller before the program sets one (URScript:
  /// the installation's TCP). A script whose set_tcp comes before its first motion runs every
  /// motion with its own TCP, as the controller does (PolyScope writes the installation's TCP
  /// so at the top of each program): a --program-tool that no motion uses and that differs from
  /// that set_tcp is said, since the TCP the user believes active is not the program's.
  void noteUnusedProgramTool(const Program& in) {
    if (!s_.initial_tool || !in.urscript || in.motions.empty()) return;
    for (const Motion& m : in.motions)
      if (m.tool.source == FrameSetting::Source::kUnset) return;  // it is used
    // the TCP of the first motion: the script's set_tcp with a value (else no claim is made)
    const FrameSetting* first = &in.motions.front().tool;
    if (first->source != FrameSetting::Source::kInline || !first->value) return;
    const Eigen::Isometry3d d = calib::toIsometry(*s_.initial_tool).inverse() * calib::toIsometry(*first->value);
    const double mm = d.translation().norm(), deg = calib::rotationAngleDeg(d.linear());
    if (!(mm > s_.tool_match_mm || deg > s_.tool_match_deg)) return;
    warning(first->where, "--program-tool is not used: the program sets its TCP here (set_tcp(" + first->text +
                              ")) before its first motion, and every motion runs with the program's TCP, " + calib::formatFixed(mm, 3) +
                              " mm and " + calib::formatFixed(deg, 3) + " deg from --program-tool's (check which TCP the cell uses)");
  }

  /// A PTP target whose compensated joints lie far from the joints the nominal robot (the
  /// OLP's simulation) takes for it: next to a wrist singularity a sub-millimetre correction can
  /// turn A4 and A6 by tens of degrees. The pose is reached, but the arm's posture differs
  /// (cables, dress pack, clearance): a warning naming the joint and how far.
  void notePostureChange(const Motion& m, const Target& t, const Compensator& comp, const Eigen::Isometry3d& T_world_target,
                         const calib::Configuration& config, const Eigen::VectorXd& seed, const Eigen::VectorXd& q_real) {
    calib::IkOptions o = s_.ik;
    o.singular_threshold = 0;  // the off-line joints may lie closer to the singularity than the real ones
    const calib::IkResult nominal = comp.controller().inverse(T_world_target, config, seed, o, calib::PoseContext{});
    if (nominal.status != calib::IkStatus::kOk || nominal.q.size() != q_real.size()) return;
    Eigen::Index joint = 0;
    const double change = (q_real - nominal.q).cwiseAbs().maxCoeff(&joint);
    if (!(change > kPostureChangeDeg)) return;
    const bool revolute = comp.controller().model().nominal.joints[static_cast<size_t>(joint)].type == calib::JointType::kRevolute;
    warning(m.where, targetLabel(t) + ": the compensated joints differ from the controller model's for this pose by up to " +
                         calib::formatFixed(change, 1) + (revolute ? " deg" : " mm") + " (joint " + std::to_string(joint + 1) + ": " +
                         calib::formatFixed(nominal.q[joint], 2) + " -> " + calib::formatFixed(q_real[joint], 2) +
                         "): the pose is reached with another arm posture than the off-line simulation's (next to a "
                         "singularity); check cables, dress pack and clearance");
  }

  /// RAPID confdata as the ABB controller treats it (docs/rapid.md, "Configuration"):
  /// MoveJ with ConfJ\On goes to the programmed configuration (the compensation solves on its
  /// branch; a correction that moves axis 1, 4 or 6 across a quadrant boundary within
  /// kTurnBandDeg updates cf1/cf4/cf6 with a warning, any other mismatch is an error);
  /// MoveL/MoveC with ConfL\On follow the path and the controller stops when axis 1, 4 or 6
  /// ends more than one quadrant from the programmed one or cfx differs (an error), a
  /// one-quadrant difference is accepted (kept as written, one warning per program);
  /// ConfJ\Off / ConfL\Off: the configuration nearest the current one, confdata kept.
  bool abbConfiguration(const Motion& m, Target& t, const Compensator& comp, const Eigen::VectorXd& q, bool cp) {
    if (!t.abb_conf || !m.conf_monitored || !abbConfModelled(m)) return true;
    const std::array<int, 4> asked = *t.abb_conf;
    const std::array<int, 4> got = abbConfdata(comp.controller().model(), q);
    ++abb_checked_;
    if (asked == got) return true;
    const int axis[3] = {0, 3, 5};
    int worst = 0;
    bool near_boundary = true, at_boundary = true;
    for (int k = 0; k < 3; ++k) {
      const int d = std::abs(asked[static_cast<size_t>(k)] - got[static_cast<size_t>(k)]);
      worst = std::max(worst, d);
      const double to_boundary = std::abs(q[axis[k]] - 90.0 * std::round(q[axis[k]] / 90.0));
      if (d && to_boundary > calib::kTurnBandDeg) near_boundary = false;
      if (d && to_boundary > calib::kJointAtBoundaryDeg) at_boundary = false;
    }
    // axis 1, 4 or 6 on a quadrant boundary within the written precision (a home position at
    // 0): the written confdata holds as it is, the text stays
    if (asked[3] == got[3] && worst <= 1 && at_boundary) return true;
    ++abb_mismatched_;
    auto text = [](const std::array<int, 4>& c) {
      return "[" + std::to_string(c[0]) + "," + std::to_string(c[1]) + "," + std::to_string(c[2]) + "," + std::to_string(c[3]) + "]";
    };
    const bool cfx_same = asked[3] == got[3];
    if (cp && cfx_same && worst <= 1) {
      if (abb_disagree_.empty())
        abb_first_ = targetLabel(t) + " (" + m.where.str() + "): written " + text(asked) + ", along the path " + text(got);
      abb_disagree_.push_back(targetLabel(t));
      if (!abb_where_.line) abb_where_ = m.where;
      return true;
    }
    if (!cp && cfx_same && worst <= 1 && near_boundary) {
      // said once per point: the MoveJs that go to one declared robtarget (value) and need the
      // same change are named in that one warning (it was repeated for each of them)
      const std::string key = (t.value_id >= 0 ? std::to_string(t.value_id) : "@" + m.where.str()) + " " + text(asked) + " " + text(got);
      const std::string said = "confdata of " + targetLabel(t) + " changed from " + text(asked) + " to " + text(got) +
                               ": the correction moves axis 1, 4 or 6 within " + calib::formatFixed(calib::kTurnBandDeg, 1) +
                               " deg of a quadrant boundary across it (ConfJ\\On goes to the programmed quadrant)";
      auto it = conf_changed_.find(key);
      if (it == conf_changed_.end()) {
        conf_changed_[key] = {r_.warnings.size(), {m.where.str()}};
        warning(m.where, said);
      } else if (std::find(it->second.second.begin(), it->second.second.end(), m.where.str()) == it->second.second.end()) {
        std::vector<std::string>& motions = it->second.second;
        motions.push_back(m.where.str());
        std::string others;
        for (size_t k = 1; k < motions.size(); ++k) others += (k > 1 ? ", " : "") + motions[k];
        r_.warnings[it->second.first].message = said + "; the same for the MoveJ(s) at " + others + " (" + std::to_string(motions.size()) +
                                                " motions to this point)";
      }
      t.abb_conf = got;
      t.modified = true;
      return true;
    }
    if (abb_first_error_ < 0) abb_first_error_ = static_cast<int>(r_.errors.size());
    if (cp)
      error(m.where, "ConfL\\On: the path reaches " + targetLabel(t) + " with confdata " + text(got) + ", programmed " + text(asked) +
                         " (axis 1, 4 or 6 more than one quadrant away, or another cfx): the controller stops here; program the confdata the path has, or ConfL\\Off");
    else
      error(m.where, targetLabel(t) + " is not reachable in its programmed confdata " + text(asked) + " (ConfJ\\On; the compensated point has " + text(got) +
                         "; program that configuration, or ConfJ\\Off)");
    return false;
  }

  /// Whether the robot has the six axes ABB's confdata describe (the quadrants of axes 1, 4, 6
  /// and the arm branch of a 6-axis arm; a 7-axis arm's cfx means another thing, a 4-axis
  /// SCARA or palletiser has no axis 6): else the confdata of a RAPID target are not
  /// interpreted, kept as written, and one warning per program says so (before: the seed in the
  /// programmed quadrants wrote axes 4-6 of a 4-axis robot beyond its joint vector).
  bool abbConfModelled(const Motion& m) {
    if (s_.calibrated.dof() == 6) return true;
    if (!abb_unmodelled_where_.line) abb_unmodelled_where_ = m.where;
    return false;
  }

  /// The IK branch (KUKA Status) and a seed in the programmed quadrants of a RAPID target.
  calib::Configuration abbBranch(const Target& t) const { return {kukaStatusOfCfx((*t.abb_conf)[3]), -1}; }
  Eigen::VectorXd abbSeed(const Target& t) const {
    Eigen::VectorXd q = q_real_ ? *q_real_ : Eigen::VectorXd::Zero(s_.calibrated.dof());
    const std::array<int, 4>& c = *t.abb_conf;
    q[0] = (c[0] + 0.5) * 90.0;
    q[3] = (c[1] + 0.5) * 90.0;
    q[4] = (c[3] & 1) ? -45.0 : 45.0;
    q[5] = (c[2] + 0.5) * 90.0;
    return q;
  }

  void flushCpConfigurations() {
    // Most of the checked confdata off, and a stop among them: the module was not made for this
    // robot (an OLP writes the confdata its IK gives on the robot it simulated, and a calibration
    // moves a pose by millimetres, far less than a quadrant): said first, before the targets
    // (before: only the confdata errors, target by target). A program that is right gets no
    // other verdict: this changes the first message only.
    if (abb_first_error_ >= 0 && abb_mismatched_ >= 3 && 2 * abb_mismatched_ > abb_checked_) {
      ProgramIssue& e = r_.errors[static_cast<size_t>(abb_first_error_)];
      e.message = "the module looks written for another robot model than " + s_.calibrated.nominal.name + " (--robot): " +
                  std::to_string(abb_mismatched_) + " of its " + std::to_string(abb_checked_) + " targets with checked confdata (ConfJ\\On, "
                  "ConfL\\On) are reached on another configuration than the one programmed, while a calibration moves a target by "
                  "millimetres; check --robot. First: " + e.message;
      std::rotate(r_.errors.begin(), r_.errors.begin() + abb_first_error_, r_.errors.begin() + abb_first_error_ + 1);
    }
    if (abb_unmodelled_where_.line)
      warning(abb_unmodelled_where_, "the confdata of the RAPID targets are not interpreted for " + s_.calibrated.nominal.name + " (" +
                                         std::to_string(s_.calibrated.dof()) + " axes; ABB's confdata [cf1,cf4,cf6,cfx] describe a "
                                         "6-axis arm): each target is compensated on the configuration nearest the robot's, and its "
                                         "confdata are kept as written. First: this motion");
    if (!abb_disagree_.empty())
      warning(abb_where_, std::to_string(abb_disagree_.size()) + " target(s) of MoveL/MoveC carry confdata that the path does not have; with ConfL\\On " +
                              "the controller accepts axis 1, 4 and 6 within one quadrant of the programmed one, so they were compensated on " +
                              "the path's configuration and their confdata are kept as written. First: " + abb_first_);
    if (exact_stop_points_ > 0)
      warning(exact_stop_where_, std::to_string(exact_stop_points_) + " auxiliary point(s) were added to " + std::to_string(exact_stop_motions_) +
                                     " motion(s) programmed with an exact stop; each point is an exact stop too, so the robot stops at "
                                     "each (a weld or a bead may show it). Approximate those motions (KRL C_DIS, a RAPID zone, a "
                                     "URScript blend radius) to pass the points without stopping. First: this motion");
    if (cp_disagree_.empty()) return;
    warning(cp_where_, std::to_string(cp_disagree_.size()) + " target(s) of CP motions (LIN, CIRC, SLIN, SCIRC, SPL) carry S/T that " +
                           "the path does not have; the controller ignores them on CP motions (Status is kept from the start, " +
                           "Turn follows the path), so they were compensated on the path's configuration and their S/T are " +
                           "kept as written. First: " + cp_first_);
  }

  /// One point (value) used by several motions must get one correction. S and T count only
  /// where a PTP uses the point: the controller ignores them on CP motions (LIN, CIRC, ...), so
  /// a point a PTP and a LIN share is written with the PTP's S/T (unifyClaimedConfigurations).
  /// A motion that needs another correction of the point (another tool, base or path) goes to a
  /// point of its own (ownPoint: KRL and RAPID); where the program has no declarations to add
  /// one to (URScript, XML) that is an error.
  void claimValue(Target& t, const SourceLocation& motion, bool cp) {
    if (t.value_id < 0) return;
    Target pose_only = t;
    pose_only.status.reset();
    pose_only.turn.reset();
    Claim c{krlAggregate(pose_only), motion, cp, t.status, t.turn};
    // RAPID: a robtarget a module given with --config declares, which accura only reads: a
    // correction goes to a new point of this module, one per distinct correction (ownPoint)
    if (const std::string place = taskModuleOf(t); !place.empty()) {
      // (by the pose: a MoveJ and a MoveL to it share one new point, written with the MoveJ's
      // confdata as a declared point is, rapid_writer.cpp)
      if (t.modified) ownPoint(t, motion, "", motion, c.pose_text, place);
      return;
    }
    auto it = claimed_.find(t.value_id);
    if (it == claimed_.end()) {
      claimed_[t.value_id] = c;
      return;
    }
    Claim& old = it->second;
    const bool same_configuration = old.status == c.status && old.turn == c.turn;
    if (old.pose_text != c.pose_text || (!old.cp && !cp && !same_configuration)) {
      const std::string conflict = targetLabel(t) + " needs a different correction here than at " + old.where.str() +
                                   " (the same point with another tool, base or path)";
      if (in_ && (in_->krl || in_->rapid) && !t.name.empty())
        return ownPoint(t, motion, conflict, old.where,
                        c.pose_text + (cp ? std::string() : " S " + std::to_string(c.status.value_or(-1)) + " T " + std::to_string(c.turn.value_or(-1))));
      error(motion, conflict + ": give the motions their own points");
      return;
    }
    if (old.cp && !cp) old = c;  // the PTP's S/T are the ones the point needs
  }

  /// Motion `motion` needs point `t` corrected otherwise than the motion at `first` did (to
  /// `correction`: its pose, and its S/T for a PTP): the controller runs both, so the motion
  /// goes to a new point declared after the one it named (the point keeps the first
  /// correction), one new point per distinct correction, as a point the program also reads
  /// elsewhere does (copyPointsReadElsewhere). Said once per new point: `conflict` (claimValue's
  /// words), and where the motion goes.
  /// `task_place`: t is a robtarget a module given with --config declares there
  /// (RapidSource::Decl::task_module), which keeps its value: every correction of it goes to a
  /// new point of this module, said so instead of `conflict`.
  void ownPoint(Target& t, const SourceLocation& motion, const std::string& conflict, const SourceLocation& first,
                const std::string& correction, const std::string& task_place = std::string()) {
    const std::string key = std::to_string(t.value_id) + "|" + correction;
    auto it = own_points_.find(key);
    if (it == own_points_.end()) {
      // KRL: an array's element (XPA[1]) has no name to derive a new one from: the motion gets
      // its corrected value as an inline aggregate, as a split CIRC's point and a point read
      // elsewhere do (`XPA[1]_1` was written, which the controller does not load). RAPID: a
      // scalar robtarget named after the array and the index (rapidPointBase).
      const std::string base = in_->rapid ? rapidPointBase(t.name) : t.name;
      const std::string name = isDeclarableName(base) ? newPointName(*in_, base, new_names_) : std::string();
      if (!name.empty()) new_names_.push_back(name);
      it = own_points_.emplace(key, name).first;
      if (!task_place.empty())
        warning(motion, t.name + " is declared in " + task_place + ", a module given with --config, which accura only reads: this motion " +
                            "goes to a new point " + name + " declared in this module (LOCAL, after its data) with the correction; " + t.name +
                            " keeps its value");
      else
        warning(motion, conflict + (name.empty() ? ": this motion gets its corrected value as an inline aggregate (" + t.name +
                                                     " has no name of its own to derive a new point's from); " + t.name + " keeps the correction for " +
                                                     first.str()
                                               : ": this motion goes to a new point " + name + " declared after " + declaredAfterAndKeeps(t.name) +
                                                     " the correction for " + first.str()));
    }
    if (!it->second.empty()) own_point_names_.push_back({motion, t.name, it->second});
    t.replaces = t.name;
    t.new_declaration = true;
    t.name = it->second;
    if (in_->rapid) t.value_id = -1;  // (RAPID's writer finds the declaration by the statement; KRL's by the value)
  }

  /// Where a module given with --config declares the RAPID robtarget `t` is
  /// (RapidSource::Decl::task_module); "" for any other target.
  std::string taskModuleOf(const Target& t) const {
    if (!in_ || !in_->rapid || t.value_id < 0 || static_cast<size_t>(t.value_id) >= in_->rapid->values.size()) return std::string();
    const int d = in_->rapid->values[static_cast<size_t>(t.value_id)].decl;
    return d >= 0 ? in_->rapid->decls[static_cast<size_t>(d)].task_module : std::string();
  }

  /// The S/T of every point a PTP claimed, on the CP motions that share it (claimValue).
  void unifyClaimedConfigurations(Program& out) const {
    auto unify = [&](Target& t) {
      const auto it = claimed_.find(t.value_id);
      if (t.value_id < 0 || t.new_declaration || it == claimed_.end() || it->second.cp) return;
      t.status = it->second.status;
      t.turn = it->second.turn;
    };
    for (Motion& m : out.motions) {
      if (m.type == MotionType::kPtp) continue;
      unify(m.target);
      if (m.aux) unify(*m.aux);
    }
  }

  void reportTarget(const Motion& m, const Target& t, const char* role, const Eigen::Isometry3d& T_world_progbase,
                    const Eigen::Isometry3d& desired, const Eigen::Isometry3d& command, bool calibrated_tool,
                    const Eigen::VectorXd& q_real = Eigen::VectorXd()) {
    TargetReport tr;
    tr.where = t.where.file.empty() ? m.where : t.where;
    tr.motion = m.where;
    tr.name = t.name;
    tr.role = role;
    tr.motion_type = motionKeyword(m);
    tr.instruction = motionInstruction(m);
    const Eigen::Vector3d d_world = command.translation() - desired.translation();
    tr.correction_mm = d_world.norm();
    tr.correction_deg = calib::rotationAngleDeg(command.linear() * desired.linear().transpose());
    const Eigen::Vector3d d_base = T_world_progbase.linear().transpose() * d_world;
    tr.dx_mm = d_base.x();
    tr.dy_mm = d_base.y();
    tr.dz_mm = d_base.z();
    tr.calibrated_tool = calibrated_tool;
    tr.q_real = q_real;
    r_.targets.push_back(tr);
  }

  // The configuration of the compensated joints `q` against the one the target names. A T bit
  // of a joint within kTurnBandDeg of 0 that the correction flips is updated in `t` (with a
  // warning): the same arm posture, and the controller needs the new sign to find q. Any
  // other change is an error.
  bool checkConfig(const Motion& m, Target& t, const Compensator& comp, const Eigen::VectorXd& q, const Eigen::Isometry3d& T_world_target) {
    const calib::Configuration asked{t.status.value_or(-1), t.turn.value_or(-1)};
    if (asked.status < 0 && asked.turn < 0) return true;
    const calib::Configuration got = calib::kukaConfiguration(comp.controller().model(), q);
    if (calib::configurationMatches(asked, got)) return true;
    // a joint at 0 within the written precision: the written T holds as it is (either sign
    // reaches the same pose; the text stays)
    if (calib::onlyTurnBitsNearZeroDiffer(asked, got, q, calib::kJointAtBoundaryDeg)) return true;
    const bool only_near_zero = calib::onlyTurnBitsNearZeroDiffer(asked, got, q);
    if (only_near_zero) {
      warning(m.where, "T of " + targetLabel(t) + " changed from " + std::to_string(asked.turn) + " to " + std::to_string(got.turn) +
                           ": the correction moves a joint that is within " + calib::formatFixed(calib::kTurnBandDeg, 1) + " deg of 0 across 0");
      t.turn = got.turn;
      return true;
    }
    // a target the controller cannot reach in its programmed S/T at all is said to be that,
    // not a boundary case of the compensation (issue 17)
    const calib::IkResult nominal = comp.controller().inverse(T_world_target, asked, q, s_.ik, s_.context);
    if (nominal.status != calib::IkStatus::kOk) {
      error(m.where, targetLabel(t) + " is not reachable in its programmed configuration S " + std::to_string(asked.status) + ", T " +
                         std::to_string(asked.turn) + " (the robot reaches it with S " + std::to_string(got.status) + ", T " +
                         std::to_string(got.turn) + "; program that configuration)");
      return false;
    }
    // the Turn bits alone differ and a joint's value with the programmed sign (360 deg away) lies
    // beyond its limit: the corrected target needs the joint past its limit in the programmed
    // configuration (a target programmed next to a limit), which is what to say
    if (asked.turn >= 0 && (asked.status < 0 || asked.status == got.status)) {
      const calib::RobotDefinition& robot = comp.controller().model().nominal;
      for (int i = 0; i < robot.dof() && i < 30; ++i) {
        const calib::JointSpec& j = robot.joints[static_cast<size_t>(i)];
        if (j.type != calib::JointType::kRevolute || ((asked.turn ^ got.turn) >> i & 1) == 0) continue;
        const double programmed = q[i] < 0 ? q[i] + 360.0 : q[i] - 360.0;  // the value with the programmed sign
        if (programmed >= j.lower && programmed <= j.upper) continue;
        error(m.where, "the compensation of " + targetLabel(t) + " needs joint " + std::to_string(i + 1) + " (" + j.name + ") at " +
                           calib::formatFixed(programmed, 2) + " deg in its programmed configuration S " + std::to_string(asked.status) +
                           ", T " + std::to_string(asked.turn) + ", beyond its limit " +
                           calib::formatFixed(programmed > j.upper ? j.upper : j.lower, 2) +
                           " deg (the target is programmed next to the limit; the robot reaches it only with T " +
                           std::to_string(got.turn) + ", joint " + std::to_string(i + 1) + " at " + calib::formatFixed(q[i], 2) +
                           " deg: move the target away from the limit or give that configuration)");
        return false;
      }
    }
    error(m.where, "the compensation of " + targetLabel(t) + " would change its configuration from S " + std::to_string(asked.status) +
                       ", T " + std::to_string(asked.turn) + " to S " + std::to_string(got.status) + ", T " + std::to_string(got.turn) +
                       " (the target is next to a configuration boundary; move it away or give the other configuration)");
    return false;
  }

  void run(const Program& in, Program& out) {
    in_ = &in;
    if (!in.robot.empty() && in.robot != s_.calibrated.nominal.name) {
      SourceLocation w;
      w.file = in.source_file;
      warning(w, "the program was made for the robot '" + in.robot + "', the model is a '" + s_.calibrated.nominal.name + "'");
    }
    std::vector<size_t> first_out;  // the first output motion of each input motion
    first_out.reserve(in.motions.size());
    // (room for a few auxiliary points: a long path is not reallocated, twice its size, at its end)
    out.motions.reserve(out.motions.size() + in.motions.size() + in.motions.size() / 16 + 16);
    for (const Motion& m : in.motions) {
      first_out.push_back(out.motions.size());
      if (m.inserted) {  // already compensated once: keep as it is
        out.motions.push_back(m);
        continue;
      }
      const size_t mark = out.motions.size();
      try {
        motion(m, out);
      } catch (const calib::NumericalError& e) {  // e.g. a CIRC whose three points are collinear
        cannotCompensate(m, mark, out, e.what());
      } catch (const calib::ArgumentError& e) {
        cannotCompensate(m, mark, out, e.what());
      }
    }
    flushCpConfigurations();
    notePayloadChanges(in);
    noteGravity(in);
    noteUnusedProgramTool(in);
    unifyClaimedConfigurations(out);
    for (const OwnPointName& o : own_point_names_) reportNewName(o.motion, o.old_name, o.new_name);
    copyPointsReadElsewhere(out);
    copyRapidPointsReadElsewhere(out);
    checkKeptValues(out);
    checkElementsChosenAtRunTime(out);
    noteGlobalPoints(out);
    noteInlinedPoints(out);
    // the pass-through statements stay before their motion, ahead of the points inserted
    out.passthrough = in.passthrough;
    for (PassThrough& s : out.passthrough)
      s.before_motion = s.before_motion < first_out.size() ? first_out[s.before_motion] : out.motions.size();
  }

 private:
  /// A Cartesian motion ready to compensate: its frames, models and complete targets (world).
  struct Cartesian {
    Eigen::Isometry3d tool, T_world_progbase, T_world_end;
    const ToolModels* models = nullptr;
    Target end;
    std::optional<Target> aux;
    calib::Configuration config;
  };

  /// Where the controller stands when the statement of a motion starts, in the program's base
  /// and the motion's tool (c): the last point inserted before the statement (`commanded`: the
  /// motion's pieces), else the previous motion's command (the controller's forward
  /// kinematics of the joints it ended on). Nothing when that is not known.
  std::optional<calib::XyzAbc> commandBefore(const Cartesian& c, const std::vector<PathSegment>* commanded = nullptr) const {
    if (commanded && commanded->size() > 1) return toProgram(c.T_world_progbase, (*commanded)[commanded->size() - 2].T_world_end);
    if (!q_real_) return std::nullopt;
    return toProgram(c.T_world_progbase, c.models->compensator->controller().forward(*q_real_));
  }

  void forget() {
    // the joints last known: the guess of where the robot stands for a motion whose start is
    // not known and whose target names no configuration (the robot keeps its configuration
    // unless a motion changes it; a loop or a branch usually comes back to it)
    if (q_real_) {
      q_hint_ = q_real_;
      hint_where_ = q_real_where_;
    }
    q_real_.reset();
    T_world_flange_intended_.reset();
  }

  /// `mo` (the motion, as far as it was changed) kept in the output; the position after it
  /// is not known. The caller recorded why (an error or a warning).
  void keep(Program& out, const Motion& mo) {
    forget();
    for (const Target* t : {&mo.target, mo.aux ? &*mo.aux : nullptr})
      if (t && t->value_id >= 0 && !kept_values_.count(t->value_id)) kept_values_[t->value_id] = mo.where;
    out.motions.push_back(mo);
  }

  /// The report's target of the motion at `motion` named `old` goes to the new point `now` (new_point_replaces).
  void reportNewName(const SourceLocation& motion, const std::string& old, const std::string& now) {
    for (TargetReport& tr : r_.targets)
      if (tr.motion.str() == motion.str() && tr.name == old && tr.new_point_replaces.empty()) {
        tr.name = now;
        tr.new_point_replaces = old;
      }
  }

  /// A corrected point the program also reads other than as a motion's target (KRL: `$BASE =
  /// XFB`, `XP2 = XFB`; KrlSource::Value::read_elsewhere): written into its declaration, the
  /// correction would move that frame or point too, and every motion after it. The declaration
  /// keeps its value; the motions that correct it go to a new point declared after it (a point
  /// declared in the .src: an inline aggregate in each motion). Said once per point.
  void copyPointsReadElsewhere(Program& out) {
    if (!in_ || !in_->krl) return;
    const std::vector<KrlSource::Value>& values = in_->krl->values;
    std::map<int, std::string> copies;  // value id -> the new point's name ("": inline)
    for (Motion& m : out.motions)
      for (Target* t : {&m.target, m.aux ? &*m.aux : nullptr}) {
        if (!t || !t->modified || t->new_declaration || t->value_id < 0 || static_cast<size_t>(t->value_id) >= values.size()) continue;
        const KrlSource::Value& v = values[static_cast<size_t>(t->value_id)];
        if (v.read_elsewhere.empty()) continue;
        auto it = copies.find(t->value_id);
        if (it == copies.end()) {
          const bool in_dat = isDeclarableName(t->name) && v.file == 1;
          const std::string name = in_dat ? newPointName(*in_, t->name, new_names_) : std::string();
          if (in_dat) new_names_.push_back(name);
          it = copies.emplace(t->value_id, name).first;
          warning(m.where, targetLabel(*t) + " is also read at " + v.read_elsewhere + ", which its correction would move: " +
                               "its declaration keeps its value, and " +
                               (name.empty() ? std::string("the motions that correct it get the corrected value as an inline aggregate")
                                             : "the motions that correct it go to the new point " + name + " (declared after it)"));
        }
        if (!it->second.empty()) reportNewName(m.where, t->name, it->second);
        t->replaces = t->name;
        t->new_declaration = true;
        t->name = it->second;
      }
  }

  /// RAPID: a robtarget that motions correct and that the program also reads other than as
  /// a motion's plain ToPoint/CirPoint (RapidSource::Decl::read_elsewhere: `p30 := p20;`, a
  /// call's argument, `Offs(p20, 0, 0, dz)` of a run-time dz; or an evaluated Offs/RelTool
  /// target written back as it is, uncorrected: RapidSource::Statement::target_reads) keeps its
  /// declaration: corrected, that read would silently move with a correction made for another
  /// motion's tool, base and path. The motions that correct it go to a new point declared right
  /// after it (Target::new_declaration, named by newPointName; its value_id is -1: it has no text
  /// in the module), with a warning naming where the point is also read. The report's targets
  /// name the new point (new_point_replaces).
  void copyRapidPointsReadElsewhere(Program& out) {
    if (!in_ || !in_->rapid) return;
    const RapidSource& src = *in_->rapid;
    auto targetsOf = [](Motion& m) {
      std::vector<Target*> ts;
      if (m.aux) ts.push_back(&*m.aux);
      if (m.target.kind == Target::Kind::kCartesian) ts.push_back(&m.target);
      return ts;
    };
    auto statementOf = [&](const Motion& m) -> const RapidSource::Statement* {
      if (m.inserted || m.statement_id < 0 || static_cast<size_t>(m.statement_id) >= src.statements.size()) return nullptr;
      return &src.statements[static_cast<size_t>(m.statement_id)];
    };
    auto declOf = [&](int value) {
      return value >= 0 && static_cast<size_t>(value) < src.values.size() ? src.values[static_cast<size_t>(value)].decl : -1;
    };
    // where each declaration is read: its reader's record, else an Offs/RelTool target that
    // stays as written
    std::map<int, std::string> read;
    for (size_t d = 0; d < src.decls.size(); ++d)
      if (!src.decls[d].read_elsewhere.empty()) read[static_cast<int>(d)] = src.decls[d].read_elsewhere;
    for (Motion& m : out.motions) {
      const RapidSource::Statement* st = statementOf(m);
      if (!st) continue;
      const std::vector<Target*> ts = targetsOf(m);
      for (size_t k = 0; k < ts.size() && k < st->target_reads.size(); ++k) {
        const int d = declOf(st->target_reads[k]);
        if (d >= 0 && !ts[k]->modified && !read.count(d)) read[d] = m.where.str() + " ('" + detail::excerpt(m.statement) + "')";
      }
    }
    if (read.empty()) return;
    std::map<int, std::string> renamed;  // declaration -> its new point
    for (Motion& m : out.motions) {
      const RapidSource::Statement* st = statementOf(m);
      if (!st) continue;
      const std::vector<Target*> ts = targetsOf(m);
      for (size_t k = 0; k < ts.size() && k < st->target_value.size(); ++k) {
        Target& t = *ts[k];
        const int d = declOf(st->target_value[k]);
        if (!t.modified || t.new_declaration || d < 0 || !read.count(d)) continue;
        const std::string old = t.name;
        auto it = renamed.find(d);
        if (it == renamed.end()) {
          it = renamed.emplace(d, newPointName(*in_, rapidPointBase(src.decls[static_cast<size_t>(d)].name), new_names_)).first;
          new_names_.push_back(it->second);
          warning(m.where, old + " is corrected for this motion and also read at " + read.at(d) + ", which the correction must not " +
                               "move: the motion goes to a new point " + it->second + " declared after " + declaredAfterAndKeeps(old) +
                               " its value");
        }
        t.new_declaration = true;
        t.replaces = old;
        t.name = it->second;
        t.value_id = -1;
        reportNewName(m.where, old, t.name);
      }
    }
  }

  /// A motion kept as written whose point another motion corrects is not unchanged on the
  /// robot: it moves with that correction, made for the other motion's tool, base and path.
  /// Said once per point, at the kept motion, naming the motion the correction is for (the
  /// program is still written: the controller runs it, and the shared point is the program's).
  void checkKeptValues(const Program& out) {
    std::set<int> named;
    for (const Motion& m : out.motions)
      for (const Target* t : {&m.target, m.aux ? &*m.aux : nullptr}) {
        if (!t || !t->modified || t->new_declaration || t->value_id < 0 || named.count(t->value_id)) continue;
        const auto it = kept_values_.find(t->value_id);
        if (it == kept_values_.end() || it->second.str() == m.where.str()) continue;  // (not the motion itself)
        named.insert(t->value_id);
        warning(it->second, "this motion is left as written, but its point " + targetLabel(*t) + " is corrected for the motion at " +
                                m.where.str() + ": it moves with that correction, made for that motion's tool, base and path "
                                "(give the motions their own points to keep this one as written)");
      }
  }

  /// A motion kept as written whose point the program chooses at run time among the elements
  /// of an array (KRL `LIN XPA[I]`) goes to an element another motion corrects (`LIN XPA[2]`)
  /// whenever the index names it: it moves with that correction, as in checkKeptValues. Said
  /// once per such motion, naming the first corrected element and how many there are.
  void checkElementsChosenAtRunTime(const Program& out) {
    if (!in_ || !in_->krl) return;
    struct Corrected {
      std::string first;  // "XPA[2] (corrected for the motion at ..)"
      std::set<int> ids;
    };
    std::map<std::string, std::pair<SourceLocation, Corrected>> at;  // by the kept motion's place
    for (const Motion& m : out.motions)
      for (const Target* t : {&m.target, m.aux ? &*m.aux : nullptr}) {
        if (!t || !t->modified || t->new_declaration || t->value_id < 0 || static_cast<size_t>(t->value_id) >= in_->krl->values.size())
          continue;
        for (const SourceLocation& kept : in_->krl->values[static_cast<size_t>(t->value_id)].chosen_at_run_time) {
          auto& [where, c] = at[kept.str()];
          where = kept;
          if (c.ids.empty()) c.first = targetLabel(*t) + " (corrected for the motion at " + m.where.str() + ")";
          c.ids.insert(t->value_id);
        }
      }
    for (const auto& [key, v] : at) {
      const size_t more = v.second.ids.size() - 1;
      warning(v.first, "this motion is left as written, but the element of the array it goes to is chosen at run time, and " +
                           v.second.first + (more ? " and " + std::to_string(more) + " more element(s) are" : " is") +
                           " corrected: where the index names a corrected element, the motion moves with that correction, made for "
                           "that motion's tool, base and path (give the motions their own points to keep this one as written)");
    }
  }

  /// A corrected point declared GLOBAL (KRL DECL GLOBAL E6POS XG1 in a PUBLIC data list) is
  /// the value other modules that use it go to as well: they move with a correction made for
  /// this program's tool, base and motions. Said once per point, at its declaration.
  void noteGlobalPoints(const Program& out) {
    if (!in_ || !in_->krl) return;
    std::set<int> named;
    for (const Motion& m : out.motions)
      for (const Target* t : {&m.target, m.aux ? &*m.aux : nullptr}) {
        if (!t || !t->modified || t->new_declaration || t->value_id < 0 || named.count(t->value_id)) continue;
        if (static_cast<size_t>(t->value_id) >= in_->krl->values.size() || !in_->krl->values[static_cast<size_t>(t->value_id)].global) continue;
        named.insert(t->value_id);
        warning(t->where.file.empty() ? m.where : t->where,
                "GLOBAL point " + targetLabel(*t) + " corrected for this program's tool and base (the motion at " + m.where.str() +
                    "): other modules that use it move with this correction");
      }
  }

  /// A corrected point declared outside the program's files (KRL: in the $config.dat, which is
  /// never rewritten) goes into its motion's statement as an inline aggregate (writeKrl): the
  /// robot lands on it, while other motions and modules that use the point keep its value
  /// there. Said at each such motion.
  void noteInlinedPoints(const Program& out) {
    if (!in_ || !in_->krl) return;
    for (const Motion& m : out.motions)
      for (const Target* t : {&m.target, m.aux ? &*m.aux : nullptr}) {
        if (!t || !t->modified || t->new_declaration || m.inserted || t->value_id >= 0 || t->name.empty()) continue;
        warning(m.where, t->name + " is declared in " + (t->where.file.empty() ? std::string("another file") : t->where.str()) +
                             ", which accura does not rewrite: this motion gets its corrected value as an inline aggregate; other "
                             "motions and modules that use " + t->name + " keep going to its value there");
      }
  }

  /// Motion `m`'s target cannot be evaluated (`why`): the motion is kept as written, counted
  /// and named in a warning.
  void leftUnchanged(const Motion& m, const std::string& why) {
    ++r_.motions_left_unchanged;
    warning(m.where, motionInstruction(m) + " left unchanged (not compensated): " + why + "; the position after it is not known");
  }

  void cannotCompensate(const Motion& m, size_t mark, Program& out, const char* why) {
    out.motions.resize(mark);
    error(m.where, std::string("this motion cannot be compensated: ") + why);
    keep(out, m);
  }

  /// One motion of the program into `out` (with the points inserted before it).
  void motion(const Motion& m, Program& out) {
    if (m.start_unknown) forget();
    if (after_arm_stays_) {
      // after a MoveExtJ the arm stands where it was; an external axis in this target or in the
      // one it stands on may be a track that carries the robot, which moved with the MoveExtJ
      after_arm_stays_ = false;
      bool ext = false;
      for (const Target* t : {&m.target, m.aux ? &*m.aux : nullptr})
        for (size_t k = 0; t && k < 6; ++k) ext = ext || t->ext[k].has_value() || ext_prev_[k].has_value();
      if (ext) forget();
    }
    if (m.arm_stays && !m.target_problem.empty()) {
      ++r_.motions_left_unchanged;
      warning(m.where, motionInstruction(m) + " left unchanged (not compensated): " + m.target_problem +
                           "; the robot arm does not move, so the next motion starts where it was, unless that motion's target gives an "
                           "external axis (a track may carry the robot)");
      after_arm_stays_ = true;
      out.motions.push_back(m);
      return;
    }
    if (!m.target_problem.empty()) {
      // A target the program computes at run time (Offs of a counter, CRobT, a variable the
      // program assigns, an instruction accura does not model) is a program the controller
      // runs: the motion is kept as written, not compensated, and named. A file that is missing
      // (the .dat of a named point) is the user's to give: an error.
      if (!m.target_file_missing) {
        leftUnchanged(m, m.target_problem);
      } else {
        error(m.where, "expected a target accura can correct for " + motionKeyword(m) + ", found: " + m.target_problem);
      }
      return keep(out, m);
    }
    if (m.target.kind == Target::Kind::kAxis) return axisMotion(m, out);
    if (m.circ_angle_deg) {
      // the controller runs it (the arc through the written points, turned by the angle): its
      // end is not the written target, which accura does not model
      leftUnchanged(m, "a CIRC with CA " + formatDeg(*m.circ_angle_deg) + " (circular angle) ends elsewhere than its written target");
      return keep(out, m);
    }
    // a value the reader could not follow ("?why": set in a branch, by the caller, by a call)
    for (const auto& [v, applies] : {std::make_pair(&m.ori_type, m.type != MotionType::kPtp), std::make_pair(&m.circ_type, m.type == MotionType::kCirc)})
      if (applies && orientationControlNotKnown(*v)) {
        leftUnchanged(m, "its orientation control is not known here: " + v->substr(1));
        return keep(out, m);
      }
    if (m.type != MotionType::kPtp && !m.ori_type.empty() && m.ori_type != "#CONSTANT" && m.ori_type != "#JOINT") {
      // the controller runs it; where the tool's orientation goes is not accura's to know
      leftUnchanged(m, "its orientation control $ORI_TYPE " + m.ori_type + " is not modelled (#VAR, #CONSTANT and #JOINT are)");
      return keep(out, m);
    }
    // $CIRC_TYPE #PATH: the orientation turns with the circle; with #CONSTANT the robot ends on
    // the start's orientation turned by the arc, neither the written one nor the start's
    const bool path_circ = m.type == MotionType::kCirc && !m.circ_type.empty();
    if (path_circ && (m.circ_type != "#PATH" || m.ori_type == "#CONSTANT")) {
      leftUnchanged(m, "its orientation control $CIRC_TYPE " + m.circ_type + (m.ori_type.empty() ? std::string() : " with $ORI_TYPE " + m.ori_type) +
                           " is not modelled");
      return keep(out, m);
    }
    const std::optional<Cartesian> c = cartesian(m);
    if (!c) return keep(out, m);
    const bool path = m.type == MotionType::kLin || m.type == MotionType::kCirc;
    // KSS $ORI_TYPE #JOINT: the wrist axes turn linearly from the start to the target (the
    // target's pose is reached as written), a path accura does not predict
    const bool joint_ori = m.type != MotionType::kPtp && (m.ori_type == "#JOINT" || path_circ);
    if (m.type == MotionType::kLin && T_world_flange_intended_ && !joint_ori) warnHalfTurn(m, *c);
    // ABB's MoveC turns the tool relative to the circle's path frame (CirPathMode \PathFrame,
    // RobotWare's default), the circle as accura interpolates it in the work object (KUKA's
    // #BASE, CirPathMode \ObjectFrame): the same path when the turn is about the circle's axis
    const double abb_gap_deg = path && q_real_ && !joint_ori && m.type == MotionType::kCirc && c->aux && T_world_flange_intended_ &&
                                       motionInstruction(m).rfind("MoveC", 0) == 0
                                   ? pathFrameOrientationGapDeg(*c)
                                   : 0.0;
    if (path && q_real_ && !joint_ori && !(abb_gap_deg > kPathFrameGapDeg)) return pathMotion(m, *c, out);
    if (path && q_real_ && !joint_ori) {
      warning(m.where, motionInstruction(m) + " to " + targetLabel(c->end) +
                           " turns the tool other than about the circle's axis: RobotWare turns it relative to the circle's path "
                           "(CirPathMode \\PathFrame, the default), up to " + calib::formatFixed(abb_gap_deg, 2) +
                           " deg from the turn in the work object that accura predicts (CirPathMode \\ObjectFrame): its points "
                           "are compensated, its path is not checked");
    } else if (path && q_real_) {
      warning(m.where, motionKeyword(m) + " with " +
                           (m.ori_type == "#JOINT" ? std::string("$ORI_TYPE #JOINT (the controller turns the wrist axes linearly")
                                                   : std::string("$CIRC_TYPE #PATH (the controller turns the orientation with the circle")) +
                           ", a path accura does not predict): its points are compensated, its path is not checked");
    } else if (path) {
      const bool guessed = !c->end.status && !c->end.turn && !c->end.abb_conf;
      std::string on;
      if (guessed && q_hint_)
        on = ", on the configuration of the last position known (after the motion at " + hint_where_.str() + ")";
      else if (guessed)
        on = ", on the solution nearest the middle of the joint ranges (no position known before it)";
      warning(m.where, motionKeyword(m) + " after a position that is not known: its points are compensated" + on + ", its path is not checked");
    }
    pointMotion(m, *c, out);
  }

  /// The largest angle (deg) between the tool's orientation along a circle as RobotWare turns
  /// it by default (CirPathMode \PathFrame: relative to the path frame, which turns about the
  /// circle's axis n by the arc A, R(s) = Rot(n, s A) slerp(R0, Rot(n, -A) R1, s)) and as accura
  /// interpolates it (slerp(R0, R1, s) in the work object; CirPathMode \ObjectFrame, KUKA's
  /// #BASE), at 65 points of the arc. 0 when R1 R0^T turns about n. The start is where the
  /// program meant the tool to be; an arc accura cannot build (collinear points) gives 0 (the
  /// path check says so).
  double pathFrameOrientationGapDeg(const Cartesian& c) const {
    PathSegment seg;
    seg.type = PathType::kCirc;
    seg.T_world_start = *T_world_flange_intended_ * c.tool;
    seg.T_world_aux = c.T_world_progbase * calib::toIsometry(c.aux->xyzAbc());
    seg.T_world_end = c.T_world_end;
    try {
      const detail::PathGeometry g(seg);
      const Eigen::Quaterniond q1_in_path0 = Eigen::Quaterniond(Eigen::AngleAxisd(-g.arc, g.n)) * g.q1;
      double gap = 0;
      for (int k = 0; k <= 64; ++k) {
        const double s = k / 64.0;
        const Eigen::Quaterniond abb = Eigen::Quaterniond(Eigen::AngleAxisd(s * g.arc, g.n)) * g.q0.slerp(s, q1_in_path0);
        gap = std::max(gap, calib::rotationAngleDeg(abb.toRotationMatrix() * g.pose(s).linear().transpose()));
      }
      return gap;
    } catch (const calib::NumericalError&) {
      return 0;
    }
  }
  /// A MoveC whose two orientation rules differ by more than this (deg) is not path-checked.
  static constexpr double kPathFrameGapDeg = 0.01;

  /// A linear move whose orientation turns by about 180 deg: the shortest way round is not
  /// defined there, and a controller may interpolate it either way (the tool swings through
  /// opposite sides). Warned once per motion when the turn is within 2 deg of 180 deg.
  void warnHalfTurn(const Motion& m, const Cartesian& c) {
    const Eigen::Matrix3d R = T_world_flange_intended_->linear().transpose() * (c.T_world_end * c.tool.inverse()).linear();
    const double turn = calib::rotationAngleDeg(R);
    if (std::fabs(turn - 180.0) > 2.0) return;
    warning(m.where, motionInstruction(m) + " to " + targetLabel(c.end) + " turns the tool's orientation by " + calib::formatFixed(turn, 1) +
                         " deg, within 2 deg of 180 deg: the controller may turn it either way round; add an intermediate "
                         "orientation to choose the way");
  }

  /// An axis target: nothing to compensate; the position after it is known when every joint is.
  void axisMotion(const Motion& m, Program& out) {
    const int dof = s_.calibrated.dof();
    Eigen::VectorXd q(dof);
    for (int k = 0; k < dof; ++k) {
      if (k < 6 && m.target.axes[k]) {
        q[k] = *m.target.axes[k];
      } else if (q_real_) {
        q[k] = (*q_real_)[k];
      } else {
        warning(m.where, "a partial axis target after an unknown position: the position after it is not known");
        return keep(out, m);
      }
    }
    q_real_ = q;
    q_real_where_ = m.where;
    calib::KinematicWorkspace ws;
    T_world_flange_intended_ = calib::forwardKinematics(models_.controllerFlange(), q, calib::PoseContext{}, ws);
    out.motions.push_back(m);
  }

  /// The frames (frames the program has not set yet come from the settings), the models and
  /// the complete targets of a Cartesian motion; nullopt (with the errors recorded) when the
  /// motion cannot be compensated.
  std::optional<Cartesian> cartesian(const Motion& m) {
    std::optional<calib::XyzAbc> tool = m.tool.value, base = m.base.value;
    if (m.tool.source == FrameSetting::Source::kUnset && s_.initial_tool) tool = s_.initial_tool;
    if (m.base.source == FrameSetting::Source::kUnset && s_.initial_base) base = s_.initial_base;
    const size_t errors = r_.errors.size();
    // What the controller runs and accura does not model or cannot evaluate is kept as written
    // and named, not refused (a program the controller runs is never rejected): an external TCP,
    // a frame the program sets to a run-time value (a routine's parameter, a datum assigned while
    // it runs) or to one accura does not model (a stationary tool, a work object a mechanical
    // unit moves). A frame that is missing (not set, or TOOL_DATA[n] without the $config.dat) is
    // the user's to give: an error.
    if (m.external_tcp) {
      leftUnchanged(m, "an external TCP (IPO_FRAME #TCP: the robot carries the part past a fixed tool), which accura does not model");
      return std::nullopt;
    }
    const bool tool_unknown = !tool && m.tool.source == FrameSetting::Source::kUnknown;
    const bool base_unknown = !base && m.base.source == FrameSetting::Source::kUnknown;
    if ((tool_unknown || base_unknown) && (tool || tool_unknown) && (base || base_unknown)) {
      const FrameSetting& f = tool_unknown ? m.tool : m.base;
      const bool is_tool = &f == &m.tool;
      leftUnchanged(m, "its " + std::string(is_tool ? "tool" : "base") +
                           (f.run_time ? " is a run-time value: " + f.note : ": " + frameHint(f, is_tool ? "$TOOL" : "$BASE")));
      return std::nullopt;
    }
    if (!tool) error(m.where, "the tool of this motion is not known: " + frameHint(m.tool, "$TOOL"));
    if (!base) error(m.where, "the base of this motion is not known: " + frameHint(m.base, "$BASE"));
    if (r_.errors.size() != errors) return std::nullopt;
    Cartesian c;
    c.tool = calib::toIsometry(*tool);
    c.T_world_progbase = models_.placement().T_world_kworld * calib::toIsometry(*base);
    c.models = &models_.compensator(c.tool);
    // partial targets: the missing components from where the program meant the robot to be
    auto complete = [&](Target& t, const char* what) -> bool {
      if (t.completePose()) return true;
      if (!T_world_flange_intended_) {
        // its other components are wherever the robot is at run time: the controller runs it,
        // accura cannot evaluate it (as a run-time target: kept, named)
        leftUnchanged(m, std::string("its ") + what + " (" + targetLabel(t) +
                             ") is partial and the position before it is not known");
        return false;
      }
      const calib::XyzAbc prev = toProgram(c.T_world_progbase, *T_world_flange_intended_ * c.tool);
      const double p[6] = {prev.x_mm, prev.y_mm, prev.z_mm, prev.a_deg, prev.b_deg, prev.c_deg};
      for (int k = 0; k < 6; ++k)
        if (!t.pose[k]) t.pose[k] = p[k];
      return true;
    };
    c.end = m.target;
    c.aux = m.aux;
    if (!complete(c.end, "target") || (c.aux && !complete(*c.aux, "auxiliary point"))) return std::nullopt;
    if (m.type != MotionType::kPtp && m.ori_type == "#CONSTANT") {
      // KSS $ORI_TYPE #CONSTANT: the controller keeps the orientation the motion starts with and
      // ignores the target's; the robot arrives with the orientation the program meant it to
      // have at the start (the written one stays in the target: keepIgnoredOrientation)
      if (!T_world_flange_intended_) {
        leftUnchanged(m, "$ORI_TYPE #CONSTANT keeps the orientation the robot has at its start, which is not known here");
        return std::nullopt;
      }
      const calib::XyzAbc prev = toProgram(c.T_world_progbase, *T_world_flange_intended_ * c.tool);
      c.end.pose[3] = prev.a_deg;
      c.end.pose[4] = prev.b_deg;
      c.end.pose[5] = prev.c_deg;
    }
    if (!externalAxesZero(m, c.end) || (c.aux && !externalAxesZero(m, *c.aux))) return std::nullopt;
    c.T_world_end = c.T_world_progbase * calib::toIsometry(c.end.xyzAbc());
    c.config = calib::Configuration{c.end.status.value_or(-1), c.end.turn.value_or(-1)};
    return c;
  }

  /// False (the motion named as left unchanged) when `t` moves an external axis: the robot files
  /// model none, so compensating it as if the axes did not move the robot or the part would be
  /// wrong; the controller runs it as written.
  bool externalAxesZero(const Motion& m, const Target& t) {
    const bool abb = t.abb_conf.has_value();  // RAPID: eax_a..eax_f, 9E9 (not used) read as none
    std::string moved;
    for (int k = 0; k < 6; ++k)
      if (t.ext[k] && *t.ext[k] != 0)
        moved += (moved.empty() ? "" : ", ") + (abb ? std::string("eax_") + static_cast<char>('a' + k) : "E" + std::to_string(k + 1)) + " " +
                 calib::formatFixed(*t.ext[k], 4);
    if (moved.empty()) return true;
    // the controller runs it; accura's correction would ignore the axes: kept as written, named
    leftUnchanged(m, targetLabel(t) + " moves external axes (" + moved + ": a track or a positioner), which the robot file '" +
                         s_.calibrated.nominal.name + "' does not model");
    return false;
  }

  /// PTP, or LIN / CIRC after an unknown position: each point compensated on its own.
  void pointMotion(const Motion& m, const Cartesian& c, Program& out) {
    const Compensator& comp = *c.models->compensator;
    // from an unknown position: the joints last known (q_hint_) as the guess of where the
    // robot stands, for targets that name no configuration (the nearest solution to them)
    const Eigen::VectorXd seed = q_real_ ? *q_real_ : q_hint_ ? *q_hint_ : Eigen::VectorXd();
    Motion mo = m;
    Target end = c.end;
    if (c.aux) {
      const Eigen::Isometry3d T_world_aux = c.T_world_progbase * calib::toIsometry(c.aux->xyzAbc());
      const PoseCompensation pa = comp.pose(T_world_aux, calib::Configuration{}, seed, s_.ik, s_.context);
      if (pa.status != calib::IkStatus::kOk) {
        error(m.where, "the auxiliary point " + targetLabel(*c.aux) + " cannot be compensated: " + toString(pa.status) +
                           (pa.message.empty() ? "" : ": " + pa.message));
        return keep(out, mo);
      }
      setPose(*mo.aux, toProgram(c.T_world_progbase, pa.T_world_tcp_command), commandBefore(c));
      claimValue(*mo.aux, m.where, true);
      reportTarget(m, *m.aux, "aux", c.T_world_progbase, T_world_aux, pa.T_world_tcp_command, c.models->calibrated_tool);
    }
    // a CP motion from a known position continues on the robot's configuration (nearest
    // solution); from an unknown one the written S/T are the best guess of where it stands
    const bool cp = m.type != MotionType::kPtp;
    calib::Configuration config = cp && q_real_ ? calib::Configuration{} : c.config;
    Eigen::VectorXd start = seed;
    if (c.end.abb_conf && ((!cp && m.conf_monitored) || (cp && !q_real_)) && abbConfModelled(m)) {  // RAPID: the programmed branch
      config = abbBranch(c.end);
      start = abbSeed(c.end);
    }
    // a Universal Robots controller has no Status/Turn: movej(pose) goes to the solution
    // nearest the joints the robot stands on (docs/urscript.md). S/T a program written for it
    // carries (XML from an OLP) are not asked (askedConfiguration); from an unknown position the
    // written Status stays the guess of the branch.
    config = askedConfiguration(reads_st_, config, q_real_.has_value());
    if (!cp && m.qnear_deg && s_.calibrated.dof() == 6) {
      // URScript get_inverse_kin(pose, qnear=q): the controller takes the solution nearest
      // to qnear, not to where the robot stands
      start = Eigen::Map<const Eigen::VectorXd>(m.qnear_deg->data(), 6);
      config = calib::Configuration{};
    }
    const PoseCompensation pc = comp.pose(c.T_world_end, config, start, s_.ik, s_.context);
    if (pc.status == calib::IkStatus::kSingular) {
      // The controller runs a motion to a singular point by its own rule (KUKA: a PTP end point
      // in the wrist singularity takes axis 4 at 0 deg or at its start value, $SINGUL_POS[3],
      // and adapts axis 6): the program is not refused. A correction would move the target off
      // the singularity, where axes 4 and 6 follow the correction's tiny wrist angle: kept as
      // written, and named.
      leftUnchanged(m, targetLabel(end) + " lies at a singularity of the arm, where the controller chooses the axes by its own rule (" +
                           pc.message + "); a correction would move it off the singularity, where the wrist axes follow the correction");
      return keep(out, mo);
    }
    if (pc.status != calib::IkStatus::kOk) {
      error(m.where, targetLabel(end) + " cannot be compensated: " + toString(pc.status) + (pc.message.empty() ? "" : ": " + pc.message));
      return keep(out, mo);
    }
    if (cp) noteCpConfiguration(m, end, comp, pc.q_real);
    else if (reads_st_ && !checkConfig(m, end, comp, pc.q_real, c.T_world_end)) return keep(out, mo);  // (a UR: S/T kept as written)
    if (!abbConfiguration(m, mo.target, comp, pc.q_real, cp)) return keep(out, mo);
    if (!cp) notePostureChange(m, end, comp, c.T_world_end, config, start, pc.q_real);
    setPose(mo.target, toProgram(c.T_world_progbase, pc.T_world_tcp_command), commandBefore(c));
    keepIgnoredOrientation(m, mo.target);
    if (mo.target.turn != end.turn) mo.target.modified = true;
    mo.target.turn = end.turn;
    claimValue(mo.target, m.where, cp);
    reportTarget(m, m.target, "end", c.T_world_progbase, c.T_world_end, pc.T_world_tcp_command, c.models->calibrated_tool,
                 pc.q_real);
    arrived(m, c, pc.q_real, end);
    out.motions.push_back(mo);
  }

  /// LIN / CIRC from a known position: the segment compensated, auxiliary points inserted.
  void pathMotion(const Motion& m, const Cartesian& c, Program& out) {
    const Compensator& comp = *c.models->compensator;
    Motion mo = m;
    Target end = c.end;
    PathSegment intended;
    intended.type = m.type == MotionType::kCirc ? PathType::kCirc : PathType::kLin;
    intended.T_world_end = c.T_world_end;
    if (c.aux) intended.T_world_aux = c.T_world_progbase * calib::toIsometry(c.aux->xyzAbc());
    const SegmentCompensation sc = compensateSegmentFrom(comp, intended, c.config, *q_real_, s_);
    if (sc.status != calib::IkStatus::kOk || sc.commanded.empty() || sc.q_real_end.size() != sc.commanded.size()) {
      error(m.where, "the " + motionKeyword(m) + " to " + targetLabel(end) + " cannot be compensated: " + toString(sc.status) +
                         (sc.message.empty() ? "" : ": " + sc.message));
      return keep(out, mo);
    }
    noteCpConfiguration(m, end, comp, sc.q_real_end.back());
    if (!abbConfiguration(m, mo.target, comp, sc.q_real_end.back(), true)) return keep(out, mo);
    SegmentReport sr;
    sr.motion = m.where;
    sr.motion_type = motionKeyword(m);
    sr.instruction = motionInstruction(m);
    sr.length_mm = pathLength(intended);
    sr.max_error_uncompensated_mm = sc.max_error_uncompensated_mm;
    sr.max_error_before_mm = sc.max_error_before_mm;
    sr.max_error_after_mm = sc.max_error_after_mm;
    sr.points_added = sc.points_added;
    std::vector<PathSegment> commanded = sc.commanded;
    // TRIGGER statements refer to the next motion: points inserted before this motion would
    // move them; a statement's other parts would be repeated (single_reason). Keep the single
    // motion (endpoints compensated).
    const std::string single = m.trigger_count > 0 ? "TRIGGER statements are bound to this motion" : m.single_reason;
    if (sc.points_added > 0 && !single.empty()) {
      PathSegment one = commanded.back();
      one.T_world_start = commanded.front().T_world_start;
      if (c.aux) {
        // the auxiliary point where the robot passes it (the path's orientation there), as the
        // prediction of the endpoints-only error (max_error_before_mm) took it
        const detail::PathGeometry arc(intended);
        const PoseCompensation pa = comp.pose(arc.pose(arc.s_aux), calib::Configuration{}, *q_real_, s_.ik, s_.context);
        if (pa.status != calib::IkStatus::kOk) {
          error(m.where, "the auxiliary point " + targetLabel(*c.aux) + " cannot be compensated: " + toString(pa.status));
          return keep(out, mo);
        }
        one.T_world_aux = pa.T_world_tcp_command;
      }
      commanded = {one};
      sr.points_added = 0;
      sr.max_error_after_mm = sc.max_error_before_mm;
      sr.note = m.trigger_count > 0
                    ? std::to_string(m.trigger_count) + " TRIGGER statement(s) bound to this motion: no auxiliary points inserted"
                    : single + ": no auxiliary points inserted";
      if (sc.max_error_before_mm > s_.tol_mm)
        warning(m.where, "the predicted path error " + formatMm(sc.max_error_before_mm) + " mm exceeds --tol " + formatMm(s_.tol_mm) +
                             " mm, but " + single + ": no auxiliary points inserted");
    }
    insertPoints(m, c, end, commanded, sr.length_mm, out);
    if (commanded.size() > 1 && m.approximation.empty() && m.spline_block == 0) {
      // the inserted points take the motion's exact stop: the robot stops at each (not in a
      // spline block, whose segments are one path without stops)
      if (exact_stop_points_ == 0) exact_stop_where_ = m.where;
      exact_stop_points_ += static_cast<int>(commanded.size()) - 1;
      ++exact_stop_motions_;
    }
    if (end.abb_conf && commanded.size() == sc.q_real_end.size() && abbConfModelled(m))  // RAPID: the confdata the path has at each inserted point
      for (size_t k = 0; k + 1 < commanded.size(); ++k)
      {
        Motion& ins = out.motions[out.motions.size() - commanded.size() + 1 + k];
        ins.target.abb_conf = abbConfdata(comp.controller().model(), sc.q_real_end[k]);
        if (ins.aux) ins.aux->abb_conf = ins.target.abb_conf;  // the circle point's confdata is not used
      }
    const Eigen::Isometry3d T_cmd_end = commanded.back().T_world_end;
    setPose(mo.target, toProgram(c.T_world_progbase, T_cmd_end), commandBefore(c, &commanded));
    keepIgnoredOrientation(m, mo.target);
    mo.target.turn = end.turn;
    claimValue(mo.target, m.where, true);
    reportTarget(m, m.target, "end", c.T_world_progbase, c.T_world_end, T_cmd_end, c.models->calibrated_tool,
                 sc.q_real_end.back());
    if (c.aux) {
      if (commanded.size() > 1 && !mo.aux->name.empty()) {
        // the last sub-arc needs its own auxiliary point: a new declaration, the declared
        // one keeps its meaning (another motion may use it)
        Target& a = *mo.aux;
        a.replaces = a.name;
        a.new_declaration = true;
        // KRL: declared next to the point it replaces in the .dat; a point declared elsewhere
        // (the .src, $config.dat) or an array's element (XPA[1]: no name to derive a new one
        // from) is replaced by an inline aggregate (no name)
        // RAPID: an element of a robtarget array gets a scalar robtarget after the array
        const std::string base = in_->rapid ? rapidPointBase(a.name) : a.name;
        const bool in_dat = isDeclarableName(base) &&
                            (!in_->krl || (a.value_id >= 0 && static_cast<size_t>(a.value_id) < in_->krl->values.size() &&
                                           in_->krl->values[static_cast<size_t>(a.value_id)].file == 1));
        a.name = in_dat ? newPointName(*in_, base, new_names_) : std::string();
        if (in_dat) new_names_.push_back(a.name);
      }
      Eigen::Isometry3d T_cmd_aux = commanded.back().T_world_aux;
      // the controller ignores the orientation of an auxiliary point: the program's stays
      if (!mo.aux->new_declaration) T_cmd_aux.linear() = intended.T_world_aux.linear();
      setPose(*mo.aux, toProgram(c.T_world_progbase, T_cmd_aux), commandBefore(c, &commanded));
      if (!mo.aux->new_declaration) claimValue(*mo.aux, m.where, true);
      if (commanded.size() == 1) {
        reportTarget(m, *m.aux, "aux", c.T_world_progbase, intended.T_world_aux, T_cmd_aux, c.models->calibrated_tool);
      } else if (mo.aux->new_declaration) {
        reportNewPoint(m, *mo.aux, c, comp, commanded.back().T_world_aux, sc.q_real_end.back());
      }
    }
    r_.segments.push_back(sr);
    arrived(m, c, sc.q_real_end.back(), end);
    out.motions.push_back(mo);
  }

  /// The report of a new declared point (the auxiliary point of the last sub-arc of a split
  /// CIRC): its command against the point of the intended path the real robot reaches there.
  void reportNewPoint(const Motion& m, const Target& t, const Cartesian& c, const Compensator& comp, const Eigen::Isometry3d& T_cmd,
                      const Eigen::VectorXd& seed) {
    const calib::IkResult r = comp.controller().inverse(T_cmd, calib::Configuration{}, seed, s_.ik);
    const Eigen::Isometry3d desired = r.status == calib::IkStatus::kOk ? comp.real().forward(r.q, s_.context) : T_cmd;
    reportTarget(m, t, "aux", c.T_world_progbase, desired, T_cmd, c.models->calibrated_tool);
    TargetReport& tr = r_.targets.back();
    tr.where = m.where;
    tr.new_point_replaces = t.replaces;
  }

  /// The inserted motions (all sub-segments of `commanded` but the last), before `m`; external
  /// axes interpolated by the length run along the path (of `length_mm`).
  void insertPoints(const Motion& m, const Cartesian& c, const Target& end, const std::vector<PathSegment>& commanded, double length_mm,
                    Program& out) const {
    const double total = std::max(1e-9, length_mm);
    double run_mm = 0;
    for (size_t k = 0; k + 1 < commanded.size(); ++k) {
      run_mm += pathLength(commanded[k]);
      Motion ins = m;
      ins.inserted = true;
      ins.trigger_count = 0;
      ins.single_reason.clear();
      ins.target_problem.clear();
      Target t;
      t.kind = Target::Kind::kCartesian;
      t.where = m.where;
      t.setPose(toProgram(c.T_world_progbase, commanded[k].T_world_end));
      t.status = end.status;
      t.turn = end.turn;
      const double frac = std::min(1.0, run_mm / total);
      for (int e = 0; e < 6; ++e) {
        if (!end.ext[e]) continue;
        const double a = ext_prev_[e].value_or(*end.ext[e]);
        t.ext[e] = a + frac * (*end.ext[e] - a);
      }
      t.modified = true;
      ins.target = t;
      if (c.aux) {
        Target ta = t;
        ta.setPose(toProgram(c.T_world_progbase, commanded[k].T_world_aux));
        ins.aux = ta;
      }
      out.motions.push_back(ins);
    }
  }

  /// $ORI_TYPE #CONSTANT: the controller ignores the target's orientation (it keeps the one the
  /// motion starts with): the written angles stay (or stay left out), only the position is
  /// corrected.
  static void keepIgnoredOrientation(const Motion& m, Target& t) {
    if (m.type == MotionType::kPtp || m.ori_type != "#CONSTANT") return;
    for (int k = 3; k < 6; ++k) t.pose[k] = m.target.pose[k];
  }

  /// The real robot reached `end` with joints q_real.
  void arrived(const Motion& m, const Cartesian& c, const Eigen::VectorXd& q_real, const Target& end) {
    q_real_ = q_real;
    q_real_where_ = m.where;
    T_world_flange_intended_ = c.T_world_end * c.tool.inverse();
    ext_prev_ = end.ext;
  }

  const JobSettings& s_;
  JobReport& r_;
  ModelFactory models_;
  /// The controller reads the Status/Turn of a Cartesian PTP (not a Universal Robots arm's; pointMotion)
  bool reads_st_ = true;
  std::optional<Eigen::VectorXd> q_real_;                    ///< real joints after the last motion
  SourceLocation q_real_where_;                              ///< the motion q_real_ is after
  std::optional<Eigen::VectorXd> q_hint_;                    ///< the joints last known (forget())
  SourceLocation hint_where_;                                ///< the motion q_hint_ is after
  std::optional<Eigen::Isometry3d> T_world_flange_intended_;  ///< where the program meant the flange to be
  std::array<std::optional<double>, 6> ext_prev_{};
  bool after_arm_stays_ = false;  ///< the motion before moved external axes only (Motion::arm_stays)
  const Program* in_ = nullptr;         ///< the program (names for new points)
  std::vector<std::string> new_names_;  ///< new points named so far
  std::vector<std::string> abb_disagree_;  ///< RAPID CP targets whose confdata differ from the path's (accepted)
  /// "confdata of X changed" said once per point and change: key -> the warning's index, the motions (file:line:column)
  std::map<std::string, std::pair<size_t, std::vector<std::string>>> conf_changed_;
  std::string abb_first_;
  SourceLocation abb_where_;
  int abb_checked_ = 0;      ///< RAPID targets whose confdata were compared with the compensated joints
  int abb_mismatched_ = 0;   ///< ... and differed (beyond a quadrant boundary at the written precision)
  int abb_first_error_ = -1; ///< index in r_.errors of the first confdata error
  SourceLocation abb_unmodelled_where_;  ///< the first RAPID target whose confdata are not interpreted (not 6 axes)
  std::vector<std::string> cp_disagree_;  ///< CP targets whose S/T differ from the path's
  std::string cp_first_;
  SourceLocation cp_where_;
  int exact_stop_points_ = 0, exact_stop_motions_ = 0;  ///< auxiliary points inserted before exact stops
  SourceLocation exact_stop_where_;
  struct Claim {
    std::string pose_text;  ///< the corrected value without S/T
    SourceLocation where;
    bool cp = false;        ///< claimed by a CP motion (S/T not used by the controller)
    std::optional<int> status, turn;
  };
  std::map<int, Claim> claimed_;
  std::map<std::string, std::string> own_points_;  ///< ownPoint: point and correction -> the new point's name
  struct OwnPointName {
    SourceLocation motion;
    std::string old_name, new_name;
  };
  std::vector<OwnPointName> own_point_names_;  ///< for the report (reportNewName), after the motions
  std::map<int, SourceLocation> kept_values_;  ///< points of motions kept as written (keep)
};

}  // namespace

calib::RobotModel realModelForTool(const calib::RobotModel& calibrated, const Eigen::Isometry3d& T_flange_tcp, double match_mm,
                            double match_deg, bool* calibrated_tool) {
  const Eigen::Isometry3d& nominal_tool = calibrated.nominal.T_flange_tcp;
  const bool same = (T_flange_tcp.translation() - nominal_tool.translation()).norm() <= match_mm &&
                    calib::rotationAngleDeg(T_flange_tcp.linear().transpose() * nominal_tool.linear()) <= match_deg;
  if (calibrated_tool) *calibrated_tool = same;
  calib::RobotModel real = calibrated;
  if (!same) {
    real.nominal.T_flange_tcp = T_flange_tcp;
    real.deviations.tool_mm.setZero();
    real.deviations.tool_rot_rad.setZero();
  }
  return real;
}

namespace {
// A KRL motion inside an inline form's fold (`;FOLD LIN P1 Vel=2 m/s CPDAT1 ..;%{PE}`, its
// parameters `%P .. 2:P1` or `Kuka.PointName=P1`) that now goes to a new point (XP1_1): the
// form names its point by the name without the X (the pendant writes `LIN XP1`, `FDAT_ACT=FP1`
// from it) and still says P1. Re-opened on the pendant it shows P1; Touch Up teaches XP1 and
// OK writes `LIN XP1` back. Whether the form would take a renamed header (P1_1, with no FDAT
// FP1_1) is not documented, so the header is kept and the motion named in a warning, once per fold.
void warnInlineFormsOfNewPoints(const Program& p, JobReport* r) {
  if (!p.krl) return;
  const KrlSource& s = *p.krl;
  const auto redirected = [](const Target* t) { return t && t->new_declaration && !t->replaces.empty() && !t->name.empty(); };
  const auto inSrc = [&](const Motion& m) {
    return !m.inserted && m.statement_id >= 0 && m.statement_id < static_cast<int>(s.statements.size()) &&
           s.statements[static_cast<size_t>(m.statement_id)].file == 0;
  };
  bool any = false;
  for (const Motion& m : p.motions) any = any || (inSrc(m) && (redirected(&m.target) || redirected(m.aux ? &*m.aux : nullptr)));
  if (!any) return;
  // the fold each line of the .src is in (the innermost open one; closed folds skipped): one pass
  // over the file with a stack of the open folds' headers (upper case, from the ';')
  struct Fold {
    size_t line_begin;
    int line;
    std::string header;
  };
  const std::string& text = s.src_text;
  std::vector<Fold> folds;
  std::vector<size_t> open;
  std::vector<std::pair<size_t, size_t>> fold_of_line;  // (the line's first byte, its fold's index + 1; 0: none)
  int line_no = 1;
  for (size_t b = 0; b < text.size(); ++line_no) {
    const size_t nl = std::min(text.find('\n', b), text.size());
    fold_of_line.emplace_back(b, open.empty() ? 0 : open.back() + 1);
    const std::string line = calib::upperAscii(text.substr(b, nl - b));
    const size_t first = line.find_first_not_of(" \t");
    if (first != std::string::npos && line.compare(first, 8, ";ENDFOLD") == 0) {
      if (!open.empty()) open.pop_back();
    } else if (first != std::string::npos && line.compare(first, 5, ";FOLD") == 0) {
      open.push_back(folds.size());
      folds.push_back({b, line_no, line.substr(first)});
    }
    b = nl + 1;
  }
  std::set<size_t> warned;  // folds warned about
  for (const Motion& m : p.motions) {
    if (!inSrc(m)) continue;
    const KrlSource::Statement& st = s.statements[static_cast<size_t>(m.statement_id)];
    auto at = std::upper_bound(fold_of_line.begin(), fold_of_line.end(), std::make_pair(st.line_begin, std::numeric_limits<size_t>::max()));
    if (at == fold_of_line.begin() || (at - 1)->second == 0) continue;
    const size_t fold = (at - 1)->second - 1;
    const std::string& header = folds[fold].header;
    for (const Target* t : {m.aux ? &*m.aux : nullptr, &m.target}) {
      if (!redirected(t)) continue;
      const std::string old = calib::upperAscii(t->replaces);
      const std::string form_name = old.size() > 1 && old[0] == 'X' ? old.substr(1) : old;
      const auto names = [&](const std::string& name) {
        for (size_t n = header.find(name); n != std::string::npos; n = header.find(name, n + 1)) {
          const auto word = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; };
          if ((n == 0 || !word(header[n - 1])) && (n + name.size() >= header.size() || !word(header[n + name.size()]))) return true;
        }
        return false;
      };
      if (header.find("%{PE}") != std::string::npos && names(form_name) && warned.insert(fold).second) {
        SourceLocation w;
        w.file = s.src_path;
        w.line = folds[fold].line;
        w.column = 1;
        r->warnings.push_back({w, "the inline form's fold names " + form_name + ", but its motion (" + m.where.str() + ") now goes to the new point " +
                                      t->name + " (declared after " + t->replaces + "): re-opened on the pendant the form shows " + form_name +
                                      ", Touch Up teaches " + t->replaces + " and OK writes the motion to " + t->replaces +
                                      " back; the fold's header is kept (edit the motion as text, or compensate again after editing)"});
      }
    }
  }
}

// Issue 11: each target whose real joint values lie outside the ranges the model's
// joint-dependent effects were fitted on (compliance, gear, scale, joint maps: fit_range in the
// model file), with how far, then how many: the correction there is an extrapolation.
void warnOutsideFitRanges(const calib::RobotModel& calibrated, JobReport* r) {
  std::vector<ProgramIssue> found;
  for (const TargetReport& t : r->targets) {
    if (t.q_real.size() != calibrated.dof()) continue;
    const std::vector<calib::OutsideFitRange> o = calib::outsideFitRanges(calibrated, t.q_real);
    if (o.empty()) continue;
    found.push_back({t.where, calib::outsideFitRangeMessage(calibrated, t.name.empty() ? std::string("target") : t.name, o)});
  }
  if (found.empty()) return;
  const SourceLocation first = found.front().where;
  r->warnings.insert(r->warnings.end(), found.begin(), found.end());
  r->warnings.push_back({first, std::to_string(found.size()) + " of " + std::to_string(r->targets.size()) +
                                    " target(s) outside the fitted joint ranges; the correction there is an extrapolation"});
}
}  // namespace

namespace {

// A program read from URScript, or carrying a script's lines (converted through XML): it runs
// on a UR controller.
bool runsOnUrController(const Program& program) {
  if (program.urscript) return true;
  for (const PassThrough& s : program.passthrough)
    if (s.language == "URScript") return true;
  return false;
}

}  // namespace

void requireArmForProgram(const Program& program, const calib::RobotDefinition& robot) {
  if (runsOnUrController(program) && !universalRobotsArm(robot))
    throw calib::InputError((program.source_file.empty() ? program.name : program.source_file) +
                            ": expected a Universal Robots arm for a URScript program (joints 2, 3 and 4 parallel, no "
                            "spherical wrist: the controller's shoulder/elbow/wrist branches are that geometry's), found '" +
                            robot.name + "': give the model of the UR that runs the program");
}

void requireOneUndeclaredFrame(const Program& program, const JobSettings& settings) {
  // a RAPID motion names its tooldata / wobjdata (Source::kUnset with its name: declared in a
  // system module, not in the file); each name is a frame of its own on the controller, and
  // --program-tool / --program-base give one
  for (const bool tool : {true, false}) {
    if (!(tool ? settings.initial_tool : settings.initial_base)) continue;
    const Motion* first = nullptr;
    std::string first_name;
    for (const Motion& m : program.motions) {
      const FrameSetting& f = tool ? m.tool : m.base;
      if (f.source != FrameSetting::Source::kUnset || f.text.empty()) continue;
      const std::string u = calib::upperAscii(f.text);  // (RAPID names: any case)
      if (!first) {
        first = &m;
        first_name = u;
      } else if (u != first_name) {
        const char* type = tool ? "tooldata" : "wobjdata";
        throw calib::InputError(m.where.file, m.where.line, m.where.column,
                                std::string("expected one ") + type + " that the program does not declare (" +
                                    (tool ? "--program-tool gives its TCP" : "--program-base gives its frame") + ", taken for '" +
                                    detail::excerpt(tool ? first->tool.text : first->base.text) +
                                    "' at " + first->where.str() + "), found a second, '" + detail::excerpt(f.text) +
                                    "', whose value the controller has and accura does not: declare it in the module");
      }
    }
  }
}

JobSettings settingsForProgram(const Program& program, const JobSettings& settings) {
  if (!runsOnUrController(program) || settings.robroot_in_kukaworld || !universalRobotsArm(settings.calibrated.nominal)) return settings;
  // URScript poses are in the controller's Base, UR's DH frame 0; a robot read from
  // ur_description's URDF from its root ('world', base_link) has its frame 0 turned 180 deg
  // about axis 1 from it (ur_calibration.h, urConventionOf): Base is then that turn away
  Eigen::Isometry3d T_frame0_urbase = Eigen::Isometry3d::Identity();
  try {
    T_frame0_urbase = calib::urConventionOf(settings.calibrated.nominal).T_frame0_urbase;
  } catch (const calib::ArgumentError&) {
    return settings;  // (no UR table: the arm's frame 0 is taken as its Base)
  }
  if (!(calib::rotationAngleDeg(T_frame0_urbase.linear()) > 1e-9)) return settings;
  JobSettings s = settings;
  s.robroot_in_kukaworld = calib::toXyzAbc(T_frame0_urbase.inverse());  // frame 0 in Base
  return s;
}

ProgramCompensation compensateProgramReport(const Program& program, const JobSettings& given) {
  const JobSettings settings = settingsForProgram(program, given);
  if (!(settings.tol_mm > 0) || !std::isfinite(settings.tol_mm))
    throw calib::ArgumentError("compensateProgram: tol_mm must be > 0 (mm)");
  std::string why;
  if (!settings.ik.IsValid(&why)) throw calib::ArgumentError("compensateProgram: IK options: " + why);
  settings.calibrated.validate();
  requireArmForProgram(program, settings.calibrated.nominal);
  requireOneUndeclaredFrame(program, settings);
  ProgramCompensation pc;
  JobReport& r = pc.report;
  pc.program = program;
  pc.program.motions.clear();
  Job job(settings, &r);
  job.run(program, pc.program);
  warnInlineFormsOfNewPoints(pc.program, &r);
  warnOutsideFitRanges(settings.calibrated, &r);

  double sum2 = 0;
  for (const auto& t : r.targets) {
    r.max_correction_mm = std::max(r.max_correction_mm, t.correction_mm);
    r.max_correction_deg = std::max(r.max_correction_deg, t.correction_deg);
    sum2 += t.correction_mm * t.correction_mm;
  }
  r.targets_corrected = static_cast<int>(r.targets.size());
  r.rms_correction_mm = r.targets.empty() ? 0 : std::sqrt(sum2 / static_cast<double>(r.targets.size()));
  for (const auto& s : r.segments) {
    r.points_added += s.points_added;
    r.max_error_uncompensated_mm = std::max(r.max_error_uncompensated_mm, s.max_error_uncompensated_mm);
    r.max_error_before_mm = std::max(r.max_error_before_mm, s.max_error_before_mm);
    r.max_error_after_mm = std::max(r.max_error_after_mm, s.max_error_after_mm);
  }
  return pc;
}

calib::InputError compensationError(const JobReport& r) {
  if (r.errors.empty()) throw calib::ArgumentError("compensationError: the report has no error");
  std::string msg = r.errors.front().message;
  if (r.errors.size() > 1) {
    msg += " (and " + std::to_string(r.errors.size() - 1) + " more problem(s):";
    for (size_t i = 1; i < r.errors.size(); ++i) msg += "\n  " + r.errors[i].where.str() + ": " + r.errors[i].message;
    msg += ")";
  }
  const SourceLocation& w = r.errors.front().where;
  return calib::InputError(w.file, w.line, w.column, msg);
}

Program compensateProgram(const Program& program, const JobSettings& settings, JobReport* report) {
  ProgramCompensation pc = compensateProgramReport(program, settings);
  if (report) *report = pc.report;
  if (!pc.ok()) throw compensationError(pc.report);
  return std::move(pc.program);
}

}  // namespace accura::postproc
