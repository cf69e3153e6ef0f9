// accura: joint maps without a stated knot spacing or smoothness (identify_internal.h): fit
// without maps, choose both by blocked cross-validation on the problem linearised there, then
// identify with them.
#include <algorithm>
#include <cmath>
#include <set>

#include "accura/calib/geometry.h"
#include "accura/calib/joint_map.h"
#include "identify_internal.h"

namespace accura::calib::identify_detail {

RobotModel identifyWithMapCv(const RobotModel& start, const std::vector<MeasurementSet>& sets,
                             const IdentifyOptions& options, double stated_knot, IdentifySummary* summary_out) {
  IdentifyOptions o0 = options;
  o0.groups.clear();
  std::set<int> map_joints;
  for (const auto& g : options.groups) {
    std::string name, err;
    std::set<int> joints;
    parseGroupSpec(g, &name, &joints, &err);
    if (name == "joint_map") map_joints = joints;
    else o0.groups.push_back(g);
  }
  if (o0.groups.empty()) o0.groups = {"base"};
  IdentifySummary s0;
  const RobotModel m0 = identify(start, sets, o0, &s0);

  const std::vector<double> knots = std::isnan(stated_knot) ? jointMapKnotCandidates() : std::vector<double>{stated_knot};
  const std::vector<double> smoothings = std::isnan(options.joint_map_smoothing)
                                             ? jointMapSmoothingCandidates()
                                             : std::vector<double>{options.joint_map_smoothing};
  const double widest = *std::max_element(knots.begin(), knots.end());
  std::vector<int> cv_joints;
  std::vector<JointRange> ranges;  // the maps' intervals, as identify makes them (jointMapSupport)
  std::vector<double> periods;     // and their periods (jointMapPeriod)
  std::vector<int> set_of_row;
  const MeasurementSet data = combine(sets, &set_of_row);
  for (int j = 0; j < m0.dof(); ++j) {
    if (!map_joints.empty() && !map_joints.count(j + 1)) continue;
    const JointRange& c = s0.coverage[static_cast<size_t>(j)];
    if (c.upper - c.lower < 2 * widest) continue;  // (before the support is computed)
    const double period = jointMapPeriod(m0, j);
    const JointRange support = jointMapSupport(jointValues(data, j), kJointMapSupportWindow, period);
    if (!jointMapCovers(c, support, 2 * widest)) continue;
    cv_joints.push_back(j);
    periods.push_back(period);
    ranges.push_back(support);
  }
  for (const double knot : knots) checkJointMapSize(ranges, knot);  // before the cross-validation's dense solves
  IdentifyOptions o1 = options;
  o1.groups.clear();
  for (const auto& g : options.groups) o1.groups.push_back(g.substr(0, g.find('@')));
  JointMapCvResult cv;
  if (cv_joints.empty()) {
    cv.knot = knots[0];
    cv.smoothing = smoothings[0];
  } else {
    // the linearised problem at m0: its free parameters, the stations, a unit dtheta per joint
    std::vector<ParamInfo> L;
    std::set<std::string> free_names;
    for (const auto& p : s0.parameters) free_names.insert(p.name);
    for (const ParamInfo& p : parameterLayout(m0))
      if (free_names.count(p.name)) L.push_back(p);
    const size_t P0 = L.size();
    for (int j : cv_joints) {
      const bool revolute = m0.nominal.joints[static_cast<size_t>(j)].type == JointType::kRevolute;
      L.push_back({revolute ? ParamKind::kOffset : ParamKind::kD, j, "map_unit", "joint_map", "", 1.0});
    }
    Stations st = stationsFor(set_of_row, sets.size(), options.same_station);
    st.offset = L.size();
    std::vector<double> x(L.size() + 6 * static_cast<size_t>(st.extra), 0.0);
    for (size_t k = 0; k < L.size(); ++k) x[k] = getParameter(m0.deviations, L[k]);
    for (int s = 1; s <= st.extra; ++s) {
      const Eigen::Isometry3d Ts = s0.T_world_base_per_set[static_cast<size_t>(s)] * m0.T_world_base().inverse();
      const Eigen::Vector3d w = logSO3(Ts.linear());
      for (int k = 0; k < 3; ++k) {
        x[st.offset + 6 * static_cast<size_t>(s - 1) + static_cast<size_t>(k)] = Ts.translation()[k];
        x[st.offset + 6 * static_cast<size_t>(s - 1) + 3 + static_cast<size_t>(k)] = w[k];
      }
    }
    const bool orientation = allOrientation(data);
    const int dim = orientation ? 6 : 3;
    const double pos_std = std::isfinite(s0.position_std_mm) ? s0.position_std_mm : 0;
    const double rot_std = std::isfinite(s0.orientation_std_deg) ? s0.orientation_std_deg * kDegToRad : 0;
    const double tau_p = s0.model_error_mm, tau_r = s0.model_error_deg * kDegToRad;
    std::vector<size_t> set_size(sets.size(), 0), seen(sets.size(), 0);
    for (int s : set_of_row) ++set_size[static_cast<size_t>(s)];
    const int folds = 5;
    const JacobianPlan plan = makePlan(m0, L);
    std::vector<JointMapCvRow> rows(data.rows.size());
    RowStack stack(m0, plan, st);
    const Eigen::Index nG = static_cast<Eigen::Index>(P0) + 6 * st.extra, nJ = static_cast<Eigen::Index>(cv_joints.size());
    for (size_t i = 0; i < data.rows.size(); ++i) {
      const Measurement& m = data.rows[i];
      Vector6d w;
      for (int k = 0; k < 6; ++k) {
        const double sd = k < 3 ? (data.has_std_position ? m.std_mm[k] : pos_std)
                                : (data.has_std_orientation ? m.std_rot_deg[k - 3] * kDegToRad : rot_std);
        const double tau = k < 3 ? tau_p : tau_r;
        w[k] = std::sqrt(m.weight) / std::sqrt(std::max(sd * sd + tau * tau, 1e-300));
      }
      const Eigen::Isometry3d T = stack.pose(x, m, i, true);
      const Eigen::MatrixXd& Jrow = stack.J();
      JointMapCvRow& row = rows[i];
      const auto W = w.head(dim).asDiagonal();
      row.G.resize(dim, nG);
      row.G.leftCols(static_cast<Eigen::Index>(P0)) = W * Jrow.topLeftCorner(dim, static_cast<Eigen::Index>(P0));
      if (st.extra > 0) row.G.rightCols(6 * st.extra) = W * Jrow.topRightCorner(dim, 6 * st.extra);
      row.U = W * Jrow.block(0, static_cast<Eigen::Index>(P0), dim, nJ);
      row.r = w.head(dim).cwiseProduct(rowError(T, m, dim).head(dim));
      row.q.resize(nJ);
      for (Eigen::Index j = 0; j < nJ; ++j) row.q[j] = m.q[cv_joints[static_cast<size_t>(j)]];
      row.w_pos = w.head<3>();
      const size_t s = static_cast<size_t>(set_of_row[i]);
      row.fold = static_cast<int>(folds * seen[s]++ / set_size[s]);
    }
    std::vector<int> harmonics;
    for (int j : cv_joints)
      harmonics.push_back(m0.nominal.joints[static_cast<size_t>(j)].type == JointType::kRevolute ? kJointMapCentredHarmonics : 0);
    cv = crossValidateJointMap(rows, ranges, periods, harmonics, knots, smoothings, folds);
  }
  o1.joint_map_knot = cv.knot;
  o1.joint_map_smoothing = cv.smoothing;
  const RobotModel m1 = identify(start, sets, o1, summary_out);
  if (summary_out) {
    summary_out->joint_map_cv = cv.table;
    summary_out->joint_map_cv_baseline_mm = cv.baseline_rms_mm;
    summary_out->joint_map_cv_knots_not_tried = cv.knots_not_tried;
  }
  return m1;
}

}  // namespace accura::calib::identify_detail
