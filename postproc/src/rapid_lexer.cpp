// RAPID tokens and token-range helpers, pose conversions, predefined data, the pass-through
// lines of a module, and ABB confdata (rapid.h, rapid_internal.h).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>

#include "accura/calib/errors.h"
#include "accura/calib/ik.h"
#include "decimal.h"
#include "excerpt.h"
#include "rapid_internal.h"

namespace accura::postproc {
namespace rapid_detail {
namespace {

bool isDigit(char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; }
bool isIdentStart(char c) { return std::isalpha(static_cast<unsigned char>(c)) || c == '_'; }
bool isIdentChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

SourceLocation locate(const std::vector<size_t>& line_starts, const std::string& path, size_t off) {
  const auto it = std::upper_bound(line_starts.begin(), line_starts.end(), off);
  const size_t line = static_cast<size_t>(it - line_starts.begin());
  SourceLocation l;
  l.file = path;
  l.line = static_cast<int>(line);
  l.column = static_cast<int>(off - line_starts[line - 1]) + 1;
  return l;
}

std::vector<Tok> lexRapid(const std::string& s, const std::string& path) {
  std::vector<size_t> starts{0};
  for (size_t i = 0; i < s.size(); ++i)
    if (s[i] == '\n') starts.push_back(i + 1);
  auto fail = [&](size_t off, const std::string& msg) {
    const SourceLocation l = locate(starts, path, off);
    throw calib::InputError(l.file, l.line, l.column, msg);
  };
  // a NUL byte anywhere (code, a comment, a string, the %%% header) is no text the controller
  // loads: the first one is the error
  if (const size_t nul = s.find('\0'); nul != std::string::npos) fail(nul, "expected a RAPID text file, found a NUL byte (binary file?)");
  std::vector<Tok> toks;
  size_t i = s.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;  // a UTF-8 byte order mark: read past (kept in the text)
  bool line_start = true;
  while (i < s.size()) {
    const char c = s[i];
    if (line_start && s.compare(i, 3, "%%%") == 0) {  // .prg header block %%% ... %%%
      size_t j = s.find("%%%", i + 3);
      if (j == std::string::npos) fail(i, "expected the '%%%' that closes this header, found the end of the file");
      i = j + 3;
      continue;
    }
    if (c == '!') {
      while (i < s.size() && s[i] != '\n') ++i;
      continue;
    }
    if (c == '\n' || c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v') {
      if (c == '\n') line_start = true;
      ++i;
      continue;
    }
    line_start = false;
    Tok t;
    t.b = i;
    if (isDigit(c) || (c == '.' && i + 1 < s.size() && isDigit(s[i + 1]))) {
      const detail::LexedNumber n = detail::lexNumber(s, i);
      const size_t j = n.end;
      if (n.error.empty() && j < s.size() && isIdentStart(s[j]))
        fail(j, "expected an operator or a separator after the number " + detail::excerpt(n.text) + ", found '" + s[j] + "'");
      if (!n.error.empty()) fail(n.error_at, n.error);
      t.kind = Tok::Kind::kNumber;
      t.e = j;
      t.s = n.text;
      t.num = n.value;
    } else if (isIdentStart(c)) {
      size_t j = i;
      while (j < s.size() && isIdentChar(s[j])) ++j;
      t.kind = Tok::Kind::kIdent;
      t.e = j;
      t.s = s.substr(i, j - i);
    } else if (c == '"') {
      size_t j = i + 1;
      while (j < s.size() && s[j] != '\n' && !(s[j] == '"' && !(j + 1 < s.size() && s[j + 1] == '"'))) j += s[j] == '"' ? 2 : 1;
      if (j >= s.size() || s[j] != '"')  // (a file cut short in the string: its end)
        fail(i, std::string("expected the closing '\"' of this string on its line, found the end of the ") + (j >= s.size() ? "file" : "line"));
      t.kind = Tok::Kind::kString;
      t.e = j + 1;
      t.s = s.substr(i, t.e - i);
    } else {
      size_t n = 1;
      if (i + 1 < s.size() && ((c == ':' && s[i + 1] == '=') || (c == '<' && (s[i + 1] == '>' || s[i + 1] == '=')) || (c == '>' && s[i + 1] == '=')))
        n = 2;
      t.kind = Tok::Kind::kOp;
      t.e = i + n;
      t.s = s.substr(i, n);
    }
    t.u = upper(t.s);
    i = t.e;
    toks.push_back(std::move(t));
  }
  return toks;
}

Eigen::Isometry3d poseOf(const double xyz[3], const double wxyz[4]) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
  T.linear() = Eigen::Quaterniond(wxyz[0], wxyz[1], wxyz[2], wxyz[3]).normalized().toRotationMatrix();
  return T;
}

std::array<double, 4> quaternionNear(const Eigen::Matrix3d& R, const double near[4]) {
  const Eigen::Quaterniond q(R);
  std::array<double, 4> v{q.w(), q.x(), q.y(), q.z()};
  double dot = 0;
  for (int k = 0; k < 4; ++k) dot += v[static_cast<size_t>(k)] * near[k];
  if (dot < 0)
    for (double& x : v) x = -x;
  return v;
}

std::optional<double> predefinedZoneMm(const std::string& u) {
  if (u == "Z0") return 0.3;
  static const int radii[] = {1, 5, 10, 15, 20, 30, 40, 50, 60, 80, 100, 150, 200};
  for (int r : radii)
    if (u == "Z" + std::to_string(r)) return static_cast<double>(r);
  return std::nullopt;
}

std::optional<double> predefinedSpeedMmS(const std::string& u) {
  static const int speeds[] = {5, 10, 20, 30, 40, 50, 60, 80, 100, 150, 200, 300, 400, 500, 600, 800, 1000, 1500, 2000, 2500, 3000, 4000, 5000, 6000, 7000};
  for (int v : speeds)
    if (u == "V" + std::to_string(v)) return static_cast<double>(v);
  return std::nullopt;
}

bool isOp(const std::vector<Tok>& t, size_t i, const char* s) { return i < t.size() && t[i].kind == Tok::Kind::kOp && t[i].s == s; }
bool isKw(const std::vector<Tok>& t, size_t i, const char* u) { return i < t.size() && t[i].kind == Tok::Kind::kIdent && t[i].u == u; }

bool opens(const Tok& t) { return t.kind == Tok::Kind::kOp && (t.s == "(" || t.s == "[" || t.s == "{"); }
bool closes(const Tok& t) { return t.kind == Tok::Kind::kOp && (t.s == ")" || t.s == "]" || t.s == "}"); }

/// Index one past the bracket closing the one at i.
size_t closing(const std::vector<Tok>& t, size_t i, size_t end) {
  int depth = 0;
  for (size_t k = i; k < end; ++k) {
    if (opens(t[k])) ++depth;
    if (closes(t[k]) && --depth == 0) return k + 1;
  }
  return end;
}

/// Comma-separated items of [i, j) at depth 0.
std::vector<Range> items(const std::vector<Tok>& t, size_t i, size_t j) {
  std::vector<Range> out;
  if (i >= j) return out;
  size_t start = i;
  int depth = 0;
  for (size_t k = i; k < j; ++k) {
    if (opens(t[k])) ++depth;
    if (closes(t[k])) --depth;
    if (depth == 0 && isOp(t, k, ",")) {
      out.push_back({start, k});
      start = k + 1;
    }
  }
  out.push_back({start, j});
  return out;
}

/// A signed number written as [+|-] number, else nullopt.
std::optional<double> number(const std::vector<Tok>& t, Range r) {
  if (r.second == r.first + 1 && t[r.first].kind == Tok::Kind::kNumber) return t[r.first].num;
  if (r.second == r.first + 2 && t[r.first + 1].kind == Tok::Kind::kNumber && (isOp(t, r.first, "-") || isOp(t, r.first, "+")))
    return t[r.first].s == "-" ? -t[r.first + 1].num : t[r.first + 1].num;
  return std::nullopt;
}


/// Every code line outside the motion model as a PassThrough (comment-only and blank lines
/// are not statements): module level -> kData, the routine holding the motions -> kBody,
/// other routines -> kTrailer.
void rapidPassThrough(const RapidSource& src, const std::vector<Tok>& t_, const std::vector<Range>& stmts_,
                    const std::vector<size_t>& starts_, const std::vector<bool>& model_line_, const std::vector<int>& motion_lines_,
                    const std::string& main_routine_, bool other_routine_motion_, Program& p) {
auto loc = [&](size_t off) { return locate(starts_, src.path, off); };
  size_t next_motion = 0;
  int main_begin = 0, main_end = 0;  // lines of the main routine
  bool in_main = false;
  std::vector<int> routine_of(starts_.size() + 1, 0);  // 0: module level, 1: main routine, 2: other
  int state = 0;
  for (const Range& r : stmts_) {
    const size_t h = t_[r.first].u == "LOCAL" && r.first + 1 < r.second ? r.first + 1 : r.first;  // LOCAL PROC
    const std::string& u = t_[h].u;
    const int a = loc(t_[r.first].b).line, b = loc(t_[r.second - 1].b).line;
    if (u == "PROC" || u == "FUNC" || u == "TRAP") {
      size_t k = h + 1 + (u == "FUNC" ? 1 : 0);
      in_main = k < r.second && t_[k].s == main_routine_ && u == "PROC";
      state = in_main ? 1 : 2;
      if (in_main) main_begin = a;
    }
    for (int l = a; l <= b; ++l) routine_of[static_cast<size_t>(l)] = state;
    if (u == "ENDPROC" || u == "ENDFUNC" || u == "ENDTRAP") {
      if (in_main) main_end = b;
      state = 0;
      in_main = false;
    }
  }
  (void)main_begin;
  (void)main_end;
  std::vector<bool> code(starts_.size() + 1, false);
  for (const Tok& t : t_) code[static_cast<size_t>(loc(t.b).line)] = true;
  for (size_t l = 1; l <= starts_.size(); ++l) {
    while (next_motion < motion_lines_.size() && motion_lines_[next_motion] <= static_cast<int>(l)) ++next_motion;
    if (!code[l] || model_line_[l]) continue;
    PassThrough s;
    s.language = "RAPID";
    const size_t b = starts_[l - 1];
    size_t e = l < starts_.size() ? starts_[l] - 1 : src.text.size();
    if (e > b && src.text[e - 1] == '\r') --e;
    s.text = src.text.substr(b, e - b);
    s.where.file = src.path;
    s.where.line = static_cast<int>(l);
    s.where.column = 1;
    s.section = routine_of[l] == 0 ? PassThrough::Section::kData : routine_of[l] == 1 ? PassThrough::Section::kBody : PassThrough::Section::kTrailer;
    s.before_motion = next_motion;
    if (other_routine_motion_ && routine_of[l] == 2)
      s.refuse = "the motions of the routine on this line are outside " + detail::excerpt(main_routine_) +
                 ", the first routine with motions, whose motions alone the other formats hold (one routine's; compensate "
                 "corrects every routine's in the module itself)";
    p.passthrough.push_back(std::move(s));
  }
}


}  // namespace rapid_detail

std::array<int, 4> abbConfdata(const calib::RobotModel& model, const Eigen::VectorXd& q) {
  if (q.size() != model.dof() || q.size() < 6) throw calib::ArgumentError("abbConfdata: expected the 6 joints of the model");
  const calib::Configuration c = calib::kukaConfiguration(model, q);
  auto quadrant = [&](int k) { return static_cast<int>(std::floor(q[k] / 90.0)); };
  int cfx = 0;
  if (c.status >= 0) cfx = ((c.status & 1) ? 4 : 0) + ((c.status & 2) ? 0 : 2) + ((c.status & 4) ? 1 : 0);
  return {quadrant(0), quadrant(3), quadrant(5), cfx};
}

int kukaStatusOfCfx(int cfx) {
  if (cfx < 0 || cfx > 7) return -1;
  return ((cfx & 4) ? 1 : 0) + ((cfx & 2) ? 0 : 2) + ((cfx & 1) ? 4 : 0);
}

}  // namespace accura::postproc
