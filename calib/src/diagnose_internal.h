// accura: internals of the diagnosis (diagnose.h), shared by its files:
//   diagnose.cpp            options, data preparation, the run, the entry point
//   diagnose_fit.cpp        noise floor, baseline, candidate columns, linearised and exact fits
//   diagnose_selection.cpp  forward selection, ranking, confounding, shrink table
//   diagnose_verdict.cpp    the verdict
//   diagnose_maps.cpp       where: maps over the workspace and the joints, the structure scan
// Not a public header.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "accura/calib/diagnose.h"
#include "accura/calib/identify.h"
#include "accura/calib/kinematics.h"
#include "accura/calib/text.h"  // formatNumber: the one number formatter

namespace accura::calib::diagnose_detail {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
/// Fewest held-out poses of a data set on which the cross-validation re-registers its station
/// (6 parameters on 3 coordinates a pose: with 20 poses the registration takes about a tenth of
/// the noise's squared error, alike for every model compared).
constexpr int kReregisterPoses = 20;

/// One-sided upper tail of the standard normal distribution.
double upperTail(double z);

/// Paired comparison of per-pose squared errors: old minus new.
struct Gain {
  double gain = 0;  ///< mean(old - new) / mean(old)
  double z = 0, p = 1;
};
Gain pairedGain(const Eigen::VectorXd& d_old, const Eigen::VectorXd& d_new);

std::string jointList(const std::vector<int>& joints);
/// The one number formatter (text.h) under the name the diagnosis code uses.
inline std::string fmtg(const char* f, double v) { return formatNumber(f, v); }
void statsOf(const std::vector<double>& e, HeldOutStats* s);
/// What each effect needs to be told apart from the others.
std::string separator(const std::string& effect, const std::vector<int>& joints);
/// Repeated joint configurations (measurements.h: repeatedConfigurations, the one definition
/// identify counts distinct configurations with).
inline std::vector<std::vector<int>> repeatGroups(const MeasurementSet& set, double tol,
                                                  std::vector<std::pair<int, int>>* pairs = nullptr,
                                                  const std::vector<int>* set_of_row = nullptr) {
  return repeatedConfigurations(set, tol, pairs, set_of_row);
}
/// Cholesky solve of a normal system with unit-scaled columns; false when it is singular
/// (a pivot ratio below 1e-7, a condition number above 1e14).
bool solveSpd(const Eigen::MatrixXd& M, const Eigen::VectorXd& v, Eigen::LLT<Eigen::MatrixXd>* llt,
              Eigen::VectorXd* x);
/// The joint maps are fitted after the other parameters, to what those leave (docs/diagnosis.md):
/// the normal system M x = v solved for the columns that are not maps (is_map false) alone, then
/// for the maps' with those held. *llt (may be null) gets the joint factorisation of M
/// (leverages, covariance). One kind of column alone: solveSpd.
bool solveStaged(const Eigen::MatrixXd& M, const Eigen::VectorXd& v, const std::vector<bool>& is_map,
                 Eigen::LLT<Eigen::MatrixXd>* llt, Eigen::VectorXd* x);
/// Why a fit's normal matrix can be singular when the data say so: its `rows` hold too few
/// distinct joint configurations (`groups`: the repeated configurations) for `parameters`
/// (": its N fit rows hold only K distinct ..."); empty otherwise.
std::string singularWhy(const std::vector<std::vector<int>>& groups, const std::vector<int>& rows, int parameters);
/// Canonical correlation of two blocks' weighted columns with the geometry projected out.
double canonicalCorrelation(const Eigen::MatrixXd& Jw, const std::vector<int>& G, const std::vector<int>& a,
                            const std::vector<int>& b);

class Diagnoser {
 public:
  Diagnoser(const RobotModel& start, const MeasurementSet& data, const MeasurementSet* validation,
            const DiagnoseOptions& options);
  Diagnosis run();
  /// Several data sets: the data set of each fit row and the files (before run()). With
  /// `own_stations` (each set measured from its own tracker station), every held-out error of the
  /// cross-validation is taken after re-registering the station of each data set on its held-out
  /// rows (reregister), as `identify --validate-station new` does with new data.
  void setRowSets(const std::vector<int>& set_of_row, const std::vector<std::string>& files, bool own_stations);

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
  /// Cross-validation folds with their per-fold normal equations (weighted, scaled columns).
  struct Scheme {
    std::string name;                       // "interleaved", "pose order", "q3 blocks", "data sets"
    std::vector<std::vector<int>> poses;    // fit rows held out in each fold
    std::vector<Eigen::MatrixXd> At;        // per fold: the normal equations without its rows
    std::vector<Eigen::VectorXd> bt;
    /// Schemes over a joint's angle: the folds at either end of the range (held out, the
    /// training data do not reach them: what new data outside the covered range see).
    std::vector<int> end_folds;
  };
  struct Exact {
    std::vector<Eigen::Vector3d> e;  // held-out residual per pose (measured - model)
    HeldOutStats stats;
    RobotModel model_all;            // fitted on all fit data
  };

  void prepareData(const MeasurementSet& data, const MeasurementSet* validation);
  void noiseFloor();
  void repeats();
  IdentifyOptions baselineOptions() const;
  void baseline();
  /// joint_map candidates: a zero map on the covered interval of every joint that the fit data
  /// cover over at least 4 knot spacings (M0_'s deviations; their columns become blocks).
  void addJointMaps();
  /// The joint maps' smoothness and centring penalties in the scaled columns (penalty_).
  void mapPenalty();
  void robust();
  void robustWeights(const std::vector<double>& residual_mm);
  void columns();
  void linearise();
  /// The fit rows as 6D data for identify (fit_ keeps every row's measured orientation and its
  /// std, with the flags off; rot_ok_ says which rows have one).
  MeasurementSet fitWithOrientation() const;
  void schemes();
  /// Held-out squared errors of the linearised fit with the columns S (cached until the next
  /// linearisation or set of schemes).
  Eval evaluate(const std::vector<int>& S, bool leverage = false) const;
  Eval evaluateUncached(const std::vector<int>& S, bool leverage) const;
  Eval cvEval(const std::vector<int>& S, const Scheme& scheme, bool leverage) const;
  void buildScheme(Scheme* s) const;
  /// Held-out residuals `e` (measured - model, mm, per pose of `held`) after a rigid re-registration
  /// of each data set's station on its held-out rows (6 parameters, linear least squares in the
  /// fit's weights; a set with fewer than kReregisterPoses held-out poses keeps the training's).
  void reregister(const std::vector<int>& held, std::vector<Eigen::Vector3d>* e) const;
  /// Adds the weighted normal equations of the fit poses `poses` (scaled columns, each row over
  /// its non-zero columns only) to the lower triangle of *A and to *b; mirrorLower() completes A.
  /// meat: with the row weights w^2 s of the noise-only covariance (mF_, mR_), b untouched.
  void addNormal(const std::vector<int>& poses, Eigen::MatrixXd* A, Eigen::VectorXd* b, bool meat = false) const;
  /// Prediction variance (mm^2) of the held-out rows `held` of the fit with the columns
  /// S(act) whose normal matrix llt factors, from the noise alone; `B` that fit's meat on S.
  void sandwichLeverage(const Eigen::LLT<Eigen::MatrixXd>& llt, const Eigen::MatrixXd& Jrows, const Eigen::MatrixXd& B,
                        Eigen::VectorXd* lev) const;
  void blockedSchemes();
  /// The checks an addition to the model must pass besides the held-out test: physically
  /// plausible parameters and a gain that survives blocked cross-validation. Fills *why when not.
  bool admissible(const std::vector<int>& cur, const std::vector<int>& add, std::string* why, double* blocked_gain,
                  std::string* scheme) const;
  /// Whether an effect block given by a formula of its joint's angle (joint_scale, gear_periodic)
  /// can carry over to the joint's whole range from the range the fit data cover: a periodic term
  /// needs 162 deg (0.45 turn) of it, and no such term is extrapolated to joint limits that lie
  /// beyond the covered range by more than half its width. Fills *why when not. Other effects
  /// always carry over (their blocked cross-validation judges them).
  bool carriesOver(const Block& B, std::string* why) const;
  /// The range of joint j (0-based; deg or mm) the training rows of fold f of a scheme cover.
  std::pair<double, double> trainingRange(const Scheme& sc, size_t f, int j) const;
  std::vector<std::string> implausible(const std::vector<EffectParameter>& ps) const;
  std::vector<Coverage> coverageOf(const std::string& effect, const std::vector<int>& joints) const;
  Eigen::VectorXd fitAll(const std::vector<int>& S, double* chi2, Eigen::VectorXd* sigma) const;
  /// Weighted rows (3 per pose, scaled columns) and weighted residuals of the fit poses.
  struct RowSystem {
    Eigen::MatrixXd Jw;
    Eigen::VectorXd rw;
  };
  /// Gauss-Newton refit of the columns S on the fit poses `rows`, from M0: the columns that are
  /// not joint maps', then the maps' with those held (solveStaged). at_m0: the system of every
  /// pose at M0 for the first stage's columns, used for its first iteration when it holds it,
  /// else filled when `rows` are all poses in order.
  RobotModel gnFit(const std::vector<int>& S, const std::vector<int>& rows, RowSystem* at_m0 = nullptr) const;
  /// Gauss-Newton over the columns S from `start` (at_m0 only when start is M0).
  RobotModel gnFitFrom(const RobotModel& start, const std::vector<int>& S, const std::vector<int>& rows,
                       RowSystem* at_m0) const;
  /// The fit poses of every interleaved fold but f (its training rows), in order.
  std::vector<int> trainingRows(int f) const;
  /// Per column of S: whether it is a joint map's coefficient.
  std::vector<bool> mapMask(const std::vector<int>& S) const;
  Exact exact(const std::vector<int>& S);
  void floorTest(const Eval& lin, const std::vector<Eigen::Vector3d>& e, const std::vector<bool>& keep,
                 HeldOutStats* s) const;
  std::vector<int> withBlocks(const std::vector<int>& blocks) const;
  std::vector<EffectParameter> parametersOf(const std::vector<int>& S, const std::string& effect) const;
  struct Forward {
    std::vector<int> blocks;        // selected, in order
    std::vector<double> drops;      // held-out MSE drop credited to each (mm^2)
    Eval cur;                       // held-out errors of the final selection
    std::vector<Gain> last_round;   // per block: gain on the final selection
    bool has_best_single = false;   // the best block of the first round, passing or not
    std::vector<int> best_single;   // its blocks (a unit: all joint_map blocks together)
    Eval best_single_eval;
    std::vector<Rejected> rejected;  // passed the held-out test, failed admissible()
    std::vector<double> blocked_gain;  // per selected block (NaN when not checked)
    std::vector<std::string> blocked_scheme;
  };
  struct ForwardRun;  // the state and steps of one forward selection (diagnose_selection.cpp)
  Forward forward(const std::vector<int>& candidates) const;
  void selection();
  void ranking();
  void confounding();
  void shrink();
  void verdict();
  /// The verdict's closing sentence naming the effects rejected as coverage-limited (carriesOver), or "".
  std::string coverageLimitedSentence() const;
  void where();
  /// The structure scan of each residual set in Es (one per pose each): per variable, the
  /// cross-validated regression of the residual on it (the sets share the factorisations).
  std::vector<std::vector<Correlation>> scan(const std::vector<const std::vector<Eigen::Vector3d>*>& Es) const;
  void spectra();
  void orientation();

  // inputs
  DiagnoseOptions o_;
  RobotModel start_;
  MeasurementSet fit_, val_;
  bool has_val_ = false;
  int m_ = 0, nv_ = 0;  // fit / validation poses
  int folds_ = 5;
  std::vector<int> set_of_row_;            // per fit pose: its data set (empty: one)
  bool own_stations_ = false;              // the data sets come from different stations
  std::vector<int> fold_;                  // per fit pose
  std::vector<std::vector<int>> fold_poses_;
  // noise
  std::vector<Eigen::Vector3d> w_fit_, w_val_;  // per-axis weights sqrt(weight)/sigma
  Eigen::VectorXd var_fit_, var_val_;          // per pose: sum of the three noise variances (mm^2)
  std::vector<Eigen::Vector3d> noise_fit_;     // per fit pose: the noise std per axis (mm; 0: unknown)
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
  Eigen::MatrixXd A_;                 // data normal matrix plus the maps' penalty
  Eigen::VectorXd b_;
  Eigen::MatrixXd penalty_;           // the maps' penalty (scaled columns; zero elsewhere)
  std::vector<bool> is_map_;          // per compact column
  std::vector<std::vector<int>> row_nz_;  // per fit row: its columns that are not zero (maps are sparse)
  double map_knot_ = 0;               // knot spacing of the diagnosis' maps (deg or mm; 0: none)
  double rr_ = 0;
  mutable std::map<std::pair<std::vector<int>, bool>, Eval> eval_cache_;  // evaluate()'s answers
  Scheme interleaved_;              // the ordinary cross-validation (fold_poses_)
  std::vector<Scheme> blocked_;     // contiguous blocks of each joint's angle and of the pose order
  // repeats, robust weights, orientation
  std::vector<std::vector<int>> groups_;   // repeated configurations of the fit data
  std::vector<double> robust_w_;           // per fit row (1: not down-weighted)
  std::vector<Eigen::Quaterniond> R_fit_;  // measured orientation of the fit rows (6D data)
  // 6D data in the linearised fits (use_orientation): per pose 3 orientation rows (rad; weight 0
  // where a row has none) beside the 3 position rows
  bool use_rot_ = false;
  bool fit_has_std_rot_ = false;        // the fit data have orientation std columns
  std::vector<Eigen::Vector3d> w_rot_;  // per-axis weights of the orientation rows (1/rad)
  Eigen::MatrixXd JR_;                  // orientation Jacobian (rad per scaled column)
  Eigen::VectorXd rR_, wR_;             // measured minus model (rad), weights
  double equations_ = 0;                // weighted equations of the fit (3 per pose, 3 more with an orientation)
  // The weights above carry the unmodelled-error term: the prediction variance from the noise
  // alone is the sandwich A^-1 B A^-1, B the normal matrix with row weights w^2 s (s the noise
  // std): these weights and B over every fit row (6D data only; else B = A).
  std::vector<Eigen::Vector3d> noise_rot_;  // per fit pose: the orientation noise std (rad)
  Eigen::VectorXd mF_, mR_;
  Eigen::MatrixXd Bm_;
  std::vector<bool> rot_ok_;               // row has a measured orientation
  std::vector<Eigen::Quaterniond> R_val_;  // the same for the validation rows
  std::vector<bool> rot_ok_val_;
  bool fit_has_rot_ = false;
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
  std::vector<double> sel_blocked_gain_;
  std::vector<std::string> sel_blocked_scheme_;
};

}  // namespace accura::calib::diagnose_detail
