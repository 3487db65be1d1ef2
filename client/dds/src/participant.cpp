#include "tgm/dds/participant.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <set>
#include <thread>
#include <vector>

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <fastcdr/exceptions/NotEnoughMemoryException.h>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastrtps/xmlparser/XMLProfileManager.h>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/qos/DomainParticipantQos.hpp>
#include <fastdds/dds/log/Log.hpp>

#include "tgm/dds_overrides.hpp"

namespace tgm::dds {

namespace {

using eprosima::fastrtps::types::ReturnCode_t;

bool ok(const ReturnCode_t& rc) { return rc == ReturnCode_t::RETCODE_OK; }

std::string code_text(const ReturnCode_t& rc) {
  switch (rc()) {
    case ReturnCode_t::RETCODE_OK:
      return "ok";
    case ReturnCode_t::RETCODE_BAD_PARAMETER:
      return "bad parameter (unknown profile name?)";
    case ReturnCode_t::RETCODE_PRECONDITION_NOT_MET:
      return "precondition not met";
    case ReturnCode_t::RETCODE_INCONSISTENT_POLICY:
      return "inconsistent QoS policy";
    case ReturnCode_t::RETCODE_OUT_OF_RESOURCES:
      return "out of resources";
    default:
      return "Fast DDS return code " + std::to_string(rc());
  }
}

eprosima::fastrtps::Duration_t to_duration(std::chrono::nanoseconds ns) {
  const auto sec = std::chrono::duration_cast<std::chrono::seconds>(ns);
  return eprosima::fastrtps::Duration_t(static_cast<std::int32_t>(sec.count()),
                                        static_cast<std::uint32_t>((ns - sec).count()));
}

// Polls a matched count until it reaches `min` (setup time only; 2 ms steps).
template <class CountFn>
bool poll_until(CountFn count, int min, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (true) {
    if (count() >= min) return true;
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
}

// The properties of Fast DDS's builtin security plugins: PKI-DH authentication, the
// Access-Permissions access control and AES-GCM-GMAC cryptography, from the files of
// dds_security_files (ca, governance, certificate, key, permissions).
void add_security(fdds::DomainParticipantQos& qos, const std::array<std::string, 5>& files) {
  namespace fs = std::filesystem;
  auto uri = [](const std::string& f) {
    std::error_code ec;
    return "file://" + fs::absolute(f, ec).string();
  };
  auto& p = qos.properties().properties();
  p.emplace_back("dds.sec.auth.plugin", "builtin.PKI-DH");
  p.emplace_back("dds.sec.auth.builtin.PKI-DH.identity_ca", uri(files[0]));
  p.emplace_back("dds.sec.auth.builtin.PKI-DH.identity_certificate", uri(files[2]));
  p.emplace_back("dds.sec.auth.builtin.PKI-DH.private_key", uri(files[3]));
  p.emplace_back("dds.sec.access.plugin", "builtin.Access-Permissions");
  p.emplace_back("dds.sec.access.builtin.Access-Permissions.permissions_ca", uri(files[0]));
  p.emplace_back("dds.sec.access.builtin.Access-Permissions.governance", uri(files[1]));
  p.emplace_back("dds.sec.access.builtin.Access-Permissions.permissions", uri(files[4]));
  p.emplace_back("dds.sec.crypto.plugin", "builtin.AES-GCM-GMAC");
}

// The hint for a domain whose ports may lie where the kernel hands out ports for outgoing
// sockets (/proc/sys/net/ipv4/ip_local_port_range, "32768 60999" by default): the domains whose
// whole block of `gain` ports from `base` lies below that range, or "" if none or unknown.
std::string ephemeral_hint(std::uint32_t base, std::uint32_t gain) {
  std::ifstream in("/proc/sys/net/ipv4/ip_local_port_range");
  long lo = 0;
  long hi = 0;
  if (!(in >> lo >> hi) || lo <= 0 || hi < lo || gain == 0) return {};
  if (lo < static_cast<long>(base + gain)) return {};
  const long last = (lo - static_cast<long>(base)) / static_cast<long>(gain) - 1;
  return ". Domains 0.." + std::to_string(std::min(last, 232L)) +
         " keep their ports below this machine's range for outgoing sockets (" +
         std::to_string(lo) + "-" + std::to_string(hi) + "), where any program can be given one";
}

// Why the enabled participant on `domain` (built from `qos`) can neither find nor be found, or
// "" when it can. Simple discovery listens on the domain's multicast port (7400 + 250 x domain
// with the default port parameters), bound with SO_REUSEADDR so that every participant on the
// host shares it. A socket of another program bound there without SO_REUSEADDR (an outgoing
// socket the kernel gave that port, when the domain's ports lie in the ephemeral range) makes
// Fast DDS's bind fail, and Fast DDS goes on without saying so: the participant was deaf, and a
// test's two participants never matched (CI, session 69). Once Fast DDS holds the port no
// such socket can take it, so a bind beside it right after creation is exact: it fails only
// if Fast DDS's failed.
std::string discovery_port_problem(const fdds::DomainParticipantQos& qos, int domain) {
  const auto& wire = qos.wire_protocol();
  const auto& builtin = wire.builtin;
  // Fast DDS's built-in transports or a UDPv4 one of the profile (tgm's own since session 76)
  // listen there; other transports do not.
  bool udp = qos.transport().use_builtin_transports;
  for (const auto& t : qos.transport().user_transports) {
    udp = udp || std::dynamic_pointer_cast<eprosima::fastdds::rtps::UDPv4TransportDescriptor>(t);
  }
  if (builtin.discovery_config.discoveryProtocol !=
          eprosima::fastrtps::rtps::DiscoveryProtocol_t::SIMPLE ||
      !builtin.metatrafficMulticastLocatorList.empty() || !udp) {
    return {};  // a profile that chose its own discovery locators or transports
  }
  // Fast DDS's own formula; it ended the process in create_participant had it overflowed.
  const std::uint32_t port = wire.port.getMulticastPort(static_cast<std::uint32_t>(domain));
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return {};
  const int one = 1;
  ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_ANY);
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  const int rc = ::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr);
  const int err = errno;
  ::close(fd);
  if (rc == 0 || err != EADDRINUSE) return {};
  return "DDS domain " + std::to_string(domain) + ": its discovery port, UDP " +
         std::to_string(port) +
         ", is held by another program (a socket that does not share it), so this participant "
         "could neither find nor be found; free the port (ss -uanp 'sport = :" +
         std::to_string(port) + "') or use another domain" +
         ephemeral_hint(wire.port.portBase, wire.port.domainIDGain);
}

// Fast DDS's own log lines go to standard error without colour codes, as tgm's do. Its default
// consumer wrote them to standard output with terminal colours: into `tgm-hmi status --json`'s
// JSON, and after the tgm message that pointed "above" to them.
class PlainErrorLog final : public eprosima::fastdds::dds::LogConsumer {
 public:
  void Consume(const eprosima::fastdds::dds::Log::Entry& e) override {
    using Log = eprosima::fastdds::dds::Log;
    const char* kind = e.kind == Log::Kind::Error     ? "error"
                       : e.kind == Log::Kind::Warning ? "warning"
                                                      : "info";
    std::fprintf(stderr, "Fast DDS %s [%s]: %s\n", kind,
                 e.context.category != nullptr ? e.context.category : "", e.message.c_str());
  }
};

void use_plain_log() {
  static std::once_flag once;
  std::call_once(once, [] {
    using Log = eprosima::fastdds::dds::Log;
    Log::ClearConsumers();
    Log::RegisterConsumer(std::make_unique<PlainErrorLog>());
  });
}

}  // namespace

void load_profiles(const std::string& path) {
  use_plain_log();
  static std::mutex mutex;
  static std::set<std::string> loaded;
  std::error_code ec;
  const std::string key = std::filesystem::weakly_canonical(path, ec).string();
  const std::lock_guard lock(mutex);
  if (loaded.count(key) != 0) return;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw SetupError("DDS profiles file '" + path + "' does not exist");
  }
  const ReturnCode_t rc =
      fdds::DomainParticipantFactory::get_instance()->load_XML_profiles_file(path);
  if (!ok(rc)) {
    throw SetupError("DDS profiles file '" + path + "' was rejected by Fast DDS (" + code_text(rc) +
                     "); Fast DDS's reason is in its log lines on standard error");
  }
  loaded.insert(key);
}

std::string config_problem(const DdsConfig& config, std::string_view role) {
  if (std::string why = dds_config_problem(config, role); !why.empty()) return why;
  if (config.profiles_file.empty()) return {};
  try {
    load_profiles(config.profiles_file);
  } catch (const SetupError& e) {
    return e.what();
  }
  // A well-formed file without the profiles tgm creates its entities from is as bad a config
  // as a malformed one: found here, before DDS is joined, not as a failure to set DDS up.
  std::vector<std::string_view> missing;
  namespace xml = eprosima::fastrtps::xmlparser;
  eprosima::fastrtps::ParticipantAttributes participant;
  if (xml::XMLProfileManager::fillParticipantAttributes(
          std::string(kParticipantProfile), participant, false) != xml::XMLP_ret::XML_OK) {
    missing.push_back(kParticipantProfile);
  }
  for (const TopicSpec& t : kAllTopics) {
    eprosima::fastrtps::PublisherAttributes w;
    eprosima::fastrtps::SubscriberAttributes r;
    if (xml::XMLProfileManager::fillPublisherAttributes(std::string(t.writer_profile), w, false) !=
        xml::XMLP_ret::XML_OK) {
      missing.push_back(t.writer_profile);
    }
    if (xml::XMLProfileManager::fillSubscriberAttributes(std::string(t.reader_profile), r, false) !=
        xml::XMLP_ret::XML_OK) {
      missing.push_back(t.reader_profile);
    }
  }
  if (missing.empty()) return {};
  std::string names;
  for (const std::string_view m : missing) {
    names += (names.empty() ? "'" : ", '") + std::string(m) + "'";
  }
  return "DDS profiles file '" + config.profiles_file + "' lacks the profile" +
         (missing.size() > 1 ? "s " : " ") + names +
         " that tgm creates its participant and topics from (config/fastdds_profiles.xml "
         "defines them all; start from a copy of it)";
}

std::string participant_name(const DdsConfig& config, std::string_view role) {
  return config.participant_prefix + "-" + std::string(role);
}

std::string participant_client_name(const std::vector<unsigned char>& user_data) {
  if (user_data.empty() || user_data.size() > kMaxClientName) return {};
  for (const unsigned char c : user_data) {
    if (c < 0x20 || c > 0x7e) return {};
  }
  return std::string(user_data.begin(), user_data.end());
}

Participant::Participant(const DdsConfig& config, std::string_view role, std::string_view profile,
                         std::string_view client_name)
    : name_(participant_name(config, role)), domain_id_(config.domain_id) {
  use_plain_log();
  if (config.domain_id < 0 || config.domain_id > 232) {
    throw SetupError("DDS domain id " + std::to_string(config.domain_id) + " outside 0..232");
  }
  if (!config.profiles_file.empty()) load_profiles(config.profiles_file);
  auto* factory = fdds::DomainParticipantFactory::get_instance();
  fdds::DomainParticipantQos qos;
  if (const ReturnCode_t rc = factory->get_participant_qos_from_profile(std::string(profile), qos);
      !ok(rc)) {
    throw SetupError("DDS participant profile '" + std::string(profile) + "' not found in '" +
                     config.profiles_file + "'");
  }
  qos.name(name_);
  if (!client_name.empty()) {
    qos.user_data().data_vec(
        std::vector<eprosima::fastrtps::rtps::octet>(client_name.begin(), client_name.end()));
  }
  if (!config.security_dir.empty()) {
    if (std::string why = dds_security_problem(config, role); !why.empty()) throw SetupError(why);
    add_security(qos, dds_security_files(config.security_dir, role));
    secure_ = true;
  }
  participant_ = factory->create_participant(static_cast<fdds::DomainId_t>(domain_id_), qos);
  if (participant_ == nullptr && secure_) {
    throw SetupError("cannot create DDS participant '" + name_ + "' on domain " +
                     std::to_string(domain_id_) + ": DDS Security refused the " +
                     std::string(role) + " identity or permissions in '" + config.security_dir +
                     "' (made by another tgm-security run than its CA and governance, expired, "
                     "or not for this domain?)");
  }
  if (participant_ == nullptr) {
    throw SetupError("cannot create DDS participant '" + name_ + "' on domain " +
                     std::to_string(domain_id_) + " from profile '" + std::string(profile) + "'");
  }
  if (std::string why = discovery_port_problem(qos, domain_id_); !why.empty()) {
    factory->delete_participant(participant_);
    throw SetupError(why);
  }
  publisher_ = participant_->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  subscriber_ = participant_->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
  if (publisher_ == nullptr || subscriber_ == nullptr) {
    participant_->delete_contained_entities();
    factory->delete_participant(participant_);
    throw SetupError("cannot create the publisher / subscriber of DDS participant '" + name_ +
                     "'");
  }
}

namespace detail {
std::atomic<std::uint64_t> g_malformed_samples{0};
}  // namespace detail

bool detail::read_older_layout(const msg::InterpolatorStatePubSubType* /*type*/,
                               eprosima::fastrtps::rtps::SerializedPayload_t* payload, void* data) {
  // plc_setup is 0, 1 or 2 in every state a service writes: a value it cannot have marks it
  // unread.
  constexpr std::uint8_t kUnread = 0xff;
  msg::InterpolatorState s;
  s.plc_setup(kUnread);
  try {
    eprosima::fastcdr::FastBuffer buffer(reinterpret_cast<char*>(payload->data), payload->length);
    eprosima::fastcdr::Cdr cdr(buffer, eprosima::fastcdr::Cdr::DEFAULT_ENDIAN,
                               eprosima::fastcdr::Cdr::DDS_CDR);
    cdr.read_encapsulation();
    payload->encapsulation =
        cdr.endianness() == eprosima::fastcdr::Cdr::BIG_ENDIANNESS ? CDR_BE : CDR_LE;
    s.deserialize(cdr);
    return false;  // read whole: it failed for another reason
  } catch (const eprosima::fastcdr::exception::NotEnoughMemoryException&) {
    // It ended early: fine if after 0.2.0's last field, which the read then got to.
  } catch (const eprosima::fastcdr::exception::Exception&) {
    return false;
  } catch (const std::bad_alloc&) {
    return false;
  }
  if (s.plc_setup() == kUnread) return false;
  *static_cast<msg::InterpolatorState*>(data) = std::move(s);
  return true;
}

std::uint64_t malformed_samples() {
  return detail::g_malformed_samples.load(std::memory_order_relaxed);
}

std::string MalformedWatch::update(int domain_id, std::chrono::steady_clock::time_point now) {
  const std::uint64_t all = malformed_samples();
  if (all == told_ || now < next_) return {};
  told_ = all;
  next_ = now + every_;
  // Reads, not samples: Fast DDS may try a sample more than once (the key of a keyed topic is
  // read from it before the sample is stored).
  return "DDS samples that cannot be read arrive and are dropped (" + std::to_string(all) +
         " failed read" + (all == 1 ? "" : "s") + " so far): a participant on domain " +
         std::to_string(domain_id) + " writes tgm topics in a form this version does not know";
}

Participant::~Participant() {
  // Entities first (writers, readers, publisher, subscriber, topics), then the participant.
  participant_->delete_contained_entities();
  fdds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
}

fdds::Topic& Participant::make_topic(std::string_view name, fdds::TypeSupport type) {
  if (auto it = topics_.find(name); it != topics_.end()) {
    if (it->second->get_type_name() != type.get_type_name()) {
      throw SetupError("DDS topic '" + std::string(name) + "' already has type '" +
                       it->second->get_type_name() + "', not '" + type.get_type_name() + "'");
    }
    return *it->second;
  }
  // No type objects / type information: with them, other vendors refuse to match (DESIGN 6).
  type->auto_fill_type_object(false);
  type->auto_fill_type_information(false);
  if (participant_->find_type(type.get_type_name()).empty()) {
    if (const ReturnCode_t rc = type.register_type(participant_); !ok(rc)) {
      throw SetupError("cannot register DDS type '" + type.get_type_name() + "' (" +
                       code_text(rc) + ")");
    }
  }
  fdds::Topic* t = participant_->create_topic(std::string(name), type.get_type_name(),
                                              fdds::TOPIC_QOS_DEFAULT);
  if (t == nullptr) {
    throw SetupError("cannot create DDS topic '" + std::string(name) + "' of type '" +
                     type.get_type_name() + "'");
  }
  topics_.emplace(std::string(name), t);
  return *t;
}

std::string Participant::entity_error(std::string_view kind, const std::string& topic,
                                      std::string_view profile) const {
  return "cannot create DDS " + std::string(kind) + " on topic '" + topic + "' with profile '" +
         std::string(profile) + "' (" +
         (secure_ ? "not allowed by this identity's DDS Security permissions for this topic on "
                    "domain " +
                        std::to_string(domain_id_) + " (tgm-security --domains), "
                  : std::string()) +
         "unknown profile or inconsistent QoS; see Fast DDS's log lines on standard error)";
}

fdds::DataWriter& Participant::writer(fdds::Topic& topic, std::string_view profile,
                                      fdds::DataWriterListener* listener,
                                      const fdds::StatusMask& mask) {
  fdds::DataWriter* w =
      publisher_->create_datawriter_with_profile(&topic, std::string(profile), listener, mask);
  if (w == nullptr) {
    throw SetupError(entity_error("writer", topic.get_name(), profile));
  }
  return *w;
}

fdds::DataReader& Participant::reader(fdds::Topic& topic, std::string_view profile) {
  fdds::DataReader* r = subscriber_->create_datareader_with_profile(&topic, std::string(profile));
  if (r == nullptr) {
    throw SetupError(entity_error("reader", topic.get_name(), profile));
  }
  return *r;
}

bool wait_for_match(fdds::DataWriter& writer, int min_readers, std::chrono::milliseconds timeout) {
  return poll_until(
      [&writer] {
        fdds::PublicationMatchedStatus st;
        writer.get_publication_matched_status(st);
        return st.current_count;
      },
      min_readers, timeout);
}

bool wait_for_match(fdds::DataReader& reader, int min_writers, std::chrono::milliseconds timeout) {
  return poll_until(
      [&reader] {
        fdds::SubscriptionMatchedStatus st;
        reader.get_subscription_matched_status(st);
        return st.current_count;
      },
      min_writers, timeout);
}

DataWaiter::DataWaiter(std::initializer_list<fdds::DataReader*> readers) : readers_(readers) {
  for (fdds::DataReader* r : readers_) {
    r->get_statuscondition().set_enabled_statuses(fdds::StatusMask::data_available());
    if (!ok(waitset_.attach_condition(r->get_statuscondition()))) {
      throw SetupError("cannot attach DDS reader of topic '" + r->get_topicdescription()->get_name() +
                       "' to a wait set");
    }
  }
  if (!ok(waitset_.attach_condition(guard_))) throw SetupError("cannot attach a guard condition");
}

DataWaiter::~DataWaiter() {
  for (fdds::DataReader* r : readers_) waitset_.detach_condition(r->get_statuscondition());
  waitset_.detach_condition(guard_);
}

bool DataWaiter::wait(std::chrono::nanoseconds timeout) {
  fdds::ConditionSeq active;
  return ok(waitset_.wait(active, to_duration(timeout)));
}

void DataWaiter::wake() { guard_.set_trigger_value(true); }

}  // namespace tgm::dds
