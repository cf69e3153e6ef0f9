// Compensation throughput per point through each program format (issue 12: URScript within
// 20% of the KRL path). One motion model (a UR10 with a 150 mm torch, a home joint move, then
// 240 LIN targets on a 20 mm zig-zag, the real robot a perturbed UR10), written once as KRL
// and once as URScript; each benchmark reads the file, compensates the program and writes it
// (items = targets). The ratio URScript / KRL is printed at the end (same run, same machine).
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
#include "accura/postproc/program_io.h"
#include "accura/postproc/urscript.h"

namespace {

using namespace accura;
using namespace accura::postproc;
using namespace accura::calib;

constexpr int kTargets = 240;

struct Setup {
  std::string dir, krl_path, ur_path;
  JobSettings settings;
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

void run(benchmark::State& state, const std::string& path) {
  const Setup& s = setup();
  const ProgramFormat format = programFormat(path);
  long targets = 0;
  for (auto _ : state) {
    const ProgramCompensation c = compensateProgramReport(readProgram(path), s.settings);
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
