#include "hrc/kin/motion.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace hrc::kin {
namespace {

std::string fmt_point(const Eigen::Vector3d& p) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.3f, %.3f, %.3f)", p.x(), p.y(), p.z());
  return buf;
}

bool finite(double v) { return std::isfinite(v); }

constexpr double kJointStep = 0.01;     // rad: spacing of the FK samples of a joint path
constexpr double kJointMeasure = 0.02;  // m per rad: a pure joint motion still takes time
// rad: how far the exact IK of a line may be from its interpolated samples (samples are
// check_step apart, so the true difference is far smaller; more means another branch)
constexpr double kSampleTolerance = 0.02;
constexpr double kAtLeavePoint = 1e-4;  // rad: an arm this close to its leave point stands there

bool same_move(const MoveCommand& a, const MoveCommand& b) {
  return a.target == b.target && a.yaw == b.yaw && a.approach_height == b.approach_height &&
         a.depart_height == b.depart_height && a.max_speed == b.max_speed;
}

std::string fmt_num(double v, int decimals) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

// Why the closest IK solution is not one: how far the tool is off in position and pointing.
std::string closest(const IkResult& r) {
  return "(closest: " + fmt_num(r.position_error * 1000.0, 1) + " mm away, tool axis " +
         fmt_num(r.angle_error * 180.0 / M_PI, 1) + " deg off)";
}

}  // namespace

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
  constexpr double kNoLimit = 2.0 * M_PI;  // rad/s: the same rule as the physics's arm bound
  const Eigen::VectorXd& vlim = model_.max_velocity();
  const Eigen::ArrayXd max_step =
      vlim.unaryExpr([](double v) { return std::isfinite(v) ? v : kNoLimit; }).array() * dt_;
  std::vector<Eigen::VectorXd> rows;
  MotionGenerator sim(*this);
  complete = false;
  while (rows.size() < max_ticks) {
    if (sim.segments_.empty()) {
      complete = true;  // step() no longer changes q
      break;
    }
    const Eigen::VectorXd q0 = sim.state_.q;
    sim.step();
    rows.emplace_back((sim.state_.q - q0).array().abs() / max_step);
  }
  Eigen::MatrixXd out(static_cast<Eigen::Index>(rows.size()), model_.dof());
  for (std::size_t i = 0; i < rows.size(); ++i)
    out.row(static_cast<Eigen::Index>(i)) = rows[i].transpose();
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
