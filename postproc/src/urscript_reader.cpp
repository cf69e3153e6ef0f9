// URScript reader (see urscript.h): tokens, statements, the motion model.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>

#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "decimal.h"
#include "excerpt.h"
#include "start_tracker.h"
#include "urscript_internal.h"

namespace fs = std::filesystem;

namespace accura::postproc {

namespace ur_detail {

Eigen::Isometry3d poseOf(const double v[6]) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(v[0], v[1], v[2]) * 1000.0;
  const Eigen::Vector3d r(v[3], v[4], v[5]);
  const double angle = r.norm();
  if (angle > 0) T.linear() = Eigen::AngleAxisd(angle, r / angle).toRotationMatrix();
  return T;
}

Eigen::Isometry3d poseAdd(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = a.translation() + b.translation();
  T.linear() = a.linear() * b.linear();
  return T;
}

Eigen::Isometry3d evaluate(const UrScriptSource& src, int id, const std::map<int, Eigen::Isometry3d>* override) {
  const UrScriptSource::Expr& e = src.exprs.at(static_cast<size_t>(id));
  switch (e.kind) {
    case UrScriptSource::Expr::Kind::kLiteral: {
      if (override) {
        const auto it = override->find(e.literal);
        if (it != override->end()) return it->second;
      }
      return poseOf(src.literals.at(static_cast<size_t>(e.literal)).value);
    }
    case UrScriptSource::Expr::Kind::kTrans: return evaluate(src, e.a, override) * evaluate(src, e.b, override);
    case UrScriptSource::Expr::Kind::kAdd: return poseAdd(evaluate(src, e.a, override), evaluate(src, e.b, override));
  }
  return Eigen::Isometry3d::Identity();
}

}  // namespace ur_detail

namespace {

using namespace ur_detail;
using detail::excerpt;

struct Tok {
  enum class Kind { kIdent, kNumber, kString, kOp, kNewline };
  Kind kind = Kind::kOp;
  size_t b = 0, e = 0;
  std::string s;
  double num = 0;
};

bool isIdentStart(char c) { return std::isalpha(static_cast<unsigned char>(c)) || c == '_'; }
bool isIdentChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }
bool isDigit(char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; }

/// A pose expression evaluated: its expression index (or why it cannot be evaluated).
struct PoseVal {
  int expr = -1;
  int literal = -1;      ///< the literal a correction is written into (the right-most one)
  std::string problem;   ///< non-empty: not evaluable
};

struct Var {
  enum class Kind { kPose, kJoints, kOther };
  Kind kind = Kind::kOther;
  PoseVal pose;
  std::array<double, 6> q{};
  std::string problem;
};

constexpr double kMaxPositionM = 100;   // beyond any robot: a typo (mm written as m)
constexpr double kMaxRotationRad = 100;
constexpr double kMaxJointRad = 100;

/// URScript commands that move the robot in ways accura does not model.
const std::set<std::string> kOtherMotions = {"servoj", "servoc", "speedj", "speedl"};

class Reader {
 public:
  Reader(const std::string& text, const std::string& path) : src_(std::make_shared<UrScriptSource>()) {
    src_->path = path;
    src_->text = text;
    line_starts_.push_back(0);
    for (size_t i = 0; i < text.size(); ++i)
      if (text[i] == '\n') line_starts_.push_back(i + 1);
  }

  Program run() {
    lex();
    movingFunctions();
    Program p;
    p.source_file = src_->path;
    p.name = fs::path(src_->path).stem().string();
    tool_.source = FrameSetting::Source::kUnset;
    tool_.note = "the TCP is not set before this motion (call set_tcp(p[...]) first, or give the TCP active on the controller with --program-tool x,y,z,A,B,C)";
    base_.source = FrameSetting::Source::kNull;
    base_.value = calib::XyzAbc{};
    base_.text = "Base";
    size_t i = 0;
    while (i < toks_.size()) {
      if (toks_[i].kind == Tok::Kind::kNewline) {
        ++i;
        continue;
      }
      size_t j = i;
      std::vector<size_t> open;
      while (j < toks_.size() && !(toks_[j].kind == Tok::Kind::kNewline && open.empty())) {
        const Tok& t = toks_[j];
        if (t.kind == Tok::Kind::kOp && (t.s == "(" || t.s == "[" || t.s == "{")) open.push_back(j);
        if (t.kind == Tok::Kind::kOp && (t.s == ")" || t.s == "]" || t.s == "}")) {
          if (open.empty()) fail(t.b, "expected a statement, found an unmatched '" + t.s + "'");
          const std::string& o = toks_[open.back()].s;
          const std::string want = o == "(" ? ")" : o == "[" ? "]" : "}";
          if (t.s != want)
            fail(t.b, "expected '" + want + "' to close the '" + o + "' at " + loc(toks_[open.back()].b).str() + ", found '" + t.s + "'");
          open.pop_back();
        }
        ++j;
      }
      if (!open.empty()) {
        const Tok& o = toks_[open.back()];
        fail(o.b, "expected '" + std::string(o.s == "(" ? ")" : o.s == "[" ? "]" : "}") + "' to close this '" + o.s +
                      "', found the end of the file");
      }
      std::vector<Tok> st;
      for (size_t k = i; k < j; ++k)
        if (toks_[k].kind != Tok::Kind::kNewline) st.push_back(toks_[k]);
      if (j >= toks_.size()) cutName(st);
      statement(st, p);
      i = j;
    }
    // a script without a statement (0 bytes, blanks, comments only) is no program: an empty
    // output would be written without a word (a script of statements without a motion is one)
    if (std::none_of(toks_.begin(), toks_.end(), [](const Tok& t) { return t.kind != Tok::Kind::kNewline; })) {
      const bool comments = src_->text.find('#') != std::string::npos;
      fail(0, std::string("expected a URScript program (def name(): ... end, or its statements such as movel(...)), found an empty file") +
                  (comments ? " (only comments and blank lines)" : ""));
    }
    if (!blocks_.empty()) {  // a script cut short: the innermost open block, and what it is
      const OpenBlock& b = blocks_.back();
      fail(src_->text.size(), "expected end closing the block at " + loc(b.at).str() + ", found the end of the file (the block is the " + b.head +
                                  (b.name.empty() ? std::string() : " " + excerpt(b.name)) + " opened there" +
                                  (blocks_.size() > 1 ? ", inside " + std::to_string(blocks_.size() - 1) + " more open block(s)" : std::string()) + ")");
    }
    if (!main_name_.empty()) p.name = main_name_;
    p.urscript = src_;
    return p;
  }

 private:
  SourceLocation loc(size_t off) const {
    const auto it = std::upper_bound(line_starts_.begin(), line_starts_.end(), off);
    const size_t line = static_cast<size_t>(it - line_starts_.begin());
    SourceLocation l;
    l.file = src_->path;
    l.line = static_cast<int>(line);
    l.column = static_cast<int>(off - line_starts_[line - 1]) + 1;
    return l;
  }

  [[noreturn]] void fail(size_t off, const std::string& msg) const {
    const SourceLocation l = loc(off);
    throw calib::InputError(l.file, l.line, l.column, msg);
  }

  /// The last statement `st`, a bare name where the file ends without a line end ('de' of
  /// 'def ...', 'set_di' of 'set_digital_out(...)'): a file cut short inside a name, not a
  /// statement. (A bare name the controller runs names a variable or a function the script
  /// defines, so it occurs elsewhere in it; the statement keywords are statements.) Inside an
  /// open block the end of the file is that block's error.
  void cutName(const std::vector<Tok>& st) const {
    // (and the words that open a block: the block's end-of-file error names it)
    static const std::set<std::string> kStatements = {"end",  "else", "break", "continue", "pass",  "return",
                                                      "halt", "def",  "thread", "if",      "while", "elif"};
    const std::string& text = src_->text;
    if (!blocks_.empty()) return;  // (the end of the file leaves a block open: that error names it)
    if (st.size() != 1 || st[0].kind != Tok::Kind::kIdent || kStatements.count(st[0].s) || text.empty() || text.back() == '\n' ||
        text.back() == '\r' || st[0].e < text.find_last_not_of(" \t") + 1)
      return;
    for (const Tok& t : toks_)
      if (t.kind == Tok::Kind::kIdent && t.s == st[0].s && t.b != st[0].b) return;
    fail(text.size(), "expected a statement (a call such as " + excerpt(st[0].s) + "(...), an assignment, end), found '" + excerpt(st[0].s) +
                          "' and then the end of the file (a file cut short?)");
  }

  std::string textOf(size_t b, size_t e) const { return src_->text.substr(b, e - b); }
  std::string textOf(const std::vector<Tok>& t, size_t i, size_t j) const {
    return i < j ? textOf(t[i].b, t[j - 1].e) : std::string();
  }
  /// The tokens [i, j) as a message quotes them (detail::excerpt: at most 80 bytes).
  std::string quoted(const std::vector<Tok>& t, size_t i, size_t j) const { return excerpt(textOf(t, i, j)); }

  void lex() {
    const std::string& s = src_->text;
    // a NUL byte anywhere (code, a comment, a string) is no text: the first one is the error
    if (const size_t nul = s.find('\0'); nul != std::string::npos) fail(nul, "expected a URScript text file, found a NUL byte (binary file?)");
    size_t i = s.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;  // a UTF-8 byte order mark: read past (kept in the text)
    while (i < s.size()) {
      const char c = s[i];
      if (c == '#') {
        while (i < s.size() && s[i] != '\n') ++i;
        continue;
      }
      if (c == '\n') {
        toks_.push_back({Tok::Kind::kNewline, i, i + 1, "\n", 0});
        ++i;
        continue;
      }
      if (c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v') {
        ++i;
        continue;
      }
      Tok t;
      t.b = i;
      if (isDigit(c) || (c == '.' && i + 1 < s.size() && isDigit(s[i + 1]))) {
        const detail::LexedNumber n = detail::lexNumber(s, i);
        if (!n.error.empty()) fail(n.error_at, n.error);
        t.kind = Tok::Kind::kNumber;
        t.e = n.end;
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
        while (j < s.size() && s[j] != '"' && s[j] != '\n') j += s[j] == '\\' && j + 1 < s.size() && s[j + 1] != '\n' ? 2 : 1;
        if (j >= s.size() || s[j] != '"')  // (a file cut short in the string: its end)
        fail(i, std::string("expected the closing '\"' of this string on its line, found the end of the ") + (j >= s.size() ? "file" : "line"));
        t.kind = Tok::Kind::kString;
        t.e = j + 1;
        t.s = s.substr(i, t.e - i);
      } else {
        size_t n = 1;
        if (i + 1 < s.size() && s[i + 1] == '=' && (c == '=' || c == '!' || c == '<' || c == '>')) n = 2;
        t.kind = Tok::Kind::kOp;
        t.e = i + n;
        t.s = s.substr(i, n);
      }
      i = t.e;
      toks_.push_back(t);
    }
  }

  static bool isOp(const std::vector<Tok>& t, size_t i, const char* s) {
    return i < t.size() && t[i].kind == Tok::Kind::kOp && t[i].s == s;
  }
  static bool isIdent(const std::vector<Tok>& t, size_t i, const char* s = nullptr) {
    return i < t.size() && t[i].kind == Tok::Kind::kIdent && (!s || t[i].s == s);
  }

  /// The index one past the bracket that closes the one at `i` (the statement is balanced).
  static size_t closing(const std::vector<Tok>& t, size_t i) {
    int depth = 0;
    for (size_t k = i; k < t.size(); ++k) {
      if (t[k].kind != Tok::Kind::kOp) continue;
      if (t[k].s == "(" || t[k].s == "[" || t[k].s == "{") ++depth;
      if (t[k].s == ")" || t[k].s == "]" || t[k].s == "}") {
        if (--depth == 0) return k + 1;
      }
    }
    return t.size();
  }

  /// The comma-separated items of [i, j) at depth 0, as index ranges.
  static std::vector<std::pair<size_t, size_t>> items(const std::vector<Tok>& t, size_t i, size_t j) {
    std::vector<std::pair<size_t, size_t>> out;
    if (i >= j) return out;
    size_t start = i;
    int depth = 0;
    for (size_t k = i; k < j; ++k) {
      if (t[k].kind == Tok::Kind::kOp) {
        if (t[k].s == "(" || t[k].s == "[" || t[k].s == "{") ++depth;
        if (t[k].s == ")" || t[k].s == "]" || t[k].s == "}") --depth;
        if (depth == 0 && t[k].s == ",") {
          out.push_back({start, k});
          start = k + 1;
        }
      }
    }
    out.push_back({start, j});
    return out;
  }

  /// A signed number written as one item ([+|-] number), else nullopt.
  static std::optional<double> number(const std::vector<Tok>& t, size_t i, size_t j) {
    if (j == i + 1 && t[i].kind == Tok::Kind::kNumber) return t[i].num;
    if (j == i + 2 && t[i + 1].kind == Tok::Kind::kNumber && (isOp(t, i, "-") || isOp(t, i, "+")))
      return t[i].s == "-" ? -t[i + 1].num : t[i + 1].num;
    return std::nullopt;
  }

  /// Adds e at `at` (its operator's token): a pose_trans/pose_add of variables built on each
  /// other may chain any number of statements, and evaluating it is a call per level, so the
  /// chain is bounded (kMaxExprDepth).
  int addExpr(UrScriptSource::Expr e, size_t at) {
    int depth = 0;  // the pose_trans/pose_add on the way down to its deepest literal
    for (int operand : {e.a, e.b})
      if (operand >= 0) depth = std::max(depth, 1 + expr_depth_[static_cast<size_t>(operand)]);
    if (depth > kMaxExprDepth)
      fail(at, "expected a pose built of at most " + std::to_string(kMaxExprDepth) +
                   " pose_trans/pose_add (through the variables it uses), found a deeper one");
    src_->exprs.push_back(e);
    expr_depth_.push_back(depth);
    return static_cast<int>(src_->exprs.size()) - 1;
  }

  /// The pose expression [i, j) of statement t.
  PoseVal pose(const std::vector<Tok>& t, size_t i, size_t j) {
    PoseVal v;
    const std::string text = textOf(t, i, j);
    if (i >= j) {
      v.problem = "an empty pose";
      return v;
    }
    if (isIdent(t, i, "p") && isOp(t, i + 1, "[") && closing(t, i + 1) == j) {
      const auto parts = items(t, i + 2, j - 1);
      if (parts.size() != 6 || (parts.size() == 1 && parts[0].first == parts[0].second))
        fail(t[i].b, "expected p[x, y, z, rx, ry, rz] with 6 numbers, found " + std::to_string(i + 2 == j - 1 ? 0 : parts.size()) +
                         " in '" + excerpt(text) + "'");
      UrScriptSource::Literal lit;
      lit.begin = t[i].b;
      lit.end = t[j - 1].e;
      for (int k = 0; k < 6; ++k) {
        const auto [a, b] = parts[static_cast<size_t>(k)];
        if (a == b) fail(a < j ? t[a].b : t[j - 1].b, "expected a number in p[...], found '" + (a < j ? excerpt(t[a].s) : std::string("]")) + "'");
        const std::optional<double> n = number(t, a, b);
        if (!n) {
          v.problem = "p[...] at " + loc(t[i].b).str() + " has a component that is not a number ('" + quoted(t, a, b) + "')";
          return v;
        }
        const double lim = k < 3 ? kMaxPositionM : kMaxRotationRad;
        if (std::abs(*n) > lim)
          fail(t[a].b, std::string("expected ") + (k < 3 ? "a position in metres" : "a rotation vector component in radians") +
                           " within +-" + calib::formatFixed(lim, 0) + ", found " + quoted(t, a, b));
        lit.number[k] = {t[a].b, t[b - 1].e};
        lit.value[k] = *n;
      }
      src_->literals.push_back(lit);
      v.literal = static_cast<int>(src_->literals.size()) - 1;
      UrScriptSource::Expr e;
      e.literal = v.literal;
      v.expr = addExpr(e, t[i].b);
      return v;
    }
    if (j == i + 1 && t[i].kind == Tok::Kind::kIdent) {
      const auto it = vars_.find(t[i].s);
      if (it == vars_.end()) {
        v.problem = "'" + excerpt(t[i].s) + "' is not assigned a pose before this line";
        return v;
      }
      refs_.push_back(t[i].s);
      if (it->second.kind == Var::Kind::kPose) return it->second.pose;
      v.problem = it->second.problem.empty() ? "'" + excerpt(t[i].s) + "' is not a pose" : it->second.problem;
      return v;
    }
    if (t[i].kind == Tok::Kind::kIdent && isOp(t, i + 1, "(") && closing(t, i + 1) == j) {
      const std::string& f = t[i].s;
      if (f == "pose_trans" || f == "pose_add") {
        const auto args = items(t, i + 2, j - 1);
        if (args.size() != 2) fail(t[i].b, "expected " + excerpt(f) + "(pose, pose) with 2 arguments, found " + std::to_string(args.size()));
        // (each level is a call: a pathological depth would overflow the stack)
        if (++pose_depth_ > kMaxPoseNesting)
          fail(t[i].b, "expected pose_trans/pose_add nested at most " + std::to_string(kMaxPoseNesting) + " deep, found deeper nesting");
        const PoseVal a = pose(t, args[0].first, args[0].second);
        const PoseVal b = pose(t, args[1].first, args[1].second);
        --pose_depth_;
        if (!a.problem.empty() || !b.problem.empty()) {
          v.problem = f + "(...) at " + loc(t[i].b).str() + " cannot be evaluated: " + (a.problem.empty() ? b.problem : a.problem);
          return v;
        }
        UrScriptSource::Expr e;
        e.kind = f == "pose_trans" ? UrScriptSource::Expr::Kind::kTrans : UrScriptSource::Expr::Kind::kAdd;
        e.a = a.expr;
        e.b = b.expr;
        v.expr = addExpr(e, t[i].b);
        v.literal = b.literal >= 0 ? b.literal : a.literal;
        return v;
      }
      v.problem = excerpt(f) + "(...) is computed by the controller at run time (accura evaluates p[...], pose variables, pose_trans and pose_add)";
      return v;
    }
    v.problem = "'" + excerpt(text) + "' is not a pose accura can evaluate (p[...], a pose variable, pose_trans, pose_add)";
    return v;
  }

  /// Joint positions [q1..q6] (rad) written as a list or a variable holding one.
  std::optional<std::array<double, 6>> joints(const std::vector<Tok>& t, size_t i, size_t j, std::string* problem) {
    if (isOp(t, i, "[") && closing(t, i) == j) {
      const auto parts = items(t, i + 1, j - 1);
      if (parts.size() != 6) fail(t[i].b, "expected 6 joint positions [q1, .., q6] (rad), found " + std::to_string(parts.size()));
      std::array<double, 6> q{};
      for (int k = 0; k < 6; ++k) {
        if (parts[k].first == parts[k].second) fail(t[parts[k].first].b, "expected a joint position, found '" + excerpt(t[parts[k].first].s) + "'");
        const std::optional<double> n = number(t, parts[k].first, parts[k].second);
        if (!n) {
          *problem = "the joint list at " + loc(t[i].b).str() + " has a value that is not a number ('" +
                     quoted(t, parts[k].first, parts[k].second) + "')";
          return std::nullopt;
        }
        if (std::abs(*n) > kMaxJointRad)
          fail(t[parts[k].first].b, "expected a joint position in radians within +-100, found " + quoted(t, parts[k].first, parts[k].second));
        q[static_cast<size_t>(k)] = *n;
      }
      return q;
    }
    if (j == i + 1 && t[i].kind == Tok::Kind::kIdent) {
      const auto it = vars_.find(t[i].s);
      refs_.push_back(t[i].s);
      if (it != vars_.end() && it->second.kind == Var::Kind::kJoints) return it->second.q;
    }
    *problem = "'" + quoted(t, i, j) + "' is not a joint list accura can evaluate";
    return std::nullopt;
  }

  /// The script's functions that move the robot, themselves or through the ones they call (a
  /// call may come before the def): a call of any other (a URCap's gripper helpers) does not
  /// change where the robot is. A def's body runs to the end matching it (if/while open blocks
  /// of their own).
  void movingFunctions() {
    std::map<std::string, bool> moves;
    std::map<std::string, std::set<std::string>> calls;
    for (size_t k = 0; k + 1 < toks_.size(); ++k)
      if (toks_[k].kind == Tok::Kind::kIdent && toks_[k].s == "def" && toks_[k + 1].kind == Tok::Kind::kIdent) moves[toks_[k + 1].s] = false;
    std::vector<std::pair<std::string, int>> open;  // enclosing defs and the depth they opened at
    int depth = 0;
    bool line_start = true;
    for (size_t k = 0; k < toks_.size(); ++k) {
      const Tok& t = toks_[k];
      if (t.kind == Tok::Kind::kNewline) {
        line_start = true;
        continue;
      }
      const bool first = line_start;
      line_start = false;
      if (t.kind != Tok::Kind::kIdent) continue;
      if (first && (t.s == "def" || t.s == "thread" || t.s == "if" || t.s == "while")) {
        ++depth;
        if ((t.s == "def" || t.s == "thread") && k + 1 < toks_.size() && toks_[k + 1].kind == Tok::Kind::kIdent)
          open.push_back({toks_[k + 1].s, depth});
        continue;
      }
      if (first && t.s == "end" && (k + 1 == toks_.size() || toks_[k + 1].kind == Tok::Kind::kNewline)) {
        if (!open.empty() && open.back().second == depth) open.pop_back();
        --depth;
        continue;
      }
      if (open.empty()) continue;
      // a name assigned in the program's own body (not in a function or a thread): a program
      // variable, which a function's assignment of the same name (without local) changes
      const size_t name_at = first && (t.s == "global" || t.s == "local") ? k + 1 : k;
      if (open.size() == 1 && (first || name_at != k) && name_at + 1 < toks_.size() && toks_[name_at].kind == Tok::Kind::kIdent &&
          toks_[name_at + 1].kind == Tok::Kind::kOp && toks_[name_at + 1].s == "=")
        program_vars_.insert(toks_[name_at].s);
      const std::string& cur = open.back().first;
      if (t.s == "movel" || t.s == "movej" || t.s == "movep" || t.s == "movec" || kOtherMotions.count(t.s) || t.s == "force_mode")
        moves[cur] = true;
      else if (moves.count(t.s))
        calls[cur].insert(t.s);
    }
    defs_ = movingRoutines(moves, calls);
  }

  /// The arguments `list` of a call `f` whose parameters are `names`, from the `first`-th on
  /// (the ones before it the caller reads): positional, then named (name=value); the value's
  /// token span by name. Errors (file:line:column): an empty argument, an unknown name, a name
  /// given twice, a name without a value, a positional argument after a named one, too many.
  std::map<std::string, std::pair<size_t, size_t>> arguments(const std::vector<Tok>& t, const std::vector<std::pair<size_t, size_t>>& list,
                                                              size_t first, const std::vector<std::string>& names, const std::string& f) const {
    std::map<std::string, std::pair<size_t, size_t>> arg;
    size_t positional = first;
    bool named_seen = false;
    for (size_t k = first; k < list.size(); ++k) {
      const auto [a, b] = list[k];
      if (a == b) fail(a < t.size() ? t[a].b : t.back().b, "expected an argument of " + f + ", found an empty one");
      if (isIdent(t, a) && isOp(t, a + 1, "=")) {
        const std::string& n = t[a].s;
        if (std::find(names.begin() + static_cast<std::ptrdiff_t>(first), names.end(), n) == names.end()) {
          std::string all;
          for (size_t x = first; x < names.size(); ++x) all += (all.empty() ? "" : ", ") + names[x];
          fail(t[a].b, "expected an argument of " + f + " (" + all + "), found '" + excerpt(n) + "'");
        }
        if (arg.count(n)) fail(t[a].b, "expected each argument of " + f + " once, found '" + excerpt(n) + "' given twice");
        if (a + 2 >= b) fail(t[a + 1].b, "expected a value after '" + excerpt(n) + "=', found none");
        arg[n] = {a + 2, b};
        named_seen = true;
      } else {
        if (named_seen) fail(t[a].b, "expected a named argument (name=value) after a named one, found '" + quoted(t, a, b) + "'");
        if (positional >= names.size())
          fail(t[a].b, "expected at most " + std::to_string(names.size()) + " arguments of " + f + ", found '" + quoted(t, a, b) + "'");
        arg[names[positional++]] = {a, b};
      }
    }
    return arg;
  }

  /// The arguments of get_inverse_kin(x, qnear, maxPositionError, maxOrientationError, tcp)
  /// after the pose (URScript manual): qnear, the joints whose nearest solution the controller
  /// takes, into m.qnear_deg; the error bounds are the controller's own tolerances; a `tcp`
  /// other than the active one is a problem of the target (accura solves for the active TCP).
  void inverseKinArguments(const std::vector<Tok>& t, const std::vector<std::pair<size_t, size_t>>& gi, Motion& m) {
    static const std::vector<std::string> names = {"x", "qnear", "maxPositionError", "maxOrientationError", "tcp"};
    const std::map<std::string, std::pair<size_t, size_t>> arg = arguments(t, gi, 1, names, "get_inverse_kin");
    // the controller's defaults written out: the active TCP, the current joints
    const auto is = [&](const std::pair<size_t, size_t>& r, const char* a, const char* b) {
      const std::string x = textOf(t, r.first, r.second);
      return x == a || x == b;
    };
    if (const auto it = arg.find("tcp");
        it != arg.end() && !is(it->second, "get_tcp_offset()", "\"active_tcp\"") && m.target_problem.empty())
      m.target_problem = "get_inverse_kin(..., tcp=" + quoted(t, it->second.first, it->second.second) +
                         ") solves for a TCP that is not the active one, which accura does not model";
    const auto it = arg.find("qnear");
    if (it == arg.end() || is(it->second, "get_actual_joint_positions()", "get_target_joint_positions()")) return;
    std::string problem;
    const auto q = joints(t, it->second.first, it->second.second, &problem);
    if (!q) {
      // the controller takes the solution nearest to qnear: without its value the branch the
      // robot goes to is not known
      if (m.target_problem.empty()) m.target_problem = "the qnear of get_inverse_kin: " + problem;
      return;
    }
    std::array<double, 6> deg{};
    for (size_t k = 0; k < 6; ++k) deg[k] = (*q)[k] * calib::kRadToDeg;
    m.qnear_deg = deg;
  }

  bool looksLikeJoints(const std::vector<Tok>& t, size_t i, size_t j) const {
    if (isOp(t, i, "[") && closing(t, i) == j) return true;
    if (j == i + 1 && t[i].kind == Tok::Kind::kIdent) {
      const auto it = vars_.find(t[i].s);
      return it != vars_.end() && it->second.kind == Var::Kind::kJoints;
    }
    return false;
  }

  void other(const std::vector<Tok>& t) {
    UrScriptSource::Other o;
    o.where = loc(t.front().b);
    o.text = textOf(t, 0, t.size());
    src_->others.push_back(o);
  }

  void statement(const std::vector<Tok>& t, Program& p) {
    // blocks: the first def at depth 0 is the program; its def and end are part of the model
    if (isIdent(t, 0, "def") || isIdent(t, 0, "thread") || isIdent(t, 0, "if") || isIdent(t, 0, "while")) {
      OpenBlock b;
      b.at = t[0].b;
      b.head = t[0].s;
      b.loop = isIdent(t, 0, "while") ? ++loops_ : 0;
      b.kind = isIdent(t, 0, "if") ? StartTracker::Block::kBranch : b.loop ? StartTracker::Block::kLoop : StartTracker::Block::kRoutine;
      if (isIdent(t, 0, "def") && blocks_.empty() && main_name_.empty() && isIdent(t, 1)) {
        main_name_ = t[1].s;
        main_open_ = true;
        b.program = true;
      } else {
        other(t);
      }
      flow_.open(b.kind);
      b.tool = tool_;
      b.vars = vars_;
      b.first_motion = p.motions.size();
      if ((isIdent(t, 0, "def") || isIdent(t, 0, "thread")) && isIdent(t, 1)) b.name = t[1].s;
      blocks_.push_back(b);
      if (b.kind == StartTracker::Block::kRoutine && !b.program) {
        // a function (or thread) runs with the caller's tool and the program variables' values
        // where it is called
        tool_ = runTimeFrame("set_tcp", loc(t[0].b), "a function runs with the tool of the place it is called from until it calls set_tcp");
        for (auto& [n, v] : vars_) {
          Var c;
          c.problem = "in the function " + excerpt(b.name) + ", '" + excerpt(n) + "' has the value it has where the function is called";
          v = c;
        }
      }
      return;
    }
    if (isIdent(t, 0, "end") && t.size() == 1) {
      if (!blocks_.empty()) {
        if (!blocks_.back().program) flow_.close();  // (the program's own end: nothing follows)
        const OpenBlock b = blocks_.back();
        blocks_.pop_back();
        endVariables(b);
        const bool changed = b.tool_changed || !sameFrame(tool_, b.tool);
        if (b.kind == StartTracker::Block::kLoop && changed)
          // the next pass: the loop's motions before the change run with the changed tool
          for (size_t i = b.first_motion; i < p.motions.size(); ++i)
            if (sameFrame(p.motions[i].tool, b.tool))
              p.motions[i].tool = runTimeFrame("set_tcp", loc(t[0].b), "set_tcp is called later in the while at " + loc(b.at).str() +
                                                                            ": the next pass runs this motion with the new tool");
        if (b.kind == StartTracker::Block::kRoutine && !b.program) {
          // a function's set_tcp runs where it is called: the text after its end has the tool
          // from before it, and a call of it sets a tool accura does not follow
          tool_ = b.tool;
          if (b.sets_tcp) tcp_setters_[b.name] = loc(b.at);
          fn_calls_[b.name].insert(b.calls.begin(), b.calls.end());
        } else if (changed && !b.program) {
          // set in a branch or a loop: after it, the tool is whichever the run took
          tool_ = runTimeFrame("set_tcp", loc(t[0].b),
                               std::string("set_tcp is called inside the ") + (b.kind == StartTracker::Block::kBranch ? "if" : "while") +
                                   " at " + loc(b.at).str() + ": after it, the tool depends on the way the program ran");
        }
      }
      if (blocks_.empty() && main_open_) {
        main_open_ = false;
        return;
      }
      other(t);
      return;
    }
    if ((isIdent(t, 0, "elif") || isIdent(t, 0, "else")) && !blocks_.empty() && blocks_.back().kind == StartTracker::Block::kBranch) {
      flow_.branch();
      OpenBlock& b = blocks_.back();  // each branch starts with the tool and variables the if was entered with
      b.tool_changed = b.tool_changed || !sameFrame(tool_, b.tool);
      tool_ = b.tool;
      for (const std::string& n : changedVariables(b.vars)) b.vars_changed.insert(n);
      vars_ = b.vars;
    }
    // a call of a function (or a started thread) of the script that assigns program variables
    // or calls set_tcp; inside a function, the call makes them the function's own (a function
    // that calls one that sets the TCP sets it too)
    for (size_t k = 0; k + 1 < t.size(); ++k) {
      if (!isIdent(t, k) || !isOp(t, k + 1, "(")) continue;
      for (OpenBlock& b : blocks_) b.calls.insert(t[k].s);
      // the functions this call runs: the one called and, through the calls in their bodies,
      // those it calls (also those defined after it in the text: they exist when it runs);
      // the one called last, so that its own words are the ones kept
      std::vector<std::string> runs, todo = {t[k].s};
      std::set<std::string> seen = {t[k].s};
      while (!todo.empty()) {
        const std::string n = todo.back();
        todo.pop_back();
        if (n != t[k].s) runs.push_back(n);
        if (const auto c = fn_calls_.find(n); c != fn_calls_.end())
          for (const std::string& m : c->second)
            if (seen.insert(m).second) todo.push_back(m);
      }
      runs.push_back(t[k].s);
      for (const std::string& f : runs) {
        const std::string through = f == t[k].s ? std::string() : ", which " + excerpt(t[k].s) + " calls";
        if (const auto fa = fn_assigns_.find(f); fa != fn_assigns_.end())
          for (const auto& [n, at] : fa->second) {
            Var v;
            v.problem = "'" + excerpt(n) + "' is assigned by " + excerpt(f) + " (at " + at.str() + ")" + through + ", called at " + loc(t[k].b).str() +
                        ": its value after the call is not followed";
            vars_[n] = v;
            for (OpenBlock& b : blocks_) b.assigned.insert(n);
          }
        if (const auto ts = tcp_setters_.find(f); ts != tcp_setters_.end()) {
          tool_ = runTimeFrame(t[k].s + "()", loc(t[k].b),
                               "the function " + excerpt(f) + " (" + ts->second.str() + ")" + (through.empty() ? "" : through + ",") +
                                   " calls set_tcp: the tool after the call is not followed");
          for (OpenBlock& b : blocks_) b.sets_tcp = true;
        }
      }
    }
    // a call of one of the script's functions that move the robot, a thread of the script that
    // moves it started (run name()), force control
    if (isIdent(t, 0) && isOp(t, 1, "(") && defs_.count(t[0].s)) flow_.unknown();
    for (size_t k = 0; k + 1 < t.size(); ++k)
      if (isIdent(t, k, "run") && isIdent(t, k + 1) && defs_.count(t[k + 1].s)) flow_.unknown();
    if (isIdent(t, 0, "force_mode") && isOp(t, 1, "(")) flow_.unknown();
    size_t s = 0;
    if (isIdent(t, 0, "global") || isIdent(t, 0, "local")) s = 1;
    if (isIdent(t, s) && isOp(t, s + 1, "=")) return assignment(t, s, p);
    if (isIdent(t, 0) && isOp(t, 1, "(")) {
      const std::string& f = t[0].s;
      if (f == "movel" || f == "movej" || f == "movep" || f == "movec" || f == "set_tcp") {
        const size_t close = closing(t, 1);
        if (close != t.size()) fail(t[close].b, "expected the end of the statement after " + f + "(...), found '" + excerpt(t[close].s) + "'");
        if (f == "set_tcp") return setTcp(t);
        return motion(t, p);
      }
      // a Cartesian target accura cannot compensate: named; a joint target (servoj) needs no
      // compensation and a speed command has none: the statement is carried, the start after
      // it unknown
      if (f == "servoc") return otherMotion(t, p);
      if (kOtherMotions.count(f)) flow_.unknown();
      if (f == "set_gravity") gravity(t);
    }
    other(t);
  }

  /// set_gravity(d): d read where it is a list of three numbers (UrScriptSource::Gravity).
  void gravity(const std::vector<Tok>& t) {
    UrScriptSource::Gravity g;
    g.where = loc(t.front().b);
    g.text = textOf(t, 0, t.size());
    const size_t close = closing(t, 1);  // one past the ')'
    if (close == t.size() && isOp(t, 2, "[") && closing(t, 2) == close - 1) {
      const auto parts = items(t, 3, close - 2);
      std::array<double, 3> d{};
      bool all = parts.size() == 3;
      for (size_t k = 0; k < parts.size() && all; ++k) {
        const std::optional<double> n = number(t, parts[k].first, parts[k].second);
        all = n && std::isfinite(*n);
        if (all) d[k] = *n;
      }
      if (all) g.d = d;
    }
    src_->gravity.push_back(g);
  }

  bool mentions(const std::vector<Tok>& t, size_t i, size_t j, const std::string& name) const {
    for (size_t k = i; k < j; ++k)
      if (t[k].kind == Tok::Kind::kIdent && t[k].s == name) return true;
    return false;
  }

  /// The loops (while) open at this statement.
  std::vector<int> openLoops() const {
    std::vector<int> out;
    for (const OpenBlock& b : blocks_)
      if (b.loop > 0) out.push_back(b.loop);
    return out;
  }

  void assignment(const std::vector<Tok>& t, size_t s, Program& p) {
    const std::string name = t[s].s;
    if (s == 1 && !blocks_.empty()) (isIdent(t, 0, "local") ? blocks_.back().locals : blocks_.back().globals).insert(name);
    for (OpenBlock& b : blocks_) b.assigned.insert(name);
    // a motion earlier in an enclosing loop that uses the variable sees this value on the next
    // pass, not the one it was read with
    const std::vector<int> loops = openLoops();
    for (const Use& u : uses_) {
      if (u.var != name) continue;
      bool same_loop = false;
      for (int l : u.loops) same_loop = same_loop || std::find(loops.begin(), loops.end(), l) != loops.end();
      Motion& m = p.motions[u.motion];
      if (same_loop && m.target_problem.empty())
        m.target_problem = "'" + excerpt(name) + "' is assigned again at " + loc(t[s].b).str() +
                           " in the loop that runs this motion: its value on the next pass is not the one it has here";
    }
    const size_t i = s + 2, j = t.size();
    Var v;
    const auto prev = vars_.find(name);
    const bool was_model = prev != vars_.end() && prev->second.kind != Var::Kind::kOther;
    const bool pose_like = (isIdent(t, i, "p") && isOp(t, i + 1, "[")) || isIdent(t, i, "pose_trans") || isIdent(t, i, "pose_add") ||
                           (j == i + 1 && t[i].kind == Tok::Kind::kIdent && vars_.count(t[i].s) && vars_.at(t[i].s).kind == Var::Kind::kPose);
    if (i >= j)  // (nothing after the '=' on its line; nothing at all after it: a file cut short)
      fail(t[s + 1].b, std::string("expected a value after '=', found the end of the ") +
                           (src_->text.find_first_not_of(" \t\r\n", t[s + 1].e) == std::string::npos ? "file" : "statement"));
    if (mentions(t, i, j, name) && (pose_like || was_model)) {
      v.problem = "'" + excerpt(name) + "' is changed at run time at " + loc(t[s].b).str() + " (" + quoted(t, s, j) + ")";
      other(t);
    } else if (pose_like) {
      v.kind = Var::Kind::kPose;
      v.pose = pose(t, i, j);
      if (!v.pose.problem.empty()) other(t);
    } else if (isOp(t, i, "[") && closing(t, i) == j && items(t, i + 1, j - 1).size() == 6) {
      std::string problem;
      const auto q = joints(t, i, j, &problem);
      if (q) {
        v.kind = Var::Kind::kJoints;
        v.q = *q;
      } else {
        v.problem = problem;
        other(t);
      }
    } else {
      v.problem = "'" + excerpt(name) + "' is assigned '" + quoted(t, i, j) + "' at " + loc(t[s].b).str() + ", which accura cannot evaluate";
      other(t);
    }
    vars_[name] = v;
  }

  void setTcp(const std::vector<Tok>& t) {
    for (OpenBlock& b : blocks_) b.sets_tcp = true;
    const auto args = items(t, 2, t.size() - 1);
    const size_t given = args.empty() || (args.size() == 1 && args[0].first == args[0].second) ? 0 : args.size();
    if (given != 1) fail(t[0].b, "expected set_tcp(pose) with 1 argument, found " + std::to_string(given));
    const PoseVal v = pose(t, args[0].first, args[0].second);
    FrameSetting f;
    f.where = loc(t[0].b);
    f.text = textOf(t, args[0].first, args[0].second);
    if (v.problem.empty()) {
      f.source = FrameSetting::Source::kInline;
      f.value = calib::toXyzAbc(evaluate(*src_, v.expr));
    } else {
      f.source = FrameSetting::Source::kUnknown;
      f.note = v.problem;
      f.run_time = true;  // the controller computes it (a variable, get_tcp_offset(), ...)
    }
    tool_ = f;
  }

  Target target(const std::vector<Tok>& t, size_t i, size_t j, const PoseVal& v) {
    Target tg;
    tg.kind = Target::Kind::kCartesian;
    tg.where = loc(t[i].b);
    if (!(isIdent(t, i, "p") && isOp(t, i + 1, "["))) tg.name = textOf(t, i, j);
    if (v.problem.empty()) {
      tg.setPose(calib::toXyzAbc(evaluate(*src_, v.expr)));
      tg.value_id = v.literal;
    }
    return tg;
  }

  void motion(const std::vector<Tok>& t, Program& p) {
    const std::string f = t[0].s;
    static const std::map<std::string, std::vector<std::string>> params = {
        {"movel", {"pose", "a", "v", "t", "r"}},
        {"movep", {"pose", "a", "v", "r"}},
        {"movej", {"q", "a", "v", "t", "r"}},
        {"movec", {"pose_via", "pose_to", "a", "v", "r", "mode"}}};
    refs_.clear();
    const std::map<std::string, std::pair<size_t, size_t>> arg = arguments(t, items(t, 2, t.size() - 1), 0, params.at(f), f);
    Motion m;
    m.where = loc(t[0].b);
    m.statement = textOf(t, 0, t.size());
    m.tool = tool_;
    m.base = base_;
    m.type = f == "movej" ? MotionType::kPtp : f == "movec" ? MotionType::kCirc : MotionType::kLin;
    UrScriptSource::Statement st = statementOf(t, m.where);
    auto number_arg = [&](const std::string& n, double lo, double hi, const char* what) -> std::optional<double> {
      const auto it = arg.find(n);
      if (it == arg.end()) return std::nullopt;
      const std::optional<double> x = number(t, it->second.first, it->second.second);
      if (x && !(*x >= lo && *x <= hi))
        fail(t[it->second.first].b, "expected " + std::string(what) + ", found " + quoted(t, it->second.first, it->second.second));
      return x;
    };
    number_arg("a", 0, 1e3, "an acceleration in [0, 1000]");
    if (const std::optional<double> time_s = number_arg("t", 0, 1e6, "a time in [0, 1e6] s"); time_s && *time_s > 0) {
      const std::pair<size_t, size_t> r = arg.at("t");
      st.duration_text = {t[r.first].b, t[r.second - 1].e};
      st.duration_s = *time_s;
      m.duration_s = *time_s;
    } else if (!time_s && arg.count("t")) {
      m.duration_expr = textOf(t, arg.at("t").first, arg.at("t").second);  // (t=tm: the controller's)
    }
    if (f == "movej") {
      number_arg("v", 0, 1e3, "a joint speed in [0, 1000] rad/s");
    } else {
      m.vel_m_s = number_arg("v", 1e-9, 100, "a tool speed > 0 and <= 100 m/s");
    }
    if (arg.count("r")) {
      const std::optional<double> r = number_arg("r", 0, 10, "a blend radius in [0, 10] m");
      if (!r || *r > 0) {
        m.approximation = {Approximation::kCDis};
        if (r) m.approximation_value = *r * 1000.0;
      }
    }
    const std::optional<double> mode = number_arg("mode", 0, 1, "mode 0 or 1");
    if (mode && *mode != 0 && *mode != 1) fail(t[arg.at("mode").first].b, "expected mode 0 or 1, found " + calib::formatFixed(*mode, 4));
    auto need = [&](const std::string& n) -> std::pair<size_t, size_t> {
      const auto it = arg.find(n);
      if (it == arg.end()) fail(t[0].b, "expected the argument '" + n + "' of " + f + ", found none");
      return it->second;
    };
    auto cartesian = [&](std::pair<size_t, size_t> r) -> Target {
      const PoseVal v = pose(t, r.first, r.second);
      if (!v.problem.empty() && m.target_problem.empty()) m.target_problem = v.problem;
      st.targets.push_back({t[r.first].b, t[r.second - 1].e});
      st.target_expr.push_back(v.problem.empty() ? v.expr : -1);
      return target(t, r.first, r.second, v);
    };
    if (f == "movec") {
      m.aux = cartesian(need("pose_via"));
      m.target = cartesian(need("pose_to"));
      if (mode && *mode == 1 && m.target_problem.empty())
        m.target_problem = "movec with mode=1 (orientation fixed to the arc's tangent), which accura does not model";
    } else if (f == "movej") {
      const auto r = need("q");
      const size_t a = r.first, b = r.second;
      if (isIdent(t, a, "get_inverse_kin") && isOp(t, a + 1, "(") && closing(t, a + 1) == b) {
        const auto gi = items(t, a + 2, b - 1);
        if (gi.empty() || gi[0].first == gi[0].second) fail(t[a].b, "expected get_inverse_kin(pose, ...), found no pose");
        m.target = cartesian(gi[0]);
        inverseKinArguments(t, gi, m);
      } else if (looksLikeJoints(t, a, b)) {
        std::string problem;
        const auto q = joints(t, a, b, &problem);
        m.target.kind = Target::Kind::kAxis;
        m.target.where = loc(t[a].b);
        if (!isOp(t, a, "[")) m.target.name = textOf(t, a, b);
        if (q) {
          for (int k = 0; k < 6; ++k) m.target.axes[static_cast<size_t>(k)] = (*q)[static_cast<size_t>(k)] * calib::kRadToDeg;
        } else {
          m.target_problem = problem;
        }
        st.targets.push_back({t[a].b, t[b - 1].e});
        st.target_expr.push_back(-1);
      } else {
        m.target = cartesian(r);
      }
    } else {
      const auto r = need("pose");
      if (looksLikeJoints(t, r.first, r.second)) {
        m.target.where = loc(t[r.first].b);
        m.target.name = textOf(t, r.first, r.second);
        m.target_problem = "joint positions given to " + f +
                           " (the controller moves to their forward kinematics): write the target as a pose p[...] to compensate it";
        st.targets.push_back({t[r.first].b, t[r.second - 1].e});
        st.target_expr.push_back(-1);
      } else {
        m.target = cartesian(r);
      }
    }
    for (const std::string& v : refs_) uses_.push_back({p.motions.size(), v, openLoops()});
    m.start_unknown = flow_.motion();
    m.statement_id = static_cast<int>(src_->statements.size());
    src_->statements.push_back(st);
    p.motions.push_back(m);
  }

  /// The span of the motion statement `t` (at `where`) in the text, and its line end.
  UrScriptSource::Statement statementOf(const std::vector<Tok>& t, const SourceLocation& where) const {
    UrScriptSource::Statement st;
    st.code_begin = t.front().b;
    st.code_end = t.back().e;
    st.line_begin = line_starts_[static_cast<size_t>(where.line - 1)];
    const size_t nl = src_->text.find('\n', st.code_end);
    st.eol = nl == std::string::npos ? "" : (nl > 0 && src_->text[nl - 1] == '\r' ? "\r\n" : "\n");
    return st;
  }

  /// servoc, a Cartesian motion accura does not model: kept as written and named in a warning
  /// (Motion::target_problem); where it leaves the robot is not known.
  void otherMotion(const std::vector<Tok>& t, Program& p) {
    Motion m;
    m.where = loc(t[0].b);
    m.statement = textOf(t, 0, t.size());
    m.tool = tool_;
    m.base = base_;
    m.type = MotionType::kLin;
    m.target.where = m.where;
    m.target_problem = t[0].s + " is a motion accura does not model (it compensates movel, movej, movep and movec)";
    UrScriptSource::Statement st = statementOf(t, m.where);
    m.start_unknown = flow_.motion();
    m.statement_id = static_cast<int>(src_->statements.size());
    src_->statements.push_back(st);
    p.motions.push_back(m);
    flow_.unknown();
  }

  std::shared_ptr<UrScriptSource> src_;
  std::vector<size_t> line_starts_;
  std::vector<Tok> toks_;
  std::map<std::string, Var> vars_;
  FrameSetting tool_, base_;
  std::string main_name_;
  bool main_open_ = false;
  std::set<std::string> defs_;  ///< the script's functions that move the robot
  StartTracker flow_;           ///< where the robot comes from (Motion::start_unknown)
  /// An open block (def, thread, if, while).
  struct OpenBlock {
    StartTracker::Block kind = StartTracker::Block::kRoutine;
    bool program = false;  ///< the program's own def
    int loop = 0;          ///< a loop id (while), else 0
    size_t at = 0;         ///< where it starts
    std::string name;      ///< a def's or thread's name
    std::string head;      ///< the word that opens it: def, thread, if, while
    FrameSetting tool;     ///< the tool when it was entered
    bool tool_changed = false;  ///< a branch before the current one changed the tool
    std::map<std::string, Var> vars;      ///< the variables when it was entered
    std::set<std::string> vars_changed;   ///< assigned by a branch before the current one
    std::set<std::string> locals, globals;  ///< names declared local / global in it
    std::set<std::string> assigned;         ///< names assigned in it (functions)
    bool sets_tcp = false;                  ///< set_tcp is called in it (functions)
    std::set<std::string> calls;            ///< the names called in it (functions)
    size_t first_motion = 0;                ///< the first motion in it
  };
  static bool sameVar(const Var& a, const Var& b) {
    return a.kind == b.kind && a.problem == b.problem && a.pose.expr == b.pose.expr && a.pose.problem == b.pose.problem && a.q == b.q;
  }
  /// The variables whose value differs from `entry` (or that it does not hold).
  std::set<std::string> changedVariables(const std::map<std::string, Var>& entry) const {
    std::set<std::string> out;
    for (const auto& [n, v] : vars_) {
      const auto it = entry.find(n);
      if (it == entry.end() || !sameVar(v, it->second)) out.insert(n);
    }
    return out;
  }
  /// At a block's end: a variable a branch or a loop assigned is, after it, whichever value the
  /// run took; a function's (or thread's) assignments run where it is called: the text after
  /// its end has the values from before it, and a call makes the program variables it assigns
  /// unknown (its locals, and names first assigned in it, stay its own).
  void endVariables(const OpenBlock& b) {
    if (b.program) return;
    std::set<std::string> changed = changedVariables(b.vars);
    changed.insert(b.vars_changed.begin(), b.vars_changed.end());
    if (b.kind == StartTracker::Block::kRoutine) {
      for (const std::string& n : b.assigned)
        if (((b.vars.count(n) || program_vars_.count(n)) && !b.locals.count(n)) || b.globals.count(n))
          fn_assigns_[b.name].emplace(n, loc(b.at));
      vars_ = b.vars;
      return;
    }
    for (const std::string& n : changed) {
      Var v;
      v.problem = "'" + excerpt(n) + "' is assigned inside the " + (b.kind == StartTracker::Block::kBranch ? "if" : "while") + " at " +
                  loc(b.at).str() + ": after it, its value depends on the way the program ran";
      vars_[n] = v;
    }
  }
  std::set<std::string> program_vars_;  ///< the names the program's own body assigns
  /// The program variables each function or thread of the script assigns (and where it starts).
  std::map<std::string, std::map<std::string, SourceLocation>> fn_assigns_;
  std::map<std::string, SourceLocation> tcp_setters_;  ///< the script's functions that call set_tcp
  std::map<std::string, std::set<std::string>> fn_calls_;  ///< the names each function of the script calls
  std::vector<OpenBlock> blocks_;
  int loops_ = 0;
  struct Use {
    size_t motion;
    std::string var;
    std::vector<int> loops;
  };
  std::vector<Use> uses_;          ///< variables the motions' targets read
  std::vector<std::string> refs_;  ///< variables read by the motion being parsed
  /// pose_trans/pose_add nested in the pose being read: at most kMaxPoseNesting.
  int pose_depth_ = 0;
  static constexpr int kMaxPoseNesting = 100;
  std::vector<int> expr_depth_;  ///< per expression of src_->exprs: its depth (addExpr)
  static constexpr int kMaxExprDepth = 1000;
};

}  // namespace

Program parseUrScript(const std::string& text, const std::string& path) { return Reader(text, path).run(); }

Program readUrScript(const std::string& path) {
  if (const std::string problem = calib::notAFileProblem(path); !problem.empty())
    throw calib::InputError(path, 0, 0, "cannot read the URScript program: " + problem);
  std::ifstream f(path, std::ios::binary);
  if (!f) throw calib::InputError(path, 0, 0, "cannot read the URScript program");
  std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (f.bad()) throw calib::InputError(path, 0, 0, "cannot read the URScript program");
  return parseUrScript(text, path);
}

}  // namespace accura::postproc
