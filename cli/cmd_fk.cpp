#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/json_text.h"
#include "accura/calib/identify.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/measurements.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"
#include "cli_util.h"
#include "commands.h"

namespace accura::cli {
namespace {
using nlohmann::ordered_json;

int runFk(const FkArgs& a) {
  const calib::RobotModel model = loadRobot(a.robot);
  const std::vector<double> q = parseNumbers(a.q, "--q", NumberRange{-1e5, 1e5, false, "deg; mm for prismatic joints"});
  if (static_cast<int>(q.size()) != model.dof())
    throw calib::InputError("--q: expected " + std::to_string(model.dof()) + " joint values for " +
                     model.nominal.name + ", found " + std::to_string(q.size()));
  Eigen::VectorXd qv = Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size()));
  for (int i = 0; i < model.dof(); ++i) {
    const calib::JointSpec& j = model.nominal.joints[i];
    // the measurement readers' slack (a URDF's limit in radians is rounded: 6.283 rad is 359.98938 deg)
    if (!calib::withinJointLimits(j, qv[i]))
      throw calib::InputError("--q: joint " + std::to_string(i + 1) + " (" + j.name + "): expected a value within [" +
                       fmt("%.10g", j.lower) + ", " + fmt("%.10g", j.upper) + "], found " + fmt("%.10g", qv[i]) + calib::jointTurnNote(j, qv[i]));
  }
  if (!(a.payload_kg >= 0)) throw calib::InputError("--payload-kg: expected a mass >= 0");
  calib::KinematicWorkspace ws;
  calib::PoseContext ctx;
  ctx.payload_kg = a.payload_kg;
  const calib::XyzAbc p = calib::toXyzAbc(calib::forwardKinematics(model, qv, ctx, ws));
  // T_world_tcp in the robot file's world frame: mm and deg (KUKA's A, B, C: Z-Y'-X'')
  std::printf("x=%s y=%s z=%s mm  A=%s B=%s C=%s deg\n", calib::formatFixed(p.x_mm, 4).c_str(), calib::formatFixed(p.y_mm, 4).c_str(),
              calib::formatFixed(p.z_mm, 4).c_str(), calib::formatFixed(p.a_deg, 5).c_str(), calib::formatFixed(p.b_deg, 5).c_str(),
              calib::formatFixed(p.c_deg, 5).c_str());
  if (!a.json.empty()) {
    ordered_json j;
    j["robot"] = model.nominal.name;
    j["q"] = q;
    j["payload_kg"] = a.payload_kg;
    j["T_world_tcp"] = {{"x_mm", num(p.x_mm)}, {"y_mm", num(p.y_mm)}, {"z_mm", num(p.z_mm)},
                        {"a_deg", num(p.a_deg)}, {"b_deg", num(p.b_deg)}, {"c_deg", num(p.c_deg)}};
    writeTextAtomically(a.json, calib::jsonText(j));
  }
  return 0;
}

}  // namespace

void addFkCommand(CLI::App& app) {
  auto fk = std::make_shared<FkArgs>();
  auto* cfk = app.add_subcommand("fk", "print the tool pose at joint values (x,y,z mm; A,B,C deg)");
  cfk->add_option("--robot", fk->robot, "robot file or bundled robot name")->required();
  cfk->add_option("--q", fk->q, "joint values v1,...,vN (deg; mm for prismatic joints)")->required();
  addNumberOption(cfk, "--payload-kg", fk->payload_kg, "payload mass (kg), for compliance models", kPayloadRange);
  cfk->add_option("--json", fk->json, "also write the pose as JSON (T_world_tcp: x_mm ... c_deg)");
  cfk->callback([=]() { exitCode() = runFk(*fk); });
}

}  // namespace accura::cli
