#!/usr/bin/env python3
"""One row per kernel from Nsight Compute's raw CSV (ncu --csv --page raw):
its mean time, its SM time (the time times the share of SMs busy: what it
takes from other sessions' work when many run at once), the warps active
while busy, its launches and shape. Usage: kernel_table.py NCU.csv"""
import collections
import csv
import sys


def number(text):
    try:
        return float(text.replace(",", ""))
    except ValueError:
        return None


def main(path):
    rows = list(csv.reader(open(path, newline="")))
    header_at = next((i for i, r in enumerate(rows) if r and r[0] == "ID"), None)
    if header_at is None:
        print(f"no kernels in {path}")
        return 1
    header = rows[header_at]
    col = {name: i for i, name in enumerate(header)}
    kernels = collections.OrderedDict()
    for r in rows[header_at + 2:]:  # the row after the header gives the units
        if len(r) < len(header):
            continue
        name = r[col["Kernel Name"]].split("(")[0].replace("void ", "").split("::")[-1]
        us = number(r[col["gpu__time_duration.sum"]]) / 1000  # ns
        busy = number(r[col["sm__cycles_active.avg"]]) / max(number(r[col["sm__cycles_elapsed.avg"]]), 1)
        warps = number(r[col["sm__warps_active.avg.pct_of_peak_sustained_active"]])
        k = kernels.setdefault(name, {"n": 0, "us": 0.0, "sm": 0.0, "warps": 0.0,
                                      "shape": f"{r[col['launch__grid_size']]} x {r[col['launch__block_size']]}, "
                                               f"{r[col['launch__registers_per_thread']]} registers"})
        k["n"] += 1
        k["us"] += us
        k["sm"] += us * busy
        k["warps"] += warps
    print("| kernel | launches | us each | SM time us each | warps active | grid x block |")
    print("|---|---|---|---|---|---|")
    for name, k in sorted(kernels.items(), key=lambda kv: -kv[1]["us"]):
        n = k["n"]
        print(f"| `{name}` | {n} | {k['us'] / n:.1f} | {k['sm'] / n:.1f} | {k['warps'] / n:.1f}% | {k['shape']} |")
    total_us = sum(k["us"] for k in kernels.values())
    total_sm = sum(k["sm"] for k in kernels.values())
    print(f"\n{sum(k['n'] for k in kernels.values())} launches: {total_us:.0f} us, SM time {total_sm:.0f} us")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
