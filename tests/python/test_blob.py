"""kiln.open: structures as `kiln dump` lists them, zero-copy views, lifetime, broken blobs."""
import gc
import json
import shutil
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import kiln
from conftest import ROOT, cli_error, run_cli


def mapped_ranges(path):
    """The address ranges of this process's mappings of `path` (/proc/self/maps)."""
    ranges = []
    real = str(path.resolve())
    with open("/proc/self/maps") as maps:
        for line in maps:
            fields = line.split()
            if len(fields) >= 6 and fields[5] == real:
                lo, hi = (int(x, 16) for x in fields[0].split("-"))
                ranges.append((lo, hi))
    return ranges


def test_structures_match_kiln_dump(mesh_blob):
    dump = json.loads(run_cli("dump", mesh_blob, "--json").stdout)["manifest"]
    with kiln.open(mesh_blob) as blob:
        assert list(blob) == [s["name"] for s in dump["structures"]]
        assert len(blob) == 4 and "bvh" in blob and "nope" not in blob
        for ours, theirs in zip(blob.structures, dump["structures"]):
            assert ours["name"] == theirs["name"] and ours["kind"] == theirs["kind"]
            assert ours["sections"] == theirs["sections"]
            # The same numbers, once both went through JSON (floats as nlohmann prints them).
            assert json.loads(json.dumps(ours["stats"])) == pytest.approx(theirs[theirs["kind"]])
        assert blob.input["triangle_count"] == len(blob.triangles)
        assert blob["bvh"].kind == "bvh" and "rays" in blob["bvh"].capabilities


def test_views_are_the_mapped_bytes(mesh_blob):
    with kiln.open(mesh_blob) as blob:
        ranges = mapped_ranges(mesh_blob)
        assert ranges, "the blob is not mapped"
        for array in (blob.vertices, blob.triangles, blob.normals, blob.triangle_mesh_ids):
            address = array.__array_interface__["data"][0]
            assert any(lo <= address and address + array.nbytes <= hi for lo, hi in ranges)
            assert not array.flags.writeable and not array.flags.owndata
            with pytest.raises(ValueError, match="read-only"):
                array[0] = 0
            with pytest.raises(ValueError):
                array.setflags(write=True)
        assert blob.vertices.dtype == np.float32 and blob.vertices.shape[1] == 3
        assert blob.triangles.dtype == np.uint32
        assert blob.layer_vertices is None and blob.table_points is None
        # The views show the blob's bytes: every triangle's corners are vertices.
        assert blob.triangles.max() < len(blob.vertices)


def test_views_and_structures_outlive_close(mesh_blob, rays):
    blob = kiln.open(mesh_blob)
    vertices, bvh = blob.vertices, blob["bvh"]
    expected = vertices.copy()
    hits = bvh.intersect(*rays)
    blob.close()
    assert blob.closed
    with pytest.raises(ValueError, match="closed"):
        blob.vertices
    with pytest.raises(ValueError, match="closed"):
        blob["bvh"]
    del blob
    gc.collect()
    np.testing.assert_array_equal(vertices, expected)  # still mapped: the view holds it
    np.testing.assert_array_equal(bvh.intersect(*rays), hits)
    ranges_before = mapped_ranges(mesh_blob)
    del bvh
    gc.collect()
    assert mapped_ranges(mesh_blob) == ranges_before  # `vertices` still holds the mapping
    del vertices
    gc.collect()
    assert mapped_ranges(mesh_blob) == []  # the last holder gone: unmapped


def test_context_manager_closes(mesh_blob):
    with kiln.open(mesh_blob) as blob:
        pass
    assert blob.closed
    blob.close()  # twice is fine


def test_many_threads_one_blob(mesh_blob, rays):
    org, dirs = rays
    with kiln.open(mesh_blob) as blob:
        bvh, points = blob["bvh"], blob["points"]
        hits = bvh.intersect(org, dirs, threads=1)
        near = points.knn(org, k=4, threads=1)

        def work(i):
            if i % 2:
                return np.array_equal(bvh.intersect(org, dirs, threads=2), hits)
            d, n = points.knn(org, k=4, threads=2)
            return np.array_equal(d, near[0]) and np.array_equal(n, near[1])

        with ThreadPoolExecutor(8) as pool:
            assert all(pool.map(work, range(32)))


def test_close_while_other_threads_query(mesh_blob, rays):
    blob = kiln.open(mesh_blob)
    bvh = blob["bvh"]
    expected = bvh.intersect(*rays)
    results = []
    threads = [threading.Thread(target=lambda: results.append(bvh.intersect(*rays)))
               for _ in range(4)]
    for t in threads:
        t.start()
    blob.close()
    del blob
    for t in threads:
        t.join()
    assert len(results) == 4 and all(np.array_equal(r, expected) for r in results)


def test_compressed_blob(tmp, mesh_blob):
    path = tmp / "compressed.kiln"
    run_cli("build", ROOT / "samples" / "wuson.obj", "-o", path, "--accel", "bvh", "--compress")
    with kiln.open(path) as packed, kiln.open(mesh_blob) as plain:
        np.testing.assert_array_equal(packed.vertices, plain.vertices)
        assert not packed.vertices.flags.writeable


def broken_copy(tmp, mesh_blob, name, edit):
    path = tmp / name
    shutil.copy(mesh_blob, path)
    data = bytearray(path.read_bytes())
    edit(data)
    path.write_bytes(bytes(data))
    return path


@pytest.mark.parametrize("name,edit", [
    ("truncated.kiln", lambda d: d.__delitem__(slice(len(d) // 2, None))),
    ("magic.kiln", lambda d: d.__setitem__(slice(0, 4), b"XXXX")),
    ("empty.kiln", lambda d: d.clear()),
])
def test_broken_blob_raises_format_error_with_the_cli_line(tmp, mesh_blob, name, edit):
    path = broken_copy(tmp, mesh_blob, name, edit)
    with pytest.raises(kiln.FormatError) as error:
        kiln.open(str(path))
    assert str(error.value) == cli_error("dump", path)
    assert isinstance(error.value, ValueError)


def test_verify_finds_what_kiln_verify_finds(tmp, mesh_blob):
    with kiln.open(mesh_blob) as blob:
        blob.verify()
    # A flipped byte deep in the vertices: open passes (O(sections)), verify's checksum fails.
    with kiln.open(mesh_blob) as blob:
        offset = blob.vertices.__array_interface__["data"][0] - min(
            lo for lo, _ in mapped_ranges(mesh_blob))
    path = broken_copy(tmp, mesh_blob, "flipped.kiln",
                       lambda d: d.__setitem__(offset + 5, d[offset + 5] ^ 0x40))
    with kiln.open(path) as blob:
        with pytest.raises(kiln.FormatError) as error:
            blob.verify()
    assert str(error.value) == cli_error("verify", path)


def test_missing_file_and_missing_structure(tmp, mesh_blob):
    with pytest.raises(kiln.FormatError) as error:
        kiln.open(str(tmp / "nothing.kiln"))
    assert str(error.value) == cli_error("dump", tmp / "nothing.kiln")
    with kiln.open(mesh_blob) as blob:
        with pytest.raises(KeyError, match="no structure 'nope'.*bvh, kdtree, points, dag"):
            blob["nope"]
