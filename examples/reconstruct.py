#!/usr/bin/env python3
"""Reconstructs an RGB-D sequence with hivox from Python and writes its mesh.

usage: examples/reconstruct.py DATASET MESH.ply [--frames N] [--voxel-size M]
  e.g. examples/reconstruct.py ../shared/data/tum_fr1_rpy fr1.ply --frames 100
Needs the hivox module on the Python path (README, "Python").
"""
import argparse

import numpy as np

import hivox


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dataset")
    ap.add_argument("mesh")
    ap.add_argument("--frames", type=int, default=0)
    ap.add_argument("--voxel-size", type=float, default=0.004)
    a = ap.parse_args()
    data = hivox.open_dataset(a.dataset, max_frames=a.frames)
    params = hivox.ReconstructionParams(
        map=hivox.MapParams(voxel_size_m=a.voxel_size, truncation_m=6 * a.voxel_size))
    rec = hivox.Reconstruction(params, data.camera)
    for i in range(len(data)):
        frame = data.read(i)
        if i == 0:  # the first frame sits at its true pose when the dataset has one
            rec.track_and_integrate(frame["depth"], frame["color"], frame["T_wc_gt"])
        else:
            rec.track_and_integrate(frame["depth"], frame["color"])
    rec.write_mesh(a.mesh)
    mesh = rec.extract_mesh()
    path = np.array([T[:3, 3] for _, T in rec.trajectory])
    print(f"{len(data)} frames, {rec.stats['blocks_total']} blocks, "
          f"{len(mesh['triangles'])} triangles -> {a.mesh}; camera travelled "
          f"{np.linalg.norm(np.diff(path, axis=0), axis=1).sum():.2f} m")


if __name__ == "__main__":
    main()
