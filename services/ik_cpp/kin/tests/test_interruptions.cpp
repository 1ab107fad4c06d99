// Interruptions come back to the task move: a hold or a detour (a retreat) leaves it on its
// path; commanded again, the arm rejoins where it left and follows the rest of the very plan, so
// it ends in exactly the configuration the undisturbed move ends in (docs/task-semantics.md,
// "Interruptions"). Also when interruptions nest.
#include "hrc/kin/motion.hpp"
#include "robots_dir.hpp"

#include <gtest/gtest.h>

#include <cmath>

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

MoveCommand move_to(double x, double y, double z, double approach = 0.0, double depart = 0.0) {
  MoveCommand c;
  c.target = Eigen::Vector3d(x, y, z);
  c.approach_height = approach;
  c.depart_height = depart;
  return c;
}

MoveCommand retreat() {
  MoveCommand c = move_to(0.45, 0.45, 0.40);
  c.detour = true;
  return c;
}

// Steps until the arm stops moving; returns the ticks taken (fails the test at max_ticks).
int settle(MotionGenerator& g, int max_ticks = 240 * 30) {
  int k = 0;
  while (g.state().status == MotionStatus::Moving && k < max_ticks) {
    g.step();
    ++k;
  }
  // A hold reports Holding while it brakes: run the brake out too.
  while (g.state().tcp_speed > 0 && k < max_ticks) {
    g.step();
    ++k;
  }
  EXPECT_LT(k, max_ticks) << "still moving";
  return k;
}

void step_n(MotionGenerator& g, int n) {
  for (int i = 0; i < n; ++i) g.step();
}

struct Fixture {
  RobotModel model = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  // A pick move (depart from the intermediate pose, line over, approach from above).
  MoveCommand task = move_to(0.66, 0.30, 0.03, 0.05, 0.05);

  MotionGenerator start() const {
    MotionGenerator g(model, base_r1(), kDt);
    EXPECT_TRUE(g.reset_to_pose(Eigen::Vector3d(0.20, 0.25, 0.25), 0.0));
    return g;
  }
  // Where the undisturbed move ends, and how long it takes.
  std::pair<Eigen::VectorXd, int> undisturbed() const {
    MotionGenerator g = start();
    EXPECT_EQ(g.move(task), MotionStatus::Moving);
    const int ticks = settle(g);
    EXPECT_EQ(g.state().status, MotionStatus::Reached);
    return {g.state().q, ticks};
  }
};

}  // namespace

TEST(Interruptions, HoldThenTheSameMoveEndsExactlyWhereTheUndisturbedMoveEnds) {
  const Fixture f;
  const auto [q_end, ticks] = f.undisturbed();
  for (const double at : {0.0, 0.3, 0.6, 0.95}) {
    MotionGenerator g = f.start();
    g.move(f.task);
    step_n(g, static_cast<int>(at * ticks));
    g.hold();
    settle(g);
    EXPECT_EQ(g.state().status, MotionStatus::Holding) << at;
    g.move(f.task);
    settle(g);
    EXPECT_EQ(g.state().status, MotionStatus::Reached) << at;
    EXPECT_EQ(g.state().q, q_end) << "interrupted at " << at;
  }
}

TEST(Interruptions, RetreatThenTheSameMoveEndsExactlyWhereTheUndisturbedMoveEnds) {
  const Fixture f;
  const auto [q_end, ticks] = f.undisturbed();
  for (const double at : {0.0, 0.3, 0.6, 0.95}) {
    MotionGenerator g = f.start();
    g.move(f.task);
    step_n(g, static_cast<int>(at * ticks));
    EXPECT_NE(g.move(retreat()), MotionStatus::Unreachable) << at;
    settle(g);
    ASSERT_EQ(g.state().status, MotionStatus::Reached) << at;
    EXPECT_LT((g.state().tcp.translation() - retreat().target).norm(), 0.005) << at;
    g.move(f.task);
    settle(g);
    EXPECT_EQ(g.state().status, MotionStatus::Reached) << at;
    EXPECT_EQ(g.state().q, q_end) << "interrupted at " << at;
  }
}

TEST(Interruptions, NestedInterruptionsStillEndWhereTheUndisturbedMoveEnds) {
  const Fixture f;
  const auto [q_end, ticks] = f.undisturbed();
  MotionGenerator g = f.start();
  g.move(f.task);
  step_n(g, ticks / 3);
  g.move(retreat());
  step_n(g, 60);  // on the way to the retreat pose: a near-collision hold
  g.hold();
  settle(g);
  g.move(retreat());  // the retreat goes on
  settle(g);
  g.move(f.task);  // resume ...
  step_n(g, 40);
  g.hold();  // ... held again while rejoining
  settle(g);
  g.move(retreat());  // and a second collision before it got back
  step_n(g, 30);
  g.move(f.task);  // resumed before the retreat ended
  settle(g);
  EXPECT_EQ(g.state().status, MotionStatus::Reached);
  EXPECT_EQ(g.state().q, q_end);
}

TEST(Interruptions, ANewTaskMoveAfterARetreatIsPlannedFromWhereTheArmLeft) {
  // A robot waiting at its intermediate pose: a retreat, and meanwhile its next move became due;
  // the next move is made from the intermediate pose at rest, as the motion check makes it.
  const Fixture f;
  MotionGenerator ref = f.start();
  const MoveCommand next = move_to(0.04, 0.16, 0.06, 0.05, 0.0);
  ref.move(next);
  settle(ref);
  ASSERT_EQ(ref.state().status, MotionStatus::Reached);
  MotionGenerator g = f.start();
  g.move(move_to(0.20, 0.25, 0.25));  // already there: reached at once (the task move)
  EXPECT_EQ(g.state().status, MotionStatus::Reached);
  g.move(retreat());
  settle(g);
  g.move(next);
  settle(g);
  EXPECT_EQ(g.state().status, MotionStatus::Reached);
  EXPECT_EQ(g.state().q, ref.state().q);
}

TEST(Interruptions, ASpeedScaleOfZeroStopsOnThePathAndTheMoveEndsTheSame) {
  const Fixture f;
  const auto [q_end, ticks] = f.undisturbed();
  MotionGenerator g = f.start();
  g.move(f.task);
  step_n(g, ticks / 2);
  g.set_speed_scale(0.0);
  step_n(g, 240);
  EXPECT_LT(g.state().tcp_speed, 1e-9);
  g.set_speed_scale(1.0);
  settle(g);
  EXPECT_EQ(g.state().status, MotionStatus::Reached);
  EXPECT_EQ(g.state().q, q_end);
}
