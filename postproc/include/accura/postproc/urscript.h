// accura post-processor: Universal Robots URScript programs (.script, also the program text
// PolyScope exports next to a .urp), read into the shared Program representation and written
// back byte for byte with only the corrected numbers changed and the auxiliary points inserted
// (docs/program-formats.md, "URScript").
//
// What the reader understands (URScript manual, module "motion" and "interfaces"):
//   motions   movel(pose, a, v, t, r), movep(pose, a, v, r), movec(pose_via, pose_to, a, v, r,
//             mode) (mode 0 only: orientation interpolated from the start to pose_to; the
//             via point's orientation is not used), movej(q | pose, a, v, t, r) and
//             movej(get_inverse_kin(pose, qnear=q)) (the PolyScope form; qnear, into
//             Motion::qnear_deg, kept as written; tcp= other than the active TCP, or a qnear
//             accura cannot evaluate, is a problem of the target). Arguments positional or named. movel/movep -> LIN, movec -> CIRC,
//             movej -> PTP (joint positions: an axis target, never changed).
//   poses     p[x, y, z, rx, ry, rz]: metres and a rotation vector (radians), in the
//             controller's Base frame (= DH frame 0 of UR's DH table, robots/README.md);
//             variables assigned poses (p1 = p[...], global/local p1 = ...), pose_trans(a, b)
//             (a * b) and pose_add(a, b) (positions added, rotations a.R * b.R) of evaluable
//             poses. A corrected target that is an expression is written back by correcting
//             its right-most literal p[...] (pose_trans(feature, p[...]): the offset).
//   tool      set_tcp(pose): T_flange_tcp.
//   blend     r (m) -> the approximation (C_DIS with r in mm); speed v of movel/movep/movec
//             (m/s) -> the path speed.
//   the rest  comments (#), def/end, logic, I/O, threads: kept as text, passed through.
// A target the reader cannot evaluate (a pose computed at run time, a variable that the
// program changes from its own value or assigns again inside the while loop that runs the
// motion, a call accura does not know) is kept with
// Motion::target_problem naming it: compensate reports it as an error on movel/movep/movec and
// leaves a movej unchanged with a warning.
// Errors (accura::InputError, file:line:column, what was expected and what was found): an
// unbalanced bracket, an unterminated string, a malformed p[...] (not six numbers, a non-finite
// or absurd value: a position beyond 100 m, a rotation or joint value beyond 100 rad), an
// unknown or repeated argument of a move, a positional argument after a named one, a blend
// radius outside [0, 10] m, a speed <= 0, a mode other than 0 or 1, a move without its
// target, a NUL byte. (movec with mode 1 reads, and is
// reported by compensate as a motion accura does not model.)
//
// UR configuration (shoulder/elbow/wrist branch): URScript targets carry none; the controller
// keeps the branch along movel/movec and takes the solution nearest the current joints (or
// qnear) for movej. The compensation does the same: each target is solved from the previous
// point's joints (compensate.h), so the branch is kept, or from qnear where it is given.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "accura/postproc/program.h"

namespace accura::postproc {

/// Text spans of a URScript program, for writing it back byte for byte.
struct UrScriptSource {
  /// A literal p[...] (its six numbers as written: metres, radians).
  struct Literal {
    size_t begin = 0, end = 0;                 ///< "p[" .. "]"
    std::pair<size_t, size_t> number[6];       ///< [begin, end) of each number
    double value[6] = {0, 0, 0, 0, 0, 0};      ///< as read
  };
  /// A pose expression: a literal, pose_trans(a, b) or pose_add(a, b).
  struct Expr {
    enum class Kind { kLiteral, kTrans, kAdd };
    Kind kind = Kind::kLiteral;
    int literal = -1;  ///< kLiteral: index in literals
    int a = -1, b = -1;  ///< operands (indices in exprs)
  };
  /// A motion statement.
  struct Statement {
    size_t line_begin = 0, code_begin = 0, code_end = 0;
    std::string eol;
    /// The target expressions ([begin, end) in the text): the via point first for movec.
    std::vector<std::pair<size_t, size_t>> targets;
    std::vector<int> target_expr;  ///< the pose expression of each target (-1: none)
    /// The programmed duration's number [begin, end) in the text (movel's t > 0), {0, 0}
    /// when there is none; duration_s its value (s). A motion split by the
    /// compensation gets each piece its share (durationShares, program.h).
    std::pair<size_t, size_t> duration_text{0, 0};
    double duration_s = 0;
  };
  /// A statement that is not part of the motion model (logic, I/O, calls): convert refuses
  /// to write a program holding one in another format.
  struct Other {
    SourceLocation where;
    std::string text;
  };
  /// A set_gravity(d) statement (also one of `others`): the arm's mounting, d the acceleration
  /// away from the earth's centre in the controller's Base (m/s^2; URScript manual).
  struct Gravity {
    SourceLocation where;
    std::string text;                         ///< the statement as written
    std::optional<std::array<double, 3>> d;   ///< empty: not a list of three numbers (a variable, an expression)
  };
  std::string path;
  std::string text;
  std::vector<Literal> literals;
  std::vector<Expr> exprs;
  std::vector<Statement> statements;
  std::vector<Other> others;
  std::vector<Gravity> gravity;  ///< in the script's order
};

/// Reads a URScript program. Throws calib::InputError (file:line:column) on malformed input and on
/// an unreadable or binary file.
Program readUrScript(const std::string& path);
/// The same from text (`path` names it in messages).
Program parseUrScript(const std::string& text, const std::string& path);

/// Writes a program as URScript. A program read from URScript (program.urscript set) is
/// written back byte for byte, except the numbers of the literals of targets marked
/// `modified` (7 decimals: 0.1 um, 0.1 urad; a literal whose every number changes by less
/// than half of that keeps its text) and the motions marked `inserted` (a copy of their
/// anchor statement with inline p[...] targets, on the line before it). Any other program is
/// written as a new script (def NAME(): ... end) with its targets converted into the Base
/// frame, except a program carrying the lines of a script (urScriptForConversion for XML):
/// those lines reassembled, read, and written back as above with the program's targets laid on
/// them (reattachCarried). Throws calib::ArgumentError naming the motion when the program
/// cannot be written: one
/// literal needing two different corrections, a frame or target that is not known, a motion
/// URScript has no form for (SPL, relative motions, CIRC with CA, external axes, an
/// approximation other than C_DIS with its distance), a KRL statement that is not a motion.
std::string writeUrScript(const Program& program);

/// A program read from URScript made ready for another format (`format_name`: "KRL", "XML",
/// "RAPID"): target names that are expressions (pose_trans(..)) cleared. For "XML" every line
/// of the script is carried (carrySourceLines, language "URScript"; the statements outside
/// the motion model as pass-through statements without a role), so that writeUrScript gives
/// the script back; for the others, throws calib::ArgumentError naming the first statement
/// they cannot carry (logic, I/O, calls, threads).
Program urScriptForConversion(const Program& program, const char* format_name);

/// p[x, y, z, rx, ry, rz] (metres, rotation vector in radians) of a pose (mm, deg), 7
/// decimals; the rotation vector is the one of the two equivalent forms (angle in [0, pi] or
/// its complement about the opposite axis) nearest to `near` (rad; zero: the short one).
std::string urPoseText(const calib::XyzAbc& pose, const double near_rotvec[3] = nullptr);

}  // namespace accura::postproc
