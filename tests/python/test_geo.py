"""2D queries: locate against geopandas sjoin on the ZIP points and the counties (once) and
against `kiln query --op polygon`; boxes and point tables against the CLI and brute force."""
import numpy as np
import pytest
from scipy.spatial import cKDTree

import kiln
from conftest import run_cli


@pytest.fixture(scope="module")
def zip_lonlat(zipcodes):
    return zipcodes["longitude"].to_numpy(), zipcodes["latitude"].to_numpy()


def test_locate_equals_geopandas_sjoin(counties_blob, zipcodes, zip_lonlat, need_geopandas):
    geopandas = need_geopandas
    lon, lat = zip_lonlat
    with kiln.open(counties_blob) as blob:
        found = blob["pip"].locate(lon, lat)
        ids, names = blob["pip"].attributes(found)
    assert found.dtype == np.int64 and found.shape == lon.shape
    # MANIFEST.md: 41,603 points inside exactly one county, 446 in none.
    assert (found >= 0).sum() == 41603 and (found < 0).sum() == 446
    counties = geopandas.read_file(str(counties_blob.parent / "counties.geojson"))
    points = geopandas.GeoDataFrame(geometry=geopandas.points_from_xy(lon, lat), crs=counties.crs)
    joined = geopandas.sjoin(points, counties, predicate="within", how="left")
    joined = joined[~joined.index.duplicated()]
    theirs = joined["index_right"].fillna(-1).astype(np.int64).to_numpy()
    np.testing.assert_array_equal(found, theirs)
    expected_ids = [None if i < 0 else str(counties["id"][i]) for i in theirs]
    assert ids == expected_ids
    assert names[int(np.argmax(found >= 0))] == counties["name"][theirs[found >= 0][0]]


def test_locate_equals_kiln_query(tmp, counties_blob, zip_lonlat):
    lon, lat = (a[::7] for a in zip_lonlat)
    with kiln.open(counties_blob) as blob:
        found = blob["pip"].locate(lon, lat)
        assert blob["pip"].locate(float(lon[0]), float(lat[0])) == found[0]
    np.stack([lon, lat], 1).astype("<f8").tofile(tmp / "pip.in")
    run_cli("query", counties_blob, "--op", "polygon", "--in", tmp / "pip.in", "--out",
            tmp / "pip.out")
    cli = np.fromfile(tmp / "pip.out", "<u4")
    np.testing.assert_array_equal(found, np.where(cli == 0xFFFFFFFF, -1, cli.astype(np.int64)))


def test_locate_batches_equal_single_calls_on_one_and_two_threads(counties_blob, zip_lonlat):
    """The batch path (runs of points split over threads) answers as one call per point does."""
    lon, lat = zip_lonlat
    with kiln.open(counties_blob) as blob:
        one = blob["pip"].locate(lon, lat, threads=1)
        two = blob["pip"].locate(lon, lat, threads=2)
        single = [blob["pip"].locate(float(x), float(y)) for x, y in zip(lon[::13], lat[::13])]
    np.testing.assert_array_equal(one, two)
    np.testing.assert_array_equal(one[::13], single)
    assert (one < 0).sum() == 446


def test_features_in_box_equals_kiln_query(tmp, counties_blob):
    rng = np.random.default_rng(3)
    lo = rng.uniform([-125, 25], [-70, 48], (200, 2))
    boxes = np.concatenate([lo, lo + rng.uniform(0.01, 3, (200, 2))], 1)
    with kiln.open(counties_blob) as blob:
        box, feature = blob["pip"].features_in_box(boxes)
    boxes.astype("<f8").tofile(tmp / "boxes.in")
    run_cli("query", counties_blob, "--op", "polygons-in-box", "--in", tmp / "boxes.in", "--out",
            tmp / "boxes.out")
    cli = np.fromfile(tmp / "boxes.out", "<u4").reshape(-1, 2)
    np.testing.assert_array_equal(box, cli[:, 0])
    np.testing.assert_array_equal(feature, cli[:, 1])
    assert len(box) > 200


def test_range_equals_kiln_query_and_brute_force(tmp, zip_blob):
    rng = np.random.default_rng(5)
    lo = rng.uniform([-125, 25], [-70, 48], (300, 2))
    boxes = np.concatenate([lo, lo + rng.uniform(0.01, 2, (300, 2))], 1)
    with kiln.open(zip_blob) as blob:
        box, point = blob["quadtree"].range(boxes)
        pts = np.array(blob.table_points)
    boxes.astype("<f8").tofile(tmp / "range.in")
    run_cli("query", zip_blob, "--op", "range", "--in", tmp / "range.in", "--out",
            tmp / "range.csv")
    cli = np.loadtxt(tmp / "range.csv", delimiter=",", skiprows=1, dtype=np.int64).reshape(-1, 2)
    np.testing.assert_array_equal(np.stack([box, point], 1), cli)
    for i in range(0, 300, 30):
        x0, y0, x1, y1 = boxes[i]
        inside = np.flatnonzero((pts[:, 0] >= x0) & (pts[:, 0] <= x1) & (pts[:, 1] >= y0) &
                                (pts[:, 1] <= y1))
        np.testing.assert_array_equal(point[box == i], inside)


def test_point_table_knn_like_ckdtree(zip_blob):
    rng = np.random.default_rng(6)
    q = rng.uniform([-125, 25], [-70, 48], (2000, 2))
    with kiln.open(zip_blob) as blob:
        d, i = blob["quadtree"].knn(q, k=4)
        tree = cKDTree(np.array(blob.table_points))
        near = blob["quadtree"].radius(q[:100], 0.3)
    rd, ri = tree.query(q, k=4)
    np.testing.assert_allclose(d, rd, rtol=1e-12)
    # ZIP codes share points (00501 and 00544): compare indices where distances differ.
    clear = np.all(np.diff(tree.query(q, k=5)[0], axis=1) > 1e-9, axis=1)
    np.testing.assert_array_equal(i[clear], ri[clear])
    for ours, theirs in zip(near, tree.query_ball_point(q[:100], 0.3)):
        assert set(ours.tolist()) == set(theirs)


def test_attributes_of_a_point_table(zip_blob, zipcodes):
    with kiln.open(zip_blob) as blob:
        ids, names = blob["quadtree"].attributes([0, 1, -1])
    assert ids[2] is None and names[2] is None
    assert len(ids) == 3


def test_nan_points_and_boxes(counties_blob, zip_blob):
    with kiln.open(counties_blob) as blob:
        found = blob["pip"].locate([np.nan, -90.0, np.inf], [40.0, np.nan, 40.0])
        np.testing.assert_array_equal(found, [-1, -1, -1])
        box, feature = blob["pip"].features_in_box([[np.nan, 30, -80, 40]])
        assert len(box) == 0
    with kiln.open(zip_blob) as blob:
        box, point = blob["quadtree"].range([[-100, np.nan, -90, 40], [-100, 30, -90, 40]])
        assert len(box) > 0 and np.all(box == 1)


def test_layer_views(counties_blob, zip_blob):
    """The 2D inputs' arrays are read-only views, consistent with each other."""
    with kiln.open(counties_blob) as blob:
        v, rings = blob.layer_vertices, blob.ring_offsets
        polygons, features = blob.polygon_offsets, blob.feature_offsets
        assert v.dtype == np.float64 and v.shape[1] == 2 and not v.flags.writeable
        assert rings[-1] == len(v) and polygons[-1] == len(rings) - 1
        assert features[-1] == len(polygons) - 1 and len(features) - 1 == 3231
        assert blob.table_points is None and len(blob.vertices) == 0
    with kiln.open(zip_blob) as blob:
        assert blob.table_points.shape == (42049, 2) and blob.layer_vertices is None
        with pytest.raises(ValueError, match="read-only"):
            blob.table_points[0, 0] = 1


def test_point_table_knn_and_radius_equal_kiln_query(tmp, zip_blob):
    rng = np.random.default_rng(8)
    q = rng.uniform([-125, 25], [-70, 48], (500, 2))
    q.astype("<f8").tofile(tmp / "knn2d.in")
    with kiln.open(zip_blob) as blob:
        d, i = blob["quadtree"].knn(q, k=3)
        near = blob["quadtree"].radius(q, 0.2)
    for op, extra in (("knn2d", ["--k", "3"]), ("radius2d", ["--radius", "0.2"])):
        run_cli("query", zip_blob, "--op", op, "--in", tmp / "knn2d.in", "--out",
                tmp / f"{op}.csv", *extra)
    rows = np.loadtxt(tmp / "knn2d.csv", delimiter=",", skiprows=1).reshape(-1, 3)
    np.testing.assert_array_equal(rows[:, 1].astype(np.int64).reshape(-1, 3), i)
    np.testing.assert_allclose(rows[:, 2].reshape(-1, 3), d, rtol=1e-15)
    rows = np.loadtxt(tmp / "radius2d.csv", delimiter=",", skiprows=1).reshape(-1, 3)
    expected = [rows[rows[:, 0] == k, 1].astype(np.int64) for k in range(len(q))]
    for ours, theirs in zip(near, expected):
        np.testing.assert_array_equal(ours, theirs)
    assert sum(map(len, near)) > 100
