// Tests of the measurement CSV reader and writer (docs/measurement-format.md).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include <unistd.h>

#include "accura/calib/errors.h"
#include "accura/calib/measurements.h"

namespace fs = std::filesystem;
using accura::calib::ArgumentError;
using accura::calib::InputError;
using accura::calib::Measurement;
using accura::calib::MeasurementSet;
using accura::calib::RobotDefinition;

namespace {

constexpr double kPi = 3.14159265358979323846;

/// A six-axis robot with KUKA KR 16-like joint limits (only dof and limits matter here).
RobotDefinition sixAxisRobot() {
  RobotDefinition robot;
  robot.name = "test six-axis";
  const double limits[6][2] = {{-185, 185}, {-155, 35}, {-130, 154},
                               {-350, 350}, {-130, 130}, {-350, 350}};
  for (int i = 0; i < 6; ++i) {
    accura::calib::JointSpec j;
    j.name = "A" + std::to_string(i + 1);
    j.type = accura::calib::JointType::kRevolute;
    j.lower = limits[i][0];
    j.upper = limits[i][1];
    robot.joints.push_back(j);
  }
  return robot;
}

/// A revolute joint and a prismatic joint (mm).
RobotDefinition revolutePrismaticRobot() {
  RobotDefinition robot;
  accura::calib::JointSpec j1;
  j1.type = accura::calib::JointType::kRevolute;
  j1.lower = -90;
  j1.upper = 90;
  accura::calib::JointSpec j2;
  j2.type = accura::calib::JointType::kPrismatic;
  j2.lower = 0;
  j2.upper = 500;
  robot.joints = {j1, j2};
  return robot;
}

Eigen::Matrix3d rotZ(double deg) {
  const double c = std::cos(deg * kPi / 180), s = std::sin(deg * kPi / 180);
  Eigen::Matrix3d R;
  R << c, -s, 0, s, c, 0, 0, 0, 1;
  return R;
}
Eigen::Matrix3d rotY(double deg) {
  const double c = std::cos(deg * kPi / 180), s = std::sin(deg * kPi / 180);
  Eigen::Matrix3d R;
  R << c, 0, s, 0, 1, 0, -s, 0, c;
  return R;
}
Eigen::Matrix3d rotX(double deg) {
  const double c = std::cos(deg * kPi / 180), s = std::sin(deg * kPi / 180);
  Eigen::Matrix3d R;
  R << 1, 0, 0, 0, c, -s, 0, s, c;
  return R;
}

const char* const kHeader = "q1,q2,q3,q4,q5,q6,x,y,z\n";
const char* const kRow = "0,-90,90,0,45,0,1000,0,1500\n";

class MeasurementsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("accura_measurements_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  std::string fixture(const std::string& text, const std::string& name = "data.csv") const {
    const std::string path = (dir_ / name).string();
    std::ofstream out(path, std::ios::binary);
    out << text;
    return path;
  }

  static std::string slurp(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }

  MeasurementSet read(const std::string& text) const {
    return accura::calib::readMeasurementsCsv(fixture(text), robot_);
  }

  /// The InputError reading `text` throws (a failure is recorded when it throws none).
  InputError readError(const std::string& text) const {
    return readErrorOf(fixture(text));
  }
  InputError readErrorOf(const std::string& path) const {
    try {
      accura::calib::readMeasurementsCsv(path, robot_);
    } catch (const InputError& e) {
      return e;
    }
    ADD_FAILURE() << "expected an InputError reading " << path;
    return InputError("no error");
  }

  std::string dataPath() const { return (dir_ / "data.csv").string(); }

  fs::path dir_;
  RobotDefinition robot_ = sixAxisRobot();
};

// ---------------------------------------------------------------------------------------
// Reading valid files

TEST_F(MeasurementsTest, ReadsRequiredColumns) {
  const MeasurementSet set = read(std::string(kHeader) + kRow +
                                  "10.5,-20.25,30,-40,50,-60.125,1234.5,-0.001,987.654321\n");
  EXPECT_EQ(set.file, dataPath());
  ASSERT_EQ(set.rows.size(), 2u);
  const Measurement& a = set.rows[0];
  EXPECT_EQ(a.line, 2);
  ASSERT_EQ(a.q.size(), 6);
  const double qa[6] = {0, -90, 90, 0, 45, 0};
  for (int i = 0; i < 6; ++i) EXPECT_EQ(a.q[i], qa[i]) << i;
  EXPECT_EQ(a.p_world_mm, Eigen::Vector3d(1000, 0, 1500));

  const Measurement& b = set.rows[1];
  EXPECT_EQ(b.line, 3);
  const double qb[6] = {10.5, -20.25, 30, -40, 50, -60.125};
  for (int i = 0; i < 6; ++i) EXPECT_EQ(b.q[i], qb[i]) << i;
  EXPECT_EQ(b.p_world_mm.x(), 1234.5);
  EXPECT_EQ(b.p_world_mm.y(), -0.001);
  EXPECT_EQ(b.p_world_mm.z(), 987.654321);

  // Nothing optional present: flags off, documented defaults in the rows.
  EXPECT_FALSE(set.has_orientation);
  EXPECT_FALSE(set.has_std_position);
  EXPECT_FALSE(set.has_std_orientation);
  EXPECT_FALSE(set.has_weight);
  EXPECT_FALSE(set.has_payload);
  EXPECT_FALSE(set.has_temperature);
  EXPECT_FALSE(set.has_direction);
  EXPECT_FALSE(set.has_time);
  EXPECT_TRUE(set.unknown_columns.empty());
  EXPECT_FALSE(b.has_orientation);
  EXPECT_TRUE(b.std_mm.array().isNaN().all());
  EXPECT_TRUE(b.std_rot_deg.array().isNaN().all());
  EXPECT_EQ(b.weight, 1.0);
  EXPECT_EQ(b.context.payload_kg, 0.0);
  EXPECT_TRUE(std::isnan(b.temp_c));
  EXPECT_TRUE(std::isnan(b.time_s));
  EXPECT_TRUE(b.dir.empty());
}

TEST_F(MeasurementsTest, HeaderIsCaseInsensitiveTrimmedAndInAnyOrder) {
  const MeasurementSet set = read(
      " Z ,Q6,\tq5 ,Y,q4,Q3,q2,X,q1\n"
      "  1.5e3 , +6, 5 ,\t-2.5E-1,4,3,-2,  .5 ,1.\n");
  ASSERT_EQ(set.rows.size(), 1u);
  const Measurement& m = set.rows[0];
  const double q[6] = {1, -2, 3, 4, 5, 6};
  for (int i = 0; i < 6; ++i) EXPECT_EQ(m.q[i], q[i]) << i;
  EXPECT_EQ(m.p_world_mm, Eigen::Vector3d(0.5, -0.25, 1500));
}

TEST_F(MeasurementsTest, SkipsCommentsAndBlankLinesAndToleratesCrlfAndBom) {
  const MeasurementSet set = read(
      "\xEF\xBB\xBF# measured 2024-05-01, laser tracker\r\n"  // line 1
      "\r\n"                                                  // line 2
      "   # indented comment before the header\r\n"           // line 3
      "q1,q2,q3,q4,q5,q6,x,y,z\r\n"                           // line 4
      "# comment between header and data\r\n"                 // line 5
      "1,2,3,4,5,6,7,8,9\r\n"                                 // line 6
      "  \t \r\n"                                             // line 7
      "\t# tab-indented comment, with, commas\r\n"            // line 8
      "11,12,13,14,15,16,17,18,19");                          // line 9, no final newline
  ASSERT_EQ(set.rows.size(), 2u);
  EXPECT_EQ(set.rows[0].line, 6);
  EXPECT_EQ(set.rows[1].line, 9);
  EXPECT_EQ(set.rows[0].q[5], 6);
  EXPECT_EQ(set.rows[0].p_world_mm.z(), 9);  // no '\r' left on the last field
  EXPECT_EQ(set.rows[1].q[0], 11);
  EXPECT_EQ(set.rows[1].p_world_mm.z(), 19);
  EXPECT_TRUE(set.unknown_columns.empty());
}

TEST_F(MeasurementsTest, QuaternionIsNormalised) {
  const MeasurementSet set = read(
      "q1,q2,q3,q4,q5,q6,x,y,z,qw,qx,qy,qz\n"
      "0,0,0,0,0,0,1,2,3,0.70710678,0,0,0.70710678\n"
      "0,0,0,0,0,0,1,2,3,1.0009,0,0,0\n"
      "0,0,0,0,0,0,1,2,3,0.5,0.5,-0.5,0.5\n");
  EXPECT_TRUE(set.has_orientation);
  ASSERT_EQ(set.rows.size(), 3u);
  for (const Measurement& m : set.rows) {
    EXPECT_TRUE(m.has_orientation);
    EXPECT_NEAR(m.R_world_tcp.norm(), 1.0, 1e-15);
  }
  // 90 deg about z: x axis goes to y.
  const Eigen::Vector3d ex = set.rows[0].R_world_tcp * Eigen::Vector3d::UnitX();
  EXPECT_NEAR((ex - Eigen::Vector3d::UnitY()).norm(), 0, 1e-8);
  // A norm 1.0009 is within 1e-3 of 1 and becomes exactly the identity.
  EXPECT_EQ(set.rows[1].R_world_tcp.w(), 1.0);
  EXPECT_EQ(set.rows[1].R_world_tcp.vec(), Eigen::Vector3d::Zero());
  const Eigen::Vector4d c = set.rows[2].R_world_tcp.coeffs();  // x, y, z, w
  EXPECT_EQ(c, Eigen::Vector4d(0.5, -0.5, 0.5, 0.5));
}

TEST_F(MeasurementsTest, KukaAbcIsRzRyRx) {
  const MeasurementSet set = read(
      "q1,q2,q3,q4,q5,q6,x,y,z,A,B,C\n"
      "0,0,0,0,0,0,1,2,3,30,20,10\n"
      "0,0,0,0,0,0,1,2,3,-120,-45,170\n");
  EXPECT_TRUE(set.has_orientation);
  ASSERT_EQ(set.rows.size(), 2u);
  const Eigen::Matrix3d R0 = rotZ(30) * rotY(20) * rotX(10);
  const Eigen::Matrix3d R1 = rotZ(-120) * rotY(-45) * rotX(170);
  EXPECT_TRUE(set.rows[0].has_orientation);
  EXPECT_LT((set.rows[0].R_world_tcp.toRotationMatrix() - R0).norm(), 1e-12);
  EXPECT_LT((set.rows[1].R_world_tcp.toRotationMatrix() - R1).norm(), 1e-12);
  EXPECT_NEAR(set.rows[1].R_world_tcp.norm(), 1.0, 1e-15);
  // Not the reverse order (Rx Ry Rz).
  EXPECT_GT((set.rows[0].R_world_tcp.toRotationMatrix() - rotX(10) * rotY(20) * rotZ(30)).norm(),
            1e-3);
}

TEST_F(MeasurementsTest, ReadsStdDevsWeightAndContext) {
  const MeasurementSet set = read(
      "q1,q2,q3,q4,q5,q6,x,y,z,qw,qx,qy,qz,std_x,std_y,std_z,std_rx,std_ry,std_rz,weight,"
      "payload_kg,temp_c,dir1,dir2,dir3,dir4,dir5,dir6,time_s\n"
      "0,0,0,0,0,0,1,2,3,1,0,0,0,0.01,0.02,0.03,0.001,0.002,0.003,2.5,16,21.5,"
      "+1,-1,1,-1,1,1,12.75\n"
      "0,0,0,0,0,0,1,2,3,1,0,0,0,0.5,0.5,0.5,0.1,0.1,0.1,0.25,0,-3,-1,-1,-1,-1,-1,-1,0\n");
  EXPECT_TRUE(set.has_orientation);
  EXPECT_TRUE(set.has_std_position);
  EXPECT_TRUE(set.has_std_orientation);
  EXPECT_TRUE(set.has_weight);
  EXPECT_TRUE(set.has_payload);
  EXPECT_TRUE(set.has_temperature);
  EXPECT_TRUE(set.has_direction);
  EXPECT_TRUE(set.has_time);
  ASSERT_EQ(set.rows.size(), 2u);
  const Measurement& m = set.rows[0];
  EXPECT_EQ(m.std_mm, Eigen::Vector3d(0.01, 0.02, 0.03));
  EXPECT_EQ(m.std_rot_deg, Eigen::Vector3d(0.001, 0.002, 0.003));
  EXPECT_EQ(m.weight, 2.5);
  EXPECT_EQ(m.context.payload_kg, 16);
  EXPECT_EQ(m.temp_c, 21.5);
  EXPECT_EQ(m.dir, (std::vector<int>{1, -1, 1, -1, 1, 1}));
  EXPECT_EQ(m.time_s, 12.75);
  const Measurement& n = set.rows[1];
  EXPECT_EQ(n.weight, 0.25);
  EXPECT_EQ(n.context.payload_kg, 0);  // zero payload is allowed
  EXPECT_EQ(n.temp_c, -3);
  EXPECT_EQ(n.dir, std::vector<int>(6, -1));
  EXPECT_EQ(n.time_s, 0);
}

TEST_F(MeasurementsTest, IsotropicStdDevsFillAllAxes) {
  const MeasurementSet set = read(
      "q1,q2,q3,q4,q5,q6,x,y,z,a,b,c,std_mm,std_deg\n"
      "0,0,0,0,0,0,1,2,3,0,0,0,0.015,0.002\n");
  EXPECT_TRUE(set.has_std_position);
  EXPECT_TRUE(set.has_std_orientation);
  EXPECT_EQ(set.rows[0].std_mm, Eigen::Vector3d::Constant(0.015));
  EXPECT_EQ(set.rows[0].std_rot_deg, Eigen::Vector3d::Constant(0.002));
}

TEST_F(MeasurementsTest, ListsUnknownColumnsInHeaderOrder) {
  const MeasurementSet set = read(
      "Pose ID,q1,q2,q3,q4,q5,q6,x,y,z,Operator,rx,q,dir,std_q,Note\n"
      "P-001,1,2,3,4,5,6,7,8,9,anna,not a number,,x,?,free text\n");
  EXPECT_EQ(set.unknown_columns,
            (std::vector<std::string>{"Pose ID", "Operator", "rx", "q", "dir", "std_q", "Note"}));
  ASSERT_EQ(set.rows.size(), 1u);
  EXPECT_EQ(set.rows[0].q[0], 1);  // known columns still found behind the unknown one
  EXPECT_EQ(set.rows[0].p_world_mm, Eigen::Vector3d(7, 8, 9));
  EXPECT_FALSE(set.has_orientation);
}

TEST_F(MeasurementsTest, JointLimitsAreInclusive) {
  const MeasurementSet set = read(std::string(kHeader) + "-185,-155,154,350,-130,-350,0,0,0\n" +
                                  "185,35,-130,-350,130,350,0,0,0\n");
  ASSERT_EQ(set.rows.size(), 2u);
  EXPECT_EQ(set.rows[0].q[1], -155);
  EXPECT_EQ(set.rows[1].q[1], 35);
}

// ---------------------------------------------------------------------------------------
// Errors: exact location and message

TEST_F(MeasurementsTest, ErrorNotANumber) {
  std::string text = "# a comment\n" + std::string(kHeader);
  for (int i = 0; i < 11; ++i) text += kRow;               // lines 3..13
  text += "0,-90,abc,0,45,0,1000,0,1500\n";                  // line 14
  const InputError e = readError(text);
  EXPECT_EQ(std::string(e.what()),
            dataPath() + ":14:3: column 'q3': expected a number, found 'abc'");
  EXPECT_EQ(e.file(), dataPath());
  EXPECT_EQ(e.line(), 14);
  EXPECT_EQ(e.column(), 3);
  EXPECT_EQ(e.message(), "column 'q3': expected a number, found 'abc'");
}

TEST_F(MeasurementsTest, ErrorMalformedNumbers) {
  struct Case {
    const char* field;
    const char* message;
  };
  const Case cases[] = {
      {"", "expected a number, found an empty field"},
      {"   ", "expected a number, found an empty field"},
      {"1.5.2", "expected a number, found '1.5.2'"},
      {"12mm", "expected a number, found '12mm'"},
      {"0x10", "expected a number, found '0x10'"},
      {"1 5", "expected a number, found '1 5'"},
      {"++1", "expected a number, found '++1'"},
      {"nan", "expected a finite number, found 'nan'"},
      {" NaN ", "expected a finite number, found 'NaN'"},
      {"inf", "expected a finite number, found 'inf'"},
      {"-Infinity", "expected a finite number, found '-Infinity'"},
      {"1e999", "expected a finite number within the range of a double, found '1e999'"},
  };
  for (const Case& c : cases) {
    const InputError e = readError(std::string(kHeader) + "0,0,0,0,0,0,1," + c.field + ",3\n");
    EXPECT_EQ(std::string(e.what()), dataPath() + ":2:8: column 'y': " + c.message)
        << "field '" << c.field << "'";
  }
}

TEST_F(MeasurementsTest, ErrorDecimalCommaChangesFieldCount) {
  // a tracker's x, y, z written with decimal commas (1235,412 0,087 1410,236): three fields too
  // many and no '.': the message names the likely cause (before: the counts alone)
  const std::string note = " (no '.' in the line: a decimal comma? numbers take a decimal point, ',' separates the fields)";
  const InputError e = readError(std::string(kHeader) + "0,-90,90,0,45,0,1235,412,0,087,1410,236\n");
  EXPECT_EQ(std::string(e.what()), dataPath() + ":2:10: expected 9 fields as in the header, found 12" + note);
  EXPECT_EQ(e.column(), 10);  // the first field beyond the header's
  // two fields too many, one of them the digits after a decimal comma ("05" of 2,05): said too
  EXPECT_EQ(std::string(readError(std::string(kHeader) + "0,0,0,0,0,0,1,5,2,05,3\n").what()),
            dataPath() + ":2:10: expected 9 fields as in the header, found 11" + note);
  // two whole numbers too many: as likely stray values, no decimal comma said (before: it was);
  // nor on a line with a decimal point, or one field too many
  EXPECT_EQ(std::string(readError(std::string(kHeader) + "0,0,0,0,0,0,1,5,2,5,3\n").what()),
            dataPath() + ":2:10: expected 9 fields as in the header, found 11");
  EXPECT_EQ(std::string(readError(std::string(kHeader) + "0,-90,90,0,45,0,1235,87,1410,1,2\n").what()),
            dataPath() + ":2:10: expected 9 fields as in the header, found 11");
  EXPECT_EQ(std::string(readError(std::string(kHeader) + "0,0,0,0,0,0,1.5,2,5,3,4\n").what()),
            dataPath() + ":2:10: expected 9 fields as in the header, found 11");
  EXPECT_EQ(std::string(readError(std::string(kHeader) + "0,0,0,0,0,0,1,2,5,3\n").what()),
            dataPath() + ":2:10: expected 9 fields as in the header, found 10");
}

// A file whose header row is missing (it starts with the data) is told so, not that the numbers
// taken as names are a duplicate column (before: "column '0': expected each column name once").
TEST_F(MeasurementsTest, ErrorDataRowWhereTheHeaderShouldBe) {
  const InputError e = readError("# tracker export\n0,-90,90,0,45,0,1235.412,0.087,1410.236\n12.5,-75,80,-30,60,15,1301.774,288.912,1372.530\n");
  EXPECT_EQ(std::string(e.what()), dataPath() + ":2:1: expected a header row (q1..q6, x, y, z), found a row starting with the "
                                                "number '0': the first line that is neither a comment nor blank names the columns");
  EXPECT_EQ(e.line(), 2);
  EXPECT_EQ(e.column(), 1);
}

TEST_F(MeasurementsTest, ErrorWrongFieldCount) {
  // 12 columns: 9 required + 3 unknown; line 9 has 11 fields.
  std::string text = "# c\n# c\nq1,q2,q3,q4,q5,q6,x,y,z,u1,u2,u3\n";  // header on line 3
  for (int i = 0; i < 5; ++i) text += "0,0,0,0,0,0,1,2,3,a,b,c\n";      // lines 4..8
  text += "0,0,0,0,0,0,1,2,3,a,b\n";                                     // line 9
  const InputError e = readError(text);
  EXPECT_EQ(std::string(e.what()), dataPath() + ":9:12: expected 12 fields as in the header, found 11");
  EXPECT_EQ(e.line(), 9);
  EXPECT_EQ(e.column(), 12);  // where the missing 12th field would start

  const InputError more = readError(std::string(kHeader) + "0,0,0,0,0,0,1,2,3,4\n");
  EXPECT_EQ(std::string(more.what()),
            dataPath() + ":2:10: expected 9 fields as in the header, found 10");
}

TEST_F(MeasurementsTest, QuotedHeaderNamesAreNamed) {
  // the native format has no quoting: the error says so (a mapping file reads quoted exports)
  const InputError e = readError("\"q1\",\"q2\",\"q3\",\"q4\",\"q5\",\"q6\",\"x\",\"y\",\"z\"\n0,0,0,0,0,0,1,2,3\n");
  EXPECT_NE(std::string(e.what()).find("the format has no quoting, found the quoted name \"q1\""), std::string::npos) << e.what();
}

TEST_F(MeasurementsTest, ErrorJointOutsideLimits) {
  std::string text = kHeader;
  for (int i = 0; i < 18; ++i) text += kRow;  // lines 2..19
  text += "0,40,90,0,45,0,1000,0,1500\n";      // line 20
  const InputError e = readError(text);
  EXPECT_EQ(std::string(e.what()),
            dataPath() +
                ":20:2: column 'q2': expected a joint value within the joint limits [-155, 35] deg, found 40 deg");

  const InputError low = readError(std::string(kHeader) + "-185.5,0,0,0,0,0,0,0,0\n");
  EXPECT_EQ(std::string(low.what()),
            dataPath() +
                ":2:1: column 'q1': expected a joint value within the joint limits [-185, 185] deg, found -185.5 deg");
  // a hair beyond (a URDF's limit in radians, rounded: 2.87979 rad is 164.99981 deg) is read
  EXPECT_DOUBLE_EQ(read(std::string(kHeader) + "-185.005,0,0,0,0,0,0,0,0\n").rows[0].q[0], -185.005);
  const InputError beyond = readError(std::string(kHeader) + "-185.02,0,0,0,0,0,0,0,0\n");
  EXPECT_NE(std::string(beyond.what()).find("found -185.02 deg"), std::string::npos) << beyond.what();
}

TEST_F(MeasurementsTest, AValueBeyondTheTurnOfAJointWithoutLimitsSaysWhichPoseItIs) {
  // a URDF's continuous joint has no limit and is given -360..360 deg: 539 deg is refused, and
  // the message says why and which value within a turn is the same pose
  robot_.joints[5].lower = -360;
  robot_.joints[5].upper = 360;
  EXPECT_EQ(std::string(readError(std::string(kHeader) + "0,-90,90,0,45,539,1000,0,1500\n").what()),
            dataPath() + ":2:6: column 'q6': expected a joint value within the joint limits [-360, 360] deg, found 539 deg; "
                         "-360..360 deg is also what a joint without limits (a URDF's continuous joint) is given: 539 deg is the "
                         "pose of 179 deg, give the value within a turn");
  // other limits: no such note
  EXPECT_EQ(std::string(readError(std::string(kHeader) + "0,-90,90,400,45,0,1000,0,1500\n").what()),
            dataPath() + ":2:4: column 'q4': expected a joint value within the joint limits [-350, 350] deg, found 400 deg");
  EXPECT_EQ(read(std::string(kHeader) + "0,-90,90,0,45,-360.004,1000,0,1500\n").rows[0].q[5], -360.004);
}

TEST_F(MeasurementsTest, ErrorPrismaticJointLimitInMm) {
  const std::string path = fixture("q1,q2,x,y,z\n0,250,1,2,3\n10,500.25,1,2,3\n");
  try {
    accura::calib::readMeasurementsCsv(path, revolutePrismaticRobot());
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              path + ":3:2: column 'q2': expected a joint value within the joint limits [0, 500] mm, found 500.25 mm");
  }
}

TEST_F(MeasurementsTest, ErrorMissingColumns) {
  const InputError e = readError("q1,q2,q3,q5,q6,x,y,z\n0,0,0,0,0,1,2,3\n");
  EXPECT_EQ(std::string(e.what()), dataPath() + ":1:1: missing column 'q4' (expected q1..q6, x, y, z)");
  EXPECT_EQ(e.line(), 1);
  EXPECT_EQ(e.column(), 1);  // the header

  const InputError two = readError("# header on line 2\nq1,q2,q3,q4,q5,q6,x,y\n");
  EXPECT_EQ(std::string(two.what()),
            dataPath() + ":2:1: missing column 'z' (expected q1..q6, x, y, z)");

  const InputError many = readError("q2,q3,q4,q5,q6,y\n");
  EXPECT_EQ(std::string(many.what()),
            dataPath() + ":1:1: missing columns 'q1', 'x', 'z' (expected q1..q6, x, y, z)");
}

TEST_F(MeasurementsTest, ErrorSemicolonDelimiterGetsAHint) {
  const InputError e = readError("q1;q2;q3;q4;q5;q6;x;y;z\n0;0;0;0;0;0;1;2;3\n");
  const std::string what = e.what();
  EXPECT_EQ(what.rfind(dataPath() + ":1:1: missing columns 'q1', 'q2'", 0), 0u) << what;
  EXPECT_NE(what.find("the delimiter is ','"), std::string::npos) << what;
  // and where such an export is read as it is (before: the delimiter alone, as if the file had
  // to be rewritten)
  EXPECT_EQ(what.substr(what.find("; the delimiter")),
            "; the delimiter is ',', found a header with ';' or tabs (an export with another delimiter or decimal commas is read as it "
            "is through a mapping file, --map: docs/measurement-mapping.md)");
}

TEST_F(MeasurementsTest, ErrorDuplicateColumn) {
  const InputError e = readError("q1,q2,q3,q4,q5,q6,x,y,z,X\n0,0,0,0,0,0,1,2,3,4\n");
  EXPECT_EQ(std::string(e.what()),
            dataPath() + ":1:10: column 'X': expected each column name once, found a duplicate "
                         "of column 7");
  EXPECT_EQ(e.column(), 10);

  const InputError unknown = readError("note,q1,q2,q3,q4,q5,q6,x,y,z,Note\n");
  EXPECT_EQ(std::string(unknown.what()).rfind(dataPath() + ":1:11: column 'Note':", 0), 0u);
  EXPECT_NE(std::string(unknown.what()).find("duplicate of column 1"), std::string::npos);
}

TEST_F(MeasurementsTest, ErrorEmptyColumnName) {
  const InputError e = readError("q1,q2,,q3,q4,q5,q6,x,y,z\n0,0,0,0,0,0,0,1,2,3\n");
  EXPECT_EQ(std::string(e.what()),
            dataPath() + ":1:3: expected a column name, found an empty field");
}

TEST_F(MeasurementsTest, ATrailingCommaOnEveryLineIsAnEmptyLastColumn) {
  // spreadsheets end every line with the delimiter: the header's empty last name was refused
  // while a mapping file read the same export (warning about a column with an empty name)
  const MeasurementSet s = read("q1,q2,q3,q4,q5,q6,x,y,z,\n0,-90,90,0,45,0,1000,0,1500,\n1,-90,90,0,45,0,1001,0,1500,\n");
  ASSERT_EQ(s.rows.size(), 2u);
  EXPECT_EQ(s.rows[1].p_world_mm.x(), 1001);
  ASSERT_EQ(s.unknown_columns.size(), 1u);
  EXPECT_EQ(s.unknown_columns[0], "an empty column at the end (a trailing ',')");
  // on the header or on the rows only: refused, and said
  EXPECT_EQ(std::string(readError("q1,q2,q3,q4,q5,q6,x,y,z,\n0,-90,90,0,45,0,1000,0,1500\n").what()),
            dataPath() + ":2:10: expected 10 fields as in the header, found 9 (the header ends with ',': an empty column at the "
                         "end, which every row must have too)");
  EXPECT_EQ(std::string(readError(std::string(kHeader) + "0,-90,90,0,45,0,1000,0,1500,\n").what()),
            dataPath() + ":2:10: expected 9 fields as in the header, found 10 (the line ends with ',', the header does not: a "
                         "trailing delimiter on the rows only)");
}

TEST_F(MeasurementsTest, ANulByteIsShownNotCutAt) {
  // the message ended at the NUL ("found '-119.538015"): shown as \0 and named
  const InputError e = readError(std::string(kHeader) + std::string("0,-90,90,0,45,0,1000,0,1500\0\n", 29));
  EXPECT_EQ(std::string(e.what()), dataPath() + ":2:9: column 'z': expected a number, found '1500\\0' (\\0 is a NUL byte: a "
                                                "binary or corrupted file?)");
  EXPECT_EQ(e.message(), "column 'z': expected a number, found '1500\\0' (\\0 is a NUL byte: a binary or corrupted file?)");
}

TEST_F(MeasurementsTest, LinesEndingInCrOnlyAndUtf16AreNamedNotReadAsAHeaderAlone) {
  // a classic Mac OS export ends its lines in CR only: the file was one line, a header alone
  // ("data.csv:1:1: expected at least one data row after the header, found none")
  const std::string cr_only = std::string("q1,q2,q3,q4,q5,q6,x,y,z\r") + "0,-90,90,0,45,0,1000,0,1500\r" + "0,-90,90,0,45,0,1001,0,1500\r";
  EXPECT_EQ(std::string(readError(cr_only).what()),
            dataPath() + ":1:1: expected lines that end in LF or CRLF, found a CR without LF after the text of line 1 (lines that end "
                         "in CR only, as classic Mac OS exports write them, 'CSV (Macintosh)'?): the file would read as one line; "
                         "convert its line ends (e.g. tr '\\r' '\\n' < in.csv > out.csv)");
  // a stray CR inside a CRLF file's third line: named at that line
  EXPECT_EQ(readError(std::string(kHeader) + kRow + "0,-90,90,0,45,0\r,1000,0,1500\r\n").line(), 3);
  // UTF-16 (a spreadsheet's "Unicode Text"): was "missing columns 'q1', ..., 'z'"
  std::string utf16 = "\xFF\xFE";
  for (char c : std::string(kHeader) + kRow) utf16 += std::string(1, c) + '\0';
  EXPECT_EQ(std::string(readError(utf16).what()),
            dataPath() + ":1:1: expected UTF-8 or ASCII text, found UTF-16 (the byte-order mark FF FE at the start of the file): "
                         "save the export as UTF-8 text (a spreadsheet's 'CSV UTF-8', not 'Unicode Text')");
  EXPECT_EQ(readError(utf16.substr(2)).message(),
            "expected UTF-8 or ASCII text, found a NUL byte at the start of the file (UTF-16 text without a byte-order mark, or a "
            "binary file?): save the export as UTF-8 text");
  // a stray CR in a comment of an LF file is not read, as before
  EXPECT_EQ(read("# pasted\rnote\n" + std::string(kHeader) + kRow).rows.size(), 1u);
  // a CR that ends the file's last line (no LF after it) is that line's end, as before
  EXPECT_EQ(read(std::string(kHeader) + "0,-90,90,0,45,0,1000,0,1500\r").rows.size(), 1u);
}

TEST_F(MeasurementsTest, TheHeaderAgainIsNamedAsTwoExportsJoined) {
  // two files joined (cat a.csv b.csv): was "data.csv:4:1: column 'q1': expected a number, found 'q1'"
  const std::string joined = std::string(kHeader) + kRow + kRow + "Q1, q2,q3,q4,q5,q6,x,y,z\n" + kRow;
  EXPECT_EQ(std::string(readError(joined).what()),
            dataPath() + ":4:1: expected a data row, found the header row again (the header is line 1): two exports joined into one "
                         "file? Split them, or delete the repeated header");
  // the second file's byte-order mark before it (joined byte for byte)
  const std::string with_bom = "\xEF\xBB\xBF" + std::string(kHeader) + kRow + "\xEF\xBB\xBF" + kHeader + kRow;
  EXPECT_EQ(readError(with_bom).line(), 3);
  EXPECT_EQ(readError(with_bom).message(),
            "expected a data row, found the header row again (the header is line 1): two exports joined into one file? Split them, or "
            "delete the repeated header");
}

TEST_F(MeasurementsTest, UnitsInColumnNamesPointToAMappingFile) {
  // an export's names ('q1 [deg]', 'x_mm'): the missing-column error says what the names are and
  // what reads them, as it does for a ';' delimiter
  const InputError e = readError("q1 [deg],q2 [deg],q3 [deg],q4 [deg],q5 [deg],q6 [deg],x [mm],y [mm],z [mm]\n0,0,0,0,0,0,1,2,3\n");
  EXPECT_EQ(std::string(e.what()), dataPath() + ":1:1: missing columns 'q1', 'q2', 'q3', 'q4', 'q5', 'q6', 'x', 'y', 'z' (expected "
                                                "q1..q6, x, y, z); found 'q1 [deg]': the format's names carry no unit (q in deg or "
                                                "mm, x, y, z in mm); read the export through a mapping file: "
                                                "docs/measurement-mapping.md");
  EXPECT_NE(std::string(readError("q1,q2,q3,q4,q5,q6,x_mm,y_mm,z_mm\n0,0,0,0,0,0,1,2,3\n").what())
                .find("missing columns 'x', 'y', 'z' (expected q1..q6, x, y, z); found 'x_mm': the format's names carry no unit"),
            std::string::npos);
}

TEST_F(MeasurementsTest, ErrorJointColumnBeyondRobot) {
  const InputError q7 = readError("q1,q2,q3,q4,q5,q6,q7,x,y,z\n");
  EXPECT_EQ(std::string(q7.what()),
            dataPath() +
                ":1:7: column 'q7': expected joint columns q1..q6 for this 6-axis robot, found 'q7'");
  const InputError q0 = readError("q0,q1,q2,q3,q4,q5,q6,x,y,z\n");
  EXPECT_EQ(std::string(q0.what()).rfind(dataPath() + ":1:1: column 'q0': expected joint columns", 0),
            0u);
  const InputError q01 = readError("q01,q2,q3,q4,q5,q6,x,y,z\n");
  EXPECT_EQ(std::string(q01.what()).rfind(dataPath() + ":1:1: column 'q01':", 0), 0u);
  const InputError dir7 = readError("q1,q2,q3,q4,q5,q6,x,y,z,dir7\n");
  EXPECT_EQ(std::string(dir7.what()),
            dataPath() + ":1:10: column 'dir7': expected direction columns dir1..dir6 for this "
                         "6-axis robot, found 'dir7'");
}

TEST_F(MeasurementsTest, ErrorNoDataRow) {
  const InputError e = readError("# only a header\nq1,q2,q3,q4,q5,q6,x,y,z\n\n# and comments\n");
  EXPECT_EQ(std::string(e.what()), dataPath() + ":2:1: expected at least one data row after the header, found none");
  EXPECT_EQ(e.line(), 2);  // the header's
}

TEST_F(MeasurementsTest, ErrorNoHeader) {
  const InputError empty = readError("");
  EXPECT_EQ(std::string(empty.what()),
            dataPath() + ":1:1: expected a header row (q1..q6, x, y, z), found an empty file");
  const InputError comments = readError("# nothing\n\n   \n# here\n");
  EXPECT_EQ(std::string(comments.what()),
            dataPath() +
                ":1:1: expected a header row (q1..q6, x, y, z), found only comments and blank lines");
}

TEST_F(MeasurementsTest, ErrorUnreadableFile) {
  const std::string missing = (dir_ / "no_such.csv").string();
  const InputError e = readErrorOf(missing);
  EXPECT_EQ(std::string(e.what()), missing + ": cannot open file: No such file or directory");
  EXPECT_EQ(e.line(), 0);
  EXPECT_EQ(e.column(), 0);

  const InputError d = readErrorOf(dir_.string());
  EXPECT_EQ(std::string(d.what()).rfind(dir_.string() + ": cannot open file: ", 0), 0u)
      << d.what();
}

TEST_F(MeasurementsTest, ErrorOrientationGroups) {
  const InputError both = readError("q1,q2,q3,q4,q5,q6,x,y,z,qw,qx,qy,qz,a,b,c\n");
  EXPECT_EQ(std::string(both.what()),
            dataPath() + ":1:14: expected orientation as either qw, qx, qy, qz or a, b, c, found both");

  const InputError quat = readError("q1,q2,q3,q4,q5,q6,x,y,z,qw,qx,qy\n");
  EXPECT_EQ(std::string(quat.what()),
            dataPath() + ":1:10: incomplete orientation columns: expected qw, qx, qy, qz together, "
                         "found qw, qx, qy (missing 'qz')");

  const InputError abc = readError("q1,q2,q3,q4,q5,q6,x,y,z,A,C\n");
  EXPECT_EQ(std::string(abc.what()),
            dataPath() + ":1:10: incomplete orientation columns: expected a, b, c together, found "
                         "a, c (missing 'b')");
}

TEST_F(MeasurementsTest, ErrorQuaternionNotUnit) {
  const InputError e = readError(
      "q1,q2,q3,q4,q5,q6,x,y,z,qw,qx,qy,qz\n"
      "0,0,0,0,0,0,1,2,3,1,0,0,0\n"
      "0,0,0,0,0,0,1,2,3,0.6,0,0.8,0.05\n");
  const std::string what = e.what();
  EXPECT_EQ(what.rfind(dataPath() + ":3:10: columns 'qw', 'qx', 'qy', 'qz': expected a unit "
                                    "quaternion (norm 1 within 1e-3), found norm 1.00124",
                       0),
            0u)
      << what;

  const InputError zero = readError(
      "q1,q2,q3,q4,q5,q6,x,y,z,qw,qx,qy,qz\n0,0,0,0,0,0,1,2,3,0,0,0,0\n");
  EXPECT_EQ(std::string(zero.what()),
            dataPath() + ":2:10: columns 'qw', 'qx', 'qy', 'qz': expected a unit quaternion "
                         "(norm 1 within 1e-3), found norm 0");
}

TEST_F(MeasurementsTest, ErrorStdDevGroups) {
  const InputError part = readError("q1,q2,q3,q4,q5,q6,x,y,z,std_x,std_z\n");
  EXPECT_EQ(std::string(part.what()),
            dataPath() + ":1:10: incomplete position standard deviation columns: expected std_x, "
                         "std_y, std_z together, found std_x, std_z (missing 'std_y')");

  const InputError both = readError("q1,q2,q3,q4,q5,q6,x,y,z,std_x,std_y,std_z,std_mm\n");
  EXPECT_EQ(std::string(both.what()),
            dataPath() + ":1:13: expected position standard deviations as either std_x, std_y, "
                         "std_z or std_mm, found both");

  const InputError rot_both =
      readError("q1,q2,q3,q4,q5,q6,x,y,z,a,b,c,std_deg,std_rx,std_ry,std_rz\n");
  EXPECT_NE(std::string(rot_both.what()).find("std_rx, std_ry, std_rz or std_deg, found both"),
            std::string::npos);

  const InputError rot_part = readError("q1,q2,q3,q4,q5,q6,x,y,z,a,b,c,std_ry\n");
  EXPECT_NE(std::string(rot_part.what()).find("found std_ry (missing 'std_rx', 'std_rz')"),
            std::string::npos)
      << rot_part.what();

  const InputError no_orient = readError("q1,q2,q3,q4,q5,q6,x,y,z,std_mm,std_rx,std_ry,std_rz\n");
  EXPECT_EQ(std::string(no_orient.what()),
            dataPath() + ":1:11: column 'std_rx': expected orientation columns (qw, qx, qy, qz "
                         "or a, b, c) with an orientation standard deviation, found none");
  const InputError no_orient_iso = readError("q1,q2,q3,q4,q5,q6,x,y,z,std_deg\n");
  EXPECT_EQ(std::string(no_orient_iso.what()).rfind(dataPath() + ":1:10: column 'std_deg':", 0),
            0u);
}

TEST_F(MeasurementsTest, ErrorNonPositiveStdWeightAndNegativePayload) {
  struct Case {
    const char* header;
    const char* values;
    const char* expected;  // after the file name
  };
  const Case cases[] = {
      {"std_x,std_y,std_z", "0.01,0,0.01",
       ":2:11: column 'std_y': expected a standard deviation > 0, found '0'"},
      {"std_mm", "-0.5", ":2:10: column 'std_mm': expected a standard deviation > 0, found '-0.5'"},
      {"a,b,c,std_deg", "0,0,0,-1e-3",
       ":2:13: column 'std_deg': expected a standard deviation > 0, found '-1e-3'"},
      {"weight", "0", ":2:10: column 'weight': expected a weight > 0, found '0'"},
      {"weight", "nan", ":2:10: column 'weight': expected a finite number, found 'nan'"},
      {"payload_kg", "-1", ":2:10: column 'payload_kg': expected a payload mass >= 0 kg, found '-1'"},
      {"temp_c", "warm", ":2:10: column 'temp_c': expected a number, found 'warm'"},
      {"time_s", "inf", ":2:10: column 'time_s': expected a finite number, found 'inf'"},
  };
  for (const Case& c : cases) {
    const InputError e = readError("q1,q2,q3,q4,q5,q6,x,y,z," + std::string(c.header) +
                                   "\n0,0,0,0,0,0,1,2,3," + c.values + "\n");
    EXPECT_EQ(std::string(e.what()), dataPath() + c.expected) << c.header;
  }
}

TEST_F(MeasurementsTest, ErrorDirections) {
  const std::string header = "q1,q2,q3,q4,q5,q6,x,y,z,dir1,dir2,dir3,dir4,dir5,dir6\n";
  const char* bad[] = {"0", "2", "0.5", "+-1", "up"};
  for (const char* v : bad) {
    const InputError e = readError(header + "0,0,0,0,0,0,1,2,3,1,1," + v + ",1,1,1\n");
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(dataPath() + ":2:12: column 'dir3': expected ", 0), 0u) << what;
    EXPECT_NE(what.find(std::string("found '") + v + "'"), std::string::npos) << what;
  }
  const InputError zero = readError(header + "0,0,0,0,0,0,1,2,3,1,1,0,1,1,1\n");
  EXPECT_EQ(std::string(zero.what()),
            dataPath() + ":2:12: column 'dir3': expected +1 or -1, found '0'");

  const InputError part = readError("q1,q2,q3,q4,q5,q6,x,y,z,dir1,dir2\n");
  EXPECT_EQ(std::string(part.what()),
            dataPath() + ":1:10: incomplete direction columns: expected dir1..dir6 together, found "
                         "dir1, dir2 (missing 'dir3', 'dir4', 'dir5', 'dir6')");
}

TEST_F(MeasurementsTest, ErrorReportsFirstBadRowOnly) {
  // Rows are checked in order: the first bad row is reported, with its own line number.
  const InputError e = readError(std::string(kHeader) + kRow + "\n# gap\n" +
                                 "0,0,0,0,0,0,1,2\n" + "0,0,0,0,0,0,1,2,x\n");
  EXPECT_EQ(e.line(), 5);
  EXPECT_EQ(std::string(e.what()), dataPath() + ":5:9: expected 9 fields as in the header, found 8");
}

// ---------------------------------------------------------------------------------------
// Writing

MeasurementSet fullSet() {
  MeasurementSet set;
  set.has_orientation = true;
  set.has_std_position = true;
  set.has_std_orientation = true;
  set.has_weight = true;
  set.has_payload = true;
  set.has_temperature = true;
  set.has_direction = true;
  set.has_time = true;
  Measurement a;
  a.q = Eigen::VectorXd(6);
  a.q << 1.25, -90, 90.0000004, 0, -1e-9, 180;
  a.p_world_mm = Eigen::Vector3d(1000.1234564, -2.5, 1500);
  a.R_world_tcp = Eigen::Quaterniond(Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitZ()));
  a.has_orientation = true;
  a.std_mm = Eigen::Vector3d(0.01, 0.02, 0.03);
  a.std_rot_deg = Eigen::Vector3d(0.001, 0.002, 0.003);
  a.weight = 2;
  a.context.payload_kg = 16;
  a.temp_c = 21.5;
  a.dir = {1, -1, 1, 1, -1, 1};
  a.time_s = 3.5;
  Measurement b = a;
  b.q << 0, 0, 0, 0, 0, 0;
  b.p_world_mm = Eigen::Vector3d(0, 0, 0);
  b.R_world_tcp = Eigen::Quaterniond(2, 0, 0, 0);  // normalised on writing
  b.dir = std::vector<int>(6, -1);
  b.temp_c = -3;
  b.time_s = 10;
  set.rows = {a, b};
  return set;
}

TEST_F(MeasurementsTest, WritesExactText) {
  const std::string path = (dir_ / "out.csv").string();
  accura::calib::writeMeasurementsCsv(path, fullSet(), 6, {"accura test", "two\nlines", ""});
  const std::string expected =
      "# accura test\n"
      "# two\n"
      "# lines\n"
      "#\n"
      "q1,q2,q3,q4,q5,q6,x,y,z,qw,qx,qy,qz,std_x,std_y,std_z,std_rx,std_ry,std_rz,weight,"
      "payload_kg,temp_c,dir1,dir2,dir3,dir4,dir5,dir6,time_s\n"
      "1.250000,-90.000000,90.000000,0.000000,0.000000,180.000000,1000.123456,-2.500000,"
      "1500.000000,0.707106781,0.000000000,0.000000000,0.707106781,0.010000,0.020000,0.030000,"
      "0.001000,0.002000,0.003000,2.000000,16.000000,21.500000,1,-1,1,1,-1,1,3.500000\n"
      "0.000000,0.000000,0.000000,0.000000,0.000000,0.000000,0.000000,0.000000,0.000000,"
      "1.000000000,0.000000000,0.000000000,0.000000000,0.010000,0.020000,0.030000,0.001000,"
      "0.002000,0.003000,2.000000,16.000000,-3.000000,-1,-1,-1,-1,-1,-1,10.000000\n";
  EXPECT_EQ(slurp(path), expected);
  EXPECT_FALSE(fs::exists(path + ".tmp"));
}

TEST_F(MeasurementsTest, WritesOnlyTheColumnsTheSetHas) {
  MeasurementSet set = fullSet();
  set.has_orientation = set.has_std_position = set.has_std_orientation = false;
  set.has_payload = set.has_direction = false;
  set.rows.resize(1);
  const std::string path = (dir_ / "out.csv").string();
  accura::calib::writeMeasurementsCsv(path, set, 6);
  EXPECT_EQ(slurp(path),
            "q1,q2,q3,q4,q5,q6,x,y,z,weight,temp_c,time_s\n"
            "1.250000,-90.000000,90.000000,0.000000,0.000000,180.000000,1000.123456,-2.500000,"
            "1500.000000,2.000000,21.500000,3.500000\n");
}

TEST_F(MeasurementsTest, RoundTripKeepsValuesAndIsDeterministic) {
  const std::string src = fixture(
      "# source\n"
      "q1,q2,q3,q4,q5,q6,x,y,z,a,b,c,std_mm,std_rx,std_ry,std_rz,weight,payload_kg,temp_c,"
      "dir1,dir2,dir3,dir4,dir5,dir6,time_s,comment\n"
      "12.3456789,-100.5,45,300.25,-129.9999999,0.1,1200.1234567,-350.5,900,"
      "30,20,10,0.02,0.001,0.002,0.003,1.5,8.25,22.1,1,-1,1,-1,1,-1,0.5,first\n"
      "-0.0000001,34.9999999,153,-1,2,3,1e3,2.5e-7,-1,-170,-60,175,0.05,0.01,0.01,0.01,"
      "0.75,0,19,-1,-1,-1,1,1,1,1234.567891,second\n",
      "source.csv");
  const MeasurementSet in = accura::calib::readMeasurementsCsv(src, robot_);
  EXPECT_EQ(in.unknown_columns, std::vector<std::string>{"comment"});

  const std::string out1 = (dir_ / "out1.csv").string();
  const std::string out2 = (dir_ / "out2.csv").string();
  accura::calib::writeMeasurementsCsv(out1, in, 6, {"round trip"});
  const MeasurementSet back = accura::calib::readMeasurementsCsv(out1, robot_);

  EXPECT_EQ(back.has_orientation, in.has_orientation);
  EXPECT_EQ(back.has_std_position, in.has_std_position);
  EXPECT_EQ(back.has_std_orientation, in.has_std_orientation);
  EXPECT_EQ(back.has_weight, in.has_weight);
  EXPECT_EQ(back.has_payload, in.has_payload);
  EXPECT_EQ(back.has_temperature, in.has_temperature);
  EXPECT_EQ(back.has_direction, in.has_direction);
  EXPECT_EQ(back.has_time, in.has_time);
  EXPECT_TRUE(back.unknown_columns.empty());  // unknown columns are not written
  ASSERT_EQ(back.rows.size(), in.rows.size());
  for (std::size_t r = 0; r < in.rows.size(); ++r) {
    const Measurement& a = in.rows[r];
    const Measurement& b = back.rows[r];
    EXPECT_EQ(b.line, static_cast<int>(r) + 3);  // comment, header, rows
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(b.q[i], a.q[i], 0.5e-6 + 1e-12) << r << " q" << i;
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(b.p_world_mm[i], a.p_world_mm[i], 0.5e-6 + 1e-12) << r;
      EXPECT_NEAR(b.std_mm[i], a.std_mm[i], 0.5e-6 + 1e-12) << r;
      EXPECT_NEAR(b.std_rot_deg[i], a.std_rot_deg[i], 0.5e-6 + 1e-12) << r;
    }
    EXPECT_TRUE(b.has_orientation);
    EXPECT_LT(b.R_world_tcp.angularDistance(a.R_world_tcp), 1e-8) << r;
    EXPECT_NEAR(b.weight, a.weight, 0.5e-6);
    EXPECT_NEAR(b.context.payload_kg, a.context.payload_kg, 0.5e-6);
    EXPECT_NEAR(b.temp_c, a.temp_c, 0.5e-6);
    EXPECT_NEAR(b.time_s, a.time_s, 0.5e-6);
    EXPECT_EQ(b.dir, a.dir);
  }
  EXPECT_EQ(in.rows[0].std_mm, Eigen::Vector3d::Constant(0.02));

  // Writing what was read back gives the same bytes; so does writing again.
  accura::calib::writeMeasurementsCsv(out2, back, 6, {"round trip"});
  EXPECT_EQ(slurp(out2), slurp(out1));
  accura::calib::writeMeasurementsCsv(out2, in, 6, {"round trip"});  // overwrites
  EXPECT_EQ(slurp(out2), slurp(out1));
  EXPECT_FALSE(fs::exists(out2 + ".tmp"));
}

TEST_F(MeasurementsTest, WriteFailureThrowsAndLeavesNoTemporaryFile) {
  const std::string no_dir = (dir_ / "missing" / "out.csv").string();
  try {
    accura::calib::writeMeasurementsCsv(no_dir, fullSet(), 6);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(no_dir + ": cannot write file: ", 0), 0u) << e.what();
  }

  // The target is a directory: the temporary file is written, the rename fails.
  const fs::path target = dir_ / "a_directory";
  fs::create_directories(target / "child");
  try {
    accura::calib::writeMeasurementsCsv(target.string(), fullSet(), 6);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(target.string() + ": cannot write file: ", 0), 0u)
        << e.what();
  }
  EXPECT_FALSE(fs::exists(target.string() + ".tmp"));
  EXPECT_TRUE(fs::is_directory(target / "child"));
}

TEST_F(MeasurementsTest, WriteRejectsInconsistentSets) {
  const std::string path = (dir_ / "out.csv").string();
  MeasurementSet wrong_q = fullSet();
  wrong_q.rows[1].q = Eigen::VectorXd::Zero(5);
  EXPECT_THROW(accura::calib::writeMeasurementsCsv(path, wrong_q, 6), ArgumentError);

  MeasurementSet nan_std = fullSet();
  nan_std.rows[0].std_mm[2] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(accura::calib::writeMeasurementsCsv(path, nan_std, 6), ArgumentError);

  MeasurementSet zero_weight = fullSet();
  zero_weight.rows[0].weight = 1e-9;  // would print as 0.000000 and not read back
  EXPECT_THROW(accura::calib::writeMeasurementsCsv(path, zero_weight, 6), ArgumentError);

  MeasurementSet short_dir = fullSet();
  short_dir.rows[0].dir.pop_back();
  EXPECT_THROW(accura::calib::writeMeasurementsCsv(path, short_dir, 6), ArgumentError);

  MeasurementSet empty = fullSet();
  empty.rows.clear();
  EXPECT_THROW(accura::calib::writeMeasurementsCsv(path, empty, 6), ArgumentError);

  EXPECT_FALSE(fs::exists(path));  // nothing written
  EXPECT_FALSE(fs::exists(path + ".tmp"));
}

}  // namespace
