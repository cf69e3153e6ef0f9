// accura: the fits of the diagnosis: noise floor, baseline, candidate columns, linearised and exact held-out errors (diagnose.h, docs/diagnosis.md).
#include "diagnose_internal.h"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <set>

#include "accura/calib/errors.h"
#include "accura/calib/identify.h"
#include "accura/calib/joint_map.h"
#include "accura/calib/kinematics.h"
#include "dense_linalg.h"
#include "identify_internal.h"

namespace accura::calib {
namespace diagnose_detail {

IdentifyOptions Diagnoser::baselineOptions() const {
  IdentifyOptions io;
  io.groups = {"geometric"};
  // weights: the std columns, else the noise floor when known, else identify's variance components
  if (!fit_.has_std_position && out_.noise_floor_known) io.position_std_mm = out_.noise_std_axis_mm;
  return io;
}

MeasurementSet Diagnoser::fitWithOrientation() const {
  MeasurementSet six = fit_;
  six.has_orientation = true;
  six.has_std_orientation = fit_has_std_rot_;
  for (int i = 0; i < m_; ++i) six.rows[static_cast<size_t>(i)].has_orientation = rot_ok_[static_cast<size_t>(i)];
  return six;
}

void Diagnoser::baseline() {
  IdentifySummary s;
  M0_ = identify(start_, use_rot_ ? fitWithOrientation() : fit_, baselineOptions(), &s);
  robust_w_.assign(static_cast<size_t>(m_), 1.0);
  addJointMaps();
  layout_ = parameterLayout(M0_);
  std::set<std::string> free;
  for (const ParameterEstimate& p : s.parameters) free.insert(p.name);
  for (size_t k = 0; k < layout_.size(); ++k)
    if (free.count(layout_[k].name)) {
      G_.push_back(static_cast<int>(cols_.size()));
      cols_.push_back(static_cast<int>(k));
    }
  if (!fit_.has_std_position && !out_.noise_floor_known) {
    // weights from the baseline's variance-component estimate (uniform: only their ratio matters)
    for (size_t i = 0; i < w_fit_.size(); ++i) w_fit_[i].setConstant(rowComponentWeight(fit_.rows[i].weight, s.position_std_mm, 0));
    if (has_val_)
      for (size_t i = 0; i < w_val_.size(); ++i) w_val_[i].setConstant(rowComponentWeight(val_.rows[i].weight, s.position_std_mm, 0));
  } else if (use_rot_ && fit_.has_std_position && s.model_error_mm > 0) {
    // 6D data whose std columns explain the residual badly: the baseline's unmodelled-error term
    // joins every row's std, as identify weights (1 / sqrt(std^2 + tau^2) per axis), so that
    // positions and orientations weigh in the fits as they do in identify's
    auto weigh = [&](const MeasurementSet& set, std::vector<Eigen::Vector3d>* w) {
      for (size_t i = 0; i < w->size(); ++i)
        for (int k = 0; k < 3; ++k) (*w)[i][k] = rowComponentWeight(set.rows[i].weight, set.rows[i].std_mm[k], s.model_error_mm);
    };
    weigh(fit_, &w_fit_);
    if (has_val_ && val_.has_std_position) weigh(val_, &w_val_);
  }
  // the orientation rows' weights (1/rad), as identify's: the std columns or the std it
  // estimated, with its unmodelled-error term
  w_rot_.assign(static_cast<size_t>(m_), Eigen::Vector3d::Zero());
  noise_rot_.assign(static_cast<size_t>(m_), Eigen::Vector3d::Zero());
  if (use_rot_) {
    const double tau_rad = s.model_error_deg * kDegToRad;
    for (int i = 0; i < m_; ++i) {
      const Measurement& r = fit_.rows[static_cast<size_t>(i)];
      if (!rot_ok_[static_cast<size_t>(i)]) continue;
      const Eigen::Vector3d sd = fit_has_std_rot_ && r.std_rot_deg.allFinite()
                                     ? Eigen::Vector3d(r.std_rot_deg * kDegToRad)
                                     : Eigen::Vector3d::Constant(s.orientation_std_deg * kDegToRad);
      const Eigen::Array3d v = sd.array().square() + tau_rad * tau_rad;
      if (!(v > 0).all()) continue;  // no std to weigh with: the row's orientation is left out
      for (int k = 0; k < 3; ++k) w_rot_[static_cast<size_t>(i)][k] = rowComponentWeight(r.weight, sd[k], tau_rad);
      noise_rot_[static_cast<size_t>(i)] = sd;
    }
  }
}

void Diagnoser::addJointMaps() {
  map_knot_ = 0;
  if (std::find(o_.effects.begin(), o_.effects.end(), "joint_map") == o_.effects.end()) return;
  const int n = M0_.dof();
  const std::vector<JointRange> range = jointRanges(fit_, n);
  double widest = 0;
  for (const JointRange& c : range) widest = std::max(widest, c.upper - c.lower);
  // at least about 10 fit poses per coefficient of the widest joint's map
  double knot = o_.joint_map_knot;
  const double max_intervals = std::max(4.0, double(m_) / 10.0 - 3.0);
  if (widest / knot > max_intervals) knot = std::ceil(2.0 * widest / max_intervals) / 2.0;
  if (M0_.deviations.joint_map.size() != static_cast<size_t>(n)) M0_.deviations.joint_map.assign(static_cast<size_t>(n), JointMap{});
  bool any = false;
  for (int j = 0; j < n; ++j) {
    const JointRange& c = range[static_cast<size_t>(j)];
    const bool rev = M0_.nominal.joints[static_cast<size_t>(j)].type == JointType::kRevolute;
    const std::string jn = "j" + std::to_string(j + 1);
    if (!M0_.deviations.joint_map[static_cast<size_t>(j)].empty()) {
      effect_note_["joint_map:" + jn] = "joint_map " + jn + ": the starting model already has a map of this joint (kept as it is)";
      continue;
    }
    const double period = jointMapPeriod(M0_, j);
    const JointRange support = jointMapSupport(jointValues(fit_, j), kJointMapSupportWindow, period);
    double width = 0;  // values a turn apart count once
    if (!jointMapCovers(c, support, 4 * knot, &width)) {
      effect_note_["joint_map:" + jn] = "joint_map " + jn + ": the fit data cover " + fmtg("%.3g", width) +
                                        (rev ? " deg" : " mm") + ", less than 4 knot spacings of " + fmtg("%.3g", knot) +
                                        ": no map";
      continue;
    }
    M0_.deviations.joint_map[static_cast<size_t>(j)] = makeJointMap(support.lower, support.upper, knot, period);
    any = true;
  }
  if (any) map_knot_ = knot;
  else effect_note_["joint_map"] = "not testable: no joint is covered over 4 knot spacings by the fit data";
}

// The joint maps' regularisation, as identify has it (joint_map.h): second differences weighted
// sqrt(smoothing) * scale, centring rows (no constant, trend or first harmonic over the fit
// data) weighted kJointMapCentringWeight * scale, scale the RMS weighted norm of the map's
// columns; expressed in the scaled columns.
void Diagnoser::mapPenalty() {
  const Eigen::Index C = static_cast<Eigen::Index>(cols_.size());
  penalty_ = Eigen::MatrixXd::Zero(C, C);
  is_map_.assign(static_cast<size_t>(C), false);
  for (const Block& b : blocks_) {
    if (b.effect != "joint_map" || b.cols.empty()) continue;
    const JointMap& jm = M0_.deviations.joint_map[static_cast<size_t>(b.joint)];
    const int K = static_cast<int>(jm.coef.size());
    std::vector<int> col(static_cast<size_t>(K), -1);
    double s2 = 0;
    for (int c : b.cols) {
      col[static_cast<size_t>(layout_[cols_[c]].index)] = c;
      s2 += colscale_[c] * colscale_[c];
      is_map_[static_cast<size_t>(c)] = true;
    }
    const double scale = std::sqrt(s2 / double(b.cols.size()));
    Eigen::MatrixXd Pk = Eigen::MatrixXd::Zero(K, K);
    auto add = [&](const std::vector<double>& a, double weight) {
      const Eigen::VectorXd v = weight * Eigen::Map<const Eigen::VectorXd>(a.data(), K);
      Pk.noalias() += v * v.transpose();
    };
    if (o_.joint_map_smoothing > 0)
      for (const auto& a : jointMapSmoothnessRows(jm)) add(a, std::sqrt(o_.joint_map_smoothing) * scale);
    const std::vector<double> qj = jointValues(fit_, b.joint);
    const bool rev = M0_.nominal.joints[static_cast<size_t>(b.joint)].type == JointType::kRevolute;
    for (const auto& a : jointMapCentringRows(jm, qj, rev ? kJointMapCentredHarmonics : 0)) {
      double nrm = 0;
      for (double v : a) nrm += v * v;
      if (nrm > 0) add(a, kJointMapCentringWeight * scale / std::sqrt(nrm));
    }
    for (const auto& a : jointMapSparseRows(jm, qj)) add(a, kJointMapSparseWeight * scale);
    for (int k = 0; k < K; ++k)
      for (int l = 0; l < K; ++l)
        if (col[static_cast<size_t>(k)] >= 0 && col[static_cast<size_t>(l)] >= 0)
          penalty_(col[static_cast<size_t>(k)], col[static_cast<size_t>(l)]) =
              Pk(k, l) / (colscale_[col[static_cast<size_t>(k)]] * colscale_[col[static_cast<size_t>(l)]]);
  }
}

// Robust estimation (IRLS, two passes): Huber weights from the residual of the richest model
// (the geometric baseline plus every testable effect, linearised), so that a catalogued effect
// does not hide a gross outlier; the baseline is refitted with them and the linearisation
// rebuilt at it.
void Diagnoser::robust() {
  if (!(o_.robust_k > 0) || blocks_.empty()) return;
  std::vector<double> w0;
  for (const Measurement& r : fit_.rows) w0.push_back(r.weight);
  const std::vector<Eigen::Vector3d> wf0 = w_fit_, wr0 = w_rot_;
  std::vector<int> all(blocks_.size());
  std::iota(all.begin(), all.end(), 0);
  for (int pass = 0; pass < 2; ++pass) {
    const std::vector<int> S = withBlocks(all);
    Eigen::VectorXd x;
    if (!solveStaged(A_(S, S), b_(S), mapMask(S), nullptr, &x)) return;
    const Eigen::VectorXd e = rF_ - JF_(Eigen::all, S) * x;
    std::vector<double> mag(static_cast<size_t>(m_));
    for (int i = 0; i < m_; ++i) mag[static_cast<size_t>(i)] = e.segment(3 * i, 3).norm();
    robustWeights(mag);
    bool changed = false;
    for (int i = 0; i < m_; ++i) {
      const double w = w0[static_cast<size_t>(i)] * robust_w_[static_cast<size_t>(i)];
      changed = changed || w != fit_.rows[static_cast<size_t>(i)].weight;
      fit_.rows[static_cast<size_t>(i)].weight = w;
      w_fit_[static_cast<size_t>(i)] = wf0[static_cast<size_t>(i)] * std::sqrt(robust_w_[static_cast<size_t>(i)]);
      w_rot_[static_cast<size_t>(i)] = wr0[static_cast<size_t>(i)] * std::sqrt(robust_w_[static_cast<size_t>(i)]);
    }
    if (!changed) break;
    M0_ = identify(M0_, use_rot_ ? fitWithOrientation() : fit_, baselineOptions(), nullptr);
    linearise();
  }
}

// Candidate columns of the effects: testable ones, per (effect, joint) block.
void Diagnoser::columns() {
  auto both = [&](auto pred) { return pred(fit_) && (!has_val_ || pred(val_)); };
  auto range = [&](const MeasurementSet& set, auto value) {
    double lo = 1e300, hi = -1e300;
    for (const Measurement& r : set.rows) {
      lo = std::min(lo, value(r));
      hi = std::max(hi, value(r));
    }
    return hi - lo;
  };
  for (const std::string& e : o_.effects) {
    std::string why;
    if (e == "thermal") {
      if (!both([](const MeasurementSet& s) { return s.has_temperature; })) why = "the data has no temp_c column";
      else if (range(fit_, [](const Measurement& r) { return r.context.temp_c; }) < 0.5)
        why = "the temperature varies by less than 0.5 K over the fit data";
    }
    if (e == "backlash" && !both([](const MeasurementSet& s) { return s.has_direction; }))
      why = "the data has no dir1..dirN columns";
    if (e == "joint_compliance") {
      // the deflection is compliance * the joint's gravity torque: of the links' masses and the payload
      const bool links = std::any_of(M0_.nominal.joints.begin(), M0_.nominal.joints.end(), [](const JointSpec& j) { return j.mass_kg > 0; });
      const auto payload = [](const MeasurementSet& s) {
        return std::any_of(s.rows.begin(), s.rows.end(), [](const Measurement& r) { return r.context.payload_kg > 0; });
      };
      if (!links && !payload(fit_) && !(has_val_ && payload(val_)))
        why = "the robot's links have no mass (mass_kg 0 on every joint: a URDF without <inertial>) and no pose carries a payload: "
              "no gravity torque loads the joints, so there is nothing for a compliance to deflect (give the links' masses, or "
              "measure with payloads)";
    }
    if (!why.empty()) {
      effect_note_[e] = "not testable: " + why;
      continue;
    }
    out_.effects_tested.push_back(e);
    std::map<int, Block> by_joint;
    for (size_t k = 0; k < layout_.size(); ++k) {
      const ParamInfo& p = layout_[k];
      if (p.group != e) continue;
      if (e == "backlash") {
        // both directions must occur for the joint
        bool plus = false, minus = false;
        for (const Measurement& r : fit_.rows) (r.context.dir[static_cast<size_t>(p.joint)] > 0 ? plus : minus) = true;
        if (!(plus && minus)) continue;
      }
      Block& b = by_joint[p.joint];
      b.effect = e;
      b.joint = p.joint;
      b.cols.push_back(static_cast<int>(cols_.size()));
      cols_.push_back(static_cast<int>(k));
    }
    for (auto& kv : by_joint) blocks_.push_back(kv.second);
  }
}

namespace {
// dst += s0 a + s1 b + s2 c over len entries (the arrays do not overlap: vectorised)
inline void axpy3(double* __restrict dst, const double* __restrict a, const double* __restrict b,
                  const double* __restrict c, double s0, double s1, double s2, int len) {
  for (int t = 0; t < len; ++t) dst[t] += s0 * a[t] + s1 * b[t] + s2 * c[t];
}

// Copies the strict lower triangle of a square matrix to its upper one.
void mirrorLower(Eigen::MatrixXd* A) {
  const Eigen::Index n = A->rows();
  for (Eigen::Index c = 1; c < n; ++c)
    for (Eigen::Index r = 0; r < c; ++r) (*A)(r, c) = (*A)(c, r);
}
}  // namespace

void Diagnoser::linearise() {
  eval_cache_.clear();
  const int C = static_cast<int>(cols_.size());
  std::vector<ParamInfo> sub;
  for (int c : cols_) sub.push_back(layout_[c]);
  // identify's residual stacking (unit weights; with 6D data the orientation rows too), measured minus model
  const identify_detail::JacobianPlan plan = identify_detail::makePlan(M0_, sub);
  auto build = [&](const MeasurementSet& set, Eigen::MatrixXd* J, Eigen::VectorXd* r, int dim) {
    identify_detail::Stations st;
    st.of_row.assign(set.rows.size(), 0);
    identify_detail::RowStack stack(M0_, plan, st);
    identify_detail::RowWeights unit;
    unit.dim = dim;
    stack.stack(std::vector<double>(sub.size(), 0.0), set, std::vector<identify_detail::RowWeights>(set.rows.size(), unit), J, r);
    *r = -*r;
  };
  Eigen::MatrixXd JF, JR;
  if (use_rot_) {
    // 6 rows a pose: the position's 3 (mm), the orientation's 3 (rad; the fit rows keep their
    // measured orientation, a row without one has no weight)
    Eigen::MatrixXd J6;
    Eigen::VectorXd r6;
    build(fit_, &J6, &r6, 6);
    JF.resize(3 * m_, J6.cols());
    JR.resize(3 * m_, J6.cols());
    rF_.resize(3 * m_);
    rR_.resize(3 * m_);
    for (int i = 0; i < m_; ++i) {
      JF.middleRows(3 * i, 3) = J6.middleRows(6 * i, 3);
      JR.middleRows(3 * i, 3) = J6.middleRows(6 * i + 3, 3);
      rF_.segment<3>(3 * i) = r6.segment<3>(6 * i);
      rR_.segment<3>(3 * i) = r6.segment<3>(6 * i + 3);
    }
  } else {
    build(fit_, &JF, &rF_, 3);
    JR.resize(0, JF.cols());
    rR_.resize(0);
  }
  wF_.resize(3 * m_);
  for (int i = 0; i < m_; ++i) wF_.segment(3 * i, 3) = w_fit_[i];
  wR_.resize(JR.rows());
  for (Eigen::Index i = 0; i < JR.rows() / 3; ++i) wR_.segment(3 * i, 3) = w_rot_[static_cast<size_t>(i)];
  equations_ = 3.0 * m_;
  for (Eigen::Index k = 0; k < wR_.size(); ++k) equations_ += wR_[k] > 0 ? 1.0 : 0.0;
  // weighted column norms over every row: scale, and screen zero / dependent columns
  Eigen::MatrixXd Jw(JF.rows() + JR.rows(), JF.cols());
  Jw << wF_.asDiagonal() * JF, wR_.asDiagonal() * JR;
  const Eigen::Index R = Jw.rows();
  Eigen::VectorXd norms = Jw.colwise().norm();
  double gmax = 0;
  for (int c : G_) gmax = std::max(gmax, norms[c]);
  // orthonormal basis of the geometric columns
  Eigen::MatrixXd Gs(R, static_cast<Eigen::Index>(G_.size()));
  for (size_t k = 0; k < G_.size(); ++k) Gs.col(static_cast<Eigen::Index>(k)) = Jw.col(G_[k]) / norms[G_[k]];
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(Gs);
  Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(R, Gs.cols());
  std::vector<bool> keep(static_cast<size_t>(C), true);
  // a block's columns kept so far, orthonormalised against Q and each other
  size_t widest_block = 0;
  for (const Block& b : blocks_) widest_block = std::max(widest_block, b.cols.size());
  Eigen::MatrixXd E(R, static_cast<Eigen::Index>(widest_block));
  for (Block& b : blocks_) {
    Eigen::Index ne = 0;
    std::vector<int> kept;
    if (b.effect == "joint_map") {
      // a map moves the measured point by its joint's lever arm: none worth a map within 10 mm of
      // the axis (the same rule as the spectrum); its dependence on the geometric parameters (the
      // constant, trend and first harmonic) is removed by the centring penalty, not by screening
      // the basis functions sum to 1 and their squares to 1/4..1 at every q: the columns' summed
      // squares over the poses are the squared lever arms within that factor
      double lever2 = 0;
      for (int c : b.cols) lever2 += JF.col(c).squaredNorm() / double(m_);
      const bool rev = M0_.nominal.joints[static_cast<size_t>(b.joint)].type == JointType::kRevolute;
      if (rev && lever2 < 25.0) {
        effect_note_[b.effect + ":j" + std::to_string(b.joint + 1)] =
            "joint_map j" + std::to_string(b.joint + 1) + ": the measured point lies within about 10 mm of the axis (about " +
            fmtg("%.3g", std::sqrt(lever2)) + " mm): a map of it has no effect on these measurements";
        b.cols.clear();
        continue;
      }
      for (int c : b.cols)
        if (norms[c] > 1e-12 * std::max(gmax, 1e-300)) kept.push_back(c);
      b.cols = kept;
      continue;
    }
    for (int c : b.cols) {
      const std::string& name = layout_[cols_[c]].name;
      if (!(norms[c] > 1e-12 * std::max(gmax, 1e-300))) {
        keep[static_cast<size_t>(c)] = false;
        effect_note_[b.effect + ":" + name] = name + " has no effect on these measurements";
        continue;
      }
      Eigen::VectorXd v = Jw.col(c) / norms[c];
      for (int pass = 0; pass < 2; ++pass) {
        v -= Q * (Q.transpose() * v);
        if (ne > 0) v -= E.leftCols(ne) * (E.leftCols(ne).transpose() * v);
      }
      const double rho = v.norm();
      if (rho < 1e-3) {
        keep[static_cast<size_t>(c)] = false;
        effect_note_[b.effect + ":" + name] =
            name + " cannot be told from the geometric parameters (relative residual " + fmtg("%.2g", rho) + ")";
        continue;
      }
      E.col(ne++) = v / rho;
      kept.push_back(c);
    }
    b.cols = kept;
  }
  blocks_.erase(std::remove_if(blocks_.begin(), blocks_.end(), [](const Block& b) { return b.cols.empty(); }),
                blocks_.end());
  colscale_ = norms.cwiseMax(1e-300);
  JF_ = JF * colscale_.cwiseInverse().asDiagonal();
  JR_ = JR * colscale_.cwiseInverse().asDiagonal();
  mapPenalty();
  row_nz_.assign(static_cast<size_t>(m_), {});
  for (int i = 0; i < m_; ++i)
    for (Eigen::Index c = 0; c < JF_.cols(); ++c)
      if (!is_map_[static_cast<size_t>(c)] || JF_.middleRows(3 * i, 3).col(c).squaredNorm() > 0)
        row_nz_[static_cast<size_t>(i)].push_back(static_cast<int>(c));
  A_ = Eigen::MatrixXd::Zero(JF_.cols(), JF_.cols());
  b_ = Eigen::VectorXd::Zero(JF_.cols());
  std::vector<int> all(static_cast<size_t>(m_));
  std::iota(all.begin(), all.end(), 0);
  addNormal(all, &A_, &b_);
  mirrorLower(&A_);
  A_ += penalty_;
  if (use_rot_) {
    mF_.resize(wF_.size());
    mR_.resize(wR_.size());
    for (int i = 0; i < m_; ++i) {
      mF_.segment<3>(3 * i) = wF_.segment<3>(3 * i).array().square() * noise_fit_[static_cast<size_t>(i)].array();
      mR_.segment<3>(3 * i) = wR_.segment<3>(3 * i).array().square() * noise_rot_[static_cast<size_t>(i)].array();
    }
    Bm_ = Eigen::MatrixXd::Zero(A_.rows(), A_.cols());
    addNormal(all, &Bm_, nullptr, true);
    mirrorLower(&Bm_);
  }
  rr_ = wF_.cwiseProduct(rF_).squaredNorm() + wR_.cwiseProduct(rR_).squaredNorm();
  if (has_val_) {
    build(val_, &JV_, &rV_, 3);
    JV_ = JV_ * colscale_.cwiseInverse().asDiagonal();
  }
}

// The held-out schemes of the final linearisation (after robust(), which relinearises).
void Diagnoser::schemes() {
  eval_cache_.clear();
  if (!has_val_) buildScheme(&interleaved_);
  blockedSchemes();
}

// A row's non-zero columns come in runs of consecutive columns (the parametric ones, and per
// joint the few map coefficients near its angle): the products are taken run by run, each
// column of the lower triangle as three contiguous multiply-adds.
void Diagnoser::addNormal(const std::vector<int>& poses, Eigen::MatrixXd* A, Eigen::VectorXd* b, bool meat) const {
  const Eigen::Index C = JF_.cols();
  const int blocks = use_rot_ ? 2 : 1;  // a pose's 3-row blocks: position, orientation
  const Eigen::MatrixXd* Js[2] = {&JF_, &JR_};
  const Eigen::VectorXd* rs[2] = {&rF_, &rR_};
  const Eigen::VectorXd* ws[2] = {meat ? &mF_ : &wF_, meat ? &mR_ : &wR_};
  if (std::all_of(poses.begin(), poses.end(), [&](int i) { return static_cast<Eigen::Index>(row_nz_[static_cast<size_t>(i)].size()) == C; })) {
    // every column of every row (no maps): one symmetric rank update of the weighted rows
    Eigen::MatrixXd Jw(3 * blocks * static_cast<Eigen::Index>(poses.size()), C);
    Eigen::VectorXd rw(Jw.rows());
    for (size_t k = 0; k < poses.size(); ++k)
      for (int t = 0; t < blocks; ++t) {
        const Eigen::Index r = 3 * (blocks * static_cast<Eigen::Index>(k) + t), i3 = 3 * static_cast<Eigen::Index>(poses[k]);
        Jw.middleRows(r, 3) = ws[t]->segment<3>(i3).asDiagonal() * Js[t]->middleRows(i3, 3);
        rw.segment<3>(r) = ws[t]->segment<3>(i3).cwiseProduct(rs[t]->segment<3>(i3));
      }
    detail::addGramLower(*A, Jw);
    if (b) b->noalias() += Jw.transpose() * rw;
    return;
  }
  struct Run {
    int col, off, len;  // first column, its place in the row's non-zero list, length
  };
  std::vector<Run> runs;
  Eigen::Matrix<double, Eigen::Dynamic, 3> W(C, 3);  // the row's weighted non-zero columns
  double* const a0 = A->data();
  const Eigen::Index lda = A->rows();
  for (int i : poses) {
    const std::vector<int>& nz = row_nz_[static_cast<size_t>(i)];
    const int n = static_cast<int>(nz.size());
    runs.clear();
    for (int a = 0; a < n; ++a) {
      if (!runs.empty() && nz[static_cast<size_t>(a)] == runs.back().col + runs.back().len) ++runs.back().len;
      else runs.push_back({nz[static_cast<size_t>(a)], a, 1});
    }
    for (int t = 0; t < blocks; ++t) {
      Eigen::Vector3d ri;
      for (int k = 0; k < 3; ++k) {
        const double w = (*ws[t])[3 * i + k];
        ri[k] = w * (*rs[t])[3 * i + k];
        for (int a = 0; a < n; ++a) W(a, k) = w * (*Js[t])(3 * i + k, nz[static_cast<size_t>(a)]);
      }
      if (b)
        for (int a = 0; a < n; ++a) (*b)[nz[static_cast<size_t>(a)]] += W(a, 0) * ri[0] + W(a, 1) * ri[1] + W(a, 2) * ri[2];
      const double* w0 = &W(0, 0);
      const double* w1 = &W(0, 1);
      const double* w2 = &W(0, 2);
      for (size_t ra = 0; ra < runs.size(); ++ra)
        for (int a = 0; a < runs[ra].len; ++a) {
          const int ia = runs[ra].off + a;
          const double s0 = w0[ia], s1 = w1[ia], s2 = w2[ia];
          double* const col = a0 + static_cast<Eigen::Index>(runs[ra].col + a) * lda;
          for (size_t rb = ra; rb < runs.size(); ++rb) {
            const int first = rb == ra ? a : 0;  // the lower triangle only
            const int ib = runs[rb].off + first;
            double* const dst = col + runs[rb].col + first;
            const int len = runs[rb].len - first;
            axpy3(dst, w0 + ib, w1 + ib, w2 + ib, s0, s1, s2, len);
          }
        }
    }
  }
}

// Per-fold training systems of a scheme: the whole system minus the sums over the fold's rows.
void Diagnoser::buildScheme(Scheme* sc) const {
  const Eigen::Index C = JF_.cols();
  sc->At.assign(sc->poses.size(), Eigen::MatrixXd::Zero(C, C));
  sc->bt.assign(sc->poses.size(), Eigen::VectorXd::Zero(C));
  for (size_t f = 0; f < sc->poses.size(); ++f) {
    Eigen::MatrixXd& At = sc->At[f];
    addNormal(sc->poses[f], &At, &sc->bt[f]);
    mirrorLower(&At);
    At = A_ - At;
    sc->bt[f] = b_ - sc->bt[f];
  }
}

// The schemes that mimic new data: contiguous blocks of each joint's angle (the poses sorted by
// q_j, cut into blocked_folds equal parts: each fold extrapolates to a joint range the training
// did not see), of the pose order (drift, a later session) and, with several data sets from
// their own stations, each data set held out in turn (a new station, session and range: what
// `identify --validate-station new` sees; reregister() places the held-out set's station).
void Diagnoser::blockedSchemes() {
  blocked_.clear();
  const int K = o_.blocked_folds;
  if (K < 2 || m_ < 2 * K) return;
  if (own_stations_) {
    Scheme sc;
    sc.name = "data sets";
    for (int i = 0; i < m_; ++i) {
      const size_t s = static_cast<size_t>(set_of_row_[static_cast<size_t>(i)]);
      if (sc.poses.size() <= s) sc.poses.resize(s + 1);
      sc.poses[s].push_back(i);
    }
    sc.poses.erase(std::remove_if(sc.poses.begin(), sc.poses.end(), [](const std::vector<int>& f) { return f.empty(); }),
                   sc.poses.end());
    if (sc.poses.size() > 1) {
      buildScheme(&sc);
      blocked_.push_back(std::move(sc));
    }
  }
  auto cut = [&](const std::vector<int>& order, const std::string& name, int folds) {
    Scheme sc;
    sc.name = name;
    sc.poses.assign(static_cast<size_t>(folds), {});
    for (int k = 0; k < m_; ++k)
      sc.poses[static_cast<size_t>(static_cast<long>(k) * folds / m_)].push_back(order[static_cast<size_t>(k)]);
    if (name != "pose order" && folds > 2) sc.end_folds = {0, folds - 1};
    buildScheme(&sc);
    blocked_.push_back(std::move(sc));
  };
  std::vector<int> order(static_cast<size_t>(m_));
  std::iota(order.begin(), order.end(), 0);
  cut(order, "pose order", K);
  for (int j = 0; j < M0_.dof(); ++j) {
    std::vector<int> by = order;
    std::stable_sort(by.begin(), by.end(), [&](int a, int b) { return fit_.rows[a].q[j] < fit_.rows[b].q[j]; });
    if (!(fit_.rows[by.back()].q[j] - fit_.rows[by.front()].q[j] > 1e-6)) continue;
    cut(by, "q" + std::to_string(j + 1) + " blocks", K);
    cut(by, "q" + std::to_string(j + 1) + " halves", 2);  // train on one half, predict the other
  }
}

bool solveSpd(const Eigen::MatrixXd& M, const Eigen::VectorXd& v, Eigen::LLT<Eigen::MatrixXd>* llt,
              Eigen::VectorXd* x) {
  llt->compute(M);
  if (llt->info() != Eigen::Success) return false;
  const Eigen::VectorXd diag = llt->matrixLLT().diagonal();
  // columns are scaled to unit norm: a pivot below 1e-7 means a condition number above 1e14
  if (!(diag.minCoeff() > 1e-7 * diag.maxCoeff())) return false;
  *x = llt->solve(v);
  return x->allFinite();
}

bool solveStaged(const Eigen::MatrixXd& M, const Eigen::VectorXd& v, const std::vector<bool>& is_map,
                 Eigen::LLT<Eigen::MatrixXd>* llt, Eigen::VectorXd* x) {
  std::vector<Eigen::Index> P, Q;
  for (size_t k = 0; k < is_map.size(); ++k) (is_map[k] ? Q : P).push_back(static_cast<Eigen::Index>(k));
  Eigen::LLT<Eigen::MatrixXd> own;
  if (P.empty() || Q.empty()) return solveSpd(M, v, llt ? llt : &own, x);
  // the joint factorisation when asked for: the leverages and the covariance (the staged
  // estimate's are close to the joint one's: the maps' columns are free of what the others hold)
  if (llt && !solveSpd(M, v, llt, x)) return false;
  Eigen::LLT<Eigen::MatrixXd> stage;
  Eigen::VectorXd xp, xq;
  if (!solveSpd(M(P, P), v(P), &stage, &xp)) return false;
  if (!solveSpd(M(Q, Q), v(Q) - M(Q, P) * xp, &stage, &xq)) return false;
  x->resize(M.rows());
  (*x)(P) = xp;
  (*x)(Q) = xq;
  return true;
}

std::vector<int> Diagnoser::trainingRows(int f) const {
  std::vector<int> rows;
  for (int i = 0; i < m_; ++i)
    if (fold_[i] != f) rows.push_back(i);
  return rows;
}

std::vector<bool> Diagnoser::mapMask(const std::vector<int>& S) const {
  std::vector<bool> m;
  for (int c : S) m.push_back(is_map_[static_cast<size_t>(c)]);
  return m;
}

Diagnoser::Eval Diagnoser::evaluate(const std::vector<int>& S, bool leverage) const {
  // the selection, ranking, confounding and shrink steps ask for some column sets again
  const auto key = std::make_pair(S, leverage);
  const auto hit = eval_cache_.find(key);
  if (hit != eval_cache_.end()) return hit->second;
  return eval_cache_[key] = evaluateUncached(S, leverage);
}

Diagnoser::Eval Diagnoser::evaluateUncached(const std::vector<int>& S, bool leverage) const {
  Eval ev;
  const Eigen::MatrixXd AS = A_(S, S);  // the normal equations of the blocks in S
  const Eigen::VectorXd bS = b_(S);
  Eigen::LLT<Eigen::MatrixXd> llt;
  Eigen::VectorXd x;
  if (has_val_) {
    if (!solveStaged(AS, bS, mapMask(S), &llt, &x)) return ev;
    const Eigen::MatrixXd JS = JV_(Eigen::all, S);
    const Eigen::VectorXd e = rV_ - JS * x;
    ev.d.resize(nv_);
    for (int i = 0; i < nv_; ++i) ev.d[i] = e.segment(3 * i, 3).squaredNorm();
    if (leverage && use_rot_) {
      sandwichLeverage(llt, JS, Bm_(S, S), &ev.lev);
    } else if (leverage) {
      ev.lev.resize(nv_);
      for (int i = 0; i < nv_; ++i)
        ev.lev[i] = llt.matrixL().solve(Eigen::MatrixXd(JS.middleRows(3 * i, 3).transpose())).squaredNorm();
    }
  } else {
    return cvEval(S, interleaved_, leverage);
  }
  ev.ok = true;
  return ev;
}

// Held-out squared errors by cross-validation over the scheme's folds (linearised at M0).
Diagnoser::Eval Diagnoser::cvEval(const std::vector<int>& S, const Scheme& scheme, bool leverage) const {
  Eval ev;
  const Eigen::Index s = static_cast<Eigen::Index>(S.size());
  Eigen::LLT<Eigen::MatrixXd> llt;
  Eigen::VectorXd x;
  const Eigen::MatrixXd JS = leverage ? Eigen::MatrixXd(JF_(Eigen::all, S)) : Eigen::MatrixXd();
  Eigen::VectorXd x_all = Eigen::VectorXd::Zero(JF_.cols());  // x on every column (0 outside S)
  ev.d.resize(m_);
  if (leverage) ev.lev.resize(m_);
  for (size_t f = 0; f < scheme.poses.size(); ++f) {
    // the fold's training system on the columns S
    const Eigen::MatrixXd& At = scheme.At[f];
    Eigen::MatrixXd M(s, s);
    Eigen::VectorXd v(s);
    for (Eigen::Index c = 0; c < s; ++c) {
      const double* src = At.data() + static_cast<Eigen::Index>(S[c]) * At.rows();
      double* dst = M.data() + c * s;
      for (Eigen::Index a = 0; a < s; ++a) dst[a] = src[S[a]];
      v[c] = scheme.bt[f][S[c]];
    }
    // blocked schemes (not the interleaved folds): a map coefficient the training rows do not fully reach (less
    // than 90% of its weight in the fit data) is zero, as a fitted map is outside the range its
    // data cover, not the smoothness penalty's extrapolation of a few rows at the edge
    std::vector<Eigen::Index> act;
    for (Eigen::Index a = 0; a < s; ++a) {
      const double data = A_(S[a], S[a]) - penalty_(S[a], S[a]);
      if (!(&scheme != &interleaved_ && is_map_[static_cast<size_t>(S[a])] && At(S[a], S[a]) - penalty_(S[a], S[a]) < 0.9 * data))
        act.push_back(a);
    }
    {
      Eigen::VectorXd xa;
      std::vector<bool> mp;
      for (Eigen::Index a : act) mp.push_back(is_map_[static_cast<size_t>(S[a])]);
      if (!solveStaged(M(act, act), v(act), mp, leverage ? &llt : nullptr, &xa)) return ev;
      x = Eigen::VectorXd::Zero(s);
      x(act) = xa;
    }
    x_all(S) = x;
    const std::vector<int>& held = scheme.poses[f];
    std::vector<Eigen::Vector3d> e(held.size());
    for (size_t k = 0; k < held.size(); ++k) {
      const int i = held[k];
      e[k] = rF_.segment<3>(3 * i);
      // the row's prediction over S's columns or its non-zero ones, the fewer
      const std::vector<int>& nz = row_nz_[static_cast<size_t>(i)];
      if (nz.size() < S.size()) {
        for (int c : nz) e[k] -= JF_.col(c).segment<3>(3 * i) * x_all[c];
      } else {
        for (Eigen::Index a = 0; a < s; ++a) e[k] -= JF_.col(S[a]).segment<3>(3 * i) * x[a];
      }
    }
    if (own_stations_) reregister(held, &e);
    for (size_t k = 0; k < held.size(); ++k) {
      // robust held-out loss: a down-weighted row counts with its weight squared (about the
      // squared cut-off for a gross outlier)
      const double w = robust_w_[static_cast<size_t>(held[k])];
      ev.d[held[k]] = e[k].squaredNorm() * w * w;
    }
    if (leverage && !held.empty() && use_rot_) {
      // the fold's meat: every row's less the held-out ones'
      Eigen::MatrixXd Bh = Eigen::MatrixXd::Zero(Bm_.rows(), Bm_.cols());
      addNormal(held, &Bh, nullptr, true);
      mirrorLower(&Bh);
      std::vector<Eigen::Index> Sa;
      for (Eigen::Index a : act) Sa.push_back(S[a]);
      Eigen::MatrixXd Jh(3 * static_cast<Eigen::Index>(held.size()), static_cast<Eigen::Index>(act.size()));
      for (size_t k = 0; k < held.size(); ++k)
        for (size_t a = 0; a < act.size(); ++a) Jh.block<3, 1>(3 * static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(a)) = JF_.col(Sa[a]).segment<3>(3 * held[k]);
      Eigen::VectorXd lev;
      sandwichLeverage(llt, Jh, Eigen::MatrixXd(Bm_(Sa, Sa) - Bh(Sa, Sa)), &lev);
      for (size_t k = 0; k < held.size(); ++k) ev.lev[held[k]] = lev[static_cast<Eigen::Index>(k)];
    } else if (leverage && !held.empty()) {
      // the held-out rows' leverages |L^-1 J_i^T|^2, all rows of the fold in one triangular solve
      // (act: the columns of the fold's factor, all of S or those its rows reach)
      Eigen::MatrixXd Jt(static_cast<Eigen::Index>(act.size()), 3 * static_cast<Eigen::Index>(held.size()));
      for (size_t k = 0; k < held.size(); ++k)
        Jt.middleCols(3 * static_cast<Eigen::Index>(k), 3) = JS.middleRows(3 * static_cast<Eigen::Index>(held[k]), 3)(Eigen::all, act).transpose();
      llt.matrixL().solveInPlace(Jt);
      for (size_t k = 0; k < held.size(); ++k) ev.lev[held[k]] = Jt.middleCols(3 * static_cast<Eigen::Index>(k), 3).squaredNorm();
    }
  }
  ev.ok = true;
  return ev;
}

// Several stations: the training fit places every set's station by the registration on all the
// data (combineStations), which new data from a new station do not have; and trained on part of a
// set's joint ranges, the base the fit finds moves with the effects it is fitted with (on the UR10's
// Series_B + Series_C, trained on the lower half of joint 2's range, Series_B held out: compliance
// of joint 2 looked 12 % worse in the stations of the registration, and is 30 % better with the
// station re-registered, as identify --validate-station new measures it).
void Diagnoser::reregister(const std::vector<int>& held, std::vector<Eigen::Vector3d>* e) const {
  std::map<int, std::vector<size_t>> by_set;
  for (size_t k = 0; k < held.size(); ++k) by_set[set_of_row_[static_cast<size_t>(held[k])]].push_back(k);
  for (const auto& [set, ks] : by_set) {
    if (static_cast<int>(ks.size()) < kReregisterPoses) continue;
    Eigen::Vector3d c = Eigen::Vector3d::Zero();  // rotations about the held-out rows' centroid
    for (size_t k : ks) c += fit_.rows[static_cast<size_t>(held[k])].p_world_mm;
    c /= static_cast<double>(ks.size());
    // e - (dt + dw x (p - c)) = e - G xi, G = [I, -[p - c]x]
    Eigen::Matrix<double, 6, 6> N = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    std::vector<Eigen::Matrix<double, 3, 6>> Gs(ks.size());
    for (size_t n = 0; n < ks.size(); ++n) {
      const int i = held[ks[n]];
      const Eigen::Vector3d p = fit_.rows[static_cast<size_t>(i)].p_world_mm - c;
      Eigen::Matrix3d px;
      px << 0, -p.z(), p.y(), p.z(), 0, -p.x(), -p.y(), p.x(), 0;
      Gs[n] << Eigen::Matrix3d::Identity(), -px;
      const double rw = robust_w_[static_cast<size_t>(i)];
      const Eigen::Matrix3d W = (rw * rw * wF_.segment<3>(3 * i).array().square()).matrix().asDiagonal();
      N += Gs[n].transpose() * W * Gs[n];
      g += Gs[n].transpose() * W * (*e)[ks[n]];
    }
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(N);
    const Eigen::VectorXd dg = ldlt.vectorD();
    if (ldlt.info() != Eigen::Success || !(dg.minCoeff() > 1e-12 * dg.maxCoeff())) continue;  // the rows do not fix a frame
    const Eigen::Matrix<double, 6, 1> xi = ldlt.solve(g);
    for (size_t n = 0; n < ks.size(); ++n) (*e)[ks[n]] -= Gs[n] * xi;
  }
}

void Diagnoser::sandwichLeverage(const Eigen::LLT<Eigen::MatrixXd>& llt, const Eigen::MatrixXd& Jrows, const Eigen::MatrixXd& B,
                                 Eigen::VectorXd* lev) const {
  // Y = A^-1 J_i^T per row; the pose's variance is the trace of Y^T B Y over its 3 rows
  const Eigen::MatrixXd Y = llt.solve(Eigen::MatrixXd(Jrows.transpose()));
  const Eigen::MatrixXd BY = B * Y;
  lev->resize(Jrows.rows() / 3);
  for (Eigen::Index k = 0; k < lev->size(); ++k) (*lev)[k] = Y.middleCols(3 * k, 3).cwiseProduct(BY.middleCols(3 * k, 3)).sum();
}

// Linear fit on all fit data: parameter update (scaled) and weighted chi^2; sigma (scaled,
// times the variance factor) when asked.
Eigen::VectorXd Diagnoser::fitAll(const std::vector<int>& S, double* chi2, Eigen::VectorXd* sigma) const {
  const Eigen::Index s = static_cast<Eigen::Index>(S.size());
  const Eigen::MatrixXd AS = A_(S, S);  // the normal equations of the blocks in S
  const Eigen::VectorXd bS = b_(S);
  Eigen::LLT<Eigen::MatrixXd> llt;
  Eigen::VectorXd x;
  if (!solveStaged(AS, bS, mapMask(S), &llt, &x)) throw NumericalError("diagnose: the normal matrix of the fit is singular");
  const double c2 = std::max(0.0, rr_ - bS.dot(x));
  if (chi2) *chi2 = c2;
  if (sigma) {
    const double dof = std::max(1.0, equations_ - double(s));
    const double s0 = c2 / dof;
    const Eigen::MatrixXd inv = llt.solve(Eigen::MatrixXd::Identity(s, s));
    *sigma = (s0 * inv.diagonal()).cwiseMax(0).cwiseSqrt();
  }
  return x;
}

std::vector<int> Diagnoser::withBlocks(const std::vector<int>& blocks) const {
  std::vector<int> S = G_;
  for (int b : blocks) S.insert(S.end(), blocks_[b].cols.begin(), blocks_[b].cols.end());
  return S;
}

std::vector<EffectParameter> Diagnoser::parametersOf(const std::vector<int>& S, const std::string& effect) const {
  Eigen::VectorXd sigma;
  const Eigen::VectorXd x = fitAll(S, nullptr, &sigma);
  std::vector<EffectParameter> out;
  for (size_t k = 0; k < S.size(); ++k) {
    const ParamInfo& p = layout_[cols_[S[k]]];
    if (p.group != effect) continue;
    const double internal = getParameter(M0_.deviations, p) + x[static_cast<Eigen::Index>(k)] / colscale_[S[k]];
    out.push_back({p.name, p.unit, internal * p.display_scale, sigma[static_cast<Eigen::Index>(k)] / colscale_[S[k]] * p.display_scale});
  }
  return out;
}

// Gauss-Newton from M0 over the parameters S on the given fit rows.
// Why a refit's normal matrix can be singular when the data say so: its rows hold too few
// distinct joint configurations (repeats, measurements.h, add no information) for its
// parameters; empty otherwise.
std::string singularWhy(const std::vector<std::vector<int>>& groups, const std::vector<int>& rows, int parameters) {
  std::vector<int> group_of;
  for (size_t g = 0; g < groups.size(); ++g)
    for (int i : groups[g]) {
      if (group_of.size() <= static_cast<size_t>(i)) group_of.resize(static_cast<size_t>(i) + 1, -1);
      group_of[static_cast<size_t>(i)] = static_cast<int>(g);
    }
  std::set<int> distinct;
  for (int i : rows) distinct.insert(static_cast<size_t>(i) < group_of.size() ? group_of[static_cast<size_t>(i)] : -1 - i);
  const int configurations = static_cast<int>(distinct.size());
  if (3 * configurations >= kMinEquationsPerParameter * parameters) return "";
  return ": its " + std::to_string(rows.size()) + " fit rows hold only " + std::to_string(configurations) +
         " distinct joint configurations (the others repeat one: every joint within the repeat tolerance), " +
         std::to_string(3 * configurations) + " independent position equations for " + std::to_string(parameters) +
         " parameters; repeats measure the noise, not the geometry: measure more distinct configurations";
}

RobotModel Diagnoser::gnFit(const std::vector<int>& S, const std::vector<int>& rows, RowSystem* at_m0) const {
  // the maps after the other columns, fitted to what those leave, as identify does
  std::vector<int> others, maps;
  for (int c : S) (is_map_[static_cast<size_t>(c)] ? maps : others).push_back(c);
  if (others.empty() || maps.empty()) return gnFitFrom(M0_, S, rows, at_m0);
  return gnFitFrom(gnFitFrom(M0_, others, rows, at_m0), maps, rows, nullptr);
}

RobotModel Diagnoser::gnFitFrom(const RobotModel& start, const std::vector<int>& S, const std::vector<int>& rows,
                                RowSystem* at_m0) const {
  RobotModel model = start;
  std::vector<ParamInfo> sub;
  Eigen::VectorXd inv_scale(static_cast<Eigen::Index>(S.size()));
  for (size_t k = 0; k < S.size(); ++k) {
    sub.push_back(layout_[cols_[S[k]]]);
    inv_scale[static_cast<Eigen::Index>(k)] = 1.0 / colscale_[S[k]];
  }
  const Eigen::Index s = static_cast<Eigen::Index>(S.size());
  // the rows' Jacobians on the kinematic core prepared once per iteration (station 0: the
  // diagnosis works in one world)
  const identify_detail::JacobianPlan plan = identify_detail::makePlan(M0_, sub);
  identify_detail::Stations st;
  st.of_row.assign(fit_.rows.size(), 0);
  identify_detail::RowStack stack(model, plan, st);
  const std::vector<double> x0(sub.size(), 0.0);  // (no station parameters)
  // per pose its position's 3 rows (mm) and, with 6D data, its orientation's 3 (rad)
  const Eigen::Index D = use_rot_ ? 6 : 3;
  const Eigen::Index R = D * static_cast<Eigen::Index>(rows.size());
  Eigen::MatrixXd Jw(R, s);  // weighted, scaled
  Eigen::VectorXd rw(R);
  const Eigen::MatrixXd P = penalty_(S, S);
  double last_step = 0;
  Eigen::LLT<Eigen::MatrixXd> llt;
  for (int it = 0; it < 10; ++it) {
    // at M0 (the first iteration), the rows' system from at_m0 when it holds it
    const bool cached = it == 0 && at_m0 && at_m0->Jw.rows() == D * m_ && at_m0->Jw.cols() == s;
    // a chord step once the last step was below one (scaled: one standard deviation of the
    // parameter on all fit data): the Jacobian and its factorisation of the last iteration, new
    // residuals only. The third iteration, which typically ends the fit with a step of 1e-6
    // after one of 0.1-0.4, then costs one FK per row instead of a Jacobian. Its end point is
    // where J0^T r = P x with the older Jacobian J0, not J^T r = P x: it differs from the
    // Gauss-Newton one by (J - J0)^T r through the normal matrix, J having changed by a step
    // below one standard deviation (on Series_B the diagnosis's outputs moved by 4.6e-9 mm at
    // most, bench/README.md).
    const bool chord = it >= 2 && last_step < 1.0;
    if (!cached) stack.prepare(model);
    for (size_t k = 0; k < rows.size(); ++k) {
      const int i = rows[k];
      const Eigen::Index r0 = D * static_cast<Eigen::Index>(k);
      if (cached) {
        Jw.middleRows(r0, D) = at_m0->Jw.middleRows(D * i, D);
        rw.segment(r0, D) = at_m0->rw.segment(D * i, D);
        continue;
      }
      const Measurement& row = fit_.rows[static_cast<size_t>(i)];
      const Eigen::Isometry3d T = stack.pose(x0, row, static_cast<size_t>(i), !chord);
      if (!chord) Jw.middleRows(r0, 3).noalias() = w_fit_[i].asDiagonal() * stack.J().topRows(3) * inv_scale.asDiagonal();
      rw.segment(r0, 3) = w_fit_[i].cwiseProduct(row.p_world_mm - T.translation());
      if (D == 6) {
        const Eigen::Vector3d& wr = w_rot_[static_cast<size_t>(i)];
        if (!chord) Jw.middleRows(r0 + 3, 3).noalias() = wr.asDiagonal() * stack.J().bottomRows(3) * inv_scale.asDiagonal();
        rw.segment(r0 + 3, 3) = -wr.cwiseProduct(identify_detail::rowError(T, row, 6).tail<3>());
      }
    }
    if (it == 0 && at_m0 && !cached && R == D * m_) {
      // every pose: keep the system at M0 for the other fits of S
      at_m0->Jw.resize(R, s);
      at_m0->rw.resize(R);
      for (size_t k = 0; k < rows.size(); ++k) {
        at_m0->Jw.middleRows(D * rows[k], D) = Jw.middleRows(D * static_cast<Eigen::Index>(k), D);
        at_m0->rw.segment(D * rows[k], D) = rw.segment(D * static_cast<Eigen::Index>(k), D);
      }
    }
    // the maps' penalty on their current (scaled) coefficients; zero for every other parameter
    Eigen::VectorXd xs(s);
    for (Eigen::Index k = 0; k < s; ++k) xs[k] = getParameter(model.deviations, sub[static_cast<size_t>(k)]) / inv_scale[k];
    Eigen::VectorXd b = -(P * xs);
    b.noalias() += Jw.transpose() * rw;
    Eigen::VectorXd dx;
    if (chord) {
      dx = llt.solve(b);
    } else {
      Eigen::MatrixXd A = P;
      if (s > 64) {
        // the maps' columns: a pose reaches 4 coefficients of each joint's map, a few dozen of
        // hundreds; its 3 rows' products over those alone (the dense product was 90% of a
        // diagnosis of Series_B and Series_C together)
        std::vector<Eigen::Index> nz;
        for (Eigen::Index r0 = 0; r0 < R; r0 += 3) {
          nz.clear();
          for (Eigen::Index c = 0; c < s; ++c)
            if (Jw(r0, c) != 0 || Jw(r0 + 1, c) != 0 || Jw(r0 + 2, c) != 0) nz.push_back(c);
          for (size_t a = 0; a < nz.size(); ++a)
            for (size_t e = 0; e <= a; ++e)
              A(nz[a], nz[e]) += Jw.block<3, 1>(r0, nz[a]).dot(Jw.block<3, 1>(r0, nz[e]));
        }
      } else {
        detail::addGramLower(A, Jw);
      }
      mirrorLower(&A);
      if (!solveSpd(A, b, &llt, &dx)) throw NumericalError("diagnose: the refit's normal matrix is singular" + singularWhy(groups_, rows, static_cast<int>(s)));
    }
    for (Eigen::Index k = 0; k < s; ++k)
      setParameter(model.deviations, sub[static_cast<size_t>(k)],
                   getParameter(model.deviations, sub[static_cast<size_t>(k)]) + dx[k] * inv_scale[k]);
    // scaled columns have unit weighted norm over all fit data: 1e-8 is far below one standard
    // deviation of any parameter. Gauss-Newton with residuals converges linearly: with the
    // ratio rho of this step to the last (below 1/2), the steps still to come sum to about
    // step rho / (1 - rho) < 2 step rho; done when that (or the step itself) is below 1e-8.
    const double step = dx.cwiseAbs().maxCoeff();
    const double rho = it > 0 ? step / last_step : 1.0;
    if (step < 1e-9 || (rho < 0.5 && 2.0 * step * rho < 1e-8)) break;
    last_step = step;
  }
  return model;
}

void Diagnoser::floorTest(const Eval& lin, const std::vector<Eigen::Vector3d>& e, const std::vector<bool>& keep,
                          HeldOutStats* s) const {
  if (!out_.noise_floor_known || !lin.ok || lin.lev.size() == 0) return;
  const Eigen::VectorXd& var = has_val_ ? var_val_ : var_fit_;
  double expected = 0, var_sum = 0, noise = 0, obs = 0;
  int n = 0;
  for (size_t i = 0; i < keep.size(); ++i) {
    if (!keep[i]) continue;
    const double E = var[static_cast<Eigen::Index>(i)] + lin.lev[static_cast<Eigen::Index>(i)];
    expected += E;
    var_sum += 2.0 / 3.0 * E * E;  // |e|^2 = (E/3) chi^2_3
    noise += var[static_cast<Eigen::Index>(i)];
    obs += e[i].squaredNorm();
    ++n;
  }
  if (n == 0) return;
  if (std::isfinite(out_.noise_floor_dof)) var_sum += 2.0 / out_.noise_floor_dof * noise * noise;
  s->expected_rms_mm = std::sqrt(expected / double(n));
  s->floor_z = var_sum > 0 ? (obs - expected) / std::sqrt(var_sum) : 0.0;
  s->floor_p = upperTail(s->floor_z);
}

Diagnoser::Exact Diagnoser::exact(const std::vector<int>& S) {
  Exact ex;
  std::vector<int> all(static_cast<size_t>(m_));
  std::iota(all.begin(), all.end(), 0);
  RowSystem at_m0;  // every row's system at M0 (the first iteration of every fit of S)
  ex.model_all = gnFit(S, all, &at_m0);
  for (JointMap& jm : ex.model_all.deviations.joint_map)  // the maps not in S stay zero: none
    if (!jm.empty() && std::all_of(jm.coef.begin(), jm.coef.end(), [](double c) { return c == 0.0; })) jm = JointMap{};
  KinematicWorkspace ws;
  if (has_val_) {
    ex.e.resize(static_cast<size_t>(nv_));
    for (int i = 0; i < nv_; ++i) {
      const Measurement& r = val_.rows[static_cast<size_t>(i)];
      ex.e[i] = r.p_world_mm - forwardKinematics(ex.model_all, r.q, r.context, ws).translation();
    }
  } else {
    ex.e.resize(static_cast<size_t>(m_));
    for (int f = 0; f < folds_; ++f) {
      const RobotModel mf = gnFit(S, trainingRows(f), &at_m0);
      for (int i : fold_poses_[f]) {
        const Measurement& r = fit_.rows[static_cast<size_t>(i)];
        ex.e[i] = r.p_world_mm - forwardKinematics(mf, r.q, r.context, ws).translation();
      }
    }
  }
  // Under cross-validation the held-out rows are the fit rows: those the robust estimation
  // down-weighted (gross outliers, glitches) are left out of the statistics and the floor test,
  // and enter the scans with their residual scaled by their weight.
  std::vector<double> mag, d;
  std::vector<bool> keep(ex.e.size(), true);
  for (size_t i = 0; i < ex.e.size(); ++i) {
    if (!has_val_ && robust_w_[i] < 1.0) {
      keep[i] = false;
      continue;
    }
    mag.push_back(ex.e[i].norm());
    d.push_back(ex.e[i].squaredNorm());
  }
  statsOf(mag, &ex.stats);
  floorTest(evaluate(S, true), ex.e, keep, &ex.stats);
  if (!has_val_)
    for (size_t i = 0; i < ex.e.size(); ++i) ex.e[i] *= robust_w_[i];
  return ex;
}

}  // namespace diagnose_detail
}  // namespace accura::calib
