// URDF loading and forward kinematics against hand-computed values.
#include "hrc/kin/kinematics.hpp"
#include "hrc/kin/robot_model.hpp"
#include "robots_dir.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

using namespace hrc::kin;

namespace {
const std::string kDir = hrc::testing::robots_dir();

// Independent standard-DH product for the UR5: T = prod Rz(q) Tz(d) Tx(a) Rx(alpha).
Eigen::Isometry3d ur5_dh(const Eigen::VectorXd& q) {
  const double d[6] = {0.089159, 0, 0, 0.10915, 0.09465, 0.0823};
  const double a[6] = {0, -0.425, -0.39225, 0, 0, 0};
  const double al[6] = {M_PI / 2, 0, 0, M_PI / 2, -M_PI / 2, 0};
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 6; ++i) {
    T = T * Eigen::AngleAxisd(q[i], Eigen::Vector3d::UnitZ()) *
        Eigen::Translation3d(a[i], 0, d[i]) * Eigen::AngleAxisd(al[i], Eigen::Vector3d::UnitX());
  }
  return T;
}
}  // namespace

TEST(RobotModel, Arm5NamesAndLimits) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  ASSERT_EQ(m.dof(), 5);
  EXPECT_EQ(m.joint_names()[0], "j1_base_yaw");
  EXPECT_EQ(m.joint_names()[4], "j5_wrist_roll");
  EXPECT_DOUBLE_EQ(m.lower()[2], -2.7);
  EXPECT_DOUBLE_EQ(m.upper()[2], 2.7);
  EXPECT_DOUBLE_EQ(m.max_velocity()[0], 2.0);
  EXPECT_TRUE(m.within_limits(m.mid_range()));
  Eigen::VectorXd q = m.mid_range();
  q[1] = 2.5;
  EXPECT_FALSE(m.within_limits(q));
  EXPECT_DOUBLE_EQ(m.clamp(q)[1], 2.0);
}

TEST(RobotModel, OtherChainsLoad) {
  EXPECT_EQ(RobotModel::from_urdf_file(kDir + "/ur5.urdf").dof(), 6);
  EXPECT_EQ(RobotModel::from_urdf_file(kDir + "/panda.urdf").dof(), 7);
}

TEST(RobotModel, BadInputNamesTheProblem) {
  try {
    RobotModel::from_urdf_file(kDir + "/does_not_exist.urdf");
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot open"), std::string::npos);
  }
  try {
    RobotModel::from_urdf_file(kDir + "/arm5.urdf", "base_link", "no_such_link");
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_link"), std::string::npos);
  }
  EXPECT_THROW(RobotModel::from_urdf_string("<robot name='x'><link name='a'/>"),
               std::runtime_error);
  const std::string no_limit =
      "<robot name='r'><link name='base_link'/><link name='tool'/>"
      "<joint name='j' type='revolute'><parent link='base_link'/><child link='tool'/>"
      "<axis xyz='0 0 1'/></joint></robot>";
  EXPECT_THROW(RobotModel::from_urdf_string(no_limit), std::runtime_error);
}

TEST(ForwardKinematics, Arm5HandComputed) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/arm5.urdf");
  KdlKinematics kin(m);
  ChainEval ev(m.chain());
  // Zero: straight up, tool at 0.20 + 0.42 + 0.40 + 0.10 = 1.12 m.
  Eigen::VectorXd q = Eigen::VectorXd::Zero(5);
  Eigen::Isometry3d T = kin.fk(q);
  EXPECT_NEAR((T.translation() - Eigen::Vector3d(0, 0, 1.12)).norm(), 0, 1e-12);
  EXPECT_NEAR(rotation_angle(T.linear(), Eigen::Matrix3d::Identity()), 0, 1e-12);
  // Shoulder at 90 deg: the arm lies along +x at shoulder height.
  q << 0, M_PI / 2, 0, 0, 0;
  T = kin.fk(q);
  EXPECT_NEAR((T.translation() - Eigen::Vector3d(0.92, 0, 0.20)).norm(), 0, 1e-12);
  // Base yaw 90 deg, elbow 90 deg, wrist 90 deg: up 0.42, across 0.40 along +y, then down 0.10;
  // tool points down (pitch sum pi/2 + pi/2 = pi with the shoulder at 0).
  q << M_PI / 2, 0, M_PI / 2, M_PI / 2, 0;
  T = kin.fk(q);
  EXPECT_NEAR((T.translation() - Eigen::Vector3d(0, 0.40, 0.62 - 0.10)).norm(), 0, 1e-12);
  EXPECT_NEAR(axis_angle(T.linear().col(2), -Eigen::Vector3d::UnitZ()), 0, 1e-12);
  // The flattened evaluator agrees with KDL.
  Eigen::Matrix3d R;
  Eigen::Vector3d p;
  ev.fk(q.data(), R, p);
  EXPECT_NEAR((p - T.translation()).norm(), 0, 1e-12);
  EXPECT_NEAR(rotation_angle(R, T.linear()), 0, 1e-12);
}

TEST(ForwardKinematics, Ur5MatchesPublishedDh) {
  const RobotModel m = RobotModel::from_urdf_file(kDir + "/ur5.urdf");
  KdlKinematics kin(m);
  // Zero configuration: x = a2 + a3, y = -(d4 + d6), z = d1 - d5.
  const Eigen::Isometry3d T0 = kin.fk(Eigen::VectorXd::Zero(6));
  EXPECT_NEAR(T0.translation().x(), -0.81725, 1e-9);
  EXPECT_NEAR(T0.translation().y(), -0.19145, 1e-9);
  EXPECT_NEAR(T0.translation().z(), 0.089159 - 0.09465, 1e-9);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-M_PI, M_PI);
  for (int k = 0; k < 50; ++k) {
    Eigen::VectorXd q(6);
    for (int i = 0; i < 6; ++i) q[i] = u(rng);
    const Eigen::Isometry3d T = kin.fk(q), D = ur5_dh(q);
    EXPECT_NEAR((T.translation() - D.translation()).norm(), 0, 1e-12);
    EXPECT_NEAR(rotation_angle(T.linear(), D.linear()), 0, 1e-9);
  }
}

TEST(ForwardKinematics, JacobianMatchesKdlAndFiniteDifferences) {
  for (const char* name : {"arm5", "ur5", "panda"}) {
    const RobotModel m = RobotModel::from_urdf_file(kDir + "/" + name + ".urdf");
    KdlKinematics kin(m);
    ChainEval ev(m.chain());
    std::mt19937_64 rng(3);
    for (int k = 0; k < 20; ++k) {
      Eigen::VectorXd q(m.dof());
      for (int i = 0; i < m.dof(); ++i)
        q[i] = std::uniform_real_distribution<double>(m.sample_lower(i), m.sample_upper(i))(rng);
      Eigen::Matrix3d R;
      Eigen::Vector3d p;
      Jacobian6 J;
      ev.fk_jacobian(q.data(), R, p, J);
      const Eigen::MatrixXd Jk = kin.jacobian(q);
      EXPECT_LT((J - Jk).cwiseAbs().maxCoeff(), 1e-12) << name;
      // Linear part by central differences.
      for (int i = 0; i < m.dof(); ++i) {
        Eigen::VectorXd a = q, b = q;
        a[i] += 1e-6;
        b[i] -= 1e-6;
        const Eigen::Vector3d d = (kin.fk(a).translation() - kin.fk(b).translation()) / 2e-6;
        EXPECT_LT((d - J.col(i).head<3>()).norm(), 1e-6) << name << " joint " << i;
      }
    }
  }
}
