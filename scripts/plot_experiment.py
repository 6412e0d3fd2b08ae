#!/usr/bin/env python3
"""Figures of a `hivox experiment` folder (matplotlib), written to DIR/figures/:

  blocks.png     blocks over the frames per configuration, and the adaptive map's blocks per
                 level (paper Fig. 6)
  renders.png    the first three maps (fixed finest, fixed coarsest, adaptive) shaded from the
                 same overview and close-up poses, beside the adaptive map's levels (paper Fig. 4)
  sdf_error.png  the sdf-error points, seen along the scene's axis of least extent, coloured by
                 each map's |SDF| (the error heat map), with their distributions
  tradeoff.png   every configuration's block saving against its sdf-error (and, with a reference
                 mesh, its accuracy and completeness): the curve a threshold sweep draws

Usage: plot_experiment.py DIR   (`hivox experiment` runs it itself when matplotlib is there)
"""
import csv
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

LEVEL_COLORS = ["#d62728", "#2ca02c", "#1f77b4", "#ff7f0e", "#9467bd"]


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def column(header, rows, name):
    i = header.index(name)
    return np.array([float(r[i]) if r[i] != "" else np.nan for r in rows])


def plot_blocks(d, report, out):
    header, rows = read_csv(os.path.join(d, "blocks.csv"))
    frames = column(header, rows, "frame")
    configs = report["configs"]
    multi = [c for c in configs if c["levels"] > 1]
    fig, axes = plt.subplots(1, 2 if multi else 1, figsize=(13 if multi else 7, 4.5), squeeze=False)
    ax = axes[0][0]
    for c in configs:
        ax.plot(frames, column(header, rows, c["slug"]),
                label=f"{c['name']}: {c['blocks']:,} blocks ({100 * c['block_saving']:.0f} % saved)")
    ax.set_xlabel("frame")
    ax.set_ylabel("allocated blocks (8x8x8 voxels)")
    ax.set_title("Blocks over the sequence")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    if multi:
        c = multi[0]
        ax = axes[0][1]
        levels = [column(header, rows, f"{c['slug']}_level{l}") for l in range(c["levels"])]
        labels = [f"level {l}: {1000 * c['voxel_size_m'] * 2 ** l:g} mm voxels" for l in range(c["levels"])]
        ax.stackplot(frames, *levels, labels=labels, colors=LEVEL_COLORS[: c["levels"]], alpha=0.85)
        ax.set_xlabel("frame")
        ax.set_ylabel("blocks")
        ax.set_title(f"{c['name']}: blocks per level")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper left")
    fig.suptitle(f"{report['dataset']}: {report['frames']} frames, poses {report['poses']}", fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def plot_renders(d, report, out):
    configs = report["configs"]
    multi = [c for c in configs if c["levels"] > 1]
    # The paper's three (fixed finest, fixed coarsest, adaptive); further configurations are in
    # the trade-off figure.
    columns = [(c["name"], c["slug"], "shaded") for c in configs[:3]]
    if multi:
        columns.append((f"{multi[0]['name']}: levels", multi[0]["slug"], "levels"))
    views = ["overview", "close"]
    fig, axes = plt.subplots(len(views), len(columns), figsize=(4.2 * len(columns), 3.4 * len(views)),
                             squeeze=False)
    for r, view in enumerate(views):
        for k, (name, slug, kind) in enumerate(columns):
            ax = axes[r][k]
            ax.axis("off")
            path = os.path.join(d, "renders", f"{slug}_{view}_{kind}.png")
            if os.path.exists(path):
                ax.imshow(plt.imread(path))
            if r == 0:
                ax.set_title(name, fontsize=10)
    fig.suptitle("The same poses: overview (top) and the sequence's view with the most surface detail (bottom)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def plot_sdf_error(d, report, out):
    header, rows = read_csv(os.path.join(d, "sdf_points.csv"))
    if not rows:
        return False
    xyz = np.stack([column(header, rows, k) for k in ("x", "y", "z")], axis=1)
    configs = report["configs"][1:] or report["configs"]
    # Seen along the axis of least extent (a room's vertical, an object's thinnest side).
    centred = xyz - xyz.mean(axis=0)
    _, _, vt = np.linalg.svd(centred[:: max(1, len(centred) // 20000)], full_matrices=False)
    uv = centred @ vt[:2].T
    errors = [column(header, rows, c["slug"] + "_mm") for c in configs]
    finite = np.concatenate([e[np.isfinite(e)] for e in errors]) if errors else np.array([0.0])
    # Most points sit near 0: the scale ends at the 95th percentile and stretches small values.
    vmax = max(float(np.percentile(finite, 95)) if finite.size else 1.0, 1e-3)
    norm = matplotlib.colors.PowerNorm(gamma=0.5, vmin=0, vmax=vmax)
    span = uv.max(axis=0) - uv.min(axis=0)
    aspect = float(span[1] / span[0]) if span[0] > 0 else 1.0
    panel_h = min(max(5.5 * aspect, 2.5), 6.0)
    fig, axes = plt.subplots(1, len(configs) + 1, figsize=(5.5 * (len(configs) + 1), panel_h + 1.4),
                             squeeze=False)
    for k, (c, e) in enumerate(zip(configs, errors)):
        ax = axes[0][k]
        missing = ~np.isfinite(e)
        ax.scatter(uv[missing, 0], uv[missing, 1], s=0.3, c="#bbbbbb", linewidths=0)
        o = np.argsort(np.nan_to_num(e, nan=-1.0))
        o = o[np.isfinite(e[o])]
        sc = ax.scatter(uv[o, 0], uv[o, 1], c=e[o], s=0.6, cmap="inferno", norm=norm, linewidths=0)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        sdf = c["sdf_error"]
        ax.set_title(f"{c['name']}\nmean |SDF| {1000 * sdf['mean_m']:.2f} mm, coverage {100 * sdf['coverage']:.0f} %",
                     fontsize=9)
    fig.colorbar(sc, ax=[axes[0][k] for k in range(len(configs))], extend="max",
                 label="|SDF| at the point, mm (grey: unobserved)", shrink=0.85)
    ax = axes[0][-1]
    bins = np.linspace(0, float(np.percentile(finite, 99.5)) if finite.size else 1.0, 80)
    for c, e in zip(configs, errors):
        ax.hist(e[np.isfinite(e)], bins=bins, histtype="step", density=True, label=c["name"])
    ax.set_yscale("log")
    ax.set_xlabel("|SDF| mm")
    ax.set_ylabel("density (log)")
    ax.set_title("Distribution", fontsize=9)
    ax.legend(fontsize=8)
    fig.suptitle(f"sdf-error at {report['sdf_samples']:,} points on the {report['configs'][0]['name']} mesh "
                 f"(shown: {len(rows):,})", fontsize=10)
    fig.savefig(out, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return True


def plot_tradeoff(report, out):
    configs = report["configs"]
    with_mesh = all("mesh_eval" in c for c in configs)
    panels = [("sdf-error (mean |SDF|), mm", lambda c: 1000 * c["sdf_error"]["mean_m"])]
    if with_mesh:
        panels.append(("accuracy (mean), mm", lambda c: 1000 * c["mesh_eval"]["accuracy"]["mean_m"]))
        panels.append(("completeness (mean), mm", lambda c: 1000 * c["mesh_eval"]["completeness"]["mean_m"]))
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 4.3), squeeze=False)
    for ax, (label, value) in zip(axes[0], panels):
        for c in configs:
            fixed = c["levels"] == 1
            ax.scatter(100 * c["block_saving"], value(c), marker="s" if fixed else "o",
                       color="#444444" if fixed else "#1f77b4", zorder=3)
            ax.annotate(c["name"], (100 * c["block_saving"], value(c)), fontsize=7,
                        xytext=(4, 4), textcoords="offset points")
        ax.set_xlabel(f"blocks saved against {configs[0]['name']}, %")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    fig.suptitle("What each configuration saves and what it costs (squares: fixed grids)", fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main(argv):
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    d = argv[1]
    with open(os.path.join(d, "report.json")) as f:
        report = json.load(f)
    figures = os.path.join(d, "figures")
    os.makedirs(figures, exist_ok=True)
    plot_blocks(d, report, os.path.join(figures, "blocks.png"))
    plot_renders(d, report, os.path.join(figures, "renders.png"))
    plot_sdf_error(d, report, os.path.join(figures, "sdf_error.png"))
    plot_tradeoff(report, os.path.join(figures, "tradeoff.png"))
    print(f"figures written to {figures}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
