// Deterministic input delivery for the tick protocol (twin of Python hrc.bus.inbox.Inbox).
// Messages from different zenoh sessions arrive in no defined order relative to each other, so a
// service never handles a message when it arrives: the Inbox keeps it until the service asks for
// "everything up to tick k", then hands it over sorted by (tick, subscription order, key,
// sender, seq).
#pragma once

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "hrc/typed_bus.hpp"

namespace hrc {

class Inbox {
 public:
  explicit Inbox(Bus& bus) : bus_(bus) {}
  Inbox(const Inbox&) = delete;
  Inbox& operator=(const Inbox&) = delete;

  /// Subscribes to `key_expr` with type M (must have a Header); handler(key, msg) runs from
  /// deliver(), on the thread that calls it.
  template <class M>
  void add(const std::string& key_expr, Bus::Handler<M> handler, Bus::Validator<M> validate = {}) {
    static_assert(HasHeader<M>::value, "Inbox inputs need a Header (tick, sender, seq)");
    std::size_t index = 0;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      index = handlers_.size();
      handlers_.push_back([handler = std::move(handler)](const std::string& key,
                                                         const google::protobuf::Message& m) {
        handler(key, static_cast<const M&>(m));
      });
      exprs_.push_back(key_expr);
    }
    bus_.subscribe<M>(
        key_expr,
        [this, index](const std::string& key, const M& msg) {
          const v2::Header& h = msg.header();
          push(Pending{index, key, h.sender(), h.seq(), h.tick(), std::make_shared<const M>(msg)});
        },
        std::move(validate));
  }

  /// The marks on keys we subscribe to whose messages have not all arrived yet.
  std::vector<v2::PublishedMark> missing(const std::vector<v2::PublishedMark>& marks);
  /// Waits until every mark (on our keys) is satisfied; returns what is still missing at timeout.
  std::vector<v2::PublishedMark> wait_for(const std::vector<v2::PublishedMark>& marks,
                                          double timeout_s);
  /// Hands every message of ticks < upto_tick to its handler (plus the messages of `master` of
  /// tick upto_tick when master is not empty), in deterministic order. Returns the count.
  std::size_t deliver(uint64_t upto_tick, const std::string& master = "");
  /// Every message of ticks <= tick.
  std::size_t deliver_through(uint64_t tick) { return deliver(tick + 1); }
  /// Messages received but not yet delivered.
  std::size_t pending() const;
  /// Messages dropped because one with their key, sender and seq had come already.
  std::size_t duplicates() const;

 private:
  struct Pending {
    std::size_t index;
    std::string key;
    std::string sender;
    uint64_t seq;
    uint64_t tick;
    std::shared_ptr<const google::protobuf::Message> msg;
  };
  using ErasedHandler = std::function<void(const std::string&, const google::protobuf::Message&)>;

  void push(Pending p);
  bool subscribed_locked(const std::string& key);
  std::vector<v2::PublishedMark> missing_locked(const std::vector<v2::PublishedMark>& wanted) const;

  Bus& bus_;
  mutable std::mutex mutex_;
  std::condition_variable cond_;
  std::vector<ErasedHandler> handlers_;
  std::vector<std::string> exprs_;
  std::vector<Pending> pending_;
  // (key, sender) -> the last seq with none missing before it: a later message that comes
  // first does not hide a lost one (docs/ARCHITECTURE.md, "Lost messages")
  std::map<std::pair<std::string, std::string>, uint64_t> received_;
  std::map<std::pair<std::string, std::string>, std::set<uint64_t>> ahead_;  // seqs past a hole
  std::size_t duplicates_ = 0;
  std::map<std::string, bool> matches_;  // key -> subscribed?
};

}  // namespace hrc
