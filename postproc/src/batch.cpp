// Batch compensation (see batch.h); the atomic writing is in batch_write.cpp.
#include "accura/postproc/batch.h"
#include "accura/postproc/krl.h"

#include <tinyxml2.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <map>
#include <mutex>
#include <thread>

#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "accura/calib/geometry.h"
#include "accura/postproc/program_io.h"
#include "accura/postproc/report.h"

namespace fs = std::filesystem;

namespace accura::postproc {
namespace {

std::string relativeSlash(const fs::path& p) {
  std::string s = p.generic_string();
  return s;
}

bool isHidden(const fs::path& p) {
  const std::string n = p.filename().string();
  return !n.empty() && n[0] == '.';
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// An .xml file whose root element is <program>.
bool isXmlProgram(const std::string& path) {
  tinyxml2::XMLDocument doc;
  if (doc.LoadFile(path.c_str()) != tinyxml2::XML_SUCCESS) return true;  // let the reader report it
  const tinyxml2::XMLElement* root = doc.RootElement();
  return root && std::string(root->Name()) == "program";
}

bool inside(const fs::path& child, const fs::path& parent) {
  auto c = child.begin();
  for (auto p = parent.begin(); p != parent.end(); ++p, ++c) {
    if (p->empty()) continue;
    if (c == child.end() || *c != *p) return false;
  }
  return true;
}

}  // namespace

namespace {

bool programExtension(const fs::path& p) {
  const std::string ext = lower(p.extension().string());
  // (RAPID: the program modules; system modules, .sys/.sysx, are the controller's: a backup's
  // base.sys and user.sys hold no program. Give one with compensate --in.)
  return ext == ".src" || ext == ".xml" || ext == ".script" || (isRapidModulePath(p.string()) && ext != ".sys" && ext != ".sysx");
}

// One directory of the tree, its subdirectories depth first. A directory that cannot be listed
// (or whose listing breaks off) is a problem of the tree, not the end of the walk: the walk goes
// on with the others (problems null: an InputError).
void walk(const fs::path& in_dir, const fs::path& dir, std::vector<std::string>& out, std::vector<TreeProblem>* problems) {
  const auto problem = [&](const fs::path& p, bool failed, const std::string& message) {
    if (!problems) {
      // without a list: a directory that cannot be listed is an error, the rest is left out
      if (message.rfind("cannot list", 0) == 0) throw calib::InputError(p.string() + ": " + message);
      return;
    }
    problems->push_back({relativeSlash(p.lexically_relative(in_dir)), failed, message});
  };
  std::error_code ec;
  fs::directory_iterator it(dir, ec), end;
  if (ec) {
    if (dir == in_dir) throw calib::InputError(in_dir.string(), 0, 0, "cannot list the directory: " + ec.message());
    problem(dir, true, "cannot list the directory: " + ec.message() + " (the programs under it are not compensated)");
    return;
  }
  std::vector<fs::path> subdirs;
  for (; !ec && it != end; it.increment(ec)) {
    const fs::path p = it->path();
    if (isHidden(p)) continue;  // not recursed into either
    std::error_code sec;
    const bool link = it->is_symlink(sec);
    const fs::file_status st = fs::status(p, sec);  // follows a symbolic link
    if (sec || !fs::exists(st)) {
      // a symbolic link to nothing, or in a loop: a program by its name that cannot be read
      if (link && programExtension(p)) problem(p, true, "cannot read the program: a symbolic link that leads to no file");
      continue;
    }
    if (fs::is_directory(st)) {
      if (link) problem(p, false, "a symbolic link to a directory: not followed (give its target as --in to compensate its programs)");
      else subdirs.push_back(p);
      continue;
    }
    if (!programExtension(p)) continue;
    if (!fs::is_regular_file(st)) {
      problem(p, true, "cannot read the program: not a regular file");
      continue;
    }
    // the name as found in the tree (lexically: a symbolic link keeps its own name, so that its
    // output lands under --out like any other, not beside the file it points to)
    out.push_back(relativeSlash(p.lexically_relative(in_dir)));
  }
  if (ec) problem(dir, true, "cannot list the directory: " + ec.message() + " (the programs under it are not compensated)");
  for (const fs::path& d : subdirs) walk(in_dir, d, out, problems);
}

}  // namespace

std::vector<std::string> findPrograms(const std::string& in_dir, std::vector<TreeProblem>* problems) {
  std::vector<std::string> out;
  walk(fs::path(in_dir), fs::path(in_dir), out, problems);
  std::sort(out.begin(), out.end());
  if (problems)
    std::sort(problems->begin(), problems->end(), [](const TreeProblem& a, const TreeProblem& b) { return a.path < b.path; });
  return out;
}

std::vector<std::string> findPrograms(const std::string& in_dir) { return findPrograms(in_dir, nullptr); }

namespace {

std::vector<calib::OutputFile> render(const Program& compensated, ProgramFormat format, const std::string& out_path) {
  std::string dat_out;
  if (compensated.krl && !compensated.krl->dat_path.empty())
    dat_out = (fs::path(out_path).parent_path() / fs::path(compensated.krl->dat_path).filename()).string();
  return renderProgram(compensated, format, out_path, dat_out);
}

}  // namespace

std::vector<calib::OutputFile> compensateFile(const std::string& in_path, const std::string& out_path,
                                       const ProgramReadOptions& read, const JobSettings& job, JobReport* report) {
  const ProgramFormat format = programFormat(in_path);
  return render(compensateProgram(readProgram(in_path, read), job, report), format, out_path);
}

CheckedProgram compensateAndCheckFile(const std::string& in_path, const std::string& out_path, const ProgramReadOptions& read,
                                      const JobSettings& job, const CellCheckSettings* cell, JobReport* report) {
  const ProgramFormat format = programFormat(in_path);
  Program program = readProgram(in_path, read);
  CheckedProgram out;
  const JobSettings placed = cell ? placedInCell(job, cell->cell) : job;
  // with a cell, the check first, on the program as read (its targets are where the tool must
  // go: docs/checks.md, "intended"): it does not need the compensation, and it explains why a
  // compensation fails (an unreachable target, a joint beyond its limit)
  if (cell)
    out.check = cell->geometry ? checkProgram(program, placed, cell->cell, cell->options, *cell->geometry)
                               : checkProgram(program, placed, cell->cell, cell->options);
  ProgramCompensation pc = compensateProgramReport(program, placed);
  program = Program();  // not needed any more: a long path's motions are not kept twice while it is written
  if (!pc.ok()) {
    if (report) *report = pc.report;  // complete, its errors included (errors.h, "The rule")
    if (!out.check || !compensationFailureExplained(*out.check, pc.report)) throw compensationError(pc.report);
    out.compensation_error = compensationError(pc.report).what();
    out.write = false;
    return out;
  }
  if (report) *report = std::move(pc.report);
  out.files = render(pc.program, format, out_path);
  if (!cell) return out;
  out.write = out.check->passed() || cell->warn_only;
  return out;
}

ProgramFileResult compensateProgramFile(const ProgramFileRequest& q, const JobSettings& job) {
  programFormat(q.in_path);  // a clear error for another extension before anything else
  std::error_code ec;
  if (fs::exists(q.out_dir, ec) && !fs::is_directory(q.out_dir, ec))
    throw calib::InputError(q.out_name + ": expected a directory, found the file " + q.out_dir);
  const std::string out_path = (fs::path(q.out_dir) / fs::path(q.in_path).filename()).string();
  ProgramFileResult r;
  r.checked = compensateAndCheckFile(q.in_path, out_path, q.read, job, q.cell, &r.report);
  std::vector<std::string> inputs = {q.in_path, fs::path(q.in_path).replace_extension(".dat").string()};
  if (!q.read.dat_path.empty()) inputs.push_back(q.read.dat_path);
  for (const std::string& c : configPaths(q.read)) inputs.push_back(c);
  inputs.insert(inputs.end(), q.other_inputs.begin(), q.other_inputs.end());
  calib::refuseToOverwrite(r.checked.files, inputs, q.out_name);
  if (!q.json_path.empty()) calib::refuseToOverwrite({{q.json_path, ""}}, inputs, q.json_name);
  // The program's files and the report are one output set: written together or not at all (a
  // report that cannot be written leaves no program behind, and the reverse).
  std::vector<calib::OutputFile> outputs;
  if (r.checked.write) outputs = r.checked.files;
  if (!q.json_path.empty()) {
    CompensationReport rep;
    rep.program = q.in_path;
    for (const auto& f : outputs) rep.outputs.push_back(f.path);
    rep.robot = job.calibrated.nominal.name;
    rep.tol_mm = job.tol_mm;
    rep.job = r.report;
    rep.compensation_error = r.checked.compensation_error;
    rep.check = r.checked.check;
    outputs.push_back({q.json_path, compensationReportText(rep)});
  }
  if (outputs.empty()) return r;
  bool created_out_dir = false;
  if (r.checked.write && !fs::exists(q.out_dir, ec)) {
    calib::createDirectories(q.out_dir);
    created_out_dir = true;
  }
  try {
    calib::writeFilesAtomically(outputs);
  } catch (...) {
    if (created_out_dir) fs::remove(q.out_dir, ec);  // only the empty directory this call made
    throw;
  }
  r.written = r.checked.write;
  return r;
}

bool compensationFailureExplained(const CheckReport& check, const JobReport& report) {
  if (check.passed() || report.errors.empty()) return false;
  const auto same = [](const SourceLocation& a, const SourceLocation& b) { return a.file == b.file && a.line == b.line; };
  for (const ProgramIssue& e : report.errors) {
    bool found = false;
    for (const CheckViolation& v : check.violations) found = found || same(v.where, e.where);
    for (const ProgramIssue& u : check.unchecked) found = found || same(u.where, e.where);
    if (!found) return false;
  }
  return true;
}

std::string firstCheckProblem(const CheckReport& check) {
  if (check.passed()) return "";
  const size_t n = check.violations.size(), u = check.unchecked.size();
  std::string counts = std::to_string(n) + " violation(s)" + (u ? ", " + std::to_string(u) + " motion(s) not checked" : "");
  if (n > 0) {
    const CheckViolation& v = check.violations.front();
    std::string deepest;  // the first violation is where the clearance gets short: how short it gets
    if (v.kind == CheckKind::kClearance)
      for (const MotionCheck& m : check.motions)
        if (m.motion_index == v.motion_index && m.min_clearance_mm < v.value)
          deepest = "; smallest clearance on this motion " + calib::formatFixed(m.min_clearance_mm, 3) + " mm";
    return v.where.str() + ": " + v.message + " [" + v.motion_type + deepest + "; " + counts + "]";
  }
  const ProgramIssue& w = check.unchecked.front();
  return w.where.str() + ": " + w.message + " [" + counts + "]";
}

BatchResult runBatch(const std::string& in_dir, const std::string& out_dir, const BatchOptions& options,
                     const std::function<void(const BatchFileResult&, int, int)>& progress) {
  std::error_code ec;
  if (!fs::is_directory(in_dir, ec)) {
    // one program given to batch: said with the command that takes one
    if (fs::exists(in_dir, ec))
      throw calib::InputError(in_dir + ": expected a directory of programs (--in), found a file; one program: accura compensate --in " + in_dir +
                              " --out DIR");
    throw calib::InputError(in_dir + ": expected a directory of programs (--in), found none");
  }
  if (options.jobs < 1) throw calib::InputError("--jobs: expected at least 1, found " + std::to_string(options.jobs));
  if (fs::exists(out_dir, ec) && !fs::is_directory(out_dir, ec))
    throw calib::InputError(out_dir + ": expected an output directory (--out), found a file");
  // --out and its directories are created as the programs are written: an --out that cannot be
  // created (under a file, in a directory that is not writable, a link to nowhere) would fail
  // every program, one by one, after its work (exit 2). Refused before any work, as an --out
  // that is a file is. An --out that exists is not judged as a whole: the programs go into its
  // subdirectories, which may be writable where it is not (each failure is the file's own).
  const fs::file_status out_status = fs::status(out_dir, ec);
  // (a status that cannot be read, a loop of links: said by the resolution below)
  if (!fs::exists(out_status) && (!ec || ec == std::errc::no_such_file_or_directory || ec == std::errc::not_a_directory)) {
    if (fs::is_symlink(fs::symlink_status(out_dir, ec)))
      throw calib::InputError(out_dir + ": cannot create the output directory (--out): it is a symbolic link to " +
                              fs::read_symlink(out_dir, ec).string() + ", which does not exist");
    fs::path existing = fs::path(out_dir).parent_path();
    while (!existing.empty() && !fs::exists(existing, ec)) existing = existing.parent_path();
    const std::string problem = calib::directoryWriteProblem(existing.string());
    if (!problem.empty()) throw calib::InputError(out_dir + ": cannot create the output directory (--out): " + problem);
  }
  const fs::path in_abs = fs::weakly_canonical(fs::absolute(in_dir), ec);
  if (ec) throw calib::InputError(in_dir + ": cannot resolve the input directory (--in): " + ec.message());
  const fs::path out_abs = fs::weakly_canonical(fs::absolute(out_dir), ec);
  if (ec) throw calib::InputError(out_dir + ": cannot resolve the output directory (--out): " + ec.message());
  if (inside(out_abs, in_abs))
    throw calib::InputError(out_dir + ": the output directory is inside the input tree " + in_dir + ", which is never modified: choose another --out");
  if (inside(in_abs, out_abs))
    throw calib::InputError(out_dir + ": the output directory contains the input tree " + in_dir + ": choose another --out");
  std::vector<TreeProblem> problems;
  const std::vector<std::string> files = findPrograms(in_dir, &problems);
  BatchResult result;
  result.files.resize(files.size());
  // Two programs whose outputs would be one file (SEAM.SRC and seam.src sharing seam.dat: the
  // .dat is found case-insensitively) would overwrite each other, the result depending on which
  // thread came last: both fail, named, before any work (the same for any --jobs).
  std::vector<bool> collides(files.size(), false);
  std::vector<std::vector<std::string>> predicted(files.size());  // each program's output paths
  {
    std::map<std::string, size_t> owner;  // predicted output path -> the first program
    for (size_t i = 0; i < files.size(); ++i) {
      const fs::path in_path = fs::path(in_dir) / files[i];
      const fs::path out_path = fs::path(out_dir) / files[i];
      std::vector<std::string> outs = {out_path.lexically_normal().string()};
      if (programFormat(in_path.string()) == ProgramFormat::kKrl) {
        const std::string dat = krlDatPath(in_path.string());
        if (!dat.empty()) outs.push_back((out_path.parent_path() / fs::path(dat).filename()).lexically_normal().string());
      }
      predicted[i] = outs;
      for (const std::string& o : outs) {
        const auto [it, fresh] = owner.emplace(o, i);
        if (fresh || it->second == i) continue;
        for (const size_t k : {it->second, i}) {
          collides[k] = true;
          BatchFileResult& r = result.files[k];
          r.input = files[k];
          r.status = BatchFileResult::Status::kFailed;
          r.message = "its output " + o + " would also be the output of " + files[k == i ? it->second : i] +
                      ": neither is written (rename one of them)";
        }
      }
    }
  }
  std::atomic<size_t> next{0};
  std::mutex mutex;
  int done = 0;
  ProgramReadOptions read;
  // the RAPID modules given with --config serve the RAPID modules of the tree, the $config.dat
  // the KRL and XML programs (one: KUKA's controller has one)
  std::vector<std::string> rapid_configs, kuka_configs;
  for (const std::string& c : configPaths(ProgramReadOptions{"", options.config_path, options.more_config_paths, {}}))
    (isRapidModulePath(c) ? rapid_configs : kuka_configs).push_back(c);
  if (kuka_configs.size() > 1)
    throw calib::InputError("--config: one $config.dat for the KRL and XML programs of the tree (the controller has one, KRC:\\R1\\System\\$config.dat), found " +
                            kuka_configs[0] + " and " + kuka_configs[1]);
  // the GLOBAL points of each KRL program's data list: another program of the batch that uses
  // one is told where it is declared (a data list that cannot be read is its own program's error)
  // (a program's own points are found in its own files first; the first declaration in sorted
  // order stands for a name declared twice)
  for (const std::string& file : files) {
    const std::string in_path = (fs::path(in_dir) / file).string();
    if (programFormat(in_path) != ProgramFormat::kKrl) continue;
    const std::string dat = krlDatPath(in_path);
    if (dat.empty()) continue;
    try {
      const std::map<std::string, SourceLocation> g = krlGlobalPoints(dat);
      read.other_globals.insert(g.begin(), g.end());
    } catch (const std::exception&) {
    }
  }
  // the cell's geometry (the BVHs of its meshes) built once for every program and thread
  std::optional<CellCheckSettings> cell = options.cell;
  if (cell && !cell->geometry) {
    try {
      cell->geometry = std::make_shared<const CellGeometry>(cell->cell, options.job.calibrated);
    } catch (const calib::ArgumentError& e) {
      throw calib::InputError(e.what());
    }
  }

  auto work = [&]() {
    for (;;) {
      if (calib::interruptRequested()) return;
      const size_t i = next.fetch_add(1);
      if (i >= files.size()) return;
      BatchFileResult& r = result.files[i];
      if (collides[i]) {
        std::lock_guard<std::mutex> lock(mutex);
        ++done;
        if (progress) progress(r, done, static_cast<int>(files.size()));
        continue;
      }
      r.input = files[i];
      const fs::path in_path = fs::path(in_dir) / files[i];
      const fs::path out_path = fs::path(out_dir) / files[i];
      std::error_code ec_dir;
      try {
        if (lower(in_path.extension().string()) == ".xml" && !isXmlProgram(in_path.string())) {
          r.status = BatchFileResult::Status::kSkipped;
          r.message = "not an XML program (its root element is not <program>)";
        } else {
          // $config.dat holds KUKA's frames: it serves the KRL and XML programs of a mixed tree; a
          // URScript program in the same tree carries its own TCP (set_tcp) and base. A RAPID
          // module given as --config (the task's tooldata and wobjdata) serves the RAPID modules.
          ProgramReadOptions file_read = read;
          const ProgramFormat format = programFormat(in_path.string());
          if (format == ProgramFormat::kRapid) setConfigPaths(file_read, rapid_configs);
          else if (format == ProgramFormat::kKrl || format == ProgramFormat::kXml) setConfigPaths(file_read, kuka_configs);
          if (format != ProgramFormat::kKrl) file_read.other_globals.clear();
          CheckedProgram out = compensateAndCheckFile(in_path.string(), out_path.string(), file_read, options.job,
                                                      cell ? &*cell : nullptr, &r.report);
          r.check = std::move(out.check);
          if (r.check && !r.check->passed()) r.message = "failed the checks of " + cell->cell.file + ": " + firstCheckProblem(*r.check);
          if (!out.compensation_error.empty()) r.message += "; it cannot be compensated either: " + out.compensation_error;
          if (out.write) {
            // --out is outside the input tree, but a directory under it may be a symbolic link
            // back into the tree (a copy made with links, a link left by hand): writing through
            // it would replace the input programs
            const fs::path real_dir = fs::weakly_canonical(fs::absolute(out_path.parent_path()), ec_dir);
            if (!ec_dir && inside(real_dir, in_abs))
              throw calib::InputError(out_path.parent_path().string() + ": the output directory is " + real_dir.string() +
                                      " (through a symbolic link), inside the input tree " + in_dir +
                                      ", which is never modified: not written");
            calib::createDirectories(out_path.parent_path().string());
            calib::writeFilesAtomically(out.files);
            for (const auto& f : out.files) r.outputs.push_back(relativeSlash(fs::relative(f.path, out_dir)));
            r.status = BatchFileResult::Status::kConverted;
          } else {
            r.status = BatchFileResult::Status::kFailed;
          }
        }
      } catch (const std::exception& e) {
        r.status = BatchFileResult::Status::kFailed;
        r.message = e.what();
      }
      std::lock_guard<std::mutex> lock(mutex);
      ++done;
      if (progress) progress(r, done, static_cast<int>(files.size()));
    }
  };
  const int n = std::max(1, std::min<int>(options.jobs, static_cast<int>(std::max<size_t>(1, files.size()))));
  std::vector<std::thread> threads;
  for (int t = 1; t < n; ++t) threads.emplace_back(work);
  work();
  for (auto& t : threads) t.join();
  // interrupted: the programs no worker took (a colliding pair failed before any work)
  result.interrupted = calib::interruptRequested();
  for (size_t i = 0; i < files.size(); ++i) {
    BatchFileResult& r = result.files[i];
    if (!r.input.empty()) continue;
    r.input = files[i];
    r.status = BatchFileResult::Status::kNotStarted;
    r.message = "not compensated: the run was interrupted before it";
  }
  // a program not written this time whose output path holds a file (an earlier run's output
  // into the same --out): that file is not this run's result, and the tree must not pass it off
  // as one
  for (size_t i = 0; i < files.size(); ++i) {
    BatchFileResult& r = result.files[i];
    if (r.status != BatchFileResult::Status::kFailed && r.status != BatchFileResult::Status::kNotStarted) continue;
    std::string stale;
    for (const std::string& o : predicted[i])
      if (fs::exists(fs::symlink_status(o, ec))) stale += (stale.empty() ? "" : ", ") + o;
    if (!stale.empty())
      r.message += "; not written, but " + stale + " exist" + (stale.find(", ") == std::string::npos ? "s" : "") +
                   " from an earlier run: not this run's output (remove or replace it)";
  }
  result.programs = static_cast<int>(files.size());
  // what the tree holds but no program was read from: said, not silently left out
  for (const TreeProblem& p : problems) {
    BatchFileResult r;
    r.input = p.path;
    r.status = p.failed ? BatchFileResult::Status::kFailed : BatchFileResult::Status::kSkipped;
    r.message = p.message;
    result.files.push_back(std::move(r));
  }
  for (const auto& r : result.files) {
    if (r.status == BatchFileResult::Status::kConverted) ++result.converted;
    else if (r.status == BatchFileResult::Status::kSkipped) ++result.skipped;
    else if (r.status == BatchFileResult::Status::kNotStarted) ++result.not_started;
    else ++result.failed;
  }
  return result;
}

}  // namespace accura::postproc
