#include "hrc/kin/baselines.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace hrc::kin {
namespace {

KDL::JntArray limit_array(const Eigen::VectorXd& v) {
  KDL::JntArray a(static_cast<unsigned>(v.size()));
  for (Eigen::Index i = 0; i < v.size(); ++i)
    a(static_cast<unsigned>(i)) = std::isfinite(v[i]) ? v[i] : (v[i] > 0 ? 1e9 : -1e9);
  return a;
}

}  // namespace

KdlNrJlSolver::KdlNrJlSolver(const RobotModel& model)
    : fk_(std::make_unique<KDL::ChainFkSolverPos_recursive>(model.chain())),
      vel_(std::make_unique<KDL::ChainIkSolverVel_pinv>(model.chain())),
      ik_(std::make_unique<KDL::ChainIkSolverPos_NR_JL>(model.chain(), limit_array(model.lower()),
                                                        limit_array(model.upper()), *fk_, *vel_)),
      q_init_(model.chain().getNrOfJoints()),
      q_out_(model.chain().getNrOfJoints()) {}

int KdlNrJlSolver::solve(const Eigen::Isometry3d& target, const Eigen::VectorXd& seed,
                         Eigen::VectorXd& q_out) {
  q_init_.data = seed;
  const int rc = ik_->CartToJnt(q_init_, to_kdl(target), q_out_);
  q_out = q_out_.data;
  return rc;
}

KdlLmaSolver::KdlLmaSolver(const RobotModel& model)
    : model_(model),
      ik_(std::make_unique<KDL::ChainIkSolverPos_LMA>(model.chain())),
      q_init_(model.chain().getNrOfJoints()),
      q_out_(model.chain().getNrOfJoints()) {}

int KdlLmaSolver::solve(const Eigen::Isometry3d& target, const Eigen::VectorXd& seed,
                        Eigen::VectorXd& q_out) {
  q_init_.data = seed;
  const int rc = ik_->CartToJnt(q_init_, to_kdl(target), q_out_);
  q_out = q_out_.data;
  wrap_into_limits(model_, q_out);
  return rc;
}

GradientDescentSolver::GradientDescentSolver(const RobotModel& model,
                                             GradientDescentOptions options)
    : model_(model), options_(options), eval_(model.chain()) {
  if (model.dof() > kMaxDof) throw std::invalid_argument("GradientDescentSolver: chain too long");
  if (!(options_.delta_deg > 0) || !(options_.learning_rate > 0) || options_.max_sweeps < 1)
    throw std::invalid_argument("GradientDescentSolver: delta, learning rate, sweeps must be > 0");
  sol_deg_.resize(model.dof());
  q_rad_.resize(model.dof());
}

double GradientDescentSolver::error(const IkTarget& target, const double* sol_deg) const {
  const int n = model_.dof();
  double q[kMaxDof];
  for (int i = 0; i < n; ++i) q[i] = model_.revolute(i) ? sol_deg[i] * (M_PI / 180.0) : sol_deg[i];
  Eigen::Matrix3d R;
  Eigen::Vector3d p;
  eval_.fk(q, R, p);
  double f = (p - target.position).norm();  // DistanceFromTarget
  if (target.mode == TaskMode::PositionAxis)
    f += options_.orientation_weight * axis_angle(R.col(2), target.axis);
  else if (target.mode == TaskMode::Pose)
    f += options_.orientation_weight * rotation_angle(R, target.rotation);
  return f;
}

bool GradientDescentSolver::solve(const IkTarget& target, const Eigen::VectorXd& seed,
                                  Eigen::VectorXd& q_out) {
  const int n = model_.dof();
  const auto to_deg = [&](int i, double v) { return model_.revolute(i) ? v * 180.0 / M_PI : v; };
  Eigen::Matrix<double, kMaxDof, 1> lo, hi;
  for (int i = 0; i < n; ++i) {
    sol_deg_[i] = to_deg(i, seed[i]);
    lo[i] = to_deg(i, model_.lower()[i]);
    hi[i] = to_deg(i, model_.upper()[i]);
  }
  double* sol = sol_deg_.data();
  bool done = error(target, sol) <= options_.stop_threshold;
  for (int sweep = 0; sweep < options_.max_sweeps && !done; ++sweep) {
    // One frame of the thesis's ApproachTarget: joints from the last to the first.
    for (int i = n - 1; i >= 0; --i) {
      const double saved = sol[i];
      const double f_x = error(target, sol);
      sol[i] += options_.delta_deg;
      const double f_x_plus_h = error(target, sol);
      sol[i] = saved;
      const double gradient = (f_x_plus_h - f_x) / options_.delta_deg;
      sol[i] -= options_.learning_rate * gradient;
      sol[i] = std::min(std::max(sol[i], lo[i]), hi[i]);  // ClampAngle
      if (error(target, sol) <= options_.stop_threshold) {
        done = true;
        break;
      }
    }
  }
  q_out.resize(n);
  for (int i = 0; i < n; ++i) q_out[i] = model_.revolute(i) ? sol[i] * M_PI / 180.0 : sol[i];
  return done;
}

}  // namespace hrc::kin
