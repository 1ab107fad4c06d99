// The Inbox releases inputs tick by tick in (tick, subscription order, key, sender, seq) order,
// whatever order they arrived in. One bus publishes to itself (zenoh delivers locally).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "hrc/inbox.hpp"
#include "test_util.hpp"

namespace {

using hrc::test::wait_until;

template <class M>
std::string with_header(M msg, const std::string& sender, uint64_t seq, uint64_t tick) {
  auto* h = msg.mutable_header();
  h->set_session("inbox");
  h->set_sender(sender);
  h->set_seq(seq);
  h->set_tick(tick);
  return msg.SerializeAsString();
}

hrc::v2::PublishedMark mark(const std::string& key, const std::string& sender, uint64_t seq) {
  hrc::v2::PublishedMark m;
  m.set_key(key);
  m.set_sender(sender);
  m.set_seq(seq);
  return m;
}

TEST(Inbox, DeliversInDeterministicOrderUpToTheTick) {
  hrc::Bus bus(hrc::BusConfig{}, "inbox", "ik_cpp");
  hrc::Inbox inbox(bus);
  std::vector<std::string> order;
  const auto& k = bus.keys();
  inbox.add<hrc::v2::HumanState>(
      k.human_state(), [&](const std::string& key, const hrc::v2::HumanState& m) {
        order.push_back(key + "|" + m.header().sender() + "#" + std::to_string(m.header().seq()));
      });
  inbox.add<hrc::v2::RobotCommand>(
      k.robot_commands(), [&](const std::string& key, const hrc::v2::RobotCommand& m) {
        order.push_back(key + "|" + m.header().sender() + "#" + std::to_string(m.header().seq()));
      });
  auto& human = bus.publisher(k.human_state());
  auto& r1 = bus.publisher(k.robot_command("r1"));
  auto& r2 = bus.publisher(k.robot_command("r2"));
  ASSERT_TRUE(wait_until(
      [&] { return human.has_subscribers() && r1.has_subscribers() && r2.has_subscribers(); }));
  // Arrival order deliberately scrambled.
  r2.put_raw(with_header(hrc::v2::RobotCommand{}, "orchestrator", 1, 0));
  human.put_raw(with_header(hrc::v2::HumanState{}, "human_input", 2, 1));
  r1.put_raw(with_header(hrc::v2::RobotCommand{}, "orchestrator", 1, 0));
  human.put_raw(with_header(hrc::v2::HumanState{}, "human_input", 1, 0));
  human.put_raw(with_header(hrc::v2::HumanState{}, "physics", 1, 2));      // the master's, tick 2
  human.put_raw(with_header(hrc::v2::HumanState{}, "human_input", 3, 2));  // tick 2: not yet

  const std::vector<hrc::v2::PublishedMark> marks = {
      mark(k.human_state(), "human_input", 3), mark(k.robot_command("r1"), "orchestrator", 1),
      mark(k.robot_command("r2"), "orchestrator", 1), mark(k.human_state(), "physics", 1),
      mark(k.world_objects(), "physics", 99)};  // not subscribed: ignored
  EXPECT_TRUE(inbox.wait_for(marks, 5.0).empty());
  EXPECT_TRUE(inbox.missing(marks).empty());

  EXPECT_EQ(inbox.deliver(2, "physics"), 5u);
  // Oldest tick first (an exchange hands over several ticks), then subscription order, key,
  // sender, seq.
  const std::vector<std::string> expected = {
      "hrc/inbox/human/state|human_input#1", "hrc/inbox/robot/r1/command|orchestrator#1",
      "hrc/inbox/robot/r2/command|orchestrator#1", "hrc/inbox/human/state|human_input#2",
      "hrc/inbox/human/state|physics#1"};
  EXPECT_EQ(order, expected);
  EXPECT_EQ(inbox.pending(), 1u);
  EXPECT_EQ(inbox.deliver_through(2), 1u);
  EXPECT_EQ(order.back(), "hrc/inbox/human/state|human_input#3");
}

TEST(Inbox, WaitForReportsWhatNeverArrived) {
  hrc::Bus bus(hrc::BusConfig{}, "inbox", "ik_cpp");
  hrc::Inbox inbox(bus);
  inbox.add<hrc::v2::HumanState>(bus.keys().human_state(),
                                 [](const std::string&, const hrc::v2::HumanState&) {});
  const auto missing = inbox.wait_for({mark(bus.keys().human_state(), "human_input", 1)}, 0.05);
  ASSERT_EQ(missing.size(), 1u);
  EXPECT_EQ(missing[0].sender(), "human_input");
}

TEST(Inbox, ALaterMessageDoesNotHideALostOneAndADuplicateIsDroppedOnce) {
  hrc::Bus bus(hrc::BusConfig{}, "inbox", "ik_cpp");
  hrc::Inbox inbox(bus);
  std::vector<uint64_t> seqs;
  const auto& k = bus.keys();
  inbox.add<hrc::v2::RobotCommand>(k.robot_commands(),
                                   [&](const std::string&, const hrc::v2::RobotCommand& m) {
                                     seqs.push_back(m.header().seq());
                                   });
  auto& r1 = bus.publisher(k.robot_command("r1"));
  ASSERT_TRUE(wait_until([&] { return r1.has_subscribers(); }));
  r1.put_raw(with_header(hrc::v2::RobotCommand{}, "orchestrator", 1, 0));
  r1.put_raw(with_header(hrc::v2::RobotCommand{}, "orchestrator", 3, 2));  // #2 lost so far
  const auto m2 = mark(k.robot_command("r1"), "orchestrator", 2);
  const auto m3 = mark(k.robot_command("r1"), "orchestrator", 3);
  ASSERT_TRUE(wait_until([&] { return inbox.pending() == 2; }));
  // #3 is here, but #2 is not: both marks are missing
  EXPECT_EQ(inbox.wait_for({m2}, 0.05).size(), 1u);
  EXPECT_EQ(inbox.wait_for({m3}, 0.05).size(), 1u);
  r1.put_raw(with_header(hrc::v2::RobotCommand{}, "orchestrator", 2, 1));  // late after all
  EXPECT_TRUE(inbox.wait_for({m2, m3}, 5.0).empty());
  r1.put_raw(with_header(hrc::v2::RobotCommand{}, "orchestrator", 3, 2));  // again
  r1.put_raw(with_header(hrc::v2::RobotCommand{}, "orchestrator", 4, 3));
  EXPECT_TRUE(inbox.wait_for({mark(k.robot_command("r1"), "orchestrator", 4)}, 5.0).empty());
  EXPECT_EQ(inbox.deliver_through(3), 4u);
  EXPECT_EQ(seqs, (std::vector<uint64_t>{1, 2, 3, 4}));
  EXPECT_EQ(inbox.duplicates(), 1u);
}

}  // namespace
