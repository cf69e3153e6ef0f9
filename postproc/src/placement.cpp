// The robot's placement and the models of a job (see placement.h).
#include "accura/postproc/placement.h"

#include <cmath>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"

namespace accura::postproc {
namespace {

std::string poseText(const calib::XyzAbc& p, const char* sep) {
  return formatMm(p.x_mm) + sep + formatMm(p.y_mm) + sep + formatMm(p.z_mm);
}

std::string anglesText(const calib::XyzAbc& p) { return formatDeg(p.a_deg) + ", " + formatDeg(p.b_deg) + ", " + formatDeg(p.c_deg); }

std::string placementText(const calib::XyzAbc& p) {
  return calib::formatFixed(p.x_mm, 3) + "," + calib::formatFixed(p.y_mm, 3) + "," + calib::formatFixed(p.z_mm, 3) + "," + calib::formatFixed(p.a_deg, 3) + "," +
         calib::formatFixed(p.b_deg, 3) + "," + calib::formatFixed(p.c_deg, 3);
}

}  // namespace

Placement placeRobot(const JobSettings& job, const std::string& placement_setting) {
  Placement p;
  p.T_world_robroot = job.robroot_in_world ? calib::toIsometry(*job.robroot_in_world) : job.calibrated.nominal.T_world_base;
  const Eigen::Isometry3d T_kworld_robroot = job.robroot_in_kukaworld ? calib::toIsometry(*job.robroot_in_kukaworld) : Eigen::Isometry3d::Identity();
  p.T_world_kworld = p.T_world_robroot * T_kworld_robroot.inverse();
  p.T_world_calbase = job.calibrated.T_world_base();
  const Eigen::Isometry3d d = p.T_world_robroot.inverse() * p.T_world_calbase;
  const double off_mm = d.translation().norm(), off_deg = calib::rotationAngleDeg(d.linear());
  if (off_mm > job.max_base_offset_mm || off_deg > job.max_base_offset_deg) {
    const calib::XyzAbc b = calib::toXyzAbc(p.T_world_robroot), c = calib::toXyzAbc(p.T_world_calbase);
    std::ostringstream m;
    m << "the calibrated base (" << poseText(c, ", ") << " mm, " << anglesText(c) << " deg) is " << formatMm(off_mm) << " mm and "
      << formatDeg(off_deg) << " deg from " << (job.robroot_in_world ? "the placement given (" : "the nominal base (") << poseText(b, ", ")
      << " mm, " << anglesText(b) << " deg): expected at most " << job.max_base_offset_mm << " mm and " << job.max_base_offset_deg
      << " deg. ";
    // A placement that was given and still misses is most often in other units (metres, radians)
    // or in another frame: telling the user to give it would not say what is wrong with it.
    if (job.robroot_in_world)
      m << "The placement given (" << placement_setting << ") is not where the model's base was "
        << "measured: give it in the model's frame (the calibrated base above), x,y,z in mm and A,B,C in deg (not metres, not radians)";
    else
      m << "The model was measured in another frame (a tracker's): give " << placement_setting
        << ", where the robot stands in that frame according to the cell layout";
    throw calib::InputError(m.str());
  }
  return p;
}

JobSettings placedInCell(const JobSettings& job, const Cell& cell) {
  JobSettings placed = job;
  if (!cell.T_world_base) return placed;
  if (!job.robroot_in_world) {
    placed.robroot_in_world = calib::toXyzAbc(*cell.T_world_base);
    return placed;
  }
  const Eigen::Isometry3d d = cell.T_world_base->inverse() * calib::toIsometry(*job.robroot_in_world);
  if (d.translation().norm() > 1e-3 || calib::rotationAngleDeg(d.linear()) > 1e-3)
    throw calib::InputError(cell.file, cell.robot_line, cell.robot_column,
                     "<robot>: the robot placement of the cell file differs from --base (" + placementText(calib::toXyzAbc(*cell.T_world_base)) +
                         " here, " + placementText(*job.robroot_in_world) + " given): expected the same placement, found two (give one of them)");
  return placed;
}

ModelFactory::ModelFactory(const JobSettings& job, const Placement& placement)
    : calibrated_(job.calibrated), tool_match_mm_(job.tool_match_mm), tool_match_deg_(job.tool_match_deg), placement_(placement) {
  if (job.controller_kinematics) {
    // the controller's own kinematics (a UR's factory calibration): its links, not its frames
    checkControllerRobot(job.calibrated.nominal, job.controller_kinematics->nominal, "the controller's kinematics");
    controller_flange_ = *job.controller_kinematics;
    calib::Deviations& d = controller_flange_.deviations;
    // a controller runs a geometric model: no load, temperature or joint-space effects
    if (d.hasEffectsBeyondGeometry())
      throw calib::InputError("the controller's kinematics ('" + job.controller_kinematics->nominal.name +
                              "'): expected a geometric model (what a controller runs: link deviations only), found compliance, "
                              "gear, scale, backlash, thermal or joint-map terms");
    d.base_mm.setZero();
    d.base_rot_rad.setZero();
    d.tool_mm.setZero();
    d.tool_rot_rad.setZero();
  } else {
    controller_flange_ = calib::RobotModel::fromDefinition(job.calibrated.nominal);
  }
  controller_flange_.nominal.T_world_base = placement.T_world_robroot;
  controller_flange_.nominal.T_flange_tcp = Eigen::Isometry3d::Identity();
}

ModelFactory::ModelFactory(const calib::RobotModel& real, const calib::RobotModel& controller)
    : calibrated_(real), tool_match_mm_(JobSettings{}.tool_match_mm), tool_match_deg_(JobSettings{}.tool_match_deg),
      controller_flange_(controller) {
  placement_.T_world_robroot = placement_.T_world_kworld = controller.nominal.T_world_base;
  placement_.T_world_calbase = real.T_world_base();
  controller_flange_.nominal.T_flange_tcp = Eigen::Isometry3d::Identity();
}

ToolModels& ModelFactory::forTool(const Eigen::Isometry3d& T_flange_tcp) {
  std::ostringstream key;
  key.precision(17);
  key << T_flange_tcp.matrix();
  auto it = cache_.find(key.str());
  if (it != cache_.end()) return it->second;
  ToolModels m;
  m.T_flange_tcp = T_flange_tcp;
  m.controller = controller_flange_;
  m.controller.nominal.T_flange_tcp = T_flange_tcp;
  m.real = realModelForTool(calibrated_, T_flange_tcp, tool_match_mm_, tool_match_deg_, &m.calibrated_tool);
  return cache_.emplace(key.str(), std::move(m)).first->second;
}

ToolModels& ModelFactory::compensator(const Eigen::Isometry3d& T_flange_tcp) {
  ToolModels& m = forTool(T_flange_tcp);
  if (!m.compensator) m.compensator = std::make_unique<Compensator>(m.controller, m.real);
  return m;
}

void checkControllerRobot(const calib::RobotDefinition& calibrated, const calib::RobotDefinition& controller, const std::string& path) {
  auto differ = [&](const std::string& what) {
    throw calib::InputError(path + ": expected the nominal robot of the calibrated model ('" + calibrated.name + "'), found '" +
                                 controller.name + "' with another " + what);
  };
  if (calibrated.dof() != controller.dof()) differ("joint count (" + std::to_string(controller.dof()) + ")");
  constexpr double kTol = 1e-9;  // mm and deg: the same numbers
  for (int i = 0; i < calibrated.dof(); ++i) {
    const calib::JointSpec &a = calibrated.joints[i], &b = controller.joints[i];
    const std::string j = "joint " + std::to_string(i + 1) + " ";
    if (a.type != b.type) differ(j + "type");
    if (std::fabs(a.a_mm - b.a_mm) > kTol || std::fabs(a.d_mm - b.d_mm) > kTol || std::fabs(a.alpha_deg - b.alpha_deg) > kTol ||
        std::fabs(a.theta0_deg - b.theta0_deg) > kTol)
      differ(j + "DH geometry");
    if (a.direction != b.direction) differ(j + "direction");
    if (std::fabs(a.lower - b.lower) > kTol || std::fabs(a.upper - b.upper) > kTol) differ(j + "limits");
  }
}

}  // namespace accura::postproc
