#include "accura/calib/identify.h"
#include "accura/calib/kinematic_core.h"

#include <ceres/ceres.h>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include "accura/calib/errors.h"
#include "accura/calib/joint_map.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/text.h"
#include "identify_internal.h"

namespace accura::calib {

// Variance factor below which the stated stds are said to be too large: stds more than 10 times
// the residuals' scale (a factor 100 in variance).
constexpr double kStatedStdTooLargeVarianceFactor = 0.01;

using namespace identify_detail;

namespace identify_detail {
bool parseGroupSpec(const std::string& full_spec, std::string* name, std::set<int>* joints, std::string* error,
                    double* knot) {
  std::string spec = full_spec;
  if (knot) *knot = std::numeric_limits<double>::quiet_NaN();
  const size_t at = spec.find('@');
  if (at != std::string::npos) {
    if (spec.compare(0, 9, "joint_map") != 0) {
      *error = "parameter group '" + full_spec + "': only joint_map takes a knot spacing (@...)";
      return false;
    }
    double k = 0;
    std::string unit;
    if (!parseJointMapKnot(spec.substr(at + 1), &k, &unit, error)) {
      *error = "parameter group '" + full_spec + "': " + *error;
      return false;
    }
    if (knot) *knot = k;
    spec = spec.substr(0, at);
  }
  const size_t colon = spec.find(':');
  *name = spec.substr(0, colon);
  joints->clear();
  if (colon == std::string::npos) return true;
  std::string rest = spec.substr(colon + 1);
  size_t pos = 0;
  while (pos <= rest.size()) {
    const size_t plus = rest.find('+', pos);
    const std::string item = rest.substr(pos, plus == std::string::npos ? std::string::npos : plus - pos);
    int j = 0;
    // At most two digits: no robot has more than kMaxDof joints, and a longer number must not wrap.
    if (item.size() < 2 || item.size() > 3 || item[0] != 'j' ||
        item.find_first_not_of("0123456789", 1) != std::string::npos || (j = std::atoi(item.c_str() + 1)) < 1 ||
        j > kMaxDof) {
      *error = "parameter group '" + spec + "': expected joints as j1+j2+..., found '" + item + "'";
      return false;
    }
    joints->insert(j);
    if (plus == std::string::npos) break;
    pos = plus + 1;
  }
  return true;
}
}  // namespace identify_detail

bool IdentifyOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (groups.empty()) return fail("no parameter group given");
  std::set<std::string> known;
  for (const auto& g : parameterGroups()) known.insert(g.first);
  for (const auto& g : groups) {
    std::string name, why;
    std::set<int> joints;
    if (!parseGroupSpec(g, &name, &joints, &why)) return fail(why);
    if (!known.count(name)) {
      std::string list;
      for (const auto& k : parameterGroups()) list += (list.empty() ? "" : ", ") + k.first;
      return fail("unknown parameter group '" + name + "' (expected one of: " + list + ")");
    }
  }
  if (!(std::isnan(position_std_mm) || position_std_mm > 0))
    return fail("position_std_mm must be > 0, got " + std::to_string(position_std_mm));
  if (!(std::isnan(orientation_std_deg) || orientation_std_deg > 0))
    return fail("orientation_std_deg must be > 0, got " + std::to_string(orientation_std_deg));
  if (loss != "none" && loss != "huber" && loss != "cauchy")
    return fail("loss must be none, huber or cauchy, got '" + loss + "'");
  if (!(loss_scale > 0)) return fail("loss_scale must be > 0");
  if (!(dependence_tol > 0 && dependence_tol < 1)) return fail("dependence_tol must be in (0, 1)");
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (!(std::isnan(joint_map_knot) || (std::isfinite(joint_map_knot) && joint_map_knot > 0)))
    return fail("joint_map_knot must be > 0 (deg or mm), got " + std::to_string(joint_map_knot));
  if (!(std::isnan(joint_map_smoothing) || (std::isfinite(joint_map_smoothing) && joint_map_smoothing >= 0)))
    return fail("joint_map_smoothing must be >= 0, got " + std::to_string(joint_map_smoothing));
  return true;
}

std::string IdentifySummary::BriefReport() const {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "%s, %d iterations, cost %.6g -> %.6g, fit RMS %.4f mm (n=%d), %d parameters, "
                "condition number %.3g",
                termination.c_str(), iterations, initial_cost, final_cost, fit.rms_mm, fit.n,
                parameters_free, condition_number);
  return buf;
}

namespace {

/// The gross threshold of a set of position errors (mm): the larger of kGrossRowFloorMm and
/// kGrossRowMedianFactor times their median.
double grossThresholdMm(std::vector<double> errors, double* median_mm = nullptr) {
  if (errors.empty()) return std::numeric_limits<double>::infinity();
  std::nth_element(errors.begin(), errors.begin() + static_cast<std::ptrdiff_t>(errors.size() / 2), errors.end());
  const double median = errors[errors.size() / 2];
  if (median_mm) *median_mm = median;
  return std::max(kGrossRowFloorMm, kGrossRowMedianFactor * median);
}

}  // namespace

double registerFrame(RobotModel& model, const MeasurementSet& data, bool estimate_tool) {
  const size_t m = data.rows.size();
  if (m < 3) throw NumericalError("registration needs at least 3 measured points, got " + std::to_string(m));
  KinematicWorkspace ws;
  std::vector<Eigen::Isometry3d> F(m);  // T_base_flange
  for (size_t i = 0; i < m; ++i) F[i] = flangePose(model, data.rows[i].q, data.rows[i].context, ws);
  Eigen::Vector3d tool = model.T_flange_tcp().translation();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  // the rows that take part: all, then (robust) without the gross ones of the last pass
  std::vector<char> in(m, 1);
  for (int pass = 0; pass < 10; ++pass) {
    size_t n_in = 0;
    for (char c : in) n_in += c ? 1 : 0;
    const int rounds = estimate_tool ? 20 : 1;
    for (int round = 0; round < rounds; ++round) {
      // Kabsch: x_i = R p_i + t
      std::vector<Eigen::Vector3d> p(m);
      Eigen::Vector3d pc = Eigen::Vector3d::Zero(), xc = Eigen::Vector3d::Zero();
      for (size_t i = 0; i < m; ++i) {
        p[i] = F[i] * tool;
        if (!in[i]) continue;
        pc += p[i];
        xc += data.rows[i].p_world_mm;
      }
      pc /= double(n_in);
      xc /= double(n_in);
      Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
      for (size_t i = 0; i < m; ++i)
        if (in[i]) H += (p[i] - pc) * (data.rows[i].p_world_mm - xc).transpose();
      Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
      const Eigen::Vector3d sv = svd.singularValues();
      if (sv[1] <= 1e-9 * std::max(1.0, sv[0]))
        throw NumericalError("registration: the measured points are collinear (singular values " +
                             std::to_string(sv[0]) + ", " + std::to_string(sv[1]) +
                             " mm^2); measure poses spread over the workspace");
      Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
      if ((svd.matrixV() * svd.matrixU().transpose()).determinant() < 0) D(2, 2) = -1;
      R = svd.matrixV() * D * svd.matrixU().transpose();
      t = xc - R * pc;
      if (!estimate_tool) break;
      // tool point: minimise sum |R (R_fi tool + p_fi) + t - x_i|^2 (linear in tool)
      Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
      Eigen::Vector3d b = Eigen::Vector3d::Zero();
      for (size_t i = 0; i < m; ++i) {
        if (!in[i]) continue;
        const Eigen::Matrix3d Ai = R * F[i].linear();
        A += Ai.transpose() * Ai;
        b += Ai.transpose() * (data.rows[i].p_world_mm - t - R * F[i].translation());
      }
      const Eigen::Vector3d new_tool = A.ldlt().solve(b);
      const double change = (new_tool - tool).norm();
      tool = new_tool;
      if (change < 1e-9) break;
    }
    // the rows beyond kGrossRowFloorMm and three times the median error: registered again
    // without them until that set holds (a frame pulled by gross rows inflates every error,
    // and the median with them; rows within the floor always take part)
    std::vector<double> err(m);
    for (size_t i = 0; i < m; ++i) err[i] = (R * (F[i] * tool) + t - data.rows[i].p_world_mm).norm();
    double median = 0;
    grossThresholdMm(err, &median);
    const double limit = std::max(kGrossRowFloorMm, 3.0 * median);
    std::vector<char> next(m);
    size_t n_next = 0;
    for (size_t i = 0; i < m; ++i) n_next += (next[i] = err[i] <= limit ? 1 : 0);
    if (next == in || n_next < 3) break;
    in.swap(next);
  }
  // T_world_base = T_nom * Trans(base_mm) * Exp(base_rot)
  Eigen::Isometry3d T_wb = Eigen::Isometry3d::Identity();
  T_wb.linear() = R;
  T_wb.translation() = t;
  const Eigen::Isometry3d D = model.nominal.T_world_base.inverse() * T_wb;
  model.deviations.base_mm = D.translation();
  model.deviations.base_rot_rad = logSO3(D.linear());
  if (estimate_tool) {
    // T_flange_tcp = T_nom * Trans(tool_mm) * Exp(tool_rot): translation part only
    const Eigen::Isometry3d& Tn = model.nominal.T_flange_tcp;
    model.deviations.tool_mm = Tn.linear().transpose() * (tool - Tn.translation());
  }
  // With orientation data and a tool to estimate: the tool rotation as the chordal mean.
  bool all_orient = estimate_tool;
  for (const auto& row : data.rows) all_orient = all_orient && row.has_orientation;
  if (all_orient) {
    const Eigen::Isometry3d T_flange_toolnom_trans = [&] {
      Eigen::Isometry3d T = model.nominal.T_flange_tcp;
      T.translate(model.deviations.tool_mm);
      return T;
    }();
    Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
    for (size_t i = 0; i < m; ++i) {
      if (!in[i]) continue;
      const Eigen::Matrix3d R_pred = (T_wb * F[i] * T_flange_toolnom_trans).linear();
      S += R_pred.transpose() * data.rows[i].R_world_tcp.toRotationMatrix();
    }
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(S, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d D3 = Eigen::Matrix3d::Identity();
    if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) D3(2, 2) = -1;
    model.deviations.tool_rot_rad = logSO3(svd.matrixU() * D3 * svd.matrixV().transpose());
  }
  double s2 = 0;
  for (double e : positionErrors(model, data)) s2 += e * e;
  return std::sqrt(s2 / double(m));
}

std::vector<std::string> excludedRowWarnings(const std::vector<ExcludedRow>& rows, const std::string& from) {
  std::vector<std::string> out;
  for (size_t k = 0; k < rows.size() && k < 10; ++k) {
    const ExcludedRow& e = rows[k];
    out.push_back(e.file + ":" + std::to_string(e.line) + ": left out of " + from + ": its measured position lies " +
                  formatFixed(e.error_mm, 1) + " mm from the model's, more than " + formatFixed(kGrossRowFloorMm, 0) + " mm and " +
                  formatFixed(kGrossRowMedianFactor, 0) + " times the median row's " + formatFixed(e.median_mm, 3) +
                  " mm (a lost beam or a corrupted row?)");
  }
  if (rows.size() > 10) out.push_back("... and " + std::to_string(rows.size() - 10) + " more gross rows left out of " + from);
  return out;
}

std::vector<ExcludedRow> removeGrossRows(const RobotModel& model, MeasurementSet& data, bool register_frame,
                                         bool estimate_tool) {
  std::vector<ExcludedRow> out;
  if (data.rows.size() < static_cast<size_t>(kGrossRowsMinRows)) return out;
  RobotModel registered = model;
  if (register_frame) {
    try {
      registerFrame(registered, data, estimate_tool);
    } catch (const NumericalError&) {
      return out;  // (collinear points: the identification's own registration says so)
    }
  }
  const std::vector<double> err = positionErrors(registered, data);
  double median = 0;
  const double limit = grossThresholdMm(err, &median);
  MeasurementSet kept = data;
  kept.rows.clear();
  for (size_t i = 0; i < data.rows.size(); ++i) {
    if (err[i] <= limit) {
      kept.rows.push_back(data.rows[i]);
    } else {
      out.push_back({data.file, data.rows[i].line, err[i], median});
    }
  }
  if (out.size() > static_cast<size_t>(kGrossRowsAllowedAlways) &&
      double(out.size()) > kMaxGrossRowShare * double(data.rows.size()))
    throw InputError(data.file, out.front().line, 0,
                     "expected a few gross rows at most (a lost beam), found " + std::to_string(out.size()) + " of " +
                         std::to_string(data.rows.size()) + " rows more than " + formatFixed(limit, 1) +
                         " mm from the model (the median row: " + formatFixed(median, 3) + " mm; this one " +
                         formatFixed(out.front().error_mm, 1) + " mm" + (register_frame ? ", after registering the measurement frame" : "") +
                         "): a second station, robot or unit within one file? Give each station its own file");
  data.rows.swap(kept.rows);
  return out;
}

namespace {

// The groups of options.groups: name -> joints (1-based; empty: all), and the joint_map knot
// stated with '@' (NaN when none).
std::map<std::string, std::set<int>> parseGroups(const IdentifyOptions& options, double* map_knot) {
  std::map<std::string, std::set<int>> groups;
  *map_knot = std::numeric_limits<double>::quiet_NaN();
  for (const auto& g : options.groups) {
    std::string name, spec_error;
    std::set<int> joints;
    double knot = 0;
    parseGroupSpec(g, &name, &joints, &spec_error, &knot);  // validated by IsValid
    if (name == "geometric") {
      for (const char* s : {"base", "tool", "offsets", "lengths", "angles"}) groups[s] = joints;
    } else {
      groups[name] = joints;
    }
    if (name == "joint_map" && !std::isnan(knot)) *map_knot = knot;
  }
  return groups;
}

}  // namespace

namespace identify_detail {

bool allOrientation(const MeasurementSet& data) {
  return !data.rows.empty() &&
         std::all_of(data.rows.begin(), data.rows.end(), [](const Measurement& r) { return r.has_orientation; });
}

// The rows of every set in one set (flags: those all sets have) and the set of each row.
MeasurementSet combine(const std::vector<MeasurementSet>& sets, std::vector<int>* set_of_row) {
  MeasurementSet data = sets[0];
  data.rows.clear();
  set_of_row->clear();
  for (size_t s = 0; s < sets.size(); ++s) {
    const MeasurementSet& d = sets[s];
    if (s > 0) {
      data.file += ", " + d.file;
      data.has_orientation = data.has_orientation && d.has_orientation;
      data.has_std_position = data.has_std_position && d.has_std_position;
      data.has_std_orientation = data.has_std_orientation && d.has_std_orientation;
      data.has_weight = data.has_weight || d.has_weight;
    }
    for (const Measurement& r : d.rows) {
      data.rows.push_back(r);
      set_of_row->push_back(static_cast<int>(s));
    }
  }
  return data;
}

// One station per data set (station 0: the model's own), or one for all when `same`.
Stations stationsFor(const std::vector<int>& set_of_row, size_t sets, bool same) {
  Stations st;
  st.of_row.assign(set_of_row.size(), 0);
  if (!same) {
    st.of_row = set_of_row;
    st.extra = static_cast<int>(sets) - 1;
  }
  return st;
}

}  // namespace identify_detail

RobotModel identify(const RobotModel& start, const MeasurementSet& data,
                    const IdentifyOptions& options, IdentifySummary* summary_out) {
  return identify(start, std::vector<MeasurementSet>{data}, options, summary_out);
}

namespace {

// True when every weight of `b` is the same multiple of `a`'s (to 1e-12 relative): rows,
// components and dimensions alike.
bool sameUpToScale(const std::vector<RowWeights>& a, const std::vector<RowWeights>& b) {
  if (a.size() != b.size() || a.empty()) return false;
  const double c = b[0].w[0] / a[0].w[0];
  if (!(std::isfinite(c) && c > 0)) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i].dim != b[i].dim) return false;
    for (int k = 0; k < a[i].dim; ++k)
      if (!(std::abs(b[i].w[k] - c * a[i].w[k]) <= 1e-12 * std::abs(b[i].w[k]))) return false;
  }
  return true;
}

// The problem of `sets` for the groups asked for: coverage of the fit data, the joint maps on
// their covered intervals, the candidate parameters' layout, the stations.
Problem setUp(const RobotModel& start, const std::vector<MeasurementSet>& sets, const IdentifyOptions& options,
              std::map<std::string, std::set<int>>& groups, double stated_knot, IdentifySummary& summary) {
  Problem pb;
  pb.model = start;
  pb.data = combine(sets, &pb.set_of_row);
  pb.st = stationsFor(pb.set_of_row, sets.size(), options.same_station);
  pb.orientation = allOrientation(pb.data);
  RobotModel& model = pb.model;
  const MeasurementSet& data = pb.data;
  const bool orientation = pb.orientation;
  const bool want_map = groups.count("joint_map") > 0;
  const int n = model.dof();

  // Coverage of the fit data, per joint.
  summary.coverage = jointRanges(data, n);
  // Joint maps: on the covered interval of each mapped joint.
  if (want_map) {
    const std::set<int>& mj = groups["joint_map"];
    std::vector<int> mapped;  // the joints this run maps
    // the maps this run fits (not those held from the start model), on the dense part of the
    // covered interval (of one turn: values a turn apart are one angle), sized before they are made
    std::vector<JointRange> ranges;
    for (int j = 0; j < n; ++j) {
      if (!mj.empty() && !mj.count(j + 1)) continue;
      const JointRange& c = summary.coverage[static_cast<size_t>(j)];
      const bool revolute = model.nominal.joints[static_cast<size_t>(j)].type == JointType::kRevolute;
      const JointRange support = jointMapSupport(jointValues(data, j), kJointMapSupportWindow, jointMapPeriod(model, j));
      double width = 0;
      if (!jointMapCovers(c, support, 2 * stated_knot, &width)) {
        summary.warnings.push_back("joint_map: j" + std::to_string(j + 1) + " covers only " + fmtNum(width) +
                                   (revolute ? " deg" : " mm") +
                                   " in the fit data (less than two knot spacings; values a turn apart count once): no map for "
                                   "this joint");
        model.deviations.joint_map[static_cast<size_t>(j)] = JointMap{};
        continue;
      }
      mapped.push_back(j);
      ranges.push_back(support);
    }
    checkJointMapSize(ranges, stated_knot);
    for (size_t k = 0; k < mapped.size(); ++k)
      model.deviations.joint_map[static_cast<size_t>(mapped[k])] =
          makeJointMap(ranges[k].lower, ranges[k].upper, stated_knot, jointMapPeriod(model, mapped[k]));
  }
  // The candidate parameters: those of the requested groups (tool rotation only with
  // orientation data). Every other deviation stays as it is in `start` and is not part of
  // the problem (nor of the Jacobian).
  std::vector<ParamInfo>& layout = pb.layout;
  for (const ParamInfo& p : parameterLayout(model)) {
    auto g = groups.find(p.group);
    if (g == groups.end()) continue;
    if (!g->second.empty() && !g->second.count(p.joint + 1)) continue;
    if (!orientation && (p.kind == ParamKind::kToolRx || p.kind == ParamKind::kToolRy ||
                         p.kind == ParamKind::kToolRz))
      continue;
    layout.push_back(p);
  }
  pb.P = layout.size();
  pb.plan = makePlan(model, layout);
  pb.st.offset = pb.P;
  pb.X = pb.P + 6 * static_cast<size_t>(pb.st.extra);
  for (size_t k = 0; k < pb.P; ++k) pb.n_map += pb.isMap(k) ? 1 : 0;
  pb.sparse = pb.n_map > 0;
  const int n_candidates = static_cast<int>(pb.X);
  const int dim = pb.dim = orientation ? 6 : 3;
  const int m_eq = pb.m_eq = dim * static_cast<int>(data.rows.size());
  if (m_eq < n_candidates + 1) {
    throw InputError(data.file, 0, 0,
                     "too few rows for the parameters asked for: " + std::to_string(data.rows.size()) +
                         " rows give " + std::to_string(m_eq) + " equations, expected more than " +
                         std::to_string(n_candidates) + " (the number of parameters in " +
                         "the groups asked for); measure at least " +
                         std::to_string(n_candidates / dim + 1 + 1) + " poses, better 10 times as many");
  }
  // Repeats of one joint configuration (measurements.h: the definition diagnose's repeatability
  // uses, within one data set) add equations but no information about the geometry: the model
  // is determined by the distinct configurations, dim equations each.
  const int rows = static_cast<int>(data.rows.size());
  const int configurations = static_cast<int>(repeatedConfigurations(data, kRepeatTolerance, nullptr, &pb.set_of_row).size());
  summary.poses = rows;
  summary.configurations = configurations;
  summary.independent_equations = dim * configurations;
  // (without repeats the few-configurations warning below counts the poses themselves)
  const std::string counted =
      configurations < rows
          ? std::to_string(rows) + " poses hold only " + std::to_string(configurations) + " distinct joint configuration" +
                (configurations == 1 ? "" : "s") + " (the others repeat one: every joint within " + fmtNum(kRepeatTolerance) +
                " deg or mm, the same payload and directions), " + std::to_string(dim * configurations) + " independent equations"
          : std::to_string(rows) + " poses, each its own joint configuration: " + std::to_string(dim * configurations) +
                " independent equations";
  if (configurations < rows) {
    if (dim * configurations < n_candidates + 1)
      throw InputError(sets[0].file, 0, 0,
                       "too few distinct joint configurations for the parameters asked for: " + counted + ", expected more than " +
                           std::to_string(n_candidates) + " (the number of parameters in the groups asked for); repeats measure the "
                           "noise, not the geometry: the model would pass exactly through these configurations and be wrong "
                           "elsewhere. Measure at least " + std::to_string(n_candidates / dim + 2) +
                           " distinct configurations, better 10 times as many");
  }
  // fewer than 10 equations per parameter from distinct configurations: warned about whether
  // or not some rows repeat a configuration (README, "The command")
  summary.few_configurations = dim * configurations < kMinEquationsPerParameter * n_candidates;
  if (summary.few_configurations)
    summary.warnings.push_back(
        "few distinct joint configurations: " + counted + " for " + std::to_string(n_candidates) +
        " parameters, fewer than " + std::to_string(kMinEquationsPerParameter) +
        " per parameter. The parameters are fitted to the errors at these few configurations and may be far off on "
        "other poses; neither the fit RMS nor poses held out from these configurations can show it: validate on other "
        "configurations (--validate), and measure more distinct ones");
  return pb;
}

// The units a message that doubts them asks to check, where the user can fix them: those the
// mapping states (its unit keys with their lines) for an export read through one, else accura's.
std::string unitsToCheck(const MeasurementSet& set) {
  return set.units_stated.empty() ? "the units (positions in mm, joint angles in deg)" : "the units the mapping states (" + set.units_stated + ")";
}

// The RMS spread of points about their centre (mm).
double spreadRms(const std::vector<Eigen::Vector3d>& p) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& v : p) c += v;
  c /= double(p.size());
  double s2 = 0;
  for (const Eigen::Vector3d& v : p) s2 += (v - c).squaredNorm();
  return std::sqrt(s2 / double(p.size()));
}

// Whether positions `rms_mm` from the model after registration, with `spread_mm` of their own,
// are of no rigid frame (units or joint order wrong, another robot): the test registration()
// refuses a data set by.
bool ofNoFrame(double rms_mm, double spread_mm) { return rms_mm > 10.0 && rms_mm > 0.5 * spread_mm; }

// What to check when the measured positions are of no frame of the model (ofNoFrame): when the
// units read are wrong by a factor of a unit (positions in m read as mm or the reverse: 1000;
// joint angles in rad read as deg or the reverse: 180/pi), the factor found and the unit to
// change (the mapping's key and line, or how to convert accura's CSV); else unitsToCheck's list,
// the joint order and the robot file. The factors are tried on `set`, registered as
// registration() does; one is said when its registration passes the test the data failed and
// takes the RMS below half of `rms_mm`.
std::string unitsAdvice(const RobotModel& model, const MeasurementSet& set, bool estimate_tool, double rms_mm) {
  const std::string general = "check " + unitsToCheck(set) + ", the joint order and the robot file";
  if (set.rows.size() < 3) return general;
  const auto statedUnit = [&](const std::string& key) -> const MeasurementSet::StatedUnit* {
    for (const MeasurementSet::StatedUnit& u : set.units)
      if (u.key == key) return &u;
    return nullptr;
  };
  const MeasurementSet::StatedUnit* pos_key = statedUnit("position_unit");
  const MeasurementSet::StatedUnit* joint_key = statedUnit("joint_unit");
  const bool pos_in_m = pos_key && pos_key->unit == "m";
  const bool joints_in_rad = joint_key && joint_key->unit == "rad";
  // factors from what was read to the truth: positions (mm per mm read), revolute joints
  std::vector<double> pos_factors = {1.0}, joint_factors = {1.0};
  if (pos_in_m) pos_factors.push_back(1e-3);  // mm read as m (m read as km is no unit of an export)
  else pos_factors.insert(pos_factors.end(), {1e3, 1e-3});  // m, or um, read as mm
  const bool revolute = std::any_of(model.nominal.joints.begin(), model.nominal.joints.end(),
                                    [](const JointSpec& j) { return j.type == JointType::kRevolute; });
  if (revolute) joint_factors.push_back(joints_in_rad ? 1.0 / kRadToDeg : kRadToDeg);
  double best_rms = rms_mm, best_pos = 1, best_joint = 1;
  for (double fp : pos_factors)
    for (double fj : joint_factors) {
      if (fp == 1.0 && fj == 1.0) continue;
      MeasurementSet scaled = set;
      std::vector<Eigen::Vector3d> points;
      for (Measurement& r : scaled.rows) {
        r.p_world_mm *= fp;
        for (int j = 0; j < model.dof(); ++j)
          if (model.nominal.joints[static_cast<size_t>(j)].type == JointType::kRevolute) r.q[j] *= fj;
        points.push_back(r.p_world_mm);
      }
      RobotModel m = model;
      double rms = 0;
      try {
        rms = registerFrame(m, scaled, estimate_tool);
      } catch (const NumericalError&) {
        continue;
      }
      if (!ofNoFrame(rms, spreadRms(points)) && rms < 0.5 * rms_mm && rms < best_rms) {
        best_rms = rms;
        best_pos = fp;
        best_joint = fj;
      }
    }
  if (best_pos == 1.0 && best_joint == 1.0) return general;
  std::string found, change;
  if (best_pos != 1.0) {
    // the factor the data show: the measured points' spread over the model's points' (rigid
    // frames keep it; the tool point not yet fitted moves it by a few percent)
    std::vector<Eigen::Vector3d> measured, modelled;
    KinematicWorkspace ws;
    for (const Measurement& r : set.rows) {
      measured.push_back(r.p_world_mm);
      Eigen::VectorXd q = r.q;
      for (int j = 0; j < model.dof(); ++j)
        if (model.nominal.joints[static_cast<size_t>(j)].type == JointType::kRevolute) q[j] *= best_joint;
      modelled.push_back(forwardKinematics(model, q, r.context, ws).translation());
    }
    const double ratio = spreadRms(measured) / spreadRms(modelled);
    const std::string read = pos_in_m ? "m" : "mm";
    const std::string truth = best_pos * (pos_in_m ? 1000.0 : 1.0) == 1000.0 ? "m" : best_pos * (pos_in_m ? 1000.0 : 1.0) == 1.0 ? "mm" : "um";
    found = "the measured positions spread " + (ratio >= 1 ? formatFixed(ratio, 1) + " times as far as" : "1/" + formatFixed(1 / ratio, 1) + " as far as") +
            " the model's points: positions in " + truth + " read as " + read;
    if (pos_key && truth != "um")
      change = "change position_unit = " + pos_key->unit + " (" + pos_key->place + ") to " + truth;
    else if (truth == "m")
      change = "convert the positions to mm (times 1000; accura's CSV is in mm and deg, docs/measurement-format.md), or read the file "
               "through a mapping file with position_unit = m (docs/measurement-mapping.md)";
    else
      change = "convert the positions to mm (divided by 1000; accura reads mm or m)";
  }
  if (best_joint != 1.0) {
    const std::string truth = joints_in_rad ? "deg" : "rad", read = joints_in_rad ? "rad" : "deg";
    found += std::string(found.empty() ? "" : ", and ") + "the joint angles fit at " +
             (joints_in_rad ? "pi/180" : "180/pi") + " times the values read: angles in " + truth + " read as " + read;
    const std::string c = joint_key ? "change joint_unit = " + joint_key->unit + " (" + joint_key->place + ") to " + truth
                                    : "convert the joint angles to deg (times 180/pi; accura's CSV is in mm and deg, "
                                      "docs/measurement-format.md), or read the file through a mapping file with joint_unit = rad "
                                      "(docs/measurement-mapping.md)";
    change += (change.empty() ? "" : ", and ") + c;
  }
  return found + " (so converted, they lie " + formatFixed(best_rms, 1) + " mm RMS from the model's after registration): " + change;
}

// 1. Closed-form registration of the measurement frame (and the tool point) on the first
// station's rows; every further station registered in closed form against that model: into
// pb.model and the stations' part of pb.x.
void registration(Problem& pb, const std::vector<MeasurementSet>& sets, const IdentifyOptions& options,
                  const std::map<std::string, std::set<int>>& groups, IdentifySummary& summary) {
  RobotModel& model = pb.model;
  const MeasurementSet& data = pb.data;
  const Stations& st = pb.st;
  const size_t P = pb.P;
  std::vector<double>& x = pb.x;
  x.assign(pb.X, 0.0);
  const RobotModel unregistered = model;  // (unitsAdvice registers data in other units from it)
  {
    MeasurementSet first = data;
    first.rows.clear();
    for (size_t i = 0; i < data.rows.size(); ++i)
      if (st.of_row[i] == 0) first.rows.push_back(data.rows[i]);
    if (options.register_frame && groups.count("base")) registerFrame(model, first, groups.count("tool") > 0);
    for (int s = 1; s <= st.extra; ++s) {
      RobotModel other = model;
      registerFrame(other, sets[static_cast<size_t>(s)], false);
      const Eigen::Isometry3d Ts = other.T_world_base() * model.T_world_base().inverse();
      const Eigen::Vector3d w = logSO3(Ts.linear());
      const size_t o = P + 6 * static_cast<size_t>(s - 1);
      for (int k = 0; k < 3; ++k) {
        x[o + k] = Ts.translation()[k];
        x[o + 3 + k] = w[k];
      }
    }
    const MeasurementSet in0 = inStationZero(data, st, x);
    double s2 = 0;
    for (double e : positionErrors(model, in0)) s2 += e * e;
    summary.registration_rms_mm = std::sqrt(s2 / double(data.rows.size()));
    const bool base = groups.count("base") > 0;
    if ((options.register_frame || !base) && (sets.size() == 1 || st.extra == 0)) {
      // measurements of another robot, or in other units (positions in metres, joint angles in
      // radians): no rigid frame brings them within half their own spread of the model's (one
      // data set, or several told to share a station; several stations have their own test,
      // JointMap.SeveralDataSetsEachFromItsOwnStation). Without 'base' nothing registers the
      // frame: data in a tracker's frame lies metres from the model
      std::vector<Eigen::Vector3d> points;
      for (const Measurement& r : in0.rows) points.push_back(r.p_world_mm);
      const double spread = spreadRms(points);
      const bool no_frame = ofNoFrame(summary.registration_rms_mm, spread);
      if (no_frame && !base)
        throw InputError(sets[0].file, 0, 0,
                         "expected measurements in the model's world frame: the groups asked for have no 'base' to register the "
                         "measurement frame (the tracker's), and the measured positions lie " + formatFixed(summary.registration_rms_mm, 1) +
                             " mm RMS from the model's; add base (e.g. --params base," + options.groups.front() +
                             ", or geometric,...), or start from a model identified in this station");
      // several sets said to share a station: a nominal robot registered in the right frame is
      // within millimetres (the real UR10: 1.1 mm); tens of millimetres is two stations
      if (base && options.register_frame && summary.registration_rms_mm > kMaxSharedStationRmsMm && sets.size() > 1)
        throw InputError(sets[1].file, 0, 0,
                         "expected data sets that share one station (they were said to: --same-station): registered together, the "
                         "measured positions lie " + formatFixed(summary.registration_rms_mm, 1) + " mm RMS from the model's, more than " +
                             formatFixed(kMaxSharedStationRmsMm, 0) + " mm; give each its own station (leave out --same-station), or "
                             "check " + unitsToCheck(sets[1]) + " and the joint order");
      if (no_frame)
        throw InputError(sets[0].file, 0, 0,
                         "expected measurements of " + model.nominal.name + " in mm and deg: after the measurement frame is registered, the " +
                             "measured positions lie " + formatFixed(summary.registration_rms_mm, 1) + " mm RMS from the model's, more than " +
                             "half their own spread (" + formatFixed(spread, 1) + " mm RMS about their centre); " +
                             unitsAdvice(unregistered, sets[0], groups.count("tool") > 0, summary.registration_rms_mm));
    }
  }
}

}  // namespace

RobotModel identify(const RobotModel& start, const std::vector<MeasurementSet>& sets,
                    const IdentifyOptions& options, IdentifySummary* summary_out) {
  std::string why;
  if (!options.IsValid(&why)) throw ArgumentError("identify: " + why);
  if (sets.empty()) throw ArgumentError("identify: no data set given");
  for (const auto& d : sets)
    if (d.rows.empty()) throw InputError(d.file, 0, 0, "expected measured rows, found none");
  refuseSharedMeasurements(sets);  // the same data twice would count twice
  start.validate();
  double stated_knot = 0;
  std::map<std::string, std::set<int>> groups = parseGroups(options, &stated_knot);
  for (const auto& g : groups)
    for (int j : g.second)
      if (j > start.dof())
        throw ArgumentError("identify: parameter group '" + g.first + "': expected joints j1..j" +
                            std::to_string(start.dof()) + " of " + start.nominal.name + ", found j" + std::to_string(j));
  {
    // rows written twice (every measured value of an earlier row of the configuration): the same
    // measurement counts once, else it would count as independent evidence (the sigmas too small)
    // (the sets are copied only when one has such rows: identify runs many times in the diagnosis)
    if (std::any_of(sets.begin(), sets.end(), [](const MeasurementSet& d) { return !duplicatedRows(d).empty(); })) {
      std::vector<MeasurementSet> once = sets;
      std::vector<std::string> said;
      for (MeasurementSet& d : once)
        if (const std::string w = duplicatedRowsWarning(d.file, removeDuplicatedRows(d)); !w.empty()) said.push_back(w);
      const RobotModel out = identify(start, once, options, summary_out);
      if (summary_out) summary_out->warnings.insert(summary_out->warnings.begin(), said.begin(), said.end());
      return out;
    }
  }
  {
    // gross rows (a lost beam, a corrupted cell): left out of the fit and named; one alone
    // would pull the registration and every parameter by metres
    std::vector<MeasurementSet> screened = sets;
    std::vector<ExcludedRow> excluded;
    for (MeasurementSet& d : screened) {
      const std::vector<ExcludedRow> e =
          removeGrossRows(start, d, options.register_frame && groups.count("base") > 0, groups.count("tool") > 0);
      excluded.insert(excluded.end(), e.begin(), e.end());
    }
    if (!excluded.empty()) {
      const RobotModel out = identify(start, screened, options, summary_out);
      if (summary_out) {
        const std::vector<std::string> said = excludedRowWarnings(excluded, "the fit");
        summary_out->warnings.insert(summary_out->warnings.begin(), said.begin(), said.end());
        summary_out->excluded.insert(summary_out->excluded.begin(), excluded.begin(), excluded.end());
      }
      return out;
    }
  }
  if (std::isnan(stated_knot)) stated_knot = options.joint_map_knot;  // '@' overrides the option
  const bool want_map = groups.count("joint_map") > 0;
  if (want_map && (std::isnan(stated_knot) || std::isnan(options.joint_map_smoothing)))
    return identifyWithMapCv(start, sets, options, stated_knot, summary_out);

  IdentifySummary summary;
  Problem pb = setUp(start, sets, options, groups, stated_knot, summary);
  registration(pb, sets, options, groups, summary);
  for (size_t k = 0; k < pb.P; ++k) pb.x[k] = getParameter(pb.model.deviations, pb.layout[k]);
  pb.data0 = inStationZero(pb.data, pb.st, pb.x);  // refreshed after every solve

  // 2. Weights: the std columns, given stds or stds estimated from the residuals. Unmodelled
  // error: when the stds of the data (or given ones) explain the residuals badly, an additive
  // isotropic term tau is estimated per component type so that sum e^2 / (s^2 + tau^2) equals
  // its share of the redundancy (variance-component estimation); weights 1 / sqrt(s^2 + tau^2).
  Weighting weighting(pb, options);
  weighting.apply(pb);

  // 3. Identifiability at the starting point, the joint maps' regularisation rows.
  Eigen::VectorXd col_sq;
  const int kept = identifiability(pb, options, summary, &col_sq);
  const int p_free = kept + static_cast<int>(pb.n_map) + 6 * pb.st.extra;
  penaltyRows(pb, options.joint_map_smoothing, col_sq);
  {
    Eigen::VectorXd r0;
    pb.stack(nullptr, &r0);
    summary.initial_cost = 0.5 * r0.squaredNorm();
  }

  // 4. Solve; with variance components: solve, re-estimate from the residuals, solve again.
  // Joint maps are fitted after the other parameters, to what those leave: stage 1 holds the
  // maps at zero, stage 2 everything else (docs/diagnosis.md, "Joint maps"; fitted together, the
  // maps and the geometry trade their slow parts, and the geometry no longer carries over to
  // joint ranges the data did not cover). The covariance is the joint one (section 5).
  const bool robust = options.loss != "none";
  int iterations = 0;  // of every solve, the weighting rounds' included (from initial_cost to final_cost)
  const std::vector<bool> free_all = pb.free;
  bool others_free = false;
  for (size_t k = 0; k < pb.X; ++k) others_free = others_free || (free_all[k] && !pb.isMap(k));
  const bool staged = pb.n_map > 0 && others_free;
  SolveResult res;
  for (int stage = staged ? 1 : 0; stage <= (staged ? 2 : 0); ++stage) {
    int stage_free = p_free;
    if (staged) {
      for (size_t k = 0; k < pb.X; ++k) pb.free[k] = free_all[k] && (pb.isMap(k) == (stage == 2));
      if (stage == 1) stage_free = kept + 6 * pb.st.extra;
    }
    // the maps' smoothness and centring relative to the weights they are solved with
    const bool maps_free = pb.n_map > 0 && stage != 1;
    if (maps_free && stage == 2) refreshPenaltyRows(pb, options.joint_map_smoothing);
    // solved: pb.x is the solution at the weights in force. A re-estimate that scales every
    // row's weights by one factor leaves it there (the least-squares optimum of c r is that of
    // r; not so with a robust loss, whose threshold is in weighted units, or with penalty rows,
    // scaled on their own): the next solve would only confirm it, with a step of ~1e-15
    // relative (a single variance component: positions alone from one station, no stds, or
    // equal stds), and is not run.
    bool solved = false;
    if (weighting.estimate_pos || weighting.estimate_rot || options.model_error) {
      for (int round = 0; round < 4; ++round) {
        if (!solved) {
          res = solve(pb, options, robust);
          iterations += res.iterations;
        }
        const std::vector<RowWeights> before = pb.weights;
        const double change = weighting.reestimate(pb, options, stage_free);
        weighting.apply(pb);
        if (maps_free) refreshPenaltyRows(pb, options.joint_map_smoothing);
        // (only after a solve that converged: one stopped by its iteration limit goes on)
        solved = !robust && pb.penalties.empty() && res.termination.rfind("CONVERGENCE", 0) == 0 && sameUpToScale(before, pb.weights);
        if (change < 0.01) break;
      }
    }
    if (!solved) {
      res = solve(pb, options, robust);
      iterations += res.iterations;
    }
    if (res.failure) throw NumericalError("identification failed: " + res.message);
  }
  pb.free = free_all;
  summary.termination = res.termination;
  summary.iterations = iterations;
  weighting.describe(pb, summary);

  // 5. Uncertainties at the solution, the summary's diagnostics.
  Eigen::VectorXd r;
  uncertainties(pb, options, robust, summary, &r);
  summary.fit = evaluate(pb.model, pb.data0);
  if (summary.fit.has_orientation && summary.fit.rot_rms_deg > kImplausibleOrientationRmsDeg && summary.fit.rms_mm < 10.0) {
    char buf[400];
    std::snprintf(buf, sizeof buf,
                  "the orientations fit to %.3g deg RMS (max %.3g deg) while the positions fit to %.3g mm: no robot is off by "
                  "degrees after identification; the orientation data is likely read in another convention or unit than it "
                  "was written in (a mapping's 'orientation' and 'orientation_unit'), or is another frame's. Check it, or fit "
                  "the positions only",
                  summary.fit.rot_rms_deg, summary.fit.rot_max_deg, summary.fit.rms_mm);
    summary.warnings.push_back(buf);
  }
  // stated stds far above what the residuals show: most often given in another unit (a std of
  // 20 mm where 0.02 mm, or micrometres, were meant). They weigh positions against orientations
  // and scale nothing else: the sigmas follow the residuals (the variance factor).
  if (summary.variance_factor > 0 && summary.variance_factor < kStatedStdTooLargeVarianceFactor && summary.fit.rms_mm > 0) {
    char buf[400];
    std::snprintf(buf, sizeof buf,
                  "the stated stds are about %.0f times what the residuals show (variance factor %.2g; position RMS %.4g mm after "
                  "the fit): check their unit (mm for positions, deg for angles: --std-mm, --std-deg or the std columns); they "
                  "weigh positions against orientations, the parameters' sigmas follow the residuals",
                  1.0 / std::sqrt(summary.variance_factor), summary.variance_factor, summary.fit.rms_mm);
    summary.warnings.push_back(buf);
  }
  // a periodic term fitted on less than half a turn is an extrapolation over the rest of the
  // joint's range where its limits reach beyond the data (the diagnosis does not select it
  // there: periodicTermHoldsOverLimits): said, with the range
  if (const auto g = groups.find("gear_periodic"); g != groups.end())
    for (int j = 0; j < pb.model.dof(); ++j) {
      const JointRange& c = summary.coverage[static_cast<size_t>(j)];
      if ((!g->second.empty() && !g->second.count(j + 1)) || pb.model.nominal.joints[static_cast<size_t>(j)].type != JointType::kRevolute)
        continue;
      if (!periodicTermHoldsOverLimits(pb.model.nominal.joints[static_cast<size_t>(j)], c.lower, c.upper))
        summary.warnings.push_back("gear_periodic j" + std::to_string(j + 1) + ": fitted on " + fmtNum(c.upper - c.lower) + " deg (" +
                                   fmtNum(c.lower) + ".." + fmtNum(c.upper) +
                                   "), less than half a turn: its harmonics are extrapolated over the rest of the joint's range, "
                                   "where they may make the model worse than without them");
    }
  finishSummary(pb, sets, r, options.joint_map_smoothing, &summary);
  if (!robust) {
    // gross outliers (a joint glitch, a wrong target: far beyond the noise, below the 50 mm of a
    // row left out as gross) pull every parameter of a least-squares fit: said, with the remedy
    std::vector<const SuspiciousRow*> gross;
    for (const SuspiciousRow& row : summary.suspicious)
      if (row.normalised > kGrossOutlierSigmas) gross.push_back(&row);
    if (!gross.empty()) {
      double lo = gross[0]->normalised, hi = lo, elo = gross[0]->error_mm, ehi = elo;
      std::string rows;
      for (size_t k = 0; k < gross.size(); ++k) {
        lo = std::min(lo, gross[k]->normalised);
        hi = std::max(hi, gross[k]->normalised);
        elo = std::min(elo, gross[k]->error_mm);
        ehi = std::max(ehi, gross[k]->error_mm);
        if (k < 10) rows += (k ? ", " : "") + gross[k]->file + ":" + std::to_string(gross[k]->line);
      }
      if (gross.size() > 10) rows += ", ...";
      const auto range = [](double a, double b, int digits) {
        return a == b ? formatFixed(a, digits) : formatFixed(a, digits) + " to " + formatFixed(b, digits);
      };
      summary.warnings.push_back(std::to_string(gross.size()) + " row(s) lie more than " + formatFixed(kGrossOutlierSigmas, 0) +
                                 " robust standard deviations from the fitted model (normalised residual " + range(lo, hi, 1) +
                                 ", position error " + range(elo, ehi, 3) + " mm; " + rows +
                                 "): gross outliers (a joint glitch, a wrong target, a lost beam's last point) that a least-squares "
                                 "fit (--loss none, the default) follows with every parameter. Check those rows, or fit with --loss "
                                 "huber, which down-weights them");
    }
  }
  // the fitted ranges belong to the model when it learnt something beyond the frames
  const bool robot_parameters = std::any_of(pb.layout.begin(), pb.layout.end(),
                                            [](const ParamInfo& p) { return p.group != "base" && p.group != "tool"; });
  if (robot_parameters) pb.model.deviations.fit_range = summary.coverage;
  // a joint that never moves: the model holds at its angle only (said, with what was fixed for
  // it: the parameters of its link and the next one's)
  if (robot_parameters)
    for (const HeldJoint& h : heldJoints(pb.data, pb.model.nominal, kRepeatTolerance)) {
      std::string fixed;
      for (const FixedParameter& f : summary.fixed)
        for (int j : {h.joint + 1, h.joint + 2})
          if (f.name.rfind("j" + std::to_string(j) + "_", 0) == 0) fixed += (fixed.empty() ? "" : ", ") + f.name;
      summary.warnings.push_back(heldJointWarning(pb.model.nominal, h, pb.data.rows.size(), kRepeatTolerance, fixed));
    }
  if (summary_out) *summary_out = summary;
  return pb.model;
}

RobotModel registerStation(const RobotModel& model, const MeasurementSet& data,
                           IdentifySummary* summary) {
  IdentifyOptions o;
  o.groups = {"base"};
  return identify(model, data, o, summary);
}

}  // namespace accura::calib
