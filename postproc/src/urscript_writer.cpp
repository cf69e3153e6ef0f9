// URScript writer (see urscript.h): a program read from URScript patched in place, or a new
// script from the motion model; and the checks for converting URScript into another format.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/text.h"
#include "accura/postproc/krl.h"
#include "excerpt.h"
#include "urscript_internal.h"

namespace accura::postproc {
namespace {

using namespace ur_detail;

constexpr int kDecimals = 7;           // 0.1 um, 0.1 urad
constexpr double kHalfUnit = 0.5e-7;   // a change below this rounds to zero at that precision

/// The rotation vector of R (angle in [0, pi]) or its equivalent of angle 2 pi - angle about the
/// opposite axis, whichever is nearer to `near`.
Eigen::Vector3d rotationVectorNear(const Eigen::Matrix3d& R, const Eigen::Vector3d& near) {
  const Eigen::AngleAxisd aa(R);
  const Eigen::Vector3d r = aa.axis() * aa.angle();
  const double angle = r.norm();
  if (angle < 1e-300) return Eigen::Vector3d::Zero();
  const Eigen::Vector3d alt = r * (1.0 - 2.0 * calib::kPi / angle);
  return (alt - near).norm() < (r - near).norm() ? alt : r;
}

/// p[...] values (m, rad) of T (mm).
std::array<double, 6> urValues(const Eigen::Isometry3d& T, const Eigen::Vector3d& near) {
  const Eigen::Vector3d r = rotationVectorNear(T.linear(), near);
  const Eigen::Vector3d p = T.translation() / 1000.0;
  return {p.x(), p.y(), p.z(), r.x(), r.y(), r.z()};
}

std::string poseText(const std::array<double, 6>& v) {
  std::string s = "p[";
  for (int k = 0; k < 6; ++k) s += (k ? ", " : "") + calib::formatFixed(v[static_cast<size_t>(k)], kDecimals);
  return s + "]";
}

void literalsOf(const UrScriptSource& s, int id, std::vector<int>* out) {
  const UrScriptSource::Expr& e = s.exprs.at(static_cast<size_t>(id));
  if (e.kind == UrScriptSource::Expr::Kind::kLiteral) return out->push_back(e.literal);
  literalsOf(s, e.a, out);
  literalsOf(s, e.b, out);
}

bool contains(const UrScriptSource& s, int id, int literal) {
  const UrScriptSource::Expr& e = s.exprs.at(static_cast<size_t>(id));
  if (e.kind == UrScriptSource::Expr::Kind::kLiteral) return e.literal == literal;
  return contains(s, e.a, literal) || contains(s, e.b, literal);
}

/// The value literal `literal` must take so that expression `id` evaluates to `want` (mm).
Eigen::Isometry3d solveLiteral(const UrScriptSource& s, int id, int literal, const Eigen::Isometry3d& want,
                               const std::map<int, Eigen::Isometry3d>& done) {
  const UrScriptSource::Expr& e = s.exprs.at(static_cast<size_t>(id));
  if (e.kind == UrScriptSource::Expr::Kind::kLiteral) return want;
  const bool in_a = contains(s, e.a, literal), in_b = contains(s, e.b, literal);
  if (in_a && in_b) throw calib::ArgumentError("the corrected literal appears on both sides of a pose_trans/pose_add");
  const Eigen::Isometry3d A = evaluate(s, e.a, &done), B = evaluate(s, e.b, &done);
  Eigen::Isometry3d x = Eigen::Isometry3d::Identity();
  if (e.kind == UrScriptSource::Expr::Kind::kTrans) {
    x = in_b ? Eigen::Isometry3d(A.inverse() * want) : Eigen::Isometry3d(want * B.inverse());
  } else {  // pose_add: P = A.P + B.P, R = A.R * B.R
    x.translation() = want.translation() - (in_b ? A.translation() : B.translation());
    x.linear() = in_b ? Eigen::Matrix3d(A.linear().transpose() * want.linear()) : Eigen::Matrix3d(want.linear() * B.linear().transpose());
  }
  return solveLiteral(s, in_b ? e.b : e.a, literal, x, done);
}

std::string label(const Target& t) { return t.name.empty() ? std::string("this target") : t.name; }

struct Edit {
  size_t begin, end;
  std::string text;
  int order;
};

/// The text of literal `lit` holding pose T (mm): the numbers that change by less than half a
/// unit of the last decimal written keep their text.
std::string literalText(const UrScriptSource& s, const UrScriptSource::Literal& lit, const Eigen::Isometry3d& T) {
  const std::array<double, 6> v = urValues(T, Eigen::Vector3d(lit.value[3], lit.value[4], lit.value[5]));
  std::string text;
  size_t pos = lit.begin;
  for (int k = 0; k < 6; ++k) {
    text += s.text.substr(pos, lit.number[k].first - pos);
    const bool same = std::abs(v[static_cast<size_t>(k)] - lit.value[k]) < kHalfUnit;
    text += same ? s.text.substr(lit.number[k].first, lit.number[k].second - lit.number[k].first)
                 : calib::formatFixed(v[static_cast<size_t>(k)], kDecimals);
    pos = lit.number[k].second;
  }
  return text + s.text.substr(pos, lit.end - pos);
}

/// The corrected literals: each modified target's right-most literal solved so that its
/// expression gives the corrected pose, with the other literals at their corrected values
/// (a target whose expression uses a literal another target corrects waits for it).
std::vector<Edit> correctedLiterals(const Program& p, int* order) {
  const UrScriptSource& s = *p.urscript;
  struct Pending {
    const Target* t;
    int expr;
    const Motion* m;
  };
  std::vector<Pending> pending;
  for (const Motion& m : p.motions) {
    if (m.inserted || m.statement_id < 0 || m.statement_id >= static_cast<int>(s.statements.size())) continue;
    const UrScriptSource::Statement& st = s.statements[static_cast<size_t>(m.statement_id)];
    size_t k = 0;
    if (m.aux && k < st.target_expr.size() && m.aux->modified) pending.push_back({&*m.aux, st.target_expr[k], &m});
    if (m.aux) ++k;
    if (m.target.modified && m.target.kind == Target::Kind::kCartesian) pending.push_back({&m.target, st.target_expr.at(k), &m});
  }
  for (const Pending& q : pending)
    if (q.expr < 0 || q.t->value_id < 0)
      throw calib::ArgumentError(q.m->where.str() + ": cannot write the corrected value of " + label(*q.t) + ": its pose is not a literal p[...]");
  std::map<int, Eigen::Isometry3d> done;
  std::map<int, std::pair<std::string, std::string>> text;  // literal -> (text, where)
  while (!pending.empty()) {
    bool progress = false;
    for (size_t i = 0; i < pending.size();) {
      const Pending q = pending[i];
      std::vector<int> lits;
      literalsOf(s, q.expr, &lits);
      bool waits = false;
      for (int l : lits)
        for (const Pending& o : pending)
          waits = waits || (l != q.t->value_id && o.t->value_id == l);
      if (waits) {
        ++i;
        continue;
      }
      const UrScriptSource::Literal& lit = s.literals.at(static_cast<size_t>(q.t->value_id));
      const Eigen::Isometry3d x = solveLiteral(s, q.expr, q.t->value_id, calib::toIsometry(q.t->xyzAbc()), done);
      const std::string t = literalText(s, lit, x);
      const auto it = text.find(q.t->value_id);
      if (it != text.end() && it->second.first != t)
        throw calib::ArgumentError(q.m->where.str() + ": " + label(*q.t) + " needs a different correction here than at " + it->second.second +
                            " (the same p[...] with another tool or path): give the motions their own poses");
      if (it == text.end()) {
        text[q.t->value_id] = {t, q.m->where.str()};
        done[q.t->value_id] = x;
      }
      pending.erase(pending.begin() + static_cast<long>(i));
      progress = true;
    }
    if (!progress)
      throw calib::ArgumentError(pending.front().m->where.str() + ": cannot write the corrected value of " + label(*pending.front().t) +
                          ": its pose expression and another corrected target's depend on each other's literals");
  }
  std::vector<Edit> edits;
  for (const auto& [l, t] : text) {
    const UrScriptSource::Literal& lit = s.literals[static_cast<size_t>(l)];
    if (t.first != s.text.substr(lit.begin, lit.end - lit.begin)) edits.push_back({lit.begin, lit.end, t.first, (*order)++});
  }
  return edits;
}

std::string patch(const Program& p) {
  const UrScriptSource& s = *p.urscript;
  int order = 0;
  std::vector<Edit> edits = correctedLiterals(p, &order);
  for (size_t i = 0; i < p.motions.size(); ++i) {
    const Motion& m = p.motions[i];
    if (m.statement_id < 0 || m.statement_id >= static_cast<int>(s.statements.size()))
      throw calib::ArgumentError("writeUrScript: a motion has no statement in the script");
    const UrScriptSource::Statement& st = s.statements[static_cast<size_t>(m.statement_id)];
    // a movel with a time t split into pieces: each piece its share of t
    const std::string duration = pieceDurationText(p, i, st.duration_s);
    if (!m.inserted && !duration.empty()) edits.push_back({st.duration_text.first, st.duration_text.second, duration, order++});
    if (m.inserted) {
      std::vector<const Target*> targets;
      if (m.aux) targets.push_back(&*m.aux);
      targets.push_back(&m.target);
      if (targets.size() != st.targets.size()) throw calib::ArgumentError("writeUrScript: an inserted motion does not match its statement");
      std::string line = s.text.substr(st.line_begin, st.code_begin - st.line_begin);
      size_t pos = st.code_begin;
      for (size_t k = 0; k < st.targets.size(); ++k) {
        // the rotation vector written like the target's first literal (its sign at 180 deg)
        Eigen::Vector3d near = Eigen::Vector3d::Zero();
        if (st.target_expr[k] >= 0) {
          std::vector<int> lits;
          literalsOf(s, st.target_expr[k], &lits);
          const UrScriptSource::Literal& first = s.literals.at(static_cast<size_t>(lits.front()));
          near = Eigen::Vector3d(first.value[3], first.value[4], first.value[5]);
        }
        line += s.text.substr(pos, st.targets[k].first - pos);
        line += poseText(urValues(calib::toIsometry(targets[k]->xyzAbc()), near));
        pos = st.targets[k].second;
      }
      if (!duration.empty()) {
        line += s.text.substr(pos, st.duration_text.first - pos) + duration;
        pos = st.duration_text.second;
      }
      line += s.text.substr(pos, st.code_end - pos);
      line += st.eol.empty() ? (s.text.find("\r\n") != std::string::npos ? "\r\n" : "\n") : st.eol;
      edits.push_back({st.line_begin, st.line_begin, line, order++});
    }
  }
  std::stable_sort(edits.begin(), edits.end(), [](const Edit& a, const Edit& b) {
    return a.begin != b.begin ? a.begin < b.begin : a.order < b.order;
  });
  std::string out;
  size_t pos = 0;
  for (const Edit& e : edits) {
    if (e.begin < pos) throw calib::ArgumentError("writeUrScript: overlapping edits");
    out += s.text.substr(pos, e.begin - pos) + e.text;
    pos = e.end;
  }
  return out + s.text.substr(pos);
}

// --- a new script from the motion model (XML, KRL)

[[noreturn]] void refuse(const Motion& m, const std::string& why) {
  throw calib::ArgumentError(m.where.str() + ": cannot convert '" + m.statement + "' to URScript: " + why);
}

std::string identifier(const std::string& name) {
  std::string s;
  for (char c : name) s += std::isalnum(static_cast<unsigned char>(c)) || c == '_' ? c : '_';
  if (s.empty() || std::isdigit(static_cast<unsigned char>(s[0]))) s = "prog_" + s;
  return s;
}

/// A KRL line's code: without the indentation, a comment and trailing blanks.
std::string trimmedCode(const std::string& line) {
  size_t b = line.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  std::string s = line.substr(b);
  const size_t semi = s.find(';');
  if (semi != std::string::npos) s = s.substr(0, semi);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.pop_back();
  return s;
}

std::string upperTrim(const std::string& line) {
  std::string s = trimmedCode(line);
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

/// KRL lines that are part of the motion model (frames, speeds, approximation, the inline
/// forms' data, the INI fold's standard housekeeping); any other code line is logic that
/// URScript output would lose.
bool motionModelLine(const std::string& u) {
  static const char* const prefixes[] = {"DEF ", "DEFDAT ", "DECL ", "$TOOL", "$BASE", "$VEL", "$APO", "BAS ", "BAS(",
                                         "PDAT_ACT", "LDAT_ACT", "FDAT_ACT", "$BWDSTART", "$H_POS", "SPLINE", "ENDSPLINE",
                                         "GLOBAL INTERRUPT DECL 3 WHEN $STOPMESS", "INTERRUPT ON 3"};
  if (u.empty() || u == "END" || u == "ENDDAT" || u[0] == '&') return true;
  for (const char* p : prefixes)
    if (u.rfind(p, 0) == 0) return true;
  return false;
}

void refuseKrlLogic(const KrlSource& k) {
  std::vector<std::pair<size_t, size_t>> motion_lines;
  for (const auto& st : k.statements)
    if (st.file == 0) motion_lines.push_back({st.line_begin, st.code_end});
  size_t pos = 0;
  int line = 1;
  while (pos < k.src_text.size()) {
    size_t nl = k.src_text.find('\n', pos);
    if (nl == std::string::npos) nl = k.src_text.size();
    bool in_motion = false;
    for (const auto& [b, e] : motion_lines) in_motion = in_motion || (pos >= b && pos <= e);
    const std::string u = upperTrim(k.src_text.substr(pos, nl - pos));
    if (!in_motion && !motionModelLine(u))
      throw calib::ArgumentError(k.src_path + ":" + std::to_string(line) + ": cannot convert to URScript: the KRL statement '" +
                          trimmedCode(k.src_text.substr(pos, nl - pos)) +
                          "' is not a motion, frame or speed, and URScript output carries the motion model only (" +
                          kDropStatementsHint + ")");
    pos = nl + 1;
    ++line;
  }
}

/// The pass-through statements of a program read from XML (a KRL, RAPID or URScript line
/// outside the motion model) that URScript written from the motion model would lose, judged by
/// the rule refuseKrlLogic applies to a .src: a KRL line of the motion model's housekeeping
/// (motionModelLine) and the .dat's declarations are left out, any other line is refused,
/// naming it (convert --drop-unconvertible leaves them out and lists them).
void refuseLogicPassThrough(const Program& p) {
  for (const PassThrough& s : p.passthrough) {
    if (!s.role.empty()) continue;  // carried for its own language only
    if (s.language == "URScript" && commentText(s)) continue;  // a comment: written (generate)
    const bool krl = s.refuse.empty() && s.language == "KRL";
    if (krl && (s.section == PassThrough::Section::kData || motionModelLine(upperTrim(s.text)))) continue;
    throw calib::ArgumentError(s.where.str() + ": cannot convert to URScript: the " + s.language + " statement '" +
                               trimmedCode(s.text) + "' is not a motion, frame or speed, and URScript output carries the motion model only (" +
                               kDropStatementsHint + ")");
  }
}

bool isIdentifier(const std::string& s) {
  if (s.empty() || !(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_')) return false;
  for (char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) return false;
  return true;
}

/// A comment's text as UTF-8, which a script is read as: UTF-8 as it is, else its bytes read as
/// ISO-8859-1 (a KUKA or ABB program's comments: "Werkst\xFCck" becomes "Werkstück"); control
/// characters become '?'.
std::string asUtf8(const std::string& text) {
  if (calib::isPlainText(text)) return text;
  std::string out;
  for (const char ch : text) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c < 0x20 || (c >= 0x7F && c < 0xA0)) out += c == '\t' ? '\t' : '?';
    else if (c < 0x80) out += ch;
    else {
      out += static_cast<char>(0xC0 | (c >> 6));
      out += static_cast<char>(0x80 | (c & 0x3F));
    }
  }
  return out;
}

std::string generate(const Program& p) {
  if (p.krl) refuseKrlLogic(*p.krl);  // its pass-through statements are the .src's own lines
  else refuseLogicPassThrough(p);
  std::ostringstream out;
  out << "def " << identifier(p.name.empty() ? "program" : p.name) << "():\n";
  out << "  # written by " << p.written_by << (p.source_file.empty() ? "" : " from " + std::filesystem::path(p.source_file).filename().string())
      << ": poses in the Base frame (m, rotation vector in rad), KUKA S/T and PTP speeds are not carried (the controller takes the joint solution nearest the current joints)\n";
  std::string tool;  // the set_tcp written last
  std::map<std::string, std::string> variables;  // pose variable -> its p[...]
  // the comments (withoutCarriedLines made every language's URScript lines) where they were:
  // before motion k, then after the last
  // (a KRL program's data-list comments first, its local subroutines' after the last motion)
  const auto comments = [&](size_t k) {
    for (const PassThrough& s : p.passthrough) {
      if (!s.role.empty() || s.language != "URScript" || !commentText(s)) continue;
      const size_t at = s.section == PassThrough::Section::kBody    ? std::min(s.before_motion, p.motions.size())
                        : s.section == PassThrough::Section::kData ? 0
                                                                    : p.motions.size();
      if (at == k) out << "  #" << asUtf8(*commentText(s)) << "\n";
    }
  };
  for (size_t mi = 0; mi < p.motions.size(); ++mi) {
    comments(mi);
    const Motion& m = p.motions[mi];
    if (m.relative) refuse(m, "URScript has no relative motion");
    if (m.type == MotionType::kSpl) refuse(m, "URScript has no spline motion");
    if (m.circ_angle_deg) refuse(m, "URScript's movec has no circular angle (CA)");
    if (m.external_tcp) refuse(m, "URScript has no external TCP");
    if (!m.target_problem.empty()) refuse(m, m.target_problem);
    if (!m.duration_expr.empty()) refuse(m, "its time (" + detail::excerpt(m.duration_expr) + ") is computed at run time in its own language");
    if (m.duration_s && m.type == MotionType::kCirc)
      refuse(m, "its time (" + calib::formatFixed(*m.duration_s, 4) + " s): URScript's movec has no time t (convert --drop-unconvertible converts it without)");
    for (const auto& e : m.target.ext)
      if (e && *e != 0) refuse(m, "the target moves external axes, which a UR has none of");
    if (!m.approximation.empty() && (m.approximation.front() != Approximation::kCDis || !m.approximation_value))
      refuse(m, "URScript's blend is a radius: only C_DIS with its distance ($APO.CDIS) converts");
    if (m.tool.source != FrameSetting::Source::kUnset) {
      if (!m.tool.value) refuse(m, "its tool (" + m.tool.text + ") is not known (give the $config.dat with --config)");
      const std::string tcp = urPoseText(*m.tool.value);
      if (tcp != tool) out << "  set_tcp(" << tcp << ")\n";
      tool = tcp;
    }
    Eigen::Isometry3d base = Eigen::Isometry3d::Identity();
    if (m.base.source != FrameSetting::Source::kUnset) {
      if (!m.base.value) refuse(m, "its base (" + m.base.text + ") is not known (give the $config.dat with --config)");
      base = calib::toIsometry(*m.base.value);
    }
    // a named point becomes a pose variable (assigned before the motion that uses it first, and
    // again where the program gives it another value)
    auto pose = [&](const Target& t) {
      if (!t.completePose()) refuse(m, "the target " + label(t) + " is partial (URScript poses are complete)");
      const std::string text = urPoseText(calib::toXyzAbc(base * calib::toIsometry(t.xyzAbc())));
      if (!isIdentifier(t.name)) return text;
      auto& known = variables[t.name];
      if (known != text) out << "  " << t.name << " = " << text << "\n";
      known = text;
      return t.name;
    };
    std::string args;
    if (m.target.kind == Target::Kind::kAxis) {
      if (m.type != MotionType::kPtp) refuse(m, "an axis target on a path motion");
      args = "[";
      for (int k = 0; k < 6; ++k) {
        if (!m.target.axes[static_cast<size_t>(k)]) refuse(m, "the axis target is partial");
        args += (k ? ", " : "") + calib::formatFixed(*m.target.axes[static_cast<size_t>(k)] * calib::kDegToRad, kDecimals);
      }
      args += "]";
      if (isIdentifier(m.target.name)) {  // a named axis point: a joint-list variable
        auto& known = variables[m.target.name];
        if (known != args) out << "  " << m.target.name << " = " << args << "\n";
        known = args;
        args = m.target.name;
      }
    } else {
      if (m.aux) args = pose(*m.aux) + ", ";
      args += pose(m.target);
    }
    const char* f = m.type == MotionType::kPtp ? "movej" : m.type == MotionType::kCirc ? "movec" : "movel";
    if (m.type != MotionType::kPtp && m.vel_m_s) args += ", v=" + calib::formatFixed(*m.vel_m_s, 4);
    if (m.duration_s) {  // the move's time (s): a piece of a split motion its share
      const std::string piece = pieceDurationText(p, static_cast<size_t>(&m - p.motions.data()), *m.duration_s);
      args += ", t=" + (piece.empty() ? calib::formatFixed(*m.duration_s, 4) : piece);
    }
    if (m.approximation_value && !m.approximation.empty()) args += ", r=" + calib::formatFixed(*m.approximation_value / 1000.0, kDecimals);
    out << "  " << f << "(" << args << ")\n";
  }
  comments(p.motions.size());
  out << "end\n";
  return out.str();
}

}  // namespace

std::string urPoseText(const calib::XyzAbc& pose, const double near_rotvec[3]) {
  const Eigen::Vector3d near = near_rotvec ? Eigen::Vector3d(near_rotvec[0], near_rotvec[1], near_rotvec[2]) : Eigen::Vector3d::Zero();
  return poseText(urValues(calib::toIsometry(pose), near));
}

std::string writeUrScript(const Program& program) {
  if (program.urscript) return patch(program);
  // converted from URScript with its text carried (XML): that text, with the model laid on it
  if (const auto text = carriedSource(program, "URScript")) return patch(reattachCarried(program, parseUrScript(*text, program.source_file)));
  return generate(program);
}

Program urScriptForConversion(const Program& program, const char* format_name) {
  Program out = program;
  if (!program.urscript) return out;
  if (std::string(format_name) == "XML") {  // XML carries the whole text (carrySourceLines)
    for (const UrScriptSource::Other& o : program.urscript->others) {
      PassThrough s;
      s.language = "URScript";
      s.text = o.text;
      s.where = o.where;
      out.passthrough.push_back(s);
    }
    std::vector<std::pair<size_t, size_t>> spans;
    for (const Motion& m : out.motions) {
      const UrScriptSource::Statement& st = program.urscript->statements.at(static_cast<size_t>(m.statement_id));
      spans.emplace_back(st.code_begin, st.code_end);
    }
    carrySourceLines(out, program.urscript->text, "URScript", '#', spans);
  } else if (program.urscript->others.empty()) {
    // the script's comment lines, which the other language writes as its own comments
    // (withoutCarriedLines)
    Program lines = out;
    std::vector<std::pair<size_t, size_t>> spans;
    for (const Motion& m : lines.motions) {
      const UrScriptSource::Statement& st = program.urscript->statements.at(static_cast<size_t>(m.statement_id));
      spans.emplace_back(st.code_begin, st.code_end);
    }
    carrySourceLines(lines, program.urscript->text, "URScript", '#', spans);
    for (const PassThrough& s : lines.passthrough)
      if (s.role == "comment" && commentText(s)) out.passthrough.push_back(s);
  } else {
    const UrScriptSource::Other& o = program.urscript->others.front();
    throw calib::ArgumentError(o.where.str() + ": cannot convert to " + format_name + ": the URScript statement '" + o.text +
                        "' is not a motion, set_tcp or pose assignment, and the conversion carries the motion model only" +
                        (program.urscript->others.size() > 1
                             ? " (" + std::to_string(program.urscript->others.size() - 1) + " more such statement(s))"
                             : std::string()) +
                        "; " + kDropStatementsHint);
  }
  for (Motion& m : out.motions) {
    if (!isIdentifier(m.target.name)) m.target.name.clear();
    if (m.aux && !isIdentifier(m.aux->name)) m.aux->name.clear();
  }
  out.urscript.reset();
  return out;
}

}  // namespace accura::postproc
