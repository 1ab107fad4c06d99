// The ik_cpp service mapping: scenario -> robots, RobotCommand -> motion generator, MotionState ->
// RobotState, ReachRequest -> ReachReply, rejection of bad commands; and the service over the bus.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <mutex>
#include <string>
#include <vector>

#include "hrc/ik_service.hpp"
#include "robots_dir.hpp"
#include "test_util.hpp"

namespace {

using hrc::v2::RobotCommand;
using hrc::v2::RobotState;

const std::string kArm5 = hrc::testing::robots_dir() + "/arm5.urdf";
constexpr double kDt = 1.0 / 240.0;

// The two robots of scenarios/minimal.toml.
hrc::v2::Scenario minimal_scenario() {
  hrc::v2::Scenario s;
  s.mutable_info()->set_name("unit");
  s.mutable_info()->set_tick_hz(240);
  auto add = [&](const std::string& id, double x, double hx) {
    hrc::v2::RobotConfig* r = s.add_robots();
    r->set_id(id);
    r->set_urdf_path(kArm5);
    r->mutable_base()->mutable_xyz()->set_x(x);
    r->mutable_base()->mutable_xyz()->set_y(0.55);
    r->mutable_base()->set_yaw_deg(180);
    r->set_max_tcp_speed(0.5);
    r->mutable_home()->set_x(hx);
    r->mutable_home()->set_y(0.30);
    r->mutable_home()->set_z(0.35);
  };
  add("r2", -0.45, -0.35);  // listed out of order on purpose: the engine sorts by id
  add("r1", 0.45, 0.35);
  return s;
}

RobotCommand move(double x, double y, double z, uint64_t id, double yaw_deg = 0,
                  double max_speed = 0) {
  RobotCommand c;
  c.set_robot("r1");
  c.set_command_id(id);
  c.set_kind(RobotCommand::KIND_MOVE);
  c.mutable_target()->set_x(x);
  c.mutable_target()->set_y(y);
  c.mutable_target()->set_z(z);
  c.set_yaw_deg(yaw_deg);
  c.set_max_speed(max_speed);
  return c;
}

Eigen::Vector3d tcp_of(const RobotState& s) {
  return {s.tcp().position().x(), s.tcp().position().y(), s.tcp().position().z()};
}

class Engine : public ::testing::Test {
 protected:
  Engine() : engine_(hrc::robots_from_scenario(minimal_scenario()), kDt) {}
  // Steps until r1 is no longer MOVING; returns the ticks and the highest measured TCP speed.
  int run_r1(int max_ticks, double* max_speed = nullptr) {
    RobotState st;
    engine_.fill_state(0, st);
    Eigen::Vector3d prev = tcp_of(st);
    double vmax = 0;
    int k = 0;
    for (; k < max_ticks; ++k) {
      engine_.step();
      engine_.fill_state(0, st);
      vmax = std::max(vmax, (tcp_of(st) - prev).norm() / kDt);
      prev = tcp_of(st);
      if (st.status() != hrc::v2::MOTION_STATUS_MOVING) break;
    }
    if (max_speed != nullptr) *max_speed = vmax;
    return k;
  }
  hrc::IkEngine engine_;
};

TEST(IkScenario, ReadsRobotsAndRejectsBadOnes) {
  const auto specs = hrc::robots_from_scenario(minimal_scenario());
  ASSERT_EQ(specs.size(), 2u);
  EXPECT_EQ(specs[1].id, "r1");
  EXPECT_NEAR(specs[1].world_T_base.translation().x(), 0.45, 1e-12);
  // yaw 180 deg about z: the base x axis points along world -x
  EXPECT_NEAR(specs[1].world_T_base.linear()(0, 0), -1.0, 1e-12);
  EXPECT_DOUBLE_EQ(specs[1].max_tcp_speed, 0.5);
  EXPECT_NEAR(hrc::tick_dt(minimal_scenario()), kDt, 1e-15);

  auto bad = minimal_scenario();
  bad.mutable_robots(0)->set_max_tcp_speed(0);
  EXPECT_THROW(hrc::robots_from_scenario(bad), std::invalid_argument);
  bad = minimal_scenario();
  bad.mutable_robots(1)->set_id("r2");
  try {
    hrc::robots_from_scenario(bad);
    FAIL() << "duplicate id accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'r2'"), std::string::npos) << e.what();
  }
  bad = minimal_scenario();
  bad.mutable_robots(0)->mutable_home()->set_z(std::nan(""));
  EXPECT_THROW(hrc::robots_from_scenario(bad), std::invalid_argument);
  bad = minimal_scenario();
  bad.mutable_info()->set_tick_hz(0);
  EXPECT_THROW(hrc::tick_dt(bad), std::invalid_argument);
  EXPECT_TRUE(hrc::robots_from_scenario(hrc::v2::Scenario{}).empty());  // allowed: nothing to move
}

TEST(IkScenario, UnloadableUrdfOrUnreachableHomeNameTheRobot) {
  auto specs = hrc::robots_from_scenario(minimal_scenario());
  specs[0].urdf_path = "/nonexistent/arm.urdf";
  try {
    hrc::IkEngine e(specs, kDt);
    FAIL() << "missing URDF accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("robot 'r2'"), std::string::npos) << e.what();
  }
  specs = hrc::robots_from_scenario(minimal_scenario());
  specs[1].home = Eigen::Vector3d(3.0, 3.0, 3.0);
  try {
    hrc::IkEngine e(specs, kDt);
    FAIL() << "unreachable home accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("robot 'r1'"), std::string::npos) << e.what();
  }
}

TEST_F(Engine, StartsIdleAtHomeToolDownInSortedOrder) {
  ASSERT_EQ(engine_.robot_ids(), (std::vector<std::string>{"r1", "r2"}));
  EXPECT_EQ(engine_.index_of("r2"), 1);
  EXPECT_EQ(engine_.index_of("r3"), -1);
  RobotState st;
  engine_.fill_state(0, st);
  EXPECT_EQ(st.robot(), "r1");
  EXPECT_EQ(st.status(), hrc::v2::MOTION_STATUS_IDLE);
  EXPECT_EQ(st.command_id(), 0u);
  EXPECT_LT((tcp_of(st) - Eigen::Vector3d(0.35, 0.30, 0.35)).norm(), 1e-4);
  const auto& q = st.tcp().orientation();
  const Eigen::Quaterniond r(q.w(), q.x(), q.y(), q.z());
  EXPECT_NEAR(std::abs(r.norm() - 1.0), 0.0, 1e-9);
  EXPECT_LT((r * Eigen::Vector3d::UnitZ() - Eigen::Vector3d(0, 0, -1)).norm(), 1e-3);  // tool down
  // joint names in URDF order, one position per joint
  const auto& names = engine_.model(0).joint_names();
  ASSERT_EQ(st.joint_names_size(), static_cast<int>(names.size()));
  ASSERT_EQ(st.joint_positions_size(), static_cast<int>(names.size()));
  for (int i = 0; i < st.joint_names_size(); ++i) {
    EXPECT_EQ(st.joint_names(i), names[static_cast<std::size_t>(i)]);
    EXPECT_DOUBLE_EQ(st.joint_positions(i), engine_.state(0).q[i]);
  }
  EXPECT_EQ(st.joint_names(0), "j1_base_yaw");
}

TEST_F(Engine, MoveReachesTheTargetAtTheCappedSpeedAndEchoesTheId) {
  // max_speed above the robot's limit is capped at max_tcp_speed (0.5 m/s)
  EXPECT_EQ(engine_.apply("r1", move(0.20, 0.25, 0.25, 7, 30, 5.0)), "");
  RobotState st;
  engine_.fill_state(0, st);
  EXPECT_EQ(st.status(), hrc::v2::MOTION_STATUS_MOVING);
  EXPECT_EQ(st.command_id(), 7u);
  double vmax = 0;
  const int ticks = run_r1(2000, &vmax);
  engine_.fill_state(0, st);
  EXPECT_EQ(st.status(), hrc::v2::MOTION_STATUS_REACHED) << st.detail();
  EXPECT_EQ(st.command_id(), 7u);
  EXPECT_LT((tcp_of(st) - Eigen::Vector3d(0.20, 0.25, 0.25)).norm(), 0.005);
  EXPECT_LE(vmax, 0.5 * 1.02);
  EXPECT_GT(vmax, 0.3);  // it did cruise, not crawl
  EXPECT_GT(ticks, 10);
  // r2 was not commanded: still idle
  engine_.fill_state(1, st);
  EXPECT_EQ(st.status(), hrc::v2::MOTION_STATUS_IDLE);
}

TEST_F(Engine, CommandSpeedBelowTheCapIsHonoured) {
  ASSERT_EQ(engine_.apply("r1", move(0.20, 0.25, 0.25, 1, 0, 0.1)), "");
  double vmax = 0;
  run_r1(4000, &vmax);
  EXPECT_LE(vmax, 0.1 * 1.02);
  EXPECT_GT(vmax, 0.08);
  RobotState st;
  engine_.fill_state(0, st);
  EXPECT_EQ(st.status(), hrc::v2::MOTION_STATUS_REACHED);
  EXPECT_NEAR(st.tcp_speed(), 0.0, 1e-3);  // the last tick ends the ramp-down
  engine_.step();
  engine_.fill_state(0, st);
  EXPECT_EQ(st.tcp_speed(), 0.0);  // then it stands still
}

TEST_F(Engine, BadCommandsChangeNothing) {
  ASSERT_EQ(engine_.apply("r1", move(0.20, 0.25, 0.25, 3)), "");
  for (int k = 0; k < 20; ++k) engine_.step();
  const Eigen::VectorXd q_before = engine_.state(0).q;

  auto nan_target = move(std::nan(""), 0.25, 0.25, 4);
  EXPECT_NE(engine_.apply("r1", nan_target).find("NaN"), std::string::npos);
  auto inf_yaw = move(0.2, 0.25, 0.25, 5, std::numeric_limits<double>::infinity());
  EXPECT_NE(engine_.apply("r1", inf_yaw), "");
  auto neg = move(0.2, 0.25, 0.25, 6);
  neg.set_approach_height(-0.1);
  EXPECT_NE(engine_.apply("r1", neg), "");
  auto slow = move(0.2, 0.25, 0.25, 7);
  slow.set_max_speed(-1);
  EXPECT_NE(engine_.apply("r1", slow).find("max_speed"), std::string::npos);
  RobotCommand nan_hold;  // every kind's numbers are checked
  nan_hold.set_kind(RobotCommand::KIND_HOLD);
  nan_hold.mutable_target()->set_y(std::nan(""));
  EXPECT_NE(engine_.apply("r1", nan_hold).find("NaN"), std::string::npos);
  auto unspecified = move(0.2, 0.25, 0.25, 8);
  unspecified.set_kind(RobotCommand::KIND_UNSPECIFIED);
  EXPECT_NE(engine_.apply("r1", unspecified).find("neither MOVE, HOLD nor SPEED_SCALE"),
            std::string::npos);
  const std::string unknown = engine_.apply("r9", move(0.2, 0.25, 0.25, 9));
  EXPECT_NE(unknown.find("unknown robot 'r9'"), std::string::npos) << unknown;

  // r1 still follows command 3 from where it was
  EXPECT_EQ(engine_.command_id(0), 3u);
  EXPECT_TRUE(engine_.state(0).q.isApprox(q_before));
  EXPECT_EQ(engine_.state(0).status, hrc::kin::MotionStatus::Moving);
  run_r1(2000);
  RobotState st;
  engine_.fill_state(0, st);
  EXPECT_EQ(st.status(), hrc::v2::MOTION_STATUS_REACHED);
  EXPECT_EQ(st.command_id(), 3u);
}

TEST_F(Engine, SpeedScaleStopsAndResumesTheMoveWithoutTakingItsCommandId) {
  ASSERT_EQ(engine_.apply("r1", move(0.20, 0.25, 0.25, 5)), "");
  for (int k = 0; k < 40; ++k) engine_.step();
  RobotState st;
  engine_.fill_state(0, st);
  EXPECT_FALSE(st.has_speed_scale());  // unset at scale 1: unchanged bytes for other policies
  RobotCommand scale;
  scale.set_kind(RobotCommand::KIND_SPEED_SCALE);
  scale.set_command_id(99);
  scale.set_speed_scale(0.0);
  ASSERT_EQ(engine_.apply("r1", scale), "");
  for (int k = 0; k < 240; ++k) engine_.step();
  engine_.fill_state(0, st);
  EXPECT_EQ(st.command_id(), 5u);
  EXPECT_EQ(st.status(), hrc::v2::MOTION_STATUS_MOVING);
  EXPECT_EQ(st.tcp_speed(), 0.0);
  ASSERT_TRUE(st.has_speed_scale());
  EXPECT_EQ(st.speed_scale(), 0.0);
  for (const double bad : {-0.1, 1.5, std::nan("")}) {
    scale.set_speed_scale(bad);
    EXPECT_NE(engine_.apply("r1", scale).find("outside [0, 1]"), std::string::npos) << bad;
  }
  scale.set_speed_scale(1.0);
  ASSERT_EQ(engine_.apply("r1", scale), "");
  run_r1(4000);
  engine_.fill_state(0, st);
  EXPECT_EQ(st.status(), hrc::v2::MOTION_STATUS_REACHED);
  EXPECT_EQ(st.command_id(), 5u);
  EXPECT_FALSE(st.has_speed_scale());
}

TEST_F(Engine, HoldStopsSmoothlyAndReportsHolding) {
  ASSERT_EQ(engine_.apply("r1", move(0.20, 0.25, 0.25, 1)), "");
  for (int k = 0; k < 40; ++k) engine_.step();
  ASSERT_GT(engine_.state(0).tcp_speed, 0.05);
  RobotCommand hold;
  hold.set_robot("r1");
  hold.set_command_id(2);
  hold.set_kind(RobotCommand::KIND_HOLD);
  ASSERT_EQ(engine_.apply("r1", hold), "");
  double prev = engine_.state(0).tcp_speed;
  for (int k = 0; k < 240; ++k) {
    engine_.step();
    // smooth: the measured speed changes by at most the 2 m/s^2 acceleration limit per tick
    EXPECT_NEAR(engine_.state(0).tcp_speed, prev, 2.0 * kDt * 1.05 + 1e-4) << "tick " << k;
    prev = engine_.state(0).tcp_speed;
  }
  RobotState st;
  engine_.fill_state(0, st);
  EXPECT_EQ(st.status(), hrc::v2::MOTION_STATUS_HOLDING);
  EXPECT_EQ(st.command_id(), 2u);
  EXPECT_NEAR(st.tcp_speed(), 0.0, 1e-9);
}

TEST_F(Engine, UnreachableTargetIsReportedAndNothingBecomesNaN) {
  ASSERT_EQ(engine_.apply("r1", move(2.0, 2.0, 0.3, 11)), "");  // applied: the arm reports it
  RobotState st;
  for (int k = 0; k < 50; ++k) {
    engine_.step();
    engine_.fill_state(0, st);
    for (const double q : st.joint_positions()) ASSERT_TRUE(std::isfinite(q));
    ASSERT_TRUE(tcp_of(st).allFinite());
    ASSERT_TRUE(std::isfinite(st.tcp_speed()));
  }
  EXPECT_EQ(st.status(), hrc::v2::MOTION_STATUS_UNREACHABLE);
  EXPECT_EQ(st.command_id(), 11u);
  EXPECT_NE(st.detail().find("unreachable"), std::string::npos) << st.detail();
  EXPECT_LT((tcp_of(st) - Eigen::Vector3d(0.35, 0.30, 0.35)).norm(), 1e-3);  // stayed home
  // a reachable command afterwards clears the detail
  ASSERT_EQ(engine_.apply("r1", move(0.30, 0.30, 0.30, 12)), "");
  run_r1(2000);
  engine_.fill_state(0, st);
  EXPECT_EQ(st.status(), hrc::v2::MOTION_STATUS_REACHED);
  EXPECT_EQ(st.detail(), "");
}

TEST_F(Engine, FillStateReusesTheMessage) {
  RobotState st;
  engine_.fill_state(1, st);
  engine_.fill_state(1, st);
  EXPECT_EQ(st.robot(), "r2");
  EXPECT_EQ(st.joint_names_size(), engine_.model(1).dof());
  EXPECT_EQ(st.joint_positions_size(), engine_.model(1).dof());
}

TEST_F(Engine, ReachAnswersEveryItem) {
  hrc::v2::ReachRequest req;
  auto add = [&](const std::string& id, const std::string& robot, double x, double y, double z) {
    auto* it = req.add_items();
    it->set_id(id);
    it->set_robot(robot);
    it->mutable_target()->set_x(x);
    it->mutable_target()->set_y(y);
    it->mutable_target()->set_z(z);
  };
  add("good", "r1", 0.66, 0.30, 0.06);  // RA1's pick in minimal.toml
  add("far", "r1", 1.60, 0.30, 0.06);   // ~1.2 m from the base: beyond the 0.8 m reach
  add("nobody", "r7", 0.0, 0.0, 0.1);
  add("nan", "r2", 0.0, std::nan(""), 0.1);
  add("good2", "r2", -0.60, 0.35, 0.05);  // r2's feeder
  const auto rep = engine_.reach(req);
  ASSERT_EQ(rep.results_size(), 5);
  EXPECT_EQ(rep.results(0).id(), "good");
  EXPECT_TRUE(rep.results(0).reachable()) << rep.results(0).detail();
  EXPECT_LT(rep.results(0).position_error_m(), 1e-4);
  EXPECT_EQ(rep.results(0).detail(), "");
  EXPECT_FALSE(rep.results(1).reachable());
  EXPECT_GT(rep.results(1).position_error_m(), 0.1);
  EXPECT_NE(rep.results(1).detail().find("cannot reach"), std::string::npos);
  EXPECT_FALSE(rep.results(2).reachable());
  EXPECT_NE(rep.results(2).detail().find("unknown robot 'r7'"), std::string::npos);
  EXPECT_FALSE(rep.results(3).reachable());
  EXPECT_NE(rep.results(3).detail().find("NaN"), std::string::npos);
  EXPECT_TRUE(rep.results(4).reachable()) << rep.results(4).detail();
}

TEST(TickTimes, Quantiles) {
  hrc::TickTimes t;
  EXPECT_EQ(t.summary(), "no ticks");
  for (int i = 1; i <= 100; ++i) t.add(i - 0.5);  // 0.5 .. 99.5 us
  EXPECT_EQ(t.count(), 100u);
  EXPECT_DOUBLE_EQ(t.quantile(0.5), 50.0);
  EXPECT_DOUBLE_EQ(t.quantile(0.99), 99.0);
  EXPECT_DOUBLE_EQ(t.quantile(1.0), 99.5);
  t.add(1e6);  // beyond the histogram: the max
  EXPECT_DOUBLE_EQ(t.quantile(1.0), 1e6);
  EXPECT_NE(t.summary().find("p99"), std::string::npos);
}

// ---------------------------------------------------------------- over the bus

TEST(IkService, ValidatesTheCommandsAddress) {
  RobotCommand c;
  c.set_robot("r1");
  c.mutable_target()->set_x(0.4);
  EXPECT_EQ(hrc::IkService::validate_command("hrc/s/robot/r1/command", c), "");
  EXPECT_NE(hrc::IkService::validate_command("hrc/s/robot/r2/command", c).find("'r2'"),
            std::string::npos);
  c.clear_robot();  // an empty robot field takes the key's
  EXPECT_EQ(hrc::IkService::validate_command("hrc/s/robot/r2/command", c), "");
}

TEST(IkService, PublishesStatesOnChangeWithKeyframesAndCountsBadCommands) {
  const auto peers = hrc::test::peer_pair();
  hrc::IkEngine engine(hrc::robots_from_scenario(minimal_scenario()), kDt);
  hrc::Bus bus(peers.a, "iks", "ik_cpp");
  hrc::LockstepParticipant participant(bus);
  hrc::IkService service(bus, participant, engine);

  hrc::Bus watcher(peers.b, "iks", "watcher");
  std::mutex mutex;
  std::vector<RobotState> got;
  watcher.subscribe<RobotState>(watcher.keys().robot_states(),
                                [&](const std::string&, const RobotState& s) {
                                  const std::lock_guard<std::mutex> lock(mutex);
                                  got.push_back(s);
                                });
  ASSERT_TRUE(hrc::test::wait_until([&] {
    return bus.publisher(bus.keys().robot_state("r1")).has_subscribers() &&
           bus.publisher(bus.keys().robot_state("r2")).has_subscribers();
  }));

  service.on_command("hrc/iks/robot/r1/command", move(0.20, 0.25, 0.25, 5));
  auto bad = move(0.20, std::nan(""), 0.25, 6);
  service.on_command("hrc/iks/robot/r1/command", bad);
  auto stranger = move(0.2, 0.25, 0.25, 7);
  stranger.set_robot("r9");
  service.on_command("hrc/iks/robot/r9/command", stranger);  // unknown robot
  EXPECT_EQ(service.commands_received(), 1u);
  EXPECT_EQ(service.commands_rejected(), 2u);
  EXPECT_EQ(bus.stats().decode_errors("hrc/iks/robot/r1/command"), 1u);
  EXPECT_EQ(bus.stats().decode_errors("hrc/iks/robot/r9/command"), 1u);

  // r1 moves to its target: a state every tick while it moves, then nothing until the keyframe
  // once per simulated second. r2 stands still: its first state and the keyframe (receivers
  // hold the last state).
  const uint64_t keyframe = static_cast<uint64_t>(std::lround(1.0 / kDt));
  hrc::v2::ClockTick tick;
  tick.set_dt(kDt);
  for (uint64_t k = 0; k <= keyframe; ++k) {
    tick.mutable_header()->set_tick(k);
    tick.mutable_header()->set_sim_time(static_cast<double>(k) * kDt);
    service.step(tick);
  }
  std::vector<uint64_t> r1_ticks;
  std::vector<uint64_t> r2_ticks;
  std::vector<RobotState> r1;
  ASSERT_TRUE(hrc::test::wait_until([&] {
    const std::lock_guard<std::mutex> lock(mutex);
    r1.clear();
    r1_ticks.clear();
    r2_ticks.clear();
    for (const auto& s : got) {
      EXPECT_EQ(s.header().sender(), "ik_cpp");
      if (s.robot() == "r1") {
        r1.push_back(s);
        r1_ticks.push_back(s.header().tick());
      } else {
        r2_ticks.push_back(s.header().tick());
        EXPECT_EQ(s.status(), hrc::v2::MOTION_STATUS_IDLE);
      }
    }
    return r2_ticks.size() >= 2 && !r1_ticks.empty() && r1_ticks.back() == keyframe;
  }));
  EXPECT_EQ(r2_ticks, (std::vector<uint64_t>{0, keyframe}));
  ASSERT_GE(r1.size(), 3u);
  for (std::size_t i = 0; i < r1.size(); ++i) {
    EXPECT_EQ(r1[i].header().seq(), i + 1);  // seq counts what was sent, from 1
    EXPECT_EQ(r1[i].command_id(), 5u);
  }
  // Moving: ticks 0, 1, 2, ... without a gap, until it reached the target.
  const std::size_t last_change = r1.size() - 2;  // the one before the keyframe
  for (std::size_t i = 0; i <= last_change; ++i) EXPECT_EQ(r1_ticks[i], i);
  EXPECT_EQ(r1[0].status(), hrc::v2::MOTION_STATUS_MOVING);
  EXPECT_EQ(r1[last_change].status(), hrc::v2::MOTION_STATUS_REACHED);
  EXPECT_LT(r1_ticks[last_change], keyframe - 1);  // then it stood still and sent nothing
  EXPECT_EQ(service.compute_times().count(), keyframe + 1);
  EXPECT_EQ(service.step_times().count(), keyframe + 1);
}

TEST(IkService, ServesReachQueries) {
  const auto peers = hrc::test::peer_pair();
  hrc::IkEngine engine(hrc::robots_from_scenario(minimal_scenario()), kDt);
  hrc::Bus bus(peers.a, "ikq", "ik_cpp");
  hrc::LockstepParticipant participant(bus);
  hrc::IkService service(bus, participant, engine);
  hrc::Bus asker(peers.b, "ikq", "orchestrator");
  hrc::v2::ReachRequest req;
  auto* it = req.add_items();
  it->set_id("home");
  it->set_robot("r2");
  it->mutable_target()->set_x(-0.35);
  it->mutable_target()->set_y(0.30);
  it->mutable_target()->set_z(0.35);
  std::vector<hrc::v2::ReachReply> replies;
  ASSERT_TRUE(hrc::test::wait_until([&] {
    replies = asker.get<hrc::v2::ReachReply>(asker.keys().robot_reach(), &req,
                                             std::chrono::milliseconds(500));
    return !replies.empty();
  }));
  ASSERT_EQ(replies.front().results_size(), 1);
  EXPECT_EQ(replies.front().results(0).id(), "home");
  EXPECT_TRUE(replies.front().results(0).reachable());
  EXPECT_EQ(replies.front().header().sender(), "ik_cpp");
}

}  // namespace

// The check mode: the moves of a request, each started where the request says, with the kind and
// verdict the engine gives them; the unreachable one names where and why.
TEST(IkCheck, PlansEachMoveFromItsStartAndReportsKindAndWhy) {
  hrc::v2::MotionCheckRequest req;
  *req.mutable_scenario() = minimal_scenario();
  auto add = [&](const std::string& label, const RobotCommand& c, const std::string& start) {
    hrc::v2::MoveCheck* m = req.add_moves();
    m->set_label(label);
    *m->mutable_command() = c;
    m->set_start(start);
  };
  add("line", move(0.25, 0.55, 0.15, 1), "");           // home -> beside the base: a line
  add("over the base", move(0.65, 0.55, 0.15, 2), "");  // from there across the base: joint
  add("far", move(2.0, 2.0, 0.3, 3), "home");
  add("again", move(0.65, 0.55, 0.15, 4), "line");  // starts where "line" ended
  add("bad start", move(0.30, 0.30, 0.30, 5), "nowhere");
  RobotCommand other = move(0.0, 0.0, 0.0, 6);
  other.set_robot("r9");
  add("unknown", other, "");
  const hrc::v2::MotionCheckReply reply = hrc::check_moves(req);
  ASSERT_EQ(reply.results_size(), 6);
  const auto& r = reply.results();
  EXPECT_TRUE(r[0].feasible()) << r[0].detail();
  EXPECT_EQ(r[0].kind(), hrc::v2::MOTION_KIND_LINEAR);
  EXPECT_TRUE(r[1].feasible()) << r[1].detail();
  EXPECT_EQ(r[1].kind(), hrc::v2::MOTION_KIND_JOINT);
  EXPECT_GT(r[1].duration_s(), 0.0);
  EXPECT_LE(r[1].max_tcp_speed(), 0.5 * 1.02);
  EXPECT_FALSE(r[2].feasible());
  EXPECT_NE(r[2].detail().find("target (2.000, 2.000, 0.300) yaw 0.0 deg unreachable"),
            std::string::npos)
      << r[2].detail();
  EXPECT_TRUE(r[3].feasible());
  EXPECT_EQ(r[3].kind(), hrc::v2::MOTION_KIND_JOINT);
  EXPECT_FALSE(r[4].feasible());
  EXPECT_NE(r[4].detail().find("no earlier move"), std::string::npos);
  EXPECT_FALSE(r[5].feasible());
  EXPECT_NE(r[5].detail().find("unknown robot"), std::string::npos);
}

TEST_F(Engine, StateReportsTheMotionKind) {
  RobotState st;
  engine_.fill_state(0, st);
  EXPECT_EQ(st.motion_kind(), hrc::v2::MOTION_KIND_UNSPECIFIED);
  ASSERT_EQ(engine_.apply("r1", move(0.20, 0.25, 0.25, 1)), "");
  engine_.fill_state(0, st);
  EXPECT_EQ(st.motion_kind(), hrc::v2::MOTION_KIND_LINEAR);
}

TEST_F(Engine, StatesDeclareJointSpeedBoundsThatTheArmKeeps) {
  RobotState st;
  engine_.fill_state(0, st);
  ASSERT_EQ(st.joint_speed_fraction_bounds_size(), st.joint_names_size());  // known at rest
  for (const double f : st.joint_speed_fraction_bounds()) EXPECT_EQ(f, 0.0);
  const hrc::kin::RobotModel& m = engine_.model(0);
  // the links' speeds: one per joint of the chain (not the fingers), 0 at rest
  ASSERT_EQ(st.link_linear_speed_bounds_size(), m.dof());
  ASSERT_EQ(st.link_angular_speed_bounds_size(), m.dof());
  for (const double v : st.link_linear_speed_bounds()) EXPECT_EQ(v, 0.0);
  const double targets[][2] = {{0.20, 0.25}, {0.35, 0.10}};
  for (const uint32_t window : {0u, 8u}) {
    engine_.set_speed_window(window);
    const double* t = targets[window == 0 ? 0 : 1];
    ASSERT_EQ(engine_.apply("r1", move(t[0], t[1], 0.25, 3)), "");
    // Every later tick of the move (within the window) stays within each state's declaration.
    std::vector<Eigen::VectorXd> declared;
    double peak = 0.0;
    for (int k = 0; k < 2000; ++k) {
      engine_.fill_state(0, st);
      ASSERT_EQ(st.joint_speed_fraction_bounds_size(), m.dof());
      ASSERT_EQ(st.link_linear_speed_bounds_size(), m.dof());
      EXPECT_EQ(st.joint_speed_window_ticks(), window);
      if (k == 10) {  // moving: the link nearest the tool moves, within the TCP's speed
        EXPECT_GT(st.link_linear_speed_bounds(m.dof() - 1), 0.0);
        EXPECT_LT(st.link_linear_speed_bounds(m.dof() - 1), 1.0);
      }
      declared.emplace_back(Eigen::Map<const Eigen::VectorXd>(
          st.joint_speed_fraction_bounds().data(), st.joint_speed_fraction_bounds_size()));
      const Eigen::VectorXd q0 = engine_.state(0).q;
      engine_.step();
      const Eigen::ArrayXd f =
          (engine_.state(0).q - q0).array().abs() / (m.max_velocity().array() * kDt);
      peak = std::max(peak, f.maxCoeff());
      const std::size_t first =
          window == 0 || declared.size() <= window ? 0 : declared.size() - window;
      for (std::size_t d = first; d < declared.size(); ++d)
        for (int j = 0; j < m.dof(); ++j)
          ASSERT_LE(f[j], declared[d][j]) << "window " << window << " tick " << k << " joint " << j;
      if (engine_.state(0).status != hrc::kin::MotionStatus::Moving) break;
    }
    EXPECT_GT(peak, 0.0);
    engine_.fill_state(0, st);
    for (const double f : st.joint_speed_fraction_bounds()) EXPECT_EQ(f, 0.0);  // at rest again
  }
  // Without the lookahead (realtime) nothing is declared.
  engine_.set_declare_speeds(false);
  ASSERT_EQ(engine_.apply("r1", move(0.20, 0.25, 0.25, 5)), "");
  engine_.fill_state(0, st);
  EXPECT_EQ(st.joint_speed_fraction_bounds_size(), 0);
  EXPECT_EQ(st.link_linear_speed_bounds_size(), 0);
  EXPECT_EQ(st.link_angular_speed_bounds_size(), 0);
  engine_.set_declare_speeds(true);
}

TEST_F(Engine, UnderASpeedScaleTheArmKeepsWhatItDeclaresUntilTheNextCommand) {
  // SSM's scale commands: 0.5, 0 (a protective stop), 1 again. After each, the states declare
  // again (from the ramp to the new scale on) and the arm keeps every declaration until the
  // next command (physics counts the exchange a command comes in with the full bound).
  const hrc::kin::RobotModel& m = engine_.model(0);
  ASSERT_EQ(engine_.apply("r1", move(0.30, 0.10, 0.25, 4)), "");
  const std::pair<int, double> commands[] = {{40, 0.5}, {160, 0.0}, {400, 1.0}};
  std::vector<Eigen::VectorXd> declared;
  RobotState st;
  double slow_peak = 0.0, stopped_peak = 1.0;
  int k = 0;
  for (; k < 4000; ++k) {
    for (const auto& [at, value] : commands) {
      if (k != at) continue;
      RobotCommand scale;
      scale.set_kind(RobotCommand::KIND_SPEED_SCALE);
      scale.set_speed_scale(value);
      ASSERT_EQ(engine_.apply("r1", scale), "");
      declared.clear();  // what came before the command no longer binds
    }
    engine_.fill_state(0, st);
    ASSERT_EQ(st.joint_speed_fraction_bounds_size(), m.dof()) << "tick " << k;
    declared.emplace_back(Eigen::Map<const Eigen::VectorXd>(st.joint_speed_fraction_bounds().data(),
                                                            st.joint_speed_fraction_bounds_size()));
    const Eigen::VectorXd q0 = engine_.state(0).q;
    engine_.step();
    const Eigen::ArrayXd f =
        (engine_.state(0).q - q0).array().abs() / (m.max_velocity().array() * kDt);
    if (k > 100 && k < 160) slow_peak = std::max(slow_peak, f.maxCoeff());
    if (k == 399) stopped_peak = f.maxCoeff();
    for (const Eigen::VectorXd& d : declared)
      for (int j = 0; j < m.dof(); ++j) ASSERT_LE(f[j], d[j]) << "tick " << k << " joint " << j;
    if (engine_.state(0).status != hrc::kin::MotionStatus::Moving) break;
  }
  EXPECT_GT(k, 400);             // it ended after the stop
  EXPECT_GT(slow_peak, 0.0);     // it moved at half speed ...
  EXPECT_EQ(stopped_peak, 0.0);  // ... and stood still at 0
  engine_.fill_state(0, st);
  for (const double f : st.joint_speed_fraction_bounds()) EXPECT_EQ(f, 0.0);  // at rest
}
