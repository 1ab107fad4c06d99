#include <gtest/gtest.h>

#include <stdexcept>

#include "hrc/keys.hpp"

namespace {

TEST(Keys, EveryKeyOfTheArchitectureTable) {
  const hrc::Keys k("s1");
  EXPECT_EQ(k.prefix(), "hrc/s1");
  EXPECT_EQ(k.clock(), "hrc/s1/clock");
  EXPECT_EQ(k.clock_ack("ik_cpp"), "hrc/s1/clock/ack/ik_cpp");
  EXPECT_EQ(k.clock_acks(), "hrc/s1/clock/ack/*");
  EXPECT_EQ(k.run_control("ik_cpp"), "hrc/s1/run/control/ik_cpp");
  EXPECT_EQ(k.run_controls(), "hrc/s1/run/control/*");
  EXPECT_EQ(k.run_end(), "hrc/s1/run/end");
  EXPECT_EQ(k.alive("physics"), "hrc/s1/alive/physics");
  EXPECT_EQ(k.alive_all(), "hrc/s1/alive/*");
  EXPECT_EQ(k.stats("ik_cpp"), "hrc/s1/stats/ik_cpp");
  EXPECT_EQ(k.replay("ik_cpp"), "hrc/s1/replay/ik_cpp");
  EXPECT_EQ(k.scenario(), "hrc/s1/scenario");
  EXPECT_EQ(k.robot_command("ur5_a"), "hrc/s1/robot/ur5_a/command");
  EXPECT_EQ(k.robot_commands(), "hrc/s1/robot/*/command");
  EXPECT_EQ(k.robot_state("ur5_a"), "hrc/s1/robot/ur5_a/state");
  EXPECT_EQ(k.robot_states(), "hrc/s1/robot/*/state");
  EXPECT_EQ(k.robot_reach(), "hrc/s1/robot/reach");
  EXPECT_EQ(k.human_state(), "hrc/s1/human/state");
  EXPECT_EQ(k.world_objects(), "hrc/s1/world/objects");
  EXPECT_EQ(k.world_contacts(), "hrc/s1/world/contacts");
  EXPECT_EQ(k.world_separation(), "hrc/s1/world/separation");
  EXPECT_EQ(k.world_commands(), "hrc/s1/world/commands");
  EXPECT_EQ(k.task_events(), "hrc/s1/task/events");
  EXPECT_EQ(k.task_indicators(), "hrc/s1/task/indicators");
  EXPECT_EQ(k.task_metrics(), "hrc/s1/task/metrics");
  EXPECT_EQ(k.bench("ping"), "hrc/s1/bench/ping");
  EXPECT_EQ(k.all(), "hrc/s1/**");
}

TEST(Keys, RejectsIdsThatWouldWidenOrBreakAKey) {
  EXPECT_THROW(hrc::Keys(""), std::invalid_argument);
  EXPECT_THROW(hrc::Keys("a/b"), std::invalid_argument);
  EXPECT_THROW(hrc::Keys("*"), std::invalid_argument);
  EXPECT_THROW(hrc::Keys(std::string(65, 'a')), std::invalid_argument);
  const hrc::Keys k("s");
  EXPECT_THROW(k.robot_command("*"), std::invalid_argument);
  EXPECT_THROW(k.alive("a$b"), std::invalid_argument);
  EXPECT_THROW(k.clock_ack("x/y"), std::invalid_argument);
  try {
    k.stats("bad name");
    FAIL() << "expected invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'bad name'"), std::string::npos) << e.what();
  }
}

TEST(Keys, SegmentsOfReceivedKeys) {
  EXPECT_EQ(hrc::Keys::last_segment("hrc/s/alive/physics"), "physics");
  EXPECT_EQ(hrc::Keys::last_segment("plain"), "plain");
  EXPECT_EQ(hrc::Keys::robot_of("hrc/s/robot/r1/command"), "r1");
  EXPECT_EQ(hrc::Keys::robot_of("hrc/s/robot"), "");
}

}  // namespace
