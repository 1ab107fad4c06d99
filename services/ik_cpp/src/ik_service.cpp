// The service logic of hrc-ik (IkEngine, IkService; interface: include/hrc/ik_service.hpp).
// Why one file of over 600 lines: the engine's tick (commands in, motion generators stepped,
// states out) and the service's handlers share the per-robot state; the motion itself is
// hrc_kin's (kin/src/motion*.cpp).
#include "hrc/ik_service.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <thread>
#include <utility>

namespace hrc {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

std::string fmt_point(const Eigen::Vector3d& p) {
  return "(" + fmt(p.x()) + ", " + fmt(p.y()) + ", " + fmt(p.z()) + ")";
}

Eigen::Vector3d vec(const v2::Vec3& v) { return {v.x(), v.y(), v.z()}; }

v2::MotionKind to_wire(kin::MotionKind k) {
  switch (k) {
    case kin::MotionKind::None: return v2::MOTION_KIND_UNSPECIFIED;
    case kin::MotionKind::Linear: return v2::MOTION_KIND_LINEAR;
    case kin::MotionKind::Joint: return v2::MOTION_KIND_JOINT;
    case kin::MotionKind::Via: return v2::MOTION_KIND_VIA;
  }
  return v2::MOTION_KIND_UNSPECIFIED;
}

v2::MotionStatus to_wire(kin::MotionStatus s) {
  switch (s) {
    case kin::MotionStatus::Idle: return v2::MOTION_STATUS_IDLE;
    case kin::MotionStatus::Moving: return v2::MOTION_STATUS_MOVING;
    case kin::MotionStatus::Reached: return v2::MOTION_STATUS_REACHED;
    case kin::MotionStatus::Holding: return v2::MOTION_STATUS_HOLDING;
    case kin::MotionStatus::Unreachable: return v2::MOTION_STATUS_UNREACHABLE;
  }
  return v2::MOTION_STATUS_UNSPECIFIED;
}

double micros_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

// ---------------------------------------------------------------- scenario -> robots

std::vector<RobotSpec> robots_from_scenario(const v2::Scenario& scenario) {
  std::vector<RobotSpec> out;  // no robots is allowed: the service then only keeps the clock
  std::set<std::string> seen;
  for (const v2::RobotConfig& r : scenario.robots()) {
    const std::string who = "robot '" + r.id() + "'";
    try {
      check_name("robot id", r.id());  // it becomes a key segment
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(who + ": " + e.what());
    }
    if (!seen.insert(r.id()).second) throw std::invalid_argument(who + " is listed twice");
    if (r.urdf_path().empty()) throw std::invalid_argument(who + ": urdf_path is empty");
    if (!(r.max_tcp_speed() > 0) || !std::isfinite(r.max_tcp_speed())) {
      throw std::invalid_argument(who + ": max_tcp_speed must be > 0, got " +
                                  fmt(r.max_tcp_speed()));
    }
    const Eigen::Vector3d base = vec(r.base().xyz());
    const Eigen::Vector3d home = vec(r.home());
    if (!base.allFinite() || !std::isfinite(r.base().yaw_deg())) {
      throw std::invalid_argument(who + ": base pose has a NaN or infinite value");
    }
    if (!home.allFinite()) throw std::invalid_argument(who + ": home has a NaN or infinite value");
    RobotSpec s;
    s.id = r.id();
    s.urdf_path = r.urdf_path();
    if (!r.base_link().empty()) s.base_link = r.base_link();
    if (!r.tip_link().empty()) s.tip_link = r.tip_link();
    if (r.has_tcp()) {
      const Eigen::Vector3d p = vec(r.tcp().position());
      const v2::Quat& q = r.tcp().orientation();
      const Eigen::Quaterniond rot(q.w(), q.x(), q.y(), q.z());
      if (!p.allFinite() || !(rot.norm() > 0.5) || !std::isfinite(rot.norm())) {
        throw std::invalid_argument(who + ": tcp has a NaN, infinite or zero-length value");
      }
      s.tip_T_tcp = Eigen::Isometry3d::Identity();
      s.tip_T_tcp.linear() = rot.normalized().toRotationMatrix();
      s.tip_T_tcp.translation() = p;
    }
    s.world_T_base.translation() = base;
    s.world_T_base.linear() =
        Eigen::AngleAxisd(r.base().yaw_deg() * kDegToRad, Eigen::Vector3d::UnitZ())
            .toRotationMatrix();
    s.max_tcp_speed = r.max_tcp_speed();
    s.home = home;
    if (r.has_gripper()) {
      s.gripper_joints.assign(r.gripper().joints().begin(), r.gripper().joints().end());
      s.gripper_open = r.gripper().open();
      s.gripper_closed = r.gripper().closed();
      if (!std::isfinite(s.gripper_open) || !std::isfinite(s.gripper_closed))
        throw std::invalid_argument(who + ": gripper open/closed is NaN or infinite");
    }
    out.push_back(std::move(s));
  }
  return out;
}

double tick_dt(const v2::Scenario& scenario) {
  const double hz = scenario.info().tick_hz();
  if (!(hz > 0) || !std::isfinite(hz)) {
    throw std::invalid_argument("scenario info.tick_hz must be > 0, got " + fmt(hz));
  }
  return 1.0 / hz;
}

// ---------------------------------------------------------------- engine

IkEngine::IkEngine(std::vector<RobotSpec> robots, double dt) : dt_(dt) {
  if (!(dt > 0) || !std::isfinite(dt)) throw std::invalid_argument("IkEngine: dt must be > 0");
  std::sort(robots.begin(), robots.end(),
            [](const RobotSpec& a, const RobotSpec& b) { return a.id < b.id; });
  for (RobotSpec& spec : robots) {
    if (!ids_.empty() && ids_.back() == spec.id)
      throw std::invalid_argument("robot '" + spec.id + "' is listed twice");
    Arm arm;
    try {
      arm.model = std::make_unique<kin::RobotModel>(
          kin::RobotModel::from_urdf_file(spec.urdf_path, spec.base_link, spec.tip_link));
      if (!spec.tip_T_tcp.isApprox(Eigen::Isometry3d::Identity()))
        arm.model->attach_tcp(spec.tip_T_tcp);
    } catch (const std::exception& e) {
      throw std::runtime_error("robot '" + spec.id + "': " + e.what());
    }
    kin::MotionLimits limits;
    limits.max_tcp_speed = spec.max_tcp_speed;
    arm.motion = std::make_unique<kin::MotionGenerator>(*arm.model, spec.world_T_base, dt, limits);
    arm.probe = std::make_unique<kin::MotionGenerator>(*arm.model, spec.world_T_base, dt, limits);
    if (!arm.motion->reset_to_pose(spec.home, kHomeYaw)) {
      throw std::runtime_error("robot '" + spec.id + "': home " + fmt_point(spec.home) +
                               " is not reachable with the tool pointing down (URDF " +
                               spec.urdf_path + ")");
    }
    arm.probe->reset(arm.motion->state().q);
    const auto fingers = static_cast<Eigen::Index>(spec.gripper_joints.size());
    arm.grip = Eigen::VectorXd::Constant(fingers, spec.gripper_open);
    arm.grip_target = arm.grip;
    arm.grip_step.resize(fingers);
    for (Eigen::Index k = 0; k < fingers; ++k) {
      const std::string& name = spec.gripper_joints[static_cast<std::size_t>(k)];
      const auto limit = arm.model->joint_limit(name);
      if (!limit) {
        throw std::runtime_error("robot '" + spec.id + "': gripper joint '" + name +
                                 "' is not a revolute or prismatic joint with limits in " +
                                 spec.urdf_path);
      }
      // A finger without a velocity limit closes in 0.5 s.
      const double v = std::isfinite(limit->velocity)
                           ? limit->velocity
                           : std::abs(spec.gripper_open - spec.gripper_closed) / 0.5;
      arm.grip_step[k] = v * dt_;
    }
    ids_.push_back(spec.id);
    arm.spec = std::move(spec);
    arms_.push_back(std::move(arm));
  }
}

int IkEngine::index_of(const std::string& robot) const {
  const auto it = std::lower_bound(ids_.begin(), ids_.end(), robot);
  return it != ids_.end() && *it == robot ? static_cast<int>(it - ids_.begin()) : -1;
}

std::string IkEngine::apply(const std::string& robot, const v2::RobotCommand& c) {
  const int i = index_of(robot);
  if (i < 0) {
    std::string known;
    for (const auto& id : ids_) known += (known.empty() ? "" : ", ") + id;
    return "unknown robot '" + robot + "' (this scenario has " + known + ")";
  }
  Arm& arm = arms_[static_cast<std::size_t>(i)];
  if (c.kind() == v2::RobotCommand::KIND_SPEED_SCALE) {
    // Only the speed along the current path changes; the command id the state echoes stays.
    if (!(c.speed_scale() >= 0.0 && c.speed_scale() <= 1.0))  // also false for NaN
      return "speed_scale " + fmt(c.speed_scale()) + " is outside [0, 1]";
    arm.motion->set_speed_scale(c.speed_scale());
    // The lookahead again, from here, at the new scale (and the ramp to it): it holds until
    // the next command, which physics counts with the full bound for the exchange it comes in.
    plan_speed_bound(arm);
    return {};
  }
  const double nums[] = {c.target().x(),      c.target().y(),    c.target().z(), c.yaw_deg(),
                         c.approach_height(), c.depart_height(), c.max_speed()};
  for (const double v : nums) {
    if (!std::isfinite(v)) return "command has a NaN or infinite number";
  }
  if (c.max_speed() < 0) return "max_speed is negative";
  switch (c.kind()) {
    case v2::RobotCommand::KIND_MOVE: {
      if (c.approach_height() < 0 || c.depart_height() < 0)
        return "approach/depart height is negative";
      kin::MoveCommand m;
      m.target = vec(c.target());
      m.yaw = c.yaw_deg() * kDegToRad;
      m.approach_height = c.approach_height();
      m.depart_height = c.depart_height();
      m.detour = c.detour();
      // 0 = the robot's max_tcp_speed; anything above it is capped (the generator caps too).
      m.max_speed = c.max_speed() > 0 ? std::min(c.max_speed(), arm.spec.max_tcp_speed) : 0.0;
      arm.motion->move(m);
      break;
    }
    case v2::RobotCommand::KIND_HOLD: arm.motion->hold(); break;
    default:
      return "command kind " + std::to_string(static_cast<int>(c.kind())) +
             " is neither MOVE, HOLD nor SPEED_SCALE";
  }
  arm.command_id = c.command_id();
  arm.grip_target.setConstant(c.holding() ? arm.spec.gripper_closed : arm.spec.gripper_open);
  plan_speed_bound(arm);
  return {};
}

void IkEngine::plan_speed_bound(Arm& arm) const {
  if (!declare_speeds_) {
    arm.speed_known = false;
    return;
  }
  // Thirty simulated seconds: far longer than any move of a task, and a bounded cost per command.
  const auto lookahead = static_cast<std::size_t>(std::ceil(30.0 / dt_));
  const kin::MotionGenerator::SpeedForecast forecast = arm.motion->speed_forecast(lookahead);
  const bool complete = forecast.complete;
  Eigen::MatrixXd steps(forecast.joint_fractions.rows(), 3 * arm.model->dof());
  steps << forecast.joint_fractions, forecast.link_linear, forecast.link_angular;
  const Eigen::Index n = steps.rows();
  arm.speed_table.resize(n, steps.cols());
  if (speed_window_ == 0) {  // the maximum over the rest of the motion
    for (Eigen::Index i = n - 1; i >= 0; --i)
      arm.speed_table.row(i) = i + 1 < n ? steps.row(i).cwiseMax(arm.speed_table.row(i + 1))
                                         : Eigen::RowVectorXd(steps.row(i));
  } else {  // the maximum over the window's steps from i on
    const auto w = static_cast<Eigen::Index>(speed_window_);
    for (Eigen::Index i = 0; i < n; ++i)
      arm.speed_table.row(i) = steps.middleRows(i, std::min(w, n - i)).colwise().maxCoeff();
  }
  arm.steps_taken = 0;
  arm.speed_known = complete;
}

void IkEngine::step() {
  for (Arm& arm : arms_) {
    arm.motion->step();
    ++arm.steps_taken;
    const Eigen::VectorXd gap = arm.grip_target - arm.grip;
    arm.grip += gap.cwiseMax(-arm.grip_step).cwiseMin(arm.grip_step);
  }
}

std::optional<Eigen::VectorXd> IkEngine::speed_row(std::size_t index) const {
  const Arm& arm = arms_.at(index);
  if (!arm.speed_known) return std::nullopt;
  // The next step is row steps_taken of the table; past its end nothing moves.
  const auto next = static_cast<Eigen::Index>(arm.steps_taken);
  if (next < arm.speed_table.rows()) return Eigen::VectorXd(arm.speed_table.row(next).transpose());
  return Eigen::VectorXd::Zero(3 * arm.model->dof());
}

const kin::MotionState& IkEngine::state(std::size_t index) const {
  return arms_.at(index).motion->state();
}
uint64_t IkEngine::min_ticks_to_end(std::size_t index) const {
  return arms_.at(index).motion->min_ticks_to_end();
}
void IkEngine::reset(std::size_t index, const Eigen::VectorXd& q) {
  Arm& arm = arms_.at(index);
  arm.motion->reset(q);
  arm.speed_table.resize(0, 3 * arm.model->dof());  // at rest
  arm.speed_known = true;
}
const kin::RobotModel& IkEngine::model(std::size_t index) const { return *arms_.at(index).model; }
uint64_t IkEngine::command_id(std::size_t index) const { return arms_.at(index).command_id; }

void IkEngine::fill_state(std::size_t index, v2::RobotState& out) const {
  const Arm& arm = arms_.at(index);
  const kin::MotionState& s = arm.motion->state();
  const auto& names = arm.model->joint_names();
  const int n_chain = static_cast<int>(names.size());
  const int n = n_chain + static_cast<int>(arm.grip.size());  // the chain, then the fingers
  if (out.robot() != arm.spec.id) out.set_robot(arm.spec.id);
  if (out.joint_names_size() != n) {
    out.clear_joint_names();
    for (const auto& name : names) out.add_joint_names(name);
    for (const auto& name : arm.spec.gripper_joints) out.add_joint_names(name);
  }
  auto* q = out.mutable_joint_positions();
  if (q->size() != n) q->Resize(n, 0.0);
  for (int i = 0; i < n_chain; ++i) q->Set(i, s.q[i]);
  for (int k = 0; k < n - n_chain; ++k) q->Set(n_chain + k, arm.grip[k]);
  const Eigen::Vector3d p = s.tcp.translation();
  const Eigen::Quaterniond r = Eigen::Quaterniond(s.tcp.linear()).normalized();
  v2::Pose* tcp = out.mutable_tcp();
  tcp->mutable_position()->set_x(p.x());
  tcp->mutable_position()->set_y(p.y());
  tcp->mutable_position()->set_z(p.z());
  tcp->mutable_orientation()->set_x(r.x());
  tcp->mutable_orientation()->set_y(r.y());
  tcp->mutable_orientation()->set_z(r.z());
  tcp->mutable_orientation()->set_w(r.w());
  out.set_tcp_speed(s.tcp_speed);
  out.set_status(to_wire(s.status));
  out.set_motion_kind(to_wire(s.kind));
  out.set_command_id(arm.command_id);
  if (out.detail() != s.detail) out.set_detail(s.detail);
  auto* bounds = out.mutable_joint_speed_fraction_bounds();
  auto* linear = out.mutable_link_linear_speed_bounds();
  auto* angular = out.mutable_link_angular_speed_bounds();
  if (const std::optional<Eigen::VectorXd> row = speed_row(index)) {
    if (bounds->size() != n) bounds->Resize(n, 0.0);
    if (linear->size() != n_chain) linear->Resize(n_chain, 0.0);
    if (angular->size() != n_chain) angular->Resize(n_chain, 0.0);
    for (int i = 0; i < n_chain; ++i) {
      bounds->Set(i, (*row)[i]);
      linear->Set(i, (*row)[n_chain + i]);
      angular->Set(i, (*row)[2 * n_chain + i]);
    }
    // A finger moves at its velocity limit until it is where the command sends it.
    for (int k = 0; k < n - n_chain; ++k)
      bounds->Set(n_chain + k, arm.grip[k] == arm.grip_target[k] ? 0.0 : 1.0);
    out.set_joint_speed_window_ticks(speed_window_);
  } else {
    bounds->Clear();
    linear->Clear();
    angular->Clear();
    out.clear_joint_speed_window_ticks();
  }
  // Unset at scale 1: the policies without speed scaling publish the same bytes as before.
  const double scale = arm.motion->speed_scale();
  if (scale < 1.0) {
    out.set_speed_scale(scale);
  } else if (out.has_speed_scale()) {
    out.clear_speed_scale();
  }
}

v2::ReachReply IkEngine::reach(const v2::ReachRequest& request) {
  v2::ReachReply reply;
  const std::lock_guard<std::mutex> lock(reach_mutex_);
  for (const v2::ReachItem& item : request.items()) {
    v2::ReachResult* r = reply.add_results();
    r->set_id(item.id());
    const int i = index_of(item.robot());
    if (i < 0) {
      r->set_reachable(false);
      r->set_position_error_m(std::numeric_limits<double>::infinity());
      r->set_detail("unknown robot '" + item.robot() + "'");
      continue;
    }
    const Eigen::Vector3d target = vec(item.target());
    if (!target.allFinite() || !std::isfinite(item.yaw_deg())) {
      r->set_reachable(false);
      r->set_position_error_m(std::numeric_limits<double>::infinity());
      r->set_detail("target or yaw has a NaN or infinite value");
      continue;
    }
    double err = 0.0;
    const bool ok = arms_[static_cast<std::size_t>(i)].probe->reachable(
        target, item.yaw_deg() * kDegToRad, &err);
    r->set_reachable(ok);
    r->set_position_error_m(err);
    if (!ok) {
      r->set_detail("robot '" + item.robot() + "' cannot reach " + fmt_point(target) +
                    " with the tool pointing down (closest " + fmt(err) + " m away)");
    }
  }
  return reply;
}

// ---------------------------------------------------------------- motion check

v2::MotionCheckReply check_moves(const v2::MotionCheckRequest& request, double max_move_s) {
  IkEngine engine(robots_from_scenario(request.scenario()), tick_dt(request.scenario()));
  engine.set_declare_speeds(false);  // nobody reads them here; the check runs each move anyway
  // Per robot: joints at home, after its last move, and after each labelled move.
  std::vector<Eigen::VectorXd> home, last;
  std::vector<std::map<std::string, Eigen::VectorXd>> after(engine.size());
  for (std::size_t i = 0; i < engine.size(); ++i) home.push_back(engine.state(i).q);
  last = home;
  v2::MotionCheckReply reply;
  for (const v2::MoveCheck& move : request.moves()) {
    v2::MoveCheckResult* r = reply.add_results();
    r->set_label(move.label());
    r->set_robot(move.command().robot());
    const int i = engine.index_of(move.command().robot());
    if (i < 0) {
      r->set_detail("unknown robot '" + move.command().robot() + "'");
      continue;
    }
    const auto k = static_cast<std::size_t>(i);
    if (move.start() == "home") {
      engine.reset(k, home[k]);
    } else if (!move.start().empty()) {
      const auto it = after[k].find(move.start());
      if (it == after[k].end()) {
        r->set_detail("start '" + move.start() + "' is no earlier move of " +
                      move.command().robot());
        continue;
      }
      engine.reset(k, it->second);
    } else {
      engine.reset(k, last[k]);
    }
    const std::string problem = engine.apply(move.command().robot(), move.command());
    if (!problem.empty()) {
      r->set_detail("command refused: " + problem);
      continue;
    }
    const auto max_ticks = static_cast<uint64_t>(std::ceil(max_move_s / engine.dt()));
    uint64_t ticks = 0;
    double vmax = 0.0;
    r->set_kind(to_wire(engine.state(k).kind));
    // An interruption: the command at at_s, then (once the arm stands still and wait_s passed)
    // the move again, as the orchestrator re-sends it.
    const bool interrupt = move.has_interrupt();
    const bool by_scale =
        interrupt && move.interrupt().command().kind() == v2::RobotCommand::KIND_SPEED_SCALE;
    bool interrupted = false, resumed = false;
    uint64_t still = 0;
    const auto wait_ticks =
        static_cast<uint64_t>(std::ceil(std::max(0.0, move.interrupt().wait_s()) / engine.dt()));
    while (ticks < max_ticks) {
      const kin::MotionState& now = engine.state(k);
      if (interrupt && !interrupted && now.status == kin::MotionStatus::Moving &&
          static_cast<double>(ticks) * engine.dt() >= move.interrupt().at_s()) {
        v2::RobotCommand c = move.interrupt().command();
        c.set_robot(move.command().robot());
        const std::string refused = engine.apply(c.robot(), c);
        if (!refused.empty()) {
          r->set_detail("interruption refused: " + refused);
          break;
        }
        interrupted = true;
      } else if (interrupted && !resumed) {
        if (now.status == kin::MotionStatus::Unreachable) {
          r->set_detail("interrupted: " + now.detail);
          break;
        }
        const bool stopped =
            now.tcp_speed < 1e-9 && (by_scale || now.status != kin::MotionStatus::Moving);
        still = stopped ? still + 1 : 0;
        if (still > wait_ticks) {
          v2::RobotCommand again = move.command();
          if (by_scale) {
            again = move.interrupt().command();
            again.set_robot(move.command().robot());
            again.set_speed_scale(1.0);
          }
          const std::string refused = engine.apply(again.robot(), again);
          if (!refused.empty()) {
            r->set_detail("resume refused: " + refused);
            break;
          }
          resumed = true;
        }
      }
      const bool waiting = interrupted && !resumed;
      if (!waiting && engine.state(k).status != kin::MotionStatus::Moving) break;
      engine.step();
      ++ticks;
      vmax = std::max(vmax, engine.state(k).tcp_speed);
    }
    r->set_interrupted(interrupted);
    const kin::MotionState& s = engine.state(k);
    r->set_duration_s(static_cast<double>(ticks) * engine.dt());
    r->set_max_tcp_speed(vmax);
    r->set_feasible(s.status == kin::MotionStatus::Reached);
    for (Eigen::Index j = 0; j < s.q.size(); ++j) r->add_end_joints(s.q[j]);
    if (!r->detail().empty()) {
      r->set_feasible(false);  // the interruption or the resume was refused: said above
    } else if (s.status == kin::MotionStatus::Moving || (interrupted && !resumed)) {
      r->set_detail("still moving after " + fmt(max_move_s) + " s");
    } else if (!r->feasible()) {
      r->set_detail(s.detail.empty() ? std::string(kin::to_string(s.status)) : s.detail);
    }
    last[k] = s.q;
    if (!move.label().empty()) after[k][move.label()] = s.q;
  }
  return reply;
}

// ---------------------------------------------------------------- tick times

void TickTimes::add(double us) {
  if (!(us >= 0)) us = 0;
  const auto bin = static_cast<std::size_t>(std::min<double>(us, kBins));
  ++bins_[std::min(bin, kBins)];
  ++count_;
  sum_ += us;
  max_ = std::max(max_, us);
}

double TickTimes::quantile(double q) const {
  if (count_ == 0) return 0.0;
  const auto rank =
      static_cast<uint64_t>(std::ceil(std::clamp(q, 0.0, 1.0) * static_cast<double>(count_)));
  uint64_t seen = 0;
  for (std::size_t b = 0; b < kBins; ++b) {
    seen += bins_[b];
    if (seen >= std::max<uint64_t>(rank, 1)) return std::min(static_cast<double>(b + 1), max_);
  }
  return max_;
}

std::string TickTimes::summary() const {
  if (count_ == 0) return "no ticks";
  return "n " + std::to_string(count_) + ", mean " + fmt(mean()) + " us, p50 " +
         fmt(quantile(0.5)) + " us, p99 " + fmt(quantile(0.99)) + " us, max " + fmt(max_) + " us";
}

// ---------------------------------------------------------------- service

IkService::IkService(Bus& bus, LockstepParticipant& participant, IkEngine& engine)
    : bus_(bus), participant_(participant), engine_(engine) {
  // Publishers first, so subscribers can match them before alive/<name> is declared.
  for (const std::string& id : engine_.robot_ids()) {
    state_pubs_.push_back(&bus_.publisher(bus_.keys().robot_state(id)));
    states_.emplace_back();
    last_sent_.emplace_back();
  }
  participant.input<v2::RobotCommand>(
      bus_.keys().robot_commands(),
      [this](const std::string& key, const v2::RobotCommand& c) { on_command(key, c); });
  participant.on_tick([this](const v2::ClockTick& t) { step(t); });
  participant.on_next_event([this] { return next_event_tick(); });
  bus_.queryable<v2::ReachRequest, v2::ReachReply>(
      bus_.keys().robot_reach(), [this](const v2::ReachRequest& req) {
        v2::ReachReply reply = engine_.reach(req);
        reply.mutable_header()->set_session(bus_.keys().session());
        reply.mutable_header()->set_sender(bus_.sender());
        return reply;
      });
}

std::string IkService::validate_command(const std::string& key, const v2::RobotCommand& c) {
  const std::string robot = Keys::robot_of(key);
  if (!c.robot().empty() && c.robot() != robot) {
    return "robot field '" + c.robot() + "' does not match the key's robot '" + robot + "'";
  }
  return {};
}

void IkService::on_command(const std::string& key, const v2::RobotCommand& command) {
  const auto t0 = std::chrono::steady_clock::now();
  std::string problem = validate_command(key, command);
  if (problem.empty()) problem = engine_.apply(Keys::robot_of(key), command);
  // Planning a move (path check by IK along the line) is part of the tick it is applied in.
  command_us_ += micros_since(t0);
  if (!problem.empty()) {
    // Counted like a malformed payload so it shows in stats/<name>; it never drives the arm.
    ++commands_rejected_;
    const uint64_t n = bus_.stats().count_error(key);
    log::warning("rejected command #" + std::to_string(n) + " on " + key + " from sender '" +
                 command.header().sender() + "' (command_id " +
                 std::to_string(command.command_id()) + "): " + problem);
    return;
  }
  ++commands_received_;
  if (log::enabled(log::Level::Debug)) {
    log::debug("command " + std::to_string(command.command_id()) + " on " + key + " applied");
  }
}

void IkService::step(const v2::ClockTick& tick) {
  if (!dt_warned_ && tick.dt() > 0 && std::abs(tick.dt() - engine_.dt()) > 1e-9 * engine_.dt()) {
    dt_warned_ = true;
    log::warning("the clock's dt " + fmt(tick.dt()) + " s differs from the scenario's " +
                 fmt(engine_.dt()) + " s; the arms step by the scenario's dt");
  }
  // Commands come before their tick's step: they plan with the previous tick's mode, which is
  // the run's.
  engine_.set_declare_speeds(tick.mode() != v2::CLOCK_MODE_REALTIME);
  const auto t0 = std::chrono::steady_clock::now();
  engine_.step();
  const double commands_us = command_us_;
  command_us_ = 0.0;
  compute_times_.add(commands_us + micros_since(t0));
  last_tick_ = tick.header().tick();
  publish_states(tick.header().tick(), tick.header().sim_time());
  step_times_.add(commands_us + micros_since(t0));
}

uint64_t IkService::next_event_tick() const {
  uint64_t best = 0;
  for (std::size_t i = 0; i < engine_.size(); ++i) {
    const uint64_t n = engine_.min_ticks_to_end(i);
    if (n > 0 && (best == 0 || last_tick_ + n < best)) best = last_tick_ + n;
  }
  return best;
}

void IkService::publish_states(uint64_t tick, double sim_time) {
  // An arm at rest would otherwise cost every receiver a message per tick for nothing.
  const auto keyframe_every = static_cast<uint64_t>(std::max(1.0, std::round(1.0 / engine_.dt())));
  const bool keyframe = tick % keyframe_every == 0;
  for (std::size_t i = 0; i < states_.size(); ++i) {
    v2::RobotState& state = states_[i];
    engine_.fill_state(i, state);
    state.clear_header();
    std::string body = state.SerializeAsString();
    if (!keyframe && body == last_sent_[i]) continue;
    last_sent_[i] = std::move(body);
    state_pubs_[i]->put(state, tick, sim_time);
  }
}

uint64_t IkService::run_standalone(double hz, const std::function<bool()>& keep_going) {
  if (!(hz > 0) || !std::isfinite(hz))
    throw std::invalid_argument("standalone rate must be > 0 Hz");
  bus_.subscribe<v2::RunEnd>(bus_.keys().run_end(),
                             [this](const std::string&, const v2::RunEnd&) { run_ended_ = true; });
  bus_.serve_stats();
  bus_.declare_token();
  using Clock = std::chrono::steady_clock;
  const auto period =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / hz));
  v2::ClockTick tick;  // synthesized, reused: only header.tick / sim_time / dt change
  tick.set_dt(1.0 / hz);
  uint64_t k = 0;
  auto next = Clock::now();
  while (keep_going() && !run_ended_) {
    // No clock: every command that has arrived is due now (still in deterministic order).
    participant_.inbox().deliver(std::numeric_limits<uint64_t>::max());
    tick.mutable_header()->set_tick(k);
    tick.mutable_header()->set_sim_time(static_cast<double>(k) / hz);
    bus_.stats().tick(k);
    step(tick);
    ++k;
    next += period;
    const auto now = Clock::now();
    if (now > next + period) {
      // More than a period behind: count it and restart the schedule rather than burst.
      ++overruns_;
      next = now;
    } else {
      std::this_thread::sleep_until(next);
    }
  }
  return k;
}

std::string IkService::timing_summary() const {
  std::string s = "per-tick compute (kinematics, " + std::to_string(engine_.size()) +
                  " arms): " + compute_times_.summary() +
                  "; with publishing: " + step_times_.summary();
  if (overruns_ > 0) s += "; timer overruns: " + std::to_string(overruns_);
  return s;
}

}  // namespace hrc
