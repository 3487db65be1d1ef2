/* An HMI and a PLC of tgm-service in one client written against Eclipse Cyclone DDS, not Fast
 * DDS: a program streamed, started, its M-function acknowledged and its message read, over the
 * topics tgm-hmi and tgm-plc use (tgm_program, tgm_request / tgm_reply, tgm_event,
 * tgm_message, tgm_state), with the types Cyclone's idlc made from idl/tgm.idl.
 *
 * usage: tgm_cyclone_run DOMAIN [TIMEOUT_S]
 *
 * The program, as `tgm-hmi compile --dump jsonl` gives it for interpolator 0 (XYZ) of
 *   G90 G1 X5 F600 / M3 / M29 (hello from cyclone) / G1 X0 / M30
 * is five records, built here by hand:
 * 1. reads interpolator 0's state (a late joiner) and waits for every endpoint to match;
 * 2. as the PLC, reports its setup done (plc.setup_before_start makes a start wait for it);
 * 3. as the HMI, streams the program in one chunk (tgm_program) and waits for a state that
 *    shows all five records taken (next_sequence), writing the chunk again while none does;
 * 4. as the HMI, starts it;
 * 5. as the PLC, takes the event of M3 (tgm_event), reads the position the motion stopped at
 *    from the state, and acknowledges it (M_Func = 0, naming the M-function and its count);
 * 6. takes the program's M29 message (tgm_message);
 * 7. waits for the end (Status 3) back at X 0.
 * Each step prints a line; exit code 0 when all worked, 1 naming the step that did not within
 * TIMEOUT_S seconds (default 10) each, 2 on bad arguments. */
#include <inttypes.h>
#include <stdio.h>
#include <string.h>

#include "cyclone_common.h"

static const char kClientName[] = "cyclone-run";
static const uint32_t kProgramId = 0x43594331; /* "CYC1" */
static const char kText[] = "hello from cyclone";

/* A state showing this program loaded whole. */
static bool loaded(const void* sample, void* context) {
  const tgm_msg_InterpolatorState* s = sample;
  return s->program_id == kProgramId && s->next_sequence == 5 && any_state(sample, context);
}

/* A state with M3 waiting for the PLC. */
static bool at_m3(const void* sample, void* context) {
  const tgm_msg_InterpolatorState* s = sample;
  return s->m_func == 3 && any_state(sample, context);
}

/* A state at the program's end. */
static bool ended(const void* sample, void* context) {
  const tgm_msg_InterpolatorState* s = sample;
  return s->program_id == kProgramId && s->status == 3 && any_state(sample, context);
}

/* The event that hands M3 to the PLC, copied to context. */
static bool m3_event(const void* sample, void* context) {
  const tgm_msg_InterpolatorEvent* e = sample;
  if (e->interpolator != 0 || e->m_func != 3) return false;
  *(tgm_msg_InterpolatorEvent*)context = *e;
  return true;
}

/* The program's M29 message, copied to context. */
static bool message(const void* sample, void* context) {
  const tgm_msg_Message* m = sample;
  if (m->interpolator != 0 || m->program_id != kProgramId || strcmp(m->text, kText) != 0) {
    return false;
  }
  *(tgm_msg_Message*)context = *m;
  return true;
}

/* A motion record of interpolator 0's XYZ: G1 to X = x at F600. */
static tgm_msg_Segment move_to(double x, int32_t line) {
  tgm_msg_Segment g;
  memset(&g, 0, sizeof g);
  g.type = 1;
  g.plane = 17;
  g.compensation = 40;
  g.line = line;
  g.m = -1;
  g.end[0] = x;
  g.feed_mm_per_min = 600.0;
  return g;
}

/* An M-function record: m_kind 1 normal (the motion waits for the PLC), 4 program end. */
static tgm_msg_Segment m_function(int32_t m, uint8_t kind, int32_t line, double x) {
  tgm_msg_Segment g = move_to(x, line);
  g.type = 5;
  g.m_kind = kind;
  g.m = m;
  return g;
}

/* Request `r` of this client, written until answered: true when accepted; else false, the
 * step and the reason said. */
static bool accepted(dds_entity_t writer, dds_entity_t reply_reader, tgm_msg_Request r,
                     const char* step, dds_duration_t timeout) {
  tgm_msg_Reply reply;
  if (!request(writer, reply_reader, &r, &reply, dds_time() + timeout)) {
    fail(step, "no reply");
    return false;
  }
  if (!reply.accepted) fail(step, reply.reason);
  return reply.accepted;
}

int main(int argc, char** argv) {
  dds_entity_t participant = 0;
  dds_duration_t timeout = 0;
  const int started =
      start_client(argc, argv, "tgm_cyclone_run DOMAIN [TIMEOUT_S]", &participant, &timeout);
  if (started != 0) return started;

  /* QoS as tgm's endpoints (config/fastdds_profiles.xml): tgm_event RELIABLE, VOLATILE,
   * KEEP_LAST 100; tgm_message RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 32; tgm_program RELIABLE,
   * VOLATILE, KEEP_ALL, with the 100 ms liveliness lease tgm's program reader asks for. */
  dds_entity_t state_reader = 0;
  dds_entity_t request_writer = 0;
  dds_entity_t reply_reader = 0;
  const bool made =
      state_and_request_endpoints(participant, &state_reader, &request_writer, &reply_reader);
  const dds_entity_t event_reader =
      endpoint(participant, &tgm_msg_InterpolatorEvent_desc, "tgm_event",
               (topic_qos){.reliable = true, .depth = 100}, false);
  const dds_entity_t message_reader =
      endpoint(participant, &tgm_msg_Message_desc, "tgm_message",
               (topic_qos){.reliable = true, .transient_local = true, .depth = 32}, false);
  const dds_entity_t program_writer =
      endpoint(participant, &tgm_msg_ProgramChunk_desc, "tgm_program",
               (topic_qos){.reliable = true, .depth = 0, .liveliness = true}, true);
  if (!made || event_reader < 0 || message_reader < 0 || program_writer < 0) return 1;

  /* 1. The state, and every endpoint matched: an event or a chunk written before is lost. */
  tgm_msg_InterpolatorState s;
  if (!take_until(state_reader, dds_time() + timeout, any_state, &s)) {
    return fail("state", "no state of interpolator 0 from tgm-service");
  }
  printf("state: status %d, program %" PRIu32 ", axes %s\n", (int)s.status, s.program_id,
         s.axis_letters);
  fflush(stdout);
  const uint64_t instance = s.service_instance;
  const dds_entity_t endpoints[4] = {request_writer, reply_reader, program_writer, event_reader};
  if (!wait_matched(endpoints, 4, dds_time() + timeout)) {
    return fail("match", "tgm_request, tgm_reply, tgm_program or tgm_event did not match");
  }

  /* 2. The PLC's setup. */
  if (!accepted(request_writer, reply_reader,
                new_request(kClientName, 1, tgm_msg_CLIENT_ROLE_PLC,
                            tgm_msg_REQUEST_KIND_PLC_SETUP_DONE, instance),
                "setup", timeout)) {
    return 1;
  }

  /* 3. The program, one chunk, written again (the same sequence number: the service drops a
   * chunk it has taken) while no state shows it taken. */
  tgm_msg_Segment records[5] = {move_to(5.0, 1), m_function(3, 1, 2, 5.0), move_to(5.0, 3),
                                move_to(0.0, 4), m_function(30, 4, 5, 0.0)};
  records[2].type = 6;
  snprintf(records[2].text, sizeof records[2].text, "%s", kText);
  tgm_msg_ProgramChunk chunk;
  memset(&chunk, 0, sizeof chunk);
  chunk.interpolator = 0;
  chunk.program_id = kProgramId;
  chunk.sequence_number = 0;
  chunk.segments._buffer = records;
  chunk.segments._length = chunk.segments._maximum = 5;
  chunk.segments._release = false;
  chunk.end_of_program = true;
  chunk.number_axes = 3;
  snprintf(chunk.axis_letters, sizeof chunk.axis_letters, "XYZ");
  const dds_time_t load_by = dds_time() + timeout;
  dds_duration_t wait = DDS_MSECS(500);
  bool taken = false;
  unsigned writes = 0;
  for (; !taken && dds_time() < load_by; wait *= 2) {
    const dds_return_t wrote = dds_write(program_writer, &chunk);
    if (wrote != DDS_RETCODE_OK) return fail("program", dds_strretcode(wrote));
    ++writes;
    const dds_time_t until = dds_time() + wait;
    taken = take_until(state_reader, until < load_by ? until : load_by, loaded, &s);
  }
  if (!taken) return fail("program", "no state shows the five records taken");
  printf("program: %" PRIu64 " records of program %" PRIu32 " taken, %d buffered (writes %u)\n",
         s.next_sequence, s.program_id, (int)s.buffered_segments, writes);
  fflush(stdout);

  /* 4. Start. */
  if (!accepted(request_writer, reply_reader,
                new_request(kClientName, 2, tgm_msg_CLIENT_ROLE_HMI, tgm_msg_REQUEST_KIND_START,
                            instance),
                "start", timeout)) {
    return 1;
  }

  /* 5. M3: the event, the position it stopped at, the acknowledgement. */
  tgm_msg_InterpolatorEvent e;
  if (!take_until(event_reader, dds_time() + timeout, m3_event, &e)) {
    return fail("event", "no event with M_Func 3");
  }
  printf("event: M_Func %d (count %" PRIu32 ", line %d), Run_Flag section state %d\n",
         (int)e.m_func, e.m_func_count, (int)e.m_func_line, (int)(e.run_flag & 0xffff));
  fflush(stdout);
  if (!take_until(state_reader, dds_time() + timeout, at_m3, &s)) {
    return fail("state at M3", "no state with M_Func 3");
  }
  printf("state at M3: Orig_Position X %g, Act_Speed %g mm/min\n", s.orig_position[0], s.act_speed);
  fflush(stdout);
  tgm_msg_Request ack = new_request(kClientName, 3, tgm_msg_CLIENT_ROLE_PLC,
                                    tgm_msg_REQUEST_KIND_WRITE_M_FUNC, instance);
  ack.value = 0.0;
  ack.m_func_acknowledged = 3;
  ack.m_func_count_acknowledged = e.m_func_count;
  if (!accepted(request_writer, reply_reader, ack, "acknowledge", timeout)) return 1;

  /* 6. The M29 message. */
  tgm_msg_Message m;
  if (!take_until(message_reader, dds_time() + timeout, message, &m)) {
    return fail("message", "no message 'hello from cyclone' of the program");
  }
  printf("message: '%s', severity %d, line %d\n", m.text, (int)m.severity, (int)m.source_line);
  fflush(stdout);

  /* 7. The end. */
  if (!take_until(state_reader, dds_time() + timeout, ended, &s)) {
    return fail("end", "no state with Status 3 (program end)");
  }
  printf("state: status %d, Orig_Position X %g, Act_Part %d, M-functions %" PRIu32 "\n",
         (int)s.status, s.orig_position[0], (int)s.act_part, s.m_func_count);
  dds_delete(participant);
  return 0;
}
