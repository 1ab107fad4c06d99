// State and execution of the motion generator: reset, IK of a pose, the TCP, holding and
// stopping, the speed scale and the per-tick step along the planned segments.
#include "hrc/kin/motion.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include "motion_detail.hpp"

namespace hrc::kin {

using motion_detail::finite;
using motion_detail::kSampleTolerance;

const char* to_string(MotionStatus s) {
  switch (s) {
    case MotionStatus::Idle: return "idle";
    case MotionStatus::Moving: return "moving";
    case MotionStatus::Reached: return "reached";
    case MotionStatus::Holding: return "holding";
    case MotionStatus::Unreachable: return "unreachable";
  }
  return "?";
}

const char* to_string(MotionKind k) {
  switch (k) {
    case MotionKind::None: return "none";
    case MotionKind::Linear: return "linear";
    case MotionKind::Joint: return "joint";
    case MotionKind::Via: return "via";
  }
  return "?";
}

MotionGenerator::MotionGenerator(const RobotModel& model, const Eigen::Isometry3d& world_T_base,
                                 double dt, MotionLimits limits, IkOptions ik_options)
    : model_(model),
      world_T_base_(world_T_base),
      base_T_world_(world_T_base.inverse()),
      dt_(dt),
      limits_(limits),
      ik_(model, ik_options) {
  if (!(dt > 0) || !finite(dt)) throw std::invalid_argument("MotionGenerator: dt must be > 0");
  if (!(limits.max_tcp_speed > 0) || !(limits.max_tcp_accel > 0) || !(limits.max_tcp_jerk > 0) ||
      !(limits.reach_tolerance > 0) || !(limits.rotation_length > 0) || !(limits.check_step > 0))
    throw std::invalid_argument(
        "MotionGenerator: max_tcp_speed, max_tcp_accel, max_tcp_jerk, reach_tolerance, "
        "rotation_length and check_step must be > 0");
  if (!world_T_base.matrix().allFinite())
    throw std::invalid_argument("MotionGenerator: base pose is not finite");
  reset(model.mid_range());
}

void MotionGenerator::reset(const Eigen::VectorXd& q) {
  if (q.size() != model_.dof() || !q.allFinite())
    throw std::invalid_argument("MotionGenerator::reset: expected " + std::to_string(model_.dof()) +
                                " finite joint values");
  state_.q = model_.clamp(q);
  segments_.clear();
  seg_t_ = 0.0;
  time_scale_ = 1.0;
  v_cmd_.setZero();
  meas_speed_ = 0.0;
  state_.status = MotionStatus::Idle;
  state_.kind = MotionKind::None;
  state_.detail.clear();
  update_tcp(0.0);
  target_ = state_.tcp.translation();
  base_.reset();
}

bool MotionGenerator::solve_pose(const Eigen::Vector3d& p_world, const Eigen::Matrix3d& R_world,
                                 const Eigen::VectorXd& seed, IkResult& res) {
  IkTarget t;
  t.mode = TaskMode::Pose;
  t.position = base_T_world_ * p_world;
  t.rotation = base_T_world_.linear() * R_world;
  t.axis = t.rotation.col(2);
  if (ik_.solve(t, seed, res)) return true;
  if (model_.dof() < 6) {
    // A 5-DOF chain may not reach every yaw: the yaw is a wish, the tool axis is not.
    t.mode = TaskMode::PositionAxis;
    return ik_.solve(t, seed, res);
  }
  return false;
}

bool MotionGenerator::reset_to_pose(const Eigen::Vector3d& position, double yaw) {
  if (!position.allFinite() || !finite(yaw)) return false;
  IkResult res;
  if (!solve_pose(position, tool_down_rotation(yaw), model_.mid_range(), res)) return false;
  reset(res.q);
  rest_ = res.q;
  return true;
}

bool MotionGenerator::reachable(const Eigen::Vector3d& position, double yaw,
                                double* position_error) {
  if (!position.allFinite() || !finite(yaw)) {
    if (position_error) *position_error = std::numeric_limits<double>::infinity();
    return false;
  }
  IkResult res;
  bool ok = solve_pose(position, tool_down_rotation(yaw), state_.q, res);
  if (!ok) ok = solve_pose(position, tool_down_rotation(yaw), model_.mid_range(), res);
  if (position_error) *position_error = res.position_error;
  return ok;
}

void MotionGenerator::update_tcp(double dt_for_speed) {
  Eigen::Matrix3d R;
  Eigen::Vector3d p;
  ik_.eval().fk(state_.q.data(), R, p);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = p;
  const Eigen::Vector3d prev = state_.tcp.translation();
  state_.tcp = world_T_base_ * T;
  state_.tcp_speed =
      dt_for_speed > 0 ? (state_.tcp.translation() - prev).norm() / dt_for_speed : 0.0;
}

void MotionGenerator::stop_with(MotionStatus status, const std::string& detail) {
  ProfileLimits lim{limits_.max_tcp_speed, limits_.max_tcp_accel, limits_.max_tcp_jerk};
  brake_segment(lim);
  final_status_ = status;
  state_.status = status;
  state_.detail = detail;
}

void MotionGenerator::hold() {
  if (base_) {
    leave();
    final_status_ = MotionStatus::Holding;
    state_.status = MotionStatus::Holding;
    state_.detail.clear();
    return;
  }
  stop_with(MotionStatus::Holding, "");
}

void MotionGenerator::set_speed_scale(double scale) {
  scale_target_ = std::isfinite(scale) ? std::clamp(scale, 0.0, 1.0) : 0.0;
}

uint64_t MotionGenerator::min_ticks_to_end() const {
  // A tick margin against rounding: the bound must not exceed the true count.
  constexpr double kMargin = 1e-6;
  uint64_t ticks = 0;
  double t = seg_t_;
  for (const Segment& seg : segments_) {
    const double left = std::max(0.0, seg.profile.duration() - t) / dt_ - kMargin;
    ticks += std::max<uint64_t>(1, static_cast<uint64_t>(std::max(0.0, std::ceil(left))));
    t = 0.0;
  }
  return ticks;
}

Eigen::MatrixXd MotionGenerator::joint_speed_fractions(std::size_t max_ticks,
                                                       bool& complete) const {
  SpeedForecast f = speed_forecast(max_ticks);
  complete = f.complete;
  return std::move(f.joint_fractions);
}

MotionGenerator::SpeedForecast MotionGenerator::speed_forecast(std::size_t max_ticks) const {
  constexpr double kNoLimit = 2.0 * M_PI;  // rad/s: the same rule as the physics's arm bound
  const Eigen::VectorXd& vlim = model_.max_velocity();
  const Eigen::ArrayXd max_step =
      vlim.unaryExpr([](double v) { return std::isfinite(v) ? v : kNoLimit; }).array() * dt_;
  const int dof = model_.dof();
  std::vector<Eigen::VectorXd> fractions, linear, angular;
  std::vector<Eigen::Isometry3d> X0, X1;
  MotionGenerator sim(*this);
  SpeedForecast out;
  model_.joint_child_frames(sim.state_.q, X0);
  while (fractions.size() < max_ticks) {
    if (sim.segments_.empty()) {
      out.complete = true;  // step() no longer changes q
      break;
    }
    const Eigen::VectorXd q0 = sim.state_.q;
    sim.step();
    fractions.emplace_back((sim.state_.q - q0).array().abs() / max_step);
    if (sim.scale_ == 0.0 && sim.scale_target_ == 0.0 && sim.state_.q == q0) {
      // stopped by a speed scale of 0 (SSM's protective stop): nothing moves until a command
      out.complete = true;
      linear.emplace_back(Eigen::VectorXd::Zero(dof));
      angular.emplace_back(Eigen::VectorXd::Zero(dof));
      break;
    }
    model_.joint_child_frames(sim.state_.q, X1);
    Eigen::VectorXd v(dof), w(dof);
    for (int j = 0; j < dof; ++j) {
      const auto i = static_cast<std::size_t>(j);
      v[j] = (X1[i].translation() - X0[i].translation()).norm() / dt_;
      w[j] = Eigen::AngleAxisd(X0[i].linear().transpose() * X1[i].linear()).angle() / dt_;
    }
    linear.push_back(std::move(v));
    angular.push_back(std::move(w));
    std::swap(X0, X1);
  }
  const auto rows = static_cast<Eigen::Index>(fractions.size());
  out.joint_fractions.resize(rows, dof);
  out.link_linear.resize(rows, dof);
  out.link_angular.resize(rows, dof);
  for (Eigen::Index i = 0; i < rows; ++i) {
    const auto k = static_cast<std::size_t>(i);
    out.joint_fractions.row(i) = fractions[k].transpose();
    out.link_linear.row(i) = linear[k].transpose();
    out.link_angular.row(i) = angular[k].transpose();
  }
  return out;
}

const MotionState& MotionGenerator::step() {
  // The applied scale moves towards the requested one by at most a dt / v_max per tick: the
  // change of speed it causes, v_nominal x d(scale)/dt, then stays below the acceleration limit.
  const double max_dscale = limits_.max_tcp_accel * dt_ / limits_.max_tcp_speed;
  scale_ += std::clamp(scale_target_ - scale_, -max_dscale, max_dscale);
  if (segments_.empty()) {
    v_cmd_.setZero();
    meas_speed_ = 0.0;
    update_tcp(dt_);
    return state_;
  }
  Segment& seg = segments_.front();
  const Eigen::VectorXd& vlim = model_.max_velocity();
  // Recover from a joint-limit slow-down no faster than the TCP acceleration limit allows.
  double sigma = std::min(
      1.0, time_scale_ + seg.limits.max_accel * dt_ / std::max(seg.limits.max_speed, 1e-3));
  double t_new = seg_t_, s = 0, vs = 0;
  bool clipped = false;
  constexpr int kTries = 5;
  for (int attempt = 0; attempt < kTries; ++attempt) {
    t_new = seg_t_ + sigma * scale_ * dt_;
    seg.profile.eval(t_new, s, vs);
    // The planned (checked, sampled) path itself. A line is refined to the exact straight line
    // by IK seeded from the samples; where that fails or lands on another branch, the samples
    // are the path (they were checked): the arm never stops for want of a solution.
    const double m = seg.m_start + s;
    const Eigen::VectorXd q_path = joint_at(seg, m);
    ik_res_.q = q_path;
    if (!seg.joint && s < seg.profile.length()) {  // a segment ends on its own samples
      const double f = seg.prof_length > 0 ? (m - seg.measure.front()) / seg.prof_length : 1.0;
      const Eigen::Vector3d p = seg.p0 + seg.u * (f * seg.lin_length);
      const Eigen::Matrix3d R = seg.r0.slerp(f, seg.r1).toRotationMatrix();
      IkResult exact;
      if (solve_pose(p, R, q_path, exact) &&
          (exact.q - q_path).cwiseAbs().maxCoeff() < kSampleTolerance)
        ik_res_.q = exact.q;
    }
    double ratio = 0.0;
    for (int i = 0; i < model_.dof(); ++i)
      ratio = std::max(ratio, std::abs(ik_res_.q[i] - state_.q[i]) / (vlim[i] * dt_));
    if (ratio <= 1.0) break;
    if (attempt == kTries - 1) {
      // The solution moved discontinuously: approach it at the joint velocity limits and do not
      // advance along the path this tick.
      for (int i = 0; i < model_.dof(); ++i) {
        const double lim = vlim[i] * dt_;
        ik_res_.q[i] = state_.q[i] + std::clamp(ik_res_.q[i] - state_.q[i], -lim, lim);
      }
      t_new = seg_t_;
      clipped = true;
      break;
    }
    sigma /= ratio * 1.02;
  }
  state_.q = ik_res_.q;
  time_scale_ = sigma;
  seg_t_ = t_new;
  const bool joint = seg.joint;
  const Eigen::Vector3d p_before = state_.tcp.translation();
  const double lin_speed = seg.prof_length > 0 ? vs * seg.lin_length / seg.prof_length : 0.0;
  v_cmd_ = clipped ? Eigen::Vector3d::Zero() : Eigen::Vector3d(seg.u * (lin_speed * sigma));
  meas_speed_ = !clipped ? vs * sigma : 0.0;
  if (base_ && (base_->trail.empty() || base_->trail.back() != state_.q))
    base_->trail.push_back(state_.q);
  if (seg_t_ >= seg.profile.duration()) {
    const Mark mark = seg.mark;
    segments_.pop_front();
    seg_t_ = 0.0;
    meas_speed_ = 0.0;
    if (mark != Mark::None) segment_done_mark(mark, std::nullopt);
    if (segments_.empty()) {
      v_cmd_.setZero();
      state_.status = final_status_;
    }
  }
  update_tcp(dt_);
  if (joint && !segments_.empty() && segments_.front().joint && meas_speed_ > 0) {
    v_cmd_ = (state_.tcp.translation() - p_before) / dt_;  // the TCP's velocity along the FK path
  } else if (joint) {
    v_cmd_.setZero();
  }
  if (segments_.empty() && final_status_ == MotionStatus::Reached) {
    const double err = (state_.tcp.translation() - target_).norm();
    if (err > limits_.reach_tolerance) {
      state_.status = MotionStatus::Unreachable;
      state_.detail = "ended " + std::to_string(err) + " m from the target";
    }
  }
  return state_;
}

}  // namespace hrc::kin
