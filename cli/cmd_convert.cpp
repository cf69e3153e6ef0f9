// accura convert: a program from KRL to the XML program format and back (formats by extension).
#include <filesystem>
#include <iostream>
#include <memory>

#include "accura/calib/errors.h"
#include "accura/postproc/batch.h"
#include "accura/postproc/program_io.h"
#include "commands.h"

namespace fs = std::filesystem;

namespace accura::cli {
namespace {

struct ConvertArgs {
  std::string in;
  std::string dat;
  std::string config;
  std::string out;
};

int runConvert(const ConvertArgs& a) {
  using namespace postproc;
  const ProgramFormat out_format = programFormat(a.out);
  ProgramReadOptions read;
  read.dat_path = a.dat;
  read.config_path = a.config;
  const Program program = readProgram(a.in, read);
  // a KRL output: the .dat next to the .src, named like it
  const std::vector<calib::OutputFile> files = renderProgram(program, out_format, a.out);
  std::vector<std::string> inputs = {a.in};
  if (program.krl && !program.krl->dat_path.empty()) inputs.push_back(program.krl->dat_path);
  if (!a.config.empty()) inputs.push_back(a.config);
  calib::refuseToOverwrite(files, inputs, "--out");
  calib::installInterruptCleanup();
  calib::writeFilesAtomically(files);
  for (const auto& f : files) std::cout << "wrote " << f.path << "\n";
  std::cout << "accura convert: " << program.motions.size() << " motions from " << a.in << "\n";
  return 0;
}

}  // namespace

void addConvertCommand(CLI::App& app) {
  auto args = std::make_shared<ConvertArgs>();
  auto* c = app.add_subcommand("convert", "convert a program between KUKA KRL (.src/.dat) and the XML program format (.xml)");
  c->add_option("--in", args->in, "program to read: PROG.src (KRL, with PROG.dat next to it) or PROG.xml")->required();
  c->add_option("--dat", args->dat, "the KRL .dat (default: the .src's name with .dat)");
  c->add_option("--config", args->config, "$config.dat: TOOL_DATA, BASE_DATA and global points such as XHOME");
  c->add_option("--out", args->out, "program to write: OUT.xml, or OUT.src (with OUT.dat)")->required();
  c->callback([=]() { exitCode() = runConvert(*args); });
}

}  // namespace accura::cli
