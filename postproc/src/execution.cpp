// Simulated execution: the controller runs the commanded path with its nominal IK and the real
// robot goes where those joints put it (execution.h, Compensator::execute).
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/text.h"
#include "accura/postproc/compensate.h"
#include "accura/postproc/execution.h"
#include "path_geometry.h"

namespace accura::postproc {

using detail::PathGeometry;
using detail::sampleCount;

std::vector<Eigen::Isometry3d> Compensator::execute(const std::vector<PathSegment>& commanded,
                                                    const Eigen::VectorXd& q_controller_start, double step_mm,
                                                    const calib::PoseContext& context) const {
  if (!(step_mm > 0)) throw calib::ArgumentError("simulated execution: the step must be positive, got " + std::to_string(step_mm));
  std::vector<Eigen::Isometry3d> out;
  if (commanded.empty()) return out;
  calib::IkOptions o;
  o.singular_threshold = 0;  // the controller follows through near-singular poses
  o.tol_mm = 1e-5;
  o.tol_rad = 1e-8;
  Eigen::VectorXd q = q_controller_start;
  calib::IkWorkspace ws;  // each solve continues from the previous solution
  for (size_t k = 0; k < commanded.size(); ++k) {
    const PathGeometry g(commanded[k]);
    const int m = sampleCount(g, step_mm, 0.5);
    for (int i = (k == 0 ? 0 : 1); i <= m; ++i) {
      const Eigen::Isometry3d C = g.pose(static_cast<double>(i) / m);
      calib::IkResult failure;
      if (controller_.follow(C, calib::Configuration{}, q, o, calib::PoseContext{}, ws, &failure) != calib::IkStatus::kOk) {
        std::ostringstream s;
        s << "simulated execution: the controller cannot follow segment " << k + 1 << " at "
          << calib::formatFixed(g.length_mm * i / m, 4) << " mm: " << failure.message;
        throw calib::NumericalError(s.str());
      }
      out.push_back(real_.forward(q, context));
    }
  }
  return out;
}

std::vector<Eigen::Isometry3d> simulateExecution(const calib::RobotModel& controller, const calib::RobotModel& real,
                                                 const std::vector<PathSegment>& commanded,
                                                 const Eigen::VectorXd& q_start, double step_mm, double payload_kg) {
  calib::PoseContext ctx;
  ctx.payload_kg = payload_kg;
  const Compensator c(controller, real);
  Eigen::VectorXd q = q_start;
  if (q.size() == 0 && !commanded.empty()) {
    calib::IkOptions o;
    o.singular_threshold = 0;
    const calib::IkResult r = c.controller().inverse(commanded.front().T_world_start, calib::Configuration{}, Eigen::VectorXd(), o);
    if (r.status != calib::IkStatus::kOk)
      throw calib::NumericalError("simulated execution: the controller cannot reach the start: " + r.message);
    q = r.q;
  }
  return c.execute(commanded, q, step_mm, ctx);
}

}  // namespace accura::postproc
