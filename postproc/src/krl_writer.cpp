// KRL writer: a program read from KRL patched in place, or a new program (see krl.h).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "accura/calib/errors.h"
#include "krl_internal.h"

namespace fs = std::filesystem;

namespace accura::postproc {
namespace {

using namespace krl_detail;

// ---------------------------------------------------------------------------------------------
// Writing

std::string formatAxis(double v) { return calib::formatFixed(v, 4); }

std::string componentText(const Target& t, const std::string& name) {
  int k;
  if ((k = indexOf(kCartNames, name)) >= 0 && t.kind == Target::Kind::kCartesian && t.pose[k])
    return k < 3 ? formatMm(*t.pose[k]) : formatDeg(*t.pose[k]);
  if ((k = indexOf(kAxisNames, name)) >= 0 && t.axes[k]) return formatAxis(*t.axes[k]);
  if ((k = indexOf(kExtNames, name)) >= 0 && t.ext[k]) return formatAxis(*t.ext[k]);
  if (name == "S" && t.status) return std::to_string(*t.status);
  if (name == "T" && t.turn) return std::to_string(*t.turn);
  return "";
}

/// `value` written like `written`: a KRL bit string ('B010010', the inline forms' and many OLP
/// tools' S and T) as one with at least as many digits, a hexadecimal one ('H12') as hex, else
/// decimal.
std::string integerLike(const std::string& written, int value) {
  const bool literal = written.size() >= 3 && written.front() == '\'' && written.back() == '\'';
  const char kind = literal ? static_cast<char>(std::toupper(static_cast<unsigned char>(written[1]))) : '\0';
  if ((kind != 'B' && kind != 'H') || value < 0) return std::to_string(value);
  const int base = kind == 'B' ? 2 : 16;
  std::string digits;
  for (int v = value; v > 0; v /= base) digits.insert(digits.begin(), "0123456789ABCDEF"[v % base]);
  while (digits.size() < written.size() - 3 || digits.empty()) digits.insert(digits.begin(), '0');
  return std::string("'") + written[1] + digits + "'";
}

// The new text of a target's aggregate: the numbers of the pose (or axes) replaced in place, and
// the components the target has that the aggregate leaves out (a partial aggregate the
// correction completed: Job::setPose) added in the canonical order, each before the first
// written component that follows it there, else after the last one.
std::string rewriteValue(const KrlSource::Value& v, const std::string& text, const Target& t) {
  const bool cart = t.kind == Target::Kind::kCartesian;
  const char* const* names = cart ? kCartNames : kAxisNames;
  std::vector<std::pair<size_t, std::pair<size_t, std::string>>> edits;  // [begin, end) -> text, in order
  for (const auto& c : v.components) {
    // the pose, and S / T when the compensation changed them
    const bool st_changed = cart && ((c.name == "S" && t.status && *t.status != c.value) ||
                                     (c.name == "T" && t.turn && *t.turn != c.value));
    // a component whose value is the same at the precision written keeps its text (X 100.0
    // stays X 100.0, not X 100.0000)
    const int k = indexOf(names, c.name);
    const std::string now = componentText(t, c.name);
    const bool same = k >= 0 && !now.empty() && now == (cart ? (k < 3 ? formatMm(c.value) : formatDeg(c.value)) : formatAxis(c.value));
    if (k >= 0 && !same) edits.push_back({c.begin, {c.end, now}});
    if (st_changed) edits.push_back({c.begin, {c.end, integerLike(text.substr(c.begin, c.end - c.begin), c.name == "S" ? *t.status : *t.turn)}});
  }
  std::vector<std::string> order;  // the canonical order of the components
  for (int k = 0; k < 6; ++k) order.push_back(names[k]);
  if (cart) order.insert(order.end(), {"S", "T"});
  for (int k = 0; k < 6; ++k) order.push_back(kExtNames[k]);
  size_t last_end = v.begin + 1;
  for (const auto& c : v.components) last_end = std::max(last_end, c.end);
  for (size_t i = 0; i < order.size(); ++i) {
    const std::string now = componentText(t, order[i]);
    const auto written = [&](const std::string& n) {
      return std::find_if(v.components.begin(), v.components.end(), [&](const KrlSource::Component& c) { return c.name == n; });
    };
    if (now.empty() || written(order[i]) != v.components.end()) continue;
    size_t at = std::string::npos;
    for (size_t j = i + 1; j < order.size() && at == std::string::npos; ++j)
      if (const auto c = written(order[j]); c != v.components.end()) at = c->name_begin;
    if (at != std::string::npos) edits.push_back({at, {at, order[i] + " " + now + ","}});
    else edits.push_back({last_end, {last_end, "," + order[i] + " " + now}});
  }
  std::stable_sort(edits.begin(), edits.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::string out;
  size_t pos = v.begin;
  for (const auto& [begin, e] : edits) {
    out += text.substr(pos, begin - pos);
    out += e.second;
    pos = e.first;
  }
  out += text.substr(pos, v.end - pos);
  return out;
}

struct Edit {
  int file;
  size_t begin, end;
  std::string text;
  int order;  // stable tie-break
};

std::string applyEdits(const std::string& text, std::vector<Edit> edits, int file) {
  std::vector<Edit> mine;
  for (auto& e : edits)
    if (e.file == file) mine.push_back(e);
  std::stable_sort(mine.begin(), mine.end(), [](const Edit& a, const Edit& b) {
    if (a.begin != b.begin) return a.begin < b.begin;
    return a.order < b.order;
  });
  std::string out;
  size_t pos = 0;
  for (const auto& e : mine) {
    if (e.begin < pos) throw calib::ArgumentError("writeKrl: overlapping edits");
    out += text.substr(pos, e.begin - pos);
    out += e.text;
    pos = e.end;
  }
  out += text.substr(pos);
  return out;
}

std::string dominantEol(const std::string& text) {
  return text.find("\r\n") != std::string::npos ? "\r\n" : "\n";
}

KrlText patchKrl(const Program& p) {
  const KrlSource& s = *p.krl;
  std::vector<Edit> edits;
  std::map<int, std::pair<std::string, std::string>> value_text;  // value id -> (text, who)
  int order = 0;
  auto textOf = [&](int file) -> const std::string& { return file == 0 ? s.src_text : s.dat_text; };
  // the motion's statement with its target (`aux`: the auxiliary point) replaced by `text`
  auto replaceInStatement = [&](const Motion& m, bool aux, const std::string& text) {
    if (m.statement_id < 0 || m.statement_id >= static_cast<int>(s.statements.size()))
      throw calib::ArgumentError("writeKrl: a motion whose target goes into its statement has no statement");
    const KrlSource::Statement& st = s.statements[static_cast<size_t>(m.statement_id)];
    const auto& span = aux ? st.targets.front() : st.targets.back();
    edits.push_back({st.file, span.first, span.second, text, order++});
  };
  auto modify = [&](const Target& t, const Motion& m, bool aux) {
    if (!t.modified) return;
    if (t.value_id < 0) {
      // declared outside the program's files (a $config.dat point, which accura never
      // rewrites): the corrected value goes into this motion as an inline aggregate, as for a
      // split CIRC's auxiliary point declared elsewhere; other users of the point keep its value
      replaceInStatement(m, aux, krlAggregate(t));
      return;
    }
    const KrlSource::Value& v = s.values.at(static_cast<size_t>(t.value_id));
    const std::string text = rewriteValue(v, textOf(v.file), t);
    auto it = value_text.find(t.value_id);
    if (it != value_text.end()) {
      if (it->second.first != text)
        throw calib::ArgumentError(m.where.str() + ": " + (t.name.empty() ? "this target" : t.name) +
                            " needs a different correction here than at " + it->second.second +
                            " (same point, different tool, base or motion): give the motions their own points");
      return;
    }
    value_text[t.value_id] = {text, m.where.str()};
    edits.push_back({v.file, v.begin, v.end, text, order++});
  };
  // a new point (Target::new_declaration: a split CIRC's last auxiliary point, a corrected
  // point the program also reads elsewhere): the statement names it, its DECL (once, for every
  // motion that names it) follows the declaration of the point it replaces in the .dat (which
  // keeps its text); a point declared elsewhere is replaced by an inline aggregate
  std::map<std::string, std::string> declared_new;  // new name -> its value's text
  auto declareNew = [&](const Target& t, const Motion& m, bool aux) {
    const bool in_dat = !t.name.empty() && t.value_id >= 0 && s.values.at(static_cast<size_t>(t.value_id)).file == 1;
    replaceInStatement(m, aux, in_dat ? t.name : krlAggregate(t));
    if (!in_dat) return;
    const KrlSource::Value& v = s.values.at(static_cast<size_t>(t.value_id));
    const std::string& text = textOf(v.file);
    // the aggregate written like the one it replaces (its S, T, E1..E6 texts)
    const std::string agg = rewriteValue(v, text, t);
    if (const auto d = declared_new.find(t.name); d != declared_new.end()) {
      if (d->second != agg) throw calib::ArgumentError(m.where.str() + ": the new point " + t.name + " has two different values");
      return;
    }
    declared_new[t.name] = agg;
    const size_t nl = text.find('\n', v.end);
    const size_t at = nl == std::string::npos ? text.size() : nl + 1;
    const std::string eol = dominantEol(text);
    // indented like the declaration it follows
    const size_t line = text.rfind('\n', v.begin);
    const size_t line_begin = line == std::string::npos ? 0 : line + 1;
    const std::string indent = text.substr(line_begin, text.find_first_not_of(" \t", line_begin) - line_begin);
    std::string decl = indent + "DECL " + (t.type.empty() ? std::string("E6POS") : t.type) + " " + t.name + "=" + agg;
    decl = nl == std::string::npos ? eol + decl : decl + eol;
    edits.push_back({v.file, at, at, decl, order++});
  };
  for (const Motion& m : p.motions) {
    if (m.inserted) {
      if (m.statement_id < 0 || m.statement_id >= static_cast<int>(s.statements.size()))
        throw calib::ArgumentError("writeKrl: an inserted motion has no anchor statement");
      const KrlSource::Statement& st = s.statements[static_cast<size_t>(m.statement_id)];
      const std::string& text = textOf(st.file);
      std::vector<std::string> repl;
      if (m.aux) repl.push_back(krlAggregate(*m.aux));
      repl.push_back(krlAggregate(m.target));
      if (repl.size() != st.targets.size())
        throw calib::ArgumentError("writeKrl: an inserted motion does not match its anchor statement's targets");
      std::string line = text.substr(st.line_begin, st.code_begin - st.line_begin);
      size_t pos = st.code_begin;
      for (size_t k = 0; k < st.targets.size(); ++k) {
        line += text.substr(pos, st.targets[k].first - pos);
        line += repl[k];
        pos = st.targets[k].second;
      }
      line += text.substr(pos, st.code_end - pos);
      line += st.eol.empty() ? dominantEol(text) : st.eol;
      edits.push_back({st.file, st.line_begin, st.line_begin, line, order++});
      continue;
    }
    if (m.aux && m.aux->new_declaration) declareNew(*m.aux, m, true);
    else if (m.aux) modify(*m.aux, m, true);
    if (m.target.new_declaration) declareNew(m.target, m, false);
    else modify(m.target, m, false);
  }
  KrlText out;
  out.src = applyEdits(s.src_text, edits, 0);
  out.dat = s.dat_path.empty() ? "" : applyEdits(s.dat_text, edits, 1);
  return out;
}

// --- a new program (from XML)

std::string frameAggregate(const calib::XyzAbc& v) {
  return "{X " + formatMm(v.x_mm) + ",Y " + formatMm(v.y_mm) + ",Z " + formatMm(v.z_mm) + ",A " + formatDeg(v.a_deg) +
         ",B " + formatDeg(v.b_deg) + ",C " + formatDeg(v.c_deg) + "}";
}

std::string frameStatement(const char* var, const FrameSetting& s, bool is_tool) {
  switch (s.source) {
    case FrameSetting::Source::kUnset: return "";
    case FrameSetting::Source::kNull: return std::string(var) + "=$NULLFRAME";
    case FrameSetting::Source::kData:
      return std::string(var) + "=" + (is_tool ? "TOOL_DATA[" : "BASE_DATA[") + std::to_string(s.index) + "]";
    case FrameSetting::Source::kInline:
      if (s.value) return std::string(var) + "=" + frameAggregate(*s.value);
      return "";
    case FrameSetting::Source::kUnknown: return std::string(var) + "=" + s.text;
  }
  return "";
}

std::string declType(const Target& t) {
  if (!t.type.empty()) return t.type;
  return t.kind == Target::Kind::kAxis ? "E6AXIS" : "E6POS";
}

KrlText generateKrl(const Program& p) {
  checkPassThrough(p, "KRL");
  const std::string name = p.name.empty() ? "program" : p.name;
  std::ostringstream src, dat;
  // the spline block open in the body (Motion::spline_block; -1: SPLs without a number, from
  // an XML written before blocks were numbered, one block with the SPLs and statements between)
  bool in_spline = false;
  int open_block = 0;
  // the body at block `block` (0: outside every block): the open one ended, `block` opened
  auto enterBlock = [&](std::ostream& out, int block, bool ptp) {
    if (in_spline && block == open_block) return;
    if (in_spline) out << "ENDSPLINE\n";
    in_spline = block != 0;
    open_block = block;
    if (in_spline) out << (ptp ? "PTP_SPLINE\n" : "SPLINE\n");
  };
  // whether block number b is a PTP_SPLINE block (from its first segment; gathered once, not per statement)
  std::map<int, bool> ptp_block;
  for (const Motion& m : p.motions) ptp_block.emplace(m.spline_block, m.ptp_spline_block);
  auto ptpBlock = [&](int b) {
    const auto it = ptp_block.find(b);
    return it != ptp_block.end() && it->second;
  };
  // $ORI_TYPE and $CIRC_TYPE as the program written so far leaves them ("": #VAR, #BASE, the
  // values BAS(#INITMOV) gives; a carried statement `$ORI_TYPE = #CONSTANT` sets them too, a
  // carried BAS(#INITMOV, ..) sets them back: BAS.SRC's INITMOV, `$ORI_TYPE=#VAR`,
  // `$CIRC_TYPE=DEF_CIRC_TYP`, #BASE in the $config.dat)
  std::string ori_type, circ_type;
  auto noteCarried = [&](const std::string& text) {
    std::string compact;
    for (char c : text)
      if (c != ' ' && c != '\t') compact += c;
    if (upper(compact).rfind("BAS(#INITMOV", 0) == 0) {
      ori_type.clear();
      circ_type.clear();
      return;
    }
    std::istringstream in(text);
    std::string lhs, eq, value;
    in >> lhs;
    const size_t at = lhs.find('=');
    if (at != std::string::npos) {  // $ORI_TYPE=#CONSTANT
      value = lhs.substr(at + 1);
      lhs = lhs.substr(0, at);
    } else {
      in >> eq;
      if (eq.size() > 1 && eq[0] == '=') value = eq.substr(1);
      else if (eq == "=") in >> value;
    }
    if (value.empty() || value[0] != '#') return;
    const std::string l = upper(lhs);
    if (l == "$ORI_TYPE") ori_type = orientationControlValue(value, false);
    if (l == "$CIRC_TYPE") circ_type = orientationControlValue(value, true);
  };
  // the pass-through statements of a section, in order; for the body those before motion `k`,
  // each in the block it was in (PassThrough::spline_block: TIME_BLOCK inside, $OUT after it)
  size_t next_body = 0;
  auto carry = [&](std::ostream& out, PassThrough::Section section, size_t before) {
    for (const PassThrough& s : p.passthrough)
      if (s.section == section && section != PassThrough::Section::kBody) out << s.text << "\n";
    while (section == PassThrough::Section::kBody && next_body < p.passthrough.size()) {
      const PassThrough& s = p.passthrough[next_body];
      if (s.section == PassThrough::Section::kBody && s.before_motion > before) break;
      if (s.section == PassThrough::Section::kBody) {
        if (!(in_spline && open_block < 0)) enterBlock(out, s.spline_block, ptpBlock(s.spline_block));
        out << s.text << "\n";
        noteCarried(s.text.substr(0, s.text.find(';')));
      }
      ++next_body;
    }
  };
  bool initmov = false;  // the program initialises itself (its own INI fold was carried)
  for (const PassThrough& s : p.passthrough) initmov = initmov || (s.section == PassThrough::Section::kBody && upper(s.text).find("#INITMOV") != std::string::npos);
  src << "&ACCESS RVP\n&REL 1\nDEF " << name << "(" << (p.krl_parameters.empty() ? " " : p.krl_parameters) << ")\n";
  if (!initmov) {
    // a KRL program declares before its first statement: the INI fold after the declarations
    // carried at its top
    auto declaration = [](const std::string& text) {
      std::istringstream in(text);
      std::string word;
      in >> word;
      static const std::set<std::string> kDeclarationWords = {"DECL", "INT", "REAL", "BOOL", "CHAR", "SIGNAL", "STRUC",
                                                              "ENUM", "GLOBAL", "CONST", "EXT", "EXTFCT", "EXTP"};
      return kDeclarationWords.count(upper(word)) > 0 || isPointType(upper(word));
    };
    while (next_body < p.passthrough.size()) {
      const PassThrough& s = p.passthrough[next_body];
      if (s.section == PassThrough::Section::kBody && (s.before_motion > 0 || !declaration(s.text))) break;
      if (s.section == PassThrough::Section::kBody) src << s.text << "\n";
      ++next_body;
    }
    src << ";FOLD INI\n  BAS (#INITMOV,0 )\n;ENDFOLD (INI)\n";
  }
  dat << "&ACCESS RVP\n&REL 1\nDEFDAT " << name << " PUBLIC\n";
  carry(dat, PassThrough::Section::kData, 0);
  std::map<std::string, std::string> declared;  // upper name -> aggregate text
  FrameSetting tool, base;
  std::optional<double> vel_cp, vel_ptp;
  std::map<Approximation, std::optional<double>> apo;
  auto targetText = [&](const Target& t, const Motion& m) -> std::string {
    if (t.name.empty() || (t.external && t.modified)) return krlAggregate(t);
    if (t.external) return t.name;  // the $config.dat's: not declared here, which would hide it
    const std::string up = upper(t.name);
    bool any = false;
    for (const auto& c : t.pose) any = any || c.has_value();
    for (const auto& c : t.axes) any = any || c.has_value();
    if (!any) return t.name;  // no value: declared outside the program (a global point)
    const std::string agg = krlAggregate(t);
    auto it = declared.find(up);
    if (it == declared.end()) {
      declared[up] = agg;
      dat << (t.global ? "DECL GLOBAL " : "DECL ") << declType(t) << " " << t.name << "=" << agg << "\n";
    } else if (it->second != agg) {
      throw calib::ArgumentError(m.where.str() + ": the point " + t.name + " has two different values in this program");
    }
    return t.name;
  };
  for (size_t k = 0; k < p.motions.size(); ++k) {
    const Motion& m = p.motions[k];
    carry(src, PassThrough::Section::kBody, k);
    const int block = m.spline_block > 0 ? m.spline_block : m.spline && m.type == MotionType::kSpl ? -1 : 0;
    // inside the block the motion continues, a path speed is the segment's own (SLIN XP2 WITH
    // $VEL.CP=0.2); other settings are statements, which a SPLINE block may not hold (KSS: a
    // block's segments take the block's $TOOL, $BASE): written before the block, which ends and
    // starts anew where they change
    const bool continues = in_spline && block == open_block;
    std::string with;
    if (continues && m.type != MotionType::kPtp && m.vel_m_s && m.vel_m_s != vel_cp) {
      with = " WITH $VEL.CP=" + calib::formatFixed(*m.vel_m_s, 4);
      vel_cp = m.vel_m_s;
    }
    std::ostringstream settings;
    // the orientation control of a CP motion: a spline motion's own (WITH, which a block's
    // segment needs: a block holds no statements), a LIN's or CIRC's a statement
    if (m.type != MotionType::kPtp) {
      const std::string circ = m.type == MotionType::kCirc ? m.circ_type : circ_type;  // (only circles read it)
      for (const auto& [var, want, now, fallback] : {std::make_tuple("$ORI_TYPE", &m.ori_type, &ori_type, "#VAR"),
                                                     std::make_tuple("$CIRC_TYPE", &circ, &circ_type, "#BASE")}) {
        if (*want == *now) continue;
        const std::string a = std::string(var) + "=" + (want->empty() ? std::string(fallback) : *want);
        if (m.spline) {
          with += (with.empty() ? " WITH " : ", ") + a;
        } else {
          settings << a << "\n";
          *now = *want;
        }
      }
    }
    if (!sameFrame(m.tool, tool)) {
      const std::string s = frameStatement("$TOOL", m.tool, true);
      if (!s.empty()) settings << s << "\n";
      tool = m.tool;
    }
    if (!sameFrame(m.base, base)) {
      const std::string s = frameStatement("$BASE", m.base, false);
      if (!s.empty()) settings << s << "\n";
      base = m.base;
    }
    if (m.type == MotionType::kPtp && m.vel_percent && m.vel_percent != vel_ptp) {
      for (int axis = 1; axis <= 6; ++axis) settings << "$VEL_AXIS[" << axis << "]=" << calib::formatFixed(*m.vel_percent, 4) << "\n";
      vel_ptp = m.vel_percent;
    }
    if (m.type != MotionType::kPtp && m.vel_m_s && m.vel_m_s != vel_cp) {
      settings << "$VEL.CP=" << calib::formatFixed(*m.vel_m_s, 4) << "\n";
      vel_cp = m.vel_m_s;
    }
    if (!m.approximation.empty() && m.approximation_value && apo[m.approximation.front()] != m.approximation_value) {
      const char* var = "CDIS";
      switch (m.approximation.front()) {
        case Approximation::kCPtp: var = "CPTP"; break;
        case Approximation::kCVel: var = "CVEL"; break;
        case Approximation::kCOri: var = "CORI"; break;
        default: break;
      }
      settings << "$APO." << var << "=" << calib::formatFixed(*m.approximation_value, 4) << "\n";
      apo[m.approximation.front()] = m.approximation_value;
    }
    if (!settings.str().empty()) enterBlock(src, 0, false);
    src << settings.str();
    enterBlock(src, block, m.ptp_spline_block);
    std::string line = motionKeyword(m) + " ";
    if (m.aux) line += targetText(*m.aux, m) + ", ";
    line += targetText(m.target, m);
    if (m.circ_angle_deg) line += ", CA " + formatDeg(*m.circ_angle_deg);
    line += with;
    for (Approximation a : m.approximation) line += std::string(" ") + toString(a);
    if (m.relative && m.relative_in_tool) line += " #TOOL";  // after the flags, as KRL writes it
    src << line << "\n";
  }
  carry(src, PassThrough::Section::kBody, p.motions.size());
  enterBlock(src, 0, false);
  src << "END\n";
  carry(src, PassThrough::Section::kTrailer, 0);
  dat << "ENDDAT\n";
  // the line end of the controller's own files: the KSS HMI (Windows) writes .src and .dat with
  // CRLF (a file read from KRL keeps its own: patchKrl)
  auto crlf = [](const std::string& text) {
    std::string out;
    out.reserve(text.size() + text.size() / 16);
    for (size_t i = 0; i < text.size(); ++i) {
      if (text[i] == '\n' && (i == 0 || text[i - 1] != '\r')) out += '\r';
      out += text[i];
    }
    return out;
  };
  return {crlf(src.str()), crlf(dat.str())};
}


}  // namespace

std::string krlAggregate(const Target& t) {
  std::string out = "{";
  auto add = [&](const std::string& name, const std::string& value) {
    if (value.empty()) return;
    if (out.size() > 1) out += ",";
    out += name + " " + value;
  };
  if (t.kind == Target::Kind::kCartesian) {
    for (int k = 0; k < 6; ++k) add(kCartNames[k], componentText(t, kCartNames[k]));
    add("S", componentText(t, "S"));
    add("T", componentText(t, "T"));
  } else {
    for (int k = 0; k < 6; ++k) add(kAxisNames[k], componentText(t, kAxisNames[k]));
  }
  for (int k = 0; k < 6; ++k) add(kExtNames[k], componentText(t, kExtNames[k]));
  return out + "}";
}

KrlText writeKrl(const Program& program) {
  if (program.krl) return patchKrl(program);
  return generateKrl(program);
}

}  // namespace accura::postproc
