// Recovery of the motion generator after an interruption: leaving (a retreat), detours and
// resuming the interrupted move; the marks a segment leaves when done.
#include "hrc/kin/motion.hpp"

#include <algorithm>
#include <cmath>

#include "motion_detail.hpp"

namespace hrc::kin {

using motion_detail::fmt_point;
using motion_detail::kAtLeavePoint;
using motion_detail::same_move;

void MotionGenerator::leave() {
  Base& b = *base_;
  if (b.left && b.leave_pending) {
    // Still braking on the task move's path to the leave point: only that brake stays.
    while (segments_.size() > 1) segments_.pop_back();
    return;
  }
  const ProfileLimits lim{limits_.max_tcp_speed, limits_.max_tcp_accel, limits_.max_tcp_jerk};
  std::deque<Segment> out;
  Cursor c;
  std::string why;
  brake_prefix(lim, out, c, why);
  if (!b.left) {
    b.rest.clear();
    if (!segments_.empty()) {
      const Segment& front = segments_.front();
      double m_end = 0.0;
      if (out.empty()) {
        double s = 0, vs = 0;
        front.profile.eval(seg_t_, s, vs);
        m_end = front.m_start + s;
      } else {
        m_end = out.back().m_start + out.back().profile.length();
      }
      b.rest = remainder_from(front, m_end);
      for (std::size_t i = 1; i < segments_.size(); ++i) b.rest.push_back(segments_[i]);
    }
    b.q_leave = c.q;
    b.left = true;
    b.next.reset();
    b.leave_pending = !out.empty();
    if (b.leave_pending) {
      out.back().mark = Mark::Left;
    } else {
      b.leave_idx = b.trail.size() - 1;
    }
  }
  segments_ = std::move(out);
  seg_t_ = 0.0;
  time_scale_ = 1.0;
  if (segments_.empty()) v_cmd_.setZero();
}

MotionStatus MotionGenerator::detour(const MoveCommand& cmd) {
  if (!base_) return plan_move(cmd);  // no task move to come back to
  leave();
  MotionKind kind = MotionKind::None;
  std::deque<Segment> plan;
  std::string why;
  if (plan_from(queue_end(), cmd, plan, why, &kind)) {
    for (Segment& sg : plan) segments_.push_back(std::move(sg));
    return start_plan(cmd, kind);
  }
  // Nothing feasible from where the brake ends: back along the path the arm came (joint space,
  // feasible by construction) to where its task move began, and the detour from there.
  std::deque<Segment> from_start;
  std::string why_start;
  if (!plan_from(base_->trail.front(), cmd, from_start, why_start, &kind)) {
    state_.kind = MotionKind::None;
    stop_with(MotionStatus::Unreachable,
              "target " + fmt_point(cmd.target) + ": no feasible move from where the arm stops (" +
                  why + ") nor from where its task move began (" + why_start + ")");
    return state_.status;
  }
  std::vector<Eigen::VectorXd> ahead = samples_ahead(segments_);
  std::vector<Eigen::VectorXd> path(ahead.rbegin(), ahead.rend());
  path.insert(path.end(), base_->trail.rbegin(), base_->trail.rend());
  Segment back;
  if (polyline(path, limits_for(cmd), back)) segments_.push_back(std::move(back));
  for (Segment& sg : from_start) segments_.push_back(std::move(sg));
  return start_plan(cmd, kind);
}

MotionStatus MotionGenerator::resume(const MoveCommand& cmd) {
  Base& b = *base_;
  const bool same = same_move(cmd, b.cmd);
  const ProfileLimits lim = limits_for(cmd);
  std::deque<Segment> tail;  // what follows the way back to the leave point
  MotionKind kind = same ? MotionKind::Joint : MotionKind::None;
  if (same) {
    tail = b.rest;
  } else {
    std::string why;
    if (!plan_from(b.q_leave, cmd, tail, why, &kind)) {
      state_.kind = MotionKind::None;
      stop_with(MotionStatus::Unreachable, "target " + fmt_point(cmd.target) + ": " + why);
      return state_.status;
    }
  }
  if (b.leave_pending) {
    while (segments_.size() > 1) segments_.pop_back();  // the brake to the leave point
  } else {
    std::deque<Segment> out;
    Cursor c;
    std::string why;
    brake_prefix(lim, out, c, why);
    segments_ = std::move(out);
    seg_t_ = 0.0;
    time_scale_ = 1.0;
    const Eigen::VectorXd q_stop = queue_end();
    // Standing at the leave point (after a hold; a line's exact IK may differ from its samples
    // by far less than this): the rest of the plan from here.
    if ((q_stop - b.q_leave).cwiseAbs().maxCoeff() > kAtLeavePoint) {
      Cursor from;
      from.q = q_stop;
      fk_world(q_stop, from.p, from.r);
      std::deque<Segment> direct;
      std::string why_direct;
      bool rejoined = false;
      if (same && !b.last.empty()) {
        // Not back to where it left (where the person may still be): on to the end of the
        // judged plan, by a joint move checked against the table, and down the plan's own
        // vertical approach where it has one. It ends where the undisturbed move ends.
        const Segment& last = b.last.front();
        const bool approach = cmd.approach_height > 0;
        const Eigen::VectorXd goal = approach ? joint_at(last, last.m_start) : b.q_end;
        if (append_joint(direct, from, goal, lim, why_direct)) {
          tail.clear();
          if (approach) {
            tail.push_back(last);
            tail.back().mark = Mark::None;
          }
          rejoined = true;
        } else {
          direct.clear();
        }
      }
      // Else back to the leave point: straight in joint space where that is clear of the
      // table, else the way the arm came; then the rest of the plan from there.
      if (!rejoined && append_joint(direct, from, b.q_leave, lim, why_direct)) rejoined = true;
      if (rejoined) {
        for (Segment& sg : direct) segments_.push_back(std::move(sg));
      } else {
        std::vector<Eigen::VectorXd> ahead = samples_ahead(segments_);
        std::vector<Eigen::VectorXd> path(ahead.rbegin(), ahead.rend());
        path.insert(path.end(), b.trail.rbegin(),
                    b.trail.rend() - static_cast<std::ptrdiff_t>(b.leave_idx));
        Segment back;
        if (polyline(path, lim, back)) segments_.push_back(std::move(back));
      }
    }
  }
  if (segments_.empty()) {
    segment_done_mark(same ? Mark::Rejoined : Mark::NewBase, cmd);
  } else {
    segments_.back().mark = same ? Mark::Rejoined : Mark::NewBase;
    if (!same) b.next = cmd;
  }
  for (Segment& sg : tail) segments_.push_back(std::move(sg));
  return start_plan(cmd, kind);
}

void MotionGenerator::segment_done_mark(Mark mark, std::optional<MoveCommand> cmd) {
  if (!base_) return;
  Base& b = *base_;
  switch (mark) {
    case Mark::None: break;
    case Mark::Left:
      b.leave_pending = false;
      b.leave_idx = b.trail.size() - 1;
      break;
    case Mark::Rejoined:
      b.left = false;
      b.leave_pending = false;
      b.rest.clear();
      break;
    case Mark::NewBase: {
      begin_base(cmd ? *cmd : b.next.value_or(b.cmd));
      break;
    }
  }
}

}  // namespace hrc::kin
