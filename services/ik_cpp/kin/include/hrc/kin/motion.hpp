#pragma once
// Motion generator for one arm, one step per fixed tick dt. A move is planned once, when it is
// commanded, and then followed tick by tick:
//  - LINEAR: straight TCP lines (optional vertical depart, main line, optional vertical approach),
//    kept wherever the line is feasible (IK along it, no branch switch);
//  - JOINT: vertical depart, a joint-space interpolation to an IK solution of the approach point
//    (its TCP path checked to stay above the table), vertical approach;
//  - VIA: vertical depart, up to a safe height, across, down, vertical approach (all lines).
// Every kind has a smooth speed profile (SpeedProfile) capped at the TCP speed limit (a joint
// move is time-scaled by the TCP arc length of its FK path) and slowed when a joint would exceed
// its velocity limit; tool pointing down with a yaw. A new command mid-move starts from the
// current position and velocity (continuing if aligned, otherwise braking along the current path
// first), so there is no velocity jump beyond the acceleration limit. A move infeasible in every
// way is refused before it starts, naming where and why.
//
// Every plan is checked and sampled in joint space when it is made (a joint configuration every
// check_step metres of line, every 0.01 rad of joint move), and step() only interpolates those
// samples: a plan that was accepted is always followed to its end (no IK while moving).
//
// Interruptions come back to the task move (docs/task-semantics.md, "Interruptions"). A move
// commanded without `detour` is the task move; a hold or a `detour` move (a retreat) leaves it
// after braking on its path, at the leave point. A detour is planned from where the brake ends;
// if no plan is feasible there, the arm retraces its own executed path (joint space) back to
// where the task move began and plans the detour from there. When the task move is commanded
// again the arm goes back to the very plan it left, which the motion check judged: from the leave
// point along its rest, or after a detour on to the plan's end (the top of its approach) by a
// checked joint move, else to the leave point (a checked joint move, or its path retraced); a
// different task move is planned from the leave point at rest, as the motion check did.

#include "hrc/kin/ik.hpp"
#include "hrc/kin/robot_model.hpp"
#include "hrc/kin/speed_profile.hpp"

#include <Eigen/Geometry>

#include <deque>
#include <optional>
#include <string>
#include <vector>

namespace hrc::kin {

enum class MotionStatus { Idle, Moving, Reached, Holding, Unreachable };
const char* to_string(MotionStatus s);

// How the current (or last) move was planned; None before the first move and for a hold.
enum class MotionKind { None, Linear, Joint, Via };
const char* to_string(MotionKind k);

struct MotionLimits {
  double max_tcp_speed = 0.5;      // m/s, default for commands with max_speed = 0
  double max_tcp_accel = 2.0;      // m/s^2
  double max_tcp_jerk = 20.0;      // m/s^3
  double reach_tolerance = 0.005;  // m: "reached" radius
  double rotation_length = 0.1;    // m per rad: how much path a pure reorientation counts for
  double check_step = 0.01;        // m: spacing of the reachability check along a new path
  double table_z = 0.0;            // m, world: the table top; joint and via moves stay above it
  double table_clearance = 0.02;   // m: TCP clearance over the table on joint moves (unless an
                                   //   endpoint is lower); elbow and wrist stay above table_z
  double via_height = 0.25;        // m, world: lowest crossing height of a VIA move
};

struct MoveCommand {
  Eigen::Vector3d target = Eigen::Vector3d::Zero();  // TCP position, world frame
  double yaw = 0.0;              // rad, tool x axis about world z (tool pointing down)
  double approach_height = 0.0;  // > 0: arrive vertically from target + h z
  double depart_height = 0.0;    // > 0: first rise vertically by h
  double max_speed = 0.0;        // m/s; 0 = MotionLimits::max_tcp_speed
  bool detour = false;           // a safety interruption (retreat): comes back to the task move
};

struct MotionState {
  Eigen::VectorXd q;                                      // joint positions
  Eigen::Isometry3d tcp = Eigen::Isometry3d::Identity();  // world frame
  double tcp_speed = 0.0;                                 // m/s, from consecutive TCP positions
  MotionStatus status = MotionStatus::Idle;
  MotionKind kind = MotionKind::None;  // how the current/last move was planned
  std::string detail;                  // why a target is unreachable, etc.
};

class MotionGenerator {
 public:
  // world_T_base: pose of the robot base in the world. dt: tick period (s), > 0.
  MotionGenerator(const RobotModel& model, const Eigen::Isometry3d& world_T_base, double dt,
                  MotionLimits limits = {}, IkOptions ik_options = {});

  // Set the joints (clamped into the limits), stop, status Idle.
  void reset(const Eigen::VectorXd& q);
  // Put the arm at a tool-down pose (world) with no motion; false (unchanged) if unreachable.
  bool reset_to_pose(const Eigen::Vector3d& position, double yaw);

  // Start a move. Returns the new status: Moving, Reached (already there) or Unreachable
  // (target or path not reachable, or invalid command; detail says why; the arm stops smoothly).
  MotionStatus move(const MoveCommand& cmd);
  // Stop smoothly on the current path and hold (leaves the task move: see the header comment).
  void hold();
  // Speed scale in [0, 1] (speed and separation monitoring): the path parameter of the motion
  // in progress, and of later moves, advances at scale x nominal, so the path is unchanged and
  // scale 0 stops the arm on it. The applied scale follows the requested one at no more than
  // max_tcp_accel / max_tcp_speed per second: slowing down, stopping and resuming stay within
  // the acceleration limit (a stop from speed v <= scale x max_tcp_speed takes at most
  // v / max_tcp_accel s and v^2 / (2 max_tcp_accel) m). Values outside [0, 1] are clamped.
  void set_speed_scale(double scale);
  double speed_scale() const { return scale_; }  // applied in the last step
  double requested_speed_scale() const { return scale_target_; }
  // Advance one tick.
  const MotionState& step();
  // Ticks, at least, until the motion in progress ends (its status leaves Moving: reached,
  // holding): the path parameter advances at most dt per tick (time scale and speed scale are
  // <= 1) and each segment takes at least one tick. 0 if no motion is in progress. Failures
  // during the move (a waypoint unreachable) may come earlier.
  uint64_t min_ticks_to_end() const;
  // How fast each joint will move from the next tick on, absent new commands and speed-scale
  // changes: row i, column j is the i-th coming step's |dq_j| / (dt v_j), v_j the joint's
  // velocity limit (2 pi rad/s where the URDF gives none). Simulated on a copy of this
  // generator, so it is exactly what step() will do. Stops where the motion ends (nothing moves
  // after that: `complete` true), where a speed scale of 0 holds it still (likewise, until a
  // command) or after max_ticks steps (`complete` false: the rest unknown).
  Eigen::MatrixXd joint_speed_fractions(std::size_t max_ticks, bool& complete) const;
  // The same steps, with how fast each movable joint's child link moves in each of them
  // (RobotModel::joint_child_frames): `link_linear` m/s of its frame's origin, `link_angular`
  // rad/s of its turn, from one tick's pose to the next. Any point of that link (and of what is
  // rigidly fixed to it) at distance r from the origin moves at most link_linear + link_angular r.
  struct SpeedForecast {
    Eigen::MatrixXd joint_fractions;  // as joint_speed_fractions
    Eigen::MatrixXd link_linear;      // steps x dof, m/s
    Eigen::MatrixXd link_angular;     // steps x dof, rad/s
    bool complete = false;
  };
  SpeedForecast speed_forecast(std::size_t max_ticks) const;

  const MotionState& state() const { return state_; }
  double dt() const { return dt_; }
  // The TCP velocity the current step commands (the speed scale applied).
  Eigen::Vector3d commanded_velocity() const { return v_cmd_ * scale_; }
  const RobotModel& model() const { return model_; }
  // Can the arm reach `position` (world) tool-down with `yaw`? Fills the position error.
  bool reachable(const Eigen::Vector3d& position, double yaw, double* position_error = nullptr);

 private:
  // What happens when a segment has been followed to its end.
  enum class Mark { None, Left, Rejoined, NewBase };
  struct Segment {
    Eigen::Vector3d p0 = Eigen::Vector3d::Zero();  // start
    Eigen::Vector3d u = Eigen::Vector3d::UnitZ();  // unit direction
    double lin_length = 0.0;                       // m
    double prof_length = 0.0;  // profile units (>= lin_length when rotation dominates)
    Eigen::Quaterniond r0 = Eigen::Quaterniond::Identity();  // orientation at start (world)
    Eigen::Quaterniond r1 = Eigen::Quaterniond::Identity();  // and at the end
    SpeedProfile profile;
    ProfileLimits limits;
    // The path in joint space: qs[k] at path measure measure[k] (TCP arc length, or rotation /
    // joint motion where they dominate; the profile's units), interpolated linearly between.
    // The profile runs over measure from m_start (> 0 when braking inside the segment).
    // joint: planned as a joint interpolation (its TCP velocity comes from FK), else a line.
    bool joint = false;
    std::vector<Eigen::VectorXd> qs;
    std::vector<double> measure;
    double m_start = 0.0;
    Mark mark = Mark::None;
  };
  // The task move: what interruptions come back to.
  struct Base {
    MoveCommand cmd;
    std::vector<Eigen::VectorXd> trail;  // every configuration since it began (front: where)
    bool left = false;                   // a hold or a detour took the arm off its path
    bool leave_pending = false;          // still braking on its path to the leave point
    std::size_t leave_idx = 0;           // trail index of the leave point
    Eigen::VectorXd q_leave;             // the leave point
    std::deque<Segment> rest;            // the move's remainder from the leave point, at rest
    std::optional<MoveCommand> next;     // a different task move planned from the leave point
    Eigen::VectorXd q_end;               // where its plan ends
    std::deque<Segment> last;            // its plan's last segment (the approach, if any)
  };
  // Where a plan being built stands: joints, TCP position and orientation (world).
  struct Cursor {
    Eigen::VectorXd q;
    Eigen::Vector3d p;
    Eigen::Quaterniond r;
  };

  // move() without the task-move bookkeeping: a plan from the current state.
  MotionStatus plan_move(const MoveCommand& cmd);
  // A plan for `cmd` from `q` at rest (a copy of this generator plans it); false and why if none.
  bool plan_from(const Eigen::VectorXd& q, const MoveCommand& cmd, std::deque<Segment>& out,
                 std::string& why, MotionKind* kind) const;
  // Hold or detour: leave the task move (brake on its path, remember the rest) or, when already
  // off it, brake on the current path. The queue is then the brake only.
  void leave();
  // A new task move starts here (the arm at rest or on its way): its trail starts now.
  void begin_base(const MoveCommand& cmd);
  MotionStatus detour(const MoveCommand& cmd);
  MotionStatus resume(const MoveCommand& cmd);
  // Where the queue ends (the current joints when it is empty).
  Eigen::VectorXd queue_end() const;
  // The joint configurations of `segs` from their current position to their ends, in order.
  std::vector<Eigen::VectorXd> samples_ahead(const std::deque<Segment>& segs) const;
  // One joint-space segment through `qs` (from rest to rest), or false if fewer than 2 differ.
  bool polyline(const std::vector<Eigen::VectorXd>& qs, const ProfileLimits& lim,
                Segment& out) const;
  // Start a composite plan (the brake already in segments_).
  MotionStatus start_plan(const MoveCommand& target_cmd, MotionKind kind);
  ProfileLimits limits_for(const MoveCommand& cmd) const;
  void plan_to(const std::vector<Eigen::Vector3d>& points, int rotate_segment,
               const Eigen::Matrix3d& goal_R, const ProfileLimits& lim);
  void brake_segment(const ProfileLimits& lim);
  bool solve_pose(const Eigen::Vector3d& p_world, const Eigen::Matrix3d& R_world,
                  const Eigen::VectorXd& seed, IkResult& res);
  // IK along the planned segments every check_step: false (and why) if the arm cannot follow.
  bool check_path(std::string& why);
  // Also samples the lines (Segment::qs) as it goes.
  bool check_segments(std::deque<Segment>& segs, Eigen::VectorXd seed, std::string& why);
  // The fallbacks: a plan of the given kind from the current state into `out`, or why not.
  bool plan_joint(const MoveCommand& cmd, const Eigen::Matrix3d& goal_R, const ProfileLimits& lim,
                  std::deque<Segment>& out, std::string& why);
  bool plan_via(const MoveCommand& cmd, const Eigen::Matrix3d& goal_R, const ProfileLimits& lim,
                std::deque<Segment>& out, std::string& why);
  // The start every planned kind shares: brake what is under way, then leave vertically.
  bool brake_and_depart(const MoveCommand& cmd, const ProfileLimits& lim, std::deque<Segment>& out,
                        Cursor& c, std::string& why);
  // Stops the current motion along its own path (no-op at rest); the cursor after it.
  bool brake_prefix(const ProfileLimits& lim, std::deque<Segment>& out, Cursor& c,
                    std::string& why);
  // A checked straight line from the cursor to p (rotating to r1); advances the cursor.
  bool append_line(std::deque<Segment>& out, Cursor& c, const Eigen::Vector3d& p,
                   const Eigen::Quaterniond& r1, const ProfileLimits& lim, std::string& why);
  // A checked joint interpolation from the cursor to q1; advances the cursor.
  bool append_joint(std::deque<Segment>& out, Cursor& c, const Eigen::VectorXd& q1,
                    const ProfileLimits& lim, std::string& why);
  Eigen::VectorXd joint_at(const Segment& s, double m) const;
  // Adds a sample at m on a line, on the exact straight line, so that a segment cut there ends
  // (and its remainder begins) where the ticks before it were refined to: no jump at the cut.
  void pin_sample(Segment& s, double m);
  // A segment that stops on s's path from position m_now at speed v (profile units).
  Segment brake_on(const Segment& s, double m_now, double v, const ProfileLimits& lim);
  // s's path from m on, re-planned from rest (empty if nothing is left of it).
  std::deque<Segment> remainder_from(const Segment& s, double m);
  // A marked segment was followed to its end (cmd: the new task move, for Mark::NewBase).
  void segment_done_mark(Mark mark, std::optional<MoveCommand> cmd);
  void fk_world(const Eigen::VectorXd& q, Eigen::Vector3d& p, Eigen::Quaterniond& r) const;
  void update_tcp(double dt_for_speed);
  void stop_with(MotionStatus status, const std::string& detail);

  const RobotModel& model_;
  Eigen::Isometry3d world_T_base_, base_T_world_;
  double dt_;
  MotionLimits limits_;
  IkSolver ik_;
  // The home pose's joints (reset_to_pose): a redundant arm's joint moves are solved from
  // there first (plan_joint). Empty: no home yet.
  Eigen::VectorXd rest_;

  MotionState state_;
  std::deque<Segment> segments_;
  double seg_t_ = 0.0;         // time into the current segment's profile
  double time_scale_ = 1.0;    // < 1 while a joint velocity limit binds
  double scale_ = 1.0;         // speed scale applied (set_speed_scale)
  double scale_target_ = 1.0;  // speed scale requested
  // Commanded TCP velocity (world) at speed scale 1: the plans blend in these nominal units.
  Eigen::Vector3d v_cmd_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d target_ = Eigen::Vector3d::Zero();
  MotionStatus final_status_ = MotionStatus::Reached;
  double meas_speed_ = 0.0;  // current speed in the front joint segment's measure units
  IkResult ik_res_;
  std::optional<Base> base_;
  Eigen::VectorXd q_prev_;
  Eigen::Vector3d p_prev_;
};

}  // namespace hrc::kin
