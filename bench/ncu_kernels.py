#!/usr/bin/env python3
"""The device's time a frame, kernel by kernel, from ncu's raw CSV of the loop's launches
(bench/gpu_check.sh's ncu_kernels step): for each kernel its launches, its mean duration and its
time a frame, slowest first, and the sum. A frame is counted by the integration kernel, which
every fused frame launches once.

usage: bench/ncu_kernels.py NCU_OUTPUT   # ncu --csv --page raw --metrics gpu__time_duration.sum
"""
import csv
import re
import sys
from collections import defaultdict

METRIC = "gpu__time_duration.sum"
UNIT_NS = {"nsecond": 1.0, "ns": 1.0, "usecond": 1e3, "us": 1e3, "msecond": 1e6, "ms": 1e6}


def short_name(kernel: str) -> str:
    """`void ns::(anonymous namespace)::name<...>(args)` -> `name<...>`: the name and its template
    arguments, without its namespaces and its parameter list."""
    name = re.sub(r"^void\s+", "", kernel.strip()).replace("(anonymous namespace)::", "")
    if name.endswith(")"):  # the parameter list: back to its matching parenthesis
        depth = 0
        for i in range(len(name) - 1, -1, -1):
            depth += {")": 1, "(": -1}.get(name[i], 0)
            if depth == 0:
                name = name[:i]
                break
    head, sep, tail = name.partition("<")
    return head.rsplit("::", 1)[-1] + sep + tail


def main() -> int:
    if len(sys.argv) != 2:
        print(__doc__.strip().splitlines()[-1], file=sys.stderr)
        return 2
    with open(sys.argv[1], newline="", errors="replace") as f:
        # ncu's CSV rows start with a quote; the program's own output is mixed in.
        rows = list(csv.reader(line for line in f if line.startswith('"')))
    header = next((r for r in rows if "Kernel Name" in r and METRIC in r), None)
    if header is None:
        print(f"{sys.argv[1]}: no ncu table with 'Kernel Name' and {METRIC}", file=sys.stderr)
        return 1
    name_col, metric_col = header.index("Kernel Name"), header.index(METRIC)
    scale = 1.0
    total = defaultdict(float)
    launches = defaultdict(int)
    for r in rows:
        if r is header or len(r) <= max(name_col, metric_col):
            continue
        value = r[metric_col].replace(",", "")
        if r[name_col] == "" and value in UNIT_NS:  # the units row
            scale = UNIT_NS[value]
            continue
        try:
            ns = float(value) * scale
        except ValueError:
            continue
        name = short_name(r[name_col])
        total[name] += ns
        launches[name] += 1
    frames = next((n for k, n in launches.items() if k.startswith("integrate_kernel")), 0)
    if not total:
        print(f"{sys.argv[1]}: no kernel launches measured", file=sys.stderr)
        return 1
    per = max(frames, 1)
    print(f"{sum(launches.values())} launches, {frames} frames (integrate_kernel's launches)")
    print(f"{'kernel':<56} {'launches':>8} {'mean us':>9} {'us a frame':>11}")
    for name in sorted(total, key=total.get, reverse=True):
        print(f"{name[:56]:<56} {launches[name]:>8} {total[name] / launches[name] / 1e3:>9.1f} "
              f"{total[name] / per / 1e3:>11.1f}")
    print(f"{'all kernels':<56} {sum(launches.values()):>8} {'':>9} "
          f"{sum(total.values()) / per / 1e3:>11.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
