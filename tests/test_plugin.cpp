// The plug-in's C interface (plugin/include/accura_plugin.h, issue 6): the same numbers as the
// C++ API for the same input, the same files as `accura compensate`, error statuses and
// messages for bad input, and concurrent use of one handle from several threads.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <thread>
#include <fstream>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"
#include "accura/calib/ik.h"
#include "accura/calib/robot_io.h"
#include "accura/calib/simulate.h"
#include "accura/postproc/compensate.h"
#include "accura/postproc/job.h"
#include "accura/postproc/program_io.h"
#include "accura_plugin.h"
#include "test_util.h"

namespace accura {
namespace {

using namespace postproc;

const std::string kModel = "tests/data/plugin/kr16_calibrated.xml";
const calib::XyzAbc kTorch = {20, 0, 250, 0, -30, 0};  // the model's (calibrated) tool

accura_pose cpose(double x, double y, double z, double a, double b, double c) { return {x, y, z, a, b, c}; }
accura_pose cpose(const calib::XyzAbc& p) { return {p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg}; }
calib::XyzAbc xyz(const accura_pose& p) { return {p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg}; }

double positionDiff(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) { return (a.translation() - b.translation()).norm(); }
double angleDiffRad(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear() * b.linear().transpose()).angle();
}

std::string lastError(const accura_model* m) {
  const char* msg = nullptr;
  EXPECT_EQ(accura_last_error(m, &msg), ACCURA_OK);
  return msg ? msg : "";
}

/// A handle with the model loaded (checked).
struct Handle {
  accura_model* m = nullptr;
  explicit Handle(const std::string& model, const accura_load_options* o = nullptr) {
    EXPECT_EQ(accura_model_create(&m), ACCURA_OK);
    EXPECT_EQ(accura_model_load(m, model.c_str(), o), ACCURA_OK) << lastError(m);
  }
  Handle() { EXPECT_EQ(accura_model_create(&m), ACCURA_OK); }
  ~Handle() { accura_model_free(m); }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
};

/// Targets on the KR 16's usual working area (program base frame), each reachable with S 2.
std::vector<accura_pose> targets() {
  std::vector<accura_pose> t;
  for (int i = 0; i < 24; ++i) {
    const double f = i / 23.0;
    t.push_back(cpose(900 + 400 * f, -500 + 1000 * std::sin(3 * f), 400 + 500 * f * f, 20 * std::cos(5 * f), 150 - 40 * f,
                      -15 + 30 * f));
  }
  return t;
}

TEST(Plugin, VersionAndStatusNames) {
  int major = -1, minor = -1, patch = -1, abi = -1;
  ASSERT_EQ(accura_version(&major, &minor, &patch, &abi), ACCURA_OK);
  EXPECT_EQ(abi, ACCURA_PLUGIN_ABI_VERSION);
  EXPECT_EQ(major, 0);
  EXPECT_EQ(minor, 1);
  EXPECT_EQ(accura_version(nullptr, nullptr, nullptr, nullptr), ACCURA_OK);
  const char* name = nullptr;
  EXPECT_EQ(accura_status_name(ACCURA_ERROR_UNREACHABLE, &name), ACCURA_OK);
  EXPECT_STREQ(name, "ACCURA_ERROR_UNREACHABLE");
  EXPECT_EQ(accura_status_name(static_cast<accura_status>(99), &name), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_STREQ(name, "ACCURA_STATUS_UNKNOWN");
  EXPECT_EQ(accura_status_name(ACCURA_OK, nullptr), ACCURA_ERROR_NULL_ARGUMENT);
}

// The C call and the C++ API (Compensator, as compensateProgram sets it up) give the same
// command for the same input: a program base frame off the robot base and, once, a tool that
// is not the calibrated one.
TEST(Plugin, PosesEqualTheCppApi) {
  const calib::RobotModel calibrated = calib::readRobotFile(test::sourcePath(kModel));
  const calib::XyzAbc base = {150, -80, 30, 12, 0, 0};  // $BASE relative to $WORLD (= robot base)
  const calib::XyzAbc other_tool = {0, 0, 180, 0, 0, 0};
  for (const bool calibrated_tool : {true, false}) {
    accura_load_options o;
    ASSERT_EQ(accura_load_options_init(&o, sizeof(o)), ACCURA_OK);
    o.has_program_base = 1;
    o.program_base = cpose(base);
    o.has_program_tool = 1;
    o.program_tool = cpose(calibrated_tool ? kTorch : other_tool);
    o.payload_kg = 8;
    Handle h(test::sourcePath(kModel), &o);

    calib::RobotModel controller = calib::RobotModel::fromDefinition(calibrated.nominal);
    controller.nominal.T_flange_tcp = calib::toIsometry(calibrated_tool ? kTorch : other_tool);
    calib::RobotModel real = calibrated;
    if (!calibrated_tool) {
      real.nominal.T_flange_tcp = calib::toIsometry(other_tool);
      real.deviations.tool_mm.setZero();
      real.deviations.tool_rot_rad.setZero();
    }
    const Compensator comp(controller, real);
    calib::PoseContext context;
    context.payload_kg = 8;
    const JobSettings defaults;
    const Eigen::Isometry3d T_world_base = calib::toIsometry(base);

    const std::vector<accura_pose> t = targets();
    std::vector<accura_pose_result> r(t.size());
    size_t n_ok = 0;
    ASSERT_EQ(accura_compensate_poses(h.m, t.data(), nullptr, t.size(), 0, r.data(), &n_ok), ACCURA_OK) << lastError(h.m);
    EXPECT_EQ(n_ok, t.size());
    double max_correction = 0;
    for (size_t i = 0; i < t.size(); ++i) {
      const Eigen::Isometry3d T_world = T_world_base * calib::toIsometry(xyz(t[i]));
      const PoseCompensation pc = comp.pose(T_world, calib::Configuration{}, Eigen::VectorXd(), defaults.ik, context);
      ASSERT_EQ(pc.status, calib::IkStatus::kOk) << i;
      const Eigen::Isometry3d cmd = T_world_base * calib::toIsometry(xyz(r[i].command));
      EXPECT_LT(positionDiff(cmd, pc.T_world_tcp_command), 1e-9) << i;
      EXPECT_LT(angleDiffRad(cmd, pc.T_world_tcp_command), 1e-11) << i;
      EXPECT_NEAR(r[i].correction_mm, pc.correction_mm, 1e-9);
      EXPECT_EQ(r[i].configuration.status, pc.configuration.status);
      EXPECT_EQ(r[i].configuration.turn, pc.configuration.turn);
      for (int k = 0; k < 6; ++k) EXPECT_NEAR(r[i].q_real[k], pc.q_real[k], 1e-9);
      max_correction = std::max(max_correction, r[i].correction_mm);
      // the single call gives the same bytes as the list
      accura_pose_result one;
      ASSERT_EQ(accura_compensate_pose(h.m, &t[i], nullptr, &one), ACCURA_OK);
      EXPECT_EQ(std::memcmp(&one.command, &r[i].command, sizeof(accura_pose)), 0);
      // forward kinematics through the C interface: FK_real(q') = target, FK_controller(q') = command
      accura_pose fr, fc;
      ASSERT_EQ(accura_forward_kinematics(h.m, ACCURA_REAL, r[i].q_real, 6, &fr), ACCURA_OK);
      ASSERT_EQ(accura_forward_kinematics(h.m, ACCURA_CONTROLLER, r[i].q_real, 6, &fc), ACCURA_OK);
      EXPECT_LT(positionDiff(calib::toIsometry(xyz(fr)), calib::toIsometry(xyz(t[i]))), 1e-6);
      EXPECT_LT(positionDiff(calib::toIsometry(xyz(fc)), calib::toIsometry(xyz(r[i].command))), 1e-9);
    }
    // the KR 16's simulated errors move points by millimetres
    EXPECT_GT(max_correction, 0.5);
    EXPECT_LT(max_correction, 10);
  }
}

// A path through the C interface equals the C++ segment chain (each segment from the real
// joints where the previous one ended).
TEST(Plugin, PathEqualsTheCppApi) {
  const calib::RobotModel calibrated = calib::readRobotFile(test::sourcePath(kModel));
  Handle h(test::sourcePath(kModel));
  const accura_pose start = cpose(1100, -250, 500, 0, 180, 0);
  std::vector<accura_path_motion> motions(4);
  motions[0] = {ACCURA_LIN, {}, cpose(1100, -50, 500, 0, 180, 0)};
  motions[1] = {ACCURA_CIRC, cpose(1180, 30, 500, 0, 180, 0), cpose(1260, -50, 500, 0, 180, 0)};
  motions[2] = {ACCURA_LIN, {}, cpose(1260, -250, 500, 0, 180, 0)};
  motions[3] = {ACCURA_LIN, {}, cpose(1000, 1000, 700, 40, 120, -20)};
  const double tol_mm = 0.05;
  accura_path_result res;
  std::vector<accura_motion_report> reports(motions.size());
  ASSERT_EQ(accura_compensate_path(h.m, &start, nullptr, motions.data(), motions.size(), tol_mm, nullptr, 0, &res, reports.data()),
            ACCURA_ERROR_BUFFER_TOO_SMALL);
  std::vector<accura_path_point> points(res.n_points);
  ASSERT_EQ(accura_compensate_path(h.m, &start, nullptr, motions.data(), motions.size(), tol_mm, points.data(), points.size(), &res,
                                   reports.data()),
            ACCURA_OK)
      << lastError(h.m);

  const Compensator comp(calib::RobotModel::fromDefinition(calibrated.nominal), calibrated);
  const JobSettings job;
  DensifyOptions dens;
  dens.tol_mm = tol_mm;
  dens.ik = job.ik;
  const PoseCompensation p0 = comp.pose(calib::toIsometry(xyz(start)), calib::Configuration{}, Eigen::VectorXd(), job.ik);
  ASSERT_EQ(p0.status, calib::IkStatus::kOk);
  EXPECT_LT(positionDiff(calib::toIsometry(xyz(res.start_command)), p0.T_world_tcp_command), 1e-9);
  Eigen::VectorXd q = p0.q_real;
  size_t k = 0;
  int added = 0;
  for (size_t i = 0; i < motions.size(); ++i) {
    PathSegment s;
    s.type = motions[i].type == ACCURA_CIRC ? PathType::kCirc : PathType::kLin;
    s.T_world_start = comp.real().forward(q);
    s.T_world_aux = calib::toIsometry(xyz(motions[i].aux));
    s.T_world_end = calib::toIsometry(xyz(motions[i].end));
    const SegmentCompensation sc = comp.segment(s, calib::Configuration{}, q, dens);
    ASSERT_EQ(sc.status, calib::IkStatus::kOk) << sc.message;
    EXPECT_DOUBLE_EQ(reports[i].max_error_after_mm, sc.max_error_after_mm);
    EXPECT_DOUBLE_EQ(reports[i].max_error_uncompensated_mm, sc.max_error_uncompensated_mm);
    EXPECT_EQ(reports[i].points_added, sc.points_added);
    EXPECT_LE(sc.max_error_after_mm, tol_mm);
    for (size_t j = 0; j < sc.commanded.size(); ++j, ++k) {
      ASSERT_LT(k, points.size());
      EXPECT_EQ(points[k].motion, static_cast<int>(i));
      EXPECT_EQ(points[k].inserted, j + 1 < sc.commanded.size() ? 1 : 0);
      EXPECT_LT(positionDiff(calib::toIsometry(xyz(points[k].end)), sc.commanded[j].T_world_end), 1e-9);
      EXPECT_LT(angleDiffRad(calib::toIsometry(xyz(points[k].end)), sc.commanded[j].T_world_end), 1e-11);
      if (s.type == PathType::kCirc) {
        EXPECT_LT(positionDiff(calib::toIsometry(xyz(points[k].aux)), sc.commanded[j].T_world_aux), 1e-9);
      }
    }
    added += sc.points_added;
    q = sc.q_real_end.back();
  }
  EXPECT_EQ(k, points.size());
  EXPECT_EQ(res.points_added, added);
  EXPECT_GE(added, 3);  // the CIRC and the long LIN need points
  EXPECT_GT(res.max_error_uncompensated_mm, 0.5);
  EXPECT_LE(res.max_error_after_mm, tol_mm);
}

// An ABB module with the other modules of its task: accura_compensate_program_modules takes
// them as `accura compensate --config` given once per module does (before, the C API took one
// config_path), with the same bytes; the modules are only read.
TEST(Plugin, ProgramWithTheModulesOfItsTaskEqualsTheCommandLine) {
  const std::string g = test::sourcePath("tests/golden/rapid/");
  const std::string dir = test::tempDir("plugin_rapid_task");
  std::string module = test::readText(g + "irb120_seam.mod");
  std::string calib = "MODULE CalibData(SYSMODULE)\n", points = "MODULE Points\n";
  for (const char* head : {"  PERS tooldata torch", "  PERS wobjdata table", "  CONST robtarget p10 ", "  CONST robtarget p20 "}) {
    const size_t b = module.find(head), e = module.find('\n', b) + 1;
    ASSERT_NE(b, std::string::npos) << head;
    (std::string(head).find("robtarget") != std::string::npos ? points : calib) += module.substr(b, e - b);
    module.erase(b, e - b);
  }
  test::writeText(dir + "/seam.mod", module);
  test::writeText(dir + "/calib.sys", calib + "ENDMODULE\n");
  test::writeText(dir + "/points.mod", points + "ENDMODULE\n");
  Handle h(g + "irb120_real.xml");
  accura_program_options o;
  ASSERT_EQ(accura_program_options_init(&o, sizeof(o)), ACCURA_OK);
  const std::string calib_path = dir + "/calib.sys", points_path = dir + "/points.mod";
  const char* modules[] = {calib_path.c_str(), points_path.c_str()};
  accura_program_summary s;
  ASSERT_EQ(accura_compensate_program_modules(h.m, (dir + "/seam.mod").c_str(), (dir + "/plugin").c_str(), &o, modules, 2, &s), ACCURA_OK) << lastError(h.m);
  const test::CliRun cli = test::runAccuraIn(dir, "compensate --robot " + g + "irb120_real.xml --in seam.mod --config calib.sys --config points.mod --out cli");
  ASSERT_EQ(cli.code, 0) << cli.err;
  const std::string ours = test::readText(dir + "/plugin/seam.mod");
  EXPECT_EQ(ours, test::readText(dir + "/cli/seam.mod"));
  EXPECT_NE(ours.find("  LOCAL CONST robtarget p10_1 := [["), std::string::npos) << ours;
  EXPECT_EQ(test::readText(points_path), points + "ENDMODULE\n");
  // a NULL among the paths is an argument error, not a crash
  const char* with_null[] = {calib_path.c_str(), nullptr};
  EXPECT_EQ(accura_compensate_program_modules(h.m, (dir + "/seam.mod").c_str(), (dir + "/plugin2").c_str(), &o, with_null, 2, &s), ACCURA_ERROR_NULL_ARGUMENT);
  EXPECT_NE(std::string(lastError(h.m)).find("accura_compensate_program_modules: task_modules[1] is NULL"), std::string::npos) << lastError(h.m);
  // its errors carry its own name also without modules
  EXPECT_EQ(accura_compensate_program_modules(h.m, nullptr, (dir + "/plugin2").c_str(), &o, nullptr, 0, &s), ACCURA_ERROR_NULL_ARGUMENT);
  EXPECT_NE(std::string(lastError(h.m)).find("accura_compensate_program_modules: program_path is NULL"), std::string::npos) << lastError(h.m);
  std::filesystem::remove_all(dir);
}

// accura_compensate_program writes the same bytes as `accura compensate` with the same settings.
TEST(Plugin, ProgramEqualsTheCommandLine) {
  const std::string dir = test::tempDir("plugin_program");
  const std::string src =
      "DEF seam( )\n"
      ";FOLD comments and logic are kept\n"
      "$BASE = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n"
      "$TOOL = {X 20, Y 0, Z 250, A 0, B -30, C 0}\n"
      "PTP {X 1100, Y -250, Z 500, A 0, B 180, C 0}\n"
      "LIN {X 1100, Y -50, Z 500, A 0, B 180, C 0} C_DIS\n"
      "CIRC {X 1180, Y 30, Z 500, A 0, B 180, C 0}, {X 1260, Y -50, Z 500, A 0, B 180, C 0}\n"
      "LIN {X 1000, Y 1000, Z 700, A 40, B 120, C -20}\n"
      "END\n";
  test::writeText(dir + "/seam.src", src);
  test::writeText(dir + "/seam.dat", "DEFDAT seam\nENDDAT\n");
  Handle h(test::sourcePath(kModel));
  accura_program_options o;
  ASSERT_EQ(accura_program_options_init(&o, sizeof(o)), ACCURA_OK);
  o.tol_mm = 0.05;
  const std::string json = dir + "/report \"1\".json";  // a name JSON must escape
  o.json_report_path = json.c_str();
  accura_program_summary s;
  ASSERT_EQ(accura_compensate_program(h.m, (dir + "/seam.src").c_str(), (dir + "/plugin").c_str(), &o, &s), ACCURA_OK) << lastError(h.m);
  const test::CliRun cli = test::runAccuraIn(dir, "compensate --robot " + test::sourcePath(kModel) + " --in seam.src --out cli --tol 0.05");
  ASSERT_EQ(cli.code, 0) << cli.err;
  const std::string ours = test::readText(dir + "/plugin/seam.src");
  EXPECT_EQ(ours, test::readText(dir + "/cli/seam.src"));
  EXPECT_EQ(test::readText(dir + "/plugin/seam.dat"), test::readText(dir + "/cli/seam.dat"));
  EXPECT_EQ(std::string(s.output_path), dir + "/plugin/seam.src");
  const nlohmann::json report = nlohmann::json::parse(test::readText(json));
  EXPECT_EQ(report["totals"]["targets_corrected"].get<int>(), s.targets_corrected);
  EXPECT_EQ(report["totals"]["points_added"].get<int>(), s.points_added);
  EXPECT_NEAR(report["totals"]["max_error_after_mm"].get<double>(), s.max_error_after_mm, 0.5e-6);  // the report rounds to 1e-6 mm
  EXPECT_EQ(report["outputs"][0].get<std::string>(), dir + "/plugin/seam.src");
  EXPECT_EQ(test::readText(dir + "/seam.src"), src);  // the input is never modified
  EXPECT_GE(s.points_added, 2);
  EXPECT_LE(s.max_error_after_mm, 0.05);
  EXPECT_GT(s.max_error_uncompensated_mm, 0.5);
  EXPECT_NE(ours.find(";FOLD comments and logic are kept"), std::string::npos);
  // no temporary file is left behind
  for (const auto& e : std::filesystem::directory_iterator(dir + "/plugin"))
    EXPECT_EQ(e.path().filename().string().find(".accura-tmp"), std::string::npos) << e.path();

  // the same program as XML (accura convert): the same bytes as the command line too
  const test::CliRun conv = test::runAccuraIn(dir, "convert --in seam.src --out seam.xml");
  ASSERT_EQ(conv.code, 0) << conv.err;
  o.json_report_path = nullptr;
  ASSERT_EQ(accura_compensate_program(h.m, (dir + "/seam.xml").c_str(), (dir + "/plugin").c_str(), &o, &s), ACCURA_OK) << lastError(h.m);
  const test::CliRun cli_xml =
      test::runAccuraIn(dir, "compensate --robot " + test::sourcePath(kModel) + " --in seam.xml --out cli --tol 0.05");
  ASSERT_EQ(cli_xml.code, 0) << cli_xml.err;
  const std::string xml = test::readText(dir + "/plugin/seam.xml");
  EXPECT_EQ(xml, test::readText(dir + "/cli/seam.xml"));
  EXPECT_NE(xml.find("<program"), std::string::npos);
  EXPECT_EQ(std::string(s.output_path), dir + "/plugin/seam.xml");

  // writing onto the input is refused, and the input stays as it is
  EXPECT_EQ(accura_compensate_program(h.m, (dir + "/seam.src").c_str(), dir.c_str(), &o, &s), ACCURA_ERROR_INPUT);
  EXPECT_NE(lastError(h.m).find("overwrite"), std::string::npos) << lastError(h.m);
  EXPECT_EQ(test::readText(dir + "/seam.src"), src);
  // a malformed program: its file and line in the message
  test::writeText(dir + "/bad.src", "DEF bad( )\nLIN {X 1100, Y -50, Z }\nEND\n");
  EXPECT_EQ(accura_compensate_program(h.m, (dir + "/bad.src").c_str(), (dir + "/plugin").c_str(), &o, &s), ACCURA_ERROR_INPUT);
  EXPECT_NE(lastError(h.m).find("bad.src:2"), std::string::npos) << lastError(h.m);
  EXPECT_FALSE(std::filesystem::exists(dir + "/plugin/bad.src"));
  // a report path on the model the handle loaded, or on the program's own output: refused,
  // nothing written (before: the report replaced the model file; on the output, a report
  // was left as seam.src)
  const std::string model_copy = dir + "/model.xml", model_text = test::readText(test::sourcePath(kModel));
  test::writeText(model_copy, model_text);
  Handle h2(model_copy);
  o.json_report_path = model_copy.c_str();
  EXPECT_EQ(accura_compensate_program(h2.m, (dir + "/seam.src").c_str(), (dir + "/plugin2").c_str(), &o, &s), ACCURA_ERROR_INPUT);
  EXPECT_NE(lastError(h2.m).find("would overwrite the input"), std::string::npos) << lastError(h2.m);
  EXPECT_EQ(test::readText(model_copy), model_text);
  const std::string own = dir + "/plugin3/seam.src";
  o.json_report_path = own.c_str();
  EXPECT_EQ(accura_compensate_program(h2.m, (dir + "/seam.src").c_str(), (dir + "/plugin3").c_str(), &o, &s), ACCURA_ERROR_INPUT);
  EXPECT_FALSE(std::filesystem::exists(own));
}

// The plug-in's report (json_report_path) is the report of `accura compensate --json`, byte
// for byte, on the test programs: the golden seam with its $config.dat, the seam above and its
// XML form (the same paths given to both, so that every file name in the reports agrees).
TEST(Plugin, ReportEqualsTheCommandsByteForByte) {
  const std::string dir = test::tempDir("plugin_report");
  const std::string golden = test::sourcePath("tests/golden/compensate/");
  for (const char* f : {"seam.src", "seam.dat", "$config.dat"}) test::writeText(dir + "/" + f, test::readText(golden + f));
  test::writeText(dir + "/arc.src",
                  "DEF arc( )\n$BASE = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n$TOOL = {X 20, Y 0, Z 250, A 0, B -30, C 0}\n"
                  "PTP {X 1100, Y -250, Z 500, A 0, B 180, C 0}\nLIN {X 1100, Y -50, Z 500, A 0, B 180, C 0} C_DIS\n"
                  "CIRC {X 1180, Y 30, Z 500, A 0, B 180, C 0}, {X 1260, Y -50, Z 500, A 0, B 180, C 0}\nEND\n");
  test::writeText(dir + "/arc.dat", "DEFDAT arc\nENDDAT\n");
  ASSERT_EQ(test::runAccuraIn(dir, "convert --in arc.src --out arc.xml").code, 0);
  struct Case {
    std::string model, program, config;
    double tol_mm;
  };
  const std::vector<Case> cases = {{golden + "kr16_real.xml", "seam.src", "$config.dat", 0.02},
                                   {test::sourcePath(kModel), "arc.src", "", 0.05},
                                   {test::sourcePath(kModel), "arc.xml", "", 0.05}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.program);
    Handle h(c.model);
    accura_program_options o;
    ASSERT_EQ(accura_program_options_init(&o, sizeof(o)), ACCURA_OK);
    o.tol_mm = c.tol_mm;
    const std::string config = dir + "/" + c.config, plugin_json = dir + "/plugin.json", cli_json = dir + "/cli.json";
    if (!c.config.empty()) o.config_path = config.c_str();
    o.json_report_path = plugin_json.c_str();
    const std::string in = dir + "/" + c.program, out = dir + "/out";
    accura_program_summary s;
    ASSERT_EQ(accura_compensate_program(h.m, in.c_str(), out.c_str(), &o, &s), ACCURA_OK) << lastError(h.m);
    const test::CliRun cli = test::runAccuraIn(dir, "compensate --robot '" + c.model + "' --in '" + in + "' --out '" + out + "' --tol " +
                                                        std::to_string(c.tol_mm) + (c.config.empty() ? "" : " --config '" + config + "'") +
                                                        " --json '" + cli_json + "'");
    ASSERT_EQ(cli.code, 0) << cli.err;
    const std::string ours = test::readText(plugin_json), theirs = test::readText(cli_json);
    EXPECT_EQ(ours, theirs);
    // and it is the report the command documents: segments a list of objects, totals
    const nlohmann::json j = nlohmann::json::parse(ours);
    ASSERT_TRUE(j["segments"].is_array());
    EXPECT_EQ(j["segments"].size(), j["totals"]["segments"].get<size_t>());
    EXPECT_EQ(j["totals"]["targets_corrected"].get<int>(), s.targets_corrected);
    EXPECT_EQ(j["totals"]["points_added"].get<int>(), s.points_added);
    EXPECT_GE(j["segments"].size(), 1u);
  }
  std::filesystem::remove_all(dir);
}

// accura_model_get_joints gives the robot file's joints (read independently here).
TEST(Plugin, JointsAreTheRobotFiles) {
  Handle h(test::sourcePath(kModel));
  const calib::RobotModel robot = calib::readRobotFile(test::sourcePath(kModel));
  accura_joint j[ACCURA_MAX_JOINTS];
  size_t n = 0;
  ASSERT_EQ(accura_model_get_joints(h.m, j, ACCURA_MAX_JOINTS, &n), ACCURA_OK) << lastError(h.m);
  ASSERT_EQ(n, 6u);
  for (size_t i = 0; i < n; ++i) {
    const calib::JointSpec& e = robot.nominal.joints[i];
    EXPECT_EQ(j[i].prismatic, 0);
    EXPECT_EQ(j[i].a_mm, e.a_mm);
    EXPECT_EQ(j[i].alpha_deg, e.alpha_deg);
    EXPECT_EQ(j[i].d_mm, e.d_mm);
    EXPECT_EQ(j[i].theta0_deg, e.theta0_deg);
    EXPECT_EQ(j[i].direction, e.direction);
    EXPECT_EQ(j[i].lower, e.lower);
    EXPECT_EQ(j[i].upper, e.upper);
  }
  EXPECT_EQ(accura_model_get_joints(h.m, j, 5, &n), ACCURA_ERROR_BUFFER_TOO_SMALL);
  EXPECT_EQ(n, 6u);
}

// accura_write_program writes URScript (.script) and ABB RAPID (.mod, .prg) too, as the
// header says; their first comment names the plug-in, not accura convert (which did not write
// them). Read back by accura's readers: the same motions.
TEST(Plugin, WrittenUrScriptAndRapidNameThePlugin) {
  const std::string dir = test::tempDir("plugin_write_langs");
  Handle h;
  const accura_program_motion motions[3] = {{ACCURA_PTP, {}, cpose(1100, -250, 500, 0, 180, 0), 0, 0.0, 0, {}},
                                            {ACCURA_LIN, {}, cpose(1100, -50, 500, 0, 180, 0), 0, 0.2, 0, {}},
                                            {ACCURA_CIRC, cpose(1180, 30, 500, 0, 180, 0), cpose(1260, -50, 500, 0, 180, 0), 0, 0.1, 0, {}}};
  accura_write_options o;
  ASSERT_EQ(accura_write_options_init(&o, sizeof(o)), ACCURA_OK);
  o.tool = cpose(20, 0, 250, 0, 0, 0);
  const std::vector<std::pair<std::string, std::string>> files = {
      {"seam.script", "  # written by the accura plug-in (accura_write_program): poses in the Base frame"},
      {"seam.mod", "  ! written by the accura plug-in (accura_write_program): targets in the work object"},
      {"seam.PRG", "  ! written by the accura plug-in (accura_write_program): targets in the work object"}};
  for (const auto& [name, comment] : files) {
    SCOPED_TRACE(name);
    ASSERT_EQ(accura_write_program(h.m, (dir + "/" + name).c_str(), motions, 3, &o), ACCURA_OK) << lastError(h.m);
    const std::string text = test::readText(dir + "/" + name);
    const size_t second = text.find('\n') + 1;
    EXPECT_EQ(text.substr(second, comment.size()), comment) << text;
    EXPECT_EQ(text.find("accura convert"), std::string::npos) << text;
    const Program p = readProgram(dir + "/" + name);
    ASSERT_EQ(p.motions.size(), 3u);
    EXPECT_EQ(p.motions[0].type, MotionType::kPtp);
    EXPECT_EQ(p.motions[1].type, MotionType::kLin);
    EXPECT_EQ(p.motions[2].type, MotionType::kCirc);
    EXPECT_NEAR(p.motions[2].target.xyzAbc().x_mm, 1260, 1e-3);
  }
  std::filesystem::remove_all(dir);
}

// accura_write_program writes a new program with accura's writer: read back by accura's
// readers, every value at the writer's resolution (1e-4 mm, 1e-5 deg), in KRL and XML.
TEST(Plugin, WrittenProgramReadsBack) {
  const std::string dir = test::tempDir("plugin_write");
  Handle h;  // no model needed
  const accura_pose p1 = cpose(1100, -250, 500, 0, 180, 0), p2 = cpose(1100, -50, 500.123456, 0.1234567, 179.5, 0);
  const accura_pose aux = cpose(1180, 30, 500, 0, 180, 0), end = cpose(1260, -50, 500, 0, 180, 0);
  const accura_program_motion motions[3] = {
      {ACCURA_PTP, {}, p1, 1, 0.0, 0, {}}, {ACCURA_LIN, {}, p2, 0, 0.2, 0, {}}, {ACCURA_CIRC, aux, end, 1, 0.1, 0, {}}};
  accura_write_options o;
  ASSERT_EQ(accura_write_options_init(&o, sizeof(o)), ACCURA_OK);
  o.tool = cpose(20, 0, 250, 0, -30, 0);
  o.base = cpose(10, 20, 30, 0, 0, 90);
  for (const std::string name : {"/sub/seam.src", "/seam.xml"}) {
    SCOPED_TRACE(name);
    ASSERT_EQ(accura_write_program(h.m, (dir + name).c_str(), motions, 3, &o), ACCURA_OK) << lastError(h.m);
    const Program p = readProgram(dir + name);
    ASSERT_EQ(p.motions.size(), 3u);
    EXPECT_EQ(p.name, "seam");
    const MotionType types[3] = {MotionType::kPtp, MotionType::kLin, MotionType::kCirc};
    const accura_pose ends[3] = {p1, p2, end};
    for (int k = 0; k < 3; ++k) {
      const Motion& m = p.motions[k];
      EXPECT_EQ(m.type, types[k]);
      const calib::XyzAbc e = m.target.xyzAbc();
      EXPECT_NEAR(e.x_mm, ends[k].x_mm, 0.5e-4);
      EXPECT_NEAR(e.z_mm, ends[k].z_mm, 0.5e-4);
      EXPECT_NEAR(e.a_deg, ends[k].a_deg, 0.5e-5);
      EXPECT_NEAR(e.b_deg, ends[k].b_deg, 0.5e-5);
      ASSERT_TRUE(m.tool.known());
      EXPECT_EQ(m.tool.value->z_mm, 250);
      EXPECT_EQ(m.tool.value->b_deg, -30);
      ASSERT_TRUE(m.base.known());
      EXPECT_EQ(m.base.value->c_deg, 90);
    }
    EXPECT_EQ(p.motions[0].approximation, std::vector<Approximation>{Approximation::kCPtp});
    EXPECT_TRUE(p.motions[1].approximation.empty());
    EXPECT_EQ(p.motions[2].approximation, std::vector<Approximation>{Approximation::kCDis});
    ASSERT_TRUE(p.motions[1].vel_m_s && p.motions[2].vel_m_s);
    EXPECT_DOUBLE_EQ(*p.motions[1].vel_m_s, 0.2);
    EXPECT_DOUBLE_EQ(*p.motions[2].vel_m_s, 0.1);
    ASSERT_TRUE(p.motions[2].aux.has_value());
    EXPECT_NEAR(p.motions[2].aux->xyzAbc().y_mm, 30, 0.5e-4);
  }
  EXPECT_TRUE(std::filesystem::exists(dir + "/sub/seam.dat"));
  // bad input: a motion type, a pose, an extension
  accura_program_motion bad[1] = {{7, {}, p1, 0, 0.0, 0, {}}};
  EXPECT_EQ(accura_write_program(h.m, (dir + "/bad.src").c_str(), bad, 1, &o), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(lastError(h.m).find("motions[0].type"), std::string::npos) << lastError(h.m);
  bad[0] = {ACCURA_LIN, {}, cpose(NAN, 0, 0, 0, 0, 0), 0, 0.0, 0, {}};
  EXPECT_EQ(accura_write_program(h.m, (dir + "/bad.src").c_str(), bad, 1, &o), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(accura_write_program(h.m, (dir + "/bad.txt").c_str(), motions, 3, &o), ACCURA_ERROR_INPUT);
  EXPECT_FALSE(std::filesystem::exists(dir + "/bad.src"));
  // accura_write_file: the bytes given, no temporary file left
  const std::string text = std::string("a,b\n") + '\0' + "c\n";
  ASSERT_EQ(accura_write_file(h.m, (dir + "/t/table.csv").c_str(), text.data(), text.size()), ACCURA_OK) << lastError(h.m);
  EXPECT_EQ(test::readText(dir + "/t/table.csv"), text);
  for (const auto& e : std::filesystem::directory_iterator(dir + "/t")) EXPECT_EQ(e.path().filename().string(), "table.csv");
  std::filesystem::remove_all(dir);
}

// Issue 17: a PTP written with the arm's joint values carries their configuration (KRL and
// XML: S and T). The expected values are KUKA's: HOME {0, -90, 90, 0, 0, 0} is S 2 (B010), T 2
// (A2 < 0); {10, -60, 80, 20, -45, 30} adds A5 < 0 (S bit 2, T bit 4): S 6, T 18.
TEST(Plugin, PtpCarriesTheConfigurationOfTheArmsJoints) {
  const std::string dir = test::tempDir("plugin_ptp_st");
  accura_load_options lo;
  ASSERT_EQ(accura_load_options_init(&lo, sizeof(lo)), ACCURA_OK);
  lo.has_program_tool = 1;
  lo.program_tool = cpose(kTorch);
  Handle h(test::sourcePath(kModel), &lo);
  const double home[6] = {0, -90, 90, 0, 0, 0}, flip[6] = {10, -60, 80, 20, -45, 30};
  accura_configuration c;
  ASSERT_EQ(accura_joint_configuration(h.m, home, 6, &c), ACCURA_OK) << lastError(h.m);
  EXPECT_EQ(c.status, 2);
  EXPECT_EQ(c.turn, 2);
  ASSERT_EQ(accura_joint_configuration(h.m, flip, 6, &c), ACCURA_OK) << lastError(h.m);
  EXPECT_EQ(c.status, 6);
  EXPECT_EQ(c.turn, 18);
  EXPECT_EQ(accura_joint_configuration(h.m, flip, 5, &c), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(lastError(h.m), "accura_joint_configuration: expected 6 joint values, got 5");

  accura_pose p_home, p_flip;
  ASSERT_EQ(accura_forward_kinematics(h.m, ACCURA_CONTROLLER, home, 6, &p_home), ACCURA_OK);
  ASSERT_EQ(accura_forward_kinematics(h.m, ACCURA_CONTROLLER, flip, 6, &p_flip), ACCURA_OK);
  accura_program_motion m[3] = {{ACCURA_PTP, {}, p_home, 0, 0.0, 6, {}}, {ACCURA_PTP, {}, p_flip, 0, 0.0, 6, {}},
                                {ACCURA_LIN, {}, p_home, 0, 0.1, 6, {}}};
  std::copy(home, home + 6, m[0].joints);
  std::copy(flip, flip + 6, m[1].joints);
  std::copy(flip, flip + 6, m[2].joints);  // a LIN keeps the configuration it starts in: not used
  accura_write_options o;
  ASSERT_EQ(accura_write_options_init(&o, sizeof(o)), ACCURA_OK);
  o.tool = cpose(kTorch);
  for (const std::string name : {"/ptp.src", "/ptp.xml"}) {
    SCOPED_TRACE(name);
    ASSERT_EQ(accura_write_program(h.m, (dir + name).c_str(), m, 3, &o), ACCURA_OK) << lastError(h.m);
    const Program p = readProgram(dir + name);
    ASSERT_EQ(p.motions.size(), 3u);
    ASSERT_TRUE(p.motions[0].target.status && p.motions[0].target.turn);
    EXPECT_EQ(*p.motions[0].target.status, 2);
    EXPECT_EQ(*p.motions[0].target.turn, 2);
    ASSERT_TRUE(p.motions[1].target.status && p.motions[1].target.turn);
    EXPECT_EQ(*p.motions[1].target.status, 6);
    EXPECT_EQ(*p.motions[1].target.turn, 18);
    EXPECT_FALSE(p.motions[2].target.status || p.motions[2].target.turn);
  }
  // bad input, messages to the letter: joints of another target, a wrong count, not finite, too
  // many, no model on the handle
  m[1].end = p_home;
  const Eigen::Isometry3d a = calib::toIsometry(xyz(p_home)), b = calib::toIsometry(xyz(p_flip));
  char numbers[64];
  std::snprintf(numbers, sizeof numbers, "%.4f mm and %.4f deg", positionDiff(a, b), angleDiffRad(a, b) * 180 / M_PI);
  EXPECT_EQ(accura_write_program(h.m, (dir + "/bad.src").c_str(), m, 3, &o), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(lastError(h.m), "accura_write_program: motions[1].joints: the joint values put the tool " + std::string(numbers) +
                                " from the target (expected the arm's joints at it, within 0.01 mm and 0.01 deg)");
  m[1].end = p_flip;
  m[1].n_joints = 5;
  EXPECT_EQ(accura_write_program(h.m, (dir + "/bad.src").c_str(), m, 3, &o), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(lastError(h.m), "accura_write_program: motions[1].joints: expected 6 joint values, got 5");
  m[1].n_joints = 6;
  m[1].joints[2] = NAN;
  EXPECT_EQ(accura_write_program(h.m, (dir + "/bad.src").c_str(), m, 3, &o), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(lastError(h.m), "accura_write_program: motions[1].joints[2] is not finite");
  m[1].n_joints = ACCURA_MAX_JOINTS + 1;
  EXPECT_EQ(accura_write_program(h.m, (dir + "/bad.src").c_str(), m, 3, &o), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(lastError(h.m), "accura_write_program: motions[1].n_joints: expected 0..12, found 13");
  Handle none;
  EXPECT_EQ(accura_write_program(none.m, (dir + "/bad.src").c_str(), m, 1, &o), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(lastError(none.m), "accura_write_program: motions[0].joints: the configuration needs the robot's geometry: load a model first");
  EXPECT_FALSE(std::filesystem::exists(dir + "/bad.src"));
  std::filesystem::remove_all(dir);
}

TEST(Plugin, BadInputGivesStatusesAndMessages) {
  Handle h;
  const accura_pose t = cpose(1100, -250, 500, 0, 180, 0);
  accura_pose_result r;
  // no model yet
  EXPECT_EQ(accura_compensate_pose(h.m, &t, nullptr, &r), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(lastError(h.m).find("no model loaded"), std::string::npos);
  // missing file: the status and the path in the message
  const std::string missing = "/tmp/accura_no_such_dir/model.xml";
  EXPECT_EQ(accura_model_load(h.m, missing.c_str(), nullptr), ACCURA_ERROR_INPUT);
  EXPECT_NE(lastError(h.m).find(missing), std::string::npos) << lastError(h.m);
  // a malformed model file: file and line
  const std::string dir = test::tempDir("plugin_bad");
  test::writeText(dir + "/broken.xml", "<?xml version=\"1.0\"?>\n<robot name=\"x\">\n  <joints>\n</robot>\n");
  EXPECT_EQ(accura_model_load(h.m, (dir + "/broken.xml").c_str(), nullptr), ACCURA_ERROR_INPUT);
  EXPECT_NE(lastError(h.m).find("broken.xml:"), std::string::npos) << lastError(h.m);
  // the controller model must be the calibrated model's robot
  accura_load_options o;
  ASSERT_EQ(accura_load_options_init(&o, sizeof(o)), ACCURA_OK);
  o.controller_model = "ur10";
  EXPECT_EQ(accura_model_load(h.m, test::sourcePath(kModel).c_str(), &o), ACCURA_ERROR_INPUT);
  EXPECT_NE(lastError(h.m).find("nominal robot of the calibrated model"), std::string::npos) << lastError(h.m);
  o.controller_model = "kuka_kr16";
  EXPECT_EQ(accura_model_load(h.m, test::sourcePath(kModel).c_str(), &o), ACCURA_OK) << lastError(h.m);
  // a failed load keeps the model that was there
  EXPECT_EQ(accura_model_load(h.m, missing.c_str(), nullptr), ACCURA_ERROR_INPUT);
  EXPECT_EQ(accura_compensate_pose(h.m, &t, nullptr, &r), ACCURA_OK);
  // the calibrated base 3 m from the placement: the model was measured in another frame
  o.controller_model = nullptr;
  o.has_robroot_in_world = 1;
  o.robroot_in_world = cpose(3000, 0, 0, 0, 0, 0);
  EXPECT_EQ(accura_model_load(h.m, test::sourcePath(kModel).c_str(), &o), ACCURA_ERROR_INPUT);
  EXPECT_NE(lastError(h.m).find("robroot_in_world"), std::string::npos) << lastError(h.m);
  // wrong sizes
  EXPECT_EQ(accura_load_options_init(&o, sizeof(o) + 8), ACCURA_ERROR_INVALID_ARGUMENT);
  o.struct_size = sizeof(o) - 8;
  EXPECT_EQ(accura_model_load(h.m, test::sourcePath(kModel).c_str(), &o), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(lastError(h.m).find("struct_size"), std::string::npos);
  double q[6] = {0, -90, 90, 0, 0, 0};
  accura_pose p;
  EXPECT_EQ(accura_forward_kinematics(h.m, ACCURA_REAL, q, 5, &p), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(lastError(h.m).find("expected 6 joint values, got 5"), std::string::npos) << lastError(h.m);
  EXPECT_EQ(accura_forward_kinematics(h.m, static_cast<accura_which_model>(7), q, 6, &p), ACCURA_ERROR_INVALID_ARGUMENT);
  // NULL pointers
  EXPECT_EQ(accura_model_create(nullptr), ACCURA_ERROR_NULL_ARGUMENT);
  EXPECT_EQ(accura_compensate_pose(nullptr, &t, nullptr, &r), ACCURA_ERROR_NULL_ARGUMENT);
  EXPECT_EQ(accura_compensate_pose(h.m, nullptr, nullptr, &r), ACCURA_ERROR_NULL_ARGUMENT);
  EXPECT_EQ(accura_compensate_pose(h.m, &t, nullptr, nullptr), ACCURA_ERROR_NULL_ARGUMENT);
  EXPECT_EQ(accura_compensate_poses(h.m, nullptr, nullptr, 3, 0, &r, nullptr), ACCURA_ERROR_NULL_ARGUMENT);
  EXPECT_EQ(accura_forward_kinematics(h.m, ACCURA_REAL, nullptr, 6, &p), ACCURA_ERROR_NULL_ARGUMENT);
  EXPECT_EQ(accura_compensate_path(h.m, &t, nullptr, nullptr, 2, 0.05, nullptr, 0, nullptr, nullptr), ACCURA_ERROR_NULL_ARGUMENT);
  EXPECT_EQ(accura_compensate_program(h.m, nullptr, "/tmp", nullptr, nullptr), ACCURA_ERROR_NULL_ARGUMENT);
  EXPECT_EQ(accura_model_get_info(h.m, nullptr), ACCURA_ERROR_NULL_ARGUMENT);
  const char* msg = nullptr;
  EXPECT_EQ(accura_last_error(h.m, nullptr), ACCURA_ERROR_NULL_ARGUMENT);
  EXPECT_EQ(accura_last_error(nullptr, &msg), ACCURA_OK);  // this thread's calls without a handle
  EXPECT_STREQ(msg, "accura_compensate_pose: model is NULL");
  EXPECT_EQ(accura_model_free(nullptr), ACCURA_OK);
  // out of memory: 2^40 poses need 128 TB of workspace (std::bad_alloc inside). Not under
  // AddressSanitizer, whose operator new reports and dies where the real one throws.
  if (!test::kUnderSanitizers) {
    EXPECT_EQ(accura_compensate_poses(h.m, &t, nullptr, size_t(1) << 40, 0, &r, nullptr), ACCURA_ERROR_OUT_OF_MEMORY);
    EXPECT_NE(lastError(h.m).find("out of memory"), std::string::npos) << lastError(h.m);
  }
  // values out of range
  accura_pose nan_pose = t;
  nan_pose.y_mm = std::nan("");
  EXPECT_EQ(accura_compensate_pose(h.m, &nan_pose, nullptr, &r), ACCURA_ERROR_INVALID_ARGUMENT);
  const accura_configuration bad_config = {-3, 0};
  EXPECT_EQ(accura_compensate_pose(h.m, &t, &bad_config, &r), ACCURA_ERROR_INVALID_ARGUMENT);
  accura_path_motion lin = {ACCURA_LIN, {}, cpose(1100, -50, 500, 0, 180, 0)};
  accura_path_result pr;
  EXPECT_EQ(accura_compensate_path(h.m, &t, nullptr, &lin, 1, 0, nullptr, 0, &pr, nullptr), ACCURA_ERROR_INVALID_ARGUMENT);
  lin.type = 5;
  EXPECT_EQ(accura_compensate_path(h.m, &t, nullptr, &lin, 1, 0.05, nullptr, 0, &pr, nullptr), ACCURA_ERROR_INVALID_ARGUMENT);
  // per-pose statuses: the unreachable one fails, the others are computed
  const accura_pose list[3] = {t, cpose(5000, 0, 0, 0, 180, 0), cpose(1260, -50, 500, 0, 180, 0)};
  accura_pose_result rs[3];
  size_t n_ok = 0;
  EXPECT_EQ(accura_compensate_poses(h.m, list, nullptr, 3, 1, rs, &n_ok), ACCURA_ERROR_UNREACHABLE);
  EXPECT_EQ(n_ok, 2u);
  EXPECT_EQ(rs[0].status, ACCURA_OK);
  EXPECT_EQ(rs[1].status, ACCURA_ERROR_UNREACHABLE);
  EXPECT_EQ(rs[2].status, ACCURA_OK);
  EXPECT_NE(lastError(h.m).find("pose 1"), std::string::npos) << lastError(h.m);
}

// accura_compensate_path names the motion that fails, whatever the reason: an unreachable LIN
// and a CIRC whose auxiliary point is collinear with its start and end (or is its start) both
// set result.failed_motion and say "motion N cannot be compensated" (before: the CIRC gave
// ACCURA_ERROR_NUMERICAL with failed_motion -1 and no motion in the message).
TEST(Plugin, AFailingMotionOfAPathIsNamed) {
  Handle h(test::sourcePath(kModel));
  const accura_pose start = cpose(1100, -250, 500, 0, 180, 0);
  accura_path_motion mo[3] = {{ACCURA_LIN, {}, cpose(1100, -50, 500, 0, 180, 0)},
                              {ACCURA_CIRC, cpose(1180, 30, 500, 0, 180, 0), cpose(1260, -50, 500, 0, 180, 0)},
                              {ACCURA_LIN, {}, cpose(1260, -250, 500, 0, 180, 0)}};
  accura_path_point pts[64];
  accura_path_result pr;
  ASSERT_EQ(accura_compensate_path(h.m, &start, nullptr, mo, 3, 0.05, pts, 64, &pr, nullptr), ACCURA_OK) << lastError(h.m);
  EXPECT_EQ(pr.failed_motion, -1);
  const std::string no_circle = "accura_compensate_path: motion 1 cannot be compensated: CIRC: start, auxiliary and end point are "
                                "collinear or coincide (no circle through them)";
  for (const accura_pose aux : {cpose(1180, -50, 500, 0, 180, 0), cpose(1100, -50, 500, 0, 180, 0)}) {  // collinear; the start
    mo[1].aux = aux;
    pr.failed_motion = 7;
    EXPECT_EQ(accura_compensate_path(h.m, &start, nullptr, mo, 3, 0.05, pts, 64, &pr, nullptr), ACCURA_ERROR_NUMERICAL);
    EXPECT_EQ(pr.failed_motion, 1);
    EXPECT_EQ(lastError(h.m), no_circle);
  }
  // the first motion a CIRC through the midpoint of the start and its end: motion 0
  const accura_path_motion first = {ACCURA_CIRC, cpose(1180, -150, 500, 0, 180, 0), cpose(1260, -50, 500, 0, 180, 0)};
  EXPECT_EQ(accura_compensate_path(h.m, &start, nullptr, &first, 1, 0.05, pts, 64, &pr, nullptr), ACCURA_ERROR_NUMERICAL);
  EXPECT_EQ(pr.failed_motion, 0);
  EXPECT_EQ(lastError(h.m).rfind("accura_compensate_path: motion 0 cannot be compensated: CIRC: ", 0), 0u) << lastError(h.m);
  // the unreachable LIN, as before
  mo[1].aux = cpose(1180, 30, 500, 0, 180, 0);
  mo[2].end = cpose(4000, -250, 500, 0, 180, 0);
  EXPECT_EQ(accura_compensate_path(h.m, &start, nullptr, mo, 3, 0.05, pts, 64, &pr, nullptr), ACCURA_ERROR_UNREACHABLE);
  EXPECT_EQ(pr.failed_motion, 2);
  EXPECT_EQ(lastError(h.m).rfind("accura_compensate_path: motion 2 cannot be compensated: unreachable", 0), 0u) << lastError(h.m);
}

// Out of memory while a cell's mesh is read is ACCURA_ERROR_OUT_OF_MEMORY "out of memory", as
// docs/plugin.md promises (before: ACCURA_ERROR_INPUT "expected a mesh file assimp can read ...,
// found: std::bad_alloc", assimp catching the std::bad_alloc and keeping its text). In a child
// process whose address space is limited (RLIMIT_AS) to what it has plus 128 MB: the 40 MB STL
// is read, assimp's copy of it and its vertices do not fit. Not under AddressSanitizer (its
// shadow memory needs the address space).
TEST(Plugin, OutOfMemoryReadingAMeshIsOutOfMemory) {
  if (test::kUnderSanitizers) GTEST_SKIP() << "RLIMIT_AS and AddressSanitizer do not go together";
  const std::string dir = test::tempDir("plugin_oom_mesh");
  {
    const uint32_t n = 800000;  // 50 bytes a triangle: 40 MB
    std::string stl(84 + size_t(n) * 50, '\0');
    std::memcpy(&stl[80], &n, 4);
    for (uint32_t i = 0; i < n; ++i) {
      const float x = float(i % 1000), y = float(i / 1000);
      const float f[12] = {0, 0, 1, x, y, 0, x + 1, y, 0, x, y + 1, 0};
      std::memcpy(&stl[84 + size_t(i) * 50], f, sizeof f);
    }
    test::writeText(dir + "/big.stl", stl);
  }
  test::writeText(dir + "/cell.xml",
                  "<?xml version=\"1.0\"?>\n<cell name=\"big\">\n"
                  "  <object name=\"floor\" file=\"big.stl\" units=\"mm\" x_mm=\"3000\" y_mm=\"-2000\" z_mm=\"-700\"/>\n"
                  "  <tool><capsule x0_mm=\"0\" y0_mm=\"0\" z0_mm=\"0\" x1_mm=\"80\" y1_mm=\"40\" z1_mm=\"150\" radius_mm=\"15\"/></tool>\n"
                  "</cell>\n");
  for (const char* f : {"seam.src", "seam.dat", "$config.dat"})
    test::writeText(dir + "/" + f, test::readText(test::sourcePath(std::string("examples/") + f)));
  Handle h("kuka_kr16");
  accura_check_options o;
  ASSERT_EQ(accura_check_options_init(&o, sizeof(o)), ACCURA_OK);
  const std::string config = dir + "/$config.dat";
  o.config_path = config.c_str();
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(fds[0]);
    long vm_kb = 0;
    std::ifstream status("/proc/self/status");
    for (std::string line; std::getline(status, line);)
      if (line.rfind("VmSize:", 0) == 0) vm_kb = std::atol(line.c_str() + 7);
    const rlim_t limit = rlim_t(vm_kb) * 1024 + (rlim_t(128) << 20);
    const rlimit rl = {limit, limit};
    accura_status st = ACCURA_ERROR_INTERNAL;
    std::string text = "setrlimit failed";
    if (vm_kb > 0 && ::setrlimit(RLIMIT_AS, &rl) == 0) {
      accura_check_summary cs;
      st = accura_check_program(h.m, (dir + "/cell.xml").c_str(), (dir + "/seam.src").c_str(), &o, &cs, nullptr, 0);
      const char* msg = "";
      accura_last_error(h.m, &msg);
      text = msg;
    }
    const std::string out = std::to_string(int(st)) + " " + text;
    if (::write(fds[1], out.data(), out.size()) < 0) ::_exit(2);
    ::_exit(0);
  }
  ::close(fds[1]);
  std::string got;
  char buf[512];
  for (ssize_t k; (k = ::read(fds[0], buf, sizeof buf)) > 0;) got.append(buf, size_t(k));
  ::close(fds[0]);
  int wstatus = 0;
  ASSERT_EQ(::waitpid(child, &wstatus, 0), child);
  EXPECT_TRUE(WIFEXITED(wstatus) && WEXITSTATUS(wstatus) == 0);
  EXPECT_EQ(got, std::to_string(int(ACCURA_ERROR_OUT_OF_MEMORY)) + " accura_check_program: out of memory");
}

// The configuration asked for is enforced as accura compensate does: a target reachable only on
// another S/T is ACCURA_ERROR_NO_CONFIGURATION (never success on another arm posture); S and T
// outside their bit ranges are invalid arguments.
TEST(Plugin, TheConfigurationAskedForIsEnforced) {
  Handle h(test::sourcePath(kModel));
  // a pose of known joints: A1 30 deg, A5 45 deg, A6 60 deg (all far from 0)
  const double q[6] = {30, -80, 95, 20, 45, 60};
  accura_pose t;
  ASSERT_EQ(accura_forward_kinematics(h.m, ACCURA_REAL, q, 6, &t), ACCURA_OK) << lastError(h.m);
  accura_pose_result r;
  // its own configuration, found by asking for any: then asked exactly, it is kept
  ASSERT_EQ(accura_compensate_pose(h.m, &t, nullptr, &r), ACCURA_OK) << lastError(h.m);
  const accura_configuration own = r.configuration;
  EXPECT_EQ(own.turn & 1, 0);  // A1 positive
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(r.q_real[i], q[i], 1e-4) << i;  // deg: the same joints
  ASSERT_EQ(accura_compensate_pose(h.m, &t, &own, &r), ACCURA_OK) << lastError(h.m);
  EXPECT_EQ(r.configuration_changed, 0);
  EXPECT_EQ(r.configuration.status, own.status);
  EXPECT_EQ(r.configuration.turn, own.turn);
  // A1 negative on the same Status (T bit 0): A1 = 30 - 360 is outside +-185 deg, so no solution
  // has it; the compensation must not come back as success on A1 = 30 deg
  const accura_configuration a1_negative = {own.status, own.turn | 1};
  const accura_status s = accura_compensate_pose(h.m, &t, &a1_negative, &r);
  EXPECT_EQ(s, ACCURA_ERROR_NO_CONFIGURATION) << lastError(h.m);
  EXPECT_EQ(r.status, s);
  EXPECT_NE(lastError(h.m).find("not with the configuration asked for"), std::string::npos) << lastError(h.m);
  EXPECT_NE(lastError(h.m).find("): it differs in the sign of joint 1"), std::string::npos) << lastError(h.m);
  // in a list: that pose fails, its neighbours are computed
  const accura_pose list[2] = {t, t};
  const accura_configuration configs[2] = {own, a1_negative};
  accura_pose_result rs[2];
  size_t n_ok = 0;
  EXPECT_EQ(accura_compensate_poses(h.m, list, configs, 2, 0, rs, &n_ok), ACCURA_ERROR_NO_CONFIGURATION);
  EXPECT_EQ(n_ok, 1u);
  EXPECT_EQ(rs[0].status, ACCURA_OK);
  EXPECT_EQ(rs[1].status, ACCURA_ERROR_NO_CONFIGURATION);
  // bits beyond their range: S has three, T one per joint (six)
  for (const accura_configuration bad : {accura_configuration{8, 0}, accura_configuration{2, 64}, accura_configuration{-2, 0}}) {
    EXPECT_EQ(accura_compensate_pose(h.m, &t, &bad, &r), ACCURA_ERROR_INVALID_ARGUMENT) << bad.status << " " << bad.turn;
    EXPECT_NE(lastError(h.m).find("expected S in 0..7 and T in 0..63"), std::string::npos) << lastError(h.m);
  }
}

/// The solution of `robot` for T nearest `to` in joint space (every closed-form branch polished
/// on the robot: independent of the compensation's own solver path); empty when none converges.
Eigen::VectorXd nearestSolution(const calib::RobotModel& robot, const Eigen::Isometry3d& T, const Eigen::VectorXd& to) {
  const calib::KinematicSolver ik(robot);
  Eigen::VectorXd best;
  for (const Eigen::VectorXd& seed : ik.closedFormSolutions(T)) {
    const calib::IkResult r = ik.inverse(T, calib::kukaConfiguration(robot, seed), seed, calib::IkOptions{});
    if (r.status != calib::IkStatus::kOk) continue;
    if (best.size() == 0 || (r.q - to).norm() < (best - to).norm()) best = r.q;
  }
  return best;
}

// A UR controller reads no Status/Turn (movej(pose): the solution nearest the joints), so the
// plug-in asks none of it either, as accura compensate does (docs/compensation.md, section 2;
// UrScript.ATargetWithJointsAtZeroIsNotTurnedByItsKukaTurnBits for a program). A host (the
// FreeCAD module) passes the S/T of its arm's joints {0, -60, 80, -110, -90, 0}: T 26, joints 1
// and 6 at exactly 0 with their Turn bits clear. The real arm reaches the pose with joint 1 or
// 6 a few hundredths below 0: on the Turn bits it went a full turn round (359.97 deg, inside
// the UR's +-360 deg) and the LIN after it, turning them further up, was refused at 360 deg.
TEST(Plugin, AUrArmIsNotTurnedByTheTurnBitsOfTheHostsJoints) {
  const std::string dir = test::tempDir("plugin_ur_turn");
  calib::RobotModel controller = test::loadBundled("ur10");
  controller.nominal.T_flange_tcp = calib::toIsometry({0, 0, 150, 0, 0, 0});
  calib::SimulateOptions so;
  so.effects = {"geometric"};
  so.set_station = false;
  so.seed = 2;
  const calib::RobotModel real = calib::perturbModel(controller, so);
  calib::writeRobotFile(dir + "/ur10_calibrated.xml", real);
  Handle h(dir + "/ur10_calibrated.xml");
  const calib::RobotModel real_read = calib::readRobotFile(dir + "/ur10_calibrated.xml");  // the model the plug-in runs
  const double q_a[6] = {0, -60, 80, -110, -90, 0}, q_b[6] = {5, -60, 80, -110, -90, 5};
  const Eigen::Map<const Eigen::VectorXd> qa(q_a, 6), qb(q_b, 6);
  accura_pose p_a, p_b;
  ASSERT_EQ(accura_forward_kinematics(h.m, ACCURA_CONTROLLER, q_a, 6, &p_a), ACCURA_OK) << lastError(h.m);
  ASSERT_EQ(accura_forward_kinematics(h.m, ACCURA_CONTROLLER, q_b, 6, &p_b), ACCURA_OK) << lastError(h.m);
  const Eigen::Isometry3d T_a = calib::toIsometry(xyz(p_a)), T_b = calib::toIsometry(xyz(p_b));
  // the poses on their own: the nominal FK of the host's joints (base = world, tool = the torch)
  EXPECT_LT(positionDiff(T_a, calib::KinematicSolver(controller).forward(qa)), 1e-9);
  accura_configuration st;
  ASSERT_EQ(accura_joint_configuration(h.m, q_a, 6, &st), ACCURA_OK) << lastError(h.m);
  ASSERT_EQ(st.turn, 26);  // joints 1 and 6 at 0: bits 0 and 5 clear
  const calib::KinematicSolver real_fk(real_read);
  // the joints the UR takes for a command from where it stands, and where they put the real tool
  auto lands = [&](const accura_pose& command, const Eigen::VectorXd& from, const Eigen::Isometry3d& T, const Eigen::VectorXd& q_host,
                   const char* what) {
    SCOPED_TRACE(what);
    const Eigen::VectorXd q = nearestSolution(controller, calib::toIsometry(xyz(command)), from);
    EXPECT_EQ(q.size(), 6);
    if (q.size() != 6) return q;
    EXPECT_LT(positionDiff(real_fk.forward(q), T), 1e-3);                  // 1 um
    EXPECT_LT(angleDiffRad(real_fk.forward(q), T) * 180 / M_PI, 1e-4);  // deg
    EXPECT_LT((q - q_host).cwiseAbs().maxCoeff(), 0.5) << q.transpose();  // no joint a turn round
    return q;
  };

  // one pose: the S asked (the guess of the branch), no Turn
  accura_pose_result r;
  ASSERT_EQ(accura_compensate_pose(h.m, &p_a, &st, &r), ACCURA_OK) << lastError(h.m);
  ASSERT_EQ(r.dof, 6);
  const Eigen::Map<const Eigen::VectorXd> q_real(r.q_real, 6);
  EXPECT_LT((q_real - qa).cwiseAbs().maxCoeff(), 0.5) << q_real.transpose();
  EXPECT_TRUE(q_real[0] < 0 || q_real[5] < 0) << q_real.transpose();  // the case of the Turn bit
  const Eigen::VectorXd q_exec_a = lands(r.command, qa, T_a, qa, "pose");
  ASSERT_EQ(q_exec_a.size(), 6);
  EXPECT_LT((q_exec_a - q_real).cwiseAbs().maxCoeff(), 1e-6);  // the joints the result says
  // reported: the configuration reached (KUKA's rule on q_real), not a change asked for
  const calib::Configuration reached = calib::kukaConfiguration(controller, q_real);
  EXPECT_EQ(r.configuration.status, reached.status);
  EXPECT_EQ(r.configuration.turn, reached.turn);
  EXPECT_NE(r.configuration.turn, st.turn);
  EXPECT_EQ(r.configuration_changed, 0);

  // a list, continuous: the second from the first's joints (the solution nearest them)
  const accura_pose list[2] = {p_a, p_b};
  const accura_configuration configs[2] = {st, st};
  accura_pose_result rs[2];
  size_t n_ok = 0;
  ASSERT_EQ(accura_compensate_poses(h.m, list, configs, 2, 1, rs, &n_ok), ACCURA_OK) << lastError(h.m);
  EXPECT_EQ(n_ok, 2u);
  const Eigen::VectorXd q0 = lands(rs[0].command, qa, T_a, qa, "poses[0]");
  if (q0.size() == 6) lands(rs[1].command, q0, T_b, qb, "poses[1]");

  // a path: the start on the host's S/T, then a LIN of 5 deg on joints 1 and 6
  const accura_path_motion lin = {ACCURA_LIN, {}, p_b};
  std::vector<accura_path_point> points(64);
  accura_path_result pr;
  ASSERT_EQ(accura_compensate_path(h.m, &p_a, &st, &lin, 1, 0.05, points.data(), points.size(), &pr, nullptr), ACCURA_OK)
      << lastError(h.m);
  ASSERT_GE(pr.n_points, 1u);
  EXPECT_EQ(pr.failed_motion, -1);
  Eigen::VectorXd q = lands(pr.start_command, qa, T_a, qa, "path start");
  for (size_t i = 0; i < pr.n_points && q.size() == 6; ++i) {
    if (points[i].inserted) {  // an auxiliary point: the joints nearest the previous, on the way from q_a to q_b
      q = nearestSolution(controller, calib::toIsometry(xyz(points[i].end)), q);
      EXPECT_LT((q - qa).cwiseAbs().maxCoeff(), 5.5) << q.transpose();
    } else {
      q = lands(points[i].end, q, T_b, qb, "path end");
    }
  }
  std::filesystem::remove_all(dir);
}

// One handle, several threads at once: the results equal the single-threaded ones, and each
// thread sees its own last error.
TEST(Plugin, OneHandleFromSeveralThreads) {
  Handle h(test::sourcePath(kModel));
  const std::vector<accura_pose> t = targets();
  std::vector<accura_pose_result> reference(t.size());
  size_t n_ok = 0;
  ASSERT_EQ(accura_compensate_poses(h.m, t.data(), nullptr, t.size(), 1, reference.data(), &n_ok), ACCURA_OK);
  accura_path_motion lin = {ACCURA_LIN, {}, cpose(1000, 1000, 700, 40, 120, -20)};
  const accura_pose start = cpose(1260, -250, 500, 0, 180, 0);
  accura_path_result ref_path;
  std::vector<accura_path_point> ref_points(16);
  ASSERT_EQ(accura_compensate_path(h.m, &start, nullptr, &lin, 1, 0.05, ref_points.data(), 16, &ref_path, nullptr), ACCURA_OK);

  constexpr int kThreads = 4, kRounds = 3;
  std::atomic<int> mismatches{0}, wrong_messages{0};
  std::vector<std::thread> threads;
  for (int k = 0; k < kThreads; ++k) {
    threads.emplace_back([&, k]() {
      for (int round = 0; round < kRounds; ++round) {
        std::vector<accura_pose_result> r(t.size());
        size_t ok = 0;
        if (accura_compensate_poses(h.m, t.data(), nullptr, t.size(), 1, r.data(), &ok) != ACCURA_OK) ++mismatches;
        for (size_t i = 0; i < t.size(); ++i)
          if (std::memcmp(&r[i], &reference[i], sizeof(accura_pose_result)) != 0) ++mismatches;
        accura_path_result pr;
        std::vector<accura_path_point> pts(16);
        if (accura_compensate_path(h.m, &start, nullptr, &lin, 1, 0.05, pts.data(), 16, &pr, nullptr) != ACCURA_OK) ++mismatches;
        if (pr.n_points != ref_path.n_points || std::memcmp(pts.data(), ref_points.data(), pr.n_points * sizeof(accura_path_point)) != 0)
          ++mismatches;
        // a failure of this thread's own: x = 5000 + 100 k mm
        const accura_pose far = cpose(5000 + 100 * k, 0, 500, 0, 180, 0);
        accura_pose_result fr;
        if (accura_compensate_pose(h.m, &far, nullptr, &fr) != ACCURA_ERROR_UNREACHABLE) ++mismatches;
        const std::string mine = "X " + std::to_string(5000 + 100 * k) + ".000";
        const char* msg = nullptr;
        accura_last_error(h.m, &msg);
        if (!msg || std::string(msg).find(mine) == std::string::npos) ++wrong_messages;
      }
    });
  }
  // meanwhile the model is loaded again (the same file): calls in flight keep the model they
  // started with, later ones get the new one; the numbers are the same
  threads.emplace_back([&]() {
    for (int round = 0; round < kRounds; ++round)
      if (accura_model_load(h.m, test::sourcePath(kModel).c_str(), nullptr) != ACCURA_OK) ++mismatches;
  });
  for (auto& th : threads) th.join();
  EXPECT_EQ(mismatches.load(), 0);
  EXPECT_EQ(wrong_messages.load(), 0);
  // this thread's last error is still its own (none of the workers' messages)
  EXPECT_EQ(lastError(h.m).find("X 5"), std::string::npos) << lastError(h.m);
}

}  // namespace
}  // namespace accura

namespace accura {
namespace {

// The reach and clearance checks through the C interface: a LIN at z = 800 mm along x passes
// a 10 x 10 mm post (tests/data/cell/post_binary.stl, x, y in [-5, 5], z in [0, 600] mm) placed
// at x 1200, z 500 and y 12 (its face at y = 7 mm) or y 118 (face at 113 mm), with a sphere of
// radius 10 mm as the tool: 3 mm into the post, or 103 mm clear.
TEST(Plugin, CheckProgramInItsCell) {
  const std::string dir = test::tempDir("plugin_check");
  test::writeText(dir + "/post.stl", test::readText(test::sourcePath("tests/data/cell/post_binary.stl")));
  auto cell = [&](const std::string& name, double y_post) {
    test::writeText(dir + "/" + name,
                    "<?xml version=\"1.0\"?>\n<cell name=\"post\">\n  <thresholds min_clearance_mm=\"5\"/>\n"
                    "  <object name=\"post\" file=\"post.stl\" units=\"mm\" x_mm=\"1200\" y_mm=\"" + std::to_string(y_post) +
                        "\" z_mm=\"500\"/>\n"
                        "  <tool><capsule x0_mm=\"0\" y0_mm=\"0\" z0_mm=\"0\" x1_mm=\"0\" y1_mm=\"0\" z1_mm=\"0\" radius_mm=\"10\"/></tool>\n"
                        "</cell>\n");
  };
  cell("near.xml", 12);
  cell("far.xml", 118);
  test::writeText(dir + "/seam.src",
                  "DEF seam( )\n$TOOL = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n$BASE = {X 0, Y 0, Z 0, A 0, B 0, C 0}\n"
                  "PTP {X 900, Y 0, Z 800, A 0, B 90, C 0}\nLIN {X 1500, Y 0, Z 800, A 0, B 90, C 0}\nEND\n");
  Handle h("kuka_kr16");
  accura_check_options o;
  ASSERT_EQ(accura_check_options_init(&o, sizeof(o)), ACCURA_OK);
  accura_check_summary s;
  accura_check_violation v[4];
  ASSERT_EQ(accura_check_program(h.m, (dir + "/far.xml").c_str(), (dir + "/seam.src").c_str(), &o, &s, v, 4), ACCURA_OK) << lastError(h.m);
  EXPECT_EQ(s.passed, 1);
  EXPECT_EQ(s.n_violations, 0u);
  EXPECT_NEAR(s.min_clearance_mm, 118 - 5 - 10, 1e-3);  // at the sample x = 1200

  ASSERT_EQ(accura_check_program(h.m, (dir + "/near.xml").c_str(), (dir + "/seam.src").c_str(), &o, &s, nullptr, 0),
            ACCURA_ERROR_BUFFER_TOO_SMALL);
  EXPECT_EQ(s.n_violations, 1u);
  ASSERT_EQ(accura_check_program(h.m, (dir + "/near.xml").c_str(), (dir + "/seam.src").c_str(), &o, &s, v, 4), ACCURA_OK) << lastError(h.m);
  EXPECT_EQ(s.passed, 0);
  ASSERT_EQ(s.n_violations, 1u);
  EXPECT_EQ(v[0].kind, ACCURA_CHECK_CLEARANCE);
  EXPECT_EQ(v[0].line, 5);
  EXPECT_EQ(v[0].motion_index, 1);
  EXPECT_EQ(v[0].on_path, 1);
  EXPECT_DOUBLE_EQ(v[0].limit, 5.0);
  // the first sample closer than 5 mm: sqrt(dx^2 + 7^2) - 10 = 5, dx = 13.27 mm before the post
  EXPECT_NEAR(v[0].p_world_tcp_mm[0], 1200 - 5 - std::sqrt(15.0 * 15.0 - 7.0 * 7.0), 2.0);
  const double dx = std::max(0.0, 1195 - v[0].p_world_tcp_mm[0]);
  EXPECT_NEAR(v[0].value, std::sqrt(dx * dx + 49.0) - 10, 2e-3);
  EXPECT_NE(std::string(v[0].message).find("post"), std::string::npos) << v[0].message;

  // the thresholds of the call instead of the cell's: the first sample closer than 0.5 mm,
  // sqrt(dx^2 + 7^2) - 10 = 0.5, dx = 7.83 mm before the post
  o.use_cell_thresholds = 0;
  o.min_clearance_mm = 0.5;
  ASSERT_EQ(accura_check_program(h.m, (dir + "/near.xml").c_str(), (dir + "/seam.src").c_str(), &o, &s, v, 4), ACCURA_OK);
  ASSERT_EQ(s.n_violations, 1u);
  EXPECT_DOUBLE_EQ(v[0].limit, 0.5);
  EXPECT_NEAR(v[0].p_world_tcp_mm[0], 1195 - std::sqrt(10.5 * 10.5 - 49.0), 1.0);
  const double dx2 = std::max(0.0, 1195 - v[0].p_world_tcp_mm[0]);
  EXPECT_NEAR(v[0].value, std::sqrt(dx2 * dx2 + 49.0) - 10, 2e-3);
  EXPECT_LT(v[0].value, 0.5);
  EXPECT_NEAR(s.min_clearance_mm, 0.0, 1e-9);  // the sphere touches the post: distance 0

  // a missing cell file: the status and its path
  EXPECT_EQ(accura_check_program(h.m, (dir + "/none.xml").c_str(), (dir + "/seam.src").c_str(), &o, &s, v, 4), ACCURA_ERROR_INPUT);
  EXPECT_NE(lastError(h.m).find(dir + "/none.xml"), std::string::npos) << lastError(h.m);
  test::writeText(dir + "/broken.xml", "<?xml version=\"1.0\"?>\n<cell>\n  <object name=\"p\" file=\"post.stl\" units=\"yards\"/>\n</cell>\n");
  EXPECT_EQ(accura_check_program(h.m, (dir + "/broken.xml").c_str(), (dir + "/seam.src").c_str(), &o, &s, v, 4), ACCURA_ERROR_INPUT);
  EXPECT_NE(lastError(h.m).find("broken.xml:3"), std::string::npos) << lastError(h.m);
}

}  // namespace
}  // namespace accura
