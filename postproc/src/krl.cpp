// KUKA KRL reader and writer (see krl.h and docs/program-formats.md).
#include "accura/postproc/krl.h"

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

namespace fs = std::filesystem;

namespace accura::postproc {
namespace {

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

// ---------------------------------------------------------------------------------------------
// Files and lines

struct Line {
  size_t begin = 0;        // first byte
  size_t content_end = 0;  // before the line end
  size_t code_end = 0;     // before a comment (';'), trailing blanks removed
  std::string eol;
  int number = 0;          // 1-based
};

std::string readFileBytes(const std::string& path, const std::string& what) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError(path, 0, 0, "cannot read " + what + ": no such file");
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(path, 0, 0, "cannot read " + what);
  std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (f.bad()) throw InputError(path, 0, 0, "cannot read " + what);
  const size_t nul = text.find('\0');
  if (nul != std::string::npos) {
    int line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(nul), '\n'));
    throw InputError(path, line, 0, "expected a KRL text file, found a NUL byte (binary file?)");
  }
  return text;
}

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
    if (lines_.empty()) return s;
    s.line = lines_[lo].number;
    s.column = static_cast<int>(offset - lines_[lo].begin) + 1;
    return s;
  }

  [[noreturn]] void fail(size_t offset, const std::string& msg) const {
    const SourceLocation s = loc(offset);
    throw InputError(s.file, s.line, s.column, msg);
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
// Tokens

struct Tok {
  enum Kind { kIdent, kNumber, kString, kChar, kEnum, kPunct };
  Kind kind = kPunct;
  std::string text;
  std::string up;
  size_t begin = 0, end = 0;
};

bool identStart(char c) { return std::isalpha(static_cast<unsigned char>(c)) || c == '_' || c == '$'; }
bool identChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '$'; }

std::vector<Tok> lex(const KrlFile& f, size_t begin, size_t end) {
  const std::string& s = f.text();
  std::vector<Tok> out;
  size_t i = begin;
  while (i < end) {
    const char c = s[i];
    if (c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v') {
      ++i;
      continue;
    }
    Tok t;
    t.begin = i;
    if (identStart(c)) {
      size_t j = i + 1;
      while (j < end && identChar(s[j])) ++j;
      t.kind = Tok::kIdent;
      t.text = s.substr(i, j - i);
      i = j;
    } else if (std::isdigit(static_cast<unsigned char>(c)) ||
               (c == '.' && i + 1 < end && std::isdigit(static_cast<unsigned char>(s[i + 1])))) {
      size_t j = i;
      while (j < end && std::isdigit(static_cast<unsigned char>(s[j]))) ++j;
      if (j < end && s[j] == '.') {
        ++j;
        while (j < end && std::isdigit(static_cast<unsigned char>(s[j]))) ++j;
      }
      if (j < end && (s[j] == 'e' || s[j] == 'E')) {
        size_t k = j + 1;
        if (k < end && (s[k] == '+' || s[k] == '-')) ++k;
        if (k < end && std::isdigit(static_cast<unsigned char>(s[k]))) {
          while (k < end && std::isdigit(static_cast<unsigned char>(s[k]))) ++k;
          j = k;
        }
      }
      t.kind = Tok::kNumber;
      t.text = s.substr(i, j - i);
      i = j;
    } else if (c == '"') {
      const size_t close = s.find('"', i + 1);
      if (close == std::string::npos || close >= end) f.fail(i, "expected a closing '\"' for this string, found the end of the line");
      t.kind = Tok::kString;
      t.text = s.substr(i, close + 1 - i);
      i = close + 1;
    } else if (c == '\'') {
      const size_t close = s.find('\'', i + 1);
      if (close == std::string::npos || close >= end) f.fail(i, "expected a closing ' for this literal, found the end of the line");
      t.kind = Tok::kChar;
      t.text = s.substr(i, close + 1 - i);
      i = close + 1;
    } else if (c == '#' && i + 1 < end && identStart(s[i + 1])) {
      size_t j = i + 2;
      while (j < end && identChar(s[j])) ++j;
      t.kind = Tok::kEnum;
      t.text = s.substr(i, j - i);
      i = j;
    } else {
      t.kind = Tok::kPunct;
      static const char* two[] = {"==", "<>", ">=", "<="};
      bool matched = false;
      for (const char* op : two) {
        if (i + 1 < end && s[i] == op[0] && s[i + 1] == op[1]) {
          t.text = op;
          i += 2;
          matched = true;
          break;
        }
      }
      if (!matched) {
        t.text = std::string(1, c);
        ++i;
      }
    }
    t.end = i;
    t.up = upper(t.text);
    out.push_back(std::move(t));
  }
  return out;
}

std::string describe(const Tok* t) {
  if (!t) return "the end of the statement";
  return "'" + t->text + "'";
}

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

bool parseCharLiteral(const std::string& text, double* value) {
  // 'B0101' binary or 'H1F' hexadecimal
  if (text.size() < 4) return false;
  const char kind = static_cast<char>(std::toupper(static_cast<unsigned char>(text[1])));
  const std::string digits = text.substr(2, text.size() - 3);
  if (digits.empty()) return false;
  int base = kind == 'B' ? 2 : kind == 'H' ? 16 : 0;
  if (!base) return false;
  char* e = nullptr;
  const long v = std::strtol(digits.c_str(), &e, base);
  if (!e || *e != '\0') return false;
  *value = static_cast<double>(v);
  return true;
}

Agg parseAggregate(Cursor& c) {
  Agg a;
  const Tok* open = c.peek();
  if (!open || open->text != "{") c.fail("expected an aggregate '{...}', found " + describe(open));
  a.begin = open->begin;
  c.next();
  if (c.peek() && c.peek()->kind == Tok::kIdent && c.isPunct(":", 1)) {
    a.type = c.peek()->up;
    c.next();
    c.next();
  }
  if (c.isPunct("}")) {
    a.end = c.next().end;
    return a;
  }
  while (true) {
    const Tok* nt = c.peek();
    if (!nt || nt->kind != Tok::kIdent) c.fail("expected a component name in the aggregate, found " + describe(nt));
    AggItem item;
    item.name_tok = *nt;
    item.name = nt->up;
    c.next();
    if (c.isPunct("[") && c.isPunct("]", 1)) {
      c.next();
      c.next();
    }
    const Tok* vt = c.peek();
    if (!vt) c.fail("expected a value for " + item.name_tok.text + ", found the end of the statement");
    item.vbegin = vt->begin;
    if (vt->text == "{") {
      item.vk = AggItem::kAgg;
      item.agg = std::make_shared<Agg>(parseAggregate(c));
      item.vend = item.agg->end;
    } else if ((vt->text == "-" || vt->text == "+") && vt->kind == Tok::kPunct) {
      const bool neg = vt->text == "-";
      c.next();
      const Tok* n = c.peek();
      if (!n || n->kind != Tok::kNumber) c.fail("expected a number after '" + vt->text + "' for " + item.name_tok.text + ", found " + describe(n));
      item.vk = AggItem::kNum;
      item.num = std::strtod(n->text.c_str(), nullptr) * (neg ? -1 : 1);
      item.is_integer_literal = n->text.find_first_of(".eE") == std::string::npos;
      item.vend = n->end;
      c.next();
    } else if (vt->kind == Tok::kNumber) {
      item.vk = AggItem::kNum;
      item.num = std::strtod(vt->text.c_str(), nullptr);
      item.is_integer_literal = vt->text.find_first_of(".eE") == std::string::npos;
      item.vend = vt->end;
      c.next();
    } else if (vt->kind == Tok::kEnum) {
      item.vk = AggItem::kEnum;
      item.vend = vt->end;
      c.next();
    } else if (vt->kind == Tok::kString) {
      item.vk = AggItem::kString;
      item.vend = vt->end;
      c.next();
    } else if (vt->kind == Tok::kChar) {
      item.vk = AggItem::kChar;
      item.vend = vt->end;
      double v = 0;
      if (parseCharLiteral(vt->text, &v)) {
        item.num = v;
        item.is_integer_literal = true;
      }
      c.next();
    } else if (vt->kind == Tok::kIdent && (vt->up == "TRUE" || vt->up == "FALSE")) {
      item.vk = AggItem::kBool;
      item.vend = vt->end;
      c.next();
    } else if (vt->kind == Tok::kIdent) {
      item.vk = AggItem::kIdent;
      item.vend = vt->end;
      c.next();
    } else {
      c.fail("expected a value for " + item.name_tok.text + ", found " + describe(vt));
    }
    item.text = c.file().text().substr(item.vbegin, item.vend - item.vbegin);
    a.items.push_back(std::move(item));
    if (c.isPunct(",")) {
      c.next();
      continue;
    }
    if (c.isPunct("}")) {
      a.end = c.next().end;
      return a;
    }
    c.fail("expected ',' or '}' after the value of " + a.items.back().name_tok.text + ", found " + describe(c.peek()));
  }
}

// ---------------------------------------------------------------------------------------------
// Targets

const char* const kCartNames[] = {"X", "Y", "Z", "A", "B", "C"};
const char* const kAxisNames[] = {"A1", "A2", "A3", "A4", "A5", "A6"};
const char* const kExtNames[] = {"E1", "E2", "E3", "E4", "E5", "E6"};

bool isPointType(const std::string& up) {
  return up == "E6POS" || up == "POS" || up == "FRAME" || up == "E6AXIS" || up == "AXIS";
}
bool isAxisType(const std::string& up) { return up == "E6AXIS" || up == "AXIS"; }

int indexOf(const char* const names[], const std::string& n) {
  for (int i = 0; i < 6; ++i)
    if (n == names[i]) return i;
  return -1;
}

std::string allowedList(const std::string& type, bool axis) {
  if (axis) return type == "AXIS" ? "A1..A6" : "A1..A6, E1..E6";
  if (type == "FRAME") return "X, Y, Z, A, B, C";
  if (type == "POS") return "X, Y, Z, A, B, C, S, T";
  return "X, Y, Z, A, B, C, S, T, E1..E6";
}

// Converts an aggregate to a target. `declared`: the declared type ("" for an inline target).
Target toTarget(const Agg& a, const std::string& declared, const KrlFile& f, KrlSource* src) {
  std::string type = a.type.empty() ? declared : a.type;
  if (!a.type.empty() && !isPointType(a.type))
    f.fail(a.begin, "expected a target aggregate of type E6POS, POS, FRAME, E6AXIS or AXIS, found type " + a.type);
  if (!a.type.empty() && !declared.empty() && isAxisType(a.type) != isAxisType(declared))
    f.fail(a.begin, "expected a " + declared + " aggregate, found a " + a.type + " aggregate");
  if (a.items.empty()) f.fail(a.begin, "expected the components of a target, found an empty aggregate '{}'");
  bool axis;
  if (!type.empty()) {
    axis = isAxisType(type);
  } else {
    bool any_axis = false, any_cart = false;
    for (const auto& it : a.items) {
      if (indexOf(kAxisNames, it.name) >= 0) any_axis = true;
      if (indexOf(kCartNames, it.name) >= 0 || it.name == "S" || it.name == "T") any_cart = true;
    }
    if (any_axis && any_cart)
      f.fail(a.begin, "expected either a Cartesian target (X, Y, Z, A, B, C) or an axis target (A1..A6), found components of both");
    axis = any_axis;
  }
  Target t;
  t.kind = axis ? Target::Kind::kAxis : Target::Kind::kCartesian;
  t.type = type;
  t.where = f.loc(a.begin);
  KrlSource::Value value;
  value.file = f.index();
  value.begin = a.begin;
  value.end = a.end;
  std::set<std::string> seen;
  for (const auto& it : a.items) {
    if (!seen.insert(it.name).second)
      f.fail(it.name_tok.begin, "component " + it.name_tok.text + " given twice in this aggregate");
    int k;
    bool ok = false;
    if (axis) {
      if ((k = indexOf(kAxisNames, it.name)) >= 0) {
        ok = true;
      } else if ((k = indexOf(kExtNames, it.name)) >= 0 && type != "AXIS") {
        ok = true;
      }
    } else {
      if (indexOf(kCartNames, it.name) >= 0) ok = true;
      else if ((it.name == "S" || it.name == "T") && type != "FRAME") ok = true;
      else if (indexOf(kExtNames, it.name) >= 0 && type != "FRAME" && type != "POS") ok = true;
    }
    if (!ok)
      f.fail(it.name_tok.begin, "expected a component of " + (type.empty() ? std::string(axis ? "an axis target" : "a Cartesian target") : type) +
                                    " (" + allowedList(type, axis) + "), found '" + it.name_tok.text + "'");
    const bool st = it.name == "S" || it.name == "T";
    const bool numeric = it.vk == AggItem::kNum || (st && it.vk == AggItem::kChar && it.is_integer_literal);
    if (!numeric)
      f.fail(it.vbegin, "expected a number for " + it.name_tok.text + ", found '" + it.text + "'");
    if (!std::isfinite(it.num)) f.fail(it.vbegin, "expected a finite number for " + it.name_tok.text + ", found '" + it.text + "'");
    if (st) {
      if (!it.is_integer_literal || it.num < 0 || it.num > 1e6)
        f.fail(it.vbegin, "expected a non-negative integer for " + it.name_tok.text + ", found '" + it.text + "'");
      (it.name == "S" ? t.status : t.turn) = static_cast<int>(it.num);
    } else if (axis && (k = indexOf(kAxisNames, it.name)) >= 0) {
      t.axes[k] = it.num;
    } else if ((k = indexOf(kExtNames, it.name)) >= 0) {
      t.ext[k] = it.num;
    } else {
      t.pose[indexOf(kCartNames, it.name)] = it.num;
    }
    value.components.push_back({it.name, it.vbegin, it.vend, it.num});
  }
  if (src) {
    t.value_id = static_cast<int>(src->values.size());
    src->values.push_back(std::move(value));
  }
  return t;
}

// A frame ($TOOL, $BASE, TOOL_DATA[n]) aggregate: X..C, missing components from `previous`
// (KRL: an aggregate assignment changes only the components it lists).
std::optional<XyzAbc> toFrame(const Agg& a, const KrlFile& f, const std::optional<XyzAbc>& previous, bool* partial) {
  if (!a.type.empty() && a.type != "FRAME" && a.type != "POS" && a.type != "E6POS")
    f.fail(a.begin, "expected a FRAME aggregate, found type " + a.type);
  std::array<std::optional<double>, 6> v;
  std::set<std::string> seen;
  for (const auto& it : a.items) {
    if (!seen.insert(it.name).second) f.fail(it.name_tok.begin, "component " + it.name_tok.text + " given twice in this aggregate");
    const int k = indexOf(kCartNames, it.name);
    if (k < 0) f.fail(it.name_tok.begin, "expected a component of FRAME (X, Y, Z, A, B, C), found '" + it.name_tok.text + "'");
    if (it.vk != AggItem::kNum || !std::isfinite(it.num))
      f.fail(it.vbegin, "expected a number for " + it.name_tok.text + ", found '" + it.text + "'");
    v[k] = it.num;
  }
  *partial = false;
  double out[6];
  for (int k = 0; k < 6; ++k) {
    if (v[k]) {
      out[k] = *v[k];
    } else if (previous) {
      const double prev[6] = {previous->x_mm, previous->y_mm, previous->z_mm, previous->a_deg, previous->b_deg, previous->c_deg};
      out[k] = prev[k];
    } else {
      *partial = true;
      return std::nullopt;
    }
  }
  return XyzAbc{out[0], out[1], out[2], out[3], out[4], out[5]};
}

// ---------------------------------------------------------------------------------------------
// Program state while reading

struct PointEntry {
  std::string name;  // as declared
  std::string type;
  std::optional<Target> value;
  std::string problem;  // why the value cannot be used (changed at run time, ...)
  SourceLocation declared;
  bool global = false;  // from $config.dat
};

struct Fdat {
  std::optional<int> tool_no, base_no;
  bool external_tcp = false;
  SourceLocation where;
};

struct MoveData {  // LDAT / PDAT
  std::optional<double> vel;       // m/s (LDAT), percent (PDAT)
  std::optional<double> apo_dist;  // mm (C_DIS), percent (C_PTP)
};

struct Declarations {
  std::map<std::string, PointEntry> points;  // upper-case names
  std::map<std::string, SourceLocation> arrays;
  std::map<std::string, Fdat> fdats;
  std::map<std::string, MoveData> ldats, pdats;
  FrameTables tables;
};

std::optional<double> numberValue(const std::vector<Tok>& toks, size_t b, size_t e) {
  // a literal number with an optional sign, nothing else
  if (e <= b) return std::nullopt;
  double sign = 1;
  if (toks[b].kind == Tok::kPunct && (toks[b].text == "-" || toks[b].text == "+")) {
    sign = toks[b].text == "-" ? -1 : 1;
    ++b;
  }
  if (e - b != 1 || toks[b].kind != Tok::kNumber) return std::nullopt;
  return sign * std::strtod(toks[b].text.c_str(), nullptr);
}

std::optional<int> integerValue(const std::vector<Tok>& toks, size_t b, size_t e) {
  const auto v = numberValue(toks, b, e);
  if (!v || *v != std::floor(*v) || std::fabs(*v) > 1e6) return std::nullopt;
  return static_cast<int>(*v);
}

void setTable(std::vector<std::optional<XyzAbc>>& table, int n, const XyzAbc& v) {
  if (n < 0 || n > 10000) return;
  if (static_cast<int>(table.size()) <= n) table.resize(static_cast<size_t>(n) + 1);
  table[static_cast<size_t>(n)] = v;
}

std::optional<XyzAbc> tableValue(const std::vector<std::optional<XyzAbc>>& table, int n) {
  if (n == 0) return XyzAbc{};
  if (n < 0 || n >= static_cast<int>(table.size())) return std::nullopt;
  return table[static_cast<size_t>(n)];
}

Fdat toFdat(const Agg& a, const KrlFile& f) {
  Fdat d;
  d.where = f.loc(a.begin);
  for (const auto& it : a.items) {
    if (it.name == "TOOL_NO" || it.name == "BASE_NO") {
      if (it.vk != AggItem::kNum || !it.is_integer_literal || it.num < 0)
        f.fail(it.vbegin, "expected a non-negative integer for " + it.name_tok.text + ", found '" + it.text + "'");
      (it.name == "TOOL_NO" ? d.tool_no : d.base_no) = static_cast<int>(it.num);
    } else if (it.name == "IPO_FRAME") {
      d.external_tcp = upper(it.text) == "#TCP";
    }
  }
  return d;
}

MoveData toMoveData(const Agg& a) {
  MoveData m;
  for (const auto& it : a.items) {
    if (it.vk != AggItem::kNum) continue;
    if (it.name == "VEL") m.vel = it.num;
    if (it.name == "APO_DIST") m.apo_dist = it.num;
  }
  return m;
}

// Parses a declaration line (DECL ... or a point type without DECL). Returns false when the
// line is not a declaration of a type accura uses.
void parseDeclaration(Cursor& c, Declarations& d, KrlSource* src, bool global) {
  const KrlFile& f = c.file();
  if (c.isIdent("DECL")) c.next();
  while (c.isIdent("GLOBAL") || c.isIdent("CONST")) c.next();
  const Tok* type_tok = c.peek();
  if (!type_tok || type_tok->kind != Tok::kIdent) return;  // not ours
  const std::string type = type_tok->up;
  const bool point = isPointType(type);
  const bool fdat = type == "FDAT";
  const bool ldat = type == "LDAT";
  const bool pdat = type == "PDAT";
  if (!point && !fdat && !ldat && !pdat) return;
  c.next();
  while (true) {
    const Tok* nt = c.peek();
    if (!nt || nt->kind != Tok::kIdent) c.fail("expected a name after " + type_tok->text + ", found " + describe(nt));
    const Tok name = *nt;
    c.next();
    if (c.isPunct("[")) {  // an array: its elements are run-time values
      while (!c.atEnd() && !c.isPunct("]")) c.next();
      c.expectPunct("]", "closing the array dimension");
      if (point) d.arrays[name.up] = f.loc(name.begin);
      if (c.acceptPunct("=")) c.fail("expected no initial value for the array " + name.text + ", found '='");
    } else if (c.acceptPunct("=")) {
      if (point) {
        PointEntry e;
        e.name = name.text;
        e.type = type;
        e.declared = f.loc(name.begin);
        e.global = global;
        if (c.isPunct("{")) {
          const Agg a = parseAggregate(c);
          e.value = toTarget(a, type, f, global ? nullptr : src);
          e.value->name = name.text;
        } else {
          // initialised from another variable: not a constant accura can correct
          while (!c.atEnd() && !c.isPunct(",")) c.next();
          e.problem = name.text + " is initialised from an expression (" + f.loc(name.begin).str() + ")";
        }
        auto it = d.points.find(name.up);
        if (it != d.points.end() && it->second.global == global)
          f.fail(name.begin, "expected one declaration of " + name.text + ", found a second one (the first is at " + it->second.declared.str() + ")");
        d.points[name.up] = std::move(e);
      } else {
        if (!c.isPunct("{")) {
          while (!c.atEnd() && !c.isPunct(",")) c.next();
        } else {
          const Agg a = parseAggregate(c);
          if (fdat) d.fdats[name.up] = toFdat(a, f);
          if (ldat) d.ldats[name.up] = toMoveData(a);
          if (pdat) d.pdats[name.up] = toMoveData(a);
        }
      }
    } else if (point) {
      // declared without a value (set at run time, or not at all)
      PointEntry e;
      e.name = name.text;
      e.type = type;
      e.declared = f.loc(name.begin);
      e.global = global;
      e.problem = name.text + " is declared without a value (" + f.loc(name.begin).str() + ")";
      if (!d.points.count(name.up) || d.points[name.up].global != global) d.points[name.up] = std::move(e);
    }
    if (c.acceptPunct(",")) continue;
    if (!c.atEnd()) c.fail("expected ',' or the end of the declaration, found " + describe(c.peek()));
    return;
  }
}

// TOOL_DATA[n] = {...} / BASE_DATA[n] = {...}; returns true when the line was one.
bool parseTableAssignment(Cursor& c, Declarations& d) {
  const Tok* t = c.peek();
  if (!t || t->kind != Tok::kIdent) return false;
  std::string up = t->up;
  if (!up.empty() && up[0] == '$') up = up.substr(1);
  const bool tool = up == "TOOL_DATA", base = up == "BASE_DATA";
  if (!tool && !base) return false;
  if (!c.isPunct("[", 1)) return false;
  const size_t start = c.pos();
  c.next();
  c.next();
  const Tok* n = c.peek();
  if (!n || n->kind != Tok::kNumber || !c.isPunct("]", 1) || !c.isPunct("=", 2)) {
    c.seek(start);
    return false;
  }
  const int idx = std::atoi(n->text.c_str());
  c.next();
  c.next();
  c.next();
  if (!c.isPunct("{")) {
    c.seek(start);
    return false;
  }
  const Agg a = parseAggregate(c);
  auto& table = tool ? d.tables.tool : d.tables.base;
  bool partial = false;
  const auto prev = tableValue(table, idx);
  const auto v = toFrame(a, c.file(), idx == 0 ? std::nullopt : prev, &partial);
  if (v) setTable(table, idx, *v);
  return true;
}

void parseDataFile(const KrlFile& f, Declarations& d, KrlSource* src, bool global) {
  for (const Line& l : f.lines()) {
    const std::vector<Tok> toks = lex(f, l.begin, l.code_end);
    if (toks.empty()) continue;
    if (toks[0].text == "&") continue;
    Cursor c(f, toks, l.code_end);
    const std::string& first = toks[0].up;
    if (first == "DECL" || ((isPointType(first) || first == "FDAT" || first == "LDAT" || first == "PDAT") &&
                            toks.size() > 1 && toks[1].kind == Tok::kIdent)) {
      parseDeclaration(c, d, src, global);
    } else {
      parseTableAssignment(c, d);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// The .src

bool isMotionKeyword(const std::string& up) {
  static const std::set<std::string> k = {"PTP", "LIN", "CIRC", "SPTP", "SLIN", "SCIRC", "SPL",
                                          "PTP_REL", "LIN_REL", "CIRC_REL", "SPTP_REL", "SLIN_REL", "SCIRC_REL", "SPL_REL"};
  return k.count(up) > 0;
}

bool isApproxTok(const Tok& t) {
  Approximation a;
  return t.kind == Tok::kIdent && parseApproximation(t.text, &a);
}

struct Reader {
  Declarations decl;
  KrlSource* src = nullptr;
  Program* program = nullptr;
  const KrlFile* f = nullptr;

  FrameSetting tool, base;
  bool external_tcp = false;
  std::string fdat_name;  // as assigned to FDAT_ACT (upper case), "" none or an aggregate
  std::optional<Fdat> fdat;
  std::string fdat_problem;
  std::optional<MoveData> ldat, pdat;
  std::optional<double> vel_cp, vel_ptp, apo_cdis, apo_cptp, apo_cvel, apo_cori;
  bool in_spline = false;
  int triggers = 0;

  FrameSetting dataFrame(bool is_tool, int n, size_t at) const {
    FrameSetting s;
    s.where = f->loc(at);
    if (n == 0) {
      s.source = FrameSetting::Source::kNull;
      s.value = XyzAbc{};
      s.text = is_tool ? "TOOL_DATA[0] ($NULLFRAME)" : "BASE_DATA[0] ($NULLFRAME)";
      return s;
    }
    s.source = FrameSetting::Source::kData;
    s.index = n;
    s.text = std::string(is_tool ? "TOOL_DATA[" : "BASE_DATA[") + std::to_string(n) + "]";
    s.value = tableValue(is_tool ? decl.tables.tool : decl.tables.base, n);
    return s;
  }

  FrameSetting unknownFrame(const std::string& text, size_t at, const std::string& note = "") const {
    FrameSetting s;
    s.source = FrameSetting::Source::kUnknown;
    s.text = text;
    s.note = note;
    s.where = f->loc(at);
    return s;
  }

  // Evaluates the right-hand side of $TOOL = ... / $BASE = ... (tokens [b, e)).
  FrameSetting evalFrame(const std::vector<Tok>& toks, size_t b, size_t e, bool is_tool, const FrameSetting& current) const {
    const std::string text = f->text().substr(toks[b].begin, toks[e - 1].end - toks[b].begin);
    if (toks[b].text == "{") {
      Cursor c(*f, toks, toks[e - 1].end);
      c.seek(b);
      const Agg a = parseAggregate(c);
      if (c.pos() != e) return unknownFrame(text, toks[b].begin);
      bool partial = false;
      const auto v = toFrame(a, *f, current.value, &partial);
      FrameSetting s;
      s.where = f->loc(toks[b].begin);
      if (!v) {
        s.source = FrameSetting::Source::kUnknown;
        s.text = text;
        s.note = "a partial frame while the previous one is not known";
        return s;
      }
      s.source = FrameSetting::Source::kInline;
      s.value = v;
      s.text = text;
      return s;
    }
    if (e - b == 1 && toks[b].up == "$NULLFRAME") {
      FrameSetting s;
      s.source = FrameSetting::Source::kNull;
      s.value = XyzAbc{};
      s.text = "$NULLFRAME";
      s.where = f->loc(toks[b].begin);
      return s;
    }
    if (e - b == 4 && (toks[b].up == "TOOL_DATA" || toks[b].up == "BASE_DATA" || toks[b].up == "$TOOL_DATA" ||
                       toks[b].up == "$BASE_DATA") &&
        toks[b + 1].text == "[" && toks[b + 2].kind == Tok::kNumber && toks[b + 3].text == "]") {
      const bool tool_table = toks[b].up.find("TOOL") != std::string::npos;
      if (tool_table == is_tool) return dataFrame(is_tool, std::atoi(toks[b + 2].text.c_str()), toks[b].begin);
    }
    return unknownFrame(text, toks[b].begin);
  }

  void applyFdatFrames(size_t at) {
    if (!fdat) {
      const std::string name = fdat_name.empty() ? "FDAT_ACT" : fdat_name;
      const std::string why = fdat_problem.empty() ? "no FDAT_ACT before BAS" : fdat_problem;
      tool = unknownFrame("TOOL_DATA[" + name + ".TOOL_NO]", at, why);
      base = unknownFrame("BASE_DATA[" + name + ".BASE_NO]", at, why);
      return;
    }
    if (fdat->tool_no) tool = dataFrame(true, *fdat->tool_no, at);
    if (fdat->base_no) base = dataFrame(false, *fdat->base_no, at);
    external_tcp = fdat->external_tcp;
  }

  // Finds the end of an expression starting at b: a depth-0 ',' or approximation flag or WITH.
  // Two operands side by side at depth 0 (no operator between them) end the expression too.
  static size_t exprEnd(const std::vector<Tok>& t, size_t b, bool stop_at_comma = true) {
    int depth = 0;
    size_t i = b;
    bool after_operand = false;  // the previous depth-0 token ended an operand
    for (; i < t.size(); ++i) {
      const Tok& k = t[i];
      const bool opens = k.kind == Tok::kPunct && (k.text == "(" || k.text == "[" || k.text == "{");
      const bool starts_operand = k.kind == Tok::kIdent || k.kind == Tok::kNumber || k.kind == Tok::kString ||
                                  k.kind == Tok::kChar || k.kind == Tok::kEnum || (k.kind == Tok::kPunct && k.text == "{");
      if (depth == 0 && after_operand && starts_operand) break;
      if (opens) {
        ++depth;
      } else if (k.kind == Tok::kPunct && (k.text == ")" || k.text == "]" || k.text == "}")) {
        --depth;
      } else if (depth == 0 && ((stop_at_comma && k.kind == Tok::kPunct && k.text == ",") || isApproxTok(k) ||
                                (k.kind == Tok::kIdent && k.up == "WITH"))) {
        break;
      }
      if (depth == 0) {
        after_operand = k.kind == Tok::kIdent || k.kind == Tok::kNumber || k.kind == Tok::kString || k.kind == Tok::kChar ||
                        k.kind == Tok::kEnum || (k.kind == Tok::kPunct && (k.text == ")" || k.text == "]" || k.text == "}"));
      }
    }
    return i;
  }

  // Resolves a target expression [b, e) into `out`; returns the problem ("" when usable).
  std::string resolveTarget(const std::vector<Tok>& t, size_t b, size_t e, Target* out) {
    const std::string text = f->text().substr(t[b].begin, t[e - 1].end - t[b].begin);
    if (t[b].text == "{") {
      Cursor c(*f, t, t[e - 1].end);
      c.seek(b);
      const Agg a = parseAggregate(c);
      if (c.pos() != e) c.fail("expected the end of the target after the aggregate, found " + describe(c.peek()));
      *out = toTarget(a, "", *f, src);
      return "";
    }
    if (e - b == 1 && t[b].kind == Tok::kIdent) {
      const std::string& up = t[b].up;
      out->name = t[b].text;
      if (!up.empty() && up[0] == '$') return "the target is the system variable " + t[b].text;
      auto it = decl.points.find(up);
      if (it == decl.points.end()) {
        if (decl.arrays.count(up)) return t[b].text + " is an array";
        return t[b].text + " is not declared in " + src->src_path + (src->dat_path.empty() ? "" : " or " + src->dat_path) +
               " (a global point: give --config $config.dat)";
      }
      const PointEntry& p = it->second;
      if (!p.problem.empty()) return p.problem;
      *out = *p.value;
      out->name = t[b].text;
      return "";
    }
    return "the target '" + text + "' is computed at run time";
  }

  void handleAssignment(const std::vector<Tok>& t, size_t eq) {
    // lhs = t[0, eq), rhs = t[eq+1, end)
    const size_t b = eq + 1, e = t.size();
    if (b >= e) return;
    const std::string lhs0 = t[0].up;
    const bool simple = eq == 1;
    const bool field = eq == 3 && t[1].text == ".";
    const std::string fieldname = field ? t[2].up : "";
    if (simple && (lhs0 == "$TOOL" || lhs0 == "$BASE")) {
      const bool is_tool = lhs0 == "$TOOL";
      FrameSetting& s = is_tool ? tool : base;
      s = evalFrame(t, b, e, is_tool, s);
      return;
    }
    if ((lhs0 == "$TOOL" || lhs0 == "$BASE") && field) {
      FrameSetting& s = lhs0 == "$TOOL" ? tool : base;
      s = unknownFrame(f->text().substr(t[0].begin, t[e - 1].end - t[0].begin), t[0].begin);
      return;
    }
    if (lhs0 == "$VEL" && field && fieldname == "CP") { vel_cp = numberValue(t, b, e); return; }
    if (lhs0 == "$VEL_AXIS" && !simple) { vel_ptp = numberValue(t, b, e); return; }
    if (lhs0 == "$APO" && field) {
      const auto v = numberValue(t, b, e);
      if (fieldname == "CDIS") apo_cdis = v;
      if (fieldname == "CPTP") apo_cptp = v;
      if (fieldname == "CVEL") apo_cvel = v;
      if (fieldname == "CORI") apo_cori = v;
      return;
    }
    if (simple && (lhs0 == "FDAT_ACT" || lhs0 == "LDAT_ACT" || lhs0 == "PDAT_ACT")) {
      const bool name = e - b == 1 && t[b].kind == Tok::kIdent;
      const std::string key = name ? t[b].up : "";
      if (lhs0 == "FDAT_ACT") {
        fdat.reset();
        fdat_problem.clear();
        fdat_name = key;
        if (t[b].text == "{") {  // FDAT_ACT = {TOOL_NO 1,BASE_NO 0,IPO_FRAME #BASE}
          Cursor c(*f, t, t[e - 1].end);
          c.seek(b);
          fdat = toFdat(parseAggregate(c), *f);
          return;
        }
        auto it = decl.fdats.find(key);
        if (it != decl.fdats.end()) fdat = it->second;
        else fdat_problem = f->text().substr(t[b].begin, t[e - 1].end - t[b].begin) + " is not declared (a global FDAT: give --config $config.dat)";
      } else {
        auto& table = lhs0 == "LDAT_ACT" ? decl.ldats : decl.pdats;
        auto it = table.find(key);
        (lhs0 == "LDAT_ACT" ? ldat : pdat) = it != table.end() ? std::optional<MoveData>(it->second) : std::nullopt;
      }
      return;
    }
    // a point changed by the program
    auto it = decl.points.find(lhs0);
    if (it != decl.points.end()) {
      PointEntry& p = it->second;
      if (simple && t[b].text == "{" ) {
        Cursor c(*f, t, t[e - 1].end);
        c.seek(b);
        const Agg a = parseAggregate(c);
        if (c.pos() == e) {
          Target v = toTarget(a, p.type, *f, src);
          const bool complete = v.kind == Target::Kind::kCartesian ? v.completePose() : [&] {
            for (int k = 0; k < 6; ++k)
              if (!v.axes[k]) return false;
            return true;
          }();
          if (complete) {
            v.name = p.name;
            p.value = v;
            p.problem.clear();
            p.global = false;
            return;
          }
        }
      }
      p.problem = p.name + " is changed at run time (" + f->loc(t[0].begin).str() + ")";
    }
  }

  void handleBas(const std::vector<Tok>& t) {
    // BAS ( #CMD [, value] )
    if (t.size() < 4 || t[1].text != "(" || t[2].kind != Tok::kEnum) return;
    const std::string cmd = t[2].up;
    std::optional<double> value;
    if (t.size() >= 6 && t[3].text == ",") value = numberValue(t, 4, t.size() - 1);
    const size_t at = t[0].begin;
    if (cmd == "#TOOL" || cmd == "#BASE") {
      const auto n = t.size() >= 6 && t[3].text == "," ? integerValue(t, 4, t.size() - 1) : std::nullopt;
      FrameSetting& s = cmd == "#TOOL" ? tool : base;
      if (n) s = dataFrame(cmd == "#TOOL", *n, at);
      else s = unknownFrame(f->text().substr(t[0].begin, t.back().end - t[0].begin), at);
    } else if (cmd == "#PTP_PARAMS") {
      applyFdatFrames(at);
      vel_ptp = value;
      if (pdat && pdat->apo_dist) apo_cptp = pdat->apo_dist;
    } else if (cmd == "#CP_PARAMS") {
      applyFdatFrames(at);
      vel_cp = value;
      if (ldat && ldat->apo_dist) apo_cdis = ldat->apo_dist;
    } else if (cmd == "#FRAMES") {
      applyFdatFrames(at);
    } else if (cmd == "#PTP_DAT") {  // KRC2 inline forms: PDAT_ACT, then BAS(#PTP_DAT)
      if (pdat && pdat->apo_dist) apo_cptp = pdat->apo_dist;
    } else if (cmd == "#CP_DAT") {
      if (ldat && ldat->apo_dist) apo_cdis = ldat->apo_dist;
    } else if (cmd == "#VEL_PTP") {
      vel_ptp = value;
    } else if (cmd == "#VEL_CP") {
      vel_cp = value;
    }
  }

  // WITH assignments of a spline motion (valid for this motion only).
  void applyWith(const std::vector<Tok>& t, size_t b, size_t e, Motion& m) {
    size_t i = b;
    while (i < e) {
      size_t j = exprEnd(t, i);
      if (j > e) j = e;
      // one assignment [i, j)
      size_t eq = i;
      while (eq < j && !(t[eq].kind == Tok::kPunct && t[eq].text == "=")) ++eq;
      if (eq < j && eq > i && eq + 1 < j) {
        const std::string lhs = t[i].up;
        const size_t rb = eq + 1, re = j;
        const bool call = re - rb >= 3 && t[rb].kind == Tok::kIdent && t[rb + 1].text == "(";
        const std::string fn = call ? t[rb].up : "";
        auto arg = [&](size_t k) -> std::pair<size_t, size_t> {  // k-th argument of the call
          size_t s = rb + 2, n = 0;
          int depth = 0;
          for (size_t x = rb + 2; x < re; ++x) {
            const std::string& tx = t[x].text;
            if (tx == "(" || tx == "[" || tx == "{") ++depth;
            if ((tx == ")" && depth == 0) || (tx == "," && depth == 0)) {
              if (n == k) return {s, x};
              ++n;
              s = x + 1;
              if (tx == ")") break;
              continue;
            }
            if (tx == ")" || tx == "]" || tx == "}") --depth;
          }
          return {0, 0};
        };
        if (lhs == "$TOOL" || lhs == "$BASE") {
          const bool is_tool = lhs == "$TOOL";
          FrameSetting& s = is_tool ? m.tool : m.base;
          if (fn == "STOOL2" || fn == "SBASE") {
            const auto a = arg(0);
            // STOOL2(FP1) / SBASE(FP1.BASE_NO)
            std::string name = a.second > a.first ? t[a.first].up : "";
            auto it = decl.fdats.find(name);
            if (it != decl.fdats.end() && ((is_tool && it->second.tool_no) || (!is_tool && it->second.base_no))) {
              s = dataFrame(is_tool, is_tool ? *it->second.tool_no : *it->second.base_no, t[rb].begin);
              if (is_tool) m.external_tcp = it->second.external_tcp;
            } else {
              s = unknownFrame(f->text().substr(t[rb].begin, t[re - 1].end - t[rb].begin), t[rb].begin,
                               name.empty() ? "" : name + " is not declared (a global FDAT: give --config $config.dat)");
            }
          } else {
            s = evalFrame(t, rb, re, is_tool, s);
          }
        } else if (lhs == "$VEL" && (fn == "SVEL_CP")) {
          const auto a = arg(0);
          m.vel_m_s = numberValue(t, a.first, a.second);
        } else if (lhs == "$VEL_AXIS" && fn == "SVEL_JOINT") {
          const auto a = arg(0);
          m.vel_percent = numberValue(t, a.first, a.second);
        } else if (lhs == "$APO" && (fn == "SAPO" || fn == "SAPO_PTP")) {
          const auto a = arg(0);
          if (a.second == a.first + 1) {
            const auto& table = fn == "SAPO" ? decl.ldats : decl.pdats;
            auto it = table.find(t[a.first].up);
            if (it != table.end() && it->second.apo_dist && !m.approximation.empty()) m.approximation_value = it->second.apo_dist;
          }
        } else if (lhs == "$IPO_MODE" && fn == "SIPO_MODE") {
          const auto a = arg(0);
          if (a.second > a.first) {
            auto it = decl.fdats.find(t[a.first].up);
            if (it != decl.fdats.end()) m.external_tcp = it->second.external_tcp;
          }
        }
      }
      i = j;
      if (i < e && t[i].text == ",") ++i;
      else break;
    }
  }

  void handleMotion(const Line& l, const std::vector<Tok>& t) {
    Motion m;
    std::string kw = t[0].up;
    m.where = f->loc(t[0].begin);
    m.statement = f->text().substr(t[0].begin, l.code_end - t[0].begin);
    if (kw.size() > 4 && kw.compare(kw.size() - 4, 4, "_REL") == 0) {
      m.relative = true;
      kw = kw.substr(0, kw.size() - 4);
    }
    if (kw == "SPTP" || kw == "SLIN" || kw == "SCIRC" || kw == "SPL") {
      m.spline = true;
      kw = kw == "SPL" ? "SPL" : kw.substr(1);
    }
    if (kw == "PTP") m.type = MotionType::kPtp;
    else if (kw == "LIN") m.type = MotionType::kLin;
    else if (kw == "CIRC") m.type = MotionType::kCirc;
    else m.type = MotionType::kSpl;
    if (m.type == MotionType::kSpl && !in_spline)
      f->fail(t[0].begin, "expected SPL inside a SPLINE ... ENDSPLINE block, found it outside");

    KrlSource::Statement st;
    st.file = f->index();
    st.line_begin = l.begin;
    st.code_begin = t[0].begin;
    st.code_end = l.code_end;
    st.eol = l.eol;

    Cursor c(*f, t, l.code_end);
    c.seek(1);
    auto takeTarget = [&](const char* what) -> std::pair<size_t, size_t> {
      const size_t b = c.pos();
      const size_t e = exprEnd(t, b);
      if (e == b) c.fail(std::string("expected ") + what + " after " + t[0].text + ", found " + describe(c.peek()));
      c.seek(e);
      return {b, e};
    };
    const auto first = takeTarget(m.type == MotionType::kCirc ? "the auxiliary point" : "a target");
    std::pair<size_t, size_t> end_range = first;
    if (m.type == MotionType::kCirc) {
      c.expectPunct(",", "between the auxiliary point and the end point of " + t[0].text);
      end_range = takeTarget("the end point");
      if (c.isPunct(",") && c.isIdent("CA", 1)) {
        c.next();
        c.next();
        const size_t b = c.pos();
        const size_t e = exprEnd(t, b);
        const auto v = numberValue(t, b, e);
        if (!v) c.fail("expected a number (deg) after CA, found " + describe(c.peek()));
        m.circ_angle_deg = *v;
        c.seek(e);
      }
    }
    // approximation flags, WITH, coordinate system of relative motions
    size_t with_b = 0, with_e = 0;
    while (!c.atEnd()) {
      const Tok& k = *c.peek();
      Approximation a;
      if (k.kind == Tok::kIdent && parseApproximation(k.text, &a)) {
        m.approximation.push_back(a);
        c.next();
      } else if (k.kind == Tok::kIdent && k.up == "WITH") {
        c.next();
        with_b = c.pos();
        size_t i = with_b;
        // the WITH list runs until a depth-0 approximation flag or the end
        while (i < t.size()) {
          const size_t j = exprEnd(t, i);
          i = j;
          if (i < t.size() && t[i].text == ",") {
            ++i;
            continue;
          }
          break;
        }
        with_e = i;
        c.seek(i);
      } else if (k.kind == Tok::kEnum && m.relative && (k.up == "#BASE" || k.up == "#TOOL")) {
        c.next();
      } else {
        c.fail("expected an approximation flag (C_PTP, C_DIS, C_VEL, C_ORI, C_SPL) or WITH after the target, found " + describe(&k));
      }
    }

    // state at this motion
    m.tool = tool;
    m.base = base;
    m.external_tcp = external_tcp;
    if (m.type == MotionType::kPtp) m.vel_percent = vel_ptp;
    else m.vel_m_s = vel_cp;
    if (!m.approximation.empty()) {
      switch (m.approximation.front()) {
        case Approximation::kCDis: m.approximation_value = apo_cdis; break;
        case Approximation::kCPtp: m.approximation_value = apo_cptp; break;
        case Approximation::kCVel: m.approximation_value = apo_cvel; break;
        case Approximation::kCOri: m.approximation_value = apo_cori; break;
        case Approximation::kCSpl: m.approximation_value = apo_cdis; break;
      }
    }
    if (with_e > with_b) applyWith(t, with_b, with_e, m);

    // targets
    std::string problem;
    if (m.type == MotionType::kCirc) {
      Target aux;
      problem = resolveTarget(t, first.first, first.second, &aux);
      m.aux = aux;
      st.targets.push_back({t[first.first].begin, t[first.second - 1].end});
    }
    {
      const std::string p2 = resolveTarget(t, end_range.first, end_range.second, &m.target);
      if (problem.empty()) problem = p2;
      st.targets.push_back({t[end_range.first].begin, t[end_range.second - 1].end});
    }
    if (m.relative && problem.empty()) problem = "a relative motion (" + t[0].text + ")";
    m.target_problem = problem;
    if (problem.empty() && m.type != MotionType::kPtp) {
      const auto check = [&](const Target& x, const char* what) {
        if (x.kind == Target::Kind::kAxis)
          f->fail(x.value_id >= 0 ? src->values[static_cast<size_t>(x.value_id)].begin : t[0].begin,
                  std::string("expected a Cartesian ") + what + " for " + t[0].text + " (E6POS, POS, FRAME), found an axis target" +
                      (x.name.empty() ? "" : " (" + x.name + ")"));
      };
      check(m.target, "target");
      if (m.aux) check(*m.aux, "auxiliary point");
    }
    m.trigger_count = triggers;
    triggers = 0;
    m.statement_id = static_cast<int>(src->statements.size());
    src->statements.push_back(std::move(st));
    program->motions.push_back(std::move(m));
  }

  void handleLine(const Line& l) {
    const std::vector<Tok> t = lex(*f, l.begin, l.code_end);
    if (t.empty() || t[0].text == "&") return;
    const std::string& k = t[0].up;
    if (k == "DEF" || (k == "GLOBAL" && t.size() > 1 && t[1].up == "DEF")) {
      if (program->name.empty()) {
        const size_t i = k == "DEF" ? 1 : 2;
        if (i < t.size() && t[i].kind == Tok::kIdent) program->name = t[i].text;
      }
      return;
    }
    if (k == "SPLINE" || k == "PTP_SPLINE") { in_spline = true; return; }
    if (k == "ENDSPLINE") { in_spline = false; return; }
    if (k == "TRIGGER") { ++triggers; return; }
    if (k == "DECL" || ((isPointType(k) || k == "FDAT" || k == "LDAT" || k == "PDAT") && t.size() > 1 && t[1].kind == Tok::kIdent)) {
      Cursor c(*f, t, l.code_end);
      parseDeclaration(c, decl, src, false);
      return;
    }
    if (isMotionKeyword(k) && t[0].kind == Tok::kIdent) {
      // "LIN = 3" would be an assignment to a variable named like a keyword: not KRL
      handleMotion(l, t);
      return;
    }
    if (k == "BAS" && t.size() > 1 && t[1].text == "(") {
      handleBas(t);
      return;
    }
    {
      Cursor c(*f, t, l.code_end);
      if (parseTableAssignment(c, decl)) return;
    }
    // assignment: find a depth-0 '=' (not '==')
    if (t[0].kind == Tok::kIdent) {
      int depth = 0;
      for (size_t i = 1; i < t.size(); ++i) {
        const std::string& x = t[i].text;
        if (x == "[" || x == "(") ++depth;
        else if (x == "]" || x == ")") --depth;
        else if (depth == 0 && x == "=" && t[i].kind == Tok::kPunct) {
          handleAssignment(t, i);
          return;
        }
        else if (depth == 0 && x != "." && t[i].kind == Tok::kPunct) break;
      }
    }
  }
};

std::string findDat(const std::string& src_path) {
  const fs::path p(src_path);
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  const std::string stem = upper(p.stem().string());
  std::error_code ec;
  std::vector<std::string> found;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (!e.is_regular_file(ec)) continue;
    const fs::path q = e.path();
    if (upper(q.stem().string()) == stem && upper(q.extension().string()) == ".DAT")
      found.push_back(p.has_parent_path() ? (dir / q.filename()).string() : q.filename().string());
  }
  if (found.empty()) return "";
  std::sort(found.begin(), found.end());
  // prefer the exact-case sibling
  for (const auto& s : found)
    if (fs::path(s).stem() == p.stem()) return s;
  return found.front();
}

// ---------------------------------------------------------------------------------------------
// Writing

std::string formatAxis(double v) { return formatFixed(v, 4); }

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

// The new text of a target's aggregate: the numbers of the pose (or axes) replaced in place when
// the aggregate has them all, else the whole aggregate rebuilt.
std::string rewriteValue(const KrlSource::Value& v, const std::string& text, const Target& t) {
  const bool cart = t.kind == Target::Kind::kCartesian;
  const char* const* names = cart ? kCartNames : kAxisNames;
  std::set<std::string> have;
  for (const auto& c : v.components) have.insert(c.name);
  bool all = true;
  for (int k = 0; k < 6; ++k)
    if (!have.count(names[k])) all = false;
  if (!all) {
    std::string agg = krlAggregate(t);
    const std::string orig = text.substr(v.begin, v.end - v.begin);
    const size_t colon = orig.find(':');
    if (!t.type.empty() && colon != std::string::npos) agg = orig.substr(0, colon + 1) + " " + agg.substr(1);
    return agg;
  }
  std::string out;
  size_t pos = v.begin;
  for (const auto& c : v.components) {
    out += text.substr(pos, c.begin - pos);
    // the pose, and S / T when the compensation changed them
    const bool st_changed = cart && ((c.name == "S" && t.status && *t.status != c.value) ||
                                     (c.name == "T" && t.turn && *t.turn != c.value));
    const bool ours = indexOf(names, c.name) >= 0 || st_changed;
    out += ours ? componentText(t, c.name) : text.substr(c.begin, c.end - c.begin);
    pos = c.end;
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
    if (e.begin < pos) throw ArgumentError("writeKrl: overlapping edits");
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
  auto modify = [&](const Target& t, const Motion& m) {
    if (!t.modified) return;
    if (t.value_id < 0)
      throw ArgumentError(m.where.str() + ": cannot write the corrected value of " + (t.name.empty() ? "this target" : t.name) +
                          ": it is declared outside the program (e.g. in $config.dat)");
    const KrlSource::Value& v = s.values.at(static_cast<size_t>(t.value_id));
    const std::string text = rewriteValue(v, textOf(v.file), t);
    auto it = value_text.find(t.value_id);
    if (it != value_text.end()) {
      if (it->second.first != text)
        throw ArgumentError(m.where.str() + ": " + (t.name.empty() ? "this target" : t.name) +
                            " needs a different correction here than at " + it->second.second +
                            " (same point, different tool, base or motion): give the motions their own points");
      return;
    }
    value_text[t.value_id] = {text, m.where.str()};
    edits.push_back({v.file, v.begin, v.end, text, order++});
  };
  for (const Motion& m : p.motions) {
    if (m.inserted) {
      if (m.statement_id < 0 || m.statement_id >= static_cast<int>(s.statements.size()))
        throw ArgumentError("writeKrl: an inserted motion has no anchor statement");
      const KrlSource::Statement& st = s.statements[static_cast<size_t>(m.statement_id)];
      const std::string& text = textOf(st.file);
      std::vector<std::string> repl;
      if (m.aux) repl.push_back(krlAggregate(*m.aux));
      repl.push_back(krlAggregate(m.target));
      if (repl.size() != st.targets.size())
        throw ArgumentError("writeKrl: an inserted motion does not match its anchor statement's targets");
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
    if (m.aux) modify(*m.aux, m);
    modify(m.target, m);
  }
  KrlText out;
  out.src = applyEdits(s.src_text, edits, 0);
  out.dat = s.dat_path.empty() ? "" : applyEdits(s.dat_text, edits, 1);
  return out;
}

// --- a new program (from XML)

std::string frameAggregate(const XyzAbc& v) {
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

bool sameFrame(const FrameSetting& a, const FrameSetting& b) {
  if (a.source != b.source || a.index != b.index || a.value.has_value() != b.value.has_value()) return false;
  if (a.source == FrameSetting::Source::kUnknown && a.text != b.text) return false;
  if (a.value) {
    const XyzAbc& x = *a.value;
    const XyzAbc& y = *b.value;
    return formatMm(x.x_mm) == formatMm(y.x_mm) && formatMm(x.y_mm) == formatMm(y.y_mm) && formatMm(x.z_mm) == formatMm(y.z_mm) &&
           formatDeg(x.a_deg) == formatDeg(y.a_deg) && formatDeg(x.b_deg) == formatDeg(y.b_deg) && formatDeg(x.c_deg) == formatDeg(y.c_deg);
  }
  return true;
}

std::string declType(const Target& t) {
  if (!t.type.empty()) return t.type;
  return t.kind == Target::Kind::kAxis ? "E6AXIS" : "E6POS";
}

KrlText generateKrl(const Program& p) {
  const std::string name = p.name.empty() ? "program" : p.name;
  std::ostringstream src, dat;
  src << "&ACCESS RVP\n&REL 1\nDEF " << name << "( )\n";
  src << ";FOLD INI\n  BAS (#INITMOV,0 )\n;ENDFOLD (INI)\n";
  dat << "&ACCESS RVP\n&REL 1\nDEFDAT " << name << " PUBLIC\n";
  std::map<std::string, std::string> declared;  // upper name -> aggregate text
  FrameSetting tool, base;
  std::optional<double> vel_cp, vel_ptp;
  std::map<Approximation, std::optional<double>> apo;
  bool in_spline = false;
  auto targetText = [&](const Target& t, const Motion& m) -> std::string {
    if (t.name.empty()) return krlAggregate(t);
    const std::string up = upper(t.name);
    bool any = false;
    for (const auto& c : t.pose) any = any || c.has_value();
    for (const auto& c : t.axes) any = any || c.has_value();
    if (!any) return t.name;  // no value: declared outside the program (a global point)
    const std::string agg = krlAggregate(t);
    auto it = declared.find(up);
    if (it == declared.end()) {
      declared[up] = agg;
      dat << "DECL " << declType(t) << " " << t.name << "=" << agg << "\n";
    } else if (it->second != agg) {
      throw ArgumentError(m.where.str() + ": the point " + t.name + " has two different values in this program");
    }
    return t.name;
  };
  for (const Motion& m : p.motions) {
    if (m.spline && m.type == MotionType::kSpl && !in_spline) {
      src << "SPLINE\n";
      in_spline = true;
    } else if (in_spline && m.type != MotionType::kSpl) {
      src << "ENDSPLINE\n";
      in_spline = false;
    }
    if (!sameFrame(m.tool, tool)) {
      const std::string s = frameStatement("$TOOL", m.tool, true);
      if (!s.empty()) src << s << "\n";
      tool = m.tool;
    }
    if (!sameFrame(m.base, base)) {
      const std::string s = frameStatement("$BASE", m.base, false);
      if (!s.empty()) src << s << "\n";
      base = m.base;
    }
    if (m.type == MotionType::kPtp && m.vel_percent && m.vel_percent != vel_ptp) {
      for (int k = 1; k <= 6; ++k) src << "$VEL_AXIS[" << k << "]=" << formatFixed(*m.vel_percent, 4) << "\n";
      vel_ptp = m.vel_percent;
    }
    if (m.type != MotionType::kPtp && m.vel_m_s && m.vel_m_s != vel_cp) {
      src << "$VEL.CP=" << formatFixed(*m.vel_m_s, 4) << "\n";
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
      src << "$APO." << var << "=" << formatFixed(*m.approximation_value, 4) << "\n";
      apo[m.approximation.front()] = m.approximation_value;
    }
    std::string line = motionKeyword(m) + " ";
    if (m.aux) line += targetText(*m.aux, m) + ", ";
    line += targetText(m.target, m);
    if (m.circ_angle_deg) line += ", CA " + formatDeg(*m.circ_angle_deg);
    for (Approximation a : m.approximation) line += std::string(" ") + toString(a);
    src << line << "\n";
  }
  if (in_spline) src << "ENDSPLINE\n";
  src << "END\n";
  dat << "ENDDAT\n";
  return {src.str(), dat.str()};
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

FrameTables readKrlFrameTables(const std::string& config_path) {
  const KrlFile f(config_path, readFileBytes(config_path, "the $config.dat"), 2);
  Declarations d;
  parseDataFile(f, d, nullptr, true);
  d.tables.file = config_path;
  return d.tables;
}

Program readKrl(const std::string& src_path, const KrlReadOptions& options) {
  auto source = std::make_shared<KrlSource>();
  source->src_path = src_path;
  source->src_text = readFileBytes(src_path, "the KRL program");
  source->dat_path = options.dat_path.empty() ? findDat(src_path) : options.dat_path;
  if (!source->dat_path.empty()) source->dat_text = readFileBytes(source->dat_path, "the KRL data file");

  Program program;
  program.source_file = src_path;
  Reader r;
  r.src = source.get();
  r.program = &program;

  if (!options.config_path.empty()) {
    const KrlFile cfg(options.config_path, readFileBytes(options.config_path, "the $config.dat"), 2);
    parseDataFile(cfg, r.decl, nullptr, true);
    r.decl.tables.file = options.config_path;
  }
  if (!source->dat_path.empty()) {
    const KrlFile dat(source->dat_path, source->dat_text, 1);
    parseDataFile(dat, r.decl, source.get(), false);
  }
  const KrlFile src(src_path, source->src_text, 0);
  r.f = &src;
  for (const Line& l : src.lines()) r.handleLine(l);
  if (program.name.empty()) {
    bool any = false;
    for (const Line& l : src.lines())
      if (l.code_end > l.begin) any = true;
    if (any || src.lines().empty()) throw InputError(src_path, 0, 0, "expected a KRL program (DEF name( ) ... END), found no DEF line");
  }
  program.krl = source;
  return program;
}

KrlText writeKrl(const Program& program) {
  if (program.krl) return patchKrl(program);
  return generateKrl(program);
}

}  // namespace accura::postproc
