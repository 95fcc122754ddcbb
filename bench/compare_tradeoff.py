#!/usr/bin/env python3
"""Two trade-off studies of the same runs, before and after a change.

    bench/compare_tradeoff.py BEFORE/tradeoff.json AFTER/tradeoff.json [...]

Pairs of files may repeat (one pair a data set). Prints, a run a row, the
default wRLS's and SVGF's PSNR change (plain, and in brackets with the
references' noise taken out), wRLS's corrected lead over SVGF before / after,
its temporal error and flicker against SVGF's, and flags a wRLS drop beyond
the study's rule (0.05 dB, plain or corrected). Standard library only: it runs
on the GPU machine too.
"""
import json
import sys

RULE_DB = 0.05


def runs(path):
    """{(dataset, scenario): {method: run}} for SVGF and the default wRLS."""
    out = {}
    for r in json.load(open(path))["runs"]:
        if r["knob"] == "denoiser" and r["config"] in ("svgf", "wrls"):
            out.setdefault((r["dataset"], r["scenario"]), {})[r["config"]] = r
    return out


def against_svgf(run, field):
    """wRLS's figure over SVGF's (nan where SVGF's is 0)."""
    svgf = run["svgf"][field]
    return run["wrls"][field] / svgf if svgf > 0 else float("nan")


def lead(run):
    """wRLS's corrected PSNR lead over SVGF, dB."""
    return run["wrls"]["psnr_corrected"] - run["svgf"]["psnr_corrected"]


def main(paths):
    if len(paths) < 2 or len(paths) % 2:
        sys.exit(__doc__)
    before, after = {}, {}
    for i in range(0, len(paths), 2):
        before.update(runs(paths[i]))
        after.update(runs(paths[i + 1]))
    print("| run | wRLS | SVGF | corrected lead | temporal error against SVGF's | flicker against SVGF's |")
    print("|---|---|---|---|---|---|")
    drops, short = [], [0, 0]
    for key in sorted(before):
        if key not in after or len(before[key]) < 2 or len(after[key]) < 2:
            continue
        b, a = before[key], after[key]

        def change(method, field):
            return a[method][field] - b[method][field]

        w, wc = change("wrls", "psnr"), change("wrls", "psnr_corrected")
        flag = "**" if min(w, wc) < -RULE_DB else ""
        if flag:
            drops.append(key)
        short[0] += lead(b) < 1.0
        short[1] += lead(a) < 1.0
        t = [against_svgf(r, "temporal") - 1.0 for r in (b, a)]
        f = [against_svgf(r, "flicker") for r in (b, a)]
        print(f"| {key[0]} / {key[1]} | {flag}{w:+.2f} ({wc:+.2f}){flag} | "
              f"{change('svgf', 'psnr'):+.2f} ({change('svgf', 'psnr_corrected'):+.2f}) | "
              f"{lead(b):+.2f} / {lead(a):+.2f} | {t[0]:+.1%} / {t[1]:+.1%} | {f[0]:.2f} / {f[1]:.2f} |")
    print(f"\nruns short of a 1 dB corrected lead: {short[0]} before, {short[1]} after")
    print(f"wRLS drops beyond {RULE_DB} dB: {len(drops)}" + "".join(f"\n  {d[0]} / {d[1]}" for d in drops))


if __name__ == "__main__":
    main(sys.argv[1:])
