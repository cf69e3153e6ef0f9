// KRL lexer: files and lines, tokens, aggregates (see krl_internal.h).
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
#include "accura/calib/file_io.h"
#include "accura/calib/text.h"
#include "krl_internal.h"

namespace fs = std::filesystem;

namespace accura::postproc::krl_detail {
namespace {

bool identStart(char c) { return std::isalpha(static_cast<unsigned char>(c)) || c == '_' || c == '$'; }
bool identChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '$'; }

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

}  // namespace

bool isFoldMarker(const std::string& line) {
  const size_t b = line.find_first_not_of(" \t");
  if (b == std::string::npos || line[b] != ';') return false;
  const std::string u = upper(line.substr(b + 1, 7));
  return u.compare(0, 4, "FOLD") == 0 || u.compare(0, 7, "ENDFOLD") == 0;
}

const BlockWords* blockOpenedBy(const std::string& up) {
  for (const BlockWords& b : kBlocks)
    if (up == b.open) return &b;
  return nullptr;
}

const BlockWords* blockClosedBy(const std::string& up) {
  for (const BlockWords& b : kBlocks)
    if (up == b.close) return &b;
  return nullptr;
}

bool startsBranch(const std::string& up) {
  for (const char* w : kBranchWords)
    if (up == w) return true;
  return false;
}

bool isJump(const std::string& up) {
  for (const char* w : kJumpWords)
    if (up == w) return true;
  return false;
}

std::string upper(std::string s) { return calib::upperAscii(std::move(s)); }

std::string readFileBytes(const std::string& path, const std::string& what) {
  if (const std::string problem = calib::notAFileProblem(path); !problem.empty())
    throw calib::InputError(path, 0, 0, "cannot read " + what + ": " + problem);  // (a directory is not "no such file")
  std::ifstream f(path, std::ios::binary);
  if (!f) throw calib::InputError(path, 0, 0, "cannot read " + what);
  std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (f.bad()) throw calib::InputError(path, 0, 0, "cannot read " + what);
  const size_t nul = text.find('\0');
  if (nul != std::string::npos) {
    const int line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(nul), '\n'));
    const size_t line_start = nul == 0 ? 0 : text.rfind('\n', nul - 1) + 1;  // npos + 1 == 0: the first line
    throw calib::InputError(path, line, static_cast<int>(nul - line_start) + 1, "expected a KRL text file, found a NUL byte (binary file?)");
  }
  return text;
}

std::vector<Tok> lex(const KrlFile& f, size_t begin, size_t end) {
  const std::string& s = f.text();
  std::vector<Tok> out;
  size_t i = begin;
  // a UTF-8 byte order mark at the start of the file (an editor's) and the end-of-file mark
  // Ctrl-Z (an old DOS editor's) are not text
  if (i == 0 && s.compare(0, 3, "\xEF\xBB\xBF") == 0) i = std::min<size_t>(3, end);
  while (i < end) {
    const char c = s[i];
    if (c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v' || c == '\x1A') {
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
      // A literal beyond a double (1e309) is no number a controller holds: never infinity.
      if (!std::isfinite(std::strtod(t.text.c_str(), nullptr)))
        f.fail(i, "expected a number within +-1.7e308, found '" + t.text + "'");
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

}  // namespace accura::postproc::krl_detail
