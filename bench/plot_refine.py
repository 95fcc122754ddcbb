#!/usr/bin/env python3
"""Plots of `cinevol-bench refine --csv` (docs/tradeoff.md, "Still frames").

    python3 bench/plot_refine.py REFINE_CSV OUT_DIR

writes OUT_DIR/refine-SCENE.svg for every scene in the CSV: the displayed
frame's PSNR over samples per pixel and over wall-clock time since the camera
stopped, the previous release's blend beside the current refinement. Plain
SVG, so that it needs nothing beyond Python.
"""
import csv
import math
import os
import sys
from collections import defaultdict

WIDTH, HEIGHT = 360, 260  # one panel
LEFT, RIGHT, TOP, BOTTOM = 52, 12, 28, 40
CURVES = [("previous", "previous_psnr", "previous_ms", "#999999", "6 4"),
          ("refined", "psnr", "ms", "#1f6fb4", "")]


def load(path):
    scenes = defaultdict(list)
    with open(path) as f:
        for row in csv.DictReader(f):
            scenes[row["scene"]].append(row)
    return scenes


def log_ticks(low, high):
    ticks, t = [], 10 ** math.floor(math.log10(low))
    while t <= high:
        for m in (1, 2, 5):
            if low <= t * m <= high:
                ticks.append(t * m)
        t *= 10
    return ticks


def panel(x0, rows, x_key_of, x_label, db_range):
    """One panel's SVG elements: log x axis, PSNR y axis, both curves."""
    xs = [float(r[x_key_of(c)]) for r in rows for c in CURVES]
    x_low, x_high = max(min(xs), 1e-3), max(xs)
    y_low, y_high = db_range
    w, h = WIDTH - LEFT - RIGHT, HEIGHT - TOP - BOTTOM

    def px(x):
        return x0 + LEFT + w * (math.log(x) - math.log(x_low)) / (math.log(x_high) - math.log(x_low))

    def py(y):
        return TOP + h * (1 - (y - y_low) / (y_high - y_low))

    out = [f'<rect x="{x0 + LEFT}" y="{TOP}" width="{w}" height="{h}" fill="none" stroke="#444"/>']
    for t in log_ticks(x_low, x_high):
        out.append(f'<line x1="{px(t):.1f}" y1="{TOP + h}" x2="{px(t):.1f}" y2="{TOP + h + 4}" stroke="#444"/>')
        out.append(f'<text x="{px(t):.1f}" y="{TOP + h + 16}" text-anchor="middle">{t:g}</text>')
    for db in range(math.ceil(y_low), math.floor(y_high) + 1, 2):
        out.append(f'<line x1="{x0 + LEFT}" y1="{py(db):.1f}" x2="{x0 + LEFT + w}" y2="{py(db):.1f}" '
                   'stroke="#ddd"/>')
        out.append(f'<text x="{x0 + LEFT - 6}" y="{py(db) + 4:.1f}" text-anchor="end">{db}</text>')
    out.append(f'<text x="{x0 + LEFT + w / 2}" y="{HEIGHT - 6}" text-anchor="middle">{x_label}</text>')
    out.append(f'<text x="{x0 + 14}" y="{TOP + h / 2}" transform="rotate(-90 {x0 + 14} {TOP + h / 2})" '
               'text-anchor="middle">PSNR dB</text>')
    for name, psnr_key, ms_key, colour, dash in CURVES:
        key = x_key_of((name, psnr_key, ms_key, colour, dash))
        points = " ".join(f"{px(max(float(r[key]), x_low)):.1f},{py(float(r[psnr_key])):.1f}" for r in rows)
        out.append(f'<polyline points="{points}" fill="none" stroke="{colour}" stroke-width="2" '
                   f'stroke-dasharray="{dash}"/>')
    return out


def plot(scene, rows, out_dir):
    psnrs = [float(r[k]) for r in rows for k in ("previous_psnr", "psnr")]
    db_range = (math.floor(min(psnrs)) - 0.5, math.ceil(max(psnrs)) + 0.5)
    name = os.path.splitext(os.path.basename(scene))[0]
    size = f'{rows[0]["width"]}x{rows[0]["height"]}'
    body = [f'<text x="{LEFT}" y="16" font-weight="bold">{name}, {size}: still frames after an orbit</text>']
    body += panel(0, rows, lambda c: "spp", "samples per pixel", db_range)
    body += panel(WIDTH, rows, lambda c: c[2], "ms since the camera stopped", db_range)
    for i, (label, _, _, colour, dash) in enumerate(CURVES):
        y = TOP + 14 + 16 * i
        body.append(f'<line x1="{2 * WIDTH - 150}" y1="{y}" x2="{2 * WIDTH - 120}" y2="{y}" stroke="{colour}" '
                    f'stroke-width="2" stroke-dasharray="{dash}"/>')
        body.append(f'<text x="{2 * WIDTH - 114}" y="{y + 4}">{label}</text>')
    svg = (f'<svg xmlns="http://www.w3.org/2000/svg" width="{2 * WIDTH}" height="{HEIGHT}" '
           f'font-family="sans-serif" font-size="11">\n<rect width="100%" height="100%" fill="white"/>\n'
           + "\n".join(body) + "\n</svg>\n")
    path = os.path.join(out_dir, f"refine-{name}.svg")
    with open(path, "w") as f:
        f.write(svg)
    print("wrote", path)


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    os.makedirs(sys.argv[2], exist_ok=True)
    for scene, rows in load(sys.argv[1]).items():
        plot(scene, rows, sys.argv[2])


if __name__ == "__main__":
    main()
