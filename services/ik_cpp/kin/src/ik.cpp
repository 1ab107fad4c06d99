#include "hrc/kin/ik.hpp"

#include <Eigen/Cholesky>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace hrc::kin {
namespace {

using Mat6N = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxDof>;
using MatNN = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxDof, kMaxDof>;

bool finite(const Eigen::Vector3d& v) { return v.allFinite(); }

// Rotation vector (axis * angle) taking the current tool axis z onto the goal axis g.
Eigen::Vector3d axis_error(const Eigen::Vector3d& z, const Eigen::Vector3d& g,
                           const Eigen::Matrix3d& R) {
  const Eigen::Vector3d c = z.cross(g);
  const double s = c.norm();
  const double angle = std::atan2(s, z.dot(g));
  if (s > 1e-12) return c * (angle / s);
  if (angle < 1.0) return Eigen::Vector3d::Zero();
  return R.col(0) * angle;  // opposite: any axis perpendicular to z
}

// Rotation vector of Rg * R^T (world frame).
Eigen::Vector3d pose_error(const Eigen::Matrix3d& R, const Eigen::Matrix3d& Rg) {
  const Eigen::Matrix3d d = Rg * R.transpose();
  const Eigen::Vector3d w(d(2, 1) - d(1, 2), d(0, 2) - d(2, 0), d(1, 0) - d(0, 1));
  const double s = 0.5 * w.norm();
  const double c = 0.5 * (d.trace() - 1.0);
  const double angle = std::atan2(s, c);
  if (s > 1e-9) return w * (0.5 * angle / s);
  if (c > 0) return 0.5 * w;  // small angle: w/2 ~ axis * angle
  // Near pi: axis from the symmetric part.
  const Eigen::AngleAxisd aa(d);
  return aa.axis() * aa.angle();
}

}  // namespace

IkTarget IkTarget::pose(const Eigen::Isometry3d& T) {
  IkTarget t;
  t.mode = TaskMode::Pose;
  t.position = T.translation();
  t.rotation = T.linear();
  t.axis = T.linear().col(2);
  return t;
}

IkTarget IkTarget::position_axis(const Eigen::Vector3d& p, const Eigen::Vector3d& axis) {
  IkTarget t;
  t.mode = TaskMode::PositionAxis;
  t.position = p;
  t.axis = axis.normalized();
  return t;
}

IkTarget IkTarget::position_only(const Eigen::Vector3d& p) {
  IkTarget t;
  t.mode = TaskMode::Position;
  t.position = p;
  return t;
}

const char* to_string(IkStatus s) {
  switch (s) {
    case IkStatus::Ok: return "ok";
    case IkStatus::Unreachable: return "unreachable";
    case IkStatus::InvalidInput: return "invalid input";
  }
  return "?";
}

IkSolver::IkSolver(const RobotModel& model, IkOptions options)
    : model_(model), options_(options), eval_(model.chain()) {
  const int n = model.dof();
  if (n > kMaxDof)
    throw std::invalid_argument("IkSolver: chain has " + std::to_string(n) + " joints, at most " +
                                std::to_string(kMaxDof) + " supported");
  if (!(options_.position_tolerance > 0) || !(options_.angle_tolerance > 0) ||
      options_.max_iterations < 1 || options_.max_restarts < 0 || !(options_.rotation_weight > 0) ||
      !(options_.max_step > 0))
    throw std::invalid_argument(
        "IkSolver: tolerances, weights and step must be > 0, iterations >= 1");
  lower_ = model.lower();
  upper_ = model.upper();
  slo_.resize(n);
  shi_.resize(n);
  for (int i = 0; i < n; ++i) {
    slo_[i] = model.sample_lower(i);
    shi_[i] = model.sample_upper(i);
  }
  if (options_.use_analytic) analytic_ = Arm5Analytic::detect(model_, eval_);
}

void IkSolver::errors(const IkTarget& target, const double* q, double& pos_err,
                      double& ang_err) const {
  Eigen::Matrix3d R;
  Eigen::Vector3d p;
  eval_.fk(q, R, p);
  pos_err = (target.position - p).norm();
  switch (target.mode) {
    case TaskMode::Position: ang_err = 0.0; break;
    case TaskMode::PositionAxis: ang_err = axis_angle(R.col(2), target.axis); break;
    case TaskMode::Pose: ang_err = rotation_angle(R, target.rotation); break;
  }
}

double IkSolver::cost(const IkTarget& target, const Eigen::Matrix3d& R, const Eigen::Vector3d& p,
                      Eigen::Matrix<double, 6, 1>& e, double& pos_err, double& ang_err) const {
  e.head<3>() = target.position - p;
  pos_err = e.head<3>().norm();
  const double w = options_.rotation_weight;
  switch (target.mode) {
    case TaskMode::Position:
      ang_err = 0.0;
      e.tail<3>().setZero();
      break;
    case TaskMode::PositionAxis: {
      const Eigen::Vector3d r = axis_error(R.col(2), target.axis, R);
      ang_err = r.norm();
      // Express in the plane perpendicular to the tool axis (rotation about it is free).
      e[3] = w * R.col(0).dot(r);
      e[4] = w * R.col(1).dot(r);
      e[5] = 0.0;
      break;
    }
    case TaskMode::Pose: {
      const Eigen::Vector3d r = pose_error(R, target.rotation);
      ang_err = r.norm();
      e.tail<3>() = w * r;
      break;
    }
  }
  return 0.5 * e.squaredNorm();
}

bool IkSolver::descend(const IkTarget& target, JointVec& q, int& iterations, double& best_cost) {
  const int n = model_.dof();
  const int m = target.mode == TaskMode::Position       ? 3
                : target.mode == TaskMode::PositionAxis ? 5
                                                        : 6;
  const double w = options_.rotation_weight;
  Eigen::Matrix3d R, Rn;
  Eigen::Vector3d p, pn;
  Jacobian6 J, Jn;
  Eigen::Matrix<double, 6, 1> e, en;
  Mat6N A(m, n);
  MatNN H(n, n);
  JointVec g(n), dq(n), qn(n);
  Eigen::LLT<MatNN> llt(n);
  double pos_err = 0, ang_err = 0, pe = 0, ae = 0;

  eval_.fk_jacobian(q.data(), R, p, J);
  double c = cost(target, R, p, e, pos_err, ang_err);
  int slow = 0;
  for (int it = 0; it < options_.max_iterations; ++it) {
    best_cost = c;
    if (pos_err <= options_.position_tolerance && ang_err <= options_.angle_tolerance) return true;
    ++iterations;
    // Weighted task-space Jacobian rows.
    A.topRows<3>() = J.topRows<3>();
    if (target.mode == TaskMode::PositionAxis) {
      A.row(3) = w * (R.col(0).transpose() * J.bottomRows<3>());
      A.row(4) = w * (R.col(1).transpose() * J.bottomRows<3>());
    } else if (target.mode == TaskMode::Pose) {
      A.bottomRows<3>() = w * J.bottomRows<3>();
    }
    // Error-based damping (Sugihara): Gauss-Newton near the goal, gradient-like far away.
    const double lambda = options_.damping * c + 1e-9;
    H.noalias() = A.transpose() * A;
    H.diagonal().array() += lambda;
    g.noalias() = A.transpose() * e.head(m);
    llt.compute(H);
    dq = llt.solve(g);
    // Active set: joints at a limit that the step pushes further out are frozen, and the step is
    // recomputed so the other joints compensate.
    bool locked = false;
    for (int i = 0; i < n; ++i) {
      if ((q[i] <= lower_[i] + 1e-12 && dq[i] < 0) || (q[i] >= upper_[i] - 1e-12 && dq[i] > 0)) {
        H.row(i).setZero();
        H.col(i).setZero();
        H(i, i) = 1.0;
        g[i] = 0.0;
        locked = true;
      }
    }
    if (locked) {
      llt.compute(H);
      dq = llt.solve(g);
    }
    const double big = dq.cwiseAbs().maxCoeff();
    if (!(big < std::numeric_limits<double>::infinity())) return false;
    if (big > options_.max_step) dq *= options_.max_step / big;

    bool accepted = false;
    for (int halving = 0; halving < 4; ++halving) {
      qn = (q + dq).cwiseMax(lower_).cwiseMin(upper_);
      eval_.fk_jacobian(qn.data(), Rn, pn, Jn);
      const double cn = cost(target, Rn, pn, en, pe, ae);
      if (cn < c) {
        slow = (c - cn) < options_.stall_ratio * c ? slow + 1 : 0;
        q = qn;
        R = Rn;
        p = pn;
        J = Jn;
        e = en;
        c = cn;
        pos_err = pe;
        ang_err = ae;
        accepted = true;
        break;
      }
      dq *= 0.5;
    }
    if (!accepted || slow >= options_.stall_count) {
      best_cost = c;
      return pos_err <= options_.position_tolerance && ang_err <= options_.angle_tolerance;
    }
  }
  best_cost = c;
  return pos_err <= options_.position_tolerance && ang_err <= options_.angle_tolerance;
}

bool IkSolver::solve_numeric(const IkTarget& target, const Eigen::VectorXd& seed, IkResult& out) {
  const int n = model_.dof();
  out.analytic = false;
  out.iterations = 0;
  out.restarts = 0;
  rng_.seed(options_.seed);
  JointVec q(n), best(n);
  for (int i = 0; i < n; ++i) q[i] = std::min(std::max(seed[i], lower_[i]), upper_[i]);
  double best_cost = std::numeric_limits<double>::infinity();
  bool ok = false;
  for (int attempt = 0; attempt <= options_.max_restarts; ++attempt) {
    if (attempt > 0) {
      ++out.restarts;
      for (int i = 0; i < n; ++i) {
        std::uniform_real_distribution<double> u(slo_[i], shi_[i]);
        q[i] = u(rng_);
      }
    }
    double c = 0;
    ok = descend(target, q, out.iterations, c);
    if (ok || c < best_cost) {
      best_cost = c;
      best = q;
    }
    if (ok) break;
  }
  out.q.resize(n);
  for (int i = 0; i < n; ++i) out.q[i] = best[i];
  errors(target, out.q.data(), out.position_error, out.angle_error);
  out.status = ok ? IkStatus::Ok : IkStatus::Unreachable;
  return ok;
}

bool IkSolver::solve(const IkTarget& target, const Eigen::VectorXd& seed, IkResult& out) {
  const int n = model_.dof();
  if (seed.size() != n || !seed.allFinite() || !finite(target.position) ||
      !target.rotation.allFinite() || !finite(target.axis) ||
      (target.mode == TaskMode::PositionAxis && std::abs(target.axis.norm() - 1.0) > 1e-6)) {
    out.status = IkStatus::InvalidInput;
    out.q = seed.size() == n && seed.allFinite() ? model_.clamp(seed) : model_.mid_range();
    out.position_error = std::numeric_limits<double>::infinity();
    out.angle_error = std::numeric_limits<double>::infinity();
    out.iterations = out.restarts = 0;
    out.analytic = false;
    return false;
  }
  if (analytic_ && target.mode != TaskMode::Position) {
    out.q.resize(n);
    const Eigen::Vector3d axis =
        target.mode == TaskMode::Pose ? Eigen::Vector3d(target.rotation.col(2)) : target.axis;
    if (analytic_->solve(target.position, axis,
                         target.mode == TaskMode::Pose ? &target.rotation : nullptr, seed.data(),
                         out.q.data())) {
      errors(target, out.q.data(), out.position_error, out.angle_error);
      if (out.position_error <= options_.position_tolerance &&
          out.angle_error <= options_.angle_tolerance) {
        out.status = IkStatus::Ok;
        out.analytic = true;
        out.iterations = 0;
        out.restarts = 0;
        return true;
      }
    }
  }
  return solve_numeric(target, seed, out);
}

IkResult IkSolver::solve(const IkTarget& target, const Eigen::VectorXd& seed) {
  IkResult r;
  solve(target, seed, r);
  return r;
}

void wrap_into_limits(const RobotModel& model, Eigen::VectorXd& q) {
  for (int i = 0; i < model.dof(); ++i) {
    if (!model.revolute(i) || !model.bounded(i) || !std::isfinite(q[i])) continue;
    const double lo = model.lower()[i], hi = model.upper()[i];
    if (q[i] >= lo && q[i] <= hi) continue;
    const double k = std::ceil((lo - q[i]) / (2.0 * M_PI));
    const double c = q[i] + k * 2.0 * M_PI;  // smallest shift at or above lo
    if (c <= hi) q[i] = c;
  }
}

}  // namespace hrc::kin
