// A CyclePort for tests: requests and chunks are queued by the test, replies, messages, events
// and snapshots are recorded.
#pragma once

#include <deque>
#include <memory>
#include <vector>

#include "tgm/service/port.hpp"

namespace tgm::service::test {

class MockPort final : public CyclePort {
 public:
  bool next_request(RequestIn& out) override {
    if (requests.empty()) return false;
    out = requests.front();
    requests.pop_front();
    return true;
  }
  ChunkIn* front_chunk(int i) override {
    auto& q = chunks[static_cast<std::size_t>(i)];
    return q.empty() ? nullptr : q.front().get();
  }
  void pop_chunk(int i) override { chunks[static_cast<std::size_t>(i)].pop_front(); }
  bool reply(const ReplyOut& r) override {
    replies.push_back(r);
    return true;
  }
  bool message(const MessageOut& m) override {
    messages.push_back(m);
    return true;
  }
  bool event(const EventOut& e) override {
    if (events.size() >= event_capacity) return false;
    events.push_back(e);
    return true;
  }
  void publish(const Snapshot& s) override {
    last = s;
    ++snapshots;
  }
  bool next_peer_notice(PeerNotice& out) override {
    if (peer_notices.empty()) return false;
    out = peer_notices.front();
    peer_notices.pop_front();
    return true;
  }

  //! Queues records [first, first + count) of `p` as one chunk.
  void add_chunk(int i, const Program& p, std::size_t first, std::size_t count, std::uint32_t program_id,
                 bool end) {
    auto c = std::make_unique<ChunkIn>();
    c->interpolator = i;
    c->program_id = program_id;
    c->sequence_number = first;
    c->end_of_program = end;
    c->program.number_axes = p.number_axes;
    c->program.axis_letters = p.axis_letters;
    c->program.params = p.params;
    c->program.messages = p.messages;
    c->program.segments.assign(p.segments.begin() + static_cast<std::ptrdiff_t>(first),
                               p.segments.begin() + static_cast<std::ptrdiff_t>(first + count));
    chunks[static_cast<std::size_t>(i)].push_back(std::move(c));
  }
  RequestIn& add_request(Role role, RequestKind kind, int interpolator = 0) {
    RequestIn r;
    r.request_id = ++ids;
    r.role = role;
    r.kind = kind;
    r.interpolator = interpolator;
    r.client.set("test");
    requests.push_back(r);
    return requests.back();
  }

  std::deque<RequestIn> requests;
  std::deque<PeerNotice> peer_notices;
  std::deque<std::unique_ptr<ChunkIn>> chunks[kMaxInterpolators];
  std::vector<ReplyOut> replies;
  std::vector<MessageOut> messages;
  //! Events queued; a test may lower the capacity to see the engine count what is dropped.
  std::vector<EventOut> events;
  std::size_t event_capacity = 1'000'000;
  Snapshot last;
  std::uint64_t snapshots = 0;
  std::uint64_t ids = 0;
};

}  // namespace tgm::service::test
