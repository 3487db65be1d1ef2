// Requests and replies written and read by hand, for tests that play a client other than
// tgm::client::Client: their own request_id, role and client name.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <thread>

#include "tgm/dds/participant.hpp"
#include "tgm/msg/tgmPubSubTypes.h"

namespace tgm::test {

// A request for interpolator 0.
inline msg::Request hand_request(std::uint64_t id, msg::ClientRole role, const std::string& client,
                                 msg::RequestKind kind) {
  msg::Request r;
  r.request_id(id);
  r.role(role);
  r.client_name(client);
  r.interpolator(0);
  r.kind(kind);
  return r;
}

// The reply to request `id` of `client` taken from `replies` within `timeout` (the replies to
// others are taken and dropped); nullopt when none came.
inline std::optional<msg::Reply> await_reply(eprosima::fastdds::dds::DataReader& replies,
                                             const std::string& client, std::uint64_t id,
                                             std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  msg::Reply got;
  while (std::chrono::steady_clock::now() < deadline) {
    while (dds::take_next(replies, got)) {
      if (got.client_name() == client && got.request_id() == id) return got;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return std::nullopt;
}

}  // namespace tgm::test
