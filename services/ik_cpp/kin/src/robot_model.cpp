#include "hrc/kin/robot_model.hpp"

#include <urdf_model/model.h>
#include <urdf_parser/urdf_parser.h>
#include <kdl/frames.hpp>
#include <kdl/joint.hpp>
#include <kdl/segment.hpp>

#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace hrc::kin {
namespace {

[[noreturn]] void fail(const std::string& source, const std::string& what) {
  throw std::runtime_error("URDF " + source + ": " + what);
}

KDL::Frame to_kdl(const urdf::Pose& pose) {
  const auto& r = pose.rotation;
  const auto& p = pose.position;
  return KDL::Frame(KDL::Rotation::Quaternion(r.x, r.y, r.z, r.w), KDL::Vector(p.x, p.y, p.z));
}

}  // namespace

RobotModel RobotModel::from_urdf_file(const std::string& path, const std::string& base,
                                      const std::string& tip) {
  std::ifstream in(path);
  if (!in) fail(path, "cannot open file");
  std::stringstream ss;
  ss << in.rdbuf();
  return from_urdf_string(ss.str(), base, tip, path);
}

RobotModel RobotModel::from_urdf_string(const std::string& xml, const std::string& base,
                                        const std::string& tip, const std::string& source) {
  if (xml.empty()) fail(source, "empty document");
  urdf::ModelInterfaceSharedPtr urdf_model;
  try {
    urdf_model = urdf::parseURDF(xml);
  } catch (const std::exception& e) {
    fail(source, std::string("parse error: ") + e.what());
  }
  if (!urdf_model) fail(source, "not a valid URDF (urdfdom could not parse it)");
  if (!urdf_model->getLink(base)) fail(source, "no link named '" + base + "' (base)");
  if (!urdf_model->getLink(tip)) fail(source, "no link named '" + tip + "' (tip)");

  // Walk from the tip up to the base, then build the chain base -> tip.
  std::vector<urdf::JointConstSharedPtr> joints;
  urdf::LinkConstSharedPtr link = urdf_model->getLink(tip);
  while (link->name != base) {
    if (!link->parent_joint) fail(source, "link '" + tip + "' is not below '" + base + "'");
    joints.push_back(link->parent_joint);
    link = urdf_model->getLink(link->parent_joint->parent_link_name);
    if (!link) fail(source, "broken parent chain above '" + joints.back()->child_link_name + "'");
  }

  RobotModel m;
  for (const auto& [name, joint] : urdf_model->joints_) {
    if (!joint->limits ||
        (joint->type != urdf::Joint::REVOLUTE && joint->type != urdf::Joint::PRISMATIC)) {
      continue;
    }
    const double v = joint->limits->velocity > 0.0 ? joint->limits->velocity
                                                   : std::numeric_limits<double>::infinity();
    m.all_limits_[name] = JointLimit{joint->limits->lower, joint->limits->upper, v};
  }
  m.name_ = urdf_model->getName();
  m.base_ = base;
  m.tip_ = tip;
  std::vector<double> lo, hi, vel;
  for (auto it = joints.rbegin(); it != joints.rend(); ++it) {
    const urdf::Joint& j = **it;
    const KDL::Frame origin = to_kdl(j.parent_to_joint_origin_transform);
    const KDL::Vector axis_local(j.axis.x, j.axis.y, j.axis.z);
    // Joint axis and origin expressed in the parent link frame, as KDL's Joint(origin, axis)
    // expects; the segment's tip frame is the joint origin (URDF: T = origin * motion(q)).
    const KDL::Vector axis = origin.M * axis_local;
    KDL::Joint kj;
    switch (j.type) {
      case urdf::Joint::FIXED: kj = KDL::Joint(j.name, KDL::Joint::None); break;
      case urdf::Joint::REVOLUTE:
      case urdf::Joint::CONTINUOUS:
      case urdf::Joint::PRISMATIC: {
        if (axis_local.Norm() < 1e-9) fail(source, "joint '" + j.name + "' has a zero axis");
        const KDL::Vector unit = axis / axis.Norm();
        kj = KDL::Joint(
            j.name, origin.p, unit,
            j.type == urdf::Joint::PRISMATIC ? KDL::Joint::TransAxis : KDL::Joint::RotAxis);
        double l = -std::numeric_limits<double>::infinity();
        double u = std::numeric_limits<double>::infinity();
        double v = std::numeric_limits<double>::infinity();
        if (j.type != urdf::Joint::CONTINUOUS) {
          if (!j.limits) fail(source, "joint '" + j.name + "' has no <limit>");
          l = j.limits->lower;
          u = j.limits->upper;
          if (!(l < u)) fail(source, "joint '" + j.name + "' has lower >= upper limit");
        }
        if (j.limits && j.limits->velocity > 0.0) v = j.limits->velocity;
        lo.push_back(l);
        hi.push_back(u);
        vel.push_back(v);
        m.joint_names_.push_back(j.name);
        m.bounded_.push_back(j.type != urdf::Joint::CONTINUOUS);
        m.revolute_.push_back(j.type != urdf::Joint::PRISMATIC);
        break;
      }
      default: fail(source, "joint '" + j.name + "' has an unsupported type (floating/planar)");
    }
    m.chain_.addSegment(KDL::Segment(j.child_link_name, kj, origin));
  }
  if (m.joint_names_.empty())
    fail(source, "no movable joint between '" + base + "' and '" + tip + "'");
  const auto n = static_cast<Eigen::Index>(lo.size());
  m.lower_ = Eigen::Map<Eigen::VectorXd>(lo.data(), n);
  m.upper_ = Eigen::Map<Eigen::VectorXd>(hi.data(), n);
  m.max_velocity_ = Eigen::Map<Eigen::VectorXd>(vel.data(), n);
  return m;
}

std::optional<RobotModel::JointLimit> RobotModel::joint_limit(const std::string& name) const {
  const auto it = all_limits_.find(name);
  if (it == all_limits_.end()) return std::nullopt;
  return it->second;
}

KDL::Frame to_kdl(const Eigen::Isometry3d& X) {
  const Eigen::Matrix3d& R = X.linear();
  return KDL::Frame(KDL::Rotation(R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0),
                                  R(2, 1), R(2, 2)),
                    KDL::Vector(X.translation().x(), X.translation().y(), X.translation().z()));
}

void RobotModel::attach_tcp(const Eigen::Isometry3d& tip_T_tcp) {
  chain_.addSegment(
      KDL::Segment("tcp", KDL::Joint("tcp_joint", KDL::Joint::None), to_kdl(tip_T_tcp)));
}

void RobotModel::joint_child_frames(const Eigen::VectorXd& q,
                                    std::vector<Eigen::Isometry3d>& base_T_links) const {
  base_T_links.resize(joint_names_.size());
  KDL::Frame base_T_segment;  // the base frame to the current segment's tip
  std::size_t j = 0;
  for (unsigned int s = 0; s < chain_.getNrOfSegments() && j < joint_names_.size(); ++s) {
    const KDL::Segment& segment = chain_.getSegment(s);
    const bool movable = segment.getJoint().getType() != KDL::Joint::None;
    base_T_segment = base_T_segment * segment.pose(movable ? q[static_cast<Eigen::Index>(j)] : 0.0);
    if (!movable) continue;
    Eigen::Isometry3d& X = base_T_links[j++];
    X.setIdentity();
    for (int r = 0; r < 3; ++r) {
      X.translation()[r] = base_T_segment.p[r];
      for (int c = 0; c < 3; ++c) X.linear()(r, c) = base_T_segment.M(r, c);
    }
  }
}

bool RobotModel::within_limits(const Eigen::VectorXd& q, double tol) const {
  if (q.size() != dof()) return false;
  for (int i = 0; i < dof(); ++i) {
    if (!std::isfinite(q[i])) return false;
    if (q[i] < lower_[i] - tol || q[i] > upper_[i] + tol) return false;
  }
  return true;
}

Eigen::VectorXd RobotModel::clamp(const Eigen::VectorXd& q) const {
  return q.cwiseMax(lower_).cwiseMin(upper_);
}

Eigen::VectorXd RobotModel::mid_range() const {
  Eigen::VectorXd m(dof());
  for (int i = 0; i < dof(); ++i) m[i] = bounded(i) ? 0.5 * (lower_[i] + upper_[i]) : 0.0;
  return m;
}

double RobotModel::sample_lower(int i) const { return bounded(i) ? lower_[i] : -M_PI; }
double RobotModel::sample_upper(int i) const { return bounded(i) ? upper_[i] : M_PI; }

}  // namespace hrc::kin
