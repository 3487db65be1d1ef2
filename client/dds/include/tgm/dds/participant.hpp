// Small Fast DDS helpers shared by tgm-service, tgm-plc and tgm-hmi (STYLE.md "The DDS
// application shape"): a participant built from the YAML config, typed topics, writers and
// readers created by XML profile name with every creation checked, waiting for matches and data.
//
// Construction throws SetupError (setup time only). Nothing here throws after setup: waiting and
// taking return bool.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <initializer_list>
#include <map>
#include <new>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <fastcdr/exceptions/Exception.h>
#include <fastdds/dds/core/condition/GuardCondition.hpp>
#include <fastdds/dds/core/condition/WaitSet.hpp>
#include <fastdds/dds/core/status/StatusMask.hpp>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include "tgm/dds/topics.hpp"
#include "tgm/msg/tgmPubSubTypes.h"
#include "tgm/yaml_config.hpp"

namespace tgm::dds {

namespace fdds = eprosima::fastdds::dds;

//! Failed reads of samples in this process (CheckedType): each such sample is dropped. Fast
//! DDS may try one sample more than once (to read the key of a keyed topic first), so this
//! counts reads, not samples: 0 means none arrived.
std::uint64_t malformed_samples();

namespace detail {
extern std::atomic<std::uint64_t> g_malformed_samples;

//! Reads `payload` into `data` as a sample of an older tgm version's layout of the type, which
//! ends before the fields appended since (idl/tgm.idl: fields are only ever appended): those
//! read as their defaults (0). Overloaded for the types that grew since the oldest layout this
//! version reads (0.2.0's); the others have none.
inline bool read_older_layout(const void* /*type*/,
                              eprosima::fastrtps::rtps::SerializedPayload_t* /*payload*/,
                              void* /*data*/) {
  return false;
}
//! InterpolatorState: 0.2.0's ends at plc_setup (0.2.1 appended machine_digest, 0.2.2 the
//! smoothing in effect). A sample that ends before plc_setup is no layout of a version this one
//! reads: not taken.
bool read_older_layout(const msg::InterpolatorStatePubSubType* type,
                       eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data);
}  // namespace detail

//! The generated type support `PubSubType` with a deserialize() that never throws. The
//! generated one catches only fastcdr's NotEnoughMemoryException; fastcdr also throws
//! BadParamException (a bool that is neither 0 nor 1, an unknown encapsulation), and that
//! escaped Fast DDS's take and terminated the process: one malformed sample from any
//! participant on the domain stopped tgm-service. A sample that cannot be read is dropped
//! (Fast DDS skips a sample whose deserialize() fails) and counted (malformed_samples()).
//! A sample of an older version's layout of a type that grew since is read, the fields it
//! lacks at their defaults (detail::read_older_layout): the generated code drops it, so a
//! client upgraded before its service read no state of it at all.
template <class PubSubType>
class CheckedType : public PubSubType {
 public:
  bool deserialize(eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) override {
    try {
      if (PubSubType::deserialize(payload, data)) return true;
    } catch (const eprosima::fastcdr::exception::Exception&) {
    } catch (const std::bad_alloc&) {
    }
    if (detail::read_older_layout(static_cast<const PubSubType*>(this), payload, data)) return true;
    detail::g_malformed_samples.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
};

//! Tells the log when samples were dropped as malformed (CheckedType), at once the first time
//! and then at most every `every`, so that a participant that writes nothing but bad samples
//! cannot flood the log.
class MalformedWatch {
 public:
  explicit MalformedWatch(std::chrono::steady_clock::duration every = std::chrono::seconds(10))
      : every_(every) {}
  //! "" or the line to log, with the failed reads so far.
  std::string update(int domain_id, std::chrono::steady_clock::time_point now);

 private:
  std::chrono::steady_clock::duration every_;
  std::uint64_t told_ = 0;
  std::chrono::steady_clock::time_point next_{};
};

//! A DDS entity could not be set up; the message says which entity, which profile and why.
class SetupError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

//! Loads a Fast DDS XML profiles file into this process. Loading a path again does nothing.
//! Throws SetupError when the file is missing or Fast DDS rejects it.
void load_profiles(const std::string& path);

//! What the binaries check before any DDS entity exists, as config errors (exit code 2):
//! tgm::dds_config_problem for the participant of `role`, then load_profiles of
//! `config.profiles_file` (a file Fast DDS rejects is a bad config, not a failure to set up
//! DDS). Empty when all is well.
std::string config_problem(const DdsConfig& config, std::string_view role);

//! The name of the participant of `role`: "<participant_prefix>-<role>".
std::string participant_name(const DdsConfig& config, std::string_view role);

//! The longest client name: the bound of the topics' client_name (TGM_MAX_NAME in idl/tgm.idl;
//! tgm::client asserts that the two agree).
inline constexpr std::size_t kMaxClientName = 64;

//! The client name a participant announced in its USER_DATA (Participant's `client_name`), or
//! empty when it announced none or something else: anything on the domain may write those
//! bytes, so only 1..kMaxClientName printable ASCII characters count as a name.
std::string participant_client_name(const std::vector<unsigned char>& user_data);

//! One DomainParticipant with one Publisher and one Subscriber. Owns every entity it creates;
//! the destructor deletes them all (delete_contained_entities), then the participant.
class Participant {
 public:
  //! Loads `config.profiles_file`, creates the participant from `profile` on
  //! `config.domain_id`, named "<participant_prefix>-<role>". A `client_name` (tgm::client's
  //! unique name, the one its requests carry) goes into the participant's USER_DATA, which
  //! discovery hands to every other participant: the service names a client by it before its
  //! first request (participant_client_name). Throws SetupError.
  Participant(const DdsConfig& config, std::string_view role,
              std::string_view profile = kParticipantProfile, std::string_view client_name = {});
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  //! Registers the generated type `PubSubType` (without type objects, see DESIGN.md section 6;
  //! reading checked, CheckedType) and creates the topic `name`; a second call with the same
  //! name returns the same topic.
  template <class PubSubType>
  fdds::Topic& topic(std::string_view name) {
    return make_topic(name, fdds::TypeSupport(new CheckedType<PubSubType>()));
  }

  //! Creates a writer on `topic` with the XML data_writer profile `profile`, and `listener`
  //! for the statuses of `mask`. The listener is attached at creation: matches with readers the
  //! participant already knows happen inside the creation. Throws SetupError.
  fdds::DataWriter& writer(fdds::Topic& topic, std::string_view profile,
                           fdds::DataWriterListener* listener = nullptr,
                           const fdds::StatusMask& mask = fdds::StatusMask::none());
  //! Creates a reader on `topic` with the XML data_reader profile `profile`. Throws SetupError.
  fdds::DataReader& reader(fdds::Topic& topic, std::string_view profile);

  //! Writer on the topic `spec` with its writer profile.
  template <class PubSubType>
  fdds::DataWriter& writer(const TopicSpec& spec, fdds::DataWriterListener* listener = nullptr,
                           const fdds::StatusMask& mask = fdds::StatusMask::none()) {
    return writer(topic<PubSubType>(spec.name), spec.writer_profile, listener, mask);
  }
  //! Reader on the topic `spec` with its reader profile.
  template <class PubSubType>
  fdds::DataReader& reader(const TopicSpec& spec) {
    return reader(topic<PubSubType>(spec.name), spec.reader_profile);
  }

  fdds::DomainParticipant& get() { return *participant_; }
  const std::string& name() const { return name_; }
  int domain_id() const { return domain_id_; }

 private:
  fdds::Topic& make_topic(std::string_view name, fdds::TypeSupport type);
  // Why a writer or reader (`kind`) could not be created.
  std::string entity_error(std::string_view kind, const std::string& topic,
                           std::string_view profile) const;

  std::string name_;
  int domain_id_ = 0;
  bool secure_ = false;  // DDS Security on (dds.security)
  fdds::DomainParticipant* participant_ = nullptr;
  fdds::Publisher* publisher_ = nullptr;
  fdds::Subscriber* subscriber_ = nullptr;
  std::map<std::string, fdds::Topic*, std::less<>> topics_;
};

//! Waits until `writer` is matched with at least `min_readers` readers. Writing before the
//! match loses the samples on a VOLATILE topic. False on timeout.
bool wait_for_match(fdds::DataWriter& writer, int min_readers, std::chrono::milliseconds timeout);
//! Waits until `reader` is matched with at least `min_writers` writers. False on timeout.
bool wait_for_match(fdds::DataReader& reader, int min_writers, std::chrono::milliseconds timeout);

//! Blocks a thread until one of some readers has data, or until wake() (for stop()). A WaitSet
//! on the readers' DATA_AVAILABLE conditions plus a guard condition.
class DataWaiter {
 public:
  explicit DataWaiter(std::initializer_list<fdds::DataReader*> readers);
  ~DataWaiter();
  DataWaiter(const DataWaiter&) = delete;
  DataWaiter& operator=(const DataWaiter&) = delete;

  //! True when data may be available (or wake() was called); false on timeout.
  bool wait(std::chrono::nanoseconds timeout);
  //! Makes the current and every later wait() return at once (thread-safe; for stop()).
  void wake();

 private:
  fdds::WaitSet waitset_;
  fdds::GuardCondition guard_;
  std::vector<fdds::DataReader*> readers_;
};

//! Takes the next valid sample of `reader` into `sample` and its `info`; false when there is
//! none left. Samples without data (disposal, unregistration notices) are skipped.
template <class T>
bool take_next(fdds::DataReader& reader, T& sample, fdds::SampleInfo& info) {
  while (reader.take_next_sample(&sample, &info) == eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
    if (info.valid_data) return true;
  }
  return false;
}

template <class T>
bool take_next(fdds::DataReader& reader, T& sample) {
  fdds::SampleInfo info;
  return take_next(reader, sample, info);
}

}  // namespace tgm::dds
