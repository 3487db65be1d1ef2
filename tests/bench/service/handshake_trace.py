#!/usr/bin/env python3
"""Breakdown of the M-function handshake from the time stamps of tgm-service and tgm-plc
(--handshake-trace of both; the same CLOCK_MONOTONIC on one host).

usage: handshake_trace.py SERVICE_CSV PLC_CSV
"""
import csv
import sys


def pct(v, q):
    v = sorted(v)
    return v[min(len(v) - 1, int(q * (len(v) - 1) + 0.5))] if v else float("nan")


def main():
    svc = {(int(r["interpolator"]), int(r["act_part"])): r for r in csv.DictReader(open(sys.argv[1]))}
    plc = {(int(r["interpolator"]), int(r["act_part"])): r for r in csv.DictReader(open(sys.argv[2]))}
    keys = sorted(set(svc) & set(plc))
    steps = [
        ("cycle hand-off -> publisher thread awake", "handoff_ns", "publisher_woke_ns", "s", "s"),
        ("publisher awake -> state write() begins", "publisher_woke_ns", "write_begin_ns", "s", "s"),
        ("state write() (all readers)", "write_begin_ns", "write_end_ns", "s", "s"),
        ("state write() begins -> PLC wakes (WaitSet)", "write_begin_ns", "woke_ns", "s", "p"),
        ("PLC wakes -> M_Func seen (take, copy)", "woke_ns", "seen_ns", "p", "p"),
        ("M_Func seen -> ack request call", "seen_ns", "ack_call_ns", "p", "p"),
        ("ack request call -> its write() returned", "ack_call_ns", "ack_written_ns", "p", "p"),
        ("ack write() returned -> service receiver took it", "ack_written_ns", "taken_ns", "p", "s"),
        ("receiver took it -> cycle applied it (quantization)", "taken_ns", "applied_ns", "s", "s"),
        ("DDS part: state write() begins -> ack taken", "write_begin_ns", "taken_ns", "s", "s"),
        ("full: hand-off of the M_Func cycle -> cycle that resumes", "handoff_ns", "applied_ns", "s", "s"),
    ]
    print(f"M-function handshakes traced: {len(keys)} (service {len(svc)}, PLC {len(plc)})")
    print(f"{'step':58s} {'min':>8s} {'p50':>8s} {'p90':>8s} {'p99':>8s} {'max':>9s}  [us]")
    for name, a, b, sa, sb in steps:
        v = []
        for k in keys:
            ra = svc[k] if sa == "s" else plc[k]
            rb = svc[k] if sb == "s" else plc[k]
            ta, tb = int(ra[a]), int(rb[b])
            if ta == 0 or tb == 0:
                continue
            v.append((tb - ta) / 1e3)
        if not v:
            continue
        print(f"{name:58s} {min(v):8.1f} {pct(v, .5):8.1f} {pct(v, .9):8.1f} {pct(v, .99):8.1f} {max(v):9.1f}  (n {len(v)})")
    early = sum(1 for k in keys if int(svc[k]["write_end_ns"]) == 0)
    if early:
        print(f"ack taken before the state write() returned: {early}")


if __name__ == "__main__":
    main()
