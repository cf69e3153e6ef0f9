// accura: URDF -> serial chain. tinyxml2 checks the file and gives file:line for every error
// it can find; urdfdom (the ROS parser, packaged by Debian) then parses it and its model gives
// the data. Where urdfdom still rejects the file, its message is mapped to the element it names.
#include <console_bridge/console.h>
#include <tinyxml2.h>
#include <urdf_parser/urdf_parser.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/text.h"
#include "accura/calib/urdf.h"
#include "accura/calib/xml_text.h"

namespace accura::calib {
namespace {

using tinyxml2::XMLElement;

constexpr double kMaxUrdfLengthM = 100.0;  // a joint origin further than this is absurd for an arm
constexpr double kMaxUrdfMassKg = 1e5;
constexpr double kMaxUrdfAngleRad = 1000.0;  // an rpy beyond this is absurd
constexpr double kMaxUrdfLimitM = 100.0;     // a prismatic limit beyond this is absurd
constexpr double kMaxUrdfLimitRad = 4 * kPi;  // a revolute limit beyond two turns is no radian value

struct UrdfJointInfo {
  int line = 0;
  const XMLElement* element = nullptr;
  const XMLElement* limit = nullptr;
  std::string type, parent, child;
  bool mimic = false;
};

// What the tinyxml2 pass knows: lines of links and joints, and the tree.
struct UrdfIndex {
  std::string file;
  int robot_line = 0;
  std::map<std::string, int> link_line;
  std::map<std::string, const XMLElement*> link_element;
  const XMLElement* robot = nullptr;
  const XmlPositions* pos = nullptr;
  std::map<std::string, UrdfJointInfo> joints;
  std::map<std::string, std::string> parent_joint;                // child link -> joint
  std::map<std::string, std::vector<std::string>> child_joints;   // link -> joints, file order

  /// An error in the element (at its '<').
  [[noreturn]] void fail(const XMLElement* e, const std::string& msg) const {
    const auto [line, column] = pos->element(e);
    throw InputError(file, line, column, msg);
  }
  /// An error in one of its attributes (at the attribute's name).
  [[noreturn]] void failAttribute(const XMLElement* e, const std::string& attr, const std::string& msg) const {
    const auto [line, column] = pos->attribute(e, attr);
    throw InputError(file, line, column, msg);
  }
};

bool isMoving(const std::string& type) {
  return type == "revolute" || type == "continuous" || type == "prismatic";
}

// What an error about a value adds when the value holds a xacro expression ("${pi/2}",
// "$(find pkg)"): the file is a xacro source, or its expansion failed part-way.
std::string xacroNote(const char* value) {
  const std::string v = value ? value : "";
  return v.find("${") != std::string::npos || v.find("$(") != std::string::npos
             ? " (an unexpanded xacro expression: give accura xacro's output, xacro FILE.xacro > FILE.urdf)"
             : "";
}

// The first xacro element (<xacro:include>, <xacro:macro>, a macro call) in document order; a
// declaration (<xacro:property>, <xacro:arg>) changes nothing by itself (a value that uses it holds
// ${...}), and ROS reads such a file as the URDF it otherwise is.
const XMLElement* firstXacroElement(const XMLElement* e) {
  for (; e; e = e->NextSiblingElement()) {
    const std::string name = e->Name();
    if (name == "xacro:property" || name == "xacro:arg") continue;
    if (name.rfind("xacro:", 0) == 0) return e;
    if (const XMLElement* inner = firstXacroElement(e->FirstChildElement())) return inner;
  }
  return nullptr;
}

// "a b c": three finite numbers, else InputError at the element's line.
Eigen::Vector3d triple(const UrdfIndex& ix, const XMLElement* e, const char* attr, const Eigen::Vector3d& dflt) {
  const char* v = e->Attribute(attr);
  if (!v) return dflt;
  std::istringstream in(v);
  Eigen::Vector3d r;
  std::string tok;
  int k = 0;
  while (in >> tok) {
    char* end = nullptr;
    const double x = std::strtod(tok.c_str(), &end);
    if (k >= 3 || end == tok.c_str() || *end != '\0' || !std::isfinite(x))
      ix.failAttribute(e, attr, "<" + std::string(e->Name()) + "> attribute '" + attr +
                                    "': expected three finite numbers, found '" + v + "'" + xacroNote(v));
    r[k++] = x;
  }
  if (k != 3)
    ix.failAttribute(e, attr, "<" + std::string(e->Name()) + "> attribute '" + attr +
                                  "': expected three finite numbers, found '" + v + "'" + xacroNote(v));
  return r;
}

double scalar(const UrdfIndex& ix, const XMLElement* e, const char* attr, bool required, double dflt = 0) {
  const char* v = e->Attribute(attr);
  if (!v) {
    if (required) ix.fail(e, "<" + std::string(e->Name()) + ">: expected an attribute '" + attr + "', found none");
    return dflt;
  }
  char* end = nullptr;
  const double x = std::strtod(v, &end);
  while (end && (*end == ' ' || *end == '\t')) ++end;
  if (end == v || *end != '\0' || !std::isfinite(x))
    ix.failAttribute(e, attr, "<" + std::string(e->Name()) + "> attribute '" + attr +
                                  "': expected a finite number, found '" + v + "'" + xacroNote(v));
  return x;
}

std::string nameAttr(const UrdfIndex& ix, const XMLElement* e, const char* attr = "name") {
  const char* v = e->Attribute(attr);
  if (!v) ix.fail(e, "<" + std::string(e->Name()) + ">: expected an attribute '" + attr + "', found none");
  if (!*v) ix.failAttribute(e, attr, "<" + std::string(e->Name()) + "> attribute '" + attr + "': expected a name, found an empty one");
  // urdfdom's own reader would not give such a name back as it is (its model would lack it)
  if (!isPlainText(v))
    ix.failAttribute(e, attr, "<" + std::string(e->Name()) + "> attribute '" + attr +
                                  "': expected a name of UTF-8 text without control characters, found '" + printableBytes(v) + "'");
  return v;
}

const XMLElement* onlyChild(const UrdfIndex& ix, const XMLElement* parent, const char* name, bool required) {
  const XMLElement* c = parent->FirstChildElement(name);
  if (!c && required)
    ix.fail(parent, "<" + std::string(parent->Name()) + " name=\"" + (parent->Attribute("name") ? parent->Attribute("name") : "") +
                        "\">: expected a <" + name + "> element, found none");
  if (c && c->NextSiblingElement(name))
    ix.fail(c->NextSiblingElement(name), "<" + std::string(parent->Name()) + ">: expected one <" + name +
                                             "> element, found a second one");
  return c;
}

void checkOrigin(const UrdfIndex& ix, const XMLElement* origin) {
  if (!origin) return;
  const Eigen::Vector3d xyz = triple(ix, origin, "xyz", Eigen::Vector3d::Zero());
  const Eigen::Vector3d rpy = triple(ix, origin, "rpy", Eigen::Vector3d::Zero());
  if (xyz.cwiseAbs().maxCoeff() > kMaxUrdfLengthM) {
    std::ostringstream s;
    s << "<origin> attribute 'xyz': expected an offset of at most " << kMaxUrdfLengthM
      << " m (URDF lengths are in metres), found " << xyz.cwiseAbs().maxCoeff() << " m";
    ix.failAttribute(origin, "xyz", s.str());
  }
  if (rpy.cwiseAbs().maxCoeff() > kMaxUrdfAngleRad) {
    std::ostringstream s;
    s << "<origin> attribute 'rpy': expected angles of at most " << kMaxUrdfAngleRad << " rad, found "
      << rpy.cwiseAbs().maxCoeff() << " rad";
    ix.failAttribute(origin, "rpy", s.str());
  }
}

// The tinyxml2 pass: every check with a line number.
UrdfIndex indexUrdf(const tinyxml2::XMLDocument& doc, const std::string& file, const XmlPositions& pos) {
  UrdfIndex ix;
  ix.file = file;
  ix.pos = &pos;
  const XMLElement* robot = doc.RootElement();
  if (!robot || std::string(robot->Name()) != "robot")
    ix.fail(robot, std::string("expected root element <robot>, found <") + (robot ? robot->Name() : "nothing") + ">");
  ix.robot_line = robot->GetLineNum();
  ix.robot = robot;
  // a xacro source (ROS packages ship the arm as <arm>_macro.xacro and <arm>.urdf.xacro): its
  // macros and includes are not URDF; every check below would name a symptom instead
  if (const XMLElement* x = firstXacroElement(robot->FirstChildElement()))
    ix.fail(x, "expected a URDF (xacro's output: xacro FILE.xacro > FILE.urdf), found the xacro element <" +
                   std::string(x->Name()) + ">: the file is an unexpanded xacro source");
  nameAttr(ix, robot);
  for (const XMLElement* l = robot->FirstChildElement("link"); l; l = l->NextSiblingElement("link")) {
    const std::string name = nameAttr(ix, l);
    if (!ix.link_line.emplace(name, l->GetLineNum()).second)
      ix.failAttribute(l, "name", "<link>: expected each link name once, found '" + name + "' a second time (first at line " +
                                      std::to_string(ix.link_line[name]) + ")");
    ix.link_element[name] = l;
    if (const XMLElement* in = onlyChild(ix, l, "inertial", false)) {
      checkOrigin(ix, onlyChild(ix, in, "origin", false));
      const XMLElement* mass = onlyChild(ix, in, "mass", true);
      const double m = scalar(ix, mass, "value", true);
      if (m < 0 || m > kMaxUrdfMassKg)
        ix.failAttribute(mass, "value", "<mass> of link '" + name + "': expected 0 to 1e5 kg, found " +
                                            std::string(mass->Attribute("value")));
      if (const XMLElement* inertia = onlyChild(ix, in, "inertia", true))
        for (const char* a : {"ixx", "ixy", "ixz", "iyy", "iyz", "izz"}) scalar(ix, inertia, a, true);
    }
  }
  if (ix.link_line.empty()) ix.fail(robot, "<robot>: expected at least one <link>, found none");
  for (const XMLElement* j = robot->FirstChildElement("joint"); j; j = j->NextSiblingElement("joint")) {
    const std::string name = nameAttr(ix, j);
    UrdfJointInfo info;
    info.line = j->GetLineNum();
    info.element = j;
    info.type = nameAttr(ix, j, "type");
    static const std::set<std::string> types = {"revolute", "continuous", "prismatic", "fixed", "floating", "planar"};
    if (!types.count(info.type))
      ix.failAttribute(j, "type", "joint '" + name + "' attribute 'type': expected revolute, continuous, prismatic, fixed, "
                                  "floating or planar, found '" + info.type + "'");
    const XMLElement* parent = onlyChild(ix, j, "parent", true);
    const XMLElement* child = onlyChild(ix, j, "child", true);
    info.parent = nameAttr(ix, parent, "link");
    info.child = nameAttr(ix, child, "link");
    for (const auto& [l, e] : {std::pair{&info.parent, parent}, std::pair{&info.child, child}})
      if (!ix.link_line.count(*l))
        ix.failAttribute(e, "link", "joint '" + name + "': expected a declared link, found '" + *l + "' (no <link name=\"" + *l + "\">)");
    if (info.parent == info.child)
      ix.failAttribute(child, "link", "joint '" + name + "': expected a child link other than the parent, found '" + info.parent + "' for both");
    checkOrigin(ix, onlyChild(ix, j, "origin", false));
    if (const XMLElement* axis = onlyChild(ix, j, "axis", false)) {
      // urdfdom leaves an <axis> without xyz at (0, 0, 0), and normalises one of infinite
      // length (1e308 components) to zero: both would be a joint without a direction
      if (!axis->Attribute("xyz")) ix.fail(axis, "<axis>: expected an attribute 'xyz', found none");
      const Eigen::Vector3d a = triple(ix, axis, "xyz", Eigen::Vector3d::UnitX());
      if (isMoving(info.type) && !(a.norm() >= 1e-9 && a.cwiseAbs().maxCoeff() <= 1e6))
        ix.failAttribute(axis, "xyz", "joint '" + name + "' <axis> attribute 'xyz': expected a non-zero axis with components of at most 1e6, found '" +
                                          axis->Attribute("xyz") + "'");
    }
    const XMLElement* limit = onlyChild(ix, j, "limit", info.type == "revolute" || info.type == "prismatic");
    if (limit) {
      info.limit = limit;
      for (const char* a : {"lower", "upper"}) {
        const double v = scalar(ix, limit, a, false);
        if (info.type == "prismatic" && std::abs(v) > kMaxUrdfLimitM)
          ix.failAttribute(limit, a, "joint '" + name + "' <limit> attribute '" + a + "': expected at most 100 m in magnitude, found '" +
                                         limit->Attribute(a) + "'");
        // a revolute joint's limit beyond two turns is no radian value: degrees written into a URDF
        if (info.type == "revolute" && std::abs(v) > kMaxUrdfLimitRad) {
          std::ostringstream s;
          s << "joint '" << name << "' <limit> attribute '" << a << "': expected radians (URDF limits are in rad: at most two turns, "
            << formatNumber("%.5g", kMaxUrdfLimitRad) << " rad, in magnitude), found '" << limit->Attribute(a) << "'";
          if (std::abs(v) <= 1e6) s << " (" << formatNumber("%.6g", v * kRadToDeg) << " deg; degrees written as radians?)";
          ix.failAttribute(limit, a, s.str());
        }
      }
      scalar(ix, limit, "effort", true);
      scalar(ix, limit, "velocity", true);
    }
    if (const XMLElement* mimic = onlyChild(ix, j, "mimic", false)) {
      nameAttr(ix, mimic, "joint");
      scalar(ix, mimic, "multiplier", false, 1);
      scalar(ix, mimic, "offset", false, 0);
      info.mimic = true;
    }
    if (ix.joints.count(name))
      ix.failAttribute(j, "name", "<joint>: expected each joint name once, found '" + name + "' a second time (first at line " +
                                      std::to_string(ix.joints[name].line) + ")");
    auto prev = ix.parent_joint.find(info.child);
    if (prev != ix.parent_joint.end())
      ix.failAttribute(child, "link", "joint '" + name + "' closes a loop: expected link '" + info.child + "' to be the child of one joint, found it "
                                      "already the child of joint '" + prev->second + "' (line " +
                                      std::to_string(ix.joints[prev->second].line) +
                                      "); a URDF describes a tree and accura needs a serial chain");
    ix.parent_joint[info.child] = name;
    ix.child_joints[info.parent].push_back(name);
    ix.joints[name] = info;
  }
  for (const auto& [name, info] : ix.joints) {
    if (!info.mimic) continue;
    const XMLElement* mimic = info.element->FirstChildElement("mimic");
    const std::string target = mimic->Attribute("joint");
    if (!ix.joints.count(target))
      ix.failAttribute(mimic, "joint", "joint '" + name + "' <mimic> attribute 'joint': expected a joint of this URDF, found '" +
                                           target + "'");
  }
  // One root; no cycle (a cycle of links without a root is caught here too).
  std::vector<std::string> roots;
  for (const auto& [name, line] : ix.link_line)
    if (!ix.parent_joint.count(name)) roots.push_back(name);
  if (roots.size() != 1) {
    std::string list;
    for (const auto& r : roots) list += (list.empty() ? "" : ", ") + r + " (line " + std::to_string(ix.link_line[r]) + ")";
    ix.fail(robot, roots.empty() ? "expected one root link (a link that is no joint's child), found none: the joints form a closed loop"
                                 : "expected one root link (a link that is no joint's child), found " +
                                       std::to_string(roots.size()) + ": " + list);
  }
  // Every link below the root: links in a closed loop of joints beside the tree have parents
  // but are not reachable (the walks over the tree below would never end).
  std::set<std::string> reached = {roots[0]};
  for (std::vector<std::string> todo = {roots[0]}; !todo.empty();) {
    const std::string link = todo.back();
    todo.pop_back();
    const auto it = ix.child_joints.find(link);
    if (it == ix.child_joints.end()) continue;
    for (const auto& jn : it->second)
      if (reached.insert(ix.joints.at(jn).child).second) todo.push_back(ix.joints.at(jn).child);
  }
  for (const XMLElement* l = robot->FirstChildElement("link"); l; l = l->NextSiblingElement("link")) {
    const std::string name = l->Attribute("name");
    if (reached.count(name)) continue;
    const UrdfJointInfo& j = ix.joints.at(ix.parent_joint.at(name));  // not the root: it has a parent
    ix.fail(j.element, "joint '" + ix.parent_joint.at(name) + "' closes a loop: expected every link below the root link '" +
                           roots[0] + "', found link '" + name + "' in a closed loop of joints");
  }
  return ix;
}

// Collects urdfdom's console_bridge messages while it parses.
class Capture : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char*, int) override {
    if (level >= console_bridge::CONSOLE_BRIDGE_LOG_ERROR) errors += (errors.empty() ? "" : "; ") + text;
  }
  std::string errors;
};

urdf::ModelInterfaceSharedPtr parseWithUrdfdom(const std::string& text, const UrdfIndex& ix) {
  static std::mutex mutex;  // console_bridge's handler is process-wide
  std::lock_guard<std::mutex> lock(mutex);
  Capture capture;
  console_bridge::useOutputHandler(&capture);
  urdf::ModelInterfaceSharedPtr model;
  try {
    model = urdf::parseURDF(text);
  } catch (const std::exception& e) {
    capture.errors += std::string(capture.errors.empty() ? "" : "; ") + e.what();
  }
  console_bridge::restorePreviousOutputHandler();
  if (!model) {
    // Point at the first joint or link the message names.
    const XMLElement* at = ix.robot;
    for (const auto& [name, info] : ix.joints)
      if (capture.errors.find("[" + name + "]") != std::string::npos || capture.errors.find("'" + name + "'") != std::string::npos) {
        at = info.element;
        break;
      }
    if (at == ix.robot)
      for (const auto& [name, l] : ix.link_element)
        if (capture.errors.find("[" + name + "]") != std::string::npos || capture.errors.find("'" + name + "'") != std::string::npos) {
          at = l;
          break;
        }
    ix.fail(at, "expected a URDF urdfdom accepts, found one it rejects: " +
                    (capture.errors.empty() ? std::string("no reason given") : capture.errors));
  }
  return model;
}

Eigen::Isometry3d poseMm(const urdf::Pose& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(p.rotation.w, p.rotation.x, p.rotation.y, p.rotation.z).normalized().toRotationMatrix();
  T.translation() = 1000.0 * Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  return T;
}

// Whether the subtree below `link` holds a moving joint.
bool hasMovingBelow(const UrdfIndex& ix, const std::string& link) {
  auto it = ix.child_joints.find(link);
  if (it == ix.child_joints.end()) return false;
  for (const auto& jn : it->second) {
    const UrdfJointInfo& j = ix.joints.at(jn);
    if (isMoving(j.type) || hasMovingBelow(ix, j.child)) return true;
  }
  return false;
}

// Down from `link` while there is one child with moving joints below it (then fixed joints
// while there is one child): where the default chain ends, or where the tree branches.
std::string followDown(const UrdfIndex& ix, std::string link, std::vector<std::string>* branches) {
  for (;;) {
    auto it = ix.child_joints.find(link);
    if (it == ix.child_joints.end()) return link;
    std::vector<std::string> moving;
    for (const auto& jn : it->second) {
      const UrdfJointInfo& j = ix.joints.at(jn);
      if (isMoving(j.type) || hasMovingBelow(ix, j.child)) moving.push_back(jn);
    }
    if (moving.size() == 1) {
      link = ix.joints.at(moving[0]).child;
    } else if (moving.empty() && it->second.size() == 1) {
      link = ix.joints.at(it->second[0]).child;  // a fixed frame after the last joint (flange)
    } else {
      if (branches) *branches = moving;
      return link;
    }
  }
}

// `accepted(spec)`: whether --chain spec reads (the suggestions name only such chains).
std::string defaultTip(const UrdfIndex& ix, const std::string& root, const std::function<bool(const std::string&)>& accepted) {
  if (ix.link_line.count("tool0")) return "tool0";
  std::vector<std::string> moving;
  const std::string link = followDown(ix, root, &moving);
  if (moving.size() < 2) return link;
  std::string list;
  for (const auto& jn : moving) list += (list.empty() ? "" : ", ") + ix.joints.at(jn).child;
  // the chain up to the branching link (what branches off beyond its tip is the last joint's
  // load: a gripper's fingers), then one along each branch
  std::vector<std::string> tips = {link};
  for (const auto& jn : moving) tips.push_back(followDown(ix, ix.joints.at(jn).child, nullptr));
  std::string ok;
  for (const std::string& tip : tips) {
    if (tip == root || !accepted(root + ":" + tip)) continue;
    ok += (ok.empty() ? "" : " or ") + ("--chain " + root + ":" + tip) +
          (tip == link ? " (the moving joints beyond its tip are the last joint's load, like a gripper's fingers)" : "");
  }
  ix.fail(ix.link_element.at(link), "expected one default chain, found the tree branching at link '" + link + "' into " + list +
                                        "; choose one with --chain ROOT:TIP" + (ok.empty() ? std::string() : ": " + ok));
}

}  // namespace

SerialChain parseUrdfChain(const std::string& text, const std::string& file, const std::string& chain_spec) {
  tinyxml2::XMLDocument doc;
  parseXml(doc, text, file, "a URDF with root element <robot>");
  const XmlPositions positions(text, doc);
  const UrdfIndex ix = indexUrdf(doc, file, positions);
  const urdf::ModelInterfaceSharedPtr model = parseWithUrdfdom(text, ix);

  std::string root, tip;
  if (chain_spec.empty()) {
    root = model->getRoot()->name;
    tip = defaultTip(ix, root, [&](const std::string& spec) {
      try {
        parseUrdfChain(text, file, spec);
        return true;
      } catch (const InputError&) {
        return false;
      }
    });
  } else {
    const size_t colon = chain_spec.find(':');
    if (colon == std::string::npos || chain_spec.find(':', colon + 1) != std::string::npos)
      throw InputError("--chain: expected ROOT_LINK:TIP_LINK, found '" + chain_spec + "'");
    root = chain_spec.substr(0, colon);
    tip = chain_spec.substr(colon + 1);
    for (const std::string* l : {&root, &tip})
      if (!ix.link_line.count(*l)) {
        std::string list;
        for (const auto& [name, line] : ix.link_line) list += (list.empty() ? "" : ", ") + name;
        throw InputError("--chain " + chain_spec + ": expected a link of " + file + " (" + list + "), found no link '" + *l + "'");
      }
  }
  // Path root -> tip: up from the root over fixed joints to the lowest link above both (for a
  // root like UR's 'base', a sibling frame of the chain's links), then down to the tip.
  std::vector<std::string> above_root = {root};
  for (std::string l = root; ix.parent_joint.count(l);) above_root.push_back(l = ix.joints.at(ix.parent_joint.at(l)).parent);
  std::vector<std::string> path;
  std::string meet;
  for (std::string l = tip;;) {
    if (std::find(above_root.begin(), above_root.end(), l) != above_root.end()) {
      meet = l;
      break;
    }
    auto it = ix.parent_joint.find(l);
    if (it == ix.parent_joint.end())
      ix.fail(ix.link_element.at(tip), "chain " + root + ":" + tip + ": expected link '" + tip + "' connected to link '" + root +
                                           "', found it in another tree");
    path.insert(path.begin(), it->second);
    l = ix.joints.at(it->second).parent;
  }
  // urdfdom's joint of a name the index holds: both read the same text, so a joint urdfdom
  // lacks is a document the two readers read differently (a located error, never a null)
  auto urdfJoint = [&](const std::string& jn) {
    const urdf::JointConstSharedPtr j = model->getJoint(jn);
    if (!j) ix.failAttribute(ix.joints.at(jn).element, "name", "joint '" + printableBytes(jn) + "': expected urdfdom (the URDF reader) to find this joint too, found it missing from its model: the two XML readers "
                                                                  "read its name differently (a bare '&' or a character reference in it?); write the name in plain characters");
    return j;
  };
  Eigen::Isometry3d T_meet_root = Eigen::Isometry3d::Identity();  // over fixed joints only
  for (std::string l = root; l != meet;) {
    const std::string& jn = ix.parent_joint.at(l);
    const UrdfJointInfo& info = ix.joints.at(jn);
    if (info.type != "fixed")
      ix.fail(info.element, "chain " + root + ":" + tip + ": expected link '" + tip + "' below link '" + root +
                                "' or fixed joints up from it, found the moving joint '" + jn + "' on the way up");
    T_meet_root = poseMm(urdfJoint(jn)->parent_to_joint_origin_transform) * T_meet_root;
    l = info.parent;
  }

  SerialChain chain;
  chain.name = model->getName();
  chain.source = file;
  chain.root_link = root;
  chain.tip_link = tip;
  const std::set<std::string> on_path(path.begin(), path.end());

  // Mass and first moment of the links rigidly attached to `link` (fixed joints, downwards),
  // in the frame `T_frame_link` maps from; moving joints met on the way are branches unless they
  // are the chain's next joint. The last chain joint carries everything below it, whatever the
  // joints (a gripper's fingers beyond the tip or branching off the links up to it): their links
  // at those joints' zero (a mimic joint at its offset) are its load.
  // Mass of the links below `link`, the link itself included (every joint).
  std::function<double(const std::string&)> subtreeMass = [&](const std::string& link) {
    const urdf::LinkConstSharedPtr l = model->getLink(link);
    double mass = l && l->inertial && l->inertial->mass > 0 ? l->inertial->mass : 0.0;
    auto it = ix.child_joints.find(link);
    if (it != ix.child_joints.end())
      for (const auto& jn : it->second) mass += subtreeMass(ix.joints.at(jn).child);
    return mass;
  };
  std::function<void(const std::string&, const Eigen::Isometry3d&, bool, const std::string&, double&, Eigen::Vector3d&)> body;
  body = [&](const std::string& link, const Eigen::Isometry3d& T, bool last, const std::string& mover, double& mass,
             Eigen::Vector3d& moment) {
    const urdf::LinkConstSharedPtr l = model->getLink(link);
    if (l && l->inertial && l->inertial->mass > 0) {
      mass += l->inertial->mass;
      moment += l->inertial->mass * (T * (1000.0 * Eigen::Vector3d(l->inertial->origin.position.x,
                                                                    l->inertial->origin.position.y,
                                                                    l->inertial->origin.position.z)));
    }
    auto it = ix.child_joints.find(link);
    if (it == ix.child_joints.end()) return;
    for (const auto& jn : it->second) {
      const UrdfJointInfo& info = ix.joints.at(jn);
      if (info.type == "fixed") {
        const urdf::JointConstSharedPtr j = urdfJoint(jn);
        body(info.child, T * poseMm(j->parent_to_joint_origin_transform), last, mover, mass, moment);
      } else if (!on_path.count(jn) && last) {
        const urdf::JointConstSharedPtr j = urdfJoint(jn);
        Eigen::Isometry3d at_zero = T * poseMm(j->parent_to_joint_origin_transform);
        const double value = j->mimic ? j->mimic->offset : 0.0;  // rad or m
        const Eigen::Vector3d axis = Eigen::Vector3d(j->axis.x, j->axis.y, j->axis.z).normalized();
        if (value != 0.0 && (info.type == "revolute" || info.type == "continuous")) at_zero.rotate(Eigen::AngleAxisd(value, axis));
        if (value != 0.0 && info.type == "prismatic") at_zero.translate(1000.0 * value * axis);
        body(info.child, at_zero, last, mover, mass, moment);
      } else if (!on_path.count(jn) && subtreeMass(info.child) == 0) {
        // a massless branch (ROS-Industrial's mimic links of a balancing cylinder and its
        // piston, frames for visuals): it loads no joint, whatever its joints' values
      } else if (!on_path.count(jn)) {
        ix.fail(info.element, "expected a serial chain, found joint '" + jn + "' (" + info.type + "), which branches off the chain " +
                                  root + ":" + tip + " at link '" + link + "', which joint '" + mover +
                                  "' moves, and its links weigh " + formatNumber("%.6g", subtreeMass(info.child)) + " kg whose gravity load on the joints between would change with its configuration (choose another --chain, or remove the branch)");
      }
    }
  };

  Eigen::Isometry3d T_acc = T_meet_root.inverse();
  for (size_t k = 0; k < path.size(); ++k) {
    const std::string& jn = path[k];
    const UrdfJointInfo& info = ix.joints.at(jn);
    const urdf::JointConstSharedPtr j = urdfJoint(jn);
    const Eigen::Isometry3d origin = poseMm(j->parent_to_joint_origin_transform);
    if (info.type == "fixed") {
      T_acc = T_acc * origin;
      continue;
    }
    if (info.type == "floating" || info.type == "planar")
      ix.failAttribute(info.element, "type", "joint '" + jn + "' on the chain " + root + ":" + tip +
                                                 ": expected revolute, continuous, prismatic or fixed, found " + info.type);
    if (j->mimic)
      ix.fail(info.element->FirstChildElement("mimic"), "joint '" + jn + "' on the chain " + root + ":" + tip +
                                                            ": expected an independent joint, found one that mimics joint '" +
                                                            j->mimic->joint_name + "' (a mimic joint couples two)");
    ChainJoint cj;
    cj.name = jn;
    cj.line = info.line;
    cj.column = ix.pos->element(info.element).second;
    cj.type = info.type == "prismatic" ? JointType::kPrismatic : JointType::kRevolute;
    cj.T_prev_joint = T_acc * origin;
    cj.axis = Eigen::Vector3d(j->axis.x, j->axis.y, j->axis.z).normalized();
    if (info.type == "continuous") {
      cj.lower = -360;
      cj.upper = 360;
    } else {
      const double scale = info.type == "prismatic" ? 1000.0 : kRadToDeg;
      cj.lower = j->limits->lower * scale;
      cj.upper = j->limits->upper * scale;
      if (!(cj.lower < cj.upper)) {
        std::ostringstream s;
        s << "joint '" << jn << "': <limit> expected lower < upper, found lower " << j->limits->lower << ", upper "
          << j->limits->upper;
        if (info.limit) ix.failAttribute(info.limit, "lower", s.str());
        ix.fail(info.element, s.str());
      }
    }
    // The body this joint moves: from its child link up to the next moving joint.
    const bool last = std::none_of(path.begin() + static_cast<std::ptrdiff_t>(k) + 1, path.end(),
                                   [&](const std::string& n) { return isMoving(ix.joints.at(n).type); });
    double mass = 0;
    Eigen::Vector3d moment = Eigen::Vector3d::Zero();
    body(info.child, Eigen::Isometry3d::Identity(), last, jn, mass, moment);
    cj.mass_kg = mass;
    cj.com_mm = mass > 0 ? Eigen::Vector3d(moment / mass) : Eigen::Vector3d::Zero();
    chain.joints.push_back(cj);
    T_acc.setIdentity();
  }
  chain.T_last_tip = T_acc;
  if (chain.joints.empty())
    ix.fail(ix.link_element.at(tip), "chain " + root + ":" + tip + ": expected at least one moving joint, found none");
  return chain;
}

SerialChain readUrdfChain(const std::string& path, const std::string& chain_spec) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, 0, "expected a URDF file, cannot open it");
  std::ostringstream s;
  s << in.rdbuf();
  return parseUrdfChain(s.str(), path, chain_spec);
}

RobotModel readUrdfRobot(const std::string& path, const std::string& chain_spec) {
  return modelFromChain(readUrdfChain(path, chain_spec));
}

}  // namespace accura::calib
