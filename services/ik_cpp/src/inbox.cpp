#include "hrc/inbox.hpp"

#include <algorithm>
#include <chrono>
#include <tuple>

namespace hrc {

void Inbox::push(Pending p) {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    const std::pair<std::string, std::string> from{p.key, p.sender};
    uint64_t& got = received_[from];
    const auto ahead = ahead_.find(from);
    if (p.seq <= got || (ahead != ahead_.end() && ahead->second.count(p.seq) > 0)) {
      ++duplicates_;  // had already: handed over once only
      return;
    }
    if (p.seq == got + 1) {
      got = p.seq;
      // the messages that came past the hole this one closes
      while (ahead != ahead_.end() && ahead->second.erase(got + 1) > 0) ++got;
    } else {
      ahead_[from].insert(p.seq);  // past a hole: one before it is late, or lost
    }
    pending_.push_back(std::move(p));
  }
  cond_.notify_all();
}

bool Inbox::subscribed_locked(const std::string& key) {
  const auto it = matches_.find(key);
  if (it != matches_.end()) return it->second;
  bool hit = false;
  for (const auto& e : exprs_) {
    try {
      if (keyexpr_intersects(e, key)) {
        hit = true;
        break;
      }
    } catch (const BusError& err) {
      // A mark with an invalid key names nothing we could receive.
      log::warning(std::string("ignoring published mark: ") + err.what());
    }
  }
  matches_.emplace(key, hit);
  return hit;
}

std::vector<v2::PublishedMark> Inbox::missing_locked(
    const std::vector<v2::PublishedMark>& wanted) const {
  std::vector<v2::PublishedMark> out;
  for (const auto& m : wanted) {
    const auto it = received_.find({m.key(), m.sender()});
    const uint64_t got = it == received_.end() ? 0 : it->second;
    if (got < m.seq()) out.push_back(m);
  }
  return out;
}

std::vector<v2::PublishedMark> Inbox::missing(const std::vector<v2::PublishedMark>& marks) {
  const std::lock_guard<std::mutex> lock(mutex_);
  std::vector<v2::PublishedMark> wanted;
  for (const auto& m : marks) {
    if (subscribed_locked(m.key())) wanted.push_back(m);
  }
  return missing_locked(wanted);
}

std::vector<v2::PublishedMark> Inbox::wait_for(const std::vector<v2::PublishedMark>& marks,
                                               double timeout_s) {
  std::unique_lock<std::mutex> lock(mutex_);
  std::vector<v2::PublishedMark> wanted;
  for (const auto& m : marks) {
    if (subscribed_locked(m.key())) wanted.push_back(m);
  }
  if (wanted.empty()) return {};
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                            std::chrono::duration<double>(timeout_s));
  while (true) {
    auto still = missing_locked(wanted);
    if (still.empty()) return still;
    if (cond_.wait_until(lock, deadline) == std::cv_status::timeout) return missing_locked(wanted);
  }
}

std::size_t Inbox::deliver(uint64_t upto_tick, const std::string& master) {
  std::vector<Pending> ready;
  std::vector<ErasedHandler> handlers;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    std::vector<Pending> keep;
    for (auto& p : pending_) {
      const bool due =
          p.tick < upto_tick || (!master.empty() && p.tick == upto_tick && p.sender == master);
      (due ? ready : keep).push_back(std::move(p));
    }
    if (ready.empty()) {
      pending_.swap(keep);
      return 0;
    }
    pending_.swap(keep);
    handlers = handlers_;
  }
  std::sort(ready.begin(), ready.end(), [](const Pending& a, const Pending& b) {
    // Oldest tick first: an exchange hands over several ticks' messages at once.
    return std::tie(a.tick, a.index, a.key, a.sender, a.seq) <
           std::tie(b.tick, b.index, b.key, b.sender, b.seq);
  });
  for (const auto& p : ready) handlers[p.index](p.key, *p.msg);
  return ready.size();
}

std::size_t Inbox::pending() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return pending_.size();
}

std::size_t Inbox::duplicates() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return duplicates_;
}

}  // namespace hrc
