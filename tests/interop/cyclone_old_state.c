/* A stand-in for an older tgm-service: writes interpolator 0's state in the layout of the IDL
 * it is built from (tgm-0.2.0.idl: without the fields appended since), the way the service
 * writes it (tgm_state: RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 1, a 100 ms liveliness lease and
 * deadline), so that a test can show what this version's clients make of an older service's samples
 * (an HMI upgraded before its service).
 *
 * usage: tgm_cyclone_old_state DOMAIN [TIMEOUT_S]
 *
 * Writes a state every 20 ms (cycle_counter counting up) for TIMEOUT_S seconds (default 10),
 * then exits 0; 1 when an endpoint cannot be made, 2 on bad arguments. */
#include <stdio.h>
#include <string.h>

#include "cyclone_common.h"

int main(int argc, char** argv) {
  dds_entity_t participant = 0;
  dds_duration_t timeout = 0;
  const int started =
      start_client(argc, argv, "tgm_cyclone_old_state DOMAIN [TIMEOUT_S]", &participant, &timeout);
  if (started != 0) return started;
  const dds_entity_t writer = endpoint(participant, &tgm_msg_InterpolatorState_desc, "tgm_state",
                                       (topic_qos){.reliable = true,
                                                   .transient_local = true,
                                                   .depth = 1,
                                                   .liveliness = true,
                                                   .deadline = true},
                                       true);
  if (writer < 0) return 1;

  static tgm_msg_InterpolatorState s; /* 4 KB: static, zeroed */
  s.interpolator = 0;
  s.number = 0;
  s.number_axes = 3;
  s.buffer_size = 10000;
  s.rel_speed = 1.0;
  s.cycle_time_us = 500;
  s.service_instance = 0x1d5e41ceULL;
  s.free_buffer_slots = 10000;
  s.plc_setup = 1;
  for (int i = 0; i < 3; ++i) s.ratio[i] = 1000.0;
  snprintf(s.axis_letters, sizeof s.axis_letters, "XYZ");
  const dds_time_t until = dds_time() + timeout;
  while (dds_time() < until) {
    ++s.cycle_counter;
    const dds_return_t wrote = dds_write(writer, &s);
    if (wrote != DDS_RETCODE_OK) return fail("state", dds_strretcode(wrote));
    dds_sleepfor(DDS_MSECS(20));
  }
  dds_delete(participant);
  return 0;
}
