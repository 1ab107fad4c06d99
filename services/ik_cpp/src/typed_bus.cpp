#include "hrc/typed_bus.hpp"

#include <climits>

namespace hrc {

// ------------------------------------------------------------------ InputStats

uint64_t InputStats::count_error(const std::string& key) {
  const std::lock_guard<std::mutex> lock(mutex_);
  return ++decode_errors_[key];
}

uint64_t InputStats::decode_errors(const std::string& key) const {
  const std::lock_guard<std::mutex> lock(mutex_);
  const auto it = decode_errors_.find(key);
  return it == decode_errors_.end() ? 0 : it->second;
}

uint64_t InputStats::total_decode_errors() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  uint64_t n = 0;
  for (const auto& [k, v] : decode_errors_) n += v;
  return n;
}

void InputStats::add_subscribed(const std::string& key_expr) {
  const std::lock_guard<std::mutex> lock(mutex_);
  subscribed_.push_back(key_expr);
}

void InputStats::tick(uint64_t k) {
  const std::lock_guard<std::mutex> lock(mutex_);
  ++ticks_seen_;
  last_tick_ = k;
}

uint64_t InputStats::ticks_seen() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return ticks_seen_;
}

uint64_t InputStats::last_tick() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return last_tick_;
}

v2::ServiceStats InputStats::to_proto(const std::string& service) const {
  const std::lock_guard<std::mutex> lock(mutex_);
  v2::ServiceStats msg;
  msg.set_service(service);
  for (const auto& s : subscribed_) msg.add_subscribed(s);
  for (const auto& [k, v] : decode_errors_) (*msg.mutable_decode_errors())[k] = v;
  msg.set_ticks_seen(ticks_seen_);
  msg.set_last_tick(last_tick_);
  return msg;
}

// ------------------------------------------------------------------ TypedPublisher

TypedPublisher::TypedPublisher(const Bus& bus, Publisher publisher)
    : bus_(bus), publisher_(std::move(publisher)) {}

void TypedPublisher::stamp(v2::Header& h, uint64_t tick, double sim_time, uint64_t seq) const {
  h.set_session(bus_.keys().session());
  h.set_tick(tick);
  h.set_sim_time(sim_time);
  h.set_sender(bus_.sender());
  h.set_seq(seq);
}

void TypedPublisher::check_size(const std::size_t size) const {
  const std::size_t limit = bus_.max_message_bytes();
  if (size <= limit) return;
  throw BusError("a " + std::to_string(size) + "-byte message on " + key() + ": above the " +
                 std::to_string(limit) + "-byte limit of Zenoh's " +
                 (bus_.lowlatency() ? "low-latency" : "standard") +
                 " transport (docs/ARCHITECTURE.md); not sent");
}

void TypedPublisher::put_bytes_locked(const std::string& bytes) {
  check_size(bytes.size());
  if (bus_.batching()) {
    held_.push_back(bytes);
    return;
  }
  publisher_.put(bytes, bus_.sender());
}

void TypedPublisher::flush() {
  const std::lock_guard<std::mutex> lock(mutex_);
  if (held_.empty()) return;
  std::vector<std::string> held;
  held.swap(held_);
  if (held.size() == 1) {
    publisher_.put(held.front(), bus_.sender());
    return;
  }
  // an item costs its bytes plus a few of framing (tag, length)
  const std::size_t limit = bus_.max_message_bytes() - 64;
  const std::string attachment = bus_.sender() + std::string(kBatchSuffix);
  v2::ExchangeBatch batch;
  std::size_t size = 0;
  const auto put_batch = [&] {
    if (batch.items_size() == 1) {
      publisher_.put(batch.items(0), bus_.sender());
    } else if (batch.items_size() > 1) {
      publisher_.put(batch.SerializeAsString(), attachment);
    }
    batch.Clear();
    size = 0;
  };
  for (auto& item : held) {
    const std::size_t cost = item.size() + 16;
    if (size + cost > limit) put_batch();
    size += cost;
    batch.add_items(std::move(item));
  }
  put_batch();
}

void TypedPublisher::put_raw(std::string_view payload) {
  const std::lock_guard<std::mutex> lock(mutex_);
  check_size(payload.size());
  publisher_.put(payload, bus_.sender());
}

void TypedPublisher::remember_locked(const uint64_t seq, std::string bytes) {
  recent_.emplace_back(seq, std::move(bytes));
  if (recent_.size() > kReplayKeep) recent_.pop_front();
}

std::vector<std::string> TypedPublisher::sent_after(const uint64_t seq) const {
  const std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::string> out;
  if (recent_.empty() || recent_.front().first > seq + 1) return out;
  for (const auto& [n, bytes] : recent_) {
    if (n > seq) out.push_back(bytes);
  }
  return out;
}

uint64_t TypedPublisher::seq() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return seq_;
}

// ------------------------------------------------------------------ Bus

Bus::Bus(const BusConfig& config, std::string session_id, std::string sender)
    : Bus(Session(), std::move(session_id), std::move(sender)) {
  // Validate names before opening anything, then open.
  session_ = Session::open(config);
  max_message_bytes_ = config.lowlatency ? kMaxLowlatencyBytes : kMaxStandardBytes;
}

Bus::Bus(Session session, std::string session_id, std::string sender)
    : keys_(std::move(session_id)),
      sender_(check_name("service name", sender)),
      session_(std::move(session)) {}

Bus::~Bus() { close(); }

void Bus::close() noexcept {
  std::map<std::string, std::unique_ptr<TypedPublisher>> pubs;
  std::vector<Subscriber> subs;
  std::vector<Queryable> queryables;
  std::vector<LivelinessToken> tokens;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    pubs.swap(publishers_);
    subs.swap(subscribers_);
    queryables.swap(queryables_);
    tokens.swap(tokens_);
  }
  // Token first (others see us leave), then inputs, then outputs, then the session.
  tokens.clear();
  subs.clear();
  queryables.clear();
  pubs.clear();
  session_.close();
}

bool Bus::parse(google::protobuf::Message& msg, std::string_view bytes) {
  if (bytes.size() > static_cast<std::size_t>(INT_MAX)) return false;
  return msg.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()));
}

TypedPublisher& Bus::publisher(const std::string& key, PublisherOptions options) {
  const std::lock_guard<std::mutex> lock(mutex_);
  auto it = publishers_.find(key);
  if (it == publishers_.end()) {
    auto pub = std::make_unique<TypedPublisher>(*this, session_.declare_publisher(key, options));
    it = publishers_.emplace(key, std::move(pub)).first;
  }
  return *it->second;
}

namespace {
v2::PublishedMark make_mark(const std::string& key, const std::string& sender, uint64_t seq) {
  v2::PublishedMark m;
  m.set_key(key);
  m.set_sender(sender);
  m.set_seq(seq);
  return m;
}
}  // namespace

std::vector<v2::PublishedMark> Bus::published_marks() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  std::vector<v2::PublishedMark> marks;
  for (const auto& [key, pub] : publishers_) {
    const uint64_t seq = pub->seq();
    if (seq > 0) marks.push_back(make_mark(key, sender_, seq));
  }
  return marks;
}

std::vector<v2::PublishedMark> Bus::new_marks(const std::string& exclude) {
  const std::lock_guard<std::mutex> lock(mutex_);
  std::vector<v2::PublishedMark> marks;
  for (const auto& [key, pub] : publishers_) {
    const uint64_t seq = pub->seq();
    uint64_t& reported = reported_[key];
    if (seq <= reported || key == exclude) continue;
    reported = seq;
    marks.push_back(make_mark(key, sender_, seq));
  }
  return marks;
}

void Bus::flush_batches() {
  batching_.store(false);
  std::vector<TypedPublisher*> pubs;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    for (auto& [key, pub] : publishers_) pubs.push_back(pub.get());
  }
  for (TypedPublisher* pub : pubs) pub->flush();
}

void Bus::malformed(const SampleView& s, const std::string& problem) {
  const std::string key(s.key);
  const std::string sender = s.attachment.empty() ? std::string("?") : std::string(s.attachment);
  const uint64_t n = stats_.count_error(key);
  log::warning("malformed message #" + std::to_string(n) + " on " + key + " from sender '" +
               sender + "': " + problem);
}

void Bus::add_subscriber(Subscriber s) {
  const std::lock_guard<std::mutex> lock(mutex_);
  subscribers_.push_back(std::move(s));
}

void Bus::add_queryable(Queryable q) {
  const std::lock_guard<std::mutex> lock(mutex_);
  queryables_.push_back(std::move(q));
}

void Bus::declare_token(const std::string& service) {
  LivelinessToken t = session_.declare_token(keys_.alive(service.empty() ? sender_ : service));
  const std::lock_guard<std::mutex> lock(mutex_);
  tokens_.push_back(std::move(t));
}

void Bus::watch_liveliness(std::function<void(const std::string& service, bool alive)> on_change) {
  auto handler = [on_change = std::move(on_change)](std::string_view key, bool alive) {
    on_change(Keys::last_segment(key), alive);
  };
  add_subscriber(
      session_.declare_liveliness_subscriber(keys_.alive_all(), std::move(handler), true));
}

void Bus::serve_replay() {
  queryable<v2::ReplayRequest, v2::ExchangeBatch>(
      keys_.replay(sender_), [this](const v2::ReplayRequest& req) {
        v2::ExchangeBatch batch;
        const TypedPublisher* pub = nullptr;
        {
          const std::lock_guard<std::mutex> lock(mutex_);
          const auto it = publishers_.find(req.key());
          if (it != publishers_.end()) pub = it->second.get();
        }
        if (pub != nullptr) {
          for (std::string& item : pub->sent_after(req.after_seq()))
            batch.add_items(std::move(item));
        }
        return batch;
      });
}

void Bus::serve_stats() {
  const std::string key = keys_.stats(sender_);
  auto on_query = [this](const QueryView&) -> QueryReply {
    v2::ServiceStats msg = stats_.to_proto(sender_);
    v2::Header& h = *msg.mutable_header();
    h.set_session(keys_.session());
    h.set_sender(sender_);
    h.set_tick(msg.last_tick());
    return QueryReply::ok(msg.SerializeAsString());
  };
  add_queryable(session_.declare_queryable(key, std::move(on_query)));
}

}  // namespace hrc
