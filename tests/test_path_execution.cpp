// Acceptance (issue 3): programs run on a simulated real robot (calib's perturbModel: a
// KR 16 with every geometric error and joint compliance, error scale 1) through a simulated
// nominal controller (LIN / CIRC interpolation plus its nominal IK). The compensated program
// with its auxiliary points follows the intended path to within the tolerance (the real
// model is known exactly here, so only a numerical margin is added); the uncompensated one is
// off by about a millimetre.
#include <gtest/gtest.h>

#include <cstdio>

#include "accura/calib/geometry.h"
#include "accura/calib/identify.h"
#include "accura/calib/simulate.h"
#include "accura/postproc/compensate.h"
#include "test_util.h"

namespace accura {
namespace {

using namespace postproc;

Eigen::Isometry3d pose(double x, double y, double z, double a, double b, double c) {
  return calib::toIsometry({x, y, z, a, b, c});
}

/// A 200 mm LIN, a half circle of radius 80 mm (CIRC), a 200 mm LIN back: 650 mm of seam.
std::vector<PathSegment> shortSeam() {
  std::vector<PathSegment> seam(3);
  seam[0].T_world_start = pose(1100, -250, 500, 0, 180, 0);
  seam[0].T_world_end = pose(1100, -50, 500, 0, 180, 0);
  seam[1].type = PathType::kCirc;
  seam[1].T_world_start = seam[0].T_world_end;
  seam[1].T_world_aux = pose(1180, 30, 500, 0, 180, 0);
  seam[1].T_world_end = pose(1260, -50, 500, 0, 180, 0);
  seam[2].T_world_start = seam[1].T_world_end;
  seam[2].T_world_end = pose(1260, -250, 500, 0, 180, 0);
  return seam;
}

struct Execution {
  double compensated_mm = 0;    ///< largest distance of the real tool from the intended path
  double uncompensated_mm = 0;
  double predicted_after_mm = 0;
  int points_added = 0;
};

/// Compensates `program` segment by segment (each continuing from the real joints where the
/// previous one ended) and executes the result and the original program.
Execution execute(const std::vector<PathSegment>& program, std::uint64_t seed, double tol_mm) {
  calib::RobotModel controller = test::loadBundled("kuka_kr16");
  controller.nominal.T_flange_tcp = calib::toIsometry({20, 0, 250, 0, -30, 0});  // a welding torch
  calib::SimulateOptions so;
  so.effects = {"geometric", "joint_compliance"};
  so.error_scale = 1;
  so.set_station = false;
  so.seed = seed;
  calib::RobotModel real = calib::perturbModel(controller, so);
  real.deviations.base_mm = Eigen::Vector3d(0.4, -0.3, 0.2);  // the cell registered to 0.5 mm
  real.deviations.base_rot_rad = Eigen::Vector3d(1e-4, -5e-5, 2e-4);
  const Compensator comp(controller, real);
  DensifyOptions o;
  o.tol_mm = tol_mm;
  Execution run;
  std::vector<PathSegment> commanded;
  Eigen::VectorXd q, q_start;
  for (const PathSegment& s : program) {
    const SegmentCompensation r = comp.segment(s, calib::Configuration{}, q, o);
    EXPECT_EQ(r.status, calib::IkStatus::kOk) << r.message;
    if (r.status != calib::IkStatus::kOk) return run;
    if (q_start.size() == 0) q_start = r.q_real_start;
    commanded.insert(commanded.end(), r.commanded.begin(), r.commanded.end());
    q = r.q_real_end.back();
    run.predicted_after_mm = std::max(run.predicted_after_mm, r.max_error_after_mm);
    run.points_added += r.points_added;
  }
  run.compensated_mm = maxPathDeviation(comp.execute(commanded, q_start, 0.1), program);
  // the program as it is: the controller starts from its own solution for the first point
  const calib::IkResult c0 = comp.controller().inverse(program.front().T_world_start, calib::Configuration{}, q_start, calib::IkOptions{});
  EXPECT_EQ(c0.status, calib::IkStatus::kOk);
  run.uncompensated_mm = maxPathDeviation(comp.execute(program, c0.q, 0.5), program);
  return run;
}

TEST(PathExecution, ShortSeamLinCircLin) {
  const std::vector<PathSegment> seam = shortSeam();
  for (const std::uint64_t seed : {1, 2, 3}) {
    const Execution r = execute(seam, seed, 0.05);
    EXPECT_LE(r.compensated_mm, 0.05 + 1e-3) << "seed " << seed;
    EXPECT_NEAR(r.compensated_mm, r.predicted_after_mm, 2e-3) << "seed " << seed;
    EXPECT_GT(r.uncompensated_mm, 0.5) << "seed " << seed;
  }
}

TEST(PathExecution, LongLinMovesAcrossTheWorkspace) {
  // 4.4 m of LIN across the workspace with 70-100 deg of reorientation per move
  std::vector<PathSegment> moves(3);
  moves[0].T_world_start = pose(900, -1100, 300, -30, 150, 10);
  moves[0].T_world_end = pose(1000, 1000, 700, 40, 120, -20);
  moves[1].T_world_start = moves[0].T_world_end;
  moves[1].T_world_end = pose(1250, 300, 1150, 0, 110, 30);
  moves[2].T_world_start = moves[1].T_world_end;
  moves[2].T_world_end = pose(700, -900, 900, -60, 170, 0);
  for (const std::uint64_t seed : {1, 4}) {
    const Execution r = execute(moves, seed, 0.05);
    EXPECT_LE(r.compensated_mm, 0.05 + 1e-3) << "seed " << seed;
    EXPECT_GT(r.points_added, 2) << "seed " << seed;
    EXPECT_GT(r.uncompensated_mm, 0.5) << "seed " << seed;
  }
  // a coarser tolerance: fewer points, still met
  const Execution coarse = execute(moves, 1, 0.2);
  EXPECT_LE(coarse.compensated_mm, 0.2 + 1e-3);
}


// The whole chain on a robot accura does not know: measure a simulated KR 16 (every geometric
// error and joint compliance; tracker noise 0.02 mm), identify it, compensate the seam with the
// identified model, and run the program on the true robot. The path error is bounded by the
// tolerance plus the identified model's own error along the path (the distance between the
// true and the identified tool at the joints the controller takes), and that model error is
// small; the uncompensated program is off by about a millimetre on the same robot.
TEST(PathExecution, IdentifiedModelOnTheTrueRobotWithinTolPlusTheModelError) {
  calib::RobotModel controller = test::loadBundled("kuka_kr16");
  controller.nominal.T_flange_tcp = calib::toIsometry({20, 0, 250, 0, -30, 0});  // the torch, measured at its TCP
  calib::SimulateOptions so;
  so.effects = {"geometric", "joint_compliance"};
  so.set_station = false;  // measured in the cell frame
  so.seed = 8;
  so.poses = 300;
  so.noise_mm = 0.02;
  const calib::RobotModel truth = calib::perturbModel(controller, so);
  const calib::MeasurementSet data = calib::simulateMeasurements(truth, so);
  calib::IdentifyOptions io;
  io.groups = {"geometric", "joint_compliance"};
  calib::IdentifySummary summary;
  const calib::RobotModel identified = calib::identify(controller, data, io, &summary);

  const std::vector<PathSegment> seam = shortSeam();
  const double tol = 0.05;
  const Compensator with_identified(controller, identified), with_truth(controller, truth);
  DensifyOptions o;
  o.tol_mm = tol;
  std::vector<PathSegment> commanded;
  Eigen::VectorXd q, q_start;
  for (const PathSegment& s : seam) {
    const SegmentCompensation r = with_identified.segment(s, calib::Configuration{}, q, o);
    ASSERT_EQ(r.status, calib::IkStatus::kOk) << r.message;
    if (q_start.size() == 0) q_start = r.q_real_start;
    commanded.insert(commanded.end(), r.commanded.begin(), r.commanded.end());
    q = r.q_real_end.back();
  }
  // the controller runs the commanded program once: the true tool and the identified model's
  // tool at the same joints, sample by sample
  const std::vector<Eigen::Isometry3d> on_truth = with_truth.execute(commanded, q_start, 0.1);
  const std::vector<Eigen::Isometry3d> on_model = with_identified.execute(commanded, q_start, 0.1);
  ASSERT_EQ(on_truth.size(), on_model.size());
  double model_error = 0;
  for (size_t k = 0; k < on_truth.size(); ++k)
    model_error = std::max(model_error, (on_truth[k].translation() - on_model[k].translation()).norm());
  const double deviation = maxPathDeviation(on_truth, seam);
  EXPECT_LE(deviation, tol + model_error + 1e-3);
  // the identification is good to about the noise (0.02 mm per axis): the model error is far
  // below the robot's own error, and so is the path error on the true robot
  EXPECT_LT(model_error, 0.1);
  EXPECT_LT(deviation, 0.15);
  const calib::IkResult c0 = with_truth.controller().inverse(seam.front().T_world_start, calib::Configuration{}, q_start, calib::IkOptions{});
  ASSERT_EQ(c0.status, calib::IkStatus::kOk);
  const double uncompensated = maxPathDeviation(with_truth.execute(seam, c0.q, 0.5), seam);
  EXPECT_GT(uncompensated, 0.5);
  EXPECT_GT(uncompensated, 8 * deviation);
  std::printf("identified model: fit RMS %.4f mm; on the true robot: path error %.4f mm (tol %.2f + model error %.4f), "
              "uncompensated %.3f mm\n",
              summary.fit.rms_mm, deviation, tol, model_error, uncompensated);
}

}  // namespace
}  // namespace accura
