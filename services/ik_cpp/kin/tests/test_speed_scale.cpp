// Speed scaling (speed and separation monitoring): the path stays the same, scale 0 stops the arm
// on it, the scaling itself stays within the acceleration limit.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <vector>

#include "hrc/kin/motion.hpp"
#include "robots_dir.hpp"

using namespace hrc::kin;

namespace {
const std::string kDir = hrc::testing::robots_dir();
constexpr double kDt = 1.0 / 240.0;

Eigen::Isometry3d base_r1() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(0.45, 0.55, 0.0);
  T.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

struct MoveRun {
  std::vector<Eigen::Vector3d> tcp;  // one per tick
  std::vector<Eigen::VectorXd> q;
  double max_dv = 0;  // largest change of TCP velocity between ticks (m/s)
  MotionStatus status = MotionStatus::Idle;
};

// Starts at `start`, moves to `target` and steps until the arm stops moving; `scale_at(tick)`
// gives the speed scale requested before each tick.
MoveRun run_move(const Eigen::Vector3d& start, const Eigen::Vector3d& target, MotionKind want,
                 const std::function<double(int)>& scale_at) {
  static const RobotModel kModel = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionLimits lim;
  lim.max_tcp_speed = 0.5;
  MotionGenerator g(kModel, base_r1(), kDt, lim);
  EXPECT_TRUE(g.reset_to_pose(start, 0.0));
  MoveCommand c;
  c.target = target;
  EXPECT_EQ(g.move(c), MotionStatus::Moving) << g.state().detail;
  EXPECT_EQ(g.state().kind, want);
  MoveRun r;
  Eigen::Vector3d p_prev = g.state().tcp.translation(), v_prev = Eigen::Vector3d::Zero();
  for (int k = 0; k < 240 * 60 && g.state().status == MotionStatus::Moving; ++k) {
    g.set_speed_scale(scale_at(k));
    const MotionState& s = g.step();
    const Eigen::Vector3d p = s.tcp.translation(), v = (p - p_prev) / kDt;
    r.max_dv = std::max(r.max_dv, (v - v_prev).norm());
    r.tcp.push_back(p);
    r.q.push_back(s.q);
    p_prev = p;
    v_prev = v;
  }
  r.status = g.state().status;
  return r;
}

double distance_to_polyline(const Eigen::Vector3d& p, const std::vector<Eigen::Vector3d>& line) {
  double best = (p - line.front()).norm();
  for (std::size_t i = 1; i < line.size(); ++i) {
    const Eigen::Vector3d a = line[i - 1], ab = line[i] - a;
    const double L2 = ab.squaredNorm();
    const double f = L2 > 0 ? std::clamp((p - a).dot(ab) / L2, 0.0, 1.0) : 0.0;
    best = std::min(best, (a + f * ab - p).norm());
  }
  return best;
}

// Slows to 0.3, stops for 2 s, resumes: a profile that exercises every part of the scaling.
double slow_stop_go(int k) {
  if (k < 60) return 1.0;
  if (k < 150) return 0.3;
  if (k < 150 + 480) return 0.0;
  return 1.0;
}

void expect_same_path(const Eigen::Vector3d& a, const Eigen::Vector3d& b, MotionKind kind) {
  const MoveRun nominal = run_move(a, b, kind, [](int) { return 1.0; });
  const MoveRun scaled = run_move(a, b, kind, slow_stop_go);
  ASSERT_EQ(nominal.status, MotionStatus::Reached);
  ASSERT_EQ(scaled.status, MotionStatus::Reached);
  EXPECT_GT(scaled.tcp.size(), nominal.tcp.size() + 480);  // it did stop for a while
  double worst = 0;
  for (const auto& p : scaled.tcp) worst = std::max(worst, distance_to_polyline(p, nominal.tcp));
  EXPECT_LT(worst, 2e-4) << "the scaled TCP left the nominal path";
  EXPECT_LT((scaled.tcp.back() - nominal.tcp.back()).norm(), 1e-6);
  // Scaling decelerates at no more than the acceleration limit (2 m/s^2), with one tick's slack.
  EXPECT_LE(scaled.max_dv, nominal.max_dv + 2.0 * kDt * 1.05);
}
}  // namespace

TEST(SpeedScale, LinearPathIsUnchanged) {
  expect_same_path({0.35, 0.30, 0.35}, {-0.05, 0.10, 0.05}, MotionKind::Linear);
}

TEST(SpeedScale, JointPathIsUnchanged) {
  expect_same_path({0.25, 0.55, 0.15}, {0.65, 0.55, 0.15}, MotionKind::Joint);
}

TEST(SpeedScale, ScaleZeroStopsTheArmOnItsPathAndItResumes) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionLimits lim;
  lim.max_tcp_speed = 0.5;
  MotionGenerator g(m, base_r1(), kDt, lim);
  ASSERT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.35, 0.30, 0.35), 0.0));
  MoveCommand c;
  c.target = Eigen::Vector3d(-0.05, 0.10, 0.05);
  g.move(c);
  for (int k = 0; k < 120; ++k) g.step();  // cruising
  const double v0 = g.state().tcp_speed;
  ASSERT_GT(v0, 0.4);
  g.set_speed_scale(0.0);
  const Eigen::Vector3d p0 = g.state().tcp.translation();
  // At most v0 / a (0.25 s) to stop, over at most v0^2 / (2 a) (+ one tick).
  const int stop_ticks = static_cast<int>(std::ceil(v0 / lim.max_tcp_accel / kDt)) + 1;
  for (int k = 0; k < stop_ticks; ++k) g.step();
  EXPECT_LT(g.state().tcp_speed, 1e-9);
  EXPECT_LE((g.state().tcp.translation() - p0).norm(),
            v0 * v0 / (2 * lim.max_tcp_accel) + v0 * kDt);
  const Eigen::Vector3d stopped_at = g.state().tcp.translation();
  for (int k = 0; k < 240 * 5; ++k) g.step();
  EXPECT_EQ(g.state().status, MotionStatus::Moving);  // stopped, not done: the move waits
  EXPECT_LT((g.state().tcp.translation() - stopped_at).norm(), 1e-12);
  EXPECT_EQ(g.speed_scale(), 0.0);
  EXPECT_LT(g.commanded_velocity().norm(), 1e-12);
  g.set_speed_scale(1.0);
  for (int k = 0; k < 240 * 5 && g.state().status == MotionStatus::Moving; ++k) g.step();
  EXPECT_EQ(g.state().status, MotionStatus::Reached) << g.state().detail;
  EXPECT_LT((g.state().tcp.translation() - c.target).norm(), 0.005);
}

TEST(SpeedScale, HalfScaleHalvesTheCruiseSpeed) {
  const MoveRun r = run_move({0.35, 0.30, 0.35}, {-0.05, 0.10, 0.05}, MotionKind::Linear,
                             [](int) { return 0.5; });
  ASSERT_EQ(r.status, MotionStatus::Reached);
  double vmax = 0;
  for (std::size_t i = 1; i < r.tcp.size(); ++i)
    vmax = std::max(vmax, (r.tcp[i] - r.tcp[i - 1]).norm() / kDt);
  EXPECT_LE(vmax, 0.25 * 1.02);
  EXPECT_GT(vmax, 0.2);
}

TEST(SpeedScale, OutOfRangeIsClamped) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  MotionGenerator g(m, base_r1(), kDt);
  g.set_speed_scale(3.0);
  EXPECT_EQ(g.requested_speed_scale(), 1.0);
  g.set_speed_scale(-1.0);
  EXPECT_EQ(g.requested_speed_scale(), 0.0);
  g.set_speed_scale(std::nan(""));
  EXPECT_EQ(g.requested_speed_scale(), 0.0);
}
