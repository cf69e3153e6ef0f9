// accura post-processor: where the robot stands and which models the controller and the real
// robot are, written once for the job (job.h), the checks (check.h), batch (batch.h) and the
// plug-in. Frames as in job.h:
//   T_world_tcp = T_world_robroot * inverse($ROBROOT) * $BASE * target.
#pragma once

#include <map>
#include <memory>
#include <string>

#include "accura/calib/kinematics.h"
#include "accura/calib/robot.h"
#include "accura/postproc/cell.h"
#include "accura/postproc/compensate.h"
#include "accura/postproc/job.h"

namespace accura::postproc {

/// The robot's placement for a job.
struct Placement {
  /// Where the OLP placed the robot in the model's world: job.robroot_in_world, else the
  /// robot file's <base> (calibrated.nominal.T_world_base).
  Eigen::Isometry3d T_world_robroot = Eigen::Isometry3d::Identity();
  /// The controller's $WORLD in the world: T_world_robroot * inverse($ROBROOT).
  Eigen::Isometry3d T_world_kworld = Eigen::Isometry3d::Identity();
  /// The calibrated model's base in the world.
  Eigen::Isometry3d T_world_calbase = Eigen::Isometry3d::Identity();
};

/// The placement of `job`. Throws InputError when the calibrated base is farther than
/// job.max_base_offset_mm (mm) or job.max_base_offset_deg (deg) from T_world_robroot: the
/// model was measured in another frame (a tracker's). The message gives both bases and says
/// to give `placement_setting`, how the caller names where the robot stands ("--base
/// x,y,z,A,B,C", "robroot_in_world").
Placement placeRobot(const JobSettings& job, const std::string& placement_setting = "--base x,y,z,A,B,C");

/// The job for a program in `cell`: the cell's robot placement (<robot>) becomes
/// job.robroot_in_world when that is not set (it is where the OLP placed the robot). Throws
/// InputError (at the cell's <robot>) when both are set and differ by more than 1e-3 mm or
/// 1e-3 deg.
JobSettings placedInCell(const JobSettings& job, const Cell& cell);

/// The robot a controller runs (a robot file read from `path`) must be the calibrated model's
/// nominal robot: the same joint count, types, DH geometry, directions and limits (within
/// 1e-9 mm / deg). Throws InputError (naming `path` and what differs) otherwise.
void checkControllerRobot(const calib::RobotDefinition& calibrated, const calib::RobotDefinition& controller, const std::string& path);

/// The models of one program tool: the controller (nominal kinematics at the placement with
/// the tool) and the real robot (realModelForTool).
struct ToolModels {
  Eigen::Isometry3d T_flange_tcp = Eigen::Isometry3d::Identity();
  calib::RobotModel controller;
  calib::RobotModel real;
  bool calibrated_tool = false;  ///< real uses the calibrated tool (job.h, "real")
  /// The compensation with these two models (built on first use by ModelFactory::compensator).
  std::unique_ptr<Compensator> compensator;
  /// For the checks (check.cpp): the IK of the model that defines the path, with widened
  /// joint limits (built on first use there).
  std::unique_ptr<calib::KinematicSolver> check_ik;
};

/// The one controller-model factory with its tool-keyed cache: the job, the checks, batch (per
/// program) and the plug-in ask it for the models of a tool. Not thread-safe (one per job or
/// per thread); what it returns lives as long as the factory.
class ModelFactory {
 public:
  /// The models of `job` placed at `placement` (both copied).
  ModelFactory(const JobSettings& job, const Placement& placement);
  /// Given models: `real` (its tool rule as realModelForTool with the match tolerances of
  /// JobSettings) and `controller` (its base is the placement; its tool is replaced).
  ModelFactory(const calib::RobotModel& real, const calib::RobotModel& controller);

  const Placement& placement() const { return placement_; }
  /// The controller's nominal model at the placement with the flange as TCP (axis targets).
  const calib::RobotModel& controllerFlange() const { return controller_flange_; }
  /// The models for the tool T_flange_tcp (cached by its exact value).
  ToolModels& forTool(const Eigen::Isometry3d& T_flange_tcp);
  /// forTool(T_flange_tcp) with its Compensator.
  ToolModels& compensator(const Eigen::Isometry3d& T_flange_tcp);

 private:
  calib::RobotModel calibrated_;
  double tool_match_mm_ = 0, tool_match_deg_ = 0;
  Placement placement_;
  calib::RobotModel controller_flange_;
  std::map<std::string, ToolModels> cache_;
};

}  // namespace accura::postproc
