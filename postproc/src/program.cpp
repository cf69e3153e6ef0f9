#include "accura/postproc/program.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <cstdio>
#include <sstream>

#include <Eigen/Geometry>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"
#include "accura/calib/text.h"
#include "accura/postproc/rapid.h"
#include "krl_internal.h"

namespace accura::postproc {

std::string SourceLocation::str() const {
  std::string s = calib::formatLocation(file, line, column);
  // formatLocation ends with ": "; a location on its own has no separator.
  if (s.size() >= 2) s.resize(s.size() - 2);
  return s;
}

const char* toString(Approximation a) {
  switch (a) {
    case Approximation::kCPtp: return "C_PTP";
    case Approximation::kCDis: return "C_DIS";
    case Approximation::kCVel: return "C_VEL";
    case Approximation::kCOri: return "C_ORI";
    case Approximation::kCSpl: return "C_SPL";
  }
  return "?";
}

bool parseApproximation(const std::string& text, Approximation* out) {
  std::string u;
  for (char c : text) u += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  static const Approximation all[] = {Approximation::kCPtp, Approximation::kCDis, Approximation::kCVel,
                                      Approximation::kCOri, Approximation::kCSpl};
  for (Approximation a : all) {
    if (u == toString(a)) {
      *out = a;
      return true;
    }
  }
  return false;
}

bool Target::completePose() const {
  for (const auto& c : pose)
    if (!c) return false;
  return true;
}

calib::XyzAbc Target::xyzAbc() const {
  if (!completePose()) throw calib::ArgumentError("Target::xyzAbc: the pose of " + (name.empty() ? std::string("an inline target") : name) + " is partial");
  return calib::XyzAbc{*pose[0], *pose[1], *pose[2], *pose[3], *pose[4], *pose[5]};
}

void Target::setPose(const calib::XyzAbc& p) {
  pose = {p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg};
}

bool Target::setPoseIfChanged(const calib::XyzAbc& p) {
  double v[6] = {p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg};
  if (pose[3] && pose[4] && pose[5]) {
    // the same rotation in the angles nearest to the written ones: (A, B, C) and
    // (A + 180, 180 - B, C + 180) are one rotation, and so is any angle +- 360; the controller
    // takes either (KUKA normalises A, B, C itself), and a correction that rounds to zero then
    // keeps the written text (A 0, B 180, C 0 stays, not A 180, B 0, C -180)
    const double written[3] = {*pose[3], *pose[4], *pose[5]};
    std::vector<std::array<double, 3>> sets = {{v[3], v[4], v[5]}, {v[3] + 180.0, 180.0 - v[4], v[5] + 180.0}};
    // at B = +-90 deg (gimbal lock) only A - C (B = 90) or A + C (B = -90) is the rotation's:
    // the written A with the C that keeps it
    if (std::abs(std::cos(v[4] * calib::kDegToRad)) < 1e-9)
      sets.push_back({written[0], v[4], v[4] > 0 ? written[0] - (v[3] - v[5]) : (v[3] + v[5]) - written[0]});
    double best = std::numeric_limits<double>::infinity();
    for (const auto& set : sets) {
      double near[3], dist = 0;
      for (int k = 0; k < 3; ++k) {
        near[k] = set[k] + 360.0 * std::round((written[k] - set[k]) / 360.0);
        dist += std::abs(near[k] - written[k]);
      }
      if (!(dist < best)) continue;
      best = dist;
      for (int k = 0; k < 3; ++k) v[3 + k] = near[k];
    }
  }
  auto text = [](int k, double x) { return k < 3 ? formatMm(x) : formatDeg(x); };
  bool changed = false;
  for (int k = 0; k < 6; ++k) {
    if (pose[k] && text(k, *pose[k]) == text(k, v[k])) continue;
    pose[k] = v[k];
    changed = true;
  }
  return changed;
}

FrameSetting runTimeFrame(const std::string& text, const SourceLocation& where, const std::string& note) {
  FrameSetting f;
  f.source = FrameSetting::Source::kUnknown;
  f.text = text;
  f.where = where;
  f.note = note;
  f.run_time = true;
  return f;
}

std::string orientationControlValue(const std::string& value, bool circ) {
  if (value.empty() || value[0] != '#') return value;
  const std::string v = calib::upperAscii(value);
  return v == (circ ? "#BASE" : "#VAR") ? std::string() : v;
}

bool sameFrame(const FrameSetting& a, const FrameSetting& b) {
  if (a.source != b.source || a.index != b.index || a.value.has_value() != b.value.has_value()) return false;
  if (a.source == FrameSetting::Source::kUnknown && a.text != b.text) return false;
  if (a.value) {
    const calib::XyzAbc& x = *a.value;
    const calib::XyzAbc& y = *b.value;
    return formatMm(x.x_mm) == formatMm(y.x_mm) && formatMm(x.y_mm) == formatMm(y.y_mm) && formatMm(x.z_mm) == formatMm(y.z_mm) &&
           formatDeg(x.a_deg) == formatDeg(y.a_deg) && formatDeg(x.b_deg) == formatDeg(y.b_deg) && formatDeg(x.c_deg) == formatDeg(y.c_deg);
  }
  return true;
}

bool programChanged(const Program& program) {
  for (const Motion& m : program.motions) {
    if (m.inserted || m.target.modified || (m.aux && m.aux->modified)) return true;
  }
  return false;
}

namespace {

using calib::upperAscii;

bool isIdentChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '$'; }

// `up` as an identifier (upper case) in `text`.
bool containsIdentifier(const std::string& text, const std::string& up) {
  const std::string u = upperAscii(text);
  for (size_t p = u.find(up); p != std::string::npos; p = u.find(up, p + 1)) {
    const bool left = p == 0 || !isIdentChar(u[p - 1]);
    const bool right = p + up.size() >= u.size() || !isIdentChar(u[p + up.size()]);
    if (left && right) return true;
  }
  return false;
}

}  // namespace

bool isDeclarableName(const std::string& name) {
  if (name.empty() || name.size() > 64 || std::isdigit(static_cast<unsigned char>(name[0]))) return false;
  return std::all_of(name.begin(), name.end(), isIdentChar);
}

namespace {

bool lineIsComment(const std::string& line, char comment) {
  const size_t b = line.find_first_not_of(" \t\r");
  return b == std::string::npos || line[b] == comment;
}

std::string motionName(const Motion& m) { return m.statement.empty() ? motionKeyword(m) : m.statement; }

}  // namespace

void carrySourceLines(Program& program, const std::string& text, const std::string& language, char comment,
                      const std::vector<std::pair<size_t, size_t>>& motion_spans) {
  std::vector<size_t> starts = {0};  // first byte of each line
  for (size_t i = 0; i < text.size(); ++i)
    if (text[i] == '\n' && i + 1 < text.size()) starts.push_back(i + 1);
  auto lineOf = [&](size_t off) { return static_cast<int>(std::upper_bound(starts.begin(), starts.end(), off) - starts.begin()); };
  const int lines = text.empty() ? 0 : static_cast<int>(starts.size());
  std::vector<int> motion_of(static_cast<size_t>(lines) + 2, -1);  // line -> motion holding it
  std::vector<int> first_line(program.motions.size(), 0);
  for (size_t k = 0; k < motion_spans.size() && k < program.motions.size(); ++k) {
    if (program.motions[k].inserted) continue;  // a point the compensator added: no line of its own
    const int a = lineOf(motion_spans[k].first), b = lineOf(motion_spans[k].second > 0 ? motion_spans[k].second - 1 : 0);
    for (int l = a; l <= b; ++l) {
      if (motion_of[static_cast<size_t>(l)] >= 0 && motion_of[static_cast<size_t>(l)] != static_cast<int>(k))
        throw calib::ArgumentError(program.motions[k].where.file + ":" + std::to_string(l) + ": cannot carry this " + language +
                                   " line through the conversion: it holds two motion statements (write them on lines of their own)");
      motion_of[static_cast<size_t>(l)] = static_cast<int>(k);
    }
    first_line[k] = a;
    program.motions[k].source_line = a;
  }
  for (size_t k = program.motions.size(), next = static_cast<size_t>(lines) + 1; k-- > 0;) {  // inserted: as the next one
    if (program.motions[k].inserted || first_line[k] == 0) first_line[k] = static_cast<int>(next);
    else next = static_cast<size_t>(first_line[k]);
  }
  std::vector<int> statement_at(static_cast<size_t>(lines) + 2, -1);  // line -> pass-through statement
  for (size_t i = 0; i < program.passthrough.size(); ++i) {
    const PassThrough& s = program.passthrough[i];
    if (s.language != language || s.where.line < 1 || s.where.line > lines) continue;
    if (motion_of[static_cast<size_t>(s.where.line)] >= 0)
      throw calib::ArgumentError(s.where.str() + ": cannot carry this " + language +
                                 " line through the conversion: it holds a motion and another statement (write them on lines of their own)");
    statement_at[static_cast<size_t>(s.where.line)] = static_cast<int>(i);
  }
  std::vector<PassThrough> all;
  size_t next_motion = 0;  // motions starting before the line
  for (int l = 1; l <= lines; ++l) {
    while (next_motion < program.motions.size() && first_line[next_motion] < l) ++next_motion;
    const size_t b = starts[static_cast<size_t>(l - 1)];
    const size_t e = l < lines ? starts[static_cast<size_t>(l)] : text.size();
    std::string line = text.substr(b, e - b), eol;
    if (!line.empty() && line.back() == '\n') {
      line.pop_back();
      eol = "\n";
      if (!line.empty() && line.back() == '\r') {
        line.pop_back();
        eol = "\r\n";
      }
    }
    PassThrough s;
    if (statement_at[static_cast<size_t>(l)] >= 0) {
      s = program.passthrough[static_cast<size_t>(statement_at[static_cast<size_t>(l)])];
    } else {
      s.language = language;
      s.where.file = program.source_file;
      s.where.line = l;
      s.where.column = 1;
      s.before_motion = next_motion;
      s.role = motion_of[static_cast<size_t>(l)] >= 0 ? "motion" : lineIsComment(line, comment) ? "comment" : "model";
    }
    s.text = line;
    s.line = l;
    s.eol = eol;
    s.section = PassThrough::Section::kBody;  // in the order of the lines
    s.before_motion = next_motion;
    all.push_back(std::move(s));
  }
  for (const PassThrough& s : program.passthrough)  // of other languages, or without a line
    if (s.line == 0 && (s.language != language || s.where.line < 1 || s.where.line > lines)) all.push_back(s);
  program.passthrough = std::move(all);
}

std::optional<std::string> carriedSource(const Program& program, const std::string& language) {
  std::vector<const PassThrough*> lines;
  for (const PassThrough& s : program.passthrough)
    if (s.language == language && s.line > 0) lines.push_back(&s);
  if (lines.empty()) return std::nullopt;
  std::stable_sort(lines.begin(), lines.end(), [](const PassThrough* a, const PassThrough* b) { return a->line < b->line; });
  std::string text;
  for (size_t i = 0; i < lines.size(); ++i) {
    if (i && lines[i]->line == lines[i - 1]->line)
      throw calib::ArgumentError(lines[i]->where.str() + ": cannot write the carried " + language + " text: line " +
                                 std::to_string(lines[i]->line) + " is given twice");
    text += lines[i]->text + lines[i]->eol;
  }
  return text;
}

Program reattachCarried(const Program& program, Program parsed) {
  std::vector<const Motion*> carried;
  for (const Motion& m : program.motions)
    if (m.source_line > 0 && !m.inserted) carried.push_back(&m);
  if (carried.size() != parsed.motions.size())
    throw calib::ArgumentError(program.source_file + ": cannot write the carried source back: it holds " + std::to_string(parsed.motions.size()) +
                               " motions and the program " + std::to_string(carried.size()) + " that carry a line");
  auto near = [](const std::optional<double>& a, const std::optional<double>& b) {
    return a.has_value() == b.has_value() && (!a || std::abs(*a - *b) <= 1e-6 * std::max(1.0, std::abs(*a)));
  };
  auto lay = [](Target& into, const Target& from) {
    if (from.kind != Target::Kind::kCartesian || into.kind != Target::Kind::kCartesian || !from.completePose() || !into.completePose()) return;
    bool changed = into.setPoseIfChanged(from.xyzAbc());
    // a new point in place of a declared one (a split CIRC's auxiliary point): declared anew,
    // the old one keeps its value
    if (!from.name.empty() && !into.name.empty() && upperAscii(from.name) != upperAscii(into.name)) {
      into.new_declaration = true;
      into.replaces = into.name;
      into.name = from.name;
      changed = true;
    }
    if (from.abb_conf && into.abb_conf != from.abb_conf) {
      into.abb_conf = from.abb_conf;
      changed = true;
    }
    into.modified = into.modified || changed;
  };
  // the time of a carried motion's pieces (a split one: each its share) adds up to its
  // statement's, within the 4 decimals each is written with
  auto sameTime = [](const std::vector<const Motion*>& pieces, const Motion& q) {
    double sum = 0;
    bool any = false;
    for (const Motion* x : pieces) {
      any = any || x->duration_s.has_value();
      sum += x->duration_s.value_or(0);
    }
    if (!q.duration_s) return !any;
    return std::abs(sum - *q.duration_s) <= 0.5e-4 * static_cast<double>(pieces.size()) + 1e-9;
  };
  std::vector<Motion> motions;
  size_t j = 0;
  std::vector<const Motion*> pending;  // motions without a line, before the next carried one
  for (const Motion& m : program.motions) {
    if (m.source_line == 0 || m.inserted) {
      pending.push_back(&m);
      continue;
    }
    Motion& q = parsed.motions[j++];
    std::vector<const Motion*> pieces = pending;
    pieces.push_back(&m);
    if (q.type != m.type || q.where.line != m.source_line || !near(q.vel_m_s, m.vel_m_s) || !near(q.approximation_value, m.approximation_value) ||
        q.approximation != m.approximation || !sameTime(pieces, q))
      throw calib::ArgumentError(m.where.str() + ": cannot write the carried source back: the motion " + motionName(m) +
                                 " differs from its carried statement at line " + std::to_string(m.source_line) + " (" + motionName(q) + ")");
    for (const Motion* a : pending) {
      Motion ins = q;
      ins.target = a->target;
      ins.aux = a->aux;
      ins.inserted = true;
      if (ins.aux.has_value() != q.aux.has_value())
        throw calib::ArgumentError(a->where.str() + ": cannot write the motion " + motionName(*a) + " into the carried source: it has no form like the next motion's");
      motions.push_back(std::move(ins));
    }
    pending.clear();
    lay(q.target, m.target);
    if (q.aux && m.aux) lay(*q.aux, *m.aux);
    motions.push_back(q);
  }
  if (!pending.empty())
    throw calib::ArgumentError(pending.front()->where.str() + ": cannot write the motion " + motionName(*pending.front()) +
                               " into the carried source: it comes after the last carried motion");
  parsed.motions = std::move(motions);
  return parsed;
}

bool isXmlComment(const PassThrough& s) { return s.language == "XML" && s.role == "comment"; }

std::optional<std::string> commentText(const PassThrough& s) {
  if (isXmlComment(s)) return s.text;
  // (a RAPID or URScript source line carried whole is role "comment": a comment or a blank line)
  if (!s.role.empty() && s.role != "comment") return std::nullopt;
  const char marker = s.language == "KRL" ? ';' : s.language == "RAPID" ? '!' : s.language == "URScript" ? '#' : '\0';
  const size_t b = s.text.find_first_not_of(" \t");
  if (!marker || b == std::string::npos || s.text[b] != marker || s.text.find('\n') != std::string::npos) return std::nullopt;
  std::string text = s.text.substr(b + 1);
  // the editor's: fold markers (paired), an inline form's parameter lines (;%{PE}, ;Params ..)
  if (s.language == "KRL" && (krl_detail::isFoldMarker(s.text) || text.compare(0, 2, "%{") == 0 || upperAscii(text.substr(0, 7)) == "PARAMS "))
    return std::nullopt;
  return text;
}

bool withoutCarriedLinesChanges(const Program& program, const std::string& language) {
  for (const PassThrough& s : program.passthrough)
    if (s.language != language && (!s.role.empty() || commentText(s))) return true;
  return false;
}

Program withoutCarriedLines(const Program& program, const std::string& language) {
  Program out = program;
  out.passthrough.clear();
  // (indented as the writers indent a routine's statements)
  const char* marker = language == "KRL" ? ";" : language == "RAPID" ? "    !" : language == "URScript" ? "  #" : nullptr;
  for (const PassThrough& s : program.passthrough) {
    const std::optional<std::string> comment = s.language == language ? std::nullopt : commentText(s);
    if (comment && marker) {
      std::istringstream lines(*comment);
      for (std::string line; std::getline(lines, line);) {
        while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) line.pop_back();
        PassThrough c = s;
        c.language = language;
        c.role.clear();
        c.line = 0;  // a statement of its own, not a line of a carried source
        c.eol = "\n";
        // not a KRL fold marker (;FOLD / ;ENDFOLD), which the KUKA editor pairs
        const bool fold = language == "KRL" && krl_detail::isFoldMarker(";" + line);
        c.text = marker + std::string(fold ? " " : "") + line;
        out.passthrough.push_back(std::move(c));
      }
      continue;
    }
    if (s.role.empty() || s.language == language) out.passthrough.push_back(s);
  }
  return out;
}

std::string newPointName(const Program& program, const std::string& base, const std::vector<std::string>& taken) {
  for (int n = 1; n < 100000; ++n) {
    const std::string suffix = "_" + std::to_string(n);
    const std::string name = base.substr(0, std::min(base.size(), static_cast<size_t>(24) - suffix.size())) + suffix;
    const std::string up = upperAscii(name);
    bool used = false;
    for (const std::string& t : taken) used = used || upperAscii(t) == up;
    for (const Motion& m : program.motions) {
      used = used || upperAscii(m.target.name) == up || (m.aux && upperAscii(m.aux->name) == up);
    }
    if (program.krl) used = used || containsIdentifier(program.krl->src_text, up) || containsIdentifier(program.krl->dat_text, up);
    // (and the names of the module given with --config: its global data are the task's)
    if (program.rapid) used = used || containsIdentifier(program.rapid->text, up) || containsIdentifier(program.rapid->task_text, up);
    for (const PassThrough& s : program.passthrough) used = used || containsIdentifier(s.text, up);
    if (!used) return name;
  }
  throw calib::ArgumentError("newPointName: no free name for " + base);
}

void checkPassThrough(const Program& program, const std::string& language) {
  for (const PassThrough& s : program.passthrough) {
    if (!s.role.empty()) continue;  // carried for its own language only (withoutCarriedLines)
    if (!s.refuse.empty())
      throw calib::ArgumentError(s.where.str() + ": cannot convert '" + s.text + "': " + s.refuse);
    if (!language.empty() && s.language != language)
      throw calib::ArgumentError(s.where.str() + ": cannot convert the " + s.language + " statement '" + s.text + "' to " + language +
                          ": it is outside the motion model and only " + s.language +
                          " can carry it (" + kDropStatementsHint + ")");
  }
}

std::string motionKeyword(const Motion& m) {
  std::string k;
  switch (m.type) {
    case MotionType::kPtp: k = "PTP"; break;
    case MotionType::kLin: k = "LIN"; break;
    case MotionType::kCirc: k = "CIRC"; break;
    case MotionType::kSpl: return "SPL";
  }
  if (m.spline) k = "S" + k;
  if (m.relative) k += "_REL";
  return k;
}

std::string motionInstruction(const Motion& m) {
  const std::string& s = m.statement;
  size_t b = s.find_first_not_of(" \t");
  if (b != std::string::npos && s[b] == '<') ++b;  // XML: <lin>
  size_t e = b;
  while (e < s.size() && (std::isalnum(static_cast<unsigned char>(s[e])) || s[e] == '_')) ++e;
  return b == std::string::npos || e == b ? motionKeyword(m) : s.substr(b, e - b);
}

namespace {

// The motions [first, last] of the statement of motion `index`: the inserted ones, then the
// statement's own (not inserted).
std::pair<size_t, size_t> statementPieces(const Program& program, size_t index) {
  const std::vector<Motion>& ms = program.motions;
  if (index >= ms.size()) throw calib::ArgumentError("statementPieces: motion " + std::to_string(index) + " of " + std::to_string(ms.size()));
  size_t last = index;
  while (last < ms.size() && ms[last].inserted) ++last;
  if (last >= ms.size() || ms[last].statement_id != ms[index].statement_id)
    throw calib::ArgumentError("statementPieces: the inserted motion " + std::to_string(index) + " is not followed by its statement's motion");
  size_t first = last;
  while (first > 0 && ms[first - 1].inserted && ms[first - 1].statement_id == ms[last].statement_id) --first;
  return {first, last};
}

}  // namespace

std::vector<double> durationShares(const Program& program, size_t index) {
  const std::vector<Motion>& ms = program.motions;
  const auto [first, last] = statementPieces(program, index);
  const size_t k = last - first + 1;
  if (k == 1) return {1.0};
  std::vector<double> shares(k, 1.0 / double(k));
  // (a motion that moves external axes only leaves the arm where the one before it did)
  size_t b = first;
  while (b > 0 && ms[b - 1].arm_stays) --b;
  const Motion* before = b > 0 ? &ms[b - 1] : nullptr;
  if (!before || ms[last].start_unknown || before->target.kind != Target::Kind::kCartesian || !before->target.completePose())
    return shares;
  std::vector<Eigen::Isometry3d> T{calib::toIsometry(before->target.xyzAbc())};
  for (size_t i = first; i <= last; ++i) {
    if (ms[i].target.kind != Target::Kind::kCartesian || !ms[i].target.completePose()) return shares;
    T.push_back(calib::toIsometry(ms[i].target.xyzAbc()));
  }
  std::vector<double> len(k), rot(k);
  double total_len = 0, total_rot = 0;
  for (size_t i = 0; i < k; ++i) {
    len[i] = (T[i + 1].translation() - T[i].translation()).norm();
    rot[i] = Eigen::AngleAxisd(T[i].linear().transpose() * T[i + 1].linear()).angle();
    total_len += len[i];
    total_rot += rot[i];
  }
  const bool by_length = total_len > 1e-6;  // mm
  if (!by_length && !(total_rot > 1e-9)) return shares;  // rad
  for (size_t i = 0; i < k; ++i) shares[i] = by_length ? len[i] / total_len : rot[i] / total_rot;
  return shares;
}

std::string pieceDurationText(const Program& program, size_t index, double duration_s) {
  if (!(duration_s > 0)) return {};  // (no time programmed)
  const auto [first, last] = statementPieces(program, index);
  if (first == last) return {};
  const std::vector<double> shares = durationShares(program, last);
  double written = 0;  // the pieces before this one, as written
  for (size_t i = 0; i < index - first; ++i) written += std::stod(calib::formatFixed(duration_s * shares[i], 4));
  if (index < last) return calib::formatFixed(duration_s * shares[index - first], 4);
  return calib::formatFixed(std::max(duration_s - written, 0.0), 4);
}

std::string formatMm(double v) { return calib::formatFixed(v, 4); }
std::string formatDeg(double v) { return calib::formatFixed(v, 5); }

}  // namespace accura::postproc
