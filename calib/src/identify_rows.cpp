// accura: the residual stacking of the identification (identify_internal.h): every row's
// weighted residual and Jacobian, on the kinematic core prepared once per evaluation point.
#include "identify_internal.h"

#include "accura/calib/errors.h"
#include "accura/calib/geometry.h"
#include "accura/calib/joint_map.h"

namespace accura::calib::identify_detail {

Eigen::Isometry3d Stations::transform(const std::vector<double>& x, int s) const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (s <= 0) return T;
  const size_t o = offset + 6 * static_cast<size_t>(s - 1);
  T.linear() = expSO3(Eigen::Vector3d(x[o + 3], x[o + 4], x[o + 5]));
  T.translation() = Eigen::Vector3d(x[o], x[o + 1], x[o + 2]);
  return T;
}

JacobianPlan makePlan(const RobotModel& model, const std::vector<ParamInfo>& layout) {
  JacobianPlan plan;
  plan.P = layout.size();
  plan.map_x.resize(static_cast<size_t>(model.dof()));
  for (size_t k = 0; k < layout.size(); ++k) {
    const ParamInfo& p = layout[k];
    if (p.kind == ParamKind::kJointMap) {
      std::vector<int>& mx = plan.map_x[static_cast<size_t>(p.joint)];
      const size_t K = model.deviations.joint_map[static_cast<size_t>(p.joint)].coef.size();
      if (mx.empty()) {
        mx.assign(K, -1);
        const bool revolute = model.nominal.joints[static_cast<size_t>(p.joint)].type == JointType::kRevolute;
        // the joint's own motion per unit dtheta (revolute) or dd (prismatic; the thermal length
        // scale of the dd column is 1 + O(1e-4): only the Jacobian, not the residual, sees it)
        plan.columns.push_back({revolute ? ParamKind::kOffset : ParamKind::kD, p.joint, "map_unit", "joint_map", "", 1.0});
        plan.x_of.push_back(-1);
        plan.unit_joint.push_back(p.joint);
      }
      mx[static_cast<size_t>(p.index)] = static_cast<int>(k);
      continue;
    }
    plan.columns.push_back(p);
    plan.x_of.push_back(static_cast<int>(k));
    plan.unit_joint.push_back(-1);
  }
  return plan;
}

RowStack::RowStack(const RobotModel& model, const JacobianPlan& plan, const Stations& stations)
    : model_(&model), km_(model), plan_(plan), st_(stations) {
  direct_ = plan.columns.size() == plan.P;
  for (size_t c = 0; c < plan.x_of.size() && direct_; ++c) direct_ = plan.x_of[c] == static_cast<int>(c);
}

void RowStack::prepare(const RobotModel& model) {
  model_ = &model;
  km_ = KinematicModel(model);
}

Eigen::Isometry3d RowStack::pose(const std::vector<double>& x, const Measurement& row, size_t i, bool jacobian) {
  if (row.q.size() != km_.dof())
    throw ArgumentError("expected " + std::to_string(km_.dof()) + " joint values, got " + std::to_string(row.q.size()));
  const int s = st_.of_row[i];
  const Eigen::Index P = static_cast<Eigen::Index>(plan_.P);
  if (!jacobian) {
    // through the base frame like the parameter Jacobian (the same bits: Ceres' last steps
    // compare costs at the rounding level)
    km_.evaluate(row.q.data(), row.context, f_, nullptr, &links_);
  } else {
    if (direct_ && s == 0 && x.size() == plan_.P) {
      // the columns are x's own: the core writes J directly
      km_.parameterJacobian(plan_.columns, row.q.data(), row.context, f_, links_, J_);
      return f_.T_world_tcp;
    }
    km_.parameterJacobian(plan_.columns, row.q.data(), row.context, f_, links_, Jcols_);
    J_.setZero(6, static_cast<Eigen::Index>(x.size()));
    for (size_t c = 0; c < plan_.columns.size(); ++c) {
      if (plan_.x_of[c] >= 0) {
        J_.col(plan_.x_of[c]) = Jcols_.col(static_cast<Eigen::Index>(c));
        continue;
      }
      const int j = plan_.unit_joint[c];
      double w[4];
      const int first = jointMapBasis(model_->deviations.joint_map[static_cast<size_t>(j)], row.q[j], w);
      for (int k = 0; k < 4; ++k) {
        const int xi = plan_.map_x[static_cast<size_t>(j)][static_cast<size_t>(first + k)];
        if (xi >= 0) J_.col(xi) = Jcols_.col(static_cast<Eigen::Index>(c)) * w[k];
      }
    }
  }
  Eigen::Isometry3d T = f_.T_world_tcp;
  if (s == 0) return T;
  const Eigen::Isometry3d Ts = st_.transform(x, s);
  T = Ts * T;
  if (jacobian) stationColumns(x, s, Ts, T, J_, P, static_cast<Eigen::Index>(st_.offset) + 6 * (s - 1));
  return T;
}

void RowStack::stationColumns(const std::vector<double>& x, int s, const Eigen::Isometry3d& Ts, const Eigen::Isometry3d& T,
                              Eigen::MatrixXd& J, Eigen::Index model_cols, Eigen::Index c) const {
  const Eigen::Matrix3d R = Ts.linear();
  J.topLeftCorner(3, model_cols) = (R * J.topLeftCorner(3, model_cols)).eval();
  J.block(3, 0, 3, model_cols) = (R * J.block(3, 0, 3, model_cols)).eval();
  J.block<3, 3>(0, c).setIdentity();
  const size_t o = st_.offset + 6 * static_cast<size_t>(s - 1);
  // expSO3(w + dw) = expSO3(Jl dw) expSO3(w), Jl(w) = Jr(w)^T: a rotation about Jl e_k through t_s
  const Eigen::Matrix3d Jl = rightJacobianSO3(Eigen::Vector3d(x[o + 3], x[o + 4], x[o + 5])).transpose();
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d u = Jl.col(k);
    J.block<3, 1>(0, c + 3 + k) = u.cross(T.translation() - Ts.translation());
    J.block<3, 1>(3, c + 3 + k) = u;
  }
}

Eigen::Isometry3d RowStack::poseCompact(const std::vector<double>& x, const Measurement& row, size_t i) {
  if (row.q.size() != km_.dof())
    throw ArgumentError("expected " + std::to_string(km_.dof()) + " joint values, got " + std::to_string(row.q.size()));
  const int s = st_.of_row[i];
  km_.parameterJacobian(plan_.columns, row.q.data(), row.context, f_, links_, Jcols_);
  Eigen::Index n = 0;
  for (size_t c = 0; c < plan_.columns.size(); ++c) n += plan_.x_of[c] >= 0 ? 1 : 4;
  Jc_.setZero(6, n + (s > 0 ? 6 : 0));
  idx_.clear();
  for (size_t c = 0; c < plan_.columns.size(); ++c) {
    if (plan_.x_of[c] >= 0) {
      Jc_.col(static_cast<Eigen::Index>(idx_.size())) = Jcols_.col(static_cast<Eigen::Index>(c));
      idx_.push_back(plan_.x_of[c]);
      continue;
    }
    const int j = plan_.unit_joint[c];
    double w[4];
    const int first = jointMapBasis(model_->deviations.joint_map[static_cast<size_t>(j)], row.q[j], w);
    for (int k = 0; k < 4; ++k) {
      // a coefficient outside the layout: a zero column that nothing reads
      Jc_.col(static_cast<Eigen::Index>(idx_.size())) = Jcols_.col(static_cast<Eigen::Index>(c)) * w[k];
      idx_.push_back(plan_.map_x[static_cast<size_t>(j)][static_cast<size_t>(first + k)]);
    }
  }
  Eigen::Isometry3d T = f_.T_world_tcp;
  if (s == 0) return T;
  const Eigen::Isometry3d Ts = st_.transform(x, s);
  T = Ts * T;
  for (int k = 0; k < 6; ++k) idx_.push_back(static_cast<int>(st_.offset) + 6 * (s - 1) + k);
  stationColumns(x, s, Ts, T, Jc_, n, n);
  return T;
}

void RowStack::stack(const std::vector<double>& x, const MeasurementSet& data, const std::vector<RowWeights>& weights,
                     Eigen::MatrixXd* J, Eigen::VectorXd* r) {
  Eigen::Index m = 0;
  for (const RowWeights& w : weights) m += w.dim;
  if (J) J->resize(m, static_cast<Eigen::Index>(x.size()));
  if (r) r->resize(m);
  Eigen::Index row = 0;
  for (size_t i = 0; i < data.rows.size(); ++i) {
    const Measurement& meas = data.rows[i];
    const Eigen::Isometry3d T = pose(x, meas, i, J != nullptr);
    const int dim = weights[i].dim;
    if (J) J->middleRows(row, dim) = weights[i].w.head(dim).asDiagonal() * J_.topRows(dim);
    if (r) r->segment(row, dim) = weights[i].w.cwiseProduct(rowError(T, meas, dim)).head(dim);
    row += dim;
  }
}

Vector6d rowError(const Eigen::Isometry3d& T, const Measurement& row, int dim) {
  Vector6d e = Vector6d::Zero();
  e.head<3>() = T.translation() - row.p_world_mm;
  if (dim == 6) e.tail<3>() = logSO3(T.linear() * row.R_world_tcp.toRotationMatrix().transpose());
  return e;
}

MeasurementSet inStationZero(const MeasurementSet& data, const Stations& st, const std::vector<double>& x) {
  MeasurementSet out = data;
  for (size_t i = 0; i < out.rows.size(); ++i) {
    if (st.of_row[i] == 0) continue;
    const Eigen::Isometry3d Tinv = st.transform(x, st.of_row[i]).inverse();
    Measurement& m = out.rows[i];
    m.p_world_mm = Tinv * m.p_world_mm;
    m.R_world_tcp = Eigen::Quaterniond(Tinv.linear() * m.R_world_tcp.toRotationMatrix()).normalized();
  }
  return out;
}

}  // namespace accura::calib::identify_detail
