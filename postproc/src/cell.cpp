// The cell file (docs/cell-format.md): reading and validation.
#include "accura/postproc/cell.h"

#include <tinyxml2.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"

namespace accura::postproc {
namespace {

using tinyxml2::XMLElement;

class CellReader {
 public:
  explicit CellReader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void fail(int line, const std::string& msg) const { throw InputError(file_, line, 0, msg); }

  void checkAttributes(const XMLElement* e, const std::set<std::string>& allowed) const {
    for (const tinyxml2::XMLAttribute* a = e->FirstAttribute(); a; a = a->Next()) {
      if (allowed.count(a->Name())) continue;
      std::string list;
      for (const auto& s : allowed) list += (list.empty() ? "" : ", ") + s;
      fail(a->GetLineNum(), std::string("<") + e->Name() + ">: expected one of the attributes " + (list.empty() ? "(none)" : list) +
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
      fail(e->GetLineNum(), std::string("<") + e->Name() + ">: expected the attribute " + name + ", found none");
    }
    const char* text = a->Value();
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(text, &end);
    while (end && *end == ' ') ++end;
    if (end == text || (end && *end != '\0') || errno == ERANGE || !std::isfinite(v))
      fail(a->GetLineNum(), std::string("<") + e->Name() + "> " + name + ": expected a number, found '" + text + "'");
    return v;
  }

  std::string text(const XMLElement* e, const char* name) const {
    const tinyxml2::XMLAttribute* a = attr(e, name);
    if (!a || std::string(a->Value()).empty())
      fail(a ? a->GetLineNum() : e->GetLineNum(), std::string("<") + e->Name() + ">: expected a non-empty attribute " + name + ", found " + (a ? "an empty one" : "none"));
    return a->Value();
  }

  /// x_mm .. c_deg (each optional, 0 when absent).
  Eigen::Isometry3d placement(const XMLElement* e) const {
    const double zero = 0;
    XyzAbc p;
    p.x_mm = number(e, "x_mm", &zero);
    p.y_mm = number(e, "y_mm", &zero);
    p.z_mm = number(e, "z_mm", &zero);
    p.a_deg = number(e, "a_deg", &zero);
    p.b_deg = number(e, "b_deg", &zero);
    p.c_deg = number(e, "c_deg", &zero);
    return toIsometry(p);
  }

  double unitScale(const XMLElement* e) const {
    const tinyxml2::XMLAttribute* a = attr(e, "units");
    if (!a) fail(e->GetLineNum(), std::string("<") + e->Name() + ">: expected the attribute units (mm, cm, m or inch) with the mesh file, found none");
    const std::string u = a->Value();
    if (u == "mm") return 1.0;
    if (u == "cm") return 10.0;
    if (u == "m") return 1000.0;
    if (u == "inch" || u == "in") return 25.4;
    fail(a->GetLineNum(), std::string("<") + e->Name() + "> units: expected mm, cm, m or inch, found '" + u + "'");
  }

  /// The shapes of an <object>, <link> or <tool>: the mesh of its file attribute and its
  /// <capsule> children, all placed by its placement attributes.
  std::vector<CellShape> shapes(const XMLElement* e, const std::string& name, const std::string& dir) const {
    std::vector<CellShape> out;
    const Eigen::Isometry3d T = placement(e);
    if (attr(e, "file")) {
      const std::string rel = text(e, "file");
      const double scale = unitScale(e);
      const std::string path = std::filesystem::path(rel).is_absolute() ? rel : (std::filesystem::path(dir) / rel).string();
      CellShape s;
      try {
        s.mesh = loadMesh(path, scale);
      } catch (const InputError& err) {
        fail(attr(e, "file")->GetLineNum(), std::string("<") + e->Name() + "> file '" + rel + "': " + err.what());
      }
      s.T_parent_shape = T;
      s.name = name;
      s.file = file_;
      s.line = e->GetLineNum();
      out.push_back(std::move(s));
    } else if (attr(e, "units")) {
      fail(attr(e, "units")->GetLineNum(), std::string("<") + e->Name() + ">: expected units only with a file attribute, found units without file");
    }
    int k = 0;
    for (const XMLElement* c = e->FirstChildElement(); c; c = c->NextSiblingElement()) {
      if (std::string(c->Name()) != "capsule")
        fail(c->GetLineNum(), std::string("<") + e->Name() + ">: expected <capsule> children only, found <" + c->Name() + ">");
      checkAttributes(c, {"x0_mm", "y0_mm", "z0_mm", "x1_mm", "y1_mm", "z1_mm", "radius_mm"});
      Capsule cap;
      cap.p0_mm = {number(c, "x0_mm", nullptr), number(c, "y0_mm", nullptr), number(c, "z0_mm", nullptr)};
      cap.p1_mm = {number(c, "x1_mm", nullptr), number(c, "y1_mm", nullptr), number(c, "z1_mm", nullptr)};
      cap.radius_mm = number(c, "radius_mm", nullptr);
      if (!(cap.radius_mm > 0)) fail(c->GetLineNum(), "<capsule> radius_mm: expected a positive radius (mm), found " + std::to_string(cap.radius_mm));
      CellShape s;
      s.capsule = cap;
      s.T_parent_shape = T;
      s.name = name + (k > 0 || attr(e, "file") ? " capsule " + std::to_string(k + 1) : "");
      s.file = file_;
      s.line = c->GetLineNum();
      out.push_back(std::move(s));
      ++k;
    }
    if (out.empty())
      fail(e->GetLineNum(), std::string("<") + e->Name() + ">: expected a file attribute (a mesh) or <capsule> children, found neither");
    return out;
  }

 private:
  std::string file_;
};

}  // namespace

Cell readCellFile(const std::string& path) {
  {
    std::ifstream probe(path);
    if (!probe) throw InputError(path, 0, 0, "expected a cell file, cannot open it");
  }
  tinyxml2::XMLDocument doc;
  if (doc.LoadFile(path.c_str()) != tinyxml2::XML_SUCCESS)
    throw InputError(path, doc.ErrorLineNum(), 0, std::string("expected well-formed XML, found: ") + doc.ErrorStr());
  CellReader R(path);
  const XMLElement* root = doc.RootElement();
  if (!root || std::string(root->Name()) != "cell")
    R.fail(root ? root->GetLineNum() : 0, std::string("expected the root element <cell>, found ") + (root ? "<" + std::string(root->Name()) + ">" : "none"));
  R.checkAttributes(root, {"name"});
  const std::string dir = std::filesystem::path(path).parent_path().string();
  Cell cell;
  cell.file = path;
  std::set<std::string> names;
  bool have_thresholds = false;
  for (const XMLElement* e = root->FirstChildElement(); e; e = e->NextSiblingElement()) {
    const std::string tag = e->Name();
    if (tag == "thresholds") {
      if (have_thresholds) R.fail(e->GetLineNum(), "expected one <thresholds>, found a second one");
      have_thresholds = true;
      R.checkAttributes(e, {"joint_margin_deg", "singular_threshold", "min_clearance_mm"});
      CheckThresholds& t = cell.thresholds;
      t.joint_margin_deg = R.number(e, "joint_margin_deg", &t.joint_margin_deg);
      t.singular_threshold = R.number(e, "singular_threshold", &t.singular_threshold);
      t.min_clearance_mm = R.number(e, "min_clearance_mm", &t.min_clearance_mm);
      if (t.joint_margin_deg < 0) R.fail(e->GetLineNum(), "<thresholds> joint_margin_deg: expected a margin >= 0, found " + std::to_string(t.joint_margin_deg));
      if (t.singular_threshold < 0) R.fail(e->GetLineNum(), "<thresholds> singular_threshold: expected a value >= 0, found " + std::to_string(t.singular_threshold));
      if (t.min_clearance_mm < 0) R.fail(e->GetLineNum(), "<thresholds> min_clearance_mm: expected a distance >= 0, found " + std::to_string(t.min_clearance_mm));
      if (e->FirstChildElement()) R.fail(e->FirstChildElement()->GetLineNum(), "<thresholds>: expected no children, found <" + std::string(e->FirstChildElement()->Name()) + ">");
    } else if (tag == "robot") {
      if (cell.T_world_base) R.fail(e->GetLineNum(), "expected one <robot>, found a second one");
      R.checkAttributes(e, {"x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"});
      cell.T_world_base = R.placement(e);
      if (e->FirstChildElement()) R.fail(e->FirstChildElement()->GetLineNum(), "<robot>: expected no children, found <" + std::string(e->FirstChildElement()->Name()) + ">");
    } else if (tag == "object") {
      R.checkAttributes(e, {"name", "file", "units", "x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"});
      const std::string name = R.text(e, "name");
      if (!names.insert(name).second) R.fail(e->GetLineNum(), "<object> name: expected a unique name, found '" + name + "' a second time");
      for (auto& s : R.shapes(e, name, dir)) cell.objects.push_back(std::move(s));
    } else if (tag == "link") {
      R.checkAttributes(e, {"joint", "file", "units", "x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"});
      const double j = R.number(e, "joint", nullptr);
      if (j < 1 || j != std::floor(j) || j > 64)
        R.fail(e->GetLineNum(), "<link> joint: expected the joint number 1..n whose DH frame the link moves with, found " + std::string(e->Attribute("joint")));
      const int joint = static_cast<int>(j);
      for (auto& s : R.shapes(e, "link " + std::to_string(joint), dir)) cell.link_shapes.emplace_back(joint, std::move(s));
    } else if (tag == "tool") {
      R.checkAttributes(e, {"file", "units", "x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"});
      for (auto& s : R.shapes(e, "tool", dir)) cell.tool_shapes.push_back(std::move(s));
    } else {
      R.fail(e->GetLineNum(), "<cell>: expected <thresholds>, <robot>, <object>, <link> or <tool>, found <" + tag + ">");
    }
  }
  return cell;
}

}  // namespace accura::postproc
