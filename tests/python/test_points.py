"""Point queries: knn like scipy's cKDTree and like `kiln query --op knn`, radius, closest,
inside and occupied like `kiln query`."""
import numpy as np
import pytest
from scipy.spatial import cKDTree

import kiln
from conftest import run_cli


@pytest.fixture(scope="module")
def queries(mesh_blob):
    rng = np.random.default_rng(11)
    with kiln.open(mesh_blob) as blob:
        v = np.array(blob.vertices)
    q = rng.uniform(v.min(0) - 0.2, v.max(0) + 0.2, (1500, 3)).astype(np.float32)
    q[:100] = v[rng.integers(0, len(v), 100)]  # on points: distance 0, ties broken by index
    return q


def cli_query(tmp, blob, op, points, *extra):
    path, out = tmp / f"{op}.in", tmp / f"{op}.out"
    np.ascontiguousarray(points, np.float32).tofile(path)
    run_cli("query", blob, "--op", op, "--in", path, "--out", out, *map(str, extra))
    return out.read_bytes()


def gaps_clear(d, eps=1e-5):
    """Rows whose sorted distances are all apart (float vs double rounding cannot reorder)."""
    return np.all(np.diff(d, axis=1) > eps, axis=1) if d.ndim == 2 else np.ones(len(d), bool)


def test_knn_like_ckdtree(mesh_blob, queries):
    with kiln.open(mesh_blob) as blob:
        points = blob["points"]
        tree = cKDTree(np.array(blob.vertices))
        for k in (1, 5, [2], [1, 3]):
            d, i = points.knn(queries, k=k)
            rd, ri = tree.query(queries, k=k)
            assert d.shape == rd.shape and i.shape == ri.shape, k
            assert d.dtype == rd.dtype == np.float64 and i.dtype == ri.dtype == np.int64
            np.testing.assert_allclose(d, rd, rtol=1e-6, atol=1e-7)
            # Rows where no two of the first max(k) + 1 distances tie (the sample has duplicate
            # vertices at seams: kiln orders ties by index, cKDTree does not promise to).
            ranks = max(k) if isinstance(k, list) else k
            clear = gaps_clear(tree.query(queries, k=ranks + 1)[0])
            np.testing.assert_array_equal(i[clear], ri[clear])
            assert clear.mean() > 0.9
        # One point: Python scalars for k=1, (k,) arrays otherwise, as cKDTree.
        d, i = points.knn(queries[200])
        rd, ri = tree.query(queries[200])
        assert isinstance(d, float) and isinstance(i, int) and (d, i) == pytest.approx((rd, ri))
        d, i = points.knn(queries[200], k=3)
        assert d.shape == (3,) and i.shape == (3,)
        # More neighbours than points: inf and n, as cKDTree.
        n = len(blob.vertices)
        d, i = points.knn(queries[:4], k=n + 2)
        rd, ri = tree.query(queries[:4], k=n + 2)
        np.testing.assert_array_equal(i[:, -2:], ri[:, -2:])
        assert np.all(np.isinf(d[:, -2:])) and np.all(i[:, -2:] == n)


def test_knn_ties_go_to_the_lower_index(tmp):
    pts = np.array([[0, 0, 0], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float32)
    header = f"ply\nformat ascii 1.0\nelement vertex {len(pts)}\nproperty float x\n" \
             "property float y\nproperty float z\nend_header\n"
    (tmp / "ties.ply").write_text(header + "\n".join(" ".join(map(str, p)) for p in pts) + "\n")
    path = tmp / "ties.kiln"
    run_cli("build", tmp / "ties.ply", "-o", path, "--accel", "points")
    with kiln.open(path) as blob:
        d, i = blob["points"].knn([[0, 0, 0]], k=5)
        np.testing.assert_array_equal(i, [[0, 1, 2, 3, 4]])


def test_knn_and_radius_equal_kiln_query(tmp, mesh_blob, queries):
    with kiln.open(mesh_blob) as blob:
        d, i = blob["points"].knn(queries, k=6)
        near = blob["points"].radius(queries, 0.05)
    records = np.frombuffer(cli_query(tmp, mesh_blob, "knn", queries, "--k", 6,
                                      "--accel", "points"),
                            dtype=[("id", "<u4"), ("d2", "<f4")]).reshape(-1, 6)
    np.testing.assert_array_equal(i, records["id"].astype(np.int64))
    np.testing.assert_allclose(d * d, records["d2"], rtol=1e-5, atol=1e-10)
    raw = np.frombuffer(cli_query(tmp, mesh_blob, "radius", queries, "--radius", 0.05,
                                  "--accel", "points"), "<u4")
    at = 0
    for ids in near:
        count = raw[at]
        np.testing.assert_array_equal(ids, raw[at + 1:at + 1 + count])
        at += 1 + count
    assert at == len(raw) and sum(map(len, near)) > 100
    assert near[0].dtype == np.int64


def test_radius_like_ckdtree(mesh_blob, queries):
    with kiln.open(mesh_blob) as blob:
        near = blob["points"].radius(queries[:300], 0.08)
        tree = cKDTree(np.array(blob.vertices))
    for ours, theirs in zip(near, tree.query_ball_point(queries[:300], 0.08)):
        assert set(ours.tolist()) == set(theirs)


def test_closest_and_inside_equal_kiln_query(tmp, mesh_blob, queries):
    with kiln.open(mesh_blob) as blob:
        dist, point, prim = blob["bvh"].closest(queries)
        inside = blob["bvh"].inside(queries)
        kd_dist, _, _ = blob["kdtree"].closest(queries)
    records = np.frombuffer(cli_query(tmp, mesh_blob, "closest", queries, "--accel", "bvh"),
                            dtype=[("d", "<f4"), ("prim", "<u4"), ("p", "<f4", 3)])
    np.testing.assert_array_equal(dist, records["d"])
    np.testing.assert_array_equal(prim, records["prim"].astype(np.int64))
    np.testing.assert_array_equal(point, records["p"])
    np.testing.assert_allclose(kd_dist, dist, rtol=1e-5, atol=1e-6)
    flags = np.frombuffer(cli_query(tmp, mesh_blob, "inside", queries, "--accel", "bvh"), "u1")
    np.testing.assert_array_equal(inside, flags.astype(bool))
    # Brute force for the distance: never farther than the nearest vertex.
    with kiln.open(mesh_blob) as blob:
        nearest_vertex = cKDTree(np.array(blob.vertices)).query(queries)[0]
    assert np.all(dist <= nearest_vertex + 1e-6)


def test_closest_within_max_distance(mesh_blob, queries):
    with kiln.open(mesh_blob) as blob:
        dist, point, prim = blob["bvh"].closest(queries, max_distance=0.01)
    far = prim < 0
    assert far.any() and (~far).any()
    assert np.all(np.isinf(dist[far])) and np.all(np.isnan(point[far]))
    assert np.all(dist[~far] <= 0.01)


def test_occupied_equals_kiln_query(tmp, mesh_blob, queries):
    with kiln.open(mesh_blob) as blob:
        solid = blob["dag"].occupied(queries)
    flags = np.frombuffer(cli_query(tmp, mesh_blob, "occupied", queries, "--accel", "dag"), "u1")
    np.testing.assert_array_equal(solid, flags.astype(bool))
    assert solid.any() and not solid.all()


def test_nan_queries_find_nothing(mesh_blob):
    q = np.array([[np.nan, 0, 0], [0, np.inf, 0], [0, 0, 0]], np.float32)
    with kiln.open(mesh_blob) as blob:
        n = len(blob.vertices)
        d, i = blob["points"].knn(q, k=2)
        assert np.all(np.isinf(d[:2])) and np.all(i[:2] == n) and np.all(i[2] < n)
        near = blob["points"].radius(q, 10.0)
        assert len(near[0]) == 0 and len(near[1]) == 0 and len(near[2]) > 0
        dist, point, prim = blob["bvh"].closest(q)
        assert list(prim[:2]) == [-1, -1] and prim[2] >= 0
        assert not blob["bvh"].inside(q)[:2].any()
        assert not blob["dag"].occupied(q)[:2].any()
