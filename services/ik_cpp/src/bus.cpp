#include "hrc/bus.hpp"

#include <array>
#include <cstdio>
#include <exception>
#include <stdexcept>

#include "hrc/log.hpp"

namespace hrc {
namespace {

constexpr std::size_t kErrCap = 1024;

// A client that starts before the router listens tries again after 10, 20, 40, then every
// 50 ms (Python's hrc.bus.config.CONNECT_RETRY): a failed local connect costs microseconds, a
// late retry costs start-up time.
const std::string kConnectRetry =
    "{ period_init_ms: 10, period_max_ms: 50, period_increase_factor: 2 }";
using ErrBuf = std::array<char, kErrCap>;

std::string err_text(const ErrBuf& buf) {
  return buf[0] != '\0' ? std::string(buf.data()) : std::string("unknown zenoh error");
}

const uint8_t* u8(std::string_view s) { return reinterpret_cast<const uint8_t*>(s.data()); }

std::string_view view(const char* p, std::size_t n) {
  return n == 0 ? std::string_view() : std::string_view(p, n);
}
std::string_view view(const uint8_t* p, std::size_t n) {
  return view(reinterpret_cast<const char*>(p), n);
}

// Exceptions must never unwind into Rust: every callback trampoline ends here on failure.
void report_callback_failure(const char* what, std::string_view key) noexcept {
  try {
    std::string msg = std::string("callback for '") + std::string(key) + "' failed";
    try {
      throw;
    } catch (const std::exception& e) {
      msg += std::string(": ") + e.what();
    } catch (...) {
      msg += ": unknown exception";
    }
    log::error(std::string(what) + " " + msg);
  } catch (...) {
    std::fputs("hrc: callback failed and logging failed too\n", stderr);
  }
}

}  // namespace

// ------------------------------------------------------------------ config

std::string json_quote(std::string_view s) {
  std::string out = "\"";
  for (const char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x",
                        static_cast<unsigned>(static_cast<unsigned char>(c)));
          out += buf;
        } else {
          out += c;
        }
    }
  }
  out += '"';
  return out;
}

namespace {
std::string json_list(const std::vector<std::string>& items) {
  std::string out = "[";
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (i > 0) out += ", ";
    out += json_quote(items[i]);
  }
  return out + "]";
}
}  // namespace

void BusConfig::validate() const {
  if (mode != "peer" && mode != "client" && mode != "router") {
    throw std::invalid_argument("invalid zenoh mode '" + mode + "': use peer, client or router");
  }
  for (const auto* list : {&connect, &listen}) {
    for (const auto& ep : *list) {
      // An endpoint is <protocol>/<address>, e.g. tcp/127.0.0.1:7447.
      const auto slash = ep.find('/');
      if (ep.empty() || slash == std::string::npos || slash == 0 || slash + 1 == ep.size()) {
        throw std::invalid_argument("invalid zenoh endpoint '" + ep +
                                    "': expected <protocol>/<address>, e.g. tcp/127.0.0.1:7447");
      }
    }
  }
  if (mode == "client" && connect.empty()) {
    throw std::invalid_argument("zenoh mode 'client' needs at least one --connect endpoint");
  }
}

std::vector<std::pair<std::string, std::string>> BusConfig::insertions() const {
  // Same keys and order as the Python BusConfig.to_zenoh(); lists are set only when given.
  std::vector<std::pair<std::string, std::string>> out;
  out.emplace_back("mode", json_quote(mode));
  out.emplace_back("scouting/multicast/enabled", multicast_scouting ? "true" : "false");
  out.emplace_back("scouting/gossip/enabled", "true");
  if (!connect.empty()) {
    out.emplace_back("connect/endpoints", json_list(connect));
    // Keep trying while the other end starts (a client otherwise fails at once).
    out.emplace_back("connect/timeout_ms", "60000");
    out.emplace_back("connect/retry", kConnectRetry);
  }
  if (!listen.empty()) out.emplace_back("listen/endpoints", json_list(listen));
  if (lowlatency) {
    out.emplace_back("transport/unicast/lowlatency", "true");
    out.emplace_back("transport/unicast/qos/enabled", "false");  // required by lowlatency
  }
  return out;
}

std::string BusConfig::to_json5() const {
  std::string out = "{\n  mode: " + json_quote(mode) + ",\n";
  out += "  scouting: { multicast: { enabled: ";
  out += multicast_scouting ? "true" : "false";
  out += " }, gossip: { enabled: true } },\n";
  if (!connect.empty()) {
    out += "  connect: { endpoints: " + json_list(connect) +
           ", timeout_ms: 60000, retry: " + kConnectRetry + " },\n";
  }
  if (!listen.empty()) out += "  listen: { endpoints: " + json_list(listen) + " },\n";
  if (lowlatency)
    out += "  transport: { unicast: { lowlatency: true, qos: { enabled: false } } },\n";
  out += "}\n";
  return out;
}

bool keyexpr_intersects(const std::string& a, const std::string& b) {
  ErrBuf err{};
  const int r = hrcz_keyexpr_intersects(a.c_str(), b.c_str(), err.data(), err.size());
  if (r < 0) throw BusError(err_text(err));
  return r == 1;
}

// ------------------------------------------------------------------ publisher

Publisher::Publisher(Publisher&& o) noexcept : handle_(o.handle_), key_(std::move(o.key_)) {
  o.handle_ = nullptr;
}

Publisher& Publisher::operator=(Publisher&& o) noexcept {
  if (this != &o) {
    hrcz_undeclare_publisher(handle_);
    handle_ = o.handle_;
    key_ = std::move(o.key_);
    o.handle_ = nullptr;
  }
  return *this;
}

Publisher::~Publisher() { hrcz_undeclare_publisher(handle_); }

void Publisher::put(std::string_view payload, std::string_view attachment) const {
  if (handle_ == nullptr) throw BusError("put on an empty Publisher");
  ErrBuf err{};
  if (hrcz_publisher_put(handle_, u8(payload), payload.size(), u8(attachment), attachment.size(),
                         err.data(), err.size()) != 0) {
    throw BusError(err_text(err));
  }
}

bool Publisher::has_subscribers() const {
  if (handle_ == nullptr) throw BusError("has_subscribers on an empty Publisher");
  ErrBuf err{};
  const int r = hrcz_publisher_has_subscribers(handle_, err.data(), err.size());
  if (r < 0) throw BusError(err_text(err));
  return r == 1;
}

// ------------------------------------------------------------------ subscriber

struct Subscriber::Callbacks {
  std::string key_expr;
  Session::SampleHandler on_sample;
  Session::LivelinessHandler on_liveliness;

  static void sample(void* ctx, const char* key, size_t key_len, const uint8_t* payload, size_t len,
                     const uint8_t* att, size_t att_len) noexcept {
    auto* self = static_cast<Callbacks*>(ctx);
    try {
      self->on_sample(SampleView{view(key, key_len), view(payload, len), view(att, att_len)});
    } catch (...) {
      report_callback_failure("subscriber", view(key, key_len));
    }
  }

  static void liveliness(void* ctx, const char* key, size_t key_len, int alive) noexcept {
    auto* self = static_cast<Callbacks*>(ctx);
    try {
      self->on_liveliness(view(key, key_len), alive != 0);
    } catch (...) {
      report_callback_failure("liveliness subscriber", view(key, key_len));
    }
  }
};

Subscriber::Subscriber(HrczSubscriber* h, std::unique_ptr<Callbacks> cb, std::string key_expr)
    : handle_(h), callbacks_(std::move(cb)), key_expr_(std::move(key_expr)) {}

Subscriber::Subscriber(Subscriber&& o) noexcept
    : handle_(o.handle_), callbacks_(std::move(o.callbacks_)), key_expr_(std::move(o.key_expr_)) {
  o.handle_ = nullptr;
}

Subscriber& Subscriber::operator=(Subscriber&& o) noexcept {
  if (this != &o) {
    reset();
    handle_ = o.handle_;
    callbacks_ = std::move(o.callbacks_);
    key_expr_ = std::move(o.key_expr_);
    o.handle_ = nullptr;
  }
  return *this;
}

void Subscriber::reset() noexcept {
  // Undeclare first: once it returns no callback runs, so the handler can be freed.
  hrcz_undeclare_subscriber(handle_);
  handle_ = nullptr;
  callbacks_.reset();
}

Subscriber::~Subscriber() { reset(); }

// ------------------------------------------------------------------ liveliness token

LivelinessToken::LivelinessToken(LivelinessToken&& o) noexcept
    : handle_(o.handle_), key_(std::move(o.key_)) {
  o.handle_ = nullptr;
}

LivelinessToken& LivelinessToken::operator=(LivelinessToken&& o) noexcept {
  if (this != &o) {
    hrcz_undeclare_token(handle_);
    handle_ = o.handle_;
    key_ = std::move(o.key_);
    o.handle_ = nullptr;
  }
  return *this;
}

LivelinessToken::~LivelinessToken() { hrcz_undeclare_token(handle_); }

// ------------------------------------------------------------------ queryable

namespace {
void query_trampoline(void* ctx, const HrczQuery* query, const char* key, size_t key_len,
                      const uint8_t* payload, size_t len, const uint8_t* att,
                      size_t att_len) noexcept {
  auto* handler = static_cast<Queryable::Handler*>(ctx);
  try {
    const QueryReply reply =
        (*handler)(QueryView{view(key, key_len), view(payload, len), view(att, att_len)});
    ErrBuf err{};
    const int rc = reply.is_error
                       ? hrcz_query_reply_err(query, u8(reply.payload), reply.payload.size(),
                                              err.data(), err.size())
                       : hrcz_query_reply(query, u8(reply.payload), reply.payload.size(), nullptr,
                                          0, err.data(), err.size());
    if (rc != 0)
      log::warning("reply to query on '" + std::string(view(key, key_len)) +
                   "' failed: " + err_text(err));
  } catch (...) {
    report_callback_failure("queryable", view(key, key_len));
  }
}
}  // namespace

Queryable::Queryable(HrczQueryable* h, std::unique_ptr<Handler> handler, std::string key)
    : handle_(h), handler_(std::move(handler)), key_(std::move(key)) {}

Queryable::Queryable(Queryable&& o) noexcept
    : handle_(o.handle_), handler_(std::move(o.handler_)), key_(std::move(o.key_)) {
  o.handle_ = nullptr;
}

Queryable& Queryable::operator=(Queryable&& o) noexcept {
  if (this != &o) {
    reset();
    handle_ = o.handle_;
    handler_ = std::move(o.handler_);
    key_ = std::move(o.key_);
    o.handle_ = nullptr;
  }
  return *this;
}

void Queryable::reset() noexcept {
  hrcz_undeclare_queryable(handle_);
  handle_ = nullptr;
  handler_.reset();
}

Queryable::~Queryable() { reset(); }

// ------------------------------------------------------------------ session

Session Session::open(const BusConfig& config) {
  try {
    config.validate();
  } catch (const std::invalid_argument& e) {
    throw BusError(e.what());
  }
  const auto pairs = config.insertions();
  std::vector<const char*> paths;
  std::vector<const char*> values;
  for (const auto& [p, v] : pairs) {
    paths.push_back(p.c_str());
    values.push_back(v.c_str());
  }
  ErrBuf err{};
  HrczSession* h = hrcz_open_ex(config.config_file.empty() ? nullptr : config.config_file.c_str(),
                                paths.data(), values.data(), pairs.size(), err.data(), err.size());
  if (h == nullptr) throw BusError(err_text(err));
  return Session(h);
}

Session Session::open_json5(const std::string& json5) {
  ErrBuf err{};
  HrczSession* h = hrcz_open(json5.c_str(), err.data(), err.size());
  if (h == nullptr) throw BusError(err_text(err));
  return Session(h);
}

Session::Session(Session&& o) noexcept : handle_(o.handle_) { o.handle_ = nullptr; }

Session& Session::operator=(Session&& o) noexcept {
  if (this != &o) {
    close();
    handle_ = o.handle_;
    o.handle_ = nullptr;
  }
  return *this;
}

Session::~Session() { close(); }

void Session::close() noexcept {
  hrcz_close(handle_);
  handle_ = nullptr;
}

namespace {
void require_open(const HrczSession* h) {
  if (h == nullptr) throw BusError("the zenoh session is closed");
}
}  // namespace

Publisher Session::declare_publisher(const std::string& key, PublisherOptions options) const {
  require_open(handle_);
  ErrBuf err{};
  HrczPublisher* p = hrcz_declare_publisher(handle_, key.c_str(), options.congestion_block ? 1 : 0,
                                            options.express ? 1 : 0, err.data(), err.size());
  if (p == nullptr) throw BusError(err_text(err));
  return Publisher(p, key);
}

Subscriber Session::declare_subscriber(const std::string& key_expr, SampleHandler handler) const {
  require_open(handle_);
  auto cb = std::make_unique<Subscriber::Callbacks>();
  cb->key_expr = key_expr;
  cb->on_sample = std::move(handler);
  ErrBuf err{};
  HrczSubscriber* s = hrcz_declare_subscriber(
      handle_, key_expr.c_str(), &Subscriber::Callbacks::sample, cb.get(), err.data(), err.size());
  if (s == nullptr) throw BusError(err_text(err));
  return Subscriber(s, std::move(cb), key_expr);
}

Subscriber Session::declare_liveliness_subscriber(const std::string& key_expr,
                                                  LivelinessHandler handler, bool history) const {
  require_open(handle_);
  auto cb = std::make_unique<Subscriber::Callbacks>();
  cb->key_expr = key_expr;
  cb->on_liveliness = std::move(handler);
  ErrBuf err{};
  HrczSubscriber* s = hrcz_declare_liveliness_subscriber(handle_, key_expr.c_str(), history ? 1 : 0,
                                                         &Subscriber::Callbacks::liveliness,
                                                         cb.get(), err.data(), err.size());
  if (s == nullptr) throw BusError(err_text(err));
  return Subscriber(s, std::move(cb), key_expr);
}

LivelinessToken Session::declare_token(const std::string& key) const {
  require_open(handle_);
  ErrBuf err{};
  HrczToken* t = hrcz_declare_token(handle_, key.c_str(), err.data(), err.size());
  if (t == nullptr) throw BusError(err_text(err));
  return LivelinessToken(t, key);
}

Queryable Session::declare_queryable(const std::string& key, Queryable::Handler handler) const {
  require_open(handle_);
  auto h = std::make_unique<Queryable::Handler>(std::move(handler));
  ErrBuf err{};
  HrczQueryable* q = hrcz_declare_queryable(handle_, key.c_str(), &query_trampoline, h.get(),
                                            err.data(), err.size());
  if (q == nullptr) throw BusError(err_text(err));
  return Queryable(q, std::move(h), key);
}

namespace {
void reply_trampoline(void* ctx, const char* key, size_t key_len, const uint8_t* payload,
                      size_t len, const uint8_t* att, size_t att_len, int is_error) noexcept {
  auto* out = static_cast<std::vector<Reply>*>(ctx);
  try {
    out->push_back(Reply{std::string(view(key, key_len)), std::string(view(payload, len)),
                         std::string(view(att, att_len)), is_error != 0});
  } catch (...) {
    report_callback_failure("get", view(key, key_len));
  }
}
}  // namespace

std::vector<Reply> Session::get(const std::string& selector, std::string_view payload,
                                std::string_view attachment,
                                std::chrono::milliseconds timeout) const {
  require_open(handle_);
  std::vector<Reply> replies;
  ErrBuf err{};
  const auto ms = static_cast<uint64_t>(timeout.count() < 0 ? 0 : timeout.count());
  const int64_t n =
      hrcz_get(handle_, selector.c_str(), u8(payload), payload.size(), u8(attachment),
               attachment.size(), ms, &reply_trampoline, &replies, err.data(), err.size());
  if (n < 0) throw BusError(err_text(err));
  return replies;
}

}  // namespace hrc
