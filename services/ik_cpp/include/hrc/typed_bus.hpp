// Typed publish/subscribe of wire-contract messages over one zenoh session (twin of Python
// hrc.bus.bus.Bus). Every put carries the sender's service name as the zenoh attachment and gets
// its Header filled (session, tick, sim_time, sender, seq per key starting at 1). A payload that
// does not decode (or carries another session's header, or fails a validator) is counted per key
// in InputStats, logged with key and sender, and never reaches service code.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "hrc.pb.h"
#include "hrc/bus.hpp"
#include "hrc/keys.hpp"
#include "hrc/log.hpp"

namespace hrc {

/// True for message types with a `Header header = 1` field.
template <class M, class = void>
struct HasHeader : std::false_type {};
template <class M>
struct HasHeader<M, std::void_t<decltype(std::declval<M&>().mutable_header())>> : std::true_type {};

/// Thread-safe counters of what a service received (source of ServiceStats).
class InputStats {
 public:
  /// Counts one malformed payload on `key`; returns the new count for that key.
  uint64_t count_error(const std::string& key);
  uint64_t decode_errors(const std::string& key) const;
  uint64_t total_decode_errors() const;
  void add_subscribed(const std::string& key_expr);
  void tick(uint64_t k);
  uint64_t ticks_seen() const;
  uint64_t last_tick() const;
  v2::ServiceStats to_proto(const std::string& service) const;

 private:
  mutable std::mutex mutex_;
  std::map<std::string, uint64_t> decode_errors_;
  std::vector<std::string> subscribed_;
  uint64_t ticks_seen_ = 0;
  uint64_t last_tick_ = 0;
};

class Bus;

/// Publishes wire messages on one key; one per (Bus, key), so seq is per (sender, key).
class TypedPublisher {
 public:
  TypedPublisher(const Bus& bus, Publisher publisher);

  /// Fills msg's header (if the type has one), serialises and puts it. Returns the seq used
  /// (0 for header-less types). Throws BusError if zenoh refuses the put.
  template <class M>
  uint64_t put(M& msg, uint64_t tick = 0, double sim_time = 0.0) {
    const std::lock_guard<std::mutex> lock(mutex_);
    uint64_t seq = 0;
    if constexpr (HasHeader<M>::value) {
      seq = ++seq_;
      stamp(*msg.mutable_header(), tick, sim_time, seq);
    }
    std::string bytes = msg.SerializeAsString();
    put_bytes_locked(bytes);
    if (seq > 0) remember_locked(seq, std::move(bytes));
    return seq;
  }

  /// Puts bytes as they are (for probes and garbage tests); does not advance seq.
  void put_raw(std::string_view payload);
  /// Puts what was held back while the bus batched: one message as it is, several as
  /// ExchangeBatch messages (attachment "<sender>+batch"), as few as the size limit allows.
  void flush();
  uint64_t seq() const;
  /// The messages after `seq` it still holds, oldest first; none unless it holds seq + 1 (a
  /// replay with a hole would not help).
  std::vector<std::string> sent_after(uint64_t seq) const;
  const std::string& key() const { return publisher_.key(); }
  bool has_subscribers() const { return publisher_.has_subscribers(); }

 private:
  void stamp(v2::Header& h, uint64_t tick, double sim_time, uint64_t seq) const;
  void put_bytes_locked(const std::string& bytes);
  void remember_locked(uint64_t seq, std::string bytes);
  /// Throws BusError, sending nothing, for a message above the transport's limit.
  void check_size(std::size_t size) const;

  const Bus& bus_;
  Publisher publisher_;
  mutable std::mutex mutex_;
  uint64_t seq_ = 0;
  std::vector<std::string> held_;  // serialized messages held back while the bus batches
  std::deque<std::pair<uint64_t, std::string>> recent_;  // (seq, message), for replays
};

// What a publisher holds of what it sent, to answer a replay (as Python's REPLAY_KEEP).
inline constexpr std::size_t kReplayKeep = 2048;

/// The attachment suffix that marks an ExchangeBatch (after the sender's name).
inline constexpr std::string_view kBatchSuffix = "+batch";
// Zenoh's low-latency transport does not fragment: a message (with its key, attachment and
// framing) must fit one 65,535-byte batch, or the link it goes out on breaks. The standard
// transport fragments; a cap still keeps one put from flooding every receiver. (As in Python.)
inline constexpr std::size_t kMaxLowlatencyBytes = 63 * 1024;
inline constexpr std::size_t kMaxStandardBytes = 16 * 1024 * 1024;

/// One service's view of the bus. Not movable: callbacks hold a pointer to it. Everything declared
/// through it is undeclared when it is destroyed (or close() is called), before the session closes.
class Bus {
 public:
  template <class M>
  using Handler = std::function<void(const std::string& key, const M& msg)>;
  /// Returns "" if the message is acceptable, else the problem (counted as malformed).
  template <class M>
  using Validator = std::function<std::string(const M& msg)>;

  /// Opens a session. Throws std::invalid_argument for a bad session id / sender, BusError if
  /// zenoh cannot open.
  Bus(const BusConfig& config, std::string session_id, std::string sender);
  Bus(Session session, std::string session_id, std::string sender);
  Bus(const Bus&) = delete;
  Bus& operator=(const Bus&) = delete;
  ~Bus();

  const Keys& keys() const { return keys_; }
  const std::string& sender() const { return sender_; }
  InputStats& stats() { return stats_; }
  const InputStats& stats() const { return stats_; }
  const Session& session() const { return session_; }

  /// The publisher for `key` (created on first use with `options`; later calls return it).
  TypedPublisher& publisher(const std::string& key, PublisherOptions options = {});
  /// The last seq of every key this service has published on (for TickAck.published).
  std::vector<v2::PublishedMark> published_marks() const;
  /// The marks that moved since the previous call, keys other than `exclude` (tick-protocol
  /// messages list only these; receivers keep the highest seq per key and sender).
  std::vector<v2::PublishedMark> new_marks(const std::string& exclude = "");

  /// From now on every put is held back (per publisher) until flush_batches(): what one
  /// exchange publishes on a key goes out in one put (docs/ARCHITECTURE.md, "Batches").
  void begin_batch() { batching_.store(true); }
  /// Ends batching and puts everything held back.
  void flush_batches();
  bool batching() const { return batching_.load(); }
  /// The largest message a put may send (kMaxLowlatencyBytes on the low-latency transport).
  std::size_t max_message_bytes() const { return max_message_bytes_; }
  bool lowlatency() const { return max_message_bytes_ == kMaxLowlatencyBytes; }

  /// Calls handler(key, msg) on a zenoh thread for each well-formed message on `key_expr`.
  template <class M>
  void subscribe(const std::string& key_expr, Handler<M> handler, Validator<M> validate = {}) {
    stats_.add_subscribed(key_expr);
    auto on_sample = [this, handler = std::move(handler),
                      validate = std::move(validate)](const SampleView& s) {
      const auto one = [&](std::string_view payload) {
        M msg;
        std::string problem = check_payload(msg, payload);
        if (problem.empty() && validate) problem = validate(msg);
        if (!problem.empty()) {
          malformed(s, problem);
          return;
        }
        handler(std::string(s.key), msg);
      };
      if (s.payload.size() > kMaxStandardBytes) {
        // no service sends this (a put refuses it): refused unread, and counted
        malformed(s, std::to_string(s.payload.size()) + " bytes, above the " +
                         std::to_string(kMaxStandardBytes) + "-byte limit");
        return;
      }
      if (!is_batch(s.attachment)) {
        one(s.payload);
        return;
      }
      v2::ExchangeBatch batch;
      if (!parse(batch, s.payload)) {
        malformed(s, "does not decode as ExchangeBatch");
        return;
      }
      for (const std::string& item : batch.items()) one(item);
    };
    add_subscriber(session_.declare_subscriber(key_expr, std::move(on_sample)));
  }

  /// Announces alive/<service> (default: this sender). Declare it after all subscriptions.
  void declare_token(const std::string& service = "");
  /// on_change(service, alive) for every alive/* token of this session, past and future.
  void watch_liveliness(std::function<void(const std::string& service, bool alive)> on_change);

  /// Answers queries on `key` with handler(request); a request that does not decode gets an error
  /// reply and is counted; a handler exception becomes an error reply.
  template <class Req, class Rep>
  void queryable(const std::string& key, std::function<Rep(const Req&)> handler) {
    auto on_query = [this, key, handler = std::move(handler)](const QueryView& q) -> QueryReply {
      Req req;
      if (!parse(req, q.payload)) {
        const uint64_t n = stats_.count_error(key);
        log::warning("malformed query #" + std::to_string(n) + " on " + key +
                     ": does not decode as " + Req::descriptor()->name());
        return QueryReply::error("request does not decode as " + Req::descriptor()->name());
      }
      try {
        return QueryReply::ok(handler(req).SerializeAsString());
      } catch (const std::exception& e) {
        log::error("query handler for " + key + " failed: " + e.what());
        return QueryReply::error(std::string("handler failed: ") + e.what());
      }
    };
    add_queryable(session_.declare_queryable(key, std::move(on_query)));
  }

  /// stats/<sender>: ServiceStats (subscribed keys, decode errors per key, ticks).
  void serve_stats();
  /// replay/<sender>: ReplayRequest (key, after_seq) -> ExchangeBatch of what this service
  /// published on the key after that seq and still holds (docs/ARCHITECTURE.md, "Lost
  /// messages").
  void serve_replay();

  /// Queries `key`; returns every reply that decodes as R (error replies and undecodable replies
  /// are logged and skipped).
  template <class R>
  std::vector<R> get(const std::string& key, const google::protobuf::Message* request = nullptr,
                     std::chrono::milliseconds timeout = std::chrono::milliseconds(2000)) const {
    const std::string payload = request != nullptr ? request->SerializeAsString() : std::string();
    std::vector<R> out;
    for (const Reply& r : session_.get(key, payload, sender_, timeout)) {
      if (r.is_error) {
        log::warning("query " + key + " answered with an error: " + r.payload);
        continue;
      }
      R msg;
      if (!parse(msg, r.payload)) {
        log::warning("reply on " + r.key + " does not decode as " + R::descriptor()->name());
        continue;
      }
      out.push_back(std::move(msg));
    }
    return out;
  }

  /// Undeclares everything and closes the session (idempotent).
  void close() noexcept;

  /// Parses `bytes` into msg; false if it is not a valid encoding.
  static bool parse(google::protobuf::Message& msg, std::string_view bytes);

 private:
  template <class M>
  std::string check_payload(M& msg, std::string_view payload) const {
    if (!parse(msg, payload)) return "does not decode as " + M::descriptor()->name();
    if constexpr (HasHeader<M>::value) {
      if (msg.header().session() != keys_.session()) {
        return "header session '" + msg.header().session() + "' is not '" + keys_.session() + "'";
      }
    }
    return {};
  }
  static bool is_batch(std::string_view attachment) {
    return attachment.size() > kBatchSuffix.size() &&
           attachment.substr(attachment.size() - kBatchSuffix.size()) == kBatchSuffix;
  }
  void malformed(const SampleView& s, const std::string& problem);
  void add_subscriber(Subscriber s);
  void add_queryable(Queryable q);

  Keys keys_;
  std::string sender_;
  std::size_t max_message_bytes_ = kMaxStandardBytes;
  InputStats stats_;
  Session session_;  // declared before every entity below, so it is destroyed after them
  mutable std::mutex mutex_;
  std::map<std::string, std::unique_ptr<TypedPublisher>> publishers_;
  std::map<std::string, uint64_t> reported_;  // seq last listed by new_marks, per key
  std::vector<Subscriber> subscribers_;
  std::vector<Queryable> queryables_;
  std::vector<LivelinessToken> tokens_;
  std::atomic<bool> batching_{false};
};

}  // namespace hrc
