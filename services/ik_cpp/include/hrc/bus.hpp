// RAII C++ layer over the hrc_zenoh_ffi C ABI (zenoh_ffi.h): sessions, publishers, subscribers,
// liveliness tokens, queryables and get. Bytes only; the typed layer is typed_bus.hpp.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "hrc/zenoh_ffi.h"

namespace hrc {

/// Any failure reported by zenoh (opening, declaring, publishing).
class BusError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Where a service meets the others (twin of Python hrc.bus.config.BusConfig).
/// Defaults: peer on loopback, multicast scouting off, gossip on, explicit endpoints.
struct BusConfig {
  std::string mode = "peer";  // peer | client | router
  std::vector<std::string> connect;
  std::vector<std::string> listen{"tcp/127.0.0.1:0"};
  bool multicast_scouting = false;
  /// Zenoh's low-latency transport (puts write on the caller's thread; no QoS; messages up to
  /// 64 KiB). A link uses it only if both ends ask for it.
  bool lowlatency = false;
  std::string config_file;  // optional zenoh JSON5 file applied first (insertions override it)

  /// (path, JSON5 value) pairs applied on top of the zenoh defaults / config_file.
  std::vector<std::pair<std::string, std::string>> insertions() const;
  /// The same settings as one JSON5 document (without config_file).
  std::string to_json5() const;
  /// Throws std::invalid_argument naming the bad field.
  void validate() const;
};

/// JSON string literal for `s` (quotes and escapes), valid JSON5.
std::string json_quote(std::string_view s);

/// A received sample; the views are valid only during the callback.
struct SampleView {
  std::string_view key;
  std::string_view payload;
  std::string_view attachment;
};

/// A query being answered; valid only during the queryable callback.
struct QueryView {
  std::string_view key;
  std::string_view payload;
  std::string_view attachment;
};

/// What a queryable handler returns: a reply payload, or an error reply.
struct QueryReply {
  std::string payload;
  bool is_error = false;
  static QueryReply ok(std::string p) { return {std::move(p), false}; }
  static QueryReply error(std::string p) { return {std::move(p), true}; }
};

/// One reply of Session::get.
struct Reply {
  std::string key;
  std::string payload;
  std::string attachment;
  bool is_error = false;
};

struct PublisherOptions {
  bool congestion_block = true;  // reliable: block rather than drop when queues are full
  // false: Zenoh batches it with what follows; the next express put (the ack) sends both at
  // once (docs/ARCHITECTURE.md). Acks and run control are express.
  bool express = false;
};

/// True if the key expressions intersect; throws BusError if either is invalid.
bool keyexpr_intersects(const std::string& a, const std::string& b);

class Publisher {
 public:
  Publisher() = default;
  Publisher(Publisher&&) noexcept;
  Publisher& operator=(Publisher&&) noexcept;
  Publisher(const Publisher&) = delete;
  Publisher& operator=(const Publisher&) = delete;
  ~Publisher();

  /// Throws BusError on failure.
  void put(std::string_view payload, std::string_view attachment) const;
  /// True if some subscriber currently matches this publisher's key.
  bool has_subscribers() const;
  const std::string& key() const { return key_; }
  explicit operator bool() const { return handle_ != nullptr; }

 private:
  friend class Session;
  Publisher(HrczPublisher* h, std::string key) : handle_(h), key_(std::move(key)) {}
  HrczPublisher* handle_ = nullptr;
  std::string key_;
};

/// Data or liveliness subscriber. Destruction undeclares; afterwards the callback never runs.
/// Never destroy a Subscriber from inside its own callback.
class Subscriber {
 public:
  Subscriber() = default;
  Subscriber(Subscriber&&) noexcept;
  Subscriber& operator=(Subscriber&&) noexcept;
  Subscriber(const Subscriber&) = delete;
  Subscriber& operator=(const Subscriber&) = delete;
  ~Subscriber();
  const std::string& key_expr() const { return key_expr_; }
  explicit operator bool() const { return handle_ != nullptr; }

 private:
  friend class Session;
  struct Callbacks;  // owns the std::function the C callback points to (stable address)
  Subscriber(HrczSubscriber* h, std::unique_ptr<Callbacks> cb, std::string key_expr);
  void reset() noexcept;
  HrczSubscriber* handle_ = nullptr;
  std::unique_ptr<Callbacks> callbacks_;
  std::string key_expr_;
};

class LivelinessToken {
 public:
  LivelinessToken() = default;
  LivelinessToken(LivelinessToken&&) noexcept;
  LivelinessToken& operator=(LivelinessToken&&) noexcept;
  LivelinessToken(const LivelinessToken&) = delete;
  LivelinessToken& operator=(const LivelinessToken&) = delete;
  ~LivelinessToken();
  const std::string& key() const { return key_; }
  explicit operator bool() const { return handle_ != nullptr; }

 private:
  friend class Session;
  LivelinessToken(HrczToken* h, std::string key) : handle_(h), key_(std::move(key)) {}
  HrczToken* handle_ = nullptr;
  std::string key_;
};

class Queryable {
 public:
  using Handler = std::function<QueryReply(const QueryView&)>;
  Queryable() = default;
  Queryable(Queryable&&) noexcept;
  Queryable& operator=(Queryable&&) noexcept;
  Queryable(const Queryable&) = delete;
  Queryable& operator=(const Queryable&) = delete;
  ~Queryable();
  const std::string& key() const { return key_; }
  explicit operator bool() const { return handle_ != nullptr; }

 private:
  friend class Session;
  Queryable(HrczQueryable* h, std::unique_ptr<Handler> handler, std::string key);
  void reset() noexcept;
  HrczQueryable* handle_ = nullptr;
  std::unique_ptr<Handler> handler_;
  std::string key_;
};

/// An open zenoh session (move-only). Entities declared on it must be destroyed before it;
/// declare them after the Session object in the same scope, or hold them in a class declared
/// after it, so C++ destruction order does that.
class Session {
 public:
  using SampleHandler = std::function<void(const SampleView&)>;
  /// (key of the token, alive) — alive = false when the token was dropped.
  using LivelinessHandler = std::function<void(std::string_view key, bool alive)>;

  /// Opens with BusConfig (config_file first, then the insertions). Throws BusError.
  static Session open(const BusConfig& config);
  /// Opens from a complete JSON5 document. Throws BusError.
  static Session open_json5(const std::string& json5);

  Session() = default;
  Session(Session&&) noexcept;
  Session& operator=(Session&&) noexcept;
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;
  ~Session();

  Publisher declare_publisher(const std::string& key, PublisherOptions options = {}) const;
  /// Handler runs on a zenoh thread, never concurrently with itself; exceptions are caught and
  /// logged to stderr.
  Subscriber declare_subscriber(const std::string& key_expr, SampleHandler handler) const;
  Subscriber declare_liveliness_subscriber(const std::string& key_expr, LivelinessHandler handler,
                                           bool history = true) const;
  LivelinessToken declare_token(const std::string& key) const;
  Queryable declare_queryable(const std::string& key, Queryable::Handler handler) const;
  /// Blocks until all replies are in or `timeout` passed.
  std::vector<Reply> get(const std::string& selector, std::string_view payload = {},
                         std::string_view attachment = {},
                         std::chrono::milliseconds timeout = std::chrono::milliseconds(2000)) const;

  explicit operator bool() const { return handle_ != nullptr; }
  void close() noexcept;

 private:
  explicit Session(HrczSession* h) : handle_(h) {}
  HrczSession* handle_ = nullptr;
};

}  // namespace hrc
