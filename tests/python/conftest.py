"""Shared fixtures of the kiln module's tests: the CLI, blobs built by it, the shared data.

CTest runs these with PYTHONPATH at the build's python/ folder and KILN_CLI naming the kiln
executable (tests/python/CMakeLists.txt); run by hand:
    PYTHONPATH=build/python KILN_CLI=build/tools/kiln /usr/bin/python3 -m pytest tests/python
"""
import os
import pathlib
import shutil
import subprocess

import numpy as np
import pytest

import kiln

ROOT = pathlib.Path(__file__).resolve().parents[2]
DATA = ROOT.parent / "shared" / "data"
CLI = os.environ.get("KILN_CLI", str(ROOT / "build" / "tools" / "kiln"))


def run_cli(*args, check=True):
    """Runs `kiln ARGS`; returns the CompletedProcess (text)."""
    result = subprocess.run([CLI, *map(str, args)], capture_output=True, text=True)
    if check and result.returncode != 0:
        raise AssertionError(f"kiln {' '.join(map(str, args))}: {result.stderr}")
    return result


def cli_error(*args):
    """The one-line message `kiln CMD` prints on failure, without its `kiln CMD: ` prefix."""
    result = run_cli(*args, check=False)
    assert result.returncode != 0
    line = result.stderr.strip().splitlines()[-1]
    prefix = f"kiln {args[0]}: "
    assert line.startswith(prefix), line
    return line[len(prefix):]


def need_data(*parts):
    path = DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"shared data {path} is absent")
    return path


@pytest.fixture(scope="session")
def tmp(tmp_path_factory):
    return tmp_path_factory.mktemp("kiln")


@pytest.fixture(scope="session")
def mesh_blob(tmp):
    """The sample mesh with every capability but the 2D ones: rays (bvh, kdtree), surface,
    neighbours (points), voxels (dag, with occupancy)."""
    path = tmp / "wuson.kiln"
    run_cli("build", ROOT / "samples" / "wuson.obj", "-o", path, "--accel", "bvh", "--accel",
            "kdtree", "--accel", "points", "--accel", "dag:resolution=64,solid=true")
    return path


@pytest.fixture(scope="session")
def rays(mesh_blob):
    """2,000 rays: half from outside towards the mesh, half random; float32."""
    rng = np.random.default_rng(7)
    with kiln.open(mesh_blob) as blob:
        v = np.array(blob.vertices)
    lo, hi = v.min(0), v.max(0)
    n = 2000
    org = rng.uniform(lo - 0.5, hi + 0.5, (n, 3)).astype(np.float32)
    target = v[rng.integers(0, len(v), n)]
    dirs = np.where(np.arange(n)[:, None] % 2 == 0, target - org,
                    rng.normal(size=(n, 3))).astype(np.float32)
    return org, dirs


@pytest.fixture(scope="session")
def counties_blob(tmp):
    path = tmp / "counties.kiln"
    run_cli("build", need_data("geo", "us-counties-10m.geojson.zst"), "-o", path, "--accel",
            "polygon-index:name=pip")
    return path


def unzstd(path, out):
    """The shared data's .zst files, inflated with the zstd tool (Python has no zstandard)."""
    if not out.exists():
        if shutil.which("zstd") is None:
            pytest.skip("the zstd tool is absent")
        out.write_bytes(subprocess.run(["zstd", "-dc", str(path)], capture_output=True,
                                       check=True).stdout)
    return out


@pytest.fixture(scope="session")
def zipcodes(tmp):
    """The 42,049 ZIP points (zip_code, latitude, longitude, city, state, county), by pandas."""
    import pandas as pd
    csv = unzstd(need_data("geo", "zipcodes.csv.zst"), tmp / "zipcodes.csv")
    return pd.read_csv(csv, dtype={"zip_code": str})


@pytest.fixture(scope="session")
def zip_blob(tmp):
    path = tmp / "zip.kiln"
    run_cli("build", need_data("geo", "zipcodes.csv.zst"), "-o", path, "--lon-column",
            "longitude", "--lat-column", "latitude", "--accel", "quadtree")
    return path


@pytest.fixture(scope="session")
def need_geopandas(counties_blob):
    """geopandas (with rtree for sjoin) and the counties as plain GeoJSON beside the blob."""
    geopandas = pytest.importorskip("geopandas")
    pytest.importorskip("rtree", reason="geopandas.sjoin needs python3-rtree")
    unzstd(need_data("geo", "us-counties-10m.geojson.zst"), counties_blob.parent / "counties.geojson")
    return geopandas
