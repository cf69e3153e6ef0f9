// Reach and clearance checks (check.h): the subdivision finds a contact that the samples of the
// path miss, a path that touches a fixture (library and command line), a point that the
// compensation pushes into the joint-limit margin (library, accura check and accura compensate
// --cell with and without --warn-only) and one it pushes beyond a joint limit, an unreachable
// target through check / compensate --cell / batch --cell, a LIN leaving the workspace, the
// wrist and elbow singularities on a path, a cell without robot geometry, and the singularity
// measure against finite differences.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/robot_io.h"
#include "accura/postproc/batch.h"
#include "accura/postproc/cell.h"
#include "accura/postproc/check.h"
#include "accura/postproc/compensate.h"
#include "accura/postproc/program_io.h"
#include "test_util.h"

namespace accura::postproc {
namespace {

std::string fixture(const std::string& name) { return test::sourcePath("tests/data/cell/" + name); }
calib::RobotModel kr16() { return test::loadBundled("kuka_kr16"); }

// Independent of the post-processor's IK: Newton's method on calib's forward kinematics with a
// central-difference Jacobian (joints in deg; orientation error weighted 1000 mm/rad).
// Returns the joint values that put the TCP at T (the residual is asserted by the callers).
Eigen::VectorXd newtonIk(const calib::RobotModel& robot, const Eigen::Isometry3d& T, Eigen::VectorXd q) {
  const auto error = [&](const Eigen::Isometry3d& F, const Eigen::Isometry3d& G) {
    Eigen::Matrix<double, 6, 1> e;
    e.head<3>() = G.translation() - F.translation();
    e.tail<3>() = 1000.0 * calib::logSO3(G.linear() * F.linear().transpose());
    return e;
  };
  for (int it = 0; it < 100; ++it) {
    const Eigen::Matrix<double, 6, 1> e = error(calib::forwardKinematics(robot, q), T);
    if (e.norm() < 1e-10) break;
    Eigen::MatrixXd J(6, q.size());
    const double h_deg = 1e-4;
    for (int i = 0; i < q.size(); ++i) {
      Eigen::VectorXd qp = q, qm = q;
      qp[i] += h_deg;
      qm[i] -= h_deg;
      J.col(i) = error(calib::forwardKinematics(robot, qm), calib::forwardKinematics(robot, qp)) / (2 * h_deg);
    }
    q += J.colPivHouseholderQr().solve(e);
  }
  return q;
}

double poseResidual(const calib::RobotModel& robot, const Eigen::VectorXd& q, const Eigen::Isometry3d& T) {
  const Eigen::Isometry3d F = calib::forwardKinematics(robot, q);
  return (F.translation() - T.translation()).norm() + 1000.0 * calib::logSO3(T.linear() * F.linear().transpose()).norm();
}

// sigma_min of docs/checks.md from a central-difference Jacobian of the forward kinematics:
// position rows / L (L = sum |a_i| + |d_i| + |tool offset|), columns per rad.
double fdSigma(const calib::RobotModel& robot, const Eigen::VectorXd& q) {
  double L = robot.nominal.T_flange_tcp.translation().norm();
  for (const auto& j : robot.nominal.joints) L += std::fabs(j.a_mm) + std::fabs(j.d_mm);
  Eigen::Matrix<double, 6, 6> J;
  const double h_deg = 1e-3;
  for (int i = 0; i < 6; ++i) {
    Eigen::VectorXd qp = q, qm = q;
    qp[i] += h_deg;
    qm[i] -= h_deg;
    const Eigen::Isometry3d Tp = calib::forwardKinematics(robot, qp), Tm = calib::forwardKinematics(robot, qm);
    const double h_rad = 2 * h_deg * calib::kDegToRad;
    J.block<3, 1>(0, i) = (Tp.translation() - Tm.translation()) / h_rad / L;
    J.block<3, 1>(3, i) = calib::logSO3(Tp.linear() * Tm.linear().transpose()) / h_rad;
  }
  return Eigen::JacobiSVD<Eigen::Matrix<double, 6, 6>>(J).singularValues()[5];
}

// The post of tests/data/cell/post_binary.stl (x, y in [-5, 5], z in [0, 600] mm) placed at
// (1200, y_post, 500): the clearance of a sphere of radius r centred at p.
double postClearance(const Eigen::Vector3d& p, double y_post, double r) {
  const Eigen::Vector3d lo(1195, y_post - 5, 500), hi(1205, y_post + 5, 1100);
  return std::max(0.0, (lo - p).cwiseMax(p - hi).cwiseMax(0.0).norm() - r);
}

Cell postCell(double y_post, double tool_radius_mm) {
  Cell cell;
  CellShape post;
  post.mesh = loadMesh(fixture("post_binary.stl"), 1.0);
  post.name = "post";
  post.T_parent_shape = calib::toIsometry(calib::XyzAbc{1200, y_post, 500, 0, 0, 0});
  cell.objects.push_back(post);
  CellShape tool;
  tool.capsule = Capsule{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), tool_radius_mm};
  tool.name = "tool";
  cell.tool_shapes.push_back(tool);
  return cell;
}

WorldMotion cartesian(MotionType type, const calib::XyzAbc& p, int line) {
  WorldMotion m;
  m.type = type;
  m.T_world_tcp_end = calib::toIsometry(p);
  m.where.line = line;
  m.label = type == MotionType::kLin ? "LIN" : "PTP";
  return m;
}

// The TCP moves along x at y = 0; the post's face is at y = 13: the sphere (r 10) passes it
// at 3 mm, closer than the 5 mm asked for, over x in (1187.5, 1212.5). With one sample at each
// end of the 600 mm path (both about 300 mm clear) sampling alone misses it; the subdivision
// finds it.
TEST(CheckClearance, SubdivisionFindsWhatTheSamplesMiss) {
  const calib::RobotModel robot = kr16();
  const double y_post = 18, radius = 10;
  const Cell cell = postCell(y_post, radius);
  CheckOptions o;
  o.thresholds.min_clearance_mm = 5;
  o.sample_step_mm = 1000;  // no pre-sampling: the two end points only
  o.sample_step_deg = 1000;
  o.max_joint_step_deg = 1000;
  const std::vector<WorldMotion> motions = {cartesian(MotionType::kPtp, {900, 0, 800, 0, 90, 0}, 1),
                                            cartesian(MotionType::kLin, {1500, 0, 800, 0, 90, 0}, 2)};
  // the samples a plain sampling would look at
  EXPECT_GT(postClearance({900, 0, 800}, y_post, radius), 250);
  EXPECT_GT(postClearance({1500, 0, 800}, y_post, radius), 250);

  const CheckReport r = checkMotions(robot, robot, cell, motions, o);
  ASSERT_EQ(r.violations.size(), 1u);
  const CheckViolation& v = r.violations[0];
  EXPECT_EQ(v.kind, CheckKind::kClearance);
  EXPECT_EQ(v.motion_index, 1);
  EXPECT_EQ(v.where.line, 2);
  EXPECT_TRUE(v.on_path);
  EXPECT_EQ(v.obstacle, "post");
  EXPECT_EQ(v.robot_part, "tool");
  // the reported distance is the analytic one at the reported TCP position
  EXPECT_NEAR(v.value, postClearance(v.p_world_tcp_mm, y_post, radius), 1e-3);
  EXPECT_LT(v.value, 5.0);
  EXPECT_NEAR(v.excess, 5.0 - v.value, 1e-12);
  EXPECT_NEAR(v.p_world_tcp_mm.y(), 0, 1e-3);
  EXPECT_NEAR(v.p_world_tcp_mm.z(), 800, 1e-3);
  EXPECT_NEAR(v.arc_mm, v.p_world_tcp_mm.x() - 900, 1e-3);
  // first: closer than 5 mm there, so past the analytic crossing of 5 mm at
  // x = 1200 - 5 - sqrt(15^2 - 13^2) = 1187.517; and everything before it is proven clear to
  // within the resolution (0.01 mm), so not past the crossing of 4.99 mm (x = 1187.543)
  const double x_cross = 1200 - 5 - std::sqrt(15.0 * 15.0 - 13.0 * 13.0);
  const double x_cross_res = 1200 - 5 - std::sqrt(std::pow(15.0 - o.resolution_mm, 2) - 13.0 * 13.0);
  EXPECT_GT(v.p_world_tcp_mm.x(), x_cross);
  EXPECT_LE(v.p_world_tcp_mm.x(), x_cross_res + 1e-6);
  ASSERT_EQ(v.q.size(), 6);
  EXPECT_GT(r.distance_queries, 10);
  EXPECT_FALSE(r.passed());
}

// A CIRC (horizontal circle of radius 200 mm about (1200, 0, 800) through (1200, 200, 800)) that
// passes the post 3 mm too close at its auxiliary point: the violation is on the circle, at the
// analytic distance, and the part of the arc before it is clear.
TEST(CheckClearance, CircPassesThePost) {
  const calib::RobotModel robot = kr16();
  const double y_post = 218, radius = 10;
  const Cell cell = postCell(y_post, radius);
  CheckOptions o;
  o.thresholds.min_clearance_mm = 5;
  WorldMotion circ = cartesian(MotionType::kCirc, {1400, 0, 800, 0, 90, 0}, 2);
  circ.T_world_tcp_aux = calib::toIsometry(calib::XyzAbc{1200, 200, 800, 0, 90, 0});
  circ.label = "CIRC";
  const CheckReport r = checkMotions(robot, robot, cell, {cartesian(MotionType::kPtp, {1000, 0, 800, 0, 90, 0}, 1), circ}, o);
  ASSERT_EQ(r.violations.size(), 1u);
  const CheckViolation& v = r.violations[0];
  EXPECT_EQ(v.kind, CheckKind::kClearance);
  EXPECT_NEAR((v.p_world_tcp_mm - Eigen::Vector3d(1200, 0, 800)).norm(), 200, 1e-3);
  EXPECT_NEAR(v.value, postClearance(v.p_world_tcp_mm, y_post, radius), 1e-3);
  EXPECT_LT(v.value, 5);
  // arc length from the start = 200 mm * the angle swept from (1000, 0)
  const double angle = std::atan2(v.p_world_tcp_mm.y(), 1200 - v.p_world_tcp_mm.x());
  EXPECT_NEAR(v.arc_mm, 200 * angle, 1e-2);
  EXPECT_NEAR(v.s, angle / calib::kPi, 1e-5);
  // before it the arc is clear: the analytic clearance at every 0.1 mm of arc before it
  for (double a = 0; a < angle - 1e-4; a += 0.1 / 200) {
    const Eigen::Vector3d p(1200 - 200 * std::cos(a), 200 * std::sin(a), 800);
    ASSERT_GE(postClearance(p, y_post, radius), 5 - o.resolution_mm) << a;
  }
}

// A PTP that turns A1 from -40 to 40 deg sweeps a sphere (radius 50 mm) on link 3 past a 100 mm
// cube placed 3 mm beyond the sphere's circle at A1 = 0: the link geometry and the joint-space
// path. The reported distance is the analytic sphere/cube distance at the reported joints, and
// the joint path before it is clear.
TEST(CheckClearance, PtpSweepsALinkPastACube) {
  const calib::RobotModel robot = kr16();
  Eigen::VectorXd qa(6), qb(6);
  qa << -40, -90, 90, 0, 45, 0;
  qb = qa;
  qb[0] = 40;
  calib::KinematicWorkspace ws;
  auto center = [&](const Eigen::VectorXd& q) {
    calib::forwardKinematics(robot, q, calib::PoseContext{}, ws);
    return Eigen::Vector3d(ws.T_base_frame[3].translation());
  };
  Eigen::VectorXd q0 = qa;
  q0[0] = 0;
  const Eigen::Vector3d c0 = center(q0);
  const Eigen::Vector3d radial = Eigen::Vector3d(c0.x(), c0.y(), 0).normalized();
  const Eigen::Vector3d cube = c0 + radial * (50 + 50 + 3);  // cube face 3 mm beyond the sphere
  Cell cell;
  CellShape box;
  box.mesh = loadMesh(fixture("box_100mm.stl"), 1.0);
  box.name = "cube";
  box.T_parent_shape = Eigen::Isometry3d::Identity();
  box.T_parent_shape.translation() = cube;
  box.T_parent_shape.linear() = Eigen::AngleAxisd(std::atan2(radial.y(), radial.x()), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  cell.objects.push_back(box);
  CellShape link;
  link.capsule = Capsule{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 50};
  link.name = "link 3";
  cell.link_shapes.emplace_back(3, link);
  auto clearance = [&](const Eigen::VectorXd& q) {
    const Eigen::Vector3d p = box.T_parent_shape.inverse() * center(q);
    return std::max(0.0, (p.cwiseAbs() - Eigen::Vector3d::Constant(50)).cwiseMax(0.0).norm() - 50);
  };
  EXPECT_NEAR(clearance(q0), 3.0, 1e-9);
  WorldMotion a, b;
  a.q_end = qa;
  b.q_end = qb;
  a.label = b.label = "PTP";
  b.where.line = 7;
  CheckOptions o;
  o.thresholds.min_clearance_mm = 5;
  o.thresholds.singular_threshold = 0;
  const CheckReport r = checkMotions(robot, robot, cell, {a, b}, o);
  ASSERT_EQ(r.violations.size(), 1u);
  const CheckViolation& v = r.violations[0];
  EXPECT_EQ(v.kind, CheckKind::kClearance);
  EXPECT_EQ(v.robot_part, "link 3");
  EXPECT_EQ(v.obstacle, "cube");
  EXPECT_EQ(v.where.line, 7);
  EXPECT_NEAR(v.value, clearance(v.q), 1e-6);
  EXPECT_LT(v.value, 5);
  EXPECT_NEAR(v.q[0], -40 + 80 * v.s, 1e-9);  // on the joint-space line
  for (double s = 0; s < v.s - 1e-9; s += 0.0005) ASSERT_GE(clearance(qa + s * (qb - qa)), 5 - o.resolution_mm) << s;
}

// The bounded distance queries (CheckOptions::exact_band_mm, docs/checks.md "Distance
// queries") change nothing but the cost: against every distance exact (band infinite), the
// default band (100 mm) and a band of 1 um (nearly every distance a lower bound, made exact on
// demand wherever a proof needs it) give the same violations, bit for bit, after the same
// samples (the same subdivision). The cell: the post (tilted) and a cube (turned), a tool
// sphere and a link-3 sphere; the motions: a LIN past the post, a CIRC around it and a PTP sweeping A1, with the
// default pre-sampling and with none (the subdivision alone).
TEST(CheckClearance, BoundedQueriesGiveTheViolationsOfExactOnes) {
  const calib::RobotModel robot = kr16();
  Cell cell = postCell(18, 10);
  // tilted: the bounding boxes are loose, so near the objects the bounds are far from exact
  cell.objects[0].T_parent_shape = calib::toIsometry(calib::XyzAbc{1200, 18, 500, 0, 20, 0});
  CellShape box;
  box.mesh = loadMesh(fixture("box_100mm.stl"), 1.0);
  box.name = "cube";
  box.T_parent_shape = calib::toIsometry(calib::XyzAbc{700, 700, 1200, 20, 45, 30});
  cell.objects.push_back(box);
  CellShape link;
  link.capsule = Capsule{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), 50};
  link.name = "link 3";
  cell.link_shapes.emplace_back(3, link);
  WorldMotion circ = cartesian(MotionType::kCirc, {900, 0, 800, 0, 90, 0}, 4);
  circ.T_world_tcp_aux = calib::toIsometry(calib::XyzAbc{1200, 300, 800, 0, 90, 0});
  circ.label = "CIRC";
  WorldMotion sweep;
  sweep.q_end = (Eigen::VectorXd(6) << 60, -90, 90, 0, 45, 0).finished();
  sweep.label = "PTP";
  sweep.where.line = 5;
  const std::vector<WorldMotion> motions = {cartesian(MotionType::kPtp, {900, 0, 800, 0, 90, 0}, 1),
                                            cartesian(MotionType::kLin, {1500, 0, 800, 0, 90, 0}, 2), circ, sweep};
  for (bool presample : {true, false}) {
    CheckOptions o;
    o.thresholds.min_clearance_mm = 5;
    o.thresholds.singular_threshold = 0;
    if (!presample) o.sample_step_mm = o.sample_step_deg = o.max_joint_step_deg = 1000;
    o.exact_band_mm = std::numeric_limits<double>::infinity();
    const CheckReport exact = checkMotions(robot, robot, cell, motions, o);
    ASSERT_GE(exact.violations.size(), 1u);
    EXPECT_EQ(exact.violations[0].kind, CheckKind::kClearance);
    for (double band : {100.0, 1e-3}) {
      o.exact_band_mm = band;
      const CheckReport r = checkMotions(robot, robot, cell, motions, o);
      SCOPED_TRACE("presample " + std::to_string(presample) + ", band " + std::to_string(band));
      EXPECT_EQ(r.samples, exact.samples);
      ASSERT_EQ(r.motions.size(), exact.motions.size());
      for (size_t m = 0; m < r.motions.size(); ++m) EXPECT_EQ(r.motions[m].samples, exact.motions[m].samples) << m;
      ASSERT_EQ(r.violations.size(), exact.violations.size());
      for (size_t k = 0; k < r.violations.size(); ++k) {
        const CheckViolation &a = r.violations[k], &b = exact.violations[k];
        EXPECT_EQ(a.kind, b.kind);
        EXPECT_EQ(a.motion_index, b.motion_index);
        EXPECT_EQ(a.s, b.s);
        EXPECT_EQ(a.arc_mm, b.arc_mm);
        EXPECT_EQ(a.p_world_tcp_mm, b.p_world_tcp_mm);
        EXPECT_EQ(a.q, b.q);
        EXPECT_EQ(a.value, b.value);
        EXPECT_EQ(a.excess, b.excess);
        EXPECT_EQ(a.robot_part, b.robot_part);
        EXPECT_EQ(a.obstacle, b.obstacle);
        EXPECT_EQ(a.message, b.message);
      }
      // per motion the smallest clearance is exact where it is below the band, else a lower bound
      for (size_t m = 0; m < r.motions.size(); ++m) {
        if (exact.motions[m].min_clearance_mm < 5 + band) {
          EXPECT_EQ(r.motions[m].min_clearance_mm, exact.motions[m].min_clearance_mm) << m;
        } else {
          EXPECT_LE(r.motions[m].min_clearance_mm, exact.motions[m].min_clearance_mm) << m;
        }
      }
      // far objects answered by their bounds: fewer FCL queries for the same answer (the
      // default band: 282 instead of 3182 with the pre-sampling)
      EXPECT_LT(r.distance_queries, exact.distance_queries);
    }
  }
  {
    CheckOptions bad;
    bad.exact_band_mm = 0;
    std::string why;
    EXPECT_FALSE(bad.IsValid(&why));
    EXPECT_NE(why.find("exact_band_mm"), std::string::npos);
  }
  {
    // a NaN is named as such, not as "must be >= 0"
    CheckOptions bad;
    bad.thresholds.min_clearance_mm = std::numeric_limits<double>::quiet_NaN();
    std::string why;
    EXPECT_FALSE(bad.IsValid(&why));
    EXPECT_EQ(why, "min_clearance_mm: expected a finite distance >= 0 (mm), found nan");
    bad.thresholds.min_clearance_mm = -1;
    EXPECT_FALSE(bad.IsValid(&why));
    EXPECT_EQ(why, "min_clearance_mm: expected a finite distance >= 0 (mm), found -1");
  }
}

// A path that touches the fixture, through accura check on a KRL program.
TEST(CheckClearance, PathTouchingAFixtureOnTheCommandLine) {
  const std::string dir = test::tempDir("check_touch");
  test::writeText(dir + "/post.stl", test::readText(fixture("post_binary.stl")));
  auto cell = [&](double y_post) {
    std::ostringstream s;
    s << "<?xml version=\"1.0\"?>\n<cell name=\"touch\">\n"
      << "  <thresholds min_clearance_mm=\"5\"/>\n"
      << "  <object name=\"post\" file=\"post.stl\" units=\"mm\" x_mm=\"1200\" y_mm=\"" << y_post << "\" z_mm=\"500\"/>\n"
      << "  <tool><capsule x0_mm=\"0\" y0_mm=\"0\" z0_mm=\"0\" x1_mm=\"0\" y1_mm=\"0\" z1_mm=\"0\" radius_mm=\"10\"/></tool>\n"
      << "</cell>\n";
    return s.str();
  };
  test::writeText(dir + "/near.xml", cell(12));   // the sphere overlaps the post by 3 mm
  test::writeText(dir + "/far.xml", cell(118));   // 103 mm clear
  test::writeText(dir + "/seam.src",
                  "DEF seam( )\n"
                  "$TOOL = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n"
                  "$BASE = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n"
                  "PTP {X 900, Y 0, Z 800, A 0, B 90, C 0}\n"
                  "LIN {X 1500, Y 0, Z 800, A 0, B 90, C 0}\n"
                  "END\n");
  const test::CliRun bad = test::runAccuraIn(dir, "check --robot kuka_kr16 --cell near.xml --in seam.src --json near.json");
  EXPECT_EQ(bad.code, 2) << bad.out << bad.err;
  EXPECT_NE(bad.out.find("FAILED"), std::string::npos) << bad.out;
  const auto j = nlohmann::json::parse(test::readText(dir + "/near.json"));
  EXPECT_FALSE(j["passed"].get<bool>());
  ASSERT_EQ(j["violations"].size(), 1u);
  const auto& v = j["violations"][0];
  EXPECT_EQ(v["check"], "clearance");
  EXPECT_EQ(v["line"], 5);
  EXPECT_EQ(v["motion"], "LIN");
  EXPECT_EQ(v["obstacle"], "post");
  const Eigen::Vector3d p(v["tcp_world_mm"][0].get<double>(), v["tcp_world_mm"][1].get<double>(), v["tcp_world_mm"][2].get<double>());
  EXPECT_NEAR(v["value"].get<double>(), postClearance(p, 12, 10), 2e-3);
  // the first point closer than 5 mm: sqrt(dx^2 + 7^2) - 10 = 5 -> dx = 13.27 mm before the post
  EXPECT_NEAR(p.x(), 1200 - 5 - std::sqrt(15.0 * 15.0 - 7.0 * 7.0), 2.0);
  EXPECT_EQ(j["violations"][0]["joints"].size(), 6u);

  const test::CliRun good = test::runAccuraIn(dir, "check --robot kuka_kr16 --cell far.xml --in seam.src --json far.json");
  EXPECT_EQ(good.code, 0) << good.out << good.err;
  const auto g = nlohmann::json::parse(test::readText(dir + "/far.json"));
  EXPECT_TRUE(g["passed"].get<bool>());
  // the sample at x = 1200 (1 mm steps from x = 900) is the closest: 118 - 5 - 10 mm
  EXPECT_NEAR(g["totals"]["min_clearance_mm"].get<double>(), 103.0, 1e-3);

  // bad input: a cell file error names file and line; exit 1
  test::writeText(dir + "/broken.xml", "<?xml version=\"1.0\"?>\n<cell>\n  <object name=\"p\" file=\"post.stl\" units=\"yards\"/>\n</cell>\n");
  const test::CliRun err = test::runAccuraIn(dir, "check --robot kuka_kr16 --cell broken.xml --in seam.src");
  EXPECT_EQ(err.code, 1);
  EXPECT_NE(err.err.find("broken.xml:3"), std::string::npos) << err.err;
  EXPECT_NE(err.err.find("found 'yards'"), std::string::npos) << err.err;
}

// The real robot's A1 zero is 1 deg off: a target the nominal robot reaches with A1 = 183.5 deg
// (1.5 deg inside the 185 deg limit) needs A1 = 184.5 deg on the real one (theta1 = -q1 + 1 deg),
// 0.5 deg inside: short of the 1 deg margin by 0.5 deg.
struct ReachCase {
  calib::RobotModel nominal = kr16();
  calib::RobotModel real;
  Eigen::VectorXd q_nominal;
  std::string program;
  ReachCase() {
    real = nominal;
    real.deviations.links[0].dtheta_rad = 1.0 * calib::kDegToRad;
    q_nominal.resize(6);
    q_nominal << 183.5, -80, 100, 20, 40, 30;
    const calib::XyzAbc p = calib::toXyzAbc(calib::forwardKinematics(nominal, q_nominal));
    const calib::Configuration c = calib::kukaConfiguration(nominal, q_nominal);
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "DEF reach( )\n$TOOL = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n$BASE = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n"
                  "PTP {X %.6f, Y %.6f, Z %.6f, A %.6f, B %.6f, C %.6f, S %d, T %d}\nEND\n",
                  p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg, c.status, c.turn);
    program = buf;
  }
};

TEST(CheckReach, CompensationPushesAPointIntoTheJointMargin) {
  const ReachCase rc;
  const std::string dir = test::tempDir("check_reach_lib");
  test::writeText(dir + "/reach.src", rc.program);
  const Program prog = readProgram(dir + "/reach.src");
  Cell cell;  // no geometry: reach, limits and singularities only
  CheckOptions o;
  o.thresholds.joint_margin_deg = 1.0;
  JobSettings job;
  job.calibrated = rc.nominal;
  const CheckReport ok = checkProgram(prog, job, cell, o);
  EXPECT_TRUE(ok.passed());
  EXPECT_NEAR(ok.min_joint_margin, 1.5, 1e-4);  // 185 - 183.5

  job.calibrated = rc.real;
  const CheckReport r = checkProgram(prog, job, cell, o);
  ASSERT_EQ(r.violations.size(), 1u);
  const CheckViolation& v = r.violations[0];
  EXPECT_EQ(v.kind, CheckKind::kJointLimit);
  EXPECT_EQ(v.joint, 0);
  EXPECT_EQ(v.unit, "deg");
  EXPECT_FALSE(v.on_path);
  EXPECT_EQ(v.where.line, 4);
  ASSERT_EQ(v.q.size(), 6);
  EXPECT_NEAR(v.q[0], 184.5, 1e-4);
  for (int i = 1; i < 6; ++i) EXPECT_NEAR(v.q[i], rc.q_nominal[i], 1e-4);
  EXPECT_NEAR(v.value, 0.5, 1e-4);
  EXPECT_NEAR(v.excess, 0.5, 1e-4);
}

TEST(CheckReach, CompensateWithCellKeepsAFailingProgramOffTheDisk) {
  const ReachCase rc;
  const std::string dir = test::tempDir("check_reach_cli");
  test::writeText(dir + "/reach.src", rc.program);
  calib::writeRobotFile(dir + "/real.xml", rc.real);
  test::writeText(dir + "/cell.xml", "<?xml version=\"1.0\"?>\n<cell name=\"empty\">\n  <thresholds joint_margin_deg=\"1\"/>\n</cell>\n");
  // the compensation alone succeeds (184.5 deg is within the limits)
  const test::CliRun plain = test::runAccuraIn(dir, "compensate --robot real.xml --in reach.src --out plain");
  EXPECT_EQ(plain.code, 0) << plain.err;
  EXPECT_TRUE(std::filesystem::exists(dir + "/plain/reach.src"));
  // with the cell it fails: exit 2, report, nothing written but the JSON report
  const test::CliRun blocked = test::runAccuraIn(dir, "compensate --robot real.xml --cell cell.xml --in reach.src --out out --json out.json");
  EXPECT_EQ(blocked.code, 2) << blocked.out << blocked.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/out/reach.src"));
  EXPECT_NE(blocked.out.find("joint limit: A1"), std::string::npos) << blocked.out;
  const auto j = nlohmann::json::parse(test::readText(dir + "/out.json"));
  EXPECT_TRUE(j["outputs"].empty());
  ASSERT_EQ(j["check"]["violations"].size(), 1u);
  EXPECT_EQ(j["check"]["violations"][0]["check"], "joint_limit");
  EXPECT_EQ(j["check"]["violations"][0]["joint"], 1);
  EXPECT_NEAR(j["check"]["violations"][0]["excess"].get<double>(), 0.5, 1e-4);
  // --joint-margin-deg 0.4 on the command line overrides the cell's 1 deg: passes
  const test::CliRun loose = test::runAccuraIn(dir, "compensate --robot real.xml --cell cell.xml --joint-margin-deg 0.4 --in reach.src --out loose");
  EXPECT_EQ(loose.code, 0) << loose.out << loose.err;
  EXPECT_TRUE(std::filesystem::exists(dir + "/loose/reach.src"));
  // --warn-only writes it, exit 0, with a warning
  const test::CliRun warned = test::runAccuraIn(dir, "compensate --robot real.xml --cell cell.xml --warn-only --in reach.src --out warned");
  EXPECT_EQ(warned.code, 0) << warned.err;
  EXPECT_TRUE(std::filesystem::exists(dir + "/warned/reach.src"));
  EXPECT_EQ(test::readText(dir + "/warned/reach.src"), test::readText(dir + "/plain/reach.src"));
  EXPECT_NE(warned.err.find("failed the checks"), std::string::npos) << warned.err;
  // the compensated program, run as written by the nominal controller, puts the real robot on
  // the same joints: accura check --as-written finds the same violation
  const test::CliRun as_written = test::runAccuraIn(dir, "check --robot real.xml --cell cell.xml --as-written --in plain/reach.src --json aw.json");
  EXPECT_EQ(as_written.code, 2) << as_written.out << as_written.err;
  const auto aw = nlohmann::json::parse(test::readText(dir + "/aw.json"));
  ASSERT_EQ(aw["violations"].size(), 1u);
  EXPECT_NEAR(aw["violations"][0]["joints"][0].get<double>(), 184.5, 1e-3);
}

// The golden seam (tests/golden/compensate) in its cell (tests/data/cell/seam_cell.xml): the
// torch's tip (capsule radius 15 mm ending at the nominal TCP) passes about 30 mm over the
// plate's top, so the smallest clearance is about 30 - 15 = 15 mm (exactly: below). With the
// default 5 mm the program passes and is written byte for byte as without --cell; asking for
// 20 mm fails it and nothing is written.
TEST(CheckClearance, CompensateTheGoldenSeamInItsCell) {
  const std::string dir = test::tempDir("check_seam");
  for (const char* f : {"seam.src", "seam.dat", "$config.dat", "kr16_real.xml"})
    test::writeText(dir + "/" + f, test::readText(test::sourcePath(std::string("tests/golden/compensate/") + f)));
  for (const char* f : {"seam_cell.xml", "plate_m.obj"}) test::writeText(dir + "/" + f, test::readText(fixture(f)));
  const std::string base = "compensate --robot kr16_real.xml --in seam.src --config '$config.dat' --tol 0.02 --cell seam_cell.xml ";
  const test::CliRun ok = test::runAccuraIn(dir, base + "--out ok --json ok.json");
  ASSERT_EQ(ok.code, 0) << ok.out << ok.err;
  EXPECT_EQ(test::readText(dir + "/ok/seam.src"), test::readText(test::sourcePath("tests/golden/compensate/expected/seam.src")));
  EXPECT_EQ(test::readText(dir + "/ok/seam.dat"), test::readText(test::sourcePath("tests/golden/compensate/expected/seam.dat")));
  const auto j = nlohmann::json::parse(test::readText(dir + "/ok.json"));
  EXPECT_TRUE(j["check"]["passed"].get<bool>());
  // the torch capsule is in the flange frame (nominal tool); the calibrated tool puts the real
  // TCP on XP3, so the capsule's end is where the nominal TCP point lands then: at XP3 (world
  // T_world_base1 * XP3) the flange is T_world_tcp * inverse(calibrated T_flange_tcp)
  const calib::RobotModel real = calib::readRobotFile(dir + "/kr16_real.xml");
  const Eigen::Isometry3d T_world_xp3 = calib::toIsometry(calib::XyzAbc{950, -400, 300, 90, 0, 0}) * calib::toIsometry(calib::XyzAbc{400, -250, 420, 150, 29.8999996, -179.300003});
  const Eigen::Vector3d tip = T_world_xp3 * real.T_flange_tcp().inverse() * Eigen::Vector3d(107.147003, 0, 313.237);
  ASSERT_NEAR(tip.z(), 720, 2.0);  // about 30 mm over the plate's top (z 690)
  EXPECT_NEAR(j["check"]["totals"]["min_clearance_mm"].get<double>(), tip.z() - 15 - 690, 2e-3);
  const test::CliRun bad = test::runAccuraIn(dir, base + "--min-clearance-mm 20 --out bad --json bad.json");
  EXPECT_EQ(bad.code, 2) << bad.out << bad.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/bad/seam.src"));
  const auto b = nlohmann::json::parse(test::readText(dir + "/bad.json"));
  ASSERT_FALSE(b["check"]["violations"].empty());
  const auto& v = b["check"]["violations"][0];
  EXPECT_EQ(v["check"], "clearance");
  EXPECT_EQ(v["robot_part"], "tool");
  EXPECT_EQ(v["obstacle"], "plate");
  EXPECT_LT(v["value"].get<double>(), 20.0);
  EXPECT_GE(v["value"].get<double>(), tip.z() - 15 - 690 - 2e-3);
}

// The mesh files a cell names are inputs like the cell file: a --json (check, compensate,
// batch) that names one is refused (exit 1) and the mesh is left byte for byte; before, the
// report replaced the fixture's mesh and the next run could not read the cell.
TEST(CheckClearance, AReportThatNamesAMeshOfTheCellIsRefused) {
  const std::string dir = test::tempDir("check_mesh_input");
  std::filesystem::create_directories(dir + "/progs");
  for (const char* f : {"seam.src", "seam.dat", "$config.dat", "kr16_real.xml"}) {
    test::writeText(dir + "/" + f, test::readText(test::sourcePath(std::string("tests/golden/compensate/") + f)));
    test::writeText(dir + "/progs/" + f, test::readText(test::sourcePath(std::string("tests/golden/compensate/") + f)));
  }
  for (const char* f : {"seam_cell.xml", "plate_m.obj"}) test::writeText(dir + "/" + f, test::readText(fixture(f)));
  const std::string mesh = test::readText(dir + "/plate_m.obj");
  const std::string job = "--robot kr16_real.xml --config '$config.dat' --cell seam_cell.xml ";
  for (const std::string& args : {"check " + job + "--in seam.src --json plate_m.obj", "compensate " + job + "--tol 0.02 --in seam.src --out out --json plate_m.obj",
                                  "batch " + job + "--tol 0.02 --in progs --out outs --json ./plate_m.obj"}) {
    const test::CliRun r = test::runAccuraIn(dir, args);
    EXPECT_EQ(r.code, 1) << args << r.out << r.err;
    EXPECT_NE(r.err.find("plate_m.obj: the output would overwrite the input plate_m.obj: choose another --json"), std::string::npos)
        << args << r.err;
    EXPECT_EQ(test::readText(dir + "/plate_m.obj"), mesh) << args;
  }
  EXPECT_FALSE(std::filesystem::exists(dir + "/out/seam.src"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/outs/seam.src"));
  // the same run with another report name passes
  EXPECT_EQ(test::runAccuraIn(dir, "check " + job + "--in seam.src --json r.json").code, 0);
  std::filesystem::remove_all(dir);
}

// A mesh in metres given units="mm" is a thousand times too small: one of 1 m or more passes
// loadMesh's 1 mm floor (a 2 x 3 x 1 m table is 3.742 mm across) and would leave the object
// out of the clearance check without a word. The check says so, at the cell's <object>, and
// still runs (a small real part is not refused); given units="m" there is no warning.
TEST(CheckClearance, AMeshOnlyMillimetresAcrossIsAWarning) {
  const std::string dir = test::tempDir("check_small_mesh");
  for (const char* f : {"seam.src", "seam.dat", "$config.dat", "kr16_real.xml"})
    test::writeText(dir + "/" + f, test::readText(test::sourcePath(std::string("tests/golden/compensate/") + f)));
  test::writeText(dir + "/plate_m.obj", test::readText(fixture("plate_m.obj")));
  // a 2 x 3 x 1 m box far from the robot, in metres: 3.742 mm across when read as mm
  test::writeText(dir + "/table_m.obj", "v 0 0 0\nv 2 0 0\nv 2 3 0\nv 0 3 0\nv 0 0 1\nv 2 0 1\nv 2 3 1\nv 0 3 1\n"
                                        "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n");
  std::string cell = test::readText(fixture("seam_cell.xml"));
  const std::string table = "  <object name=\"table\" file=\"table_m.obj\" units=\"mm\" x_mm=\"-3000\"/>\n";
  cell.insert(cell.find("</cell>"), table);
  test::writeText(dir + "/cell.xml", cell);
  const std::string run = "check --robot kr16_real.xml --config '$config.dat' --cell cell.xml --in seam.src --json r.json";
  const test::CliRun r = test::runAccuraIn(dir, run);
  EXPECT_EQ(r.code, 0) << r.out << r.err;
  // the <object>'s line and column in the cell file
  size_t line_start = cell.rfind("\n", cell.find(table)) + 1;
  const int line = static_cast<int>(std::count(cell.begin(), cell.begin() + static_cast<std::ptrdiff_t>(line_start), '\n')) + 1;
  const std::string message = "object 'table': its mesh table_m.obj is only 3.742 mm across: check the units the cell gives the file (a file "
                              "in metres needs units=\"m\"); the check measures it as it is";
  EXPECT_NE(r.err.find("cell.xml:" + std::to_string(line) + ":3: " + message), std::string::npos) << r.err;
  const auto j = nlohmann::json::parse(test::readText(dir + "/r.json"));
  ASSERT_EQ(j["warnings"].size(), 1u) << j["warnings"].dump();
  EXPECT_EQ(j["warnings"][0]["message"], message);
  EXPECT_TRUE(j["passed"].get<bool>());
  // in metres: no warning
  std::string metres = cell;
  metres.replace(metres.find("table_m.obj\" units=\"mm\""), std::string("table_m.obj\" units=\"mm\"").size(), "table_m.obj\" units=\"m\"");
  test::writeText(dir + "/cell.xml", metres);
  EXPECT_EQ(test::runAccuraIn(dir, run).code, 0);
  EXPECT_TRUE(nlohmann::json::parse(test::readText(dir + "/r.json"))["warnings"].empty());
  std::filesystem::remove_all(dir);
}

// sigma_min of the scaled joint Jacobian at A5 = 0.5 deg, against the singular values of a
// central-difference Jacobian of the forward kinematics.
TEST(CheckSingularity, SigmaMinMatchesFiniteDifferences) {
  const calib::RobotModel robot = kr16();
  Eigen::VectorXd q(6);
  q << 10, -80, 100, 30, 0.5, 20;
  WorldMotion m;
  m.type = MotionType::kPtp;
  m.q_end = q;
  m.label = "PTP";
  CheckOptions o;
  o.thresholds.singular_threshold = 0.005;
  const CheckReport r = checkMotions(robot, robot, Cell{}, {m}, o);
  ASSERT_EQ(r.violations.size(), 1u);
  EXPECT_EQ(r.violations[0].kind, CheckKind::kSingularity);
  double L = 0;
  for (const auto& j : robot.nominal.joints) L += std::fabs(j.a_mm) + std::fabs(j.d_mm);
  EXPECT_NEAR(L, 2478, 1e-9);  // KR 16: a 260 + 680 + 35, d 675 + 670 + 158; no tool offset
  Eigen::Matrix<double, 6, 6> J;
  const double h_deg = 1e-3;
  for (int i = 0; i < 6; ++i) {
    Eigen::VectorXd qp = q, qm = q;
    qp[i] += h_deg;
    qm[i] -= h_deg;
    const Eigen::Isometry3d Tp = calib::forwardKinematics(robot, qp), Tm = calib::forwardKinematics(robot, qm);
    const double h_rad = 2 * h_deg * calib::kDegToRad;
    J.block<3, 1>(0, i) = (Tp.translation() - Tm.translation()) / h_rad / L;
    J.block<3, 1>(3, i) = calib::logSO3(Tp.linear() * Tm.linear().transpose()) / h_rad;
  }
  const double sigma_fd = Eigen::JacobiSVD<Eigen::Matrix<double, 6, 6>>(J).singularValues()[5];
  EXPECT_NEAR(r.violations[0].value, sigma_fd, 1e-8);
  EXPECT_LT(sigma_fd, 0.005);
  EXPECT_NEAR(sigma_fd, 0.25 * 0.5 * calib::kDegToRad, 0.5e-3);  // docs/compensation.md: about 0.25 |A5|
  // away from it: no violation
  m.q_end[4] = 30;
  EXPECT_TRUE(checkMotions(robot, robot, Cell{}, {m}, o).passed());
}

// A geometry prepared once (accura batch: the BVHs built once for every program) gives the
// report of a geometry built for the check; one prepared for another robot is refused.
TEST(CheckProgram, PreparedGeometryGivesTheSameReport) {
  const std::string dir = test::tempDir("check_shared");
  test::writeText(dir + "/seam.src",
                  "DEF seam( )\n$TOOL = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n$BASE = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n"
                  "PTP {X 900, Y 0, Z 800, A 0, B 90, C 0}\nLIN {X 1500, Y 0, Z 800, A 0, B 90, C 0}\nEND\n");
  const Program prog = readProgram(dir + "/seam.src");
  const Cell cell = postCell(12, 10);
  JobSettings job;
  job.calibrated = kr16();
  CheckOptions o;
  const CheckReport built = checkProgram(prog, job, cell, o);
  const CellGeometry prepared(cell, job.calibrated);
  const CheckReport shared = checkProgram(prog, job, cell, o, prepared);
  ASSERT_EQ(built.violations.size(), 1u);
  ASSERT_EQ(shared.violations.size(), 1u);
  EXPECT_EQ(shared.violations[0].message, built.violations[0].message);
  EXPECT_EQ(shared.violations[0].q, built.violations[0].q);
  EXPECT_EQ(shared.violations[0].value, built.violations[0].value);
  EXPECT_EQ(shared.samples, built.samples);
  EXPECT_EQ(shared.distance_queries, built.distance_queries);
  EXPECT_EQ(shared.min_clearance_mm, built.min_clearance_mm);
  calib::RobotModel other = job.calibrated;
  other.deviations.links[1].da_mm = 0.5;
  EXPECT_TRUE(prepared.madeFor(cell, job.calibrated));
  EXPECT_FALSE(prepared.madeFor(cell, other));
  EXPECT_FALSE(prepared.madeFor(Cell{}, job.calibrated));
  job.calibrated = other;
  EXPECT_THROW(checkProgram(prog, job, cell, o, prepared), calib::ArgumentError);
}

TEST(CheckProgram, CellPlacementAgainstBaseOption) {
  const ReachCase rc;
  const std::string dir = test::tempDir("check_place");
  test::writeText(dir + "/reach.src", rc.program);
  const Program prog = readProgram(dir + "/reach.src");
  Cell cell;
  cell.file = "cell.xml";
  cell.T_world_base = calib::toIsometry(calib::XyzAbc{0, 0, 10, 0, 0, 0});
  JobSettings job;
  job.calibrated = rc.nominal;
  job.robroot_in_world = calib::XyzAbc{0, 0, 0, 0, 0, 0};
  EXPECT_THROW(checkProgram(prog, job, cell, CheckOptions{}), calib::InputError);
  // a placement 60 mm from the calibrated base: the model was measured elsewhere
  job.robroot_in_world.reset();
  cell.T_world_base = calib::toIsometry(calib::XyzAbc{0, 0, 60, 0, 0, 0});
  EXPECT_THROW(checkProgram(prog, job, cell, CheckOptions{}), calib::InputError);
}


// ---- reach, wrist and elbow singularities along a path (docs/checks.md, "The checks")

// The KR 16's reach: the wrist centre W (origin of DH frame 5, where axes 4, 5, 6 meet) is at
// most r_max = |a2| + hypot(a3, d4) from the shoulder S (origin of DH frame 1, on axis 2), the
// arm stretched (the elbow singularity); `w_flange`: W in the flange frame (constant).
struct Stretch {
  Eigen::Vector3d shoulder;
  Eigen::Vector3d w_flange;
  double r_max = 0;
};
Stretch kr16Stretch(const calib::RobotModel& robot) {
  calib::KinematicWorkspace ws;
  Eigen::VectorXd q(6);
  q << 0, -60, 60, 20, 30, 40;  // A1 = 0: the shoulder in the x-z plane
  const Eigen::Isometry3d F = calib::forwardKinematics(robot, q, calib::PoseContext{}, ws);
  Stretch st;
  st.shoulder = ws.T_base_frame[1].translation();
  st.w_flange = F.inverse() * ws.T_base_frame[5].translation();
  const auto& j = robot.nominal.joints;
  st.r_max = std::fabs(j[1].a_mm) + std::hypot(j[2].a_mm, j[3].d_mm);
  return st;
}

// A LIN at a fixed orientation (tool pointing down, so the wrist stays far from its
// singularity) along +x at y 0, z 800. The wrist centre W(x) moves with the TCP; it is at
// |W - S| = r rather than the maximum where x_at(r) says (a quadratic).
struct StretchLine {
  Stretch st;
  static calib::XyzAbc pose(double x) { return calib::XyzAbc{x, 0, 800, 0, 0, 180}; }
  double x_at(double r) const {
    const Eigen::Vector3d e = calib::toIsometry(pose(0)) * st.w_flange - st.shoulder;  // W(x) = W(0) + x (1, 0, 0)
    return -e.x() + std::sqrt(r * r - e.y() * e.y() - e.z() * e.z());
  }
};

// From x = 1300 to 2000 mm: the wrist centre leaves the workspace at x* = x_at(r_max). The check
// reports `reach` on the path at the first sample beyond x*: the samples before it are
// reachable, so it is at most one sample step (1 mm of path) past x*. (The arm gets within 1 mm
// of the stretch only there: the last reachable sample is at sigma_min about 0.008, above the
// threshold; the elbow singularity itself is the next test.)
TEST(CheckReach, LinLeavesTheWorkspace) {
  const calib::RobotModel robot = kr16();
  const StretchLine line{kr16Stretch(robot)};
  EXPECT_NEAR(line.st.r_max, 680 + std::hypot(35.0, 670.0), 1e-9);
  EXPECT_NEAR(line.st.shoulder.x(), 260, 1e-9);
  EXPECT_NEAR(line.st.shoulder.z(), 675, 1e-9);
  const double x_star = line.x_at(line.st.r_max);
  ASSERT_GT(x_star, 1400);
  ASSERT_LT(x_star, 1900);
  CheckOptions o;  // defaults: 1 mm samples, sigma_min >= 0.005, margin 1 deg
  const CheckReport r = checkMotions(robot, robot, Cell{},
                                     {cartesian(MotionType::kPtp, line.pose(1300), 1), cartesian(MotionType::kLin, line.pose(2000), 2)}, o);
  ASSERT_EQ(r.violations.size(), 1u);
  const CheckViolation& v = r.violations[0];
  EXPECT_EQ(v.kind, CheckKind::kReach);
  EXPECT_EQ(v.motion_index, 1);
  EXPECT_EQ(v.where.line, 2);
  EXPECT_TRUE(v.on_path);
  EXPECT_EQ(v.q.size(), 0);
  EXPECT_GE(v.p_world_tcp_mm.x(), x_star);
  EXPECT_LE(v.p_world_tcp_mm.x() - x_star, o.sample_step_mm + 1e-9);
  EXPECT_NEAR((v.p_world_tcp_mm - Eigen::Vector3d(1300 + 700 * v.s, 0, 800)).norm(), 0, 1e-9);
  EXPECT_NEAR(v.arc_mm, 700 * v.s, 1e-9);
  EXPECT_NE(v.message.find("unreachable"), std::string::npos) << v.message;
}

// The elbow singularity: the same line, ending with the wrist centre 0.05 mm short of the full
// stretch (still reachable). sigma_min falls monotonically as the arm stretches; the check
// reports the first sample below 0.005, with the singular direction in A2, A3, and one sample
// step (1 mm) earlier sigma_min is still above (a finite-difference sigma_min at an IK
// solution of our own). Near the stretch the elbow angle from straight is delta ~ sqrt(2 (r_max
// - r) r / (a2 l3)) and sigma_min ~ delta (a2 l3 / r) / L: the threshold is crossed within about
// 0.3 mm of the stretch.
TEST(CheckSingularity, LinStretchesTheArm) {
  const calib::RobotModel robot = kr16();
  const StretchLine line{kr16Stretch(robot)};
  const double x_end = line.x_at(line.st.r_max - 0.05);
  CheckOptions o;
  const CheckReport r = checkMotions(robot, robot, Cell{},
                                     {cartesian(MotionType::kPtp, line.pose(1300), 1), cartesian(MotionType::kLin, line.pose(x_end), 2)}, o);
  ASSERT_EQ(r.violations.size(), 1u);
  const CheckViolation& v = r.violations[0];
  const double length = x_end - 1300;
  EXPECT_EQ(v.kind, CheckKind::kSingularity);
  EXPECT_EQ(v.motion_index, 1);
  EXPECT_TRUE(v.on_path);
  ASSERT_EQ(v.q.size(), 6);
  const double x_v = 1300 + v.s * length;
  EXPECT_NEAR(v.p_world_tcp_mm.x(), x_v, 1e-3);  // FK of the IK's joints: within its 1 um
  EXPECT_LT(poseResidual(robot, v.q, calib::toIsometry(line.pose(x_v))), 1e-3);  // the IK's tolerance: 1 um, 1 urad
  EXPECT_NEAR(v.value, fdSigma(robot, v.q), 1e-6);
  EXPECT_LT(v.value, 0.005);
  EXPECT_NEAR(v.excess, 0.005 - v.value, 1e-12);
  const Eigen::Isometry3d T_before = calib::toIsometry(line.pose(x_v - o.sample_step_mm));
  const Eigen::VectorXd q_before = newtonIk(robot, T_before, v.q);
  ASSERT_LT(poseResidual(robot, q_before, T_before), 1e-6);
  EXPECT_GE(fdSigma(robot, q_before), 0.005);
  EXPECT_NE(v.message.find("A2, A3"), std::string::npos) << v.message;
  const double short_mm = line.st.r_max - (calib::toIsometry(line.pose(x_v)) * line.st.w_flange - line.st.shoulder).norm();
  EXPECT_GT(short_mm, 0.05);
  EXPECT_LT(short_mm, 0.5);
  EXPECT_LT(r.min_sigma, v.value);  // and lower still at the end
}

// A PTP to a Cartesian target outside the workspace: `reach` at the end point.
TEST(CheckReach, PtpToATargetOutsideTheWorkspace) {
  const calib::RobotModel robot = kr16();
  const Stretch st = kr16Stretch(robot);
  const calib::XyzAbc far{2000, 0, 800, 0, 90, 0};
  EXPECT_GT((calib::toIsometry(far) * st.w_flange - st.shoulder).norm(), st.r_max + 200);
  const CheckReport r =
      checkMotions(robot, robot, Cell{}, {cartesian(MotionType::kPtp, {1300, 0, 800, 0, 90, 0}, 1), cartesian(MotionType::kPtp, far, 2)}, CheckOptions{});
  ASSERT_EQ(r.violations.size(), 1u);
  const CheckViolation& v = r.violations[0];
  EXPECT_EQ(v.kind, CheckKind::kReach);
  EXPECT_EQ(v.motion_index, 1);
  EXPECT_EQ(v.where.line, 2);
  EXPECT_FALSE(v.on_path);
  EXPECT_EQ(v.s, 1.0);
  EXPECT_EQ(v.p_world_tcp_mm, Eigen::Vector3d(2000, 0, 800));
  EXPECT_EQ(v.q.size(), 0);
  EXPECT_NE(v.message.find("unreachable"), std::string::npos) << v.message;
}

// The wrist singularity: the TCP at the wrist centre, a LIN that only turns the tool about the
// A5 axis from A5 = +9.9 to -9.9 deg (A1..A4, A6 fixed: A5(s) = 9.9 - 19.8 s, exactly). The
// 19.8 deg turn is sampled every 0.5 deg: 40 samples, s = k/40. sigma_min ~ 0.25 |A5| (rad) is
// below 0.005 first at the first k with fdSigma(q(k/40)) < 0.005: k = 18, A5 = 0.99 deg.
TEST(CheckSingularity, LinThroughTheWristSingularity) {
  const calib::RobotModel robot = kr16();
  const Stretch st = kr16Stretch(robot);
  Eigen::Isometry3d T_flange_tcp = Eigen::Isometry3d::Identity();
  T_flange_tcp.translation() = st.w_flange;
  calib::RobotModel with_tool = robot;
  with_tool.nominal.T_flange_tcp = T_flange_tcp;
  const auto q_at = [](double s) { return (Eigen::VectorXd(6) << 0, -90, 90, 0, 9.9 - 19.8 * s, 0).finished(); };
  WorldMotion start;
  start.q_end = q_at(0);
  start.label = "PTP";
  start.T_flange_tcp = T_flange_tcp;
  start.where.line = 1;
  WorldMotion lin;
  lin.type = MotionType::kLin;
  lin.label = "LIN";
  lin.T_flange_tcp = T_flange_tcp;
  lin.T_world_tcp_end = calib::forwardKinematics(with_tool, q_at(1));
  lin.where.line = 2;
  // independent expectation: the first sample below the threshold
  int k_first = -1;
  for (int k = 1; k <= 40 && k_first < 0; ++k)
    if (fdSigma(robot, q_at(k / 40.0)) < 0.005) k_first = k;
  ASSERT_EQ(k_first, 18);  // A5 = 0.99 deg (at 1.485 deg sigma_min is 0.0065)
  CheckOptions o;
  const CheckReport r = checkMotions(robot, robot, Cell{}, {start, lin}, o);
  ASSERT_EQ(r.violations.size(), 1u);
  const CheckViolation& v = r.violations[0];
  EXPECT_EQ(v.kind, CheckKind::kSingularity);
  EXPECT_EQ(v.motion_index, 1);
  EXPECT_TRUE(v.on_path);
  EXPECT_DOUBLE_EQ(v.s, k_first / 40.0);
  ASSERT_EQ(v.q.size(), 6);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(v.q[i], q_at(v.s)[i], 1e-6) << i;
  EXPECT_NEAR(v.value, fdSigma(robot, q_at(v.s)), 1e-6);
  EXPECT_NEAR(v.value, 0.25 * 0.99 * calib::kDegToRad, 0.5e-3);
  EXPECT_NEAR(v.excess, 0.005 - v.value, 1e-12);
  EXPECT_NE(v.message.find("A4, A6"), std::string::npos) << v.message;
  EXPECT_EQ(r.motions[1].samples, 40);

  // Exactly through the singularity the joint path is continuous (A5 through 0, A4 and A6
  // fixed): without the threshold nothing is reported.
  o.thresholds.singular_threshold = 0;
  EXPECT_TRUE(checkMotions(robot, robot, Cell{}, {start, lin}, o).passed());

  // Past it by a hair: the rotation axis tilted by eta = 1e-3 rad from the A5 axis toward the
  // forearm axis, so the tool axis passes the forearm axis at eta (1 - cos 9.9 deg) = 1.5e-5
  // rad. There A4 and A6 have to turn by 180 deg within a few 1e-5 rad of turn; within the IK's
  // tolerance (1 urad) they are determined only to tol / |A5|, and the joint values of the
  // samples jump: the joint-jump detection (bisection to 2^-30 of a sample interval) reports
  // `singularity` on the path where the wrist is within 0.01 deg of straight.
  calib::KinematicWorkspace ws;
  const Eigen::Isometry3d Ta = calib::forwardKinematics(with_tool, q_at(0), calib::PoseContext{}, ws);
  const Eigen::Vector3d z4 = ws.T_base_frame[4].linear().col(2), z3 = ws.T_base_frame[3].linear().col(2);  // axes 5 and 4
  const double eta = 1e-3;
  WorldMotion miss = lin;
  miss.T_world_tcp_end = Ta;
  miss.T_world_tcp_end.linear() =
      Eigen::AngleAxisd(-19.8 * calib::kDegToRad, std::cos(eta) * z4 + std::sin(eta) * z3).toRotationMatrix() * Ta.linear();
  {
    Eigen::Isometry3d exact = Ta;  // with eta = 0 this is the LIN above
    exact.linear() = Eigen::AngleAxisd(-19.8 * calib::kDegToRad, z4).toRotationMatrix() * Ta.linear();
    ASSERT_LT(poseResidual(with_tool, q_at(1), exact), 1e-9);
  }
  const CheckReport j = checkMotions(robot, robot, Cell{}, {start, miss}, o);
  ASSERT_EQ(j.violations.size(), 1u);
  const CheckViolation& jv = j.violations[0];
  EXPECT_EQ(jv.kind, CheckKind::kSingularity);
  EXPECT_TRUE(jv.on_path);
  EXPECT_NE(jv.message.find("the joint values jump"), std::string::npos) << jv.message;
  ASSERT_EQ(jv.q.size(), 6);
  EXPECT_LT(std::fabs(jv.q[4]), 0.01);                  // A5 (deg): the wrist nearly straight
  EXPECT_LT(std::fabs(jv.s - 0.5) * 19.8, 0.01);        // the turn (deg) from where it is straightest
  EXPECT_NEAR(jv.value, fdSigma(robot, jv.q), 1e-6);    // sigma_min there
  EXPECT_LT(jv.value, 0.25 * 0.01 * calib::kDegToRad * 1.1);   // ~ 0.25 |A5|
  EXPECT_EQ(jv.excess, 0.0);                            // the threshold is 0
}

// ---- compensation and check together (accura compensate --cell, accura batch --cell)

std::string krlProgram(const std::string& name, const std::vector<std::string>& motions) {
  std::string s = "DEF " + name + "( )\n$TOOL = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n$BASE = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n";
  for (const auto& m : motions) s += m + "\n";
  return s + "END\n";
}

// An unreachable target (2000 mm out along x: the wrist centre 1587 mm from the shoulder, reach
// 1351 mm): accura check reports `reach` (exit 2); accura compensate alone cannot compensate it
// (exit 1, bad input, unchanged); with --cell it reports it as the check does: exit 2, the
// reach violation printed and in the --json `check` section, nothing written (not even with
// --warn-only: there is no compensated program); accura batch --cell the same for that program
// while the others are written.
TEST(CheckReach, UnreachableTargetIsACheckFailureOfCompensateWithCell) {
  const std::string dir = test::tempDir("check_unreach_cli");
  const std::string prog = krlProgram("unreach", {"PTP {X 1300, Y 0, Z 800, A 0, B 90, C 0}", "PTP {X 2000, Y 0, Z 800, A 0, B 90, C 0}"});
  test::writeText(dir + "/unreach.src", prog);
  test::writeText(dir + "/cell.xml", "<?xml version=\"1.0\"?>\n<cell name=\"empty\">\n  <thresholds joint_margin_deg=\"1\"/>\n</cell>\n");
  const test::CliRun check = test::runAccuraIn(dir, "check --robot kuka_kr16 --cell cell.xml --in unreach.src --json check.json");
  EXPECT_EQ(check.code, 2) << check.out << check.err;
  const auto c = nlohmann::json::parse(test::readText(dir + "/check.json"));
  ASSERT_EQ(c["violations"].size(), 1u);
  EXPECT_EQ(c["violations"][0]["check"], "reach");

  const test::CliRun plain = test::runAccuraIn(dir, "compensate --robot kuka_kr16 --in unreach.src --out plain");
  EXPECT_EQ(plain.code, 1) << plain.out << plain.err;
  EXPECT_NE(plain.err.find("unreach.src:5"), std::string::npos) << plain.err;

  const test::CliRun cell = test::runAccuraIn(dir, "compensate --robot kuka_kr16 --cell cell.xml --in unreach.src --out out --json out.json");
  EXPECT_EQ(cell.code, 2) << cell.out << cell.err;
  EXPECT_NE(cell.out.find("VIOLATION unreach.src:5"), std::string::npos) << cell.out;
  EXPECT_NE(cell.out.find("reach: unreachable"), std::string::npos) << cell.out;
  EXPECT_NE(cell.out.find("not written"), std::string::npos) << cell.out;
  EXPECT_FALSE(std::filesystem::exists(dir + "/out/unreach.src"));
  const auto j = nlohmann::json::parse(test::readText(dir + "/out.json"));
  EXPECT_TRUE(j["outputs"].empty());
  EXPECT_NE(j["compensation_error"].get<std::string>().find("unreach.src:5"), std::string::npos) << j.dump(2);
  EXPECT_FALSE(j["check"]["passed"].get<bool>());
  ASSERT_EQ(j["check"]["violations"].size(), 1u);
  const auto& v = j["check"]["violations"][0];
  EXPECT_EQ(v["check"], "reach");
  EXPECT_EQ(v["line"], 5);
  EXPECT_EQ(v["motion"], "PTP");
  EXPECT_FALSE(v["on_path"].get<bool>());
  EXPECT_EQ(v["tcp_world_mm"], nlohmann::json::array({2000.0, 0.0, 800.0}));
  EXPECT_TRUE(v["joints"].empty());

  const test::CliRun warned = test::runAccuraIn(dir, "compensate --robot kuka_kr16 --cell cell.xml --warn-only --in unreach.src --out warned");
  EXPECT_EQ(warned.code, 2) << warned.out << warned.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/warned/unreach.src"));

  std::filesystem::create_directories(dir + "/in");
  test::writeText(dir + "/in/unreach.src", prog);
  test::writeText(dir + "/in/good.src", krlProgram("good", {"PTP {X 1300, Y 0, Z 800, A 0, B 90, C 0}", "LIN {X 1300, Y 100, Z 800, A 0, B 90, C 0}"}));
  const test::CliRun batch = test::runAccuraIn(dir, "batch --robot kuka_kr16 --cell cell.xml --in in --out bout --json batch.json");
  EXPECT_EQ(batch.code, 2) << batch.out << batch.err;
  EXPECT_TRUE(std::filesystem::exists(dir + "/bout/good.src"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/bout/unreach.src"));
  const auto b = nlohmann::json::parse(test::readText(dir + "/batch.json"));
  bool seen = false;
  for (const auto& f : b["files"]) {
    if (f["input"] != "unreach.src") continue;
    seen = true;
    EXPECT_EQ(f["status"], "failed");
    EXPECT_NE(f["message"].get<std::string>().find("reach: unreachable"), std::string::npos) << f.dump(2);
    ASSERT_EQ(f["check"]["violations"].size(), 1u);
    EXPECT_EQ(f["check"]["violations"][0]["check"], "reach");
    EXPECT_EQ(f["check"]["violations"][0]["line"], 5);
  }
  EXPECT_TRUE(seen) << b.dump(2);
}

// Which compensation failures the check explains: every error at a motion the check reports.
TEST(CheckReach, CompensationFailureExplainedByTheCheck) {
  CheckReport check;
  CheckViolation v;
  v.where = SourceLocation{"p.src", 5, 1};
  check.violations.push_back(v);
  JobReport job;
  EXPECT_FALSE(compensationFailureExplained(check, job));  // no error to explain
  job.errors.push_back({SourceLocation{"p.src", 5, 1}, "cannot be compensated"});
  EXPECT_TRUE(compensationFailureExplained(check, job));
  job.errors.push_back({SourceLocation{"p.src", 7, 1}, "cannot be compensated"});
  EXPECT_FALSE(compensationFailureExplained(check, job));  // line 7: the check says nothing
  check.unchecked.push_back({SourceLocation{"p.src", 7, 1}, "not checked"});
  EXPECT_TRUE(compensationFailureExplained(check, job));
  check.violations.clear();
  check.unchecked.clear();
  EXPECT_FALSE(compensationFailureExplained(check, job));  // the check passed
}

// Issue 5's "a program whose compensation pushes a point out of reach": the nominal program has
// A1 = 184.5 deg, within the limit of 185 deg (0.5 deg inside); the real robot's A1 zero is 1 deg
// off and its upper arm 0.5 mm longer, so the calibrated model needs A1 beyond the limit to put
// the TCP there. The excess is asserted against the calibrated model's own IK (Newton on calib's
// forward kinematics).
struct BeyondCase {
  calib::RobotModel nominal = kr16();
  calib::RobotModel real;
  Eigen::VectorXd q_nominal, q_real;
  std::string program;
  BeyondCase() {
    real = nominal;
    real.deviations.links[0].dtheta_rad = 1.0 * calib::kDegToRad;
    real.deviations.links[1].da_mm = 0.5;
    q_nominal.resize(6);
    q_nominal << 184.5, -80, 100, 20, 40, 30;
    const Eigen::Isometry3d T = calib::forwardKinematics(nominal, q_nominal);
    q_real = newtonIk(real, T, q_nominal);
    const calib::XyzAbc p = calib::toXyzAbc(T);
    const calib::Configuration c = calib::kukaConfiguration(nominal, q_nominal);
    char buf[256];
    std::snprintf(buf, sizeof buf, "PTP {X %.6f, Y %.6f, Z %.6f, A %.6f, B %.6f, C %.6f, S %d, T %d}", p.x_mm, p.y_mm, p.z_mm, p.a_deg,
                  p.b_deg, p.c_deg, c.status, c.turn);
    program = krlProgram("beyond", {buf});
  }
};

// A joint beyond its limit was "A1 = 190.000 deg is -5.000 deg outside its limits": minus and
// "outside" said the sign twice (read as 5 deg inside). Now the distance is said once, by the
// word: 190 - 185 = 5 deg outside, short of the 1 deg margin by 5 + 1 = 6 deg; value keeps its
// sign (-5).
TEST(CheckReach, AJointBeyondItsLimitIsSaidOutsideByAPositiveDistance) {
  const std::string dir = test::tempDir("check_outside");
  test::writeText(dir + "/out.src", krlProgram("out", {"PTP {A1 190, A2 -90, A3 90, A4 0, A5 30, A6 0}",
                                                       "PTP {A1 -184.5, A2 -90, A3 90, A4 0, A5 30, A6 0}"}));
  JobSettings job;
  job.calibrated = kr16();
  const CheckReport r = checkProgram(readProgram(dir + "/out.src"), job, Cell{}, CheckOptions{});
  ASSERT_EQ(r.violations.size(), 2u);
  EXPECT_EQ(r.violations[0].kind, CheckKind::kJointLimit);
  EXPECT_NEAR(r.violations[0].value, -5.0, 1e-9);
  EXPECT_EQ(r.violations[0].message.substr(0, r.violations[0].message.find(" at the end point")),
            "joint limit: A1 = 190.000 deg is 5.000 deg outside its limits [-185.0, 185.0]; required 1.000 deg inside (short by 6.000 deg)");
  EXPECT_EQ(r.violations[1].message.substr(0, r.violations[1].message.find(" at the end point")),
            "joint limit: A1 = -184.500 deg is 0.500 deg inside its limits [-185.0, 185.0]; required 1.000 deg inside (short by 0.500 deg)");
}

TEST(CheckReach, CompensationPushesAPointBeyondAJointLimit) {
  const BeyondCase bc;
  ASSERT_LT(poseResidual(bc.real, bc.q_real, calib::forwardKinematics(bc.nominal, bc.q_nominal)), 1e-6);
  ASSERT_GT(bc.q_real[0], 185.0);  // beyond the limit on the real robot
  const double excess_limit = bc.q_real[0] - 185.0;
  const std::string dir = test::tempDir("check_beyond");
  test::writeText(dir + "/beyond.src", bc.program);
  const Program prog = readProgram(dir + "/beyond.src");
  CheckOptions o;
  o.thresholds.joint_margin_deg = 0.25;
  JobSettings job;
  job.calibrated = bc.nominal;
  const CheckReport ok = checkProgram(prog, job, Cell{}, o);
  EXPECT_TRUE(ok.passed());
  EXPECT_NEAR(ok.min_joint_margin, 0.5, 1e-4);  // the nominal program: 185 - 184.5
  job.calibrated = bc.real;
  const CheckReport r = checkProgram(prog, job, Cell{}, o);
  ASSERT_EQ(r.violations.size(), 1u);
  const CheckViolation& v = r.violations[0];
  EXPECT_EQ(v.kind, CheckKind::kJointLimit);
  EXPECT_EQ(v.joint, 0);
  EXPECT_EQ(v.where.line, 4);
  ASSERT_EQ(v.q.size(), 6);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(v.q[i], bc.q_real[i], 1e-4) << i;
  EXPECT_NEAR(v.value, -excess_limit, 1e-4);       // outside the limit by this much
  EXPECT_NEAR(v.excess, 0.25 + excess_limit, 1e-4);  // short of the 0.25 deg margin
  EXPECT_NE(v.message.find("outside its limits"), std::string::npos) << v.message;

  // on the command line: accura compensate alone fails (exit 1), with --cell it is the check's
  // joint_limit violation (exit 2) with the same numbers
  calib::writeRobotFile(dir + "/real.xml", bc.real);
  test::writeText(dir + "/cell.xml", "<?xml version=\"1.0\"?>\n<cell name=\"empty\">\n  <thresholds joint_margin_deg=\"0.25\"/>\n</cell>\n");
  const test::CliRun plain = test::runAccuraIn(dir, "compensate --robot real.xml --in beyond.src --out plain");
  EXPECT_EQ(plain.code, 1) << plain.out << plain.err;
  const test::CliRun cell = test::runAccuraIn(dir, "compensate --robot real.xml --cell cell.xml --in beyond.src --out out --json out.json");
  EXPECT_EQ(cell.code, 2) << cell.out << cell.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/out/beyond.src"));
  const auto j = nlohmann::json::parse(test::readText(dir + "/out.json"));
  ASSERT_EQ(j["check"]["violations"].size(), 1u);
  const auto& jv = j["check"]["violations"][0];
  EXPECT_EQ(jv["check"], "joint_limit");
  EXPECT_EQ(jv["joint"], 1);
  EXPECT_NEAR(jv["value"].get<double>(), -excess_limit, 1e-4);
  EXPECT_NEAR(jv["excess"].get<double>(), 0.25 + excess_limit, 1e-4);
  EXPECT_NEAR(jv["joints"][0].get<double>(), bc.q_real[0], 1e-4);
  EXPECT_FALSE(j["compensation_error"].get<std::string>().empty());
}

// A cell with objects but no robot geometry: nothing to measure the clearance with. The report
// says so (a warning, printed and in the JSON), never a silent pass with 0 distance queries.
TEST(CheckClearance, ObjectsWithoutRobotGeometryAreAWarning) {
  const std::string dir = test::tempDir("check_nogeom");
  test::writeText(dir + "/post.stl", test::readText(fixture("post_binary.stl")));
  test::writeText(dir + "/cell.xml",
                  "<?xml version=\"1.0\"?>\n<cell name=\"no robot geometry\">\n"
                  "  <object name=\"post\" file=\"post.stl\" units=\"mm\" x_mm=\"1200\" y_mm=\"12\" z_mm=\"500\"/>\n</cell>\n");
  test::writeText(dir + "/seam.src", krlProgram("seam", {"PTP {X 900, Y 0, Z 800, A 0, B 90, C 0}", "LIN {X 1500, Y 0, Z 800, A 0, B 90, C 0}"}));
  const test::CliRun run = test::runAccuraIn(dir, "check --robot kuka_kr16 --cell cell.xml --in seam.src --json r.json");
  EXPECT_EQ(run.code, 0) << run.out << run.err;  // nothing violated: a warning, not a failure
  EXPECT_NE(run.err.find("warning: cell.xml: clearance not checked: the cell has 1 object(s) but no robot geometry"), std::string::npos)
      << run.err;
  const auto j = nlohmann::json::parse(test::readText(dir + "/r.json"));
  EXPECT_EQ(j["totals"]["distance_queries"], 0);
  bool warned = false;
  for (const auto& w : j["warnings"]) warned = warned || w["message"].get<std::string>().find("clearance not checked") == 0;
  EXPECT_TRUE(warned) << j.dump(2);
  // with a tool the same cell is measured (the LIN passes the post at 12 - 10 = 2 mm) and no
  // such warning
  const Program prog = readProgram(dir + "/seam.src");
  JobSettings job;
  job.calibrated = kr16();
  Cell cell = readCellFile(dir + "/cell.xml");
  CheckReport none = checkProgram(prog, job, cell, CheckOptions{});
  ASSERT_EQ(none.warnings.size(), 1u);
  EXPECT_EQ(none.distance_queries, 0);
  cell.tool_shapes = postCell(12, 10).tool_shapes;
  const CheckReport with_tool = checkProgram(prog, job, cell, CheckOptions{});
  for (const auto& w : with_tool.warnings) EXPECT_EQ(w.message.find("clearance not checked"), std::string::npos) << w.message;
  EXPECT_GT(with_tool.distance_queries, 0);
  EXPECT_NEAR(with_tool.min_clearance_mm, 0, 1e-6);  // the tool sphere overlaps the post
}

// The cell's <robot> and --base disagree: the error names the <robot> element (file:line:column).
TEST(CheckProgram, CellPlacementConflictNamesTheRobotElement) {
  const std::string dir = test::tempDir("check_place_cli");
  test::writeText(dir + "/p.src", krlProgram("p", {"PTP {X 1300, Y 0, Z 800, A 0, B 90, C 0}"}));
  test::writeText(dir + "/cell.xml", "<?xml version=\"1.0\"?>\n<cell name=\"c\">\n\n   <robot z_mm=\"10\"/>\n</cell>\n");
  const test::CliRun run = test::runAccuraIn(dir, "check --robot kuka_kr16 --cell cell.xml --base 0,0,0,0,0,0 --in p.src");
  EXPECT_EQ(run.code, 1) << run.out << run.err;
  EXPECT_NE(run.err.find("cell.xml:4:4: <robot>: the robot placement of the cell file differs from --base"), std::string::npos) << run.err;
  const test::CliRun comp = test::runAccuraIn(dir, "compensate --robot kuka_kr16 --cell cell.xml --base 0,0,0,0,0,0 --in p.src --out o");
  EXPECT_EQ(comp.code, 1) << comp.out << comp.err;
  EXPECT_NE(comp.err.find("cell.xml:4:4: <robot>"), std::string::npos) << comp.err;
}

TEST(CheckReach, ALoopsFirstLinIsSolvedOnTheConfigurationTheRobotStandsIn) {
  // LIN at a loop's start (from before the loop, or from the loop's end), without S/T (KUKA
  // ignores them on a LIN): the robot keeps the configuration it stands in. check follows the
  // text (the first pass comes from the PTP before the loop), so the LIN is checked from the
  // PTP's joints and ends on their configuration (wrist A4 at 300 deg, 50 deg from its limit),
  // not on the solution nearest the middle of the ranges.
  const calib::RobotModel nominal = test::loadBundled("kuka_kr16");
  Eigen::VectorXd q_ptp(6), q_target(6);
  q_ptp << 10, -80, 100, 280, -30, 220;
  q_target << 12, -78, 98, 300, -32, 215;
  const Eigen::Isometry3d T = calib::forwardKinematics(nominal, q_target);
  const calib::XyzAbc p = calib::toXyzAbc(T);
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "DEF loop( )\n$TOOL = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n$BASE = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n"
                "PTP {A1 10, A2 -80, A3 100, A4 280, A5 -30, A6 220}\nLOOP\n"
                "LIN {X %.6f, Y %.6f, Z %.6f, A %.6f, B %.6f, C %.6f}\nENDLOOP\nEND\n",
                p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg);
  const std::string dir = test::tempDir("check_loop_lib");
  test::writeText(dir + "/loop.src", buf);
  const Program prog = readProgram(dir + "/loop.src");
  ASSERT_EQ(prog.motions.size(), 2u);
  ASSERT_TRUE(prog.motions[1].start_unknown);
  // the expectation on its own: every solution of the pose within the limits, the margin of
  // the one nearest the PTP's joints and of the one nearest the middle of the ranges
  const calib::KinematicSolver ik(nominal);
  auto margin = [&](const Eigen::VectorXd& q) {
    double m = std::numeric_limits<double>::infinity();
    for (int i = 0; i < 6; ++i)
      m = std::min({m, q[i] - nominal.nominal.joints[i].lower, nominal.nominal.joints[i].upper - q[i]});
    return m;
  };
  Eigen::VectorXd q_mid(6);
  for (int i = 0; i < 6; ++i) q_mid[i] = 0.5 * (nominal.nominal.joints[i].lower + nominal.nominal.joints[i].upper);
  auto nearest = [&](const Eigen::VectorXd& to) {
    Eigen::VectorXd best;
    for (const Eigen::VectorXd& q : ik.closedFormSolutions(T))
      if (best.size() == 0 || (q - to).norm() < (best - to).norm()) best = q;
    return best;
  };
  const Eigen::VectorXd q_near = nearest(q_ptp), q_other = nearest(q_mid);
  ASSERT_EQ(q_near.size(), 6);
  EXPECT_NEAR((q_near - q_target).norm(), 0.0, 1e-6);
  EXPECT_GT(std::abs(margin(q_near) - margin(q_other)), 1.0);  // the check tells them apart
  Cell cell;
  CheckOptions o;
  JobSettings job;
  job.calibrated = nominal;
  const CheckReport r = checkProgram(prog, job, cell, o);
  ASSERT_EQ(r.motions.size(), 2u);
  EXPECT_NEAR(r.motions[1].min_joint_margin, margin(q_near), 1e-4);
  std::filesystem::remove_all(dir);
}
}  // namespace
}  // namespace accura::postproc
