// Triangle meshes of the cell, read with assimp (see cell.h).
//
// assimp is lax with malformed files: a PLY face index beyond the vertices, a declared face
// that is missing, a truncated binary body or header make it crash, loop for ever or read out
// of bounds, and a half-read ASCII STL or OBJ is accepted as a smaller mesh. So the formats
// accura reads most (PLY, STL, OBJ) are checked here, byte for byte, before assimp sees them
// (a half-read file is an error, not a shorter mesh), and every scene assimp returns is
// checked (face indices, finite coordinates, node mesh indices) before its post-processing.
#include <assimp/Importer.hpp>
#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <new>
#include <sstream>
#include <string_view>

#include "accura/calib/errors.h"
#include "accura/calib/text.h"
#include "accura/postproc/cell.h"
#include "decimal.h"

namespace accura::postproc {
namespace {

std::string quoted(std::string_view s) {
  return "'" + calib::printableBytes(std::string(s.substr(0, 40))) + (s.size() > 40 ? "...'" : "'");
}

/// A whitespace-separated word of a text file and where it starts (1-based line and column).
struct Word {
  std::string_view text;
  int line = 0, column = 0;
};

/// Reads a text file's words in order; knows where it is (for messages).
class Scanner {
 public:
  Scanner(std::string_view data, size_t pos, int line) : d_(data), p_(pos), line_(line), line_start_(pos) {
    // the column of `pos` counts from the start of its line
    while (line_start_ > 0 && d_[line_start_ - 1] != '\n') --line_start_;
  }

  /// The next word on the current line (false at a line end or the end of the file).
  bool wordOnLine(Word* w) {
    while (p_ < d_.size() && (d_[p_] == ' ' || d_[p_] == '\t' || d_[p_] == '\r' || d_[p_] == '\f' || d_[p_] == '\v')) ++p_;
    if (p_ >= d_.size() || d_[p_] == '\n') return false;
    return take(w);
  }
  /// The next word, on this line or a later one (false at the end of the file).
  bool word(Word* w) {
    while (p_ < d_.size() && std::isspace(static_cast<unsigned char>(d_[p_]))) {
      if (d_[p_] == '\n') newLine();
      else ++p_;
    }
    if (p_ >= d_.size()) return false;
    return take(w);
  }
  /// The rest of the current line (without its line end), moving past the line end.
  std::string_view restOfLine() {
    const size_t start = p_;
    while (p_ < d_.size() && d_[p_] != '\n') ++p_;
    std::string_view s = d_.substr(start, p_ - start);
    if (p_ < d_.size()) newLine();
    return s;
  }
  /// Moves past the current line's end; false when the line holds more words.
  bool endLine(Word* extra) {
    if (wordOnLine(extra)) return false;
    if (p_ < d_.size()) newLine();
    return true;
  }
  bool atEnd() const { return p_ >= d_.size(); }
  bool lastLineEnded() const { return d_.empty() || d_.back() == '\n'; }
  /// Where the scanner is (where the next word would start, before skipping blanks).
  Word here() const { return {std::string_view(), line_, static_cast<int>(p_ - line_start_) + 1}; }
  size_t offset() const { return p_; }
  int line() const { return line_; }

 private:
  bool take(Word* w) {
    const size_t start = p_;
    while (p_ < d_.size() && !std::isspace(static_cast<unsigned char>(d_[p_]))) ++p_;
    *w = {d_.substr(start, p_ - start), line_, static_cast<int>(start - line_start_) + 1};
    return true;
  }
  void newLine() {
    ++p_;
    ++line_;
    line_start_ = p_;
  }
  std::string_view d_;
  size_t p_;
  int line_;
  size_t line_start_;
};

using detail::parseDecimal;
using detail::parseDecimalInteger;

class MeshChecker {
 public:
  MeshChecker(const std::string& path, std::string_view data, double scale_to_mm) : path_(path), d_(data), scale_(scale_to_mm) {}

  [[noreturn]] void fail(int line, int column, const std::string& msg) const { throw calib::InputError(path_, line, column, msg); }
  [[noreturn]] void fail(const Word& w, const std::string& msg) const { throw calib::InputError(path_, w.line, w.column, msg); }
  /// Binary files: the place is a byte offset (there are no lines).
  [[noreturn]] void failAt(size_t offset, const std::string& msg) const {
    throw calib::InputError(path_, 0, 0, "at byte " + std::to_string(offset) + ": " + msg);
  }

  /// A vertex coordinate (in the file's unit): finite and within the cell bound once in mm.
  void coordinate(double v, const std::function<void(const std::string&)>& bad) const {
    if (!std::isfinite(v)) bad("expected a finite coordinate, found " + std::to_string(v));
    if (!(std::abs(v * scale_) <= kMaxCellExtent_mm))
      bad("expected a coordinate within " + std::to_string(static_cast<long>(kMaxCellExtent_mm / 1000)) + " m of the mesh origin, found " +
          std::to_string(v) + " (" + std::to_string(v * scale_ / 1000) + " m)");
  }
  double number(const Word& w, const char* what) const {
    double v = 0;
    if (!parseDecimal(w.text, &v)) fail(w, std::string("expected ") + what + " (a finite decimal number), found " + quoted(w.text));
    return v;
  }
  // A facet normal's component (ASCII STL): the normals are not used (the triangle's corners
  // are), and exporters write nan or inf for a facet without area; so as assimp reads them
  // ([+-] nan, inf, infinity in any case), else a decimal number.
  void normalComponent(const Word& w) const {
    double v = 0;
    if (parseDecimal(w.text, &v)) return;
    std::string t(w.text);
    for (char& c : t) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (!t.empty() && (t[0] == '-' || t[0] == '+')) t.erase(0, 1);
    if (t == "nan" || t == "inf" || t == "infinity") return;
    fail(w, "expected a component of the facet's normal (a decimal number, or nan / inf as exporters write for a facet "
            "without area), found " + quoted(w.text));
  }
  double coordinate(const Word& w, const char* what) const {
    const double v = number(w, what);
    coordinate(v, [&](const std::string& m) { fail(w, std::string(what) + ": " + m); });
    return v;
  }

  // ---- PLY (http://paulbourke.net/dataformats/ply/) ----
  enum class Scalar { kI8, kU8, kI16, kU16, kI32, kU32, kF32, kF64 };
  struct PlyProperty {
    std::string name;
    bool list = false;
    Scalar count_type = Scalar::kU8, type = Scalar::kF32;
  };
  struct PlyElement {
    std::string name;
    long long count = 0;
    std::vector<PlyProperty> properties;
    Word where;
  };

  static bool scalarType(std::string_view s, Scalar* t) {
    static const std::pair<const char*, Scalar> names[] = {
        {"char", Scalar::kI8},   {"int8", Scalar::kI8},     {"uchar", Scalar::kU8},   {"uint8", Scalar::kU8},
        {"short", Scalar::kI16}, {"int16", Scalar::kI16},   {"ushort", Scalar::kU16}, {"uint16", Scalar::kU16},
        {"int", Scalar::kI32},   {"int32", Scalar::kI32},   {"uint", Scalar::kU32},   {"uint32", Scalar::kU32},
        {"float", Scalar::kF32}, {"float32", Scalar::kF32}, {"double", Scalar::kF64}, {"float64", Scalar::kF64}};
    for (const auto& [n, type] : names)
      if (s == n) return *t = type, true;
    return false;
  }
  static size_t scalarSize(Scalar t) {
    switch (t) {
      case Scalar::kI8: case Scalar::kU8: return 1;
      case Scalar::kI16: case Scalar::kU16: return 2;
      case Scalar::kI32: case Scalar::kU32: case Scalar::kF32: return 4;
      case Scalar::kF64: return 8;
    }
    return 8;
  }
  static bool isFloat(Scalar t) { return t == Scalar::kF32 || t == Scalar::kF64; }
  static std::pair<long long, long long> range(Scalar t) {
    switch (t) {
      case Scalar::kI8: return {-128, 127};
      case Scalar::kU8: return {0, 255};
      case Scalar::kI16: return {-32768, 32767};
      case Scalar::kU16: return {0, 65535};
      case Scalar::kI32: return {INT32_MIN, INT32_MAX};
      default: return {0, UINT32_MAX};
    }
  }
  static bool isVertexIndexList(const PlyElement& e, const PlyProperty& p) {
    return e.name == "face" && p.list && isVertexIndices(p);
  }
  static bool isVertexIndices(const PlyProperty& p) { return p.name == "vertex_indices" || p.name == "vertex_index"; }

  /// A text format's bytes before `end` hold no control byte but white space: assimp's parsers
  /// stop at a NUL and misread what follows ("Invalid face index", no line).
  void textOnly(size_t end) const {
    int line = 1, column = 1;
    for (size_t i = 0; i < end && i < d_.size(); ++i) {
      const auto c = static_cast<unsigned char>(d_[i]);
      if (c == '\n') {
        ++line;
        column = 1;
        continue;
      }
      // a carriage return ends a line for assimp but not for the line counting here: only as CRLF
      if (c == '\r' && (i + 1 >= d_.size() || d_[i + 1] != '\n'))
        fail(line, column, "expected a line feed after the carriage return (CRLF line ends), found a carriage return alone");
      // a vertical tab or a form feed separates numbers here but not for assimp: control bytes too
      if (c < 0x20 && c != '\t' && c != '\r') {
        char hex[8];
        std::snprintf(hex, sizeof hex, "0x%02X", c);
        fail(line, column, std::string("expected text, found the control byte ") + hex);
      }
      ++column;
    }
  }

  void ply() {
    Scanner s(d_, 0, 1);
    Word w;
    if (!s.wordOnLine(&w) || w.text != "ply" || !s.endLine(&w)) fail(1, 1, "expected a PLY file starting with the line 'ply', found " + quoted(d_.substr(0, d_.find('\n'))));
    enum class Format { kNone, kAscii, kLittle, kBig } format = Format::kNone;
    std::vector<PlyElement> elements;
    for (;;) {
      if (s.atEnd()) fail(s.here().line, s.here().column, "expected the PLY header to end with 'end_header', found the end of the file");
      if (!s.wordOnLine(&w)) {
        const Word at = s.here();
        s.endLine(&w);
        fail(at, "expected a PLY header line (format, element, property, comment, obj_info, end_header), found an empty line");
      }
      const Word keyword = w;
      if (w.text == "comment" || w.text == "obj_info") {
        s.restOfLine();
        continue;
      }
      if (w.text == "end_header") {
        if (!s.endLine(&w)) fail(w, "expected nothing after 'end_header' on its line, found " + quoted(w.text));
        break;
      }
      std::vector<Word> args;
      while (s.wordOnLine(&w)) args.push_back(w);
      s.endLine(&w);
      const auto argument = [&](size_t i, const char* expected) -> const Word& {
        if (i >= args.size()) fail(keyword, "'" + std::string(keyword.text) + "': expected " + expected + ", found the end of the line");
        return args[i];
      };
      if (keyword.text == "format") {
        if (format != Format::kNone) fail(keyword, "expected one 'format' line, found a second one");
        const Word& f = argument(0, "ascii, binary_little_endian or binary_big_endian");
        if (f.text == "ascii") format = Format::kAscii;
        else if (f.text == "binary_little_endian") format = Format::kLittle;
        else if (f.text == "binary_big_endian") format = Format::kBig;
        else fail(f, "expected the format ascii, binary_little_endian or binary_big_endian, found " + quoted(f.text));
        const Word& v = argument(1, "the version 1.0");
        if (v.text != "1.0") fail(v, "expected the PLY version 1.0, found " + quoted(v.text));
        if (args.size() > 2) fail(args[2], "expected the end of the 'format' line, found " + quoted(args[2].text));
      } else if (keyword.text == "element") {
        if (format == Format::kNone) fail(keyword, "expected the 'format' line before the first element, found 'element'");
        PlyElement e;
        e.name = std::string(argument(0, "an element name").text);
        e.where = keyword;
        const Word& c = argument(1, "the number of elements");
        // an element takes at least a byte in the file (the properties come later: checked in the body)
        if (!parseDecimalInteger(c.text, &e.count) || e.count < 0 || e.count > INT32_MAX)
          fail(c, "expected the number of '" + e.name + "' elements (0 .. 2147483647), found " + quoted(c.text));
        if (args.size() > 2) fail(args[2], "expected the end of the 'element' line, found " + quoted(args[2].text));
        for (const auto& other : elements)
          if (other.name == e.name) fail(args[0], "expected each element name once, found '" + e.name + "' a second time");
        // assimp turns triangle strips into faces without checking their indices
        if (e.name == "tristrips") fail(args[0], "expected the faces as element 'face', found 'tristrips' (not supported)");
        elements.push_back(std::move(e));
      } else if (keyword.text == "property") {
        if (elements.empty()) fail(keyword, "expected an 'element' line before the first property, found 'property'");
        PlyProperty p;
        size_t i = 0;
        if (argument(0, "a type or 'list'").text == "list") {
          p.list = true;
          const Word& ct = argument(1, "the type of the list's count");
          if (!scalarType(ct.text, &p.count_type) || isFloat(p.count_type))
            fail(ct, "expected an integer type for the list's count (uchar, ushort, uint, char, short, int), found " + quoted(ct.text));
          i = 2;
        }
        const Word& t = argument(i, "a type");
        if (!scalarType(t.text, &p.type))
          fail(t, "expected a PLY type (char, uchar, short, ushort, int, uint, float, double, int8 .. float64), found " + quoted(t.text));
        p.name = std::string(argument(i + 1, "a property name").text);
        if (args.size() > i + 2) fail(args[i + 2], "expected the end of the 'property' line, found " + quoted(args[i + 2].text));
        for (const auto& other : elements.back().properties)
          if (other.name == p.name) fail(args[i + 1], "expected each property name once per element, found '" + p.name + "' a second time");
        if (elements.back().name == "face" && isVertexIndices(p) && (!p.list || isFloat(p.type)))
          fail(p.list ? t : args[0], "expected the vertex indices of a face as a list of an integer type (property list uchar int " + p.name + "), found " +
                                         quoted(p.list ? t.text : args[0].text));
        elements.back().properties.push_back(std::move(p));
      } else {
        fail(keyword, "expected a PLY header line (format, element, property, comment, obj_info, end_header), found " + quoted(keyword.text));
      }
    }
    // what assimp needs: vertices with x, y and z
    long long vertices = -1;
    for (const auto& e : elements) {
      if (e.name != "vertex") continue;
      vertices = e.count;
      for (const char* axis : {"x", "y", "z"}) {
        const auto it = std::find_if(e.properties.begin(), e.properties.end(), [&](const PlyProperty& p) { return p.name == axis; });
        if (it == e.properties.end() || it->list)
          fail(e.where, std::string("element 'vertex': expected a property ") + axis + " (a number), found " + (it == e.properties.end() ? "none" : "a list"));
      }
    }
    textOnly(format == Format::kAscii ? d_.size() : s.offset());
    if (vertices < 0) fail(1, 1, "expected an element 'vertex' in the PLY header, found none");
    // a collision body needs faces (assimp would reject the file as a whole, without a line)
    const auto face = std::find_if(elements.begin(), elements.end(), [](const PlyElement& e) { return e.name == "face"; });
    if (face == elements.end()) fail(1, 1, "expected an element 'face' in the PLY header (a mesh of faces), found none");
    if (std::none_of(face->properties.begin(), face->properties.end(), [&](const PlyProperty& p) { return isVertexIndexList(*face, p); }))
      fail(face->where, "element 'face': expected a property list of vertex indices (property list uchar int vertex_indices), found none");
    if (face->count == 0) fail(face->where, "element 'face': expected at least one face, found 0");
    if (format == Format::kAscii) plyAscii(s, elements, vertices);
    else plyBinary(s.offset(), elements, vertices, format == Format::kBig);
  }

  static std::string elementName(const PlyElement& e, long long i) {
    return "'" + e.name + "' " + std::to_string(i + 1) + " of " + std::to_string(e.count);
  }

  void plyAscii(Scanner& s, const std::vector<PlyElement>& elements, long long vertices) {
    Word w;
    for (const auto& e : elements) {
      for (long long i = 0; i < e.count; ++i) {
        // one element a line (assimp reads them so)
        if (s.atEnd()) fail(s.here(), "expected " + elementName(e, i) + ", found the end of the file (a truncated file?)");
        const Word start = s.here();
        for (const auto& p : e.properties) {
          long long n = 1;
          if (p.list) {
            if (!s.wordOnLine(&w)) fail(s.here(), "expected the number of values of " + p.name + " in " + elementName(e, i) + ", found the end of the line");
            const auto [lo, hi] = range(p.count_type);
            if (!parseDecimalInteger(w.text, &n) || n < std::max(lo, 0LL) || n > hi)
              fail(w, "expected the number of values of " + p.name + " in " + elementName(e, i) + " (an integer 0.." + std::to_string(hi) + "), found " + quoted(w.text));
            if (isVertexIndexList(e, p) && n < 3)
              fail(w, "expected a face of 3 or more vertices (" + elementName(e, i) + "), found " + std::to_string(n));
          }
          for (long long k = 0; k < n; ++k) {
            if (!s.wordOnLine(&w))
              fail(s.here(), "expected " + std::to_string(n) + (n == 1 ? " value" : " values") + " of " + p.name + " in " + elementName(e, i) + " on line " +
                                 std::to_string(start.line) + ", found " + std::to_string(k) + " (a truncated line?)");
            if (isFloat(p.type)) {
              const double v = number(w, (p.name + " of " + elementName(e, i)).c_str());
              if (e.name == "vertex" && (p.name == "x" || p.name == "y" || p.name == "z"))
                coordinate(v, [&](const std::string& m) { fail(w, p.name + " of " + elementName(e, i) + ": " + m); });
            } else {
              long long v = 0;
              const auto [lo, hi] = range(p.type);
              if (!parseDecimalInteger(w.text, &v) || v < lo || v > hi)
                fail(w, "expected " + p.name + " of " + elementName(e, i) + " (an integer " + std::to_string(lo) + ".." + std::to_string(hi) + "), found " + quoted(w.text));
              if (isVertexIndexList(e, p) && (v < 0 || v >= vertices))
                fail(w, "expected a vertex index 0.." + std::to_string(vertices - 1) + " in " + elementName(e, i) + ", found " + std::to_string(v));
              if (e.name == "vertex" && (p.name == "x" || p.name == "y" || p.name == "z"))
                coordinate(static_cast<double>(v), [&](const std::string& m) { fail(w, p.name + " of " + elementName(e, i) + ": " + m); });
            }
          }
        }
        if (!s.endLine(&w)) fail(w, "expected the end of " + elementName(e, i) + " (one element a line), found " + quoted(w.text));
      }
    }
    if (s.word(&w)) fail(w, "expected the end of the file after the declared elements, found " + quoted(w.text));
  }

  void plyBinary(size_t p, const std::vector<PlyElement>& elements, long long vertices, bool big_endian) {
    const auto read = [&](Scalar t, const PlyElement& e, long long i, const std::string& what) -> std::pair<double, long long> {
      const size_t n = scalarSize(t);
      if (d_.size() - p < n)
        failAt(p, "expected " + what + " of " + elementName(e, i) + " (" + std::to_string(n) + " bytes), found the end of the file (a truncated file?)");
      unsigned char b[8];
      for (size_t k = 0; k < n; ++k) b[k] = static_cast<unsigned char>(d_[p + (big_endian ? n - 1 - k : k)]);
      p += n;
      switch (t) {
        case Scalar::kI8: return {0, static_cast<int8_t>(b[0])};
        case Scalar::kU8: return {0, b[0]};
        case Scalar::kI16: { int16_t v; std::memcpy(&v, b, 2); return {0, v}; }
        case Scalar::kU16: { uint16_t v; std::memcpy(&v, b, 2); return {0, v}; }
        case Scalar::kI32: { int32_t v; std::memcpy(&v, b, 4); return {0, v}; }
        case Scalar::kU32: { uint32_t v; std::memcpy(&v, b, 4); return {0, v}; }
        case Scalar::kF32: { float v; std::memcpy(&v, b, 4); return {v, 0}; }
        case Scalar::kF64: { double v; std::memcpy(&v, b, 8); return {v, 0}; }
      }
      return {0, 0};
    };
    for (const auto& e : elements) {
      if (e.properties.empty() && e.count > 0) failAt(p, "expected properties for the " + std::to_string(e.count) + " elements '" + e.name + "', found none");
      for (long long i = 0; i < e.count; ++i) {
        for (const auto& pr : e.properties) {
          long long n = 1;
          const size_t at = p;
          if (pr.list) {
            n = read(pr.count_type, e, i, "the number of values of " + pr.name).second;
            if (n < 0) failAt(at, "expected the number of values of " + pr.name + " in " + elementName(e, i) + " (>= 0), found " + std::to_string(n));
            if (isVertexIndexList(e, pr) && n < 3)
              failAt(at, "expected a face of 3 or more vertices (" + elementName(e, i) + "), found " + std::to_string(n));
          }
          for (long long k = 0; k < n; ++k) {
            const size_t value_at = p;
            const auto [f, v] = read(pr.type, e, i, pr.name);
            const bool axis = e.name == "vertex" && (pr.name == "x" || pr.name == "y" || pr.name == "z");
            if (isFloat(pr.type)) {
              if (!std::isfinite(f)) failAt(value_at, "expected " + pr.name + " of " + elementName(e, i) + " to be a finite number, found " + std::to_string(f));
              if (axis) coordinate(f, [&](const std::string& m) { failAt(value_at, pr.name + " of " + elementName(e, i) + ": " + m); });
            } else {
              if (isVertexIndexList(e, pr) && (v < 0 || v >= vertices))
                failAt(value_at, "expected a vertex index 0.." + std::to_string(vertices - 1) + " in " + elementName(e, i) + ", found " + std::to_string(v));
              if (axis) coordinate(static_cast<double>(v), [&](const std::string& m) { failAt(value_at, pr.name + " of " + elementName(e, i) + ": " + m); });
            }
          }
        }
      }
    }
    if (p != d_.size())
      failAt(p, "expected the end of the file after the declared elements, found " + std::to_string(d_.size() - p) + " more bytes");
  }

  // ---- STL ----
  /// Checks an STL file; returns where an ASCII one's 'solid' starts (after blank lines or
  /// spaces), std::string::npos for a binary one.
  size_t stl() {
    const uint64_t size = d_.size();
    if (size >= 84) {
      uint32_t n = 0;
      for (int k = 3; k >= 0; --k) n = (n << 8) | static_cast<unsigned char>(d_[80 + static_cast<size_t>(k)]);
      const uint64_t expected = 84 + 50 * static_cast<uint64_t>(n);
      if (expected == size) {
        stlBinary(n);
        return std::string::npos;
      }
      // assimp computes this size in 32 bits: a count that wraps would make it read past the end
      if (static_cast<uint32_t>(expected) == static_cast<uint32_t>(size))
        failAt(80, "expected a binary STL of 84 + 50 x " + std::to_string(n) + " = " + std::to_string(expected) + " bytes, found " + std::to_string(size) + " bytes");
    }
    size_t first = 0;
    while (first < d_.size() && std::isspace(static_cast<unsigned char>(d_[first]))) ++first;
    const bool text_start = d_.compare(first, 5, "solid") == 0;
    const bool binary_bytes = std::any_of(d_.begin(), d_.end(), [](char c) {
      const auto u = static_cast<unsigned char>(c);
      return u < 0x20 && u != '\n' && u != '\r' && u != '\t' && u != '\f' && u != '\v';
    });
    if (!text_start && !binary_bytes && first < d_.size()) {
      // an ASCII STL in upper case (SOLID, FACET ...): assimp reads only lower-case keywords
      std::string head(d_.substr(first, 5));
      for (char& ch : head) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
      if (head == "solid")
        fail(1, static_cast<int>(first) + 1, "expected an ASCII STL's keywords in lower case ('solid', 'facet', 'vertex', ...), found '" +
                                                 std::string(d_.substr(first, 5)) + "'");
    }
    if (!text_start || binary_bytes) {
      if (size < 84) fail(1, 1, "expected an STL file (ASCII starting with 'solid', or binary of 84 + 50 x N bytes), found " + std::to_string(size) + " bytes");
      uint32_t n = 0;
      for (int k = 3; k >= 0; --k) n = (n << 8) | static_cast<unsigned char>(d_[80 + static_cast<size_t>(k)]);
      const uint64_t expected = 84 + 50 * static_cast<uint64_t>(n);
      failAt(80, "expected a binary STL of 84 + 50 x N bytes (N = " + std::to_string(n) + " triangles at byte 80: " +
                     std::to_string(expected) + " bytes), found " + std::to_string(size) + " bytes" +
                     (size > expected ? " (" + std::to_string(size - expected) + " after the last triangle)" : std::string(" (a truncated file?)")));
    }
    textOnly(d_.size());  // a vertical tab or a lone carriage return would split numbers differently for assimp
    stlAscii();
    return first;
  }

  void stlBinary(uint32_t n) {
    if (n == 0) failAt(80, "expected at least one triangle, found a count of 0");
    for (uint64_t t = 0; t < n; ++t) {
      for (int k = 0; k < 9; ++k) {
        const size_t at = static_cast<size_t>(84 + 50 * t + 12 + 4 * static_cast<uint64_t>(k));
        unsigned char b[4];
        for (int j = 0; j < 4; ++j) b[j] = static_cast<unsigned char>(d_[at + static_cast<size_t>(j)]);
        uint32_t bits = static_cast<uint32_t>(b[0]) | static_cast<uint32_t>(b[1]) << 8 | static_cast<uint32_t>(b[2]) << 16 | static_cast<uint32_t>(b[3]) << 24;
        float f;
        std::memcpy(&f, &bits, 4);
        coordinate(f, [&](const std::string& m) { failAt(at, "triangle " + std::to_string(t + 1) + " of " + std::to_string(n) + ": " + m); });
      }
    }
  }

  void stlAscii() {
    Scanner s(d_, 0, 1);
    Word w;
    const auto expect = [&](const char* keyword, const char* after) {
      if (!s.word(&w)) fail(s.here(), std::string("expected '") + keyword + "'" + after + ", found the end of the file (a truncated file?)");
      if (w.text != keyword) fail(w, std::string("expected '") + keyword + "'" + after + ", found " + quoted(w.text));
    };
    int solids = 0;
    long long facets = 0;
    Word last_end;
    while (s.word(&w)) {
      if (w.text != "solid") fail(w, std::string("expected ") + (solids ? "'solid' or the end of the file" : "'solid'") + ", found " + quoted(w.text));
      ++solids;
      s.restOfLine();  // the solid's name
      for (;;) {
        if (!s.word(&w)) fail(s.here(), "expected 'facet' or 'endsolid', found the end of the file (a truncated file?)");
        if (w.text == "endsolid") {
          last_end = w;
          s.restOfLine();
          break;
        }
        if (w.text != "facet") fail(w, "expected 'facet' or 'endsolid', found " + quoted(w.text));
        expect("normal", " after 'facet'");
        for (int k = 0; k < 3; ++k) {
          // on the keyword's line, as assimp reads them
          if (!s.wordOnLine(&w)) fail(s.here(), "expected the 3 numbers of the facet's normal on its line, found the end of the line");
          normalComponent(w);
        }
        expect("outer", "");
        expect("loop", " after 'outer'");
        for (int v = 0; v < 3; ++v) {
          expect("vertex", v == 0 ? "" : " (a facet has 3 vertices)");
          for (int k = 0; k < 3; ++k) {
            if (!s.wordOnLine(&w)) fail(s.here(), "expected the 3 coordinates of a vertex on its line, found the end of the line");
            coordinate(w, "a vertex coordinate");
          }
        }
        expect("endloop", " (a facet has 3 vertices)");
        expect("endfacet", "");
        ++facets;
      }
    }
    if (solids == 0) fail(s.here(), "expected 'solid', found an empty file");
    if (facets == 0) fail(last_end, "expected at least one 'facet', found 'endsolid' with none before it");
  }

  // ---- OBJ (vertices and polygonal faces; see http://paulbourke.net/dataformats/obj/) ----
  void obj() {
    textOnly(d_.size());
    Scanner s(d_, 0, 1);
    long long v = 0, vt = 0, vn = 0;
    Word w;
    bool any = false;
    long long faces = 0;
    while (!s.atEnd()) {
      if (!s.wordOnLine(&w) || w.text[0] == '#') {
        s.restOfLine();
        continue;
      }
      // assimp reads a statement only at the start of its line and skips an indented one whole
      if (w.column != 1) fail(w, "expected the statement " + quoted(w.text) + " at the start of its line (an indented line is skipped by the mesh reader), found it at column " + std::to_string(w.column));
      any = true;
      const Word keyword = w;
      const std::string_view k = w.text;
      if (k == "v" || k == "vt" || k == "vn" || k == "vp") {
        std::vector<Word> args;
        while (s.wordOnLine(&w)) args.push_back(w);
        const size_t lo = k == "v" || k == "vn" ? 3 : 1, hi = k == "v" ? 7 : 3;
        if (args.size() < lo || args.size() > hi || (k == "v" && args.size() == 5))
          fail(args.size() < lo ? s.here() : args[hi < args.size() ? hi : 3],
               "'" + std::string(k) + "': expected " + (k == "v" ? "3 coordinates (x y z, optionally w, or r g b)" : k == "vn" ? "3 numbers" : "1 to 3 numbers") +
                   ", found " + std::to_string(args.size()) + (args.size() < lo ? " (a truncated line?)" : ""));
        double x[3] = {0, 0, 0};
        for (size_t i = 0; i < args.size(); ++i) {
          // assimp counts a vertex component only when it starts with a digit or a sign ('.5' would
          // shift the vertex's components and, with them, the face indices)
          const char c0 = args[i].text[0];
          if (!(std::isdigit(static_cast<unsigned char>(c0)) || c0 == '-' || c0 == '+'))
            fail(args[i], "expected a number starting with a digit or a sign (write '0.5', not '.5'), found " + quoted(args[i].text));
          if (k == "v" && i < 3) x[i] = coordinate(args[i], "a vertex coordinate");
          else number(args[i], "a number");
        }
        if (k == "v" && args.size() == 4) {
          // x y z w: assimp reads the vertex (x/w, y/w, z/w)
          const double wh = number(args[3], "the homogeneous w");
          if (wh == 0) fail(args[3], "expected a non-zero homogeneous w (the vertex is x/w, y/w, z/w), found " + quoted(args[3].text));
          for (const double c : x) coordinate(c / wh, [&](const std::string& m) { fail(args[3], "the vertex x/w, y/w, z/w: " + m); });
        }
        if (k == "v") ++v;
        else if (k == "vt") ++vt;
        else if (k == "vn") ++vn;
        s.endLine(&w);
      } else if (k == "f" || k == "l" || k == "p") {
        const size_t least = k == "f" ? 3 : k == "l" ? 2 : 1;
        size_t n = 0;
        while (s.wordOnLine(&w)) {
          ++n;
          objReference(w, v, vt, vn);
        }
        if (n < least)
          fail(s.here(), "'" + std::string(k) + "': expected " + std::to_string(least) + " or more vertex references, found " + std::to_string(n) + " (a truncated line?)");
        if (k == "f") ++faces;
        s.endLine(&w);
      } else if (k == "o" || k == "g" || k == "s" || k == "usemtl" || k == "mtllib") {
        // materials are of no use here, and assimp would open whatever file mtllib names
        if (k == "mtllib") mtllib_offsets_.push_back(static_cast<size_t>(keyword.text.data() - d_.data()));
        s.restOfLine();
      } else {
        fail(keyword, "expected an OBJ statement (v, vt, vn, vp, f, l, p, o, g, s, usemtl, mtllib, #), found " + quoted(k));
      }
    }
    if (!any) fail(1, 1, "expected OBJ statements (v, f, ...), found an empty file");
    if (!s.lastLineEnded()) {
      const Word end = s.here();
      fail(end, "expected the last line to end with a line end, found the end of the file (a truncated file?)");
    }
    if (faces == 0) fail(s.here(), "expected at least one face ('f' with 3 or more vertex references), found none before the end of the file");
  }

  /// One corner of a face, line or point: v, v/vt, v//vn or v/vt/vn (1-based; negative counts
  /// back from the last one read).
  void objReference(const Word& w, long long v, long long vt, long long vn) const {
    std::string_view parts[3];
    size_t count = 0, start = 0;
    for (size_t i = 0; i <= w.text.size(); ++i) {
      if (i == w.text.size() || w.text[i] == '/') {
        if (count == 3) fail(w, "expected a vertex reference v, v/vt, v//vn or v/vt/vn, found " + quoted(w.text));
        parts[count++] = w.text.substr(start, i - start);
        start = i + 1;
      }
    }
    const long long limits[3] = {v, vt, vn};
    const char* names[3] = {"vertex", "texture coordinate", "normal"};
    for (size_t i = 0; i < count; ++i) {
      if (parts[i].empty() && i > 0) continue;  // v//vn, v/vt/
      long long x = 0;
      if (!parseDecimalInteger(parts[i], &x) || x == 0)
        fail(w, "expected a vertex reference v, v/vt, v//vn or v/vt/vn (non-zero integers), found " + quoted(w.text));
      if (x > limits[i] || -x > limits[i])
        fail(w, std::string("expected a ") + names[i] + " index 1.." + std::to_string(limits[i]) + " (or -1..-" + std::to_string(limits[i]) +
                    ": the ones read so far), found " + std::to_string(x));
    }
  }

  /// Where the OBJ's mtllib statements start (checkMeshBytes turns them into comments).
  const std::vector<size_t>& mtllibOffsets() const { return mtllib_offsets_; }

 private:
  const std::string& path_;
  std::string_view d_;
  double scale_;
  std::vector<size_t> mtllib_offsets_;
};

std::string lowerExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

/// What assimp gave before its post-processing: every face index within its mesh, every
/// coordinate finite and within the cell bound, every node's mesh index within the scene.
void checkScene(const std::string& path, const aiScene& scene, double scale_to_mm) {
  const auto fail = [&](const std::string& msg) { throw calib::InputError(path, 0, 0, msg); };
  if (scene.mNumMeshes > 0 && !scene.mMeshes) fail("expected the meshes assimp read, found none");
  for (unsigned m = 0; m < scene.mNumMeshes; ++m) {
    const aiMesh* am = scene.mMeshes[m];
    if (!am) fail("expected mesh " + std::to_string(m + 1) + ", found none");
    if (am->mNumVertices > 0 && !am->mVertices) fail("mesh " + std::to_string(m + 1) + ": expected its vertices, found none");
    if (am->mNumFaces > 0 && !am->mFaces) fail("mesh " + std::to_string(m + 1) + ": expected its faces, found none");
    for (unsigned v = 0; v < am->mNumVertices; ++v) {
      const aiVector3D& p = am->mVertices[v];
      for (const double x : {p.x, p.y, p.z})
        if (!std::isfinite(x) || !(std::abs(x * scale_to_mm) <= kMaxCellExtent_mm))
          fail("mesh " + std::to_string(m + 1) + " vertex " + std::to_string(v + 1) + ": expected a finite coordinate within " +
               std::to_string(static_cast<long>(kMaxCellExtent_mm / 1000)) + " m of the origin, found " + std::to_string(x));
    }
    for (unsigned f = 0; f < am->mNumFaces; ++f) {
      const aiFace& face = am->mFaces[f];
      if (face.mNumIndices == 0 || !face.mIndices) fail("mesh " + std::to_string(m + 1) + " face " + std::to_string(f + 1) + ": expected vertex indices, found none");
      for (unsigned k = 0; k < face.mNumIndices; ++k)
        if (face.mIndices[k] >= am->mNumVertices)
          fail("mesh " + std::to_string(m + 1) + " face " + std::to_string(f + 1) + ": expected vertex indices below " + std::to_string(am->mNumVertices) +
               ", found " + std::to_string(face.mIndices[k]));
    }
  }
  if (!scene.mRootNode) fail("expected a scene with a root node, found none");
  // nodes: iteratively (a deep hierarchy must not exhaust the stack), with a bound on their number
  std::vector<std::pair<const aiNode*, int>> stack{{scene.mRootNode, 0}};
  size_t nodes = 0;
  while (!stack.empty()) {
    const auto [node, depth] = stack.back();
    stack.pop_back();
    if (++nodes > 1000000 || depth > 1000) fail("expected a scene graph of at most 1,000,000 nodes and 1,000 levels, found more");
    for (unsigned i = 0; i < node->mNumMeshes; ++i)
      if (!node->mMeshes || node->mMeshes[i] >= scene.mNumMeshes)
        fail("node '" + std::string(node->mName.C_Str()) + "': expected mesh indices below " + std::to_string(scene.mNumMeshes) + ", found a larger one");
    const aiMatrix4x4& t = node->mTransformation;
    for (const float x : {t.a1, t.a2, t.a3, t.a4, t.b1, t.b2, t.b3, t.b4, t.c1, t.c2, t.c3, t.c4, t.d1, t.d2, t.d3, t.d4})
      if (!std::isfinite(x)) fail("node '" + std::string(node->mName.C_Str()) + "': expected a finite transformation, found " + std::to_string(x));
    if (node->mNumChildren > 0 && !node->mChildren) fail("node '" + std::string(node->mName.C_Str()) + "': expected its children, found none");
    for (unsigned i = 0; i < node->mNumChildren; ++i) {
      if (!node->mChildren[i]) fail("node '" + std::string(node->mName.C_Str()) + "': expected child " + std::to_string(i + 1) + ", found none");
      stack.emplace_back(node->mChildren[i], depth + 1);
    }
  }
}

/// Checks a PLY, STL or OBJ file's bytes (throws InputError) and makes an OBJ's mtllib
/// statements comments (the bytes assimp reads are these).
void checkMeshBytes(const std::string& path, std::string& bytes, double scale_to_mm) {
  MeshChecker c(path, bytes, scale_to_mm);
  const std::string ext = lowerExtension(path);
  if (ext == ".ply") c.ply();
  else if (ext == ".stl") {
    // an ASCII STL after blank lines or spaces (checked): assimp needs 'solid' first
    const size_t solid = c.stl();
    if (solid != std::string::npos && solid > 0) bytes.erase(0, solid);
  }
  else if (ext == ".obj") c.obj();
  for (const size_t at : c.mtllibOffsets()) bytes[at] = '#';
}

/// A COLLADA file's unit (mm a unit): <asset><unit meter="..."/>, 1 m when it has none (the
/// COLLADA specification's default). Throws InputError on a value that is not a positive number.
double colladaUnitMm(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  const std::string text = s.str();
  // the document's own <asset> (the first one, before any library): its <unit>
  const size_t asset = text.find("<asset"), asset_end = asset == std::string::npos ? asset : text.find("</asset>", asset);
  const size_t unit = asset_end == std::string::npos ? std::string::npos : text.find("<unit", asset);
  const size_t end = unit == std::string::npos || unit > asset_end ? std::string::npos : text.find('>', unit);
  if (unit == std::string::npos || end == std::string::npos) return 1000.0;
  const std::string tag = text.substr(unit, end - unit);
  const size_t meter = tag.find("meter=");
  if (meter == std::string::npos || meter + 7 >= tag.size()) return 1000.0;
  const char quote = tag[meter + 6];
  const size_t close = tag.find(quote, meter + 7);
  const std::string value = close == std::string::npos ? std::string() : tag.substr(meter + 7, close - meter - 7);
  char* stop = nullptr;
  const double m = std::strtod(value.c_str(), &stop);
  if (value.empty() || *stop != '\0' || !(m > 0) || !std::isfinite(m))
    throw calib::InputError(path, 0, 0, "<unit meter=...>: expected a positive number of metres, found '" + value + "'");
  return m * 1000.0;
}

}  // namespace

Mesh loadMesh(const std::string& path, double scale_to_mm) {
  if (!(scale_to_mm > 0) || !std::isfinite(scale_to_mm))
    throw calib::ArgumentError("loadMesh: scale_to_mm must be a positive number, got " + std::to_string(scale_to_mm));
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw calib::InputError(path, 0, 0, "expected a mesh file, found a directory");
  if (!std::filesystem::is_regular_file(path, ec))
    throw calib::InputError(path, 0, 0, "expected a mesh file, found no such file");
  const std::string ext = lowerExtension(path);
  const bool checked_format = ext == ".ply" || ext == ".stl" || ext == ".obj";
  std::string bytes;
  if (checked_format) {
    // read at the file's size: running out of memory is std::bad_alloc from resize (a stream
    // copy, s << in.rdbuf(), would catch it and leave a truncated text)
    std::ifstream in(path, std::ios::binary | std::ios::ate);
    const std::streamoff size = in ? static_cast<std::streamoff>(in.tellg()) : -1;
    if (size < 0) throw calib::InputError(path, 0, 0, "expected a mesh file, cannot read it");
    bytes.resize(static_cast<size_t>(size));
    in.seekg(0);
    if (!in.read(bytes.data(), size) || in.gcount() != size) throw calib::InputError(path, 0, 0, "expected a mesh file, cannot read it");
    checkMeshBytes(path, bytes, scale_to_mm);
  }
  Assimp::Importer importer;
  // Read without post-processing, check what was read (checkScene), then: triangulate
  // polygons, drop points and lines, merge duplicated vertices (for STL, which stores every
  // triangle's corners), apply the scene graph's node transforms.
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  // COLLADA: coordinates as written (assimp would turn a Z_UP file into Y-up, the robot cell's
  // z is up); its <unit>, which assimp applies (to metres), is checked against the cell's below
  importer.SetPropertyBool(AI_CONFIG_IMPORT_COLLADA_IGNORE_UP_DIRECTION, true);
  if (ext == ".dae") {
    const double file_mm = colladaUnitMm(path);
    // (a unit written in single precision, SketchUp's inch 0.02539999969, is that unit)
    if (std::abs(file_mm - scale_to_mm) > 1e-6 * scale_to_mm)
      throw calib::InputError(path, 0, 0, "expected the cell's units to be the file's own (<unit meter=\"" + calib::formatFixed(file_mm / 1000, 6) +
                                              "\">: " + calib::formatFixed(file_mm, 4) + " mm a unit), found " + calib::formatFixed(scale_to_mm, 4) +
                                              " mm a unit: give the object units that match the file");
    scale_to_mm = 1000.0;  // assimp has applied the file's unit: its coordinates are metres
  }
  // the bytes checked above (not the file again), so what assimp reads is what was checked
  const aiScene* scene = checked_format ? importer.ReadFileFromMemory(bytes.data(), bytes.size(), 0, ext.c_str() + 1) : importer.ReadFile(path, 0);
  const auto unreadable = [&]() {
    std::string why = importer.GetErrorString();
    why.erase(0, std::min(why.size(), why.find_first_not_of(" \t\r\n")));
    why.erase(why.find_last_not_of(" \t\r\n") + 1);
    // assimp catches what is thrown inside it and keeps its text: out of memory is not a bad
    // file (the plug-in's ACCURA_ERROR_OUT_OF_MEMORY, docs/plugin.md)
    if (why.find("bad_alloc") != std::string::npos) throw std::bad_alloc();
    throw calib::InputError(path, 0, 0, "expected a mesh file assimp can read (STL, OBJ, PLY, 3MF, glTF, COLLADA, ...), found: " +
                                     (why.empty() ? std::string("assimp gave no reason (out of memory?)") : why));
  };
  if (!scene || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) || !scene->mRootNode) unreadable();
  checkScene(path, *scene, scale_to_mm);
  scene = importer.ApplyPostProcessing(aiProcess_ValidateDataStructure | aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                       aiProcess_SortByPType | aiProcess_PreTransformVertices);
  if (!scene || !scene->mRootNode) unreadable();
  Mesh mesh;
  mesh.file = path;
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* am = scene->mMeshes[m];
    if (!am || !(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
    const int base = static_cast<int>(mesh.vertices_mm.size());
    for (unsigned v = 0; v < am->mNumVertices; ++v) {
      const aiVector3D& p = am->mVertices[v];
      const Eigen::Vector3d x = Eigen::Vector3d(p.x, p.y, p.z) * scale_to_mm;
      // node transforms can move a vertex checked above
      if (!x.allFinite() || !(x.cwiseAbs().maxCoeff() <= kMaxCellExtent_mm))
        throw calib::InputError(path, 0, 0, "expected vertex coordinates within " + std::to_string(static_cast<long>(kMaxCellExtent_mm / 1000)) +
                                         " m of the origin once the scene's transforms are applied, found vertex " + std::to_string(v + 1) + " at " +
                                         std::to_string(x.cwiseAbs().maxCoeff() / 1000) + " m");
      mesh.vertices_mm.push_back(x);
    }
    for (unsigned f = 0; f < am->mNumFaces; ++f) {
      const aiFace& face = am->mFaces[f];
      if (face.mNumIndices != 3) continue;
      std::array<int, 3> t{};
      bool ok = true;
      for (int k = 0; k < 3; ++k) {
        if (face.mIndices[k] >= am->mNumVertices) ok = false;
        else t[k] = base + static_cast<int>(face.mIndices[k]);
      }
      if (!ok) throw calib::InputError(path, 0, 0, "expected vertex indices below " + std::to_string(am->mNumVertices) + ", found a larger one (face " + std::to_string(f) + ")");
      mesh.triangles.push_back(t);
    }
  }
  if (mesh.triangles.empty())
    throw calib::InputError(path, 0, 0, "expected a mesh with triangles, found none (" + std::to_string(scene->mNumMeshes) + " mesh(es), no faces)");
  // triangles without area (three equal, two equal or collinear corners, as CAD exports leave
  // them on edges) bound no volume, and a sphere's distance to them is not defined (FCL gave
  // 0 mm for a sphere 100 mm away): left out
  const size_t all = mesh.triangles.size();
  mesh.triangles.erase(std::remove_if(mesh.triangles.begin(), mesh.triangles.end(),
                                      [&](const std::array<int, 3>& t) {
                                        const Eigen::Vector3d& a = mesh.vertices_mm[static_cast<size_t>(t[0])];
                                        const Eigen::Vector3d u = mesh.vertices_mm[static_cast<size_t>(t[1])] - a;
                                        const Eigen::Vector3d v = mesh.vertices_mm[static_cast<size_t>(t[2])] - a;
                                        const double longest2 = std::max({u.squaredNorm(), v.squaredNorm(), (u - v).squaredNorm()});
                                        return !(u.cross(v).norm() > 1e-12 * longest2);
                                      }),
                       mesh.triangles.end());
  if (mesh.triangles.empty())
    throw calib::InputError(path, 1, 1, "expected a mesh with triangles, found " + std::to_string(all) + " without area");  // (the whole file: 1:1)
  // a mesh smaller than a millimetre is a unit mistake (a file in metres read as mm), not an object
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const auto& t : mesh.triangles)
    for (const int k : t) {
      lo = lo.cwiseMin(mesh.vertices_mm[static_cast<size_t>(k)]);
      hi = hi.cwiseMax(mesh.vertices_mm[static_cast<size_t>(k)]);
    }
  if ((hi - lo).norm() < 1.0)
    throw calib::InputError(path, 1, 1, "expected an object at least 1 mm across, found one of " + calib::formatFixed((hi - lo).norm(), 4) +
                                            " mm: check the units the cell gives the file (its coordinates times " +
                                            calib::formatFixed(scale_to_mm, 4) + " mm)");
  return mesh;
}

}  // namespace accura::postproc
