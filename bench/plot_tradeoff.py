#!/usr/bin/env python3
"""Plots of a `cinevol-bench tradeoff` run (docs/tradeoff.md shows them).

    python3 bench/plot_tradeoff.py RESULTS_DIR

reads RESULTS_DIR/tradeoff.csv and images/, and writes RESULTS_DIR/plots/:
  pareto-DATASET.png    PSNR against ms per frame for every configuration, the
                        Pareto front drawn, one panel per scenario
  psnr-DATASET.png      PSNR over the frames for every denoiser, per scenario
  strip-DATASET-SCENARIO.png  the middle frame: noisy, every denoiser,
                        reference, with |error| maps below
"""
import csv
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

SCENARIOS = ["orbit", "area-light", "point-light", "tf-edit", "static", "transparent"]


def load(results):
    runs = defaultdict(list)  # (dataset, scenario, config) -> rows
    with open(os.path.join(results, "tradeoff.csv")) as f:
        for row in csv.DictReader(f):
            runs[(row["dataset"], row["scenario"], row["config"])].append(row)
    return runs


def mean(rows, key, skip_first=False):
    values = [float(r[key]) for r in rows if not (skip_first and r["frame"] == "0")]
    return sum(values) / len(values) if values else float("nan")


def total_ms(rows):
    return sum(mean(rows, k) for k in ("render_ms", "denoise_ms", "tonemap_ms", "encode_ms"))


def pareto(points):
    """The points no other point beats on both time (lower) and PSNR (higher)."""
    front, best = [], float("-inf")
    for ms, psnr, label in sorted(points):
        if psnr > best:
            front.append((ms, psnr, label))
            best = psnr
    return front


def panels(scenarios):
    cols = 3
    rows = (len(scenarios) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(5 * cols, 4 * rows), squeeze=False)
    for ax in axes.flat[len(scenarios):]:
        ax.axis("off")
    return fig, list(axes.flat)


def plot_pareto(runs, dataset, scenarios, out):
    fig, axes = panels(scenarios)
    for ax, scenario in zip(axes, scenarios):
        points = [(total_ms(rows), mean(rows, "psnr"), config)
                  for (d, s, config), rows in runs.items() if d == dataset and s == scenario]
        for ms, psnr, label in points:
            ax.scatter(ms, psnr, s=14, color="tab:red" if label.startswith("wrls") else "tab:blue")
            ax.annotate(label, (ms, psnr), fontsize=6, xytext=(3, 2), textcoords="offset points")
        front = pareto(points)
        ax.plot([p[0] for p in front], [p[1] for p in front], color="black", linewidth=0.8, label="Pareto front")
        ax.set_xscale("log")
        ax.set_title(f"{dataset} / {scenario}")
        ax.set_xlabel("ms per frame (render + denoise + tone map + encode)")
        ax.set_ylabel("PSNR dB (displayed)")
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(out, f"pareto-{dataset}.png"), dpi=110)
    plt.close(fig)


def plot_psnr_over_frames(runs, dataset, scenarios, out):
    fig, axes = panels(scenarios)
    for ax, scenario in zip(axes, scenarios):
        for (d, s, config), rows in sorted(runs.items()):
            if d != dataset or s != scenario or rows[0]["knob"] != "denoiser":
                continue
            ax.plot([int(r["frame"]) for r in rows], [float(r["psnr"]) for r in rows], label=config,
                    linewidth=2 if config == "wrls" else 1)
        ax.set_title(f"{dataset} / {scenario}")
        ax.set_xlabel("frame")
        ax.set_ylabel("PSNR dB")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(out, f"psnr-{dataset}.png"), dpi=110)
    plt.close(fig)


def plot_strip(results, runs, dataset, scenario, out):
    folder = os.path.join(results, "images", dataset, scenario)
    if not os.path.isdir(folder):
        return
    labels = [c for (d, s, c), rows in sorted(runs.items())
              if d == dataset and s == scenario and rows[0]["knob"] == "denoiser"
              and os.path.exists(os.path.join(folder, c.replace("+", "_") + ".jpg"))]
    labels = ["none"] + [c for c in labels if c != "none"] if "none" in labels else labels
    reference = plt.imread(os.path.join(folder, "reference.jpg"))[..., :3] / 255.0
    fig, axes = plt.subplots(2, len(labels) + 1, figsize=(2.6 * (len(labels) + 1), 3.4), squeeze=False)
    for i, label in enumerate(labels + ["reference"]):
        image = reference if label == "reference" else plt.imread(
            os.path.join(folder, label.replace("+", "_") + ".jpg"))[..., :3] / 255.0
        axes[0][i].imshow(image)
        axes[0][i].set_title("noisy" if label == "none" else label, fontsize=8)
        error = abs(image - reference).mean(axis=2)
        axes[1][i].imshow(error, cmap="inferno", vmin=0, vmax=0.25)
        for row in (0, 1):
            axes[row][i].axis("off")
    fig.suptitle(f"{dataset} / {scenario}, middle frame (half size, JPEG 92); below: |error| against the reference", fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(out, f"strip-{dataset}-{scenario}.png"), dpi=110)
    plt.close(fig)


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    results = sys.argv[1]
    runs = load(results)
    out = os.path.join(results, "plots")
    os.makedirs(out, exist_ok=True)
    for dataset in sorted({d for d, _, _ in runs}):
        scenarios = [s for s in SCENARIOS if any(d == dataset and sc == s for d, sc, _ in runs)]
        plot_pareto(runs, dataset, scenarios, out)
        plot_psnr_over_frames(runs, dataset, scenarios, out)
        for scenario in scenarios:
            plot_strip(results, runs, dataset, scenario, out)
    print(f"plots in {out}")


if __name__ == "__main__":
    main()
