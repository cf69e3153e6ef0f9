// Positions in an XML file's text and the message for malformed XML (xml_text.h).
#include "accura/calib/xml_text.h"

#include <tinyxml2.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <functional>

#include "accura/calib/errors.h"

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

}  // namespace

void parseXml(tinyxml2::XMLDocument& doc, const std::string& text, const std::string& file,
              const std::string& what) {
  const tinyxml2::XMLError err = doc.Parse(text.data(), text.size());
  if (err == tinyxml2::XML_SUCCESS && doc.RootElement()) return;
  if (err == tinyxml2::XML_SUCCESS || err == tinyxml2::XML_ERROR_EMPTY_DOCUMENT) {  // no element at all
    const bool blank = std::all_of(text.begin(), text.end(), [](char c) { return std::isspace(static_cast<unsigned char>(c)); });
    throw InputError(file, 1, 1, "expected " + what + ", found " +
                                     (text.empty() ? "an empty file" : blank ? "only white space" : "no element"));
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
