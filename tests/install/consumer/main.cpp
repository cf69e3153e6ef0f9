// A host of the installed accura: the KR 16's flange at q = (10,-80,70,20,30,40) deg through
// accura::calib, an XML program parsed through accura::postproc, the plug-in's version through
// accura::plugin. Prints "x y z" (mm) of the pose for the test to compare with the command.
#include <accura_plugin.h>

#include <cstdio>
#include <exception>

#include "accura/calib/geometry.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/robot_io.h"
#include "accura/postproc/program_io.h"

int main() {
  try {
    int abi = 0;
    if (accura_version(nullptr, nullptr, nullptr, &abi) != ACCURA_OK || abi != ACCURA_PLUGIN_ABI_VERSION) {
      std::fprintf(stderr, "consumer: plug-in ABI %d, expected %d\n", abi, ACCURA_PLUGIN_ABI_VERSION);
      return 1;
    }
    const auto model = accura::calib::readRobotFile(std::string(ROBOTS_DIR) + "/kuka_kr16.xml");
    Eigen::VectorXd q(6);
    q << 10, -80, 70, 20, 30, 40;
    const auto p = accura::calib::toXyzAbc(accura::calib::forwardKinematics(model, q));
    std::printf("x=%.4f y=%.4f z=%.4f mm  A=%.5f B=%.5f C=%.5f deg\n", p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg);  // as accura fk
    (void)accura::postproc::programFormat("p.xml");
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "consumer: %s\n", e.what());
    return 1;
  }
}
