// A participant that writes malformed samples (another vendor's bug, a fuzzer, an attacker):
// a type support that sends whatever bytes it is given under the name of a real tgm type.
#pragma once

#include <cstdint>
#include <cstring>
#include <functional>
#include <string>

#include <fastdds/rtps/common/SerializedPayload.h>
#include <gtest/gtest.h>
#include <fastdds/dds/topic/TopicDataType.hpp>

#include "tgm/msg/tgmPubSubTypes.h"

namespace tgm::test {

// Sends the bytes it is given as a sample of the real type `Real` (its name and size).
template <class Real>
class RawBytesType : public eprosima::fastdds::dds::TopicDataType {
 public:
  RawBytesType() {
    Real real;
    setName(real.getName());
    m_typeSize = real.m_typeSize;
    m_isGetKeyDefined = true;  // every keyed tgm type has `@key unsigned short interpolator`
  }
  bool serialize(void* data, eprosima::fastrtps::rtps::SerializedPayload_t* payload) override {
    const auto* bytes = static_cast<const std::string*>(data);
    if (bytes->size() > payload->max_size) return false;
    std::memcpy(payload->data, bytes->data(), bytes->size());
    payload->length = static_cast<std::uint32_t>(bytes->size());
    return true;
  }
  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t*, void*) override { return false; }
  std::function<std::uint32_t()> getSerializedSizeProvider(void* data) override {
    return [data] { return static_cast<std::uint32_t>(static_cast<std::string*>(data)->size()); };
  }
  void* createData() override { return new std::string(); }
  void deleteData(void* data) override { delete static_cast<std::string*>(data); }
  // The key of a tgm type, its interpolator, is the first member (after the 4-byte
  // encapsulation, little endian); the key hash is its big-endian CDR, padded to 16 bytes.
  bool getKey(void* data, eprosima::fastrtps::rtps::InstanceHandle_t* handle, bool) override {
    const auto* bytes = static_cast<const std::string*>(data);
    if (bytes->size() < 6) return false;
    std::memset(handle->value, 0, sizeof handle->value);
    handle->value[0] = static_cast<eprosima::fastrtps::rtps::octet>((*bytes)[5]);
    handle->value[1] = static_cast<eprosima::fastrtps::rtps::octet>((*bytes)[4]);
    return true;
  }
};

// The bytes the generated type support makes of `sample`.
template <class PubSubType, class T>
std::string serialized(T& sample) {
  PubSubType type;
  eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(&sample)());
  EXPECT_TRUE(type.serialize(&sample, &payload));
  return std::string(reinterpret_cast<const char*>(payload.data), payload.length);
}

// A program chunk (empty, the end of program `program_id`) whose end_of_program byte is 2: the
// generated code cannot read it (fastcdr throws BadParamException for a bool that is neither 0
// nor 1). Empty when the layout is not the one expected: encapsulation (4 bytes), interpolator
// u16 + 2 padding, program_id u32, sequence_number u64, segment count u32, end_of_program.
inline std::string chunk_with_a_bool_of_2(std::uint16_t interpolator, std::uint32_t program_id) {
  msg::ProgramChunk chunk;
  chunk.interpolator(interpolator);
  chunk.program_id(program_id);
  chunk.end_of_program(true);
  std::string bytes = serialized<msg::ProgramChunkPubSubType>(chunk);
  constexpr std::size_t kEndOfProgram = 4 + 4 + 4 + 8 + 4;
  if (bytes.size() <= kEndOfProgram || bytes[kEndOfProgram] != 1) return {};
  bytes[kEndOfProgram] = 2;
  return bytes;
}

}  // namespace tgm::test
