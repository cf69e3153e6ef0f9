// A run of LIN / CIRC motions compensated from a start pose (see path_job.h).
#include "accura/postproc/path_job.h"

#include "accura/calib/errors.h"
#include "accura/calib/ik.h"

namespace accura::postproc {

void enforceConfiguration(const calib::Configuration& asked, PoseCompensation& pc) {
  if (pc.status != calib::IkStatus::kOk || !pc.configuration_changed) return;
  if (calib::onlyTurnBitsNearZeroDiffer(asked, pc.configuration, pc.q_real)) return;
  pc.status = calib::IkStatus::kNoConfiguration;
  pc.message = "reachable only with " + calib::configurationMismatch(asked, pc.configuration);
}

PoseCompensation compensateTarget(const Compensator& comp, const Eigen::Isometry3d& T_world_tcp, const calib::Configuration& asked,
                                  const Eigen::VectorXd& seed, const JobSettings& settings) {
  const bool reads = controllerReadsConfiguration(settings.calibrated.nominal);
  const calib::Configuration config = askedConfiguration(reads, asked, seed.size() > 0);
  PoseCompensation pc = comp.pose(T_world_tcp, config, seed, settings.ik, settings.context);
  if (reads) {
    enforceConfiguration(config, pc);
  } else if (pc.status == calib::IkStatus::kOk) {  // a UR: the S/T reached, nothing to carry
    pc.configuration_changed = false;
    pc.message.clear();
  }
  return pc;
}

SegmentCompensation compensateSegmentFrom(const Compensator& comp, PathSegment& intended, const calib::Configuration& config,
                                          const Eigen::VectorXd& q_real, const JobSettings& settings) {
  intended.T_world_start = comp.real().forward(q_real, settings.context);
  DensifyOptions dens = settings.densify;
  dens.tol_mm = settings.tol_mm;
  dens.ik = settings.ik;
  return comp.segment(intended, config, q_real, dens, settings.context);
}

PathCompensation compensatePath(const Compensator& comp, const Eigen::Isometry3d& T_world_start, const calib::Configuration& start_config,
                                const std::vector<PathSegment>& motions, const JobSettings& settings) {
  PathCompensation r;
  r.start = compensateTarget(comp, T_world_start, start_config, Eigen::VectorXd(), settings);
  if (r.start.status != calib::IkStatus::kOk) return r;
  Eigen::VectorXd q = r.start.q_real;
  for (size_t i = 0; i < motions.size(); ++i) {
    r.intended.push_back(motions[i]);
    try {
      r.segments.push_back(compensateSegmentFrom(comp, r.intended.back(), calib::Configuration{}, q, settings));
    } catch (const calib::NumericalError& e) {  // the motion's own geometry (no circle through a CIRC's points)
      r.failed_motion = static_cast<int>(i);
      r.numerical_error = e.what();
      return r;
    }
    const SegmentCompensation& sc = r.segments.back();
    if (sc.status != calib::IkStatus::kOk || sc.commanded.empty() || sc.q_real_end.size() != sc.commanded.size()) {
      r.failed_motion = static_cast<int>(i);
      return r;
    }
    q = sc.q_real_end.back();
  }
  return r;
}

}  // namespace accura::postproc
