// XML programs (see xml_program.h, postproc/schema/accura-program.xsd).
#include "accura/postproc/xml_program.h"

#include <tinyxml2.h>
#include "accura/calib/text.h"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <sstream>
#include <tuple>

#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "accura/calib/xml_text.h"
#include "excerpt.h"

namespace accura::postproc {
namespace {

using tinyxml2::XMLElement;

const char* const kPoseAttrs[] = {"x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"};
const char* const kAxisAttrs[] = {"a1", "a2", "a3", "a4", "a5", "a6"};
const char* const kExtAttrs[] = {"e1", "e2", "e3", "e4", "e5", "e6"};
const char* const kMotionElements[] = {"ptp", "lin", "circ", "sptp", "slin", "scirc", "spl"};

std::set<std::string> passThroughAttrs() { return {"language", "section", "encoding", "role", "line", "eol", "spline_block"}; }

std::set<std::string> targetAttrs(bool cartesian) {
  std::set<std::string> s = {"name", "type", "global", "external"};
  for (const char* a : cartesian ? kPoseAttrs : kAxisAttrs) s.insert(a);
  for (const char* a : kExtAttrs) s.insert(a);
  if (cartesian) {
    s.insert("s");
    s.insert("t");
    s.insert("abb_conf");
  }
  return s;
}

std::set<std::string> frameAttrs() {
  std::set<std::string> s = {"source", "index", "text"};
  for (const char* a : kPoseAttrs) s.insert(a);
  return s;
}

std::set<std::string> motionAttrs() {
  return {"vel_percent", "vel_m_s", "approx", "approx_value", "ca_deg", "relative", "relative_frame", "external_tcp", "conf_monitored", "source_line",
          "start_unknown", "spline_block", "spline_block_type", "time_s", "ori_type", "circ_type"};
}

class Reader {
 public:
  Reader(std::string file, const calib::XmlPositions& pos) : file_(std::move(file)), pos_(pos) {}

  /// Where the element is: its '<' (xml_text.h).
  SourceLocation loc(const XMLElement* e) const {
    SourceLocation s;
    s.file = file_;
    std::tie(s.line, s.column) = pos_.element(e);
    return s;
  }

  [[noreturn]] void fail(const XMLElement* e, const std::string& msg) const {
    const SourceLocation s = loc(e);
    throw calib::InputError(s.file, s.line, s.column, msg);
  }

  /// A point's name: an identifier every controller language can declare (a letter, '_' or '$',
  /// then letters, digits, '_' or '$'; at most 64 characters). Anything else would be copied into
  /// a program as text: a newline in a name becomes a statement of its own.
  std::string pointName(const XMLElement* e, const std::string& name) const {
    if (!isDeclarableName(name))
      fail(e, "<" + std::string(e->Name()) + "> attribute 'name': expected a point name (a letter, '_' or '$', then "
              "letters, digits, '_' or '$'; at most 64 characters), found '" + calib::printableBytes(name) + "'");
    return name;
  }

  void checkAttributes(const XMLElement* e, const std::set<std::string>& allowed) const {
    for (const tinyxml2::XMLAttribute* a = e->FirstAttribute(); a; a = a->Next()) {
      if (!allowed.count(a->Name())) {
        std::string list;
        for (const auto& s : allowed) list += (list.empty() ? "" : ", ") + s;
        fail(e, "<" + std::string(e->Name()) + ">: unknown attribute '" + a->Name() + "' (expected one of: " + list + ")");
      }
    }
  }

  std::optional<std::string> text(const XMLElement* e, const char* name) const {
    const char* v = e->Attribute(name);
    if (!v) return std::nullopt;
    return std::string(v);
  }

  /// A free-text attribute (a program's or robot's name, a frame's text): UTF-8 without control
  /// characters, which the writer gives back as it was read (an XML reader turns a CR into a LF).
  std::string plain(const XMLElement* e, const char* name, const std::string& v) const {
    if (!calib::isPlainText(v))
      fail(e, "<" + std::string(e->Name()) + "> attribute '" + name + "': expected UTF-8 text without control characters, found '" +
                  calib::printableBytes(v) + "'");
    return v;
  }

  std::optional<double> number(const XMLElement* e, const char* name) const {
    const auto s = text(e, name);
    if (!s) return std::nullopt;
    char* end = nullptr;
    const double v = std::strtod(s->c_str(), &end);
    if (s->empty() || end == s->c_str() || *end != '\0' || !std::isfinite(v))
      fail(e, "<" + std::string(e->Name()) + "> attribute '" + name + "': expected a finite number, found '" + *s + "'");
    return v;
  }

  std::optional<int> integer(const XMLElement* e, const char* name) const {
    const auto v = number(e, name);
    if (!v) return std::nullopt;
    if (*v != std::floor(*v) || *v < 0 || *v > 1e6)
      fail(e, "<" + std::string(e->Name()) + "> attribute '" + name + "': expected a non-negative integer, found '" + *text(e, name) + "'");
    return static_cast<int>(*v);
  }

  bool flag(const XMLElement* e, const char* name) const {
    const auto s = text(e, name);
    if (!s) return false;
    if (*s == "true") return true;
    if (*s == "false") return false;
    fail(e, "<" + std::string(e->Name()) + "> attribute '" + name + "': expected 'true' or 'false', found '" + *s + "'");
  }

  const std::string& file() const { return file_; }

 private:
  std::string file_;
  const calib::XmlPositions& pos_;
};

bool hasAnyValue(const XMLElement* e) {
  for (const tinyxml2::XMLAttribute* a = e->FirstAttribute(); a; a = a->Next()) {
    const std::string n = a->Name();
    if (n != "name" && n != "type") return true;
  }
  return false;
}

// <pose>, <aux> (Cartesian) or <axes>
Target readTarget(const Reader& R, const XMLElement* e, bool cartesian) {
  R.checkAttributes(e, targetAttrs(cartesian));
  Target t;
  t.kind = cartesian ? Target::Kind::kCartesian : Target::Kind::kAxis;
  t.where = R.loc(e);
  if (const auto n = R.text(e, "name")) t.name = R.pointName(e, *n);
  if (const auto ty = R.text(e, "type")) {
    std::string u;
    for (char c : *ty) u += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    const bool ok = cartesian ? (u == "E6POS" || u == "POS" || u == "FRAME") : (u == "E6AXIS" || u == "AXIS");
    if (!ok)
      R.fail(e, "<" + std::string(e->Name()) + "> attribute 'type': expected " +
                    (cartesian ? "E6POS, POS or FRAME" : "E6AXIS or AXIS") + ", found '" + *ty + "'");
    t.type = u;
  }
  if (const auto g = R.text(e, "global")) {
    if (*g != "true" && *g != "false")
      R.fail(e, "<" + std::string(e->Name()) + "> attribute 'global': expected true or false, found '" + *g + "'");
    if (*g == "true" && t.name.empty())
      R.fail(e, "<" + std::string(e->Name()) + "> attribute 'global': expected a 'name' with it (a global point is a declared one), found none");
    t.global = *g == "true";
  }
  if (e->Attribute("external")) {
    t.external = R.flag(e, "external");
    if (t.external && t.name.empty())
      R.fail(e, "<" + std::string(e->Name()) + "> attribute 'external': expected a 'name' with it (the point it refers to), found none");
  }
  for (int k = 0; k < 6; ++k) {
    if (cartesian) t.pose[k] = R.number(e, kPoseAttrs[k]);
    else t.axes[k] = R.number(e, kAxisAttrs[k]);
    t.ext[k] = R.number(e, kExtAttrs[k]);
  }
  if (cartesian) {
    t.status = R.integer(e, "s");
    t.turn = R.integer(e, "t");
    if (const auto c = R.text(e, "abb_conf")) {
      // cf1,cf4,cf6,cfx: four integers
      std::array<int, 4> v{};
      std::istringstream in(*c);
      bool ok = true;
      for (int k = 0; k < 4 && ok; ++k) {
        long x = 0;
        ok = static_cast<bool>(in >> x) && x >= -1000 && x <= 1000;
        v[static_cast<size_t>(k)] = static_cast<int>(x);
        if (ok && k < 3) ok = in.get() == ',';
      }
      if (!ok || in.peek() != std::char_traits<char>::eof())
        R.fail(e, "<" + std::string(e->Name()) + "> attribute 'abb_conf': expected four integers cf1,cf4,cf6,cfx, found '" + *c + "'");
      t.abb_conf = v;
    }
  }
  return t;
}

FrameSetting readFrame(const Reader& R, const XMLElement* e, bool is_tool, const FrameTables* tables) {
  R.checkAttributes(e, frameAttrs());
  FrameSetting s;
  s.where = R.loc(e);
  const auto source = R.text(e, "source");
  if (!source) R.fail(e, "<" + std::string(e->Name()) + ">: expected an attribute 'source' (inline, data, null or unknown), found none");
  std::array<std::optional<double>, 6> v;
  int given = 0;
  for (int k = 0; k < 6; ++k) {
    v[k] = R.number(e, kPoseAttrs[k]);
    if (v[k]) ++given;
  }
  if (given != 0 && given != 6)
    R.fail(e, "<" + std::string(e->Name()) + ">: expected all of x_mm, y_mm, z_mm, a_deg, b_deg, c_deg or none, found " +
                  std::to_string(given) + " of them");
  const std::string table = is_tool ? "TOOL_DATA" : "BASE_DATA";
  if (*source == "inline") {
    if (given != 6) R.fail(e, "<" + std::string(e->Name()) + " source=\"inline\">: expected x_mm, y_mm, z_mm, a_deg, b_deg, c_deg");
    s.source = FrameSetting::Source::kInline;
  } else if (*source == "data") {
    const auto idx = R.integer(e, "index");
    if (!idx || *idx < 1) R.fail(e, "<" + std::string(e->Name()) + " source=\"data\">: expected attribute 'index' >= 1");
    s.source = FrameSetting::Source::kData;
    s.index = *idx;
    s.text = table + "[" + std::to_string(*idx) + "]";
    if (given == 0 && tables) {
      const auto& tab = is_tool ? tables->tool : tables->base;
      if (*idx < static_cast<int>(tab.size()) && tab[static_cast<size_t>(*idx)]) s.value = tab[static_cast<size_t>(*idx)];
    }
  } else if (*source == "null") {
    if (given) R.fail(e, "<" + std::string(e->Name()) + " source=\"null\">: expected no pose attributes");
    s.source = FrameSetting::Source::kNull;
    s.value = calib::XyzAbc{};
    s.text = "$NULLFRAME";
  } else if (*source == "unknown") {
    const auto t = R.text(e, "text");
    if (!t) R.fail(e, "<" + std::string(e->Name()) + " source=\"unknown\">: expected an attribute 'text', found none");
    s.source = FrameSetting::Source::kUnknown;
    s.text = R.plain(e, "text", *t);
  } else {
    R.fail(e, "<" + std::string(e->Name()) + "> attribute 'source': expected inline, data, null or unknown, found '" + *source + "'");
  }
  if (s.source != FrameSetting::Source::kData && e->Attribute("index"))
    R.fail(e, "<" + std::string(e->Name()) + ">: expected the attribute 'index' only with source=\"data\", found it with source=\"" + *source + "\"");
  if (s.source != FrameSetting::Source::kUnknown && e->Attribute("text"))
    R.fail(e, "<" + std::string(e->Name()) + ">: expected the attribute 'text' only with source=\"unknown\", found it with source=\"" + *source + "\"");
  if (given == 6) s.value = calib::XyzAbc{*v[0], *v[1], *v[2], *v[3], *v[4], *v[5]};
  if (s.source == FrameSetting::Source::kInline) s.text = "inline frame";
  return s;
}

const char* sectionName(PassThrough::Section s) {
  switch (s) {
    case PassThrough::Section::kBody: return "body";
    case PassThrough::Section::kTrailer: return "trailer";
    case PassThrough::Section::kData: return "data";
  }
  return "body";
}

void writePassThrough(std::ostream& out, const PassThrough& s) {
  if (isXmlComment(s)) {  // an XML comment of the program, as it was (read from XML, its text holds no "--")
    std::string text = s.text;
    for (size_t at = text.find("--"); at != std::string::npos; at = text.find("--", at)) text.insert(at + 1, " ");
    if (!text.empty() && text.back() == '-') text += ' ';
    out << "    <!--" << text << "-->\n";
    return;
  }
  out << "    <passthrough language=\"" << calib::xmlEscape(s.language) << "\"";
  if (s.section != PassThrough::Section::kBody) out << " section=\"" << sectionName(s.section) << "\"";
  if (!s.role.empty()) out << " role=\"" << calib::xmlEscape(s.role) << "\"";
  if (s.spline_block > 0) out << " spline_block=\"" << s.spline_block << "\"";
  if (s.line > 0) {
    out << " line=\"" << s.line << "\"";
    if (s.eol != "\n") out << " eol=\"" << (s.eol == "\r\n" ? "crlf" : "none") << "\"";
  }
  // a line of blanks only is hex too: an XML reader drops whitespace-only text
  // pass-through text: as XML text when it is UTF-8 without control characters, else its bytes
  // in hexadecimal (encoding="hex": a KRL comment in Windows-1252 round-trips byte for byte)
  if (calib::isPlainText(s.text) && (s.text.empty() || s.text.find_first_not_of(" \t") != std::string::npos)) {
    out << ">" << calib::xmlEscape(s.text) << "</passthrough>\n";
    return;
  }
  static const char* const hex = "0123456789abcdef";
  out << " encoding=\"hex\">";
  for (char c : s.text) out << hex[(static_cast<unsigned char>(c) >> 4) & 0xF] << hex[static_cast<unsigned char>(c) & 0xF];
  out << "</passthrough>\n";
}

PassThrough readPassThrough(const Reader& R, const XMLElement* e, size_t before_motion) {
  R.checkAttributes(e, passThroughAttrs());
  PassThrough p;
  p.where = R.loc(e);
  p.before_motion = before_motion;
  const auto language = R.text(e, "language");
  if (!language || language->empty()) R.fail(e, "<passthrough>: expected attribute 'language' (KRL, ...)");
  p.language = R.plain(e, "language", *language);
  if (p.language == "XML")  // the program's own comments are <!-- -->, not pass-through statements
    R.fail(e, "<passthrough> attribute 'language': expected the language of a robot program (KRL, RAPID, URScript), found 'XML' "
              "(write a comment of the XML program as <!-- ... -->)");
  const std::string section = R.text(e, "section").value_or("body");
  if (section == "body") p.section = PassThrough::Section::kBody;
  else if (section == "trailer") p.section = PassThrough::Section::kTrailer;
  else if (section == "data") p.section = PassThrough::Section::kData;
  else R.fail(e, "<passthrough> attribute 'section': expected body, trailer or data, found '" + section + "'");
  if (e->FirstChildElement()) R.fail(e->FirstChildElement(), "<passthrough>: expected text only, found an element");
  const std::string text = e->GetText() ? e->GetText() : "";
  const std::string encoding = R.text(e, "encoding").value_or("text");
  if (encoding == "text") {
    p.text = text;
  } else if (encoding == "hex") {
    auto nibble = [&](char c) -> int {
      if (c >= '0' && c <= '9') return c - '0';
      if (c >= 'a' && c <= 'f') return c - 'a' + 10;
      if (c >= 'A' && c <= 'F') return c - 'A' + 10;
      R.fail(e, std::string("<passthrough encoding=\"hex\">: expected hexadecimal digits, found '") + c + "'");
    };
    if (text.size() % 2) R.fail(e, "<passthrough encoding=\"hex\">: expected an even number of hexadecimal digits, found " + std::to_string(text.size()));
    for (size_t i = 0; i < text.size(); i += 2) p.text += static_cast<char>(nibble(text[i]) * 16 + nibble(text[i + 1]));
  } else {
    R.fail(e, "<passthrough> attribute 'encoding': expected text or hex, found '" + encoding + "'");
  }
  if (p.text.find('\n') != std::string::npos) R.fail(e, "<passthrough>: expected one line, found a line break");
  p.role = R.text(e, "role").value_or("");
  if (!p.role.empty() && p.role != "motion" && p.role != "model" && p.role != "comment")
    R.fail(e, "<passthrough> attribute 'role': expected motion, model or comment, found '" + p.role + "'");
  if (const auto l = R.integer(e, "line")) {
    if (*l < 1) R.fail(e, "<passthrough> attribute 'line': expected a line number >= 1, found '" + std::to_string(*l) + "'");
    p.line = *l;
  }
  const std::string eol = R.text(e, "eol").value_or("lf");
  if (eol == "lf") p.eol = "\n";
  else if (eol == "crlf") p.eol = "\r\n";
  else if (eol == "none") p.eol = "";
  else R.fail(e, "<passthrough> attribute 'eol': expected lf, crlf or none, found '" + eol + "'");
  if ((e->Attribute("role") || e->Attribute("eol")) && p.line == 0)
    R.fail(e, "<passthrough>: expected the attribute 'line' with 'role' or 'eol' (a line carried with its place), found none");
  if (const auto b = R.integer(e, "spline_block")) {
    if (*b < 1) R.fail(e, "<passthrough> attribute 'spline_block': expected a positive block number, found '" + std::to_string(*b) + "'");
    p.spline_block = *b;
  }
  return p;
}

std::string describe(const XMLElement* e) { return e ? "<" + std::string(e->Name()) + ">" : "nothing"; }

// An XML comment of the program as a pass-through line before motion `before_motion`.
PassThrough xmlComment(const tinyxml2::XMLComment* c, const std::string& file, size_t before_motion) {
  PassThrough p;
  p.language = "XML";
  p.role = "comment";
  p.text = c->Value() ? c->Value() : "";
  p.before_motion = before_motion;
  p.where = {file, c->GetLineNum(), 0};
  return p;
}

Motion readMotion(const Reader& R, const XMLElement* e) {
  R.checkAttributes(e, motionAttrs());
  const std::string n = e->Name();
  Motion m;
  m.where = R.loc(e);
  m.spline = n == "sptp" || n == "slin" || n == "scirc" || n == "spl";
  if (n == "ptp" || n == "sptp") m.type = MotionType::kPtp;
  else if (n == "lin" || n == "slin") m.type = MotionType::kLin;
  else if (n == "circ" || n == "scirc") m.type = MotionType::kCirc;
  else m.type = MotionType::kSpl;
  m.statement = "<" + n + ">";
  m.vel_percent = R.number(e, "vel_percent");
  m.vel_m_s = R.number(e, "vel_m_s");
  if (const auto a = R.text(e, "approx")) {
    std::istringstream in(*a);
    std::string w;
    while (in >> w) {
      Approximation x;
      if (!parseApproximation(w, &x))
        R.fail(e, "<" + n + "> attribute 'approx': expected C_PTP, C_DIS, C_VEL, C_ORI or C_SPL, found '" + w + "'");
      m.approximation.push_back(x);
    }
  }
  m.approximation_value = R.number(e, "approx_value");
  if (m.approximation_value && m.approximation.empty())
    R.fail(e, "<" + n + ">: expected the attribute 'approx' with 'approx_value', found none");
  m.circ_angle_deg = R.number(e, "ca_deg");
  if (m.circ_angle_deg && m.type != MotionType::kCirc) R.fail(e, "<" + n + ">: attribute 'ca_deg' is only for circ and scirc");
  m.relative = R.flag(e, "relative");
  if (const auto f = R.text(e, "relative_frame")) {
    if (!m.relative || (*f != "base" && *f != "tool"))
      R.fail(e, "<" + n + "> attribute 'relative_frame': expected 'base' or 'tool' on a motion with relative=\"true\", found '" + *f +
                    "'" + (m.relative ? "" : " on a motion that is not relative"));
    m.relative_in_tool = *f == "tool";
  }
  m.external_tcp = R.flag(e, "external_tcp");
  if (e->Attribute("conf_monitored")) m.conf_monitored = R.flag(e, "conf_monitored");
  if (const auto l = R.integer(e, "source_line")) m.source_line = *l;
  if (e->Attribute("start_unknown")) m.start_unknown = R.flag(e, "start_unknown");
  m.duration_s = R.number(e, "time_s");
  if (m.duration_s && !(*m.duration_s > 0 && *m.duration_s <= 1e6))
    R.fail(e, "<" + n + "> attribute 'time_s': expected the move's time in (0, 1e6] s, found " + calib::formatFixed(*m.duration_s, 4));
  if (m.type == MotionType::kSpl && m.relative) R.fail(e, "<spl>: attribute 'relative' is not allowed");
  // KUKA $ORI_TYPE / $CIRC_TYPE of a CP motion (program.h; absent: #VAR / #BASE)
  if (const auto o = R.text(e, "ori_type")) {
    if (m.type == MotionType::kPtp || o->empty()) R.fail(e, "<" + n + "> attribute 'ori_type': expected it on a CP motion, not empty, found '" + *o + "' on " + n);
    // (KRL's names: any case; an enumeration value upper case as the KRL reader gives it)
    m.ori_type = orientationControlValue(*o, false);
  }
  if (const auto c = R.text(e, "circ_type")) {
    if (m.type != MotionType::kCirc || c->empty()) R.fail(e, "<" + n + "> attribute 'circ_type': expected it on circ or scirc, not empty, found '" + *c + "' on " + n);
    m.circ_type = orientationControlValue(*c, true);
  }
  if (const auto b = R.integer(e, "spline_block")) {
    if (!m.spline || *b < 1)
      R.fail(e, "<" + n + "> attribute 'spline_block': expected a positive block number on sptp, slin, scirc or spl, found '" +
                    *R.text(e, "spline_block") + "' on " + n);
    m.spline_block = *b;
  }
  if (const auto k = R.text(e, "spline_block_type")) {
    if (m.spline_block == 0 || (*k != "SPLINE" && *k != "PTP_SPLINE"))
      R.fail(e, "<" + n + "> attribute 'spline_block_type': expected SPLINE or PTP_SPLINE with 'spline_block', found '" + *k + "'" +
                    (m.spline_block == 0 ? " without 'spline_block'" : ""));
    m.ptp_spline_block = *k == "PTP_SPLINE";
  }

  const XMLElement* c = e->FirstChildElement();
  if (m.type == MotionType::kCirc) {
    if (!c || std::string(c->Name()) != "aux")
      R.fail(c ? c : e, "<" + n + ">: expected an <aux> (auxiliary point) first, found " + describe(c));
    if (hasAnyValue(c)) {
      m.aux = readTarget(R, c, true);
    } else {
      R.checkAttributes(c, {"name"});
      if (!c->Attribute("name")) R.fail(c, "<aux>: expected a name or the pose attributes");
      Target t;
      t.name = R.pointName(c, c->Attribute("name"));
      t.where = R.loc(c);
      m.aux = t;
      m.target_problem = t.name + " is declared outside the program";
    }
    c = c->NextSiblingElement();
  }
  if (!c) R.fail(e, "<" + n + ">: expected a target (<pose>, <axes> or <ref>), found nothing");
  const std::string cn = c->Name();
  if ((cn == "pose" || cn == "axes") && !hasAnyValue(c))
    R.fail(c, "<" + cn + ">: expected the target's values (a target declared elsewhere is a <ref name=\"..\"/>)");
  if (cn == "pose") {
    m.target = readTarget(R, c, true);
  } else if (cn == "axes") {
    m.target = readTarget(R, c, false);
  } else if (cn == "ref") {
    R.checkAttributes(c, {"name"});
    const auto name = R.text(c, "name");
    if (!name || name->empty()) R.fail(c, "<ref>: expected attribute 'name'");
    m.target.name = R.pointName(c, *name);
    m.target.where = R.loc(c);
    if (m.target_problem.empty()) m.target_problem = *name + " is declared outside the program";
  } else {
    R.fail(c, "<" + n + ">: expected a target (<pose>, <axes> or <ref>), found <" + cn + ">");
  }
  if (c->NextSiblingElement()) R.fail(c->NextSiblingElement(), "<" + n + ">: expected one target, found another element " + describe(c->NextSiblingElement()));
  if (m.relative && m.target_problem.empty()) m.target_problem = "a relative motion";
  if (m.type != MotionType::kPtp && cn == "axes")
    R.fail(c, "<" + n + ">: expected a Cartesian target (<pose>), found <axes>");
  return m;
}

void writeFrame(std::ostream& out, const char* tag, const FrameSetting& s) {
  out << "    <" << tag << " source=\"";
  switch (s.source) {
    case FrameSetting::Source::kInline: out << "inline\""; break;
    case FrameSetting::Source::kData: out << "data\" index=\"" << s.index << "\""; break;
    case FrameSetting::Source::kNull: out << "null\""; break;
    case FrameSetting::Source::kUnknown: out << "unknown\" text=\"" << calib::xmlEscape(s.text) << "\""; break;
    case FrameSetting::Source::kUnset: return;
  }
  if (s.value && s.source != FrameSetting::Source::kNull) {
    const calib::XyzAbc& v = *s.value;
    out << " x_mm=\"" << formatMm(v.x_mm) << "\" y_mm=\"" << formatMm(v.y_mm) << "\" z_mm=\"" << formatMm(v.z_mm)
        << "\" a_deg=\"" << formatDeg(v.a_deg) << "\" b_deg=\"" << formatDeg(v.b_deg) << "\" c_deg=\"" << formatDeg(v.c_deg) << "\"";
  }
  out << "/>\n";
}

void writeTarget(std::ostream& out, const char* tag, const Target& t) {
  out << "      <" << tag;
  // a name the format cannot hold (a KRL array's element, XPA[1]) is left out with its type:
  // the target travels as an inline value (which KRL writes back untyped); so is a corrected
  // point declared outside the program (its declaration there keeps the other value)
  const bool inline_external = t.external && t.modified;
  const bool named = isDeclarableName(t.name) && !inline_external;
  if (named) out << " name=\"" << calib::xmlEscape(t.name) << "\"";
  if (!t.type.empty() && (named || t.name.empty() || inline_external)) out << " type=\"" << t.type << "\"";
  if (named && t.global) out << " global=\"true\"";
  if (named && t.external) out << " external=\"true\"";
  if (t.kind == Target::Kind::kCartesian) {
    for (int k = 0; k < 6; ++k)
      if (t.pose[k]) out << " " << kPoseAttrs[k] << "=\"" << (k < 3 ? formatMm(*t.pose[k]) : formatDeg(*t.pose[k])) << "\"";
    if (t.status) out << " s=\"" << *t.status << "\"";
    if (t.turn) out << " t=\"" << *t.turn << "\"";
    if (t.abb_conf)
      out << " abb_conf=\"" << (*t.abb_conf)[0] << "," << (*t.abb_conf)[1] << "," << (*t.abb_conf)[2] << "," << (*t.abb_conf)[3] << "\"";
  } else {
    for (int k = 0; k < 6; ++k)
      if (t.axes[k]) out << " " << kAxisAttrs[k] << "=\"" << calib::formatFixed(*t.axes[k], 4) << "\"";
  }
  for (int k = 0; k < 6; ++k)
    if (t.ext[k]) out << " " << kExtAttrs[k] << "=\"" << calib::formatFixed(*t.ext[k], 4) << "\"";
  out << "/>\n";
}

bool hasValues(const Target& t) {
  for (int k = 0; k < 6; ++k)
    if (t.pose[k] || t.axes[k]) return true;
  return false;
}

}  // namespace

const std::map<std::string, std::set<std::string>>& xmlProgramVocabulary() {
  static const std::map<std::string, std::set<std::string>> v = [] {
    std::map<std::string, std::set<std::string>> m;
    m["program"] = {"name", "version", "krl_parameters"};
    m["robot"] = {"name"};
    m["motions"] = {};
    m["tool"] = frameAttrs();
    m["base"] = frameAttrs();
    for (const char* n : kMotionElements) m[n] = motionAttrs();
    m["pose"] = targetAttrs(true);
    m["aux"] = targetAttrs(true);
    m["axes"] = targetAttrs(false);
    m["ref"] = {"name"};
    m["passthrough"] = passThroughAttrs();
    return m;
  }();
  return v;
}

Program parseXmlProgram(const std::string& text, const std::string& file, const FrameTables* tables) {
  tinyxml2::XMLDocument doc;
  calib::parseXml(doc, text, file, "an XML program with root element <program>");
  const calib::XmlPositions positions(text, doc);
  const Reader R(file, positions);
  const XMLElement* root = doc.RootElement();
  if (!root || std::string(root->Name()) != "program")
    R.fail(root, "expected root element <program>, found " + describe(root));
  R.checkAttributes(root, {"name", "version", "krl_parameters"});
  const auto version = R.text(root, "version");
  if (!version) R.fail(root, "<program>: expected an attribute 'version' (1), found none");
  if (*version != "1") R.fail(root, "<program> attribute 'version': expected 1, found '" + *version + "'");
  Program p;
  p.source_file = file;
  if (const auto n = R.text(root, "name")) p.name = R.plain(root, "name", *n);
  if (const auto n = R.text(root, "krl_parameters")) p.krl_parameters = R.plain(root, "krl_parameters", *n);
  const XMLElement* motions = nullptr;
  for (const XMLElement* c = root->FirstChildElement(); c; c = c->NextSiblingElement()) {
    const std::string n = c->Name();
    if (n == "robot") {
      R.checkAttributes(c, {"name"});
      if (!c->Attribute("name")) R.fail(c, "<robot>: expected an attribute 'name', found none");
      if (!p.robot.empty()) R.fail(c, "<program>: expected one <robot> element, found a second one");
      p.robot = R.plain(c, "name", c->Attribute("name"));
    } else if (n == "motions") {
      if (motions) R.fail(c, "<program>: expected one <motions> element, found a second one");
      R.checkAttributes(c, {});
      motions = c;
    } else {
      R.fail(c, "unknown element <" + n + "> in <program> (expected robot, motions)");
    }
  }
  if (!motions) R.fail(root, "<program>: expected a <motions> element, found none");
  // comments outside <motions> (before the root, in <program> before or after <motions>): kept
  // at the start or the end of the motions, where the writer puts them back
  std::vector<PassThrough> leading, trailing;
  bool after = false;
  for (const tinyxml2::XMLNode* n = doc.FirstChild(); n; n = n->NextSibling()) {
    if (n == root) {
      for (const tinyxml2::XMLNode* c = root->FirstChild(); c; c = c->NextSibling()) {
        if (c == motions) after = true;
        if (const tinyxml2::XMLComment* cm = c->ToComment()) (after ? trailing : leading).push_back(xmlComment(cm, file, 0));
      }
      after = true;
    } else if (const tinyxml2::XMLComment* cm = n->ToComment()) {
      (after ? trailing : leading).push_back(xmlComment(cm, file, 0));
    }
  }
  p.passthrough = leading;
  FrameSetting tool, base;
  int triggers = 0;
  for (const tinyxml2::XMLNode* node = motions->FirstChild(); node; node = node->NextSibling()) {
    if (const tinyxml2::XMLComment* cm = node->ToComment()) {
      p.passthrough.push_back(xmlComment(cm, file, p.motions.size()));
      continue;
    }
    const XMLElement* c = node->ToElement();
    if (!c) continue;
    const std::string n = c->Name();
    if (n == "tool") {
      tool = readFrame(R, c, true, tables);
    } else if (n == "base") {
      base = readFrame(R, c, false, tables);
    } else if (n == "passthrough") {
      p.passthrough.push_back(readPassThrough(R, c, p.motions.size()));
      // a KRL TRIGGER binds to the next motion (as the KRL reader counts it)
      const std::string& t = p.passthrough.back().text;
      const size_t b = t.find_first_not_of(" \t");
      std::string word = b == std::string::npos ? "" : t.substr(b, 8);
      for (char& ch : word) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
      if (p.passthrough.back().language == "KRL" && p.passthrough.back().section == PassThrough::Section::kBody &&
          (word == "TRIGGER" || word == "TRIGGER " || word == "TRIGGER\t"))
        ++triggers;
    } else {
      bool motion = false;
      for (const char* k : kMotionElements) motion = motion || n == k;
      if (!motion) R.fail(c, "unknown element <" + n + "> in <motions> (expected tool, base, ptp, lin, circ, sptp, slin, scirc, spl, passthrough)");
      // comments inside the motion's element: kept just before the motion
      for (const tinyxml2::XMLNode* inner = c->FirstChild(); inner; inner = inner->NextSibling())
        if (const tinyxml2::XMLComment* cm = inner->ToComment()) p.passthrough.push_back(xmlComment(cm, file, p.motions.size()));
      Motion m = readMotion(R, c);
      m.tool = tool;
      m.base = base;
      m.trigger_count = triggers;
      triggers = 0;
      p.motions.push_back(std::move(m));
    }
  }
  for (PassThrough& t : trailing) {
    t.before_motion = p.motions.size();
    p.passthrough.push_back(std::move(t));
  }
  auto source = std::make_shared<XmlSource>();
  source->text = text;
  source->motions = p.motions.size();
  p.xml = source;
  return p;
}

Program readXmlProgram(const std::string& path, const FrameTables* tables) {
  // a named pipe is refused before it is opened (opening it waits for a writer), as the KRL,
  // URScript and RAPID readers refuse it
  if (const std::string problem = calib::notAFileProblem(path); !problem.empty())
    throw calib::InputError(path, 0, 0, "cannot read the XML program: " + problem);
  std::ifstream f(path, std::ios::binary);
  if (!f) throw calib::InputError(path, 0, 0, "cannot read the XML program");
  const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  return parseXmlProgram(text, path, tables);
}

std::string writeXmlProgram(const Program& p) {
  // read from XML and unchanged (nothing corrected, nothing inserted): the bytes as read
  if (p.xml && p.motions.size() == p.xml->motions && !programChanged(p)) return p.xml->text;
  checkPassThrough(p, "");
  std::ostringstream out;
  out << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  out << "<program";
  if (!p.name.empty()) out << " name=\"" << calib::xmlEscape(p.name) << "\"";
  if (!p.krl_parameters.empty()) out << " krl_parameters=\"" << calib::xmlEscape(p.krl_parameters) << "\"";
  out << " version=\"1\">\n";
  if (!p.robot.empty()) out << "  <robot name=\"" << calib::xmlEscape(p.robot) << "\"/>\n";
  out << "  <motions>\n";
  FrameSetting tool, base;
  size_t next = 0;  // the next pass-through statement
  auto carry = [&](bool body, size_t before) {
    if (!body) {  // after the last motion: the rest of the body, then the other sections
      for (; next < p.passthrough.size(); ++next)
        if (p.passthrough[next].section == PassThrough::Section::kBody) writePassThrough(out, p.passthrough[next]);
      for (const PassThrough& s : p.passthrough)
        if (s.section != PassThrough::Section::kBody) writePassThrough(out, s);
      return;
    }
    for (; next < p.passthrough.size(); ++next) {
      const PassThrough& s = p.passthrough[next];
      if (s.section != PassThrough::Section::kBody) continue;
      if (s.before_motion > before) break;
      writePassThrough(out, s);
    }
  };
  for (size_t k = 0; k < p.motions.size(); ++k) {
    const Motion& m = p.motions[k];
    carry(true, k);
    if (m.tool.source != FrameSetting::Source::kUnset && !sameFrame(m.tool, tool)) writeFrame(out, "tool", m.tool);
    tool = m.tool;
    if (m.base.source != FrameSetting::Source::kUnset && !sameFrame(m.base, base)) writeFrame(out, "base", m.base);
    base = m.base;
    std::string tag;
    switch (m.type) {
      case MotionType::kPtp: tag = "ptp"; break;
      case MotionType::kLin: tag = "lin"; break;
      case MotionType::kCirc: tag = "circ"; break;
      case MotionType::kSpl: tag = "spl"; break;
    }
    if (m.spline && m.type != MotionType::kSpl) tag = "s" + tag;
    out << "    <" << tag;
    if (m.vel_percent) out << " vel_percent=\"" << calib::formatFixed(*m.vel_percent, 4) << "\"";
    if (m.vel_m_s) out << " vel_m_s=\"" << calib::formatFixed(*m.vel_m_s, 4) << "\"";
    if (!m.approximation.empty()) {
      out << " approx=\"";
      for (size_t ai = 0; ai < m.approximation.size(); ++ai) out << (ai ? " " : "") << toString(m.approximation[ai]);
      out << "\"";
      if (m.approximation_value) out << " approx_value=\"" << calib::formatFixed(*m.approximation_value, 4) << "\"";
    }
    if (m.circ_angle_deg) out << " ca_deg=\"" << formatDeg(*m.circ_angle_deg) << "\"";
    if (m.relative) out << " relative=\"true\"";
    if (m.relative && m.relative_in_tool) out << " relative_frame=\"tool\"";
    if (m.external_tcp) out << " external_tcp=\"true\"";
    if (!m.conf_monitored) out << " conf_monitored=\"false\"";
    if (m.source_line > 0 && !m.inserted) out << " source_line=\"" << m.source_line << "\"";
    if (m.start_unknown && !m.inserted) out << " start_unknown=\"true\"";
    for (const std::string* v : {&m.ori_type, &m.circ_type})
      if (orientationControlNotKnown(*v))  // (the KRL reader could not follow it: krl_reader.cpp)
        throw calib::ArgumentError(m.where.str() + ": cannot write '" + detail::excerpt(m.statement) +
                                   "' as an XML motion: its orientation control is not known here (" + v->substr(1) +
                                   "), and the XML program states each motion's");
    if (!m.ori_type.empty()) out << " ori_type=\"" << calib::xmlEscape(m.ori_type) << "\"";
    if (!m.circ_type.empty()) out << " circ_type=\"" << calib::xmlEscape(m.circ_type) << "\"";
    if (m.spline_block > 0)
      out << " spline_block=\"" << m.spline_block << "\" spline_block_type=\"" << (m.ptp_spline_block ? "PTP_SPLINE" : "SPLINE") << "\"";
    if (!m.duration_expr.empty())
      throw calib::ArgumentError(m.where.str() + ": cannot write '" + detail::excerpt(m.statement) + "' as XML: its time (" +
                                 detail::excerpt(m.duration_expr) + ") is computed at run time, which the XML's motion model cannot hold " +
                                 "(convert --drop-unconvertible converts the motion without it)");
    if (m.duration_s) {
      // a motion the compensation split: each piece its share of the time (program.h)
      const std::string piece = pieceDurationText(p, k, *m.duration_s);
      out << " time_s=\"" << (piece.empty() ? calib::formatFixed(*m.duration_s, 4) : piece) << "\"";
    }
    out << ">\n";
    auto refOrValue = [&](const char* tag_name, const Target& t, bool aux) {
      if (hasValues(t)) {
        writeTarget(out, tag_name, t);
        return;
      }
      if (!isDeclarableName(t.name))
        throw calib::ArgumentError(m.where.str() + ": cannot write this motion's target as XML: " +
                            (m.target_problem.empty() ? std::string("it has no value") : m.target_problem));
      out << "      <" << (aux ? "aux" : "ref") << " name=\"" << calib::xmlEscape(t.name) << "\"/>\n";
    };
    if (m.aux) refOrValue("aux", *m.aux, true);
    refOrValue(m.target.kind == Target::Kind::kAxis ? "axes" : "pose", m.target, false);
    out << "    </" << tag << ">\n";
  }
  carry(false, p.motions.size());
  out << "  </motions>\n</program>\n";
  return out.str();
}

}  // namespace accura::postproc
