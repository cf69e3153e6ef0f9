// accura post-processor: the program representation shared by the KRL and the XML readers and
// writers (docs/program-formats.md).
//
// A Program is the motion model of a robot program: its motions in textual order, each with its
// target(s), motion type, approximation, speed, and the tool and base frames active when it
// runs. Everything else a program holds (logic, I/O, comments, folds) is kept by the KRL reader
// as text (KrlSource) and written back byte for byte; the XML format carries the motion model
// only.
//
// Units: mm and deg (targets, frames), m/s (path speed), percent (PTP speed). Frames: a
// Cartesian target is T_base_tcp: the tool ($TOOL, T_flange_tcp) in the program's base frame
// ($BASE, relative to the controller's $WORLD).
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "accura/calib/geometry.h"
#include "accura/calib/text.h"

namespace accura::postproc {

/// A place in a program file: 1-based line and column (column counts bytes).
struct SourceLocation {
  std::string file;
  int line = 0;
  int column = 0;
  /// "file:line:column" (parts that are unknown are left out).
  std::string str() const;
};

/// The motion types of the model. kSpl is a spline segment (SPL inside SPLINE ... ENDSPLINE):
/// its path is not a line or a circle, so only its end point is compensated.
enum class MotionType { kPtp, kLin, kCirc, kSpl };

/// Approximation (blending) flags as written after a motion (KRL C_PTP, C_DIS, ...).
enum class Approximation { kCPtp, kCDis, kCVel, kCOri, kCSpl };
/// "C_PTP", "C_DIS", ...
const char* toString(Approximation a);
/// Parses "C_PTP", "C_DIS", ... (case-insensitive); false when `text` is none of them.
bool parseApproximation(const std::string& text, Approximation* out);

/// A robot target as the program gives it: Cartesian (E6POS, POS, FRAME) or axis-specific
/// (E6AXIS, AXIS). Components the program leaves out are empty (a partial aggregate: the
/// controller takes them from the current position).
struct Target {
  enum class Kind { kCartesian, kAxis };
  Kind kind = Kind::kCartesian;
  std::string name;  ///< declared name as written (XP1), empty for an inline aggregate
  std::string type;  ///< E6POS, POS, FRAME, E6AXIS, AXIS (upper case); empty when untyped
  std::array<std::optional<double>, 6> pose;  ///< X, Y, Z (mm), A, B, C (deg)
  std::optional<int> status;                  ///< KUKA S
  std::optional<int> turn;                    ///< KUKA T
  std::array<std::optional<double>, 6> axes;  ///< A1..A6 (deg; mm for prismatic joints)
  std::array<std::optional<double>, 6> ext;   ///< E1..E6 (external axes, deg or mm)
  SourceLocation where;                       ///< where the value is written
  int value_id = -1;  ///< KRL: index of the aggregate's text in KrlSource::values (-1: none)
  bool modified = false;  ///< changed by the compensator (the writers rewrite its value)
  /// A new point made by the compensator where the old name must keep its meaning (the
  /// auxiliary point of the last sub-arc of a split CIRC): `name` is new and must be declared
  /// (KRL: a DECL after the declaration of value_id in the .dat, which stays untouched) and the
  /// motion refers to it instead of the point it replaces (`replaces`); `name` empty: an inline
  /// aggregate in the statement instead (the replaced point is not declared in the .dat).
  bool new_declaration = false;
  std::string replaces;  ///< for new_declaration: the name the motion used before
  /// ABB confdata [cf1, cf4, cf6, cfx] of a RAPID robtarget (rapid.h); empty for other
  /// languages. The compensation treats it as the controller does (ConfJ / ConfL, see
  /// Motion::conf_monitored) and writes back the quadrants the compensated point has where
  /// a correction moves a monitored axis across a quadrant boundary.
  std::optional<std::array<int, 4>> abb_conf;
  /// KRL: the point is declared GLOBAL (`DECL GLOBAL E6POS XP1=..` in a PUBLIC data list):
  /// other modules use it by its name. XML `global="true"`; a KRL program written anew declares
  /// it GLOBAL again.
  bool global = false;
  /// KRL: declared outside the program's files (in the $config.dat, given with --config): the
  /// program refers to it by name. XML `external="true"` (with its values, for the other
  /// languages); a KRL program written anew does not declare it (a declaration in the module's
  /// data list would hide the $config.dat's); corrected, it is written as an inline value.
  bool external = false;

  /// True when X, Y, Z, A, B and C are all given.
  bool completePose() const;
  /// The pose (all six components must be given; ArgumentError otherwise).
  calib::XyzAbc xyzAbc() const;
  /// Sets X..C (keeps S, T, external axes).
  void setPose(const calib::XyzAbc& p);
  /// Sets X..C where they change at the precision the writers use (formatMm: 1e-4 mm,
  /// formatDeg: 1e-5 deg); a component that does not change keeps its value, so that its text
  /// is written back as it was. Returns false (and changes nothing) when no component changes:
  /// a correction that rounds to zero leaves the target as written.
  bool setPoseIfChanged(const calib::XyzAbc& p);
};

/// The tool ($TOOL) or base ($BASE) frame active at a motion, and where it came from.
struct FrameSetting {
  enum class Source {
    kUnset,     ///< the program has not set it before this motion
    kInline,    ///< an inline aggregate ($TOOL = {X ..})
    kData,      ///< TOOL_DATA[n] / BASE_DATA[n] (value known only with the $config.dat)
    kNull,      ///< $NULLFRAME (TOOL_DATA[0] / BASE_DATA[0]: flange / world)
    kUnknown,   ///< set by something accura cannot evaluate (see `text`)
  };
  Source source = Source::kUnset;
  int index = 0;                ///< for kData: n of TOOL_DATA[n] / BASE_DATA[n]
  std::optional<calib::XyzAbc> value;  ///< the frame when known (mm, deg)
  std::string text;             ///< how the program said it (KRL expression: "TOOL_DATA[1]")
  std::string note;             ///< for kUnknown: why accura cannot evaluate it
  /// kUnknown: a value the program receives or computes at run time (a routine's parameter, a
  /// datum assigned while it runs): the motion is kept as written and named; otherwise a frame
  /// accura does not model (an error)
  bool run_time = false;
  SourceLocation where;         ///< where it was set

  bool known() const { return value.has_value(); }
};

/// A frame the program receives or computes at run time (FrameSetting::run_time): kUnknown,
/// written as `text`, set at `where`, `note` saying why its value is not known.
FrameSetting runTimeFrame(const std::string& text, const SourceLocation& where, const std::string& note);

/// The same frame as written: source, data index, the text of one accura cannot evaluate, and
/// the value at the written precision (formatMm / formatDeg); not where it was set. The writers
/// skip a frame the motion before already set; the readers compare a frame with the one a block
/// was entered with.
bool sameFrame(const FrameSetting& a, const FrameSetting& b);

/// A KUKA `$ORI_TYPE` (`circ` false) or `$CIRC_TYPE` (`circ` true) value as Motion::ori_type /
/// circ_type hold it: an enumeration constant (`#constant`, any case) in upper case, "" for the
/// default (#VAR, #BASE); anything else (an expression, `SORI_TYP(LCPDAT1)`) as written. The one
/// rule of the KRL reader, the KRL writer (a carried statement) and the XML reader.
std::string orientationControlValue(const std::string& value, bool circ);

/// Whether a Motion::ori_type / circ_type value is one the KRL reader could not follow ("?why":
/// set in a branch, by the caller, by a call); its reason is the text after the '?'.
inline bool orientationControlNotKnown(const std::string& value) { return !value.empty() && value[0] == '?'; }

/// A name every controller language can declare (a point's, a program's): a letter, '_' or '$',
/// then letters, digits, '_' or '$'; at most 64 characters. Anything else copied into a program
/// as text could change it (a newline in a name starts a statement of its own).
bool isDeclarableName(const std::string& name);

/// One motion statement.
struct Motion {
  MotionType type = MotionType::kPtp;
  bool spline = false;    ///< SPTP / SLIN / SCIRC / SPL (KUKA spline motions)
  /// KUKA: the spline block (SPLINE ... ENDSPLINE, PTP_SPLINE ... ENDSPLINE) the motion is a
  /// segment of, numbered 1, 2, ... in the program's order; 0: not in a block (a PTP, LIN, CIRC,
  /// or an SPTP / SLIN / SCIRC on its own, which stops at its end unless approximated). The
  /// segments of one block are one path, without stops between them.
  int spline_block = 0;
  bool ptp_spline_block = false;  ///< the block is a PTP_SPLINE block (else SPLINE)
  bool relative = false;  ///< PTP_REL / LIN_REL / CIRC_REL (not compensated)
  /// KUKA: the coordinate system of a relative motion, `#TOOL` written after it (the offset in
  /// the tool frame at the motion's start); false: `#BASE`, the default (written or not)
  bool relative_in_tool = false;
  Target target;          ///< end point
  std::optional<Target> aux;  ///< CIRC auxiliary point
  std::optional<double> circ_angle_deg;  ///< CIRC ... CA angle (not compensated)
  std::vector<Approximation> approximation;  ///< as written, in order (empty: exact stop)
  /// Blending parameter of the first approximation flag when known: C_DIS $APO.CDIS (mm),
  /// C_PTP $APO.CPTP (%), C_VEL $APO.CVEL (%), C_ORI $APO.CORI (deg).
  std::optional<double> approximation_value;
  std::optional<double> vel_m_s;      ///< path speed of LIN/CIRC ($VEL.CP, m/s)
  std::optional<double> vel_percent;  ///< PTP speed ($VEL_AXIS, percent)
  FrameSetting tool;   ///< T_flange_tcp active at this motion
  FrameSetting base;   ///< T_world_base (program base, relative to the controller's $WORLD)
  bool external_tcp = false;  ///< IPO_FRAME #TCP (stationary tool): not compensated
  /// KUKA: the orientation control of a CP motion ($ORI_TYPE, upper case): "" (#VAR, the
  /// default: the orientation turns from the start's to the target's), "#CONSTANT" (the start's
  /// orientation is kept, the target's ignored), "#JOINT" (the wrist axes turn linearly),
  /// "#IGNORE", or the expression as written when it is not a constant.
  std::string ori_type;
  /// KUKA: the orientation reference of a circular motion ($CIRC_TYPE, upper case): "" (#BASE,
  /// the default), "#PATH" (the orientation turns with the path), or the expression as written.
  std::string circ_type;
  /// Why the target cannot be evaluated (an undeclared name, an expression computed at run
  /// time, a point changed at run time); empty when it can.
  std::string target_problem;
  /// The problem is a data file that does not exist (KRL: a named point and no .dat next to the
  /// .src): the program is incomplete, an error for every motion type, PTP included.
  bool target_file_missing = false;
  std::string statement;  ///< the statement as written (for messages)
  SourceLocation where;   ///< of the statement
  int statement_id = -1;  ///< KRL: index in KrlSource::statements
  bool inserted = false;  ///< an auxiliary point added by the compensator (before statement_id)
  int trigger_count = 0;  ///< KRL: TRIGGER statements bound to this motion (since the last one)
  /// Why no auxiliary points may be inserted before this motion ("": they may): the pieces of a
  /// split motion would repeat or move something its statement carries (RAPID: a statement
  /// sharing its line, a MultiMove \ID, a time \T that is not a number). The end point is
  /// still compensated.
  std::string single_reason;
  /// Line of the source file (RAPID, URScript) this motion's statement starts on, carried
  /// through a conversion (carrySourceLines); 0: not carried.
  int source_line = 0;
  /// RAPID: configuration monitoring active at this motion (ConfJ\On for MoveJ, ConfL\On
  /// for MoveL/MoveC; the controller's default). Used only when the target has abb_conf.
  bool conf_monitored = true;
  /// The position before this motion is not known (RAPID: the first motion of a routine,
  /// which may be called from anywhere): the compensation starts afresh here.
  bool start_unknown = false;
  /// The motion moves external axes only and never the robot arm (RAPID MoveExtJ: mechanical
  /// units without a TCP). It is kept as written (target_problem says why); the arm's joints
  /// after it are those before it, so the next motion starts where the arm was, unless that
  /// motion's target (or the one the arm stands on) gives an external axis (a track may carry
  /// the robot).
  bool arm_stays = false;
  /// The programmed duration of the motion's statement (s): RAPID `\T:=`, URScript movel's and
  /// movej's `t`, XML `time_s`. The controller makes the move take that long (its speed is
  /// then not used). A writer carries it where its language can (RAPID `\T:=`, URScript `t=`,
  /// XML; a motion split into pieces gives each its share: pieceDurationText) and refuses a
  /// motion it cannot carry it for (KRL has no per-motion time). Empty: none.
  std::optional<double> duration_s;
  /// A duration the statement gives as an expression the controller computes (RAPID
  /// `\T:=tm`, URScript `t=tm`): its text. No other format can carry it (a conversion refuses
  /// the motion, or --drop-unconvertible leaves it out and lists it). Empty: none.
  std::string duration_expr;
  /// URScript movej(get_inverse_kin(pose, qnear=q)): the joints (deg) whose nearest solution
  /// the controller takes for the pose (URScript manual, get_inverse_kin); the compensation
  /// solves the target from them instead of from the previous point. Empty: not given.
  std::optional<std::array<double, 6>> qnear_deg;
};

/// Text spans of a KRL program, for writing it back byte for byte with only the corrected
/// values changed and the auxiliary points inserted.
struct KrlSource {
  struct Component {
    std::string name;   ///< upper case (X, Y, ..., S, T, E1, A1)
    size_t begin = 0;   ///< value text [begin, end) in the file
    size_t end = 0;
    double value = 0;   ///< as read
    size_t name_begin = 0;  ///< the component's name (X in "X 100.0")
  };
  struct Value {        ///< an aggregate {...} holding a target
    int file = 0;       ///< 0: .src, 1: .dat
    size_t begin = 0;   ///< '{'
    size_t end = 0;     ///< one past '}'
    std::vector<Component> components;  ///< in written order
    /// The point is declared GLOBAL (DECL GLOBAL E6POS XG1 in a PUBLIC data list): other modules
    /// may use it, and move with its correction.
    bool global = false;
    /// Where the program reads the point's value other than as a motion's target ("" when it
    /// does not), e.g. "P.src:6:3 ($BASE = XFB)": a frame or another point taken from it. A
    /// correction written into this value would move that use too; it goes into a new point.
    std::string read_elsewhere;
    /// The motions whose target is an element of this point's array chosen at run time (`LIN
    /// XPA[I]`, kept as written): they go to this value when the index says so, and move with
    /// its correction.
    std::vector<SourceLocation> chosen_at_run_time;
  };
  struct Statement {    ///< a motion statement line
    int file = 0;
    size_t line_begin = 0;   ///< first byte of the line
    size_t code_begin = 0;   ///< first non-blank byte
    size_t code_end = 0;     ///< end of the code (before a comment and trailing blanks)
    std::string eol;         ///< the line's end ("\n", "\r\n" or "" at the end of the file)
    /// Target expressions in the statement ([begin, end) in the file): end point, and the
    /// auxiliary point first for CIRC.
    std::vector<std::pair<size_t, size_t>> targets;
  };
  std::string src_path, dat_path;  ///< as given to the reader ("" when there is no .dat)
  std::string src_text, dat_text;  ///< the files' bytes
  std::vector<Value> values;
  std::vector<Statement> statements;
};

/// A statement the motion model does not express (I/O, logic, waits, comments, declarations of
/// other types), carried verbatim so that `convert` loses nothing (docs/program-formats.md,
/// "Pass-through statements"). Written back only into the language it was written in; a
/// writer for another language refuses it, naming `where`.
struct PassThrough {
  enum class Section {
    kBody,     ///< in the program body, before motion `before_motion`
    kTrailer,  ///< after the end of the main program (KRL: local subroutines after END)
    kData,     ///< in the data part (KRL: the .dat, before ENDDAT)
  };
  std::string language;      ///< "KRL", ...
  std::string text;          ///< one line as written, without its line end
  Section section = Section::kBody;
  size_t before_motion = 0;  ///< kBody: index in Program::motions (motions.size(): after the last)
  /// KRL: the spline block the statement is inside (Motion::spline_block: TIME_BLOCK, a
  /// trigger), 0: outside every block.
  int spline_block = 0;
  SourceLocation where;      ///< where it was read
  /// Why no other program can carry it (a motion of a KRL local subroutine, which the
  /// motion model does not hold): writers other than the in-place KRL one refuse it.
  std::string refuse;
  /// What the line is when it is carried only to give the source back byte for byte
  /// (carrySourceLines): empty: a statement outside the motion model (the other languages'
  /// writers refuse it); "motion": a line of a motion statement; "model": a line the motion
  /// model expresses (declarations of targets, tools and work objects, routine and module
  /// structure, configuration settings); "comment": a comment or blank line. The writers of
  /// other languages leave the lines with a role out.
  std::string role;
  int line = 0;     ///< line in the source file (1-based; 0: not carried with its place)
  std::string eol;  ///< the line's end as read: "\n", "\r\n" or "" (the file's last line)
};


/// The bytes of a program read from an XML file, for writing it back unchanged.
struct XmlSource {
  std::string text;
  size_t motions = 0;  ///< the motion count read
};

struct UrScriptSource;  // urscript.h
struct RapidSource;     // rapid.h

/// A program: the motion model, plus the source text it was read from (KRL, XML or URScript),
/// for writing it back with only the corrected numbers and inserted points changed.
struct Program {
  std::string name;    ///< program name (KRL DEF name, XML name attribute)
  /// KRL: the main DEF's parameter list as written ("count :IN"; empty: none), XML attribute
  /// krl_parameters; written back into a KRL DEF line (the other languages' routines take none).
  std::string krl_parameters;
  std::string robot;   ///< robot name (XML; empty when not given)
  std::vector<Motion> motions;
  /// Statements outside the motion model, in order (see PassThrough).
  std::vector<PassThrough> passthrough;
  std::shared_ptr<const KrlSource> krl;  ///< set by the KRL reader
  std::shared_ptr<const XmlSource> xml;  ///< set by the XML reader
  std::shared_ptr<const UrScriptSource> urscript;  ///< set by the URScript reader (urscript.h)
  std::shared_ptr<const RapidSource> rapid;        ///< set by the RAPID reader (rapid.h)
  std::string source_file;               ///< the file the program was read from
  /// What wrote a program made from the motion model alone (no source text to patch): named
  /// in the first comment of the URScript and RAPID writers ("written by accura convert").
  std::string written_by = "accura convert";
  /// KRL: the module holds functions only (GLOBAL DEFFCT ... ENDFCT, no DEF): a module the
  /// controller loads, without motions; `compensate` and `batch` write it as it is, a writer of
  /// another form refuses it. Says which function and where ("" for every other program).
  std::string krl_functions_only;
};

/// True when a writer must produce new text: a target is modified, a motion inserted.
bool programChanged(const Program& program);

/// ArgumentError naming the first pass-through statement of `program` that a writer for
/// `language` cannot carry (another language, or PassThrough::refuse); nothing when all can.
/// `language` empty: a writer that carries every language (XML).
void checkPassThrough(const Program& program, const std::string& language);

/// How a refusal to convert a statement outside the motion model ends: the option that converts
/// the program without such statements.
inline constexpr const char* kDropStatementsHint = "convert --drop-unconvertible leaves such statements out and lists them";
/// The same for a setting of a motion another language cannot hold.
inline constexpr const char* kDropSettingHint = "convert --drop-unconvertible converts the motion without it and lists it";

/// Carries the whole source `text` of a program read from `language` (RAPID, URScript) in
/// Program::passthrough, so that the writer of that language gives it back byte for byte after
/// a conversion (docs/program-formats.md, "Pass-through statements"): every line gets its
/// number and line end; the pass-through statements already there keep their role (none);
/// the lines of motion statements (motion_spans[k]: [first byte, one past the last byte] of
/// motion k's statement; an inserted motion has none) get the role "motion" and set
/// Motion::source_line; a blank line or a
/// line starting with `comment` gets "comment"; any other line "model". Throws ArgumentError
/// naming the line when a line holds two motion statements or a motion and another statement.
void carrySourceLines(Program& program, const std::string& text, const std::string& language, char comment,
                      const std::vector<std::pair<size_t, size_t>>& motion_spans);

/// The source text carried in `program` for `language` (carrySourceLines; the lines in their
/// order, each with its line end); nothing when it carries none. Throws ArgumentError naming
/// the line when a line number is given twice.
std::optional<std::string> carriedSource(const Program& program, const std::string& language);

/// `parsed` (the carried source read back) with the motion model of `program` laid on it:
/// each carried motion (Motion::source_line) takes the targets of the corresponding motion of
/// `program` (marked modified where they differ at the precision written, abb_conf included;
/// a target named otherwise than its declared point is a new declaration replacing it),
/// and a motion of `program` that carries no line is inserted before the next carried one
/// (Motion::inserted). Throws ArgumentError naming the motion when the two disagree (another
/// count, type, speed or approximation of the motions, an added motion after the last one).
Program reattachCarried(const Program& program, Program parsed);

/// `program` without the lines carried only for `language`'s byte-for-byte return (a role
/// set), for a writer of another language. A comment (commentText: an XML comment, a KRL `;`,
/// RAPID `!` or URScript `#` line) of another language becomes comment lines of `language`
/// instead, one per line of its text: KRL `;`, RAPID `!`, URScript `#` (RAPID and URScript
/// indented like a routine's statements).
Program withoutCarriedLines(const Program& program, const std::string& language);
/// Whether withoutCarriedLines(program, language) differs from `program` (a line carried for
/// another language, a comment of another language to rewrite): else the writer needs no copy.
bool withoutCarriedLinesChanges(const Program& program, const std::string& language);

/// The text of a carried statement that is a comment and nothing else, without its marker and
/// the blanks around it: an XML comment (isXmlComment), a KRL line starting with `;` (not a fold
/// marker, which the KUKA editor pairs), a RAPID `!` line, a URScript `#` line. nullopt for any
/// other statement.
std::optional<std::string> commentText(const PassThrough& s);

/// True for a comment of an XML program (`<!-- .. -->`, read as language "XML", role "comment"):
/// the XML writer writes it back where it was.
bool isXmlComment(const PassThrough& s);

/// A point name that `program` does not use yet (no target of it, no identifier of its KRL
/// text, case-insensitive) and `taken` does not hold: `base` followed by "_1", "_2", ...,
/// shortened to KRL's 24 characters.
std::string newPointName(const Program& program, const std::string& base, const std::vector<std::string>& taken);

/// The KRL keyword of a motion: PTP, LIN, CIRC, SPL, SPTP, SLIN, SCIRC; _REL appended for a
/// relative motion (LIN_REL, SPTP_REL).
std::string motionKeyword(const Motion& m);

/// The motion instruction as the source language writes it: the first word of
/// Motion::statement (MoveL, MoveAbsJ, movel, LIN, PTP_REL; for XML the element name: lin);
/// motionKeyword when the statement is not known.
std::string motionInstruction(const Motion& m);

/// A motion statement whose programmed duration (URScript movel's `t`, RAPID's `\T:=`) the
/// compensation split into pieces: `index` is the motion of the statement itself (the last
/// piece), the inserted motions of the same statement come right before it. Returns each
/// piece's share of the duration, in order (sum 1): proportional to its TCP path length, or to
/// its rotation when the statement only turns the tool, or equal when the start is unknown.
/// A single share of 1 when nothing was inserted.
std::vector<double> durationShares(const Program& program, size_t index);

/// The duration of motion `index`'s piece (inserted or not) of a statement programmed to take
/// `duration_s` (s), as the writers put it: seconds with 4 decimals, the statement's last piece
/// taking what the others leave, so that the pieces add up to the time as written. Empty when
/// the statement was not split or has no time (duration_s <= 0). Throws ArgumentError when an inserted motion is not followed by
/// its statement's motion.
std::string pieceDurationText(const Program& program, size_t index, double duration_s);

/// Number formats for values the post-processor writes (fixed decimals, never "-0"):
/// lengths %.4f (mm, 0.1 um), angles %.5f (deg, ~0.2 urad), speeds and other values %.4f.
/// (formatFixed is calib's one number formatter, accura/calib/text.h.)
std::string formatMm(double v);
std::string formatDeg(double v);

/// A TOOL_DATA / BASE_DATA table (index -> frame), e.g. from $config.dat.
struct FrameTables {
  std::vector<std::optional<calib::XyzAbc>> tool;  ///< [n] = TOOL_DATA[n]
  std::vector<std::optional<calib::XyzAbc>> base;  ///< [n] = BASE_DATA[n]
  std::string file;                          ///< where they were read from
};

}  // namespace accura::postproc
