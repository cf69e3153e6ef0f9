#include "accura/postproc/program_io.h"

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "accura/calib/errors.h"
#include "accura/postproc/krl.h"
#include "accura/postproc/rapid.h"
#include "accura/postproc/urscript.h"
#include "accura/postproc/xml_program.h"
#include "excerpt.h"
#include "krl_internal.h"

namespace fs = std::filesystem;

namespace accura::postproc {

namespace {

/// Why `format` cannot carry motion `m`'s programmed time (Motion::duration_s / duration_expr),
/// "" when it can: KRL has no per-motion time; URScript's movec has no `t`; a time computed
/// at run time is its own language's only.
std::string timeNotCarried(const Motion& m, ProgramFormat format) {
  if (!m.duration_expr.empty()) return "the controller computes it at run time in the source's language";
  if (!m.duration_s) return "";
  if (format == ProgramFormat::kKrl) return "KRL has no per-motion time";
  if (format == ProgramFormat::kUrScript && m.type == MotionType::kCirc) return "URScript's movec has no time t";
  return "";
}

/// The time of `m` as a message names it: "4.0000 s", or the expression.
std::string timeText(const Motion& m) {
  return m.duration_s ? calib::formatFixed(*m.duration_s, 4) + " s" : "'" + detail::excerpt(m.duration_expr) + "'";
}

/// Whether a motion of `program` has a KUKA orientation control other than the default
/// (Motion::ori_type of a CP motion, circ_type of a circle).
bool hasOrientationControl(const Program& program) {
  for (const Motion& m : program.motions)
    if ((m.type != MotionType::kPtp && !m.ori_type.empty()) || (m.type == MotionType::kCirc && !m.circ_type.empty())) return true;
  return false;
}

/// `program` for RAPID or URScript (`format`), which have no orientation control: their path
/// motions turn the orientation from the start's to the target's (KUKA's $ORI_TYPE #VAR,
/// $CIRC_TYPE #BASE). A CP motion with $ORI_TYPE #CONSTANT keeps the orientation it starts
/// with (KSS 8.x Operating and Programming Instructions for System Integrators, "Orientation
/// control LIN, CIRC"): written exactly as a motion to its target with that orientation (the
/// auxiliary point's too), where it is known (the previous motion's Cartesian target or kept
/// orientation, in the same tool and base, no call or branch in between). Another value (#JOINT,
/// $CIRC_TYPE #PATH, one the KRL reader could not follow) or a #CONSTANT start that is not known
/// cannot be written: an error naming the motion, or with `dropped` the motion converts without
/// it and is listed there (in the program's order). The result has no orientation control left.
Program orientationControlWritten(const Program& program, ProgramFormat format, std::vector<PassThrough>* dropped) {
  const char* language = format == ProgramFormat::kRapid ? "RAPID" : "URScript";
  Program out = program;
  std::vector<PassThrough> listed;
  std::optional<std::array<double, 3>> ori;  // A, B, C (deg) the robot has after the previous motion
  const Motion* prev = nullptr;
  for (Motion& m : out.motions) {
    const bool known_start = prev && !m.start_unknown && ori && sameFrame(m.tool, prev->tool) && sameFrame(m.base, prev->base);
    const std::optional<std::array<double, 3>> start = known_start ? ori : std::nullopt;
    const std::string o = m.type != MotionType::kPtp ? m.ori_type : "";
    const std::string c = m.type == MotionType::kCirc ? m.circ_type : "";
    std::string setting, why;
    if (orientationControlNotKnown(o)) {
      setting = "$ORI_TYPE";
      why = "it is not known here: " + o.substr(1);
    } else if (orientationControlNotKnown(c)) {
      setting = "$CIRC_TYPE";
      why = "it is not known here: " + c.substr(1);
    } else if (!c.empty()) {
      setting = "$CIRC_TYPE " + c + (o.empty() ? "" : " with $ORI_TYPE " + o);
      why = "the orientation turns with the circle";
    } else if (o == "#CONSTANT" && !start) {
      setting = "$ORI_TYPE #CONSTANT";
      why = "it keeps the orientation the robot has at its start, which is not known here";
    } else if (!o.empty() && o != "#CONSTANT") {
      setting = "$ORI_TYPE " + o;
      why = o == "#JOINT" ? "the controller turns the wrist axes linearly" : "not a setting accura writes";
    }
    // the orientation after the motion, as the KUKA controller runs it
    std::optional<std::array<double, 3>> after;
    const Target& t = m.target;
    if (o == "#CONSTANT" && c.empty()) after = start;
    else if (t.kind == Target::Kind::kCartesian && t.pose[3] && t.pose[4] && t.pose[5] && (c.empty() || o.empty()))
      after = std::array<double, 3>{*t.pose[3], *t.pose[4], *t.pose[5]};
    if (o == "#CONSTANT" && start && c.empty()) {
      for (Target* p : {&m.target, m.aux ? &*m.aux : nullptr})
        if (p && p->kind == Target::Kind::kCartesian)
          for (size_t k = 0; k < 3; ++k) p->pose[3 + k] = (*start)[k];
    } else if (!setting.empty()) {
      if (!dropped)
        throw calib::ArgumentError(m.where.str() + ": cannot convert '" + detail::excerpt(m.statement) + "' to " + language + ": its orientation control " +
                                   setting + " cannot be carried (" + why + "; " + language +
                                   " turns the orientation from the start's to the target's) (" + kDropSettingHint + ")");
      PassThrough s;
      s.language = "orientation";
      s.where = m.where;
      s.text = "orientation control " + setting + " of " + detail::excerpt(m.statement) + " (" + why + "; " + language + " has no such setting)";
      listed.push_back(std::move(s));
    }
    m.ori_type.clear();
    m.circ_type.clear();
    ori = after;
    prev = &m;
  }
  if (dropped) dropped->insert(dropped->end(), listed.begin(), listed.end());
  return out;
}

}  // namespace

ProgramFormat programFormat(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".src") return ProgramFormat::kKrl;
  if (ext == ".xml") return ProgramFormat::kXml;
  if (ext == ".script") return ProgramFormat::kUrScript;
  if (isRapidModulePath(path)) return ProgramFormat::kRapid;
  std::error_code ec;
  const bool dir = fs::is_directory(path, ec);  // (a directory given for a program: say so, not its empty extension)
  throw calib::InputError(path + ": expected a program file ending in .src (KUKA KRL) or .xml (accura XML program) or .script (URScript) or .mod/.modx/.sys/.sysx/.prg (ABB RAPID), found " +
                          (dir ? std::string("a directory") : "'" + fs::path(path).extension().string() + "'"));
}

// RAPID modules: .mod and .sys (program and system modules, RobotWare 5), .modx and .sysx (the
// same text as RobotStudio saves them for RobotWare 6 and later), .prg (S4C era)
bool isRapidModulePath(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".mod" || ext == ".modx" || ext == ".sys" || ext == ".sysx" || ext == ".prg";
}

void setConfigPaths(ProgramReadOptions& options, const std::vector<std::string>& paths) {
  options.config_path = paths.empty() ? std::string() : paths.front();
  options.more_config_paths.assign(paths.size() > 1 ? paths.begin() + 1 : paths.end(), paths.end());
}

std::vector<std::string> configPaths(const ProgramReadOptions& options) {
  std::vector<std::string> out;
  if (!options.config_path.empty()) out.push_back(options.config_path);
  for (const std::string& p : options.more_config_paths)
    if (!p.empty()) out.push_back(p);
  return out;
}

Program readProgram(const std::string& path, const ProgramReadOptions& options) {
  const ProgramFormat format = programFormat(path);
  const std::vector<std::string> configs = configPaths(options);
  if (format == ProgramFormat::kUrScript) {
    if (!options.dat_path.empty()) throw calib::InputError("--dat: only for KRL programs (.src), found the URScript program " + path);
    if (!configs.empty())
      throw calib::InputError("--config: only for KRL and XML programs ($config.dat frames), found the URScript program " + path +
                       " (its TCP comes from set_tcp or --program-tool)");
    return readUrScript(path);
  }
  if (format == ProgramFormat::kRapid) {
    if (!options.dat_path.empty()) throw calib::InputError("--dat: only for KRL programs (.src), found the RAPID module " + path);
    // --config for a RAPID module: the other modules of its task (CalibData.mod, user.sys)
    // whose data it uses; a $config.dat (KUKA's frames) is of no use to it
    for (const std::string& c : configs)
      if (!isRapidModulePath(c))
        throw calib::InputError("--config: a KUKA $config.dat is only for KRL and XML programs, found the RAPID module " + path +
                                (configs.size() > 1 ? " and " + c : std::string()) +
                                " (give the module of its task that declares its tooldata and wobjdata, CalibData.mod or user.sys, "
                                "or --program-tool / --program-base)");
    return readRapid(path, configs);
  }
  for (const std::string& c : configs)
    if (isRapidModulePath(c))
      throw calib::InputError("--config: a RAPID module (the tooldata and wobjdata of an ABB task) is only for RAPID programs, found " +
                              std::string(format == ProgramFormat::kKrl ? "the KRL program " : "the XML program ") + path +
                              (configs.size() > 1 ? " and " + c : std::string()) + " (give the $config.dat with TOOL_DATA and BASE_DATA)");
  // KUKA's controller has one $config.dat (KRC:\R1\System\$config.dat, the system's global
  // data list); a second one would be another controller's, and taking either would be a guess
  if (configs.size() > 1)
    throw calib::InputError("--config: a KRL or XML program takes one $config.dat (the controller has one, KRC:\\R1\\System\\$config.dat), found " +
                            std::to_string(configs.size()) + ": " + configs[0] + " and " + configs[1] +
                            " (the GLOBAL points of other programs' .dat files are found by accura batch in its tree)");
  if (format == ProgramFormat::kKrl) {
    KrlReadOptions o;
    o.dat_path = options.dat_path;
    o.config_path = options.config_path;
    o.other_globals = options.other_globals;
    return readKrl(path, o);
  }
  if (!options.dat_path.empty()) throw calib::InputError("--dat: only for KRL programs (.src), found the XML program " + path);
  if (!options.config_path.empty()) {
    const FrameTables tables = readKrlFrameTables(options.config_path);
    return readXmlProgram(path, &tables);
  }
  return readXmlProgram(path);
}

namespace {

// How a statement steers the run: opens a block (IF .. THEN, a loop, SWITCH / TEST, URScript's
// `if ..:`), continues it (ELSE, CASE, elif), closes it, or jumps (GOTO, RETURN, EXIT); 0 else.
char flowRole(const PassThrough& s) {
  const size_t b = s.text.find_first_not_of(" \t");
  if (b == std::string::npos) return 0;
  size_t e = b;
  while (e < s.text.size() && (std::isalnum(static_cast<unsigned char>(s.text[e])) || s.text[e] == '_')) ++e;
  const std::string word = s.text.substr(b, e - b);
  std::string up = word;
  for (char& c : up) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (s.language == "URScript") {
    std::string line = s.text;
    while (!line.empty() && std::isspace(static_cast<unsigned char>(line.back()))) line.pop_back();
    if ((word == "if" || word == "while" || word == "for" || word == "thread" || word == "def") && !line.empty() && line.back() == ':')
      return 'o';
    if (word == "elif" || word == "else") return 'm';
    if (word == "end") return 'c';
    if (word == "return" || word == "halt") return 'j';
    return 0;
  }
  if (s.language == "RAPID") {
    std::string text = s.text;
    for (char& c : text) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    if ((up == "IF" && text.find("THEN") != std::string::npos) || up == "FOR" || up == "WHILE" || up == "TEST") return 'o';
    if (up == "ELSEIF" || up == "ELSE" || up == "CASE" || up == "DEFAULT") return 'm';
    if (up == "ENDIF" || up == "ENDFOR" || up == "ENDWHILE" || up == "ENDTEST") return 'c';
    if (up == "GOTO" || up == "RETURN" || up == "EXIT" || (up == "IF" && text.find("GOTO") != std::string::npos)) return 'j';
    return 0;
  }
  if (s.language == "KRL") {  // (a spline block holds motions only: it does not steer the run)
    using krl_detail::BlockWords;
    const BlockWords* open = krl_detail::blockOpenedBy(up);
    const BlockWords* close = krl_detail::blockClosedBy(up);
    if (open && open->kind != BlockWords::kSpline) return 'o';
    if (krl_detail::startsBranch(up)) return 'm';
    if (close && close->kind != BlockWords::kSpline) return 'c';
    if (krl_detail::isJump(up)) return 'j';
  }
  return 0;
}

// Dropping a branch, a loop or a jump around motions would run them unconditionally (both
// branches one after the other, a loop's body once, the motions after a RETURN): another path
// than the program's. Refused, naming the statement and the motion it governs.
void refuseDroppedFlowAroundMotions(const std::vector<PassThrough>& dropped, const std::vector<Motion>& motions) {
  const auto refuse = [&](const PassThrough& s, size_t motion) {
    throw calib::ArgumentError(s.where.str() + ": cannot drop '" + detail::excerpt(s.text) + "': it " +
                               (flowRole(s) == 'j' ? "jumps over or ends before" : "branches or loops around") + " the motion at " +
                               motions[std::min(motion, motions.size() - 1)].where.str() +
                               ", which would then run unconditionally (the converted program would take another path)");
  };
  std::vector<const PassThrough*> open;
  for (const PassThrough& s : dropped) {
    if (s.section != PassThrough::Section::kBody) continue;
    const char role = flowRole(s);
    if (role == 'o') open.push_back(&s);
    if ((role == 'm' || role == 'c') && !open.empty() && open.back()->before_motion != s.before_motion) refuse(*open.back(), open.back()->before_motion);
    if (role == 'c' && !open.empty()) open.pop_back();
    if (role == 'j' && s.before_motion < motions.size()) refuse(s, s.before_motion);
  }
  for (const PassThrough* s : open)
    if (s->before_motion < motions.size()) refuse(*s, s->before_motion);
}

}  // namespace

Program dropUnconvertible(const Program& program, ProgramFormat format, std::vector<PassThrough>* dropped) {
  // a motion's time the output cannot carry: the motion converts without it, listed
  const auto dropTimes = [&](Program& p) {
    std::vector<PassThrough> times;
    for (Motion& m : p.motions) {
      const std::string why = timeNotCarried(m, format);
      if (why.empty()) continue;
      PassThrough s;
      s.language = "time";
      s.where = m.where;
      s.text = "time " + timeText(m) + " of " + detail::excerpt(m.statement) + " (" + why + ")";
      times.push_back(std::move(s));
      m.duration_s.reset();
      m.duration_expr.clear();
    }
    // (in the program's order with the statements dropped before)
    const size_t before = dropped->size();
    dropped->insert(dropped->end(), times.begin(), times.end());
    std::stable_sort(dropped->begin() + static_cast<std::ptrdiff_t>(before), dropped->end(),
                     [](const PassThrough& a, const PassThrough& b) { return a.where.line < b.where.line; });
  };
  if (format == ProgramFormat::kXml) {
    Program out = program;
    dropTimes(out);
    return out;
  }
  const char* language = format == ProgramFormat::kKrl ? "KRL" : format == ProgramFormat::kRapid ? "RAPID" : "URScript";
  Program out = program.rapid && format != ProgramFormat::kRapid         ? rapidForConversion(program)
                : program.urscript && format != ProgramFormat::kUrScript ? urScriptForConversion(program, "XML")
                                                                         : program;
  std::vector<PassThrough> kept;
  for (const PassThrough& s : out.passthrough) {
    // (a comment of another language becomes one of this language: withoutCarriedLines)
    if (!s.role.empty() || (s.language == language && s.refuse.empty()) || commentText(s)) kept.push_back(s);
    else dropped->push_back(s);
  }
  out.passthrough = std::move(kept);
  refuseDroppedFlowAroundMotions(*dropped, out.motions);
  // into another language, the KRL text is not written back: its logic lines were the
  // pass-through statements just left out
  if (format != ProgramFormat::kKrl) out.krl.reset();
  if (!(format == ProgramFormat::kRapid && program.rapid) && !(format == ProgramFormat::kUrScript && program.urscript)) dropTimes(out);
  if (format != ProgramFormat::kKrl && hasOrientationControl(out)) out = orientationControlWritten(out, format, dropped);
  return out;
}

namespace {

/// write(withoutCarriedLines(program, language)), copying the program only when that changes
/// it (withoutCarriedLinesChanges): a compensated path of 100 000 motions is some 170 MB of
/// motions, not to be copied for nothing.
template <class Write>
auto writeWithoutCarriedLines(const Program& program, const char* language, Write write) {
  return withoutCarriedLinesChanges(program, language) ? write(withoutCarriedLines(program, language)) : write(program);
}

}  // namespace

std::vector<calib::OutputFile> renderProgram(const Program& program, ProgramFormat format, const std::string& path,
                                      const std::string& dat_path) {
  // a KRL module of functions only has no program another language could hold (with its
  // statements dropped, an empty one)
  if (!program.krl_functions_only.empty() && (format != ProgramFormat::kKrl || !program.krl))
    throw calib::ArgumentError(program.source_file + ": cannot write it as a program: the module holds functions only (the first: " +
                               program.krl_functions_only + "), no DEF program with motions");
  if ((format == ProgramFormat::kRapid || format == ProgramFormat::kUrScript) && hasOrientationControl(program))
    return renderProgram(orientationControlWritten(program, format, nullptr), format, path, dat_path);
  if (format == ProgramFormat::kRapid) {
    if (!program.rapid && program.urscript) return renderProgram(urScriptForConversion(program, "RAPID"), format, path, dat_path);
    return {{path, writeWithoutCarriedLines(program, "RAPID", writeRapid)}};
  }
  if (program.rapid) return renderProgram(rapidForConversion(program), format, path, dat_path);
  if (format == ProgramFormat::kUrScript) return {{path, writeWithoutCarriedLines(program, "URScript", writeUrScript)}};
  if (program.urscript) return renderProgram(urScriptForConversion(program, format == ProgramFormat::kXml ? "XML" : "KRL"), format, path, dat_path);
  if (format == ProgramFormat::kXml) return {{path, writeXmlProgram(program)}};
  if (!program.krl)  // (a program read from KRL has no time)
    for (const Motion& m : program.motions)
      if (const std::string why = timeNotCarried(m, ProgramFormat::kKrl); !why.empty())
        throw calib::ArgumentError(m.where.str() + ": cannot convert '" + detail::excerpt(m.statement) + "' to KRL: its time " + timeText(m) +
                                   " cannot be carried, " + why + " (" + kDropSettingHint + ")");
  const KrlText t = writeWithoutCarriedLines(program, "KRL", writeKrl);
  std::vector<calib::OutputFile> out = {{path, t.src}};
  const bool has_dat = program.krl ? !program.krl->dat_path.empty() : true;
  if (has_dat) out.push_back({dat_path.empty() ? fs::path(path).replace_extension(".dat").string() : dat_path, t.dat});
  return out;
}

}  // namespace accura::postproc
