#!/usr/bin/env bash
# Process-level benchmarks of tgm-service (BENCHMARKS.md, section "Service"):
#   1. M-function handshake round trip (service writes the event with M_Func, tgm-plc acks, service
#      takes the ack) against a raw Fast DDS ping-pong of the same samples and QoS
#      (InterpolatorEvent -> Request; WaitSet and listener mode) in the same run;
#   2. program streaming rate into a running service;
#   3. cycle lateness at the config's cycle time with three interpolators running programs and
#      an HMI subscribed (tgm-hmi watch).
# usage: tests/bench/service_bench.sh BUILD_DIR [SECONDS_FOR_3 (default 30)]
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:?usage: service_bench.sh BUILD_DIR [SECONDS]}
seconds=${2:-30}
m_count=${M_COUNT:-2000}
# DDS_PRIO=N: run the service's DDS threads and the PLC emulator SCHED_FIFO at N (0 = normal).
dds_prio=${DDS_PRIO:-0}
svc_prio=(); plc_prio=()
if ((dds_prio > 0)); then svc_prio=(--dds-priority "$dds_prio"); plc_prio=(--rt-priority "$dds_prio"); fi
# SECURITY_DIR=DIR: all three processes with DDS Security (the raw ping-pong stays without).
# SVC_ARGS / PLC_ARGS: extra options for tgm-service / tgm-plc in part 1 (word-split).
read -r -a svc_extra <<< "${SVC_ARGS:-}"
read -r -a plc_extra <<< "${PLC_ARGS:-}"
# DOMAIN=N: the service on domain N, the raw ping-pongs on N+1 and N+2 (default 5: clear of
# the tests' domains 10..99 and of tgm's default 0)
domain=${DOMAIN:-5}
tmp=$(mktemp -d)
pids=()
# SIGINT is the clean stop; a process that got it before it had started its own handling (a
# failure right after its start: the signal reached the shell's child before exec) is killed
# after 5 s rather than left serving the domain.
stop_pid() {
  kill -INT "$1" 2>/dev/null || return 0
  for _ in $(seq 50); do kill -0 "$1" 2>/dev/null || break; sleep 0.1; done
  kill -KILL "$1" 2>/dev/null || true
  wait "$1" 2>/dev/null || true
}
cleanup() {
  for p in "${pids[@]}"; do stop_pid "$p"; done
  wait 2>/dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT

# The default machine with an absolute profiles path, this benchmark's domain and a 100,000-record
# buffer on interpolator 0 (the streaming run needs the whole program in the buffer). No PLC
# setup before a start: the PLC here runs with --no-basic-params (it reports no setup then),
# and the stream benchmark loads programs without one.
sed -e "s|# profiles_file: fastdds_profiles.xml|profiles_file: $PWD/config/fastdds_profiles.xml|" \
    -e "s#domain_id: 0#domain_id: $domain#" \
    -e "s#setup_before_start: true#setup_before_start: false#" \
    -e "0,/buffer_size: 10000/s//buffer_size: 100000/" config/default.yaml > "$tmp/config.yaml"
cfg=(--config "$tmp/config.yaml")
# SECURITY_DIR=DIR: every process with DDS Security (config/security/tgm-security --out DIR).
[[ -n ${SECURITY_DIR:-} ]] && cfg+=(--security "$SECURITY_DIR")
svc=$build/service/tgm-service
plc=$build/client/tgm-plc
hmi=$build/client/tgm-hmi

stop_all() {
  for p in "${pids[@]}"; do stop_pid "$p"; done
  pids=()
}
json() { python3 -c "import json,sys; d=json.load(open('$1')); print($2)"; }

# ONLY_LATENESS=1: part 3 only. SVC_CPU=N: pin the service's cycle thread to CPU N (--cpu).
svc_cpu=(); [[ -n ${SVC_CPU:-} ]] && svc_cpu=(--cpu "$SVC_CPU")
if [[ -z ${ONLY_LATENESS:-} ]]; then
echo "== 1. M-function handshake: $m_count x (G1 X0.01, M51), tgm-plc acknowledges at once"
echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
for ((i = 0; i < m_count; ++i)); do printf 'G1 X0.01\nM51\n'; done > "$tmp/m.ngc"
echo "M2" >> "$tmp/m.ngc"
"$svc" "${cfg[@]}" "${svc_prio[@]}" "${svc_extra[@]}" --stats "$tmp/hs.json" --handshake-trace "$tmp/hs_svc.csv" \
  > "$tmp/svc1.log" 2>&1 & pids+=($!)
"$plc" "${cfg[@]}" "${plc_prio[@]}" "${plc_extra[@]}" --ack-delay 0 --quiet --no-basic-params --handshake-trace "$tmp/hs_plc.csv" \
  > "$tmp/plc1.log" 2>&1 & pids+=($!)
# The raw ping-pong (the event sample with the event QoS, answered by the Request with the request
# QoS; WaitSet and listener mode alternating in blocks of 500) runs while the handshake program
# runs (same load on the machine: the service's cycle and publisher threads, the HMI, the PLC),
# and alone after it. The goal compares with the faster mode of the concurrent run.
# RAW_DURING=0 (diagnosis only): no concurrent ping-pong, to see how much it slows the handshake.
raw_pid=
if [[ ${RAW_DURING:-1} != 0 ]]; then
  "$build/tests/bench/service/tgm_bench_state_pingpong" --sample event --mode both --count 30000 \
    --domain $((domain + 2)) --profiles "$PWD/config/fastdds_profiles.xml" > "$tmp/raw_during.log" 2>&1 &
  raw_pid=$!
else
  echo "(no concurrent raw ping-pong: RAW_DURING=0)" > "$tmp/raw_during.log"
fi
"$hmi" run "$tmp/m.ngc" "${cfg[@]}" --quiet --timeout 600 > "$tmp/hmi1.log" || echo "tgm-hmi run failed (exit $?)"
[[ -n $raw_pid ]] && { wait "$raw_pid" || true; }
stop_all
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
tail -n 3 "$tmp/hmi1.log"
echo "time stamps of every handshake (service and PLC, same clock):"
python3 tests/bench/service/handshake_trace.py "$tmp/hs_svc.csv" "$tmp/hs_plc.csv" --raw "$tmp/raw_during.log"
json "$tmp/hs.json" "'service handshake (event write with new M_Func -> ack taken): n %d, min %.1f us, median %.1f us, p99 %.1f us, max %.1f us' % (d['handshake_ns']['count'], d['handshake_ns']['min']/1e3, d['handshake_ns']['p50']/1e3, d['handshake_ns']['p99']/1e3, d['handshake_ns']['max']/1e3)"
echo "raw ping-pong while the handshake program ran:"
cat "$tmp/raw_during.log"
echo "raw ping-pong alone (event -> request, both modes):"
"$build/tests/bench/service/tgm_bench_state_pingpong" --sample event --mode both --count 10000 \
  --domain $((domain + 1)) --profiles "$PWD/config/fastdds_profiles.xml"
# The handshake is sporadic (one M-function every ~23 ms here), the ping-pong back to back; on a
# VM whose idle vCPUs halt, a sporadic exchange pays the wake-ups. Context, not the goal:
echo "raw ping-pong alone, paced like the handshake (one round trip every 20 ms; context only):"
"$build/tests/bench/service/tgm_bench_state_pingpong" --sample event --mode both --count 400 --block 50 \
  --warmup 20 --interval-us 20000 --domain $((domain + 1)) --profiles "$PWD/config/fastdds_profiles.xml"
echo "raw ping-pong alone, the former reference (state -> request, WaitSet; 1 and 2 state readers):"
"$build/tests/bench/service/tgm_bench_state_pingpong" --count 5000 --domain $((domain + 1)) \
  --profiles "$PWD/config/fastdds_profiles.xml"
"$build/tests/bench/service/tgm_bench_state_pingpong" --count 5000 --domain $((domain + 1)) --sinks 1 \
  --profiles "$PWD/config/fastdds_profiles.xml"

[[ -n ${ONLY_HANDSHAKE:-} ]] && exit 0
echo "== 2. program streaming rate (100,000 G1 records, 5 runs)"
"$svc" "${cfg[@]}" > "$tmp/svc2.log" 2>&1 & pids+=($!)
"$build/tests/bench/service/tgm_bench_stream" "${cfg[@]}" --records 100000 --runs 5
stop_all
fi

echo "== 3. cycle lateness, ${seconds} s: three interpolators running, tgm-hmi watch subscribed"
# A closed contour of short lines and arcs, repeated: keeps an interpolator moving.
{
  echo "F3000"
  for ((i = 0; i < 400; ++i)); do
    printf 'G1 X10\nG3 X5 Y5 I0 J5\nG1 Y10\nG3 X-5 Y5 I-5 J0\nG1 X-10\nG3 X-5 Y-5 I0 J-5\nG1 Y-10\nG3 X5 Y-5 I5 J0\n'
  done
  echo "M2"
} > "$tmp/loop.ngc"
"$svc" "${cfg[@]}" "${svc_cpu[@]}" --stats "$tmp/lat.json" --duration "$seconds" > "$tmp/svc3.log" 2>&1 & svc_pid=$!
sleep 0.5
grep -h "SCHED\|realtime" "$tmp/svc3.log" || true
"$plc" "${cfg[@]}" --quiet > "$tmp/plc3.log" 2>&1 & pids+=($!)
sleep 1
"$hmi" watch "${cfg[@]}" --interval 0.2 > /dev/null 2>&1 & pids+=($!)
for ip in 0 1 2; do
  "$hmi" run "$tmp/loop.ngc" "${cfg[@]}" --interpolator $ip --quiet --timeout "$((seconds - 3))" \
    > "$tmp/hmi3_$ip.log" 2>&1 & pids+=($!)
done
wait "$svc_pid" || true
stop_all
grep -h "stopping" "$tmp/svc3.log" || true
json "$tmp/lat.json" "'lateness over %d cycles of %d us: p50 %.1f us, p99 %.1f us, p99.9 %.1f us, max %.1f us, missed cycles %d; cycle work p50 %.1f us, p99.9 %.1f us, max %.1f us' % (d['cycles'], d['cycle_time_us'], d['lateness_ns']['p50']/1e3, d['lateness_ns']['p99']/1e3, d['lateness_ns']['p999']/1e3, d['lateness_ns']['max']/1e3, d['missed_cycles'], d['cycle_work_ns']['p50']/1e3, d['cycle_work_ns']['p999']/1e3, d['cycle_work_ns']['max']/1e3)"
