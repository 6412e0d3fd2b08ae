"""The hivox Python module against the library: same results as the C++ run, numpy in and out,
errors as exceptions. Run by CTest (Python.pytest) with PYTHONPATH at the built module."""
import os
import subprocess
import sys

import numpy as np
import pytest

import hivox

SCENE = "synthetic:box?frames=6&width=80&height=60&noise=none"


def small_params():
    return hivox.ReconstructionParams(
        map=hivox.MapParams(voxel_size_m=0.01, levels=1, truncation_m=0.04, max_blocks=1 << 14,
                            buckets_per_level=1 << 12, excess_per_level=1 << 12))


def test_params_take_keywords_print_and_validate():
    p = hivox.MapParams(voxel_size_m=0.004, levels=2)
    assert p.voxel_size_m == pytest.approx(0.004) and p.levels == 2
    assert "voxel 4.0/8.0 mm (2 levels)" in repr(p)
    with pytest.raises(TypeError, match="no field 'voxel_size'"):
        hivox.MapParams(voxel_size=0.004)
    with pytest.raises(hivox.Error, match="levels"):
        hivox.MapParams(levels=9).validate()
    assert isinstance(hivox.__version__, str) and hivox.__version__.count(".") == 2
    r = hivox.RefineParams(split_weight_scale=1.0, settled_weight=8.0, min_samples=2,
                           merge_noise_ratio=0.5)
    assert (r.split_weight_scale, r.settled_weight, r.min_samples) == (1.0, 8.0, 2)
    assert r.merge_noise_ratio == pytest.approx(0.5)
    with pytest.raises(hivox.Error, match="split_weight_scale must be in"):
        hivox.RefineParams(split_weight_scale=0.0).validate()
    r = hivox.RefineParams(criterion="det-cov")
    assert r.criterion == "det-cov" and "criterion det-cov" in repr(r)
    with pytest.raises(hivox.Error, match="refine criterion must be 'detail' or 'det-cov'"):
        r.criterion = "curvature"
    f = hivox.FusionParams(depth_sampling="nearest")
    assert f.depth_sampling == "nearest" and "nearest" in repr(f)
    with pytest.raises(hivox.Error, match="got 'cubic'"):
        f.depth_sampling = "cubic"
    t = hivox.TrackParams(iterations=[3, 5], model_subsample=4, loss="tukey")
    assert (t.iterations, t.model_subsample, t.loss) == ([3, 5], 4, "tukey")
    assert "2 levels (iterations 3/5 finest first), tukey loss" in repr(t)
    assert "model 1/4 resolution" in repr(t)
    with pytest.raises(hivox.Error, match="unknown robust loss 'cauchy'"):
        t.loss = "cauchy"
    with pytest.raises(hivox.Error, match="model_subsample must be 1, 2 or 4, got 3"):
        hivox.TrackParams(model_subsample=3).validate()
    quiet = hivox.TrackParams(noise=hivox.SensorNoise.none(), residual_floor_m=0.0)
    assert quiet.noise.sigma_m(2.0) == 0.0
    with pytest.raises(hivox.Error, match="residual_floor_m must be > 0 with a noise-free sensor"):
        quiet.validate()
    quiet.noise = hivox.SensorNoise.kinect()
    quiet.validate()
    quiet.noise.quadratic_per_m = 0.0  # edited in place, as the other nested structs
    quiet.noise.sigma_min_m = 0.0
    with pytest.raises(hivox.Error, match="residual_floor_m must be > 0 with a noise-free sensor"):
        quiet.validate()
    c = hivox.RaycastParams(step_fraction=0.5, hint_margin_mu=1.0)
    assert "step 0.50 mu, min weight 1, hints from 1 mu ahead" in repr(c)
    with pytest.raises(hivox.Error, match="step_fraction must be in"):
        hivox.RaycastParams(step_fraction=1.5).validate()
    p = hivox.ReconstructionParams(raycast=c, previous_raycast_hints=False)
    assert "step 0.50 mu" in repr(p) and not p.previous_raycast_hints
    p.raycast.step_fraction = 1.5  # the struct in place, as map, fusion and refine
    with pytest.raises(hivox.Error, match="step_fraction must be in"):
        p.validate()


def test_the_device_is_chosen_by_name():
    p = small_params()
    assert p.device == "cpu"
    p.device = "cuda:1"
    assert p.device == "cuda:1"
    with pytest.raises(hivox.Error, match="device must be 'cpu', 'cuda' or 'cuda:N', got 'gpu'"):
        p.device = "gpu"
    # A device this machine cannot run is refused naming it (where a GPU is, the run's tests in
    # test_cuda_loop cover it).
    p.device = "cuda:7"
    with pytest.raises(hivox.Error, match="cuda:7"):
        hivox.Reconstruction(p, hivox.PinholeCamera(fx=80.0, fy=80.0, cx=39.5, cy=29.5, width=80,
                                                    height=60))


def test_devices_list_the_cpu_first_and_the_gpus_a_run_can_name():
    devices = hivox.devices()
    assert devices[0]["device"] == "cpu"
    assert devices[0]["name"].endswith("(OpenMP)")
    for i, d in enumerate(devices[1:]):
        # Each GPU by its index, with its memory (what `hivox devices` prints).
        assert d["device"] == f"cuda:{i}"
        assert 0 <= d["free_bytes"] <= d["memory_bytes"]
        assert d["multiprocessors"] > 0
        # A listed device runs: a reconstruction starts on it.
        p = small_params()
        p.device = d["device"]
        hivox.Reconstruction(p, hivox.PinholeCamera(fx=80.0, fy=80.0, cx=39.5, cy=29.5, width=80,
                                                    height=60))


def test_frames_fused_from_python_equal_the_library_run(tmp_path):
    data = hivox.open_dataset(SCENE)
    assert len(data) == 6 and data.layout == "synthetic" and data.has_ground_truth
    rec = hivox.Reconstruction(small_params(), data.camera, noise_free=True)
    for i in range(len(data)):
        f = data.read(i)
        assert f["depth"].dtype == np.float32 and f["depth"].shape == (60, 80)
        assert f["color"].dtype == np.uint8 and f["color"].shape == (60, 80, 3)
        s = rec.integrate(f["depth"], f["color"], f["T_wc_gt"])
        assert s["fused"] and s["blocks_total"] > 0
    mesh = rec.extract_mesh()
    assert mesh["vertices"].shape[1] == 3 and mesh["triangles"].dtype == np.int32
    assert mesh["triangles"].max() < len(mesh["vertices"])
    assert mesh["colors"].shape == mesh["vertices"].shape

    # Read ahead on two threads: the same frames, the same mesh.
    run_params = hivox.RunParams(poses="gt", reconstruction=small_params(),
                                 out_dir=str(tmp_path / "run"), read_threads=2)
    same, summary = hivox.run(data, run_params)
    assert summary["frames_fused"] == 6 and summary["end"] == "completed"
    other = same.extract_mesh()
    assert np.array_equal(mesh["vertices"], other["vertices"])
    assert np.array_equal(mesh["triangles"], other["triangles"])
    assert (tmp_path / "run" / "mesh.ply").exists()

    # Renders as arrays: depth where the model is seen, levels -1 elsewhere.
    _, T_last = rec.trajectory[-1]
    r = rec.render(data.camera, T_last)
    assert r["depth"].shape == (60, 80) and r["normals"].shape == (60, 80, 3)
    hit = r["depth"] > 0
    assert hit.mean() > 0.05
    assert (r["levels"][~hit] == -1).all() and (r["levels"][hit] == 0).all()
    assert np.allclose(np.linalg.norm(r["normals"][hit], axis=1), 1.0, atol=1e-3)


def test_frames_read_ahead_are_the_frames_read_in_turn():
    data = hivox.open_dataset("synthetic:desk?frames=12&width=80&height=60&noise=kinect")
    for threads in (0, 1, 3):
        frames = list(data.frames(first=2, count=7, threads=threads))
        assert [f["index"] for f in frames] == list(range(2, 9))
        for f in frames:
            same = data.read(f["index"])
            assert np.array_equal(f["depth"], same["depth"])
            assert np.array_equal(f["color"], same["color"])
            assert np.array_equal(f["T_wc_gt"], same["T_wc_gt"])
    assert len(list(data.frames(first=10))) == 2
    with pytest.raises(IndexError):
        data.frames(first=13)
    with pytest.raises(hivox.Error, match="threads"):
        data.frames(threads=-1)


def test_uint16_depth_with_its_scale_equals_metres():
    data = hivox.open_dataset(SCENE)
    a = hivox.Reconstruction(small_params(), data.camera, noise_free=True)
    b = hivox.Reconstruction(small_params(), data.camera, depth_scale=5000.0, noise_free=True)
    for i in range(3):
        f = data.read(i)
        raw = np.round(f["depth"] * 5000.0).astype(np.uint16)
        a.integrate(raw.astype(np.float32) / 5000.0, None, f["T_wc_gt"])
        b.integrate(raw, None, f["T_wc_gt"])
    assert np.array_equal(a.extract_mesh()["vertices"], b.extract_mesh()["vertices"])


def test_bad_input_raises_with_a_clear_message():
    data = hivox.open_dataset(SCENE)
    rec = hivox.Reconstruction(small_params(), data.camera)
    f = data.read(0)
    with pytest.raises(ValueError, match=r"color must be a uint8 array of shape \(60, 80, 3\)"):
        rec.integrate(f["depth"], np.zeros((10, 10, 3), np.uint8), f["T_wc_gt"])
    with pytest.raises(ValueError, match="2-D"):
        rec.integrate(np.zeros((2, 60, 80), np.float32), None, f["T_wc_gt"])
    with pytest.raises(ValueError, match="depth_scale"):
        rec.integrate(np.zeros((60, 80), np.uint16), None, f["T_wc_gt"])
    bad = small_params()
    bad.map.voxel_size_m = -1.0
    with pytest.raises(hivox.Error, match="voxel_size"):
        hivox.Reconstruction(bad, data.camera)
    with pytest.raises(hivox.Error, match="does not exist"):
        hivox.open_dataset("/nonexistent/folder")
    with pytest.raises(IndexError):
        data.read(99)


def test_maps_save_load_and_continue(tmp_path):
    data = hivox.open_dataset(SCENE)
    whole = hivox.Reconstruction(small_params(), data.camera, noise_free=True)
    half = hivox.Reconstruction(small_params(), data.camera, noise_free=True)
    for i in range(6):
        f = data.read(i)
        whole.integrate(f["depth"], f["color"], f["T_wc_gt"])
        if i < 3:
            half.integrate(f["depth"], f["color"], f["T_wc_gt"])
    half.save_map(tmp_path / "half.hvx")
    rest = hivox.load_map(tmp_path / "half.hvx")
    for i in range(3, 6):
        f = data.read(i)
        rest.integrate(f["depth"], f["color"], f["T_wc_gt"])
    whole.save_map(tmp_path / "whole.hvx")
    rest.save_map(tmp_path / "rest.hvx")
    assert (tmp_path / "whole.hvx").read_bytes() == (tmp_path / "rest.hvx").read_bytes()
    with pytest.raises(hivox.Error, match="not a hivox map file"):
        (tmp_path / "x.hvx").write_text("nothing")
        hivox.load_map(tmp_path / "x.hvx")


def test_meshes_are_cropped_to_their_bounds():
    # A mesh made inside a box (the library skips the blocks outside) holds exactly the whole
    # mesh's triangles whose three corners lie inside it.
    data = hivox.open_dataset(SCENE)
    rec = hivox.Reconstruction(small_params(), data.camera, noise_free=True)
    for i in range(len(data)):
        f = data.read(i)
        rec.integrate(f["depth"], None, f["T_wc_gt"])
    whole = rec.extract_mesh()
    v = whole["vertices"]
    lo = v.min(axis=0) + 0.3 * (v.max(axis=0) - v.min(axis=0))
    hi = v.max(axis=0)
    params = hivox.MeshParams(bounds=(tuple(lo), tuple(hi)))
    assert np.allclose(params.bounds, (lo, hi)) and "inside [" in repr(params)
    part = rec.extract_mesh(params)

    def corners(mesh):
        return {tuple(map(tuple, np.round(mesh["vertices"][t], 6))) for t in mesh["triangles"]}

    inside = ((v >= lo) & (v <= hi)).all(axis=1)
    kept = whole["triangles"][inside[whole["triangles"]].all(axis=1)]
    assert 0 < len(kept) < len(whole["triangles"])
    assert corners(part) == corners({"vertices": v, "triangles": kept})
    params.bounds = None
    assert params.bounds is None
    assert len(rec.extract_mesh(params)["triangles"]) == len(whole["triangles"])
    with pytest.raises(hivox.Error, match="mesh bounds"):
        params.bounds = ((0.0, 0.0, 1.0), (1.0, 1.0, 0.0))
    with pytest.raises(TypeError):
        params.bounds = (0.0, 0.0, 0.0, 1.0, 1.0, 1.0)


def test_refinement_compares_detail_with_the_noise_it_is_given():
    # Two levels, the desk's noise-free frames: refinement splits where detail exceeds the larger
    # of its threshold and a fraction of the sensor's noise at the block's depth. The noise can be
    # the camera's (Reconstruction's depth_noise) or refinement's own (RefineParams.noise): the
    # same noise either way gives the same map, and a noisier sensor splits less.
    data = hivox.open_dataset("synthetic:desk?frames=40&width=160&height=120&noise=none")
    kinect = hivox.SensorNoise.kinect()
    assert kinect.sigma_m(0.4) == pytest.approx(kinect.sigma_min_m)
    assert kinect.sigma_m(1.4) == pytest.approx(kinect.sigma_min_m + kinect.quadratic_per_m)
    assert hivox.SensorNoise.none().sigma_m(3.0) == 0.0
    loud = hivox.SensorNoise(sigma_min_m=0.01, quadratic_per_m=0.02)

    def splits(noise=None, depth_noise=None, noise_free=False):
        p = hivox.ReconstructionParams(map=hivox.MapParams(voxel_size_m=0.004, levels=2),
                                       refine=hivox.RefineParams(every_n_frames=1))
        p.refine.noise = noise
        rec = hivox.Reconstruction(p, data.camera, noise_free=noise_free, depth_noise=depth_noise)
        for i in range(0, 40, 4):
            f = data.read(i)
            rec.integrate(f["depth"], None, f["T_wc_gt"])
        return rec.stats["blocks_per_level"]

    quiet = splits(noise_free=True)
    assert splits(noise=hivox.SensorNoise.none()) == quiet
    assert splits(noise=loud, noise_free=True) == splits(depth_noise=loud)
    assert splits(depth_noise=loud)[0] < quiet[0]
    r = hivox.RefineParams(noise=loud)
    assert r.noise.sigma_min_m == pytest.approx(0.01) and "sigma(z)" in repr(r)
    r.noise.sigma_min_m = -1.0  # in place
    with pytest.raises(hivox.Error, match="refine sensor noise terms must be >= 0"):
        r.validate()
    with pytest.raises(hivox.Error, match="noise_free and depth_noise"):
        hivox.Reconstruction(small_params(), data.camera, noise_free=True, depth_noise=loud)


@pytest.mark.parametrize("refine_after_raycast", [False, True])
def test_tracking_follows_the_camera(refine_after_raycast):
    # 300 frames along the scene's path, the first 8 of them (max_frames=8 would spread the path
    # over 8 frames: a synthetic scene's frame count sets its path's steps). Refining before the
    # model raycast or after it.
    data = hivox.open_dataset("synthetic:desk?frames=300&width=160&height=120&noise=none")
    p = hivox.ReconstructionParams(map=hivox.MapParams(voxel_size_m=0.008, truncation_m=0.064),
                                   refine_after_raycast=refine_after_raycast)
    assert p.refine_after_raycast == refine_after_raycast
    assert ("after the raycast" in repr(p)) == refine_after_raycast
    rec = hivox.Reconstruction(p, data.camera, noise_free=True)
    first = data.read(0)
    rec.track_and_integrate(first["depth"], first["color"], first["T_wc_gt"])
    for i in range(1, 8):
        f = data.read(i)
        s = rec.track_and_integrate(f["depth"], f["color"])
        assert s["tracking"] != "lost"
        assert np.linalg.norm(s["T_wc"][:3, 3] - f["T_wc_gt"][:3, 3]) < 0.01
    assert rec.stats["tracking"]["lost"] == 0


def test_tracking_takes_its_parameters():
    # The tracker's parameters set from Python reach the loop: two pyramid levels of at most two
    # iterations each, the model raycast at a quarter of the frame's resolution; a bad one is
    # refused when the reconstruction is made.
    data = hivox.open_dataset("synthetic:desk?frames=300&width=160&height=120&noise=none")
    p = hivox.ReconstructionParams(map=hivox.MapParams(voxel_size_m=0.008, truncation_m=0.064),
                                   track=hivox.TrackParams(iterations=[2, 2], model_subsample=4))
    assert p.track.iterations == [2, 2] and "model 1/4 resolution" in repr(p)
    rec = hivox.Reconstruction(p, data.camera, noise_free=True)
    first = data.read(0)
    rec.track_and_integrate(first["depth"], first["color"], first["T_wc_gt"])
    iterations = []
    for i in range(1, 6):
        f = data.read(i)
        s = rec.track_and_integrate(f["depth"], f["color"])
        iterations.append(s["track_iterations"])
        assert s["tracking"] == "good" and s["track_inlier_ratio"] > 0.4
        assert np.linalg.norm(s["T_wc"][:3, 3] - f["T_wc_gt"][:3, 3]) < 0.01
    assert max(iterations) <= 4 and min(iterations) >= 1, iterations
    model = rec.last_raycast()  # 160x120 at a quarter
    assert model["depth"].shape == (30, 40) and model["normals"].shape == (30, 40, 3)
    assert (model["depth"] > 0).mean() > 0.9
    p.track.max_distance_m = 0.0
    with pytest.raises(hivox.Error, match="max_distance_m must be > 0"):
        hivox.Reconstruction(p, data.camera)


@pytest.mark.skipif(not os.path.isdir(os.path.join(os.environ.get("HIVOX_DATA_DIR", ""),
                                                   "tum_fr1_rpy")),
                    reason="real data set tum_fr1_rpy not found (../shared/data)")
def test_the_example_reconstructs_a_real_sequence(tmp_path):
    script = os.path.join(os.environ.get("HIVOX_SOURCE_DIR", "."), "examples", "reconstruct.py")
    data = os.path.join(os.environ["HIVOX_DATA_DIR"], "tum_fr1_rpy")
    out = subprocess.run([sys.executable, script, data, str(tmp_path / "mesh.ply"), "--frames",
                          "20"], capture_output=True, text=True, check=True).stdout
    assert "20 frames" in out
    assert (tmp_path / "mesh.ply").stat().st_size > 100000
