#!/usr/bin/env python3
"""Map files against memory and meshing: size, save and load time (BENCHMARKS.md, "Map files").

For each configuration, fuses a whole sequence with ground-truth poses and `--save-map` (the save
time is the run's own), then loads the file (`hivox info`) and meshes it (`hivox mesh`) ROUNDS
times, alternating, and prints a Markdown table of medians. With --continue-at N it also checks
that N frames, a save and the rest give the same file as one run (cmp).

usage: bench/map_files.py [--hivox build/hivox] [--data ../shared/data/tum_fr1_rpy]
                          [--rounds 3] [--continue-at 300] [--keep DIR]
"""
import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile

CONFIGS = [
    ("fixed 5 mm", ["--levels", "1", "--voxel-size", "0.005", "--truncation", "0.02"]),
    ("fixed 2 mm", ["--levels", "1", "--voxel-size", "0.002", "--truncation", "0.024"]),
    ("3 levels from 2 mm (default)", []),
]


def run(cmd):
    out = subprocess.run(cmd, check=True, capture_output=True, text=True)
    return out.stdout + out.stderr


def seconds(pattern, text):
    m = re.search(pattern, text)
    if not m:
        sys.exit(f"map_files.py: no '{pattern}' in:\n{text}")
    return float(m.group(1))


def main():
    ap = argparse.ArgumentParser()
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--hivox", default=os.path.join(here, "..", "build", "hivox"))
    ap.add_argument("--data", default=os.path.join(here, "..", "..", "shared", "data",
                                                   "tum_fr1_rpy"))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--continue-at", type=int, default=0)
    ap.add_argument("--keep", default="")
    a = ap.parse_args()
    tmp = a.keep or tempfile.mkdtemp(prefix="hivox-mapbench-")
    os.makedirs(tmp, exist_ok=True)
    rows = []
    try:
        for name, flags in CONFIGS:
            hvx = os.path.join(tmp, re.sub(r"\W+", "_", name) + ".hvx")
            out = run([a.hivox, "reconstruct", a.data, "--poses", "gt", "--no-raycast",
                       "--save-map", hvx, "--out", hvx + ".run", "--overwrite"] + flags)
            save_s = seconds(r"map saved to .* in ([0-9.]+) s", out)
            info = run([a.hivox, "info", hvx])
            memory = seconds(r"memory: ([0-9.]+) MiB of voxels", info)
            blocks = int(re.search(r"memory: .*\(([0-9]+) blocks", info).group(1))
            loads, meshes = [], []
            for _ in range(a.rounds):
                loads.append(seconds(r"loaded in ([0-9.]+) s", run([a.hivox, "info", hvx])))
                m = run([a.hivox, "mesh", hvx, "--out", hvx + ".ply"])
                meshes.append(seconds(r"triangles \(.*\) in ([0-9.]+) s", m))
            size = os.path.getsize(hvx) / 2**20
            rows.append((name, blocks, memory, size, save_s, statistics.median(loads),
                         statistics.median(meshes)))
            print(f"{name}: {blocks} blocks, {memory:.1f} MiB voxels, file {size:.1f} MiB, "
                  f"save {save_s:.2f} s, load {statistics.median(loads):.2f} s, "
                  f"mesh {statistics.median(meshes):.2f} s", file=sys.stderr)
        print("| map | blocks | voxel memory | file | file / memory | save | load | mesh "
              "extraction |")
        print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
        for name, blocks, memory, size, save_s, load_s, mesh_s in rows:
            print(f"| {name} | {blocks} | {memory:.1f} MiB | {size:.1f} MiB | "
                  f"{size / memory:.2f} | {save_s:.2f} s | {load_s:.2f} s | {mesh_s:.2f} s |")
        fixed2 = next(r for r in rows if r[0] == "fixed 2 mm")
        levels = rows[-1]
        print(f"\n3-level file / fixed 2 mm file: {levels[3] / fixed2[3]:.2f}")
        if a.continue_at > 0:
            whole = rows[-1]
            first = os.path.join(tmp, "first.hvx")
            rest = os.path.join(tmp, "rest.hvx")
            base = [a.hivox, "reconstruct", a.data, "--poses", "gt", "--no-raycast", "--overwrite"]
            run(base + ["--frames", str(a.continue_at), "--save-map", first,
                        "--out", first + ".run"])
            run(base + ["--first-frame", str(a.continue_at), "--map", first, "--save-map", rest,
                        "--out", rest + ".run"])
            same = subprocess.run(["cmp", rest, os.path.join(
                tmp, re.sub(r"\W+", "_", whole[0]) + ".hvx")]).returncode == 0
            print(f"continued after {a.continue_at} frames: "
                  f"{'the same file as one run' if same else 'DIFFERENT from one run'}")
    finally:
        if not a.keep:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
