// Positions in an XML file's text and the message for malformed XML (xml_text.h).
#include "accura/calib/xml_text.h"

#include <tinyxml2.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <functional>
#include <tuple>
#include <vector>

#include "accura/calib/errors.h"
#include "accura/calib/text.h"

namespace accura::calib {

using tinyxml2::XMLElement;

namespace {

/// What tinyxml2's error means, in words ("found ...").
std::string describeXmlError(tinyxml2::XMLError err) {
  switch (err) {
    case tinyxml2::XML_ERROR_PARSING_ELEMENT: return "an element that is malformed or not closed";
    case tinyxml2::XML_ERROR_PARSING_ATTRIBUTE: return "a malformed attribute (name=\"value\")";
    case tinyxml2::XML_ERROR_PARSING_TEXT: return "malformed text (an unescaped '<' or '&'?)";
    case tinyxml2::XML_ERROR_PARSING_CDATA: return "an unterminated CDATA section";
    case tinyxml2::XML_ERROR_PARSING_COMMENT: return "an unterminated comment";
    case tinyxml2::XML_ERROR_PARSING_DECLARATION: return "a malformed declaration (<?...?>)";
    case tinyxml2::XML_ERROR_PARSING_UNKNOWN: return "a malformed <!...> construct";
    case tinyxml2::XML_ERROR_MISMATCHED_ELEMENT: return "an element whose end tag does not match its name";
    case tinyxml2::XML_ERROR_PARSING: return "text that is not XML (outside the root element?)";
    default: return "text that is not XML";
  }
}

/// 1-based line and column of `offset` in `text`.
std::pair<int, int> lineColumnOf(const std::string& text, size_t offset) {
  int line = 1;
  size_t start = 0;
  for (size_t i = 0; i < offset && i < text.size(); ++i)
    if (text[i] == '\n') {
      ++line;
      start = i + 1;
    }
  return {line, static_cast<int>(offset - start) + 1};
}

/// When the text ends inside an element (its end tag missing: a truncated file, a forgotten
/// </robot>), inside a start tag (also inside an attribute's value), an end tag, a comment, a
/// CDATA section or a declaration, and nothing before is malformed in the ways this scan sees (a
/// mismatched end tag): the message, and where (just after the last character that is not white
/// space). Empty otherwise.
struct UnclosedAtEnd {
  std::string message;
  int line = 0, column = 0;
};
UnclosedAtEnd unclosedAtEnd(const std::string& text) {
  struct Open {
    std::string name;
    size_t at;
  };
  std::vector<Open> open;
  const auto nameAt = [&](size_t p) {
    size_t e = p;
    while (e < text.size() && !std::isspace(static_cast<unsigned char>(text[e])) && text[e] != '>' && text[e] != '/') ++e;
    return text.substr(p, e - p);
  };
  const auto where = [&](size_t at) {
    const auto [l, c] = lineColumnOf(text, at);
    return std::to_string(l) + ":" + std::to_string(c);
  };
  UnclosedAtEnd out;
  size_t end = text.size();
  while (end > 0 && std::isspace(static_cast<unsigned char>(text[end - 1]))) --end;
  std::tie(out.line, out.column) = lineColumnOf(text, end);
  const auto outer = [&](size_t count) {  // the end tags of the `count` innermost open elements, innermost first
    std::string s;
    for (size_t k = open.size(); k-- > open.size() - count;)
      s += std::string(s.empty() ? "" : ", ") + "</" + open[k].name + "> for <" + open[k].name + "> at " + where(open[k].at);
    return s;
  };
  for (size_t p = 0;;) {
    p = text.find('<', p);
    if (p == std::string::npos) break;
    const auto skip = [&](const char* o, const char* c) {
      if (text.compare(p, std::strlen(o), o) != 0) return false;
      const size_t e = text.find(c, p + std::strlen(o));
      p = e == std::string::npos ? std::string::npos : e + std::strlen(c);
      return true;
    };
    const size_t construct = p;
    for (const auto& [o, c, what] : {std::make_tuple("<!--", "-->", "a comment"), std::make_tuple("<![CDATA[", "]]>", "a CDATA section"),
                                     std::make_tuple("<?", "?>", "a declaration"), std::make_tuple("<!", ">", "a <!...> construct")})
      if (skip(o, c)) {
        if (p == std::string::npos) {  // cut short inside it (a file cut short: what is open around it)
          out.message = std::string("the end of the file inside ") + what + " opened at " + where(construct) + " (its '" + c + "' is missing" +
                        (open.empty() ? std::string(")") : ", and then " + outer(open.size()) + ")");
          return out;
        }
        break;
      }
    if (p != construct) continue;
    if (p + 1 < text.size() && text[p + 1] == '/') {  // an end tag
      const std::string name = nameAt(p + 2);
      if (!open.empty() && text.find('>', p) == std::string::npos && open.back().name.compare(0, name.size(), name) == 0) {
        // cut short inside the end tag of the innermost open element
        out.message = "the end of the file inside the end tag </" + name + " at " + where(p) + " (the end tag </" + open.back().name + "> of <" +
                      open.back().name + "> at " + where(open.back().at) + " is cut short" +
                      (open.size() > 1 ? ", and then " + outer(open.size()).substr(outer(open.size()).find(", ") + 2) + ")" : std::string(")"));
        return out;
      }
      if (open.empty() || open.back().name != name) return {};  // mismatched: tinyxml2's message
      open.pop_back();
      p += 2;
      continue;
    }
    // a start tag: to its '>' outside quoted values
    const size_t start = p;
    char quote = 0;
    size_t q = p + 1, quote_at = 0;
    for (; q < text.size(); ++q) {
      if (quote) {
        if (text[q] == quote) quote = 0;
      } else if (text[q] == '"' || text[q] == '\'') {
        quote = text[q];
        quote_at = q;
      } else if (text[q] == '>') {
        break;
      }
    }
    const std::string name = nameAt(start + 1);
    if (q >= text.size()) {
      // an unclosed quote: the file cut short inside an attribute's value when the value runs on
      // its line to the end of the file; else tinyxml2's message (a malformed attribute)
      if (quote && text.find_first_of("<>\n", quote_at) != std::string::npos) return {};
      if (quote) {
        out.message = "the end of the file inside the value of an attribute of <" + name + " at " + where(start) + " (its closing " +
                      (quote == '"' ? "'\"'" : "\"'\"") + " and the start tag's '>' are missing" +
                      (open.empty() ? std::string(")") : ", and then " + outer(open.size()) + ")");
        return out;
      }
      out.message = "the end of the file inside the start tag <" + name + " at " + where(start) + " (its '>' is missing" +
                    (open.empty() ? std::string(")") : ", and then " + outer(open.size()) + ")");
      return out;
    }
    if (text[q - 1] != '/') open.push_back({name, start});
    p = q + 1;
  }
  if (open.empty()) return {};
  out.message = "the end of the file before the element <" + open.back().name + "> opened at " + where(open.back().at) +
                " was closed (its end tag </" + open.back().name + "> is missing" +
                (open.size() > 1 ? ", and then " + outer(open.size()).substr(outer(open.size()).find(", ") + 2) + ")" : std::string(")"));
  return out;
}

}  // namespace

void parseXml(tinyxml2::XMLDocument& doc, const std::string& text, const std::string& file,
              const std::string& what) {
  // UTF-16 (a Windows editor's "Unicode"): every other byte a NUL, which XML reads as garbage
  if (text.size() >= 2 && ((text[0] == '\xFF' && text[1] == '\xFE') || (text[0] == '\xFE' && text[1] == '\xFF')))
    throw InputError(file, 1, 1, "expected " + what + " in UTF-8, found UTF-16 (byte-order mark " +
                                     std::string(text[0] == '\xFF' ? "FF FE" : "FE FF") + "): save it as UTF-8");
  const tinyxml2::XMLError err = doc.Parse(text.data(), text.size());
  if (err != tinyxml2::XML_SUCCESS) {
    // a file that is not XML at all (a measurement CSV or a KRL program given as --robot or
    // --cell): tinyxml2's "malformed text (an unescaped '<' or '&'?)" would send the user into
    // the file to look for a '<'; say that it does not start as XML does, with its first text
    size_t p = text.compare(0, 3, "\xEF\xBB\xBF") == 0 ? 3 : 0;
    while (p < text.size() && std::isspace(static_cast<unsigned char>(text[p]))) ++p;
    if (p < text.size() && text[p] != '<') {
      const size_t line_start = text.rfind('\n', p) == std::string::npos ? 0 : text.rfind('\n', p) + 1;
      const int line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(p), '\n'));
      std::string first = text.substr(p, std::min(text.find_first_of("\r\n", p), text.size()) - p);
      if (first.size() > 40) first = first.substr(0, 40) + "...";
      throw InputError(file, line, static_cast<int>(p - line_start) + 1,
                       "expected " + what + " (XML, which starts with '<'), found text that is not XML: '" + first + "'");
    }
  }
  if (err == tinyxml2::XML_SUCCESS && doc.RootElement()) {
    // one root element: a second one (a file pasted after the first's end tag) is not part of
    // the document, and reading the first alone would silently drop it
    if (const tinyxml2::XMLElement* second = doc.RootElement()->NextSiblingElement()) {
      const int line = std::max(1, second->GetLineNum());
      size_t start = 0;
      for (int l = 1; l < line && start != std::string::npos; ++l) {
        start = text.find('\n', start);
        if (start != std::string::npos) ++start;
      }
      const size_t lt = start == std::string::npos ? std::string::npos : text.find('<', start);
      const int column = lt == std::string::npos ? 1 : static_cast<int>(lt - start) + 1;
      throw InputError(file, line, column, "expected " + what + " and nothing after its end tag </" + doc.RootElement()->Name() +
                                               ">, found another element <" + second->Name() + ">");
    }
    return;
  }
  if (err == tinyxml2::XML_SUCCESS || err == tinyxml2::XML_ERROR_EMPTY_DOCUMENT) {  // no element at all
    const bool blank = std::all_of(text.begin(), text.end(), [](char c) { return std::isspace(static_cast<unsigned char>(c)); });
    throw InputError(file, 1, 1, "expected " + what + ", found " +
                                     (text.empty() ? "an empty file" : blank ? "only white space" : "no element"));
  }
  // a file that ends inside an element: tinyxml2 points at the element it was parsing ("text
  // that is not XML" at the root's line for a missing </robot>); say what is missing instead
  // (whatever tinyxml2 calls it: malformed text, attribute or declaration, a mismatched end tag
  // where the file ends right after a start tag; the scan says the end of the file when the text
  // before it is well-formed as far as it sees and the file ends inside something)
  if (err == tinyxml2::XML_ERROR_PARSING || err == tinyxml2::XML_ERROR_PARSING_ELEMENT || err == tinyxml2::XML_ERROR_PARSING_TEXT ||
      err == tinyxml2::XML_ERROR_PARSING_ATTRIBUTE || err == tinyxml2::XML_ERROR_MISMATCHED_ELEMENT ||
      err == tinyxml2::XML_ERROR_PARSING_DECLARATION || err == tinyxml2::XML_ERROR_PARSING_COMMENT ||
      err == tinyxml2::XML_ERROR_PARSING_CDATA || err == tinyxml2::XML_ERROR_PARSING_UNKNOWN) {
    const UnclosedAtEnd u = unclosedAtEnd(text);
    if (!u.message.empty()) throw InputError(file, u.line, u.column, "expected well-formed XML, found " + u.message);
  }
  // tinyxml2 gives the line of the construct it failed on: its first non-blank character
  int line = std::max(1, doc.ErrorLineNum());
  size_t start = 0;
  for (int l = 1; l < line; ++l) {
    const size_t nl = text.find('\n', start);
    if (nl == std::string::npos) {
      line = l;
      break;
    }
    start = nl + 1;
  }
  size_t p = start;
  while (p < text.size() && text[p] != '\n' && std::isspace(static_cast<unsigned char>(text[p]))) ++p;
  const int column = static_cast<int>((p < text.size() && text[p] != '\n' ? p : start) - start) + 1;
  throw InputError(file, line, column, "expected well-formed XML, found " + describeXmlError(err));
}

XmlPositions::XmlPositions(std::string text, const tinyxml2::XMLDocument& doc) : text_(std::move(text)) {
  line_start_.push_back(0);
  for (size_t i = 0; i < text_.size(); ++i)
    if (text_[i] == '\n') line_start_.push_back(i + 1);
  // every element in document order: its '<tag' is the first one (outside comments, CDATA,
  // declarations) at or after the previous element's and on or after its own line
  size_t cursor = 0;
  std::function<void(const XMLElement*)> visit = [&](const XMLElement* e) {
    for (; e; e = e->NextSiblingElement()) {
      const int line = e->GetLineNum();
      size_t from = cursor;
      if (line >= 1 && static_cast<size_t>(line) <= line_start_.size()) from = std::max(from, line_start_[static_cast<size_t>(line - 1)]);
      const size_t at = findTag(e->Name(), from);
      if (at != std::string::npos) {
        element_[e] = at;
        cursor = at + 1;
      }
      visit(e->FirstChildElement());
    }
  };
  visit(doc.FirstChildElement());
}

std::pair<int, int> XmlPositions::element(const XMLElement* e) const {
  if (!e) return {0, 0};
  const auto it = element_.find(e);
  if (it != element_.end()) return lineColumn(it->second);
  // not found in the text (should not happen): the first non-blank character of its line
  const int line = e->GetLineNum();
  if (line < 1 || static_cast<size_t>(line) > line_start_.size()) return {line, 0};
  size_t p = line_start_[static_cast<size_t>(line - 1)];
  while (p < text_.size() && text_[p] != '\n' && std::isspace(static_cast<unsigned char>(text_[p]))) ++p;
  return {line, static_cast<int>(p - line_start_[static_cast<size_t>(line - 1)]) + 1};
}

// The start tag: '<' name, then (whitespace name whitespace? '=' whitespace? quoted)* until '>'
// or '/>'. Calls `onName(start, end)` for each attribute name; returns the offset after the
// tag's '>' (npos when the tag cannot be followed), stopping early when onName returns true.
namespace {
template <class F>
size_t walkStartTag(const std::string& text, size_t p, F&& onName) {
  const auto space = [&](size_t i) { return i < text.size() && std::isspace(static_cast<unsigned char>(text[i])); };
  for (;;) {
    while (space(p)) ++p;
    if (p >= text.size()) return std::string::npos;
    if (text[p] == '>') return p + 1;
    if (text[p] == '/') return p + 1 < text.size() && text[p + 1] == '>' ? p + 2 : std::string::npos;
    const size_t start = p;
    while (p < text.size() && !space(p) && text[p] != '=' && text[p] != '>' && text[p] != '/') ++p;
    if (onName(start, p)) return std::string::npos;
    while (space(p)) ++p;
    if (p >= text.size() || text[p] != '=') return std::string::npos;
    ++p;
    while (space(p)) ++p;
    if (p >= text.size() || (text[p] != '"' && text[p] != '\'')) return std::string::npos;
    const size_t close = text.find(text[p], p + 1);
    if (close == std::string::npos) return std::string::npos;
    p = close + 1;
  }
}
}  // namespace

std::pair<int, int> XmlPositions::attribute(const XMLElement* e, const std::string& name) const {
  if (!e) return {0, 0};
  const auto it = element_.find(e);
  if (it == element_.end()) return element(e);
  size_t found = std::string::npos;
  walkStartTag(text_, nameEnd(it->second, e), [&](size_t start, size_t end) {
    if (end - start == name.size() && text_.compare(start, end - start, name) == 0) found = start;
    return found != std::string::npos;
  });
  return found == std::string::npos ? element(e) : lineColumn(found);
}

std::string strayText(const XMLElement* e) {
  if (!e) return {};
  for (const tinyxml2::XMLNode* n = e->FirstChild(); n; n = n->NextSibling()) {
    const tinyxml2::XMLText* t = n->ToText();
    if (!t || !t->Value()) continue;
    const std::string s = t->Value();
    const size_t a = s.find_first_not_of(" \t\r\n");
    if (a != std::string::npos) return s.substr(a, s.find_last_not_of(" \t\r\n") - a + 1);
  }
  return {};
}

void refuseStrayText(const XMLElement* e, const XmlPositions& positions, const std::string& file) {
  const std::string t = strayText(e);
  if (t.empty()) return;
  const auto [line, column] = positions.content(e, t.substr(0, t.find_first_of("\r\n&<")));
  throw InputError(file, line, column, std::string("<") + e->Name() + ">: expected no text, found '" + printableBytes(t.substr(0, 40)) +
                                           (t.size() > 40 ? "...'" : "'"));
}

std::pair<int, int> XmlPositions::content(const XMLElement* e, const std::string& token) const {
  if (!e) return {0, 0};
  const size_t body = startTagEnd(e);
  if (body == std::string::npos || token.empty()) return element(e);
  const size_t at = text_.find(token, body);
  return at == std::string::npos ? element(e) : lineColumn(at);
}

size_t XmlPositions::startTagEnd(const XMLElement* e) const {
  const auto it = element_.find(e);
  if (it == element_.end()) return std::string::npos;
  return walkStartTag(text_, nameEnd(it->second, e), [](size_t, size_t) { return false; });
}

// After '<' (tinyxml2 allows white space before the name) and the element's name.
size_t XmlPositions::nameEnd(size_t lt, const XMLElement* e) const {
  size_t p = lt + 1;
  while (p < text_.size() && std::isspace(static_cast<unsigned char>(text_[p]))) ++p;
  return p + std::strlen(e->Name());
}

std::pair<int, int> XmlPositions::lineColumn(size_t offset) const {
  const auto it = std::upper_bound(line_start_.begin(), line_start_.end(), offset);
  const size_t line = static_cast<size_t>(it - line_start_.begin());  // >= 1: line_start_[0] = 0
  return {static_cast<int>(line), static_cast<int>(offset - line_start_[line - 1]) + 1};
}

/// The offset of the next "<name" (white space allowed after '<') followed by whitespace, '/' or '>' at or after `from`,
/// skipping comments, CDATA sections, declarations and processing instructions.
size_t XmlPositions::findTag(const std::string& name, size_t from) const {
  size_t p = from;
  for (;;) {
    p = text_.find('<', p);
    if (p == std::string::npos) return p;
    const auto skipTo = [&](const char* open, const char* close) {
      if (text_.compare(p, std::strlen(open), open) != 0) return false;
      const size_t end = text_.find(close, p + std::strlen(open));
      p = end == std::string::npos ? text_.size() : end + std::strlen(close);
      return true;
    };
    if (skipTo("<!--", "-->") || skipTo("<![CDATA[", "]]>") || skipTo("<?", "?>") || skipTo("<!", ">")) continue;
    size_t q = p + 1;
    while (q < text_.size() && std::isspace(static_cast<unsigned char>(text_[q]))) ++q;
    const size_t after = q + name.size();
    if (text_.compare(q, name.size(), name) == 0 &&
        (after >= text_.size() || std::isspace(static_cast<unsigned char>(text_[after])) || text_[after] == '/' || text_[after] == '>'))
      return p;
    ++p;
  }
}

}  // namespace accura::calib
