// accura: complete model -> URDF (the calibrated geometry as joint origins), with the list of
// what URDF cannot hold, and the check that the text reads back to the same FK.
#include <cmath>
#include <cstdlib>
#include <map>
#include <cstdio>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/text.h"
#include "accura/calib/urdf.h"
#include "urdf_common.h"

namespace accura::calib {
namespace {

using urdf_detail::shortestNumber;
constexpr auto num = shortestNumber;

std::string origin(const Eigen::Isometry3d& T_mm) {
  const Eigen::Vector3d p = T_mm.translation() / 1000.0;
  const Eigen::Vector3d rpy = urdf_detail::urdfRpy(T_mm.linear());
  return "<origin xyz=\"" + num(p.x()) + " " + num(p.y()) + " " + num(p.z()) + "\" rpy=\"" + num(rpy.x()) + " " +
         num(rpy.y()) + " " + num(rpy.z()) + "\"/>";
}

constexpr auto constantPart = urdf_detail::calibratedLinkAtZero;

}  // namespace

UrdfText modelToUrdf(const RobotModel& model) {
  model.validate();
  const int n = model.dof();
  UrdfText out;

  // What URDF cannot hold.
  {
    out.not_represented = urdf_detail::effectsLeftOut(model, "URDF");
    // A URDF has no gravity: its root's z is up (REP-103). Say so when the model's is not.
    const Eigen::Vector3d g = model.nominal.gravity_base;
    const Eigen::Vector3d g_world = model.T_world_base().linear() * g;
    if ((g_world - Eigen::Vector3d(0, 0, -9.80665)).norm() > 1e-9)
      out.not_represented.push_back("gravity (" + num(g.x()) + ", " + num(g.y()) + ", " + num(g.z()) +
                                    ") m/s^2 in the base frame, not along -z of the URDF's root 'world' "
                                    "(a URDF has no gravity; ROS takes the root's z as up)");
    const Eigen::Vector3d c = model.nominal.payload_com_mm;
    if (c.norm() > 0)
      out.not_represented.push_back("payload centre of mass (" + num(c.x()) + ", " + num(c.y()) + ", " + num(c.z()) +
                                    ") mm in the flange frame (URDF has no payload)");
    out.not_represented.push_back(
        "inertia tensors: accura's model has link masses and centres of mass only; the tensors are written as 0");
    out.not_represented.push_back(
        "effort and velocity limits: not in accura's model; written as 0 (take them from the vendor's URDF)");
  }

  std::ostringstream x;
  x << "<?xml version=\"1.0\"?>\n<!--\n  Written by accura from the model '" << model.nominal.name
    << "': its calibrated geometry as joint origins\n  (world -> base_link = T_world_base, one joint per axis, "
       "flange = DH frame n, tool0 = T_flange_tcp).\n  Not represented in this URDF:\n";
  for (const std::string& s : out.not_represented) {
    std::string t = s;
    for (size_t pos; (pos = t.find("--")) != std::string::npos;) t.replace(pos, 2, "- -");
    x << "  - " << t << "\n";
  }
  x << "-->\n<robot name=\"" << xmlEscape(model.nominal.name) << "\">\n";
  x << "  <link name=\"world\"/>\n";
  x << "  <joint name=\"world-base_link\" type=\"fixed\">\n    <parent link=\"world\"/>\n    <child link=\"base_link\"/>\n    "
    << origin(model.T_world_base()) << "\n  </joint>\n";
  x << "  <link name=\"base_link\"/>\n";
  for (int i = 0; i < n; ++i) {
    const JointSpec& j = model.nominal.joints[static_cast<size_t>(i)];
    const bool revolute = j.type == JointType::kRevolute;
    const std::string parent = i == 0 ? "base_link" : "link_" + std::to_string(i);
    const std::string child = "link_" + std::to_string(i + 1);
    const Eigen::Isometry3d O = i == 0 ? Eigen::Isometry3d::Identity() : constantPart(model, i - 1);
    const double scale = revolute ? kDegToRad : 1e-3;
    x << "  <joint name=\"" << xmlEscape(j.name) << "\" type=\"" << (revolute ? "revolute" : "prismatic") << "\">\n"
      << "    <parent link=\"" << parent << "\"/>\n    <child link=\"" << child << "\"/>\n    " << origin(O) << "\n"
      << "    <axis xyz=\"0 0 " << j.direction << "\"/>\n"
      << "    <limit lower=\"" << num(j.lower * scale) << "\" upper=\"" << num(j.upper * scale)
      << "\" effort=\"0\" velocity=\"0\"/>\n  </joint>\n";
    x << "  <link name=\"" << child << "\"";
    if (j.mass_kg > 0) {
      // DH frame i+1 = this link's frame * constantPart(i): the COM in the link frame.
      const Eigen::Vector3d com = constantPart(model, i) * j.com_mm / 1000.0;
      x << ">\n    <inertial>\n      <origin xyz=\"" << num(com.x()) << " " << num(com.y()) << " " << num(com.z())
        << "\" rpy=\"0 0 0\"/>\n      <mass value=\"" << num(j.mass_kg)
        << "\"/>\n      <inertia ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"/>\n    </inertial>\n  </link>\n";
    } else {
      x << "/>\n";
    }
  }
  x << "  <joint name=\"link_" << n << "-flange\" type=\"fixed\">\n    <parent link=\"link_" << n
    << "\"/>\n    <child link=\"flange\"/>\n    " << origin(constantPart(model, n - 1)) << "\n  </joint>\n";
  x << "  <link name=\"flange\"/>\n";
  x << "  <joint name=\"flange-tool0\" type=\"fixed\">\n    <parent link=\"flange\"/>\n    <child link=\"tool0\"/>\n    "
    << origin(model.T_flange_tcp()) << "\n  </joint>\n";
  x << "  <link name=\"tool0\"/>\n</robot>\n";
  out.text = x.str();

  // Check: the text's own chain against the model's geometry (the effects URDF cannot hold
  // set to zero).
  const RobotModel geometric = urdf_detail::geometricPart(model);
  const SerialChain chain = parseUrdfChain(out.text, "<URDF written for '" + model.nominal.name + "'>", "world:tool0");
  const ChainComparison c = compareModelWithChain(geometric, chain);
  if (!(c.max_position_mm <= kChainCheckTolMm) || !(c.max_rotation_rad <= kChainCheckTolRad)) {
    std::ostringstream s;
    s << "URDF export of '" << model.nominal.name << "': the written chain differs from the model by "
      << c.max_position_mm << " mm / " << c.max_rotation_rad << " rad";
    throw NumericalError(s.str());
  }
  return out;
}

}  // namespace accura::calib
