// Compensation throughput per point through each program format (issue 12: URScript and RAPID
// within 20% of the KRL path). One motion model (a UR10 with a 150 mm torch, a home joint move,
// then 240 LIN targets on a 20 mm zig-zag, the real robot a perturbed UR10), written once as
// KRL and once as URScript; and the same on an IRB 120 (a zig-zag in its reach) written once as
// KRL and once as RAPID (declared robtargets with their confdata, ConfL\On: the confdata check
// runs). Each benchmark reads the file, compensates the program and writes it (items =
// targets). The ratios URScript / KRL and RAPID / KRL are printed at the end (same run).
//   build/bench/accura_bench_formats --benchmark_min_time=0.5
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>

#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"
#include "accura/postproc/job.h"
#include "accura/calib/ik.h"
#include "accura/postproc/program_io.h"
#include "accura/postproc/rapid.h"
#include "accura/postproc/urscript.h"

namespace {

using namespace accura;
using namespace accura::postproc;
using namespace accura::calib;

constexpr int kTargets = 240;

struct Setup {
  std::string dir, krl_path, ur_path, irb_krl_path, rapid_path;
  JobSettings settings, irb_settings;
  Setup() {
    dir = (std::filesystem::temp_directory_path() / ("accura_bench_formats_" + std::to_string(::getpid()))).string();
    std::filesystem::create_directories(dir);
    krl_path = dir + "/b.src";
    ur_path = dir + "/b.script";
    std::string krl = "DEF b( )\n$TOOL={X 0.0,Y 0.0,Z 150.0,A 0.0,B 0.0,C 0.0}\n$BASE=$NULLFRAME\n"
                      "PTP {A1 0.0,A2 -90.0,A3 90.0,A4 -90.0,A5 -90.0,A6 0.0}\n";
    std::string ur = "def b():\n  set_tcp(p[0.0, 0.0, 0.15, 0.0, 0.0, 0.0])\n  movej([0.0, -1.5707963, 1.5707963, -1.5707963, -1.5707963, 0.0])\n";
    for (int k = 0; k < kTargets; ++k) {
      const XyzAbc p{-700.0 - 20.0 * (k % 2), -350.0 + 2.5 * k, 200.0 + 0.1 * k, 90, 0, 180};  // tool z down
      krl += "LIN {X " + formatMm(p.x_mm) + ",Y " + formatMm(p.y_mm) + ",Z " + formatMm(p.z_mm) + ",A " + formatDeg(p.a_deg) +
             ",B " + formatDeg(p.b_deg) + ",C " + formatDeg(p.c_deg) + "}\n";
      ur += "  movel(" + urPoseText(p) + ", a=1.2, v=0.01)\n";
    }
    krl += "END\n";
    ur += "end\n";
    std::ofstream(krl_path, std::ios::binary) << krl;
    std::ofstream(ur_path, std::ios::binary) << ur;
    RobotModel controller = readRobotFile(std::string(ACCURA_SOURCE_DIR) + "/robots/ur10.xml");
    controller.nominal.T_flange_tcp = toIsometry({0, 0, 150, 0, 0, 0});
    SimulateOptions so;
    so.effects = {"geometric", "joint_compliance"};
    so.set_station = false;
    so.seed = 1;
    settings.calibrated = perturbModel(controller, so);
    irb120();
  }
  /// The IRB 120 pair: KRL and RAPID of one motion model.
  void irb120() {
    irb_krl_path = dir + "/irb.src";
    rapid_path = dir + "/irb.mod";
    RobotModel controller = readRobotFile(std::string(ACCURA_SOURCE_DIR) + "/robots/abb_irb120.xml");
    controller.nominal.T_flange_tcp = toIsometry({0, 0, 150, 0, 0, 0});
    std::string krl = "DEF irb( )\n$TOOL={X 0.0,Y 0.0,Z 150.0,A 0.0,B 0.0,C 0.0}\n$BASE=$NULLFRAME\nPTP {A1 -23.0,A2 17.0,A3 10.0,A4 0.0,A5 63.0,A6 157.0}\n";  // near the first target: the first LIN turns little
    // the confdata: where the nominal controller's path puts each target (a first pass with
    // ConfL\Off, which checks nothing), so that the ConfL\On module is the controller's own
    auto module = [&](const std::vector<std::array<int, 4>>& conf, const char* confl) {
      std::string decl, body;
      for (int k = 0; k < kTargets; ++k) {
        const XyzAbc p{350.0 + 20.0 * (k % 2), -150.0 + 1.25 * k, 250.0 + 0.1 * k, 0, 0, 180};  // tool z down
        const Eigen::Quaterniond r(toIsometry(p).linear());
        const std::array<int, 4>& c = conf[static_cast<size_t>(k)];
        decl += "  CONST robtarget p" + std::to_string(k) + " := [[" + formatMm(p.x_mm) + "," + formatMm(p.y_mm) + "," + formatMm(p.z_mm) +
                "],[" + formatFixed(r.w(), 9) + "," + formatFixed(r.x(), 9) + "," + formatFixed(r.y(), 9) + "," + formatFixed(r.z(), 9) +
                "],[" + std::to_string(c[0]) + "," + std::to_string(c[1]) + "," + std::to_string(c[2]) + "," + std::to_string(c[3]) +
                "],[9E9,9E9,9E9,9E9,9E9,9E9]];\n";
        body += "    MoveL p" + std::to_string(k) + ", v10, fine, torch;\n";
      }
      return "MODULE irb\n  PERS tooldata torch := [TRUE,[[0,0,150],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];\n" + decl +
             "  PROC main()\n    " + confl + "\n    MoveAbsJ [[-23,17,10,0,63,157],[9E9,9E9,9E9,9E9,9E9,9E9]], v1000, fine, torch;\n" + body +
             "  ENDPROC\nENDMODULE\n";
    };
    for (int k = 0; k < kTargets; ++k) {
      const XyzAbc p{350.0 + 20.0 * (k % 2), -150.0 + 1.25 * k, 250.0 + 0.1 * k, 0, 0, 180};
      krl += "LIN {X " + formatMm(p.x_mm) + ",Y " + formatMm(p.y_mm) + ",Z " + formatMm(p.z_mm) + ",A " + formatDeg(p.a_deg) +
             ",B " + formatDeg(p.b_deg) + ",C " + formatDeg(p.c_deg) + "}\n";
    }
    krl += "END\n";
    JobSettings nominal;
    nominal.calibrated = controller;
    const ProgramCompensation first =
        compensateProgramReport(parseRapid(module(std::vector<std::array<int, 4>>(kTargets, {0, 0, 0, 0}), "ConfL\\Off;"), "irb.mod"), nominal);
    std::vector<std::array<int, 4>> conf;
    for (const TargetReport& t : first.report.targets) conf.push_back(abbConfdata(controller, t.q_real));
    conf.resize(kTargets);
    const std::string rapid = module(conf, "ConfL\\On;");
    std::ofstream(irb_krl_path, std::ios::binary) << krl;
    std::ofstream(rapid_path, std::ios::binary) << rapid;
    SimulateOptions so;
    so.effects = {"geometric", "joint_compliance"};
    so.set_station = false;
    so.seed = 1;
    irb_settings.calibrated = perturbModel(controller, so);
  }
  ~Setup() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
};

const Setup& setup() {
  static Setup s;
  return s;
}

void run(benchmark::State& state, const std::string& path, bool irb120 = false) {
  const Setup& s = setup();
  const JobSettings& settings = irb120 ? s.irb_settings : s.settings;
  const ProgramFormat format = programFormat(path);
  long targets = 0;
  for (auto _ : state) {
    const ProgramCompensation c = compensateProgramReport(readProgram(path), settings);
    if (!c.ok()) return state.SkipWithError(c.report.errors.front().message.c_str());
    const std::vector<OutputFile> out = renderProgram(c.program, format, path + ".out");
    benchmark::DoNotOptimize(out.data());
    targets += c.report.targets_corrected;
  }
  state.SetItemsProcessed(targets);
}

void BM_Program_Krl(benchmark::State& state) { run(state, setup().krl_path); }
void BM_Program_UrScript(benchmark::State& state) { run(state, setup().ur_path); }
BENCHMARK(BM_Program_Krl)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Program_UrScript)->Unit(benchmark::kMillisecond);
void BM_Program_Krl_Irb120(benchmark::State& state) { run(state, setup().irb_krl_path, true); }
void BM_Program_Rapid_Irb120(benchmark::State& state) { run(state, setup().rapid_path, true); }
BENCHMARK(BM_Program_Krl_Irb120)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Program_Rapid_Irb120)->Unit(benchmark::kMillisecond);

/// The console output and the ratio of the per-target CPU times.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& r : runs) time_[r.benchmark_name()] = r.GetAdjustedCPUTime();
  }
  void Finalize() override {
    ConsoleReporter::Finalize();
    const double krl = time_["BM_Program_Krl"], ur = time_["BM_Program_UrScript"];
    if (krl > 0) std::printf("per target: URScript / KRL = %.3f (issue 12: <= 1.2)\n", ur / krl);
    const double krl_irb = time_["BM_Program_Krl_Irb120"], rapid = time_["BM_Program_Rapid_Irb120"];
    if (krl_irb > 0) std::printf("per target: RAPID / KRL (IRB 120) = %.3f (issue 12: <= 1.2)\n", rapid / krl_irb);
  }

 private:
  std::map<std::string, double> time_;
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  return 0;
}
