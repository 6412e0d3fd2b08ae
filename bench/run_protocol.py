#!/usr/bin/env python3
"""Runs the fusion speed protocol and prints a Markdown table; with the stage benchmarks built,
also the raycast after the last frame.

Protocol: TUM fr1/rpy, first N frames (default 200), ground-truth poses, 5 mm voxels, mu = 20 mm,
depth <= 3 m, 2 threads. hivox and (when `import open3d` works: Debian package python3-open3d)
Open3D's VoxelBlockGrid run in the same session, so ratios are comparable on a noisy machine.

    python3 bench/run_protocol.py [--data ../shared/data/tum_fr1_rpy] [--frames 200]
"""

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def run_hivox(binary, data, frames, extra, threads):
    out = tempfile.mkdtemp(prefix="hivox_bench_")
    cmd = [binary, "reconstruct", str(data), "--poses", "gt", "--frames", str(frames),
           "--threads", str(threads), "--out", out, "--quiet"] + extra
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    subprocess.run(cmd, check=True)
    peak_kib = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    stats = json.loads((Path(out) / "stats.json").read_text())
    stats["peak_rss_mib"] = max(peak_kib, before) / 1024.0
    return stats


def run_stage_bench(binary, frames, threads, env_extra):
    """Median ms of the stage benchmarks of the raycast after `frames` frames (the map fused with
    them, the last frame's view): the pipeline's raycast (hints: the depth just fused and the
    previous raycast warped), the warp that makes the second hint, and a raycast without hints."""
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), HIVOX_BENCH_WARMUP=str(frames - 1),
               **env_extra)
    out = subprocess.run([binary, "--benchmark_filter=BM_RaycastPipeline$|BM_WarpRaycast$|BM_Raycast$",
                          "--benchmark_repetitions=5", "--benchmark_format=json"],
                         check=True, env=env, capture_output=True, text=True).stdout
    medians = {}
    for b in json.loads(out)["benchmarks"]:
        if b.get("aggregate_name") == "median":
            medians[b["run_name"]] = b["real_time"]  # ms: the benchmarks report milliseconds
    return medians


def read_tum(data, frames):
    """(depth path, colour path, T_wc 4x4) for the first `frames` associated frames with GT."""
    import numpy as np
    gt = []
    for line in (data / "groundtruth.txt").read_text().splitlines():
        if line.startswith("#") or not line.strip():
            continue
        gt.append([float(v) for v in line.split()])
    gt = np.array(gt)
    out = []
    for line in (data / "associations.txt").read_text().splitlines():
        if line.startswith("#") or not line.strip():
            continue
        t_rgb, rgb, t_d, depth = line.split()
        i = int(np.argmin(np.abs(gt[:, 0] - float(t_d))))
        if abs(gt[i, 0] - float(t_d)) > 0.02:
            continue
        tx, ty, tz, qx, qy, qz, qw = gt[i, 1:]
        R = np.array([[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
                      [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
                      [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)]])
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = [tx, ty, tz]
        out.append((data / depth, data / rgb, T))
        if len(out) == frames:
            break
    return out


def run_open3d(data, frames, voxel, trunc_mult, max_depth, raycast, block_count):
    import numpy as np
    import open3d as o3d
    import open3d.core as o3c
    intr = json.loads((data / "intrinsics.json").read_text())
    K = o3c.Tensor([[intr["fx"], 0, intr["cx"]], [0, intr["fy"], intr["cy"]], [0, 0, 1]],
                   o3c.Dtype.Float64)
    scale = float(intr["depth_scale"])
    device = o3c.Device("CPU:0")
    vbg = o3d.t.geometry.VoxelBlockGrid(
        attr_names=("tsdf", "weight", "color"),
        attr_dtypes=(o3c.float32, o3c.float32, o3c.float32),
        attr_channels=((1), (1), (3)), voxel_size=voxel, block_resolution=8,
        block_count=block_count, device=device)
    items = read_tum(data, frames)
    integrate_s = raycast_s = 0.0
    for depth_path, rgb_path, T_wc in items:
        depth = o3d.t.io.read_image(str(depth_path))
        color = o3d.t.io.read_image(str(rgb_path))
        extrinsic = o3c.Tensor(np.linalg.inv(T_wc), o3c.Dtype.Float64)
        t0 = time.perf_counter()
        coords = vbg.compute_unique_block_coordinates(depth, K, extrinsic, scale, max_depth,
                                                      trunc_mult)
        vbg.integrate(coords, depth, color, K, extrinsic, scale, max_depth, trunc_mult)
        t1 = time.perf_counter()
        integrate_s += t1 - t0
        if raycast:
            vbg.ray_cast(coords, K, extrinsic, intr["width"], intr["height"],
                         ["depth", "normal", "color"], scale, 0.2, max_depth, 1.0, trunc_mult, 8)
            raycast_s += time.perf_counter() - t1
    last_raycast_ms = 0.0
    if raycast and items:
        # The raycast after all frames, from the last frame's view, repeated (median).
        times = []
        for _ in range(10):
            t0 = time.perf_counter()
            vbg.ray_cast(coords, K, extrinsic, intr["width"], intr["height"],
                         ["depth", "normal", "color"], scale, 0.2, max_depth, 1.0, trunc_mult, 8)
            times.append(1000 * (time.perf_counter() - t0))
        last_raycast_ms = float(np.median(times))
    n = len(items)
    return {"frames": n, "integrate_ms": 1000 * integrate_s / n, "raycast_ms": 1000 * raycast_s / n,
            "last_raycast_ms": last_raycast_ms,
            "blocks": vbg.hashmap().size(),
            "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}


def main():
    root = Path(__file__).resolve().parent.parent
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=root.parent / "shared/data/tum_fr1_rpy")
    ap.add_argument("--hivox", default=str(root / "build/hivox"))
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--skip-open3d", action="store_true")
    ap.add_argument("--bench", default=str(root / "build/bench/hivox_bench"),
                    help="stage benchmarks (-DHIVOX_BUILD_BENCHMARKS=ON) for the raycast after "
                         "the last frame; skipped when absent")
    args = ap.parse_args()
    if not args.data.is_dir():
        sys.exit(f"{args.data}: data set not found (see ../shared/data/README.md)")
    os.environ["OMP_NUM_THREADS"] = str(args.threads)
    common = ["--levels", "1", "--voxel-size", "0.005", "--truncation", "0.02", "--max-depth", "3"]
    rows = []
    s = run_hivox(args.hivox, args.data, args.frames, common + ["--no-raycast"], args.threads)
    t = s["timing_ms"]
    rows.append(("hivox, integration", s["fps"], t["allocate"] + t["integrate"], 0.0,
                 s["blocks_total"], s["bytes_per_voxel"], s["memory_bytes"] / 2**20))
    # Nearest-pixel depth, as the peers read it (the default, bilinear, costs ~1.2x).
    s = run_hivox(args.hivox, args.data, args.frames,
                  common + ["--no-raycast", "--depth-sampling", "nearest"], args.threads)
    t = s["timing_ms"]
    rows.append(("hivox, integration, nearest-pixel depth", s["fps"], t["allocate"] + t["integrate"],
                 0.0, s["blocks_total"], s["bytes_per_voxel"], s["memory_bytes"] / 2**20))
    # Full-resolution raycast, as the peer does (tracking uses a half-resolution one).
    s = run_hivox(args.hivox, args.data, args.frames, common + ["--icp-model-subsample", "1"],
                  args.threads)
    t = s["timing_ms"]
    rows.append(("hivox, integration + raycast", s["fps"], t["allocate"] + t["integrate"],
                 t["raycast"], s["blocks_total"], s["bytes_per_voxel"], s["memory_bytes"] / 2**20))
    open3d_rows = []
    open3d_last_raycast_ms = None
    if not args.skip_open3d:
        try:
            import open3d  # noqa: F401
            for raycast in (False, True):
                o = run_open3d(args.data, args.frames, 0.005, 4.0, 3.0, raycast, 80000)
                name = "Open3D VoxelBlockGrid" + (", integration + raycast" if raycast else ", integration")
                total = o["integrate_ms"] + o["raycast_ms"]
                # Map memory: blocks x 512 voxels x 20 B (float TSDF, weight, RGB).
                open3d_rows.append((name, 1000.0 / total, o["integrate_ms"], o["raycast_ms"],
                                    o["blocks"], 20, o["blocks"] * 512 * 20 / 2**20))
                if raycast:
                    open3d_last_raycast_ms = o["last_raycast_ms"]
        except ImportError:
            print("open3d not importable (apt-get install python3-open3d): peers skipped\n")
    s = run_hivox(args.hivox, args.data, args.frames,
                  ["--levels", "1", "--voxel-size", "0.002", "--truncation", "0.024", "--max-depth",
                   "3", "--no-raycast"], args.threads)
    t = s["timing_ms"]
    rows.append(("hivox 2 mm, mu 24 mm, integration", s["fps"], t["allocate"] + t["integrate"], 0.0,
                 s["blocks_total"], s["bytes_per_voxel"], s["memory_bytes"] / 2**20))

    print(f"{args.data.name}, first {args.frames} frames, GT poses, depth <= 3 m, "
          f"{args.threads} threads ({os.uname().nodename})\n")
    print("| run | fps | fuse ms | raycast ms | blocks | B/voxel | map MiB |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for r in rows[:3] + open3d_rows + rows[3:]:
        print(f"| {r[0]} | {r[1]:.1f} | {r[2]:.2f} | {r[3]:.2f} | {r[4]} | {r[5]} | {r[6]:.0f} |")
    if open3d_rows:
        print(f"\nratios (same run): integration fps hivox / Open3D = {rows[0][1] / open3d_rows[0][1]:.2f} "
              f"({rows[1][1] / open3d_rows[0][1]:.2f} with the nearest pixel, as Open3D); "
              f"integration + raycast fps hivox / Open3D = {rows[2][1] / open3d_rows[1][1]:.2f}; "
              f"raycast ms Open3D / hivox = {open3d_rows[1][3] / max(rows[2][3], 1e-9):.2f}")

    # The raycast after the last frame: the map fused with all frames, the last frame's
    # view, 640x480, from the stage benchmarks.
    if Path(args.bench).is_file():
        maps = [("fixed 5 mm, mu 20 mm", {}),
                ("fixed 2 mm, mu 24 mm", {"HIVOX_BENCH_VOXEL": "0.002", "HIVOX_BENCH_TRUNC": "0.024"}),
                ("3 levels from 2 mm, mu 24 mm", {"HIVOX_BENCH_VOXEL": "0.002",
                                                  "HIVOX_BENCH_TRUNC": "0.024",
                                                  "HIVOX_BENCH_LEVELS": "3"})]
        print(f"\nraycast after {args.frames} frames (the last frame's view, 640x480, median of 5; "
              "the pipeline's raycast = the warp of the previous raycast + the hinted raycast)\n")
        print("| map | pipeline raycast ms | of which warp | without hints ms |")
        print("| --- | ---: | ---: | ---: |")
        pipeline = {}
        for name, env in maps:
            m = run_stage_bench(args.bench, args.frames, args.threads, env)
            pipeline[name] = m["BM_RaycastPipeline"] + m["BM_WarpRaycast"]
            print(f"| hivox {name} | {pipeline[name]:.1f} | {m['BM_WarpRaycast']:.1f} | "
                  f"{m['BM_Raycast']:.1f} |")
        if open3d_last_raycast_ms is not None:
            print(f"| Open3D VoxelBlockGrid 5 mm (the last frame's blocks) | "
                  f"{open3d_last_raycast_ms:.1f} | – | – |")
            print(f"\nratio Open3D / hivox pipeline raycast at 5 mm = "
                  f"{open3d_last_raycast_ms / pipeline[maps[0][0]]:.2f}")
        print(f"hierarchy / fixed 2 mm = {pipeline[maps[2][0]] / pipeline[maps[1][0]]:.2f}")


if __name__ == "__main__":
    main()
