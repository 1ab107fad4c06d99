#include "hrc/kin/kinematics.hpp"

#include <kdl/frames.hpp>
#include <kdl/jacobian.hpp>
#include <kdl/jntarray.hpp>

#include <cmath>
#include <stdexcept>
#include <string>

namespace hrc::kin {
namespace {

Eigen::Matrix3d to_eigen(const KDL::Rotation& r) {
  Eigen::Matrix3d m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m(i, j) = r(i, j);
  return m;
}
Eigen::Vector3d to_eigen(const KDL::Vector& v) { return {v.x(), v.y(), v.z()}; }

// Rotation by angle about a unit axis (Rodrigues), specialised for the coordinate axes.
inline void axis_rotation(const Eigen::Vector3d& a, double angle, Eigen::Matrix3d& R) {
  const double c = std::cos(angle), s = std::sin(angle), t = 1.0 - c;
  const double x = a.x(), y = a.y(), z = a.z();
  R << t * x * x + c, t * x * y - s * z, t * x * z + s * y, t * x * y + s * z, t * y * y + c,
      t * y * z - s * x, t * x * z - s * y, t * y * z + s * x, t * z * z + c;
}

}  // namespace

KdlKinematics::KdlKinematics(const RobotModel& model)
    : chain_(model.chain()),
      fk_(std::make_unique<KDL::ChainFkSolverPos_recursive>(chain_)),
      jac_(std::make_unique<KDL::ChainJntToJacSolver>(chain_)),
      q_(chain_.getNrOfJoints()) {}

Eigen::Isometry3d KdlKinematics::fk(const Eigen::VectorXd& q) const {
  if (q.size() != static_cast<Eigen::Index>(chain_.getNrOfJoints()))
    throw std::invalid_argument("fk: expected " + std::to_string(chain_.getNrOfJoints()) +
                                " joints, got " + std::to_string(q.size()));
  q_.data = q;
  KDL::Frame f;
  if (fk_->JntToCart(q_, f) < 0) throw std::runtime_error("fk: KDL FK solver failed");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = to_eigen(f.M);
  T.translation() = to_eigen(f.p);
  return T;
}

Eigen::Matrix<double, 6, Eigen::Dynamic> KdlKinematics::jacobian(const Eigen::VectorXd& q) const {
  if (q.size() != static_cast<Eigen::Index>(chain_.getNrOfJoints()))
    throw std::invalid_argument("jacobian: wrong joint count");
  q_.data = q;
  KDL::Jacobian J(chain_.getNrOfJoints());
  if (jac_->JntToJac(q_, J) < 0) throw std::runtime_error("jacobian: KDL solver failed");
  return J.data;
}

ChainEval::ChainEval(const KDL::Chain& chain) {
  // Segment pose: joint.pose(q) * f_tip, where joint.pose(q) moves about/along `axis` through
  // `origin`: Trans(o) Rot(a, scale q + offset) Trans(-o).  Fold every fixed part into the next
  // joint's `pre` transform so evaluation is one rotation + one product per joint.
  Eigen::Matrix3d acc_R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d acc_p = Eigen::Vector3d::Zero();
  for (unsigned s = 0; s < chain.getNrOfSegments(); ++s) {
    const KDL::Segment& seg = chain.getSegment(s);
    const KDL::Joint& j = seg.getJoint();
    const KDL::Frame tip = seg.getFrameToTip();
    const Eigen::Matrix3d tip_R = to_eigen(tip.M);
    const Eigen::Vector3d tip_p = to_eigen(tip.p);
    if (j.getType() == KDL::Joint::None) {
      acc_p = acc_p + acc_R * tip_p;
      acc_R = acc_R * tip_R;
      continue;
    }
    Joint jt;
    const Eigen::Vector3d a = to_eigen(j.JointAxis()).normalized();
    const bool prismatic = j.getType() == KDL::Joint::TransAxis ||
                           j.getType() == KDL::Joint::TransX || j.getType() == KDL::Joint::TransY ||
                           j.getType() == KDL::Joint::TransZ;
    const Eigen::Vector3d o = prismatic ? Eigen::Vector3d::Zero() : to_eigen(j.JointOrigin());
    // Scale and offset are private in KDL::Joint: recover them from the motion at q = 0 and 1.
    const KDL::Frame m0 = j.pose(0.0), m1 = j.pose(1.0);
    if (prismatic) {
      jt.offset = to_eigen(m0.p).dot(a);
      jt.scale = to_eigen(m1.p).dot(a) - jt.offset;
    } else {
      const auto signed_angle = [&](const KDL::Rotation& r) {
        const Eigen::AngleAxisd aa(to_eigen(r));
        return aa.axis().dot(a) >= 0 ? aa.angle() : -aa.angle();
      };
      jt.offset = signed_angle(m0.M);
      jt.scale = std::remainder(signed_angle(m1.M) - jt.offset, 2.0 * M_PI);
    }
    jt.prismatic = prismatic;
    jt.axis = a;
    jt.axis_index = -1;
    for (int k = 0; k < 3; ++k)
      if ((a - Eigen::Vector3d::Unit(k)).norm() < 1e-15) {
        jt.axis = Eigen::Vector3d::Unit(k);
        jt.axis_index = k;
      }
    jt.pre_R_identity = (acc_R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() == 0.0;
    jt.pre_R = acc_R;
    jt.pre_p = acc_p + acc_R * o;
    joints_.push_back(jt);
    // After the motion: Trans(-o) * tip.
    acc_R = tip_R;
    acc_p = tip_p - o;
  }
  post_R_ = acc_R;
  post_p_ = acc_p;
}

void ChainEval::apply_pre(const Joint& j, Eigen::Matrix3d& R, Eigen::Vector3d& p) {
  p.noalias() += R * j.pre_p;
  if (!j.pre_R_identity) R = (R * j.pre_R).eval();
}

void ChainEval::apply_motion(const Joint& j, double v, Eigen::Matrix3d& R, Eigen::Vector3d& p) {
  if (j.prismatic) {
    p.noalias() += R * (j.axis * v);
    return;
  }
  const double c = std::cos(v), s = std::sin(v);
  if (j.axis_index >= 0) {
    // Rotation about a coordinate axis only mixes the two other columns.
    const int a = (j.axis_index + 1) % 3, b = (j.axis_index + 2) % 3;
    const Eigen::Vector3d ca = R.col(a), cb = R.col(b);
    R.col(a) = c * ca + s * cb;
    R.col(b) = c * cb - s * ca;
    return;
  }
  Eigen::Matrix3d M;
  axis_rotation(j.axis, v, M);
  R = (R * M).eval();
}

void ChainEval::fk(const double* q, Eigen::Matrix3d& R, Eigen::Vector3d& p) const {
  R.setIdentity();
  p.setZero();
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    const Joint& j = joints_[i];
    apply_pre(j, R, p);
    apply_motion(j, j.scale * q[i] + j.offset, R, p);
  }
  p.noalias() += R * post_p_;
  R = (R * post_R_).eval();
}

void ChainEval::fk_jacobian(const double* q, Eigen::Matrix3d& R, Eigen::Vector3d& p,
                            Jacobian6& J) const {
  const int n = dof();
  J.resize(6, n);
  R.setIdentity();
  p.setZero();
  // Store joint origins/axes in J temporarily: top rows origin, bottom rows axis.
  for (int i = 0; i < n; ++i) {
    const Joint& j = joints_[static_cast<std::size_t>(i)];
    // Joint point and axis: the frame after `pre`, before the joint's own motion.
    apply_pre(j, R, p);
    J.col(i).head<3>() = p;
    J.col(i).tail<3>() =
        j.axis_index >= 0 ? Eigen::Vector3d(R.col(j.axis_index)) : Eigen::Vector3d(R * j.axis);
    apply_motion(j, j.scale * q[i] + j.offset, R, p);
  }
  p.noalias() += R * post_p_;
  R = (R * post_R_).eval();
  for (int i = 0; i < n; ++i) {
    const Joint& j = joints_[static_cast<std::size_t>(i)];
    const Eigen::Vector3d z = J.col(i).tail<3>() * j.scale;
    if (j.prismatic) {
      J.col(i).head<3>() = z;
      J.col(i).tail<3>().setZero();
    } else {
      const Eigen::Vector3d o = J.col(i).head<3>();
      J.col(i).head<3>() = z.cross(p - o);
      J.col(i).tail<3>() = z;
    }
  }
}

void ChainEval::joint_frame(const double* q, int idx, Eigen::Vector3d& origin,
                            Eigen::Vector3d& axis) const {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int i = 0; i <= idx; ++i) {
    const Joint& j = joints_[static_cast<std::size_t>(i)];
    apply_pre(j, R, p);
    if (i == idx) break;
    apply_motion(j, j.scale * q[i] + j.offset, R, p);
  }
  origin = p;
  axis = R * joints_[static_cast<std::size_t>(idx)].axis;
}

double rotation_angle(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  const Eigen::Matrix3d d = a.transpose() * b;
  // atan2 form is accurate for small and large angles alike.
  const Eigen::Vector3d w(d(2, 1) - d(1, 2), d(0, 2) - d(2, 0), d(1, 0) - d(0, 1));
  return std::atan2(0.5 * w.norm(), 0.5 * (d.trace() - 1.0));
}

double axis_angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

Eigen::Matrix3d tool_down_rotation(double yaw) {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

}  // namespace hrc::kin
