// accura post-processor: ABB RAPID modules (.mod, .prg), read into the shared Program
// representation and written back byte for byte with only the corrected numbers changed and
// the auxiliary points inserted (docs/rapid.md).
//
// What the reader understands (ABB "Technical reference manual - RAPID Instructions,
// Functions and Data types"):
//   motions   MoveL ToPoint, Speed, Zone, Tool [\WObj];  MoveJ (same);  MoveC CirPoint,
//             ToPoint, Speed, Zone, Tool [\WObj];  MoveAbsJ ToJointPos, ... (an axis target,
//             never changed). Optional arguments (\ID, \V, \T, \Z, \Inpos, \Corr, ...) are kept
//             as written. MoveL/MoveC -> LIN/CIRC, MoveJ/MoveAbsJ -> PTP.
//   targets   inline [[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax_a,..,eax_f]] (mm, a
//             quaternion w,x,y,z: normalised on read, an error when its norm is off 1 by more
//             than 1e-3), CONST/PERS/VAR robtarget declared in the module or the routine,
//             an element of a robtarget array with a constant index (pts{2}, grid{1,3}),
//             Offs(p, dx, dy, dz) and RelTool(p, dx, dy, dz [\Rx] [\Ry] [\Rz]) of such targets
//             with constant numbers (a corrected one is written as an inline robtarget).
//   frames    tooldata (robhold TRUE: T_flange_tcp = tframe; tool0 = the flange) and
//             wobjdata (robhold FALSE, ufprog TRUE: T_world_wobj = uframe * oframe; wobj0 =
//             world). A stationary tool (tooldata robhold FALSE), a robot-held work object
//             (wobjdata robhold TRUE) or a coordinated one (ufprog FALSE) is kept with
//             FrameSetting::kUnknown naming it: compensate refuses those motions.
//   zone      fine -> exact stop; z0..z200 and inline zonedata (pzone_tcp) -> the
//             approximation (C_DIS with the zone radius in mm; z0 is 0.3 mm). Speed: v5..v7000
//             and inline speeddata (v_tcp mm/s) -> the path speed; all speed arguments kept.
//   config    ConfJ \On|\Off, ConfL \On|\Off (Motion::conf_monitored), confdata in
//             Target::abb_conf. The rules the compensation follows are in docs/rapid.md.
//   the rest  comments (!), other declarations, logic, I/O, calls: kept as text and, for
//             convert, carried as PassThrough statements of language "RAPID".
// Errors (calib::InputError, file:line:column, expected/found): an unbalanced bracket, an
// unterminated string, a malformed robtarget/tooldata/wobjdata (wrong shape, a non-finite or
// absurd number, a non-unit quaternion), a move with the wrong number of arguments, a NUL
// byte, a module without MODULE/ENDMODULE, a move outside a routine.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "accura/calib/robot.h"
#include "accura/postproc/program.h"

namespace accura::postproc {

/// Text spans of a RAPID module, for writing it back byte for byte.
struct RapidSource {
  /// A robtarget value [[x,y,z],[q1..q4],[cf1,cf4,cf6,cfx],[eax...]] as written.
  struct Value {
    size_t begin = 0, end = 0;           ///< '[' .. one past ']'
    std::pair<size_t, size_t> num[11];   ///< x, y, z, q1..q4, cf1, cf4, cf6, cfx ([begin, end))
    double v[11] = {};                   ///< as read (the quaternion as written, not normalised)
    /// The declaration holding it (-1: inline in a statement).
    int decl = -1;
  };
  /// A robtarget declaration: `[LOCAL] CONST|PERS|VAR robtarget name := value;`, or one element
  /// of a robtarget array declared with its value (`CONST robtarget pts{3} := [v1, v2, v3];`,
  /// one Decl per element written as a robtarget value: name `pts{2}`, `grid{1,3}`; the lines,
  /// indent and head are the array's, so that a new point goes after the array's declaration).
  struct Decl {
    std::string name;
    size_t line_begin = 0, line_end = 0;  ///< the line(s) of the declaration, with the line end
    std::string indent;                   ///< the blanks before it
    std::string head;                     ///< the text before the name ("CONST robtarget ")
    int value = -1;                       ///< index in values
    /// The first place the program reads this robtarget's value other than as the plain
    /// ToPoint/CirPoint of a MoveL/MoveJ/MoveC, "file:line:column ('statement')" (excerpt);
    /// empty when there is none: an assignment (`p30 := p20;`), a call's argument, an Offs or
    /// RelTool the reader cannot evaluate (`Offs(p20, 0, 0, dz)`), a motion instruction accura
    /// does not model, a condition. Such a read gets the declared value even where the
    /// compensation corrects it for a motion (Job: the motions then go to a new point).
    std::string read_elsewhere;
    /// A robtarget a module given with --config declares (only read), "file:line:column" there;
    /// "" for a declaration of this module. Its value's text is not in `text` (Value::begin ==
    /// end): a motion that corrects it goes to a new point (Job), declared at line_end with
    /// `head` (`LOCAL CONST robtarget `: this module's own, so no other module of the task can
    /// declare its name too).
    std::string task_module;
  };
  /// A motion statement.
  struct Statement {
    size_t line_begin = 0, code_begin = 0, code_end = 0;  ///< code_end: one past ';'
    std::string eol;
    /// The target expressions [begin, end): CirPoint first for MoveC.
    std::vector<std::pair<size_t, size_t>> targets;
    /// The robtarget value each target reads (-1: none, e.g. an Offs/RelTool expression).
    std::vector<int> target_value;
    /// The robtarget value an Offs/RelTool target the reader evaluated is built on, for each
    /// target (-1: none): the expression reads that point as long as it is written as it is (a
    /// corrected one is written as an inline robtarget, which reads nothing).
    std::vector<int> target_reads;
    /// The programmed duration's number [begin, end) in the text (a move's \T:=), {0, 0}
    /// when there is none; duration_s its value (s). A motion split by the
    /// compensation gets each piece its share (durationShares, program.h).
    std::pair<size_t, size_t> duration_text{0, 0};
    double duration_s = 0;
  };
  std::string path;
  std::string text;
  std::vector<Value> values;
  std::vector<Decl> decls;
  std::vector<Statement> statements;
  /// The texts of the task modules given with the module (readRapid(path, task_modules), one
  /// after the other; "" none): their global names are the task's too, so a new point's name
  /// must not be one of their names.
  std::string task_text;
};

/// Reads a RAPID module. Throws calib::InputError (file:line:column) on malformed input and
/// on an unreadable or binary file.
Program readRapid(const std::string& path);
/// The same, with another module of the task, `task_module` (CalibData.mod, user.sys; "" none),
/// whose task-global data (those not LOCAL: RAPID's global data are visible in every module of
/// the task) the module uses without declaring them: its tooldata, wobjdata, speeddata,
/// zonedata and CONST nums serve the names the module does not declare itself. That module is
/// only read. Throws like readRapid, for either file.
Program readRapid(const std::string& path, const std::string& task_module);
/// The same with several modules of the task (--config given more than once): each serves the
/// names the module does not declare; a name two of them (or one of them and this module)
/// declare global is an InputError at the second naming the first (the controller refuses to
/// load such a task), except a PERS both declare (one persistent they share). A robtarget
/// one of them declares (CONST or VAR, not assigned in them, read) is the value of the motions
/// that go to it (RapidSource::Decl::task_module); a PERS one is kept, named (Motion::target_problem).
Program readRapid(const std::string& path, const std::vector<std::string>& task_modules);
/// The same from text (`path` names it in messages).
Program parseRapid(const std::string& text, const std::string& path);

/// Writes a program as RAPID. A program read from RAPID (program.rapid set) is written back
/// byte for byte, except the numbers of modified targets (positions 4 decimals in mm,
/// quaternions 9 decimals with the sign of the written one; a number whose new text rounds
/// to the old value keeps its text; an orientation whose correction rounds to zero keeps its
/// quaternion text), the confdata the compensation changed, the Offs/RelTool expressions of
/// corrected targets (an inline robtarget), the new declarations (after the declaration they
/// replace) and the inserted motions (a copy of their statement with inline robtargets, on
/// the line before it). Any other program is written as a new module (MODULE NAME, PROC
/// main()) with tooldata, wobjdata and inline robtargets, except a program carrying the lines
/// of a module (rapidForConversion, e.g. through XML): those lines reassembled, read, and
/// written back as above with the program's targets laid on them (reattachCarried). Throws calib::ArgumentError naming
/// the motion when the program cannot be written: a declared value needing two corrections, a
/// frame or target that is not known, a motion RAPID has no form for here (SPL, relative
/// motions, CIRC with CA), a pass-through statement of another language.
std::string writeRapid(const Program& program);

/// A program read from RAPID made ready for another format: target names that are
/// expressions (Offs(..), RelTool(..)) cleared, the RAPID source dropped and every line of it
/// carried (carrySourceLines, language "RAPID"). The statements outside the motion model are
/// pass-through statements without a role: the other languages' writers refuse them naming
/// their line (checkPassThrough), XML carries them, and writeRapid gives the module back.
Program rapidForConversion(const Program& program);

/// ABB confdata [cf1, cf4, cf6, cfx] of joints q (deg) of `model` (a 6R arm with a spherical
/// wrist): cf1, cf4, cf6 the quadrants floor(q/90 deg) of axes 1, 4, 6; cfx the sum of 4
/// (wrist centre behind axis 1), 2 (wrist centre behind the lower arm) and 1 (axis 5
/// negative) (ABB confdata, "cfx" for 6-axis robots). Throws ArgumentError on a dof mismatch.
std::array<int, 4> abbConfdata(const calib::RobotModel& model, const Eigen::VectorXd& q);

/// The KUKA Status (ik.h) that selects the same arm branch as ABB's cfx (0..7); -1 for any
/// other value.
int kukaStatusOfCfx(int cfx);

}  // namespace accura::postproc
