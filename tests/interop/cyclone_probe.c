/* A client of tgm-service written against Eclipse Cyclone DDS, not Fast DDS: the proof that
 * the topics match another vendor (idl/tgm.idl: every struct @final, no type objects; DESIGN.md
 * section 6). The types come from idl/tgm.idl through Cyclone's own IDL compiler (idlc).
 *
 * usage: tgm_cyclone_probe DOMAIN [TIMEOUT_S]
 *
 * 1. reads interpolator 0's state (tgm_state, a late joiner: TRANSIENT_LOCAL) and prints it;
 * 2. as a PLC, writes Rel_Speed = 0.5 (tgm_request) and waits for the service's reply
 *    (tgm_reply, the one with this request's id and client name), writing it again while
 *    there is none;
 * 3. waits for a state that shows Rel_Speed 0.5;
 * 4. reads a setpoint of interpolator 0 (tgm_setpoints, BEST_EFFORT: what a drive follows).
 * Each step prints one line; exit code 0 when all four worked, 1 naming the step that did
 * not within TIMEOUT_S seconds (default 10), 2 on bad arguments. */
#include <inttypes.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dds/dds.h"
/* The generated types: of idl/tgm.idl, or of an older version's IDL (TGM_PROBE_BEFORE_DIGEST:
 * 0.2.0's, without InterpolatorState.machine_digest). */
#include TGM_PROBE_TYPES

static const char kClientName[] = "cyclone-probe";

static int fail(const char* step, const char* why) {
  fprintf(stderr, "tgm_cyclone_probe: %s: %s\n", step, why);
  return 1;
}

/* A reader, or a writer, of topic `name` with `qos`; negative, and said, when the topic or the
 * endpoint cannot be made. */
static dds_entity_t endpoint(dds_entity_t participant, const dds_topic_descriptor_t* type,
                             const char* name, const dds_qos_t* qos, bool writer) {
  const dds_entity_t topic = dds_create_topic(participant, type, name, NULL, NULL);
  if (topic < 0) {
    fail(name, dds_strretcode(topic));
    return topic;
  }
  const dds_entity_t e = writer ? dds_create_writer(participant, topic, qos, NULL)
                                : dds_create_reader(participant, topic, qos, NULL);
  if (e < 0) fail(name, dds_strretcode(e));
  return e;
}

/* Takes samples from `reader` one at a time until `accept(sample, context)` returns true for
 * one with valid data, or the deadline passes. */
static bool take_until(dds_entity_t reader, dds_time_t deadline,
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

/* A state of interpolator 0, copied to context. */
static bool any_state(const void* sample, void* context) {
  const tgm_msg_InterpolatorState* s = sample;
  if (s->interpolator != 0) return false;
  *(tgm_msg_InterpolatorState*)context = *s;
  return true;
}

/* A state of interpolator 0 at Rel_Speed 0.5, copied to context. */
static bool half_speed(const void* sample, void* context) {
  const tgm_msg_InterpolatorState* s = sample;
  return s->rel_speed == 0.5 && any_state(sample, context);
}

/* The reply to the request in context, printed. */
static bool reply_to(const void* sample, void* context) {
  const tgm_msg_Reply* a = sample;
  const tgm_msg_Request* r = context;
  if (a->request_id != r->request_id || strcmp(a->client_name, r->client_name) != 0) return false;
  printf("reply: request %" PRIu64 " accepted %d, code %d, reason '%s', cycle %" PRIu64
         " (writes %u)\n",
         a->request_id, (int)a->accepted, (int)a->code, a->reason, a->cycle_counter,
         (unsigned)r->attempt);
  return true;
}

/* A setpoint of interpolator 0, printed. */
static bool setpoint(const void* sample, void* context) {
  (void)context;
  const tgm_msg_Setpoints* p = sample;
  if (p->interpolator != 0) return false;
  printf("setpoints: cycle %" PRIu64 ", Position %g %g %g mm, PositionInc %" PRId64 " %" PRId64
         " %" PRId64 "\n",
         p->cycle_counter, p->position[0], p->position[1], p->position[2], p->position_inc[0],
         p->position_inc[1], p->position_inc[2]);
  return true;
}

int main(int argc, char** argv) {
  if (argc < 2 || argc > 3) {
    fprintf(stderr, "usage: tgm_cyclone_probe DOMAIN [TIMEOUT_S]\n");
    return 2;
  }
  char* end = NULL;
  const long domain = strtol(argv[1], &end, 10);
  if (*argv[1] == '\0' || *end != '\0' || domain < 0 || domain > 232) {
    fprintf(stderr, "tgm_cyclone_probe: DOMAIN must be 0..232, not '%s'\n", argv[1]);
    return 2;
  }
  double timeout_s = 10.0;
  if (argc == 3) {
    timeout_s = strtod(argv[2], &end);
    if (*argv[2] == '\0' || *end != '\0' || !(timeout_s > 0.0 && timeout_s <= 3600.0)) {
      fprintf(stderr, "tgm_cyclone_probe: TIMEOUT_S must be a number in (0, 3600], not '%s'\n",
              argv[2]);
      return 2;
    }
  }
  const dds_duration_t timeout = (dds_duration_t)(timeout_s * 1e9);

  const dds_entity_t participant = dds_create_participant((dds_domainid_t)domain, NULL, NULL);
  if (participant < 0) return fail("participant", dds_strretcode(participant));

  /* tgm_state: RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 1, as tgm's readers; no deadline or
   * liveliness requested (the writer's offers are stricter than the defaults ask). */
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_durability(qos, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 1);
  const dds_entity_t state_reader =
      endpoint(participant, &tgm_msg_InterpolatorState_desc, "tgm_state", qos, false);
  dds_delete_qos(qos);
  if (state_reader < 0) return 1;

  /* tgm_setpoints: BEST_EFFORT, VOLATILE, KEEP_LAST 1 (a late setpoint is of no use). */
  qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 1);
  const dds_entity_t setpoints_reader =
      endpoint(participant, &tgm_msg_Setpoints_desc, "tgm_setpoints", qos, false);
  dds_delete_qos(qos);
  if (setpoints_reader < 0) return 1;

  /* Requests: tgm's request readers want a liveliness lease of at most 100 ms. */
  qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_durability(qos, DDS_DURABILITY_VOLATILE);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 100);
  dds_qset_liveliness(qos, DDS_LIVELINESS_AUTOMATIC, DDS_MSECS(100));
  const dds_entity_t request_writer =
      endpoint(participant, &tgm_msg_Request_desc, "tgm_request", qos, true);
  const dds_entity_t reply_reader =
      endpoint(participant, &tgm_msg_Reply_desc, "tgm_reply", qos, false);
  dds_delete_qos(qos);
  if (request_writer < 0 || reply_reader < 0) return 1;

  /* 1. The state. */
  tgm_msg_InterpolatorState s;
  if (!take_until(state_reader, dds_time() + timeout, any_state, &s)) {
    return fail("state", "no state of interpolator 0 from tgm-service");
  }
  printf("state: interpolator %u, status %d, cycle %" PRIu64
         " of %d us, axes %s (Number_Axes %d), ",
         (unsigned)s.interpolator, (int)s.status, s.cycle_counter, (int)s.cycle_time_us,
         s.axis_letters, (int)s.number_axes);
#ifndef TGM_PROBE_BEFORE_DIGEST
  printf("machine digest %016" PRIx64 ", ", s.machine_digest);
#endif
  printf("service instance %016" PRIx64 ", Rel_Speed %g\n", s.service_instance, s.rel_speed);
  fflush(stdout);

  /* 2. A request once the service's request reader and its reply writer have matched
   * (written before, it would be lost). */
  const dds_time_t match_by = dds_time() + timeout;
  for (;;) {
    dds_publication_matched_status_t pub;
    dds_subscription_matched_status_t sub;
    if (dds_get_publication_matched_status(request_writer, &pub) == DDS_RETCODE_OK &&
        dds_get_subscription_matched_status(reply_reader, &sub) == DDS_RETCODE_OK &&
        pub.current_count > 0 && sub.current_count > 0) {
      break;
    }
    if (dds_time() >= match_by) return fail("request", "tgm_request or tgm_reply did not match");
    dds_sleepfor(DDS_MSECS(10));
  }
  tgm_msg_Request r;
  memset(&r, 0, sizeof r);
  r.request_id = 1;
  r.role = tgm_msg_CLIENT_ROLE_PLC;
  snprintf(r.client_name, sizeof r.client_name, "%s", kClientName);
  r.interpolator = 0;
  r.kind = tgm_msg_REQUEST_KIND_WRITE_REL_SPEED;
  r.value = 0.5;
  r.service_instance = s.service_instance;
  /* Without a reply, the same request again (the same id; Request.attempt counts the writes)
   * after 0.5 s, then after twice the last wait, as tgm's own clients do: the service executes
   * it once and answers a repeat with its first reply. The match seen here is the writer's
   * view: the service's reader may learn of this writer later, and drops what was written
   * before it did (VOLATILE). One write in three was lost that way on one host. */
  const dds_time_t reply_by = dds_time() + timeout;
  dds_duration_t wait = DDS_MSECS(500);
  bool replied = false;
  for (r.attempt = 1; !replied && dds_time() < reply_by; ++r.attempt, wait *= 2) {
    const dds_return_t wrote = dds_write(request_writer, &r);
    if (wrote != DDS_RETCODE_OK) return fail("request", dds_strretcode(wrote));
    const dds_time_t until = dds_time() + wait;
    replied = take_until(reply_reader, until < reply_by ? until : reply_by, reply_to, &r);
  }
  if (!replied) return fail("reply", "no reply to the Rel_Speed write");
  fflush(stdout);

  /* 3. The state shows it. */
  if (!take_until(state_reader, dds_time() + timeout, half_speed, &s)) {
    return fail("state after the write", "no state with Rel_Speed 0.5");
  }
  printf("state: Rel_Speed %g at cycle %" PRIu64 "\n", s.rel_speed, s.cycle_counter);
  fflush(stdout);

  /* 4. A setpoint. */
  if (!take_until(setpoints_reader, dds_time() + timeout, setpoint, NULL)) {
    return fail("setpoints", "no setpoint of interpolator 0");
  }
  dds_delete(participant);
  return 0;
}
