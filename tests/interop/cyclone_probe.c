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
#include <stdio.h>
#include <string.h>

/* The generated types (TGM_PROBE_TYPES): of idl/tgm.idl, or of an older version's IDL
 * (TGM_PROBE_BEFORE_DIGEST: 0.2.0's, without InterpolatorState.machine_digest). */
#include "cyclone_common.h"

static const char kClientName[] = "cyclone-probe";

/* A state of interpolator 0 at Rel_Speed 0.5, copied to context. */
static bool half_speed(const void* sample, void* context) {
  const tgm_msg_InterpolatorState* s = sample;
  return s->rel_speed == 0.5 && any_state(sample, context);
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
  dds_entity_t participant = 0;
  dds_duration_t timeout = 0;
  const int started =
      start_client(argc, argv, "tgm_cyclone_probe DOMAIN [TIMEOUT_S]", &participant, &timeout);
  if (started != 0) return started;

  /* QoS as tgm's endpoints (config/fastdds_profiles.xml); tgm_setpoints: BEST_EFFORT, VOLATILE,
   * KEEP_LAST 1 (a late setpoint is of no use). */
  dds_entity_t state_reader = 0;
  dds_entity_t request_writer = 0;
  dds_entity_t reply_reader = 0;
  const dds_entity_t setpoints_reader = endpoint(participant, &tgm_msg_Setpoints_desc,
                                                 "tgm_setpoints", (topic_qos){.depth = 1}, false);
  if (!state_and_request_endpoints(participant, &state_reader, &request_writer, &reply_reader) ||
      setpoints_reader < 0) {
    return 1;
  }

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
  const dds_entity_t requests[2] = {request_writer, reply_reader};
  if (!wait_matched(requests, 2, dds_time() + timeout)) {
    return fail("request", "tgm_request or tgm_reply did not match");
  }
  tgm_msg_Request r = new_request(kClientName, 1, tgm_msg_CLIENT_ROLE_PLC,
                                  tgm_msg_REQUEST_KIND_WRITE_REL_SPEED, s.service_instance);
  r.value = 0.5;
  tgm_msg_Reply reply;
  if (!request(request_writer, reply_reader, &r, &reply, dds_time() + timeout)) {
    return fail("reply", "no reply to the Rel_Speed write");
  }

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
