// The robot and the cell as FCL geometry (check.h: CellGeometry).
#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/geometry/shape/capsule.h>
#include <fcl/geometry/shape/sphere.h>
#include <fcl/math/bv/OBBRSS.h>
#include <fcl/narrowphase/distance.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "accura/calib/errors.h"
#include "accura/postproc/check.h"

namespace accura::postproc {

struct CellGeometry::Impl {
  struct Shape {
    std::shared_ptr<fcl::CollisionGeometryd> geom;
    Eigen::Isometry3d T_parent_geom = Eigen::Isometry3d::Identity();  // FCL geometry frame in the parent
    Eigen::Vector3d center_parent = Eigen::Vector3d::Zero();          // bounding sphere (parent frame)
    double radius_mm = 0;
    Eigen::Vector3d aabb_min = Eigen::Vector3d::Zero(), aabb_max = Eigen::Vector3d::Zero();  // objects: world AABB
    int frame = 0;  // robot shapes: DH frame (1..n)
    std::string name;
  };
  calib::RobotModel robot;
  std::vector<Shape> robot_shapes, objects;
  Eigen::MatrixXd lever;  // [shape, joint]
  mutable calib::KinematicWorkspace ws;

  static Shape make(const CellShape& s) {
    Shape out;
    out.name = s.name;
    if (s.mesh) {
      auto bvh = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
      std::vector<fcl::Vector3d> pts(s.mesh->vertices_mm.begin(), s.mesh->vertices_mm.end());
      std::vector<fcl::Triangle> tris;
      tris.reserve(s.mesh->triangles.size());
      for (const auto& t : s.mesh->triangles) tris.emplace_back(t[0], t[1], t[2]);
      bvh->beginModel(static_cast<int>(tris.size()), static_cast<int>(pts.size()));
      bvh->addSubModel(pts, tris);
      bvh->endModel();
      out.geom = bvh;
      out.T_parent_geom = s.T_parent_shape;
      Eigen::Vector3d lo = pts.front(), hi = pts.front();
      for (const auto& p : pts) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
      const Eigen::Vector3d c = 0.5 * (lo + hi);
      double r = 0;
      for (const auto& p : pts) r = std::max(r, (p - c).norm());
      out.center_parent = s.T_parent_shape * c;
      out.radius_mm = r;
    } else if (s.capsule) {
      const Capsule& cap = *s.capsule;
      const Eigen::Vector3d a = s.T_parent_shape * cap.p0_mm, b = s.T_parent_shape * cap.p1_mm;
      const double len = (b - a).norm();
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.translation() = 0.5 * (a + b);
      if (len > 1e-9) {
        out.geom = std::make_shared<fcl::Capsuled>(cap.radius_mm, len);
        // z axis along the segment
        T.linear() = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), (b - a) / len).toRotationMatrix();
      } else {
        out.geom = std::make_shared<fcl::Sphered>(cap.radius_mm);
      }
      out.T_parent_geom = T;
      out.center_parent = 0.5 * (a + b);
      out.radius_mm = 0.5 * len + cap.radius_mm;
    } else {
      throw calib::ArgumentError("CellGeometry: the shape '" + s.name + "' has neither a mesh nor a capsule");
    }
    return out;
  }
};

CellGeometry::CellGeometry(const Cell& cell, const calib::RobotModel& robot) : impl_(std::make_unique<Impl>()) {
  robot.validate();
  Impl& I = *impl_;
  I.robot = robot;
  const int n = robot.dof();
  for (size_t k = 0; k < cell.link_shapes.size(); ++k) {
    const auto& ls = cell.link_shapes[k];
    if (ls.first < 1 || ls.first > n) {
      const std::string what = "<link> joint: expected 1.." + std::to_string(n) + " (the robot has " + std::to_string(n) + " joints), found " +
                               std::to_string(ls.first);
      // read from a cell file: an error of that file, at the joint attribute (a host's
      // ACCURA_ERROR_INPUT, not a wrong argument)
      if (k < cell.link_joint_positions.size() && cell.link_joint_positions[k].first > 0)
        throw calib::InputError(ls.second.file, cell.link_joint_positions[k].first, cell.link_joint_positions[k].second, what);
      throw calib::ArgumentError(calib::formatLocation(ls.second.file, ls.second.line, ls.second.column) + what);
    }
    Impl::Shape s = Impl::make(ls.second);
    s.frame = ls.first;
    I.robot_shapes.push_back(std::move(s));
  }
  for (const auto& ts : cell.tool_shapes) {
    Impl::Shape s = Impl::make(ts);
    s.frame = n;
    I.robot_shapes.push_back(std::move(s));
  }
  for (const auto& os : cell.objects) {
    Impl::Shape s = Impl::make(os);
    // world AABB of the object (static)
    if (os.mesh) {
      Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
      for (const auto& p : os.mesh->vertices_mm) {
        const Eigen::Vector3d w = os.T_parent_shape * p;
        lo = lo.cwiseMin(w);
        hi = hi.cwiseMax(w);
      }
      s.aabb_min = lo;
      s.aabb_max = hi;
    } else {
      s.aabb_min = s.center_parent - Eigen::Vector3d::Constant(s.radius_mm);
      s.aabb_max = s.center_parent + Eigen::Vector3d::Constant(s.radius_mm);
    }
    I.objects.push_back(std::move(s));
  }
  // Lever arms: joint i (1-based) turns frames i..n about z_{i-1} through o_{i-1}. A point p of
  // a shape in frame f >= i is at |A_i ... A_f p| <= sum_{k=i..f} |t_k| + |p| from o_{i-1}
  // (t_k the translation of A_k, whose length does not depend on a revolute joint's angle).
  // |t_k| from the complete model at the middle of the joint ranges; a prismatic joint's
  // translation grows with q: its largest value over the range. 1% + 1 mm for the effects
  // (thermal expansion, compliance) that change lengths slightly.
  Eigen::VectorXd q_mid(n);
  for (int i = 0; i < n; ++i) q_mid[i] = 0.5 * (robot.nominal.joints[i].lower + robot.nominal.joints[i].upper);
  calib::forwardKinematics(robot, q_mid, calib::PoseContext{}, I.ws);
  std::vector<double> t_len(n + 1, 0.0);
  for (int k = 1; k <= n; ++k) {
    t_len[k] = (I.ws.T_base_frame[k].translation() - I.ws.T_base_frame[k - 1].translation()).norm();
    const calib::JointSpec& j = robot.nominal.joints[k - 1];
    if (j.type == calib::JointType::kPrismatic) t_len[k] += 0.5 * (j.upper - j.lower);
    t_len[k] = t_len[k] * 1.01 + 1.0;
  }
  I.lever = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(I.robot_shapes.size()), n);
  for (size_t s = 0; s < I.robot_shapes.size(); ++s) {
    const Impl::Shape& sh = I.robot_shapes[s];
    const double far = sh.center_parent.norm() + sh.radius_mm;
    for (int i = 1; i <= sh.frame; ++i) {
      if (robot.nominal.joints[i - 1].type == calib::JointType::kPrismatic) {
        I.lever(static_cast<Eigen::Index>(s), i - 1) = 1.0;
        continue;
      }
      double sum = far;
      for (int k = i; k <= sh.frame; ++k) sum += t_len[k];
      I.lever(static_cast<Eigen::Index>(s), i - 1) = sum;
    }
  }
}

CellGeometry::~CellGeometry() = default;
CellGeometry::CellGeometry(const CellGeometry& other) : impl_(std::make_unique<Impl>(*other.impl_)) {}

bool CellGeometry::madeFor(const Cell& cell, const calib::RobotModel& robot) const {
  const Impl& I = *impl_;
  if (robot.dof() != I.robot.dof()) return false;
  if (robotShapes() != static_cast<int>(cell.link_shapes.size() + cell.tool_shapes.size()) || objects() != static_cast<int>(cell.objects.size()))
    return false;
  const int n = robot.dof();
  Eigen::VectorXd q_mid(n);
  for (int i = 0; i < n; ++i) q_mid[i] = 0.5 * (robot.nominal.joints[i].lower + robot.nominal.joints[i].upper);
  calib::KinematicWorkspace a, b;
  calib::forwardKinematics(robot, q_mid, calib::PoseContext{}, a);
  calib::forwardKinematics(I.robot, q_mid, calib::PoseContext{}, b);
  if (!robot.T_world_base().isApprox(I.robot.T_world_base(), 1e-12) ||
      (robot.T_world_base().translation() - I.robot.T_world_base().translation()).norm() > 1e-9)
    return false;
  for (int k = 0; k <= n; ++k) {
    const Eigen::Isometry3d& Ta = a.T_base_frame[static_cast<size_t>(k)];
    const Eigen::Isometry3d& Tb = b.T_base_frame[static_cast<size_t>(k)];
    if ((Ta.translation() - Tb.translation()).norm() > 1e-9 || (Ta.linear() - Tb.linear()).norm() > 1e-9) return false;
  }
  return true;
}
CellGeometry::CellGeometry(CellGeometry&&) noexcept = default;
CellGeometry& CellGeometry::operator=(CellGeometry&&) noexcept = default;

int CellGeometry::robotShapes() const { return static_cast<int>(impl_->robot_shapes.size()); }
int CellGeometry::objects() const { return static_cast<int>(impl_->objects.size()); }
const std::string& CellGeometry::robotShapeName(int k) const { return impl_->robot_shapes.at(static_cast<size_t>(k)).name; }
const std::string& CellGeometry::objectName(int k) const { return impl_->objects.at(static_cast<size_t>(k)).name; }

double CellGeometry::leverArm(int robot_shape, int joint) const {
  if (robot_shape < 0 || robot_shape >= robotShapes() || joint < 0 || joint >= impl_->robot.dof())
    throw calib::ArgumentError("CellGeometry::leverArm: index out of range");
  return impl_->lever(robot_shape, joint);
}

namespace {

constexpr double kInfMm = std::numeric_limits<double>::infinity();

// The distance of robot shape s (its parent frame at T_world_parent) to the nearest object.
CellGeometry::Distance nearestObject(const CellGeometry::Impl& I, size_t s, const Eigen::Isometry3d& T_world_parent, double exact_below_mm,
                                     long long* queries) {
  using Distance = CellGeometry::Distance;
  using Shape = CellGeometry::Impl::Shape;
  fcl::DistanceRequestd request;
  const Shape& sh = I.robot_shapes[s];
  const Eigen::Vector3d c = T_world_parent * sh.center_parent;
  // objects by their lower bound (bounding sphere to AABB), nearest first
  std::vector<std::pair<double, int>> order;
  order.reserve(I.objects.size());
  for (size_t o = 0; o < I.objects.size(); ++o) {
    const Shape& ob = I.objects[o];
    const Eigen::Vector3d d = (ob.aabb_min - c).cwiseMax(c - ob.aabb_max).cwiseMax(0.0);
    order.emplace_back(std::max(0.0, d.norm() - sh.radius_mm), static_cast<int>(o));
  }
  std::sort(order.begin(), order.end());
  // After each object, best is the exact distance to the objects seen so far when that is
  // below exact_below_mm, else a lower bound of it no smaller than exact_below_mm.
  Distance best;
  best.mm = kInfMm;
  best.robot_shape = static_cast<int>(s);
  const Eigen::Isometry3d T_world_geom = T_world_parent * sh.T_parent_geom;
  for (const auto& [lower, o] : order) {
    if (lower >= best.mm) break;  // this object and the rest are no nearer
    if (lower >= exact_below_mm) {  // this one and the rest are far enough: their bound will do
      best.mm = lower;
      best.object = o;
      best.lower_bound = true;
      break;
    }
    const Shape& ob = I.objects[static_cast<size_t>(o)];
    // The bounded query: FCL's traversal starts from min_distance = cap instead of infinity,
    // so it prunes every bounding volume (and skips every triangle) not nearer than cap. It
    // returns the exact distance when that is below cap (the minimum over the same triangles
    // as the unbounded query: those pruned are not nearer), else cap unchanged: then the
    // object is at least cap away.
    const double cap = std::min(best.mm, exact_below_mm);
    fcl::DistanceResultd result;
    if (cap < kInfMm) result.min_distance = cap;
    fcl::distance(sh.geom.get(), T_world_geom, ob.geom.get(), ob.T_parent_geom, request, result);
    if (queries) ++*queries;
    if (result.min_distance < cap) {  // exact, and nearer than every object before
      best.mm = std::max(0.0, result.min_distance);  // FCL: 0 or negative in contact
      best.object = o;
      best.lower_bound = false;
    } else if (cap < best.mm) {  // at least exact_below_mm away, as every object before
      best.mm = cap;
      best.object = o;
      best.lower_bound = true;
    }
  }
  return best;
}

}  // namespace

std::vector<CellGeometry::Distance> CellGeometry::distances(const Eigen::VectorXd& q, const calib::PoseContext& context, double exact_below_mm,
                                                            long long* queries) const {
  const Impl& I = *impl_;
  calib::forwardKinematics(I.robot, q, context, I.ws);
  const Eigen::Isometry3d T_world_base = I.robot.T_world_base();
  std::vector<Distance> out(I.robot_shapes.size());
  for (size_t s = 0; s < I.robot_shapes.size(); ++s)
    out[s] = nearestObject(I, s, T_world_base * I.ws.T_base_frame[static_cast<size_t>(I.robot_shapes[s].frame)], exact_below_mm, queries);
  return out;
}

CellGeometry::Distance CellGeometry::distance(int robot_shape, const Eigen::VectorXd& q, const calib::PoseContext& context, double exact_below_mm,
                                              long long* queries) const {
  if (robot_shape < 0 || robot_shape >= robotShapes()) throw calib::ArgumentError("CellGeometry::distance: robot shape index out of range");
  const Impl& I = *impl_;
  calib::forwardKinematics(I.robot, q, context, I.ws);
  const size_t s = static_cast<size_t>(robot_shape);
  return nearestObject(I, s, I.robot.T_world_base() * I.ws.T_base_frame[static_cast<size_t>(I.robot_shapes[s].frame)], exact_below_mm, queries);
}

double CellGeometry::sphereDistance(const Eigen::Vector3d& center_world_mm, double radius_mm, int object) const {
  const Impl::Shape& ob = impl_->objects.at(static_cast<size_t>(object));
  fcl::Sphered sphere(radius_mm);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = center_world_mm;
  fcl::DistanceRequestd request;
  fcl::DistanceResultd result;
  return std::max(0.0, fcl::distance(&sphere, T, ob.geom.get(), ob.T_parent_geom, request, result));
}

}  // namespace accura::postproc
