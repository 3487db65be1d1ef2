#!/usr/bin/env python3
"""Breakdown of the M-function handshake from the time stamps of tgm-service and tgm-plc
(--handshake-trace of both; the same CLOCK_MONOTONIC on one host).

usage: handshake_trace.py SERVICE_CSV PLC_CSV [--raw RAW_LOG ...]

The DDS part starts when the service begins the write() of the event sample that first shows
the M_Func (older traces without an event write: the state write) and ends when the service
has taken the acknowledging request. --raw names logs of tgm_bench_state_pingpong run in the
same run (their RESULT lines); the goal (BENCHMARKS.md "Service") compares the DDS part's
median with the fastest raw median among them.
"""
import csv
import sys


def pct(v, q):
    v = sorted(v)
    return v[min(len(v) - 1, int(q * (len(v) - 1) + 0.5))] if v else float("nan")


def raw_results(paths):
    out = []
    for path in paths:
        for line in open(path):
            if not line.startswith("RESULT "):
                continue
            fields = dict(kv.split("=", 1) for kv in line.split()[1:])
            if "median_us" in fields:
                out.append((path, fields))
    return out


def main():
    args = sys.argv[1:]
    raw = []
    if "--raw" in args:
        i = args.index("--raw")
        raw = args[i + 1:]
        args = args[:i]
    if len(args) != 2:
        sys.exit(__doc__)
    svc = {(int(r["interpolator"]), int(r["act_part"])): r for r in csv.DictReader(open(args[0]))}
    # The handshakes of the PLC's trace: since session 76 it also has notes of continuous
    # M-functions, repeats and acknowledgements the service refused or left unanswered, named in
    # its kind, path and reply columns (older traces have none of them: every row counts).
    plc = {}
    for r in csv.DictReader(open(args[1])):
        if r.get("kind", "normal") != "normal" or r.get("path") == "repeat" \
                or r.get("reply", "accepted") != "accepted":
            continue
        plc.setdefault((int(r["interpolator"]), int(r["act_part"])), r)
    keys = sorted(set(svc) & set(plc))
    any_svc = next(iter(svc.values()), {})
    # Column names of older traces (before the event topic): the state write was the first one.
    first = "event_write_begin_ns" if "event_write_begin_ns" in any_svc else "write_begin_ns"
    state_begin = "state_write_begin_ns" if "state_write_begin_ns" in any_svc else "write_begin_ns"
    state_end = "state_write_end_ns" if "state_write_end_ns" in any_svc else "write_end_ns"
    what = "event" if first == "event_write_begin_ns" else "state"
    steps = [
        ("cycle hand-off -> publisher thread awake", "handoff_ns", "publisher_woke_ns", "s", "s"),
        (f"publisher awake -> {what} write() begins", "publisher_woke_ns", first, "s", "s"),
    ]
    if what == "event":
        steps += [
            ("event write() (1 reader: the PLC)", "event_write_begin_ns", "event_write_end_ns", "s", "s"),
            ("event write() begins -> state write() begins", "event_write_begin_ns", state_begin, "s", "s"),
        ]
    steps += [
        ("state write() (all readers)", state_begin, state_end, "s", "s"),
        (f"{what} write() begins -> PLC wakes", first, "woke_ns", "s", "p"),
        ("PLC wakes -> M_Func seen (take, copy)", "woke_ns", "seen_ns", "p", "p"),
        ("M_Func seen -> ack request call", "seen_ns", "ack_call_ns", "p", "p"),
        ("ack request call -> its write() returned", "ack_call_ns", "ack_written_ns", "p", "p"),
        ("ack request call -> service took it", "ack_call_ns", "taken_ns", "p", "s"),
        ("service took it -> cycle applied it (quantization)", "taken_ns", "applied_ns", "s", "s"),
        (f"DDS part: {what} write() begins -> ack taken", first, "taken_ns", "s", "s"),
        ("full: hand-off of the M_Func cycle -> cycle that resumes", "handoff_ns", "applied_ns", "s", "s"),
    ]
    paths = {}
    for k in keys:
        p = plc[k].get("path", "loop")
        paths[p] = paths.get(p, 0) + 1
    print(f"M-function handshakes traced: {len(keys)} (service {len(svc)}, PLC {len(plc)}; PLC acknowledged "
          + ", ".join(f"{n} from the {'event callback' if p == 'event' else 'main loop'}" for p, n in sorted(paths.items()))
          + ")")
    print(f"{'step':58s} {'min':>8s} {'p50':>8s} {'p90':>8s} {'p99':>8s} {'max':>9s}  [us]")
    dds = []
    for name, a, b, sa, sb in steps:
        v = []
        for k in keys:
            ra = svc[k] if sa == "s" else plc[k]
            rb = svc[k] if sb == "s" else plc[k]
            ta, tb = int(ra.get(a) or 0), int(rb.get(b) or 0)
            if ta == 0 or tb == 0:
                continue
            v.append((tb - ta) / 1e3)
        if not v:
            continue
        if name.startswith("DDS part"):
            dds = v
        print(f"{name:58s} {min(v):8.1f} {pct(v, .5):8.1f} {pct(v, .9):8.1f} {pct(v, .99):8.1f} {max(v):9.1f}  (n {len(v)})")
    early = sum(1 for k in keys if int(svc[k].get(state_end) or 0) > int(svc[k]["taken_ns"]))
    if early:
        print(f"ack taken before the state write() returned: {early}")
    results = raw_results(raw)
    if results and dds:
        for path, f in results:
            back = f", return hop (pong write() begins -> taken) median {float(f['return_median_us']):.1f} us" \
                if "return_median_us" in f else ""
            print(f"raw reference {f.get('sample', '?')}/{f.get('mode', '?')} ({path.split('/')[-1]}): "
                  f"median {float(f['median_us']):.1f} us, p99 {float(f['p99_us']):.1f} us (n {f['n']}){back}")
        path, best = min(results, key=lambda pf: float(pf[1]["median_us"]))
        ratio = pct(dds, .5) / float(best["median_us"])
        print(f"goal: DDS part median {pct(dds, .5):.1f} us / fastest raw median {float(best['median_us']):.1f} us "
              f"({best.get('sample', '?')}/{best.get('mode', '?')}) = {ratio:.2f} -> "
              f"{'met' if ratio < 1.5 else 'missed'} (< 1.5)")


if __name__ == "__main__":
    main()
