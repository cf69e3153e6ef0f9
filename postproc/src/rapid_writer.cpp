// RAPID writer (see rapid.h): a module read from RAPID patched in place, or a new module from
// the motion model; and the preparation of a RAPID program for another format.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>
#include <tuple>

#include "accura/calib/errors.h"
#include "accura/calib/text.h"
#include "excerpt.h"
#include "rapid_internal.h"

namespace accura::postproc {
namespace {

using namespace rapid_detail;

constexpr int kQuatDecimals = 9;        // ~2e-9 rad
constexpr double kQuatHalfUnit = 0.5e-9;

std::string label(const Target& t) { return t.name.empty() ? std::string("the inline target") : t.name; }

std::string quatText(double v) { return calib::formatFixed(v, kQuatDecimals); }

/// How the module writes an unused external axis: 9E9 when it does so and never 9E+09.
std::string unusedAxisText(const std::string& module) {
  const bool short_form = module.find("9E9") != std::string::npos || module.find("9e9") != std::string::npos;
  const bool long_form = module.find("9E+09") != std::string::npos || module.find("9e+09") != std::string::npos;
  return short_form && !long_form ? "9E9" : "9E+09";
}

/// An inline robtarget of `t` (wobj frame), the quaternion signed like `near` (w, x, y, z);
/// unused external axes written as `unused`.
std::string robtargetText(const Target& t, const double near[4], const std::string& unused = "9E+09") {
  auto extText = [&](const std::optional<double>& e) { return e ? formatMm(*e) : unused; };
  const Eigen::Isometry3d T = calib::toIsometry(t.xyzAbc());
  const std::array<double, 4> q = quaternionNear(T.linear(), near);
  const Eigen::Vector3d p = T.translation();
  const std::array<int, 4> c = t.abb_conf.value_or(std::array<int, 4>{0, 0, 0, 0});
  std::string s = "[[" + formatMm(p.x()) + "," + formatMm(p.y()) + "," + formatMm(p.z()) + "],[";
  for (int k = 0; k < 4; ++k) s += (k ? "," : "") + quatText(q[static_cast<size_t>(k)]);
  s += "],[" + std::to_string(c[0]) + "," + std::to_string(c[1]) + "," + std::to_string(c[2]) + "," + std::to_string(c[3]) + "],[";
  for (int k = 0; k < 6; ++k) s += (k ? "," : "") + extText(t.ext[static_cast<size_t>(k)]);
  return s + "]]";
}

struct Edit {
  size_t begin, end;
  std::string text;
  int order;
};

/// The text of value `v` holding target `t`: numbers whose correction rounds to zero keep
/// their text; an orientation that did not change keeps its quaternion text.
std::string valueText(const RapidSource& s, const RapidSource::Value& v, const Target& t) {
  const Eigen::Isometry3d T = calib::toIsometry(t.xyzAbc());
  const Eigen::Isometry3d T0 = poseOf(v.v, v.v + 3);
  const calib::XyzAbc a0 = calib::toXyzAbc(T0), a1 = t.xyzAbc();
  const bool same_rotation = formatDeg(a0.a_deg) == formatDeg(a1.a_deg) && formatDeg(a0.b_deg) == formatDeg(a1.b_deg) &&
                             formatDeg(a0.c_deg) == formatDeg(a1.c_deg);
  const std::array<double, 4> q = quaternionNear(T.linear(), v.v + 3);
  std::string out;
  size_t pos = v.begin;
  for (int k = 0; k < 11; ++k) {
    out += s.text.substr(pos, v.num[k].first - pos);
    const std::string old = s.text.substr(v.num[k].first, v.num[k].second - v.num[k].first);
    std::string now = old;
    if (k < 3) {
      const double x = T.translation()[k];
      if (formatMm(x) != formatMm(v.v[k])) now = formatMm(x);
    } else if (k < 7) {
      const double x = q[static_cast<size_t>(k - 3)];
      if (!same_rotation && std::abs(x - v.v[k]) >= kQuatHalfUnit) now = quatText(x);
    } else if (t.abb_conf && (*t.abb_conf)[static_cast<size_t>(k - 7)] != static_cast<int>(v.v[k])) {
      now = std::to_string((*t.abb_conf)[static_cast<size_t>(k - 7)]);
    }
    out += now;
    pos = v.num[k].second;
  }
  return out + s.text.substr(pos, v.end - pos);
}

std::string lineEnd(const RapidSource& s, const std::string& eol) {
  return eol.empty() ? (s.text.find("\r\n") != std::string::npos ? "\r\n" : "\n") : eol;
}

/// Edits of one motion's targets (not inserted). `movej_conf`: per robtarget value, the confdata
/// a MoveJ to it was compensated on (ConfJ\On needs it exactly; a MoveL/MoveC keeps what is
/// written and ConfL\On accepts axes 1, 4, 6 within one quadrant): a value shared by both is
/// written with the MoveJ's. `new_points`: the new declarations written so far (name -> value,
/// the motion), each written once.
void targetEdits(const Program& p, const Motion& m, std::map<int, std::pair<std::string, std::string>>& values,
                 std::map<std::string, std::pair<std::string, std::string>>& new_points, const std::map<int, std::array<int, 4>>& movej_conf,
                 std::vector<Edit>& edits, int& order) {
  const RapidSource& s = *p.rapid;
  const RapidSource::Statement& st = s.statements[static_cast<size_t>(m.statement_id)];
  std::vector<const Target*> ts;
  if (m.aux) ts.push_back(&*m.aux);
  if (m.target.kind == Target::Kind::kCartesian) ts.push_back(&m.target);
  for (size_t k = 0; k < ts.size() && k < st.targets.size(); ++k) {
    const Target& t = *ts[k];
    if (!t.modified) continue;
    const int vid = st.target_value[k];
    const RapidSource::Value* v = vid >= 0 ? &s.values[static_cast<size_t>(vid)] : nullptr;
    const double unit[4] = {1, 0, 0, 0};
    if (t.new_declaration) {
      const bool declared = v && v->decl >= 0 && !t.name.empty();
      // (a MoveJ and a MoveL to the new point: the MoveJ's confdata, as for a declared one)
      Target shared = t;
      const auto mj = movej_conf.find(vid);
      if (m.type != MotionType::kPtp && mj != movej_conf.end() && t.abb_conf && vid >= 0) shared.abb_conf = mj->second;
      const std::string value = robtargetText(declared ? shared : t, v ? v->v + 3 : unit, unusedAxisText(s.text));
      if (!declared) {
        edits.push_back({st.targets[k].first, st.targets[k].second, value, order++});
        continue;
      }
      // a new point several motions go to (Job::copyRapidPointsReadElsewhere) is declared once
      const auto seen = new_points.find(t.name);
      if (seen != new_points.end()) {
        if (seen->second.first != value)
          throw calib::ArgumentError(m.where.str() + ": " + t.name + " (for " + t.replaces + ") needs a different correction here than at " +
                                     seen->second.second + " (the same robtarget with another tool, work object or path): give the motions their own robtargets");
        edits.push_back({st.targets[k].first, st.targets[k].second, t.name, order++});
        continue;
      }
      new_points[t.name] = {value, m.where.str()};
      const RapidSource::Decl& d = s.decls[static_cast<size_t>(v->decl)];
      const std::string eol = d.line_end > 1 && s.text[d.line_end - 2] == '\r' ? "\r\n" : "\n";
      std::string line = d.indent + d.head + t.name + " := " + value + ";" + eol;
      if (d.line_end == s.text.size() && (s.text.empty() || s.text.back() != '\n')) line = lineEnd(s, "") + d.indent + d.head + t.name + " := " + value + ";";
      edits.push_back({d.line_end, d.line_end, line, order++});
      edits.push_back({st.targets[k].first, st.targets[k].second, t.name, order++});
      continue;
    }
    // (a robtarget of a module given with --config: its text is not this module's; Job sends
    // every correction of it to a new point)
    if (v && v->decl >= 0 && !s.decls[static_cast<size_t>(v->decl)].task_module.empty())
      throw calib::ArgumentError(m.where.str() + ": " + label(t) + " is declared in " + s.decls[static_cast<size_t>(v->decl)].task_module +
                                 ", a module given with --config, which is only read: its correction must go to a new point");
    if (!v) {  // Offs / RelTool: the corrected point as an inline robtarget
      edits.push_back({st.targets[k].first, st.targets[k].second, robtargetText(t, unit, unusedAxisText(s.text)), order++});
      continue;
    }
    Target shared = t;
    const auto mj = movej_conf.find(vid);
    if (m.type != MotionType::kPtp && mj != movej_conf.end() && t.abb_conf) shared.abb_conf = mj->second;
    const std::string text = valueText(s, *v, shared);
    const auto it = values.find(vid);
    if (it != values.end() && it->second.first != text)
      throw calib::ArgumentError(m.where.str() + ": " + label(t) + " needs a different correction here than at " + it->second.second +
                                 " (the same robtarget with another tool, work object or path): give the motions their own robtargets");
    if (it == values.end()) {
      values[vid] = {text, m.where.str()};
      if (text != s.text.substr(v->begin, v->end - v->begin)) edits.push_back({v->begin, v->end, text, order++});
    }
  }
}

std::string patch(const Program& p) {
  const RapidSource& s = *p.rapid;
  int order = 0;
  std::vector<Edit> edits;
  std::map<int, std::pair<std::string, std::string>> values;
  std::map<std::string, std::pair<std::string, std::string>> new_points;  // a new declaration's name -> its value, the motion
  std::map<int, std::array<int, 4>> movej_conf;
  for (const Motion& m : p.motions) {
    if (m.inserted || m.type != MotionType::kPtp || m.target.kind != Target::Kind::kCartesian || !m.target.modified ||
        !m.target.abb_conf || m.statement_id < 0 || m.statement_id >= static_cast<int>(s.statements.size()))
      continue;
    const RapidSource::Statement& st = s.statements[static_cast<size_t>(m.statement_id)];
    if (!st.target_value.empty() && st.target_value.back() >= 0) movej_conf.emplace(st.target_value.back(), *m.target.abb_conf);
  }
  for (size_t i = 0; i < p.motions.size(); ++i) {
    const Motion& m = p.motions[i];
    if (m.statement_id < 0 || m.statement_id >= static_cast<int>(s.statements.size()))
      throw calib::ArgumentError("writeRapid: a motion has no statement in the module");
    const RapidSource::Statement& st = s.statements[static_cast<size_t>(m.statement_id)];
    // a move with a time \T split into pieces: each piece its share of the time
    const std::string duration = pieceDurationText(p, i, st.duration_s);
    if (!m.inserted) {
      targetEdits(p, m, values, new_points, movej_conf, edits, order);
      if (!duration.empty()) edits.push_back({st.duration_text.first, st.duration_text.second, duration, order++});
      continue;
    }
    std::vector<const Target*> ts;
    if (m.aux) ts.push_back(&*m.aux);
    ts.push_back(&m.target);
    if (ts.size() != st.targets.size()) throw calib::ArgumentError("writeRapid: an inserted motion does not match its statement");
    std::string line = s.text.substr(st.line_begin, st.code_begin - st.line_begin);
    size_t pos = st.code_begin;
    for (size_t k = 0; k < st.targets.size(); ++k) {
      const int vid = st.target_value[k];
      const double unit[4] = {1, 0, 0, 0};
      line += s.text.substr(pos, st.targets[k].first - pos);
      line += robtargetText(*ts[k], vid >= 0 ? s.values[static_cast<size_t>(vid)].v + 3 : unit, unusedAxisText(s.text));
      pos = st.targets[k].second;
    }
    if (!duration.empty()) {
      line += s.text.substr(pos, st.duration_text.first - pos) + duration;
      pos = st.duration_text.second;
    }
    line += s.text.substr(pos, st.code_end - pos) + lineEnd(s, st.eol);
    edits.push_back({st.line_begin, st.line_begin, line, order++});
  }
  std::stable_sort(edits.begin(), edits.end(), [](const Edit& a, const Edit& b) { return a.begin != b.begin ? a.begin < b.begin : a.order < b.order; });
  std::string out;
  size_t pos = 0;
  for (const Edit& e : edits) {
    if (e.begin < pos) throw calib::ArgumentError("writeRapid: overlapping edits");
    out += s.text.substr(pos, e.begin - pos) + e.text;
    pos = e.end;
  }
  return out + s.text.substr(pos);
}

// --- a new module from the motion model (XML, KRL, URScript)

[[noreturn]] void refuse(const Motion& m, const std::string& why) {
  throw calib::ArgumentError(m.where.str() + ": cannot convert '" + m.statement + "' to RAPID: " + why);
}

bool isIdentifier(const std::string& s) {
  if (s.empty() || s.size() > 32 || !std::isalpha(static_cast<unsigned char>(s[0]))) return false;
  for (char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) return false;
  return true;
}

std::string frameText(const calib::XyzAbc& f) {
  const Eigen::Isometry3d T = calib::toIsometry(f);
  const double unit[4] = {1, 0, 0, 0};
  const std::array<double, 4> q = quaternionNear(T.linear(), unit);
  return "[[" + formatMm(T.translation().x()) + "," + formatMm(T.translation().y()) + "," + formatMm(T.translation().z()) + "],[" +
         quatText(q[0]) + "," + quatText(q[1]) + "," + quatText(q[2]) + "," + quatText(q[3]) + "]]";
}

std::string zoneText(const Motion& m) {
  if (m.approximation.empty()) return "fine";
  if (m.approximation.front() != Approximation::kCDis || !m.approximation_value)
    refuse(m, "RAPID's zone is a radius: only an exact stop or C_DIS with its distance ($APO.CDIS) converts");
  const double r = *m.approximation_value;
  for (int z : {1, 5, 10, 15, 20, 30, 40, 50, 60, 80, 100, 150, 200})
    if (formatMm(r) == formatMm(z)) return "z" + std::to_string(z);
  return "[FALSE," + formatMm(r) + "," + formatMm(1.5 * r) + "," + formatMm(1.5 * r) + "," + formatMm(0.15 * r) + "," + formatMm(1.5 * r) +
         "," + formatMm(0.15 * r) + "]";
}

std::string speedText(const Motion& m) {
  if (m.type == MotionType::kPtp || !m.vel_m_s) return "v1000";
  const double v = *m.vel_m_s * 1000.0;
  if (const auto p = predefinedSpeedMmS("V" + calib::formatFixed(v, 0)); p && formatMm(*p) == formatMm(v)) return "v" + calib::formatFixed(v, 0);
  return "[" + formatMm(v) + ",500,5000,1000]";
}

class Generator {
 public:
  explicit Generator(const Program& p) : p_(p) {}

  std::string run() {
    checkPassThrough(p_, "RAPID");
    std::string name = p_.name;
    for (char& c : name)
      if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) c = '_';
    if (!isIdentifier(name)) name = "accura_" + name;
    for (size_t i = 0; i < p_.motions.size(); ++i) motion(p_.motions[i], i);
    std::ostringstream o;
    o << "MODULE " << name << "\n";
    o << "  ! written by " << p_.written_by << (p_.source_file.empty() ? "" : " from " + std::filesystem::path(p_.source_file).filename().string())
      << ": targets in the work object (mm, quaternion w,x,y,z); confdata the source does not give is 0 and configuration "
         "monitoring is off (ConfJ\\Off, ConfL\\Off: the controller takes the configuration nearest the current one)\n";
    for (const PassThrough& s : p_.passthrough)
      if (s.section == PassThrough::Section::kData) o << s.text << "\n";
    o << data_.str();
    o << "  PROC main()\n";
    if (!all_conf_) o << "    ConfJ\\Off;\n    ConfL\\Off;\n";
    size_t next = 0;
    for (size_t i = 0; i <= body_.size(); ++i) {
      for (; next < p_.passthrough.size(); ++next) {
        const PassThrough& s = p_.passthrough[next];
        if (s.section != PassThrough::Section::kBody) continue;
        if (s.before_motion > i) break;
        o << s.text << "\n";
      }
      if (i < body_.size()) o << body_[i];
    }
    for (; next < p_.passthrough.size(); ++next)
      if (p_.passthrough[next].section == PassThrough::Section::kBody) o << p_.passthrough[next].text << "\n";
    o << "  ENDPROC\n";
    for (const PassThrough& s : p_.passthrough)
      if (s.section == PassThrough::Section::kTrailer) o << s.text << "\n";
    o << "ENDMODULE\n";
    return o.str();
  }

 private:
  /// The name of a declared frame (tooldata / wobjdata) with this value, declared on first use.
  std::string frame(const Motion& m, const FrameSetting& f, bool tool) {
    const char* builtin = tool ? "tool0" : "wobj0";
    if (f.source == FrameSetting::Source::kUnset && !f.value) return builtin;
    if (!f.value) refuse(m, std::string("its ") + (tool ? "tool" : "base") + " (" + f.text + ") is not known (give the $config.dat with --config)");
    if (calib::toIsometry(*f.value).isApprox(Eigen::Isometry3d::Identity(), 1e-12)) return builtin;
    const std::string v = frameText(*f.value);
    auto& known = tool ? tools_ : wobjs_;
    const auto it = known.find(v);
    if (it != known.end()) return it->second;
    const std::string name = std::string(tool ? "accura_tool" : "accura_wobj") + std::to_string(known.size() + 1);
    known[v] = name;
    if (tool)  // the source format has no load data: a placeholder, said so where the controller's user sees it
      data_ << "  ! " << name << ": the load (1 kg at [0,0,1] mm) is a placeholder, not the tool's: set its mass and centre of "
                                  "gravity (LoadIdentify) before running\n"
            << "  PERS tooldata " << name << " := [TRUE," << v << ",[1,[0,0,1],[1,0,0,0],0,0,0]];\n";
    else data_ << "  PERS wobjdata " << name << " := [FALSE,TRUE,\"\"," << v << ",[[0,0,0],[1,0,0,0]]];\n";
    return name;
  }

  std::string target(const Motion& m, const Target& t) {
    if (!t.completePose()) refuse(m, "the target " + label(t) + " is partial (a robtarget is complete)");
    for (const auto& e : t.ext)
      if (e && *e != 0) refuse(m, "the target " + label(t) + " moves external axes, which the converted module does not model");
    Target c = t;
    c.ext = {};
    if (!c.abb_conf) {
      all_conf_ = false;
      int cfx = 0;
      if (t.status && *t.status >= 0) cfx = ((*t.status & 1) ? 4 : 0) + ((*t.status & 2) ? 0 : 2) + ((*t.status & 4) ? 1 : 0);
      c.abb_conf = std::array<int, 4>{0, 0, 0, cfx};
    }
    const double unit[4] = {1, 0, 0, 0};
    const std::string value = robtargetText(c, unit);
    if (!isIdentifier(t.name)) return value;
    std::string& known = targets_[t.name];
    if (known.empty()) {
      known = value;
      data_ << "  CONST robtarget " << t.name << " := " << value << ";\n";
      return t.name;
    }
    return known == value ? t.name : value;
  }

  void motion(const Motion& m, size_t index) {
    if (m.relative) refuse(m, "a relative motion (RAPID has Offs/RelTool of a known point instead)");
    if (!m.duration_expr.empty()) refuse(m, "its time (" + detail::excerpt(m.duration_expr) + ") is computed at run time in its own language");
    if (m.type == MotionType::kSpl) refuse(m, "RAPID has no spline motion");
    if (m.circ_angle_deg) refuse(m, "MoveC has no circular angle (CA)");
    if (m.external_tcp) refuse(m, "a stationary tool is not converted");
    if (!m.target_problem.empty()) refuse(m, m.target_problem);
    const std::string tool = frame(m, m.tool, true), wobj = frame(m, m.base, false);
    std::string s = "    ";
    if (m.target.kind == Target::Kind::kAxis) {
      if (m.type != MotionType::kPtp) refuse(m, "an axis target on a path motion");
      s += "MoveAbsJ [[";
      for (int k = 0; k < 6; ++k) {
        if (!m.target.axes[static_cast<size_t>(k)]) refuse(m, "the axis target is partial");
        s += (k ? "," : "") + formatDeg(*m.target.axes[static_cast<size_t>(k)]);
      }
      s += "],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]";
    } else {
      s += m.type == MotionType::kPtp ? "MoveJ " : m.type == MotionType::kCirc ? "MoveC " : "MoveL ";
      if (m.aux) s += target(m, *m.aux) + ", ";
      s += target(m, m.target);
    }
    // the move's time (\T:=, s): the controller makes it take that long; a piece of a split
    // motion its share
    std::string time;
    if (m.duration_s) {
      const std::string piece = pieceDurationText(p_, index, *m.duration_s);
      time = "\\T:=" + (piece.empty() ? calib::formatFixed(*m.duration_s, 4) : piece);
    }
    s += ", " + speedText(m) + time + ", " + zoneText(m) + ", " + tool + (wobj == "wobj0" ? "" : "\\WObj:=" + wobj) + ";\n";
    body_.push_back(s);
  }

  const Program& p_;
  std::ostringstream data_;
  std::vector<std::string> body_;
  std::map<std::string, std::string> tools_, wobjs_, targets_;
  bool all_conf_ = true;
};

}  // namespace

std::string writeRapid(const Program& program) {
  if (program.rapid) return patch(program);
  // converted from RAPID with its text carried (XML): that text, with the model laid on it
  if (const auto text = carriedSource(program, "RAPID")) return patch(reattachCarried(program, parseRapid(*text, program.source_file)));
  return Generator(program).run();
}

Program rapidForConversion(const Program& program) {
  Program out = program;
  if (!program.rapid) return out;
  // a tooldata or wobjdata the module names but does not declare (a system module's): the other
  // format's motion would have no tool or base, which no one would notice (compensate names the
  // option that supplies it)
  for (const Motion& m : program.motions)
    for (const auto& [f, what, type] : {std::make_tuple(&m.tool, "tool", "tooldata"), std::make_tuple(&m.base, "work object", "wobjdata")})
      if (f->source == FrameSetting::Source::kUnset && !f->text.empty())
        throw calib::ArgumentError(m.where.str() + ": cannot convert '" + detail::excerpt(m.statement) + "': the " + type + " '" +
                                   detail::excerpt(f->text) + "' is not declared with a value in the program (a system module's?), so the " +
                                   "converted motion would have no " + what + ": declare it in the module, or convert the .prg that holds its module");
  // MoveLDO, TriggL, MoveLSync, ... (their targets compensated as MoveL's): the motion model
  // holds the move and not what the instruction does besides (a signal, a trigger, a
  // procedure), so no other format can carry it (an XML would give KRL a plain LIN): refused
  for (const Motion& m : program.motions) {
    const std::string word = m.statement.substr(0, m.statement.find_first_of(" \t\r\n\\,;"));
    const std::string u = calib::upperAscii(word);
    if (m.target_problem.empty() && !isPlainMove(u))
      throw calib::ArgumentError(m.where.str() + ": cannot convert '" + detail::excerpt(m.statement) + "': " + word +
                                 " does more than move (a signal, a trigger, a procedure or a weld), which only RAPID carries");
  }
  std::vector<std::pair<size_t, size_t>> spans;
  for (const Motion& m : out.motions) {
    const RapidSource::Statement& st = program.rapid->statements.at(static_cast<size_t>(m.statement_id));
    spans.emplace_back(st.code_begin, st.code_end);
  }
  carrySourceLines(out, program.rapid->text, "RAPID", '!', spans);
  for (Motion& m : out.motions) {
    if (!isIdentifier(m.target.name)) m.target.name.clear();
    if (m.aux && !isIdentifier(m.aux->name)) m.aux->name.clear();
  }
  out.rapid.reset();
  return out;
}

}  // namespace accura::postproc
