// KRL reading internals shared by the lexer (krl_lexer.cpp), the data part (krl_data.cpp:
// targets, frames, declarations of the .dat and $config.dat), the reader of the .src
// (krl_reader.cpp) and the writer (krl_writer.cpp). Not installed: see krl.h for the API.
#pragma once

#include <algorithm>
#include <cstddef>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "accura/calib/errors.h"
#include "accura/postproc/krl.h"

namespace accura::postproc::krl_detail {

/// Upper case (ASCII).
std::string upper(std::string s);
/// ;FOLD / ;ENDFOLD (any case, after blanks): the KUKA editor's structure, which it pairs; not a
/// statement (an inline form's fold holds the motion the model writes anew) nor a comment.
bool isFoldMarker(const std::string& line);

// ---------------------------------------------------------------------------------------------
// Control structures (krl_lexer.cpp): for the reader's structure check and flow tracking
// (krl_reader.cpp) and the pass-through statements' flow roles (program_io.cpp)

/// A KRL block: the word that opens it, the word that closes it, and what it is. A branch or a
/// loop steers the run; a spline block (SPLINE / PTP_SPLINE .. ENDSPLINE) holds motions only.
struct BlockWords {
  enum Kind { kBranch, kLoop, kSpline };
  const char* open;
  const char* close;
  Kind kind;
};
inline constexpr BlockWords kBlocks[] = {
    {"IF", "ENDIF", BlockWords::kBranch},       {"SWITCH", "ENDSWITCH", BlockWords::kBranch},
    {"FOR", "ENDFOR", BlockWords::kLoop},       {"WHILE", "ENDWHILE", BlockWords::kLoop},
    {"LOOP", "ENDLOOP", BlockWords::kLoop},     {"REPEAT", "UNTIL", BlockWords::kLoop},
    {"SPLINE", "ENDSPLINE", BlockWords::kSpline}, {"PTP_SPLINE", "ENDSPLINE", BlockWords::kSpline}};
/// The words that start another branch of the open block: ELSE an IF's, CASE and DEFAULT a SWITCH's.
inline constexpr const char* kBranchWords[] = {"ELSE", "CASE", "DEFAULT"};
/// The words that jump.
inline constexpr const char* kJumpWords[] = {"GOTO", "RETURN", "EXIT"};

/// The block the (upper-case) word `up` opens, null when it opens none.
const BlockWords* blockOpenedBy(const std::string& up);
/// The block `up` closes (ENDSPLINE: the first spline block, it closes either), null when none.
const BlockWords* blockClosedBy(const std::string& up);
/// `up` is one of kBranchWords.
bool startsBranch(const std::string& up);
/// `up` is one of kJumpWords.
bool isJump(const std::string& up);

// ---------------------------------------------------------------------------------------------
// Files and lines (krl_lexer.cpp)

struct Line {
  size_t begin = 0;        // first byte
  size_t content_end = 0;  // before the line end
  size_t code_end = 0;     // before a comment (';'), trailing blanks removed
  std::string eol;
  int number = 0;          // 1-based
};

/// The bytes of a KRL text file (InputError when missing, unreadable or binary).
std::string readFileBytes(const std::string& path, const std::string& what);

class KrlFile {
 public:
  KrlFile(std::string path, std::string text, int index) : path_(std::move(path)), text_(std::move(text)), index_(index) {
    size_t pos = 0;
    int number = 1;
    while (pos < text_.size()) {
      Line l;
      l.begin = pos;
      l.number = number++;
      const size_t nl = text_.find('\n', pos);
      if (nl == std::string::npos) {
        l.content_end = text_.size();
        l.eol = "";
        pos = text_.size();
      } else {
        l.content_end = (nl > pos && text_[nl - 1] == '\r') ? nl - 1 : nl;
        l.eol = text_.substr(l.content_end, nl + 1 - l.content_end);
        pos = nl + 1;
      }
      l.code_end = findCodeEnd(l);
      lines_.push_back(l);
    }
  }

  const std::string& path() const { return path_; }
  const std::string& text() const { return text_; }
  int index() const { return index_; }
  const std::vector<Line>& lines() const { return lines_; }

  SourceLocation loc(size_t offset) const {
    // the line containing offset
    size_t lo = 0, hi = lines_.size();
    while (hi - lo > 1) {
      const size_t mid = (lo + hi) / 2;
      if (lines_[mid].begin <= offset) lo = mid; else hi = mid;
    }
    SourceLocation s;
    s.file = path_;
    if (lines_.empty()) {  // an empty file: its start
      s.line = 1;
      s.column = 1;
      return s;
    }
    s.line = lines_[lo].number;
    // (the end of a file that ends with a line end: its last line, after its text)
    s.column = static_cast<int>(std::min(offset, lines_[lo].content_end) - lines_[lo].begin) + 1;
    return s;
  }

  /// An InputError at offset. A statement, string or literal cut off by the end of the file
  /// (the error lies on a last line without a line end: a file cut short) found the end of the
  /// file, not the end of a statement or a line: the message says so.
  [[noreturn]] void fail(size_t offset, const std::string& msg) const {
    const SourceLocation s = loc(offset);
    std::string m = msg;
    if (!lines_.empty() && lines_.back().eol.empty() && offset >= lines_.back().begin)
      for (const char* cut : {"found the end of the statement", "found the end of the line"})
        if (const size_t at = m.rfind(cut); at != std::string::npos && at + std::string(cut).size() == m.size())
          m = m.substr(0, at) + "found the end of the file";
    throw calib::InputError(s.file, s.line, s.column, m);
  }

 private:
  size_t findCodeEnd(const Line& l) const {
    bool in_string = false;
    size_t end = l.content_end;
    for (size_t i = l.begin; i < l.content_end; ++i) {
      const char c = text_[i];
      if (in_string) {
        if (c == '"') in_string = false;
        continue;
      }
      if (c == '"') {
        in_string = true;
      } else if (c == '\'') {
        const size_t close = text_.find('\'', i + 1);
        if (close != std::string::npos && close < l.content_end) i = close;
      } else if (c == ';') {
        end = i;
        break;
      }
    }
    while (end > l.begin && (text_[end - 1] == ' ' || text_[end - 1] == '\t' || text_[end - 1] == '\r')) --end;
    return end;
  }

  std::string path_;
  std::string text_;
  int index_;
  std::vector<Line> lines_;
};

// ---------------------------------------------------------------------------------------------
// Tokens and aggregates (krl_lexer.cpp)

struct Tok {
  enum Kind { kIdent, kNumber, kString, kChar, kEnum, kPunct };
  Kind kind = kPunct;
  std::string text;
  std::string up;
  size_t begin = 0, end = 0;
};

/// The tokens of f's text in [begin, end).
std::vector<Tok> lex(const KrlFile& f, size_t begin, size_t end);
/// "'text'", or "the end of the statement" for null.
std::string describe(const Tok* t);

class Cursor {
 public:
  Cursor(const KrlFile& f, const std::vector<Tok>& toks, size_t line_end) : f_(f), t_(toks), line_end_(line_end) {}
  const Tok* peek(size_t k = 0) const { return i_ + k < t_.size() ? &t_[i_ + k] : nullptr; }
  bool atEnd() const { return i_ >= t_.size(); }
  const Tok& next() {
    if (atEnd()) fail("expected more, found the end of the statement");
    return t_[i_++];
  }
  bool isPunct(const char* p, size_t k = 0) const {
    const Tok* t = peek(k);
    return t && t->kind == Tok::kPunct && t->text == p;
  }
  bool isIdent(const char* up, size_t k = 0) const {
    const Tok* t = peek(k);
    return t && t->kind == Tok::kIdent && t->up == up;
  }
  bool acceptPunct(const char* p) {
    if (isPunct(p)) {
      ++i_;
      return true;
    }
    return false;
  }
  void expectPunct(const char* p, const std::string& context) {
    if (!acceptPunct(p)) fail(std::string("expected '") + p + "' " + context + ", found " + describe(peek()));
  }
  [[noreturn]] void fail(const std::string& msg) const { f_.fail(atEnd() ? line_end_ : t_[i_].begin, msg); }
  [[noreturn]] void failAt(const Tok& t, const std::string& msg) const { f_.fail(t.begin, msg); }
  size_t pos() const { return i_; }
  void seek(size_t i) { i_ = i; }
  const std::vector<Tok>& tokens() const { return t_; }
  const KrlFile& file() const { return f_; }

 private:
  const KrlFile& f_;
  const std::vector<Tok>& t_;
  size_t i_ = 0;
  size_t line_end_;
};

// ---------------------------------------------------------------------------------------------
// Aggregates: {[TYPE:] NAME value, NAME value, ...}

struct Agg;
struct AggItem {
  enum VK { kNum, kEnum, kBool, kString, kChar, kAgg, kIdent };
  std::string name;  // upper case
  Tok name_tok;
  VK vk = kNum;
  double num = 0;
  bool is_integer_literal = false;
  std::string text;  // value text
  size_t vbegin = 0, vend = 0;
  std::shared_ptr<Agg> agg;
};

struct Agg {
  std::string type;  // upper case, "" when untyped
  size_t begin = 0, end = 0;
  std::vector<AggItem> items;
};

/// {[TYPE:] NAME value, NAME value, ...} at the cursor.
Agg parseAggregate(Cursor& c);

// ---------------------------------------------------------------------------------------------
// Targets, frames and declarations (krl_data.cpp)

inline const char* const kCartNames[] = {"X", "Y", "Z", "A", "B", "C"};
inline const char* const kAxisNames[] = {"A1", "A2", "A3", "A4", "A5", "A6"};
inline const char* const kExtNames[] = {"E1", "E2", "E3", "E4", "E5", "E6"};

/// E6POS, POS, FRAME, E6AXIS, AXIS.
bool isPointType(const std::string& up);
/// Index of n in names[0..5], -1 when absent.
int indexOf(const char* const names[], const std::string& n);
/// The target of an aggregate declared as `declared` (its text spans recorded in src).
Target toTarget(const Agg& a, const std::string& declared, const KrlFile& f, KrlSource* src);
/// The frame of an aggregate; components it leaves out from `previous` (*partial set).
std::optional<calib::XyzAbc> toFrame(const Agg& a, const KrlFile& f, const std::optional<calib::XyzAbc>& previous, bool* partial);

struct PointEntry {
  std::string name;  // as declared
  std::string type;
  std::optional<Target> value;
  std::string problem;  // why the value cannot be used (changed at run time, ...)
  SourceLocation declared;
  bool global = false;  // from $config.dat
  bool config = false;  // declared in the $config.dat (also after the program assigns it a value)
  bool global_keyword = false;  // declared GLOBAL (other modules may use it)
};

struct Fdat {
  std::optional<int> tool_no, base_no;
  bool external_tcp = false;
  SourceLocation where;
};

struct MoveData {  // LDAT / PDAT
  std::optional<double> vel;       // m/s (LDAT), percent (PDAT)
  std::optional<double> apo_dist;  // mm (C_DIS), percent (C_PTP)
  std::string ori_typ;             // LDAT: ORI_TYP (#VAR, #CONSTANT, #JOINT; upper case), "" not given
  std::string circ_typ;            // LDAT: CIRC_TYP (#BASE, #PATH; upper case), "" not given
};

/// A point array (DECL E6POS XPA[10]): its elements given a value in a data list
/// (XPA[1]={X ..}) are points of their own in Declarations::points, named "XPA[1]".
struct ArrayEntry {
  std::string name;  // as declared
  std::string type;  // E6POS, POS, FRAME, E6AXIS, AXIS
  SourceLocation declared;
  bool global_keyword = false;  // DECL GLOBAL: its elements are global points
};

struct Declarations {
  std::map<std::string, PointEntry> points;  // upper-case names; array elements as "XPA[1]"
  std::map<std::string, ArrayEntry> arrays;  // upper-case names
  std::map<std::string, Fdat> fdats;
  std::map<std::string, MoveData> ldats, pdats;
  FrameTables tables;
  /// The program's data list's name (DEFDAT name) as written, and where the name is.
  std::string defdat_name;
  SourceLocation defdat_where;
};

/// A literal number (with an optional sign) in toks[b, e), else nullopt.
std::optional<double> numberValue(const std::vector<Tok>& toks, size_t b, size_t e);
std::optional<int> integerValue(const std::vector<Tok>& toks, size_t b, size_t e);
std::optional<calib::XyzAbc> tableValue(const std::vector<std::optional<calib::XyzAbc>>& table, int n);
Fdat toFdat(const Agg& a, const KrlFile& f);
/// DECL ... at the cursor.
void parseDeclaration(Cursor& c, Declarations& d, KrlSource* src, bool global);
/// TOOL_DATA[n] = / BASE_DATA[n] = at the cursor; false when it is not one.
bool parseTableAssignment(Cursor& c, Declarations& d);
/// The name and upper-case key of element `index` of the point array `a`: "XPA[1]".
std::string arrayElementName(const ArrayEntry& a, int index);
/// NAME[n] = {...} at the cursor, NAME a point array of `d`: the element's value, a point of
/// its own (its text spans recorded in src unless it is global); false when it is not one.
bool parseArrayElement(Cursor& c, Declarations& d, KrlSource* src, bool global);
/// Every declaration of a .dat or $config.dat.
void parseDataFile(const KrlFile& f, Declarations& d, KrlSource* src, bool global);

}  // namespace accura::postproc::krl_detail
