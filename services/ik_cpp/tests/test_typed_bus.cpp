// Real zenoh sessions on loopback: two Bus objects in this process, A listening, B connecting.
#include <gtest/gtest.h>

#include <atomic>
#include <mutex>
#include <string>
#include <vector>

#include "hrc/typed_bus.hpp"
#include "test_util.hpp"

namespace {

using hrc::test::wait_until;

struct Received {
  std::mutex mutex;
  std::vector<std::pair<std::string, hrc::v2::HumanState>> msgs;
  std::size_t size() {
    const std::lock_guard<std::mutex> lock(mutex);
    return msgs.size();
  }
};

class TwoPeers : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto cfg = hrc::test::peer_pair();
    a_ = std::make_unique<hrc::Bus>(cfg.a, "t1", "alpha");
    b_ = std::make_unique<hrc::Bus>(cfg.b, "t1", "beta");
  }
  void TearDown() override {
    b_.reset();
    a_.reset();
  }
  std::unique_ptr<hrc::Bus> a_;
  std::unique_ptr<hrc::Bus> b_;
};

TEST(HeaderSeq, PerKeyStartingAtOneWithSessionTickTimeSender) {
  hrc::Bus bus(hrc::BusConfig{}, "seqs", "ik_cpp");
  auto& p1 = bus.publisher(bus.keys().robot_state("r1"));
  auto& p2 = bus.publisher(bus.keys().robot_state("r2"));
  EXPECT_EQ(&p1, &bus.publisher(bus.keys().robot_state("r1")));  // one publisher per key
  hrc::v2::RobotState s;
  EXPECT_EQ(p1.put(s, 7, 0.07), 1u);
  EXPECT_EQ(s.header().session(), "seqs");
  EXPECT_EQ(s.header().tick(), 7u);
  EXPECT_DOUBLE_EQ(s.header().sim_time(), 0.07);
  EXPECT_EQ(s.header().sender(), "ik_cpp");
  EXPECT_EQ(s.header().seq(), 1u);
  EXPECT_EQ(p1.put(s, 8, 0.08), 2u);
  EXPECT_EQ(s.header().seq(), 2u);
  EXPECT_EQ(p2.put(s, 8, 0.08), 1u);  // another key counts on its own
  EXPECT_EQ(bus.publisher(bus.keys().robot_state("r1")).put(s, 9, 0.09), 3u);
  // Header-less types are published without a seq.
  hrc::v2::ReachRequest req;
  EXPECT_EQ(bus.publisher(bus.keys().bench("reach")).put(req), 0u);

  const auto marks = bus.published_marks();
  ASSERT_EQ(marks.size(), 2u);  // keys with seq > 0, in key order
  EXPECT_EQ(marks[0].key(), "hrc/seqs/robot/r1/state");
  EXPECT_EQ(marks[0].seq(), 3u);
  EXPECT_EQ(marks[0].sender(), "ik_cpp");
  EXPECT_EQ(marks[1].key(), "hrc/seqs/robot/r2/state");
  EXPECT_EQ(marks[1].seq(), 1u);

  // new_marks: what moved since the previous call, without the excluded key.
  const auto first = bus.new_marks(bus.keys().robot_state("r2"));
  ASSERT_EQ(first.size(), 1u);
  EXPECT_EQ(first[0].key(), "hrc/seqs/robot/r1/state");
  EXPECT_EQ(first[0].seq(), 3u);
  EXPECT_TRUE(bus.new_marks(bus.keys().robot_state("r2")).empty());  // nothing new
  p1.put(s, 10, 0.10);
  const auto again = bus.new_marks();
  ASSERT_EQ(again.size(), 2u);  // r1 moved; r2 was never reported
  EXPECT_EQ(again[0].seq(), 4u);
  EXPECT_EQ(again[1].key(), "hrc/seqs/robot/r2/state");
  EXPECT_TRUE(bus.new_marks().empty());
}

TEST_F(TwoPeers, TypedRoundTripCarriesSenderAttachmentAndHeader) {
  Received got;
  std::atomic<int> attachments_ok{0};
  b_->subscribe<hrc::v2::HumanState>(b_->keys().human_state(),
                                     [&](const std::string& k, const hrc::v2::HumanState& m) {
                                       const std::lock_guard<std::mutex> lock(got.mutex);
                                       got.msgs.emplace_back(k, m);
                                     });
  // A raw subscriber on the same key sees the attachment (the sender name).
  hrc::Subscriber raw =
      b_->session().declare_subscriber(a_->keys().human_state(), [&](const hrc::SampleView& s) {
        if (s.attachment == "alpha") ++attachments_ok;
      });
  auto& pub = a_->publisher(a_->keys().human_state());
  ASSERT_TRUE(wait_until([&] { return pub.has_subscribers(); }));
  for (int i = 1; i <= 3; ++i) {
    hrc::v2::HumanState h;
    h.mutable_head()->mutable_position()->set_x(0.5 * i);
    h.set_left_grip(0.25);
    h.set_source(hrc::v2::INPUT_SOURCE_SCRIPTED);
    pub.put(h, static_cast<uint64_t>(10 + i), 0.01 * (10 + i));
  }
  ASSERT_TRUE(wait_until([&] { return got.size() == 3 && attachments_ok == 3; }));
  const std::lock_guard<std::mutex> lock(got.mutex);
  for (int i = 1; i <= 3; ++i) {
    const auto& [key, m] = got.msgs[static_cast<std::size_t>(i - 1)];
    EXPECT_EQ(key, "hrc/t1/human/state");
    EXPECT_EQ(m.header().sender(), "alpha");
    EXPECT_EQ(m.header().session(), "t1");
    EXPECT_EQ(m.header().seq(), static_cast<uint64_t>(i));
    EXPECT_EQ(m.header().tick(), static_cast<uint64_t>(10 + i));
    EXPECT_DOUBLE_EQ(m.head().position().x(), 0.5 * i);
    EXPECT_EQ(m.source(), hrc::v2::INPUT_SOURCE_SCRIPTED);
  }
  EXPECT_EQ(b_->stats().total_decode_errors(), 0u);
}

TEST_F(TwoPeers, ReplayAnswersWhatWasSentAfterTheSeqAskedAsLongAsItIsHeld) {
  // docs/ARCHITECTURE.md, "Lost messages": a Python receiver asks ik_cpp for what it lacks
  auto& out = a_->publisher(a_->keys().robot_state("r1"));
  a_->begin_batch();  // batched or not, every message is held for a replay
  for (uint64_t k = 0; k < 5; ++k) {
    hrc::v2::RobotState s;
    out.put(s, k, 0.0);
  }
  a_->flush_batches();
  a_->serve_replay();
  const auto ask = [&](const std::string& key, uint64_t after) {
    hrc::v2::ReplayRequest req;
    req.set_key(key);
    req.set_after_seq(after);
    std::vector<uint64_t> seqs;
    for (const auto& batch : b_->get<hrc::v2::ExchangeBatch>(a_->keys().replay("alpha"), &req)) {
      for (const auto& item : batch.items()) {
        hrc::v2::RobotState s;
        EXPECT_TRUE(s.ParseFromString(item));
        seqs.push_back(s.header().seq());
      }
    }
    return seqs;
  };
  // (the link and the queryable come up a moment after the sessions open)
  ASSERT_TRUE(
      wait_until([&] { return !ask(out.key(), 2).empty(); }, std::chrono::milliseconds(20000)));
  EXPECT_EQ(ask(out.key(), 2), (std::vector<uint64_t>{3, 4, 5}));
  EXPECT_TRUE(ask(out.key(), 5).empty());
  EXPECT_TRUE(ask(a_->keys().robot_state("r2"), 0).empty());  // a key it never published on
  EXPECT_EQ(out.sent_after(0).size(), 5u);
  EXPECT_TRUE(out.sent_after(9).empty());
}

TEST_F(TwoPeers, GarbageIsCountedPerKeyAndNeverDelivered) {
  Received got;
  const std::string key = b_->keys().human_state();
  b_->subscribe<hrc::v2::HumanState>(key, [&](const std::string& k, const hrc::v2::HumanState& m) {
    const std::lock_guard<std::mutex> lock(got.mutex);
    got.msgs.emplace_back(k, m);
  });
  auto& pub = a_->publisher(key);
  ASSERT_TRUE(wait_until([&] { return pub.has_subscribers(); }));
  // 0xff... is an invalid tag/varint: no protobuf parser accepts it.
  pub.put_raw(std::string(8, '\xff'));
  pub.put_raw(std::string("\x0a\x05\x0a", 3));  // truncated length-delimited header
  // Decodes, but belongs to another session: malformed too.
  hrc::v2::HumanState foreign;
  foreign.mutable_header()->set_session("other");
  pub.put_raw(foreign.SerializeAsString());
  // Then a good one, proving the subscriber keeps working.
  hrc::v2::HumanState good;
  good.set_source(hrc::v2::INPUT_SOURCE_VR);
  pub.put(good, 1, 0.01);
  ASSERT_TRUE(wait_until([&] { return got.size() == 1; }));
  EXPECT_EQ(b_->stats().decode_errors(key), 3u);
  EXPECT_EQ(b_->stats().total_decode_errors(), 3u);
  const std::lock_guard<std::mutex> lock(got.mutex);
  EXPECT_EQ(got.msgs[0].second.source(), hrc::v2::INPUT_SOURCE_VR);
}

TEST_F(TwoPeers, HandlerExceptionsStayInsideTheService) {
  std::atomic<int> calls{0};
  const std::string key = b_->keys().task_events();
  b_->subscribe<hrc::v2::TaskEvent>(key, [&](const std::string&, const hrc::v2::TaskEvent&) {
    ++calls;
    throw std::runtime_error("handler bug");
  });
  auto& pub = a_->publisher(key);
  ASSERT_TRUE(wait_until([&] { return pub.has_subscribers(); }));
  hrc::v2::TaskEvent e;
  pub.put(e, 1, 0.0);
  pub.put(e, 2, 0.0);
  ASSERT_TRUE(wait_until([&] { return calls == 2; }));
}

TEST_F(TwoPeers, LivelinessTokensAppearAndDisappear) {
  std::mutex m;
  std::vector<std::pair<std::string, bool>> events;
  b_->watch_liveliness([&](const std::string& service, bool alive) {
    const std::lock_guard<std::mutex> lock(m);
    events.emplace_back(service, alive);
  });
  a_->declare_token();
  const auto seen = [&](const std::string& s, bool alive) {
    const std::lock_guard<std::mutex> lock(m);
    for (const auto& e : events) {
      if (e.first == s && e.second == alive) return true;
    }
    return false;
  };
  ASSERT_TRUE(wait_until([&] { return seen("alpha", true); }));
  a_.reset();  // session closes: the token goes away
  ASSERT_TRUE(wait_until([&] { return seen("alpha", false); }));
}

TEST_F(TwoPeers, StatsQueryableAndTypedQueryable) {
  b_->subscribe<hrc::v2::HumanState>(b_->keys().human_state(),
                                     [](const std::string&, const hrc::v2::HumanState&) {});
  b_->stats().count_error("hrc/t1/human/state");
  b_->stats().tick(41);
  b_->stats().tick(42);
  b_->serve_stats();
  b_->queryable<hrc::v2::ReachRequest, hrc::v2::ReachReply>(
      b_->keys().robot_reach(), [](const hrc::v2::ReachRequest& req) {
        hrc::v2::ReachReply rep;
        for (const auto& item : req.items()) {
          auto* r = rep.add_results();
          r->set_id(item.id());
          r->set_reachable(item.target().z() > 0);
        }
        return rep;
      });
  std::vector<hrc::v2::ServiceStats> stats;
  ASSERT_TRUE(wait_until([&] {
    stats = a_->get<hrc::v2::ServiceStats>(a_->keys().stats("beta"), nullptr,
                                           std::chrono::milliseconds(500));
    return !stats.empty();
  }));
  EXPECT_EQ(stats[0].service(), "beta");
  ASSERT_EQ(stats[0].subscribed_size(), 1);
  EXPECT_EQ(stats[0].subscribed(0), "hrc/t1/human/state");
  EXPECT_EQ(stats[0].decode_errors().at("hrc/t1/human/state"), 1u);
  EXPECT_EQ(stats[0].ticks_seen(), 2u);
  EXPECT_EQ(stats[0].last_tick(), 42u);

  hrc::v2::ReachRequest req;
  auto* item = req.add_items();
  item->set_id("p1");
  item->mutable_target()->set_z(0.3);
  const auto replies = a_->get<hrc::v2::ReachReply>(a_->keys().robot_reach(), &req);
  ASSERT_EQ(replies.size(), 1u);
  ASSERT_EQ(replies[0].results_size(), 1);
  EXPECT_EQ(replies[0].results(0).id(), "p1");
  EXPECT_TRUE(replies[0].results(0).reachable());

  // A request that does not decode gets an error reply and is counted on the queryable's key.
  const auto raw = a_->session().get(a_->keys().robot_reach(), std::string(8, '\xff'));
  ASSERT_EQ(raw.size(), 1u);
  EXPECT_TRUE(raw[0].is_error);
  EXPECT_EQ(b_->stats().decode_errors(b_->keys().robot_reach()), 1u);
}

TEST_F(TwoPeers, NoCallbackAfterUndeclare) {
  std::atomic<int> calls{0};
  const std::string key = b_->keys().bench("undeclare");
  auto sub = std::make_unique<hrc::Subscriber>(
      b_->session().declare_subscriber(key, [&](const hrc::SampleView&) { ++calls; }));
  auto& pub = a_->publisher(key);
  ASSERT_TRUE(wait_until([&] { return pub.has_subscribers(); }));
  pub.put_raw("x");
  ASSERT_TRUE(wait_until([&] { return calls == 1; }));
  sub.reset();
  const int after = calls;
  for (int i = 0; i < 20; ++i) pub.put_raw("y");
  // The publisher may still believe a subscriber exists for a moment; either way nothing arrives.
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(calls, after);
}

TEST(Intersects, KeyExpressions) {
  EXPECT_TRUE(hrc::keyexpr_intersects("hrc/s/robot/*/command", "hrc/s/robot/r1/command"));
  EXPECT_FALSE(hrc::keyexpr_intersects("hrc/s/robot/*/command", "hrc/s/robot/r1/state"));
  EXPECT_THROW(hrc::keyexpr_intersects("hrc//x", "hrc/x"), hrc::BusError);
}

}  // namespace

namespace {

// docs/ARCHITECTURE.md, "Batches": what one exchange publishes on a key goes in one put
// ("<sender>+batch"); the receiver hands on each message with its own tick and seq.
TEST_F(TwoPeers, AnExchangeGoesOutInOnePutAndArrivesMessageByMessage) {
  Received got;
  std::mutex puts_mutex;
  std::vector<std::string> puts;
  b_->subscribe<hrc::v2::HumanState>(b_->keys().human_state(),
                                     [&](const std::string& k, const hrc::v2::HumanState& m) {
                                       const std::lock_guard<std::mutex> lock(got.mutex);
                                       got.msgs.emplace_back(k, m);
                                     });
  hrc::Subscriber raw =
      b_->session().declare_subscriber(a_->keys().human_state(), [&](const hrc::SampleView& s) {
        const std::lock_guard<std::mutex> lock(puts_mutex);
        puts.emplace_back(s.attachment);
      });
  auto& pub = a_->publisher(a_->keys().human_state());
  ASSERT_TRUE(wait_until([&] { return pub.has_subscribers(); }));
  a_->begin_batch();
  for (int i = 0; i < 4; ++i) {
    hrc::v2::HumanState h;
    h.set_left_grip(0.25 * i);
    pub.put(h, static_cast<uint64_t>(20 + i), 0.0);
  }
  {
    const std::lock_guard<std::mutex> lock(puts_mutex);
    EXPECT_TRUE(puts.empty());  // held back until the flush
  }
  a_->flush_batches();
  ASSERT_TRUE(wait_until([&] { return got.size() == 4; }));
  {
    const std::lock_guard<std::mutex> lock(puts_mutex);
    ASSERT_EQ(puts.size(), 1u);
    EXPECT_EQ(puts[0], "alpha+batch");
  }
  const std::lock_guard<std::mutex> lock(got.mutex);
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(got.msgs[i].second.header().tick(), 20 + i);
    EXPECT_EQ(got.msgs[i].second.header().seq(), i + 1);
    EXPECT_DOUBLE_EQ(got.msgs[i].second.left_grip(), 0.25 * static_cast<double>(i));
  }
}

// The low-latency transport cannot fragment: a message above its limit is refused at the sender
// (the receiver's link would break), and an exchange of many messages goes out in as many
// batches as the limit needs. On a Unix socket (a fresh low-latency TCP link may lose a first
// large message).
TEST(SizeLimit, RefusedAboveTheLowLatencyLimitAndBigExchangesSplit) {
  const std::string ep =
      "unixsock-stream//tmp/hrc-size-" + std::to_string(hrc::test::free_port()) + ".sock";
  hrc::BusConfig ca;
  ca.listen = {ep};
  ca.lowlatency = true;
  hrc::BusConfig cb;
  cb.listen = {};
  cb.connect = {ep};
  cb.lowlatency = true;
  hrc::Bus a(ca, "t3", "alpha");
  hrc::Bus b(cb, "t3", "beta");
  EXPECT_EQ(a.max_message_bytes(), hrc::kMaxLowlatencyBytes);
  Received got;
  b.subscribe<hrc::v2::HumanState>(b.keys().human_state(),
                                   [&](const std::string& k, const hrc::v2::HumanState& m) {
                                     const std::lock_guard<std::mutex> lock(got.mutex);
                                     got.msgs.emplace_back(k, m);
                                   });
  std::atomic<int> batches{0};
  hrc::Subscriber raw =
      b.session().declare_subscriber(a.keys().human_state(), [&](const hrc::SampleView& s) {
        if (s.attachment == "alpha+batch") ++batches;
      });
  auto& pub = a.publisher(a.keys().human_state());
  ASSERT_TRUE(wait_until([&] { return pub.has_subscribers(); }));
  try {
    pub.put_raw(std::string(70 * 1024, 'x'));
    FAIL() << "a 70 KiB put was sent";
  } catch (const hrc::BusError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("71680-byte message on hrc/t3/human/state"), std::string::npos) << what;
    EXPECT_NE(what.find("low-latency"), std::string::npos) << what;
  }
  constexpr std::size_t kN = 3000;  // about 50 bytes each on the wire: some 150 KB in one exchange
  a.begin_batch();
  for (std::size_t i = 0; i < kN; ++i) {
    hrc::v2::HumanState h;
    h.set_left_grip(0.5);
    pub.put(h, i, 0.0);
  }
  a.flush_batches();
  ASSERT_TRUE(wait_until([&] { return got.size() == kN; }, std::chrono::milliseconds(20000)))
      << got.size();
  EXPECT_GE(batches.load(), 3);
  const std::lock_guard<std::mutex> lock(got.mutex);
  for (std::size_t i = 0; i < kN; ++i) EXPECT_EQ(got.msgs[i].second.header().seq(), i + 1);
}

}  // namespace
