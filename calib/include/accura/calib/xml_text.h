// accura: where elements and attributes are in an XML file's text, and one message for
// malformed XML (issue 14). tinyxml2 reports line numbers only; the project's errors give
// file:line:column (1-based, in bytes), so the readers of XML files (robot file, URDF, XML
// program, cell file) compute columns from the text they parsed.
//
// Only tinyxml2's types are named here (forward-declared): a caller that uses this header
// parses with tinyxml2 itself.
#pragma once

#include <cstddef>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace tinyxml2 {
class XMLDocument;
class XMLElement;
}  // namespace tinyxml2

namespace accura::calib {

/// Parses `text` (the whole file, as read) into `doc`. On malformed XML throws InputError
/// (errors.h) at file:line:column: "expected well-formed XML ..., found ..." where found names
/// the problem in words (an empty file, an unclosed element, a malformed attribute, text after
/// the root element, ...); a document without any element is an error too (at 1:1). `what` names the document ("a robot file with root element
/// <robot>") for the message of an empty file. The column is that of the first character of
/// the construct tinyxml2 failed on (tinyxml2 gives its line only: the first non-blank one).
void parseXml(tinyxml2::XMLDocument& doc, const std::string& text, const std::string& file,
              const std::string& what);

/// The first text of `e`'s own content (not its children's) that is more than white space,
/// trimmed; empty when there is none. Comments are not text. For the readers' errors: text
/// where the format has none (`<base ...>500</base>`) is never ignored.
std::string strayText(const tinyxml2::XMLElement* e);

/// Positions of a parsed document's elements and attributes in its text.
class XmlPositions {
 public:
  XmlPositions() = default;
  /// `text` must be the text `doc` was parsed from (parseXml).
  XmlPositions(std::string text, const tinyxml2::XMLDocument& doc);

  /// 1-based line and column of the element's '<' (when it cannot be found in the text: of
  /// the first non-blank character of tinyxml2's line for it; {0, 0} for a null element).
  std::pair<int, int> element(const tinyxml2::XMLElement* e) const;
  /// 1-based line and column of the attribute's name in the element's start tag (the
  /// element's position when it has no such attribute).
  std::pair<int, int> attribute(const tinyxml2::XMLElement* e, const std::string& name) const;
  /// 1-based line and column of the first occurrence of `token` in the element's text
  /// content, after its start tag (the element's position when not found).
  std::pair<int, int> content(const tinyxml2::XMLElement* e, const std::string& token) const;

 private:
  std::pair<int, int> lineColumn(size_t offset) const;
  size_t findTag(const std::string& name, size_t from) const;
  size_t startTagEnd(const tinyxml2::XMLElement* e) const;
  size_t nameEnd(size_t lt, const tinyxml2::XMLElement* e) const;

  std::string text_;
  std::vector<size_t> line_start_;
  std::map<const tinyxml2::XMLElement*, size_t> element_;
};

/// Throws InputError at `e`'s stray text (strayText(e), when there is any: its line and column
/// in `positions`) saying "<name>: expected no text, found '...'" (the first 40 bytes).
void refuseStrayText(const tinyxml2::XMLElement* e, const XmlPositions& positions, const std::string& file);

}  // namespace accura::calib
