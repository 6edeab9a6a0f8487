"""Ray queries: intersect and occluded equal `kiln trace` on the same blob and rays, and a
brute-force ray-triangle test."""
import numpy as np
import pytest

import kiln
from conftest import run_cli

HIT = np.dtype([("t", "<f4"), ("prim", "<u4"), ("u", "<f4"), ("v", "<f4")])
VOXEL_HIT = np.dtype([("t", "<f4"), ("voxel", "<u4", 3), ("face_normal", "<f4", 3),
                      ("normal", "<f4", 3)])


def cli_trace(tmp, blob, accel, org, dirs, any_hit=False, tmin=0.0, tmax=np.inf):
    """`kiln trace` on a RAYS file of the same float32 rays: its HITS records."""
    records = np.zeros((len(org), 8), np.float32)
    records[:, 0:3], records[:, 3], records[:, 4:7], records[:, 7] = org, tmin, dirs, tmax
    rays, hits = tmp / f"{accel}.rays", tmp / f"{accel}.hits"
    records.tofile(rays)
    run_cli("trace", blob, "--rays", rays, "--out", hits, "--accel", accel,
            *(["--any-hit"] if any_hit else []))
    return np.fromfile(hits, dtype=VOXEL_HIT if accel in ("dag", "esvo") else HIT)


@pytest.mark.parametrize("accel", ["bvh", "kdtree"])
def test_intersect_equals_kiln_trace(tmp, mesh_blob, rays, accel):
    org, dirs = rays
    with kiln.open(mesh_blob) as blob:
        hits = blob[accel].intersect(org, dirs)
    cli = cli_trace(tmp, mesh_blob, accel, org, dirs)
    assert hits.dtype.names == ("t", "prim", "u", "v")
    assert hits["t"].dtype == np.float32 and hits["prim"].dtype == np.int64
    np.testing.assert_array_equal(hits["t"], cli["t"])
    np.testing.assert_array_equal(hits["prim"], np.where(cli["prim"] == 0xFFFFFFFF, -1,
                                                         cli["prim"].astype(np.int64)))
    np.testing.assert_array_equal(hits["u"], cli["u"])
    np.testing.assert_array_equal(hits["v"], cli["v"])
    assert 200 < (hits["prim"] >= 0).sum() < len(org)
    assert np.all(np.isinf(hits["t"][hits["prim"] < 0]))


def test_voxel_intersect_equals_kiln_trace(tmp, mesh_blob, rays):
    org, dirs = rays
    with kiln.open(mesh_blob) as blob:
        hits = blob["dag"].intersect(org, dirs)
    cli = cli_trace(tmp, mesh_blob, "dag", org, dirs)
    np.testing.assert_array_equal(hits["t"], cli["t"])
    voxel = np.where(cli["voxel"] == 0xFFFFFFFF, -1, cli["voxel"].astype(np.int64))
    np.testing.assert_array_equal(hits["voxel"], voxel)
    np.testing.assert_array_equal(hits["normal"], cli["normal"])
    np.testing.assert_array_equal(hits["face_normal"], cli["face_normal"])
    np.testing.assert_array_equal(hits["prim"], np.where(np.isinf(cli["t"]), -1, 0))


@pytest.mark.parametrize("accel", ["bvh", "kdtree", "dag"])
def test_occluded_equals_kiln_trace_any_hit(tmp, mesh_blob, rays, accel):
    org, dirs = rays
    with kiln.open(mesh_blob) as blob:
        blocked = blob[accel].occluded(org, dirs, tmax=2.0)
    cli = cli_trace(tmp, mesh_blob, accel, org, dirs, any_hit=True, tmax=2.0)
    assert blocked.dtype == np.bool_
    np.testing.assert_array_equal(blocked, ~np.isinf(cli["t"]))


def brute_force(v, tri, org, dirs):
    """Closest t per ray over every triangle (Moller-Trumbore in float64)."""
    a, b, c = (v[tri[:, k]].astype(np.float64) for k in range(3))
    e1, e2 = b - a, c - a
    best = np.full(len(org), np.inf)
    for i, (o, d) in enumerate(zip(org.astype(np.float64), dirs.astype(np.float64))):
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1 / np.where(ok, det, 1), 0)
        s = o - a
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        w = (q @ d) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
        hit = ok & (u >= 0) & (w >= 0) & (u + w <= 1) & (t >= 0)
        if hit.any():
            best[i] = t[hit].min()
    return best


def test_intersect_equals_brute_force(mesh_blob, rays):
    # The random half: rays aimed at vertices hit exactly on edges, where tests may differ.
    org, dirs = rays[0][1:800:2], rays[1][1:800:2]
    with kiln.open(mesh_blob) as blob:
        hits = blob["bvh"].intersect(org, dirs)
        expected = brute_force(np.array(blob.vertices), np.array(blob.triangles), org, dirs)
    # Watertight vs Moller-Trumbore differ only on edges: compare where both are clear.
    both = np.isfinite(expected) == np.isfinite(hits["t"])
    assert both.mean() > 0.99
    np.testing.assert_allclose(hits["t"][both & np.isfinite(expected)],
                               expected[both & np.isfinite(expected)], rtol=1e-4, atol=1e-5)


def test_inputs_are_converted_and_broadcast(mesh_blob, rays):
    org, dirs = rays
    with kiln.open(mesh_blob) as blob:
        bvh = blob["bvh"]
        ref = bvh.intersect(org, dirs)
        # float64, Fortran order, strided and list inputs give the same answers.
        np.testing.assert_array_equal(bvh.intersect(org.astype(np.float64),
                                                    np.asfortranarray(dirs)), ref)
        wide = np.zeros((len(org), 6), np.float32)
        wide[:, ::2] = org
        np.testing.assert_array_equal(bvh.intersect(wide[:, ::2], dirs), ref)
        np.testing.assert_array_equal(bvh.intersect(org[:3].tolist(), dirs[:3].tolist()),
                                      ref[:3])
        # One origin for every direction; per-ray tmax; threads never change the answer.
        one = bvh.intersect(org[0], dirs)
        np.testing.assert_array_equal(one, bvh.intersect(np.repeat(org[:1], len(dirs), 0), dirs))
        t = np.where(np.isfinite(ref["t"]), ref["t"] * 0.5, 1.0).astype(np.float32)
        cut = bvh.intersect(org, dirs, tmax=t)
        assert np.all(cut["t"][np.isfinite(cut["t"])] <= t[np.isfinite(cut["t"])])
        np.testing.assert_array_equal(bvh.intersect(org, dirs, threads=1), ref)
        assert len(bvh.intersect(np.zeros((0, 3)), np.zeros((0, 3)))) == 0


def test_nan_and_inf_rays_are_misses(mesh_blob, rays):
    org, dirs = (a[:8].copy() for a in rays)
    org[0, 0], dirs[1, 2], org[2, 1] = np.nan, np.nan, np.inf
    with kiln.open(mesh_blob) as blob:
        for name in ("bvh", "dag"):
            hits = blob[name].intersect(org, dirs, tmin=np.array([0, 0, 0, np.nan, 0, 0, 0, 0]))
            assert np.all(hits["prim"][:4] == -1) and np.all(np.isinf(hits["t"][:4]))
            assert not blob[name].occluded(org, dirs)[:3].any()


def test_depth_image_example(tmp):
    """examples/python/depth_image.py runs and writes a PNG."""
    import os
    import subprocess
    import sys
    from conftest import ROOT
    out = tmp / "depth.png"
    subprocess.run([sys.executable, str(ROOT / "examples" / "python" / "depth_image.py"), "",
                    str(out)], check=True, capture_output=True, env=dict(os.environ))
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_esvo_hits_carry_the_stored_colour(tmp):
    """An ESVO of a one-colour mesh stores that colour on every voxel: the hits' `color` field
    is the input's RGBA, misses are zero, and the rest of the record equals `kiln trace`."""
    ply = tmp / "orange_tetra.ply"
    corners = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    ply.write_text("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\n"
                   "property float y\nproperty float z\nproperty uchar red\n"
                   "property uchar green\nproperty uchar blue\nproperty uchar alpha\n"
                   "element face 4\nproperty list uchar int vertex_indices\nend_header\n" +
                   "".join(f"{x} {y} {z} 200 100 50 255\n" for x, y, z in corners) +
                   "".join(f"3 {a} {b} {c}\n" for a, b, c in faces))
    blob_path = tmp / "orange.kiln"
    run_cli("build", ply, "-o", blob_path, "--accel", "esvo:resolution=32")
    rng = np.random.default_rng(3)
    n = 500
    org = np.tile(np.float32([2.0, 2.0, 2.0]), (n, 1))
    dirs = (rng.uniform(0.0, 0.6, (n, 3)) - org).astype(np.float32)
    with kiln.open(blob_path) as blob:
        hits = blob["esvo"].intersect(org, dirs)
    assert "color" in hits.dtype.names and hits["color"].dtype == np.uint8
    hit = ~np.isinf(hits["t"])
    assert 50 < hit.sum() < n
    np.testing.assert_array_equal(hits["color"][hit], np.tile([200, 100, 50, 255], (hit.sum(), 1)))
    assert not hits["color"][~hit].any()
    cli = cli_trace(tmp, blob_path, "esvo", org, dirs)
    np.testing.assert_array_equal(hits["t"], cli["t"])
    np.testing.assert_array_equal(hits["normal"], cli["normal"])
