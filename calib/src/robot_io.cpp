#include "accura/calib/robot_io.h"

#include <dlfcn.h>

#include <tinyxml2.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "accura/calib/text.h"
#include "accura/calib/joint_map.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/urdf.h"
#include "accura/calib/xml_text.h"

namespace fs = std::filesystem;

namespace accura::calib {
namespace {

using tinyxml2::XMLElement;

/// The robot file's reader: every error at file:line:column (xml_text.h), saying what was
/// expected and what was found.
class RobotReader {
 public:
  RobotReader(std::string file, const XmlPositions& pos) : file_(std::move(file)), pos_(pos) {}

  /// An error in the element (at its '<').
  [[noreturn]] void fail(const XMLElement* e, const std::string& msg) const {
    const auto [line, column] = pos_.element(e);
    throw InputError(file_, line, column, msg);
  }
  /// An error in one of its attributes (at the attribute's name).
  [[noreturn]] void failAttribute(const XMLElement* e, const std::string& name, const std::string& msg) const {
    const auto [line, column] = pos_.attribute(e, name);
    throw InputError(file_, line, column, msg);
  }
  /// An error in its text content (at the first occurrence of `token` after the start tag).
  [[noreturn]] void failContent(const XMLElement* e, const std::string& token, const std::string& msg) const {
    const auto [line, column] = pos_.content(e, token);
    throw InputError(file_, line, column, msg);
  }

  // Checks that `e` has only the attributes in `allowed`.
  void checkAttributes(const XMLElement* e, const std::set<std::string>& allowed) const {
    for (const tinyxml2::XMLAttribute* a = e->FirstAttribute(); a; a = a->Next()) {
      if (!allowed.count(a->Name())) {
        std::string list;
        for (const auto& s : allowed) list += (list.empty() ? "" : ", ") + s;
        failAttribute(e, a->Name(), "<" + std::string(e->Name()) + ">: expected " +
                                        (list.empty() ? "no attributes" : "one of the attributes " + list) +
                                        ", found unknown attribute '" + a->Name() + "'");
      }
    }
  }

  std::string text(const XMLElement* e, const char* name, bool required = true) const {
    const char* v = e->Attribute(name);
    if (!v) {
      if (required) fail(e, "<" + std::string(e->Name()) + ">: expected an attribute '" + name + "', found none");
      return {};
    }
    return v;
  }

  /// A number attribute: finite, and at most 1e6 in magnitude (1 km, a million degrees: no
  /// robot file value comes near; beyond is a corrupted file, not a robot).
  double number(const XMLElement* e, const char* name) const {
    const std::string s = text(e, name);
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    const bool converted = end != s.c_str();  // " " converts nothing: not a zero
    while (end && (*end == ' ' || *end == '\t')) ++end;
    // decimal only: strtod also reads hexadecimal ("0x2A8" as 680) and "infinity"
    const bool decimal = s.find_first_of("xXpP") == std::string::npos;
    if (s.empty() || !converted || *end != '\0' || !std::isfinite(v) || !decimal) {
      failAttribute(e, name, "<" + std::string(e->Name()) + "> attribute '" + name +
                                 "': expected a finite number, found '" + s + "'");
    }
    if (std::abs(v) > kMaxMagnitude)
      failAttribute(e, name, "<" + std::string(e->Name()) + "> attribute '" + name +
                                 "': expected a magnitude of at most 1e6, found '" + s + "'");
    return v;
  }

  Eigen::Isometry3d pose(const XMLElement* e) const {
    checkAttributes(e, {"x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"});
    checkContent(e, false);
    XyzAbc p;
    p.x_mm = number(e, "x_mm");
    p.y_mm = number(e, "y_mm");
    p.z_mm = number(e, "z_mm");
    p.a_deg = number(e, "a_deg");
    p.b_deg = number(e, "b_deg");
    p.c_deg = number(e, "c_deg");
    return toIsometry(p);
  }

  /// What an element holds besides its attributes: no text (`<base ...>500</base>`), and no
  /// child elements unless `children` (`<joint ...><limit .../></joint>`): never ignored.
  void checkContent(const XMLElement* e, bool children) const {
    if (!children)
      if (const XMLElement* c = e->FirstChildElement())
        fail(c, "<" + std::string(e->Name()) + ">: expected no child elements, found <" + c->Name() + ">");
    refuseStrayText(e, pos_, file_);
  }

  const XMLElement* child(const XMLElement* parent, const char* name, bool required) const {
    const XMLElement* c = parent->FirstChildElement(name);
    if (!c && required)
      fail(parent, "<" + std::string(parent->Name()) + ">: expected a <" + name + "> element, found none");
    if (c && c->NextSiblingElement(name))
      fail(c->NextSiblingElement(name), "<" + std::string(parent->Name()) + ">: expected one <" + name +
                                            "> element, found a second one");
    return c;
  }

  const std::string& file() const { return file_; }

  static constexpr double kMaxMagnitude = 1e6;

 private:
  std::string file_;
  const XmlPositions& pos_;
};

std::string fmt(double v) {
  return v == 0.0 ? "0" : formatNumber("%.12g", v);  // "0" also folds -0
}

void writePose(std::ostream& out, const char* tag, const Eigen::Isometry3d& T,
               const std::string& indent) {
  const XyzAbc p = toXyzAbc(T);
  out << indent << "<" << tag << " x_mm=\"" << fmt(p.x_mm) << "\" y_mm=\"" << fmt(p.y_mm)
      << "\" z_mm=\"" << fmt(p.z_mm) << "\" a_deg=\"" << fmt(p.a_deg) << "\" b_deg=\""
      << fmt(p.b_deg) << "\" c_deg=\"" << fmt(p.c_deg) << "\"/>\n";
}

// An installed accura (cmake --install) finds its robots next to the binary that contains
// this code (bin/accura or lib/libaccura_plugin.so): <prefix>/share/accura/robots.
std::string installedRobotsDir() {
  Dl_info info;
  if (dladdr(reinterpret_cast<void*>(&installedRobotsDir), &info) == 0 || !info.dli_fname) return "";
  std::error_code ec;
  const fs::path module = fs::canonical(info.dli_fname, ec);
  if (ec) return "";
  const fs::path dir = module.parent_path().parent_path() / "share" / "accura" / "robots";
  return fs::is_directory(dir, ec) ? dir.string() : "";
}

std::string robotsDir() {
  if (const char* env = std::getenv("ACCURA_ROBOTS_DIR")) return env;
  const std::string installed = installedRobotsDir();
  return installed.empty() ? ACCURA_ROBOTS_DIR : installed;
}

}  // namespace

namespace {

JointSpec readJoint(const RobotReader& R, const XMLElement* j) {
  if (std::string(j->Name()) != "joint")
    R.fail(j, "<joints>: expected <joint>, found <" + std::string(j->Name()) + ">");
  R.checkAttributes(j, {"name", "type", "a_mm", "alpha_deg", "d_mm", "theta0_deg", "direction",
                        "lower", "upper", "mass_kg", "com_x_mm", "com_y_mm", "com_z_mm"});
  R.checkContent(j, false);
  JointSpec s;
  s.name = R.text(j, "name");
  const std::string type = R.text(j, "type");
  if (type == "revolute") s.type = JointType::kRevolute;
  else if (type == "prismatic") s.type = JointType::kPrismatic;
  else R.failAttribute(j, "type", "<joint> attribute 'type': expected 'revolute' or 'prismatic', found '" + type + "'");
  s.a_mm = R.number(j, "a_mm");
  s.alpha_deg = R.number(j, "alpha_deg");
  s.d_mm = R.number(j, "d_mm");
  s.theta0_deg = R.number(j, "theta0_deg");
  const double dir = R.number(j, "direction");
  if (dir != 1.0 && dir != -1.0)
    R.failAttribute(j, "direction", "<joint> attribute 'direction': expected 1 or -1, found '" + R.text(j, "direction") + "'");
  s.direction = static_cast<int>(dir);
  s.lower = R.number(j, "lower");
  s.upper = R.number(j, "upper");
  if (!(s.lower < s.upper))
    R.failAttribute(j, "lower", "<joint> '" + s.name + "': expected lower < upper, found lower " + fmt(s.lower) +
                                    ", upper " + fmt(s.upper));
  s.mass_kg = R.number(j, "mass_kg");
  if (s.mass_kg < 0) R.failAttribute(j, "mass_kg", "<joint> attribute 'mass_kg': expected >= 0, found " + fmt(s.mass_kg));
  s.com_mm = Eigen::Vector3d(R.number(j, "com_x_mm"), R.number(j, "com_y_mm"), R.number(j, "com_z_mm"));
  return s;
}

/// The nominal robot: <robot>'s attributes, base, tool, payload, gravity and joints.
RobotDefinition readDefinition(const RobotReader& R, const XMLElement* root) {
  R.checkAttributes(root, {"name", "source"});
  R.checkContent(root, true);
  for (const XMLElement* c = root->FirstChildElement(); c; c = c->NextSiblingElement()) {
    static const std::set<std::string> known = {"base", "tool", "payload", "gravity", "joints",
                                                "calibration"};
    if (!known.count(c->Name()))
      R.fail(c, "<robot>: expected one of the elements base, tool, payload, gravity, joints, calibration, found <" +
                    std::string(c->Name()) + ">");
  }
  RobotDefinition def;
  def.name = R.text(root, "name");
  def.source = R.text(root, "source", false);
  def.T_world_base = R.pose(R.child(root, "base", true));
  def.T_flange_tcp = R.pose(R.child(root, "tool", true));
  const XMLElement* payload = R.child(root, "payload", true);
  R.checkAttributes(payload, {"com_x_mm", "com_y_mm", "com_z_mm"});
  R.checkContent(payload, false);
  def.payload_com_mm = Eigen::Vector3d(R.number(payload, "com_x_mm"), R.number(payload, "com_y_mm"),
                                       R.number(payload, "com_z_mm"));
  if (const XMLElement* g = R.child(root, "gravity", false)) {
    R.checkAttributes(g, {"x", "y", "z"});
    R.checkContent(g, false);
    def.gravity_base = Eigen::Vector3d(R.number(g, "x"), R.number(g, "y"), R.number(g, "z"));
    // m/s^2 on the Earth's surface (9.78 to 9.83; 10 when rounded): a vector in mm/s^2, in g or
    // zero is a unit mistake, and it would scale every gravity load (compliance) silently
    const double magnitude = def.gravity_base.norm();
    if (!(magnitude >= 9.0 && magnitude <= 10.5))
      R.fail(g, "<gravity>: expected the gravity vector in m/s^2, of magnitude about 9.81 (9 to 10.5; standard 0 0 -9.80665), found magnitude " +
                    formatNumber("%.6g", magnitude) +
                    (magnitude > 9000 && magnitude < 10500 ? " (mm/s^2?)" : magnitude > 0.9 && magnitude < 1.05 ? " (in g?)" : ""));
  }
  const XMLElement* joints = R.child(root, "joints", true);
  R.checkAttributes(joints, {});
  R.checkContent(joints, true);
  for (const XMLElement* j = joints->FirstChildElement(); j; j = j->NextSiblingElement()) {
    def.joints.push_back(readJoint(R, j));
    // names identify joints (messages, the mapping files' joints, URDF export): one per joint
    const std::string& name = def.joints.back().name;
    for (size_t k = 0; k + 1 < def.joints.size(); ++k)
      if (!name.empty() && def.joints[k].name == name)
        R.failAttribute(j, "name", "<joint>: expected a name of its own, found '" + name + "', the name of joint " + std::to_string(k + 1));
  }
  if (def.joints.empty()) R.fail(joints, "<joints>: expected at least one <joint>, found none");
  return def;
}

/// A <joint_map> or <fit_range> of <calibration>: the joint's index (0-based), its limits
/// checked. The map itself goes into the model; a range into `ranges`.
void readJointCurve(const RobotReader& R, const XMLElement* p, RobotModel& model, std::vector<JointRange>& ranges,
                    std::set<int>& range_seen) {
  const std::string tag = p->Name();
  const int dof = model.dof();
  R.checkAttributes(p, tag == "fit_range" ? std::set<std::string>{"joint", "lower", "upper", "unit"}
                                          : std::set<std::string>{"joint", "lower", "upper", "intervals", "taper", "period", "unit"});
  // a <fit_range> holds nothing, a <joint_map> its values (text) only
  if (tag == "fit_range") R.checkContent(p, false);
  else if (const XMLElement* c = p->FirstChildElement())
    R.fail(c, "<joint_map>: expected its values (text) only, found <" + std::string(c->Name()) + ">");
  const double jv = R.number(p, "joint");
  if (jv != std::floor(jv) || jv < 1 || jv > dof)
    R.failAttribute(p, "joint", "<" + tag + "> attribute 'joint': expected 1.." + std::to_string(dof) + ", found '" +
                                    R.text(p, "joint") + "'");
  const int j = static_cast<int>(jv) - 1;
  const bool revolute = model.nominal.joints[static_cast<size_t>(j)].type == JointType::kRevolute;
  const std::string unit = R.text(p, "unit");
  if (unit != (revolute ? "deg" : "mm"))
    R.failAttribute(p, "unit", "<" + tag + "> of joint " + std::to_string(j + 1) + ": expected unit '" +
                                   (revolute ? "deg" : "mm") + "', found '" + unit + "'");
  const double lower = R.number(p, "lower"), upper = R.number(p, "upper");
  if (!(lower < upper))
    R.failAttribute(p, "lower", "<" + tag + ">: expected lower < upper, found lower " + fmt(lower) + ", upper " + fmt(upper));
  if (tag == "fit_range") {
    if (!range_seen.insert(j).second)
      R.fail(p, "<calibration>: expected one <fit_range> per joint, found a second one for joint " + std::to_string(j + 1));
    ranges[static_cast<size_t>(j)] = {lower, upper};
    return;
  }
  JointMap& m = model.deviations.joint_map[static_cast<size_t>(j)];
  if (!m.empty())
    R.fail(p, "<calibration>: expected one <joint_map> per joint, found a second one for joint " + std::to_string(j + 1));
  const double iv = R.number(p, "intervals");
  if (iv != std::floor(iv) || iv < 1 || iv > 100000)
    R.failAttribute(p, "intervals", "<joint_map> attribute 'intervals': expected an integer from 1 to 100000, found '" +
                                        R.text(p, "intervals") + "'");
  m.lower = lower;
  m.upper = upper;
  m.intervals = static_cast<int>(iv);
  m.taper = R.number(p, "taper");
  if (!(m.taper > 0)) R.failAttribute(p, "taper", "<joint_map> attribute 'taper': expected > 0, found " + fmt(m.taper));
  if (p->Attribute("period")) {  // written for revolute joints since 2026-11-27; absent: no period (older files)
    m.period = R.number(p, "period");
    if (!revolute || m.period != 360.0 || !(m.period + 1e-6 >= upper - lower + 2 * m.taper))  // deg; the file's rounding
      R.failAttribute(p, "period", "<joint_map> of joint " + std::to_string(j + 1) + " attribute 'period': expected " +
                                       (revolute ? "360 (one turn), at least the interval and its tapers, " + fmt(upper - lower + 2 * m.taper) + " deg"
                                                 : std::string("none for a prismatic joint")) +
                                       ", found " + fmt(m.period));
  }
  const double scale = revolute ? kRadToDeg : 1.0;
  std::istringstream values(p->GetText() ? p->GetText() : "");
  for (std::string v; values >> v;) {
    char* end = nullptr;
    const double x = std::strtod(v.c_str(), &end);
    if (end == v.c_str() || *end != '\0' || !std::isfinite(x) || std::abs(x) > RobotReader::kMaxMagnitude)
      R.failContent(p, v, "<joint_map> of joint " + std::to_string(j + 1) +
                              ": expected finite numbers of magnitude at most 1e6, found '" + v + "'");
    m.coef.push_back(x / scale);
  }
  if (m.coef.size() != static_cast<size_t>(m.intervals) + 3)
    R.fail(p, "<joint_map> of joint " + std::to_string(j + 1) + ": expected intervals + 3 = " +
                  std::to_string(m.intervals + 3) + " values, found " + std::to_string(m.coef.size()));
}

/// <calibration>'s parameters, joint maps and fitted ranges into the model's deviations.
void readCalibration(const RobotReader& R, const XMLElement* cal, FormPolicy policy, RobotModel& model) {
  const std::vector<ParamInfo> layout = parameterLayout(model);
  std::set<std::string> seen;
  model.deviations.fit_range.clear();
  std::vector<JointRange> ranges(static_cast<size_t>(model.dof()));
  std::set<int> range_seen;
  for (const XMLElement* p = cal->FirstChildElement(); p; p = p->NextSiblingElement()) {
    const std::string tag = p->Name();
    if (tag == "joint_map" || tag == "fit_range") {
      readJointCurve(R, p, model, ranges, range_seen);
      continue;
    }
    if (tag != "parameter")
      R.fail(p, "<calibration>: expected <parameter>, <joint_map> or <fit_range>, found <" + tag + ">");
    R.checkAttributes(p, {"name", "value", "sigma", "unit"});
    R.checkContent(p, false);
    const std::string name = R.text(p, "name");
    auto it = std::find_if(layout.begin(), layout.end(),
                           [&](const ParamInfo& info) { return info.name == name; });
    if (it == layout.end())
      R.failAttribute(p, "name", "<parameter> attribute 'name': expected a parameter of this robot and form '" +
                                     std::string(policy == FormPolicy::kDHOnly ? "dh" : "auto") + "', found unknown parameter name '" +
                                     name + "'");
    if (!seen.insert(name).second)
      R.failAttribute(p, "name", "<calibration>: expected each parameter once, found '" + name + "' given twice");
    const std::string unit = R.text(p, "unit");
    if (unit != it->unit)
      R.failAttribute(p, "unit", "<parameter> '" + name + "': expected unit '" + it->unit + "', found '" + unit + "'");
    setParameter(model.deviations, *it, R.number(p, "value") / it->display_scale);
    if (p->Attribute("sigma")) {
      const std::string s = R.text(p, "sigma");
      if (s != "nan") R.number(p, "sigma");  // validated, informative only
    }
  }
  if (!range_seen.empty()) {
    if (static_cast<int>(range_seen.size()) != model.dof())
      R.fail(cal, "<calibration>: expected a <fit_range> for every joint or none, found " +
                      std::to_string(range_seen.size()) + " of " + std::to_string(model.dof()));
    model.deviations.fit_range = ranges;
  }
}

}  // namespace

RobotModel readRobotFile(const std::string& path) {
  if (fs::path(path).extension() == ".urdf") return readUrdfRobot(path);  // urdf.h, default chain
  std::string text;
  {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path, 0, 0, "expected a robot file, cannot open it");
    std::ostringstream s;
    s << in.rdbuf();
    if (in.bad()) throw InputError(path, 0, 0, "expected a robot file, cannot read it");
    text = s.str();
  }
  tinyxml2::XMLDocument doc;
  parseXml(doc, text, path, "a robot file with root element <robot>");
  const XmlPositions positions(text, doc);
  const RobotReader R(path, positions);
  const XMLElement* root = doc.RootElement();
  if (!root || std::string(root->Name()) != "robot")
    R.fail(root, "expected root element <robot>, found <" + std::string(root ? root->Name() : "nothing") + ">");
  // a URDF under another name (robot_description.xml): its <robot> holds <link>s and no <joints>;
  // so is a xacro source (<xacro:include>, <xacro:macro>, macro calls), which the URDF reader names
  bool xacro = false;
  for (const XMLElement* c = root->FirstChildElement(); c && !xacro; c = c->NextSiblingElement())
    xacro = std::string(c->Name()).rfind("xacro:", 0) == 0;
  if ((root->FirstChildElement("link") || xacro) && !root->FirstChildElement("joints")) return readUrdfRobot(path);
  const RobotDefinition def = readDefinition(R, root);
  FormPolicy policy = FormPolicy::kAuto;
  const XMLElement* cal = R.child(root, "calibration", false);
  if (cal) {
    R.checkAttributes(cal, {"form", "data"});
    R.checkContent(cal, true);
    const std::string form = R.text(cal, "form");
    if (form == "dh") policy = FormPolicy::kDHOnly;
    else if (form != "auto") R.failAttribute(cal, "form", "<calibration> attribute 'form': expected 'auto' or 'dh', found '" + form + "'");
  }
  RobotModel model = RobotModel::fromDefinition(def, policy);
  if (cal) readCalibration(R, cal, policy, model);
  return model;
}

void writeRobotFile(const std::string& path, const RobotModel& model,
                    const std::vector<ParameterRecord>& records, const std::string& comment) {
  writeFileAtomically(path, robotFileText(model, records, comment));
}

std::string robotFileText(const RobotModel& model, const std::vector<ParameterRecord>& records,
                          const std::string& comment) {
  model.validate();
  std::ostringstream out;
  out << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  if (!comment.empty()) {
    std::string c = comment;
    for (size_t pos; (pos = c.find("--")) != std::string::npos;) c.replace(pos, 2, "- -");
    out << "<!--\n" << c << "\n-->\n";
  }
  const RobotDefinition& d = model.nominal;
  out << "<robot name=\"" << xmlEscape(d.name) << "\"";
  if (!d.source.empty()) out << " source=\"" << xmlEscape(d.source) << "\"";
  out << ">\n";
  writePose(out, "base", d.T_world_base, "  ");
  writePose(out, "tool", d.T_flange_tcp, "  ");
  out << "  <payload com_x_mm=\"" << fmt(d.payload_com_mm.x()) << "\" com_y_mm=\""
      << fmt(d.payload_com_mm.y()) << "\" com_z_mm=\"" << fmt(d.payload_com_mm.z()) << "\"/>\n";
  out << "  <gravity x=\"" << fmt(d.gravity_base.x()) << "\" y=\"" << fmt(d.gravity_base.y())
      << "\" z=\"" << fmt(d.gravity_base.z()) << "\"/>\n";
  out << "  <joints>\n";
  for (const JointSpec& j : d.joints) {
    out << "    <joint name=\"" << xmlEscape(j.name) << "\" type=\""
        << (j.type == JointType::kRevolute ? "revolute" : "prismatic") << "\" a_mm=\""
        << fmt(j.a_mm) << "\" alpha_deg=\"" << fmt(j.alpha_deg) << "\" d_mm=\"" << fmt(j.d_mm)
        << "\" theta0_deg=\"" << fmt(j.theta0_deg) << "\" direction=\"" << j.direction
        << "\"\n           lower=\"" << fmt(j.lower) << "\" upper=\"" << fmt(j.upper)
        << "\" mass_kg=\"" << fmt(j.mass_kg) << "\" com_x_mm=\"" << fmt(j.com_mm.x())
        << "\" com_y_mm=\"" << fmt(j.com_mm.y()) << "\" com_z_mm=\"" << fmt(j.com_mm.z())
        << "\"/>\n";
  }
  out << "  </joints>\n";
  const bool dh = model.forms != chooseLinkForms(d, FormPolicy::kAuto);
  const std::vector<ParamInfo> layout = parameterLayout(model);
  std::map<std::string, const ParameterRecord*> by_name;
  for (const auto& r : records) by_name[r.name] = &r;
  std::ostringstream params;
  for (const ParamInfo& p : layout) {
    const double v = getParameter(model.deviations, p) * p.display_scale;
    if (p.kind == ParamKind::kJointMap) continue;  // written as <joint_map> below
    auto it = by_name.find(p.name);
    if (v == 0.0 && it == by_name.end()) continue;
    // the reader takes magnitudes up to 1e6 (RobotReader::kMaxMagnitude): a file it would refuse is
    // not written; such a value is a parameter the data did not determine
    const double sigma = it != by_name.end() ? it->second->sigma : 0.0;
    if (std::abs(v) > RobotReader::kMaxMagnitude || (std::isfinite(sigma) && std::abs(sigma) > RobotReader::kMaxMagnitude))
      throw NumericalError(p.name + " = " + fmt(v) + (it != by_name.end() ? " +- " + fmt(sigma) : std::string()) + " " + p.unit +
                           ": beyond what a robot file holds (magnitude at most 1e6): the data does not determine it, and the "
                           "model is not written; leave it out of --params (e.g. joint_compliance:j1+j2+j3), or measure what "
                           "determines it (for a compliance: poses with payloads)");
    params << "    <parameter name=\"" << p.name << "\" value=\"" << fmt(v) << "\"";
    if (it != by_name.end()) {
      params << " sigma=\"" << (std::isfinite(it->second->sigma) ? fmt(it->second->sigma) : "nan") << "\"";
    }
    params << " unit=\"" << p.unit << "\"/>\n";
  }
  // joint maps (values in deg or mm, one per coefficient) and the fitted joint ranges
  for (int i = 0; i < model.dof(); ++i) {
    const JointMap& m = model.deviations.joint_map[static_cast<size_t>(i)];
    if (m.empty()) continue;
    const bool revolute = d.joints[static_cast<size_t>(i)].type == JointType::kRevolute;
    params << "    <joint_map joint=\"" << i + 1 << "\" lower=\"" << fmt(m.lower) << "\" upper=\"" << fmt(m.upper)
           << "\" intervals=\"" << m.intervals << "\" taper=\"" << fmt(m.taper)
           << (m.period > 0 ? "\" period=\"" + fmt(m.period) : std::string()) << "\" unit=\""
           << (revolute ? "deg" : "mm") << "\">";
    for (size_t k = 0; k < m.coef.size(); ++k)
      params << (k % 8 == 0 ? "\n      " : " ") << fmt(m.coef[k] * (revolute ? kRadToDeg : 1.0));
    params << "\n    </joint_map>\n";
  }
  for (size_t i = 0; i < model.deviations.fit_range.size(); ++i) {
    const JointRange& r = model.deviations.fit_range[i];
    params << "    <fit_range joint=\"" << i + 1 << "\" lower=\"" << fmt(r.lower) << "\" upper=\"" << fmt(r.upper)
           << "\" unit=\"" << (d.joints[i].type == JointType::kRevolute ? "deg" : "mm") << "\"/>\n";
  }
  if (!params.str().empty() || dh) {
    out << "  <calibration form=\"" << (dh ? "dh" : "auto") << "\">\n" << params.str()
        << "  </calibration>\n";
  }
  out << "</robot>\n";
  return out.str();
}

std::vector<std::string> bundledRobotNames() {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(robotsDir(), ec)) {
    if (e.path().extension() == ".xml") names.push_back(e.path().stem().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

std::string resolveRobotPath(const std::string& name_or_path) {
  std::error_code ec;
  if (fs::is_regular_file(name_or_path, ec)) return name_or_path;
  const fs::path dir = robotsDir();
  for (const std::string& candidate : {name_or_path, name_or_path + ".xml"}) {
    const fs::path p = dir / candidate;
    if (name_or_path.find('/') == std::string::npos && fs::is_regular_file(p, ec)) return p.string();
  }
  std::string list;
  for (const auto& n : bundledRobotNames()) list += (list.empty() ? "" : ", ") + n;
  // what is at the path: nothing (a path mistyped, a model not yet written), a directory, another
  // kind of file, or a status that cannot be read (a directory on the way without search
  // permission: its reason, not "no such file")
  const fs::file_status st = fs::status(name_or_path, ec);
  const std::string what = ec && ec != std::errc::no_such_file_or_directory ? ec.message()
                           : fs::is_directory(st)                          ? "a directory"
                           : fs::exists(st)                                ? "not a regular file"
                                                                           : "no such file";
  throw InputError("expected a robot file or one of the bundled robots (" + list + "), found '" + name_or_path + "' (" + what + ")");
}

}  // namespace accura::calib
