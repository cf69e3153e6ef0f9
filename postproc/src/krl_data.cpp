// KRL data: targets and frames from aggregates, the declarations of a .dat or $config.dat
// (see krl_internal.h).
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
#include "accura/calib/text.h"
#include "krl_internal.h"

namespace fs = std::filesystem;

namespace accura::postproc::krl_detail {

namespace {
/// Largest position (mm) or angle (deg) of a target component.
constexpr double kMaxTargetValue = 1e5;
}  // namespace

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
      f.fail(it.name_tok.begin, "expected each component once in this aggregate, found " + it.name_tok.text + " a second time");
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
    // a position or an angle beyond 100 m or 100000 deg is no robot's (RAPID's and URScript's
    // readers have the same bound)
    if (!st && !(std::fabs(it.num) <= kMaxTargetValue))
      f.fail(it.vbegin, "expected " + it.name_tok.text + " within +-" + calib::formatFixed(kMaxTargetValue, 0) +
                            " (mm or deg), found '" + it.text + "'");
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
    value.components.push_back({it.name, it.vbegin, it.vend, it.num, it.name_tok.begin});
  }
  if (src) {
    t.value_id = static_cast<int>(src->values.size());
    src->values.push_back(std::move(value));
  }
  return t;
}

// A frame ($TOOL, $BASE, TOOL_DATA[n]) aggregate: X..C, missing components from `previous`
// (KRL: an aggregate assignment changes only the components it lists).
std::optional<calib::XyzAbc> toFrame(const Agg& a, const KrlFile& f, const std::optional<calib::XyzAbc>& previous, bool* partial) {
  if (!a.type.empty() && a.type != "FRAME" && a.type != "POS" && a.type != "E6POS")
    f.fail(a.begin, "expected a FRAME aggregate, found type " + a.type);
  std::array<std::optional<double>, 6> v;
  std::set<std::string> seen;
  for (const auto& it : a.items) {
    if (!seen.insert(it.name).second)
      f.fail(it.name_tok.begin, "expected each component once in this aggregate, found " + it.name_tok.text + " a second time");
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
  return calib::XyzAbc{out[0], out[1], out[2], out[3], out[4], out[5]};
}

// ---------------------------------------------------------------------------------------------
// Program state while reading


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

void setTable(std::vector<std::optional<calib::XyzAbc>>& table, int n, const calib::XyzAbc& v) {
  if (n < 0 || n > 10000) return;
  if (static_cast<int>(table.size()) <= n) table.resize(static_cast<size_t>(n) + 1);
  table[static_cast<size_t>(n)] = v;
}

std::optional<calib::XyzAbc> tableValue(const std::vector<std::optional<calib::XyzAbc>>& table, int n) {
  if (n == 0) return calib::XyzAbc{};
  if (n < 0 || n >= static_cast<int>(table.size())) return std::nullopt;
  return table[static_cast<size_t>(n)];
}

Fdat toFdat(const Agg& a, const KrlFile& f) {
  Fdat d;
  d.where = f.loc(a.begin);
  for (const auto& it : a.items) {
    if (it.name == "TOOL_NO" || it.name == "BASE_NO") {
      // KUKA's tool and base tables have at most 32 entries; anything above 999 cannot be an
      // index (and would not fit an int)
      if (it.vk != AggItem::kNum || !it.is_integer_literal || !(it.num >= 0 && it.num <= 999))
        f.fail(it.vbegin, "expected an integer 0..999 for " + it.name_tok.text + ", found '" + it.text + "'");
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
    if (it.name == "ORI_TYP" && it.vk == AggItem::kEnum) m.ori_typ = upper(it.text);
    if (it.name == "CIRC_TYP" && it.vk == AggItem::kEnum) m.circ_typ = upper(it.text);
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
  bool global_keyword = false;  // DECL GLOBAL: other modules may use the point
  while (c.isIdent("GLOBAL") || c.isIdent("CONST")) {
    // (each keyword consumed: `DECL GLOBAL CONST ...` must not stop the cursor after GLOBAL)
    if (c.next().up == "GLOBAL") global_keyword = true;
  }
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
      if (point) d.arrays[name.up] = ArrayEntry{name.text, type, f.loc(name.begin), global_keyword};
      if (c.acceptPunct("=")) c.fail("expected no initial value for the array " + name.text + ", found '='");
    } else if (c.acceptPunct("=")) {
      if (point) {
        PointEntry e;
        e.name = name.text;
        e.type = type;
        e.declared = f.loc(name.begin);
        e.global = e.config = global;
        e.global_keyword = global_keyword;
        if (c.isPunct("{")) {
          const Agg a = parseAggregate(c);
          e.value = toTarget(a, type, f, global ? nullptr : src);
          e.value->name = name.text;
          if (src && e.value->value_id >= 0) src->values[static_cast<size_t>(e.value->value_id)].global = global_keyword;
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
      e.global = e.config = global;
      e.global_keyword = global_keyword;
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

std::string arrayElementName(const ArrayEntry& a, int index) { return a.name + "[" + std::to_string(index) + "]"; }

// XPA[1]={X ..}: a data list's value of an element of a point array declared before it.
bool parseArrayElement(Cursor& c, Declarations& d, KrlSource* src, bool global) {
  const Tok* t = c.peek();
  if (!t || t->kind != Tok::kIdent || !c.isPunct("[", 1)) return false;
  const auto a = d.arrays.find(t->up);
  if (a == d.arrays.end()) return false;
  const size_t start = c.pos();
  if (!c.peek(2)) return false;
  const std::optional<int> index = integerValue(c.tokens(), start + 2, start + 3);
  if (!index || !c.isPunct("]", 3) || !c.isPunct("=", 4) || !c.isPunct("{", 5)) return false;  // XPA[1,2], XPA[1].X = ..
  const KrlFile& f = c.file();
  c.seek(start + 5);
  const Agg agg = parseAggregate(c);
  if (!c.atEnd()) c.fail("expected the end of the statement after the value of " + arrayElementName(a->second, *index) + ", found " + describe(c.peek()));
  PointEntry e;
  e.name = arrayElementName(a->second, *index);
  e.type = a->second.type;
  e.declared = f.loc(t->begin);
  e.global = e.config = global;
  e.global_keyword = a->second.global_keyword;
  e.value = toTarget(agg, e.type, f, global ? nullptr : src);
  e.value->name = e.name;
  if (src && e.value->value_id >= 0) src->values[static_cast<size_t>(e.value->value_id)].global = e.global_keyword;
  const std::string key = upper(e.name);
  const auto it = d.points.find(key);
  if (it != d.points.end() && it->second.global == global)
    f.fail(t->begin, "expected one value of " + e.name + " in the data list, found a second one (the first is at " + it->second.declared.str() + ")");
  d.points[key] = std::move(e);
  return true;
}

void parseDataFile(const KrlFile& f, Declarations& d, KrlSource* src, bool global) {
  // DEFDAT name [PUBLIC] ... ENDDAT: a file cut short (or empty) is an error, not fewer points
  bool defdat = false, enddat = false;
  for (const Line& l : f.lines()) {
    const std::vector<Tok> toks = lex(f, l.begin, l.code_end);
    if (toks.empty()) continue;
    if (toks[0].text == "&") continue;
    Cursor c(f, toks, l.code_end);
    const std::string& first = toks[0].up;
    if (enddat) f.fail(toks[0].begin, "expected nothing after ENDDAT, found " + describe(&toks[0]));
    if (first == "DEFDAT" && !defdat) {
      defdat = true;
      if (!global && toks.size() > 1 && toks[1].kind == Tok::kIdent) {
        d.defdat_name = toks[1].text;
        d.defdat_where = f.loc(toks[1].begin);
      }
      continue;
    }
    if (!defdat) f.fail(toks[0].begin, "expected the data list to start with DEFDAT name, found " + describe(&toks[0]));
    if (first == "ENDDAT" && toks.size() == 1) {
      enddat = true;
      continue;
    }
    if (first == "DECL" || ((isPointType(first) || first == "FDAT" || first == "LDAT" || first == "PDAT") &&
                            toks.size() > 1 && toks[1].kind == Tok::kIdent)) {
      parseDeclaration(c, d, src, global);
    } else if (!parseTableAssignment(c, d)) {
      parseArrayElement(c, d, src, global);
    }
  }
  if (!defdat) f.fail(f.text().size(), "expected a data list (DEFDAT name ... ENDDAT), found the end of the file");
  if (!enddat) f.fail(f.text().size(), "expected ENDDAT closing the data list, found the end of the file");
}


}  // namespace accura::postproc::krl_detail
