// accura: identification of the complete model from measured poses (method.md section 3):
// closed-form registration of the measurement frame, identifiability analysis, weighted
// Levenberg-Marquardt (Ceres) with the analytic parameter Jacobian, uncertainties.
#pragma once

#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "accura/calib/joint_map.h"
#include "accura/calib/measurements.h"
#include "accura/calib/robot.h"

namespace accura::calib {

struct IdentifyOptions {
  /// Parameter groups to identify (see parameterGroups()): "geometric" (= base, tool,
  /// offsets, lengths, angles) and/or single groups and the effects ("joint_compliance", ...).
  /// A group may be restricted to some joints: "gear_periodic:j1+j2". joint_map may also state
  /// its knot spacing: "joint_map@3deg", "joint_map:j1+j2+j3@3deg" (deg for revolute joints,
  /// the same number in mm for prismatic ones); this overrides joint_map_knot.
  std::vector<std::string> groups = {"geometric"};
  /// joint_map: knot spacing (deg for revolute joints, mm for prismatic ones) and relative
  /// smoothness weight (the second differences of the coefficients weighted sqrt(smoothing)
  /// times the RMS norm of the map's weighted Jacobian columns). NaN (the default): chosen by
  /// blocked cross-validation on the fit data (kJointMapKnotCandidates x
  /// kJointMapSmoothingCandidates; contiguous blocks of each data set's rows as folds, which
  /// keeps repeated configurations together and holds out regions of the slowly varying joints).
  double joint_map_knot = std::numeric_limits<double>::quiet_NaN();
  double joint_map_smoothing = std::numeric_limits<double>::quiet_NaN();
  /// Several data sets (identify's vector overload): false (the default) = each set was measured
  /// from its own tracker station (6 station parameters per set beyond the first); true = they
  /// share one station.
  bool same_station = false;
  /// Closed-form registration of T_world_base (and the tool point) before the iterations:
  /// the measurement frame may be anywhere. Only when "base" is identified.
  bool register_frame = true;
  /// Standard deviations used when the data has no std columns: position (mm) and
  /// orientation (deg). NaN (the default): estimated from the residuals (variance
  /// components, one re-solve), reported in the summary.
  double position_std_mm = std::numeric_limits<double>::quiet_NaN();
  double orientation_std_deg = std::numeric_limits<double>::quiet_NaN();
  /// When the data's (or the given) stds explain the residuals badly, estimate an additive
  /// unmodelled-error std per component type (position, orientation) and weight each row by
  /// 1 / sqrt(std^2 + tau^2): the instrument's stds alone would over-trust the most precise
  /// rows when the model, not the instrument, limits the fit. tau = 0 when the stds
  /// already explain the residuals.
  bool model_error = true;
  /// Robust loss on the weighted residual of each pose: "none", "huber" or "cauchy";
  /// loss_scale in units of the residual's standard deviation.
  std::string loss = "none";
  double loss_scale = 3.0;
  /// A parameter whose scaled Jacobian column lies within this relative distance of the span
  /// of the parameters kept before it (1 = orthogonal, 0 = dependent) is fixed and reported.
  double dependence_tol = 1e-3;
  int max_iterations = 200;
  /// Ceres' relative cost-change and parameter-change tolerances.
  double function_tolerance = 1e-14;
  double parameter_tolerance = 1e-12;

  /// True when the options are usable; otherwise *error says why.
  bool IsValid(std::string* error) const;
};

/// Error statistics of a model against measurements. Position error: Euclidean distance
/// (mm); orientation error: rotation angle (deg), only when the data has orientation.
struct ErrorStats {
  int n = 0;
  double rms_mm = 0, mean_mm = 0, max_mm = 0, p95_mm = 0;
  bool has_orientation = false;
  double rot_rms_deg = 0, rot_mean_deg = 0, rot_max_deg = 0, rot_p95_deg = 0;
};

/// An orientation fit RMS above this (deg) after identification is a warning: a robot is off
/// by hundredths of a degree, so degrees mean orientation data read in the wrong convention or
/// unit (IdentifySummary::warnings).
constexpr double kImplausibleOrientationRmsDeg = 1.0;

/// Several data sets said to share one station (IdentifyOptions::same_station) that lie more
/// than this far (mm RMS) from the start model after registering that one station are refused:
/// a robot registered in the right frame is within millimetres, so tens of millimetres are two
/// stations (InputError naming the second file).
constexpr double kMaxSharedStationRmsMm = 25.0;

/// Fit data with repeated configurations whose distinct configurations give fewer independent
/// equations than this many per candidate parameter are warned about (IdentifySummary::warnings);
/// not more than the parameters are refused (InputError). The count of poses the refusal for too
/// few rows advises ("better 10 times as many").
constexpr int kMinEquationsPerParameter = 10;

struct FixedParameter {
  std::string name;
  std::string reason;
};

struct ParameterEstimate {
  std::string name, group, unit;
  double value = 0;  ///< deviation from nominal, display units
  double sigma = 0;  ///< one standard deviation, display units
};

/// Candidates of the joint_map cross-validation: knot spacing (deg or mm) and smoothness.
inline const std::vector<double>& jointMapKnotCandidates() {
  static const std::vector<double> v = {1.5, 2.0, 3.0};
  return v;
}
inline const std::vector<double>& jointMapSmoothingCandidates() {
  static const std::vector<double> v = {0.001, 0.003, 0.01, 0.03};
  return v;
}

/// A fitted joint map, for reports.
struct JointMapReport {
  int joint = 0;                   ///< 1-based
  std::string unit;                ///< deg or mm
  double lower = 0, upper = 0;     ///< covered interval (unit)
  double knot = 0;                 ///< knot spacing (unit)
  int coefficients = 0;
  double smoothing = 0;
  double amplitude = 0;            ///< largest |m(q)| on the interval (unit)
  double rms = 0;                  ///< RMS of m(q) over the fit data (unit)
};

/// A row whose normalised residual is far beyond what the others show.
struct SuspiciousRow {
  std::string file;
  int line = 0;
  double normalised = 0;  ///< |weighted residual| / its robust scale (chi with dim dof)
  double error_mm = 0;    ///< position error of the fitted model (mm)
};

/// A measured row left out because it lies grossly far from where the model puts it (a lost
/// tracker beam, a row of another station, a corrupted cell): removeGrossRows().
struct ExcludedRow {
  std::string file;
  int line = 0;
  double error_mm = 0;   ///< its position error (mm) after the robust registration
  double median_mm = 0;  ///< the median position error of its data set (mm), for scale
};

/// A row is gross when its position error after registration exceeds the larger of these:
/// kGrossRowFloorMm (mm), and kGrossRowMedianFactor times the median error of its data set.
/// A nominal robot registered in its tracker's frame is within millimetres (the real UR10:
/// 1.1 mm RMS); tens of millimetres above twenty times the median is no robot error.
constexpr double kGrossRowFloorMm = 50.0;
constexpr double kGrossRowMedianFactor = 20.0;
/// More gross rows than this share of a data set (and more than kGrossRowsAllowedAlways) is
/// refused: that is not a glitch but another station, robot or unit in the same file.
constexpr double kMaxGrossRowShare = 0.05;
constexpr int kGrossRowsAllowedAlways = 3;
/// Data sets of fewer rows are not screened for gross rows (their median says little).
constexpr int kGrossRowsMinRows = 10;

/// A fit row whose normalised residual (SuspiciousRow::normalised: its weighted residual over the
/// robust scale of all rows, the median's chi with 3 or 6 degrees of freedom) exceeds this is a
/// gross outlier: Gaussian noise reaches 10 robust standard deviations with a probability below
/// 1e-18, and one such row weighs at least 100/dim (17-33) typical rows in the least-squares cost.
/// A fit without a robust loss (--loss none) that has such rows warns, counting them and
/// recommending --loss huber.
constexpr double kGrossOutlierSigmas = 10.0;

struct IdentifySummary {
  std::string termination;     ///< Ceres' termination reason and message
  int iterations = 0;          ///< of every solve from initial_cost to final_cost (the weighting rounds included)
  double initial_cost = 0;     ///< 1/2 sum of squared weighted residuals, after registration
  double final_cost = 0;
  double registration_rms_mm = 0;   ///< position RMS right after the closed-form registration
  double condition_number = 0;      ///< of the column-scaled weighted Jacobian, kept params
  double condition_number_all = 0;  ///< the same with every candidate (inf when singular)
  double observability_index = 0;   ///< O1 = (prod sigma_i)^(1/p) / sqrt(m), scaled Jacobian
  double variance_factor = 0;       ///< s0^2 = weighted RSS / (m - p); ~1 with correct stds
  std::string weighting;            ///< how residuals were weighted (file stds, given, estimated)
  double position_std_mm = 0;       ///< the position std used when not from the file
  double orientation_std_deg = 0;
  double model_error_mm = 0;        ///< the unmodelled-error term (0: none needed)
  double model_error_deg = 0;
  int equations = 0, parameters_free = 0;
  /// Fit rows, and the distinct joint configurations among them (repeatedConfigurations() within
  /// each data set): only these carry information about the geometry; independent_equations =
  /// configurations times 3 (positions) or 6 (with orientations).
  int poses = 0, configurations = 0, independent_equations = 0;
  /// The distinct configurations give fewer than kMinEquationsPerParameter independent
  /// equations per candidate parameter, repeats or not (a warning says so).
  bool few_configurations = false;
  std::vector<FixedParameter> fixed;
  std::vector<ParameterEstimate> parameters;
  std::vector<int> downweighted_lines;  ///< source lines the robust loss down-weighted
  ErrorStats fit;
  /// Range of each joint's values in the fit data (deg or mm; all data sets together).
  std::vector<JointRange> coverage;
  /// T_world_base as seen from each data set's station (one per data set; all equal to the
  /// model's T_world_base when they share one station).
  std::vector<Eigen::Isometry3d> T_world_base_per_set;
  std::vector<JointMapReport> joint_maps;
  /// The joint_map cross-validation (empty when knot and smoothing were given).
  std::vector<JointMapCvCandidate> joint_map_cv;
  double joint_map_cv_baseline_mm = 0;  ///< held-out RMS of the same folds without maps
  /// Knot spacings the cross-validation did not try (a wider one was at least as good as the
  /// next finer one: JointMapCvResult::knots_not_tried).
  std::vector<double> joint_map_cv_knots_not_tried;
  /// Rows with a normalised residual above the chi quantile 0.9999 (file:line).
  std::vector<SuspiciousRow> suspicious;
  /// Rows left out of the fit as gross (removeGrossRows; each also named in `warnings`).
  std::vector<ExcludedRow> excluded;
  /// Physically implausible estimates and other warnings (negative compliance, thermal
  /// coefficient of the wrong sign or size, gear or map amplitude above a degree, maps left out).
  std::vector<std::string> warnings;

  /// One line: termination, iterations, cost before/after, fit RMS, condition number.
  std::string BriefReport() const;
};

/// Identifies the parameters named by options.groups starting from `start` (nominal or
/// previously calibrated; its deviations are the initial guess) on `data`. With joint_map and
/// other groups, the maps are fitted after the others, to what those leave, those held (two
/// solves; the reported sigmas are the joint covariance's): where a map is zero the model is the
/// one without maps. A row written twice (duplicatedRows(): every measured value of an earlier row of
/// its configuration) counts once: it is left out, and a warning names it. Returns the calibrated
/// model. Throws InputError when the data is too small for the
/// parameters asked for (too few rows, or too few distinct joint configurations: repeats,
/// repeatedConfigurations(), count once) and when, registered, the measured positions lie more
/// than 10 mm and half their own spread from the model's (units, joint order or robot wrong: a
/// factor of a unit, positions times 1000 or 1/1000 or joint angles times 180/pi or pi/180, that
/// brings them onto the model is said, with the mapping's line to change, MeasurementSet::units),
/// ArgumentError on invalid options, NumericalError when the
/// registration is degenerate (collinear points) or the solver fails.
RobotModel identify(const RobotModel& start, const MeasurementSet& data,
                    const IdentifyOptions& options, IdentifySummary* summary);
/// The same on several data sets at once: each from its own tracker station (6 parameters per
/// set beyond the first; the returned model's T_world_base is the first set's station) unless
/// options.same_station. Throws ArgumentError when `data` is empty.
RobotModel identify(const RobotModel& start, const std::vector<MeasurementSet>& data,
                    const IdentifyOptions& options, IdentifySummary* summary);

/// Re-registers the measurement station: T_world_base alone (6 parameters: closed-form
/// registration, then weighted least squares) is identified on `data`, every other parameter
/// held at its value in `model`. For validation data measured from another tracker station.
RobotModel registerStation(const RobotModel& model, const MeasurementSet& data,
                           IdentifySummary* summary);

/// Errors of `model` against `data`.
ErrorStats evaluate(const RobotModel& model, const MeasurementSet& data);

/// Per-row position errors (mm) of `model` against `data`.
std::vector<double> positionErrors(const RobotModel& model, const MeasurementSet& data);

/// Closed-form registration: T_world_base (and, with estimate_tool, the tool point) that
/// best maps the model's tool points onto the measured points (Kabsch with alternating
/// tool-point least squares). Robust to gross rows: registered again without the rows whose
/// error exceeds kGrossRowFloorMm and three times the median error, until that set no longer
/// changes (rows within kGrossRowFloorMm always take part). Throws NumericalError for fewer than 3 non-collinear points.
/// Returns the position RMS (mm) after registration, over every row.
double registerFrame(RobotModel& model, const MeasurementSet& data, bool estimate_tool);

/// Removes from `data` the rows whose position error exceeds the gross threshold
/// (kGrossRowFloorMm, kGrossRowMedianFactor) and returns them in file order. The errors are
/// those of `model` after registerFrame() on `data` when `register_frame` (the measurement
/// frame, and with estimate_tool the tool point), else of `model` as it is (data in its
/// world frame). A set of fewer than kGrossRowsMinRows rows, or one whose points are
/// collinear, is left as it is. Throws InputError (at the first gross row) when more than kMaxGrossRowShare
/// of the rows, and more than kGrossRowsAllowedAlways, are gross.
std::vector<ExcludedRow> removeGrossRows(const RobotModel& model, MeasurementSet& data, bool register_frame,
                                         bool estimate_tool);

/// The warnings naming rows removeGrossRows() left out of `from` ("the fit", "the validation"):
/// one line for each of the first ten (file:line, its error and the threshold it exceeds),
/// then one line counting the rest.
std::vector<std::string> excludedRowWarnings(const std::vector<ExcludedRow>& rows, const std::string& from);

/// The rows whose normalised residual exceeds the chi quantile 0.9999 with `dim` (3 or 6)
/// degrees of freedom: norms[i] is the norm of row i's weighted residual, normalised by a robust
/// scale (the median norm over the median of chi with dim degrees of freedom). Returns (row
/// index, normalised residual) in row order. IdentifySummary::suspicious of the fit is this.
std::vector<std::pair<size_t, double>> suspiciousResiduals(const std::vector<double>& norms, int dim);

/// The suspicious rows of `data` against `model` (validation data): suspiciousResiduals() of the
/// position errors (dim 3, unweighted: the model's error, not the instrument's, dominates there).
std::vector<SuspiciousRow> suspiciousRows(const RobotModel& model, const MeasurementSet& data);

/// Summary statistics of a list of non-negative errors (RMS, mean, max, 95th percentile
/// by nearest rank).
void summarize(const std::vector<double>& errors, double* rms, double* mean, double* max,
               double* p95);

}  // namespace accura::calib
