#include "cyclone_common.h"

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Set by parse_args: the program's name in its messages. */
static const char* program_name = "tgm_cyclone";

int fail(const char* step, const char* why) {
  fprintf(stderr, "%s: %s: %s\n", program_name, step, why);
  return 1;
}

int start_client(int argc, char** argv, const char* usage, dds_entity_t* participant,
                 dds_duration_t* timeout) {
  program_name = argv[0];
  if (strrchr(program_name, '/') != NULL) program_name = strrchr(program_name, '/') + 1;
  if (argc < 2 || argc > 3) {
    fprintf(stderr, "usage: %s\n", usage);
    return 2;
  }
  char* end = NULL;
  const long domain = strtol(argv[1], &end, 10);
  if (*argv[1] == '\0' || *end != '\0' || domain < 0 || domain > 232) {
    fprintf(stderr, "%s: DOMAIN must be 0..232, not '%s'\n", program_name, argv[1]);
    return 2;
  }
  double timeout_s = 10.0;
  if (argc == 3) {
    timeout_s = strtod(argv[2], &end);
    if (*argv[2] == '\0' || *end != '\0' || !(timeout_s > 0.0 && timeout_s <= 3600.0)) {
      fprintf(stderr, "%s: TIMEOUT_S must be a number in (0, 3600], not '%s'\n", program_name,
              argv[2]);
      return 2;
    }
  }
  *timeout = (dds_duration_t)(timeout_s * 1e9);
  *participant = dds_create_participant((dds_domainid_t)domain, NULL, NULL);
  if (*participant < 0) return fail("participant", dds_strretcode(*participant));
  return 0;
}

dds_entity_t endpoint(dds_entity_t participant, const dds_topic_descriptor_t* type,
                      const char* name, topic_qos q, bool writer) {
  const dds_entity_t topic = dds_create_topic(participant, type, name, NULL, NULL);
  if (topic < 0) {
    fail(name, dds_strretcode(topic));
    return topic;
  }
  dds_qos_t* qos = dds_create_qos();
  if (q.reliable) {
    dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  } else {
    dds_qset_reliability(qos, DDS_RELIABILITY_BEST_EFFORT, 0);
  }
  dds_qset_durability(qos,
                      q.transient_local ? DDS_DURABILITY_TRANSIENT_LOCAL : DDS_DURABILITY_VOLATILE);
  if (q.depth > 0) {
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, q.depth);
  } else {
    dds_qset_history(qos, DDS_HISTORY_KEEP_ALL, 0);
  }
  if (q.liveliness) dds_qset_liveliness(qos, DDS_LIVELINESS_AUTOMATIC, DDS_MSECS(100));
  if (q.deadline) dds_qset_deadline(qos, DDS_MSECS(100));
  const dds_entity_t e = writer ? dds_create_writer(participant, topic, qos, NULL)
                                : dds_create_reader(participant, topic, qos, NULL);
  dds_delete_qos(qos);
  if (e < 0) fail(name, dds_strretcode(e));
  return e;
}

bool state_and_request_endpoints(dds_entity_t participant, dds_entity_t* state_reader,
                                 dds_entity_t* request_writer, dds_entity_t* reply_reader) {
  *state_reader =
      endpoint(participant, &tgm_msg_InterpolatorState_desc, "tgm_state",
               (topic_qos){.reliable = true, .transient_local = true, .depth = 1}, false);
  const topic_qos request_qos = {.reliable = true, .depth = 100, .liveliness = true};
  *request_writer = endpoint(participant, &tgm_msg_Request_desc, "tgm_request", request_qos, true);
  *reply_reader = endpoint(participant, &tgm_msg_Reply_desc, "tgm_reply", request_qos, false);
  return *state_reader >= 0 && *request_writer >= 0 && *reply_reader >= 0;
}

bool any_state(const void* sample, void* context) {
  const tgm_msg_InterpolatorState* s = sample;
  if (s->interpolator != 0) return false;
  *(tgm_msg_InterpolatorState*)context = *s;
  return true;
}

bool take_until(dds_entity_t reader, dds_time_t deadline,
                bool (*accept)(const void* sample, void* context), void* context) {
  while (dds_time() < deadline) {
    void* samples[1] = {NULL};
    dds_sample_info_t info[1];
    const int32_t n = dds_take(reader, samples, info, 1, 1);
    if (n <= 0) {
      dds_sleepfor(DDS_MSECS(10));
      continue;
    }
    const bool ok = info[0].valid_data && accept(samples[0], context);
    dds_return_loan(reader, samples, n);
    if (ok) return true;
  }
  return false;
}

bool wait_matched(const dds_entity_t* endpoints, int n, dds_time_t deadline) {
  for (;;) {
    int matched = 0;
    for (int i = 0; i < n; ++i) {
      dds_publication_matched_status_t pub;
      dds_subscription_matched_status_t sub;
      if (dds_get_publication_matched_status(endpoints[i], &pub) == DDS_RETCODE_OK) {
        matched += pub.current_count > 0;
      } else if (dds_get_subscription_matched_status(endpoints[i], &sub) == DDS_RETCODE_OK) {
        matched += sub.current_count > 0;
      }
    }
    if (matched == n) return true;
    if (dds_time() >= deadline) return false;
    dds_sleepfor(DDS_MSECS(10));
  }
}

tgm_msg_Request new_request(const char* client, uint64_t id, tgm_msg_ClientRole role,
                            tgm_msg_RequestKind kind, uint64_t service_instance) {
  tgm_msg_Request r;
  memset(&r, 0, sizeof r);
  r.request_id = id;
  r.role = role;
  snprintf(r.client_name, sizeof r.client_name, "%s", client);
  r.interpolator = 0;
  r.kind = kind;
  r.service_instance = service_instance;
  return r;
}

/* The reply to the request in context[0], copied to context[1]. */
static bool reply_to(const void* sample, void* context) {
  const tgm_msg_Reply* a = sample;
  void** c = context;
  const tgm_msg_Request* r = c[0];
  if (a->request_id != r->request_id || strcmp(a->client_name, r->client_name) != 0) return false;
  *(tgm_msg_Reply*)c[1] = *a;
  return true;
}

bool request(dds_entity_t writer, dds_entity_t reply_reader, tgm_msg_Request* r,
             tgm_msg_Reply* reply, dds_time_t deadline) {
  void* context[2] = {r, reply};
  dds_duration_t wait = DDS_MSECS(500);
  bool replied = false;
  for (r->attempt = 1; !replied && dds_time() < deadline; ++r->attempt, wait *= 2) {
    const dds_return_t wrote = dds_write(writer, r);
    if (wrote != DDS_RETCODE_OK) {
      fail("request", dds_strretcode(wrote));
      return false;
    }
    const dds_time_t until = dds_time() + wait;
    replied = take_until(reply_reader, until < deadline ? until : deadline, reply_to, context);
  }
  if (!replied) return false;
  printf("reply: request %" PRIu64 " accepted %d, code %d, reason '%s', cycle %" PRIu64
         " (writes %u)\n",
         reply->request_id, (int)reply->accepted, (int)reply->code, reply->reason,
         reply->cycle_counter, (unsigned)(r->attempt - 1));
  fflush(stdout);
  return true;
}
