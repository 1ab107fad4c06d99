// Planning of the motion generator: a move's path (linear, joint or via points) as segments,
// checked against the arm's IK and limits along the way.
#include "hrc/kin/motion.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "motion_detail.hpp"

namespace hrc::kin {

using motion_detail::closest;
using motion_detail::finite;
using motion_detail::fmt_num;
using motion_detail::fmt_point;
using motion_detail::kJointMeasure;
using motion_detail::kJointStep;
using motion_detail::kSampleTolerance;

void MotionGenerator::plan_to(const std::vector<Eigen::Vector3d>& points, int rotate_segment,
                              const Eigen::Matrix3d& goal_R, const ProfileLimits& lim) {
  Eigen::Vector3d p = state_.tcp.translation();
  Eigen::Quaterniond R(state_.tcp.linear());
  const Eigen::Quaterniond G(goal_R);
  double speed = v_cmd_.norm();
  std::deque<Segment> prefix;
  if (!segments_.empty() && segments_.front().joint) {
    // Mid joint move: stop along it first, then the lines start at rest.
    Cursor c;
    std::string why;
    brake_prefix(lim, prefix, c, why);
    p = c.p;
    R = c.r;
    speed = 0.0;
  }
  segments_ = std::move(prefix);
  seg_t_ = 0.0;
  time_scale_ = 1.0;
  bool first = true;
  for (std::size_t k = 0; k < points.size(); ++k) {
    const Eigen::Quaterniond r1 = static_cast<int>(k) == rotate_segment ? G : R;
    Eigen::Vector3d d = points[k] - p;
    double L = d.norm();
    double ang = R.angularDistance(r1);
    double prof = std::max(L, limits_.rotation_length * ang);
    double v0 = 0.0;
    if (first && speed > 1e-9) {
      // Blend: keep going if the current velocity already points along the new line (within one
      // tick of acceleration), otherwise brake along the current direction first.
      bool brake = true;
      if (L > 1e-9) {
        const Eigen::Vector3d u = d / L;
        const double v_par = v_cmd_.dot(u);
        const double v_perp = (v_cmd_ - v_par * u).norm();
        if (v_par > 0 && v_perp <= limits_.max_tcp_accel * dt_) {
          Segment s;
          s.limits = lim;
          v0 = v_par * prof / L;
          if (s.profile.plan(prof, v0, lim)) brake = false;
        }
      }
      if (brake) {
        Segment b;
        b.p0 = p;
        b.u = v_cmd_ / speed;
        b.limits = lim;
        b.profile.plan_brake(speed, lim);
        b.lin_length = b.prof_length = b.profile.length();
        b.r0 = b.r1 = R;
        segments_.push_back(b);
        p = p + b.u * b.lin_length;
        d = points[k] - p;
        L = d.norm();
        prof = std::max(L, limits_.rotation_length * ang);
        v0 = 0.0;
      }
    }
    first = false;
    if (prof < 1e-9) continue;
    Segment s;
    s.p0 = p;
    s.u = L > 1e-12 ? Eigen::Vector3d(d / L) : Eigen::Vector3d::UnitZ();
    s.lin_length = L;
    s.prof_length = prof;
    s.r0 = R;
    s.r1 = r1;
    s.limits = lim;
    if (!s.profile.plan(prof, v0, lim)) s.profile.plan(prof, 0.0, lim);  // v0 = 0 always plans
    segments_.push_back(s);
    p = points[k];
    R = r1;
  }
}

bool MotionGenerator::check_path(std::string& why) {
  return check_segments(segments_, state_.q, why);
}

bool MotionGenerator::check_segments(std::deque<Segment>& segs, Eigen::VectorXd seed,
                                     std::string& why) {
  IkResult res;
  for (Segment& s : segs) {
    if (!s.qs.empty()) {  // checked and sampled when it was built: continue from where it ends
      seed = joint_at(s, s.m_start + s.profile.length());
      continue;
    }
    const int n = std::max(1, static_cast<int>(std::ceil(s.prof_length / limits_.check_step)));
    s.qs.assign(1, seed);
    s.measure.assign(1, 0.0);
    for (int k = 1; k <= n; ++k) {
      const double f = static_cast<double>(k) / n;
      const Eigen::Vector3d p = s.p0 + s.u * (f * s.lin_length);
      const Eigen::Matrix3d R = s.r0.slerp(f, s.r1).toRotationMatrix();
      if (!solve_pose(p, R, seed, res)) {
        why = "path leaves the workspace near " + fmt_point(p) + " " + closest(res);
        return false;
      }
      // A jump between neighbouring samples means the solution switches branch (a joint limit
      // or singularity in the way): the arm could not follow the straight line.
      const double jump = (res.q - seed).cwiseAbs().maxCoeff();
      if (jump > 0.35) {
        why = "path needs a joint reconfiguration near " + fmt_point(p);
        return false;
      }
      seed = res.q;
      s.qs.push_back(seed);
      s.measure.push_back(f * s.prof_length);
    }
  }
  return true;
}

// ---------------------------------------------------------------- planning helpers

void MotionGenerator::fk_world(const Eigen::VectorXd& q, Eigen::Vector3d& p,
                               Eigen::Quaterniond& r) const {
  Eigen::Matrix3d R;
  Eigen::Vector3d pb;
  ik_.eval().fk(q.data(), R, pb);
  p = world_T_base_ * pb;
  r = Eigen::Quaterniond(world_T_base_.linear() * R);
}

Eigen::VectorXd MotionGenerator::joint_at(const Segment& s, double m) const {
  const std::vector<double>& meas = s.measure;
  const int n = static_cast<int>(meas.size()) - 1;
  if (n <= 0 || m >= meas.back()) return s.qs.back();
  if (m <= 0.0) return s.qs.front();
  const auto it = std::upper_bound(meas.begin(), meas.end(), m);
  const int k = static_cast<int>(it - meas.begin());  // meas[k-1] <= m < meas[k]
  const double span = meas[k] - meas[k - 1];
  const double frac = span > 0 ? (m - meas[k - 1]) / span : 1.0;
  const auto a = static_cast<std::size_t>(k - 1);
  return s.qs[a] + frac * (s.qs[a + 1] - s.qs[a]);
}

void MotionGenerator::pin_sample(Segment& s, double m) {
  if (s.joint || s.measure.size() < 2) return;
  const auto it = std::upper_bound(s.measure.begin(), s.measure.end(), m);
  if (it == s.measure.begin() || it == s.measure.end()) return;
  constexpr double kSameSample = 1e-9;
  if (m - *(it - 1) < kSameSample || *it - m < kSameSample) return;
  const Eigen::VectorXd q_path = joint_at(s, m);
  const double f = s.prof_length > 0 ? (m - s.measure.front()) / s.prof_length : 1.0;
  const Eigen::Vector3d p = s.p0 + s.u * (f * s.lin_length);
  const Eigen::Matrix3d R = s.r0.slerp(f, s.r1).toRotationMatrix();
  IkResult exact;
  // The same refinement step() makes: where it fails, the samples are the path there too.
  if (!solve_pose(p, R, q_path, exact) ||
      (exact.q - q_path).cwiseAbs().maxCoeff() >= kSampleTolerance)
    return;
  const auto k = it - s.measure.begin();
  s.qs.insert(s.qs.begin() + k, exact.q);
  s.measure.insert(it, m);
}

bool MotionGenerator::append_line(std::deque<Segment>& out, Cursor& c, const Eigen::Vector3d& p,
                                  const Eigen::Quaterniond& r1, const ProfileLimits& lim,
                                  std::string& why) {
  const Eigen::Vector3d d = p - c.p;
  const double L = d.norm();
  const double prof = std::max(L, limits_.rotation_length * c.r.angularDistance(r1));
  if (prof < 1e-9) return true;
  Segment s;
  s.p0 = c.p;
  s.u = L > 1e-12 ? Eigen::Vector3d(d / L) : Eigen::Vector3d::UnitZ();
  s.lin_length = L;
  s.prof_length = prof;
  s.r0 = c.r;
  s.r1 = r1;
  s.limits = lim;
  s.profile.plan(prof, 0.0, lim);
  // The same check as a straight move's; its last solution is where the arm ends up.
  Eigen::VectorXd seed = c.q;
  IkResult res;
  const int n = std::max(1, static_cast<int>(std::ceil(prof / limits_.check_step)));
  s.qs.assign(1, seed);
  s.measure.assign(1, 0.0);
  for (int k = 1; k <= n; ++k) {
    const double f = static_cast<double>(k) / n;
    const Eigen::Vector3d q_p = s.p0 + s.u * (f * L);
    if (!solve_pose(q_p, s.r0.slerp(f, s.r1).toRotationMatrix(), seed, res)) {
      why = "line leaves the workspace near " + fmt_point(q_p) + " " + closest(res);
      return false;
    }
    if ((res.q - seed).cwiseAbs().maxCoeff() > 0.35) {
      why = "line needs a joint reconfiguration near " + fmt_point(q_p);
      return false;
    }
    seed = res.q;
    s.qs.push_back(seed);
    s.measure.push_back(f * prof);
  }
  out.push_back(std::move(s));
  c.q = seed;
  c.p = p;
  c.r = r1;
  return true;
}

bool MotionGenerator::append_joint(std::deque<Segment>& out, Cursor& c, const Eigen::VectorXd& q1,
                                   const ProfileLimits& lim, std::string& why) {
  Segment s;
  s.joint = true;
  const Eigen::VectorXd dq = q1 - c.q;
  const double span = dq.cwiseAbs().maxCoeff();
  const int n = std::max(8, static_cast<int>(std::ceil(span / kJointStep)));
  Eigen::Vector3d p_end;
  Eigen::Quaterniond r_end;
  fk_world(q1, p_end, r_end);
  // The TCP may go no lower than the table clearance, or than an endpoint that is itself lower.
  const double tcp_floor =
      std::min({limits_.table_z + limits_.table_clearance, c.p.z(), p_end.z()}) - 1e-6;
  s.measure.assign(static_cast<std::size_t>(n) + 1, 0.0);
  s.qs.assign(1, c.q);
  Eigen::Vector3d p_prev = c.p;
  Eigen::Quaterniond r_prev = c.r;
  for (int k = 1; k <= n; ++k) {
    const Eigen::VectorXd q = c.q + (static_cast<double>(k) / n) * dq;
    Eigen::Vector3d p;
    Eigen::Quaterniond r;
    fk_world(q, p, r);
    if (p.z() < tcp_floor) {
      why = "joint path takes the tool down to z " + fmt_num(p.z(), 3) + " m near " + fmt_point(p) +
            " (table at z " + fmt_num(limits_.table_z, 3) + " m)";
      return false;
    }
    for (int i = 2; i < model_.dof(); ++i) {
      Eigen::Vector3d origin, axis;
      ik_.eval().joint_frame(q.data(), i, origin, axis);
      const Eigen::Vector3d o = world_T_base_ * origin;
      if (o.z() < limits_.table_z) {
        why = "joint path takes joint " + model_.joint_names()[static_cast<std::size_t>(i)] +
              " below the table near " + fmt_point(o);
        return false;
      }
    }
    const double dm =
        std::max({(p - p_prev).norm(), limits_.rotation_length * r_prev.angularDistance(r),
                  kJointMeasure * (span / n)});
    s.measure[static_cast<std::size_t>(k)] = s.measure[static_cast<std::size_t>(k) - 1] + dm;
    s.qs.push_back(q);
    p_prev = p;
    r_prev = r;
  }
  s.p0 = c.p;
  s.lin_length = s.prof_length = s.measure.back();
  s.u = (p_end - c.p).norm() > 1e-12 ? Eigen::Vector3d((p_end - c.p).normalized())
                                     : Eigen::Vector3d::UnitZ();
  s.r0 = c.r;
  s.r1 = r_end;
  s.limits = lim;
  if (s.prof_length < 1e-9) return true;
  s.profile.plan(s.prof_length, 0.0, lim);
  out.push_back(std::move(s));
  c.q = q1;
  c.p = p_end;
  c.r = r_end;
  return true;
}

bool MotionGenerator::plan_joint(const MoveCommand& cmd, const Eigen::Matrix3d& goal_R,
                                 const ProfileLimits& lim, std::deque<Segment>& out,
                                 std::string& why) {
  out.clear();
  Cursor c;
  if (!brake_and_depart(cmd, lim, out, c, why)) return false;
  const Eigen::Vector3d pre = cmd.target + Eigen::Vector3d(0, 0, cmd.approach_height);
  const Eigen::Quaterniond G(goal_R);
  // Candidate configurations at the approach point: the branch nearest the arm first, then the
  // other branches (elbow flipped, base turned half a turn, the middle of the ranges).
  std::vector<Eigen::VectorXd> seeds{c.q, model_.mid_range()};
  // A redundant arm (more joints than a pose's six) is solved from its home posture first, so
  // its goals depend on the target, not on the arm's history: repeated moves do not drift.
  if (model_.dof() > 6 && rest_.size() == model_.dof()) seeds.insert(seeds.begin(), rest_);
  if (model_.dof() >= 3) {
    Eigen::VectorXd e = c.q;
    e[2] = -e[2];
    seeds.push_back(e);
    Eigen::VectorXd b = c.q;
    b[0] += b[0] > 0 ? -M_PI : M_PI;
    seeds.push_back(model_.clamp(b));
  }
  std::vector<Eigen::VectorXd> goals;
  IkResult res;
  for (const Eigen::VectorXd& seed : seeds) {
    if (!solve_pose(pre, goal_R, seed, res)) continue;
    bool seen = false;
    for (const auto& g : goals) seen = seen || (g - res.q).cwiseAbs().maxCoeff() < 1e-3;
    if (!seen) goals.push_back(res.q);
  }
  if (goals.empty()) {
    why = "no joint solution at " + fmt_point(pre);
    return false;
  }
  std::string first_why;
  for (const Eigen::VectorXd& q1 : goals) {
    std::deque<Segment> tmp = out;
    Cursor tc = c;
    std::string w;
    bool ok = append_joint(tmp, tc, q1, lim, w);
    if (ok && cmd.approach_height > 0) {
      ok = append_line(tmp, tc, cmd.target, G, lim, w);
      if (!ok) w = "approach: " + w;
    }
    if (ok) {
      out = std::move(tmp);
      return true;
    }
    if (first_why.empty()) first_why = w;
  }
  why = first_why;
  return false;
}

bool MotionGenerator::plan_via(const MoveCommand& cmd, const Eigen::Matrix3d& goal_R,
                               const ProfileLimits& lim, std::deque<Segment>& out,
                               std::string& why) {
  out.clear();
  Cursor c;
  if (!brake_and_depart(cmd, lim, out, c, why)) return false;
  const Eigen::Vector3d pre = cmd.target + Eigen::Vector3d(0, 0, cmd.approach_height);
  const Eigen::Quaterniond G(goal_R);
  const double z0 = std::max({c.p.z(), pre.z(), limits_.via_height});
  std::string first_why;
  for (const double z : {z0, z0 + 0.1}) {
    std::deque<Segment> tmp = out;
    Cursor tc = c;
    std::string w;
    const bool ok = append_line(tmp, tc, Eigen::Vector3d(c.p.x(), c.p.y(), z), c.r, lim, w) &&
                    append_line(tmp, tc, Eigen::Vector3d(pre.x(), pre.y(), z), G, lim, w) &&
                    append_line(tmp, tc, pre, G, lim, w) &&
                    append_line(tmp, tc, cmd.target, G, lim, w);
    if (ok) {
      out = std::move(tmp);
      return true;
    }
    if (first_why.empty()) first_why = "at height " + fmt_num(z, 3) + " m: " + w;
  }
  why = first_why;
  return false;
}

// ---------------------------------------------------------------- commands

MotionStatus MotionGenerator::move(const MoveCommand& cmd) {
  if (cmd.detour) return detour(cmd);
  if (base_ && base_->left) return resume(cmd);
  const MotionStatus st = plan_move(cmd);
  if (st != MotionStatus::Unreachable) begin_base(cmd);
  return st;
}

MotionStatus MotionGenerator::plan_move(const MoveCommand& cmd) {
  if (!cmd.target.allFinite() || !finite(cmd.yaw) || !finite(cmd.approach_height) ||
      !finite(cmd.depart_height) || !finite(cmd.max_speed) || cmd.approach_height < 0 ||
      cmd.depart_height < 0 || cmd.max_speed < 0) {
    state_.kind = MotionKind::None;
    stop_with(MotionStatus::Unreachable,
              "invalid command: target/yaw must be finite, heights and max_speed >= 0");
    return state_.status;
  }
  const ProfileLimits lim = limits_for(cmd);
  const Eigen::Matrix3d goal_R = tool_down_rotation(cmd.yaw);
  const auto yaw_deg = [&] { return fmt_num(cmd.yaw * 180.0 / M_PI, 1); };

  IkResult res;
  if (!solve_pose(cmd.target, goal_R, state_.q, res) &&
      !solve_pose(cmd.target, goal_R, model_.mid_range(), res)) {
    state_.kind = MotionKind::None;
    stop_with(MotionStatus::Unreachable, "target " + fmt_point(cmd.target) + " yaw " + yaw_deg() +
                                             " deg unreachable " + closest(res));
    return state_.status;
  }
  if (cmd.approach_height > 0) {
    // The vertical approach starts there whatever the kind of move: without it nothing can work.
    const Eigen::Vector3d pre = cmd.target + Eigen::Vector3d(0, 0, cmd.approach_height);
    const Eigen::VectorXd seed = res.q;  // the target's solution: the nearest approach branch
    if (!solve_pose(pre, goal_R, seed, res) && !solve_pose(pre, goal_R, model_.mid_range(), res)) {
      state_.kind = MotionKind::None;
      stop_with(MotionStatus::Unreachable, "target " + fmt_point(cmd.target) + " yaw " + yaw_deg() +
                                               " deg: approach point " + fmt_point(pre) + " (" +
                                               fmt_num(cmd.approach_height, 3) +
                                               " m above) unreachable " + closest(res));
      return state_.status;
    }
  }

  std::vector<Eigen::Vector3d> points;
  if (cmd.depart_height > 0)
    points.push_back(state_.tcp.translation() + Eigen::Vector3d(0, 0, cmd.depart_height));
  if (cmd.approach_height > 0)
    points.push_back(cmd.target + Eigen::Vector3d(0, 0, cmd.approach_height));
  points.push_back(cmd.target);
  const int rotate = static_cast<int>(points.size()) - (cmd.approach_height > 0 ? 2 : 1);

  // Plan into the live queue, but keep the old one to restore if the path is refused.
  std::deque<Segment> old = segments_;
  const double old_t = seg_t_, old_scale = time_scale_;
  plan_to(points, rotate, goal_R, lim);
  std::string why_line;
  MotionKind kind = MotionKind::Linear;
  if (!check_path(why_line)) {
    // The straight line is not feasible: a joint-space transfer, else via points.
    segments_ = std::move(old);
    seg_t_ = old_t;
    time_scale_ = old_scale;
    std::deque<Segment> alt;
    std::string why_joint, why_via;
    if (plan_joint(cmd, goal_R, lim, alt, why_joint)) {
      kind = MotionKind::Joint;
    } else if (plan_via(cmd, goal_R, lim, alt, why_via)) {
      kind = MotionKind::Via;
    } else {
      state_.kind = MotionKind::None;
      stop_with(MotionStatus::Unreachable,
                "target " + fmt_point(cmd.target) + " yaw " + yaw_deg() +
                    " deg: no feasible move: straight line: " + why_line +
                    "; joint move: " + why_joint + "; via points: " + why_via);
      return state_.status;
    }
    segments_ = std::move(alt);
    seg_t_ = 0.0;
    time_scale_ = 1.0;
    v_cmd_.setZero();
  }
  target_ = cmd.target;
  final_status_ = MotionStatus::Reached;
  state_.kind = kind;
  state_.detail.clear();
  if (segments_.empty()) {
    state_.status = MotionStatus::Reached;
    v_cmd_.setZero();
  } else {
    state_.status = MotionStatus::Moving;
  }
  return state_.status;
}

// ---------------------------------------------------------------- interruptions

void MotionGenerator::begin_base(const MoveCommand& cmd) {
  Base b;
  b.cmd = cmd;
  b.trail.assign(1, state_.q);
  b.q_end = queue_end();
  if (!segments_.empty()) b.last.assign(1, segments_.back());
  base_ = std::move(b);
}

ProfileLimits MotionGenerator::limits_for(const MoveCommand& cmd) const {
  const double vmax = cmd.max_speed > 0 && finite(cmd.max_speed)
                          ? std::min(cmd.max_speed, limits_.max_tcp_speed)
                          : limits_.max_tcp_speed;
  return {vmax, limits_.max_tcp_accel, limits_.max_tcp_jerk};
}

bool MotionGenerator::plan_from(const Eigen::VectorXd& q, const MoveCommand& cmd,
                                std::deque<Segment>& out, std::string& why,
                                MotionKind* kind) const {
  // Exactly what the motion check does for a move that starts at q: a generator at rest there.
  MotionGenerator sim(*this);
  sim.reset(q);
  MoveCommand plain = cmd;
  plain.detour = false;
  if (sim.plan_move(plain) == MotionStatus::Unreachable) {
    why = sim.state_.detail;
    return false;
  }
  out = std::move(sim.segments_);
  if (kind != nullptr) *kind = sim.state_.kind;
  return true;
}

Eigen::VectorXd MotionGenerator::queue_end() const {
  if (segments_.empty()) return state_.q;
  const Segment& b = segments_.back();
  return joint_at(b, b.m_start + b.profile.length());
}

std::vector<Eigen::VectorXd> MotionGenerator::samples_ahead(const std::deque<Segment>& segs) const {
  std::vector<Eigen::VectorXd> out;
  bool front = &segs == &segments_;
  for (const Segment& sg : segs) {
    double m0 = sg.m_start;
    if (front) {
      double s = 0, vs = 0;
      sg.profile.eval(seg_t_, s, vs);
      m0 += s;
      front = false;
    }
    const double m1 = sg.m_start + sg.profile.length();
    out.push_back(joint_at(sg, m0));
    for (std::size_t k = 0; k < sg.measure.size(); ++k)
      if (sg.measure[k] > m0 && sg.measure[k] < m1) out.push_back(sg.qs[k]);
    out.push_back(joint_at(sg, m1));
  }
  return out;
}

bool MotionGenerator::polyline(const std::vector<Eigen::VectorXd>& qs, const ProfileLimits& lim,
                               Segment& s) const {
  s = Segment{};
  s.joint = true;
  for (const Eigen::VectorXd& q : qs)
    if (s.qs.empty() || (q - s.qs.back()).cwiseAbs().maxCoeff() > 1e-12) s.qs.push_back(q);
  if (s.qs.size() < 2) return false;
  Eigen::Vector3d p_prev, p;
  Eigen::Quaterniond r_prev, r;
  fk_world(s.qs.front(), p_prev, r_prev);
  s.p0 = p_prev;
  s.r0 = r_prev;
  s.measure.assign(1, 0.0);
  for (std::size_t k = 1; k < s.qs.size(); ++k) {
    fk_world(s.qs[k], p, r);
    const double dm =
        std::max({(p - p_prev).norm(), limits_.rotation_length * r_prev.angularDistance(r),
                  kJointMeasure * (s.qs[k] - s.qs[k - 1]).cwiseAbs().maxCoeff()});
    s.measure.push_back(s.measure.back() + dm);
    p_prev = p;
    r_prev = r;
  }
  s.r1 = r;
  s.u = (p - s.p0).norm() > 1e-12 ? Eigen::Vector3d((p - s.p0).normalized())
                                  : Eigen::Vector3d::UnitZ();
  s.lin_length = s.prof_length = s.measure.back();
  s.limits = lim;
  s.profile.plan(s.prof_length, 0.0, lim);
  return true;
}

MotionStatus MotionGenerator::start_plan(const MoveCommand& cmd, MotionKind kind) {
  target_ = cmd.target;
  final_status_ = MotionStatus::Reached;
  state_.kind = kind;
  state_.detail.clear();
  if (segments_.empty()) {
    state_.status = MotionStatus::Reached;
    v_cmd_.setZero();
  } else {
    state_.status = MotionStatus::Moving;
  }
  return state_.status;
}

}  // namespace hrc::kin
