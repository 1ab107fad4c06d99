// IK: round trips, joint limits, unreachable targets, and the baselines' plumbing.
#include "hrc/kin/baselines.hpp"
#include "hrc/kin/ik.hpp"
#include "hrc/kin/kinematics.hpp"
#include "robots_dir.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace hrc::kin;

namespace {
const std::string kDir = hrc::testing::robots_dir();
constexpr double kPos = 1e-4;              // 0.1 mm
constexpr double kAng = 0.1 * M_PI / 180;  // 0.1 deg

Eigen::VectorXd random_joints(const RobotModel& m, std::mt19937_64& rng) {
  Eigen::VectorXd q(m.dof());
  for (int i = 0; i < m.dof(); ++i)
    q[i] = std::uniform_real_distribution<double>(m.sample_lower(i), m.sample_upper(i))(rng);
  return q;
}

void round_trip(const std::string& name, bool axis_only, bool numeric_only, int n) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/" + name + ".urdf");
  IkSolver ik(m);
  KdlKinematics kin(m);
  std::mt19937_64 rng(11);
  int ok = 0;
  for (int k = 0; k < n; ++k) {
    const Eigen::Isometry3d T = kin.fk(random_joints(m, rng));
    const IkTarget t =
        axis_only ? IkTarget::position_axis(T.translation(), T.linear().col(2)) : IkTarget::pose(T);
    IkResult r;
    if (numeric_only)
      ik.solve_numeric(t, m.mid_range(), r);
    else
      ik.solve(t, m.mid_range(), r);
    ASSERT_TRUE(r.q.allFinite());
    EXPECT_TRUE(m.within_limits(r.q, 1e-12)) << name << " target " << k;
    const Eigen::Isometry3d F = kin.fk(r.q);
    const double pe = (F.translation() - T.translation()).norm();
    const double ae = axis_only ? axis_angle(F.linear().col(2), T.linear().col(2))
                                : rotation_angle(F.linear(), T.linear());
    if (r.status == IkStatus::Ok) {
      EXPECT_LT(pe, kPos);
      EXPECT_LT(ae, kAng);
      ++ok;
    }
  }
  EXPECT_EQ(ok, n) << name;
}
}  // namespace

TEST(Ik, Arm5ClosedFormIsDetected) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  EXPECT_TRUE(IkSolver(m).has_analytic());
  EXPECT_FALSE(IkSolver(RobotModel::from_urdf_file(kDir + "/ur5.urdf")).has_analytic());
}

TEST(Ik, Arm5RoundTripPositionAxis) { round_trip("arm5", true, false, 2000); }
TEST(Ik, Arm5RoundTripFullPose) { round_trip("arm5", false, false, 1000); }
TEST(Ik, Arm5NumericFallbackRoundTrip) { round_trip("arm5", true, true, 300); }
TEST(Ik, Ur5RoundTripFullPose) { round_trip("ur5", false, false, 500); }
TEST(Ik, PandaRoundTripFullPose) { round_trip("panda", false, false, 500); }

TEST(Ik, ClosestSolutionToSeedIsChosen) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  IkSolver ik(m);
  KdlKinematics kin(m);
  Eigen::VectorXd q(5);
  q << 0.3, 0.5, 1.2, 1.44, 0.2;
  const IkResult r = ik.solve(IkTarget::pose(kin.fk(q)), q + Eigen::VectorXd::Constant(5, 0.01));
  ASSERT_EQ(r.status, IkStatus::Ok);
  EXPECT_LT((r.q - q).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Ik, UnreachableTargetIsReportedWithoutNaN) {
  for (const char* name : {"arm5", "ur5", "panda"}) {
    const RobotModel m = RobotModel::from_urdf_file(kDir + "/" + name + ".urdf");
    IkOptions o;
    o.max_restarts = 5;
    IkSolver ik(m, o);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(3.0, 0.0, 0.5);  // far beyond every arm's reach
    const IkResult r = ik.solve(IkTarget::pose(T), m.mid_range());
    EXPECT_EQ(r.status, IkStatus::Unreachable) << name;
    EXPECT_TRUE(r.q.allFinite()) << name;
    EXPECT_TRUE(m.within_limits(r.q)) << name;
    EXPECT_TRUE(std::isfinite(r.position_error)) << name;
    EXPECT_GT(r.position_error, 1.0) << name;  // best residual: about 3 m minus the reach
  }
}

TEST(Ik, InvalidInputIsRejected) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  IkSolver ik(m);
  IkTarget t = IkTarget::position_axis(Eigen::Vector3d(0.4, 0, 0.2), -Eigen::Vector3d::UnitZ());
  t.position.x() = std::nan("");
  EXPECT_EQ(ik.solve(t, m.mid_range()).status, IkStatus::InvalidInput);
  t.position.x() = 0.4;
  EXPECT_EQ(ik.solve(t, Eigen::VectorXd::Zero(3)).status, IkStatus::InvalidInput);
}

TEST(Ik, JointLimitsRespectedWhenTheFreeSolutionViolatesThem) {
  // A pose whose nearest unconstrained solution from the seed lies beyond the elbow limit: the
  // solver must return one within the limits (or report failure), never outside.
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/panda.urdf");
  IkSolver ik(m);
  KdlKinematics kin(m);
  Eigen::VectorXd q = m.mid_range();
  q[3] = -0.08;  // close to the upper limit of joint 4 (-0.0698)
  q[5] = 3.7;    // and of joint 6 (3.7525)
  const Eigen::Isometry3d T = kin.fk(q);
  Eigen::VectorXd seed = q;
  seed[3] = 0.3;  // seed outside the limits on purpose: clamped first
  const IkResult r = ik.solve(IkTarget::pose(T), seed);
  EXPECT_TRUE(m.within_limits(r.q, 0.0));
  EXPECT_EQ(r.status, IkStatus::Ok);
}

TEST(Ik, DeterministicForSameInput) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/panda.urdf");
  IkSolver a(m), b(m);
  KdlKinematics kin(m);
  std::mt19937_64 rng(5);
  for (int k = 0; k < 50; ++k) {
    const IkTarget t = IkTarget::pose(kin.fk(random_joints(m, rng)));
    const IkResult ra = a.solve(t, m.mid_range());
    b.solve(IkTarget::pose(kin.fk(random_joints(m, rng))), m.mid_range());  // different history
    const IkResult rb = b.solve(t, m.mid_range());
    EXPECT_EQ(ra.q, rb.q);
  }
}

TEST(Baselines, KdlAndGradientDescentRunAndStayFinite) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  KdlKinematics kin(m);
  KdlNrJlSolver nr(m);
  KdlLmaSolver lma(m);
  GradientDescentOptions go;
  go.max_sweeps = 200;
  GradientDescentSolver gd(m, go);
  Eigen::VectorXd q(5);
  q << 0.2, 0.4, 1.0, 1.2, 0.3;
  const Eigen::Isometry3d T = kin.fk(q);
  Eigen::VectorXd out;
  // From a nearby seed both KDL solvers converge.
  EXPECT_EQ(nr.solve(T, q + Eigen::VectorXd::Constant(5, 0.05), out), 0);
  EXPECT_LT((kin.fk(out).translation() - T.translation()).norm(), 1e-5);
  EXPECT_GE(lma.solve(T, q + Eigen::VectorXd::Constant(5, 0.05), out), 0);
  EXPECT_LT((kin.fk(out).translation() - T.translation()).norm(), 1e-4);
  // The thesis's gradient descent gets closer than where it started.
  const IkTarget t = IkTarget::position_axis(T.translation(), T.linear().col(2));
  const double before = (kin.fk(m.mid_range()).translation() - T.translation()).norm();
  gd.solve(t, m.mid_range(), out);
  ASSERT_TRUE(out.allFinite());
  EXPECT_TRUE(m.within_limits(out));
  EXPECT_LT((kin.fk(out).translation() - T.translation()).norm(), 0.5 * before);
}
