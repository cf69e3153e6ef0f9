// The cell file (docs/cell-format.md): reading and validation.
#include "accura/postproc/cell.h"

#include <tinyxml2.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string_view>
#include <tuple>

#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "accura/calib/geometry.h"
#include "accura/calib/xml_text.h"
#include "decimal.h"

namespace accura::postproc {
namespace {

using tinyxml2::XMLElement;

class CellReader {
 public:
  CellReader(std::string file, const calib::XmlPositions& pos) : file_(std::move(file)), pos_(pos) {}

  /// An error in the element (at its '<').
  [[noreturn]] void fail(const XMLElement* e, const std::string& msg) const {
    const auto [line, column] = e ? pos_.element(e) : std::pair<int, int>{0, 0};
    throw calib::InputError(file_, line, column, msg);
  }
  /// An error in one of its attributes (at the attribute's name).
  [[noreturn]] void failAttribute(const XMLElement* e, const std::string& name, const std::string& msg) const {
    const auto [line, column] = pos_.attribute(e, name);
    throw calib::InputError(file_, line, column, msg);
  }
  std::pair<int, int> where(const XMLElement* e) const { return pos_.element(e); }
  std::pair<int, int> whereAttribute(const XMLElement* e, const std::string& name) const { return pos_.attribute(e, name); }

  /// Text in an element of the cell file, which holds none (`<tool>torch<capsule .../></tool>`):
  /// never ignored.
  void checkNoText(const XMLElement* e) const { calib::refuseStrayText(e, pos_, file_); }

  void checkAttributes(const XMLElement* e, const std::set<std::string>& allowed) const {
    for (const tinyxml2::XMLAttribute* a = e->FirstAttribute(); a; a = a->Next()) {
      if (allowed.count(a->Name())) continue;
      std::string list;
      for (const auto& s : allowed) list += (list.empty() ? "" : ", ") + s;
      failAttribute(e, a->Name(), std::string("<") + e->Name() + ">: expected one of the attributes " + (list.empty() ? "(none)" : list) +
                                      ", found '" + a->Name() + "'");
    }
  }

  const tinyxml2::XMLAttribute* attr(const XMLElement* e, const char* name) const {
    for (const tinyxml2::XMLAttribute* a = e->FirstAttribute(); a; a = a->Next())
      if (std::string(a->Name()) == name) return a;
    return nullptr;
  }

  double number(const XMLElement* e, const char* name, const double* fallback) const {
    const tinyxml2::XMLAttribute* a = attr(e, name);
    if (!a) {
      if (fallback) return *fallback;
      fail(e, std::string("<") + e->Name() + ">: expected the attribute " + name + ", found none");
    }
    const char* text = a->Value();
    // a decimal number, blanks around it allowed (not a blank value, hex, inf, nan, 1e309)
    std::string_view s(text);
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
    while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
    double v = 0;
    if (!detail::parseDecimal(s, &v))
      failAttribute(e, name, std::string("<") + e->Name() + "> " + name + ": expected a number, found '" + text + "' (a finite decimal number: not blank, hex, inf, nan or beyond 1e308)");
    return v;
  }

  /// A number within +-bound (a coordinate in mm, an angle in deg): larger ones are a unit
  /// mistake or garbage (see kMaxCellExtent_mm).
  double bounded(const XMLElement* e, const char* name, const double* fallback, double bound, const char* unit) const {
    const double v = number(e, name, fallback);
    if (!(std::abs(v) <= bound)) {
      std::ostringstream m;
      m << "<" << e->Name() << "> " << name << ": expected a value within +-" << bound << " " << unit
        << (std::string(unit) == "mm" ? " (100 m: no robot cell is larger)" : "") << ", found " << attr(e, name)->Value();
      failAttribute(e, name, m.str());
    }
    return v;
  }

  std::string text(const XMLElement* e, const char* name) const {
    const tinyxml2::XMLAttribute* a = attr(e, name);
    if (!a || std::string(a->Value()).empty()) {
      const std::string msg = std::string("<") + e->Name() + ">: expected a non-empty attribute " + name + ", found " + (a ? "an empty one" : "none");
      if (a) failAttribute(e, name, msg);
      fail(e, msg);
    }
    return a->Value();
  }

  /// x_mm .. c_deg (each optional, 0 when absent).
  Eigen::Isometry3d placement(const XMLElement* e) const {
    const double zero = 0;
    calib::XyzAbc p;
    p.x_mm = bounded(e, "x_mm", &zero, kMaxCellExtent_mm, "mm");
    p.y_mm = bounded(e, "y_mm", &zero, kMaxCellExtent_mm, "mm");
    p.z_mm = bounded(e, "z_mm", &zero, kMaxCellExtent_mm, "mm");
    p.a_deg = bounded(e, "a_deg", &zero, kMaxCellAngle_deg, "deg");
    p.b_deg = bounded(e, "b_deg", &zero, kMaxCellAngle_deg, "deg");
    p.c_deg = bounded(e, "c_deg", &zero, kMaxCellAngle_deg, "deg");
    return calib::toIsometry(p);
  }

  double unitScale(const XMLElement* e) const {
    const tinyxml2::XMLAttribute* a = attr(e, "units");
    if (!a) fail(e, std::string("<") + e->Name() + ">: expected the attribute units (mm, cm, m, inch or ft) with the mesh file, found none");
    const std::string u = a->Value();
    if (u == "mm") return 1.0;
    if (u == "cm") return 10.0;
    if (u == "m") return 1000.0;
    if (u == "inch" || u == "in") return 25.4;
    if (u == "ft" || u == "foot" || u == "feet") return 304.8;
    failAttribute(e, "units", std::string("<") + e->Name() + "> units: expected mm, cm, m, inch or ft, found '" + u + "'");
  }

  /// The shapes of an <object>, <link> or <tool>: the mesh of its file attribute and its
  /// <capsule> children, all placed by its placement attributes.
  std::vector<CellShape> shapes(const XMLElement* e, const std::string& name, const std::string& dir) const {
    std::vector<CellShape> out;
    checkNoText(e);
    const Eigen::Isometry3d T = placement(e);
    if (attr(e, "file")) {
      const std::string rel = text(e, "file");
      const double scale = unitScale(e);
      const std::string path = std::filesystem::path(rel).is_absolute() ? rel : (std::filesystem::path(dir) / rel).string();
      CellShape s;
      try {
        s.mesh = loadMesh(path, scale);
      } catch (const calib::InputError& err) {
        failAttribute(e, "file", std::string("<") + e->Name() + "> file '" + rel + "': " + err.what());
      }
      s.T_parent_shape = T;
      s.name = name;
      s.file = file_;
      std::tie(s.line, s.column) = where(e);
      out.push_back(std::move(s));
    } else if (attr(e, "units")) {
      failAttribute(e, "units", std::string("<") + e->Name() + ">: expected units only with a file attribute, found units without file");
    }
    int k = 0;
    for (const XMLElement* c = e->FirstChildElement(); c; c = c->NextSiblingElement()) {
      if (std::string(c->Name()) != "capsule")
        fail(c, std::string("<") + e->Name() + ">: expected <capsule> children only, found <" + c->Name() + ">");
      checkAttributes(c, {"x0_mm", "y0_mm", "z0_mm", "x1_mm", "y1_mm", "z1_mm", "radius_mm"});
      if (const XMLElement* cc = c->FirstChildElement()) fail(cc, "<capsule>: expected no children, found <" + std::string(cc->Name()) + ">");
      checkNoText(c);
      Capsule cap;
      const double B = kMaxCellExtent_mm;
      cap.p0_mm = {bounded(c, "x0_mm", nullptr, B, "mm"), bounded(c, "y0_mm", nullptr, B, "mm"), bounded(c, "z0_mm", nullptr, B, "mm")};
      cap.p1_mm = {bounded(c, "x1_mm", nullptr, B, "mm"), bounded(c, "y1_mm", nullptr, B, "mm"), bounded(c, "z1_mm", nullptr, B, "mm")};
      cap.radius_mm = bounded(c, "radius_mm", nullptr, B, "mm");
      if (!(cap.radius_mm > 0)) failAttribute(c, "radius_mm", "<capsule> radius_mm: expected a positive radius (mm), found " + std::to_string(cap.radius_mm));
      CellShape s;
      s.capsule = cap;
      s.T_parent_shape = T;
      s.name = name + (k > 0 || attr(e, "file") ? " capsule " + std::to_string(k + 1) : "");
      s.file = file_;
      std::tie(s.line, s.column) = where(c);
      out.push_back(std::move(s));
      ++k;
    }
    if (out.empty())
      fail(e, std::string("<") + e->Name() + ">: expected a file attribute (a mesh) or <capsule> children, found neither");
    return out;
  }

 private:
  std::string file_;
  const calib::XmlPositions& pos_;
};

}  // namespace

Cell readCellFile(const std::string& path) {
  std::string text;
  // a directory opens as an empty stream ("found an empty file"): said as what it is
  if (const std::string problem = calib::notAFileProblem(path); !problem.empty())
    throw calib::InputError(path, 0, 0, "cannot read the cell file: " + problem);
  {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw calib::InputError(path, 0, 0, "expected a cell file, cannot open it");
    std::ostringstream s;
    s << in.rdbuf();
    if (in.bad()) throw calib::InputError(path, 0, 0, "expected a cell file, cannot read it");
    text = s.str();
  }
  tinyxml2::XMLDocument doc;
  // the text read above (not the file again): the positions below are positions in it
  calib::parseXml(doc, text, path, "a cell file with root element <cell>");
  const calib::XmlPositions positions(text, doc);
  CellReader R(path, positions);
  const XMLElement* root = doc.RootElement();
  if (!root || std::string(root->Name()) != "cell")
    R.fail(root, std::string("expected the root element <cell>, found ") + (root ? "<" + std::string(root->Name()) + ">" : "none"));
  R.checkAttributes(root, {"name"});
  R.checkNoText(root);
  const std::string dir = std::filesystem::path(path).parent_path().string();
  Cell cell;
  cell.file = path;
  std::set<std::string> names;
  bool have_thresholds = false;
  for (const XMLElement* e = root->FirstChildElement(); e; e = e->NextSiblingElement()) {
    const std::string tag = e->Name();
    if (tag == "thresholds") {
      if (have_thresholds) R.fail(e, "expected one <thresholds>, found a second one");
      have_thresholds = true;
      R.checkAttributes(e, {"joint_margin_deg", "singular_threshold", "min_clearance_mm"});
      CheckThresholds& t = cell.thresholds;
      t.joint_margin_deg = R.number(e, "joint_margin_deg", &t.joint_margin_deg);
      t.singular_threshold = R.number(e, "singular_threshold", &t.singular_threshold);
      t.min_clearance_mm = R.bounded(e, "min_clearance_mm", &t.min_clearance_mm, kMaxCellExtent_mm, "mm");
      if (t.joint_margin_deg < 0) R.failAttribute(e, "joint_margin_deg", "<thresholds> joint_margin_deg: expected a margin >= 0, found " + std::to_string(t.joint_margin_deg));
      if (t.singular_threshold < 0) R.failAttribute(e, "singular_threshold", "<thresholds> singular_threshold: expected a value >= 0, found " + std::to_string(t.singular_threshold));
      if (t.min_clearance_mm < 0) R.failAttribute(e, "min_clearance_mm", "<thresholds> min_clearance_mm: expected a distance >= 0, found " + std::to_string(t.min_clearance_mm));
      if (e->FirstChildElement()) R.fail(e->FirstChildElement(), "<thresholds>: expected no children, found <" + std::string(e->FirstChildElement()->Name()) + ">");
      R.checkNoText(e);
    } else if (tag == "robot") {
      if (cell.T_world_base) R.fail(e, "expected one <robot>, found a second one");
      R.checkAttributes(e, {"x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"});
      cell.T_world_base = R.placement(e);
      std::tie(cell.robot_line, cell.robot_column) = R.where(e);
      if (e->FirstChildElement()) R.fail(e->FirstChildElement(), "<robot>: expected no children, found <" + std::string(e->FirstChildElement()->Name()) + ">");
      R.checkNoText(e);
    } else if (tag == "object") {
      R.checkAttributes(e, {"name", "file", "units", "x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"});
      const std::string name = R.text(e, "name");
      if (!names.insert(name).second) R.failAttribute(e, "name", "<object> name: expected a unique name, found '" + name + "' a second time");
      for (auto& s : R.shapes(e, name, dir)) cell.objects.push_back(std::move(s));
    } else if (tag == "link") {
      R.checkAttributes(e, {"joint", "file", "units", "x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"});
      const double j = R.number(e, "joint", nullptr);
      if (j < 1 || j != std::floor(j) || j > 64)
        R.failAttribute(e, "joint", "<link> joint: expected the joint number 1..n whose DH frame the link moves with, found " + std::string(e->Attribute("joint")));
      const int joint = static_cast<int>(j);
      for (auto& s : R.shapes(e, "link " + std::to_string(joint), dir)) {
        cell.link_shapes.emplace_back(joint, std::move(s));
        cell.link_joint_positions.push_back(R.whereAttribute(e, "joint"));
      }
    } else if (tag == "tool") {
      R.checkAttributes(e, {"file", "units", "x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"});
      for (auto& s : R.shapes(e, "tool", dir)) cell.tool_shapes.push_back(std::move(s));
    } else {
      R.fail(e, "<cell>: expected <thresholds>, <robot>, <object>, <link> or <tool>, found <" + tag + ">");
    }
  }
  return cell;
}

}  // namespace accura::postproc
