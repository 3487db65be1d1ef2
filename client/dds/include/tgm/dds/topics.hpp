// Topic names of tgm and the XML profile each side uses (config/fastdds_profiles.xml).
// The one list every process takes its topics from (DESIGN.md section 6).
#pragma once

#include <array>
#include <string_view>

namespace tgm::dds {

//! Participant profile every tgm process starts from (domain id and name come from the config).
inline constexpr std::string_view kParticipantProfile = "tgm_participant";

//! A topic with the profiles of its writers and readers.
struct TopicSpec {
  std::string_view name;
  std::string_view writer_profile;
  std::string_view reader_profile;
};

//! tgm::msg::InterpolatorState: every register, keyed per interpolator (service -> all).
inline constexpr TopicSpec kStateTopic{"tgm_state", "tgm_state_writer", "tgm_state_reader"};
//! tgm::msg::InterpolatorEvent: the event registers (M_Func, Status, Run_Flag, ...) in a small
//! sample, written just before the state when one of them changes (service -> PLC). VOLATILE:
//! late joiners read the state.
inline constexpr TopicSpec kEventTopic{"tgm_event", "tgm_event_writer", "tgm_event_reader"};
//! tgm::msg::Setpoints: Position / PositionInc per cycle (service -> drives).
inline constexpr TopicSpec kSetpointsTopic{"tgm_setpoints", "tgm_setpoints_writer",
                                           "tgm_setpoints_reader"};
//! tgm::msg::Request: commands, register writes, start / stop / clear (PLC, HMI -> service).
inline constexpr TopicSpec kRequestTopic{"tgm_request", "tgm_request_writer",
                                         "tgm_request_reader"};
//! With DDS Security (dds.security) each role writes its requests on a topic of its own, which
//! only that role's permissions allow: the service takes a request's role from the topic it
//! came on, so a PLC identity cannot pass a request off as the HMI's. Same QoS profiles.
inline constexpr TopicSpec kRequestPlcTopic{"tgm_request_plc", "tgm_request_writer",
                                            "tgm_request_reader"};
inline constexpr TopicSpec kRequestHmiTopic{"tgm_request_hmi", "tgm_request_writer",
                                            "tgm_request_reader"};
//! tgm::msg::Reply: accepted or why not (service -> PLC, HMI).
inline constexpr TopicSpec kReplyTopic{"tgm_reply", "tgm_reply_writer", "tgm_reply_reader"};
//! tgm::msg::ProgramChunk: intercode records (HMI -> service).
inline constexpr TopicSpec kProgramTopic{"tgm_program", "tgm_program_writer",
                                         "tgm_program_reader"};
//! Program chunks a sender may have written beyond the last one the service confirmed
//! (InterpolatorState.next_sequence). The tgm_program profiles size the writer history (2x)
//! and the reader history (4x) for it: Fast DDS 2.9 silently loses samples that a full reader
//! history rejects, so this window is what keeps the stream lossless.
inline constexpr int kProgramChunksInFlight = 64;

//! tgm::msg::Message: M29 texts and errors (service -> HMI).
inline constexpr TopicSpec kMessageTopic{"tgm_message", "tgm_message_writer",
                                         "tgm_message_reader"};

//! Every topic of tgm.
inline constexpr std::array kAllTopics{kStateTopic, kEventTopic,   kSetpointsTopic, kRequestTopic,
                                       kReplyTopic, kProgramTopic, kMessageTopic};

}  // namespace tgm::dds
