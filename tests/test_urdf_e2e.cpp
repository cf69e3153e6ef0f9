// URDFs of industrial arms as their ROS-Industrial support packages describe them, checked
// against FK written out by hand from the URDF's joint origins (independent of the URDF and DH
// code).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "accura/calib/kinematics.h"
#include "accura/calib/urdf.h"

using namespace accura::calib;

namespace {
const std::string kData = std::string(ACCURA_SOURCE_DIR) + "/tests/data/urdf/";
constexpr double kPiHere = 3.14159265358979323846;
}  // namespace

// ros-industrial/abb's IRB 6640 hangs its balancing cylinder off link_1 and the piston off
// link_2 on continuous joints that mimic joint_2 (visual only: the links have no inertial).
// MoveIt loads it; accura refused it ("branches off the chain base_link:tool0 at link 'link_1'").
// A branch without mass loads no joint, so the chain reads, and its FK is the URDF's.
TEST(UrdfIndustrial, MasslessMimicLinksOffTheArmAreNotABranch) {
  const RobotModel m = readUrdfRobot(kData + "irb6640_185_280.urdf");
  ASSERT_EQ(m.dof(), 6);
  for (const auto& j : m.nominal.joints) EXPECT_EQ(j.mass_kg, 0.0);
  // URDF: joint_1 z 0.78 about z; joint_2 x 0.32 about y; joint_3 z 1.075 about y; joint_4 z 0.2
  // about x; joint_5 x 1.392 about y; joint_6 x 0.2 about x; tool0 Ry(pi/2). Joints 4 and 6 at
  // zero, joint 5 about y too: the arm lies in the plane turned by q1, pitched by q2, q2+q3, q2+q3+q5.
  for (const auto& q : {std::array<double, 3>{0, 0, 0}, std::array<double, 3>{40, 30, -20}, std::array<double, 3>{-120, -50, 60}}) {
    const double q1 = q[0] * kPiHere / 180, q2 = q[1] * kPiHere / 180, q3 = q[2] * kPiHere / 180, q5 = 25 * kPiHere / 180;
    // in the arm's plane (x forward, z up); Ry(t) (x, 0, z) = (x cos t + z sin t, 0, -x sin t + z cos t)
    double x = 320 + 1075 * std::sin(q2), z = 780 + 1075 * std::cos(q2);
    x += 200 * std::sin(q2 + q3) + 1392 * std::cos(q2 + q3);
    z += 200 * std::cos(q2 + q3) - 1392 * std::sin(q2 + q3);
    x += 200 * std::cos(q2 + q3 + q5);
    z += -200 * std::sin(q2 + q3 + q5);
    const Eigen::Vector3d expected(x * std::cos(q1), x * std::sin(q1), z);
    Eigen::VectorXd qv(6);
    qv << q[0], q[1], q[2], 0, 25, 0;
    const Eigen::Isometry3d T = forwardKinematics(m, qv);
    EXPECT_LT((T.translation() - expected).norm(), 1e-9) << T.translation().transpose() << " vs " << expected.transpose();
    // tool0's z (Ry(pi/2) of link_6: link_6's x) points along the pitched forearm
    const Eigen::Vector3d z_expected(std::cos(q2 + q3 + q5) * std::cos(q1), std::cos(q2 + q3 + q5) * std::sin(q1), -std::sin(q2 + q3 + q5));
    EXPECT_LT((T.linear().col(2) - z_expected).norm(), 1e-10);  // the URDF writes pi/2 as 1.57079632679
  }
}
