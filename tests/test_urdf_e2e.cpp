// URDFs of industrial arms as their ROS-Industrial support packages describe them, checked
// against FK written out by hand from the URDF's joint origins (independent of the URDF and DH
// code).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "accura/calib/ik.h"
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

// FANUC's and Yaskawa's URDFs turn J3's axis against J2's (`0 -1 0` after `0 1 0`). Read with z
// along each axis, alpha2 came out -180 deg, and the closed-form IK (which needs parallel axes
// 2 and 3, alpha2 = 0) was not found: every cold solve fell back to multi-start Newton. z3 now
// follows z2 with the joint turning the other way (direction -1): the same arm (its FK the
// URDF's, written out by hand), alpha2 = 0, the spherical-wrist closed form, whose solutions
// hold the joints the pose came from.
TEST(UrdfIndustrial, AJointTurnedAgainstThePreviousOneKeepsTheClosedForm) {
  const RobotModel m = readUrdfRobot(kData + "fanuc_m10ia_like.urdf");
  ASSERT_EQ(m.dof(), 6);
  EXPECT_NEAR(m.nominal.joints[1].alpha_deg, 0.0, 1e-9);
  EXPECT_EQ(m.nominal.joints[2].direction, -1);
  // joint_1 z 0.45 about z; joint_2 x 0.15 about y; joint_3 z 0.6 about -y; joint_4 z 0.2 about
  // -x; joint_5 x 0.64 about -y; joint_6 x 0.1 about -x. With q4 = q6 = 0 the arm lies in the
  // plane turned by q1, pitched (about y) by q2, q2 - q3, q2 - q3 - q5.
  for (const auto& q : {std::array<double, 4>{0, 0, 0, 0}, std::array<double, 4>{30, 20, -40, 60},
                        std::array<double, 4>{-100, -50, 80, -30}}) {
    const double r = kPiHere / 180, q1 = q[0] * r, q2 = q[1] * r, t = (q[1] - q[2]) * r, t2 = (q[1] - q[2] - q[3]) * r;
    const double x = 150 + 600 * std::sin(q2) + 200 * std::sin(t) + 640 * std::cos(t) + 100 * std::cos(t2);
    const double z = 450 + 600 * std::cos(q2) + 200 * std::cos(t) - 640 * std::sin(t) - 100 * std::sin(t2);
    Eigen::VectorXd qv(6);
    qv << q[0], q[1], q[2], 0, q[3], 0;
    const Eigen::Isometry3d T = forwardKinematics(m, qv);
    EXPECT_LT((T.translation() - Eigen::Vector3d(x * std::cos(q1), x * std::sin(q1), z)).norm(), 1e-9) << T.translation().transpose();
  }
  const KinematicSolver solver(m);
  EXPECT_STREQ(solver.closedForm(), "spherical_wrist");
  Eigen::VectorXd q(6);
  q << 30, 20, -40, 50, 60, 70;
  const Eigen::Isometry3d T = forwardKinematics(m, q);
  const std::vector<Eigen::VectorXd> sols = solver.closedFormSolutions(T);
  EXPECT_GE(sols.size(), 4u);
  bool found = false;
  for (const Eigen::VectorXd& s : sols) {
    const Eigen::Isometry3d Ts = forwardKinematics(m, s);
    EXPECT_LT((Ts.translation() - T.translation()).norm(), 1e-6) << s.transpose();
    EXPECT_LT((Ts.linear() - T.linear()).norm(), 1e-9) << s.transpose();
    found = found || (s - q).cwiseAbs().maxCoeff() < 1e-6;
  }
  EXPECT_TRUE(found) << "the joints the pose came from are one of the closed form's solutions";
}
