// accura: diagnosis of the sim-to-real gap (diagnose.h, docs/diagnosis.md).
#include "accura/calib/diagnose.h"

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
#include "accura/calib/kinematics.h"

namespace accura {

bool DiagnoseOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  const std::vector<std::string>& cat = effectCatalogue();
  for (const std::string& e : effects) {
    if (std::find(cat.begin(), cat.end(), e) == cat.end()) {
      std::string list;
      for (const auto& c : cat) list += (list.empty() ? "" : ", ") + c;
      return fail("unknown effect '" + e + "' (expected one of: " + list + ")");
    }
  }
  if (gear_harmonics < 1 || gear_harmonics > kMaxGearHarmonics)
    return fail("gear harmonics must be 1.." + std::to_string(kMaxGearHarmonics) + ", got " +
                std::to_string(gear_harmonics));
  if (folds < 2 || folds > 20) return fail("folds must be 2..20, got " + std::to_string(folds));
  if (!(std::isnan(noise_std_mm) || (noise_std_mm > 0 && std::isfinite(noise_std_mm))))
    return fail("noise std must be a number > 0 mm, got " + std::to_string(noise_std_mm));
  if (!(alpha > 0 && alpha < 0.5)) return fail("alpha must be in (0, 0.5)");
  if (!(min_gain >= 0 && min_gain < 1)) return fail("min_gain must be in [0, 1)");
  if (!(floor_alpha > 0 && floor_alpha < 0.5)) return fail("floor_alpha must be in (0, 0.5)");
  if (max_steps < 0 || max_steps > 100) return fail("max_steps must be 0..100");
  if (grid_cells < 2 || grid_cells > 50) return fail("grid_cells must be 2..50");
  if (joint_bins < 2 || joint_bins > 50) return fail("joint_bins must be 2..50");
  return true;
}

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// One-sided upper tail of the standard normal distribution.
double upperTail(double z) { return 0.5 * std::erfc(z / std::sqrt(2.0)); }

// Paired comparison of per-pose squared errors: old minus new.
struct Gain {
  double gain = 0;  // mean(old - new) / mean(old)
  double z = 0, p = 1;
};

Gain pairedGain(const Eigen::VectorXd& d_old, const Eigen::VectorXd& d_new) {
  Gain g;
  const Eigen::Index n = d_old.size();
  if (n < 2 || d_new.size() != n) return g;
  const Eigen::VectorXd delta = d_old - d_new;
  const double mean = delta.mean();
  const double var = (delta.array() - mean).square().sum() / double(n - 1);
  const double se = std::sqrt(var / double(n));
  const double base = d_old.mean();
  g.gain = base > 0 ? mean / base : 0.0;
  if (se > 0) {
    g.z = mean / se;
  } else {
    g.z = mean > 0 ? 1e9 : (mean < 0 ? -1e9 : 0.0);
  }
  g.p = upperTail(g.z);
  return g;
}

std::string jointList(const std::vector<int>& joints) {
  std::string s;
  for (int j : joints) s += (s.empty() ? "j" : ", j") + std::to_string(j);
  return s;
}

std::string fmtg(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

void statsOf(const std::vector<double>& e, HeldOutStats* s) {
  s->n = static_cast<int>(e.size());
  summarize(e, &s->rms_mm, &s->mean_mm, &s->max_mm, &s->p95_mm);
}

// What each effect needs to be told apart from the others.
std::string separator(const std::string& effect, const std::vector<int>& joints) {
  const std::string j = joints.empty() ? std::string("the joints") : "joint" + std::string(joints.size() > 1 ? "s " : " ") + jointList(joints);
  if (effect == "joint_compliance") return "poses with other payloads (the deflection scales with the load)";
  if (effect == "gear_periodic") return "poses spread over the whole range of " + j + " (several periods of the harmonics)";
  if (effect == "joint_scale") return "poses over the whole range of " + j + " (a scale error grows linearly with q)";
  if (effect == "backlash") return "each pose approached from both directions (dirN +1 and -1)";
  if (effect == "thermal") return "the same poses measured at another temperature (a cold and a warm robot)";
  return "other poses";
}

// ---------------------------------------------------------------------------------------

class Diagnoser {
 public:
  Diagnoser(const RobotModel& start, const MeasurementSet& data, const MeasurementSet* validation,
            const DiagnoseOptions& options);
  Diagnosis run();

 private:
  struct Block {
    std::string effect;
    int joint = -1;         // 0-based; -1 for thermal
    std::vector<int> cols;  // compact column indices
  };
  struct Eval {
    bool ok = false;
    Eigen::VectorXd d;          // held-out squared error per pose (mm^2)
    Eigen::VectorXd lev;        // prediction variance per held-out pose (mm^2), when asked
  };
  struct Exact {
    std::vector<Eigen::Vector3d> e;  // held-out residual per pose (measured - model)
    HeldOutStats stats;
    RobotModel model_all;            // fitted on all fit data
  };

  void prepareData(const MeasurementSet& data, const MeasurementSet* validation);
  void noiseFloor();
  void baseline();
  void columns();
  void linearise();
  Eval evaluate(const std::vector<int>& S, bool leverage = false) const;
  Eigen::VectorXd fitAll(const std::vector<int>& S, double* chi2, Eigen::VectorXd* sigma) const;
  RobotModel gnFit(const std::vector<int>& S, const std::vector<int>& rows) const;
  Exact exact(const std::vector<int>& S);
  void floorTest(const Eval& lin, const std::vector<double>& d, HeldOutStats* s) const;
  std::vector<int> withBlocks(const std::vector<int>& blocks) const;
  std::vector<EffectParameter> parametersOf(const std::vector<int>& S, const std::string& effect) const;
  struct Forward {
    std::vector<int> blocks;        // selected, in order
    std::vector<double> drops;      // held-out MSE drop credited to each (mm^2)
    Eval cur;                       // held-out errors of the final selection
    std::vector<Gain> last_round;   // per block: gain on the final selection
    bool has_best_single = false;   // the best block of the first round, passing or not
    int best_single = -1;
    Eval best_single_eval;
  };
  Forward forward(const std::vector<int>& candidates) const;
  void selection();
  void ranking();
  void confounding();
  void shrink();
  void verdict();
  void where();
  std::vector<Correlation> scan(const std::vector<Eigen::Vector3d>& E) const;

  // inputs
  DiagnoseOptions o_;
  RobotModel start_;
  MeasurementSet fit_, val_;
  bool has_val_ = false;
  int m_ = 0, nv_ = 0;  // fit / validation poses
  int folds_ = 5;
  std::vector<int> fold_;                  // per fit pose
  std::vector<std::vector<int>> fold_poses_;
  // noise
  std::vector<Eigen::Vector3d> w_fit_, w_val_;  // per-axis weights sqrt(weight)/sigma
  Eigen::VectorXd var_fit_, var_val_;          // per pose: sum of the three noise variances (mm^2)
  // model and columns
  RobotModel M0_;
  std::vector<ParamInfo> layout_;
  std::vector<int> cols_;       // layout index of each compact column
  std::vector<int> G_;          // compact indices of the geometric parameters
  std::vector<Block> blocks_;
  std::map<std::string, std::string> effect_note_;
  Eigen::VectorXd colscale_;
  // linearisation at M0 (scaled columns)
  Eigen::MatrixXd JF_, JV_;
  Eigen::VectorXd rF_, rV_, wF_;
  Eigen::MatrixXd A_;
  Eigen::VectorXd b_;
  double rr_ = 0;
  std::vector<Eigen::MatrixXd> Af_;
  std::vector<Eigen::VectorXd> bf_;
  // results
  Diagnosis out_;
  Eval base_eval_;
  std::vector<int> sel_blocks_;             // in selection order
  std::vector<double> sel_drop_;            // held-out MSE drop of each (mm^2)
  std::vector<Gain> round1_;                // per block, on the baseline
  std::vector<Eval> round1_eval_;
  std::vector<Gain> last_round_;            // per block, on the final selection (NaN gain if selected)
  std::vector<Eigen::Vector3d> E0_, E1_;    // exact held-out residuals, baseline and final
  HeldOutStats final_stats_;
  bool above_floor_ = false;
  std::vector<std::string> order_;  // selected effects, in order of first selection
  std::map<std::string, std::vector<int>> blocks_of_;
  std::map<std::string, double> drop_of_;
};

Diagnoser::Diagnoser(const RobotModel& start, const MeasurementSet& data, const MeasurementSet* validation,
                     const DiagnoseOptions& options)
    : o_(options), start_(start) {
  std::string why;
  if (!o_.IsValid(&why)) throw ArgumentError("diagnose: " + why);
  if (o_.effects.empty()) o_.effects = effectCatalogue();
  start_.validate();
  if (start_.deviations.gear_harmonics != o_.gear_harmonics) {
    // same deviations with another number of gear harmonics (the common ones kept)
    Deviations d = Deviations::zero(start_.dof(), o_.gear_harmonics);
    const Deviations& s = start_.deviations;
    d.base_mm = s.base_mm;
    d.base_rot_rad = s.base_rot_rad;
    d.tool_mm = s.tool_mm;
    d.tool_rot_rad = s.tool_rot_rad;
    d.links = s.links;
    d.compliance = s.compliance;
    d.joint_scale = s.joint_scale;
    d.backlash = s.backlash;
    d.thermal_alpha_per_k = s.thermal_alpha_per_k;
    const int H = std::min(s.gear_harmonics, o_.gear_harmonics);
    for (int i = 0; i < start_.dof(); ++i)
      for (int h = 0; h < H; ++h) {
        d.gear_sin[i * o_.gear_harmonics + h] = s.gear_sin[i * s.gear_harmonics + h];
        d.gear_cos[i * o_.gear_harmonics + h] = s.gear_cos[i * s.gear_harmonics + h];
      }
    start_.deviations = d;
  }
  prepareData(data, validation);
}

void Diagnoser::prepareData(const MeasurementSet& data, const MeasurementSet* validation) {
  const int n = start_.dof();
  auto prepare = [&](const MeasurementSet& in, MeasurementSet* outset) {
    *outset = in;
    if (outset->has_orientation) out_.orientation_ignored = true;
    outset->has_orientation = false;
    outset->has_std_orientation = false;
    for (Measurement& r : outset->rows) {
      if (r.q.size() != n)
        throw InputError(in.file, r.line, 0,
                         "expected " + std::to_string(n) + " joint values, found " + std::to_string(r.q.size()));
      r.has_orientation = false;
      // the model's context from the measured columns (whoever filled the row)
      if (in.has_temperature && std::isfinite(r.temp_c)) r.context.temp_c = r.temp_c;
      if (in.has_direction) r.context.dir = r.dir;
    }
  };
  prepare(data, &fit_);
  m_ = static_cast<int>(fit_.rows.size());
  if (m_ < 30)
    throw InputError(data.file, 0, 0,
                     "the diagnosis needs at least 30 measured poses, found " + std::to_string(m_));
  if (validation) {
    prepare(*validation, &val_);
    has_val_ = true;
    nv_ = static_cast<int>(val_.rows.size());
    if (nv_ < 20)
      throw InputError(validation->file, 0, 0,
                       "the diagnosis needs at least 20 validation poses, found " + std::to_string(nv_));
  }
  out_.data_file = data.file;
  out_.fit_poses = m_;
  out_.validation_poses = has_val_ ? nv_ : m_;
  out_.robot = start_.nominal.name;
  for (const JointSpec& j : start_.nominal.joints) out_.joint_names.push_back(j.name);
}

// Repeated poses: same joint values (within 1e-6 deg or mm), payload and directions.
std::vector<std::vector<int>> repeatGroups(const MeasurementSet& set) {
  const size_t m = set.rows.size();
  std::vector<int> order(m);
  std::iota(order.begin(), order.end(), 0);
  auto key_less = [&](int a, int b) {
    const Measurement &A = set.rows[a], &B = set.rows[b];
    for (Eigen::Index k = 0; k < A.q.size(); ++k)
      if (std::abs(A.q[k] - B.q[k]) > 1e-6) return A.q[k] < B.q[k];
    if (std::abs(A.context.payload_kg - B.context.payload_kg) > 1e-9) return A.context.payload_kg < B.context.payload_kg;
    return A.dir < B.dir;
  };
  std::sort(order.begin(), order.end(), key_less);
  std::vector<std::vector<int>> groups;
  for (size_t k = 0; k < m;) {
    size_t e = k + 1;
    while (e < m && !key_less(order[k], order[e]) && !key_less(order[e], order[k])) ++e;
    std::vector<int> g(order.begin() + static_cast<long>(k), order.begin() + static_cast<long>(e));
    std::sort(g.begin(), g.end());
    groups.push_back(g);
    k = e;
  }
  std::sort(groups.begin(), groups.end(), [](const auto& a, const auto& b) { return a.front() < b.front(); });
  return groups;
}

void Diagnoser::noiseFloor() {
  // Folds: repeated poses stay together.
  const std::vector<std::vector<int>> groups = repeatGroups(fit_);
  folds_ = o_.folds;
  fold_.assign(m_, 0);
  for (size_t g = 0; g < groups.size(); ++g)
    for (int i : groups[g]) fold_[i] = static_cast<int>(g % static_cast<size_t>(folds_));
  fold_poses_.assign(folds_, {});
  for (int i = 0; i < m_; ++i) fold_poses_[fold_[i]].push_back(i);
  if (!has_val_) out_.validation_method = std::to_string(folds_) + "-fold cross-validation over the poses of " + fit_.file;
  else out_.validation_method = "validation set " + val_.file;

  // Pooled within-pose scatter of the repeated poses (fit and validation data).
  double ss = 0;
  double dof = 0;
  int n_groups = 0;
  auto pool = [&](const MeasurementSet& set) {
    for (const auto& g : repeatGroups(set)) {
      if (g.size() < 2) continue;
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (int i : g) mean += set.rows[i].p_world_mm;
      mean /= double(g.size());
      for (int i : g) ss += (set.rows[i].p_world_mm - mean).squaredNorm();
      dof += 3.0 * double(g.size() - 1);
      ++n_groups;
    }
  };
  pool(fit_);
  if (has_val_) pool(val_);

  double sigma = kNaN;  // per axis
  bool per_row = false;
  if (!std::isnan(o_.noise_std_mm)) {
    sigma = o_.noise_std_mm;
    out_.noise_floor_source = "given: " + fmtg("%.4g", sigma) + " mm per axis";
  } else if (dof >= 30) {
    sigma = std::sqrt(ss / dof);
    out_.noise_floor_dof = dof;
    out_.noise_floor_source = "repeated poses: " + std::to_string(n_groups) + " poses measured more than once, pooled scatter " +
                              fmtg("%.4g", sigma) + " mm per axis (" + fmtg("%.0f", dof) + " degrees of freedom)";
  } else if (fit_.has_std_position && (!has_val_ || val_.has_std_position)) {
    per_row = true;
    out_.noise_floor_source = "std columns of the data (the instrument's stated uncertainty)";
  } else {
    out_.noise_floor_known = false;
    out_.noise_floor_source =
        "unknown: no repeated poses (" + std::to_string(n_groups) + " found, at least 10 needed), no std columns and no "
        "--noise-mm; estimated from the fit residual of the geometric model plus every testable effect, an upper "
        "bound when an effect outside the catalogue is present; `unexplained` is then judged by the structure scan";
  }
  auto fill = [&](const MeasurementSet& set, std::vector<Eigen::Vector3d>* w, Eigen::VectorXd* var) {
    w->assign(set.rows.size(), Eigen::Vector3d::Ones());
    var->setZero(static_cast<Eigen::Index>(set.rows.size()));
    for (size_t i = 0; i < set.rows.size(); ++i) {
      const Measurement& r = set.rows[i];
      Eigen::Vector3d s = Eigen::Vector3d::Constant(std::isnan(sigma) ? 1.0 : sigma);
      if (set.has_std_position) s = r.std_mm;  // relative weights from the instrument
      (*w)[i] = std::sqrt(r.weight) * s.cwiseInverse();
      const Eigen::Vector3d sf = per_row ? r.std_mm : Eigen::Vector3d::Constant(std::isnan(sigma) ? 0.0 : sigma);
      (*var)[static_cast<Eigen::Index>(i)] = sf.squaredNorm();
    }
  };
  fill(fit_, &w_fit_, &var_fit_);
  if (has_val_) fill(val_, &w_val_, &var_val_);
  if (out_.noise_floor_known) {
    const Eigen::VectorXd& v = has_val_ ? var_val_ : var_fit_;
    out_.noise_floor_mm = std::sqrt(v.mean());
    out_.noise_std_axis_mm = out_.noise_floor_mm / std::sqrt(3.0);
  }
}

void Diagnoser::baseline() {
  IdentifyOptions io;
  io.groups = {"geometric"};
  if (!fit_.has_std_position) {
    // weights: the noise floor when known, else identify's variance components
    if (out_.noise_floor_known) io.position_std_mm = out_.noise_std_axis_mm;
  }
  IdentifySummary s;
  M0_ = identify(start_, fit_, io, &s);
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
    for (auto& w : w_fit_) w = Eigen::Vector3d::Constant(1.0 / s.position_std_mm);
    for (size_t i = 0; i < w_fit_.size(); ++i) w_fit_[i] *= std::sqrt(fit_.rows[i].weight);
    if (has_val_)
      for (size_t i = 0; i < w_val_.size(); ++i) w_val_[i] = Eigen::Vector3d::Constant(std::sqrt(val_.rows[i].weight) / s.position_std_mm);
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

void Diagnoser::linearise() {
  const int C = static_cast<int>(cols_.size());
  std::vector<ParamInfo> sub;
  for (int c : cols_) sub.push_back(layout_[c]);
  auto build = [&](const MeasurementSet& set, Eigen::MatrixXd* J, Eigen::VectorXd* r) {
    const Eigen::Index m = static_cast<Eigen::Index>(set.rows.size());
    J->resize(3 * m, C);
    r->resize(3 * m);
    KinematicWorkspace ws;
    Eigen::MatrixXd J6;
    for (Eigen::Index i = 0; i < m; ++i) {
      const Measurement& row = set.rows[static_cast<size_t>(i)];
      const Eigen::Isometry3d T = parameterJacobian(M0_, sub, row.q, row.context, ws, J6);
      J->middleRows(3 * i, 3) = J6.topRows(3);
      r->segment(3 * i, 3) = row.p_world_mm - T.translation();
    }
  };
  Eigen::MatrixXd JF;
  build(fit_, &JF, &rF_);
  wF_.resize(3 * m_);
  for (int i = 0; i < m_; ++i) wF_.segment(3 * i, 3) = w_fit_[i];
  // weighted column norms: scale, and screen zero / dependent columns
  Eigen::MatrixXd Jw = wF_.asDiagonal() * JF;
  Eigen::VectorXd norms = Jw.colwise().norm();
  double gmax = 0;
  for (int c : G_) gmax = std::max(gmax, norms[c]);
  // orthonormal basis of the geometric columns
  Eigen::MatrixXd Gs(3 * m_, static_cast<Eigen::Index>(G_.size()));
  for (size_t k = 0; k < G_.size(); ++k) Gs.col(static_cast<Eigen::Index>(k)) = Jw.col(G_[k]) / norms[G_[k]];
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(Gs);
  Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(3 * m_, Gs.cols());
  std::vector<bool> keep(static_cast<size_t>(C), true);
  for (Block& b : blocks_) {
    Eigen::MatrixXd Qb = Q;
    std::vector<int> kept;
    for (int c : b.cols) {
      const std::string& name = layout_[cols_[c]].name;
      if (!(norms[c] > 1e-12 * std::max(gmax, 1e-300))) {
        keep[static_cast<size_t>(c)] = false;
        effect_note_[b.effect + ":" + name] = name + " has no effect on these measurements";
        continue;
      }
      Eigen::VectorXd v = Jw.col(c) / norms[c];
      for (int pass = 0; pass < 2; ++pass) v -= Qb * (Qb.transpose() * v);
      const double rho = v.norm();
      if (rho < 1e-3) {
        keep[static_cast<size_t>(c)] = false;
        effect_note_[b.effect + ":" + name] =
            name + " cannot be told from the geometric parameters (relative residual " + fmtg("%.2g", rho) + ")";
        continue;
      }
      Qb.conservativeResize(Eigen::NoChange, Qb.cols() + 1);
      Qb.col(Qb.cols() - 1) = v / rho;
      kept.push_back(c);
    }
    b.cols = kept;
  }
  blocks_.erase(std::remove_if(blocks_.begin(), blocks_.end(), [](const Block& b) { return b.cols.empty(); }),
                blocks_.end());
  colscale_ = norms.cwiseMax(1e-300);
  JF_ = JF * colscale_.cwiseInverse().asDiagonal();
  Jw = wF_.asDiagonal() * JF_;
  const Eigen::VectorXd rw = wF_.cwiseProduct(rF_);
  A_ = Jw.transpose() * Jw;
  b_ = Jw.transpose() * rw;
  rr_ = rw.squaredNorm();
  if (has_val_) {
    build(val_, &JV_, &rV_);
    JV_ = JV_ * colscale_.cwiseInverse().asDiagonal();
  } else {
    Af_.assign(folds_, Eigen::MatrixXd::Zero(C, C));
    bf_.assign(folds_, Eigen::VectorXd::Zero(C));
    for (int f = 0; f < folds_; ++f) {
      for (int i : fold_poses_[f]) {
        const Eigen::MatrixXd Ji = Jw.middleRows(3 * i, 3);
        Af_[f].noalias() += Ji.transpose() * Ji;
        bf_[f].noalias() += Ji.transpose() * rw.segment(3 * i, 3);
      }
    }
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

Diagnoser::Eval Diagnoser::evaluate(const std::vector<int>& S, bool leverage) const {
  Eval ev;
  const Eigen::Index s = static_cast<Eigen::Index>(S.size());
  const Eigen::MatrixXd AS = A_(S, S);  // the normal equations of the blocks in S
  const Eigen::VectorXd bS = b_(S);
  Eigen::LLT<Eigen::MatrixXd> llt;
  Eigen::VectorXd x;
  if (has_val_) {
    if (!solveSpd(AS, bS, &llt, &x)) return ev;
    const Eigen::MatrixXd JS = JV_(Eigen::all, S);
    const Eigen::VectorXd e = rV_ - JS * x;
    ev.d.resize(nv_);
    for (int i = 0; i < nv_; ++i) ev.d[i] = e.segment(3 * i, 3).squaredNorm();
    if (leverage) {
      ev.lev.resize(nv_);
      for (int i = 0; i < nv_; ++i)
        ev.lev[i] = llt.matrixL().solve(Eigen::MatrixXd(JS.middleRows(3 * i, 3).transpose())).squaredNorm();
    }
  } else {
    const Eigen::MatrixXd JS = JF_(Eigen::all, S);
    ev.d.resize(m_);
    if (leverage) ev.lev.resize(m_);
    for (int f = 0; f < folds_; ++f) {
      Eigen::MatrixXd M = AS;
      Eigen::VectorXd v = bS;
      for (Eigen::Index a = 0; a < s; ++a) {
        v[a] -= bf_[f][S[a]];
        for (Eigen::Index c = 0; c < s; ++c) M(a, c) -= Af_[f](S[a], S[c]);
      }
      if (!solveSpd(M, v, &llt, &x)) return ev;
      for (int i : fold_poses_[f]) {
        const Eigen::MatrixXd Ji = JS.middleRows(3 * i, 3);
        ev.d[i] = (rF_.segment(3 * i, 3) - Ji * x).squaredNorm();
        if (leverage) ev.lev[i] = llt.matrixL().solve(Eigen::MatrixXd(Ji.transpose())).squaredNorm();
      }
    }
  }
  ev.ok = true;
  return ev;
}

// Linear fit on all fit data: parameter update (scaled) and weighted chi^2; sigma (scaled,
// times the variance factor) when asked.
Eigen::VectorXd Diagnoser::fitAll(const std::vector<int>& S, double* chi2, Eigen::VectorXd* sigma) const {
  const Eigen::Index s = static_cast<Eigen::Index>(S.size());
  const Eigen::MatrixXd AS = A_(S, S);  // the normal equations of the blocks in S
  const Eigen::VectorXd bS = b_(S);
  Eigen::LLT<Eigen::MatrixXd> llt;
  Eigen::VectorXd x;
  if (!solveSpd(AS, bS, &llt, &x)) throw NumericalError("diagnose: the normal matrix of the fit is singular");
  const double c2 = std::max(0.0, rr_ - bS.dot(x));
  if (chi2) *chi2 = c2;
  if (sigma) {
    const double dof = std::max(1.0, 3.0 * m_ - double(s));
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
RobotModel Diagnoser::gnFit(const std::vector<int>& S, const std::vector<int>& rows) const {
  RobotModel model = M0_;
  std::vector<ParamInfo> sub;
  Eigen::VectorXd scale(static_cast<Eigen::Index>(S.size()));
  for (size_t k = 0; k < S.size(); ++k) {
    sub.push_back(layout_[cols_[S[k]]]);
    scale[static_cast<Eigen::Index>(k)] = colscale_[S[k]];
  }
  const Eigen::Index s = static_cast<Eigen::Index>(S.size());
  KinematicWorkspace ws;
  Eigen::MatrixXd J6;
  Eigen::MatrixXd Jp(3, s);
  for (int it = 0; it < 10; ++it) {
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(s, s);
    Eigen::VectorXd b = Eigen::VectorXd::Zero(s);
    for (int i : rows) {
      const Measurement& row = fit_.rows[static_cast<size_t>(i)];
      const Eigen::Isometry3d T = parameterJacobian(model, sub, row.q, row.context, ws, J6);
      Jp = w_fit_[i].asDiagonal() * J6.topRows(3) * scale.cwiseInverse().asDiagonal();
      A.noalias() += Jp.transpose() * Jp;
      b.noalias() += Jp.transpose() * w_fit_[i].cwiseProduct(row.p_world_mm - T.translation());
    }
    Eigen::LLT<Eigen::MatrixXd> llt;
    Eigen::VectorXd dx;
    if (!solveSpd(A, b, &llt, &dx)) throw NumericalError("diagnose: the refit's normal matrix is singular");
    for (Eigen::Index k = 0; k < s; ++k)
      setParameter(model.deviations, sub[static_cast<size_t>(k)],
                   getParameter(model.deviations, sub[static_cast<size_t>(k)]) + dx[k] / scale[k]);
    // scaled columns have unit weighted norm over all fit data: a step of 1e-9 is far below
    // one standard deviation of any parameter
    if (dx.cwiseAbs().maxCoeff() < 1e-9) break;
  }
  return model;
}

void Diagnoser::floorTest(const Eval& lin, const std::vector<double>& d, HeldOutStats* s) const {
  if (!out_.noise_floor_known || !lin.ok || lin.lev.size() == 0) return;
  const Eigen::VectorXd& var = has_val_ ? var_val_ : var_fit_;
  double expected = 0, var_sum = 0, noise = 0, obs = 0;
  for (size_t i = 0; i < d.size(); ++i) {
    const double E = var[static_cast<Eigen::Index>(i)] + lin.lev[static_cast<Eigen::Index>(i)];
    expected += E;
    var_sum += 2.0 / 3.0 * E * E;  // |e|^2 = (E/3) chi^2_3
    noise += var[static_cast<Eigen::Index>(i)];
    obs += d[i];
  }
  if (std::isfinite(out_.noise_floor_dof)) var_sum += 2.0 / out_.noise_floor_dof * noise * noise;
  s->expected_rms_mm = std::sqrt(expected / double(d.size()));
  s->floor_z = var_sum > 0 ? (obs - expected) / std::sqrt(var_sum) : 0.0;
  s->floor_p = upperTail(s->floor_z);
}

Diagnoser::Exact Diagnoser::exact(const std::vector<int>& S) {
  Exact ex;
  std::vector<int> all(static_cast<size_t>(m_));
  std::iota(all.begin(), all.end(), 0);
  ex.model_all = gnFit(S, all);
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
      std::vector<int> train;
      for (int i = 0; i < m_; ++i)
        if (fold_[i] != f) train.push_back(i);
      const RobotModel mf = gnFit(S, train);
      for (int i : fold_poses_[f]) {
        const Measurement& r = fit_.rows[static_cast<size_t>(i)];
        ex.e[i] = r.p_world_mm - forwardKinematics(mf, r.q, r.context, ws).translation();
      }
    }
  }
  std::vector<double> mag, d;
  for (const auto& e : ex.e) {
    mag.push_back(e.norm());
    d.push_back(e.squaredNorm());
  }
  statsOf(mag, &ex.stats);
  floorTest(evaluate(S, true), d, &ex.stats);
  return ex;
}

// ---------------------------------------------------------------------------------------

// Forward selection over the candidate blocks, starting from the baseline: each round adds
// the block with the largest held-out gain if it passes the test; when no single block
// passes, the remaining blocks of each effect are tried together (one candidate per effect),
// so that an effect spread thinly over several joints is not missed.
Diagnoser::Forward Diagnoser::forward(const std::vector<int>& candidates) const {
  Forward fw;
  const size_t B = blocks_.size();
  fw.cur = base_eval_;
  fw.last_round.assign(B, Gain{});
  std::vector<bool> used(B, false);
  auto evalWith = [&](const std::vector<int>& add) {
    if (fw.blocks.empty() && add.size() == 1) return round1_eval_[static_cast<size_t>(add[0])];
    std::vector<int> blocks = fw.blocks;
    blocks.insert(blocks.end(), add.begin(), add.end());
    return evaluate(withBlocks(blocks));
  };
  auto accept = [&](const std::vector<int>& add, const Eval& e) {
    for (size_t k = 0; k < add.size(); ++k) {
      used[static_cast<size_t>(add[k])] = true;
      fw.blocks.push_back(add[k]);
      fw.drops.push_back(k == 0 ? fw.cur.d.mean() - e.d.mean() : 0.0);
    }
    fw.cur = e;
  };
  std::set<std::string> selected_effects;
  for (int step = 0; step < o_.max_steps; ++step) {
    // two families, each with its own Bonferroni correction: blocks of effects already in
    // the model (is the effect on more joints?) and blocks of new effects
    int best[2] = {-1, -1}, tried[2] = {0, 0};
    Gain best_gain[2];
    Eval best_eval[2];
    std::vector<Gain> round(B, Gain{});
    for (int b : candidates) {
      if (used[static_cast<size_t>(b)]) continue;
      const Eval e = evalWith({b});
      if (!e.ok) continue;
      const int fam = selected_effects.count(blocks_[static_cast<size_t>(b)].effect) ? 0 : 1;
      ++tried[fam];
      round[static_cast<size_t>(b)] = pairedGain(fw.cur.d, e.d);
      if (best[fam] < 0 || round[static_cast<size_t>(b)].gain > best_gain[fam].gain) {
        best[fam] = b;
        best_gain[fam] = round[static_cast<size_t>(b)];
        best_eval[fam] = e;
      }
    }
    fw.last_round = round;
    if (best[0] < 0 && best[1] < 0) break;
    if (fw.blocks.empty() && !fw.has_best_single && best[1] >= 0) {
      fw.has_best_single = true;
      fw.best_single = best[1];
      fw.best_single_eval = best_eval[1];
    }
    int pick = -1;
    for (int fam = 0; fam < 2; ++fam) {
      if (best[fam] < 0) continue;
      const bool passes = best_gain[fam].p < o_.alpha / double(tried[fam]) && best_gain[fam].gain >= o_.min_gain;
      if (passes && (pick < 0 || best_gain[fam].gain > best_gain[pick].gain)) pick = fam;
    }
    if (pick >= 0) {
      selected_effects.insert(blocks_[static_cast<size_t>(best[pick])].effect);
      accept({best[pick]}, best_eval[pick]);
      continue;
    }
    // no single block passes: the remaining blocks of each effect together
    std::map<std::string, std::vector<int>> groups;
    for (int b : candidates)
      if (!used[static_cast<size_t>(b)]) groups[blocks_[static_cast<size_t>(b)].effect].push_back(b);
    std::vector<int> best_group;
    Gain group_gain;
    Eval group_eval;
    int groups_tried = 0;
    for (const auto& kv : groups) {
      if (kv.second.size() < 2) continue;  // a single block was tried above
      const Eval e = evalWith(kv.second);
      if (!e.ok) continue;
      ++groups_tried;
      const Gain g = pairedGain(fw.cur.d, e.d);
      if (best_group.empty() || g.gain > group_gain.gain) {
        best_group = kv.second;
        group_gain = g;
        group_eval = e;
      }
    }
    if (!best_group.empty() && group_gain.p < o_.alpha / double(groups_tried) && group_gain.gain >= o_.min_gain) {
      selected_effects.insert(blocks_[static_cast<size_t>(best_group[0])].effect);
      accept(best_group, group_eval);
      continue;
    }
    break;
  }
  return fw;
}

void Diagnoser::selection() {
  base_eval_ = evaluate(G_);
  if (!base_eval_.ok) throw NumericalError("diagnose: the baseline's normal matrix is singular on a fold");
  const size_t B = blocks_.size();
  round1_.assign(B, Gain{});
  round1_eval_.assign(B, Eval{});
  for (size_t b = 0; b < B; ++b) {
    round1_eval_[b] = evaluate(withBlocks({static_cast<int>(b)}));
    if (round1_eval_[b].ok) round1_[b] = pairedGain(base_eval_.d, round1_eval_[b].d);
  }
  std::vector<int> all(B);
  std::iota(all.begin(), all.end(), 0);
  const Forward fw = forward(all);
  sel_blocks_ = fw.blocks;
  sel_drop_ = fw.drops;
  last_round_ = fw.last_round;
}

void Diagnoser::ranking() {
  const double base_rms = std::sqrt(base_eval_.d.mean());
  for (const std::string& e : o_.effects) {
    EffectEvidence ev;
    ev.effect = e;
    ev.rms_before_mm = base_rms;
    std::vector<int> mine;
    for (size_t b = 0; b < blocks_.size(); ++b)
      if (blocks_[b].effect == e) mine.push_back(static_cast<int>(b));
    if (mine.empty()) {
      ev.testable = false;
      auto it = effect_note_.find(e);
      ev.note = it != effect_note_.end() ? it->second : "not testable: no parameter of it can be determined from these measurements";
      ev.rms_after_mm = base_rms;
      out_.ranking.push_back(ev);
      continue;
    }
    for (int b : mine) {
      JointEvidence je;
      je.joint = blocks_[b].joint + 1;
      je.rms_after_mm = round1_eval_[b].ok ? std::sqrt(round1_eval_[b].d.mean()) : kNaN;
      je.gain = round1_[b].gain;
      je.z = round1_[b].z;
      je.p_value = round1_[b].p;
      if (blocks_[b].joint >= 0) ev.per_joint.push_back(je);
    }
    // forward selection within the effect
    const Forward fw = forward(mine);
    std::vector<int> chosen = fw.blocks;
    Eval cur = fw.cur;
    ev.significant = !chosen.empty();
    if (chosen.empty() && fw.has_best_single) {
      chosen = {fw.best_single};  // the best single block, reported as not significant
      cur = fw.best_single_eval;
    }
    for (int b : chosen)
      if (blocks_[b].joint >= 0) ev.joints.push_back(blocks_[b].joint + 1);
    std::sort(ev.joints.begin(), ev.joints.end());
    ev.rms_after_mm = std::sqrt(cur.d.mean());
    ev.max_after_mm = std::sqrt(cur.d.maxCoeff());
    const Gain g = pairedGain(base_eval_.d, cur.d);
    ev.gain = g.gain;
    ev.z = g.z;
    ev.p_value = g.p;
    const std::vector<int> S = withBlocks(chosen);
    double chi_with = 0, chi_without = 0;
    fitAll(S, &chi_with, nullptr);
    fitAll(G_, &chi_without, nullptr);
    ev.delta_bic = chi_with - chi_without + double(S.size() - G_.size()) * std::log(3.0 * m_);
    ev.parameters = parametersOf(S, e);
    if (!ev.significant) ev.note = "not significant: the best joint alone does not pass the test";
    out_.ranking.push_back(ev);
  }
  std::stable_sort(out_.ranking.begin(), out_.ranking.end(), [](const EffectEvidence& a, const EffectEvidence& b) {
    if (a.testable != b.testable) return a.testable;
    if (a.significant != b.significant) return a.significant;
    return a.rms_after_mm < b.rms_after_mm;
  });
}

// Canonical correlation of two blocks' weighted columns with the geometry projected out.
double canonicalCorrelation(const Eigen::MatrixXd& Jw, const std::vector<int>& G, const std::vector<int>& a,
                            const std::vector<int>& b) {
  Eigen::MatrixXd Gm = Jw(Eigen::all, G);
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(Gm);
  const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(Gm.rows(), Gm.cols());
  auto basis = [&](const std::vector<int>& cols) {
    Eigen::MatrixXd X = Jw(Eigen::all, cols);
    X -= Q * (Q.transpose() * X);
    Eigen::HouseholderQR<Eigen::MatrixXd> q2(X);
    return Eigen::MatrixXd(q2.householderQ() * Eigen::MatrixXd::Identity(X.rows(), X.cols()));
  };
  const Eigen::MatrixXd Qa = basis(a), Qb = basis(b);
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(Qa.transpose() * Qb);
  return std::min(1.0, svd.singularValues().size() ? svd.singularValues()[0] : 0.0);
}

void Diagnoser::confounding() {
  const size_t B = blocks_.size();
  const double thr1 = o_.alpha / double(std::max<size_t>(1, B));
  const Eigen::MatrixXd Jw = wF_.asDiagonal() * JF_;
  std::map<std::pair<std::string, std::string>, Confounding> pairs;
  for (size_t d = 0; d < B; ++d) {
    if (std::find(sel_blocks_.begin(), sel_blocks_.end(), static_cast<int>(d)) != sel_blocks_.end()) continue;
    if (!(round1_[d].p < thr1 && round1_[d].gain >= o_.min_gain)) continue;  // D alone did not matter
    const Gain& given = last_round_[d];
    if (given.p < thr1 && given.gain >= o_.min_gain) continue;  // still helps: not explained away
    // which selected block explains it away?
    int best_c = -1;
    double best_ratio = 1e300, best_given = 0;
    for (int c : sel_blocks_) {
      if (blocks_[c].effect == blocks_[d].effect) continue;
      const Eval ec = evaluate(withBlocks({c}));
      const Eval ecd = evaluate(withBlocks({c, static_cast<int>(d)}));
      if (!ec.ok || !ecd.ok) continue;
      const double g = pairedGain(ec.d, ecd.d).gain;
      const double ratio = g / std::max(round1_[d].gain, 1e-300);
      if (ratio < best_ratio) {
        best_ratio = ratio;
        best_c = c;
        best_given = g;
      }
    }
    if (best_c < 0 || best_ratio > 0.5) continue;
    const Block& C = blocks_[best_c];
    const Block& D = blocks_[d];
    Confounding& cf = pairs[{C.effect, D.effect}];
    cf.effect_a = C.effect;
    cf.effect_b = D.effect;
    if (C.joint >= 0 && std::find(cf.joints_a.begin(), cf.joints_a.end(), C.joint + 1) == cf.joints_a.end())
      cf.joints_a.push_back(C.joint + 1);
    if (D.joint >= 0 && std::find(cf.joints_b.begin(), cf.joints_b.end(), D.joint + 1) == cf.joints_b.end())
      cf.joints_b.push_back(D.joint + 1);
    cf.gain_b_alone = std::max(cf.gain_b_alone, round1_[d].gain);
    cf.gain_b_given_a = std::max(cf.gain_b_given_a, best_given);
    cf.canonical_correlation = std::max(cf.canonical_correlation, canonicalCorrelation(Jw, G_, C.cols, D.cols));
    // could the data tell them apart? C alone against D alone on the baseline
    const Gain cd = pairedGain(round1_eval_[d].d, round1_eval_[best_c].d);
    if (cd.p > 0.05) cf.indistinguishable = true;
    cf.rms_a_alone_mm = std::sqrt(round1_eval_[best_c].d.mean());
    cf.rms_b_alone_mm = std::sqrt(round1_eval_[d].d.mean());
    cf.p_a_better = std::min(cf.p_a_better, cd.p);
  }
  for (auto& kv : pairs) {
    Confounding& cf = kv.second;
    std::sort(cf.joints_a.begin(), cf.joints_a.end());
    std::sort(cf.joints_b.begin(), cf.joints_b.end());
    const std::string sa = separator(cf.effect_a, cf.joints_a), sb = separator(cf.effect_b, cf.joints_b);
    cf.separate_by = sa == sb ? sa : sa + "; " + sb;
    out_.confounded.push_back(cf);
  }
}

void Diagnoser::shrink() {
  // cumulative steps by effect, in the order of their first selection
  std::vector<std::string> order;
  std::map<std::string, std::vector<int>> blocks_of;
  std::map<std::string, double> drop_of;
  for (size_t k = 0; k < sel_blocks_.size(); ++k) {
    const Block& b = blocks_[sel_blocks_[k]];
    if (!blocks_of.count(b.effect)) order.push_back(b.effect);
    blocks_of[b.effect].push_back(sel_blocks_[k]);
    drop_of[b.effect] += sel_drop_[k];
  }
  Exact base = exact(G_);
  E0_ = base.e;
  out_.baseline = base.stats;
  out_.baseline_model = base.model_all;
  out_.shrink.push_back({"baseline", {}, base.stats});
  std::vector<int> cumulative;
  Eval prev = base_eval_;
  Exact last = base;
  for (const std::string& e : order) {
    cumulative.insert(cumulative.end(), blocks_of[e].begin(), blocks_of[e].end());
    const std::vector<int> S = withBlocks(cumulative);
    Exact ex = exact(S);
    const Eval lin = evaluate(S);
    EffectEvidence ev;
    ev.effect = e;
    for (int b : blocks_of[e])
      if (blocks_[b].joint >= 0) ev.joints.push_back(blocks_[b].joint + 1);
    std::sort(ev.joints.begin(), ev.joints.end());
    ev.rms_before_mm = last.stats.rms_mm;
    ev.rms_after_mm = ex.stats.rms_mm;
    ev.max_after_mm = ex.stats.max_mm;
    ev.significant = true;
    if (lin.ok) {
      const Gain g = pairedGain(prev.d, lin.d);
      ev.gain = g.gain;
      ev.z = g.z;
      ev.p_value = g.p;
      prev = lin;
    }
    double chi_with = 0, chi_without = 0;
    fitAll(S, &chi_with, nullptr);
    std::vector<int> before(cumulative.begin(), cumulative.end() - static_cast<long>(blocks_of[e].size()));
    fitAll(withBlocks(before), &chi_without, nullptr);
    ev.delta_bic = chi_with - chi_without + double(S.size() - withBlocks(before).size()) * std::log(3.0 * m_);
    ev.parameters = parametersOf(S, e);
    out_.selected.push_back(ev);
    out_.shrink.push_back({e, ev.joints, ex.stats});
    last = std::move(ex);
  }
  E1_ = last.e;
  final_stats_ = last.stats;
  out_.final_model = last.model_all;
  order_ = order;
  blocks_of_ = blocks_of;
  drop_of_ = drop_of;
}

void Diagnoser::verdict() {
  const std::vector<std::string>& order = order_;
  std::map<std::string, std::vector<int>>& blocks_of = blocks_of_;
  std::map<std::string, double>& drop_of = drop_of_;
  if (!out_.noise_floor_known) {
    // upper bound: the fit residual of the geometric model plus every testable effect
    std::vector<int> all_blocks(blocks_.size());
    std::iota(all_blocks.begin(), all_blocks.end(), 0);
    const std::vector<int> S = withBlocks(all_blocks);
    Eigen::VectorXd x = fitAll(S, nullptr, nullptr);
    const Eigen::VectorXd e = rF_ - JF_(Eigen::all, S) * x;
    const double dof = std::max(1.0, 3.0 * m_ - double(S.size()));
    out_.noise_std_axis_mm = std::sqrt(e.squaredNorm() / dof);
    out_.noise_floor_mm = std::sqrt(3.0) * out_.noise_std_axis_mm;
  }
  // verdict
  Verdict& v = out_.verdict;
  v.validation_rms_after_mm = final_stats_.rms_mm;
  bool structured = false;
  std::vector<const Correlation*> corr;
  {
    const double thr = o_.alpha / double(std::max<size_t>(1, out_.correlations.size()));
    for (const Correlation& c : out_.correlations)
      if (c.p_after < thr && c.r2_after >= 0.05) corr.push_back(&c);
    std::sort(corr.begin(), corr.end(), [](const Correlation* a, const Correlation* b) { return a->r2_after > b->r2_after; });
    structured = !corr.empty();
  }
  // Unexplained: above the noise floor, and structured: a variable of the pose or context
  // predicts it, or it is large (its excess over the expected RMS, in quadrature, is at least
  // the noise floor). Without a noise floor: when the structure scan finds a predictor.
  // (The excess is taken against the upper 95% confidence bound of the noise variance when
  // the floor is estimated from repeated poses: chi^2 quantile by Wilson-Hilferty.)
  double expected_ms = std::isfinite(final_stats_.expected_rms_mm) ? final_stats_.expected_rms_mm * final_stats_.expected_rms_mm : 0.0;
  if (std::isfinite(out_.noise_floor_dof)) {
    const double nu = out_.noise_floor_dof;
    const double c = 1.0 - 2.0 / (9.0 * nu) - 1.645 * std::sqrt(2.0 / (9.0 * nu));
    const double upper = c > 0.05 ? 1.0 / (c * c * c) : 20.0;  // nu / chi^2_{nu, 0.05}
    expected_ms += (upper - 1.0) * out_.noise_floor_mm * out_.noise_floor_mm;
  }
  const double excess_mm = std::sqrt(std::max(0.0, final_stats_.rms_mm * final_stats_.rms_mm - expected_ms));
  const bool large = excess_mm >= out_.noise_floor_mm;
  const bool significant_excess = out_.noise_floor_known && final_stats_.floor_p < o_.floor_alpha;
  above_floor_ = out_.noise_floor_known ? (significant_excess && (structured || large)) : structured;
  std::string after = order.empty() ? std::string("the complete geometric model") : "the geometric model plus ";
  for (size_t k = 0; k < order.size(); ++k) after += (k ? ", " : "") + order[k];
  const std::string against =
      out_.noise_floor_known
          ? "held-out RMS " + fmtg("%.4f", final_stats_.rms_mm) + " mm against " + fmtg("%.4f", final_stats_.expected_rms_mm) +
                " mm expected from the noise floor and the parameter uncertainty (z = " + fmtg("%.1f", final_stats_.floor_z) + ")"
          : "held-out RMS " + fmtg("%.4f", final_stats_.rms_mm) + " mm; the noise floor is unknown";
  for (const Correlation* c : corr) {
    std::string s = c->variable + " (R2 " + fmtg("%.2f", c->r2_after);
    if (c->via_joint_after > 0) s += ", acting like a motion of joint " + std::to_string(c->via_joint_after);
    else s += ", acting like a translation";
    v.correlates.push_back(s + ")");
    if (v.correlates.size() >= 4) break;
  }
  if (above_floor_) {
    v.effect = "unexplained";
    std::set<int> js;
    if (!corr.empty() && corr[0]->via_joint_after > 0) js.insert(corr[0]->via_joint_after);
    v.joints.assign(js.begin(), js.end());
    v.explanation = "after " + after + ", a structured residual remains that no catalogued effect explains: " + against + ".";
    if (!v.correlates.empty()) {
      v.explanation += " It follows ";
      for (size_t k = 0; k < v.correlates.size(); ++k) v.explanation += (k ? "; " : "") + v.correlates[k];
      v.explanation += ".";
    } else {
      v.explanation += " No single variable of the pose or context predicts it.";
    }
    if (!order.empty())
      v.explanation += " The selected effects explain only part of it; do not take them for the cause.";
  } else if (order.empty()) {
    v.effect = "none";
    if (significant_excess)
      v.explanation = "slightly above the noise floor (" + fmtg("%.4f", excess_mm) +
                      " mm in quadrature) but without structure: ";
    v.explanation += "the complete geometric model explains the data down to the noise: " + against + "; no catalogued effect improves the held-out error significantly.";
  } else {
    std::string best = order[0];
    for (const std::string& e : order)
      if (drop_of[e] > drop_of[best]) best = e;
    v.effect = best;
    for (int b : blocks_of[best])
      if (blocks_[b].joint >= 0) v.joints.push_back(blocks_[b].joint + 1);
    std::sort(v.joints.begin(), v.joints.end());
    v.explanation = best + (v.joints.empty() ? std::string() : " (" + jointList(v.joints) + ")") +
                    " causes the largest part of the gap: held-out RMS " + fmtg("%.4f", out_.baseline.rms_mm) + " -> " +
                    fmtg("%.4f", final_stats_.rms_mm) + " mm with " + after + "; " + against + ".";
    if (significant_excess)
      v.explanation += " What remains is slightly above the noise floor (" + fmtg("%.4f", excess_mm) +
                       " mm in quadrature) but follows no variable of the pose or context.";
    for (const Confounding& c : out_.confounded) {
      if (!c.indistinguishable) continue;
      if (c.effect_a == best) v.confounded_with.push_back(c.effect_b);
      if (c.effect_b == best) v.confounded_with.push_back(c.effect_a);
    }
    if (!v.confounded_with.empty()) {
      v.explanation += " Confounded: this data cannot tell it from ";
      for (size_t k = 0; k < v.confounded_with.size(); ++k) v.explanation += (k ? ", " : "") + v.confounded_with[k];
      v.explanation += " (see `confounded` for the measurements that would separate them).";
    }
  }
}

// ---------------------------------------------------------------------------------------
// Where: maps, joint profiles, correlations

std::vector<Correlation> Diagnoser::scan(const std::vector<Eigen::Vector3d>& E) const {
  const MeasurementSet& set = has_val_ ? val_ : fit_;
  const int n = M0_.dof();
  const int N = static_cast<int>(E.size());
  // joint Jacobian (position rows, per rad or mm) of each held-out pose at M0
  std::vector<Eigen::Matrix<double, 3, Eigen::Dynamic>> Jq(static_cast<size_t>(N));
  std::vector<Eigen::VectorXd> tau(static_cast<size_t>(N));
  KinematicWorkspace ws;
  for (int i = 0; i < N; ++i) {
    const Measurement& r = set.rows[static_cast<size_t>(i)];
    Jq[i] = jointJacobian(M0_, r.q, r.context, ws).topRows(3);
    tau[i] = gravityLoads(M0_, r.q, r.context);
  }
  struct Variable {
    std::string name;
    std::vector<Eigen::VectorXd> f;  // feature functions, each N values
    Eigen::VectorXd raw;
  };
  std::vector<Variable> vars;
  auto centred = [](Eigen::VectorXd v) {
    v.array() -= v.mean();
    return v;
  };
  auto varies = [](const Eigen::VectorXd& v) { return v.size() > 1 && (v.maxCoeff() - v.minCoeff()) > 1e-9; };
  for (int j = 0; j < n; ++j) {
    const bool revolute = M0_.nominal.joints[j].type == JointType::kRevolute;
    Eigen::VectorXd q(N), s(N), c(N);
    for (int i = 0; i < N; ++i) {
      const double v = set.rows[static_cast<size_t>(i)].q[j] * (revolute ? kDegToRad : 1.0);
      q[i] = v;
      s[i] = std::sin(v);
      c[i] = std::cos(v);
    }
    if (!varies(q)) continue;
    Variable var{"q" + std::to_string(j + 1), {centred(q)}, q};
    if (revolute) {
      var.f.push_back(s);
      var.f.push_back(c);
    }
    vars.push_back(var);
  }
  for (int j = 0; j < n; ++j) {
    Eigen::VectorXd t(N);
    for (int i = 0; i < N; ++i) t[i] = tau[i][j];
    if (varies(t)) vars.push_back({"tau" + std::to_string(j + 1), {centred(t)}, t});
  }
  auto scalar = [&](const std::string& name, bool has, auto get) {
    if (!has) return;
    Eigen::VectorXd v(N);
    for (int i = 0; i < N; ++i) v[i] = get(set.rows[static_cast<size_t>(i)]);
    if (varies(v)) vars.push_back({name, {centred(v)}, v});
  };
  scalar("payload_kg", set.has_payload, [](const Measurement& r) { return r.context.payload_kg; });
  scalar("temp_c", set.has_temperature, [](const Measurement& r) { return r.context.temp_c; });
  scalar("time_s", set.has_time, [](const Measurement& r) { return r.time_s; });
  if (set.has_direction)
    for (int j = 0; j < n; ++j)
      scalar("dir" + std::to_string(j + 1), true, [j](const Measurement& r) { return double(r.dir[static_cast<size_t>(j)]); });

  // folds for the regression
  std::vector<int> fold(static_cast<size_t>(N));
  for (int i = 0; i < N; ++i) fold[i] = has_val_ ? i % folds_ : fold_[i];
  Eigen::VectorXd y(3 * N), d0(N);
  for (int i = 0; i < N; ++i) {
    y.segment(3 * i, 3) = E[i];
    d0[i] = E[i].squaredNorm();
  }
  const double sst = d0.sum();
  std::vector<Correlation> out;
  for (const Variable& var : vars) {
    const int per = n + 3;
    const int p = per * static_cast<int>(var.f.size());
    Eigen::MatrixXd X(3 * N, p);
    for (int i = 0; i < N; ++i) {
      for (size_t k = 0; k < var.f.size(); ++k) {
        const double fv = var.f[k][i];
        X.block(3 * i, static_cast<Eigen::Index>(k) * per, 3, n) = fv * Jq[i];
        X.block(3 * i, static_cast<Eigen::Index>(k) * per + n, 3, 3) = fv * Eigen::Matrix3d::Identity();
      }
    }
    Eigen::VectorXd sc = X.colwise().norm();
    for (Eigen::Index c = 0; c < p; ++c) sc[c] = sc[c] > 1e-12 ? sc[c] : 1.0;
    X = X * sc.cwiseInverse().asDiagonal();
    const Eigen::MatrixXd XtX = X.transpose() * X;
    const Eigen::VectorXd Xty = X.transpose() * y;
    const double ridge = 1e-8;  // relative to unit-norm columns: keeps dependent columns solvable
    Eigen::VectorXd d1(N);
    for (int f = 0; f < folds_; ++f) {
      Eigen::MatrixXd M = XtX;
      Eigen::VectorXd v = Xty;
      for (int i = 0; i < N; ++i) {
        if (fold[i] != f) continue;
        M.noalias() -= X.middleRows(3 * i, 3).transpose() * X.middleRows(3 * i, 3);
        v.noalias() -= X.middleRows(3 * i, 3).transpose() * y.segment(3 * i, 3);
      }
      M.diagonal().array() += ridge;
      const Eigen::VectorXd c = M.ldlt().solve(v);
      for (int i = 0; i < N; ++i)
        if (fold[i] == f) d1[i] = (y.segment(3 * i, 3) - X.middleRows(3 * i, 3) * c).squaredNorm();
    }
    Correlation co;
    co.variable = var.name;
    co.r2_after = sst > 0 ? 1.0 - d1.sum() / sst : 0.0;
    co.p_after = pairedGain(d0, d1).p;
    // via: which joint's columns carry the fit on all poses
    Eigen::MatrixXd M = XtX;
    M.diagonal().array() += ridge;
    const Eigen::VectorXd c = M.ldlt().solve(Xty);
    double best = -1;
    for (int j = 0; j <= n; ++j) {
      Eigen::VectorXd part = Eigen::VectorXd::Zero(3 * N);
      for (size_t k = 0; k < var.f.size(); ++k) {
        const Eigen::Index off = static_cast<Eigen::Index>(k) * per;
        if (j < n) part += X.col(off + j) * c[off + j];
        else part += X.middleCols(off + n, 3) * c.segment(off + n, 3);
      }
      if (part.squaredNorm() > best) {
        best = part.squaredNorm();
        co.via_joint_after = j < n ? j + 1 : 0;
      }
    }
    // Pearson correlation of |e| with the raw variable
    Eigen::VectorXd mag(N);
    for (int i = 0; i < N; ++i) mag[i] = E[i].norm();
    const Eigen::VectorXd a = mag.array() - mag.mean(), b = var.raw.array() - var.raw.mean();
    const double den = a.norm() * b.norm();
    co.pearson_before = den > 0 ? a.dot(b) / den : 0.0;
    out.push_back(co);
  }
  return out;
}

void Diagnoser::where() {
  const MeasurementSet& set = has_val_ ? val_ : fit_;
  const int N = static_cast<int>(set.rows.size());
  const Eigen::Isometry3d T_base_world = M0_.T_world_base().inverse();
  std::vector<Eigen::Vector3d> pb(static_cast<size_t>(N));
  for (int i = 0; i < N; ++i) pb[i] = T_base_world * set.rows[static_cast<size_t>(i)].p_world_mm;
  auto rmsCells = [&](const std::vector<int>& cell, int cells, const std::vector<Eigen::Vector3d>& E, std::vector<double>* rms,
                      std::vector<int>* count) {
    std::vector<double> ss(static_cast<size_t>(cells), 0.0);
    count->assign(static_cast<size_t>(cells), 0);
    for (int i = 0; i < N; ++i) {
      if (cell[i] < 0) continue;
      ss[cell[i]] += E[i].squaredNorm();
      (*count)[cell[i]]++;
    }
    rms->assign(static_cast<size_t>(cells), kNaN);
    for (int c = 0; c < cells; ++c)
      if ((*count)[c] > 0) (*rms)[c] = std::sqrt(ss[c] / (*count)[c]);
  };
  auto edges = [](double lo, double hi, int k) {
    std::vector<double> e(static_cast<size_t>(k + 1));
    if (!(hi > lo)) hi = lo + 1;
    for (int i = 0; i <= k; ++i) e[i] = lo + (hi - lo) * i / k;
    return e;
  };
  auto bin = [](const std::vector<double>& e, double v) {
    const int k = static_cast<int>(e.size()) - 1;
    int b = static_cast<int>(std::floor((v - e[0]) / (e[k] - e[0]) * k));
    return std::clamp(b, 0, k - 1);
  };
  const int g = o_.grid_cells;
  for (int plane = 0; plane < 2; ++plane) {
    FieldMap fm;
    fm.plane = plane == 0 ? "base_xy" : "base_rz";
    fm.x_label = plane == 0 ? "x (mm, robot base)" : "radius from axis 1, r (mm)";
    fm.y_label = plane == 0 ? "y (mm, robot base)" : "height z (mm, robot base)";
    std::vector<double> xs(static_cast<size_t>(N)), ys(static_cast<size_t>(N));
    for (int i = 0; i < N; ++i) {
      xs[i] = plane == 0 ? pb[i].x() : std::hypot(pb[i].x(), pb[i].y());
      ys[i] = plane == 0 ? pb[i].y() : pb[i].z();
    }
    fm.x_edges_mm = edges(*std::min_element(xs.begin(), xs.end()), *std::max_element(xs.begin(), xs.end()), g);
    fm.y_edges_mm = edges(*std::min_element(ys.begin(), ys.end()), *std::max_element(ys.begin(), ys.end()), g);
    std::vector<int> cell(static_cast<size_t>(N));
    for (int i = 0; i < N; ++i) cell[i] = bin(fm.y_edges_mm, ys[i]) * g + bin(fm.x_edges_mm, xs[i]);
    rmsCells(cell, g * g, E0_, &fm.rms_before_mm, &fm.count);
    rmsCells(cell, g * g, E1_, &fm.rms_after_mm, &fm.count);
    for (int c = 0; c < g * g; ++c) {
      if (fm.count[c] < 3) continue;
      Region r;
      r.plane = fm.plane;
      r.x0_mm = fm.x_edges_mm[c % g];
      r.x1_mm = fm.x_edges_mm[c % g + 1];
      r.y0_mm = fm.y_edges_mm[c / g];
      r.y1_mm = fm.y_edges_mm[c / g + 1];
      r.count = fm.count[c];
      r.rms_before_mm = fm.rms_before_mm[c];
      r.rms_after_mm = fm.rms_after_mm[c];
      out_.worst_regions.push_back(r);
    }
    out_.fields.push_back(fm);
  }
  std::sort(out_.worst_regions.begin(), out_.worst_regions.end(),
            [](const Region& a, const Region& b) { return a.rms_before_mm > b.rms_before_mm; });
  if (out_.worst_regions.size() > 5) out_.worst_regions.resize(5);
  for (int j = 0; j < M0_.dof(); ++j) {
    JointProfile jp;
    jp.joint = j + 1;
    jp.name = M0_.nominal.joints[j].name;
    jp.unit = M0_.nominal.joints[j].type == JointType::kRevolute ? "deg" : "mm";
    double lo = 1e300, hi = -1e300;
    for (const Measurement& r : set.rows) {
      lo = std::min(lo, r.q[j]);
      hi = std::max(hi, r.q[j]);
    }
    jp.edges = edges(lo, hi, o_.joint_bins);
    std::vector<int> cell(static_cast<size_t>(N));
    for (int i = 0; i < N; ++i) cell[i] = bin(jp.edges, set.rows[static_cast<size_t>(i)].q[j]);
    rmsCells(cell, o_.joint_bins, E0_, &jp.rms_before_mm, &jp.count);
    rmsCells(cell, o_.joint_bins, E1_, &jp.rms_after_mm, &jp.count);
    out_.joints.push_back(jp);
  }
  std::vector<int> idx(static_cast<size_t>(N));
  std::iota(idx.begin(), idx.end(), 0);
  std::sort(idx.begin(), idx.end(), [&](int a, int b) { return E0_[a].squaredNorm() > E0_[b].squaredNorm(); });
  for (int k = 0; k < std::min(5, N); ++k) {
    const int i = idx[k];
    out_.worst_poses.push_back({set.rows[static_cast<size_t>(i)].line, i, E0_[i].norm(), E1_[i].norm()});
  }
}

Diagnosis Diagnoser::run() {
  const auto t0 = std::chrono::steady_clock::now();
  noiseFloor();
  baseline();
  columns();
  linearise();
  selection();
  ranking();
  confounding();
  shrink();  // exact held-out residuals of the baseline and of the final model
  {
    const std::vector<Correlation> before = scan(E0_);
    std::vector<Correlation> after = scan(E1_);
    for (size_t k = 0; k < after.size(); ++k) {
      after[k].r2_before = before[k].r2_after;
      after[k].p_before = before[k].p_after;
      after[k].pearson_before = before[k].pearson_before;
    }
    out_.correlations = after;
  }
  verdict();
  where();
  char tests[1024];
  std::snprintf(tests, sizeof tests,
                "held-out error: %s; selection: forward over (effect, joint) blocks, one-sided paired z-test of the "
                "per-pose held-out squared errors, p < %.3g / (blocks tried in the round) (Bonferroni) and a drop of "
                "the held-out mean squared error of at least %.3g%%; ranking and selection on the model linearised "
                "at the baseline, shrink table and verdict on exact non-linear refits; noise floor: z-test of the "
                "held-out squared errors against noise plus parameter variance, p < %.3g; confounding: an effect "
                "whose significant gain on the baseline drops below half once another is in the model; structure "
                "scan: the residual regressed on each variable times the joint Jacobian and a translation, %d-fold "
                "cross-validated",
                out_.validation_method.c_str(), o_.alpha, 100 * o_.min_gain, o_.floor_alpha, folds_);
  out_.tests = tests;
  for (const auto& kv : effect_note_)
    if (kv.first.find(':') != std::string::npos) out_.notes.push_back(kv.second);
  out_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out_;
}

}  // namespace

Diagnosis diagnose(const RobotModel& start, const MeasurementSet& data, const MeasurementSet* validation,
                   const DiagnoseOptions& options) {
  Diagnoser d(start, data, validation, options);
  return d.run();
}

}  // namespace accura
