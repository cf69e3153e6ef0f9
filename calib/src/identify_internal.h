// accura: internals of the identification (identify.h), shared by its files and by the
// diagnosis:
//   identify.cpp           options, registration, the problem's set-up, identify() in steps
//   identify_rows.cpp      the residual stacking: every row's weighted residual and Jacobian on
//                          the kinematic core (KinematicModel prepared once per evaluation
//                          point, one workspace, no allocation per row)
//   identify_solve.cpp     the Ceres problem on the stacked rows
//   identify_normal.cpp    joint maps without a robust loss: the normal equations pose by pose
//                          and a Levenberg-Marquardt on them that follows Ceres' iteration
//   identify_analysis.cpp  identifiability, weights (variance components), uncertainties and
//                          the summary's diagnostics
//   identify_mapcv.cpp     joint maps without a stated knot spacing or smoothness
// Not a public header.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "accura/calib/identify.h"
#include "accura/calib/kinematic_core.h"
#include "accura/calib/kinematics.h"

namespace accura::calib::identify_detail {

/// Residual weights of one row: sqrt(weight) / sigma per component (position mm, rotation rad).
struct RowWeights {
  int dim = 3;
  Vector6d w = Vector6d::Ones();
};

/// Tracker stations. Rows of a data set s > 0 measured from its own station are predicted as
/// T_s * T_world_tcp, T_s = (expSO3(w_s), t_s) a correction in the world frame; its 6
/// parameters (t_s mm, w_s rad) follow the layout's parameters in x. Station 0 is the model's
/// own T_world_base (no correction).
struct Stations {
  std::vector<int> of_row;  ///< station per row
  int extra = 0;            ///< number of stations beyond the first
  size_t offset = 0;        ///< x index of the first station parameter (= layout size)

  Eigen::Isometry3d transform(const std::vector<double>& x, int s) const;
};

/// How the Jacobian over the layout is computed: the core's parameter Jacobian on the layout
/// without the joint maps' coefficients plus one unit column (a unit dtheta, or dd) per mapped
/// joint; a coefficient's column is that unit column times its basis function at q
/// (joint_map.h), and only 4 per mapped joint are non-zero: this keeps the cost independent of
/// the maps' resolution.
struct JacobianPlan {
  std::vector<ParamInfo> columns;
  std::vector<int> x_of;                ///< x index of each column; -1: the unit column of a mapped joint
  std::vector<int> unit_joint;          ///< joint of each column (unit columns), else -1
  std::vector<std::vector<int>> map_x;  ///< per joint: x index of each map coefficient (empty: not mapped)
  size_t P = 0;                         ///< layout size
};
JacobianPlan makePlan(const RobotModel& model, const std::vector<ParamInfo>& layout);

/// The residual stacking shared by identify() and the diagnosis: a RobotModel prepared once
/// (KinematicModel) at the current evaluation point and the workspace of one thread. prepare()
/// again after the model's values change.
class RowStack {
 public:
  RowStack(const RobotModel& model, const JacobianPlan& plan, const Stations& stations);
  /// Prepares the kinematic core for `model` (same robot, new parameter values).
  void prepare(const RobotModel& model);
  /// Pose of row i (data row `row`, station st.of_row[i]) with its station applied; with
  /// `jacobian`, its Jacobian over x (6 x x.size(), rows [dp mm; dphi rad]) into J(): the
  /// model's columns rotated into the station's world, then the station's 6 columns.
  Eigen::Isometry3d pose(const std::vector<double>& x, const Measurement& row, size_t i, bool jacobian);
  const Eigen::MatrixXd& J() const { return J_; }
  /// Pose of row i like pose(), with its Jacobian in compact form: only the columns of x that
  /// can be non-zero for this row (every parameter of the layout but the joint maps', 4
  /// coefficients per mapped joint, the row's station if not 0) in Jc() (6 x idx().size(), rows
  /// as in J()), their x indices in idx() (-1: a map coefficient outside the layout). The cost
  /// does not grow with the maps' resolution.
  Eigen::Isometry3d poseCompact(const std::vector<double>& x, const Measurement& row, size_t i);
  const Eigen::MatrixXd& Jc() const { return Jc_; }
  const std::vector<int>& idx() const { return idx_; }
  /// Weighted stacked Jacobian over x (rows: each row's `dim` components in turn; J may be
  /// null) and weighted residual (model minus measurement) of every row of `data`.
  void stack(const std::vector<double>& x, const MeasurementSet& data, const std::vector<RowWeights>& weights,
             Eigen::MatrixXd* J, Eigen::VectorXd* r);
  const KinematicModel& core() const { return km_; }

 private:
  const RobotModel* model_;  // the joint maps' knots (their basis functions)
  KinematicModel km_;
  const JacobianPlan& plan_;
  const Stations& st_;
  KinematicFrames f_;
  LinkFrames links_;
  // Station s's columns of J (at c) for T = Ts T_model, the model's first model_cols columns
  // rotated into the station's world.
  void stationColumns(const std::vector<double>& x, int s, const Eigen::Isometry3d& Ts, const Eigen::Isometry3d& T,
                      Eigen::MatrixXd& J, Eigen::Index model_cols, Eigen::Index c) const;
  Eigen::MatrixXd Jcols_, J_, Jc_;
  std::vector<int> idx_;
  bool direct_ = false;  // the plan's columns are x's first P entries in order (no joint maps)
};

/// Row error (model minus measurement): position (mm), with dim 6 also the rotation (rad).
Vector6d rowError(const Eigen::Isometry3d& T, const Measurement& row, int dim);

/// The data with each row's measurement carried into station 0's world (p' = R^T (p - t),
/// R' = R^T R): what the model predicts directly, for statistics.
MeasurementSet inStationZero(const MeasurementSet& data, const Stations& st, const std::vector<double>& x);

/// A --params item: a group name, optionally restricted to some joints: "gear_periodic:j1+j2".
/// Returns false with *error on a malformed item. `joints` is empty when all joints are meant.
/// joint_map may end in "@KNOT" (knot spacing, e.g. "@3deg"): *knot gets it (NaN when absent).
bool parseGroupSpec(const std::string& full_spec, std::string* name, std::set<int>* joints, std::string* error,
                    double* knot = nullptr);
/// The rows of every set in one set (flags: those all sets have) and the set of each row.
MeasurementSet combine(const std::vector<MeasurementSet>& sets, std::vector<int>* set_of_row);
/// Every row has an orientation.
bool allOrientation(const MeasurementSet& data);
/// One station per data set (station 0: the model's own), or one for all when `same`.
Stations stationsFor(const std::vector<int>& set_of_row, size_t sets, bool same);
std::string fmtNum(double v);

/// A weighted penalty row over x: coefficients by x index (joint-map regularisation).
struct PenaltyRow {
  std::vector<std::pair<int, double>> terms;
};

/// One identification problem: the model, the rows, the parameters x (the layout's values,
/// then 6 per extra station) and which of them are free, the weights and penalty rows.
struct Problem {
  RobotModel model;  ///< the layout's values of x are applied after every solve
  MeasurementSet data;   ///< every row of every set
  MeasurementSet data0;  ///< the rows in station 0's world (inStationZero), after every solve
  std::vector<int> set_of_row;
  Stations st;
  std::vector<ParamInfo> layout;
  JacobianPlan plan;
  size_t P = 0, X = 0;  ///< layout size; parameters with the stations
  int dim = 3;          ///< components per row (6 with orientation)
  int m_eq = 0;         ///< equations (rows x dim)
  size_t n_map = 0;     ///< joint-map coefficients in the layout
  bool orientation = false;
  bool sparse = false;  ///< joint maps: sparse normal equations
  std::vector<double> x;
  std::vector<bool> free;
  std::vector<RowWeights> weights;
  std::vector<PenaltyRow> penalties;
  bool isMap(size_t k) const { return k < P && layout[k].kind == ParamKind::kJointMap; }
  /// Weighted stacked Jacobian over x (J may be null) and weighted residual at the model.
  void stack(Eigen::MatrixXd* J, Eigen::VectorXd* r) const;

  /// The last stacked Jacobian and residual with the point and weights they were computed at:
  /// a pass at the same point with the same weights takes them (the identifiability pass and
  /// the first solve start at the same x; the covariance pass is at the last solve's point).
  struct Stacked {
    std::vector<double> x;
    std::vector<RowWeights> weights;
    Eigen::MatrixXd J;
    Eigen::VectorXd r;
    bool valid = false;
  };
  mutable Stacked last;
  /// The stacked Jacobian and residual of the solves' evaluations (identify_solve.cpp): one
  /// buffer for every solve of this problem (3000 x 27 doubles are 648 kB: allocated afresh
  /// per solve, their pages are faulted in again each time).
  mutable Eigen::MatrixXd solve_J;
  mutable Eigen::VectorXd solve_r;
  /// The (parameters x parameters) matrices of solveNormal (identify_normal.cpp), kept for every
  /// solve of this problem for the same reason: the normal matrix, the damped one factorised in
  /// place, the penalty rows' A^T A.
  mutable Eigen::MatrixXd normal_N, normal_M, normal_AtA;
  /// last holds the stacking at xs with the current weights.
  bool lastAt(const std::vector<double>& xs) const;
  void keep(const std::vector<double>& xs, const Eigen::MatrixXd& J, const Eigen::VectorXd& r) const;
};

/// The weights of the rows: the std columns of the data, or given stds, or stds estimated
/// from the residuals, plus an unmodelled-error term per component type (method.md).
struct Weighting {
  bool file_pos = false, file_rot = false;          ///< per-row std columns
  bool estimate_pos = false, estimate_rot = false;  ///< std estimated from the residuals
  double pos_std_mm = 0.05, rot_std_deg = 0.005;
  double tau_pos_mm = 0, tau_rot_rad = 0;
  Weighting(const Problem& pb, const IdentifyOptions& options);
  /// Std of component k (0..2 mm, 3..5 rad) of a row, before its weight column and tau.
  double baseStd(const Measurement& r, int k) const;
  /// Fills pb.weights: sqrt(weight) / sqrt(std^2 + tau^2).
  void apply(Problem& pb) const;
  /// Re-estimates the stds and tau from the residuals at pb.model; returns the relative change.
  double reestimate(const Problem& pb, const IdentifyOptions& options, int p_free);
  /// summary.weighting and the std / model-error fields.
  void describe(const Problem& pb, IdentifySummary& s) const;
};

/// Identifiability at the starting point: fixes the candidates (not the joint maps'
/// coefficients) that have no effect or depend on others (summary.fixed, with the reason),
/// fills pb.free, the condition numbers and the observability index; col_sq gets the squared
/// norm of every column of the weighted stacked Jacobian (over x). Returns the number of kept
/// candidates.
int identifiability(Problem& pb, const IdentifyOptions& options, IdentifySummary& s, Eigen::VectorXd* col_sq);
/// The joint maps' regularisation rows (smoothness, centring) into pb.penalties; col_sq as
/// identifiability() returns it.
void penaltyRows(Problem& pb, double smoothing, const Eigen::VectorXd& col_sq);
/// The joint maps' regularisation rows again, scaled to the weights in force now (the weighting
/// rounds change them: the rows' scale is the maps' weighted columns', so that the smoothness
/// stays relative to the data's own weight). No-op without maps.
void refreshPenaltyRows(Problem& pb, double smoothing);
/// How a solve ended.
struct SolveResult {
  std::string termination;  ///< Ceres' termination type and message
  int iterations = 0;
  bool failure = false;     ///< Ceres reported FAILURE
  std::string message;
};
/// The Levenberg-Marquardt's initial trust-region radius with joint maps (both solvers; Ceres'
/// default, 1e4, elsewhere). In the Jacobi-scaled variables the LM adds diagonal / radius to the
/// normal matrix: at 1e4 that damping is larger than the smallest eigenvalues of the smoothed
/// maps' system, every step falls short (the model predicts the decrease exactly, rho = 1) and
/// the solve crawls until the parameter tolerance stops it short of the optimum (5-6 steps per
/// variance round on the KR 16 of bench_diagnose, 2e-4 of the cost left). At 1e8 the first step
/// is the Gauss-Newton step and the next ends the solve; a step that does not decrease the cost
/// still shrinks the radius as before (by 2, 4, 8, ...: below 1e4 after 5 refusals in a row).
constexpr double kJointMapInitialRadius = 1e8;
/// Levenberg-Marquardt on the stacked rows from pb.x; applies the solution to pb.model and
/// refreshes pb.data0. Ceres' on the stacked Jacobian, except with joint maps and no robust
/// loss: then solveNormal.
SolveResult solve(Problem& pb, const IdentifyOptions& options, bool robust);
/// While one lives (in this thread) solve() takes Ceres also where it would take solveNormal:
/// the tests compare the two optima.
class CeresForJointMaps {
 public:
  CeresForJointMaps();
  ~CeresForJointMaps();
  CeresForJointMaps(const CeresForJointMaps&) = delete;
  CeresForJointMaps& operator=(const CeresForJointMaps&) = delete;

 private:
  bool before_;
};
/// A parameter block of x (Ceres' unit of parameters): x indices [start, start + size).
struct Block {
  int start, size;
};
/// The parameter blocks of x: one per base, tool, joint, compliance, extra station; the joint
/// maps' coefficients in blocks of 4. Returns the block of each x index.
std::vector<int> parameterBlocks(const Problem& pb, std::vector<Block>* blocks);

/// The free parameters of a problem as the columns of its normal equations.
struct FreeColumns {
  explicit FreeColumns(const Problem& pb);
  std::vector<int> col_of;  ///< per x index its column, -1: fixed
  std::vector<int> x_of;    ///< per column its x index
  Eigen::Index n = 0;
};
/// The normal equations of the weighted rows at `model` (the layout's values in x applied) and
/// x over the free columns, accumulated row by row from the compact Jacobians (RowStack::
/// poseCompact): N += J_i^T J_i (N's lower triangle; the strictly upper one is zero), g +=
/// J_i^T r_i. r (may be null) gets the stacked weighted residual of the rows. Returns 0.5
/// |r|^2. The penalty rows are not included.
double rowNormalEquations(const Problem& pb, const RobotModel& model, const std::vector<double>& x,
                          const FreeColumns& fc, Eigen::MatrixXd* N, Eigen::VectorXd* g, Eigen::VectorXd* r);
/// The penalty rows' values at x (fixed parameters included), one per PenaltyRow.
Eigen::VectorXd penaltyValues(const Problem& pb, const std::vector<double>& x);
/// Adds the penalty rows A (over the free columns) to the normal equations from their terms:
/// A^T A to *N's lower triangle (may be null), A^T value to *g (may be null; value as
/// penaltyValues()).
void addPenaltyNormal(const Problem& pb, const FreeColumns& fc, const Eigen::VectorXd* value, Eigen::MatrixXd* N,
                      Eigen::VectorXd* g);
/// Levenberg-Marquardt on the normal equations accumulated pose by pose (rowNormalEquations,
/// the penalty rows added analytically, a dense Cholesky factorisation per step): the problem
/// with joint maps and no robust loss. Reproduces Ceres' trust-region iteration as solve()
/// configures it (Jacobi scaling, the LM diagonal, step acceptance and radius updates, the
/// function / parameter / gradient tolerances, the termination messages), so both end at the
/// same optimum; the stacked Jacobian is never formed.
SolveResult solveNormal(Problem& pb, const IdentifyOptions& options);
/// Covariance of the free parameters at the solution, the estimates with their sigmas, the
/// final cost, the variance factor and the down-weighted rows.
void uncertainties(Problem& pb, const IdentifyOptions& options, bool robust, IdentifySummary& s,
                   Eigen::VectorXd* r);
/// Stations per set, joint-map reports, suspicious rows and plausibility warnings.
void finishSummary(const Problem& pb, const std::vector<MeasurementSet>& sets, const Eigen::VectorXd& r,
                   double smoothing, IdentifySummary* s);
/// joint_map without a stated knot spacing or smoothness: fit without maps, choose both by
/// blocked cross-validation on the problem linearised there, then identify with them.
RobotModel identifyWithMapCv(const RobotModel& start, const std::vector<MeasurementSet>& sets,
                             const IdentifyOptions& options, double stated_knot, IdentifySummary* summary_out);

}  // namespace accura::calib::identify_detail
