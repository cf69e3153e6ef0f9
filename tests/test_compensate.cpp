// Discrete compensation and auxiliary points (postproc/src/compensate.cpp): the defining
// properties of method.md section 4 checked with calib's FK, the controller's own IK, the
// path geometry, and the densification (tolerance met, adaptive, the sampling bound holds).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/text.h"
#include "accura/calib/simulate.h"
#include "accura/postproc/compensate.h"
#include "accura/postproc/placement.h"
#include "test_util.h"

namespace accura {
namespace {

using namespace postproc;

Eigen::Isometry3d pose(double x, double y, double z, double a, double b, double c) {
  return calib::toIsometry({x, y, z, a, b, c});
}

/// The controller: the nominal KR 16 with the program's tool. The real robot: every
/// geometric error, joint compliance (simulate.h, error scale 1) and a base registered to
/// 0.5 mm.
struct Cell {
  calib::RobotModel controller, real;
  explicit Cell(std::uint64_t seed = 1) {
    controller = test::loadBundled("kuka_kr16");
    controller.nominal.T_flange_tcp = calib::toIsometry({20, 0, 250, 0, -30, 0});
    calib::SimulateOptions o;
    o.effects = {"geometric", "joint_compliance"};
    o.set_station = false;
    o.seed = seed;
    real = calib::perturbModel(controller, o);
    real.deviations.base_mm = Eigen::Vector3d(0.4, -0.3, 0.2);
    real.deviations.base_rot_rad = Eigen::Vector3d(1e-4, -5e-5, 2e-4);
  }
};

double positionError(const calib::RobotModel& m, const Eigen::VectorXd& q, const Eigen::Isometry3d& T) {
  calib::KinematicWorkspace ws;
  return (calib::forwardKinematics(m, q, calib::PoseContext{}, ws).translation() - T.translation()).norm();
}

double rotationError(const calib::RobotModel& m, const Eigen::VectorXd& q, const Eigen::Isometry3d& T) {
  calib::KinematicWorkspace ws;
  return calib::logSO3(calib::forwardKinematics(m, q, calib::PoseContext{}, ws).linear() * T.linear().transpose()).norm();
}

// ---------------------------------------------------------------------------------------
// Discrete compensation

TEST(CompensatePose, RealRobotLandsOnTheTargetAndTheControllerReturnsQ) {
  const Cell cell;
  const Compensator comp(cell.controller, cell.real);
  const calib::KinematicSolver controller(cell.controller);
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(0.1, 0.9);
  int checked = 0;
  double sum_correction = 0;
  for (int k = 0; k < 200; ++k) {
    Eigen::VectorXd q(6);
    for (int i = 0; i < 6; ++i) {
      const calib::JointSpec& j = cell.controller.nominal.joints[static_cast<size_t>(i)];
      q[i] = j.lower + u(rng) * (j.upper - j.lower);
    }
    // a target the OLP computed with the nominal model, with its S and T
    const Eigen::Isometry3d desired = controller.forward(q);
    const calib::Configuration config = calib::kukaConfiguration(cell.controller, q);
    const PoseCompensation r = comp.pose(desired, config, Eigen::VectorXd(), calib::IkOptions{});
    if (r.status == calib::IkStatus::kSingular) continue;  // (a near-singular target)
    ASSERT_EQ(r.status, calib::IkStatus::kOk) << r.message;
    ++checked;
    // the real robot at q' is on the desired pose (calib's FK, not the solver's)
    EXPECT_LE(positionError(cell.real, r.q_real, desired), 1e-3);
    EXPECT_LE(rotationError(cell.real, r.q_real, desired), 1e-6);
    // the command is the controller's FK at q'
    EXPECT_LE(positionError(cell.controller, r.q_real, r.T_world_tcp_command), 1e-9);
    EXPECT_LE(rotationError(cell.controller, r.q_real, r.T_world_tcp_command), 1e-12);
    // and the controller's own IK of the command, on the configuration written with it,
    // returns q' (cold: the controller knows nothing else)
    const calib::IkResult back = controller.inverse(r.T_world_tcp_command, r.configuration, Eigen::VectorXd(), calib::IkOptions{});
    ASSERT_EQ(back.status, calib::IkStatus::kOk) << back.message;
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(back.q[i], r.q_real[i], 1e-4);
    if (!r.configuration_changed) {
      EXPECT_TRUE(calib::configurationMatches(config, r.configuration));
    }
    // about a millimetre of correction, the size of the model's error
    EXPECT_GT(r.correction_mm, 0.05);
    EXPECT_LT(r.correction_mm, 10);
    EXPECT_NEAR(r.correction_mm, (r.T_world_tcp_command.translation() - desired.translation()).norm(), 1e-12);
    sum_correction += r.correction_mm;
    // without compensation the real robot misses: the controller's joints for the desired
    // pose put the real tool elsewhere by about the correction
    const calib::IkResult plain = controller.inverse(desired, config, Eigen::VectorXd(), calib::IkOptions{});
    ASSERT_EQ(plain.status, calib::IkStatus::kOk);
    EXPECT_NEAR(positionError(cell.real, plain.q, desired), r.correction_mm, 0.5 * r.correction_mm + 0.05);
  }
  EXPECT_GT(checked, 190);
  EXPECT_GT(sum_correction / checked, 0.3);
}

TEST(CompensatePose, FreeFunctionEqualsCompensator) {
  const Cell cell;
  Eigen::VectorXd q(6);
  q << 10, -70, 80, 20, 50, 30;
  const Eigen::Isometry3d desired = calib::KinematicSolver(cell.controller).forward(q);
  const calib::Configuration c = calib::kukaConfiguration(cell.controller, q);
  const PoseCompensation a = compensatePose(cell.controller, cell.real, desired, c, Eigen::VectorXd(), calib::IkOptions{});
  const PoseCompensation b = Compensator(cell.controller, cell.real).pose(desired, c, Eigen::VectorXd(), calib::IkOptions{});
  ASSERT_EQ(a.status, calib::IkStatus::kOk);
  EXPECT_EQ((a.q_real - b.q_real).norm(), 0.0);
  EXPECT_TRUE(a.T_world_tcp_command.isApprox(b.T_world_tcp_command, 0));
}

TEST(CompensatePose, ConfigurationChangeIsReported) {
  // A1 just above 0 on the nominal robot: Turn bit 0 clear. The real robot needs A1 a few
  // hundredths of a degree away; on one side of 0 the compensated A1 has the other sign.
  const Cell cell;
  const Compensator comp(cell.controller, cell.real);
  int changed = 0, kept = 0;
  for (const double a1 : {0.002, -0.002}) {
    Eigen::VectorXd q(6);
    q << a1, -70, 80, 20, 50, 30;
    const Eigen::Isometry3d desired = comp.controller().forward(q);
    const calib::Configuration c = calib::kukaConfiguration(cell.controller, q);
    const PoseCompensation r = comp.pose(desired, c, Eigen::VectorXd(), calib::IkOptions{});
    ASSERT_EQ(r.status, calib::IkStatus::kOk) << r.message;
    EXPECT_LE(positionError(cell.real, r.q_real, desired), 1e-3);
    EXPECT_EQ(r.configuration, calib::kukaConfiguration(cell.real, r.q_real));
    if (r.configuration_changed) {
      ++changed;
      EXPECT_NE(r.configuration.turn & 1, c.turn & 1);
      EXPECT_FALSE(r.message.empty());
    } else {
      ++kept;
      EXPECT_EQ(r.configuration, c);
    }
  }
  EXPECT_EQ(changed, 1);
  EXPECT_EQ(kept, 1);
}

TEST(CompensatePose, UnreachableIsReportedWithoutACommand) {
  const Cell cell;
  const PoseCompensation r = compensatePose(cell.controller, cell.real, pose(4000, 0, 500, 0, 90, 0), calib::Configuration{},
                                            Eigen::VectorXd(), calib::IkOptions{});
  EXPECT_EQ(r.status, calib::IkStatus::kUnreachable);
  EXPECT_EQ(r.q_real.size(), 0);
  EXPECT_FALSE(r.message.empty());
  EXPECT_THROW(Compensator(cell.controller, test::loadBundled("scara")), calib::ArgumentError);
}

// ---------------------------------------------------------------------------------------
// Path geometry

TEST(PathGeometry, CircThroughThreePoints) {
  // a circle of radius 100 about (1000, 0, 500) in a tilted plane
  const Eigen::Vector3d c(1000, 0, 500);
  const Eigen::Vector3d e1 = Eigen::Vector3d(1, 0, 1).normalized(), e2(0, 1, 0);
  auto at = [&](double deg) { return Eigen::Vector3d(c + 100 * (std::cos(deg * calib::kDegToRad) * e1 + std::sin(deg * calib::kDegToRad) * e2)); };
  PathSegment s;
  s.type = PathType::kCirc;
  s.T_world_start = pose(0, 0, 0, 0, 90, 0);
  s.T_world_start.translation() = at(0);
  s.T_world_aux.translation() = at(100);
  s.T_world_end = pose(0, 0, 0, 40, 90, 0);
  s.T_world_end.translation() = at(200);
  EXPECT_NEAR(pathLength(s), 100 * 200 * calib::kDegToRad, 1e-9);
  EXPECT_NEAR(pathRotation(s), 40 * calib::kDegToRad, 1e-12);
  for (int k = 0; k <= 10; ++k) {
    const Eigen::Isometry3d T = interpolate(s, k / 10.0);
    EXPECT_LT((T.translation() - at(20.0 * k)).norm(), 1e-9);
    EXPECT_LT(distanceToPath(T.translation(), s), 1e-9);
  }
  EXPECT_TRUE(interpolate(s, 1).isApprox(s.T_world_end, 1e-12));
  // orientation: slerp, half way = A rotated by 20 deg
  EXPECT_LT(calib::logSO3(interpolate(s, 0.5).linear() * pose(0, 0, 0, 20, 90, 0).linear().transpose()).norm(), 1e-12);
  // distance: a point 3 above the plane and 4 outside the circle is 5 away; beyond the
  // ends of the arc the nearest point is an end (300 deg: the start, 60 deg away)
  const Eigen::Vector3d n = e1.cross(e2);
  EXPECT_NEAR(distanceToPath(c + 104 * (std::cos(1.0) * e1 + std::sin(1.0) * e2) + 3 * n, s), 5.0, 1e-9);
  EXPECT_NEAR(distanceToPath(at(300), s), (at(300) - at(0)).norm(), 1e-9);
  EXPECT_NEAR(distanceToPath(at(240), s), (at(240) - at(200)).norm(), 1e-9);
  // collinear points: no circle
  s.T_world_aux.translation() = 0.5 * (at(0) + at(200));
  EXPECT_THROW(interpolate(s, 0.5), calib::NumericalError);
}

TEST(PathGeometry, LinDistance) {
  PathSegment s;
  s.T_world_start = pose(0, 0, 0, 0, 0, 0);
  s.T_world_end = pose(100, 0, 0, 0, 0, 0);
  EXPECT_NEAR(distanceToPath(Eigen::Vector3d(50, 3, 4), s), 5, 1e-12);
  EXPECT_NEAR(distanceToPath(Eigen::Vector3d(-3, 4, 0), s), 5, 1e-12);
  EXPECT_NEAR(distanceToPath(Eigen::Vector3d(103, 0, 4), s), 5, 1e-12);
  EXPECT_NEAR(pathLength(s), 100, 1e-12);
  const std::vector<Eigen::Isometry3d> samples = {pose(10, 1, 0, 0, 0, 0), pose(20, 0, -2, 0, 0, 0)};
  EXPECT_NEAR(maxPathDeviation(samples, {s}), 2, 1e-12);
}

TEST(SimulatedExecution, ExactModelFollowsThePath) {
  // controller = real: the robot follows the commanded path exactly (checks the machinery)
  const Cell cell;
  PathSegment s;
  s.type = PathType::kCirc;
  s.T_world_start = pose(1100, -100, 600, 0, 180, 0);
  s.T_world_aux = pose(1200, 0, 650, 0, 180, 0);
  s.T_world_end = pose(1300, -100, 700, 30, 170, 0);
  const std::vector<Eigen::Isometry3d> path = simulateExecution(cell.controller, cell.controller, {s}, Eigen::VectorXd(), 1.0);
  EXPECT_GT(path.size(), static_cast<size_t>(pathLength(s)));
  EXPECT_LT(maxPathDeviation(path, {s}), 1e-4);
  EXPECT_LT((path.back().translation() - s.T_world_end.translation()).norm(), 1e-4);
}

// ---------------------------------------------------------------------------------------
// Auxiliary points

struct Densified {
  SegmentCompensation result;
  std::vector<Eigen::Isometry3d> executed;  ///< the real robot on the compensated path
};

Densified densify(const Compensator& comp, const PathSegment& s, const DensifyOptions& o, double step_mm) {
  Densified d;
  d.result = comp.segment(s, calib::Configuration{}, Eigen::VectorXd(), o);
  if (d.result.status == calib::IkStatus::kOk) d.executed = comp.execute(d.result.commanded, d.result.q_real_start, step_mm);
  return d;
}

TEST(Densify, ShortSegmentWithinToleranceGetsNoPoint) {
  const Cell cell;
  const Compensator comp(cell.controller, cell.real);
  PathSegment s;
  s.T_world_start = pose(1100, -250, 500, 0, 180, 0);
  s.T_world_end = pose(1100, -50, 500, 0, 180, 0);
  const Densified d = densify(comp, s, DensifyOptions{}, 0.2);
  ASSERT_EQ(d.result.status, calib::IkStatus::kOk) << d.result.message;
  EXPECT_LT(d.result.max_error_before_mm, 0.05);
  EXPECT_EQ(d.result.points_added, 0);
  EXPECT_EQ(d.result.max_error_after_mm, d.result.max_error_before_mm);
  EXPECT_GT(d.result.max_error_uncompensated_mm, 0.5);
  EXPECT_NEAR(maxPathDeviation(d.executed, {s}), d.result.max_error_after_mm, 2e-4);
}

TEST(Densify, LongMoveMeetsTheToleranceWithFewPoints) {
  const Cell cell;
  const Compensator comp(cell.controller, cell.real);
  PathSegment s;
  s.T_world_start = pose(900, -1100, 300, -30, 150, 10);
  s.T_world_end = pose(1000, 1000, 700, 40, 120, -20);
  DensifyOptions o;
  const Densified d = densify(comp, s, o, 0.1);
  const SegmentCompensation& r = d.result;
  ASSERT_EQ(r.status, calib::IkStatus::kOk) << r.message;
  EXPECT_GT(r.max_error_before_mm, o.tol_mm);
  EXPECT_GT(r.points_added, 0);
  EXPECT_LE(r.max_error_after_mm, o.tol_mm);
  EXPECT_LE(r.max_error_bound_mm, o.tol_mm);
  ASSERT_EQ(r.q_real_end.size(), r.commanded.size());
  EXPECT_EQ(r.points_added, static_cast<int>(r.commanded.size()) - 1);
  // the pieces are chained, and the last one ends on the compensated end pose
  for (size_t i = 0; i + 1 < r.commanded.size(); ++i)
    EXPECT_TRUE(r.commanded[i].T_world_end.isApprox(r.commanded[i + 1].T_world_start, 0));
  EXPECT_LE(positionError(cell.real, r.q_real_end.back(), s.T_world_end), 1e-3);
  EXPECT_LE(positionError(cell.controller, r.q_real_end.back(), r.commanded.back().T_world_end), 1e-9);
  // the sampling is fine enough: ten times finer (0.1 mm against the 1 mm of the
  // prediction) the real path stays within the bound (plus the IK's 1e-5 mm)
  const double executed = maxPathDeviation(d.executed, {s});
  EXPECT_LE(executed, r.max_error_bound_mm + 1e-4);
  EXPECT_GE(executed, r.max_error_after_mm - 1e-4);
  // adaptive, close to the fewest points: merging any two neighbouring pieces breaks the
  // tolerance (the greedy pieces are each as long as the tolerance allows)
  for (size_t i = 0; i + 1 < r.commanded.size(); ++i) {
    PathSegment merged = r.commanded[i];
    merged.T_world_end = r.commanded[i + 1].T_world_end;
    const Eigen::VectorXd q0 = i == 0 ? r.q_real_start : r.q_real_end[i - 1];
    const double e = maxPathDeviation(comp.execute({merged}, q0, 1.0), {s});
    EXPECT_GT(e, o.tol_mm) << "pieces " << i << " and " << i + 1;
  }
  // a tighter tolerance needs more points; the error scales with the square of the piece
  // length, so halving the tolerance needs about sqrt(2) times the pieces
  DensifyOptions tight = o;
  tight.tol_mm = 0.025;
  const SegmentCompensation rt = comp.segment(s, calib::Configuration{}, Eigen::VectorXd(), tight);
  ASSERT_EQ(rt.status, calib::IkStatus::kOk);
  EXPECT_LE(rt.max_error_after_mm, 0.025);
  EXPECT_GT(rt.commanded.size(), r.commanded.size());
  EXPECT_LE(rt.commanded.size(), 2 * r.commanded.size() + 1);
}

TEST(Densify, CircBecomesShorterCircs) {
  const Cell cell;
  const Compensator comp(cell.controller, cell.real);
  PathSegment s;
  s.type = PathType::kCirc;
  s.T_world_start = pose(1000, -300, 500, 0, 180, 0);
  s.T_world_aux = pose(1250, -50, 550, 0, 180, 0);
  s.T_world_end = pose(1000, 200, 600, 20, 170, 0);
  DensifyOptions o;
  o.tol_mm = 0.02;
  const Densified d = densify(comp, s, o, 0.1);
  const SegmentCompensation& r = d.result;
  ASSERT_EQ(r.status, calib::IkStatus::kOk) << r.message;
  EXPECT_GT(r.points_added, 0);
  EXPECT_GT(r.max_error_before_mm, o.tol_mm);
  for (const PathSegment& p : r.commanded) EXPECT_EQ(p.type, PathType::kCirc);
  EXPECT_LE(r.max_error_after_mm, o.tol_mm);
  EXPECT_LE(maxPathDeviation(d.executed, {s}), r.max_error_bound_mm + 1e-4);
  EXPECT_GT(r.max_error_uncompensated_mm, 0.5);
  // each commanded aux point is the compensated middle of its piece: the real robot at the
  // controller's joints for it is on the intended circle
  for (const PathSegment& p : r.commanded) {
    const calib::IkResult q = comp.controller().inverse(p.T_world_aux, calib::Configuration{}, r.q_real_start, calib::IkOptions{});
    ASSERT_EQ(q.status, calib::IkStatus::kOk);
    EXPECT_LT(distanceToPath(comp.real().forward(q.q).translation(), s), 1e-3);
  }
}

TEST(Densify, BadOptionsAndDegenerateCircThrow) {
  const Cell cell;
  const Compensator comp(cell.controller, cell.real);
  PathSegment s;
  s.T_world_start = pose(1100, -250, 500, 0, 180, 0);
  s.T_world_end = pose(1100, -50, 500, 0, 180, 0);
  DensifyOptions o;
  o.tol_mm = 0;
  EXPECT_THROW(comp.segment(s, calib::Configuration{}, Eigen::VectorXd(), o), calib::ArgumentError);
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("tolerance"), std::string::npos);
  s.type = PathType::kCirc;
  s.T_world_aux = pose(1100, -150, 500, 0, 180, 0);  // on the line
  EXPECT_THROW(comp.segment(s, calib::Configuration{}, Eigen::VectorXd(), DensifyOptions{}), calib::NumericalError);
}

TEST(Densify, UnreachablePathIsReported) {
  const Cell cell;
  const Compensator comp(cell.controller, cell.real);
  PathSegment s;
  s.T_world_start = pose(1100, -250, 500, 0, 180, 0);
  s.T_world_end = pose(3500, -50, 500, 0, 180, 0);
  const SegmentCompensation r = comp.segment(s, calib::Configuration{}, Eigen::VectorXd(), DensifyOptions{});
  EXPECT_NE(r.status, calib::IkStatus::kOk);
  EXPECT_TRUE(r.commanded.empty());
  EXPECT_FALSE(r.message.empty());
}

// A placement that was given (--base) and misses the calibrated base by metres is named as the
// user's value, with its units, not answered with "give --base" (which they did): here the
// tracker-frame base 2400,-1700,-600 mm given in metres.
TEST(Placement, AGivenPlacementThatMissesTheCalibratedBaseIsNamedWithItsUnits) {
  JobSettings job;
  job.calibrated = test::loadBundled("kuka_kr16");  // nominal base: the identity
  job.calibrated.deviations.base_mm = Eigen::Vector3d(2400, -1700, -600);
  job.robroot_in_world = calib::XyzAbc{2.4, -1.7, -0.6, 0, 0, 0};
  std::string message;
  try {
    placeRobot(job);
  } catch (const calib::InputError& e) {
    message = e.what();
  }
  const double off = std::sqrt(2397.6 * 2397.6 + 1698.3 * 1698.3 + 599.4 * 599.4);  // 3000.4 mm
  EXPECT_NE(message.find("is " + calib::formatFixed(off, 4) + " mm and 0.00000 deg from the placement given (2.4000, -1.7000, -0.6000 mm"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("The placement given (--base x,y,z,A,B,C) is not where the model's base was measured: "
                         "give it in the model's frame (the calibrated base above), x,y,z in mm and A,B,C in deg (not metres, not radians)"),
            std::string::npos)
      << message;
  EXPECT_EQ(message.find("give --base"), std::string::npos) << message;
  // without a placement the message asks for one, as before
  job.robroot_in_world.reset();
  message.clear();
  try {
    placeRobot(job);
  } catch (const calib::InputError& e) {
    message = e.what();
  }
  EXPECT_NE(message.find("The model was measured in another frame (a tracker's): give --base x,y,z,A,B,C, where the robot stands"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("deg from the nominal base (0.0000, 0.0000, 0.0000 mm"), std::string::npos) << message;
}

}  // namespace
}  // namespace accura
