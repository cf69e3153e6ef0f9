// accura convert: a program from KRL to the XML program format and back (formats by extension).
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "accura/calib/json_text.h"
#include "accura/postproc/batch.h"
#include "accura/postproc/program_io.h"
#include "accura/postproc/urscript.h"
#include "cli_util.h"
#include "commands.h"

namespace fs = std::filesystem;

namespace accura::cli {
namespace {

struct ConvertArgs {
  std::string in;
  std::string dat;
  std::vector<std::string> config;  // --config, once or more (RAPID: the task's other modules)
  std::string out;
  std::string json;
  bool drop = false;
};

int runConvert(const ConvertArgs& a) {
  using namespace postproc;
  const ProgramFormat out_format = programFormat(a.out);
  ProgramReadOptions read;
  read.dat_path = a.dat;
  setConfigPaths(read, a.config);
  const Program read_program = readProgram(a.in, read);
  std::vector<PassThrough> dropped;
  const Program program = a.drop ? dropUnconvertible(read_program, out_format, &dropped) : read_program;
  // a KRL output: the .dat next to the .src, named like it
  const std::vector<calib::OutputFile> files = renderProgram(program, out_format, a.out);
  std::vector<std::string> inputs = {a.in};
  if (program.krl && !program.krl->dat_path.empty()) inputs.push_back(program.krl->dat_path);
  inputs.insert(inputs.end(), a.config.begin(), a.config.end());
  calib::refuseToOverwrite(files, inputs, "--out");
  std::string json_text;
  if (!a.json.empty()) {
    calib::refuseToOverwrite({{a.json, ""}}, inputs, "--json");
    nlohmann::ordered_json j;
    j["in"] = a.in;
    j["inputs"] = inputs;
    j["motions"] = program.motions.size();
    nlohmann::ordered_json outputs = nlohmann::ordered_json::array();
    for (const auto& f : files) outputs.push_back(f.path);
    j["outputs"] = outputs;
    if (a.drop) {
      nlohmann::ordered_json d = nlohmann::ordered_json::array();
      for (const PassThrough& s : dropped) d.push_back({{"file", s.where.file}, {"line", s.where.line}, {"text", s.text}});
      j["dropped"] = d;
    }
    json_text = calib::jsonText(j);
  }
  calib::installInterruptCleanup();
  // like compensate: the output's directory is created
  const fs::path dir = fs::path(a.out).parent_path();
  if (!dir.empty()) calib::createDirectories(dir.string());
  std::vector<calib::OutputFile> all = files;
  if (!a.json.empty()) all.push_back({a.json, json_text});
  calib::writeFilesAtomically(all);
  for (const PassThrough& s : dropped) std::cerr << s.where.str() << ": dropped '" << s.text << "'\n";
  for (const auto& f : all) std::cout << "wrote " << f.path << "\n";
  std::cout << "accura convert: " << program.motions.size() << " motions";
  if (out_format != ProgramFormat::kKrl || !program.krl) {
    // a URScript program keeps its other statements in its source (UrScriptSource::others),
    // not in passthrough, until a conversion carries them
    const size_t carried = program.urscript ? program.urscript->others.size()
                                            : static_cast<size_t>(std::count_if(program.passthrough.begin(), program.passthrough.end(),
                                                                                [](const PassThrough& s) { return s.role.empty(); }));
    std::cout << ", " << carried << " other statements carried verbatim";
  }
  if (a.drop) std::cout << ", " << dropped.size() << " dropped";
  std::cout << " from " << a.in << "\n";
  return 0;
}

}  // namespace

void addConvertCommand(CLI::App& app) {
  auto args = std::make_shared<ConvertArgs>();
  auto* c = app.add_subcommand("convert", "convert a program between KUKA KRL (.src/.dat), the XML program format (.xml), URScript (.script) and ABB RAPID (.mod, .modx, .sys, .sysx, .prg)");
  c->add_option("--in", args->in, "program to read: PROG.src (KRL, with PROG.dat next to it), PROG.xml, PROG.script or PROG.mod/.modx/.sys/.sysx/.prg")->required();
  c->add_option("--dat", args->dat, "the KRL .dat (default: the .src's name with .dat)");
  addConfigOption(c, args->config, "$config.dat: TOOL_DATA, BASE_DATA and global points such as XHOME; for a RAPID module: a module of its task that "
                "declares its tooldata, wobjdata or robtargets (CalibData.mod, user.sys; once per module)");
  c->add_option("--out", args->out, "program to write: OUT.xml, OUT.src (with OUT.dat), OUT.script or OUT.mod/.modx/.sys/.sysx/.prg; its directory is created")->required();
  c->add_option("--json", args->json, "report: the inputs read, the motions, the files written (and the lines dropped)");
  c->add_flag("--drop-unconvertible", args->drop,
              "keep the motions only: leave out the statements the output format cannot hold, each listed on stderr "
              "(file:line: dropped 'text') and in the --json report as \"dropped\"");
  c->callback([=]() { exitCode() = runConvert(*args); });
}

}  // namespace accura::cli
