"""Every bad input raises the stated exception with a message naming the argument; nothing
crashes the interpreter."""
import numpy as np
import pytest

import kiln


@pytest.fixture(scope="module")
def blob(mesh_blob):
    with kiln.open(mesh_blob) as b:
        yield b


@pytest.mark.parametrize("call,error,message", [
    (lambda b: b["bvh"].intersect(np.zeros((4, 2)), np.zeros((4, 3))), ValueError,
     r"origins: expected shape \(n, 3\) or \(3,\), got \(4, 2\)"),
    (lambda b: b["bvh"].intersect(np.zeros((4, 3)), np.zeros((5, 3))), ValueError,
     r"origins: expected shape \(5, 3\) or \(3,\) to match directions, got \(4, 3\)"),
    (lambda b: b["bvh"].intersect(np.zeros((4, 3)), np.zeros((4, 3, 1))), ValueError,
     r"directions: expected shape \(n, 3\)"),
    (lambda b: b["bvh"].intersect("rays", np.zeros((4, 3))), TypeError,
     r"origins: expected an array of shape \(n, 3\) of numbers, got str"),
    (lambda b: b["bvh"].intersect([[1, 2, "x"]], np.zeros((1, 3))), TypeError,
     r"origins: expected an array of shape \(n, 3\) convertible to float32"),
    (lambda b: b["bvh"].intersect(None, np.zeros((1, 3))), TypeError, r"origins"),
    (lambda b: b["bvh"].intersect(np.zeros((4, 3)), np.ones((4, 3)), tmax=np.ones(3)), ValueError,
     r"tmax: expected a number or shape \(4,\), got \(3,\)"),
    (lambda b: b["bvh"].occluded(np.zeros((4, 3)), np.ones((4, 3)), threads="all"), TypeError,
     r"threads: expected None or an int"),
    (lambda b: b["bvh"].occluded(np.zeros((4, 3)), np.ones((4, 3)), threads=-5), ValueError,
     r"threads: expected None, -1 or 0"),
    (lambda b: b["points"].knn(np.zeros((4, 2))), ValueError,
     r"points: expected shape \(n, 3\) or \(3,\), got \(4, 2\)"),
    (lambda b: b["points"].knn(np.zeros((4, 3)), k=0), ValueError, r"k: expected an int >= 1"),
    (lambda b: b["points"].knn(np.zeros((4, 3)), k=2.5), TypeError, r"k: expected an int"),
    (lambda b: b["points"].radius(np.zeros((4, 3)), -1.0), ValueError, r"r: expected a number >= 0"),
    (lambda b: b["points"].radius(np.zeros((4, 3)), float("nan")), ValueError, r"r: expected"),
    (lambda b: b["bvh"].closest(np.zeros((4, 3)), max_distance=0), ValueError, r"max_distance"),
    (lambda b: b["bvh"].knn(np.zeros((4, 3))), TypeError,
     r"structure 'bvh' \(bvh\) cannot answer knn; it offers rays \(intersect, occluded\), "
     r"surface \(closest, inside\)"),
    (lambda b: b["points"].intersect(np.zeros((4, 3)), np.ones((4, 3))), TypeError,
     r"structure 'points' \(points\) cannot answer intersect; it offers neighbours"),
    (lambda b: b["kdtree"].occupied(np.zeros((4, 3))), TypeError, r"cannot answer occupied"),
    (lambda b: b["dag"].inside(np.zeros((4, 3))), TypeError,
     r"'dag' \(dag\) cannot answer inside; it offers rays .*occupancy"),
    (lambda b: b["bvh"].locate([1.0], [2.0]), TypeError, r"cannot answer locate"),
    (lambda b: b["bvh"].range([[0, 0, 1, 1]]), TypeError, r"cannot answer range"),
    (lambda b: b["bvh"].count(), TypeError, r"cannot answer count"),
    (lambda b: b["bvh"].attributes([0]), TypeError, r"not over a 2D layer"),
    (lambda b: b["nope"], KeyError, r"no structure 'nope'"),
    (lambda b: kiln.open(3), TypeError, r"path: expected a path"),
])
def test_bad_input(blob, call, error, message):
    with pytest.raises(error, match=message):
        call(blob)


def test_bad_2d_input(counties_blob):
    with kiln.open(counties_blob) as blob:
        pip = blob["pip"]
        with pytest.raises(ValueError, match=r"lat: expected shape \(3,\) to match lon, got \(2,\)"):
            pip.locate([1.0, 2.0, 3.0], [1.0, 2.0])
        with pytest.raises(ValueError, match=r"lon: expected shape \(n,\), got \(2, 2\)"):
            pip.locate(np.zeros((2, 2)), np.zeros(2))
        with pytest.raises(ValueError, match=r"boxes: expected shape \(n, 4\), got \(2, 3\)"):
            pip.features_in_box(np.zeros((2, 3)))
        with pytest.raises(ValueError, match=r"indices: 5000 is out of range for 3231 features"):
            pip.attributes([5000])
        with pytest.raises(TypeError, match=r"cannot answer knn; it offers polygons \(locate\)"):
            pip.knn([[0.0, 0.0]])


def test_empty_and_odd_but_valid_input(blob):
    bvh = blob["bvh"]
    assert bvh.intersect(np.empty((0, 3)), np.empty((0, 3))).shape == (0,)
    assert bvh.occluded(np.empty((0, 3)), np.empty((0, 3))).shape == (0,)
    d, i = blob["points"].knn(np.empty((0, 3)), k=3)
    assert d.shape == (0, 3) and i.shape == (0, 3)
    assert blob["points"].radius(np.empty((0, 3)), 1.0) == []
    # Integer and big-endian inputs are converted.
    pts = np.array([[0, 1, 0], [0, 0, 0]], dtype=">i4")
    np.testing.assert_array_equal(blob["points"].knn(pts)[1],
                                  blob["points"].knn(pts.astype(np.float32))[1])
