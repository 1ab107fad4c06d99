// Motion generator: straight lines, speed cap, approach/depart, retarget blending, hold,
// unreachable targets, joint velocity limits.
#include "hrc/kin/motion.hpp"
#include "robots_dir.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace hrc::kin;

namespace {
const std::string kDir = hrc::testing::robots_dir();

Eigen::Isometry3d base_r1() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(0.45, 0.55, 0.0);
  T.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

MoveCommand move_to(double x, double y, double z, double yaw_deg = 0) {
  MoveCommand c;
  c.target = Eigen::Vector3d(x, y, z);
  c.yaw = yaw_deg * M_PI / 180.0;
  return c;
}

struct RunStats {
  int ticks = 0;
  double max_speed = 0;
  double max_joint_ratio = 0;  // max |dq| / (vmax dt)
  double max_dv = 0;           // max change of TCP velocity between ticks (m/s)
  double max_line_dev = 0;     // distance from the line start -> target
};

// Step until not moving (or max_ticks); collect bounds.
RunStats run_until_done(MotionGenerator& g, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                        int max_ticks, Eigen::Vector3d* v_last = nullptr) {
  RunStats r;
  const RobotModel& m = g.model();
  Eigen::Vector3d v_prev = v_last ? *v_last : Eigen::Vector3d::Zero();
  Eigen::Vector3d p_prev = g.state().tcp.translation();
  Eigen::VectorXd q_prev = g.state().q;
  const Eigen::Vector3d u = (b - a).normalized();
  for (; r.ticks < max_ticks; ++r.ticks) {
    const MotionState& s = g.step();
    EXPECT_TRUE(s.q.allFinite());
    EXPECT_TRUE(m.within_limits(s.q));
    const Eigen::Vector3d p = s.tcp.translation();
    const Eigen::Vector3d v = (p - p_prev) / g.dt();
    r.max_speed = std::max(r.max_speed, s.tcp_speed);
    r.max_dv = std::max(r.max_dv, (v - v_prev).norm());
    for (int i = 0; i < m.dof(); ++i)
      r.max_joint_ratio = std::max(r.max_joint_ratio,
                                   std::abs(s.q[i] - q_prev[i]) / (m.max_velocity()[i] * g.dt()));
    const Eigen::Vector3d d = p - a;
    r.max_line_dev = std::max(r.max_line_dev, (d - d.dot(u) * u).norm());
    p_prev = p;
    v_prev = v;
    q_prev = s.q;
    if (s.status != MotionStatus::Moving) break;
  }
  if (v_last) *v_last = v_prev;
  return r;
}
}  // namespace

TEST(Motion, StraightLineCappedSpeedReachesTarget) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionLimits lim;
  lim.max_tcp_speed = 0.5;
  MotionGenerator g(m, base_r1(), 1.0 / 240.0, lim);
  ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.35, 0.30, 0.35), 0.0));
  const Eigen::Vector3d a = g.state().tcp.translation();
  const Eigen::Vector3d b(-0.05, 0.10, 0.05);
  ASSERT_EQ(g.move(move_to(b.x(), b.y(), b.z(), 90)), MotionStatus::Moving);
  const RunStats r = run_until_done(g, a, b, 240 * 10);
  EXPECT_EQ(g.state().status, MotionStatus::Reached) << g.state().detail;
  EXPECT_LT((g.state().tcp.translation() - b).norm(), 0.005);
  EXPECT_LE(r.max_speed, 0.5 * 1.02);
  EXPECT_GT(r.max_speed, 0.45);  // actually cruises near the cap on a 0.5 m move
  EXPECT_LE(r.max_joint_ratio, 1.0 + 1e-9);
  EXPECT_LT(r.max_line_dev, 1e-4);
  // Tool points down with the commanded yaw.
  const Eigen::Matrix3d R = g.state().tcp.linear();
  EXPECT_NEAR(axis_angle(R.col(2), -Eigen::Vector3d::UnitZ()), 0, 1e-6);
  EXPECT_NEAR(std::atan2(R(1, 0), R(0, 0)), M_PI / 2, 1e-6);
  // Next tick: holds still, status stays reached.
  g.step();
  EXPECT_EQ(g.state().status, MotionStatus::Reached);
  EXPECT_LT(g.state().tcp_speed, 1e-9);
}

TEST(Motion, LowerCommandSpeedIsRespected) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionGenerator g(m, base_r1(), 1.0 / 240.0);
  ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.35, 0.30, 0.35), 0.0));
  MoveCommand c = move_to(0.05, 0.15, 0.10);
  c.max_speed = 0.2;
  const Eigen::Vector3d a = g.state().tcp.translation();
  g.move(c);
  const RunStats r = run_until_done(g, a, c.target, 240 * 20);
  EXPECT_EQ(g.state().status, MotionStatus::Reached);
  EXPECT_LE(r.max_speed, 0.2 * 1.02);
}

TEST(Motion, VerticalDepartAndApproach) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionGenerator g(m, base_r1(), 1.0 / 240.0);
  ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.30, 0.25, 0.10), 0.0));
  const Eigen::Vector3d start = g.state().tcp.translation();
  MoveCommand c = move_to(0.05, 0.10, 0.04, 30);
  c.approach_height = 0.06;
  c.depart_height = 0.05;
  ASSERT_EQ(g.move(c), MotionStatus::Moving);
  bool rose_vertically = true, descended_vertically = true;
  bool departed = false, above_target = false;
  const Eigen::Vector3d above = c.target + Eigen::Vector3d(0, 0, 0.06);
  for (int k = 0; k < 240 * 10 && g.state().status == MotionStatus::Moving; ++k) {
    const Eigen::Vector3d p = g.step().tcp.translation();
    // Phase 1, until the depart height is reached: straight up from the start.
    if (!departed) {
      rose_vertically &= (p.head<2>() - start.head<2>()).norm() < 1e-5;
      departed = p.z() >= start.z() + 0.05 - 1e-6;
    }
    // Last phase, once above the target: straight down onto it.
    if (above_target) descended_vertically &= (p.head<2>() - c.target.head<2>()).norm() < 1e-5;
    above_target = above_target || (p - above).norm() < 1e-6;
  }
  EXPECT_TRUE(departed);
  EXPECT_TRUE(above_target);
  EXPECT_EQ(g.state().status, MotionStatus::Reached);
  EXPECT_TRUE(rose_vertically);
  EXPECT_TRUE(descended_vertically);
}

TEST(Motion, RetargetMidMoveBlendsWithoutJumps) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionLimits lim;
  const double dt = 1.0 / 240.0;
  MotionGenerator g(m, base_r1(), dt, lim);
  ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.35, 0.30, 0.35), 0.0));
  const Eigen::Vector3d a = g.state().tcp.translation();
  g.move(move_to(-0.05, 0.10, 0.05));
  RunStats r1 = run_until_done(g, a, Eigen::Vector3d(-0.05, 0.10, 0.05), 120);  // ~0.5 s: at speed
  ASSERT_EQ(g.state().status, MotionStatus::Moving);
  ASSERT_GT(g.commanded_velocity().norm(), 0.2);
  Eigen::Vector3d v = g.commanded_velocity();
  // Retreat: a target off to the side and up (collision retreat).
  const Eigen::Vector3d b(0.45, 0.45, 0.40);
  ASSERT_EQ(g.move(move_to(b.x(), b.y(), b.z())), MotionStatus::Moving);
  const RunStats r2 = run_until_done(g, g.state().tcp.translation(), b, 240 * 10, &v);
  EXPECT_EQ(g.state().status, MotionStatus::Reached);
  EXPECT_LE(r1.max_joint_ratio, 1.0 + 1e-9);
  EXPECT_LE(r2.max_joint_ratio, 1.0 + 1e-9);
  // No velocity jump beyond the acceleration limit (finite differences: one tick of accel,
  // plus the discretisation of the cosine ramps).
  EXPECT_LE(r2.max_dv, lim.max_tcp_accel * dt * 1.05);
  EXPECT_LE(r2.max_speed, lim.max_tcp_speed * 1.02);
  // Aligned retarget (same direction, further on): continues without braking to zero.
  ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.35, 0.30, 0.30), 0.0));
  g.move(move_to(0.05, 0.30, 0.30));
  for (int k = 0; k < 60; ++k) g.step();
  const double speed_before = g.commanded_velocity().norm();
  g.move(move_to(-0.05, 0.30, 0.30));
  g.step();
  EXPECT_GT(g.commanded_velocity().norm(), speed_before - lim.max_tcp_accel * dt * 1.01);
}

TEST(Motion, HoldStopsSmoothly) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionLimits lim;
  const double dt = 1.0 / 240.0;
  MotionGenerator g(m, base_r1(), dt, lim);
  ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.35, 0.30, 0.35), 0.0));
  g.move(move_to(-0.05, 0.10, 0.05));
  for (int k = 0; k < 120; ++k) g.step();
  Eigen::Vector3d v = g.commanded_velocity();
  g.hold();
  EXPECT_EQ(g.state().status, MotionStatus::Holding);
  const RunStats r =
      run_until_done(g, g.state().tcp.translation(), g.state().tcp.translation() + v, 240 * 3, &v);
  (void)r;
  for (int k = 0; k < 240; ++k) g.step();
  EXPECT_EQ(g.state().status, MotionStatus::Holding);
  EXPECT_LT(g.state().tcp_speed, 1e-9);
  EXPECT_LE(r.max_dv, lim.max_tcp_accel * dt * 1.05);
}

TEST(Motion, UnreachableTargetIsReportedAndArmHolds) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionGenerator g(m, base_r1(), 1.0 / 240.0);
  ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.35, 0.30, 0.35), 0.0));
  const Eigen::VectorXd q0 = g.state().q;
  EXPECT_EQ(g.move(move_to(-1.5, -0.5, 0.05)), MotionStatus::Unreachable);
  EXPECT_FALSE(g.state().detail.empty());
  for (int k = 0; k < 10; ++k) g.step();
  EXPECT_EQ(g.state().status, MotionStatus::Unreachable);
  EXPECT_TRUE(g.state().q.allFinite());
  EXPECT_EQ(g.state().q, q0);
  // Invalid numbers are refused the same way.
  MoveCommand bad = move_to(0.1, 0.1, 0.1);
  bad.target.z() = std::nan("");
  EXPECT_EQ(g.move(bad), MotionStatus::Unreachable);
  EXPECT_NE(g.state().detail.find("invalid"), std::string::npos);
  // And a reachable target afterwards works.
  EXPECT_EQ(g.move(move_to(0.20, 0.25, 0.25)), MotionStatus::Moving);
}

TEST(Motion, JointVelocityLimitsSlowThePath) {
  // A large yaw change over a short move needs the wrist roll to turn fast: the generator must
  // slow down rather than exceed the wrist's velocity limit.
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionLimits lim;
  lim.max_tcp_speed = 1.5;
  lim.max_tcp_accel = 10.0;
  lim.max_tcp_jerk = 200.0;
  MotionGenerator g(m, base_r1(), 1e-3, lim);
  ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.20, 0.25, 0.25), 0.0));
  const Eigen::Vector3d a = g.state().tcp.translation();
  const Eigen::Vector3d b(0.20, 0.15, 0.25);
  ASSERT_EQ(g.move(move_to(b.x(), b.y(), b.z(), 175)), MotionStatus::Moving);
  const RunStats r = run_until_done(g, a, b, 20000);
  EXPECT_EQ(g.state().status, MotionStatus::Reached);
  EXPECT_LE(r.max_joint_ratio, 1.0 + 1e-9);
  EXPECT_LT(r.max_line_dev, 1e-4);
}

// A straight line from one side of the base to the other passes over the base, where the tool
// cannot point down: the planner replaces it by a joint-space move that reaches the target.
TEST(Motion, LineOverTheBaseBecomesAFeasibleJointMove) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  for (const double cap : {0.5, 0.2}) {
    MotionLimits lim;
    lim.max_tcp_speed = cap;
    MotionGenerator g(m, base_r1(), 1.0 / 240.0, lim);
    ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.25, 0.55, 0.15), 0.0));
    const Eigen::Vector3d a = g.state().tcp.translation();
    const Eigen::Vector3d b(0.65, 0.55, 0.15);
    ASSERT_EQ(g.move(move_to(b.x(), b.y(), b.z(), 30)), MotionStatus::Moving) << g.state().detail;
    EXPECT_EQ(g.state().kind, MotionKind::Joint);
    double min_z = 1.0;
    int ticks = 0;
    for (; ticks < 240 * 20 && g.state().status == MotionStatus::Moving; ++ticks) {
      const RunStats r = run_until_done(g, a, b, 1);  // one tick: joint limits checked inside
      min_z = std::min(min_z, g.state().tcp.translation().z());
      EXPECT_LE(r.max_speed, cap * 1.02);
      EXPECT_LE(r.max_joint_ratio, 1.0 + 1e-9);
    }
    EXPECT_EQ(g.state().status, MotionStatus::Reached) << g.state().detail;
    EXPECT_EQ(g.state().kind, MotionKind::Joint);
    EXPECT_LT((g.state().tcp.translation() - b).norm(), 0.005);
    EXPECT_GE(min_z, lim.table_z + lim.table_clearance - 1e-6);
    const Eigen::Matrix3d R = g.state().tcp.linear();
    EXPECT_NEAR(axis_angle(R.col(2), -Eigen::Vector3d::UnitZ()), 0, 1e-6);
  }
}

TEST(Motion, JointMoveKeepsDepartAndApproachVertical) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionGenerator g(m, base_r1(), 1.0 / 240.0);
  ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.25, 0.55, 0.10), 0.0));
  const Eigen::Vector3d start = g.state().tcp.translation();
  MoveCommand c = move_to(0.65, 0.55, 0.05);
  c.approach_height = 0.05;
  c.depart_height = 0.05;
  ASSERT_EQ(g.move(c), MotionStatus::Moving) << g.state().detail;
  EXPECT_EQ(g.state().kind, MotionKind::Joint);
  bool rose_vertically = true, descended_vertically = true, departed = false, above = false;
  const Eigen::Vector3d pre = c.target + Eigen::Vector3d(0, 0, 0.05);
  for (int k = 0; k < 240 * 10 && g.state().status == MotionStatus::Moving; ++k) {
    const Eigen::Vector3d p = g.step().tcp.translation();
    if (!departed) {
      rose_vertically &= (p.head<2>() - start.head<2>()).norm() < 1e-5;
      departed = p.z() >= start.z() + 0.05 - 1e-6;
    }
    if (above) descended_vertically &= (p.head<2>() - c.target.head<2>()).norm() < 1e-5;
    above = above || (p - pre).norm() < 1e-6;
  }
  EXPECT_EQ(g.state().status, MotionStatus::Reached) << g.state().detail;
  EXPECT_TRUE(departed && above);
  EXPECT_TRUE(rose_vertically);
  EXPECT_TRUE(descended_vertically);
}

TEST(Motion, HoldAndRetargetMidJointMoveStaySmooth) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionLimits lim;
  const double dt = 1.0 / 240.0;
  for (const bool retarget : {false, true}) {
    MotionGenerator g(m, base_r1(), dt, lim);
    ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.25, 0.55, 0.15), 0.0));
    ASSERT_EQ(g.move(move_to(0.65, 0.55, 0.15)), MotionStatus::Moving);
    Eigen::Vector3d v;
    RunStats r0 =
        run_until_done(g, g.state().tcp.translation(), Eigen::Vector3d(0.65, 0.55, 0.15), 120, &v);
    ASSERT_EQ(g.state().status, MotionStatus::Moving);
    ASSERT_GT(g.state().tcp_speed, 0.05);
    if (retarget) {
      ASSERT_EQ(g.move(move_to(0.45, 0.30, 0.30)), MotionStatus::Moving) << g.state().detail;
    } else {
      g.hold();
    }
    const RunStats r = run_until_done(g, g.state().tcp.translation(),
                                      g.state().tcp.translation() + v, 240 * 10, &v);
    EXPECT_LE(r0.max_joint_ratio, 1.0 + 1e-9);
    EXPECT_LE(r.max_joint_ratio, 1.0 + 1e-9);
    EXPECT_LE(r.max_speed, lim.max_tcp_speed * 1.02);
    // Braking along the joint path: the finite-difference velocity changes smoothly (the FK
    // path curves, so allow a little more than one tick of acceleration).
    EXPECT_LE(r.max_dv, lim.max_tcp_accel * dt * 1.5);
    EXPECT_EQ(g.state().status, retarget ? MotionStatus::Reached : MotionStatus::Holding)
        << g.state().detail;
  }
}

// Every way is blocked (a table above the arm's shoulder, no crossing height in reach): the move
// is refused before it starts, the arm does not move, and the message names where and why.
TEST(Motion, MoveInfeasibleInEveryWayIsRefusedBeforeItStarts) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionLimits lim;
  lim.table_z = 0.3;
  lim.via_height = 2.0;
  MotionGenerator g(m, base_r1(), 1.0 / 240.0, lim);
  ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.25, 0.55, 0.15), 0.0));
  const Eigen::VectorXd q0 = g.state().q;
  EXPECT_EQ(g.move(move_to(0.65, 0.55, 0.15)), MotionStatus::Unreachable);
  const std::string& d = g.state().detail;
  EXPECT_NE(d.find("target (0.650, 0.550, 0.150)"), std::string::npos) << d;
  EXPECT_NE(d.find("straight line: path leaves the workspace near ("), std::string::npos) << d;
  EXPECT_NE(d.find("joint move: joint path takes joint"), std::string::npos) << d;
  EXPECT_NE(d.find("via points: at height"), std::string::npos) << d;
  EXPECT_EQ(g.state().kind, MotionKind::None);
  for (int k = 0; k < 10; ++k) g.step();
  EXPECT_EQ(g.state().q, q0);
}

TEST(Motion, FeasibleLinesStayLinear) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionGenerator g(m, base_r1(), 1.0 / 240.0);
  ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.35, 0.30, 0.35), 0.0));
  ASSERT_EQ(g.move(move_to(-0.05, 0.10, 0.05)), MotionStatus::Moving);
  EXPECT_EQ(g.state().kind, MotionKind::Linear);
}

// Neither the line nor a joint move (a raised table keeps the wrist too high for it) but via
// points: up to the crossing height, across, down; limits and the speed cap hold throughout.
TEST(Motion, ViaPointsWhenLineAndJointMoveAreBlocked) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionLimits lim;
  lim.table_z = 0.15;
  MotionGenerator g(m, base_r1(), 1.0 / 240.0, lim);
  ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.491, 0.964, 0.089), 0.0));
  const Eigen::Vector3d a = g.state().tcp.translation();
  const Eigen::Vector3d b(0.683, 0.003, 0.194);
  ASSERT_EQ(g.move(move_to(b.x(), b.y(), b.z())), MotionStatus::Moving) << g.state().detail;
  EXPECT_EQ(g.state().kind, MotionKind::Via);
  double max_z = 0.0;
  int ticks = 0;
  for (; ticks < 240 * 20 && g.state().status == MotionStatus::Moving; ++ticks) {
    const RunStats r = run_until_done(g, a, b, 1);
    max_z = std::max(max_z, g.state().tcp.translation().z());
    EXPECT_LE(r.max_speed, lim.max_tcp_speed * 1.02);
    EXPECT_LE(r.max_joint_ratio, 1.0 + 1e-9);
  }
  EXPECT_EQ(g.state().status, MotionStatus::Reached) << g.state().detail;
  EXPECT_LT((g.state().tcp.translation() - b).norm(), 0.005);
  EXPECT_GE(max_z, lim.via_height - 1e-6);
}

// The exchange step's declared event: min_ticks_to_end() never exceeds the ticks the motion
// in progress still takes, and is exact on a move no joint limit slows (docs/ARCHITECTURE.md).
TEST(Motion, MinTicksToEndBoundsTheMotionsEnd) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionLimits lim;
  lim.max_tcp_speed = 0.5;
  for (const bool joint_move : {false, true}) {
    MotionGenerator g(m, base_r1(), 1.0 / 240.0, lim);
    // a line over the base becomes a joint move (see LineOverTheBaseBecomesAFeasibleJointMove)
    const Eigen::Vector3d start =
        joint_move ? Eigen::Vector3d(0.25, 0.55, 0.15) : Eigen::Vector3d(0.35, 0.30, 0.35);
    ASSERT_TRUE(g.reset_to_pose(start, 0.0));
    EXPECT_EQ(g.min_ticks_to_end(), 0u);  // at rest
    MoveCommand c = joint_move ? move_to(0.65, 0.55, 0.15, 30) : move_to(-0.05, 0.10, 0.05, 90);
    if (!joint_move) c.approach_height = 0.05;
    ASSERT_EQ(g.move(c), MotionStatus::Moving) << g.state().detail;
    std::vector<uint64_t> bounds;
    int ticks = 0;
    while (g.state().status == MotionStatus::Moving && ticks < 240 * 20) {
      bounds.push_back(g.min_ticks_to_end());
      g.step();
      ++ticks;
    }
    ASSERT_EQ(g.state().status, MotionStatus::Reached) << g.state().detail;
    EXPECT_EQ(g.min_ticks_to_end(), 0u);
    int exact = 0;
    for (std::size_t i = 0; i < bounds.size(); ++i) {
      const auto left = static_cast<uint64_t>(ticks) - i;  // steps until Reached, this one too
      EXPECT_LE(bounds[i], left) << "tick " << i;
      EXPECT_GE(bounds[i], 1u);
      if (bounds[i] == left) ++exact;
    }
    if (!joint_move) EXPECT_EQ(exact, ticks) << "a straight move is bounded exactly";
  }
}

TEST(Motion, LinkSpeedsBoundEveryPointOfEachLink) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionLimits lim;
  lim.max_tcp_speed = 0.5;
  MotionGenerator g(m, base_r1(), 1.0 / 240.0, lim);
  ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.35, 0.30, 0.35), 0.0));
  MoveCommand c = move_to(-0.05, 0.10, 0.05, 90);
  c.approach_height = 0.05;
  ASSERT_EQ(g.move(c), MotionStatus::Moving) << g.state().detail;
  const MotionGenerator::SpeedForecast f = g.speed_forecast(240 * 20);
  ASSERT_TRUE(f.complete);
  ASSERT_EQ(f.link_linear.rows(), f.joint_fractions.rows());
  ASSERT_EQ(f.link_angular.cols(), m.dof());
  // Points of each link (its frame's origin and 0.3 m away along each axis) move by at most
  // (linear + angular r) dt from one real step to the next.
  std::vector<Eigen::Isometry3d> X0, X1;
  m.joint_child_frames(g.state().q, X0);
  double fastest = 0.0;
  for (Eigen::Index i = 0; i < f.link_linear.rows(); ++i) {
    g.step();
    m.joint_child_frames(g.state().q, X1);
    for (int j = 0; j < m.dof(); ++j) {
      const auto k = static_cast<std::size_t>(j);
      for (const Eigen::Vector3d& r : std::vector<Eigen::Vector3d>{
               Eigen::Vector3d::Zero(), Eigen::Vector3d(0.3, 0, 0), Eigen::Vector3d(0, 0.3, 0),
               Eigen::Vector3d(0, 0, 0.3), Eigen::Vector3d(-0.2, 0.2, -0.2)}) {
        const double moved = (X1[k] * r - X0[k] * r).norm() / g.dt();
        fastest = std::max(fastest, moved);
        ASSERT_LE(moved, f.link_linear(i, j) + f.link_angular(i, j) * r.norm() + 1e-9)
            << "step " << i << " joint " << j;
      }
    }
    std::swap(X0, X1);
  }
  EXPECT_EQ(g.state().status, MotionStatus::Reached);
  // the bound is tight: the arm's fastest point is near the TCP's speed limit, far below what
  // the joints' velocity limits would allow
  EXPECT_GT(fastest, 0.2);
  EXPECT_LT(f.link_linear.maxCoeff(), 1.0);
  // the first joint's child frame has its origin on that joint's axis: it turns, never moves
  EXPECT_LT(f.link_linear.col(0).maxCoeff(), 1e-9);
  EXPECT_GT(f.link_angular.col(0).maxCoeff(), 0.01);
}

TEST(Motion, JointSpeedFractionsAreWhatTheStepsDo) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionLimits lim;
  lim.max_tcp_speed = 0.5;
  MotionGenerator g(m, base_r1(), 1.0 / 240.0, lim);
  ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.35, 0.30, 0.35), 0.0));
  bool complete = false;
  EXPECT_EQ(g.joint_speed_fractions(100, complete).rows(), 0);  // at rest: nothing moves
  EXPECT_TRUE(complete);
  MoveCommand c = move_to(-0.05, 0.10, 0.05, 90);
  c.approach_height = 0.05;
  ASSERT_EQ(g.move(c), MotionStatus::Moving) << g.state().detail;
  for (int k = 0; k < 30; ++k) g.step();  // from the middle of the move
  const Eigen::MatrixXd predicted = g.joint_speed_fractions(240 * 20, complete);
  ASSERT_TRUE(complete);
  ASSERT_GT(predicted.rows(), 100);
  EXPECT_LE(predicted.maxCoeff(), 1.0 + 1e-9);  // the joint velocity limits hold
  EXPECT_GT(predicted.maxCoeff(), 0.05);        // it does move
  // The real steps do exactly what the copy predicted, then stop.
  for (Eigen::Index i = 0; i < predicted.rows(); ++i) {
    const Eigen::VectorXd q0 = g.state().q;
    g.step();
    const Eigen::ArrayXd f = (g.state().q - q0).array().abs() / (m.max_velocity().array() * g.dt());
    for (int j = 0; j < m.dof(); ++j) ASSERT_EQ(f[j], predicted(i, j)) << "step " << i;
  }
  EXPECT_EQ(g.state().status, MotionStatus::Reached);
  // A lookahead shorter than the motion says so.
  ASSERT_EQ(g.move(move_to(0.35, 0.30, 0.35)), MotionStatus::Moving);
  EXPECT_EQ(g.joint_speed_fractions(10, complete).rows(), 10);
  EXPECT_FALSE(complete);
}
