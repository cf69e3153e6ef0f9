// accura: the joint_map effect (docs/diagnosis.md, docs/method.md): per joint a smooth 1-D
// error map over the joint's own value, dtheta_i = m_i(q_i) (rad; prismatic joints dd_i in mm).
//
// The map is a uniform cubic B-spline on the interval [lower, upper] of q that the fit data
// cover (see JointMap in robot.h). Outside that interval it is not extrapolated: its value at
// the nearer end is multiplied by a cosine taper 0.5 (1 + cos(pi s / taper)), s the distance
// beyond the end (0 <= s <= taper), and is zero beyond: continuous in q, zero where the fit
// had no data. Everything here is linear in the coefficients.
//
// q is the controller's joint value: deg (revolute) or mm (prismatic), as everywhere in the
// kinematics.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "accura/calib/robot.h"

namespace accura::calib {

/// The map's value at q (rad or mm). Zero for an empty map. With `slope`, also dm/dq (rad per
/// deg, or mm per mm).
double jointMapValue(const JointMap& map, double q, double* slope = nullptr);

/// The basis of the map at q: m(q) = sum_{k=0..3} w[k] coef[first + k]. Returns `first`
/// (0 .. intervals-1); the weights include the taper outside the interval (all zero beyond it).
/// Returns -1 for an empty map.
int jointMapBasis(const JointMap& map, double q, double w[4]);

/// d m(q) / d coef[k] (dimensionless): the k-th basis function at q, taper included.
double jointMapBasisValue(const JointMap& map, double q, int k);

/// A zero map on [lower, upper] (deg or mm) with knot spacing close to `knot` (the interval is
/// divided into ceil((upper - lower) / knot) equal intervals, at least 1) and a taper width of
/// one knot spacing. `period` (deg; jointMapPeriod): a map of the joint's angle modulo `period`,
/// evaluated at the turn of q nearest the interval; an interval wider than period - 2 knot is
/// narrowed about its centre to that width, so that the map and its tapers fit in one turn
/// (with a knot spacing above a quarter of the period, which would leave less than half a turn,
/// the map has no period instead). Throws ArgumentError when lower >= upper, knot <= 0 or
/// period < 0 (or non-finite values).
JointMap makeJointMap(double lower, double upper, double knot, double period = 0);

/// The period of joint j's map (0-based): 360 deg for a revolute joint (the gear's and the
/// encoder's errors repeat with each turn of the joint; the UR's joints turn +-360 deg, and a
/// program may reach an angle the fit data hold one turn away), 0 for a prismatic joint.
double jointMapPeriod(const RobotModel& model, int j);

/// Width (deg, or mm for a prismatic joint) of the window jointMapSupport counts values in: the
/// widest knot spacing the cross-validation tries, one number for every knot spacing so that
/// the cross-validation and the fit it chooses map the same interval.
constexpr double kJointMapSupportWindow = 3.0;

/// The interval a joint's map is defined on: the fit data's range of the joint (`q_fit`, deg or
/// mm), less the sparse tails at either end. An end moves inwards to the first value from which
/// a window of `window` holds at least a fifth of the data's mean count per window (and at least
/// 2 values): beyond it a map's coefficients would rest on a handful of poses, and the
/// smoothness penalty would extrapolate the map's trend over a part of the range that other data
/// may fill (on the real UR10, Series_C reaches joint 2's -90 deg with 1 pose; its bulk ends near
/// -125). The whole range when the rest would be narrower than two windows. With a `period`
/// (jointMapPeriod) the values are first taken as angles of one turn: each is moved by whole
/// periods into the turn that starts after the widest gap between the data's angles (values
/// already in that turn keep their value; Series_C's joint 4, -254..289 deg, becomes one turn
/// that holds all of its data). Throws ArgumentError when q_fit is empty, window is not
/// positive and finite, or period is negative or not finite.
JointRange jointMapSupport(std::vector<double> q_fit, double window = kJointMapSupportWindow, double period = 0);

/// The largest |m(q)| over the covered interval (rad or mm), sampled at 8 points per interval.
double jointMapAmplitude(const JointMap& map);

/// The rows of the map's regularisation on the coefficients, for identification:
///   smoothness: the second differences coef[k-1] - 2 coef[k] + coef[k+1], k = 1..K-2;
///   centring: the means over `q_fit` (the fit data's values of this joint) of m(q) times 1,
///   (q - q_mean) / q_sd and, for h = 1..harmonics, sin(h q) and cos(h q) (q in rad), which the
///   constraint drives to zero: the map carries no constant (a joint offset), no linear trend (a
///   joint scale) and no low harmonics (what geometry, gravity compliance and gear_periodic
///   describe, and what extrapolates beyond the covered range). Only the fine structure is left.
/// Each row is a coefficient vector (size K); the caller weights them.
std::vector<std::vector<double>> jointMapSmoothnessRows(const JointMap& map);
/// Rows that pull to zero every coefficient the fit data barely reach: its data mass (the sum
/// of its basis function over `q_fit`, about the number of poses within a knot spacing) below
/// kJointMapSparseShare of the mass it would have with the same data spread evenly over the map's
/// interval (jointMapSupport's rule for the ends, here inside the interval). Across a gap in the data a map is then zero, not the
/// smoothness penalty's interpolation over the gap (on the real UR10, Series_B has 3 poses with
/// joint 3 within 12 deg of 0; held out in its fold, the home pose at q3 = 0 got -6.4 mrad of
/// map, 4.4 mm). One unit row per such coefficient; the caller weights them like the centring.
std::vector<std::vector<double>> jointMapSparseRows(const JointMap& map, const std::vector<double>& q_fit);
std::vector<std::vector<double>> jointMapCentringRows(const JointMap& map, const std::vector<double>& q_fit,
                                                      int harmonics);

/// Low harmonics kept out of a revolute joint's map (see jointMapCentringRows); prismatic: 0.
/// Those of gear_periodic (kDefaultGearHarmonics, 1 and 2 cycles per revolution): what varies
/// that slowly over a joint's range is the offsets', the scale's, the geometry's, the
/// compliance's and gear_periodic's, and it does not carry over from one series to another; the
/// map holds the errors of many cycles per revolution that none of those describe (docs/diagnosis.md).
constexpr int kJointMapCentredHarmonics = kDefaultGearHarmonics;

/// The most map coefficients identify solves (all joints together): they are solved densely,
/// and beyond this a run takes minutes to hours (a knot spacing of 0.1 deg on six joints) while
/// no data set determines that many. The finest spacing the cross-validation tries (1.5 deg)
/// gives at most 6 x 243 = 1458.
constexpr size_t kMaxJointMapCoefficients = 3000;

/// Throws InputError when maps of spacing `knot` over `ranges` (one per mapped joint) would
/// have more than kMaxJointMapCoefficients coefficients, naming the spacing that fits.
void checkJointMapSize(const std::vector<JointRange>& ranges, double knot);

/// Whether a joint's fit values leave a map room for `need` (deg or mm: a multiple of the knot
/// spacing): q's own range `coverage` must reach it, and so must the map's interval `support`
/// (jointMapSupport with the joint's period) up to two support windows (a support trims sparse
/// tails; it is narrower than that only where values a turn apart are one angle, e.g. a joint
/// held at -90 deg written 270 deg in half the rows). *width: the width that counts, the
/// smaller of the two.
bool jointMapCovers(const JointRange& coverage, const JointRange& support, double need, double* width = nullptr);

/// Parses a knot spacing as given on the command line: "3deg", "3" (deg for revolute joints) or
/// "5mm" (prismatic). Returns false with *error on anything else (not a positive finite number,
/// unknown unit).
bool parseJointMapKnot(const std::string& text, double* knot, std::string* unit, std::string* error);

/// A joint value counts as outside a fitted joint range only beyond this (deg, or mm for a
/// prismatic joint): exports in radians carry 6-7 significant digits (1e-6 rad = 5.7e-5 deg),
/// so a pose at the edge of the fit data reads a few 1e-5 deg beyond it; 1e-3 deg moves the
/// tool of a 1 m arm by 0.017 mm, and no joint-dependent effect changes over it.
constexpr double kFitRangeTolerance = 1e-3;

/// The period of joint j's (0-based) fitted range in `model` (deg): 360 for a revolute joint
/// whose joint-dependent effects all repeat with each turn (maps with a period, gear_periodic,
/// the gravity torques of compliance), 0 when one does not (a joint_scale of that joint, a map
/// without a period) and for prismatic joints. Throws ArgumentError on a bad index.
double fitRangePeriod(const RobotModel& model, int j);

/// How far q lies beyond the fitted range c (deg or mm; 0 within it). With a `period`
/// (fitRangePeriod) q counts at its turn nearest the range (100 deg is 260 deg beyond -260..-200
/// without a period, within it with one), and a range of a turn or more holds every q.
double beyondFitRange(const JointRange& c, double q, double period = 0);

/// The share of a turn a gear_periodic term of a joint needs in the fit data to be told apart
/// from the joint's offset and scale (0.45 turn, deg).
constexpr double kPeriodicCoverageDeg = 162.0;
/// How far (a share of the covered width) a joint's limits may lie beyond the fit data's range for
/// a periodic term fitted on less than kPeriodicCoverageDeg: a joint whose limits span less than
/// half a turn (the IRB 120's joint 3: -110..70 deg) cannot give more, and data that reach this
/// close to both limits leave nothing of its range to extrapolate to.
constexpr double kPeriodicLimitShare = 0.2;

/// Whether a gear_periodic term of `joint` fitted on data covering [lower, upper] (deg) holds
/// wherever the joint can move: the data cover at least kPeriodicCoverageDeg, or the joint's
/// limits lie no further than kPeriodicLimitShare of the covered width beyond them. False for a
/// prismatic joint (no period), and below kPeriodicCoverageDeg for a joint without limits
/// (upper <= lower: the rest of the turn may be reached).
bool periodicTermHoldsOverLimits(const JointSpec& joint, double lower, double upper);

/// A joint value outside the range the model's joint-dependent effects were fitted on.
struct OutsideFitRange {
  int joint = 0;            ///< 1-based
  double q = 0;             ///< the joint value (deg or mm)
  double lower = 0, upper = 0;  ///< the fitted range (deg or mm)
  double beyond = 0;        ///< distance beyond the nearer end (deg or mm), > 0
};

/// The joints of `q` (deg / mm) that lie outside (by more than kFitRangeTolerance) the fitted range (Deviations::fit_range, else
/// the joint map's interval) of a joint whose effects depend on its value: a joint map, gear
/// harmonics or a scale error of that joint; joint compliance depends on every joint's value
/// (the gravity torques). Empty when the model has no fitted range or no such effect; there the
/// effects are extrapolated (maps are zero), not fitted. Throws ArgumentError when q does not
/// have one value per joint.
std::vector<OutsideFitRange> outsideFitRanges(const RobotModel& model, const Eigen::VectorXd& q);

/// The message of a target (or pose) outside the fitted ranges, one place for every command:
/// "<what> lies outside the joint ranges the model was fitted on: joint 1 (shoulder_pan) at
/// 14.48 deg (fitted -180.00..-44.89 deg, 59.37 deg beyond); ... (its joint-dependent effects
/// are not fitted there)"; deg (mm for prismatic joints), 2 decimals, joint names from `model`.
/// Empty for an empty list.
std::string outsideFitRangeMessage(const RobotModel& model, const std::string& what,
                                   const std::vector<OutsideFitRange>& outside);

// ---------------------------------------------------------------------------------------
// Choosing the resolution and the smoothness by blocked cross-validation (linearised)

/// One measured pose of the linearised problem at a fit without maps.
struct JointMapCvRow {
  Eigen::MatrixXd G;      ///< dim x p: weighted Jacobian of the other free parameters
  Eigen::VectorXd r;      ///< dim: weighted residual (model - measured) at the linearisation
  Eigen::MatrixXd U;      ///< dim x J: weighted Jacobian of a unit dtheta (dd) of each mapped joint
  Eigen::VectorXd q;      ///< J: the mapped joints' values (deg or mm)
  Eigen::Vector3d w_pos;  ///< position weights (1/mm): held-out errors are reported in mm
  int fold = 0;           ///< 0..folds-1
};

struct JointMapCvCandidate {
  double knot = 0;        ///< knot spacing (deg or mm)
  double smoothing = 0;   ///< relative smoothness weight (see IdentifyOptions)
  double cv_rms_mm = 0;   ///< held-out position RMS over all folds
};

struct JointMapCvResult {
  double knot = 0, smoothing = 0;  ///< the candidate with the smallest held-out RMS
  double baseline_rms_mm = 0;      ///< held-out position RMS without maps (same folds)
  double best_rms_mm = 0;
  std::vector<JointMapCvCandidate> table;
  /// Knot spacings not tried: the candidates are tried from the widest down, and a finer one
  /// only while the last one tried gained on the wider one before it (coarse to fine).
  std::vector<double> knots_not_tried;
};

/// The smoothness and centring penalties of identification, in one place: the weight of the
/// second-difference rows is sqrt(smoothing) * scale, the centring rows (normalised to unit
/// norm) are weighted kCentringWeight * scale; `scale` is the RMS norm of the map's weighted
/// Jacobian columns, so `smoothing` is relative to the data's own weight.
constexpr double kJointMapCentringWeight = 1e3;
/// Weight of jointMapSparseRows' rows, times the same scale: a ridge, a tenth of a coefficient's
/// mean data weight (a hard constraint left the normal matrix too ill-conditioned to factor). On
/// the real UR10 it leaves identify's own blocked cross-validation of the maps within 0.5 % on
/// Series_B and Series_C (a weight of 1 made it 1.8 % worse on B) and takes the diagnosis' held-out
/// error of Series_B with the maps from 0.235 to 0.201 mm, its maximum from 4.4 mm (a pose alone in
/// a gap of joint 3) to 1.1 mm.
constexpr double kJointMapSparseWeight = 0.1;
/// jointMapSparseRows: the share of its even-coverage data mass below which a coefficient is
/// pulled to zero (a fifth, as jointMapSupport's ends).
constexpr double kJointMapSparseShare = 0.2;

/// Refits the linearised problem for every (knot, smoothing) candidate on all folds but one and
/// predicts the held-out fold (maps on `ranges`, one per mapped joint, the centring taken on
/// the training rows, with centred_harmonics[j] low harmonics kept out). As identify fits them,
/// the maps are fitted after the other columns (G): G's solution on the training rows (the
/// baseline's), then the maps' with it held. The knot spacings are
/// tried from the widest down; a finer one only while the last one tried has a smaller best
/// held-out RMS than the wider one before it (the rest are listed in knots_not_tried: the
/// finest candidates have the largest systems, most of the cost). Cost per knot tried: one
/// pass over the rows; per candidate and fold one dense Cholesky factorisation. Throws
/// ArgumentError on inconsistent sizes or empty candidates.
JointMapCvResult crossValidateJointMap(const std::vector<JointMapCvRow>& rows, const std::vector<JointRange>& ranges,
                                       const std::vector<double>& periods,
                                       const std::vector<int>& centred_harmonics, const std::vector<double>& knots,
                                       const std::vector<double>& smoothings, int folds);

}  // namespace accura::calib
