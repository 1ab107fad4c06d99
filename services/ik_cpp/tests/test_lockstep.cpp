// LockstepParticipant against an in-process fake clock master ("physics") over loopback.
#include <gtest/gtest.h>

#include <atomic>
#include <future>
#include <iostream>
#include <map>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

#include "hrc/lockstep.hpp"
#include "test_util.hpp"

namespace {

using hrc::test::wait_until;

/// Minimal clock master: token alive/physics, collects acks, publishes ticks and run/end.
class FakePhysics {
 public:
  explicit FakePhysics(const hrc::BusConfig& cfg, const std::string& session)
      : bus(cfg, session, "physics") {
    bus.subscribe<hrc::v2::TickAck>(bus.keys().clock_acks(),
                                    [this](const std::string&, const hrc::v2::TickAck& a) {
                                      const std::lock_guard<std::mutex> lock(mutex);
                                      acks.push_back(a);
                                    });
    // Like the clock master: an abort ends the run at once, naming its sender.
    bus.subscribe<hrc::v2::RunControl>(
        bus.keys().run_controls(), [this](const std::string&, const hrc::v2::RunControl& c) {
          if (c.command() != hrc::v2::RunControl::COMMAND_ABORT) return;
          {
            const std::lock_guard<std::mutex> lock(mutex);
            aborts.push_back(c);
          }
          end(false, "aborted by " + c.header().sender() + ": " + c.reason(), c.header().sender());
        });
    bus.watch_liveliness([this](const std::string& s, bool alive) {
      const std::lock_guard<std::mutex> lock(mutex);
      alive_services[s] = alive;
    });
    bus.declare_token();
  }
  bool sees_alive(const std::string& s) {
    const std::lock_guard<std::mutex> lock(mutex);
    const auto it = alive_services.find(s);
    return it != alive_services.end() && it->second;
  }
  std::size_t ack_count() {
    const std::lock_guard<std::mutex> lock(mutex);
    return acks.size();
  }
  void tick(uint64_t k, std::vector<hrc::v2::PublishedMark> marks = {}) {
    hrc::v2::ClockTick t;
    t.set_mode(hrc::v2::CLOCK_MODE_LOCKSTEP);
    t.set_dt(0.01);
    t.add_participants("ik_cpp");
    for (auto& m : marks) *t.add_published() = m;
    bus.publisher(bus.keys().clock(), hrc::PublisherOptions{true, true})
        .put(t, k, 0.01 * static_cast<double>(k));
  }
  void end(bool ok, const std::string& reason, const std::string& failed = "") {
    hrc::v2::RunEnd e;
    e.set_ok(ok);
    e.set_reason(reason);
    e.set_failed_participant(failed);
    bus.publisher(bus.keys().run_end()).put(e, 0, 0.0);
  }

  hrc::Bus bus;
  std::mutex mutex;
  std::vector<hrc::v2::TickAck> acks;
  std::vector<hrc::v2::RunControl> aborts;
  std::map<std::string, bool> alive_services;
};

class Lockstep : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto cfg = hrc::test::peer_pair();
    physics_ = std::make_unique<FakePhysics>(cfg.a, "ls");
    bus_ = std::make_unique<hrc::Bus>(cfg.b, "ls", "ik_cpp");
  }
  void TearDown() override {
    bus_.reset();
    physics_.reset();
  }
  std::unique_ptr<FakePhysics> physics_;
  std::unique_ptr<hrc::Bus> bus_;
};

TEST_F(Lockstep, TicksAreSteppedAndAckedThenRunEndOkReturnsZero) {
  hrc::LockstepParticipant p(*bus_);
  std::vector<uint64_t> stepped;
  p.on_tick([&](const hrc::v2::ClockTick& t) {
    stepped.push_back(t.header().tick());
    hrc::v2::RobotState s;
    s.set_robot("r1");
    bus_->publisher(bus_->keys().robot_state("r1"))
        .put(s, t.header().tick(), t.header().sim_time());
  });
  p.start();
  ASSERT_TRUE(wait_until([&] { return physics_->sees_alive("ik_cpp"); }));
  auto result = std::async(std::launch::async, [&] { return p.run(); });
  constexpr uint64_t kTicks = 50;
  for (uint64_t k = 1; k <= kTicks; ++k) {
    physics_->tick(k);
    ASSERT_TRUE(wait_until([&] { return physics_->ack_count() == k; })) << "no ack for tick " << k;
  }
  physics_->end(true, "ticks");
  const hrc::Outcome o = result.get();
  EXPECT_TRUE(o.ok);
  EXPECT_EQ(o.exit_code(), 0);
  EXPECT_EQ(o.reason, "ticks");
  ASSERT_TRUE(o.run_end.has_value());
  ASSERT_EQ(stepped.size(), kTicks);
  for (uint64_t k = 1; k <= kTicks; ++k) EXPECT_EQ(stepped[k - 1], k);
  const std::lock_guard<std::mutex> lock(physics_->mutex);
  for (uint64_t k = 1; k <= kTicks; ++k) {
    const auto& a = physics_->acks[k - 1];
    EXPECT_EQ(a.header().tick(), k);
    EXPECT_EQ(a.header().sender(), "ik_cpp");
    EXPECT_EQ(a.header().seq(), k);
    EXPECT_EQ(a.participant(), "ik_cpp");
    // The ack tells physics how many states it must have seen (the ack key itself is left out).
    ASSERT_EQ(a.published_size(), 1);
    EXPECT_EQ(a.published(0).key(), "hrc/ls/robot/r1/state");
    EXPECT_EQ(a.published(0).seq(), k);
  }
  EXPECT_EQ(bus_->stats().ticks_seen(), kTicks);
  EXPECT_EQ(bus_->stats().last_tick(), kTicks);
}

TEST_F(Lockstep, RunEndNotOkReturnsOne) {
  hrc::LockstepParticipant p(*bus_);
  p.start();
  ASSERT_TRUE(wait_until([&] { return physics_->sees_alive("ik_cpp"); }));
  auto result = std::async(std::launch::async, [&] { return p.run(); });
  physics_->end(false, "participant orchestrator missed the barrier");
  const hrc::Outcome o = result.get();
  EXPECT_FALSE(o.ok);
  EXPECT_EQ(o.exit_code(), 1);
}

TEST_F(Lockstep, LosingTheClockMasterEndsTheRunWithAnError) {
  hrc::LockstepParticipant p(*bus_);
  p.start();
  ASSERT_TRUE(wait_until([&] { return physics_->sees_alive("ik_cpp"); }));
  auto result = std::async(std::launch::async, [&] { return p.run(); });
  physics_.reset();  // its session closes, its token disappears
  ASSERT_EQ(result.wait_for(std::chrono::seconds(10)), std::future_status::ready);
  const hrc::Outcome o = result.get();
  EXPECT_FALSE(o.ok);
  EXPECT_NE(o.reason.find("physics"), std::string::npos) << o.reason;
}

TEST_F(Lockstep, StepWaitsForInputsTheClockSaysWerePublished) {
  hrc::LockstepParticipant p(*bus_);
  std::vector<std::string> log;
  std::mutex m;
  p.input<hrc::v2::RobotCommand>(bus_->keys().robot_commands(),
                                 [&](const std::string&, const hrc::v2::RobotCommand& c) {
                                   const std::lock_guard<std::mutex> lock(m);
                                   log.push_back("command " + std::to_string(c.command_id()));
                                 });
  p.on_tick([&](const hrc::v2::ClockTick& t) {
    const std::lock_guard<std::mutex> lock(m);
    log.push_back("step " + std::to_string(t.header().tick()));
  });
  p.start();
  ASSERT_TRUE(wait_until([&] { return physics_->sees_alive("ik_cpp"); }));
  auto result = std::async(std::launch::async, [&] { return p.run(); });
  // The clock says the orchestrator published command #1, but it is slower than the clock.
  const std::string key = bus_->keys().robot_command("r1");
  hrc::v2::PublishedMark mk;
  mk.set_key(key);
  mk.set_sender("orchestrator");
  mk.set_seq(1);
  physics_->tick(1, {mk});
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  {
    const std::lock_guard<std::mutex> lock(m);
    EXPECT_TRUE(log.empty()) << "stepped before its input arrived";
  }
  hrc::v2::RobotCommand c;
  c.set_command_id(77);
  c.mutable_header()->set_session("ls");
  c.mutable_header()->set_sender("orchestrator");
  c.mutable_header()->set_seq(1);
  c.mutable_header()->set_tick(0);
  physics_->bus.publisher(key).put_raw(c.SerializeAsString());
  ASSERT_TRUE(wait_until([&] { return physics_->ack_count() == 1; }));
  physics_->end(true, "ticks");
  EXPECT_TRUE(result.get().ok);
  const std::lock_guard<std::mutex> lock(m);
  EXPECT_EQ(log, (std::vector<std::string>{"command 77", "step 1"}));
}

TEST_F(Lockstep, AStepThatThrowsAbortsTheRunAtOnceNamingTheParticipant) {
  hrc::LockstepParticipant p(*bus_);
  std::chrono::steady_clock::time_point thrown_at;
  p.on_tick([&](const hrc::v2::ClockTick& t) {
    if (t.header().tick() == 3) {
      thrown_at = std::chrono::steady_clock::now();
      throw std::runtime_error("bad value in tick 3");
    }
  });
  p.start();
  ASSERT_TRUE(wait_until([&] { return physics_->sees_alive("ik_cpp"); }));
  auto result = std::async(std::launch::async, [&] { return p.run(); });
  for (uint64_t k = 1; k <= 3; ++k) physics_->tick(k);
  ASSERT_EQ(result.wait_for(std::chrono::seconds(2)), std::future_status::ready);
  const hrc::Outcome o = result.get();
  const double took_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - thrown_at)
          .count();
  std::cout << "run() returned " << took_ms << " ms after the step threw\n";
  EXPECT_LT(took_ms, 2000.0);
  EXPECT_FALSE(o.ok);
  EXPECT_EQ(o.exit_code(), 1);
  EXPECT_EQ(o.reason, "tick 3 failed: bad value in tick 3");
  ASSERT_TRUE(o.run_end.has_value()) << "run() returned before the clock master ended the run";
  EXPECT_EQ(o.run_end->failed_participant(), "ik_cpp");
  const std::lock_guard<std::mutex> lock(physics_->mutex);
  ASSERT_EQ(physics_->aborts.size(), 1U);
  EXPECT_EQ(physics_->aborts[0].header().sender(), "ik_cpp");
  EXPECT_EQ(physics_->aborts[0].header().tick(), 3U);
  EXPECT_EQ(physics_->aborts[0].reason(), "tick 3 failed: bad value in tick 3");
  EXPECT_EQ(physics_->acks.size(), 2U) << "the failed tick must not be acked";
}

TEST_F(Lockstep, NoTickWithinTheTimeoutIsAnError) {
  hrc::LockstepParticipant p(*bus_);
  p.start();
  const hrc::Outcome o = p.run(0.1);
  EXPECT_FALSE(o.ok);
  EXPECT_NE(o.reason.find("no clock tick"), std::string::npos) << o.reason;
}

TEST_F(Lockstep, StopEndsTheRun) {
  hrc::LockstepParticipant p(*bus_);
  p.start();
  auto result = std::async(std::launch::async, [&] { return p.run(); });
  p.stop("stopped by signal SIGTERM");
  const hrc::Outcome o = result.get();
  EXPECT_TRUE(o.stopped);
  EXPECT_EQ(o.reason, "stopped by signal SIGTERM");
}

}  // namespace
