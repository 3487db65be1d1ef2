/* What the Cyclone DDS clients of tgm-service share (tests/interop): argument parsing, the
 * endpoints with tgm's QoS, taking samples until one fits, waiting for a match, and a request
 * written until its reply comes, as tgm's own clients write them. */
#ifndef TGM_INTEROP_CYCLONE_COMMON_H
#define TGM_INTEROP_CYCLONE_COMMON_H

#include <stdbool.h>

#include "dds/dds.h"
#include TGM_PROBE_TYPES

/* Prints "PROGRAM: step: why" on stderr; returns 1 (the clients' exit code for a failed step). */
int fail(const char* step, const char* why);

/* Reads "DOMAIN [TIMEOUT_S]" (TIMEOUT_S default 10, in (0, 3600]) and joins the domain. 0 with
 * the participant and the timeout; else the exit code: 2 on bad arguments (said with `usage`),
 * 1 when the participant cannot be made. */
int start_client(int argc, char** argv, const char* usage, dds_entity_t* participant,
                 dds_duration_t* timeout);

/* The QoS of tgm's topics (config/fastdds_profiles.xml), as a reader or writer of another
 * vendor needs them to match: reliability, durability, history depth (0: KEEP_ALL) and, where
 * tgm's endpoints ask for them, a 100 ms automatic liveliness lease and a 100 ms deadline. */
typedef struct {
  bool reliable;
  bool transient_local;
  int depth;
  bool liveliness;
  bool deadline;
} topic_qos;

/* A reader, or a writer, of topic `name`; negative, and said, when the topic or the endpoint
 * cannot be made. */
dds_entity_t endpoint(dds_entity_t participant, const dds_topic_descriptor_t* type,
                      const char* name, topic_qos q, bool writer);

/* tgm_state's reader (RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 1: a late joiner gets the current
 * state at once; no deadline or liveliness asked, the writer offers stricter ones), and the
 * request writer with its reply reader (RELIABLE, VOLATILE; tgm's request readers want a
 * liveliness lease of at most 100 ms). False, and said, when one cannot be made. */
bool state_and_request_endpoints(dds_entity_t participant, dds_entity_t* state_reader,
                                 dds_entity_t* request_writer, dds_entity_t* reply_reader);

/* For take_until: a state of interpolator 0, copied to context. */
bool any_state(const void* sample, void* context);

/* Takes samples from `reader` one at a time until `accept(sample, context)` returns true for
 * one with valid data, or the deadline passes. */
bool take_until(dds_entity_t reader, dds_time_t deadline,
                bool (*accept)(const void* sample, void* context), void* context);

/* Waits until every one of the `n` endpoints has matched a peer (a writer a reader, a reader
 * a writer): written before, a sample is lost. False at the deadline. */
bool wait_matched(const dds_entity_t* endpoints, int n, dds_time_t deadline);

/* A request of `client` to interpolator 0, every field not named 0. */
tgm_msg_Request new_request(const char* client, uint64_t id, tgm_msg_ClientRole role,
                            tgm_msg_RequestKind kind, uint64_t service_instance);

/* Writes `r` and takes its reply (the one with its request_id and client_name) into `reply`;
 * without one, writes it again (the same id; Request.attempt counts the writes) after 0.5 s,
 * then after twice the last wait, as tgm's own clients do: the service executes it once and
 * answers a repeat with its first reply. A match seen by the writer is its own view: the
 * service's reader may learn of this writer later and drop what came before (VOLATILE), one
 * write in three on one host. Prints the reply; false without one by the deadline. */
bool request(dds_entity_t writer, dds_entity_t reply_reader, tgm_msg_Request* r,
             tgm_msg_Reply* reply, dds_time_t deadline);

#endif
