// Braking of the motion generator: a segment's braking ramp, the rest of an interrupted
// segment, and braking before a new departure.
#include "hrc/kin/motion.hpp"

#include <algorithm>
#include <cmath>

#include "motion_detail.hpp"

namespace hrc::kin {

void MotionGenerator::brake_segment(const ProfileLimits& lim) {
  // Brake along the planned path itself: the arm never leaves a path that was checked.
  std::deque<Segment> out;
  Cursor c;
  std::string why;
  brake_prefix(lim, out, c, why);
  segments_ = std::move(out);
  seg_t_ = 0.0;
  time_scale_ = 1.0;
  if (segments_.empty()) v_cmd_.setZero();
}

MotionGenerator::Segment MotionGenerator::brake_on(const Segment& s, double m_now, double v,
                                                   const ProfileLimits& lim) {
  Segment b = s;
  b.m_start = m_now;
  b.limits = lim;
  b.mark = Mark::None;
  const double left = std::max(0.0, s.measure.back() - m_now);
  b.profile.plan_brake(v, lim);
  if (b.profile.length() > left) {
    // The segment's own profile was already stopping harder than a fresh brake would: stop at
    // its end, with the limits raised just enough (the path, not the limits, is what must hold).
    ProfileLimits hard = lim;
    for (int i = 0; i < 40 && !b.profile.plan(left, v, hard); ++i) {
      hard.max_accel *= 1.5;
      hard.max_jerk *= 2.25;
    }
  }
  pin_sample(b, m_now + b.profile.length());
  return b;  // the geometry stays the segment's: only where and how fast it runs change
}

std::deque<MotionGenerator::Segment> MotionGenerator::remainder_from(const Segment& s, double m) {
  std::deque<Segment> out;
  const double left = s.measure.back() - m;
  if (left <= 1e-9) return out;
  Segment r = s;
  pin_sample(r, m);
  r.m_start = m;
  r.mark = Mark::None;
  r.profile.plan(left, 0.0, r.limits);
  out.push_back(std::move(r));
  return out;
}

bool MotionGenerator::brake_prefix(const ProfileLimits& lim, std::deque<Segment>& out, Cursor& c,
                                   std::string& why) {
  (void)why;  // braking on a sampled path cannot fail
  c.q = state_.q;
  c.p = state_.tcp.translation();
  c.r = Eigen::Quaterniond(state_.tcp.linear());
  if (segments_.empty() || meas_speed_ < 1e-9) return true;
  const Segment& front = segments_.front();
  double s = 0, vs = 0;
  front.profile.eval(seg_t_, s, vs);
  Segment b = brake_on(front, front.m_start + s, meas_speed_, lim);
  c.q = joint_at(b, b.m_start + b.profile.length());
  fk_world(c.q, c.p, c.r);
  out.push_back(std::move(b));
  return true;
}

bool MotionGenerator::brake_and_depart(const MoveCommand& cmd, const ProfileLimits& lim,
                                       std::deque<Segment>& out, Cursor& c, std::string& why) {
  if (!brake_prefix(lim, out, c, why)) return false;
  if (cmd.depart_height > 0 &&
      !append_line(out, c, c.p + Eigen::Vector3d(0, 0, cmd.depart_height), c.r, lim, why)) {
    why = "depart: " + why;
    return false;
  }
  return true;
}

}  // namespace hrc::kin
